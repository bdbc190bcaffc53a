//! The record of a distances run: `report.json` ([`DistancesReport`]: inputs, options,
//! timings, failures, summaries, dual gaps, the resume key), and the writing of a run's files
//! from its parts, shared by a run and by the merge of shards.

use std::path::{Path, PathBuf};
use std::time::Instant;

use serde::Serialize;
use shapespace_geometry::io::write_atomically;

use super::run_folder::{remove_if_present, write_pairs_csv};
use crate::distance::PairRecord;
use crate::error::AnalysisError;
use crate::matrix_io::{write_distance_matrix, DistanceMatrix};
use crate::resume::{ResumeReport, RunIdentity};
use crate::run_settings::{DistancesOptions, ShapeReport};
use crate::stats::{summarize, Summary};

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
    /// `DistancesOptions::source_faces` (absent when not set).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub source_faces: Option<usize>,
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

/// The result of [`run_distances`](super::pipeline::run_distances).
#[derive(Clone, Debug)]
pub struct DistancesRun {
    pub matrix: DistanceMatrix,
    pub pairs: Vec<PairRecord>,
    pub report: DistancesReport,
    /// Shapes taken from [`DistancesOptions::cache`] (not in the report, so that a run with and
    /// without the cache writes the same files).
    pub cache_hits: usize,
}

/// The options of a run as its report records them.
pub(super) fn report_options(options: &DistancesOptions) -> ReportOptions {
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
        source_faces: options.source_faces,
        domain: None,
    }
}

/// What [`write_run`] writes: a run's (or the merged shards') inputs, options, pairs and matrix.
pub(super) struct RunParts {
    pub(super) inputs: Vec<ShapeReport>,
    pub(super) options: ReportOptions,
    pub(super) threads: usize,
    pub(super) timings: StageTimings,
    /// By target, then source (pair names are replaced by the inputs' names).
    pub(super) pairs: Vec<PairRecord>,
    pub(super) matrix: Vec<f64>,
    pub(super) asymmetries: Vec<f64>,
    pub(super) debias: Option<DebiasReport>,
    pub(super) resumed: Option<ResumeReport>,
    pub(super) marker_warnings: Vec<String>,
    pub(super) identity: RunIdentity,
    pub(super) shard: Option<crate::shard::Shard>,
}

/// Writes `out/distances.csv`, `out/pairs.csv` and `out/report.json` (each atomically) from
/// `parts`; the report's summaries (failures, iterations, asymmetry, dual gaps) are computed
/// here from the pairs, so a run and the merge of its shards write the same bytes.
pub(super) fn write_run(out: &Path, parts: RunParts, t_total: Instant) -> Result<DistancesRun, AnalysisError> {
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
