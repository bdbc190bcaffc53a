//! The conformal crate's error type.

use std::path::PathBuf;

use shapespace_geometry::GeometryError;

/// Errors of disk maps, markers, harmonic maps and their inputs.
///
/// `Display` follows `path:line: problem` where a file is known; otherwise it names the
/// offending element (vertex, face, edge) so the caller can locate it.
#[derive(Debug, thiserror::Error)]
pub enum ConformalError {
    /// An error from the geometry crate (reading, validation, topology).
    #[error(transparent)]
    Geometry(#[from] GeometryError),
    /// The mesh is not a topological disk (one boundary loop, χ = 1, manifold, oriented).
    #[error("not a disk: {reason} (hint: `shapespace prepare` keeps the largest component, fills holes and cuts closed surfaces open)")]
    NotDisk { reason: String },
    /// The mesh is not a closed genus-0 surface (one component, manifold, oriented, no
    /// boundary, χ = 2, every vertex used), which the sphere map needs.
    #[error("not a closed genus-0 surface: {reason}")]
    NotSphere { reason: String },
    /// Two faces traverse edge (v0, v1) in the same direction: the orientation is inconsistent.
    #[error("inconsistent face orientation at edge ({v0}, {v1}) (hint: orient the faces consistently)")]
    InconsistentOrientation { v0: u32, v1: u32 },
    /// An edge shared by more than two faces.
    #[error("non-manifold edge ({v0}, {v1})")]
    NonManifoldEdge { v0: u32, v1: u32 },
    /// A face with zero area or coincident corners: no conformal structure there.
    #[error("degenerate face {face}: {reason}")]
    DegenerateFace { face: usize, reason: String },
    /// A marker that does not fit the mesh (out of range, on the wrong part of the mesh).
    #[error("invalid marker: {0}")]
    InvalidMarker(String),
    /// A marker specification that cannot be parsed (CLI string or JSON).
    #[error("{source_name}: cannot parse marker: {message}")]
    MarkerParse { source_name: String, message: String },
    /// Reading a marker file failed. (The I/O error is part of the message, not a `source()`,
    /// so that `{:#}` chains do not print it twice.)
    #[error("{path}: {error}")]
    Io { path: PathBuf, error: std::io::Error },
    /// A constraint of the harmonic map that is inconsistent (e.g. a pinned boundary vertex, a
    /// vertex constrained twice, fewer than three anchors).
    #[error("invalid constraint: {0}")]
    InvalidConstraint(String),
    /// Sparse Cholesky factorization failed (matrix not positive definite: e.g. a disconnected
    /// mesh or a component without any Dirichlet vertex).
    /// Malformed input to a lower-level routine (lengths that do not match, bad indices).
    #[error("invalid input: {0}")]
    InvalidInput(String),
    /// The fold repair of a planar map could not produce an embedding; `folded` faces remain.
    #[error("fold repair: {message} ({folded} folded faces)")]
    FoldRepair { folded: usize, message: String },
    #[error("linear algebra: {0}")]
    LinearAlgebra(String),
    /// The intrinsic Delaunay flip loop did not finish within its flip budget.
    #[error("intrinsic Delaunay flips did not terminate after {flips} flips")]
    FlipBudgetExceeded { flips: usize },
    /// The image of some original faces is folded (orientation reversed or zero area).
    /// `boundary_out_of_order`: boundary edges whose images run clockwise on the circle (the
    /// Green's construction's harmonic conjugate is not monotone there; no interior repair can
    /// unfold their faces). `bff_fallback_error`: why the BFF fallback
    /// ([`crate::DiskMapParams::bff_fallback`]) failed too, when it was tried;
    /// `region_repair_error`: why the region repair ([`crate::DiskMapParams::region_repair`])
    /// left folds, when it was tried.
    #[error("{num_flipped} image triangles are flipped or degenerate (first: face {first_face}; flipped area fraction {flipped_area_fraction:.3e}){}{}{}", if *boundary_out_of_order > 0 { format!("; {boundary_out_of_order} boundary edges run clockwise on the circle (boundary order lost there; `--method bff` places the boundary by its own iteration)") } else { String::new() }, bff_fallback_error.as_ref().map(|e| format!("; the BFF fallback failed too: {e}")).unwrap_or_default(), region_repair_error.as_ref().map(|e| format!("; the region repair failed: {e}")).unwrap_or_default())]
    FoldedImage {
        num_flipped: usize,
        first_face: usize,
        flipped_area_fraction: f64,
        boundary_out_of_order: usize,
        bff_fallback_error: Option<String>,
        region_repair_error: Option<String>,
    },
    /// A value of the map is not representable in f64: the conformal factor range of the surface
    /// (e.g. a long protrusion, which shrinks like e^{−H/ρ}) exceeds what f64 coordinates or
    /// densities can hold. `log10_value` is the decimal exponent that was needed.
    #[error("{what} out of the f64 range at {element} (log10 = {log10_value:.1}); the surface has a protrusion too long for a conformal map in double precision")]
    OutOfRange {
        what: &'static str,
        element: String,
        log10_value: f64,
    },
    /// An interior vertex's image is on or outside the unit circle. The discrete harmonic
    /// function log|z| obeys the maximum principle only with non-negative edge weights; folded
    /// or near-degenerate triangles (angles near π) break it. (With non-negative weights the
    /// same symptom is crowding below the solve's rounding: [`ConformalError::OutOfRange`].)
    #[error("interior vertex {vertex} maps on or outside the unit circle (|z| = {radius:.9}): folded or near-degenerate triangles (angles close to 180°) broke the discrete maximum principle")]
    InteriorOutsideDisk { vertex: usize, radius: f64 },
    /// Interior vertices that no path through interior vertices connects to the centre, even
    /// after the intrinsic splits of the edges joining two boundary vertices that cut them off
    /// ([`crate::intrinsic::IntrinsicTriangulation::connect_interior`]); a harmonic disk map
    /// would put them on the boundary circle. `rounds`: the rounds of splits tried; `by_flips`:
    /// with intrinsic Delaunay flips.
    #[error("{count} interior vertices (first: vertex {vertex}) stay cut off from the centre's part of the interior after {rounds} rounds of intrinsic splits of the edges joining two boundary vertices{}, so a harmonic disk map would put them on the boundary circle", if *by_flips { " and Delaunay flips" } else { "" })]
    CutOffInterior {
        vertex: usize,
        count: usize,
        rounds: usize,
        by_flips: bool,
    },
    /// An iteration (e.g. the boundary scale factors of BFF) did not reach its tolerance.
    #[error("{what} did not converge: residual {residual:.3e} after {iterations} iterations")]
    NoConvergence {
        what: &'static str,
        iterations: usize,
        residual: f64,
    },
    /// A non-finite intermediate value (a bug or a broken input), named by stage.
    #[error("non-finite value in {stage} at vertex {vertex}")]
    NonFinite { stage: &'static str, vertex: usize },
}
