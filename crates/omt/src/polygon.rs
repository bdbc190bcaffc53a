//! Exact integrals of polygons and the convex hull of points: the planar geometry shared by the
//! measure (its domain) and the restricted integration (its cells).

use crate::predicates::orient;

/// Exact integrals of the (unit-density) convex polygon relative to the site: area, ∫ z, ∫ |z|².
/// (The area, a signed fan sum, is the signed area of any polygon.)
pub(crate) fn polygon_integrals(v: &[[f64; 2]]) -> (f64, [f64; 2], f64) {
    let (mut area, mut m1, mut m2) = (0.0, [0.0; 2], 0.0);
    if v.len() < 3 {
        return (area, m1, m2);
    }
    let a = v[0];
    let aa = a[0] * a[0] + a[1] * a[1];
    for k in 1..v.len() - 1 {
        let (b, c) = (v[k], v[k + 1]);
        let t = 0.5 * ((b[0] - a[0]) * (c[1] - a[1]) - (b[1] - a[1]) * (c[0] - a[0]));
        area += t;
        m1[0] += t * (a[0] + b[0] + c[0]) / 3.0;
        m1[1] += t * (a[1] + b[1] + c[1]) / 3.0;
        let s = aa
            + b[0] * b[0]
            + b[1] * b[1]
            + c[0] * c[0]
            + c[1] * c[1]
            + (a[0] * b[0] + a[1] * b[1])
            + (b[0] * c[0] + b[1] * c[1])
            + (c[0] * a[0] + c[1] * a[1]);
        m2 += t * s / 6.0;
    }
    (area, m1, m2)
}

/// Convex hull (counter-clockwise, no collinear vertices) by Andrew's monotone chain with the
/// exact orientation predicate.
pub(crate) fn convex_hull(points: &[[f64; 2]]) -> Vec<[f64; 2]> {
    let mut p: Vec<[f64; 2]> = points.to_vec();
    p.sort_unstable_by(|a, b| a[0].total_cmp(&b[0]).then(a[1].total_cmp(&b[1])));
    p.dedup();
    if p.len() < 3 {
        return p;
    }
    let mut hull: Vec<[f64; 2]> = Vec::with_capacity(2 * p.len());
    for pass in 0..2 {
        let start = hull.len();
        let iter: Box<dyn Iterator<Item = &[f64; 2]>> = if pass == 0 {
            Box::new(p.iter())
        } else {
            Box::new(p.iter().rev())
        };
        for &q in iter {
            while hull.len() >= start + 2 && orient(hull[hull.len() - 2], hull[hull.len() - 1], q) <= 0 {
                hull.pop();
            }
            hull.push(q);
        }
        hull.pop();
    }
    hull
}

/// A disk inside the counter-clockwise convex polygon `polygon`: its centre, the mean of the
/// vertices, and its radius, the smallest signed distance from that centre to the edges' lines
/// (zero-length edges skipped). The radius is ≤ 0 for a clockwise or degenerate polygon and +∞
/// without edges; each edge's signed distance is 1-Lipschitz, so it is at least the radius
/// minus the distance to the centre.
pub(crate) fn inner_disk(polygon: &[[f64; 2]]) -> ([f64; 2], f64) {
    let m = polygon.len();
    let centre = polygon
        .iter()
        .fold([0.0, 0.0], |c, p| [c[0] + p[0] / m as f64, c[1] + p[1] / m as f64]);
    let mut radius = f64::INFINITY;
    for k in 0..m {
        let (p, q) = (polygon[k], polygon[(k + 1) % m]);
        let e = [q[0] - p[0], q[1] - p[1]];
        let len = e[0].hypot(e[1]);
        if len > 0.0 {
            radius = radius.min((e[0] * (centre[1] - p[1]) - e[1] * (centre[0] - p[0])) / len);
        }
    }
    (centre, radius)
}

/// Componentwise minimum and maximum of `points` (([∞, ∞], [−∞, −∞]) when empty).
pub(crate) fn bounding_box(points: &[[f64; 2]]) -> ([f64; 2], [f64; 2]) {
    points
        .iter()
        .fold(([f64::INFINITY; 2], [f64::NEG_INFINITY; 2]), |(lo, hi), p| {
            ([lo[0].min(p[0]), lo[1].min(p[1])], [hi[0].max(p[0]), hi[1].max(p[1])])
        })
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The unit square's inner disk is its inscribed one. A repeated vertex (a zero-length
    /// edge) is skipped: the centre moves to the mean of the five vertices, (0.6, 0.4), and the
    /// radius is its distance to the nearest side, 0.4, not NaN. Clockwise, the radius is
    /// negative; without edges it is +∞.
    #[test]
    fn inner_disk_of_a_square() {
        let square = [[0.0, 0.0], [1.0, 0.0], [1.0, 1.0], [0.0, 1.0]];
        assert_eq!(inner_disk(&square), ([0.5, 0.5], 0.5));
        let repeated = [[0.0, 0.0], [1.0, 0.0], [1.0, 0.0], [1.0, 1.0], [0.0, 1.0]];
        let (centre, radius) = inner_disk(&repeated);
        assert!(
            (centre[0] - 0.6).abs() < 1e-15 && (centre[1] - 0.4).abs() < 1e-15,
            "{centre:?}"
        );
        assert!((radius - 0.4).abs() < 1e-15, "{radius}");
        let clockwise: Vec<[f64; 2]> = square.iter().rev().copied().collect();
        assert_eq!(inner_disk(&clockwise).1, -0.5);
        assert_eq!(inner_disk(&[]).1, f64::INFINITY);
    }
}
