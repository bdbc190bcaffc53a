//! Distortion of a piecewise-linear map from a closed surface to the unit sphere.
//!
//! The image of a face is its flat chordal triangle (the corners on S²); the affine map from
//! the 3D triangle (the surface scaled to area 4π) to it has singular values γ_max ≥ γ_min, and
//! Υ = ln(γ_max γ_min) = ln(A_chord / A_3D), Λ = ln(γ_max / γ_min), the angle distortion is the
//! mean |θ_3D − θ_image| over the corners, as for the disk ([`crate::quality`]). Orientation
//! is the exact sign of det(a, b, c) of the image corners (`orient_3d` with the origin): the
//! triangle seen from outside the sphere is counter-clockwise when positive. Chordal areas are
//! O(h²) smaller than spherical ones; Σ A_chord < 4π.

use geogram_predicates::{orient_3d, Sign};
use rayon::prelude::*;
use shapespace_geometry::TriMesh;

use crate::error::ConformalError;
use crate::quality::{power_of_two_scale, FaceDistortions};

fn sub3(a: [f64; 3], b: [f64; 3]) -> [f64; 3] {
    [a[0] - b[0], a[1] - b[1], a[2] - b[2]]
}
fn dot3(a: [f64; 3], b: [f64; 3]) -> f64 {
    a[0] * b[0] + a[1] * b[1] + a[2] * b[2]
}
fn cross3(a: [f64; 3], b: [f64; 3]) -> [f64; 3] {
    [
        a[1] * b[2] - a[2] * b[1],
        a[2] * b[0] - a[0] * b[2],
        a[0] * b[1] - a[1] * b[0],
    ]
}
fn norm3(a: [f64; 3]) -> f64 {
    dot3(a, a).sqrt()
}

/// The corner angles of a 3D triangle.
fn angles(p: [[f64; 3]; 3]) -> [f64; 3] {
    [0, 1, 2].map(|k| {
        let (u, v) = (sub3(p[(k + 1) % 3], p[k]), sub3(p[(k + 2) % 3], p[k]));
        norm3(cross3(u, v)).atan2(dot3(u, v))
    })
}

/// Local frame of a 3D triangle given by its two edge vectors: E1 = (l1, 0), E2 = (x, y),
/// y ≥ 0 (`None` when degenerate).
fn frame(e1: [f64; 3], e2: [f64; 3]) -> Option<(f64, f64, f64)> {
    let l1 = norm3(e1);
    let twice_area = norm3(cross3(e1, e2));
    if !(l1 > 0.0) || !(twice_area > 0.0) || !twice_area.is_finite() {
        return None;
    }
    Some((l1, dot3(e1, e2) / l1, twice_area / l1))
}

/// Exact orientation of the spherical image triangle (a, b, c): +1 when det(a, b, c) > 0.
pub fn orientation_on_sphere(a: [f64; 3], b: [f64; 3], c: [f64; 3]) -> i8 {
    match orient_3d(&[0.0, 0.0, 0.0], &a, &b, &c) {
        // geogram's orient_3d(p0, p1, p2, p3) is the sign of det(p1 − p0, p2 − p0, p3 − p0)
        Sign::Positive => 1,
        Sign::Negative => -1,
        Sign::Zero => 0,
    }
}

/// Per-face distortion of the map `positions` (#V points on S²) of the closed surface `mesh`,
/// with the surface scaled to area 4π (Υ = 0: the chordal image triangle has the face's area).
///
/// Errors: `positions` of the wrong length, a zero-area 3D face.
pub fn sphere_face_distortions(mesh: &TriMesh, positions: &[[f64; 3]]) -> Result<FaceDistortions, ConformalError> {
    if positions.len() != mesh.num_vertices() {
        return Err(ConformalError::InvalidConstraint(format!(
            "{} image points for {} vertices",
            positions.len(),
            mesh.num_vertices()
        )));
    }
    let total = shapespace_geometry::quantities::total_area(mesh);
    let ln_scale2 = (4.0 * std::f64::consts::PI / total).ln();
    let per_face: Vec<Option<(f64, f64, f64, i8)>> = (0..mesh.num_faces())
        .into_par_iter()
        .map(|f| {
            let p3 = mesh.face_positions(f);
            let (l1, x, y) = frame(sub3(p3[1], p3[0]), sub3(p3[2], p3[0]))?;
            let q = mesh.faces[f].map(|v| positions[v as usize]);
            let orientation = orientation_on_sphere(q[0], q[1], q[2]);
            let (d1, d2) = (sub3(q[1], q[0]), sub3(q[2], q[0]));
            let m = d1.iter().chain(&d2).fold(0.0f64, |a, c| a.max(c.abs()));
            let (s, e) = if m > 0.0 && m.is_finite() {
                power_of_two_scale(m)
            } else {
                (1.0, 0)
            };
            let (d1, d2) = (d1.map(|c| c * s), d2.map(|c| c * s));
            let Some((m1, mx, my)) = frame(d1, d2) else {
                return Some((
                    f64::NEG_INFINITY,
                    f64::INFINITY,
                    std::f64::consts::PI / 3.0,
                    orientation,
                ));
            };
            // J = [D1 D2] E⁻¹ in the two local frames, D1 = (m1, 0), D2 = (mx, my)
            let inv = 1.0 / (l1 * y);
            let (ja, jb, jc, jd) = (m1 * y * inv, (mx * l1 - m1 * x) * inv, 0.0, my * l1 * inv);
            let sp = ((ja + jd).powi(2) + (jc - jb).powi(2)).sqrt();
            let sm = ((ja - jd).powi(2) + (jb + jc).powi(2)).sqrt();
            let (gmax, gmin) = (0.5 * (sp + sm), 0.5 * (sp - sm).abs());
            let det = (ja * jd - jb * jc).abs();
            let area_distortion = det.ln() + 2.0 * e as f64 * std::f64::consts::LN_2 - ln_scale2;
            let quasi_conformal = if gmin > 0.0 { (gmax / gmin).ln() } else { f64::INFINITY };
            let (a3, a2) = (angles(p3), angles([[0.0; 3], d1, d2]));
            let angle = (0..3).map(|k| (a3[k] - a2[k]).abs()).sum::<f64>() / 3.0;
            Some((area_distortion, quasi_conformal, angle, orientation))
        })
        .collect();
    FaceDistortions::from_faces(per_face)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn orientation_convention() {
        // counter-clockwise seen from outside: positive
        let (a, b, c) = ([1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]);
        assert_eq!(orientation_on_sphere(a, b, c), 1);
        assert_eq!(orientation_on_sphere(a, c, b), -1);
        assert_eq!(orientation_on_sphere(a, a, b), 0);
    }

    #[test]
    fn the_unit_sphere_onto_itself_has_no_distortion_beyond_the_chords() {
        let mesh = shapespace_geometry::primitives::icosphere(3);
        let d = sphere_face_distortions(&mesh, &mesh.positions).unwrap();
        assert!(d.orientation.iter().all(|&o| o == 1));
        assert!(d.quasi_conformal_distortion.iter().all(|&x| x < 1e-12));
        assert!(d.angle_distortion.iter().all(|&x| x < 1e-12));
        // the icosphere has area < 4π; scaled to 4π, its own chords have Υ = ln(A/4π) < 0
        let a = shapespace_geometry::quantities::total_area(&mesh);
        let expected = (a / (4.0 * std::f64::consts::PI)).ln();
        assert!(d.area_distortion.iter().all(|&x| (x - expected).abs() < 1e-12));
    }
}
