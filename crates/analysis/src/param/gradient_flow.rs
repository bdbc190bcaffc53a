//! Area-preserving disk parameterization by the gradient flow of the Monge–Kantorovich
//! functional [Angenent, Haker & Tannenbaum 2003, "Minimizing flows for the
//! Monge–Kantorovich problem", SIAM J. Math. Anal. 35(1)], as used for texture mapping by
//! [Dominitz & Tannenbaum 2010, "Texture mapping via optimal mass transport", IEEE TVCG 16(3)]:
//! start from the conformal map, correct its area with a first mass-preserving map, then flow
//! that map, among mass-preserving maps, down the transport cost to the L²-optimal one.
//!
//! The surface (scaled to the area of its image) pushed forward by the conformal disk map has
//! the density $\mu_0$ on its image $\Omega_0$; the target density is $\mu_1 = 1$ on the disk.
//! A map $u$ is mass-preserving when $\mu_0 = \det(Du)$. Every other one is $u \circ s^{-1}$
//! with $s$ a $\mu_0$-preserving rearrangement of $\Omega_0$, the flow of a field $\zeta/\mu_0$
//! with $\operatorname{div}\zeta = 0$ and $\zeta\cdot n = 0$ on $\partial\Omega_0$. The cost
//! $M(u) = \int |u(x) - x|^2 \mu_0(x)\,dx$ then changes at the rate $-2\int u\cdot\zeta\,dx$,
//! steepest for $\zeta$ the divergence-free part of $u$ (Helmholtz), which in the plane is
//! $\zeta = \nabla^\perp h$, $\nabla^\perp = (-\partial_y, \partial_x)$, with
//!
//! $$\Delta h = \operatorname{curl} u = -\operatorname{div}(u^\perp), \qquad h = 0 \text{ on }
//!   \partial\Omega_0, \qquad u_t = -\frac{1}{\mu_0}\,Du\,\zeta
//!   = \frac{1}{\mu_0}\,Du\,\nabla^\perp\Delta^{-1}\operatorname{div}(u^\perp)$$
//!
//! (AHT's Eq. for the planar case; the Dirichlet condition makes $\zeta$ tangent to the rim).
//! $M$ decreases at the rate $-2\|\zeta\|^2$; the flow stops at a curl-free $u$, the gradient
//! of a convex function (Brenier): the optimal map.
//!
//! # Discrete form
//! The domain is the conformal image (the mesh at its conformal positions $x_i$, fixed); the map
//! is piecewise linear, one image point $u_i$ per vertex; $\mu_0(f) = a_f/|f_0|$ per face.
//! 1. **First mass-preserving map**: the Moser flow of [`crate::lie_advection`] (with its fold
//!    repair and correction), then the mass projection below.
//! 2. **Curl part**: one P1 finite-element Dirichlet problem on $\Omega_0$ per step,
//!    $K h = b$ with $K$ the cotangent stiffness matrix of the $x_i$ on the interior vertices
//!    (factored once by faer's sparse Cholesky; the domain does not move) and
//!    $b_i = \int (u_2\,\partial_x\lambda_i - u_1\,\partial_y\lambda_i)$ (the weak form of
//!    $\Delta h = \operatorname{curl} u$, $u$ integrated exactly per face);
//!    $\zeta_f = \nabla^\perp h|_f$.
//! 3. **Step**: $u_t = -Du\,V$ transports $u$ along $V = \zeta/\mu_0$, so the step is
//!    semi-Lagrangian, $u^{new}_i = u(x_i - \delta t\,V_i)$, with the vertex field
//!    $V_i = \sum_{f\ni i}|f_0|\,\zeta_f / \sum_{f\ni i} a_f$ (tangential on the rim) and $u$
//!    interpolated linearly in the face of $\Omega_0$ holding the point
//!    ([`crate::point_location`]); rim images are put back on the circle. $\delta t$ is at most
//!    `max_time_step`, moves no vertex's foot point more than `cfl` times its shortest edge in
//!    $\Omega_0$, changes no foot triangle's area by more than 10 %, and is halved while the
//!    new map folds a face.
//! 4. **Mass projection**: interpolation does not keep the face areas exactly, so after each
//!    step `projection_iterations` linearized Moser corrections on the current image
//!    (a Neumann problem with the face-area errors as sources, as in the Lie correction) pull
//!    the map back to the mass-preserving ones; a correction is kept only when it folds no face
//!    and lowers the area-weighted rms of $\ln(|u(f)|/a_f)$. At the end up to
//!    `final_projection_iterations` more.
//!
//! The flow stops when $\|\zeta\|/\|u\|$ (L² norms on $\Omega_0$) falls below `tolerance`,
//! after `max_steps` steps, or when a step halved below [`MIN_TIME_STEP`] × `max_time_step`
//! still folds. On real meshes started from the Lie map the last happens within a few steps: a
//! face beside the few that the Lie map's fold repair leaves 40–60 times their area collapses
//! at any step size (docs/benchmarks.md, decision 0044).
//!
//! # Multiresolution
//! Dominitz & Tannenbaum accelerate the flow by a multiresolution scheme (spherical wavelets on
//! their sphere). [`gradient_flow_map`] runs it by default (`multiresolution_levels` 2,
//! [`crate::multiresolution`]): the flow on coarse ring-layout disks carrying the restricted
//! surface area, each result prolonged to the next level and Moser-corrected, and the flow on
//! the mesh from the prolonged map in place of step 1's Lie map (the correction's folds
//! repaired as the Lie map's are). When the prolonged map keeps folds after the fold repair or
//! its Moser correction fails the Lie map is the start, as with
//! `multiresolution_levels` 0 (and only if that one keeps folds, the uncorrected prolonged map).

use std::time::Instant;

use faer::linalg::solvers::Solve;
use faer::sparse::linalg::solvers::{Llt, Lu, SymbolicLlt};
use faer::sparse::{SparseColMat, Triplet};
use rayon::prelude::*;
use serde::Serialize;
use shapespace_conformal::{disk_map, DiskMap, Markers};
use shapespace_geometry::quantities::face_areas;
use shapespace_geometry::{Connectivity, TriMesh};

use crate::error::AnalysisError;
use crate::fold_repair::repair_folds_with;
use crate::lie_advection::{
    acceptable, face_gradient, face_is_ccw, lie_advection_map, moved, signed_area, tangential, vertex_velocities,
    LieAdvectionInfo, LieAdvectionParams, PlanarPoisson,
};
use crate::multiresolution::{corrected_start, disk_moser_correction, disk_multiresolution_start, MultiresolutionInfo};
use crate::point_location::PointLocator;

/// Parameters of [`gradient_flow_map`] (module docs).
#[derive(Clone, Debug)]
pub struct GradientFlowParams {
    /// The first mass-preserving map (the Lie-advection map; its `disk_map` is the conformal
    /// map the method starts from).
    pub start: LieAdvectionParams,
    /// Most flow steps (default 200).
    pub max_steps: usize,
    /// The flow stops when the relative L² norm of the curl part, ‖ζ‖/‖u‖, is below this
    /// (default 1e-3).
    pub tolerance: f64,
    /// Largest foot-point displacement of a step, in shortest edges of the vertex on the
    /// conformal image (default 2).
    pub cfl: f64,
    /// Longest step in flow time (default 0.25; the curl part of a rotation of the uniform
    /// disk decays at rate 1, and longer steps overshoot).
    pub max_time_step: f64,
    /// Mass projections after each step (default 1).
    pub projection_iterations: usize,
    /// Most mass projections at the start and at the end (default 10).
    pub final_projection_iterations: usize,
    /// Coarse levels of Dominitz & Tannenbaum's multiresolution scheme run before the flow on
    /// the mesh ([`crate::multiresolution`]; default 2; 0: the single-level flow from the Lie
    /// map). Used by [`gradient_flow_map`]; [`flow`] itself is one level.
    pub multiresolution_levels: usize,
}

impl Default for GradientFlowParams {
    fn default() -> Self {
        GradientFlowParams {
            start: LieAdvectionParams::default(),
            max_steps: 200,
            tolerance: 1e-3,
            cfl: 2.0,
            max_time_step: 0.25,
            projection_iterations: 1,
            final_projection_iterations: 10,
            multiresolution_levels: 2,
        }
    }
}

/// What the flow did (the part of [`GradientFlowInfo`] that [`flow`] reports).
#[derive(Clone, Debug, Default, PartialEq, Serialize)]
pub struct FlowInfo {
    /// Accepted flow steps.
    pub steps: usize,
    /// Steps halved because the new map folded a face.
    pub halvings: usize,
    /// Flow time reached (the sum of the accepted steps).
    pub time: f64,
    /// Dirichlet solves (one per step and one for the final curl norm).
    pub dirichlet_solves: usize,
    /// Neumann solves of the mass projections.
    pub projection_solves: usize,
    /// Mass projections kept.
    pub projections_kept: usize,
    /// Neumann solves done by LU after a Cholesky failed in floating point.
    pub lu_fallbacks: usize,
    /// ‖ζ‖/‖u‖ of the start (after its mass projection) and of the result.
    pub start_curl: f64,
    /// See `start_curl`.
    pub final_curl: f64,
    /// Transport cost ∫|u − x|² μ0 of the start and of the result (units of the disk's area).
    pub start_cost: f64,
    /// See `start_cost`.
    pub final_cost: f64,
    /// Largest |ln(|u(f)| / a_f)| over the faces (areas scaled to the same total), start and result.
    pub start_max_area_error: f64,
    /// See `start_max_area_error`.
    pub final_max_area_error: f64,
    /// Why the flow stopped.
    pub stop: String,
}

/// What [`gradient_flow_map`] did.
#[derive(Clone, Debug, Default, PartialEq, Serialize)]
pub struct GradientFlowInfo {
    /// The first mass-preserving map (Lie advection; all zero when the flow on the mesh
    /// started from the multiresolution levels).
    pub start: LieAdvectionInfo,
    /// The coarse levels of the multiresolution scheme, or why the flow did not use them.
    pub multiresolution: MultiresolutionInfo,
    /// The flow.
    pub flow: FlowInfo,
}

/// Wall-clock seconds of [`gradient_flow_map`].
#[derive(Clone, Debug, Default, PartialEq, Serialize)]
pub struct GradientFlowTimings {
    /// The conformal disk map.
    pub conformal: f64,
    /// The first mass-preserving map (Lie advection, repair and correction), or the coarse
    /// levels of the multiresolution scheme (with a fallback to the Lie map: both).
    pub start: f64,
    /// The flow on the mesh with its projections.
    pub flow: f64,
    /// Everything.
    pub total: f64,
}

/// The map of [`gradient_flow_map`].
#[derive(Clone, Debug)]
pub struct GradientFlowMap {
    /// Image of each vertex in the unit disk, #V (rim vertices on |z| = 1).
    pub uv: Vec<[f64; 2]>,
    /// The map the flow on the mesh started from (the prolonged coarse map, or the Lie map), #V.
    pub start_uv: Vec<[f64; 2]>,
    /// The conformal map.
    pub conformal: DiskMap,
    /// Steps and solves.
    pub info: GradientFlowInfo,
    /// Timings.
    pub timings: GradientFlowTimings,
}

/// The OMT map of a disk-type `mesh` onto the unit disk by the Angenent–Haker–Tannenbaum
/// gradient flow (module docs; Dominitz & Tannenbaum 2010): the conformal map, the Lie-advection
/// map as the first mass-preserving map, and the flow toward the L²-optimal one.
///
/// Errors: those of [`lie_advection_map`]; [`AnalysisError::FlowStartFolded`] when its fold
/// repair failed; [`AnalysisError::InvalidInput`] for bad parameters or a failed Poisson solve.
pub fn gradient_flow_map(
    mesh: &TriMesh,
    markers: &Markers,
    params: &GradientFlowParams,
) -> Result<GradientFlowMap, AnalysisError> {
    check_params(params)?;
    let t0 = Instant::now();
    let secs = |a: Instant, b: Instant| (b - a).as_secs_f64();
    let conn = Connectivity::of(mesh);
    let is_boundary = conn.boundary_vertices(mesh.num_vertices());
    let areas = face_areas(mesh);
    let mut multiresolution = MultiresolutionInfo::default();
    // the unfolded prolonged map whose Moser correction failed, with its conformal map
    let mut uncorrected: Option<Vec<[f64; 2]>> = None;
    let mut multiresolution_conformal: Option<DiskMap> = None;
    if params.multiresolution_levels > 0 {
        let conformal = disk_map(mesh, markers, &params.start.disk_map).map_err(AnalysisError::DiskMap)?;
        let t1 = Instant::now();
        let start = disk_multiresolution_start(
            &mesh.faces,
            &areas,
            &is_boundary,
            &conformal.uv,
            params.multiresolution_levels,
            params,
            &mut multiresolution,
        )
        .and_then(|mut start| {
            if multiresolution.prolonged_folds > 0 {
                // (a failed repair leaves folds, counted below)
                let _ = repair_folds_with(mesh, Some(&conn), &is_boundary, &mut start, &params.start.fold_repair);
                multiresolution.prolonged_folds_after_repair =
                    mesh.faces.iter().filter(|f| !face_is_ccw(&start, f)).count();
            }
            corrected_start(
                multiresolution.prolonged_folds_after_repair,
                || disk_moser_correction(mesh, Some(&conn), &areas, &is_boundary, start, &params.start),
                &mut multiresolution,
                &mut uncorrected,
                "the prolonged coarse map keeps them after the fold repair",
            )
        });
        match start {
            Ok(start) => {
                let t2 = Instant::now();
                let (uv, flow_info) = flow(&mesh.faces, &areas, &is_boundary, &conformal.uv, &start, params)?;
                let t3 = Instant::now();
                return Ok(GradientFlowMap {
                    uv,
                    start_uv: start,
                    timings: GradientFlowTimings {
                        conformal: secs(t0, t1),
                        start: secs(t1, t2),
                        flow: secs(t2, t3),
                        total: secs(t0, t3),
                    },
                    conformal,
                    info: GradientFlowInfo {
                        start: LieAdvectionInfo::default(),
                        multiresolution,
                        flow: flow_info,
                    },
                });
            }
            Err(e) => {
                multiresolution.fallback = Some(e.to_string());
                multiresolution_conformal = Some(conformal);
            }
        }
    }
    let lie = lie_advection_map(mesh, markers, &params.start)?;
    if let Some(reason) = &lie.info.fold_repair_error {
        if let (Some(start), Some(conformal)) = (uncorrected, multiresolution_conformal) {
            // the Lie map folds: the flow starts from the unfolded, uncorrected prolonged map
            let t1 = Instant::now();
            multiresolution.uncorrected_start = true;
            let (uv, flow_info) = flow(&mesh.faces, &areas, &is_boundary, &conformal.uv, &start, params)?;
            let t2 = Instant::now();
            return Ok(GradientFlowMap {
                uv,
                start_uv: start,
                timings: GradientFlowTimings {
                    conformal: lie.timings.conformal,
                    start: secs(t0, t1) - lie.timings.conformal,
                    flow: secs(t1, t2),
                    total: secs(t0, t2),
                },
                conformal,
                info: GradientFlowInfo {
                    start: lie.info,
                    multiresolution,
                    flow: flow_info,
                },
            });
        }
        let folded = mesh.faces.iter().filter(|f| !face_is_ccw(&lie.uv, f)).count();
        return Err(AnalysisError::FlowStartFolded {
            folded,
            reason: reason.clone(),
        });
    }
    let t1 = Instant::now();
    let (uv, flow_info) = flow(&mesh.faces, &areas, &is_boundary, &lie.conformal.uv, &lie.uv, params)?;
    let t2 = Instant::now();
    Ok(GradientFlowMap {
        uv,
        start_uv: lie.uv,
        timings: GradientFlowTimings {
            conformal: lie.timings.conformal,
            start: secs(t0, t1) - lie.timings.conformal,
            flow: secs(t1, t2),
            total: secs(t0, t2),
        },
        conformal: lie.conformal,
        info: GradientFlowInfo {
            start: lie.info,
            multiresolution,
            flow: flow_info,
        },
    })
}

fn check_params(params: &GradientFlowParams) -> Result<(), AnalysisError> {
    params.control().check()
}

/// The gradient flow (module docs, steps 2–4) on the domain triangulation `domain` (#V,
/// counter-clockwise faces, rim vertices on the unit circle where `is_boundary`) with the
/// density `surface_areas / domain areas` (#F, any common scale), from the map `start` (#V,
/// counter-clockwise, rim on the unit circle). Returns the end map.
///
/// Errors: [`AnalysisError::InvalidInput`] for bad parameters, lengths, a zero-area face, a
/// folded domain or start, no interior vertex, or a failed solve.
pub fn flow(
    faces: &[[u32; 3]],
    surface_areas: &[f64],
    is_boundary: &[bool],
    domain: &[[f64; 2]],
    start: &[[f64; 2]],
    params: &GradientFlowParams,
) -> Result<(Vec<[f64; 2]>, FlowInfo), AnalysisError> {
    check_params(params)?;
    let n = domain.len();
    if start.len() != n || is_boundary.len() != n || surface_areas.len() != faces.len() {
        return Err(AnalysisError::InvalidInput(format!(
            "gradient flow: {n} domain points, {} start points, {} rim flags, {} faces, {} face areas",
            start.len(),
            is_boundary.len(),
            faces.len(),
            surface_areas.len()
        )));
    }
    if let Some(f) = surface_areas.iter().position(|a| !(a.is_finite() && *a > 0.0)) {
        return Err(AnalysisError::InvalidInput(format!(
            "face {f} has surface area {} (must be finite and > 0)",
            surface_areas[f]
        )));
    }
    if let Some(f) = faces.iter().position(|f| !face_is_ccw(domain, f)) {
        return Err(AnalysisError::InvalidInput(format!(
            "face {f} of the conformal image is folded or degenerate"
        )));
    }
    if let Some(f) = faces.iter().position(|f| !face_is_ccw(start, f)) {
        return Err(AnalysisError::InvalidInput(format!(
            "face {f} of the starting map is folded or degenerate"
        )));
    }
    let domain_areas: Vec<f64> = faces.iter().map(|f| signed_area(domain, f)).collect();
    let scale = domain_areas.iter().sum::<f64>() / surface_areas.iter().sum::<f64>();
    // μ0 |f0| per face and its one-ring sums (the lumped mass of each vertex)
    let masses: Vec<f64> = surface_areas.iter().map(|a| scale * a).collect();
    let mut ring_mass = vec![0.0; n];
    let mut shortest = vec![f64::INFINITY; n];
    for (f, face) in faces.iter().enumerate() {
        for k in 0..3 {
            let (i, j) = (face[k] as usize, face[(k + 1) % 3] as usize);
            let l = (domain[i][0] - domain[j][0]).hypot(domain[i][1] - domain[j][1]);
            shortest[i] = shortest[i].min(l);
            shortest[j] = shortest[j].min(l);
            ring_mass[i] += masses[f];
        }
    }
    let mut disk = DiskFlow {
        curl: CurlPart::new(faces, is_boundary, domain, &domain_areas)?,
        locator: PointLocator::new(domain, faces)?,
        neumann: PlanarPoisson::new(n, faces)?,
        faces,
        surface_areas,
        is_boundary,
        domain,
        domain_areas: &domain_areas,
        masses: &masses,
        ring_mass,
        shortest,
    };
    let mut info = FlowInfo::default();
    let u = run_flow(&mut disk, start.to_vec(), &params.control(), &mut info)?;
    info.lu_fallbacks = disk.neumann.lu_fallbacks;
    Ok((u, info))
}

/// The scalar controls of the flow's time stepping (the fields of [`GradientFlowParams`] but
/// the start; shared by the disk and the sphere).
#[derive(Clone, Debug)]
pub struct FlowControl {
    /// Most flow steps.
    pub max_steps: usize,
    /// Stop when ‖ζ‖/‖u‖ is below this.
    pub tolerance: f64,
    /// Largest foot-point displacement of a step, in shortest edges of the vertex.
    pub cfl: f64,
    /// Longest step in flow time.
    pub max_time_step: f64,
    /// Mass projections after each step.
    pub projection_iterations: usize,
    /// Most mass projections at the start and at the end.
    pub final_projection_iterations: usize,
}

impl Default for FlowControl {
    fn default() -> Self {
        GradientFlowParams::default().control()
    }
}

impl FlowControl {
    /// Errors: a tolerance, step or CFL number that is not finite and positive.
    pub fn check(&self) -> Result<(), AnalysisError> {
        if !(self.tolerance.is_finite() && self.tolerance >= 0.0) {
            return Err(AnalysisError::InvalidInput(format!(
                "gradient flow tolerance {} (must be finite and >= 0)",
                self.tolerance
            )));
        }
        if !(self.max_time_step.is_finite() && self.max_time_step > 0.0) {
            return Err(AnalysisError::InvalidInput(format!(
                "gradient flow max_time_step {} (must be finite and > 0)",
                self.max_time_step
            )));
        }
        if !(self.cfl.is_finite() && self.cfl > 0.0) {
            return Err(AnalysisError::InvalidInput(format!(
                "gradient flow cfl {} (must be finite and > 0)",
                self.cfl
            )));
        }
        Ok(())
    }
}

impl GradientFlowParams {
    /// The time-stepping controls.
    pub fn control(&self) -> FlowControl {
        FlowControl {
            max_steps: self.max_steps,
            tolerance: self.tolerance,
            cfl: self.cfl,
            max_time_step: self.max_time_step,
            projection_iterations: self.projection_iterations,
            final_projection_iterations: self.final_projection_iterations,
        }
    }
}

/// What the flow's time stepping ([`run_flow`]) needs of its domain: the disk's conformal
/// image or the sphere's.
pub(crate) trait FlowDomain {
    /// A point of the map's image.
    type Point: Copy;
    /// The curl part ζ of the map `u`: ‖ζ‖/‖u‖, the vertex field V = ζ/μ0 (#V), and the
    /// longest step ≤ `control.max_time_step` that moves no foot point more than `cfl` shortest
    /// edges and changes no foot triangle's area by more than 10 %.
    fn curl_step(
        &mut self,
        u: &[Self::Point],
        control: &FlowControl,
    ) -> Result<(f64, Vec<Self::Point>, f64), AnalysisError>;
    /// The semi-Lagrangian step: u at the foot points of the field `field` after time `dt`.
    fn backtrack(&self, field: &[Self::Point], u: &[Self::Point], dt: f64) -> Vec<Self::Point>;
    /// Whether no face of `u` is folded.
    fn unfolded(&self, u: &[Self::Point]) -> bool;
    /// Up to `iterations` mass projections of `u` (see [`project`]).
    fn project(
        &mut self,
        u: &mut Vec<Self::Point>,
        iterations: usize,
        info: &mut FlowInfo,
    ) -> Result<(), AnalysisError>;
    /// The transport cost of `u` and its largest face area error.
    fn cost_and_error(&self, u: &[Self::Point]) -> (f64, f64);
}

/// The flow's time stepping (module docs, steps 2–4) on `domain` from `u`: projections, then
/// steps until the curl part's relative norm is below the tolerance, `max_steps` steps or a
/// stall, then the final projections. Shared by the disk and the sphere.
pub(crate) fn run_flow<D: FlowDomain>(
    domain: &mut D,
    mut u: Vec<D::Point>,
    control: &FlowControl,
    info: &mut FlowInfo,
) -> Result<Vec<D::Point>, AnalysisError> {
    domain.project(&mut u, control.final_projection_iterations, info)?;
    (info.start_cost, info.start_max_area_error) = domain.cost_and_error(&u);
    loop {
        let (relative, field, mut dt) = domain.curl_step(&u, control)?;
        info.dirichlet_solves += 1;
        if info.steps == 0 {
            info.start_curl = relative;
        }
        info.final_curl = relative;
        if relative <= control.tolerance {
            info.stop = format!("‖ζ‖/‖u‖ = {relative:.2e} <= {:.1e}", control.tolerance);
            break;
        }
        if info.steps >= control.max_steps {
            info.stop = format!("{} steps (‖ζ‖/‖u‖ = {relative:.2e})", control.max_steps);
            break;
        }
        let mut accepted = None;
        while dt >= MIN_TIME_STEP * control.max_time_step {
            let next = domain.backtrack(&field, &u, dt);
            if domain.unfolded(&next) {
                accepted = Some(next);
                break;
            }
            info.halvings += 1;
            dt *= 0.5;
        }
        let Some(next) = accepted else {
            info.stop = format!("stalled: a step of {dt:.1e} still folds a face");
            break;
        };
        u = next;
        info.time += dt;
        info.steps += 1;
        domain.project(&mut u, control.projection_iterations, info)?;
    }
    domain.project(&mut u, control.final_projection_iterations, info)?;
    (info.final_cost, info.final_max_area_error) = domain.cost_and_error(&u);
    Ok(u)
}

/// The longest step t ≤ `dt` for which the foot triangle's area A0 + b1 t + b2 t² (bounds
/// `b1`, `b2` ≥ 0 of its first and second order terms) changes by at most 10 % of `area`.
pub(crate) fn area_step_limit(b1: f64, b2: f64, area: f64, dt: f64) -> f64 {
    let limit = 0.1 * area;
    if b1 * dt + b2 * dt * dt > limit {
        let t = if b2 > 0.0 {
            (-b1 + (b1 * b1 + 4.0 * b2 * limit).sqrt()) / (2.0 * b2)
        } else {
            limit / b1
        };
        dt.min(t)
    } else {
        dt
    }
}

/// The disk's [`FlowDomain`]: the conformal image with its Dirichlet problem, point location and
/// Neumann problem.
struct DiskFlow<'a> {
    curl: CurlPart,
    locator: PointLocator,
    neumann: PlanarPoisson,
    faces: &'a [[u32; 3]],
    surface_areas: &'a [f64],
    is_boundary: &'a [bool],
    domain: &'a [[f64; 2]],
    domain_areas: &'a [f64],
    masses: &'a [f64],
    /// μ0 |f0| summed over each vertex's faces.
    ring_mass: Vec<f64>,
    /// Each vertex's shortest edge in the domain.
    shortest: Vec<f64>,
}

impl FlowDomain for DiskFlow<'_> {
    type Point = [f64; 2];

    fn curl_step(&mut self, u: &[[f64; 2]], control: &FlowControl) -> Result<(f64, Vec<[f64; 2]>, f64), AnalysisError> {
        let (faces, domain) = (self.faces, self.domain);
        let zeta = self.curl.zeta(u)?;
        let relative = self.curl.relative_norm(&zeta, u);
        // V_i = Σ |f0| ζ_f / Σ μ0 |f0| (tangential on the rim)
        let mut field = vec![[0.0; 2]; domain.len()];
        for (f, face) in faces.iter().enumerate() {
            for &v in face {
                field[v as usize][0] += self.domain_areas[f] * zeta[f][0];
                field[v as usize][1] += self.domain_areas[f] * zeta[f][1];
            }
        }
        let mut dt = control.max_time_step;
        for i in 0..domain.len() {
            let mut v = [field[i][0] / self.ring_mass[i], field[i][1] / self.ring_mass[i]];
            if self.is_boundary[i] {
                v = tangential(domain[i], v);
            }
            field[i] = v;
            let speed = v[0].hypot(v[1]);
            if speed > 0.0 {
                dt = dt.min(control.cfl * self.shortest[i] / speed);
            }
        }
        // no foot triangle changes its area by more than 10 %
        for (face, a) in faces.iter().zip(self.domain_areas) {
            let [p, q, r] = face.map(|v| field[v as usize]);
            let [a0, b0, c0] = face.map(|v| domain[v as usize]);
            // area of the foot triangle x − t V = a + t·b1 + t²·b2
            let cross = |e: [f64; 2], g: [f64; 2]| 0.5 * (e[0] * g[1] - e[1] * g[0]);
            let (e1, e2) = ([b0[0] - a0[0], b0[1] - a0[1]], [c0[0] - a0[0], c0[1] - a0[1]]);
            let (d1, d2) = ([q[0] - p[0], q[1] - p[1]], [r[0] - p[0], r[1] - p[1]]);
            let b1 = (cross(e1, d2) + cross(d1, e2)).abs();
            let b2 = cross(d1, d2).abs();
            dt = area_step_limit(b1, b2, *a, dt);
        }
        Ok((relative, field, dt))
    }

    fn backtrack(&self, field: &[[f64; 2]], u: &[[f64; 2]], dt: f64) -> Vec<[f64; 2]> {
        backtrack(&self.locator, self.faces, self.domain, field, self.is_boundary, u, dt)
    }

    fn unfolded(&self, u: &[[f64; 2]]) -> bool {
        self.faces.iter().all(|f| face_is_ccw(u, f))
    }

    fn project(&mut self, u: &mut Vec<[f64; 2]>, iterations: usize, info: &mut FlowInfo) -> Result<(), AnalysisError> {
        project(
            &mut self.neumann,
            self.faces,
            self.surface_areas,
            self.is_boundary,
            u,
            iterations,
            info,
        )
    }

    fn cost_and_error(&self, u: &[[f64; 2]]) -> (f64, f64) {
        (
            transport_cost(self.faces, self.masses, self.domain, u),
            area_errors(self.faces, self.surface_areas, u).0,
        )
    }
}

/// The semi-Lagrangian step: u at the foot points x_i − dt V_i (linear in the domain face
/// holding them; points outside snap to the nearest rim face), rim images on the circle.
fn backtrack(
    locator: &PointLocator,
    faces: &[[u32; 3]],
    domain: &[[f64; 2]],
    field: &[[f64; 2]],
    is_boundary: &[bool],
    u: &[[f64; 2]],
    dt: f64,
) -> Vec<[f64; 2]> {
    (0..domain.len())
        .into_par_iter()
        .map(|i| {
            let foot = [domain[i][0] - dt * field[i][0], domain[i][1] - dt * field[i][1]];
            let Some(loc) = locator.locate(foot) else {
                return u[i];
            };
            let f = faces[loc.face as usize];
            let mut p = [0.0; 2];
            for k in 0..3 {
                p[0] += loc.bary[k] * u[f[k] as usize][0];
                p[1] += loc.bary[k] * u[f[k] as usize][1];
            }
            if is_boundary[i] {
                let r = p[0].hypot(p[1]);
                if r > 0.0 {
                    p = [p[0] / r, p[1] / r];
                }
            }
            p
        })
        .collect()
}

/// Up to `iterations` linearized Moser corrections of `u` toward the face areas `surface_areas`
/// (scaled to u's total), each kept only when it folds no face, changes no face's area more than
/// twofold and lowers the area-weighted rms log area error (halved up to 8 times before giving
/// up).
fn project(
    poisson: &mut PlanarPoisson,
    faces: &[[u32; 3]],
    surface_areas: &[f64],
    is_boundary: &[bool],
    u: &mut Vec<[f64; 2]>,
    iterations: usize,
    info: &mut FlowInfo,
) -> Result<(), AnalysisError> {
    let image_areas = |x: &[[f64; 2]]| faces.iter().map(|f| signed_area(x, f)).collect::<Vec<f64>>();
    mass_projection(
        u,
        iterations,
        info,
        |x: &[[f64; 2]]| vertex_area_rms(faces, surface_areas, x),
        |x: &[[f64; 2]]| {
            let image = image_areas(x);
            let (rhs, scale) = moser_sources(faces, surface_areas, &image, x.len(), 1.0);
            let potential = poisson.solve(x, &rhs)?;
            let velocity = vertex_velocities(x, faces, &potential, &image, scale, surface_areas, is_boundary);
            Ok(velocity
                .iter()
                .all(|v| v[0].is_finite() && v[1].is_finite())
                .then_some(velocity))
        },
        |x: &[[f64; 2]], v: &[[f64; 2]], h| moved(x, v, h, is_boundary),
        |x: &[[f64; 2]], next: &[[f64; 2]]| acceptable(faces, x, next),
    )
}

/// The right side of the linearized Moser correction toward the face areas `surface_areas`
/// (scaled to the image's total `Σ image`): b_i = −factor Σ_{f∋i} (scale a_f − |f|)/3, which
/// sums to 0; and the scale. Shared by the disk and the sphere.
pub(crate) fn moser_sources(
    faces: &[[u32; 3]],
    surface_areas: &[f64],
    image: &[f64],
    n: usize,
    factor: f64,
) -> (Vec<f64>, f64) {
    let scale = image.iter().sum::<f64>() / surface_areas.iter().sum::<f64>();
    let mut rhs = vec![0.0; n];
    for (f, face) in faces.iter().enumerate() {
        let r = -factor * (scale * surface_areas[f] - image[f]) / 3.0;
        for &v in face {
            rhs[v as usize] += r;
        }
    }
    (rhs, scale)
}

/// The mass projection's iterations, shared by the disk and the sphere: up to `iterations`
/// times, `velocity(u)` (one Poisson solve; `None` when not finite) and the largest step
/// h = 1, ½, … ([`PROJECTION_HALVINGS`] tries) whose `moved(u, v, h)` is `acceptable` and
/// lowers `rms`; stops at the first iteration that keeps nothing.
pub(crate) fn mass_projection<P: Clone>(
    u: &mut Vec<P>,
    iterations: usize,
    info: &mut FlowInfo,
    rms: impl Fn(&[P]) -> f64,
    mut velocity: impl FnMut(&[P]) -> Result<Option<Vec<P>>, AnalysisError>,
    moved: impl Fn(&[P], &[P], f64) -> Vec<P>,
    acceptable: impl Fn(&[P], &[P]) -> bool,
) -> Result<(), AnalysisError> {
    for _ in 0..iterations {
        let before = rms(u);
        let v = velocity(u)?;
        info.projection_solves += 1;
        let Some(v) = v else {
            return Ok(());
        };
        let mut h = 1.0;
        let mut kept = false;
        for _ in 0..PROJECTION_HALVINGS {
            let next = moved(u, &v, h);
            if acceptable(u, &next) && rms(&next) < before {
                *u = next;
                kept = true;
                break;
            }
            h *= 0.5;
        }
        if !kept {
            return Ok(());
        }
        info.projections_kept += 1;
    }
    Ok(())
}

/// Smallest flow step, relative to `max_time_step`: a step halved below it (the new map still
/// folds a face) stops the flow.
pub const MIN_TIME_STEP: f64 = 1e-6;

/// Most halvings of one mass projection's step.
pub const PROJECTION_HALVINGS: usize = 20;

/// Area-weighted rms over the vertices of ε_i = ln(Σ_{f∋i} |u(f)| / Σ_{f∋i} a_f), the surface
/// areas `a_f` scaled to u's total: the one-ring area error that the mass projection lowers.
pub fn vertex_area_rms(faces: &[[u32; 3]], surface_areas: &[f64], u: &[[f64; 2]]) -> f64 {
    let image: Vec<f64> = faces.iter().map(|f| signed_area(u, f)).collect();
    vertex_area_rms_of(faces, surface_areas, &image, u.len())
}

/// [`vertex_area_rms`] from the image's face areas `image` (#F) of a map of `n` vertices.
pub(crate) fn vertex_area_rms_of(faces: &[[u32; 3]], surface_areas: &[f64], image: &[f64], n: usize) -> f64 {
    let total: f64 = surface_areas.iter().sum();
    let scale = image.iter().sum::<f64>() / total;
    let (mut ring_image, mut ring_surface) = (vec![0.0; n], vec![0.0; n]);
    for ((f, i), a) in faces.iter().zip(image).zip(surface_areas) {
        for &v in f {
            ring_image[v as usize] += i;
            ring_surface[v as usize] += scale * a;
        }
    }
    let sum: f64 = ring_image
        .iter()
        .zip(&ring_surface)
        .filter(|(_, s)| **s > 0.0)
        .map(|(i, s)| {
            let e = if *i > 0.0 { (i / s).ln() } else { f64::INFINITY };
            s * e * e
        })
        .sum();
    (sum / (3.0 * scale * total)).sqrt()
}

/// (max, area-weighted rms) of ln(|u(f)| / a_f) with the surface areas `a_f` scaled to u's total.
pub fn area_errors(faces: &[[u32; 3]], surface_areas: &[f64], u: &[[f64; 2]]) -> (f64, f64) {
    let image: Vec<f64> = faces.iter().map(|f| signed_area(u, f)).collect();
    area_errors_of(surface_areas, &image)
}

/// [`area_errors`] from the image's face areas `image` (#F; ≤ 0 for a folded face).
pub(crate) fn area_errors_of(surface_areas: &[f64], image: &[f64]) -> (f64, f64) {
    let total: f64 = surface_areas.iter().sum();
    let scale = image.iter().sum::<f64>() / total;
    let (mut max, mut sum) = (0.0f64, 0.0);
    for (a, i) in surface_areas.iter().zip(image) {
        let e = if *i > 0.0 {
            (i / (scale * a)).ln()
        } else {
            f64::INFINITY
        };
        max = max.max(e.abs());
        sum += a * e * e;
    }
    (max, (sum / total).sqrt())
}

/// ∫|u − x|² μ0 over the domain, u − x linear per face: Σ_f μ0|f0| (Σ_k |d_k|² + |Σ_k d_k|²)/12.
fn transport_cost(faces: &[[u32; 3]], masses: &[f64], domain: &[[f64; 2]], u: &[[f64; 2]]) -> f64 {
    faces
        .iter()
        .zip(masses)
        .map(|(f, m)| {
            let d = f.map(|v| {
                [
                    u[v as usize][0] - domain[v as usize][0],
                    u[v as usize][1] - domain[v as usize][1],
                ]
            });
            let sq: f64 = d.iter().map(|d| d[0] * d[0] + d[1] * d[1]).sum();
            let s = [d[0][0] + d[1][0] + d[2][0], d[0][1] + d[1][1] + d[2][1]];
            m * (sq + s[0] * s[0] + s[1] * s[1]) / 12.0
        })
        .sum()
}

/// The curl part ζ = ∇⊥h, Δh = curl u, h = 0 on the rim (module docs, step 2), on a fixed
/// domain triangulation: the interior stiffness matrix factored once.
pub struct CurlPart {
    faces: Vec<[u32; 3]>,
    domain: Vec<[f64; 2]>,
    domain_areas: Vec<f64>,
    /// Interior index of each vertex (`None` on the rim).
    interior: Vec<Option<usize>>,
    solver: Factor,
}

enum Factor {
    Llt(Llt<usize, f64>),
    Lu(Box<Lu<usize, f64>>),
}

impl CurlPart {
    /// Assembles and factors the Dirichlet stiffness matrix of the counter-clockwise `domain`
    /// (#V) with areas `domain_areas` (#F). Errors: no interior vertex, a failed factorization.
    pub fn new(
        faces: &[[u32; 3]],
        is_boundary: &[bool],
        domain: &[[f64; 2]],
        domain_areas: &[f64],
    ) -> Result<Self, AnalysisError> {
        let mut interior = vec![None; domain.len()];
        let mut m = 0;
        for (i, &b) in is_boundary.iter().enumerate() {
            if !b {
                interior[i] = Some(m);
                m += 1;
            }
        }
        if m == 0 {
            return Err(AnalysisError::InvalidInput(
                "the gradient flow needs an interior vertex".into(),
            ));
        }
        let (mut lower, mut full) = (Vec::new(), Vec::new());
        for f in faces {
            for k in 0..3 {
                // ½ cot of corner k on the edge (i, j) opposite it
                let o = domain[f[k] as usize];
                let (i, j) = (f[(k + 1) % 3] as usize, f[(k + 2) % 3] as usize);
                let (p, q) = (domain[i], domain[j]);
                let (a, b) = ([p[0] - o[0], p[1] - o[1]], [q[0] - o[0], q[1] - o[1]]);
                let w = 0.5 * (a[0] * b[0] + a[1] * b[1]) / (a[0] * b[1] - a[1] * b[0]);
                for (r, c) in [(i, j), (j, i)] {
                    if let Some(r) = interior[r] {
                        full.push(Triplet::new(r, r, w));
                        lower.push(Triplet::new(r, r, w));
                        if let Some(c) = interior[c] {
                            full.push(Triplet::new(r, c, -w));
                            if r > c {
                                lower.push(Triplet::new(r, c, -w));
                            }
                        }
                    }
                }
            }
        }
        let assemble = |t: &[Triplet<usize, usize, f64>]| {
            SparseColMat::try_new_from_triplets(m, m, t)
                .map_err(|e| AnalysisError::InvalidInput(format!("assembling the Dirichlet Laplacian: {e:?}")))
        };
        let a = assemble(&lower)?;
        let symbolic = SymbolicLlt::try_new(a.symbolic(), faer::Side::Lower)
            .map_err(|e| AnalysisError::InvalidInput(format!("symbolic Cholesky of the Dirichlet Laplacian: {e:?}")))?;
        let solver = match Llt::try_new_with_symbolic(symbolic, a.as_ref(), faer::Side::Lower) {
            Ok(llt) => Factor::Llt(llt),
            Err(_) => Factor::Lu(Box::new(assemble(&full)?.sp_lu().map_err(|e| {
                AnalysisError::InvalidInput(format!("LU of the Dirichlet Laplacian: {e:?}"))
            })?)),
        };
        Ok(CurlPart {
            faces: faces.to_vec(),
            domain: domain.to_vec(),
            domain_areas: domain_areas.to_vec(),
            interior,
            solver,
        })
    }

    /// ζ_f = ∇⊥h per face (#F) for the map `u` (#V).
    pub fn zeta(&self, u: &[[f64; 2]]) -> Result<Vec<[f64; 2]>, AnalysisError> {
        let m = self.interior.iter().flatten().count();
        let mut rhs = faer::Mat::<f64>::zeros(m, 1);
        for f in &self.faces {
            let mean = [0, 1].map(|c| (u[f[0] as usize][c] + u[f[1] as usize][c] + u[f[2] as usize][c]) / 3.0);
            for k in 0..3 {
                let Some(r) = self.interior[f[k] as usize] else {
                    continue;
                };
                // |f| ∇λ_k = rot90(p_{k+2} − p_{k+1}) / 2
                let (a, b) = (
                    self.domain[f[(k + 1) % 3] as usize],
                    self.domain[f[(k + 2) % 3] as usize],
                );
                let g = [-(b[1] - a[1]) / 2.0, (b[0] - a[0]) / 2.0];
                rhs[(r, 0)] += mean[1] * g[0] - mean[0] * g[1];
            }
        }
        match &self.solver {
            Factor::Llt(s) => s.solve_in_place(rhs.as_mut()),
            Factor::Lu(s) => s.solve_in_place(rhs.as_mut()),
        }
        let h: Vec<f64> = self.interior.iter().map(|r| r.map_or(0.0, |r| rhs[(r, 0)])).collect();
        let zeta: Vec<[f64; 2]> = self
            .faces
            .iter()
            .zip(&self.domain_areas)
            .map(|(f, &area)| {
                let g = face_gradient(&self.domain, f, &h, area);
                [-g[1], g[0]]
            })
            .collect();
        if zeta.iter().any(|z| !(z[0].is_finite() && z[1].is_finite())) {
            return Err(AnalysisError::InvalidInput(
                "the curl part of the map is not finite (Dirichlet solve failed)".into(),
            ));
        }
        Ok(zeta)
    }

    /// ‖ζ‖/‖u‖, L² norms on the domain (u by its face means).
    pub fn relative_norm(&self, zeta: &[[f64; 2]], u: &[[f64; 2]]) -> f64 {
        let (mut z2, mut u2) = (0.0, 0.0);
        for ((f, z), a) in self.faces.iter().zip(zeta).zip(&self.domain_areas) {
            let mean = [0, 1].map(|c| (u[f[0] as usize][c] + u[f[1] as usize][c] + u[f[2] as usize][c]) / 3.0);
            z2 += a * (z[0] * z[0] + z[1] * z[1]);
            u2 += a * (mean[0] * mean[0] + mean[1] * mean[1]);
        }
        (z2 / u2).sqrt()
    }
}
