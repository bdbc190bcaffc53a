//! Probe: the Newton log (per step: error, τ, rejections by cause, timings) of the area-preserving
//! OT on camelhead subdivided 1-to-4 (45k sites, Voronoi start), run twice; `NOSUB=1` for the
//! original mesh, or a disk mesh given as the argument.
//! `cargo run --release -p shapespace-tools --bin camel_probe [-- MESH]`.
use shapespace_analysis::area_preserving::{transport_problem, AreaPreservingParams};
use shapespace_conformal::Markers;
use shapespace_geometry::prepare::subdivide_midpoint;
use shapespace_tools::newton_log;

fn main() {
    let mesh = match std::env::args().nth(1) {
        // any disk mesh (e.g. a TOSCA mesh or Nefertiti cut open by `shapespace prepare`)
        Some(path) => shapespace_geometry::io::read_mesh(std::path::Path::new(&path)).unwrap(),
        None => {
            let m = shapespace_geometry::io::read_mesh(
                &shapespace_test_support::shared_datasets_dir().join("libigl_tutorial_data/camelhead.off"),
            )
            .unwrap();
            if std::env::var("NOSUB").is_ok() {
                m
            } else {
                subdivide_midpoint(&m).unwrap()
            }
        }
    };
    let problem = transport_problem(&mesh, &Markers::default(), &AreaPreservingParams::default()).unwrap();
    let (measure, c, nu) = (&problem.measure, &problem.conformal, &problem.target_masses);
    println!(
        "conformal: {} linear solves, {} intrinsic flips, {:?}",
        c.info.linear_solves, c.info.intrinsic_flips, c.info.timings
    );
    for _ in 0..2 {
        let sol = shapespace_omt::solve_ot(measure, &c.uv, nu, &Default::default()).unwrap();
        newton_log::print_newton_log(&sol);
        println!(
            "it {} evals {} start {:?} t_start {:.3} total {:.3} stop {}",
            sol.iterations, sol.evaluations, sol.start, sol.t_start, sol.t_total, sol.stop
        );
        println!(
            "linear: assembly {:.3} s, {} symbolic ({} orderings) {:.3} s, numeric + solve {:.3} s",
            sol.t_assembly, sol.symbolic_factorizations, sol.orderings, sol.t_symbolic, sol.t_numeric
        );
    }
}
