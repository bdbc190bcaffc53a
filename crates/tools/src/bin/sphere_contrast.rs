//! Spherical OT against contrasting zonal densities ρ ∝ exp(k z) (ratio e^{2k}) from the
//! Voronoi start: Newton steps, evaluations and the stop, per k.
//! `cargo run --release -p shapespace-tools --bin sphere_contrast [N]` (default 5000 points).

use shapespace_omt::sphere::{icosphere, random_sphere_points, solve_sphere_ot, SphereMeasure, SphereOtParams};

fn main() {
    let n: usize = std::env::args()
        .nth(1)
        .and_then(|a| a.parse::<f64>().ok())
        .map(|v| v as usize)
        .unwrap_or(5000);
    let points = random_sphere_points(n, 5);
    let (v, t) = icosphere(5);
    println!(
        "{:>6} {:>10} {:>7} {:>6} {:>6} {:>10} {:>8}  stop",
        "k", "ratio", "stages", "steps", "evals", "max rel", "total s"
    );
    for k in [0.5, 1.0, 2.0, 3.0, 4.0, 5.0] {
        let measure =
            SphereMeasure::from_spherical_density(v.clone(), t.clone(), |x| (k * x[2]).exp()).expect("measure");
        match solve_sphere_ot(&measure, &points, &vec![1.0; n], &SphereOtParams::default()) {
            Ok(s) => println!(
                "{:>6} {:>10.1} {:>7} {:>6} {:>6} {:>10.2e} {:>8.2}  {}",
                k,
                (2.0 * k).exp(),
                s.continuation_stages,
                s.iterations + s.continuation_iterations,
                s.evaluations,
                s.max_relative_error,
                s.t_total,
                s.stop
            ),
            Err(e) => println!("{k:>6} {:>10.1}  error: {e}", (2.0 * k).exp()),
        }
    }
}
