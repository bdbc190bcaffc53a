//! Shape-space analysis: distance matrices and labels, classical MDS, nearest-neighbour and
//! silhouette statistics, metric checks, and plots.
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

pub mod area_preserving;
pub mod distance;
pub mod distortion;
pub mod error;
/// The fold repair of planar maps lives in the conformal crate (the disk map uses it too).
pub use shapespace_conformal::fold_repair;
pub mod geodesic;
pub mod gradient_flow;
pub mod invariance;
pub mod lie_advection;
pub mod matrix_io;
pub mod mds;
pub mod pipeline;
pub mod plot;
pub mod point_location;
pub mod registration;
pub mod report_path;
pub mod resume;
pub mod rotation;
pub mod run_settings;
pub mod shape_cache;
pub mod shape_space;
pub mod shard;
pub mod shared_markers;
pub mod sphere_distance;
pub mod sphere_param;
pub mod stats;

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
