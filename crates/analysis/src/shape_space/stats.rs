//! Statistics of a distance matrix: leave-one-out nearest-neighbour accuracy, silhouettes,
//! within/between-class distances, and metric checks (symmetry, triangle inequality).
//!
//! All statistics except [`symmetry_gap`] use the symmetric distance
//! $\bar d_{ij} = (d_{ij} + d_{ji})/2$ of [`DistanceMatrix::symmetric`] (the one present
//! direction if the other is missing), and skip pairs where both directions are missing.
//!
//! - Leave-one-out 1-NN accuracy: shape $i$ is classified with the label of
//!   $\arg\min_{j \ne i} \bar d_{ij}$ (Cover & Hart 1967); the accuracy is the fraction of shapes
//!   whose neighbour has the same label. **Ties** are broken by the lowest index $j$ (the order
//!   of the matrix rows), so the result is deterministic.
//! - Silhouette (Rousseeuw 1987, J. Comput. Appl. Math. 20:53–65):
//!   $s(i) = (b(i) - a(i)) / \max(a(i), b(i))$ with $a(i)$ the mean distance from $i$ to the other
//!   members of its class and $b(i)$ the smallest mean distance from $i$ to another class;
//!   $s(i) = 0$ for a singleton class (Rousseeuw's convention).
//! - An **empty label cell** means "unknown", not a class: such a shape is neither scored nor
//!   anyone's neighbour or class member for that column (it counts in `unscored`), and its
//!   pairs are left out of the within/between-class distances.

use serde::{Deserialize, Serialize};

use crate::error::AnalysisError;
use crate::matrix_io::{DistanceMatrix, Labels};

/// Result of a leave-one-out nearest-neighbour classification.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct NnAccuracy {
    /// Shapes whose nearest admissible neighbour has the same target label.
    pub correct: usize,
    /// Shapes that had an admissible neighbour (the denominator).
    pub total: usize,
    /// Shapes not scored: no admissible neighbour (all candidates missing, excluded or without
    /// a label), or the shape's own label cell empty.
    pub unscored: usize,
    /// `correct / total`, `None` when `total == 0`.
    pub accuracy: Option<f64>,
}

/// Index of the nearest admissible neighbour of `i` (lowest index on ties), skipping missing
/// distances.
fn nearest_neighbour(d: &DistanceMatrix, i: usize, admissible: impl Fn(usize) -> bool) -> Option<usize> {
    let mut best: Option<(usize, f64)> = None;
    for j in 0..d.len() {
        if j == i || !admissible(j) {
            continue;
        }
        let v = d.symmetric(i, j);
        if v.is_nan() {
            continue;
        }
        if best.is_none_or(|(_, b)| v < b) {
            best = Some((j, v));
        }
    }
    best.map(|(j, _)| j)
}

fn check_rows(d: &DistanceMatrix, labels: &Labels) -> Result<(), AnalysisError> {
    if labels.len() != d.len() {
        return Err(AnalysisError::LabelCountMismatch {
            labels: labels.len(),
            shapes: d.len(),
        });
    }
    Ok(())
}

fn accuracy_of(correct: usize, total: usize, unscored: usize) -> NnAccuracy {
    NnAccuracy {
        correct,
        total,
        unscored,
        accuracy: (total > 0).then(|| correct as f64 / total as f64),
    }
}

/// Leave-one-out 1-nearest-neighbour accuracy of label column `target_col` (module docs; ties
/// by lowest index). `labels` must be aligned with `d` (one row per shape).
///
/// Example: identity accuracy of a face matrix = fraction of faces whose nearest other face is
/// of the same person.
pub fn loo_1nn_accuracy(d: &DistanceMatrix, labels: &Labels, target_col: &str) -> Result<NnAccuracy, AnalysisError> {
    check_rows(d, labels)?;
    let target = labels.column(target_col)?;
    let (mut correct, mut total, mut unscored) = (0, 0, 0);
    for i in 0..d.len() {
        if target[i].is_empty() {
            unscored += 1;
            continue;
        }
        match nearest_neighbour(d, i, |j| !target[j].is_empty()) {
            Some(j) => {
                total += 1;
                correct += usize::from(target[j] == target[i]);
            }
            None => unscored += 1,
        }
    }
    Ok(accuracy_of(correct, total, unscored))
}

/// Leave-one-out 1-NN accuracy of `target_col` when the neighbour must have a *different* value
/// of `exclude_same_col` than the query (ties by lowest index).
///
/// Example: `loo_1nn_accuracy_across(d, labels, "expression", "identity")` asks whether the
/// nearest face of *another person* shows the same expression. Shapes with no admissible
/// neighbour are counted in `unscored`.
pub fn loo_1nn_accuracy_across(
    d: &DistanceMatrix,
    labels: &Labels,
    target_col: &str,
    exclude_same_col: &str,
) -> Result<NnAccuracy, AnalysisError> {
    check_rows(d, labels)?;
    let target = labels.column(target_col)?;
    let exclude = labels.column(exclude_same_col)?;
    let (mut correct, mut total, mut unscored) = (0, 0, 0);
    for i in 0..d.len() {
        if target[i].is_empty() || exclude[i].is_empty() {
            unscored += 1;
            continue;
        }
        let admissible = |j: usize| !target[j].is_empty() && !exclude[j].is_empty() && exclude[j] != exclude[i];
        match nearest_neighbour(d, i, admissible) {
            Some(j) => {
                total += 1;
                correct += usize::from(target[j] == target[i]);
            }
            None => unscored += 1,
        }
    }
    Ok(accuracy_of(correct, total, unscored))
}

/// Per-shape silhouette values `s(i)` for the classes of `col` (Rousseeuw 1987; module docs),
/// `#shapes` entries in `[-1, 1]`.
///
/// `s(i) = 0` for a member of a singleton class; `None` when `s(i)` is undefined: fewer than two
/// classes, or all distances from `i` to its own class (or to every other class) missing.
/// Means skip missing distances.
pub fn silhouette_values(d: &DistanceMatrix, labels: &Labels, col: &str) -> Result<Vec<Option<f64>>, AnalysisError> {
    check_rows(d, labels)?;
    let column = labels.column(col)?;
    let classes = label_classes(&column);
    // (usize::MAX: no label)
    let class_of: Vec<usize> = column
        .iter()
        .map(|c| classes.binary_search(c).unwrap_or(usize::MAX))
        .collect();
    let class_sizes: Vec<usize> = (0..classes.len())
        .map(|c| class_of.iter().filter(|&&k| k == c).count())
        .collect();
    let n = d.len();
    let mut out = Vec::with_capacity(n);
    for i in 0..n {
        if classes.len() < 2 || class_of[i] == usize::MAX {
            out.push(None);
            continue;
        }
        let own = class_of[i];
        if class_sizes[own] == 1 {
            out.push(Some(0.0));
            continue;
        }
        let mut sums = vec![0.0; classes.len()];
        let mut counts = vec![0usize; classes.len()];
        for j in 0..n {
            if j == i || class_of[j] == usize::MAX {
                continue;
            }
            let v = d.symmetric(i, j);
            if !v.is_nan() {
                sums[class_of[j]] += v;
                counts[class_of[j]] += 1;
            }
        }
        if counts[own] == 0 {
            out.push(None);
            continue;
        }
        let a = sums[own] / counts[own] as f64;
        let b = (0..classes.len())
            .filter(|&c| c != own && counts[c] > 0)
            .map(|c| sums[c] / counts[c] as f64)
            .fold(f64::INFINITY, f64::min);
        if !b.is_finite() {
            out.push(None);
            continue;
        }
        let denom = a.max(b);
        out.push(Some(if denom > 0.0 { (b - a) / denom } else { 0.0 }));
    }
    Ok(out)
}

/// The distinct non-empty values of a label column, sorted (an empty cell is no class).
pub fn label_classes<'a>(column: &[&'a str]) -> Vec<&'a str> {
    let mut classes: Vec<&str> = column.iter().copied().filter(|c| !c.is_empty()).collect();
    classes.sort_unstable();
    classes.dedup();
    classes
}

/// Mean silhouette of column `col` over the shapes where it is defined ([`silhouette_values`]);
/// `None` if it is defined nowhere (e.g. a single class).
pub fn mean_silhouette(d: &DistanceMatrix, labels: &Labels, col: &str) -> Result<Option<f64>, AnalysisError> {
    let values: Vec<f64> = silhouette_values(d, labels, col)?.into_iter().flatten().collect();
    Ok((!values.is_empty()).then(|| values.iter().sum::<f64>() / values.len() as f64))
}

/// Count, median, min and max of a set of distances (`None` fields when it is empty).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct Summary {
    pub count: usize,
    pub median: Option<f64>,
    pub min: Option<f64>,
    pub max: Option<f64>,
}

/// Median of `values` (mean of the two middle values for an even count); `None` when empty.
/// NaNs must be removed by the caller.
pub fn median(values: &[f64]) -> Option<f64> {
    if values.is_empty() {
        return None;
    }
    let mut v = values.to_vec();
    v.sort_by(f64::total_cmp);
    let m = v.len() / 2;
    Some(if v.len() % 2 == 1 {
        v[m]
    } else {
        0.5 * (v[m - 1] + v[m])
    })
}

/// [`Summary`] of `values`.
pub fn summarize(values: &[f64]) -> Summary {
    Summary {
        count: values.len(),
        median: median(values),
        min: values.iter().copied().reduce(f64::min),
        max: values.iter().copied().reduce(f64::max),
    }
}

/// Distances within and between the classes of one label column.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct ClassDistances {
    /// Pairs `{i, j}` with the same label.
    pub within: Summary,
    /// Pairs `{i, j}` with different labels.
    pub between: Summary,
}

/// Summaries of the symmetric distances over unordered pairs `i < j` (missing pairs skipped),
/// split by whether `col` has the same value for `i` and `j`.
pub fn class_distances(d: &DistanceMatrix, labels: &Labels, col: &str) -> Result<ClassDistances, AnalysisError> {
    check_rows(d, labels)?;
    let column = labels.column(col)?;
    let (mut within, mut between) = (Vec::new(), Vec::new());
    for i in 0..d.len() {
        for j in i + 1..d.len() {
            let v = d.symmetric(i, j);
            if v.is_nan() || column[i].is_empty() || column[j].is_empty() {
                continue;
            }
            if column[i] == column[j] {
                within.push(v);
            } else {
                between.push(v);
            }
        }
    }
    Ok(ClassDistances {
        within: summarize(&within),
        between: summarize(&between),
    })
}

/// Asymmetry of a distance matrix.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct SymmetryGap {
    /// Unordered pairs `i < j` with both directions present and different: the pairs the gap
    /// is measured on.
    pub pairs: usize,
    /// Pairs whose two directions are equal to the last bit. Two directions computed apart are
    /// never that (the discretization is not symmetric); such entries come from a matrix
    /// written with one value per pair (`shapespace distances` writes one direction, or with
    /// `--symmetrize` the mean, to both cells; its `report.json` has the measured asymmetry), so
    /// they carry no asymmetry to measure and are left out of the gap.
    pub identical_pairs: usize,
    /// Mean of all present off-diagonal entries (the normalizer).
    pub mean_distance: Option<f64>,
    /// `max |d_ij − d_ji| / mean(d)` over those pairs.
    pub max_relative: Option<f64>,
    /// `median |d_ij − d_ji| / mean(d)`.
    pub median_relative: Option<f64>,
    /// The pair attaining the maximum (names).
    pub worst_pair: Option<(String, String)>,
}

/// Symmetry gap `|d_ij − d_ji| / mean(d)` (max and median over the pairs with both directions
/// present and not identical, [`SymmetryGap::identical_pairs`]). `mean(d)` is the mean of all
/// present off-diagonal entries. Fields are `None` when no pair has two different directions or
/// every distance is 0.
pub fn symmetry_gap(d: &DistanceMatrix) -> SymmetryGap {
    let n = d.len();
    let (mut sum, mut count) = (0.0, 0usize);
    for i in 0..n {
        for j in 0..n {
            let v = d.get(i, j);
            if i != j && !v.is_nan() {
                sum += v;
                count += 1;
            }
        }
    }
    let mean = (count > 0).then(|| sum / count as f64);
    let mut gaps = Vec::new();
    let mut identical = 0;
    let mut worst: Option<(f64, usize, usize)> = None;
    for i in 0..n {
        for j in i + 1..n {
            let (a, b) = (d.get(i, j), d.get(j, i));
            if a.is_nan() || b.is_nan() {
                continue;
            }
            if a.to_bits() == b.to_bits() {
                identical += 1;
                continue;
            }
            let g = (a - b).abs();
            gaps.push(g);
            if worst.is_none_or(|(w, _, _)| g > w) {
                worst = Some((g, i, j));
            }
        }
    }
    let normalizer = mean.filter(|&m| m > 0.0);
    SymmetryGap {
        pairs: gaps.len(),
        identical_pairs: identical,
        mean_distance: mean,
        max_relative: normalizer.and_then(|m| worst.map(|(g, _, _)| g / m)),
        median_relative: normalizer.and_then(|m| median(&gaps).map(|g| g / m)),
        worst_pair: worst.map(|(_, i, j)| (d.names[i].clone(), d.names[j].clone())),
    }
}

/// Triangle-inequality check of the symmetric distances.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct TriangleViolations {
    /// Unordered triples with all three distances present.
    pub triples_checked: u64,
    /// Triples whose longest side exceeds the sum of the other two by more than `eps`.
    pub violations: u64,
    /// The tolerance used.
    pub eps: f64,
    /// Largest `(d_ik − d_ij − d_jk) / d_ik` over violating triples, 0 if none.
    pub worst_relative: f64,
    /// The worst triple `[i, j, k]` (names; `j` is the intermediate point).
    pub worst_triple: Option<[String; 3]>,
}

/// Counts unordered triples `{i, j, k}` with `d̄_ik > d̄_ij + d̄_jk + eps` (at most one of a
/// triple's three inequalities can fail when distances are ≥ 0, so each violating triple is
/// counted once; `eps` should be ≥ 0). O(n³): n = 500 checks 6·10⁷ triples.
pub fn triangle_violations(d: &DistanceMatrix, eps: f64) -> TriangleViolations {
    let n = d.len();
    let sym = d.symmetrized_values();
    let mut checked = 0u64;
    let mut violations = 0u64;
    let mut worst: Option<(f64, usize, usize, usize)> = None;
    for i in 0..n {
        for k in i + 1..n {
            let d_ik = sym[i * n + k];
            if d_ik.is_nan() {
                continue;
            }
            for j in 0..n {
                if j == i || j == k {
                    continue;
                }
                let (d_ij, d_jk) = (sym[i * n + j], sym[j * n + k]);
                if d_ij.is_nan() || d_jk.is_nan() {
                    continue;
                }
                // Each unordered triple {a < b < c} is visited three times, once per choice of
                // the side {i, k}; count the check once (j > k), a violation whenever it occurs
                // (only the longest side can violate, so at most once per triple).
                if j > k {
                    checked += 1;
                }
                let excess = d_ik - d_ij - d_jk;
                if excess > eps {
                    violations += 1;
                    let rel = excess / d_ik;
                    if worst.is_none_or(|(w, ..)| rel > w) {
                        worst = Some((rel, i, j, k));
                    }
                }
            }
        }
    }
    TriangleViolations {
        triples_checked: checked,
        violations,
        eps,
        worst_relative: worst.map_or(0.0, |w| w.0),
        worst_triple: worst.map(|(_, i, j, k)| [d.names[i].clone(), d.names[j].clone(), d.names[k].clone()]),
    }
}
