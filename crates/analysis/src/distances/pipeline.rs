//! The main job: conformal Wasserstein distances among mesh files, written as files a
//! statistician can use directly (`distances.csv`, `pairs.csv`, `report.json`).
//!
//! Each file is read, validated and mapped once ([`crate::distance::prepare_shape`]); a file that
//! fails (unreadable, not a disk, bad markers) is reported with its reason and its row and
//! column of the matrix are empty, while all other pairs still complete.

use std::collections::{HashMap, HashSet};
use std::path::{Path, PathBuf};
use std::time::Instant;

use rayon::prelude::*;
use serde::Serialize;
use shapespace_conformal::{MarkerFile, Markers};
use shapespace_geometry::io::{write_atomically, AtomicFile};
use shapespace_geometry::TriMesh;

use crate::distance::{
    directed_pairs, matrix_from_pairs, pairwise_distances_of, prepare_shape, PairRecord, Prepared, PreparedShape,
};
use crate::error::AnalysisError;
use crate::matrix_io::{write_distance_matrix, DistanceMatrix};
pub use crate::resume::{build_identity, InputIdentity, ResumeReport, RunIdentity};
use crate::resume::{earlier_pairs, pair_row, run_identity, sha256_hex, PAIRS_HEADER};
pub use crate::run_settings::{
    DistancesOptions, Domain, MarkerChoice, MarkerOptions, ShapeReport, PARTIAL_IDENTITY, PARTIAL_PAIRS,
    PREVIOUS_PARTIAL_IDENTITY, PREVIOUS_PARTIAL_PAIRS,
};
use crate::stats::{summarize, Summary};

/// The markers of one mesh file of `num_vertices` vertices: command-line values first, then
/// `marker_file`, then the sidecar (`NAME.landmarks.json`, else `landmarks.json` beside the
/// mesh), else `auto`. A marker file whose named landmarks lie outside the mesh's vertex range
/// is an error even where the landmarks are not used (the file does not belong to the mesh).
pub fn markers_for(
    path: &Path,
    options: &MarkerOptions,
    num_vertices: usize,
) -> Result<(Markers, String), AnalysisError> {
    let file = match &options.marker_file {
        Some(p) => Some(p.clone()),
        None => MarkerFile::sidecar_path(path),
    };
    let shape_error = |message: String| AnalysisError::Shape {
        name: path.display().to_string(),
        message,
    };
    let (mut markers, source) = match &file {
        Some(p) => {
            let parsed = MarkerFile::from_json_file(p).map_err(|e| shape_error(e.to_string()))?;
            if let Some((name, v)) = parsed.landmarks.iter().find(|(_, &v)| v as usize >= num_vertices) {
                return Err(shape_error(format!(
                    "marker file {}: landmark \"{name}\" is vertex {v}, out of range for a mesh of {num_vertices} vertices",
                    p.display()
                )));
            }
            (parsed.markers, p.display().to_string())
        }
        None => (Markers::default(), "auto".to_string()),
    };
    if let Some(c) = &options.center {
        markers.center = c.clone();
    }
    if let Some(b) = &options.boundary {
        markers.boundary = b.clone();
    }
    Ok((markers, source))
}

/// A file read for [`run_distances`]: its SHA-256, the seconds spent, and its mesh with its
/// markers and their source (or why it could not be read).
type LoadedFile = (Option<String>, f64, Result<(TriMesh, Markers, String), String>);

/// Timing of the stages, seconds (wall clock, except `pairs_cpu`: the sum over pairs).
#[derive(Clone, Debug, Default, Serialize, serde::Deserialize)]
pub struct StageTimings {
    pub prepare_wall: f64,
    pub pairs_wall: f64,
    pub pairs_cpu: f64,
    pub write: f64,
    pub total: f64,
}

/// Everything `report.json` holds.
#[derive(Clone, Debug, Serialize, serde::Deserialize)]
pub struct DistancesReport {
    pub shapespace_version: String,
    pub inputs: Vec<ShapeReport>,
    pub options: ReportOptions,
    pub threads: usize,
    pub timings: StageTimings,
    /// Directed pairs in `pairs.csv`, those taken from earlier runs included (`resumed`).
    pub pairs_computed: usize,
    pub pairs_failed: usize,
    pub failures: Vec<String>,
    /// Newton iterations over the pairs.
    pub iterations: Option<Summary>,
    /// Relative asymmetry |d(a→b) − d(b→a)| / mean over the unordered pairs (with symmetrize).
    pub asymmetry: Option<Summary>,
    /// With debiasing: the self-costs and the clamped pairs.
    pub debias: Option<DebiasReport>,
    /// |cost − dual cost| / cost over the converged pairs: the a-posteriori check of the costs
    /// (first order in the mass residual; the dual cost is a lower bound on the exact one).
    pub cost_dual_gap: Option<Summary>,
    /// With [`DistancesOptions::resume`]: the pairs taken from earlier runs, and what each
    /// earlier file gave or why it was not used.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub resumed: Option<ResumeReport>,
    /// Files whose automatic markers differ strongly from the others'
    /// ([`crate::shared_markers::marker_outliers`]).
    pub marker_warnings: Vec<String>,
    /// What the pairs depend on, for a later `resume`.
    pub resume_key: RunIdentity,
    #[serde(serialize_with = "crate::report_path::many")]
    pub files: Vec<PathBuf>,
    /// The shard of the pairs this run computed (`distances --shard K/N`); absent for a whole
    /// run and for the merge of the shards.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub shard: Option<crate::shard::Shard>,
}

/// The options as recorded in the report.
#[derive(Clone, Debug, Serialize, serde::Deserialize)]
pub struct ReportOptions {
    pub symmetrize: bool,
    /// Relative mass tolerance of the finest level (the distances' accuracy).
    pub tolerance: f64,
    /// Relative mass tolerance of the coarse levels of the coarse-to-fine start.
    pub coarse_tolerance: f64,
    /// Linear solver of the Newton directions (`LinearSolver`'s debug form).
    pub linear_solver: String,
    pub max_iterations: usize,
    pub warm_start: bool,
    pub intrinsic_delaunay: bool,
    /// Per-pair time limit, seconds (`PairwiseOptions::time_limit`).
    pub pair_time_limit: Option<f64>,
    /// `DistancesOptions::target_points`.
    pub target_points: Option<usize>,
    /// `Fixed` (the markers' alignment) or `Rotation` (minimum over rotations of the disk).
    pub invariance: crate::invariance::Invariance,
    /// Whether the matrix holds debiased distances √max(0, c(a, b) − c(b, b)).
    pub debias: bool,
    /// `sphere` for closed surfaces compared on the sphere (absent for disks).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub domain: Option<String>,
}

/// Each shape's self-cost c(s, s) and the pairs clamped at 0 by the debiasing
/// ([`crate::distance::PairwiseOptions::debias`]).
#[derive(Clone, Debug, Serialize, serde::Deserialize)]
pub struct DebiasReport {
    /// Self-cost per input, in the order of `inputs` (null where the shape failed).
    pub self_costs: Vec<Option<f64>>,
    /// Directed pairs whose cost was below the target's self-cost (distance 0).
    pub clamped_pairs: usize,
}

/// The result of [`run_distances`].
#[derive(Clone, Debug)]
pub struct DistancesRun {
    pub matrix: DistanceMatrix,
    pub pairs: Vec<PairRecord>,
    pub report: DistancesReport,
    /// Shapes taken from [`DistancesOptions::cache`] (not in the report, so that a run with and
    /// without the cache writes the same files).
    pub cache_hits: usize,
}

/// Shape name of a file: its stem, or, when stems repeat, the shortest suffix of its path
/// (folders and stem, joined by `/`) that no other file shares: `a/cat` and `b/cat` for
/// `data/a/cat.obj` and `data/b/cat.obj`, `x/cat` and `y/x/cat` when the folder names repeat
/// too; files that differ only in their extension (`cat.obj`, `cat.off`) keep it (`cat.obj`).
/// An absolute path's full name starts with `/` (`/x/cat` beside the relative `x/cat`), and
/// bytes that are not UTF-8 are written as `\xNN` (two such names stay apart). The same path
/// given twice keeps one name (which [`run_distances`] refuses as a duplicate).
pub fn shape_names(paths: &[PathBuf]) -> Vec<String> {
    use std::path::Component;
    // the path's folders and its stem, or (`with_extension`) its file name; a root is an empty
    // first part
    let split = |p: &PathBuf, with_extension: bool| {
        let mut parts: Vec<String> = p
            .parent()
            .map(|d| {
                d.components()
                    .filter_map(|c| match c {
                        Component::Normal(s) => Some(escaped(s)),
                        Component::ParentDir => Some("..".to_string()),
                        Component::RootDir => Some(String::new()),
                        _ => None,
                    })
                    .collect()
            })
            .unwrap_or_default();
        let last = if with_extension { p.file_name() } else { p.file_stem() };
        parts.push(last.map(escaped).unwrap_or_default());
        parts
    };
    let stems: Vec<Vec<String>> = paths.iter().map(|p| split(p, false)).collect();
    let files: Vec<Vec<String>> = paths.iter().map(|p| split(p, true)).collect();
    let suffix = |parts: &[Vec<String>], i: usize, k: usize| parts[i][parts[i].len().saturating_sub(k)..].join("/");
    // the shortest suffix of `parts[i]` no other path shares, or None when all of it is shared
    // by a different path; all of `parts[i]` may equal a suffix of a longer path (that one then
    // takes a longer name)
    let shortest = |parts: &[Vec<String>], i: usize| {
        let len = parts[i].len();
        (1..=len).find_map(|k| {
            let name = suffix(parts, i, k);
            let clash = (0..paths.len()).any(|j| {
                j != i && paths[j] != paths[i] && suffix(parts, j, k) == name && !(k == len && parts[j].len() > len)
            });
            (!clash).then_some(name)
        })
    };
    (0..paths.len())
        .map(|i| {
            shortest(&stems, i)
                .or_else(|| shortest(&files, i))
                .unwrap_or_else(|| files[i].join("/"))
        })
        .collect()
}

/// A path component as text, bytes that are not UTF-8 as `\xNN` (on Unix; elsewhere lossy), so
/// that different names stay different.
fn escaped(s: &std::ffi::OsStr) -> String {
    #[cfg(unix)]
    {
        use std::fmt::Write;
        use std::os::unix::ffi::OsStrExt;
        let mut out = String::new();
        for chunk in s.as_bytes().utf8_chunks() {
            out.push_str(chunk.valid());
            for b in chunk.invalid() {
                let _ = write!(out, "\\x{b:02x}");
            }
        }
        out
    }
    #[cfg(not(unix))]
    {
        s.to_string_lossy().into_owned()
    }
}

/// [`PARTIAL_PAIRS`], appended to from the worker threads: its writer, or after the first
/// failed write, that failure; `failed` is set with it (the run's stop signal).
struct PartialPairs {
    path: PathBuf,
    identity: RunIdentity,
    writer: std::sync::Mutex<Result<csv::Writer<std::fs::File>, AnalysisError>>,
    failed: std::sync::atomic::AtomicBool,
}

impl PartialPairs {
    /// Creates the file (a new one: never an existing file or a symbolic link, which the
    /// caller has moved aside); an error here is an output error of the run.
    fn create(path: PathBuf, identity: RunIdentity) -> Result<Self, AnalysisError> {
        let file = std::fs::OpenOptions::new()
            .write(true)
            .create_new(true)
            .open(&path)
            .map_err(|e| AnalysisError::checkpoint(&path, e.to_string()))?;
        let mut writer = csv::Writer::from_writer(file);
        writer
            .write_record(PAIRS_HEADER)
            .and_then(|()| writer.flush().map_err(csv::Error::from))
            .map_err(|e| AnalysisError::checkpoint(&path, e.to_string()))?;
        Ok(Self {
            path,
            identity,
            writer: std::sync::Mutex::new(Ok(writer)),
            failed: std::sync::atomic::AtomicBool::new(false),
        })
    }

    /// Appends one row and flushes it to the file. The first failure is kept and sets
    /// [`PartialPairs::failed`]: a run whose pairs can no longer be saved stops, since a kill
    /// or a full disk later would lose them all.
    fn append(&self, record: &PairRecord) {
        let mut state = self.writer.lock().unwrap_or_else(|poisoned| poisoned.into_inner());
        if let Ok(w) = &mut *state {
            let written = w
                .write_record(pair_row(&self.identity, record))
                .map_err(|e| e.to_string())
                .and_then(|()| w.flush().map_err(|e| e.to_string()));
            if let Err(e) = written {
                *state = Err(AnalysisError::checkpoint(&self.path, e));
                self.failed.store(true, std::sync::atomic::Ordering::Relaxed);
            }
        }
    }

    /// Closes the file and returns the first append failure, if any.
    fn finish(self) -> Result<(), AnalysisError> {
        let state = self
            .writer
            .into_inner()
            .unwrap_or_else(|poisoned| poisoned.into_inner());
        state.map(drop)
    }
}

/// The per-shape stage of a run ([`prepare_inputs`]): each input's prepared shape (None where
/// it failed) and its report, the warnings about automatic markers, and the wall-clock seconds.
pub struct PreparedInputs {
    pub shapes: Vec<Option<Prepared>>,
    /// Whether the shapes are closed surfaces compared on the sphere.
    pub sphere: bool,
    pub inputs: Vec<ShapeReport>,
    pub marker_warnings: Vec<String>,
    pub seconds: f64,
    /// Shapes taken from [`DistancesOptions::cache`] (not prepared again).
    pub cache_hits: usize,
}

/// A file prepared (or taken from the cache) by [`prepare_inputs`].
struct PreparedFile {
    shape: PreparedShape,
    choice: MarkerChoice,
    vertices: usize,
    faces: usize,
    figures: crate::shape_cache::CachedFigures,
    hit: bool,
}

/// SHA-256 (hex) of a mesh in memory: its positions' and faces' little-endian bytes.
pub fn mesh_sha256(mesh: &TriMesh) -> String {
    let mut bytes = Vec::with_capacity(mesh.positions.len() * 24 + mesh.faces.len() * 12);
    for p in &mesh.positions {
        for x in p {
            bytes.extend_from_slice(&x.to_le_bytes());
        }
    }
    for f in &mesh.faces {
        for v in f {
            bytes.extend_from_slice(&v.to_le_bytes());
        }
    }
    sha256_hex(&bytes)
}

/// The per-shape work of [`run_distances`]: reads `paths` (or, with `meshes`, takes those
/// meshes, one per path; the paths then only name them and locate marker sidecars), resolves
/// the markers (automatic ones shared by the files with the same faces), and maps and
/// prepares each shape (`names` as [`shape_names`] gives them). A file that fails is reported
/// in its [`ShapeReport`]; only an inconsistent call is an error.
pub fn prepare_inputs(
    paths: &[PathBuf],
    meshes: Option<&[TriMesh]>,
    names: &[String],
    options: &DistancesOptions,
    progress: &(dyn Fn(usize, usize, &str) + Sync),
) -> Result<PreparedInputs, AnalysisError> {
    let n = paths.len();
    if names.len() != n || meshes.is_some_and(|m| m.len() != n) {
        return Err(AnalysisError::InvalidInput(format!(
            "{n} paths, {} names and {} meshes",
            names.len(),
            meshes.map_or(n, |m| m.len())
        )));
    }
    let t_prepare = Instant::now();
    // (a panic, i.e. a bug, fails this file only, as it fails a pair only in the pairs)
    let loaded: Vec<LoadedFile> = paths
        .par_iter()
        .enumerate()
        .map(|(i, path)| {
            let t = Instant::now();
            // (the bytes hashed are the bytes parsed; a mesh in memory hashes its arrays)
            let (sha256, mesh) = match meshes {
                Some(meshes) => (Some(mesh_sha256(&meshes[i])), Ok(meshes[i].clone())),
                None => {
                    let bytes = shapespace_geometry::io::read_mesh_bytes(path);
                    let sha256 = bytes.as_ref().ok().map(|bytes| sha256_hex(bytes));
                    let mesh = bytes.and_then(|bytes| shapespace_geometry::io::parse_mesh(bytes, path));
                    (sha256, mesh)
                }
            };
            let outcome = crate::distance::guarded(|| -> Result<(TriMesh, Markers, String), AnalysisError> {
                let mesh = mesh.map_err(|e| AnalysisError::Mesh(e.with_path(path)))?;
                let (markers, source) = markers_for(path, &options.markers, mesh.num_vertices())?;
                Ok((mesh, markers, source))
            });
            (sha256, t.elapsed().as_secs_f64(), outcome)
        })
        .collect();
    if run_domain(paths, &loaded, options)? == Domain::Sphere {
        return prepare_spheres(paths, names, loaded, options, progress, t_prepare);
    }
    // automatic markers: one choice per group of files with the same faces
    let mut loaded = loaded;
    let inputs: Vec<crate::shared_markers::MarkerInput> = loaded
        .iter()
        .enumerate()
        .filter_map(|(i, (_, _, r))| {
            r.as_ref()
                .ok()
                .map(|(mesh, markers, _)| crate::shared_markers::MarkerInput {
                    name: &names[i],
                    mesh,
                    markers,
                })
        })
        .collect();
    let shared = crate::shared_markers::share_auto_markers(&inputs);
    drop(inputs);
    let mut shared = shared.into_iter();
    for (_, _, r) in &mut loaded {
        if let Ok((_, markers, source)) = r {
            if let Some(s) = shared.next().flatten() {
                *markers = s.markers;
                *source = format!("{source}, {}", s.note);
            }
        }
    }
    let done = std::sync::atomic::AtomicUsize::new(0);
    let hits = std::sync::atomic::AtomicUsize::new(0);
    if let Some(dir) = &options.cache {
        std::fs::create_dir_all(dir).map_err(|e| AnalysisError::io(dir, e))?;
    }
    let cache_settings = format!("{:?}|target_points {:?}", options.disk_map, options.target_points);
    let prepared: Vec<(Option<PreparedShape>, ShapeReport)> = paths
        .par_iter()
        .zip(names)
        .zip(loaded)
        .map(|((path, name), (sha256, load_seconds, loaded))| {
            let t = Instant::now();
            let outcome = loaded.and_then(|(mesh, markers, source)| {
                crate::distance::guarded(|| -> Result<PreparedFile, AnalysisError> {
                    let key = match (&options.cache, &sha256) {
                        (Some(_), Some(sha)) => Some(crate::shape_cache::entry_key(&cache_settings, sha, &markers)),
                        _ => None,
                    };
                    let cached = match (&options.cache, &key) {
                        (Some(dir), Some(key)) => crate::shape_cache::load(dir, key, name),
                        _ => None,
                    };
                    let hit = cached.is_some();
                    let (shape, figures) = match cached {
                        Some(entry) => entry,
                        None => {
                            let mut shape = prepare_shape(name, &mesh, &markers, &options.disk_map).map_err(|e| {
                                AnalysisError::Shape {
                                    name: path.display().to_string(),
                                    message: e.to_string().trim_start_matches(&format!("{name}: ")).to_string(),
                                }
                            })?;
                            if let Some(n) = options.target_points {
                                shape = crate::distance::quantize_target(shape, n);
                            }
                            let figures = crate::shape_cache::CachedFigures {
                                flipped_faces: shape.disk.quality.num_flipped,
                                bff_fallback_after_green_folds: shape
                                    .disk
                                    .info
                                    .bff_fallback
                                    .as_ref()
                                    .map(|f| f.green_folds),
                            };
                            if let (Some(dir), Some(key)) = (&options.cache, &key) {
                                crate::shape_cache::store(dir, key, &shape, &figures)?;
                            }
                            (shape, figures)
                        }
                    };
                    let resolved = shape.disk.info.markers;
                    let choice = MarkerChoice {
                        center: resolved.center,
                        boundary: resolved.boundary_vertex,
                        source,
                        axis: crate::shared_markers::marker_axis(&mesh, &resolved),
                    };
                    Ok(PreparedFile {
                        shape,
                        choice,
                        vertices: mesh.num_vertices(),
                        faces: mesh.num_faces(),
                        figures,
                        hit,
                    })
                })
            });
            let k = done.fetch_add(1, std::sync::atomic::Ordering::Relaxed) + 1;
            progress(k, n, "prepare");
            let seconds = load_seconds + t.elapsed().as_secs_f64();
            match outcome {
                Ok(PreparedFile {
                    shape,
                    choice,
                    vertices: v,
                    faces: f,
                    figures,
                    hit,
                }) => {
                    if hit {
                        hits.fetch_add(1, std::sync::atomic::Ordering::Relaxed);
                    }
                    let (lo, hi) = shape
                        .disk
                        .face_densities
                        .iter()
                        .fold((f64::INFINITY, 0.0f64), |(lo, hi), &d| (lo.min(d), hi.max(d)));
                    let report = ShapeReport {
                        name: name.clone(),
                        path: path.clone(),
                        sha256,
                        ok: true,
                        error: None,
                        vertices: Some(v),
                        faces: Some(f),
                        markers: Some(choice),
                        seconds,
                        density_range: Some([lo, hi]),
                        flipped_faces: Some(figures.flipped_faces),
                        bff_fallback_after_green_folds: figures.bff_fallback_after_green_folds,
                        conformal_method: Some(shape.disk.info.method.clone()),
                    };
                    (Some(shape), report)
                }
                Err(e) => (
                    None,
                    ShapeReport {
                        name: name.clone(),
                        path: path.clone(),
                        sha256,
                        ok: false,
                        // (the other errors name the file already)
                        error: Some(if e.starts_with(crate::distance::INTERNAL_ERROR) {
                            format!("{}: {e}", path.display())
                        } else {
                            e
                        }),
                        vertices: None,
                        faces: None,
                        markers: None,
                        seconds,
                        density_range: None,
                        flipped_faces: None,
                        bff_fallback_after_green_folds: None,
                        conformal_method: None,
                    },
                ),
            }
        })
        .collect();
    let prepare_wall = t_prepare.elapsed().as_secs_f64();
    let (shapes, inputs): (Vec<Option<PreparedShape>>, Vec<ShapeReport>) = prepared.into_iter().unzip();
    let shapes: Vec<Option<Prepared>> = shapes
        .into_iter()
        .map(|s| s.map(|s| Prepared::Disk(Box::new(s))))
        .collect();
    // automatic markers far from the others' (files of different connectivity)
    let automatic: Vec<(&str, [f64; 3])> = inputs
        .iter()
        .filter_map(|r| {
            let m = r.markers.as_ref()?;
            m.source.starts_with("auto").then_some((r.name.as_str(), m.axis?))
        })
        .collect();
    let marker_warnings: Vec<String> = crate::shared_markers::marker_outliers(&automatic)
        .into_iter()
        .map(|(name, angle)| {
            format!(
                "{name}: its automatic markers point {angle:.0} degrees away from the other files' (the 3D direction from the center marker to the boundary marker, against the mean of the others); if the files share a frame, give the markers with a landmarks file"
            )
        })
        .collect();
    Ok(PreparedInputs {
        shapes,
        sphere: false,
        inputs,
        marker_warnings,
        seconds: prepare_wall,
        cache_hits: hits.into_inner(),
    })
}

/// The domain of a run: [`DistancesOptions::domain`], or with [`Domain::Auto`] the sphere when
/// every file that could be read is closed (no boundary edge) and the disk otherwise. A run
/// with closed files and files with a boundary is an error naming both groups.
fn run_domain(paths: &[PathBuf], loaded: &[LoadedFile], options: &DistancesOptions) -> Result<Domain, AnalysisError> {
    if options.domain != Domain::Auto {
        return Ok(options.domain);
    }
    let (mut closed, mut open) = (Vec::new(), Vec::new());
    for (path, (_, _, r)) in paths.iter().zip(loaded) {
        if let Ok((mesh, _, _)) = r {
            let conn = shapespace_geometry::connectivity::Connectivity::of(mesh);
            if conn.boundary_loops(&mesh.faces).is_empty() {
                closed.push(path.display().to_string());
            } else {
                open.push(path.display().to_string());
            }
        }
    }
    match (closed.is_empty(), open.is_empty()) {
        (false, false) => Err(AnalysisError::InvalidInput(format!(
            "closed surfaces (compared on the sphere) and surfaces with a boundary (compared on the disk) cannot be mixed in one run: closed: {}; with a boundary: {}",
            closed.join(", "),
            open.join(", ")
        ))),
        (false, true) => Ok(Domain::Sphere),
        _ => Ok(Domain::Disk),
    }
}

/// The per-shape stage of a run on the sphere ([`crate::sphere_distance::prepare_sphere_shape`]):
/// sphere maps normalized by [`MarkerOptions::sphere_markers`] or by Möbius centering. The
/// disk's markers (flags, marker files) do not apply, and the shape cache is not used.
fn prepare_spheres(
    paths: &[PathBuf],
    names: &[String],
    loaded: Vec<LoadedFile>,
    options: &DistancesOptions,
    progress: &(dyn Fn(usize, usize, &str) + Sync),
    t_prepare: Instant,
) -> Result<PreparedInputs, AnalysisError> {
    let m = &options.markers;
    if m.center.is_some() || m.boundary.is_some() || m.marker_file.is_some() {
        return Err(AnalysisError::InvalidInput(
            "the center and boundary markers and marker files are disk markers; closed surfaces (the sphere) take three markers p1,p2,p3 (sphere markers) or none (Möbius centering and a search over rotations)".into(),
        ));
    }
    if options.target_points.is_some() {
        return Err(AnalysisError::InvalidInput(
            "target points (a quantization in the disk) apply to disks, not to closed surfaces on the sphere".into(),
        ));
    }
    let normalization = match m.sphere_markers {
        Some(p) => shapespace_conformal::SphereNormalization::ThreeMarkers(p),
        None => shapespace_conformal::SphereNormalization::Centered { rotation: None },
    };
    let params = shapespace_conformal::SphereMapParams {
        normalization,
        intrinsic_delaunay: options.disk_map.intrinsic_delaunay,
        ..Default::default()
    };
    let method = match normalization {
        shapespace_conformal::SphereNormalization::ThreeMarkers([a, b, c]) => {
            format!("sphere, three markers {a}, {b}, {c}")
        }
        _ => "sphere, Möbius centering (rotation searched per pair)".to_string(),
    };
    let n = paths.len();
    let done = std::sync::atomic::AtomicUsize::new(0);
    let prepared: Vec<(Option<Prepared>, ShapeReport)> = paths
        .par_iter()
        .zip(names)
        .zip(loaded)
        .map(|((path, name), (sha256, load_seconds, loaded))| {
            let t = Instant::now();
            let outcome = loaded.and_then(|(mesh, _, _)| {
                crate::distance::guarded(|| {
                    crate::sphere_distance::prepare_sphere_shape(name, &mesh, &params)
                        .map(|s| (s, mesh.num_vertices(), mesh.num_faces()))
                        .map_err(|e| AnalysisError::Shape {
                            name: path.display().to_string(),
                            message: e.to_string().trim_start_matches(&format!("{name}: ")).to_string(),
                        })
                })
            });
            let k = done.fetch_add(1, std::sync::atomic::Ordering::Relaxed) + 1;
            progress(k, n, "prepare");
            let seconds = load_seconds + t.elapsed().as_secs_f64();
            let failed = |error: String| ShapeReport {
                name: name.clone(),
                path: path.clone(),
                sha256: sha256.clone(),
                ok: false,
                error: Some(error),
                vertices: None,
                faces: None,
                markers: None,
                seconds,
                density_range: None,
                flipped_faces: None,
                bff_fallback_after_green_folds: None,
                conformal_method: None,
            };
            match outcome {
                Ok((shape, v, f)) => {
                    let (lo, hi) = shape
                        .map
                        .face_densities
                        .iter()
                        .fold((f64::INFINITY, 0.0f64), |(lo, hi), &d| (lo.min(d), hi.max(d)));
                    let report = ShapeReport {
                        ok: true,
                        error: None,
                        vertices: Some(v),
                        faces: Some(f),
                        density_range: Some([lo, hi]),
                        flipped_faces: Some(shape.map.quality.num_flipped),
                        conformal_method: Some(method.clone()),
                        ..failed(String::new())
                    };
                    (Some(Prepared::Sphere(Box::new(shape))), report)
                }
                Err(e) if e.starts_with(crate::distance::INTERNAL_ERROR) => {
                    (None, failed(format!("{}: {e}", path.display())))
                }
                Err(e) => (None, failed(e)),
            }
        })
        .collect();
    let (shapes, inputs): (Vec<Option<Prepared>>, Vec<ShapeReport>) = prepared.into_iter().unzip();
    Ok(PreparedInputs {
        shapes,
        sphere: true,
        inputs,
        marker_warnings: Vec::new(),
        seconds: t_prepare.elapsed().as_secs_f64(),
        cache_hits: 0,
    })
}

/// Reads, maps and compares all `paths`; writes `out/distances.csv`, `out/pairs.csv` and
/// `out/report.json`. `progress(done, total, stage)` is called as work finishes. While the pairs
/// run, each finished one is also appended to `out/`[`PARTIAL_PAIRS`] before its progress call,
/// so that a run killed before the end keeps the pairs it finished; such a file found at the
/// start is moved to `out/`[`PREVIOUS_PARTIAL_PAIRS`] first (with its [`PARTIAL_IDENTITY`]).
///
/// With [`DistancesOptions::resume`], the directed pairs found in those files or in an earlier
/// `out/pairs.csv` ([`crate::resume`]) are taken from there when their two files (by content,
/// [`RunIdentity`]), markers, the executable and the solver settings are the same: a stopped run
/// goes on where it stopped, and a finished one extended by more files computes only the new
/// pairs. The results are those of a run from scratch (every pair is computed on its own, from
/// its two shapes), except for `seconds`, which is the earlier run's; the taken pairs are
/// written to the new [`PARTIAL_PAIRS`] first and counted in `report.json`'s `resumed`.
///
/// With [`DistancesOptions::shard`], only that shard's pairs are computed (the others' cells
/// are empty) and the report names the shard, for [`merge_shards`]; with
/// [`DistancesOptions::cache`], the per-shape work is taken from and stored in that folder.
///
/// Only output failures are errors: per-file and per-pair failures are recorded in the
/// report, the pair list and as empty matrix cells.
pub fn run_distances(
    paths: &[PathBuf],
    out: &Path,
    options: &DistancesOptions,
    progress: &(dyn Fn(usize, usize, &str) + Sync),
) -> Result<DistancesRun, AnalysisError> {
    let t_total = Instant::now();
    if options.resume && options.pairwise.warm_start {
        return Err(AnalysisError::InvalidInput(
            "resume cannot be combined with warm start (a warm-started pair depends on the pairs solved before it)"
                .into(),
        ));
    }
    if options.shard.is_some() && (options.pairwise.warm_start || options.pairwise.debias) {
        return Err(AnalysisError::InvalidInput(
            "a shard cannot be computed with warm start or debiasing (their pairs depend on other pairs or on every shape's self-cost)"
                .into(),
        ));
    }
    if paths.len() < 2 {
        return Err(AnalysisError::InvalidInput(format!(
            "distances need at least 2 mesh files, got {}",
            paths.len()
        )));
    }
    let names = shape_names(paths);
    // (the same file given twice, also under two spellings: refused before any work, not
    // after all pairs)
    let canonical: Vec<Option<PathBuf>> = paths.iter().map(|p| std::fs::canonicalize(p).ok()).collect();
    for (i, name) in names.iter().enumerate() {
        let same_file = |j: usize| canonical[i].is_some() && canonical[j] == canonical[i];
        if let Some(j) = (0..i).find(|&j| names[j] == *name || same_file(j)) {
            return Err(AnalysisError::InvalidInput(format!(
                "{} and {} are the same file or have the same shape name \"{name}\"",
                paths[j].display(),
                paths[i].display()
            )));
        }
    }
    std::fs::create_dir_all(out).map_err(|e| AnalysisError::io(out, e))?;
    let _lock = lock_output_folder(out)?;
    let n = paths.len();
    let prepared = prepare_inputs(paths, None, &names, options, progress)?;
    let sphere = prepared.sphere;
    let (shapes, inputs, marker_warnings, prepare_wall, cache_hits) = (
        prepared.shapes,
        prepared.inputs,
        prepared.marker_warnings,
        prepared.seconds,
        prepared.cache_hits,
    );

    let t_pairs = Instant::now();
    let identity = run_identity(options, &inputs);
    let needed: HashSet<(usize, usize)> = match options.shard {
        Some(shard) => shard.pairs(n, options.pairwise.symmetrize).into_iter().collect(),
        None => directed_pairs(n, options.pairwise.symmetrize).collect(),
    };
    let (known, resume_notes) = if options.resume {
        earlier_pairs(out, &identity, &needed)
    } else {
        (HashMap::new(), Vec::new())
    };
    let total_pairs = needed.len() - known.len();
    let done = std::sync::atomic::AtomicUsize::new(0);
    let partial_path = out.join(PARTIAL_PAIRS);
    let identity_path = out.join(PARTIAL_IDENTITY);
    if std::fs::symlink_metadata(&partial_path).is_ok() {
        // the moved pairs file keeps its own identity file (or none)
        let previous = out.join(PREVIOUS_PARTIAL_PAIRS);
        std::fs::rename(&partial_path, &previous).map_err(|e| AnalysisError::io(&previous, e))?;
        let previous = out.join(PREVIOUS_PARTIAL_IDENTITY);
        remove_if_present(&previous)?;
        if identity_path.exists() {
            std::fs::rename(&identity_path, &previous).map_err(|e| AnalysisError::io(&previous, e))?;
        }
    }
    let json = serde_json::to_string_pretty(&identity).map_err(|e| AnalysisError::Serialize {
        path: identity_path.clone(),
        message: e.to_string(),
    })?;
    write_atomically(&identity_path, json.as_bytes()).map_err(|e| AnalysisError::io(&identity_path, e))?;
    let partial = PartialPairs::create(partial_path, identity.clone())?;
    let mut taken: Vec<(&(usize, usize), &PairRecord)> = known.iter().collect();
    taken.sort_by_key(|((s, t), _)| (*t, *s));
    for (_, record) in taken {
        partial.append(record);
    }
    let only = options.shard.map(|_| &needed);
    let result = pairwise_distances_of(&shapes, &options.pairwise, only, &known, &partial.failed, &|record| {
        // (the file names, as below)
        partial.append(&PairRecord {
            a: names[record.source].clone(),
            b: names[record.target].clone(),
            ..record.clone()
        });
        let k = done.fetch_add(1, std::sync::atomic::Ordering::Relaxed) + 1;
        progress(k, total_pairs, "pairs");
    });
    partial.finish()?;
    let pairs_wall = t_pairs.elapsed().as_secs_f64();

    let timings = StageTimings {
        prepare_wall,
        pairs_wall,
        pairs_cpu: result.pair_seconds,
        write: 0.0,
        total: 0.0,
    };
    let mut written = write_run(
        out,
        RunParts {
            inputs,
            options: ReportOptions {
                domain: sphere.then(|| "sphere".to_string()),
                ..report_options(options)
            },
            threads: rayon::current_num_threads(),
            timings,
            pairs: result.pairs,
            matrix: result.matrix,
            asymmetries: result.asymmetries,
            debias: result.self_costs.as_ref().map(|own| DebiasReport {
                self_costs: own.iter().map(|c| c.is_finite().then_some(*c)).collect(),
                clamped_pairs: result.debias_clamped,
            }),
            resumed: options.resume.then_some(ResumeReport {
                pairs: known.len(),
                sources: resume_notes,
            }),
            marker_warnings,
            identity,
            shard: options.shard,
        },
        t_total,
    )?;
    // Everything it held is in pairs.csv now. (A file that cannot be removed only repeats
    // pairs.csv's rows, so that is not an error.)
    let _ = std::fs::remove_file(out.join(PARTIAL_PAIRS));
    let _ = std::fs::remove_file(out.join(PARTIAL_IDENTITY));
    written.cache_hits = cache_hits;
    Ok(written)
}

/// The options of a run as its report records them.
fn report_options(options: &DistancesOptions) -> ReportOptions {
    ReportOptions {
        symmetrize: options.pairwise.symmetrize,
        tolerance: options.pairwise.newton.tolerance,
        coarse_tolerance: options.pairwise.newton.coarse_tolerance,
        linear_solver: format!("{:?}", options.pairwise.newton.linear_solver),
        max_iterations: options.pairwise.newton.max_iterations,
        warm_start: options.pairwise.warm_start,
        intrinsic_delaunay: options.disk_map.intrinsic_delaunay,
        pair_time_limit: options.pairwise.time_limit.map(|l| l.as_secs_f64()),
        invariance: options.pairwise.invariance,
        debias: options.pairwise.debias,
        target_points: options.target_points,
        domain: None,
    }
}

/// What [`write_run`] writes: a run's (or the merged shards') inputs, options, pairs and matrix.
struct RunParts {
    inputs: Vec<ShapeReport>,
    options: ReportOptions,
    threads: usize,
    timings: StageTimings,
    /// By target, then source (pair names are replaced by the inputs' names).
    pairs: Vec<PairRecord>,
    matrix: Vec<f64>,
    asymmetries: Vec<f64>,
    debias: Option<DebiasReport>,
    resumed: Option<ResumeReport>,
    marker_warnings: Vec<String>,
    identity: RunIdentity,
    shard: Option<crate::shard::Shard>,
}

/// Writes `out/distances.csv`, `out/pairs.csv` and `out/report.json` (each atomically) from
/// `parts`; the report's summaries (failures, iterations, asymmetry, dual gaps) are computed
/// here from the pairs, so a run and the merge of its shards write the same bytes.
fn write_run(out: &Path, parts: RunParts, t_total: Instant) -> Result<DistancesRun, AnalysisError> {
    let t_write = Instant::now();
    let RunParts {
        inputs,
        options,
        threads,
        mut timings,
        mut pairs,
        matrix,
        asymmetries,
        debias,
        resumed,
        marker_warnings,
        identity,
        shard,
    } = parts;
    let names: Vec<String> = inputs.iter().map(|i| i.name.clone()).collect();
    // `pairwise_distances` knows only the prepared shapes' names (a failed one is `#i`): use the
    // file names throughout, as in distances.csv.
    for r in &mut pairs {
        r.a.clone_from(&names[r.source]);
        r.b.clone_from(&names[r.target]);
    }
    // An earlier report.json goes first: pairs.csv is read by a resumed run against the
    // report's resume_key, so a run stopped between the two writes must not leave the new
    // pairs beside the old key (its partial file, removed last, still has them).
    let report_path = out.join("report.json");
    remove_if_present(&report_path)?;
    let matrix = DistanceMatrix::new(names, matrix)?;
    let mut files = Vec::new();
    let matrix_path = out.join("distances.csv");
    write_distance_matrix(&matrix_path, &matrix)?;
    files.push(matrix_path);
    let pairs_path = out.join("pairs.csv");
    write_pairs_csv(&pairs_path, &pairs, &identity)?;
    files.push(pairs_path);

    let mut failures: Vec<String> = inputs.iter().filter_map(|r| r.error.clone()).collect();
    failures.extend(
        pairs
            .iter()
            .filter(|p| !p.distance.is_finite())
            .map(|p| format!("{} -> {}: {}", p.a, p.b, p.status)),
    );
    let iterations: Vec<f64> = pairs
        .iter()
        .filter(|p| p.distance.is_finite())
        .map(|p| p.iterations as f64)
        .collect();
    let gaps: Vec<f64> = pairs
        .iter()
        .filter(|p| p.distance.is_finite() && p.cost > 0.0)
        .map(|p| (p.cost - p.dual_cost).abs() / p.cost)
        .collect();
    files.push(report_path.clone());
    timings.write = t_write.elapsed().as_secs_f64();
    timings.total = t_total.elapsed().as_secs_f64();
    let report = DistancesReport {
        shapespace_version: env!("CARGO_PKG_VERSION").to_string(),
        inputs,
        options,
        threads,
        timings,
        pairs_computed: pairs.len(),
        pairs_failed: pairs.iter().filter(|p| !p.distance.is_finite()).count(),
        failures,
        iterations: (!iterations.is_empty()).then(|| summarize(&iterations)),
        asymmetry: (!asymmetries.is_empty()).then(|| summarize(&asymmetries)),
        debias,
        cost_dual_gap: (!gaps.is_empty()).then(|| summarize(&gaps)),
        resumed,
        marker_warnings,
        resume_key: identity,
        files,
        shard,
    };
    let json = serde_json::to_string_pretty(&report).map_err(|e| AnalysisError::Serialize {
        path: report_path.clone(),
        message: e.to_string(),
    })?;
    write_atomically(&report_path, json.as_bytes()).map_err(|e| AnalysisError::io(&report_path, e))?;
    Ok(DistancesRun {
        matrix,
        pairs,
        report,
        cache_hits: 0,
    })
}

/// Assembles the output folders of `distances --shard K/N` runs (all N shards of one run) into
/// `out`: distances.csv, pairs.csv and report.json as one run over all pairs writes them, byte
/// for byte but for the timings (report.json's `timings` and inputs' `seconds`, pairs.csv's
/// `seconds` and the `check` that covers them; the merged report's `threads`, inputs, marker
/// warnings and `seconds` are those of shard 1, its wall times the largest of the shards' and
/// `pairs_cpu` their sum).
///
/// Refused, before anything is written: a folder that is not a shard's, shards of different
/// runs (inputs, markers, settings, executable or shard count), a shard given twice, missing
/// shards (named by number), a pairs.csv row changed after it was written or a pairs.csv
/// without exactly its shard's pairs, and an `out` that is one of the shard folders.
pub fn merge_shards(dirs: &[PathBuf], out: &Path) -> Result<DistancesRun, AnalysisError> {
    let t_total = Instant::now();
    let invalid = |message: String| AnalysisError::InvalidInput(message);
    if dirs.is_empty() {
        return Err(invalid("merge needs the shard folders".into()));
    }
    let out_canonical = std::fs::canonicalize(out).ok();
    let mut shards: Vec<(PathBuf, DistancesReport, crate::shard::Shard)> = Vec::new();
    for dir in dirs {
        if out_canonical.is_some() && std::fs::canonicalize(dir).ok() == out_canonical {
            return Err(invalid(format!(
                "{}: the output folder is one of the shard folders (merge never writes over its inputs)",
                dir.display()
            )));
        }
        let path = dir.join("report.json");
        let text = std::fs::read_to_string(&path).map_err(|e| AnalysisError::io(&path, e))?;
        let report: DistancesReport = serde_json::from_str(&text)
            .map_err(|e| invalid(format!("{}: not a report of shapespace distances: {e}", path.display())))?;
        let Some(shard) = report.shard else {
            return Err(invalid(format!(
                "{}: not a shard (a run without --shard K/N)",
                path.display()
            )));
        };
        shards.push((dir.clone(), report, shard));
    }
    shards.sort_by_key(|(_, _, shard)| shard.index);
    let (first_dir, first, first_shard) = &shards[0];
    let count = first_shard.count;
    let described = |dir: &Path| dir.join("report.json").display().to_string();
    for (dir, report, shard) in &shards[1..] {
        let differs = if shard.count != count {
            Some(format!("it is one of {} shards, not {count}", shard.count))
        } else if report.resume_key.shapespace_version != first.resume_key.shapespace_version
            || report.resume_key.build != first.resume_key.build
        {
            Some("another shapespace executable computed it".into())
        } else if report.resume_key.settings != first.resume_key.settings
            || serde_json::to_string(&report.options).ok() != serde_json::to_string(&first.options).ok()
        {
            Some("its solver or conformal-map settings differ".into())
        } else if report.resume_key.inputs != first.resume_key.inputs
            || report
                .inputs
                .iter()
                .map(|i| &i.path)
                .ne(first.inputs.iter().map(|i| &i.path))
        {
            Some("its input files, their contents or their markers differ".into())
        } else {
            None
        };
        if let Some(why) = differs {
            return Err(invalid(format!(
                "{} is not a shard of the same run as {}: {why}",
                described(dir),
                described(first_dir)
            )));
        }
    }
    for pair in shards.windows(2) {
        if pair[0].2.index == pair[1].2.index {
            return Err(invalid(format!(
                "shard {} of {count} is given twice: {} and {}",
                pair[0].2.index,
                pair[0].0.display(),
                pair[1].0.display()
            )));
        }
    }
    let present: HashSet<usize> = shards.iter().map(|(_, _, s)| s.index).collect();
    let missing: Vec<String> = (1..=count)
        .filter(|k| !present.contains(k))
        .map(|k| k.to_string())
        .collect();
    if !missing.is_empty() {
        return Err(invalid(format!(
            "missing shard{} {} of {count} (the folders given hold shards {})",
            if missing.len() > 1 { "s" } else { "" },
            missing.join(", "),
            shards
                .iter()
                .map(|(_, _, s)| s.index.to_string())
                .collect::<Vec<_>>()
                .join(", ")
        )));
    }
    let identity = first.resume_key.clone();
    let n = first.inputs.len();
    let symmetrize = first.options.symmetrize;
    let index: HashMap<&str, usize> = first
        .inputs
        .iter()
        .enumerate()
        .map(|(i, input)| (input.name.as_str(), i))
        .collect();
    let mut pairs: Vec<PairRecord> = Vec::new();
    for (dir, _, shard) in &shards {
        let path = dir.join("pairs.csv");
        let records = read_shard_pairs(&path, &identity, &index)?;
        let expected = shard.pairs(n, symmetrize);
        let got: Vec<(usize, usize)> = records.iter().map(|r| (r.source, r.target)).collect();
        if got != expected {
            return Err(invalid(format!(
                "{}: {} pairs, not the {} pairs of shard {} of {count} (was it written by another run?)",
                path.display(),
                got.len(),
                expected.len(),
                shard.index
            )));
        }
        pairs.extend(records);
    }
    let ok: Vec<bool> = first.inputs.iter().map(|i| i.ok).collect();
    let (matrix, asymmetries, _) = matrix_from_pairs(&ok, &pairs, symmetrize, None);
    let max = |f: fn(&StageTimings) -> f64| shards.iter().map(|(_, r, _)| f(&r.timings)).fold(0.0, f64::max);
    let timings = StageTimings {
        prepare_wall: max(|t| t.prepare_wall),
        pairs_wall: max(|t| t.pairs_wall),
        pairs_cpu: shards.iter().map(|(_, r, _)| r.timings.pairs_cpu).sum(),
        write: 0.0,
        total: 0.0,
    };
    let first = first.clone();
    std::fs::create_dir_all(out).map_err(|e| AnalysisError::io(out, e))?;
    let _lock = lock_output_folder(out)?;
    write_run(
        out,
        RunParts {
            inputs: first.inputs,
            options: first.options,
            threads: first.threads,
            timings,
            pairs,
            matrix,
            asymmetries,
            debias: None,
            resumed: None,
            marker_warnings: first.marker_warnings,
            identity,
            shard: None,
        },
        t_total,
    )
}

/// The rows of a shard's pairs.csv, with their indices among the inputs `index` (by name), in
/// the file's order; a row that does not match its check is refused, naming its line.
fn read_shard_pairs(
    path: &Path,
    identity: &RunIdentity,
    index: &HashMap<&str, usize>,
) -> Result<Vec<PairRecord>, AnalysisError> {
    let mut reader = csv::Reader::from_path(path).map_err(|e| AnalysisError::csv(path, e))?;
    let headers = reader.headers().map_err(|e| AnalysisError::csv(path, e))?.clone();
    if headers.iter().ne(PAIRS_HEADER) {
        return Err(AnalysisError::InvalidInput(format!(
            "{}: not a pairs.csv of shapespace distances (columns {})",
            path.display(),
            headers.iter().collect::<Vec<_>>().join(",")
        )));
    }
    let mut records = Vec::new();
    for row in reader.records() {
        let row = row.map_err(|e| AnalysisError::csv(path, e))?;
        let line = row.position().map_or(0, |p| p.line());
        let bad = |why: &str| AnalysisError::InvalidInput(format!("{}:{line}: {why}", path.display()));
        let record: PairRecord = row
            .deserialize(Some(&headers))
            .map_err(|e| bad(&format!("unreadable row: {e}")))?;
        let fields: Vec<&str> = row.iter().take(PAIRS_HEADER.len() - 1).collect();
        let check = crate::resume::row_check(identity, &fields).unwrap_or_default();
        if row.get(PAIRS_HEADER.len() - 1) != Some(check.as_str()) {
            return Err(bad("the row does not match its check (changed after it was written)"));
        }
        let (Some(&source), Some(&target)) = (index.get(record.a.as_str()), index.get(record.b.as_str())) else {
            return Err(bad(&format!("{} -> {}: not shapes of this run", record.a, record.b)));
        };
        records.push(PairRecord {
            source,
            target,
            ..record
        });
    }
    Ok(records)
}

/// The lock file of an output folder ([`lock_output_folder`]).
pub const LOCK_FILE: &str = ".shapespace.lock";

/// Takes the lock of the output folder `out` for the caller's lifetime of the returned file: an
/// exclusive advisory lock (`flock`) on `out/`[`LOCK_FILE`], released when the file is dropped
/// or the process ends (a killed run leaves the empty file, not the lock). A second run into the
/// same folder while one is going on gets [`AnalysisError::Locked`] (two runs would write the
/// same checkpoint and outputs).
pub fn lock_output_folder(out: &Path) -> Result<std::fs::File, AnalysisError> {
    let path = out.join(LOCK_FILE);
    shapespace_geometry::io::atomic::refuse_symlink(&path).map_err(|e| AnalysisError::io(&path, e))?;
    let file = std::fs::OpenOptions::new()
        .read(true)
        .write(true)
        .create(true)
        .truncate(false)
        .open(&path)
        .map_err(|e| AnalysisError::io(&path, e))?;
    match file.try_lock() {
        Ok(()) => Ok(file),
        Err(std::fs::TryLockError::WouldBlock) => Err(AnalysisError::Locked { path }),
        Err(std::fs::TryLockError::Error(e)) => Err(AnalysisError::io(&path, e)),
    }
}

/// Removes `path` if it exists.
fn remove_if_present(path: &Path) -> Result<(), AnalysisError> {
    match std::fs::remove_file(path) {
        Err(e) if e.kind() != std::io::ErrorKind::NotFound => Err(AnalysisError::io(path, e)),
        _ => Ok(()),
    }
}

/// Writes `pairs.csv` of a run of `identity`: the columns of [`PAIRS_HEADER`],
/// `a,b,distance,cost,iterations,max_mass_error,seconds,status,evaluations,dual_cost,check` (a
/// is the source density side, b the target points side; `check` protects the row for a
/// resumed run, [`crate::resume::row_check`]).
pub fn write_pairs_csv(path: &Path, pairs: &[PairRecord], identity: &RunIdentity) -> Result<(), AnalysisError> {
    let to_err = |e: csv::Error| AnalysisError::csv(path, e);
    let file = AtomicFile::create(path).map_err(|e| AnalysisError::io(path, e))?;
    let mut w = csv::Writer::from_writer(file);
    w.write_record(PAIRS_HEADER).map_err(to_err)?;
    for p in pairs {
        w.write_record(pair_row(identity, p)).map_err(to_err)?;
    }
    w.into_inner()
        .map_err(|e| AnalysisError::io(path, e.into_error()))?
        .commit()
        .map_err(|e| AnalysisError::io(path, e))
}

#[cfg(test)]
mod tests {
    use super::*;

    fn identity() -> RunIdentity {
        RunIdentity {
            shapespace_version: "0".into(),
            build: None,
            settings: "s".into(),
            inputs: Vec::new(),
        }
    }

    fn record(a: &str) -> PairRecord {
        PairRecord {
            a: a.into(),
            b: "b".into(),
            source: 0,
            target: 1,
            distance: 0.5,
            cost: 0.25,
            iterations: 3,
            max_mass_error: 1e-5,
            seconds: 0.1,
            status: "converged".into(),
            evaluations: 4,
            dual_cost: 0.25,
        }
    }

    /// Rows reach the disk as they are appended (another reader sees them before the file is
    /// closed).
    #[test]
    fn partial_pairs_are_flushed_row_by_row() {
        let dir = std::env::temp_dir().join(format!("shapespace-partial-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let path = dir.join(PARTIAL_PAIRS);
        let partial = PartialPairs::create(path.clone(), identity()).unwrap();
        partial.append(&record("x"));
        let text = std::fs::read_to_string(&path).unwrap();
        assert_eq!(text.lines().count(), 2, "{text}");
        assert!(text.lines().nth(1).unwrap().starts_with("x,b,0.5,0.25,3,"), "{text}");
        partial.append(&record("y"));
        assert_eq!(std::fs::read_to_string(&path).unwrap().lines().count(), 3);
        partial.finish().unwrap();
        std::fs::remove_dir_all(&dir).ok();
    }

    /// A device that refuses every write: the first failure sets the stop signal and is
    /// returned, naming the file (no panic).
    #[cfg(target_os = "linux")]
    #[test]
    fn a_partial_pairs_write_failure_stops_the_run() {
        let file = std::fs::OpenOptions::new().write(true).open("/dev/full").unwrap();
        let partial = PartialPairs {
            path: PathBuf::from("/dev/full"),
            identity: identity(),
            writer: std::sync::Mutex::new(Ok(csv::Writer::from_writer(file))),
            failed: std::sync::atomic::AtomicBool::new(false),
        };
        partial.append(&record("x"));
        assert!(partial.failed.load(std::sync::atomic::Ordering::Relaxed));
        partial.append(&record("y"));
        let error = partial.finish().expect_err("writing to /dev/full fails").to_string();
        assert!(
            error.starts_with("/dev/full: cannot write the resume checkpoint"),
            "{error}"
        );
    }
}
