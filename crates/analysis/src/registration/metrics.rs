//! Quality measures of a registration f: S₁ → S₂ [Su et al. 2015, §5.3.2], plus the geodesic
//! error against a ground-truth correspondence.
//!
//! Both surfaces are normalized to the same total area (S₂ is scaled to the area of S₁ for
//! areas; curvatures are taken on both surfaces scaled to area π).
//!
//! * **Flipped area ratio, disk** ([`RegistrationMetrics::flipped_area_ratio`]): the area of
//!   the S₁ triangles t = (a, b, c) whose image (g(φ₁(a)), g(φ₁(b)), g(φ₁(c))) in the disk is
//!   inverted, i.e. has a strictly negative signed area, while the disk orientation is the
//!   counter-clockwise one of φ₁(S₁) (the disk maps preserve the orientation of S₁: their
//!   boundary runs counter-clockwise and unfolded faces have positive signed area), over the
//!   total area of S₁. Not relative to each face of φ₁: an area-preserving map may itself fold a
//!   few faces, and g (with positive weights) tends to unfold them; those are not flips of the
//!   registration. Folds of φ₂ are seen by the 3D measure.
//! * **Flipped area ratio, 3D** ([`RegistrationMetrics::flipped_area_ratio_3d`]): the area of
//!   the S₁ triangles whose image triangle (f(a), f(b), f(c)) in space has a normal with a
//!   negative dot product with the normal of S₂ there: the normal of the face of S₂ that holds
//!   the image of t's centroid (g is linear on t in the disk, so that point is the mean of the
//!   corners' g-images, located in φ₂(S₂)), over the total area. This sees folds of the whole
//!   composition, including those of φ₂. (Vertex normals would not do: at a sharp crease a
//!   face's own normal can point away from its corners' averaged normals, and the identity map
//!   would count as folded.) A refined registration (ZoomOut) is not g: its corners' points
//!   are carried into the disk by φ₂ (their faces' φ₂ images, barycentrically), which is g's
//!   image again for an unrefined one, and the mean of the three is located in φ₂(S₂). An image
//!   triangle with two corners on the same point (a vertex map can collapse faces) has a zero
//!   normal and is not counted: a collapse, not a flip (it shows in the area distortion).
//! * **Curvature difference** per interior vertex v of S₁: max(|c₁|/|c₂|, |c₂|/|c₁|) with c the
//!   signed mean curvature (`shapespace_geometry::curvature::vertex_mean_curvatures`), c₁ at v,
//!   c₂ interpolated at f(v) from the corners of its face. Near-zero curvatures are clamped:
//!   |c| ≥ `curvature_floor` × median |c| of that surface (counted in
//!   [`RegistrationMetrics::curvature_clamped`]). Excluded: boundary vertices of S₁ and
//!   vertices whose image face touches the boundary of S₂ (boundary curvature is not
//!   meaningful).
//! * **Local area distortion** per vertex v of S₁: max(J, 1/J) with J = (area of the image of
//!   v's one-ring on S₂: the 3D triangles (f(a), f(b), f(c)), unsigned) / (one-ring area on S₁),
//!   areas normalized to equal totals.
//! * **Geodesic error** (when the meshes share their vertex order, as the TOSCA pose sets):
//!   for a fixed random subset of vertices v (xorshift-based sampling with a fixed seed), the
//!   geodesic distance on S₂ between f(v) and the true partner v, by the heat method
//!   ([`crate::geodesic`], one heat solve per sampled source, evaluated at f(v) by barycentric
//!   interpolation), divided by √(area of S₂). Reported with the fraction of samples under the
//!   thresholds 0, 0.01, …, 0.25 (the correspondence-benchmark curve). For a target that does
//!   not share the source's triangulation ([`registration_metrics_against`]) the true partner
//!   of v is a given point of S₂ (e.g. carried over by closest point,
//!   [`crate::registration::truth`]) and the heat source is that point.

use serde::Serialize;
use shapespace_geometry::curvature::vertex_mean_curvatures;
use shapespace_geometry::quantities::{face_areas, total_area};
use shapespace_geometry::{Connectivity, TriMesh};

use crate::error::AnalysisError;
use crate::geodesic::HeatGeodesics;
use crate::point_location::PointLocator;
use crate::registration::truth::SurfacePoint;
use crate::registration::Registration;

/// Parameters of [`registration_metrics`].
#[derive(Clone, Debug, PartialEq)]
pub struct MetricParams {
    /// Curvature magnitudes are clamped below this fraction of the surface's median |c|
    /// (default 0.05).
    pub curvature_floor: f64,
    /// Number of sampled vertices for the geodesic error (default 300; all when fewer).
    pub geodesic_samples: usize,
    /// Seed of the sample (default 7).
    pub seed: u64,
    /// Evaluate the geodesic error against the identity correspondence v ↔ v (needs equal
    /// vertex counts; default true, skipped when the counts differ).
    pub ground_truth: bool,
}

impl Default for MetricParams {
    fn default() -> Self {
        MetricParams {
            curvature_floor: 0.05,
            geodesic_samples: 300,
            seed: 7,
            ground_truth: true,
        }
    }
}

/// Mean, median, 95th percentile and maximum of a set of values (NaN when empty).
#[derive(Clone, Copy, Debug, PartialEq, Serialize)]
pub struct ValueSummary {
    /// The finite values summarized.
    pub count: usize,
    /// Values left out because they are not finite (e.g. max(J, 1/J) = ∞ of a collapsed
    /// one-ring).
    pub non_finite: usize,
    pub mean: f64,
    pub median: f64,
    pub p95: f64,
    pub max: f64,
}

impl ValueSummary {
    /// Summary of `values` (non-finite values are left out and counted); percentiles by nearest rank on the
    /// sorted values (median: mean of the two middle values for an even count).
    pub fn of(values: &[f64]) -> Self {
        let mut v: Vec<f64> = values.iter().copied().filter(|x| x.is_finite()).collect();
        let non_finite = values.len() - v.len();
        if v.is_empty() {
            return ValueSummary {
                count: 0,
                non_finite,
                mean: f64::NAN,
                median: f64::NAN,
                p95: f64::NAN,
                max: f64::NAN,
            };
        }
        v.sort_by(f64::total_cmp);
        let n = v.len();
        let median = if n % 2 == 1 {
            v[n / 2]
        } else {
            0.5 * (v[n / 2 - 1] + v[n / 2])
        };
        let rank = ((0.95 * n as f64).ceil() as usize).clamp(1, n) - 1;
        ValueSummary {
            count: n,
            non_finite,
            mean: v.iter().sum::<f64>() / n as f64,
            median,
            p95: v[rank],
            max: v[n - 1],
        }
    }
}

/// Geodesic errors of sampled vertices against the ground truth.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct GeodesicErrors {
    /// The sampled vertices (indices on both surfaces).
    pub samples: Vec<u32>,
    /// d_{S₂}(f(v), v) / √area(S₂) per sample.
    pub errors: Vec<f64>,
    /// Summary of `errors`.
    pub summary: ValueSummary,
    /// Thresholds 0, 0.01, …, 0.25.
    pub thresholds: Vec<f64>,
    /// Fraction of samples with error ≤ each threshold.
    pub fractions: Vec<f64>,
}

/// The measures of the module docs.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct RegistrationMetrics {
    /// Flipped area ratio in the disk (inverted faces of g ∘ φ₁).
    pub flipped_area_ratio: f64,
    /// Number of such flipped faces.
    pub flipped_faces: usize,
    /// Flipped area ratio of the 3D image against the normals of S₂.
    pub flipped_area_ratio_3d: f64,
    /// Number of such flipped faces.
    pub flipped_faces_3d: usize,
    /// Curvature difference per evaluated vertex (see `curvature_vertices`).
    #[serde(skip)]
    pub curvature_difference: Vec<f64>,
    /// The vertices of S₁ where the curvature difference was evaluated.
    #[serde(skip)]
    pub curvature_vertices: Vec<u32>,
    /// Summary of the curvature difference.
    pub curvature_summary: ValueSummary,
    /// Evaluated vertices where c₁ or c₂ was clamped to the floor.
    pub curvature_clamped: usize,
    /// The floors used for |c₁| and |c₂| (surfaces scaled to area π).
    pub curvature_floors: [f64; 2],
    /// Area distortion max(J, 1/J) per vertex of S₁, #V₁.
    #[serde(skip)]
    pub area_distortion: Vec<f64>,
    /// Summary of the area distortion max(J, 1/J): read its median and quantiles; its mean is
    /// dominated by a few collapsed one-rings (1e10 on real pairs) and says little.
    pub area_distortion_summary: ValueSummary,
    /// Summary of |ln J| = ln max(J, 1/J) per vertex: its mean is the meaningful average.
    pub log_area_distortion_summary: ValueSummary,
    /// Geodesic errors (when a ground truth is available).
    pub geodesic: Option<GeodesicErrors>,
    /// Vertices snapped onto φ₂(S₂) during the composition.
    pub num_snapped: usize,
}

fn sub(a: [f64; 3], b: [f64; 3]) -> [f64; 3] {
    [a[0] - b[0], a[1] - b[1], a[2] - b[2]]
}
fn cross(a: [f64; 3], b: [f64; 3]) -> [f64; 3] {
    [
        a[1] * b[2] - a[2] * b[1],
        a[2] * b[0] - a[0] * b[2],
        a[0] * b[1] - a[1] * b[0],
    ]
}
fn dot(a: [f64; 3], b: [f64; 3]) -> f64 {
    a[0] * b[0] + a[1] * b[1] + a[2] * b[2]
}
fn signed_area2(a: [f64; 2], b: [f64; 2], c: [f64; 2]) -> f64 {
    (b[0] - a[0]) * (c[1] - a[1]) - (b[1] - a[1]) * (c[0] - a[0])
}

/// A fixed pseudo-random sample of `k` distinct indices of 0..n (partial Fisher–Yates with a
/// splitmix64 stream seeded by `seed`), sorted. All indices when k ≥ n.
pub fn sample_indices(n: usize, k: usize, seed: u64) -> Vec<u32> {
    let mut idx: Vec<u32> = (0..n as u32).collect();
    if k >= n {
        return idx;
    }
    let mut state = seed;
    let mut next = || {
        state = state.wrapping_add(0x9E37_79B9_7F4A_7C15);
        let mut z = state;
        z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
        z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
        z ^ (z >> 31)
    };
    for i in 0..k {
        let j = i + (next() % (n - i) as u64) as usize;
        idx.swap(i, j);
    }
    let mut out = idx[..k].to_vec();
    out.sort_unstable();
    out
}

/// Evaluates the measures of the module docs for a registration of `source` onto `target`
/// (the geodesic error against v ↔ v when `params.ground_truth` and the vertex counts agree).
/// Errors: the registration does not match the meshes, or the heat method fails on S₂.
pub fn registration_metrics(
    source: &TriMesh,
    target: &TriMesh,
    reg: &Registration,
    params: &MetricParams,
) -> Result<RegistrationMetrics, AnalysisError> {
    registration_metrics_against(source, target, reg, params, None)
}

/// [`registration_metrics`] with the ground truth given as points: `truth[v]` (#V₁ (face of S₂,
/// barycentric coordinates) pairs) is the true partner of source vertex v, whatever the
/// triangulations. `None`: v ↔ v as in [`registration_metrics`]. Errors: also a `truth` of
/// the wrong length or with a face out of range of S₂.
pub fn registration_metrics_against(
    source: &TriMesh,
    target: &TriMesh,
    reg: &Registration,
    params: &MetricParams,
    truth: Option<&[SurfacePoint]>,
) -> Result<RegistrationMetrics, AnalysisError> {
    let n1 = source.num_vertices();
    if reg.points.len() != n1 || reg.harmonic_uv.len() != n1 || reg.source_uv.len() != n1 {
        return Err(AnalysisError::InvalidInput(format!(
            "registration has {} points for {} source vertices",
            reg.points.len(),
            n1
        )));
    }
    let areas1 = face_areas(source);

    // flips
    let locator = PointLocator::new(&reg.target_uv, &target.faces)?;
    let mut flips = FlipCounts::default();
    // φ₂(f(v)): the harmonic image itself, or for a refined map its point mapped by φ₂
    let image_uv: Vec<[f64; 2]> = if reg.refinement.is_some() {
        (0..n1)
            .map(|v| {
                let t = target.faces[reg.faces[v] as usize];
                let mut u = [0.0; 2];
                for k in 0..3 {
                    for d in 0..2 {
                        u[d] += reg.bary[v][k] * reg.target_uv[t[k] as usize][d];
                    }
                }
                u
            })
            .collect()
    } else {
        reg.harmonic_uv.clone()
    };
    for (fi, f) in source.faces.iter().enumerate() {
        let [a, b, c] = [f[0] as usize, f[1] as usize, f[2] as usize];
        let s1 = signed_area2(reg.harmonic_uv[a], reg.harmonic_uv[b], reg.harmonic_uv[c]);
        if s1 < 0.0 {
            flips.faces += 1;
            flips.area += areas1[fi];
        }
        let (ha, hb, hc) = (image_uv[a], image_uv[b], image_uv[c]);
        let centroid = [(ha[0] + hb[0] + hc[0]) / 3.0, (ha[1] + hb[1] + hc[1]) / 3.0];
        let reference = locator.locate(centroid).map(|l| l.face);
        if image_is_flipped(target, [reg.points[a], reg.points[b], reg.points[c]], reference) {
            flips.faces_3d += 1;
            flips.area_3d += areas1[fi];
        }
    }
    surface_metrics(
        source,
        target,
        &reg.faces,
        &reg.bary,
        &reg.points,
        reg.num_snapped,
        flips,
        params,
        truth,
    )
}

/// Flipped faces of a registration and their areas on S₁ (unnormalized), in the parameter
/// domain (disk or sphere) and in 3D: the input of [`surface_metrics`].
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub(crate) struct FlipCounts {
    pub faces: usize,
    pub area: f64,
    pub faces_3d: usize,
    pub area_3d: f64,
}

/// Whether the image triangle `p` (f(a), f(b), f(c)) in space is flipped against the normal of
/// the face `reference` of S₂ (module docs; `None`: no reference, not flipped; a collapsed
/// image has a zero normal and is not flipped).
pub(crate) fn image_is_flipped(target: &TriMesh, p: [[f64; 3]; 3], reference: Option<u32>) -> bool {
    let nimg = cross(sub(p[1], p[0]), sub(p[2], p[0]));
    let nref = reference.map_or([0.0; 3], |fi| {
        let q = target.face_positions(fi as usize);
        cross(sub(q[1], q[0]), sub(q[2], q[0]))
    });
    dot(nimg, nref) < 0.0
}

/// The measures of the module docs that depend only on the map f (per source vertex: the face
/// of S₂ holding f(v), its barycentric coordinates and the 3D point), with the flips counted by
/// the caller in its parameter domain (disk or sphere). Errors: lengths that do not match the
/// meshes, a surface of zero area, a bad `truth`, the heat method failing on S₂.
#[allow(clippy::too_many_arguments)]
pub(crate) fn surface_metrics(
    source: &TriMesh,
    target: &TriMesh,
    faces: &[u32],
    bary: &[[f64; 3]],
    points: &[[f64; 3]],
    num_snapped: usize,
    flips: FlipCounts,
    params: &MetricParams,
    truth: Option<&[SurfacePoint]>,
) -> Result<RegistrationMetrics, AnalysisError> {
    let (a1, a2) = checked_areas(source, target, faces, bary, points, truth)?;
    let area_distortion = local_area_distortion(source, points, a1, a2);
    let curvature = curvature_difference(source, target, faces, bary, a1, a2, params);
    let geodesic = geodesic_errors(target, faces, bary, a2, params, truth)?;
    Ok(RegistrationMetrics {
        flipped_area_ratio: flips.area / a1,
        flipped_faces: flips.faces,
        flipped_area_ratio_3d: flips.area_3d / a1,
        flipped_faces_3d: flips.faces_3d,
        curvature_summary: ValueSummary::of(&curvature.values),
        curvature_difference: curvature.values,
        curvature_vertices: curvature.vertices,
        curvature_clamped: curvature.clamped,
        curvature_floors: curvature.floors,
        area_distortion_summary: ValueSummary::of(&area_distortion),
        log_area_distortion_summary: ValueSummary::of(&area_distortion.iter().map(|a| a.ln()).collect::<Vec<_>>()),
        area_distortion,
        geodesic,
        num_snapped,
    })
}

/// The errors of [`surface_metrics`] on its inputs (a `truth` or a map whose length is not
/// #V₁, an image face out of range, a surface of zero area); the areas of S₁ and S₂.
fn checked_areas(
    source: &TriMesh,
    target: &TriMesh,
    faces: &[u32],
    bary: &[[f64; 3]],
    points: &[[f64; 3]],
    truth: Option<&[SurfacePoint]>,
) -> Result<(f64, f64), AnalysisError> {
    let n1 = source.num_vertices();
    if let Some(t) = truth {
        if t.len() != n1 {
            return Err(AnalysisError::InvalidInput(format!(
                "ground truth has {} points for {} source vertices",
                t.len(),
                n1
            )));
        }
    }
    if points.len() != n1 || faces.len() != n1 || bary.len() != n1 {
        return Err(AnalysisError::InvalidInput(format!(
            "registration has {} points for {} source vertices",
            points.len(),
            n1
        )));
    }
    if let Some(v) = faces.iter().position(|&f| f as usize >= target.faces.len()) {
        return Err(AnalysisError::InvalidInput(format!(
            "the image of source vertex {v} lies on face {} of a target with {} faces",
            faces[v],
            target.faces.len()
        )));
    }
    let a1 = total_area(source);
    let a2 = total_area(target);
    if !(a1 > 0.0 && a2 > 0.0) {
        return Err(AnalysisError::InvalidInput("a surface has zero area".into()));
    }
    Ok((a1, a2))
}

/// Local area distortion per source vertex: max(J, 1/J) of the one-ring's image area (S₂
/// scaled to the area of S₁) over its area; infinite for a collapsed or non-finite ring.
fn local_area_distortion(source: &TriMesh, points: &[[f64; 3]], a1: f64, a2: f64) -> Vec<f64> {
    let n1 = source.num_vertices();
    let areas1 = face_areas(source);
    let mut ring_image = vec![0.0; n1];
    let mut ring_source = vec![0.0; n1];
    for (fi, f) in source.faces.iter().enumerate() {
        let (pa, pb, pc) = (points[f[0] as usize], points[f[1] as usize], points[f[2] as usize]);
        let nimg = cross(sub(pb, pa), sub(pc, pa));
        let img_area = 0.5 * dot(nimg, nimg).sqrt() * (a1 / a2);
        for &v in f {
            ring_image[v as usize] += img_area;
            ring_source[v as usize] += areas1[fi];
        }
    }
    (0..n1)
        .map(|v| {
            let j = ring_image[v] / ring_source[v];
            if j > 0.0 && j.is_finite() {
                j.max(1.0 / j)
            } else {
                f64::INFINITY
            }
        })
        .collect()
}

/// The curvature difference of [`surface_metrics`]: the finite ratios, their source vertices,
/// how many vertices had a curvature under its floor, and the floors of S₁ and S₂.
struct CurvatureDifference {
    values: Vec<f64>,
    vertices: Vec<u32>,
    clamped: usize,
    floors: [f64; 2],
}

/// Curvature difference max(|c1|/|c2|, |c2|/|c1|) per interior source vertex with an interior
/// image face, the surfaces scaled to area π (c ↦ c·√(A/π)) and |c| floored at
/// `params.curvature_floor` times the median |c| over the interior vertices.
fn curvature_difference(
    source: &TriMesh,
    target: &TriMesh,
    faces: &[u32],
    bary: &[[f64; 3]],
    a1: f64,
    a2: f64,
    params: &MetricParams,
) -> CurvatureDifference {
    let n1 = source.num_vertices();
    let k1 = (a1 / std::f64::consts::PI).sqrt();
    let k2 = (a2 / std::f64::consts::PI).sqrt();
    let c1: Vec<f64> = vertex_mean_curvatures(source).iter().map(|c| c * k1).collect();
    let c2: Vec<f64> = vertex_mean_curvatures(target).iter().map(|c| c * k2).collect();
    let b1 = Connectivity::of(source).boundary_vertices(n1);
    let b2 = Connectivity::of(target).boundary_vertices(target.num_vertices());
    let median_abs = |c: &[f64], b: &[bool]| {
        let v: Vec<f64> = c.iter().zip(b).filter(|(_, &bb)| !bb).map(|(x, _)| x.abs()).collect();
        ValueSummary::of(&v).median
    };
    let floors = [
        params.curvature_floor * median_abs(&c1, &b1),
        params.curvature_floor * median_abs(&c2, &b2),
    ];
    let mut values = Vec::new();
    let mut vertices = Vec::new();
    let mut clamped = 0usize;
    for v in 0..n1 {
        let t = target.faces[faces[v] as usize];
        if b1[v] || t.iter().any(|&w| b2[w as usize]) {
            continue;
        }
        let cv2: f64 = (0..3).map(|k| bary[v][k] * c2[t[k] as usize]).sum();
        let (x, y) = (c1[v].abs(), cv2.abs());
        if x < floors[0] || y < floors[1] {
            clamped += 1;
        }
        let (x, y) = (x.max(floors[0]), y.max(floors[1]));
        let r = (x / y).max(y / x);
        if r.is_finite() {
            values.push(r);
            vertices.push(v as u32);
        }
    }
    CurvatureDifference {
        values,
        vertices,
        clamped,
        floors,
    }
}

/// Geodesic error against v ↔ v (same vertex count and `params.ground_truth`), or against the
/// given points `truth`, over √area of S₂ at sampled source vertices; None when neither applies.
fn geodesic_errors(
    target: &TriMesh,
    faces: &[u32],
    bary: &[[f64; 3]],
    a2: f64,
    params: &MetricParams,
    truth: Option<&[SurfacePoint]>,
) -> Result<Option<GeodesicErrors>, AnalysisError> {
    let n1 = faces.len();
    if !(truth.is_some() || (params.ground_truth && n1 == target.num_vertices())) {
        return Ok(None);
    }
    let heat = HeatGeodesics::new(target)?;
    let samples = sample_indices(n1, params.geodesic_samples, params.seed);
    let dist = match truth {
        Some(t) => heat.distances_from_points(&samples.iter().map(|&v| t[v as usize]).collect::<Vec<_>>())?,
        None => heat.distances(&samples)?,
    };
    let norm = a2.sqrt();
    let errors: Vec<f64> = samples
        .iter()
        .zip(&dist)
        .map(|(&v, d)| {
            let t = target.faces[faces[v as usize] as usize];
            let b = bary[v as usize];
            let e: f64 = (0..3).map(|k| b[k] * d[t[k] as usize]).sum();
            e.max(0.0) / norm
        })
        .collect();
    let thresholds: Vec<f64> = (0..=25).map(|k| k as f64 * 0.01).collect();
    let fractions = thresholds
        .iter()
        .map(|&th| errors.iter().filter(|&&e| e <= th).count() as f64 / errors.len().max(1) as f64)
        .collect();
    Ok(Some(GeodesicErrors {
        summary: ValueSummary::of(&errors),
        samples,
        errors,
        thresholds,
        fractions,
    }))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn summary_and_sampling() {
        let s = ValueSummary::of(&[4.0, 1.0, 3.0, 2.0, f64::NAN]);
        assert_eq!((s.count, s.mean, s.median, s.max), (4, 2.5, 2.5, 4.0));
        assert_eq!(s.p95, 4.0);
        let a = sample_indices(1000, 300, 7);
        assert_eq!(a.len(), 300);
        assert!(a.windows(2).all(|w| w[0] < w[1]));
        assert_eq!(a, sample_indices(1000, 300, 7));
        assert_ne!(a, sample_indices(1000, 300, 8));
        assert_eq!(sample_indices(5, 10, 1), vec![0, 1, 2, 3, 4]);
    }
}
