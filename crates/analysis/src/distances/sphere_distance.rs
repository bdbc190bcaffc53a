//! Conformal Wasserstein distances between closed genus-0 surfaces on the sphere
//! [Su et al. 2015, §4.3, Theorem 6 and Algorithm 3 with S² for D].
//!
//! Each surface M_k, scaled to area 4π, has a conformal map φ_k onto S²
//! ([`shapespace_conformal::sphere_map`]), unique up to the Möbius maps of S². The source
//! measure is the pushed-forward area of M₁ (a density per flat chordal image triangle), the
//! target the points y_i = φ₂(v_i) with masses ν_i = one third of M₂'s one-ring areas, and the
//! cost the chordal one, |x − y|² = 2 − 2⟨x, y⟩ on S²:
//! $$ W_2^2(M_1, M_2) = \min_{R} \sum_i \int_{W_i} |x - R y_i|^2 \, d\mu_1(x). $$
//! The Möbius ambiguity is removed in one of two ways:
//!
//! - **Three markers** p₁, p₂, p₃ ↦ 0, 1, ∞ (Theorem 6: the Möbius map is then unique): one
//!   transport solve, R = I ([`SphereAlignment::Fixed`]).
//! - **Möbius centering**, which leaves a rotation free, and a search over SO(3)
//!   ([`SphereAlignment::Rotation`]):
//!   1. *Proxy grid.* Both shapes' vertex masses are binned at the 162 vertices of an icosphere
//!      (mass-weighted mean directions), and every rotation of an 864-rotation grid
//!      ([`crate::rotation::rotation_grid`], 72 directions × 12 spins) is scored by the
//!      kernel correlation Σ_ab m_a n_b exp(κ(⟨x_a, R y_b⟩ − 1)), κ = [`KERNEL_KAPPA`]: 22 M
//!      kernel terms, a fraction of one transport solve. The best grid rotations at least
//!      0.5 rad apart ([`SEEDS`]) climb the correlation by weighted Horn steps.
//!   2. *Scoring.* The [`CANDIDATES`] best distinct local maxima are each scored by a cold
//!      transport solve to a loose tolerance ([`SCORING_TOLERANCE`]).
//!   3. *Refinement.* From the best, the solve to the full tolerance, then alternating steps:
//!      with the cells fixed the cost is −2 Σ_i ⟨m_i, R y_i⟩ + const (m_i the first moment of
//!      cell i), minimized over R in closed form by Horn's method; the next solve is
//!      warm-started from the heights. Each step lowers the cost (the old cells are feasible
//!      for the new rotation), as in ICP. Repeated, such steps converge slowly where the cells
//!      adapt to the rotation (the cost is flatter than with fixed cells: 20 steps left a
//!      bumpy sphere's cost 4 % above its minimum), so only the first step is Horn's; then
//!      quasi-Newton (BFGS) steps on the rotation vector with the exact gradient
//!      ∇C = −2 Σ_i (R y_i) × m_i along exp(ω)R (envelope theorem), halved until the cost falls.
//!      The steps stop below [`ROTATION_TOLERANCE`] or when the cost falls by less than
//!      [`COST_STALL`] relative.
//!
//! Per-shape work is done once ([`prepare_sphere_shape`]); pairs reuse it.

use std::collections::HashMap;
use std::time::Instant;

use rayon::prelude::*;
use serde::Serialize;
use shapespace_conformal::{sphere_map, SphereMap, SphereMapParams, SphereNormalization};
use shapespace_geometry::quantities::vertex_dual_areas;
use shapespace_geometry::topology::{find, union};
use shapespace_geometry::TriMesh;
use shapespace_omt::sphere::{icosphere, solve_sphere_ot, SphereMeasure, SphereOtParams, SphereOtSolution};
use shapespace_omt::StopReason;

use crate::error::AnalysisError;
use crate::rotation::{
    angle_between, apply, best_rotation, compose, exp_rotation, log_rotation, rotation_grid, transpose, Rotation,
    IDENTITY,
};

/// κ of the proxy's kernel exp(κ(cos θ − 1)): an angular width 1/√κ ≈ 0.32 rad, about the
/// spacing of the 162 bins (0.28 rad) and the grid's covering radius.
pub const KERNEL_KAPPA: f64 = 10.0;
/// Subdivisions of the icosphere whose vertices bin the proxy's masses (162 vertices).
pub const PROXY_SUBDIVISIONS: usize = 2;
/// Grid of the proxy: Fibonacci directions × spins.
pub const GRID_DIRECTIONS: usize = 72;
pub const GRID_SPINS: usize = 12;
/// Best grid rotations (at least [`SEED_SEPARATION`] apart) that climb the proxy.
pub const SEEDS: usize = 8;
/// Radians between seeds.
pub const SEED_SEPARATION: f64 = 0.5;
/// Local maxima of the proxy scored by transport solves.
pub const CANDIDATES: usize = 3;
/// Relative mass tolerance of the refinement's solves (at most the pair's tolerance).
pub const REFINEMENT_TOLERANCE: f64 = 1e-7;
/// Relative mass tolerance of the scoring solves.
pub const SCORING_TOLERANCE: f64 = 1e-2;
/// The refinement stops when a step turns by less than this (radians).
pub const ROTATION_TOLERANCE: f64 = 1e-4;
/// The refinement also stops when a step lowers the cost by less than this (relative): far
/// below the error of the cost itself at the default mass tolerance (the dual gap).
pub const COST_STALL: f64 = 1e-7;
/// Largest turn of one refinement step (radians).
pub const MAX_REFINEMENT_TURN: f64 = 0.5;
/// Refinement steps at most.
pub const MAX_REFINEMENT_STEPS: usize = 20;
/// A cold direct solve that has not halved its largest relative mass error in this many steps
/// gives way to the density continuation (decision 0036: on the TOSCA bodies the direct solve
/// crawls at τ ≈ 1e-3 and its 100 steps only took the error from 111 to 101).
pub const DIRECT_STALL_STEPS: usize = 20;
/// Target points closer than this on S² are merged (as [`crate::distance::COINCIDENT_POINTS`]
/// in the disk).
pub const COINCIDENT_SPHERE_POINTS: f64 = 1e-12;

/// How the two sphere maps of a pair are aligned.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize, serde::Deserialize)]
pub enum SphereAlignment {
    /// As the maps are normalized (three markers, or centering with rotation markers).
    Fixed,
    /// The minimum over rotations of the target (the search of the module docs).
    #[default]
    Rotation,
}

/// A closed genus-0 surface ready for spherical distances.
#[derive(Clone, Debug)]
pub struct PreparedSphere {
    /// Display name.
    pub name: String,
    /// The conformal sphere map (area scaled to 4π).
    pub map: SphereMap,
    /// (S², μ): the image triangles (flat chords) with the pushed-forward density.
    pub measure: SphereMeasure,
    /// Target points φ(v_i) on S² (images closer than [`COINCIDENT_SPHERE_POINTS`] merged).
    pub points: Vec<[f64; 3]>,
    /// Target masses: one third of the one-ring areas, surface scaled to 4π.
    pub masses: Vec<f64>,
    /// The merge's own cost Σ ν_i |y_i − c_g(i)|², subtracted from the costs to this target.
    pub merge_variance: f64,
    /// The masses binned at the icosphere's vertices for the rotation proxy: directions, masses.
    pub proxy_points: Vec<[f64; 3]>,
    pub proxy_masses: Vec<f64>,
    /// Seconds spent preparing.
    pub seconds: f64,
}

impl PreparedSphere {
    /// The normalization of the conformal map.
    pub fn normalization(&self) -> SphereNormalization {
        self.map.info.normalization
    }
}

/// Conformal sphere map, density, target points and the proxy's bins of one closed genus-0
/// surface. Errors name the shape: not a closed genus-0 surface, the map fails (beyond double
/// precision, bad markers), a vertex without area.
pub fn prepare_sphere_shape(
    name: &str,
    mesh: &TriMesh,
    params: &SphereMapParams,
) -> Result<PreparedSphere, AnalysisError> {
    let start = Instant::now();
    let shape_error = |message: String| AnalysisError::Shape {
        name: name.to_string(),
        message,
    };
    let map = sphere_map(mesh, params).map_err(|e| shape_error(e.to_string()))?;
    let measure = SphereMeasure::new(map.positions.clone(), mesh.faces.clone(), map.face_densities.clone())
        .map_err(|e| shape_error(format!("pushed-forward density: {e}")))?;
    let scale2 = map.scale * map.scale;
    let masses: Vec<f64> = vertex_dual_areas(mesh).iter().map(|a| a * scale2).collect();
    if let Some(i) = masses.iter().position(|&m| !(m > 0.0 && m.is_finite())) {
        return Err(shape_error(format!(
            "vertex {i} has no incident area (unreferenced vertex or degenerate one-ring)"
        )));
    }
    let (points, masses, merge_variance) = merge_coincident_sphere_points(&map.positions, masses);
    let (proxy_points, proxy_masses) = proxy_bins(&points, &masses);
    Ok(PreparedSphere {
        name: name.to_string(),
        map,
        measure,
        points,
        masses,
        merge_variance,
        proxy_points,
        proxy_masses,
        seconds: start.elapsed().as_secs_f64(),
    })
}

/// Points within [`COINCIDENT_SPHERE_POINTS`] of each other (transitively) become one point at
/// their normalized mass-weighted mean with their summed mass; returns the points, masses and
/// Σ_i ν_i |y_i − c_g(i)|² (0 and the input when nothing merges).
pub fn merge_coincident_sphere_points(points: &[[f64; 3]], masses: Vec<f64>) -> (Vec<[f64; 3]>, Vec<f64>, f64) {
    let radius = COINCIDENT_SPHERE_POINTS;
    let cell = |p: [f64; 3]| p.map(|x| (x / radius).floor() as i64);
    let mut grid: HashMap<[i64; 3], Vec<usize>> = HashMap::new();
    for (i, &p) in points.iter().enumerate() {
        grid.entry(cell(p)).or_default().push(i);
    }
    let mut parent: Vec<u32> = (0..points.len() as u32).collect();
    let mut merged = false;
    for (i, &p) in points.iter().enumerate() {
        let c = cell(p);
        for dx in -1..=1 {
            for dy in -1..=1 {
                for dz in -1..=1 {
                    let Some(others) = grid.get(&[c[0] + dx, c[1] + dy, c[2] + dz]) else {
                        continue;
                    };
                    for &j in others {
                        if j > i && chord2(points[j], p).sqrt() < radius {
                            merged |= union(&mut parent, i as u32, j as u32);
                        }
                    }
                }
            }
        }
    }
    if !merged {
        return (points.to_vec(), masses, 0.0);
    }
    let mut group_of = vec![usize::MAX; points.len()];
    let (mut sums, mut group_masses): (Vec<[f64; 3]>, Vec<f64>) = (Vec::new(), Vec::new());
    for i in 0..points.len() {
        let r = find(&mut parent, i as u32) as usize;
        if group_of[r] == usize::MAX {
            group_of[r] = sums.len();
            sums.push([0.0; 3]);
            group_masses.push(0.0);
        }
        let g = group_of[r];
        group_of[i] = g;
        for k in 0..3 {
            sums[g][k] += masses[i] * points[i][k];
        }
        group_masses[g] += masses[i];
    }
    let centers: Vec<[f64; 3]> = sums.iter().map(|&s| unit(s)).collect();
    let variance = (0..points.len())
        .map(|i| masses[i] * chord2(points[i], centers[group_of[i]]))
        .sum();
    (centers, group_masses, variance)
}

fn chord2(a: [f64; 3], b: [f64; 3]) -> f64 {
    (a[0] - b[0]).powi(2) + (a[1] - b[1]).powi(2) + (a[2] - b[2]).powi(2)
}

fn dot(a: [f64; 3], b: [f64; 3]) -> f64 {
    a[0] * b[0] + a[1] * b[1] + a[2] * b[2]
}

fn cross(a: [f64; 3], b: [f64; 3]) -> [f64; 3] {
    [
        a[1] * b[2] - a[2] * b[1],
        a[2] * b[0] - a[0] * b[2],
        a[0] * b[1] - a[1] * b[0],
    ]
}

/// The BFGS update of an inverse Hessian `h` by the step `s` and the gradient change `y`
/// (sᵀy > 0): H⁺ = (I − ρ s yᵀ) H (I − ρ y sᵀ) + ρ s sᵀ, ρ = 1/(sᵀy).
fn bfgs_update(h: &[[f64; 3]; 3], s: [f64; 3], y: [f64; 3]) -> [[f64; 3]; 3] {
    let rho = 1.0 / dot(s, y);
    let mut a = [[0.0; 3]; 3];
    for (i, row) in a.iter_mut().enumerate() {
        for (j, x) in row.iter_mut().enumerate() {
            *x = if i == j { 1.0 } else { 0.0 } - rho * s[i] * y[j];
        }
    }
    let mut out = [[0.0; 3]; 3];
    for i in 0..3 {
        for j in 0..3 {
            let mut v = 0.0;
            for k in 0..3 {
                for l in 0..3 {
                    v += a[i][k] * h[k][l] * a[j][l];
                }
            }
            out[i][j] = v + rho * s[i] * s[j];
        }
    }
    out
}

fn norm3(a: [f64; 3]) -> f64 {
    dot(a, a).sqrt()
}

fn unit(a: [f64; 3]) -> [f64; 3] {
    let r = dot(a, a).sqrt();
    a.map(|x| x / r)
}

/// The masses binned at the nearest vertex of the icosphere of [`PROXY_SUBDIVISIONS`]: each
/// non-empty bin as its normalized mass-weighted mean direction and its mass.
fn proxy_bins(points: &[[f64; 3]], masses: &[f64]) -> (Vec<[f64; 3]>, Vec<f64>) {
    let (bins, _) = icosphere(PROXY_SUBDIVISIONS);
    let mut sums = vec![[0.0; 3]; bins.len()];
    let mut total = vec![0.0; bins.len()];
    for (p, &m) in points.iter().zip(masses) {
        let k = (0..bins.len())
            .max_by(|&a, &b| dot(bins[a], *p).total_cmp(&dot(bins[b], *p)))
            .unwrap_or(0);
        for c in 0..3 {
            sums[k][c] += m * p[c];
        }
        total[k] += m;
    }
    let keep: Vec<usize> = (0..bins.len())
        .filter(|&k| total[k] > 0.0 && dot(sums[k], sums[k]) > 0.0)
        .collect();
    (
        keep.iter().map(|&k| unit(sums[k])).collect(),
        keep.iter().map(|&k| total[k]).collect(),
    )
}

/// The proxy's score of the target rotated by `r`: Σ_ab m_a n_b exp(κ(⟨x_a, R y_b⟩ − 1)).
fn proxy_score(source: &PreparedSphere, target: &PreparedSphere, r: &Rotation) -> f64 {
    let rotated: Vec<[f64; 3]> = target.proxy_points.iter().map(|&y| apply(r, y)).collect();
    source
        .proxy_points
        .iter()
        .zip(&source.proxy_masses)
        .map(|(&x, &m)| {
            m * rotated
                .iter()
                .zip(&target.proxy_masses)
                .map(|(&y, &n)| n * (KERNEL_KAPPA * (dot(x, y) - 1.0)).exp())
                .sum::<f64>()
        })
        .sum()
}

/// One climb of the proxy from `r`: weighted Horn steps (the kernel's weights at the current
/// rotation) until a step turns by less than 1e-4 rad (at most 30).
fn climb(source: &PreparedSphere, target: &PreparedSphere, mut r: Rotation) -> Rotation {
    for _ in 0..30 {
        let rotated: Vec<[f64; 3]> = target.proxy_points.iter().map(|&y| apply(&r, y)).collect();
        let pairs = source
            .proxy_points
            .iter()
            .zip(&source.proxy_masses)
            .flat_map(|(&x, &m)| {
                rotated
                    .iter()
                    .zip(&target.proxy_points)
                    .zip(&target.proxy_masses)
                    .map(move |((&ry, &y), &n)| (y, x, m * n * (KERNEL_KAPPA * (dot(x, ry) - 1.0)).exp()))
            });
        let next = best_rotation(pairs);
        let turn = angle_between(&next, &r);
        r = next;
        if turn < 1e-4 {
            break;
        }
    }
    r
}

/// The rotations of the target the transport solves score: the proxy's [`CANDIDATES`] best
/// distinct local maxima (module docs), best first, with their proxy scores.
pub fn proxy_candidates(source: &PreparedSphere, target: &PreparedSphere) -> Vec<(Rotation, f64)> {
    let grid = rotation_grid(GRID_DIRECTIONS, GRID_SPINS);
    let scores: Vec<f64> = grid.par_iter().map(|r| proxy_score(source, target, r)).collect();
    let mut order: Vec<usize> = (0..grid.len()).collect();
    order.sort_by(|&a, &b| scores[b].total_cmp(&scores[a]).then(a.cmp(&b)));
    let mut seeds: Vec<Rotation> = Vec::new();
    for k in order {
        if seeds.len() >= SEEDS {
            break;
        }
        if seeds.iter().all(|s| angle_between(s, &grid[k]) > SEED_SEPARATION) {
            seeds.push(grid[k]);
        }
    }
    let climbed: Vec<(Rotation, f64)> = seeds
        .par_iter()
        .map(|&s| {
            let r = climb(source, target, s);
            (r, proxy_score(source, target, &r))
        })
        .collect();
    let mut climbed = climbed;
    climbed.sort_by(|a, b| b.1.total_cmp(&a.1));
    let mut out: Vec<(Rotation, f64)> = Vec::new();
    for (r, s) in climbed {
        if out.len() < CANDIDATES && out.iter().all(|(o, _)| angle_between(o, &r) > 0.1) {
            out.push((r, s));
        }
    }
    out
}

/// The outcome of one directed spherical computation source → target.
#[derive(Clone, Debug, Serialize)]
pub struct SphereDistance {
    /// Transport cost W₂² (minimized over rotations with [`SphereAlignment::Rotation`]), less
    /// the target's merge variance.
    pub cost: f64,
    /// The final solve's Kantorovich dual value (less the same variance).
    pub dual_cost: f64,
    /// √cost.
    pub distance: f64,
    /// The rotation applied to the target's points (rows).
    pub rotation: Rotation,
    /// Transport solves (scoring, full, refinement).
    pub solves: usize,
    /// Newton iterations and cell evaluations over all solves.
    pub iterations: usize,
    pub evaluations: usize,
    /// Refinement steps taken (Horn steps accepted).
    pub refinement_steps: usize,
    /// The final solve's max relative cell-mass error.
    pub max_mass_error: f64,
    /// Whether the final solve reached its tolerance.
    pub converged: bool,
    /// The final solve's stop reason.
    pub status: String,
    /// Seconds: the proxy grid, the scoring solves, the full solve and refinement, in total.
    pub seconds_proxy: f64,
    pub seconds_scoring: f64,
    pub seconds_refinement: f64,
    pub seconds: f64,
}

/// Counters of the solves of one pair.
#[derive(Default)]
struct Tally {
    solves: usize,
    iterations: usize,
    evaluations: usize,
}

/// One transport solve from `source`'s density to `target`'s points rotated by `r`: directly
/// (no density continuation; the solver's coarse-to-fine start when the images crowd), and,
/// when that stops without converging and no warm start was given, once more with the density
/// continuation (as the disk's fallback).
fn solve(
    source: &PreparedSphere,
    target: &PreparedSphere,
    r: &Rotation,
    warm: Option<(Vec<f64>, Vec<f64>)>,
    tolerance: f64,
    params: &SphereOtParams,
    tally: &mut Tally,
) -> Result<(SphereOtSolution, Vec<[f64; 3]>), AnalysisError> {
    let pair_error = |e: shapespace_omt::OmtError| AnalysisError::Pair {
        a: source.name.clone(),
        b: target.name.clone(),
        message: e.to_string(),
    };
    let points: Vec<[f64; 3]> = target.points.iter().map(|&y| apply(r, y)).collect();
    let cold = warm.is_none();
    let (warm_hi, warm_lo) = warm.unzip();
    let direct = SphereOtParams {
        tolerance,
        initial_heights: warm_hi,
        initial_heights_lo: warm_lo,
        density_continuation: None,
        // a cold direct solve that crawls hands over to the continuation early
        stall_window: if cold {
            Some(DIRECT_STALL_STEPS)
        } else {
            params.stall_window
        },
        ..params.clone()
    };
    let first = solve_sphere_ot(&source.measure, &points, &target.masses, &direct);
    let past = params.deadline.is_some_and(|d| Instant::now() >= d);
    let solution = match first {
        Ok(s) if s.converged() || !cold || past => s,
        first => {
            let (its, evals) = first.as_ref().map_or((0, 0), |s| (s.iterations, s.evaluations));
            let fallback = SphereOtParams {
                tolerance,
                initial_heights: None,
                initial_heights_lo: None,
                density_continuation: params.density_continuation.or(Some(10.0)),
                ..params.clone()
            };
            let mut s = solve_sphere_ot(&source.measure, &points, &target.masses, &fallback).map_err(pair_error)?;
            s.iterations += its;
            s.evaluations += evals;
            s
        }
    };
    tally.solves += 1;
    tally.iterations += solution.iterations + solution.continuation_iterations;
    tally.evaluations += solution.evaluations;
    Ok((solution, points))
}

/// W₂ between `source`'s pushed-forward area and `target`'s vertex masses on S², aligned as
/// `alignment` says (module docs), with the solver settings `params` (tolerance, caps,
/// deadline).
///
/// Errors: a transport solve that fails outright ([`AnalysisError::Pair`] naming both shapes).
pub fn directed_sphere_distance(
    source: &PreparedSphere,
    target: &PreparedSphere,
    alignment: SphereAlignment,
    params: &SphereOtParams,
) -> Result<SphereDistance, AnalysisError> {
    let start = Instant::now();
    let mut tally = Tally::default();
    let (mut rotation, mut warm, seconds_proxy, seconds_scoring) = match alignment {
        SphereAlignment::Fixed => (IDENTITY, None, 0.0, 0.0),
        SphereAlignment::Rotation => {
            let candidates = proxy_candidates(source, target);
            let seconds_proxy = start.elapsed().as_secs_f64();
            let scoring = params.tolerance.max(SCORING_TOLERANCE);
            let mut best: Option<(Rotation, SphereOtSolution)> = None;
            for (r, _) in &candidates {
                let (s, _) = solve(source, target, r, None, scoring, params, &mut tally)?;
                let better = best.as_ref().is_none_or(|(_, b)| {
                    (s.converged() && !b.converged()) || (s.converged() == b.converged() && s.cost < b.cost)
                });
                if better {
                    best = Some((*r, s));
                }
            }
            // (the grid always yields a candidate; a scoring solve stopped by the deadline passes
            // no heights on)
            let (r, warm) = match best {
                Some((r, s)) => (
                    r,
                    (s.stop != StopReason::TimeLimit).then_some((s.heights, s.heights_lo)),
                ),
                None => (IDENTITY, None),
            };
            (r, warm, seconds_proxy, start.elapsed().as_secs_f64() - seconds_proxy)
        }
    };
    let t_refine = Instant::now();
    // (the gradient's error is first order in the mass residual: at 1e-4 it is as large as the
    // gradient itself near the minimum, so the refinement's solves go further)
    let refine_tolerance = match alignment {
        SphereAlignment::Rotation => params.tolerance.min(REFINEMENT_TOLERANCE),
        SphereAlignment::Fixed => params.tolerance,
    };
    let (mut solution, _) = match solve(
        source,
        target,
        &rotation,
        warm.take(),
        refine_tolerance,
        params,
        &mut tally,
    ) {
        Ok(s) => s,
        // a warm start that cannot start (an empty cell) is solved cold
        Err(_) if alignment == SphereAlignment::Rotation => {
            solve(source, target, &rotation, None, refine_tolerance, params, &mut tally)?
        }
        Err(e) => return Err(e),
    };
    let mut refinement_steps = 0;
    if alignment == SphereAlignment::Rotation && solution.converged() {
        // C′ along exp(ω)R: ∇C = −2 Σ_i (R y_i) × m_i (envelope theorem, module docs)
        let gradient = |s: &SphereOtSolution, r: &Rotation| -> [f64; 3] {
            let mut g = [0.0; 3];
            for (&y, m) in target.points.iter().zip(&s.cells.first_moments) {
                let c = cross(apply(r, y), *m);
                for k in 0..3 {
                    g[k] -= 2.0 * c[k];
                }
            }
            g
        };
        let mut g = gradient(&solution, &rotation);
        // the inverse Hessian of the BFGS model, once a step has measured the curvature
        let mut inverse: Option<[[f64; 3]; 3]> = None;
        for _ in 0..MAX_REFINEMENT_STEPS {
            // the first step is Horn's (the minimum with the cells held fixed), then quasi-Newton
            let mut step = match &inverse {
                None => {
                    let horn = best_rotation(
                        target
                            .points
                            .iter()
                            .zip(&solution.cells.first_moments)
                            .map(|(&y, &m)| (y, m, 1.0)),
                    );
                    log_rotation(&compose(&horn, &transpose(&rotation)))
                }
                Some(h) => [0, 1, 2].map(|i| -(h[i][0] * g[0] + h[i][1] * g[1] + h[i][2] * g[2])),
            };
            let length = norm3(step);
            if length > MAX_REFINEMENT_TURN {
                step = step.map(|x| x * MAX_REFINEMENT_TURN / length);
            }
            if norm3(step) < ROTATION_TOLERANCE {
                // a quasi-Newton step this short may come from a curvature measured at a
                // smaller scale: one more Horn step decides
                if inverse.take().is_some() {
                    continue;
                }
                break;
            }
            // halve until the cost falls (at most 4 times)
            let mut taken = None;
            for _ in 0..5 {
                let next = compose(&exp_rotation(step), &rotation);
                let warm = Some((solution.heights.clone(), solution.heights_lo.clone()));
                if let Ok((s, _)) = solve(source, target, &next, warm, refine_tolerance, params, &mut tally) {
                    if s.converged() && s.cost < solution.cost {
                        taken = Some((next, s));
                        break;
                    }
                }
                step = step.map(|x| x / 2.0);
            }
            let Some((next, s)) = taken else {
                break;
            };
            let decrease = (solution.cost - s.cost) / solution.cost;
            let g_next = gradient(&s, &next);
            let y = [0, 1, 2].map(|k| g_next[k] - g[k]);
            let sy = dot(step, y);
            if sy > 0.0 {
                let h = inverse.unwrap_or_else(|| {
                    let scale = sy / dot(y, y);
                    [[scale, 0.0, 0.0], [0.0, scale, 0.0], [0.0, 0.0, scale]]
                });
                inverse = Some(bfgs_update(&h, step, y));
            }
            (rotation, solution, g) = (next, s, g_next);
            refinement_steps += 1;
            if decrease < COST_STALL || norm3(step) < ROTATION_TOLERANCE {
                break;
            }
        }
    }
    let cost = solution.cost - target.merge_variance;
    Ok(SphereDistance {
        cost,
        dual_cost: solution.dual_value() - target.merge_variance,
        distance: cost.max(0.0).sqrt(),
        rotation,
        solves: tally.solves,
        iterations: tally.iterations,
        evaluations: tally.evaluations,
        refinement_steps,
        max_mass_error: solution.max_relative_error,
        converged: solution.converged(),
        status: solution.stop.to_string(),
        seconds_proxy,
        seconds_scoring,
        seconds_refinement: t_refine.elapsed().as_secs_f64(),
        seconds: start.elapsed().as_secs_f64(),
    })
}
