//! The side-by-side table of a `register-bench` run and its peer from their CSV files, for a
//! peer run apart (e.g. one `scripts/pyfmaps_bench.py` process per class, in parallel):
//! `cargo run --release -p shapespace-tools --bin peer_table -- OUT/results.csv PEER.csv...`
//! prints what `register-bench --peer` writes to `comparison.md`.
use std::path::PathBuf;
use std::process::ExitCode;

use shapespace_analysis::registration::bench::{peer_comparison, read_rows, BenchRow, PeerRow};

fn main() -> ExitCode {
    let args: Vec<PathBuf> = std::env::args_os().skip(1).map(PathBuf::from).collect();
    if args.len() < 2 {
        eprintln!("usage: peer_table RESULTS.csv PEER.csv...");
        return ExitCode::from(2);
    }
    let rows: Vec<BenchRow> = match read_rows(&args[0]) {
        Ok(r) => r,
        Err(e) => {
            eprintln!("peer_table: {e}");
            return ExitCode::from(2);
        }
    };
    let mut peer: Vec<PeerRow> = Vec::new();
    for p in &args[1..] {
        match read_rows(p) {
            Ok(r) => peer.extend(r),
            Err(e) => {
                eprintln!("peer_table: {e}");
                return ExitCode::from(2);
            }
        }
    }
    print!("{}", peer_comparison(&rows, &peer));
    ExitCode::SUCCESS
}
