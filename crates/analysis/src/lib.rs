//! Shape analysis on the conformal disk and sphere, in four parts:
//! - [`param`]: area-preserving parameterizations (OMT, Lie advection, on the sphere) and their
//!   distortion;
//! - [`distances`]: conformal Wasserstein distances and the pairwise pipeline;
//! - [`registration`]: Su et al.'s registration, its refinement, metrics and benchmark;
//! - [`shape_space`]: distance matrices, MDS, statistics;
//!
//! and [`plot`], the figures of all of them.
//!
//! ```
//! use shapespace_analysis::{classical_mds, DistanceMatrix};
//!
//! // three points on a line at 0, 1 and 3: one positive eigenvalue, distances recovered in 1D
//! let names = vec!["a".to_string(), "b".to_string(), "c".to_string()];
//! let d = DistanceMatrix::new(names, vec![0.0, 1.0, 3.0, 1.0, 0.0, 2.0, 3.0, 2.0, 0.0])?;
//! let mds = classical_mds(&d, 1)?;
//! let x: Vec<f64> = mds.coordinates.iter().map(|row| row[0]).collect();
//! assert!(((x[2] - x[0]).abs() - 3.0).abs() < 1e-12);
//! assert!(((x[1] - x[0]).abs() - 1.0).abs() < 1e-12);
//! assert!((mds.variance_shares[0] - 1.0).abs() < 1e-12);
//! # Ok::<(), shapespace_analysis::AnalysisError>(())
//! ```

pub mod distances;
pub mod error;
pub mod param;
pub mod plot;
pub mod registration;
pub mod shape_space;

/// The fold repair of planar maps lives in the conformal crate (the disk map uses it too).
pub use shapespace_conformal::fold_repair;

// The parts' modules also under their short paths (`shapespace_analysis::distance`, …).
pub use distances::{
    distance, invariance, pipeline, report_path, resume, rotation, run_settings, shape_cache, shard, shared_markers,
    sphere_distance,
};
pub use param::{
    area_preserving, distortion, gradient_flow, lie_advection, multiresolution, sphere_flows, sphere_param,
    spherical_mds,
};
pub use registration::{geodesic, point_location};
pub use shape_space::{matrix_io, mds, stats};

pub use error::AnalysisError;
pub use matrix_io::{read_distance_matrix, read_labels, write_distance_matrix, DistanceMatrix, Labels};
pub use mds::smacof::{smacof_mds, stress, SmacofInfo, SmacofParams, Stress};
pub use mds::{classical_mds, Mds};
pub use shape_space::{run_mds, MdsMethod, MdsParams, MdsResult};

/// The code blocks of the repository's README, compiled as doctests so that its library
/// example keeps building.
#[cfg(doctest)]
#[doc = include_str!("../../../README.md")]
pub struct ReadmeDoctests;
