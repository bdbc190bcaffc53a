//! Resuming a pairwise run: what a directed pair's result depends on ([`RunIdentity`]: the
//! executable, the settings, and per input the file's bytes and markers), recorded beside the
//! pairs files of a run, and the rows of earlier runs in an output folder that a new run can
//! take instead of computing them (`earlier_pairs`, used by
//! [`run_distances`](crate::pipeline::run_distances) with `resume`).
//!
//! A row is taken only if it is intact: its `check` column ([`row_check`]) covers the run's
//! settings and build, the keys of its two inputs and its values as written, so a row changed
//! after it was written (by hand, or a disk error) is not taken silently; and its values must be
//! those a computation gives (`invalid_values`: a converged pair has a finite distance >= 0
//! that is the square root of its cost, a pair that did not converge has none, the status is one
//! the solver writes). Such rows are computed again and listed in the resume notes.

use std::collections::{HashMap, HashSet};
use std::path::Path;

use serde::{Deserialize, Serialize};

use crate::distance::PairRecord;
use crate::run_settings::{
    DistancesOptions, ShapeReport, PARTIAL_IDENTITY, PARTIAL_PAIRS, PREVIOUS_PARTIAL_IDENTITY, PREVIOUS_PARTIAL_PAIRS,
};

/// The pairs a resumed run took from earlier runs.
#[derive(Clone, Debug, Serialize, Deserialize)]
pub struct ResumeReport {
    /// Directed pairs taken from earlier files (not computed by this run).
    pub pairs: usize,
    /// One line per earlier pairs file found in the output folder: how many of its rows were
    /// taken, or why none were.
    pub sources: Vec<String>,
}

/// What a run's pairs depend on: the version and the executable, the solver and conformal-map
/// settings, and per input the file's content and resolved markers. Written before the first pair beside
/// [`PARTIAL_PAIRS`] (as [`PARTIAL_IDENTITY`]) and into `report.json` (`resume_key`), so that a
/// resumed run reuses exactly the rows whose two shapes and settings are unchanged (a directed
/// pair's result depends on nothing else: not on the other files, the thread count or
/// `symmetrize`).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct RunIdentity {
    pub shapespace_version: String,
    /// SHA-256 of the running executable ([`build_identity`]): the version string alone does
    /// not change with the code, and a pair's bits depend on it. None when the executable cannot
    /// be read (its pairs are then never taken).
    pub build: Option<String>,
    /// SHA-256 (hex) of the debug form of the solver parameters, `warm_start` and the conformal
    /// map's parameters.
    pub settings: String,
    pub inputs: Vec<InputIdentity>,
}

/// One input of a [`RunIdentity`].
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct InputIdentity {
    pub name: String,
    /// The file's SHA-256 and its resolved markers (`SHA:CENTER:BOUNDARY`, the markers as in a
    /// marker file); None for a file that failed to prepare.
    pub key: Option<String>,
}

/// SHA-256 of the running executable, computed once per process (~0.1 s for a 50 MB test
/// binary); None when it cannot be read. Two runs with equal identities ran the same machine
/// code; the dynamically linked C library (libm's `exp`, `atan2`, ...) is not covered, so a
/// folder moved to another machine should not be resumed there.
pub fn build_identity() -> Option<String> {
    static BUILD: std::sync::OnceLock<Option<String>> = std::sync::OnceLock::new();
    BUILD
        .get_or_init(|| {
            let exe = std::env::current_exe().ok()?;
            std::fs::read(exe).ok().map(|bytes| sha256_hex(&bytes))
        })
        .clone()
}

/// SHA-256 of `bytes`, lower-case hex.
pub(crate) fn sha256_hex(bytes: &[u8]) -> String {
    use sha2::Digest;
    sha2::Sha256::digest(bytes).iter().map(|b| format!("{b:02x}")).collect()
}

/// The columns of `pairs.csv` and of the partial pairs files: those of [`PairRecord`], then
/// `check` ([`row_check`]).
pub const PAIRS_HEADER: [&str; 11] = [
    "a",
    "b",
    "distance",
    "cost",
    "iterations",
    "max_mass_error",
    "seconds",
    "status",
    "evaluations",
    "dual_cost",
    "check",
];

/// The fields of `record` as `pairs.csv` writes them (the columns of [`PAIRS_HEADER`] but the
/// last; floats in their shortest round-trip form, NaN as `NaN`).
fn record_fields(record: &PairRecord) -> Vec<String> {
    let mut w = csv::WriterBuilder::new().has_headers(false).from_writer(Vec::new());
    // (serializing strings and numbers into memory cannot fail)
    w.serialize(record).expect("a PairRecord serializes");
    let bytes = w.into_inner().expect("writing into memory");
    let row = csv::ReaderBuilder::new()
        .has_headers(false)
        .from_reader(bytes.as_slice())
        .records()
        .next()
        .expect("one row")
        .expect("a row just written");
    row.iter().map(str::to_string).collect()
}

/// The row of `pairs.csv` for `record` in a run of `identity`: its fields and its check (empty
/// when one of its shapes has no key: a file that failed to prepare, whose rows are never taken).
pub(crate) fn pair_row(identity: &RunIdentity, record: &PairRecord) -> Vec<String> {
    let mut fields = record_fields(record);
    let fields_ref: Vec<&str> = fields.iter().map(String::as_str).collect();
    let check = row_check(identity, &fields_ref).unwrap_or_default();
    fields.push(check);
    fields
}

/// The check of a pairs row of a run of `identity` whose fields (the [`PAIRS_HEADER`] columns
/// but `check`, as written) are `fields`: the first 16 hex digits of the SHA-256 of the
/// settings, the build, the keys of the row's two inputs (named by its first two fields) and the
/// fields. None when a name has no key. It detects a changed row, not a forged one (anyone can
/// compute it).
pub fn row_check(identity: &RunIdentity, fields: &[&str]) -> Option<String> {
    let key = |name: &str| {
        identity
            .inputs
            .iter()
            .find(|input| input.name == name)
            .and_then(|input| input.key.as_deref())
    };
    let (a, b) = (key(fields.first()?)?, key(fields.get(1)?)?);
    let mut text = format!(
        "{}\u{1e}{}\u{1e}{a}\u{1e}{b}",
        identity.settings,
        identity.build.as_deref().unwrap_or("")
    );
    for field in fields {
        text.push('\u{1e}');
        text.push_str(field);
    }
    Some(sha256_hex(text.as_bytes())[..16].to_string())
}

/// Why the values of a pairs row cannot be those of a computation, if they cannot: a converged
/// pair has a finite distance >= 0 equal to the square root of its finite cost, a finite dual
/// cost and a mass error >= 0; a pair that did not converge (status `failed: ...`, `iteration
/// cap...`, `stalled...`, `time limit...`) has no distance; seconds are finite and >= 0; any
/// other status is unknown.
pub(crate) fn invalid_values(r: &PairRecord) -> Option<String> {
    let non_negative = |x: f64| x.is_finite() && x >= 0.0;
    if !non_negative(r.seconds) {
        return Some(format!("seconds {} (must be finite and >= 0)", r.seconds));
    }
    if r.status.starts_with("converged") {
        if !non_negative(r.distance) {
            return Some(format!("distance {} (must be finite and >= 0)", r.distance));
        }
        if !r.cost.is_finite() || r.distance != r.cost.max(0.0).sqrt() {
            return Some(format!(
                "distance {} is not the square root of the cost {}",
                r.distance, r.cost
            ));
        }
        if !non_negative(r.max_mass_error) || !r.dual_cost.is_finite() {
            return Some(format!(
                "mass error {} and dual cost {} (must be finite, the error >= 0)",
                r.max_mass_error, r.dual_cost
            ));
        }
        None
    } else if ["failed: ", "iteration cap", "stalled", "time limit"]
        .iter()
        .any(|s| r.status.starts_with(s))
    {
        (!r.distance.is_nan()).then(|| format!("distance {} for a pair that did not converge", r.distance))
    } else {
        Some(format!("unknown status {:?}", r.status))
    }
}

/// An earlier run's pairs file in the output folder and where its [`RunIdentity`] is: a
/// finished run's `pairs.csv` (`report.json`'s `resume_key`), a stopped run's
/// [`PARTIAL_PAIRS`], and one moved aside by a restart ([`PREVIOUS_PARTIAL_PAIRS`]).
const EARLIER_PAIRS: [(&str, &str, bool); 3] = [
    ("pairs.csv", "report.json", true),
    (PARTIAL_PAIRS, PARTIAL_IDENTITY, false),
    (PREVIOUS_PARTIAL_PAIRS, PREVIOUS_PARTIAL_IDENTITY, false),
];

/// The rows of the earlier runs' pairs files in `out` ([`EARLIER_PAIRS`]) that this run can
/// take: those whose version and settings equal `identity`'s and whose two shapes have the key
/// of a current input (the same file content and markers, whatever its name now), keyed by the
/// current (source, target) among `needed` (a row serves every current pair of files with those
/// keys), each with the current names and indices. The first file to give a pair wins (all of them give the same record). Rows that are not intact
/// (module docs) are not taken and are listed in that file's line. Failed pairs
/// are taken (the same shapes and settings fail the same way), except internal errors (panics:
/// bugs) and pairs stopped at their time limit, which are computed again. Also returns
/// one line per file found: how many rows it gave, or why it gave none. A last line without its
/// newline (a run killed in the middle of a row) is not read.
pub(crate) fn earlier_pairs(
    out: &Path,
    identity: &RunIdentity,
    needed: &HashSet<(usize, usize)>,
) -> (HashMap<(usize, usize), PairRecord>, Vec<String>) {
    let mut by_key: HashMap<&str, Vec<usize>> = HashMap::new();
    for (i, input) in identity.inputs.iter().enumerate() {
        if let Some(key) = &input.key {
            by_key.entry(key).or_default().push(i);
        }
    }
    let mut known = HashMap::new();
    let mut notes = Vec::new();
    for (pairs_name, identity_name, in_report) in EARLIER_PAIRS {
        let pairs_path = out.join(pairs_name);
        let not_used = |why: String| format!("{}: not used: {why}", pairs_path.display());
        // (bytes: a last row cut inside a multi-byte character must not make the whole file
        // unreadable; it is dropped below with any other unfinished last row)
        let mut text = match std::fs::read(&pairs_path) {
            Ok(text) => text,
            Err(e) if e.kind() == std::io::ErrorKind::NotFound => continue,
            Err(e) => {
                notes.push(not_used(e.to_string()));
                continue;
            }
        };
        let earlier = match compatible_earlier_run(&out.join(identity_name), in_report, identity) {
            Ok(earlier) => earlier,
            Err(why) => {
                notes.push(not_used(why));
                continue;
            }
        };
        let incomplete = text.last().is_some_and(|&b| b != b'\n');
        if incomplete {
            text.truncate(text.iter().rposition(|&b| b == b'\n').map_or(0, |k| k + 1));
        }
        let mut tally = RowTally {
            unreadable: usize::from(incomplete),
            ..RowTally::default()
        };
        let rows = EarlierRows {
            earlier: &earlier,
            identity,
            by_key: &by_key,
            needed,
        };
        rows.take(&text, &mut known, &mut tally);
        notes.push(tally.note(&pairs_path));
    }
    (known, notes)
}

/// The identity of the earlier run written to `identity_path` (the report's `resume_key` when
/// `in_report`), when its version, build and settings are this run's; else why not.
fn compatible_earlier_run(
    identity_path: &Path,
    in_report: bool,
    identity: &RunIdentity,
) -> Result<RunIdentity, String> {
    #[derive(Deserialize)]
    struct Report {
        resume_key: Option<RunIdentity>,
    }
    let earlier = std::fs::read_to_string(identity_path)
        .map_err(|e| e.to_string())
        .and_then(|json| {
            if in_report {
                serde_json::from_str::<Report>(&json).map(|r| r.resume_key)
            } else {
                serde_json::from_str::<RunIdentity>(&json).map(Some)
            }
            .map_err(|e| e.to_string())
        })
        .map_err(|e| format!("{}: {e}", identity_path.display()))?
        .ok_or_else(|| format!("{} has no resume_key", identity_path.display()))?;
    if earlier.shapespace_version != identity.shapespace_version {
        return Err(format!(
            "written by shapespace {} (this is {})",
            earlier.shapespace_version, identity.shapespace_version
        ));
    }
    if earlier.build.is_none() || earlier.build != identity.build {
        return Err("written by another build of shapespace (or one whose executable could not be read)".into());
    }
    if earlier.settings != identity.settings {
        return Err("computed with other solver or conformal-map settings (tolerance, iteration cap, ...)".into());
    }
    Ok(earlier)
}

/// What one earlier pairs file gave: rows read, rows unreadable or incomplete, pairs taken,
/// internal errors and time-limited pairs left to compute again, invalid rows (with why).
#[derive(Default)]
struct RowTally {
    rows: usize,
    unreadable: usize,
    taken: usize,
    panicked: usize,
    timed_out: usize,
    invalid: Vec<String>,
}

impl RowTally {
    /// The file's line for the run's notes.
    fn note(&self, pairs_path: &Path) -> String {
        let mut skipped = String::new();
        if self.unreadable > 0 {
            skipped += &format!(", {} unreadable or incomplete skipped", self.unreadable);
        }
        if self.panicked > 0 {
            skipped += &format!(", {} internal errors computed again", self.panicked);
        }
        if self.timed_out > 0 {
            skipped += &format!(", {} stopped at their time limit computed again", self.timed_out);
        }
        if !self.invalid.is_empty() {
            skipped += &format!(
                ", {} invalid rows computed again: {}",
                self.invalid.len(),
                self.invalid.join("; ")
            );
        }
        format!(
            "{}: {} pairs taken from {} rows{skipped}",
            pairs_path.display(),
            self.taken,
            self.rows
        )
    }
}

/// The rows of a compatible earlier run's pairs file, taken for this run's pairs.
struct EarlierRows<'a> {
    earlier: &'a RunIdentity,
    identity: &'a RunIdentity,
    /// current inputs by shape key
    by_key: &'a HashMap<&'a str, Vec<usize>>,
    needed: &'a HashSet<(usize, usize)>,
}

impl EarlierRows<'_> {
    /// Takes the intact rows of `text` (complete lines of a pairs CSV) into `known` for every
    /// needed current pair of files with the rows' shape keys, counting in `tally`.
    fn take(&self, text: &[u8], known: &mut HashMap<(usize, usize), PairRecord>, tally: &mut RowTally) {
        let earlier_key: HashMap<&str, &str> = self
            .earlier
            .inputs
            .iter()
            .filter_map(|input| input.key.as_deref().map(|k| (input.name.as_str(), k)))
            .collect();
        let mut reader = csv::Reader::from_reader(text);
        let headers = reader.headers().cloned().unwrap_or_default();
        let check_column = headers.iter().position(|h| h == "check");
        for row in reader.records() {
            let Some((row, record)) = row
                .ok()
                .and_then(|row| row.deserialize::<PairRecord>(Some(&headers)).ok().map(|r| (row, r)))
            else {
                tally.unreadable += 1;
                continue;
            };
            tally.rows += 1;
            if crate::distance::is_internal_error(&record.status) {
                tally.panicked += 1;
                continue;
            }
            if crate::distance::is_time_limit(&record.status) {
                tally.timed_out += 1;
                continue;
            }
            let fields: Vec<&str> = row
                .iter()
                .enumerate()
                .filter(|&(i, _)| Some(i) != check_column)
                .map(|(_, f)| f)
                .collect();
            // (a row of a file that failed to prepare has no check and is never taken)
            let Some(expected) = row_check(self.earlier, &fields) else {
                continue;
            };
            let line = row.position().map_or(0, |p| p.line());
            let why = if check_column.and_then(|c| row.get(c)) != Some(expected.as_str()) {
                Some("does not match its check (changed after it was written)".to_string())
            } else {
                invalid_values(&record)
            };
            if let Some(why) = why {
                tally
                    .invalid
                    .push(format!("line {line} ({} -> {}): {why}", record.a, record.b));
                continue;
            }
            let current = |name: &str| {
                earlier_key
                    .get(name)
                    .and_then(|k| self.by_key.get(k))
                    .map_or(&[][..], |v| v)
            };
            for &s in current(&record.a) {
                for &t in current(&record.b) {
                    if s != t && self.needed.contains(&(s, t)) && !known.contains_key(&(s, t)) {
                        let current = PairRecord {
                            a: self.identity.inputs[s].name.clone(),
                            b: self.identity.inputs[t].name.clone(),
                            source: s,
                            target: t,
                            ..record.clone()
                        };
                        known.insert((s, t), current);
                        tally.taken += 1;
                    }
                }
            }
        }
    }
}

/// The [`RunIdentity`] of a run with `options` over the prepared `inputs`.
pub(crate) fn run_identity(options: &DistancesOptions, inputs: &[ShapeReport]) -> RunIdentity {
    // (a deadline is a moment, not a setting: a pair stopped by it is computed again anyway)
    let newton = shapespace_omt::NewtonParams {
        deadline: None,
        ..options.pairwise.newton.clone()
    };
    let settings = format!(
        "{newton:?}|warm_start {}|{:?}{}{}{}",
        options.pairwise.warm_start,
        options.disk_map,
        // (each absent in its default, so the settings of earlier runs keep their hash)
        match options.pairwise.invariance {
            crate::invariance::Invariance::Fixed => String::new(),
            other => format!("|{other:?}"),
        },
        options
            .target_points
            .map(|n| format!("|target_points {n}"))
            .unwrap_or_default(),
        options
            .source_faces
            .map(|n| format!("|source_faces {n}"))
            .unwrap_or_default()
    );
    RunIdentity {
        shapespace_version: env!("CARGO_PKG_VERSION").to_string(),
        build: build_identity(),
        settings: sha256_hex(settings.as_bytes()),
        inputs: inputs
            .iter()
            .map(|input| InputIdentity {
                name: input.name.clone(),
                key: match (&input.sha256, &input.markers, input.ok) {
                    (Some(sha), Some(m), true) => serde_json::to_string(&m.center)
                        .ok()
                        .map(|center| format!("{sha}:{center}:{}", m.boundary)),
                    // a closed surface on the sphere: its normalization (markers) is in the
                    // method's name
                    (Some(sha), None, true) => input.conformal_method.as_ref().map(|m| format!("{sha}:{m}")),
                    _ => None,
                },
            })
            .collect(),
    }
}
