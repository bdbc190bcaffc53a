//! Dominitz & Tannenbaum's multiresolution scheme for the OMT gradient flow
//! (`shapespace_analysis::multiresolution`): on the disk and on the sphere the flow started
//! from the prolonged coarse levels reaches the closed forms and the single-level flow's map,
//! in fewer steps on the mesh. Numbers quoted in comments were measured on this implementation
//! (release build); the bounds leave a margin.

use shapespace_analysis::area_preserving::{area_preserving_map, AreaPreservingParams};
use shapespace_analysis::distortion::{map_distortion, sphere_map_distortion};
use shapespace_analysis::gradient_flow::{gradient_flow_map, GradientFlowParams};
use shapespace_analysis::sphere_flows::{sphere_gradient_flow_map, sphere_lie_map, SphereFlowParams, SphereLieParams};
use shapespace_conformal::{BoundaryMarker, CenterMarker, Markers};
use shapespace_geometry::{primitives, TriMesh};

fn max_distance<const D: usize>(a: &[[f64; D]], b: &[[f64; D]]) -> f64 {
    a.iter()
        .zip(b)
        .map(|(p, q)| (0..D).map(|d| (p[d] - q[d]).powi(2)).sum::<f64>().sqrt())
        .fold(0.0, f64::max)
}

fn single_level() -> GradientFlowParams {
    GradientFlowParams {
        multiresolution_levels: 0,
        ..Default::default()
    }
}

/// Center vertex 0 and the rim vertex at angle 0 of a ring-layout mesh.
fn ring_markers(mesh: &TriMesh) -> Markers {
    let q = (0..mesh.num_vertices())
        .filter(|&v| mesh.positions[v][1].abs() < 1e-12 && mesh.positions[v][0] > 0.0)
        .max()
        .unwrap();
    Markers {
        center: CenterMarker::Vertex(0),
        boundary: BoundaryMarker::Vertex(q as u32),
    }
}

/// Root mean square of |r_i − R(θ_i)|, R(θ) = sin(θ/2)/sin(α/2): the radial optimal map of a
/// cap of half-angle α centred at its pole.
fn radial_rms(mesh: &TriMesh, alpha: f64, uv: &[[f64; 2]]) -> f64 {
    let sum: f64 = mesh
        .positions
        .iter()
        .zip(uv)
        .map(|(p, q)| {
            let theta = p[2].clamp(-1.0, 1.0).acos();
            ((theta / 2.0).sin() / (alpha / 2.0).sin() - q[0].hypot(q[1])).powi(2)
        })
        .sum();
    (sum / uv.len() as f64).sqrt()
}

/// A spherical cap of half-angle 2 centred at its pole: the optimal map is the radial one,
/// R(θ) = sin(θ/2)/sin(α/2). The flow from the prolonged coarse levels converges to it under
/// refinement, without folds, and its distance to the single-level flow's map (from the Lie
/// map) shrinks.
///
/// Measured (8, 16, 32 rings; levels of 61 / 61 and 217 / 217 and 817 vertices): rms radial
/// error 2.45e-3, 1.02e-3, 7.75e-4 (single level 2.07e-3, 9.67e-4, 4.04e-4); max |multi −
/// single| 1.24e-2, 8.3e-3, 4.5e-3; 30, 6, 2 steps on the mesh.
#[test]
fn radial_cap_converges_and_agrees_with_the_single_level_flow() {
    let alpha = 2.0;
    let mut rows = Vec::new();
    for rings in [8usize, 16, 32] {
        let mesh = primitives::spherical_cap(alpha, rings);
        let multi = gradient_flow_map(&mesh, &ring_markers(&mesh), &GradientFlowParams::default()).unwrap();
        let single = gradient_flow_map(&mesh, &ring_markers(&mesh), &single_level()).unwrap();
        let d = map_distortion("flow", &mesh, &multi.uv).unwrap();
        assert_eq!(d.num_flipped + d.num_degenerate, 0, "rings {rings}");
        assert_eq!(multi.info.multiresolution.fallback, None, "rings {rings}");
        assert!(!multi.info.multiresolution.levels.is_empty());
        rows.push((
            radial_rms(&mesh, alpha, &multi.uv),
            max_distance(&multi.uv, &single.uv),
            multi.info.flow.steps,
        ));
    }
    eprintln!("radial cap (rms radial error, max |multi − single|, steps): {rows:?}");
    for w in rows.windows(2) {
        assert!(w[1].0 < w[0].0 && w[1].1 < 0.8 * w[0].1, "{rows:?}");
    }
    assert!(rows[2].0 < 1e-3 && rows[2].1 < 6e-3, "{rows:?}");
}

/// The cap centred off the pole (the Lie map is not optimal there): the flow from the coarse
/// levels ends as close to the Newton OMT map as the single-level flow, at the same transport
/// cost, in far fewer steps on the mesh.
///
/// Measured (16, 24 rings): steps on the mesh 6 / 18 and 3 / 15; max |multi − OMT| 8.3e-3 /
/// 5.4e-3 against |single − OMT| 6.5e-3 / 4.9e-3; max |multi − single| 6.9e-3 / 5.9e-3; cost
/// 0.27452 and 0.17730 for both.
#[test]
fn off_center_cap_takes_fewer_steps_on_the_mesh() {
    for rings in [16usize, 24] {
        let mesh = primitives::spherical_cap(2.0, rings);
        let markers = Markers {
            center: CenterMarker::Vertex((1 + 6 * (1 + 2 + 3 + 4)) as u32),
            ..ring_markers(&mesh)
        };
        let multi = gradient_flow_map(&mesh, &markers, &GradientFlowParams::default()).unwrap();
        let single = gradient_flow_map(&mesh, &markers, &single_level()).unwrap();
        let omt = area_preserving_map(&mesh, &markers, &AreaPreservingParams::default()).unwrap();
        let d = map_distortion("flow", &mesh, &multi.uv).unwrap();
        let (m, s) = (&multi.info.flow, &single.info.flow);
        let row = (
            m.steps,
            s.steps,
            max_distance(&multi.uv, &omt.uv),
            max_distance(&single.uv, &omt.uv),
            max_distance(&multi.uv, &single.uv),
            m.final_cost,
            s.final_cost,
        );
        eprintln!("off-center cap, {rings} rings (steps multi, single; |multi − OMT|, |single − OMT|, |multi − single|; costs): {row:?}");
        assert_eq!(d.num_flipped + d.num_degenerate, 0);
        assert_eq!(multi.info.multiresolution.levels.len(), 2);
        assert!(2 * row.0 < row.1, "{row:?}");
        assert!(row.2 < 1.5 * row.3 && row.4 < 1e-2, "{row:?}");
        assert!((row.5 - row.6).abs() < 1e-4 * row.6, "{row:?}");
    }
}

fn ellipsoid(subdivisions: usize, b: f64, c: f64) -> TriMesh {
    let ico = primitives::icosphere(subdivisions);
    TriMesh::new(
        ico.positions.iter().map(|p| [p[0], b * p[1], c * p[2]]).collect(),
        ico.faces.clone(),
    )
    .unwrap()
}

/// Area of the spheroid x² + y² + (z/c)² = 1 above the height c cos t (composite Simpson).
fn cap_area(c: f64, t: f64) -> f64 {
    let m = 4000;
    let h = t / m as f64;
    let g = |s: f64| s.sin() * (s.cos().powi(2) + c * c * s.sin().powi(2)).sqrt();
    let mut sum = g(0.0) + g(t);
    for k in 1..m {
        sum += if k % 2 == 1 { 4.0 } else { 2.0 } * g(k as f64 * h);
    }
    2.0 * std::f64::consts::PI * sum * h / 3.0
}

/// The area-preserving map of a spheroid (axis z, ratio c) onto S² that keeps the longitude: a
/// point at height z goes to the height 1 − 2 A(z)/A, A(z) the area above it. The optimal map
/// of the zonal density (symmetric under rotations about and reflections through the axis) is
/// this rearrangement too. Returns the rms over the vertices of the image's height along the
/// best-fitting axis n (least squares of x'_i · n against the closed form) minus the closed form.
fn zonal_error(mesh: &TriMesh, c: f64, image: &[[f64; 3]]) -> f64 {
    let total = cap_area(c, std::f64::consts::PI);
    let want: Vec<f64> = mesh
        .positions
        .iter()
        .map(|p| 1.0 - 2.0 * cap_area(c, (p[2] / c).clamp(-1.0, 1.0).acos()) / total)
        .collect();
    // normal equations of min Σ (x'_i · n − want_i)²
    let (mut a, mut b) = ([[0.0; 3]; 3], [0.0; 3]);
    for (x, w) in image.iter().zip(&want) {
        for r in 0..3 {
            b[r] += x[r] * w;
            for s in 0..3 {
                a[r][s] += x[r] * x[s];
            }
        }
    }
    let det = |m: [[f64; 3]; 3]| {
        m[0][0] * (m[1][1] * m[2][2] - m[1][2] * m[2][1]) - m[0][1] * (m[1][0] * m[2][2] - m[1][2] * m[2][0])
            + m[0][2] * (m[1][0] * m[2][1] - m[1][1] * m[2][0])
    };
    let d = det(a);
    let n: [f64; 3] = [0, 1, 2].map(|k| {
        let mut m = a;
        for r in 0..3 {
            m[r][k] = b[r];
        }
        det(m) / d
    });
    let l = (n[0] * n[0] + n[1] * n[1] + n[2] * n[2]).sqrt();
    let n = n.map(|t| t / l);
    let sum: f64 = image
        .iter()
        .zip(&want)
        .map(|(x, w)| (x[0] * n[0] + x[1] * n[1] + x[2] * n[2] - w).powi(2))
        .sum();
    (sum / image.len() as f64).sqrt()
}

/// Spheroids 1:1:2 at 642, 2,562 and 10,242 vertices (icosphere levels of 162; 162 and 642;
/// 642 and 2,562 vertices): the flow from the coarse levels approaches the closed-form latitude
/// rearrangement under refinement, without folds, and the single-level flow's map. Both run to
/// ‖ζ‖/‖u‖ ≤ 1e-4: at the default 1e-3 a residual turn about the axis whose curl part is below
/// the tolerance is left (max |multi − single| 7.7e-3, 6.2e-3, 5.1e-3).
///
/// Measured: rms height error 7.8e-4, 4.9e-4, 2.0e-4; max |multi − single| 3.7e-3, 2.8e-3,
/// 1.9e-3.
#[test]
fn spheroid_converges_to_the_latitude_rearrangement() {
    let c = 2.0;
    let mut params = SphereFlowParams::default();
    params.control.tolerance = 1e-4;
    let single_params = SphereFlowParams {
        multiresolution_levels: 0,
        ..params.clone()
    };
    let mut rows = Vec::new();
    for s in [3usize, 4, 5] {
        let mesh = ellipsoid(s, 1.0, c);
        let multi = sphere_gradient_flow_map(&mesh, &params).unwrap();
        let single = sphere_gradient_flow_map(&mesh, &single_params).unwrap();
        assert_eq!(multi.info.num_flipped, 0);
        assert_eq!(multi.info.multiresolution.fallback, None);
        rows.push((
            zonal_error(&mesh, c, &multi.positions),
            max_distance(&multi.positions, &single.positions),
            multi.info.multiresolution.levels.len(),
        ));
    }
    eprintln!("spheroid 1:1:2 (rms height error, max |multi − single|, levels): {rows:?}");
    for w in rows.windows(2) {
        assert!(w[1].0 < 0.75 * w[0].0 && w[1].1 < 0.8 * w[0].1, "{rows:?}");
    }
    assert!(rows[2].0 < 3e-4 && rows[2].1 < 3e-3, "{rows:?}");
}

/// TOSCA wolf0 (shared datasets): the sphere's Lie map folds 448 faces, which the chart repair
/// now undoes (its foldover-free untangling, decision 0051; 16 stayed folded before, and the
/// single-level flow could not start); the coarse levels give an unfolded start (the prolonged map
/// folds a face, which the chart repair undoes), whose Moser advection folds faces that the
/// chart repair undoes too, so the flow on the mesh starts from the corrected map and runs
/// without folds. The conformal image is crowded far beyond the coarse grids (local area
/// ratios up to e^{±25}), yet the corrected start carries most of the area correction: p95 |ε|
/// a tenth of the conformal map's and a third of the Lie map's.
///
/// Measured: levels of 162 and 642 vertices (112 and 45 flow steps), the prolonged map 1 fold,
/// 0 after the repair; 9 steps on the mesh; p95 |ε| 2.27 (conformal 24.9, Lie map 6.8), 0
/// flipped.
#[test]
fn tosca_wolf_flow_starts_from_the_corrected_prolonged_map() {
    let Some(path) = shapespace_test_support::shared_file("tosca/wolf0.off") else {
        eprintln!("tosca/wolf0.off: not found beside the repository; skipped");
        return;
    };
    let mesh = shapespace_geometry::io::read_mesh(&path).unwrap();
    let map = sphere_gradient_flow_map(&mesh, &SphereFlowParams::default()).unwrap();
    let lie = sphere_lie_map(&mesh, &SphereLieParams::default()).unwrap();
    let p95 = |x: &[[f64; 3]]| {
        sphere_map_distortion("m", &mesh, x)
            .unwrap()
            .abs_vertex_log_area_ratio
            .p95
    };
    let (conformal, flowed, advected) = (p95(&map.conformal.positions), p95(&map.positions), p95(&lie.positions));
    let info = &map.info.multiresolution;
    eprintln!("wolf0: p95 |ε| {flowed:.3} (conformal {conformal:.3}, Lie {advected:.3}); {info:?}");
    assert_eq!(map.info.num_flipped, 0);
    // (the Lie map's 448 folds: 16 left by the chart repair before its foldover-free
    // untangling, none now)
    assert_eq!(lie.info.num_flipped, 0);
    assert_eq!((info.levels.len(), info.prolonged_folds_after_repair), (2, 0));
    assert_eq!(info.fallback, None);
    assert!(!info.uncorrected_start && info.correction_mean_steps > 0.0, "{info:?}");
    assert!(flowed < 0.15 * conformal, "{flowed} against {conformal}");
    assert!(flowed < 0.5 * advected, "{flowed} against {advected}");
}

/// The bundled neutral face (9.4k vertices): the Moser advection of the prolonged coarse map
/// folds a few faces where the conformal image crowds, the fold repair undoes them (as it does
/// the Lie map's), and the flow on the mesh starts from that corrected map. It ends closer to
/// the optimal map than the single-level flow, which stalls at its Lie start: lower curl part,
/// lower transport cost, lower area distortion, nearer the Newton OMT map, no fold.
///
/// Measured: Moser correction 4.8 steps per vertex; ‖ζ‖/‖u‖ 1.2e-3 against 3.7e-2, cost 0.0626
/// against 0.0650, p95 |Υ| 0.241 against 0.292 (the Lie map's area-rate correction applied),
/// max distance to the Newton OMT map 2.07e-2 against 0.164.
#[test]
fn bundled_face_starts_from_the_corrected_prolonged_map() {
    let path = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("../../datasets/faces/id00_neutral.obj");
    let mesh = shapespace_geometry::io::read_mesh(&path).unwrap();
    let multi = gradient_flow_map(&mesh, &Markers::default(), &GradientFlowParams::default()).unwrap();
    let single = gradient_flow_map(&mesh, &Markers::default(), &single_level()).unwrap();
    let info = &multi.info.multiresolution;
    let (dm, ds) = (
        map_distortion("multi", &mesh, &multi.uv).unwrap(),
        map_distortion("single", &mesh, &single.uv).unwrap(),
    );
    let (m, s) = (&multi.info.flow, &single.info.flow);
    let omt = area_preserving_map(&mesh, &Markers::default(), &AreaPreservingParams::default()).unwrap();
    let (to_omt_multi, to_omt_single) = (max_distance(&multi.uv, &omt.uv), max_distance(&single.uv, &omt.uv));
    eprintln!(
        "id00_neutral: curl {:.2e} / {:.2e}, cost {:.5} / {:.5}, p95 |Υ| {:.3} / {:.3}, max |· − OMT| {to_omt_multi:.3e} / {to_omt_single:.3e}; {info:?}",
        m.final_curl, s.final_curl, m.final_cost, s.final_cost, dm.abs_area_distortion.p95, ds.abs_area_distortion.p95
    );
    assert_eq!(info.levels.len(), 2);
    assert_eq!(info.fallback, None);
    assert!(!info.uncorrected_start && info.correction_mean_steps > 0.0, "{info:?}");
    assert_eq!(dm.num_flipped + dm.num_degenerate, 0);
    assert!(
        m.final_curl < 0.2 * s.final_curl,
        "{} against {}",
        m.final_curl,
        s.final_curl
    );
    assert!(m.final_cost < s.final_cost);
    // (measured 0.241 against 0.292: the single-level flow starts from the Lie map, whose
    // area-rate correction already lowers it; 0.33 is the bound this test held the
    // multiresolution map to when the single level stood at 0.547)
    assert!(
        dm.abs_area_distortion.p95 < 0.33 && dm.abs_area_distortion.p95 < ds.abs_area_distortion.p95,
        "{} against {}",
        dm.abs_area_distortion.p95,
        ds.abs_area_distortion.p95
    );
    assert!(
        to_omt_multi < 0.3 * to_omt_single,
        "{to_omt_multi} against {to_omt_single}"
    );
}
