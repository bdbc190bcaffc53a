//! Metric MDS by SMACOF: majorization of Kruskal's raw stress with the Guttman transform.
//!
//! De Leeuw (1977), "Applications of convex analysis to multidimensional scaling", in *Recent
//! Developments in Statistics*; Borg & Groenen (2005), *Modern Multidimensional Scaling*, 2nd
//! ed., §8.4–8.6. With $\delta_{ij}$ the given (symmetric) distances and $d_{ij}(X)$ the
//! Euclidean distances of the configuration $X$ ($n \times K$), the raw stress is
//!
//! $$\sigma_r(X) = \sum_{i<j} \big(\delta_{ij} - d_{ij}(X)\big)^2 .$$
//!
//! With unit weights its majorizer is minimized by the Guttman transform
//!
//! $$X^{+} = \tfrac1n B(X)\,X, \qquad B_{ij} = -\frac{\delta_{ij}}{d_{ij}(X)}\ (i \ne j,\ d_{ij} > 0;\ 0 \text{ otherwise}),
//! \qquad B_{ii} = -\sum_{j \ne i} B_{ij},$$
//!
//! and $\sigma_r(X^{+}) \le \sigma_r(X)$ at every step (Borg & Groenen, Eq. 8.29). The start is
//! the classical (Torgerson) embedding ([`super::classical_mds`]), so SMACOF can only lower
//! the stress of the classical solution. Kruskal's normalized stress-1 is
//! $\sqrt{\sigma_r / \sum_{i<j} \delta_{ij}^2}$ (scale-free; 0 for an exact embedding).
//!
//! Embedding dimensions whose classical eigenvalue was clamped to 0 start as all-zero columns,
//! and the Guttman transform keeps a zero column zero: those axes stay empty, as in the
//! classical embedding.

use serde::{Deserialize, Serialize};

use super::{classical_mds, Mds};
use crate::error::AnalysisError;
use crate::matrix_io::DistanceMatrix;

/// Parameters of [`smacof_mds`].
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct SmacofParams {
    /// Stop when the relative decrease of the raw stress in one step,
    /// $(\sigma_r^{k-1} - \sigma_r^k)/\sigma_r^{k-1}$, falls below this (default 1e-9), or when
    /// the stress-1 falls below it (an exact embedding).
    pub tolerance: f64,
    /// Most Guttman transforms (default 1000).
    pub max_iterations: usize,
}

impl Default for SmacofParams {
    fn default() -> Self {
        SmacofParams {
            tolerance: 1e-9,
            max_iterations: 1000,
        }
    }
}

/// Raw stress and stress-1 of a configuration against the distances.
#[derive(Clone, Copy, Debug, Default, PartialEq, Serialize, Deserialize)]
pub struct Stress {
    /// $\sigma_r = \sum_{i<j} (\delta_{ij} - d_{ij}(X))^2$, in squared distance units.
    pub raw: f64,
    /// Kruskal's stress-1, $\sqrt{\sigma_r / \sum_{i<j}\delta_{ij}^2}$ (0 when every distance is 0).
    pub stress1: f64,
}

/// What [`smacof_mds`] did.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct SmacofInfo {
    /// Guttman transforms applied.
    pub iterations: usize,
    /// Whether the tolerance was reached before the iteration cap.
    pub converged: bool,
    /// Stress of the classical embedding the iteration started from.
    pub initial: Stress,
    /// Stress of the returned configuration.
    pub stress: Stress,
    /// Raw stress after each transform (`iterations` entries, non-increasing up to round-off),
    /// in the units of the distances squared.
    pub raw_stress_history: Vec<f64>,
}

/// [`Stress`] of the configuration `x` (#shapes rows of K coordinates) against the symmetric
/// distances of `d` ((d_ij + d_ji)/2). Errors: [`AnalysisError::InvalidInput`] when `x` has
/// the wrong number of rows, [`AnalysisError::MissingDistance`] naming a pair with neither
/// direction.
pub fn stress(d: &DistanceMatrix, x: &[Vec<f64>]) -> Result<Stress, AnalysisError> {
    let n = d.len();
    if x.len() != n {
        return Err(AnalysisError::InvalidInput(format!(
            "stress: {} configuration rows for {n} shapes",
            x.len()
        )));
    }
    let delta = symmetric_distances(d)?;
    Ok(stress_of(&delta, x))
}

/// The symmetric distances as a dense row-major n² matrix; errors on a missing pair.
fn symmetric_distances(d: &DistanceMatrix) -> Result<Vec<f64>, AnalysisError> {
    let n = d.len();
    let mut delta = vec![0.0; n * n];
    for i in 0..n {
        for j in 0..n {
            if i == j {
                continue;
            }
            let v = d.symmetric(i, j);
            if v.is_nan() {
                return Err(AnalysisError::MissingDistance {
                    a: d.names[i].clone(),
                    b: d.names[j].clone(),
                });
            }
            delta[i * n + j] = v;
        }
    }
    Ok(delta)
}

fn euclid(a: &[f64], b: &[f64]) -> f64 {
    a.iter().zip(b).map(|(p, q)| (p - q) * (p - q)).sum::<f64>().sqrt()
}

fn stress_of(delta: &[f64], x: &[Vec<f64>]) -> Stress {
    let n = x.len();
    let (mut raw, mut norm) = (0.0, 0.0);
    for i in 0..n {
        for j in i + 1..n {
            let e = delta[i * n + j] - euclid(&x[i], &x[j]);
            raw += e * e;
            norm += delta[i * n + j] * delta[i * n + j];
        }
    }
    Stress {
        raw,
        stress1: if norm > 0.0 { (raw / norm).sqrt() } else { 0.0 },
    }
}

/// One Guttman transform $X^+ = \frac1n B(X) X$ (module docs).
fn guttman(delta: &[f64], x: &[Vec<f64>]) -> Vec<Vec<f64>> {
    let n = x.len();
    let k = x.first().map_or(0, Vec::len);
    let mut out = vec![vec![0.0; k]; n];
    for i in 0..n {
        let mut diag = 0.0;
        for j in 0..n {
            if j == i {
                continue;
            }
            let e = euclid(&x[i], &x[j]);
            if e > 0.0 {
                let b = -delta[i * n + j] / e;
                diag -= b;
                for c in 0..k {
                    out[i][c] += b * x[j][c];
                }
            }
        }
        for c in 0..k {
            out[i][c] = (out[i][c] + diag * x[i][c]) / n as f64;
        }
    }
    out
}

/// Turns the centred configuration `x` to its principal axes (the eigenvectors of XᵀX, largest
/// first), with the sign convention of [`classical_mds`] (each axis's component of largest
/// magnitude is positive). Returns Σ_i x_ik² per axis.
fn principal_axes(x: &mut [Vec<f64>]) -> Result<Vec<f64>, AnalysisError> {
    let n = x.len();
    let k = x.first().map_or(0, Vec::len);
    for c in 0..k {
        let mean = x.iter().map(|r| r[c]).sum::<f64>() / n as f64;
        for r in x.iter_mut() {
            r[c] -= mean;
        }
    }
    let gram = faer::Mat::<f64>::from_fn(k, k, |a, b| x.iter().map(|r| r[a] * r[b]).sum());
    let evd = gram
        .self_adjoint_eigen(faer::Side::Lower)
        .map_err(|_| AnalysisError::EigenNoConvergence { n: k })?;
    let u = evd.U();
    let rotated: Vec<Vec<f64>> = x
        .iter()
        .map(|r| {
            (0..k)
                .rev()
                .map(|col| (0..k).map(|a| r[a] * u[(a, col)]).sum())
                .collect()
        })
        .collect();
    let mut sums = vec![0.0; k];
    for c in 0..k {
        let mut arg = 0;
        for i in 1..n {
            if rotated[i][c].abs() > rotated[arg][c].abs() {
                arg = i;
            }
        }
        let sign = if rotated.get(arg).is_some_and(|r| r[c] < 0.0) {
            -1.0
        } else {
            1.0
        };
        for (row, src) in x.iter_mut().zip(&rotated) {
            row[c] = sign * src[c];
            sums[c] += row[c] * row[c];
        }
    }
    Ok(sums)
}

/// Metric MDS of `d` into `dims` dimensions by SMACOF (module docs; de Leeuw 1977), started
/// from the classical embedding.
///
/// Returns an [`Mds`] whose `coordinates` are the SMACOF configuration turned to its principal
/// axes (centred, largest spread first, signs as in [`classical_mds`]) and whose
/// `variance_shares` are Σ_i x_ik² over the classical `positive_sum` (comparable with the
/// classical shares; they need not add up to 1). The eigenvalue fields are those of the
/// classical decomposition (they describe the matrix, not the configuration). Cost per
/// iteration O(n² · dims).
///
/// Errors: those of [`classical_mds`].
pub fn smacof_mds(d: &DistanceMatrix, dims: usize, params: &SmacofParams) -> Result<(Mds, SmacofInfo), AnalysisError> {
    let classical = classical_mds(d, dims)?;
    // (the classical solve has checked the range; the iteration runs on the distances divided
    // by the largest, like the classical one, and scales back at the end)
    let delta = symmetric_distances(d)?;
    let unit = delta.iter().fold(0.0f64, |m, &v| m.max(v));
    let unit = if unit > 0.0 { unit } else { 1.0 };
    let delta_scaled: Vec<f64> = delta.iter().map(|v| v / unit).collect();
    let mut x: Vec<Vec<f64>> = classical
        .coordinates
        .iter()
        .map(|r| r.iter().map(|v| v / unit).collect())
        .collect();
    let initial = stress_of(&delta_scaled, &x);
    let mut current = initial;
    let mut history = Vec::new();
    let mut converged = current.stress1 < params.tolerance;
    let mut iterations = 0;
    while !converged && iterations < params.max_iterations {
        let next = guttman(&delta_scaled, &x);
        let s = stress_of(&delta_scaled, &next);
        iterations += 1;
        history.push(s.raw * unit * unit);
        let decrease = current.raw - s.raw;
        x = next;
        let previous = current;
        current = s;
        converged = s.stress1 < params.tolerance || decrease <= params.tolerance * previous.raw;
    }
    let sums = principal_axes(&mut x)?;
    for row in &mut x {
        for v in row.iter_mut() {
            *v *= unit;
        }
    }
    let positive = classical.positive_sum;
    let variance_shares = sums
        .iter()
        .map(|s| {
            if positive > 0.0 {
                s * unit * unit / positive
            } else {
                0.0
            }
        })
        .collect();
    let scale = |s: Stress| Stress {
        raw: s.raw * unit * unit,
        stress1: s.stress1,
    };
    let info = SmacofInfo {
        iterations,
        converged,
        initial: scale(initial),
        stress: scale(current),
        raw_stress_history: history,
    };
    Ok((
        Mds {
            coordinates: x,
            variance_shares,
            ..classical
        },
        info,
    ))
}

#[cfg(test)]
mod tests {
    use super::*;

    fn matrix(n: usize, f: impl Fn(usize, usize) -> f64) -> DistanceMatrix {
        let names = (0..n).map(|i| format!("p{i}")).collect();
        let values = (0..n * n)
            .map(|k| if k / n == k % n { 0.0 } else { f(k / n, k % n) })
            .collect();
        DistanceMatrix::new(names, values).unwrap()
    }

    /// Two points at distance 2: stress 0, coordinates ±1 after centring, in one step or none.
    #[test]
    fn two_points_closed_form() {
        let d = matrix(2, |_, _| 2.0);
        let (mds, info) = smacof_mds(&d, 1, &SmacofParams::default()).unwrap();
        assert!(info.stress.raw < 1e-24 && info.stress.stress1 < 1e-12, "{info:?}");
        let mut x: Vec<f64> = mds.coordinates.iter().map(|r| r[0]).collect();
        x.sort_by(f64::total_cmp);
        assert!((x[0] + 1.0).abs() < 1e-12 && (x[1] - 1.0).abs() < 1e-12, "{x:?}");
    }

    /// The equilateral triangle forced onto a line: the classical start has stress > 0, and the
    /// stress never rises along the iteration.
    #[test]
    fn stress_never_rises_on_a_triangle_in_one_dimension() {
        let d = matrix(3, |_, _| 1.0);
        let (_, info) = smacof_mds(&d, 1, &SmacofParams::default()).unwrap();
        assert!(info.initial.raw > 0.1, "{info:?}");
        let mut prev = info.initial.raw;
        for &s in &info.raw_stress_history {
            assert!(s <= prev * (1.0 + 1e-12), "{:?}", info.raw_stress_history);
            prev = s;
        }
        assert!(info.stress.raw <= info.initial.raw);
        // A line placement a ≤ b ≤ c has d_ac = d_ab + d_bc; among equispaced ones (gap g)
        // 2(1 − g)² + (1 − 2g)² is least at g = 2/3: σ_r = 2/9 + 1/9 = 1/3.
        assert!((info.stress.raw - 1.0 / 3.0).abs() < 1e-6, "{info:?}");
    }

    #[test]
    fn missing_pair_and_bad_rows_are_errors() {
        let mut d = matrix(3, |_, _| 1.0);
        d.values[1] = f64::NAN;
        d.values[3] = f64::NAN;
        assert!(matches!(
            smacof_mds(&d, 1, &SmacofParams::default()),
            Err(AnalysisError::MissingDistance { .. })
        ));
        let d = matrix(3, |_, _| 1.0);
        assert!(matches!(stress(&d, &[vec![0.0]]), Err(AnalysisError::InvalidInput(_))));
    }
}
