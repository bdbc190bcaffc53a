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

use crate::common::*;

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

/// A tube slit along its length (`prepare_disk` with a seam from its extremity, the cap centre,
/// to the open end) is a strip of width W = 2πρ with boundary on both long sides. A strip's
/// conformal image shrinks like e^{−π d/W} = e^{−d/(2ρ)} along it (the strip → half-plane map
/// exp(πw/W), then the Cayley map), against e^{−d/ρ} on the closed tube, so ln(density) changes
/// by 1/ρ per unit length instead of 2/ρ: the crowding exponent of a limb is halved. Measured
/// along the strip's middle line (φ = π), H = 30, z from 8 to 25: slope 1.00 against −2.00 on
/// the closed tube. (The crowding moves from the cap to the open end: the automatic centre, the
/// vertex farthest from the boundary, sits π from the slit near the cap. The top corners, where
/// the slit meets the open end, crowd faster still: the largest density grows like e^{1.44 H}.)
#[test]
fn a_slit_along_the_tube_halves_the_decay() {
    use shapespace_geometry::prepare::{prepare_disk, PrepareOptions};
    let h = 30.0;
    let tube = capped_tube(1.0, h, 6, (h * 3.0) as usize);
    let (slit, _, report) = prepare_disk(
        &tube,
        &PrepareOptions {
            seam_extremities: 1,
            ..Default::default()
        },
    )
    .unwrap();
    assert_eq!(report.seam_extremities, vec![Some(0)]);
    assert_eq!(report.seam_edges, 6 + 90, "straight up the tube from the cap centre");
    let dm = disk_map(&slit, &Default::default(), &DiskMapParams::default()).unwrap();
    assert_eq!(dm.quality.num_flipped + dm.quality.num_degenerate, 0);
    assert!(dm.info.bff_fallback.is_none());
    let closed = map(&tube, &vertex_markers(0, (tube.num_vertices() - 1) as u32));
    // least-squares slope of ln(density) against z over the faces on the line φ = π
    let slope = |mesh: &shapespace_geometry::TriMesh, densities: &[f64], lo: f64, hi: f64| {
        let (mut n, mut sz, mut sd, mut szz, mut szd) = (0.0, 0.0, 0.0, 0.0, 0.0);
        for (f, face) in mesh.faces.iter().enumerate() {
            let c = face.iter().fold([0.0; 3], |a, &v| {
                let p = mesh.positions[v as usize];
                [a[0] + p[0] / 3.0, a[1] + p[1] / 3.0, a[2] + p[2] / 3.0]
            });
            if c[0] < -0.95 && c[1].abs() < 0.1 && c[2] > lo && c[2] < hi {
                let d = densities[f].ln();
                n += 1.0;
                sz += c[2];
                sd += d;
                szz += c[2] * c[2];
                szd += c[2] * d;
            }
        }
        assert!(n > 40.0, "{n} faces on the line");
        (n * szd - sz * sd) / (n * szz - sz * sz)
    };
    let strip = slope(&slit, &dm.face_densities, 8.0, 25.0);
    let tube_slope = slope(&tube, &closed.face_densities, 8.0, 25.0);
    assert!((strip - 1.0).abs() < 0.03, "slit tube: d ln(density)/dz = {strip}");
    assert!(
        (tube_slope + 2.0).abs() < 0.06,
        "closed tube: d ln(density)/dz = {tube_slope}"
    );
}
