//! Nearest-neighbour accuracy, silhouettes and metric checks on hand-built matrices.

use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use shapespace_analysis::stats::{
    class_distances, loo_1nn_accuracy, loo_1nn_accuracy_across, mean_silhouette, silhouette_values, symmetry_gap,
    triangle_violations,
};
use shapespace_analysis::{DistanceMatrix, Labels};

fn symmetric_matrix(n: usize, pairs: &[(usize, usize, f64)]) -> DistanceMatrix {
    let mut values = vec![f64::NAN; n * n];
    for i in 0..n {
        values[i * n + i] = 0.0;
    }
    for &(i, j, v) in pairs {
        values[i * n + j] = v;
        values[j * n + i] = v;
    }
    DistanceMatrix::new((0..n).map(|i| format!("s{i}")).collect(), values).unwrap()
}

fn labels(columns: &[&str], rows: &[&[&str]]) -> Labels {
    Labels {
        columns: columns.iter().map(|s| s.to_string()).collect(),
        values: rows.iter().map(|r| r.iter().map(|s| s.to_string()).collect()).collect(),
        unlabeled: Vec::new(),
    }
}

/// Two people (p1: s0–s2, p2: s3–s5) with three expressions each; s2 and s3 planted close.
fn faces() -> (DistanceMatrix, Labels) {
    let mut pairs = vec![
        (0, 1, 0.1),
        (0, 2, 0.3),
        (1, 2, 0.2),
        (3, 4, 0.15),
        (3, 5, 0.25),
        (4, 5, 0.35),
    ];
    for i in 0..3 {
        for j in 3..6 {
            let v = if (i, j) == (2, 3) {
                0.12
            } else if i == j - 3 {
                0.5
            } else {
                0.9
            };
            pairs.push((i, j, v));
        }
    }
    let l = labels(
        &["identity", "expression"],
        &[
            &["p1", "e1"],
            &["p1", "e2"],
            &["p1", "e3"],
            &["p2", "e1"],
            &["p2", "e2"],
            &["p2", "e3"],
        ],
    );
    (symmetric_matrix(6, &pairs), l)
}

#[test]
fn loo_1nn_identity_accuracy_matches_hand_count() {
    // s2 → s3 and s3 → s2 are wrong; the other four find their own person.
    let (d, l) = faces();
    let acc = loo_1nn_accuracy(&d, &l, "identity").unwrap();
    assert_eq!((acc.correct, acc.total, acc.unscored), (4, 6, 0));
    assert!((acc.accuracy.unwrap() - 4.0 / 6.0).abs() < 1e-15);
    // Expression within the whole set: every nearest neighbour is the same person with another
    // expression, except s2 ↔ s3 (e3 vs e1): 0 of 6.
    let acc = loo_1nn_accuracy(&d, &l, "expression").unwrap();
    assert_eq!(acc.correct, 0);
}

#[test]
fn loo_1nn_across_identities_matches_hand_count() {
    // Neighbour must be the other person: s0→s3 (e1 ✓), s1→s4 ✓, s2→s3 ✗, s3→s2 ✗, s4→s1 ✓, s5→s2 ✓.
    let (d, l) = faces();
    let acc = loo_1nn_accuracy_across(&d, &l, "expression", "identity").unwrap();
    assert_eq!((acc.correct, acc.total, acc.unscored), (4, 6, 0));
    // Identity with the neighbour forced to another identity can never be right.
    let acc = loo_1nn_accuracy_across(&d, &l, "identity", "identity").unwrap();
    assert_eq!((acc.correct, acc.total), (0, 6));
    // Everyone has the same "all" label: no admissible neighbour, all unscored.
    let mut l2 = l.clone();
    l2.columns.push("all".into());
    for row in &mut l2.values {
        row.push("x".into());
    }
    let acc = loo_1nn_accuracy_across(&d, &l2, "identity", "all").unwrap();
    assert_eq!((acc.total, acc.unscored, acc.accuracy), (0, 6, None));
}

#[test]
fn ties_go_to_the_lowest_index() {
    // d(0,1) = d(0,2) = 1: shape 0 takes s1 (label B, wrong). With the highest index it would
    // be right, so this pins the documented rule.
    let d = symmetric_matrix(3, &[(0, 1, 1.0), (0, 2, 1.0), (1, 2, 2.0)]);
    let l = labels(&["c"], &[&["A"], &["B"], &["A"]]);
    let acc = loo_1nn_accuracy(&d, &l, "c").unwrap();
    assert_eq!((acc.correct, acc.total), (1, 3));
}

#[test]
fn missing_distances_are_skipped_by_nearest_neighbour() {
    // s0's only close candidate s1 is missing, so it falls back to s2.
    let d = symmetric_matrix(3, &[(0, 2, 5.0), (1, 2, 1.0)]);
    let l = labels(&["c"], &[&["A"], &["B"], &["A"]]);
    let acc = loo_1nn_accuracy(&d, &l, "c").unwrap();
    // s0 → s2 (A ✓), s1 → s2 (A vs B ✗), s2 → s1 (✗).
    assert_eq!((acc.correct, acc.total), (1, 3));
}

#[test]
fn silhouette_matches_hand_computation() {
    // 1-D points 0, 1 (class A) and 4, 6 (class B), d = |x − y|.
    // s(0) = (5 − 1)/5, s(1) = (4 − 1)/4, s(4) = (3.5 − 2)/3.5, s(6) = (5.5 − 2)/5.5.
    let x = [0.0, 1.0, 4.0, 6.0];
    let mut pairs = Vec::new();
    for i in 0..4 {
        for j in i + 1..4 {
            pairs.push((i, j, f64::abs(x[i] - x[j])));
        }
    }
    let d = symmetric_matrix(4, &pairs);
    let l = labels(&["c"], &[&["A"], &["A"], &["B"], &["B"]]);
    let want = [0.8, 0.75, 1.5 / 3.5, 3.5 / 5.5];
    let got = silhouette_values(&d, &l, "c").unwrap();
    for (g, w) in got.iter().zip(want) {
        assert!((g.unwrap() - w).abs() < 1e-15, "{got:?}");
    }
    let mean = mean_silhouette(&d, &l, "c").unwrap().unwrap();
    assert!((mean - want.iter().sum::<f64>() / 4.0).abs() < 1e-15);

    // A singleton class gets 0; it also becomes the nearest other class for shape 3:
    // add x = 8 as class C. s(6): a = 2, b = min(5.5, 2) = 2 → 0.
    let x = [0.0, 1.0, 4.0, 6.0, 8.0];
    let mut pairs = Vec::new();
    for i in 0..5 {
        for j in i + 1..5 {
            pairs.push((i, j, f64::abs(x[i] - x[j])));
        }
    }
    let d = symmetric_matrix(5, &pairs);
    let l = labels(&["c"], &[&["A"], &["A"], &["B"], &["B"], &["C"]]);
    let got = silhouette_values(&d, &l, "c").unwrap();
    assert_eq!(got[4], Some(0.0));
    assert!(got[3].unwrap().abs() < 1e-15);
    // s(4): a = 2, b = min(mean(4, 3) = 3.5, 4) = 3.5.
    assert!((got[2].unwrap() - 1.5 / 3.5).abs() < 1e-15);

    // A single class: undefined.
    let l = labels(&["c"], &[&["A"] as &[&str]; 5]);
    assert_eq!(mean_silhouette(&d, &l, "c").unwrap(), None);
}

#[test]
fn class_distance_summaries() {
    let (d, l) = faces();
    let s = class_distances(&d, &l, "identity").unwrap();
    // Within: 0.1, 0.3, 0.2, 0.15, 0.25, 0.35 → median 0.225.
    assert_eq!(s.within.count, 6);
    assert!((s.within.median.unwrap() - 0.225).abs() < 1e-15);
    assert_eq!((s.within.min, s.within.max), (Some(0.1), Some(0.35)));
    // Between: 0.12, 0.5 ×3 (same expression), 0.9 ×5 → 9 values, median 0.9.
    assert_eq!(s.between.count, 9);
    assert_eq!(
        (s.between.min, s.between.median, s.between.max),
        (Some(0.12), Some(0.9), Some(0.9))
    );
}

#[test]
fn unknown_label_column_is_an_error() {
    let (d, l) = faces();
    let err = loo_1nn_accuracy(&d, &l, "age").unwrap_err();
    assert!(
        err.to_string().contains("\"age\"") && err.to_string().contains("identity"),
        "{err}"
    );
}

#[test]
fn triangle_counter_finds_planted_violations_and_none_in_euclidean() {
    // All distances 1 except d(0,1) = 3: triples {0,1,2} and {0,1,3} violate, excess 1 of 3.
    let mut pairs = vec![(0, 1, 3.0)];
    for (i, j) in [(0, 2), (0, 3), (1, 2), (1, 3), (2, 3)] {
        pairs.push((i, j, 1.0));
    }
    let d = symmetric_matrix(4, &pairs);
    let t = triangle_violations(&d, 1e-12);
    assert_eq!(t.triples_checked, 4);
    assert_eq!(t.violations, 2);
    assert!((t.worst_relative - 1.0 / 3.0).abs() < 1e-15);
    let w = t.worst_triple.unwrap();
    assert_eq!((w[0].as_str(), w[2].as_str()), ("s0", "s1"));

    // Random Euclidean points in 3-D: none (with round-off tolerance), C(30,3) triples.
    let mut rng = ChaCha8Rng::seed_from_u64(5);
    let pts: Vec<[f64; 3]> = (0..30)
        .map(|_| std::array::from_fn(|_| rng.random_range(0.0..1.0)))
        .collect();
    let mut pairs = Vec::new();
    for i in 0..30 {
        for j in i + 1..30 {
            let v = (0..3).map(|k| (pts[i][k] - pts[j][k]).powi(2)).sum::<f64>().sqrt();
            pairs.push((i, j, v));
        }
    }
    let d = symmetric_matrix(30, &pairs);
    let t = triangle_violations(&d, 1e-12);
    assert_eq!(t.triples_checked, 30 * 29 * 28 / 6);
    assert_eq!(t.violations, 0);
    assert_eq!(t.worst_triple, None);
    // Colinear points sit exactly on the equality: still no violation with eps > 0.
    let d = symmetric_matrix(3, &[(0, 1, 0.1), (1, 2, 0.2), (0, 2, 0.30000000000000004)]);
    assert_eq!(triangle_violations(&d, 1e-12).violations, 0);
}

#[test]
fn symmetry_gap_of_known_matrix() {
    let n = 3;
    let mut values = vec![0.0; 9];
    let entries = [
        (0, 1, 1.0),
        (1, 0, 1.2),
        (0, 2, 2.0),
        (2, 0, 2.0),
        (1, 2, 3.0),
        (2, 1, 3.3),
    ];
    for (i, j, v) in entries {
        values[i * n + j] = v;
    }
    let d = DistanceMatrix::new(vec!["a".into(), "b".into(), "c".into()], values).unwrap();
    let g = symmetry_gap(&d);
    let mean = 12.5 / 6.0;
    // a–c has two identical directions: left out of the gap (one value written to both cells)
    assert_eq!((g.pairs, g.identical_pairs), (2, 1));
    assert!((g.mean_distance.unwrap() - mean).abs() < 1e-15);
    assert!((g.max_relative.unwrap() - 0.3 / mean).abs() < 1e-12);
    assert!((g.median_relative.unwrap() - 0.25 / mean).abs() < 1e-12);
    assert_eq!(g.worst_pair, Some(("b".to_string(), "c".to_string())));
    // a matrix written with one value per pair (as `distances` writes it) has no gap to report:
    // not a gap of 0
    let mirrored = symmetric_matrix(3, &[(0, 1, 1.0), (0, 2, 2.0), (1, 2, 3.0)]);
    let g = symmetry_gap(&mirrored);
    assert_eq!((g.pairs, g.identical_pairs), (0, 3));
    assert_eq!((g.max_relative, g.median_relative, g.worst_pair), (None, None, None));
    // Statistics use the mean of both directions.
    assert!((d.symmetric(1, 2) - 3.15).abs() < 1e-15);
}

/// An empty label cell is "unknown", not a class: the reviewer's case, three shapes where b and
/// c have no label, used to count as two classes with c → b a correct neighbour.
#[test]
fn empty_label_cells_are_unknown_not_a_class() {
    let d = symmetric_matrix(3, &[(0, 1, 0.5), (0, 2, 0.6), (1, 2, 0.1)]);
    let l = labels(&["kind"], &[&["x"], &[""], &[""]]);
    let acc = loo_1nn_accuracy(&d, &l, "kind").unwrap();
    // only a is scored, and has no labelled neighbour
    assert_eq!((acc.correct, acc.total, acc.unscored), (0, 0, 3));
    assert_eq!(silhouette_values(&d, &l, "kind").unwrap(), vec![None, None, None]);
    let s = class_distances(&d, &l, "kind").unwrap();
    assert_eq!((s.within.count, s.between.count), (0, 0));
    assert_eq!(
        shapespace_analysis::stats::label_classes(&["x", "", "y", "x"]),
        ["x", "y"]
    );

    // the faces with s2's identity unknown: s2 is skipped as query and as neighbour, so s1's
    // nearest labelled neighbour is s0 (p1) and s3's is s4 (p2): 5 of 5 correct
    let (d, mut l) = faces();
    l.values[2][0].clear();
    let acc = loo_1nn_accuracy(&d, &l, "identity").unwrap();
    assert_eq!((acc.correct, acc.total, acc.unscored), (5, 5, 1));
    let across = loo_1nn_accuracy_across(&d, &l, "expression", "identity").unwrap();
    assert_eq!(across.unscored, 1);
    assert!(silhouette_values(&d, &l, "identity").unwrap()[2].is_none());
    // within pairs: 0.1 (s0 s1) and the three of p2
    assert_eq!(class_distances(&d, &l, "identity").unwrap().within.count, 4);
}
