//! Authalic (area-preserving) disk parameterization by Lie advection of the area 2-form
//! [Zou, Hu, Gu, Hua 2011, "Authalic parameterization of general surfaces using Lie
//! advection", IEEE TVCG 17(12)], built on Moser's trick [Moser 1965, "On the volume elements
//! on a manifold"; Dacorogna & Moser 1990].
//!
//! The surface (scaled to the area of its image) pushed forward by the conformal disk map φ
//! has the area form $\omega_0 = \rho_0\,dx\wedge dy$ on the disk; the target is
//! $\omega_1 = dx \wedge dy$ with the same total. Along the interpolation
//! $\omega_t = (1-t)\,\omega_0 + t\,\omega_1$ the flow $\psi_t$ of the time-dependent field
//! $v_t$ with
//!
//! $$\mathcal L_{v_t}\,\omega_t = -\partial_t \omega_t = \omega_0 - \omega_1
//!   \iff \operatorname{div}(\rho_t v_t) = \rho_0 - 1, \qquad \rho_t v_t = \nabla f,\quad
//!   \Delta f = \rho_0 - 1,\quad \partial_n f = 0 \text{ on } \partial D,$$
//!
//! satisfies $\psi_t^*\omega_t = \omega_0$ (Cartan: $\mathcal L_v \omega = d\,\iota_v\omega$
//! for a 2-form on a surface; the Neumann condition keeps $v_t$ tangent to the rim). At
//! $t = 1$ the map $\psi_1 \circ \varphi$ sends every region of the surface to a region of the
//! disk of the same area.
//!
//! # Discrete form
//! 1. **Advection** (Moser's construction: one field on the fixed initial domain). On the
//!    conformal image, $\rho_0(f) = a_f/|f_0|$ per face ($a_f$ the surface's face area scaled
//!    to the image's total). One P1 finite-element Neumann problem (cotangent stiffness,
//!    lumped right side, one vertex pinned; faer sparse Cholesky)
//!    $L f = -\big(\sum_{f \ni i} \tfrac13 (a_f - |f_0|)\big)_i$ gives $\nabla f$ per face;
//!    its area-weighted vertex averages (tangential part on the rim) and the one-ring densities
//!    $\rho_0(i)$ are interpolated linearly over the faces, and
//!    $v_t(x) = \nabla f(x) / ((1-t)\rho_0(x) + t)$. Each vertex's trajectory is integrated
//!    on its own (in parallel) by adaptive Bogacki–Shampine 3(2) steps, the point located in
//!    the initial mesh at every stage ([`crate::point_location`]); rim vertices move by
//!    their angle on the unit circle. The local error bound is
//!    `tolerance` × the square root of the image area of the vertex's faces at that time.
//! 2. **Fold repair.** The straight-line triangles between the advected vertices can fold
//!    where the field varies within a face of the crowded conformal image; the fold repair of
//!    the OMT map ([`crate::fold_repair`]) re-embeds the vertices around them. When it fails,
//!    the advected map is kept with its folds ([`LieAdvectionInfo::fold_repair_error`]).
//! 3. **Correction** (this implementation's addition). The interpolated field is not
//!    exactly divergence-consistent, so the advected map keeps an error of the order of the
//!    mesh's (rim one-rings worst). From the unfolded map, the same Moser flow is run again,
//!    evaluated on the *current* mesh: there the pushed-forward density is
//!    $\rho_t(f) = a_f/|f_t|$ and $\rho_0 - 1 = (\rho_t - 1)/(1 - t)$, so at each stage one
//!    Poisson problem on the current image (symbolic factorization reused) gives
//!    $v_i = \sum_{f\ni i} |f_t|\,\nabla f|_f / \sum_{f\ni i} a_f$; `correction_steps` explicit
//!    midpoint steps over [0, 1], halved when a face would fold or change its area more than
//!    twofold. The factor 1/(1 − t) feeds the remaining density error back, so the last step is
//!    a full linearized correction. On real meshes it stalls within its first steps: the fold
//!    repair leaves faces 40–60 times their area beside faces of the right size, and the
//!    vertex-averaged field collapses a neighbouring face in finite time at any step size.
//!    The **area-rate correction** then runs instead (decision 0044): damped Newton steps
//!    x ← x + α v on the face areas, v = M⁻¹Jᵀλ with (J M⁻¹ Jᵀ) λ = T − |f| (J the face
//!    areas' derivatives by the vertex positions, M the lumped masses; one sparse Cholesky of
//!    a face-by-face matrix per step), the least-kinetic-energy velocity giving every face its
//!    exact rate, so no face short of area is squeezed. It is not a gradient field and can add
//!    a rotation, hence only a fallback. When it makes no step either the repaired advected
//!    map is returned ([`CorrectionInfo::skipped`]).

use std::time::Instant;

use faer::linalg::solvers::Solve;
use faer::sparse::linalg::solvers::{Llt, SymbolicLlt};
use faer::sparse::{SparseColMat, Triplet};
use serde::Serialize;
use shapespace_conformal::{disk_map, DiskMap, DiskMapParams, Markers};
use shapespace_geometry::quantities::face_areas;
use shapespace_geometry::{Connectivity, TriMesh};
use shapespace_omt::predicates::orient;

use crate::error::AnalysisError;
use crate::fold_repair::{repair_folds_with, FoldRepairInfo, FoldRepairParams};
use crate::point_location::PointLocator;
use rayon::prelude::*;

/// Parameters of [`lie_advection_map`].
#[derive(Clone, Debug)]
pub struct LieAdvectionParams {
    /// Parameters of the conformal map the flow starts from.
    pub disk_map: DiskMapParams,
    /// Local error bound of each integration step, relative to the square root of the image
    /// area of the vertex's faces at that point of the flow (default 1e-3).
    pub tolerance: f64,
    /// Most integration steps (accepted and rejected) of one vertex (default 10,000).
    pub max_attempts: usize,
    /// Fold repair of the advected map (default on; [`crate::fold_repair`], as for the OMT map).
    pub fold_repair: FoldRepairParams,
    /// Time steps of the correction flow after the advection (default 4; 0: none; module docs,
    /// "Correction").
    pub correction_steps: usize,
}

impl Default for LieAdvectionParams {
    fn default() -> Self {
        LieAdvectionParams {
            disk_map: DiskMapParams::default(),
            tolerance: 1e-3,
            max_attempts: 10_000,
            fold_repair: FoldRepairParams::default(),
            correction_steps: 4,
        }
    }
}

/// What the flow did.
#[derive(Clone, Debug, Default, PartialEq, Serialize)]
pub struct LieAdvectionInfo {
    /// Poisson solves (one: the field's potential on the conformal image).
    pub poisson_solves: usize,
    /// Poisson solves whose Cholesky factorization failed in floating point and that were done
    /// by LU instead.
    pub lu_fallbacks: usize,
    /// Accepted integration steps over all vertices.
    pub total_steps: usize,
    /// Mean accepted steps per vertex (the "iterations" of the flow).
    pub mean_steps: f64,
    /// Most accepted steps of one vertex.
    pub max_steps: usize,
    /// Rejected (error too large) steps over all vertices.
    pub rejected_steps: usize,
    /// The fold repair of the advected map.
    pub fold_repair: FoldRepairInfo,
    /// Why the fold repair failed, if it did (the map is then the advected one, with its folds).
    pub fold_repair_error: Option<String>,
    /// The correction flow.
    pub correction: CorrectionInfo,
}

/// What the correction flow did (module docs, "Correction").
#[derive(Clone, Debug, Default, PartialEq, Serialize)]
pub struct CorrectionInfo {
    /// Accepted time steps.
    pub steps: usize,
    /// Steps halved because they would have folded a face or changed a face's area more than
    /// twofold.
    pub halvings: usize,
    /// Poisson solves.
    pub poisson_solves: usize,
    /// Whether the correction was applied (`false`: not asked for, the map still folded, or it
    /// stalled; the map is then the repaired advected one).
    pub applied: bool,
    /// Why it was not applied, if it was not; or, when the area-rate correction was applied in
    /// its place, why the Moser flow stopped.
    pub skipped: Option<String>,
    /// Accepted steps of the area-rate correction, run when the Moser flow stalls (0: not run).
    pub area_rate_steps: usize,
}

impl CorrectionInfo {
    /// One line for reports: the Moser correction's steps, the area-rate correction that ran in
    /// its place and why, or why none was applied.
    pub fn summary(&self) -> String {
        match (&self.skipped, self.applied) {
            (None, _) => format!("correction {} steps ({} halved)", self.steps, self.halvings),
            (Some(why), true) => format!(
                "area-rate correction {} steps (the Moser correction flow {why})",
                self.area_rate_steps
            ),
            (Some(why), false) => format!("correction not applied ({why})"),
        }
    }
}

/// Wall-clock seconds of [`lie_advection_map`].
#[derive(Clone, Debug, Default, PartialEq, Serialize)]
pub struct LieAdvectionTimings {
    /// The conformal disk map.
    pub conformal: f64,
    /// The advection (Poisson solve and trajectories).
    pub advection: f64,
    /// The fold repair.
    pub repair: f64,
    /// The correction flow.
    pub correction: f64,
    /// Everything.
    pub total: f64,
}

/// The authalic map of [`lie_advection_map`].
#[derive(Clone, Debug)]
pub struct LieAdvectionMap {
    /// Image of each vertex in the unit disk, #V (rim vertices on |z| = 1).
    pub uv: Vec<[f64; 2]>,
    /// The conformal map the flow started from.
    pub conformal: DiskMap,
    /// Steps and solves.
    pub info: LieAdvectionInfo,
    /// Timings.
    pub timings: LieAdvectionTimings,
}

/// The Lie-advection authalic map of a disk-type `mesh` onto the unit disk (module docs; Zou
/// et al. 2011): the conformal disk map, the advection of its vertices by the Moser flow of
/// its area form to the uniform one, the fold repair, and the correction flow.
///
/// Errors: those of the conformal map; [`AnalysisError::InvalidInput`]
/// for a zero-area face, a bad tolerance, a failed Poisson solve or a non-finite velocity;
/// [`AnalysisError::FlowStalled`] when a vertex's trajectory needs more than `max_attempts`
/// steps.
pub fn lie_advection_map(
    mesh: &TriMesh,
    markers: &Markers,
    params: &LieAdvectionParams,
) -> Result<LieAdvectionMap, AnalysisError> {
    let t0 = Instant::now();
    let conformal = disk_map(mesh, markers, &params.disk_map).map_err(AnalysisError::DiskMap)?;
    let t1 = Instant::now();
    let conn = Connectivity::of(mesh);
    let is_boundary = conn.boundary_vertices(mesh.num_vertices());
    let areas = face_areas(mesh);
    let (mut uv, mut info) = advect(&mesh.faces, &areas, &is_boundary, &conformal.uv, params)?;
    let t2 = Instant::now();
    // (a repair that fails leaves the advected map, folds and all, and says why)
    let mut repaired = uv.clone();
    match repair_folds_with(mesh, Some(&conn), &is_boundary, &mut repaired, &params.fold_repair) {
        Ok(repair) => {
            info.fold_repair = repair;
            uv = repaired;
        }
        Err(e) => info.fold_repair_error = Some(e.to_string()),
    }
    let t3 = Instant::now();
    info.correction = if params.correction_steps == 0 {
        CorrectionInfo {
            skipped: Some("not asked for".into()),
            ..Default::default()
        }
    } else if let Some(f) = mesh.faces.iter().position(|f| !face_is_ccw(&uv, f)) {
        CorrectionInfo {
            skipped: Some(format!("face {f} is still folded")),
            ..Default::default()
        }
    } else {
        let (corrected, correction) = correct(&mesh.faces, &areas, &is_boundary, &uv, params.correction_steps)?;
        if correction.applied {
            uv = corrected;
        }
        correction
    };
    let t4 = Instant::now();
    let secs = |a: Instant, b: Instant| (b - a).as_secs_f64();
    Ok(LieAdvectionMap {
        uv,
        conformal,
        info,
        timings: LieAdvectionTimings {
            conformal: secs(t0, t1),
            advection: secs(t1, t2),
            repair: secs(t2, t3),
            correction: secs(t3, t4),
            total: secs(t0, t4),
        },
    })
}

/// The Moser flow of the planar mesh `start` (#V, counter-clockwise faces, rim vertices on the
/// unit circle where `is_boundary`) from its density `surface_areas / image areas` (#F,
/// any common scale) to the uniform density (module docs). Returns the end positions.
///
/// Errors: see [`lie_advection_map`].
pub fn advect(
    faces: &[[u32; 3]],
    surface_areas: &[f64],
    is_boundary: &[bool],
    start: &[[f64; 2]],
    params: &LieAdvectionParams,
) -> Result<(Vec<[f64; 2]>, LieAdvectionInfo), AnalysisError> {
    if !(params.tolerance.is_finite() && params.tolerance > 0.0) {
        return Err(AnalysisError::InvalidInput(format!(
            "Lie advection tolerance {} (must be finite and > 0)",
            params.tolerance
        )));
    }
    if let Some(f) = surface_areas.iter().position(|a| !(a.is_finite() && *a > 0.0)) {
        return Err(AnalysisError::InvalidInput(format!(
            "face {f} has surface area {} (must be finite and > 0)",
            surface_areas[f]
        )));
    }
    if let Some(f) = faces.iter().position(|f| !face_is_ccw(start, f)) {
        return Err(AnalysisError::InvalidInput(format!(
            "face {f} of the starting map is folded or degenerate"
        )));
    }
    let field = MoserField::new(faces, surface_areas, is_boundary, start)?;
    let results: Vec<Result<Trajectory, AnalysisError>> = (0..start.len())
        .into_par_iter()
        .map(|i| field.trajectory(i, params))
        .collect();
    let mut uv = Vec::with_capacity(start.len());
    let mut info = LieAdvectionInfo {
        poisson_solves: 1,
        lu_fallbacks: field.lu_fallbacks,
        ..Default::default()
    };
    for r in results {
        let (p, steps, rejected) = r?;
        uv.push(p);
        info.total_steps += steps;
        info.max_steps = info.max_steps.max(steps);
        info.rejected_steps += rejected;
    }
    info.mean_steps = info.total_steps as f64 / start.len().max(1) as f64;
    Ok((uv, info))
}

/// A trajectory's end point, accepted and rejected steps.
type Trajectory = ([f64; 2], usize, usize);

/// The time-dependent field v_t = ∇f / ((1 − t) ρ_0 + t) on the starting mesh (module docs):
/// ∇f averaged to the vertices by area and ρ_0 as one-ring ratios, both interpolated
/// linearly over the faces.
struct MoserField<'a> {
    locator: PointLocator,
    faces: &'a [[u32; 3]],
    /// Vertex values of ∇f (tangential part on the rim).
    gradients: Vec<[f64; 2]>,
    /// Vertex values of ρ_0.
    densities: Vec<f64>,

    /// Mean surface area (scaled to the image's total) of each vertex's faces: the image area
    /// of those faces at the end of the flow, which sets the vertex's step tolerance.
    end_areas: Vec<f64>,
    is_boundary: &'a [bool],
    start: &'a [[f64; 2]],
    lu_fallbacks: usize,
}

impl<'a> MoserField<'a> {
    fn new(
        faces: &'a [[u32; 3]],
        surface_areas: &[f64],
        is_boundary: &'a [bool],
        start: &'a [[f64; 2]],
    ) -> Result<Self, AnalysisError> {
        let n = start.len();
        let image: Vec<f64> = faces.iter().map(|f| signed_area(start, f)).collect();
        let scale = image.iter().sum::<f64>() / surface_areas.iter().sum::<f64>();
        let mut rhs = vec![0.0; n];
        for (f, face) in faces.iter().enumerate() {
            let r = -(scale * surface_areas[f] - image[f]) / 3.0;
            for &v in face {
                rhs[v as usize] += r;
            }
        }
        let mut poisson = PlanarPoisson::new(n, faces)?;
        let potential = poisson.solve(start, &rhs)?;
        let mut flux = vec![[0.0; 2]; n];
        let mut image_ring = vec![0.0; n];
        let mut surface_ring = vec![0.0; n];
        let mut count = vec![0usize; n];
        for (f, face) in faces.iter().enumerate() {
            let g = face_gradient(start, face, &potential, image[f]);
            for &v in face {
                let v = v as usize;
                flux[v][0] += image[f] * g[0];
                flux[v][1] += image[f] * g[1];
                image_ring[v] += image[f];
                surface_ring[v] += scale * surface_areas[f];
                count[v] += 1;
            }
        }
        let gradients = (0..n)
            .map(|i| {
                let g = [flux[i][0] / image_ring[i], flux[i][1] / image_ring[i]];
                if is_boundary[i] {
                    tangential(start[i], g)
                } else {
                    g
                }
            })
            .collect();
        let densities = (0..n).map(|i| surface_ring[i] / image_ring[i]).collect();
        let end_areas = (0..n).map(|i| surface_ring[i] / count[i].max(1) as f64).collect();
        Ok(MoserField {
            locator: PointLocator::new(start, faces)?,
            faces,
            gradients,
            densities,
            end_areas,
            is_boundary,
            start,
            lu_fallbacks: poisson.lu_fallbacks,
        })
    }

    /// v_t(p) and ρ_t(p).
    fn at(&self, p: [f64; 2], t: f64) -> ([f64; 2], f64) {
        let Some(loc) = self.locator.locate(p) else {
            return ([f64::NAN; 2], f64::NAN);
        };
        let f = self.faces[loc.face as usize];
        let (mut g, mut rho) = ([0.0; 2], 0.0);
        for k in 0..3 {
            let v = f[k] as usize;
            g[0] += loc.bary[k] * self.gradients[v][0];
            g[1] += loc.bary[k] * self.gradients[v][1];
            rho += loc.bary[k] * self.densities[v];
        }
        let rho_t = (1.0 - t) * rho + t;
        ([g[0] / rho_t, g[1] / rho_t], rho_t)
    }

    /// The end point of vertex `i`'s trajectory, its accepted and rejected steps: adaptive
    /// Bogacki–Shampine 3(2) (Bogacki & Shampine 1989) on dx/dt = v_t(x), with the local error
    /// bound `tolerance · √(image area at p)` (the image area of the vertex's faces at time t
    /// near p being `end_area / ρ_t(p)`). Rim vertices move on the unit circle by their angle,
    /// dθ/dt = v_t · e_θ.
    fn trajectory(&self, i: usize, params: &LieAdvectionParams) -> Result<Trajectory, AnalysisError> {
        let rim = self.is_boundary[i];
        let p0 = self.start[i];
        // state: the point, or (θ, 0) on the rim
        let to_point = |s: [f64; 2]| if rim { [s[0].cos(), s[0].sin()] } else { s };
        let rate = |s: [f64; 2], t: f64| -> ([f64; 2], f64) {
            let p = to_point(s);
            let (v, rho) = self.at(p, t);
            if rim {
                ([-p[1] * v[0] + p[0] * v[1], 0.0], rho)
            } else {
                (v, rho)
            }
        };
        let s = if rim { [p0[1].atan2(p0[0]), 0.0] } else { p0 };
        let end_area = self.end_areas[i];
        let (s, steps, rejected) = bogacki_shampine(
            s,
            rate,
            |rho| params.tolerance * (end_area / rho).sqrt(),
            |s| s,
            params.max_attempts,
            i,
        )?;
        Ok((to_point(s), steps, rejected))
    }
}

/// Adaptive Bogacki–Shampine 3(2) (Bogacki & Shampine 1989) on ds/dt = rate(s, t) over
/// t ∈ [0, 1] from `start`, the first step 1/16: `rate` returns the velocity and the density
/// ρ_t at s, the local error bound of a step is `tolerance(max ρ at its ends)`, and every
/// accepted state goes through `finish` (the plane: none; the sphere: back onto S²). Returns
/// the end state, the accepted and the rejected steps. Shared by the disk's and the sphere's
/// trajectories.
///
/// Errors: [`AnalysisError::InvalidInput`] for a non-finite velocity (of vertex `vertex`),
/// [`AnalysisError::FlowStalled`] after `max_attempts` steps or a step below 1e-12.
pub(crate) fn bogacki_shampine<const D: usize>(
    start: [f64; D],
    rate: impl Fn([f64; D], f64) -> ([f64; D], f64),
    tolerance: impl Fn(f64) -> f64,
    finish: impl Fn([f64; D]) -> [f64; D],
    max_attempts: usize,
    vertex: usize,
) -> Result<([f64; D], usize, usize), AnalysisError> {
    let i = vertex;
    let mut s = start;
    let (mut t, mut h) = (0.0f64, 1.0f64 / 16.0);
    let (mut steps, mut rejected) = (0, 0);
    let (mut k1, mut rho) = rate(s, 0.0);
    let add = |s: [f64; D], terms: &[(f64, [f64; D])]| {
        let mut out = s;
        for (c, k) in terms {
            for (o, kd) in out.iter_mut().zip(k) {
                *o += c * kd;
            }
        }
        out
    };
    while t < 1.0 {
        if !k1.iter().all(|x| x.is_finite()) {
            return Err(AnalysisError::InvalidInput(format!(
                "the flow's velocity at vertex {i} is not finite at t = {t}"
            )));
        }
        h = h.min(1.0 - t);
        let (k2, _) = rate(add(s, &[(0.5 * h, k1)]), t + 0.5 * h);
        let (k3, _) = rate(add(s, &[(0.75 * h, k2)]), t + 0.75 * h);
        let next = add(s, &[(2.0 / 9.0 * h, k1), (h / 3.0, k2), (4.0 / 9.0 * h, k3)]);
        let (k4, rho_next) = rate(next, t + h);
        let e = add(
            [0.0; D],
            &[(-5.0 / 72.0, k1), (1.0 / 12.0, k2), (1.0 / 9.0, k3), (-0.125, k4)],
        );
        // (|e| by repeated hypot: for D = 2 exactly e[0].hypot(e[1]))
        let err = h * e.iter().fold(0.0f64, |a, x| a.hypot(*x));
        let tol = tolerance(rho.max(rho_next));
        if err <= tol || h < 1e-12 {
            if !(err <= tol) {
                return Err(AnalysisError::FlowStalled {
                    time: t,
                    step: h,
                    attempts: steps + rejected,
                });
            }
            s = finish(next);
            t += h;
            k1 = k4;
            rho = rho_next;
            steps += 1;
        } else {
            rejected += 1;
        }
        let factor = if err > 0.0 { 0.9 * (tol / err).cbrt() } else { 5.0 };
        h *= factor.clamp(0.2, 5.0);
        if steps + rejected > max_attempts {
            return Err(AnalysisError::FlowStalled {
                time: t,
                step: h,
                attempts: max_attempts,
            });
        }
    }
    Ok((s, steps, rejected))
}

/// Most attempted steps (accepted and halved) of the correction flow.
pub const CORRECTION_ATTEMPTS: usize = 64;

/// Smallest time step of the correction flow: a step halved below it stops the correction.
pub const CORRECTION_MIN_STEP: f64 = 1e-4;

/// The correction flow (module docs, "Correction") from the unfolded map `start`: `steps`
/// midpoint steps over [0, 1] of the Moser flow evaluated on the current mesh, halved when a
/// step would fold a face or change a face's area more than twofold. A correction that needs
/// more than [`CORRECTION_ATTEMPTS`] attempted steps or a step below [`CORRECTION_MIN_STEP`]
/// stops; the area-rate correction ([`area_rate_correction`]) then runs from `start` instead,
/// and when it makes no step either the input map is kept (`applied` false).
fn correct(
    faces: &[[u32; 3]],
    surface_areas: &[f64],
    is_boundary: &[bool],
    start: &[[f64; 2]],
    steps: usize,
) -> Result<(Vec<[f64; 2]>, CorrectionInfo), AnalysisError> {
    let mut poisson = PlanarPoisson::new(start.len(), faces)?;
    let (x, moser) = correction_flow(
        start,
        steps,
        |x: &[[f64; 2]], t| current_velocity(&mut poisson, faces, surface_areas, is_boundary, x, t),
        |x: &[[f64; 2]], v: &[[f64; 2]], h| moved(x, v, h, is_boundary),
        |x: &[[f64; 2]], next: &[[f64; 2]]| acceptable(faces, x, next),
    );
    if moser.applied {
        return Ok((x, moser));
    }
    let (x, rate) = area_rate_correction(faces, surface_areas, is_boundary, start)?;
    Ok((
        x,
        CorrectionInfo {
            steps: moser.steps + rate.steps,
            halvings: moser.halvings + rate.halvings,
            poisson_solves: moser.poisson_solves + rate.poisson_solves,
            applied: rate.applied,
            skipped: match rate.skipped {
                Some(why) if !rate.applied => Some(format!("{}; {why}", moser.skipped.unwrap_or_default())),
                _ => moser.skipped,
            },
            area_rate_steps: rate.steps,
        },
    ))
}

/// The area-rate correction of the unfolded map `start`, the correction flow's fallback: damped Newton steps
/// on the face areas, x ← x + α v with v the least-kinetic-energy velocity that moves every
/// face's area to its target at unit rate ([`AreaRateVelocity`]), α = 1 halved until no face
/// folds or changes its area more than twofold, then doubled back toward 1. It stops after
/// [`CORRECTION_ATTEMPTS`] attempts, a step below [`CORRECTION_MIN_STEP`], or when a full step
/// lowers the area-weighted rms of ln(|f| / a_f) by less than 1 %; it is
/// applied when one step was accepted. The velocity is not a gradient: it can add a rotation
/// the Moser field does not (decision 0044), hence only a fallback.
fn area_rate_correction(
    faces: &[[u32; 3]],
    surface_areas: &[f64],
    is_boundary: &[bool],
    start: &[[f64; 2]],
) -> Result<(Vec<[f64; 2]>, CorrectionInfo), AnalysisError> {
    let rates = AreaRateVelocity::new(start.len(), faces)?;
    let total: f64 = surface_areas.iter().sum();
    let mut mass = vec![0.0; start.len()];
    let start_image: f64 = faces.iter().map(|f| signed_area(start, f)).sum();
    for (f, face) in faces.iter().enumerate() {
        for &v in face {
            mass[v as usize] += start_image / total * surface_areas[f] / 3.0;
        }
    }
    let rms = |x: &[[f64; 2]]| {
        let image: Vec<f64> = faces.iter().map(|f| signed_area(x, f)).collect();
        let scale = image.iter().sum::<f64>() / total;
        let s: f64 = image
            .iter()
            .zip(surface_areas)
            .map(|(a, t)| t * (a / (scale * t)).ln().powi(2))
            .sum();
        (s / total).sqrt()
    };
    let mut x = start.to_vec();
    let mut info = CorrectionInfo::default();
    let mut error = rms(&x);
    let mut alpha = 1.0f64;
    while info.steps + info.halvings < CORRECTION_ATTEMPTS {
        let image: Vec<f64> = faces.iter().map(|f| signed_area(&x, f)).collect();
        let scale = image.iter().sum::<f64>() / total;
        let target: Vec<f64> = image.iter().zip(surface_areas).map(|(a, t)| scale * t - a).collect();
        let Ok(v) = rates.solve(faces, is_boundary, &x, &mass, &target) else {
            info.skipped = Some(format!("failed solve after {} steps", info.steps));
            break;
        };
        info.poisson_solves += 1;
        if v.iter().any(|v| !(v[0].is_finite() && v[1].is_finite())) {
            info.skipped = Some(format!("no finite velocity after {} steps", info.steps));
            break;
        }
        let mut accepted = false;
        while alpha >= CORRECTION_MIN_STEP && info.steps + info.halvings < CORRECTION_ATTEMPTS {
            let next = moved(&x, &v, alpha, is_boundary);
            if acceptable(faces, &x, &next) {
                let e = rms(&next);
                let gain = 1.0 - e / error;
                x = next;
                error = e;
                info.steps += 1;
                accepted = true;
                if alpha == 1.0 && gain < 0.01 {
                    info.applied = true;
                    return Ok((x, info));
                }
                alpha = (2.0 * alpha).min(1.0);
                break;
            }
            info.halvings += 1;
            alpha *= 0.5;
        }
        if !accepted {
            break;
        }
    }
    info.applied = info.steps > 0;
    if !info.applied && info.skipped.is_none() {
        info.skipped = Some(format!("no step lowered the area error (step {alpha:.1e})"));
    }
    Ok((x, info))
}

/// The correction flow's time stepping, shared by the disk and the sphere: from `start`,
/// `steps` explicit midpoint steps over [0, 1] of `velocity(x, t)` (one Poisson solve each),
/// positions advanced by `moved(x, v, h)`, a step halved when `acceptable(x, next)` refuses its
/// midpoint or its end and doubled back toward 1/`steps` after a success. A failed velocity,
/// more than [`CORRECTION_ATTEMPTS`] attempted steps or a step below [`CORRECTION_MIN_STEP`]
/// stop it, and `start` is returned (`applied` false).
pub(crate) fn correction_flow<P: Clone>(
    start: &[P],
    steps: usize,
    mut velocity: impl FnMut(&[P], f64) -> Result<Vec<P>, AnalysisError>,
    moved: impl Fn(&[P], &[P], f64) -> Vec<P>,
    acceptable: impl Fn(&[P], &[P]) -> bool,
) -> (Vec<P>, CorrectionInfo) {
    let mut x = start.to_vec();
    let mut info = CorrectionInfo::default();
    let nominal = 1.0 / steps as f64;
    let (mut t, mut h) = (0.0f64, nominal);
    while 1.0 - t > 1e-12 {
        h = h.min(1.0 - t);
        if info.steps + info.halvings >= CORRECTION_ATTEMPTS || (h < CORRECTION_MIN_STEP && h < 1.0 - t) {
            info.skipped = Some(format!("stalled at t = {t:.3} (step {h:.1e})"));
            return (x, info);
        }
        // (a failed solve or a non-finite velocity: the correction stops, the input map stays)
        let Ok(k1) = velocity(&x, t) else {
            info.skipped = Some(format!("no finite velocity at t = {t:.3}"));
            return (x, info);
        };
        info.poisson_solves += 1;
        let mid = moved(&x, &k1, 0.5 * h);
        let accepted = if acceptable(&x, &mid) {
            let Ok(k2) = velocity(&mid, t + 0.5 * h) else {
                info.skipped = Some(format!("no finite velocity at t = {t:.3}"));
                return (x, info);
            };
            info.poisson_solves += 1;
            let next = moved(&x, &k2, h);
            acceptable(&x, &next).then_some(next)
        } else {
            None
        };
        match accepted {
            Some(next) => {
                x = next;
                t += h;
                info.steps += 1;
                h = (2.0 * h).min(nominal);
            }
            None => {
                info.halvings += 1;
                h *= 0.5;
            }
        }
    }
    info.applied = true;
    (x, info)
}

/// The least-kinetic-energy vertex velocities that change every face's area at a prescribed
/// rate: v = M⁻¹ Jᵀ λ with (J M⁻¹ Jᵀ) λ = r, J the derivatives of the face areas by the vertex
/// positions (rim vertices: along the circle's tangent only) and M the lumped target masses.
/// To first order each face's area then moves at exactly its rate, so a face short of area
/// cannot be collapsed by the motion of its neighbours (as the vertex-averaged Moser field can).
pub(crate) struct AreaRateVelocity {
    /// For each vertex, its faces and the corner it is.
    ring: Vec<Vec<(u32, u8)>>,
    symbolic: SymbolicLlt<usize>,
    pattern: Vec<(usize, usize)>,
    nf: usize,
}

impl AreaRateVelocity {
    pub(crate) fn new(n: usize, faces: &[[u32; 3]]) -> Result<Self, AnalysisError> {
        let mut ring: Vec<Vec<(u32, u8)>> = vec![Vec::new(); n];
        for (fi, f) in faces.iter().enumerate() {
            for (k, &v) in f.iter().enumerate() {
                ring[v as usize].push((fi as u32, k as u8));
            }
        }
        let mut pattern = Vec::new();
        for r in &ring {
            for &(f, _) in r {
                for &(g, _) in r {
                    if f >= g {
                        pattern.push((f as usize, g as usize));
                    }
                }
            }
        }
        pattern.sort_unstable();
        pattern.dedup();
        let trip: Vec<Triplet<usize, usize, f64>> = pattern.iter().map(|&(i, j)| Triplet::new(i, j, 1.0)).collect();
        let a = SparseColMat::try_new_from_triplets(faces.len(), faces.len(), &trip)
            .map_err(|e| AnalysisError::InvalidInput(format!("assembling the face matrix: {e:?}")))?;
        let symbolic = SymbolicLlt::try_new(a.symbolic(), faer::Side::Lower)
            .map_err(|e| AnalysisError::InvalidInput(format!("symbolic Cholesky of the face matrix: {e:?}")))?;
        Ok(AreaRateVelocity {
            ring,
            symbolic,
            pattern,
            nf: faces.len(),
        })
    }

    /// Velocities of the positions `x` for the face-area rates `rates` (#F), vertex masses `mass`.
    pub(crate) fn solve(
        &self,
        faces: &[[u32; 3]],
        is_boundary: &[bool],
        x: &[[f64; 2]],
        mass: &[f64],
        rates: &[f64],
    ) -> Result<Vec<[f64; 2]>, AnalysisError> {
        // the area gradient of face f by its corner k's position
        let grad = |f: u32, k: u8| {
            let face = faces[f as usize];
            let b = x[face[(k as usize + 1) % 3] as usize];
            let c = x[face[(k as usize + 2) % 3] as usize];
            [0.5 * (b[1] - c[1]), 0.5 * (c[0] - b[0])]
        };
        // the directions each vertex may move along: both axes, or the rim's tangent
        let dirs = |i: usize| -> Vec<[f64; 2]> {
            if is_boundary[i] {
                let r = x[i][0].hypot(x[i][1]);
                vec![[-x[i][1] / r, x[i][0] / r]]
            } else {
                vec![[1.0, 0.0], [0.0, 1.0]]
            }
        };
        let mut trip = Vec::with_capacity(self.pattern.len() * 3);
        for (i, r) in self.ring.iter().enumerate() {
            for d in dirs(i) {
                let j: Vec<(usize, f64)> = r
                    .iter()
                    .map(|&(f, k)| {
                        let g = grad(f, k);
                        (f as usize, g[0] * d[0] + g[1] * d[1])
                    })
                    .collect();
                for &(f, a) in &j {
                    for &(g, b) in &j {
                        if f >= g {
                            trip.push(Triplet::new(f, g, a * b / mass[i]));
                        }
                    }
                }
            }
        }
        // (λ constant is nearly a null vector: the rim's tangential moves barely change the
        // total area; a tiny diagonal shift fixes it, the rates summing to zero)
        let mut diagonal = vec![0.0; self.nf];
        for t in &trip {
            if t.row == t.col {
                diagonal[t.row] += t.val;
            }
        }
        let shift = 1e-9 * diagonal.iter().sum::<f64>() / self.nf as f64;
        trip.extend((0..self.nf).map(|f| Triplet::new(f, f, shift)));
        let a = SparseColMat::try_new_from_triplets(self.nf, self.nf, &trip)
            .map_err(|e| AnalysisError::InvalidInput(format!("assembling the face matrix: {e:?}")))?;
        let llt = Llt::try_new_with_symbolic(self.symbolic.clone(), a.as_ref(), faer::Side::Lower)
            .map_err(|e| AnalysisError::InvalidInput(format!("Cholesky of the face matrix: {e:?}")))?;
        let mut lambda = faer::Mat::<f64>::from_fn(self.nf, 1, |f, _| rates[f]);
        llt.solve_in_place(lambda.as_mut());
        Ok((0..x.len())
            .map(|i| {
                let mut v = [0.0; 2];
                for d in dirs(i) {
                    let s: f64 = self.ring[i]
                        .iter()
                        .map(|&(f, k)| {
                            let g = grad(f, k);
                            lambda[(f as usize, 0)] * (g[0] * d[0] + g[1] * d[1])
                        })
                        .sum::<f64>()
                        / mass[i];
                    v[0] += s * d[0];
                    v[1] += s * d[1];
                }
                v
            })
            .collect())
    }
}

/// Whether every face of `next` is counter-clockwise with an area within a factor 2 of its
/// area in `x`.
pub(crate) fn acceptable(faces: &[[u32; 3]], x: &[[f64; 2]], next: &[[f64; 2]]) -> bool {
    faces.iter().all(|f| {
        if !face_is_ccw(next, f) {
            return false;
        }
        let ratio = signed_area(next, f) / signed_area(x, f);
        (0.5..=2.0).contains(&ratio)
    })
}

/// `x + h v`, rim vertices put back on the unit circle.
pub(crate) fn moved(x: &[[f64; 2]], v: &[[f64; 2]], h: f64, is_boundary: &[bool]) -> Vec<[f64; 2]> {
    x.iter()
        .zip(v)
        .zip(is_boundary)
        .map(|((p, v), &b)| {
            let q = [p[0] + h * v[0], p[1] + h * v[1]];
            if b {
                let r = q[0].hypot(q[1]);
                [q[0] / r, q[1] / r]
            } else {
                q
            }
        })
        .collect()
}

/// Vertex velocities of the Moser flow from a potential: per vertex, the image-area-weighted
/// mean of the potential's face gradients divided by the vertex's (scaled) surface area, the
/// rim's made tangential. Shared by the correction flow and the gradient flow's projection.
pub(crate) fn vertex_velocities(
    x: &[[f64; 2]],
    faces: &[[u32; 3]],
    potential: &[f64],
    image: &[f64],
    scale: f64,
    surface_areas: &[f64],
    is_boundary: &[bool],
) -> Vec<[f64; 2]> {
    let n = x.len();
    let mut flux = vec![[0.0; 2]; n];
    let mut mass = vec![0.0; n];
    for (f, face) in faces.iter().enumerate() {
        let g = face_gradient(x, face, potential, image[f]);
        for &v in face {
            let v = v as usize;
            flux[v][0] += image[f] * g[0];
            flux[v][1] += image[f] * g[1];
            mass[v] += scale * surface_areas[f];
        }
    }
    (0..n)
        .map(|i| {
            let v = [flux[i][0] / mass[i], flux[i][1] / mass[i]];
            if is_boundary[i] {
                tangential(x[i], v)
            } else {
                v
            }
        })
        .collect()
}

/// The correction flow's vertex velocities at time `t < 1` on the current mesh `x`: the
/// density ρ_t = a_f / |f_t| of the current map and ρ_0 − 1 = (ρ_t − 1)/(1 − t) (module docs).
fn current_velocity(
    poisson: &mut PlanarPoisson,
    faces: &[[u32; 3]],
    surface_areas: &[f64],
    is_boundary: &[bool],
    x: &[[f64; 2]],
    t: f64,
) -> Result<Vec<[f64; 2]>, AnalysisError> {
    let n = x.len();
    let image: Vec<f64> = faces.iter().map(|f| signed_area(x, f)).collect();
    let scale = image.iter().sum::<f64>() / surface_areas.iter().sum::<f64>();
    let factor = 1.0 / (1.0 - t);
    let mut rhs = vec![0.0; n];
    for (f, face) in faces.iter().enumerate() {
        let r = -factor * (scale * surface_areas[f] - image[f]) / 3.0;
        for &v in face {
            rhs[v as usize] += r;
        }
    }
    let potential = poisson.solve(x, &rhs)?;
    let v = vertex_velocities(x, faces, &potential, &image, scale, surface_areas, is_boundary);
    if let Some(i) = v.iter().position(|v| !(v[0].is_finite() && v[1].is_finite())) {
        return Err(AnalysisError::InvalidInput(format!(
            "the correction flow's velocity at vertex {i} is not finite at t = {t}"
        )));
    }
    Ok(v)
}

/// The part of `v` tangent to the circle through `p` about the origin.
pub(crate) fn tangential(p: [f64; 2], v: [f64; 2]) -> [f64; 2] {
    let r2 = p[0] * p[0] + p[1] * p[1];
    if r2 == 0.0 {
        return v;
    }
    let dot = (v[0] * p[0] + v[1] * p[1]) / r2;
    [v[0] - dot * p[0], v[1] - dot * p[1]]
}

pub(crate) fn face_is_ccw(x: &[[f64; 2]], f: &[u32; 3]) -> bool {
    orient(x[f[0] as usize], x[f[1] as usize], x[f[2] as usize]) > 0
}

pub(crate) fn signed_area(x: &[[f64; 2]], f: &[u32; 3]) -> f64 {
    let [a, b, c] = f.map(|v| x[v as usize]);
    0.5 * ((b[0] - a[0]) * (c[1] - a[1]) - (b[1] - a[1]) * (c[0] - a[0]))
}

/// Gradient of the piecewise-linear `u` on the counter-clockwise face `f` of area `area`:
/// Σ_k u_k ∇λ_k, ∇λ_k = rot90(p_{k+2} − p_{k+1}) / (2 area).
pub(crate) fn face_gradient(x: &[[f64; 2]], f: &[u32; 3], u: &[f64], area: f64) -> [f64; 2] {
    let mut g = [0.0; 2];
    for k in 0..3 {
        let (a, b) = (x[f[(k + 1) % 3] as usize], x[f[(k + 2) % 3] as usize]);
        let e = [b[0] - a[0], b[1] - a[1]];
        let uk = u[f[k] as usize];
        g[0] -= uk * e[1];
        g[1] += uk * e[0];
    }
    [g[0] / (2.0 * area), g[1] / (2.0 * area)]
}

/// P1 Neumann Poisson problems `L u = b` on one planar triangulation whose vertices move: the
/// cotangent stiffness matrix of the current positions with vertex 0 pinned (u_0 = 0), factored
/// by faer's sparse Cholesky on a symbolic factorization computed once (the pattern is the
/// mesh's). `b` must sum to 0 (the Neumann compatibility condition); its vertex-0 entry is
/// then implied by the others.
pub(crate) struct PlanarPoisson {
    /// Unique edges (i < j) of the mesh.
    edges: Vec<(usize, usize)>,
    /// For face f and corner k, the index in `edges` of the edge opposite the corner.
    corner_edges: Vec<[usize; 3]>,
    faces: Vec<[u32; 3]>,
    symbolic: SymbolicLlt<usize>,
    n: usize,
    /// Solves whose Cholesky failed (round-off) and that were done by LU.
    pub(crate) lu_fallbacks: usize,
}

impl PlanarPoisson {
    pub(crate) fn new(n: usize, faces: &[[u32; 3]]) -> Result<Self, AnalysisError> {
        if n < 2 {
            return Err(AnalysisError::InvalidInput(
                "a Poisson problem needs at least 2 vertices".into(),
            ));
        }
        let mut keyed: Vec<((usize, usize), usize)> = Vec::with_capacity(3 * faces.len());
        for (fi, f) in faces.iter().enumerate() {
            for k in 0..3 {
                let (i, j) = (f[(k + 1) % 3] as usize, f[(k + 2) % 3] as usize);
                keyed.push(((i.min(j), i.max(j)), 3 * fi + k));
            }
        }
        keyed.sort_unstable();
        let mut edges: Vec<(usize, usize)> = Vec::new();
        let mut corner_edges = vec![[0usize; 3]; faces.len()];
        for (key, corner) in keyed {
            if edges.last() != Some(&key) {
                edges.push(key);
            }
            corner_edges[corner / 3][corner % 3] = edges.len() - 1;
        }
        let weights = vec![1.0; edges.len()];
        let a = Self::matrix(n, &edges, &weights)?;
        let symbolic = SymbolicLlt::try_new(a.symbolic(), faer::Side::Lower)
            .map_err(|e| AnalysisError::InvalidInput(format!("symbolic Cholesky of the Laplacian: {e:?}")))?;
        Ok(PlanarPoisson {
            edges,
            corner_edges,
            faces: faces.to_vec(),
            lu_fallbacks: 0,
            symbolic,
            n,
        })
    }

    /// The lower triangle of the (n−1)×(n−1) Laplacian of edge weights `w`, vertex 0 removed.
    fn matrix(n: usize, edges: &[(usize, usize)], w: &[f64]) -> Result<SparseColMat<usize, f64>, AnalysisError> {
        let mut trip = Vec::with_capacity(3 * edges.len() + n);
        for (k, &(i, j)) in edges.iter().enumerate() {
            for v in [i, j] {
                if v > 0 {
                    trip.push(Triplet::new(v - 1, v - 1, w[k]));
                }
            }
            if i > 0 {
                trip.push(Triplet::new(j - 1, i - 1, -w[k]));
            }
        }
        SparseColMat::try_new_from_triplets(n - 1, n - 1, &trip)
            .map_err(|e| AnalysisError::InvalidInput(format!("assembling the Laplacian: {e:?}")))
    }

    /// Both triangles of the (n−1)×(n−1) Laplacian of edge weights `w`, vertex 0 removed.
    fn full_matrix(n: usize, edges: &[(usize, usize)], w: &[f64]) -> Result<SparseColMat<usize, f64>, AnalysisError> {
        let mut trip = Vec::with_capacity(4 * edges.len());
        for (k, &(i, j)) in edges.iter().enumerate() {
            for (a, b) in [(i, j), (j, i)] {
                if a > 0 {
                    trip.push(Triplet::new(a - 1, a - 1, w[k]));
                    if b > 0 {
                        trip.push(Triplet::new(a - 1, b - 1, -w[k]));
                    }
                }
            }
        }
        SparseColMat::try_new_from_triplets(n - 1, n - 1, &trip)
            .map_err(|e| AnalysisError::InvalidInput(format!("assembling the Laplacian: {e:?}")))
    }

    /// Solves with the stiffness matrix of the (unfolded) positions `x`; returns u (#V, u_0 = 0).
    pub(crate) fn solve(&mut self, x: &[[f64; 2]], b: &[f64]) -> Result<Vec<f64>, AnalysisError> {
        // ½ cot of each corner, on the edge opposite it
        let mut w = vec![0.0; self.edges.len()];
        for (f, corners) in self.faces.iter().zip(&self.corner_edges) {
            for k in 0..3 {
                let o = x[f[k] as usize];
                let (p, q) = (x[f[(k + 1) % 3] as usize], x[f[(k + 2) % 3] as usize]);
                let (u, v) = ([p[0] - o[0], p[1] - o[1]], [q[0] - o[0], q[1] - o[1]]);
                let cross = u[0] * v[1] - u[1] * v[0];
                w[corners[k]] += 0.5 * (u[0] * v[0] + u[1] * v[1]) / cross;
            }
        }
        self.solve_weights(&w, b)
    }

    /// Solves with the stiffness matrix of the points `x` on S² (#V), the faces taken as flat
    /// chordal triangles: ½ cot of each corner from the 3D edge vectors, cot = (u·v)/|u × v|.
    /// Used by the sphere's Lie advection and gradient flow (`param/sphere_flows.rs`), where the
    /// mesh is closed and the pinned vertex fixes the constant of the Laplacian's kernel.
    pub(crate) fn solve_sphere(&mut self, x: &[[f64; 3]], b: &[f64]) -> Result<Vec<f64>, AnalysisError> {
        let mut w = vec![0.0; self.edges.len()];
        for (f, corners) in self.faces.iter().zip(&self.corner_edges) {
            for k in 0..3 {
                let o = x[f[k] as usize];
                let (p, q) = (x[f[(k + 1) % 3] as usize], x[f[(k + 2) % 3] as usize]);
                let u = [p[0] - o[0], p[1] - o[1], p[2] - o[2]];
                let v = [q[0] - o[0], q[1] - o[1], q[2] - o[2]];
                let c = [
                    u[1] * v[2] - u[2] * v[1],
                    u[2] * v[0] - u[0] * v[2],
                    u[0] * v[1] - u[1] * v[0],
                ];
                let cross = (c[0] * c[0] + c[1] * c[1] + c[2] * c[2]).sqrt();
                w[corners[k]] += 0.5 * (u[0] * v[0] + u[1] * v[1] + u[2] * v[2]) / cross;
            }
        }
        self.solve_weights(&w, b)
    }

    /// Solves with the Laplacian of the edge weights `w` (vertex 0 pinned).
    fn solve_weights(&mut self, w: &[f64], b: &[f64]) -> Result<Vec<f64>, AnalysisError> {
        let a = Self::matrix(self.n, &self.edges, w)?;
        let mut rhs = faer::Mat::<f64>::from_fn(self.n - 1, 1, |i, _| b[i + 1]);
        match Llt::try_new_with_symbolic(self.symbolic.clone(), a.as_ref(), faer::Side::Lower) {
            Ok(llt) => llt.solve_in_place(rhs.as_mut()),
            Err(_) => {
                // positive definite in exact arithmetic (no folded face, one vertex pinned), but
                // not always in floating point when the conformal image crowds faces to 1e-10
                // of the disk: LU of the full matrix then
                self.lu_fallbacks += 1;
                let full = Self::full_matrix(self.n, &self.edges, w)?;
                let lu = full.sp_lu().map_err(|e| {
                    AnalysisError::InvalidInput(format!("LU of the Laplacian of the current map: {e:?}"))
                })?;
                lu.solve_in_place(rhs.as_mut());
            }
        }
        let mut u = vec![0.0; self.n];
        for i in 1..self.n {
            u[i] = rhs[(i - 1, 0)];
        }
        Ok(u)
    }
}
