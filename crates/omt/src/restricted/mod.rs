//! Exact integrals over power cells restricted to a triangulated source measure.
//!
//! For the piecewise-constant density ρ_t on the triangles t of Ω (assumed convex; Ω is the
//! union of the measure's triangles), every restricted cell W_i ∩ Ω splits into convex pieces
//! W_i ∩ t. Each piece is the triangle clipped by the half-planes of the neighbours j of i,
//! which in coordinates z = x − y_i relative to the site read
//! $$ z \cdot d_j \le \tfrac12 \left(|d_j|^2 + w_i - w_j\right), \qquad d_j = y_j - y_i, $$
//! and its integrals are exact closed forms (`docs/conventions.md`, "Transport cost and exact integrals"): a fan of triangles
//! (a, b, c) of area A gives ∫ z = A (a + b + c)/3 and
//! ∫ |z|² = A (|a|² + |b|² + |c|² + a·b + b·c + c·a)/6.
//!
//! The pieces of one source triangle are enumerated as in Lévy's restricted Voronoi diagram
//! (Lévy & Bonneel 2012, *Variational anisotropic surface meshing with Voronoi parallel linear
//! enumeration*; Lévy 2015, *A numerical algorithm for L2 semi-discrete optimal transport in
//! 3D*): start from one cell meeting the triangle (the one of its largest piece at the previous
//! call if it still meets it, else the cell containing its centroid), clip, and walk to the
//! neighbours across clipped edges. Total cost O(N + M + #pieces) for N sites and M source
//! triangles. Triangles are processed in parallel (rayon) and the pieces are summed afterwards
//! in a fixed triangle order (along a Hilbert curve of the centroids, which also keeps point
//! location walks short), so the result does not depend on the number of threads.
//!
//! Each triangle first goes through the boundary (Green's theorem) form of
//! the same integrals (module `boundary`): the cells' power polygons are built once per diagram,
//! each cell meeting t clips its polygon's *edges* to t, and arcs of ∂t close the pieces; about
//! a third of the clipping path's work. It declines triangles where a combinatorial decision is
//! close (a power vertex or edge on t's boundary, crowded cells); those, and diagrams that are
//! not two-dimensional, go through the clipping path described here, so the rules below for
//! degenerate cases hold for both.
//!
//! The Newton evaluations can take the masses and edge masses only, by the
//! flux form (module `flux`, [`RestrictedIntegrator::integrate_masses`]; opt-in,
//! `NewtonParams::flux_masses`: fewer instructions on face pairs, but not faster in wall time): a Raviart–Thomas
//! field with divergence ρ, built once per measure, turns every cell mass into a sum over its
//! power edges, traced through the source triangles; the moments (centroids, transport cost)
//! come from the full integration of the final diagram.
//!
//! Precision: all clipping happens relative to the site y_i, and new polygon vertices are
//! intersections of the two supporting lines (not interpolations along long edges), so cells
//! of size 1e-12 keep their relative accuracy; source-triangle edges passing through a tiny
//! cell have their offset from y_i computed in compensated arithmetic. The combinatorics (which
//! cells are neighbours) come from the exact [`PowerDiagram`]; the geometry here is floating
//! point. The same frame bounds how far a site may lie from the source: a triangle of size s at
//! distance r from y_i keeps a relative precision of about ε·r/s, so sites must lie within
//! [`MAX_SITE_DISTANCE`] source diameters of the source's bounding box (`solve_ot` refuses
//! farther targets; a power-diagram fuzz run found a lone site at 1e28 beside the unit square,
//! whose triangles rounded to points and got no mass).
//!
//! Edge masses μ(e_ij) are summed from both sides (half from the pieces of i, half from those of
//! j). A power edge lying exactly on a source-triangle edge (a density jump) thus gets the mean
//! of the two densities — the mean of the one-sided derivatives of the masses. Pieces of zero
//! width (area ≤ 1e-14 × squared diameter: a cell touching a triangle along a segment, up to
//! rounding) are dropped, so such an edge is never counted twice.

use std::sync::atomic::Ordering::Relaxed;
use std::sync::atomic::{AtomicU32, AtomicUsize};
use std::sync::{Arc, Mutex, OnceLock};

use rayon::prelude::*;

use crate::cells::CellIntegrals;

/// How far, in diameters of the source's bounding box, a site may lie from that box: beyond,
/// clipping relative to the site (module docs) loses more than about 1e-10 of a triangle's
/// size to rounding.
pub const MAX_SITE_DISTANCE: f64 = 1e6;
mod boundary;
mod flux;
use crate::measure::SourceMeasure;
use crate::polygon::polygon_integrals;
use crate::power_diagram::{hilbert_order, PowerDiagram};
use crate::predicates::{two_product, two_sum};
use boundary::{BoundaryScratch, CellPolygons};
pub(crate) use flux::FluxField;

/// Label of a polygon edge that is not a power-diagram edge (source triangle or domain edge).
const NO_LABEL: u32 = u32::MAX;

/// No seed cell recorded for a triangle.
const NO_SEED: u32 = u32::MAX;

/// A directed polygon edge: the supporting line {z : n·z = c} (inside: n·z ≤ c) and its label,
/// the slot of the neighbour in the diagram's neighbour list of the cell being clipped.
#[derive(Clone, Copy, Debug)]
struct Line {
    n: [f64; 2],
    c: f64,
    label: u32,
}

/// A convex polygon (up to rounding): vertex k and the line of the edge from vertex k to vertex
/// k + 1, the first `len` entries of the buffers (which `clip_to_cell` keeps at least twice as
/// long as the polygon being clipped, so that `clip` writes by index without growing them).
#[derive(Clone, Debug, Default)]
struct Polygon {
    len: usize,
    vertices: Vec<[f64; 2]>,
    lines: Vec<Line>,
}

const UNSET_LINE: Line = Line {
    n: [0.0; 2],
    c: 0.0,
    label: NO_LABEL,
};

impl Polygon {
    fn vertices(&self) -> &[[f64; 2]] {
        &self.vertices[..self.len]
    }

    /// Makes room for `capacity` vertices.
    fn reserve(&mut self, capacity: usize) {
        if self.vertices.len() < capacity {
            self.vertices.resize(capacity, [0.0; 2]);
            self.lines.resize(capacity, UNSET_LINE);
        }
    }

    /// Sets the polygon to the convex polygon `points` − `origin` (counter-clockwise), edges
    /// unlabelled.
    fn set_convex(&mut self, points: &[[f64; 2]], origin: [f64; 2]) {
        let m = points.len();
        self.reserve(m + 1);
        for k in 0..m {
            let (p, q) = (points[k], points[if k + 1 == m { 0 } else { k + 1 }]);
            let n = [q[1] - p[1], p[0] - q[0]];
            self.vertices[k] = [p[0] - origin[0], p[1] - origin[1]];
            self.lines[k] = Line {
                n,
                c: edge_offset(p, q, origin),
                label: NO_LABEL,
            };
        }
        self.len = m;
    }
}

/// The power line between the cells of sites i and j, relative to y_i: {z : z·d = c} with
/// d = y_j − y_i and c = ½(|d|² + w_i − w_j) (the weights in double-double form), W_i on the side
/// z·d ≤ c (module docs). Shared by the boundary and flux forms, so both see the same line.
#[inline]
pub(super) fn power_line_between(diagram: &PowerDiagram, i: usize, j: usize) -> ([f64; 2], f64) {
    let sites = diagram.sites();
    let (y, yj) = (sites[i], sites[j]);
    let d = [yj[0] - y[0], yj[1] - y[1]];
    let (wi, wj) = (diagram.weight(i), diagram.weight(j));
    (
        d,
        0.5 * ((d[0] * d[0] + d[1] * d[1]) + ((wi[0] - wj[0]) + (wi[1] - wj[1]))),
    )
}

/// The offset c = n·(p − y) of the line through p and q (normal n = (q_y − p_y, p_x − q_x)),
/// relative to y, in compensated arithmetic: the line's distance from y is accurate to
/// ~ε² |q − p| |p − y| instead of ε |q − p| |p − y|. This matters when the edge of a large source
/// triangle passes through a tiny cell around y: the offset is then much smaller than |p − y|.
fn edge_offset(p: [f64; 2], q: [f64; 2], y: [f64; 2]) -> f64 {
    let (nx, nxl) = two_sum(q[1], -p[1]);
    let (ny, nyl) = two_sum(p[0], -q[0]);
    let (ax, axl) = two_sum(p[0], -y[0]);
    let (ay, ayl) = two_sum(p[1], -y[1]);
    let (p1, e1) = two_product(nx, ax);
    let (p2, e2) = two_product(ny, ay);
    let (s, se) = two_sum(p1, p2);
    s + (se + e1 + e2 + (nx * axl + nxl * ax) + (ny * ayl + nyl * ay) + (nxl * axl + nyl * ayl))
}

/// Intersection of the edge p→q (on line `l`) with line `h`, where p and q are on opposite sides
/// of h (values fp, fq of n_h·z − c_h). Solves the 2×2 system of the two lines when it is well
/// conditioned (accurate at the scale of the lines, even when p and q are far away), else
/// interpolates; the result is kept within the bounding box of the segment.
#[inline]
fn intersect(l: &Line, h: &Line, p: [f64; 2], q: [f64; 2], fp: f64, fq: f64) -> [f64; 2] {
    let det = l.n[0] * h.n[1] - l.n[1] * h.n[0];
    let scale = (l.n[0].abs() + l.n[1].abs()) * (h.n[0].abs() + h.n[1].abs());
    let z = if det.abs() > 1e-6 * scale {
        [(l.c * h.n[1] - h.c * l.n[1]) / det, (l.n[0] * h.c - h.n[0] * l.c) / det]
    } else {
        let t = fp / (fp - fq);
        [p[0] + t * (q[0] - p[0]), p[1] + t * (q[1] - p[1])]
    };
    // `f64::clamp` without its check that the bounds are ordered (they are).
    let clamp = |x: f64, a: f64, b: f64| {
        let (lo, hi) = if a <= b { (a, b) } else { (b, a) };
        if x < lo {
            lo
        } else if x > hi {
            hi
        } else {
            x
        }
    };
    [clamp(z[0], p[0], q[0]), clamp(z[1], p[1], q[1])]
}

/// Keeps the part of `src` where n·z ≤ c, writing it to `dst` (Sutherland–Hodgman; new edges
/// get the line `h`). Returns false when nothing is cut (`dst` untouched), after relabelling in
/// place an edge of `src` lying on the line. `values` must hold at least `src.len` entries and
/// `dst` room for `2 src.len` vertices: a convex `src` gives at most `src.len + 1`, but one made
/// slightly non-convex by the rounding of earlier cuts (cells ~1e-14 wide among crowded sites)
/// can cross the line more than twice, and each edge emits at most two vertices.
#[inline]
fn clip(src: &mut Polygon, dst: &mut Polygon, h: &Line, values: &mut [f64]) -> bool {
    let m = src.len;
    let (mut any_out, mut any_on) = (false, false);
    for (f_out, v) in values[..m].iter_mut().zip(&src.vertices[..m]) {
        let (a, b) = (h.n[0] * v[0], h.n[1] * v[1]);
        let mut f = a + b - h.c;
        // Vertices on the line up to rounding count as on it (and inside): an edge of the
        // polygon lying on the clipping line then becomes that line's edge instead of
        // producing a sliver of zero width.
        if f.abs() <= 64.0 * f64::EPSILON * (a.abs() + b.abs() + h.c.abs()) {
            f = 0.0;
            any_on = true;
        }
        any_out |= f > 0.0;
        *f_out = f;
    }
    let values = &values[..m];
    if !any_out {
        // Nothing cut; still relabel an edge lying on the line (the common case, no vertex on
        // it, skips the search).
        if any_on {
            if let Some(k) = (0..m).find(|&k| values[k] == 0.0 && values[if k + 1 == m { 0 } else { k + 1 }] == 0.0) {
                src.lines[k] = *h;
            }
        }
        return false;
    }
    let (sv, sl) = (&src.vertices[..m], &src.lines[..m]);
    let (dv, dl) = (&mut dst.vertices[..2 * m], &mut dst.lines[..2 * m]);
    let mut n = 0;
    for k in 0..m {
        let k1 = if k + 1 == m { 0 } else { k + 1 };
        let (p, q) = (sv[k], sv[k1]);
        let (fp, fq) = (values[k], values[k1]);
        let mut l = sl[k];
        if any_on && fp == 0.0 && fq == 0.0 {
            // The edge lies on the clipping line (a power edge along a source-triangle edge):
            // it is the power edge.
            l = *h;
        }
        if fp <= 0.0 {
            dv[n] = p;
            dl[n] = l;
            n += 1;
            if fq > 0.0 {
                dv[n] = intersect(&l, h, p, q, fp, fq);
                dl[n] = *h;
                n += 1;
            }
        } else if fq <= 0.0 {
            dv[n] = intersect(&l, h, p, q, fp, fq);
            dl[n] = l;
            n += 1;
        }
    }
    dst.len = if n < 3 { 0 } else { n };
    true
}

/// Squared diagonal of the bounding box of the points.
fn diameter_squared(points: &[[f64; 2]]) -> f64 {
    let (lo, hi) = crate::polygon::bounding_box(points);
    (hi[0] - lo[0]).powi(2) + (hi[1] - lo[1]).powi(2)
}

/// One piece W_i ∩ t: the cell, the triangle's density, and the unit-density integrals relative
/// to y_i.
#[derive(Clone, Copy, Debug)]
struct Piece {
    cell: u32,
    density: f64,
    area: f64,
    first_moment: [f64; 2],
    second_moment: f64,
}

/// Per-worker scratch space.
struct Scratch {
    visited: Vec<u32>,
    stamp: u32,
    queue: Vec<u32>,
    a: Polygon,
    b: Polygon,
    values: Vec<f64>,
    hint: Option<usize>,
    boundary: Box<BoundaryScratch>,
}

impl Scratch {
    fn new(n: usize) -> Self {
        Scratch {
            visited: vec![0; n],
            stamp: 0,
            queue: Vec::new(),
            a: Polygon::default(),
            b: Polygon::default(),
            values: Vec::new(),
            hint: None,
            boundary: Box::default(),
        }
    }
}

/// Results of a chunk of source triangles: pieces and edge contributions (slot in the
/// diagram's neighbour list, μ-weighted length), in processing order.
#[derive(Default)]
struct ChunkResult {
    pieces: Vec<Piece>,
    edges: Vec<(u32, f64)>,
    /// Triangles integrated by the clipping path although the boundary form was on.
    declined: usize,
}

/// How one integration went (see [`RestrictedIntegrator::integrate_with_stats`]).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct IntegrationStats {
    /// Source triangles.
    pub triangles: usize,
    /// Whether the boundary form was used (on, and a two-dimensional diagram).
    pub boundary_form: bool,
    /// Triangles the boundary form declined (integrated by clipping instead).
    pub declined: usize,
}

/// Reusable integration data for one source measure: the triangles with their areas and the
/// boundary of Ω. Build it once and call [`RestrictedIntegrator::integrate`] at every Newton
/// iteration.
#[derive(Debug)]
pub struct RestrictedIntegrator {
    vertices: Vec<[f64; 2]>,
    triangles: Vec<[u32; 3]>,
    densities: Vec<f64>,
    triangle_areas: Vec<f64>,
    /// Convex hull of the measure's vertices (= Ω for a convex domain), counter-clockwise.
    boundary: Vec<[f64; 2]>,
    /// A box around Ω three times its size, counter-clockwise: bounds the unbounded cells'
    /// polygons of the boundary form.
    frame: Vec<[f64; 2]>,
    /// Whether triangles go through the boundary form first (module docs of `boundary`).
    boundary_form: bool,
    /// Processing order of the triangles: along a Hilbert curve of their centroids, so that
    /// point location walks from one triangle to the next are short.
    order: Vec<u32>,
    /// Per triangle: the cell of its largest piece at the last integration (`u32::MAX`: none
    /// yet). Only a starting point of the walk over the pieces (the next diagram usually differs
    /// little), so it never changes a result; relaxed atomics, as concurrent integrations may
    /// race on it harmlessly.
    seeds: Vec<AtomicU32>,
    /// The Raviart–Thomas field of the flux form (module `flux`), built at its first use; shared
    /// by the integrators of one [`crate::PreparedMeasure`] ([`Self::with_flux_slot`]), so built
    /// once per measure for all its solves; `None` inside when the measure is not a convex disk.
    flux: FluxSlot,
    /// The sites of the last flux-form integration and a source triangle at or near each.
    site_triangles: Mutex<Option<SiteTriangles>>,
    /// The error bound relative to each cell's mass under which [`Self::integrate_masses`]
    /// takes the flux form (default 1e-8; `None`: never).
    flux_bound: Option<f64>,
    /// Flux-form integrations declined in a row; from [`MAX_FLUX_DECLINES`] on, the masses go
    /// through the full integration directly.
    flux_declines: AtomicUsize,
}

/// The flux field of a measure, built by the first integrator that needs it (`None` inside: the
/// form declines the measure).
pub(crate) type FluxSlot = Arc<OnceLock<Option<Arc<FluxField>>>>;

/// Sites and, per site, a source triangle at or near it (see `flux::FluxField::locate_sites`).
type SiteTriangles = (Vec<[f64; 2]>, Arc<Vec<u32>>);

/// After this many declined flux-form integrations an integrator stops trying it (crowded
/// points, whose cells are too small for it, stay crowded for the whole solve).
const MAX_FLUX_DECLINES: usize = 3;

impl Clone for RestrictedIntegrator {
    fn clone(&self) -> Self {
        RestrictedIntegrator {
            vertices: self.vertices.clone(),
            triangles: self.triangles.clone(),
            densities: self.densities.clone(),
            triangle_areas: self.triangle_areas.clone(),
            boundary: self.boundary.clone(),
            frame: self.frame.clone(),
            boundary_form: self.boundary_form,
            order: self.order.clone(),
            seeds: self.seeds.iter().map(|a| AtomicU32::new(a.load(Relaxed))).collect(),
            flux: self.flux.clone(),
            flux_bound: self.flux_bound,
            site_triangles: Mutex::new(self.site_triangles.lock().map(|g| g.clone()).unwrap_or(None)),
            flux_declines: AtomicUsize::new(self.flux_declines.load(Relaxed)),
        }
    }
}

impl RestrictedIntegrator {
    /// Precomputes triangle areas and the boundary polygon of Ω (the convex hull of the
    /// measure's vertices; Ω is assumed convex).
    pub fn new(measure: &SourceMeasure) -> Self {
        let triangle_areas = measure
            .triangles
            .iter()
            .map(|t| {
                let [a, b, c] = t.map(|v| measure.vertices[v as usize]);
                0.5 * ((b[0] - a[0]) * (c[1] - a[1]) - (b[1] - a[1]) * (c[0] - a[0]))
            })
            .collect();
        let centroids: Vec<[f64; 2]> = measure
            .triangles
            .iter()
            .map(|t| {
                let [a, b, c] = t.map(|v| measure.vertices[v as usize]);
                [(a[0] + b[0] + c[0]) / 3.0, (a[1] + b[1] + c[1]) / 3.0]
            })
            .collect();
        let (lo, hi) = crate::polygon::bounding_box(&measure.vertices);
        let span = (hi[0] - lo[0]).max(hi[1] - lo[1]).max(f64::MIN_POSITIVE);
        let (lo, hi) = ([lo[0] - span, lo[1] - span], [hi[0] + span, hi[1] + span]);
        RestrictedIntegrator {
            frame: vec![lo, [hi[0], lo[1]], hi, [lo[0], hi[1]]],
            boundary_form: true,
            order: hilbert_order(&centroids),
            vertices: measure.vertices.clone(),
            triangles: measure.triangles.clone(),
            densities: measure.densities.clone(),
            triangle_areas,
            // (of the vertices the triangles use: an unreferenced one would widen the cells)
            boundary: measure.domain_hull(),
            seeds: (0..measure.triangles.len()).map(|_| AtomicU32::new(NO_SEED)).collect(),
            flux: Default::default(),
            flux_bound: Some(1e-8),
            site_triangles: Mutex::new(None),
            flux_declines: AtomicUsize::new(0),
        }
    }

    /// Takes its flux field (when the flux form is on) from `slot`, which the integrators of one
    /// measure share ([`crate::PreparedMeasure`]): the first that needs the field builds it.
    pub(crate) fn with_flux_slot(mut self, slot: FluxSlot) -> Self {
        self.flux = slot;
        self
    }

    /// The boundary of Ω (convex hull of the measure's vertices), counter-clockwise.
    pub fn boundary(&self) -> &[[f64; 2]] {
        &self.boundary
    }

    /// Turns the boundary (Green's theorem) form of the integration on (the default) or off.
    /// Off, every triangle goes through the clipping path; the integrals agree up to rounding.
    pub fn with_boundary_form(mut self, on: bool) -> Self {
        self.boundary_form = on;
        self
    }

    /// Sets the error bound (relative to each cell's mass) under which [`Self::integrate_masses`]
    /// takes the flux form (default `Some(1e-8)`); `None` makes it [`Self::integrate`].
    pub fn with_flux_form(mut self, bound: Option<f64>) -> Self {
        self.flux_bound = bound;
        self
    }

    /// The sites whose power cell meets Ω in no area, so that their mass is 0 whatever the
    /// density (hidden sites are not listed). A line-search trial with such a cell is rejected;
    /// this finds them without integrating the cells. A cell with a power vertex strictly
    /// inside Ω (by more than the vertex's error bound) meets Ω in area: the cell is
    /// two-dimensional and a neighbourhood of that vertex lies in Ω. Every other cell is
    /// clipped to Ω as the integration clips it, and listed when nothing is left. Empty when
    /// the diagram is not two-dimensional (nothing is decided then).
    pub fn cells_outside(&self, diagram: &PowerDiagram) -> Vec<u32> {
        let n = diagram.num_sites();
        if diagram.dimension() != 2 || self.boundary.len() < 3 {
            return Vec::new();
        }
        let inside = DomainTest::new(&self.boundary);
        let mut seen = vec![false; n];
        let (triangles, _) = diagram.raw_triangulation();
        for t in triangles {
            if t[0] == u32::MAX || t.iter().any(|&v| v as usize >= n) || t.iter().all(|&v| seen[v as usize]) {
                continue;
            }
            if let Some((x, error)) = flux::power_centre(diagram, *t) {
                if inside.strictly_inside(x, error) {
                    t.iter().for_each(|&v| seen[v as usize] = true);
                }
            }
        }
        let mut scratch = Scratch::new(0);
        (0..n)
            .filter(|&i| !seen[i] && !diagram.is_hidden(i))
            .filter(|&i| !Self::clip_to_cell(diagram, i, &self.boundary, &mut scratch))
            .map(|i| i as u32)
            .collect()
    }

    /// Clips the convex polygon `poly` (absolute coordinates) to the power cell of `i`, in
    /// coordinates relative to y_i, into `s.a`. Returns false when the result is empty.
    fn clip_to_cell(diagram: &PowerDiagram, i: usize, poly: &[[f64; 2]], s: &mut Scratch) -> bool {
        let sites = diagram.sites();
        let y = sites[i];
        let offsets = diagram.neighbor_offsets();
        let list = diagram.neighbor_list();
        let (start, end) = (offsets[i] as usize, offsets[i + 1] as usize);
        // Every clip of a convex polygon adds at most one vertex (more room is made below if
        // rounding made it non-convex).
        let capacity = 2 * (poly.len() + (end - start) + 1);
        s.b.reserve(capacity);
        if s.values.len() < capacity {
            s.values.resize(capacity, 0.0);
        }
        s.a.set_convex(poly, y);
        s.a.reserve(capacity);
        let wi = diagram.weight(i);
        for (slot, &j) in (start..end).zip(&list[start..end]) {
            let j = j as usize;
            let d = [sites[j][0] - y[0], sites[j][1] - y[1]];
            // w_i − w_j from the double-double weights: exact high difference for close weights
            // (Sterbenz) plus the low parts, so sites closer than the weights' ulp still get the
            // bisector the weights say.
            let wj = diagram.weight(j);
            let c = 0.5 * ((d[0] * d[0] + d[1] * d[1]) + ((wi[0] - wj[0]) + (wi[1] - wj[1])));
            let h = Line {
                n: d,
                c,
                label: slot as u32,
            };
            // (room for what `clip` may emit; beyond the convex bound only after rounding)
            let m = s.a.len;
            s.b.reserve(2 * m);
            if s.values.len() < m {
                s.values.resize(m, 0.0);
            }
            if clip(&mut s.a, &mut s.b, &h, &mut s.values) {
                std::mem::swap(&mut s.a, &mut s.b);
                if s.a.len == 0 {
                    return false;
                }
            }
        }
        s.a.len != 0
    }

    /// The piece W_i ∩ t; records it and its edges, pushes unvisited neighbours across its
    /// power edges. Returns the piece's area.
    fn visit(
        &self,
        diagram: &PowerDiagram,
        t: usize,
        i: usize,
        s: &mut Scratch,
        out: &mut ChunkResult,
        push: bool,
    ) -> f64 {
        let tri = self.triangles[t].map(|v| self.vertices[v as usize]);
        if !Self::clip_to_cell(diagram, i, &tri, s) {
            return 0.0;
        }
        let density = self.densities[t];
        let (area, first_moment, second_moment) = polygon_integrals(s.a.vertices());
        let list = diagram.neighbor_list();
        let m = s.a.len;
        if !(area > 1e-14 * diameter_squared(s.a.vertices())) {
            // Degenerate piece: the cell touches t along a segment or at a point (a power edge
            // on a source-triangle edge, up to rounding). Its edge is counted from the
            // non-degenerate pieces on both sides. The walk still continues across its edges,
            // so that it does not depend on where it started.
            if push {
                for k in 0..m {
                    let slot = s.a.lines[k].label;
                    if slot != NO_LABEL {
                        let j = list[slot as usize];
                        if s.visited[j as usize] != s.stamp {
                            s.visited[j as usize] = s.stamp;
                            s.queue.push(j);
                        }
                    }
                }
            }
            return 0.0;
        }
        out.pieces.push(Piece {
            cell: i as u32,
            density,
            area,
            first_moment,
            second_moment,
        });
        for k in 0..m {
            let slot = s.a.lines[k].label;
            if slot == NO_LABEL {
                continue;
            }
            let j = list[slot as usize];
            // Each edge is seen from both cells: half from each side. A power edge lying on
            // a source-triangle edge is seen from one cell in each of the two triangles, and
            // gets the mean density of the two.
            let (p, q) = (s.a.vertices[k], s.a.vertices[if k + 1 == m { 0 } else { k + 1 }]);
            let length = ((q[0] - p[0]) * (q[0] - p[0]) + (q[1] - p[1]) * (q[1] - p[1])).sqrt();
            out.edges.push((slot, 0.5 * density * length));
            if push && s.visited[j as usize] != s.stamp {
                s.visited[j as usize] = s.stamp;
                s.queue.push(j);
            }
        }
        area
    }

    /// All pieces of source triangle t: a walk over the cells from a seed cell across the power
    /// edges inside t. The seed is the cell of t's largest piece at the last integration when
    /// it still meets t (the diagrams of successive Newton trials differ little), else the cell
    /// containing t's centroid (point location from that cell or the previous triangle's). The
    /// set of pieces does not depend on the seed: the pieces of t tile it and the walk crosses
    /// every edge between two of them; the area check below is the safety net.
    fn integrate_triangle(&self, diagram: &PowerDiagram, t: usize, s: &mut Scratch, out: &mut ChunkResult) {
        s.stamp = s.stamp.wrapping_add(1);
        if s.stamp == 0 {
            s.visited.iter_mut().for_each(|v| *v = 0);
            s.stamp = 1;
        }
        s.queue.clear();
        let n = diagram.num_sites();
        let first_piece = out.pieces.len();
        let mut covered = 0.0;
        let seed = self.seeds[t].load(Relaxed) as usize;
        let seeded = seed < n && !diagram.is_hidden(seed) && {
            s.visited[seed] = s.stamp;
            let a = self.visit(diagram, t, seed, s, out, true);
            covered += a;
            a > 0.0
        };
        if !seeded {
            let tri = self.triangles[t].map(|v| self.vertices[v as usize]);
            let centroid = [
                (tri[0][0] + tri[1][0] + tri[2][0]) / 3.0,
                (tri[0][1] + tri[1][1] + tri[2][1]) / 3.0,
            ];
            let hint = if seed < n && !diagram.is_hidden(seed) {
                Some(seed)
            } else {
                s.hint
            };
            let i = diagram.locate(centroid, hint);
            if s.visited[i] != s.stamp {
                s.visited[i] = s.stamp;
                s.queue.push(i as u32);
            }
        }
        while let Some(i) = s.queue.pop() {
            covered += self.visit(diagram, t, i as usize, s, out, true);
        }
        let area = self.triangle_areas[t];
        if (covered - area).abs() > 1e-9 * area {
            // Safety net for degenerate walks (a seed cell touching t only at a point, ...):
            // visit every remaining visible cell. Never observed on non-degenerate input.
            for i in 0..diagram.num_sites() {
                if s.visited[i] != s.stamp && !diagram.is_hidden(i) {
                    s.visited[i] = s.stamp;
                    self.visit(diagram, t, i, s, out, false);
                }
            }
        }
        // Pieces of one triangle in cell order: the sum does not depend on the walk.
        let pieces = &mut out.pieces[first_piece..];
        pieces.sort_unstable_by_key(|p| p.cell);
        if let Some(largest) = pieces.iter().max_by(|a, b| a.area.total_cmp(&b.area)) {
            self.seeds[t].store(largest.cell, Relaxed);
            s.hint = Some(largest.cell as usize);
        }
    }

    /// Integrals over the restricted cells W_i ∩ Ω (see [`CellIntegrals`]): masses, first
    /// moments ∫x dμ, second moments ∫|x − y_i|² dμ (#N each) and, for neighbouring cells
    /// i < j, ∫_{e_ij ∩ Ω} μ ds (sum over source triangles of density × length of the power edge
    /// inside the triangle; mean density on a density jump), sorted by (i, j), only pairs with a
    /// positive value. Exact for the piecewise-constant density up to floating point. Hidden
    /// cells and cells outside Ω get zeros. Deterministic (independent of the thread count).
    /// Cost O(N + M + #pieces), parallel over source triangles.
    pub fn integrate(&self, diagram: &PowerDiagram) -> CellIntegrals {
        self.integrate_with_stats(diagram).0
    }

    /// [`Self::integrate`], and how many triangles the boundary form declined (they went through
    /// the clipping path: a power vertex or edge on a triangle's boundary, crowded cells, ...).
    pub fn integrate_with_stats(&self, diagram: &PowerDiagram) -> (CellIntegrals, IntegrationStats) {
        let n = diagram.num_sites();
        let polygons =
            (self.boundary_form && diagram.dimension() == 2).then(|| CellPolygons::new(diagram, &self.frame));
        let num_triangles = self.triangles.len();
        let chunk = num_triangles.div_ceil(256).max(1);
        let num_chunks = num_triangles.div_ceil(chunk);
        let results: Vec<ChunkResult> = (0..num_chunks)
            .into_par_iter()
            .map_init(
                || Scratch::new(n),
                |s, c| {
                    // ~3.6 pieces per triangle and 3 power edges per piece on face pairs.
                    let mut out = ChunkResult {
                        pieces: Vec::with_capacity(4 * chunk),
                        edges: Vec::with_capacity(12 * chunk),
                        declined: 0,
                    };
                    for &t in &self.order[c * chunk..((c + 1) * chunk).min(num_triangles)] {
                        let t = t as usize;
                        match &polygons {
                            Some(p) if self.integrate_triangle_boundary(diagram, p, t, s, &mut out) => {}
                            Some(_) => {
                                out.declined += 1;
                                self.integrate_triangle(diagram, t, s, &mut out);
                            }
                            None => self.integrate_triangle(diagram, t, s, &mut out),
                        }
                    }
                    out
                },
            )
            .collect();
        let sites = diagram.sites();
        let mut masses = vec![0.0; n];
        let mut first_moments = vec![[0.0; 2]; n];
        let mut second_moments = vec![0.0; n];
        let mut edge_values = vec![0.0; diagram.neighbor_list().len()];
        for r in &results {
            for p in &r.pieces {
                let i = p.cell as usize;
                let mass = p.density * p.area;
                masses[i] += mass;
                first_moments[i][0] += mass * sites[i][0] + p.density * p.first_moment[0];
                first_moments[i][1] += mass * sites[i][1] + p.density * p.first_moment[1];
                second_moments[i] += p.density * p.second_moment;
            }
            for &(slot, v) in &r.edges {
                edge_values[slot as usize] += v;
            }
        }
        let offsets = diagram.neighbor_offsets();
        let list = diagram.neighbor_list();
        let mut edge_masses = Vec::new();
        for i in 0..n {
            let start = edge_masses.len();
            for slot in offsets[i] as usize..offsets[i + 1] as usize {
                let j = list[slot];
                if (i as u32) < j {
                    let back = (offsets[j as usize]..offsets[j as usize + 1]).find(|&b| list[b as usize] == i as u32);
                    let value = edge_values[slot] + back.map_or(0.0, |b| edge_values[b as usize]);
                    if value > 0.0 {
                        edge_masses.push((i as u32, j, value));
                    }
                }
            }
            edge_masses[start..].sort_unstable_by_key(|e| e.1);
        }
        let stats = IntegrationStats {
            triangles: num_triangles,
            boundary_form: polygons.is_some(),
            declined: results.iter().map(|r| r.declined).sum(),
        };
        (
            CellIntegrals {
                masses,
                first_moments,
                second_moments,
                edge_masses,
            },
            stats,
        )
    }

    /// The masses μ(W_i ∩ Ω) and edge masses of [`Self::integrate`], without the moments
    /// (`first_moments` and `second_moments` empty, see [`CellIntegrals::has_moments`]) when
    /// the flux form (module `flux`) takes the diagram, else all of [`Self::integrate`]. The
    /// flux form is tried when the measure has at least as many triangles as the diagram has
    /// sites (where it pays). The
    /// flux form declines where it cannot bound a cell's error by the integrator's bound
    /// ([`Self::with_flux_form`]) relative to its mass;
    /// on face pairs the masses agree with those of [`Self::integrate`] to ~1e-12. What a Newton
    /// evaluation needs, at about two thirds of the cost on face pairs.
    pub fn integrate_masses(&self, diagram: &PowerDiagram) -> CellIntegrals {
        // The flux form pays where the source is finer than the diagram (its work grows with
        // the power edges, the boundary form's with the pieces, ~ N + M): face pairs, 18.8k
        // triangles for 9.4k sites, −12 %; the area-preserving map of Nefertiti, 7.3k triangles
        // for 50k sites, +14 % (`docs/decisions/0010-restricted-integration.md`).
        let pays = self.triangles.len() >= diagram.num_sites();
        if let Some(bound) = self
            .flux_bound
            .filter(|_| pays && self.flux_declines.load(Relaxed) < MAX_FLUX_DECLINES)
        {
            if let Some(cells) = self.try_integrate_masses(diagram, bound) {
                self.flux_declines.store(0, Relaxed);
                return cells;
            }
            self.flux_declines.fetch_add(1, Relaxed);
        }
        self.integrate(diagram)
    }

    /// The flux form alone: `None` when it declines (module `flux`: a measure that is not a
    /// convex disk, a diagram that is not two-dimensional, a walk without consistent exit, cells
    /// too small for its error bound).
    pub fn try_integrate_masses(&self, diagram: &PowerDiagram, relative_bound: f64) -> Option<CellIntegrals> {
        let field = self
            .flux
            .get_or_init(|| {
                FluxField::new(&self.vertices, &self.triangles, &self.densities, &self.triangle_areas).map(Arc::new)
            })
            .as_ref()?;
        let sites = diagram.sites();
        let located = {
            let mut cache = self.site_triangles.lock().ok()?;
            match cache.as_ref() {
                Some((s, t)) if s.as_slice() == sites => t.clone(),
                _ => {
                    let t = Arc::new(field.locate_sites(&self.vertices, &self.triangles, sites, &self.order));
                    *cache = Some((sites.to_vec(), t.clone()));
                    t
                }
            }
        };
        field.integrate(
            &self.vertices,
            &self.triangles,
            &self.densities,
            diagram,
            &located,
            relative_bound,
        )
    }

    /// The restricted cells W_i ∩ Ω as convex polygons (absolute coordinates,
    /// counter-clockwise), #N; an empty Vec for hidden cells and cells missing Ω.
    pub fn cell_polygons(&self, diagram: &PowerDiagram) -> Vec<Vec<[f64; 2]>> {
        let n = diagram.num_sites();
        (0..n)
            .into_par_iter()
            .map_init(
                || Scratch::new(0),
                |s, i| {
                    if diagram.is_hidden(i) || !Self::clip_to_cell(diagram, i, &self.boundary, s) {
                        return Vec::new();
                    }
                    let (area, _, _) = polygon_integrals(s.a.vertices());
                    if !(area > 1e-14 * diameter_squared(s.a.vertices())) {
                        return Vec::new();
                    }
                    let y = diagram.sites()[i];
                    s.a.vertices().iter().map(|v| [v[0] + y[0], v[1] + y[1]]).collect()
                },
            )
            .collect()
    }
}

/// Exact integrals over the restricted power cells W_i ∩ Ω of the piecewise-constant measure
/// (see [`RestrictedIntegrator::integrate`]). `sites` and `weights` must be the ones `diagram`
/// was built from (the diagram's own copies are used). Ω, the union of the measure's triangles,
/// must be convex. For repeated calls with one measure, reuse a [`RestrictedIntegrator`].
pub fn integrate_cells(
    diagram: &PowerDiagram,
    sites: &[[f64; 2]],
    weights: &[f64],
    measure: &SourceMeasure,
) -> CellIntegrals {
    let _ = (sites, weights);
    RestrictedIntegrator::new(measure).integrate(diagram)
}

/// The restricted cells W_i ∩ Ω as convex polygons (counter-clockwise, absolute coordinates;
/// empty Vec for empty cells), #N, for output and plots. `sites` and `weights` must be the ones
/// `diagram` was built from. Ω is the convex hull of the measure's vertices.
pub fn cell_polygons(
    diagram: &PowerDiagram,
    sites: &[[f64; 2]],
    weights: &[f64],
    measure: &SourceMeasure,
) -> Vec<Vec<[f64; 2]>> {
    let _ = (sites, weights);
    RestrictedIntegrator::new(measure).cell_polygons(diagram)
}

/// Point-in-Ω tests for a convex counter-clockwise polygon: a disk around the vertices' mean
/// that lies inside answers most queries; the others find their edge by the angle around the
/// centroid.
struct DomainTest<'a> {
    polygon: &'a [[f64; 2]],
    centre: [f64; 2],
    inner_radius: f64,
    /// Angles of the vertices around the centre, unwrapped to increase from the first.
    angles: Vec<f64>,
}

impl<'a> DomainTest<'a> {
    fn new(polygon: &'a [[f64; 2]]) -> Self {
        let (centre, inner_radius) = crate::polygon::inner_disk(polygon);
        let mut angles = Vec::with_capacity(polygon.len());
        for p in polygon {
            let mut a = (p[1] - centre[1]).atan2(p[0] - centre[0]);
            if let Some(&first) = angles.first() {
                while a < first {
                    a += std::f64::consts::TAU;
                }
            }
            angles.push(a);
        }
        DomainTest {
            polygon,
            centre,
            inner_radius: inner_radius * (1.0 - 1e-9),
            angles,
        }
    }

    /// True when x lies inside the polygon by more than `error` (false when unsure).
    fn strictly_inside(&self, x: [f64; 2], error: f64) -> bool {
        let (dx, dy) = (x[0] - self.centre[0], x[1] - self.centre[1]);
        let r = dx.hypot(dy);
        if r + error < self.inner_radius {
            return true;
        }
        if !(self.inner_radius > 0.0) || !r.is_finite() {
            return false;
        }
        let first = self.angles[0];
        let mut a = dy.atan2(dx);
        while a < first {
            a += std::f64::consts::TAU;
        }
        // the edge k → k + 1 whose angular sector holds a (the last edge closes the polygon)
        let k = self.angles.partition_point(|&b| b <= a).saturating_sub(1);
        let m = self.polygon.len();
        let (p, q) = (self.polygon[k], self.polygon[(k + 1) % m]);
        let e = [q[0] - p[0], q[1] - p[1]];
        let len = e[0].hypot(e[1]);
        let d = (e[0] * (x[1] - p[1]) - e[1] * (x[0] - p[0])) / len;
        // (the sector's edge decides only up to the angles' rounding: a margin of 1e-12 of the
        // polygon's size on top of the vertex's error)
        d > error + 1e-12 * (1.0 + self.inner_radius)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A polygon made non-convex (here by construction; in a solve by the rounding of earlier
    /// cuts in cells ~1e-14 wide) can cross the clipping line more than twice: two spikes above
    /// y = 1 give m + 2 vertices. `clip` has room for 2m vertices
    /// (with m + 1 slots it panicked in `shapespace distances` on the bundled TOSCA wolves and
    /// centaurs together).
    #[test]
    fn clip_keeps_every_crossing_of_a_non_convex_polygon() {
        let spikes = [[0.0, 0.0], [4.0, 0.0], [3.0, 2.0], [2.0, 0.5], [1.0, 2.0]];
        let mut src = Polygon {
            len: 0,
            vertices: Vec::new(),
            lines: Vec::new(),
        };
        src.set_convex(&spikes, [0.0, 0.0]);
        let mut dst = Polygon {
            len: 0,
            vertices: Vec::new(),
            lines: Vec::new(),
        };
        dst.reserve(2 * spikes.len());
        let mut values = vec![0.0; spikes.len()];
        let below = Line {
            n: [0.0, 1.0],
            c: 1.0,
            label: 7,
        };
        assert!(clip(&mut src, &mut dst, &below, &mut values));
        let expected = [
            [0.0, 0.0],
            [4.0, 0.0],
            [3.5, 1.0],
            [2.0 + 1.0 / 3.0, 1.0],
            [2.0, 0.5],
            [2.0 - 1.0 / 3.0, 1.0],
            [0.5, 1.0],
        ];
        assert_eq!(dst.len, expected.len());
        for (v, e) in dst.vertices().iter().zip(&expected) {
            assert!(
                (v[0] - e[0]).abs() < 1e-15 && (v[1] - e[1]).abs() < 1e-15,
                "{v:?} vs {e:?}"
            );
        }
        // the new edges lie on the clipping line, the others keep theirs
        let labels: Vec<u32> = dst.lines[..dst.len].iter().map(|l| l.label).collect();
        assert_eq!(labels, [NO_LABEL, NO_LABEL, 7, NO_LABEL, NO_LABEL, 7, NO_LABEL]);
        // area of the part below y = 1: the rectangle 4 × 1 minus its two corner triangles (1/4
        // each) and the notch between the spikes, (5/3, 1), (2, 0.5), (7/3, 1) (1/6)
        let (area, _, _) = polygon_integrals(dst.vertices());
        assert!(
            (area - (4.0 - 0.5 * (2.0 / 3.0) * 0.5 - 0.5 * 0.5 - 0.5 * 0.5)).abs() < 1e-14,
            "{area}"
        );
    }

    /// `cells_outside` lists exactly the non-hidden sites whose integrated mass is 0: sites in
    /// and around the unit disk (up to radius 1.15), random weights of a few squared spacings
    /// pushing some cells off the disk, checked against the full integration on many diagrams.
    #[test]
    fn cells_outside_are_exactly_the_cells_of_mass_zero() {
        let measure = crate::synthetic::disk_rings_measure(12, |x| 1.0 + x[0] * x[0]).unwrap();
        let integrator = RestrictedIntegrator::new(&measure);
        let (mut listed_total, mut hidden_total) = (0, 0);
        for seed in 0..40u64 {
            let n = 60 + (seed as usize % 5) * 40;
            let mut state = seed;
            let sites: Vec<[f64; 2]> = crate::synthetic::random_disk_points(n, seed + 1000)
                .into_iter()
                .map(|p| [1.15 * p[0], 1.15 * p[1]])
                .collect();
            let spacing2 = 4.0 / n as f64;
            let weights: Vec<f64> = (0..n)
                .map(|_| 6.0 * spacing2 * (crate::synthetic::uniform01(&mut state) - 0.5))
                .collect();
            let diagram = PowerDiagram::new(&sites, &weights).unwrap();
            let listed = integrator.cells_outside(&diagram);
            let masses = integrator.integrate(&diagram).masses;
            let zero: Vec<u32> = (0..n as u32)
                .filter(|&i| masses[i as usize] == 0.0 && !diagram.is_hidden(i as usize))
                .collect();
            assert_eq!(listed, zero, "seed {seed}");
            listed_total += listed.len();
            hidden_total += (0..n).filter(|&i| diagram.is_hidden(i)).count();
        }
        // (the cases exercise both kinds of cell without mass)
        assert!(
            listed_total >= 20 && hidden_total >= 5,
            "{listed_total} listed, {hidden_total} hidden"
        );
    }

    /// A site beside the unit square whose cell is pushed off it is listed until its weight
    /// brings the cell back over the square.
    #[test]
    fn a_cell_beside_the_domain_is_listed_until_it_reaches_it() {
        let measure = SourceMeasure::new(
            vec![[0.0, 0.0], [1.0, 0.0], [1.0, 1.0], [0.0, 1.0]],
            vec![[0, 1, 2], [0, 2, 3]],
            vec![1.0, 1.0],
        )
        .unwrap();
        let integrator = RestrictedIntegrator::new(&measure);
        let sites = [[0.25, 0.25], [0.25, 0.75], [0.75, 0.5], [2.0, 0.5]];
        // The bisector of sites 2 and 3 is x = 1.375 + (w2 − w3)/2.5 (the other sites' bisectors
        // with 3 lie beyond it near the square): site 3's cell misses the square for
        // w3 < w2 + 0.9375.
        for (w3, outside) in [(-2.0, true), (0.0, true), (0.9, true), (0.95, false), (2.0, false)] {
            let diagram = PowerDiagram::new(&sites, &[0.0, 0.0, 0.0, w3]).unwrap();
            let masses = integrator.integrate(&diagram).masses;
            assert_eq!(masses[3] == 0.0, outside, "w3 {w3}: mass {}", masses[3]);
            assert_eq!(
                integrator.cells_outside(&diagram),
                if outside { vec![3] } else { vec![] },
                "w3 {w3}"
            );
        }
    }
}
