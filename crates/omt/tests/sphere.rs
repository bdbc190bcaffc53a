//! Semi-discrete OT on the sphere: closed forms, oracles, derivatives, invariances and errors.

use shapespace_omt::sphere::SphereStart;
use shapespace_omt::sphere::{
    fibonacci_sphere, icosphere, random_sphere_points, spherical_area, SphereCells, SphereIntegrator, SphereMeasure,
};
use shapespace_omt::synthetic::uniform01;
use shapespace_omt::{solve_sphere_ot, OmtError, SphereOtParams, StopReason};

use std::f64::consts::PI;

fn dot(a: [f64; 3], b: [f64; 3]) -> f64 {
    a[0] * b[0] + a[1] * b[1] + a[2] * b[2]
}

fn unit(a: [f64; 3]) -> [f64; 3] {
    let r = dot(a, a).sqrt();
    [a[0] / r, a[1] / r, a[2] / r]
}

/// ρ ∝ 1 + a·z on the sphere (a zonal density), on an icosphere.
fn zonal_measure(subdivisions: usize, a: f64) -> SphereMeasure {
    let (v, t) = icosphere(subdivisions);
    SphereMeasure::from_spherical_density(v, t, |x| 1.0 + a * x[2]).unwrap()
}

/// Small random heights, reproducible.
fn jittered_heights(n: usize, amplitude: f64, seed: u64) -> Vec<f64> {
    let mut s = seed;
    (0..n).map(|_| amplitude * (uniform01(&mut s) - 0.5)).collect()
}

/// Uniform density against N equal-mass points: every cell, measured independently as the
/// spherical area of its pieces projected radially on S², has area 4π/N (up to the O(h²) of
/// the flat triangles).
#[test]
fn uniform_density_to_equal_masses_gives_equal_spherical_areas() {
    let measure = SphereMeasure::uniform_icosphere(4).unwrap();
    assert!((measure.total_mass() - 4.0 * PI).abs() < 1e-12);
    let n = 150;
    let points = random_sphere_points(n, 3);
    let solution = solve_sphere_ot(&measure, &points, &vec![1.0; n], &SphereOtParams::default())
        .unwrap()
        .into_result()
        .unwrap();
    assert!(solution.max_relative_error <= 1e-6);
    let integrator = SphereIntegrator::new(&measure, &solution.points);
    let mut areas = vec![0.0; n];
    for piece in integrator.pieces(&solution.heights) {
        let p: Vec<[f64; 3]> = piece.polygon.iter().map(|&x| unit(x)).collect();
        for k in 1..p.len() - 1 {
            areas[piece.site as usize] += spherical_area(p[0], p[k], p[k + 1]);
        }
    }
    let target = 4.0 * PI / n as f64;
    let worst = areas.iter().map(|a| (a / target - 1.0).abs()).fold(0.0, f64::max);
    // the Voronoi cells of random points differ by tens of percent; the flat triangles' O(h²)
    // (h ≈ 0.07 at 4 subdivisions) is what is left: 3.5e-5 measured
    assert!(
        worst < 2e-4,
        "largest relative deviation of a cell's spherical area {worst:e}"
    );
    let voronoi = SphereIntegrator::new(&measure, &solution.points).integrate(&vec![0.0; n]);
    let spread = voronoi
        .masses
        .iter()
        .map(|m| (m / target - 1.0).abs())
        .fold(0.0, f64::max);
    assert!(
        spread > 0.2,
        "the start must be far from the answer for the test to mean something"
    );
}

/// Two targets at the poles: the boundary is the plane z = z₀ with the cap's mass
/// 2π[(1 − z₀) + a(1 − z₀²)/2] = ν_N μ(S²)/(ν_N + ν_S) for ρ = 1 + a z, and
/// h_S − h_N = 2 z₀ (⟨x, N − S⟩ = h_S − h_N on the boundary). The cost is
/// 2π ∫ (2 ∓ 2z)(1 + a z) dz over the two parts.
#[test]
fn two_poles_against_a_zonal_density_match_the_closed_form() {
    let a = 0.6;
    let measure = zonal_measure(5, a);
    let (nu_n, nu_s) = (0.3, 0.7);
    let points = [[0.0, 0.0, 1.0], [0.0, 0.0, -1.0]];
    let solution = solve_sphere_ot(&measure, &points, &[nu_n, nu_s], &SphereOtParams::default())
        .unwrap()
        .into_result()
        .unwrap();
    // (1 − z₀) + a(1 − z₀²)/2 = 2 ν_N/(ν_N+ν_S): a quadratic in z₀
    let f = 2.0 * nu_n / (nu_n + nu_s);
    // −(a/2) z² − z + (1 + a/2 − f) = 0
    let (qa, qb, qc) = (-a / 2.0, -1.0, 1.0 + a / 2.0 - f);
    let z0 = (-qb - (qb * qb - 4.0 * qa * qc).sqrt()) / (2.0 * qa);
    assert!(z0.abs() < 1.0);
    let z_computed = 0.5 * (solution.heights[1] - solution.heights[0]);
    // measured: −1.2e-4 (the flat triangles cut by the plane), cost −1.9e-4 relative
    assert!((z_computed - z0).abs() < 2e-4, "boundary z {z_computed} against {z0}");
    // cost by Simpson's rule on both parts
    let simpson = |g: &dyn Fn(f64) -> f64, lo: f64, hi: f64| {
        let k = 2000;
        let h = (hi - lo) / k as f64;
        (0..=k)
            .map(|i| {
                let w = if i == 0 || i == k {
                    1.0
                } else if i % 2 == 1 {
                    4.0
                } else {
                    2.0
                };
                w * g(lo + i as f64 * h)
            })
            .sum::<f64>()
            * h
            / 3.0
    };
    let cost = 2.0
        * PI
        * (simpson(&|z| (2.0 - 2.0 * z) * (1.0 + a * z), z0, 1.0)
            + simpson(&|z| (2.0 + 2.0 * z) * (1.0 + a * z), -1.0, z0));
    assert!(
        (solution.cost / cost - 1.0).abs() < 3e-4,
        "cost {} against {cost}",
        solution.cost
    );
    assert!(solution.dual_value() <= solution.cost + 1e-9);
}

/// ρ ∝ 1 + a z against rings of equal-mass points at the centres of equal-area bands (a
/// discretized uniform target): the monotone meridian map sends the source band between the
/// cumulative masses (k−1)/R and k/R to ring k, so the μ-mean height z of ring k's cells is that
/// band's mean, ∫ z dμ / ∫ dμ over it. The azimuthal waviness of the cells' boundaries is what
/// the tolerance allows for; against the mean of a uniform source (a = 0) it fails by far.
#[test]
fn zonal_density_against_rings_follows_the_monotone_rearrangement() {
    let a = 0.8;
    let measure = zonal_measure(5, a);
    let (rings, per_ring) = (10usize, 30usize);
    let mut points = Vec::new();
    for k in 0..rings {
        // equal-area bands of the uniform target: z from 1 down to −1 in steps 2/R
        let z = 1.0 - (2 * k + 1) as f64 / rings as f64;
        let r = (1.0 - z * z).sqrt();
        for j in 0..per_ring {
            let t = 2.0 * PI * (j as f64 + 0.5 * (k % 2) as f64) / per_ring as f64;
            points.push([r * t.cos(), r * t.sin(), z]);
        }
    }
    let n = points.len();
    let solution = solve_sphere_ot(&measure, &points, &vec![1.0; n], &SphereOtParams::default())
        .unwrap()
        .into_result()
        .unwrap();
    // source: mass above height z (per 2π) M(z) = (1 − z) + a(1 − z²)/2, total 2; moment of z
    // above z: ∫_z^1 s(1 + a s) ds
    let mass_above = |a: f64, z: f64| (1.0 - z) + a * (1.0 - z * z) / 2.0;
    let moment_above = |a: f64, z: f64| (1.0 - z * z) / 2.0 + a * (1.0 - z * z * z) / 3.0;
    let level = |a: f64, m: f64| {
        // the z with mass_above(z) = m, by bisection (mass_above decreases in z)
        let (mut lo, mut hi) = (-1.0f64, 1.0f64);
        for _ in 0..100 {
            let mid = 0.5 * (lo + hi);
            if mass_above(a, mid) > m {
                lo = mid;
            } else {
                hi = mid;
            }
        }
        0.5 * (lo + hi)
    };
    let band_mean = |a: f64, k: usize| {
        let top = level(a, 2.0 * k as f64 / rings as f64);
        let bottom = level(a, 2.0 * (k + 1) as f64 / rings as f64);
        (moment_above(a, bottom) - moment_above(a, top)) / (mass_above(a, bottom) - mass_above(a, top))
    };
    let mut worst: f64 = 0.0;
    let mut against_uniform: f64 = 0.0;
    for k in 0..rings {
        let cells = k * per_ring..(k + 1) * per_ring;
        let mass: f64 = cells.clone().map(|i| solution.cells.masses[i]).sum();
        let zm: f64 = cells.map(|i| solution.cells.first_moments[i][2]).sum::<f64>() / mass;
        worst = worst.max((zm - band_mean(a, k)).abs());
        against_uniform = against_uniform.max((zm - band_mean(0.0, k)).abs());
    }
    // measured 3.7e-4; against the uniform source's bands 0.4
    assert!(worst < 1e-3, "largest deviation of a ring's mean height {worst:e}");
    assert!(against_uniform > 100.0 * 1e-3, "{against_uniform:e}");
}

/// Σ_i μ(W_i) = μ(S²) at any heights, with the fast and the brute-force candidates.
#[test]
fn cell_masses_conserve_the_source_mass() {
    let measure = zonal_measure(4, 0.5);
    let total = measure.total_mass();
    let points = random_sphere_points(300, 11);
    for heights in [vec![0.0; 300], jittered_heights(300, 0.02, 5)] {
        for integrator in [
            SphereIntegrator::new(&measure, &points),
            SphereIntegrator::brute_force(&measure, &points),
        ] {
            let cells = integrator.integrate(&heights);
            let sum: f64 = cells.masses.iter().sum();
            assert!((sum / total - 1.0).abs() < 1e-12, "{sum} against {total}");
        }
    }
}

/// The candidate search against every site in every triangle (the O(N·M) oracle): the same
/// masses, moments and edges, with the vertices off S² by up to the accepted 1e-6 (the tree's
/// bounds scale by the corners' norms).
#[test]
fn fast_candidates_agree_with_brute_force() {
    let (v, t) = icosphere(3);
    let mut s = 71u64;
    let v: Vec<[f64; 3]> = v
        .into_iter()
        .map(|p| p.map(|c| c * (1.0 + 9e-7 * (2.0 * uniform01(&mut s) - 1.0))))
        .collect();
    let measure = SphereMeasure::from_spherical_density(v, t, |x| 1.0 + 0.5 * x[2]).unwrap();
    let points = random_sphere_points(120, 17);
    let heights = jittered_heights(120, 0.05, 9);
    let fast = SphereIntegrator::new(&measure, &points).integrate(&heights);
    let slow = SphereIntegrator::brute_force(&measure, &points).integrate(&heights);
    assert_same_cells(&fast, &slow);
}

/// The fast integration against the brute-force one: far fewer candidates, the same masses,
/// second moments and Hessian entries.
fn assert_same_cells(fast: &SphereCells, slow: &SphereCells) {
    assert!(fast.mean_candidates < 0.2 * slow.mean_candidates);
    for i in 0..slow.masses.len() {
        assert!((fast.masses[i] - slow.masses[i]).abs() < 1e-13, "cell {i}");
        assert!((fast.second_moments[i] - slow.second_moments[i]).abs() < 1e-13);
    }
    assert_eq!(fast.hessian.len(), slow.hessian.len());
    for (e, f) in fast.hessian.iter().zip(&slow.hessian) {
        assert_eq!((e.0, e.1), (f.0, f.1));
        assert!((e.2 - f.2).abs() < 1e-12 * (1.0 + f.2));
    }
}

/// The same oracle under heights that vary strongly and smoothly over S² (a slope and a
/// curvature of order 0.3, as at the solution for the conformal image of an ellipsoid 1:1:2, plus
/// a jitter): the site tree's tilted bounds must not lose a cell's piece.
#[test]
fn fast_candidates_agree_with_brute_force_under_strongly_varying_heights() {
    let measure = zonal_measure(3, 0.5);
    let points = random_sphere_points(150, 23);
    let jitter = jittered_heights(150, 0.02, 13);
    let heights: Vec<f64> = points
        .iter()
        .zip(&jitter)
        .map(|(p, j)| 0.3 * p[2] * p[2] + 0.2 * p[0] - 0.1 * p[1] * p[2] + j)
        .collect();
    let fast = SphereIntegrator::new(&measure, &points).integrate(&heights);
    let slow = SphereIntegrator::brute_force(&measure, &points).integrate(&heights);
    // (the heights empty some cells and enlarge others)
    assert!(fast.masses.iter().filter(|&&m| m == 0.0).count() > 0);
    assert_same_cells(&fast, &slow);
}

/// Monte-Carlo oracle: points sampled on the flat triangles in proportion to their mass and
/// assigned by argmax ⟨x, y_i⟩ + h_i over all sites; the fractions match the cell masses within
/// 5 standard deviations.
#[test]
fn cell_masses_match_monte_carlo_assignment() {
    let measure = zonal_measure(3, 0.7);
    let n = 40;
    let points = random_sphere_points(n, 23);
    let heights = jittered_heights(n, 0.1, 4);
    let cells = SphereIntegrator::new(&measure, &points).integrate(&heights);
    let total = measure.total_mass();
    let masses = measure.triangle_masses();
    let mut cumulative = Vec::with_capacity(masses.len());
    let mut acc = 0.0;
    for m in &masses {
        acc += m;
        cumulative.push(acc);
    }
    let samples = 200_000;
    let mut counts = vec![0usize; n];
    let mut s = 99u64;
    for _ in 0..samples {
        let u = uniform01(&mut s) * acc;
        let t = cumulative.partition_point(|&c| c < u).min(masses.len() - 1);
        let (mut r1, mut r2) = (uniform01(&mut s), uniform01(&mut s));
        if r1 + r2 > 1.0 {
            (r1, r2) = (1.0 - r1, 1.0 - r2);
        }
        let [a, b, c] = measure.triangles[t].map(|v| measure.vertices[v as usize]);
        let x: [f64; 3] = std::array::from_fn(|k| a[k] + r1 * (b[k] - a[k]) + r2 * (c[k] - a[k]));
        let owner = (0..n)
            .max_by(|&i, &j| (dot(x, points[i]) + heights[i]).total_cmp(&(dot(x, points[j]) + heights[j])))
            .unwrap();
        counts[owner] += 1;
    }
    let mut empty_or_small = 0;
    for i in 0..n {
        let p = cells.masses[i] / total;
        let sigma = (p * (1.0 - p) / samples as f64).sqrt();
        let fraction = counts[i] as f64 / samples as f64;
        assert!(
            (fraction - p).abs() <= 5.0 * sigma + 1e-9,
            "cell {i}: sampled {fraction}, computed {p} (σ {sigma:e})"
        );
        if p < 1e-3 {
            empty_or_small += 1;
        }
    }
    assert!(empty_or_small < n / 2);
}

/// ∂μ(W_i)/∂h_j against the assembled Hessian: H_ij = −Σ_T ρ_T ℓ_T / |Π_T(y_i − y_j)| (i ≠ j),
/// H_ii = −Σ_j H_ij, by central differences. With unequal heights the plain |y_i − y_j| of the
/// planar formula is off by more than the tolerance (checked, so the test can tell them apart).
#[test]
fn hessian_matches_finite_differences() {
    let measure = zonal_measure(4, 0.5);
    let n = 40;
    let points = random_sphere_points(n, 31);
    let heights = jittered_heights(n, 0.3, 8);
    let integrator = SphereIntegrator::new(&measure, &points);
    let cells = integrator.integrate(&heights);
    let mut analytic = vec![vec![0.0; n]; n];
    let mut planar = vec![vec![0.0; n]; n];
    for (&(i, j, c), &(_, _, em)) in cells.hessian.iter().zip(&cells.edge_masses) {
        let (i, j) = (i as usize, j as usize);
        analytic[i][j] -= c;
        analytic[j][i] -= c;
        analytic[i][i] += c;
        analytic[j][j] += c;
        let d: f64 = (0..3)
            .map(|k| (points[i][k] - points[j][k]).powi(2))
            .sum::<f64>()
            .sqrt();
        planar[i][j] -= em / d;
    }
    let eps = 1e-6;
    let mut worst: f64 = 0.0;
    let mut planar_worst: f64 = 0.0;
    let scale = analytic
        .iter()
        .map(|r| r.iter().fold(0.0f64, |m, v| m.max(v.abs())))
        .fold(0.0, f64::max);
    for j in 0..n {
        let mut plus = heights.clone();
        plus[j] += eps;
        let mut minus = heights.clone();
        minus[j] -= eps;
        let (mp, mm) = (integrator.integrate(&plus).masses, integrator.integrate(&minus).masses);
        for i in 0..n {
            // H_ij = ∂μ(W_i)/∂h_j (raising h_j grows W_j and shrinks its neighbours)
            let fd = (mp[i] - mm[i]) / (2.0 * eps);
            worst = worst.max((fd - analytic[i][j]).abs());
            if i < j && planar[i][j] != 0.0 {
                planar_worst = planar_worst.max((fd - planar[i][j]).abs());
            }
        }
    }
    // measured: 2.8e-10 against a scale of 9.3; the planar formula is off by 0.16
    assert!(
        worst < 1e-7 * scale,
        "finite differences off by {worst:e} (scale {scale:e})"
    );
    assert!(planar_worst > 1e-3 * scale, "{planar_worst:e} against {worst:e}");
}

/// Rotating the source and the targets together leaves the cost and the heights unchanged.
#[test]
fn rotation_leaves_cost_and_heights_unchanged() {
    let (v, t) = icosphere(4);
    let density = |x: [f64; 3]| 1.0 + 0.5 * x[2] + 0.3 * x[0] * x[1];
    let measure = SphereMeasure::from_spherical_density(v.clone(), t.clone(), density).unwrap();
    let points = fibonacci_sphere(200);
    let mut s = 3u64;
    let masses: Vec<f64> = (0..200).map(|_| 0.5 + uniform01(&mut s)).collect();
    // a rotation from a unit quaternion
    let q = {
        let q = [0.3, -0.5, 0.7, 0.2];
        let r = q.iter().map(|x| x * x).sum::<f64>().sqrt();
        q.map(|x| x / r)
    };
    let (w, x, y, z) = (q[0], q[1], q[2], q[3]);
    let m = [
        [
            1.0 - 2.0 * (y * y + z * z),
            2.0 * (x * y - w * z),
            2.0 * (x * z + w * y),
        ],
        [
            2.0 * (x * y + w * z),
            1.0 - 2.0 * (x * x + z * z),
            2.0 * (y * z - w * x),
        ],
        [
            2.0 * (x * z - w * y),
            2.0 * (y * z + w * x),
            1.0 - 2.0 * (x * x + y * y),
        ],
    ];
    let rotate = |p: [f64; 3]| std::array::from_fn::<f64, 3, _>(|r| dot(m[r], p));
    let rotated = SphereMeasure::new(
        v.iter().map(|&p| unit(rotate(p))).collect(),
        t,
        measure.densities.clone(),
    )
    .unwrap();
    let rotated_points: Vec<[f64; 3]> = points.iter().map(|&p| rotate(p)).collect();
    let params = SphereOtParams {
        tolerance: 1e-9,
        ..Default::default()
    };
    let a = solve_sphere_ot(&measure, &points, &masses, &params)
        .unwrap()
        .into_result()
        .unwrap();
    let b = solve_sphere_ot(&rotated, &rotated_points, &masses, &params)
        .unwrap()
        .into_result()
        .unwrap();
    assert!((a.cost / b.cost - 1.0).abs() < 1e-11, "{} against {}", a.cost, b.cost);
    let shift = a.heights[0] - b.heights[0];
    for i in 0..200 {
        assert!((a.heights[i] - b.heights[i] - shift).abs() < 1e-8, "height {i}");
    }
}

/// A few thousand random points on a contrasting zonal density converge in a few steps, with
/// the dual value just below the cost.
#[test]
fn random_points_converge_quickly() {
    let measure = zonal_measure(5, 0.9);
    let n = 5000;
    let points = random_sphere_points(n, 41);
    let solution = solve_sphere_ot(&measure, &points, &vec![1.0; n], &SphereOtParams::default()).unwrap();
    assert_eq!(solution.stop, StopReason::Converged);
    assert!(solution.iterations <= 12, "{} steps", solution.iterations);
    let gap = solution.cost - solution.dual_value();
    assert!(gap.abs() < 1e-6 * solution.cost, "cost − dual {gap:e}");
    let total: f64 = solution.cells.masses.iter().sum();
    assert!((total / measure.total_mass() - 1.0).abs() < 1e-12);
}

/// A density ratio of 400 (ρ ∝ exp(3z)) takes the density continuation (two softened stages)
/// and converges to the same cells as the plain solve, which converges here too.
#[test]
fn contrasting_density_converges_through_the_continuation() {
    let (v, t) = icosphere(4);
    let measure = SphereMeasure::from_spherical_density(v, t, |x| (3.0 * x[2]).exp()).unwrap();
    let n = 1000;
    let points = random_sphere_points(n, 13);
    let masses = vec![1.0; n];
    let with = solve_sphere_ot(&measure, &points, &masses, &SphereOtParams::default()).unwrap();
    assert_eq!(with.stop, StopReason::Converged);
    assert_eq!(with.continuation_stages, 2);
    let plain = solve_sphere_ot(
        &measure,
        &points,
        &masses,
        &SphereOtParams {
            density_continuation: None,
            ..Default::default()
        },
    )
    .unwrap();
    assert_eq!(plain.stop, StopReason::Converged);
    assert_eq!(plain.continuation_stages, 0);
    assert!(
        (with.cost / plain.cost - 1.0).abs() < 1e-6,
        "{} against {}",
        with.cost,
        plain.cost
    );
}

#[test]
fn bad_inputs_are_errors_that_say_what() {
    let measure = SphereMeasure::uniform_icosphere(2).unwrap();
    let params = SphereOtParams::default();
    let off = solve_sphere_ot(&measure, &[[0.0, 0.0, 1.0], [0.0, 2.0, 0.0]], &[1.0, 1.0], &params);
    assert!(matches!(&off, Err(OmtError::InvalidInput(m)) if m.contains("point 1") && m.contains("unit sphere")));
    let dup = solve_sphere_ot(&measure, &[[0.0, 0.0, 1.0], [0.0, 0.0, 1.0]], &[1.0, 1.0], &params);
    assert!(matches!(dup, Err(OmtError::DuplicatePoints { i: 0, j: 1 })));
    let zero = solve_sphere_ot(&measure, &[[0.0, 0.0, 1.0], [0.0, 1.0, 0.0]], &[1.0, 0.0], &params);
    assert!(matches!(&zero, Err(OmtError::InvalidInput(m)) if m.contains("point 1")));
    // a northern cap only: the south pole's cell is empty
    let (v, t) = icosphere(2);
    let north: Vec<[u32; 3]> = t
        .into_iter()
        .filter(|tri| tri.iter().all(|&i| v[i as usize][2] > 0.2))
        .collect();
    let cap = SphereMeasure::new(v, north.clone(), vec![1.0; north.len()]).unwrap();
    let empty = solve_sphere_ot(&cap, &[[0.0, 0.0, 1.0], [0.0, 0.0, -1.0]], &[1.0, 1.0], &params);
    assert!(matches!(&empty, Err(OmtError::InvalidInput(m)) if m.contains("cell 1 is empty")));
    let bad_vertex = SphereMeasure::new(
        vec![[0.0, 0.0, 1.5], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0]],
        vec![[0, 1, 2]],
        vec![1.0],
    );
    assert!(matches!(&bad_vertex, Err(OmtError::InvalidInput(m)) if m.contains("vertex 0")));
    let bad_density = SphereMeasure::new(
        vec![[0.0, 0.0, 1.0], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0]],
        vec![[0, 1, 2]],
        vec![-1.0],
    );
    assert!(matches!(&bad_density, Err(OmtError::InvalidInput(m)) if m.contains("triangle 0")));
}

/// The unit sphere as a subdivided octahedron (`subdivisions` midpoint steps, vertices
/// normalized): the same set under the quarter turn (x, y, z) ↦ (−y, x, z), exactly in f64.
fn octahedral_sphere(subdivisions: usize) -> SphereMeasure {
    let mut vertices: Vec<[f64; 3]> = vec![
        [1.0, 0.0, 0.0],
        [0.0, 1.0, 0.0],
        [-1.0, 0.0, 0.0],
        [0.0, -1.0, 0.0],
        [0.0, 0.0, 1.0],
        [0.0, 0.0, -1.0],
    ];
    let mut triangles: Vec<[u32; 3]> = (0..4u32)
        .flat_map(|k| [[k, (k + 1) % 4, 4], [(k + 1) % 4, k, 5]])
        .collect();
    for _ in 0..subdivisions {
        let mut middle = std::collections::HashMap::new();
        let mut next = Vec::new();
        for t in &triangles {
            let mut mid = |a: u32, b: u32| {
                *middle.entry((a.min(b), a.max(b))).or_insert_with(|| {
                    let (p, q) = (vertices[a as usize], vertices[b as usize]);
                    vertices.push(unit([p[0] + q[0], p[1] + q[1], p[2] + q[2]]));
                    vertices.len() as u32 - 1
                })
            };
            let [a, b, c] = *t;
            let (ab, bc, ca) = (mid(a, b), mid(b, c), mid(c, a));
            next.extend([[a, ab, ca], [b, bc, ab], [c, ca, bc], [ab, bc, ca]]);
        }
        triangles = next;
    }
    let n = triangles.len();
    SphereMeasure::new(vertices, triangles, vec![1.0; n]).unwrap()
}

/// Four sites 1e-9 apart around each pole (a quarter turn maps the sites and the source onto
/// themselves), one of them lengthened by 2⁻⁵² (radially, to 1e-25): the unit vectors the
/// points stand for keep the symmetry, so the four cells of a cluster have equal masses. The
/// bisector margins |y_i − y_j|²/2 ≈ 5e-19 lie far below such f64 radial errors: without the
/// integrator's radial corrections the lengthened site takes the others' cells (an empty cell
/// on the TOSCA centaur and the GOAST fingers, whose conformal images crowd sites 3e-11 apart).
#[test]
fn sites_crowded_far_below_f64_resolution_keep_their_cells() {
    let measure = octahedral_sphere(4);
    let r = 1e-9;
    let mut points = Vec::new();
    for z in [1.0, -1.0] {
        for [x, y] in [[r, 0.0], [0.0, r], [-r, 0.0], [0.0, -r]] {
            points.push(unit([x, y, z]));
        }
    }
    points[1] = points[1].map(|c| c * (1.0 + f64::EPSILON));
    points[6] = points[6].map(|c| c * (1.0 - f64::EPSILON / 2.0));
    let cells = SphereIntegrator::new(&measure, &points).integrate(&[0.0; 8]);
    let total = measure.total_mass();
    for cluster in [&cells.masses[..4], &cells.masses[4..]] {
        let sum: f64 = cluster.iter().sum();
        assert!((sum - total / 2.0).abs() < 1e-6 * total, "{:?}", cells.masses);
        for m in cluster {
            assert!((m - sum / 4.0).abs() < 1e-9 * sum, "{:?}", cells.masses);
        }
    }
}

/// The flat area of the source's triangles (density 1) in the half-space z ≥ z0: each triangle
/// clipped by the plane, exactly.
fn flat_area_above(measure: &SphereMeasure, z0: f64) -> f64 {
    let area = |p: &[[f64; 3]]| -> f64 {
        let mut s = 0.0;
        for k in 1..p.len().saturating_sub(1) {
            let (u, v) = (
                [p[k][0] - p[0][0], p[k][1] - p[0][1], p[k][2] - p[0][2]],
                [p[k + 1][0] - p[0][0], p[k + 1][1] - p[0][1], p[k + 1][2] - p[0][2]],
            );
            let c = [
                u[1] * v[2] - u[2] * v[1],
                u[2] * v[0] - u[0] * v[2],
                u[0] * v[1] - u[1] * v[0],
            ];
            s += 0.5 * dot(c, c).sqrt();
        }
        s
    };
    let mut total = 0.0;
    for tri in &measure.triangles {
        let corners = tri.map(|i| measure.vertices[i as usize]);
        let mut clipped = Vec::new();
        for k in 0..3 {
            let (p, q) = (corners[k], corners[(k + 1) % 3]);
            let (a, b) = (p[2] - z0, q[2] - z0);
            if a >= 0.0 {
                clipped.push(p);
            }
            if (a >= 0.0) != (b >= 0.0) {
                let t = a / (a - b);
                clipped.push([0, 1, 2].map(|c| p[c] + t * (q[c] - p[c])));
            }
        }
        total += area(&clipped);
    }
    total
}

/// Two 6×6 grids of sites 1e-9 apart at the poles, the northern one with three quarters of
/// the mass (the conformal image of two fingertips, in miniature). From the Voronoi start the
/// 32 inner sites hold ~1e-18 of the sphere against targets of 0.2, and Newton cannot grow
/// them: the solve does not converge. The coarse-to-fine start converges, and the solution
/// has the closed form the geometry dictates: up to the grids' size, the two clusters' cells
/// meet on the plane z = z₀ below which the source holds a quarter of its mass, so
/// (h_south − h_north)/2 = z₀ for every pair (the bisector ⟨x, y_n − y_s⟩ = h_s − h_n with
/// y_n − y_s = 2e_z); and the quarter turn (x, y, z) ↦ (−y, x, z), which maps the source
/// and the sites onto themselves exactly, maps the heights onto themselves.
#[test]
fn crowded_clusters_converge_from_the_coarse_to_fine_start() {
    let measure = octahedral_sphere(5);
    let d = 1e-9;
    let mut points = Vec::new();
    let mut masses = Vec::new();
    for (z, mass) in [(1.0, 3.0), (-1.0, 1.0)] {
        for k in 0..6 {
            for l in 0..6 {
                points.push(unit([(k as f64 - 2.5) * d, (l as f64 - 2.5) * d, z]));
                masses.push(mass);
            }
        }
    }
    let voronoi = solve_sphere_ot(
        &measure,
        &points,
        &masses,
        &SphereOtParams {
            start: SphereStart::Voronoi,
            ..Default::default()
        },
    )
    .unwrap();
    assert!(!voronoi.converged(), "{:e}", voronoi.max_relative_error);
    assert!(voronoi.max_relative_error > 0.5, "{:e}", voronoi.max_relative_error);
    let solution = solve_sphere_ot(&measure, &points, &masses, &SphereOtParams::default()).unwrap();
    assert!(
        solution.converged(),
        "{} {:e}",
        solution.stop,
        solution.max_relative_error
    );
    assert!(!solution.coarse_levels.is_empty());
    assert!(solution.max_relative_error <= 1e-6);
    // z₀ by bisection on the exact flat area above the plane
    let total = measure.total_mass();
    let (mut lo, mut hi) = (-1.0, 1.0);
    for _ in 0..60 {
        let mid = 0.5 * (lo + hi);
        if flat_area_above(&measure, mid) > 0.75 * total {
            lo = mid;
        } else {
            hi = mid;
        }
    }
    let z0 = 0.5 * (lo + hi);
    let h = |i: usize| solution.heights[i] + solution.heights_lo[i];
    let mut worst_z: f64 = 0.0;
    for i in 0..36 {
        for j in 36..72 {
            let z = 0.5 * (h(j) - h(i));
            assert!((z - z0).abs() < 1e-5, "({i}, {j}): {z} against z0 = {z0}");
            worst_z = worst_z.max((z - z0).abs());
        }
    }
    // the quarter turn maps grid site (k, l) to (5 − l, k); heights agree far below the
    // siblings' height differences (~1e-9)
    let spread = (0..36).map(h).fold(f64::NEG_INFINITY, f64::max) - (0..36).map(h).fold(f64::INFINITY, f64::min);
    assert!(spread > 1e-10, "{spread:e}");
    let mut worst_gap: f64 = 0.0;
    for c in 0..2 {
        for k in 0..6 {
            for l in 0..6 {
                let (i, j) = (36 * c + 6 * k + l, 36 * c + 6 * (5 - l) + k);
                let gap =
                    (solution.heights[i] - solution.heights[j]) + (solution.heights_lo[i] - solution.heights_lo[j]);
                assert!(gap.abs() < 1e-12, "sites {i}, {j}: {gap:e} (spread {spread:e})");
                worst_gap = worst_gap.max(gap.abs());
            }
        }
    }
    eprintln!(
        "Voronoi start: {} after {} steps, error {:.2e}; coarse-to-fine: levels {:?}, {} steps, error {:.2e}; \
         |z − z0| ≤ {worst_z:.1e} (z0 = {z0:.6}), quarter-turn height gaps ≤ {worst_gap:.1e} against a spread of {spread:.1e}",
        voronoi.stop,
        voronoi.iterations,
        voronoi.max_relative_error,
        solution.coarse_levels,
        solution.iterations,
        solution.max_relative_error
    );
}

/// The crowded case of the tests below: the density e^{8z} (contrast 9e6) on an icosphere of
/// level 4 against 200 spread sites and two 6×6 grids of sites 1e-9 apart at the poles
/// (masses 3 at the north pole, 0.5 at the south, 1 elsewhere).
fn crowded_case() -> (SphereMeasure, Vec<[f64; 3]>, Vec<f64>) {
    let (v, t) = icosphere(4);
    let measure = SphereMeasure::from_spherical_density(v, t, |x| (8.0 * x[2]).exp()).unwrap();
    let d = 1e-9;
    let mut points = random_sphere_points(200, 7);
    let mut masses = vec![1.0; 200];
    for (z, mass) in [(1.0, 3.0), (-1.0, 0.5)] {
        for k in 0..6 {
            for l in 0..6 {
                points.push(unit([(k as f64 - 2.5) * d, (l as f64 - 2.5) * d, z]));
                masses.push(mass);
            }
        }
    }
    (measure, points, masses)
}

/// A crowded source and crowded sites: the density e^{8z} (contrast 9e6) against two 6×6 grids
/// of sites 1e-9 apart at the poles and 200 spread sites converges through the density
/// continuation; a warm start from the solution's double-double heights
/// (`initial_heights_lo`) is converged at once, with the same heights and cost.
#[test]
fn crowded_source_restarts_from_double_double_heights_in_no_steps() {
    let (measure, points, masses) = crowded_case();
    let continued = solve_sphere_ot(&measure, &points, &masses, &SphereOtParams::default()).unwrap();
    assert!(
        continued.converged(),
        "{} {:e}",
        continued.stop,
        continued.max_relative_error
    );
    assert!(continued.continuation_stages > 0);
    let warm = solve_sphere_ot(
        &measure,
        &points,
        &masses,
        &SphereOtParams {
            initial_heights: Some(continued.heights.clone()),
            initial_heights_lo: Some(continued.heights_lo.clone()),
            ..Default::default()
        },
    )
    .unwrap();
    assert_eq!(warm.iterations, 0);
    // (the cost is summed in parallel: equal to rounding)
    assert!(
        (warm.cost / continued.cost - 1.0).abs() < 1e-13,
        "{} {}",
        warm.cost,
        continued.cost
    );
    assert_eq!(warm.heights, continued.heights);
    assert_eq!(warm.heights_lo, continued.heights_lo);
    // a length mismatch of the low parts is an input error
    let bad = solve_sphere_ot(
        &measure,
        &points,
        &masses,
        &SphereOtParams {
            initial_heights: Some(continued.heights.clone()),
            initial_heights_lo: Some(vec![0.0; 3]),
            ..Default::default()
        },
    );
    assert!(
        matches!(bad, Err(OmtError::InvalidInput(ref m)) if m.contains("low parts")),
        "{bad:?}"
    );
}

/// The stall window (decision 0036): on the crowded case above without the continuation the
/// direct solve crawls (decision 0030: to the step cap); with a window of 10 it stops as
/// `Stalled` once 10 accepted steps have not halved the largest mass error, and the error it
/// reports is that of its last step. On a case that converges the window changes nothing.
#[test]
fn a_crawling_direct_solve_stops_at_its_stall_window() {
    let (measure, points, masses) = crowded_case();
    let window = 10;
    let direct = SphereOtParams {
        density_continuation: None,
        stall_window: Some(window),
        ..Default::default()
    };
    let s = solve_sphere_ot(&measure, &points, &masses, &direct).unwrap();
    assert!(matches!(s.stop, StopReason::Stalled { .. }), "{}", s.stop);
    assert!(
        s.iterations < SphereOtParams::default().max_iterations,
        "{} steps",
        s.iterations
    );
    // the last path's log: at least `window` steps, and the last `window` did not halve the error
    assert!(s.log.len() >= window, "{} logged steps", s.log.len());
    let last = s.log[s.log.len() - 1].max_relative_error;
    assert_eq!(last, s.max_relative_error);
    if s.log.len() > window {
        let before = s.log[s.log.len() - 1 - window].max_relative_error;
        assert!(last > 0.5 * before, "{before:e} → {last:e}");
    }
    assert!(s.max_relative_error > 1e-6);
    // a converging solve: the same steps, heights and cost with and without a window
    let measure = zonal_measure(4, 0.9);
    let n = 1000;
    let points = random_sphere_points(n, 43);
    let plain = solve_sphere_ot(&measure, &points, &vec![1.0; n], &SphereOtParams::default()).unwrap();
    let windowed = solve_sphere_ot(
        &measure,
        &points,
        &vec![1.0; n],
        &SphereOtParams {
            stall_window: Some(4),
            ..Default::default()
        },
    )
    .unwrap();
    assert!(plain.converged());
    assert_eq!(windowed.stop, StopReason::Converged);
    assert_eq!(windowed.iterations, plain.iterations);
    assert_eq!(windowed.heights, plain.heights);
    assert_eq!(windowed.cost, plain.cost);
}
