//! Probe: which OT start suits an area-preserving map. For each disk mesh (a path; a closed
//! mesh is cut open as `shapespace prepare` does; `camelhead-sub` is the bundled camelhead
//! subdivided 1-to-4): the Voronoi start's cell masses against the targets (min and max of
//! m/ν), then the OT from the Voronoi and from the coarse-to-fine start (finest-level steps,
//! evaluations, coarse steps, seconds).
//! `cargo run --release -p shapespace-tools --bin param_start_probe -- MESH...`
use std::time::Instant;

use shapespace_analysis::area_preserving::{transport_problem, AreaPreservingParams};
use shapespace_conformal::Markers;
use shapespace_geometry::prepare::{prepare_disk, subdivide_midpoint, PrepareOptions};
use shapespace_geometry::Connectivity;
use shapespace_omt::newton::{integrate_at_heights, CellIntegrator, Start};
use shapespace_omt::{solve_ot, NewtonParams, StartStrategy};

fn main() {
    for arg in std::env::args().skip(1) {
        let mesh = if arg == "camelhead-sub" {
            let m = shapespace_geometry::io::read_mesh(
                &shapespace_test_support::shared_datasets_dir().join("libigl_tutorial_data/camelhead.off"),
            )
            .unwrap();
            subdivide_midpoint(&m).unwrap()
        } else {
            let m = shapespace_geometry::io::read_mesh(std::path::Path::new(&arg)).unwrap();
            if Connectivity::of(&m).boundary_loops(&m.faces).len() == 1 {
                m
            } else {
                prepare_disk(&m, &PrepareOptions::default()).unwrap().0
            }
        };
        let problem = match transport_problem(&mesh, &Markers::default(), &AreaPreservingParams::default()) {
            Ok(p) => p,
            Err(e) => {
                println!("{arg}: {e}");
                continue;
            }
        };
        let (measure, c, nu) = (&problem.measure, &problem.conformal, &problem.target_masses);
        let h0: Vec<f64> = c.uv.iter().map(|y| -0.5 * (y[0] * y[0] + y[1] * y[1])).collect();
        let cells = integrate_at_heights(measure, &c.uv, &h0, CellIntegrator::Restricted).unwrap();
        let ratios: Vec<f64> = cells.masses.iter().zip(nu).map(|(m, n)| m / n).collect();
        let (lo, hi) = ratios
            .iter()
            .fold((f64::INFINITY, 0.0f64), |(l, h), &r| (l.min(r), h.max(r)));
        let mut sorted = ratios.clone();
        sorted.sort_by(f64::total_cmp);
        let q = |p: f64| sorted[((sorted.len() - 1) as f64 * p) as usize];
        println!(
            "{arg}: N {}, Voronoi m/nu min {lo:.1e} p1 {:.1e} p99 {:.1e} max {hi:.1e}",
            nu.len(),
            q(0.01),
            q(0.99)
        );
        for strategy in [StartStrategy::Voronoi, StartStrategy::CoarseToFine] {
            let params = NewtonParams {
                start_strategy: strategy,
                ..Default::default()
            };
            let t = Instant::now();
            let sol = solve_ot(measure, &c.uv, nu, &params).unwrap();
            let coarse = match sol.start {
                Start::CoarseToFine { coarse_iterations, .. } => coarse_iterations,
                _ => 0,
            };
            println!(
                "  {strategy:?}: {} steps, {} evals, coarse steps {coarse}, {} , {:.2} s",
                sol.iterations,
                sol.evaluations,
                sol.stop,
                t.elapsed().as_secs_f64()
            );
        }
    }
}
