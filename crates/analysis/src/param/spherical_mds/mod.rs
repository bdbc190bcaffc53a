//! Texture mapping by spherical multidimensional scaling: a closed genus-0 surface is mapped
//! onto the unit sphere so that great-circle distances reproduce its geodesic distances
//! (A. Elad, Y. Keller & R. Kimmel, "Texture mapping via spherical multi-dimensional
//! scaling", Scale-Space 2005, LNCS 3459).
//!
//! With $g_{ij}$ the geodesic distance of vertices i and j on the surface, the target angles
//! are
//! $$\delta_{ij} = \theta_{max}\,\frac{g_{ij}}{g_{max}},$$
//! $g_{max}$ the largest geodesic distance measured, and the embedding $x_i \in S^2$ minimizes
//! the spherical stress
//! $$\sigma(X) = \sum_{i<j} w_{ij}\,\big(\delta_{ij} - \arccos\langle x_i, x_j\rangle\big)^2 .$$
//! $\theta_{max}$ ([`SphericalMdsParams::max_angle`]) is the angle the surface's diameter is
//! given on S², i.e. it fixes the radius $R = g_{max}/\theta_{max}$ of the sphere the surface
//! is laid on. θ_max = π (the default) sends the two farthest points of the surface to
//! antipodes and is the only value at which a round sphere is embedded isometrically. Above π
//! the sphere is smaller than the diameter asks for: targets beyond π (pairs farther apart
//! than πR) are clamped to π, "as far apart as S² allows", and an elongated surface wraps
//! around S² instead of folding over itself (measured below). Below π the sphere is larger and
//! the closed surface, which must still cover it, is stretched or folded. Elad, Keller &
//! Kimmel choose the sphere for the texture and weight the stress by the texture's content;
//! the form of both choices here, θ_max with clamping and the pair weights
//! $w_{ij} = w_i w_j \delta_{ij}^{-p}$ (`weights`, e.g. an importance map sampled at the
//! vertices, and `distance_power` p; 1 and 0 by default), is ours, not a transcription of
//! the paper's equations.
//!
//! The steps, each in its own function:
//! 1. geodesic distances by the heat method ([`crate::geodesic::HeatGeodesics`], Crane et al.
//!    2013) in place of the paper's fast marching: from k landmark vertices only, k × #V
//!    values, so memory is O(#V · k), never O(#V²);
//! 2. landmarks by farthest-point sampling ([`sampling::farthest_point_sample`]), the coarse
//!    level of the multiresolution;
//! 3. the landmarks' start by spherical classical scaling: for points of S²,
//!    ⟨x_i, x_j⟩ = cos δ_ij, so the three leading eigenvectors of the k × k matrix cos δ,
//!    scaled by √λ and normalized, are exact for a round sphere;
//! 4. spherical SMACOF on the landmarks ([`stress`]: the Guttman step carried to S² by the
//!    exponential map, with step halving so that the stress never rises);
//! 5. every other vertex placed against the fixed landmarks by minimizing its own stress to
//!    them (Gauss–Newton on S², from the position of its nearest landmark);
//! 6. optionally `refine_sweeps` sweeps over all points: the landmarks, one at a time, against
//!    the other landmarks and all placed vertices, then the vertices against the landmarks
//!    again, each a monotone block step on the full landmark × vertex stress;
//! 7. the map is mirrored if it turns the surface inside out (stress cannot tell a reflection),
//!    and faces it folds are counted (exact orientation on S²) and, unless disabled, repaired
//!    in gnomonic charts as in [`crate::sphere_param`] (an addition to the published method;
//!    the folds before the repair are reported).
//!
//! MDS preserves distances, not orientation: nothing in the stress forbids folds, and where the
//! surface's metric is far from a sphere's (long limbs, whose geodesic circles are short) the
//! best-stress embedding folds. Measured (`tests/spherical_mds.rs`, 500 landmarks): a jittered
//! round sphere embeds onto itself with a mean angular error of 4.2e-3, 1.6e-3, 6.9e-4 rad at
//! 162, 642, 2,562 vertices (the heat method's error); an ellipsoid 1:1:1.5 with no fold; an
//! ellipsoid 1:1:2 folded over itself from the classical start (2,559 of 5,120 faces, stress-1
//! 0.219: a local minimum; from the conformal start the iteration ends unfolded at 0.218), and
//! with no fold at θ_max = 270°; TOSCA wolf0 with 40–55 % of its faces folded whatever the start, θ_max
//! or p, which the chart repair cannot undo (`docs/sphere.md`).

pub mod sampling;
pub mod stress;

use std::time::Instant;

use faer::Mat;
use rayon::prelude::*;
use serde::Serialize;
use shapespace_conformal::sphere::quality::orientation_on_sphere;
use shapespace_conformal::{sphere_map, SphereMapParams};
use shapespace_geometry::topology::{classify, MeshClass};
use shapespace_geometry::TriMesh;

use crate::error::AnalysisError;
use crate::geodesic::HeatGeodesics;
use crate::sphere_param::{folded_on_sphere, repair_in_charts, SphereFoldRepairInfo};
use stress::{arc, place_point, point_stress, smacof_on_sphere, StressStage};

/// The largest θ_max accepted (4π: all but the nearest quarter of the diameter is antipodal).
const MAX_ANGLE_LIMIT: f64 = 4.0 * std::f64::consts::PI;

/// Where the landmarks' SMACOF starts.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize)]
#[serde(rename_all = "kebab-case")]
pub enum SphericalMdsStart {
    /// Spherical classical scaling of the landmarks' target angles (module docs, step 3); the
    /// placed vertices start at their nearest landmark.
    #[default]
    Classical,
    /// The conformal sphere map ([`shapespace_conformal::sphere_map`], Möbius-centred), for the
    /// landmarks and the placed vertices alike.
    Conformal,
}

/// Options of [`spherical_mds_map`].
#[derive(Clone, Debug)]
pub struct SphericalMdsParams {
    /// θ_max: the angle (radians, in (0, 4π]) that the largest geodesic distance becomes on S²
    /// (module docs; targets beyond π are clamped to π); default π.
    pub max_angle: f64,
    /// The landmarks' start (default: classical scaling).
    pub start: SphericalMdsStart,
    /// Landmarks embedded first (default 500; all vertices when the mesh has fewer).
    pub landmarks: usize,
    /// Most spherical SMACOF iterations on the landmarks (default 300).
    pub landmark_iterations: usize,
    /// Stop the landmark iteration when one step lowers the stress by less than this,
    /// relative (default 1e-7).
    pub tolerance: f64,
    /// Most Gauss–Newton steps per placed vertex (default 30).
    pub placement_iterations: usize,
    /// Refinement sweeps over all points after the placement (default 0).
    pub refine_sweeps: usize,
    /// p: the pair (i, j) weighs w_i w_j δ_ij^(−p); 0 (the default) is the plain stress, 2
    /// the local emphasis of stress-majorization graph drawing (Gansner, Koren & North 2004).
    pub distance_power: f64,
    /// Per-vertex weights w_i > 0 (#V); the pair (i, j) weighs w_i w_j. `None`: all 1.
    pub weights: Option<Vec<f64>>,
    /// Repair folded faces in charts after the embedding (default true).
    pub fold_repair: bool,
}

impl Default for SphericalMdsParams {
    fn default() -> Self {
        SphericalMdsParams {
            max_angle: std::f64::consts::PI,
            start: SphericalMdsStart::Classical,
            landmarks: 500,
            landmark_iterations: 300,
            tolerance: 1e-7,
            placement_iterations: 30,
            refine_sweeps: 0,
            distance_power: 0.0,
            weights: None,
            fold_repair: true,
        }
    }
}

/// Wall-clock seconds of the stages of [`spherical_mds_map`].
#[derive(Clone, Copy, Debug, Default, Serialize)]
pub struct SphericalMdsTimings {
    /// Heat-method factorizations, landmark sampling and the k × #V distances.
    pub geodesics: f64,
    /// Classical start and SMACOF on the landmarks.
    pub landmarks: f64,
    /// Placement of the other vertices and refinement sweeps.
    pub placement: f64,
    /// Orientation, fold count and repair.
    pub output: f64,
}

/// What [`spherical_mds_map`] did.
#[derive(Clone, Debug, Serialize)]
pub struct SphericalMdsInfo {
    /// θ_max (radians).
    pub max_angle: f64,
    /// The start used.
    pub start: SphericalMdsStart,
    /// Target angles clamped to π (landmark × vertex pairs whose scaled distance passed π).
    pub clamped_targets: usize,
    /// g_max: the largest landmark-to-vertex heat-method distance (mesh units).
    pub max_geodesic: f64,
    /// Landmarks embedded first.
    pub num_landmarks: usize,
    /// SMACOF on the landmarks.
    pub landmark_smacof: StressStage,
    /// Mean and largest Gauss–Newton steps of the placed vertices.
    pub placement_mean_steps: f64,
    pub placement_max_steps: usize,
    /// The landmark × vertex stress (pairs of a landmark and a placed vertex, plus landmark
    /// pairs) after the placement and after each refinement sweep (non-increasing).
    pub full_stress_history: Vec<f64>,
    /// Whether the embedding was mirrored to keep the surface's orientation.
    pub mirrored: bool,
    /// Faces folded on S² by the embedding, before any repair.
    pub flipped_before_repair: usize,
    /// The chart repair, when it ran.
    pub fold_repair: Option<SphereFoldRepairInfo>,
    /// Faces not positively oriented on S² in the returned map (exact test).
    pub num_flipped: usize,
}

/// The result of [`spherical_mds_map`].
#[derive(Clone, Debug)]
pub struct SphericalMdsMap {
    /// Image of each vertex on S², #V.
    pub positions: Vec<[f64; 3]>,
    /// The landmark vertices, in sampling order.
    pub landmarks: Vec<u32>,
    pub info: SphericalMdsInfo,
    pub timings: SphericalMdsTimings,
}

/// The spherical MDS map of the closed genus-0 `mesh` onto the unit sphere (module docs).
///
/// Errors: [`AnalysisError::NotClosedGenusZero`] for any other mesh; parameters out of range
/// (θ_max outside (0, π], no landmarks, weights of the wrong length or not positive); the
/// heat method's factorizations failing (a degenerate face).
pub fn spherical_mds_map(mesh: &TriMesh, params: &SphericalMdsParams) -> Result<SphericalMdsMap, AnalysisError> {
    let class = classify(mesh).map_err(AnalysisError::Mesh)?;
    if class.class != MeshClass::Sphere {
        return Err(AnalysisError::NotClosedGenusZero {
            class: class.class.to_string(),
            reasons: class.reasons,
        });
    }
    let pi = std::f64::consts::PI;
    if !(params.max_angle > 0.0 && params.max_angle <= MAX_ANGLE_LIMIT) {
        return Err(AnalysisError::InvalidInput(format!(
            "spherical MDS: the largest angle must lie in (0, 4π] radians, got {}",
            params.max_angle
        )));
    }
    if params.landmarks < 4 {
        return Err(AnalysisError::InvalidInput(format!(
            "spherical MDS: at least 4 landmarks are needed, got {}",
            params.landmarks
        )));
    }
    let n = mesh.num_vertices();
    let weights = match &params.weights {
        None => vec![1.0; n],
        Some(w) if w.len() != n => {
            return Err(AnalysisError::InvalidInput(format!(
                "spherical MDS: {} weights for {n} vertices",
                w.len()
            )))
        }
        Some(w) => {
            if let Some(v) = w.iter().position(|x| !(*x > 0.0 && x.is_finite())) {
                return Err(AnalysisError::InvalidInput(format!(
                    "spherical MDS: the weight of vertex {v} is {} (must be positive)",
                    w[v]
                )));
            }
            w.clone()
        }
    };

    // 1–2: landmarks and their heat-method distances, vertex-major (#V × k)
    let clock = Instant::now();
    let heat = HeatGeodesics::new(mesh)?;
    let landmarks = sampling::farthest_point_sample(mesh, params.landmarks);
    let k = landmarks.len();
    let mut dist = vec![0.0f64; n * k];
    for (c, chunk) in landmarks.chunks(32).enumerate() {
        for (i, column) in heat.distances(chunk)?.into_iter().enumerate() {
            let l = 32 * c + i;
            for (v, d) in column.into_iter().enumerate() {
                // (the heat method's distances can dip a little below 0 beside the source)
                dist[v * k + l] = d.max(0.0);
            }
        }
    }
    drop(heat);
    let max_geodesic = dist.iter().fold(0.0f64, |m, &d| m.max(d));
    if !(max_geodesic > 0.0 && max_geodesic.is_finite()) {
        return Err(AnalysisError::InvalidInput(format!(
            "spherical MDS: the largest geodesic distance is {max_geodesic}"
        )));
    }
    let scale = params.max_angle / max_geodesic;
    dist.par_iter_mut().for_each(|d| *d *= scale);
    let clamped_targets = dist.iter().filter(|&&d| d > pi).count();
    dist.par_iter_mut().for_each(|d| *d = d.min(pi));
    let delta = dist;
    let mut timings = SphericalMdsTimings {
        geodesics: clock.elapsed().as_secs_f64(),
        ..Default::default()
    };

    // 3–4: the landmarks, symmetrized
    let clock = Instant::now();
    let mut landmark_delta = vec![0.0; k * k];
    for a in 0..k {
        for b in 0..k {
            if a != b {
                let (va, vb) = (landmarks[a] as usize, landmarks[b] as usize);
                landmark_delta[a * k + b] = 0.5 * (delta[vb * k + a] + delta[va * k + b]);
            }
        }
    }
    let power = params.distance_power;
    let landmark_weights: Vec<f64> = landmarks.iter().map(|&v| weights[v as usize]).collect();
    let mut x_landmarks = match params.start {
        SphericalMdsStart::Classical => classical_start(&landmark_delta, k)?,
        SphericalMdsStart::Conformal => Vec::new(),
    };
    let conformal_start = match params.start {
        SphericalMdsStart::Classical => None,
        SphericalMdsStart::Conformal => {
            let c = sphere_map(mesh, &SphereMapParams::default()).map_err(AnalysisError::SphereMap)?;
            x_landmarks = landmarks.iter().map(|&v| c.positions[v as usize]).collect();
            Some(c.positions)
        }
    };
    let landmark_smacof = smacof_on_sphere(
        &landmark_delta,
        &landmark_weights,
        power,
        &mut x_landmarks,
        params.landmark_iterations,
        params.tolerance,
    );
    timings.landmarks = clock.elapsed().as_secs_f64();

    // 5: the other vertices against the landmarks
    let clock = Instant::now();
    let mut is_landmark = vec![usize::MAX; n];
    for (l, &v) in landmarks.iter().enumerate() {
        is_landmark[v as usize] = l;
    }
    let mut positions = vec![[0.0; 3]; n];
    let mut steps = vec![0usize; n];
    let place = |x_landmarks: &[[f64; 3]], positions: &mut [[f64; 3]], steps: &mut [usize], warm: bool| {
        positions
            .par_iter_mut()
            .zip(steps.par_iter_mut())
            .enumerate()
            .filter(|(v, _)| is_landmark[*v] == usize::MAX)
            .for_each(|(v, (p, s))| {
                let row = &delta[v * k..(v + 1) * k];
                let pair_weights: Vec<f64> = (0..k)
                    .map(|l| stress::pair_weight(landmark_weights[l], weights[v], row[l], power))
                    .collect();
                let start = if warm {
                    *p
                } else if let Some(c) = &conformal_start {
                    c[v]
                } else {
                    let nearest = (0..k).min_by(|&a, &b| row[a].total_cmp(&row[b])).unwrap_or(0);
                    x_landmarks[nearest]
                };
                let (x, _, taken) = place_point(
                    start,
                    x_landmarks,
                    row,
                    Some(&pair_weights),
                    params.placement_iterations,
                );
                *p = x;
                *s += taken;
            });
    };
    place(&x_landmarks, &mut positions, &mut steps, false);
    for (l, &v) in landmarks.iter().enumerate() {
        positions[v as usize] = x_landmarks[l];
    }
    let placed = n - k;
    let (placement_mean_steps, placement_max_steps) = if placed > 0 {
        let total: usize = steps.iter().sum();
        (total as f64 / placed as f64, steps.iter().copied().max().unwrap_or(0))
    } else {
        (0.0, 0)
    };
    let full_stress = |positions: &[[f64; 3]], x_landmarks: &[[f64; 3]]| {
        let rows: Vec<f64> = (0..n)
            .into_par_iter()
            .map(|v| {
                if is_landmark[v] != usize::MAX {
                    return 0.0;
                }
                let row = &delta[v * k..(v + 1) * k];
                let pair_weights: Vec<f64> = (0..k)
                    .map(|l| stress::pair_weight(landmark_weights[l], weights[v], row[l], power))
                    .collect();
                point_stress(positions[v], x_landmarks, row, Some(&pair_weights))
            })
            .collect();
        rows.iter().sum::<f64>() + stress::landmark_stress(&landmark_delta, &landmark_weights, power, x_landmarks)
    };
    let mut full_stress_history = vec![full_stress(&positions, &x_landmarks)];

    // 6: refinement sweeps
    for _ in 0..params.refine_sweeps {
        if placed == 0 {
            break;
        }
        for l in 0..k {
            // landmark l against the other landmarks and every placed vertex
            let mut targets = Vec::with_capacity(n);
            let mut row = Vec::with_capacity(n);
            let mut pair_weights = Vec::with_capacity(n);
            for m in (0..k).filter(|&m| m != l) {
                targets.push(x_landmarks[m]);
                row.push(landmark_delta[l * k + m]);
                pair_weights.push(stress::pair_weight(
                    landmark_weights[l],
                    landmark_weights[m],
                    landmark_delta[l * k + m],
                    power,
                ));
            }
            for v in (0..n).filter(|&v| is_landmark[v] == usize::MAX) {
                targets.push(positions[v]);
                row.push(delta[v * k + l]);
                pair_weights.push(stress::pair_weight(
                    landmark_weights[l],
                    weights[v],
                    delta[v * k + l],
                    power,
                ));
            }
            let (x, _, _) = place_point(
                x_landmarks[l],
                &targets,
                &row,
                Some(&pair_weights),
                params.placement_iterations,
            );
            x_landmarks[l] = x;
            positions[landmarks[l] as usize] = x;
        }
        let mut unused = vec![0usize; n];
        place(&x_landmarks, &mut positions, &mut unused, true);
        full_stress_history.push(full_stress(&positions, &x_landmarks));
    }
    timings.placement = clock.elapsed().as_secs_f64();

    // 7: orientation and folds
    let clock = Instant::now();
    let signed: f64 = mesh
        .faces
        .iter()
        .map(|f| {
            let [a, b, c] = f.map(|v| positions[v as usize]);
            stress::dot(a, stress::cross(b, c))
        })
        .sum();
    let mirrored = signed < 0.0;
    if mirrored {
        for p in &mut positions {
            p[2] = -p[2];
        }
    }
    let flipped_before_repair = folded_on_sphere(mesh, &positions).len();
    let fold_repair = (params.fold_repair && flipped_before_repair > 0).then(|| repair_in_charts(mesh, &mut positions));
    let num_flipped = mesh
        .faces
        .iter()
        .filter(|f| {
            let [a, b, c] = f.map(|v| positions[v as usize]);
            orientation_on_sphere(a, b, c) != 1
        })
        .count();
    timings.output = clock.elapsed().as_secs_f64();
    Ok(SphericalMdsMap {
        positions,
        landmarks,
        info: SphericalMdsInfo {
            max_angle: params.max_angle,
            start: params.start,
            clamped_targets,
            max_geodesic,
            num_landmarks: k,
            landmark_smacof,
            placement_mean_steps,
            placement_max_steps,
            full_stress_history,
            mirrored,
            flipped_before_repair,
            fold_repair,
            num_flipped,
        },
        timings,
    })
}

/// The landmarks' start (module docs, step 3): the three leading eigenvectors of cos δ
/// (k × k, row-major), scaled by the square roots of their eigenvalues, rows normalized.
fn classical_start(delta: &[f64], k: usize) -> Result<Vec<[f64; 3]>, AnalysisError> {
    let gram = Mat::<f64>::from_fn(k, k, |a, b| if a == b { 1.0 } else { delta[a * k + b].cos() });
    let evd = gram
        .self_adjoint_eigen(faer::Side::Lower)
        .map_err(|_| AnalysisError::EigenNoConvergence { n: k })?;
    let s = evd.S().column_vector();
    let u = evd.U();
    let top = [k - 1, k - 2, k - 3];
    Ok((0..k)
        .map(|a| {
            let p = top.map(|c| s[c].max(0.0).sqrt() * u[(a, c)]);
            // (a zero row, possible only for a degenerate spectrum, starts at a pole)
            stress::normalized(p).unwrap_or([0.0, 0.0, 1.0])
        })
        .collect())
}

/// The great-circle distance of two points of S² (radians), re-exported for tests.
pub fn great_circle_distance(a: [f64; 3], b: [f64; 3]) -> f64 {
    arc(a, b)
}
