//! The integration tests of shapespace-conformal, one module per file, built as one test binary
//! (`cargo test -p shapespace-conformal --test integration [MODULE::]`).

mod bff;
mod cap;
mod common;
mod degenerate;
mod errors;
mod harmonic;
mod invariance;
mod markers;
mod planar;
mod real;
mod sphere;
mod tubes;
