//! The integration tests of shapespace-omt, one module per file, built as one test binary
//! (`cargo test -p shapespace-omt --test integration [MODULE::]`).

mod averaging;
mod common;
mod power_diagram;
mod restricted;
mod solver;
mod solver_pot;
mod solver_radial;
mod solver_stress;
mod sphere;
