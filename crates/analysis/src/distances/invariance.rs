//! A conformal Wasserstein distance free of the boundary marker: the minimum over rotations of
//! the disk,
//! $$ d_{rot}(M_1, M_2) = \min_\theta W_2\big(\mu_1, (R_\theta)_\# \nu_2\big). $$
//!
//! With the interior marker fixed, another boundary marker only rotates a disk map (Riemann
//! mapping theorem: the maps with p ↦ 0 differ by a rotation), so d_rot does not depend on the
//! boundary markers at all; it is at most the fixed-marker distance (θ = 0 is a candidate).
//!
//! **Search.** C(θ) = W₂²(μ₁, R_θ ν₂) is smooth where the optimal plan is unique, and its
//! derivative comes with every solve (envelope theorem: moving target y_i changes the cost by
//! ∫_{W_i} 2(y_i − x) dμ, with the cells held fixed):
//! $$ C'(\theta) = \sum_i 2\big(\mu(W_i)\,y_i - \textstyle\int_{W_i} x\,d\mu\big)\cdot J y_i
//!   = -2 \sum_i \Big(\int_{W_i} x\,d\mu\Big) \cdot J y_i, \qquad J = \begin{pmatrix}0&-1\\1&0\end{pmatrix}. $$
//! 1. Candidates: θ = 0 and the best peaks of the circular cross-correlation of the two
//!    shapes' angular profiles (mass × r² per degree, the angular part of the second moment;
//!    O(N + 360²)), each scored by one transport solve.
//! 2. From the best candidate, secant steps on C′(θ), each solve warm-started from the previous
//!    heights (a small rotation moves the heights little), until |Δθ| < [`THETA_TOLERANCE`].
//!
//! Cost: one cold solve per distinct candidate (at most [`MAX_CANDIDATES`]) plus a few warm
//! solves (`RotationSearch::solves` counts them all).

use std::f64::consts::{PI, TAU};

use serde::Serialize;
use shapespace_omt::{solve_ot_prepared, NewtonParams, OtSolution};

use crate::distance::PreparedShape;
use crate::error::AnalysisError;

/// The search stops when a secant step is below this many radians.
pub const THETA_TOLERANCE: f64 = 1e-3;
/// Cold solves at most: θ = 0 and the best correlation peak 10 degrees or more away from it.
pub const MAX_CANDIDATES: usize = 2;
/// Relative mass tolerance of the solves that score the candidates.
pub const SCORING_TOLERANCE: f64 = 1e-2;
/// Secant steps at most.
pub const MAX_SECANT_STEPS: usize = 12;

/// The outcome of [`rotation_invariant_distance`].
#[derive(Clone, Debug, Serialize)]
pub struct RotationSearch {
    /// min_θ W₂² found.
    pub cost: f64,
    /// √cost.
    pub distance: f64,
    /// The minimizing rotation of the target's disk, radians in (−π, π].
    pub theta: f64,
    /// Transport solves made (cold candidates and warm secant steps).
    pub solves: usize,
    /// Newton iterations over all solves.
    pub iterations: usize,
    /// Whether the final solve reached its tolerance.
    pub converged: bool,
    /// The final solve's dual value ([`shapespace_omt::OtSolution::dual_value`]).
    pub dual_cost: f64,
    /// The final solve's max relative cell-mass error.
    pub max_mass_error: f64,
    /// Cell evaluations over all solves.
    pub evaluations: usize,
    /// The final solve's stop reason.
    pub status: String,
}

/// Which alignments of the target's disk a distance minimizes over.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize, serde::Deserialize)]
pub enum Invariance {
    /// The markers' alignment: interior marker at 0, boundary marker at 1 (Su et al.).
    #[default]
    Fixed,
    /// Every rotation of the disk ([`rotation_invariant_distance`]): free of the boundary marker.
    Rotation,
}

/// `points` rotated by `theta` (radians, counter-clockwise).
pub(crate) fn rotate(points: &[[f64; 2]], theta: f64) -> Vec<[f64; 2]> {
    let (s, c) = theta.sin_cos();
    points
        .iter()
        .map(|p| [c * p[0] - s * p[1], s * p[0] + c * p[1]])
        .collect()
}

/// C′(θ) at a solution whose targets are `points` (already rotated): −2 Σ_i M_i · J y_i with
/// M_i the cell's first moment (module docs).
pub fn rotation_derivative(solution: &OtSolution, points: &[[f64; 2]]) -> f64 {
    -2.0 * solution
        .cells
        .first_moments
        .iter()
        .zip(points)
        .map(|(m, y)| -m[0] * y[1] + m[1] * y[0])
        .sum::<f64>()
}

/// Angular profile: Σ mass · r² per one-degree bin.
fn angular_profile(points: impl Iterator<Item = ([f64; 2], f64)>) -> Vec<f64> {
    let mut bins = vec![0.0; 360];
    for (p, m) in points {
        let a = p[1].atan2(p[0]).rem_euclid(TAU);
        let k = ((a / TAU * 360.0) as usize).min(359);
        bins[k] += m * (p[0] * p[0] + p[1] * p[1]);
    }
    // smooth over ±2 degrees
    (0..360)
        .map(|k| (0..5).map(|d| bins[(k + 358 + d) % 360]).sum::<f64>())
        .collect()
}

/// Rotations θ (radians) at the best peaks of the correlation of the source's and the target's
/// angular profiles: rotating the target by θ lines its profile up with the source's.
fn correlation_candidates(source: &PreparedShape, target: &PreparedShape) -> Vec<f64> {
    let m = &source.measure;
    let src = angular_profile(m.triangles.iter().zip(&m.densities).map(|(t, &d)| {
        let [a, b, c] = t.map(|v| m.vertices[v as usize]);
        let area = 0.5 * ((b[0] - a[0]) * (c[1] - a[1]) - (b[1] - a[1]) * (c[0] - a[0])).abs();
        ([(a[0] + b[0] + c[0]) / 3.0, (a[1] + b[1] + c[1]) / 3.0], d * area)
    }));
    let tgt = angular_profile(target.points.iter().copied().zip(target.masses.iter().copied()));
    // corr[s] = Σ_k src[k] tgt[k − s]: the target rotated by s degrees
    let corr: Vec<f64> = (0..360)
        .map(|s| (0..360).map(|k| src[k] * tgt[(k + 360 - s) % 360]).sum())
        .collect();
    let mut peaks: Vec<usize> = (0..360)
        .filter(|&s| corr[s] >= corr[(s + 359) % 360] && corr[s] >= corr[(s + 1) % 360])
        .collect();
    peaks.sort_by(|&a, &b| corr[b].total_cmp(&corr[a]).then(a.cmp(&b)));
    peaks.into_iter().map(|s| s as f64 / 360.0 * TAU).collect()
}

/// Wraps an angle to (−π, π].
fn wrap(theta: f64) -> f64 {
    let t = theta.rem_euclid(TAU);
    if t > PI {
        t - TAU
    } else {
        t
    }
}

/// d_rot(source, target) = min_θ W₂(μ_source, R_θ ν_target) by the search of the module docs,
/// with the solver settings `params` (as for a fixed-marker pair).
///
/// Errors: a transport solve that fails outright (an [`AnalysisError::Pair`] naming both).
pub fn rotation_invariant_distance(
    source: &PreparedShape,
    target: &PreparedShape,
    params: &NewtonParams,
) -> Result<RotationSearch, AnalysisError> {
    let pair_error = |e: shapespace_omt::OmtError| AnalysisError::Pair {
        a: source.name.clone(),
        b: target.name.clone(),
        message: format!("rotation search: {e}"),
    };
    let mut solves = 0;
    let mut iterations = 0;
    let mut evaluations = 0;
    let mut solve =
        |theta: f64, warm: Option<Vec<f64>>, tolerance: f64| -> Result<(OtSolution, Vec<[f64; 2]>), AnalysisError> {
            let points = rotate(&target.points, theta);
            let p = NewtonParams {
                initial_heights: warm,
                tolerance,
                density_continuation: None,
                // (the coarsening is built for the unrotated points)
                target_coarsening: if theta == 0.0 {
                    Some(target.coarsening.clone())
                } else {
                    None
                },
                ..params.clone()
            };
            let s = solve_ot_prepared(&source.measure, &points, &target.masses, &p).map_err(pair_error)?;
            solves += 1;
            iterations += s.all_iterations();
            evaluations += s.evaluations;
            Ok((s, points))
        };
    // candidates: θ = 0 and the best correlation peaks at least 10 degrees from those taken
    let mut candidates = vec![0.0];
    for t in correlation_candidates(source, target) {
        if candidates.len() >= MAX_CANDIDATES {
            break;
        }
        let t = wrap(t);
        if candidates.iter().all(|&c| wrap(t - c).abs() > 10f64.to_radians()) {
            candidates.push(t);
        }
    }
    // candidates scored by solves to a loose tolerance (their costs differ by far more than its
    // error), the best one then solved to the full tolerance from its heights
    let scoring = params.tolerance.max(SCORING_TOLERANCE);
    let mut best: Option<(f64, OtSolution)> = None;
    for &theta in &candidates {
        let (s, _) = solve(theta, None, scoring)?;
        if best.as_ref().is_none_or(|b| s.cost < b.1.cost) {
            best = Some((theta, s));
        }
    }
    let (mut theta, loose) = best.expect("θ = 0 is always a candidate");
    let (mut sol, points) = solve(theta, Some(loose.heights), params.tolerance)?;
    let mut g = rotation_derivative(&sol, &points);
    // first step: a small probe against the slope, then secant steps on C′
    let mut step = -g.signum() * 1e-2;
    for _ in 0..MAX_SECANT_STEPS {
        if step.abs() < THETA_TOLERANCE || !step.is_finite() {
            break;
        }
        let next = wrap(theta + step);
        let (s, rotated) = solve(next, Some(sol.heights.clone()), params.tolerance)?;
        let g_next = rotation_derivative(&s, &rotated);
        let secant = (g_next - g) / step;
        if s.cost <= sol.cost {
            (theta, sol) = (next, s);
            step = if secant > 0.0 { -g_next / secant } else { step };
            g = g_next;
        } else if secant > 0.0 {
            // overshoot: the minimum lies between; step from the kept point by the secant
            step = -g / secant;
        } else {
            step *= -0.5;
        }
    }
    // (a quantized target: corrected to the full target, as for a fixed pair)
    let correction = target.quantization_correction(&sol, theta);
    let cost = sol.cost + correction;
    Ok(RotationSearch {
        cost,
        distance: cost.max(0.0).sqrt(),
        theta,
        solves,
        iterations,
        converged: sol.converged(),
        dual_cost: sol.dual_value() + correction,
        max_mass_error: sol.max_relative_error,
        evaluations,
        status: sol.stop_description(),
    })
}
