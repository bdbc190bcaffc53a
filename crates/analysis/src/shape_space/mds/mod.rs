//! Classical (Torgerson) multidimensional scaling.
//!
//! Torgerson (1952), "Multidimensional scaling: I. Theory and method", Psychometrika 17; Gower
//! (1966), Biometrika 53. Given distances $d_{ij}$ between $n$ shapes, double-centre the squared
//! distances
//!
//! $$B = -\tfrac12 J D^{(2)} J, \qquad J = I - \tfrac1n \mathbf{1}\mathbf{1}^\top,$$
//!
//! i.e. $B_{ij} = -\tfrac12 (d_{ij}^2 - \bar d^2_{i\cdot} - \bar d^2_{\cdot j} + \bar d^2_{\cdot\cdot})$,
//! take the eigenpairs $B v_k = \lambda_k v_k$ with $\lambda_1 \ge \lambda_2 \ge \dots$, and
//! place shape $i$ at $x_{ik} = v_{ik} \sqrt{\max(\lambda_k, 0)}$, $k = 1..K$. If the distances
//! are Euclidean in $\mathbb{R}^K$ this recovers the configuration up to a rigid motion; otherwise
//! $B$ has negative eigenvalues (reported, and clamped to 0 in the coordinates).
//!
//! Metric MDS minimizing the stress (SMACOF, started from this embedding) is in [`smacof`].

pub mod smacof;

use serde::{Deserialize, Serialize};

use crate::error::AnalysisError;
use crate::matrix_io::DistanceMatrix;

/// The result of [`classical_mds`].
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct Mds {
    /// `#shapes` rows of `dims` coordinates: `coordinates[i][k] = v_ik √max(λ_k, 0)`.
    pub coordinates: Vec<Vec<f64>>,
    /// All `#shapes` eigenvalues of `B`, in non-increasing order (the centring always
    /// contributes one eigenvalue ≈ 0, eigenvector ∝ 1).
    pub eigenvalues: Vec<f64>,
    /// Share of variance per embedding dimension, `max(λ_k, 0) / Σ_{λ>0} λ` (`dims` entries;
    /// all 0 when every distance is 0).
    pub variance_shares: Vec<f64>,
    /// `Σ_{λ>0} λ`, the total variance of the Euclidean part.
    pub positive_sum: f64,
    /// `Σ_{λ<0} |λ|`: how far the distances are from Euclidean (0 for Euclidean input, up to
    /// round-off). `negative_sum / positive_sum` is a common summary.
    pub negative_sum: f64,
    /// Number of eigenvalues below `−1e-12 · max|λ|` (significantly negative).
    pub negative_count: usize,
    /// Number of the `dims` embedding dimensions whose eigenvalue was ≤ 0 and clamped to 0 (their
    /// coordinates are all 0).
    pub clamped_dims: usize,
}

impl Mds {
    /// Number of embedding dimensions.
    pub fn dims(&self) -> usize {
        self.variance_shares.len()
    }

    /// Share `λ_k / Σ_{λ>0} λ` of every eigenvalue, in the order of `eigenvalues` (negative
    /// eigenvalues give negative shares; all 0 when `positive_sum` is 0).
    pub fn eigenvalue_shares(&self) -> Vec<f64> {
        self.eigenvalues
            .iter()
            .map(|&l| {
                if self.positive_sum > 0.0 {
                    l / self.positive_sum
                } else {
                    0.0
                }
            })
            .collect()
    }
}

/// The double-centred matrix `B = −½ J D² J` (row-major `n²`) of the symmetric distances
/// [`DistanceMatrix::symmetric`] (`(d_ij + d_ji)/2`, diagonal 0).
///
/// Errors: [`AnalysisError::MissingDistance`] naming the first pair with neither direction,
/// [`AnalysisError::DistanceTooLarge`] when the squared distances overflow.
pub fn double_centred(d: &DistanceMatrix) -> Result<Vec<f64>, AnalysisError> {
    let n = d.len();
    let mut sq = vec![0.0; n * n];
    for i in 0..n {
        for j in 0..n {
            let v = d.symmetric(i, j);
            if v.is_nan() {
                return Err(AnalysisError::MissingDistance {
                    a: d.names[i].clone(),
                    b: d.names[j].clone(),
                });
            }
            sq[i * n + j] = v * v;
        }
    }
    let row_means: Vec<f64> = (0..n)
        .map(|i| sq[i * n..(i + 1) * n].iter().sum::<f64>() / n as f64)
        .collect();
    let grand_mean = row_means.iter().sum::<f64>() / n as f64;
    let mut b = vec![0.0; n * n];
    for i in 0..n {
        for j in 0..n {
            b[i * n + j] = -0.5 * (sq[i * n + j] - row_means[i] - row_means[j] + grand_mean);
        }
    }
    if b.iter().any(|x| !x.is_finite()) {
        // finite distances whose squares (or their sums) overflow: name the largest
        let k = (0..n * n).max_by(|&k, &l| sq[k].total_cmp(&sq[l])).unwrap_or(0);
        return Err(AnalysisError::DistanceTooLarge {
            a: d.names[k / n].clone(),
            b: d.names[k % n].clone(),
            value: d.symmetric(k / n, k % n),
        });
    }
    Ok(b)
}

/// Classical MDS of `d` into `dims` dimensions (module docs; Torgerson 1952, Gower 1966).
///
/// Uses the symmetric distances `(d_ij + d_ji)/2` (diagonal ignored) and faer's dense
/// self-adjoint eigensolver on the `n × n` matrix `B` (O(n³); n = 500 takes tens of ms).
/// Sign convention: each eigenvector is flipped so that its component of largest magnitude is
/// positive (the first such index on exact ties), which makes the embedding deterministic up to
/// rotations inside repeated eigenvalues.
///
/// Errors: [`AnalysisError::TooFewShapes`] for an empty matrix, [`AnalysisError::InvalidDims`]
/// unless `1 <= dims <= n`, [`AnalysisError::MissingDistance`] naming a missing pair,
/// [`AnalysisError::EigenNoConvergence`].
pub fn classical_mds(d: &DistanceMatrix, dims: usize) -> Result<Mds, AnalysisError> {
    let n = d.len();
    if n == 0 {
        return Err(AnalysisError::TooFewShapes {
            what: "MDS",
            needed: 1,
            got: 0,
        });
    }
    if dims == 0 || dims > n {
        return Err(AnalysisError::InvalidDims { dims, n });
    }
    // The distances divided by the largest first, so that neither their squares nor the
    // eigenvalues under- or overflow along the way; the coordinates and eigenvalues are scaled
    // back at the end, which needs the largest squared distance to be a normal f64 (beyond, the
    // eigenvalues written would be 0 or infinite beside finite shares: an error either way).
    let mut largest = (0.0f64, 0, 0);
    for i in 0..n {
        for j in 0..n {
            let v = d.symmetric(i, j);
            if v > largest.0 {
                largest = (v, i, j);
            }
        }
    }
    let unit = if largest.0.is_finite() && largest.0 > 0.0 {
        largest.0
    } else {
        1.0
    };
    if !(unit * unit).is_finite() {
        return Err(AnalysisError::DistanceTooLarge {
            a: d.names[largest.1].clone(),
            b: d.names[largest.2].clone(),
            value: largest.0,
        });
    }
    if unit * unit < f64::MIN_POSITIVE {
        return Err(AnalysisError::DistanceTooSmall {
            a: d.names[largest.1].clone(),
            b: d.names[largest.2].clone(),
            value: largest.0,
        });
    }
    let scaled = DistanceMatrix {
        names: d.names.clone(),
        values: d.values.iter().map(|v| v / unit).collect(),
    };
    let b = double_centred(&scaled)?;
    let b_mat = faer::Mat::<f64>::from_fn(n, n, |i, j| b[i * n + j]);
    let evd = b_mat
        .self_adjoint_eigen(faer::Side::Lower)
        .map_err(|_| AnalysisError::EigenNoConvergence { n })?;
    let s = evd.S().column_vector();
    let u = evd.U();
    // faer sorts eigenvalues in non-decreasing order; we want non-increasing.
    let order: Vec<usize> = (0..n).rev().collect();
    // (of the scaled matrix; the shares and signs are scale-free)
    let eigenvalues: Vec<f64> = order.iter().map(|&k| s[k]).collect();

    let (positive_sum, negative_sum) = eigenvalue_sums(&eigenvalues);
    let max_abs = eigenvalues.iter().fold(0.0f64, |m, l| m.max(l.abs()));
    let negative_count = eigenvalues.iter().filter(|&&l| l < -1e-12 * max_abs).count();

    let mut coordinates = vec![vec![0.0; dims]; n];
    let mut variance_shares = Vec::with_capacity(dims);
    let mut clamped_dims = 0;
    for (k, &col) in order.iter().take(dims).enumerate() {
        let lambda = eigenvalues[k];
        let scale = if lambda > 0.0 {
            lambda.sqrt()
        } else {
            clamped_dims += 1;
            0.0
        };
        variance_shares.push(if positive_sum > 0.0 {
            lambda.max(0.0) / positive_sum
        } else {
            0.0
        });
        // Sign convention: the component of largest |v_ik| is positive.
        let mut arg = 0;
        for i in 1..n {
            if u[(i, col)].abs() > u[(arg, col)].abs() {
                arg = i;
            }
        }
        let sign = if u[(arg, col)] < 0.0 { -1.0 } else { 1.0 };
        for (i, row) in coordinates.iter_mut().enumerate() {
            row[k] = sign * u[(i, col)] * scale * unit;
        }
    }
    let squared = unit * unit;
    Ok(Mds {
        coordinates,
        eigenvalues: eigenvalues.iter().map(|l| l * squared).collect(),
        variance_shares,
        positive_sum: positive_sum * squared,
        negative_sum: negative_sum * squared,
        negative_count,
        clamped_dims,
    })
}

/// Σ of the positive eigenvalues and Σ |negative eigenvalues|, each from +0: an empty f64
/// `sum()` is −0, which printed as "-0.000" and serialized as `-0.0`.
fn eigenvalue_sums(eigenvalues: &[f64]) -> (f64, f64) {
    let positive = eigenvalues.iter().filter(|&&l| l > 0.0).fold(0.0, |s, l| s + l);
    let negative = eigenvalues.iter().filter(|&&l| l < 0.0).fold(0.0, |s, l| s - l);
    (positive, negative)
}

#[cfg(test)]
mod tests {

    /// Without negative eigenvalues the negative sum is +0, not −0 ("-0.000" in the summary).
    #[test]
    fn eigenvalue_sums_start_from_positive_zero() {
        let (p, n) = eigenvalue_sums(&[3.0, 1.0, 0.0]);
        assert_eq!(p, 4.0);
        assert!(n == 0.0 && n.is_sign_positive());
        assert_eq!(format!("{:.3}", n / p), "0.000");
        assert_eq!(eigenvalue_sums(&[2.0, -0.5, -0.25]), (2.0, 0.75));
    }
    use super::*;

    fn euclidean_matrix(points: &[Vec<f64>]) -> DistanceMatrix {
        let n = points.len();
        let names = (0..n).map(|i| format!("p{i}")).collect();
        let mut values = vec![0.0; n * n];
        for i in 0..n {
            for j in 0..n {
                values[i * n + j] = points[i]
                    .iter()
                    .zip(&points[j])
                    .map(|(a, b)| (a - b) * (a - b))
                    .sum::<f64>()
                    .sqrt();
            }
        }
        DistanceMatrix::new(names, values).unwrap()
    }

    #[test]
    fn collinear_points_embed_on_a_line_with_known_eigenvalue() {
        // Points 0, 1, 3 on a line: centred coordinates −4/3, −1/3, 5/3, so
        // λ₁ = Σ x² = 16/9 + 1/9 + 25/9 = 42/9 and all other eigenvalues vanish.
        let d = euclidean_matrix(&[vec![0.0], vec![1.0], vec![3.0]]);
        let mds = classical_mds(&d, 2).unwrap();
        assert!((mds.eigenvalues[0] - 42.0 / 9.0).abs() < 1e-12);
        assert!(mds.eigenvalues[1].abs() < 1e-12);
        assert!(mds.eigenvalues[2].abs() < 1e-12);
        // Largest |x| is the third point (5/3), made positive by the sign convention.
        let x: Vec<f64> = mds.coordinates.iter().map(|r| r[0]).collect();
        for (got, want) in x.iter().zip([-4.0 / 3.0, -1.0 / 3.0, 5.0 / 3.0]) {
            assert!((got - want).abs() < 1e-12, "{x:?}");
        }
        assert!((mds.variance_shares[0] - 1.0).abs() < 1e-12);
        assert!(mds.variance_shares[1].abs() < 1e-12);
    }

    /// The embedding scales with the distances wherever the eigenvalues (squared distances)
    /// are normal f64: 1e-150 times the points above gives 1e-150 times their coordinates and
    /// 1e-300 times the eigenvalues (the squared distances underflowed to an all-zero embedding
    /// at 1e-170 before the rescaling), and 1e150 times them 1e150 times (eigenvalues 1e300
    /// times); beyond either end the error names the largest distance (at 1e-300 the
    /// eigenvalues were written as 0 beside finite shares).
    #[test]
    fn embedding_scales_with_the_distances() {
        let d = euclidean_matrix(&[vec![0.0], vec![1.0], vec![3.0]]);
        let base = classical_mds(&d, 1).unwrap();
        for s in [1e-150, 1e150] {
            let scaled = DistanceMatrix {
                names: d.names.clone(),
                values: d.values.iter().map(|v| v * s).collect(),
            };
            let mds = classical_mds(&scaled, 1).unwrap();
            for (a, b) in mds.coordinates.iter().zip(&base.coordinates) {
                assert!((a[0] / s - b[0]).abs() < 1e-12, "scale {s:e}: {a:?} vs {b:?}");
            }
            assert!((mds.variance_shares[0] - 1.0).abs() < 1e-12);
            assert!((mds.eigenvalues[0] / (s * s) - 42.0 / 9.0).abs() < 1e-12);
        }
        for s in [1e-170, 1e-300] {
            let tiny = DistanceMatrix {
                names: d.names.clone(),
                values: d.values.iter().map(|v| v * s).collect(),
            };
            match classical_mds(&tiny, 1) {
                Err(AnalysisError::DistanceTooSmall { a, b, value }) => {
                    assert_eq!((a.as_str(), b.as_str(), value), ("p0", "p2", 3.0 * s));
                }
                other => panic!("{other:?}"),
            }
        }
        let big = DistanceMatrix {
            names: d.names.clone(),
            values: vec![0.0, 1.5e160, 2e160, 1.5e160, 0.0, 1e160, 2e160, 1e160, 0.0],
        };
        match classical_mds(&big, 1) {
            Err(AnalysisError::DistanceTooLarge { a, b, value }) => {
                assert_eq!((a.as_str(), b.as_str(), value), ("p0", "p2", 2e160));
            }
            other => panic!("{other:?}"),
        }
    }

    #[test]
    fn missing_entry_names_the_pair() {
        let mut d = euclidean_matrix(&[vec![0.0], vec![1.0], vec![3.0]]);
        d.values[3 + 2] = f64::NAN; // d(p1, p2)
                                    // One direction present: the symmetric value uses it, MDS still works.
        assert!(classical_mds(&d, 1).is_ok());
        d.values[2 * 3 + 1] = f64::NAN;
        let err = classical_mds(&d, 1).unwrap_err();
        assert!(
            matches!(&err, AnalysisError::MissingDistance { a, b } if a == "p1" && b == "p2"),
            "{err}"
        );
        assert!(err.to_string().contains("\"p1\"") && err.to_string().contains("\"p2\""));
    }

    #[test]
    fn invalid_dims_rejected() {
        let d = euclidean_matrix(&[vec![0.0], vec![1.0]]);
        assert!(matches!(classical_mds(&d, 0), Err(AnalysisError::InvalidDims { .. })));
        assert!(matches!(classical_mds(&d, 3), Err(AnalysisError::InvalidDims { .. })));
    }
}
