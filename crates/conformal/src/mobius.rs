//! Möbius automorphisms of the unit disk.
//!
//! Every conformal automorphism of the unit disk D has the form
//! $$ M(z) = e^{i\theta}\,\frac{z - a}{1 - \bar a z}, \qquad |a| < 1, $$
//! [Ahlfors, *Complex Analysis*, §1.3]. It maps D onto D and the circle onto itself, sends
//! a ↦ 0, and |M'(z)| = (1 − |a|²)/|1 − āz|². The disk-map normalization of `docs/conventions.md` takes
//! a = φ(p) (the image of the interior marker) and θ such that M(φ(q)) = 1.
//!
//! Points are `[re, im]` pairs; internally [`faer::c64`].

use faer::c64;

/// z ↦ e^{iθ}(z − a)/(1 − āz), a disk automorphism for |a| < 1.
#[derive(Clone, Copy, Debug, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct Mobius {
    /// The point sent to 0, |a| < 1.
    pub a: [f64; 2],
    /// The rotation angle θ (radians).
    pub theta: f64,
}

#[inline]
fn c(z: [f64; 2]) -> c64 {
    c64::new(z[0], z[1])
}

#[inline]
fn arr(z: c64) -> [f64; 2] {
    [z.re, z.im]
}

impl Mobius {
    /// The identity map (a = 0, θ = 0).
    pub fn identity() -> Self {
        Mobius {
            a: [0.0, 0.0],
            theta: 0.0,
        }
    }

    /// The automorphism with a ↦ 0 and `q` ↦ 1, for |a| < 1 and |q| = 1 (q ≠ a).
    /// θ = −arg((q − a)/(1 − āq)).
    pub fn normalizing(a: [f64; 2], q: [f64; 2]) -> Self {
        let (ac, qc) = (c(a), c(q));
        let w = (qc - ac) / (c64::new(1.0, 0.0) - ac.conj() * qc);
        Mobius { a, theta: -w.arg() }
    }

    /// M(z). Evaluated as e^{iθ}(z − a)/(1 − āz); when a = 0 it is the exact rotation
    /// e^{iθ}z, which keeps the relative precision of tiny |z|.
    pub fn apply(&self, z: [f64; 2]) -> [f64; 2] {
        let rot = c64::new(self.theta.cos(), self.theta.sin());
        if self.a == [0.0, 0.0] {
            return arr(rot * c(z));
        }
        let (zc, ac) = (c(z), c(self.a));
        arr(rot * (zc - ac) / (c64::new(1.0, 0.0) - ac.conj() * zc))
    }

    /// |M'(z)| = (1 − |a|²)/|1 − āz|², the local scale factor of M.
    pub fn derivative_abs(&self, z: [f64; 2]) -> f64 {
        let ac = c(self.a);
        (1.0 - ac.norm_sqr()) / (c64::new(1.0, 0.0) - ac.conj() * c(z)).norm_sqr()
    }

    /// The inverse automorphism: a' = −a e^{iθ}, θ' = −θ.
    pub fn inverse(&self) -> Self {
        let rot = c64::new(self.theta.cos(), self.theta.sin());
        Mobius {
            a: arr(-(c(self.a) * rot)),
            theta: -self.theta,
        }
    }

    /// The composition `self ∘ first` (apply `first`, then `self`), again of the same form:
    /// with α = e^{iθ₁} + a₂ā₁, β = e^{iθ₁}a₁ + a₂, γ = 1 + ā₂e^{iθ₁}a₁ one gets
    /// a = β/α and e^{iθ} = e^{iθ₂}α/γ (|α| = |γ|).
    pub fn compose(&self, first: &Mobius) -> Self {
        let (a1, a2) = (c(first.a), c(self.a));
        let r1 = c64::new(first.theta.cos(), first.theta.sin());
        let alpha = r1 + a2 * a1.conj();
        let beta = r1 * a1 + a2;
        let gamma = c64::new(1.0, 0.0) + a2.conj() * r1 * a1;
        let a = beta / alpha;
        let rot = (alpha / gamma).arg() + self.theta;
        Mobius {
            a: arr(a),
            theta: rot.rem_euclid(std::f64::consts::TAU),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use rand::{Rng, SeedableRng};
    use rand_chacha::ChaCha8Rng;

    fn random_in_disk(rng: &mut ChaCha8Rng, rmax: f64) -> [f64; 2] {
        let r = rmax * rng.random::<f64>().sqrt();
        let t = rng.random::<f64>() * std::f64::consts::TAU;
        [r * t.cos(), r * t.sin()]
    }

    fn dist(a: [f64; 2], b: [f64; 2]) -> f64 {
        ((a[0] - b[0]).powi(2) + (a[1] - b[1]).powi(2)).sqrt()
    }

    #[test]
    fn maps_a_to_zero_q_to_one_and_circle_to_circle() {
        let mut rng = ChaCha8Rng::seed_from_u64(7);
        for _ in 0..200 {
            let a = random_in_disk(&mut rng, 0.95);
            let t = rng.random::<f64>() * std::f64::consts::TAU;
            let q = [t.cos(), t.sin()];
            let m = Mobius::normalizing(a, q);
            let z0 = m.apply(a);
            assert!(z0[0].hypot(z0[1]) < 1e-15, "{z0:?}");
            assert!(dist(m.apply(q), [1.0, 0.0]) < 1e-14);
            for _ in 0..10 {
                let s = rng.random::<f64>() * std::f64::consts::TAU;
                let w = m.apply([s.cos(), s.sin()]);
                assert!((w[0].hypot(w[1]) - 1.0).abs() < 1e-15 * 4.0, "{w:?}");
                let z = random_in_disk(&mut rng, 0.999);
                let w = m.apply(z);
                assert!(w[0].hypot(w[1]) < 1.0);
            }
        }
    }

    #[test]
    fn inverse_and_composition() {
        let mut rng = ChaCha8Rng::seed_from_u64(11);
        for _ in 0..200 {
            let m1 = Mobius {
                a: random_in_disk(&mut rng, 0.9),
                theta: rng.random::<f64>() * 6.0,
            };
            let m2 = Mobius {
                a: random_in_disk(&mut rng, 0.9),
                theta: rng.random::<f64>() * 6.0,
            };
            let inv = m1.inverse();
            let comp = m2.compose(&m1);
            for _ in 0..10 {
                let z = random_in_disk(&mut rng, 0.99);
                assert!(dist(inv.apply(m1.apply(z)), z) < 1e-12);
                assert!(dist(m1.apply(inv.apply(z)), z) < 1e-12);
                assert!(dist(comp.apply(z), m2.apply(m1.apply(z))) < 1e-12);
            }
            let id = m1.compose(&inv);
            assert!(id.a[0].hypot(id.a[1]) < 1e-14);
        }
    }

    #[test]
    fn derivative_matches_finite_difference() {
        let m = Mobius {
            a: [0.3, -0.4],
            theta: 1.0,
        };
        let z = [0.1, 0.2];
        let h = 1e-7;
        let w0 = m.apply(z);
        let w1 = m.apply([z[0] + h, z[1]]);
        let fd = dist(w0, w1) / h;
        assert!((fd - m.derivative_abs(z)).abs() < 1e-6);
    }

    #[test]
    fn rotation_keeps_tiny_points_exactly_scaled() {
        let m = Mobius {
            a: [0.0, 0.0],
            theta: 0.5,
        };
        let w = m.apply([1e-200, 0.0]);
        assert!((w[0].hypot(w[1]) / 1e-200 - 1.0).abs() < 1e-15);
    }
}
