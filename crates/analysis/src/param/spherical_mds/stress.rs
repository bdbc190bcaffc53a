//! The spherical stress and its minimization on S² (the parent module gives the method).
//!
//! Points are unit vectors; the distance of two points is the great-circle angle
//! $d(x, y) = \operatorname{atan2}(|x \times y|, x \cdot y)$. Its Riemannian gradient in x is
//! $-u_{xy}$, the unit tangent at x pointing towards y, so the gradient of one stress term
//! $w(\delta - d(x, y))^2$ is $2w(\delta - d)\,u_{xy}$.
//!
//! - `smacof_on_sphere` moves all landmarks at once by the spherical Guttman step
//!   $$x_i^+ = \exp_{x_i}\Big(\frac{\alpha}{W_i}\sum_{j \ne i} w_{ij}\,(d_{ij} - \delta_{ij})\,u_{ij}\Big),
//!   \qquad W_i = \sum_{j \ne i} w_{ij},$$
//!   which in the plane (where $\exp_x(t) = x + t$ and $(d - \delta)u = (1 - \delta/d)(y - x)$)
//!   is the per-point Guttman transform of SMACOF at α = 1 (Borg & Groenen 2005, §8.6, with
//!   the weights' diagonal V). On the sphere the majorization argument does not hold as it
//!   stands (positive curvature), so α is halved until the stress does not rise: the stress is
//!   non-increasing over the iterations by construction, and α returns to 1 after each
//!   accepted step.
//! - `place_point` minimizes one point's stress against fixed points by Gauss–Newton in the
//!   tangent plane (2 × 2 normal equations, step halving), for the vertices placed against the
//!   landmarks and for the refinement sweeps.

use rayon::prelude::*;
use serde::Serialize;

pub(crate) fn dot(a: [f64; 3], b: [f64; 3]) -> f64 {
    a[0] * b[0] + a[1] * b[1] + a[2] * b[2]
}

pub(crate) fn cross(a: [f64; 3], b: [f64; 3]) -> [f64; 3] {
    [
        a[1] * b[2] - a[2] * b[1],
        a[2] * b[0] - a[0] * b[2],
        a[0] * b[1] - a[1] * b[0],
    ]
}

/// `a / |a|`, or `None` for a zero or non-finite vector.
pub(crate) fn normalized(a: [f64; 3]) -> Option<[f64; 3]> {
    let l = dot(a, a).sqrt();
    (l > 0.0 && l.is_finite()).then(|| a.map(|t| t / l))
}

/// Great-circle distance (radians, in [0, π]) of the unit vectors `a` and `b`.
pub fn arc(a: [f64; 3], b: [f64; 3]) -> f64 {
    let c = cross(a, b);
    dot(c, c).sqrt().atan2(dot(a, b))
}

/// The unit tangent at `x` pointing along the great circle towards `y` (`None` when y = ±x).
fn toward(x: [f64; 3], y: [f64; 3]) -> Option<[f64; 3]> {
    let c = dot(x, y);
    let v = [y[0] - c * x[0], y[1] - c * x[1], y[2] - c * x[2]];
    let l = dot(v, v).sqrt();
    (l > 1e-14).then(|| v.map(|t| t / l))
}

/// The exponential map of S² at `x` applied to the tangent vector `t`.
pub fn exp_map(x: [f64; 3], t: [f64; 3]) -> [f64; 3] {
    let theta = dot(t, t).sqrt();
    if !(theta > 0.0) {
        return x;
    }
    let (s, c) = theta.sin_cos();
    let p = [0, 1, 2].map(|k| c * x[k] + s * t[k] / theta);
    normalized(p).unwrap_or(x)
}

/// The largest step factor α of [`smacof_on_sphere`]: over-relaxed steps (α up to 2, as in
/// relaxed SMACOF) are kept when they lower the stress.
const MAX_STEP: f64 = 2.0;

/// What one minimization stage did.
#[derive(Clone, Debug, Default, Serialize)]
pub struct StressStage {
    /// Iterations applied (accepted steps).
    pub iterations: usize,
    /// Whether the relative decrease fell below the tolerance before the iteration cap.
    pub converged: bool,
    /// Weighted raw stress before the first iteration (radians²).
    pub initial_stress: f64,
    /// Weighted raw stress at the end (radians²).
    pub final_stress: f64,
    /// $\sqrt{\sigma / \sum w\delta^2}$ at the end (scale-free; 0 for an exact embedding).
    pub stress1: f64,
    /// Step halvings (α ← α/2) taken because a full step raised the stress.
    pub halvings: usize,
    /// The stress after each iteration (non-increasing).
    pub stress_history: Vec<f64>,
}

/// The weight of a pair: w_i w_j δ^(−power) (0 for δ = 0 when power > 0).
pub(crate) fn pair_weight(wi: f64, wj: f64, delta: f64, power: f64) -> f64 {
    if power == 0.0 {
        wi * wj
    } else if delta > 0.0 {
        wi * wj * delta.powf(-power)
    } else {
        0.0
    }
}

/// Weighted raw stress of the landmark configuration `x` (k points): Σ_{i<j} w_i w_j (δ_ij −
/// d_ij)², `delta` row-major k × k, `w` the k landmark weights. Summed in a fixed order.
pub(crate) fn landmark_stress(delta: &[f64], w: &[f64], power: f64, x: &[[f64; 3]]) -> f64 {
    let k = x.len();
    let rows: Vec<f64> = (0..k)
        .into_par_iter()
        .map(|i| {
            let mut s = 0.0;
            for j in i + 1..k {
                let e = delta[i * k + j] - arc(x[i], x[j]);
                s += pair_weight(w[i], w[j], delta[i * k + j], power) * e * e;
            }
            s
        })
        .collect();
    rows.iter().sum()
}

/// Spherical SMACOF on the landmarks (module docs): moves `x` (k unit vectors) to lower the
/// weighted stress against `delta` (row-major k × k, radians) for at most `max_iterations`
/// accepted steps, stopping when a step lowers the stress by less than `tolerance` relative.
pub(crate) fn smacof_on_sphere(
    delta: &[f64],
    w: &[f64],
    power: f64,
    x: &mut [[f64; 3]],
    max_iterations: usize,
    tolerance: f64,
) -> StressStage {
    let k = x.len();
    let norm: f64 = (0..k)
        .map(|i| {
            (i + 1..k)
                .map(|j| pair_weight(w[i], w[j], delta[i * k + j], power) * delta[i * k + j].powi(2))
                .sum::<f64>()
        })
        .sum();
    let mut sigma = landmark_stress(delta, w, power, x);
    let mut stage = StressStage {
        initial_stress: sigma,
        ..Default::default()
    };
    let mut alpha = 1.0f64;
    while stage.iterations < max_iterations && sigma > 0.0 {
        let directions: Vec<[f64; 3]> = (0..k)
            .into_par_iter()
            .map(|i| {
                let (mut t, mut total) = ([0.0; 3], 0.0);
                let p = x[i];
                for j in (0..k).filter(|&j| j != i) {
                    let wij = pair_weight(w[i], w[j], delta[i * k + j], power);
                    total += wij;
                    // (d − δ) u with u = v / |v|, v the tangent part of x_j, |v| = sin d
                    let q = x[j];
                    let c = dot(p, q);
                    let v = [q[0] - c * p[0], q[1] - c * p[1], q[2] - c * p[2]];
                    let sin = dot(v, v).sqrt();
                    if sin > 1e-14 {
                        let f = wij * (sin.atan2(c) - delta[i * k + j]) / sin;
                        for c in 0..3 {
                            t[c] += f * v[c];
                        }
                    }
                }
                if total > 0.0 {
                    t.map(|v| v / total)
                } else {
                    [0.0; 3]
                }
            })
            .collect();
        let accepted = loop {
            let trial: Vec<[f64; 3]> = x
                .iter()
                .zip(&directions)
                .map(|(&p, t)| exp_map(p, t.map(|v| alpha * v)))
                .collect();
            let s = landmark_stress(delta, w, power, &trial);
            if s <= sigma {
                break Some((trial, s));
            }
            alpha *= 0.5;
            stage.halvings += 1;
            if alpha < 1e-12 {
                break None;
            }
        };
        let Some((trial, s)) = accepted else {
            stage.converged = true;
            break;
        };
        x.copy_from_slice(&trial);
        stage.iterations += 1;
        stage.stress_history.push(s);
        let decrease = (sigma - s) / sigma;
        sigma = s;
        alpha = (2.0 * alpha).min(MAX_STEP);
        if decrease < tolerance {
            stage.converged = true;
            break;
        }
    }
    stage.final_stress = sigma;
    stage.stress1 = if norm > 0.0 { (sigma / norm).sqrt() } else { 0.0 };
    stage
}

/// Σ_l w_l (δ_l − d(x, y_l))² (`w` None: all 1).
pub(crate) fn point_stress(x: [f64; 3], targets: &[[f64; 3]], delta: &[f64], w: Option<&[f64]>) -> f64 {
    let mut s = 0.0;
    for (l, &y) in targets.iter().enumerate() {
        let e = delta[l] - arc(x, y);
        s += w.map_or(1.0, |w| w[l]) * e * e;
    }
    s
}

/// Minimizes [`point_stress`] over x ∈ S² from `x0` by Gauss–Newton in the tangent plane with
/// step halving (module docs), for at most `max_iterations` steps. Returns the point, its
/// stress and the steps taken. The stress never rises.
pub(crate) fn place_point(
    x0: [f64; 3],
    targets: &[[f64; 3]],
    delta: &[f64],
    w: Option<&[f64]>,
    max_iterations: usize,
) -> ([f64; 3], f64, usize) {
    let mut x = x0;
    let mut f = point_stress(x, targets, delta, w);
    let mut steps = 0;
    while steps < max_iterations && f > 0.0 {
        // a tangent basis at x
        let axis = if x[0].abs() < 0.6 {
            [1.0, 0.0, 0.0]
        } else {
            [0.0, 1.0, 0.0]
        };
        let Some(e1) = normalized(cross(x, axis)) else {
            break;
        };
        let e2 = cross(x, e1);
        let (mut h, mut g) = ([0.0f64; 3], [0.0f64; 2]);
        for (l, &y) in targets.iter().enumerate() {
            let Some(u) = toward(x, y) else {
                continue;
            };
            let wl = w.map_or(1.0, |w| w[l]);
            let r = arc(x, y) - delta[l];
            // ∇d = −u
            let j = [-dot(u, e1), -dot(u, e2)];
            h[0] += wl * j[0] * j[0];
            h[1] += wl * j[0] * j[1];
            h[2] += wl * j[1] * j[1];
            g[0] += wl * r * j[0];
            g[1] += wl * r * j[1];
        }
        let damping = 1e-12 * (h[0] + h[2]) + f64::MIN_POSITIVE;
        let (a, b, c) = (h[0] + damping, h[1], h[2] + damping);
        let det = a * c - b * b;
        if !(det > 0.0) {
            break;
        }
        let s = [-(c * g[0] - b * g[1]) / det, -(a * g[1] - b * g[0]) / det];
        let t = [0, 1, 2].map(|k| s[0] * e1[k] + s[1] * e2[k]);
        let mut alpha = 1.0;
        let accepted = loop {
            let trial = exp_map(x, t.map(|v| alpha * v));
            let ft = point_stress(trial, targets, delta, w);
            if ft <= f {
                break Some((trial, ft));
            }
            alpha *= 0.5;
            if alpha < 1e-10 {
                break None;
            }
        };
        let Some((trial, ft)) = accepted else {
            break;
        };
        let moved = alpha * dot(t, t).sqrt();
        let decrease = f - ft;
        x = trial;
        f = ft;
        steps += 1;
        if moved < 1e-12 || decrease <= 1e-14 * f {
            break;
        }
    }
    (x, f, steps)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn unit(p: [f64; 3]) -> [f64; 3] {
        normalized(p).unwrap()
    }

    /// exp and the great-circle distance agree: a tangent step of length θ < π moves by θ.
    #[test]
    fn exp_map_moves_by_the_tangent_length() {
        let x = unit([0.3, -0.4, 0.8]);
        let e = normalized(cross(x, [1.0, 0.0, 0.0])).unwrap();
        for theta in [1e-9, 0.1, 1.0, 3.0] {
            let y = exp_map(x, e.map(|v| theta * v));
            assert!((arc(x, y) - theta).abs() < 1e-14 * theta.max(1.0), "{theta}");
            assert!((dot(y, y) - 1.0).abs() < 1e-15);
        }
        assert_eq!(arc([0.0, 0.0, 1.0], [0.0, 0.0, -1.0]), std::f64::consts::PI);
    }

    /// A point placed from its exact distances to four fixed points returns to its position.
    #[test]
    fn place_point_trilaterates() {
        let targets = [
            [1.0, 0.0, 0.0],
            [0.0, 1.0, 0.0],
            [0.0, 0.0, 1.0],
            unit([-1.0, -1.0, 0.2]),
        ];
        let truth = unit([0.2, 0.5, -0.3]);
        let delta: Vec<f64> = targets.iter().map(|&y| arc(truth, y)).collect();
        let (x, f, steps) = place_point(unit([0.6, 0.6, 0.1]), &targets, &delta, None, 50);
        assert!(
            arc(x, truth) < 1e-10 && f < 1e-20,
            "{x:?} after {steps} steps, stress {f}"
        );
    }

    /// The landmark iteration recovers points of S² from their exact distances (up to a
    /// rotation or reflection: all distances match) from a perturbed start, the stress never
    /// rising.
    #[test]
    fn smacof_on_sphere_recovers_exact_distances() {
        let truth: Vec<[f64; 3]> = (0..40)
            .map(|i| {
                let z = 1.0 - (2 * i + 1) as f64 / 40.0;
                let a = i as f64 * 2.399_963;
                let r = (1.0 - z * z).sqrt();
                [r * a.cos(), r * a.sin(), z]
            })
            .collect();
        let k = truth.len();
        let delta: Vec<f64> = (0..k * k).map(|ij| arc(truth[ij / k], truth[ij % k])).collect();
        let mut x: Vec<[f64; 3]> = truth
            .iter()
            .enumerate()
            .map(|(i, p)| unit([p[0] + 0.2 * (i as f64).sin(), p[1] + 0.2 * (i as f64 * 1.7).cos(), p[2]]))
            .collect();
        let w = vec![1.0; k];
        let stage = smacof_on_sphere(&delta, &w, 0.0, &mut x, 2000, 1e-14);
        let mut prev = stage.initial_stress;
        for &s in &stage.stress_history {
            assert!(s <= prev);
            prev = s;
        }
        assert!(stage.stress1 < 1e-6, "{stage:?}");
        let worst = (0..k * k)
            .map(|ij| (arc(x[ij / k], x[ij % k]) - delta[ij]).abs())
            .fold(0.0, f64::max);
        assert!(worst < 1e-5, "{worst}");
    }
}
