//! Distortion of a piecewise-linear map from a surface to the plane.
//!
//! Per face, the affine map J from the 3D triangle (after scaling the whole surface to area π)
//! to its image triangle has singular values γ_max ≥ γ_min. Following Zhao et al. 2013
//! ("Area-preservation mapping using optimal mass transport", §6):
//! $$ \Upsilon = \ln(\gamma_{max}\gamma_{min}) = \ln\frac{A_{2D}}{A_{3D}}, \qquad
//!    \Lambda = \ln\frac{\gamma_{max}}{\gamma_{min}} \;(\ge 0, = 0 \text{ iff conformal}). $$
//! The angle distortion of a face is the mean over its corners of |θ_3D − θ_2D| (radians).
//! Orientation uses the exact `orient_2d` predicate (geogram_predicates) on the image
//! coordinates scaled by a power of two ([`orient_scaled`]); image edge vectors are rescaled by a power of two before any product, so
//! triangles of size 1e-150 keep full relative precision.

use geogram_predicates::{orient_2d, Sign};
use rayon::prelude::*;
use serde::Serialize;
use shapespace_geometry::TriMesh;

use crate::error::ConformalError;

/// (2^−e, e) with e = ⌊log₂ m⌋ for finite m > 0, read from the bits of m (no libm calls: the
/// fold checks call this for every face they test). Multiplying by 2^−e is exact and brings m
/// into [1, 2). Falls back to `log2`/`powi` for subnormal m (and to the same for NaN and ∞,
/// which callers exclude).
pub fn power_of_two_scale(m: f64) -> (f64, i32) {
    let biased = ((m.to_bits() >> 52) & 0x7ff) as i64;
    if (1..=2045).contains(&biased) {
        // m = f·2^(biased − 1023), f ∈ [1, 2); 2^(1023 − biased) has biased exponent 2046 − biased
        (f64::from_bits(((2046 - biased) as u64) << 52), (biased - 1023) as i32)
    } else if biased == 2046 {
        // m ≥ 2^1023: 2^−1023 is subnormal (a single mantissa bit)
        (f64::from_bits(1 << 51), 1023)
    } else {
        let e = m.log2().floor() as i32;
        (2f64.powi(-e), e)
    }
}

/// Exact orientation of the image triangle (a, b, c): the points are first scaled by a common
/// power of two (exact) so that the largest coordinate is about 1, because the adaptive exact
/// predicate is only valid when its products do not underflow (coordinates ≲ 1e-150 would).
pub fn orient_scaled(a: [f64; 2], b: [f64; 2], c: [f64; 2]) -> Sign {
    let m = [a, b, c]
        .iter()
        .flat_map(|p| p.iter())
        .fold(0.0f64, |acc, x| acc.max(x.abs()));
    if !(m > 0.0) || !m.is_finite() {
        return orient_2d(&a, &b, &c);
    }
    let (s, _) = power_of_two_scale(m);
    let sc = |p: [f64; 2]| [p[0] * s, p[1] * s];
    orient_2d(&sc(a), &sc(b), &sc(c))
}

/// Per-face distortion values, each #F.
#[derive(Clone, Debug, Serialize)]
pub struct FaceDistortions {
    /// Υ = ln(A_2D/A_3D) with the surface scaled to area π (0 = area preserving).
    pub area_distortion: Vec<f64>,
    /// Λ = ln(γ_max/γ_min) (0 = conformal).
    pub quasi_conformal_distortion: Vec<f64>,
    /// Mean |θ_3D − θ_2D| over the three corners, radians.
    pub angle_distortion: Vec<f64>,
    /// Orientation of the image: +1 counter-clockwise, −1 flipped, 0 degenerate (exact).
    pub orientation: Vec<i8>,
}

impl FaceDistortions {
    /// Gathers per-face values `(Υ, Λ, angle distortion, orientation)` (#F), `None` for a face of
    /// zero 3D area, which is an error naming the first such face.
    pub(crate) fn from_faces(per_face: Vec<Option<(f64, f64, f64, i8)>>) -> Result<Self, ConformalError> {
        let nf = per_face.len();
        let mut out = FaceDistortions {
            area_distortion: Vec::with_capacity(nf),
            quasi_conformal_distortion: Vec::with_capacity(nf),
            angle_distortion: Vec::with_capacity(nf),
            orientation: Vec::with_capacity(nf),
        };
        for (f, values) in per_face.into_iter().enumerate() {
            let Some((area, quasi_conformal, angle, orientation)) = values else {
                return Err(ConformalError::DegenerateFace {
                    face: f,
                    reason: "zero 3D area".into(),
                });
            };
            out.area_distortion.push(area);
            out.quasi_conformal_distortion.push(quasi_conformal);
            out.angle_distortion.push(angle);
            out.orientation.push(orientation);
        }
        Ok(out)
    }
}

/// Summary statistics of a per-face quantity.
#[derive(Clone, Debug, Default, PartialEq, Serialize)]
pub struct Stats {
    /// Arithmetic mean.
    pub mean: f64,
    /// Median (nearest rank).
    pub median: f64,
    /// 95th percentile (nearest rank).
    pub p95: f64,
    /// Largest value.
    pub max: f64,
    /// Smallest value.
    pub min: f64,
    /// Entries left out of the statistics above because they are not finite (Υ = −∞ of a
    /// face whose image is degenerate, or NaN).
    pub non_finite: usize,
}

impl Stats {
    /// Statistics of the finite entries of `values` (all zero when there are none), with the
    /// count of the others. Percentiles use the nearest rank on the sorted values.
    pub fn of(values: &[f64]) -> Stats {
        let mut v: Vec<f64> = values.iter().copied().filter(|x| x.is_finite()).collect();
        let non_finite = values.len() - v.len();
        if v.is_empty() {
            return Stats {
                non_finite,
                ..Stats::default()
            };
        }
        v.sort_by(f64::total_cmp);
        let rank = |q: f64| v[((q * (v.len() - 1) as f64).round() as usize).min(v.len() - 1)];
        Stats {
            mean: v.iter().sum::<f64>() / v.len() as f64,
            median: rank(0.5),
            p95: rank(0.95),
            max: v[v.len() - 1],
            min: v[0],
            non_finite,
        }
    }
}

/// Summary of the distortion of a map.
#[derive(Clone, Debug, Default, PartialEq, Serialize)]
pub struct QualitySummary {
    /// Statistics of Υ (signed).
    pub area_distortion: Stats,
    /// Statistics of Λ.
    pub quasi_conformal_distortion: Stats,
    /// Statistics of the angle distortion, in degrees.
    pub angle_distortion_deg: Stats,
    /// Number of faces whose image is clockwise.
    pub num_flipped: usize,
    /// Number of faces whose image has zero signed area (exactly).
    pub num_degenerate: usize,
    /// 3D area fraction of the flipped and degenerate faces.
    pub flipped_area_fraction: f64,
}

/// ln of the signed doubled area of the image triangle and the scaled edge vectors: returns
/// (ln |d1 × d2|, normalized d1, d2, ln of the scale factor removed).
fn scaled_edges(p: [[f64; 2]; 3]) -> ([f64; 2], [f64; 2], f64) {
    let d1 = [p[1][0] - p[0][0], p[1][1] - p[0][1]];
    let d2 = [p[2][0] - p[0][0], p[2][1] - p[0][1]];
    let m = d1.iter().chain(d2.iter()).fold(0.0f64, |a, x| a.max(x.abs()));
    if !(m > 0.0) || !m.is_finite() {
        return (d1, d2, 0.0);
    }
    // exact power-of-two scaling
    let (s, e) = power_of_two_scale(m);
    (
        [d1[0] * s, d1[1] * s],
        [d2[0] * s, d2[1] * s],
        e as f64 * std::f64::consts::LN_2,
    )
}

/// The face whose image is smallest relative to the rounding of its own coordinates, and that
/// ratio: min over faces of (smallest image altitude) / (ε · largest |coordinate| of its corners),
/// ε = 2^−52. Below about 1e3 the image is crowded within a few digits of what f64 positions
/// can tell apart: the solves that produce it (whose error grows with the system's condition
/// number) can fold it and no re-embedding in f64 can unfold it. `None` without faces.
pub fn precision_margin(mesh: &TriMesh, uv: &[[f64; 2]]) -> Option<(usize, f64)> {
    mesh.faces
        .iter()
        .enumerate()
        .map(|(f, face)| {
            let p = face.map(|v| uv[v as usize]);
            let longest = (0..3)
                .map(|k| {
                    let (a, b) = (p[k], p[(k + 1) % 3]);
                    (b[0] - a[0]).hypot(b[1] - a[1])
                })
                .fold(0.0f64, f64::max);
            let (u, w) = (
                [p[1][0] - p[0][0], p[1][1] - p[0][1]],
                [p[2][0] - p[0][0], p[2][1] - p[0][1]],
            );
            let cross = u[0] * w[1] - u[1] * w[0];
            if !(cross > 0.0) {
                // folded or degenerate: no altitude to speak of
                return (f, f64::INFINITY);
            }
            let height = cross / longest;
            let scale = p.iter().flatten().fold(0.0f64, |m, x| m.max(x.abs()));
            let ratio = if scale > 0.0 && longest > 0.0 {
                height / (f64::EPSILON * scale)
            } else {
                f64::INFINITY
            };
            (f, ratio)
        })
        .min_by(|a, b| a.1.total_cmp(&b.1))
}

/// The pushed-forward density of each face, μ_f = e^{−Υ_f} from the area distortions Υ
/// ([`face_distortions`]); a density that is zero or not finite is beyond the f64 range
/// (`OutOfRange`, naming the face).
pub fn face_densities(area_distortion: &[f64]) -> Result<Vec<f64>, ConformalError> {
    area_distortion
        .iter()
        .enumerate()
        .map(|(f, &ups)| {
            let mu = (-ups).exp();
            if mu.is_finite() && mu > 0.0 {
                Ok(mu)
            } else {
                Err(ConformalError::OutOfRange {
                    what: "face density",
                    element: format!("face {f}"),
                    log10_value: -ups / std::f64::consts::LN_10,
                })
            }
        })
        .collect()
}

/// Per-face distortion of the map given by `uv` (#V) on `mesh` (the 3D surface is scaled to
/// total area π first, so Υ = 0 means the density of an area-π normalization).
///
/// Errors: `uv` of the wrong length, a zero-area 3D face.
pub fn face_distortions(mesh: &TriMesh, uv: &[[f64; 2]]) -> Result<FaceDistortions, ConformalError> {
    if uv.len() != mesh.num_vertices() {
        return Err(ConformalError::InvalidConstraint(format!(
            "{} image points for {} vertices",
            uv.len(),
            mesh.num_vertices()
        )));
    }
    let areas = shapespace_geometry::quantities::face_areas(mesh);
    let total: f64 = areas.iter().sum();
    let ln_scale2 = (std::f64::consts::PI / total).ln(); // ln s²
    let nf = mesh.num_faces();
    // per face (Υ, ln K, mean angle error, orientation), in parallel; the first degenerate face
    // (lowest index) is the one reported
    let per_face: Vec<Option<(f64, f64, f64, i8)>> = (0..nf)
        .into_par_iter()
        .map(|f| {
            let [a, b, c] = mesh.face_positions(f);
            let e1 = [b[0] - a[0], b[1] - a[1], b[2] - a[2]];
            let e2 = [c[0] - a[0], c[1] - a[1], c[2] - a[2]];
            let l1 = (e1[0] * e1[0] + e1[1] * e1[1] + e1[2] * e1[2]).sqrt();
            let cr = [
                e1[1] * e2[2] - e1[2] * e2[1],
                e1[2] * e2[0] - e1[0] * e2[2],
                e1[0] * e2[1] - e1[1] * e2[0],
            ];
            let twice_area = (cr[0] * cr[0] + cr[1] * cr[1] + cr[2] * cr[2]).sqrt();
            if !(twice_area > 0.0) || !(l1 > 0.0) {
                return None;
            }
            // local frame of the 3D triangle: E1 = (l1, 0), E2 = (x, y)
            let x = (e1[0] * e2[0] + e1[1] * e2[1] + e1[2] * e2[2]) / l1;
            let y = twice_area / l1;
            let face = mesh.faces[f];
            let p = face.map(|v| uv[v as usize]);
            let orientation = match orient_scaled(p[0], p[1], p[2]) {
                Sign::Positive => 1,
                Sign::Negative => -1,
                Sign::Zero => 0,
            };
            let (d1, d2, ln_s) = scaled_edges(p);
            // J = [d1 d2] E⁻¹, E⁻¹ = 1/(l1 y) [[y, −x], [0, l1]]
            let inv = 1.0 / (l1 * y);
            let j = [
                [d1[0] * y * inv, (d2[0] * l1 - d1[0] * x) * inv],
                [d1[1] * y * inv, (d2[1] * l1 - d1[1] * x) * inv],
            ];
            let (ja, jb, jc, jd) = (j[0][0], j[0][1], j[1][0], j[1][1]);
            let sp = ((ja + jd).powi(2) + (jc - jb).powi(2)).sqrt();
            let sm = ((ja - jd).powi(2) + (jb + jc).powi(2)).sqrt();
            let (gmax, gmin) = (0.5 * (sp + sm), 0.5 * (sp - sm).abs());
            let det = (ja * jd - jb * jc).abs();
            // Υ = ln det(J_true) − ln s², J_true = J·2^e
            let area_distortion = det.ln() + 2.0 * ln_s - ln_scale2;
            let quasi_conformal = if gmin > 0.0 { (gmax / gmin).ln() } else { f64::INFINITY };
            // corner angles
            let p3 = [a, b, c];
            let q2 = [[0.0, 0.0], d1, d2];
            let mut sum = 0.0;
            for k in 0..3 {
                let (u3, v3) = (sub3(p3[(k + 1) % 3], p3[k]), sub3(p3[(k + 2) % 3], p3[k]));
                let t3 = norm3(cross3(u3, v3)).atan2(dot3(u3, v3));
                let (u2, v2) = (sub2(q2[(k + 1) % 3], q2[k]), sub2(q2[(k + 2) % 3], q2[k]));
                let t2 = (u2[0] * v2[1] - u2[1] * v2[0])
                    .abs()
                    .atan2(u2[0] * v2[0] + u2[1] * v2[1]);
                sum += (t3 - t2).abs();
            }
            Some((area_distortion, quasi_conformal, sum / 3.0, orientation))
        })
        .collect();
    FaceDistortions::from_faces(per_face)
}

fn sub3(a: [f64; 3], b: [f64; 3]) -> [f64; 3] {
    [a[0] - b[0], a[1] - b[1], a[2] - b[2]]
}
fn sub2(a: [f64; 2], b: [f64; 2]) -> [f64; 2] {
    [a[0] - b[0], a[1] - b[1]]
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

/// Summary statistics of per-face distortions; `face_areas` (#F, 3D) weigh the flipped area.
pub fn summarize(d: &FaceDistortions, face_areas: &[f64]) -> QualitySummary {
    let total: f64 = face_areas.iter().sum();
    let bad: f64 = d
        .orientation
        .iter()
        .zip(face_areas)
        .filter(|(o, _)| **o <= 0)
        .map(|(_, a)| a)
        .sum();
    let deg: Vec<f64> = d.angle_distortion.iter().map(|x| x.to_degrees()).collect();
    QualitySummary {
        area_distortion: Stats::of(&d.area_distortion),
        quasi_conformal_distortion: Stats::of(&d.quasi_conformal_distortion),
        angle_distortion_deg: Stats::of(&deg),
        num_flipped: d.orientation.iter().filter(|&&o| o < 0).count(),
        num_degenerate: d.orientation.iter().filter(|&&o| o == 0).count(),
        flipped_area_fraction: if total > 0.0 { bad / total } else { 0.0 },
    }
}

/// Per-face distortions and their summary for the map `uv` of `mesh`.
pub fn evaluate(mesh: &TriMesh, uv: &[[f64; 2]]) -> Result<(FaceDistortions, QualitySummary), ConformalError> {
    let d = face_distortions(mesh, uv)?;
    let s = summarize(&d, &shapespace_geometry::quantities::face_areas(mesh));
    Ok((d, s))
}

/// Per-vertex log conformal factors λ (#V) of a map with per-face area distortions Υ (#F):
/// e^{2λ_v} = Σ A₃ / Σ A_image over the faces around v, with A₃ = `face_areas`·s² and
/// A_image = A₃·e^{Υ}, summed by log-sum-exp so that images far below or above f64's range
/// of areas still give a finite λ. Errors: a non-finite λ (a vertex in no face, or Υ = ±∞
/// on its whole one-ring).
pub fn vertex_conformal_factors(
    mesh: &TriMesh,
    face_areas: &[f64],
    scale: f64,
    area_distortion: &[f64],
) -> Result<Vec<f64>, ConformalError> {
    let n = mesh.num_vertices();
    let mut ring3 = vec![0.0; n];
    let mut ring_max = vec![f64::NEG_INFINITY; n];
    let ln_a3: Vec<f64> = face_areas.iter().map(|x| (x * scale * scale).ln()).collect();
    for (f, face) in mesh.faces.iter().enumerate() {
        let l2 = ln_a3[f] + area_distortion[f];
        for &v in face {
            ring3[v as usize] += face_areas[f] * scale * scale;
            ring_max[v as usize] = ring_max[v as usize].max(l2);
        }
    }
    let mut ring2 = vec![0.0; n];
    for (f, face) in mesh.faces.iter().enumerate() {
        let l2 = ln_a3[f] + area_distortion[f];
        for &v in face {
            ring2[v as usize] += (l2 - ring_max[v as usize]).exp();
        }
    }
    let conformal_factor: Vec<f64> = (0..n)
        .map(|v| 0.5 * (ring3[v].ln() - (ring_max[v] + ring2[v].ln())))
        .collect();
    if let Some(v) = conformal_factor.iter().position(|x| !x.is_finite()) {
        return Err(ConformalError::NonFinite {
            stage: "conformal factor",
            vertex: v,
        });
    }
    Ok(conformal_factor)
}

#[cfg(test)]
mod tests {

    /// The altitude over the rounding of the coordinates: a triangle of altitude h at distance
    /// ~1 from the origin has margin h / ε; folded faces are skipped; far from the origin the same
    /// shape has less margin.
    #[test]
    fn precision_margin_measures_altitudes_in_ulps() {
        let mesh = TriMesh {
            positions: vec![[0.0; 3]; 6],
            faces: vec![[0, 1, 2], [3, 5, 4]],
            uvs: None,
        };
        let h = 1e-10;
        let uv = [
            [1.0, 0.0],
            [1.0, 1.0],
            [1.0 - h, 0.5],
            [0.0, 0.0],
            [0.1, 0.0],
            [0.0, 0.1],
        ];
        // face 1 is folded (clockwise), so face 0 decides: altitude h below the edge x = 1
        let (f, margin) = precision_margin(&mesh, &uv).unwrap();
        assert_eq!(f, 0);
        let expect = h / f64::EPSILON;
        assert!((margin - expect).abs() < 0.02 * expect, "{margin} {expect}");
        let far: Vec<[f64; 2]> = uv.iter().map(|p| [p[0] + 1e3, p[1]]).collect();
        let (_, margin_far) = precision_margin(&mesh, &far).unwrap();
        assert!(margin_far < 2e-3 * margin, "{margin_far} {margin}");
    }

    use super::*;

    #[test]
    fn power_of_two_scale_brings_values_into_one_two() {
        let mut x = 3.7e-300;
        while x < 1e300 {
            let (s, e) = power_of_two_scale(x);
            let y = x * s;
            assert!((1.0..2.0).contains(&y), "{x:e} · {s:e} = {y}");
            assert_eq!(s, 2f64.powi(-e));
            x *= 7.3;
        }
        for k in [-1021, -1, 0, 1, 52, 1022] {
            let p = 2f64.powi(k);
            assert_eq!(power_of_two_scale(p), (2f64.powi(-k), k));
            // just below a power of two, where log2 rounds up to k: the bits give k − 1
            let below = f64::from_bits(p.to_bits() - 1);
            assert_eq!(power_of_two_scale(below).1, k - 1);
        }
        // the fallback where 2^-e is not normal
        assert_eq!(power_of_two_scale(f64::MAX), (2f64.powi(-1023), 1023));
        assert_eq!(power_of_two_scale(2f64.powi(-1030)), (2f64.powi(1030), -1030));
    }

    fn tri(p: [[f64; 3]; 3]) -> TriMesh {
        TriMesh::new(p.to_vec(), vec![[0, 1, 2]]).unwrap()
    }

    #[test]
    fn similarity_is_conformal_and_scaled_map_has_known_area_distortion() {
        // right triangle of area 0.5, scaled to area π: s² = 2π
        let m = tri([[0.0, 0.0, 1.0], [1.0, 0.0, 1.0], [0.0, 1.0, 1.0]]);
        // image: rotated by 30° and scaled by 3 → area ratio 9/(2π)
        let (c, s) = (30f64.to_radians().cos(), 30f64.to_radians().sin());
        let uv = vec![[0.0, 0.0], [3.0 * c, 3.0 * s], [-3.0 * s, 3.0 * c]];
        let d = face_distortions(&m, &uv).unwrap();
        assert!(d.quasi_conformal_distortion[0].abs() < 1e-14);
        assert!((d.area_distortion[0] - (9.0 / (2.0 * std::f64::consts::PI)).ln()).abs() < 1e-14);
        assert!(d.angle_distortion[0] < 1e-14);
        assert_eq!(d.orientation[0], 1);
    }

    #[test]
    fn stretch_has_log_ratio_and_mirror_is_flipped() {
        let m = tri([[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0]]);
        let uv = vec![[0.0, 0.0], [4.0, 0.0], [0.0, 1.0]];
        let d = face_distortions(&m, &uv).unwrap();
        assert!((d.quasi_conformal_distortion[0] - 4f64.ln()).abs() < 1e-14);
        let uv = vec![[0.0, 0.0], [0.0, 1.0], [1.0, 0.0]];
        let d = face_distortions(&m, &uv).unwrap();
        assert_eq!(d.orientation[0], -1);
        let s = summarize(&d, &[0.5]);
        assert_eq!(s.num_flipped, 1);
        assert_eq!(s.flipped_area_fraction, 1.0);
    }

    #[test]
    fn tiny_image_keeps_relative_precision() {
        let m = tri([[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0]]);
        let t = 1e-160;
        let off = [3e-158, 1e-158];
        let uv = vec![off, [off[0] + t, off[1]], [off[0], off[1] + t]];
        let d = face_distortions(&m, &uv).unwrap();
        assert_eq!(d.orientation[0], 1);
        // Υ = ln(t²·0.5 / (0.5·2π)) = 2 ln t − ln 2π
        let expect = 2.0 * t.ln() - (2.0 * std::f64::consts::PI).ln();
        assert!(
            (d.area_distortion[0] - expect).abs() < 1e-10,
            "{} vs {expect}",
            d.area_distortion[0]
        );
        assert!(d.quasi_conformal_distortion[0].abs() < 1e-10);
    }

    #[test]
    fn stats_nearest_rank() {
        let v: Vec<f64> = (0..101).map(|i| i as f64).collect();
        let s = Stats::of(&v);
        assert_eq!((s.mean, s.median, s.p95, s.max, s.min), (50.0, 50.0, 95.0, 100.0, 0.0));
        assert_eq!(s.non_finite, 0);
        // a degenerate face's Υ = −∞ and a NaN are left out, and counted
        let s = Stats::of(&[1.0, f64::NEG_INFINITY, 3.0, f64::NAN]);
        assert_eq!((s.mean, s.max, s.min, s.non_finite), (2.0, 3.0, 1.0, 2));
        assert_eq!(Stats::of(&[f64::INFINITY]).non_finite, 1);
    }
}
