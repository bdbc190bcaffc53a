//! The OMT crate's error type.

/// Errors of power-diagram construction and semi-discrete OT.
#[derive(Debug, thiserror::Error)]
pub enum OmtError {
    /// Input that violates the problem's assumptions (shapes, NaN, non-positive masses, ...).
    #[error("invalid input: {0}")]
    InvalidInput(String),
    /// Two target points coincide (power diagrams of coincident sites are not defined).
    #[error("target points {i} and {j} coincide")]
    DuplicatePoints { i: usize, j: usize },
    /// The Newton iteration stopped at its cap (or could not make progress) before reaching the
    /// tolerance.
    #[error("no convergence after {iterations} iterations: max relative mass error {residual:e} > tolerance {tolerance:e} ({reason})")]
    NoConvergence {
        iterations: usize,
        residual: f64,
        tolerance: f64,
        reason: String,
    },
    /// A failure of the sparse factorization or solve.
    #[error("linear algebra: {0}")]
    LinearAlgebra(String),
    /// `NewtonParams::deadline` passed before the solve had a start to report (what it was doing
    /// then).
    #[error("time limit: the deadline passed while {0}")]
    TimeLimit(String),
}
