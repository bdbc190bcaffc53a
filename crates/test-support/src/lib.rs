//! Where the tests and examples find data that the repository does not carry.
//!
//! The public meshes the tests read (libigl's camel head and face, geometry-central's cat
//! head, the TOSCA poses, GOAST's plate, …) are not copied into the repository; they are read
//! from a folder of shared datasets with the upstream layout (`libigl_tutorial_data/`,
//! `geometry_central_assets/`, `tosca/`, `goast/`, `common_3d_test_models/`, `ict_facekit/`):
//!
//! * the environment variable `SHAPESPACE_DATA`, when set (a relative path is taken from the
//!   current directory, which for `cargo test` is the crate's folder);
//! * otherwise `../shared/datasets` beside the workspace root.
//!
//! A test whose data is absent is skipped *loudly*: [`shared_file`] and [`shared_dir`] print a
//! `SKIPPED` line to stderr naming the missing path and return `None`, and the test returns.
//! The repository's own data (`datasets/faces`, `datasets/poses`, `tests/`) is found with
//! [`workspace_root`].

use std::path::{Path, PathBuf};

/// The environment variable that names the shared datasets folder.
pub const DATA_ENV: &str = "SHAPESPACE_DATA";

/// The workspace root (the folder of the top-level `Cargo.toml`).
pub fn workspace_root() -> PathBuf {
    Path::new(concat!(env!("CARGO_MANIFEST_DIR"), "/../..")).to_path_buf()
}

/// A path relative to the workspace root.
pub fn repo(rel: &str) -> PathBuf {
    workspace_root().join(rel)
}

/// The shared datasets folder: `$SHAPESPACE_DATA`, else `../shared/datasets` beside the
/// workspace root. It may not exist; [`shared_dir`] and [`shared_file`] check.
pub fn shared_datasets_dir() -> PathBuf {
    match std::env::var_os(DATA_ENV) {
        Some(dir) if !dir.is_empty() => PathBuf::from(dir),
        _ => Path::new(concat!(env!("CARGO_MANIFEST_DIR"), "/../../../shared/datasets")).to_path_buf(),
    }
}

fn skip(path: &Path, what: &str) {
    eprintln!(
        "SKIPPED: {what} {} not found (set {DATA_ENV} to the shared datasets folder, default ../shared/datasets beside the workspace)",
        path.display()
    );
}

/// The shared datasets folder, or `None` after a `SKIPPED` line on stderr when it is absent.
pub fn shared_root() -> Option<PathBuf> {
    let dir = shared_datasets_dir();
    if dir.is_dir() {
        Some(dir)
    } else {
        skip(&dir, "shared datasets folder");
        None
    }
}

/// A folder under the shared datasets folder (`rel` as in the upstream layout, e.g. `"tosca"`),
/// or `None` after a `SKIPPED` line on stderr naming it.
pub fn shared_dir(rel: &str) -> Option<PathBuf> {
    let dir = shared_datasets_dir().join(rel);
    if dir.is_dir() {
        Some(dir)
    } else {
        skip(&dir, "folder");
        None
    }
}

/// A file under the shared datasets folder (e.g. `"libigl_tutorial_data/camelhead.off"`), or
/// `None` after a `SKIPPED` line on stderr naming it.
pub fn shared_file(rel: &str) -> Option<PathBuf> {
    let file = shared_datasets_dir().join(rel);
    if file.is_file() {
        Some(file)
    } else {
        skip(&file, "file");
        None
    }
}

/// Every file of `rels` under the shared datasets folder, or `None` after a `SKIPPED` line for
/// each one that is missing.
pub fn shared_files(rels: &[&str]) -> Option<Vec<PathBuf>> {
    let found: Vec<Option<PathBuf>> = rels.iter().map(|r| shared_file(r)).collect();
    found.into_iter().collect()
}

/// The public disk-topology meshes the tests map (formerly copied into the repository), by a
/// short name and their path in the shared datasets folder.
pub const PUBLIC_DISKS: [(&str, &str); 7] = [
    ("camelhead", "libigl_tutorial_data/camelhead.off"),
    ("lion", "libigl_tutorial_data/lion.off"),
    ("face", "libigl_tutorial_data/face.obj"),
    ("woody", "common_3d_test_models/woody.obj"),
    ("cat_head", "geometry_central_assets/cat_head.obj"),
    ("plate121", "goast/plate/plate121.ply"),
    ("plate121_rolledA", "goast/plate/plate121_rolledA.ply"),
];

/// The public disk whose conformal image double precision cannot hold (the alligator's tail).
pub const BEYOND_F64_DISK: &str = "common_3d_test_models/alligator.obj";

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_workspace_root_holds_the_workspace_manifest() {
        assert!(workspace_root().join("Cargo.toml").is_file());
        assert!(repo("datasets/faces").is_dir());
    }
}
