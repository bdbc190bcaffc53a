//! Sparse symmetric positive definite solves with faer's sparse Cholesky (AMD ordering, or an
//! elimination order given by the caller).

use faer::dyn_stack::{MemBuffer, MemStack};
use faer::perm::PermRef;
use faer::sparse::linalg::cholesky::{factorize_symbolic_cholesky, LltRef, SymbolicCholesky, SymmetricOrdering};
use faer::sparse::{SparseColMat, Triplet};
use faer::{Conj, Mat, Side};

use crate::error::ConformalError;
use crate::intrinsic::IntrinsicTriangulation;

/// A factorized SPD matrix, reusable for several right-hand sides.
pub struct SpdSolver {
    symbolic: SymbolicCholesky<usize>,
    values: Vec<f64>,
    n: usize,
}

impl SpdSolver {
    /// Factorizes the n × n matrix given by (row, col, value) triplets (duplicates summed), in
    /// an AMD ordering. Only the lower triangle is read: give each off-diagonal entry once, with
    /// row > col.
    pub fn new(n: usize, triplets: &[Triplet<usize, usize, f64>], what: &str) -> Result<Self, ConformalError> {
        Self::with_order(n, triplets, None, what)
    }

    /// [`SpdSolver::new`] eliminating the unknowns in the order `order` (a permutation of
    /// 0..n) when given, instead of computing an AMD ordering: the restriction of a whole
    /// mesh's ordering to a part of it keeps most of its quality at none of its cost.
    pub fn with_order(
        n: usize,
        triplets: &[Triplet<usize, usize, f64>],
        order: Option<&[usize]>,
        what: &str,
    ) -> Result<Self, ConformalError> {
        let err = |stage: &str, e: &dyn std::fmt::Debug| {
            ConformalError::LinearAlgebra(format!(
                "{stage} of {what} ({n} unknowns): {e:?} (is every component anchored?)"
            ))
        };
        let a = SparseColMat::try_new_from_triplets(n, n, triplets)
            .map_err(|e| ConformalError::LinearAlgebra(format!("assembling {what}: {e:?}")))?;
        let inverse: Vec<usize>;
        let ordering = match order {
            Some(forward) => {
                let mut inv = vec![usize::MAX; n];
                for (k, &i) in forward.iter().enumerate() {
                    if i >= n || inv[i] != usize::MAX {
                        return Err(ConformalError::LinearAlgebra(format!(
                            "ordering of {what}: not a permutation of {n} unknowns"
                        )));
                    }
                    inv[i] = k;
                }
                if forward.len() != n {
                    return Err(ConformalError::LinearAlgebra(format!(
                        "ordering of {what}: {} entries for {n} unknowns",
                        forward.len()
                    )));
                }
                inverse = inv;
                SymmetricOrdering::Custom(PermRef::new_checked(forward, &inverse, n))
            }
            None => SymmetricOrdering::Amd,
        };
        // (the calls of faer's `sp_cholesky`, with the ordering exposed)
        let symbolic = factorize_symbolic_cholesky(a.symbolic(), Side::Lower, ordering, Default::default())
            .map_err(|e| err("symbolic Cholesky", &e))?;
        let mut values = vec![0.0; symbolic.len_val()];
        let par = faer::get_global_parallelism();
        let mut buffer = MemBuffer::try_new(symbolic.factorize_numeric_llt_scratch::<f64>(par, Default::default()))
            .map_err(|e| err("Cholesky scratch", &e))?;
        symbolic
            .factorize_numeric_llt::<f64>(
                &mut values,
                a.as_ref(),
                Side::Lower,
                Default::default(),
                par,
                MemStack::new(&mut buffer),
                Default::default(),
            )
            .map_err(|e| err("Cholesky", &e))?;
        Ok(SpdSolver { symbolic, values, n })
    }

    /// The elimination order: the unknowns in the order the factorization eliminates them.
    pub fn elimination_order(&self) -> Vec<usize> {
        match self.symbolic.perm() {
            Some(p) => p.arrays().0.to_vec(),
            None => (0..self.n).collect(),
        }
    }

    /// Solves A X = B for the columns of `rhs` (each of length n), in place.
    pub fn solve(&self, rhs: &mut [Vec<f64>]) {
        let mut b = Mat::<f64>::from_fn(self.n, rhs.len(), |i, j| rhs[j][i]);
        let par = faer::get_global_parallelism();
        let mut buffer = MemBuffer::new(self.symbolic.solve_in_place_scratch::<f64>(rhs.len(), par));
        LltRef::<'_, usize, f64>::new(&self.symbolic, &self.values).solve_in_place_with_conj(
            Conj::No,
            b.as_mut(),
            par,
            MemStack::new(&mut buffer),
        );
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
    restricted_laplacian_in_order(tri, index, m, None, what)
}

/// [`restricted_laplacian`] eliminating the unknowns in `order` when given
/// ([`SpdSolver::with_order`]).
pub(crate) fn restricted_laplacian_in_order(
    tri: &IntrinsicTriangulation,
    index: &[u32],
    m: usize,
    order: Option<&[usize]>,
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
    Ok((SpdSolver::with_order(m, &trip, order, what)?, coupling))
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The 5-point Laplacian of a k × k grid plus 0.1 on the diagonal (lower triangle).
    fn grid(k: usize) -> Vec<Triplet<usize, usize, f64>> {
        let mut t = Vec::new();
        for i in 0..k {
            for j in 0..k {
                let v = i * k + j;
                t.push(Triplet::new(v, v, 4.1));
                if i > 0 {
                    t.push(Triplet::new(v, v - k, -1.0));
                }
                if j > 0 {
                    t.push(Triplet::new(v, v - 1, -1.0));
                }
            }
        }
        t
    }

    fn residual(t: &[Triplet<usize, usize, f64>], x: &[f64], b: &[f64]) -> f64 {
        let mut r: Vec<f64> = b.iter().map(|v| -v).collect();
        for e in t {
            r[e.row] += e.val * x[e.col];
            if e.row != e.col {
                r[e.col] += e.val * x[e.row];
            }
        }
        r.iter().fold(0.0, |m, v| m.max(v.abs()))
    }

    #[test]
    fn a_given_order_solves_the_same_system() {
        let k = 20;
        let n = k * k;
        let t = grid(k);
        let b: Vec<f64> = (0..n).map(|i| ((i * 7919) % 101) as f64 / 101.0 - 0.5).collect();
        let amd = SpdSolver::new(n, &t, "grid").unwrap();
        let mut x_amd = vec![b.clone()];
        amd.solve(&mut x_amd);
        // the AMD order itself, its reverse and a scrambled order
        let order = amd.elimination_order();
        let mut sorted = order.clone();
        sorted.sort_unstable();
        assert_eq!(sorted, (0..n).collect::<Vec<_>>());
        let reversed: Vec<usize> = order.iter().rev().copied().collect();
        let scrambled: Vec<usize> = (0..n).map(|i| (i * 37) % n).collect();
        for order in [order, reversed, scrambled] {
            let s = SpdSolver::with_order(n, &t, Some(&order), "grid").unwrap();
            assert_eq!(s.elimination_order(), order);
            let mut x = vec![b.clone()];
            s.solve(&mut x);
            assert!(residual(&t, &x[0], &b) < 1e-13, "{}", residual(&t, &x[0], &b));
            let diff = x[0]
                .iter()
                .zip(&x_amd[0])
                .fold(0.0f64, |m, (p, q)| m.max((p - q).abs()));
            assert!(diff < 1e-13, "{diff}");
        }
    }

    #[test]
    fn an_order_that_is_not_a_permutation_is_an_error() {
        let t = grid(3);
        for order in [
            vec![0, 1, 2, 3, 4, 5, 6, 7, 7],
            vec![0, 1, 2],
            vec![0, 1, 2, 3, 4, 5, 6, 7, 9],
        ] {
            let e = SpdSolver::with_order(9, &t, Some(&order), "grid")
                .err()
                .expect("an error");
            assert!(e.to_string().contains("grid"), "{e}");
        }
    }
}
