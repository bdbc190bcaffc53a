//! Probe: the Newton log of the area-preserving OT of a TOSCA body slit as `shapespace prepare
//! --seam K` makes it. `body_ot_log NAME [K]` (default victoria0, 1; NAME is read from `tosca/`
//! of the shared datasets folder, `$SHAPESPACE_DATA`, default `../shared/datasets`), or
//! `body_ot_log PATH` for a mesh that is already a disk (e.g. written by `shapespace prepare`).
use shapespace_tools::newton_log;

use shapespace_analysis::area_preserving::{transport_problem, AreaPreservingParams};
use shapespace_conformal::Markers;
use shapespace_geometry::prepare::{prepare_disk, PrepareOptions};

fn main() {
    let args: Vec<String> = std::env::args().collect();
    let name = args.get(1).cloned().unwrap_or("victoria0".into());
    let k: usize = args.get(2).and_then(|s| s.parse().ok()).unwrap_or(1);
    let disk = if name.contains('/') {
        shapespace_geometry::io::read_mesh(std::path::Path::new(&name)).unwrap()
    } else {
        let path = shapespace_test_support::shared_datasets_dir().join(format!("tosca/{name}.off"));
        let mesh = shapespace_geometry::io::read_mesh(&path).unwrap_or_else(|e| panic!("{e} (set SHAPESPACE_DATA)"));
        let options = PrepareOptions {
            seam_extremities: k,
            ..Default::default()
        };
        prepare_disk(&mesh, &options).unwrap().0
    };
    let params = AreaPreservingParams::default();
    let problem = transport_problem(&disk, &Markers::default(), &params).unwrap();
    let t = std::time::Instant::now();
    let sol = shapespace_omt::solve_ot(
        &problem.measure,
        &problem.conformal.uv,
        &problem.target_masses,
        &params.newton,
    )
    .unwrap();
    newton_log::print_newton_log(&sol);
    println!(
        "{name} seam {k}: {} V, start {:?}, t_start {:.2} s, total {:.2} s ({:.2} s wall), stop {:?}",
        disk.num_vertices(),
        sol.start,
        sol.t_start,
        sol.t_total,
        t.elapsed().as_secs_f64(),
        sol.stop
    );
    println!(
        "linear algebra (finest level): assembly {:.3} s, symbolic {:.3} s ({} factorizations, {} orderings), numeric + solve {:.3} s",
        sol.t_assembly, sol.t_symbolic, sol.symbolic_factorizations, sol.orderings, sol.t_numeric
    );
}
