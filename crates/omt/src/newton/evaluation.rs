//! One evaluation of the cells at given heights: the power diagram (built anew, by flips from
//! the previous trial's, or stopped once too many sites are hidden) and its restricted
//! integration, or the brute-force oracle; and the mass errors.

use std::sync::OnceLock;
use std::time::Instant;

use super::{line_search, CellIntegrator, Heights, NewtonParams};
use crate::cells::CellIntegrals;
use crate::error::OmtError;
use crate::linear::{NewtonSystem, SpeculativeSymbolic};
use crate::measure::SourceMeasure;
use crate::power_diagram::{Construction, InsertionOrder, PowerDiagram};
use crate::prepared::PreparedMeasure;
use crate::restricted::RestrictedIntegrator;

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
        &Backend::plain(measure, integrator),
        points,
        &Heights::from_f64(heights.to_vec()),
    )
    .map(|e| e.cells)
}

/// The flux form's error bound per cell relative to its mass in a solve with `params`: a
/// hundredth of the tolerance, so that the masses' errors stay far below what the convergence
/// test resolves (1e-8 by default; at 1e-10 the form declines almost everywhere and the solve
/// integrates in full); `None` with `flux_masses` off.
pub(super) fn flux_bound(params: &NewtonParams) -> Option<f64> {
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
    pub(crate) fn new(measure: &'a PreparedMeasure, integrator: CellIntegrator, flux_bound: Option<f64>) -> Self {
        match integrator {
            CellIntegrator::Restricted => Backend::Restricted(
                RestrictedIntegrator::new(measure)
                    .with_flux_slot(measure.flux_slot())
                    .with_flux_form(flux_bound),
                OnceLock::new(),
            ),
            CellIntegrator::BruteForce => Backend::BruteForce(measure),
        }
    }

    /// The backend of a plain measure, without the flux form (nothing to keep between solves).
    pub(crate) fn plain(measure: &'a SourceMeasure, integrator: CellIntegrator) -> Self {
        match integrator {
            CellIntegrator::Restricted => {
                Backend::Restricted(RestrictedIntegrator::new(measure).with_flux_form(None), OnceLock::new())
            }
            CellIntegrator::BruteForce => Backend::BruteForce(measure),
        }
    }
}

/// Replaces the cells of an evaluation whose masses came from the flux form (no moments) by the
/// full integrals of its diagram (or of the diagram of `heights`, rebuilt, if it has none);
/// true when it did.
pub(super) fn complete_moments(
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
            integrator.integrate(
                &PowerDiagram::builder(points, &weights)
                    .low_parts(Some(&weights_lo))
                    .order(&order)
                    .build()?,
            )
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
pub(super) fn evaluate_keeping_diagram(
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
    let diagram = PowerDiagram::builder(points, &weights)
        .low_parts(Some(&weights_lo))
        .order(&order)
        .build()?;
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

/// [`evaluate`]; with `skip_if_hidden`, a diagram with a hidden site or a cell that misses Ω
/// (mass 0 < ε₀ either way, so a line-search trial that must be rejected;
/// [`RestrictedIntegrator::cells_outside`](crate::restricted::RestrictedIntegrator::cells_outside))
/// is not integrated: the masses are 0 for those sites and NaN for the others, the moments NaN
/// and the edge list empty. With
/// `speculate`, the symbolic factorization the next Newton direction would need if this trial
/// is accepted is computed on another thread while the cells are integrated (the integration
/// is parallel too, so on two cores the ordering takes about half of one core's share of it).
/// With `previous` (a diagram of the same points), the power diagram is updated from it by
/// flips ([`DiagramBuilder::update_from`](crate::power_diagram::DiagramBuilder::update_from); the same diagram as built anew).
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
                Some(previous) => PowerDiagram::builder(points, &weights)
                    .low_parts(Some(&weights_lo))
                    .order(order)
                    .update_from(previous)
                    .stop_past_hidden(max_hidden)
                    .construct()?,
                None => (
                    PowerDiagram::builder(points, &weights)
                        .low_parts(Some(&weights_lo))
                        .order(order)
                        .stop_past_hidden(max_hidden)
                        .construct()
                        .map(|(c, _)| c)?,
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
                // Likewise a trial with a cell that misses Ω (mass 0: rim cells pushed off the
                // domain), found geometrically without integrating the cells.
                let outside = integrator.cells_outside(&diagram);
                if !outside.is_empty() {
                    return Ok(masked_evaluation(
                        points.len(),
                        &outside,
                        t0.elapsed().as_secs_f64(),
                        by_flips,
                    ));
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
