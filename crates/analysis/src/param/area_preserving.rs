//! Area-preserving parameterization of a disk-type surface by optimal mass transport
//! [Su et al. 2015, "Shape classification using Wasserstein distance for brain morphometry
//! analysis", Algorithm 2; Zhao et al. 2013, "Area-preservation mapping using optimal mass
//! transport", §4].
//!
//! Steps (surface scaled to total area π):
//! 1. the conformal disk map φ: M → D (interior marker ↦ 0, boundary marker ↦ 1), from
//!    `shapespace_conformal::disk_map`;
//! 2. target points $y_i = \varphi(v_i)$ with masses $\nu_i = \tfrac13 \sum_{f \ni i} A_f$
//!    (optionally multiplied by importance weights $w_i$ and renormalized to total π);
//! 3. semi-discrete OT from the *uniform* (Lebesgue) measure on the domain Ω to $(y, \nu)$:
//!    heights h with $|W_i(h) \cap \Omega| = \nu_i$ for every i (`shapespace_omt::solve_ot`);
//! 4. every vertex is sent to the centroid $c_i = \frac{1}{|W_i|}\int_{W_i} x\,dx$ of its cell.
//!    The OT map $T = \nabla u_h$ sends $W_i$ to $y_i$; the map $v_i \mapsto c_i$ is the discrete
//!    inverse $T^{-1} \circ \varphi$, the area-preserving map closest to φ in the $L^2$ sense.
//! 5. fold repair (on by default, [`AreaPreservingParams::fold_repair`]): the single-shot
//!    centroid map can fold small triangles where the conformal image is strongly compressed
//!    (the points y_i are nearly coincident relative to their cells, the cells become long
//!    strips, and the order of their centroids need not follow the mesh). The vertices around
//!    the folded faces are re-embedded by a Tutte/Floater map with mean-value weights of the
//!    centroid layout, in regions that grow until no face is folded
//!    ([`crate::fold_repair`]; guaranteed to end with an embedding when the region reaches
//!    the whole disk). Only positions change: `cell_areas` and the OT summary still describe
//!    the transport; [`FoldRepairSummary`] reports the distortion before and after.
//!
//! # Domain and boundary (choices, not in the papers)
//! - **Disk** ([`Domain::Disk`]): Ω is the regular polygon with K vertices (one at angle 0) and
//!   circumradius $\rho_K = \sqrt{2\pi / (K \sin(2\pi/K))}$, so that $|\Omega| = \pi = \sum \nu_i$
//!   exactly and no mass rescaling happens. Its boundary stays within
//!   $\pi^2/(3K^2)$ of the unit circle (≈ 3.1e-6 for K = 1024). K defaults to
//!   max(1024, 8·#boundary vertices), so every boundary cell's outer side is resolved by ≥ 8
//!   chords: the boundary cells' areas are then those of the true disk up to a band of relative
//!   width ~1e-5.
//! - **Square** ([`Domain::Square`]): Ω = [−√π/2, √π/2]², area π (Su et al. 2015, Fig. 2).
//!   The targets stay in the unit disk (which sticks out of the square: the OT solver handles
//!   sites outside Ω).
//! - **Boundary vertices.** Their cell centroids lie strictly inside Ω. Each one is projected
//!   radially from the origin onto ∂D (the unit circle, for both `Disk`) or onto ∂Ω (`Square`):
//!   $c \mapsto c / |c|$, resp. $c \mapsto c\,\frac{\sqrt\pi/2}{\max(|c_x|, |c_y|)}$. Radial
//!   projection preserves the angular order of the centroids, and the boundary cells meet ∂Ω in
//!   the same cyclic order as the boundary vertices (the OT map is monotone), but a cell's
//!   centroid need not lie at the angle where the cell meets ∂Ω: two thin neighbouring boundary
//!   cells can have their centroids in the opposite angular order (TOSCA centaur0 slit twice:
//!   two cut-boundary vertices 5e-5 rad apart, swapped). No interior re-embedding can repair
//!   that, so [`order_boundary`] restores the order first: it keeps a longest run of
//!   boundary vertices whose angles increase and spaces the others evenly between them. The
//!   result counts the violations ([`AreaPreservingMap::boundary_order_violations`]) and the
//!   vertices moved ([`AreaPreservingMap::boundary_vertices_reordered`]).
//! - **Square corners.** A face with all three corners on the boundary (an ear: boundary
//!   vertices a, m, b consecutive along a loop) whose images land on one side of the square is
//!   flat, and no interior re-embedding can repair it: a corner of the square must lie between
//!   a's and b's images. When some ears are flat after the OT (a square plate, whose corner
//!   triangles are ears, maps its corners to the middles of the square's sides), the targets
//!   are turned about the origin by the angle that puts a corner inside the most ears
//!   ([`corner_rotation`], from the first map's boundary angles), the OT is solved again, and
//!   the turned map is kept when it has fewer flat ears
//!   ([`AreaPreservingMap::square_rotation`]). The OT map is not exactly equivariant under
//!   turns of the targets alone (the square is not round), so this is a best effort; flat ears
//!   that remain stay degenerate in the map and are counted by the fold repair
//!   (`FoldRepairInfo::flat_boundary_faces`; the square's boundary projection sets the side's
//!   coordinate exactly, so they are exactly flat, not flipped by rounding).
//!
//! # Importance weights (Zhao et al. 2013, §4; Su et al. 2015, §5.2)
//! Per-vertex weights $w_i > 0$ give $\nu_i \leftarrow \pi\, w_i \nu_i / \sum_j w_j \nu_j$: a region
//! R then receives the share $\sum_{i \in R} w_i\nu_i / \sum_j w_j\nu_j$ of the domain.

use std::path::Path;
use std::time::Instant;

use serde::Serialize;
use shapespace_conformal::quality::Stats;
use shapespace_conformal::{disk_map, DiskMap, DiskMapParams, Markers};
use shapespace_geometry::quantities::vertex_dual_areas;
use shapespace_geometry::{Connectivity, TriMesh};
use shapespace_omt::{solve_ot, NewtonParams, OtSolution, SourceMeasure};

use crate::distortion::map_distortion;
use crate::error::AnalysisError;
use crate::fold_repair::{repair_folds_with, FoldRepairInfo, FoldRepairParams};

/// The domain of the area-preserving map.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize)]
#[serde(rename_all = "lowercase")]
pub enum Domain {
    /// The unit disk (as a K-gon of area π, module docs).
    #[default]
    Disk,
    /// The square [−√π/2, √π/2]² of area π.
    Square,
}

impl std::str::FromStr for Domain {
    type Err = AnalysisError;
    /// Parses `disk` or `square` (case-insensitive).
    fn from_str(s: &str) -> Result<Self, Self::Err> {
        match s.trim().to_ascii_lowercase().as_str() {
            "disk" => Ok(Domain::Disk),
            "square" => Ok(Domain::Square),
            other => Err(AnalysisError::InvalidInput(format!(
                "unknown domain `{other}` (expected disk or square)"
            ))),
        }
    }
}

/// Parameters of [`area_preserving_map`].
#[derive(Clone, Debug)]
pub struct AreaPreservingParams {
    /// The domain Ω (default the disk).
    pub domain: Domain,
    /// Number K of vertices of the polygon standing for the unit disk; `None`: max(1024,
    /// 8·#boundary vertices). Ignored for the square.
    pub disk_polygon_vertices: Option<usize>,
    /// Parameters of the conformal map.
    pub disk_map: DiskMapParams,
    /// Parameters of the Newton OT solver (tolerance on max_i |μ(W_i) − ν_i|/ν_i, default 1e-6).
    pub newton: NewtonParams,
    /// Per-vertex importance weights w_i > 0 (#V) multiplying the masses ν_i; `None`: all 1.
    pub weights: Option<Vec<f64>>,
    /// Return [`AnalysisError::Transport`] when the OT solver does not reach its tolerance
    /// (default true). When false, the map of the last iterate is returned and
    /// [`OtSummary::converged`] tells.
    pub require_convergence: bool,
    /// Fold repair after the centroid map (default on; [`crate::fold_repair`]).
    pub fold_repair: FoldRepairParams,
}

impl Default for AreaPreservingParams {
    fn default() -> Self {
        AreaPreservingParams {
            domain: Domain::Disk,
            disk_polygon_vertices: None,
            disk_map: DiskMapParams::default(),
            newton: NewtonParams::default(),
            weights: None,
            require_convergence: true,
            fold_repair: FoldRepairParams::default(),
        }
    }
}

/// Summary of the OT solve.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct OtSummary {
    /// Newton steps taken.
    pub iterations: usize,
    /// max_i |μ(W_i) − ν_i| / ν_i at the end.
    pub max_relative_error: f64,
    /// The tolerance asked for.
    pub tolerance: f64,
    /// Whether the tolerance was reached.
    pub converged: bool,
    /// Why the iteration stopped (`converged`, `iteration cap`, `stalled: ...`).
    pub stop: String,
    /// Where the initial heights came from.
    pub start: String,
    /// Transport cost Σ_i ∫_{W_i} |x − y_i|² dx.
    pub cost: f64,
    /// Factor the solver applied to the masses (1 up to roundoff: Ω has area π).
    pub mass_scale: f64,
    /// Number of vertices of the domain polygon.
    pub domain_vertices: usize,
}

/// Wall-clock seconds of the stages of [`area_preserving_map`].
#[derive(Clone, Debug, Default, PartialEq, Serialize)]
pub struct Timings {
    /// Conformal disk map.
    pub conformal: f64,
    /// Optimal transport: the Newton solve (both, when the square was turned).
    pub ot: f64,
    /// Centroids, boundary projection and checks (for the square also the ears' test).
    pub output: f64,
    /// Fold repair, with the distortion measured before and after it.
    pub repair: f64,
    /// Everything.
    pub total: f64,
}

/// Area distortion and folds of a map (the summary kept in [`FoldRepairSummary`]).
#[derive(Clone, Debug, Default, PartialEq, Serialize)]
pub struct MapQuality {
    /// Statistics of |Υ| per face.
    pub abs_area_distortion: Stats,
    /// Statistics of |ε| per vertex (log one-ring area ratio, [`crate::distortion`]).
    pub abs_vertex_log_area_ratio: Stats,
    /// Clockwise faces (exact predicate).
    pub num_flipped: usize,
    /// Faces of exactly zero image area.
    pub num_degenerate: usize,
}

/// The fold repair step of [`area_preserving_map`]: what it did and the distortion of the
/// centroid map (before) and of the returned map (after).
#[derive(Clone, Debug, Default, PartialEq, Serialize)]
pub struct FoldRepairSummary {
    /// Counts, rounds and moved vertices of the repair.
    #[serde(flatten)]
    pub info: FoldRepairInfo,
    /// The centroid map.
    pub before: MapQuality,
    /// The returned map (equal to `before` when nothing moved).
    pub after: MapQuality,
}

/// An area-preserving map of a disk-type surface onto the disk or the square.
#[derive(Clone, Debug)]
pub struct AreaPreservingMap {
    /// Image of each vertex, #V: the centroid of its OT cell, boundary vertices on ∂Ω, then
    /// (fold repair on) the vertices near folded faces re-embedded ([`crate::fold_repair`]).
    pub uv: Vec<[f64; 2]>,
    /// The conformal map the OT started from (its `uv` are the targets y_i).
    pub conformal: DiskMap,
    /// Target masses ν_i after weights and normalization, #V (Σ = π).
    pub target_masses: Vec<f64>,
    /// Areas |W_i ∩ Ω| of the cells at the final heights, #V (of the OT, not of the repaired
    /// map's one-rings: see [`FoldRepairSummary::after`]).
    pub cell_areas: Vec<f64>,
    /// OT heights h, #V (u_h(x) = max_i ⟨x, y_i⟩ + h_i).
    pub heights: Vec<f64>,
    /// The domain used.
    pub domain: Domain,
    /// The domain polygon Ω (counter-clockwise).
    pub domain_polygon: Vec<[f64; 2]>,
    /// Whether each vertex lies on the mesh boundary, #V.
    pub is_boundary: Vec<bool>,
    /// Largest distance a boundary centroid moved in the projection onto ∂Ω.
    pub max_boundary_projection: f64,
    /// Boundary edges whose projected centroids turn the wrong way around the origin (0 = the
    /// boundary order is preserved), before [`order_boundary`].
    pub boundary_order_violations: usize,
    /// Boundary vertices that [`order_boundary`] moved to restore the order (0 when there was
    /// no violation).
    pub boundary_vertices_reordered: usize,
    /// The angle (radians) by which the conformal image was turned about the origin before the
    /// OT, so that the square's corners fall inside the boundary's ears (module docs, "Square
    /// corners"); 0 for the disk and when no ear needed it. When it is not 0 the OT was solved
    /// twice: `ot` describes the second solve, `timings.ot` counts both.
    pub square_rotation: f64,
    /// OT solver summary.
    pub ot: OtSummary,
    /// The fold repair step.
    pub fold_repair: FoldRepairSummary,
    /// Stage timings.
    pub timings: Timings,
}

/// The polygon standing for Ω: for the disk, the regular K-gon of area π (circumradius
/// ρ_K = √(2π/(K sin(2π/K))), vertex 0 at angle 0); for the square, [−√π/2, √π/2]².
/// Counter-clockwise. Errors when K < 3.
pub fn domain_polygon(domain: Domain, k: usize) -> Result<Vec<[f64; 2]>, AnalysisError> {
    match domain {
        Domain::Disk => {
            if k < 3 {
                return Err(AnalysisError::InvalidInput(format!(
                    "the disk polygon needs at least 3 vertices, got {k}"
                )));
            }
            let step = std::f64::consts::TAU / k as f64;
            let rho = (std::f64::consts::TAU / (k as f64 * step.sin())).sqrt();
            Ok((0..k)
                .map(|j| [rho * (j as f64 * step).cos(), rho * (j as f64 * step).sin()])
                .collect())
        }
        Domain::Square => {
            let a = 0.5 * std::f64::consts::PI.sqrt();
            Ok(vec![[-a, -a], [a, -a], [a, a], [-a, a]])
        }
    }
}

/// The uniform (density 1) source measure on the domain polygon `polygon` of [`domain_polygon`].
///
/// The square is split into two triangles. The disk K-gon is triangulated by *graded rings*
/// instead of a fan (a fan of K slivers from the center makes every sliver cross a whole radius
/// of OT cells, and restricted integration costs O(K·√N)): ring 0 is the K-gon, ring j + 1 has
/// half the vertices of ring j (at the angles of its even vertices) at radius
/// r_{j+1} = r_j (1 − 2π/K_j), so every triangle has comparable edge lengths, three triangles
/// join a ring to the next (one per inner vertex and two per outer edge pair), and the last
/// ring (≤ 16 vertices, or K not divisible by 2) is a fan from the center. About 3K triangles,
/// all of aspect ratio O(1). Errors when K < 3.
pub fn domain_measure(domain: Domain, polygon: &[[f64; 2]]) -> Result<SourceMeasure, AnalysisError> {
    let k = polygon.len();
    if k < 3 {
        return Err(AnalysisError::InvalidInput(format!(
            "the domain polygon needs at least 3 vertices, got {k}"
        )));
    }
    if domain == Domain::Square || k <= 16 {
        return SourceMeasure::uniform_polygon(polygon, 1.0).map_err(AnalysisError::Transport);
    }
    let mut vertices: Vec<[f64; 2]> = polygon.to_vec();
    let mut triangles: Vec<[u32; 3]> = Vec::new();
    let rho = polygon[0][0].hypot(polygon[0][1]);
    let step0 = std::f64::consts::TAU / k as f64;
    // the current (outer) ring: its first vertex index, count and radius
    let (mut start, mut count, mut radius) = (0usize, k, rho);
    while count > 16 && count % 2 == 0 {
        let inner_count = count / 2;
        let inner_radius = radius * (1.0 - std::f64::consts::TAU / count as f64);
        let inner_start = vertices.len();
        let stride = k / inner_count; // angle index step of the inner ring in units of step0
        for m in 0..inner_count {
            let t = (m * stride) as f64 * step0;
            vertices.push([inner_radius * t.cos(), inner_radius * t.sin()]);
        }
        let o = |j: usize| (start + j % count) as u32;
        let i = |m: usize| (inner_start + m % inner_count) as u32;
        for m in 0..inner_count {
            triangles.push([i(m), o(2 * m), o(2 * m + 1)]);
            triangles.push([i(m), o(2 * m + 1), o(2 * m + 2)]);
            triangles.push([i(m), o(2 * m + 2), i(m + 1)]);
        }
        start = inner_start;
        count = inner_count;
        radius = inner_radius;
    }
    let center = vertices.len() as u32;
    vertices.push([0.0, 0.0]);
    for j in 0..count {
        triangles.push([center, (start + j) as u32, (start + (j + 1) % count) as u32]);
    }
    let densities = vec![1.0; triangles.len()];
    SourceMeasure::new(vertices, triangles, densities).map_err(AnalysisError::Transport)
}

/// Radial projection of `c` from the origin onto ∂Ω: the unit circle for the disk, the square's
/// boundary for the square. The origin itself is returned unchanged (it cannot be a boundary
/// centroid of a non-degenerate diagram; the caller reports it).
fn project_to_boundary(domain: Domain, c: [f64; 2]) -> [f64; 2] {
    match domain {
        Domain::Disk => {
            let r = c[0].hypot(c[1]);
            if r > 0.0 {
                [c[0] / r, c[1] / r]
            } else {
                c
            }
        }
        Domain::Square => {
            // radially onto the side the point faces, whose coordinate is set exactly (±a), so
            // that vertices on one side are exactly collinear: an ear flat on a side is then
            // degenerate, not flipped by rounding
            let a = 0.5 * std::f64::consts::PI.sqrt();
            let m = c[0].abs().max(c[1].abs());
            if !(m > 0.0) {
                c
            } else if c[0].abs() >= c[1].abs() {
                [a.copysign(c[0]), c[1] * (a / m)]
            } else {
                [c[0] * (a / m), a.copysign(c[1])]
            }
        }
    }
}

/// Target masses ν_i = π·w_i a_i / Σ_j w_j a_j from one-ring thirds a_i (#V) and optional
/// weights w (#V, finite and > 0; used relative to the largest). Errors on a vertex without
/// incident area, a bad weight, or a mass that is not a normal f64 (weights or areas spanning
/// more orders of magnitude than f64 holds).
pub fn weighted_target_masses(ring_thirds: &[f64], weights: Option<&[f64]>) -> Result<Vec<f64>, AnalysisError> {
    if let Some(w) = weights {
        if w.len() != ring_thirds.len() {
            return Err(AnalysisError::InvalidInput(format!(
                "{} weights for {} vertices",
                w.len(),
                ring_thirds.len()
            )));
        }
        if let Some(i) = w.iter().position(|x| !(x.is_finite() && *x > 0.0)) {
            return Err(AnalysisError::InvalidInput(format!(
                "weight of vertex {i} is {} (must be finite and > 0)",
                w[i]
            )));
        }
    }
    if let Some(i) = ring_thirds.iter().position(|a| !(a.is_finite() && *a > 0.0)) {
        return Err(AnalysisError::InvalidInput(format!(
            "vertex {i} has no incident area ({}): remove unreferenced vertices and degenerate faces first",
            ring_thirds[i]
        )));
    }
    // (the weights relative to the largest, so that any finite positive weights give finite
    // masses: 1e308 on every vertex is no weighting at all)
    let largest = weights.map_or(1.0, |w| w.iter().fold(0.0f64, |m, &x| m.max(x)));
    let raw: Vec<f64> = match weights {
        Some(w) => ring_thirds.iter().zip(w).map(|(a, w)| a * (w / largest)).collect(),
        None => ring_thirds.to_vec(),
    };
    let total: f64 = raw.iter().sum();
    // (in the order of operations before the weights were scaled: the same masses, to the bit,
    // as before for unweighted maps; m·π cannot overflow with the weights at most 1)
    let masses: Vec<f64> = raw.iter().map(|m| m * std::f64::consts::PI / total).collect();
    if let Some(i) = masses.iter().position(|m| !m.is_normal()) {
        return Err(AnalysisError::InvalidInput(match weights {
            Some(w) => format!(
                "the weights leave vertex {i} a target mass of {:e} (weight {:e} against the largest {:e}): \
                 the weights span too many orders of magnitude",
                masses[i], w[i], largest
            ),
            None => format!(
                "vertex {i} has a target mass of {:e}: its one-ring area ({:e}) is too small beside the total ({total:e})",
                masses[i], ring_thirds[i]
            ),
        }));
    }
    Ok(masses)
}

/// The OT problem of [`area_preserving_map`] (Su et al. 2015, Algorithm 2, steps 1–2): the
/// conformal disk map φ, the targets y_i = φ(v_i) with masses ν_i (one third of the one-ring
/// area of the surface scaled to π, times the weights, renormalized to π), and the source: Ω
/// with the uniform density (the disk as a K-gon of area π, K = max(1024, 8 × boundary
/// vertices) unless set, or the square).
#[derive(Clone, Debug)]
pub struct TransportProblem {
    /// The conformal map; its `uv` are the target points.
    pub conformal: DiskMap,
    /// ν_i, #V (Σ = π).
    pub target_masses: Vec<f64>,
    /// Whether each vertex lies on the mesh boundary, #V.
    pub is_boundary: Vec<bool>,
    /// The domain polygon Ω (counter-clockwise).
    pub polygon: Vec<[f64; 2]>,
    /// The uniform measure on Ω.
    pub measure: SourceMeasure,
}

/// Builds the [`TransportProblem`] of `mesh` (errors of the conformal map, the weights or the
/// domain).
pub fn transport_problem(
    mesh: &TriMesh,
    markers: &Markers,
    params: &AreaPreservingParams,
) -> Result<TransportProblem, AnalysisError> {
    transport_problem_with(mesh, &Connectivity::of(mesh), markers, params)
}

/// [`transport_problem`] with the mesh's connectivity `conn`.
fn transport_problem_with(
    mesh: &TriMesh,
    conn: &Connectivity,
    markers: &Markers,
    params: &AreaPreservingParams,
) -> Result<TransportProblem, AnalysisError> {
    let conformal = disk_map(mesh, markers, &params.disk_map).map_err(AnalysisError::DiskMap)?;
    let scale2 = conformal.scale * conformal.scale;
    let thirds: Vec<f64> = vertex_dual_areas(mesh).iter().map(|a| a * scale2).collect();
    let target_masses = weighted_target_masses(&thirds, params.weights.as_deref())?;
    let is_boundary = conn.boundary_vertices(mesh.num_vertices());
    let num_boundary = is_boundary.iter().filter(|&&b| b).count();
    let k = match params.domain {
        Domain::Disk => params.disk_polygon_vertices.unwrap_or((8 * num_boundary).max(1024)),
        Domain::Square => 4,
    };
    let polygon = domain_polygon(params.domain, k)?;
    let measure = domain_measure(params.domain, &polygon)?;
    Ok(TransportProblem {
        conformal,
        target_masses,
        is_boundary,
        polygon,
        measure,
    })
}

/// The area-preserving map of a disk-type `mesh` (#V positions, #F faces) onto the unit disk or
/// the square, by composing its conformal disk map with the inverse OT map (module docs;
/// Su et al. 2015, Alg. 2).
///
/// Output: [`AreaPreservingMap`] with `uv` (#V) whose cells have areas `target_masses` to the
/// solver tolerance. Errors: the conformal map fails (not a disk, bad markers, folded image),
/// invalid weights, the OT solver fails or (with `require_convergence`) does not converge.
pub fn area_preserving_map(
    mesh: &TriMesh,
    markers: &Markers,
    params: &AreaPreservingParams,
) -> Result<AreaPreservingMap, AnalysisError> {
    let t0 = Instant::now();
    // (one connectivity for the boundary flags, the boundary order and the fold repair)
    let conn = Connectivity::of(mesh);
    let TransportProblem {
        conformal,
        target_masses,
        is_boundary,
        polygon,
        measure,
    } = transport_problem_with(mesh, &conn, markers, params)?;
    let t1 = Instant::now();
    // OT from Ω to the targets (the conformal image turned by `rotation`), the centroid map and
    // the boundary order
    let place = |rotation: f64| -> Result<Placement, AnalysisError> {
        let (sin, cos) = rotation.sin_cos();
        let targets: Vec<[f64; 2]> = if rotation == 0.0 {
            conformal.uv.clone()
        } else {
            conformal
                .uv
                .iter()
                .map(|p| [cos * p[0] - sin * p[1], sin * p[0] + cos * p[1]])
                .collect()
        };
        let t_solve = Instant::now();
        let solution =
            solve_ot(&measure, &targets, &target_masses, &params.newton).map_err(AnalysisError::Transport)?;
        let ot_seconds = t_solve.elapsed().as_secs_f64();
        let solution = if params.require_convergence {
            solution.into_result().map_err(AnalysisError::Transport)?
        } else {
            solution
        };
        let (mut uv, max_projection) = centroid_map(params.domain, &solution, &is_boundary)?;
        let violations = boundary_order_violations_with(&conn, mesh, &uv);
        let reordered = if violations > 0 {
            order_boundary_with(&conn, mesh, params.domain, &mut uv)
        } else {
            0
        };
        Ok(Placement {
            solution,
            uv,
            max_projection,
            violations,
            reordered,
            ot_seconds,
        })
    };
    let mut placed = place(0.0)?;
    let mut ot_seconds = placed.ot_seconds;
    // The square: ears flat on one side (module docs, "Square corners") are avoided by turning
    // the targets so that a corner falls inside each ear, when a turn does better.
    let mut square_rotation = 0.0;
    if params.domain == Domain::Square {
        let ears = boundary_ears(mesh);
        let flat = |uv: &[[f64; 2]]| ears.iter().filter(|e| !ear_is_proper(uv, e)).count();
        let flat_before = flat(&placed.uv);
        if flat_before > 0 {
            if let Some(rotation) = corner_rotation(&ears, &placed.uv) {
                // (a turned solve that fails keeps the first map: its flat ears are then the fold
                // repair's report)
                if let Ok(turned) = place(rotation) {
                    ot_seconds += turned.ot_seconds;
                    // (never a converged map for one that did not converge)
                    let converged = turned.solution.converged() || !placed.solution.converged();
                    if converged && flat(&turned.uv) < flat_before {
                        placed = turned;
                        square_rotation = rotation;
                    }
                }
            }
        }
    }
    let Placement {
        solution,
        mut uv,
        max_projection: max_boundary_projection,
        violations: boundary_order_violations,
        reordered: boundary_vertices_reordered,
        ..
    } = placed;
    let ot = OtSummary {
        iterations: solution.iterations,
        max_relative_error: solution.max_relative_error,
        tolerance: solution.tolerance,
        converged: solution.converged(),
        stop: solution.stop_description(),
        start: format!("{:?}", solution.start),
        cost: solution.cost,
        mass_scale: solution.mass_scale,
        domain_vertices: polygon.len(),
    };
    let t3 = Instant::now();
    // The input's report runs beside the repair (which is mostly sequential: its retraction).
    let input = uv.clone();
    let (before, info) = rayon::join(
        || map_quality(mesh, &input),
        || repair_folds_with(mesh, Some(&conn), &is_boundary, &mut uv, &params.fold_repair),
    );
    let (before, info) = (before?, info.map_err(AnalysisError::from_fold_repair)?);
    let after = if info.vertices_moved > 0 {
        map_quality(mesh, &uv)?
    } else {
        before.clone()
    };
    let fold_repair = FoldRepairSummary { info, before, after };
    let t4 = Instant::now();
    let secs = |a: Instant, b: Instant| (b - a).as_secs_f64();
    Ok(AreaPreservingMap {
        uv,
        conformal,
        target_masses,
        cell_areas: solution.cells.masses,
        heights: solution.heights,
        domain: params.domain,
        domain_polygon: polygon,
        is_boundary,
        max_boundary_projection,
        boundary_order_violations,
        boundary_vertices_reordered,
        square_rotation,
        ot,
        fold_repair,
        timings: Timings {
            conformal: secs(t0, t1),
            ot: ot_seconds,
            output: secs(t1, t3) - ot_seconds,
            repair: secs(t3, t4),
            total: secs(t0, t4),
        },
    })
}

/// |Υ|, |ε| statistics and fold counts of the map `uv` of `mesh`.
fn map_quality(mesh: &TriMesh, uv: &[[f64; 2]]) -> Result<MapQuality, AnalysisError> {
    let d = map_distortion("", mesh, uv)?;
    Ok(MapQuality {
        abs_area_distortion: d.abs_area_distortion,
        abs_vertex_log_area_ratio: d.abs_vertex_log_area_ratio,
        num_flipped: d.num_flipped,
        num_degenerate: d.num_degenerate,
    })
}

/// Cell centroids, boundary vertices projected onto ∂Ω; returns the map and the largest
/// projection distance. Errors on an empty cell (only possible for an unconverged solution).
fn centroid_map(
    domain: Domain,
    solution: &OtSolution,
    is_boundary: &[bool],
) -> Result<(Vec<[f64; 2]>, f64), AnalysisError> {
    let mut max_move = 0.0f64;
    let mut uv = Vec::with_capacity(is_boundary.len());
    for (i, c) in solution.centroids().into_iter().enumerate() {
        let c = c.ok_or_else(|| {
            AnalysisError::InvalidInput(format!(
                "the OT cell of vertex {i} is empty (solver stopped: {}); no centroid",
                solution.stop
            ))
        })?;
        if is_boundary[i] {
            let p = project_to_boundary(domain, c);
            max_move = max_move.max((p[0] - c[0]).hypot(p[1] - c[1]));
            uv.push(p);
        } else {
            uv.push(c);
        }
    }
    Ok((uv, max_move))
}

/// Number of boundary edges (a → b along the oriented boundary loops of `mesh`) whose images
/// turn clockwise around the origin, i.e. cross(uv_a, uv_b) ≤ 0. For a map that keeps the
/// boundary on a star-shaped curve in counter-clockwise order this is 0.
pub fn boundary_order_violations(mesh: &TriMesh, uv: &[[f64; 2]]) -> usize {
    boundary_order_violations_with(&Connectivity::of(mesh), mesh, uv)
}

/// [`boundary_order_violations`] with the mesh's connectivity `conn`.
fn boundary_order_violations_with(conn: &Connectivity, mesh: &TriMesh, uv: &[[f64; 2]]) -> usize {
    conn.boundary_halfedges(&mesh.faces)
        .iter()
        .filter(|[a, b]| {
            let (p, q) = (uv[*a as usize], uv[*b as usize]);
            p[0] * q[1] - p[1] * q[0] <= 0.0
        })
        .count()
}

/// Puts the boundary images back in counter-clockwise order along each boundary loop of `mesh`
/// (module docs, "Boundary vertices"), in place; returns the number of boundary vertices moved.
///
/// Per loop, with the angles θ_k of the images in loop order: the loop is read from the vertex
/// after its largest angular gap, a longest subsequence whose unwrapped angles increase
/// strictly and span less than a turn is kept, and every other vertex is put on ∂Ω at evenly
/// spaced angles between the kept vertices before and after it. A loop whose images do not
/// wind once around the origin (gaps are taken in (−π, π], so this includes a correctly
/// ordered loop with a gap of π or more) is left as it is (nothing local can order it; the
/// fold repair then reports it).
pub fn order_boundary(mesh: &TriMesh, domain: Domain, uv: &mut [[f64; 2]]) -> usize {
    order_boundary_with(&Connectivity::of(mesh), mesh, domain, uv)
}

/// [`order_boundary`] with the mesh's connectivity `conn`.
fn order_boundary_with(conn: &Connectivity, mesh: &TriMesh, domain: Domain, uv: &mut [[f64; 2]]) -> usize {
    let mut moved = 0;
    for lp in conn.boundary_loops(&mesh.faces) {
        let n = lp.len();
        if n < 3 {
            continue;
        }
        let theta: Vec<f64> = lp.iter().map(|&v| uv[v as usize][1].atan2(uv[v as usize][0])).collect();
        let tau = std::f64::consts::TAU;
        let wrap = |d: f64| d - tau * (d / tau).round();
        let gaps: Vec<f64> = (0..n).map(|k| wrap(theta[(k + 1) % n] - theta[k])).collect();
        let winding: f64 = gaps.iter().sum();
        // (also skips NaN images: the comparison is false for them)
        if !((winding - tau).abs() <= 1e-6) || gaps.iter().all(|&d| d > 0.0) {
            continue;
        }
        // start after the largest gap; u: unwrapped angles in that order
        let start = (0..n)
            .max_by(|&a, &b| gaps[a].total_cmp(&gaps[b]))
            .map_or(0, |k| (k + 1) % n);
        let mut u = Vec::with_capacity(n);
        let mut acc = theta[start];
        for j in 0..n {
            u.push(acc);
            acc += gaps[(start + j) % n];
        }
        let mut kept = longest_increasing(&u);
        // The unwrapped angles are bounded only at the loop's end (u_n = u_0 + 2π): on a
        // boundary that folds back on itself the kept run can span a turn or more, and the
        // vertices after its last kept one would then be spread backwards. Keep less than a turn.
        while kept.len() > 1 && u[kept[kept.len() - 1]] >= u[kept[0]] + tau {
            kept.pop();
        }
        if kept.len() < 2 {
            continue;
        }
        // spread the others between consecutive kept vertices (cyclically: the last kept one
        // and the first kept one plus a turn)
        for (w, &a) in kept.iter().enumerate() {
            let (b, ub) = if w + 1 < kept.len() {
                (kept[w + 1], u[kept[w + 1]])
            } else {
                (kept[0] + n, u[kept[0]] + tau)
            };
            for j in a + 1..b {
                let t = u[a] + (ub - u[a]) * (j - a) as f64 / (b - a) as f64;
                let v = lp[(start + j) % n] as usize;
                uv[v] = project_to_boundary(domain, [t.cos(), t.sin()]);
                moved += 1;
            }
        }
    }
    moved
}

/// One placement of the vertices by [`area_preserving_map`]: the OT solution towards the
/// (possibly turned) targets, the centroid map with its largest boundary projection, the
/// boundary order violations found and the vertices [`order_boundary`] moved, and the seconds
/// of the OT solve.
struct Placement {
    solution: OtSolution,
    uv: Vec<[f64; 2]>,
    max_projection: f64,
    violations: usize,
    reordered: usize,
    ot_seconds: f64,
}

/// The ears of `mesh`: faces whose three corners are consecutive along a boundary loop, as
/// (a, m, b) with a → m → b the loop's order.
pub fn boundary_ears(mesh: &TriMesh) -> Vec<[u32; 3]> {
    let conn = Connectivity::of(mesh);
    let mut next: Vec<Option<u32>> = vec![None; mesh.num_vertices()];
    for [a, b] in conn.boundary_halfedges(&mesh.faces) {
        next[a as usize] = Some(b);
    }
    let mut ears = Vec::new();
    for f in &mesh.faces {
        for k in 0..3 {
            let a = f[k];
            if let Some(m) = next[a as usize] {
                if let Some(b) = next[m as usize] {
                    if b != a && f.contains(&m) && f.contains(&b) {
                        ears.push([a, m, b]);
                    }
                }
            }
        }
    }
    ears
}

/// Whether the ear (a, m, b) has an image of non-zero area above rounding (a flat ear has its
/// three corners on one side of the square; a flipped one counts as proper here, it is the fold
/// repair's business).
fn ear_is_proper(uv: &[[f64; 2]], ear: &[u32; 3]) -> bool {
    let [pa, pm, pb] = ear.map(|v| uv[v as usize]);
    let area = (pm[0] - pa[0]) * (pb[1] - pa[1]) - (pm[1] - pa[1]) * (pb[0] - pa[0]);
    let scale = (pm[0] - pa[0]).hypot(pm[1] - pa[1]) * (pb[0] - pa[0]).hypot(pb[1] - pa[1]);
    area.abs() > 1e-9 * scale
}

/// The turn ρ ∈ (−π/4, π/4] of the targets that puts a corner of the square (at angles
/// π/4 + kπ/2) inside the most `ears`, judged on the boundary angles of the map `uv` (a corner
/// is inside an ear when it lies in the middle 80 % of the arc from a's image to b's); candidates
/// are the turns that centre a corner on one ear. `None` when no candidate does better than no
/// turn.
pub fn corner_rotation(ears: &[[u32; 3]], uv: &[[f64; 2]]) -> Option<f64> {
    use std::f64::consts::{FRAC_PI_2, FRAC_PI_4, TAU};
    let angle = |v: u32| uv[v as usize][1].atan2(uv[v as usize][0]);
    let arcs: Vec<(f64, f64)> = ears
        .iter()
        .map(|&[a, _, b]| (angle(a), (angle(b) - angle(a)).rem_euclid(TAU)))
        .filter(|&(_, width)| width < FRAC_PI_2)
        .collect();
    // corners inside the ears after a turn by rho
    let score = |rho: f64| {
        arcs.iter()
            .filter(|&&(start, width)| {
                let offset = (FRAC_PI_4 - rho - start).rem_euclid(FRAC_PI_2);
                offset > 0.1 * width && offset < 0.9 * width
            })
            .count()
    };
    let wrap = |r: f64| {
        let r = r.rem_euclid(FRAC_PI_2);
        if r > FRAC_PI_4 {
            r - FRAC_PI_2
        } else {
            r
        }
    };
    let base = score(0.0);
    arcs.iter()
        .map(|&(start, width)| wrap(FRAC_PI_4 - (start + 0.5 * width)))
        .map(|rho| (score(rho), rho))
        .filter(|&(s, _)| s > base)
        .max_by(|x, y| x.0.cmp(&y.0).then(y.1.abs().total_cmp(&x.1.abs())))
        .map(|(_, rho)| rho)
}

/// Indices of a longest strictly increasing subsequence of `x` (patience sorting, O(n log n)).
fn longest_increasing(x: &[f64]) -> Vec<usize> {
    // tails[l]: index of the smallest last element of an increasing subsequence of length l + 1
    let mut tails: Vec<usize> = Vec::new();
    let mut prev = vec![usize::MAX; x.len()];
    for i in 0..x.len() {
        let l = tails.partition_point(|&t| x[t] < x[i]);
        if l > 0 {
            prev[i] = tails[l - 1];
        }
        if l == tails.len() {
            tails.push(i);
        } else {
            tails[l] = i;
        }
    }
    let mut out = Vec::with_capacity(tails.len());
    let mut k = tails.last().copied().unwrap_or(usize::MAX);
    while k != usize::MAX {
        out.push(k);
        k = prev[k];
    }
    out.reverse();
    out
}

/// Per-vertex importance weights from a CSV file of rows `vertex,weight` (vertex: 0-based index
/// < `num_vertices`, weight: finite > 0), optionally below the header `vertex,weight`; vertices
/// not listed get 1. Errors (as `path:line: problem`): unreadable file, a first row that is
/// neither that header nor a data row, malformed row, index out of range, repeated vertex, bad
/// weight, no data row at all.
pub fn read_vertex_weights(path: &Path, num_vertices: usize) -> Result<Vec<f64>, AnalysisError> {
    let mut reader = csv::ReaderBuilder::new()
        .has_headers(false)
        .flexible(true)
        .trim(csv::Trim::All)
        .comment(Some(b'#'))
        .from_path(path)
        .map_err(|e| AnalysisError::csv(path, e))?;
    let mut weights = vec![1.0; num_vertices];
    let mut seen = vec![false; num_vertices];
    let mut rows = 0;
    for (k, record) in reader.records().enumerate() {
        let record = record.map_err(|e| AnalysisError::csv(path, e))?;
        let line = record.position().map_or(0, |p| p.line());
        if record.len() != 2 {
            return Err(AnalysisError::parse(
                path,
                line,
                format!("expected 2 fields `vertex,weight`, got {}", record.len()),
            ));
        }
        let is_number = record[0].parse::<f64>().is_ok() || record[1].parse::<f64>().is_ok();
        if k == 0 && !is_number {
            if record[0].eq_ignore_ascii_case("vertex") && record[1].eq_ignore_ascii_case("weight") {
                continue;
            }
            return Err(AnalysisError::parse(
                path,
                line,
                format!(
                    "expected the header `vertex,weight` or a row of numbers, got `{},{}`",
                    &record[0], &record[1]
                ),
            ));
        }
        let v: usize = record[0]
            .parse()
            .map_err(|_| AnalysisError::parse(path, line, format!("`{}` is not a vertex index", &record[0])))?;
        let w: f64 = record[1]
            .parse()
            .map_err(|_| AnalysisError::parse(path, line, format!("`{}` is not a number", &record[1])))?;
        if v >= num_vertices {
            return Err(AnalysisError::parse(
                path,
                line,
                format!("vertex {v} out of range (the mesh has {num_vertices} vertices)"),
            ));
        }
        if !(w.is_finite() && w > 0.0) {
            return Err(AnalysisError::parse(
                path,
                line,
                format!("weight {w} of vertex {v} must be finite and > 0"),
            ));
        }
        if seen[v] {
            return Err(AnalysisError::parse(path, line, format!("vertex {v} listed twice")));
        }
        seen[v] = true;
        weights[v] = w;
        rows += 1;
    }
    if rows == 0 {
        return Err(AnalysisError::parse(
            path,
            0,
            "no `vertex,weight` row (an empty weights file is likely a mistake; omit --weights for none)",
        ));
    }
    Ok(weights)
}

/// Per-vertex weights (#V): `factor` on the vertices of `region`, 1 elsewhere. Errors on an
/// index out of range or a factor that is not finite and > 0.
pub fn region_weights(num_vertices: usize, region: &[u32], factor: f64) -> Result<Vec<f64>, AnalysisError> {
    if !(factor.is_finite() && factor > 0.0) {
        return Err(AnalysisError::InvalidInput(format!(
            "weight factor {factor} must be finite and > 0"
        )));
    }
    let mut w = vec![1.0; num_vertices];
    for &v in region {
        let slot = w.get_mut(v as usize).ok_or_else(|| {
            AnalysisError::InvalidInput(format!("region vertex {v} out of range (#V = {num_vertices})"))
        })?;
        *slot = factor;
    }
    Ok(w)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn disk_polygon_has_area_pi_and_stays_near_the_circle() {
        for k in [3usize, 16, 64, 1024, 5000] {
            let p = domain_polygon(Domain::Disk, k).unwrap();
            let area: f64 = (0..k)
                .map(|j| {
                    let (a, b) = (p[j], p[(j + 1) % k]);
                    0.5 * (a[0] * b[1] - a[1] * b[0])
                })
                .sum();
            assert!((area - std::f64::consts::PI).abs() < 1e-13, "k={k}: {area}");
            let rho = p[0][0];
            let inner = rho * (std::f64::consts::PI / k as f64).cos();
            let dev = (rho - 1.0).max(1.0 - inner);
            let bound = std::f64::consts::PI.powi(2) / (3.0 * (k * k) as f64);
            // π²/(3K²) is the leading term: within 1% from K = 64 on
            if k >= 64 {
                assert!(dev <= bound * 1.01, "k={k}: deviation {dev} > {bound}");
            }
        }
        let sq = domain_polygon(Domain::Square, 4).unwrap();
        let side = sq[1][0] - sq[0][0];
        assert!((side * side - std::f64::consts::PI).abs() < 1e-14);
        assert!(domain_polygon(Domain::Disk, 2).is_err());
    }

    #[test]
    fn graded_disk_measure_covers_the_polygon_with_fat_triangles() {
        for k in [17usize, 64, 1000, 1024, 4096] {
            let p = domain_polygon(Domain::Disk, k).unwrap();
            let m = domain_measure(Domain::Disk, &p).unwrap(); // checks counter-clockwise triangles
            assert!(
                (m.total_mass() - std::f64::consts::PI).abs() < 1e-12,
                "k={k}: {}",
                m.total_mass()
            );
            assert!(
                m.triangles.len() <= 3 * k + 16,
                "k={k}: {} triangles",
                m.triangles.len()
            );
            // the boundary edges of the triangulation are exactly the K-gon's edges: every
            // directed polygon edge appears in exactly one triangle
            let mut found = 0;
            for t in &m.triangles {
                for e in 0..3 {
                    let (a, b) = (t[e] as usize, t[(e + 1) % 3] as usize);
                    if a < k && b == (a + 1) % k {
                        found += 1;
                    }
                }
            }
            assert_eq!(found, k);
        }
    }

    #[test]
    fn projection_is_radial_onto_the_boundary() {
        let p = project_to_boundary(Domain::Disk, [0.3, -0.4]);
        assert!((p[0] - 0.6).abs() < 1e-15 && (p[1] + 0.8).abs() < 1e-15);
        let a = 0.5 * std::f64::consts::PI.sqrt();
        let q = project_to_boundary(Domain::Square, [0.2, 0.1]);
        assert!((q[0] - a).abs() < 1e-15 && (q[1] - a / 2.0).abs() < 1e-15);
    }

    #[test]
    fn weights_renormalize_to_pi() {
        let thirds = [1.0, 2.0, 3.0];
        let nu = weighted_target_masses(&thirds, Some(&[2.0, 1.0, 1.0])).unwrap();
        // raw 2, 2, 3 → total 7
        let pi = std::f64::consts::PI;
        assert!((nu[0] - 2.0 * pi / 7.0).abs() < 1e-15 && (nu[2] - 3.0 * pi / 7.0).abs() < 1e-15);
        assert!(weighted_target_masses(&thirds, Some(&[1.0, 0.0, 1.0])).is_err());
        assert!(weighted_target_masses(&thirds, Some(&[1.0])).is_err());
        assert!(weighted_target_masses(&[1.0, 0.0], None).is_err());
        assert_eq!(region_weights(3, &[2], 5.0).unwrap(), vec![1.0, 1.0, 5.0]);
        // weights as large as f64 allows: uniform ones change nothing (their sum overflowed to
        // inf, and the masses to NaN, before the weights were scaled by the largest), and one at
        // 1e300 beside ones leaves the others 1e-300 of it
        let thirds = [0.5, 0.25, 0.25, 1.0];
        assert_eq!(
            weighted_target_masses(&thirds, Some(&[1e308; 4])).unwrap(),
            weighted_target_masses(&thirds, None).unwrap()
        );
        let top = weighted_target_masses(&thirds, Some(&[1.0, 1.0, 1.0, 1e300])).unwrap();
        assert!(top.iter().all(|m| m.is_normal()), "{top:?}");
        assert!((top[3] - std::f64::consts::PI).abs() < 1e-15 && (top[0] / top[1] - 2.0).abs() < 1e-15);
        // a range too wide for f64 masses is an error naming the vertex, not an infinite mass
        let e = weighted_target_masses(&thirds, Some(&[1.0, 1.0, 1.0, f64::MAX])).unwrap_err();
        assert!(e.to_string().contains("vertex 0"), "{e}");
        assert!(region_weights(3, &[3], 5.0).is_err());
    }

    #[test]
    fn domain_parses() {
        assert_eq!("Disk".parse::<Domain>().unwrap(), Domain::Disk);
        assert_eq!("square".parse::<Domain>().unwrap(), Domain::Square);
        assert!("circle".parse::<Domain>().is_err());
    }

    #[test]
    fn longest_increasing_subsequence() {
        assert_eq!(longest_increasing(&[1.0, 2.0, 3.0]), vec![0, 1, 2]);
        assert_eq!(longest_increasing(&[1.0, 3.0, 2.0, 4.0]).len(), 3);
        assert_eq!(longest_increasing(&[0.0, 5.0, 1.0, 2.0, 3.0, 4.0]), vec![0, 2, 3, 4, 5]);
        // strictly increasing: ties are not kept together
        assert_eq!(longest_increasing(&[1.0, 1.0, 1.0]).len(), 1);
        assert!(longest_increasing(&[]).is_empty());
    }

    /// The unit disk mesh with its boundary images on the circle at their own angles, then two
    /// neighbours swapped (the case of TOSCA centaur0 slit twice): `order_boundary` moves one
    /// of them, between its neighbours, and the order is restored; an ordered boundary, and a
    /// boundary that winds twice, are left as they are.
    #[test]
    fn order_boundary_restores_a_swapped_pair() {
        let mesh = shapespace_geometry::primitives::unit_disk(6);
        let conn = Connectivity::of(&mesh);
        let lp = conn.boundary_loops(&mesh.faces).remove(0);
        let base: Vec<[f64; 2]> = mesh.positions.iter().map(|p| [p[0], p[1]]).collect();
        for domain in [Domain::Disk, Domain::Square] {
            let mut uv = base.clone();
            for &v in &lp {
                uv[v as usize] = project_to_boundary(domain, uv[v as usize]);
            }
            let ordered = uv.clone();
            assert_eq!(boundary_order_violations(&mesh, &uv), 0);
            assert_eq!(order_boundary(&mesh, domain, &mut uv), 0);
            assert_eq!(uv, ordered);
            let (a, b) = (lp[5] as usize, lp[6] as usize);
            uv.swap(a, b);
            assert!(boundary_order_violations(&mesh, &uv) > 0);
            assert_eq!(order_boundary(&mesh, domain, &mut uv), 1, "{domain:?}");
            assert_eq!(boundary_order_violations(&mesh, &uv), 0, "{domain:?}");
            let angle = |p: [f64; 2]| p[1].atan2(p[0]);
            let (before, after) = (angle(uv[lp[4] as usize]), angle(uv[lp[7] as usize]));
            for v in [a, b] {
                let t = angle(uv[v]);
                assert!(before < t && t < after, "{domain:?}: {before} < {t} < {after}");
                let on = project_to_boundary(domain, uv[v]);
                assert!((on[0] - uv[v][0]).abs() < 1e-15 && (on[1] - uv[v][1]).abs() < 1e-15);
            }
            // only one of the pair moved; every other vertex is where it was
            let moved = (0..uv.len()).filter(|&v| uv[v] != ordered[v]).count();
            assert!(moved <= 2, "{moved}");
        }
        // A boundary that folds back on itself (a Z, still winding once): read from after its
        // largest gap, the longest increasing run of unwrapped angles would span more than a
        // turn and spread the rest backwards; kept below a turn, the order comes out right.
        {
            let n = lp.len();
            // the largest gap is 0.7 → 1.5 (the steps below are shorter), the Z goes back to
            // 0.5, and the loop closes at 2π + 0.7: the increasing run 0.5 … 2π + 0.7 spans
            // 2π + 0.2
            let mut theta = vec![0.7, 1.5, 1.6, 1.2, 0.8, 0.5];
            let step = (std::f64::consts::TAU + 0.2) / (n - 5) as f64;
            assert!(step < 0.8);
            while theta.len() < n {
                let t = theta[theta.len() - 1] + step;
                theta.push(t);
            }
            let mut uv = base.clone();
            for (k, &v) in lp.iter().enumerate() {
                uv[v as usize] = [theta[k].cos(), theta[k].sin()];
            }
            assert!(boundary_order_violations(&mesh, &uv) > 0);
            assert!(order_boundary(&mesh, Domain::Disk, &mut uv) > 0);
            assert_eq!(boundary_order_violations(&mesh, &uv), 0);
        }
        // twice around: nothing local can order it
        let mut uv = base.clone();
        for &v in &lp {
            let t = 2.0 * uv[v as usize][1].atan2(uv[v as usize][0]);
            uv[v as usize] = [t.cos(), t.sin()];
        }
        let twice = uv.clone();
        assert_eq!(order_boundary(&mesh, Domain::Disk, &mut uv), 0);
        assert_eq!(uv, twice);
    }
}
