//! The damped step of Kitagawa, Mérigot, Thibert [2019, Alg. 1]: accept τ when every cell
//! keeps mass ≥ ε₀ and ‖G(h + τδ)‖₂ ≤ (1 − τ/2)‖G(h)‖₂.
//!
//! The acceptance test is exactly KMT's; two deviations in how the trial τ are chosen, for speed
//! (measured on face pairs, `docs/decisions/0006-line-search.md`):
//! - The search starts at τ = min(1, `growth`·τ_prev) (τ_prev the previous accepted step; the
//!   caller picks the growth, 1.5), so a long phase of small steps (strong density contrast)
//!   does not re-evaluate the same rejected trials every iteration, while τ can still grow back
//!   to 1 in a few iterations, where the quadratic phase starts.
//! - After a rejected trial τ_r the next trial is not τ_r/2 but a model prediction clamped to
//!   [τ_r/10, 0.7·τ_r] (safeguarded backtracking, so the search still terminates and the KMT
//!   lower bound on acceptable τ still gives an accepted τ within a factor 10 of it):
//!   * for each cell whose mass fell below ε₀, the mass along the line is modelled as a shrinking
//!     similar polygon, m(τ) = m(0)(1 − τ/τ₀)², fitted through m(0) and m(τ_r) (m(τ_r) = 0 gives
//!     τ₀ = τ_r, the most optimistic vanishing point); its root of m = ε₀ is a candidate;
//!   * if the norm test failed, ‖G(h + τδ)‖ is modelled by the quadratic with value ‖G‖ and slope
//!     −‖G‖ at 0 (the Newton direction's) through the observed value at τ_r; the largest τ
//!     passing the test under that model is a candidate;
//!
//!   * if more than a tenth of the sites vanished, the per-cell model is blind to how far the
//!     trial overshot: the next trial is the lower end, τ_r/10;
//!   * if at least ten sites vanished at this trial and more at the rejected trial before, the
//!     hidden count is fitted by h(τ) ∝ τ^p through both and the τ where h = ½ is a candidate
//!     (the per-cell model takes every vanished cell to vanish just at τ_r, so with hundreds of
//!     them it creeps down by 0.7 per trial). Camelhead subdivided: the first step's trials
//!     13 → 8 (evaluations 29 → 24, same 14 steps); face pairs (`distance_bench 8`):
//!     finest-level evaluations 556 → 450, steps 693 → 697, costs equal to 6e-11; instructions
//!     (callgrind, 4 faces / 6 pairs, 1 thread) 39.85e9 → 38.15e9, −4.3 %; `ot_bench` 100×
//!     contrast 1e4: default 15 → 17 steps in the same 1.53 s, Voronoi + density continuation
//!     419 → 515 steps (30.7 → 32.0 s), mass continuation 1201 → 1166 steps (96 → 70 s);
//!
//! The next trial is 0.9 × the smallest candidate. On the faces every rejection was a mass floor
//! violation by one to a few cells, and this cut the evaluations per step from ~2.4 to ~1.5.
//!
//! A trial whose power diagram already hides a site (its cell is empty: mass 0 < ε₀), or has a
//! cell that misses Ω altogether (found geometrically, `RestrictedIntegrator::cells_outside`), is
//! rejected without integrating the cells; `next_trial` then sees mass 0 for the hidden sites and nothing
//! for the others (NaN). About half the evaluations on face pairs are rejected trials, most of them
//! with a vanished cell: this cut the 8-face distance benchmark from 16.8 to 12.2 s with the same
//! costs to 7e-12 (the trial sequence differs slightly: 1063 → 1052 evaluations). Its diagram
//! construction stops as soon as more than a tenth of the sites are hidden (the next trial is then
//! τ_r/10 whichever they are), which leaves every trial sequence unchanged. The gain is small: on
//! camelhead subdivided (45k sites, Voronoi start) the first two of the first step's 13 trials
//! stop after 4.6k and 7.0k insertions (−0.07 s of 4.4 s); the other ten hide 1 to 4.5k sites
//! each, and face pairs' rejected trials hide a few sites at most. On the 30k-vertex facefuns
//! scans most rejected trials hide no site but push one to a few rim cells off Ω (42 of the 44
//! integrated rejections of five consecutive pairs); skipping their integration took the pairs
//! from 4.9, 4.2, 3.5, 5.7, 6.9 s to 2.8, 3.5, 3.3, 4.1, 4.9 s (`scan_probe`, interleaved runs,
//! same costs; on the bundled faces 20 of 1,560 demo distances moved, by at most 2.4e-9
//! relative: a trial with a cell below ε₀ but not at 0 now lacks the other masses for the next
//! trial's model).
//!
//! The search gives up below τ = 2^−`max_halvings` (the conditions hold for τ small enough by KMT's
//! Prop. 6.1, so failing there means a floating-point floor or a pathological start).

use super::{errors, evaluate_unless_hidden, Backend, Evaluation, Heights};
use crate::cells::CellIntegrals;
use crate::error::OmtError;
use crate::linear::NewtonSystem;
use crate::power_diagram::PowerDiagram;

/// Safeguards of the backtracking: the next trial lies in [LOWER·τ_r, UPPER·τ_r].
const LOWER: f64 = 0.1;
const UPPER: f64 = 0.7;
/// Fewest hidden sites at a trial for the trend of the hidden counts to predict the next trial
/// (with one to a few, as on face pairs, the fit overshoots as often as it helps).
const TREND_MIN_HIDDEN: usize = 10;
/// Factor applied to the model's predicted largest acceptable τ.
const SAFETY: f64 = 0.9;

/// An accepted step.
pub(crate) struct AcceptedStep {
    pub heights: Heights,
    pub evaluation: Evaluation,
    pub tau: f64,
}

/// The line search's result: the accepted step (None when τ would fall below
/// 2^−max_halvings), the number of rejected trials by cause and the time spent.
pub(crate) struct LineSearchOutcome {
    pub accepted: Option<AcceptedStep>,
    /// Trials rejected because some cell mass fell below ε₀.
    pub rejected_min_mass: usize,
    /// Trials rejected (with every mass ≥ ε₀) by the gradient-norm test.
    pub rejected_norm: usize,
    /// Trials whose diagram was updated by flips.
    pub flip_updates: usize,
    pub t_diagram: f64,
    pub t_integration: f64,
}

impl LineSearchOutcome {
    /// Rejected trials (the former "halvings").
    pub fn rejections(&self) -> usize {
        self.rejected_min_mass + self.rejected_norm
    }
}

/// The number of hidden sites among `n` above which a rejected trial is followed by the
/// safeguard's lower end (more than a tenth; see `next_trial`). A trial's diagram construction
/// stops once it has found more hidden sites than this.
pub(crate) fn hidden_limit(n: usize) -> usize {
    n / 10
}

/// The number of hidden sites (mass exactly 0) of a trial, when it is complete: `None` above
/// [`hidden_limit`], where the diagram's construction stops early and the count is a lower bound.
fn hidden_count(m1: &[f64]) -> Option<usize> {
    let hidden = m1.iter().filter(|&&m| m == 0.0).count();
    (hidden <= hidden_limit(m1.len())).then_some(hidden)
}

/// The next trial after rejecting `tau` (see the module docs): masses `m0` at τ = 0 and `m1`
/// at `tau`, gradient norms `g0` at 0 and `g1` at `tau`; `previous` is the rejected trial
/// before (τ, its complete hidden count), if any.
fn next_trial(
    tau: f64,
    m0: &[f64],
    m1: &[f64],
    epsilon0: f64,
    g0: f64,
    g1: f64,
    previous: Option<(f64, usize)>,
) -> f64 {
    let mut predicted = f64::INFINITY;
    let hidden = hidden_count(m1);
    // Many cells vanished at two successive trials, fewer at the second: the count is fitted
    // by h(τ) = h₂ (τ/τ₂)^p through both, and the τ where fewer than one is left (h = ½) is a
    // candidate. The per-cell model cannot see this: it takes each vanished cell to vanish just
    // at the trial, so with hundreds of them it creeps down by the factor 0.7 per trial.
    if let (Some((tau1, h1)), Some(h2)) = (previous, hidden) {
        if h2 >= TREND_MIN_HIDDEN && h1 > h2 && tau1 > tau {
            let p = (h1 as f64 / h2 as f64).ln() / (tau1 / tau).ln();
            predicted = tau * (0.5 / h2 as f64).powf(1.0 / p);
        }
    }
    for (&a, &b) in m0.iter().zip(m1) {
        if b < epsilon0 && a > b && a > epsilon0 {
            let (r_eps, r_1) = ((epsilon0 / a).sqrt(), (b.max(0.0) / a).sqrt());
            predicted = predicted.min(tau * (1.0 - r_eps) / (1.0 - r_1));
        }
    }
    if g1 > (1.0 - 0.5 * tau) * g0 {
        let curvature = (g1 - g0 + g0 * tau) / (tau * tau);
        if curvature > 0.0 {
            predicted = predicted.min(g0 / (2.0 * curvature));
        }
    }
    // More than a tenth of the sites hidden: the trial overshot by far more than the per-cell
    // model can tell (it takes each vanished cell to vanish just at `tau`), so jump to the
    // safeguard's lower end. Seen on Voronoi starts of conformal images (camelhead subdivided:
    // 99 %, 87 %, 59 %, 27 % of 45k cells hidden at τ = 1, 0.26, 0.079, 0.030); this cut the
    // first step's trials from 15 to 9 there (OT 2.6 → 2.4 s) and left face pairs as they were.
    if hidden.is_none() {
        return LOWER * tau;
    }
    // NaN (not expected) falls back to halving.
    let next = SAFETY * predicted;
    if next.is_nan() {
        0.5 * tau
    } else {
        next.clamp(LOWER * tau, UPPER * tau)
    }
}

/// Searches τ from `tau_start` down (see `next_trial`) to 2^−max_halvings for the KMT
/// conditions from heights `heights` (cells `current`) along `delta` (both #N), with current
/// gradient norm `gradient_norm`. Each trial's diagram is updated by flips from `diagram`, the
/// diagram of `heights`, when given.
#[allow(clippy::too_many_arguments)]
pub(crate) fn damped_step(
    backend: &Backend<'_>,
    points: &[[f64; 2]],
    targets: &[f64],
    heights: &Heights,
    current: &CellIntegrals,
    delta: &[f64],
    gradient_norm: f64,
    epsilon0: f64,
    max_halvings: usize,
    tau_start: f64,
    speculate: Option<&NewtonSystem>,
    diagram: Option<&PowerDiagram>,
) -> Result<LineSearchOutcome, OmtError> {
    let mut tau = tau_start.min(1.0);
    let tau_min = 0.5f64.powi(max_halvings.min(1000) as i32);
    let mut outcome = LineSearchOutcome {
        accepted: None,
        rejected_min_mass: 0,
        rejected_norm: 0,
        flip_updates: 0,
        t_diagram: 0.0,
        t_integration: 0.0,
    };
    let mut previous = None;
    loop {
        let trial = heights.step(delta, tau);
        let evaluation = evaluate_unless_hidden(backend, points, &trial, true, speculate, diagram)?;
        outcome.t_diagram += evaluation.t_diagram;
        outcome.flip_updates += usize::from(evaluation.by_flips);
        outcome.t_integration += evaluation.t_integration;
        let min_mass = evaluation.cells.masses.iter().cloned().fold(f64::INFINITY, f64::min);
        let (_, norm, _) = errors(&evaluation.cells, targets);
        if min_mass >= epsilon0 && norm <= (1.0 - 0.5 * tau) * gradient_norm {
            outcome.accepted = Some(AcceptedStep {
                heights: trial,
                evaluation,
                tau,
            });
            return Ok(outcome);
        }
        if min_mass < epsilon0 {
            outcome.rejected_min_mass += 1;
        } else {
            outcome.rejected_norm += 1;
        }
        let next = next_trial(
            tau,
            &current.masses,
            &evaluation.cells.masses,
            epsilon0,
            gradient_norm,
            norm,
            previous,
        );
        previous = hidden_count(&evaluation.cells.masses).map(|h| (tau, h));
        if next < tau_min {
            return Ok(outcome);
        }
        tau = next;
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A vanished cell alone lets the model predict a near trial (0.7 τ at most); when more than
    /// a tenth of the sites vanished the next trial is the safeguard's lower end, 0.1 τ.
    #[test]
    fn many_hidden_sites_cut_the_step_tenfold() {
        let m0 = vec![1.0; 20];
        let mut m1 = vec![f64::NAN; 20];
        m1[0] = 0.0;
        let one = next_trial(0.5, &m0, &m1, 1e-3, 1.0, f64::NAN, None);
        assert!(one > 0.1 * 0.5 && one <= 0.7 * 0.5, "{one}");
        m1[1] = 0.0;
        m1[2] = 0.0;
        let three = next_trial(0.5, &m0, &m1, 1e-3, 1.0, f64::NAN, None);
        assert_eq!(three, 0.1 * 0.5);
    }

    /// Hidden counts 80 at τ = 0.01 and 20 at τ = 0.007 fit h ∝ τ^p with p = ln 4 / ln(10/7);
    /// the next trial is 0.9 × the τ where h = ½, far below the per-cell model's 0.7 τ. With
    /// fewer than `TREND_MIN_HIDDEN` hidden sites, or without a previous count, the trend is
    /// not used; a count above `hidden_limit` is not a count (the construction stopped early).
    #[test]
    fn a_falling_hidden_count_predicts_the_next_trial() {
        let n = 1000;
        let m0 = vec![1.0; n];
        let masses = |hidden: usize| {
            let mut m1 = vec![f64::NAN; n];
            m1[..hidden].iter_mut().for_each(|m| *m = 0.0);
            m1
        };
        let (tau1, tau) = (0.01, 0.007);
        let without = next_trial(tau, &m0, &masses(20), 1e-3, 1.0, f64::NAN, None);
        assert!((without - 0.7 * tau).abs() < 1e-15, "{without}");
        let with = next_trial(tau, &m0, &masses(20), 1e-3, 1.0, f64::NAN, Some((tau1, 80)));
        let p = 4f64.ln() / (tau1 / tau).ln();
        let expected = SAFETY * tau * (0.5f64 / 20.0).powf(1.0 / p);
        assert!(
            (with - expected).abs() < 1e-15 && with < 0.4 * tau,
            "{with} vs {expected}"
        );
        // a count that barely falls predicts a tiny τ: the safeguard still bounds it
        let flat = next_trial(tau, &m0, &masses(20), 1e-3, 1.0, f64::NAN, Some((tau1, 21)));
        assert_eq!(flat, LOWER * tau);
        // too few hidden sites, or a rising count: the model alone
        let few = next_trial(tau, &m0, &masses(5), 1e-3, 1.0, f64::NAN, Some((tau1, 80)));
        assert_eq!(few, next_trial(tau, &m0, &masses(5), 1e-3, 1.0, f64::NAN, None));
        let rising = next_trial(tau, &m0, &masses(20), 1e-3, 1.0, f64::NAN, Some((tau1, 15)));
        assert_eq!(rising, without);
        assert_eq!(hidden_count(&masses(100)), Some(100));
        assert_eq!(hidden_count(&masses(101)), None);
    }
}
