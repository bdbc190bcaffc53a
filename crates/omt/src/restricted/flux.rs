//! Flux (divergence-theorem) form of the integrals a Newton evaluation needs: the cell masses
//! μ(W_i ∩ Ω) and the edge masses ∫_{e_ij ∩ Ω} ρ ds, without the moments.
//!
//! **The field.** Once per source measure we build a vector field F on Ω that is linear on each
//! triangle t, F_t(x) = a_t + b_t (x − c_t) (c_t the centroid), with
//! $$ \operatorname{div} F_t = 2 b_t = \rho_t \quad\text{and the normal component } F\cdot n
//! \text{ continuous across every interior edge,} $$
//! i.e. a lowest-order Raviart–Thomas field whose divergence is the density. Its edge fluxes
//! f_e come from a finite-volume Poisson problem on the triangles (two-point fluxes
//! f_e = w_e (λ_t − λ_t′), w_e = |e| / |c_t − c_t′|, λ = 0 outside Ω): (Σ_e w_e …) λ_t = ρ_t |t|, one
//! sparse Cholesky solve per measure. The flux out of each triangle then sums to its mass up to
//! the solve's residual; b_t takes that sum / 2|t| (a relative change of the density of
//! ~1e-15), a_t is fitted to the fluxes, and the normal component is continuous exactly.
//!
//! **The integrals.** By the divergence theorem, for any constant vector F₀,
//! $$ \mu(W_i \cap \Omega) = \sum_j \int_{e_{ij} \cap \Omega} (F - F_0)\cdot n_{ij}\,ds +
//! \int_{\partial\Omega \cap W_i} (F - F_0)\cdot n\,ds, $$
//! with n_ij the unit normal from y_i towards y_j. So each power edge is traced through the
//! source triangles it crosses (a straight walk with exact orientation tests), adding per piece
//! its length × (F_t(midpoint) − F₀)·n_ij to the mass of i, the opposite to j, and ρ_t × length to
//! the edge mass; the arcs of ∂Ω between consecutive crossings of power edges add their share of
//! the boundary edges' fluxes. F₀ is F at one of the cell's vertices, so that the terms are of the
//! size of the cell's mass rather than of F × its perimeter. The work is proportional to the
//! crossings of power edges with source edges (plus one walk locating each power vertex); on
//! face pairs an evaluation costs about 60 % of the boundary form's (module `boundary`); the
//! field is built once per measure and shared by all solves from it
//! (`docs/decisions/0010-restricted-integration.md`).
//!
//! **When it declines.** The walks decide with exact predicates, but the positions are floating
//! point, so each cell gets an error estimate (the terms' rounding, and the endpoints' position
//! errors, including the power centres' with the conditioning of their systems, times the
//! field). When a bound exceeds the caller's fraction of its cell's mass (the
//! Newton solver asks for a hundredth of its tolerance: 1e-8 by default; slivers and cells much
//! smaller than their distance to the origin allows decline), when a walk gets stuck, when the
//! crossings along ∂Ω do not alternate between the right cells, or when the diagram is not
//! two-dimensional, the evaluation is left to the full integration. A measure whose triangles
//! do not form a convex disk (a single boundary loop without reflex corners) never uses this form.

use faer::dyn_stack::{MemBuffer, MemStack};
use faer::sparse::linalg::cholesky::{factorize_symbolic_cholesky, CholeskySymbolicParams, LltRef, SymmetricOrdering};
use faer::sparse::linalg::SupernodalThreshold;
use faer::sparse::{SparseColMat, Triplet};
use faer::{Conj, MatMut, Par, Side};
use rayon::prelude::*;

use super::power_line_between;
use crate::cells::CellIntegrals;
use crate::power_diagram::PowerDiagram;
use crate::predicates::orient;

const NONE: u32 = u32::MAX;

/// The next corner (or edge) of a triangle, counter-clockwise; edge k runs from corner k to
/// corner k + 1.
const NEXT: [usize; 3] = [1, 2, 0];

/// The Raviart–Thomas field of one source measure and the adjacency its walks use.
#[derive(Clone, Debug)]
pub(crate) struct FluxField {
    /// Per triangle: F_t(x) = a_t + b_t (x − c_t).
    a: Vec<[f64; 2]>,
    b: Vec<f64>,
    centroids: Vec<[f64; 2]>,
    /// Per triangle and edge k: 4 × the triangle across + the index of the shared edge in it,
    /// or NONE on ∂Ω.
    across: Vec<[u32; 3]>,
    /// Per triangle and edge k on ∂Ω: the edge's index in the boundary loop.
    loop_index: Vec<[u32; 3]>,
    /// The boundary loop, counter-clockwise: each edge's start point (it ends at the next one's),
    /// its triangle, and the outward flux of F through it.
    loop_points: Vec<[f64; 2]>,
    loop_triangles: Vec<u32>,
    loop_flux: Vec<f64>,
    /// Largest |coordinate| of a vertex: scales position errors.
    extent: f64,
}

/// Where a walk along a segment ended.
enum End {
    /// The segment's end point lies in this triangle.
    Inside(u32),
    /// The segment leaves Ω through boundary-loop edge `edge`, at position `s` ∈ [0, 1] along it.
    Boundary { edge: u32, s: f64 },
    /// No consistent exit (degenerate input, or more steps than triangles).
    Stuck,
}

/// A crossing of a power edge with ∂Ω: boundary edge, position along it, and the cells before
/// and after it counter-clockwise along ∂Ω.
#[derive(Clone, Copy, Debug)]
struct Crossing {
    edge: u32,
    s: f64,
    from: u32,
    to: u32,
    /// Bound on the crossing point's position error.
    error: f64,
}

/// A power centre, the source triangle holding it (NONE: outside Ω) and its error estimate.
type LocatedCentre = ([f64; 2], u32, f64);

/// The edges traced by one chunk of triangles and their crossings with ∂Ω (`None`: declined).
type TracedChunk = Option<(Vec<EdgeTerms>, Vec<Crossing>)>;

/// Per cell: masses, error estimates; the edge masses; the crossings with ∂Ω.
type CellSums = (Vec<f64>, Vec<f64>, Vec<(u32, u32, f64)>, Vec<Crossing>);

/// What the tracing of the power edges reads: the source mesh and densities, the diagram, the
/// located power centres and the cells' fields F₀.
#[derive(Clone, Copy)]
struct TraceInput<'a> {
    vertices: &'a [[f64; 2]],
    triangles: &'a [[u32; 3]],
    densities: &'a [f64],
    diagram: &'a PowerDiagram,
    centres: &'a [LocatedCentre],
    f0: &'a [[f64; 2]],
}

/// A power edge's segment to trace (see `FluxField::power_edge_segment`): its ends p, q and the
/// source triangles holding them (NONE: outside Ω), the unit normal and the vector from y_i to
/// y_j, and the bound on its points' position error.
struct EdgeSegment {
    p: [f64; 2],
    q: [f64; 2],
    p_tri: u32,
    q_tri: u32,
    normal: [f64; 2],
    dij: [f64; 2],
    position_error: f64,
}

/// One traced power edge: its two cells, their mass terms and error estimates, and the edge mass.
#[derive(Clone, Copy, Debug)]
struct EdgeTerms {
    i: u32,
    j: u32,
    term_i: f64,
    term_j: f64,
    error_i: f64,
    error_j: f64,
    edge_mass: f64,
}

/// max(|x₀|, |x₁|).
#[inline]
fn magnitude(x: [f64; 2]) -> f64 {
    x[0].abs().max(x[1].abs())
}

#[inline]
fn cross(u: [f64; 2], v: [f64; 2]) -> f64 {
    u[0] * v[1] - u[1] * v[0]
}

#[inline]
fn sub(u: [f64; 2], v: [f64; 2]) -> [f64; 2] {
    [u[0] - v[0], u[1] - v[1]]
}

impl FluxField {
    /// The field of the measure (vertices, counter-clockwise triangles, densities, areas), or
    /// `None` when its triangles do not form a convex topological disk or the Poisson solve
    /// fails.
    pub(super) fn new(
        vertices: &[[f64; 2]],
        triangles: &[[u32; 3]],
        densities: &[f64],
        areas: &[f64],
    ) -> Option<FluxField> {
        let nt = triangles.len();
        if nt == 0 || nt >= NONE as usize / 4 {
            return None;
        }
        let (across, boundary) = edge_adjacency(triangles)?;
        if boundary.len() < 3 {
            return None;
        }
        let loop_edges = boundary_loop(triangles, &boundary)?;
        let m = loop_edges.len();
        let loop_points: Vec<[f64; 2]> = loop_edges
            .iter()
            .map(|&e| vertices[triangles[e as usize / 3][e as usize % 3] as usize])
            .collect();
        for q in 0..m {
            let (u, v, w) = (loop_points[q], loop_points[(q + 1) % m], loop_points[(q + 2) % m]);
            if orient(u, v, w) < 0 {
                return None; // a reflex corner: Ω is not convex
            }
        }
        let mut loop_index = vec![[NONE; 3]; nt];
        for (q, &e) in loop_edges.iter().enumerate() {
            loop_index[e as usize / 3][e as usize % 3] = q as u32;
        }
        let centroids: Vec<[f64; 2]> = triangles
            .iter()
            .map(|t| {
                let [a, b, c] = t.map(|v| vertices[v as usize]);
                [(a[0] + b[0] + c[0]) / 3.0, (a[1] + b[1] + c[1]) / 3.0]
            })
            .collect();
        // Two-point flux weights and the Poisson matrix (lower triangle).
        let corner = |t: usize, k: usize| vertices[triangles[t][k] as usize];
        let weight = |t: usize, k: usize| -> f64 {
            let (p, q) = (corner(t, k), corner(t, NEXT[k]));
            let length = ((q[0] - p[0]) * (q[0] - p[0]) + (q[1] - p[1]) * (q[1] - p[1])).sqrt();
            let other = across[t][k] >> 2;
            let distance = if across[t][k] == NONE {
                let mid = [0.5 * (p[0] + q[0]), 0.5 * (p[1] + q[1])];
                2.0 * (mid[0] - centroids[t][0]).hypot(mid[1] - centroids[t][1])
            } else {
                let c = centroids[other as usize];
                (c[0] - centroids[t][0]).hypot(c[1] - centroids[t][1])
            };
            length / distance.max(1e-3 * length)
        };
        let mut triplets: Vec<Triplet<usize, usize, f64>> = Vec::with_capacity(3 * nt);
        let mut diagonal = vec![0.0; nt];
        for t in 0..nt {
            for k in 0..3 {
                let w = weight(t, k);
                diagonal[t] += w;
                let other = across[t][k] >> 2;
                if across[t][k] != NONE && (other as usize) < t {
                    triplets.push(Triplet::new(t, other as usize, -w));
                }
            }
        }
        for (t, &d) in diagonal.iter().enumerate() {
            triplets.push(Triplet::new(t, t, d));
        }
        let mut lambda: Vec<f64> = (0..nt).map(|t| densities[t] * areas[t]).collect();
        solve_poisson(nt, &triplets, &mut lambda)?;
        if lambda.iter().any(|l| !l.is_finite()) {
            return None;
        }
        // Per triangle: outward fluxes, b_t from their sum, a_t fitted to edges 0 and 1.
        let mut a = vec![[0.0; 2]; nt];
        let mut b = vec![0.0; nt];
        for t in 0..nt {
            let flux: [f64; 3] = std::array::from_fn(|k| {
                let other = across[t][k];
                let outside = if other == NONE {
                    0.0
                } else {
                    lambda[(other >> 2) as usize]
                };
                weight(t, k) * (lambda[t] - outside)
            });
            let bt = (flux[0] + flux[1] + flux[2]) / (2.0 * areas[t]);
            // a·N_k = f_k − b (mid_k − c)·N_k with N_k the outward normal scaled by |e_k|
            let row = |k: usize| {
                let (p, q) = (corner(t, k), corner(t, NEXT[k]));
                let n = [q[1] - p[1], p[0] - q[0]];
                let mid = [
                    0.5 * (p[0] + q[0]) - centroids[t][0],
                    0.5 * (p[1] + q[1]) - centroids[t][1],
                ];
                (n, flux[k] - bt * (mid[0] * n[0] + mid[1] * n[1]))
            };
            let ((n0, r0), (n1, r1)) = (row(0), row(1));
            let det = n0[0] * n1[1] - n0[1] * n1[0];
            a[t] = [(r0 * n1[1] - r1 * n0[1]) / det, (n0[0] * r1 - n1[0] * r0) / det];
            b[t] = bt;
            if !(a[t][0].is_finite() && a[t][1].is_finite() && bt.is_finite()) {
                return None;
            }
        }
        let loop_triangles: Vec<u32> = loop_edges.iter().map(|&e| e / 3).collect();
        let loop_flux: Vec<f64> = loop_edges
            .iter()
            .map(|&e| {
                let (t, k) = (e as usize / 3, e as usize % 3);
                weight(t, k) * lambda[t]
            })
            .collect();
        let extent = vertices.iter().fold(0.0f64, |r, &p| r.max(magnitude(p)));
        Some(FluxField {
            a,
            b,
            centroids,
            across,
            loop_index,
            loop_points,
            loop_triangles,
            loop_flux,
            extent,
        })
    }

    /// F_t(x).
    #[inline]
    fn field(&self, t: usize, x: [f64; 2]) -> [f64; 2] {
        let (a, b, c) = (self.a[t], self.b[t], self.centroids[t]);
        [a[0] + b * (x[0] - c[0]), a[1] + b * (x[1] - c[1])]
    }

    /// Walks the triangulation along p → q from triangle `tri`, which the segment crosses at
    /// parameters ≥ `t_prev` (it contains p, or the segment enters Ω through one of its edges
    /// at `t_prev`), calling `piece(triangle, t0, t1)` for the part in each triangle. Exact
    /// orientation tests decide the exits (a corner on the line counts as left of it).
    #[allow(clippy::too_many_arguments)]
    fn walk(
        &self,
        vertices: &[[f64; 2]],
        triangles: &[[u32; 3]],
        p: [f64; 2],
        q: [f64; 2],
        mut tri: u32,
        mut t_prev: f64,
        mut piece: impl FnMut(u32, f64, f64),
    ) -> End {
        let d = sub(q, p);
        let corners_of = |t: u32| triangles[t as usize].map(|v| vertices[v as usize]);
        let mut corners = corners_of(tri);
        let mut o: [i8; 3] = std::array::from_fn(|k| orient(p, q, corners[k]));
        for _ in 0..=self.a.len() {
            let Some(k) = (0..3).find(|&k| o[k] < 0 && o[NEXT[k]] >= 0) else {
                if p == q {
                    return End::Inside(tri);
                }
                return End::Stuck;
            };
            let (u, v) = (corners[k], corners[NEXT[k]]);
            if orient(u, v, q) >= 0 {
                piece(tri, t_prev, 1.0);
                return End::Inside(tri);
            }
            let e = sub(v, u);
            let t_cross = cross(sub(u, p), e) / cross(d, e);
            if !t_cross.is_finite() {
                return End::Stuck; // the line along the edge, to rounding
            }
            let t_cross = t_cross.clamp(t_prev, 1.0);
            piece(tri, t_prev, t_cross);
            let next = self.across[tri as usize][k];
            if next == NONE {
                let (ou, ov) = (cross(d, sub(u, p)), cross(d, sub(v, p)));
                let s = if ou != ov {
                    (ou / (ou - ov)).clamp(0.0, 1.0)
                } else {
                    0.5
                };
                return End::Boundary {
                    edge: self.loop_index[tri as usize][k],
                    s,
                };
            }
            // In the next triangle the shared edge runs v → u (corners nk, nk + 1): only its
            // third corner needs a new orientation test.
            let (nt, nk) = (next >> 2, (next & 3) as usize);
            let next_corners = corners_of(nt);
            let mut next_o = [0i8; 3];
            next_o[nk] = o[NEXT[k]];
            next_o[NEXT[nk]] = o[k];
            let w = NEXT[NEXT[nk]];
            next_o[w] = orient(p, q, next_corners[w]);
            tri = nt;
            corners = next_corners;
            o = next_o;
            t_prev = t_cross;
        }
        End::Stuck
    }

    /// Where segment p → q (p outside Ω) enters Ω: (parameter, boundary-loop edge, position
    /// along it), by clipping against every boundary edge's line; `None` when it misses Ω.
    fn entry(&self, p: [f64; 2], q: [f64; 2]) -> Option<(f64, u32, f64)> {
        let m = self.loop_points.len();
        let (mut t0, mut t1) = (0.0f64, 1.0f64);
        let mut entry_edge = NONE;
        for e in 0..m {
            let (a, b) = (self.loop_points[e], self.loop_points[(e + 1) % m]);
            let ab = sub(b, a);
            let (gp, gq) = (cross(ab, sub(p, a)), cross(ab, sub(q, a)));
            if gp < 0.0 && gq < 0.0 {
                return None;
            }
            if gp < 0.0 {
                let t = gp / (gp - gq);
                if t > t0 {
                    t0 = t;
                    entry_edge = e as u32;
                }
            } else if gq < 0.0 {
                let t = gp / (gp - gq);
                if t < t1 {
                    t1 = t;
                }
            }
        }
        if entry_edge == NONE || t0 >= t1 {
            return None;
        }
        let (a, b) = (
            self.loop_points[entry_edge as usize],
            self.loop_points[(entry_edge as usize + 1) % m],
        );
        let x = [p[0] + t0 * (q[0] - p[0]), p[1] + t0 * (q[1] - p[1])];
        let ab = sub(b, a);
        let s = ((x[0] - a[0]) * ab[0] + (x[1] - a[1]) * ab[1]) / (ab[0] * ab[0] + ab[1] * ab[1]);
        Some((t0, entry_edge, s.clamp(0.0, 1.0)))
    }

    /// Per site, the source triangle containing it, or for a site outside Ω the boundary
    /// triangle where the walk towards it left Ω. Walks from site to site along a Hilbert curve,
    /// the first from `triangle_order[0]`.
    pub(super) fn locate_sites(
        &self,
        vertices: &[[f64; 2]],
        triangles: &[[u32; 3]],
        sites: &[[f64; 2]],
        triangle_order: &[u32],
    ) -> Vec<u32> {
        let mut out = vec![0u32; sites.len()];
        let mut hint = triangle_order.first().copied().unwrap_or(0);
        for i in crate::power_diagram::hilbert_order(sites) {
            let y = sites[i as usize];
            let c = self.centroids[hint as usize];
            if y[0].is_finite() && y[1].is_finite() {
                hint = match self.walk(vertices, triangles, c, y, hint, 0.0, |_, _, _| {}) {
                    End::Inside(t) => t,
                    End::Boundary { edge, .. } => self.loop_triangles[edge as usize],
                    End::Stuck => hint,
                };
            }
            out[i as usize] = hint;
        }
        out
    }

    /// Masses and edge masses of the cells of `diagram` restricted to Ω (moments left empty), or
    /// `None` when this form declines (module docs). `site_triangles`: per site, a triangle at or
    /// near it (the start of the walks locating its cell's vertices).
    pub(super) fn integrate(
        &self,
        vertices: &[[f64; 2]],
        triangles: &[[u32; 3]],
        densities: &[f64],
        diagram: &PowerDiagram,
        site_triangles: &[u32],
        relative_bound: f64,
    ) -> Option<CellIntegrals> {
        let n = diagram.num_sites();
        if diagram.dimension() != 2 || site_triangles.len() != n {
            return None;
        }
        let (tv, _) = diagram.raw_triangulation();
        let chunk = tv.len().div_ceil(64).max(1);
        let centres = self.locate_centres(vertices, triangles, diagram, site_triangles, chunk)?;
        let f0 = self.cell_fields(diagram, &centres, site_triangles);
        let input = TraceInput {
            vertices,
            triangles,
            densities,
            diagram,
            centres: &centres,
            f0: &f0,
        };
        // Pass 2: trace every power edge once (from the finite triangle whose sorted vertices
        // come first, or from its only finite triangle for a ray).
        let traced: Vec<TracedChunk> = (0..tv.len())
            .collect::<Vec<_>>()
            .par_chunks(chunk)
            .map(|part| {
                let mut edges = Vec::new();
                let mut crossings = Vec::new();
                for &t in part {
                    if !finite_triangle(&tv[t], n) {
                        continue;
                    }
                    for k in 0..3 {
                        self.trace_power_edge(&input, t, k, &mut edges, &mut crossings)?;
                    }
                }
                Some((edges, crossings))
            })
            .collect();
        let (mut masses, mut errors, edge_masses, crossings) = sum_edge_terms(diagram, traced)?;
        self.add_boundary_arcs(diagram, &f0, crossings, &mut masses, &mut errors)?;
        for i in 0..n {
            let empty = masses[i] == 0.0 && errors[i] == 0.0;
            if !empty && !(errors[i] <= relative_bound * masses[i]) {
                return None;
            }
        }
        Some(CellIntegrals {
            masses,
            first_moments: Vec::new(),
            second_moments: Vec::new(),
            edge_masses,
        })
    }

    /// Pass 1 of [`Self::integrate`]: the power centres of the finite triangles of `diagram`
    /// (in its storage order; NaN for the others) and the source triangle holding each (NONE:
    /// outside Ω); `None` when a walk gets stuck or a centre cannot be computed.
    fn locate_centres(
        &self,
        vertices: &[[f64; 2]],
        triangles: &[[u32; 3]],
        diagram: &PowerDiagram,
        site_triangles: &[u32],
        chunk: usize,
    ) -> Option<Vec<LocatedCentre>> {
        let (tv, _) = diagram.raw_triangulation();
        let n = diagram.num_sites();
        let located: Vec<Option<Vec<LocatedCentre>>> = tv
            .par_chunks(chunk)
            .map(|part| {
                let mut out = Vec::with_capacity(part.len());
                for t in part {
                    if !finite_triangle(t, n) {
                        out.push(([f64::NAN; 2], NONE, 0.0));
                        continue;
                    }
                    let t = canonical(*t);
                    let (centre, centre_error) = power_centre(diagram, t)?;
                    let start = site_triangles[t[0] as usize];
                    let c = self.centroids[start as usize];
                    let where_ = match self.walk(vertices, triangles, c, centre, start, 0.0, |_, _, _| {}) {
                        End::Inside(s) => s,
                        End::Boundary { .. } => NONE,
                        End::Stuck => return None,
                    };
                    out.push((centre, where_, centre_error));
                }
                Some(out)
            })
            .collect();
        let mut centres = Vec::with_capacity(tv.len());
        for part in located {
            centres.extend(part?);
        }
        Some(centres)
    }

    /// F₀ per cell: the field at one of its vertices (of the incident triangle whose sorted
    /// vertices come first, so independent of the storage order), or at its site when that
    /// vertex is outside Ω: close to the cell even when the weights put it far from its site.
    fn cell_fields(&self, diagram: &PowerDiagram, centres: &[LocatedCentre], site_triangles: &[u32]) -> Vec<[f64; 2]> {
        let (tv, _) = diagram.raw_triangulation();
        let n = diagram.num_sites();
        let sites = diagram.sites();
        let mut anchor: Vec<Option<([u32; 3], usize)>> = vec![None; n];
        for (k, t) in tv.iter().enumerate() {
            if !finite_triangle(t, n) {
                continue;
            }
            let mut sorted = *t;
            sorted.sort_unstable();
            for &v in t {
                let slot = &mut anchor[v as usize];
                if slot.is_none_or(|(s, _)| sorted < s) {
                    *slot = Some((sorted, k));
                }
            }
        }
        (0..n)
            .map(|i| match anchor[i] {
                Some((_, k)) if centres[k].1 != NONE => self.field(centres[k].1 as usize, centres[k].0),
                _ => self.field(site_triangles[i] as usize, sites[i]),
            })
            .collect()
    }

    /// Traces the power edge opposite corner `k` of the diagram's triangle `t` (unless the
    /// neighbouring finite triangle traces it): its pieces in Ω give both cells' flux terms and
    /// the edge mass (pushed to `edges` when positive), its ends on ∂Ω the `crossings`. `None`
    /// when this form declines.
    fn trace_power_edge(
        &self,
        input: &TraceInput<'_>,
        t: usize,
        k: usize,
        edges: &mut Vec<EdgeTerms>,
        crossings: &mut Vec<Crossing>,
    ) -> Option<()> {
        let TraceInput {
            vertices,
            triangles,
            densities,
            diagram,
            centres,
            f0,
        } = *input;
        let (tv, tn) = diagram.raw_triangulation();
        let n = diagram.num_sites();
        let other = tn[t][k];
        let other_finite = other != NONE && finite_triangle(&tv[other as usize], n);
        // (traced from the triangle whose sorted vertices come first, so that an
        // edge's terms do not depend on how the triangulation stores it)
        let sorted = |t: [u32; 3]| {
            let mut t = t;
            t.sort_unstable();
            t
        };
        if other_finite && sorted(tv[other as usize]) < sorted(tv[t]) {
            return Some(());
        }
        let (i, j) = (tv[t][NEXT[k]], tv[t][NEXT[NEXT[k]]]);
        let EdgeSegment {
            p,
            q,
            p_tri,
            q_tri,
            normal,
            dij,
            position_error,
        } = self.power_edge_segment(diagram, centres, t, (i, j), other_finite.then_some(other as usize))?;
        let mut terms = EdgeTerms {
            i,
            j,
            term_i: 0.0,
            term_j: 0.0,
            error_i: 0.0,
            error_j: 0.0,
            edge_mass: 0.0,
        };
        let (fi, fj) = (f0[i as usize], f0[j as usize]);
        let mut add_piece = |a: [f64; 2], b: [f64; 2], tri: u32, t0: f64, t1: f64| {
            if !(t1 > t0) {
                return;
            }
            let ab = sub(b, a);
            let length = (t1 - t0) * (ab[0] * ab[0] + ab[1] * ab[1]).sqrt();
            let tm = 0.5 * (t0 + t1);
            let x = [a[0] + tm * ab[0], a[1] + tm * ab[1]];
            let f = self.field(tri as usize, x);
            let (gi, gj) = (sub(f, fi), sub(f, fj));
            let (ni, nj) = (
                gi[0] * normal[0] + gi[1] * normal[1],
                gj[0] * normal[0] + gj[1] * normal[1],
            );
            terms.term_i += length * ni;
            terms.term_j -= length * nj;
            // rounding of the term, and the endpoints' position errors
            terms.error_i += 4.0 * f64::EPSILON * (length * ni).abs() + position_error * (gi[0].abs() + gi[1].abs());
            terms.error_j += 4.0 * f64::EPSILON * (length * nj).abs() + position_error * (gj[0].abs() + gj[1].abs());
            terms.edge_mass += densities[tri as usize] * length;
        };
        // the cells before and after a crossing, counter-clockwise along ∂Ω
        let crossing = |edge: u32, s: f64| -> Option<Crossing> {
            let m = self.loop_points.len();
            let e = edge as usize;
            let along = sub(self.loop_points[(e + 1) % m], self.loop_points[e]);
            let dot = along[0] * dij[0] + along[1] * dij[1];
            let (from, to) = match dot.partial_cmp(&0.0) {
                Some(std::cmp::Ordering::Greater) => (i, j),
                Some(std::cmp::Ordering::Less) => (j, i),
                _ => return None,
            };
            Some(Crossing {
                edge,
                s,
                from,
                to,
                error: position_error,
            })
        };
        if p_tri != NONE {
            match self.walk(vertices, triangles, p, q, p_tri, 0.0, |tri, t0, t1| {
                add_piece(p, q, tri, t0, t1)
            }) {
                End::Inside(_) => {}
                End::Boundary { edge, s, .. } => crossings.push(crossing(edge, s)?),
                End::Stuck => return None,
            }
        } else if q_tri != NONE {
            match self.walk(vertices, triangles, q, p, q_tri, 0.0, |tri, t0, t1| {
                add_piece(q, p, tri, t0, t1)
            }) {
                End::Inside(_) => {}
                End::Boundary { edge, s, .. } => crossings.push(crossing(edge, s)?),
                End::Stuck => return None,
            }
        } else if let Some((t_in, edge_in, s_in)) = self.entry(p, q) {
            let start = self.loop_triangles[edge_in as usize];
            match self.walk(vertices, triangles, p, q, start, t_in, |tri, t0, t1| {
                add_piece(p, q, tri, t0, t1)
            }) {
                End::Boundary { edge, s, .. } => {
                    crossings.push(crossing(edge_in, s_in)?);
                    crossings.push(crossing(edge, s)?);
                }
                End::Inside(_) | End::Stuck => return None,
            }
        }
        if terms.edge_mass > 0.0 {
            edges.push(terms);
        }
        Some(())
    }

    /// The power edge of sites (i, j) between the centre of the diagram's triangle `t` and
    /// that of its finite neighbour `other` (None: a ray to beyond Ω), its ends outside Ω moved
    /// onto the line within reach of Ω, the unit normal from y_i to y_j, and the bound on the
    /// position error of its points. `None` for coincident sites.
    fn power_edge_segment(
        &self,
        diagram: &PowerDiagram,
        centres: &[LocatedCentre],
        t: usize,
        (i, j): (u32, u32),
        other: Option<usize>,
    ) -> Option<EdgeSegment> {
        let sites = diagram.sites();
        let (yi, yj) = (sites[i as usize], sites[j as usize]);
        let dij = sub(yj, yi);
        let norm = (dij[0] * dij[0] + dij[1] * dij[1]).sqrt();
        if !(norm > 0.0) {
            return None;
        }
        let normal = [dij[0] / norm, dij[1] / norm];
        // The power line of (i, j), x·d = c relative to y_i: its point x0 nearest
        // to y_i and its direction τ (to the right of y_i → y_j, away from t).
        let (_, c) = power_line_between(diagram, i as usize, j as usize);
        let x0 = [yi[0] + c / norm * normal[0], yi[1] + c / norm * normal[1]];
        let tau = [normal[1], -normal[0]];
        // Points of Ω on the line have |s| ≤ |x0| + √2 extent along τ from x0.
        let reach = ((x0[0] * x0[0] + x0[1] * x0[1]).sqrt() + std::f64::consts::SQRT_2 * self.extent) * (1.0 + 1e-12);
        let on_line = |s: f64| [x0[0] + s * tau[0], x0[1] + s * tau[1]];
        let along = |x: [f64; 2]| (x[0] - x0[0]) * tau[0] + (x[1] - x0[1]) * tau[1];
        // An end point outside Ω is replaced by the point of the line at its
        // position, clamped to ±reach: a power centre far away (nearly collinear
        // sites) has an absolute error ε|p| that would shift the line near Ω.
        let (p, p_tri, p_error) = centres[t];
        let p = if p_tri == NONE {
            on_line(along(p).clamp(-reach, reach))
        } else {
            p
        };
        let (q, q_tri, q_error) = if let Some(other) = other {
            let (q, q_tri, q_error) = centres[other];
            let q = if q_tri == NONE {
                on_line(along(q).clamp(-reach, reach))
            } else {
                q
            };
            (q, q_tri, q_error)
        } else {
            // a ray along τ (away from the triangle), to beyond Ω
            (on_line(reach), NONE, 0.0)
        };
        // The walk starts at p when p is in Ω, else at q when q is; its pieces' end
        // points a + t (b − a) lie in Ω, so t |b − a| ≤ |a| + extent, and with the
        // rounding of t, of the product and of the sum their error is below a
        // few ε (|a| + extent), plus the line's own (ε |x0|).
        let start = if p_tri == NONE && q_tri != NONE { q } else { p };
        // plus the error of the power centres (an estimate: crossings at shallow
        // angles are not magnified; convergence is decided on the full integrals
        // in any case)
        let position_error =
            4.0 * f64::EPSILON * (magnitude(start) + magnitude(x0) + self.extent) + p_error.max(q_error);
        Some(EdgeSegment {
            p,
            q,
            p_tri,
            q_tri,
            normal,
            dij,
            position_error,
        })
    }

    /// The arcs of ∂Ω: between consecutive `crossings` counter-clockwise, each in the cell
    /// entered (all of ∂Ω in one cell when there is no crossing), added to `masses` and
    /// `errors`. `None` when the crossings do not chain.
    fn add_boundary_arcs(
        &self,
        diagram: &PowerDiagram,
        f0: &[[f64; 2]],
        mut crossings: Vec<Crossing>,
        masses: &mut [f64],
        errors: &mut [f64],
    ) -> Option<()> {
        let m = self.loop_points.len();
        let arc =
            |cell: usize, e: usize, from: f64, to: f64, position_error: f64, masses: &mut [f64], errors: &mut [f64]| {
                let (a, b) = (self.loop_points[e], self.loop_points[(e + 1) % m]);
                let outward = [b[1] - a[1], a[0] - b[0]];
                let g = self.loop_flux[e] - (f0[cell][0] * outward[0] + f0[cell][1] * outward[1]);
                let share = (to - from) * g;
                masses[cell] += share;
                errors[cell] += 4.0 * f64::EPSILON * share.abs()
                    + position_error * g.abs() / (outward[0] * outward[0] + outward[1] * outward[1]).sqrt();
            };
        if crossings.is_empty() {
            let cell = diagram.locate(self.loop_points[0], None);
            for e in 0..m {
                arc(cell, e, 0.0, 1.0, 0.0, masses, errors);
            }
        } else {
            crossings.sort_unstable_by(|a, b| {
                (a.edge.cmp(&b.edge))
                    .then(a.s.total_cmp(&b.s))
                    .then((a.from, a.to).cmp(&(b.from, b.to)))
            });
            let count = crossings.len();
            for k in 0..count {
                let (x, y) = (crossings[k], crossings[(k + 1) % count]);
                if x.to != y.from {
                    return None;
                }
                let cell = x.to as usize;
                let (ex, ey) = (x.edge as usize, y.edge as usize);
                let position_error = x.error.max(y.error);
                // (sorted by edge and position, so only the pair from the last crossing back to
                // the first can go all the way round)
                let full_turn = k + 1 == count && ex == ey;
                if ex == ey && !full_turn {
                    arc(cell, ex, x.s, y.s, position_error, masses, errors);
                } else {
                    arc(cell, ex, x.s, 1.0, position_error, masses, errors);
                    let mut e = (ex + 1) % m;
                    while e != ey {
                        arc(cell, e, 0.0, 1.0, position_error, masses, errors);
                        e = (e + 1) % m;
                    }
                    arc(cell, ey, 0.0, y.s, position_error, masses, errors);
                }
            }
        }
        Some(())
    }
}

/// Each cell's flux terms and error estimates summed over its traced edges, its edge masses
/// (i < j, sorted by j per i), and all crossings with ∂Ω. Each edge's terms go to its two slots
/// in the neighbour lists, and each cell sums its slots in the order of its list: the masses do
/// not depend on the triangulation's storage order (a flip update and a construction give the
/// same bits). `None` when a chunk declined.
fn sum_edge_terms(diagram: &PowerDiagram, traced: Vec<TracedChunk>) -> Option<CellSums> {
    let n = diagram.num_sites();
    let offsets = diagram.neighbor_offsets();
    let list = diagram.neighbor_list();
    let slot = |i: u32, j: u32| {
        let (a, b) = (offsets[i as usize] as usize, offsets[i as usize + 1] as usize);
        list[a..b].iter().position(|&v| v == j).map(|k| a + k)
    };
    // per slot: mass term, error, edge mass
    let mut slots = vec![(0.0f64, 0.0f64, 0.0f64); list.len()];
    let mut crossings = Vec::new();
    for part in traced {
        let (edges, c) = part?;
        for e in edges {
            let (si, sj) = (slot(e.i, e.j)?, slot(e.j, e.i)?);
            slots[si] = (e.term_i, e.error_i, e.edge_mass);
            slots[sj] = (e.term_j, e.error_j, e.edge_mass);
        }
        crossings.extend(c);
    }
    let mut masses = vec![0.0; n];
    let mut errors = vec![0.0; n];
    let mut edge_masses = Vec::with_capacity(list.len() / 2);
    for i in 0..n {
        let start = edge_masses.len();
        for k in offsets[i] as usize..offsets[i + 1] as usize {
            let (term, error, edge_mass) = slots[k];
            masses[i] += term;
            errors[i] += error;
            if (i as u32) < list[k] && edge_mass > 0.0 {
                edge_masses.push((i as u32, list[k], edge_mass));
            }
        }
        edge_masses[start..].sort_unstable_by_key(|e| e.1);
    }
    Some((masses, errors, edge_masses, crossings))
}

/// Edge adjacency of counter-clockwise `triangles`: per triangle and corner k, the triangle
/// across the edge from corner k to k + 1 and its corner, packed as 4·t + k (NONE on the
/// boundary), and the boundary edges as 3·t + k. `None` when an edge has more than two
/// triangles or two triangles traverse it in the same direction.
fn edge_adjacency(triangles: &[[u32; 3]]) -> Option<(Vec<[u32; 3]>, Vec<u32>)> {
    let nt = triangles.len();
    // Edge adjacency: sort the undirected edges.
    let mut keys: Vec<(u64, u32)> = Vec::with_capacity(3 * nt);
    for (t, tri) in triangles.iter().enumerate() {
        for k in 0..3 {
            let (a, b) = (tri[k], tri[NEXT[k]]);
            let key = ((a.min(b) as u64) << 32) | a.max(b) as u64;
            keys.push((key, (3 * t + k) as u32));
        }
    }
    keys.sort_unstable();
    let mut across = vec![[NONE; 3]; nt];
    let mut boundary: Vec<u32> = Vec::new();
    let mut g = 0;
    while g < keys.len() {
        let mut h = g + 1;
        while h < keys.len() && keys[h].0 == keys[g].0 {
            h += 1;
        }
        match h - g {
            1 => boundary.push(keys[g].1),
            2 => {
                let (x, y) = (keys[g].1 as usize, keys[g + 1].1 as usize);
                let (tx, kx, ty, ky) = (x / 3, x % 3, y / 3, y % 3);
                // the two triangles must traverse the edge in opposite directions
                if triangles[tx][kx] == triangles[ty][ky] {
                    return None;
                }
                across[tx][kx] = (4 * ty + ky) as u32;
                across[ty][ky] = (4 * tx + kx) as u32;
            }
            _ => return None,
        }
        g = h;
    }
    Some((across, boundary))
}

/// The boundary edges (3·t + k, each from corner k to k + 1 of its triangle) as one loop,
/// counter-clockwise around Ω; `None` where the boundary touches itself or has several loops.
fn boundary_loop(triangles: &[[u32; 3]], boundary: &[u32]) -> Option<Vec<u32>> {
    // The boundary loop: each boundary edge runs from corner k to corner k + 1 of its
    // triangle, counter-clockwise around Ω; follow it from each edge's end vertex.
    let mut starting_at: std::collections::HashMap<u32, u32> = std::collections::HashMap::new();
    for &e in boundary {
        let (t, k) = (e as usize / 3, e as usize % 3);
        if starting_at.insert(triangles[t][k], e).is_some() {
            return None; // a vertex where the boundary touches itself
        }
    }
    let mut loop_edges = Vec::with_capacity(boundary.len());
    let mut e = boundary[0];
    for _ in 0..boundary.len() {
        loop_edges.push(e);
        let (t, k) = (e as usize / 3, e as usize % 3);
        e = *starting_at.get(&triangles[t][NEXT[k]])?;
        if e == boundary[0] {
            break;
        }
    }
    if loop_edges.len() != boundary.len() || e != boundary[0] {
        return None; // several boundary loops
    }
    Some(loop_edges)
}

/// Solves the symmetric positive definite system given by its lower-triangle `triplets`
/// (nt × nt) in place on `rhs`, by sparse Cholesky (AMD, supernodal, sequential so that the result
/// does not depend on the thread count); `None` when a factorization fails.
fn solve_poisson(nt: usize, triplets: &[Triplet<usize, usize, f64>], rhs: &mut [f64]) -> Option<()> {
    let matrix = SparseColMat::<usize, f64>::try_new_from_triplets(nt, nt, triplets).ok()?;
    // Sequential, so that the field (hence every mass) does not depend on the thread count.
    let par = Par::Seq;
    let symbolic = factorize_symbolic_cholesky(
        matrix.symbolic(),
        Side::Lower,
        SymmetricOrdering::Amd,
        CholeskySymbolicParams {
            // (faer's automatic choice is the simplicial factorization)
            supernodal_flop_ratio_threshold: SupernodalThreshold::FORCE_SUPERNODAL,
            ..Default::default()
        },
    )
    .ok()?;
    let scratch = symbolic
        .factorize_numeric_llt_scratch::<f64>(par, Default::default())
        .or(symbolic.solve_in_place_scratch::<f64>(1, par));
    let mut buffer = MemBuffer::try_new(scratch).ok()?;
    let stack = MemStack::new(&mut buffer);
    let mut factor = vec![0.0; symbolic.len_val()];
    symbolic
        .factorize_numeric_llt::<f64>(
            &mut factor,
            matrix.as_ref(),
            Side::Lower,
            Default::default(),
            par,
            &mut *stack,
            Default::default(),
        )
        .ok()?;
    LltRef::new(&symbolic, &factor).solve_in_place_with_conj(
        Conj::No,
        MatMut::from_column_major_slice_mut(rhs, nt, 1),
        par,
        stack,
    );
    Some(())
}

/// Whether a triangle of the diagram's raw triangulation (over `n` sites) is finite: stored and
/// without the vertex at infinity.
fn finite_triangle(t: &[u32; 3], n: usize) -> bool {
    t[0] != NONE && !t.contains(&(n as u32))
}

/// The triangle's vertices rotated so that the smallest index comes first (the orientation is
/// kept): the same triple however the triangulation stores it.
fn canonical(t: [u32; 3]) -> [u32; 3] {
    let k = (0..3).min_by_key(|&k| t[k]).unwrap_or(0);
    [t[k], t[NEXT[k]], t[NEXT[NEXT[k]]]]
}

/// The power centre of the regular triangle (a, b, c) (counter-clockwise, canonical), computed
/// relative to y_a, and an estimate of its absolute error: 4ε (|y_a| + κ |z|) with z the centre
/// relative to y_a and κ the conditioning of its 2 × 2 system (large for nearly collinear
/// sites); `None` when they are too nearly collinear.
pub(super) fn power_centre(diagram: &PowerDiagram, t: [u32; 3]) -> Option<([f64; 2], f64)> {
    let y = diagram.sites()[t[0] as usize];
    let line = |v: u32| power_line_between(diagram, t[0] as usize, v as usize);
    let ((d1, c1), (d2, c2)) = (line(t[1]), line(t[2]));
    let det = cross(d1, d2);
    let scale = (d1[0].abs() + d1[1].abs()) * (d2[0].abs() + d2[1].abs());
    if !(det > 1e-10 * scale) {
        return None;
    }
    let z = [(c1 * d2[1] - c2 * d1[1]) / det, (d1[0] * c2 - d2[0] * c1) / det];
    let error = 4.0 * f64::EPSILON * (magnitude(y) + scale / det * magnitude(z));
    Some(([y[0] + z[0], y[1] + z[1]], error))
}
