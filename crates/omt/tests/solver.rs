//! Damped Newton solver: derivatives, closed forms, invariances and errors.

use crate::common::{disk_measure, sunflower, Rng};
use shapespace_omt::linear::{dense_hessian, LinearSolver};
use shapespace_omt::newton::{integrate_at_heights, kantorovich_energy, CellIntegrator, Start};
use shapespace_omt::{solve_ot, NewtonParams, OmtError, SourceMeasure, StartStrategy, StopReason};

fn voronoi_heights(points: &[[f64; 2]]) -> Vec<f64> {
    points.iter().map(|y| -0.5 * (y[0] * y[0] + y[1] * y[1])).collect()
}

fn integrators() -> [CellIntegrator; 2] {
    [CellIntegrator::BruteForce, CellIntegrator::Restricted]
}

/// ∂E/∂h_i = μ(W_i) − ν_i and ∂μ(W_i)/∂h_j = H_ij with H_ij = −μ(e_ij)/|y_i − y_j| (i ≠ j),
/// H_ii = −Σ_j H_ij: central differences of the exact energy and of the cell masses.
#[test]
fn gradient_and_hessian_match_finite_differences_in_the_heights() {
    let measure = disk_measure(10, &|x| 1.0 + 2.0 * (x[0] * x[0] + x[1] * x[1]));
    let mut rng = Rng(7);
    let points: Vec<[f64; 2]> = (0..30).map(|_| rng.in_disk(0.9)).collect();
    let targets = vec![measure.total_mass() / 30.0; 30];
    let mut heights = voronoi_heights(&points);
    for h in heights.iter_mut() {
        *h += 0.002 * (rng.next() - 0.5);
    }
    for integrator in integrators() {
        let cells = integrate_at_heights(&measure, &points, &heights, integrator).unwrap();
        assert!(
            cells.masses.iter().all(|&m| m > 1e-4),
            "{integrator:?}: a cell is (nearly) empty"
        );
        let hessian = dense_hessian(&points, &cells);
        let s = 1e-6;
        let mut max_gradient_error: f64 = 0.0;
        let mut max_hessian_error: f64 = 0.0;
        let hessian_scale = (0..30).map(|i| hessian[i][i]).fold(0.0, f64::max);
        for j in 0..30 {
            let mut plus = heights.clone();
            plus[j] += s;
            let mut minus = heights.clone();
            minus[j] -= s;
            let cp = integrate_at_heights(&measure, &points, &plus, integrator).unwrap();
            let cm = integrate_at_heights(&measure, &points, &minus, integrator).unwrap();
            let de = (kantorovich_energy(&points, &plus, &targets, &cp)
                - kantorovich_energy(&points, &minus, &targets, &cm))
                / (2.0 * s);
            max_gradient_error = max_gradient_error.max((de - (cells.masses[j] - targets[j])).abs());
            for i in 0..30 {
                let dm = (cp.masses[i] - cm.masses[i]) / (2.0 * s);
                max_hessian_error = max_hessian_error.max((dm - hessian[i][j]).abs() / hessian_scale);
            }
        }
        eprintln!("{integrator:?}: max |dE/dh - G| = {max_gradient_error:e}, max |dm/dh - H|/max H_ii = {max_hessian_error:e}");
        // Masses are O(0.1) and the energy is O(1): central differences with s = 1e-6 are accurate to
        // ~1e-9 here (rounding ~1e-16/1e-6 plus the kinks of the piecewise-quadratic mass function).
        assert!(
            max_gradient_error < 1e-8,
            "{integrator:?}: gradient error {max_gradient_error:e}"
        );
        assert!(
            max_hessian_error < 1e-6,
            "{integrator:?}: Hessian error {max_hessian_error:e}"
        );
        // The weight-variable Hessian carries a factor ½ (w = 2h + |y|²): with the factor of `docs/conventions.md`
        // applied to h and not to w, a wrong factor would give an error of 50%.
    }
}

/// Uniform density on [0,1]², a k×k grid of points with equal masses: the Voronoi start is
/// optimal, every cell is a square of side 1/k around its point, cost = k²·(1/k)⁴/6 = 1/(6k²).
#[test]
fn regular_grid_on_the_unit_square_is_solved_by_the_voronoi_start() {
    let measure = SourceMeasure::unit_square().unwrap();
    for integrator in integrators() {
        for k in [1usize, 2, 8] {
            let points: Vec<[f64; 2]> = (0..k * k)
                .map(|i| [((i % k) as f64 + 0.5) / k as f64, ((i / k) as f64 + 0.5) / k as f64])
                .collect();
            let masses = vec![1.0; k * k];
            let params = NewtonParams {
                integrator,
                ..Default::default()
            };
            let sol = solve_ot(&measure, &points, &masses, &params).unwrap();
            assert!(
                sol.converged() && sol.iterations == 0,
                "{integrator:?} k={k}: {:?}",
                sol.stop
            );
            assert!((sol.mass_scale - 1.0 / (k * k) as f64).abs() < 1e-15);
            let expected = 1.0 / (6.0 * (k * k) as f64);
            assert!(
                (sol.cost - expected).abs() < 1e-15,
                "{integrator:?} k={k}: cost {} vs {expected}",
                sol.cost
            );
            for (i, c) in sol.centroids().iter().enumerate() {
                let c = c.unwrap();
                assert!((c[0] - points[i][0]).abs() < 1e-14 && (c[1] - points[i][1]).abs() < 1e-14);
            }
        }
    }
}

/// Two points on the unit square with masses 0.3 and 0.7: the cells are x ≤ 0.3 and x ≥ 0.3;
/// per box [a,b]×[0,1] around (c, ½): ∫(x−c)² = ((b−c)³ − (a−c)³)/3 and ∫(y−½)² = (b−a)/12.
#[test]
fn two_points_on_the_unit_square_closed_form() {
    let measure = SourceMeasure::unit_square().unwrap();
    let points = [[0.25, 0.5], [0.75, 0.5]];
    let box_cost = |a: f64, b: f64, c: f64| ((b - c).powi(3) - (a - c).powi(3)) / 3.0 + (b - a) / 12.0;
    let expected = box_cost(0.0, 0.3, 0.25) + box_cost(0.3, 1.0, 0.75);
    for integrator in integrators() {
        for solver in [
            LinearSolver::Cholesky,
            LinearSolver::ConjugateGradient {
                relative_tolerance: 1e-12,
                max_iterations: 100,
            },
        ] {
            let params = NewtonParams {
                integrator,
                linear_solver: solver,
                tolerance: 1e-12,
                ..Default::default()
            };
            let sol = solve_ot(&measure, &points, &[0.3, 0.7], &params)
                .unwrap()
                .into_result()
                .unwrap();
            assert!((sol.cells.masses[0] - 0.3).abs() < 1e-12);
            assert!((sol.cost - expected).abs() < 1e-12, "{} vs {expected}", sol.cost);
            // The cells meet at x = 0.3: ⟨x,y0⟩+h0 = ⟨x,y1⟩+h1 there.
            let x = 0.3;
            assert!((x * points[0][0] + sol.heights[0] - (x * points[1][0] + sol.heights[1])).abs() < 1e-12);
        }
    }
}

/// One point: its cell is Ω, the cost is ∫|x − y|² dμ = ∫|x|² − 2⟨y, ∫x⟩ + |y|² μ(Ω).
#[test]
fn one_point_owns_the_whole_domain() {
    let measure = SourceMeasure::unit_square().unwrap();
    for integrator in integrators() {
        let params = NewtonParams {
            integrator,
            ..Default::default()
        };
        let sol = solve_ot(&measure, &[[2.0, -1.0]], &[5.0], &params).unwrap();
        assert!(sol.converged() && sol.iterations == 0);
        assert!((sol.mass_scale - 0.2).abs() < 1e-15);
        // ∫|x|² over the unit square = 2/3, ∫x = (½, ½), |y|² = 5.
        let expected = 2.0 / 3.0 - 2.0 * (2.0 * 0.5 - 1.0 * 0.5) + 5.0;
        assert!((sol.cost - expected).abs() < 1e-13, "{} vs {expected}", sol.cost);
    }
}

/// Random points in the disk, nonuniform density: the solver reaches the tolerance, masses are
/// right, both integrators agree, and a warm start from the solution takes 0 steps.
#[test]
fn random_points_converge_and_integrators_agree() {
    let measure = disk_measure(12, &|x| 1.0 + 4.0 * x[0] * x[0]);
    let mut rng = Rng(11);
    let points: Vec<[f64; 2]> = (0..200).map(|_| rng.in_disk(1.0)).collect();
    let masses: Vec<f64> = (0..200).map(|_| 0.5 + rng.next()).collect();
    let mut costs = Vec::new();
    for integrator in integrators() {
        let params = NewtonParams {
            integrator,
            tolerance: 1e-9,
            ..Default::default()
        };
        let sol = solve_ot(&measure, &points, &masses, &params)
            .unwrap()
            .into_result()
            .unwrap();
        assert!(
            sol.iterations >= 2 && sol.iterations < 30,
            "{} iterations",
            sol.iterations
        );
        assert!(sol.max_relative_error <= 1e-9);
        for i in 0..200 {
            assert!((sol.cells.masses[i] - sol.target_masses[i]).abs() <= 1e-9 * sol.target_masses[i]);
        }
        // The last steps are full Newton steps and converge quadratically.
        let last = sol.log.last().unwrap();
        assert_eq!(last.step, 1.0);
        costs.push(sol.cost);
        let warm = NewtonParams {
            initial_heights: Some(sol.heights.clone()),
            ..params.clone()
        };
        let again = solve_ot(&measure, &points, &masses, &warm).unwrap();
        assert_eq!(again.start, Start::Warm);
        assert_eq!(again.iterations, 0);
    }
    assert!((costs[0] - costs[1]).abs() < 1e-12 * costs[0], "{costs:?}");
}

/// Scaling domain and points by s scales the cost by s⁴ (density 1) and changes nothing else.
#[test]
fn scale_invariance() {
    let mut rng = Rng(3);
    let points: Vec<[f64; 2]> = (0..60).map(|_| rng.in_disk(0.8)).collect();
    let masses = vec![1.0; 60];
    let base = {
        let measure = SourceMeasure::unit_disk(64).unwrap();
        solve_ot(
            &measure,
            &points,
            &masses,
            &NewtonParams {
                tolerance: 1e-10,
                ..Default::default()
            },
        )
        .unwrap()
    };
    assert!(base.converged());
    for s in [1e-6, 1e6] {
        let polygon: Vec<[f64; 2]> = (0..64)
            .map(|k| {
                let t = 2.0 * std::f64::consts::PI * k as f64 / 64.0;
                [s * t.cos(), s * t.sin()]
            })
            .collect();
        let measure = SourceMeasure::uniform_polygon(&polygon, 1.0).unwrap();
        let scaled: Vec<[f64; 2]> = points.iter().map(|p| [s * p[0], s * p[1]]).collect();
        let sol = solve_ot(
            &measure,
            &scaled,
            &masses,
            &NewtonParams {
                tolerance: 1e-10,
                ..Default::default()
            },
        )
        .unwrap();
        assert!(sol.converged(), "s = {s}: {:?}", sol.stop);
        assert_eq!(sol.iterations, base.iterations, "s = {s}");
        let ratio = sol.cost / (base.cost * s.powi(4));
        assert!((ratio - 1.0).abs() < 1e-8, "s = {s}: cost ratio {ratio}");
    }
}

#[test]
fn invalid_input_is_rejected() {
    let measure = SourceMeasure::unit_square().unwrap();
    let p = NewtonParams::default();
    assert!(matches!(
        solve_ot(&measure, &[], &[], &p),
        Err(OmtError::InvalidInput(_))
    ));
    assert!(matches!(
        solve_ot(&measure, &[[0.5, 0.5]], &[0.0], &p),
        Err(OmtError::InvalidInput(_))
    ));
    assert!(matches!(
        solve_ot(&measure, &[[0.5, 0.5]], &[f64::NAN], &p),
        Err(OmtError::InvalidInput(_))
    ));
    assert!(matches!(
        solve_ot(&measure, &[[f64::INFINITY, 0.5]], &[1.0], &p),
        Err(OmtError::InvalidInput(_))
    ));
    assert!(matches!(
        solve_ot(&measure, &[[0.5, 0.5], [0.2, 0.2]], &[1.0], &p),
        Err(OmtError::InvalidInput(_))
    ));
    assert!(matches!(
        solve_ot(&measure, &[[0.5, 0.5], [0.2, 0.2], [0.5, 0.5]], &[1.0; 3], &p),
        Err(OmtError::DuplicatePoints { i: 0, j: 2 })
    ));
    // Masses each finite whose rescaling to the source's mass leaves f64: a sum that overflows
    // (the targets would all be 0 and the solve stall), and subnormal masses whose scale
    // overflows. Masses near either end of the range whose rescaling stays finite are solved.
    let points = [[0.5, 0.5], [0.2, 0.2], [0.8, 0.3]];
    for masses in [[1e308; 3], [5e-324; 3]] {
        match solve_ot(&measure, &points, &masses, &p) {
            Err(OmtError::InvalidInput(m)) => assert!(m.contains("rescale the masses"), "{m}"),
            other => panic!("masses {masses:?}: {:?}", other.map(|s| s.stop)),
        }
    }
    // one subnormal mass beside ordinary ones: the sum and the scale are fine, that mass's
    // target underflows; the error names it
    match solve_ot(&measure, &points, &[1.0, 1.0, 5e-324], &p) {
        Err(OmtError::InvalidInput(m)) => assert!(m.contains("target mass 2 is") && m.contains("too small"), "{m}"),
        other => panic!("{:?}", other.map(|s| s.stop)),
    }
    for scale in [1e300, 1e-300] {
        let masses = [scale, 3.0 * scale, 2.0 * scale];
        let sol = solve_ot(&measure, &points, &masses, &p).unwrap();
        assert!(sol.converged(), "scale {scale:e}");
        assert!((sol.cells.masses[1] / sol.cells.masses[0] - 3.0).abs() < 1e-5);
    }
    // Parameters `p` must be rejected as invalid input whose message contains `needle`.
    let rejected = |p: NewtonParams, needle: &str, case: String| match solve_ot(
        &measure,
        &[[0.5, 0.5], [0.2, 0.2]],
        &[1.0, 1.0],
        &p,
    ) {
        Err(OmtError::InvalidInput(m)) => assert!(m.contains(needle), "{m}"),
        other => panic!("{case}: {:?}", other.map(|s| s.stop)),
    };
    // A relative mass tolerance outside (0, 1) bounds nothing (1e300 "converged" in 0 steps).
    for tolerance in [0.0, 1.0, 1e300, f64::NAN, f64::INFINITY] {
        let p = NewtonParams {
            tolerance,
            ..Default::default()
        };
        rejected(p, "(0, 1)", format!("tolerance {tolerance}"));
    }
    // So does a coarse levels' tolerance outside (0, 1) (the coarse solves would fail and the
    // coarse-to-fine start vanish silently).
    for coarse_tolerance in [0.0, 1.0, f64::NAN, -1e-3] {
        let p = NewtonParams {
            coarse_tolerance,
            ..Default::default()
        };
        rejected(p, "coarse tolerance", format!("coarse tolerance {coarse_tolerance}"));
    }
    // A cap of the intermediate targets at or below 1 would aim no step anywhere.
    for cap in [1.0, 0.5, -3.0, f64::NAN, f64::INFINITY] {
        let p = NewtonParams {
            target_ratio_cap: Some(cap),
            ..Default::default()
        };
        rejected(p, "target ratio cap", format!("cap {cap}"));
    }
}

/// The iteration cap is reported, and `into_result` turns it into `NoConvergence`.
#[test]
fn iteration_cap_is_reported() {
    let measure = disk_measure(8, &|x| if x[0] > 0.0 { 100.0 } else { 1.0 });
    let points = sunflower(300, 1.0);
    let params = NewtonParams {
        max_iterations: 1,
        density_continuation: None,
        ..Default::default()
    };
    let sol = solve_ot(&measure, &points, &vec![1.0; 300], &params).unwrap();
    assert_eq!(sol.stop, StopReason::IterationCap);
    assert_eq!(sol.iterations, 1);
    assert!(matches!(
        sol.into_result(),
        Err(OmtError::NoConvergence { iterations: 1, .. })
    ));
}

/// A deadline that has passed stops every path of the solve before its first step, as
/// `TimeLimit` (not as a stall of the continuation it interrupted, and without trying another
/// start); one far ahead changes nothing, bit for bit.
#[test]
fn a_passed_deadline_stops_every_path_and_a_distant_one_changes_nothing() {
    // contrast 1e3: the coarse-to-fine start (Auto) or the density continuation (Voronoi)
    let measure = disk_measure(8, &|x| if x[0] > 0.0 { 1e3 } else { 1.0 });
    let points = sunflower(1500, 1.0);
    let masses = vec![1.0; points.len()];
    for (start_strategy, density_continuation) in [
        (StartStrategy::Auto, Some(10.0)),
        (StartStrategy::Voronoi, Some(10.0)),
        (StartStrategy::Voronoi, None),
    ] {
        let params = NewtonParams {
            start_strategy,
            density_continuation,
            ..Default::default()
        };
        let passed = NewtonParams {
            deadline: Some(std::time::Instant::now()),
            ..params.clone()
        };
        // (the coarse-to-fine start has no start to report: an error saying where it stopped)
        match solve_ot(&measure, &points, &masses, &passed) {
            Ok(sol) => {
                assert_eq!(
                    sol.stop,
                    StopReason::TimeLimit,
                    "{start_strategy:?} {density_continuation:?}"
                );
                assert_eq!(sol.all_iterations(), 0, "{start_strategy:?} {density_continuation:?}");
                assert!(matches!(sol.into_result(), Err(OmtError::NoConvergence { .. })));
            }
            Err(e) => assert!(
                matches!(&e, OmtError::TimeLimit(w) if w.contains("level of the coarse-to-fine start")),
                "{start_strategy:?} {density_continuation:?}: {e}"
            ),
        }
        let free = solve_ot(&measure, &points, &masses, &params).unwrap();
        let distant = NewtonParams {
            deadline: Some(std::time::Instant::now() + std::time::Duration::from_secs(3600)),
            ..params
        };
        let timed = solve_ot(&measure, &points, &masses, &distant).unwrap();
        // a deadline in the middle of the solve: converged, or stopped on it, whatever the
        // path was doing then
        if free.converged() {
            for ms in [1, 3, 10, 30, 100] {
                let mid = NewtonParams {
                    deadline: Some(std::time::Instant::now() + std::time::Duration::from_millis(ms)),
                    ..distant.clone()
                };
                match solve_ot(&measure, &points, &masses, &mid) {
                    Ok(sol) => assert!(
                        sol.converged() || sol.stop == StopReason::TimeLimit,
                        "{start_strategy:?} {density_continuation:?} {ms} ms: {}",
                        sol.stop
                    ),
                    Err(e) => assert!(matches!(e, OmtError::TimeLimit(_)), "{ms} ms: {e}"),
                }
            }
        }
        assert_eq!(free.stop, timed.stop);
        assert_eq!(free.heights, timed.heights);
        assert_eq!(free.all_iterations(), timed.all_iterations());
    }
}

/// The coarse-to-fine start reaches the same solution as the Voronoi start, from a start with no
/// empty cell (its prolongation guarantees that; a heuristic lift would fall back to the
/// Voronoi start on these points).
#[test]
fn coarse_to_fine_start_reaches_the_same_solution() {
    let measure = disk_measure(20, &|x| 1.0 + x[1] * x[1]);
    let mut rng = Rng(21);
    let points: Vec<[f64; 2]> = (0..3000).map(|_| rng.in_disk(1.0)).collect();
    let masses = vec![1.0; 3000];
    let plain = solve_ot(
        &measure,
        &points,
        &masses,
        &NewtonParams {
            tolerance: 1e-9,
            start_strategy: StartStrategy::Voronoi,
            ..Default::default()
        },
    )
    .unwrap();
    assert_eq!(plain.start, Start::Voronoi);
    let params = NewtonParams {
        tolerance: 1e-9,
        start_strategy: StartStrategy::CoarseToFine,
        ..Default::default()
    };
    let multi = solve_ot(&measure, &points, &masses, &params).unwrap();
    eprintln!(
        "Voronoi start: {} steps; {:?}: {} steps",
        plain.iterations, multi.start, multi.iterations
    );
    assert!(plain.converged() && multi.converged());
    // Pairwise merging until at most N/4 groups remain: 3000 → ≤ 750.
    assert!(
        matches!(multi.start, Start::CoarseToFine { coarse_points, .. } if (375..=750).contains(&coarse_points)),
        "{:?}",
        multi.start
    );
    assert!((plain.cost - multi.cost).abs() < 1e-9 * plain.cost);
    // Heights are unique up to a constant.
    let shift = plain.heights[0] - multi.heights[0];
    assert!(plain
        .heights
        .iter()
        .zip(&multi.heights)
        .all(|(a, b)| (a - b - shift).abs() < 1e-6));
}
