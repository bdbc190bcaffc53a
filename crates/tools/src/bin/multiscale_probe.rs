//! Probe: the coarse-to-fine start (`StartStrategy::CoarseToFine`) against the default start.
//! `multiscale_probe CASE N` with CASE = contrast (ot_bench's 100× half-disk) or uniform.
use shapespace_omt::synthetic::{disk_rings_measure, random_disk_points};
use shapespace_omt::{solve_ot, NewtonParams, SourceMeasure, StartStrategy};

fn main() {
    let args: Vec<String> = std::env::args().collect();
    let case = args.get(1).map(String::as_str).unwrap_or("contrast");
    let n: usize = args.get(2).and_then(|s| s.parse::<f64>().ok()).unwrap_or(1e4) as usize;
    let which = args.get(3).map(String::as_str).unwrap_or("both");
    let measure = match case {
        "uniform" => SourceMeasure::unit_disk(512).unwrap(),
        _ => disk_rings_measure(30, |x| if x[0] > 0.0 { 100.0 } else { 1.0 }).unwrap(),
    };
    let points = random_disk_points(n, 2024);
    let masses = vec![1.0; n];
    for c2f in [true, false] {
        if (which == "c2f" && !c2f) || (which == "default" && c2f) {
            continue;
        }
        let params = NewtonParams {
            start_strategy: if c2f {
                StartStrategy::CoarseToFine
            } else {
                StartStrategy::Voronoi
            },
            ..Default::default()
        };
        let sol = solve_ot(&measure, &points, &masses, &params).unwrap();
        println!(
            "{case} N {n} coarse_to_fine {c2f}: start {:?} ({:.2} s) steps {} evals {} total {:.2} s err {:.2e} cost {:.12e} {}",
            sol.start, sol.t_start, sol.iterations, sol.evaluations, sol.t_total, sol.max_relative_error, sol.cost, sol.stop
        );
    }
}
