//! Output files of a registration and the registration benchmark over pose sets (Su et al.
//! 2015, Fig. 7: flipped area, curvature difference and area distortion histograms of OMT vs
//! conformal registration), with the geodesic error against the ground truth v ↔ v.

use std::io::Write;
use std::path::{Path, PathBuf};
use std::time::Instant;

use serde::Serialize;
use shapespace_conformal::MarkerFile;
use shapespace_geometry::io::{write_atomically, AtomicFile};
use shapespace_geometry::TriMesh;

use crate::area_preserving::AreaPreservingParams;
use crate::error::AnalysisError;
use crate::plot::histograms;
use crate::registration::metrics::{registration_metrics_against, MetricParams, RegistrationMetrics};
use crate::registration::truth::{carry_markers, closest_points, marker_file_json, SurfacePoint};
use crate::registration::zoomout::vertex_points;
use crate::registration::{
    disk_image, refine_registration, register_with_maps, DiskImage, HarmonicParams, Landmarks, Method, Refinement,
    Registration, SpectralBasis, ZoomOutParams,
};

/// Per method: the pooled curvature-difference and area-distortion samples, and the geodesic
/// errors per class (`CLASS`, or `CLASS/remeshed` for the pairs onto remeshed targets).
type Pooled = (Method, Vec<f64>, Vec<f64>, Vec<(String, Vec<f64>)>);

/// Histogram range of the curvature difference and the area distortion (Su et al. 2015, Fig. 7).
pub const HISTOGRAM_RANGE: (f64, f64) = (1.0, 3.0);
/// Number of histogram bins over [`HISTOGRAM_RANGE`].
pub const HISTOGRAM_BINS: usize = 40;

/// Starts writing `path` atomically (committed by the caller).
pub(crate) fn create(path: &Path) -> Result<AtomicFile, AnalysisError> {
    AtomicFile::create(path).map_err(|e| AnalysisError::io(path, e))
}

/// Writes the outputs of one registration into `out` (created if missing) and returns the
/// paths: `correspondence.csv` (vertex, face, b0, b1, b2, x, y, z per source vertex),
/// `metrics.json`, `curvature_difference.{png,svg}`, `area_distortion.{png,svg}`,
/// `source_colored.obj` (the source mesh with per-vertex colours `v x y z r g b`, the colour
/// of v being the position of f(v) in the bounding box of S₂ mapped to RGB) and
/// `target_colored.obj` (the target with the same colouring of its own vertices: matching
/// colours = corresponding points).
pub fn write_registration(
    out: &Path,
    source: &TriMesh,
    target: &TriMesh,
    reg: &Registration,
    metrics: &RegistrationMetrics,
    extra: &serde_json::Value,
) -> Result<Vec<PathBuf>, AnalysisError> {
    let head = serde_json::json!({
        "method": reg.method,
        "timings": reg.timings,
        "num_snapped": reg.num_snapped,
        "max_snap_distance": reg.max_snap_distance,
        "harmonic_released": reg.harmonic_released,
    });
    let map = MapOutput {
        label: reg.method.name(),
        faces: &reg.faces,
        bary: &reg.bary,
        points: &reg.points,
    };
    write_map_outputs(out, source, target, &map, head, metrics, extra)
}

/// A registration f as written by [`write_map_outputs`]: per source vertex the face of S₂, the
/// barycentric coordinates there and the 3D point, with a label for the histograms.
pub(crate) struct MapOutput<'a> {
    pub label: &'a str,
    pub faces: &'a [u32],
    pub bary: &'a [[f64; 3]],
    pub points: &'a [[f64; 3]],
}

/// The files of [`write_registration`] for any route: `head` (an object) opens metrics.json,
/// followed by `metrics`, the histogram settings and `run` = `extra`.
pub(crate) fn write_map_outputs(
    out: &Path,
    source: &TriMesh,
    target: &TriMesh,
    reg: &MapOutput,
    head: serde_json::Value,
    metrics: &RegistrationMetrics,
    extra: &serde_json::Value,
) -> Result<Vec<PathBuf>, AnalysisError> {
    std::fs::create_dir_all(out).map_err(|e| AnalysisError::io(out, e))?;
    let mut files = Vec::new();
    let path = out.join("correspondence.csv");
    {
        let mut w = create(&path)?;
        let io = |e| AnalysisError::io(&path, e);
        writeln!(w, "vertex,face,b0,b1,b2,x,y,z").map_err(io)?;
        for v in 0..reg.points.len() {
            let (b, p) = (reg.bary[v], reg.points[v]);
            writeln!(
                w,
                "{v},{},{:.17},{:.17},{:.17},{:.17},{:.17},{:.17}",
                reg.faces[v], b[0], b[1], b[2], p[0], p[1], p[2]
            )
            .map_err(io)?;
        }
        w.commit().map_err(io)?;
    }
    files.push(path);

    let path = out.join("metrics.json");
    let mut json = head;
    if let Some(obj) = json.as_object_mut() {
        obj.insert("metrics".into(), serde_json::json!(metrics));
        obj.insert("histogram_range".into(), serde_json::json!(HISTOGRAM_RANGE));
        obj.insert("histogram_bins".into(), serde_json::json!(HISTOGRAM_BINS));
        obj.insert("run".into(), extra.clone());
    }
    let text = serde_json::to_string_pretty(&json).map_err(|e| AnalysisError::Serialize {
        path: path.clone(),
        message: e.to_string(),
    })?;
    write_atomically(&path, text.as_bytes()).map_err(|e| AnalysisError::io(&path, e))?;
    files.push(path);

    for ext in ["png", "svg"] {
        let p = out.join(format!("curvature_difference.{ext}"));
        let cname = series_name(reg.label, &metrics.curvature_difference);
        histograms(
            &p,
            &[(cname.as_str(), &metrics.curvature_difference)],
            HISTOGRAM_BINS,
            Some(HISTOGRAM_RANGE),
            "Curvature difference",
            "max(|c1|/|c2|, |c2|/|c1|)",
        )?;
        files.push(p);
        let p = out.join(format!("area_distortion.{ext}"));
        let aname = series_name(reg.label, &metrics.area_distortion);
        histograms(
            &p,
            &[(aname.as_str(), &metrics.area_distortion)],
            HISTOGRAM_BINS,
            Some(HISTOGRAM_RANGE),
            "Local area distortion",
            "max(J, 1/J)",
        )?;
        files.push(p);
    }

    let (lo, hi) = bounding_box(&target.positions);
    let color = |p: [f64; 3]| -> [f64; 3] {
        let mut c = [0.0; 3];
        for d in 0..3 {
            c[d] = if hi[d] > lo[d] {
                ((p[d] - lo[d]) / (hi[d] - lo[d])).clamp(0.0, 1.0)
            } else {
                0.5
            };
        }
        c
    };
    for (file, mesh, colors) in [
        (
            "source_colored.obj",
            source,
            reg.points.iter().map(|&p| color(p)).collect::<Vec<_>>(),
        ),
        (
            "target_colored.obj",
            target,
            target.positions.iter().map(|&p| color(p)).collect(),
        ),
    ] {
        let path = out.join(file);
        write_colored_obj(&path, mesh, &colors)?;
        files.push(path);
    }
    Ok(files)
}

fn bounding_box(p: &[[f64; 3]]) -> ([f64; 3], [f64; 3]) {
    let mut lo = [f64::INFINITY; 3];
    let mut hi = [f64::NEG_INFINITY; 3];
    for q in p {
        for d in 0..3 {
            lo[d] = lo[d].min(q[d]);
            hi[d] = hi[d].max(q[d]);
        }
    }
    (lo, hi)
}

/// Writes an OBJ with per-vertex colours (`v x y z r g b`, r, g, b in [0, 1], the extension read
/// by MeshLab, Blender and most viewers) and 1-based faces.
pub fn write_colored_obj(path: &Path, mesh: &TriMesh, colors: &[[f64; 3]]) -> Result<(), AnalysisError> {
    let mut w = create(path)?;
    let io = |e| AnalysisError::io(path, e);
    writeln!(
        w,
        "# shapespace register: vertex colours = position of the corresponding point on the target"
    )
    .map_err(io)?;
    for (p, c) in mesh.positions.iter().zip(colors) {
        writeln!(w, "v {} {} {} {:.4} {:.4} {:.4}", p[0], p[1], p[2], c[0], c[1], c[2]).map_err(io)?;
    }
    for f in &mesh.faces {
        writeln!(w, "f {} {} {}", f[0] + 1, f[1] + 1, f[2] + 1).map_err(io)?;
    }
    w.commit().map_err(io)
}

/// One row of the benchmark (`results.csv`).
#[derive(Clone, Debug, Serialize, serde::Deserialize)]
pub struct BenchRow {
    pub class: String,
    pub source: String,
    pub target: String,
    /// `same` (the target shares the source's triangulation, ground truth v ↔ v) or `remeshed`
    /// (the target is a remeshing of the pose, ground truth carried over by closest point).
    pub triangulation: Triangulation,
    pub method: Method,
    /// The refinement after the disk-map stage.
    pub refine: Refinement,
    /// `ok`, or the error that stopped this pair.
    pub status: String,
    pub flipped_ratio: f64,
    pub flipped_ratio_3d: f64,
    /// Folded faces of g ∘ φ₁ before its fold repair (exact predicate).
    pub harmonic_folded: usize,
    /// The largest distance in the disk between a landmark's image under g and its target,
    /// when the folds of g were re-embedded with the landmarks released (0 when they stayed
    /// on their targets; [`crate::registration::HarmonicParams::release_landmarks`]); on the
    /// sphere, the chordal distance on S² after the repair of the faces folded there
    /// ([`crate::registration::sphere::SphereHarmonicRepair`]).
    pub landmark_shift: f64,
    pub curvature_median: f64,
    pub curvature_mean: f64,
    /// Median of max(J, 1/J) over the vertices.
    pub area_distortion_median: f64,
    /// 95th percentile of max(J, 1/J).
    pub area_distortion_p95: f64,
    /// Mean of |ln J| (the mean of max(J, 1/J) is dominated by a few collapsed one-rings).
    pub area_distortion_mean_abs_log: f64,
    pub geodesic_median: f64,
    pub geodesic_mean: f64,
    pub seconds: f64,
    /// Of `seconds`: the refinement (both surfaces' eigenpairs and the iterations; 0 without).
    pub refine_seconds: f64,
    /// Of `refine_seconds`: both surfaces' eigenpairs.
    pub eigen_seconds: f64,
    /// Of `seconds`, the pair's own work: `seconds` without the per-mesh disk maps and
    /// eigenpairs (which the benchmark computes once per mesh and shares by all its pairs).
    pub pair_seconds: f64,
    /// `pair_seconds` plus the class's per-mesh work (disk maps, eigenpairs) over its number of
    /// pairs: the cost per pair of registering every ordered pair of the class.
    pub amortized_seconds: f64,
    /// `amortized_seconds` of the first stage alone (no eigenpairs, no ZoomOut iterations).
    pub stage1_amortized_seconds: f64,
    /// Flipped 3D source faces of the refined vertex map before and after its untangling
    /// ([`crate::registration::untangle`]; 0 and 0 without refinement).
    pub untangle_flipped_before: usize,
    pub untangle_flipped_after: usize,
    /// Of `refine_seconds`: the untangling.
    pub untangle_seconds: f64,
    /// Source faces flipped by the metric's 3D test before and after the untangling with points
    /// ([`crate::registration::untangle::untangle_points`]; 0 and 0 without refinement).
    pub point_untangle_flipped_before: usize,
    pub point_untangle_flipped_after: usize,
    /// Of `refine_seconds`: the untangling with points.
    pub point_untangle_seconds: f64,
    /// The refined vertex map (before the untangling with points), scored the same way:
    /// flipped 3D area ratio, geodesic error mean and median (NaN without refinement, and on
    /// the sphere route).
    pub vertex_map_flipped_ratio_3d: f64,
    pub vertex_map_geodesic_mean: f64,
    pub vertex_map_geodesic_median: f64,
    /// For a remeshed target: the largest distance from a vertex of the pose to the remeshed
    /// surface over √area (the error of the carried ground truth); 0 for the same triangulation.
    pub truth_max_distance: f64,
}

impl BenchRow {
    /// A row before its pair runs: status "ok", figures not yet measured (NaN; counts and
    /// stage seconds 0), no remeshed-truth distance.
    pub fn pending(
        class: &str,
        source: String,
        target: String,
        triangulation: Triangulation,
        method: Method,
        refine: Refinement,
    ) -> Self {
        BenchRow {
            class: class.to_string(),
            source,
            target,
            triangulation,
            method,
            refine,
            status: "ok".into(),
            flipped_ratio: f64::NAN,
            flipped_ratio_3d: f64::NAN,
            harmonic_folded: 0,
            landmark_shift: 0.0,
            curvature_median: f64::NAN,
            curvature_mean: f64::NAN,
            area_distortion_median: f64::NAN,
            area_distortion_p95: f64::NAN,
            area_distortion_mean_abs_log: f64::NAN,
            geodesic_median: f64::NAN,
            geodesic_mean: f64::NAN,
            seconds: f64::NAN,
            refine_seconds: 0.0,
            eigen_seconds: 0.0,
            pair_seconds: f64::NAN,
            amortized_seconds: f64::NAN,
            stage1_amortized_seconds: f64::NAN,
            untangle_flipped_before: 0,
            untangle_flipped_after: 0,
            untangle_seconds: 0.0,
            point_untangle_flipped_before: 0,
            point_untangle_flipped_after: 0,
            point_untangle_seconds: 0.0,
            vertex_map_flipped_ratio_3d: f64::NAN,
            vertex_map_geodesic_mean: f64::NAN,
            vertex_map_geodesic_median: f64::NAN,
            truth_max_distance: 0.0,
        }
    }
}

/// Means over the successful pairs of one method (in one class, or `all`).
#[derive(Clone, Debug, Serialize)]
pub struct MethodSummary {
    /// The class folder, or `all` for every class together.
    pub class: String,
    /// The pairs' kind of target (`same` or `remeshed`).
    pub triangulation: Triangulation,
    pub method: Method,
    pub refine: Refinement,
    pub pairs_ok: usize,
    pub pairs_failed: usize,
    pub flipped_ratio: f64,
    pub flipped_ratio_3d: f64,
    pub curvature_median: f64,
    pub curvature_mean: f64,
    /// Median of max(J, 1/J) over the vertices.
    pub area_distortion_median: f64,
    /// 95th percentile of max(J, 1/J).
    pub area_distortion_p95: f64,
    /// Mean of |ln J| (the mean of max(J, 1/J) is dominated by a few collapsed one-rings).
    pub area_distortion_mean_abs_log: f64,
    pub geodesic_median: f64,
    pub geodesic_mean: f64,
    pub seconds: f64,
    /// Of `seconds`: the refinement.
    pub refine_seconds: f64,
    /// Of `refine_seconds`: both surfaces' eigenpairs.
    pub eigen_seconds: f64,
    /// Of `seconds`: the pair's own work (no disk maps, no eigenpairs).
    pub pair_seconds: f64,
    /// The cost per pair of registering every ordered pair of the class (`pair_seconds` plus
    /// the per-mesh work over the number of pairs).
    pub amortized_seconds: f64,
    /// `amortized_seconds` of the first stage alone.
    pub stage1_amortized_seconds: f64,
}

/// Whether a benchmark pair's target shares the source's triangulation.
#[derive(Clone, Copy, Debug, PartialEq, Eq, PartialOrd, Ord, Serialize, serde::Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum Triangulation {
    /// The target is a pose of the class (same vertices and faces as the source).
    Same,
    /// The target is a remeshed pose (`register_bench`'s `remeshed` folder).
    Remeshed,
}

impl Triangulation {
    /// `same` or `remeshed`.
    pub fn name(self) -> &'static str {
        match self {
            Triangulation::Same => "same",
            Triangulation::Remeshed => "remeshed",
        }
    }
}

impl std::fmt::Display for Triangulation {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(self.name())
    }
}

/// A remeshed pose of a class: the mesh, its markers carried over from the pose, the ground
/// truth (the point of the remeshed mesh closest to each vertex of the pose) and the largest
/// closest-point distance over √area.
struct RemeshedTarget {
    mesh: TriMesh,
    markers: MarkerFile,
    truth: Vec<SurfacePoint>,
    max_distance: f64,
}

/// Reads the remeshed poses of a class (`folder/STEM.{off,obj,ply}` for each pose file) and
/// carries the ground truth and the markers over; writes both into `truth_dir`
/// (`STEM.csv`: vertex,face,b0,b1,b2 per vertex of the pose; `STEM.landmarks.json`).
fn remeshed_targets(
    folder: &Path,
    files: &[PathBuf],
    meshes: &[TriMesh],
    markers: &[(PathBuf, MarkerFile)],
    truth_dir: &Path,
) -> Result<Vec<RemeshedTarget>, AnalysisError> {
    std::fs::create_dir_all(truth_dir).map_err(|e| AnalysisError::io(truth_dir, e))?;
    let available = mesh_files(folder)?;
    let mut out = Vec::new();
    for ((f, pose), (_, mf)) in files.iter().zip(meshes).zip(markers) {
        let name = stem(f);
        let path = available
            .iter()
            .find(|p| stem(p) == name)
            .ok_or_else(|| AnalysisError::Shape {
                name: folder.display().to_string(),
                message: format!("no remeshed pose `{name}` (.off, .obj or .ply) for {}", f.display()),
            })?;
        let mesh = shapespace_geometry::io::read_mesh(path).map_err(|e| AnalysisError::Shape {
            name: path.display().to_string(),
            message: e.to_string(),
        })?;
        let (truth, max) = closest_points(&pose.positions, &mesh)?;
        let carried = carry_markers(pose, mf, &mesh).map_err(|e| AnalysisError::Shape {
            name: path.display().to_string(),
            message: format!("carrying the markers over: {e}"),
        })?;
        let csv_path = truth_dir.join(format!("{name}.csv"));
        {
            let mut w = create(&csv_path)?;
            let io = |e| AnalysisError::io(&csv_path, e);
            writeln!(w, "vertex,face,b0,b1,b2").map_err(io)?;
            for (v, (face, b)) in truth.iter().enumerate() {
                writeln!(w, "{v},{face},{:.17},{:.17},{:.17}", b[0], b[1], b[2]).map_err(io)?;
            }
            w.commit().map_err(io)?;
        }
        let json_path = truth_dir.join(format!("{name}.landmarks.json"));
        let text = serde_json::to_string_pretty(&marker_file_json(&carried)).map_err(|e| AnalysisError::Serialize {
            path: json_path.clone(),
            message: e.to_string(),
        })?;
        write_atomically(&json_path, text.as_bytes()).map_err(|e| AnalysisError::io(&json_path, e))?;
        let area = shapespace_geometry::quantities::total_area(pose);
        out.push(RemeshedTarget {
            mesh,
            markers: carried,
            truth,
            max_distance: max / area.sqrt(),
        });
    }
    Ok(out)
}

/// Result of [`register_bench`].
#[derive(Clone, Debug, Serialize)]
pub struct BenchResult {
    pub rows: Vec<BenchRow>,
    pub summaries: Vec<MethodSummary>,
    /// Wall-clock seconds of the whole benchmark (disk maps computed once per mesh and method,
    /// metrics included).
    pub total_seconds: f64,
    /// Files written.
    #[serde(serialize_with = "crate::report_path::many")]
    pub files: Vec<PathBuf>,
}

/// Mesh files (`.off`, `.obj`, `.ply`) of a folder, sorted by name.
pub(crate) fn mesh_files(dir: &Path) -> Result<Vec<PathBuf>, AnalysisError> {
    let mut out: Vec<PathBuf> = std::fs::read_dir(dir)
        .map_err(|e| AnalysisError::io(dir, e))?
        .filter_map(|e| e.ok().map(|e| e.path()))
        .filter(|p| {
            p.is_file()
                && p.extension()
                    .map(|e| e.to_string_lossy().to_ascii_lowercase())
                    .is_some_and(|e| e == "off" || e == "obj" || e == "ply")
        })
        .collect();
    out.sort();
    Ok(out)
}

pub(crate) fn stem(p: &Path) -> String {
    p.file_stem()
        .map(|s| s.to_string_lossy().to_string())
        .unwrap_or_default()
}

/// The registration benchmark: for each class folder of `dataset` (a folder of mesh files with
/// a `landmarks.json` or per-mesh sidecars, meshes of a class sharing the vertex order), all
/// ordered pairs of meshes within the class, for each method: register (disk maps computed once
/// per mesh and method), evaluate the metrics (geodesic error against v ↔ v), write
/// `results.csv`, `summary.json`, `geodesic_curve.csv` (per class and method and over all classes,
/// mean over pairs of the fraction of samples under each threshold) and pooled histograms per method (all evaluated vertices of all pairs)
/// `curvature_difference.{png,svg}` and `area_distortion.{png,svg}` into `out`. A pair whose
/// disk map fails is recorded with its error and NaN measures; the benchmark continues.
/// g of each method: `harmonic(method)` (e.g. [`HarmonicParams::for_method`]).
/// With `refine` = [`Refinement::ZoomOut`] each registration is refined
/// ([`refine_registration`] with `zoomout`; eigenpairs computed once per mesh).
/// `seconds` of a pair = both disk maps + harmonic map + composition (+ both surfaces'
/// eigenpairs + the ZoomOut iterations): a registration from scratch, not the metrics.
///
/// With `remeshed` = Some(R), each class also registers every pose onto the remeshings of the
/// other poses, `R/CLASS/NAME.{off,obj,ply}` for each pose `NAME` (no shared triangulation;
/// e.g. `scripts/remesh_targets.py`): the ground truth of pose i → remeshed pose j is the point
/// of the remeshed mesh closest to each vertex of pose j, its markers vertices at their closest
/// points ([`crate::registration::truth::carry_markers`]); both are written to `out/truth/CLASS/NAME.csv` and
/// `NAME.landmarks.json` (for a peer scored on the same ground truth). Those rows have
/// `triangulation` = `remeshed`; the per-mesh work of a class is shared over all its pairs.
#[allow(clippy::too_many_arguments)]
pub fn register_bench(
    dataset: &Path,
    out: &Path,
    remeshed: Option<&Path>,
    methods: &[Method],
    params: &AreaPreservingParams,
    harmonic: &dyn Fn(Method) -> HarmonicParams,
    refine: Refinement,
    zoomout: &ZoomOutParams,
    metric_params: &MetricParams,
    mut progress: impl FnMut(&str),
) -> Result<BenchResult, AnalysisError> {
    let t0 = Instant::now();
    let ctx = BenchContext {
        out,
        remeshed,
        methods,
        params,
        harmonic,
        refine,
        zoomout,
        metric_params,
    };
    std::fs::create_dir_all(out).map_err(|e| AnalysisError::io(out, e))?;
    let mut classes: Vec<PathBuf> = std::fs::read_dir(dataset)
        .map_err(|e| AnalysisError::io(dataset, e))?
        .filter_map(|e| e.ok().map(|e| e.path()))
        .filter(|p| p.is_dir())
        .collect();
    classes.sort();
    let mut tally = BenchTally {
        rows: Vec::new(),
        pooled: methods
            .iter()
            .map(|&m| (m, Vec::new(), Vec::new(), Vec::new()))
            .collect(),
    };
    let mut num_classes = 0;
    for class_dir in &classes {
        let files = mesh_files(class_dir)?;
        if files.len() < 2 {
            continue;
        }
        num_classes += 1;
        let class = BenchClass::read(&ctx, class_dir, files, &mut progress)?;
        let bases = class.spectral_bases(&ctx, &mut progress);
        for mi in 0..methods.len() {
            bench_method(&ctx, &class, mi, &bases, &mut tally, &mut progress);
        }
    }
    if num_classes == 0 {
        return Err(AnalysisError::InvalidInput(format!(
            "{}: no class folder with at least 2 mesh files (.obj, .off, .ply); expected DATASET/CLASS/*.obj with a landmarks.json",
            dataset.display()
        )));
    }
    let BenchTally { rows, pooled } = tally;
    let mut files = Vec::new();
    let path = out.join("results.csv");
    write_results_csv(&path, &rows)?;
    files.push(path);
    let summaries = summarize(&rows, methods, refine);
    let path = out.join("geodesic_curve.csv");
    write_geodesic_curve(&path, &pooled)?;
    files.push(path);
    files.extend(write_pooled_histograms(out, &pooled)?);
    let total_seconds = t0.elapsed().as_secs_f64();
    let path = out.join("summary.json");
    let text =
        serde_json::to_string_pretty(&serde_json::json!({"summaries": summaries, "total_seconds": total_seconds}))
            .map_err(|e| AnalysisError::Serialize {
                path: path.clone(),
                message: e.to_string(),
            })?;
    write_atomically(&path, text.as_bytes()).map_err(|e| AnalysisError::io(&path, e))?;
    files.push(path);
    Ok(BenchResult {
        rows,
        summaries,
        total_seconds,
        files,
    })
}

/// The settings of one [`register_bench`] run, shared by all its classes and pairs.
struct BenchContext<'a> {
    out: &'a Path,
    remeshed: Option<&'a Path>,
    methods: &'a [Method],
    params: &'a AreaPreservingParams,
    harmonic: &'a dyn Fn(Method) -> HarmonicParams,
    refine: Refinement,
    zoomout: &'a ZoomOutParams,
    metric_params: &'a MetricParams,
}

/// What the pairs of [`register_bench`] accumulate: the rows in order and, per method, the
/// pooled samples and geodesic curves.
struct BenchTally {
    rows: Vec<BenchRow>,
    pooled: Vec<Pooled>,
}

/// One class of the benchmark: its pose files, meshes and markers, and the remeshed poses.
/// Targets are the poses, then their remeshings: target k is (a remeshing of) pose k % n.
struct BenchClass {
    name: String,
    files: Vec<PathBuf>,
    meshes: Vec<TriMesh>,
    markers: Vec<(PathBuf, MarkerFile)>,
    remeshed: Vec<RemeshedTarget>,
}

/// A pair's registration, its metrics and (for a refined vertex map) the metrics of the vertex
/// map before the untangling with points.
type Scored = (Registration, RegistrationMetrics, Option<RegistrationMetrics>);

impl BenchClass {
    /// Reads the poses of `class_dir` (`files`) with their landmark files and, when the run has
    /// a remeshed folder, the remeshed poses with their carried ground truth.
    fn read(
        ctx: &BenchContext,
        class_dir: &Path,
        files: Vec<PathBuf>,
        progress: &mut dyn FnMut(&str),
    ) -> Result<Self, AnalysisError> {
        let name = stem(class_dir);
        let mut meshes = Vec::new();
        let mut markers = Vec::new();
        for f in &files {
            let mesh = shapespace_geometry::io::read_mesh(f).map_err(|e| AnalysisError::Shape {
                name: f.display().to_string(),
                message: e.to_string(),
            })?;
            let side = MarkerFile::sidecar_path(f).ok_or_else(|| AnalysisError::Shape {
                name: f.display().to_string(),
                message: "no landmark file (NAME.landmarks.json or landmarks.json beside it)".into(),
            })?;
            let mf = MarkerFile::from_json_file(&side).map_err(AnalysisError::DiskMap)?;
            meshes.push(mesh);
            markers.push((side, mf));
        }
        let remeshed = match ctx.remeshed {
            Some(dir) => {
                progress(&format!("{name}: remeshed poses, ground truth by closest point"));
                remeshed_targets(
                    &dir.join(&name),
                    &files,
                    &meshes,
                    &markers,
                    &ctx.out.join("truth").join(&name),
                )?
            }
            None => Vec::new(),
        };
        Ok(BenchClass {
            name,
            files,
            meshes,
            markers,
            remeshed,
        })
    }

    /// Number of poses.
    fn n(&self) -> usize {
        self.meshes.len()
    }

    /// Every target mesh: the poses, then their remeshings.
    fn all_meshes(&self) -> Vec<&TriMesh> {
        self.meshes
            .iter()
            .chain(self.remeshed.iter().map(|r| &r.mesh))
            .collect()
    }

    /// The markers of every target, in the order of [`Self::all_meshes`].
    fn all_markers(&self) -> Vec<&MarkerFile> {
        self.markers
            .iter()
            .map(|m| &m.1)
            .chain(self.remeshed.iter().map(|r| &r.markers))
            .collect()
    }

    /// The name of target k in progress lines and errors.
    fn name_of(&self, k: usize) -> String {
        let n = self.n();
        if k < n {
            stem(&self.files[k])
        } else {
            format!("{} (remeshed)", stem(&self.files[k - n]))
        }
    }

    /// With the ZoomOut refinement, the eigenpairs of every target (once per mesh, shared by all
    /// methods and pairs); empty without.
    fn spectral_bases(&self, ctx: &BenchContext, progress: &mut dyn FnMut(&str)) -> Vec<Result<SpectralBasis, String>> {
        if ctx.refine == Refinement::ZoomOut {
            self.all_meshes()
                .iter()
                .enumerate()
                .map(|(k, m)| {
                    progress(&format!("{}: eigenpairs of {}", self.name, self.name_of(k)));
                    SpectralBasis::of(m, ctx.zoomout.k_end, &ctx.zoomout.eigen).map_err(|e| error_chain(&e))
                })
                .collect()
        } else {
            Vec::new()
        }
    }
}

/// One method over one class: the disk maps of every target (once per mesh), every ordered
/// pair (pose i onto target j ≠ i) registered, scored and recorded, then the per-mesh work
/// shared out over the class's pairs.
fn bench_method(
    ctx: &BenchContext,
    class: &BenchClass,
    mi: usize,
    bases: &[Result<SpectralBasis, String>],
    tally: &mut BenchTally,
    progress: &mut dyn FnMut(&str),
) {
    let method = ctx.methods[mi];
    let all_meshes = class.all_meshes();
    let all_markers = class.all_markers();
    let n = class.n();
    let maps: Vec<Result<DiskImage, String>> = all_meshes
        .iter()
        .zip(&all_markers)
        .enumerate()
        .map(|(k, (m, mf))| {
            progress(&format!("{}: {method} disk map of {}", class.name, class.name_of(k)));
            disk_image(m, &mf.markers, method, ctx.params).map_err(|e| error_chain(&e))
        })
        .collect();
    let first_row = tally.rows.len();
    let mut mesh_seconds = vec![0.0; all_meshes.len()];
    let mut mesh_eigen_seconds = vec![0.0; all_meshes.len()];
    for i in 0..n {
        for j in 0..all_meshes.len() {
            if i == j % n {
                continue;
            }
            let (src, tgt) = (stem(&class.files[i]), stem(&class.files[j % n]));
            let (triangulation, remeshed_target) = if j < n {
                (Triangulation::Same, None)
            } else {
                (Triangulation::Remeshed, Some(&class.remeshed[j - n]))
            };
            progress(&format!("{}: {method} {src} -> {}", class.name, class.name_of(j)));
            let mut row = BenchRow::pending(&class.name, src, tgt, triangulation, method, ctx.refine);
            row.truth_max_distance = remeshed_target.map_or(0.0, |r| r.max_distance);
            let pair = PairInputs {
                class,
                maps: &maps,
                bases,
                method,
                remeshed_target,
            };
            match register_pair(ctx, &pair, i, j) {
                Ok((reg, met, before)) => {
                    fill_row(&mut row, &reg, &met, before.as_ref());
                    if let Some(g) = &met.geodesic {
                        let key = match triangulation {
                            Triangulation::Same => class.name.clone(),
                            Triangulation::Remeshed => format!("{}/remeshed", class.name),
                        };
                        tally.pooled[mi].3.push((key, g.fractions.clone()));
                    }
                    let t = &reg.timings;
                    let eigen = |k: usize| reg.refinement.as_ref().map_or(0.0, |r| r.eigen_seconds[k]);
                    mesh_seconds[i] = t.source_map + eigen(0);
                    mesh_seconds[j] = t.target_map + eigen(1);
                    mesh_eigen_seconds[i] = eigen(0);
                    mesh_eigen_seconds[j] = eigen(1);
                    tally.pooled[mi].1.extend_from_slice(&met.curvature_difference);
                    tally.pooled[mi].2.extend_from_slice(&met.area_distortion);
                }
                Err(e) => row.status = e,
            }
            tally.rows.push(row);
        }
    }
    share_mesh_work(&mut tally.rows[first_row..], &mesh_seconds, &mesh_eigen_seconds);
}

/// What a pair of one class and method reads besides its indices: the disk maps and eigenpairs
/// of every target, and the remeshed target's ground truth (None for the same triangulation).
struct PairInputs<'a> {
    class: &'a BenchClass,
    maps: &'a [Result<DiskImage, String>],
    bases: &'a [Result<SpectralBasis, String>],
    method: Method,
    remeshed_target: Option<&'a RemeshedTarget>,
}

/// Registers pose i onto target j from the shared disk maps (refined with the shared eigenpairs
/// under ZoomOut) and scores it; the error (a disk map or eigenpairs that failed, landmarks,
/// registration, metrics) is the pair's status.
fn register_pair(ctx: &BenchContext, pair: &PairInputs, i: usize, j: usize) -> Result<Scored, String> {
    let class = pair.class;
    let n = class.n();
    let all_meshes = class.all_meshes();
    let all_markers = class.all_markers();
    let markers = &class.markers;
    let meshes = &class.meshes;
    let phi1 = pair.maps[i]
        .as_ref()
        .map_err(|e| format!("disk map of {}: {e}", class.name_of(i)))?;
    let phi2 = pair.maps[j]
        .as_ref()
        .map_err(|e| format!("disk map of {}: {e}", class.name_of(j)))?;
    let target_markers = if j < n {
        markers[j].0.display().to_string()
    } else {
        format!(
            "{} carried onto the remeshed {}",
            markers[j - n].0.display(),
            class.name_of(j - n)
        )
    };
    let landmarks = Landmarks::from_named(
        &markers[i].1.landmarks,
        &all_markers[j].landmarks,
        &format!("{} / {target_markers}", markers[i].0.display()),
    )
    .map_err(|e| error_chain(&e))?;
    let target = all_meshes[j];
    let mut reg = register_with_maps(&meshes[i], target, phi1, phi2, &landmarks, &(ctx.harmonic)(pair.method))
        .map_err(|e| error_chain(&e))?;
    if ctx.refine == Refinement::ZoomOut {
        let basis = |m: usize| {
            pair.bases[m]
                .as_ref()
                .map_err(|e| format!("eigenpairs of {}: {e}", class.name_of(m)))
        };
        refine_registration(
            &meshes[i],
            target,
            &mut reg,
            &landmarks,
            basis(i)?,
            basis(j)?,
            ctx.zoomout,
        )
        .map_err(|e| error_chain(&e))?;
    }
    let truth = pair.remeshed_target.map(|r| r.truth.as_slice());
    let met = registration_metrics_against(&meshes[i], target, &reg, ctx.metric_params, truth)
        .map_err(|e| error_chain(&e))?;
    // the refined vertex map before the untangling with points (and before the projection of
    // `ZoomOutOutput::Projected`), scored alike
    let before = match &reg.refinement {
        Some(info) => {
            let mut r = reg.clone();
            (r.faces, r.bary) = vertex_points(target, &info.vertex_map);
            r.points = info.vertex_map.iter().map(|&w| target.positions[w as usize]).collect();
            Some(
                registration_metrics_against(&meshes[i], target, &r, ctx.metric_params, truth)
                    .map_err(|e| error_chain(&e))?,
            )
        }
        _ => None,
    };
    Ok((reg, met, before))
}

/// Writes a successful pair's figures into its row: the metrics, the vertex map's scores
/// (`before`), the timings and the untangling counts.
fn fill_row(row: &mut BenchRow, reg: &Registration, met: &RegistrationMetrics, before: Option<&RegistrationMetrics>) {
    if let Some(b) = before {
        row.vertex_map_flipped_ratio_3d = b.flipped_area_ratio_3d;
        if let Some(g) = &b.geodesic {
            row.vertex_map_geodesic_mean = g.summary.mean;
            row.vertex_map_geodesic_median = g.summary.median;
        }
    }
    let shift = reg
        .harmonic_released
        .as_ref()
        .filter(|r| r.error.is_none())
        .map_or(0.0, |r| r.landmark_shift);
    fill_measures(
        row,
        met,
        (reg.harmonic_folded, shift),
        &reg.timings,
        reg.refinement.as_ref(),
    );
}

/// The columns both routes fill alike: the metrics, g's folds and largest landmark shift, the
/// seconds (the eigenpairs out of `pair_seconds`: the benchmarks compute them once per mesh)
/// and the refinement's untangling counts.
pub(super) fn fill_measures(
    row: &mut BenchRow,
    met: &RegistrationMetrics,
    (harmonic_folded, landmark_shift): (usize, f64),
    t: &super::RegistrationTimings,
    refinement: Option<&super::RefinementInfo>,
) {
    row.flipped_ratio = met.flipped_area_ratio;
    row.flipped_ratio_3d = met.flipped_area_ratio_3d;
    row.harmonic_folded = harmonic_folded;
    row.landmark_shift = landmark_shift;
    row.curvature_median = met.curvature_summary.median;
    row.curvature_mean = met.curvature_summary.mean;
    row.area_distortion_median = met.area_distortion_summary.median;
    row.area_distortion_p95 = met.area_distortion_summary.p95;
    row.area_distortion_mean_abs_log = met.log_area_distortion_summary.mean;
    if let Some(g) = &met.geodesic {
        row.geodesic_median = g.summary.median;
        row.geodesic_mean = g.summary.mean;
    }
    row.seconds = t.total;
    row.refine_seconds = t.refine;
    row.pair_seconds = t.total - t.source_map - t.target_map;
    if let Some(info) = refinement {
        row.eigen_seconds = info.eigen_seconds[0] + info.eigen_seconds[1];
        row.pair_seconds -= row.eigen_seconds;
        row.untangle_flipped_before = info.untangle.flipped_before;
        row.untangle_flipped_after = info.untangle.flipped_after;
        row.untangle_seconds = info.untangle.seconds;
        row.point_untangle_flipped_before = info.point_untangle.flipped_before;
        row.point_untangle_flipped_after = info.point_untangle.flipped_after;
        row.point_untangle_seconds = info.point_untangle.seconds;
    }
}

/// The per-mesh work (disk maps and eigenpairs, seconds per target) shared out over the rows of
/// one class and method: `amortized_seconds` and `stage1_amortized_seconds`.
pub(super) fn share_mesh_work(rows: &mut [BenchRow], mesh_seconds: &[f64], mesh_eigen_seconds: &[f64]) {
    let pairs = rows.len().max(1) as f64;
    let share = mesh_seconds.iter().sum::<f64>() / pairs;
    let eigen_share = mesh_eigen_seconds.iter().sum::<f64>() / pairs;
    for r in rows {
        r.amortized_seconds = r.pair_seconds + share;
        // without the refinement: no eigenpairs, no iterations
        let iterations = r.refine_seconds - r.eigen_seconds;
        r.stage1_amortized_seconds = r.amortized_seconds - eigen_share - iterations;
    }
}

/// Writes the rows as `results.csv`.
fn write_results_csv(path: &Path, rows: &[BenchRow]) -> Result<(), AnalysisError> {
    let mut w = csv::Writer::from_writer(create(path)?);
    for r in rows {
        w.serialize(r).map_err(|e| AnalysisError::Serialize {
            path: path.to_path_buf(),
            message: e.to_string(),
        })?;
    }
    w.into_inner()
        .map_err(|e| AnalysisError::io(path, e.into_error()))?
        .commit()
        .map_err(|e| AnalysisError::io(path, e))
}

/// Means over the successful rows per class (in order of appearance, then `all`), target
/// triangulation (`same`, then `remeshed` if any) and method.
fn summarize(rows: &[BenchRow], methods: &[Method], refine: Refinement) -> Vec<MethodSummary> {
    let mut class_names: Vec<String> = Vec::new();
    for r in rows {
        if !class_names.contains(&r.class) {
            class_names.push(r.class.clone());
        }
    }
    class_names.push("all".into());
    let mut kinds = vec![Triangulation::Same];
    if rows.iter().any(|r| r.triangulation == Triangulation::Remeshed) {
        kinds.push(Triangulation::Remeshed);
    }
    let groups: Vec<(String, Triangulation, Method)> = class_names
        .iter()
        .flat_map(|c| {
            kinds
                .iter()
                .flat_map(move |&t| methods.iter().map(move |&m| (c.clone(), t, m)))
        })
        .collect();
    groups
        .into_iter()
        .map(|(class, triangulation, m)| {
            let in_group = |r: &&BenchRow| {
                r.method == m && r.triangulation == triangulation && (class == "all" || r.class == class)
            };
            let ok: Vec<&BenchRow> = rows.iter().filter(in_group).filter(|r| r.status == "ok").collect();
            let mean = |f: &dyn Fn(&BenchRow) -> f64| {
                let v: Vec<f64> = ok.iter().map(|r| f(r)).filter(|x| x.is_finite()).collect();
                if v.is_empty() {
                    f64::NAN
                } else {
                    v.iter().sum::<f64>() / v.len() as f64
                }
            };
            MethodSummary {
                pairs_failed: rows.iter().filter(in_group).filter(|r| r.status != "ok").count(),
                class,
                triangulation,
                method: m,
                refine,
                pairs_ok: ok.len(),
                flipped_ratio: mean(&|r| r.flipped_ratio),
                flipped_ratio_3d: mean(&|r| r.flipped_ratio_3d),
                curvature_median: mean(&|r| r.curvature_median),
                curvature_mean: mean(&|r| r.curvature_mean),
                area_distortion_median: mean(&|r| r.area_distortion_median),
                area_distortion_p95: mean(&|r| r.area_distortion_p95),
                area_distortion_mean_abs_log: mean(&|r| r.area_distortion_mean_abs_log),
                geodesic_median: mean(&|r| r.geodesic_median),
                geodesic_mean: mean(&|r| r.geodesic_mean),
                seconds: mean(&|r| r.seconds),
                refine_seconds: mean(&|r| r.refine_seconds),
                eigen_seconds: mean(&|r| r.eigen_seconds),
                pair_seconds: mean(&|r| r.pair_seconds),
                amortized_seconds: mean(&|r| r.amortized_seconds),
                stage1_amortized_seconds: mean(&|r| r.stage1_amortized_seconds),
            }
        })
        .collect()
}

/// Writes `geodesic_curve.csv`: per threshold 0, 0.01, …, 0.25, the mean over pairs of the
/// fraction of samples under it, per class/method (sorted) and then all/method.
fn write_geodesic_curve(path: &Path, pooled: &[Pooled]) -> Result<(), AnalysisError> {
    let mut w = create(path)?;
    let io = |e| AnalysisError::io(path, e);
    // columns: class/method for every class with curves, then all/method
    let mut columns: Vec<(String, usize)> = Vec::new();
    for (mi, (_, _, _, curves)) in pooled.iter().enumerate() {
        for (c, _) in curves {
            if !columns.iter().any(|(cc, mm)| cc == c && *mm == mi) {
                columns.push((c.clone(), mi));
            }
        }
    }
    columns.sort();
    columns.extend((0..pooled.len()).map(|mi| ("all".to_string(), mi)));
    write!(w, "threshold").map_err(io)?;
    for (c, mi) in &columns {
        write!(w, ",{c}/{}", pooled[*mi].0).map_err(io)?;
    }
    writeln!(w).map_err(io)?;
    for k in 0..=25 {
        write!(w, "{:.2}", k as f64 * 0.01).map_err(io)?;
        for (c, mi) in &columns {
            let sel: Vec<f64> = pooled[*mi]
                .3
                .iter()
                .filter(|(cc, _)| c == "all" || cc == c)
                .map(|(_, f)| f[k])
                .collect();
            let v = if sel.is_empty() {
                f64::NAN
            } else {
                sel.iter().sum::<f64>() / sel.len() as f64
            };
            write!(w, ",{v:.6}").map_err(io)?;
        }
        writeln!(w).map_err(io)?;
    }
    w.commit().map_err(io)
}

/// Writes the pooled histograms of every method with samples, `curvature_difference.{png,svg}`
/// and `area_distortion.{png,svg}`, and returns their paths (none without samples).
fn write_pooled_histograms(out: &Path, pooled: &[Pooled]) -> Result<Vec<PathBuf>, AnalysisError> {
    let mut files = Vec::new();
    let have: Vec<&Pooled> = pooled.iter().filter(|p| !p.1.is_empty()).collect();
    if have.is_empty() {
        return Ok(files);
    }
    let curv_names: Vec<String> = have.iter().map(|p| series_name(p.0, &p.1)).collect();
    let area_names: Vec<String> = have.iter().map(|p| series_name(p.0, &p.2)).collect();
    let curv: Vec<(&str, &[f64])> = have
        .iter()
        .zip(&curv_names)
        .map(|(p, n)| (n.as_str(), p.1.as_slice()))
        .collect();
    let area: Vec<(&str, &[f64])> = have
        .iter()
        .zip(&area_names)
        .map(|(p, n)| (n.as_str(), p.2.as_slice()))
        .collect();
    for ext in ["png", "svg"] {
        let p = out.join(format!("curvature_difference.{ext}"));
        histograms(
            &p,
            &curv,
            HISTOGRAM_BINS,
            Some(HISTOGRAM_RANGE),
            "Curvature difference (all pairs)",
            "max(|c1|/|c2|, |c2|/|c1|)",
        )?;
        files.push(p);
        let p = out.join(format!("area_distortion.{ext}"));
        histograms(
            &p,
            &area,
            HISTOGRAM_BINS,
            Some(HISTOGRAM_RANGE),
            "Local area distortion (all pairs)",
            "max(J, 1/J)",
        )?;
        files.push(p);
    }
    Ok(files)
}

/// Histogram series name: the method and the share of values beyond the truncated range (the
/// bars show fractions of the values inside the range only).
fn series_name(method: impl std::fmt::Display, values: &[f64]) -> String {
    let beyond = values.iter().filter(|&&v| !(v <= HISTOGRAM_RANGE.1)).count();
    format!(
        "{method}: {:.0}% > {} not shown",
        100.0 * beyond as f64 / values.len().max(1) as f64,
        HISTOGRAM_RANGE.1
    )
}

pub use crate::error::error_chain;

/// One row of a peer's results (`scripts/pyfmaps_bench.py`'s CSV): the peer's geodesic error
/// of one ordered pair, scored like [`register_bench`], and its seconds from scratch. Read with
/// [`read_rows`].
#[derive(Clone, Debug, serde::Deserialize)]
pub struct PeerRow {
    pub class: String,
    pub source: String,
    pub target: String,
    pub triangulation: String,
    pub geodesic_mean: f64,
    pub geodesic_median: f64,
    pub seconds: f64,
}

/// Reads a CSV of rows (`results.csv` of [`register_bench`] into [`BenchRow`]s, or a peer's
/// results into [`PeerRow`]s); a malformed row is a `Parse` error naming its line.
pub fn read_rows<T: serde::de::DeserializeOwned>(path: &Path) -> Result<Vec<T>, AnalysisError> {
    let mut r = csv::Reader::from_path(path).map_err(|e| AnalysisError::Parse {
        path: path.to_path_buf(),
        line: 0,
        message: e.to_string(),
    })?;
    r.deserialize()
        .enumerate()
        .map(|(k, row)| {
            row.map_err(|e| AnalysisError::Parse {
                path: path.to_path_buf(),
                line: (k + 2) as u64,
                message: e.to_string(),
            })
        })
        .collect()
}

/// The side-by-side table of [`register_bench`]'s rows and a peer's (Markdown), per class,
/// target triangulation and method, over the ordered pairs both measured: geodesic error mean /
/// median (means over the pairs), their ratio (shapespace over peer, of the means), the flipped
/// 3D area (mean and max over the pairs, %), seconds per pair from scratch of both and
/// shapespace's ratio to its first stage (`seconds` over `seconds − refine_seconds`).
pub fn peer_comparison(rows: &[BenchRow], peer: &[PeerRow]) -> String {
    let mut groups: Vec<(String, Triangulation, Method)> = Vec::new();
    for r in rows.iter().filter(|r| r.status == "ok") {
        let key = (r.class.clone(), r.triangulation, r.method);
        if !groups.contains(&key) {
            groups.push(key);
        }
    }
    let mut out = String::from(
        "| class | target | method | pairs | shapespace geodesic mean / median | peer geodesic mean / median | ratio of means | flipped 3D area %: mean (max) | s/pair shapespace (× first stage) | s/pair peer |\n|---|---|---|---|---|---|---|---|---|---|\n",
    );
    for (class, tri, method) in groups {
        let matched: Vec<(&BenchRow, &PeerRow)> = rows
            .iter()
            .filter(|r| r.status == "ok" && r.class == class && r.triangulation == tri && r.method == method)
            .filter_map(|r| {
                peer.iter()
                    .find(|p| {
                        p.class == r.class
                            && p.source == r.source
                            && p.target == r.target
                            && p.triangulation == tri.name()
                    })
                    .map(|p| (r, p))
            })
            .collect();
        if matched.is_empty() {
            continue;
        }
        let mean =
            |f: &dyn Fn(&(&BenchRow, &PeerRow)) -> f64| matched.iter().map(f).sum::<f64>() / matched.len() as f64;
        let (s_mean, s_median) = (mean(&|m| m.0.geodesic_mean), mean(&|m| m.0.geodesic_median));
        let (p_mean, p_median) = (mean(&|m| m.1.geodesic_mean), mean(&|m| m.1.geodesic_median));
        let flip = mean(&|m| m.0.flipped_ratio_3d);
        let flip_max = matched.iter().map(|m| m.0.flipped_ratio_3d).fold(0.0, f64::max);
        let secs = mean(&|m| m.0.seconds);
        let stage1 = mean(&|m| m.0.seconds - m.0.refine_seconds);
        out += &format!(
            "| {class} | {tri} | {method} {} | {} | {s_mean:.4} / {s_median:.4} | {p_mean:.4} / {p_median:.4} | {:.2} | {:.2} ({:.2}) | {secs:.1} ({:.1}×) | {:.1} |\n",
            rows.iter().find(|r| r.class == class).map_or("", |r| r.refine.name()),
            matched.len(),
            s_mean / p_mean,
            100.0 * flip,
            100.0 * flip_max,
            secs / stage1,
            mean(&|m| m.1.seconds),
        );
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    fn row(source: &str, target: &str, triangulation: Triangulation, mean: f64, flips: f64) -> BenchRow {
        BenchRow {
            flipped_ratio: 0.0,
            flipped_ratio_3d: flips,
            curvature_median: 1.0,
            curvature_mean: 1.0,
            area_distortion_median: 1.0,
            area_distortion_p95: 1.0,
            area_distortion_mean_abs_log: 0.0,
            geodesic_median: mean / 2.0,
            geodesic_mean: mean,
            seconds: 10.0,
            refine_seconds: 8.0,
            eigen_seconds: 4.0,
            pair_seconds: 6.0,
            amortized_seconds: 6.0,
            stage1_amortized_seconds: 1.0,
            ..BenchRow::pending(
                "wolf",
                source.into(),
                target.into(),
                triangulation,
                Method::Omt,
                Refinement::ZoomOut,
            )
        }
    }

    fn peer(source: &str, target: &str, triangulation: &str, mean: f64) -> PeerRow {
        PeerRow {
            class: "wolf".into(),
            source: source.into(),
            target: target.into(),
            triangulation: triangulation.into(),
            geodesic_mean: mean,
            geodesic_median: mean / 4.0,
            seconds: 30.0,
        }
    }

    #[test]
    fn the_peer_table_pairs_rows_by_class_pair_and_triangulation() {
        let rows = vec![
            row("a", "b", Triangulation::Same, 0.002, 0.001),
            row("b", "a", Triangulation::Same, 0.004, 0.003),
            row("a", "b", Triangulation::Remeshed, 0.008, 0.009),
            // no peer row for this pair: left out of the means
            row("b", "a", Triangulation::Remeshed, 1.0, 0.5),
        ];
        let peers = vec![
            peer("a", "b", "same", 0.004),
            peer("b", "a", "same", 0.004),
            peer("a", "b", "remeshed", 0.010),
        ];
        let table = peer_comparison(&rows, &peers);
        // results.csv read back gives the same table
        let path = std::env::temp_dir().join(format!("shapespace-results-{}.csv", std::process::id()));
        let mut w = csv::Writer::from_path(&path).unwrap();
        rows.iter().for_each(|r| w.serialize(r).unwrap());
        w.flush().unwrap();
        let back: Vec<BenchRow> = read_rows(&path).unwrap();
        std::fs::remove_file(&path).unwrap();
        assert_eq!(peer_comparison(&back, &peers), table);
        let lines: Vec<&str> = table.lines().collect();
        assert_eq!(lines.len(), 4, "{table}");
        assert_eq!(
            lines[2],
            "| wolf | same | omt zoomout | 2 | 0.0030 / 0.0015 | 0.0040 / 0.0010 | 0.75 | 0.20 (0.30) | 10.0 (5.0×) | 30.0 |"
        );
        assert_eq!(
            lines[3],
            "| wolf | remeshed | omt zoomout | 1 | 0.0080 / 0.0040 | 0.0100 / 0.0025 | 0.80 | 0.90 (0.90) | 10.0 (5.0×) | 30.0 |"
        );
    }

    #[test]
    fn a_bad_peer_csv_names_its_line() {
        let path = std::env::temp_dir().join(format!("shapespace-peer-{}.csv", std::process::id()));
        std::fs::write(
            &path,
            "class,source,target,triangulation,geodesic_mean,geodesic_median,seconds\nwolf,a,b,same,0.1,0.1,3\nwolf,a,b,same,x,0.1,3\n",
        )
        .unwrap();
        let err = read_rows::<PeerRow>(&path).unwrap_err().to_string();
        std::fs::remove_file(&path).unwrap();
        assert!(err.contains(":3:") || err.contains("line 3"), "{err}");
    }
}
