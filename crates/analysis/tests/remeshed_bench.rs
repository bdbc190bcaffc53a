//! `register_bench` with remeshed targets on a small synthetic class: two bent spherical caps
//! (the same vertex order) and their remeshings (the same surfaces sampled by a finer ring
//! layout), ground truth carried over by closest point.

use std::path::{Path, PathBuf};

use shapespace_analysis::registration::bench::{register_bench, BenchRow, Triangulation};
use shapespace_analysis::registration::ZoomOutParams;
use shapespace_analysis::registration::{registration_area_params, HarmonicParams, Method, MetricParams, Refinement};
use shapespace_geometry::primitives::spherical_cap;
use shapespace_geometry::TriMesh;

const ALPHA: f64 = 1.2;

/// Pose k of the cap meshed with `rings` rings: the cap of half-angle ALPHA bent by a pose-
/// dependent smooth map (not an isometry, not a similarity).
fn pose(k: usize, rings: usize) -> TriMesh {
    let mut m = spherical_cap(ALPHA, rings);
    for p in &mut m.positions {
        let [x, y, z] = *p;
        *p = match k {
            0 => [x, y, z + 0.3 * x * x],
            _ => [x + 0.25 * y * y, 1.1 * y, z - 0.2 * x * y],
        };
    }
    m
}

fn write_obj(path: &Path, m: &TriMesh) {
    let mut s = String::new();
    for p in &m.positions {
        s += &format!("v {:.17} {:.17} {:.17}\n", p[0], p[1], p[2]);
    }
    for f in &m.faces {
        s += &format!("f {} {} {}\n", f[0] + 1, f[1] + 1, f[2] + 1);
    }
    std::fs::write(path, s).unwrap();
}

/// The vertex of the undeformed cap (`rings` rings) nearest the direction (θ, φ), among the
/// boundary ones when `boundary`.
fn vertex_at(rings: usize, theta: f64, phi: f64, boundary: bool) -> u32 {
    let m = spherical_cap(ALPHA, rings);
    let q = [theta.sin() * phi.cos(), theta.sin() * phi.sin(), theta.cos()];
    let n_boundary = 6 * rings;
    let first = if boundary { m.positions.len() - n_boundary } else { 0 };
    let last = if boundary {
        m.positions.len()
    } else {
        m.positions.len() - n_boundary
    };
    (first..last)
        .min_by(|&a, &b| {
            let d = |v: usize| (0..3).map(|k| (m.positions[v][k] - q[k]).powi(2)).sum::<f64>();
            d(a).total_cmp(&d(b))
        })
        .unwrap() as u32
}

/// A dataset `cap/cap{0,1}.obj` (12 rings) with markers, and remeshings of both: `remeshed`
/// rings each (the same vertices as the poses when `remeshed` = 12).
fn dataset(dir: &Path, remeshed: usize) -> (PathBuf, PathBuf) {
    let (data, re) = (dir.join("dataset"), dir.join("remeshed"));
    std::fs::create_dir_all(data.join("cap")).unwrap();
    std::fs::create_dir_all(re.join("cap")).unwrap();
    for k in 0..2 {
        write_obj(&data.join(format!("cap/cap{k}.obj")), &pose(k, 12));
        write_obj(&re.join(format!("cap/cap{k}.obj")), &pose(k, remeshed));
    }
    let lm = serde_json::json!({
        "center": 0,
        "boundary": vertex_at(12, ALPHA, 0.0, true),
        "landmarks": {
            "a": vertex_at(12, 0.7, 0.3, false),
            "b": vertex_at(12, 0.7, 2.4, false),
            "c": vertex_at(12, 0.8, 4.4, false),
        }
    });
    std::fs::write(data.join("cap/landmarks.json"), lm.to_string()).unwrap();
    (data, re)
}

fn run(dir: &Path, remeshed: usize, refine: Refinement) -> Vec<BenchRow> {
    let _ = std::fs::remove_dir_all(dir);
    let (data, re) = dataset(dir, remeshed);
    let zoomout = ZoomOutParams {
        k_end: 40,
        ..ZoomOutParams::default()
    };
    let res = register_bench(
        &data,
        &dir.join("out"),
        Some(&re),
        &[Method::Omt],
        &registration_area_params(),
        &HarmonicParams::for_method,
        refine,
        &zoomout,
        &MetricParams::default(),
        |_| {},
    )
    .unwrap();
    for r in &res.rows {
        eprintln!(
            "{} -> {} {}: {} geodesic mean {:.5} median {:.5} flipped 3D {:.5} truth max {:.2e}",
            r.source,
            r.target,
            r.triangulation,
            r.status,
            r.geodesic_mean,
            r.geodesic_median,
            r.flipped_ratio_3d,
            r.truth_max_distance
        );
    }
    assert_eq!(res.rows.len(), 4);
    assert!(res.rows.iter().all(|r| r.status == "ok"));
    res.rows
}

fn scratch(name: &str) -> PathBuf {
    std::env::temp_dir().join(format!("shapespace-{name}-{}", std::process::id()))
}

/// A "remeshing" that is the pose itself: its ground truth is each vertex (closest point at
/// distance 0), its markers the pose's, so the remeshed rows must equal the same-triangulation
/// rows bit for bit (the point-source geodesic error reduces to the vertex-source one).
#[test]
fn a_remeshing_equal_to_the_pose_gives_the_same_rows() {
    let dir = scratch("remeshed-identity");
    let rows = run(&dir, 12, Refinement::None);
    for tri in [Triangulation::Same, Triangulation::Remeshed] {
        assert_eq!(rows.iter().filter(|r| r.triangulation == tri).count(), 2);
    }
    for same in rows.iter().filter(|r| r.triangulation == Triangulation::Same) {
        let re = rows
            .iter()
            .find(|r| r.triangulation == Triangulation::Remeshed && r.source == same.source && r.target == same.target)
            .unwrap();
        assert_eq!(re.truth_max_distance, 0.0);
        assert_eq!(re.geodesic_mean, same.geodesic_mean);
        assert_eq!(re.geodesic_median, same.geodesic_median);
        assert_eq!(re.flipped_ratio_3d, same.flipped_ratio_3d);
    }
    // the ground truth file: one line per vertex of the pose, each at a corner
    let truth = std::fs::read_to_string(dir.join("out/truth/cap/cap1.csv")).unwrap();
    let n = pose(1, 12).positions.len();
    assert_eq!(truth.lines().count(), n + 1);
    let json = std::fs::read_to_string(dir.join("out/truth/cap/cap1.landmarks.json")).unwrap();
    let carried: serde_json::Value = serde_json::from_str(&json).unwrap();
    assert_eq!(
        carried["landmarks"]["a"],
        serde_json::json!(vertex_at(12, 0.7, 0.3, false))
    );
    let _ = std::fs::remove_dir_all(&dir);
}

/// Real remeshings (17 rings against 12): the ground truth lies within the interpolation error
/// of the surfaces, and the registration onto the remeshed pose is about as accurate as onto
/// the pose itself (the same smooth surface). Measured: truth within 6.3e-4 of √area; geodesic
/// error means 0.0138 / 0.0209 (same) and 0.0216 / 0.0204 (remeshed), no flipped area (0.0241 /
/// 0.0240 and 0.0295 / 0.0283 without the landmark pairs in ZoomOut's fits, decision 0066).
/// Asserted: each pair below 0.025, the class mean onto the remeshings within 1.3× of the one
/// onto the poses (measured 1.21; the same-triangulation pairs can hit vertices exactly, and the
/// first pair does on most of the cap, median 0), no flips.
#[test]
fn remeshed_targets_are_registered_about_as_well_as_the_poses() {
    let dir = scratch("remeshed-17");
    let rows = run(&dir, 17, Refinement::ZoomOut);
    let class_mean = |t: Triangulation| {
        let r: Vec<f64> = rows
            .iter()
            .filter(|r| r.triangulation == t)
            .map(|r| r.geodesic_mean)
            .collect();
        r.iter().sum::<f64>() / r.len() as f64
    };
    let (same_mean, remeshed_mean) = (class_mean(Triangulation::Same), class_mean(Triangulation::Remeshed));
    assert!(
        remeshed_mean < 1.3 * same_mean,
        "remeshed {remeshed_mean} against same {same_mean}"
    );
    for same in rows.iter().filter(|r| r.triangulation == Triangulation::Same) {
        let re = rows
            .iter()
            .find(|r| r.triangulation == Triangulation::Remeshed && r.source == same.source && r.target == same.target)
            .unwrap();
        assert!(
            re.truth_max_distance > 0.0 && re.truth_max_distance < 1e-3,
            "{}",
            re.truth_max_distance
        );
        assert!(same.geodesic_mean < 0.025, "same: {}", same.geodesic_mean);
        assert!(re.geodesic_mean < 0.025, "remeshed: {}", re.geodesic_mean);
        assert!(re.flipped_ratio_3d < 1e-3, "remeshed flips: {}", re.flipped_ratio_3d);
    }
    let _ = std::fs::remove_dir_all(&dir);
}
