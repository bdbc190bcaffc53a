//! Probe: density continuation ratios on the ot_bench contrast case (uniform random points,
//! density 100 on x > 0), default parameters otherwise. `N=10000 contrast_probe RATIO...`
//! (results: `docs/experiments.md`; fixed ratios 1.5 / 2 / 3 all converge, in 392 / 325 / 300
//! steps on 1e4 points).
use shapespace_omt::synthetic::{disk_rings_measure, random_disk_points};
use shapespace_omt::{solve_ot, NewtonParams};

fn main() {
    let ratios: Vec<f64> = std::env::args().skip(1).map(|s| s.parse().unwrap()).collect();
    let n: usize = std::env::var("N").map(|s| s.parse().unwrap()).unwrap_or(10_000);
    let contrast = disk_rings_measure(30, |x| if x[0] > 0.0 { 100.0 } else { 1.0 }).unwrap();
    let points = random_disk_points(n, 2024);
    let masses = vec![1.0; n];
    for r in ratios {
        let params = NewtonParams {
            density_continuation: Some(r),
            ..Default::default()
        };
        let sol = solve_ot(&contrast, &points, &masses, &params).unwrap();
        let evals = sol.evaluations;
        println!(
            "ratio {r}: start {:?} it {} evals {} t {:.2} err {:.2e} stop {}",
            sol.start, sol.iterations, evals, sol.t_total, sol.max_relative_error, sol.stop
        );
    }
}
