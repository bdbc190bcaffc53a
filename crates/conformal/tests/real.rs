//! Real meshes: the repository's `datasets/` (faces, poses) and the public disks of the shared
//! datasets folder (`$SHAPESPACE_DATA`, default `../shared/datasets`; a test whose files are
//! absent is skipped with a `SKIPPED` line naming them).
//!
//! Observed (auto markers unless stated; Λ = ln(γmax/γmin) mean / p95 / max):
//! * camelhead (11,381 V): 6,488 intrinsic flips remove all 4,881 negative interior weights;
//!   no flipped image triangle; Λ 0.068 / 0.174 / 3.77.
//! * ICT face id00_neutral (9,412 V, markers from faces/landmarks.json): 4,867 flips remove
//!   4,619 negative weights; no flipped triangle; Λ 0.059 / 0.215 / 1.71. With the plain
//!   cotangent Laplacian the same face folds 37 triangles (flipped area 5.2e-5).
//! * the 40 ICT faces: 33 without any fold; 7 (happy/sad) fold one sliver of 165°–175° each,
//!   which the local repair fixes by moving 1–5 vertices (Λ max rises to 5–9 on those slivers).
//! * face.obj (25,905 V): 13,008 negative weights → 0; Λ 0.029 / 0.063 / 0.200.
//! * TOSCA michael0 (not bundled; a fixture of 282 vertices): a fold of adjacent slivers that no
//!   single-vertex move removes; the patch re-embedding moves 92 vertices.
//! * alligator (flat, long tail; `common_3d_test_models/alligator.obj`): boundary crowding, 1 − |φ| ≈ 1e-15
//!   in the tail → a clear `OutOfRange` error instead of 13 folded triangles.

use crate::common::*;
use shapespace_conformal::{disk_map, ConformalError, DiskMapParams, MarkerFile, Markers};
use shapespace_geometry::io::read_mesh;

#[test]
fn camelhead_has_no_flips() {
    let Some(path) = shared_file("libigl_tutorial_data/camelhead.off") else {
        return;
    };
    let m = read_mesh(&path).unwrap();
    let dm = map(&m, &Markers::default());
    assert_eq!(dm.quality.num_flipped + dm.quality.num_degenerate, 0);
    assert!(dm.info.negative_weights_before > 1000);
    assert_eq!(dm.info.negative_weights_after, 0);
    assert!(dm.face_densities.iter().all(|&x| x > 0.0 && x.is_finite()));
    let q = &dm.quality.quasi_conformal_distortion;
    eprintln!("camelhead Λ {q:?}");
    assert!(q.mean < 0.1 && q.p95 < 0.25, "{q:?}");
    for (v, z) in dm.uv.iter().enumerate() {
        assert!(z[0].hypot(z[1]) <= 1.0 + 1e-15, "vertex {v}");
    }
}

#[test]
fn ict_face_has_no_flips_and_plain_cotan_folds() {
    let Some(d) = datasets_dir() else { return };
    let path = d.join("faces/id00_neutral.obj");
    let m = read_mesh(&path).unwrap();
    let sidecar = MarkerFile::sidecar_path(&path).expect("faces/landmarks.json");
    let markers = MarkerFile::from_json_file(&sidecar).unwrap().markers;
    let dm = map(&m, &markers);
    assert_eq!(dm.quality.num_flipped + dm.quality.num_degenerate, 0);
    assert_eq!(dm.info.negative_weights_after, 0);
    let q = &dm.quality.quasi_conformal_distortion;
    eprintln!("ICT face Λ {q:?}, flips {}", dm.info.intrinsic_flips);
    assert!(q.mean < 0.1 && q.p95 < 0.3, "{q:?}");
    match disk_map(
        &m,
        &markers,
        &DiskMapParams {
            intrinsic_delaunay: false,
            repair_folds: false,
            ..Default::default()
        },
    ) {
        Err(ConformalError::FoldedImage { num_flipped, .. }) => assert!(num_flipped > 0),
        other => panic!(
            "plain cotan Laplacian should fold this face, got {:?}",
            other.map(|d| d.quality)
        ),
    }
}

#[test]
fn face_expressions_map_without_flips_after_a_few_repairs() {
    // over all 40 faces (measured once): 33 have no fold at all; 7 (happy/sad expressions,
    // compressed lips) fold 1 sliver (angles 165°–175°) each, repaired by moving 1–5 vertices
    let Some(d) = datasets_dir() else { return };
    let markers = MarkerFile::from_json_file(&d.join("faces/landmarks.json"))
        .unwrap()
        .markers;
    for (name, raw_folds) in [("id01_happy", true), ("id02_sad", true), ("id03_surprise", false)] {
        let m = read_mesh(&d.join(format!("faces/{name}.obj"))).unwrap();
        let dm = map(&m, &markers);
        assert_eq!(dm.quality.num_flipped + dm.quality.num_degenerate, 0, "{name}");
        assert!(dm.info.fold_repairs <= 5, "{name}: {}", dm.info.fold_repairs);
        assert_eq!(dm.info.fold_repairs > 0, raw_folds, "{name}");
        let raw = disk_map(
            &m,
            &markers,
            &DiskMapParams {
                repair_folds: false,
                ..Default::default()
            },
        );
        assert_eq!(
            matches!(raw, Err(ConformalError::FoldedImage { .. })),
            raw_folds,
            "{name}"
        );
    }
}

/// The meshes of a bundled folder (OBJ, OFF, PLY), sorted, with their sidecar markers
/// (`NAME.landmarks.json` or `landmarks.json` beside them; `auto` when there is none).
fn bundled_meshes(dir: &std::path::Path) -> Vec<(std::path::PathBuf, Markers)> {
    let mut paths: Vec<_> = std::fs::read_dir(dir)
        .unwrap()
        .map(|e| e.unwrap().path())
        .filter(|p| {
            p.extension()
                .is_some_and(|x| ["obj", "off", "ply"].contains(&x.to_str().unwrap_or("")))
        })
        .collect();
    paths.sort();
    paths
        .into_iter()
        .map(|p| {
            let markers = MarkerFile::sidecar_path(&p)
                .map(|f| MarkerFile::from_json_file(&f).unwrap().markers)
                .unwrap_or_default();
            (p, markers)
        })
        .collect()
}

/// The real-data check over whole folders, so a disk added to `datasets/` is checked too:
/// every mesh in `poses/*/`, the neutral face of each identity and every public disk of the
/// shared folder ([`PUBLIC_DISKS`]) maps with no flipped or degenerate image triangle, positive
/// finite densities and the boundary on the circle (Λ statistics printed). The public disk whose
/// conformal image is beyond f64 (the alligator, its tail at 1 − |z| ≈ 1e-15.5 for every
/// interior marker) is refused with the range error instead (1 − |z| below 1e-10).
///
/// Measured over these 23 meshes: Λ mean 0.029 (libigl face) … 0.30 (cat head, 131 V), p95
/// 0.063 … 0.66 (wolf), max 0.20 … 16.4 (centaur: slivers in the crowded limbs).
#[test]
fn every_bundled_disk_maps_without_flips_and_beyond_f64_ones_are_refused() {
    let Some(d) = datasets_dir() else { return };
    let mut meshes: Vec<(String, std::path::PathBuf, Markers)> = Vec::new();
    for pose in ["wolf", "centaur"] {
        for (p, m) in bundled_meshes(&d.join("poses").join(pose)) {
            meshes.push((p.strip_prefix(&d).unwrap().display().to_string(), p, m));
        }
    }
    for (p, m) in bundled_meshes(&d.join("faces")) {
        if p.to_string_lossy().ends_with("_neutral.obj") {
            meshes.push((p.strip_prefix(&d).unwrap().display().to_string(), p, m));
        }
    }
    assert_eq!(meshes.len(), 6 + 10, "bundled meshes");
    let public: Vec<_> = PUBLIC_DISKS.iter().filter_map(|(_, rel)| shared_file(rel)).collect();
    for (path, (name, _)) in public.iter().zip(PUBLIC_DISKS) {
        meshes.push((name.to_string(), path.clone(), Markers::default()));
    }
    eprintln!(
        "{} meshes: 16 bundled, {} of {} public disks found",
        meshes.len(),
        public.len(),
        PUBLIC_DISKS.len()
    );
    for (name, path, markers) in &meshes {
        let m = read_mesh(path).unwrap();
        let dm = disk_map(&m, markers, &DiskMapParams::default()).unwrap_or_else(|e| panic!("{}: {e}", path.display()));
        assert_eq!(dm.quality.num_flipped + dm.quality.num_degenerate, 0, "{name}");
        assert!(dm.face_densities.iter().all(|&x| x > 0.0 && x.is_finite()), "{name}");
        for (v, z) in dm.uv.iter().enumerate() {
            assert!(z[0].hypot(z[1]) <= 1.0 + 1e-12, "{name}: vertex {v} outside the disk");
        }
        let q = &dm.quality.quasi_conformal_distortion;
        eprintln!("{name}: Λ mean {:.3} p95 {:.3} max {:.2}", q.mean, q.p95, q.max);
        assert!(q.mean.is_finite() && q.p95 < 1.0, "{name}: {q:?}");
    }
    let Some(path) = shared_file(shapespace_test_support::BEYOND_F64_DISK) else {
        return;
    };
    let m = read_mesh(&path).unwrap();
    match disk_map(&m, &Markers::default(), &DiskMapParams::default()) {
        Err(ConformalError::OutOfRange { log10_value, .. }) => assert!(log10_value < -10.0),
        other => panic!(
            "{}: expected a range error, got {:?}",
            path.display(),
            other.map(|d| d.quality)
        ),
    }
}

/// The ICT template face (4 boundary loops) with the three inner loops filled by a centroid fan
/// (triangles (L[j+1], L[j], c), as in datasets/README): a private helper of this test.
fn fill_inner_loops(mesh: &shapespace_geometry::TriMesh) -> shapespace_geometry::TriMesh {
    let conn = shapespace_geometry::Connectivity::of(mesh);
    let loops = conn.boundary_loops(&mesh.faces);
    let mut out = mesh.clone();
    for l in loops.iter().skip(1) {
        let c = out.positions.len() as u32;
        let mut centroid = [0.0; 3];
        for &v in l {
            for d in 0..3 {
                centroid[d] += mesh.positions[v as usize][d] / l.len() as f64;
            }
        }
        out.positions.push(centroid);
        for j in 0..l.len() {
            out.faces.push([l[(j + 1) % l.len()], l[j], c]);
        }
    }
    out
}

#[test]
fn shared_ict_template_with_filled_holes_has_no_flips() {
    let Some(path) = shared_file("ict_facekit/template_face_full_neutral.obj") else {
        return;
    };
    let raw = read_mesh(&path).unwrap();
    assert!(matches!(
        disk_map(&raw, &Markers::default(), &DiskMapParams::default()),
        Err(ConformalError::NotDisk { .. })
    ));
    let m = fill_inner_loops(&raw);
    let dm = map(&m, &Markers::default());
    assert_eq!(dm.quality.num_flipped + dm.quality.num_degenerate, 0);
    eprintln!(
        "ICT template: Λ {:?}, repairs {}",
        dm.quality.quasi_conformal_distortion, dm.info.fold_repairs
    );
    assert!(dm.quality.quasi_conformal_distortion.p95 < 0.3);
}

/// A fold no single-vertex move can remove (TOSCA michael0: adjacent slivers of 147°–165° whose
/// one-ring kernels are empty; fixture: the 8-ring patch of its disk map after the single-vertex
/// repair, border fixed). The patch re-embedding (mean value weights on the surface's angles,
/// 4 rings, measured) unfolds it, and moves no fixed vertex.
#[test]
fn a_fold_of_adjacent_slivers_is_repaired_by_a_patch() {
    use shapespace_conformal::fold_repair::local::repair_folds;
    use shapespace_conformal::quality::orient_scaled;
    let text = include_str!("fixtures/michael0_fold_patch.txt");
    let (mut uv, mut fixed, mut faces, mut angles) = (Vec::new(), Vec::new(), Vec::new(), Vec::new());
    for line in text.lines().filter(|l| !l.starts_with('#')) {
        let t: Vec<&str> = line.split_whitespace().collect();
        match t[0] {
            "v" => {
                uv.push([t[1].parse::<f64>().unwrap(), t[2].parse::<f64>().unwrap()]);
                fixed.push(t[3] == "1");
            }
            _ => {
                faces.push([0, 1, 2].map(|k| t[1 + k].parse::<u32>().unwrap()));
                angles.push([0, 1, 2].map(|k| t[4 + k].parse::<f64>().unwrap()));
            }
        }
    }
    let mut vertex_faces = vec![Vec::new(); uv.len()];
    for (f, face) in faces.iter().enumerate() {
        for &v in face {
            vertex_faces[v as usize].push(f as u32);
        }
    }
    let folded = |uv: &[[f64; 2]]| {
        faces
            .iter()
            .filter(|f| {
                orient_scaled(uv[f[0] as usize], uv[f[1] as usize], uv[f[2] as usize])
                    != geogram_predicates::Sign::Positive
            })
            .count()
    };
    assert_eq!(folded(&uv), 1);
    let before = uv.clone();
    let moves = repair_folds(&faces, &vertex_faces, &angles, &fixed, &mut uv);
    assert_eq!(folded(&uv), 0);
    assert!(moves > 0);
    for v in 0..uv.len() {
        if fixed[v] {
            assert_eq!(uv[v], before[v], "fixed vertex {v} moved");
        }
    }
    eprintln!("michael0 patch: {moves} vertices moved");
}

/// The bundled TOSCA centaur0 slit from two extremities (`prepare_disk` with
/// `seam_extremities: 2`): the zigzag edge path of the second slit has reflex boundary corners
/// at which the Green's-function map folds 39 faces that its repair cannot fix; BFF maps the
/// same mesh without a fold, so `disk_map` returns BFF's map and says so. Without the fallback
/// the fold is the error it was.
#[test]
fn folds_of_the_green_map_fall_back_to_bff() {
    let Some(d) = datasets_dir() else { return };
    let m = read_mesh(&d.join("poses/centaur/centaur0.off")).unwrap();
    let options = shapespace_geometry::prepare::PrepareOptions {
        seam_extremities: 2,
        ..Default::default()
    };
    let (slit, _, report) = shapespace_geometry::prepare::prepare_disk(&m, &options).unwrap();
    assert_eq!(report.seam_extremities.len(), 2);
    let dm = map(&slit, &Markers::default());
    let fallback = dm
        .info
        .bff_fallback
        .as_ref()
        .expect("the Green's-function map folds here");
    assert!(fallback.green_folds > 10, "{}", fallback.green_folds);
    assert!(dm.info.method.contains("fallback"), "{}", dm.info.method);
    assert_eq!(dm.quality.num_flipped + dm.quality.num_degenerate, 0);
    let q = &dm.quality.quasi_conformal_distortion;
    assert!(q.mean < 0.3 && q.p95 < 0.7, "{q:?}");
    assert!(dm.face_densities.iter().all(|&x| x.is_finite() && x > 0.0));
    match disk_map(
        &slit,
        &Markers::default(),
        &DiskMapParams {
            bff_fallback: false,
            region_repair: false,
            ..Default::default()
        },
    ) {
        Err(ConformalError::FoldedImage { num_flipped, .. }) => assert_eq!(num_flipped, fallback.green_folds),
        other => panic!(
            "expected the Green's-function folds, got {:?}",
            other.map(|d| d.quality)
        ),
    }
    // without BFF, the region repair re-embeds the Green's map around its folds: no fold, and
    // the rest of the map is the Green's map (most vertices do not move, none far)
    let repaired = disk_map(
        &slit,
        &Markers::default(),
        &DiskMapParams {
            bff_fallback: false,
            ..Default::default()
        },
    )
    .unwrap();
    let region = repaired.info.region_repair.as_ref().expect("a region repair");
    assert_eq!(region.flipped_before + region.degenerate_before, fallback.green_folds);
    assert_eq!(repaired.quality.num_flipped + repaired.quality.num_degenerate, 0);
    assert!(region.vertices_moved * 4 < slit.num_vertices(), "{region:?}");
    assert!(region.max_displacement < 0.02, "{region:?}");
    eprintln!(
        "centaur0 slit: Green's map region repair moved {} of {} vertices, at most {:.2e}",
        region.vertices_moved,
        region.max_displacement,
        slit.num_vertices()
    );
}
