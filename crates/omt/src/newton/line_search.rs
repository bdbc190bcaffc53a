//! The damped step of Kitagawa, Mérigot, Thibert [2019, Alg. 1]: τ = 1, ½, ¼, … until every cell
//! keeps mass ≥ ε₀ and ‖G(h + τδ)‖₂ ≤ (1 − τ/2)‖G(h)‖₂.
//!
//! One deviation from the paper, for speed: the search starts at τ = min(1, 4τ_prev) instead of 1
//! (τ_prev the previous accepted step), so a long phase of small steps (strong density contrast)
//! does not re-evaluate the same rejected trials every iteration; the accepted τ can still grow
//! back to 1 in a few iterations, where the quadratic phase starts. The search gives up below
//! τ = 2^−`max_halvings` (the conditions hold for τ small enough by KMT's Prop. 6.1, so failing
//! there means a floating-point floor or a pathological start).

use super::{errors, evaluate, Backend, Evaluation};
use crate::error::OmtError;

/// An accepted step.
pub(crate) struct AcceptedStep {
    pub heights: Vec<f64>,
    pub evaluation: Evaluation,
    pub tau: f64,
}

/// The line search's result: the accepted step (None after `max_halvings` failed halvings),
/// the number of halvings and the time spent.
pub(crate) struct LineSearchOutcome {
    pub accepted: Option<AcceptedStep>,
    pub halvings: usize,
    pub t_diagram: f64,
    pub t_integration: f64,
}

/// Searches τ ∈ {τ_start, τ_start/2, …} down to 2^−max_halvings for the KMT conditions from
/// heights `heights` along `delta` (both #N), with current gradient norm `gradient_norm`.
#[allow(clippy::too_many_arguments)]
pub(crate) fn damped_step(
    backend: &Backend<'_>,
    points: &[[f64; 2]],
    targets: &[f64],
    heights: &[f64],
    delta: &[f64],
    gradient_norm: f64,
    epsilon0: f64,
    max_halvings: usize,
    tau_start: f64,
) -> Result<LineSearchOutcome, OmtError> {
    let mut tau = tau_start.min(1.0);
    let tau_min = 0.5f64.powi(max_halvings.min(1000) as i32);
    let mut outcome = LineSearchOutcome { accepted: None, halvings: 0, t_diagram: 0.0, t_integration: 0.0 };
    loop {
        let trial: Vec<f64> = heights.iter().zip(delta).map(|(h, d)| h + tau * d).collect();
        let evaluation = evaluate(backend, points, &trial)?;
        outcome.t_diagram += evaluation.t_diagram;
        outcome.t_integration += evaluation.t_integration;
        let min_mass = evaluation.cells.masses.iter().cloned().fold(f64::INFINITY, f64::min);
        let (_, norm, _) = errors(&evaluation.cells, targets);
        if min_mass >= epsilon0 && norm <= (1.0 - 0.5 * tau) * gradient_norm {
            outcome.accepted = Some(AcceptedStep { heights: trial, evaluation, tau });
            return Ok(outcome);
        }
        if tau * 0.5 < tau_min {
            return Ok(outcome);
        }
        tau *= 0.5;
        outcome.halvings += 1;
    }
}
