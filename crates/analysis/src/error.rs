//! The error type of the analysis crate.
//!
//! Every variant carries what a caller needs to point at the problem: a path and a 1-based line
//! for file contents (`Display` as `path:line: problem`), shape names for matrix entries.

use std::path::PathBuf;

/// Errors of the analysis crate (matrix and label I/O, MDS, statistics, plots).
#[derive(Debug, thiserror::Error)]
pub enum AnalysisError {
    /// Reading or writing a file failed. (The I/O error is part of the message, not a
    /// `source()`, so that `{:#}` chains do not print it twice.)
    #[error("{}: {error}", path.display())]
    Io { path: PathBuf, error: std::io::Error },
    /// The resume checkpoint of a pairwise run (`pairs.partial.csv`) could not be created or
    /// written; the run stops (its pairs could not be kept).
    #[error("{}: cannot write the resume checkpoint: {message}; the run stopped", path.display())]
    Checkpoint { path: PathBuf, message: String },
    /// Another run holds the lock of the output folder (`pipeline::lock_output_folder`).
    #[error("{}: another shapespace run is writing into this folder; wait for it to end or choose another output folder", path.display())]
    Locked { path: PathBuf },
    /// A mesh file could not be read (the error names the file).
    #[error(transparent)]
    Mesh(shapespace_geometry::GeometryError),
    /// A CSV file is malformed at a given 1-based line.
    #[error("{}:{line}: {message}", path.display())]
    Parse { path: PathBuf, line: u64, message: String },
    /// The distance matrix has `rows` rows but a row or the name list has `cols` entries.
    #[error("distance matrix is not square: {rows} rows but {cols} columns")]
    NotSquare { rows: usize, cols: usize },
    /// The same shape name occurs twice in a distance matrix.
    #[error("duplicate shape name {name:?} in the distance matrix")]
    DuplicateName { name: String },
    /// A distance is negative or infinite (missing distances are NaN and reported as
    /// [`AnalysisError::MissingDistance`] where they are not allowed).
    #[error("invalid distance {value} between {a:?} and {b:?} (must be finite and >= 0)")]
    InvalidDistance { a: String, b: String, value: f64 },
    /// A distance so large that the squared distances of classical MDS overflow f64.
    #[error("distance {value:e} between {a:?} and {b:?} is too large for classical MDS (the squared distances overflow); rescale the matrix")]
    DistanceTooLarge { a: String, b: String, value: f64 },
    /// Distances so small that the eigenvalues of classical MDS (squared distances) underflow
    /// f64: the largest is below √(smallest normal f64) ≈ 1.5e-154.
    #[error("the largest distance, {value:e} between {a:?} and {b:?}, is too small for classical MDS (its square, the scale of the eigenvalues, underflows); rescale the matrix (MDS is scale-equivariant)")]
    DistanceTooSmall { a: String, b: String, value: f64 },
    /// A distance needed by the computation is missing (empty cell or NaN: a failed pair).
    #[error("missing distance between {a:?} and {b:?} (empty or NaN cell); MDS needs a complete matrix")]
    MissingDistance { a: String, b: String },
    /// `|d_ab − d_ba|` exceeds the tolerance allowed by the caller.
    #[error("distance matrix is not symmetric: d({a:?},{b:?}) = {d_ab} but d({b:?},{a:?}) = {d_ba}")]
    Asymmetric { a: String, b: String, d_ab: f64, d_ba: f64 },
    /// A shape name matches more than one row of the labels file.
    #[error("{}:{line}: label row {key:?} matches shape {name:?}, which already matched line {first_line}", path.display())]
    AmbiguousLabel {
        path: PathBuf,
        line: u64,
        key: String,
        name: String,
        first_line: u64,
    },
    /// The labels do not have one row per shape.
    #[error("labels have {labels} rows but the distance matrix has {shapes} shapes")]
    LabelCountMismatch { labels: usize, shapes: usize },
    /// A label column asked for does not exist.
    #[error("label column {column:?} not found (available: {})", available.join(", "))]
    UnknownLabelColumn { column: String, available: Vec<String> },
    /// An option that refers to label columns was given without a labels file.
    #[error("{what} needs a labels file")]
    LabelsRequired { what: String },
    /// Too few shapes for the computation.
    #[error("{what} needs at least {needed} shapes, got {got}")]
    TooFewShapes {
        what: &'static str,
        needed: usize,
        got: usize,
    },
    /// The number of MDS dimensions is out of range.
    #[error("MDS dimension {dims} must be between 1 and the number of shapes ({n})")]
    InvalidDims { dims: usize, n: usize },
    /// The dense symmetric eigensolver did not converge.
    #[error("eigendecomposition of the {n}x{n} double-centred matrix did not converge")]
    EigenNoConvergence { n: usize },
    /// Results could not be serialized to JSON.
    #[error("{}: cannot serialize results: {message}", path.display())]
    Serialize { path: PathBuf, message: String },
    /// The conformal disk map (or its distortion evaluation) failed.
    #[error("conformal disk map")]
    DiskMap(#[source] shapespace_conformal::ConformalError),
    /// The conformal sphere map of a closed genus-0 surface failed.
    #[error("conformal sphere map")]
    SphereMap(#[source] shapespace_conformal::ConformalError),
    /// The optimal transport step of an area-preserving map failed or did not converge.
    #[error("optimal transport")]
    Transport(#[source] shapespace_omt::OmtError),
    /// A shape could not be prepared for distance computations (not a disk, bad markers, ...).
    #[error("{name}: {message}")]
    Shape { name: String, message: String },
    /// A registration pair of a closed surface (registered on the sphere) and a surface with a
    /// boundary (registered on the disk), naming both.
    #[error("cannot register {closed} (closed, registered on the sphere) with {with_boundary} (with a boundary, registered on the disk): cut a disk from the closed one (`shapespace prepare`) or close the other")]
    MixedDomains { closed: String, with_boundary: String },
    /// A pair of shapes failed (the OT solver returned an error).
    #[error("{a} -> {b}: {message}")]
    Pair { a: String, b: String, message: String },
    /// A map onto the sphere was asked of a mesh that is not a closed genus-0 surface
    /// (`class` is what it is, `reasons` why).
    #[error("not a closed genus-0 surface ({class}), so it has no map onto the sphere: {}", reasons.join("; "))]
    NotClosedGenusZero { class: String, reasons: Vec<String> },
    /// Invalid input to a computation (weights, parameters), with the reason.
    #[error("invalid input: {0}")]
    InvalidInput(String),
    /// A plot could not be drawn or written.
    #[error("{}: plotting failed: {message}", path.display())]
    Plot { path: PathBuf, message: String },
    /// A registration landmark that is malformed, out of range, repeated or on the boundary;
    /// `source_name` is the file (or `pairs`) it came from, `landmark` its name or line.
    #[error("{source_name}: landmark {landmark}: {message}")]
    Landmark {
        source_name: String,
        landmark: String,
        message: String,
    },
    /// Invalid plot input (empty data, mismatched lengths, bad range).
    #[error("invalid plot input: {message}")]
    PlotInput { message: String },
    /// The fold repair of a planar map could not produce an embedding; `folded` faces remain.
    #[error("fold repair: {message} ({folded} folded faces)")]
    FoldRepair { folded: usize, message: String },
    /// The OMT gradient flow (`gradient_flow`) cannot start: the fold repair of its first
    /// mass-preserving map (the Lie-advection map) failed and `folded` faces stay folded.
    #[error(
        "the OMT gradient flow cannot start: its first mass-preserving map keeps {folded} folded faces ({reason})"
    )]
    FlowStartFolded { folded: usize, reason: String },
    /// An area-correcting flow could not take a step without folding a face.
    #[error("the flow stalled at t = {time}: every step down to {step:e} folded a face ({attempts} attempts)")]
    FlowStalled { time: f64, step: f64, attempts: usize },
}

impl AnalysisError {
    /// An error of [`crate::fold_repair`] (a conformal-crate routine) as this crate's error:
    /// its own input and repair failures keep their kind, anything else is a disk-map error.
    pub fn from_fold_repair(e: shapespace_conformal::ConformalError) -> Self {
        use shapespace_conformal::ConformalError as C;
        match e {
            C::InvalidInput(message) => AnalysisError::InvalidInput(message),
            C::FoldRepair { folded, message } => AnalysisError::FoldRepair { folded, message },
            other => AnalysisError::DiskMap(other),
        }
    }

    /// Wraps an I/O error with the path it concerns.
    pub fn io(path: impl Into<PathBuf>, source: std::io::Error) -> Self {
        AnalysisError::Io {
            path: path.into(),
            error: source,
        }
    }

    /// A CSV reading or writing error of `path`, worded for users: the line, and what is wrong
    /// with it (not the parser's internal record).
    pub fn csv(path: impl Into<PathBuf>, err: csv::Error) -> Self {
        let line = err.position().map_or(0, |p| p.line());
        let message = match err.kind() {
            csv::ErrorKind::UnequalLengths { expected_len, len, .. } => {
                format!("{len} fields where the earlier rows have {expected_len}")
            }
            csv::ErrorKind::Utf8 { .. } => "not valid UTF-8 text".to_string(),
            _ => err.to_string(),
        };
        match err.into_kind() {
            csv::ErrorKind::Io(source) => AnalysisError::io(path, source),
            _ => AnalysisError::parse(path, line, message),
        }
    }

    /// A [`AnalysisError::Checkpoint`] failure of `path`.
    pub fn checkpoint(path: impl Into<PathBuf>, message: impl Into<String>) -> Self {
        AnalysisError::Checkpoint {
            path: path.into(),
            message: message.into(),
        }
    }

    /// A parse error at `path:line`.
    pub fn parse(path: impl Into<PathBuf>, line: u64, message: impl Into<String>) -> Self {
        AnalysisError::Parse {
            path: path.into(),
            line,
            message: message.into(),
        }
    }
}

/// The error and its sources joined by `: ` (for messages that keep the whole cause).
pub fn error_chain(e: &dyn std::error::Error) -> String {
    let mut s = e.to_string();
    let mut cur = e.source();
    while let Some(c) = cur {
        s.push_str(": ");
        s.push_str(&c.to_string());
        cur = c.source();
    }
    s
}
