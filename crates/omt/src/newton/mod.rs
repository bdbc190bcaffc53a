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

mod diagnosis;
mod heights;
mod line_search;
mod multiscale;
mod validate;

use diagnosis::*;
use validate::*;

pub(crate) use heights::Heights;

pub use multiscale::{TargetCoarsening, RETRY_CONTINUATION};

use std::sync::{Arc, OnceLock};
use std::time::Instant;

use crate::cells::CellIntegrals;
use crate::error::OmtError;
use crate::linear::{LinearSolver, NewtonSystem, SpeculativeSymbolic};
use crate::measure::SourceMeasure;
use crate::power_diagram::{Construction, InsertionOrder, PowerDiagram};
use crate::restricted::RestrictedIntegrator;

/// The line search of a step starts at min(1, g × the previous accepted τ), with g =
/// TAU_GROWTH_FREE when that step was accepted at its first trial and TAU_GROWTH otherwise.
const TAU_GROWTH: f64 = 1.5;
const TAU_GROWTH_FREE: f64 = 4.0;
/// Stall detection: the solve stops (`Stalled`) when each of the last STALL_WINDOW steps was
/// cut by the damping to τ < STALL_TAU and together they lowered the max relative error by
/// less than a factor 1 − STALL_GAIN. (Measured on TOSCA horse5 from the coarse-to-fine start:
/// 85 steps at τ ≈ 1e-30 with the error fixed at 20 before the iteration cap; a Voronoi start
/// that still grows τ from 1e-26 by 4 per step is accepted at first trial and not affected.)
const STALL_WINDOW: usize = 10;
const STALL_TAU: f64 = 1e-20;
const STALL_GAIN: f64 = 1e-3;
/// The second stall rule ([`flat_without_growth`]): FLAT_WINDOW steps with τ < FLAT_TAU whose
/// largest τ stopped growing (second half ≤ FLAT_GROWTH × first half) and that lowered the error
/// by less than STALL_GAIN.
const FLAT_WINDOW: usize = 20;
const FLAT_TAU: f64 = 1e-6;
const FLAT_GROWTH: f64 = 2.0;

/// Which cell integrator the solver calls.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum CellIntegrator {
    /// The restricted power diagram (`power_diagram` + `restricted`): exact predicates, O(N + M).
    #[default]
    Restricted,
    /// The O(N² + N·M) oracle of `reference` (tests and N ≲ 2000 only).
    BruteForce,
}

/// Parameters of [`solve_ot`].
#[derive(Clone, Debug)]
pub struct NewtonParams {
    /// Stop when max_i |μ(W_i) − ν_i| / ν_i ≤ tolerance (default 1e-6).
    pub tolerance: f64,
    /// Maximum number of Newton steps (default 100).
    pub max_iterations: usize,
    /// The line search gives up (`Stalled`) below τ = 2^−max_halvings (default 100: with the
    /// heights in double-double form a step τδ down to ~2^−100 still changes them; conformal
    /// images of protrusions start with cells of mass 1e-26 that only such steps keep
    /// non-empty, `docs/decisions/0005-double-double-heights.md`).
    pub max_halvings: usize,
    /// Linear solver of the Newton system (default sparse Cholesky).
    pub linear_solver: LinearSolver,
    /// Warm start (#N heights), e.g. the solution of a previous problem with the same target.
    pub initial_heights: Option<Vec<f64>>,
    /// Low parts of a double-double warm start (#N; with `initial_heights` as the high parts,
    /// e.g. [`OtSolution::heights_lo`]): the start is then h_i = hi_i + lo_i exactly, which
    /// matters for points closer together than ~1e-8 of Ω's extent. Ignored without
    /// `initial_heights`.
    pub initial_heights_lo: Option<Vec<f64>>,
    /// How the initial heights are chosen when no warm start is given (default
    /// [`StartStrategy::Auto`]).
    pub start_strategy: StartStrategy,
    /// Cell integrator (default `Restricted`).
    pub integrator: CellIntegrator,
    /// Density continuation: when the source's density ratio max/min exceeds this value r
    /// (default 10) and no warm start is given, solve first for the densities ρ^t along an
    /// adaptive path t = Δt, 2Δt, … with initial Δt = 1/K, K = ⌈ln(max/min)/ln r⌉, each stage
    /// warm-starting the next (module docs). `None` disables it.
    pub density_continuation: Option<f64>,
    /// Mass continuation (`Some(r)`, r > 1; default `None`): start from the Voronoi (or
    /// contracted) start, whose cell masses m⁰ make it an exact solution for the targets m⁰,
    /// and solve for ν(t) = (1 − t) m⁰ + t ν along t = t₁ < t₂ < … < 1, each t_{k+1} the largest
    /// with every ν_i(t_{k+1}) / ν_i(t_k) ∈ [1/r, r], each stage warm-starting the next
    /// (intermediate stages stop at max(tolerance, 1e-3)). Takes precedence over density
    /// continuation; ignored with `initial_heights`.
    pub mass_continuation: Option<f64>,
    /// Soft cap κ > 1 on the mass ratio a Newton step aims for (default `Some(32)`): each step
    /// aims at ν'_i = m_i exp(K tanh(ln(ν_i/m_i)/K)), K = ln κ, instead of ν_i (module docs,
    /// "Intermediate targets"). `None`: every step aims at ν (KMT's algorithm as published).
    pub target_ratio_cap: Option<f64>,
    /// Build each line-search trial's power diagram from the current one by flips
    /// ([`PowerDiagram::with_order_dd_unless_hidden_from`]) instead of by insertion (default
    /// `true`). The diagrams, hence every result, are the same either way; `false` is for
    /// comparisons.
    pub flip_updates: bool,
    /// Integrate the masses and edge masses of the Newton evaluations by the flux form
    /// ([`RestrictedIntegrator::integrate_masses`]; where it declines, the full integration), and
    /// the moments only once at the end; the convergence test always uses the full integrals.
    /// Default `false`: on face pairs it saves 7 % of the instructions (its field built once per
    /// source face) but was slower in wall time (30 faces, 2 threads: 134 and 149 s against 129
    /// and 118 s, interleaved), and on the area-preserving maps it costs 9 % more instructions
    /// (Nefertiti: several measures solved once each); `docs/decisions/0010-restricted-integration.md`.
    pub flux_masses: bool,
    /// Tolerance of the coarser levels of the coarse-to-fine start (default 1e-3; the finest
    /// level's `tolerance` where that is looser). Their solutions only shape the start (its
    /// guarantee that no cell is empty holds for any coarse heights), so a looser value trades
    /// coarse steps against the start's quality: on face pairs 1e-1 gives the same finest-level
    /// steps with ~4 fewer coarse ones, on the TOSCA bodies it costs 1–3 finest steps
    /// (`docs/decisions/0008-distance-tolerance-and-dual-check.md`). Must be in (0, 1).
    pub coarse_tolerance: f64,
    /// The target's coarsening hierarchy ([`TargetCoarsening`], built once per target) for the
    /// coarse-to-fine start; ignored when it is not that of this solve's points and masses.
    /// `None` (default): the start coarsens the target itself, from the masses rescaled to the
    /// source's mass; the hierarchy is built from the masses as given, so the two starts differ
    /// in rounding (which can also flip a discrete choice of a later merging round) and the
    /// solves agree within their tolerance.
    pub target_coarsening: Option<Arc<TargetCoarsening>>,
    /// Stop as [`StopReason::TimeLimit`] at the first Newton step that would begin after this
    /// instant (checked before each step, so a step under way is finished). It holds for the
    /// whole solve: every coarse level, continuation stage and start, none of which begins
    /// another attempt once it has passed; when it passes before the finest level has a start
    /// (in the coarse levels of the coarse-to-fine start, or in the search for a start with no
    /// empty cell) the solve returns `Err(OmtError::TimeLimit)` saying where. A solve that ends
    /// before it is exactly the solve without it. Default `None`.
    pub deadline: Option<Instant>,
}

impl NewtonParams {
    /// Whether [`Self::deadline`] has passed.
    pub fn past_deadline(&self) -> bool {
        self.deadline.is_some_and(|d| Instant::now() >= d)
    }
}

impl Default for NewtonParams {
    fn default() -> Self {
        NewtonParams {
            tolerance: 1e-6,
            max_iterations: 100,
            max_halvings: 100,
            linear_solver: LinearSolver::Cholesky,
            initial_heights: None,
            initial_heights_lo: None,
            start_strategy: StartStrategy::Auto,
            integrator: CellIntegrator::Restricted,
            density_continuation: Some(10.0),
            mass_continuation: None,
            target_ratio_cap: Some(TARGET_RATIO_CAP),
            flip_updates: true,
            flux_masses: false,
            coarse_tolerance: 1e-3,
            target_coarsening: None,
            deadline: None,
        }
    }
}

/// Default of [`NewtonParams::target_ratio_cap`]. Measured (`docs/decisions/0004-intermediate-targets.md`): on 8
/// faces (28 distance pairs) 16, 24, 32, 64, 128 and 256 with a hard cap all cut the finest
/// level's evaluations by about a fifth, 4 and 1000 less; the soft cap at 32 cut the steps over
/// all levels 697 → 603 and the evaluations of the finest level 450 → 315.
pub const TARGET_RATIO_CAP: f64 = 32.0;

/// A step's target is left at ν_i when the soft cap would change it by less than this fraction.
const TARGET_CAP_SLACK: f64 = 1e-3;

/// A step aimed at intermediate targets and accepted below this τ switches them off for the
/// rest of the solve.
const TARGET_CAP_MIN_TAU: f64 = 0.01;

/// The intermediate targets ν' of one Newton step (module docs, "Intermediate targets"):
/// ν'_i = m_i exp(K tanh(ln(ν_i/m_i)/K)) with K = ln `cap`, or ν_i where that differs from ν_i by
/// less than `TARGET_CAP_SLACK` (relative), all rescaled to Σ ν, with the number of cells whose
/// target was capped. `None` when no target changes.
/// Cells with zero mass (not expected: the line search keeps masses ≥ ε₀ > 0) keep ν_i.
pub(crate) fn intermediate_targets(masses: &[f64], targets: &[f64], cap: f64) -> Option<(Vec<f64>, usize)> {
    let k = cap.ln();
    let mut changed = 0;
    let mut out: Vec<f64> = masses
        .iter()
        .zip(targets)
        .map(|(&m, &nu)| {
            let r = nu / m;
            if !(m > 0.0 && r.is_finite()) {
                return nu;
            }
            let capped = (k * (r.ln() / k).tanh()).exp();
            if (capped / r - 1.0).abs() < TARGET_CAP_SLACK {
                nu
            } else {
                changed += 1;
                m * capped
            }
        })
        .collect();
    if changed == 0 {
        return None;
    }
    let scale = targets.iter().sum::<f64>() / out.iter().sum::<f64>();
    out.iter_mut().for_each(|t| *t *= scale);
    Some((out, changed))
}

/// How [`solve_ot`] chooses its initial heights when no warm start is given.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum StartStrategy {
    /// The coarse-to-fine start when the source density's max/min exceeds 10 or the Voronoi
    /// start has a cell below 1e-8 of its target mass (points crowded by a conformal map) or
    /// above 100 times its target (points sparse where the targets are large), the
    /// Voronoi start otherwise (where it is the faster one: uniform density, spread points). If
    /// the solve from the coarse-to-fine start does not converge, the Voronoi path (with its
    /// continuations) runs too and the better result is returned, with the steps of both.
    #[default]
    Auto,
    /// The Voronoi start (with the density or mass continuation if enabled).
    Voronoi,
    /// The coarse-to-fine start of `multiscale` (for N ≥ 1000, or ≥ 16 crowded points; the
    /// Voronoi start below that).
    CoarseToFine,
}

/// [`StartStrategy::Auto`] takes the coarse-to-fine start above this density ratio max/min.
const AUTO_CONTRAST: f64 = 10.0;
/// [`StartStrategy::Auto`] takes the coarse-to-fine start when a Voronoi cell has less than this
/// fraction of its target mass.
const AUTO_MIN_START: f64 = 1e-8;
/// [`StartStrategy::Auto`] takes the coarse-to-fine start when a Voronoi cell has more than this
/// multiple of its target mass. Measured on area-preserving maps (uniform disk, the
/// conformal images as targets; `analysis/examples/param_start_probe.rs`): the coarse-to-fine
/// start was the faster one where the largest Voronoi cell was 2.4e3 (Nefertiti cut open, 50k
/// points: 15 against 25 steps, OT 5.5 against 8.2 s) and 3.4e3 times its target (Igea, 134k:
/// 13 against 19 steps, 10.6 against 14.7 s), the slower one at 6.5 … 70 (camelhead and its
/// 1-to-4 subdivision, the libigl face, lion, woody, cat head, an ICT face, a bump domain).
/// Why 100 and not 300: Nefertiti cut open and slit twice (`prepare --seam
/// 2`, 50k points) has its largest Voronoi cell at 130 times its target, and the coarse-to-fine
/// start took 6 steps / 2.4 s against 25 steps / 8.5 s from the Voronoi start; camelhead
/// subdivided (70) stays on the Voronoi start (8 steps, 2.3 s, against 9 steps, 3.2 s).
const AUTO_MAX_START: f64 = 100.0;

/// Why the iteration stopped.
#[derive(Clone, Debug, PartialEq)]
pub enum StopReason {
    /// The tolerance was reached.
    Converged,
    /// `max_iterations` steps were taken.
    IterationCap,
    /// No acceptable step could be found, or a non-finite value appeared.
    Stalled { reason: String },
    /// [`NewtonParams::deadline`] passed before the solve ended.
    TimeLimit,
}

impl std::fmt::Display for StopReason {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            StopReason::Converged => write!(f, "converged"),
            StopReason::IterationCap => write!(f, "iteration cap"),
            StopReason::Stalled { reason } => write!(f, "stalled: {reason}"),
            StopReason::TimeLimit => write!(f, "time limit"),
        }
    }
}

/// Where the initial heights came from.
#[derive(Clone, Debug, PartialEq)]
pub enum Start {
    /// h_i = −|y_i|²/2.
    Voronoi,
    /// `NewtonParams::initial_heights`.
    Warm,
    /// The coarse-to-fine start (module `multiscale`): the next coarser level has `coarse_points`
    /// points, and all coarser levels together took `coarse_iterations` Newton steps (the
    /// solution's own `iterations` count the finest level only). `level_iterations` splits
    /// `coarse_iterations` by level, next coarser level first (a level's retry from the Voronoi
    /// start included in its count).
    CoarseToFine {
        coarse_points: usize,
        coarse_iterations: usize,
        level_iterations: Vec<usize>,
    },
    /// The Voronoi diagram of the points contracted by `scale` toward the area centroid of Ω (used
    /// when the other start had an empty cell).
    Contracted { scale: f64 },
    /// Warm start from a density continuation of `stages` converged stages (the last is the
    /// problem itself) that took `iterations` Newton steps before the last stage (including
    /// the steps of discarded stages).
    DensityContinuation { stages: usize, iterations: usize },
    /// Warm start from a mass continuation of `stages` stages (the last is the problem itself)
    /// that took `iterations` Newton steps before the last stage.
    MassContinuation { stages: usize, iterations: usize },
}

/// One Newton step.
#[derive(Clone, Debug, Default)]
pub struct IterationRecord {
    /// max_i |G_i|/ν_i after the step.
    pub max_relative_error: f64,
    /// ‖G‖₂ after the step.
    pub gradient_norm: f64,
    /// Accepted step length τ.
    pub step: f64,
    /// Number of rejected line-search trials (reductions of τ; not always by ½).
    pub halvings: usize,
    /// Line-search trials (diagram + integration evaluations) of this step.
    pub evaluations: usize,
    /// Rejected trials with some cell mass below ε₀.
    pub rejected_min_mass: usize,
    /// Rejected trials with every mass ≥ ε₀ but ‖G(h + τδ)‖ > (1 − τ/2)‖G(h)‖.
    pub rejected_norm: usize,
    /// Trials whose power diagram was updated by flips from the step's start (the others were
    /// built by insertion; [`NewtonParams::flip_updates`]).
    pub flip_updates: usize,
    /// min_i μ(W_i) after the step.
    pub min_cell_mass: f64,
    /// Seconds building power diagrams (all line-search trials).
    pub t_diagram: f64,
    /// Seconds integrating cells (all line-search trials).
    pub t_integration: f64,
    /// Seconds assembling and solving the Newton system.
    pub t_solve: f64,
    /// Cells whose target this step replaced by an intermediate one (0: the plain KMT step;
    /// see [`NewtonParams::target_ratio_cap`]).
    pub intermediate_targets: usize,
}

/// The result of [`solve_ot`], converged or not (see [`OtSolution::into_result`]).
#[derive(Clone, Debug)]
pub struct OtSolution {
    /// Heights h (#N): u_h(x) = max_i ⟨x, y_i⟩ + h_i (the high parts of the solver's
    /// double-double heights).
    pub heights: Vec<f64>,
    /// Low parts of the heights (#N): the solver's heights are `heights[i] + heights_lo[i]`
    /// exactly. Pass both back as a warm start ([`NewtonParams::initial_heights_lo`]) to resume
    /// without rounding.
    pub heights_lo: Vec<f64>,
    /// Power weights w_i = 2h_i + |y_i|² (#N).
    pub weights: Vec<f64>,
    /// Cell integrals at the final heights.
    pub cells: CellIntegrals,
    /// Transport cost Σ_i ∫_{W_i} |x − y_i|² dμ.
    pub cost: f64,
    /// Newton steps taken (all stages of a continuation; with the coarse-to-fine start the finest
    /// level only, the coarser ones are in [`Start::CoarseToFine`]).
    pub iterations: usize,
    /// Cell evaluations (power diagram + integration) of all line searches, including the
    /// initial one of each stage.
    pub evaluations: usize,
    /// max_i |μ(W_i) − ν_i| / ν_i at the final heights (ν rescaled).
    pub max_relative_error: f64,
    /// The tolerance that was asked for.
    pub tolerance: f64,
    /// Why the iteration stopped.
    pub stop: StopReason,
    /// One record per Newton step.
    pub log: Vec<IterationRecord>,
    /// Factor applied to the target masses so that they sum to μ(Ω).
    pub mass_scale: f64,
    /// The rescaled target masses ν (#N).
    pub target_masses: Vec<f64>,
    /// The damping threshold ε₀.
    pub epsilon0: f64,
    /// Where the initial heights came from.
    pub start: Start,
    /// Seconds spent on the start (including a coarse solve) and in total.
    pub t_start: f64,
    pub t_total: f64,
    /// Number of symbolic Cholesky factorizations (changes of the neighbour graph).
    pub symbolic_factorizations: usize,
    /// Number of those that computed a new fill-reducing ordering (the others reused one).
    pub orderings: usize,
    /// Seconds in Hessian assembly, symbolic factorization, numeric factorization + solve.
    /// `t_symbolic` includes the symbolic factorizations computed ahead of need and used (from
    /// 5000 sites on, with `LinearSolver::Cholesky`), which ran alongside an integration.
    pub t_assembly: f64,
    pub t_symbolic: f64,
    pub t_numeric: f64,
    /// When the solve stopped at the iteration cap and the solver can tell why (points too
    /// crowded for double precision), the explanation; [`OtSolution::into_result`] appends it.
    pub diagnosis: Option<String>,
}

impl OtSolution {
    /// True when the tolerance was reached.
    pub fn converged(&self) -> bool {
        self.stop == StopReason::Converged
    }

    /// `Ok(self)` if converged, else `OmtError::NoConvergence` with the stop reason.
    pub fn into_result(self) -> Result<Self, OmtError> {
        if self.converged() {
            return Ok(self);
        }
        Err(OmtError::NoConvergence {
            iterations: self.iterations,
            residual: self.max_relative_error,
            tolerance: self.tolerance,
            reason: self.stop_description(),
        })
    }

    /// Newton steps on every level: [`OtSolution::iterations`] (the finest level, with a
    /// continuation's stages) plus, after a coarse-to-fine start, the coarser levels' steps.
    pub fn all_iterations(&self) -> usize {
        self.iterations
            + match self.start {
                Start::CoarseToFine { coarse_iterations, .. } => coarse_iterations,
                _ => 0,
            }
    }

    /// The stop reason with the [`OtSolution::diagnosis`], if any, for reports and messages.
    pub fn stop_description(&self) -> String {
        match &self.diagnosis {
            Some(d) => format!("{}{d}", self.stop),
            None => self.stop.to_string(),
        }
    }

    /// The Kantorovich dual value at the final heights,
    /// $$ F = \sum_i w_i \nu_i + \sum_i \int_{W_i} (|x - y_i|^2 - w_i)\,d\mu
    ///      = \text{cost} + \sum_i w_i (\nu_i - \mu(W_i)), $$
    /// with w_i = 2h_i + |y_i|² the power weights (W_i is where |x − y_i|² − w_i is smallest)
    /// and ν the rescaled targets. By weak duality F ≤ W²(μ, ν) for any heights; F − W² is
    /// second order in the mass residual G = μ(W) − ν (≈ −GᵀH⁻¹G with the Newton Hessian
    /// H = ∂μ(W)/∂h), while [`OtSolution::cost`], the exact cost towards the masses μ(W_i)
    /// instead of ν, is off at first order (C − F = Σ_i w_i G_i). So F is within about GᵀH⁻¹G
    /// of W², and the gap C − F measures the cost's first-order error a posteriori (as long as
    /// the residual is not smooth over the whole domain, where GᵀH⁻¹G can reach
    /// ~e²·μ(Ω)·diam(Ω)² for a max relative mass error e).
    pub fn dual_value(&self) -> f64 {
        let correction: f64 = self
            .weights
            .iter()
            .zip(&self.target_masses)
            .zip(&self.cells.masses)
            .map(|((w, nu), m)| w * (nu - m))
            .sum();
        self.cost + correction
    }

    /// μ-centroids of the cells (#N; `None` for an empty cell).
    pub fn centroids(&self) -> Vec<Option<[f64; 2]>> {
        self.cells.centroids()
    }
}

/// Power weights w_i = 2h_i + |y_i|² of heights h (#N).
pub fn weights_from_heights(points: &[[f64; 2]], heights: &[f64]) -> Vec<f64> {
    points
        .iter()
        .zip(heights)
        .map(|(y, h)| 2.0 * h + y[0] * y[0] + y[1] * y[1])
        .collect()
}

/// Heights h_i = (w_i − |y_i|²)/2 of power weights w (#N).
pub fn heights_from_weights(points: &[[f64; 2]], weights: &[f64]) -> Vec<f64> {
    points
        .iter()
        .zip(weights)
        .map(|(y, w)| 0.5 * (w - y[0] * y[0] - y[1] * y[1]))
        .collect()
}

/// The Kantorovich energy E(h) = ∫_Ω u_h dμ − Σ ν_i h_i, evaluated exactly from the cell
/// integrals at h: on W_i, u_h(x) = ⟨x, y_i⟩ + h_i, so ∫ u_h dμ = Σ_i ⟨∫_{W_i} x dμ, y_i⟩ + h_i μ(W_i).
pub fn kantorovich_energy(points: &[[f64; 2]], heights: &[f64], targets: &[f64], cells: &CellIntegrals) -> f64 {
    (0..points.len())
        .map(|i| {
            let m1 = cells.first_moments[i];
            m1[0] * points[i][0] + m1[1] * points[i][1] + heights[i] * (cells.masses[i] - targets[i])
        })
        .sum()
}

/// Cell integrals with timings (diagram, integration) in seconds.
pub(crate) struct Evaluation {
    pub cells: CellIntegrals,
    pub t_diagram: f64,
    pub t_integration: f64,
    /// The symbolic factorization for the diagram's pattern, computed alongside the
    /// integration when the evaluation was asked to speculate (see
    /// [`crate::linear::NewtonSystem::speculate`]).
    pub speculative: Option<SpeculativeSymbolic>,
    /// The power diagram that was integrated (restricted backend), from which the next
    /// line search's trials are updated by flips.
    pub diagram: Option<PowerDiagram>,
    /// Whether that diagram (or the sites found hidden) came from flips of the previous one.
    pub by_flips: bool,
}

/// Integrates the cells of heights `heights` (#N) with the chosen integrator.
pub fn integrate_at_heights(
    measure: &SourceMeasure,
    points: &[[f64; 2]],
    heights: &[f64],
    integrator: CellIntegrator,
) -> Result<CellIntegrals, OmtError> {
    evaluate(
        &Backend::new(measure, integrator, None),
        points,
        &Heights::from_f64(heights.to_vec()),
    )
    .map(|e| e.cells)
}

/// The flux form's error bound per cell relative to its mass in a solve with `params`: a
/// hundredth of the tolerance, so that the masses' errors stay far below what the convergence
/// test resolves (1e-8 by default; at 1e-10 the form declines almost everywhere and the solve
/// integrates in full); `None` with `flux_masses` off.
fn flux_bound(params: &NewtonParams) -> Option<f64> {
    params.flux_masses.then_some(0.01 * params.tolerance)
}

/// The cell integrator with its per-measure precomputation, and the insertion order of the
/// points (computed at the first evaluation; a backend serves one set of points). One backend
/// lives for a whole solve, so the size of the `Restricted` variant costs nothing; boxing it
/// would add an indirection to every evaluation.
#[allow(clippy::large_enum_variant)]
pub(crate) enum Backend<'a> {
    Restricted(RestrictedIntegrator, OnceLock<InsertionOrder>),
    BruteForce(&'a SourceMeasure),
}

impl<'a> Backend<'a> {
    /// `flux_bound`: the flux form's error bound relative to each cell's mass (`None`: every
    /// evaluation integrated in full); see [`NewtonParams::flux_masses`] and [`flux_bound`].
    pub(crate) fn new(measure: &'a SourceMeasure, integrator: CellIntegrator, flux_bound: Option<f64>) -> Self {
        match integrator {
            CellIntegrator::Restricted => Backend::Restricted(
                RestrictedIntegrator::new(measure).with_flux_form(flux_bound),
                OnceLock::new(),
            ),
            CellIntegrator::BruteForce => Backend::BruteForce(measure),
        }
    }
}

/// Replaces the cells of an evaluation whose masses came from the flux form (no moments) by the
/// full integrals of its diagram (or of the diagram of `heights`, rebuilt, if it has none);
/// true when it did.
fn complete_moments(
    backend: &Backend<'_>,
    points: &[[f64; 2]],
    heights: &Heights,
    evaluation: &mut Evaluation,
) -> Result<bool, OmtError> {
    if evaluation.cells.has_moments() {
        return Ok(false);
    }
    let Backend::Restricted(integrator, order) = backend else {
        return Ok(false);
    };
    let t0 = Instant::now();
    evaluation.cells = match &evaluation.diagram {
        Some(diagram) => integrator.integrate(diagram),
        None => {
            let order = cached_order(order, points)?;
            let (weights, weights_lo) = heights.weights(points);
            integrator.integrate(&PowerDiagram::with_order_dd(
                points,
                &weights,
                Some(&weights_lo),
                &order,
            )?)
        }
    };
    evaluation.t_integration += t0.elapsed().as_secs_f64();
    Ok(true)
}

/// The evaluation of `heights` from their power diagram `diagram` (built by the caller, e.g. the
/// coarse-to-fine start's last check), with that diagram's insertion `order` kept for the
/// later evaluations when the backend has none yet.
pub(crate) fn evaluate_diagram(
    backend: &Backend<'_>,
    points: &[[f64; 2]],
    heights: &Heights,
    diagram: PowerDiagram,
    order: InsertionOrder,
) -> Evaluation {
    let t0 = Instant::now();
    let (cells, diagram) = match backend {
        Backend::Restricted(integrator, cached) => {
            let _ = cached.set(order);
            (integrator.integrate_masses(&diagram), Some(diagram))
        }
        Backend::BruteForce(measure) => (
            crate::reference::integrate_cells_bruteforce(points, &heights.weights(points).0, measure),
            None,
        ),
    };
    Evaluation {
        cells,
        t_diagram: 0.0,
        t_integration: t0.elapsed().as_secs_f64(),
        speculative: None,
        diagram,
        by_flips: false,
    }
}

/// The backend's insertion order of `points`: the cached one, computed and cached on first use,
/// or (for a point set of another size than the cached one) computed without caching.
fn cached_order<'b>(
    cached: &'b OnceLock<InsertionOrder>,
    points: &[[f64; 2]],
) -> Result<std::borrow::Cow<'b, InsertionOrder>, OmtError> {
    use std::borrow::Cow;
    Ok(match cached.get() {
        Some(order) if order.len() == points.len() => Cow::Borrowed(order),
        Some(_) => Cow::Owned(InsertionOrder::new(points)?),
        None => {
            let computed = InsertionOrder::new(points)?;
            Cow::Borrowed(cached.get_or_init(|| computed))
        }
    })
}

/// [`evaluate`], also returning the insertion order when all weights are exactly 0 (none with
/// the brute-force backend): the evaluation's diagram is then the Delaunay triangulation, which
/// Auto's Voronoi test hands with the order to the coarse-to-fine start (its coarsening needs
/// that triangulation first, its check the order).
fn evaluate_keeping_diagram(
    backend: &Backend<'_>,
    points: &[[f64; 2]],
    heights: &Heights,
) -> Result<(Evaluation, Option<InsertionOrder>), OmtError> {
    let Backend::Restricted(_, cached) = backend else {
        return Ok((evaluate(backend, points, heights)?, None));
    };
    let t0 = Instant::now();
    let order = cached_order(cached, points)?.into_owned();
    let (weights, weights_lo) = heights.weights(points);
    let diagram = PowerDiagram::with_order_dd(points, &weights, Some(&weights_lo), &order)?;
    let t_diagram = t0.elapsed().as_secs_f64();
    // The Voronoi heights give weights exactly 0 except for points within ~1e-146 of the origin
    // (subnormal |y|²); only an exact Delaunay triangulation is handed on.
    let delaunay = weights.iter().chain(&weights_lo).all(|&w| w == 0.0);
    let kept = delaunay.then(|| order.clone());
    let mut evaluation = evaluate_diagram(backend, points, heights, diagram, order);
    evaluation.t_diagram = t_diagram;
    Ok((evaluation, kept))
}

pub(crate) fn evaluate(backend: &Backend<'_>, points: &[[f64; 2]], heights: &Heights) -> Result<Evaluation, OmtError> {
    evaluate_unless_hidden(backend, points, heights, false, None, None)
}

/// [`evaluate`]; with `skip_if_hidden`, a diagram with a hidden site (an empty cell: mass 0 < ε₀,
/// so a line-search trial that must be rejected) is not integrated: the masses are 0 for the
/// hidden sites and NaN for the others, the moments NaN and the edge list empty. With
/// `speculate`, the symbolic factorization the next Newton direction would need if this trial
/// is accepted is computed on another thread while the cells are integrated (the integration
/// is parallel too, so on two cores the ordering takes about half of one core's share of it).
/// With `previous` (a diagram of the same points), the power diagram is updated from it by
/// flips ([`PowerDiagram::with_order_dd_unless_hidden_from`]; the same diagram as built anew).
pub(crate) fn evaluate_unless_hidden(
    backend: &Backend<'_>,
    points: &[[f64; 2]],
    heights: &Heights,
    skip_if_hidden: bool,
    speculate: Option<&NewtonSystem>,
    previous: Option<&PowerDiagram>,
) -> Result<Evaluation, OmtError> {
    let (weights, weights_lo) = heights.weights(points);
    if let Some(i) = (0..weights.len()).find(|&i| !(weights[i].is_finite() && weights_lo[i].is_finite())) {
        return Err(OmtError::InvalidInput(format!(
            "height {i} is not finite ({})",
            heights.hi[i]
        )));
    }
    match backend {
        Backend::BruteForce(measure) => {
            let t0 = Instant::now();
            let cells = crate::reference::integrate_cells_bruteforce(points, &weights, measure);
            Ok(Evaluation {
                cells,
                t_diagram: 0.0,
                t_integration: t0.elapsed().as_secs_f64(),
                speculative: None,
                diagram: None,
                by_flips: false,
            })
        }
        Backend::Restricted(integrator, order) => {
            let t0 = Instant::now();
            let order = cached_order(order, points)?;
            let order = &*order;
            // A trial that hides a site is rejected whatever the other cells. The line search only
            // needs to know whether more than a tenth vanished (then it cuts τ tenfold) or else
            // which ones did, so the construction stops once more than a tenth are hidden (those
            // are hidden in the full diagram too). On a Voronoi start of a conformal image, where
            // most sites are hidden at τ = 1, that is a fraction of the insertions.
            let max_hidden = if skip_if_hidden {
                line_search::hidden_limit(points.len())
            } else {
                usize::MAX
            };
            let (construction, by_flips) = match previous {
                Some(previous) => PowerDiagram::with_order_dd_unless_hidden_from(
                    previous,
                    points,
                    &weights,
                    Some(&weights_lo),
                    order,
                    max_hidden,
                )?,
                None => (
                    PowerDiagram::with_order_dd_unless_hidden(points, &weights, Some(&weights_lo), order, max_hidden)?,
                    false,
                ),
            };
            let diagram = match construction {
                Construction::Complete(diagram) => diagram,
                Construction::Hidden { hidden, .. } => {
                    return Ok(masked_evaluation(
                        points.len(),
                        &hidden,
                        t0.elapsed().as_secs_f64(),
                        by_flips,
                    ));
                }
            };
            let t_diagram = t0.elapsed().as_secs_f64();
            if skip_if_hidden {
                let hidden: Vec<u32> = (0..points.len() as u32)
                    .filter(|&i| diagram.is_hidden(i as usize))
                    .collect();
                if !hidden.is_empty() {
                    return Ok(masked_evaluation(points.len(), &hidden, t_diagram, by_flips));
                }
            }
            let t1 = Instant::now();
            let (cells, speculative) = match speculate.filter(|system| system.speculates(points.len())) {
                Some(system) => {
                    let (cells, speculative) = rayon::join(
                        || integrator.integrate_masses(&diagram),
                        || system.speculate(points.len(), &diagram_pairs(&diagram)),
                    );
                    (cells, speculative.transpose()?)
                }
                None => (integrator.integrate_masses(&diagram), None),
            };
            Ok(Evaluation {
                cells,
                t_diagram,
                t_integration: t1.elapsed().as_secs_f64(),
                speculative,
                diagram: Some(diagram),
                by_flips,
            })
        }
    }
}

/// The power diagram's neighbour pairs (i < j), sorted: a superset of the pairs whose common
/// edge meets Ω, for [`NewtonSystem::speculate`].
fn diagram_pairs(diagram: &PowerDiagram) -> Vec<(u32, u32)> {
    let offsets = diagram.neighbor_offsets();
    let list = diagram.neighbor_list();
    let mut pairs = Vec::with_capacity(list.len() / 2);
    for i in 0..diagram.num_sites() {
        for &j in &list[offsets[i] as usize..offsets[i + 1] as usize] {
            if (i as u32) < j {
                pairs.push((i as u32, j));
            }
        }
    }
    pairs.sort_unstable();
    pairs.dedup();
    pairs
}

/// The evaluation of a rejected trial that hides sites `hidden` among `n`: mass 0 for those,
/// NaN for the other masses and the moments, no edges.
fn masked_evaluation(n: usize, hidden: &[u32], t_diagram: f64, by_flips: bool) -> Evaluation {
    let mut masses = vec![f64::NAN; n];
    for &i in hidden {
        masses[i as usize] = 0.0;
    }
    Evaluation {
        cells: CellIntegrals {
            masses,
            first_moments: vec![[f64::NAN; 2]; n],
            second_moments: vec![f64::NAN; n],
            edge_masses: Vec::new(),
        },
        t_diagram,
        t_integration: 0.0,
        speculative: None,
        diagram: None,
        by_flips,
    }
}

/// Whether the last [`STALL_WINDOW`] steps of `log` were all cut by the damping to
/// τ < [`STALL_TAU`] and lowered the max relative error by less than [`STALL_GAIN`] together
/// (records hold the error after their step).
fn no_progress(log: &[IterationRecord]) -> bool {
    let Some(k) = log.len().checked_sub(STALL_WINDOW + 1) else {
        return false;
    };
    let window = &log[k..];
    window[1..]
        .iter()
        .all(|r| r.step < STALL_TAU && r.rejected_min_mass + r.rejected_norm > 0)
        && window[STALL_WINDOW].max_relative_error > (1.0 - STALL_GAIN) * window[0].max_relative_error
}

/// Whether the last [`FLAT_WINDOW`] steps of `log` all had τ < [`FLAT_TAU`], the largest τ of
/// the window's second half is at most [`FLAT_GROWTH`] times that of its first half (τ no longer
/// grows), and together they lowered the max relative error by less than [`STALL_GAIN`].
/// Measured on TOSCA michael0 from the Voronoi start: after τ grew 4× per step to
/// ~1e-14 it oscillated between 1e-16 and 7e-14 for 70 steps, the error fixed at 5.64e3 (the
/// points are a few ulps apart), until the iteration cap; horse5, which converges, grows τ 4×
/// per step from 1e-26 to 1e-4 with a flat error (growth: not a stall) and then lowers the
/// error by 1–2 % per 20 steps at τ ≈ 1e-4 … 1e-2. victoria0's plateau sits at 6e-11 … 2.3e-9,
/// hence FLAT_TAU = 1e-6: with τ below 1e-6 and not growing, the 100 steps of the iteration
/// cap cover less than 1e-4 of a Newton step.
fn flat_without_growth(log: &[IterationRecord]) -> bool {
    let Some(k) = log.len().checked_sub(FLAT_WINDOW + 1) else {
        return false;
    };
    let window = &log[k..];
    let steps = &window[1..];
    let half = FLAT_WINDOW / 2;
    let max_tau = |r: &[IterationRecord]| r.iter().map(|r| r.step).fold(0.0f64, f64::max);
    steps.iter().all(|r| r.step < FLAT_TAU)
        && max_tau(&steps[half..]) <= FLAT_GROWTH * max_tau(&steps[..half])
        && window[FLAT_WINDOW].max_relative_error > (1.0 - STALL_GAIN) * window[0].max_relative_error
}

/// max_i |G_i| / ν_i and ‖G‖₂ for G = masses − targets.
pub(crate) fn errors(cells: &CellIntegrals, targets: &[f64]) -> (f64, f64, Vec<f64>) {
    let gradient: Vec<f64> = cells.masses.iter().zip(targets).map(|(m, t)| m - t).collect();
    let max_rel = gradient
        .iter()
        .zip(targets)
        .map(|(g, t)| g.abs() / t)
        .fold(0.0, f64::max);
    let norm = gradient.iter().map(|g| g * g).sum::<f64>().sqrt();
    (max_rel, norm, gradient)
}

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
    measure: &SourceMeasure,
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

/// Smallest continuation increment Δt before the density continuation gives up.
const MIN_CONTINUATION_STEP: f64 = 1.0 / 512.0;

/// The density continuation of [`NewtonParams::density_continuation`], adaptive: ρ_t = ρ^t from
/// t = 0 in increments Δt (initially 1/`stages`), each stage warm-started from the last converged
/// one; intermediate stages stop at max(tolerance, 1e-3) within max_iterations/2 steps. A stage that
/// does not converge is discarded and retried with Δt halved (below 1/512 the solve stops as
/// `Stalled`, with the reason); a stage that converges in a quarter of its budget doubles Δt.
/// The last stage (t = 1) is the problem itself with the full iteration budget; if it does not
/// converge, Δt is halved and the path continues from the last converged stage.
fn solve_density_continuation(
    measure: &SourceMeasure,
    points: &[[f64; 2]],
    masses: &[f64],
    params: &NewtonParams,
    stages: usize,
    t_begin: Instant,
) -> Result<OtSolution, OmtError> {
    let stage_cap = (params.max_iterations / 2).max(1);
    let (mut t, mut dt) = (0.0f64, 1.0 / stages as f64);
    let mut heights: Option<(Vec<f64>, Vec<f64>)> = None;
    let mut log = Vec::new();
    let (mut iterations, mut evaluations, mut solved_stages) = (0, 0, 0);
    loop {
        let t_next = if t + dt >= 1.0 - 1e-12 { 1.0 } else { t + dt };
        let last = t_next == 1.0;
        let stage_measure;
        let stage_source = if last {
            measure
        } else {
            stage_measure = SourceMeasure::from_checked_parts(
                measure.vertices.clone(),
                measure.triangles.clone(),
                measure.densities.iter().map(|d| d.powf(t_next)).collect(),
            );
            &stage_measure
        };
        let stage_params = NewtonParams {
            tolerance: if last {
                params.tolerance
            } else {
                params.tolerance.max(1e-3)
            },
            max_iterations: if last { params.max_iterations } else { stage_cap },
            initial_heights: heights.as_ref().map(|h| h.0.clone()),
            initial_heights_lo: heights.as_ref().map(|h| h.1.clone()),
            density_continuation: None,
            ..params.clone()
        };
        let mut stage = solve_single(stage_source, points, masses, &stage_params, Instant::now(), None)?;
        iterations += stage.iterations;
        evaluations += stage.evaluations;
        let converged = stage.converged();
        let timed_out = stage.stop == StopReason::TimeLimit;
        let give_up = !converged && (timed_out || dt * 0.5 < MIN_CONTINUATION_STEP);
        if (converged && last) || give_up {
            if give_up && !last && !timed_out {
                stage.stop = StopReason::Stalled {
                    reason: format!(
                        "density continuation could not advance past t = {t:.4}: the stage toward t = {t_next:.4} stopped ({})",
                        stage.stop
                    ),
                };
            }
            stage.start = Start::DensityContinuation {
                stages: solved_stages + 1,
                iterations: iterations - stage.iterations,
            };
            stage.iterations = iterations;
            stage.evaluations = evaluations;
            log.append(&mut stage.log);
            stage.log = log;
            stage.t_total = t_begin.elapsed().as_secs_f64();
            return Ok(stage);
        }
        log.append(&mut stage.log);
        if converged {
            solved_stages += 1;
            heights = Some((stage.heights, stage.heights_lo));
            t = t_next;
            if stage.iterations * 4 <= stage_cap {
                dt *= 2.0;
            }
        } else {
            dt *= 0.5;
        }
    }
}

/// The mass continuation of [`NewtonParams::mass_continuation`].
fn solve_mass_continuation(
    measure: &SourceMeasure,
    points: &[[f64; 2]],
    masses: &[f64],
    params: &NewtonParams,
    ratio: f64,
    t_begin: Instant,
) -> Result<OtSolution, OmtError> {
    if !(ratio > 1.0 && ratio.is_finite()) {
        return Err(OmtError::InvalidInput(format!(
            "mass continuation ratio {ratio} (must be finite and > 1)"
        )));
    }
    let base = NewtonParams {
        mass_continuation: None,
        density_continuation: None,
        initial_heights: None,
        ..params.clone()
    };
    // The start alone (no step): its cell masses m⁰ are all > 0.
    let start = solve_single(
        measure,
        points,
        masses,
        &NewtonParams {
            max_iterations: 0,
            ..base.clone()
        },
        Instant::now(),
        None,
    )?;
    let m0 = start.cells.masses.clone();
    let targets = &start.target_masses;
    let mut heights = start.heights;
    let mut heights_lo = start.heights_lo;
    let (mut t, mut stages, mut iterations, mut log) = (0.0f64, 0usize, 0usize, Vec::new());
    let mut evaluations = start.evaluations;
    loop {
        // The largest t' ≤ 1 with ν_i(t') / ν_i(t) ∈ [1/r, r] for all i (ν_i(t) is linear in t).
        let mut t_next = 1.0f64;
        for (&a, &b) in m0.iter().zip(targets) {
            let (d, current) = (b - a, a + t * (b - a));
            let bound = if d > 0.0 {
                (ratio * current - a) / d
            } else if d < 0.0 {
                (current / ratio - a) / d
            } else {
                f64::INFINITY
            };
            t_next = t_next.min(bound);
        }
        let last = t_next >= 1.0;
        let t_stage = if last { 1.0 } else { t_next };
        let stage_targets: Vec<f64> = m0
            .iter()
            .zip(targets)
            .map(|(&a, &b)| (1.0 - t_stage) * a + t_stage * b)
            .collect();
        let stage_params = NewtonParams {
            tolerance: if last {
                params.tolerance
            } else {
                params.tolerance.max(1e-3)
            },
            initial_heights: Some(heights),
            initial_heights_lo: Some(heights_lo),
            ..base.clone()
        };
        let mut stage = solve_single(measure, points, &stage_targets, &stage_params, Instant::now(), None)?;
        stages += 1;
        if last || !stage.converged() {
            // The final problem, or an intermediate stage that failed (reported as it stopped).
            stage.start = Start::MassContinuation { stages, iterations };
            stage.iterations += iterations;
            stage.evaluations += evaluations;
            log.append(&mut stage.log);
            stage.log = log;
            if !last && stage.stop != StopReason::TimeLimit {
                stage.stop = StopReason::Stalled {
                    reason: format!(
                        "mass continuation stage {stages} at t = {t_stage:.3e} stopped: {}",
                        stage.stop
                    ),
                };
            }
            stage.target_masses = targets.clone();
            stage.mass_scale = start.mass_scale;
            stage.t_total = t_begin.elapsed().as_secs_f64();
            return Ok(stage);
        }
        iterations += stage.iterations;
        evaluations += stage.evaluations;
        log.append(&mut stage.log);
        heights = stage.heights;
        heights_lo = stage.heights_lo;
        t = t_stage;
    }
}

/// One damped Newton solve (no density continuation). `prepared`: the backend and the
/// evaluation of the start heights when the caller has them: of the Voronoi heights without a
/// warm start, of `params.initial_heights` with one (the backend keeps its insertion order and
/// integration seeds). The caller guarantees that the evaluation is of those heights: a
/// mismatched one would be taken as the start.
fn solve_single(
    measure: &SourceMeasure,
    points: &[[f64; 2]],
    masses: &[f64],
    params: &NewtonParams,
    t_begin: Instant,
    prepared: Option<(Backend<'_>, Evaluation)>,
) -> Result<OtSolution, OmtError> {
    let n = points.len();
    let total = measure.total_mass();
    let mass_scale = total / masses.iter().sum::<f64>();
    let targets: Vec<f64> = masses.iter().map(|m| m * mass_scale).collect();

    // Initial heights and their evaluation; every cell must be non-empty.
    let mut start = Start::Voronoi;
    let mut heights = match &params.initial_heights {
        Some(h) => {
            start = Start::Warm;
            match &params.initial_heights_lo {
                Some(lo) => Heights::from_parts(h, lo),
                None => Heights::from_f64(h.clone()),
            }
        }
        None => Heights::voronoi(points),
    };
    let (backend, mut current) = match prepared {
        Some((backend, evaluation)) => (backend, evaluation),
        None => {
            let backend = Backend::new(measure, params.integrator, flux_bound(params));
            let evaluation = evaluate(&backend, points, &heights)?;
            (backend, evaluation)
        }
    };
    let mut start_evaluations = 1;
    if current.cells.masses.iter().any(|&m| !(m > 0.0)) {
        let center = domain_centroid(measure);
        let (lo, hi) = crate::measure::bounding_box(&measure.vertices);
        let empty_at = |cells: &CellIntegrals| cells.masses.iter().filter(|&&m| !(m > 0.0)).count();
        let mut fewest_empty = empty_at(&current.cells);
        let first_empty: Vec<usize> = (0..n).filter(|&i| !(current.cells.masses[i] > 0.0)).collect();
        let first_start = start.clone();
        // Plain Voronoi first (if that was not the start), then contracted ones. Contraction
        // brings points from outside Ω in; once every contracted point lies in Ω's bounding box
        // and four more halvings empty no fewer cells, the empty cells come from points too close
        // together for f64 (crowding), which contraction cannot cure: stop there.
        let mut scale = if start == Start::Voronoi { 1.0 } else { 2.0 };
        let mut stale = 0;
        loop {
            if params.past_deadline() {
                return Err(OmtError::TimeLimit(
                    "searching for a start with no empty cell (contracted Voronoi diagrams)".into(),
                ));
            }
            scale *= 0.5;
            heights = Heights::contracted(points, center, scale);
            current = evaluate(&backend, points, &heights)?;
            start_evaluations += 1;
            let empty = empty_at(&current.cells);
            if empty == 0 {
                break;
            }
            if empty < fewest_empty {
                fewest_empty = empty;
                stale = 0;
            } else {
                stale += 1;
            }
            let inside = points.iter().all(|y| {
                (0..2).all(|d| {
                    let z = center[d] + scale * (y[d] - center[d]);
                    lo[d] <= z && z <= hi[d]
                })
            });
            if (inside && stale >= 4) || scale < 1e-30 {
                return Err(OmtError::InvalidInput(no_start_diagnosis(
                    points,
                    &first_empty,
                    first_start,
                    lo,
                    hi,
                    scale,
                )));
            }
        }
        start = if scale == 1.0 {
            Start::Voronoi
        } else {
            Start::Contracted { scale }
        };
    }
    let t_start = t_begin.elapsed().as_secs_f64();

    let min_target = targets.iter().cloned().fold(f64::INFINITY, f64::min);
    let min_mass0 = current.cells.masses.iter().cloned().fold(f64::INFINITY, f64::min);
    let epsilon0 = 0.5 * min_target.min(min_mass0);
    let pinned = (0..n).fold(0, |best, i| if targets[i] > targets[best] { i } else { best });
    let mut system = NewtonSystem::new(pinned, params.linear_solver.clone());

    let (mut max_rel, mut norm, mut gradient) = errors(&current.cells, &targets);
    let mut log = Vec::new();
    let stop;
    let mut iterations = 0;
    let mut tau_start = 1.0;
    let mut target_cap = params.target_ratio_cap;
    loop {
        if !(max_rel.is_finite() && norm.is_finite()) {
            stop = StopReason::Stalled {
                reason: "non-finite cell masses".into(),
            };
            break;
        }
        if max_rel <= params.tolerance {
            // (decided on the full integrals: the flux form's masses may differ by ~1e-12)
            if complete_moments(&backend, points, &heights, &mut current)? {
                (max_rel, norm, gradient) = errors(&current.cells, &targets);
            }
            if max_rel <= params.tolerance {
                stop = StopReason::Converged;
                break;
            }
        }
        if iterations >= params.max_iterations {
            stop = StopReason::IterationCap;
            break;
        }
        if params.past_deadline() {
            stop = StopReason::TimeLimit;
            break;
        }
        let t_solve = Instant::now();
        // The step's targets: intermediate ones for the cells far from theirs (module docs).
        let step = target_cap.and_then(|cap| intermediate_targets(&current.cells.masses, &targets, cap));
        let step_errors = step.as_ref().map(|(t, _)| errors(&current.cells, t));
        let (step_targets, step_norm, step_gradient) = match (&step, &step_errors) {
            (Some((t, _)), Some((_, norm, gradient))) => (t, *norm, gradient),
            _ => (&targets, norm, &gradient),
        };
        let delta = system.newton_direction(points, &current.cells, step_gradient)?;
        let t_solve = t_solve.elapsed().as_secs_f64();
        if delta.iter().any(|d| !d.is_finite()) {
            stop = StopReason::Stalled {
                reason: "the Newton direction is not finite".into(),
            };
            break;
        }
        let outcome = line_search::damped_step(
            &backend,
            points,
            step_targets,
            &heights,
            &current.cells,
            &delta,
            step_norm,
            epsilon0,
            params.max_halvings,
            tau_start,
            Some(&system),
            current.diagram.as_ref().filter(|_| params.flip_updates),
        )?;
        iterations += 1;
        let mut record = IterationRecord {
            max_relative_error: max_rel,
            gradient_norm: norm,
            step: 0.0,
            halvings: outcome.rejections(),
            evaluations: outcome.rejections() + usize::from(outcome.accepted.is_some()),
            rejected_min_mass: outcome.rejected_min_mass,
            rejected_norm: outcome.rejected_norm,
            flip_updates: outcome.flip_updates,
            min_cell_mass: current.cells.masses.iter().cloned().fold(f64::INFINITY, f64::min),
            t_diagram: outcome.t_diagram,
            t_integration: outcome.t_integration,
            t_solve,
            intermediate_targets: step.as_ref().map_or(0, |s| s.1),
        };
        if step.is_some() && outcome.accepted.as_ref().is_none_or(|s| s.tau < TARGET_CAP_MIN_TAU) {
            // Intermediate targets that do not pay (crowded cells that must grow by many
            // orders of magnitude): the plain KMT steps from here on.
            target_cap = None;
            if outcome.accepted.is_none() {
                // (the trials are counted; the step is retried with the plain targets)
                log.push(record);
                continue;
            }
        }
        match outcome.accepted {
            Some(step) => {
                heights = step.heights;
                current = step.evaluation;
                if let Some(speculative) = current.speculative.take() {
                    system.adopt(speculative, &current.cells);
                }
                (max_rel, norm, gradient) = errors(&current.cells, &targets);
                record.step = step.tau;
                let growth = if outcome.rejected_min_mass + outcome.rejected_norm == 0 {
                    TAU_GROWTH_FREE
                } else {
                    TAU_GROWTH
                };
                tau_start = (growth * step.tau).min(1.0);
                record.max_relative_error = max_rel;
                record.gradient_norm = norm;
                record.min_cell_mass = current.cells.masses.iter().cloned().fold(f64::INFINITY, f64::min);
                log.push(record);
                let what = if no_progress(&log) {
                    Some(format!(
                        "{STALL_WINDOW} steps, each cut by the damping to τ < {STALL_TAU:e},"
                    ))
                } else if flat_without_growth(&log) {
                    Some(format!("{FLAT_WINDOW} steps of τ < {FLAT_TAU:e} that stopped growing"))
                } else {
                    None
                };
                if let Some(what) = what {
                    let (lo, hi) = crate::measure::bounding_box(&measure.vertices);
                    stop = StopReason::Stalled {
                        reason: format!(
                            "no progress: {what} left the max relative mass error at {max_rel:e}{}",
                            stall_diagnosis(points, &current.cells.masses, lo, hi)
                        ),
                    };
                    break;
                }
            }
            None => {
                log.push(record);
                let (lo, hi) = crate::measure::bounding_box(&measure.vertices);
                stop = StopReason::Stalled {
                    reason: format!(
                        "no step τ ≥ 2^-{} satisfied the damping conditions (max relative mass error {max_rel:e}){}",
                        params.max_halvings,
                        stall_diagnosis(points, &current.cells.masses, lo, hi)
                    ),
                };
                break;
            }
        }
    }
    if complete_moments(&backend, points, &heights, &mut current)? {
        (max_rel, _, _) = errors(&current.cells, &targets);
    }
    let weights = heights.weights(points).0;
    let cost = current.cells.transport_cost();
    let diagnosis = if stop == StopReason::IterationCap {
        let (lo, hi) = crate::measure::bounding_box(&measure.vertices);
        Some(stall_diagnosis(points, &current.cells.masses, lo, hi)).filter(|d| !d.is_empty())
    } else {
        None
    };
    Ok(OtSolution {
        heights: heights.hi,
        heights_lo: heights.lo,
        weights,
        cells: current.cells,
        cost,
        iterations,
        evaluations: start_evaluations + log.iter().map(|r| r.evaluations).sum::<usize>(),
        max_relative_error: max_rel,
        tolerance: params.tolerance,
        stop,
        log,
        mass_scale,
        target_masses: targets,
        epsilon0,
        start,
        t_start,
        t_total: t_begin.elapsed().as_secs_f64(),
        symbolic_factorizations: system.symbolic_factorizations,
        orderings: system.orderings,
        t_assembly: system.t_assembly,
        t_symbolic: system.t_symbolic,
        t_numeric: system.t_numeric,
        diagnosis,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    fn record(error: f64, step: f64, rejected: usize) -> IterationRecord {
        IterationRecord {
            max_relative_error: error,
            step,
            rejected_min_mass: rejected,
            ..Default::default()
        }
    }

    /// The soft cap (κ = 32, K = ln 32): a cell with 1e-3 of its target aims at
    /// exp(K tanh(ln 1000 / K)) ≈ 28.2 times its mass, one with 10 times its target at
    /// exp(K tanh(ln 0.1 / K)) ≈ 0.133 of it; cells at 0.9 and 1.2 of their targets (a change
    /// below 0.1 %) keep them; the targets are rescaled to their old sum. All within the band:
    /// no intermediate targets.
    #[test]
    fn intermediate_targets_soft_cap_far_cells_and_keep_near_ones() {
        let masses = [1e-3, 1.0, 10.0, 1.2, 0.9];
        let targets = [1.0; 5];
        let (step, capped) = intermediate_targets(&masses, &targets, 32.0).unwrap();
        assert_eq!(capped, 2);
        let k = 32f64.ln();
        let raw = [
            1e-3 * (k * (1000f64.ln() / k).tanh()).exp(),
            1.0,
            10.0 * (k * (0.1f64.ln() / k).tanh()).exp(),
            1.0,
            1.0,
        ];
        assert!(
            (raw[0] / 1e-3 - 28.2).abs() < 0.05 && (raw[2] / 10.0 - 0.1333).abs() < 1e-3,
            "{raw:?}"
        );
        let scale = 5.0 / raw.iter().sum::<f64>();
        for i in 0..5 {
            assert!(
                (step[i] - scale * raw[i]).abs() <= 1e-15 * raw[i],
                "{i}: {} vs {}",
                step[i],
                scale * raw[i]
            );
            // between the mass and the target (before the common rescaling)
            let (lo, hi) = (masses[i].min(targets[i]), masses[i].max(targets[i]));
            assert!(lo <= raw[i] && raw[i] <= hi);
        }
        assert!((step.iter().sum::<f64>() - 5.0).abs() < 1e-14);
        assert!(intermediate_targets(&[0.8, 1.3, 1.0], &[1.0; 3], 32.0).is_none());
    }

    #[test]
    fn no_progress_needs_ten_cut_tiny_steps_without_gain() {
        // eleven records: the first is the reference, the last ten cut to τ ≈ 2e-30
        let stalled: Vec<_> = (0..11)
            .map(|k| record(20.0, 2e-30 * (1.0 + (k % 2) as f64), 3))
            .collect();
        assert!(no_progress(&stalled));
        // one record fewer: not yet
        assert!(!no_progress(&stalled[1..]));
        // τ growing from 1e-26 by 4 per step, every step accepted at its first trial (a crowded
        // Voronoi start on its way out): not a stall
        let growing: Vec<_> = (0..11).map(|k| record(380.0, 1e-26 * 4f64.powi(k), 0)).collect();
        assert!(!no_progress(&growing));
        // cut tiny steps that still lower the error by 1 % over the window: not a stall
        let slow: Vec<_> = (0..11)
            .map(|k| record(20.0 * (1.0 - 1e-3 * k as f64), 1e-25, 2))
            .collect();
        assert!(!no_progress(&slow));
        // one step of the window with τ ≥ 1e-20: not a stall
        let mut mixed = stalled.clone();
        mixed[6].step = 1e-12;
        assert!(!no_progress(&mixed));
    }

    #[test]
    fn flat_without_growth_needs_twenty_tiny_steps_that_stopped_growing() {
        // michael0-like: τ oscillating around 1e-14 (some steps accepted at the first trial),
        // the error flat
        let plateau: Vec<_> = (0..21)
            .map(|k| record(5640.0, 1e-14 * [1.0, 3.0, 0.4, 6.0][k % 4], k % 3))
            .collect();
        assert!(flat_without_growth(&plateau));
        assert!(!no_progress(&plateau));
        assert!(!flat_without_growth(&plateau[1..]));
        // τ growing 4× per step from 1e-26 (horse5 from the Voronoi start): not a stall
        let growing: Vec<_> = (0..21).map(|k| record(379.0, 1e-26 * 4f64.powi(k), 0)).collect();
        assert!(!flat_without_growth(&growing));
        // a plateau at τ ≈ 1e-4 that slowly lowers the error (horse5 later): not a stall
        let slow: Vec<_> = (0..21)
            .map(|k| record(379.0 * (1.0 - 1e-3 * k as f64), 1e-4, 1))
            .collect();
        assert!(!flat_without_growth(&slow));
        // the same tiny steps with a 1 % gain over the window: not a stall
        let gaining: Vec<_> = (0..21)
            .map(|k| record(5640.0 * (1.0 - 5e-4 * k as f64), 1e-14, 1))
            .collect();
        assert!(!flat_without_growth(&gaining));
        // one step at 1e-6 (victoria0's plateau reaches 2e-9): not a stall
        let mut mixed = plateau.clone();
        mixed[12].step = 1e-6;
        assert!(!flat_without_growth(&mixed));
    }
}

#[cfg(test)]
mod contraction_tests {
    use super::*;
    use crate::power_diagram::{InsertionOrder, PowerDiagram};
    use crate::restricted::RestrictedIntegrator;

    /// The contracted heights' power diagram is the Voronoi diagram of the contracted points,
    /// also for a row of points 1.6e-11 apart (as at a limb's tip in a conformal image): no cell
    /// is empty and every cell mass agrees with that of the Voronoi diagram of the z_i (exact
    /// here) to 1e-13 (measured 7.6e-15), and the crowded cells (1e-13 … 4e-13 each) to 1e-3 of
    /// their mass (measured 1.2e-4). With f64 heights −|z_i|²/(2s)
    /// the masses are off by up to 1.3e-9, 6.3 times the crowded cells' own, and 22 of the
    /// cells were empty at s = 1/2.
    #[test]
    fn contracted_heights_give_the_voronoi_diagram_of_the_contracted_points() {
        let measure = SourceMeasure::unit_disk(256).unwrap();
        let mut points = Vec::new();
        // (dyadic coordinates, center and scales: the contracted points are exact)
        for k in 0..40 {
            let d = k as f64 * (2.0f64).powi(-37);
            points.push([0.5 + 2.0 * d, 0.25 + d + d * d * 1e3]);
        }
        for i in 0..7 {
            for j in 0..7 {
                let p = [-0.6 + 0.2 * i as f64, -0.6 + 0.2 * j as f64 + 0.01 * i as f64];
                points.push(p);
            }
        }
        let integrator = RestrictedIntegrator::new(&measure);
        let center = [0.125, -0.0625];
        for scale in [0.5, 0.25] {
            let heights = Heights::contracted(&points, center, scale);
            let (w, wl) = heights.weights(&points);
            let order = InsertionOrder::new(&points).unwrap();
            let ours = integrator.integrate(&PowerDiagram::with_order_dd(&points, &w, Some(&wl), &order).unwrap());
            let z: Vec<[f64; 2]> = points
                .iter()
                .map(|y| {
                    [
                        center[0] + scale * (y[0] - center[0]),
                        center[1] + scale * (y[1] - center[1]),
                    ]
                })
                .collect();
            let voronoi = integrator.integrate(&PowerDiagram::new(&z, &vec![0.0; z.len()]).unwrap());
            for i in 0..points.len() {
                let (a, b) = (ours.masses[i], voronoi.masses[i]);
                assert!(
                    a > 0.0 && (a - b).abs() <= 1e-13,
                    "s = {scale}, cell {i}: {a:e} against {b:e}"
                );
                // the row's thin cells also relative to their own mass (measured ≤ 1.2e-4: the
                // integration's rounding on cells ~1e-11 wide)
                if i < 40 {
                    assert!((a - b).abs() <= 1e-3 * b, "s = {scale}, cell {i}: {a:e} against {b:e}");
                }
            }
        }
    }
}
