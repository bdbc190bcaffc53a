//! Sparse symmetric positive definite solves with faer's sparse Cholesky (AMD ordering).

use faer::linalg::solvers::Solve;
use faer::sparse::{SparseColMat, Triplet};
use faer::{Mat, Side};

use crate::error::ConformalError;
use crate::intrinsic::IntrinsicTriangulation;

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

/// A one-thread rayon pool: faer's sparse triangular solves run with the global parallelism,
/// and on a loaded 2-core machine their parallel version took 0.3–0.8 s per solve of a
/// 130k-unknown chart where the sequential one took 0.07 s (`crates/tools/benches/sphere_map_bench.rs`).
fn sequential_pool() -> Option<&'static rayon::ThreadPool> {
    static POOL: std::sync::OnceLock<Option<rayon::ThreadPool>> = std::sync::OnceLock::new();
    POOL.get_or_init(|| rayon::ThreadPoolBuilder::new().num_threads(1).build().ok())
        .as_ref()
}

impl SpdSolver {
    /// [`SpdSolver::solve`] on one thread (see `sequential_pool`).
    pub fn solve_sequential(&self, rhs: &mut [Vec<f64>]) {
        match sequential_pool() {
            Some(pool) => pool.install(|| self.solve(rhs)),
            None => self.solve(rhs),
        }
    }
}

/// A matrix row's coupling to an excluded vertex: (row, vertex, w), the entry being −w.
pub(crate) type Coupling = (u32, u32, f64);

/// Factorizes the cotangent Laplacian of `tri` restricted to the vertices with
/// `index[v] != u32::MAX` (m of them). Returns the solver and the couplings (row, excluded
/// vertex, w) of the rows to the excluded vertices (L_row,v = −w).
pub(crate) fn restricted_laplacian(
    tri: &IntrinsicTriangulation,
    index: &[u32],
    m: usize,
    what: &str,
) -> Result<(SpdSolver, Vec<Coupling>), ConformalError> {
    let mut diag = vec![0.0; m];
    let mut trip = Vec::with_capacity(tri.tail.len() + m);
    let mut coupling = Vec::new();
    for (i, j, w) in tri.half_cotan_triplets() {
        if i == j {
            continue;
        }
        let (ii, jj) = (index[i as usize], index[j as usize]);
        if ii != u32::MAX {
            diag[ii as usize] += w;
        }
        if jj != u32::MAX {
            diag[jj as usize] += w;
        }
        match (ii != u32::MAX, jj != u32::MAX) {
            (true, true) => {
                let (r, c) = if ii > jj { (ii, jj) } else { (jj, ii) };
                trip.push(Triplet::new(r as usize, c as usize, -w));
            }
            (true, false) => coupling.push((ii, j, w)),
            (false, true) => coupling.push((jj, i, w)),
            (false, false) => {}
        }
    }
    trip.extend(diag.iter().enumerate().map(|(i, &d)| Triplet::new(i, i, d)));
    Ok((SpdSolver::new(m, &trip, what)?, coupling))
}
