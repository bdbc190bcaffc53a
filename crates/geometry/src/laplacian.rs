//! The cotangent Laplacian and the lumped mass matrix as faer sparse matrices.
//!
//! Convention (positive semidefinite, as in geometry-central): for a function u on vertices,
//! $$ (L u)_i = \sum_{j \sim i} w_{ij} (u_i - u_j), \qquad w_{ij} = \tfrac12(\cot\alpha_{ij} + \cot\beta_{ij}), $$
//! with α, β the angles opposite edge ij [Pinkall & Polthier 1993]. Constants are in its kernel;
//! a harmonic function has L u = 0 at interior vertices. The mass matrix is diagonal with the
//! barycentric vertex areas, so $M^{-1} L$ approximates −Δ.

use faer::sparse::{SparseColMat, Triplet};

use crate::error::GeometryError;
use crate::mesh::TriMesh;
use crate::quantities::{corner_cotangents, vertex_dual_areas};

/// Half-cotangent weight of each directed corner: for face f and corner k, the weight
/// ½ cot θ_k that belongs to the edge opposite corner k, i.e. (`faces[f][k+1]`, `faces[f][k+2]`).
pub fn edge_cotan_triplets(mesh: &TriMesh) -> Vec<(u32, u32, f64)> {
    let cots = corner_cotangents(mesh);
    let mut out = Vec::with_capacity(3 * mesh.num_faces());
    for (face, cot) in mesh.faces.iter().zip(&cots) {
        for k in 0..3 {
            out.push((face[(k + 1) % 3], face[(k + 2) % 3], 0.5 * cot[k]));
        }
    }
    out
}

/// Builds the Laplacian from per-edge weights given as (i, j, w) triplets (duplicates summed):
/// L_ij = −w, L_ii = Σ_j w. #V × #V, symmetric.
pub fn laplacian_from_weights(
    num_vertices: usize,
    weights: &[(u32, u32, f64)],
) -> Result<SparseColMat<usize, f64>, GeometryError> {
    let mut trip = Vec::with_capacity(4 * weights.len());
    for &(i, j, w) in weights {
        let (i, j) = (i as usize, j as usize);
        trip.push(Triplet::new(i, j, -w));
        trip.push(Triplet::new(j, i, -w));
        trip.push(Triplet::new(i, i, w));
        trip.push(Triplet::new(j, j, w));
    }
    SparseColMat::try_new_from_triplets(num_vertices, num_vertices, &trip)
        .map_err(|e| GeometryError::LinearAlgebra(format!("building the Laplacian: {e:?}")))
}

/// The cotangent Laplacian L (#V × #V, positive semidefinite, see the module docs).
pub fn cotan_laplacian(mesh: &TriMesh) -> Result<SparseColMat<usize, f64>, GeometryError> {
    laplacian_from_weights(mesh.num_vertices(), &edge_cotan_triplets(mesh))
}

/// The lumped (barycentric) mass matrix M, #V × #V diagonal, M_ii = one third of the one-ring area.
pub fn mass_matrix(mesh: &TriMesh) -> Result<SparseColMat<usize, f64>, GeometryError> {
    let areas = vertex_dual_areas(mesh);
    let trip: Vec<_> = areas.iter().enumerate().map(|(i, &a)| Triplet::new(i, i, a)).collect();
    SparseColMat::try_new_from_triplets(areas.len(), areas.len(), &trip)
        .map_err(|e| GeometryError::LinearAlgebra(format!("building the mass matrix: {e:?}")))
}

/// Sparse matrix–vector product y = A x for a column-major sparse matrix.
pub fn sparse_mul_vec(a: &SparseColMat<usize, f64>, x: &[f64]) -> Vec<f64> {
    let mut y = vec![0.0; a.nrows()];
    let a = a.as_ref();
    for j in 0..a.ncols() {
        let xj = x[j];
        for (i, v) in a.row_idx_of_col(j).zip(a.val_of_col(j)) {
            y[i] += v * xj;
        }
    }
    y
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn constants_in_kernel_and_symmetric() {
        let m = TriMesh::new(
            vec![[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [1.0, 1.0, 0.3], [0.0, 1.0, 0.0]],
            vec![[0, 1, 2], [0, 2, 3]],
        )
        .unwrap();
        let l = cotan_laplacian(&m).unwrap();
        let y = sparse_mul_vec(&l, &[1.0; 4]);
        assert!(y.iter().all(|v| v.abs() < 1e-14));
        let d = l.to_dense();
        for i in 0..4 {
            for j in 0..4 {
                assert!((d[(i, j)] - d[(j, i)]).abs() < 1e-14);
            }
        }
    }
}
