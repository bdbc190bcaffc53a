//! Damped Newton for semi-discrete OT on the sphere [Kitagawa, Mérigot, Thibert 2019;
//! Mérigot, Meyron, Thibert 2018 for sources on triangle soups].
//!
//! The same iteration as the planar solver's plain KMT step (conventions, "Damping and
//! stopping"): solve H δ = −G with the unknown of the largest target pinned, and shrink τ from
//! min(1, 4τ_prev) (2τ_prev after a step that was halved) by halving until every cell keeps at least ε₀ = ½ min(min ν, min μ(W_i(h₀)))
//! and ‖G(h + τδ)‖ ≤ (1 − τ/2)‖G(h)‖. As in the plane, a step aims at soft-capped intermediate
//! targets ν'_i = m_i exp(K tanh(ln(ν_i/m_i)/K)), K = ln 32, while some cell is far from its
//! target (decision 0004), and plain KMT steps once such a step is accepted below τ = 0.01.
//! Heights are double-double (the bisector offsets of sites 1e-11 apart need more than an ulp
//! of heights of order one, decision 0005). The start ([`SphereStart`]): the Voronoi diagram
//! (h = 0, all sites on S²), or the coarse-to-fine start of [`super::multiscale`] when a
//! Voronoi cell holds less than 1e-8 or more than 100 times its target (the conformal images
//! of limbs, docs/decisions/0025-sphere-coarse-to-fine-start.md). Above a density ratio of 10
//! a density continuation solves softened densities ρ^t first
//! ([`SphereOtParams::density_continuation`]).
//!
//! Measured (`crates/tools/src/bin/sphere_contrast.rs`, 5,000 random equal-mass points, ρ ∝ exp(k z) on
//! 20,480 triangles; steps of all stages): ratio 2.7 and 7.4: 5 steps; 55: 9; 400: 13 (2
//! stages); 3,000: 97 steps, 525 evaluations (3 stages); 22,000: 172 steps, 958 evaluations
//! (4 stages). Without the continuation (with or without the intermediate targets) the last two
//! stopped at 100 steps with mass errors of 360–430 % and 1,060 %. High contrast with points spread evenly
//! (the low-density cells must reach far from their sites) is this solver's weak case.

use std::time::Instant;

use crate::error::OmtError;
use crate::linear::{LinearSolver, NewtonSystem};
use crate::newton::{intermediate_targets, StopReason};

/// A step aimed at intermediate targets and accepted below this τ switches them off (as in the
/// plane).
const TARGET_CAP_MIN_TAU: f64 = 0.01;

use super::cells::{SphereCells, SphereIntegrator};
use super::measure::{norm, SphereMeasure, SPHERE_TOLERANCE};
use super::multiscale::coarse_to_fine_heights;
use crate::newton::Heights;

/// Parameters of [`solve_sphere_ot`].
#[derive(Clone, Debug)]
pub struct SphereOtParams {
    /// Stop when max_i |μ(W_i) − ν_i| / ν_i ≤ tolerance (default 1e-6).
    pub tolerance: f64,
    /// Newton step cap (default 100).
    pub max_iterations: usize,
    /// Step halvings per line search before the solve stalls (default 40).
    pub max_halvings: usize,
    /// Linear solver (default sparse Cholesky).
    pub linear_solver: LinearSolver,
    /// Warm start heights (#N); the Voronoi start h = 0 without them.
    pub initial_heights: Option<Vec<f64>>,
    /// The low parts of the warm start's double-double heights (#N, with `initial_heights`;
    /// [`SphereOtSolution::heights_lo`]): without them a warm start rounds the heights to f64,
    /// which moves the bisectors of sites 1e-11 apart by 1e-5 of their spacing' reciprocal
    /// (decision 0005) and costs every warm-started solve of a crowded image its first steps.
    pub initial_heights_lo: Option<Vec<f64>>,
    /// Stop as [`StopReason::TimeLimit`] at the first step that would begin after this.
    pub deadline: Option<Instant>,
    /// Integrate with every site a candidate in every triangle (the O(N·M) oracle; tests).
    pub brute_force: bool,
    /// Density continuation (default `Some(10)`): without a warm start and with a density ratio
    /// max/min above r, solve first for ρ^t, t = 1/K, 2/K, …, (K−1)/K with
    /// K = ⌈ln(max/min)/ln r⌉ (each stage to max(tolerance, 1e-3), warm-starting the next), as
    /// the planar [`crate::NewtonParams::density_continuation`]. `None` disables it.
    pub density_continuation: Option<f64>,
    /// Soft cap κ on the mass ratio a step aims for (default `Some(32)`, as in the plane:
    /// [`crate::NewtonParams::target_ratio_cap`]); `None`: plain KMT steps.
    pub target_ratio_cap: Option<f64>,
    /// How the initial heights are chosen without a warm start (default
    /// [`SphereStart::Auto`]).
    pub start: SphereStart,
    /// Tolerance of the coarse levels of the coarse-to-fine start (default 1e-3; a level is
    /// solved to max(tolerance, coarse_tolerance)).
    pub coarse_tolerance: f64,
    /// Give up early (default `None`: never): stop as [`StopReason::Stalled`] when this many
    /// accepted steps have not halved the largest relative mass error. For an attempt that
    /// has a more robust path after it (the direct solve before the density continuation):
    /// on a crowded body the direct solve crawls at τ ≈ 1e-3 for its whole step cap
    /// (docs/decisions/0036-sphere-direct-solve-stall.md). Not passed on to the coarse levels
    /// or the continuation's stages. With a window, [`SphereStart::Auto`] does not retry from
    /// the Voronoi start after the coarse-to-fine start's solve stops.
    pub stall_window: Option<usize>,
}

/// How [`solve_sphere_ot`] chooses its initial heights when no warm start is given.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum SphereStart {
    /// The coarse-to-fine start ([`super::multiscale`]) when some Voronoi cell holds less than
    /// 1e-8 or more than 100 times its target (points crowded by a conformal map), the Voronoi
    /// start otherwise. If the solve from the coarse-to-fine start does not converge, the
    /// Voronoi path runs too and the better result is returned, with the steps of both
    /// (not with a [`SphereOtParams::stall_window`]: the caller has a more robust path).
    #[default]
    Auto,
    /// h = 0.
    Voronoi,
    /// The coarse-to-fine start whenever a coarse level applies (else the Voronoi start).
    CoarseToFine,
}

impl Default for SphereOtParams {
    fn default() -> Self {
        SphereOtParams {
            tolerance: 1e-6,
            max_iterations: 100,
            max_halvings: 40,
            linear_solver: LinearSolver::Cholesky,
            initial_heights: None,
            initial_heights_lo: None,
            deadline: None,
            brute_force: false,
            target_ratio_cap: Some(crate::newton::TARGET_RATIO_CAP),
            density_continuation: Some(10.0),
            start: SphereStart::Auto,
            coarse_tolerance: 1e-3,
            stall_window: None,
        }
    }
}

/// The line search's first trial is min(1, STEP_GROWTH·τ_prev), τ_prev the last accepted step
/// (the planar solver's rule with a faster growth, decision 0006): the first steps from a
/// coarse-to-fine start of a crowded image are accepted near τ = 1e-2 and would each re-try
/// the same rejected trials from 1, while τ still returns to 1 within a few steps.
const STEP_GROWTH: f64 = 4.0;
/// The growth after a step whose first trial was rejected: its τ lies near the largest
/// acceptable one, and four times it was rejected again on the crowded images (decision 0049).
const STEP_GROWTH_AFTER_HALVING: f64 = 2.0;

/// One Newton step.
#[derive(Clone, Debug, Default)]
pub struct SphereIteration {
    /// max_i |G_i|/ν_i after the step.
    pub max_relative_error: f64,
    /// ‖G‖₂ after the step.
    pub gradient_norm: f64,
    /// Accepted step length τ.
    pub step: f64,
    /// Rejected trials.
    pub halvings: usize,
    /// Cells whose target this step replaced by an intermediate one.
    pub intermediate_targets: usize,
    /// min_i μ(W_i) after the step.
    pub min_cell_mass: f64,
    /// Seconds integrating cells (all trials) and solving the Newton system.
    pub t_integration: f64,
    pub t_solve: f64,
}

/// The result of [`solve_sphere_ot`], converged or not (see [`SphereOtSolution::into_result`]).
#[derive(Clone, Debug)]
pub struct SphereOtSolution {
    /// The target points as used: normalized to |y_i| = 1 (#N).
    pub points: Vec<[f64; 3]>,
    /// Heights h (#N): u_h(x) = max_i ⟨x, y_i⟩ + h_i, the high parts of double-double values.
    pub heights: Vec<f64>,
    /// The low parts (#N): h_i = `heights[i] + heights_lo[i]`.
    pub heights_lo: Vec<f64>,
    /// Power weights w_i = 2h_i + |y_i|² = 2h_i + 1 (#N).
    pub weights: Vec<f64>,
    /// Cell integrals at the final heights.
    pub cells: SphereCells,
    /// Transport cost Σ_i ∫_{W_i} |x − y_i|² dμ on the flat triangles
    /// ([`SphereCells::transport_cost`]).
    pub cost: f64,
    /// Newton steps taken (with a density continuation, of the last stage).
    pub iterations: usize,
    /// Stages of a density continuation before the problem itself (0 without one) and their
    /// Newton steps.
    pub continuation_stages: usize,
    pub continuation_iterations: usize,
    /// The coarse-to-fine start's coarser levels as (points, Newton steps), next coarser first
    /// (empty for another start).
    pub coarse_levels: Vec<(usize, usize)>,
    /// Points whose prolonged height the start's check recomputed over all coarse groups.
    pub start_rechecked: usize,
    /// Cell integrations, the initial one included.
    pub evaluations: usize,
    /// max_i |μ(W_i) − ν_i| / ν_i at the final heights (ν rescaled).
    pub max_relative_error: f64,
    /// The tolerance asked for.
    pub tolerance: f64,
    /// Why the iteration stopped.
    pub stop: StopReason,
    /// One record per step.
    pub log: Vec<SphereIteration>,
    /// Factor applied to the target masses so that they sum to μ(S²).
    pub mass_scale: f64,
    /// The rescaled target masses ν (#N).
    pub target_masses: Vec<f64>,
    /// The damping threshold ε₀.
    pub epsilon0: f64,
    /// Seconds in total.
    pub t_total: f64,
}

impl SphereOtSolution {
    /// True when the tolerance was reached.
    pub fn converged(&self) -> bool {
        self.stop == StopReason::Converged
    }

    /// `Ok(self)` if converged, else `OmtError::NoConvergence`.
    pub fn into_result(self) -> Result<Self, OmtError> {
        if self.converged() {
            return Ok(self);
        }
        Err(OmtError::NoConvergence {
            iterations: self.iterations,
            residual: self.max_relative_error,
            tolerance: self.tolerance,
            reason: self.stop.to_string(),
        })
    }

    /// The Kantorovich dual value F = cost + Σ_i w_i (ν_i − μ(W_i)) (as in the plane: ≤ the
    /// optimal cost for any heights, within about GᵀH⁻¹G of it).
    pub fn dual_value(&self) -> f64 {
        self.cost
            + self
                .weights
                .iter()
                .zip(&self.target_masses)
                .zip(&self.cells.masses)
                .map(|((w, nu), m)| w * (nu - m))
                .sum::<f64>()
    }

    /// μ-centroids of the cells projected radially on S² (#N).
    pub fn centroids_on_sphere(&self) -> Vec<Option<[f64; 3]>> {
        self.cells.centroids_on_sphere()
    }
}

/// The points normalized to S²: each must be finite with | |y| − 1 | ≤ [`SPHERE_TOLERANCE`]
/// (errors name the first point that is not), and no two may coincide after normalization.
pub fn normalize_sphere_points(points: &[[f64; 3]]) -> Result<Vec<[f64; 3]>, OmtError> {
    let mut out = Vec::with_capacity(points.len());
    for (i, p) in points.iter().enumerate() {
        let r = norm(*p);
        if !p.iter().all(|c| c.is_finite()) || !((r - 1.0).abs() <= SPHERE_TOLERANCE) {
            return Err(OmtError::InvalidInput(format!(
                "point {i} ({}, {}, {}) is not on the unit sphere (|y| = {r})",
                p[0], p[1], p[2]
            )));
        }
        out.push([p[0] / r, p[1] / r, p[2] / r]);
    }
    let mut order: Vec<usize> = (0..out.len()).collect();
    order.sort_by(|&a, &b| {
        let (p, q) = (out[a], out[b]);
        p[0].total_cmp(&q[0])
            .then(p[1].total_cmp(&q[1]))
            .then(p[2].total_cmp(&q[2]))
    });
    for w in order.windows(2) {
        if out[w[0]] == out[w[1]] {
            return Err(OmtError::DuplicatePoints {
                i: w[0].min(w[1]),
                j: w[0].max(w[1]),
            });
        }
    }
    Ok(out)
}

/// Semi-discrete OT from `measure` to the points `points` on S² with masses `masses` (rescaled
/// to μ(S²)), chordal cost |x − y|² = 2 − 2⟨x, y⟩. Every stop returns a solution;
/// `into_result()` maps non-convergence to an error. Errors: invalid input (points off S²,
/// coincident points, non-positive masses, a warm start of the wrong length) and a start with
/// an empty cell (a source that does not cover the direction of some point).
pub fn solve_sphere_ot(
    measure: &SphereMeasure,
    points: &[[f64; 3]],
    masses: &[f64],
    params: &SphereOtParams,
) -> Result<SphereOtSolution, OmtError> {
    let t_start = Instant::now();
    let n = points.len();
    if n == 0 {
        return Err(OmtError::InvalidInput("no target points".into()));
    }
    if masses.len() != n {
        return Err(OmtError::InvalidInput(format!(
            "{} masses for {n} points",
            masses.len()
        )));
    }
    if let Some((i, m)) = masses.iter().enumerate().find(|(_, m)| !(m.is_finite() && **m > 0.0)) {
        return Err(OmtError::InvalidInput(format!(
            "mass {m} of point {i} is not positive and finite"
        )));
    }
    if !(params.tolerance > 0.0) {
        return Err(OmtError::InvalidInput(format!(
            "tolerance {} is not positive",
            params.tolerance
        )));
    }
    let points = normalize_sphere_points(points)?;
    if params.initial_heights.is_none() {
        if let Some(r) = params.density_continuation.filter(|&r| r > 1.0) {
            let lo = measure.densities.iter().copied().fold(f64::INFINITY, f64::min);
            let hi = measure.densities.iter().copied().fold(0.0, f64::max);
            if hi / lo > r {
                return continuation(measure, &points, masses, params, (hi / lo).ln() / r.ln(), t_start);
            }
        }
    }
    let total = measure.total_mass();
    let sum: f64 = masses.iter().sum();
    let mass_scale = total / sum;
    let targets: Vec<f64> = masses.iter().map(|m| m * mass_scale).collect();
    if let Some(i) = targets.iter().position(|t| !(t.is_finite() && *t > 0.0)) {
        return Err(OmtError::InvalidInput(format!(
            "mass {} of point {i} cannot be rescaled to the source mass {total} (beside the sum {sum})",
            masses[i]
        )));
    }
    let integrator = if params.brute_force {
        SphereIntegrator::brute_force(measure, &points)
    } else {
        SphereIntegrator::new(measure, &points)
    };
    let problem = Problem {
        integrator: &integrator,
        targets: &targets,
        mass_scale,
        params,
        t_start,
    };
    if let Some(h) = &params.initial_heights {
        if h.len() != n {
            return Err(OmtError::InvalidInput(format!(
                "{} initial heights for {n} points",
                h.len()
            )));
        }
        if h.iter().any(|v| !v.is_finite()) {
            return Err(OmtError::InvalidInput("the initial heights are not all finite".into()));
        }
        let heights = match &params.initial_heights_lo {
            None => Heights::from_f64(h.clone()),
            Some(lo) if lo.len() == n && lo.iter().all(|v| v.is_finite()) => Heights {
                hi: h.clone(),
                lo: lo.clone(),
            },
            Some(lo) => {
                return Err(OmtError::InvalidInput(format!(
                    "{} low parts of the initial heights for {n} points, or not all finite",
                    lo.len()
                )))
            }
        };
        return problem.iterate(heights, None, StartRecord::default());
    }
    let voronoi = || Heights::from_f64(vec![0.0; n]);
    let (voronoi_cells, try_coarse) = match params.start {
        SphereStart::Voronoi => (None, false),
        SphereStart::CoarseToFine => (None, true),
        SphereStart::Auto => {
            let cells = integrator.integrate(&vec![0.0; n]);
            let poor = cells.masses.iter().zip(&targets).any(|(&m, &t)| {
                let r = m / t;
                !(AUTO_MIN_START..=AUTO_MAX_START).contains(&r)
            });
            (Some(cells), poor)
        }
    };
    if try_coarse {
        if let Some(start) = coarse_to_fine_heights(measure, &integrator, &targets, params)? {
            let record = StartRecord {
                coarse_levels: start.levels.clone(),
                start_rechecked: start.rechecked,
            };
            let coarse_steps: usize = record.coarse_levels.iter().map(|l| l.1).sum();
            let cells = integrator.integrate_dd(&start.heights.hi, Some(&start.heights.lo));
            let empty = cells.masses.iter().any(|&m| !(m > 0.0));
            if !empty {
                let solution = problem.iterate(start.heights, Some(cells), record)?;
                // (a stall window means a more robust path follows: the caller's, not the
                // Voronoi start's, which crawls where the coarse-to-fine start did)
                if solution.converged()
                    || params.start == SphereStart::CoarseToFine
                    || solution.stop == StopReason::TimeLimit
                    || params.stall_window.is_some()
                {
                    return Ok(solution);
                }
                // Auto: the Voronoi path too, and the better result
                let mut other = problem.iterate(voronoi(), voronoi_cells, StartRecord::default())?;
                let coarse_path = solution.iterations + coarse_steps;
                if other.converged() || other.max_relative_error < solution.max_relative_error {
                    other.iterations += coarse_path;
                    return Ok(other);
                }
                let mut solution = solution;
                solution.iterations += other.iterations;
                return Ok(solution);
            }
        }
    }
    problem.iterate(voronoi(), voronoi_cells, StartRecord::default())
}

/// [`SphereStart::Auto`] takes the coarse-to-fine start when some Voronoi cell holds less than
/// this fraction of its target…
const AUTO_MIN_START: f64 = 1e-8;
/// …or more than this multiple of it (the planar thresholds, decision 0003).
const AUTO_MAX_START: f64 = 100.0;

/// What the start contributes to the solution's record.
#[derive(Clone, Debug, Default)]
struct StartRecord {
    coarse_levels: Vec<(usize, usize)>,
    start_rechecked: usize,
}

/// One solve's fixed data: the integrator over the (normalized) sites, the rescaled targets.
struct Problem<'a, 'm> {
    integrator: &'a SphereIntegrator<'m>,
    targets: &'a [f64],
    mass_scale: f64,
    params: &'a SphereOtParams,
    t_start: Instant,
}

impl Problem<'_, '_> {
    /// Damped Newton from `heights` (`cells`: their integrals, when already computed).
    fn iterate(
        &self,
        mut heights: Heights,
        cells: Option<SphereCells>,
        record: StartRecord,
    ) -> Result<SphereOtSolution, OmtError> {
        let (integrator, targets, params) = (self.integrator, self.targets, self.params);
        let points = integrator.points();
        let n = points.len();
        let mut cells = match cells {
            Some(c) => c,
            None => integrator.integrate_dd(&heights.hi, Some(&heights.lo)),
        };
        let mut evaluations = 1;
        if let Some(i) = cells.masses.iter().position(|&m| !(m > 0.0)) {
            return Err(OmtError::InvalidInput(format!(
                "cell {i} is empty at the start: the source does not reach the direction of point {i} \
                 ({:.6}, {:.6}, {:.6})",
                points[i][0], points[i][1], points[i][2]
            )));
        }
        let min_mass = cells.masses.iter().copied().fold(f64::INFINITY, f64::min);
        let min_target = targets.iter().copied().fold(f64::INFINITY, f64::min);
        let epsilon0 = 0.5 * min_mass.min(min_target);
        let pinned = (0..n).max_by(|&a, &b| targets[a].total_cmp(&targets[b])).unwrap_or(0);
        let mut system = NewtonSystem::new(pinned, params.linear_solver.clone());
        let errors = |cells: &SphereCells| -> (Vec<f64>, f64, f64) {
            let g: Vec<f64> = cells.masses.iter().zip(targets).map(|(m, t)| m - t).collect();
            let rel = g.iter().zip(targets).map(|(g, t)| (g / t).abs()).fold(0.0, f64::max);
            let norm = g.iter().map(|v| v * v).sum::<f64>().sqrt();
            (g, rel, norm)
        };
        let (mut gradient, mut rel, mut gnorm) = errors(&cells);
        let mut log = Vec::new();
        let mut stop = StopReason::IterationCap;
        let mut iterations = 0;
        let mut target_cap = params.target_ratio_cap;
        let mut last_tau: f64 = 1.0;
        let mut last_halved = false;
        // the largest relative mass error at the start and after each accepted step
        let mut history = vec![rel];
        loop {
            if rel <= params.tolerance {
                stop = StopReason::Converged;
                break;
            }
            if let Some(w) = params.stall_window.filter(|&w| w > 0 && history.len() > w) {
                let before = history[history.len() - 1 - w];
                if rel > 0.5 * before {
                    stop = StopReason::Stalled {
                        reason: format!("{w} steps took the mass error only from {before:.3e} to {rel:.3e}"),
                    };
                    break;
                }
            }
            if !rel.is_finite() {
                stop = StopReason::Stalled {
                    reason: "a non-finite mass error".into(),
                };
                break;
            }
            if iterations >= params.max_iterations {
                break;
            }
            if params.deadline.is_some_and(|d| Instant::now() >= d) {
                stop = StopReason::TimeLimit;
                break;
            }
            let t0 = Instant::now();
            let step = target_cap.and_then(|cap| intermediate_targets(&cells.masses, targets, cap));
            let (step_targets, step_gradient, step_norm) = match &step {
                Some((t, _)) => {
                    let g: Vec<f64> = cells.masses.iter().zip(t).map(|(m, t)| m - t).collect();
                    let norm = g.iter().map(|v| v * v).sum::<f64>().sqrt();
                    (&t[..], g, norm)
                }
                None => (targets, gradient.clone(), gnorm),
            };
            let delta = system.newton_direction_from_coefficients(n, &cells.hessian, &step_gradient)?;
            let t_solve = t0.elapsed().as_secs_f64();
            if delta.iter().any(|d| !d.is_finite()) {
                stop = StopReason::Stalled {
                    reason: "the Newton direction is not finite".into(),
                };
                break;
            }
            let t1 = Instant::now();
            let growth = if last_halved {
                STEP_GROWTH_AFTER_HALVING
            } else {
                STEP_GROWTH
            };
            let mut tau = (growth * last_tau).min(1.0);
            let mut halvings = 0;
            let accepted = loop {
                let trial = heights.step(&delta, tau);
                let trial_cells = integrator.integrate_dd(&trial.hi, Some(&trial.lo));
                evaluations += 1;
                let min_mass = trial_cells.masses.iter().copied().fold(f64::INFINITY, f64::min);
                let trial_norm = trial_cells
                    .masses
                    .iter()
                    .zip(step_targets)
                    .map(|(m, t)| (m - t) * (m - t))
                    .sum::<f64>()
                    .sqrt();
                if min_mass >= epsilon0 && trial_norm <= (1.0 - tau / 2.0) * step_norm {
                    let (g, r, gn) = errors(&trial_cells);
                    break Some((trial, trial_cells, g, r, gn, min_mass));
                }
                halvings += 1;
                if halvings > params.max_halvings {
                    break None;
                }
                tau *= 0.5;
            };
            let t_integration = t1.elapsed().as_secs_f64();
            if step.is_some() && (accepted.is_none() || tau < TARGET_CAP_MIN_TAU) {
                // intermediate targets that do not pay: plain KMT steps from here on
                target_cap = None;
                if accepted.is_none() {
                    iterations += 1;
                    continue;
                }
            }
            let Some((trial, trial_cells, g, r, gn, min_mass)) = accepted else {
                stop = StopReason::Stalled {
                    reason: format!("no acceptable step after {} halvings", params.max_halvings),
                };
                break;
            };
            last_tau = tau;
            last_halved = halvings > 0;
            heights = trial;
            cells = trial_cells;
            (gradient, rel, gnorm) = (g, r, gn);
            iterations += 1;
            history.push(rel);
            log.push(SphereIteration {
                max_relative_error: rel,
                gradient_norm: gnorm,
                step: tau,
                halvings,
                intermediate_targets: step.as_ref().map_or(0, |s| s.1),
                min_cell_mass: min_mass,
                t_integration,
                t_solve,
            });
        }
        let cost = cells.transport_cost();
        let weights = heights
            .hi
            .iter()
            .zip(&heights.lo)
            .map(|(h, l)| 2.0 * h + 2.0 * l + 1.0)
            .collect();
        Ok(SphereOtSolution {
            points: points.to_vec(),
            heights: heights.hi,
            heights_lo: heights.lo,
            weights,
            cells,
            cost,
            iterations,
            evaluations,
            max_relative_error: rel,
            tolerance: params.tolerance,
            stop,
            log,
            continuation_stages: 0,
            continuation_iterations: 0,
            coarse_levels: record.coarse_levels,
            start_rechecked: record.start_rechecked,
            mass_scale: self.mass_scale,
            target_masses: targets.to_vec(),
            epsilon0,
            t_total: self.t_start.elapsed().as_secs_f64(),
        })
    }
}

/// The density continuation of [`SphereOtParams::density_continuation`]: K = ⌈`stages`⌉ stages.
fn continuation(
    measure: &SphereMeasure,
    points: &[[f64; 3]],
    masses: &[f64],
    params: &SphereOtParams,
    stages: f64,
    t_start: Instant,
) -> Result<SphereOtSolution, OmtError> {
    let k = stages.ceil().max(1.0) as usize;
    let mut heights: Option<(Vec<f64>, Vec<f64>)> = None;
    let mut iterations = 0;
    let mut evaluations = 0;
    for stage in 1..k {
        let t = stage as f64 / k as f64;
        let softened = SphereMeasure {
            vertices: measure.vertices.clone(),
            triangles: measure.triangles.clone(),
            densities: measure.densities.iter().map(|d| d.powf(t)).collect(),
        };
        let (hi, lo) = heights.take().unzip();
        let stage_params = SphereOtParams {
            tolerance: params.tolerance.max(1e-3),
            initial_heights: hi,
            initial_heights_lo: lo,
            density_continuation: None,
            stall_window: None,
            ..params.clone()
        };
        let solution = solve_sphere_ot(&softened, points, masses, &stage_params)?;
        iterations += solution.iterations;
        evaluations += solution.evaluations;
        if solution.stop == StopReason::TimeLimit {
            return Ok(solution);
        }
        heights = Some((solution.heights, solution.heights_lo));
    }
    let (hi, lo) = heights.unzip();
    let last = SphereOtParams {
        initial_heights: hi,
        initial_heights_lo: lo,
        density_continuation: None,
        stall_window: None,
        ..params.clone()
    };
    let mut solution = solve_sphere_ot(measure, points, masses, &last)?;
    solution.continuation_stages = k - 1;
    solution.continuation_iterations = iterations;
    solution.evaluations += evaluations;
    solution.t_total = t_start.elapsed().as_secs_f64();
    Ok(solution)
}
