//! Power diagrams through their dual, the regular (weighted Delaunay) triangulation.
//!
//! For sites $y_i \in \mathbb{R}^2$ with power weights $w_i$, the power cell of $i$ is
//! $$W_i = \{x : |x - y_i|^2 - w_i \le |x - y_j|^2 - w_j \ \forall j\}.$$
//! Two cells share an edge exactly when the sites are joined by an edge of the regular
//! triangulation, the projection of the lower convex hull of the lifted points
//! $\hat y_i = (y_i, |y_i|^2 - w_i)$ (Aurenhammer 1987; Edelsbrunner & Shah 1996). Sites whose
//! lifted point is not on the lower hull own no cell: they are *hidden* (redundant).
//!
//! # Construction
//! Incremental Bowyer–Watson insertion (beneath–beyond in the lifted space): the triangles in
//! conflict with the new point (lifted point below their lifted plane, [`crate::predicates`]) form
//! a topological disk, which is replaced by the star of the new point; vertices interior to the
//! disk become hidden. A point inside a triangle it is not in conflict with is hidden. The
//! convex hull is closed by an *infinite vertex* as in CGAL (Boissonnat, Devillers, Pion,
//! Teillaud, Yvinec 2002), so no bounding construction can hide true hull points. Insertion
//! follows a biased randomized insertion order (Amenta, Choi, Rote 2003) whose rounds are sorted
//! along a Hilbert curve; point location is a visibility walk from the last created triangle
//! (it terminates on regular triangulations, Edelsbrunner 1990). The insertion order depends on the
//! sites only ([`InsertionOrder`]); the Newton solver computes it once per set of points and
//! rebuilds only the triangulation for every new set of weights ([`DiagramBuilder::order`]).
//! All constructions go through [`PowerDiagram::builder`], whose options ([`DiagramBuilder`])
//! only save work: the diagram is the same.
//!
//! # Update by flips
//! Between close weights (the line-search trials of a Newton step, all from the step's start)
//! [`DiagramBuilder::update_from`] repairs the previous triangulation instead:
//! Lawson's flips lifted to regular triangulations (2-2 flips of non-regular edges of convex
//! quads, 3-1 flips that remove a reflex vertex of degree three, which is then hidden), then the
//! previously hidden sites are inserted as above. A triangulation that is locally regular
//! everywhere, with every hidden site above it, is the regular one, so the result is the same as
//! the construction's; in the weighted case flips can get stuck (a reflex vertex of higher
//! degree, three collinear corners), and the construction is the fallback. Neighbour rings start
//! at a canonical place (after the infinite vertex, or at the smallest index), so both paths
//! give the same neighbour lists, hence the same integrals to the last bit.
//!
//! All combinatorial decisions use exact predicates with symbolic perturbation, so the result is
//! the regular triangulation of the input (for ties: of the consistently perturbed input).
//! When all sites are collinear the diagram is one-dimensional (cells are parallel strips); it is
//! computed by a lower-hull scan along the line with the same predicates. One site owns the
//! whole plane.
//!
//! Input range: coordinates with |x| ≤ 1e30 and weights with |w| ≤ 1e60 (so that no exact
//! product overflows), and nonzero coordinates with |x| ≥ 1e-30 ([`MIN_COORDINATE`], so that no
//! exact product underflows); coincident sites are rejected with [`OmtError::DuplicatePoints`].

mod check;
mod flips;
mod order;
mod triangulator;

pub(crate) use order::hilbert_order;
pub use order::InsertionOrder;

use crate::error::OmtError;
use crate::predicates::{orient, power_compare, power_side_1d, Weight};
use order::validate_and_sort;
use triangulator::{dd_weights, Triangulator};

/// Sentinel for "no triangle / dead triangle".
const NONE: u32 = u32::MAX;

/// Smallest magnitude of a nonzero site coordinate: the predicates multiply up to four
/// coordinates, and their exact error terms must stay normal f64 (spade refuses values below
/// 1.8e-43 for the same reason, `InsertionError::TooSmall`). A power-diagram fuzz sweep with
/// subnormal coordinates beside ordinary ones broke the diagram's invariants (non-regular edges,
/// clockwise triangles, an index out of bounds).
pub const MIN_COORDINATE: f64 = 1e-30;

/// A power diagram, or the sites found hidden before its construction was stopped
/// ([`DiagramBuilder::stop_past_hidden`]).
#[derive(Clone, Debug)]
pub enum Construction {
    /// The complete diagram; with an early stop requested, no site is hidden.
    Complete(PowerDiagram),
    /// Sites hidden among the first `inserted` sites of the insertion order, hence hidden in
    /// the complete diagram (which may hide more). (From a flip update, `inserted` = N: the
    /// sites its 3-1 flips hid, or, after the re-insertion of the previously hidden sites, all
    /// hidden sites.)
    Hidden { hidden: Vec<u32>, inserted: usize },
}

impl Construction {
    /// The diagram of a construction that ran without an early stop (`max_hidden` =
    /// `usize::MAX`), which is always complete.
    fn complete(self) -> PowerDiagram {
        match self {
            Construction::Complete(diagram) => diagram,
            Construction::Hidden { .. } => unreachable!("a construction without early stop is complete"),
        }
    }
}

/// The power diagram of weighted sites, stored as its dual regular triangulation.
#[derive(Clone, Debug)]
pub struct PowerDiagram {
    sites: Vec<[f64; 2]>,
    /// The weights in double-double form, as the predicates see them.
    weights: Vec<Weight>,
    hidden: Vec<bool>,
    /// CSR offsets into `neighbor_list`, #N + 1.
    neighbor_offsets: Vec<u32>,
    /// Neighbours of every site, counter-clockwise around it (2-D case).
    neighbor_list: Vec<u32>,
    /// 0 (one site), 1 (all sites collinear) or 2.
    dimension: usize,
    /// Triangles of the triangulation including the infinite ones (vertex index N is the
    /// infinite vertex), counter-clockwise; dead slots hold `[NONE; 3]`. Empty unless dim 2.
    triangle_vertices: Vec<[u32; 3]>,
    /// `triangle_neighbors[t][k]`: the triangle across the edge opposite vertex k of t.
    triangle_neighbors: Vec<[u32; 3]>,
    /// A visible (non-hidden) site, start of point location without hint.
    start_site: u32,
}

/// The options of one power-diagram construction ([`PowerDiagram::builder`]): low parts of the
/// weights, an insertion order computed beforehand, a previous diagram to update by flips, an
/// early stop once too many sites are hidden. Every combination gives the same diagram as
/// [`PowerDiagram::new`] on the exact weights (or the sites found hidden before an early stop);
/// the options only save work.
#[derive(Clone, Copy, Debug)]
pub struct DiagramBuilder<'a> {
    sites: &'a [[f64; 2]],
    weights: &'a [f64],
    weights_lo: Option<&'a [f64]>,
    order: Option<&'a InsertionOrder>,
    previous: Option<&'a PowerDiagram>,
    max_hidden: usize,
}

impl<'a> DiagramBuilder<'a> {
    /// Weights in double-double form: w_i = `weights[i]` + `weights_lo[i]` exactly (|lo| at most
    /// half an ulp of the high part). Every predicate sees the exact sum, so sites closer than
    /// the weights' ulp still get their cells right. `None`: the weights as given.
    pub fn low_parts(mut self, weights_lo: Option<&'a [f64]>) -> Self {
        self.weights_lo = weights_lo;
        self
    }

    /// The insertion order of the sites, computed beforehand ([`InsertionOrder::new`]) for many
    /// diagrams of the same sites with different weights (the Newton iterations): skips the
    /// validation of the sites and their sorting. The result is the same as without it.
    pub fn order(mut self, order: &'a InsertionOrder) -> Self {
        self.order = Some(order);
        self
    }

    /// Starts from `previous`, a diagram of the same sites with other weights: its triangulation
    /// is repaired by flips instead of built by insertion when it can be (Lawson's flip algorithm
    /// lifted to regular triangulations; Edelsbrunner & Shah 1996). Every non-regular edge is
    /// flipped (2-2), or its reflex vertex removed when it has three neighbours (3-1: that site
    /// is hidden); the sites hidden in `previous` are then inserted as by the construction, and
    /// become visible when they are in conflict. A triangulation that is locally regular
    /// everywhere, with every hidden site above it, is the regular one, so the result is the
    /// diagram the construction builds (with the same neighbour lists:
    /// [`PowerDiagram::neighbors`] depends on the triangulation only). Flips can get stuck on a
    /// non-regular edge whose reflex vertex has more than three neighbours, and collinear quads
    /// are not flipped; the construction by insertion is the fallback then, and when `previous`
    /// is not a 2-D diagram of the same sites with at least four visible sites. (The triangle
    /// slots, hence the order of [`PowerDiagram::triangles`], do depend on the path.) Cost: one
    /// predicate per edge plus the flips; between close weights (the Newton steps of an OT
    /// solve) a fraction of the construction's.
    pub fn update_from(mut self, previous: &'a PowerDiagram) -> Self {
        self.previous = Some(previous);
        self
    }

    /// Stops as soon as more than `max_hidden` sites are hidden (for the damped Newton step,
    /// which rejects any trial with an empty cell and only needs to know whether many vanished);
    /// applies to [`DiagramBuilder::construct`]. A site hidden among the sites inserted so far
    /// is hidden in the full diagram too: its lifted point lies above the lower hull of a subset
    /// of the lifted points, hence above the lower hull of all of them. So
    /// [`Construction::Hidden`] lists more than `max_hidden` sites that are hidden in the complete
    /// diagram, and [`Construction::Complete`] is that diagram, with at most `max_hidden` hidden
    /// sites when the sites are not collinear (collinear sites are always built completely).
    pub fn stop_past_hidden(mut self, max_hidden: usize) -> Self {
        self.max_hidden = max_hidden;
        self
    }

    /// The complete diagram (an early stop of [`DiagramBuilder::stop_past_hidden`] is not
    /// applied). Errors as [`DiagramBuilder::construct`].
    pub fn build(self) -> Result<PowerDiagram, OmtError> {
        Ok(self.stop_past_hidden(usize::MAX).construct()?.0.complete())
    }

    /// The construction, which stops early past [`DiagramBuilder::stop_past_hidden`] hidden
    /// sites, and whether it was reached by flips from [`DiagramBuilder::update_from`]'s diagram
    /// (false: built by insertion).
    ///
    /// Errors: [`OmtError::InvalidInput`] for mismatched lengths (of the sites, weights, low
    /// parts and insertion order), no site, a non-finite coordinate or weight, or one out of
    /// range (|x| > 1e30, 0 < |x| < 1e-30, |w| > 1e60), naming the index;
    /// [`OmtError::DuplicatePoints`] `{ i, j }` (i < j) when sites i and j coincide exactly.
    /// With an insertion order, the sites are not checked again.
    pub fn construct(self) -> Result<(Construction, bool), OmtError> {
        let computed;
        let order = match self.order {
            Some(order) => order,
            None => {
                let sorted = validate_and_sort(self.sites, self.weights)?;
                computed = InsertionOrder::from_sorted(self.sites, sorted);
                &computed
            }
        };
        PowerDiagram::validate(self.sites, self.weights, self.weights_lo, order)?;
        let (sites, weights, weights_lo, max_hidden) = (self.sites, self.weights, self.weights_lo, self.max_hidden);
        if let Some(previous) = self.previous {
            let visible = previous.hidden.iter().filter(|&&h| !h).count();
            if previous.dimension == 2 && visible >= 4 && previous.sites.as_slice() == sites {
                let w = dd_weights(weights, weights_lo);
                if let Some(updated) = previous.by_flips(w, order, max_hidden) {
                    return Ok((updated, true));
                }
            }
        }
        Ok((
            PowerDiagram::build(sites, weights, weights_lo, order, max_hidden),
            false,
        ))
    }
}

impl PowerDiagram {
    /// The regular (weighted Delaunay) triangulation of `sites` (#N) with power weights
    /// `weights` (#N), i.e. the power diagram with cells
    /// W_i = {x : |x − y_i|² − w_i ≤ |x − y_j|² − w_j ∀j}. Equal weights give the Voronoi
    /// diagram. Expected O(N log N) time. The same as `PowerDiagram::builder(sites,
    /// weights).build()`; errors as [`DiagramBuilder::construct`].
    pub fn new(sites: &[[f64; 2]], weights: &[f64]) -> Result<Self, OmtError> {
        Self::builder(sites, weights).build()
    }

    /// A construction of the diagram of `sites` (#N) with power weights `weights` (#N), with the
    /// options of [`DiagramBuilder`]; [`DiagramBuilder::build`] or [`DiagramBuilder::construct`]
    /// runs it.
    pub fn builder<'a>(sites: &'a [[f64; 2]], weights: &'a [f64]) -> DiagramBuilder<'a> {
        DiagramBuilder {
            sites,
            weights,
            weights_lo: None,
            order: None,
            previous: None,
            max_hidden: usize::MAX,
        }
    }

    fn validate(
        sites: &[[f64; 2]],
        weights: &[f64],
        weights_lo: Option<&[f64]>,
        order: &InsertionOrder,
    ) -> Result<(), OmtError> {
        if let Some(lo) = weights_lo {
            if lo.len() != weights.len() {
                return Err(OmtError::InvalidInput(format!(
                    "{} weights but {} low parts",
                    weights.len(),
                    lo.len()
                )));
            }
            if let Some(i) = lo.iter().position(|w| !w.is_finite()) {
                return Err(OmtError::InvalidInput(format!("weight {i} has a non-finite low part")));
            }
        }
        if sites.len() != order.order.len() || weights.len() != sites.len() {
            return Err(OmtError::InvalidInput(format!(
                "{} sites and {} weights for an insertion order of {} sites",
                sites.len(),
                weights.len(),
                order.order.len()
            )));
        }
        if let Some(i) = weights.iter().position(|w| !w.is_finite() || w.abs() > 1e60) {
            return Err(OmtError::InvalidInput(format!(
                "weight {i} = {} is not finite or exceeds 1e60 in magnitude",
                weights[i]
            )));
        }
        Ok(())
    }

    fn build(
        sites: &[[f64; 2]],
        weights: &[f64],
        weights_lo: Option<&[f64]>,
        order: &InsertionOrder,
        max_hidden: usize,
    ) -> Construction {
        let n = sites.len();
        let weights = dd_weights(weights, weights_lo);
        let mut diagram = PowerDiagram {
            sites: sites.to_vec(),
            weights,
            hidden: vec![false; n],
            neighbor_offsets: vec![0; n + 1],
            neighbor_list: Vec::new(),
            dimension: 0,
            triangle_vertices: Vec::new(),
            triangle_neighbors: Vec::new(),
            start_site: order.first,
        };
        if n == 1 {
            return Construction::Complete(diagram);
        }
        if order.collinear {
            diagram.build_collinear();
        } else if let Some(stopped) = diagram.build_2d(&order.order, max_hidden) {
            return stopped;
        }
        Construction::Complete(diagram)
    }

    /// One-dimensional case: all sites on a line. Lower hull of the lifted points along the line.
    fn build_collinear(&mut self) {
        let n = self.sites.len();
        self.dimension = 1;
        let s = &self.sites;
        let w = &self.weights;
        let mut along: Vec<u32> = (0..n as u32).collect();
        along.sort_unstable_by(|&i, &j| {
            let (p, q) = (s[i as usize], s[j as usize]);
            p[0].total_cmp(&q[0]).then(p[1].total_cmp(&q[1]))
        });
        let mut chain: Vec<u32> = Vec::with_capacity(n);
        for &q in &along {
            while chain.len() >= 2 {
                let b = chain[chain.len() - 1];
                let a = chain[chain.len() - 2];
                let (ai, bi, qi) = (a as usize, b as usize, q as usize);
                if power_side_1d(s[ai], w[ai], a, s[qi], w[qi], q, s[bi], w[bi], b) {
                    break;
                }
                self.hidden[bi] = true;
                chain.pop();
            }
            chain.push(q);
        }
        let mut lists: Vec<Vec<u32>> = vec![Vec::new(); n];
        for k in 0..chain.len() {
            let i = chain[k] as usize;
            if k > 0 {
                lists[i].push(chain[k - 1]);
            }
            if k + 1 < chain.len() {
                lists[i].push(chain[k + 1]);
            }
        }
        self.set_neighbors(lists);
        self.start_site = chain[chain.len() / 2];
    }

    fn set_neighbors(&mut self, lists: Vec<Vec<u32>>) {
        let mut offsets = Vec::with_capacity(lists.len() + 1);
        offsets.push(0u32);
        let total: usize = lists.iter().map(Vec::len).sum();
        let mut flat = Vec::with_capacity(total);
        for l in lists {
            flat.extend_from_slice(&l);
            offsets.push(flat.len() as u32);
        }
        self.neighbor_offsets = offsets;
        self.neighbor_list = flat;
    }

    /// Two-dimensional case; `order[0..3]` is a non-degenerate triangle. Returns
    /// [`Construction::Hidden`] after the insertion that hides the (`max_hidden` + 1)-th site
    /// (`self` is then unfinished).
    fn build_2d(&mut self, order: &[u32], max_hidden: usize) -> Option<Construction> {
        let n = self.sites.len();
        self.dimension = 2;
        let inf = n as u32;
        let (mut a, mut b, c) = (order[0], order[1], order[2]);
        if orient(self.sites[a as usize], self.sites[b as usize], self.sites[c as usize]) < 0 {
            std::mem::swap(&mut a, &mut b);
        }
        // Triangle 0 = (a, b, c); infinite triangles 1 = (b, a, ∞), 2 = (c, b, ∞), 3 = (a, c, ∞).
        let tv = vec![[a, b, c], [b, a, inf], [c, b, inf], [a, c, inf]];
        let tn = vec![[2, 3, 1], [3, 2, 0], [1, 3, 0], [2, 1, 0]];
        let mut builder = Triangulator::new(&self.sites, &self.weights, tv, tn, vec![false; n]);
        builder.last = 0;
        for v in [a, b, c] {
            builder.vertex_triangle[v as usize] = 0;
        }
        builder.tv.reserve(2 * n);
        builder.tn.reserve(2 * n);
        builder.mark.reserve(2 * n);
        let mut hidden = 0usize;
        for (k, &q) in order[3..].iter().enumerate() {
            hidden += builder.insert(q);
            if hidden > max_hidden {
                return Some(Construction::Hidden {
                    hidden: (0..n as u32).filter(|&i| builder.hidden[i as usize]).collect(),
                    inserted: k + 4,
                });
            }
        }
        let Triangulator {
            tv,
            tn,
            hidden,
            vertex_triangle,
            ..
        } = builder;
        self.set_triangulation(order, tv, tn, hidden, vertex_triangle);
        None
    }

    /// Stores a finished 2-D triangulation and derives the neighbour lists from it.
    /// `vertex_triangle[v]` is a triangle incident to every visible site v.
    ///
    /// Neighbours: rotate counter-clockwise around every visible vertex, in insertion (spatially
    /// coherent) order for memory locality, then scatter into CSR by index. Each ring starts
    /// after the infinite vertex (hull sites) or at its smallest index (interior sites), so the
    /// lists depend on the triangulation only, not on how it was reached (built by insertion or
    /// updated by flips, [`DiagramBuilder::update_from`]).
    fn set_triangulation(
        &mut self,
        order: &[u32],
        tv: Vec<[u32; 3]>,
        tn: Vec<[u32; 3]>,
        hidden: Vec<bool>,
        vertex_triangle: Vec<u32>,
    ) {
        let n = self.sites.len();
        let inf = n as u32;
        let mut rings: Vec<u32> = Vec::with_capacity(6 * n);
        let mut ring_range = vec![(0u32, 0u32); n];
        for &v in order {
            if hidden[v as usize] {
                continue;
            }
            let start = vertex_triangle[v as usize];
            let first = rings.len();
            let mut t = start;
            loop {
                let tri = tv[t as usize];
                let k = if tri[0] == v {
                    0
                } else if tri[1] == v {
                    1
                } else {
                    2
                };
                rings.push(tri[(k + 1) % 3]);
                t = tn[t as usize][(k + 1) % 3];
                if t == start || rings.len() - first > n + 1 {
                    break;
                }
            }
            let ring = &mut rings[first..];
            if let Some(pos) = ring.iter().position(|&u| u == inf) {
                ring.rotate_left(pos + 1);
                rings.pop();
            } else {
                let smallest = (0..ring.len()).min_by_key(|&k| ring[k]).unwrap_or(0);
                ring.rotate_left(smallest);
            }
            ring_range[v as usize] = (first as u32, rings.len() as u32);
        }
        let mut offsets = Vec::with_capacity(n + 1);
        let mut flat: Vec<u32> = Vec::with_capacity(rings.len());
        offsets.push(0u32);
        for &(a, b) in &ring_range {
            flat.extend_from_slice(&rings[a as usize..b as usize]);
            offsets.push(flat.len() as u32);
        }
        self.hidden = hidden;
        self.neighbor_offsets = offsets;
        self.neighbor_list = flat;
        self.start_site = (0..n as u32).find(|&v| !self.hidden[v as usize]).unwrap_or(0);
        self.triangle_vertices = tv;
        self.triangle_neighbors = tn;
    }

    /// Number of sites N (hidden ones included).
    pub fn num_sites(&self) -> usize {
        self.sites.len()
    }

    /// The sites the diagram was built from, #N.
    pub fn sites(&self) -> &[[f64; 2]] {
        &self.sites
    }

    /// Weight `i` in double-double form (low part 0 unless built by
    /// [`DiagramBuilder::low_parts`]).
    pub fn weight(&self, i: usize) -> Weight {
        self.weights[i]
    }

    /// 0 (a single site), 1 (all sites on one line: the cells are parallel strips) or 2.
    pub fn dimension(&self) -> usize {
        self.dimension
    }

    /// True when site i owns no cell at all: its lifted point is not on the lower convex hull
    /// (it is redundant in the regular triangulation). Out-of-range i: false.
    pub fn is_hidden(&self, i: usize) -> bool {
        self.hidden.get(i).copied().unwrap_or(false)
    }

    /// Sites whose cells share an edge with cell i: its neighbours in the regular triangulation,
    /// counter-clockwise around y_i (2-D case; for collinear sites: the previous and next visible
    /// site along the line). Empty for hidden sites, for N = 1 and for out-of-range i. Under
    /// exact ties (co-circular sites) the perturbed triangulation may list a neighbour whose
    /// common edge has zero length.
    pub fn neighbors(&self, i: usize) -> &[u32] {
        if i >= self.sites.len() {
            return &[];
        }
        &self.neighbor_list[self.neighbor_offsets[i] as usize..self.neighbor_offsets[i + 1] as usize]
    }

    /// CSR offsets of the neighbour lists (#N + 1): the neighbours of i are
    /// `neighbor_list()[offsets[i]..offsets[i + 1]]`.
    pub fn neighbor_offsets(&self) -> &[u32] {
        &self.neighbor_offsets
    }

    /// All neighbour lists concatenated (see [`Self::neighbor_offsets`]).
    pub fn neighbor_list(&self) -> &[u32] {
        &self.neighbor_list
    }

    /// The finite triangles of the regular triangulation, counter-clockwise (#T). Empty when the
    /// sites are collinear or N = 1. Their power centres are the vertices of the power diagram.
    /// Their order (and each one's first vertex) depends on how the triangulation was reached
    /// (construction or flip update), unlike the neighbour lists.
    pub fn triangles(&self) -> Vec<[u32; 3]> {
        let inf = self.sites.len() as u32;
        self.triangle_vertices
            .iter()
            .filter(|t| t[0] != NONE && !t.contains(&inf))
            .copied()
            .collect()
    }

    /// The triangulation as stored (2-D case; empty otherwise): triangles counter-clockwise
    /// including the infinite ones (vertex N is the infinite vertex), dead slots `[u32::MAX; 3]`,
    /// and per triangle the triangle across the edge opposite each of its vertices.
    pub(crate) fn raw_triangulation(&self) -> (&[[u32; 3]], &[[u32; 3]]) {
        (&self.triangle_vertices, &self.triangle_neighbors)
    }

    /// Per triangle of [`Self::triangles`] (same order), the index in that list of the triangle
    /// across the edge opposite each of its vertices; `u32::MAX` across a hull edge.
    pub fn triangle_neighbors(&self) -> Vec<[u32; 3]> {
        let inf = self.sites.len() as u32;
        let finite = |t: &[u32; 3]| t[0] != NONE && !t.contains(&inf);
        let mut index = vec![NONE; self.triangle_vertices.len()];
        let mut count = 0;
        for (t, v) in self.triangle_vertices.iter().enumerate() {
            if finite(v) {
                index[t] = count;
                count += 1;
            }
        }
        self.triangle_vertices
            .iter()
            .zip(&self.triangle_neighbors)
            .filter(|(v, _)| finite(v))
            .map(|(_, across)| across.map(|u| if u == NONE { NONE } else { index[u as usize] }))
            .collect()
    }

    /// Index of a site whose (closed) power cell contains x: greedy descent of the power
    /// distance π_j(x) = |x − y_j|² − w_j over the neighbour graph, starting at `hint` (or a
    /// fixed site). Every comparison is exact ([`power_compare`]); it stops at the first site no
    /// neighbour of which is strictly closer, which is a global minimiser because a power cell
    /// is the intersection of the half-planes of its neighbours. Ties between cells are thus
    /// broken deterministically by the walk. Cost O(distance in cells from the hint).
    /// Non-finite x returns the start site.
    pub fn locate(&self, x: [f64; 2], hint: Option<usize>) -> usize {
        let mut v = match hint {
            Some(h) if h < self.sites.len() && !self.hidden[h] => h,
            _ => self.start_site as usize,
        };
        if !(x[0].is_finite() && x[1].is_finite()) {
            return v;
        }
        loop {
            let mut best = v;
            for &j in self.neighbors(v) {
                let j = j as usize;
                if power_compare(x, self.sites[j], self.weights[j], self.sites[best], self.weights[best]) < 0 {
                    best = j;
                }
            }
            if best == v {
                return v;
            }
            v = best;
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Uniform numbers in [0, 1) from a fixed xorshift sequence.
    fn uniform(state: &mut u64) -> f64 {
        *state ^= *state << 13;
        *state ^= *state >> 7;
        *state ^= *state << 17;
        (*state >> 11) as f64 / (1u64 << 53) as f64
    }

    /// From a diagram with random weights, the flip update to perturbed weights (small steps
    /// keep the triangulation nearly unchanged, large ones hide and reveal many sites) is the
    /// diagram built by insertion: same hidden sites and neighbour lists, and it passes the
    /// exact sanity check. On random sites (and hull sites on a circle) the flips succeed (no
    /// fallback) up to perturbations of the order of the squared spacing; with a grid patch
    /// (collinear triples, which the flips leave to the construction) the result is the same.
    #[test]
    fn flip_updates_give_the_constructed_diagram() {
        let mut rng = 0x1234_5678_9ABC_DEF1u64;
        let mut sites: Vec<[f64; 2]> = (0..3000)
            .map(|_| [2.0 * uniform(&mut rng) - 1.0, 2.0 * uniform(&mut rng) - 1.0])
            .collect();
        for k in 0..64 {
            let a = k as f64 * std::f64::consts::TAU / 64.0;
            sites.push([1.5 * a.cos(), 1.5 * a.sin()]);
        }
        let mut with_grid = sites.clone();
        for i in 0..10 {
            for j in 0..10 {
                with_grid.push([1.2 + 0.01 * i as f64, 0.01 * j as f64]);
            }
        }
        let mut flipped_cases = 0;
        for (sites, random) in [(sites, true), (with_grid, false)] {
            let n = sites.len();
            let order = InsertionOrder::new(&sites).unwrap();
            let w0: Vec<f64> = (0..n).map(|_| 1e-3 * uniform(&mut rng)).collect();
            let d0 = PowerDiagram::builder(&sites, &w0).order(&order).build().unwrap();
            let hidden0 = (0..n).filter(|&i| d0.is_hidden(i)).count();
            assert!(hidden0 > 10, "{hidden0} hidden sites at the start");
            for scale in [1e-9, 1e-6, 1e-4, 1e-3, 1e-2] {
                let w1: Vec<f64> = w0.iter().map(|w| w + scale * (2.0 * uniform(&mut rng) - 1.0)).collect();
                let lo = vec![0.0; n];
                let built = PowerDiagram::builder(&sites, &w1)
                    .low_parts(Some(&lo))
                    .order(&order)
                    .build()
                    .unwrap();
                let flipped = d0.by_flips(dd_weights(&w1, Some(&lo)), &order, usize::MAX);
                if random && scale <= 1e-3 {
                    assert!(flipped.is_some(), "scale {scale}: the flips got stuck");
                }
                flipped_cases += usize::from(flipped.is_some());
                let (via, by_flips) = PowerDiagram::builder(&sites, &w1)
                    .low_parts(Some(&lo))
                    .order(&order)
                    .update_from(&d0)
                    .stop_past_hidden(usize::MAX)
                    .construct()
                    .unwrap();
                assert_eq!(by_flips, flipped.is_some());
                for d in flipped.into_iter().map(Construction::complete).chain([via.complete()]) {
                    d.sanity_check().unwrap();
                    assert_eq!(d.hidden, built.hidden, "scale {scale}");
                    assert_eq!(d.neighbor_offsets, built.neighbor_offsets, "scale {scale}");
                    assert_eq!(d.neighbor_list, built.neighbor_list, "scale {scale}");
                    assert_eq!(d.start_site, built.start_site);
                }
                let changed = (0..n).filter(|&i| built.is_hidden(i) != d0.is_hidden(i)).count();
                if scale >= 1e-4 {
                    assert!(changed > 0, "scale {scale}: no site changed visibility");
                }
            }
        }
        assert!(flipped_cases >= 6, "{flipped_cases}");
    }

    /// With an early stop, the flip update stops exactly when the construction does (more than
    /// `max_hidden` hidden sites), and a complete result is the constructed diagram.
    #[test]
    fn flip_updates_stop_early_like_the_construction() {
        let mut rng = 0x0F0F_1234_4321_F0F0u64;
        let n = 2000;
        let sites: Vec<[f64; 2]> = (0..n).map(|_| [uniform(&mut rng), uniform(&mut rng)]).collect();
        let order = InsertionOrder::new(&sites).unwrap();
        let d0 = PowerDiagram::builder(&sites, &vec![0.0; n])
            .order(&order)
            .build()
            .unwrap();
        for scale in [1e-5, 1e-4, 3e-4, 1e-3] {
            let w1: Vec<f64> = (0..n).map(|_| scale * uniform(&mut rng)).collect();
            let built = PowerDiagram::builder(&sites, &w1).order(&order).build().unwrap();
            let hidden = (0..n).filter(|&i| built.is_hidden(i)).count();
            for max_hidden in [0, hidden / 2, hidden, hidden + 1] {
                let (via, _) = PowerDiagram::builder(&sites, &w1)
                    .order(&order)
                    .update_from(&d0)
                    .stop_past_hidden(max_hidden)
                    .construct()
                    .unwrap();
                match via {
                    Construction::Complete(d) => {
                        assert!(
                            hidden <= max_hidden,
                            "scale {scale}: complete with {hidden} > {max_hidden} hidden"
                        );
                        assert_eq!(d.neighbor_list, built.neighbor_list);
                        assert_eq!(d.hidden, built.hidden);
                    }
                    Construction::Hidden { hidden: listed, .. } => {
                        assert!(
                            hidden > max_hidden,
                            "scale {scale}: stopped with {hidden} ≤ {max_hidden} hidden"
                        );
                        assert!(listed.len() > max_hidden);
                        assert!(listed.iter().all(|&i| built.is_hidden(i as usize)));
                    }
                }
            }
        }
    }
}
