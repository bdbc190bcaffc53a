//! Probe: how good a solver start is on a face pair. Prints the quantiles of the start's
//! relative cell-mass errors (m_i − ν_i)/ν_i and the cells that are farthest off.
//!
//! `cargo run --release -p shapespace-tools --bin start_probe -- [A] [B] [voronoi|c2f] [STEPS]`
//! (defaults id01_happy id00_neutral c2f 0; STEPS > 0 shows the errors after that many Newton
//! steps instead). Run from the repository root.
use shapespace_omt::{NewtonParams, StartStrategy};
use shapespace_tools::faces;

fn main() {
    let args: Vec<String> = std::env::args().collect();
    let a = args.get(1).cloned().unwrap_or("id01_happy".into());
    let b = args.get(2).cloned().unwrap_or("id00_neutral".into());
    let start_strategy = match args.get(3).map(String::as_str) {
        Some("voronoi") => StartStrategy::Voronoi,
        _ => StartStrategy::CoarseToFine,
    };
    let steps: usize = args.get(4).and_then(|s| s.parse().ok()).unwrap_or(0);
    let shapes = faces::prepared_faces(&[a.as_str(), b.as_str()]);
    let params = NewtonParams {
        max_iterations: steps,
        start_strategy,
        // the start itself, not the continuation's first stage
        density_continuation: None,
        ..Default::default()
    };
    let sol = shapespace_omt::solve_ot(&shapes[0].measure, &shapes[1].points, &shapes[1].masses, &params).unwrap();
    let points = &shapes[1].points;
    let mut errors: Vec<(f64, usize)> = (0..points.len())
        .map(|i| {
            let t = sol.target_masses[i];
            ((sol.cells.masses[i] - t) / t, i)
        })
        .collect();
    errors.sort_by(|x, y| x.0.total_cmp(&y.0));
    let q = |p: f64| errors[((errors.len() - 1) as f64 * p).round() as usize].0;
    println!("{a} → {b}: start {:?}, {} steps", sol.start, sol.iterations);
    println!(
        "relative error quantiles: 0.1% {:+.2e}  1% {:+.2e}  10% {:+.2e}  50% {:+.2e}  90% {:+.2e}  99% {:+.2e}  max {:+.2e}",
        q(0.001),
        q(0.01),
        q(0.1),
        q(0.5),
        q(0.9),
        q(0.99),
        q(1.0)
    );
    for threshold in [0.1, 0.5, 1.0, 10.0] {
        let count = errors.iter().filter(|e| e.0.abs() > threshold).count();
        println!("  |error| > {threshold}: {count} of {}", errors.len());
    }
    errors.sort_by(|x, y| y.0.abs().total_cmp(&x.0.abs()));
    for &(e, i) in errors.iter().take(10) {
        let y = points[i];
        println!(
            "  vertex {i}: error {e:+.3e}, |y| {:.4}, angle {:.1}°, target {:.2e}",
            y[0].hypot(y[1]),
            y[1].atan2(y[0]).to_degrees(),
            sol.target_masses[i]
        );
    }
}
