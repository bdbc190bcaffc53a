//! Merging the folders of `distances --shard K/N` runs into one run ([`merge_shards`]): every
//! shard must come from the same inputs and settings, and together they must cover each pair
//! exactly once.

use std::collections::{HashMap, HashSet};
use std::path::{Path, PathBuf};
use std::time::Instant;

use super::run_folder::lock_output_folder;
use super::run_report::{write_run, DistancesReport, DistancesRun, RunParts, StageTimings};
use crate::distance::{matrix_from_pairs, PairRecord};
use crate::error::AnalysisError;
use crate::resume::{RunIdentity, PAIRS_HEADER};

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
