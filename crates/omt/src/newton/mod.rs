//! Damped Newton solver of semi-discrete optimal transport on the heights
//! [Kitagawa, Mérigot, Thibert 2019, Alg. 1; Gu, Luo, Sun, Yau 2013].
//!
//! Given a source measure μ on a convex Ω (piecewise-constant density on triangles), target
//! points $y_i$ and masses $\nu_i > 0$ with $\sum_i \nu_i = \mu(\Omega)$, find heights $h$ such that the
//! cells of $u_h(x) = \max_i \langle x, y_i\rangle + h_i$,
//! $W_i = \{x : \langle x, y_i\rangle + h_i \ge \langle x, y_j\rangle + h_j\ \forall j\}$
//! (the power cells with weights $w_i = 2h_i + |y_i|^2$), have masses $\mu(W_i \cap \Omega) = \nu_i$.
//! They minimize the convex energy
//! $$E(h) = \int_\Omega u_h\,d\mu - \sum_i \nu_i h_i, \qquad \nabla E = G = \big(\mu(W_i) - \nu_i\big)_i,$$
//! whose Hessian is the graph Laplacian of `linear`. Each iteration solves $H\delta = -G$ and
//! takes the damped step $h \leftarrow h + \tau\delta$ of KMT: $\tau = 1, \frac12, \frac14, \dots$ until
//! $\min_i \mu(W_i(h + \tau\delta)) \ge \varepsilon_0$ and $\|G(h + \tau\delta)\|_2 \le (1 - \tau/2)\|G(h)\|_2$,
//! with $\varepsilon_0 = \frac12\min(\min_i \nu_i, \min_i \mu(W_i(h_0)))$.
//!
//! ## Choices (documented here because they are not in the paper)
//! - **Target masses** are always rescaled by `mass_scale = μ(Ω)/Σν` (recorded in the solution);
//!   masses must be finite and > 0, and so must Σν and every rescaled mass (else an input
//!   error asks to rescale them: 1e308 masses overflow the sum, subnormal ones the scale).
//! - **Start.** Warm start if given, else ([`StartStrategy`]) the coarse-to-fine start of
//!   `multiscale` or the Voronoi diagram $h_i = -|y_i|^2/2$. KMT need every cell non-empty
//!   at $h_0$ (otherwise ε₀ = 0 and the damping protects nothing). If a start has an empty cell,
//!   the solver replaces it by the Voronoi diagram of the points contracted toward the area
//!   centroid $c$ of Ω, $z_i = c + s(y_i - c)$, which is a power diagram of the $y_i$ with
//!   $h_i = -|z_i|^2/(2s)$ up to a constant, $-(1-s)\langle c, y_i\rangle - s|y_i|^2/2$ in
//!   double-double (`Heights::contracted`; the common term $(1-s)\langle x, c\rangle$ drops out); $s$ is halved from
//!   1 until every cell has positive mass (for $s$ small all $z_i$ lie inside Ω, whose cells then
//!   contain a disk around $z_i$). Thus ε₀ is always positive and the KMT guarantee applies.
//! - **Coarse-to-fine** ([`StartStrategy`], module `multiscale`): the points are merged pairwise,
//!   closest first, into a hierarchy of coarser problems; each level is solved from the
//!   prolongation of the one below it, which provably leaves no cell empty. From a Voronoi start
//!   the damped steps are limited to about one cell width, so a large displacement (a density
//!   contrast, points crowded by a conformal map) costs many steps; from the prolongation the
//!   finest level needs 6–18 (`docs/decisions/0003-coarse-to-fine-start.md`). `StartStrategy::Auto` (default)
//!   takes it when the density ratio exceeds 10 or the Voronoi start has a cell below 1e-8 or
//!   above 100 times its target.
//! - **Density continuation** (with `StartStrategy::Voronoi`, and on the coarsest level of the
//!   coarse-to-fine start). With a strong density contrast the Newton model of the Voronoi
//!   start is far off (cells are pushed into regions 100× denser than their edges say) and KMT
//!   accepts only τ ≈ 2^−10 for tens of steps. When max ρ / min ρ exceeds `density_continuation`
//!   (default 10), the solver first solves for ρ^t along t = Δt, 2Δt, … (Δt = 1/K initially,
//!   K = ⌈ln(max/min)/ln r⌉; tolerance max(tol, 1e-3), max_iterations/2 steps per stage), each
//!   stage warm-starting the next; the last stage is the real problem with the KMT rule and its
//!   own ε₀. The schedule adapts: a stage that does not converge is retried from the last
//!   converged one with Δt halved, one that converges in a quarter of its budget doubles Δt,
//!   and below Δt = 1/512 the solve stops as `Stalled` with the t it reached. (A fixed schedule of
//!   ratio 10 stopped at the iteration cap on 4000 and 10⁴ uniform random points with a 100×
//!   half-plane contrast; `tests/solver_stress.rs`.) Iterations and logs of all stages,
//!   discarded ones included, are reported together.
//! - **Intermediate targets** (`NewtonParams::target_ratio_cap`, default 32). A cell far below
//!   or above its target is where the Newton model fails: a cell with 1e-3 of its mass grows,
//!   by the linear model, as its perimeter times the height change, so the full step asks for
//!   a height change that overruns its neighbours, and KMT's test then accepts only τ ≈ 1e-2
//!   for every cell. Each step therefore aims at
//!   $\nu'_i = m_i \exp\big(K \tanh(\ln(\nu_i/m_i)/K)\big)$, $K = \ln \kappa$ (a soft cap of the
//!   ratio at κ), kept exactly at ν_i where that changes it by less than 0.1 % (cells within
//!   about −28 % … +39 % of their targets), all rescaled to the total mass; the step solves
//!   $H\delta = -(m - \nu')$ and takes KMT's damped step for ν'. Every ν'_i lies between m_i and
//!   ν_i (up to the common rescaling), and once every cell is within that band the step is
//!   exactly KMT's, so the quadratic phase and the stopping rule are unchanged. If a step with
//!   modified targets is accepted only below τ = 0.01, or not at all, the solve continues with
//!   the plain targets (the crowded TOSCA meshes, whose cells must grow 1e20-fold: centaur0
//!   takes 15 steps with it and 14 without; `docs/decisions/0004-intermediate-targets.md`).
//! - **Pinning.** The unknown with the largest target mass (first one on ties) is pinned for the
//!   whole solve (step 0), so the sparsity pattern only changes when neighbours change.
//! - **Stops.** `Converged` when $\max_i |G_i|/\nu_i \le$ `tolerance`; `IterationCap`; `Stalled` when
//!   the line search would need τ below 2^−`max_halvings` (typically the floating-point floor
//!   of the mass error, far below the default tolerance), when a non-finite value appears, or
//!   when ten consecutive steps were each cut by the damping to τ < 1e-20 and lowered the max
//!   relative error by less than 0.1 % together (TOSCA horse5 from the coarse-to-fine start
//!   spent 85 such steps with the error fixed at 20; with this rule its Auto solve falls back to
//!   the Voronoi start after 29 instead of 100 steps: 196 → 125 steps, OT 16.4 → 11 s).
//!
//! ## Layout
//! - `params`: [`NewtonParams`], [`StartStrategy`], [`CellIntegrator`];
//! - `solution`: [`OtSolution`], [`StopReason`], [`Start`], [`IterationRecord`], and the conversions
//!   between heights, weights and the Kantorovich energy;
//! - `evaluation`: one evaluation of the cells at given heights (power diagram + restricted
//!   integration, or the brute-force oracle), with the mass errors;
//! - `damped`: one damped Newton solve from a start, with its stall rules;
//! - `line_search`: the KMT damping of one step; `targets`: the intermediate targets;
//! - `continuation`: the density and mass continuations; `multiscale`: the coarse-to-fine start;
//! - `heights`: double-double heights; `validate`, `diagnosis`: input checks and crowding messages;
//! - this module: [`solve_ot`], which chooses the start and the path.

mod continuation;
mod damped;
mod diagnosis;
mod evaluation;
mod heights;
mod line_search;
mod multiscale;
mod params;
mod solution;
mod targets;
mod validate;

use std::time::Instant;

use continuation::{solve_density_continuation, solve_mass_continuation};
use damped::solve_single;
use evaluation::{evaluate_keeping_diagram, flux_bound};
use params::{AUTO_CONTRAST, AUTO_MAX_START, AUTO_MIN_START};
use validate::validate;

pub use evaluation::integrate_at_heights;
pub use multiscale::{TargetCoarsening, RETRY_CONTINUATION};
pub use params::{CellIntegrator, NewtonParams, StartStrategy};
pub use solution::{
    heights_from_weights, kantorovich_energy, weights_from_heights, IterationRecord, OtSolution, Start, StopReason,
};
pub use targets::TARGET_RATIO_CAP;

pub(crate) use evaluation::{errors, evaluate, evaluate_diagram, evaluate_unless_hidden, Backend, Evaluation};
pub(crate) use heights::Heights;
pub(crate) use targets::intermediate_targets;

use crate::error::OmtError;
use crate::measure::SourceMeasure;
use crate::prepared::PreparedMeasure;

/// The area centroid of Ω (the density ignored), the center of the contracted starts. It lies
/// deep inside the convex Ω (it cuts every chord through it at most 2 : 1). Not the
/// μ-barycenter: on TOSCA dog0 → dog1, both slit, as a distance pair (μ-barycenter
/// at radius 0.38, area centroid at 1.7e-4), the direct solve from the contraction toward the
/// μ-barycenter ran past 300 s, and from the one toward the centroid it stopped on crowding
/// (points 1e-14 apart) after 22 steps.
fn domain_centroid(measure: &SourceMeasure) -> [f64; 2] {
    let (mut m, mut c) = (0.0, [0.0, 0.0]);
    for tri in &measure.triangles {
        let [a, b, e] = tri.map(|v| measure.vertices[v as usize]);
        let area = 0.5 * ((b[0] - a[0]) * (e[1] - a[1]) - (b[1] - a[1]) * (e[0] - a[0]));
        m += area;
        c[0] += area * (a[0] + b[0] + e[0]) / 3.0;
        c[1] += area * (a[1] + b[1] + e[1]) / 3.0;
    }
    [c[0] / m, c[1] / m]
}

/// Solves semi-discrete OT from `measure` to the points `points` (#N) with masses `masses` (#N,
/// positive, rescaled to sum to μ(Ω)) by the damped Newton method of Kitagawa–Mérigot–Thibert on the
/// heights (module docs). Returns the solution whether or not it converged (check
/// [`OtSolution::converged`] or call [`OtSolution::into_result`]); errors on invalid input
/// (N = 0, non-finite values, masses ≤ 0, coincident points) and linear-algebra failures.
pub fn solve_ot(
    measure: &SourceMeasure,
    points: &[[f64; 2]],
    masses: &[f64],
    params: &NewtonParams,
) -> Result<OtSolution, OmtError> {
    solve_ot_prepared(&PreparedMeasure::new(measure.clone()), points, masses, params)
}

/// [`solve_ot`] from a prepared measure, which keeps what the solve builds from the measure
/// (the coarse levels' averaged copies, the flux form's field) for the next solves from it:
/// the same solution, faster when many solves share one source (pairwise runs).
pub fn solve_ot_prepared(
    measure: &PreparedMeasure,
    points: &[[f64; 2]],
    masses: &[f64],
    params: &NewtonParams,
) -> Result<OtSolution, OmtError> {
    let t_begin = Instant::now();
    validate(measure, points, masses, params)?;
    let (lo, hi) = measure
        .densities
        .iter()
        .fold((f64::INFINITY, 0.0f64), |(lo, hi), &d| (lo.min(d), hi.max(d)));
    let contrast = hi / lo;
    let cold = params.initial_heights.is_none() && params.mass_continuation.is_none();
    let mass_scale = measure.total_mass() / masses.iter().sum::<f64>();
    let mut voronoi_start = None;
    // The Voronoi test's diagram (all weights 0: the Delaunay triangulation of the points) and
    // insertion order, for the coarse-to-fine start.
    let mut delaunay = None;
    let multiscale = cold
        && match params.start_strategy {
            StartStrategy::Voronoi => false,
            StartStrategy::CoarseToFine => true,
            StartStrategy::Auto => {
                contrast > AUTO_CONTRAST || {
                    let backend = Backend::new(measure, params.integrator, flux_bound(params));
                    let (mut evaluation, order) =
                        evaluate_keeping_diagram(&backend, points, &Heights::voronoi(points))?;
                    let poor = evaluation.cells.masses.iter().zip(masses).any(|(&m, &nu)| {
                        !(m >= AUTO_MIN_START * nu * mass_scale && m <= AUTO_MAX_START * nu * mass_scale)
                    });
                    // (the diagram goes to the coarse-to-fine start; a Voronoi-start solve keeps
                    // it in its first evaluation, for the first step's flip updates)
                    if let Some(order) = order.filter(|_| poor) {
                        delaunay = evaluation.diagram.take().map(|diagram| (diagram, order));
                    }
                    voronoi_start = Some((backend, evaluation));
                    poor
                }
            }
        };
    if multiscale {
        let targets: Vec<f64> = masses.iter().map(|m| m * mass_scale).collect();
        if let Some(multiscale::CoarseStart {
            heights,
            coarse_points,
            coarse_iterations,
            level_iterations,
            checked,
        }) = multiscale::coarse_to_fine_heights(measure, points, masses, &targets, params, delaunay.take())?
        {
            // The start's last check built the power diagram of these heights: integrate it
            // instead of building it again, with the backend of the Voronoi test if there was one.
            let prepared = checked.map(|(diagram, order)| {
                let backend = voronoi_start
                    .take()
                    .map(|(backend, _)| backend)
                    .unwrap_or_else(|| Backend::new(measure, params.integrator, flux_bound(params)));
                let evaluation = evaluate_diagram(&backend, points, &heights, diagram, order);
                (backend, evaluation)
            });
            let fine_params = NewtonParams {
                initial_heights: Some(heights.hi),
                initial_heights_lo: Some(heights.lo),
                ..params.clone()
            };
            let mut solution = solve_single(measure, points, masses, &fine_params, t_begin, prepared)?;
            if solution.start == Start::Warm {
                solution.start = Start::CoarseToFine {
                    coarse_points,
                    coarse_iterations,
                    level_iterations,
                };
            }
            if solution.converged() || params.start_strategy != StartStrategy::Auto || params.past_deadline() {
                return Ok(solution);
            }
            // Auto: the start it chose did not work out; the Voronoi path gets its chance, and
            // the better of the two is returned with the work of both counted.
            // (the Voronoi test's evaluation, unless its backend went to the coarse-to-fine solve)
            let plain = solve_from_voronoi(measure, points, masses, params, contrast, t_begin, voronoi_start.take())?;
            let (mut better, worse) = if plain.converged() || plain.max_relative_error <= solution.max_relative_error {
                (plain, solution)
            } else {
                (solution, plain)
            };
            better.iterations += worse.iterations;
            better.evaluations += worse.evaluations;
            better.t_total = t_begin.elapsed().as_secs_f64();
            if worse.stop == StopReason::TimeLimit {
                // (the better heights, but the solve as a whole ended on the deadline)
                better.stop = StopReason::TimeLimit;
            }
            return Ok(better);
        }
    }
    solve_from_voronoi(measure, points, masses, params, contrast, t_begin, voronoi_start)
}

/// The rest of [`solve_ot`] without the coarse-to-fine start: mass continuation, density
/// continuation or a single solve from the Voronoi (or warm) start.
fn solve_from_voronoi(
    measure: &PreparedMeasure,
    points: &[[f64; 2]],
    masses: &[f64],
    params: &NewtonParams,
    contrast: f64,
    t_begin: Instant,
    voronoi_start: Option<(Backend<'_>, Evaluation)>,
) -> Result<OtSolution, OmtError> {
    if let (Some(ratio), None) = (params.mass_continuation, &params.initial_heights) {
        return solve_mass_continuation(measure, points, masses, params, ratio, t_begin);
    }
    let stages = match params.density_continuation {
        Some(ratio) if ratio > 1.0 && contrast > ratio && params.initial_heights.is_none() => {
            (contrast.ln() / ratio.ln()).ceil() as usize
        }
        _ => 1,
    };
    if stages == 1 {
        return solve_single(measure, points, masses, params, t_begin, voronoi_start);
    }
    solve_density_continuation(measure, points, masses, params, stages, t_begin)
}
