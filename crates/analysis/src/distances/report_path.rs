//! Paths in the JSON reports. serde serializes a `PathBuf` only when it is valid UTF-8, so one
//! input or output named otherwise would fail a whole report after all the work was done; the
//! reports write paths as `Path::to_string_lossy` gives them instead (invalid bytes become
//! U+FFFD), as the CLI's messages show them.
//!
//! Use with `#[serde(serialize_with = "crate::report_path::one")]` (or `many`).

use std::path::{Path, PathBuf};

use serde::Serializer;

/// A path as a (lossy) UTF-8 string.
pub fn one<S: Serializer>(path: &Path, serializer: S) -> Result<S::Ok, S::Error> {
    serializer.serialize_str(&path.to_string_lossy())
}

/// A list of paths as (lossy) UTF-8 strings.
pub fn many<S: Serializer>(paths: &[PathBuf], serializer: S) -> Result<S::Ok, S::Error> {
    serializer.collect_seq(paths.iter().map(|p| p.to_string_lossy()))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[derive(serde::Serialize)]
    struct Report {
        #[serde(serialize_with = "one")]
        path: PathBuf,
        #[serde(serialize_with = "many")]
        files: Vec<PathBuf>,
    }

    #[test]
    fn non_utf8_paths_serialize_lossily() {
        #[cfg(unix)]
        let odd = {
            use std::os::unix::ffi::OsStrExt;
            PathBuf::from(std::ffi::OsStr::from_bytes(b"dir/x\xff.obj"))
        };
        #[cfg(not(unix))]
        let odd = PathBuf::from("dir/x\u{fffd}.obj");
        // serde's own PathBuf serialization refuses it
        #[cfg(unix)]
        assert!(serde_json::to_string(&odd).is_err());
        let report = Report {
            path: odd.clone(),
            files: vec![PathBuf::from("a b/c,\"d\".csv"), odd],
        };
        assert_eq!(
            serde_json::to_string(&report).unwrap(),
            r#"{"path":"dir/x�.obj","files":["a b/c,\"d\".csv","dir/x�.obj"]}"#
        );
    }
}
