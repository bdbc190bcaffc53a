//! Shape-space analysis: distance matrices and labels, classical MDS, nearest-neighbour and
//! silhouette statistics, metric checks, and plots.

pub mod area_preserving;
pub mod distance;
pub mod distortion;
pub mod error;
pub mod fold_repair;
pub mod geodesic;
pub mod invariance;
pub mod matrix_io;
pub mod mds;
pub mod pipeline;
pub mod plot;
pub mod point_location;
pub mod registration;
pub mod report_path;
pub mod resume;
pub mod shape_cache;
pub mod shape_space;
pub mod shard;
pub mod shared_markers;
pub mod stats;

pub use error::AnalysisError;
pub use matrix_io::{read_distance_matrix, read_labels, write_distance_matrix, DistanceMatrix, Labels};
pub use mds::{classical_mds, Mds};
pub use shape_space::{run_mds, MdsParams, MdsResult};

/// The code blocks of the repository's README, compiled as doctests so that its library
/// example keeps building.
#[cfg(doctest)]
#[doc = include_str!("../../../README.md")]
pub struct ReadmeDoctests;
