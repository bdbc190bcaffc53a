//! The result of a solve ([`OtSolution`]) and the conversions between heights, power weights
//! and the Kantorovich energy.

use crate::cells::CellIntegrals;
use crate::error::OmtError;

/// Why the iteration stopped.
#[derive(Clone, Debug, PartialEq)]
pub enum StopReason {
    /// The tolerance was reached.
    Converged,
    /// `max_iterations` steps were taken.
    IterationCap,
    /// No acceptable step could be found, or a non-finite value appeared.
    Stalled { reason: String },
    /// [`NewtonParams::deadline`](crate::newton::NewtonParams::deadline) passed before the solve ended.
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
    /// built by insertion; [`NewtonParams::flip_updates`](crate::newton::NewtonParams::flip_updates)).
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
    /// see [`NewtonParams::target_ratio_cap`](crate::newton::NewtonParams::target_ratio_cap)).
    pub intermediate_targets: usize,
}

/// The result of [`solve_ot`](crate::newton::solve_ot), converged or not (see [`OtSolution::into_result`]).
#[derive(Clone, Debug)]
pub struct OtSolution {
    /// Heights h (#N): u_h(x) = max_i ⟨x, y_i⟩ + h_i (the high parts of the solver's
    /// double-double heights).
    pub heights: Vec<f64>,
    /// Low parts of the heights (#N): the solver's heights are `heights[i] + heights_lo[i]`
    /// exactly. Pass both back as a warm start ([`NewtonParams::initial_heights_lo`](crate::newton::NewtonParams::initial_heights_lo)) to resume
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
