//! Mesh generators for analytic test cases: flat disks, spherical caps, icospheres, planar grids
//! and capped tubes. All faces are counter-clockwise seen from the outside (from +z for planar
//! meshes), so the boundary loop of a disk runs counter-clockwise.

use std::collections::HashMap;

use crate::mesh::TriMesh;

/// Concentric ring layout on the unit disk: vertex 0 is the center, ring k (1 ≤ k ≤ `rings`)
/// has 6k vertices at radius k/rings and angles 2πj/(6k). Returns (radius parameter s ∈ [0, 1],
/// angle φ) per vertex and the faces. Near-equilateral triangles, #V = 1 + 3·rings·(rings + 1).
fn ring_layout(rings: usize) -> (Vec<(f64, f64)>, Vec<[u32; 3]>) {
    let rings = rings.max(1);
    let mut params = vec![(0.0, 0.0)];
    let mut faces = Vec::new();
    let mut prev_start = 0usize;
    let mut prev_len = 1usize;
    for k in 1..=rings {
        let start = params.len();
        let len = 6 * k;
        for j in 0..len {
            params.push((
                k as f64 / rings as f64,
                2.0 * std::f64::consts::PI * j as f64 / len as f64,
            ));
        }
        if k == 1 {
            for j in 0..len {
                faces.push([0, (start + j) as u32, (start + (j + 1) % len) as u32]);
            }
        } else {
            // merge the two rings by angle: advance whichever next vertex has the smaller angle
            let angle = |idx: usize, count: usize| 2.0 * std::f64::consts::PI * idx as f64 / count as f64;
            let (mut i, mut j) = (0usize, 0usize);
            while i < prev_len || j < len {
                let inner_next = angle(i + 1, prev_len);
                let outer_next = angle(j + 1, len);
                let a = (prev_start + i % prev_len) as u32;
                let b = (start + j % len) as u32;
                if j < len && (i >= prev_len || outer_next <= inner_next) {
                    let c = (start + (j + 1) % len) as u32;
                    faces.push([a, b, c]);
                    j += 1;
                } else {
                    let c = (prev_start + (i + 1) % prev_len) as u32;
                    faces.push([a, b, c]);
                    i += 1;
                }
            }
        }
        prev_start = start;
        prev_len = len;
    }
    (params, faces)
}

/// The flat unit disk in the plane z = 0, meshed by concentric rings (see `ring_layout`):
/// vertex 0 is the center, the last 6·rings vertices lie exactly on the unit circle.
pub fn unit_disk(rings: usize) -> TriMesh {
    let (params, faces) = ring_layout(rings);
    let positions = params
        .iter()
        .map(|&(s, phi)| [s * phi.cos(), s * phi.sin(), 0.0])
        .collect();
    TriMesh {
        positions,
        faces,
        uvs: None,
    }
}

/// A spherical cap of half-angle `alpha` (0 < α ≤ π) on the unit sphere, pole at +z.
///
/// Vertex 0 is the pole; ring k lies at polar angle θ = α·k/rings. With the pole as interior
/// marker its conformal map to the unit disk is stereographic projection, r = tan(θ/2)/tan(α/2)
/// (`docs/conventions.md`). Outward normals, so faces are counter-clockwise seen from above.
pub fn spherical_cap(alpha: f64, rings: usize) -> TriMesh {
    let (params, faces) = ring_layout(rings);
    let positions = params
        .iter()
        .map(|&(s, phi)| {
            let theta = alpha * s;
            [theta.sin() * phi.cos(), theta.sin() * phi.sin(), theta.cos()]
        })
        .collect();
    TriMesh {
        positions,
        faces,
        uvs: None,
    }
}

/// The icosphere of radius 1: an icosahedron with each face split into four `subdivisions`
/// times, new vertices projected to the sphere. #V = 10·4^s + 2, #F = 20·4^s. Outward normals.
pub fn icosphere(subdivisions: usize) -> TriMesh {
    let t = (1.0 + 5f64.sqrt()) / 2.0;
    let mut positions: Vec<[f64; 3]> = vec![
        [-1.0, t, 0.0],
        [1.0, t, 0.0],
        [-1.0, -t, 0.0],
        [1.0, -t, 0.0],
        [0.0, -1.0, t],
        [0.0, 1.0, t],
        [0.0, -1.0, -t],
        [0.0, 1.0, -t],
        [t, 0.0, -1.0],
        [t, 0.0, 1.0],
        [-t, 0.0, -1.0],
        [-t, 0.0, 1.0],
    ];
    let normalize = |p: [f64; 3]| {
        let l = (p[0] * p[0] + p[1] * p[1] + p[2] * p[2]).sqrt();
        [p[0] / l, p[1] / l, p[2] / l]
    };
    for p in &mut positions {
        *p = normalize(*p);
    }
    let mut faces: Vec<[u32; 3]> = vec![
        [0, 11, 5],
        [0, 5, 1],
        [0, 1, 7],
        [0, 7, 10],
        [0, 10, 11],
        [1, 5, 9],
        [5, 11, 4],
        [11, 10, 2],
        [10, 7, 6],
        [7, 1, 8],
        [3, 9, 4],
        [3, 4, 2],
        [3, 2, 6],
        [3, 6, 8],
        [3, 8, 9],
        [4, 9, 5],
        [2, 4, 11],
        [6, 2, 10],
        [8, 6, 7],
        [9, 8, 1],
    ];
    for _ in 0..subdivisions {
        let mut cache: HashMap<(u32, u32), u32> = HashMap::new();
        let mut midpoint = |a: u32, b: u32, positions: &mut Vec<[f64; 3]>| -> u32 {
            let key = (a.min(b), a.max(b));
            *cache.entry(key).or_insert_with(|| {
                let pa = positions[a as usize];
                let pb = positions[b as usize];
                positions.push(normalize([
                    (pa[0] + pb[0]) / 2.0,
                    (pa[1] + pb[1]) / 2.0,
                    (pa[2] + pb[2]) / 2.0,
                ]));
                (positions.len() - 1) as u32
            })
        };
        let mut next = Vec::with_capacity(4 * faces.len());
        for &[a, b, c] in &faces {
            let ab = midpoint(a, b, &mut positions);
            let bc = midpoint(b, c, &mut positions);
            let ca = midpoint(c, a, &mut positions);
            next.extend_from_slice(&[[a, ab, ca], [b, bc, ab], [c, ca, bc], [ab, bc, ca]]);
        }
        faces = next;
    }
    TriMesh {
        positions,
        faces,
        uvs: None,
    }
}

/// A planar grid on [0, 1]² (z = 0) with `nx` × `ny` cells, each split along its diagonal
/// (i, j)–(i+1, j+1). Vertex (i, j) has index j·(nx + 1) + i.
pub fn grid(nx: usize, ny: usize) -> TriMesh {
    let (nx, ny) = (nx.max(1), ny.max(1));
    let mut positions = Vec::with_capacity((nx + 1) * (ny + 1));
    for j in 0..=ny {
        for i in 0..=nx {
            positions.push([i as f64 / nx as f64, j as f64 / ny as f64, 0.0]);
        }
    }
    let id = |i: usize, j: usize| (j * (nx + 1) + i) as u32;
    let mut faces = Vec::with_capacity(2 * nx * ny);
    for j in 0..ny {
        for i in 0..nx {
            faces.push([id(i, j), id(i + 1, j), id(i + 1, j + 1)]);
            faces.push([id(i, j), id(i + 1, j + 1), id(i, j + 1)]);
        }
    }
    TriMesh {
        positions,
        faces,
        uvs: None,
    }
}

/// A tube of radius `radius` and height `height` along +z, closed at z = 0 by a flat cap and
/// open at z = height: a disk-topology surface whose conformal factor decays like e^{−z/ρ}
/// along the tube (`docs/conventions.md`). The cap has `cap_rings` rings (vertex 0 is the cap center, the
/// natural interior marker); the tube has `6·cap_rings` vertices around and `along` segments.
/// Faces are oriented with outward normals (the cap faces −z).
pub fn capped_tube(radius: f64, height: f64, cap_rings: usize, along: usize) -> TriMesh {
    let (params, cap_faces) = ring_layout(cap_rings);
    let mut positions: Vec<[f64; 3]> = params
        .iter()
        .map(|&(s, phi)| [radius * s * phi.cos(), radius * s * phi.sin(), 0.0])
        .collect();
    // the cap is seen from −z: reverse its faces so normals point outward (−z)
    let mut faces: Vec<[u32; 3]> = cap_faces.iter().map(|&[a, b, c]| [a, c, b]).collect();
    let around = 6 * cap_rings.max(1);
    let rim_start = positions.len() - around;
    let along = along.max(1);
    let mut prev = rim_start;
    for k in 1..=along {
        let z = height * k as f64 / along as f64;
        let start = positions.len();
        for j in 0..around {
            let phi = 2.0 * std::f64::consts::PI * j as f64 / around as f64;
            positions.push([radius * phi.cos(), radius * phi.sin(), z]);
        }
        for j in 0..around {
            let a = (prev + j) as u32;
            let b = (prev + (j + 1) % around) as u32;
            let c = (start + (j + 1) % around) as u32;
            let d = (start + j) as u32;
            // outward normal (radial): a→b runs counter-clockwise seen from +z, so a, b, c and a, c, d
            faces.push([a, b, c]);
            faces.push([a, c, d]);
        }
        prev = start;
    }
    TriMesh {
        positions,
        faces,
        uvs: None,
    }
}

/// A flat 4 × 2 strip of unit squares whose middle column has no vertex at y = 1: the edge
/// (2, 0)–(2, 2) joins two boundary vertices and cuts the interior vertices (1, 1) and (3, 1)
/// apart (vertices 4 and 9; the others are all on the boundary). A test case for
/// [`crate::prepare::interior_components`] and for the disk maps' error on such meshes. Two more interior edges join
/// boundary vertices, (0, 1)–(1, 2) and (3, 0)–(4, 1), without cutting anything.
pub fn pinched_strip() -> TriMesh {
    let positions = vec![
        [0.0, 0.0, 0.0],
        [0.0, 1.0, 0.0],
        [0.0, 2.0, 0.0],
        [1.0, 0.0, 0.0],
        [1.0, 1.0, 0.0],
        [1.0, 2.0, 0.0],
        [2.0, 0.0, 0.0],
        [2.0, 2.0, 0.0],
        [3.0, 0.0, 0.0],
        [3.0, 1.0, 0.0],
        [3.0, 2.0, 0.0],
        [4.0, 0.0, 0.0],
        [4.0, 1.0, 0.0],
        [4.0, 2.0, 0.0],
    ];
    let faces = vec![
        [0, 3, 4],
        [0, 4, 1],
        [1, 4, 5],
        [1, 5, 2],
        [3, 6, 4],
        [4, 6, 7],
        [4, 7, 5],
        [6, 8, 9],
        [6, 9, 7],
        [7, 9, 10],
        [8, 11, 12],
        [8, 12, 9],
        [9, 12, 13],
        [9, 13, 10],
    ];
    TriMesh {
        positions,
        faces,
        uvs: None,
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::connectivity::Connectivity;
    use crate::quantities::{face_areas, face_normals, total_area};

    fn euler(mesh: &TriMesh) -> i64 {
        let c = Connectivity::of(mesh);
        mesh.num_vertices() as i64 - c.num_edges() as i64 + mesh.num_faces() as i64
    }

    #[test]
    fn disk_is_a_disk_with_ccw_faces() {
        for rings in [1, 2, 5, 20] {
            let m = unit_disk(rings);
            m.validate().unwrap();
            assert_eq!(m.num_vertices(), 1 + 3 * rings * (rings + 1));
            assert_eq!(euler(&m), 1);
            let loops = Connectivity::of(&m).boundary_loops(&m.faces);
            assert_eq!(loops.len(), 1);
            assert_eq!(loops[0].len(), 6 * rings);
            assert!(face_normals(&m).iter().all(|n| (n[2] - 1.0).abs() < 1e-12));
            assert!(face_areas(&m).iter().all(|&a| a > 0.0));
        }
        // area of the inscribed polygon converges to π
        let a = total_area(&unit_disk(40));
        let polygon = 0.5 * 240.0 * (2.0 * std::f64::consts::PI / 240.0).sin();
        assert!((a - polygon).abs() < 1e-12);
    }

    #[test]
    fn hemisphere_area_and_orientation() {
        let m = spherical_cap(std::f64::consts::FRAC_PI_2, 30);
        assert_eq!(euler(&m), 1);
        let a = total_area(&m);
        assert!((a - 2.0 * std::f64::consts::PI).abs() < 0.01, "{a}");
        // outward: the normal agrees with the position
        let n = face_normals(&m);
        for (f, nf) in n.iter().enumerate() {
            let [p, _, _] = m.face_positions(f);
            assert!(nf[0] * p[0] + nf[1] * p[1] + nf[2] * p[2] > 0.0);
        }
    }

    #[test]
    fn icosphere_counts_and_area() {
        let m = icosphere(3);
        assert_eq!(m.num_vertices(), 10 * 64 + 2);
        assert_eq!(m.num_faces(), 20 * 64);
        assert_eq!(euler(&m), 2);
        let a = total_area(&m);
        assert!((a - 4.0 * std::f64::consts::PI).abs() < 0.05 * 4.0 * std::f64::consts::PI);
        let n = face_normals(&m);
        for (f, nf) in n.iter().enumerate() {
            let [p, _, _] = m.face_positions(f);
            assert!(nf[0] * p[0] + nf[1] * p[1] + nf[2] * p[2] > 0.0);
        }
    }

    #[test]
    fn grid_and_tube_topology() {
        let g = grid(4, 3);
        assert_eq!(g.num_vertices(), 20);
        assert_eq!(euler(&g), 1);
        assert!((total_area(&g) - 1.0).abs() < 1e-14);
        let t = capped_tube(0.5, 3.0, 4, 10);
        assert_eq!(euler(&t), 1);
        let loops = Connectivity::of(&t).boundary_loops(&t.faces);
        assert_eq!(loops.len(), 1);
        let expected = std::f64::consts::PI * 0.25 + 2.0 * std::f64::consts::PI * 0.5 * 3.0;
        assert!((total_area(&t) - expected).abs() < 0.03 * expected);
        // outward normals on the wall
        let n = face_normals(&t);
        for (f, nf) in n.iter().enumerate() {
            let [p, q, r] = t.face_positions(f);
            let c = [
                (p[0] + q[0] + r[0]) / 3.0,
                (p[1] + q[1] + r[1]) / 3.0,
                (p[2] + q[2] + r[2]) / 3.0,
            ];
            if c[2] > 1e-9 {
                assert!(nf[0] * c[0] + nf[1] * c[1] > 0.0);
            } else {
                assert!(nf[2] < 0.0);
            }
        }
    }
}
