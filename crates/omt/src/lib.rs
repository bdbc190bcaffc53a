//! # shapespace-omt
//!
//! Semi-discrete optimal mass transport on convex planar domains and on the unit sphere: power
//! diagrams restricted to a triangulated density, exact cell integrals, and a damped Newton solver on the heights
//! [Gu, Luo, Sun, Yau 2013; Kitagawa, Mérigot, Thibert 2019]. See `ARCHITECTURE.md`.

pub mod averaging;
pub mod cells;
pub mod error;
pub mod linear;
pub mod measure;
pub mod newton;
pub mod peaks;
pub mod power_diagram;
pub mod predicates;
pub mod quantization;
pub mod reference;
pub mod restricted;
pub mod sphere;
pub mod synthetic;

pub use cells::CellIntegrals;
pub use error::OmtError;
pub use measure::SourceMeasure;
pub use newton::{solve_ot, NewtonParams, OtSolution, StartStrategy, StopReason};
pub use sphere::{solve_sphere_ot, SphereMeasure, SphereOtParams, SphereOtSolution};
