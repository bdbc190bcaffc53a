//! The regular triangulation under construction: Bowyer–Watson insertion in the lifted space
//! and the lifted Lawson flips of the update (module docs of `power_diagram`).

use super::NONE;
use crate::predicates::{orient, power_side_1d, power_side_sos, Weight};

/// The triangulation under construction (2-D case).
pub(super) struct Triangulator<'a> {
    pub(super) sites: &'a [[f64; 2]],
    pub(super) weights: &'a [Weight],
    pub(super) infinite: u32,
    pub(super) tv: Vec<[u32; 3]>,
    pub(super) tn: Vec<[u32; 3]>,
    pub(super) free: Vec<u32>,
    /// Per triangle: 2·stamp when in conflict with the current point, 2·stamp+1 when tested and
    /// not in conflict.
    pub(super) mark: Vec<u32>,
    pub(super) vertex_mark: Vec<u32>,
    /// New triangle starting at a boundary vertex (scratch for linking the star).
    pub(super) star_link: Vec<u32>,
    pub(super) hidden: Vec<bool>,
    pub(super) vertex_triangle: Vec<u32>,
    pub(super) last: u32,
    pub(super) stamp: u32,
    pub(super) rng: u64,
    pub(super) cavity: Vec<u32>,
    pub(super) boundary: Vec<(u32, u8)>,
    pub(super) stack: Vec<u32>,
    pub(super) cavity_vertices: Vec<u32>,
    pub(super) edges: Vec<(u32, u32, u32)>,
    pub(super) created: Vec<u32>,
}

impl<'a> Triangulator<'a> {
    /// A builder over the triangulation `tv`/`tn` of `sites` (dead slots `[NONE; 3]` become
    /// free slots) with hidden flags `hidden`, ready for insertions and flips.
    pub(super) fn new(
        sites: &'a [[f64; 2]],
        weights: &'a [Weight],
        tv: Vec<[u32; 3]>,
        tn: Vec<[u32; 3]>,
        hidden: Vec<bool>,
    ) -> Self {
        let n = sites.len();
        let free = (0..tv.len() as u32).filter(|&t| tv[t as usize][0] == NONE).collect();
        let last = (0..tv.len() as u32).find(|&t| tv[t as usize][0] != NONE).unwrap_or(0);
        let mark = vec![0; tv.len()];
        Triangulator {
            sites,
            weights,
            infinite: n as u32,
            tv,
            tn,
            free,
            mark,
            vertex_mark: vec![0; n + 1],
            star_link: vec![NONE; n + 1],
            hidden,
            vertex_triangle: vec![NONE; n],
            last,
            stamp: 0,
            rng: 0x2545_F491_4F6C_DD1D,
            cavity: Vec::new(),
            boundary: Vec::new(),
            stack: Vec::new(),
            cavity_vertices: Vec::new(),
            edges: Vec::new(),
            created: Vec::new(),
        }
    }

    #[inline]
    pub(super) fn p(&self, v: u32) -> [f64; 2] {
        self.sites[v as usize]
    }

    /// Conflict test of site `q` with triangle `t` (finite or infinite).
    pub(super) fn conflict(&self, t: u32, q: u32) -> bool {
        let [a, b, c] = self.tv[t as usize];
        let inf = self.infinite;
        let (a, b) = if c == inf {
            (a, b)
        } else if a == inf {
            (b, c)
        } else if b == inf {
            (c, a)
        } else {
            let s = self.sites;
            let w = self.weights;
            let (ai, bi, ci, qi) = (a as usize, b as usize, c as usize, q as usize);
            return power_side_sos(s[ai], w[ai], a, s[bi], w[bi], b, s[ci], w[ci], c, s[qi], w[qi], q);
        };
        // Infinite triangle (a, b, ∞): the exterior of the hull edge a→b lies to its left.
        let o = orient(self.p(a), self.p(b), self.p(q));
        if o != 0 {
            return o > 0;
        }
        let w = self.weights;
        power_side_1d(
            self.p(a),
            w[a as usize],
            a,
            self.p(b),
            w[b as usize],
            b,
            self.p(q),
            w[q as usize],
            q,
        )
    }

    pub(super) fn next_random(&mut self) -> u64 {
        self.rng ^= self.rng << 13;
        self.rng ^= self.rng >> 7;
        self.rng ^= self.rng << 17;
        self.rng
    }

    /// Visibility walk from `start` to a triangle containing site q, or to an infinite triangle
    /// whose hull edge sees q (which is then in conflict with q).
    pub(super) fn locate(&mut self, q: u32, start: u32) -> u32 {
        let x = self.p(q);
        let inf = self.infinite;
        let mut t = start;
        if self.tv[t as usize].contains(&inf) {
            let k = self.tv[t as usize].iter().position(|&v| v == inf).unwrap_or(0);
            t = self.tn[t as usize][k];
        }
        let mut previous = NONE;
        let mut steps = 0usize;
        'walk: loop {
            steps += 1;
            if steps > 4 * self.tv.len() + 16 {
                // Cannot happen on a regular triangulation; safe exhaustive fallback.
                return self.locate_exhaustive(q);
            }
            let tri = self.tv[t as usize];
            if tri.contains(&inf) {
                return t;
            }
            let r = (self.next_random() % 3) as usize;
            for i in 0..3 {
                let k = (r + i) % 3;
                let nb = self.tn[t as usize][k];
                if nb == previous {
                    continue;
                }
                let (u, v) = (tri[(k + 1) % 3], tri[(k + 2) % 3]);
                if orient(self.p(u), self.p(v), x) < 0 {
                    previous = t;
                    t = nb;
                    continue 'walk;
                }
            }
            return t;
        }
    }

    pub(super) fn locate_exhaustive(&self, q: u32) -> u32 {
        let x = self.p(q);
        let inf = self.infinite;
        for (t, tri) in self.tv.iter().enumerate() {
            if tri[0] == NONE || tri.contains(&inf) {
                continue;
            }
            if (0..3).all(|k| orient(self.p(tri[(k + 1) % 3]), self.p(tri[(k + 2) % 3]), x) >= 0) {
                return t as u32;
            }
        }
        for (t, tri) in self.tv.iter().enumerate() {
            if tri[0] != NONE && tri.contains(&inf) && self.conflict(t as u32, q) {
                return t as u32;
            }
        }
        self.last
    }

    pub(super) fn new_triangle(&mut self) -> u32 {
        if let Some(t) = self.free.pop() {
            t
        } else {
            self.tv.push([NONE; 3]);
            self.tn.push([NONE; 3]);
            self.mark.push(0);
            (self.tv.len() - 1) as u32
        }
    }

    /// Inserts site q (Bowyer–Watson on the lifted points). Returns the number of sites that
    /// became hidden (q, or the vertices interior to q's cavity).
    pub(super) fn insert(&mut self, q: u32) -> usize {
        let t0 = self.locate(q, self.last);
        if !self.conflict(t0, q) {
            self.hidden[q as usize] = true;
            return 1;
        }
        self.stamp += 1;
        let (yes, no) = (2 * self.stamp, 2 * self.stamp + 1);
        self.cavity.clear();
        self.boundary.clear();
        self.stack.clear();
        self.mark[t0 as usize] = yes;
        self.stack.push(t0);
        while let Some(s) = self.stack.pop() {
            self.cavity.push(s);
            for k in 0..3u8 {
                let nb = self.tn[s as usize][k as usize];
                let m = self.mark[nb as usize];
                if m == yes {
                    continue;
                }
                if m != no && self.conflict(nb, q) {
                    self.mark[nb as usize] = yes;
                    self.stack.push(nb);
                } else {
                    self.mark[nb as usize] = no;
                    self.boundary.push((s, k));
                }
            }
        }
        // Vertices of the cavity, recorded before its slots are reused.
        self.cavity_vertices.clear();
        for i in 0..self.cavity.len() {
            let s = self.cavity[i] as usize;
            let tri = self.tv[s];
            self.cavity_vertices.extend_from_slice(&tri);
        }
        // Star of q over the cavity boundary.
        self.edges.clear();
        for i in 0..self.boundary.len() {
            let (s, k) = self.boundary[i];
            let tri = self.tv[s as usize];
            let k = k as usize;
            self.edges
                .push((tri[(k + 1) % 3], tri[(k + 2) % 3], self.tn[s as usize][k]));
        }
        for i in 0..self.cavity.len() {
            let s = self.cavity[i];
            self.tv[s as usize] = [NONE; 3];
            self.free.push(s);
        }
        self.created.clear();
        for i in 0..self.edges.len() {
            let (u, v, outside) = self.edges[i];
            let t = self.new_triangle();
            self.tv[t as usize] = [u, v, q];
            self.tn[t as usize] = [NONE, NONE, outside];
            self.mark[t as usize] = 0;
            // The outside triangle pointed to a cavity triangle across edge (v, u).
            let on = self.tv[outside as usize];
            let slot = (0..3).find(|&j| on[j] != u && on[j] != v).unwrap_or(0);
            self.tn[outside as usize][slot] = t;
            self.star_link[u as usize] = t;
            self.vertex_mark[u as usize] = self.stamp;
            if u != self.infinite {
                self.vertex_triangle[u as usize] = t;
            }
            self.created.push(t);
        }
        for i in 0..self.created.len() {
            let t = self.created[i];
            let v = self.tv[t as usize][1];
            let s = self.star_link[v as usize];
            self.tn[t as usize][0] = s;
            self.tn[s as usize][1] = t;
        }
        // Vertices of the cavity that are not on its boundary disappear: hidden.
        let mut hid = 0;
        for i in 0..self.cavity_vertices.len() {
            let v = self.cavity_vertices[i];
            // (a vertex is listed once per cavity triangle it belongs to)
            if v != self.infinite && self.vertex_mark[v as usize] != self.stamp && !self.hidden[v as usize] {
                self.hidden[v as usize] = true;
                hid += 1;
            }
        }
        self.vertex_triangle[q as usize] = self.created[0];
        self.vertex_mark[q as usize] = self.stamp;
        self.last = self.created[self.created.len() - 1];
        hid
    }
}

/// What [`Triangulator::restore_edge`] did with one edge.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(super) enum EdgeRepair {
    /// The edge is locally regular (or its slot is dead).
    Regular,
    /// A 2-2 flip, or a 3-1 flip that hid a site.
    Flipped,
    /// Not regular, but its reflex vertex has more than three neighbours, or the quad has three
    /// collinear corners: try again later.
    Blocked,
    /// A case the flips do not handle: an inconsistent adjacency, a 3-1 flip whose new
    /// triangle would contain the infinite vertex or not be counter-clockwise.
    Degenerate,
}

impl Triangulator<'_> {
    /// Makes edge k of triangle t locally regular if one flip can: with t = (x, u, v) (x its
    /// vertex k) and s = (y, v, u) across the edge, the edge is regular unless y is in conflict
    /// with t (x with s when y is the infinite vertex). A non-regular edge of a convex quad
    /// (x, u, y, v) is flipped to (x, y) (2-2 flip); of a quad reflex at u (or v), the reflex
    /// vertex lies inside the triangle of the other three and above their lifted plane, so when
    /// it has exactly three neighbours it is removed (3-1 flip) and becomes hidden. The edges
    /// that may have become non-regular are pushed on `stack`, a hidden site on `hidden_now`.
    pub(super) fn restore_edge(
        &mut self,
        t: u32,
        k: usize,
        stack: &mut Vec<(u32, u8)>,
        hidden_now: &mut Vec<u32>,
    ) -> EdgeRepair {
        let inf = self.infinite;
        match self.edge_is_regular(t, k) {
            Some(true) => return EdgeRepair::Regular,
            Some(false) => {}
            None => return EdgeRepair::Degenerate,
        }
        let tri = self.tv[t as usize];
        let s = self.tn[t as usize][k];
        let Some(j) = (0..3).find(|&j| self.tn[s as usize][j] == t) else {
            return EdgeRepair::Degenerate;
        };
        let (x, u, v) = (tri[k], tri[(k + 1) % 3], tri[(k + 2) % 3]);
        let y = self.tv[s as usize][j];
        if x == inf || y == inf {
            return EdgeRepair::Degenerate;
        }
        // Orientation of the new triangles (x, u, y) and (y, v, x); one containing the infinite
        // vertex is valid exactly when the other one is.
        let o1 = if u == inf {
            1
        } else {
            orient(self.p(x), self.p(u), self.p(y))
        };
        let o2 = if v == inf {
            1
        } else {
            orient(self.p(y), self.p(v), self.p(x))
        };
        if o1 > 0 && o2 > 0 {
            self.flip(t, k, s, j);
            stack.extend_from_slice(&[(t, 0), (t, 2), (s, 0), (s, 2)]);
            return EdgeRepair::Flipped;
        }
        if o1 == 0 || o2 == 0 {
            // (x, u, y) or (y, v, x) collinear: neither flip applies now; other flips may
            // change the quad.
            return EdgeRepair::Blocked;
        }
        let reflex = if o1 < 0 { u } else { v };
        if reflex == inf {
            return EdgeRepair::Degenerate;
        }
        match self.remove_degree3(t, reflex) {
            Some(Ok(r)) => {
                self.hidden[reflex as usize] = true;
                hidden_now.push(reflex);
                stack.extend_from_slice(&[(r, 0), (r, 1), (r, 2)]);
                EdgeRepair::Flipped
            }
            Some(Err(())) => EdgeRepair::Degenerate,
            None => EdgeRepair::Blocked,
        }
    }

    /// Whether edge k of triangle t = (x, u, v) is locally regular: the vertex y across it is
    /// not in conflict with t (x not with the triangle across when y is the infinite vertex).
    /// A dead slot counts as regular; None for an inconsistent adjacency.
    pub(super) fn edge_is_regular(&self, t: u32, k: usize) -> Option<bool> {
        let inf = self.infinite;
        let tri = self.tv[t as usize];
        if tri[0] == NONE {
            return Some(true);
        }
        let s = self.tn[t as usize][k];
        let j = (0..3).find(|&j| self.tn[s as usize][j] == t)?;
        let (x, y) = (tri[k], self.tv[s as usize][j]);
        if y != inf {
            Some(!self.conflict(t, y))
        } else if x != inf {
            Some(!self.conflict(s, x))
        } else {
            None
        }
    }

    /// 2-2 flip of the edge shared by t = (x, u, v) (x at index k) and s = (y, v, u) (y at
    /// index j): t becomes (x, u, y) and s becomes (y, v, x).
    pub(super) fn flip(&mut self, t: u32, k: usize, s: u32, j: usize) {
        let (ti, si) = (t as usize, s as usize);
        let [x, u, v] = [self.tv[ti][k], self.tv[ti][(k + 1) % 3], self.tv[ti][(k + 2) % 3]];
        let y = self.tv[si][j];
        let n_vx = self.tn[ti][(k + 1) % 3];
        let n_xu = self.tn[ti][(k + 2) % 3];
        let n_uy = self.tn[si][(j + 1) % 3];
        let n_yv = self.tn[si][(j + 2) % 3];
        self.tv[ti] = [x, u, y];
        self.tn[ti] = [n_uy, s, n_xu];
        self.tv[si] = [y, v, x];
        self.tn[si] = [n_vx, t, n_yv];
        self.relink(n_uy, s, t);
        self.relink(n_vx, t, s);
    }

    /// In triangle `t`, the neighbour pointer to `from` now points to `to`.
    pub(super) fn relink(&mut self, t: u32, from: u32, to: u32) {
        if let Some(slot) = self.tn[t as usize].iter_mut().find(|n| **n == from) {
            *slot = to;
        }
    }

    /// 3-1 flip: replaces the three triangles around vertex w (one of them `t0`) by the triangle
    /// of w's three neighbours, in t0's slot (returned). None when w has more than three
    /// neighbours; Some(Err) when a neighbour is the infinite vertex or the new triangle would
    /// not be counter-clockwise.
    pub(super) fn remove_degree3(&mut self, t0: u32, w: u32) -> Option<Result<u32, ()>> {
        let mut ts = [NONE; 3];
        let mut link = [NONE; 3];
        let mut t = t0;
        for i in 0..3 {
            let tri = self.tv[t as usize];
            let kw = tri.iter().position(|&v| v == w)?;
            ts[i] = t;
            link[i] = tri[(kw + 1) % 3];
            t = self.tn[t as usize][(kw + 1) % 3];
        }
        if t != t0 {
            return None;
        }
        if link.contains(&self.infinite) || orient(self.p(link[0]), self.p(link[1]), self.p(link[2])) <= 0 {
            return Some(Err(()));
        }
        // The outer neighbour of each triangle (w, link[i], link[i + 1]) is across w.
        let outer = |b: &Self, i: usize| {
            let tri = b.tv[ts[i] as usize];
            let kw = tri.iter().position(|&v| v == w).unwrap_or(0);
            b.tn[ts[i] as usize][kw]
        };
        let (o0, o1, o2) = (outer(self, 0), outer(self, 1), outer(self, 2));
        // New triangle (link[0], link[1], link[2]): across link[0] is edge (link[1], link[2]),
        // the outer edge of ts[1]; across link[1] that of ts[2]; across link[2] that of ts[0].
        self.tv[t0 as usize] = link;
        self.tn[t0 as usize] = [o1, o2, o0];
        self.relink(o1, ts[1], t0);
        self.relink(o2, ts[2], t0);
        for &dead in &ts[1..] {
            self.tv[dead as usize] = [NONE; 3];
            self.tn[dead as usize] = [NONE; 3];
            self.free.push(dead);
        }
        Some(Ok(t0))
    }
}

/// Weights as the predicates see them: (high, low) pairs, low 0 without `weights_lo`.
pub(super) fn dd_weights(weights: &[f64], weights_lo: Option<&[f64]>) -> Vec<Weight> {
    match weights_lo {
        Some(lo) => weights.iter().zip(lo).map(|(&h, &l)| [h, l]).collect(),
        None => weights.iter().map(|&h| [h, 0.0]).collect(),
    }
}
