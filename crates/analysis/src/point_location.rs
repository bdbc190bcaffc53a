//! Point location in a planar triangulation: which triangle of a disk image φ(S) holds a
//! point, and its barycentric coordinates there. Used to compose maps through the disk
//! (f = φ₂⁻¹ ∘ g ∘ φ₁, Su et al. 2015, Alg. 4): the image on S₂ of a point p of the disk is
//! the barycentric point of the 3D triangle whose planar image holds p.
//!
//! # Index
//! An adaptive quadtree over the bounding box of the planar vertices. Each leaf lists the
//! triangles whose bounding box overlaps it; a leaf with more than [`LEAF_CAPACITY`] triangles
//! is split into four, down to a depth of [`MAX_DEPTH`]. Conformal disk images squeeze long
//! protrusions into regions of size ~e^{−H/ρ} (DESIGN.md): a uniform grid would pile thousands
//! of tiny triangles into one cell, the quadtree refines there instead. Build O(F log F)
//! (triangles of bounded overlap), query O(depth + leaf size).
//!
//! # Query
//! Barycentric coordinates are computed from edge vectors relative to a corner of each
//! candidate triangle (differences of nearby coordinates, DESIGN.md), as ratios of signed
//! areas. A point is inside when its smallest coordinate is ≥ −[`INSIDE_TOLERANCE`]. Among the
//! candidates of the leaf, the triangle with the largest smallest coordinate wins, so points on
//! shared edges and vertices get a deterministic answer. Points that no candidate holds (outside
//! the triangulated polygon: the boundary of a disk image is a polygon inscribed in the circle,
//! and a point of the circular segment between a chord and the circle lies outside) **snap**
//! to the closest point of the nearest boundary triangle (a triangle with a boundary edge;
//! linear scan of those, only for the few points outside); [`Location::snap_distance`] tells
//! how far they moved.

use shapespace_geometry::Connectivity;

use crate::error::AnalysisError;

/// A leaf holding more triangles than this is split (unless at [`MAX_DEPTH`]).
pub const LEAF_CAPACITY: usize = 12;
/// Maximum depth of the quadtree (cell side = bounding box / 2^depth).
pub const MAX_DEPTH: u32 = 40;
/// A point is inside a triangle when all its barycentric coordinates are ≥ −this.
pub const INSIDE_TOLERANCE: f64 = 1e-12;

/// Where a point lies: a triangle, barycentric coordinates with respect to its corners in
/// order (summing to 1, each ≥ −[`INSIDE_TOLERANCE`] unless snapped: then all ≥ 0), and the
/// distance the point was moved onto the triangulation (0 when inside).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Location {
    /// Face index.
    pub face: u32,
    /// Barycentric coordinates (b0, b1, b2) for the corners `faces[face][0..3]`.
    pub bary: [f64; 3],
    /// Distance from the query point to the located point (0 inside, > 0 when snapped).
    pub snap_distance: f64,
}

#[derive(Clone, Debug)]
enum Node {
    Leaf(Vec<u32>),
    Split(Box<[usize; 4]>),
}

/// A quadtree point locator over a planar triangulation (module docs).
#[derive(Clone, Debug)]
pub struct PointLocator {
    positions: Vec<[f64; 2]>,
    faces: Vec<[u32; 3]>,
    nodes: Vec<Node>,
    lo: [f64; 2],
    hi: [f64; 2],
    boundary_faces: Vec<u32>,
}

fn face_box(positions: &[[f64; 2]], f: [u32; 3]) -> ([f64; 2], [f64; 2]) {
    let mut lo = [f64::INFINITY; 2];
    let mut hi = [f64::NEG_INFINITY; 2];
    for &v in &f {
        let p = positions[v as usize];
        for k in 0..2 {
            lo[k] = lo[k].min(p[k]);
            hi[k] = hi[k].max(p[k]);
        }
    }
    (lo, hi)
}

/// Barycentric coordinates of `p` in triangle (a, b, c) from signed areas of sub-triangles,
/// computed relative to `a`. `None` for a degenerate (zero-area) triangle.
pub fn barycentric(p: [f64; 2], a: [f64; 2], b: [f64; 2], c: [f64; 2]) -> Option<[f64; 3]> {
    let (ux, uy) = (b[0] - a[0], b[1] - a[1]);
    let (vx, vy) = (c[0] - a[0], c[1] - a[1]);
    let (wx, wy) = (p[0] - a[0], p[1] - a[1]);
    let det = ux * vy - uy * vx;
    if det == 0.0 || !det.is_finite() {
        return None;
    }
    let b1 = (wx * vy - wy * vx) / det;
    let b2 = (ux * wy - uy * wx) / det;
    Some([1.0 - b1 - b2, b1, b2])
}

/// Closest point of the segment a–b to p, as the parameter t ∈ [0, 1] (point a + t(b − a)).
fn segment_parameter(p: [f64; 2], a: [f64; 2], b: [f64; 2]) -> f64 {
    let (dx, dy) = (b[0] - a[0], b[1] - a[1]);
    let len2 = dx * dx + dy * dy;
    if len2 == 0.0 {
        return 0.0;
    }
    (((p[0] - a[0]) * dx + (p[1] - a[1]) * dy) / len2).clamp(0.0, 1.0)
}

/// The closest point of triangle (a, b, c) to p: barycentric coordinates (all ≥ 0) and the
/// distance. For a point inside, itself and 0.
pub fn closest_point_in_triangle(p: [f64; 2], a: [f64; 2], b: [f64; 2], c: [f64; 2]) -> ([f64; 3], f64) {
    if let Some(bc) = barycentric(p, a, b, c) {
        if bc.iter().all(|&x| x >= 0.0) {
            return (bc, 0.0);
        }
    }
    let corners = [a, b, c];
    let mut best = ([1.0, 0.0, 0.0], f64::INFINITY);
    for k in 0..3 {
        let (i, j) = (k, (k + 1) % 3);
        let t = segment_parameter(p, corners[i], corners[j]);
        let q = [corners[i][0] + t * (corners[j][0] - corners[i][0]), corners[i][1] + t * (corners[j][1] - corners[i][1])];
        let d = (q[0] - p[0]).hypot(q[1] - p[1]);
        if d < best.1 {
            let mut bc = [0.0; 3];
            bc[i] = 1.0 - t;
            bc[j] = t;
            best = (bc, d);
        }
    }
    best
}

impl PointLocator {
    /// Builds the locator over planar `positions` (#V) and `faces` (#F). Errors on a face
    /// index out of range or a non-finite position.
    pub fn new(positions: &[[f64; 2]], faces: &[[u32; 3]]) -> Result<Self, AnalysisError> {
        let n = positions.len();
        if let Some(f) = faces.iter().position(|f| f.iter().any(|&v| v as usize >= n)) {
            return Err(AnalysisError::InvalidInput(format!("point location: face {f} references a vertex out of range (#V = {n})")));
        }
        if let Some(v) = positions.iter().position(|p| !(p[0].is_finite() && p[1].is_finite())) {
            return Err(AnalysisError::InvalidInput(format!("point location: vertex {v} has a non-finite position")));
        }
        let mut lo = [f64::INFINITY; 2];
        let mut hi = [f64::NEG_INFINITY; 2];
        for p in positions {
            for k in 0..2 {
                lo[k] = lo[k].min(p[k]);
                hi[k] = hi[k].max(p[k]);
            }
        }
        if faces.is_empty() {
            lo = [0.0; 2];
            hi = [0.0; 2];
        }
        // square root box, slightly enlarged
        let side = (hi[0] - lo[0]).max(hi[1] - lo[1]).max(f64::MIN_POSITIVE) * (1.0 + 1e-9);
        let hi = [lo[0] + side, lo[1] + side];
        let conn = Connectivity::new(n, faces);
        let boundary_edges: std::collections::HashSet<(u32, u32)> =
            conn.boundary_halfedges(faces).iter().map(|[a, b]| (*a, *b)).collect();
        let boundary_faces = faces
            .iter()
            .enumerate()
            .filter(|(_, f)| (0..3).any(|k| boundary_edges.contains(&(f[k], f[(k + 1) % 3]))))
            .map(|(i, _)| i as u32)
            .collect();
        let mut loc = PointLocator {
            positions: positions.to_vec(),
            faces: faces.to_vec(),
            nodes: vec![Node::Leaf(Vec::new())],
            lo,
            hi,
            boundary_faces,
        };
        let boxes: Vec<([f64; 2], [f64; 2])> = faces.iter().map(|&f| face_box(positions, f)).collect();
        let all: Vec<u32> = (0..faces.len() as u32).collect();
        loc.build(0, lo, hi, all, &boxes, 0);
        Ok(loc)
    }

    fn build(&mut self, node: usize, lo: [f64; 2], hi: [f64; 2], items: Vec<u32>, boxes: &[([f64; 2], [f64; 2])], depth: u32) {
        if items.len() <= LEAF_CAPACITY || depth >= MAX_DEPTH {
            self.nodes[node] = Node::Leaf(items);
            return;
        }
        let mid = [0.5 * (lo[0] + hi[0]), 0.5 * (lo[1] + hi[1])];
        let quads = [
            (lo, mid),
            ([mid[0], lo[1]], [hi[0], mid[1]]),
            ([lo[0], mid[1]], [mid[0], hi[1]]),
            (mid, hi),
        ];
        let mut parts: [Vec<u32>; 4] = Default::default();
        for &t in &items {
            let (bl, bh) = boxes[t as usize];
            for (q, (ql, qh)) in quads.iter().enumerate() {
                if bl[0] <= qh[0] && bh[0] >= ql[0] && bl[1] <= qh[1] && bh[1] >= ql[1] {
                    parts[q].push(t);
                }
            }
        }
        // no progress (every triangle overlaps every quadrant): stop splitting
        if parts.iter().all(|p| p.len() == items.len()) {
            self.nodes[node] = Node::Leaf(items);
            return;
        }
        let base = self.nodes.len();
        for _ in 0..4 {
            self.nodes.push(Node::Leaf(Vec::new()));
        }
        self.nodes[node] = Node::Split(Box::new([base, base + 1, base + 2, base + 3]));
        for (q, part) in parts.into_iter().enumerate() {
            let (ql, qh) = quads[q];
            self.build(base + q, ql, qh, part, boxes, depth + 1);
        }
    }

    /// Number of triangles indexed.
    pub fn num_faces(&self) -> usize {
        self.faces.len()
    }

    fn leaf_of(&self, p: [f64; 2]) -> Option<&[u32]> {
        if !(p[0] >= self.lo[0] && p[0] <= self.hi[0] && p[1] >= self.lo[1] && p[1] <= self.hi[1]) {
            return None;
        }
        let (mut lo, mut hi) = (self.lo, self.hi);
        let mut node = 0;
        loop {
            match &self.nodes[node] {
                Node::Leaf(items) => return Some(items),
                Node::Split(children) => {
                    let mid = [0.5 * (lo[0] + hi[0]), 0.5 * (lo[1] + hi[1])];
                    let right = p[0] >= mid[0];
                    let top = p[1] >= mid[1];
                    let q = usize::from(right) + 2 * usize::from(top);
                    if right {
                        lo[0] = mid[0];
                    } else {
                        hi[0] = mid[0];
                    }
                    if top {
                        lo[1] = mid[1];
                    } else {
                        hi[1] = mid[1];
                    }
                    node = children[q];
                }
            }
        }
    }

    fn corners(&self, t: u32) -> [[f64; 2]; 3] {
        let f = self.faces[t as usize];
        [self.positions[f[0] as usize], self.positions[f[1] as usize], self.positions[f[2] as usize]]
    }

    /// Locates `p` (module docs): the triangle holding it, or the closest point of the nearest
    /// boundary triangle when none does. `None` only for an empty triangulation or a
    /// non-finite point.
    pub fn locate(&self, p: [f64; 2]) -> Option<Location> {
        if self.faces.is_empty() || !(p[0].is_finite() && p[1].is_finite()) {
            return None;
        }
        if let Some(items) = self.leaf_of(p) {
            let mut best: Option<(u32, [f64; 3], f64)> = None;
            for &t in items {
                let [a, b, c] = self.corners(t);
                if let Some(bc) = barycentric(p, a, b, c) {
                    let m = bc[0].min(bc[1]).min(bc[2]);
                    if m >= -INSIDE_TOLERANCE && best.is_none_or(|(_, _, bm)| m > bm) {
                        best = Some((t, bc, m));
                    }
                }
            }
            if let Some((t, bc, _)) = best {
                return Some(Location { face: t, bary: bc, snap_distance: 0.0 });
            }
        }
        // outside the triangulation (or in a crack): the closest point of the boundary triangles,
        // then of all triangles if there is no boundary (closed fan) or it is far
        let candidates: Box<dyn Iterator<Item = u32>> = if self.boundary_faces.is_empty() {
            Box::new(0..self.faces.len() as u32)
        } else {
            Box::new(self.boundary_faces.iter().copied())
        };
        let mut best: Option<Location> = None;
        for t in candidates {
            let [a, b, c] = self.corners(t);
            let (bc, d) = closest_point_in_triangle(p, a, b, c);
            if best.is_none_or(|l| d < l.snap_distance) {
                best = Some(Location { face: t, bary: bc, snap_distance: d });
            }
        }
        best
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A fan of k triangles around the origin approximating the unit disk.
    fn fan(k: usize) -> (Vec<[f64; 2]>, Vec<[u32; 3]>) {
        let mut p = vec![[0.0, 0.0]];
        for j in 0..k {
            let t = std::f64::consts::TAU * j as f64 / k as f64;
            p.push([t.cos(), t.sin()]);
        }
        let f = (0..k as u32).map(|j| [0, 1 + j, 1 + (j + 1) % k as u32]).collect();
        (p, f)
    }

    #[test]
    fn locates_inside_points_and_reproduces_them() {
        let (p, f) = fan(16);
        let loc = PointLocator::new(&p, &f).unwrap();
        for q in [[0.1, 0.2], [-0.5, 0.3], [0.0, -0.9], [0.6, -0.6]] {
            let l = loc.locate(q).unwrap();
            assert_eq!(l.snap_distance, 0.0);
            let t = f[l.face as usize];
            let x: f64 = (0..3).map(|k| l.bary[k] * p[t[k] as usize][0]).sum();
            let y: f64 = (0..3).map(|k| l.bary[k] * p[t[k] as usize][1]).sum();
            assert!((x - q[0]).abs() < 1e-15 && (y - q[1]).abs() < 1e-15, "{q:?} -> {x},{y}");
            assert!(l.bary.iter().all(|&b| b >= -INSIDE_TOLERANCE));
        }
    }

    #[test]
    fn points_outside_snap_to_the_boundary() {
        let (p, f) = fan(8);
        let loc = PointLocator::new(&p, &f).unwrap();
        // on the circle between two corners: outside the octagon, distance to the chord
        let t = std::f64::consts::TAU / 16.0;
        let l = loc.locate([t.cos(), t.sin()]).unwrap();
        let chord = (std::f64::consts::TAU / 16.0).cos();
        assert!((l.snap_distance - (1.0 - chord)).abs() < 1e-14, "{}", l.snap_distance);
        assert_eq!(l.face, 0);
        assert!((l.bary[1] - 0.5).abs() < 1e-12 && (l.bary[2] - 0.5).abs() < 1e-12);
        // far outside the bounding box
        let l = loc.locate([3.0, 0.0]).unwrap();
        assert!((l.snap_distance - 2.0).abs() < 1e-14);
        assert!(loc.locate([f64::NAN, 0.0]).is_none());
    }

    #[test]
    fn tiny_triangles_are_resolved_by_the_quadtree() {
        // a fan scaled by 1e-13 around (0.5, 0.25) plus a unit fan: points in both are found
        let (p, f) = fan(64);
        let mut pos: Vec<[f64; 2]> = p.clone();
        let mut faces = f.clone();
        let off = pos.len() as u32;
        pos.extend(p.iter().map(|q| [3.0 + 1e-13 * q[0], 0.25 + 1e-13 * q[1]]));
        faces.extend(f.iter().map(|t| [t[0] + off, t[1] + off, t[2] + off]));
        let loc = PointLocator::new(&pos, &faces).unwrap();
        let q = [3.0 + 0.3e-13, 0.25 + 0.2e-13];
        let l = loc.locate(q).unwrap();
        assert_eq!(l.snap_distance, 0.0);
        assert!(l.face >= 64);
        let t = faces[l.face as usize];
        let x: f64 = (0..3).map(|k| l.bary[k] * (pos[t[k] as usize][0] - 3.0)).sum();
        assert!((x - 0.3e-13).abs() < 1e-27 + 1e-3 * 0.3e-13, "{x}");
    }
}
