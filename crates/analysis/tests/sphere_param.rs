//! Area-preserving maps onto the sphere: an ellipsoid of revolution (1:1:2), whose conformal
//! map crowds the poles, and TOSCA wolf0 from the shared datasets.

use shapespace_analysis::sphere_param::{area_preserving_sphere_map, SphereAreaPreservingMap, SphereParamParams};
use shapespace_geometry::io::read_mesh;
use shapespace_geometry::quantities::vertex_dual_areas;
use shapespace_geometry::TriMesh;
use shapespace_omt::sphere::icosphere;

/// |ln(image one-ring area / 3D one-ring area)| per vertex, both normalized to their totals,
/// sorted: the image's flat chordal triangles on S² against the surface scaled to the same area.
fn log_area_ratios(mesh: &TriMesh, image: &[[f64; 3]]) -> Vec<f64> {
    let surface = vertex_dual_areas(mesh);
    let mapped = vertex_dual_areas(&TriMesh::new(image.to_vec(), mesh.faces.clone()).unwrap());
    let (s, m): (f64, f64) = (surface.iter().sum(), mapped.iter().sum());
    let mut r: Vec<f64> = surface
        .iter()
        .zip(&mapped)
        .map(|(a, b)| ((b / m) / (a / s)).ln().abs())
        .collect();
    r.sort_by(f64::total_cmp);
    r
}

fn p95(sorted: &[f64]) -> f64 {
    sorted[(0.95 * (sorted.len() - 1) as f64).round() as usize]
}

/// Checks common to every mesh: at most `max_flipped` flipped faces, each cell's area its target
/// to the solver's tolerance, every image on S², and the area distortion at most `factor` times
/// the conformal map's (95th percentile of |ln| of the one-ring area ratio). Returns both
/// percentiles.
fn check(mesh: &TriMesh, map: &SphereAreaPreservingMap, factor: f64, max_flipped: usize) -> (f64, f64) {
    assert!(map.num_flipped <= max_flipped, "{} flipped faces", map.num_flipped);
    for (v, (a, m)) in map.cell_areas.iter().zip(&map.target_masses).enumerate() {
        assert!(
            (a - m).abs() <= 1e-6 * m * 1.0001,
            "vertex {v}: cell area {a}, target {m}"
        );
    }
    for p in &map.positions {
        assert!(((p[0] * p[0] + p[1] * p[1] + p[2] * p[2]).sqrt() - 1.0).abs() < 1e-12);
    }
    let conformal = p95(&log_area_ratios(mesh, &map.conformal.positions));
    let preserving = p95(&log_area_ratios(mesh, &map.positions));
    assert!(
        preserving < factor * conformal,
        "p95 |ln area ratio|: {preserving} against {conformal}"
    );
    (conformal, preserving)
}

#[test]
fn an_ellipsoid_becomes_area_preserving_without_flips() {
    let (vertices, faces) = icosphere(4);
    let positions = vertices.iter().map(|v| [v[0], v[1], 2.0 * v[2]]).collect();
    let mesh = TriMesh::new(positions, faces).unwrap();
    let map = area_preserving_sphere_map(&mesh, &SphereParamParams::default()).unwrap();
    let (conformal, preserving) = check(&mesh, &map, 0.2, 0);
    eprintln!(
        "ellipsoid 1:1:2, {} V: p95 |ln area ratio| conformal {conformal:.3}, area-preserving {preserving:.4}; {} Newton steps on {} subdivisions",
        mesh.num_vertices(),
        map.iterations,
        map.source_subdivisions
    );
}

#[test]
fn tosca_wolf_becomes_area_preserving_without_flips() {
    let Some(path) = shapespace_test_support::shared_file("tosca/wolf0.off") else {
        return;
    };
    let mesh = read_mesh(&path).unwrap();
    let map = area_preserving_sphere_map(&mesh, &SphereParamParams::default()).unwrap();
    // the centroid map folds faces here; the repairs must leave none
    assert!(map.flipped_before_repair > 0);
    let (conformal, preserving) = check(&mesh, &map, 0.2, 0);
    eprintln!(
        "wolf0: {} folded by the centroid map, {} after the chart repair ({} vertices moved, {} charts); p95 |ln area ratio| conformal {conformal:.3}, area-preserving {preserving:.4}",
        map.flipped_before_repair, map.num_flipped, map.fold_repair.as_ref().map_or(0, |i| i.vertices_moved), map.fold_repair.as_ref().map_or(0, |i| i.repaired)
    );
}

/// GOAST finger0: the conformal image crowds the fingertip's vertices 3e-11 apart (densities to
/// 4e17), where the Voronoi start of the OT holds cells of 1e-21 against targets of 1e-3 and
/// the Newton steps stall at the first step. The coarse-to-fine start solves it: every cell gets
/// its target area to the solver's tolerance, and the area distortion drops from the conformal
/// map's (p95 |ln| ≈ 32) to below two percent of it. The centroid map folds faces near the tip,
/// some in charts whose boundary is not convex (the planar repair's whole-patch Tutte solve
/// then folds too); grown around their reflex corners, the charts unfold them all.
#[test]
fn goast_finger_converges_from_the_coarse_to_fine_start() {
    let Some(path) = shapespace_test_support::shared_file("goast/finger/finger0.ply") else {
        return;
    };
    let mesh = read_mesh(&path).unwrap();
    let map = area_preserving_sphere_map(&mesh, &SphereParamParams::default()).unwrap();
    assert!(map.flipped_before_repair > 0);
    let (conformal, preserving) = check(&mesh, &map, 0.02, 0);
    assert!(conformal > 10.0, "{conformal}");
    eprintln!(
        "finger0: {} Newton steps; p95 |ln area ratio| conformal {conformal:.3}, area-preserving {preserving:.4}; {} folded before the repair, 0 after ({:?})",
        map.iterations, map.flipped_before_repair, map.fold_repair
    );
}

/// A Sumner cat pose (7,207 vertices, crowded paws and tail): the OT converges from the
/// coarse-to-fine start and the chart repair leaves no face folded.
#[test]
fn sumner_cat_becomes_area_preserving_without_flips() {
    let Some(path) = shapespace_test_support::shared_file("sumner_deformation_transfer/cat-poses/0005.obj") else {
        return;
    };
    let mesh = read_mesh(&path).unwrap();
    let map = area_preserving_sphere_map(&mesh, &SphereParamParams::default()).unwrap();
    assert!(map.flipped_before_repair > 0);
    let (conformal, preserving) = check(&mesh, &map, 0.05, 0);
    eprintln!(
        "cat 0005: {} Newton steps; p95 |ln area ratio| conformal {conformal:.3}, area-preserving {preserving:.4}; {} folded before the repair, 0 after",
        map.iterations, map.flipped_before_repair
    );
}

/// Sumner cat 0006 (crowded paws): 16 faces stayed folded when a chart's whole-patch Tutte solve
/// that still folded was given up and each cluster was tried once. Kernel moves on such a
/// solve and a second pass over the clusters given up unfolded them (decision 0048); now the
/// foldover-free untangling unfolds the clusters every Tutte chart fails in the first pass
/// (decision 0051): no face is left folded, after one pass.
#[test]
fn sumner_cat_paws_unfold_in_one_pass() {
    let Some(path) = shapespace_test_support::shared_file("sumner_deformation_transfer/cat-poses/0006.obj") else {
        return;
    };
    let mesh = read_mesh(&path).unwrap();
    let map = area_preserving_sphere_map(&mesh, &SphereParamParams::default()).unwrap();
    let repair = map.fold_repair.as_ref().unwrap();
    assert!(map.flipped_before_repair > 100, "{}", map.flipped_before_repair);
    assert_eq!(repair.passes, 1, "{repair:?}");
    assert!(repair.untangle_repaired >= 1, "{repair:?}");
    let (conformal, preserving) = check(&mesh, &map, 0.05, 0);
    eprintln!(
        "cat 0006: {} folded before the repair, 0 after ({repair:?}); p95 |ln area ratio| conformal {conformal:.3}, area-preserving {preserving:.4}",
        map.flipped_before_repair
    );
}

/// Sumner cat 0001 (crowded paws and tail): 9 faces stayed folded where every chart's
/// whole-patch Tutte solve left some folded even after the kernel moves. The foldover-free
/// untangling in the same charts unfolds them, and the repaired map preserves area better than
/// the one that kept them (p95 |ln area ratio| 0.846 then, 0.822 now).
#[test]
fn sumner_cat_folds_left_by_tutte_are_untangled() {
    let Some(path) = shapespace_test_support::shared_file("sumner_deformation_transfer/cat-poses/0001.obj") else {
        return;
    };
    let mesh = read_mesh(&path).unwrap();
    let map = area_preserving_sphere_map(&mesh, &SphereParamParams::default()).unwrap();
    let repair = map.fold_repair.as_ref().unwrap();
    assert!(map.flipped_before_repair > 300, "{}", map.flipped_before_repair);
    assert!(repair.untangle_repaired >= 1, "{repair:?}");
    let (conformal, preserving) = check(&mesh, &map, 0.05, 0);
    assert!(preserving < 0.84, "{preserving}");
    eprintln!(
        "cat 0001: {} folded before the repair, 0 after ({repair:?}); p95 |ln area ratio| conformal {conformal:.3}, area-preserving {preserving:.4}",
        map.flipped_before_repair
    );
}

/// GOAST cactus5: a cluster of its centroid map's folds that no gnomonic chart within 1.45 rad
/// and a quarter of the faces unfolds is unfolded in a stereographic chart; no face is left
/// folded.
#[test]
fn goast_cactus5_unfolds_in_a_stereographic_chart() {
    let Some(path) = shapespace_test_support::shared_file("goast/cactus/cactus5.ply") else {
        return;
    };
    let mesh = read_mesh(&path).unwrap();
    let map = area_preserving_sphere_map(&mesh, &SphereParamParams::default()).unwrap();
    assert!(map.flipped_before_repair > 0);
    let repair = map.fold_repair.as_ref().unwrap();
    assert!(repair.stereographic_repaired >= 1, "{repair:?}");
    assert_eq!(repair.clusters_too_large, 0, "{repair:?}");
    let (conformal, preserving) = check(&mesh, &map, 0.05, 0);
    eprintln!(
        "cactus5: {} folded before the repair, 0 after ({repair:?}); p95 |ln area ratio| conformal {conformal:.3}, area-preserving {preserving:.4}",
        map.flipped_before_repair
    );
}
