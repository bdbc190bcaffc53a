//! Exact geometric predicates for power diagrams (regular triangulations).
//!
//! Every combinatorial decision of [`crate::power_diagram`] goes through this module. Each
//! predicate first evaluates its determinant in floating point with a forward error bound (a
//! "filter", as in Shewchuk 1997 and Geogram's PCK); when the bound cannot certify the sign it
//! recomputes the determinant exactly with floating-point expansions (Shewchuk, *Adaptive
//! Precision Floating-Point Arithmetic and Fast Robust Geometric Predicates*, 1997). The plain
//! orientation test is `geogram_predicates::orient_2d`.
//!
//! # The power test
//! Sites $p_k$ with power weights $w_k$ lift to $\hat p_k = (p_k, |p_k|^2 - w_k)$. For a
//! counter-clockwise triangle $(a, b, c)$, the point $p$ is *in conflict* with the triangle when
//! $\hat p$ lies strictly below the plane through $\hat a, \hat b, \hat c$, i.e. when
//! $$\det\begin{pmatrix} a - p & |a - p|^2 - (w_a - w_p) \\ b - p & |b - p|^2 - (w_b - w_p) \\
//! c - p & |c - p|^2 - (w_c - w_p)\end{pmatrix} > 0 .$$
//! This is Geogram's `orient_2dlifted` with heights $|p|^2 - w$, written in coordinates relative
//! to $p$ so that no lifted height is ever rounded (the heights $|p|^2 - w$ themselves are not
//! representable in `f64`, and rounding them would destroy the combinatorics of clusters of
//! nearby sites). With $w = 0$ it is the classical in-circle test.
//!
//! # Simulation of simplicity
//! Exact ties (four co-circular sites, a site exactly on the boundary of being hidden) are broken
//! by perturbing every lifted height symbolically, $|p_k|^2 - w_k + \varepsilon^{2^{k}}$ with the
//! site index $k$ as key: the site with the smallest index receives the dominant perturbation
//! (Edelsbrunner & Mücke 1990; Devillers & Teillaud 2011 for regular triangulations). Because it
//! is one consistent perturbation of the input, all predicates (2-D and 1-D) agree with one
//! another and the triangulation built from them is the regular triangulation of the perturbed
//! weights. Orientation of three sites is never perturbed: collinear configurations are handled
//! combinatorially (infinite vertex and [`power_side_1d`]).

use geogram_predicates::Sign;

/// Machine epsilon of f64 (2⁻⁵²); the filters below use generous multiples of it.
const EPS: f64 = f64::EPSILON;

/// Sign of the orientation of (a, b, c): `1` counter-clockwise, `-1` clockwise, `0` collinear.
/// Exact (`geogram_predicates::orient_2d`, behind a Shewchuk-style static filter).
#[inline]
pub fn orient(a: [f64; 2], b: [f64; 2], c: [f64; 2]) -> i8 {
    let l = (b[0] - a[0]) * (c[1] - a[1]);
    let r = (b[1] - a[1]) * (c[0] - a[0]);
    let det = l - r;
    let bound = 4.0 * EPS * (l.abs() + r.abs());
    if det > bound {
        return 1;
    }
    if det < -bound {
        return -1;
    }
    match geogram_predicates::orient_2d(&a, &b, &c) {
        Sign::Positive => 1,
        Sign::Negative => -1,
        Sign::Zero => 0,
    }
}

/// Exact sign of the power-test determinant (see the module docs) for the counter-clockwise
/// triangle (a, b, c) with weights (wa, wb, wc) and the query p with weight wp: `1` when p is in
/// conflict (its lifted point is strictly below the lifted plane of the triangle), `-1` when it is
/// strictly above, `0` exactly on it. No perturbation.
#[allow(clippy::too_many_arguments)] // the four weighted points of the determinant
#[inline]
pub fn power_side_exact_sign(
    a: [f64; 2],
    wa: Weight,
    b: [f64; 2],
    wb: Weight,
    c: [f64; 2],
    wc: Weight,
    p: [f64; 2],
    wp: Weight,
) -> i8 {
    // Floating-point filter.
    let (ax, ay) = (a[0] - p[0], a[1] - p[1]);
    let (bx, by) = (b[0] - p[0], b[1] - p[1]);
    let (cx, cy) = (c[0] - p[0], c[1] - p[1]);
    let ((dwa, ea), (dwb, eb), (dwc, ec)) = (weight_diff(wa, wp), weight_diff(wb, wp), weight_diff(wc, wp));
    let (sa, sb, sc) = (ax * ax + ay * ay, bx * bx + by * by, cx * cx + cy * cy);
    let (az, bz, cz) = (sa - dwa, sb - dwb, sc - dwc);
    let (ma, mb, mc) = (sa + ea, sb + eb, sc + ec);
    let det = ax * (by * cz - bz * cy) + ay * (bz * cx - bx * cz) + az * (bx * cy - by * cx);
    let permanent = ax.abs() * (by.abs() * mc + mb * cy.abs())
        + ay.abs() * (mb * cx.abs() + bx.abs() * mc)
        + ma * (bx.abs() * cy.abs() + by.abs() * cx.abs());
    let bound = 64.0 * EPS * permanent;
    if permanent.is_finite() && permanent > 1e-250 {
        if det > bound {
            return 1;
        }
        if det < -bound {
            return -1;
        }
    }
    power_side_expansion(a, wa, b, wb, c, wc, p, wp)
}

/// The exact evaluation of [`power_side_exact_sign`] with expansions, out of line: the filter
/// decides almost every call.
#[cold]
#[inline(never)]
#[allow(clippy::too_many_arguments)]
fn power_side_expansion(
    a: [f64; 2],
    wa: Weight,
    b: [f64; 2],
    wb: Weight,
    c: [f64; 2],
    wc: Weight,
    p: [f64; 2],
    wp: Weight,
) -> i8 {
    let row = |q: [f64; 2], wq: Weight| -> [Expansion; 3] {
        let x = Expansion::diff(q[0], p[0]);
        let y = Expansion::diff(q[1], p[1]);
        let z = x.mul(&x).add(&y.mul(&y)).sub(&weight_diff_exact(wq, wp));
        [x, y, z]
    };
    let [ax, ay, az] = row(a, wa);
    let [bx, by, bz] = row(b, wb);
    let [cx, cy, cz] = row(c, wc);
    let t1 = ax.mul(&by.mul(&cz).sub(&bz.mul(&cy)));
    let t2 = ay.mul(&bz.mul(&cx).sub(&bx.mul(&cz)));
    let t3 = az.mul(&bx.mul(&cy).sub(&by.mul(&cx)));
    t1.add(&t2).add(&t3).sign()
}

/// Power test with simulation of simplicity: is site `p` (index `kp`) in conflict with the
/// counter-clockwise, non-degenerate triangle of sites `a, b, c` (indices `ka, kb, kc`)?
/// Never ties: exact zeros are resolved by the symbolic perturbation of the module docs.
///
/// Writing the determinant as a function of the perturbations δ_k of the lifted heights, its
/// coefficients are δ_a: orient(p,b,c), δ_b: orient(p,c,a), δ_c: orient(p,a,b),
/// δ_p: −orient(a,b,c) (nonzero), and the smallest key present decides first.
#[allow(clippy::too_many_arguments)]
#[inline]
pub fn power_side_sos(
    a: [f64; 2],
    wa: Weight,
    ka: u32,
    b: [f64; 2],
    wb: Weight,
    kb: u32,
    c: [f64; 2],
    wc: Weight,
    kc: u32,
    p: [f64; 2],
    wp: Weight,
    kp: u32,
) -> bool {
    let s = power_side_exact_sign(a, wa, b, wb, c, wc, p, wp);
    if s != 0 {
        return s > 0;
    }
    let mut keyed = [(ka, 0u8), (kb, 1), (kc, 2), (kp, 3)];
    keyed.sort_unstable();
    for &(_, which) in &keyed {
        let coefficient = match which {
            0 => orient(p, b, c),
            1 => orient(p, c, a),
            2 => orient(p, a, b),
            _ => -orient(a, b, c),
        };
        if coefficient != 0 {
            return coefficient > 0;
        }
    }
    // Unreachable for a non-degenerate triangle (the δ_p coefficient is nonzero); answer "no
    // conflict", the conservative choice.
    false
}

/// One-dimensional power test with simulation of simplicity, for three *collinear* sites: is
/// the lifted point of `p` strictly below the lifted line through â and b̂? (For p between a and
/// b this means p is in conflict with the segment; for p beyond b it means b becomes redundant.)
/// Exact zeros are resolved consistently with [`power_side_sos`] (same perturbation of the
/// lifted heights, smallest key dominant): if p has the smallest key the answer is "no"; if b
/// does, "yes" iff p is on b's side of a; if a does, "yes" iff p is on a's side of b.
#[allow(clippy::too_many_arguments)]
pub fn power_side_1d(
    a: [f64; 2],
    wa: Weight,
    ka: u32,
    b: [f64; 2],
    wb: Weight,
    kb: u32,
    p: [f64; 2],
    wp: Weight,
    kp: u32,
) -> bool {
    // Coordinate along the line: x unless the line is vertical.
    let axis = if a[0] != b[0] { 0 } else { 1 };
    let s = power_side_1d_exact_sign(a, wa, b, wb, p, wp, axis);
    if s != 0 {
        return s < 0;
    }
    let b_side_of_a = (p[axis] > a[axis]) == (b[axis] > a[axis]);
    let a_side_of_b = (p[axis] > b[axis]) == (a[axis] > b[axis]);
    if kp < ka && kp < kb {
        false
    } else if kb < ka {
        b_side_of_a
    } else {
        a_side_of_b
    }
}

/// Sign of V' = sign(u_b)·(u_b ζ_p − u_p ζ_b) where u are coordinates along `axis` relative to
/// `a` and ζ_q = |q − a|² − (w_q − w_a) (lifted heights relative to â, up to a linear function
/// along the line). Negative means p̂ is strictly below the lifted line through â, b̂.
fn power_side_1d_exact_sign(
    a: [f64; 2],
    wa: Weight,
    b: [f64; 2],
    wb: Weight,
    p: [f64; 2],
    wp: Weight,
    axis: usize,
) -> i8 {
    let ub = b[axis] - a[axis];
    let up = p[axis] - a[axis];
    let (bx, by, px, py) = (b[0] - a[0], b[1] - a[1], p[0] - a[0], p[1] - a[1]);
    let ((dwb, eb), (dwp, ep)) = (weight_diff(wb, wa), weight_diff(wp, wa));
    let (sb, sp) = (bx * bx + by * by, px * px + py * py);
    let value = (ub * (sp - dwp) - up * (sb - dwb)) * ub.signum();
    let magnitude = ub.abs() * (sp + ep) + up.abs() * (sb + eb);
    if magnitude.is_finite() && magnitude > 1e-250 {
        let bound = 32.0 * EPS * magnitude;
        if value > bound {
            return 1;
        }
        if value < -bound {
            return -1;
        }
    }
    let ub = Expansion::diff(b[axis], a[axis]);
    let up = Expansion::diff(p[axis], a[axis]);
    let zeta = |q: [f64; 2], wq: Weight| {
        let x = Expansion::diff(q[0], a[0]);
        let y = Expansion::diff(q[1], a[1]);
        x.mul(&x).add(&y.mul(&y)).sub(&weight_diff_exact(wq, wa))
    };
    let v = ub.mul(&zeta(p, wp)).sub(&up.mul(&zeta(b, wb)));
    v.sign() * ub.sign()
}

/// Exact sign of π_i(x) − π_j(x) = (|x − y_i|² − w_i) − (|x − y_j|² − w_j): `-1` when x is
/// strictly closer to site i in the power sense, `1` when strictly closer to j, `0` on the
/// bisector (no perturbation: point location breaks ties by the order of its walk).
pub fn power_compare(x: [f64; 2], yi: [f64; 2], wi: Weight, yj: [f64; 2], wj: Weight) -> i8 {
    let (ax, ay, bx, by) = (x[0] - yi[0], x[1] - yi[1], x[0] - yj[0], x[1] - yj[1]);
    let (dw, ew) = weight_diff(wi, wj);
    let (sa, sb) = (ax * ax + ay * ay, bx * bx + by * by);
    let value = (sa - sb) - dw;
    let magnitude = sa + sb + ew;
    if magnitude.is_finite() && magnitude > 1e-250 {
        let bound = 16.0 * EPS * magnitude;
        if value > bound {
            return 1;
        }
        if value < -bound {
            return -1;
        }
    }
    let (ax, ay) = (Expansion::diff(x[0], yi[0]), Expansion::diff(x[1], yi[1]));
    let (bx, by) = (Expansion::diff(x[0], yj[0]), Expansion::diff(x[1], yj[1]));
    let pa = ax.mul(&ax).add(&ay.mul(&ay));
    let pb = bx.mul(&bx).add(&by.mul(&by));
    pa.sub(&pb).sub(&weight_diff_exact(wi, wj)).sign()
}

/// A power weight in double-double form, `w = w[0] + w[1]` with `|w[1]| ≤ ulp(w[0])/2` (`w[1] = 0` for
/// plain `f64` weights). The solver keeps its heights, hence the weights 2h + |y|², in this form:
/// cells of sites 1e-9 apart must be placed by weight differences below one ulp of the weights
/// themselves (see `newton`).
pub type Weight = [f64; 2];

/// The difference a − b of two weights, rounded (the filters' value), and a bound on its magnitude
/// that also covers the rounding of the low parts (the filters' error terms).
#[inline]
fn weight_diff(a: Weight, b: Weight) -> (f64, f64) {
    let hi = a[0] - b[0];
    let lo = a[1] - b[1];
    (hi + lo, hi.abs() + lo.abs())
}

/// The exact difference a − b of two weights as an expansion.
fn weight_diff_exact(a: Weight, b: Weight) -> Expansion {
    let hi = Expansion::diff(a[0], b[0]);
    if a[1] == 0.0 && b[1] == 0.0 {
        hi
    } else {
        hi.add(&Expansion::diff(a[1], b[1]))
    }
}

/// A nonoverlapping floating-point expansion (Shewchuk 1997): the exact value is the sum of the
/// components, stored in increasing magnitude, zeros eliminated. Exact as long as no intermediate
/// product overflows or underflows (inputs are range-checked by the callers).
#[derive(Clone, Debug)]
pub(crate) struct Expansion(Vec<f64>);

/// Error-free sum: (x, y) with x = fl(a + b) and a + b = x + y exactly (Knuth).
#[inline]
pub(crate) fn two_sum(a: f64, b: f64) -> (f64, f64) {
    let x = a + b;
    let bv = x - a;
    let av = x - bv;
    (x, (a - av) + (b - bv))
}

/// Error-free product: (x, y) with x = fl(a·b) and a·b = x + y exactly (fused multiply-add).
#[inline]
pub(crate) fn two_product(a: f64, b: f64) -> (f64, f64) {
    let x = a * b;
    (x, a.mul_add(b, -x))
}

impl Expansion {
    /// The exact difference a − b as an expansion of at most two components.
    pub(crate) fn diff(a: f64, b: f64) -> Expansion {
        let (x, y) = two_sum(a, -b);
        let mut v = Vec::with_capacity(2);
        if y != 0.0 {
            v.push(y);
        }
        if x != 0.0 {
            v.push(x);
        }
        Expansion(v)
    }

    /// e + b (Shewchuk's GROW-EXPANSION with zero elimination).
    fn grow(&self, b: f64) -> Expansion {
        let mut out = Vec::with_capacity(self.0.len() + 1);
        let mut q = b;
        for &e in &self.0 {
            let (s, h) = two_sum(q, e);
            if h != 0.0 {
                out.push(h);
            }
            q = s;
        }
        if q != 0.0 {
            out.push(q);
        }
        Expansion(out)
    }

    /// Exact sum.
    pub(crate) fn add(&self, other: &Expansion) -> Expansion {
        let (big, small) = if self.0.len() >= other.0.len() {
            (self, other)
        } else {
            (other, self)
        };
        let mut acc = big.clone();
        for &f in &small.0 {
            acc = acc.grow(f);
        }
        acc
    }

    /// Exact difference.
    pub(crate) fn sub(&self, other: &Expansion) -> Expansion {
        let neg = Expansion(other.0.iter().map(|&x| -x).collect());
        self.add(&neg)
    }

    /// Exact product e·b (Shewchuk's SCALE-EXPANSION with zero elimination).
    fn scale(&self, b: f64) -> Expansion {
        let mut out = Vec::with_capacity(2 * self.0.len());
        if self.0.is_empty() || b == 0.0 {
            return Expansion(out);
        }
        let (mut q, h) = two_product(self.0[0], b);
        if h != 0.0 {
            out.push(h);
        }
        for &e in &self.0[1..] {
            let (t1, t0) = two_product(e, b);
            let (s, h) = two_sum(q, t0);
            if h != 0.0 {
                out.push(h);
            }
            let (s2, h2) = two_sum(t1, s);
            if h2 != 0.0 {
                out.push(h2);
            }
            q = s2;
        }
        if q != 0.0 {
            out.push(q);
        }
        Expansion(out)
    }

    /// Exact product.
    pub(crate) fn mul(&self, other: &Expansion) -> Expansion {
        let mut acc = Expansion(Vec::new());
        for &f in &other.0 {
            acc = acc.add(&self.scale(f));
        }
        acc
    }

    /// Sign of the exact value: the sign of the largest (last) component.
    pub(crate) fn sign(&self) -> i8 {
        match self.0.last() {
            Some(&x) if x > 0.0 => 1,
            Some(&x) if x < 0.0 => -1,
            _ => 0,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Small deterministic generator for the tests.
    fn lcg(state: &mut u64) -> u64 {
        *state = state
            .wrapping_mul(6364136223846793005)
            .wrapping_add(1442695040888963407);
        *state >> 33
    }

    /// The exact power test agrees with i128 integer arithmetic on small integer inputs, where the
    /// filter is inconclusive for most cases (many exact zeros).
    #[test]
    fn power_side_matches_integer_arithmetic() {
        let mut s = 7u64;
        let mut zeros = 0;
        for _ in 0..20000 {
            let mut pt = || [(lcg(&mut s) % 7) as i64 - 3, (lcg(&mut s) % 7) as i64 - 3];
            let (a, b, c, p) = (pt(), pt(), pt(), pt());
            let mut w = || (lcg(&mut s) % 5) as i64 - 2;
            let (wa, wb, wc, wp) = (w(), w(), w(), w());
            let row = |q: [i64; 2], wq: i64| {
                let (x, y) = ((q[0] - p[0]) as i128, (q[1] - p[1]) as i128);
                [x, y, x * x + y * y - (wq - wp) as i128]
            };
            let (ra, rb, rc) = (row(a, wa), row(b, wb), row(c, wc));
            let det = ra[0] * (rb[1] * rc[2] - rb[2] * rc[1])
                + ra[1] * (rb[2] * rc[0] - rb[0] * rc[2])
                + ra[2] * (rb[0] * rc[1] - rb[1] * rc[0]);
            // Scale by a power of two: exactness is preserved, the filter sees non-integers.
            let f = |q: [i64; 2]| [q[0] as f64 * 0.125, q[1] as f64 * 0.125];
            let g = |wq: i64| [wq as f64 / 64.0, 0.0];
            let got = power_side_exact_sign(f(a), g(wa), f(b), g(wb), f(c), g(wc), f(p), g(wp));
            assert_eq!(got as i128, det.signum(), "a={a:?} b={b:?} c={c:?} p={p:?}");
            if det == 0 {
                zeros += 1;
            }
        }
        assert!(zeros > 100, "the test must exercise exact ties ({zeros})");
    }

    #[test]
    fn power_compare_exact_on_ties_at_tiny_scale() {
        // x on the bisector of two sites 1e-12 apart near (1, 1): exactly zero.
        let yi = [1.0, 1.0];
        let yj = [1.0 + 2f64.powi(-40), 1.0];
        let x = [1.0 + 2f64.powi(-41), 1.0 + 0.3];
        assert_eq!(power_compare(x, yi, [0.0; 2], yj, [0.0; 2]), 0);
        let x2 = [1.0 + 2f64.powi(-41) + 2f64.powi(-52), 1.3];
        assert_eq!(power_compare(x2, yi, [0.0; 2], yj, [0.0; 2]), 1);
        // Weights shift the bisector: w_i larger wins, also by a low part alone.
        assert_eq!(power_compare(x, yi, [1e-30, 0.0], yj, [0.0; 2]), -1);
        assert_eq!(power_compare(x, yi, [1.0, 1e-30], yj, [1.0, 0.0]), -1);
        assert_eq!(power_compare(x, yi, [1.0, -1e-30], yj, [1.0, 0.0]), 1);
    }

    #[test]
    fn expansion_products_are_exact() {
        // (1 + 2^-60)^2 = 1 + 2^-59 + 2^-120.
        let e = Expansion::diff(1.0, -(2f64.powi(-60)));
        let sq = e.mul(&e);
        let minus = sq.sub(&Expansion::diff(1.0, -(2f64.powi(-59))));
        assert_eq!(minus.0, vec![2f64.powi(-120)]);
    }
}
