//! Repair of folded triangles of a planar disk map by local Tutte/Floater re-embedding
//! [Tutte 1963, "How to draw a graph"; Floater 2003, "One-to-one piecewise linear mappings over
//! triangulations", Thm. 1; Floater 2003, "Mean value coordinates"].
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
//! embedding: the loop ends after at most ⌈log₂(diameter in rings)⌉ + 1 rounds. In floating
//! point, a whole-disk solve that still folds is retried once with [`RepairWeights::Surface`];
//! if that folds too, the repair fails with a typed error instead of returning a folded map.
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

use faer::dyn_stack::{MemBuffer, MemStack, StackReq};
use faer::sparse::linalg::lu::{factorize_symbolic_lu, LuSymbolicParams, NumericLu};
use faer::sparse::linalg::SupernodalThreshold;
use faer::sparse::{SparseColMat, SparseColMatRef, Triplet};
use faer::{Conj, Par};
use geogram_predicates::Sign;
use serde::Serialize;
use shapespace_conformal::quality::{orient_scaled, power_of_two_scale};
use shapespace_geometry::quantities::face_areas;
use shapespace_geometry::{Connectivity, TriMesh};

use crate::error::AnalysisError;

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

/// tan(θ/2) of the unsigned angle θ ∈ [0, π] between `a` and `b` (∞ at θ = π, NaN for a zero
/// vector). Scale-free: the vectors are scaled by a power of two first.
fn half_angle_tan<const D: usize>(a: [f64; D], b: [f64; D]) -> f64 {
    let m = a.iter().chain(b.iter()).fold(0.0f64, |acc, x| acc.max(x.abs()));
    if !(m > 0.0 && m.is_finite()) {
        return f64::NAN;
    }
    let (s, _) = power_of_two_scale(m);
    let (a, b) = (a.map(|x| x * s), b.map(|x| x * s));
    let dot: f64 = (0..D).map(|k| a[k] * b[k]).sum();
    let na = a.iter().map(|x| x * x).sum::<f64>().sqrt();
    let nb = b.iter().map(|x| x * x).sum::<f64>().sqrt();
    // |a × b| = sqrt(|a|²|b|² − dot²), stable via Lagrange: |a|²|b|² − dot² = Σ_{k<l} (a_k b_l − a_l b_k)²
    let mut cr2 = 0.0;
    for k in 0..D {
        for l in k + 1..D {
            let c = a[k] * b[l] - a[l] * b[k];
            cr2 += c * c;
        }
    }
    let cr = cr2.sqrt();
    if na == 0.0 || nb == 0.0 {
        return f64::NAN;
    }
    if dot >= 0.0 {
        cr / (na * nb + dot)
    } else {
        (na * nb - dot) / cr
    }
}

/// Mean-value weights (unsigned angles) of every vertex over its sorted neighbour list
/// `neighbors[i]`, from positions `p` (#V × D). Rows of boundary vertices are left empty.
/// Entries may be 0, ∞ or NaN on degenerate layouts; rows are not normalized.
fn mean_value_weights<const D: usize>(
    faces: &[[u32; 3]],
    vertex_faces: &[Vec<u32>],
    neighbors: &[Vec<u32>],
    is_boundary: &[bool],
    p: &[[f64; D]],
) -> Vec<Vec<f64>> {
    let sub = |x: [f64; D], y: [f64; D]| -> [f64; D] { std::array::from_fn(|k| x[k] - y[k]) };
    let norm = |x: [f64; D]| -> f64 {
        // hypot-style scaling to avoid underflow of tiny edges
        let m = x.iter().fold(0.0f64, |acc, v| acc.max(v.abs()));
        if m == 0.0 || !m.is_finite() {
            return m;
        }
        m * x.iter().map(|v| (v / m) * (v / m)).sum::<f64>().sqrt()
    };
    // per vertex, its faces in increasing order (the same sums in the same order as a loop
    // over all faces), in parallel
    (0..neighbors.len())
        .into_par_iter()
        .map(|i| {
            if is_boundary[i] {
                return Vec::new();
            }
            let mut row = vec![0.0; neighbors[i].len()];
            for &f in &vertex_faces[i] {
                let face = faces[f as usize];
                for c in (0..3).filter(|&c| face[c] as usize == i) {
                    let (j, k) = (face[(c + 1) % 3] as usize, face[(c + 2) % 3] as usize);
                    let (a, b) = (sub(p[j], p[i]), sub(p[k], p[i]));
                    let t = half_angle_tan(a, b);
                    for (other, e) in [(j, a), (k, b)] {
                        if let Ok(slot) = neighbors[i].binary_search(&(other as u32)) {
                            row[slot] += t / norm(e);
                        }
                    }
                }
            }
            row
        })
        .collect()
}

/// Normalizes every interior row to sum 1 with entries ≥ 1e-12 of the row maximum; returns
/// false for a row that cannot be (non-finite or all zero), leaving it unchanged.
fn normalize_row(row: &mut [f64]) -> bool {
    let max = row
        .iter()
        .fold(0.0f64, |a, &x| if x.is_nan() { f64::NAN } else { a.max(x) });
    if !(max.is_finite() && max > 0.0) || row.iter().any(|x| !x.is_finite() || *x < 0.0) {
        return false;
    }
    for x in row.iter_mut() {
        *x = x.max(1e-12 * max);
    }
    let sum: f64 = row.iter().sum();
    for x in row.iter_mut() {
        *x /= sum;
    }
    true
}

/// The normalized Tutte weights of every interior vertex (module docs). Errors when a surface
/// row is degenerate (a zero-area 3D face).
fn tutte_weights(
    mesh: &TriMesh,
    vertex_faces: &[Vec<u32>],
    neighbors: &[Vec<u32>],
    is_boundary: &[bool],
    uv: &[[f64; 2]],
    kind: RepairWeights,
) -> Result<Vec<Vec<f64>>, AnalysisError> {
    let (mut surface, layout) = rayon::join(
        || mean_value_weights(&mesh.faces, vertex_faces, neighbors, is_boundary, &mesh.positions),
        || {
            (kind == RepairWeights::Layout)
                .then(|| mean_value_weights(&mesh.faces, vertex_faces, neighbors, is_boundary, uv))
        },
    );
    for (i, row) in surface.iter_mut().enumerate() {
        if !is_boundary[i] && !normalize_row(row) {
            return Err(AnalysisError::InvalidInput(format!(
                "fold repair: degenerate 3D one-ring at vertex {i} (zero-length edge or zero-area face)"
            )));
        }
    }
    let Some(mut layout) = layout else {
        return Ok(surface);
    };
    for (i, row) in layout.iter_mut().enumerate() {
        if !is_boundary[i] && !normalize_row(row) {
            row.clone_from(&surface[i]);
        }
    }
    Ok(layout)
}

/// Solutions of the Tutte system's connected components from an earlier round of
/// [`repair_folds`], keyed by (first vertex, size): the region only grows, so a component with
/// the same first vertex and size is the same vertex set, with the same weights and fixed
/// neighbours, and its solution can be taken as it is.
type ComponentSolutions = Vec<((usize, usize), Vec<[f64; 2]>)>;

/// Solves the Tutte system on the region (`in_region`, interior vertices only) with every other
/// vertex fixed at `fixed`, one connected component at a time (in parallel; each solve is
/// sequential, so the result does not depend on the thread count); returns the new positions.
/// With `earlier`, components solved in an earlier call (same weights, same `fixed`) are taken
/// from it, and it is replaced by this call's components.
fn solve_region(
    neighbors: &[Vec<u32>],
    weights: &[Vec<f64>],
    in_region: &[bool],
    fixed: &[[f64; 2]],
    earlier: Option<&mut ComponentSolutions>,
) -> Result<Vec<[f64; 2]>, AnalysisError> {
    let n = fixed.len();
    // the components, each listed in breadth-first order from its smallest vertex, and every
    // region vertex's index within its component
    let mut local = vec![u32::MAX; n];
    let mut components: Vec<Vec<usize>> = Vec::new();
    for start in 0..n {
        if !in_region[start] || local[start] != u32::MAX {
            continue;
        }
        let mut comp = vec![start];
        local[start] = 0;
        let mut head = 0;
        while head < comp.len() {
            let v = comp[head];
            head += 1;
            for &u in &neighbors[v] {
                let u = u as usize;
                if in_region[u] && local[u] == u32::MAX {
                    local[u] = comp.len() as u32;
                    comp.push(u);
                }
            }
        }
        components.push(comp);
    }
    let known = earlier.as_deref().map_or(&[][..], |e| e.as_slice());
    let solutions: Vec<Vec<[f64; 2]>> = components
        .par_iter()
        // (one job per component: rayon's adaptive split can leave the large ones on one thread)
        .with_max_len(1)
        .map(
            |comp| match known.iter().find(|(key, _)| *key == (comp[0], comp.len())) {
                Some((_, solution)) => Ok(solution.clone()),
                None => solve_component(neighbors, weights, in_region, fixed, &local, comp),
            },
        )
        // (all results first, then the first error in component order: the same error
        // whatever the threads do)
        .collect::<Vec<_>>()
        .into_iter()
        .collect::<Result<_, _>>()?;
    let mut out = fixed.to_vec();
    for (comp, solution) in components.iter().zip(&solutions) {
        for (&v, &p) in comp.iter().zip(solution) {
            out[v] = p;
        }
    }
    if let Some(earlier) = earlier {
        *earlier = components
            .iter()
            .map(|comp| (comp[0], comp.len()))
            .zip(solutions)
            .collect();
    }
    Ok(out)
}

/// The Tutte solve of one connected component `comp` of the region (`local`: each region
/// vertex's index within its component), in coordinates relative to the mean of its fixed
/// neighbours; its vertices' new positions, in the order of `comp`.
fn solve_component(
    neighbors: &[Vec<u32>],
    weights: &[Vec<f64>],
    in_region: &[bool],
    fixed: &[[f64; 2]],
    local: &[u32],
    comp: &[usize],
) -> Result<Vec<[f64; 2]>, AnalysisError> {
    // reference point: mean of the fixed neighbours
    let (mut c, mut count) = ([0.0f64; 2], 0usize);
    for &v in comp {
        for &u in &neighbors[v] {
            if !in_region[u as usize] {
                c[0] += fixed[u as usize][0];
                c[1] += fixed[u as usize][1];
                count += 1;
            }
        }
    }
    if count == 0 {
        return Err(AnalysisError::InvalidInput(format!(
            "fold repair: region component of vertex {} touches no fixed vertex",
            comp[0]
        )));
    }
    c = [c[0] / count as f64, c[1] / count as f64];
    let m = comp.len();
    let mut trip = Vec::with_capacity(m * 8);
    let mut rhs = faer::Mat::<f64>::zeros(m, 2);
    for (li, &v) in comp.iter().enumerate() {
        trip.push(Triplet::new(li, li, 1.0));
        for (&u, &w) in neighbors[v].iter().zip(&weights[v]) {
            let u = u as usize;
            if in_region[u] {
                trip.push(Triplet::new(li, local[u] as usize, -w));
            } else {
                rhs[(li, 0)] += w * (fixed[u][0] - c[0]);
                rhs[(li, 1)] += w * (fixed[u][1] - c[1]);
            }
        }
    }
    let a = SparseColMat::<usize, f64>::try_new_from_triplets(m, m, &trip)
        .map_err(|e| AnalysisError::InvalidInput(format!("fold repair: assembling the Tutte system: {e:?}")))?;
    lu_solve_in_place(a.as_ref(), rhs.as_mut())
        .map_err(|e| AnalysisError::InvalidInput(format!("fold repair: LU of the Tutte system ({m} unknowns): {e}")))?;
    comp.iter()
        .enumerate()
        .map(|(li, &v)| {
            let p = [rhs[(li, 0)] + c[0], rhs[(li, 1)] + c[1]];
            if p[0].is_finite() && p[1].is_finite() {
                Ok(p)
            } else {
                Err(AnalysisError::InvalidInput(format!(
                    "fold repair: non-finite position of vertex {v}"
                )))
            }
        })
        .collect()
}

/// From this many unknowns on, the Tutte systems are factorized supernodally (faer's automatic
/// choice takes the simplicial LU for these 2-D mesh systems, about twice as slow on the
/// 10⁴-unknown regions of the TOSCA bodies).
const SUPERNODAL_LU_MIN: usize = 2000;

/// Solves A X = B in place (B: m × k) by a sparse LU with partial pivoting (faer: COLAMD column
/// ordering; supernodal from [`SUPERNODAL_LU_MIN`] unknowns), sequential, so the result does not
/// depend on the thread count.
fn lu_solve_in_place(a: SparseColMatRef<'_, usize, f64>, rhs: faer::MatMut<'_, f64>) -> Result<(), String> {
    let m = a.nrows();
    let params = LuSymbolicParams {
        supernodal_flop_ratio_threshold: if m >= SUPERNODAL_LU_MIN {
            SupernodalThreshold::FORCE_SUPERNODAL
        } else {
            SupernodalThreshold::AUTO
        },
        ..Default::default()
    };
    let symbolic = factorize_symbolic_lu(a.symbolic(), params).map_err(|e| format!("{e:?}"))?;
    let scratch = StackReq::or(
        symbolic.factorize_numeric_lu_scratch::<f64>(Par::Seq, Default::default()),
        symbolic.solve_in_place_scratch::<f64>(rhs.ncols(), Par::Seq),
    );
    let mut buffer = MemBuffer::try_new(scratch).map_err(|e| format!("{e:?}"))?;
    let mut numeric = NumericLu::new();
    let lu = symbolic
        .factorize_numeric_lu(
            &mut numeric,
            a,
            Par::Seq,
            MemStack::new(&mut buffer),
            Default::default(),
        )
        .map_err(|e| format!("{e:?}"))?;
    lu.solve_in_place_with_conj(Conj::No, rhs, Par::Seq, MemStack::new(&mut buffer));
    Ok(())
}

/// Doubled area of face `f` with vertex `v` at `p` (`None`: folded).
fn doubled_area_with(faces: &[[u32; 3]], uv: &[[f64; 2]], f: usize, v: usize, p: [f64; 2]) -> Option<f64> {
    let [a, b, c] = faces[f].map(|u| if u as usize == v { p } else { uv[u as usize] });
    doubled_area(a, b, c)
}

/// Retraction towards `target` (the input map): Gauss–Seidel sweeps over `movable` moving
/// each vertex along the segment to its target by the largest step 2^{-s} (s = 0..5) after
/// which every face around it is valid and has doubled area ≥ min(its current value,
/// `floors[f]`), so an embedding stays one and no face is squeezed below its floor. Stops
/// after `max_sweeps` or when a sweep moves nothing. Returns the sweeps run.
fn retract(
    faces: &[[u32; 3]],
    vertex_faces: &[Vec<u32>],
    floors: &[f64],
    movable: &[usize],
    target: &[[f64; 2]],
    uv: &mut [[f64; 2]],
    max_sweeps: usize,
) -> usize {
    // doubled area of every face at the current positions (None: folded), kept up to date
    // as vertices move.
    let mut current: Vec<Option<f64>> = vec![None; faces.len()];
    for &v in movable {
        for &f in &vertex_faces[v] {
            let f = f as usize;
            current[f] = doubled_area_with(faces, uv, f, v, uv[v]);
        }
    }
    let star_ok = |uv: &[[f64; 2]], current: &[Option<f64>], v: usize, p: [f64; 2]| {
        vertex_faces[v].iter().all(|&f| {
            let f = f as usize;
            match (doubled_area_with(faces, uv, f, v, p), current[f]) {
                (Some(new), Some(old)) => new >= old.min(floors[f]),
                (Some(_), None) => true,
                (None, _) => false,
            }
        })
    };
    // A vertex is tried again only after it or a vertex of its star moved: otherwise its
    // trials see the same faces and fail the same way (the sweeps are unchanged, just cheaper).
    let mut dirty = vec![false; uv.len()];
    for &v in movable {
        dirty[v] = true;
    }
    for sweep in 0..max_sweeps {
        let mut moved = false;
        for &v in movable {
            if !std::mem::replace(&mut dirty[v], false) {
                continue;
            }
            let (x, goal) = (uv[v], target[v]);
            if x == goal {
                continue;
            }
            let mut t = 1.0;
            for _ in 0..6 {
                let p = if t == 1.0 {
                    goal
                } else {
                    [x[0] + t * (goal[0] - x[0]), x[1] + t * (goal[1] - x[1])]
                };
                if p != x && star_ok(uv, &current, v, p) {
                    uv[v] = p;
                    for &f in &vertex_faces[v] {
                        let f = f as usize;
                        current[f] = doubled_area_with(faces, uv, f, v, p);
                        for &u in &faces[f] {
                            dirty[u as usize] = true;
                        }
                    }
                    moved = true;
                    break;
                }
                t *= 0.5;
            }
        }
        if !moved {
            return sweep + 1;
        }
    }
    max_sweeps
}

/// [`retract`] run on each connected component of `movable` (adjacency `neighbors`) on its own,
/// the components in parallel; returns the most sweeps any ran. Two movable vertices on one
/// face are neighbours, so different components share no face: each component's moves see
/// only its own vertices' positions, and the result is exactly that of [`retract`] over all of
/// `movable` in its order (Gauss–Seidel order within a component is kept). Each component is
/// solved on a compact copy (its vertices, their stars and the stars' other corners).
#[allow(clippy::too_many_arguments)]
fn retract_components(
    faces: &[[u32; 3]],
    vertex_faces: &[Vec<u32>],
    neighbors: &[Vec<u32>],
    floors: &[f64],
    movable: &[usize],
    target: &[[f64; 2]],
    uv: &mut [[f64; 2]],
    max_sweeps: usize,
) -> usize {
    const NONE: u32 = u32::MAX;
    // component of each movable vertex (by breadth-first search), in the order of `movable`
    let mut component = vec![NONE; uv.len()];
    for &v in movable {
        component[v] = NONE - 1;
    }
    let mut count = 0u32;
    let mut queue = Vec::new();
    for &s in movable {
        if component[s] != NONE - 1 {
            continue;
        }
        component[s] = count;
        queue.push(s);
        while let Some(v) = queue.pop() {
            for &u in &neighbors[v] {
                if component[u as usize] == NONE - 1 {
                    component[u as usize] = count;
                    queue.push(u as usize);
                }
            }
        }
        count += 1;
    }
    let mut members: Vec<Vec<usize>> = vec![Vec::new(); count as usize];
    for &v in movable {
        members[component[v] as usize].push(v);
    }
    if members.is_empty() {
        // (what `retract` returns for nothing to move)
        return usize::from(max_sweeps > 0);
    }
    // largest first, for the balance of the parallel loop
    members.sort_by_key(|m| std::cmp::Reverse(m.len()));
    let uv_in: &[[f64; 2]] = uv;
    // per component: its sweeps, and its vertices' final positions
    type Retracted = (usize, Vec<(usize, [f64; 2])>);
    let moved: Vec<Retracted> = members
        .par_iter()
        // (one job per component: rayon's adaptive split would leave the largest ones, listed
        // first, together on one thread)
        .with_max_len(1)
        .map(|part| {
            // compact copy: local vertex ids for the component, its stars' faces and corners
            let mut local: std::collections::HashMap<u32, u32> = std::collections::HashMap::new();
            let mut global: Vec<usize> = Vec::new();
            let mut id = |v: u32, global: &mut Vec<usize>| {
                *local.entry(v).or_insert_with(|| {
                    global.push(v as usize);
                    (global.len() - 1) as u32
                })
            };
            // (a vertex listed twice in `movable` keeps one local id and is tried twice per
            // sweep, as in `retract`)
            let sub_movable: Vec<usize> = part.iter().map(|&v| id(v as u32, &mut global) as usize).collect();
            let distinct = global.len();
            let mut face_id: std::collections::HashMap<u32, u32> = std::collections::HashMap::new();
            let (mut sub_faces, mut sub_floors) = (Vec::new(), Vec::new());
            let mut sub_vertex_faces: Vec<Vec<u32>> = vec![Vec::new(); distinct];
            for k in 0..distinct {
                for &f in &vertex_faces[global[k]] {
                    let g = *face_id.entry(f).or_insert_with(|| {
                        sub_faces.push(faces[f as usize].map(|u| id(u, &mut global)));
                        sub_floors.push(floors[f as usize]);
                        (sub_faces.len() - 1) as u32
                    });
                    sub_vertex_faces[k].push(g);
                }
            }
            let mut sub_uv: Vec<[f64; 2]> = global.iter().map(|&v| uv_in[v]).collect();
            let sub_target: Vec<[f64; 2]> = global.iter().map(|&v| target[v]).collect();
            sub_vertex_faces.resize(global.len(), Vec::new());
            let sweeps = retract(
                &sub_faces,
                &sub_vertex_faces,
                &sub_floors,
                &sub_movable,
                &sub_target,
                &mut sub_uv,
                max_sweeps,
            );
            (sweeps, (0..distinct).map(|k| (global[k], sub_uv[k])).collect())
        })
        .collect();
    let mut sweeps = 0;
    for (s, positions) in moved {
        sweeps = sweeps.max(s);
        for (v, p) in positions {
            uv[v] = p;
        }
    }
    sweeps
}

/// Grows `in_region` by the interior vertices within `rings` edges of `seeds` (the path may
/// pass through boundary vertices). Returns the number of vertices added.
fn grow_region(
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
) -> Result<FoldRepairInfo, AnalysisError> {
    repair_folds_with(mesh, None, is_boundary, uv, params)
}

/// [`repair_folds`] with the mesh's connectivity when the caller has it (built here otherwise,
/// once a fold that moving interior vertices can repair is found).
pub(crate) fn repair_folds_with(
    mesh: &TriMesh,
    connectivity: Option<&Connectivity>,
    is_boundary: &[bool],
    uv: &mut [[f64; 2]],
    params: &FoldRepairParams,
) -> Result<FoldRepairInfo, AnalysisError> {
    let n = mesh.num_vertices();
    if uv.len() != n || is_boundary.len() != n {
        return Err(AnalysisError::InvalidInput(format!(
            "fold repair: {} uv and {} boundary flags for {n} vertices",
            uv.len(),
            is_boundary.len()
        )));
    }
    if let Some(t) = &params.target_face_areas {
        if t.len() != mesh.num_faces() {
            return Err(AnalysisError::InvalidInput(format!(
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
            return Err(AnalysisError::FoldRepair {
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
                let candidate = solve_region(&neighbors, &weights, &in_region, &original, None)?;
                bad = repairable(&candidate);
                if bad.is_empty() {
                    break candidate;
                }
            }
            return Err(AnalysisError::FoldRepair {
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

/// The convex-combination (Tutte) map of `mesh` with the mean-value weights of the planar
/// layout `layout` (#V; [`RepairWeights::Layout`], unsigned angles, floored at 1e-12 of the row
/// maximum, a degenerate layout row falling back to the 3D mean-value weights) and the vertices
/// with `fixed[v] = Some(p)` held at p: $x_i = \sum_j w_{ij} x_j$ at every other vertex
/// [Floater 2003, "Mean value coordinates"]. #V positions. Where `layout` is an embedding the
/// weights are its mean value coordinates, so with every fixed vertex at its layout position
/// the result reproduces `layout` (to roundoff). Floater's theorem makes it an embedding when
/// the fixed vertices are exactly a convex boundary polygon in order; fixed interior vertices
/// (landmarks) void that guarantee: count the folds.
///
/// Errors: `fixed` or `layout` not #V long, a free vertex on the boundary of `mesh` (its row
/// would be empty), a degenerate 3D one-ring, a failed sparse solve.
pub fn mean_value_tutte_map(
    mesh: &TriMesh,
    layout: &[[f64; 2]],
    fixed: &[Option<[f64; 2]>],
) -> Result<Vec<[f64; 2]>, AnalysisError> {
    let n = mesh.num_vertices();
    if layout.len() != n || fixed.len() != n {
        return Err(AnalysisError::InvalidInput(format!(
            "mean-value map: {} layout points and {} constraints for {n} vertices",
            layout.len(),
            fixed.len()
        )));
    }
    let conn = Connectivity::of(mesh);
    let on_boundary = conn.boundary_vertices(n);
    if let Some(v) = (0..n).find(|&v| on_boundary[v] && fixed[v].is_none()) {
        return Err(AnalysisError::InvalidInput(format!(
            "mean-value map: boundary vertex {v} is not fixed"
        )));
    }
    let neighbors = conn.vertex_neighbors(n);
    let is_fixed: Vec<bool> = fixed.iter().map(Option::is_some).collect();
    let weights = tutte_weights(
        mesh,
        &conn.vertex_faces,
        &neighbors,
        &is_fixed,
        layout,
        RepairWeights::Layout,
    )?;
    let positions: Vec<[f64; 2]> = fixed.iter().zip(layout).map(|(f, p)| f.unwrap_or(*p)).collect();
    let free: Vec<bool> = is_fixed.iter().map(|f| !f).collect();
    solve_region(&neighbors, &weights, &free, &positions, None)
}

/// What [`untangle_kernels`] did.
#[derive(Clone, Debug, Default, PartialEq, Serialize)]
pub struct UntangleInfo {
    /// Folded faces before (exact predicate, [`face_is_valid`]).
    pub folded_before: usize,
    /// Folded faces after.
    pub folded_after: usize,
    /// Sweeps run.
    pub sweeps: usize,
    /// Vertex moves made.
    pub moves: usize,
}

/// The kernel of the star of a vertex: the polygon of points x with every face (x, a, b) of the
/// star counter-clockwise (left of every link edge a → b), by Sutherland–Hodgman clipping of the
/// link's bounding box, in coordinates relative to `origin`. Empty when the kernel is.
fn star_kernel(links: &[([f64; 2], [f64; 2])], origin: [f64; 2]) -> Vec<[f64; 2]> {
    let rel = |p: [f64; 2]| [p[0] - origin[0], p[1] - origin[1]];
    let (mut lo, mut hi) = ([f64::INFINITY; 2], [f64::NEG_INFINITY; 2]);
    for &(a, b) in links {
        for q in [rel(a), rel(b)] {
            for d in 0..2 {
                lo[d] = lo[d].min(q[d]);
                hi[d] = hi[d].max(q[d]);
            }
        }
    }
    let mut poly = vec![[lo[0], lo[1]], [hi[0], lo[1]], [hi[0], hi[1]], [lo[0], hi[1]]];
    for &(a, b) in links {
        let (a, b) = (rel(a), rel(b));
        let side = |p: [f64; 2]| (b[0] - a[0]) * (p[1] - a[1]) - (b[1] - a[1]) * (p[0] - a[0]);
        let mut out = Vec::with_capacity(poly.len() + 1);
        for k in 0..poly.len() {
            let (p, q) = (poly[k], poly[(k + 1) % poly.len()]);
            let (sp, sq) = (side(p), side(q));
            if sp >= 0.0 {
                out.push(p);
            }
            if (sp >= 0.0) != (sq >= 0.0) {
                let t = sp / (sp - sq);
                out.push([p[0] + t * (q[0] - p[0]), p[1] + t * (q[1] - p[1])]);
            }
        }
        poly = out;
        if poly.len() < 3 {
            return Vec::new();
        }
    }
    poly
}

/// Area centroid of a polygon (relative coordinates); `None` when its area is not positive.
fn polygon_centroid(poly: &[[f64; 2]]) -> Option<[f64; 2]> {
    let (mut a, mut cx, mut cy) = (0.0, 0.0, 0.0);
    for k in 0..poly.len() {
        let (p, q) = (poly[k], poly[(k + 1) % poly.len()]);
        let c = p[0] * q[1] - q[0] * p[1];
        a += c;
        cx += (p[0] + q[0]) * c;
        cy += (p[1] + q[1]) * c;
    }
    (a > 0.0 && a.is_finite()).then(|| [cx / (3.0 * a), cy / (3.0 * a)])
}

/// Untangles folded faces of the planar map `uv` (#V) of `faces` by moving free vertices
/// (`fixed[v] == false`) into the kernels of their stars [the kernel is the set of positions
/// where every incident face is counter-clockwise; see e.g. Freitag & Plassmann 2000, "Local
/// optimization-based simplicial mesh untangling"; here the kernel's area centroid is taken
/// instead of an optimum]. Gauss–Seidel sweeps over the free vertices of the folded faces
/// (after `max_sweeps / 2` sweeps without success, also their one-ring neighbours); a move is
/// made only when it strictly lowers the number of invalid faces around the vertex (exact
/// predicate), so the number of folded faces never increases, and only faces around the moved
/// vertex change. Stops when nothing is folded, a sweep moves nothing, or after `max_sweeps`.
/// Fixed vertices (boundary, landmarks) never move.
pub fn untangle_kernels(
    faces: &[[u32; 3]],
    vertex_faces: &[Vec<u32>],
    fixed: &[bool],
    uv: &mut [[f64; 2]],
    max_sweeps: usize,
) -> UntangleInfo {
    let bad = folded_faces(faces, uv).2;
    let mut info = UntangleInfo {
        folded_before: bad.len(),
        folded_after: bad.len(),
        ..Default::default()
    };
    let invalid_around = |uv: &[[f64; 2]], v: usize| {
        vertex_faces[v]
            .iter()
            .filter(|&&f| {
                let [a, b, c] = faces[f as usize].map(|u| uv[u as usize]);
                !face_is_valid(a, b, c)
            })
            .count()
    };
    let mut bad = bad;
    while !bad.is_empty() && info.sweeps < max_sweeps {
        info.sweeps += 1;
        let mut verts: Vec<usize> = bad.iter().flat_map(|&f| faces[f].map(|v| v as usize)).collect();
        if info.sweeps > max_sweeps / 2 {
            let ring: Vec<usize> = verts
                .iter()
                .flat_map(|&v| {
                    vertex_faces[v]
                        .iter()
                        .flat_map(|&f| faces[f as usize].map(|u| u as usize))
                })
                .collect();
            verts.extend(ring);
        }
        verts.sort_unstable();
        verts.dedup();
        let mut moved = false;
        for v in verts {
            if fixed[v] {
                continue;
            }
            let before = invalid_around(uv, v);
            if before == 0 {
                continue;
            }
            let links: Vec<([f64; 2], [f64; 2])> = vertex_faces[v]
                .iter()
                .map(|&f| {
                    let t = faces[f as usize];
                    let k = t.iter().position(|&u| u as usize == v).unwrap_or(0);
                    (uv[t[(k + 1) % 3] as usize], uv[t[(k + 2) % 3] as usize])
                })
                .collect();
            let origin = uv[v];
            let Some(c) = polygon_centroid(&star_kernel(&links, origin)) else {
                continue;
            };
            let old = uv[v];
            uv[v] = [origin[0] + c[0], origin[1] + c[1]];
            if invalid_around(uv, v) < before {
                info.moves += 1;
                moved = true;
            } else {
                uv[v] = old;
            }
        }
        bad = folded_faces(faces, uv).2;
        if !moved && info.sweeps <= max_sweeps / 2 {
            info.sweeps = max_sweeps / 2; // widen to the one-ring neighbours
        } else if !moved {
            break;
        }
    }
    info.folded_after = bad.len();
    info
}

/// Number of folded faces (clockwise or below [`MIN_DOUBLED_AREA`], exact predicate) of the
/// planar map `uv` of `faces`.
pub fn count_folded_faces(faces: &[[u32; 3]], uv: &[[f64; 2]]) -> usize {
    folded_faces(faces, uv).2.len()
}

#[cfg(test)]
mod tests {
    use super::*;
    use shapespace_geometry::primitives;

    fn disk_layout(rings: usize) -> (TriMesh, Vec<bool>, Vec<[f64; 2]>) {
        let mesh = primitives::unit_disk(rings);
        let is_boundary = Connectivity::of(&mesh).boundary_vertices(mesh.num_vertices());
        let uv: Vec<[f64; 2]> = mesh.positions.iter().map(|p| [p[0], p[1]]).collect();
        (mesh, is_boundary, uv)
    }

    /// `reference` squeezed radially (|p| → |p|^e, e = `exponent(p)`): an embedding of the disk.
    fn squeezed(reference: &[[f64; 2]], exponent: impl Fn([f64; 2]) -> f64) -> Vec<[f64; 2]> {
        reference
            .iter()
            .map(|&p| {
                let r = p[0].hypot(p[1]);
                let f = if r > 0.0 { r.powf(exponent(p)) / r } else { 1.0 };
                [p[0] * f, p[1] * f]
            })
            .collect()
    }

    /// Retraction floors: the faces' doubled areas in `reference` times e^{-0.3}, so that some
    /// moves towards the reference are refused.
    fn retraction_floors(mesh: &TriMesh, reference: &[[f64; 2]]) -> Vec<f64> {
        mesh.faces
            .iter()
            .map(|f| {
                let [a, b, c] = f.map(|v| reference[v as usize]);
                doubled_area(a, b, c).unwrap() * (-0.3f64).exp()
            })
            .collect()
    }

    /// max_v |a_v − b_v|.
    fn max_distance(a: &[[f64; 2]], b: &[[f64; 2]]) -> f64 {
        a.iter()
            .zip(b)
            .map(|(p, q)| (p[0] - q[0]).hypot(p[1] - q[1]))
            .fold(0.0, f64::max)
    }

    /// The next state of a xorshift64 generator (the tests' reproducible random numbers).
    fn xorshift(state: &mut u64) -> u64 {
        *state ^= *state << 13;
        *state ^= *state >> 7;
        *state ^= *state << 17;
        *state
    }

    /// `reference` with vertex v pushed past its neighbour `far` by half an edge, so that v's
    /// star folds, and the number of flipped faces (at least 2).
    fn pushed_past(mesh: &TriMesh, reference: &[[f64; 2]], v: usize, far: usize) -> (Vec<[f64; 2]>, usize) {
        let mut uv = reference.to_vec();
        uv[v] = [
            reference[far][0] + 0.5 * (reference[far][0] - reference[v][0]),
            reference[far][1] + 0.5 * (reference[far][1] - reference[v][1]),
        ];
        let (flipped, _, _) = folded_faces(&mesh.faces, &uv);
        assert!(flipped >= 2, "the push should fold faces, got {flipped}");
        (uv, flipped)
    }

    #[test]
    fn validity_uses_orientation_and_an_area_floor() {
        assert!(face_is_valid([0.0, 0.0], [1.0, 0.0], [0.0, 1.0]));
        assert!(!face_is_valid([0.0, 0.0], [0.0, 1.0], [1.0, 0.0]));
        assert!(!face_is_valid([0.0, 0.0], [1.0, 0.0], [2.0, 0.0]));
        // tiny but representable triangles are valid; below 1e-300 doubled area they are not
        assert!(face_is_valid([1e-140, 1e-140], [2e-140, 1e-140], [1e-140, 2e-140]));
        assert!(face_is_valid([0.0, 0.0], [1e-150, 0.0], [0.0, 1e-150]));
        assert!(!face_is_valid([0.0, 0.0], [1e-151, 0.0], [0.0, 1e-151]));
        // subnormal edge vectors (their power-of-two scale overflows): area ~1e-646, folded
        let (a, h) = (2f64.powi(-1023), 2f64.powi(-1073));
        assert!(!face_is_valid([a, a], [a + h, a - h], [a + h, a + h]));
    }

    /// The per-vertex weights sum each vertex's faces in increasing order: the same bits as the
    /// loop over all faces they replaced, on a jittered disk.
    #[test]
    fn per_vertex_mean_value_weights_equal_the_loop_over_faces() {
        let (mesh, is_boundary, mut uv) = disk_layout(12);
        let mut state = 0x9e37_79b9_7f4a_7c15u64;
        for (v, p) in uv.iter_mut().enumerate() {
            if !is_boundary[v] {
                let state = xorshift(&mut state);
                p[0] += 0.02 * ((state >> 11) as f64 / (1u64 << 53) as f64 - 0.5);
                p[1] += 0.02 * ((state & 0xffff) as f64 / 65536.0 - 0.5);
            }
        }
        let conn = Connectivity::of(&mesh);
        let neighbors = conn.vertex_neighbors(mesh.num_vertices());
        let got = mean_value_weights(&mesh.faces, &conn.vertex_faces, &neighbors, &is_boundary, &uv);
        let mut want: Vec<Vec<f64>> = neighbors
            .iter()
            .zip(&is_boundary)
            .map(|(n, &b)| if b { Vec::new() } else { vec![0.0; n.len()] })
            .collect();
        for face in &mesh.faces {
            for c in 0..3 {
                let (i, j, k) = (face[c] as usize, face[(c + 1) % 3] as usize, face[(c + 2) % 3] as usize);
                if is_boundary[i] {
                    continue;
                }
                let (a, b) = (
                    [uv[j][0] - uv[i][0], uv[j][1] - uv[i][1]],
                    [uv[k][0] - uv[i][0], uv[k][1] - uv[i][1]],
                );
                let t = half_angle_tan(a, b);
                for (other, e) in [(j, a), (k, b)] {
                    let slot = neighbors[i].binary_search(&(other as u32)).unwrap();
                    let m = e[0].abs().max(e[1].abs());
                    want[i][slot] += t / (m * ((e[0] / m) * (e[0] / m) + (e[1] / m) * (e[1] / m)).sqrt());
                }
            }
        }
        assert_eq!(got, want);
        assert!(got.iter().any(|row| row.len() > 4));
    }

    /// The float filter in `doubled_area` never decides differently from the exact
    /// predicate: random and nearly collinear triangles at scales 1e-140 … 1e3.
    #[test]
    fn filtered_validity_agrees_with_the_exact_predicate() {
        let mut state = 0x2545_f491_4f6c_dd1du64;
        let mut next = || (xorshift(&mut state) >> 11) as f64 / (1u64 << 53) as f64 - 0.5;
        let mut decided_by_filter = 0;
        for k in 0..20_000 {
            let scale = [1e-140, 1e-20, 1.0, 1e3][k % 4];
            let a = [next() * scale, next() * scale];
            let b = [next() * scale, next() * scale];
            // every other triangle nearly collinear: c on the line ab plus a tiny offset
            let c = if k % 2 == 0 {
                [next() * scale, next() * scale]
            } else {
                let t = next();
                let off = next() * scale * [1e-12, 1e-15, 1e-17][k % 3];
                [
                    a[0] + t * (b[0] - a[0]) - off * (b[1] - a[1]),
                    a[1] + t * (b[1] - a[1]) + off * (b[0] - a[0]),
                ]
            };
            let exact_positive = orient_scaled(a, b, c) == Sign::Positive;
            let got = doubled_area(a, b, c);
            if !exact_positive {
                assert!(got.is_none(), "{a:?} {b:?} {c:?}");
            } else {
                decided_by_filter += 1;
                let d1 = [b[0] - a[0], b[1] - a[1]];
                let d2 = [c[0] - a[0], c[1] - a[1]];
                let cross = d1[0] * d2[1] - d1[1] * d2[0];
                if cross > 1e-250 {
                    let area = got.expect("a positive face of area > 1e-250 is valid");
                    assert!((area - cross).abs() <= 1e-9 * cross, "{area} vs {cross}");
                }
            }
        }
        assert!(decided_by_filter > 5_000);
    }

    /// The retraction tries a vertex again only after its star changed; it must end where the
    /// plain sweeps over every vertex end (same positions, same sweep count).
    #[test]
    fn retraction_with_a_worklist_matches_plain_sweeps() {
        let (mesh, is_boundary, reference) = disk_layout(10);
        let n = mesh.num_vertices();
        let conn = Connectivity::of(&mesh);
        let movable: Vec<usize> = (0..n).filter(|&v| !is_boundary[v]).collect();
        // start: the disk squeezed radially (an embedding), target: the reference layout,
        // floors from the reference areas minus a margin, so some moves are refused
        let start = squeezed(&reference, |_| 1.8);
        let floors = retraction_floors(&mesh, &reference);
        let mut fast = start.clone();
        let sweeps = retract(
            &mesh.faces,
            &conn.vertex_faces,
            &floors,
            &movable,
            &reference,
            &mut fast,
            200,
        );
        // plain Gauss–Seidel sweeps (the rule of `retract` without the worklist)
        let mut plain = start.clone();
        let star_ok = |uv: &[[f64; 2]], v: usize, p: [f64; 2]| {
            conn.vertex_faces[v].iter().all(|&f| {
                let f = f as usize;
                match (
                    doubled_area_with(&mesh.faces, uv, f, v, p),
                    doubled_area_with(&mesh.faces, uv, f, v, uv[v]),
                ) {
                    (Some(new), Some(old)) => new >= old.min(floors[f]),
                    (Some(_), None) => true,
                    (None, _) => false,
                }
            })
        };
        let mut plain_sweeps = 200;
        for sweep in 0..200 {
            let mut moved = false;
            for &v in &movable {
                let (x, goal) = (plain[v], reference[v]);
                if x == goal {
                    continue;
                }
                let mut t = 1.0;
                for _ in 0..6 {
                    let p = if t == 1.0 {
                        goal
                    } else {
                        [x[0] + t * (goal[0] - x[0]), x[1] + t * (goal[1] - x[1])]
                    };
                    if p != x && star_ok(&plain, v, p) {
                        plain[v] = p;
                        moved = true;
                        break;
                    }
                    t *= 0.5;
                }
            }
            if !moved {
                plain_sweeps = sweep + 1;
                break;
            }
        }
        assert!(sweeps > 2, "the case should need several sweeps, took {sweeps}");
        assert_eq!(sweeps, plain_sweeps);
        assert_eq!(fast, plain);
        assert_ne!(fast, reference, "the floors should hold some vertices back");
    }

    /// The retraction run per connected component of the movable vertices (in parallel) ends
    /// exactly where one retraction over all of them does, after as many sweeps.
    #[test]
    fn retraction_by_components_matches_one_retraction() {
        let (mesh, is_boundary, reference) = disk_layout(12);
        let n = mesh.num_vertices();
        let conn = Connectivity::of(&mesh);
        let neighbors = conn.vertex_neighbors(n);
        // movable: interior vertices off the centre and off three fixed spokes, i.e. three
        // sectors that share no face
        let tau = std::f64::consts::TAU;
        let movable: Vec<usize> = (0..n)
            .filter(|&v| {
                let p = reference[v];
                let sector = (p[1].atan2(p[0]).rem_euclid(tau) / (tau / 3.0)).fract();
                !is_boundary[v] && p[0].hypot(p[1]) > 0.3 && sector > 0.12 && sector < 0.88
            })
            .collect();
        let mut component = vec![usize::MAX; n];
        let mut count = 0;
        for &s in &movable {
            if component[s] == usize::MAX {
                let mut stack = vec![s];
                component[s] = count;
                while let Some(v) = stack.pop() {
                    for &u in &neighbors[v] {
                        if component[u as usize] == usize::MAX && movable.contains(&(u as usize)) {
                            component[u as usize] = count;
                            stack.push(u as usize);
                        }
                    }
                }
                count += 1;
            }
        }
        assert_eq!(count, 3, "three sectors");
        // start: squeezed radially, with one sector squeezed harder (different sweep counts)
        let start = squeezed(&reference, |p| if p[1] > 0.0 { 1.8 } else { 1.4 });
        let floors = retraction_floors(&mesh, &reference);
        let mut one = start.clone();
        let sweeps = retract(
            &mesh.faces,
            &conn.vertex_faces,
            &floors,
            &movable,
            &reference,
            &mut one,
            200,
        );
        let mut parts = start.clone();
        let part_sweeps = retract_components(
            &mesh.faces,
            &conn.vertex_faces,
            &neighbors,
            &floors,
            &movable,
            &reference,
            &mut parts,
            200,
        );
        assert!(sweeps > 2, "the case should need several sweeps, took {sweeps}");
        assert_eq!(part_sweeps, sweeps);
        assert_eq!(parts, one);
        assert_ne!(one, start);
        assert_ne!(one, reference, "the floors should hold some vertices back");
        // a vertex listed twice is tried twice per sweep by both
        let mut repeated = movable.clone();
        repeated.insert(3, movable[movable.len() / 2]);
        let (mut one, mut parts) = (start.clone(), start.clone());
        let sweeps = retract(
            &mesh.faces,
            &conn.vertex_faces,
            &floors,
            &repeated,
            &reference,
            &mut one,
            200,
        );
        let part_sweeps = retract_components(
            &mesh.faces,
            &conn.vertex_faces,
            &neighbors,
            &floors,
            &repeated,
            &reference,
            &mut parts,
            200,
        );
        assert_eq!((part_sweeps, &parts), (sweeps, &one));
    }

    #[test]
    fn half_angle_tangent_is_exact_on_known_angles() {
        let t = half_angle_tan([1.0, 0.0], [0.0, 2.0]);
        assert!((t - 1.0).abs() < 1e-15);
        let t = half_angle_tan([1.0, 0.0], [-1.0, 1.0]); // 135°
        assert!((t - (3.0 * std::f64::consts::PI / 8.0).tan()).abs() < 1e-14);
        let t = half_angle_tan([1e-200, 0.0, 0.0], [1e-200, 1e-200, 0.0]); // 45°, tiny
        assert!((t - (std::f64::consts::PI / 8.0).tan()).abs() < 1e-15);
        assert!(half_angle_tan([0.0, 0.0], [1.0, 0.0]).is_nan());
    }

    #[test]
    fn layout_weights_reproduce_an_embedded_map() {
        // 6 rings: the simplicial LU; 30 rings (2.6k interior vertices): the supernodal one
        for rings in [6, 30] {
            let (mesh, is_boundary, uv) = disk_layout(rings);
            let n = mesh.num_vertices();
            let conn = Connectivity::of(&mesh);
            let neighbors = conn.vertex_neighbors(n);
            let w = tutte_weights(
                &mesh,
                &conn.vertex_faces,
                &neighbors,
                &is_boundary,
                &uv,
                RepairWeights::Layout,
            )
            .unwrap();
            let all_interior: Vec<bool> = is_boundary.iter().map(|b| !b).collect();
            let interior = all_interior.iter().filter(|&&b| b).count();
            assert_eq!(interior >= SUPERNODAL_LU_MIN, rings == 30, "{interior} unknowns");
            let out = solve_region(&neighbors, &w, &all_interior, &uv, None).unwrap();
            let d = max_distance(&out, &uv);
            assert!(d < 1e-14, "{rings} rings: max displacement {d:e}");
        }
    }

    /// A component whose vertex set did not change since the last round is taken from it, and
    /// the positions equal a fresh solve's bit for bit; a grown component is solved again.
    #[test]
    fn unchanged_components_are_taken_from_the_earlier_round() {
        let (mesh, is_boundary, mut uv) = disk_layout(12);
        let n = mesh.num_vertices();
        let mut state = 7u64;
        for (p, &b) in uv.iter_mut().zip(&is_boundary) {
            if !b {
                p[0] += 0.01 * (xorshift(&mut state) as f64 / u64::MAX as f64 - 0.5);
                p[1] += 0.01 * (xorshift(&mut state) as f64 / u64::MAX as f64 - 0.5);
            }
        }
        let conn = Connectivity::of(&mesh);
        let neighbors = conn.vertex_neighbors(n);
        let w = tutte_weights(
            &mesh,
            &conn.vertex_faces,
            &neighbors,
            &is_boundary,
            &uv,
            RepairWeights::Surface,
        )
        .unwrap();
        let near = |c: [f64; 2], r: f64| -> Vec<bool> {
            (0..n)
                .map(|v| !is_boundary[v] && (uv[v][0] - c[0]).hypot(uv[v][1] - c[1]) < r)
                .collect()
        };
        let (a, a_grown, b) = (near([-0.5, 0.0], 0.2), near([-0.5, 0.0], 0.3), near([0.5, 0.0], 0.2));
        let union = |x: &[bool], y: &[bool]| -> Vec<bool> { x.iter().zip(y).map(|(p, q)| *p || *q).collect() };
        let (first, second) = (union(&a, &b), union(&a_grown, &b));
        let mut earlier = ComponentSolutions::new();
        solve_region(&neighbors, &w, &first, &uv, Some(&mut earlier)).unwrap();
        assert_eq!(earlier.len(), 2);
        let cached = solve_region(&neighbors, &w, &second, &uv, Some(&mut earlier)).unwrap();
        let fresh = solve_region(&neighbors, &w, &second, &uv, None).unwrap();
        assert_eq!(cached, fresh);
        assert!(
            max_distance(&fresh, &uv) > 1e-4,
            "the solve moves the jittered vertices"
        );
        // the entry for b is what is taken: a marked copy shows up in the result
        let key_b = earlier.iter().map(|(k, _)| *k).find(|&(v, _)| b[v]).unwrap();
        for (k, solution) in earlier.iter_mut() {
            if *k == key_b {
                solution.iter_mut().for_each(|p| *p = [9.0, 9.0]);
            }
        }
        let marked = solve_region(&neighbors, &w, &second, &uv, Some(&mut earlier)).unwrap();
        for v in 0..n {
            let expected = if b[v] { [9.0, 9.0] } else { fresh[v] };
            assert_eq!(marked[v], expected, "vertex {v}");
        }
    }

    /// The unit test of the issue: fold a known planar disk mesh by pushing an interior vertex
    /// across its neighbours; the repair restores an embedding, moving only nearby vertices.
    #[test]
    fn pushed_vertex_fold_is_repaired_locally() {
        let (mesh, is_boundary, reference) = disk_layout(8);
        let n = mesh.num_vertices();
        let neighbors = Connectivity::of(&mesh).vertex_neighbors(n);
        // an interior vertex on ring 4 and the direction to its farthest neighbour
        let v = (0..n)
            .find(|&v| !is_boundary[v] && (reference[v][0].hypot(reference[v][1]) - 0.5).abs() < 1e-9)
            .unwrap();
        let far = *neighbors[v]
            .iter()
            .max_by(|&&a, &&b| {
                let d = |u: u32| {
                    (reference[u as usize][0] - reference[v][0]).hypot(reference[u as usize][1] - reference[v][1])
                };
                d(a).total_cmp(&d(b))
            })
            .unwrap() as usize;
        let (uv, flipped) = pushed_past(&mesh, &reference, v, far);
        for kind in [RepairWeights::Layout, RepairWeights::Surface] {
            let mut out = uv.clone();
            // the Tutte rounds alone (the kernel untangling would fix this fold by itself: see
            // `pushed_vertex_fold_is_untangled_first`)
            let params = FoldRepairParams {
                weights: kind,
                untangle_sweeps: 0,
                ..Default::default()
            };
            let info = repair_folds(&mesh, &is_boundary, &mut out, &params).unwrap();
            assert!(info.rounds >= 1 && info.untangle == UntangleInfo::default(), "{info:?}");
            let (f, d, _) = folded_faces(&mesh.faces, &out);
            assert_eq!((f, d), (0, 0), "{kind:?}: {info:?}");
            assert_eq!(info.flipped_before, flipped);
            assert_eq!(info.folded_after, 0);
            assert!(!info.whole_disk, "{kind:?}: {info:?}");
            assert!(info.vertices_moved < n / 4, "{kind:?}: {info:?}");
            // vertices far from v do not move
            for u in 0..n {
                let dist = (reference[u][0] - reference[v][0]).hypot(reference[u][1] - reference[v][1]);
                if dist > 0.6 {
                    assert_eq!(out[u], uv[u], "{kind:?}: vertex {u} at distance {dist} moved");
                }
            }
            if kind == RepairWeights::Layout {
                // the pushed vertex's layout weights come from its folded star; it lands within
                // its neighbours' hull, near its old place
                let e = (out[v][0] - reference[v][0]).hypot(out[v][1] - reference[v][1]);
                assert!(
                    e < 0.125,
                    "vertex {v} repaired to {:?}, reference {:?}",
                    out[v],
                    reference[v]
                );
            }
        }
    }

    /// By default the kernel untangling runs first: a single pushed vertex's fold is undone by
    /// moving corners of the folded faces into the kernels of their stars, and no Tutte round
    /// runs.
    #[test]
    fn pushed_vertex_fold_is_untangled_first() {
        let (mesh, is_boundary, reference) = disk_layout(6);
        let v = (0..mesh.num_vertices()).find(|&v| !is_boundary[v] && v > 0).unwrap();
        let conn = Connectivity::of(&mesh);
        let neighbors = conn.vertex_neighbors(mesh.num_vertices());
        let far = neighbors[v][0] as usize;
        let (uv, flipped) = pushed_past(&mesh, &reference, v, far);
        let mut out = uv.clone();
        let info = repair_folds(&mesh, &is_boundary, &mut out, &FoldRepairParams::default()).unwrap();
        assert_eq!(folded_faces(&mesh.faces, &out).2.len(), 0, "{info:?}");
        assert_eq!(info.flipped_before, flipped);
        assert_eq!(
            (info.rounds, info.folded_after, info.untangle.folded_after),
            (0, 0, 0),
            "{info:?}"
        );
        assert!(info.untangle.moves >= 1);
        // only corners of the folded faces move (the sweep visits them in index order, so a
        // neighbour of v may go first); everything else keeps its place
        let corners: std::collections::BTreeSet<usize> = folded_faces(&mesh.faces, &uv)
            .2
            .iter()
            .flat_map(|&f| mesh.faces[f].map(|u| u as usize))
            .collect();
        assert!(corners.contains(&v));
        let moved: Vec<usize> = (0..out.len()).filter(|&u| out[u] != uv[u]).collect();
        assert_eq!(info.vertices_moved, moved.len(), "{info:?}");
        assert!(
            !moved.is_empty() && moved.iter().all(|u| corners.contains(u)),
            "{moved:?} not in {corners:?}"
        );
        assert!(moved.len() < corners.len(), "{moved:?}");
    }

    /// A scrambled map (every interior vertex at a pseudo-random point of the disk) needs the
    /// whole disk: Floater's theorem then gives an embedding.
    #[test]
    fn scrambled_map_is_repaired_on_the_whole_disk() {
        let (mesh, is_boundary, reference) = disk_layout(10);
        let mut uv = reference.clone();
        let mut state = 0x2545_f491_4f6c_dd1du64;
        for (v, p) in uv.iter_mut().enumerate() {
            if !is_boundary[v] {
                let state = xorshift(&mut state);
                let r = 0.9 * ((state >> 11) as f64 / (1u64 << 53) as f64).sqrt();
                let t = (state & 0xffff) as f64 / 65536.0 * std::f64::consts::TAU;
                *p = [r * t.cos(), r * t.sin()];
            }
        }
        let before = folded_faces(&mesh.faces, &uv).0;
        assert!(before > 50, "{before}");
        let info = repair_folds(&mesh, &is_boundary, &mut uv, &FoldRepairParams::default()).unwrap();
        assert_eq!(folded_faces(&mesh.faces, &uv).2.len(), 0, "{info:?}");
        assert!(info.whole_disk, "{info:?}");
        for (v, p) in uv.iter().enumerate() {
            if is_boundary[v] {
                assert_eq!(*p, reference[v]);
            } else {
                assert!(p[0].hypot(p[1]) < 1.0);
            }
        }
    }

    #[test]
    fn disabled_repair_only_counts() {
        let (mesh, is_boundary, reference) = disk_layout(4);
        let mut uv = reference.clone();
        let v = (0..mesh.num_vertices()).find(|&v| !is_boundary[v] && v > 0).unwrap();
        uv[v] = [-uv[v][0] * 3.0, -uv[v][1] * 3.0];
        let before = uv.clone();
        let info = repair_folds(
            &mesh,
            &is_boundary,
            &mut uv,
            &FoldRepairParams {
                enabled: false,
                ..Default::default()
            },
        )
        .unwrap();
        assert_eq!(uv, before);
        assert!(info.flipped_before > 0 && info.folded_after == info.flipped_before + info.degenerate_before);
        assert_eq!((info.rounds, info.vertices_moved), (0, 0));
    }

    /// Kernel untangling of a pushed vertex: the fold is removed, the count never grows, and
    /// fixed vertices (the boundary and a pinned "landmark") do not move.
    #[test]
    fn untangle_kernels_removes_a_pushed_fold_and_keeps_fixed_vertices() {
        let (mesh, is_boundary, reference) = disk_layout(8);
        let n = mesh.num_vertices();
        let conn = Connectivity::of(&mesh);
        let neighbors = conn.vertex_neighbors(n);
        let v = (0..n)
            .find(|&v| !is_boundary[v] && (reference[v][0].hypot(reference[v][1]) - 0.5).abs() < 1e-9)
            .unwrap();
        let far = neighbors[v][0] as usize;
        let (mut uv, _) = pushed_past(&mesh, &reference, v, far);
        let mut fixed = is_boundary.clone();
        let pinned = neighbors[v]
            .iter()
            .map(|&u| u as usize)
            .find(|&u| u != far && !is_boundary[u])
            .unwrap();
        fixed[pinned] = true;
        let before = uv.clone();
        let info = untangle_kernels(&mesh.faces, &conn.vertex_faces, &fixed, &mut uv, 20);
        assert!(info.folded_before >= 2, "{info:?}");
        assert_eq!(info.folded_after, 0, "{info:?}");
        assert_eq!(count_folded_faces(&mesh.faces, &uv), 0);
        for u in (0..n).filter(|&u| fixed[u]) {
            assert_eq!(uv[u], before[u], "fixed vertex {u} moved");
        }
        // an embedded map is left as it is
        let mut clean = reference.clone();
        let info = untangle_kernels(&mesh.faces, &conn.vertex_faces, &is_boundary, &mut clean, 20);
        assert_eq!((info.folded_before, info.moves), (0, 0));
        assert_eq!(clean, reference);
    }

    /// The mean-value Tutte map reproduces an embedded layout when its vertices are pinned where
    /// the layout has them (here: the boundary and one interior landmark), and with a warped but
    /// embedded layout (r ↦ r², boundary fixed) it is an embedding.
    #[test]
    fn mean_value_tutte_map_reproduces_and_embeds() {
        let (mesh, is_boundary, reference) = disk_layout(8);
        let n = mesh.num_vertices();
        let landmark = (0..n).find(|&v| !is_boundary[v] && reference[v][0] > 0.3).unwrap();
        let fixed: Vec<Option<[f64; 2]>> = (0..n)
            .map(|v| (is_boundary[v] || v == landmark).then_some(reference[v]))
            .collect();
        let out = mean_value_tutte_map(&mesh, &reference, &fixed).unwrap();
        let d = max_distance(&out, &reference);
        assert!(d < 1e-12, "max displacement {d:e}");
        let warped: Vec<[f64; 2]> = reference
            .iter()
            .map(|p| {
                let r = p[0].hypot(p[1]);
                [p[0] * r, p[1] * r]
            })
            .collect();
        let boundary_only: Vec<Option<[f64; 2]>> = (0..n).map(|v| is_boundary[v].then_some(warped[v])).collect();
        let out = mean_value_tutte_map(&mesh, &warped, &boundary_only).unwrap();
        assert_eq!(count_folded_faces(&mesh.faces, &out), 0);
        // the bad inputs are errors
        assert!(mean_value_tutte_map(&mesh, &reference[..n - 1], &fixed).is_err());
        let free_boundary: Vec<Option<[f64; 2]>> = vec![None; n];
        assert!(mean_value_tutte_map(&mesh, &reference, &free_boundary).is_err());
    }
}
