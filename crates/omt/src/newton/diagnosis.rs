//! The messages of a start without cells and of a stall: where the points crowd beyond double
//! precision, and the nearest-point distances that show it.

use super::*;

/// The end of the crowding diagnoses (no start, stall).
pub(super) const CROWDING: &str =
    "the points are too crowded for double precision (typical of the conformal image of a long \
     protrusion); spread them or use a less distorted embedding";

/// The error message when no start has all cells non-empty: how many cells were empty at the
/// Voronoi start (`empty`, indices), the smallest distance from one of their points to another
/// point, and the likely cause. Points closer than ~1e−9 of Ω's extent get cells whose masses
/// (areas ~ spacing²) and bisector offsets (height differences ~ spacing × cell size) are below
/// what f64 heights of order one resolve: typical of conformal images of long protrusions.
pub(super) fn no_start_diagnosis(
    points: &[[f64; 2]],
    empty: &[usize],
    start: Start,
    lo: [f64; 2],
    hi: [f64; 2],
    scale: f64,
) -> String {
    let extent = (hi[0] - lo[0]).hypot(hi[1] - lo[1]);
    let closest = nearest_other_point(points, empty);
    let cause = if closest < 1e-9 * extent {
        CROWDING
    } else {
        "points far outside the domain?"
    };
    format!(
        "no start with all cells non-empty was found: {} of {} cells are empty at the {} start, and neither \
         the Voronoi start nor contracting the points toward Ω's centroid (down to scale {scale:.1e}) \
         filled them; the nearest other point of one of these is {closest:.2e} away, against Ω's extent \
         {extent:.2e}: {cause}",
        empty.len(),
        points.len(),
        if start == Start::Voronoi {
            "Voronoi"
        } else {
            "given (warm or coarse-to-fine)"
        }
    )
}

/// The smallest distance from a point of `subset` to another point (a sweep over the points
/// sorted by x; for error messages).
pub(super) fn nearest_other_point(points: &[[f64; 2]], subset: &[usize]) -> f64 {
    let mut order: Vec<usize> = (0..points.len()).collect();
    order.sort_by(|&a, &b| points[a][0].total_cmp(&points[b][0]));
    let mut rank = vec![0usize; points.len()];
    for (r, &i) in order.iter().enumerate() {
        rank[i] = r;
    }
    let mut closest = f64::INFINITY;
    for &i in subset {
        let p = points[i];
        let mut best = f64::INFINITY;
        for dir in [-1isize, 1] {
            let mut r = rank[i] as isize + dir;
            while r >= 0 && (r as usize) < order.len() {
                let q = points[order[r as usize]];
                if (q[0] - p[0]).abs() >= best {
                    break;
                }
                best = best.min((q[0] - p[0]).hypot(q[1] - p[1]));
                r += dir;
            }
        }
        closest = closest.min(best);
    }
    closest
}

/// Why a line search found no acceptable step: when the smallest cells belong to points much
/// closer together than Ω's extent, the Newton direction (f64) cannot resolve their heights.
pub(super) fn stall_diagnosis(points: &[[f64; 2]], masses: &[f64], lo: [f64; 2], hi: [f64; 2]) -> String {
    let extent = (hi[0] - lo[0]).hypot(hi[1] - lo[1]);
    let mut smallest: Vec<usize> = (0..points.len()).collect();
    smallest.sort_by(|&a, &b| masses[a].total_cmp(&masses[b]));
    smallest.truncate(64);
    let closest = nearest_other_point(points, &smallest);
    if closest < 1e-12 * extent {
        format!(
            "; the smallest cells belong to points {closest:.2e} from another point, against Ω's extent \
             {extent:.2e}: {CROWDING}"
        )
    } else {
        String::new()
    }
}
