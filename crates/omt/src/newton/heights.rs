//! The heights in double-double form (decision 0005): the bisectors' weights of crowded
//! points need more than f64's resolution.

/// Heights in double-double form, h_i = hi_i + lo_i exactly, as the solver keeps them.
///
/// What places a cell edge is a weight difference w_i − w_j = 2(h_i − h_j) + |y_i|² − |y_j|²
/// against the site distance |y_i − y_j|: sites 1e-9 apart whose cells must be 1e-2 wide need
/// h_i − h_j to ~1e-17, below one ulp of heights of order one. With plain f64 heights the
/// solve then ends at a floor of the mass error (≈ 1e-6 on the wolf of the area-preserving
/// tests, `docs/decisions/0005-double-double-heights.md`); in double-double form the weights reach the predicates and
/// the clipping exactly ([`DiagramBuilder::low_parts`](crate::power_diagram::DiagramBuilder::low_parts)). The Newton directions stay f64: an
/// error of a few ulps in δ only perturbs the step, it does not set a floor.
#[derive(Clone, Debug)]
pub(crate) struct Heights {
    pub hi: Vec<f64>,
    pub lo: Vec<f64>,
}

/// Renormalizes a + b (|b| small against |a| or not) into a double-double pair.
#[inline]
pub(super) fn renormalize(a: f64, b: f64) -> [f64; 2] {
    let (s, e) = crate::predicates::two_sum(a, b);
    [s, e]
}

/// ⟨u, v⟩ as a double-double pair (exact up to the last renormalization).
#[inline]
pub(super) fn dot_dd(u: [f64; 2], v: [f64; 2]) -> [f64; 2] {
    let (p1, e1) = crate::predicates::two_product(u[0], v[0]);
    let (p2, e2) = crate::predicates::two_product(u[1], v[1]);
    let (s, e) = crate::predicates::two_sum(p1, p2);
    renormalize(s, e + e1 + e2)
}

/// |y|² as a double-double pair (exact up to the last renormalization).
#[inline]
pub(super) fn squared_norm_dd(y: [f64; 2]) -> [f64; 2] {
    dot_dd(y, y)
}

/// k·d for a double-double d, as (high part, low part): the high product exact, the low part
/// rounded once (not renormalized).
#[inline]
pub(super) fn times_dd(k: f64, d: [f64; 2]) -> (f64, f64) {
    let (p, e) = crate::predicates::two_product(k, d[0]);
    (p, e + k * d[1])
}

impl Heights {
    pub(crate) fn from_f64(hi: Vec<f64>) -> Self {
        let lo = vec![0.0; hi.len()];
        Heights { hi, lo }
    }

    /// hi + lo, renormalized (the parts need not be a normalized pair).
    pub(crate) fn from_parts(hi: &[f64], lo: &[f64]) -> Self {
        let (hi, lo) = hi
            .iter()
            .zip(lo)
            .map(|(&h, &l)| {
                let r = renormalize(h, l);
                (r[0], r[1])
            })
            .unzip();
        Heights { hi, lo }
    }

    /// The Voronoi heights −|y_i|²/2 (weights exactly 0).
    pub(crate) fn voronoi(points: &[[f64; 2]]) -> Self {
        let (hi, lo) = points
            .iter()
            .map(|&y| {
                let q = squared_norm_dd(y);
                (-0.5 * q[0], -0.5 * q[1])
            })
            .unzip();
        Heights { hi, lo }
    }

    /// The heights whose power diagram is the Voronoi diagram of the points contracted by
    /// `scale` toward `center`, z_i = c + s(y_i − c): h_i = −(1 − s)⟨c, y_i⟩ − s|y_i|²/2, which
    /// is −|z_i|²/(2s) up to a constant common to all points (the weights are
    /// w_i = (1 − s)(|y_i − c|² − |c|²), and |x − y_i|² − w_i = |x − z_i|²/s + terms in x alone).
    /// In double-double: f64 heights −|z_i|²/(2s) carry a rounding of ~1e-16/s, which moves the
    /// bisector of two points δ apart by ~1e-16/(sδ); at the spacings of conformal images of
    /// limbs that emptied the cells the contraction should have filled (TOSCA dog0 → dog1, both
    /// slit, as a distance pair: at s = 1/2 880 empty cells toward the area centroid and 1,465
    /// toward the μ-barycenter, against none in the Voronoi diagram of the z_i; the solve then
    /// reported "no start" and guessed points far outside Ω).
    pub(crate) fn contracted(points: &[[f64; 2]], center: [f64; 2], scale: f64) -> Self {
        let (hi, lo) = points
            .iter()
            .map(|&y| {
                // (1 − s)⟨c, y⟩ and s|y|²/2 (1 − s and s/2 exact for the halved scales)
                let (a, a_lo) = times_dd(1.0 - scale, dot_dd(center, y));
                let (b, b_lo) = times_dd(0.5 * scale, squared_norm_dd(y));
                let (sum, es) = crate::predicates::two_sum(a, b);
                let r = renormalize(sum, es + a_lo + b_lo);
                (-r[0], -r[1])
            })
            .unzip();
        Heights { hi, lo }
    }

    /// h + τ·δ (the product rounded once, the sum kept exactly).
    pub(crate) fn step(&self, delta: &[f64], tau: f64) -> Self {
        let (hi, lo) = self
            .hi
            .iter()
            .zip(&self.lo)
            .zip(delta)
            .map(|((&h, &l), &d)| {
                let (s, e) = crate::predicates::two_sum(h, tau * d);
                let r = renormalize(s, e + l);
                (r[0], r[1])
            })
            .unzip();
        Heights { hi, lo }
    }

    /// The power weights w_i = 2h_i + |y_i|² as (high parts, low parts).
    pub(crate) fn weights(&self, points: &[[f64; 2]]) -> (Vec<f64>, Vec<f64>) {
        points
            .iter()
            .zip(self.hi.iter().zip(&self.lo))
            .map(|(&y, (&h, &l))| {
                let q = squared_norm_dd(y);
                let (s, e) = crate::predicates::two_sum(2.0 * h, q[0]);
                let r = renormalize(s, e + 2.0 * l + q[1]);
                (r[0], r[1])
            })
            .unzip()
    }
}

#[cfg(test)]
mod contraction_tests {
    use super::*;
    use crate::measure::SourceMeasure;
    use crate::power_diagram::{InsertionOrder, PowerDiagram};
    use crate::restricted::RestrictedIntegrator;

    /// The contracted heights' power diagram is the Voronoi diagram of the contracted points,
    /// also for a row of points 1.6e-11 apart (as at a limb's tip in a conformal image): no cell
    /// is empty and every cell mass agrees with that of the Voronoi diagram of the z_i (exact
    /// here) to 1e-13 (measured 7.6e-15), and the crowded cells (1e-13 … 4e-13 each) to 1e-3 of
    /// their mass (measured 1.2e-4). With f64 heights −|z_i|²/(2s)
    /// the masses are off by up to 1.3e-9, 6.3 times the crowded cells' own, and 22 of the
    /// cells were empty at s = 1/2.
    #[test]
    fn contracted_heights_give_the_voronoi_diagram_of_the_contracted_points() {
        let measure = SourceMeasure::unit_disk(256).unwrap();
        let mut points = Vec::new();
        // (dyadic coordinates, center and scales: the contracted points are exact)
        for k in 0..40 {
            let d = k as f64 * (2.0f64).powi(-37);
            points.push([0.5 + 2.0 * d, 0.25 + d + d * d * 1e3]);
        }
        for i in 0..7 {
            for j in 0..7 {
                let p = [-0.6 + 0.2 * i as f64, -0.6 + 0.2 * j as f64 + 0.01 * i as f64];
                points.push(p);
            }
        }
        let integrator = RestrictedIntegrator::new(&measure);
        let center = [0.125, -0.0625];
        for scale in [0.5, 0.25] {
            let heights = Heights::contracted(&points, center, scale);
            let (w, wl) = heights.weights(&points);
            let order = InsertionOrder::new(&points).unwrap();
            let ours = integrator.integrate(
                &PowerDiagram::builder(&points, &w)
                    .low_parts(Some(&wl))
                    .order(&order)
                    .build()
                    .unwrap(),
            );
            let z: Vec<[f64; 2]> = points
                .iter()
                .map(|y| {
                    [
                        center[0] + scale * (y[0] - center[0]),
                        center[1] + scale * (y[1] - center[1]),
                    ]
                })
                .collect();
            let voronoi = integrator.integrate(&PowerDiagram::new(&z, &vec![0.0; z.len()]).unwrap());
            for i in 0..points.len() {
                let (a, b) = (ours.masses[i], voronoi.masses[i]);
                assert!(
                    a > 0.0 && (a - b).abs() <= 1e-13,
                    "s = {scale}, cell {i}: {a:e} against {b:e}"
                );
                // the row's thin cells also relative to their own mass (measured ≤ 1.2e-4: the
                // integration's rounding on cells ~1e-11 wide)
                if i < 40 {
                    assert!((a - b).abs() <= 1e-3 * b, "s = {scale}, cell {i}: {a:e} against {b:e}");
                }
            }
        }
    }
}
