//! `sphere_distance_probe A B [fixed|rotation|direct|direct-coarse|fallback|continuation=R]`: the spherical distance A → B of two closed
//! meshes with its stages (the transport solves' steps and seconds, the rotation search).

use shapespace_analysis::sphere_distance::{directed_sphere_distance, prepare_sphere_shape, SphereAlignment};
use shapespace_conformal::SphereMapParams;
use shapespace_omt::sphere::SphereOtParams;

fn main() {
    let args: Vec<String> = std::env::args().collect();
    if args.len() < 3 {
        eprintln!("usage: sphere_distance_probe A B [fixed|rotation|direct|direct-coarse|fallback|continuation=R]");
        std::process::exit(2);
    }
    let prepare = |p: &str| {
        let mesh = shapespace_geometry::io::read_mesh(std::path::Path::new(p)).expect("mesh");
        let t = std::time::Instant::now();
        let s = prepare_sphere_shape(p, &mesh, &SphereMapParams::default()).expect("sphere map");
        let (lo, hi) = s
            .map
            .face_densities
            .iter()
            .fold((f64::INFINITY, 0.0f64), |(a, b), &d| (a.min(d), b.max(d)));
        println!(
            "{p}: {} points, density {lo:.2e} .. {hi:.2e}, prepared in {:.2} s",
            s.points.len(),
            t.elapsed().as_secs_f64()
        );
        s
    };
    let (a, b) = (prepare(&args[1]), prepare(&args[2]));
    if let Some(r) = args.get(3).and_then(|a| a.strip_prefix("continuation=")) {
        // the continuation alone, ratio r per stage
        let p = SphereOtParams {
            tolerance: 1e-4,
            density_continuation: Some(r.parse().expect("ratio")),
            ..SphereOtParams::default()
        };
        let t = std::time::Instant::now();
        match shapespace_omt::sphere::solve_sphere_ot(&a.measure, &b.points, &b.masses, &p) {
            Ok(s) => println!(
                "continuation {r}: {} stages, {} + {} steps, {} evaluations, stop {}, error {:.2e}, cost {:.6e}, {:.2} s",
                s.continuation_stages, s.continuation_iterations, s.iterations, s.evaluations, s.stop, s.max_relative_error, s.cost, t.elapsed().as_secs_f64()
            ),
            Err(e) => println!("continuation failed: {e}"),
        }
        return;
    }
    if args.get(3).map(String::as_str) == Some("fallback") {
        // the cold solve of `distances` at the maps' own alignment (the direct solve, then the
        // continuation if it does not converge), with the direct solve's full step cap and with
        // its stall window (decision 0036), one after the other
        for window in [None, Some(shapespace_analysis::sphere_distance::DIRECT_STALL_STEPS)] {
            let t = std::time::Instant::now();
            let direct = SphereOtParams {
                tolerance: 1e-4,
                density_continuation: None,
                stall_window: window,
                ..SphereOtParams::default()
            };
            let first =
                shapespace_omt::sphere::solve_sphere_ot(&a.measure, &b.points, &b.masses, &direct).expect("direct");
            let t_direct = t.elapsed().as_secs_f64();
            let fallback = SphereOtParams {
                tolerance: 1e-4,
                ..SphereOtParams::default()
            };
            let s = shapespace_omt::sphere::solve_sphere_ot(&a.measure, &b.points, &b.masses, &fallback)
                .expect("continuation");
            println!(
                "stall window {window:?}: direct {} steps ({}, error {:.2e}, {t_direct:.2} s); continuation {} stages, {} + {} steps, {}, error {:.2e}, cost {:.6e}; total {:.2} s",
                first.iterations, first.stop, first.max_relative_error, s.continuation_stages, s.continuation_iterations,
                s.iterations, s.stop, s.max_relative_error, s.cost, t.elapsed().as_secs_f64()
            );
        }
        return;
    }
    if let Some(mode @ ("direct" | "direct-coarse")) = args.get(3).map(String::as_str) {
        // the direct solve alone (no continuation), its Newton log; `direct-coarse` forces the
        // coarse-to-fine start (no Voronoi path after it)
        let p = SphereOtParams {
            tolerance: 1e-4,
            density_continuation: None,
            start: if mode == "direct" {
                shapespace_omt::sphere::SphereStart::Auto
            } else {
                shapespace_omt::sphere::SphereStart::CoarseToFine
            },
            ..SphereOtParams::default()
        };
        let t = std::time::Instant::now();
        match shapespace_omt::sphere::solve_sphere_ot(&a.measure, &b.points, &b.masses, &p) {
            Ok(s) => {
                println!(
                    "direct: {} steps, stop {}, error {:.2e}, coarse levels {:?}, {:.2} s",
                    s.iterations,
                    s.stop,
                    s.max_relative_error,
                    s.coarse_levels,
                    t.elapsed().as_secs_f64()
                );
                for (k, it) in s.log.iter().enumerate() {
                    println!(
                        "  {k}: error {:.2e} tau {:.2e} halvings {} capped {} min cell {:.2e}",
                        it.max_relative_error, it.step, it.halvings, it.intermediate_targets, it.min_cell_mass
                    );
                }
            }
            Err(e) => println!("direct failed: {e}"),
        }
        return;
    }
    let alignment = match args.get(3).map(String::as_str) {
        Some("fixed") => SphereAlignment::Fixed,
        _ => SphereAlignment::Rotation,
    };
    let params = SphereOtParams {
        tolerance: 1e-4,
        ..SphereOtParams::default()
    };
    match directed_sphere_distance(&a, &b, alignment, &params) {
        Ok(d) => println!(
            "cost {:.6e} dual {:.6e} converged {} ({}); {} solves, {} iterations, {} evaluations, {} refinement steps; seconds: proxy {:.2}, scoring {:.2}, refinement {:.2}, total {:.2}",
            d.cost, d.dual_cost, d.converged, d.status, d.solves, d.iterations, d.evaluations, d.refinement_steps,
            d.seconds_proxy, d.seconds_scoring, d.seconds_refinement, d.seconds
        ),
        Err(e) => println!("failed: {e}"),
    }
}
