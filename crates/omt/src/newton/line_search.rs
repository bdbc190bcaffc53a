//! The damped step of Kitagawa, Mérigot, Thibert [2019, Alg. 1]: τ = 1, ½, ¼, … until every cell
//! keeps mass ≥ ε₀ and ‖G(h + τδ)‖₂ ≤ (1 − τ/2)‖G(h)‖₂.

use super::{errors, evaluate, CellIntegrator, Evaluation};
use crate::error::OmtError;
use crate::measure::SourceMeasure;

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

/// Searches τ ∈ {1, ½, …, 2^−max_halvings} for the KMT conditions from heights `heights` along
/// `delta` (both #N), with current gradient norm `gradient_norm`.
#[allow(clippy::too_many_arguments)]
pub(crate) fn damped_step(
    measure: &SourceMeasure,
    points: &[[f64; 2]],
    targets: &[f64],
    heights: &[f64],
    delta: &[f64],
    gradient_norm: f64,
    epsilon0: f64,
    max_halvings: usize,
    integrator: CellIntegrator,
) -> Result<LineSearchOutcome, OmtError> {
    let mut tau = 1.0;
    let mut outcome = LineSearchOutcome { accepted: None, halvings: 0, t_diagram: 0.0, t_integration: 0.0 };
    loop {
        let trial: Vec<f64> = heights.iter().zip(delta).map(|(h, d)| h + tau * d).collect();
        let evaluation = evaluate(measure, points, &trial, integrator)?;
        outcome.t_diagram += evaluation.t_diagram;
        outcome.t_integration += evaluation.t_integration;
        let min_mass = evaluation.cells.masses.iter().cloned().fold(f64::INFINITY, f64::min);
        let (_, norm, _) = errors(&evaluation.cells, targets);
        if min_mass >= epsilon0 && norm <= (1.0 - 0.5 * tau) * gradient_norm {
            outcome.accepted = Some(AcceptedStep { heights: trial, evaluation, tau });
            return Ok(outcome);
        }
        if outcome.halvings >= max_halvings {
            return Ok(outcome);
        }
        tau *= 0.5;
        outcome.halvings += 1;
    }
}
