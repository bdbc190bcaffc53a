//! Probe: the Newton log of the area-preserving OT on the sphere of one closed mesh, as
//! `shapespace param --domain sphere` sets it up (conformal sphere map, uniform icosphere source,
//! vertex area shares as masses). `sphere_ot_log PATH` (a path relative to the shared datasets
//! folder, `$SHAPESPACE_DATA`, default `../shared/datasets`, or an existing path) [START: `auto`
//! (default), `voronoi` or `c2f`].
use shapespace_analysis::area_preserving::weighted_target_masses;
use shapespace_conformal::{sphere_map, SphereMapParams};
use shapespace_geometry::quantities::vertex_dual_areas;
use shapespace_omt::sphere::{solve_sphere_ot, SphereMeasure, SphereOtParams, SphereStart};

fn main() {
    shapespace_tools::at_repository_root();
    let arg = std::env::args().nth(1).unwrap_or("goast/finger/finger0.ply".into());
    let path = if std::path::Path::new(&arg).exists() {
        std::path::PathBuf::from(&arg)
    } else {
        shapespace_test_support::shared_datasets_dir().join(&arg)
    };
    let mesh = shapespace_geometry::io::read_mesh(&path).unwrap_or_else(|e| panic!("{e}"));
    let map = sphere_map(&mesh, &SphereMapParams::default()).unwrap();
    let n = mesh.num_vertices();
    let s = shapespace_analysis::sphere_param::default_source_subdivisions(n);
    let source = SphereMeasure::uniform_icosphere(s).unwrap();
    let scale = source.total_mass() / std::f64::consts::PI;
    let masses: Vec<f64> = weighted_target_masses(&vertex_dual_areas(&mesh), None)
        .unwrap()
        .into_iter()
        .map(|m| m * scale)
        .collect();
    let t = std::time::Instant::now();
    let start = match std::env::args().nth(2).as_deref() {
        Some("voronoi") => SphereStart::Voronoi,
        Some("c2f") => SphereStart::CoarseToFine,
        _ => SphereStart::Auto,
    };
    let params = SphereOtParams {
        start,
        ..Default::default()
    };
    let sol = solve_sphere_ot(&source, &map.positions, &masses, &params).unwrap();
    for (k, it) in sol.log.iter().enumerate() {
        println!(
            "step {k:3}: rel {:.3e} |G| {:.3e} tau {:.3e} halvings {:2} capped {:5} min cell {:.3e}",
            it.max_relative_error, it.gradient_norm, it.step, it.halvings, it.intermediate_targets, it.min_cell_mass
        );
    }
    let fine: f64 = sol.log.iter().map(|it| it.t_integration + it.t_solve).sum();
    println!("finest level's steps: {fine:.2} s");
    println!(
        "coarse levels (points, steps): {:?}; start rechecked {}",
        sol.coarse_levels, sol.start_rechecked
    );
    println!(
        "{}: V {n}, subdivisions {s}, stop {}, steps {} (+{} in {} continuation stages), evaluations {}, rel {:.3e}, {:.2} s",
        path.display(),
        sol.stop,
        sol.iterations,
        sol.continuation_iterations,
        sol.continuation_stages,
        sol.evaluations,
        sol.max_relative_error,
        t.elapsed().as_secs_f64()
    );
}
