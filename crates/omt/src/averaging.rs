//! A source measure averaged over a coarser triangulation, for the coarse levels of the
//! coarse-to-fine start.
//!
//! The coarse levels of [`crate::newton`]'s multiscale start solve OT towards a few hundred or
//! thousand merged points; only their solution's cells matter (the prolongation needs nothing
//! but cells and their μ-centroids), and every evaluation integrates the whole source measure.
//! On the conformal image of a face (18.6k triangles) against 1,349 or 337 coarse points, that
//! made the coarse levels about a third of a pair's time. Here the measure is replaced by its
//! average over the Delaunay triangulation T_c of a sample of its own vertices:
//! $$ \bar\rho_T = \frac{\mu(T)}{|T|} = \frac{1}{|T|}\sum_t \rho_t\,|T \cap t|, \qquad T \in T_c, $$
//! so every coarse triangle carries exactly the mass μ gives it, and the averaged measure equals
//! μ on every union of coarse triangles. The sample is every k-th vertex along a Hilbert curve
//! (a stratified sample: the vertices of a conformal image crowd where its density is high, and
//! so does the sample) plus the vertices of the convex hull, so that T_c covers the same Ω.
//!
//! The overlay |T ∩ t| clips each source triangle t by the coarse triangles it meets, found by a
//! visibility walk to t's centroid and a breadth-first search across the coarse edges. The result
//! is a start heuristic only; the finest level always integrates the exact measure. Where the
//! overlay cannot be trusted (areas that do not add up to |t| within 1e-9, a coarse triangle with
//! a non-positive area), `averaged_measure` returns `None` and the caller keeps μ.

use crate::measure::SourceMeasure;
use crate::polygon::convex_hull;
use crate::power_diagram::{hilbert_order, PowerDiagram};
use crate::predicates::orient;

/// No neighbour across a coarse edge (a hull edge; [`PowerDiagram::triangle_neighbors`]).
const NONE: u32 = u32::MAX;

/// The measure averaged over the Delaunay triangulation of about `sample` of its vertices (and
/// its hull vertices), exact per coarse triangle up to rounding; `None` when `sample` is not
/// smaller than the vertex count or the overlay fails its area check.
/// The sample is every ⌈V/sample⌉-th vertex along the curve, so only the sizes V/2, V/3, …
/// occur (the coarse levels' copies, whose sizes need not be exact);
/// [`averaged_measure_evenly`] takes exactly `sample` vertices.
pub fn averaged_measure(measure: &SourceMeasure, sample: usize) -> Option<SourceMeasure> {
    averaged_on_sample(measure, sample, false)
}

/// [`averaged_measure`] on exactly `sample` vertices spread evenly along the Hilbert curve (the
/// k-th at position ⌊kV/sample⌋) plus the hull: a copy of any size, for a source coarsened to
/// a requested number of triangles (about 2·sample plus the hull's vertex count).
pub fn averaged_measure_evenly(measure: &SourceMeasure, sample: usize) -> Option<SourceMeasure> {
    averaged_on_sample(measure, sample, true)
}

/// The stratified sample along a Hilbert curve (strided, or `evenly` spread), then
/// [`averaged_over`] it and the hull.
fn averaged_on_sample(measure: &SourceMeasure, sample: usize, evenly: bool) -> Option<SourceMeasure> {
    let vertices = &measure.vertices;
    let n = vertices.len();
    if sample < 3 || sample >= n {
        return None;
    }
    let along = hilbert_order(vertices);
    let points: Vec<[f64; 2]> = if evenly {
        (0..sample).map(|k| vertices[along[k * n / sample] as usize]).collect()
    } else {
        along
            .iter()
            .step_by(n.div_ceil(sample))
            .map(|&v| vertices[v as usize])
            .collect()
    };
    averaged_over(measure, points)
}

/// The measure averaged over the Delaunay triangulation of `points` and the hull of its
/// vertices (the body of [`averaged_measure`]).
fn averaged_over(measure: &SourceMeasure, mut points: Vec<[f64; 2]>) -> Option<SourceMeasure> {
    let vertices = &measure.vertices;
    points.extend(convex_hull(vertices));
    points.sort_unstable_by(|a, b| a[0].total_cmp(&b[0]).then(a[1].total_cmp(&b[1])));
    points.dedup();
    let delaunay = PowerDiagram::new(&points, &vec![0.0; points.len()]).ok()?;
    let coarse = delaunay.triangles();
    if coarse.is_empty() {
        return None;
    }
    let corners = |c: usize| coarse[c].map(|v| points[v as usize]);
    let areas: Vec<f64> = (0..coarse.len())
        .map(|c| {
            let [a, b, d] = corners(c);
            0.5 * ((b[0] - a[0]) * (d[1] - a[1]) - (b[1] - a[1]) * (d[0] - a[0]))
        })
        .collect();
    if areas.iter().any(|&a| !(a > 0.0)) {
        return None;
    }
    let adjacency = delaunay.triangle_neighbors();
    // Source triangles along a Hilbert curve of their centroids: short walks.
    let centroid = |t: &[u32; 3]| {
        let [a, b, c] = t.map(|v| vertices[v as usize]);
        [(a[0] + b[0] + c[0]) / 3.0, (a[1] + b[1] + c[1]) / 3.0]
    };
    let centroids: Vec<[f64; 2]> = measure.triangles.iter().map(centroid).collect();
    let mut mass = vec![0.0; coarse.len()];
    let mut visited = vec![u32::MAX; coarse.len()];
    let mut queue: Vec<u32> = Vec::new();
    let mut current = 0usize;
    for t in hilbert_order(&centroids) {
        let t = t as usize;
        let tri = measure.triangles[t].map(|v| vertices[v as usize]);
        let p = centroids[t];
        current = walk(&coarse, &points, &adjacency, current, p);
        let area = 0.5
            * ((tri[1][0] - tri[0][0]) * (tri[2][1] - tri[0][1]) - (tri[1][1] - tri[0][1]) * (tri[2][0] - tri[0][0]));
        let density = measure.densities[t];
        let mut covered = 0.0;
        queue.clear();
        queue.push(current as u32);
        visited[current] = t as u32;
        while let Some(c) = queue.pop() {
            let c = c as usize;
            let piece = clipped_area(tri, corners(c), p);
            if piece > 0.0 {
                covered += piece;
                mass[c] += density * piece;
                for &d in &adjacency[c] {
                    if d != NONE && visited[d as usize] != t as u32 {
                        visited[d as usize] = t as u32;
                        queue.push(d);
                    }
                }
            }
        }
        if !((covered - area).abs() <= 1e-9 * area) {
            return None;
        }
    }
    // The average of densities lies between their extremes; clamping guards coarse triangles
    // whose overlay areas lost their relative accuracy (tiny triangles far from the origin).
    let (dmin, dmax) = measure
        .densities
        .iter()
        .fold((f64::INFINITY, 0.0f64), |(a, b), &d| (a.min(d), b.max(d)));
    let densities: Vec<f64> = mass
        .iter()
        .zip(&areas)
        .map(|(m, a)| (m / a).clamp(dmin, dmax))
        .collect();
    SourceMeasure::new(points, coarse, densities).ok()
}

/// Visibility walk from coarse triangle `start` to one containing p (or the hull triangle where
/// p leaves the hull), with the exact orientation predicate; at most one step per triangle.
fn walk(triangles: &[[u32; 3]], points: &[[f64; 2]], adjacency: &[[u32; 3]], start: usize, p: [f64; 2]) -> usize {
    let mut c = start;
    'steps: for _ in 0..triangles.len() {
        let t = triangles[c];
        for k in 0..3 {
            let (a, b) = (points[t[(k + 1) % 3] as usize], points[t[(k + 2) % 3] as usize]);
            let next = adjacency[c][k];
            if next != NONE && orient(a, b, p) < 0 {
                c = next as usize;
                continue 'steps;
            }
        }
        break;
    }
    c
}

/// Area of the source triangle `tri` clipped to the coarse triangle `coarse` (both
/// counter-clockwise), computed in coordinates relative to `origin`.
fn clipped_area(tri: [[f64; 2]; 3], coarse: [[f64; 2]; 3], origin: [f64; 2]) -> f64 {
    let rel = |p: [f64; 2]| [p[0] - origin[0], p[1] - origin[1]];
    // (a cut emits at most m + min(kept, m − kept) vertices even when rounding has made the
    // polygon non-convex: 3 → 4 → 6 → 9, so nine slots always suffice)
    let mut poly = [[0.0; 2]; 9];
    let mut next = [[0.0; 2]; 9];
    let mut len = 3;
    for k in 0..3 {
        poly[k] = rel(tri[k]);
    }
    for k in 0..3 {
        let (a, b) = (rel(coarse[k]), rel(coarse[(k + 1) % 3]));
        let side = |p: [f64; 2]| (b[0] - a[0]) * (p[1] - a[1]) - (b[1] - a[1]) * (p[0] - a[0]);
        let mut m = 0;
        for j in 0..len {
            let (p, q) = (poly[j], poly[(j + 1) % len]);
            let (fp, fq) = (side(p), side(q));
            if fp >= 0.0 {
                next[m] = p;
                m += 1;
            }
            if (fp >= 0.0) != (fq >= 0.0) {
                let s = fp / (fp - fq);
                next[m] = [p[0] + s * (q[0] - p[0]), p[1] + s * (q[1] - p[1])];
                m += 1;
            }
        }
        if m < 3 {
            return 0.0;
        }
        len = m;
        poly[..len].copy_from_slice(&next[..len]);
    }
    let mut area = 0.0;
    for j in 1..len - 1 {
        let (a, b, c) = (poly[0], poly[j], poly[j + 1]);
        area += 0.5 * ((b[0] - a[0]) * (c[1] - a[1]) - (b[1] - a[1]) * (c[0] - a[0]));
    }
    area.max(0.0)
}
