//! The smallest eigenpairs of the Laplace–Beltrami operator: the generalized symmetric problem
//! $$ L \varphi = \lambda M \varphi, \qquad \varphi^\top M \varphi = 1, $$
//! with L the cotangent stiffness matrix and M the lumped (diagonal) mass matrix of
//! [`crate::laplacian`] (on a disk these are the Neumann eigenpairs: the free boundary is the
//! natural condition of the P1 stiffness matrix).
//!
//! Method: shift-invert block Lanczos with full reorthogonalization [Ericsson & Ruhe 1980,
//! "The spectral transformation Lanczos method"; Golub & Van Loan, §10.3]. With a small shift
//! σ < 0 the matrix L − σM is positive definite (L is only semidefinite: constants are in its
//! kernel) and is factored once by sparse Cholesky (faer, AMD ordering). The operator
//! $$ A = (L - \sigma M)^{-1} M $$
//! is self-adjoint in the M-inner product, with the same eigenvectors and eigenvalues
//! θ = 1/(λ − σ): the smallest λ become the largest, best separated θ. A Krylov basis Q of
//! blocks of `block_size` random start vectors is grown with each new block M-orthogonalized
//! twice against all previous ones (classical Gram–Schmidt, twice, as dense products); the
//! Rayleigh–Ritz matrix H = Qᵀ M A Q is accumulated from the stored products A Q, its
//! eigenvectors give Ritz pairs, and the iteration stops when every one of the k wanted pairs
//! has relative residual ‖A y − θ y‖_M / θ ≤ `tolerance`. Blocks (rather than one start
//! vector) find eigenvalues of multiplicity up to `block_size` (a sphere's l(l+1), 2l+1 times).
//! No restart: the basis holds at most `max_basis` vectors (2 × #V × max_basis doubles).

use faer::linalg::matmul::matmul;
use faer::linalg::solvers::Solve;
use faer::sparse::linalg::solvers::{Llt, SymbolicLlt};
use faer::sparse::{SparseColMat, Triplet};
use faer::{Accum, Mat, MatRef, Par};

use crate::error::GeometryError;
use crate::laplacian::cotan_laplacian;
use crate::mesh::TriMesh;
use crate::quantities::vertex_dual_areas;

/// Parameters of [`generalized_eigenpairs`].
#[derive(Clone, Debug, PartialEq)]
pub struct EigenParams {
    /// Vectors per Krylov block: the largest eigenvalue multiplicity found reliably (default 8).
    pub block_size: usize,
    /// Relative residual ‖A y − θ y‖_M / θ every returned pair reaches (default 1e-8; the
    /// eigenvalue errors are of its square).
    pub tolerance: f64,
    /// Largest Krylov basis (columns); `None`: max(8k, k + 16·block_size), at most #V.
    pub max_basis: Option<usize>,
    /// σ = −shift_factor · tr(L)/tr(M) (default 1e-6: far below the first nonzero eigenvalue of
    /// any reasonable mesh, far above roundoff).
    pub shift_factor: f64,
    /// Seed of the random start block.
    pub seed: u64,
}

impl Default for EigenParams {
    fn default() -> Self {
        EigenParams {
            block_size: 8,
            tolerance: 1e-8,
            max_basis: None,
            shift_factor: 1e-6,
            seed: 1,
        }
    }
}

/// The k smallest eigenpairs of L φ = λ M φ.
#[derive(Clone, Debug)]
pub struct Eigenpairs {
    /// λ_0 ≤ λ_1 ≤ … ≤ λ_{k−1} (units 1/length²).
    pub values: Vec<f64>,
    /// φ_i as column i (#V × k), M-orthonormal: Φᵀ M Φ = I. Sign: the entry of largest
    /// magnitude of each column is positive.
    pub vectors: Mat<f64>,
    /// Largest relative residual ‖A y − θ y‖_M / θ of the returned pairs.
    pub max_residual: f64,
    /// Columns of the final Krylov basis (= linear solves done).
    pub basis_size: usize,
}

/// The k smallest eigenpairs of the cotangent Laplacian of `mesh` against its lumped mass
/// matrix ([`generalized_eigenpairs`] with [`cotan_laplacian`] and [`vertex_dual_areas`]).
/// Errors: a vertex with zero dual area (unreferenced or only in degenerate faces), k > #V,
/// a failed factorization or no convergence.
pub fn laplace_beltrami_eigenpairs(
    mesh: &TriMesh,
    k: usize,
    params: &EigenParams,
) -> Result<Eigenpairs, GeometryError> {
    let stiffness = cotan_laplacian(mesh)?;
    let mass = vertex_dual_areas(mesh);
    generalized_eigenpairs(&stiffness, &mass, k, params)
}

/// splitmix64 values mapped to [−1, 1).
struct Random(u64);

impl Random {
    fn next(&mut self) -> f64 {
        self.0 = self.0.wrapping_add(0x9E37_79B9_7F4A_7C15);
        let mut z = self.0;
        z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
        z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
        z ^= z >> 31;
        (z >> 11) as f64 / (1u64 << 52) as f64 - 1.0
    }
}

/// The k smallest eigenpairs of `stiffness` φ = λ diag(`mass`) φ (module docs): `stiffness`
/// symmetric positive semidefinite (#V × #V, both triangles stored), `mass` #V positive
/// entries. Errors: mismatched sizes, k = 0 or k > #V, a non-positive or non-finite mass, a
/// failed Cholesky factorization (stiffness not semidefinite), or residuals above the tolerance
/// when the basis is full ([`GeometryError::LinearAlgebra`] with the residual reached).
pub fn generalized_eigenpairs(
    stiffness: &SparseColMat<usize, f64>,
    mass: &[f64],
    k: usize,
    params: &EigenParams,
) -> Result<Eigenpairs, GeometryError> {
    let n = mass.len();
    if stiffness.nrows() != n || stiffness.ncols() != n {
        return Err(GeometryError::Invalid(format!(
            "eigenpairs: stiffness matrix {}×{} for {n} masses",
            stiffness.nrows(),
            stiffness.ncols()
        )));
    }
    if k == 0 || k > n {
        return Err(GeometryError::Invalid(format!(
            "eigenpairs: {k} eigenpairs asked of a {n}-vertex problem"
        )));
    }
    if let Some(i) = mass.iter().position(|&m| !(m > 0.0 && m.is_finite())) {
        return Err(GeometryError::Invalid(format!(
            "eigenpairs: vertex {i} has mass {} (unreferenced, or only in degenerate faces)",
            mass[i]
        )));
    }
    let b = params.block_size.clamp(1, n);
    let max_basis = params.max_basis.unwrap_or((8 * k).max(k + 16 * b)).clamp(k.min(n), n);

    // L − σM, σ = −shift_factor · tr(L)/tr(M)
    let a = stiffness.as_ref();
    let trace: f64 = (0..n)
        .map(|j| {
            a.row_idx_of_col(j)
                .zip(a.val_of_col(j))
                .filter(|(i, _)| *i == j)
                .map(|(_, v)| *v)
                .sum::<f64>()
        })
        .sum();
    let shift = params.shift_factor * trace.max(0.0) / mass.iter().sum::<f64>();
    let shift = if shift > 0.0 {
        shift
    } else {
        params.shift_factor.max(f64::MIN_POSITIVE)
    };
    let mut trip = Vec::with_capacity(a.compute_nnz() + n);
    for j in 0..n {
        for (i, v) in a.row_idx_of_col(j).zip(a.val_of_col(j)) {
            if i >= j {
                trip.push(Triplet::new(i, j, *v));
            }
        }
        trip.push(Triplet::new(j, j, shift * mass[j]));
    }
    let shifted = SparseColMat::<usize, f64>::try_new_from_triplets(n, n, &trip)
        .map_err(|e| GeometryError::LinearAlgebra(format!("eigenpairs: assembling L − σM: {e:?}")))?;
    let symbolic = SymbolicLlt::try_new(shifted.symbolic(), faer::Side::Lower)
        .map_err(|e| GeometryError::LinearAlgebra(format!("eigenpairs: symbolic Cholesky of L − σM: {e:?}")))?;
    let llt = Llt::try_new_with_symbolic(symbolic, shifted.as_ref(), faer::Side::Lower).map_err(|e| {
        GeometryError::LinearAlgebra(format!(
            "eigenpairs: Cholesky of L − σM failed ({e:?}): the stiffness matrix is not positive semidefinite"
        ))
    })?;

    let mut q = Mat::<f64>::zeros(n, max_basis); // M-orthonormal Krylov basis
    let mut h = Mat::<f64>::zeros(max_basis, max_basis); // Qᵀ M A Q
    let mut rng = Random(params.seed);
    let mut block = Mat::<f64>::from_fn(n, b, |_, _| rng.next());
    let mut m = 0; // columns of q in use
    let mut last_check = 0;
    let mut best_residual = f64::INFINITY;
    loop {
        // the next block, M-orthonormal and M-orthogonal to the basis (random refills on breakdown)
        let added = orthonormalize_block(&q, m, &mut block, mass, &mut rng);
        if added == 0 {
            break;
        }
        q.as_mut()
            .subcols_mut(m, added)
            .copy_from(block.as_ref().subcols(0, added));
        // A times the new columns: solve (L − σM) X = M Q_new
        let mut x = Mat::<f64>::from_fn(n, added, |i, j| mass[i] * q[(i, m + j)]);
        llt.solve_in_place(x.as_mut());
        // H[:, new] = Qᵀ M (A Q_new), mirrored into H[new, :]; the new × new block symmetrized
        let col = m_project(&q, m + added, x.as_ref(), mass);
        for j in 0..added {
            for i in 0..m + added {
                let v = if i >= m {
                    0.5 * (col[(i, j)] + col[(m + j, i - m)])
                } else {
                    col[(i, j)]
                };
                h[(i, m + j)] = v;
                h[(m + j, i)] = v;
            }
        }
        // remainder F = A Q_new − Q H[:, new]: A Q = Q H + F Eᵀ, so a Ritz pair (θ, Q s) has
        // residual F s_new (s_new: the entries of s on the newest block)
        matmul(
            x.as_mut(),
            Accum::Add,
            q.as_ref().subcols(0, m + added),
            col.as_ref(),
            -1.0,
            Par::rayon(0),
        );
        project_out(&q, m + added, &mut x, mass);
        let gram = m_gram(x.as_ref(), mass);
        m += added;
        block = x;
        let full = m + 1 > max_basis;
        // Rayleigh–Ritz (a dense m × m eigenproblem) from 2k columns on, then every 15 % more
        let due = if last_check == 0 {
            2 * k
        } else {
            last_check + (last_check * 3 / 20).max(2 * b)
        };
        if m >= k && (m >= due || full || m == n) {
            last_check = m;
            let ritz = ritz_pairs(&h, m, k, added, &gram)?;
            best_residual = ritz.max_residual;
            if ritz.max_residual <= params.tolerance || m == n {
                let values: Vec<f64> = ritz.theta.iter().map(|&t| (1.0 / t - shift).max(0.0)).collect();
                let mut vectors = Mat::<f64>::zeros(n, k);
                matmul(
                    vectors.as_mut(),
                    Accum::Replace,
                    q.as_ref().subcols(0, m),
                    ritz.coefficients.as_ref(),
                    1.0,
                    Par::rayon(0),
                );
                for j in 0..k {
                    // sign: the entry of largest magnitude positive
                    let c = vectors.col(j);
                    let arg = (0..n).fold(0, |a, i| if c[i].abs() > c[a].abs() { i } else { a });
                    if c[arg] < 0.0 {
                        vectors.col_mut(j).iter_mut().for_each(|v| *v = -*v);
                    }
                }
                return Ok(Eigenpairs {
                    values,
                    vectors,
                    max_residual: ritz.max_residual,
                    basis_size: m,
                });
            }
        }
        if full {
            break;
        }
    }
    Err(GeometryError::LinearAlgebra(format!(
        "eigenpairs: {k} pairs not converged with a Krylov basis of {m} vectors (relative residual {best_residual:.2e} > {:.0e}); raise max_basis",
        params.tolerance
    )))
}

/// Ritz pairs of the basis: the k largest θ (descending), their coefficients in the basis
/// (m × k) and the largest relative residual ‖F s_new‖_M / θ.
struct Ritz {
    theta: Vec<f64>,
    coefficients: Mat<f64>,
    max_residual: f64,
}

fn ritz_pairs(h: &Mat<f64>, m: usize, k: usize, last: usize, gram: &Mat<f64>) -> Result<Ritz, GeometryError> {
    let hm = h.as_ref().submatrix(0, 0, m, m).to_owned();
    let evd = hm
        .self_adjoint_eigen(faer::Side::Lower)
        .map_err(|e| GeometryError::LinearAlgebra(format!("eigenpairs: Rayleigh–Ritz matrix: {e:?}")))?;
    let s = evd.S().column_vector();
    let u = evd.U();
    // faer sorts ascending: the k largest θ are the last k columns, taken in descending order
    let order: Vec<usize> = (0..k).map(|i| m - 1 - i).collect();
    let theta: Vec<f64> = order.iter().map(|&c| s[c]).collect();
    let coefficients = Mat::<f64>::from_fn(m, k, |i, j| u[(i, order[j])]);
    let mut max_residual = 0.0f64;
    for j in 0..k {
        let tail: Vec<f64> = (0..last).map(|a| coefficients[(m - last + a, j)]).collect();
        let mut r2 = 0.0;
        for a in 0..last {
            for c in 0..last {
                r2 += tail[a] * gram[(a, c)] * tail[c];
            }
        }
        let rel = r2.max(0.0).sqrt() / theta[j].abs();
        max_residual = max_residual.max(if rel.is_finite() { rel } else { f64::INFINITY });
    }
    Ok(Ritz {
        theta,
        coefficients,
        max_residual,
    })
}

/// Qᵀ M X over the first `m` columns of `q` (m × #cols of x).
fn m_project(q: &Mat<f64>, m: usize, x: MatRef<'_, f64>, mass: &[f64]) -> Mat<f64> {
    let mx = Mat::<f64>::from_fn(x.nrows(), x.ncols(), |i, j| mass[i] * x[(i, j)]);
    let mut c = Mat::<f64>::zeros(m, x.ncols());
    matmul(
        c.as_mut(),
        Accum::Replace,
        q.as_ref().subcols(0, m).transpose(),
        mx.as_ref(),
        1.0,
        Par::rayon(0),
    );
    c
}

/// Xᵀ M X.
fn m_gram(x: MatRef<'_, f64>, mass: &[f64]) -> Mat<f64> {
    let mx = Mat::<f64>::from_fn(x.nrows(), x.ncols(), |i, j| mass[i] * x[(i, j)]);
    let mut g = Mat::<f64>::zeros(x.ncols(), x.ncols());
    matmul(
        g.as_mut(),
        Accum::Replace,
        x.transpose(),
        mx.as_ref(),
        1.0,
        Par::rayon(0),
    );
    g
}

/// X ← X − Q Qᵀ M X over the first `m` columns of `q` (one classical Gram–Schmidt pass).
fn project_out(q: &Mat<f64>, m: usize, x: &mut Mat<f64>, mass: &[f64]) {
    if m == 0 {
        return;
    }
    let c = m_project(q, m, x.as_ref(), mass);
    matmul(
        x.as_mut(),
        Accum::Add,
        q.as_ref().subcols(0, m),
        c.as_ref(),
        -1.0,
        Par::rayon(0),
    );
}

/// M-inner product of two columns.
fn m_dot(mass: &[f64], x: MatRef<'_, f64>, a: usize, y: MatRef<'_, f64>, c: usize) -> f64 {
    let (x, y) = (x.col(a), y.col(c));
    (0..mass.len()).map(|i| mass[i] * x[i] * y[i]).sum()
}

/// Makes the columns of `block` (already M-orthogonal to the first `m` columns of `q`)
/// M-orthonormal (modified Gram–Schmidt within the block, each column twice). A column that keeps less than 1e-10 of its norm lies in the span
/// already (the Krylov space is invariant there) and is replaced by a random vector. Returns
/// the number of valid leading columns (limited by the columns left in `q` and by #V).
fn orthonormalize_block(q: &Mat<f64>, m: usize, block: &mut Mat<f64>, mass: &[f64], rng: &mut Random) -> usize {
    let n = mass.len();
    let want = block.ncols().min(q.ncols() - m).min(n - m);
    let mut added = 0;
    let mut attempts = 0;
    while added < want && attempts < 4 * want + 8 {
        attempts += 1;
        let col = added;
        let norm0 = m_dot(mass, block.as_ref(), col, block.as_ref(), col).sqrt();
        for _ in 0..2 {
            for p in 0..col {
                let d = m_dot(mass, block.as_ref(), p, block.as_ref(), col);
                for i in 0..n {
                    let v = block[(i, p)];
                    block[(i, col)] -= d * v;
                }
            }
        }
        let norm = m_dot(mass, block.as_ref(), col, block.as_ref(), col).sqrt();
        if norm > 1e-10 * norm0 && norm > 0.0 && norm.is_finite() {
            block.col_mut(col).iter_mut().for_each(|v| *v /= norm);
            added += 1;
        } else {
            // a random replacement, projected against the basis twice
            let mut r = Mat::<f64>::from_fn(n, 1, |_, _| rng.next());
            project_out(q, m, &mut r, mass);
            project_out(q, m, &mut r, mass);
            block.col_mut(col).copy_from(r.col(0));
        }
    }
    added
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::primitives::{grid, icosphere};

    /// Φᵀ M Φ = I to roundoff.
    fn assert_m_orthonormal(e: &Eigenpairs, mass: &[f64]) {
        let k = e.values.len();
        let v = e.vectors.as_ref();
        let mut worst = 0.0f64;
        for a in 0..k {
            for c in 0..k {
                let d = m_dot(mass, v, a, v, c) - if a == c { 1.0 } else { 0.0 };
                worst = worst.max(d.abs());
            }
        }
        assert!(worst < 1e-10, "Φᵀ M Φ − I up to {worst:e}");
    }

    /// Unit sphere: λ = l(l+1) with multiplicity 2l+1 (0; 2 ×3; 6 ×5; 12 ×7), the error
    /// shrinking about fourfold per subdivision (O(h²)), eigenvectors M-orthonormal.
    #[test]
    fn icosphere_spectrum_converges_to_l_times_l_plus_one() {
        let exact: Vec<f64> = (0..4usize)
            .flat_map(|l| std::iter::repeat_n((l * (l + 1)) as f64, 2 * l + 1))
            .collect();
        let k = exact.len(); // 16
        let mut errors = Vec::new();
        for s in [2, 3, 4] {
            let mesh = icosphere(s);
            let e = laplace_beltrami_eigenpairs(&mesh, k, &EigenParams::default()).unwrap();
            assert!(e.max_residual <= 1e-8);
            assert!(e.values[0].abs() < 1e-8, "λ0 = {}", e.values[0]);
            let err = e
                .values
                .iter()
                .zip(&exact)
                .map(|(a, b)| (a - b).abs() / b.max(1.0))
                .fold(0.0f64, f64::max);
            assert_m_orthonormal(&e, &vertex_dual_areas(&mesh));
            errors.push(err);
        }
        eprintln!("icosphere 2, 3, 4 subdivisions: largest relative error of λ_0..λ_15 {errors:?}");
        assert!(errors[2] < 0.01, "relative error at 4 subdivisions {errors:?}");
        for w in errors.windows(2) {
            let ratio = w[0] / w[1];
            assert!(ratio > 3.0 && ratio < 5.0, "convergence ratios {errors:?}");
        }
    }

    /// Rectangle [0, a] × [0, b] with the free (Neumann) boundary: λ = π²(m²/a² + n²/b²).
    #[test]
    fn rectangle_neumann_spectrum() {
        let (a, b) = (2.0, 1.0);
        let mut exact: Vec<f64> = (0..8)
            .flat_map(|m| {
                (0..8)
                    .map(move |n| std::f64::consts::PI.powi(2) * ((m * m) as f64 / (a * a) + (n * n) as f64 / (b * b)))
            })
            .collect();
        exact.sort_by(f64::total_cmp);
        let k = 12;
        let mut errors = Vec::new();
        for cells in [16, 32] {
            let mut mesh = grid(2 * cells, cells);
            for p in &mut mesh.positions {
                p[0] *= a;
            }
            let e = laplace_beltrami_eigenpairs(&mesh, k, &EigenParams::default()).unwrap();
            assert_m_orthonormal(&e, &vertex_dual_areas(&mesh));
            let err = e.values[1..]
                .iter()
                .zip(&exact[1..k])
                .map(|(x, y)| (x - y).abs() / y)
                .fold(0.0f64, f64::max);
            assert!(e.values[0].abs() < 1e-8);
            errors.push(err);
        }
        eprintln!("rectangle 32 × 16 and 64 × 32 cells: largest relative error of λ_1..λ_11 {errors:?}");
        assert!(errors[1] < 0.01, "relative errors {errors:?}");
        assert!(errors[0] / errors[1] > 3.0, "O(h²): {errors:?}");
    }

    /// Scaling the mesh by s scales every eigenvalue by 1/s² and leaves M-normalized
    /// eigenvectors scaled by 1/s (same basis functions).
    #[test]
    fn eigenvalues_scale_with_one_over_length_squared() {
        let mesh = icosphere(2);
        let e1 = laplace_beltrami_eigenpairs(&mesh, 9, &EigenParams::default()).unwrap();
        for s in [1e-3, 1e3] {
            let mut scaled = mesh.clone();
            for p in &mut scaled.positions {
                for x in p.iter_mut() {
                    *x *= s;
                }
            }
            let e2 = laplace_beltrami_eigenpairs(&scaled, 9, &EigenParams::default()).unwrap();
            for (a, b) in e1.values.iter().zip(&e2.values) {
                assert!((a - b * s * s).abs() < 1e-8 * a.max(1.0), "{a} vs {}", b * s * s);
            }
        }
    }

    #[test]
    fn bad_input_is_an_error() {
        let mesh = icosphere(1);
        assert!(laplace_beltrami_eigenpairs(&mesh, 0, &EigenParams::default()).is_err());
        assert!(laplace_beltrami_eigenpairs(&mesh, mesh.num_vertices() + 1, &EigenParams::default()).is_err());
        let l = cotan_laplacian(&mesh).unwrap();
        let mut mass = vertex_dual_areas(&mesh);
        mass[3] = 0.0;
        let err = generalized_eigenpairs(&l, &mass, 4, &EigenParams::default()).unwrap_err();
        assert!(err.to_string().contains("vertex 3"), "{err}");
        assert!(generalized_eigenpairs(&l, &mass[1..], 4, &EigenParams::default()).is_err());
    }

    /// A small problem solved to the whole space (k = #V) matches the dense generalized
    /// eigenvalues of M^{-1/2} L M^{-1/2}.
    #[test]
    fn full_spectrum_matches_dense_solver() {
        let mesh = icosphere(1); // 42 vertices
        let n = mesh.num_vertices();
        let l = cotan_laplacian(&mesh).unwrap();
        let mass = vertex_dual_areas(&mesh);
        let e = generalized_eigenpairs(&l, &mass, n, &EigenParams::default()).unwrap();
        let d = l.to_dense();
        let s = Mat::<f64>::from_fn(n, n, |i, j| d[(i, j)] / (mass[i] * mass[j]).sqrt());
        let dense = s.self_adjoint_eigen(faer::Side::Lower).unwrap();
        let dv = dense.S().column_vector();
        for i in 0..n {
            assert!(
                (e.values[i] - dv[i].max(0.0)).abs() < 1e-8 * dv[n - 1],
                "{i}: {} vs {}",
                e.values[i],
                dv[i]
            );
        }
    }
}
