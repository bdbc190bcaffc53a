//! Ground truth carried onto a remeshed target: when S₂' is a remeshing of S₂ (same surface, other
//! triangulation) and v ↔ v is the ground truth S₁ → S₂, the true partner of v on S₂' is the point
//! of S₂' closest to the vertex v of S₂. The error of that transfer is the remeshing's distance
//! from the surface (a fraction of an edge length for an isotropic remeshing that checks it).
//!
//! The closest point is exact: faces are bucketed in a uniform grid by their bounding boxes and
//! the grid is searched in growing shells of cells until no unvisited cell can hold a closer
//! point; within a face, the closest point of a triangle [Ericson, *Real-Time Collision
//! Detection*, §5.1.5] (`shapespace_conformal::closest_point_barycentric`).
//!
//! The markers of a remeshed target ([`carry_markers`]) are vertices of S₂' at the markers' closest
//! points: the corner of the face holding the closest point that lies nearest the marker (among
//! boundary vertices for the boundary marker, interior ones for the center and the landmarks; the
//! nearest such vertex anywhere when no corner of that face is of the kind). The nearest vertex
//! in space alone can lie on another part of the surface where two parts almost touch (a paw of
//! a Sumner cat pose lies 0.0029 √area from a vertex of another part of the body, 0.0033 from
//! the nearest vertex of its own).

use std::collections::BTreeMap;

use shapespace_conformal::markers::closest_point_barycentric;
use shapespace_conformal::{BoundaryMarker, CenterMarker, MarkerFile, Markers};
use shapespace_geometry::{Connectivity, TriMesh};

use super::at_surface_point;
use crate::error::AnalysisError;

/// A point of a mesh: a face and barycentric coordinates with respect to its corners in order.
pub type SurfacePoint = (u32, [f64; 3]);

/// Uniform grid of the faces of a mesh by their bounding boxes.
struct FaceGrid<'a> {
    mesh: &'a TriMesh,
    lo: [f64; 3],
    cell: f64,
    dims: [usize; 3],
    /// Faces per cell, x fastest.
    cells: Vec<Vec<u32>>,
}

impl<'a> FaceGrid<'a> {
    fn new(mesh: &'a TriMesh) -> Self {
        let mut lo = [f64::INFINITY; 3];
        let mut hi = [f64::NEG_INFINITY; 3];
        for p in &mesh.positions {
            for d in 0..3 {
                lo[d] = lo[d].min(p[d]);
                hi[d] = hi[d].max(p[d]);
            }
        }
        // about two faces per cell on a uniform surface: cells of twice the mean edge length
        let mut edge_sum = 0.0;
        for fi in 0..mesh.num_faces() {
            let p = mesh.face_positions(fi);
            for k in 0..3 {
                let q = p[(k + 1) % 3];
                edge_sum += ((p[k][0] - q[0]).powi(2) + (p[k][1] - q[1]).powi(2) + (p[k][2] - q[2]).powi(2)).sqrt();
            }
        }
        let extent = (0..3).map(|d| hi[d] - lo[d]).fold(0.0, f64::max);
        let mut cell = 2.0 * edge_sum / (3 * mesh.num_faces().max(1)) as f64;
        if !(cell > 0.0) || !cell.is_finite() {
            cell = extent.max(1.0);
        }
        // at most about 2^21 cells
        while (0..3).map(|d| ((hi[d] - lo[d]) / cell) as usize + 1).product::<usize>() > 1 << 21 {
            cell *= 2.0;
        }
        let dims = [0, 1, 2].map(|d| ((hi[d] - lo[d]) / cell) as usize + 1);
        let mut cells = vec![Vec::new(); dims[0] * dims[1] * dims[2]];
        let mut grid = FaceGrid {
            mesh,
            lo,
            cell,
            dims,
            cells: Vec::new(),
        };
        for fi in 0..mesh.num_faces() {
            let p = mesh.face_positions(fi);
            let mut a = [usize::MAX; 3];
            let mut b = [0; 3];
            for q in p {
                let c = grid.cell_of(q);
                for d in 0..3 {
                    a[d] = a[d].min(c[d]);
                    b[d] = b[d].max(c[d]);
                }
            }
            for z in a[2]..=b[2] {
                for y in a[1]..=b[1] {
                    for x in a[0]..=b[0] {
                        cells[grid.index([x, y, z])].push(fi as u32);
                    }
                }
            }
        }
        grid.cells = cells;
        grid
    }

    fn cell_of(&self, p: [f64; 3]) -> [usize; 3] {
        [0, 1, 2].map(|d| {
            let c = ((p[d] - self.lo[d]) / self.cell).floor();
            if c > 0.0 {
                (c as usize).min(self.dims[d] - 1)
            } else {
                0
            }
        })
    }

    fn index(&self, c: [usize; 3]) -> usize {
        c[0] + self.dims[0] * (c[1] + self.dims[1] * c[2])
    }

    /// The closest point of the mesh to `p` (face, barycentric coordinates, squared distance).
    fn closest(&self, p: [f64; 3]) -> (u32, [f64; 3], f64) {
        // p clamped into the grid's box: the distance from p to any cell is at least the distance
        // from p to the box plus the Chebyshev ring distance, so rings are searched from there
        let home = self.cell_of(p);
        let mut outside = 0.0f64;
        for d in 0..3 {
            let hi = self.lo[d] + self.dims[d] as f64 * self.cell;
            outside += (self.lo[d] - p[d]).max(0.0).powi(2) + (p[d] - hi).max(0.0).powi(2);
        }
        let mut best = (0u32, [1.0, 0.0, 0.0], f64::INFINITY);
        let max_ring = self.dims.iter().copied().max().unwrap_or(1);
        for ring in 0..=max_ring {
            // every point of a cell at Chebyshev ring r ≥ 1 from home lies at least (r − 1)
            // cells from p along one axis (p lies in its home cell or beyond the box)
            if ring >= 1 {
                let gap = (ring - 1) as f64 * self.cell;
                if best.2 <= gap * gap + outside && best.2.is_finite() {
                    break;
                }
            }
            let r = ring as isize;
            let range = |d: usize| {
                let c = home[d] as isize;
                ((c - r).max(0) as usize, ((c + r) as usize).min(self.dims[d] - 1))
            };
            let ((x0, x1), (y0, y1), (z0, z1)) = (range(0), range(1), range(2));
            for z in z0..=z1 {
                for y in y0..=y1 {
                    for x in x0..=x1 {
                        let on_ring = [x, y, z]
                            .iter()
                            .zip(home)
                            .map(|(&a, h)| (a as isize - h as isize).unsigned_abs())
                            .max()
                            == Some(ring);
                        if !on_ring {
                            continue;
                        }
                        for &fi in &self.cells[self.index([x, y, z])] {
                            let q = self.mesh.face_positions(fi as usize);
                            let b = closest_point_barycentric(p, q[0], q[1], q[2]);
                            let mut d2 = 0.0;
                            for d in 0..3 {
                                let x = b[0] * q[0][d] + b[1] * q[1][d] + b[2] * q[2][d];
                                d2 += (x - p[d]) * (x - p[d]);
                            }
                            if d2 < best.2 || (d2 == best.2 && fi < best.0) {
                                best = (fi, b, d2);
                            }
                        }
                    }
                }
            }
        }
        best
    }
}

/// The closest point of `mesh` to each of `points` (#points (face, barycentric) pairs) and the
/// largest distance met, exact (module docs). Ties go to the lower face index. Errors: a mesh
/// without faces, or a point that is not finite.
pub fn closest_points(points: &[[f64; 3]], mesh: &TriMesh) -> Result<(Vec<SurfacePoint>, f64), AnalysisError> {
    use rayon::prelude::*;
    if mesh.faces.is_empty() {
        return Err(AnalysisError::InvalidInput(
            "closest points: the mesh has no faces".into(),
        ));
    }
    if let Some(i) = points.iter().position(|p| !p.iter().all(|x| x.is_finite())) {
        return Err(AnalysisError::InvalidInput(format!(
            "closest points: point {i} is not finite: {:?}",
            points[i]
        )));
    }
    let grid = FaceGrid::new(mesh);
    let found: Vec<(u32, [f64; 3], f64)> = points.par_iter().map(|&p| grid.closest(p)).collect();
    let max = found.iter().map(|f| f.2.sqrt()).fold(0.0, f64::max);
    Ok((found.into_iter().map(|(f, b, _)| (f, b)).collect(), max))
}

/// The vertex of `mesh` among `allowed` nearest to `p` (the lowest index among equals).
fn nearest_vertex(mesh: &TriMesh, p: [f64; 3], allowed: &[bool]) -> Option<u32> {
    let mut best: Option<(u32, f64)> = None;
    for (v, q) in mesh.positions.iter().enumerate() {
        if !allowed[v] {
            continue;
        }
        let d2 = (0..3).map(|d| (q[d] - p[d]).powi(2)).sum::<f64>();
        if best.is_none_or(|b| d2 < b.1) {
            best = Some((v as u32, d2));
        }
    }
    best.map(|b| b.0)
}

/// The markers of `original` (a marker file of that mesh) carried onto `remeshed`, a remeshing
/// of the same surface: vertex markers and landmarks become vertices of `remeshed` at their
/// closest points (module docs: the boundary marker a boundary vertex, the center and the
/// landmarks interior ones); a barycentric center becomes a point in space (projected by the disk map);
/// `auto` stays `auto`. Errors: a marker index out of range of `original`, or `remeshed`
/// without interior or boundary vertices.
pub fn carry_markers(
    original: &TriMesh,
    markers: &MarkerFile,
    remeshed: &TriMesh,
) -> Result<MarkerFile, AnalysisError> {
    let n = remeshed.num_vertices();
    let boundary = Connectivity::of(remeshed).boundary_vertices(n);
    let interior: Vec<bool> = boundary.iter().map(|b| !b).collect();
    let position = |v: u32, what: &str| {
        original.positions.get(v as usize).copied().ok_or_else(|| {
            AnalysisError::InvalidInput(format!(
                "{what} {v} out of range of the original mesh (#V = {})",
                original.num_vertices()
            ))
        })
    };
    if remeshed.faces.is_empty() {
        return Err(AnalysisError::InvalidInput(
            "carrying markers: the remeshed mesh has no faces".into(),
        ));
    }
    let grid = FaceGrid::new(remeshed);
    // the corner of the closest point's face nearest p among the allowed vertices, else the
    // nearest allowed vertex anywhere
    let nearest = |p: [f64; 3], allowed: &[bool], what: &str| {
        let d2 = |w: u32| {
            let q = remeshed.positions[w as usize];
            (0..3).map(|d| (q[d] - p[d]).powi(2)).sum::<f64>()
        };
        let (face, _, _) = grid.closest(p);
        remeshed.faces[face as usize]
            .into_iter()
            .filter(|&w| allowed[w as usize])
            .min_by(|&a, &b| d2(a).total_cmp(&d2(b)).then(a.cmp(&b)))
            .or_else(|| nearest_vertex(remeshed, p, allowed))
            .ok_or_else(|| AnalysisError::InvalidInput(format!("the remeshed mesh has no vertex for the {what}")))
    };
    let center = match &markers.markers.center {
        CenterMarker::Vertex(v) => CenterMarker::Vertex(nearest(position(*v, "center")?, &interior, "center")?),
        CenterMarker::Barycentric { face, bary } => {
            if *face as usize >= original.faces.len() {
                return Err(AnalysisError::InvalidInput(format!(
                    "center face {face} out of range of the original mesh"
                )));
            }
            CenterMarker::Point(at_surface_point(&original.faces, &original.positions, (*face, *bary)))
        }
        other => other.clone(),
    };
    let boundary_marker = match &markers.markers.boundary {
        BoundaryMarker::Vertex(v) => {
            BoundaryMarker::Vertex(nearest(position(*v, "boundary marker")?, &boundary, "boundary marker")?)
        }
        BoundaryMarker::Auto => BoundaryMarker::Auto,
    };
    let mut landmarks = BTreeMap::new();
    for (name, &v) in &markers.landmarks {
        let w = nearest(position(v, &format!("landmark `{name}`"))?, &interior, "landmarks")?;
        landmarks.insert(name.clone(), w);
    }
    Ok(MarkerFile {
        markers: Markers {
            center,
            boundary: boundary_marker,
        },
        landmarks,
    })
}

/// A marker file as JSON (`{"center", "boundary", "landmarks"}`, the format
/// `MarkerFile::from_json_file` reads; `auto` markers are left out).
pub fn marker_file_json(markers: &MarkerFile) -> serde_json::Value {
    let mut o = serde_json::Map::new();
    match &markers.markers.center {
        CenterMarker::Vertex(v) => {
            o.insert("center".into(), serde_json::json!(v));
        }
        CenterMarker::Barycentric { face, bary } => {
            o.insert("center".into(), serde_json::json!({"face": face, "bary": bary}));
        }
        CenterMarker::Point(p) => {
            o.insert("center".into(), serde_json::json!(p));
        }
        CenterMarker::Auto => {}
    }
    if let BoundaryMarker::Vertex(v) = markers.markers.boundary {
        o.insert("boundary".into(), serde_json::json!(v));
    }
    o.insert("landmarks".into(), serde_json::json!(markers.landmarks));
    serde_json::Value::Object(o)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A triangulated m × m grid of [0,1]², diagonals alternating (`alternate`) or all alike.
    fn grid(m: usize, alternate: bool) -> TriMesh {
        let mut p = Vec::new();
        for j in 0..=m {
            for i in 0..=m {
                p.push([i as f64 / m as f64, j as f64 / m as f64, 0.0]);
            }
        }
        let idx = |i: usize, j: usize| (j * (m + 1) + i) as u32;
        let mut f = Vec::new();
        for j in 0..m {
            for i in 0..m {
                if alternate && (i + j) % 2 == 1 {
                    f.push([idx(i, j), idx(i + 1, j), idx(i, j + 1)]);
                    f.push([idx(i + 1, j), idx(i + 1, j + 1), idx(i, j + 1)]);
                } else {
                    f.push([idx(i, j), idx(i + 1, j), idx(i + 1, j + 1)]);
                    f.push([idx(i, j), idx(i + 1, j + 1), idx(i, j + 1)]);
                }
            }
        }
        TriMesh::new(p, f).unwrap()
    }

    /// The graph z = h(x, y) of a smooth bump over a mesh of [0,1]².
    fn lift(mut mesh: TriMesh) -> TriMesh {
        for p in &mut mesh.positions {
            p[2] = 0.3 * (3.0 * p[0]).sin() * (2.0 * p[1]).cos();
        }
        mesh
    }

    fn point(mesh: &TriMesh, p: SurfacePoint) -> [f64; 3] {
        at_surface_point(&mesh.faces, &mesh.positions, p)
    }

    #[test]
    fn closest_points_of_a_known_remeshing_are_the_known_points() {
        // flat: S₂ a 30 × 30 grid of the unit square, S₂' a 17 × 17 one with other diagonals
        // (the known map is the identity): each vertex of S₂' is its own closest point on S₂
        let (fine, coarse) = (grid(30, true), grid(17, false));
        let (found, max) = closest_points(&coarse.positions, &fine).unwrap();
        assert!(max < 1e-15, "max distance {max}");
        for (v, &fp) in found.iter().enumerate() {
            let (q, p) = (point(&fine, fp), coarse.positions[v]);
            assert!(
                (q[0] - p[0]).abs() < 1e-15 && (q[1] - p[1]).abs() < 1e-15,
                "{p:?} -> {q:?}"
            );
        }
        // curved: the graph of a bump over both grids (the known map is (x, y) ↦ (x, y)); the
        // vertices of S₂' lie off the piecewise-linear S₂ by its interpolation error only
        let fine = lift(grid(30, true));
        let coarse = lift(grid(17, false));
        let (found, max) = closest_points(&coarse.positions, &fine).unwrap();
        // the coarse vertices are not on the fine surface exactly (it is piecewise linear), but
        // within the interpolation error of the bump; the projection moves (x, y) by less
        for (v, &fp) in found.iter().enumerate() {
            let q = point(&fine, fp);
            let p = coarse.positions[v];
            assert!((q[0] - p[0]).hypot(q[1] - p[1]) < 2e-3, "vertex {v}: {p:?} -> {q:?}");
            assert!(fp.1.iter().all(|&b| b >= -1e-12) && (fp.1.iter().sum::<f64>() - 1.0).abs() < 1e-12);
        }
        assert!(max < 1e-3, "max distance {max}");
        // the same mesh: every vertex is its own closest point
        let (own, max) = closest_points(&fine.positions, &fine).unwrap();
        assert_eq!(max, 0.0);
        for (v, &fp) in own.iter().enumerate() {
            let t = fine.faces[fp.0 as usize];
            let k = t
                .iter()
                .position(|&w| w as usize == v)
                .expect("a face around the vertex");
            assert_eq!(fp.1[k], 1.0);
        }
    }

    #[test]
    fn closest_points_match_brute_force_off_the_surface() {
        let mesh = lift(grid(12, true));
        let mut rng_state = 12345u64;
        let mut next = || {
            rng_state = rng_state
                .wrapping_mul(6364136223846793005)
                .wrapping_add(1442695040888963407);
            (rng_state >> 11) as f64 / (1u64 << 53) as f64
        };
        // points around and far outside the bounding box
        let points: Vec<[f64; 3]> = (0..300)
            .map(|_| [3.0 * next() - 1.0, 3.0 * next() - 1.0, 2.0 * next() - 1.0])
            .collect();
        let (found, _) = closest_points(&points, &mesh).unwrap();
        for (p, fp) in points.iter().zip(&found) {
            let d2 = |q: [f64; 3]| (0..3).map(|d| (q[d] - p[d]).powi(2)).sum::<f64>();
            let brute = (0..mesh.num_faces())
                .map(|fi| {
                    let q = mesh.face_positions(fi);
                    d2(point(
                        &mesh,
                        (fi as u32, closest_point_barycentric(*p, q[0], q[1], q[2])),
                    ))
                })
                .fold(f64::INFINITY, f64::min);
            assert!((d2(point(&mesh, *fp)) - brute).abs() <= 1e-14, "{p:?}");
        }
        assert!(closest_points(&[[f64::NAN, 0.0, 0.0]], &mesh).is_err());
    }

    #[test]
    fn markers_carry_to_vertices_of_their_kind_at_their_closest_points() {
        let fine = grid(30, true);
        let coarse = grid(10, false);
        // on the fine grid: center (1/2, 1/2), boundary (13/30, 0), landmarks (8/30, 22/30) and
        // (1/30, 1/30)
        let v = |i: usize, j: usize| (j * 31 + i) as u32;
        let mf = MarkerFile {
            markers: Markers {
                center: CenterMarker::Vertex(v(15, 15)),
                boundary: BoundaryMarker::Vertex(v(13, 0)),
            },
            landmarks: [("a".to_string(), v(8, 22)), ("b".to_string(), v(1, 1))].into(),
        };
        let carried = carry_markers(&fine, &mf, &coarse).unwrap();
        let w = |i: usize, j: usize| (j * 11 + i) as u32;
        assert_eq!(carried.markers.center, CenterMarker::Vertex(w(5, 5)));
        assert_eq!(carried.markers.boundary, BoundaryMarker::Vertex(w(4, 0)));
        assert_eq!(carried.landmarks["a"], w(3, 7));
        // (1/30, 1/30) is nearest the boundary corner (0, 0), but landmarks are interior
        assert_eq!(carried.landmarks["b"], w(1, 1));
        let back = MarkerFile::from_json_str(&marker_file_json(&carried).to_string(), "carried").unwrap();
        assert_eq!(back.markers, carried.markers);
        assert_eq!(back.landmarks, carried.landmarks);
        // two parts that almost touch: a landmark of the fine grid at (5/40, 7/40), 0.035 from
        // the nearest vertex (1/10, 2/10) of the coarse grid, 0.03 below a vertex of a small
        // sheet over it; it stays on its own part
        let mut sheet = grid(2, false);
        for p in &mut sheet.positions {
            *p = [0.075 + 0.1 * p[0], 0.125 + 0.1 * p[1], 0.03];
        }
        let n = coarse.num_vertices() as u32;
        let two_parts = TriMesh::new(
            coarse.positions.iter().chain(&sheet.positions).copied().collect(),
            coarse
                .faces
                .iter()
                .copied()
                .chain(sheet.faces.iter().map(|f| f.map(|v| v + n)))
                .collect(),
        )
        .unwrap();
        let fine = grid(40, true);
        let at = |i: usize, j: usize| (j * 41 + i) as u32;
        let mf = MarkerFile {
            markers: Markers {
                center: CenterMarker::Vertex(at(20, 20)),
                boundary: BoundaryMarker::Auto,
            },
            landmarks: [("paw".to_string(), at(5, 7))].into(),
        };
        let sheet_center = n + 4;
        assert_eq!(two_parts.positions[sheet_center as usize], [0.125, 0.175, 0.03]);
        assert_eq!(
            nearest_vertex(&two_parts, fine.positions[at(5, 7) as usize], &[true; 130]),
            Some(sheet_center)
        );
        let carried = carry_markers(&fine, &mf, &two_parts).unwrap();
        assert_eq!(carried.landmarks["paw"], w(1, 2));
        assert_eq!(carried.markers.center, CenterMarker::Vertex(w(5, 5)));
        let bad = MarkerFile {
            markers: Markers {
                center: CenterMarker::Vertex(10_000),
                boundary: BoundaryMarker::Auto,
            },
            landmarks: BTreeMap::new(),
        };
        assert!(carry_markers(&fine, &bad, &coarse).is_err());
    }
}
