//! Intrinsic triangulations and the intrinsic Delaunay cotangent Laplacian.
//!
//! An intrinsic triangulation keeps the vertex set of the input surface and only edge *lengths*;
//! an edge flip replaces the diagonal of the two triangles around an edge by the other diagonal,
//! whose length follows from laying the two triangles out in the plane. Flipping every edge
//! whose opposite angles sum to more than π (Lawson's algorithm) terminates in the intrinsic
//! Delaunay triangulation [Bobenko & Springborn 2007; Fisher, Springborn, Schröder & Bobenko
//! 2007; Sharp, Soliman & Crane 2019, "Navigating intrinsic triangulations"]. Its cotangent
//! weights
//! $$ w_{ij} = \tfrac12(\cot\alpha_{ij} + \cot\beta_{ij}) \ge 0 $$
//! are non-negative on every interior edge, so the Laplacian satisfies a discrete maximum
//! principle, while it still discretizes the same smooth Dirichlet energy of the same
//! (piecewise flat) surface. Flipped edges live only here: functions are still values at the
//! original vertices.
//!
//! Storage: half-edge `h = 3f + k` is the k-th side of face f and goes from `tail[h]` to
//! `tail[next(h)]`; `next(h) = 3f + (k+1) mod 3`. `twin[h] == NONE` marks a boundary side.
//! Faces are counter-clockwise in the orientation of the input faces.

use std::collections::VecDeque;

use shapespace_geometry::quantities::face_edge_lengths;
use shapespace_geometry::topology::{find, union};
use shapespace_geometry::TriMesh;

use crate::error::ConformalError;

/// Tolerance of the Delaunay condition cot α + cot β ≥ −tol (keeps co-circular
/// configurations such as regular grids from flipping back and forth).
const DELAUNAY_TOLERANCE: f64 = 1e-12;

/// Rounds of flips and splits [`IntrinsicTriangulation::connect_interior`] makes at most.
pub const MAX_CONNECT_ROUNDS: usize = 64;

/// Marker for a boundary half-edge without twin.
pub const NONE: u32 = u32::MAX;

/// An intrinsic triangulation: half-edge connectivity plus edge lengths.
#[derive(Clone, Debug)]
pub struct IntrinsicTriangulation {
    /// Number of vertices #V (same vertex set as the input mesh).
    pub num_vertices: usize,
    /// Tail vertex of each half-edge, 3·#F.
    pub tail: Vec<u32>,
    /// Opposite half-edge, or [`NONE`] on the boundary, 3·#F.
    pub twin: Vec<u32>,
    /// Length of each half-edge (equal on twins), 3·#F.
    pub length: Vec<f64>,
    /// Per vertex: true when it lies on a boundary edge, #V.
    pub is_boundary: Vec<bool>,
    /// Number of edge flips performed so far.
    pub num_flips: usize,
}

/// The next half-edge of the same face.
#[inline]
pub fn next(h: u32) -> u32 {
    if h % 3 == 2 {
        h - 2
    } else {
        h + 1
    }
}

/// The previous half-edge of the same face.
#[inline]
pub fn prev(h: u32) -> u32 {
    if h.is_multiple_of(3) {
        h + 2
    } else {
        h - 1
    }
}

pub use shapespace_geometry::quantities::triangle_area_from_lengths;

/// Cotangent of the angle opposite side `e` in a triangle with sides `e`, `u`, `v` and area
/// `area`: cot θ = (u² + v² − e²) / (4A).
#[inline]
pub fn cot_from_lengths(e: f64, u: f64, v: f64, area: f64) -> f64 {
    (u * u + v * v - e * e) / (4.0 * area)
}

impl IntrinsicTriangulation {
    /// Builds the intrinsic triangulation of `mesh` (edge lengths measured in 3D).
    ///
    /// Errors: an edge with more than two faces, two faces with the same direction on an edge
    /// (inconsistent orientation), a zero-length edge or a zero-area face; a degenerate face of
    /// the mesh is named with the reason `info` and `prepare` give
    /// ([`shapespace_geometry::topology::degenerate_face`]).
    pub fn from_mesh(mesh: &TriMesh) -> Result<Self, ConformalError> {
        if let Some((face, reason)) =
            (0..mesh.num_faces()).find_map(|f| shapespace_geometry::topology::degenerate_face(mesh, f).map(|r| (f, r)))
        {
            return Err(ConformalError::DegenerateFace {
                face,
                reason: reason.into(),
            });
        }
        let lengths: Vec<f64> = mesh
            .faces
            .iter()
            .flat_map(|f| face_edge_lengths(f.map(|v| mesh.positions[v as usize])))
            .collect();
        Self::from_lengths(mesh.num_vertices(), &mesh.faces, lengths)
    }

    /// Builds an intrinsic triangulation from faces and per-half-edge lengths
    /// (`lengths[3f + k]` is the length of side (`faces[f][k]`, `faces[f][k+1]`)).
    pub fn from_lengths(num_vertices: usize, faces: &[[u32; 3]], lengths: Vec<f64>) -> Result<Self, ConformalError> {
        let nh = 3 * faces.len();
        let mut tail = Vec::with_capacity(nh);
        for f in faces {
            tail.extend_from_slice(f);
        }
        for (f, face) in faces.iter().enumerate() {
            let l = [lengths[3 * f], lengths[3 * f + 1], lengths[3 * f + 2]];
            if face[0] == face[1] || face[1] == face[2] || face[0] == face[2] {
                return Err(ConformalError::DegenerateFace {
                    face: f,
                    reason: "repeated vertex".into(),
                });
            }
            if l.iter().any(|x| x.is_infinite()) {
                return Err(ConformalError::DegenerateFace {
                    face: f,
                    reason: "edge length overflows f64 (coordinates too large; rescale the mesh)".into(),
                });
            }
            if l.iter().any(|x| !(*x > 0.0) || !x.is_finite()) {
                return Err(ConformalError::DegenerateFace {
                    face: f,
                    reason: "zero-length edge (coincident vertices)".into(),
                });
            }
            if !(triangle_area_from_lengths(l[0], l[1], l[2]) > 0.0) {
                return Err(ConformalError::DegenerateFace {
                    face: f,
                    reason: "zero area (collinear corners)".into(),
                });
            }
        }
        // pair half-edges by their undirected key
        let mut keyed: Vec<(u64, u32)> = (0..nh as u32)
            .map(|h| {
                let a = tail[h as usize];
                let b = tail[next(h) as usize];
                let (lo, hi) = if a < b { (a, b) } else { (b, a) };
                (((lo as u64) << 32) | hi as u64, h)
            })
            .collect();
        keyed.sort_unstable();
        let mut twin = vec![NONE; nh];
        let mut i = 0;
        while i < keyed.len() {
            let mut j = i + 1;
            while j < keyed.len() && keyed[j].0 == keyed[i].0 {
                j += 1;
            }
            let (lo, hi) = ((keyed[i].0 >> 32) as u32, keyed[i].0 as u32);
            match j - i {
                1 => {}
                2 => {
                    let (h, g) = (keyed[i].1, keyed[i + 1].1);
                    if tail[h as usize] == tail[g as usize] {
                        return Err(ConformalError::InconsistentOrientation { v0: lo, v1: hi });
                    }
                    twin[h as usize] = g;
                    twin[g as usize] = h;
                }
                _ => return Err(ConformalError::NonManifoldEdge { v0: lo, v1: hi }),
            }
            i = j;
        }
        let mut is_boundary = vec![false; num_vertices];
        for h in 0..nh {
            if twin[h] == NONE {
                is_boundary[tail[h] as usize] = true;
                is_boundary[tail[next(h as u32) as usize] as usize] = true;
            }
        }
        // make twin lengths bit-identical
        let mut length = lengths;
        for h in 0..nh {
            let t = twin[h];
            if t != NONE && (t as usize) > h {
                let l = 0.5 * (length[h] + length[t as usize]);
                length[h] = l;
                length[t as usize] = l;
            }
        }
        Ok(IntrinsicTriangulation {
            num_vertices,
            tail,
            twin,
            length,
            is_boundary,
            num_flips: 0,
        })
    }

    /// Number of faces.
    pub fn num_faces(&self) -> usize {
        self.tail.len() / 3
    }

    /// Head vertex of half-edge h.
    #[inline]
    pub fn head(&self, h: u32) -> u32 {
        self.tail[next(h) as usize]
    }

    /// Area of the face containing half-edge h.
    #[inline]
    pub fn face_area(&self, f: usize) -> f64 {
        triangle_area_from_lengths(self.length[3 * f], self.length[3 * f + 1], self.length[3 * f + 2])
    }

    /// Cotangent of the angle opposite half-edge h (in h's face).
    #[inline]
    pub fn cot_opposite(&self, h: u32) -> f64 {
        let e = self.length[h as usize];
        let u = self.length[next(h) as usize];
        let v = self.length[prev(h) as usize];
        let area = triangle_area_from_lengths(e, u, v);
        cot_from_lengths(e, u, v, area)
    }

    /// Cotangent weight of the edge of h: ½(cot α + cot β), one term on the boundary.
    pub fn edge_cotan_weight(&self, h: u32) -> f64 {
        let t = self.twin[h as usize];
        let mut w = 0.5 * self.cot_opposite(h);
        if t != NONE {
            w += 0.5 * self.cot_opposite(t);
        }
        w
    }

    /// True when the interior edge of h violates the intrinsic Delaunay condition
    /// cot α + cot β ≥ −tol.
    fn is_non_delaunay(&self, h: u32, tol: f64) -> bool {
        let t = self.twin[h as usize];
        if t == NONE || t / 3 == h / 3 {
            return false;
        }
        self.cot_opposite(h) + self.cot_opposite(t) < -tol
    }

    /// True when the two faces of h share another side too (a vertex of degree 2 or a folded
    /// pair): such an edge is not flipped.
    fn touches_itself(&self, h: u32) -> bool {
        let t = self.twin[h as usize];
        let own = [h, next(h), prev(h), t, next(t), prev(t)];
        [next(h), prev(h), next(t), prev(t)]
            .iter()
            .any(|&g| own.contains(&self.twin[g as usize]))
    }

    /// Makes x and y twins (y may be [`NONE`]: x is then a boundary side).
    fn link(&mut self, x: u32, y: u32) {
        self.twin[x as usize] = y;
        if y != NONE {
            self.twin[y as usize] = x;
        }
    }

    /// Flips the interior edge of half-edge h (faces (a,b,c) and (b,a,d) become (c,d,b) and
    /// (d,c,a)); the new length |cd| comes from laying both triangles out in the plane.
    fn flip(&mut self, h: u32) {
        let t = self.twin[h as usize];
        debug_assert!(t != NONE);
        let (hn, hp, tn, tp) = (next(h), prev(h), next(t), prev(t));
        let a = self.tail[h as usize];
        let b = self.tail[t as usize];
        let c = self.tail[hp as usize];
        let d = self.tail[tp as usize];
        let l_ab = self.length[h as usize];
        let l_bc = self.length[hn as usize];
        let l_ca = self.length[hp as usize];
        let l_ad = self.length[tn as usize];
        let l_db = self.length[tp as usize];
        // layout: a = (0,0), b = (l_ab, 0), c above, d below
        let xc = (l_ab * l_ab + l_ca * l_ca - l_bc * l_bc) / (2.0 * l_ab);
        let yc = 2.0 * triangle_area_from_lengths(l_ab, l_bc, l_ca) / l_ab;
        let xd = (l_ab * l_ab + l_ad * l_ad - l_db * l_db) / (2.0 * l_ab);
        let yd = -2.0 * triangle_area_from_lengths(l_ab, l_ad, l_db) / l_ab;
        let l_cd = ((xc - xd).powi(2) + (yc - yd).powi(2)).sqrt();
        let (x1, x2, x3, x4) = (
            self.twin[hn as usize],
            self.twin[hp as usize],
            self.twin[tn as usize],
            self.twin[tp as usize],
        );
        // face of h: h = c→d, hn = d→b, hp = b→c
        self.tail[h as usize] = c;
        self.tail[hn as usize] = d;
        self.tail[hp as usize] = b;
        // face of t: t = d→c, tn = c→a, tp = a→d
        self.tail[t as usize] = d;
        self.tail[tn as usize] = c;
        self.tail[tp as usize] = a;
        self.length[h as usize] = l_cd;
        self.length[t as usize] = l_cd;
        self.length[hn as usize] = l_db;
        self.length[hp as usize] = l_bc;
        self.length[tn as usize] = l_ca;
        self.length[tp as usize] = l_ad;
        self.link(hn, x4);
        self.link(hp, x1);
        self.link(tn, x2);
        self.link(tp, x3);
        self.num_flips += 1;
    }

    /// Flips edges until the triangulation is intrinsically Delaunay (every interior edge has
    /// cot α + cot β ≥ −1e-12, a tolerance that keeps co-circular configurations such as
    /// regular grids from flipping back and forth). Boundary edges are never flipped.
    ///
    /// Returns the number of flips. Errors if more than 50·#E + 1000 flips are needed (Lawson's
    /// algorithm terminates in theory; the budget guards against roundoff cycles).
    pub fn make_delaunay(&mut self) -> Result<usize, ConformalError> {
        let tol = DELAUNAY_TOLERANCE;
        let nh = self.tail.len();
        let budget = 50 * nh + 1000;
        let mut queued = vec![false; nh];
        let mut queue: VecDeque<u32> = VecDeque::new();
        for h in 0..nh as u32 {
            let t = self.twin[h as usize];
            if t != NONE && h < t {
                queue.push_back(h);
                queued[h as usize] = true;
            }
        }
        let start = self.num_flips;
        while let Some(h) = queue.pop_front() {
            queued[h as usize] = false;
            if !self.is_non_delaunay(h, tol) || self.touches_itself(h) {
                continue;
            }
            if self.num_flips - start > budget {
                return Err(ConformalError::FlipBudgetExceeded {
                    flips: self.num_flips - start,
                });
            }
            self.flip(h);
            let t = self.twin[h as usize];
            for g in [next(h), prev(h), next(t), prev(t)] {
                let gt = self.twin[g as usize];
                if gt == NONE {
                    continue;
                }
                let key = g.min(gt);
                if !queued[key as usize] {
                    queued[key as usize] = true;
                    queue.push_back(key);
                }
            }
        }
        Ok(self.num_flips - start)
    }

    /// Splits the interior edge of half-edge h = a→b at its midpoint m, a new interior vertex
    /// with index `num_vertices` (returned): the faces (a, b, c) and (b, a, d) become (a, m, c),
    /// (m, b, c), (b, m, d) and (m, a, d). The first and third keep the slots of h's and its
    /// twin's faces, the other two are appended. |mc| and |md| are the medians of the two
    /// triangles laid out in the plane, so the surface (its metric and area) is unchanged and m
    /// is flat (angle sum 2π) [Sharp, Soliman & Crane 2019, §3: vertex insertion].
    pub fn split_edge(&mut self, h: u32) -> u32 {
        let t = self.twin[h as usize];
        debug_assert!(t != NONE, "split_edge needs an interior edge");
        let (hn, hp, tn, tp) = (next(h), prev(h), next(t), prev(t));
        let (a, b) = (self.tail[h as usize], self.tail[t as usize]);
        let (c, d) = (self.tail[hp as usize], self.tail[tp as usize]);
        let l_ab = self.length[h as usize];
        let (l_bc, l_ca) = (self.length[hn as usize], self.length[hp as usize]);
        let (l_ad, l_db) = (self.length[tn as usize], self.length[tp as usize]);
        let median = |u: f64, v: f64| (0.5 * (u * u + v * v) - 0.25 * l_ab * l_ab).max(0.0).sqrt();
        let (l_mc, l_md) = (median(l_bc, l_ca), median(l_ad, l_db));
        let half = 0.5 * l_ab;
        let m = self.num_vertices as u32;
        self.num_vertices += 1;
        self.is_boundary.push(false);
        let (x_bc, x_ad) = (self.twin[hn as usize], self.twin[tn as usize]);
        let f2 = self.tail.len() as u32; // (m, b, c)
        let f4 = f2 + 3; // (m, a, d)
        self.tail.extend_from_slice(&[m, b, c, m, a, d]);
        self.length.extend_from_slice(&[half, l_bc, l_mc, half, l_ad, l_md]);
        self.twin.extend_from_slice(&[NONE; 6]);
        // (a, m, c) in h's slots: h = a→m, hn = m→c, hp = c→a (unchanged)
        self.tail[hn as usize] = m;
        self.length[h as usize] = half;
        self.length[hn as usize] = l_mc;
        // (b, m, d) in t's slots: t = b→m, tn = m→d, tp = d→b (unchanged)
        self.tail[tn as usize] = m;
        self.length[t as usize] = half;
        self.length[tn as usize] = l_md;
        self.link(h, f4); // a→m / m→a
        self.link(hn, f2 + 2); // m→c / c→m
        self.link(f2, t); // m→b / b→m
        self.link(f2 + 1, x_bc); // b→c
        self.link(tn, f4 + 2); // m→d / d→m
        self.link(f4 + 1, x_ad); // a→d
        m
    }

    /// Interior vertices that no path through interior vertices joins to `center` (an interior
    /// vertex): edges joining two boundary vertices cut them off, and the Dirichlet problems of
    /// a harmonic disk map are zero there, which puts them on the boundary circle.
    pub fn cut_off_vertices(&self, center: u32) -> Vec<u32> {
        let mut parent: Vec<u32> = (0..self.num_vertices as u32).collect();
        for h in 0..self.tail.len() as u32 {
            let (a, b) = (self.tail[h as usize], self.head(h));
            if !self.is_boundary[a as usize] && !self.is_boundary[b as usize] {
                union(&mut parent, a, b);
            }
        }
        let root = find(&mut parent, center);
        (0..self.num_vertices as u32)
            .filter(|&v| !self.is_boundary[v as usize] && find(&mut parent, v) != root)
            .collect()
    }

    /// Makes every interior vertex reachable from `center` through interior vertices, and
    /// with `delaunay` the triangulation intrinsically Delaunay too: rounds of Delaunay flips
    /// ([`Self::make_delaunay`]) and midpoint splits ([`Self::split_edge`]) of the interior
    /// edges that join two boundary vertices opposite a cut-off vertex. A split vertex is
    /// interior and joins both sides of the edge, and the flips never remove it (its angle on
    /// the split edge is π, so the diagonal back to the edge is never Delaunay); a cut-off part
    /// a few triangles wide needs one round per row of such edges. The inserted vertices carry
    /// values in the linear solves only: maps are read at the original vertices, which keep
    /// their indices. Returns the number of inserted vertices.
    ///
    /// Errors: [`ConformalError::CutOffInterior`] when interior vertices are still cut off after
    /// [`MAX_CONNECT_ROUNDS`] rounds, or lie in a part with no such edge to split (neither
    /// happens on a disk), and the errors of [`Self::make_delaunay`].
    pub fn connect_interior(&mut self, center: u32, delaunay: bool) -> Result<usize, ConformalError> {
        let start = self.num_vertices;
        for _ in 0..MAX_CONNECT_ROUNDS {
            if delaunay {
                self.make_delaunay()?;
            }
            let cut = self.cut_off_vertices(center);
            if cut.is_empty() {
                return Ok(self.num_vertices - start);
            }
            let mut is_cut = vec![false; self.num_vertices];
            for &v in &cut {
                is_cut[v as usize] = true;
            }
            let mut split = 0;
            while let Some(h) = self.bridge_next_to(&is_cut) {
                self.split_edge(h);
                split += 1;
            }
            if split == 0 {
                return Err(self.cut_off_error(&cut, delaunay));
            }
        }
        let cut = self.cut_off_vertices(center);
        if cut.is_empty() {
            return Ok(self.num_vertices - start);
        }
        Err(self.cut_off_error(&cut, delaunay))
    }

    /// An interior edge joining two boundary vertices with a vertex flagged in `is_cut`
    /// opposite it (a half-edge of it), if any.
    fn bridge_next_to(&self, is_cut: &[bool]) -> Option<u32> {
        (0..self.tail.len() as u32).find(|&h| {
            let t = self.twin[h as usize];
            t != NONE
                && h < t
                && self.is_boundary[self.tail[h as usize] as usize]
                && self.is_boundary[self.head(h) as usize]
                && [prev(h), prev(t)].iter().any(|&g| {
                    let v = self.tail[g as usize] as usize;
                    v < is_cut.len() && is_cut[v]
                })
        })
    }

    fn cut_off_error(&self, cut: &[u32], by_flips: bool) -> ConformalError {
        ConformalError::CutOffInterior {
            vertex: cut[0] as usize,
            count: cut.len(),
            rounds: MAX_CONNECT_ROUNDS,
            by_flips,
        }
    }

    /// Per half-edge weight triplets (tail, head, ½ cot of the opposite angle), 3·#F entries:
    /// summed by [`shapespace_geometry::laplacian::laplacian_from_weights`] they give the
    /// cotangent Laplacian of this triangulation (self-loop edges contribute nothing).
    pub fn half_cotan_triplets(&self) -> Vec<(u32, u32, f64)> {
        (0..self.tail.len() as u32)
            .map(|h| (self.tail[h as usize], self.head(h), 0.5 * self.cot_opposite(h)))
            .collect()
    }

    /// The outgoing half-edge after h in counter-clockwise order around tail(h), or NONE at
    /// the boundary.
    #[inline]
    pub fn rotate_ccw(&self, h: u32) -> u32 {
        self.twin[prev(h) as usize]
    }

    /// Smallest interior-edge value of cot α + cot β (the Delaunay criterion), for diagnostics.
    pub fn min_delaunay_cot_sum(&self) -> f64 {
        let mut m = f64::INFINITY;
        for h in 0..self.tail.len() as u32 {
            let t = self.twin[h as usize];
            if t != NONE && h < t {
                m = m.min(self.cot_opposite(h) + self.cot_opposite(t));
            }
        }
        m
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn heron_is_stable_and_exact_on_right_triangle() {
        assert!((triangle_area_from_lengths(3.0, 4.0, 5.0) - 6.0).abs() < 1e-14);
        // needle: sides 1, 1, 1e-9 → area ≈ 0.5e-9
        let a = triangle_area_from_lengths(1.0, 1.0, 1e-9);
        assert!((a / 0.5e-9 - 1.0).abs() < 1e-9, "{a}");
        assert_eq!(triangle_area_from_lengths(1.0, 1.0, 3.0), 0.0);
    }

    /// A midpoint split keeps the surface: total area, the lengths of the two triangles' other
    /// sides, a flat new vertex (angle sum 2π), consistent twins; and a Delaunay pass after it
    /// does not flip the split edge back.
    #[test]
    fn split_edge_keeps_the_surface_and_makes_a_flat_interior_vertex() {
        let positions = vec![[0.0, 0.0, 0.0], [2.0, 0.1, 0.3], [0.7, 1.3, -0.2], [1.1, -0.9, 0.4]];
        let mesh = TriMesh::new(positions, vec![[0, 1, 2], [1, 0, 3]]).unwrap();
        let mut it = IntrinsicTriangulation::from_mesh(&mesh).unwrap();
        let area0: f64 = (0..it.num_faces()).map(|f| it.face_area(f)).sum();
        let h = (0..6u32).find(|&h| it.twin[h as usize] != NONE).unwrap();
        let m = it.split_edge(h);
        assert_eq!((m, it.num_vertices, it.num_faces()), (4, 5, 4));
        assert!(!it.is_boundary[4]);
        let area1: f64 = (0..it.num_faces()).map(|f| it.face_area(f)).sum();
        assert!((area0 - area1).abs() < 1e-14 * area0, "{area0} vs {area1}");
        let mut angle_sum = 0.0;
        for g in 0..it.tail.len() as u32 {
            let t = it.twin[g as usize];
            if t != NONE {
                assert_eq!(it.twin[t as usize], g);
                assert_eq!((it.tail[t as usize], it.head(t)), (it.head(g), it.tail[g as usize]));
                assert_eq!(it.length[t as usize], it.length[g as usize]);
            }
            if it.tail[g as usize] == m {
                let (e, a, b) = (
                    it.length[next(g) as usize],
                    it.length[g as usize],
                    it.length[prev(g) as usize],
                );
                angle_sum += (4.0 * triangle_area_from_lengths(e, a, b)).atan2(a * a + b * b - e * e);
            }
        }
        assert!((angle_sum - std::f64::consts::TAU).abs() < 1e-12, "{angle_sum}");
        // the four outer sides keep their 3D lengths
        let d = |a: usize, b: usize| {
            let (p, q) = (mesh.positions[a], mesh.positions[b]);
            ((p[0] - q[0]).powi(2) + (p[1] - q[1]).powi(2) + (p[2] - q[2]).powi(2)).sqrt()
        };
        for (a, b) in [(1, 2), (2, 0), (0, 3), (3, 1)] {
            let g = (0..it.tail.len() as u32)
                .find(|&g| it.tail[g as usize] == a && it.head(g) == b)
                .unwrap();
            assert!((it.length[g as usize] - d(a as usize, b as usize)).abs() < 1e-15);
        }
        let flips = it.make_delaunay().unwrap();
        assert!((0..it.tail.len() as u32).all(|g| it.tail[g as usize] != it.head(g)));
        assert!(it.min_delaunay_cot_sum() >= -1e-12, "after {flips} flips");
    }

    #[test]
    fn flip_makes_a_nondelaunay_quad_delaunay_and_preserves_area() {
        // a flat quad (0,0),(1,0),(1,1e-1... ) with a long diagonal: kite whose diagonal 0-2 is
        // non-Delaunay (opposite angles obtuse)
        let positions = vec![[0.0, 0.0, 0.0], [1.0, -0.2, 0.0], [2.0, 0.0, 0.0], [1.0, 0.2, 0.0]];
        let faces = vec![[0, 1, 2], [0, 2, 3]];
        let mesh = TriMesh::new(positions, faces).unwrap();
        let mut it = IntrinsicTriangulation::from_mesh(&mesh).unwrap();
        let area0: f64 = (0..2).map(|f| it.face_area(f)).sum();
        assert!(it.min_delaunay_cot_sum() < 0.0);
        let flips = it.make_delaunay().unwrap();
        assert_eq!(flips, 1);
        let area1: f64 = (0..2).map(|f| it.face_area(f)).sum();
        assert!((area0 - area1).abs() < 1e-15);
        assert!(it.min_delaunay_cot_sum() >= 0.0);
        // the new diagonal joins 1 and 3 with length 0.4
        let h = (0..6).find(|&h| it.twin[h] != NONE).unwrap();
        assert!((it.length[h] - 0.4).abs() < 1e-15);
        let ends = [it.tail[h], it.head(h as u32)];
        assert!(ends.contains(&1) && ends.contains(&3));
    }
}
