//! Long tubes (a cylinder of radius ρ and height H closed by a flat cap, open end = boundary,
//! pole = cap center): the image of the cap shrinks like e^{−H/ρ}, so densities span many
//! orders of magnitude.
//!
//! Observed (ρ = 1, 36 vertices around): H = 2, 5, 10, 20, 40, 60 give λ at the pole 1.20,
//! 3.81, 8.49, 18.17, 37.85, 57.68 (slope dλ/dH → 0.98 ≈ 1/ρ) and max densities 1.1e1, 2.1e3,
//! 2.4e7, 6.2e15, 7.7e32, 1.3e50. No NaN anywhere. At H = 400 the cap density would be
//! ~1e348 > f64::MAX: `OutOfRange` error (documented in `disk_map`).

use shapespace_conformal::{disk_map, ConformalError, DiskMapParams};
use shapespace_geometry::primitives::capped_tube;

mod common;
use common::*;

#[test]
fn tubes_have_exponential_but_finite_factors() {
    let mut lambdas = Vec::new();
    for h in [5.0, 20.0, 60.0] {
        let m = capped_tube(1.0, h, 6, (h * 3.0) as usize);
        let dm = map(&m, &vertex_markers(0, (m.num_vertices() - 1) as u32));
        assert!(dm.uv.iter().all(|z| z[0].is_finite() && z[1].is_finite()));
        assert!(dm.conformal_factor.iter().all(|x| x.is_finite()));
        assert!(dm.face_densities.iter().all(|&x| x.is_finite() && x > 0.0));
        assert_eq!(dm.quality.num_flipped, 0);
        let max = dm.face_densities.iter().cloned().fold(0.0, f64::max);
        // the cap is at scale e^{−H}: density ≈ e^{2H} up to O(1) factors
        assert!(
            max.ln() > 2.0 * h - 6.0 && max.ln() < 2.0 * h + 6.0,
            "H {h}: max density {max:e}"
        );
        lambdas.push(dm.conformal_factor[0]);
    }
    let slope = (lambdas[2] - lambdas[1]) / 40.0;
    assert!((slope - 1.0).abs() < 0.05, "dλ/dH = {slope}, λ = {lambdas:?}");
}

#[test]
fn tube_beyond_f64_range_is_a_clear_error() {
    let m = capped_tube(1.0, 400.0, 4, 800);
    match disk_map(
        &m,
        &vertex_markers(0, (m.num_vertices() - 1) as u32),
        &DiskMapParams::default(),
    ) {
        Err(ConformalError::OutOfRange { log10_value, what, .. }) => {
            assert!(log10_value.abs() > 150.0, "{what}: {log10_value}");
        }
        other => panic!("expected OutOfRange, got {:?}", other.map(|d| d.quality)),
    }
}
