//! Repair of folded triangles of planar disk maps, at two scales: [`local`] for the conformal
//! map's rare folded slivers (a corner moved into the kernel of its image one-ring, else a small
//! Tutte patch; the map stays conformal away from the moved vertices), and this module's region
//! repair ([`repair_folds_with`]) for maps with many folds, the area-preserving maps' and the
//! registration's, by local Tutte/Floater re-embedding [Tutte 1963, "How to draw a graph";
//! Floater 2003, "One-to-one piecewise linear mappings over triangulations", Thm. 1; Floater
//! 2003, "Mean value coordinates"]. The conformal map falls back on the region repair when the
//! local one leaves folds (`docs/decisions/0026-disk-map-region-repair.md`), and the sphere's
//! repair applies the local one in stereographic charts. [`untangle_foldover_free`] (the
//! regularized Winslow energy of Garanzha et al. 2021, every free vertex moved at once) is not
//! part of the region repair: the sphere's chart repair calls it on a chart whose Tutte repair
//! failed (`docs/decisions/0051-foldover-free-untangling-in-sphere-charts.md`).
//!
//! Input: a map `uv` (#V) of a disk-type mesh whose boundary vertices lie on a convex curve
//! (the unit circle or the square) in counter-clockwise order, with some faces folded (clockwise
//! or degenerate image). Every interior vertex i gets strictly positive weights $w_{ij}$ over its
//! neighbours, normalized to $\sum_j w_{ij} = 1$. A region R of interior vertices is re-solved
//! as a convex-combination (Tutte) map with everything outside R fixed at its input position:
//! $$ x_i - \sum_{j \in R} w_{ij} x_j = \sum_{j \notin R} w_{ij}\, x_j \qquad (i \in R), $$
//! a sparse, row-diagonally dominant system (every connected component of R touches a fixed
//! vertex) solved by faer's sparse LU, one system per connected component, in coordinates
//! relative to the mean of the component's fixed neighbours (keeps relative precision in small
//! regions). The components are solved in parallel, and a component that did not change since
//! the previous round is taken from it (TOSCA michael1 slit: repair 0.96 → 0.72 s, the same
//! map bit for bit).
//!
//! Untangling first: [`untangle_kernels`] (Gauss–Seidel, a corner of a folded face moves into
//! the kernel of its star when that lowers the folds around it) runs for up to
//! `untangle_sweeps` sweeps. It undoes most isolated folds by moving a few vertices, and it
//! removes 75–80 % of the folds of the TOSCA meshes (horse0: 1279 → 316, Nefertiti cut open:
//! 1885 → 434). What it leaves goes to the Tutte rounds below, with the untangled map as
//! their input; without this step the Tutte rounds start from more folds, their region grows
//! larger, and the retraction leaves more vertices displaced (measured with
//! `examples/repair_probe.rs`: |Υ| median / p95 of the repaired map on wolf0 0.366 / 1.164 →
//! 0.275 / 1.168, horse0 0.417 / 1.386 → 0.365 / 1.297, Nefertiti 0.538 / 1.288 →
//! 0.483 / 1.190).
//!
//! Rounds: R starts as the folded faces' vertices grown by k rings (k = `initial_rings`), only
//! interior vertices (boundary vertices never move). After each solve the faces are checked;
//! if some are still folded, R grows by 2k rings around them (R only grows, the solve restarts
//! from the input positions) and k doubles. Once R holds every interior vertex, the fixed
//! vertices are exactly the boundary polygon, which is convex, and Floater's theorem (strictly
//! positive weights, convex boundary polygon, boundary in order) makes the solution an
//! embedding: the loop ends after at most ⌈log₂(diameter in rings)⌉ + 1 rounds. A whole-disk
//! solve that still folds (floating point, or a boundary that is not convex: the sphere's chart
//! repair fixes the boundary of a patch where the map has put it) is untangled by the kernel
//! moves above, then retried with [`RepairWeights::Surface`] and untangled again; if folds
//! remain, the repair fails with a typed error instead of returning a folded map. (The
//! charts of the Sumner cats' sphere maps: whole-patch solves leave 1–100 faces folded, and
//! the kernel moves undo a few of them completely; with the sphere repair's second passes
//! this unfolds cats 0002 and 0006, `docs/decisions/0048-untangle-the-whole-patch-solve.md`.)
//!
//! Retraction: the Tutte solve moves the whole region (its displacement solves a Laplace-like
//! equation with sources at the folded stars, so it spreads over R). Afterwards, Gauss–Seidel
//! sweeps move each region vertex back along the segment towards its input position, by the
//! largest step 1, ½, …, 1/32 that keeps every face around it valid and no smaller than
//! min(its current area, e^{-τ}·its share of the 3D area, its input area if that face was
//! valid); faces never fold, so the map stays an embedding, and vertices away from the folds
//! return exactly. The floor τ keeps the retraction from squeezing slivers against the
//! repaired folds (without it, wolf0's |Υ| p95 rises from 1.18 to 3.4). A vertex is tried
//! again only after it or a vertex of its star moved (its trials would otherwise see the same
//! faces and fail again), and the faces' areas are kept between sweeps: the same sweeps and the
//! same result as trying every vertex every sweep, 3–4× faster on the TOSCA horse (141 sweeps
//! over 19k vertices: 2.9 → 0.7 s). The connected components of R share no face, so each is
//! retracted on its own, in parallel, with the same result (TOSCA michael1 slit: components of
//! 9.0k, 8.9k and 4.4k vertices, 0.21 → 0.13 s).
//!
//! Weights (both are mean-value weights $w_{ij} \propto (\tan\frac{\alpha_{ij}}2 +
//! \tan\frac{\beta_{ij}}2)/\lVert x_j - x_i\rVert$, α, β the angles at i of the two faces at the
//! edge ij, Floater's mean value coordinates; the angles are unsigned, in [0, π], so the weights
//! are ≥ 0 on any layout):
//! - [`RepairWeights::Layout`] (default): measured on the input map `uv` itself. On a vertex
//!   whose one-ring is embedded (star-shaped around it) these are its mean value coordinates,
//!   which reproduce its position exactly; so wherever the input is already an embedding, the
//!   Tutte map reproduces it, and the area-preserving layout changes only near the folds.
//!   Weights are floored at 1e-12 of the largest weight of their row (strict positivity); a
//!   row that is not finite (coincident or straight-angle neighbours) takes the surface weights.
//! - [`RepairWeights::Surface`]: measured on the 3D mesh (a discrete harmonic-like map; it
//!   ignores the area-preserving layout inside R).
//!
//! Validity of a face: the exact orientation predicate ([`orient_scaled`]) says
//! counter-clockwise, and its doubled area, computed from power-of-two scaled edge vectors,
//! is at least 1e-300 (relative to the unit disk / square of area π); anything else is folded.

use std::collections::VecDeque;

use rayon::prelude::*;

use crate::quality::{orient_scaled, power_of_two_scale};
use faer::dyn_stack::{MemBuffer, MemStack, StackReq};
use faer::sparse::linalg::lu::{factorize_symbolic_lu, LuSymbolicParams, NumericLu};
use faer::sparse::linalg::SupernodalThreshold;
use faer::sparse::{SparseColMat, SparseColMatRef, Triplet};
use faer::{Conj, Par};
use geogram_predicates::Sign;
use serde::Serialize;
use shapespace_geometry::quantities::face_areas;
use shapespace_geometry::{Connectivity, TriMesh};

mod foldover_free;
pub mod local;
mod retract;
#[cfg(test)]
mod tests;
mod tutte;
mod untangle;
mod weights;

pub use foldover_free::{
    reference_equilateral, reference_from_layout, reference_from_surface, untangle_foldover_free, FoldoverFreeInfo,
    FoldoverFreeParams,
};
use retract::*;
pub use tutte::mean_value_tutte_map;
use tutte::*;
pub use untangle::{untangle_kernels, UntangleInfo};
use weights::*;

use crate::error::ConformalError;

/// Smallest doubled image area of a valid face (relative to a domain of area π).
pub const MIN_DOUBLED_AREA: f64 = 1e-300;

/// Relative error bound of the floating-point orientation determinant, (3 + 16ε)ε.
const ORIENT_ERROR_BOUND: f64 = (3.0 + 16.0 * f64::EPSILON) * f64::EPSILON / 2.0;

/// Where the Tutte weights come from (module docs).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize)]
#[serde(rename_all = "lowercase")]
pub enum RepairWeights {
    /// Mean-value weights of the input planar map (reproduce it where it is embedded).
    #[default]
    Layout,
    /// Mean-value weights of the 3D surface.
    Surface,
}

/// Parameters of [`repair_folds`].
#[derive(Clone, Debug)]
pub struct FoldRepairParams {
    /// Run the repair (default true). When false, [`repair_folds`] only counts folds.
    pub enabled: bool,
    /// Tutte weights (default [`RepairWeights::Layout`]).
    pub weights: RepairWeights,
    /// Sweeps of [`untangle_kernels`] before the Tutte rounds (default 200; 0: none). What it
    /// leaves folded goes to the Tutte rounds, with the untangled map as their input.
    pub untangle_sweeps: usize,
    /// Rings k of the first region around the folded faces (default 2; at least 1).
    pub initial_rings: usize,
    /// Maximum sweeps of the retraction towards the input positions after the Tutte solve
    /// (default 200; 0: none; on the bundled disks it stops by itself within ~60).
    pub retraction_sweeps: usize,
    /// The retraction never makes a face smaller than e^{-τ} times its share of the 3D area
    /// (or its input area, if smaller and valid), unless it already is (default τ = 1).
    pub retraction_log_floor: f64,
    /// The image area each face should have (#F), for the retraction's floor; default (`None`):
    /// its share of the 3D area, scaled to the image's total area. A chart whose scale varies
    /// over the image (a stereographic chart of the sphere) gives each face its own.
    pub target_face_areas: Option<Vec<f64>>,
}

impl Default for FoldRepairParams {
    fn default() -> Self {
        FoldRepairParams {
            enabled: true,
            weights: RepairWeights::Layout,
            untangle_sweeps: 200,
            initial_rings: 2,
            retraction_sweeps: 200,
            retraction_log_floor: 1.0,
            target_face_areas: None,
        }
    }
}

/// What [`repair_folds`] did.
#[derive(Clone, Debug, Default, PartialEq, Serialize)]
pub struct FoldRepairInfo {
    /// Whether the repair ran.
    pub enabled: bool,
    /// The weights asked for.
    pub weights: RepairWeights,
    /// Clockwise faces of the input map (exact predicate).
    pub flipped_before: usize,
    /// Faces of the input map with zero or sub-1e-300 area.
    pub degenerate_before: usize,
    /// Folded (flipped or degenerate) faces of the output map: 0, unless the repair is off or
    /// `flat_boundary_faces` remain.
    pub folded_after: usize,
    /// Faces with three boundary corners whose image is flat (three distinct, exactly collinear
    /// corners: ears lying on a side of the square). No move of interior vertices can repair them; they are
    /// left as they are and count in `folded_after`.
    pub flat_boundary_faces: usize,
    /// Sweeps and vertex moves of the kernel untangling run first, and the faces it left folded.
    pub untangle: UntangleInfo,
    /// Tutte solve rounds (0 when nothing was folded after the untangling, or the repair is off).
    pub rounds: usize,
    /// Rings k of the last round.
    pub rings: usize,
    /// Interior vertices in the final region R.
    pub region_vertices: usize,
    /// Whether R grew to every interior vertex.
    pub whole_disk: bool,
    /// Whether the whole-disk fallback to surface weights was used.
    pub surface_fallback: bool,
    /// The kernel untangling of the last whole-disk solve that still folded (`None` when no
    /// such solve ran).
    pub whole_disk_untangle: Option<UntangleInfo>,
    /// Retraction sweeps run.
    pub retraction_sweeps: usize,
    /// Vertices whose position changed.
    pub vertices_moved: usize,
    /// Largest displacement |uv_after − uv_before|.
    pub max_displacement: f64,
}

/// Whether the image of face (a, b, c) is counter-clockwise with doubled area ≥
/// [`MIN_DOUBLED_AREA`] (module docs).
pub fn face_is_valid(a: [f64; 2], b: [f64; 2], c: [f64; 2]) -> bool {
    doubled_area(a, b, c).is_some()
}

/// The doubled area of a valid face (a, b, c) ([`face_is_valid`]), `None` for a folded one.
/// The edge vectors are scaled by a power of two first, so tiny faces keep their relative
/// precision (a valid face's doubled area, at least 1e-300, is a normal f64; it is +∞ only for
/// edges beyond ~1e154, far outside the unit domains of the maps). Subnormal edge vectors
/// (scale 2^−e overflowing to ∞) give no finite area: folded.
fn doubled_area(a: [f64; 2], b: [f64; 2], c: [f64; 2]) -> Option<f64> {
    let d1 = [b[0] - a[0], b[1] - a[1]];
    let d2 = [c[0] - a[0], c[1] - a[1]];
    let m = d1.iter().chain(d2.iter()).fold(0.0f64, |acc, x| acc.max(x.abs()));
    if !(m > 0.0 && m.is_finite()) {
        return None;
    }
    let (s, _) = power_of_two_scale(m);
    let (t1, t2) = ((d1[0] * s) * (d2[1] * s), (d1[1] * s) * (d2[0] * s));
    let cross = t1 - t2;
    // Shewchuk's orient2d filter [Shewchuk 1997, ccwerrboundA] on the exactly scaled edge
    // vectors certifies most positive orientations; the exact predicate decides the rest (and
    // any case where a product may have underflowed).
    let magnitude = t1.abs() + t2.abs();
    let certified = magnitude > 1e-290 && cross > ORIENT_ERROR_BOUND * magnitude;
    if !certified && orient_scaled(a, b, c) != Sign::Positive {
        return None;
    }
    // doubled area = cross · 4^e (exact scaling by 2^e twice; below 1e-300 it may round or
    // underflow, which only makes it smaller)
    let inv = 1.0 / s;
    let area = (cross * inv) * inv;
    (cross > 0.0 && area >= MIN_DOUBLED_AREA).then_some(area)
}

/// Whether the triangle (a, b, c) is flat: three distinct, exactly collinear corners (exact
/// orientation predicate). Coincident corners are not flat: they mean a boundary out of order.
fn is_flat(a: [f64; 2], b: [f64; 2], c: [f64; 2]) -> bool {
    a != b && b != c && c != a && orient_scaled(a, b, c) == Sign::Zero
}

/// Counts (flipped, degenerate) faces of `uv` and lists the folded ones.
fn folded_faces(faces: &[[u32; 3]], uv: &[[f64; 2]]) -> (usize, usize, Vec<usize>) {
    let (mut flipped, mut degenerate, mut bad) = (0, 0, Vec::new());
    for (f, face) in faces.iter().enumerate() {
        let [a, b, c] = face.map(|v| uv[v as usize]);
        if !face_is_valid(a, b, c) {
            bad.push(f);
            if orient_scaled(a, b, c) == Sign::Negative {
                flipped += 1;
            } else {
                degenerate += 1;
            }
        }
    }
    (flipped, degenerate, bad)
}

/// Grows `in_region` by the vertices within `rings` edges of `seeds` (`neighbors`: each
/// vertex's neighbours) that are not flagged in `is_boundary`; the paths may pass through
/// those. Returns the number of vertices added.
pub fn grow_region(
    neighbors: &[Vec<u32>],
    is_boundary: &[bool],
    seeds: &[usize],
    rings: usize,
    in_region: &mut [bool],
) -> usize {
    let n = neighbors.len();
    let mut depth = vec![usize::MAX; n];
    let mut queue = VecDeque::new();
    for &s in seeds {
        if depth[s] == usize::MAX {
            depth[s] = 0;
            queue.push_back(s);
        }
    }
    let mut added = 0;
    while let Some(v) = queue.pop_front() {
        if !is_boundary[v] && !in_region[v] {
            in_region[v] = true;
            added += 1;
        }
        if depth[v] == rings {
            continue;
        }
        for &u in &neighbors[v] {
            let u = u as usize;
            if depth[u] == usize::MAX {
                depth[u] = depth[v] + 1;
                queue.push_back(u);
            }
        }
    }
    added
}

/// Repairs the folded faces of the planar map `uv` (#V) of `mesh` in place by local Tutte
/// re-embedding with growing regions (module docs); boundary vertices (`is_boundary`, #V) never
/// move. With `params.enabled == false` only counts the folds.
///
/// Errors: a flipped face with three boundary vertices, or one with coincident corners (cannot
/// be repaired by moving interior vertices: the boundary is out of order; a flat one with
/// distinct corners, an ear on a side of the square, is left and counted in
/// `flat_boundary_faces`), a degenerate 3D
/// one-ring, a failed sparse solve, or a whole-disk solve that still folds with both weights
/// (floating point defeating Floater's theorem).
pub fn repair_folds(
    mesh: &TriMesh,
    is_boundary: &[bool],
    uv: &mut [[f64; 2]],
    params: &FoldRepairParams,
) -> Result<FoldRepairInfo, ConformalError> {
    repair_folds_with(mesh, None, is_boundary, uv, params)
}

/// [`repair_folds`] with the mesh's connectivity when the caller has it (built here otherwise,
/// once a fold that moving interior vertices can repair is found).
pub fn repair_folds_with(
    mesh: &TriMesh,
    connectivity: Option<&Connectivity>,
    is_boundary: &[bool],
    uv: &mut [[f64; 2]],
    params: &FoldRepairParams,
) -> Result<FoldRepairInfo, ConformalError> {
    let n = mesh.num_vertices();
    if uv.len() != n || is_boundary.len() != n {
        return Err(ConformalError::InvalidInput(format!(
            "fold repair: {} uv and {} boundary flags for {n} vertices",
            uv.len(),
            is_boundary.len()
        )));
    }
    if let Some(t) = &params.target_face_areas {
        if t.len() != mesh.num_faces() {
            return Err(ConformalError::InvalidInput(format!(
                "fold repair: {} target face areas for {} faces",
                t.len(),
                mesh.num_faces()
            )));
        }
    }
    let (flipped, degenerate, mut bad) = folded_faces(&mesh.faces, uv);
    let mut info = FoldRepairInfo {
        enabled: params.enabled,
        weights: params.weights,
        flipped_before: flipped,
        degenerate_before: degenerate,
        folded_after: bad.len(),
        ..Default::default()
    };
    if !params.enabled || bad.is_empty() {
        return Ok(info);
    }
    // Folded faces with three boundary corners cannot be repaired by moving interior vertices.
    // A flat one (an ear lying on a side of the square, module docs of `area_preserving`) is
    // left as it is and counted; a flipped one means the boundary is out of order: an error.
    let on_boundary = |f: usize| mesh.faces[f].iter().all(|&v| is_boundary[v as usize]);
    for &f in bad.iter().filter(|&&f| on_boundary(f)) {
        let [a, b, c] = mesh.faces[f].map(|v| uv[v as usize]);
        if !is_flat(a, b, c) {
            return Err(ConformalError::FoldRepair {
                folded: bad.len(),
                message: format!(
                    "face {f} is folded and has only boundary vertices (boundary out of order or coincident)"
                ),
            });
        }
        info.flat_boundary_faces += 1;
    }
    // the folded faces the repair can act on
    let repairable = |uv: &[[f64; 2]]| -> Vec<usize> {
        let mut bad = folded_faces(&mesh.faces, uv).2;
        bad.retain(|&f| !on_boundary(f));
        bad
    };
    bad.retain(|&f| !on_boundary(f));
    if bad.is_empty() {
        return Ok(info);
    }
    let built;
    let conn = match connectivity {
        Some(c) => c,
        None => {
            built = Connectivity::of(mesh);
            &built
        }
    };
    let input = uv.to_vec();
    if params.untangle_sweeps > 0 {
        info.untangle = untangle_kernels(&mesh.faces, &conn.vertex_faces, is_boundary, uv, params.untangle_sweeps);
        bad = repairable(uv);
        if bad.is_empty() {
            info.folded_after = info.flat_boundary_faces;
            count_moves(&input, uv, &mut info);
            return Ok(info);
        }
    }
    let neighbors = conn.vertex_neighbors(n);
    let mut weights = tutte_weights(mesh, &conn.vertex_faces, &neighbors, is_boundary, uv, params.weights)?;
    let original = uv.to_vec();
    let num_interior = is_boundary.iter().filter(|&&b| !b).count();
    let mut in_region = vec![false; n];
    let mut region_size = 0;
    let mut rings = params.initial_rings.max(1);
    let mut solved = ComponentSolutions::new();
    // the kernel moves on a whole-disk solve that still folds (None when untangling is off)
    let untangle_whole = |candidate: &mut Vec<[f64; 2]>| {
        (params.untangle_sweeps > 0).then(|| {
            untangle_kernels(
                &mesh.faces,
                &conn.vertex_faces,
                is_boundary,
                candidate,
                params.untangle_sweeps,
            )
        })
    };
    let mut result = loop {
        info.rounds += 1;
        info.rings = rings;
        let mut seeds: Vec<usize> = bad.iter().flat_map(|&f| mesh.faces[f].map(|v| v as usize)).collect();
        seeds.sort_unstable();
        seeds.dedup();
        region_size += grow_region(&neighbors, is_boundary, &seeds, rings, &mut in_region);
        let whole = region_size == num_interior;
        let candidate = solve_region(&neighbors, &weights, &in_region, &original, Some(&mut solved))?;
        bad = repairable(&candidate);
        if bad.is_empty() {
            info.whole_disk = whole;
            break candidate;
        }
        if whole {
            info.whole_disk = true;
            // (a boundary that is not convex, as in the sphere's charts, or floating point:
            // the kernel moves often undo the few folds left)
            let mut candidate = candidate;
            if let Some(u) = untangle_whole(&mut candidate) {
                info.whole_disk_untangle = Some(u);
                bad = repairable(&candidate);
                if bad.is_empty() {
                    break candidate;
                }
            }
            if info.weights == RepairWeights::Layout && !info.surface_fallback {
                info.surface_fallback = true;
                weights = tutte_weights(
                    mesh,
                    &conn.vertex_faces,
                    &neighbors,
                    is_boundary,
                    uv,
                    RepairWeights::Surface,
                )?;
                let mut candidate = solve_region(&neighbors, &weights, &in_region, &original, None)?;
                bad = repairable(&candidate);
                if bad.is_empty() {
                    break candidate;
                }
                if let Some(u) = untangle_whole(&mut candidate) {
                    info.whole_disk_untangle = Some(u);
                    bad = repairable(&candidate);
                    if bad.is_empty() {
                        break candidate;
                    }
                }
            }
            return Err(ConformalError::FoldRepair {
                folded: bad.len(),
                message: "the whole-disk Tutte map still folds with layout and surface weights (floating point)".into(),
            });
        }
        rings = rings.saturating_mul(2);
    };
    info.region_vertices = region_size;
    let movable: Vec<usize> = (0..n).filter(|&v| in_region[v]).collect();
    // floors: 2 · e^{-τ} · A3D_f · A2D_total / A3D_total (or 2 · e^{-τ} times the face's given
    // target area), lowered to the input's valid area
    let areas3 = face_areas(mesh);
    let total3: f64 = areas3.iter().sum();
    let total2: f64 = mesh
        .faces
        .iter()
        .map(|f| {
            let [a, b, c] = f.map(|v| result[v as usize]);
            0.5 * ((b[0] - a[0]) * (c[1] - a[1]) - (b[1] - a[1]) * (c[0] - a[0]))
        })
        .sum();
    let floors: Vec<f64> = mesh
        .faces
        .iter()
        .zip(&areas3)
        .enumerate()
        .map(|(i, (f, a3))| {
            let target = match &params.target_face_areas {
                Some(t) => t.get(i).copied().unwrap_or(0.0),
                None => a3 * total2 / total3,
            };
            let share = 2.0 * target * (-params.retraction_log_floor).exp();
            let [a, b, c] = f.map(|v| original[v as usize]);
            doubled_area(a, b, c).map_or(share, |l| l.min(share))
        })
        .collect();
    info.retraction_sweeps = retract_components(
        &mesh.faces,
        &conn.vertex_faces,
        &neighbors,
        &floors,
        &movable,
        &original,
        &mut result,
        params.retraction_sweeps,
    );
    info.folded_after = info.flat_boundary_faces;
    uv.copy_from_slice(&result);
    count_moves(&input, uv, &mut info);
    Ok(info)
}

/// Fills `vertices_moved` and `max_displacement` of `info` from the input and output maps.
fn count_moves(input: &[[f64; 2]], output: &[[f64; 2]], info: &mut FoldRepairInfo) {
    for (p, q) in output.iter().zip(input) {
        if p != q {
            info.vertices_moved += 1;
            info.max_displacement = info.max_displacement.max((p[0] - q[0]).hypot(p[1] - q[1]));
        }
    }
}

/// Number of folded faces (clockwise or below [`MIN_DOUBLED_AREA`], exact predicate) of the
/// planar map `uv` of `faces`.
pub fn count_folded_faces(faces: &[[u32; 3]], uv: &[[f64; 2]]) -> usize {
    folded_faces(faces, uv).2.len()
}
