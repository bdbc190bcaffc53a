//! Probe: one full solve and the cost of one evaluation split into its parts, for a uniform disk
//! problem or a face pair dumped by the `dump_pair` probe.
//!
//! `cargo run --release -p shapespace-tools --bin eval_probe -- disk N [REPEATS]`
//! `cargo run --release -p shapespace-tools --bin eval_probe -- pair FILE.json [REPEATS]`
//!
//! The pair is solved as `distance::directed_distance` does (no density continuation, Voronoi
//! start, `LinearSolver::CholeskyReusedOrdering`; env CHOLESKY=1: `LinearSolver::Cholesky`). Prints iterations, evaluations and the cost to full precision (to check that a change
//! keeps the result), then the best times over REPEATS (default 10) of: power diagram, restricted
//! integration, Newton direction with a new symbolic factorization and with a reused one, all
//! at the solution heights.

use std::time::Instant;

use shapespace_omt::linear::{LinearSolver, NewtonSystem};
use shapespace_omt::newton::weights_from_heights;
use shapespace_omt::power_diagram::PowerDiagram;
use shapespace_omt::restricted::RestrictedIntegrator;
use shapespace_omt::synthetic::random_disk_points;
use shapespace_omt::{solve_ot, NewtonParams, SourceMeasure};

/// Minimum: the least disturbed run on a shared machine.
fn best(v: Vec<f64>) -> f64 {
    v.into_iter().fold(f64::INFINITY, f64::min)
}

fn main() {
    let args: Vec<String> = std::env::args().skip(1).collect();
    let repeats: usize = args.get(2).and_then(|s| s.parse().ok()).unwrap_or(10);
    let (measure, points, masses, params) = match args.first().map(String::as_str) {
        Some("pair") => {
            let text = std::fs::read_to_string(&args[1]).expect("pair file");
            let v: serde_json::Value = serde_json::from_str(&text).expect("json");
            let get = |k: &str| v[k].clone();
            let measure = SourceMeasure::new(
                serde_json::from_value(get("vertices")).unwrap(),
                serde_json::from_value(get("triangles")).unwrap(),
                serde_json::from_value(get("densities")).unwrap(),
            )
            .unwrap();
            let params = NewtonParams {
                density_continuation: None,
                linear_solver: if std::env::var("CHOLESKY").is_ok() {
                    LinearSolver::Cholesky
                } else {
                    LinearSolver::CholeskyReusedOrdering
                },
                ..NewtonParams::default()
            };
            (
                measure,
                serde_json::from_value::<Vec<[f64; 2]>>(get("points")).unwrap(),
                serde_json::from_value::<Vec<f64>>(get("masses")).unwrap(),
                params,
            )
        }
        _ => {
            let n = args.get(1).and_then(|s| s.parse::<f64>().ok()).unwrap_or(1e5) as usize;
            (
                SourceMeasure::unit_disk(512).unwrap(),
                random_disk_points(n, 2024),
                vec![1.0; n],
                NewtonParams::default(),
            )
        }
    };
    let sol = solve_ot(&measure, &points, &masses, &params).expect("solve");
    if std::env::var("LOG").is_ok() {
        for (k, r) in sol.log.iter().enumerate() {
            println!(
                "{k:3} err {:.3e} tau {:.3e} evals {} min mass {:.2e}",
                r.max_relative_error, r.step, r.evaluations, r.min_cell_mass
            );
        }
    }
    let sum = |f: fn(&shapespace_omt::newton::IterationRecord) -> f64| sol.log.iter().map(f).sum::<f64>();
    println!(
        "solve: N {} M {} its {} evals {} symbolic {} orderings {} err {:.3e} stop {} cost {:.17e}",
        points.len(),
        measure.triangles.len(),
        sol.iterations,
        sol.evaluations,
        sol.symbolic_factorizations,
        sol.orderings,
        sol.max_relative_error,
        sol.stop,
        sol.cost
    );
    println!(
        "solve: total {:.3} s start {:.3} diagram {:.3} integration {:.3} linear {:.3} (assembly {:.3} symbolic {:.3} numeric {:.3})",
        sol.t_total,
        sol.t_start,
        sum(|r| r.t_diagram),
        sum(|r| r.t_integration),
        sum(|r| r.t_solve),
        sol.t_assembly,
        sol.t_symbolic,
        sol.t_numeric
    );
    let heights = sol.heights.clone();
    let weights = weights_from_heights(&points, &heights);
    let integrator = RestrictedIntegrator::new(&measure);
    let (mut td, mut ti, mut tsym, mut tnum) = (vec![], vec![], vec![], vec![]);
    let pinned = (0..masses.len()).fold(0, |b, i| if masses[i] > masses[b] { i } else { b });
    for _ in 0..repeats {
        let t = Instant::now();
        let diagram = PowerDiagram::new(&points, &weights).unwrap();
        td.push(t.elapsed().as_secs_f64());
        let t = Instant::now();
        let cells = integrator.integrate(&diagram);
        ti.push(t.elapsed().as_secs_f64());
        let gradient: Vec<f64> = cells
            .masses
            .iter()
            .zip(&sol.target_masses)
            .map(|(m, t)| m - t)
            .collect();
        let mut system = NewtonSystem::new(pinned, LinearSolver::Cholesky);
        let t = Instant::now();
        system.newton_direction(&points, &cells, &gradient).unwrap();
        tsym.push(t.elapsed().as_secs_f64());
        let t = Instant::now();
        system.newton_direction(&points, &cells, &gradient).unwrap();
        tnum.push(t.elapsed().as_secs_f64());
    }
    println!(
        "one evaluation (best of {repeats}): diagram {:.4} s, integration {:.4} s; Newton direction: new symbolic {:.4} s, reused {:.4} s",
        best(td),
        best(ti),
        best(tsym),
        best(tnum)
    );
}
