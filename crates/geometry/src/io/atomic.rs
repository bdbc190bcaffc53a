//! Output files written atomically: the bytes go to a temporary file in the destination's
//! folder, which is flushed, synced to the disk and then renamed over the destination. A reader
//! (or a later run) sees the previous complete file or the new complete file, never a cut one:
//! a full disk, a killed process or an error half way leaves the previous file as it was and
//! removes the temporary one (except after a kill, which leaves a `.shapespace-tmp.PID.N.NAME`
//! file that nothing reads).
//!
//! The destination is never written through a symbolic link: a symlink at the destination is
//! refused ([`refuse_symlink`]), so that `DIR/distances.csv → elsewhere` cannot redirect an
//! output onto another file.

use std::fs::File;
use std::io::{self, BufWriter, Write};
use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicU64, Ordering};

/// Refuses `path` if it is a symbolic link (dangling or not); a missing path is fine.
pub fn refuse_symlink(path: &Path) -> io::Result<()> {
    match std::fs::symlink_metadata(path) {
        Ok(meta) if meta.file_type().is_symlink() => Err(io::Error::new(
            io::ErrorKind::InvalidInput,
            "is a symbolic link; outputs are not written through links (remove it or name another file)",
        )),
        _ => Ok(()),
    }
}

/// The temporary file beside `path`: `.shapespace-tmp.PID.N.NAME` in the same folder (so that
/// the rename stays on one file system), unique within the process, with the destination's
/// extension (a plotting backend picks the image format from it).
fn temp_path(path: &Path) -> io::Result<PathBuf> {
    static COUNTER: AtomicU64 = AtomicU64::new(0);
    let name = path
        .file_name()
        .ok_or_else(|| io::Error::new(io::ErrorKind::InvalidInput, "not a file name"))?;
    let k = COUNTER.fetch_add(1, Ordering::Relaxed);
    let mut temp = std::ffi::OsString::from(format!(".shapespace-tmp.{}.{k}.", std::process::id()));
    temp.push(name);
    Ok(path.with_file_name(temp))
}

/// Creates the temporary file for `path` (never an existing file: `create_new`).
fn create_temp(path: &Path) -> io::Result<(PathBuf, File)> {
    refuse_symlink(path)?;
    let temp = temp_path(path)?;
    let file = std::fs::OpenOptions::new().write(true).create_new(true).open(&temp)?;
    Ok((temp, file))
}

/// Syncs `temp` and renames it to `path`, then syncs the folder (best effort: not every file
/// system supports syncing a folder). Removes `temp` on failure.
fn finish(temp: &Path, file: File, path: &Path) -> io::Result<()> {
    let result = file
        .sync_all()
        .and_then(|()| refuse_symlink(path))
        .and_then(|()| std::fs::rename(temp, path));
    if result.is_err() {
        let _ = std::fs::remove_file(temp);
    }
    result?;
    let parent = path
        .parent()
        .filter(|p| !p.as_os_str().is_empty())
        .unwrap_or(Path::new("."));
    if let Ok(dir) = File::open(parent) {
        let _ = dir.sync_all();
    }
    Ok(())
}

/// A file being written atomically: [`Write`] into a buffered temporary file beside the
/// destination; [`AtomicFile::commit`] puts it in place. Dropped without a commit (an error on
/// the way), it removes the temporary file and leaves the destination as it was.
pub struct AtomicFile {
    path: PathBuf,
    temp: PathBuf,
    writer: Option<BufWriter<File>>,
}

impl AtomicFile {
    /// Starts writing `path` (refused if `path` is a symbolic link).
    pub fn create(path: &Path) -> io::Result<Self> {
        let (temp, file) = create_temp(path)?;
        Ok(Self {
            path: path.to_path_buf(),
            temp,
            writer: Some(BufWriter::new(file)),
        })
    }

    /// The destination.
    pub fn path(&self) -> &Path {
        &self.path
    }

    /// Flushes and syncs the data and renames the temporary file to the destination.
    pub fn commit(mut self) -> io::Result<()> {
        let writer = self.writer.take().expect("an AtomicFile is committed once");
        let file = match writer.into_inner() {
            Ok(file) => file,
            Err(e) => {
                let _ = std::fs::remove_file(&self.temp);
                return Err(e.into_error());
            }
        };
        finish(&self.temp, file, &self.path)
    }
}

impl Write for AtomicFile {
    fn write(&mut self, buf: &[u8]) -> io::Result<usize> {
        self.writer.as_mut().expect("not committed").write(buf)
    }

    fn flush(&mut self) -> io::Result<()> {
        self.writer.as_mut().expect("not committed").flush()
    }
}

impl Drop for AtomicFile {
    fn drop(&mut self) {
        if self.writer.take().is_some() {
            let _ = std::fs::remove_file(&self.temp);
        }
    }
}

/// Writes `bytes` to `path` atomically.
pub fn write_atomically(path: &Path, bytes: &[u8]) -> io::Result<()> {
    let mut file = AtomicFile::create(path)?;
    file.write_all(bytes)?;
    file.commit()
}

/// Runs `fill` on a temporary path beside `path` (for writers that take a path, such as a
/// plotting backend), then syncs that file and renames it to `path`; I/O failures of these
/// steps go through `io_err`. On any error the temporary file is removed and `path` left as it
/// was.
pub fn replace_atomically<T, E>(
    path: &Path,
    fill: impl FnOnce(&Path) -> Result<T, E>,
    io_err: impl Fn(io::Error) -> E,
) -> Result<T, E> {
    let (temp, file) = create_temp(path).map_err(&io_err)?;
    drop(file);
    let value = match fill(&temp) {
        Ok(value) => value,
        Err(e) => {
            let _ = std::fs::remove_file(&temp);
            return Err(e);
        }
    };
    let file = match std::fs::OpenOptions::new().write(true).open(&temp) {
        Ok(file) => file,
        Err(e) => {
            let _ = std::fs::remove_file(&temp);
            return Err(io_err(e));
        }
    };
    finish(&temp, file, path).map_err(io_err)?;
    Ok(value)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn scratch(name: &str) -> PathBuf {
        let dir = std::env::temp_dir().join(format!("shapespace-atomic-{}-{name}", std::process::id()));
        let _ = std::fs::remove_dir_all(&dir);
        std::fs::create_dir_all(&dir).unwrap();
        dir
    }

    fn entries(dir: &Path) -> Vec<String> {
        let mut names: Vec<String> = std::fs::read_dir(dir)
            .unwrap()
            .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
            .collect();
        names.sort();
        names
    }

    /// A write that fails half way leaves the previous file whole and no temporary file.
    #[test]
    fn a_failed_write_keeps_the_previous_file() {
        let dir = scratch("failed");
        let path = dir.join("out.csv");
        write_atomically(&path, b"old complete\n").unwrap();
        let mut file = AtomicFile::create(&path).unwrap();
        file.write_all(b"new but cut").unwrap();
        drop(file);
        assert_eq!(std::fs::read(&path).unwrap(), b"old complete\n");
        let failed: Result<(), io::Error> = replace_atomically(
            &path,
            |temp| {
                std::fs::write(temp, b"partial")?;
                Err(io::Error::other("disk full"))
            },
            |e| e,
        );
        assert!(failed.is_err());
        assert_eq!(std::fs::read(&path).unwrap(), b"old complete\n");
        assert_eq!(entries(&dir), ["out.csv"]);
        write_atomically(&path, b"new\n").unwrap();
        assert_eq!(std::fs::read(&path).unwrap(), b"new\n");
        assert_eq!(entries(&dir), ["out.csv"]);
        std::fs::remove_dir_all(&dir).ok();
    }

    /// A symbolic link at the destination is refused and its target left alone.
    #[cfg(unix)]
    #[test]
    fn a_symlink_destination_is_refused() {
        let dir = scratch("symlink");
        let target = dir.join("elsewhere.txt");
        std::fs::write(&target, b"precious").unwrap();
        let link = dir.join("out.csv");
        std::os::unix::fs::symlink(&target, &link).unwrap();
        let e = write_atomically(&link, b"x").unwrap_err();
        assert!(e.to_string().contains("symbolic link"), "{e}");
        let e = replace_atomically(&link, |temp| std::fs::write(temp, b"x"), |e| e).unwrap_err();
        assert!(e.to_string().contains("symbolic link"), "{e}");
        assert_eq!(std::fs::read(&target).unwrap(), b"precious");
        assert!(std::fs::symlink_metadata(&link).unwrap().file_type().is_symlink());
        std::fs::remove_dir_all(&dir).ok();
    }
}
