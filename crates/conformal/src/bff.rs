//! Boundary First Flattening onto the unit disk (Sawhney & Crane 2017, "Boundary First
//! Flattening", ACM TOG 37(1), art. 5; the "uniformization over the disk" application).
//!
//! BFF computes a flat metric e^{2u}·g conformal to the surface metric g by prescribing data
//! on the boundary only. Discretely (intrinsic Delaunay cotangent Laplacian L, positive
//! semidefinite, [`crate::intrinsic`]):
//! * **curvatures.** Interior angle defects K_i = 2π − Σ_corners θ and boundary exterior
//!   angles (integrated geodesic curvature) k_i = π − Σ_corners θ; Σ K + Σ k = 2π (discrete
//!   Gauss–Bonnet, exact);
//! * **discrete Cherrier formula** (BFF's Yamabe/Cherrier equation): scaling by e^{u} changes
//!   the curvatures to
//!   $$ \tilde K_I = K_I + (L u)_I, \qquad \tilde k_B = k_B + (L u)_B ; $$
//! * **Neumann-to-Dirichlet map** (one of BFF's two Poincaré–Steklov operators): the flat
//!   metric (K̃ = 0) with boundary curvature k̃ (Σ k̃ = 2π) has the scale factors u solving
//!   $$ L u = \begin{pmatrix} -K_I \\ \tilde k_B - k_B \end{pmatrix}, $$
//!   determined up to a constant; here one vertex is pinned (u = 0 there, which drops the
//!   redundant row: the right-hand side sums to 0), so the matrix is SPD and is factorized once;
//! * **disk target** (BFF's uniformization): the boundary curvature of a circle through the
//!   flattened boundary polygon is proportional to the dual boundary length under the new
//!   metric,
//!   $$ \tilde\ell_{ij} = e^{(u_i + u_j)/2}\,\ell_{ij}, \qquad
//!   \tilde k_i = 2\pi\,\frac{\tfrac12(\tilde\ell_{i-1,i} + \tilde\ell_{i,i+1})}{\sum \tilde\ell} ,$$
//!   which depends on u, so u and k̃ are iterated (boundary values only; the interior values
//!   of u are not needed): u⁰ = 0, k̃ⁿ from uⁿ, û from the Neumann-to-Dirichlet map of k̃ⁿ,
//!   uⁿ⁺¹ = uⁿ + (I − P)(û − uⁿ), until max_B |(I − P)(û − uⁿ)| < `tolerance`. P is the
//!   weighted least-squares projection onto span{1, cos ψ, sin ψ} (ψ the current boundary
//!   angles): the global scale and, to first order, the Möbius automorphisms of the disk,
//!   log|M'(e^{iψ})| = 2 Re(ā e^{iψ}) + O(|a|²). The published code stops after a fixed 10
//!   iterations. Linearized at a circle, boundary Fourier mode m of the error is multiplied by
//!   1/|m| per iteration (the Neumann-to-Dirichlet map of a circle), so m = 2 contracts by ½
//!   (observed: residual ratio ≈ 0.5; 7–20 iterations to 1e-11 on caps, 28–38 on real
//!   meshes and on f(D)) while m = ±1 does not contract at all: without P the iterates drift along the
//!   Möbius orbit (measured: the residual stalls at 2e-4 … 8e-4 on real meshes and at 4e-9 on
//!   a 331-vertex cap). With P they converge geometrically to roundoff; the Möbius part left
//!   in u is removed exactly by the marker normalization;
//! * **boundary curve.** Boundary vertex b_j (counter-clockwise from the start vertex) goes to
//!   e^{iψ_j}, ψ_j = 2π Σ_{i<j} ℓ̃_i / Σ ℓ̃: the inscribed polygon with central angles
//!   α_i = 2πℓ̃_i/Σℓ̃ has exterior angle ½(α_{i−1} + α_i) = k̃_i at b_i, i.e. exactly the target
//!   curvature, and lies on the unit circle (the published best-fit curve differs from it by
//!   O(h²) in the edge lengths and is only approximately circular);
//! * **extension** (BFF's disk mode extends both coordinates harmonically): L_II x_I = −L_IB x_B
//!   for x = Re z and y = Im z (one more factorization, two right-hand sides). With the
//!   non-negative weights of the intrinsic Delaunay Laplacian and a convex boundary polygon
//!   this is a Tutte-type embedding of the intrinsic triangulation (no fold there; the original
//!   faces are checked separately, as for the Green's-function map).
//!
//! [`bff_disk_coordinates`] returns these raw disk coordinates; [`bff_disk_map`] adds marker
//! resolution, the Möbius normalization p ↦ 0, q ↦ 1, fold repair, densities and conformal
//! factors exactly as [`crate::disk_map()`] does, so the two constructions are compared like with
//! like (measurements: `docs/decisions/0001-green-function-disk-map.md`).

use std::f64::consts::{PI, TAU};
use std::time::Instant;

use serde::Serialize;
use shapespace_geometry::TriMesh;

use crate::error::ConformalError;
use crate::finish::{center_vertex, check_disk, count_negative, finish, neighbors, CROWDING_LIMIT};
use crate::intrinsic::{next, prev, triangle_area_from_lengths, IntrinsicTriangulation, NONE};
use crate::linsolve::restricted_laplacian;
use crate::markers::{resolve_markers, Markers, ResolvedMarkers};
use crate::mobius::Mobius;
use crate::quality::QualitySummary;

/// Parameters of [`bff_disk_map`] and [`bff_disk_coordinates`].
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct BffParams {
    /// Build the Laplacian on the intrinsic Delaunay triangulation (default true; as for
    /// [`crate::DiskMapParams::intrinsic_delaunay`]).
    pub intrinsic_delaunay: bool,
    /// Largest number of scale-factor iterations (default 200).
    pub max_iterations: usize,
    /// Stop when the update of the boundary scale factors without its scale and Möbius
    /// modes, max_B |(I − P)δu|, is below this (default 1e-11; module docs).
    pub tolerance: f64,
    /// Repair isolated folded original faces as [`crate::disk_map()`] does (default true).
    pub repair_folds: bool,
    /// Smallest accepted 1 − |z| at an interior vertex of the normalized map (default
    /// [`CROWDING_LIMIT`] = 1e-14, the limit of [`crate::disk_map()`]); below it the result is
    /// [`ConformalError::OutOfRange`]. 0 disables the check (for measurements: the map is
    /// then returned even where f64 cannot resolve its shape).
    pub crowding_limit: f64,
    /// Re-embed the region around folds that survive the local repair
    /// ([`crate::DiskMapParams::region_repair`]; default true, only with `repair_folds`).
    pub region_repair: bool,
}

impl Default for BffParams {
    fn default() -> Self {
        BffParams {
            intrinsic_delaunay: true,
            max_iterations: 200,
            tolerance: 1e-11,
            repair_folds: true,
            crowding_limit: CROWDING_LIMIT,
            region_repair: true,
        }
    }
}

/// Raw BFF disk coordinates (before the marker normalization).
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct BffCoordinates {
    /// Image of each vertex, #V: boundary vertices exactly on |z| = 1 (the start vertex at
    /// (1, 0)), interior vertices inside.
    pub z: Vec<[f64; 2]>,
    /// Boundary log scale factors u of the flat metric e^{2u}g, in boundary-loop order from
    /// the start vertex, before the rescaling to the unit circle (up to a constant).
    pub boundary_log_scale: Vec<f64>,
    /// Scale-factor iterations performed.
    pub iterations: usize,
    /// max_B |(I − P)δu| after each iteration (module docs).
    pub residuals: Vec<f64>,
    /// Seconds: factorizations, iterations, extension.
    pub timings: [f64; 3],
}

/// Timings of [`bff_disk_map`], seconds.
#[derive(Clone, Debug, Default, PartialEq, Serialize)]
pub struct BffTimings {
    /// Validation, half-edges, disk check, marker resolution.
    pub setup: f64,
    /// Intrinsic Delaunay flips.
    pub delaunay: f64,
    /// The two sparse Cholesky factorizations (Neumann and Dirichlet Laplacians).
    pub factorize: f64,
    /// The scale-factor iterations (one back substitution each).
    pub iterate: f64,
    /// Boundary placement and the harmonic extension.
    pub extend: f64,
    /// Möbius normalization, fold repair, densities, factors, quality.
    pub finish: f64,
    /// Everything.
    pub total: f64,
}

/// What [`bff_disk_map`] did.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct BffInfo {
    /// Name of the construction.
    pub method: String,
    /// Markers after resolution.
    pub markers: ResolvedMarkers,
    /// The Möbius normalization applied to the raw BFF disk coordinates.
    pub mobius: Mobius,
    /// Scale-factor iterations performed.
    pub iterations: usize,
    /// max_B |(I − P)δu| after each iteration (module docs).
    pub residuals: Vec<f64>,
    /// Intrinsic edge flips performed (0 without intrinsic Delaunay).
    pub intrinsic_flips: usize,
    /// Vertices inserted by intrinsic edge splits
    /// ([`crate::intrinsic::IntrinsicTriangulation::connect_interior`]).
    pub inserted_vertices: usize,
    /// Interior edges with a negative cotangent weight after the flips.
    pub negative_weights_after: usize,
    /// Vertices moved by the fold repair.
    pub fold_repairs: usize,
    /// The region repair of folds left by the local one ([`BffParams::region_repair`]).
    pub region_repair: Option<crate::fold_repair::FoldRepairInfo>,
    /// Smallest 1 − |z| over the interior vertices of the normalized map (boundary crowding).
    pub min_interior_gap: f64,
    /// Stage timings.
    pub timings: BffTimings,
}

/// A BFF conformal map onto the unit disk with its densities (the fields mean what they mean
/// in [`crate::DiskMap`]).
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct BffDiskMap {
    /// Image of each vertex, #V; boundary vertices on |z| = 1, p ↦ 0, q ↦ (1, 0).
    pub uv: Vec<[f64; 2]>,
    /// λ per vertex, #V (as [`crate::DiskMap::conformal_factor`]).
    pub conformal_factor: Vec<f64>,
    /// μ per face, #F (as [`crate::DiskMap::face_densities`]).
    pub face_densities: Vec<f64>,
    /// The factor applied to 3D lengths to reach total area π.
    pub scale: f64,
    /// Iterations, markers, timings.
    pub info: BffInfo,
    /// Distortion statistics of the map.
    pub quality: QualitySummary,
}

/// The boundary loop of a disk starting at `start`, in the direction of its half-edges
/// (counter-clockwise: the faces are on the left). Returns the vertices and the length of the
/// edge from each vertex to the next.
fn boundary_loop(tri: &IntrinsicTriangulation, start: u32) -> Result<(Vec<u32>, Vec<f64>), ConformalError> {
    let n = tri.num_vertices;
    let mut out = vec![NONE; n];
    for h in 0..tri.tail.len() {
        if tri.twin[h] == NONE {
            let t = tri.tail[h] as usize;
            if out[t] != NONE {
                return Err(ConformalError::NotDisk {
                    reason: format!("non-manifold boundary vertex {t}"),
                });
            }
            out[t] = h as u32;
        }
    }
    if start as usize >= n || out[start as usize] == NONE {
        return Err(ConformalError::InvalidMarker(format!(
            "BFF start vertex {start} is not a boundary vertex"
        )));
    }
    let (mut verts, mut lens) = (Vec::new(), Vec::new());
    let mut v = start;
    loop {
        let h = out[v as usize];
        if h == NONE || verts.len() > n {
            return Err(ConformalError::NotDisk {
                reason: "the boundary loop through the start vertex does not close".into(),
            });
        }
        verts.push(v);
        lens.push(tri.length[h as usize]);
        v = tri.head(h);
        if v == start {
            break;
        }
    }
    if verts.len() < 3 {
        return Err(ConformalError::NotDisk {
            reason: format!("a boundary loop of {} vertices", verts.len()),
        });
    }
    Ok((verts, lens))
}

/// δ − P δ, where P is the weighted least-squares projection (weights: the dual boundary
/// lengths ½(ℓ̃_{i−1,i} + ℓ̃_{i,i+1})) onto span{1, cos ψ, sin ψ}, ψ the boundary angles of the
/// scaled arc length `lt`. These three modes are, to first order, the global scale and the
/// infinitesimal Möbius automorphisms of the disk (log|M'(e^{iψ})| = 2 Re(ā e^{iψ}) + O(|a|²)),
/// which the marker normalization removes anyway.
fn remove_mobius_modes(delta: &[f64], lt: &[f64]) -> Vec<f64> {
    let nb = delta.len();
    let total: f64 = lt.iter().sum();
    let mut ata = [[0.0f64; 3]; 3];
    let mut atb = [0.0f64; 3];
    let mut basis = Vec::with_capacity(nb);
    let mut acc = 0.0;
    for i in 0..nb {
        let psi = TAU * acc / total;
        acc += lt[i];
        let w = 0.5 * (lt[(i + nb - 1) % nb] + lt[i]);
        let b = [1.0, psi.cos(), psi.sin()];
        for r in 0..3 {
            for c in 0..3 {
                ata[r][c] += w * b[r] * b[c];
            }
            atb[r] += w * b[r] * delta[i];
        }
        basis.push(b);
    }
    let coef = solve3(ata, atb).unwrap_or([delta.iter().sum::<f64>() / nb as f64, 0.0, 0.0]);
    delta
        .iter()
        .zip(&basis)
        .map(|(d, b)| d - coef[0] * b[0] - coef[1] * b[1] - coef[2] * b[2])
        .collect()
}

/// Solves a 3×3 system by Cramer's rule (None when singular).
fn solve3(a: [[f64; 3]; 3], b: [f64; 3]) -> Option<[f64; 3]> {
    let det = |m: [[f64; 3]; 3]| {
        m[0][0] * (m[1][1] * m[2][2] - m[1][2] * m[2][1]) - m[0][1] * (m[1][0] * m[2][2] - m[1][2] * m[2][0])
            + m[0][2] * (m[1][0] * m[2][1] - m[1][1] * m[2][0])
    };
    let d = det(a);
    if !(d.abs() > 0.0) || !d.is_finite() {
        return None;
    }
    let mut x = [0.0; 3];
    for k in 0..3 {
        let mut m = a;
        for r in 0..3 {
            m[r][k] = b[r];
        }
        x[k] = det(m) / d;
    }
    Some(x)
}

/// Raw BFF disk coordinates of the intrinsic triangulation `tri` of a disk (module docs):
/// boundary on the unit circle with `start` at (1, 0), interior by harmonic extension.
///
/// Errors: `start` not on the boundary, a boundary that is not one closed loop, a failed
/// factorization, non-finite values, no convergence within `params.max_iterations`.
pub fn bff_disk_coordinates(
    tri: &IntrinsicTriangulation,
    start: u32,
    params: &BffParams,
) -> Result<BffCoordinates, ConformalError> {
    let n = tri.num_vertices;
    let (bverts, blen) = boundary_loop(tri, start)?;
    let nb = bverts.len();
    if nb == n {
        return Err(ConformalError::InvalidMarker("the mesh has no interior vertex".into()));
    }
    // angle sums from the lengths: angle at tail(h) is opposite next(h)
    let mut angle_sum = vec![0.0; n];
    for h in 0..tri.tail.len() as u32 {
        let e = tri.length[next(h) as usize];
        let (a, b) = (tri.length[h as usize], tri.length[prev(h) as usize]);
        let area = triangle_area_from_lengths(e, a, b);
        angle_sum[tri.tail[h as usize] as usize] += (4.0 * area).atan2(a * a + b * b - e * e);
    }
    // κ: K = 2π − Σθ inside, k = π − Σθ on the boundary
    let kappa: Vec<f64> = (0..n)
        .map(|v| if tri.is_boundary[v] { PI } else { TAU } - angle_sum[v])
        .collect();

    let t0 = Instant::now();
    // Neumann Laplacian with the start vertex pinned
    let mut idx_n = vec![u32::MAX; n];
    let mut m = 0usize;
    for v in 0..n {
        if v as u32 != start {
            idx_n[v] = m as u32;
            m += 1;
        }
    }
    let (neumann, _) = restricted_laplacian(tri, &idx_n, m, "the Neumann Laplacian (BFF scale factors)")?;
    // Dirichlet Laplacian on the interior vertices
    let mut idx_d = vec![u32::MAX; n];
    let mut mi = 0usize;
    for v in 0..n {
        if !tri.is_boundary[v] {
            idx_d[v] = mi as u32;
            mi += 1;
        }
    }
    let (dirichlet, coupling) =
        restricted_laplacian(tri, &idx_d, mi, "the Dirichlet Laplacian (BFF harmonic extension)")?;
    let t1 = Instant::now();

    // scale-factor iteration on the boundary values ub (ub[i] = u at bverts[i])
    let scaled_lengths = |ub: &[f64]| -> Vec<f64> {
        (0..nb)
            .map(|i| (0.5 * (ub[i] + ub[(i + 1) % nb])).exp() * blen[i])
            .collect()
    };
    let mut ub = vec![0.0; nb];
    let mut residuals = Vec::new();
    let mut converged = false;
    let mut rhs = vec![0.0; m];
    for v in 0..n {
        if idx_n[v] != u32::MAX && !tri.is_boundary[v] {
            rhs[idx_n[v] as usize] = -kappa[v];
        }
    }
    for _ in 0..params.max_iterations {
        let lt = scaled_lengths(&ub);
        let total: f64 = lt.iter().sum();
        for i in 0..nb {
            let v = bverts[i] as usize;
            let k_target = PI * (lt[(i + nb - 1) % nb] + lt[i]) / total;
            if idx_n[v] != u32::MAX {
                rhs[idx_n[v] as usize] = k_target - kappa[v];
            }
        }
        let mut cols = vec![rhs.clone()];
        neumann.solve(&mut cols);
        let mut delta = vec![0.0; nb];
        for i in 0..nb {
            let v = bverts[i] as usize;
            let new = if idx_n[v] != u32::MAX {
                cols[0][idx_n[v] as usize]
            } else {
                0.0
            };
            if !new.is_finite() {
                return Err(ConformalError::NonFinite {
                    stage: "BFF scale factors",
                    vertex: v,
                });
            }
            delta[i] = new - ub[i];
        }
        // the update without its scale and first-order Möbius modes (see remove_mobius_modes)
        let step = remove_mobius_modes(&delta, &lt);
        let r = step.iter().fold(0.0f64, |a, x| a.max(x.abs()));
        for i in 0..nb {
            ub[i] += step[i];
        }
        residuals.push(r);
        if r < params.tolerance {
            converged = true;
            break;
        }
    }
    if !converged {
        return Err(ConformalError::NoConvergence {
            what: "BFF boundary scale factors",
            iterations: residuals.len(),
            residual: residuals.last().copied().unwrap_or(f64::NAN),
        });
    }
    let t2 = Instant::now();

    // boundary on the unit circle by the scaled arc length, then the harmonic extension
    let lt = scaled_lengths(&ub);
    let total: f64 = lt.iter().sum();
    let mut z = vec![[0.0, 0.0]; n];
    let mut acc = 0.0;
    for i in 0..nb {
        let psi = TAU * acc / total;
        z[bverts[i] as usize] = [psi.cos(), psi.sin()];
        acc += lt[i];
    }
    let mut cols = vec![vec![0.0; mi], vec![0.0; mi]];
    for &(row, v, w) in &coupling {
        cols[0][row as usize] += w * z[v as usize][0];
        cols[1][row as usize] += w * z[v as usize][1];
    }
    dirichlet.solve(&mut cols);
    for v in 0..n {
        if idx_d[v] != u32::MAX {
            let p = [cols[0][idx_d[v] as usize], cols[1][idx_d[v] as usize]];
            if !(p[0].is_finite() && p[1].is_finite()) {
                return Err(ConformalError::NonFinite {
                    stage: "BFF harmonic extension",
                    vertex: v,
                });
            }
            z[v] = p;
        }
    }
    let t3 = Instant::now();
    Ok(BffCoordinates {
        z,
        boundary_log_scale: ub,
        iterations: residuals.len(),
        residuals,
        timings: [
            (t1 - t0).as_secs_f64(),
            (t2 - t1).as_secs_f64(),
            (t3 - t2).as_secs_f64(),
        ],
    })
}

/// The conformal map of `mesh` onto the unit disk with p ↦ 0 and q ↦ 1 by Boundary First
/// Flattening (module docs), normalized and finished exactly like [`crate::disk_map()`].
///
/// Input: a consistently oriented disk-type mesh. Errors: not a disk, invalid markers,
/// degenerate faces, no convergence, a folded image left after the repair, values beyond the
/// f64 range, an interior vertex within `params.crowding_limit` of the circle.
pub fn bff_disk_map(mesh: &TriMesh, markers: &Markers, params: &BffParams) -> Result<BffDiskMap, ConformalError> {
    let t0 = Instant::now();
    mesh.validate()?;
    shapespace_geometry::topology::check_coordinate_range(mesh)?;
    let mut tri = IntrinsicTriangulation::from_mesh(mesh)?;
    check_disk(mesh, &tri)?;
    let adj = neighbors(&tri);
    let resolved = resolve_markers(mesh, &tri.is_boundary, &adj, markers)?;
    let t1 = Instant::now();
    let center = center_vertex(mesh, &tri.is_boundary, resolved.center)?;
    let inserted_vertices = tri.connect_interior(center, params.intrinsic_delaunay)?;
    let negative_weights_after = count_negative(&tri);
    let t2 = Instant::now();
    let raw = bff_disk_coordinates(&tri, resolved.boundary_vertex, params)?;
    let t3 = Instant::now();
    let n = mesh.num_vertices();
    let fin = finish(
        mesh,
        &tri.is_boundary[..n],
        &resolved,
        &raw.z[..n],
        params.repair_folds,
        params.region_repair,
    )?;
    // boundary crowding (module docs of crate::disk_map): the same limit as the Green's map
    let (gap_vertex, min_interior_gap) = fin
        .uv
        .iter()
        .enumerate()
        .filter(|(v, _)| !tri.is_boundary[*v])
        .map(|(v, p)| (v, 1.0 - p[0].hypot(p[1])))
        .fold((0, f64::INFINITY), |a, b| if b.1 < a.1 { b } else { a });
    if min_interior_gap < params.crowding_limit {
        return Err(ConformalError::OutOfRange {
            what: "distance of the image to the boundary circle (crowding of a protrusion along the boundary)",
            element: format!("vertex {gap_vertex}"),
            log10_value: min_interior_gap.max(f64::MIN_POSITIVE).log10(),
        });
    }
    let t4 = Instant::now();
    let secs = |a: Instant, b: Instant| (b - a).as_secs_f64();
    Ok(BffDiskMap {
        uv: fin.uv,
        conformal_factor: fin.conformal_factor,
        face_densities: fin.face_densities,
        scale: fin.scale,
        info: BffInfo {
            method: format!(
                "bff-disk ({} cotan Laplacian, scale factors iterated to {:.0e}, harmonic extension{})",
                if params.intrinsic_delaunay {
                    "intrinsic Delaunay"
                } else {
                    "plain"
                },
                params.tolerance,
                crate::finish::region_repair_note(fin.region_repair.as_ref())
            ),
            markers: resolved,
            mobius: fin.mobius,
            iterations: raw.iterations,
            residuals: raw.residuals,
            intrinsic_flips: tri.num_flips,
            inserted_vertices,
            negative_weights_after,
            fold_repairs: fin.fold_repairs,
            region_repair: fin.region_repair,
            min_interior_gap,
            timings: BffTimings {
                setup: secs(t0, t1),
                delaunay: secs(t1, t2),
                factorize: raw.timings[0],
                iterate: raw.timings[1],
                extend: raw.timings[2],
                finish: secs(t3, t4),
                total: secs(t0, t4),
            },
        },
        quality: fin.quality,
    })
}
