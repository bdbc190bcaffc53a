//! The integration tests of shapespace-geometry, one module per file, built as one test binary
//! (`cargo test -p shapespace-geometry --test integration [MODULE::]`).

mod bad_input;
mod curvature;
mod datasets;
mod io;
mod seam;
mod topology;
