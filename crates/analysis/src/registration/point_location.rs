//! Point location in a planar triangulation: which triangle of a disk image φ(S) holds a
//! point, and its barycentric coordinates there. Used to compose maps through the disk
//! (f = φ₂⁻¹ ∘ g ∘ φ₁, Su et al. 2015, Alg. 4): the image on S₂ of a point p of the disk is
//! the barycentric point of the 3D triangle whose planar image holds p.
//!
//! # Index
//! A bounding-volume hierarchy over the triangles' bounding boxes (`box_tree`: binary, split at
//! the median centroid along the longer side, leaves of at most [`LEAF_CAPACITY`] triangles):
//! exactly 2⌈F/leaf⌉ − 1 nodes whatever the geometry. Conformal disk images squeeze long protrusions
//! into regions of size ~e^{−H/ρ} (`docs/conventions.md`, "Conformal map") and area-preserving (centroid) maps may fold
//! triangles over each other: a uniform grid would pile thousands of tiny triangles into one
//! cell, and a subdividing quadtree never terminates inside a stack of overlapping triangles;
//! the hierarchy adapts to both. Build O(F log F), query O(log F) plus the overlapping boxes.
//!
//! # Query
//! Barycentric coordinates are computed from edge vectors relative to a corner of each
//! candidate triangle (differences of nearby coordinates, `docs/conventions.md`), as ratios of signed
//! areas. A point is inside when its smallest coordinate is ≥ −[`INSIDE_TOLERANCE`]. Among the
//! candidates of the leaf, the triangle with the largest smallest coordinate wins, so points on
//! shared edges and vertices get a deterministic answer. Points that no candidate holds (outside
//! the triangulated polygon: the boundary of a disk image is a polygon inscribed in the circle,
//! and a point of the circular segment between a chord and the circle lies outside) **snap**
//! to the closest point of the nearest boundary triangle (a triangle with a boundary edge;
//! linear scan of those, only for the few points outside); [`Location::snap_distance`] tells
//! how far they moved.

use shapespace_geometry::Connectivity;

use super::box_tree::BoxTree;
pub use super::box_tree::LEAF_CAPACITY;
use crate::error::AnalysisError;

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

/// A point locator over a planar triangulation (module docs).
#[derive(Clone, Debug)]
pub struct PointLocator {
    positions: Vec<[f64; 2]>,
    faces: Vec<[u32; 3]>,
    tree: BoxTree<2>,
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
        let q = [
            corners[i][0] + t * (corners[j][0] - corners[i][0]),
            corners[i][1] + t * (corners[j][1] - corners[i][1]),
        ];
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
            return Err(AnalysisError::InvalidInput(format!(
                "point location: face {f} references a vertex out of range (#V = {n})"
            )));
        }
        if let Some(v) = positions.iter().position(|p| !(p[0].is_finite() && p[1].is_finite())) {
            return Err(AnalysisError::InvalidInput(format!(
                "point location: vertex {v} has a non-finite position"
            )));
        }
        let conn = Connectivity::new(n, faces);
        let boundary_edges: std::collections::HashSet<(u32, u32)> =
            conn.boundary_halfedges(faces).iter().map(|[a, b]| (*a, *b)).collect();
        let boundary_faces = faces
            .iter()
            .enumerate()
            .filter(|(_, f)| (0..3).any(|k| boundary_edges.contains(&(f[k], f[(k + 1) % 3]))))
            .map(|(i, _)| i as u32)
            .collect();
        let boxes: Vec<([f64; 2], [f64; 2])> = faces.iter().map(|&f| face_box(positions, f)).collect();
        Ok(PointLocator {
            positions: positions.to_vec(),
            faces: faces.to_vec(),
            // (the longer side; ties to x)
            tree: BoxTree::new(&boxes, |lo, hi| if hi[0] - lo[0] >= hi[1] - lo[1] { 0 } else { 1 }),
            boundary_faces,
        })
    }

    /// Number of triangles indexed.
    pub fn num_faces(&self) -> usize {
        self.faces.len()
    }

    fn corners(&self, t: u32) -> [[f64; 2]; 3] {
        let f = self.faces[t as usize];
        [
            self.positions[f[0] as usize],
            self.positions[f[1] as usize],
            self.positions[f[2] as usize],
        ]
    }

    /// Locates `p` (module docs): the triangle holding it, or the closest point of the nearest
    /// boundary triangle when none does. `None` only for an empty triangulation or a
    /// non-finite point.
    pub fn locate(&self, p: [f64; 2]) -> Option<Location> {
        if self.faces.is_empty() || !(p[0].is_finite() && p[1].is_finite()) {
            return None;
        }
        let mut best: Option<(u32, [f64; 3], f64)> = None;
        self.tree.for_candidates(p, |t| {
            let [a, b, c] = self.corners(t);
            if let Some(bc) = barycentric(p, a, b, c) {
                let m = bc[0].min(bc[1]).min(bc[2]);
                if m >= -INSIDE_TOLERANCE && best.is_none_or(|(bt, _, bm)| m > bm || (m == bm && t < bt)) {
                    best = Some((t, bc, m));
                }
            }
        });
        if let Some((t, bc, _)) = best {
            return Some(Location {
                face: t,
                bary: bc,
                snap_distance: 0.0,
            });
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
                best = Some(Location {
                    face: t,
                    bary: bc,
                    snap_distance: d,
                });
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
    fn tiny_triangles_are_resolved_by_the_hierarchy() {
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
        // reconstruct q − a from the (exact) corner differences: relative precision is kept
        let t = faces[l.face as usize];
        let a = pos[t[0] as usize];
        for d in 0..2 {
            let x: f64 = (1..3).map(|k| l.bary[k] * (pos[t[k] as usize][d] - a[d])).sum();
            let want = q[d] - a[d];
            assert!((x - want).abs() < 1e-9 * 1e-13, "{x} vs {want}");
        }
    }
}
