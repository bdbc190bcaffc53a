//! `sphere_schedule_probe A B T0,T1,...,1 [MAX_STEPS]`: the transport A → B on the sphere
//! (as `distances` sets it up, fixed alignment) solved through the softened sources ρ^t for the
//! given exponents, each stage warm-started from the last (the first from the solver's own
//! start), with each stage's steps, evaluations, seconds and stop printed.

use shapespace_analysis::sphere_distance::prepare_sphere_shape;
use shapespace_conformal::SphereMapParams;
use shapespace_omt::sphere::{solve_sphere_ot, SphereMeasure, SphereOtParams, SphereStart};

fn main() {
    let args: Vec<String> = std::env::args().collect();
    if args.len() < 4 {
        eprintln!("usage: sphere_schedule_probe A B T0,T1,...,1 [MAX_STEPS]");
        std::process::exit(2);
    }
    let prepare = |p: &str| {
        let mesh = shapespace_geometry::io::read_mesh(std::path::Path::new(p)).expect("mesh");
        prepare_sphere_shape(p, &mesh, &SphereMapParams::default()).expect("sphere map")
    };
    let (a, b) = (prepare(&args[1]), prepare(&args[2]));
    let schedule: Vec<f64> = args[3].split(',').map(|t| t.parse().expect("exponent")).collect();
    let max_steps: usize = args.get(4).map_or(100, |s| s.parse().expect("steps"));
    let total = std::time::Instant::now();
    let mut heights: Option<(Vec<f64>, Vec<f64>)> = None;
    let keep_lo = std::env::var("DROP_LO").is_err();
    for (k, &t) in schedule.iter().enumerate() {
        let last = k + 1 == schedule.len();
        let softened = SphereMeasure {
            vertices: a.measure.vertices.clone(),
            triangles: a.measure.triangles.clone(),
            densities: a.measure.densities.iter().map(|d| d.powf(t)).collect(),
        };
        let p = SphereOtParams {
            tolerance: if last { 1e-4 } else { 1e-3 },
            max_iterations: max_steps,
            initial_heights: heights.as_ref().map(|h| h.0.clone()),
            initial_heights_lo: heights.as_ref().filter(|_| keep_lo).map(|h| h.1.clone()),
            density_continuation: None,
            start: match std::env::var("SPHERE_START").as_deref() {
                Ok("c2f") => SphereStart::CoarseToFine,
                Ok("voronoi") => SphereStart::Voronoi,
                _ => SphereStart::Auto,
            },
            ..SphereOtParams::default()
        };
        let clock = std::time::Instant::now();
        match solve_sphere_ot(&softened, &b.points, &b.masses, &p) {
            Ok(s) => {
                let first = s.log.first().map_or(0.0, |l| l.step);
                println!(
                    "t {t:.3}: {} steps (coarse {:?}), {} evaluations, stop {}, error {:.2e}, first tau {first:.1e}, cost {:.6e}, {:.2} s",
                    s.iterations,
                    s.coarse_levels,
                    s.evaluations,
                    s.stop,
                    s.max_relative_error,
                    s.cost,
                    clock.elapsed().as_secs_f64()
                );
                if !s.converged() {
                    println!("  stopped; total {:.2} s", total.elapsed().as_secs_f64());
                    return;
                }
                heights = Some((s.heights, s.heights_lo));
            }
            Err(e) => {
                println!("t {t:.3}: failed: {e}");
                return;
            }
        }
    }
    println!("total {:.2} s", total.elapsed().as_secs_f64());
}
