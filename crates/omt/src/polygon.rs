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

/// Componentwise minimum and maximum of `points` (([∞, ∞], [−∞, −∞]) when empty).
pub(crate) fn bounding_box(points: &[[f64; 2]]) -> ([f64; 2], [f64; 2]) {
    points
        .iter()
        .fold(([f64::INFINITY; 2], [f64::NEG_INFINITY; 2]), |(lo, hi), p| {
            ([lo[0].min(p[0]), lo[1].min(p[1])], [hi[0].max(p[0]), hi[1].max(p[1])])
        })
}
