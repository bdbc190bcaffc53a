//! Probe: Newton iteration logs of one face pair with the pairwise distances' solver settings
//! (`PairwiseOptions::default()`; args A B \[CONTINUATION\]; env `FLUX`: the Newton evaluations'
//! masses by the flux form).
use shapespace_omt::NewtonParams;
use shapespace_tools::faces;
use shapespace_tools::newton_log;

fn main() {
    let args: Vec<String> = std::env::args().collect();
    let a = args.get(1).cloned().unwrap_or("id00_neutral".into());
    let b = args.get(2).cloned().unwrap_or("id00_happy".into());
    let cont: Option<f64> = args.get(3).and_then(|s| s.parse().ok());
    let shapes = faces::prepared_faces(&[a.as_str(), b.as_str()]);
    let (lo, hi) = shapes[0]
        .measure
        .densities
        .iter()
        .fold((f64::INFINITY, 0.0f64), |(l, h), &d| (l.min(d), h.max(d)));
    println!("density range {lo:.3e} .. {hi:.3e}");
    let params = NewtonParams {
        density_continuation: cont,
        max_iterations: 300,
        flux_masses: std::env::var("FLUX").is_ok(),
        // the distances' settings (tolerance, coarse tolerance, linear solver), as a pair runs
        ..shapespace_analysis::distance::PairwiseOptions::default().newton
    };
    let sol = shapespace_omt::solve_ot(&shapes[0].measure, &shapes[1].points, &shapes[1].masses, &params).unwrap();
    newton_log::print_newton_log(&sol);
    let (rm, rn): (usize, usize) = sol
        .log
        .iter()
        .fold((0, 0), |(a, b), r| (a + r.rejected_min_mass, b + r.rejected_norm));
    println!(
        "SUMMARY it {} evals {} rej_minmass {rm} rej_norm {rn} cost {:.15e} err {:.2e}",
        sol.iterations, sol.evaluations, sol.cost, sol.max_relative_error
    );
    println!(
        "finest linear algebra: assembly {:.4} s, symbolic {:.4} s ({} factorizations, {} orderings), numeric + solve {:.4} s",
        sol.t_assembly, sol.t_symbolic, sol.symbolic_factorizations, sol.orderings, sol.t_numeric
    );
    println!(
        "start {:?} eps0 {:.2e} t_start {:.3} total {:.3} cost {:.6} stop {}",
        sol.start, sol.epsilon0, sol.t_start, sol.t_total, sol.cost, sol.stop
    );
}
