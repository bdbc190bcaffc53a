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

/// The process's CPU time (user + system, all threads) in seconds, from /proc/self/stat
/// (clock ticks of 1/100 s); NaN where it cannot be read.
pub fn cpu_seconds() -> f64 {
    std::fs::read_to_string("/proc/self/stat")
        .ok()
        .and_then(|s| {
            // (the fields after the command name, which is in parentheses)
            let rest = &s[s.rfind(')')? + 2..];
            let f: Vec<&str> = rest.split_whitespace().collect();
            Some((f.get(11)?.parse::<f64>().ok()? + f.get(12)?.parse::<f64>().ok()?) / 100.0)
        })
        .unwrap_or(f64::NAN)
}
