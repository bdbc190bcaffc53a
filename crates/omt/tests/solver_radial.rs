//! Radial closed forms on the unit disk: a radial source density μ(r) against N sunflower points
//! of the uniform disk (equal masses). The optimal map of the continuous problem is radial,
//! T(r) = √(F(r)/π) with F the source's cumulative mass, and the semi-discrete cost converges to
//! ∫₀¹ (r − T(r))² μ(r) 2πr dr as N grows (`docs/conventions.md`, "Closed-form test values").

use crate::common::{disk_measure, quadrature, sunflower};
use shapespace_omt::{solve_ot, NewtonParams, SourceMeasure};

/// Semi-discrete costs for N = 500, 2000, 8000.
fn costs(measure: &SourceMeasure) -> Vec<(usize, f64, usize)> {
    [500usize, 2000, 8000]
        .iter()
        .map(|&n| {
            let points = sunflower(n, 1.0);
            let sol = solve_ot(measure, &points, &vec![1.0; n], &NewtonParams::default())
                .unwrap()
                .into_result()
                .unwrap();
            (n, sol.cost, sol.iterations)
        })
        .collect()
}

fn check_convergence(name: &str, measured: &[(usize, f64, usize)], exact: f64) {
    let errors: Vec<f64> = measured.iter().map(|m| (m.1 - exact).abs()).collect();
    for (k, m) in measured.iter().enumerate() {
        eprintln!(
            "{name}: N = {:5}  cost = {:.7}  |cost − exact| = {:.3e}  ({} Newton steps)",
            m.0, m.1, errors[k], m.2
        );
    }
    let rates: Vec<f64> = (1..errors.len())
        .map(|k| (errors[k - 1] / errors[k]).ln() / 4f64.ln())
        .collect();
    eprintln!("{name}: observed rates (error ∝ N^−rate): {rates:.2?}");
    for k in 1..errors.len() {
        assert!(errors[k] < errors[k - 1], "{name}: error does not decrease: {errors:?}");
    }
    // Quantization error of N cells of area π/N: first order in 1/N.
    assert!(rates.iter().all(|&r| r > 0.8), "{name}: rates {rates:?}");
    // The error of the finest level is below 1% of the cost.
    assert!(errors[errors.len() - 1] < 1e-2 * exact, "{name}: {errors:?}");
}

/// The stereographic hemisphere density μ(r) = 2/(1 + r²)² (R = 1) against the uniform disk:
/// T(r) = r√(2/(1 + r²)), cost 0.0329512 (`docs/conventions.md`).
#[test]
fn hemisphere_density_to_uniform_points_converges_to_the_radial_cost() {
    let density = |x: [f64; 2]| {
        let r2 = x[0] * x[0] + x[1] * x[1];
        2.0 / ((1.0 + r2) * (1.0 + r2))
    };
    let exact = quadrature(
        &|r| {
            let t = r * (2.0 / (1.0 + r * r)).sqrt();
            (r - t).powi(2) * 2.0 / (1.0 + r * r).powi(2) * 2.0 * std::f64::consts::PI * r
        },
        0.0,
        1.0,
        200,
    );
    assert!((exact - 0.0329512).abs() < 1e-7, "quadrature {exact}");
    let measure = disk_measure(120, &density);
    check_convergence("hemisphere", &costs(&measure), exact);
}

/// μ(r) = c(1 + a r²) with a = 3, c = 1/(1 + a/2) (total mass π): F(r) = cπ(r² + a r⁴/2),
/// T(r) = √(c(r² + a r⁴/2)); the exact cost by 5-point Gauss–Legendre on 200 panels.
#[test]
fn quadratic_radial_density_to_uniform_points_converges_to_the_radial_cost() {
    let a = 3.0;
    let c = 1.0 / (1.0 + a / 2.0);
    let exact = quadrature(
        &|r| {
            let t = (c * (r * r + a * r.powi(4) / 2.0)).sqrt();
            (r - t).powi(2) * c * (1.0 + a * r * r) * 2.0 * std::f64::consts::PI * r
        },
        0.0,
        1.0,
        200,
    );
    let measure = disk_measure(120, &|x| c * (1.0 + a * (x[0] * x[0] + x[1] * x[1])));
    check_convergence("1 + 3r²", &costs(&measure), exact);
}

/// The dual value F = cost + Σ w_i (ν_i − μ(W_i)) (`OtSolution::dual_value`) is a lower bound on
/// W² at any heights and second-order accurate in the mass residual: stopped at a loose
/// tolerance it matches the cost of a tight solve far better than the cost C of the same
/// loose solve, which is off at first order; at a tight solve F and C coincide.
#[test]
fn dual_value_is_a_second_order_lower_bound() {
    let measure = disk_measure(60, &|x| {
        let r2 = x[0] * x[0] + x[1] * x[1];
        2.0 / ((1.0 + r2) * (1.0 + r2))
    });
    let n = 2000;
    let points = sunflower(n, 1.0);
    let solve = |tolerance: f64| {
        let params = NewtonParams {
            tolerance,
            ..NewtonParams::default()
        };
        solve_ot(&measure, &points, &vec![1.0; n], &params)
            .unwrap()
            .into_result()
            .unwrap()
    };
    let tight = solve(1e-10);
    let w2 = tight.cost;
    assert!(
        (tight.dual_value() - w2).abs() <= 1e-12 * w2,
        "{} {w2}",
        tight.dual_value()
    );
    // Stop the loose solves before convergence: every iterate of the tight solve's log is a
    // candidate; take the solves at tolerances just above the errors of its steps.
    let mut checked = 0;
    for record in &tight.log {
        let e = record.max_relative_error;
        if !(1e-8..=1e-2).contains(&e) {
            continue;
        }
        let loose = solve(e * 1.01);
        let (c, f) = (loose.cost, loose.dual_value());
        eprintln!(
            "mass error {:.1e}: |C − W²|/W² = {:.1e}, |F − W²|/W² = {:.1e}",
            loose.max_relative_error,
            (c - w2).abs() / w2,
            (f - w2).abs() / w2
        );
        assert!(f <= w2 * (1.0 + 1e-12), "dual value {f} above W² {w2}");
        // second order: F's error is below the square of the mass error (times a modest
        // constant), C's is not bound by it
        let e = loose.max_relative_error;
        assert!(
            (f - w2).abs() <= (10.0 * e * e).max(1e-12) * w2,
            "F {f} W² {w2} at {e:e}"
        );
        assert!((f - w2).abs() <= (c - w2).abs(), "F {f} C {c} W² {w2} at {e:e}");
        checked += 1;
    }
    assert!(
        checked >= 1,
        "no iterate between 1e-8 and 1e-2: {:?}",
        tight.log.iter().map(|r| r.max_relative_error).collect::<Vec<_>>()
    );
}
