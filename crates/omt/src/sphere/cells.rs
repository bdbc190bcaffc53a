//! Laguerre cells on the sphere restricted to the flat source triangles, and their integrals.
//!
//! The Laguerre cell of y_i at heights h is W_i = {x : ⟨x, y_i⟩ + h_i ≥ ⟨x, y_j⟩ + h_j ∀j}, the
//! 3D power cell with weight w_i = 2h_i + |y_i|². Per flat source triangle T (plane P):
//!
//! 1. **Candidates.** A bounding-volume tree over the sites (spherical caps, built once per
//!    target; per evaluation each node's heights are bounded by a fitted affine function,
//!    h_j ≤ ⟨g, y_j⟩ + b, so ⟨c, y⟩ + h is bounded by the cap's bound of ⟨c + g, y⟩ plus b:
//!    tight where the heights vary smoothly but strongly) gives the best site k_v at every
//!    vertex v of the source (branch and bound, vertices in Morton order so each search starts
//!    from the previous answer). ℓ_k(x) = ⟨x, y_k⟩ + h_k is a minorant of
//!    u_h = max_i ℓ_i for any k, and ℓ_j − ℓ_k is affine, so a site j can own a point of T only
//!    if ℓ_j − ℓ_k ≥ 0 at some corner of T. The candidates are the sites passing this test
//!    for k = k_a (corner a; a margin of 1e-10 keeps it conservative), filtered by the same test
//!    for k_b and k_c: a superset of the cells meeting T (1.8–8 per triangle in the measured
//!    cases). The sites passing the first test are found per vertex, not per triangle: one tree
//!    query per vertex v lists the sites within s_v of u_h(v), s_v the largest gap
//!    u_h(v) − ℓ_{k_a}(v) over v's triangles, and a triangle tests the union of its corners'
//!    lists.
//! 2. **Clipping.** Each candidate's piece is T clipped by the half-spaces
//!    ⟨x, y_i − y_j⟩ ≥ h_j − h_i of the other candidates (largest ℓ_j at T's centroid first, so that
//!    losing candidates are dropped after one or two clips). Within P this is the 2D power
//!    diagram of the sites projected on P with weights w_i − dist(y_i, P)². Each polygon edge
//!    carries the site whose half-space made it, which names the neighbour of an edge. The
//!    normal y_i − y_j is that of the unit vectors the f64 sites stand for: the stored
//!    difference (exact for close sites) plus the difference of each site's radial correction
//!    onto S² (double-double, `radial_corrections`). Sites 3e-11 apart (a fingertip's
//!    conformal image) have bisector margins of 5e-22, far below the 1e-16 by which f64 points
//!    miss the sphere; uncorrected, such a site falls inside its neighbours' hull and loses
//!    its cell.
//! 3. **Integrals.** Piece masses, first moments and ∫|x − y_i|² are exact on the flat
//!    triangle (fan triangulation); an edge
//!    between i and j in T of length ℓ adds ρ_T ℓ to the edge mass and ρ_T ℓ / |Π_P(y_i − y_j)|
//!    to −H_ij, Π_P the projection on P: raising h_j by t moves that edge into W_i by
//!    t / |Π_P(y_i − y_j)| within P. (On S² itself the factor is the tangential component
//!    √(|y_i − y_j|² − (h_i − h_j)²); |y_i − y_j| alone holds only where h_i = h_j.)
//!
//! The combinatorics are floating point: each triangle is partitioned independently, so the
//! pieces of one triangle agree with each other up to round-off, and nothing across triangles
//! has to agree (docs/decisions/0021-spherical-laguerre-cells.md says why, and what exact
//! predicates would add).
//!
//! Triangles are processed in parallel in fixed chunks of a fixed (Morton) order and reduced in
//! that order, so the results do not depend on the thread count.

use rayon::prelude::*;

use super::measure::{cross, dot, norm, sub, SphereMeasure};

/// Integrals over the Laguerre cells W_i restricted to the flat source triangles.
#[derive(Clone, Debug, Default)]
pub struct SphereCells {
    /// μ(W_i), #N.
    pub masses: Vec<f64>,
    /// ∫_{W_i} x dμ(x) on the flat triangles, #N (divide by the mass for the centroid; it lies
    /// inside the ball, project it radially for a point on S²).
    pub first_moments: Vec<[f64; 3]>,
    /// ∫_{W_i} |x − y_i|² dμ(x) on the flat triangles, #N: the transport cost of cell i.
    pub second_moments: Vec<f64>,
    /// For each pair i < j of cells sharing an edge inside some source triangle:
    /// (i, j, ∫_{e_ij} μ ds), the μ-weighted length of the common edge, summed over triangles.
    pub edge_masses: Vec<(u32, u32, f64)>,
    /// For the same pairs (i, j, −H_ij) = Σ_T ρ_T ℓ_T(e_ij) / |Π_T(y_i − y_j)|, the off-diagonal
    /// Hessian magnitudes of the Kantorovich energy in the heights (module docs).
    pub hessian: Vec<(u32, u32, f64)>,
    /// Source triangles processed, and the mean number of candidate sites per triangle.
    pub triangles: usize,
    pub mean_candidates: f64,
}

impl SphereCells {
    /// μ-centroids of the cells projected radially on S² (#N; `None` for an empty cell).
    pub fn centroids_on_sphere(&self) -> Vec<Option<[f64; 3]>> {
        self.first_moments
            .iter()
            .zip(&self.masses)
            .map(|(m, &mass)| {
                let r = norm(*m);
                (mass > 0.0 && r > 0.0).then(|| [m[0] / r, m[1] / r, m[2] / r])
            })
            .collect()
    }

    /// The transport cost Σ_i ∫_{W_i} |x − y_i|² dμ(x), x on the flat triangles. For x = (1 − δ) x̂
    /// with x̂ on S², |x − y|² = (1 − δ)|x̂ − y|² + δ²: within a relative O(h²) of the chordal
    /// cost of the radial projection. (The linear form ∫ (2 − 2⟨x, y_i⟩) dμ has the same
    /// optimal cells but is off by ≈ 2δ per unit mass, as large as the whole cost of 1e5
    /// equal cells on a 82k-triangle icosphere.)
    pub fn transport_cost(&self) -> f64 {
        self.second_moments.iter().sum()
    }
}

/// One clipped piece: its site, source triangle and polygon (corners on the triangle's plane).
#[derive(Clone, Debug)]
pub struct CellPiece {
    pub site: u32,
    pub triangle: u32,
    pub polygon: Vec<[f64; 3]>,
}

const LEAF: usize = 8;
const NONE: u32 = u32::MAX;

/// Per node of a [`SiteTree`], for given heights: a slope g and the offset
/// max_j h_j − ⟨g, y_j⟩ over the node's sites ([`SiteTree::height_bounds`]).
#[derive(Clone, Debug)]
pub(crate) struct NodeBounds {
    slope: Vec<[f64; 3]>,
    offset: Vec<f64>,
}

/// Two unit vectors completing the unit vector `a` to an orthonormal basis.
fn tangent_basis(a: [f64; 3]) -> [[f64; 3]; 2] {
    // the coordinate axis least aligned with a
    let k = (0..3).min_by(|&i, &j| a[i].abs().total_cmp(&a[j].abs())).unwrap_or(0);
    let mut e = [0.0; 3];
    e[k] = 1.0;
    let t = cross(a, e);
    let r = norm(t);
    let t = [t[0] / r, t[1] / r, t[2] / r];
    [t, cross(a, t)]
}

#[derive(Clone, Debug)]
struct Node {
    /// A spherical cap holding the node's sites: unit axis, cos and sin of its angular radius.
    axis: [f64; 3],
    cos_radius: f64,
    sin_radius: f64,
    /// An orthonormal basis of the plane orthogonal to `axis` (the heights' slope fit).
    tangents: [[f64; 3]; 2],
    start: u32,
    end: u32,
    left: u32,
    right: u32,
}

/// A bounding-volume tree over the sites on S² (median splits along the widest axis, leaves of
/// at most 8 sites; each node bounded by a spherical cap), with per-node maxima of the heights.
/// Caps, not boxes: near its maximum ⟨c, y⟩ is quadratic in the distance, and a box's corners
/// overestimate it to first order (with boxes, a query visited ~500 sites at N = 1e4).
#[derive(Clone, Debug)]
pub struct SiteTree {
    points: Vec<[f64; 3]>,
    nodes: Vec<Node>,
    order: Vec<u32>,
}

impl SiteTree {
    /// The tree of `points` (unit vectors).
    pub fn new(points: &[[f64; 3]]) -> Self {
        let mut tree = SiteTree {
            points: points.to_vec(),
            nodes: Vec::new(),
            order: (0..points.len() as u32).collect(),
        };
        if !points.is_empty() {
            tree.build(0, points.len());
        }
        tree
    }

    fn build(&mut self, start: usize, end: usize) -> u32 {
        let mut lo = [f64::INFINITY; 3];
        let mut hi = [f64::NEG_INFINITY; 3];
        let mut sum = [0.0; 3];
        for &i in &self.order[start..end] {
            let p = self.points[i as usize];
            for k in 0..3 {
                lo[k] = lo[k].min(p[k]);
                hi[k] = hi[k].max(p[k]);
                sum[k] += p[k];
            }
        }
        let r = norm(sum);
        let (axis, cos_radius) = if r > 1e-9 * (end - start) as f64 {
            let axis = [sum[0] / r, sum[1] / r, sum[2] / r];
            let c = self.order[start..end]
                .iter()
                .map(|&i| dot(axis, self.points[i as usize]))
                .fold(1.0, f64::min);
            // (a hair wider than measured, against rounding)
            (axis, (c - 1e-12).max(-1.0))
        } else {
            ([0.0, 0.0, 1.0], -1.0)
        };
        let sin_radius = (1.0 - cos_radius * cos_radius).max(0.0).sqrt();
        let tangents = tangent_basis(axis);
        let id = self.nodes.len();
        self.nodes.push(Node {
            axis,
            cos_radius,
            sin_radius,
            tangents,
            start: start as u32,
            end: end as u32,
            left: NONE,
            right: NONE,
        });
        if end - start > LEAF {
            let axis = (0..3)
                .max_by(|&a, &b| (hi[a] - lo[a]).total_cmp(&(hi[b] - lo[b])))
                .unwrap_or(0);
            let mid = (start + end) / 2;
            let points = &self.points;
            self.order[start..end].select_nth_unstable_by(mid - start, |&a, &b| {
                points[a as usize][axis]
                    .total_cmp(&points[b as usize][axis])
                    .then(a.cmp(&b))
            });
            let left = self.build(start, mid);
            let right = self.build(mid, end);
            self.nodes[id].left = left;
            self.nodes[id].right = right;
        }
        id as u32
    }

    /// Per node, a slope g fitted to the heights by least squares, h_j ≈ h₀ + ⟨g, y_j⟩
    /// ([`Self::fitted_slope`]), and the bound max_j h_j − ⟨g, y_j⟩ (with a rounding margin).
    /// For any g, ⟨c, y⟩ + h = ⟨c + g, y⟩ + (h − ⟨g, y⟩) is at most the cap's bound of
    /// ⟨c + g, y⟩ plus that maximum; with g = 0 that is max h. Heights of a converged solve vary
    /// smoothly over S² (by 0.3 on the conformal image of an ellipsoid 1:1:2, against 1e-4
    /// between neighbours), so max h alone let a query visit hundreds of sites.
    fn height_bounds(&self, heights: &[f64]) -> NodeBounds {
        let per_node: Vec<([f64; 3], f64)> = (0..self.nodes.len())
            .into_par_iter()
            .with_min_len(64)
            .map(|id| {
                let n = &self.nodes[id];
                let sites = &self.order[n.start as usize..n.end as usize];
                let slope = self.fitted_slope(n, sites, heights);
                let mut offset = f64::NEG_INFINITY;
                let mut scale: f64 = 0.0;
                for &i in sites {
                    let h = heights[i as usize];
                    offset = offset.max(h - dot(slope, self.points[i as usize]));
                    scale = scale.max(h.abs());
                }
                // (the computed differences are within a few ulps of |h| + |g| of the true ones)
                (slope, offset + 1e-14 * (1.0 + scale + norm(slope)))
            })
            .collect();
        NodeBounds {
            slope: per_node.iter().map(|p| p.0).collect(),
            offset: per_node.iter().map(|p| p.1).collect(),
        }
    }

    /// The least-squares fit h_j ≈ h₀ + ⟨g, y_j⟩ over `sites`, in the node's frame: the two
    /// tangent components of y_j and its component along the axis, 1 − |t|²/2 to second order,
    /// which absorbs the isotropic curvature of the heights (g = 0 for fewer than four sites, a
    /// degenerate spread, or |g| > 4, where the bounds' rounding margins would not hold).
    fn fitted_slope(&self, n: &Node, sites: &[u32], heights: &[f64]) -> [f64; 3] {
        if sites.len() < 4 {
            return [0.0; 3];
        }
        let frame = [n.tangents[0], n.tangents[1], n.axis];
        let k = sites.len() as f64;
        let mut mean = [0.0; 4];
        for &i in sites {
            let y = self.points[i as usize];
            for d in 0..3 {
                mean[d] += dot(y, frame[d]);
            }
            mean[3] += heights[i as usize];
        }
        let mean = mean.map(|m| m / k);
        let mut a = [[0.0; 3]; 3];
        let mut b = [0.0; 3];
        for &i in sites {
            let y = self.points[i as usize];
            let x = [0, 1, 2].map(|d| dot(y, frame[d]) - mean[d]);
            let h = heights[i as usize] - mean[3];
            for r in 0..3 {
                for c in 0..3 {
                    a[r][c] += x[r] * x[c];
                }
                b[r] += x[r] * h;
            }
        }
        let det3 = |m: &[[f64; 3]; 3]| {
            m[0][0] * (m[1][1] * m[2][2] - m[1][2] * m[2][1]) - m[0][1] * (m[1][0] * m[2][2] - m[1][2] * m[2][0])
                + m[0][2] * (m[1][0] * m[2][1] - m[1][1] * m[2][0])
        };
        let det = det3(&a);
        let scale = a[0][0] * a[1][1] * a[2][2];
        if !(det > 1e-9 * scale && scale > 0.0) {
            return [0.0; 3];
        }
        let mut g = [0.0; 3];
        for (col, gc) in g.iter_mut().enumerate() {
            let mut m = a;
            for r in 0..3 {
                m[r][col] = b[r];
            }
            *gc = det3(&m) / det;
        }
        if !(g.iter().all(|v| v.is_finite()) && dot(g, g) <= 16.0) {
            return [0.0; 3];
        }
        [0, 1, 2].map(|d| g[0] * frame[0][d] + g[1] * frame[1][d] + g[2] * frame[2][d])
    }

    /// Whether max ⟨v, y⟩ over the node's cap (`norm2` = |v|²) can reach `level`: the test
    /// |v| cos(max(0, θ − α)) + 1e-12 ≥ level (θ the angle from v to the cap's axis, α its
    /// radius) without divisions or square roots: with d = ⟨v, axis⟩ = |v| cos θ, θ ≤ α is d ≥ |v| cos α, and otherwise the
    /// maximum d cos α + √(|v|² − d²) sin α reaches l when l − d cos α ≤ 0 or
    /// (|v|² − d²) sin² α ≥ (l − d cos α)².
    fn cap_reaches(&self, id: usize, v: [f64; 3], norm2: f64, level: f64) -> bool {
        let n = &self.nodes[id];
        let l = level - 1e-12;
        if l > 0.0 && l * l > norm2 {
            return false;
        }
        if norm2 == 0.0 {
            return l <= 0.0;
        }
        let d = dot(v, n.axis);
        let c2 = norm2 * n.cos_radius * n.cos_radius;
        let inside = if n.cos_radius >= 0.0 {
            d >= 0.0 && d * d >= c2
        } else {
            d >= 0.0 || d * d <= c2
        };
        if inside {
            return true;
        }
        let rest = l - d * n.cos_radius;
        rest <= 0.0 || (norm2 - d * d) * n.sin_radius * n.sin_radius >= rest * rest
    }

    /// Whether ⟨c, y⟩ + h can reach `level` on the node's sites: with u = c + g (g the node's
    /// slope), ⟨c, y⟩ + h ≤ max ⟨u, y⟩ over the cap + max_j (h_j − ⟨g, y_j⟩)
    /// ([`Self::cap_reaches`]).
    fn tilted_reaches(&self, id: usize, c: [f64; 3], level: f64, bounds: &NodeBounds) -> bool {
        let g = bounds.slope[id];
        let u = [c[0] + g[0], c[1] + g[1], c[2] + g[2]];
        self.cap_reaches(id, u, dot(u, u), level - bounds.offset[id])
    }

    /// max_i ⟨c, y_i⟩ + h_i and its site (the smallest index among equal values), branch and
    /// bound from the site `guess`'s value.
    fn best(
        &self,
        c: [f64; 3],
        guess: u32,
        heights: &[f64],
        bounds: &NodeBounds,
        stack: &mut Vec<(u32, f64)>,
    ) -> (f64, u32) {
        let g = guess as usize;
        let mut best = (dot(c, self.points[g]) + heights[g], guess);
        stack.clear();
        stack.push((0, f64::INFINITY));
        // (children are tested against the running maximum when pushed and again when popped,
        // with the division-free cap test; the key only orders them)
        while let Some((id, _)) = stack.pop() {
            if id != 0 && !self.tilted_reaches(id as usize, c, best.0, bounds) {
                continue;
            }
            let n = &self.nodes[id as usize];
            if n.left == NONE {
                for &i in &self.order[n.start as usize..n.end as usize] {
                    let v = dot(c, self.points[i as usize]) + heights[i as usize];
                    if v > best.0 || (v == best.0 && i < best.1) {
                        best = (v, i);
                    }
                }
            } else {
                // the more promising child last, so it is popped first
                let (l, r) = (n.left, n.right);
                let key = |k: u32| {
                    let (g, m) = (bounds.slope[k as usize], &self.nodes[k as usize]);
                    dot([c[0] + g[0], c[1] + g[1], c[2] + g[2]], m.axis) + bounds.offset[k as usize]
                };
                let (kl, kr) = (key(l), key(r));
                if kl > kr {
                    stack.extend([(r, kr), (l, kl)]);
                } else {
                    stack.extend([(l, kl), (r, kr)]);
                }
            }
        }
        best
    }

    /// Heights bounds for [`Self::above`] (per node, a slope and an offset bounding the
    /// heights: [`Self::height_bounds`]).
    pub(crate) fn bounds(&self, heights: &[f64]) -> NodeBounds {
        self.height_bounds(heights)
    }

    /// The `k` sites nearest to site `i` (other than i), as (|y_i − y_j|², j) ascending; the
    /// squared distances are taken from the differences of the points (exact for close
    /// points, where 1 − ⟨y_i, y_j⟩ would be lost to rounding).
    pub(crate) fn nearest(&self, i: usize, k: usize, stack: &mut Vec<u32>, out: &mut Vec<(f64, u32)>) {
        out.clear();
        if k == 0 || self.nodes.is_empty() {
            return;
        }
        let c = self.points[i];
        stack.clear();
        stack.push(0);
        while let Some(id) = stack.pop() {
            let id = id as usize;
            // ⟨c, y⟩ ≥ 1 − d²/2 for a site within chord d of c
            if out.len() == k {
                let d2 = out[k - 1].0;
                if self.cap_max(id, c) < 1.0 - 0.5 * d2 {
                    continue;
                }
            }
            let n = &self.nodes[id];
            if n.left == NONE {
                for &j in &self.order[n.start as usize..n.end as usize] {
                    if j as usize == i {
                        continue;
                    }
                    let d = sub(c, self.points[j as usize]);
                    let d2 = dot(d, d);
                    if out.len() == k && d2 >= out[k - 1].0 {
                        continue;
                    }
                    let at = out.partition_point(|e| (e.0, e.1) < (d2, j));
                    out.insert(at, (d2, j));
                    out.truncate(k);
                }
            } else {
                let (l, r) = (n.left, n.right);
                if self.cap_max(l as usize, c) > self.cap_max(r as usize, c) {
                    stack.extend([r, l]);
                } else {
                    stack.extend([l, r]);
                }
            }
        }
    }

    /// The site nearest to the direction of `c` (largest ⟨c, y⟩).
    pub(crate) fn nearest_to(&self, c: [f64; 3], stack: &mut Vec<u32>) -> usize {
        if self.points.is_empty() {
            return 0;
        }
        let mut best = (f64::NEG_INFINITY, 0u32);
        stack.clear();
        stack.push(0);
        while let Some(id) = stack.pop() {
            let id = id as usize;
            if self.cap_max(id, c) <= best.0 {
                continue;
            }
            let n = &self.nodes[id];
            if n.left == NONE {
                for &i in &self.order[n.start as usize..n.end as usize] {
                    let v = dot(c, self.points[i as usize]);
                    if v > best.0 {
                        best = (v, i);
                    }
                }
            } else {
                let (l, r) = (n.left, n.right);
                if self.cap_max(l as usize, c) > self.cap_max(r as usize, c) {
                    stack.extend([r, l]);
                } else {
                    stack.extend([l, r]);
                }
            }
        }
        best.1 as usize
    }

    /// An upper bound of ⟨c, y⟩ over the node's cap (heights left out), with a 1e-12 margin.
    fn cap_max(&self, id: usize, c: [f64; 3]) -> f64 {
        let n = &self.nodes[id];
        let r = norm(c);
        if r == 0.0 {
            return 1e-12;
        }
        let cos_t = dot(c, n.axis) / r;
        let best = if cos_t >= n.cos_radius {
            1.0
        } else {
            let sin_t = (1.0 - cos_t * cos_t).max(0.0).sqrt();
            cos_t * n.cos_radius + sin_t * n.sin_radius
        };
        r * best + 1e-12
    }

    /// Every site j with ⟨c, y_j⟩ + h_j ≥ `level`, into `out` (any order); `bounds` from
    /// [`Self::bounds`] of the same heights.
    pub(crate) fn above(
        &self,
        c: [f64; 3],
        level: f64,
        heights: &[f64],
        bounds: &NodeBounds,
        stack: &mut Vec<u32>,
        out: &mut Vec<u32>,
    ) {
        out.clear();
        if self.nodes.is_empty() {
            return;
        }
        stack.clear();
        stack.push(0);
        while let Some(id) = stack.pop() {
            let id = id as usize;
            if !self.tilted_reaches(id, c, level, bounds) {
                continue;
            }
            let n = &self.nodes[id];
            if n.left == NONE {
                for &j in &self.order[n.start as usize..n.end as usize] {
                    if dot(c, self.points[j as usize]) + heights[j as usize] >= level {
                        out.push(j);
                    }
                }
            } else {
                stack.extend([n.left, n.right]);
            }
        }
    }
}

/// Integrates the Laguerre cells of fixed sites over a fixed spherical source, for any heights.
pub struct SphereIntegrator<'a> {
    measure: &'a SphereMeasure,
    points: Vec<[f64; 3]>,
    /// Each site's correction onto the unit sphere: `points[i] + radial[i]` is a unit vector to
    /// about 1e-32 ([`radial_corrections`]); the bisectors use both.
    radial: Vec<[f64; 3]>,
    tree: SiteTree,
    /// Triangles and vertices in Morton order of their positions (cache and search locality).
    triangle_order: Vec<u32>,
    vertex_order: Vec<u32>,
    /// Use every site as a candidate in every triangle (the brute-force oracle, O(N·M)).
    brute_force: bool,
}

/// Triangles per parallel chunk (fixed, so the reduction order does not depend on threads).
const CHUNK: usize = 512;

#[derive(Default)]
struct ChunkOut {
    masses: Vec<(u32, f64, [f64; 3], f64)>,
    edges: Vec<(u32, u32, f64, f64)>,
    candidates: usize,
    pieces: Vec<CellPiece>,
}

/// Per source vertex, the sites that may own a point of its triangles (compressed rows).
#[derive(Default)]
struct VertexLists {
    start: Vec<u32>,
    sites: Vec<u32>,
}

impl VertexLists {
    fn of(&self, v: u32) -> &[u32] {
        let v = v as usize;
        &self.sites[self.start[v] as usize..self.start[v + 1] as usize]
    }
}

/// The candidate test's margin for a minorant of height h (keeps it conservative).
fn candidate_margin(h: f64) -> f64 {
    1e-10 * (1.0 + h.abs())
}

struct Scratch {
    cand: Vec<(f64, u32)>,
    poly: Vec<([f64; 3], i64)>,
    next: Vec<([f64; 3], i64)>,
}

impl<'a> SphereIntegrator<'a> {
    /// An integrator for the sites `points` (unit vectors) over `measure`.
    pub fn new(measure: &'a SphereMeasure, points: &[[f64; 3]]) -> Self {
        let centroids: Vec<[f64; 3]> = measure
            .triangles
            .iter()
            .map(|tri| {
                let [a, b, c] = tri.map(|i| measure.vertices[i as usize]);
                [a[0] + b[0] + c[0], a[1] + b[1] + c[1], a[2] + b[2] + c[2]].map(|x| x / 3.0)
            })
            .collect();
        SphereIntegrator {
            measure,
            points: points.to_vec(),
            radial: radial_corrections(points),
            tree: SiteTree::new(points),
            triangle_order: morton_order(&centroids),
            vertex_order: morton_order(&measure.vertices),
            brute_force: false,
        }
    }

    /// The brute-force variant: every site is a candidate in every triangle (tests, N ≲ 1000).
    pub fn brute_force(measure: &'a SphereMeasure, points: &[[f64; 3]]) -> Self {
        SphereIntegrator {
            brute_force: true,
            ..SphereIntegrator::new(measure, points)
        }
    }

    /// The sites.
    pub fn points(&self) -> &[[f64; 3]] {
        &self.points
    }

    /// The sites' radial corrections onto S² ([`radial_corrections`]).
    pub(crate) fn radial(&self) -> &[[f64; 3]] {
        &self.radial
    }

    /// The sites' cap tree.
    pub(crate) fn tree(&self) -> &SiteTree {
        &self.tree
    }

    /// Cell integrals at `heights` (#N).
    pub fn integrate(&self, heights: &[f64]) -> SphereCells {
        self.integrate_dd(heights, None)
    }

    /// Cell integrals at the double-double heights `hi + lo` (#N each; `lo` `None`: zero). The
    /// bisector offsets h_i − h_j are taken from both parts; everything else (candidate search,
    /// ordering) uses `hi` with its margins.
    pub fn integrate_dd(&self, hi: &[f64], lo: Option<&[f64]>) -> SphereCells {
        let n = self.points.len();
        let outs = self.run(hi, lo, false);
        let mut cells = SphereCells {
            masses: vec![0.0; n],
            first_moments: vec![[0.0; 3]; n],
            second_moments: vec![0.0; n],
            triangles: self.measure.triangles.len(),
            ..Default::default()
        };
        let mut edges = Vec::new();
        let mut candidates = 0usize;
        for out in outs {
            for (i, m, f, q) in out.masses {
                let i = i as usize;
                cells.masses[i] += m;
                cells.second_moments[i] += q;
                for k in 0..3 {
                    cells.first_moments[i][k] += f[k];
                }
            }
            edges.extend(out.edges);
            candidates += out.candidates;
        }
        cells.mean_candidates = candidates as f64 / cells.triangles.max(1) as f64;
        // stable: equal pairs keep the triangle order, so the sums are deterministic
        edges.sort_by_key(|e| (e.0, e.1));
        let mut k = 0;
        while k < edges.len() {
            let (i, j) = (edges[k].0, edges[k].1);
            let (mut em, mut hc) = (0.0, 0.0);
            while k < edges.len() && edges[k].0 == i && edges[k].1 == j {
                em += edges[k].2;
                hc += edges[k].3;
                k += 1;
            }
            cells.edge_masses.push((i, j, em));
            cells.hessian.push((i, j, hc));
        }
        cells
    }

    /// The clipped pieces at `heights` (for output and plots), in triangle order.
    pub fn pieces(&self, heights: &[f64]) -> Vec<CellPiece> {
        self.run(heights, None, true)
            .into_iter()
            .flat_map(|o| o.pieces)
            .collect()
    }

    fn run(&self, heights: &[f64], lo: Option<&[f64]>, keep_pieces: bool) -> Vec<ChunkOut> {
        let bounds = self.tree.height_bounds(heights);
        // the best site at every vertex (in spatial order, each search starting from the
        // previous vertex's site)
        let nv = self.measure.vertices.len();
        let mut vertex_best = vec![0u32; nv];
        let mut lists = VertexLists::default();
        if !self.brute_force && !self.points.is_empty() {
            let found: Vec<Vec<(u32, u32, f64)>> = self
                .vertex_order
                .par_chunks(CHUNK)
                .map(|chunk| {
                    let mut stack = Vec::new();
                    let mut guess = 0u32;
                    chunk
                        .iter()
                        .map(|&v| {
                            let (value, k) =
                                self.tree
                                    .best(self.measure.vertices[v as usize], guess, heights, &bounds, &mut stack);
                            guess = k;
                            (v, k, value)
                        })
                        .collect()
                })
                .collect();
            let mut vertex_value = vec![0.0; nv];
            for (v, k, value) in found.into_iter().flatten() {
                vertex_best[v as usize] = k;
                vertex_value[v as usize] = value;
            }
            lists = self.vertex_lists(heights, &bounds, &vertex_best, &vertex_value);
        }
        self.triangle_order
            .par_chunks(CHUNK)
            .map(|chunk| {
                let mut out = ChunkOut::default();
                let mut scratch = Scratch {
                    cand: Vec::new(),
                    poly: Vec::new(),
                    next: Vec::new(),
                };
                for &t in chunk {
                    self.triangle(
                        t as usize,
                        heights,
                        lo,
                        &vertex_best,
                        &lists,
                        &mut scratch,
                        &mut out,
                        keep_pieces,
                    );
                }
                out
            })
            .collect()
    }

    /// Per source vertex v, every site j with ℓ_j(v) ≥ u_h(v) − s_v, where s_v is the largest
    /// u_h(v) − ℓ_{k_a}(v) + margin over the triangles T at v (k_a the best site at T's first
    /// corner a): a site passing T's candidate test ℓ_j(w) ≥ ℓ_{k_a}(w) − margin at some corner
    /// w is in w's list, so the union of T's three lists filtered by that test is exactly the
    /// candidate set (one tree query per vertex with one corner, not one per triangle with three;
    /// 1e-12 more than s_v against rounding).
    fn vertex_lists(
        &self,
        heights: &[f64],
        bounds: &NodeBounds,
        vertex_best: &[u32],
        vertex_value: &[f64],
    ) -> VertexLists {
        let nv = self.measure.vertices.len();
        let mut slack = vec![f64::NEG_INFINITY; nv];
        for tri in &self.measure.triangles {
            let ka = vertex_best[tri[0] as usize] as usize;
            let margin = candidate_margin(heights[ka]);
            for &v in tri {
                let v = v as usize;
                let lower = dot(self.measure.vertices[v], self.points[ka]) + heights[ka];
                slack[v] = slack[v].max(vertex_value[v] - lower + margin);
            }
        }
        let found: Vec<Vec<(u32, Vec<u32>)>> = self
            .vertex_order
            .par_chunks(CHUNK)
            .map(|chunk| {
                let (mut stack, mut out) = (Vec::new(), Vec::new());
                chunk
                    .iter()
                    .map(|&v| {
                        let level = vertex_value[v as usize] - slack[v as usize] - 1e-12;
                        self.tree.above(
                            self.measure.vertices[v as usize],
                            level,
                            heights,
                            bounds,
                            &mut stack,
                            &mut out,
                        );
                        (v, out.clone())
                    })
                    .collect()
            })
            .collect();
        let mut per_vertex = vec![Vec::new(); nv];
        for (v, list) in found.into_iter().flatten() {
            per_vertex[v as usize] = list;
        }
        let mut lists = VertexLists {
            start: Vec::with_capacity(nv + 1),
            sites: Vec::new(),
        };
        lists.start.push(0);
        for list in per_vertex {
            lists.sites.extend(list);
            lists.start.push(lists.sites.len() as u32);
        }
        lists
    }

    /// y_i − y_j of the unit vectors `points + radial`: the difference of the stored points is
    /// exact for close points (Sterbenz), and the corrections restore what rounding the points
    /// onto the sphere left (|y| − 1 ≈ 1e-16, beside a bisector's margin |y_i − y_j|²/2).
    fn difference(&self, i: usize, j: usize) -> [f64; 3] {
        let (d, r) = (sub(self.points[i], self.points[j]), sub(self.radial[i], self.radial[j]));
        [d[0] + r[0], d[1] + r[1], d[2] + r[2]]
    }

    #[allow(clippy::too_many_arguments)]
    fn triangle(
        &self,
        t: usize,
        heights: &[f64],
        lo: Option<&[f64]>,
        vertex_best: &[u32],
        lists: &VertexLists,
        s: &mut Scratch,
        out: &mut ChunkOut,
        keep_pieces: bool,
    ) {
        let tri = self.measure.triangles[t];
        let rho = self.measure.densities[t];
        let [a, b, c] = tri.map(|i| self.measure.vertices[i as usize]);
        let centroid = [
            (a[0] + b[0] + c[0]) / 3.0,
            (a[1] + b[1] + c[1]) / 3.0,
            (a[2] + b[2] + c[2]) / 3.0,
        ];
        if self.brute_force {
            s.cand.clear();
            for (i, y) in self.points.iter().enumerate() {
                s.cand.push((dot(centroid, *y) + heights[i], i as u32));
            }
        } else {
            // the best site at corner a gives an affine minorant of u_h; the best sites at the
            // other corners give two more necessary conditions, checked on the list
            let corners = [a, b, c];
            let [ka, kb, kc] = tri.map(|v| vertex_best[v as usize]);
            let margin = candidate_margin(heights[ka as usize]);
            let lower_of = |k: u32| corners.map(|v| dot(v, self.points[k as usize]) + heights[k as usize]);
            // the sites beating ℓ_ka somewhere on T (as far as the margin goes): each is in its
            // corner's list ([`Self::vertex_lists`])
            let lower = lower_of(ka);
            s.cand.clear();
            for v in tri {
                for &j in lists.of(v) {
                    if s.cand.iter().any(|e| e.1 == j) {
                        continue;
                    }
                    let (y, h) = (self.points[j as usize], heights[j as usize]);
                    let gain = (0..3)
                        .map(|w| dot(corners[w], y) + h - lower[w])
                        .fold(f64::NEG_INFINITY, f64::max);
                    if gain >= -margin {
                        s.cand.push((dot(centroid, y) + h, j));
                    }
                }
            }
            for kv in [kb, kc] {
                if kv != ka {
                    let lower = lower_of(kv);
                    s.cand.retain(|&(_, j)| {
                        let (y, h) = (self.points[j as usize], heights[j as usize]);
                        (0..3).any(|w| dot(corners[w], y) + h - lower[w] >= -margin)
                    });
                }
            }
        }
        // most competitive first; ties by site index (deterministic)
        s.cand.sort_unstable_by(|p, q| q.0.total_cmp(&p.0).then(p.1.cmp(&q.1)));
        out.candidates += s.cand.len();
        let normal = cross(sub(b, a), sub(c, a));
        let nn = norm(normal);
        let unit_normal = [normal[0] / nn, normal[1] / nn, normal[2] / nn];
        for ci in 0..s.cand.len() {
            let i = s.cand[ci].1 as usize;
            let yi = self.points[i];
            s.poly.clear();
            s.poly.extend([(a, -1), (b, -1), (c, -1)]);
            let mut empty = false;
            for cj in 0..s.cand.len() {
                if cj == ci {
                    continue;
                }
                let j = s.cand[cj].1 as usize;
                let d = self.difference(i, j);
                // (the low parts: children of a crowded group differ by less than an ulp)
                let offset = match lo {
                    Some(lo) => (heights[i] - heights[j]) + (lo[i] - lo[j]),
                    None => heights[i] - heights[j],
                };
                // keep ⟨x, d⟩ + offset ≥ 0
                if !clip(&s.poly, &mut s.next, d, offset, j as i64) {
                    empty = true;
                    break;
                }
                std::mem::swap(&mut s.poly, &mut s.next);
            }
            if empty || s.poly.len() < 3 {
                continue;
            }
            // fan from the first corner: area (along the normal), first moment
            let p0 = s.poly[0].0;
            let (mut area, mut moment, mut second) = (0.0, [0.0; 3], 0.0);
            let e0 = sub(p0, yi);
            for k in 1..s.poly.len() - 1 {
                let (p1, p2) = (s.poly[k].0, s.poly[k + 1].0);
                let ar = 0.5 * dot(cross(sub(p1, p0), sub(p2, p0)), unit_normal);
                area += ar;
                for q in 0..3 {
                    moment[q] += ar * (p0[q] + p1[q] + p2[q]) / 3.0;
                }
                let (e1, e2) = (sub(p1, yi), sub(p2, yi));
                second +=
                    ar * (dot(e0, e0) + dot(e1, e1) + dot(e2, e2) + dot(e0, e1) + dot(e1, e2) + dot(e2, e0)) / 6.0;
            }
            // (clipping keeps the triangle's orientation, so the fan's areas are positive)
            if area > 0.0 {
                out.masses.push((
                    i as u32,
                    rho * area,
                    [rho * moment[0], rho * moment[1], rho * moment[2]],
                    rho * second,
                ));
            }
            for k in 0..s.poly.len() {
                let label = s.poly[k].1;
                if label > i as i64 {
                    let j = label as usize;
                    let len = norm(sub(s.poly[(k + 1) % s.poly.len()].0, s.poly[k].0));
                    if len > 0.0 {
                        let d = self.difference(i, j);
                        let dn = dot(d, unit_normal);
                        let tangential = (dot(d, d) - dn * dn).max(0.0).sqrt();
                        if tangential > 0.0 {
                            out.edges.push((i as u32, j as u32, rho * len, rho * len / tangential));
                        }
                    }
                }
            }
            if keep_pieces {
                out.pieces.push(CellPiece {
                    site: i as u32,
                    triangle: t as u32,
                    polygon: s.poly.iter().map(|p| p.0).collect(),
                });
            }
        }
    }
}

/// For each point p (|p| ≈ 1), the vector r with |p + r| = 1 to about 1e-32: r = −p·e/2 with
/// e = |p|² − 1 in double-double arithmetic.
///
/// Sites closer than about 1e-8 (conformal images of protrusions) have bisector margins
/// |y_i − y_j|²/2 below the 1e-16 by which f64 misses the sphere; without the correction such a
/// site can fall inside the convex hull of its neighbours and lose its cell entirely.
pub(crate) fn radial_corrections(points: &[[f64; 3]]) -> Vec<[f64; 3]> {
    let two_prod = |a: f64, b: f64| {
        let p = a * b;
        (p, a.mul_add(b, -p))
    };
    let two_sum = |a: f64, b: f64| {
        let s = a + b;
        let v = s - a;
        (s, (a - (s - v)) + (b - v))
    };
    points
        .iter()
        .map(|p| {
            let (x, ex) = two_prod(p[0], p[0]);
            let (y, ey) = two_prod(p[1], p[1]);
            let (z, ez) = two_prod(p[2], p[2]);
            let (s1, e1) = two_sum(x, y);
            let (s2, e2) = two_sum(s1, z);
            // (s2 − 1 is exact for s2 near 1)
            let e = (s2 - 1.0) + (ex + ey + ez + e1 + e2);
            p.map(|c| -0.5 * e * c)
        })
        .collect()
}

/// Sutherland–Hodgman: the part of `poly` (corners with the label of the edge that starts
/// there) where ⟨x, d⟩ + offset ≥ 0, into `next`; the new edge along the plane gets `label`.
/// Returns false when nothing is left.
fn clip(poly: &[([f64; 3], i64)], next: &mut Vec<([f64; 3], i64)>, d: [f64; 3], offset: f64, label: i64) -> bool {
    next.clear();
    let values: [f64; 8] = {
        let mut v = [0.0; 8];
        for (k, p) in poly.iter().enumerate().take(8) {
            v[k] = dot(p.0, d) + offset;
        }
        v
    };
    let value = |k: usize| if k < 8 { values[k] } else { dot(poly[k].0, d) + offset };
    let len = poly.len();
    let mut inside = 0;
    for k in 0..len {
        if value(k) >= 0.0 {
            inside += 1;
        }
    }
    if inside == len {
        next.extend_from_slice(poly);
        return true;
    }
    if inside == 0 {
        return false;
    }
    for k in 0..len {
        let (p, lp) = poly[k];
        let q = poly[(k + 1) % len].0;
        let (sp, sq) = (value(k), value((k + 1) % len));
        if sp >= 0.0 {
            next.push((p, lp));
            if sq < 0.0 {
                next.push((lerp(p, q, sp / (sp - sq)), label));
            }
        } else if sq >= 0.0 {
            next.push((lerp(p, q, sp / (sp - sq)), lp));
        }
    }
    next.len() >= 3
}

/// Indices of `points` (in [−1, 1]³) sorted by their 3D Morton codes (10 bits per axis).
fn morton_order(points: &[[f64; 3]]) -> Vec<u32> {
    let spread = |x: f64| -> u64 {
        let mut v = (((x.clamp(-1.0, 1.0) + 1.0) * 511.5) as u64).min(1023);
        let mut out = 0u64;
        for bit in 0..10 {
            out |= (v & 1) << (3 * bit);
            v >>= 1;
        }
        out
    };
    let mut keyed: Vec<(u64, u32)> = points
        .iter()
        .enumerate()
        .map(|(i, p)| (spread(p[0]) | spread(p[1]) << 1 | spread(p[2]) << 2, i as u32))
        .collect();
    keyed.sort_unstable();
    keyed.into_iter().map(|(_, i)| i).collect()
}

fn lerp(p: [f64; 3], q: [f64; 3], t: f64) -> [f64; 3] {
    [
        p[0] + t * (q[0] - p[0]),
        p[1] + t * (q[1] - p[1]),
        p[2] + t * (q[2] - p[2]),
    ]
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::sphere::measure::{icosphere, random_sphere_points};
    use crate::synthetic::uniform01;

    /// Heights with a large smooth part (a slope and a curvature of order 0.3, as on the
    /// conformal image of an ellipsoid) and, optionally, a jitter at the scale of the sites'
    /// spacing: the case the tree's tilted bounds are for.
    fn varying_heights(points: &[[f64; 3]], jitter: f64, seed: u64) -> Vec<f64> {
        let mut s = seed;
        points
            .iter()
            .map(|p| 0.3 * p[2] * p[2] + 0.2 * p[0] - 0.1 * p[1] * p[2] + jitter * (uniform01(&mut s) - 0.5))
            .collect()
    }

    /// Query points: an icosphere's vertices, scaled off S² by up to 1e-6 (as the flat
    /// triangles' corners may be).
    fn queries() -> Vec<[f64; 3]> {
        let mut s = 5u64;
        icosphere(4)
            .0
            .into_iter()
            .map(|p| p.map(|c| c * (1.0 + 1e-6 * (2.0 * uniform01(&mut s) - 1.0))))
            .collect()
    }

    /// The branch and bound's best site is the exact maximum of ⟨c, y_i⟩ + h_i over all sites,
    /// the smallest index among equal values, whatever the guess.
    #[test]
    fn best_site_is_the_exact_maximum_under_strongly_varying_heights() {
        let points = random_sphere_points(3000, 41);
        let tree = SiteTree::new(&points);
        for (jitter, seed) in [(0.0, 1), (1e-3, 2), (0.05, 3)] {
            let heights = varying_heights(&points, jitter, seed);
            let bounds = tree.height_bounds(&heights);
            let mut stack = Vec::new();
            for (q, c) in queries().into_iter().enumerate() {
                let (mut value, mut site) = (f64::NEG_INFINITY, 0u32);
                for (i, y) in points.iter().enumerate() {
                    let v = dot(c, *y) + heights[i];
                    if v > value {
                        (value, site) = (v, i as u32);
                    }
                }
                for guess in [0u32, (q % 3000) as u32, site] {
                    let found = tree.best(c, guess, &heights, &bounds, &mut stack);
                    assert_eq!(found, (value, site), "query {q}, jitter {jitter}, guess {guess}");
                }
            }
        }
    }

    /// The tree's list of the sites above a level at a point is exactly the brute-force list
    /// (the tilted bounds prune, never decide), at levels just below the maximum.
    #[test]
    fn above_lists_exactly_the_sites_above_the_level() {
        let points = random_sphere_points(3000, 43);
        let tree = SiteTree::new(&points);
        for (jitter, seed) in [(0.0, 4), (1e-3, 5), (0.05, 6)] {
            let heights = varying_heights(&points, jitter, seed);
            let bounds = tree.height_bounds(&heights);
            let (mut stack, mut out) = (Vec::new(), Vec::new());
            let mut total = 0;
            let queries = queries();
            for (q, c) in queries.iter().enumerate() {
                let values: Vec<f64> = points.iter().zip(&heights).map(|(y, h)| dot(*c, *y) + h).collect();
                let top = values.iter().copied().fold(f64::NEG_INFINITY, f64::max);
                let level = top - [1e-4, 1e-3, 1e-2][q % 3];
                tree.above(*c, level, &heights, &bounds, &mut stack, &mut out);
                out.sort_unstable();
                let expected: Vec<u32> = (0..points.len() as u32)
                    .filter(|&j| values[j as usize] >= level)
                    .collect();
                assert_eq!(out, expected, "query {q}, jitter {jitter}");
                total += out.len();
            }
            assert!(
                total > 2 * queries.len(),
                "{total} sites listed at {} points",
                queries.len()
            );
        }
    }
}
