//! The settings of a distances run and its per-file records: what
//! [`run_distances`](crate::pipeline::run_distances) takes and reports, and what
//! [`crate::resume`] compares when it decides which earlier pairs a run may take. Apart from
//! the pipeline so that `resume` does not import it.

use std::path::PathBuf;

use serde::Serialize;
use shapespace_conformal::{BoundaryMarker, CenterMarker, DiskMapParams};

use crate::distance::PairwiseOptions;

/// How markers are chosen for each file.
#[derive(Clone, Debug, Default)]
pub struct MarkerOptions {
    /// `--center` for every file (overrides marker files).
    pub center: Option<CenterMarker>,
    /// `--boundary-marker` for every file (overrides marker files).
    pub boundary: Option<BoundaryMarker>,
    /// One marker file for all files (a set with shared vertex order).
    pub marker_file: Option<PathBuf>,
    /// Closed surfaces (the sphere): vertices p₁, p₂, p₃ ↦ 0, 1, ∞ in every file (a set with
    /// shared vertex order); without them the sphere maps are Möbius-centred and each pair is
    /// minimized over rotations.
    pub sphere_markers: Option<[u32; 3]>,
}

/// Where a run compares its shapes.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize, serde::Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum Domain {
    /// The sphere when every readable file is closed, the disk when none is; a run mixing
    /// the two is refused.
    #[default]
    Auto,
    /// Disk maps (a closed file fails as not a disk).
    Disk,
    /// Sphere maps (a file with a boundary fails as not closed).
    Sphere,
}

/// A file's resolved markers and where they came from, for the report. `center` and `boundary`
/// serialize as in a marker file (`123` or `{"face": f, "bary": [..]}`, and a vertex index).
#[derive(Clone, Debug, Serialize, serde::Deserialize)]
pub struct MarkerChoice {
    pub center: shapespace_conformal::markers::ResolvedCenter,
    pub boundary: u32,
    pub source: String,
    /// Unit 3D direction from the center marker to the boundary marker (for
    /// [`crate::shared_markers::marker_outliers`]).
    #[serde(skip)]
    pub axis: Option<[f64; 3]>,
}

/// Options of [`run_distances`](crate::pipeline::run_distances).
#[derive(Clone, Debug, Default)]
pub struct DistancesOptions {
    pub markers: MarkerOptions,
    pub pairwise: PairwiseOptions,
    pub disk_map: DiskMapParams,
    /// Take the directed pairs that earlier runs in the output folder computed from the same
    /// files, markers and solver settings, with the same executable, from their files instead
    /// of computing them again (see [`run_distances`](crate::pipeline::run_distances)). Not with `pairwise.warm_start` (a warm-started pair depends on
    /// the pairs solved before it).
    pub resume: bool,
    /// Quantize each shape's target measure to at most this many points
    /// ([`crate::distance::quantize_target`]): faster pairs at a measured loss of accuracy.
    pub target_points: Option<usize>,
    /// Average each shape's source density over a coarser triangulation of at most this many
    /// triangles ([`crate::distance::coarsen_source`]): cheaper integration at a measured loss
    /// of accuracy.
    pub source_faces: Option<usize>,
    /// Compute only this shard of the pairs ([`crate::shard`]); `merge_shards` assembles the
    /// shards' folders. Not with `pairwise.warm_start` or `pairwise.debias`.
    pub shard: Option<crate::shard::Shard>,
    /// Keep each shape's per-shape work in this folder and take it from there when the same
    /// file, markers, settings and executable come again ([`crate::shape_cache`]).
    pub cache: Option<PathBuf>,
    /// Disk or sphere ([`Domain::Auto`]: from the files).
    pub domain: Domain,
}

/// Per-file outcome of the preparation stage.
#[derive(Clone, Debug, Serialize, serde::Deserialize)]
pub struct ShapeReport {
    pub name: String,
    #[serde(serialize_with = "crate::report_path::one")]
    pub path: PathBuf,
    /// SHA-256 of the file's bytes (hex, as `sha256sum` prints it); None when it cannot be read.
    pub sha256: Option<String>,
    pub ok: bool,
    /// Why the file failed, starting with its path.
    pub error: Option<String>,
    pub vertices: Option<usize>,
    pub faces: Option<usize>,
    pub markers: Option<MarkerChoice>,
    pub seconds: f64,
    /// Range of the pushed-forward density (min, max) on the disk.
    pub density_range: Option<[f64; 2]>,
    /// Flipped image triangles of the conformal map.
    pub flipped_faces: Option<usize>,
    /// Faces the Green's-function map folded when the conformal map is BFF's instead
    /// (`DiskMapParams::bff_fallback`); None for the Green's-function map.
    pub bff_fallback_after_green_folds: Option<usize>,
    /// The conformal map's construction, as `DiskMapInfo::method` names it (a region repair and
    /// the vertices it moved included); None for a file that failed.
    #[serde(default)]
    pub conformal_method: Option<String>,
    /// Vertices the disk map's region repair moved (a Tutte re-embedding of the folds its local
    /// repair left: not conformal there, and the densities there are the repair's); absent
    /// when it did not run. `distances` warns about such files.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub conformal_repair_moved: Option<usize>,
}

/// The file in the output folder that holds the pairs finished so far while a run is going on,
/// one `pairs.csv` row each, in the order they finish, flushed row by row: what a run that is
/// killed or crashes leaves behind. Removed once `pairs.csv` and `report.json` are written.
pub const PARTIAL_PAIRS: &str = "pairs.partial.csv";

/// Where a run moves a [`PARTIAL_PAIRS`] file it finds (left by a run that was stopped), so that
/// starting again in the same folder does not erase those pairs (an older one is replaced).
pub const PREVIOUS_PARTIAL_PAIRS: &str = "pairs.partial.prev.csv";

/// The [`RunIdentity`](crate::resume::RunIdentity) of the run writing [`PARTIAL_PAIRS`], written before its first row.
pub const PARTIAL_IDENTITY: &str = "pairs.partial.json";

/// Where [`PARTIAL_IDENTITY`] goes with [`PREVIOUS_PARTIAL_PAIRS`].
pub const PREVIOUS_PARTIAL_IDENTITY: &str = "pairs.partial.prev.json";
