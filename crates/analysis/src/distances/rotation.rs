//! Rotations of S² for the spherical distance's search over SO(3): unit quaternions, the best
//! rotation between weighted point pairs [Horn 1987, "Closed-form solution of absolute
//! orientation using unit quaternions", §4], a grid over SO(3), and the angle between two
//! rotations.
//!
//! Horn's method: the rotation R maximizing Σ_k w_k ⟨R a_k, b_k⟩ is the unit quaternion of the
//! largest eigenvalue of the symmetric 4×4 matrix N built from S = Σ_k w_k a_k b_kᵀ; unlike the
//! polar factor of S it is a proper rotation (det +1) for any S. The 4×4 eigenproblem is solved
//! by cyclic Jacobi rotations.

/// A rotation matrix, rows.
pub type Rotation = [[f64; 3]; 3];

/// The identity rotation.
pub const IDENTITY: Rotation = [[1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]];

/// R·p.
pub fn apply(r: &Rotation, p: [f64; 3]) -> [f64; 3] {
    r.map(|row| row[0] * p[0] + row[1] * p[1] + row[2] * p[2])
}

/// The product A·B (B first).
pub fn compose(a: &Rotation, b: &Rotation) -> Rotation {
    let mut out = [[0.0; 3]; 3];
    for (i, row) in out.iter_mut().enumerate() {
        for (j, x) in row.iter_mut().enumerate() {
            *x = (0..3).map(|k| a[i][k] * b[k][j]).sum();
        }
    }
    out
}

/// Rᵀ.
pub fn transpose(r: &Rotation) -> Rotation {
    let mut out = [[0.0; 3]; 3];
    for (i, row) in r.iter().enumerate() {
        for (j, &x) in row.iter().enumerate() {
            out[j][i] = x;
        }
    }
    out
}

/// The angle (radians, in [0, π]) of the rotation A Bᵀ taking B to A.
pub fn angle_between(a: &Rotation, b: &Rotation) -> f64 {
    let trace: f64 = (0..3).map(|i| (0..3).map(|k| a[i][k] * b[i][k]).sum::<f64>()).sum();
    ((trace - 1.0) / 2.0).clamp(-1.0, 1.0).acos()
}

/// The rotation of the unit quaternion (w, x, y, z) (normalized here).
pub fn from_quaternion(q: [f64; 4]) -> Rotation {
    let n = q.iter().map(|x| x * x).sum::<f64>().sqrt();
    let [w, x, y, z] = q.map(|c| c / n);
    [
        [
            1.0 - 2.0 * (y * y + z * z),
            2.0 * (x * y - z * w),
            2.0 * (x * z + y * w),
        ],
        [
            2.0 * (x * y + z * w),
            1.0 - 2.0 * (x * x + z * z),
            2.0 * (y * z - x * w),
        ],
        [
            2.0 * (x * z - y * w),
            2.0 * (y * z + x * w),
            1.0 - 2.0 * (x * x + y * y),
        ],
    ]
}

/// The rotation by `angle` radians about the unit `axis` (right-handed).
pub fn axis_angle(axis: [f64; 3], angle: f64) -> Rotation {
    let (s, c) = (angle / 2.0).sin_cos();
    from_quaternion([c, s * axis[0], s * axis[1], s * axis[2]])
}

/// The rotation vector ω (axis × angle, |ω| ≤ π) of `r`: `exp_rotation(log_rotation(r)) = r`.
pub fn log_rotation(r: &Rotation) -> [f64; 3] {
    let angle = ((r[0][0] + r[1][1] + r[2][2] - 1.0) / 2.0).clamp(-1.0, 1.0).acos();
    let v = [r[2][1] - r[1][2], r[0][2] - r[2][0], r[1][0] - r[0][1]];
    if angle < 1e-8 {
        return v.map(|x| x / 2.0);
    }
    if angle > std::f64::consts::PI - 1e-6 {
        // near a half turn: the axis from the diagonal of (R + I)/2 = a aᵀ
        let k = (0..3).max_by(|&i, &j| r[i][i].total_cmp(&r[j][j])).unwrap_or(0);
        let col = [0, 1, 2].map(|i| (r[i][k] + r[k][i]) / 2.0 + if i == k { 1.0 } else { 0.0 });
        let n = (col[0] * col[0] + col[1] * col[1] + col[2] * col[2]).sqrt();
        return col.map(|x| x / n * angle);
    }
    let s = 2.0 * angle.sin();
    v.map(|x| x / s * angle)
}

/// The rotation exp(ω): by |ω| radians about ω/|ω|.
pub fn exp_rotation(w: [f64; 3]) -> Rotation {
    let angle = (w[0] * w[0] + w[1] * w[1] + w[2] * w[2]).sqrt();
    if angle == 0.0 {
        return IDENTITY;
    }
    axis_angle(w.map(|x| x / angle), angle)
}

/// The rotation R maximizing Σ_k w_k ⟨R a_k, b_k⟩ (Horn's quaternion method, module docs);
/// `pairs` yields (a_k, b_k, w_k). The identity when S = 0.
pub fn best_rotation(pairs: impl Iterator<Item = ([f64; 3], [f64; 3], f64)>) -> Rotation {
    let mut s = [[0.0; 3]; 3];
    for (a, b, w) in pairs {
        for i in 0..3 {
            for j in 0..3 {
                s[i][j] += w * a[i] * b[j];
            }
        }
    }
    let [[sxx, sxy, sxz], [syx, syy, syz], [szx, szy, szz]] = s;
    let n = [
        [sxx + syy + szz, syz - szy, szx - sxz, sxy - syx],
        [syz - szy, sxx - syy - szz, sxy + syx, szx + sxz],
        [szx - sxz, sxy + syx, -sxx + syy - szz, syz + szy],
        [sxy - syx, szx + sxz, syz + szy, -sxx - syy + szz],
    ];
    if n.iter().flatten().all(|&x| x == 0.0) {
        return IDENTITY;
    }
    let (values, vectors) = jacobi_eigen4(n);
    let k = (0..4).max_by(|&i, &j| values[i].total_cmp(&values[j])).unwrap_or(0);
    from_quaternion([vectors[0][k], vectors[1][k], vectors[2][k], vectors[3][k]])
}

/// Eigenvalues and eigenvectors (columns of the second result) of a symmetric 4×4 matrix by
/// cyclic Jacobi sweeps until the off-diagonal part is below 1e-15 of the norm.
fn jacobi_eigen4(mut a: [[f64; 4]; 4]) -> ([f64; 4], [[f64; 4]; 4]) {
    let mut v = [[0.0; 4]; 4];
    for (i, row) in v.iter_mut().enumerate() {
        row[i] = 1.0;
    }
    let scale: f64 = a.iter().flatten().map(|x| x * x).sum::<f64>().sqrt();
    for _ in 0..50 {
        let off: f64 = (0..4)
            .flat_map(|i| (0..4).filter(move |&j| j != i).map(move |j| (i, j)))
            .map(|(i, j)| a[i][j] * a[i][j])
            .sum::<f64>()
            .sqrt();
        if off <= 1e-15 * scale {
            break;
        }
        for p in 0..3 {
            for q in (p + 1)..4 {
                if a[p][q] == 0.0 {
                    continue;
                }
                let theta = (a[q][q] - a[p][p]) / (2.0 * a[p][q]);
                let t = theta.signum() / (theta.abs() + (theta * theta + 1.0).sqrt());
                let t = if theta == 0.0 { 1.0 } else { t };
                let c = 1.0 / (t * t + 1.0).sqrt();
                let s = t * c;
                for k in 0..4 {
                    let (akp, akq) = (a[k][p], a[k][q]);
                    a[k][p] = c * akp - s * akq;
                    a[k][q] = s * akp + c * akq;
                }
                for k in 0..4 {
                    let (apk, aqk) = (a[p][k], a[q][k]);
                    a[p][k] = c * apk - s * aqk;
                    a[q][k] = s * apk + c * aqk;
                }
                for row in v.iter_mut() {
                    let (vp, vq) = (row[p], row[q]);
                    row[p] = c * vp - s * vq;
                    row[q] = s * vp + c * vq;
                }
            }
        }
    }
    ([a[0][0], a[1][1], a[2][2], a[3][3]], v)
}

/// A rotation taking the north pole e₃ to the unit vector `d`.
fn pole_to(d: [f64; 3]) -> Rotation {
    let t = if d[0].abs() < 0.9 {
        [1.0, 0.0, 0.0]
    } else {
        [0.0, 1.0, 0.0]
    };
    let dot = t[0] * d[0] + t[1] * d[1] + t[2] * d[2];
    let p = [t[0] - dot * d[0], t[1] - dot * d[1], t[2] - dot * d[2]];
    let l = (p[0] * p[0] + p[1] * p[1] + p[2] * p[2]).sqrt();
    let e1 = p.map(|x| x / l);
    let e2 = [
        d[1] * e1[2] - d[2] * e1[1],
        d[2] * e1[0] - d[0] * e1[2],
        d[0] * e1[1] - d[1] * e1[0],
    ];
    // columns e1, e2, d
    [[e1[0], e2[0], d[0]], [e1[1], e2[1], d[1]], [e1[2], e2[2], d[2]]]
}

/// A grid over SO(3): for each of `directions` Fibonacci directions d, the rotations
/// R = P_d · R_z(2πj/`spins`), j < `spins`, with P_d a rotation taking e₃ to d (so R e₃ = d). Every rotation lies within about half the directions' spacing plus half the spin step of
/// one of them (√(4π/directions)/2 + π/spins: 0.21 + 0.26 rad for 72 × 12).
pub fn rotation_grid(directions: usize, spins: usize) -> Vec<Rotation> {
    let mut out = Vec::with_capacity(directions * spins);
    for d in shapespace_omt::sphere::fibonacci_sphere(directions) {
        let p = pole_to(d);
        for j in 0..spins {
            let spin = axis_angle([0.0, 0.0, 1.0], std::f64::consts::TAU * j as f64 / spins as f64);
            out.push(compose(&p, &spin));
        }
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    fn det(r: &Rotation) -> f64 {
        r[0][0] * (r[1][1] * r[2][2] - r[1][2] * r[2][1]) - r[0][1] * (r[1][0] * r[2][2] - r[1][2] * r[2][0])
            + r[0][2] * (r[1][0] * r[2][1] - r[1][1] * r[2][0])
    }

    /// Horn's method recovers a rotation from exact pairs (to 1e-12), and from pairs whose
    /// cross-covariance has a negative determinant (a reflection would fit better) it still
    /// returns a proper rotation.
    #[test]
    fn best_rotation_recovers_a_rotation_and_is_proper() {
        let r = axis_angle([0.48, -0.6, 0.64], 2.3);
        let a = shapespace_omt::sphere::random_sphere_points(50, 7);
        let b: Vec<[f64; 3]> = a.iter().map(|&p| apply(&r, p)).collect();
        let got = best_rotation(a.iter().zip(&b).map(|(&p, &q)| (p, q, 1.0)));
        assert!(angle_between(&got, &r) < 1e-12, "{}", angle_between(&got, &r));
        // the mirror image of `a` through the xy plane
        let mirrored: Vec<[f64; 3]> = a.iter().map(|p| [p[0], p[1], -p[2]]).collect();
        let got = best_rotation(a.iter().zip(&mirrored).map(|(&p, &q)| (p, q, 1.0)));
        assert!((det(&got) - 1.0).abs() < 1e-12, "{}", det(&got));
        // no rotation fits better than the one found: random perturbations do worse
        let score = |r: &Rotation| -> f64 {
            a.iter()
                .zip(&mirrored)
                .map(|(&p, q)| {
                    let x = apply(r, p);
                    x[0] * q[0] + x[1] * q[1] + x[2] * q[2]
                })
                .sum()
        };
        for (k, axis) in shapespace_omt::sphere::random_sphere_points(20, 3)
            .into_iter()
            .enumerate()
        {
            let other = compose(&axis_angle(axis, 0.05 * (1 + k % 4) as f64), &got);
            assert!(score(&other) <= score(&got) + 1e-12);
        }
    }

    #[test]
    fn log_inverts_exp() {
        for (k, axis) in shapespace_omt::sphere::random_sphere_points(30, 5)
            .into_iter()
            .enumerate()
        {
            let angle = [1e-10, 1e-3, 0.5, 2.0, 3.0, std::f64::consts::PI - 1e-8][k % 6];
            let r = axis_angle(axis, angle);
            let back = exp_rotation(log_rotation(&r));
            assert!(angle_between(&back, &r) < 1e-7, "{angle}: {}", angle_between(&back, &r));
        }
    }

    /// Every rotation of a random sample lies within the grid's covering radius (0.47 rad for
    /// 72 × 12) of some grid rotation.
    #[test]
    fn the_grid_covers_so3() {
        let grid = rotation_grid(72, 12);
        assert_eq!(grid.len(), 864);
        for g in &grid {
            assert!((det(g) - 1.0).abs() < 1e-12);
        }
        let axes = shapespace_omt::sphere::random_sphere_points(200, 11);
        let mut worst: f64 = 0.0;
        for (k, axis) in axes.iter().enumerate() {
            let r = axis_angle(*axis, std::f64::consts::PI * ((k * 37) % 100) as f64 / 100.0);
            let nearest = grid.iter().map(|g| angle_between(g, &r)).fold(f64::INFINITY, f64::min);
            worst = worst.max(nearest);
        }
        assert!(worst < 0.47, "{worst}");
    }
}
