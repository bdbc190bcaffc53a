//! Benchmark of the main job: pairwise conformal Wasserstein distances among the
//! first N bundled faces (default 30, i.e. 435 pairs), printing a table of the stages.
//!
//! `cargo bench -p shapespace-tools --bench distance_bench -- [N] [THREADS]`
//! (THREADS default 2; env WARM=1 warm-starts each pair from the
//! previous one with the same target; env FLUX takes the Newton evaluations' masses by the flux form).
//! Outputs go to `out/distance_bench/`.

use std::path::PathBuf;

use shapespace_analysis::pipeline::{run_distances, DistancesOptions};
use shapespace_analysis::stats::summarize;

fn main() -> Result<(), Box<dyn std::error::Error>> {
    shapespace_tools::at_repository_root();
    let mut args = std::env::args().skip(1).filter(|a| a != "--bench");
    let n: usize = args.next().map(|s| s.parse()).transpose()?.unwrap_or(30);
    let threads: usize = args.next().map(|s| s.parse()).transpose()?.unwrap_or(2);
    rayon::ThreadPoolBuilder::new().num_threads(threads).build_global()?;
    let mut files: Vec<PathBuf> = std::fs::read_dir("datasets/faces")?
        .filter_map(|e| e.ok().map(|e| e.path()))
        .filter(|p| p.extension().is_some_and(|x| x == "obj"))
        .collect();
    files.sort();
    files.truncate(n);
    let out = PathBuf::from("out/distance_bench");
    let mut options = DistancesOptions::default();
    if std::env::var("WARM").is_ok() {
        options.pairwise.warm_start = true;
    }
    // (comparisons: env FLUX takes the Newton evaluations' masses by the flux form)
    options.pairwise.newton.flux_masses = std::env::var("FLUX").is_ok();
    let run = run_distances(&files, &out, &options, &|_, _, _| {})?;
    let r = &run.report;
    let ok: Vec<_> = run.pairs.iter().filter(|p| p.distance.is_finite()).collect();
    let seconds: Vec<f64> = ok.iter().map(|p| p.seconds).collect();
    let iterations: Vec<f64> = ok.iter().map(|p| p.iterations as f64).collect();
    let (s, it) = (summarize(&seconds), summarize(&iterations));
    // the pairs' seconds summed over the threads: the wall time of a perfectly balanced run
    let balanced = r.timings.pairs_cpu / r.threads.max(1) as f64;
    println!("| faces | pairs | failed | threads | prepare s | pairs s (wall) | pairs s summed / threads | pair s median / max | Newton its median / max | total s |");
    println!("|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|");
    println!(
        "| {} | {} | {} | {} | {:.1} | {:.1} | {balanced:.1} | {:.2} / {:.2} | {} / {} | {:.1} |",
        files.len(),
        r.pairs_computed,
        r.pairs_failed,
        r.threads,
        r.timings.prepare_wall,
        r.timings.pairs_wall,
        s.median.unwrap_or(f64::NAN),
        s.max.unwrap_or(f64::NAN),
        it.median.unwrap_or(f64::NAN),
        it.max.unwrap_or(f64::NAN),
        r.timings.total
    );
    Ok(())
}
