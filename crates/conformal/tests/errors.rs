//! Inputs that are not usable give typed errors, never panics or garbage.

use shapespace_conformal::{disk_map, ConformalError, DiskMapParams, Markers};
use shapespace_geometry::prepare::subdivide_midpoint;
use shapespace_geometry::primitives::{icosphere, pinched_strip, unit_disk};
use shapespace_geometry::TriMesh;

fn run(m: &TriMesh) -> Result<shapespace_conformal::DiskMap, ConformalError> {
    disk_map(m, &Markers::default(), &DiskMapParams::default())
}

#[test]
fn closed_surface_is_not_a_disk() {
    match run(&icosphere(1)) {
        Err(ConformalError::NotDisk { reason }) => assert!(reason.contains("0 boundary loop"), "{reason}"),
        other => panic!("{:?}", other.map(|d| d.quality)),
    }
}

#[test]
fn two_components_are_not_a_disk() {
    let a = unit_disk(2);
    let mut m = a.clone();
    let n = a.num_vertices() as u32;
    m.positions.extend(a.positions.iter().map(|p| [p[0] + 5.0, p[1], p[2]]));
    m.faces.extend(a.faces.iter().map(|f| [f[0] + n, f[1] + n, f[2] + n]));
    assert!(matches!(run(&m), Err(ConformalError::NotDisk { .. })));
}

#[test]
fn inconsistent_orientation_and_degenerate_faces_are_errors() {
    let mut m = unit_disk(3);
    let f = m.faces[5];
    m.faces[5] = [f[0], f[2], f[1]];
    assert!(matches!(run(&m), Err(ConformalError::InconsistentOrientation { .. })));
    let mut m = unit_disk(3);
    let [a, b, _] = m.faces[7];
    m.positions[b as usize] = m.positions[a as usize];
    assert!(matches!(run(&m), Err(ConformalError::DegenerateFace { .. })));
    let mut m = unit_disk(3);
    m.positions.push([9.0, 9.0, 9.0]); // unreferenced vertex
    assert!(matches!(run(&m), Err(ConformalError::NotDisk { .. })));
}

/// A 5 × 5 grid whose interior vertex 6 is pushed just across the boundary edge y = 0 (a fold):
/// with plain cotangent weights (some negative) the harmonic log-radius of vertex 6 exceeds the
/// boundary's 0. That is named as such, not as "crowding ... (log10 = NaN)" as before.
#[test]
fn interior_vertex_outside_the_circle_is_named() {
    let mut positions = Vec::new();
    for j in 0..5 {
        for i in 0..5 {
            positions.push([i as f64 / 4.0, j as f64 / 4.0, 0.0]);
        }
    }
    positions[6] = [0.25, -0.001, 0.0];
    let mut faces = Vec::new();
    for j in 0..4u32 {
        for i in 0..4u32 {
            let a = j * 5 + i;
            faces.push([a, a + 1, a + 6]);
            faces.push([a, a + 6, a + 5]);
        }
    }
    let m = TriMesh::new(positions, faces).unwrap();
    let markers = Markers {
        center: shapespace_conformal::CenterMarker::Vertex(12),
        ..Markers::default()
    };
    let params = DiskMapParams {
        intrinsic_delaunay: false,
        ..DiskMapParams::default()
    };
    match disk_map(&m, &markers, &params) {
        Err(e @ ConformalError::InteriorOutsideDisk { vertex: 6, radius }) => {
            assert!(radius > 1.0 && radius < 1.01, "{radius}");
            assert!(e.to_string().contains("interior vertex 6"), "{e}");
        }
        other => panic!("{:?}", other.map(|d| d.quality)),
    }
}

/// Interior vertices that only a path through boundary vertices joins to the centre (an edge
/// between two boundary vertices cuts the interior): the Dirichlet problem is zero there, so
/// the map would put them on the circle. Named as such, with the remedy; `prepare_disk` splits
/// the cutting edges, after which (refined) the map exists and the former pocket is inside the
/// disk.
#[test]
fn interior_cut_off_by_a_boundary_edge_is_named() {
    let m = pinched_strip();
    let markers = Markers {
        center: shapespace_conformal::CenterMarker::Vertex(4),
        ..Markers::default()
    };
    match disk_map(&m, &markers, &DiskMapParams::default()) {
        Err(
            e @ ConformalError::CutOffInterior {
                vertex: 9,
                count: 1,
                by_flips: false,
            },
        ) => {
            assert!(e.to_string().contains("shapespace prepare"), "{e}");
        }
        other => panic!("{:?}", other.map(|d| d.quality)),
    }
    let (prepared, _, report) = shapespace_geometry::prepare::prepare_disk(&m, &Default::default()).unwrap();
    assert_eq!(report.bridges_split, 3);
    // (the 17-vertex strip itself is too coarse for an unfolded map: refine it, same surface)
    let fine = subdivide_midpoint(&subdivide_midpoint(&prepared).unwrap()).unwrap();
    let map = disk_map(&fine, &markers, &DiskMapParams::default()).unwrap();
    let r = |v: usize| map.uv[v][0].hypot(map.uv[v][1]);
    assert!(r(9) < 0.99 && r(9) > 0.1, "|z(9)| = {}", r(9));
    assert_eq!(r(4), 0.0);
    assert_eq!(map.quality.num_flipped, 0);
}
