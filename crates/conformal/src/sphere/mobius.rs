//! Möbius maps of the unit sphere in homogeneous coordinates.
//!
//! A point x ∈ S² is a pair (u, v) ∈ ℂ² \ {0} up to a complex factor, with stereographic
//! coordinate ζ = u / v (projection from the north pole: the south pole is ζ = 0, the north
//! pole ζ = ∞, the equator |ζ| = 1, the point (1, 0, 0) is ζ = 1):
//! $$ x = \frac{\big(2\,\mathrm{Re}(u\bar v),\; 2\,\mathrm{Im}(u\bar v),\; |u|^2 - |v|^2\big)}{|u|^2 + |v|^2}. $$
//! A Möbius map ζ ↦ (aζ + b)/(cζ + d) acts linearly, (u, v) ↦ (au + bv, cu + dv), so the poles
//! need no special case and a composition is a 2 × 2 matrix product. Every orientation-
//! preserving conformal map of S² onto itself is of this form.

use std::ops::{Add, Div, Mul, Neg, Sub};

/// A complex number (the crate keeps planar points as `[f64; 2]`; this is the arithmetic).
#[derive(Clone, Copy, Debug, Default, PartialEq, serde::Serialize)]
pub struct Complex {
    pub re: f64,
    pub im: f64,
}

impl Complex {
    /// re + i·im.
    pub const fn new(re: f64, im: f64) -> Self {
        Complex { re, im }
    }
    /// The complex conjugate.
    pub fn conj(self) -> Self {
        Complex::new(self.re, -self.im)
    }
    /// |z|² .
    pub fn norm_sqr(self) -> f64 {
        self.re * self.re + self.im * self.im
    }
    /// |z| (without overflow).
    pub fn abs(self) -> f64 {
        self.re.hypot(self.im)
    }
    /// 1 / z (∞ components for z = 0).
    pub fn recip(self) -> Self {
        let s = self.re.abs().max(self.im.abs());
        if !(s > 0.0) {
            return Complex::new(f64::INFINITY, 0.0);
        }
        let (a, b) = (self.re / s, self.im / s);
        let d = a * a + b * b;
        Complex::new(a / (d * s), -b / (d * s))
    }
    /// z · s for real s.
    pub fn scale(self, s: f64) -> Self {
        Complex::new(self.re * s, self.im * s)
    }
}

impl Add for Complex {
    type Output = Complex;
    fn add(self, o: Complex) -> Complex {
        Complex::new(self.re + o.re, self.im + o.im)
    }
}
impl Sub for Complex {
    type Output = Complex;
    fn sub(self, o: Complex) -> Complex {
        Complex::new(self.re - o.re, self.im - o.im)
    }
}
impl Mul for Complex {
    type Output = Complex;
    fn mul(self, o: Complex) -> Complex {
        Complex::new(self.re * o.re - self.im * o.im, self.re * o.im + self.im * o.re)
    }
}
impl Div for Complex {
    type Output = Complex;
    fn div(self, w: Complex) -> Complex {
        let r = w.recip();
        Complex::new(self.re * r.re - self.im * r.im, self.re * r.im + self.im * r.re)
    }
}
impl Neg for Complex {
    type Output = Complex;
    fn neg(self) -> Complex {
        Complex::new(-self.re, -self.im)
    }
}

/// Homogeneous coordinates (u, v) of a point of the extended plane / the sphere.
pub type Homogeneous = [Complex; 2];

/// (u, v) scaled by a power of two so that max(|u|, |v|) ∈ [1, 2) (exact; the point is the
/// same). `None` for (0, 0) or non-finite input.
pub fn rescale(h: Homogeneous) -> Option<Homogeneous> {
    let m = [h[0].re, h[0].im, h[1].re, h[1].im]
        .iter()
        .fold(0.0f64, |a, x| a.max(x.abs()));
    if !(m > 0.0) || !m.is_finite() {
        return None;
    }
    let (s, _) = crate::quality::power_of_two_scale(m);
    Some([h[0].scale(s), h[1].scale(s)])
}

/// The point of S² with homogeneous coordinates h (module docs); `None` for (0, 0) or
/// non-finite h.
pub fn to_sphere(h: Homogeneous) -> Option<[f64; 3]> {
    let [u, v] = rescale(h)?;
    let (nu, nv) = (u.norm_sqr(), v.norm_sqr());
    let d = nu + nv;
    let w = u * v.conj();
    Some([2.0 * w.re / d, 2.0 * w.im / d, (nu - nv) / d])
}

/// Homogeneous coordinates of x ∈ S² (|x| = 1 is assumed): (x₁ + i x₂, 1 − x₃) on the southern
/// half, (1 + x₃, x₁ − i x₂) on the northern half (the same point, without cancellation).
pub fn from_sphere(x: [f64; 3]) -> Homogeneous {
    if x[2] <= 0.0 {
        [Complex::new(x[0], x[1]), Complex::new(1.0 - x[2], 0.0)]
    } else {
        [Complex::new(1.0 + x[2], 0.0), Complex::new(x[0], -x[1])]
    }
}

/// A Möbius map of the sphere, ζ ↦ (aζ + b)/(cζ + d), as the matrix [[a, b], [c, d]] acting on
/// homogeneous coordinates (module docs). The matrix is kept with max entry about 1.
#[derive(Clone, Copy, Debug, PartialEq, serde::Serialize)]
pub struct SphereMobius {
    /// [[a, b], [c, d]].
    pub m: [[Complex; 2]; 2],
}

impl SphereMobius {
    /// The identity.
    pub fn identity() -> Self {
        let (o, z) = (Complex::new(1.0, 0.0), Complex::default());
        SphereMobius { m: [[o, z], [z, o]] }
    }

    /// Applies the map to homogeneous coordinates.
    pub fn apply(&self, h: Homogeneous) -> Homogeneous {
        let m = &self.m;
        [m[0][0] * h[0] + m[0][1] * h[1], m[1][0] * h[0] + m[1][1] * h[1]]
    }

    /// Applies the map to a point of S².
    pub fn apply_point(&self, x: [f64; 3]) -> Option<[f64; 3]> {
        to_sphere(self.apply(from_sphere(x)))
    }

    /// The inverse map ([[d, −b], [−c, a]], the same map as the inverse matrix).
    pub fn inverse(&self) -> Self {
        let m = &self.m;
        SphereMobius {
            m: [[m[1][1], -m[0][1]], [-m[1][0], m[0][0]]],
        }
    }

    /// `self ∘ first` (first `first`, then `self`).
    pub fn compose(&self, first: &SphereMobius) -> Self {
        let (a, b) = (&self.m, &first.m);
        let mut m = [[Complex::default(); 2]; 2];
        for i in 0..2 {
            for j in 0..2 {
                m[i][j] = a[i][0] * b[0][j] + a[i][1] * b[1][j];
            }
        }
        SphereMobius { m }.normalized()
    }

    /// The same map with its matrix scaled (by a power of two) to entries of size about 1.
    fn normalized(self) -> Self {
        let mx = self
            .m
            .iter()
            .flatten()
            .fold(0.0f64, |a, z| a.max(z.re.abs()).max(z.im.abs()));
        if !(mx > 0.0) || !mx.is_finite() {
            return self;
        }
        let (s, _) = crate::quality::power_of_two_scale(mx);
        SphereMobius {
            m: self.m.map(|row| row.map(|z| z.scale(s))),
        }
    }

    /// The map sending the points h1, h2, h3 to ζ = 0, 1, ∞ (south pole, (1, 0, 0), north
    /// pole): ζ ↦ (ζ − ζ₁)(ζ₂ − ζ₃) / ((ζ − ζ₃)(ζ₂ − ζ₁)) [Su et al. 2015, Theorem 6], to
    /// rounding (callers that need the markers exact set them afterwards). `None` when two of
    /// the points coincide (to rounding) or an input is not finite.
    pub fn three_points(h1: Homogeneous, h2: Homogeneous, h3: Homogeneous) -> Option<Self> {
        let (h1, h2, h3) = (rescale(h1)?, rescale(h2)?, rescale(h3)?);
        // (ζ − ζ_k) ∝ v_k u − u_k v
        let cross = |p: Homogeneous, q: Homogeneous| p[1] * q[0] - p[0] * q[1];
        let d1 = cross(h1, h2);
        let d3 = cross(h3, h2);
        let d13 = cross(h1, h3);
        let tiny = 1e-14;
        if !(d1.abs() > tiny && d3.abs() > tiny && d13.abs() > tiny) {
            return None;
        }
        // rows (k·v1, −k·u1) and (v3, −u3) with k = d3/d1, so that h2 ↦ (d3, d3)
        let k = d3 / d1;
        let m = SphereMobius {
            m: [[k * h1[1], -(k * h1[0])], [h3[1], -h3[0]]],
        };
        let m = m.normalized();
        m.m.iter()
            .flatten()
            .all(|z| z.re.is_finite() && z.im.is_finite())
            .then_some(m)
    }

    /// The hyperbolic boost exp(β·σ/2) along β ∈ ℝ³: it fixes ±β/|β| and moves every other
    /// point towards +β/|β| along great circles; to first order x ↦ x + β − ⟨β, x⟩x.
    pub fn boost(beta: [f64; 3]) -> Self {
        let b = (beta[0] * beta[0] + beta[1] * beta[1] + beta[2] * beta[2]).sqrt();
        if !(b > 0.0) {
            return Self::identity();
        }
        let (ch, sh) = ((0.5 * b).cosh(), (0.5 * b).sinh() / b);
        let (x, y, z) = (beta[0] * sh, beta[1] * sh, beta[2] * sh);
        // ch·I + x σ_x − y σ_y + z σ_z (σ_y enters with a minus sign: x₂ = −⟨σ_y⟩ in the
        // coordinates of the module docs)
        SphereMobius {
            m: [
                [Complex::new(ch + z, 0.0), Complex::new(x, y)],
                [Complex::new(x, -y), Complex::new(ch - z, 0.0)],
            ],
        }
        .normalized()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn close(a: [f64; 3], b: [f64; 3], tol: f64) -> bool {
        (0..3).all(|k| (a[k] - b[k]).abs() <= tol)
    }

    #[test]
    fn round_trip_and_poles() {
        for x in [
            [0.0, 0.0, 1.0],
            [0.0, 0.0, -1.0],
            [1.0, 0.0, 0.0],
            [0.6, 0.0, 0.8],
            [0.0, -0.6, -0.8],
            [0.48, 0.64, 0.6],
        ] {
            let y = to_sphere(from_sphere(x)).unwrap();
            assert!(close(x, y, 1e-15), "{x:?} {y:?}");
        }
        let south = to_sphere([Complex::default(), Complex::new(3.0, 1.0)]).unwrap();
        assert_eq!(south, [0.0, 0.0, -1.0]);
        let one = to_sphere([Complex::new(1.0, 0.0), Complex::new(1.0, 0.0)]).unwrap();
        assert_eq!(one, [1.0, 0.0, 0.0]);
        assert!(to_sphere([Complex::default(), Complex::default()]).is_none());
    }

    #[test]
    fn three_points_hit_zero_one_infinity() {
        let p = [[0.48, 0.64, 0.6], [0.0, -0.6, -0.8], [-0.36, 0.48, 0.8]];
        let m = SphereMobius::three_points(from_sphere(p[0]), from_sphere(p[1]), from_sphere(p[2])).unwrap();
        assert!(close(m.apply_point(p[0]).unwrap(), [0.0, 0.0, -1.0], 1e-15));
        assert!(close(m.apply_point(p[2]).unwrap(), [0.0, 0.0, 1.0], 1e-15));
        assert!(close(m.apply_point(p[1]).unwrap(), [1.0, 0.0, 0.0], 1e-15));
        assert!(SphereMobius::three_points(from_sphere(p[0]), from_sphere(p[0]), from_sphere(p[2])).is_none());
    }

    #[test]
    fn boost_moves_points_towards_its_direction() {
        let dir = [0.0, 0.6, 0.8];
        let m = SphereMobius::boost([0.0, 0.3, 0.4]);
        // the fixed points
        assert!(close(m.apply_point(dir).unwrap(), dir, 1e-15));
        let anti = [0.0, -0.6, -0.8];
        assert!(close(m.apply_point(anti).unwrap(), anti, 1e-15));
        // first order: x + β − ⟨β, x⟩x
        let eps = 1e-6;
        let beta = [eps, -2.0 * eps, 0.5 * eps];
        let x = [0.48, 0.64, 0.6];
        let y = SphereMobius::boost(beta).apply_point(x).unwrap();
        let d = beta[0] * x[0] + beta[1] * x[1] + beta[2] * x[2];
        for k in 0..3 {
            let expected = x[k] + beta[k] - d * x[k];
            assert!((y[k] - expected).abs() < 1e-11, "{k}: {} {}", y[k], expected);
        }
        // a composition is the matrix product
        let a = SphereMobius::boost([0.2, -0.1, 0.3]);
        let c = a.compose(&m);
        let (y1, y2) = (
            c.apply_point(x).unwrap(),
            a.apply_point(m.apply_point(x).unwrap()).unwrap(),
        );
        assert!(close(y1, y2, 1e-14));
        assert!(close(c.inverse().apply_point(y1).unwrap(), x, 1e-14));
    }
}
