//! The geometry crate's error type.

use std::path::PathBuf;

/// Errors of mesh reading, validation, topology and preparation.
///
/// `Display` follows `path:line: problem` where a file and line are known.
#[derive(Debug, thiserror::Error)]
pub enum GeometryError {
    /// An I/O failure while reading or writing `path`. (The I/O error is part of the message,
    /// not a `source()`, so that `{:#}` chains do not print it twice.)
    #[error("{path}: {error}")]
    Io { path: PathBuf, error: std::io::Error },
    /// A parse error at a line (1-based) of a text file, or at an element of a binary one.
    #[error("{path}:{line}: {message}")]
    Parse {
        path: PathBuf,
        line: usize,
        message: String,
    },
    /// A parse error at a byte offset of a binary file (binary PLY); `message` names the element
    /// and its index, e.g. `face 17: vertex index 9000 out of range`.
    #[error("{path}: byte {offset}: {message}")]
    BinaryParse {
        path: PathBuf,
        offset: u64,
        message: String,
    },
    /// A file format that is not recognised (by extension or content).
    #[error("{path}: unsupported mesh format ({message})")]
    UnsupportedFormat { path: PathBuf, message: String },
    /// A face references a vertex that does not exist.
    #[error("face {face} references vertex {index}, but the mesh has {num_vertices} vertices")]
    IndexOutOfRange {
        face: usize,
        index: i64,
        num_vertices: usize,
    },
    /// A vertex coordinate is NaN or infinite.
    #[error("vertex {vertex} has a non-finite coordinate")]
    NonFiniteCoordinate { vertex: usize },
    /// An edge shared by more than two faces.
    #[error("non-manifold edge ({v0}, {v1}) shared by {num_faces} faces")]
    NonManifoldEdge { v0: u32, v1: u32, num_faces: usize },
    /// A vertex whose incident faces form more than one fan.
    #[error("non-manifold vertex {vertex} ({num_fans} separate fans of faces)")]
    NonManifoldVertex { vertex: u32, num_fans: usize },
    /// The mesh has the wrong topology for the operation (e.g. not a disk).
    #[error("wrong topology: {0}")]
    Topology(String),
    /// A degenerate face (repeated index or zero area) where a proper triangle is needed.
    #[error("degenerate face {face}: {reason}")]
    DegenerateFace { face: usize, reason: String },
    /// Any other invalid input, with an explanation.
    #[error("{0}")]
    Invalid(String),
    /// An error in a numerical factorization or solve.
    #[error("linear algebra: {0}")]
    LinearAlgebra(String),
    /// Wraps another error with the file it came from (the inner error is part of the message,
    /// not a `source()`, so that `{:#}` chains do not print it twice).
    #[error("{path}: {error}")]
    WithPath { path: PathBuf, error: Box<GeometryError> },
}

impl GeometryError {
    /// Attaches a path to an error that has none.
    pub fn with_path(self, path: impl Into<PathBuf>) -> Self {
        match self {
            e @ (GeometryError::Io { .. }
            | GeometryError::Parse { .. }
            | GeometryError::BinaryParse { .. }
            | GeometryError::UnsupportedFormat { .. }
            | GeometryError::WithPath { .. }) => e,
            e => GeometryError::WithPath {
                path: path.into(),
                error: Box::new(e),
            },
        }
    }
}
