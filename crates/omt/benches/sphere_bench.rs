//! Spherical semi-discrete OT timings: uniform density on an icosphere to N random equal-mass
//! points on S². `cargo bench -p shapespace-omt --bench sphere_bench [-- N ...]`
//! (default 1e4 and 1e5).

use shapespace_omt::sphere::{random_sphere_points, solve_sphere_ot, SphereMeasure, SphereOtParams};

fn main() {
    let sizes: Vec<usize> = std::env::args()
        .skip(1)
        .filter_map(|a| a.parse::<f64>().ok().map(|v| v as usize))
        .collect();
    let sizes = if sizes.is_empty() { vec![10_000, 100_000] } else { sizes };
    println!(
        "{:>8} {:>9} {:>6} {:>6} {:>10} {:>10} {:>9} {:>9} {:>8}",
        "points", "triangles", "steps", "evals", "max rel", "cost", "integr s", "solve s", "total s"
    );
    for n in sizes {
        // at least half as many source triangles as points (20·4^s ≥ n/2), at least 5 levels
        let mut s = 5;
        while 2 * 20 * 4usize.pow(s as u32) < n {
            s += 1;
        }
        let measure = SphereMeasure::uniform_icosphere(s).expect("icosphere");
        let points = random_sphere_points(n, 7);
        let masses = vec![1.0; n];
        let solution = solve_sphere_ot(&measure, &points, &masses, &SphereOtParams::default()).expect("solve");
        let ti: f64 = solution.log.iter().map(|r| r.t_integration).sum();
        let ts: f64 = solution.log.iter().map(|r| r.t_solve).sum();
        println!(
            "{:>8} {:>9} {:>6} {:>6} {:>10.2e} {:>10.6} {:>9.2} {:>9.2} {:>8.2}   {} (mean candidates per triangle {:.1})",
            n,
            measure.triangles.len(),
            solution.iterations,
            solution.evaluations,
            solution.max_relative_error,
            solution.cost,
            ti,
            ts,
            solution.t_total,
            solution.stop,
            solution.cells.mean_candidates
        );
    }
}
