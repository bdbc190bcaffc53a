//! Exact predicates on mesh positions, and the one definition of a degenerate face that `info`,
//! `prepare` and the disk maps share.
//!
//! Orientation goes through Shewchuk's adaptive exact `orient2d` [Shewchuk 1997, "Adaptive
//! precision floating-point arithmetic and fast robust geometric predicates"], as
//! `geogram_predicates::orient_2d`. Three points of space are collinear exactly when their
//! projections onto the three coordinate planes all are: the cross product
//! $(q - p) \times (r - p)$ has the three projected orientation determinants as components.

use geogram_predicates::{orient_2d, Sign};

use crate::quantities::{face_edge_lengths, triangle_area_from_lengths};

/// A power of two close to 1/`m` (exact scaling; `m` > 0 and finite).
fn power_of_two_scale(m: f64) -> f64 {
    2f64.powi(-(m.log2().floor() as i32).clamp(-1000, 1000))
}

/// Whether `p`, `q`, `r` are exactly collinear (coincident points included): the exact
/// orientation of each of their three coordinate-plane projections is zero. The points are
/// first scaled by a common power of two (exact) so that the predicate's products neither
/// underflow nor overflow.
pub fn collinear(p: [f64; 3], q: [f64; 3], r: [f64; 3]) -> bool {
    let m = [p, q, r].iter().flatten().fold(0.0f64, |acc, x| acc.max(x.abs()));
    let s = if m > 0.0 && m.is_finite() {
        power_of_two_scale(m)
    } else {
        1.0
    };
    let [p, q, r] = [p, q, r].map(|x| x.map(|c| c * s));
    [(0, 1), (1, 2), (2, 0)]
        .iter()
        .all(|&(i, j)| orient_2d(&[p[i], p[j]], &[q[i], q[j]], &[r[i], r[j]]) == Sign::Zero)
}

/// Why a face with corner positions `p`, `q`, `r` is degenerate, if it is: coincident corners,
/// collinear corners ([`collinear`], exact), or corners so nearly collinear that the area the
/// disk maps compute from the edge lengths ([`face_edge_lengths`],
/// [`triangle_area_from_lengths`]) is zero (the area is below the rounding of the lengths).
/// A face with a repeated vertex index is degenerate too ([`crate::topology::degenerate_faces`]).
pub fn degenerate_corners(p: [f64; 3], q: [f64; 3], r: [f64; 3]) -> Option<&'static str> {
    if p == q || q == r || r == p {
        return Some("coincident corners");
    }
    if collinear(p, q, r) {
        return Some("zero area (collinear corners)");
    }
    let [a, b, c] = face_edge_lengths([p, q, r]);
    if !(triangle_area_from_lengths(a, b, c) > 0.0) {
        return Some("zero area to rounding (nearly collinear corners)");
    }
    None
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn collinear_points_in_space() {
        // exactly on a line in every projection, at several (power-of-two: exact) scales
        for s in [2f64.powi(-130), 2f64.powi(-20), 1.0, 2f64.powi(20), 2f64.powi(130)] {
            let p = [1.0 * s, 2.0 * s, 3.0 * s];
            let q = [3.0 * s, 3.0 * s, 5.0 * s];
            let r = [5.0 * s, 4.0 * s, 7.0 * s];
            assert!(collinear(p, q, r));
            assert!(!collinear(p, q, [5.0 * s, 4.0 * s, 7.5 * s]));
            assert_eq!(degenerate_corners(p, q, r), Some("zero area (collinear corners)"));
        }
        // a plane-parallel triangle is not degenerate
        assert_eq!(
            degenerate_corners([0.0, 0.0, 1.0], [1.0, 0.0, 1.0], [0.0, 1.0, 1.0]),
            None
        );
        assert_eq!(
            degenerate_corners([0.5, 0.0, 0.0], [0.5, 0.0, 0.0], [0.0, 1.0, 0.0]),
            Some("coincident corners")
        );
    }

    /// The centre of the issue-42 fan: the decimal midpoint of two corners, not exactly on
    /// their segment in binary (area ~1e-18), but with a zero area from its edge lengths.
    #[test]
    fn nearly_collinear_corners_whose_length_area_vanishes() {
        let (p, q, r) = ([0.735, 0.45, -0.17], [0.95, 0.01, -0.08], [0.52, 0.89, -0.26]);
        assert!(!collinear(p, q, r));
        assert_eq!(
            degenerate_corners(p, q, r),
            Some("zero area to rounding (nearly collinear corners)")
        );
    }
}
