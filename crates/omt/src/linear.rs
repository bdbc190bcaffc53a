//! The Newton system of semi-discrete OT: assembly of the Hessian of the Kantorovich energy in the
//! heights, and its solution by sparse Cholesky (symbolic factorization reused while no new
//! neighbour pair appears) or Jacobi-preconditioned conjugate gradients.
//!
//! The Hessian of $E(h) = \int_\Omega u_h\,d\mu - \sum_i \nu_i h_i$ is the weighted graph Laplacian
//! of the restricted power diagram [Kitagawa, Mérigot, Thibert 2019, Thm. 1.3; Zhao et al. 2013]:
//! $$H_{ij} = -\frac{\mu(e_{ij})}{|y_i - y_j|} \ (i \ne j \text{ neighbours}), \qquad H_{ii} = -\sum_{j \ne i} H_{ij},$$
//! with $\mu(e_{ij}) = \int_{e_{ij} \cap \Omega} \mu\,ds$. (Raising $h_j$ by $t$ moves the edge
//! $e_{ij}$ into $W_i$ by $t/|y_i - y_j|$, so $\partial \mu(W_i)/\partial h_j = -\mu(e_{ij})/|y_i-y_j|$.)
//! Cholesky reuses its symbolic factorization across Newton steps while the neighbour pattern
//! stays within the one it was computed for (explicit zeros for vanished pairs);
//! [`LinearSolver::CholeskyReusedOrdering`] also keeps its fill-reducing (AMD) ordering across
//! new patterns while the fill stays low.
//! The constant vector spans its kernel when the cells with positive mass form a connected graph;
//! we remove it by pinning one unknown, `pinned`: its row and column are dropped and its step is 0.
//! A row whose diagonal is below $10^{-13}$ times the mean diagonal (an isolated cell) gets the mean
//! diagonal instead, so the step of that cell is $-G_i / \bar H$; with the damped line search this
//! never happens after the start (every cell keeps mass ≥ ε₀ > 0 and Ω is connected).

use faer::dyn_stack::{MemBuffer, MemStack};
use faer::perm::PermRef;
use faer::sparse::linalg::cholesky::{
    factorize_symbolic_cholesky, CholeskySymbolicParams, LltRef, SymbolicCholesky, SymmetricOrdering,
};
use faer::sparse::linalg::SupernodalThreshold;
use faer::sparse::{SparseColMatRef, SymbolicSparseColMat};
use faer::{Conj, MatMut, Par, Side};

use crate::cells::CellIntegrals;
use crate::error::OmtError;

/// How the Newton system H δ = −G is solved.
#[derive(Clone, Debug, PartialEq, Default)]
pub enum LinearSolver {
    /// Sparse LLᵀ (faer, AMD ordering, sequential, supernodal from 2,000 unknowns); the symbolic
    /// factorization is kept while no new neighbouring pair appears, and recomputed on the union
    /// of all patterns since the previous one otherwise.
    #[default]
    Cholesky,
    /// As `Cholesky`, but a new pattern with few new pairs (at most `REORDER_CHECK_NEW_PAIRS`,
    /// 0.4 %, of them) keeps the previous AMD ordering while its fill nnz(L)/nnz(A) stays within
    /// 20% of the fill the ordering was computed with (checked by counting, see `factor_nnz`),
    /// and the symbolic factorization is on the current pattern only. The same solutions up to
    /// round-off. On face pairs (9.4k unknowns, a new pattern at almost every step) its linear
    /// solves were ~30 % cheaper than `Cholesky`'s, measured when `Cholesky` still factorized
    /// simplicially there (`docs/decisions/0009-linear-algebra.md`); the supernodal
    /// factorization was part of that gain, and the kept ordering's share alone has not been
    /// re-measured separately. Not the default: on the uniform
    /// disk the first steps change so many pairs that a kept ordering's fill grows 5–9× (1e5),
    /// and on camelhead subdivided it gave no gain. (It was also held back by the f64 floor of
    /// the heights on the wolf of the area-preserving tests; with the heights in double-double
    /// form that floor is gone.)
    CholeskyReusedOrdering,
    /// Conjugate gradients with a Jacobi preconditioner, stopped at
    /// ‖r‖ ≤ `relative_tolerance`·‖b‖ or after `max_iterations`.
    ConjugateGradient {
        relative_tolerance: f64,
        max_iterations: usize,
    },
}

/// The reduced (pinned) Hessian in lower-triangular CSC form, #(N−1) columns.
struct ReducedHessian {
    col_ptr: Vec<u32>,
    row_idx: Vec<u32>,
    values: Vec<f64>,
}

/// Solver state carried across Newton iterations: the last symbolic factorization, the neighbour
/// pattern it was built for, and the fill-reducing ordering.
pub struct NewtonSystem {
    pinned: usize,
    solver: LinearSolver,
    pattern: Vec<(u32, u32)>,
    symbolic: Option<SymbolicCholesky<u32>>,
    /// The last AMD ordering, reused for later patterns with few new pairs
    /// ([`REORDER_CHECK_NEW_PAIRS`]) while their fill ratio stays within
    /// [`REORDER_FILL_GROWTH`] of its own (`CholeskyReusedOrdering` only).
    ordering: Option<KeptOrdering>,
    /// Values of the Cholesky factor (reused buffer).
    factor: Vec<f64>,
    /// Number of symbolic factorizations computed so far.
    pub symbolic_factorizations: usize,
    /// Number of those that computed a new (AMD) ordering (all of them, but with
    /// [`LinearSolver::CholeskyReusedOrdering`]).
    pub orderings: usize,
    /// Seconds spent in assembly, symbolic factorization and numeric factorization + solve
    /// (`t_symbolic` and the counts above include adopted speculative factorizations, whose
    /// time overlapped an integration).
    pub t_assembly: f64,
    pub t_symbolic: f64,
    pub t_numeric: f64,
}

/// An AMD ordering kept for later patterns: (forward, inverse), and the fill ratio nnz(L)/nnz(A)
/// it has on the pattern it was computed for. That ratio is counted only when a later pattern
/// is checked against it (most new orderings on face pairs are replaced before any check), from
/// the kept lower pattern (`col_ptr`, `row_idx`) of the reduced Hessian.
struct KeptOrdering {
    forward: Vec<u32>,
    inverse: Vec<u32>,
    fill: Option<f64>,
    col_ptr: Vec<u32>,
    row_idx: Vec<u32>,
}

/// A symbolic factorization computed ahead of need (see [`NewtonSystem::speculate`]).
pub struct SpeculativeSymbolic {
    /// The pattern it was computed for: the system's pattern when speculating, united with the
    /// power diagram's neighbour pairs (sorted, i < j).
    pattern: Vec<(u32, u32)>,
    symbolic: SymbolicCholesky<u32>,
    /// Seconds it took (on another thread, overlapped with the integration).
    seconds: f64,
}

/// From this many unknowns on, [`NewtonSystem::speculate`] computes anything: below, an AMD
/// ordering costs less than handing it to another thread.
pub const SPECULATION_MIN: usize = 5000;

/// A new neighbour pattern keeps the previous fill-reducing ordering while its fill ratio
/// nnz(L)/nnz(A) is at most this factor times the ratio the ordering had on its own pattern.
const REORDER_FILL_GROWTH: f64 = 1.2;

/// A pattern with more new neighbour pairs than this share of its pairs gets a new ordering
/// without counting the kept one's fill. Measured on five face pairs (finest level, 9,411
/// unknowns, 28,029 pairs): every pattern with 90 or fewer new pairs (0.3 %)
/// kept the ordering, every one with 152 or more (0.5 %) failed the fill test; each count
/// (about 1 ms, and 1 ms more for the new ordering's own fill) was spent for nothing in 22
/// of 28 symbolic factorizations. New pairs are counted against the current symbolic
/// factorization's pattern (the ordering's own one or a later pattern that kept it; the fill
/// test guards the drift). Patterns of fewer than 250 pairs never keep an ordering once a pair
/// is new (their AMD costs little; on face pairs the coarse levels' orderings therefore changed
/// by round-off).
const REORDER_CHECK_NEW_PAIRS: f64 = 0.004;

/// From this many unknowns on the factorization is supernodal, with every backend and for the
/// speculative symbolic factorizations too. faer's automatic choice takes the simplicial one for
/// the Hessians here (their fill is low: nnz(L) ≈ 4–7 nnz(A) with AMD), which is slower: at
/// 52.8k unknowns (TOSCA michael1 slit, nnz(L) 0.89–1.45M) a late Newton step's factorization
/// and solve took 0.20–0.23 s simplicial and 0.09–0.16 s supernodal; on a 9.4k-unknown grid one
/// numeric factorization takes 0.012–0.020 s simplicial and 0.009 s supernodal
/// (`docs/decisions/0009-linear-algebra.md`). Below ~2,000 unknowns the two take the same time.
const SUPERNODAL_MIN: usize = 2000;

/// Parameters of the symbolic factorization of an m × m system.
fn symbolic_params(m: usize) -> CholeskySymbolicParams<'static> {
    CholeskySymbolicParams {
        supernodal_flop_ratio_threshold: if m >= SUPERNODAL_MIN {
            SupernodalThreshold::FORCE_SUPERNODAL
        } else {
            SupernodalThreshold::AUTO
        },
        ..Default::default()
    }
}

impl NewtonSystem {
    /// A solver for N unknowns with unknown `pinned` held fixed.
    pub fn new(pinned: usize, solver: LinearSolver) -> Self {
        NewtonSystem {
            pinned,
            solver,
            pattern: Vec::new(),
            symbolic: None,
            ordering: None,
            factor: Vec::new(),
            symbolic_factorizations: 0,
            orderings: 0,
            t_assembly: 0.0,
            t_symbolic: 0.0,
            t_numeric: 0.0,
        }
    }

    /// Whether [`Self::speculate`] can compute anything for `n` unknowns: at least
    /// [`SPECULATION_MIN`] of them and the solver [`LinearSolver::Cholesky`]. The Newton loop
    /// asks first, so that other solvers' evaluations neither list the diagram's pairs nor join.
    pub fn speculates(&self, n: usize) -> bool {
        n >= SPECULATION_MIN.max(2) && self.solver == LinearSolver::Cholesky
    }

    /// The symbolic factorization the next Newton direction would need if the accepted cells'
    /// pattern were all of `diagram_pairs` (the power diagram's neighbour pairs, i < j, sorted,
    /// distinct: a superset of the pairs whose common edge meets Ω), computed without changing
    /// the system, so that it can run on another thread while those cells are integrated
    /// (`rayon::join` in the Newton loop). None for fewer than [`SPECULATION_MIN`] unknowns,
    /// for solvers other than [`LinearSolver::Cholesky`] (the kept ordering of
    /// `CholeskyReusedOrdering` is cheap already), and when the current pattern holds every
    /// pair (the symbolic factorization is reused then anyway).
    pub fn speculate(&self, n: usize, diagram_pairs: &[(u32, u32)]) -> Option<Result<SpeculativeSymbolic, OmtError>> {
        if !self.speculates(n) {
            return None;
        }
        let t0 = std::time::Instant::now();
        let edges: Vec<(u32, u32, f64)> = diagram_pairs.iter().map(|&(i, j)| (i, j, 0.0)).collect();
        let (merged, added) = merge_patterns(&self.pattern, &edges);
        if added == 0 && self.symbolic.is_some() {
            return None;
        }
        let hessian = self.assemble(n, &merged);
        let structure = SymbolicSparseColMat::<u32>::new_checked(
            n - 1,
            n - 1,
            hessian.col_ptr.clone(),
            None,
            hessian.row_idx.clone(),
        );
        Some(amd_symbolic(structure.as_ref()).map(|symbolic| SpeculativeSymbolic {
            pattern: merged.iter().map(|e| (e.0, e.1)).collect(),
            symbolic,
            seconds: t0.elapsed().as_secs_f64(),
        }))
    }

    /// Takes `speculative` as the current symbolic factorization when the accepted `cells` have a
    /// pair outside the current pattern (so the next direction would factorize anew) and
    /// `speculative` covers them all; otherwise drops it, and nothing changes. Returns whether
    /// it was taken. Deterministic: the choice depends on the patterns only.
    pub fn adopt(&mut self, speculative: SpeculativeSymbolic, cells: &CellIntegrals) -> bool {
        if self.solver != LinearSolver::Cholesky {
            return false;
        }
        let pairs = pattern_edges(cells, |_, _, _| 0.0);
        let needed = self.symbolic.is_none() || merge_patterns(&self.pattern, &pairs).1 > 0;
        if !needed || merge_patterns(&speculative.pattern, &pairs).1 > 0 {
            return false;
        }
        self.factor = vec![0.0; speculative.symbolic.len_val()];
        self.symbolic = Some(speculative.symbolic);
        self.pattern = speculative.pattern;
        self.symbolic_factorizations += 1;
        self.orderings += 1;
        self.t_symbolic += speculative.seconds;
        true
    }

    /// Newton direction δ (#N, δ_pinned = 0) solving H δ = −G on the other unknowns, with
    /// H assembled from `cells.edge_masses` and the site distances, and G = masses − targets.
    ///
    /// `cells.edge_masses` must list each pair once with i < j (any order).
    pub fn newton_direction(
        &mut self,
        points: &[[f64; 2]],
        cells: &CellIntegrals,
        gradient: &[f64],
    ) -> Result<Vec<f64>, OmtError> {
        let n = points.len();
        if n <= 1 {
            return Ok(vec![0.0; n]);
        }
        let t0 = std::time::Instant::now();
        let edges = pattern_edges(cells, |a, b, m| {
            let (p, q) = (points[a as usize], points[b as usize]);
            m / (p[0] - q[0]).hypot(p[1] - q[1])
        });
        self.t_assembly += t0.elapsed().as_secs_f64();
        self.direction_from_edges(n, edges, gradient)
    }

    /// Newton direction δ (#N, δ_pinned = 0) solving H δ = −G, with the off-diagonal entries
    /// given directly: `coefficients` lists (i, j, −H_ij) for neighbouring i ≠ j (any order,
    /// repeated pairs summed, non-positive values dropped). The spherical solver uses it, whose
    /// coefficients are not edge masses over planar distances.
    pub fn newton_direction_from_coefficients(
        &mut self,
        n: usize,
        coefficients: &[(u32, u32, f64)],
        gradient: &[f64],
    ) -> Result<Vec<f64>, OmtError> {
        if n <= 1 {
            return Ok(vec![0.0; n]);
        }
        let t0 = std::time::Instant::now();
        let edges = normalized_edges(coefficients.iter().copied(), |_, _, c| c);
        self.t_assembly += t0.elapsed().as_secs_f64();
        self.direction_from_edges(n, edges, gradient)
    }

    /// The direction for the off-diagonal magnitudes `edges` (i < j, sorted, distinct).
    fn direction_from_edges(
        &mut self,
        n: usize,
        mut edges: Vec<(u32, u32, f64)>,
        gradient: &[f64],
    ) -> Result<Vec<f64>, OmtError> {
        let t0 = std::time::Instant::now();
        // For Cholesky, assemble on the pattern of the current symbolic factorization (explicit
        // zeros for absent pairs) when it contains every pair of this one, reusing the symbolic
        // factorization. Otherwise a new symbolic factorization, on the union of both patterns
        // (`Cholesky`) or, when the ordering is kept (cheap symbolic factorizations, see
        // `symbolic_factorization`), on this step's own pattern, so no stale pairs add fill.
        let mut new_pairs = false;
        let mut added = 0;
        if matches!(
            self.solver,
            LinearSolver::Cholesky | LinearSolver::CholeskyReusedOrdering
        ) {
            let merged;
            (merged, added) = merge_patterns(&self.pattern, &edges);
            new_pairs = added > 0 || self.symbolic.is_none();
            if !new_pairs || self.solver == LinearSolver::Cholesky {
                edges = merged;
            }
        }
        let hessian = self.assemble(n, &edges);
        let rhs: Vec<f64> = (0..n).filter(|&i| i != self.pinned).map(|i| -gradient[i]).collect();
        self.t_assembly += t0.elapsed().as_secs_f64();
        let reduced = match self.solver.clone() {
            LinearSolver::Cholesky | LinearSolver::CholeskyReusedOrdering => {
                // (with a new symbolic factorization, the kept ordering is tried only when few
                // of the pairs are new)
                let try_kept = (added as f64) <= REORDER_CHECK_NEW_PAIRS * edges.len() as f64;
                self.solve_cholesky(n - 1, &edges, new_pairs.then_some(try_kept), &hessian, rhs)?
            }
            LinearSolver::ConjugateGradient {
                relative_tolerance,
                max_iterations,
            } => conjugate_gradient(&hessian, &rhs, relative_tolerance, max_iterations),
        };
        let mut delta = Vec::with_capacity(n);
        let mut k = 0;
        for i in 0..n {
            if i == self.pinned {
                delta.push(0.0);
            } else {
                delta.push(reduced[k]);
                k += 1;
            }
        }
        Ok(delta)
    }

    fn reduced_index(&self, i: u32) -> Option<u32> {
        let p = self.pinned as u32;
        match i.cmp(&p) {
            std::cmp::Ordering::Less => Some(i),
            std::cmp::Ordering::Equal => None,
            std::cmp::Ordering::Greater => Some(i - 1),
        }
    }

    /// Lower-triangular CSC of the pinned Hessian: column c holds the diagonal, then the rows of
    /// the neighbours j > i (the reduced index is monotone, so rows come out sorted).
    fn assemble(&self, n: usize, edges: &[(u32, u32, f64)]) -> ReducedHessian {
        let m = n - 1;
        let mut diagonal = vec![0.0; n];
        for &(i, j, a) in edges {
            diagonal[i as usize] += a;
            diagonal[j as usize] += a;
        }
        let mean = diagonal.iter().sum::<f64>() / n as f64;
        let floor = 1e-13 * mean;
        let mut col_ptr = vec![0u32; m + 1];
        for &(i, j, _) in edges {
            if let (Some(ri), Some(_)) = (self.reduced_index(i), self.reduced_index(j)) {
                col_ptr[ri as usize + 1] += 1;
            }
        }
        for c in 0..m {
            col_ptr[c + 1] += col_ptr[c] + 1;
        }
        let nnz = col_ptr[m] as usize;
        let mut row_idx = vec![0u32; nnz];
        let mut values = vec![0.0; nnz];
        let mut next: Vec<u32> = col_ptr[..m].to_vec();
        for i in 0..n {
            if let Some(r) = self.reduced_index(i as u32) {
                let d = diagonal[i];
                let k = next[r as usize] as usize;
                row_idx[k] = r;
                values[k] = if d > floor {
                    d
                } else if mean > 0.0 {
                    mean
                } else {
                    1.0
                };
                next[r as usize] += 1;
            }
        }
        for &(i, j, a) in edges {
            if let (Some(ri), Some(rj)) = (self.reduced_index(i), self.reduced_index(j)) {
                let k = next[ri as usize] as usize;
                row_idx[k] = rj;
                values[k] = -a;
                next[ri as usize] += 1;
            }
        }
        ReducedHessian {
            col_ptr,
            row_idx,
            values,
        }
    }

    /// `new_pattern`: None when the pattern is the current symbolic factorization's, else
    /// whether a kept ordering may be tried for the new one.
    fn solve_cholesky(
        &mut self,
        m: usize,
        edges: &[(u32, u32, f64)],
        new_pattern: Option<bool>,
        hessian: &ReducedHessian,
        mut rhs: Vec<f64>,
    ) -> Result<Vec<f64>, OmtError> {
        if m == 0 {
            return Ok(rhs);
        }
        let structure =
            SymbolicSparseColMat::<u32>::new_checked(m, m, hessian.col_ptr.clone(), None, hessian.row_idx.clone());
        let new_pattern = if self.symbolic.is_none() {
            Some(true)
        } else {
            new_pattern
        };
        if let Some(try_kept) = new_pattern {
            let t0 = std::time::Instant::now();
            let symbolic = self.symbolic_factorization(hessian, structure.as_ref(), try_kept)?;
            self.factor = vec![0.0; symbolic.len_val()];
            self.symbolic = Some(symbolic);
            self.pattern = edges.iter().map(|e| (e.0, e.1)).collect();
            self.symbolic_factorizations += 1;
            self.t_symbolic += t0.elapsed().as_secs_f64();
        }
        let t0 = std::time::Instant::now();
        let symbolic = self
            .symbolic
            .as_ref()
            .expect("symbolic factorization was just computed");
        // Sequential: as fast as rayon at N = 1e5 on 2 shared cores (and faster when the
        // caller already runs one solve per thread), and independent of the thread count.
        let par = Par::Seq;
        let scratch = symbolic
            .factorize_numeric_llt_scratch::<f64>(par, Default::default())
            .or(symbolic.solve_in_place_scratch::<f64>(1, par));
        let mut buffer = MemBuffer::try_new(scratch)
            .map_err(|_| OmtError::LinearAlgebra("out of memory in the Cholesky factorization".into()))?;
        let stack = MemStack::new(&mut buffer);
        // A Hessian whose edge weights span ~20 orders of magnitude (sites 1e-18 apart beside
        // ordinary ones) can lose a pivot to round-off. Then the diagonal is raised by a relative
        // 1e-10, 1e-8, 1e-6 (strict diagonal dominance; the direction changes by about as much,
        // which the damped step tolerates) before giving up.
        let mut shifted: Vec<f64>;
        let mut values: &[f64] = &hessian.values;
        let mut attempt = 0;
        loop {
            let matrix = SparseColMatRef::new(structure.as_ref(), values);
            match symbolic.factorize_numeric_llt::<f64>(
                &mut self.factor,
                matrix,
                Side::Lower,
                Default::default(),
                par,
                &mut *stack,
                Default::default(),
            ) {
                Ok(_) => break,
                Err(e) if attempt >= 3 => {
                    return Err(OmtError::LinearAlgebra(format!(
                        "numeric Cholesky of the Newton Hessian (also with the diagonal raised by 1e-6): {e:?}"
                    )))
                }
                Err(_) => {
                    attempt += 1;
                    let raise = 1.0 + [1e-10, 1e-8, 1e-6][attempt - 1];
                    shifted = hessian.values.clone();
                    for c in 0..m {
                        shifted[hessian.col_ptr[c] as usize] *= raise;
                    }
                    values = &shifted;
                }
            }
        }
        LltRef::new(symbolic, &self.factor).solve_in_place_with_conj(
            Conj::No,
            MatMut::from_column_major_slice_mut(&mut rhs, m, 1),
            par,
            stack,
        );
        self.t_numeric += t0.elapsed().as_secs_f64();
        Ok(rhs)
    }

    /// Symbolic Cholesky factorization of the reduced Hessian's pattern (m × m, lower), with a
    /// new AMD ordering; with [`LinearSolver::CholeskyReusedOrdering`], with the kept ordering
    /// when there is one and its fill nnz(L)/nnz(A) stays within [`REORDER_FILL_GROWTH`] of the
    /// fill it had on the pattern it was computed for (the new AMD ordering is then kept). The
    /// fill of the kept ordering is counted first (elimination tree and column counts only,
    /// much cheaper than AMD), since a few new neighbour pairs can multiply it: on the 1e5 disk
    /// the first Newton steps change enough pairs to raise it 5–9×, while on face pairs most
    /// steps keep it. With `try_kept` false (many new pairs, [`REORDER_CHECK_NEW_PAIRS`]) the
    /// count is skipped and a new ordering computed.
    fn symbolic_factorization(
        &mut self,
        hessian: &ReducedHessian,
        structure: faer::sparse::SymbolicSparseColMatRef<'_, u32>,
        try_kept: bool,
    ) -> Result<SymbolicCholesky<u32>, OmtError> {
        let err = |e| OmtError::LinearAlgebra(format!("symbolic Cholesky: {e:?}"));
        let m = structure.nrows();
        let reuse = self.solver == LinearSolver::CholeskyReusedOrdering;
        if let Some(kept) = self
            .ordering
            .as_mut()
            .filter(|k| reuse && try_kept && k.forward.len() == m)
        {
            let fill = *kept.fill.get_or_insert_with(|| {
                let nnz_l = factor_nnz(&kept.col_ptr, &kept.row_idx, &kept.inverse, usize::MAX);
                nnz_l.unwrap_or(usize::MAX) as f64 / kept.row_idx.len() as f64
            });
            let budget = (REORDER_FILL_GROWTH * fill * structure.compute_nnz() as f64) as usize;
            if factor_nnz(&hessian.col_ptr, &hessian.row_idx, &kept.inverse, budget).is_some() {
                return factorize_symbolic_cholesky(
                    structure,
                    Side::Lower,
                    SymmetricOrdering::Custom(PermRef::new_checked(&kept.forward, &kept.inverse, m)),
                    symbolic_params(m),
                )
                .map_err(err);
            }
        }
        let symbolic = amd_symbolic(structure)?;
        self.orderings += 1;
        if reuse {
            let (forward, inverse) = symbolic.perm().expect("AMD gives a permutation").arrays();
            self.ordering = Some(KeptOrdering {
                forward: forward.to_vec(),
                inverse: inverse.to_vec(),
                fill: None,
                col_ptr: hessian.col_ptr.clone(),
                row_idx: hessian.row_idx.clone(),
            });
        }
        Ok(symbolic)
    }
}

/// Symbolic Cholesky factorization of the lower pattern `structure` with a new AMD ordering.
fn amd_symbolic(structure: faer::sparse::SymbolicSparseColMatRef<'_, u32>) -> Result<SymbolicCholesky<u32>, OmtError> {
    let m = structure.nrows();
    factorize_symbolic_cholesky(structure, Side::Lower, SymmetricOrdering::Amd, symbolic_params(m))
        .map_err(|e| OmtError::LinearAlgebra(format!("symbolic Cholesky: {e:?}")))
}

/// The pairs of `cells.edge_masses` with positive mass, each once as (i, j) with i < j, sorted,
/// with value the sum of `value(i, j, mass)` over its entries.
fn pattern_edges(cells: &CellIntegrals, value: impl Fn(u32, u32, f64) -> f64) -> Vec<(u32, u32, f64)> {
    normalized_edges(cells.edge_masses.iter().copied(), value)
}

/// `raw` pairs with a positive value, as (i < j, value(i, j, m)), sorted, repeated pairs summed.
fn normalized_edges(
    raw: impl Iterator<Item = (u32, u32, f64)>,
    value: impl Fn(u32, u32, f64) -> f64,
) -> Vec<(u32, u32, f64)> {
    let mut edges: Vec<(u32, u32, f64)> = raw
        .filter(|e| e.2 > 0.0 && e.0 != e.1)
        .map(|(i, j, m)| {
            let (a, b) = if i < j { (i, j) } else { (j, i) };
            (a, b, value(a, b, m))
        })
        .collect();
    edges.sort_unstable_by_key(|e| (e.0, e.1));
    edges.dedup_by(|b, a| {
        if a.0 == b.0 && a.1 == b.1 {
            a.2 += b.2;
            true
        } else {
            false
        }
    });
    edges
}

/// nnz(L) of the Cholesky factor of the symmetric pattern (`col_ptr`, `row_idx`) (lower CSC
/// with diagonal, as the reduced Hessian) permuted by `inv` (unknown → elimination position),
/// or None when it exceeds `budget`.
/// Counts by walking the row subtrees of the elimination tree (Liu 1990; as faer's
/// `prefactorize_symbolic_cholesky`), O(nnz(L)), stopping as soon as the budget is exceeded.
fn factor_nnz(col_ptr_a: &[u32], row_idx_a: &[u32], inv: &[u32], budget: usize) -> Option<usize> {
    const NONE: u32 = u32::MAX;
    let m = inv.len();
    // Permuted upper triangle by columns (rows unsorted, diagonal dropped).
    let mut col_ptr = vec![0u32; m + 1];
    let entries = || {
        (0..m).flat_map(move |c| {
            row_idx_a[col_ptr_a[c] as usize..col_ptr_a[c + 1] as usize]
                .iter()
                .map(move |&r| (inv[r as usize], inv[c]))
        })
    };
    for (p, q) in entries() {
        if p != q {
            col_ptr[p.max(q) as usize + 1] += 1;
        }
    }
    for c in 0..m {
        col_ptr[c + 1] += col_ptr[c];
    }
    let mut next = col_ptr[..m].to_vec();
    let mut row_idx = vec![0u32; col_ptr[m] as usize];
    for (p, q) in entries() {
        if p != q {
            let col = p.max(q) as usize;
            row_idx[next[col] as usize] = p.min(q);
            next[col] += 1;
        }
    }
    let mut parent = vec![NONE; m];
    let mut visited = vec![NONE; m];
    let mut count = m;
    for j in 0..m {
        visited[j] = j as u32;
        for &row in &row_idx[col_ptr[j] as usize..col_ptr[j + 1] as usize] {
            let mut i = row as usize;
            while visited[i] != j as u32 {
                if parent[i] == NONE {
                    parent[i] = j as u32;
                }
                count += 1;
                visited[i] = j as u32;
                i = parent[i] as usize;
            }
        }
        if count > budget {
            return None;
        }
    }
    Some(count)
}

/// Union of the sorted pair list `pattern` with the sorted weighted `edges` (pairs of `pattern`
/// absent from `edges` get weight 0), and how many pairs of `edges` are not in `pattern`.
fn merge_patterns(pattern: &[(u32, u32)], edges: &[(u32, u32, f64)]) -> (Vec<(u32, u32, f64)>, usize) {
    let mut merged = Vec::with_capacity(pattern.len().max(edges.len()));
    let (mut a, mut b) = (0, 0);
    let mut added = 0;
    while a < pattern.len() || b < edges.len() {
        let pa = pattern.get(a).copied();
        let eb = edges.get(b).map(|e| (e.0, e.1));
        match (pa, eb) {
            (Some(p), Some(e)) if p == e => {
                merged.push(edges[b]);
                a += 1;
                b += 1;
            }
            (Some(p), Some(e)) if p < e => {
                merged.push((p.0, p.1, 0.0));
                a += 1;
            }
            (Some(p), None) => {
                merged.push((p.0, p.1, 0.0));
                a += 1;
            }
            _ => {
                merged.push(edges[b]);
                added += 1;
                b += 1;
            }
        }
    }
    (merged, added)
}

/// y = A x for the symmetric matrix stored as its lower triangle.
fn symmetric_matvec(a: &ReducedHessian, x: &[f64], y: &mut [f64]) {
    y.iter_mut().for_each(|v| *v = 0.0);
    for c in 0..x.len() {
        for k in a.col_ptr[c] as usize..a.col_ptr[c + 1] as usize {
            let r = a.row_idx[k] as usize;
            let v = a.values[k];
            y[r] += v * x[c];
            if r != c {
                y[c] += v * x[r];
            }
        }
    }
}

/// Jacobi-preconditioned conjugate gradients from x = 0 [Saad, Iterative Methods, Alg. 9.1].
fn conjugate_gradient(a: &ReducedHessian, b: &[f64], relative_tolerance: f64, max_iterations: usize) -> Vec<f64> {
    let m = b.len();
    let inv_diag: Vec<f64> = (0..m).map(|c| 1.0 / a.values[a.col_ptr[c] as usize]).collect();
    let dot = |u: &[f64], v: &[f64]| u.iter().zip(v).map(|(p, q)| p * q).sum::<f64>();
    let mut x = vec![0.0; m];
    let mut r = b.to_vec();
    let mut z: Vec<f64> = r.iter().zip(&inv_diag).map(|(r, d)| r * d).collect();
    let mut p = z.clone();
    let mut ap = vec![0.0; m];
    let b_norm = dot(b, b).sqrt();
    let mut rz = dot(&r, &z);
    for _ in 0..max_iterations {
        if dot(&r, &r).sqrt() <= relative_tolerance * b_norm {
            break;
        }
        symmetric_matvec(a, &p, &mut ap);
        let pap = dot(&p, &ap);
        if !(pap > 0.0) {
            break;
        }
        let alpha = rz / pap;
        for k in 0..m {
            x[k] += alpha * p[k];
            r[k] -= alpha * ap[k];
        }
        for k in 0..m {
            z[k] = r[k] * inv_diag[k];
        }
        let rz_new = dot(&r, &z);
        let beta = rz_new / rz;
        rz = rz_new;
        for k in 0..m {
            p[k] = z[k] + beta * p[k];
        }
    }
    x
}

/// The full N×N Hessian as dense rows (tests and small problems only), H_ij = −μ(e_ij)/|y_i − y_j|,
/// H_ii = −Σ_j H_ij.
pub fn dense_hessian(points: &[[f64; 2]], cells: &CellIntegrals) -> Vec<Vec<f64>> {
    let n = points.len();
    let mut h = vec![vec![0.0; n]; n];
    for &(i, j, m) in &cells.edge_masses {
        let (i, j) = (i as usize, j as usize);
        let a = m / (points[i][0] - points[j][0]).hypot(points[i][1] - points[j][1]);
        h[i][j] -= a;
        h[j][i] -= a;
        h[i][i] += a;
        h[j][j] += a;
    }
    h
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A path graph 0–1–2–3 with unit couplings: H δ = −G on the sum-zero gradient.
    #[test]
    fn cholesky_and_cg_agree_on_a_path_laplacian() {
        let points = [[0.0, 0.0], [1.0, 0.0], [2.0, 0.0], [3.0, 0.0]];
        let cells = CellIntegrals {
            masses: vec![1.0; 4],
            first_moments: vec![[0.0; 2]; 4],
            second_moments: vec![0.0; 4],
            edge_masses: vec![(1, 2, 2.0), (0, 1, 1.0), (2, 3, 3.0)],
        };
        let gradient = [0.5, -1.0, 0.25, 0.25];
        for pinned in 0..4 {
            let mut chol = NewtonSystem::new(pinned, LinearSolver::Cholesky);
            let d1 = chol.newton_direction(&points, &cells, &gradient).unwrap();
            let mut cg = NewtonSystem::new(
                pinned,
                LinearSolver::ConjugateGradient {
                    relative_tolerance: 1e-14,
                    max_iterations: 100,
                },
            );
            let d2 = cg.newton_direction(&points, &cells, &gradient).unwrap();
            let h = dense_hessian(&points, &cells);
            for i in 0..4 {
                let hd: f64 = (0..4).map(|j| h[i][j] * d1[j]).sum();
                assert!((hd + gradient[i]).abs() < 1e-13, "pinned {pinned} row {i}: {hd}");
                assert!((d1[i] - d2[i]).abs() < 1e-12);
            }
            assert_eq!(d1[pinned], 0.0);
            // The same pattern reuses the symbolic factorization.
            chol.newton_direction(&points, &cells, &gradient).unwrap();
            assert_eq!(chol.symbolic_factorizations, 1);
        }
    }

    /// Dropping a pair reuses the symbolic factorization (explicit zero); a new pair recomputes
    /// it on the union. The step solves the actual system either way.
    #[test]
    fn symbolic_factorization_is_reused_on_sub_patterns() {
        let points = [[0.0, 0.0], [1.0, 0.0], [1.0, 1.0], [0.0, 1.0]];
        let gradient = [0.5, -1.0, 0.25, 0.25];
        let cells_with = |edges: Vec<(u32, u32, f64)>| CellIntegrals {
            masses: vec![1.0; 4],
            first_moments: vec![[0.0; 2]; 4],
            second_moments: vec![0.0; 4],
            edge_masses: edges,
        };
        let mut system = NewtonSystem::new(1, LinearSolver::Cholesky);
        let patterns = [
            (vec![(0, 1, 1.0), (1, 2, 2.0), (2, 3, 1.5), (0, 3, 0.5)], 1),
            (vec![(0, 1, 1.0), (1, 2, 2.0), (2, 3, 1.5)], 1),
            (vec![(0, 1, 1.0), (1, 2, 2.0), (2, 3, 1.5), (0, 2, 0.7)], 2),
        ];
        for (edges, factorizations) in patterns {
            let cells = cells_with(edges);
            let delta = system.newton_direction(&points, &cells, &gradient).unwrap();
            let h = dense_hessian(&points, &cells);
            for i in 0..4 {
                let hd: f64 = (0..4).map(|j| h[i][j] * delta[j]).sum();
                assert!((hd + gradient[i]).abs() < 1e-13);
            }
            assert_eq!(system.symbolic_factorizations, factorizations);
        }
    }

    /// A speculative symbolic factorization on a superset pattern is taken exactly when the
    /// accepted pattern has a new pair it covers; the direction then needs no new symbolic
    /// factorization and still solves the system. (75 × 75 grid: above `SPECULATION_MIN`.)
    #[test]
    fn speculative_symbolic_is_adopted_only_when_needed_and_covering() {
        let k = 75u32;
        let n = (k * k) as usize;
        assert!(n >= SPECULATION_MIN);
        let points: Vec<[f64; 2]> = (0..n).map(|v| [(v as u32 % k) as f64, (v as u32 / k) as f64]).collect();
        let gradient: Vec<f64> = (0..n).map(|v| ((v * 37 % 101) as f64 - 50.0) * 1e-3).collect();
        let mean = gradient.iter().sum::<f64>() / n as f64;
        let gradient: Vec<f64> = gradient.iter().map(|g| g - mean).collect();
        let id = |x: u32, y: u32| y * k + x;
        let mut grid = Vec::new();
        let mut diagonals = Vec::new();
        for y in 0..k {
            for x in 0..k {
                if x + 1 < k {
                    grid.push((id(x, y), id(x + 1, y), 1.0 + 0.01 * ((x + y) % 7) as f64));
                }
                if y + 1 < k {
                    grid.push((id(x, y), id(x, y + 1), 1.0 + 0.02 * ((x * y) % 5) as f64));
                }
                if x + 1 < k && y + 1 < k {
                    diagonals.push((id(x, y), id(x + 1, y + 1), 0.3));
                }
            }
        }
        let cells_with = |edges: Vec<(u32, u32, f64)>| CellIntegrals {
            masses: vec![1.0; n],
            first_moments: vec![[0.0; 2]; n],
            second_moments: vec![0.0; n],
            edge_masses: edges,
        };
        let residual = |edges: &[(u32, u32, f64)], delta: &[f64]| -> f64 {
            let mut hd = vec![0.0; n];
            for &(i, j, m) in edges {
                let (p, q) = (points[i as usize], points[j as usize]);
                let a = m / (p[0] - q[0]).hypot(p[1] - q[1]);
                let d = a * (delta[i as usize] - delta[j as usize]);
                hd[i as usize] += d;
                hd[j as usize] -= d;
            }
            (0..n).map(|i| (hd[i] + gradient[i]).abs()).fold(0.0, f64::max)
        };
        let superset: Vec<(u32, u32)> = {
            let mut p: Vec<(u32, u32)> = grid.iter().chain(&diagonals).map(|e| (e.0, e.1)).collect();
            p.sort_unstable();
            p
        };
        // from SUPERNODAL_MIN unknowns every path factorizes supernodally (faer's automatic
        // choice takes the simplicial factorization for this low-fill pattern)
        let supernodal = |system: &NewtonSystem| {
            matches!(
                system.symbolic.as_ref().map(|s| s.raw()),
                Some(faer::sparse::linalg::cholesky::SymbolicCholeskyRaw::Supernodal(_))
            )
        };
        let mut system = NewtonSystem::new(0, LinearSolver::Cholesky);
        let delta = system
            .newton_direction(&points, &cells_with(grid.clone()), &gradient)
            .unwrap();
        assert!(residual(&grid, &delta) < 1e-10);
        assert_eq!(system.symbolic_factorizations, 1);
        assert!(supernodal(&system));

        // the accepted cells keep the pattern: the speculation is dropped
        let spec = system.speculate(n, &superset).unwrap().unwrap();
        assert!(!system.adopt(spec, &cells_with(grid.clone())));
        assert_eq!(system.symbolic_factorizations, 1);

        // a new pair outside the speculated pattern (an anti-diagonal): dropped as well
        let spec = system.speculate(n, &superset).unwrap().unwrap();
        let mut outside = grid.clone();
        outside.push((id(1, 0), id(0, 1), 0.2));
        assert!(!system.adopt(spec, &cells_with(outside)));

        // new pairs inside it: adopted, and the next direction reuses it
        let spec = system.speculate(n, &superset).unwrap().unwrap();
        let mut inside = grid.clone();
        inside.extend(diagonals.iter().step_by(5).copied());
        assert!(system.adopt(spec, &cells_with(inside.clone())));
        assert_eq!(system.symbolic_factorizations, 2);
        assert!(supernodal(&system));
        let delta = system
            .newton_direction(&points, &cells_with(inside.clone()), &gradient)
            .unwrap();
        assert_eq!(system.symbolic_factorizations, 2);
        assert!(residual(&inside, &delta) < 1e-10);
        // the fresh system's direction agrees
        let fresh = NewtonSystem::new(0, LinearSolver::Cholesky)
            .newton_direction(&points, &cells_with(inside.clone()), &gradient)
            .unwrap();
        let diff = delta.iter().zip(&fresh).map(|(a, b)| (a - b).abs()).fold(0.0, f64::max);
        assert!(
            diff < 1e-9 * fresh.iter().map(|x| x.abs()).fold(0.0, f64::max),
            "{diff}"
        );

        // nothing new to speculate on now; small systems and other solvers never speculate
        assert!(system.speculate(n, &superset).is_none());
        let small = NewtonSystem::new(0, LinearSolver::Cholesky);
        assert!(small.speculate(SPECULATION_MIN - 1, &superset[..10]).is_none());
        let mut reused = NewtonSystem::new(0, LinearSolver::CholeskyReusedOrdering);
        assert!(reused.speculate(n, &superset).is_none());
        assert!(system.speculates(n) && !small.speculates(SPECULATION_MIN - 1) && !reused.speculates(n));

        // the kept-ordering backend: supernodal with a new AMD ordering and with the kept one
        let mut few = grid.clone();
        few.extend(diagonals.iter().step_by(200).copied());
        for (edges, orderings) in [(&grid, 1), (&few, 1)] {
            let delta = reused
                .newton_direction(&points, &cells_with(edges.clone()), &gradient)
                .unwrap();
            assert!(residual(edges, &delta) < 1e-10);
            assert_eq!(reused.orderings, orderings);
            assert!(supernodal(&reused));
        }
        assert_eq!(reused.symbolic_factorizations, 2);
    }

    /// A new pair recomputes the symbolic factorization, with the kept ordering (no new AMD)
    /// when asked for, few pairs are new and the fill stays low; the step solves the system
    /// either way.
    #[test]
    fn ordering_is_reused_across_new_pairs() {
        // 40 × 40 grid graph, later with a few diagonals added (as when neighbours change), then
        // with many (12 % new pairs: a new ordering without counting the kept one's fill).
        let k = 40u32;
        let n = (k * k) as usize;
        let points: Vec<[f64; 2]> = (0..n).map(|v| [(v as u32 % k) as f64, (v as u32 / k) as f64]).collect();
        let mut grid = Vec::new();
        for y in 0..k {
            for x in 0..k {
                let v = y * k + x;
                if x + 1 < k {
                    grid.push((v, v + 1, 1.0 + 0.01 * v as f64));
                }
                if y + 1 < k {
                    grid.push((v, v + k, 1.0));
                }
            }
        }
        let gradient: Vec<f64> = (0..n).map(|i| ((i * 7) % 5) as f64 - 2.0).collect();
        let mean = gradient.iter().sum::<f64>() / n as f64;
        let gradient: Vec<f64> = gradient.iter().map(|g| g - mean).collect();
        let mut with_diagonals = grid.clone();
        for v in [130u32, 500, 777, 1000] {
            with_diagonals.push((v, v + k + 1, 0.3));
        }
        with_diagonals.sort_unstable_by_key(|e| (e.0, e.1));
        let mut many = grid.clone();
        for y in 0..k - 1 {
            for x in (0..k - 1).filter(|x| (x + y) % 4 == 0) {
                many.push((y * k + x, y * k + x + k + 1, 0.25));
            }
        }
        assert!(many.len() - grid.len() > 300);
        for solver in [LinearSolver::Cholesky, LinearSolver::CholeskyReusedOrdering] {
            let mut system = NewtonSystem::new(0, solver.clone());
            let steps = [(&grid, 1, 1), (&with_diagonals, 2, 1), (&grid, 2, 1), (&many, 3, 2)];
            for (edges, factorizations, kept_orderings) in steps {
                let edges = edges.clone();
                let cells = CellIntegrals {
                    masses: vec![1.0; n],
                    first_moments: vec![[0.0; 2]; n],
                    second_moments: vec![0.0; n],
                    edge_masses: edges,
                };
                let delta = system.newton_direction(&points, &cells, &gradient).unwrap();
                let h = dense_hessian(&points, &cells);
                for i in 1..n {
                    let hd: f64 = (0..n).map(|j| h[i][j] * delta[j]).sum();
                    assert!((hd + gradient[i]).abs() < 1e-10, "row {i}: {}", hd + gradient[i]);
                }
                assert_eq!(system.symbolic_factorizations, factorizations);
                let orderings = if solver == LinearSolver::Cholesky {
                    factorizations
                } else {
                    kept_orderings
                };
                assert_eq!(system.orderings, orderings);
            }
        }
    }

    /// The fill count agrees with faer's simplicial symbolic factorization (whose value count
    /// is nnz(L)), and stops at the budget.
    #[test]
    fn factor_nnz_matches_faer() {
        let k = 9u32;
        let n = (k * k) as usize;
        let mut edges = Vec::new();
        for y in 0..k {
            for x in 0..k {
                let v = y * k + x;
                if x + 1 < k {
                    edges.push((v, v + 1, 1.0));
                }
                if y + 1 < k {
                    edges.push((v, v + k, 1.0));
                }
                if x + 1 < k && y + 1 < k && (x + y) % 3 == 0 {
                    edges.push((v, v + k + 1, 1.0));
                }
            }
        }
        edges.sort_unstable_by_key(|e| (e.0, e.1));
        let system = NewtonSystem::new(4, LinearSolver::Cholesky);
        let hessian = system.assemble(n, &edges);
        let m = n - 1;
        let structure =
            SymbolicSparseColMat::<u32>::new_checked(m, m, hessian.col_ptr.clone(), None, hessian.row_idx.clone());
        for ordering in [0, 1] {
            let params = CholeskySymbolicParams {
                supernodal_flop_ratio_threshold: SupernodalThreshold::FORCE_SIMPLICIAL,
                ..Default::default()
            };
            let identity: Vec<u32> = (0..m as u32).collect();
            let ord = if ordering == 0 {
                SymmetricOrdering::Amd
            } else {
                SymmetricOrdering::Custom(PermRef::new_checked(&identity, &identity, m))
            };
            let symbolic = factorize_symbolic_cholesky(structure.as_ref(), Side::Lower, ord, params).unwrap();
            let (_, inv) = symbolic.perm().unwrap().arrays();
            let (c, r) = (&hessian.col_ptr, &hessian.row_idx);
            let count = factor_nnz(c, r, inv, usize::MAX).unwrap();
            assert_eq!(count, symbolic.len_val());
            assert_eq!(factor_nnz(c, r, inv, count), Some(count));
            assert_eq!(factor_nnz(c, r, inv, count - 1), None);
        }
    }
}
