//! The per-shape stage of a distances run: each input file read, its markers resolved
//! ([`markers_for`]), its name made unique ([`shape_names`]), and the shape mapped and prepared
//! once ([`prepare_inputs`]; disks through [`crate::distance::prepare_shape`], closed genus-0
//! meshes on the sphere). A file that fails keeps its place with its reason.

use std::path::{Path, PathBuf};
use std::time::Instant;

use rayon::prelude::*;
use shapespace_conformal::{MarkerFile, Markers};
use shapespace_geometry::TriMesh;

use crate::distance::{prepare_shape, Prepared, PreparedShape};
use crate::error::AnalysisError;
use crate::resume::sha256_hex;
use crate::run_settings::{DistancesOptions, Domain, MarkerChoice, MarkerOptions, ShapeReport};

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

/// A file read for [`run_distances`](super::pipeline::run_distances): its SHA-256, the seconds spent, and its mesh with its
/// markers and their source (or why it could not be read).
pub(super) type LoadedFile = (Option<String>, f64, Result<(TriMesh, Markers, String), String>);

/// Shape name of a file: its stem, or, when stems repeat, the shortest suffix of its path
/// (folders and stem, joined by `/`) that no other file shares: `a/cat` and `b/cat` for
/// `data/a/cat.obj` and `data/b/cat.obj`, `x/cat` and `y/x/cat` when the folder names repeat
/// too; files that differ only in their extension (`cat.obj`, `cat.off`) keep it (`cat.obj`).
/// An absolute path's full name starts with `/` (`/x/cat` beside the relative `x/cat`), and
/// bytes that are not UTF-8 are written as `\xNN` (two such names stay apart). The same path
/// given twice keeps one name (which [`run_distances`](super::pipeline::run_distances) refuses as a duplicate).
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

/// The per-shape work of [`run_distances`](super::pipeline::run_distances): reads `paths` (or, with `meshes`, takes those
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
    let loaded = load_files(paths, meshes, options);
    if run_domain(paths, &loaded, options)? == Domain::Sphere {
        return prepare_spheres(paths, names, loaded, options, progress, t_prepare);
    }
    let mut loaded = loaded;
    share_automatic_markers(&mut loaded, names);
    let done = std::sync::atomic::AtomicUsize::new(0);
    let hits = std::sync::atomic::AtomicUsize::new(0);
    if let Some(dir) = &options.cache {
        std::fs::create_dir_all(dir).map_err(|e| AnalysisError::io(dir, e))?;
    }
    let cache_settings = format!(
        "{:?}|target_points {:?}{}",
        options.disk_map,
        options.target_points,
        // (absent in its default, so the cache entries of earlier runs keep their keys)
        options
            .source_faces
            .map(|n| format!("|source_faces {n}"))
            .unwrap_or_default()
    );
    let prepared: Vec<(Option<PreparedShape>, ShapeReport)> = paths
        .par_iter()
        .zip(names)
        .zip(loaded)
        .map(|((path, name), (sha256, load_seconds, loaded))| {
            let t = Instant::now();
            let outcome = loaded.and_then(|(mesh, markers, source)| {
                crate::distance::guarded(|| {
                    prepare_disk_file(
                        path,
                        name,
                        &mesh,
                        &markers,
                        source,
                        sha256.as_deref(),
                        options,
                        &cache_settings,
                    )
                })
            });
            let k = done.fetch_add(1, std::sync::atomic::Ordering::Relaxed) + 1;
            progress(k, n, "prepare");
            let seconds = load_seconds + t.elapsed().as_secs_f64();
            match outcome {
                Ok(PreparedFile {
                    shape,
                    choice,
                    vertices,
                    faces,
                    figures,
                    hit,
                }) => {
                    if hit {
                        hits.fetch_add(1, std::sync::atomic::Ordering::Relaxed);
                    }
                    let report = ShapeReport {
                        ok: true,
                        error: None,
                        vertices: Some(vertices),
                        faces: Some(faces),
                        markers: Some(choice),
                        density_range: Some(density_range(&shape.disk.face_densities)),
                        flipped_faces: Some(figures.flipped_faces),
                        bff_fallback_after_green_folds: figures.bff_fallback_after_green_folds,
                        conformal_method: Some(shape.disk.info.method.clone()),
                        conformal_repair_moved: shape.disk.info.region_repair.as_ref().map(|r| r.vertices_moved),
                        ..failed_report(name, path, sha256, seconds, String::new())
                    };
                    (Some(shape), report)
                }
                Err(e) => (None, failed_report(name, path, sha256, seconds, e)),
            }
        })
        .collect();
    let prepare_wall = t_prepare.elapsed().as_secs_f64();
    let (shapes, inputs): (Vec<Option<PreparedShape>>, Vec<ShapeReport>) = prepared.into_iter().unzip();
    let shapes: Vec<Option<Prepared>> = shapes
        .into_iter()
        .map(|s| s.map(|s| Prepared::Disk(Box::new(s))))
        .collect();
    let marker_warnings = automatic_marker_warnings(&inputs);
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
    if options.source_faces.is_some() {
        return Err(AnalysisError::InvalidInput(
            "source faces (an averaging of the density in the disk) apply to disks, not to closed surfaces on the sphere".into(),
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
            match outcome {
                Ok((shape, vertices, faces)) => {
                    let report = ShapeReport {
                        ok: true,
                        error: None,
                        vertices: Some(vertices),
                        faces: Some(faces),
                        density_range: Some(density_range(&shape.map.face_densities)),
                        flipped_faces: Some(shape.map.quality.num_flipped),
                        conformal_method: Some(method.clone()),
                        ..failed_report(name, path, sha256, seconds, String::new())
                    };
                    (Some(Prepared::Sphere(Box::new(shape))), report)
                }
                Err(e) => (None, failed_report(name, path, sha256, seconds, e)),
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

/// Reads each file (or takes the mesh given in memory) and resolves its markers, in parallel.
fn load_files(paths: &[PathBuf], meshes: Option<&[TriMesh]>, options: &DistancesOptions) -> Vec<LoadedFile> {
    // (a panic, i.e. a bug, fails this file only, as it fails a pair only in the pairs)
    paths
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
        .collect()
}

/// Automatic markers: one choice per group of files with the same faces
/// ([`crate::shared_markers::share_auto_markers`]).
fn share_automatic_markers(loaded: &mut [LoadedFile], names: &[String]) {
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
    for (_, _, r) in loaded.iter_mut() {
        if let Ok((_, markers, source)) = r {
            if let Some(s) = shared.next().flatten() {
                *markers = s.markers;
                *source = format!("{source}, {}", s.note);
            }
        }
    }
}

/// Maps and prepares one disk file, or takes it from [`DistancesOptions::cache`].
#[allow(clippy::too_many_arguments)]
fn prepare_disk_file(
    path: &Path,
    name: &str,
    mesh: &TriMesh,
    markers: &Markers,
    source: String,
    sha256: Option<&str>,
    options: &DistancesOptions,
    cache_settings: &str,
) -> Result<PreparedFile, AnalysisError> {
    let key = match (&options.cache, sha256) {
        (Some(_), Some(sha)) => Some(crate::shape_cache::entry_key(cache_settings, sha, markers)),
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
            let mut shape =
                prepare_shape(name, mesh, markers, &options.disk_map).map_err(|e| AnalysisError::Shape {
                    name: path.display().to_string(),
                    message: e.to_string().trim_start_matches(&format!("{name}: ")).to_string(),
                })?;
            if let Some(n) = options.target_points {
                shape = crate::distance::quantize_target(shape, n);
            }
            if let Some(n) = options.source_faces {
                shape = crate::distance::coarsen_source(shape, n).map_err(|e| AnalysisError::Shape {
                    name: path.display().to_string(),
                    message: e.to_string().trim_start_matches(&format!("{name}: ")).to_string(),
                })?;
            }
            let figures = crate::shape_cache::CachedFigures {
                flipped_faces: shape.disk.quality.num_flipped,
                bff_fallback_after_green_folds: shape.disk.info.bff_fallback.as_ref().map(|f| f.green_folds),
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
        axis: crate::shared_markers::marker_axis(mesh, &resolved),
    };
    Ok(PreparedFile {
        shape,
        choice,
        vertices: mesh.num_vertices(),
        faces: mesh.num_faces(),
        figures,
        hit,
    })
}

/// The report of an input that could not be prepared. `error` names the file already, except
/// an internal error (a bug), which gets the path in front.
fn failed_report(name: &str, path: &Path, sha256: Option<String>, seconds: f64, error: String) -> ShapeReport {
    let error = if error.starts_with(crate::distance::INTERNAL_ERROR) {
        format!("{}: {error}", path.display())
    } else {
        error
    };
    ShapeReport {
        name: name.to_string(),
        path: path.to_path_buf(),
        sha256,
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
        conformal_repair_moved: None,
    }
}

/// The smallest and largest density of a mapped shape's faces.
fn density_range(densities: &[f64]) -> [f64; 2] {
    let (lo, hi) = densities
        .iter()
        .fold((f64::INFINITY, 0.0f64), |(lo, hi), &d| (lo.min(d), hi.max(d)));
    [lo, hi]
}

/// Warnings for automatic markers far from the other files' (files of different connectivity;
/// [`crate::shared_markers::marker_outliers`]).
fn automatic_marker_warnings(inputs: &[ShapeReport]) -> Vec<String> {
    let automatic: Vec<(&str, [f64; 3])> = inputs
        .iter()
        .filter_map(|r| {
            let m = r.markers.as_ref()?;
            m.source.starts_with("auto").then_some((r.name.as_str(), m.axis?))
        })
        .collect();
    crate::shared_markers::marker_outliers(&automatic)
        .into_iter()
        .map(|(name, angle)| {
            format!(
                "{name}: its automatic markers point {angle:.0} degrees away from the other files' (the 3D direction from the center marker to the boundary marker, against the mean of the others); if the files share a frame, give the markers with a landmarks file"
            )
        })
        .collect()
}
