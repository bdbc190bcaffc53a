//! The main job: conformal Wasserstein distances among mesh files, written as files a
//! statistician can use directly (`distances.csv`, `pairs.csv`, `report.json`).
//!
//! Each file is read, validated and mapped once ([`crate::distance::prepare_shape`]); a file that
//! fails (unreadable, not a disk, bad markers) is reported with its reason and its row and
//! column of the matrix are empty, while all other pairs still complete.

use std::collections::{HashMap, HashSet};
use std::path::{Path, PathBuf};
use std::time::Instant;

use shapespace_geometry::io::write_atomically;

use crate::distance::{directed_pairs, pairwise_distances_of, PairRecord};
use crate::error::AnalysisError;
pub use crate::resume::{build_identity, InputIdentity, ResumeReport, RunIdentity};
use crate::resume::{earlier_pairs, run_identity};
pub use crate::run_settings::{
    DistancesOptions, Domain, MarkerChoice, MarkerOptions, ShapeReport, PARTIAL_IDENTITY, PARTIAL_PAIRS,
    PREVIOUS_PARTIAL_IDENTITY, PREVIOUS_PARTIAL_PAIRS,
};

pub use super::inputs::{markers_for, mesh_sha256, prepare_inputs, shape_names, PreparedInputs};
pub use super::merge::merge_shards;
pub use super::run_folder::{lock_output_folder, write_pairs_csv, LOCK_FILE};
use super::run_folder::{remove_if_present, PartialPairs};
use super::run_report::{report_options, write_run, RunParts};
pub use super::run_report::{DebiasReport, DistancesReport, DistancesRun, ReportOptions, StageTimings};

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
