//! Stress cases: strong density contrasts, exponentially clustered points, points outside the
//! domain, masses that do not quite sum to μ(Ω). Every case must converge or return a clear
//! error; none may loop or produce NaN.

mod common;

use common::{disk_measure, sunflower, Rng};
use shapespace_omt::newton::Start;
use shapespace_omt::{solve_ot, NewtonParams, OtSolution, SourceMeasure};

fn check(name: &str, sol: &OtSolution, tolerance: f64) {
    let steps: Vec<(f64, usize)> = sol.log.iter().map(|r| (r.step, r.halvings)).collect();
    eprintln!(
        "{name}: {} — {} steps, error {:.2e}, ε₀ = {:.2e}, start {:?}, (τ, halvings) = {steps:?}",
        sol.stop, sol.iterations, sol.max_relative_error, sol.epsilon0, sol.start
    );
    assert!(sol.converged(), "{name}: {}", sol.stop);
    assert!(sol.max_relative_error <= tolerance);
    assert!(sol.cost.is_finite() && sol.heights.iter().all(|h| h.is_finite()));
    for (m, t) in sol.cells.masses.iter().zip(&sol.target_masses) {
        assert!((m - t).abs() <= tolerance * t, "{name}: mass {m} vs {t}");
    }
}

/// Density 100× and 1000× higher on the sub-disk r < ½, and on the half-plane x > 0.
#[test]
fn density_contrast_100_and_1000() {
    let points = sunflower(1000, 1.0);
    for contrast in [100.0, 1000.0] {
        let disk = disk_measure(30, &|x| if x[0] * x[0] + x[1] * x[1] < 0.25 { contrast } else { 1.0 });
        let sol = solve_ot(&disk, &points, &vec![1.0; 1000], &NewtonParams::default()).unwrap();
        check(&format!("sub-disk ×{contrast}"), &sol, 1e-6);
        let half = disk_measure(30, &|x| if x[0] > 0.0 { contrast } else { 1.0 });
        let sol = solve_ot(&half, &points, &vec![1.0; 1000], &NewtonParams::default()).unwrap();
        check(&format!("half-plane ×{contrast}"), &sol, 1e-6);
    }
}

/// y_k = e^{−k/10}(cos k, sin k), k = 0..N: cells near the origin start with masses ~e^{−2N/10}.
#[test]
fn exponentially_clustered_points() {
    let measure = SourceMeasure::unit_disk(128).unwrap();
    for n in [100usize, 200] {
        let points: Vec<[f64; 2]> = (0..n)
            .map(|k| {
                let r = (-(k as f64) / 10.0).exp();
                [0.99 * r * (k as f64).cos(), 0.99 * r * (k as f64).sin()]
            })
            .collect();
        let params = NewtonParams { max_iterations: 300, ..Default::default() };
        let sol = solve_ot(&measure, &points, &vec![1.0; n], &params).unwrap();
        check(&format!("clustered N = {n}"), &sol, 1e-6);
    }
}

/// Points partly outside Ω: the Voronoi start has empty cells, the contracted start does not.
#[test]
fn points_outside_the_domain() {
    let measure = SourceMeasure::unit_square().unwrap();
    let mut rng = Rng(5);
    let points: Vec<[f64; 2]> = (0..100).map(|_| [3.0 * rng.next() - 1.0, 3.0 * rng.next() - 1.0]).collect();
    let sol = solve_ot(&measure, &points, &vec![1.0; 100], &NewtonParams::default()).unwrap();
    assert!(matches!(sol.start, Start::Contracted { .. }), "{:?}", sol.start);
    check("outside", &sol, 1e-6);
}

/// Masses summing to (1 + 1e−9)·μ(Ω) are rescaled by 1/(1 + 1e−9).
#[test]
fn masses_off_by_1e9_are_rescaled() {
    let measure = SourceMeasure::unit_disk(64).unwrap();
    let points = sunflower(400, 0.9);
    let total = measure.total_mass();
    let masses = vec![total * (1.0 + 1e-9) / 400.0; 400];
    let sol = solve_ot(&measure, &points, &masses, &NewtonParams::default()).unwrap();
    assert!((sol.mass_scale * (1.0 + 1e-9) - 1.0).abs() < 1e-13, "{}", sol.mass_scale);
    check("masses 1 + 1e-9", &sol, 1e-6);
}

/// Very unequal target masses (ratio 1e4) on the uniform disk.
#[test]
fn unequal_target_masses() {
    let measure = SourceMeasure::unit_disk(64).unwrap();
    let mut rng = Rng(9);
    let points: Vec<[f64; 2]> = (0..300).map(|_| rng.in_disk(1.0)).collect();
    let masses: Vec<f64> = (0..300).map(|_| 10f64.powf(4.0 * rng.next())).collect();
    let sol = solve_ot(&measure, &points, &masses, &NewtonParams::default()).unwrap();
    check("masses 1..1e4", &sol, 1e-6);
}
