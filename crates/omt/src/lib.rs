//! # shapespace-omt
//!
//! Semi-discrete optimal mass transport on convex planar domains and on the unit sphere: power
//! diagrams restricted to a triangulated density, exact cell integrals, and a damped Newton solver on the heights
//! [Gu, Luo, Sun, Yau 2013; Kitagawa, Mérigot, Thibert 2019]. See `ARCHITECTURE.md`.
//!
//! ```
//! use shapespace_omt::{solve_ot, NewtonParams, SourceMeasure};
//!
//! // the uniform unit square to four points of equal mass: at the solution each power cell is
//! // a quarter of the square, and the cost is that of the quadrant centres
//! let square = SourceMeasure::unit_square()?;
//! let points = [[0.25, 0.25], [0.75, 0.25], [0.75, 0.75], [0.25, 0.75]];
//! let solution = solve_ot(&square, &points, &[0.25; 4], &NewtonParams::default())?.into_result()?;
//! for mass in &solution.cells.masses {
//!     assert!((mass - 0.25).abs() < 1e-9);
//! }
//! // each quadrant has second moment about its centre 2 · (1/2)² / 12 · (1/4) = 1/96
//! assert!((solution.cost - 4.0 / 96.0).abs() < 1e-9);
//! # Ok::<(), shapespace_omt::OmtError>(())
//! ```

pub mod averaging;
pub mod cells;
pub mod error;
pub mod linear;
pub mod measure;
pub mod newton;
pub mod peaks;
mod polygon;
pub mod power_diagram;
pub mod predicates;
pub mod prepared;
pub mod quantization;
// Test oracles and synthetic inputs: public for the integration tests, benchmarks and probes
// (and the brute-force backend), not part of the API: hidden from the docs.
#[doc(hidden)]
pub mod reference;
pub mod restricted;
pub mod sphere;
#[doc(hidden)]
pub mod synthetic;

pub use cells::CellIntegrals;
pub use error::OmtError;
pub use measure::SourceMeasure;
pub use newton::{solve_ot, solve_ot_prepared, NewtonParams, OtSolution, StartStrategy, StopReason};
pub use prepared::PreparedMeasure;
pub use sphere::{solve_sphere_ot, SphereMeasure, SphereOtParams, SphereOtSolution};
