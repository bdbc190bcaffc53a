//! Benchmark of the damped Newton OT solver: prints a table (no criterion: one solve per case).
//!
//! `cargo bench -p shapespace-omt --bench ot_bench [-- N1 N2 ...] [--coarse-to-fine] [--no-contrast] [--split]`
//! (`--split` solves again and prints the linear-solve time split: assembly/symbolic/numeric).
//!
//! Cases: N uniform random points in the unit disk (fixed seed, equal masses), uniform density
//! on `SourceMeasure::unit_disk(512)` (default N = 1e3, 1e4, 1e5); and N = 1e4 with a 100×
//! contrast density (density 100 on the half-disk x > 0, 1 elsewhere, on a 30-ring triangulated
//! disk), solved with the default start (coarse-to-fine for this contrast), from the Voronoi start
//! with the adaptive density continuation, and with mass continuation (ratio 2, 400 steps per
//! stage). Columns: Newton steps, mean seconds per step split into diagram / integration / solve
//! (line-search trials included), seconds for the start, total seconds, final max relative mass
//! error, stop reason.

use shapespace_omt::newton::IterationRecord;
use shapespace_omt::synthetic::{disk_rings_measure, random_disk_points};
use shapespace_omt::{solve_ot, NewtonParams, SourceMeasure, StartStrategy};

fn run(name: &str, measure: &SourceMeasure, n: usize, params: &NewtonParams) {
    let points = random_disk_points(n, 2024);
    let masses = vec![1.0; n];
    match solve_ot(measure, &points, &masses, params) {
        Ok(sol) => {
            let steps = sol.log.len().max(1) as f64;
            let mean = |f: fn(&IterationRecord) -> f64| sol.log.iter().map(f).sum::<f64>() / steps;
            println!(
                "| {name:<24} | {n:>8} | {:>5} | {:>9.4} | {:>11.4} | {:>8.4} | {:>8.3} | {:>8.2} | {:>9.2e} | {} |",
                sol.iterations,
                mean(|r| r.t_diagram),
                mean(|r| r.t_integration),
                mean(|r| r.t_solve),
                sol.t_start,
                sol.t_total,
                sol.max_relative_error,
                sol.stop
            );
        }
        Err(e) => println!("| {name:<24} | {n:>8} | error: {e} |"),
    }
}

fn solve_split(n: usize, measure: &SourceMeasure, params: &NewtonParams) {
    let points = random_disk_points(n, 2024);
    if let Ok(sol) = solve_ot(measure, &points, &vec![1.0; n], params) {
        println!(
            "  N = {n}: solve split over the final stage: assembly {:.3} s, symbolic {:.3} s ({} factorizations, {} orderings), numeric+solve {:.3} s",
            sol.t_assembly, sol.t_symbolic, sol.symbolic_factorizations, sol.orderings, sol.t_numeric
        );
    }
}

fn main() {
    let args: Vec<String> = std::env::args().skip(1).filter(|a| a != "--bench").collect();
    let coarse_to_fine = args.iter().any(|a| a == "--coarse-to-fine");
    let contrast_case = !args.iter().any(|a| a == "--no-contrast");
    let mut sizes: Vec<usize> = args
        .iter()
        .filter_map(|a| a.parse::<f64>().ok())
        .map(|x| x as usize)
        .collect();
    if sizes.is_empty() {
        sizes = vec![1_000, 10_000, 100_000];
    }
    let params = NewtonParams {
        start_strategy: if coarse_to_fine {
            StartStrategy::CoarseToFine
        } else {
            StartStrategy::Auto
        },
        ..NewtonParams::default()
    };
    println!(
        "threads: {}, coarse_to_fine: {coarse_to_fine}",
        rayon::current_num_threads()
    );
    println!("| case                     |        N | steps | diagram/s | integrate/s |  solve/s |  start/s |  total/s | max error | stop |");
    println!("|--------------------------|---------:|------:|----------:|------------:|---------:|---------:|---------:|----------:|------|");
    let uniform = SourceMeasure::unit_disk(512).expect("unit disk");
    for &n in &sizes {
        run("uniform disk", &uniform, n, &params);
    }
    if args.iter().any(|a| a == "--split") {
        for &n in &sizes {
            solve_split(n, &uniform, &params);
        }
    }
    if contrast_case {
        let contrast = disk_rings_measure(30, |x| if x[0] > 0.0 { 100.0 } else { 1.0 }).expect("valid disk");
        run("100x contrast (default)", &contrast, 10_000, &params);
        let continuation = NewtonParams {
            start_strategy: StartStrategy::Voronoi,
            ..params.clone()
        };
        run("100x, Voronoi + density c.", &contrast, 10_000, &continuation);
        let mass = NewtonParams {
            mass_continuation: Some(2.0),
            max_iterations: 400,
            ..params.clone()
        };
        run("100x, mass continuation", &contrast, 10_000, &mass);
    }
}
