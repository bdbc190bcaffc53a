//! The solver's parameters: [`NewtonParams`], the start ([`StartStrategy`]) and the cell
//! integrator ([`CellIntegrator`]).

use std::sync::Arc;
use std::time::Instant;

use super::TargetCoarsening;
use super::TARGET_RATIO_CAP;
use crate::linear::LinearSolver;

/// Which cell integrator the solver calls.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum CellIntegrator {
    /// The restricted power diagram (`power_diagram` + `restricted`): exact predicates, O(N + M).
    #[default]
    Restricted,
    /// The O(N² + N·M) oracle of `reference` (tests and N ≲ 2000 only).
    BruteForce,
}

/// Parameters of [`solve_ot`](crate::newton::solve_ot).
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
    /// e.g. [`OtSolution::heights_lo`](crate::newton::OtSolution::heights_lo)): the start is then h_i = hi_i + lo_i exactly, which
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
    /// ([`DiagramBuilder::update_from`](crate::power_diagram::DiagramBuilder::update_from)) instead of by insertion (default
    /// `true`). The diagrams, hence every result, are the same either way; `false` is for
    /// comparisons.
    pub flip_updates: bool,
    /// Integrate the masses and edge masses of the Newton evaluations by the flux form
    /// ([`RestrictedIntegrator::integrate_masses`](crate::restricted::RestrictedIntegrator::integrate_masses); where it declines, the full integration), and
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
    /// Stop as [`StopReason::TimeLimit`](crate::newton::StopReason::TimeLimit) at the first Newton step that would begin after this
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

/// How [`solve_ot`](crate::newton::solve_ot) chooses its initial heights when no warm start is given.
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
pub(super) const AUTO_CONTRAST: f64 = 10.0;
/// [`StartStrategy::Auto`] takes the coarse-to-fine start when a Voronoi cell has less than this
/// fraction of its target mass.
pub(super) const AUTO_MIN_START: f64 = 1e-8;
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
pub(super) const AUTO_MAX_START: f64 = 100.0;
