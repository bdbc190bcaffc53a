//! Geodesic distances on a triangle mesh by the heat method [Crane, Weischedel & Wardetzky
//! 2013, "Geodesics in heat", Algorithm 1].
//!
//! For a source vertex s:
//! 1. heat flow for a short time t: $(M + tL)\,u = \delta_s$ (one backward Euler step), with L
//!    the positive semidefinite cotangent Laplacian, M the lumped (barycentric) mass matrix and
//!    $t = \bar h^2$ (mean edge length squared, the paper's choice m = 1);
//! 2. the normalized field per face $X_f = -\nabla u_f / |\nabla u_f|$ (X = 0 where ∇u = 0);
//! 3. the Poisson problem $\Delta\phi = \nabla\cdot X$, i.e. in weak form
//!    $$ (L\phi)_i = \sum_f A_f\, \nabla\varphi_i \cdot X_f, $$
//!    (φ_i the hat function of vertex i; the right side sums to zero exactly, so pinning one
//!    vertex gives the Neumann solution), then φ ← φ − φ(s).
//!
//! Boundary condition: Neumann for the heat step (the natural condition of M + tL); Crane et
//! al. suggest averaging with a Dirichlet solve on surfaces with large holes, the holes of the
//! registration data are small. The two factorizations are computed once
//! ([`HeatGeodesics::new`]) and reused for every source (batched right-hand sides).
//!
//! [`HeatGeodesics::intrinsic_delaunay`] runs the same steps on the mesh's intrinsic Delaunay
//! triangulation (ZoomOut's landmark fields, decision 0037); the registration metric's
//! geodesic error uses the mesh's own faces.

use faer::linalg::solvers::Solve;
use faer::sparse::{SparseColMat, Triplet};
use faer::{Mat, Side};
use rayon::prelude::*;
use shapespace_conformal::intrinsic::IntrinsicTriangulation;
use shapespace_geometry::quantities::vertex_dual_areas;
use shapespace_geometry::TriMesh;

use crate::error::AnalysisError;

/// Prefactored heat-method solver on one mesh (module docs).
pub struct HeatGeodesics {
    n: usize,
    /// The triangles of the operators: the mesh's faces, or those of its intrinsic Delaunay
    /// triangulation ([`HeatGeodesics::intrinsic_delaunay`]).
    faces: Vec<[u32; 3]>,
    /// The mesh's faces, which hold the point sources of [`HeatGeodesics::distances_from_points`].
    source_faces: Vec<[u32; 3]>,
    /// Per face of `faces`, the gradients of the three hat functions (3D vectors, or in the
    /// triangle's planar layout), #F.
    hat_gradients: Vec<[[f64; 3]; 3]>,
    face_areas: Vec<f64>,
    heat: faer::sparse::linalg::solvers::Llt<usize, f64>,
    poisson: faer::sparse::linalg::solvers::Llt<usize, f64>,
    /// The heat time t.
    pub time: f64,
}

fn sub(a: [f64; 3], b: [f64; 3]) -> [f64; 3] {
    [a[0] - b[0], a[1] - b[1], a[2] - b[2]]
}
fn cross(a: [f64; 3], b: [f64; 3]) -> [f64; 3] {
    [
        a[1] * b[2] - a[2] * b[1],
        a[2] * b[0] - a[0] * b[2],
        a[0] * b[1] - a[1] * b[0],
    ]
}
fn dot(a: [f64; 3], b: [f64; 3]) -> f64 {
    a[0] * b[0] + a[1] * b[1] + a[2] * b[2]
}

fn la_err(what: &str, e: impl std::fmt::Debug) -> AnalysisError {
    AnalysisError::InvalidInput(format!("heat method: {what}: {e:?}"))
}

impl HeatGeodesics {
    /// Builds the operators and factorizes M + tL and the Laplacian with vertex 0 pinned.
    /// Errors: a degenerate face (zero area), a vertex without incident area, a disconnected
    /// mesh or a failed factorization.
    pub fn new(mesh: &TriMesh) -> Result<Self, AnalysisError> {
        if mesh.num_vertices() < 3 || mesh.faces.is_empty() {
            return Err(AnalysisError::InvalidInput(
                "heat method: the mesh has no triangles".into(),
            ));
        }
        let corners: Vec<[[f64; 3]; 3]> = (0..mesh.num_faces()).map(|f| mesh.face_positions(f)).collect();
        Self::assemble(mesh, mesh.faces.clone(), &corners, None)
    }

    /// The heat method on the intrinsic Delaunay triangulation of `mesh`
    /// ([`shapespace_conformal::intrinsic`], decision 0002): the same vertices and surface, its
    /// edges flipped (lengths only) until every cotangent weight is non-negative; gradient and
    /// divergence per intrinsic triangle, laid out in the plane from its lengths; the heat time
    /// from the mesh's own mean edge length. On meshes with needle triangles (the Sumner horse
    /// poses: angles down to 0.01°) the plain cotangent operators gave a field from one landmark
    /// whose largest value was 0.1 √area where the surface's extent is 1.3–1.5 √area; this
    /// one does not depend on the triangulation that way (Sharp, Soliman & Crane 2019,
    /// "Navigating intrinsic triangulations", §5). Point sources still lie in the mesh's faces.
    /// Errors: those of [`HeatGeodesics::new`] and a degenerate face or a flip budget exceeded
    /// in the intrinsic triangulation.
    pub fn intrinsic_delaunay(mesh: &TriMesh) -> Result<Self, AnalysisError> {
        if mesh.num_vertices() < 3 || mesh.faces.is_empty() {
            return Err(AnalysisError::InvalidInput(
                "heat method: the mesh has no triangles".into(),
            ));
        }
        let idt_err = |e: shapespace_conformal::ConformalError| {
            AnalysisError::InvalidInput(format!("heat method: intrinsic Delaunay triangulation: {e}"))
        };
        let mut idt = IntrinsicTriangulation::from_mesh(mesh).map_err(idt_err)?;
        idt.make_delaunay().map_err(idt_err)?;
        let mut edge_sum = 0.0;
        for f in 0..mesh.num_faces() {
            let p = mesh.face_positions(f);
            for k in 0..3 {
                edge_sum += dot(sub(p[(k + 1) % 3], p[k]), sub(p[(k + 1) % 3], p[k])).sqrt();
            }
        }
        let h = edge_sum / (3 * mesh.num_faces()) as f64;
        let faces: Vec<[u32; 3]> = (0..idt.num_faces())
            .map(|f| [idt.tail[3 * f], idt.tail[3 * f + 1], idt.tail[3 * f + 2]])
            .collect();
        // corner 0 at the origin, corner 1 on the x axis, corner 2 above it (counter-clockwise)
        let corners: Vec<[[f64; 3]; 3]> = (0..idt.num_faces())
            .map(|f| {
                let (l0, l1, l2) = (idt.length[3 * f], idt.length[3 * f + 1], idt.length[3 * f + 2]);
                let x = (l0 * l0 + l2 * l2 - l1 * l1) / (2.0 * l0);
                let y = (l2 * l2 - x * x).max(0.0).sqrt();
                [[0.0, 0.0, 0.0], [l0, 0.0, 0.0], [x, y, 0.0]]
            })
            .collect();
        Self::assemble(mesh, faces, &corners, Some(h))
    }

    /// The operators of the triangles `faces` with corner positions `corners` (3D, or a planar
    /// layout of each) and t = h². `mean_edge` = None: the mesh's own faces, h their mean edge
    /// length, the mesh's barycentric masses; Some(h): the masses lumped from `faces`.
    fn assemble(
        mesh: &TriMesh,
        faces: Vec<[u32; 3]>,
        corners: &[[[f64; 3]; 3]],
        mean_edge: Option<f64>,
    ) -> Result<Self, AnalysisError> {
        let n = mesh.num_vertices();
        let mut hat_gradients = Vec::with_capacity(faces.len());
        let mut face_areas = Vec::with_capacity(faces.len());
        let mut edge_sum = 0.0;
        let mut trip_l: Vec<(usize, usize, f64)> = Vec::with_capacity(9 * faces.len());
        let mut lumped = vec![0.0; n];
        for (fi, (f, p)) in faces.iter().zip(corners).enumerate() {
            let nrm = cross(sub(p[1], p[0]), sub(p[2], p[0]));
            let a2 = dot(nrm, nrm).sqrt();
            if !(a2 > 0.0) || !a2.is_finite() {
                return Err(AnalysisError::InvalidInput(format!(
                    "heat method: face {fi} is degenerate (zero area)"
                )));
            }
            let unit = [nrm[0] / a2, nrm[1] / a2, nrm[2] / a2];
            let mut g = [[0.0; 3]; 3];
            for k in 0..3 {
                // ∇φ_k = N × e_k / (2A), e_k the edge opposite corner k, counter-clockwise
                let e = sub(p[(k + 2) % 3], p[(k + 1) % 3]);
                let c = cross(unit, e);
                g[k] = [c[0] / a2, c[1] / a2, c[2] / a2];
                edge_sum += dot(e, e).sqrt();
            }
            let area = 0.5 * a2;
            for i in 0..3 {
                lumped[f[i] as usize] += area / 3.0;
                for j in 0..3 {
                    trip_l.push((f[i] as usize, f[j] as usize, area * dot(g[i], g[j])));
                }
            }
            hat_gradients.push(g);
            face_areas.push(area);
        }
        // the mesh's own faces: its barycentric masses as they always were
        let (h, mass) = match mean_edge {
            Some(h) => (h, lumped),
            None => (edge_sum / (3 * faces.len()) as f64, vertex_dual_areas(mesh)),
        };
        let time = h * h;
        if let Some(i) = mass.iter().position(|m| !(*m > 0.0)) {
            return Err(AnalysisError::InvalidInput(format!(
                "heat method: vertex {i} has no incident triangle"
            )));
        }
        let mut heat_trip: Vec<Triplet<usize, usize, f64>> =
            trip_l.iter().map(|&(i, j, w)| Triplet::new(i, j, time * w)).collect();
        heat_trip.extend(mass.iter().enumerate().map(|(i, &m)| Triplet::new(i, i, m)));
        let a = SparseColMat::try_new_from_triplets(n, n, &heat_trip).map_err(|e| la_err("assembling M + tL", e))?;
        let heat = a
            .sp_cholesky(Side::Lower)
            .map_err(|e| la_err("Cholesky of M + tL", e))?;
        // Laplacian with vertex 0 removed (its value pinned to 0)
        let pin_trip: Vec<Triplet<usize, usize, f64>> = trip_l
            .iter()
            .filter(|&&(i, j, _)| i != 0 && j != 0)
            .map(|&(i, j, w)| Triplet::new(i - 1, j - 1, w))
            .collect();
        let lp = SparseColMat::try_new_from_triplets(n - 1, n - 1, &pin_trip).map_err(|e| la_err("assembling L", e))?;
        let poisson = lp
            .sp_cholesky(Side::Lower)
            .map_err(|e| la_err("Cholesky of the pinned Laplacian (is the mesh connected?)", e))?;
        Ok(HeatGeodesics {
            n,
            faces,
            source_faces: mesh.faces.clone(),
            hat_gradients,
            face_areas,
            heat,
            poisson,
            time,
        })
    }

    /// Number of vertices.
    pub fn num_vertices(&self) -> usize {
        self.n
    }

    /// Geodesic distances (#V each, mesh length units, 0 at the source) from each source vertex
    /// in `sources`; one `Vec` per source, in order. Errors on a source out of range.
    pub fn distances(&self, sources: &[u32]) -> Result<Vec<Vec<f64>>, AnalysisError> {
        if let Some(&s) = sources.iter().find(|&&s| s as usize >= self.n) {
            return Err(AnalysisError::InvalidInput(format!(
                "heat method: source {s} out of range (#V = {})",
                self.n
            )));
        }
        let weighted: Vec<[(usize, f64); 3]> = sources
            .iter()
            .map(|&s| [(s as usize, 1.0), (s as usize, 0.0), (s as usize, 0.0)])
            .collect();
        Ok(self.distances_weighted(&weighted))
    }

    /// Geodesic distances (#V each, mesh length units) from points inside faces: `sources` holds
    /// (face, barycentric coordinates) pairs. The heat source is the point's delta spread over
    /// the face's corners by its barycentric weights, and each field is shifted to 0 at the point
    /// (its linear interpolation there); a point at a corner gives that vertex's field exactly.
    /// Errors on a face out of range or coordinates that are not finite.
    pub fn distances_from_points(&self, sources: &[(u32, [f64; 3])]) -> Result<Vec<Vec<f64>>, AnalysisError> {
        let mut weighted = Vec::with_capacity(sources.len());
        for &(face, bary) in sources {
            let f = self.source_faces.get(face as usize).ok_or_else(|| {
                AnalysisError::InvalidInput(format!(
                    "heat method: source face {face} out of range (#F = {})",
                    self.source_faces.len()
                ))
            })?;
            if !bary.iter().all(|b| b.is_finite()) {
                return Err(AnalysisError::InvalidInput(format!(
                    "heat method: source in face {face} has coordinates {bary:?}"
                )));
            }
            weighted.push([0, 1, 2].map(|k| (f[k] as usize, bary[k])));
        }
        Ok(self.distances_weighted(&weighted))
    }

    fn distances_weighted(&self, sources: &[[(usize, f64); 3]]) -> Vec<Vec<f64>> {
        let mut out = Vec::with_capacity(sources.len());
        for chunk in sources.chunks(32) {
            out.extend(self.distances_batch(chunk));
        }
        out
    }

    fn distances_batch(&self, sources: &[[(usize, f64); 3]]) -> Vec<Vec<f64>> {
        let n = self.n;
        let k = sources.len();
        let mut u = Mat::<f64>::zeros(n, k);
        for (c, s) in sources.iter().enumerate() {
            for &(v, w) in s {
                u[(v, c)] += w;
            }
        }
        self.heat.solve_in_place(u.as_mut());
        let columns: Vec<Vec<f64>> = (0..k)
            .into_par_iter()
            .map(|c| {
                let mut rhs = vec![0.0; n];
                for (fi, f) in self.faces.iter().enumerate() {
                    let g = &self.hat_gradients[fi];
                    let mut grad = [0.0; 3];
                    for i in 0..3 {
                        let ui = u[(f[i] as usize, c)];
                        for d in 0..3 {
                            grad[d] += ui * g[i][d];
                        }
                    }
                    let len = dot(grad, grad).sqrt();
                    if !(len > 0.0) || !len.is_finite() {
                        continue;
                    }
                    let x = [-grad[0] / len, -grad[1] / len, -grad[2] / len];
                    let a = self.face_areas[fi];
                    for i in 0..3 {
                        rhs[f[i] as usize] += a * dot(g[i], x);
                    }
                }
                rhs
            })
            .collect();
        let mut b = Mat::<f64>::from_fn(n - 1, k, |i, c| columns[c][i + 1]);
        self.poisson.solve_in_place(b.as_mut());
        sources
            .iter()
            .enumerate()
            .map(|(c, s)| {
                let mut phi = Vec::with_capacity(n);
                phi.push(0.0);
                phi.extend((0..n - 1).map(|i| b[(i, c)]));
                let shift: f64 = s.iter().map(|&(v, w)| w * phi[v]).sum();
                phi.iter_mut().for_each(|x| *x -= shift);
                phi
            })
            .collect()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A regular triangulated square grid [0,1]² with m×m cells.
    fn grid(m: usize) -> TriMesh {
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
                // alternate diagonals so the grid has no preferred direction
                if (i + j) % 2 == 0 {
                    f.push([idx(i, j), idx(i + 1, j), idx(i + 1, j + 1)]);
                    f.push([idx(i, j), idx(i + 1, j + 1), idx(i, j + 1)]);
                } else {
                    f.push([idx(i, j), idx(i + 1, j), idx(i, j + 1)]);
                    f.push([idx(i + 1, j), idx(i + 1, j + 1), idx(i, j + 1)]);
                }
            }
        }
        TriMesh::new(p, f).unwrap()
    }

    fn max_rel_error(m: usize) -> f64 {
        let mesh = grid(m);
        centre_error(&HeatGeodesics::new(&mesh).unwrap(), &mesh, m)
    }

    #[test]
    fn flat_grid_distances_are_euclidean_and_converge() {
        let e20 = max_rel_error(20);
        let e40 = max_rel_error(40);
        // measured: a few percent, decreasing under refinement
        assert!(e40 < 0.05, "relative error {e40} on the 40x40 grid");
        assert!(e40 < e20, "no convergence: {e20} -> {e40}");
    }

    /// Largest relative error (beyond 0.25) of the distances from a point inside a face near the
    /// centre of the m × m grid, against the Euclidean distances from that point.
    fn max_rel_error_from_point(m: usize) -> f64 {
        let mesh = grid(m);
        let heat = HeatGeodesics::new(&mesh).unwrap();
        let s = (m / 2 * (m + 1) + m / 2) as u32;
        let face = mesh.faces.iter().position(|f| f[0] == s).unwrap() as u32;
        let bary = [0.2, 0.3, 0.5];
        let d = &heat.distances_from_points(&[(face, bary)]).unwrap()[0];
        let c = crate::registration::at_surface_point(&mesh.faces, &mesh.positions, (face, bary));
        worst_relative_error(&mesh.positions, d, c)
    }

    #[test]
    fn distances_from_a_point_in_a_face_converge_and_a_corner_is_its_vertex() {
        let (e20, e40) = (max_rel_error_from_point(20), max_rel_error_from_point(40));
        // measured 0.130 / 0.069 / 0.042 at 20 / 40 / 80 cells (a vertex source: 0.058 / 0.037 /
        // 0.025): the delta spread over the corners is a wider source than one vertex's
        assert!(e40 < 0.075, "relative error {e40} on the 40x40 grid");
        assert!(e40 < 0.6 * e20, "no convergence: {e20} -> {e40}");
        let mesh = grid(10);
        let heat = HeatGeodesics::new(&mesh).unwrap();
        let f = mesh.faces[37];
        let at_corner = &heat.distances_from_points(&[(37, [0.0, 1.0, 0.0])]).unwrap()[0];
        assert_eq!(at_corner, &heat.distances(&[f[1]]).unwrap()[0]);
        assert!(heat
            .distances_from_points(&[(mesh.faces.len() as u32, [1.0, 0.0, 0.0])])
            .is_err());
        assert!(heat.distances_from_points(&[(0, [f64::NAN, 0.0, 1.0])]).is_err());
    }

    /// The m × m grid with a vertex `offset` (of the cell size) off the midpoint of every cell's
    /// diagonal, inside the lower triangle, which it splits into three: one of them a needle
    /// along the diagonal, its angle at the new vertex near 180° (cotangent near −1/(4 offset)).
    fn needle_grid(m: usize, offset: f64) -> TriMesh {
        let h = 1.0 / m as f64;
        let mut p = Vec::new();
        for j in 0..=m {
            for i in 0..=m {
                p.push([i as f64 * h, j as f64 * h, 0.0]);
            }
        }
        let idx = |i: usize, j: usize| (j * (m + 1) + i) as u32;
        let mut f = Vec::new();
        for j in 0..m {
            for i in 0..m {
                let c = p.len() as u32;
                // off the diagonal (i, j)–(i+1, j+1), towards (i+1, j)
                p.push([(i as f64 + 0.5 + offset) * h, (j as f64 + 0.5 - offset) * h, 0.0]);
                let (a, b, d, e) = (idx(i, j), idx(i + 1, j), idx(i + 1, j + 1), idx(i, j + 1));
                f.extend([[a, b, c], [b, d, c], [d, a, c], [a, d, e]]);
            }
        }
        TriMesh::new(p, f).unwrap()
    }

    /// Largest relative error of the distances `d` against the planar distance from `c`, over
    /// the vertices farther than 0.25 from it.
    fn worst_relative_error(positions: &[[f64; 3]], d: &[f64], c: [f64; 3]) -> f64 {
        let mut worst = 0.0f64;
        for (v, p) in positions.iter().enumerate() {
            let exact = (p[0] - c[0]).hypot(p[1] - c[1]);
            if exact > 0.25 {
                worst = worst.max((d[v] - exact).abs() / exact);
            }
        }
        worst
    }

    /// Largest relative error (beyond 0.25) of the field from the grid's centre vertex.
    fn centre_error(heat: &HeatGeodesics, mesh: &TriMesh, m: usize) -> f64 {
        let s = (m / 2 * (m + 1) + m / 2) as u32;
        let d = &heat.distances(&[s]).unwrap()[0];
        let c = mesh.positions[s as usize];
        worst_relative_error(&mesh.positions, d, c)
    }

    #[test]
    fn intrinsic_delaunay_heat_method_survives_needle_triangles() {
        let m = 20;
        let mesh = needle_grid(m, 1e-4);
        let plain = centre_error(&HeatGeodesics::new(&mesh).unwrap(), &mesh, m);
        let idt = centre_error(&HeatGeodesics::intrinsic_delaunay(&mesh).unwrap(), &mesh, m);
        assert!(idt < 0.05, "intrinsic Delaunay: relative error {idt}");
        assert!(
            idt < 0.6 * plain,
            "intrinsic Delaunay {idt} against plain cotangents {plain}"
        );
        // on a triangulation that is already Delaunay no edge flips: the same operators and
        // fields up to the planar layout's roundoff
        let g = grid(16);
        let (a, b) = (
            HeatGeodesics::new(&g).unwrap(),
            HeatGeodesics::intrinsic_delaunay(&g).unwrap(),
        );
        assert!((a.time - b.time).abs() < 1e-15);
        let (da, db) = (&a.distances(&[100]).unwrap()[0], &b.distances(&[100]).unwrap()[0]);
        let gap = da.iter().zip(db).map(|(x, y)| (x - y).abs()).fold(0.0, f64::max);
        assert!(gap < 1e-10, "grid fields differ by {gap}");
    }

    #[test]
    fn sphere_distances_follow_great_circles() {
        let mesh = shapespace_geometry::primitives::icosphere(4);
        let heat = HeatGeodesics::new(&mesh).unwrap();
        let d = &heat.distances(&[0]).unwrap()[0];
        let p0 = mesh.positions[0];
        let mut worst = 0.0f64;
        for (v, p) in mesh.positions.iter().enumerate() {
            let r = dot(*p, *p).sqrt() * dot(p0, p0).sqrt();
            let exact = (dot(*p, p0) / r).clamp(-1.0, 1.0).acos();
            if exact > 0.3 {
                worst = worst.max((d[v] - exact).abs() / exact);
            }
        }
        assert!(worst < 0.05, "relative error {worst} on the sphere");
        assert!(heat.distances(&[u32::MAX]).is_err());
    }
}
