//! The files a distances run keeps in its output folder besides its results: the lock that
//! keeps two runs out of one folder ([`lock_output_folder`]), the resume checkpoint appended
//! pair by pair (`PartialPairs`), and `pairs.csv` ([`write_pairs_csv`]).

use std::path::{Path, PathBuf};

use shapespace_geometry::io::AtomicFile;

use crate::distance::PairRecord;
use crate::error::AnalysisError;
use crate::resume::{pair_row, RunIdentity, PAIRS_HEADER};

/// [`PARTIAL_PAIRS`], appended to from the worker threads: its writer, or after the first
/// failed write, that failure; `failed` is set with it (the run's stop signal).
pub(super) struct PartialPairs {
    path: PathBuf,
    identity: RunIdentity,
    writer: std::sync::Mutex<Result<csv::Writer<std::fs::File>, AnalysisError>>,
    pub(super) failed: std::sync::atomic::AtomicBool,
}

impl PartialPairs {
    /// Creates the file (a new one: never an existing file or a symbolic link, which the
    /// caller has moved aside); an error here is an output error of the run.
    pub(super) fn create(path: PathBuf, identity: RunIdentity) -> Result<Self, AnalysisError> {
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
    pub(super) fn append(&self, record: &PairRecord) {
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
    pub(super) fn finish(self) -> Result<(), AnalysisError> {
        let state = self
            .writer
            .into_inner()
            .unwrap_or_else(|poisoned| poisoned.into_inner());
        state.map(drop)
    }
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
pub(super) fn remove_if_present(path: &Path) -> Result<(), AnalysisError> {
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
    use crate::run_settings::PARTIAL_PAIRS;

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
