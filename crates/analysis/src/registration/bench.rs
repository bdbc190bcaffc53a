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
use crate::registration::metrics::{registration_metrics, MetricParams, RegistrationMetrics};
use crate::registration::{
    disk_image, refine_registration, register_with_maps, DiskImage, HarmonicParams, Landmarks, Method, Refinement,
    Registration, SpectralBasis, ZoomOutParams,
};

/// Per method: the pooled curvature-difference and area-distortion samples, and the geodesic
/// errors per class.
type Pooled = (Method, Vec<f64>, Vec<f64>, Vec<(String, Vec<f64>)>);

/// Histogram range of the curvature difference and the area distortion (Su et al. 2015, Fig. 7).
pub const HISTOGRAM_RANGE: (f64, f64) = (1.0, 3.0);
/// Number of histogram bins over [`HISTOGRAM_RANGE`].
pub const HISTOGRAM_BINS: usize = 40;

/// Starts writing `path` atomically (committed by the caller).
fn create(path: &Path) -> Result<AtomicFile, AnalysisError> {
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
    let json = serde_json::json!({
        "method": reg.method,
        "timings": reg.timings,
        "num_snapped": reg.num_snapped,
        "max_snap_distance": reg.max_snap_distance,
        "metrics": metrics,
        "histogram_range": HISTOGRAM_RANGE,
        "histogram_bins": HISTOGRAM_BINS,
        "run": extra,
    });
    let text = serde_json::to_string_pretty(&json).map_err(|e| AnalysisError::Serialize {
        path: path.clone(),
        message: e.to_string(),
    })?;
    write_atomically(&path, text.as_bytes()).map_err(|e| AnalysisError::io(&path, e))?;
    files.push(path);

    for ext in ["png", "svg"] {
        let p = out.join(format!("curvature_difference.{ext}"));
        let cname = series_name(reg.method, &metrics.curvature_difference);
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
        let aname = series_name(reg.method, &metrics.area_distortion);
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
#[derive(Clone, Debug, Serialize)]
pub struct BenchRow {
    pub class: String,
    pub source: String,
    pub target: String,
    pub method: Method,
    /// The refinement after the disk-map stage.
    pub refine: Refinement,
    /// `ok`, or the error that stopped this pair.
    pub status: String,
    pub flipped_ratio: f64,
    pub flipped_ratio_3d: f64,
    /// Folded faces of g ∘ φ₁ before its fold repair (exact predicate).
    pub harmonic_folded: usize,
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
}

/// Means over the successful pairs of one method (in one class, or `all`).
#[derive(Clone, Debug, Serialize)]
pub struct MethodSummary {
    /// The class folder, or `all` for every class together.
    pub class: String,
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
fn mesh_files(dir: &Path) -> Result<Vec<PathBuf>, AnalysisError> {
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

fn stem(p: &Path) -> String {
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
#[allow(clippy::too_many_arguments)]
pub fn register_bench(
    dataset: &Path,
    out: &Path,
    methods: &[Method],
    params: &AreaPreservingParams,
    harmonic: &dyn Fn(Method) -> HarmonicParams,
    refine: Refinement,
    zoomout: &ZoomOutParams,
    metric_params: &MetricParams,
    mut progress: impl FnMut(&str),
) -> Result<BenchResult, AnalysisError> {
    let t0 = Instant::now();
    std::fs::create_dir_all(out).map_err(|e| AnalysisError::io(out, e))?;
    let mut classes: Vec<PathBuf> = std::fs::read_dir(dataset)
        .map_err(|e| AnalysisError::io(dataset, e))?
        .filter_map(|e| e.ok().map(|e| e.path()))
        .filter(|p| p.is_dir())
        .collect();
    classes.sort();
    let mut rows = Vec::new();
    let mut pooled: Vec<Pooled> = methods
        .iter()
        .map(|&m| (m, Vec::new(), Vec::new(), Vec::new()))
        .collect();
    let mut num_classes = 0;
    for class_dir in &classes {
        let files = mesh_files(class_dir)?;
        if files.len() < 2 {
            continue;
        }
        num_classes += 1;
        let class = stem(class_dir);
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
        let bases: Vec<Result<SpectralBasis, String>> = if refine == Refinement::ZoomOut {
            meshes
                .iter()
                .zip(&files)
                .map(|(m, f)| {
                    progress(&format!("{class}: eigenpairs of {}", stem(f)));
                    SpectralBasis::of(m, zoomout.k_end, &zoomout.eigen).map_err(|e| error_chain(&e))
                })
                .collect()
        } else {
            Vec::new()
        };
        for (mi, &method) in methods.iter().enumerate() {
            let maps: Vec<Result<DiskImage, String>> = meshes
                .iter()
                .zip(&markers)
                .zip(&files)
                .map(|((m, (_, mf)), f)| {
                    progress(&format!("{class}: {method} disk map of {}", stem(f)));
                    disk_image(m, &mf.markers, method, params).map_err(|e| error_chain(&e))
                })
                .collect();
            let first_row = rows.len();
            let mut mesh_seconds = vec![0.0; meshes.len()];
            let mut mesh_eigen_seconds = vec![0.0; meshes.len()];
            for i in 0..meshes.len() {
                for j in 0..meshes.len() {
                    if i == j {
                        continue;
                    }
                    let (src, tgt) = (stem(&files[i]), stem(&files[j]));
                    progress(&format!("{class}: {method} {src} -> {tgt}"));
                    let mut row = BenchRow {
                        class: class.clone(),
                        source: src,
                        target: tgt,
                        method,
                        refine,
                        status: "ok".into(),
                        flipped_ratio: f64::NAN,
                        flipped_ratio_3d: f64::NAN,
                        harmonic_folded: 0,
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
                    };
                    let outcome = (|| -> Result<(Registration, RegistrationMetrics), String> {
                        let phi1 = maps[i]
                            .as_ref()
                            .map_err(|e| format!("disk map of {}: {e}", stem(&files[i])))?;
                        let phi2 = maps[j]
                            .as_ref()
                            .map_err(|e| format!("disk map of {}: {e}", stem(&files[j])))?;
                        let landmarks = Landmarks::from_named(
                            &markers[i].1.landmarks,
                            &markers[j].1.landmarks,
                            &format!("{} / {}", markers[i].0.display(), markers[j].0.display()),
                        )
                        .map_err(|e| error_chain(&e))?;
                        let mut reg =
                            register_with_maps(&meshes[i], &meshes[j], phi1, phi2, &landmarks, &harmonic(method))
                                .map_err(|e| error_chain(&e))?;
                        if refine == Refinement::ZoomOut {
                            let basis = |m: usize| {
                                bases[m]
                                    .as_ref()
                                    .map_err(|e| format!("eigenpairs of {}: {e}", stem(&files[m])))
                            };
                            refine_registration(&meshes[i], &meshes[j], &mut reg, basis(i)?, basis(j)?, zoomout)
                                .map_err(|e| error_chain(&e))?;
                        }
                        let met = registration_metrics(&meshes[i], &meshes[j], &reg, metric_params)
                            .map_err(|e| error_chain(&e))?;
                        Ok((reg, met))
                    })();
                    match outcome {
                        Ok((reg, met)) => {
                            row.flipped_ratio = met.flipped_area_ratio;
                            row.flipped_ratio_3d = met.flipped_area_ratio_3d;
                            row.harmonic_folded = reg.harmonic_folded;
                            row.curvature_median = met.curvature_summary.median;
                            row.curvature_mean = met.curvature_summary.mean;
                            row.area_distortion_median = met.area_distortion_summary.median;
                            row.area_distortion_p95 = met.area_distortion_summary.p95;
                            row.area_distortion_mean_abs_log = met.log_area_distortion_summary.mean;
                            if let Some(g) = &met.geodesic {
                                row.geodesic_median = g.summary.median;
                                row.geodesic_mean = g.summary.mean;
                                pooled[mi].3.push((class.clone(), g.fractions.clone()));
                            }
                            row.seconds = reg.timings.total;
                            row.refine_seconds = reg.timings.refine;
                            let t = &reg.timings;
                            row.pair_seconds = t.total - t.source_map - t.target_map;
                            if let Some(info) = &reg.refinement {
                                row.eigen_seconds = info.eigen_seconds[0] + info.eigen_seconds[1];
                                row.pair_seconds -= row.eigen_seconds;
                                row.untangle_flipped_before = info.untangle.flipped_before;
                                row.untangle_flipped_after = info.untangle.flipped_after;
                                row.untangle_seconds = info.untangle.seconds;
                            }
                            let eigen = |k: usize| reg.refinement.as_ref().map_or(0.0, |r| r.eigen_seconds[k]);
                            mesh_seconds[i] = t.source_map + eigen(0);
                            mesh_seconds[j] = t.target_map + eigen(1);
                            mesh_eigen_seconds[i] = eigen(0);
                            mesh_eigen_seconds[j] = eigen(1);
                            pooled[mi].1.extend_from_slice(&met.curvature_difference);
                            pooled[mi].2.extend_from_slice(&met.area_distortion);
                        }
                        Err(e) => row.status = e,
                    }
                    rows.push(row);
                }
            }
            // the per-mesh work shared out over the class's pairs
            let pairs = (rows.len() - first_row).max(1) as f64;
            let share = mesh_seconds.iter().sum::<f64>() / pairs;
            let eigen_share = mesh_eigen_seconds.iter().sum::<f64>() / pairs;
            for r in &mut rows[first_row..] {
                r.amortized_seconds = r.pair_seconds + share;
                // without the refinement: no eigenpairs, no iterations
                let iterations = r.refine_seconds - r.eigen_seconds;
                r.stage1_amortized_seconds = r.amortized_seconds - eigen_share - iterations;
            }
        }
    }
    if num_classes == 0 {
        return Err(AnalysisError::InvalidInput(format!(
            "{}: no class folder with at least 2 mesh files (.obj, .off, .ply); expected DATASET/CLASS/*.obj with a landmarks.json",
            dataset.display()
        )));
    }
    let mut files = Vec::new();
    let path = out.join("results.csv");
    {
        let mut w = csv::Writer::from_writer(create(&path)?);
        for r in &rows {
            w.serialize(r).map_err(|e| AnalysisError::Serialize {
                path: path.clone(),
                message: e.to_string(),
            })?;
        }
        w.into_inner()
            .map_err(|e| AnalysisError::io(&path, e.into_error()))?
            .commit()
            .map_err(|e| AnalysisError::io(&path, e))?;
    }
    files.push(path);

    let mut class_names: Vec<String> = Vec::new();
    for r in &rows {
        if !class_names.contains(&r.class) {
            class_names.push(r.class.clone());
        }
    }
    class_names.push("all".into());
    let groups: Vec<(String, Method)> = class_names
        .iter()
        .flat_map(|c| methods.iter().map(move |&m| (c.clone(), m)))
        .collect();
    let summaries: Vec<MethodSummary> = groups
        .into_iter()
        .map(|(class, m)| {
            let in_group = |r: &&BenchRow| r.method == m && (class == "all" || r.class == class);
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
        .collect();

    let path = out.join("geodesic_curve.csv");
    {
        let mut w = create(&path)?;
        let io = |e| AnalysisError::io(&path, e);
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
        w.commit().map_err(io)?;
    }
    files.push(path);

    let have: Vec<&Pooled> = pooled.iter().filter(|p| !p.1.is_empty()).collect();
    if !have.is_empty() {
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
    }
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

/// Histogram series name: the method and the share of values beyond the truncated range (the
/// bars show fractions of the values inside the range only).
fn series_name(method: Method, values: &[f64]) -> String {
    let beyond = values.iter().filter(|&&v| !(v <= HISTOGRAM_RANGE.1)).count();
    format!(
        "{method}: {:.0}% > {} not shown",
        100.0 * beyond as f64 / values.len().max(1) as f64,
        HISTOGRAM_RANGE.1
    )
}

pub use crate::error::error_chain;
