//! The averaged source measures of the coarse levels (`shapespace_omt::averaging`): every coarse
//! triangle carries exactly the mass of the fine measure on it, the copies are kept per measure
//! and rebuilt when its fields change, and a solve whose coarse levels use them reaches the
//! solution of the plain Voronoi start.

use std::sync::Arc;

use crate::common::{disk_measure, Rng};
use shapespace_omt::averaging::{averaged_measure, averaged_measure_evenly};
use shapespace_omt::{solve_ot_prepared, NewtonParams, PreparedMeasure, SourceMeasure, StartStrategy};

/// Area of the convex polygon `a` ∩ triangle `t` (both counter-clockwise), by Sutherland–Hodgman
/// in absolute coordinates: an implementation independent of the library's.
fn intersection_area(a: &[[f64; 2]], t: [[f64; 2]; 3]) -> f64 {
    let mut poly = a.to_vec();
    for k in 0..3 {
        let (p, q) = (t[k], t[(k + 1) % 3]);
        let side = |x: [f64; 2]| (q[0] - p[0]) * (x[1] - p[1]) - (q[1] - p[1]) * (x[0] - p[0]);
        let mut next = Vec::new();
        for j in 0..poly.len() {
            let (u, v) = (poly[j], poly[(j + 1) % poly.len()]);
            let (fu, fv) = (side(u), side(v));
            if fu >= 0.0 {
                next.push(u);
            }
            if (fu >= 0.0) != (fv >= 0.0) {
                let s = fu / (fu - fv);
                next.push([u[0] + s * (v[0] - u[0]), u[1] + s * (v[1] - u[1])]);
            }
        }
        poly = next;
        if poly.len() < 3 {
            return 0.0;
        }
    }
    (1..poly.len() - 1)
        .map(|j| {
            let (a, b, c) = (poly[0], poly[j], poly[j + 1]);
            0.5 * ((b[0] - a[0]) * (c[1] - a[1]) - (b[1] - a[1]) * (c[0] - a[0]))
        })
        .sum()
}

fn corners(m: &SourceMeasure, t: usize) -> [[f64; 2]; 3] {
    m.triangles[t].map(|v| m.vertices[v as usize])
}

fn area(p: [[f64; 2]; 3]) -> f64 {
    0.5 * ((p[1][0] - p[0][0]) * (p[2][1] - p[0][1]) - (p[1][1] - p[0][1]) * (p[2][0] - p[0][0]))
}

/// A density with a 400× contrast and a sharp ring, so that averaging visibly changes it.
fn contrast(x: [f64; 2]) -> f64 {
    let r2 = x[0] * x[0] + x[1] * x[1];
    0.05 + 20.0 * (-40.0 * (r2.sqrt() - 0.5).powi(2)).exp() + 2.0 * (x[0] - 0.3 * x[1]).max(0.0)
}

#[test]
fn every_coarse_triangle_carries_the_fine_mass_on_it() {
    let fine = disk_measure(24, &contrast);
    let coarse = averaged_measure(&fine, 150).expect("averaging applies");
    // (about 2·sample triangles, plus the hull's)
    assert!(
        coarse.triangles.len() < fine.triangles.len() / 4,
        "{} triangles",
        coarse.triangles.len()
    );
    check_coarse_masses(&fine, &coarse);
    check_averaged(&fine, &coarse);
}

/// The even sample takes exactly the vertices asked for (plus the hull), whatever the size,
/// so the triangle count follows the request (2·sample + hull − 2 for a Delaunay triangulation
/// with the hull's vertices on its boundary), and its triangles carry the fine masses too.
#[test]
fn the_even_sample_has_the_size_asked_for_and_the_fine_masses() {
    let fine = disk_measure(24, &contrast);
    let (mut counts, mut hulls) = (Vec::new(), Vec::new());
    for sample in [150, 151, 200, 333, 400] {
        let coarse = averaged_measure_evenly(&fine, sample).expect("averaging applies");
        let (v, t) = (coarse.vertices.len(), coarse.triangles.len());
        // (Euler: t = 2v − 2 − h with h hull vertices; a sampled vertex on the hull counts once)
        let h = 2 * v - 2 - t;
        assert!(
            v >= sample.max(h) && v <= sample + h,
            "{sample}: {v} vertices, hull {h}"
        );
        counts.push(t);
        hulls.push(h);
        check_coarse_masses(&fine, &coarse);
    }
    assert!(hulls.iter().all(|&h| h == hulls[0] && h >= 3), "{hulls:?}");
    assert!(counts.windows(2).all(|w| w[0] < w[1]), "{counts:?}");
    // the stride of the coarse levels' copies gives one size for every request in [V/3, V/2)
    let n = fine.vertices.len();
    let requests = [n.div_ceil(3), n / 2 - 1];
    let size = |f: fn(&SourceMeasure, usize) -> Option<SourceMeasure>, s: usize| f(&fine, s).unwrap().triangles.len();
    assert_eq!(size(averaged_measure, requests[0]), size(averaged_measure, requests[1]));
    assert!(size(averaged_measure_evenly, requests[0]) < size(averaged_measure_evenly, requests[1]));
    assert!(averaged_measure_evenly(&fine, fine.vertices.len()).is_none());
}

/// Every coarse triangle's mass against a brute-force overlay, and the total mass.
fn check_coarse_masses(fine: &SourceMeasure, coarse: &SourceMeasure) {
    let (mut fine_total, mut coarse_total) = (0.0, 0.0);
    for t in 0..fine.triangles.len() {
        fine_total += fine.densities[t] * area(corners(fine, t));
    }
    let mut worst = 0.0f64;
    for c in 0..coarse.triangles.len() {
        let cc = corners(coarse, c);
        let mass = coarse.densities[c] * area(cc);
        coarse_total += mass;
        // brute force over all fine triangles, no walk
        let exact: f64 = (0..fine.triangles.len())
            .map(|t| fine.densities[t] * intersection_area(&corners(fine, t), cc))
            .sum();
        worst = worst.max((mass - exact).abs() / exact);
    }
    assert!(
        worst < 1e-10,
        "worst relative mass error of a coarse triangle {worst:e}"
    );
    assert!((coarse_total - fine_total).abs() < 1e-12 * fine_total);
}

/// The averaged densities differ from the fine ones (the mass checks are not vacuous).
fn check_averaged(fine: &SourceMeasure, coarse: &SourceMeasure) {
    let (lo, hi) = coarse
        .densities
        .iter()
        .fold((f64::INFINITY, 0.0f64), |(a, b), &d| (a.min(d), b.max(d)));
    let fine_max = fine.densities.iter().fold(0.0f64, |a, &d| a.max(d));
    assert!(
        hi / lo > 10.0 && hi < 0.99 * fine_max,
        "coarse densities {lo} .. {hi}, fine max {fine_max}"
    );
}

#[test]
fn averaging_declines_when_the_sample_is_not_smaller() {
    let fine = disk_measure(6, &contrast);
    assert!(averaged_measure(&fine, fine.vertices.len()).is_none());
    assert!(averaged_measure(&fine, 2).is_none());
}

/// A prepared measure builds an averaged copy once per sample size and shares it with its clones;
/// a prepared measure of other fields builds its own, with the mass of those fields.
#[test]
fn averaged_copies_are_kept_and_shared_by_clones() {
    let fine = PreparedMeasure::new(disk_measure(16, &contrast));
    let a = fine.averaged(100).expect("averaging applies");
    let b = fine.averaged(100).expect("averaging applies");
    assert!(Arc::ptr_eq(&a, &b), "the second call reuses the copy");
    assert!(
        Arc::ptr_eq(&a, &fine.clone().averaged(100).unwrap()),
        "clones share the copies"
    );
    assert_eq!(fine.averaged_samples(), vec![100]);
    // the copy is exact per coarse triangle: the same total mass
    assert!((a.total_mass() - fine.total_mass()).abs() < 1e-12 * fine.total_mass());
    let mut doubled = fine.measure().clone();
    doubled.densities.iter_mut().for_each(|d| *d *= 2.0);
    let doubled = PreparedMeasure::new(doubled);
    let c = doubled.averaged(100).expect("averaging applies");
    assert!(!Arc::ptr_eq(&a, &c));
    assert!((c.total_mass() - 2.0 * a.total_mass()).abs() < 1e-12 * c.total_mass());
}

/// 4,000 random points against a 12k-triangle measure: the coarse levels (about 600 and 150
/// points) are solved on averaged copies, and the solve reaches the solution of the Voronoi start.
#[test]
fn coarse_levels_on_averaged_measures_reach_the_same_solution() {
    let fine = PreparedMeasure::new(disk_measure(45, &|x| {
        0.3 + (x[0] + 0.2).max(0.0) + 2.0 * (-10.0 * (x[0] * x[0] + x[1] * x[1])).exp()
    }));
    assert!(fine.triangles.len() > 12_000);
    let mut rng = Rng(7);
    let points: Vec<[f64; 2]> = (0..4000).map(|_| rng.in_disk(0.97)).collect();
    let masses = vec![1.0; points.len()];
    let solve = |start| {
        let params = NewtonParams {
            start_strategy: start,
            ..NewtonParams::default()
        };
        solve_ot_prepared(&fine, &points, &masses, &params).expect("solve")
    };
    let multiscale = solve(StartStrategy::CoarseToFine);
    let plain = solve(StartStrategy::Voronoi);
    assert!(multiscale.converged() && plain.converged());
    assert!(
        matches!(multiscale.start, shapespace_omt::newton::Start::CoarseToFine { .. }),
        "{:?}",
        multiscale.start
    );
    assert!(
        (multiscale.cost - plain.cost).abs() < 1e-7 * plain.cost,
        "costs {} and {}",
        multiscale.cost,
        plain.cost
    );
    // The coarse level had an averaged copy built for it.
    let samples = fine.averaged_samples();
    assert!(!samples.is_empty(), "no averaged copy was built");
    assert!(samples.iter().all(|&s| s < fine.vertices.len() / 2 + 1), "{samples:?}");
}
