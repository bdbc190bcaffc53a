//! The per-step Newton log of an OT solve, one line per step (shared by the probes).

use shapespace_omt::OtSolution;

/// Prints step k: max relative error, accepted τ, rejected trials (all, by the mass floor, by
/// the norm test), smallest cell mass, the cells given intermediate targets, and the seconds in
/// diagrams, integration and solves.
pub fn print_newton_log(sol: &OtSolution) {
    for (k, r) in sol.log.iter().enumerate() {
        println!(
            "{k:3} err {:.2e} tau {:.3e} halv {} rejm {} rejn {} minmass {:.2e} capped {} diag {:.3} integ {:.3} solve {:.3}",
            r.max_relative_error,
            r.step,
            r.halvings,
            r.rejected_min_mass,
            r.rejected_norm,
            r.min_cell_mass,
            r.intermediate_targets,
            r.t_diagram,
            r.t_integration,
            r.t_solve
        );
    }
}
