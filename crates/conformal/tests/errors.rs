//! Inputs that are not usable give typed errors, never panics or garbage.

use shapespace_conformal::green::green_function;
use shapespace_conformal::intrinsic::IntrinsicTriangulation;
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
        bff_fallback: false,
        region_repair: false,
        ..DiskMapParams::default()
    };
    match disk_map(&m, &markers, &params) {
        Err(e @ ConformalError::InteriorOutsideDisk { vertex: 6, radius }) => {
            assert!(radius > 1.0 && radius < 1.01, "{radius}");
            assert!(e.to_string().contains("interior vertex 6"), "{e}");
        }
        other => panic!("{:?}", other.map(|d| d.quality)),
    }
    // with the fallback allowed, the vertex outside the circle sends the map to BFF, whose map
    // of the same Laplacian keeps every vertex inside and folds nothing
    let fallback = disk_map(
        &m,
        &markers,
        &DiskMapParams {
            intrinsic_delaunay: false,
            ..DiskMapParams::default()
        },
    )
    .unwrap();
    let reason = &fallback.info.method;
    assert!(reason.contains("put vertex 6 outside the circle"), "{reason}");
    assert_eq!(fallback.info.bff_fallback.as_ref().unwrap().green_folds, 0);
    assert_eq!(fallback.quality.num_flipped + fallback.quality.num_degenerate, 0);
    assert!(fallback.uv[6][0].hypot(fallback.uv[6][1]) < 1.0);
}

/// Interior vertices that only a path through boundary vertices joins to the centre (an edge
/// between two boundary vertices cuts the interior) would have a zero Dirichlet problem and map
/// onto the circle. The map splits such edges intrinsically (`connect_interior`): its Green's
/// function equals, at the input's vertices, that of the mesh whose same edges were split in
/// 3D (a flat strip: the same surface and the same vertices), and is positive on the former
/// pocket; once refined, the strip maps without a fold and without `prepare`.
#[test]
fn interior_cut_off_by_a_boundary_edge_is_joined_by_intrinsic_splits() {
    let m = pinched_strip();
    let mut tri = IntrinsicTriangulation::from_mesh(&m).unwrap();
    assert_eq!(tri.cut_off_vertices(4), vec![9]);
    let inserted = tri.connect_interior(4, false).unwrap();
    assert!(inserted > 0);
    assert!(tri.cut_off_vertices(4).is_empty());
    // the edges split: the two boundary neighbours of each inserted vertex in line with it
    let n = m.num_vertices();
    let mut split = Vec::new();
    for v in n..tri.num_vertices {
        let ends: Vec<(u32, f64)> = (0..tri.tail.len() as u32)
            .filter(|&h| tri.tail[h as usize] as usize == v && tri.is_boundary[tri.head(h) as usize])
            .map(|h| (tri.head(h), tri.length[h as usize]))
            .collect();
        let dist = |a: u32, b: u32| {
            let (p, q) = (m.positions[a as usize], m.positions[b as usize]);
            ((p[0] - q[0]).powi(2) + (p[1] - q[1]).powi(2) + (p[2] - q[2]).powi(2)).sqrt()
        };
        let pair = ends
            .iter()
            .flat_map(|a| ends.iter().map(move |b| (a, b)))
            .find(|(a, b)| a.0 < b.0 && (dist(a.0, b.0) - a.1 - b.1).abs() < 1e-12)
            .expect("an inserted vertex lies on the edge it split");
        split.push([pair.0 .0, pair.1 .0]);
    }
    let in_3d = shapespace_geometry::prepare::split_edges(&m, &split).unwrap();
    let tri_3d = IntrinsicTriangulation::from_mesh(&in_3d).unwrap();
    let u = green_function(&tri, 4).unwrap();
    let u_3d = green_function(&tri_3d, 4).unwrap();
    for v in 0..n {
        assert!((u[v] - u_3d[v]).abs() < 1e-13, "vertex {v}: {} vs {}", u[v], u_3d[v]);
    }
    assert!(u[9] > 1e-3, "u(9) = {}", u[9]);

    let markers = Markers {
        center: shapespace_conformal::CenterMarker::Vertex(4),
        ..Markers::default()
    };
    let fine = subdivide_midpoint(&subdivide_midpoint(&m).unwrap()).unwrap();
    let map = disk_map(&fine, &markers, &DiskMapParams::default()).unwrap();
    let r = |v: usize| map.uv[v][0].hypot(map.uv[v][1]);
    assert!(r(9) < 0.99 && r(9) > 0.1, "|z(9)| = {}", r(9));
    assert_eq!(map.quality.num_flipped, 0);
}
