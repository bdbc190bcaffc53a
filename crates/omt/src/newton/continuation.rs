//! The density continuation (ρ^t from t = 0 to 1) and the mass continuation, each stage
//! warm-starting the next.

use std::time::Instant;

use super::damped::solve_single;
use super::*;
use crate::prepared::PreparedMeasure;

/// Smallest continuation increment Δt before the density continuation gives up.
const MIN_CONTINUATION_STEP: f64 = 1.0 / 512.0;

/// The density continuation of [`NewtonParams::density_continuation`], adaptive: ρ_t = ρ^t from
/// t = 0 in increments Δt (initially 1/`stages`), each stage warm-started from the last converged
/// one; intermediate stages stop at max(tolerance, 1e-3) within max_iterations/2 steps. A stage that
/// does not converge is discarded and retried with Δt halved (below 1/512 the solve stops as
/// `Stalled`, with the reason); a stage that converges in a quarter of its budget doubles Δt.
/// The last stage (t = 1) is the problem itself with the full iteration budget; if it does not
/// converge, Δt is halved and the path continues from the last converged stage.
pub(super) fn solve_density_continuation(
    measure: &PreparedMeasure,
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
            stage_measure = PreparedMeasure::new(SourceMeasure {
                vertices: measure.vertices.clone(),
                triangles: measure.triangles.clone(),
                densities: measure.densities.iter().map(|d| d.powf(t_next)).collect(),
            });
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
pub(super) fn solve_mass_continuation(
    measure: &PreparedMeasure,
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
