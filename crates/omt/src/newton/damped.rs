//! One damped Newton solve from a start (KMT's algorithm with the line search of `line_search`,
//! the intermediate targets of `targets` and the stall rules below).

use std::time::Instant;

use super::diagnosis::*;
use super::evaluation::complete_moments;
use super::targets::TARGET_CAP_MIN_TAU;
use super::*;
use crate::cells::CellIntegrals;
use crate::linear::NewtonSystem;
use crate::prepared::PreparedMeasure;

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

/// One damped Newton solve (no density continuation). `prepared`: the backend and the
/// evaluation of the start heights when the caller has them: of the Voronoi heights without a
/// warm start, of `params.initial_heights` with one (the backend keeps its insertion order and
/// integration seeds). The caller guarantees that the evaluation is of those heights: a
/// mismatched one would be taken as the start.
pub(super) fn solve_single(
    measure: &PreparedMeasure,
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

    let (start, mut heights, backend, mut current, start_evaluations) =
        initial_state(measure, points, params, prepared)?;
    let t_start = t_begin.elapsed().as_secs_f64();

    let min_target = targets.iter().cloned().fold(f64::INFINITY, f64::min);
    let min_mass0 = current.cells.masses.iter().cloned().fold(f64::INFINITY, f64::min);
    let epsilon0 = 0.5 * min_target.min(min_mass0);
    let pinned = (0..n).fold(0, |best, i| if targets[i] > targets[best] { i } else { best });
    let mut system = NewtonSystem::new(pinned, params.linear_solver.clone());

    // (max relative error, gradient norm, gradient) of the current cells
    let mut errs = errors(&current.cells, &targets);
    let mut log = Vec::new();
    let stop;
    let mut iterations = 0;
    let mut tau_start = 1.0;
    let mut target_cap = params.target_ratio_cap;
    loop {
        if let Some(reason) = finished(&backend, points, &heights, &mut current, &targets, params, &mut errs)? {
            stop = reason;
            break;
        }
        let (max_rel, norm, gradient) = (errs.0, errs.1, &errs.2);
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
            _ => (&targets, norm, gradient),
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
        let capped = step.as_ref().map_or(0, |s| s.1);
        let mut record = step_record(max_rel, norm, &outcome, &current.cells, t_solve, capped);
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
                errs = errors(&current.cells, &targets);
                let (max_rel, norm) = (errs.0, errs.1);
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
                if let Some(what) = stalled(&log) {
                    stop = StopReason::Stalled {
                        reason: format!(
                            "no progress: {what} left the max relative mass error at {max_rel:e}{}",
                            diagnosis_in(measure, points, &current.cells.masses)
                        ),
                    };
                    break;
                }
            }
            None => {
                log.push(record);
                stop = StopReason::Stalled {
                    reason: format!(
                        "no step τ ≥ 2^-{} satisfied the damping conditions (max relative mass error {max_rel:e}){}",
                        params.max_halvings,
                        diagnosis_in(measure, points, &current.cells.masses)
                    ),
                };
                break;
            }
        }
    }
    if complete_moments(&backend, points, &heights, &mut current)? {
        errs = errors(&current.cells, &targets);
    }
    let weights = heights.weights(points).0;
    let cost = current.cells.transport_cost();
    let diagnosis = (stop == StopReason::IterationCap)
        .then(|| diagnosis_in(measure, points, &current.cells.masses))
        .filter(|d| !d.is_empty());
    Ok(OtSolution {
        heights: heights.hi,
        heights_lo: heights.lo,
        weights,
        cells: current.cells,
        cost,
        iterations,
        evaluations: start_evaluations + log.iter().map(|r| r.evaluations).sum::<usize>(),
        max_relative_error: errs.0,
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

/// The stop before another step, if any: non-finite masses, or convergence (decided on the
/// full integrals: the flux form's masses may differ by ~1e-12, so `current` gets its moments
/// and `errs` is updated from them first).
fn finished(
    backend: &Backend<'_>,
    points: &[[f64; 2]],
    heights: &Heights,
    current: &mut Evaluation,
    targets: &[f64],
    params: &NewtonParams,
    errs: &mut (f64, f64, Vec<f64>),
) -> Result<Option<StopReason>, OmtError> {
    if !(errs.0.is_finite() && errs.1.is_finite()) {
        return Ok(Some(StopReason::Stalled {
            reason: "non-finite cell masses".into(),
        }));
    }
    if errs.0 <= params.tolerance {
        if complete_moments(backend, points, heights, current)? {
            *errs = errors(&current.cells, targets);
        }
        if errs.0 <= params.tolerance {
            return Ok(Some(StopReason::Converged));
        }
    }
    Ok(None)
}

/// The start of [`solve_single`]: the warm heights or the Voronoi diagram (or `prepared`, the
/// caller's backend and evaluation of them), replaced by [`start_without_empty_cells`] when a
/// cell is empty. Returns the start, its heights, the backend, their evaluation and the
/// evaluations it took.
fn initial_state<'a>(
    measure: &'a PreparedMeasure,
    points: &[[f64; 2]],
    params: &NewtonParams,
    prepared: Option<(Backend<'a>, Evaluation)>,
) -> Result<(Start, Heights, Backend<'a>, Evaluation, usize), OmtError> {
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
    let mut evaluations = 1;
    if current.cells.masses.iter().any(|&m| !(m > 0.0)) {
        let (contracted_start, contracted, evaluation, more) =
            start_without_empty_cells(&backend, measure, points, params, start, &current)?;
        (start, heights, current) = (contracted_start, contracted, evaluation);
        evaluations += more;
    }
    Ok((start, heights, backend, current, evaluations))
}

/// The record of a step from the state before it (errors `max_rel`, `norm`, cells `before`),
/// its line search `outcome`, the direction's time and the number of intermediate targets;
/// the caller sets the accepted τ and the errors after it.
fn step_record(
    max_rel: f64,
    norm: f64,
    outcome: &line_search::LineSearchOutcome,
    before: &CellIntegrals,
    t_solve: f64,
    intermediate_targets: usize,
) -> IterationRecord {
    IterationRecord {
        max_relative_error: max_rel,
        gradient_norm: norm,
        step: 0.0,
        halvings: outcome.rejections(),
        evaluations: outcome.rejections() + usize::from(outcome.accepted.is_some()),
        rejected_min_mass: outcome.rejected_min_mass,
        rejected_norm: outcome.rejected_norm,
        flip_updates: outcome.flip_updates,
        min_cell_mass: before.masses.iter().cloned().fold(f64::INFINITY, f64::min),
        t_diagram: outcome.t_diagram,
        t_integration: outcome.t_integration,
        t_solve,
        intermediate_targets,
    }
}

/// [`stall_diagnosis`] of the cell masses in the bounding box of the measure's vertices.
fn diagnosis_in(measure: &PreparedMeasure, points: &[[f64; 2]], masses: &[f64]) -> String {
    let (lo, hi) = crate::polygon::bounding_box(&measure.vertices);
    stall_diagnosis(points, masses, lo, hi)
}

/// Which stall rule the steps so far meet, in words ([`no_progress`], [`flat_without_growth`]).
fn stalled(log: &[IterationRecord]) -> Option<String> {
    if no_progress(log) {
        Some(format!(
            "{STALL_WINDOW} steps, each cut by the damping to τ < {STALL_TAU:e},"
        ))
    } else if flat_without_growth(log) {
        Some(format!("{FLAT_WINDOW} steps of τ < {FLAT_TAU:e} that stopped growing"))
    } else {
        None
    }
}

/// The start when the first one (`start`, evaluated as `first`) has an empty cell: the plain
/// Voronoi diagram (unless that was the first), then the Voronoi diagrams of the points contracted
/// toward Ω's area centroid by 1/2, 1/4, … (module docs, "Start"), until no cell is empty.
/// Returns that start, its heights and evaluation, and the evaluations it took; an input error
/// with a diagnosis when contraction cannot help (points too close together for f64).
fn start_without_empty_cells(
    backend: &Backend<'_>,
    measure: &PreparedMeasure,
    points: &[[f64; 2]],
    params: &NewtonParams,
    start: Start,
    first: &Evaluation,
) -> Result<(Start, Heights, Evaluation, usize), OmtError> {
    let n = points.len();
    let center = domain_centroid(measure);
    let (lo, hi) = crate::polygon::bounding_box(&measure.vertices);
    let empty_at = |cells: &CellIntegrals| cells.masses.iter().filter(|&&m| !(m > 0.0)).count();
    let mut fewest_empty = empty_at(&first.cells);
    let first_empty: Vec<usize> = (0..n).filter(|&i| !(first.cells.masses[i] > 0.0)).collect();
    let first_start = start.clone();
    let mut evaluations = 0;
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
        let heights = Heights::contracted(points, center, scale);
        let current = evaluate(backend, points, &heights)?;
        evaluations += 1;
        let empty = empty_at(&current.cells);
        if empty == 0 {
            let start = if scale == 1.0 {
                Start::Voronoi
            } else {
                Start::Contracted { scale }
            };
            return Ok((start, heights, current, evaluations));
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
