//! Topology reports, classification and the preparation operations on analytic meshes:
//! icospheres, a torus, a Möbius strip, a bowtie, a fin of three triangles on one edge, a flipped
//! face, a square annulus, cuts of a sphere, area normalization.

use std::f64::consts::PI;

use shapespace_geometry::connectivity::Connectivity;
use shapespace_geometry::prepare::{self, Radius};
use shapespace_geometry::primitives::{grid, icosphere, pinched_strip, unit_disk};
use shapespace_geometry::quantities::{face_areas, face_normals, total_area};
use shapespace_geometry::topology::{classify, inconsistent_edges, mesh_report, require_disk, MeshClass};
use shapespace_geometry::TriMesh;

/// Torus with radii `big` > `small`, `n` segments around the big circle and `m` around the tube,
/// outward normals. #V = n·m, #F = 2·n·m.
fn torus(big: f64, small: f64, n: usize, m: usize) -> TriMesh {
    let mut positions = Vec::new();
    for i in 0..n {
        let u = 2.0 * PI * i as f64 / n as f64;
        for j in 0..m {
            let v = 2.0 * PI * j as f64 / m as f64;
            let r = big + small * v.cos();
            positions.push([r * u.cos(), r * u.sin(), small * v.sin()]);
        }
    }
    let id = |i: usize, j: usize| ((i % n) * m + (j % m)) as u32;
    let mut faces = Vec::new();
    for i in 0..n {
        for j in 0..m {
            // (u, v) increasing: ∂u × ∂v points outward
            faces.push([id(i, j), id(i + 1, j), id(i + 1, j + 1)]);
            faces.push([id(i, j), id(i + 1, j + 1), id(i, j + 1)]);
        }
    }
    TriMesh::new(positions, faces).unwrap()
}

/// Möbius strip with `n` quads along the centre circle (two vertex rows, glued with a twist).
fn mobius(n: usize) -> TriMesh {
    let mut positions = Vec::new();
    for i in 0..n {
        let u = 2.0 * PI * i as f64 / n as f64;
        for s in [-0.3, 0.3] {
            let r = 1.0 + s * (u / 2.0).cos();
            positions.push([r * u.cos(), r * u.sin(), s * (u / 2.0).sin()]);
        }
    }
    let mut faces = Vec::new();
    for i in 0..n {
        let (a, b) = (2 * i as u32, 2 * i as u32 + 1);
        // the last quad glues row 0 to row 1 (the twist)
        let (c, d) = if i + 1 < n {
            (2 * (i as u32 + 1), 2 * (i as u32 + 1) + 1)
        } else {
            (1, 0)
        };
        faces.push([a, c, d]);
        faces.push([a, d, b]);
    }
    TriMesh::new(positions, faces).unwrap()
}

/// The grid [0, 1]² with `n` × `n` cells minus the faces of the central `k` × `k` cells:
/// a square annulus (2 boundary loops, χ = 0).
fn square_annulus(n: usize, k: usize) -> TriMesh {
    let g = grid(n, n);
    let lo = (n - k) / 2;
    let hi = lo + k;
    let faces = g
        .faces
        .iter()
        .enumerate()
        .filter(|(f, _)| {
            let cell = f / 2;
            let (i, j) = (cell % n, cell / n);
            !(lo <= i && i < hi && lo <= j && j < hi)
        })
        .map(|(_, f)| *f)
        .collect();
    // the vertices strictly inside the removed square are unreferenced now: drop them
    let (m, _) = prepare::drop_unreferenced_vertices(&TriMesh::new(g.positions.clone(), faces).unwrap()).unwrap();
    m
}

#[test]
fn icospheres_are_spheres() {
    for s in 2..=5 {
        let m = icosphere(s);
        let r = mesh_report(&m).unwrap();
        let p = 4usize.pow(s as u32);
        assert_eq!((r.num_vertices, r.num_edges, r.num_faces), (10 * p + 2, 30 * p, 20 * p));
        assert_eq!(r.euler_characteristic, 2);
        assert_eq!(r.num_components, 1);
        assert_eq!(r.num_boundary_loops, 0);
        assert_eq!(r.genus, 0.0);
        assert!(r.closed && r.manifold && r.consistently_oriented && r.orientable);
        assert_eq!(
            r.num_degenerate_faces + r.num_duplicate_vertices + r.num_unreferenced_vertices,
            0
        );
        assert_eq!(r.classification.class, MeshClass::Sphere);
        assert!(r.classification.reasons.is_empty());
        assert!((r.area - 4.0 * PI).abs() < 0.05 * 4.0 * PI);
    }
}

#[test]
fn torus_has_genus_one() {
    let m = torus(2.0, 0.7, 24, 12);
    let r = mesh_report(&m).unwrap();
    assert_eq!(r.euler_characteristic, 0);
    assert_eq!(r.genus, 1.0);
    assert_eq!(r.components[0].genus, 1.0);
    assert!(r.closed && r.manifold && r.consistently_oriented);
    assert_eq!(r.classification.class, MeshClass::Other);
    assert!(
        r.classification.reasons.iter().any(|s| s.contains("χ = 0")),
        "{:?}",
        r.classification
    );
    let err = require_disk(&m).unwrap_err().to_string();
    assert!(err.contains("genus 1"), "{err}");
}

#[test]
fn mobius_strip_is_not_orientable() {
    let m = mobius(20);
    let r = mesh_report(&m).unwrap();
    assert!(!r.orientable);
    assert!(!r.consistently_oriented);
    // V − E + F = 40 − 80 + 40, and one boundary curve of 40 vertices (it is not a directed
    // loop: the walk goes on backwards at the twist; it used to count 2 loops)
    assert_eq!(r.euler_characteristic, 0);
    assert_eq!((r.num_boundary_loops, r.boundary_loop_lengths.clone()), (1, vec![40]));
    assert_eq!(r.classification.class, MeshClass::Other);
    assert!(r.classification.reasons.iter().any(|s| s.contains("not orientable")));
    let err = prepare::reorient(&m).unwrap_err().to_string();
    assert!(err.contains("non-orientable"), "{err}");
}

#[test]
fn bowtie_has_a_non_manifold_vertex() {
    // two triangles sharing only vertex 2
    let m = TriMesh::new(
        vec![
            [0.0, 0.0, 0.0],
            [1.0, 0.0, 0.0],
            [0.5, 0.5, 0.0],
            [0.0, 1.0, 0.0],
            [1.0, 1.0, 0.0],
        ],
        vec![[0, 1, 2], [2, 4, 3]],
    )
    .unwrap();
    let r = mesh_report(&m).unwrap();
    assert_eq!(r.num_non_manifold_vertices, 1);
    assert_eq!(r.first_non_manifold_vertices, vec![2]);
    assert_eq!(r.num_non_manifold_edges, 0);
    assert!(!r.manifold);
    assert_eq!(r.num_components, 2);
    // V − E + F = 5 − 6 + 2
    assert_eq!(r.euler_characteristic, 1);
    assert_eq!(r.num_boundary_loops, 2);
    assert_eq!(r.classification.class, MeshClass::Other);
    assert!(
        r.classification
            .reasons
            .iter()
            .any(|s| s == "1 non-manifold vertex, first 2"),
        "{:?}",
        r.classification
    );
    // keeping the largest component repairs it: a single triangle (tie → the one with face 0)
    let (one, map) = prepare::keep_largest_component(&m).unwrap();
    assert_eq!(one.faces, vec![[0, 1, 2]]);
    assert_eq!(map, vec![Some(0), Some(1), Some(2), None, None]);
    assert_eq!(classify(&one).unwrap().class, MeshClass::Disk);
}

#[test]
fn three_faces_on_one_edge() {
    let m = TriMesh::new(
        vec![
            [0.0, 0.0, 0.0],
            [1.0, 0.0, 0.0],
            [0.5, 1.0, 0.0],
            [0.5, -1.0, 0.0],
            [0.5, 0.0, 1.0],
        ],
        vec![[0, 1, 2], [1, 0, 3], [0, 1, 4]],
    )
    .unwrap();
    let r = mesh_report(&m).unwrap();
    assert_eq!(r.num_non_manifold_edges, 1);
    assert_eq!(r.first_non_manifold_edges, vec![[0, 1]]);
    // the edge's endpoints have three separate fans each
    assert_eq!(r.first_non_manifold_vertices, vec![0, 1]);
    assert_eq!(r.num_components, 1);
    assert!(
        r.classification
            .reasons
            .iter()
            .any(|s| s == "1 non-manifold edge, first (0, 1)"),
        "{:?}",
        r.classification
    );
    let err = require_disk(&m).unwrap_err().to_string();
    assert!(err.contains("non-manifold edge"), "{err}");
}

#[test]
fn flipped_face_is_found_and_fixed() {
    let sphere = icosphere(2);
    let mut m = sphere.clone();
    m.faces[17].swap(0, 1);
    let conn = Connectivity::of(&m);
    let bad = inconsistent_edges(&m.faces, &conn);
    assert_eq!(bad.len(), 3);
    let [a, b, c] = m.faces[17];
    for e in [[a, b], [b, c], [c, a]] {
        assert!(bad.contains(&[e[0].min(e[1]), e[0].max(e[1])]));
    }
    let r = mesh_report(&m).unwrap();
    assert!(!r.consistently_oriented && r.orientable);
    assert_eq!(r.num_inconsistent_edges, 3);
    assert_eq!(r.classification.class, MeshClass::Other);
    assert!(r.classification.reasons[0].starts_with("inconsistent orientation at 3 edges"));

    let (fixed, info) = prepare::reorient(&m).unwrap();
    assert_eq!(fixed.positions, m.positions);
    assert_eq!(classify(&fixed).unwrap().class, MeshClass::Sphere);
    // the BFS keeps face 0's orientation, which is outward: only face 17 flips, no global turn
    assert_eq!(info.faces_flipped_for_consistency, 1);
    assert_eq!(info.closed_components_turned_outward, 0);
    let normals = face_normals(&fixed);
    for (f, n) in normals.iter().enumerate() {
        let [p, q, s] = fixed.face_positions(f);
        let centroid = [
            (p[0] + q[0] + s[0]) / 3.0,
            (p[1] + q[1] + s[1]) / 3.0,
            (p[2] + q[2] + s[2]) / 3.0,
        ];
        let outward = n[0] * centroid[0] + n[1] * centroid[1] + n[2] * centroid[2];
        assert!(outward > 0.9, "face {f} points inward after reorient");
    }

    // a sphere with every face reversed is consistent but inward: reorient turns it outward
    let mut inward = sphere.clone();
    for f in &mut inward.faces {
        f.swap(1, 2);
    }
    let (out, info) = prepare::reorient(&inward).unwrap();
    assert_eq!(
        info,
        prepare::ReorientInfo {
            faces_flipped_for_consistency: 0,
            closed_components_turned_outward: 1
        }
    );
    for (f, g) in out.faces.iter().zip(&sphere.faces) {
        // same cyclic orientation as the original outward face
        let rot = |x: [u32; 3]| {
            let k = (0..3).min_by_key(|&k| x[k]).unwrap();
            [x[k], x[(k + 1) % 3], x[(k + 2) % 3]]
        };
        assert_eq!(rot(*f), rot(*g));
    }
}

#[test]
fn filling_the_square_annulus_gives_a_disk() {
    let m = square_annulus(8, 2);
    assert_eq!(m.num_vertices(), 81 - 1);
    let r = mesh_report(&m).unwrap();
    assert_eq!((r.num_boundary_loops, r.euler_characteristic), (2, 0));
    // the outer loop has 32 vertices, the inner 8
    assert_eq!(r.boundary_loop_lengths, vec![32, 8]);
    assert_eq!(r.classification.class, MeshClass::Other);
    assert!(
        r.classification
            .reasons
            .iter()
            .any(|s| s == "2 boundary loops (a disk needs 1)"),
        "{:?}",
        r.classification
    );
    let err = require_disk(&m).unwrap_err().to_string();
    assert!(err.contains("fill_holes_except_longest"), "{err}");

    let (filled, info) = prepare::fill_holes_except_longest(&m).unwrap();
    assert_eq!(info.holes_filled, 1);
    assert!((info.kept_loop_length - 4.0).abs() < 1e-12);
    assert_eq!(filled.num_vertices(), m.num_vertices() + 1);
    assert_eq!(&filled.positions[..m.num_vertices()], &m.positions[..]);
    assert_eq!(&filled.faces[..m.num_faces()], &m.faces[..]);
    // the fan centre is the centre of the square, the hole's 8 triangles cover its area 1/16
    assert_eq!(filled.positions[m.num_vertices()], [0.5, 0.5, 0.0]);
    assert_eq!(filled.num_faces(), m.num_faces() + 8);
    assert!((total_area(&filled) - 1.0).abs() < 1e-14);
    // oriented like the rest: all normals +z
    assert!(face_normals(&filled).iter().all(|n| n[2] == 1.0));
    let r = mesh_report(&filled).unwrap();
    assert_eq!(r.classification.class, MeshClass::Disk, "{:?}", r.classification);
    require_disk(&filled).unwrap();

    // a single named hole, and a wrong loop
    let conn = Connectivity::of(&m);
    let loops = conn.boundary_loops(&m.faces);
    let one = prepare::fill_hole(&m, &loops[1]).unwrap();
    assert_eq!(classify(&one).unwrap().class, MeshClass::Disk);
    let mut reversed = loops[1].clone();
    reversed.reverse();
    // the same triangles (in reverse order): orientation comes from the adjacent faces
    let mut a = prepare::fill_hole(&m, &reversed).unwrap().faces;
    let mut b = one.faces.clone();
    a.sort_unstable();
    b.sort_unstable();
    assert_eq!(a, b);
    assert!(prepare::fill_hole(&m, &[0, 1, 10]).is_err());
}

#[test]
fn cut_disk_on_icosphere() {
    let m = icosphere(3);
    for radius in [
        Radius::Rings(1),
        Radius::Rings(3),
        Radius::Geodesic(0.2),
        Radius::Geodesic(1.0),
    ] {
        let (disk, map) = prepare::cut_disk(&m, 5, radius).unwrap();
        let r = mesh_report(&disk).unwrap();
        assert_eq!(
            r.classification.class,
            MeshClass::Disk,
            "{radius:?}: {:?}",
            r.classification
        );
        require_disk(&disk).unwrap();
        assert!(map[5].is_none());
        // kept vertices keep their positions and relative order
        let mut last = None;
        for (old, new) in map.iter().enumerate() {
            if let Some(n) = *new {
                assert_eq!(disk.positions[n as usize], m.positions[old]);
                assert!(last.is_none_or(|l| n == l + 1));
                last = Some(n);
            }
        }
        assert!(disk.num_faces() < m.num_faces());
    }
    // Rings(1) removes exactly the 5 or 6 faces around the centre (vertex 5 is an icosahedron vertex)
    let (disk, _) = prepare::cut_disk(&m, 5, Radius::Rings(1)).unwrap();
    assert_eq!(m.num_faces() - disk.num_faces(), 5);
    // a ball covering everything, an open mesh, an invalid centre
    assert!(prepare::cut_disk(&m, 5, Radius::Geodesic(10.0)).is_err());
    assert!(prepare::cut_disk(&unit_disk(3), 0, Radius::Rings(1)).is_err());
    assert!(prepare::cut_disk(&m, 1_000_000, Radius::Rings(1)).is_err());
}

#[test]
fn cut_that_leaves_an_annulus_is_reported() {
    // a geodesic ball of radius ~ the full sphere minus a cap near the antipode leaves a disk;
    // on the torus, cutting a small ball leaves genus 1 with one boundary: not a disk
    let t = torus(2.0, 0.7, 24, 12);
    let err = prepare::cut_disk(&t, 0, Radius::Rings(1)).unwrap_err().to_string();
    assert!(err.contains("non-disk") && err.contains("χ = -1"), "{err}");
}

#[test]
fn scale_to_area_and_normalize() {
    let mut m = icosphere(3);
    for p in &mut m.positions {
        p[0] = 3.0 * p[0] + 100.0;
        p[2] -= 7.0;
    }
    for target in [PI, 1e-6, 1e6] {
        let s = prepare::scale_to_area(&m, target).unwrap();
        assert!((total_area(&s) - target).abs() <= 1e-12 * target, "{target}");
    }
    let n = prepare::normalize_for_shape_space(&m).unwrap();
    assert!((total_area(&n) - PI).abs() < 1e-12 * PI);
    // the area-weighted centroid stays put
    let centroid = |mesh: &TriMesh| {
        let a = face_areas(mesh);
        let mut c = [0.0; 3];
        for (f, &af) in a.iter().enumerate() {
            let [p, q, r] = mesh.face_positions(f);
            for d in 0..3 {
                c[d] += af * (p[d] + q[d] + r[d]) / 3.0;
            }
        }
        let s: f64 = a.iter().sum();
        c.map(|x| x / s)
    };
    let (c0, c1) = (centroid(&m), centroid(&n));
    for d in 0..3 {
        assert!((c0[d] - c1[d]).abs() < 1e-10 * (1.0 + c0[d].abs()));
    }
    // zero area and a bad target are errors
    let flat = TriMesh::new(vec![[0.0; 3], [1.0, 0.0, 0.0], [2.0, 0.0, 0.0]], vec![[0, 1, 2]]).unwrap();
    assert!(prepare::scale_to_area(&flat, PI).is_err());
    assert!(prepare::scale_to_area(&m, 0.0).is_err());
    assert!(prepare::scale_to_area(&m, f64::NAN).is_err());
}

#[test]
fn midpoint_subdivision_keeps_the_surface_and_its_topology() {
    for mesh in [unit_disk(3), icosphere(1)] {
        let conn = Connectivity::of(&mesh);
        let fine = prepare::subdivide_midpoint(&mesh).unwrap();
        let e = conn.num_edges();
        assert_eq!(
            (fine.num_vertices(), fine.num_faces()),
            (mesh.num_vertices() + e, 4 * mesh.num_faces())
        );
        assert_eq!(&fine.positions[..mesh.num_vertices()], &mesh.positions[..]);
        assert!((total_area(&fine) - total_area(&mesh)).abs() < 1e-12 * total_area(&mesh));
        assert_eq!(classify(&fine).unwrap().class, classify(&mesh).unwrap().class);
        assert!(inconsistent_edges(&fine.faces, &Connectivity::of(&fine)).is_empty());
    }
    // texture coordinates are interpolated at the midpoints
    let mut m = grid(2, 2);
    m.uvs = Some(m.positions.iter().map(|p| [p[0], p[1]]).collect());
    let fine = prepare::subdivide_midpoint(&m).unwrap();
    for (p, uv) in fine.positions.iter().zip(fine.uvs.as_ref().unwrap()) {
        assert!((p[0] - uv[0]).abs() < 1e-15 && (p[1] - uv[1]).abs() < 1e-15);
    }
}

#[test]
fn unreferenced_duplicate_and_degenerate_elements() {
    let mut m = unit_disk(2);
    let n = m.num_vertices() as u32;
    m.positions.push([5.0, 5.0, 5.0]); // unreferenced, index n
    m.positions.push(m.positions[3]); // duplicate of 3, unreferenced, index n + 1
    m.faces.push([0, 0, 1]); // repeated index
    let r = mesh_report(&m).unwrap();
    assert_eq!(r.num_unreferenced_vertices, 2);
    assert_eq!(r.first_unreferenced_vertices, vec![n, n + 1]);
    assert_eq!(r.first_duplicate_vertices, vec![[3, n + 1]]);
    assert_eq!(r.first_degenerate_faces, vec![m.num_faces() as u32 - 1]);
    let err = require_disk(&m).unwrap_err().to_string();
    assert!(
        err.contains("drop_unreferenced_vertices") && err.contains("degenerate face"),
        "{err}"
    );

    m.faces.pop();
    let (clean, map) = prepare::drop_unreferenced_vertices(&m).unwrap();
    assert_eq!(clean, unit_disk(2));
    assert_eq!(map.len(), n as usize + 2);
    assert!(map[..n as usize].iter().enumerate().all(|(i, x)| *x == Some(i as u32)));
    assert_eq!(&map[n as usize..], &[None, None]);
    require_disk(&clean).unwrap();

    // a zero-area face with distinct indices (three collinear points)
    let collinear = TriMesh::new(
        vec![[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [2.0, 0.0, 0.0], [0.0, 1.0, 0.0]],
        vec![[0, 1, 3], [1, 2, 3], [0, 2, 1]],
    )
    .unwrap();
    assert_eq!(mesh_report(&collinear).unwrap().first_degenerate_faces, vec![2]);
}

#[test]
fn several_components() {
    // a sphere and a far-away disk: keep_largest_component keeps the sphere
    let s = icosphere(2);
    let d = unit_disk(3);
    let mut m = d.clone();
    let off = m.num_vertices() as u32;
    m.positions
        .extend(s.positions.iter().map(|p| [p[0] + 10.0, p[1], p[2]]));
    m.faces.extend(s.faces.iter().map(|f| f.map(|v| v + off)));
    let r = mesh_report(&m).unwrap();
    assert_eq!(r.num_components, 2);
    assert_eq!(r.euler_characteristic, 3);
    assert_eq!(r.components[0].faces, s.num_faces());
    assert_eq!(
        (r.components[0].euler_characteristic, r.components[0].boundary_loops),
        (2, 0)
    );
    assert_eq!(
        (r.components[1].euler_characteristic, r.components[1].boundary_loops),
        (1, 1)
    );
    assert_eq!(r.genus, 0.0);
    assert!(r.classification.reasons[0].starts_with("2 components"));
    assert!(require_disk(&m)
        .unwrap_err()
        .to_string()
        .contains("keep_largest_component"));
    let (largest, map) = prepare::keep_largest_component(&m).unwrap();
    assert_eq!(largest.faces, s.faces);
    assert!(map[..off as usize].iter().all(|x| x.is_none()));
    assert_eq!(classify(&largest).unwrap().class, MeshClass::Sphere);
}

#[test]
fn report_serializes_to_json() {
    let r = mesh_report(&unit_disk(2)).unwrap();
    let json = serde_json::to_value(&r).unwrap();
    assert_eq!(json["classification"]["class"], "disk");
    assert_eq!(json["euler_characteristic"], 1);
    assert_eq!(json["num_faces"], 24);
}

#[test]
fn invalid_meshes_are_errors_not_panics() {
    let bad = TriMesh {
        positions: vec![[0.0; 3]; 3],
        faces: vec![[0, 1, 7]],
        uvs: None,
    };
    assert!(mesh_report(&bad).is_err());
    assert!(classify(&bad).is_err());
    assert!(require_disk(&bad).is_err());
    assert!(prepare::reorient(&bad).is_err());
    assert!(prepare::keep_largest_component(&bad).is_err());
    assert!(prepare::drop_unreferenced_vertices(&bad).is_err());
    assert!(prepare::fill_holes_except_longest(&bad).is_err());
    assert!(prepare::scale_to_area(&bad, 1.0).is_err());
    let nan = TriMesh {
        positions: vec![[0.0; 3], [1.0, 0.0, 0.0], [f64::NAN, 1.0, 0.0]],
        faces: vec![[0, 1, 2]],
        uvs: None,
    };
    assert!(mesh_report(&nan).is_err());
    // an empty mesh is a valid mesh with no class
    let empty = TriMesh::default();
    let r = mesh_report(&empty).unwrap();
    assert_eq!((r.num_vertices, r.num_faces, r.euler_characteristic), (0, 0, 0));
    assert_eq!(r.classification.class, MeshClass::Other);
    assert!(require_disk(&empty).is_err());
}

#[test]
fn reorient_an_open_disk_and_fill_three_holes() {
    // a 9 × 9 grid with three separate 1-cell holes: 4 boundary loops, χ = −2 (like a face with
    // two eyes and a mouth)
    let g = grid(9, 9);
    let holes = [(2, 2), (6, 2), (4, 6)];
    let faces: Vec<[u32; 3]> = g
        .faces
        .iter()
        .enumerate()
        .filter(|(f, _)| !holes.contains(&((f / 2) % 9, (f / 2) / 9)))
        .map(|(_, f)| *f)
        .collect();
    let mut m = TriMesh::new(g.positions.clone(), faces).unwrap();
    let r = mesh_report(&m).unwrap();
    assert_eq!((r.num_boundary_loops, r.euler_characteristic), (4, -2));
    assert_eq!(r.boundary_loop_lengths, vec![36, 4, 4, 4]);
    let err = require_disk(&m).unwrap_err().to_string();
    assert!(
        err.contains("4 boundary loops: fill the inner holes with `prepare::fill_holes_except_longest`"),
        "{err}"
    );

    // flip a third of the faces: reorient restores +z normals everywhere (face 0 is kept)
    for f in (1..m.faces.len()).step_by(3) {
        m.faces[f].swap(0, 2);
    }
    assert!(!mesh_report(&m).unwrap().consistently_oriented);
    let (fixed, info) = prepare::reorient(&m).unwrap();
    assert_eq!(info.faces_flipped_for_consistency, (m.faces.len() - 1).div_ceil(3));
    assert_eq!(info.closed_components_turned_outward, 0);
    assert!(face_normals(&fixed).iter().all(|n| n[2] == 1.0));

    // only face 0 wound the wrong way: it is the one flipped (it used to set the orientation
    // of the whole piece, mirroring the disk); the outer boundary, which face 0 touches, is
    // still one loop, and the report still finds the 4 loops
    let mut one = fixed.clone();
    one.faces[0].swap(1, 2);
    assert_eq!(mesh_report(&one).unwrap().num_boundary_loops, 4);
    let (again, info) = prepare::reorient(&one).unwrap();
    assert_eq!(info.faces_flipped_for_consistency, 1);
    assert!(face_normals(&again).iter().all(|n| n[2] == 1.0));

    let (filled, info) = prepare::fill_holes_except_longest(&fixed).unwrap();
    assert_eq!(info.holes_filled, 3);
    assert_eq!(filled.num_vertices(), fixed.num_vertices() + 3);
    assert!((total_area(&filled) - 1.0).abs() < 1e-14);
    assert!(face_normals(&filled).iter().all(|n| n[2] == 1.0));
    require_disk(&filled).unwrap();
}

/// `prepare_disk` runs the explicit operations in order and says what it did: a closed sphere
/// is cut open at the vertex nearest its centroid (or a given input vertex), an annulus gets its
/// inner hole filled, a second component and unreferenced vertices are dropped; every result is
/// a disk whose vertices map back to the input's; a torus stays a non-disk and the error says so.
#[test]
fn prepare_disk_makes_disks_and_reports_its_steps() {
    // sphere plus a far, smaller second sphere and an unreferenced vertex
    let big = icosphere(2);
    let small = icosphere(1);
    let mut positions = big.positions.clone();
    let off = positions.len() as u32;
    positions.extend(
        small
            .positions
            .iter()
            .map(|p| [p[0] * 0.1 + 5.0, p[1] * 0.1, p[2] * 0.1]),
    );
    positions.push([9.0, 9.0, 9.0]);
    let mut faces = big.faces.clone();
    faces.extend(small.faces.iter().map(|f| f.map(|v| v + off)));
    let mesh = TriMesh {
        positions,
        faces,
        uvs: None,
    };
    let (disk, origin, report) = prepare::prepare_disk(&mesh, &prepare::PrepareOptions::default()).unwrap();
    require_disk(&disk).unwrap();
    assert_eq!(report.unreferenced_dropped, 1);
    assert_eq!(report.faces_of_other_components_dropped, small.num_faces());
    assert_eq!(disk.num_faces(), big.num_faces() - report.faces_cut);
    assert!(report.faces_cut > 0 && report.holes_filled == 0);
    for (v, o) in origin.iter().enumerate() {
        let o = o.expect("no vertex added on a cut") as usize;
        assert!(o < big.num_vertices());
        assert_eq!(disk.positions[v], mesh.positions[o]);
    }
    // the automatic centre is the vertex nearest the centroid (the origin for an icosphere:
    // any vertex; the rule picks the first nearest); a given centre is honoured
    let (_, _, given) = prepare::prepare_disk(
        &mesh,
        &prepare::PrepareOptions {
            cut_center: prepare::CutCenter::Vertex(7),
            cut_radius: Radius::Rings(1),
            ..Default::default()
        },
    )
    .unwrap();
    assert_eq!(given.cut_center, Some(7));
    assert_eq!(given.closed_components_turned_outward, 0);
    // an inward-facing sphere is turned outward, and the report says so
    let inward = TriMesh {
        faces: big.faces.iter().map(|f| [f[0], f[2], f[1]]).collect(),
        ..big.clone()
    };
    let (_, _, turned) = prepare::prepare_disk(&inward, &prepare::PrepareOptions::default()).unwrap();
    assert_eq!((turned.faces_flipped, turned.closed_components_turned_outward), (0, 1));
    // a centre on the dropped component or out of range is an error naming it
    for v in [off + 2, 1_000_000] {
        let err = prepare::prepare_disk(
            &mesh,
            &prepare::PrepareOptions {
                cut_center: prepare::CutCenter::Vertex(v),
                ..Default::default()
            },
        )
        .unwrap_err()
        .to_string();
        assert!(err.contains(&v.to_string()), "{err}");
    }
    // an annulus: the inner hole is filled with one appended vertex
    let annulus = square_annulus(6, 2);
    let (disk, origin, report) = prepare::prepare_disk(&annulus, &prepare::PrepareOptions::default()).unwrap();
    require_disk(&disk).unwrap();
    assert_eq!(report.holes_filled, 1);
    assert_eq!(report.cut_center, None);
    assert_eq!(origin.iter().filter(|o| o.is_none()).count(), 1);
    // a torus cannot become a disk by cutting a ball out
    let err = prepare::prepare_disk(&torus(2.0, 0.7, 24, 12), &prepare::PrepareOptions::default())
        .unwrap_err()
        .to_string();
    assert!(err.contains("non-disk"), "{err}");
}

#[test]
fn bridges_split_joins_the_interior() {
    let m = pinched_strip();
    require_disk(&m).unwrap();
    assert_eq!(prepare::boundary_bridges(&m), vec![[1, 5], [6, 7], [8, 12]]);
    let (labels, count) = prepare::interior_components(&m);
    assert_eq!(count, 2);
    assert_ne!(labels[4], labels[9]);
    assert!(labels[4].is_some() && labels[9].is_some() && labels[6].is_none());
    // split by hand: one vertex at (2, 1), four faces instead of two, same area, still a disk
    let s = prepare::split_edges(&m, &[[6, 7]]).unwrap();
    assert_eq!((s.num_vertices(), s.num_faces()), (15, 16));
    assert_eq!(s.positions[14], [2.0, 1.0, 0.0]);
    assert!((total_area(&s) - total_area(&m)).abs() < 1e-12);
    assert!(face_areas(&s).iter().all(|&a| a > 0.0));
    require_disk(&s).unwrap();
    assert!(inconsistent_edges(&s.faces, &Connectivity::of(&s)).is_empty());
    assert_eq!(prepare::interior_components(&s).1, 1);
    assert_eq!(prepare::boundary_bridges(&s), vec![[1, 5], [8, 12]]);
    // prepare_disk splits every bridge when (and only when) the interior falls apart
    let (p, origin, report) = prepare::prepare_disk(&m, &Default::default()).unwrap();
    assert_eq!(report.bridges_split, 3);
    assert_eq!((p.num_vertices(), p.num_faces()), (17, 20));
    assert!((total_area(&p) - total_area(&m)).abs() < 1e-12);
    assert!(prepare::boundary_bridges(&p).is_empty());
    assert_eq!(prepare::interior_components(&p).1, 1);
    assert_eq!(origin.len(), 17);
    assert!(origin[14..].iter().all(|o| o.is_none()));
    assert!(origin[..14].iter().enumerate().all(|(v, o)| *o == Some(v as u32)));
    let (_, _, again) = prepare::prepare_disk(&p, &Default::default()).unwrap();
    assert_eq!(again.bridges_split, 0);
    // a bridge that does not cut the interior is left alone: the unit disk's interior is
    // connected whatever its boundary edges
    let d = unit_disk(4);
    assert_eq!(prepare::interior_components(&d).1, 1);
    assert_eq!(
        prepare::prepare_disk(&d, &Default::default()).unwrap().2.bridges_split,
        0
    );
    // a boundary edge cannot be split
    assert!(prepare::split_edges(&m, &[[0, 3]]).is_err());
}

/// The report's area with coordinates near f64::MAX, where the direct cross products overflow:
/// triangles whose true areas are finite are reported to 1e-12 (a short edge beside a huge one
/// must not underflow, an edge spanning more than f64::MAX must not overflow), collinear corners
/// give 0 (not NaN), and a true area beyond f64 gives inf.
#[test]
fn report_area_with_coordinates_near_the_f64_limit() {
    let area = |positions: Vec<[f64; 3]>| {
        let m = TriMesh::new(positions, vec![[0, 1, 2]]).unwrap();
        mesh_report(&m).unwrap().area
    };
    let close = |got: f64, expected: f64| {
        assert!(
            ((got - expected) / expected).abs() < 1e-12,
            "area {got:e}, expected {expected:e}"
        );
    };
    // ½ |(1e308, 0, 0) × (1e308, 1, 0)| = 5e307 (sine of the angle 1e-308)
    close(area(vec![[0.0, 0.0, 0.0], [1e308, 0.0, 0.0], [1e308, 1.0, 0.0]]), 5e307);
    // ½ · 3.4e308 · 1: the edge's length exceeds f64, the area does not
    close(
        area(vec![[-1.7e308, 0.0, 0.0], [1.7e308, 0.0, 0.0], [0.0, 1.0, 0.0]]),
        1.7e308,
    );
    // ½ |(1e308 − 1, 1e308, 0) × (0, 1, 0)| beside a unit square
    let m = TriMesh::new(
        vec![
            [0.0, 0.0, 0.0],
            [1.0, 0.0, 0.0],
            [1.0, 1.0, 0.0],
            [0.0, 1.0, 0.0],
            [1e308, 1e308, 0.0],
        ],
        vec![[0, 1, 2], [0, 2, 3], [1, 4, 2]],
    )
    .unwrap();
    close(mesh_report(&m).unwrap().area, 0.5 * (1e308 - 1.0));
    assert_eq!(
        area(vec![[-1.7e308, 0.0, 0.0], [1.7e308, 0.0, 0.0], [0.0, 0.0, 0.0]]),
        0.0
    );
    assert_eq!(
        area(vec![[0.0, 0.0, 0.0], [1e300, 0.0, 0.0], [0.0, 1e300, 0.0]]),
        f64::INFINITY
    );
}

/// `prepare_disk` drops a face with a repeated corner (it surfaced as "a hole needs at least 3
/// vertices, got 1" from the hole filling) and names the defect no step of it repairs by input
/// vertex indices: an edge with three faces.
#[test]
fn prepare_drops_repeated_vertex_faces_and_names_non_manifold_edges() {
    let g = grid(4, 4);
    let mut degenerate = g.clone();
    degenerate.faces.insert(3, [5, 5, 6]);
    let (disk, origin, report) = prepare::prepare_disk(&degenerate, &prepare::PrepareOptions::default()).unwrap();
    assert_eq!(report.repeated_vertex_faces_dropped, 1);
    assert_eq!(disk.faces, g.faces);
    assert_eq!(disk.positions, g.positions);
    assert!(origin.iter().enumerate().all(|(v, o)| *o == Some(v as u32)));
    // a fin on an interior edge of the grid's first face (shared with a second face)
    let mut fin = g.clone();
    let [_, a, b] = g.faces[0];
    assert_eq!(g.faces.iter().filter(|t| t.contains(&a) && t.contains(&b)).count(), 2);
    fin.positions.push([0.1, 0.1, 1.0]);
    fin.faces.push([a, b, g.num_vertices() as u32]);
    let err = prepare::prepare_disk(&fin, &prepare::PrepareOptions::default())
        .unwrap_err()
        .to_string();
    let (lo, hi) = (a.min(b), a.max(b));
    assert!(
        err.contains("1 non-manifold edges") && err.contains(&format!("input vertices {lo} and {hi}")),
        "{err}"
    );
}
