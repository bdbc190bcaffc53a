//! Benchmarks and investigation probes of shapespace, outside the published crates and the
//! workspace's default members: `benches/` prints timing tables (`cargo bench -p
//! shapespace-tools --bench NAME`, README.md), `src/bin/` holds the probes that measured the
//! choices recorded in `docs/decisions/` (`cargo run --release -p shapespace-tools --bin NAME`).
//! This library is what they share.

pub mod crowding;
pub mod faces;
pub mod newton_log;
pub mod scans;

/// Makes the repository root the working directory: `cargo bench` starts a bench in its
/// package's folder, and the benches read `datasets/…` and take paths relative to the root.
pub fn at_repository_root() {
    let root = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("../..");
    if let Err(e) = std::env::set_current_dir(&root) {
        eprintln!("cannot enter the repository root {}: {e}", root.display());
        std::process::exit(2);
    }
}
