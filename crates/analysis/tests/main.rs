//! The integration tests of shapespace-analysis, one module per file, built as one test binary
//! (`cargo test -p shapespace-analysis --test integration [MODULE::]`).

mod area_preserving;
mod distance;
mod faces40;
mod gradient_flow;
mod invariance;
mod lie_advection;
mod matrix_io;
mod mds;
mod multiresolution;
mod outside;
mod plot;
mod registration;
mod registration_probe;
mod remeshed_bench;
mod remeshed_markers;
mod scans;
mod shape_space;
mod sphere_disk_ranking;
mod sphere_distance;
mod sphere_flows;
mod sphere_param;
mod sphere_registration;
mod spherical_mds;
mod stats;
mod zoomout;
mod zoomout_landmarks;
