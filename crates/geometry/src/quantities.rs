//! Per-element geometric quantities: face areas and normals, barycentric vertex areas, corner
//! angles and cotangents, vertex normals.
//!
//! Names follow geometry-central (`face_areas`, `vertex_dual_areas`, ...). All arrays are in
//! element order.

use crate::mesh::TriMesh;
use crate::vec3::{cross, dot, norm, scale, sub};

/// Area of the triangle with corners `a`, `b`, `c`: ½|(b−a)×(c−a)|.
#[inline]
pub fn triangle_area(a: [f64; 3], b: [f64; 3], c: [f64; 3]) -> f64 {
    0.5 * norm(cross(sub(b, a), sub(c, a)))
}

/// Area of a triangle from its side lengths with Kahan's stable form of Heron's formula
/// [Kahan 2014, "Miscalculating area and angles of a needle-like triangle", §2] (accurate for
/// needle-like triangles). Returns 0 when roundoff violates the triangle inequality.
pub fn triangle_area_from_lengths(a: f64, b: f64, c: f64) -> f64 {
    let mut s = [a, b, c];
    s.sort_by(|x, y| y.total_cmp(x));
    let [a, b, c] = s;
    let p = (a + (b + c)) * (c - (a - b)) * (c + (a - b)) * (a + (b - c));
    if p > 0.0 {
        0.25 * p.sqrt()
    } else {
        0.0
    }
}

/// Side lengths of the triangle with corners `p[0]`, `p[1]`, `p[2]`: entry k is `|p[k] − p[k+1]|`
/// (indices mod 3), the lengths the disk maps start from.
pub fn face_edge_lengths(p: [[f64; 3]; 3]) -> [f64; 3] {
    std::array::from_fn(|k| {
        let (a, b) = (p[k], p[(k + 1) % 3]);
        ((a[0] - b[0]).powi(2) + (a[1] - b[1]).powi(2) + (a[2] - b[2]).powi(2)).sqrt()
    })
}

/// Face areas, #F.
pub fn face_areas(mesh: &TriMesh) -> Vec<f64> {
    (0..mesh.num_faces())
        .map(|f| {
            let [a, b, c] = mesh.face_positions(f);
            triangle_area(a, b, c)
        })
        .collect()
}

/// Total surface area Σ_f A_f.
pub fn total_area(mesh: &TriMesh) -> f64 {
    face_areas(mesh).iter().sum()
}

/// Unit face normals, #F, by the right-hand rule on the face's vertex order. A zero-area face
/// gets the zero vector.
pub fn face_normals(mesh: &TriMesh) -> Vec<[f64; 3]> {
    (0..mesh.num_faces())
        .map(|f| {
            let [a, b, c] = mesh.face_positions(f);
            let n = cross(sub(b, a), sub(c, a));
            let l = norm(n);
            if l > 0.0 {
                scale(n, 1.0 / l)
            } else {
                [0.0; 3]
            }
        })
        .collect()
}

/// Barycentric vertex areas, #V: one third of the areas of the faces around each vertex.
/// These are the target masses ν_i of Su et al. 2015 (§4.2); Σ_i ν_i = total area.
pub fn vertex_dual_areas(mesh: &TriMesh) -> Vec<f64> {
    let mut areas = vec![0.0; mesh.num_vertices()];
    for (f, face) in mesh.faces.iter().enumerate() {
        let [a, b, c] = mesh.face_positions(f);
        let third = triangle_area(a, b, c) / 3.0;
        for &v in face {
            areas[v as usize] += third;
        }
    }
    areas
}

/// Interior angles at the three corners of each face, #F × 3, in radians; corner k is at vertex
/// `faces[f][k]`. Computed with atan2(|u×v|, u·v), accurate for tiny and obtuse angles.
pub fn corner_angles(mesh: &TriMesh) -> Vec<[f64; 3]> {
    (0..mesh.num_faces())
        .map(|f| {
            let p = mesh.face_positions(f);
            let mut out = [0.0; 3];
            for k in 0..3 {
                let u = sub(p[(k + 1) % 3], p[k]);
                let v = sub(p[(k + 2) % 3], p[k]);
                out[k] = norm(cross(u, v)).atan2(dot(u, v));
            }
            out
        })
        .collect()
}

/// Cotangents of the corner angles, #F × 3: cot θ = (u·v)/|u×v|. A degenerate corner
/// (|u×v| = 0) gets 0, so it contributes no weight.
pub fn corner_cotangents(mesh: &TriMesh) -> Vec<[f64; 3]> {
    (0..mesh.num_faces())
        .map(|f| {
            let p = mesh.face_positions(f);
            let mut out = [0.0; 3];
            for k in 0..3 {
                let u = sub(p[(k + 1) % 3], p[k]);
                let v = sub(p[(k + 2) % 3], p[k]);
                let s = norm(cross(u, v));
                out[k] = if s > 0.0 { dot(u, v) / s } else { 0.0 };
            }
            out
        })
        .collect()
}

/// Area-weighted vertex normals, #V (sum of the non-normalized face normals, normalized).
/// Vertices with no incident face get the zero vector.
pub fn vertex_normals(mesh: &TriMesh) -> Vec<[f64; 3]> {
    let mut normals = vec![[0.0; 3]; mesh.num_vertices()];
    for (f, face) in mesh.faces.iter().enumerate() {
        let [a, b, c] = mesh.face_positions(f);
        let n = cross(sub(b, a), sub(c, a));
        for &v in face {
            let acc = &mut normals[v as usize];
            for d in 0..3 {
                acc[d] += n[d];
            }
        }
    }
    for n in &mut normals {
        let l = norm(*n);
        if l > 0.0 {
            *n = scale(*n, 1.0 / l);
        }
    }
    normals
}

#[cfg(test)]
mod tests {
    use super::*;

    fn square() -> TriMesh {
        TriMesh::new(
            vec![[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [1.0, 1.0, 0.0], [0.0, 1.0, 0.0]],
            vec![[0, 1, 2], [0, 2, 3]],
        )
        .unwrap()
    }

    #[test]
    fn unit_square_areas_angles() {
        let m = square();
        assert_eq!(face_areas(&m), vec![0.5, 0.5]);
        let va = vertex_dual_areas(&m);
        assert!((va.iter().sum::<f64>() - 1.0).abs() < 1e-15);
        assert!((va[0] - 1.0 / 3.0).abs() < 1e-15);
        assert!((va[1] - 1.0 / 6.0).abs() < 1e-15);
        let ang = corner_angles(&m);
        for a in &ang {
            assert!((a.iter().sum::<f64>() - std::f64::consts::PI).abs() < 1e-14);
        }
        assert!((ang[0][1] - std::f64::consts::FRAC_PI_2).abs() < 1e-15);
        let n = face_normals(&m);
        assert_eq!(n[0], [0.0, 0.0, 1.0]);
        let cot = corner_cotangents(&m);
        assert!(cot[0][1].abs() < 1e-15 && (cot[0][0] - 1.0).abs() < 1e-15);
    }
}
