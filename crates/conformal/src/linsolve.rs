//! Sparse symmetric positive definite solves with faer's sparse Cholesky (AMD ordering).

use faer::linalg::solvers::Solve;
use faer::sparse::{SparseColMat, Triplet};
use faer::{Mat, Side};

use crate::error::ConformalError;

/// A factorized SPD matrix, reusable for several right-hand sides.
pub struct SpdSolver {
    llt: faer::sparse::linalg::solvers::Llt<usize, f64>,
    n: usize,
}

impl SpdSolver {
    /// Factorizes the n × n matrix given by (row, col, value) triplets (duplicates summed).
    /// Only the lower triangle is read: give each off-diagonal entry once, with row > col.
    pub fn new(n: usize, triplets: &[Triplet<usize, usize, f64>], what: &str) -> Result<Self, ConformalError> {
        let a = SparseColMat::try_new_from_triplets(n, n, triplets)
            .map_err(|e| ConformalError::LinearAlgebra(format!("assembling {what}: {e:?}")))?;
        let llt = a.sp_cholesky(Side::Lower).map_err(|e| {
            ConformalError::LinearAlgebra(format!(
                "Cholesky of {what} ({n} unknowns): {e:?} (is every component anchored?)"
            ))
        })?;
        Ok(SpdSolver { llt, n })
    }

    /// Solves A X = B for the columns of `rhs` (each of length n), in place.
    pub fn solve(&self, rhs: &mut [Vec<f64>]) {
        let mut b = Mat::<f64>::from_fn(self.n, rhs.len(), |i, j| rhs[j][i]);
        self.llt.solve_in_place(b.as_mut());
        for (j, col) in rhs.iter_mut().enumerate() {
            for (i, x) in col.iter_mut().enumerate() {
                *x = b[(i, j)];
            }
        }
    }
}
