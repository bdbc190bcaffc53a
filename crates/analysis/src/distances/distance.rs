//! Conformal Wasserstein distances between disk-topology surfaces [Su et al. 2015, Algorithm 3].
//!
//! For surfaces M₁, M₂ scaled to area π with conformal maps φ_k onto the unit disk D (interior
//! marker ↦ 0, boundary marker ↦ 1), the source measure is (D, μ₁) with μ₁ the pushed-forward
//! area of M₁ (constant per image triangle: 3D area / 2D area), and the target is the points
//! y_i = φ₂(v_i) with masses ν_i = one third of M₂'s one-ring areas. The squared distance is the
//! optimal semi-discrete transport cost (Eq. 19)
//! $$ W_2^2(M_1, M_2) = \sum_i \int_{W_i} |x - y_i|^2 \, d\mu_1(x). $$
//! The discretization is not symmetric in (M₁, M₂); the asymmetry |d(1→2) − d(2→1)| is reported
//! as an accuracy diagnostic and the mean of both directions is available.
//!
//! Per-shape work (conformal map, density, points, masses) is done once per shape
//! ([`prepare_shape`]); the pairs reuse it. Each pair starts cold by default: the solver's
//! coarse-to-fine start (taken automatically for these densities) needs 6–10 steps at the finest
//! level (measured on 30 pairs of bundled faces), the previous pair's heights 16–32
//! (`docs/decisions/0016-pairwise-scheduling.md`).
//! With [`PairwiseOptions::warm_start`] the pairs that share a target are solved in a fixed order,
//! each warm-started from the previous one's heights; either way the results do not depend on
//! the number of threads.

use std::collections::HashMap;
use std::sync::atomic::{AtomicUsize, Ordering};
use std::sync::Arc;
use std::time::Instant;

use serde::{Deserialize, Serialize};
use shapespace_conformal::{disk_map, DiskMap, DiskMapParams, Markers};
use shapespace_geometry::quantities::vertex_dual_areas;
use shapespace_geometry::topology::{find, union};
use shapespace_geometry::TriMesh;
use shapespace_omt::linear::LinearSolver;
use shapespace_omt::newton::{TargetCoarsening, RETRY_CONTINUATION};
use shapespace_omt::peaks::{spread_density_peaks, PeakSpreading};
use shapespace_omt::{
    solve_ot_prepared, NewtonParams, OtSolution, PreparedMeasure, SourceMeasure, StartStrategy, StopReason,
};

use crate::error::AnalysisError;
use crate::invariance::{rotation_invariant_distance, Invariance};
use crate::sphere_distance::{directed_sphere_distance, PreparedSphere, SphereAlignment};
use shapespace_conformal::SphereNormalization;
use shapespace_omt::sphere::SphereOtParams;

/// A surface ready for distance computations: its conformal disk map, the pushed-forward
/// density on the disk (as a source measure) and the target points and masses.
#[derive(Clone, Debug)]
pub struct PreparedShape {
    /// Display name (usually the file stem).
    pub name: String,
    /// The conformal map onto the unit disk (area normalized to π).
    pub disk: DiskMap,
    /// (D, μ): the image triangulation with per-face densities 3D area / 2D area, density
    /// peaks above [`DENSITY_PEAK_RATIO`] × the median spread over small patches
    /// ([`shapespace_omt::peaks::spread_density_peaks`]; what it did is `peak_spreading`).
    /// Prepared: the solver's averaged copies of it are built once and serve every pair.
    pub measure: PreparedMeasure,
    /// What the spreading of the density peaks changed (nothing on the bundled faces).
    pub peak_spreading: PeakSpreading,
    /// Target points y_i = φ(v_i), #V.
    pub points: Vec<[f64; 2]>,
    /// Target masses ν_i: one third of the one-ring areas after scaling to area π, #V.
    pub masses: Vec<f64>,
    /// The coarsening hierarchy of (`points`, `masses`) for the solver's coarse-to-fine start,
    /// built once here and shared by every solve with this shape as target
    /// ([`NewtonParams::target_coarsening`]; without it a solve coarsens the target itself,
    /// with the same result up to rounding).
    pub coarsening: Arc<TargetCoarsening>,
    /// Seconds spent preparing.
    pub seconds: f64,
    /// 0, or after [`quantize_target`] the within-group variance Σ_i ν_i |y_i − c_g(i)|² of the
    /// quantization (the transport cost of the grouping, an upper bound on W₂² between the
    /// full and the quantized target). Without `quantization_moments` (coincident points
    /// merged by [`prepare_shape`]) it is subtracted from the costs to this target.
    pub quantization_variance: f64,
    /// Empty, or after [`quantize_target`] the groups' second moments about their means
    /// S_g = Σ_{i∈g} ν_i (y_i − c_g)(y_i − c_g)ᵀ as [S_xx, S_xy, S_yy] (#points): the costs to
    /// this target then take the second-order correction
    /// ([`shapespace_omt::quantization::quantization_correction`]; [`Self::quantization_correction`]).
    pub quantization_moments: Vec<[f64; 3]>,
}

impl PreparedShape {
    /// What to add to the cost (and the dual value) of `solution`, a solve towards this
    /// shape's points rotated by `theta` (radians, counter-clockwise), for the cost towards
    /// its full target: 0 for a target that was neither quantized nor merged; after
    /// [`quantize_target`] the second-order estimate s·(V − 2 Σ_g tr(A_g S_g)) of
    /// [`shapespace_omt::quantization::quantization_correction`] (the moments rotated with the
    /// points); after a merge of coincident points only −V.
    pub fn quantization_correction(&self, solution: &OtSolution, theta: f64) -> f64 {
        if self.quantization_moments.is_empty() {
            return -self.quantization_variance;
        }
        let points = crate::invariance::rotate(&self.points, theta);
        let moments = rotate_moments(&self.quantization_moments, theta);
        shapespace_omt::quantization::quantization_correction(solution, &points, &moments)
    }
}

/// Second moments [S_xx, S_xy, S_yy] of point sets rotated by `theta`: R S Rᵀ (unchanged at 0).
fn rotate_moments(moments: &[[f64; 3]], theta: f64) -> Vec<[f64; 3]> {
    if theta == 0.0 {
        return moments.to_vec();
    }
    let (sin, cos) = theta.sin_cos();
    moments
        .iter()
        .map(|&[xx, xy, yy]| {
            [
                cos * cos * xx - 2.0 * cos * sin * xy + sin * sin * yy,
                cos * sin * (xx - yy) + (cos * cos - sin * sin) * xy,
                sin * sin * xx + 2.0 * cos * sin * xy + cos * cos * yy,
            ]
        })
        .collect()
}

/// Densities above this many times the median of a shape's pushed-forward density are spread
/// over small patches, keeping every patch's mass ([`shapespace_omt::peaks`]). Measured
/// (`examples/scan_probe.rs`): the BFF maps of the facefuns composite scans (30k vertices) crush
/// 14–17 rim faces to 1e4–1e10 times the median density (together 2e-4 of the mass); spread,
/// their pairs take 15/19/11 finest Newton steps instead of 26/25/13 and the costs move by
/// ≤ 1e-4 relative. The bundled faces' densities stay below 6e3 × the median and are not
/// touched: a lower ratio would flatten their real density variation (at 1e2: 6–10 → 9–19 steps).
pub const DENSITY_PEAK_RATIO: f64 = 1e4;

/// Conformal map, density and target data of one surface (scaled to area π internally).
pub fn prepare_shape(
    name: &str,
    mesh: &TriMesh,
    markers: &Markers,
    params: &DiskMapParams,
) -> Result<PreparedShape, AnalysisError> {
    let start = Instant::now();
    let disk = disk_map(mesh, markers, params).map_err(|e| AnalysisError::Shape {
        name: name.to_string(),
        message: e.to_string(),
    })?;
    let measure =
        SourceMeasure::new(disk.uv.clone(), mesh.faces.clone(), disk.face_densities.clone()).map_err(|e| {
            AnalysisError::Shape {
                name: name.to_string(),
                message: format!("pushed-forward density: {e}"),
            }
        })?;
    let (measure, peak_spreading) =
        spread_density_peaks(&measure, DENSITY_PEAK_RATIO).map_err(|e| AnalysisError::Shape {
            name: name.to_string(),
            message: format!("pushed-forward density: {e}"),
        })?;
    let scale2 = disk.scale * disk.scale;
    let masses: Vec<f64> = vertex_dual_areas(mesh).iter().map(|a| a * scale2).collect();
    if let Some(i) = masses.iter().position(|&m| !(m > 0.0 && m.is_finite())) {
        return Err(AnalysisError::Shape {
            name: name.to_string(),
            message: format!("vertex {i} has no incident area (unreferenced vertex or degenerate one-ring): remove unreferenced vertices first"),
        });
    }
    let (points, masses, quantization_variance) = merge_coincident_points(&disk.uv, masses, COINCIDENT_POINTS);
    let coarsening = Arc::new(TargetCoarsening::new(&points, &masses));
    Ok(PreparedShape {
        name: name.to_string(),
        points,
        disk,
        measure: PreparedMeasure::new(measure),
        peak_spreading,
        masses,
        coarsening,
        seconds: start.elapsed().as_secs_f64(),
        quantization_variance,
        quantization_moments: Vec::new(),
    })
}

/// Target points closer than this (in the unit disk) are merged into one point with their
/// summed mass ([`merge_coincident_points`]). The conformal maps of the Sumner face poses crush
/// the creases of their closed mouths so far that vertices land 1e-16 apart; a power diagram
/// cannot give such points cells of their masses (the Newton solve stalls), while merging them
/// changes the cost by their within-group variance, below 1e-24 here.
pub const COINCIDENT_POINTS: f64 = 1e-12;

/// Points within `radius` of each other (transitively) become one point at their mass-weighted
/// mean carrying their summed mass; returns the points, the masses and the merge's own cost
/// Σ_i ν_i |y_i − c_g(i)|² (the quantization variance subtracted from costs, as for
/// [`quantize_target`]). Without such points the input comes back unchanged (variance 0).
pub fn merge_coincident_points(points: &[[f64; 2]], masses: Vec<f64>, radius: f64) -> (Vec<[f64; 2]>, Vec<f64>, f64) {
    use std::collections::HashMap;
    let cell = |p: [f64; 2]| ((p[0] / radius).floor() as i64, (p[1] / radius).floor() as i64);
    let mut grid: HashMap<(i64, i64), Vec<usize>> = HashMap::new();
    for (i, &p) in points.iter().enumerate() {
        grid.entry(cell(p)).or_default().push(i);
    }
    let mut parent: Vec<u32> = (0..points.len() as u32).collect();
    let mut merged = false;
    for (i, &p) in points.iter().enumerate() {
        let (cx, cy) = cell(p);
        for dx in -1..=1 {
            for dy in -1..=1 {
                let Some(others) = grid.get(&(cx + dx, cy + dy)) else {
                    continue;
                };
                for &j in others {
                    if j > i && (points[j][0] - p[0]).hypot(points[j][1] - p[1]) < radius {
                        merged |= union(&mut parent, i as u32, j as u32);
                    }
                }
            }
        }
    }
    if !merged {
        return (points.to_vec(), masses, 0.0);
    }
    let mut group_of = vec![usize::MAX; points.len()];
    let (mut sums, mut group_masses): (Vec<[f64; 2]>, Vec<f64>) = (Vec::new(), Vec::new());
    for i in 0..points.len() {
        let r = find(&mut parent, i as u32) as usize;
        if group_of[r] == usize::MAX {
            group_of[r] = sums.len();
            sums.push([0.0, 0.0]);
            group_masses.push(0.0);
        }
        let g = group_of[r];
        group_of[i] = g;
        sums[g][0] += masses[i] * points[i][0];
        sums[g][1] += masses[i] * points[i][1];
        group_masses[g] += masses[i];
    }
    let centers: Vec<[f64; 2]> = sums
        .iter()
        .zip(&group_masses)
        .map(|(s, &m)| [s[0] / m, s[1] / m])
        .collect();
    let variance = grouping_cost(points, &masses, &group_of, &centers);
    (centers, group_masses, variance)
}

/// The transport cost of a grouping of weighted points onto the groups' points,
/// Σ_i ν_i |y_i − c_group(i)|²: what a quantized or merged target subtracts from its costs.
fn grouping_cost(points: &[[f64; 2]], masses: &[f64], group: &[usize], centers: &[[f64; 2]]) -> f64 {
    group
        .iter()
        .enumerate()
        .map(|(i, &g)| {
            let (y, c) = (points[i], centers[g]);
            masses[i] * ((y[0] - c[0]).powi(2) + (y[1] - c[1]).powi(2))
        })
        .sum()
}

/// The shape with its target measure (points and masses) quantized to at most `target_points`
/// points by mass-weighted k-means in the disk ([`shapespace_omt::quantization::quantize`]:
/// total mass and mean kept); its coarsening hierarchy is rebuilt for the new points. The source
/// side (the density) is unchanged. A shape with at most that many points is returned as is.
///
/// The cost to the quantized points exceeds the cost to the full target by about the grouping's
/// own cost V = Σ_i ν_i |y_i − c_g(i)|² (`quantization_variance`; W₂²(ν, ν_q) ≤ V), which on
/// face pairs is of the order of the cost itself. The shape keeps the groups' second moments
/// (`quantization_moments`), and the costs to it take the second-order correction
/// ([`PreparedShape::quantization_correction`]) instead of −V. The error that remains is
/// measured in docs/benchmarks.md ("Scans").
pub fn quantize_target(mut shape: PreparedShape, target_points: usize) -> PreparedShape {
    if shape.points.len() <= target_points {
        return shape;
    }
    let q = shapespace_omt::quantization::quantize(&shape.points, &shape.masses, target_points);
    // (the grouping's cost is the sum of the moments' traces)
    shape.quantization_variance = q.moments.iter().map(|s| s[0] + s[2]).sum();
    shape.quantization_moments = q.moments;
    shape.coarsening = Arc::new(TargetCoarsening::new(&q.points, &q.masses));
    shape.points = q.points;
    shape.masses = q.masses;
    shape
}

/// The shape with its source measure (the pushed-forward density) averaged over a coarser
/// triangulation of at most `source_faces` triangles: the Delaunay triangulation of a stratified
/// sample of the disk image's vertices plus its hull, each coarse triangle carrying exactly the
/// mass the full density gives it ([`shapespace_omt::averaging::averaged_measure`], the measure
/// the solver's coarse levels use). The target side (points and masses) is unchanged. A shape
/// with at most that many triangles is returned as is.
///
/// Every directed cost from this shape then integrates the averaged density: the finest level's
/// integration gets cheaper in proportion (the diagram and the linear algebra, which scale with
/// the target's points, do not). Averaging moves mass only within coarse triangles, so with h
/// their largest diameter W₂(μ, μ̄) ≤ h and, by the triangle inequality, the distance moves by
/// at most h and the cost by at most h·(2·W₂(μ, ν) + h); the error measured on scans is in the
/// docs/benchmarks.md ("Scans").
///
/// Fails, naming the shape, when the hull alone needs more triangles than asked for (every
/// hull vertex stays, so the disk keeps its boundary) or when the overlay of the two
/// triangulations fails its area check.
pub fn coarsen_source(mut shape: PreparedShape, source_faces: usize) -> Result<PreparedShape, AnalysisError> {
    let faces = shape.measure.triangles.len();
    if faces <= source_faces {
        return Ok(shape);
    }
    let fail = |message: String| AnalysisError::Shape {
        name: shape.name.clone(),
        message,
    };
    // The averaged triangulation has 2·v − 2 − h triangles for its v vertices, h of them on the
    // hull (all of them kept): start from the sample that would give `source_faces` without
    // the hull, then correct by the excess (a sampled vertex on the hull counts once, so at
    // most a few rounds).
    let mut sample = source_faces / 2;
    loop {
        if sample < 3 {
            return Err(fail(format!(
                "the source density cannot be averaged to {source_faces} triangles: the disk's boundary alone needs more (ask for more source faces)"
            )));
        }
        let Some(averaged) = shapespace_omt::averaging::averaged_measure_evenly(&shape.measure, sample) else {
            return Err(fail(format!(
                "the source density could not be averaged to {source_faces} triangles (the overlay of the two triangulations failed its area check); run without source coarsening"
            )));
        };
        let got = averaged.triangles.len();
        if got <= source_faces {
            shape.measure = PreparedMeasure::new(averaged);
            return Ok(shape);
        }
        sample -= (got - source_faces).div_ceil(2).min(sample);
    }
}

/// The outcome of one directed computation source → target.
#[derive(Clone, Debug, Serialize)]
pub struct DirectedDistance {
    /// Transport cost W₂² (Eq. 19).
    pub cost: f64,
    /// The Kantorovich dual value at the solution (`OtSolution::dual_value`): a lower bound on
    /// the exact cost, second-order accurate in the mass residual; its gap to `cost` is an
    /// a-posteriori check of the cost.
    pub dual_cost: f64,
    /// √cost.
    pub distance: f64,
    /// Newton iterations (all levels of a coarse-to-fine start, all stages of a continuation).
    pub iterations: usize,
    /// max_i |μ(W_i) − ν_i| / ν_i at the end.
    pub max_mass_error: f64,
    /// Seconds.
    pub seconds: f64,
    /// "converged" or the reason it stopped.
    pub status: String,
    /// Whether the tolerance was reached.
    pub converged: bool,
    /// Cell evaluations (power diagram + restricted integration), including line-search trials.
    pub evaluations: usize,
}

/// The debiased squared distance max(0, c(a, b) − c(b, b)) and whether it was clamped at 0.
///
/// The directed cost c(a, b) from a's density to b's vertex masses carries b's quantization:
/// even c(b, b), b's density against its own points, is O(h²) above 0 (the self-distance floor).
/// Subtracting the target's own floor removes most of it: hemisphere against flat disk, where
/// W₂² is known in closed form, the relative error goes from 1.0e-2 to 2.0e-4 (cap 20 rings, disk
/// 40) and from 1.5e-1 to 1.1e-2 (cap 40, disk 10), while the symmetric form
/// c(a, b) − (c(a, a) + c(b, b))/2 misses by 1.6e-2 and 6.6e-2 there (the test
/// `debiasing_by_the_targets_self_cost_approaches_the_closed_form`). A clamp means the two shapes are
/// within the target's resolution of each other.
pub fn debiased_cost(cost: f64, target_self_cost: f64) -> (f64, bool) {
    let d = cost - target_self_cost;
    if d < 0.0 {
        (0.0, true)
    } else {
        (d, false)
    }
}

/// Solves the semi-discrete OT from `source`'s density to `target`'s points and masses.
/// Returns the directed distance and the final heights (for warm starts).
///
/// Strategy (measured on the bundled faces, density contrast ~6·10⁴): the damped Newton method
/// from the given warm heights or, without them, from the solver's start (`StartStrategy::Auto`
/// takes the coarse-to-fine start for this contrast: 6–10 steps at the finest level, 0.3–0.9 s),
/// without density continuation; continuation (`NewtonParams::density_continuation`) takes 3–5×
/// longer on these inputs, so it is only the fallback when the direct solve does not converge or
/// cannot start. The fallback restarts from the Voronoi start with continuation (ratio
/// [`RETRY_CONTINUATION`], 10, if `params` has none); its iterations are added to the count.
pub fn directed_distance(
    source: &PreparedShape,
    target: &PreparedShape,
    params: &NewtonParams,
) -> Result<(DirectedDistance, Vec<f64>), AnalysisError> {
    let start = Instant::now();
    let pair_error = |e: shapespace_omt::OmtError| AnalysisError::Pair {
        a: source.name.clone(),
        b: target.name.clone(),
        message: e.to_string(),
    };
    let direct_params = NewtonParams {
        density_continuation: None,
        target_coarsening: Some(target.coarsening.clone()),
        ..params.clone()
    };
    // Past the deadline a solve that stopped for another reason is reported as stopped by it
    // (without the limit the fallback would have run), and no further attempt is made.
    // (an error that is the deadline says so itself: "time limit: the deadline passed while ...")
    let timed_out = |e: shapespace_omt::OmtError, what: &str, after: String| AnalysisError::Pair {
        a: source.name.clone(),
        b: target.name.clone(),
        message: match e {
            shapespace_omt::OmtError::TimeLimit(_) => format!("{e}{after}"),
            e => format!("time limit ({what} stopped: {e}){after}"),
        },
    };
    let direct = solve_ot_prepared(&source.measure, &target.points, &target.masses, &direct_params);
    let (mut solution, mut note) = match direct {
        Ok(solution) if solution.converged() => (solution, String::new()),
        Ok(solution) if params.past_deadline() => (solution, String::new()),
        Err(e) if params.past_deadline() => return Err(timed_out(e, "the direct solve", String::new())),
        first => {
            let (first_iterations, first_evaluations, why) = match &first {
                Ok(s) => (s.iterations, s.evaluations, s.stop_description()),
                Err(e) => (0, 0, e.to_string()),
            };
            let fallback_params = NewtonParams {
                initial_heights: None,
                start_strategy: StartStrategy::Voronoi,
                density_continuation: params.density_continuation.or(Some(RETRY_CONTINUATION)),
                ..params.clone()
            };
            let mut solution = solve_ot_prepared(&source.measure, &target.points, &target.masses, &fallback_params)
                .map_err(|e| match params.past_deadline() {
                    true => timed_out(
                        e,
                        "the fallback",
                        format!(" (after a direct solve that stopped: {why})"),
                    ),
                    false => pair_error(e),
                })?;
            solution.iterations += first_iterations;
            solution.evaluations += first_evaluations;
            (solution, format!(" (after a direct solve that stopped: {why})"))
        }
    };
    if !solution.converged() && params.past_deadline() && solution.stop != StopReason::TimeLimit {
        // (what stopped it is kept: "time limit (stopped: ...) ...")
        note = format!(" (stopped: {}){note}", solution.stop_description());
        solution.stop = StopReason::TimeLimit;
        solution.diagnosis = None;
    }
    let converged = solution.converged();
    // (a quantized target: the cost to its groups' means, corrected to the full target)
    let correction = target.quantization_correction(&solution, 0.0);
    let cost = solution.cost + correction;
    let result = DirectedDistance {
        cost,
        dual_cost: solution.dual_value() + correction,
        distance: cost.max(0.0).sqrt(),
        iterations: solution.all_iterations(),
        max_mass_error: solution.max_relative_error,
        seconds: start.elapsed().as_secs_f64(),
        status: format!("{}{note}", solution.stop_description()),
        converged,
        evaluations: solution.evaluations,
    };
    Ok((result, solution.heights))
}

/// Options of a pairwise run.
#[derive(Clone, Debug)]
pub struct PairwiseOptions {
    /// Compute both directions and report their mean (and the asymmetry).
    pub symmetrize: bool,
    /// Newton parameters (tolerance, caps). Default: `NewtonParams::default()` with
    /// - `tolerance` 1e-4 on the relative cell-mass error (the solver's default is 1e-6). The
    ///   cost of Eq. 19 is off at first order in the mass residual, so this is what sets the
    ///   distances' accuracy: on 30 ordered face pairs, against solves to 1e-11, the cost is within
    ///   7.6e-9 relative at 1e-4 and 5.4e-11 at 1e-6, for 221 instead of 234 finest-level steps;
    ///   on the 780 pairs of the demo the distances agree with those at 1e-6 to 2.1e-8 (`docs/decisions/
    ///   0008-distance-tolerance-and-dual-check.md`). Each pair's dual value
    ///   ([`DirectedDistance::dual_cost`]) measures that error a posteriori.
    /// - `LinearSolver::CholeskyReusedOrdering` (~30 % cheaper linear solves on face pairs,
    ///   measured when the plain `Cholesky` still factorized them simplicially; see its docs).
    /// - `coarse_tolerance` 1e-1 (measured on 60 face pairs: the same 444 finest-level steps and
    ///   663 evaluations as with 1e-3, and 1,314 coarse steps instead of 1,590; on 435 pairs
    ///   8,990 steps over all levels instead of 10,102, distances equal to 1e-10 relative: both
    ///   solutions met the 1e-6 mass tolerance then in force).
    ///
    /// (`flux_masses` stays off: 7 % fewer instructions on face pairs, but slower in wall time,
    /// `docs/decisions/0010-restricted-integration.md`.)
    pub newton: NewtonParams,
    /// Warm-start each pair from the previous pair with the same target (default false: slower
    /// than the solver's coarse-to-fine start on the bundled faces).
    pub warm_start: bool,
    /// Give up a directed pair (status `time limit ...`, no distance) at its first Newton step
    /// that would begin this long after the pair started ([`NewtonParams::deadline`]; the
    /// fallback is not tried then). Pairs that finish within it are exactly those without it
    /// (with `warm_start`, only up to the first pair given up in each target's group: the pairs
    /// after it start from other heights); which pairs reach it depends on the machine.
    /// Default `None`.
    pub time_limit: Option<std::time::Duration>,
    /// Minimize each directed cost over rotations of the target's disk
    /// ([`crate::invariance`]; default: the markers' alignment).
    pub invariance: Invariance,
    /// Report debiased distances in the matrix: √max(0, c(a, b) − c(b, b)) with c(b, b) the
    /// target's self-cost, computed once per shape ([`debiased_cost`]; default false).
    /// `pairs` keep the raw costs.
    pub debias: bool,
}

impl Default for PairwiseOptions {
    fn default() -> Self {
        PairwiseOptions {
            symmetrize: false,
            newton: NewtonParams {
                tolerance: 1e-4,
                linear_solver: LinearSolver::CholeskyReusedOrdering,
                coarse_tolerance: 1e-1,
                ..NewtonParams::default()
            },
            warm_start: false,
            time_limit: None,
            invariance: Invariance::Fixed,
            debias: false,
        }
    }
}

/// One row of `pairs.csv` (read back by `pipeline::run_distances`' `resume`; the index fields
/// are not in the file).
#[derive(Clone, Debug, Serialize, Deserialize)]
pub struct PairRecord {
    pub a: String,
    pub b: String,
    /// Index of the source shape (the density side) and the target shape (the points side).
    #[serde(skip)]
    pub source: usize,
    #[serde(skip)]
    pub target: usize,
    pub distance: f64,
    pub cost: f64,
    pub iterations: usize,
    pub max_mass_error: f64,
    pub seconds: f64,
    pub status: String,
    /// Cell evaluations (diagram + integration) of the solve, line-search trials included.
    pub evaluations: usize,
    /// The Kantorovich dual value at the solution ([`DirectedDistance::dual_cost`]); NaN where
    /// the pair did not converge (like `distance`: the last iterate of a density continuation
    /// that gave up belongs to another density).
    pub dual_cost: f64,
}

/// The result of a pairwise run over n shapes.
#[derive(Clone, Debug)]
pub struct PairwiseResult {
    /// Names, n.
    pub names: Vec<String>,
    /// n × n matrix (row-major): the distance reported for each unordered pair (the mean of
    /// both directions with `symmetrize`); NaN where the pair failed; 0 on the diagonal.
    pub matrix: Vec<f64>,
    /// Every directed computation, in a fixed order (by target, then source).
    pub pairs: Vec<PairRecord>,
    /// Relative asymmetry |d(a→b) − d(b→a)| / mean, per unordered pair (only with `symmetrize`).
    pub asymmetries: Vec<f64>,
    /// Seconds spent in the pairs computed (sum over pairs, not wall time; known pairs of
    /// [`pairwise_distances_resuming`] not included).
    pub pair_seconds: f64,
    /// With [`PairwiseOptions::debias`]: each shape's self-cost c(s, s), n.
    pub self_costs: Option<Vec<f64>>,
    /// With [`PairwiseOptions::debias`]: directed pairs whose debiased cost was clamped at 0.
    pub debias_clamped: usize,
}

/// All pairwise distances among prepared shapes (`None` entries are shapes that failed to
/// prepare; their rows and columns are NaN).
///
/// Without `symmetrize`, the pair {i, j} (i < j) is computed as i → j (source i, target j);
/// with it, both directions. Every pair is independent (cold start) and the pairs run in
/// parallel one by one, so the two threads stay busy to the end (grouped by target, the groups
/// hold 1 … n − 1 pairs and the last large group ran alone); with `warm_start` the pairs of a
/// target run sequentially in a fixed order (each warm-started from the previous one), the
/// groups in parallel, largest first. Either way the result is the same for any number of
/// threads, and `pairs` is in the fixed order by target, then source. `progress` is called once
/// per finished directed pair, with its record, as it finishes (the order of completion, which
/// depends on the threads).
pub fn pairwise_distances<S: PairShape>(
    shapes: &[Option<S>],
    options: &PairwiseOptions,
    progress: &(dyn Fn(&PairRecord) + Sync),
) -> PairwiseResult {
    let go_on = std::sync::atomic::AtomicBool::new(false);
    pairwise_distances_resuming(shapes, options, &HashMap::new(), &go_on, progress)
}

/// The directed pairs (source, target) a pairwise run over n shapes computes, by target, then
/// source: s → t for s < t, and with `symmetrize` also s → t for s > t.
pub fn directed_pairs(n: usize, symmetrize: bool) -> impl Iterator<Item = (usize, usize)> {
    (0..n).flat_map(move |t| {
        (0..n)
            .filter(move |&s| s != t && (symmetrize || s < t))
            .map(move |s| (s, t))
    })
}

/// [`pairwise_distances`], taking the directed pairs (source, target) in `known` from there
/// instead of computing them (the records of an earlier run, see `pipeline::run_distances`'
/// `resume`): their records are used as they are (index fields set to the pair), `progress` is
/// not called for them and their seconds are not in [`PairwiseResult::pair_seconds`]. With
/// `warm_start` a known pair passes no heights on, so the pairs after it start as a group's
/// first does. Once `stop` is set (by `progress`, say, when the pairs can no longer be saved),
/// no further pair starts: the pairs not yet begun get a failed record (`failed: not
/// computed: the run was stopped`) and no `progress` call; the pairs under way finish.
pub fn pairwise_distances_resuming<S: PairShape>(
    shapes: &[Option<S>],
    options: &PairwiseOptions,
    known: &HashMap<(usize, usize), PairRecord>,
    stop: &std::sync::atomic::AtomicBool,
    progress: &(dyn Fn(&PairRecord) + Sync),
) -> PairwiseResult {
    pairwise_distances_of(shapes, options, None, known, stop, progress)
}

/// [`pairwise_distances_resuming`] over the directed pairs of `only` (all of
/// [`directed_pairs`] when None; the others are neither computed nor recorded, and their matrix
/// cells are NaN): a shard or a tile of a pairwise run. The pairs that are computed give the
/// same records as in a run over all pairs. With `debias`, the self-costs are those of every
/// shape.
pub fn pairwise_distances_of<S: PairShape>(
    shapes: &[Option<S>],
    options: &PairwiseOptions,
    only: Option<&std::collections::HashSet<(usize, usize)>>,
    known: &HashMap<(usize, usize), PairRecord>,
    stop: &std::sync::atomic::AtomicBool,
    progress: &(dyn Fn(&PairRecord) + Sync),
) -> PairwiseResult {
    let n = shapes.len();
    let names: Vec<String> = shapes
        .iter()
        .enumerate()
        .map(|(i, s)| {
            s.as_ref()
                .map(|s| s.shape_name().to_string())
                .unwrap_or_else(|| format!("#{i}"))
        })
        .collect();
    let mut groups: Vec<(usize, Vec<usize>)> = Vec::new();
    for (s, t) in directed_pairs(n, options.symmetrize).filter(|pair| only.is_none_or(|o| o.contains(pair))) {
        match groups.last_mut() {
            Some((last, sources)) if *last == t => sources.push(s),
            _ => groups.push((t, vec![s])),
        }
    }
    // One directed pair, optionally warm-started; returns the record and the heights to pass on.
    let run = |s: usize, t: usize, warm: Option<Vec<f64>>| -> (PairRecord, Option<Vec<f64>>) {
        if let Some(record) = known.get(&(s, t)) {
            let record = PairRecord {
                source: s,
                target: t,
                ..record.clone()
            };
            return (record, None);
        }
        if stop.load(std::sync::atomic::Ordering::Relaxed) {
            return (
                failed_record(&names, s, t, "not computed: the run was stopped".into()),
                None,
            );
        }
        let out = match (&shapes[s], &shapes[t]) {
            (Some(src), Some(tgt)) => {
                let mut params = options.newton.clone();
                if options.warm_start {
                    params.initial_heights = warm;
                }
                // (a limit too far ahead for the clock is no limit; a caller's own deadline
                // holds if it is earlier)
                if let Some(deadline) = options.time_limit.and_then(|limit| Instant::now().checked_add(limit)) {
                    params.deadline = Some(params.deadline.map_or(deadline, |d| d.min(deadline)));
                }
                let started = Instant::now();
                let solved = guarded(|| src.directed_pair(tgt, options.invariance, &params));
                match solved {
                    Ok((d, heights)) => (
                        PairRecord {
                            a: names[s].clone(),
                            b: names[t].clone(),
                            source: s,
                            target: t,
                            distance: if d.converged { d.distance } else { f64::NAN },
                            cost: d.cost,
                            iterations: d.iterations,
                            max_mass_error: d.max_mass_error,
                            seconds: d.seconds,
                            status: d.status,
                            evaluations: d.evaluations,
                            dual_cost: if d.converged { d.dual_cost } else { f64::NAN },
                        },
                        d.converged.then_some(heights),
                    ),
                    Err(e) => {
                        // (the time it took before failing: up to a time limit, or minutes on a
                        // pair that fails late)
                        let seconds = started.elapsed().as_secs_f64();
                        (
                            PairRecord {
                                seconds,
                                ..failed_record(&names, s, t, e)
                            },
                            None,
                        )
                    }
                }
            }
            _ => (failed_record(&names, s, t, "shape failed to prepare".into()), None),
        };
        progress(&out.0);
        out
    };
    let records: Vec<Vec<PairRecord>> = if options.warm_start {
        let mut order: Vec<usize> = (0..groups.len()).collect();
        order.sort_by_key(|&g| std::cmp::Reverse(groups[g].1.len()));
        let mut done: Vec<(usize, Vec<PairRecord>)> = one_per_thread(order.len(), |k| {
            let g = order[k];
            let (t, sources) = &groups[g];
            let mut warm: Option<Vec<f64>> = None;
            let records = sources
                .iter()
                .map(|&s| {
                    let (record, heights) = run(s, *t, warm.clone());
                    // a pair that did not converge passes on the last converged heights
                    if heights.is_some() {
                        warm = heights;
                    }
                    record
                })
                .collect();
            (g, records)
        });
        done.sort_by_key(|(g, _)| *g);
        done.into_iter().map(|(_, r)| r).collect()
    } else {
        let flat: Vec<(usize, usize)> = groups
            .iter()
            .flat_map(|(t, sources)| sources.iter().map(move |&s| (s, *t)))
            .collect();
        vec![one_per_thread(flat.len(), |k| run(flat[k].0, flat[k].1, None).0)]
    };
    let pairs: Vec<PairRecord> = records.into_iter().flatten().collect();
    let self_costs = options.debias.then(|| self_costs(shapes, options));
    let ok: Vec<bool> = shapes.iter().map(Option::is_some).collect();
    let (matrix, asymmetries, debias_clamped) =
        matrix_from_pairs(&ok, &pairs, options.symmetrize, self_costs.as_deref());
    let pair_seconds = pairs
        .iter()
        .filter(|p| !known.contains_key(&(p.source, p.target)))
        .map(|p| p.seconds)
        .sum();
    PairwiseResult {
        names,
        matrix,
        pairs,
        asymmetries,
        pair_seconds,
        self_costs,
        debias_clamped,
    }
}

/// The matrix of a pairwise run from its directed `pairs` over the shapes whose `ok` is true
/// (the others' rows and columns NaN): the distance of each unordered pair {i, j} (i < j), the
/// mean of both directions with `symmetrize`, else that of i → j; NaN where a pair is missing or
/// failed; 0 on the diagonal. With `self_costs`, the debiased distances
/// ([`debiased_cost`]). Also the relative asymmetries (with `symmetrize`) and the number of
/// clamped debiased costs. A shard's pairs and the merge of all shards give the same cells as
/// one run.
pub fn matrix_from_pairs(
    ok: &[bool],
    pairs: &[PairRecord],
    symmetrize: bool,
    self_costs: Option<&[f64]>,
) -> (Vec<f64>, Vec<f64>, usize) {
    let n = ok.len();
    let mut debias_clamped = 0;
    let mut directed = vec![f64::NAN; n * n];
    for p in pairs {
        directed[p.source * n + p.target] = match self_costs {
            Some(own) if p.distance.is_finite() => {
                let (c, clamped) = debiased_cost(p.cost, own[p.target]);
                debias_clamped += clamped as usize;
                c.sqrt()
            }
            _ => p.distance,
        };
    }
    let mut matrix = vec![f64::NAN; n * n];
    let mut asymmetries = Vec::new();
    for i in 0..n {
        matrix[i * n + i] = if ok[i] { 0.0 } else { f64::NAN };
        for j in (i + 1)..n {
            let d = if symmetrize {
                let (a, b) = (directed[i * n + j], directed[j * n + i]);
                if a.is_finite() && b.is_finite() {
                    let mean = 0.5 * (a + b);
                    if mean > 0.0 {
                        asymmetries.push((a - b).abs() / mean);
                    }
                }
                0.5 * (a + b)
            } else {
                directed[i * n + j]
            };
            matrix[i * n + j] = d;
            matrix[j * n + i] = d;
        }
    }
    (matrix, asymmetries, debias_clamped)
}

/// Each shape's self-cost c(s, s), its density against its own points (NaN for a shape that
/// failed or a solve that did not converge), with the pairs' solver settings.
fn self_costs<S: PairShape>(shapes: &[Option<S>], options: &PairwiseOptions) -> Vec<f64> {
    one_per_thread(shapes.len(), |i| match &shapes[i] {
        Some(s) => match guarded(|| s.directed_pair(s, Invariance::Fixed, &options.newton)) {
            Ok((d, _)) if d.converged => d.cost,
            _ => f64::NAN,
        },
        None => f64::NAN,
    })
}

/// A shape the pairwise run compares: a disk ([`PreparedShape`]), a closed surface on the
/// sphere ([`PreparedSphere`]) or either ([`Prepared`]).
pub trait PairShape: Sync {
    /// Display name.
    fn shape_name(&self) -> &str;
    /// One directed pair self → target with the solver settings `params` (with
    /// `invariance`: the minimum over rotations of the target's domain), and the final heights
    /// when they can warm-start the next pair with the same target (else empty).
    fn directed_pair(
        &self,
        target: &Self,
        invariance: Invariance,
        params: &NewtonParams,
    ) -> Result<(DirectedDistance, Vec<f64>), AnalysisError>;
}

impl PairShape for PreparedShape {
    fn shape_name(&self) -> &str {
        &self.name
    }

    fn directed_pair(
        &self,
        target: &Self,
        invariance: Invariance,
        params: &NewtonParams,
    ) -> Result<(DirectedDistance, Vec<f64>), AnalysisError> {
        let started = Instant::now();
        match invariance {
            Invariance::Fixed => directed_distance(self, target, params),
            Invariance::Rotation => rotation_invariant_distance(self, target, params).map(|r| {
                (
                    DirectedDistance {
                        cost: r.cost,
                        dual_cost: r.dual_cost,
                        distance: r.distance,
                        iterations: r.iterations,
                        max_mass_error: r.max_mass_error,
                        seconds: started.elapsed().as_secs_f64(),
                        status: if r.converged {
                            format!("converged (target rotated by {:.6} rad; {} solves)", r.theta, r.solves)
                        } else {
                            r.status
                        },
                        converged: r.converged,
                        evaluations: r.evaluations,
                    },
                    Vec::new(),
                )
            }),
        }
    }
}

impl PairShape for PreparedSphere {
    fn shape_name(&self) -> &str {
        &self.name
    }

    /// Aligned by the markers when both maps are normalized by markers and `invariance` is
    /// `Fixed`; otherwise the minimum over rotations of the target's sphere
    /// ([`crate::sphere_distance`]). The solver takes `params`' tolerance, iteration cap and
    /// deadline.
    fn directed_pair(
        &self,
        target: &Self,
        invariance: Invariance,
        params: &NewtonParams,
    ) -> Result<(DirectedDistance, Vec<f64>), AnalysisError> {
        let free = |s: &PreparedSphere| s.normalization() == SphereNormalization::Centered { rotation: None };
        // (a shape against itself is the quantization floor: no search)
        let alignment = if std::ptr::eq(self, target) && invariance == Invariance::Fixed {
            SphereAlignment::Fixed
        } else if invariance == Invariance::Rotation || free(self) || free(target) {
            SphereAlignment::Rotation
        } else {
            SphereAlignment::Fixed
        };
        let sphere_params = SphereOtParams {
            tolerance: params.tolerance,
            max_iterations: params.max_iterations,
            deadline: params.deadline,
            ..SphereOtParams::default()
        };
        let d = directed_sphere_distance(self, target, alignment, &sphere_params)?;
        let status = match (alignment, d.converged) {
            (SphereAlignment::Rotation, true) => {
                let w = crate::rotation::log_rotation(&d.rotation);
                format!(
                    "converged (target rotated by ({:.6}, {:.6}, {:.6}) rad; {} solves, {:.2} s of {:.2} s in the rotation search)",
                    w[0],
                    w[1],
                    w[2],
                    d.solves,
                    d.seconds_proxy + d.seconds_scoring,
                    d.seconds
                )
            }
            _ => d.status.clone(),
        };
        Ok((
            DirectedDistance {
                cost: d.cost,
                dual_cost: d.dual_cost,
                distance: d.distance,
                iterations: d.iterations,
                max_mass_error: d.max_mass_error,
                seconds: d.seconds,
                status,
                converged: d.converged,
                evaluations: d.evaluations,
            },
            Vec::new(),
        ))
    }
}

/// A prepared shape of either domain (what [`crate::pipeline::prepare_inputs`] returns). A pair
/// of a disk and a sphere fails with a message saying so (the pipeline refuses such a run
/// before any pair).
#[derive(Clone, Debug)]
pub enum Prepared {
    Disk(Box<PreparedShape>),
    Sphere(Box<PreparedSphere>),
}

impl Prepared {
    /// The disk shape, if it is one.
    pub fn as_disk(&self) -> Option<&PreparedShape> {
        match self {
            Prepared::Disk(s) => Some(s),
            Prepared::Sphere(_) => None,
        }
    }

    /// The sphere shape, if it is one.
    pub fn as_sphere(&self) -> Option<&PreparedSphere> {
        match self {
            Prepared::Disk(_) => None,
            Prepared::Sphere(s) => Some(s),
        }
    }
}

impl PairShape for Prepared {
    fn shape_name(&self) -> &str {
        match self {
            Prepared::Disk(s) => &s.name,
            Prepared::Sphere(s) => &s.name,
        }
    }

    fn directed_pair(
        &self,
        target: &Self,
        invariance: Invariance,
        params: &NewtonParams,
    ) -> Result<(DirectedDistance, Vec<f64>), AnalysisError> {
        match (self, target) {
            (Prepared::Disk(a), Prepared::Disk(b)) => a.directed_pair(b, invariance, params),
            (Prepared::Sphere(a), Prepared::Sphere(b)) => a.directed_pair(b, invariance, params),
            _ => Err(AnalysisError::Pair {
                a: self.shape_name().to_string(),
                b: target.shape_name().to_string(),
                message: "a disk and a closed surface (sphere) cannot be compared".into(),
            }),
        }
    }
}

/// How a pair's status starts (after `failed: `) when it panicked.
pub(crate) const INTERNAL_ERROR: &str = "internal error (a bug in shapespace; please report it with the mesh files)";

/// Whether a `pairs.csv` status is that of a pair that panicked (a bug, which a resumed run
/// computes again rather than repeating its record).
pub fn is_internal_error(status: &str) -> bool {
    status
        .strip_prefix("failed: ")
        .is_some_and(|s| s.starts_with(INTERNAL_ERROR))
}

/// Whether a `pairs.csv` status is that of a pair that stopped at its time limit
/// ([`PairwiseOptions::time_limit`]): an outcome of the machine's speed, not of the inputs, so a
/// resumed run computes it again.
pub fn is_time_limit(status: &str) -> bool {
    status
        .strip_prefix("failed: ")
        .unwrap_or(status)
        .starts_with("time limit")
}

/// `work(0) … work(count − 1)`, in parallel on the threads of the current rayon pool: each
/// thread takes the next index as it becomes free, so no thread starts an item while another
/// of its items waits. (With the items as rayon tasks, a thread waiting inside an item's own
/// parallel work could steal and run a whole other item before returning to it, so that item's
/// clock and time limit would count the other's work: seen at six threads.) The items' own
/// parallel work is shared as usual. Results in index order.
fn one_per_thread<T: Send>(count: usize, work: impl Fn(usize) -> T + Sync) -> Vec<T> {
    let next = AtomicUsize::new(0);
    let mut done: Vec<(usize, T)> = rayon::broadcast(|_| {
        let mut mine = Vec::new();
        loop {
            let k = next.fetch_add(1, Ordering::Relaxed);
            if k >= count {
                return mine;
            }
            mine.push((k, work(k)));
        }
    })
    .into_iter()
    .flatten()
    .collect();
    done.sort_unstable_by_key(|(k, _)| *k);
    done.into_iter().map(|(_, t)| t).collect()
}

/// Runs one pair's computation so that a panic (a bug, such as an index overrun in the clipping
/// of crowded cells) fails that pair with its message instead of taking the
/// whole run down after every other pair has been computed. The shared per-shape caches are
/// safe to use after it: their locks recover from poisoning. A pair error's message is returned
/// without the pair's names (the record has them, and a resumed run may call the files
/// otherwise). `run_distances` runs each file's preparation under it too.
pub(crate) fn guarded<T>(pair: impl FnOnce() -> Result<T, AnalysisError>) -> Result<T, String> {
    match std::panic::catch_unwind(std::panic::AssertUnwindSafe(pair)) {
        Ok(result) => result.map_err(|e| match e {
            AnalysisError::Pair { message, .. } => message,
            e => e.to_string(),
        }),
        Err(payload) => {
            let what = payload
                .downcast_ref::<&str>()
                .map(|s| s.to_string())
                .or_else(|| payload.downcast_ref::<String>().cloned())
                .unwrap_or_else(|| "no message".into());
            Err(format!("{INTERNAL_ERROR}: {what}"))
        }
    }
}

fn failed_record(names: &[String], s: usize, t: usize, status: String) -> PairRecord {
    PairRecord {
        a: names[s].clone(),
        b: names[t].clone(),
        source: s,
        target: t,
        distance: f64::NAN,
        cost: f64::NAN,
        iterations: 0,
        max_mass_error: f64::NAN,
        seconds: 0.0,
        status: format!("failed: {status}"),
        evaluations: 0,
        dual_cost: f64::NAN,
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Three points 1e-14 apart (a chain) and one 1e-9 from them: the chain becomes one point
    /// at its mass-weighted mean with the summed mass, the far point stays; the merge's own
    /// cost is Σ ν_i |y_i − c|²; without close points the input comes back as it was.
    #[test]
    fn coincident_points_merge_into_their_weighted_mean() {
        let points = [
            [0.5, 0.25],
            [0.5 + 1e-14, 0.25],
            [0.5 + 2e-14, 0.25],
            [0.5, 0.25 + 1e-9],
        ];
        let masses = vec![1.0, 2.0, 1.0, 3.0];
        let (p, m, v) = merge_coincident_points(&points, masses.clone(), COINCIDENT_POINTS);
        assert_eq!(p.len(), 2);
        assert_eq!(m, vec![4.0, 3.0]);
        let cx = (0.5 + 2.0 * (0.5 + 1e-14) + (0.5 + 2e-14)) / 4.0;
        assert!((p[0][0] - cx).abs() < 1e-16 && p[0][1] == 0.25, "{:?}", p[0]);
        assert_eq!(p[1], points[3]);
        let expected = (0.5 - cx).powi(2) + 2.0 * (0.5 + 1e-14 - cx).powi(2) + (0.5 + 2e-14 - cx).powi(2);
        assert!((v - expected).abs() <= 1e-3 * expected, "{v} {expected}");
        let (same, same_m, zero) = merge_coincident_points(&points[2..], masses[2..].to_vec(), COINCIDENT_POINTS);
        assert_eq!(
            (same.as_slice(), same_m.as_slice(), zero),
            (&points[2..], &masses[2..], 0.0)
        );
    }

    /// R S Rᵀ is the second moment of the rotated points: `rotate_moments` against the moments
    /// of rotated groups computed from scratch.
    #[test]
    fn rotated_moments_are_those_of_the_rotated_points() {
        use shapespace_omt::quantization::second_moments;
        let points: Vec<[f64; 2]> = (0..12)
            .map(|i| {
                let t = i as f64;
                [0.3 * t.sin() + 0.01 * t, 0.2 * (1.7 * t).cos()]
            })
            .collect();
        let masses: Vec<f64> = (0..12).map(|i| 1.0 + 0.1 * i as f64).collect();
        let group: Vec<usize> = (0..12).map(|i| i % 3).collect();
        let centre = |pts: &[[f64; 2]], g: usize| {
            let (mut c, mut m) = ([0.0, 0.0], 0.0);
            for i in (0..12).filter(|i| group[*i] == g) {
                c[0] += masses[i] * pts[i][0];
                c[1] += masses[i] * pts[i][1];
                m += masses[i];
            }
            [c[0] / m, c[1] / m]
        };
        let centres: Vec<[f64; 2]> = (0..3).map(|g| centre(&points, g)).collect();
        let moments = second_moments(&points, &masses, &group, &centres);
        for theta in [0.0, 0.7, -2.5] {
            let rotated = crate::invariance::rotate(&points, theta);
            let rotated_centres: Vec<[f64; 2]> = (0..3).map(|g| centre(&rotated, g)).collect();
            let expected = second_moments(&rotated, &masses, &group, &rotated_centres);
            for (got, want) in rotate_moments(&moments, theta).iter().zip(&expected) {
                for c in 0..3 {
                    assert!((got[c] - want[c]).abs() < 1e-15, "θ {theta}: {got:?} against {want:?}");
                }
            }
        }
    }

    /// No item starts on a thread while another item waits there, even when the items' own
    /// parallel halves are stolen and waited for (the flat `par_iter` over pairs this replaced
    /// nested items 2–3 deep in each of ten runs of this test), and the results come in index
    /// order.
    #[test]
    fn one_item_at_a_time_per_thread() {
        use std::cell::Cell;
        thread_local!(static ACTIVE: Cell<usize> = const { Cell::new(0) });
        let deepest = AtomicUsize::new(0);
        let pool = rayon::ThreadPoolBuilder::new().num_threads(6).build().unwrap();
        let results = pool.install(|| {
            one_per_thread(96, |k| {
                let depth = ACTIVE.with(|a| {
                    a.set(a.get() + 1);
                    a.get()
                });
                deepest.fetch_max(depth, Ordering::Relaxed);
                for _ in 0..5 {
                    // the second half is stolen by an idle thread, and the first half's thread
                    // then waits for it
                    rayon::join(
                        || std::thread::sleep(std::time::Duration::from_micros(200)),
                        || std::thread::sleep(std::time::Duration::from_millis(2)),
                    );
                }
                ACTIVE.with(|a| a.set(a.get() - 1));
                k * k
            })
        });
        assert_eq!(results, (0..96).map(|k| k * k).collect::<Vec<_>>());
        assert_eq!(deepest.load(Ordering::Relaxed), 1);
    }

    #[test]
    fn a_panicking_pair_fails_with_its_message() {
        let ok: Result<u32, String> = guarded(|| Ok(3));
        assert_eq!(ok, Ok(3));
        let err = guarded::<u32>(|| {
            Err(AnalysisError::Pair {
                a: "a".into(),
                b: "b".into(),
                message: "no convergence".into(),
            })
        });
        // (the names are the record's columns, not part of its status)
        assert_eq!(err.unwrap_err(), "no convergence");
        let index = 12;
        let panicked = guarded::<u32>(|| {
            let v = [0u32; 12];
            Ok(v[index])
        })
        .unwrap_err();
        assert!(
            panicked.starts_with("internal error") && panicked.contains("the len is 12 but the index is 12"),
            "{panicked}"
        );
        let literal = guarded::<u32>(|| panic!("plain")).unwrap_err();
        assert!(literal.ends_with(": plain"), "{literal}");
        // as a failed record's status, recognized as a panic (a resumed run computes it again)
        assert!(is_internal_error(
            &failed_record(&["a".into(), "b".into()], 0, 1, literal).status
        ));
        assert!(!is_internal_error(
            &failed_record(&["a".into(), "b".into()], 0, 1, "no convergence".into()).status
        ));
    }
}
