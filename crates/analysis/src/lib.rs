//! Shape-space analysis: distance matrices and labels, classical MDS, nearest-neighbour and
//! silhouette statistics, metric checks, and plots.

pub mod error;
pub mod matrix_io;
pub mod mds;
pub mod plot;
pub mod stats;

pub use error::AnalysisError;
pub use matrix_io::{read_distance_matrix, read_labels, write_distance_matrix, DistanceMatrix, Labels};
pub use mds::{classical_mds, Mds};
