//! Shared by the face-pair probes and benchmarks: the bundled faces
//! prepared for distances, with the markers of `datasets/faces/landmarks.json` (nose tip 4841,
//! chin 8889). Run from the repository root.

use shapespace_analysis::distance::{prepare_shape, PreparedShape};
use shapespace_conformal::{BoundaryMarker, CenterMarker, DiskMapParams, Markers};

/// `datasets/faces/NAME.obj` for each name, prepared (conformal map, density, points, masses).
pub fn prepared_faces<S: AsRef<str>>(names: &[S]) -> Vec<PreparedShape> {
    let dir = std::path::Path::new("datasets/faces");
    let markers = Markers {
        center: CenterMarker::Vertex(4841),
        boundary: BoundaryMarker::Vertex(8889),
    };
    names
        .iter()
        .map(|n| {
            let n = n.as_ref();
            let mesh = shapespace_geometry::io::read_mesh(&dir.join(format!("{n}.obj"))).unwrap();
            prepare_shape(n, &mesh, &markers, &DiskMapParams::default()).unwrap()
        })
        .collect()
}
