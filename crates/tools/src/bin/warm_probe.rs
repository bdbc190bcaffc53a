//! Probe: warm starts across sources with a common target.
use shapespace_omt::NewtonParams;
use shapespace_tools::faces;

fn main() {
    let args: Vec<String> = std::env::args().skip(1).collect();
    let shapes = faces::prepared_faces(&args);
    let t = shapes.last().unwrap();
    let mut warm: Option<Vec<f64>> = None;
    for s in &shapes[..shapes.len() - 1] {
        for (label, init) in [("voronoi", None), ("warm", warm.clone())] {
            if label == "warm" && init.is_none() {
                continue;
            }
            let params = NewtonParams {
                density_continuation: None,
                max_iterations: 300,
                initial_heights: init,
                ..Default::default()
            };
            let sol = shapespace_omt::solve_ot(&s.measure, &t.points, &t.masses, &params).unwrap();
            let evals = sol.evaluations;
            let (rm, rn): (usize, usize) = sol
                .log
                .iter()
                .fold((0, 0), |(a, b), r| (a + r.rejected_min_mass, b + r.rejected_norm));
            println!(
                "{} -> {} {label}: it {} evals {} (rej minmass {rm} norm {rn}) t {:.3} cost {:.15e} err0 {:.2e}",
                s.name,
                t.name,
                sol.iterations,
                evals,
                sol.t_total,
                sol.cost,
                sol.log.first().map(|r| r.max_relative_error).unwrap_or(0.0)
            );
            if label == "voronoi" {
                warm = Some(sol.heights.clone());
            }
        }
    }
}
