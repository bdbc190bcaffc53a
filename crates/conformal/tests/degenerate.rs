//! Degenerate faces on a real mesh: `prepare_disk` repairs them without moving a vertex, and the
//! disk map of the repaired mesh agrees with that of the clean mesh.
//!
//! A bundled face gets vertices at the midpoints of some edges, each splitting one face in two
//! and leaving a zero-area face (a, b, m) on the edge ab: interior edges (repaired by a flip of
//! ab) and boundary edges (repaired by removing the face; m becomes a boundary vertex on the
//! straight rim). The disk map refuses such a mesh; after `prepare_disk` it maps, and the images
//! of the original vertices stay where the clean mesh puts them, up to the change a local
//! refinement makes.

use crate::common::*;
use shapespace_conformal::markers::ResolvedCenter;
use shapespace_conformal::{disk_map, BoundaryMarker, CenterMarker, DiskMapParams, Markers};
use shapespace_geometry::io::read_mesh;
use shapespace_geometry::prepare::{prepare_disk, PrepareOptions};
use shapespace_geometry::topology::{degenerate_face, degenerate_faces};
use shapespace_geometry::{Connectivity, TriMesh};

/// Inserts the midpoint m of edge (a, b) of face `f` = (a, b, c) (in its order): the face
/// becomes (a, m, c) and (m, b, c), plus the degenerate (a, b, m) on the old edge.
fn split_with_sliver(mesh: &mut TriMesh, f: usize, k: usize) {
    let t = mesh.faces[f];
    let (a, b, c) = (t[k], t[(k + 1) % 3], t[(k + 2) % 3]);
    let (pa, pb) = (mesh.positions[a as usize], mesh.positions[b as usize]);
    let m = mesh.positions.len() as u32;
    mesh.positions.push([0, 1, 2].map(|i| 0.5 * (pa[i] + pb[i])));
    mesh.faces[f] = [a, m, c];
    mesh.faces.push([m, b, c]);
    mesh.faces.push([a, b, m]);
}

#[test]
fn a_face_with_slivers_maps_after_prepare_as_the_clean_face() {
    let Some(dir) = datasets_dir() else { return };
    let clean = read_mesh(&dir.join("faces/id00_neutral.obj")).unwrap();
    let base = map(&clean, &Markers::default());
    let ResolvedCenter::Vertex(p) = base.info.markers.center else {
        panic!("auto centre is a vertex")
    };
    let q = base.info.markers.boundary_vertex;
    // three boundary edges along the rim and five interior edges over the face, on faces that
    // share no vertex with each other or the markers
    let conn = Connectivity::of(&clean);
    let rim_loop = conn.boundary_loops(&clean.faces).swap_remove(0);
    let rim_edges: std::collections::HashSet<[u32; 2]> = (0..rim_loop.len())
        .map(|i| [rim_loop[i], rim_loop[(i + 1) % rim_loop.len()]])
        .flat_map(|[x, y]| [[x, y], [y, x]])
        .collect();
    let mut used: std::collections::HashSet<u32> = [p, q].into();
    let mut mesh = clean.clone();
    let (mut interior, mut rim) = (0, 0);
    let mut try_split = |mesh: &mut TriMesh, f: usize, want_rim: bool| -> bool {
        let t = clean.faces[f];
        if t.iter().any(|v| used.contains(v)) {
            return false;
        }
        let Some(k) = (0..3).find(|&k| rim_edges.contains(&[t[k], t[(k + 1) % 3]]) == want_rim) else {
            return false;
        };
        split_with_sliver(mesh, f, k);
        // a midpoint rounded off the line leaves a proper (if thin) face: try another edge
        if degenerate_face(mesh, mesh.num_faces() - 1).is_none() {
            mesh.faces.truncate(mesh.num_faces() - 2);
            mesh.positions.pop();
            mesh.faces[f] = t;
            return false;
        }
        used.extend(t);
        true
    };
    for i in (0..rim_loop.len()).step_by(rim_loop.len() / 10) {
        let [x, y] = [rim_loop[i], rim_loop[(i + 1) % rim_loop.len()]];
        let f = (0..clean.num_faces())
            .find(|&f| clean.faces[f].contains(&x) && clean.faces[f].contains(&y))
            .unwrap();
        if rim < 3 {
            rim += try_split(&mut mesh, f, true) as usize;
        }
    }
    for f in (0..clean.num_faces()).step_by(clean.num_faces() / 50).skip(1) {
        if interior < 5 {
            interior += try_split(&mut mesh, f, false) as usize;
        }
    }
    assert_eq!((interior, rim), (5, 3));
    assert_eq!(degenerate_faces(&mesh).len(), 8);
    let markers = Markers {
        center: CenterMarker::Vertex(p),
        boundary: BoundaryMarker::Vertex(q),
    };
    let err = disk_map(&mesh, &markers, &DiskMapParams::default())
        .unwrap_err()
        .to_string();
    assert!(err.contains("degenerate face"), "{err}");

    let (repaired, origin, report) = prepare_disk(&mesh, &PrepareOptions::default()).unwrap();
    assert_eq!(report.degenerate_faces_repaired.flipped, 5, "{report:?}");
    assert_eq!(report.degenerate_faces_repaired.removed, 3, "{report:?}");
    assert_eq!(report.degenerate_faces_repaired.collapsed, 0, "{report:?}");
    assert!(degenerate_faces(&repaired).is_empty());
    // no vertex moved or renumbered: the inserted midpoints stay at the end
    assert_eq!(repaired.positions, mesh.positions);
    assert!(origin.iter().enumerate().all(|(v, o)| *o == Some(v as u32)));
    let dm = map(&repaired, &markers);
    assert_eq!(dm.quality.num_flipped + dm.quality.num_degenerate, 0);
    let n = clean.num_vertices();
    let moved = max_dist(&base.uv, &dm.uv[..n]);
    eprintln!("largest image displacement of an original vertex: {moved:.2e}");
    assert!(moved < 2e-3, "{moved}");
}
