//! The `run_mds` pipeline on a synthetic face-like distance matrix written to CSV.

use std::path::PathBuf;

use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use shapespace_analysis::shape_space::{run_mds, MdsMethod, MdsParams, ShapeSpaceStats};
use shapespace_analysis::stats::loo_1nn_accuracy_across;
use shapespace_analysis::{read_labels, write_distance_matrix, AnalysisError, DistanceMatrix};

fn dir(name: &str) -> PathBuf {
    let d = PathBuf::from(env!("CARGO_TARGET_TMPDIR"))
        .join("shape_space")
        .join(name);
    let _ = std::fs::remove_dir_all(&d); // outputs of an earlier run
    std::fs::create_dir_all(&d).unwrap();
    d
}

/// 8 people × 5 expressions in ℝ⁴: person offsets ~0.05, expression offsets ~0.015, a little
/// noise; distances made slightly asymmetric (±0.2%, like the two OT directions).
fn faces(rng: &mut ChaCha8Rng) -> (DistanceMatrix, String) {
    let expressions = ["neutral", "smile", "anger", "surprise", "disgust"];
    let people: Vec<[f64; 4]> = (0..8)
        .map(|_| std::array::from_fn(|_| rng.random_range(-0.05..0.05)))
        .collect();
    let expr: Vec<[f64; 4]> = (0..5)
        .map(|_| std::array::from_fn(|_| rng.random_range(-0.015..0.015)))
        .collect();
    let mut pts = Vec::new();
    let mut names = Vec::new();
    let mut labels = String::from("file,identity,expression\n");
    for (p, pv) in people.iter().enumerate() {
        for (e, ev) in expr.iter().enumerate() {
            pts.push(std::array::from_fn::<f64, 4, _>(|k| {
                pv[k] + ev[k] + rng.random_range(-0.002..0.002)
            }));
            names.push(format!("id{p:02}_{}", expressions[e]));
            labels.push_str(&format!(
                "faces/id{p:02}_{}.obj,person{p:02},{}\n",
                expressions[e], expressions[e]
            ));
        }
    }
    let n = pts.len();
    let mut values = vec![0.0; n * n];
    for i in 0..n {
        for j in 0..n {
            if i != j {
                let e: f64 = (0..4).map(|k| (pts[i][k] - pts[j][k]).powi(2)).sum::<f64>().sqrt();
                values[i * n + j] = e * (1.0 + rng.random_range(-0.002..0.002));
            }
        }
    }
    (DistanceMatrix::new(names, values).unwrap(), labels)
}

#[test]
fn run_mds_writes_all_outputs_with_consistent_statistics() {
    let mut rng = ChaCha8Rng::seed_from_u64(42);
    let (d, labels_csv) = faces(&mut rng);
    let work = dir("faces");
    let dist_path = work.join("distances.csv");
    let labels_path = work.join("labels.csv");
    write_distance_matrix(&dist_path, &d).unwrap();
    std::fs::write(&labels_path, labels_csv).unwrap();
    let out = work.join("out");
    let params = MdsParams {
        dims: 3,
        marker_by: Some("expression".into()),
        ..MdsParams::default()
    };
    let result = run_mds(&dist_path, Some(&labels_path), &out, &params).unwrap();
    assert_eq!(result.color_by.as_deref(), Some("identity"));
    // with 3 dimensions the scatter matrix too
    assert_eq!(result.files.len(), 7);
    assert!(out.join("mds_matrix.png").is_file() && out.join("mds_matrix.svg").is_file());

    // mds.csv: header and 40 rows with 3 coordinates.
    let text = std::fs::read_to_string(out.join("mds.csv")).unwrap();
    let lines: Vec<&str> = text.lines().collect();
    assert_eq!(lines[0], "name,identity,expression,x1,x2,x3");
    assert_eq!(lines.len(), 41);
    assert!(lines[1].starts_with("id00_neutral,person00,neutral,"));
    let x1: f64 = lines[1].split(',').nth(3).unwrap().parse().unwrap();
    assert_eq!(x1, result.mds.coordinates[0][0]);

    // eigenvalues.csv: all 40 eigenvalues; shares of the positive ones sum to 1.
    let text = std::fs::read_to_string(out.join("eigenvalues.csv")).unwrap();
    let rows: Vec<Vec<f64>> = text
        .lines()
        .skip(1)
        .map(|l| l.split(',').map(|c| c.parse().unwrap()).collect())
        .collect();
    assert_eq!(rows.len(), 40);
    let positive_share: f64 = rows.iter().filter(|r| r[1] > 0.0).map(|r| r[2]).sum();
    assert!((positive_share - 1.0).abs() < 1e-12);
    // Data live in ℝ⁴ up to small noise and asymmetry: the first four dimensions dominate.
    let first4: f64 = rows.iter().take(4).map(|r| r[2]).sum();
    assert!(first4 > 0.95, "first four shares {first4}");

    // stats.json is the serialized result and parses back; it agrees with direct calls.
    let json = std::fs::read_to_string(out.join("stats.json")).unwrap();
    assert_eq!(json, serde_json::to_string_pretty(&result.stats).unwrap() + "\n");
    let stats: ShapeSpaceStats = serde_json::from_str(&json).unwrap();
    assert_eq!(stats.n, 40);
    assert_eq!(stats.labels["identity"].classes, 8);
    assert_eq!(stats.labels["expression"].classes, 5);
    // People are far apart relative to expressions: identity is recovered perfectly.
    assert_eq!(stats.labels["identity"].loo_1nn.accuracy, Some(1.0));
    assert!(stats.labels["identity"].silhouette.unwrap() > 0.5);
    assert!(stats.labels["identity"].distances.within.median < stats.labels["identity"].distances.between.median);
    // Two ordered pairs of columns.
    assert_eq!(stats.cross.len(), 2);
    let labels = read_labels(&labels_path, &d.names).unwrap();
    let direct = loo_1nn_accuracy_across(&d, &labels, "expression", "identity").unwrap();
    let cross = stats.cross.iter().find(|c| c.target == "expression").unwrap();
    assert_eq!(cross.exclude_same, "identity");
    assert_eq!(cross.loo_1nn, direct);
    // Asymmetry ±0.2% of each entry: relative gap below 0.4% of a distance; the mean
    // normalization makes it at most 0.004 · max(d)/mean(d).
    assert!(stats.symmetry.max_relative.unwrap() < 0.004 * 3.0);
    assert!(stats.symmetry.median_relative.unwrap() > 0.0);
    assert_eq!(stats.missing_pairs, 0);
    for ext in ["png", "svg"] {
        assert!(std::fs::metadata(out.join(format!("mds.{ext}"))).unwrap().len() > 5000);
    }

    // two dimensions into the same folder: the earlier scatter matrix would describe another
    // embedding, and is removed
    let two = run_mds(&dist_path, Some(&labels_path), &out, &MdsParams::default()).unwrap();
    assert_eq!(two.files.len(), 5);
    assert!(!out.join("mds_matrix.png").exists() && !out.join("mds_matrix.svg").exists());
}

#[test]
fn run_mds_errors_name_the_problem() {
    let mut rng = ChaCha8Rng::seed_from_u64(1);
    let (mut d, labels_csv) = faces(&mut rng);
    let work = dir("errors");
    let labels_path = work.join("labels.csv");
    std::fs::write(&labels_path, labels_csv).unwrap();
    let dist_path = work.join("distances.csv");
    write_distance_matrix(&dist_path, &d).unwrap();
    let out = work.join("out");

    let bad_col = MdsParams {
        color_by: Some("age".into()),
        ..MdsParams::default()
    };
    let err = run_mds(&dist_path, Some(&labels_path), &out, &bad_col).unwrap_err();
    assert!(matches!(err, AnalysisError::UnknownLabelColumn { .. }), "{err}");
    let err = run_mds(&dist_path, None, &out, &bad_col).unwrap_err();
    assert!(matches!(err, AnalysisError::LabelsRequired { .. }), "{err}");

    // A failed pair (both directions missing): one of its two shapes (the later, of equal
    // counts) leaves the embedding, and the statistics say which.
    let n = d.len();
    d.values[3 * n + 7] = f64::NAN;
    d.values[7 * n + 3] = f64::NAN;
    write_distance_matrix(&dist_path, &d).unwrap();
    let r = run_mds(&dist_path, Some(&labels_path), &out, &MdsParams::default()).unwrap();
    assert_eq!(r.stats.dropped_shapes, vec![d.names[7].clone()]);
    assert_eq!((r.stats.n, r.names.len(), r.stats.missing_pairs), (n - 1, n - 1, 0));
    assert!(!r.names.contains(&d.names[7]));
    let rows = std::fs::read_to_string(out.join("mds.csv")).unwrap().lines().count();
    assert_eq!(rows, n);

    // Without labels everything but the label statistics is written.
    d.values[3 * n + 7] = 0.05;
    write_distance_matrix(&dist_path, &d).unwrap();
    let r = run_mds(&dist_path, None, &out, &MdsParams::default()).unwrap();
    assert!(r.stats.labels.is_empty() && r.stats.cross.is_empty());
    let header = std::fs::read_to_string(out.join("mds.csv")).unwrap();
    assert!(header.starts_with("name,x1,x2\n"));
}

/// `--method smacof` on the faces matrix (4-dimensional points in 2 dimensions: not exact):
/// stats.json reports the method, the stress of the configuration written to mds.csv, below
/// the classical embedding's, and the iterations; the classical run reports its own stress in
/// both fields.
#[test]
fn smacof_reports_a_stress_below_the_classical_one() {
    let mut rng = ChaCha8Rng::seed_from_u64(42);
    let (d, _) = faces(&mut rng);
    let work = dir("smacof");
    let dist_path = work.join("distances.csv");
    write_distance_matrix(&dist_path, &d).unwrap();
    let classical = run_mds(&dist_path, None, &work.join("classical"), &MdsParams::default()).unwrap();
    let params = MdsParams {
        method: MdsMethod::Smacof,
        ..MdsParams::default()
    };
    let out = work.join("smacof");
    let result = run_mds(&dist_path, None, &out, &params).unwrap();
    let stats: ShapeSpaceStats =
        serde_json::from_str(&std::fs::read_to_string(out.join("stats.json")).unwrap()).unwrap();
    assert_eq!(stats, result.stats);
    let m = &stats.mds;
    assert_eq!(m.method, MdsMethod::Smacof);
    assert_eq!(classical.stats.mds.method, MdsMethod::Classical);
    assert_eq!(classical.stats.mds.stress, classical.stats.mds.classical_stress);
    assert!(classical.stats.mds.smacof_iterations.is_none());
    // (the same embedding; SMACOF measures it on the distances divided by the largest)
    let c = classical.stats.mds.stress;
    assert!((m.classical_stress.raw - c.raw).abs() < 1e-12 * c.raw, "{m:?} vs {c:?}");
    assert!((m.classical_stress.stress1 - c.stress1).abs() < 1e-12, "{m:?} vs {c:?}");
    assert!(m.stress.raw < m.classical_stress.raw, "{m:?}");
    assert!(
        m.smacof_iterations.unwrap() > 0 && m.smacof_converged == Some(true),
        "{m:?}"
    );
    // the stress of the coordinates in mds.csv (as written, full precision) is the one reported
    let text = std::fs::read_to_string(out.join("mds.csv")).unwrap();
    let coordinates: Vec<Vec<f64>> = text
        .lines()
        .skip(1)
        .map(|l| l.split(',').skip(1).map(|v| v.parse().unwrap()).collect())
        .collect();
    let check = shapespace_analysis::stress(&d, &coordinates).unwrap();
    assert!(
        (check.raw - m.stress.raw).abs() < 1e-9 * m.stress.raw,
        "{check:?} vs {m:?}"
    );
    eprintln!(
        "faces matrix: classical stress-1 {:.4}, SMACOF {:.4} after {:?} iterations",
        m.classical_stress.stress1, m.stress.stress1, m.smacof_iterations
    );
}
