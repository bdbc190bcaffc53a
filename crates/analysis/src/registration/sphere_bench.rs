//! The sphere route of the registration benchmark: the closed poses behind a disk benchmark's
//! cut poses ([`super::bench::register_bench`]), registered on the sphere ([`super::sphere`])
//! with the same landmarks and the same metrics, so that one run measures both routes.
//!
//! A class folder `DATASET/CLASS` of cut poses `NAME.off` (with `landmarks.json` and, when the
//! cut dropped vertices, `original_indices.txt`: line i = the closed mesh's index of cut vertex
//! i, kept vertices in their original order) has closed poses `CLOSED/NAME.{off,obj,ply}`; the
//! landmarks are carried to the closed meshes through `original_indices.txt`. The closed poses
//! of a class share their vertex order, so v ↔ v is the ground truth of the geodesic error, as
//! for the cut poses; the sampled vertices differ (the closed meshes have the cut's vertices
//! and the few it removed).

use std::collections::BTreeMap;
use std::io::Write;
use std::path::{Path, PathBuf};
use std::time::Instant;

use serde::Serialize;
use shapespace_conformal::MarkerFile;
use shapespace_geometry::io::write_atomically;
use shapespace_geometry::TriMesh;

use super::bench::{create, fill_measures, mesh_files, share_mesh_work, stem, BenchRow, MethodSummary, Triangulation};
use super::sphere::{register_sphere_with_maps, sphere_image, sphere_registration_metrics, SphereImage};
use super::{
    refine_registration, HarmonicParams, Landmarks, Method, MetricParams, Refinement, SpectralBasis, ZoomOutParams,
};
use crate::error::{error_chain, AnalysisError};
use crate::sphere_param::SphereParamParams;

/// The named landmarks of a class folder of cut poses carried to the closed poses: the
/// landmarks of `CLASS/landmarks.json`, each vertex index i replaced by line i of
/// `CLASS/original_indices.txt` (unchanged when there is no such file). Errors name the file
/// and the line.
pub fn closed_pose_landmarks(class_dir: &Path) -> Result<BTreeMap<String, u32>, AnalysisError> {
    let json = class_dir.join("landmarks.json");
    let mf = MarkerFile::from_json_file(&json).map_err(|e| AnalysisError::Shape {
        name: json.display().to_string(),
        message: error_chain(&e),
    })?;
    let map_path = class_dir.join("original_indices.txt");
    if !map_path.is_file() {
        return Ok(mf.landmarks);
    }
    let text = std::fs::read_to_string(&map_path).map_err(|e| AnalysisError::io(&map_path, e))?;
    let map: Vec<u32> = text
        .lines()
        .enumerate()
        .filter(|(_, l)| !l.trim().is_empty())
        .map(|(i, l)| {
            l.trim()
                .parse::<u32>()
                .map_err(|_| AnalysisError::parse(&map_path, i as u64 + 1, format!("`{l}` is not a vertex index")))
        })
        .collect::<Result<_, _>>()?;
    mf.landmarks
        .into_iter()
        .map(|(name, v)| {
            map.get(v as usize)
                .map(|&w| (name.clone(), w))
                .ok_or_else(|| AnalysisError::Landmark {
                    source_name: json.display().to_string(),
                    landmark: name,
                    message: format!("vertex {v} has no line in {} ({} lines)", map_path.display(), map.len()),
                })
        })
        .collect()
}

/// Result of [`sphere_bench`].
#[derive(Clone, Debug, Serialize)]
pub struct SphereBenchResult {
    /// One row per ordered pair and method (`flipped_ratio`: on the sphere).
    pub rows: Vec<BenchRow>,
    /// Means per class and method, and over all classes (`all`).
    pub summaries: Vec<MethodSummary>,
    /// Wall-clock seconds.
    pub total_seconds: f64,
    /// Files written.
    #[serde(serialize_with = "crate::report_path::many")]
    pub files: Vec<PathBuf>,
}

/// The sphere route over the closed poses of every class folder of `dataset` found in
/// `closed` (module docs): per method the sphere maps once per pose, every ordered pair
/// registered ([`register_sphere_with_maps`] with `harmonic(method)`), with
/// [`Refinement::ZoomOut`] refined ([`super::refine_registration`] with `zoomout`; the
/// eigenpairs once per pose) and measured ([`sphere_registration_metrics`]; the `vertex_map_*`
/// columns are left NaN); `sphere_results.csv` and `sphere_summary.json` in `out`.
/// A class without closed poses is skipped (reported through `progress`); a pair whose sphere
/// map fails is recorded with its error. Errors: unreadable folders or files, no class with
/// closed poses.
#[allow(clippy::too_many_arguments)]
pub fn sphere_bench(
    dataset: &Path,
    closed: &Path,
    out: &Path,
    methods: &[Method],
    sphere_params: &SphereParamParams,
    harmonic: &dyn Fn(Method) -> HarmonicParams,
    refine: Refinement,
    zoomout: &ZoomOutParams,
    metric_params: &MetricParams,
    mut progress: impl FnMut(&str),
) -> Result<SphereBenchResult, AnalysisError> {
    let t0 = Instant::now();
    std::fs::create_dir_all(out).map_err(|e| AnalysisError::io(out, e))?;
    let mut classes: Vec<PathBuf> = std::fs::read_dir(dataset)
        .map_err(|e| AnalysisError::io(dataset, e))?
        .filter_map(|e| e.ok().map(|e| e.path()))
        .filter(|p| p.is_dir())
        .collect();
    classes.sort();
    let available = mesh_files(closed)?;
    let mut rows = Vec::new();
    for class_dir in &classes {
        let class = stem(class_dir);
        let poses = mesh_files(class_dir)?;
        let files: Vec<PathBuf> = poses
            .iter()
            .filter_map(|p| available.iter().find(|c| stem(c) == stem(p)).cloned())
            .collect();
        if files.len() < 2 || files.len() != poses.len() {
            progress(&format!(
                "{class}: {} of {} poses closed in {}: skipped on the sphere",
                files.len(),
                poses.len(),
                closed.display()
            ));
            continue;
        }
        let named = closed_pose_landmarks(class_dir)?;
        let mut meshes = Vec::new();
        for f in &files {
            meshes.push(shapespace_geometry::io::read_mesh(f).map_err(|e| AnalysisError::Shape {
                name: f.display().to_string(),
                message: e.to_string(),
            })?);
        }
        let landmarks = Landmarks::from_named(
            &named,
            &named,
            &format!(
                "{} carried to the closed poses",
                class_dir.join("landmarks.json").display()
            ),
        )?;
        // the eigenpairs, once per pose for every method's pairs
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
        for &method in methods {
            let maps: Vec<Result<SphereImage, String>> = meshes
                .iter()
                .zip(&files)
                .map(|(m, f)| {
                    progress(&format!("{class}: {method} sphere map of {}", stem(f)));
                    sphere_image(m, method, sphere_params).map_err(|e| error_chain(&e))
                })
                .collect();
            let first_row = rows.len();
            let mesh_seconds: f64 = maps.iter().flatten().map(|m| m.seconds).sum();
            for i in 0..meshes.len() {
                for j in 0..meshes.len() {
                    if i == j {
                        continue;
                    }
                    progress(&format!(
                        "{class}: sphere {method} {} -> {}",
                        stem(&files[i]),
                        stem(&files[j])
                    ));
                    let mut row = BenchRow::pending(
                        &class,
                        stem(&files[i]),
                        stem(&files[j]),
                        Triangulation::Same,
                        method,
                        refine,
                    );
                    let outcome = pair(
                        (&meshes[i], &meshes[j]),
                        (&maps[i], &maps[j]),
                        bases.get(i).zip(bases.get(j)),
                        &landmarks,
                        method,
                        harmonic,
                        zoomout,
                        metric_params,
                    );
                    match outcome {
                        Ok((reg, met)) => {
                            let shift = reg.harmonic_sphere_repair.as_ref().map_or(0.0, |r| r.landmark_shift);
                            fill_measures(
                                &mut row,
                                &met,
                                (reg.harmonic_folded, shift),
                                &reg.timings,
                                reg.refinement.as_ref(),
                            );
                        }
                        Err(e) => row.status = e,
                    }
                    rows.push(row);
                }
            }
            let eigen_seconds: Vec<f64> = bases.iter().map(|b| b.as_ref().map_or(0.0, |b| b.seconds)).collect();
            // per-mesh work: the sphere maps and the eigenpairs, as the disk route counts it
            let mesh_work = mesh_seconds + eigen_seconds.iter().sum::<f64>();
            share_mesh_work(&mut rows[first_row..], &[mesh_work], &eigen_seconds);
        }
    }
    if rows.is_empty() {
        return Err(AnalysisError::InvalidInput(format!(
            "no class of {} has its poses closed in {} (NAME.off, .obj or .ply for every pose NAME)",
            dataset.display(),
            closed.display()
        )));
    }
    let summaries = summarize(&rows, methods, refine);
    let mut files = Vec::new();
    let path = out.join("sphere_results.csv");
    {
        let mut w = csv::Writer::from_writer(create(&path)?);
        for r in &rows {
            w.serialize(r).map_err(|e| AnalysisError::Serialize {
                path: path.clone(),
                message: e.to_string(),
            })?;
        }
        let mut inner = w.into_inner().map_err(|e| AnalysisError::io(&path, e.into_error()))?;
        inner.flush().map_err(|e| AnalysisError::io(&path, e))?;
        inner.commit().map_err(|e| AnalysisError::io(&path, e))?;
    }
    files.push(path);
    let total_seconds = t0.elapsed().as_secs_f64();
    let path = out.join("sphere_summary.json");
    let text = serde_json::to_string_pretty(&serde_json::json!({
        "domain": "sphere",
        "closed_poses": closed.display().to_string(),
        "summaries": summaries,
        "total_seconds": total_seconds,
    }))
    .map_err(|e| AnalysisError::Serialize {
        path: path.clone(),
        message: e.to_string(),
    })?;
    write_atomically(&path, text.as_bytes()).map_err(|e| AnalysisError::io(&path, e))?;
    files.push(path);
    Ok(SphereBenchResult {
        rows,
        summaries,
        total_seconds,
        files,
    })
}

type Bases<'a> = Option<(&'a Result<SpectralBasis, String>, &'a Result<SpectralBasis, String>)>;

#[allow(clippy::too_many_arguments)]
fn pair(
    (source, target): (&TriMesh, &TriMesh),
    (psi1, psi2): (&Result<SphereImage, String>, &Result<SphereImage, String>),
    bases: Bases<'_>,
    landmarks: &Landmarks,
    method: Method,
    harmonic: &dyn Fn(Method) -> HarmonicParams,
    zoomout: &ZoomOutParams,
    metric_params: &MetricParams,
) -> Result<(super::sphere::SphereRegistration, super::RegistrationMetrics), String> {
    let psi1 = psi1.as_ref().map_err(|e| format!("sphere map of the source: {e}"))?;
    let psi2 = psi2.as_ref().map_err(|e| format!("sphere map of the target: {e}"))?;
    let mut reg = register_sphere_with_maps(source, target, psi1, psi2, landmarks, &harmonic(method))
        .map_err(|e| error_chain(&e))?;
    if let Some((b1, b2)) = bases {
        let b1 = b1.as_ref().map_err(|e| format!("eigenpairs of the source: {e}"))?;
        let b2 = b2.as_ref().map_err(|e| format!("eigenpairs of the target: {e}"))?;
        refine_registration(source, target, &mut reg, landmarks, b1, b2, zoomout).map_err(|e| error_chain(&e))?;
    }
    let met = sphere_registration_metrics(source, target, &reg, metric_params).map_err(|e| error_chain(&e))?;
    Ok((reg, met))
}

/// Means over the successful rows per class and method, then over all classes.
fn summarize(rows: &[BenchRow], methods: &[Method], refine: Refinement) -> Vec<MethodSummary> {
    let mut classes: Vec<String> = Vec::new();
    for r in rows {
        if !classes.contains(&r.class) {
            classes.push(r.class.clone());
        }
    }
    classes.push("all".into());
    let mut out = Vec::new();
    for class in classes {
        for &m in methods {
            let group = |r: &&BenchRow| r.method == m && (class == "all" || r.class == class);
            let ok: Vec<&BenchRow> = rows.iter().filter(group).filter(|r| r.status == "ok").collect();
            let mean = |f: &dyn Fn(&BenchRow) -> f64| {
                let v: Vec<f64> = ok.iter().map(|r| f(r)).filter(|x| x.is_finite()).collect();
                if v.is_empty() {
                    f64::NAN
                } else {
                    v.iter().sum::<f64>() / v.len() as f64
                }
            };
            out.push(MethodSummary {
                class: class.clone(),
                triangulation: Triangulation::Same,
                method: m,
                refine,
                pairs_ok: ok.len(),
                pairs_failed: rows.iter().filter(group).filter(|r| r.status != "ok").count(),
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
            });
        }
    }
    out
}
