//! The discrete Riemann map of a disk-type surface onto the unit disk.
//!
//! Given a disk-type triangle mesh M, an interior marker p and a boundary marker q, compute
//! the conformal map φ: M → D with φ(p) = 0 and φ(q) = 1 (unique by the Riemann mapping
//! theorem; Su et al. 2015, "Shape classification using Wasserstein distance for brain
//! morphometry analysis", Thm. 5):
//! 1. the intrinsic Delaunay triangulation of M (edge flips on lengths, [`crate::intrinsic`]),
//!    so every interior cotangent weight is ≥ 0;
//! 2. the Green's function construction φ = exp(−2π(G + iG*)) ([`crate::green`]):
//!    |φ| from the Dirichlet problem L u = δ_p, arg φ from a least-squares harmonic conjugate
//!    on the annulus M minus the star of p, with a 2π cut;
//! 3. the Möbius normalization z ↦ e^{iθ}(z − a)/(1 − āz) ([`crate::mobius`]) with a = φ(p)
//!    and θ such that q ↦ 1; a is the vertex image, or for p inside a face the barycentric
//!    interpolation refined by a fixed-point iteration so that the piecewise-linear image of p
//!    is exactly 0. The pole of the Green's function ([`PolePlacement`]) is by default p
//!    itself (its vertex, or the interior face corner of largest weight), so a = 0 or a is
//!    within one triangle of 0. Alternatively it is the *central* vertex (farthest from the
//!    boundary) and the Möbius map moves φ(p) to 0, with a fallback to p where the central
//!    map is too small around p (|z − a| < 1e-8, p in a protrusion) or |a| > 1 − 1e-6.
//!    Measured: the discrete Green's function carries an O(h) local error at an irregular
//!    pole (a symmetric pole such as the center of a ring mesh has none), which reaches the
//!    boundary as O(h/dist(pole, ∂M)). Cap of half-angle 1, p at 0.7 of the radius, rings
//!    10 → 80: max error 6.2e-2 → 4.9e-3 at p, 3.5e-3 → 8.9e-5 central (a symmetric pole).
//!    Domain f(D), f(z) = z/(1 − z/2), p = f(0) symmetric, rings 10 → 40: 5.4e-3 → 4.3e-4 at
//!    p, 1.3e-2 → 5.9e-3 central (irregular pole). Neither wins in general; `Central` is
//!    the safer choice when p is close to the boundary;
//! 4. a local repair of the rare folded original faces (slivers; [`crate::fold_repair::local`]); when folds
//!    remain, Boundary First Flattening ([`crate::bff`]) is tried and its map returned if it has
//!    none ([`DiskMapParams::bff_fallback`], recorded in [`DiskMapInfo::bff_fallback`]);
//! 5. the pushed-forward densities μ_f = area₃(f)/area₂(φ(f)) (surface scaled to area π) and
//!    per-vertex conformal factors e^{2λ_i} = Σ_{f∋i} area₃ / Σ_{f∋i} area₂, evaluated on the
//!    ORIGINAL faces (the intrinsic triangulation shares the vertex set).
//!
//! Why this construction (measured, `docs/decisions/0001-green-function-disk-map.md`): two sparse Cholesky solves, no
//! iteration, the boundary lies exactly on |z| = 1 (u = 0 there), and the radius error on
//! the hemisphere is first order in the edge length (the reference accuracy of `docs/conventions.md`).
//! Compared with Boundary First Flattening ([`crate::bff`]): BFF is second order
//! on smooth surfaces (12× smaller error on the hemisphere at 19k vertices, no pole error for
//! off-center markers), but on the real meshes this construction is closer to the refined
//! solution of the same polyhedral surface (ICT face: ≈ 2× in the max, ≈ 4× in the mean;
//! camelhead: 1.7× in the mean, while BFF's max is smaller there), with equal distortion and
//! folds, and faster; so it stays the default.
//!
//! Range: |φ| = e^{−2πu} shrinks exponentially along protrusions. Image coordinates are
//! kept in relative precision (rotation-only normalization when p is a vertex; areas from
//! power-of-two-rescaled edge vectors), so densities up to ~1e300 are exact to roundoff.
//! Past that (|φ| below ~1e-150 for a face, a protrusion of height ≳ 55 radii) a density or
//! coordinate would not be representable in f64 and [`ConformalError::OutOfRange`] is
//! returned, never garbage. Protrusions attached along the boundary (a flat alligator's tail)
//! crowd instead towards the circle, 1 − |φ| ≈ 2πu → 0; since f64 resolves only ~1.1e-16 near
//! |z| = 1, an interior vertex with 1 − |φ| < [`CROWDING_LIMIT`] = 1e-14 is an `OutOfRange`
//! error too (it could not be told from the circle). Crowding inside the disk is judged by the
//! outcome: when every construction and repair folds and the Green's map has a triangle whose
//! altitude is below one rounding unit of its coordinates
//! ([`crate::quality::precision_margin`] < 1), the refusal is that `OutOfRange` error, not the
//! folds.

use std::time::Instant;

use serde::Serialize;
use shapespace_geometry::TriMesh;

use crate::error::ConformalError;
use crate::finish::{
    center_image, center_vertex, check_disk, clockwise_edges, count_negative, finish, neighbors, region_repair_note,
    Finished,
};
use crate::fold_repair::FoldRepairInfo;
use crate::green::{boundary_angles_from_flux, green_function, ConjugateSystem};
use crate::intrinsic::IntrinsicTriangulation;
use crate::markers::{resolve_markers, Markers, ResolvedCenter, ResolvedMarkers};
use crate::mobius::Mobius;
use crate::quality::QualitySummary;

pub use crate::finish::CROWDING_LIMIT;

/// Where the Green's function's pole goes (see the module docs for measurements).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize)]
pub enum PolePlacement {
    /// At the center marker p (its vertex, or for a point in a face the interior corner of
    /// largest barycentric weight); a = φ(p) is then 0 or within one triangle of 0.
    AtCenter,
    /// At the central vertex (farthest from the boundary), then the Möbius map sends φ(p) to
    /// 0; falls back to `AtCenter` where the subtraction z − φ(p) would lose digits.
    Central,
}

/// Which construction [`disk_map`] starts from.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize)]
#[serde(rename_all = "lowercase")]
pub enum Construction {
    /// Green's function and harmonic conjugate (default), with the BFF fallback and the region
    /// repair when allowed.
    #[default]
    Green,
    /// Boundary First Flattening iterated to the circle ([`crate::bff::bff_disk_map`]) alone,
    /// with the same normalization, local repair and (when allowed) region repair; `pole` and
    /// `bff_fallback` do not apply.
    Bff,
}

/// Parameters of [`disk_map`].
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct DiskMapParams {
    /// The construction (default [`Construction::Green`]).
    pub construction: Construction,
    /// Build the Laplacian on the intrinsic Delaunay triangulation (default true). Turning it
    /// off gives the plain cotangent Laplacian of the input triangles (for comparisons only:
    /// it folds images of badly shaped meshes).
    pub intrinsic_delaunay: bool,
    /// Where the Green's function has its pole (default [`PolePlacement::AtCenter`]).
    pub pole: PolePlacement,
    /// Repair the few folded original faces by moving one free corner each into the kernel of
    /// its image one-ring ([`crate::fold_repair::local`]; default true). Without it a fold is an error.
    pub repair_folds: bool,
    /// When folds remain after the repair, try Boundary First Flattening ([`crate::bff`]) and
    /// return its map if it has none (default true; only with `repair_folds`).
    /// [`DiskMapInfo::bff_fallback`] then says so. Measured: the slits of
    /// `prepare --seam 1` through the limbs of TOSCA bodies run along zigzag edge paths whose
    /// reflex boundary corners fold 11–254 faces of the Green's-function map (cat1, dog1, dog3,
    /// michael0, wolf2); BFF, which places the boundary by its own scale-factor iteration, maps
    /// those five without a fold.
    pub bff_fallback: bool,
    /// When folds survive the local repair of both constructions (the Green's map and, with
    /// `bff_fallback`, BFF's), re-embed the region around them as a Tutte map
    /// ([`crate::fold_repair`]: untangling, growing regions, retraction towards the conformal
    /// positions) and return that map, recording it in [`DiskMapInfo::region_repair`]
    /// (default true; only with `repair_folds`). The map is then not conformal inside the
    /// region. Measured: the nine Sumner face poses, whose closed mouths are pockets with creases
    /// of angle sums 0.8–3 rad, fold 79–134 faces of BFF's map (1.2–6.1k vertices in the region,
    /// 0.9–1.4k moved, of 29.3k); without the repair eight of the nine were refused.
    pub region_repair: bool,
}

impl Default for DiskMapParams {
    fn default() -> Self {
        DiskMapParams {
            construction: Construction::Green,
            intrinsic_delaunay: true,
            pole: PolePlacement::AtCenter,
            repair_folds: true,
            bff_fallback: true,
            region_repair: true,
        }
    }
}

/// Timings of the stages of [`disk_map`], seconds.
#[derive(Clone, Debug, Default, PartialEq, Serialize)]
pub struct DiskMapTimings {
    /// Validation, half-edges, disk check, marker resolution.
    pub setup: f64,
    /// Intrinsic Delaunay flips.
    pub delaunay: f64,
    /// Green's function solve(s).
    pub green: f64,
    /// Harmonic conjugate solve(s).
    pub conjugate: f64,
    /// Möbius normalization, fold repair, densities, factors, quality.
    pub finish: f64,
    /// Everything.
    pub total: f64,
}

/// What [`disk_map`] did.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct DiskMapInfo {
    /// Name of the construction.
    pub method: String,
    /// Markers after resolution.
    pub markers: ResolvedMarkers,
    /// The vertex used as the pole of the Green's function: the central vertex (farthest from
    /// the boundary), or the center marker's vertex when the Möbius route is not accurate.
    pub pole: u32,
    /// The Möbius normalization applied to the Green's-function map.
    pub mobius: Mobius,
    /// Intrinsic edge flips performed (0 without intrinsic Delaunay).
    pub intrinsic_flips: usize,
    /// Vertices inserted by intrinsic edge splits so that every interior vertex is joined to
    /// the center through interior vertices
    /// ([`IntrinsicTriangulation::connect_interior`]); they take part in the linear solves
    /// only, the map is given at the input vertices.
    pub inserted_vertices: usize,
    /// Interior edges with a negative cotangent weight in the input triangulation.
    pub negative_weights_before: usize,
    /// Same after the intrinsic Delaunay flips (0 unless the flips were disabled).
    pub negative_weights_after: usize,
    /// Vertices moved by the fold repair (0 when the raw map has no fold).
    pub fold_repairs: usize,
    /// Whether the boundary angles came from the normal flux of the log-radius
    /// ([`crate::green::boundary_angles_from_flux`]) because the least-squares conjugate put
    /// boundary vertices out of order on the circle.
    pub boundary_from_flux: bool,
    /// Number of sparse linear solves of the Green's route (2, or 4 when the fallback route was
    /// needed; 0 with [`Construction::Bff`]).
    pub linear_solves: usize,
    /// Stage timings (of the Green's-function route; `total` includes a BFF fallback).
    pub timings: DiskMapTimings,
    /// When the Green's-function map still folded after the repair and BFF's map was returned
    /// instead ([`DiskMapParams::bff_fallback`]): the folds it had and what BFF did. The
    /// `markers`, `mobius`, `intrinsic_flips`, `negative_weights_after` and `fold_repairs`
    /// fields above are then BFF's.
    pub bff_fallback: Option<BffFallback>,
    /// The region repair, when folds survived the local repair ([`DiskMapParams::region_repair`]):
    /// faces folded before it, the region re-embedded, vertices moved and how far.
    pub region_repair: Option<FoldRepairInfo>,
}

/// Why and how [`disk_map`] returned a BFF map ([`DiskMapParams::bff_fallback`]).
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct BffFallback {
    /// Faces the Green's-function map folded after its repair (0 when it put a vertex outside the
    /// circle instead).
    pub green_folds: usize,
    /// BFF's record.
    pub bff: crate::bff::BffInfo,
}

/// A conformal map onto the unit disk with its densities.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct DiskMap {
    /// Image of each vertex, #V; boundary vertices on |z| = 1, p ↦ 0, q ↦ (1, 0).
    pub uv: Vec<[f64; 2]>,
    /// λ per vertex, #V: e^{2λ_i} = (3D one-ring area, surface scaled to area π) / (2D image
    /// one-ring area).
    pub conformal_factor: Vec<f64>,
    /// μ per face, #F: 3D area (scaled to π) / image area; positive and finite.
    pub face_densities: Vec<f64>,
    /// The factor s applied to 3D lengths to reach total area π (s² = π / area).
    pub scale: f64,
    /// Method, markers, timings.
    pub info: DiskMapInfo,
    /// Distortion statistics of the map.
    pub quality: QualitySummary,
}

/// Smallest image distance from φ(p) to its neighbours under the central map for which the
/// Möbius route is used (below, z − a would lose more than 8 of 16 digits).
pub const MOBIUS_MIN_SCALE: f64 = 1e-8;
/// Smallest 1 − |φ(p)| for the Möbius route (its derivative grows like 2/(1 − |a|)).
pub const MOBIUS_MIN_GAP: f64 = 1e-6;

/// Green's function u and conjugate angle θ with the given pole; adds the solve times to
/// `times` = [green, conjugate]. The conjugate's matrix does not depend on u, so it is
/// factorized in parallel with the Green's function solve (rayon::join; the two factorizations
/// are the largest serial steps of the map); "green" is the wall time of that joint stage and
/// "conjugate" the rest (right-hand side, solve, angles at the pole).
fn solve_green_map(
    tri: &IntrinsicTriangulation,
    pole: u32,
    pin: u32,
    times: &mut [f64; 2],
) -> Result<(Vec<f64>, Vec<f64>), ConformalError> {
    let t = Instant::now();
    let (u, conjugate) = rayon::join(|| green_function(tri, pole), || ConjugateSystem::new(tri, pole, pin));
    let (u, conjugate) = (u?, conjugate?);
    times[0] += t.elapsed().as_secs_f64();
    let t = Instant::now();
    let a: Vec<f64> = u.iter().map(|x| -std::f64::consts::TAU * x).collect();
    let theta = conjugate.angle(tri, &a)?;
    times[1] += t.elapsed().as_secs_f64();
    Ok((a, theta))
}

/// z = e^{a + iθ} per vertex (z = 0 at the pole), after the range checks of the module docs:
/// e^{a} must stay a normal f64 with room for areas, and interior vertices must keep
/// 1 − |z| ≥ [`CROWDING_LIMIT`].
fn exp_map(
    a: &[f64],
    theta: &[f64],
    pole: u32,
    is_boundary: &[bool],
    maximum_principle: bool,
) -> Result<Vec<[f64; 2]>, ConformalError> {
    for (v, &x) in a.iter().enumerate() {
        if v as u32 != pole && x < -690.0 {
            return Err(ConformalError::OutOfRange {
                what: "image radius",
                element: format!("vertex {v}"),
                log10_value: x / std::f64::consts::LN_10,
            });
        }
    }
    // boundary crowding: an interior vertex within 1e-14 of the circle is within ~90 ulps of it
    // (the absolute spacing of f64 near 1 is 1.1e-16)
    if let Some((v, &x)) = a
        .iter()
        .enumerate()
        .filter(|(v, _)| !is_boundary[*v] && *v as u32 != pole)
        .max_by(|p, q| p.1.total_cmp(q.1))
    {
        if x.is_nan() {
            return Err(ConformalError::NonFinite {
                stage: "log-radius of the disk map",
                vertex: v,
            });
        }
        if x >= 0.0 && maximum_principle {
            // non-negative weights and a connected interior: the exact solution is < 0 here,
            // so the computed value is within the solve's rounding of 0 (about ε·max|a|)
            let max_abs = a
                .iter()
                .fold(0.0f64, |m, &y| if y.is_finite() { m.max(y.abs()) } else { m });
            return Err(ConformalError::OutOfRange {
                what: "distance of the image to the boundary circle, below the rounding of the harmonic solve (crowding of a protrusion along the boundary)",
                element: format!("vertex {v}"),
                log10_value: (f64::EPSILON * max_abs.max(1.0)).log10(),
            });
        }
        if x >= 0.0 {
            return Err(ConformalError::InteriorOutsideDisk {
                vertex: v,
                radius: x.exp(),
            });
        }
        if -x < CROWDING_LIMIT {
            return Err(ConformalError::OutOfRange {
                what: "distance of the image to the boundary circle (crowding of a protrusion along the boundary)",
                element: format!("vertex {v}"),
                log10_value: (-x).log10(),
            });
        }
    }
    let mut z: Vec<[f64; 2]> = a
        .iter()
        .zip(theta)
        .map(|(&r, &t)| {
            let m = r.exp();
            [m * t.cos(), m * t.sin()]
        })
        .collect();
    z[pole as usize] = [0.0, 0.0];
    Ok(z)
}

/// [`boundary_out_of_order`] from the boundary half-edges of a triangulation (no twin; the
/// intrinsic flips keep them), without building the mesh connectivity.
fn boundary_out_of_order_tri(tri: &IntrinsicTriangulation, uv: &[[f64; 2]]) -> usize {
    let halfedges = (0..tri.tail.len() as u32)
        .filter(|&h| tri.twin[h as usize] == crate::intrinsic::NONE)
        .map(|h| [tri.tail[h as usize], tri.head(h)]);
    clockwise_edges(halfedges, uv)
}

/// The markers [`disk_map`] would use on `mesh`: explicit ones checked, automatic ones
/// resolved ([`crate::markers`]), without mapping. Errors: as [`disk_map`]'s checks of the
/// input (not a disk, degenerate faces) and of the markers.
pub fn resolve_markers_of(mesh: &TriMesh, markers: &Markers) -> Result<ResolvedMarkers, ConformalError> {
    mesh.validate()?;
    let tri = IntrinsicTriangulation::from_mesh(mesh)?;
    check_disk(mesh, &tri)?;
    let adj = neighbors(&tri);
    resolve_markers(mesh, &tri.is_boundary, &adj, markers)
}

/// The discrete Riemann map of `mesh` onto the unit disk with p ↦ 0 and q ↦ 1 (module docs).
///
/// Input: a consistently oriented disk-type mesh (#V positions, #F faces). Output: see
/// [`DiskMap`]. Errors: not a disk, invalid markers, degenerate faces, a folded image (any
/// original face with non-positive image orientation), values beyond the f64 range.
pub fn disk_map(mesh: &TriMesh, markers: &Markers, params: &DiskMapParams) -> Result<DiskMap, ConformalError> {
    let t0 = Instant::now();
    mesh.validate()?;
    shapespace_geometry::topology::check_coordinate_range(mesh)?;
    let mut tri = IntrinsicTriangulation::from_mesh(mesh)?;
    check_disk(mesh, &tri)?;
    let adj = neighbors(&tri);
    let resolved = resolve_markers(mesh, &tri.is_boundary, &adj, markers)?;
    let own_pole = center_vertex(mesh, &tri.is_boundary, resolved.center)?;
    let negative_weights_before = count_negative(&tri);
    if params.construction == Construction::Bff {
        let bff_params = crate::bff::BffParams {
            intrinsic_delaunay: params.intrinsic_delaunay,
            repair_folds: params.repair_folds,
            region_repair: params.repair_folds && params.region_repair,
            ..Default::default()
        };
        let b = crate::bff::bff_disk_map(mesh, markers, &bff_params)?;
        let route = GreenRoute {
            pole: own_pole,
            negative_weights_before,
            boundary_from_flux: false,
            linear_solves: 0,
            timings: DiskMapTimings {
                total: t0.elapsed().as_secs_f64(),
                ..Default::default()
            },
        };
        return Ok(bff_as_disk_map(b, route, None));
    }
    let t1 = Instant::now();
    let inserted_vertices = tri.connect_interior(own_pole, params.intrinsic_delaunay)?;
    let negative_weights_after = count_negative(&tri);
    let n = mesh.num_vertices();
    let t2 = Instant::now();
    // Route 1 (default): Green's function at the central vertex, then the Möbius map sending
    // φ(p) to 0. Route 2 (fallback): Green's function at p itself, used when p lies where the
    // central map is too small to subtract a = φ(p) accurately (a protrusion) or too close to
    // the circle.
    let central = match (&markers.center, resolved.center) {
        // the automatic center is the central vertex (resolved above by the same function)
        (crate::markers::CenterMarker::Auto, ResolvedCenter::Vertex(v)) => v,
        _ => crate::markers::central_vertex(mesh, &tri.is_boundary[..n], &adj)
            .ok_or_else(|| ConformalError::InvalidMarker("the mesh has no interior vertex".into()))?,
    };
    let first_pole = if params.pole == PolePlacement::Central {
        central
    } else {
        own_pole
    };
    let green = green_map(
        mesh,
        &tri,
        &adj,
        &resolved,
        first_pole,
        own_pole,
        negative_weights_after == 0,
    )?;
    let GreenMap {
        z: z_result,
        pole,
        linear_solves,
        boundary_from_flux,
        stage_times,
    } = green;
    let t4 = Instant::now();
    let secs = |a: Instant, b: Instant| (b - a).as_secs_f64();
    let timings_until = |t5: Instant| DiskMapTimings {
        setup: secs(t0, t1),
        delaunay: secs(t1, t2),
        green: stage_times[0],
        conjugate: stage_times[1],
        finish: secs(t4, t5),
        total: secs(t0, t5),
    };
    let (z, first) = match z_result {
        Ok(z) => {
            let first = finish(
                mesh,
                &tri.is_boundary[..n],
                &resolved,
                &z[..n],
                params.repair_folds,
                false,
            );
            (Some(z), first)
        }
        Err(e) => (None, Err(e)),
    };
    let fin = match first {
        Err(e @ (ConformalError::FoldedImage { .. } | ConformalError::InteriorOutsideDisk { .. }))
            if params.repair_folds && (params.bff_fallback || params.region_repair) =>
        {
            let z = z.as_ref().map(|z| &z[..n]);
            match fold_fallback(e, mesh, markers, params, &tri.is_boundary[..n], &resolved, z)? {
                FoldFallback::RegionRepaired(fin) => *fin,
                FoldFallback::Bff {
                    map,
                    green_folds,
                    reason,
                } => {
                    let route = GreenRoute {
                        pole,
                        negative_weights_before,
                        boundary_from_flux,
                        linear_solves,
                        timings: timings_until(Instant::now()),
                    };
                    return Ok(bff_as_disk_map(*map, route, Some((green_folds, reason))));
                }
            }
        }
        other => other?,
    };
    let t5 = Instant::now();
    Ok(DiskMap {
        uv: fin.uv,
        conformal_factor: fin.conformal_factor,
        face_densities: fin.face_densities,
        scale: fin.scale,
        info: DiskMapInfo {
            method: green_method(params.intrinsic_delaunay, pole == central, fin.region_repair.as_ref()),
            markers: resolved,
            pole,
            mobius: fin.mobius,
            intrinsic_flips: tri.num_flips,
            inserted_vertices,
            negative_weights_before,
            negative_weights_after,
            fold_repairs: fin.fold_repairs,
            boundary_from_flux,
            linear_solves,
            timings: timings_until(t5),
            bff_fallback: None,
            region_repair: fin.region_repair,
        },
        quality: fin.quality,
    })
}

/// What follows a Green's-function map that folded after repair (or put a vertex outside the
/// circle): the BFF map (`params.bff_fallback`), else the region repair of the Green's-function
/// map `z` (`params.region_repair`).
enum FoldFallback {
    Bff {
        map: Box<crate::bff::BffDiskMap>,
        green_folds: usize,
        reason: String,
    },
    RegionRepaired(Box<Finished>),
}

/// The fallback after the Green's-function map's error `e` (a fold or a vertex outside the
/// circle): BFF when allowed and it succeeds, else the region repair of `z` when allowed; the
/// refusal otherwise (beyond f64 when the map's crowding is below the rounding of its
/// coordinates, decision 0014; else `e` with what the fallbacks reported).
fn fold_fallback(
    e: ConformalError,
    mesh: &TriMesh,
    markers: &Markers,
    params: &DiskMapParams,
    is_boundary: &[bool],
    resolved: &ResolvedMarkers,
    z: Option<&[[f64; 2]]>,
) -> Result<FoldFallback, ConformalError> {
    let reason = match &e {
        ConformalError::FoldedImage { num_flipped, .. } => {
            format!("the Green's-function map folded {num_flipped} faces after repair")
        }
        ConformalError::InteriorOutsideDisk { vertex, .. } => {
            format!("the Green's-function map put vertex {vertex} outside the circle")
        }
        _ => return Err(e),
    };
    let green_folds = match &e {
        ConformalError::FoldedImage { num_flipped, .. } => *num_flipped,
        _ => 0,
    };
    let mut bff_error = None;
    if params.bff_fallback {
        let bff_params = crate::bff::BffParams {
            intrinsic_delaunay: params.intrinsic_delaunay,
            region_repair: params.region_repair,
            ..Default::default()
        };
        match crate::bff::bff_disk_map(mesh, markers, &bff_params) {
            Ok(map) => {
                return Ok(FoldFallback::Bff {
                    map: Box::new(map),
                    green_folds,
                    reason,
                })
            }
            // BFF fails too: the Green's-function map with the region repair, if allowed
            Err(e) => bff_error = Some(e.to_string()),
        }
    }
    // crowding below the rounding of the coordinates (decision 0014): no construction or
    // repair in f64 can resolve such a map, and that is the refusal to report
    let beyond_f64 = z
        .and_then(|z| crate::quality::precision_margin(mesh, z))
        .filter(|&(_, margin)| margin < 1.0);
    let refusal = |e: ConformalError, region_repair_error: Option<String>| match e {
        _ if beyond_f64.is_some() => {
            let (face, margin) = beyond_f64.expect("checked");
            ConformalError::OutOfRange {
                what: "smallest altitude of an image triangle, in units of the rounding of its coordinates (crowding inside the disk),",
                element: format!("face {face} of the Green's-function map"),
                log10_value: margin.log10(),
            }
        }
        ConformalError::FoldedImage {
            num_flipped,
            first_face,
            flipped_area_fraction,
            boundary_out_of_order,
            ..
        } => ConformalError::FoldedImage {
            num_flipped,
            first_face,
            flipped_area_fraction,
            boundary_out_of_order,
            bff_fallback_error: bff_error.clone(),
            region_repair_error,
        },
        other => other,
    };
    match (z, params.region_repair) {
        (Some(z), true) => match finish(mesh, is_boundary, resolved, z, true, true) {
            Ok(fin) => Ok(FoldFallback::RegionRepaired(Box::new(fin))),
            Err(ConformalError::FoldedImage {
                region_repair_error, ..
            }) => Err(refusal(e, region_repair_error)),
            Err(other) => Err(other),
        },
        _ => Err(refusal(e, None)),
    }
}

/// The method string of a Green's-function map.
fn green_method(intrinsic_delaunay: bool, central_pole: bool, region_repair: Option<&FoldRepairInfo>) -> String {
    format!(
        "green-function ({} cotan Laplacian, least-squares conjugate; {}{})",
        if intrinsic_delaunay {
            "intrinsic Delaunay"
        } else {
            "plain"
        },
        if central_pole {
            "pole at the central vertex, Möbius to the center"
        } else {
            "pole at the center marker"
        },
        region_repair_note(region_repair)
    )
}

/// The Green's-function map and how it was reached: `z` (or why it failed: a vertex outside the
/// circle is, like a fold, a reason for the fallback), the pole finally used (the central vertex
/// `first_pole` gives way to the center marker's own vertex where the central map is too small
/// near the center or the center too close to the circle), the linear solves, whether the
/// boundary angles came from the flux, and the seconds of the Green and conjugate solves.
struct GreenMap {
    z: Result<Vec<[f64; 2]>, ConformalError>,
    pole: u32,
    linear_solves: usize,
    boundary_from_flux: bool,
    stage_times: [f64; 2],
}

/// Route 1 of [`disk_map`] (module docs): Green's function at `first_pole`, its harmonic
/// conjugate, the exponential map, with the fallback to the center marker's vertex and to
/// boundary angles from the flux. `delaunay_weights`: no negative cotangent weight is left.
fn green_map(
    mesh: &TriMesh,
    tri: &IntrinsicTriangulation,
    adj: &[Vec<u32>],
    resolved: &ResolvedMarkers,
    first_pole: u32,
    own_pole: u32,
    delaunay_weights: bool,
) -> Result<GreenMap, ConformalError> {
    let image_of_center = |z: &[[f64; 2]]| center_image(mesh, resolved.center, z);
    // smallest image distance from the center's image to the corners around it
    let local_scale = |z: &[[f64; 2]], a: [f64; 2]| -> f64 {
        let ring: Vec<u32> = match resolved.center {
            ResolvedCenter::Vertex(v) => adj[v as usize].clone(),
            ResolvedCenter::Face { face, .. } => mesh.faces[face as usize].to_vec(),
        };
        ring.iter()
            .map(|&w| (z[w as usize][0] - a[0]).hypot(z[w as usize][1] - a[1]))
            .fold(f64::INFINITY, f64::min)
    };
    let mut pole = first_pole;
    let mut stage_times = [0.0f64; 2];
    let (mut u, mut theta) = solve_green_map(tri, pole, resolved.boundary_vertex, &mut stage_times)?;
    let mut linear_solves = 2;
    let mut boundary_from_flux = false;
    // the Green's map; a vertex outside the circle is, like a fold, a reason for the fallback
    let z_result: Result<Vec<[f64; 2]>, ConformalError> = 'green: {
        let mut z = match exp_map(&u, &theta, pole, &tri.is_boundary, delaunay_weights) {
            Ok(z) => z,
            Err(e) => break 'green Err(e),
        };
        let a_img = image_of_center(&z);
        if pole != own_pole
            && (local_scale(&z, a_img) < MOBIUS_MIN_SCALE || 1.0 - a_img[0].hypot(a_img[1]) < MOBIUS_MIN_GAP)
        {
            pole = own_pole;
            (u, theta) = solve_green_map(tri, pole, resolved.boundary_vertex, &mut stage_times)?;
            linear_solves += 2;
            z = match exp_map(&u, &theta, pole, &tri.is_boundary, delaunay_weights) {
                Ok(z) => z,
                Err(e) => break 'green Err(e),
            };
        }
        // boundary order: the least-squares conjugate can run backwards along an irregular
        // boundary (libigl decimated-max cut open); then the boundary angles come from the flux
        if boundary_out_of_order_tri(tri, &z) > 0 {
            let loops = shapespace_geometry::Connectivity::of(mesh).boundary_loops(&mesh.faces);
            if let Some(boundary_loop) = loops.first() {
                theta = boundary_angles_from_flux(tri, &u, boundary_loop, &theta);
                z = match exp_map(&u, &theta, pole, &tri.is_boundary, delaunay_weights) {
                    Ok(z) => z,
                    Err(e) => break 'green Err(e),
                };
                boundary_from_flux = true;
            }
        }
        Ok(z)
    };
    Ok(GreenMap {
        z: z_result,
        pole,
        linear_solves,
        boundary_from_flux,
        stage_times,
    })
}

/// The Green's route's part of a [`DiskMapInfo`] whose map is BFF's.
struct GreenRoute {
    pole: u32,
    negative_weights_before: usize,
    boundary_from_flux: bool,
    linear_solves: usize,
    timings: DiskMapTimings,
}

/// BFF's map as [`disk_map`]'s result: with `fallback` = (the Green's map's folds, why it was
/// given up) the method string and [`DiskMapInfo::bff_fallback`] say so; without, it is the map
/// of [`Construction::Bff`].
fn bff_as_disk_map(b: crate::bff::BffDiskMap, route: GreenRoute, fallback: Option<(usize, String)>) -> DiskMap {
    let method = match &fallback {
        Some((_, reason)) => format!("{} (fallback: {reason})", b.info.method),
        None => b.info.method.clone(),
    };
    DiskMap {
        uv: b.uv,
        conformal_factor: b.conformal_factor,
        face_densities: b.face_densities,
        scale: b.scale,
        quality: b.quality,
        info: DiskMapInfo {
            method,
            markers: b.info.markers,
            pole: route.pole,
            mobius: b.info.mobius,
            intrinsic_flips: b.info.intrinsic_flips,
            inserted_vertices: b.info.inserted_vertices,
            negative_weights_before: route.negative_weights_before,
            negative_weights_after: b.info.negative_weights_after,
            fold_repairs: b.info.fold_repairs,
            boundary_from_flux: route.boundary_from_flux,
            linear_solves: route.linear_solves,
            timings: route.timings,
            region_repair: b.info.region_repair.clone(),
            bff_fallback: fallback.map(|(green_folds, _)| BffFallback {
                green_folds,
                bff: b.info,
            }),
        },
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::finish::boundary_out_of_order;

    /// An interior log-radius ≥ 0: with non-negative weights (and a connected interior) the
    /// exact value is < 0, so it is crowding below the rounding of the solve; with negative
    /// weights the maximum principle itself may fail. Just below 0 (above −1e-14): crowding.
    #[test]
    fn interior_log_radius_at_or_above_zero_is_classified() {
        let theta = [0.0, 0.5, 1.0];
        let is_boundary = [false, false, true];
        for (x, maximum_principle, crowding) in [
            (1e-17, true, true),
            (0.0, true, true),
            (1e-17, false, false),
            (-1e-15, false, true),
        ] {
            let a = [-3.0, x, 0.0];
            match exp_map(&a, &theta, 0, &is_boundary, maximum_principle) {
                Err(ConformalError::OutOfRange {
                    element, log10_value, ..
                }) => {
                    assert!(crowding, "{x} {maximum_principle}");
                    assert_eq!(element, "vertex 1");
                    assert!(log10_value < -14.0, "{log10_value}");
                }
                Err(ConformalError::InteriorOutsideDisk { vertex: 1, radius }) => {
                    assert!(!crowding, "{x} {maximum_principle}");
                    assert!(radius >= 1.0);
                }
                other => panic!("{x} {maximum_principle}: {other:?}"),
            }
        }
        // a regular interior value passes
        let z = exp_map(&[-3.0, -0.5, 0.0], &theta, 0, &is_boundary, true).unwrap();
        assert_eq!(z[0], [0.0, 0.0]);
        assert!(((z[1][0].hypot(z[1][1])) - (-0.5f64).exp()).abs() < 1e-15);
        // 1e-12 from the circle is within the limit (1 − |z| is then 1e4 ulps of 1)
        let z = exp_map(&[-3.0, -1e-12, 0.0], &theta, 0, &is_boundary, true).unwrap();
        assert!(1.0 - z[1][0].hypot(z[1][1]) > 0.5e-12);
    }

    /// Two neighbouring boundary vertices swapped on the circle: exactly the edge between them
    /// runs clockwise.
    #[test]
    fn boundary_edges_running_clockwise_are_counted() {
        let mesh = shapespace_geometry::primitives::unit_disk(3);
        let mut uv: Vec<[f64; 2]> = mesh.positions.iter().map(|p| [p[0], p[1]]).collect();
        let tri = IntrinsicTriangulation::from_mesh(&mesh).unwrap();
        assert_eq!(boundary_out_of_order(&mesh, &uv), 0);
        assert_eq!(boundary_out_of_order_tri(&tri, &uv), 0);
        let loop0 = shapespace_geometry::Connectivity::of(&mesh).boundary_loops(&mesh.faces)[0].clone();
        uv.swap(loop0[4] as usize, loop0[5] as usize);
        assert_eq!(boundary_out_of_order(&mesh, &uv), 1);
        assert_eq!(boundary_out_of_order_tri(&tri, &uv), 1);
    }
}
