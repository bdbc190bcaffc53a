//! Brute-force oracle for restricted power-cell integrals: **for tests only**.
//!
//! For a site $y_i$ with power weight $w_i$ the power cell is
//! $$W_i = \{x : |x - y_i|^2 - w_i \le |x - y_j|^2 - w_j \ \forall j \ne i\},$$
//! an intersection of $N - 1$ half-planes. In coordinates $z = x - y_i$ relative to the site, and
//! with $d = y_j - y_i$, the constraint from site $j$ reads
//! $$\langle z, d\rangle \le \tfrac12\,(|d|^2 + w_i - w_j).$$
//! The oracle clips a box around the domain by all $N - 1$ half-planes (Sutherland–Hodgman on
//! convex polygons, every edge labelled by the constraint that produced it), then clips every
//! source triangle whose bounding box meets the cell by the cell's edges, and integrates the
//! pieces exactly (`docs/conventions.md`, "Transport cost and exact integrals"): for a triangle $(a, b, c)$ of area $A$,
//! $\int x = A(a+b+c)/3$ and $\int |x|^2 = A(|a|^2+|b|^2+|c|^2+a\cdot b+b\cdot c+c\cdot a)/6$.
//!
//! Cost $O(N^2 + N M)$ per call with $N$ sites and $M$ source triangles (plus the clipping work):
//! use it only for $N \lesssim 2000$. It shares no code with the fast path (`restricted`), uses
//! no exact predicates (a site whose cell is degenerate to a point or a segment is reported
//! with zero mass either way) and is meant to be read, not to be fast.

use crate::cells::CellIntegrals;
use crate::measure::SourceMeasure;

/// Label of a polygon edge that does not come from a power constraint (a box or triangle edge).
const NO_SITE: u32 = u32::MAX;

/// A convex polygon as vertices (counter-clockwise) and, for each vertex k, the label of the edge
/// from vertex k to vertex k+1.
#[derive(Clone, Debug, Default)]
struct LabelledPolygon {
    vertices: Vec<[f64; 2]>,
    labels: Vec<u32>,
}

impl LabelledPolygon {
    /// Keeps the part where ⟨z, normal⟩ ≤ offset; new edges get `label`.
    fn clip(&self, normal: [f64; 2], offset: f64, label: u32) -> LabelledPolygon {
        let n = self.vertices.len();
        let mut out = LabelledPolygon {
            vertices: Vec::with_capacity(n + 1),
            labels: Vec::with_capacity(n + 1),
        };
        if n == 0 {
            return out;
        }
        let f = |p: [f64; 2]| p[0] * normal[0] + p[1] * normal[1] - offset;
        let values: Vec<f64> = self.vertices.iter().map(|&p| f(p)).collect();
        if values.iter().all(|&v| v <= 0.0) {
            return self.clone();
        }
        for k in 0..n {
            let (p, q) = (self.vertices[k], self.vertices[(k + 1) % n]);
            let (fp, fq) = (values[k], values[(k + 1) % n]);
            let l = self.labels[k];
            let crossing = |fp: f64, fq: f64| {
                let t = fp / (fp - fq);
                [p[0] + t * (q[0] - p[0]), p[1] + t * (q[1] - p[1])]
            };
            if fp <= 0.0 {
                if fq <= 0.0 {
                    out.vertices.push(p);
                    out.labels.push(l);
                } else if fp < 0.0 {
                    out.vertices.push(p);
                    out.labels.push(l);
                    out.vertices.push(crossing(fp, fq));
                    out.labels.push(label);
                } else {
                    // p on the line, q outside: the edge leaving p runs along the clip line.
                    out.vertices.push(p);
                    out.labels.push(label);
                }
            } else if fq < 0.0 {
                out.vertices.push(crossing(fp, fq));
                out.labels.push(l);
            }
        }
        if out.vertices.len() < 3 {
            out.vertices.clear();
            out.labels.clear();
        }
        out
    }

    fn bounding_box(&self) -> ([f64; 2], [f64; 2]) {
        crate::polygon::bounding_box(&self.vertices)
    }
}

/// Area, ∫ z dA and ∫ |z|² dA of a convex polygon (fan from its first vertex).
fn polygon_moments(p: &[[f64; 2]]) -> (f64, [f64; 2], f64) {
    let (mut area, mut first, mut second) = (0.0, [0.0, 0.0], 0.0);
    if p.len() < 3 {
        return (area, first, second);
    }
    let a = p[0];
    for k in 1..p.len() - 1 {
        let (b, c) = (p[k], p[k + 1]);
        let t = 0.5 * ((b[0] - a[0]) * (c[1] - a[1]) - (b[1] - a[1]) * (c[0] - a[0]));
        let dot = |u: [f64; 2], v: [f64; 2]| u[0] * v[0] + u[1] * v[1];
        area += t;
        first[0] += t * (a[0] + b[0] + c[0]) / 3.0;
        first[1] += t * (a[1] + b[1] + c[1]) / 3.0;
        second += t * (dot(a, a) + dot(b, b) + dot(c, c) + dot(a, b) + dot(b, c) + dot(c, a)) / 6.0;
    }
    (area, first, second)
}

/// The power cell of site `i` clipped to an axis-aligned box (relative coordinates z = x − y_i),
/// edges labelled by the site j of their constraint or `NO_SITE` for box edges.
fn power_cell_in_box(sites: &[[f64; 2]], weights: &[f64], i: usize, lo: [f64; 2], hi: [f64; 2]) -> LabelledPolygon {
    let y = sites[i];
    let mut cell = LabelledPolygon {
        vertices: vec![
            [lo[0] - y[0], lo[1] - y[1]],
            [hi[0] - y[0], lo[1] - y[1]],
            [hi[0] - y[0], hi[1] - y[1]],
            [lo[0] - y[0], hi[1] - y[1]],
        ],
        labels: vec![NO_SITE; 4],
    };
    for j in 0..sites.len() {
        if j == i {
            continue;
        }
        let d = [sites[j][0] - y[0], sites[j][1] - y[1]];
        let offset = 0.5 * (d[0] * d[0] + d[1] * d[1] + weights[i] - weights[j]);
        cell = cell.clip(d, offset, j as u32);
        if cell.vertices.is_empty() {
            break;
        }
    }
    cell
}

/// Bounding box of the source domain, enlarged by 1% of its diagonal (plus a tiny absolute margin).
fn domain_box(measure: &SourceMeasure) -> ([f64; 2], [f64; 2]) {
    let (lo, hi) = crate::polygon::bounding_box(&measure.vertices);
    let margin = 0.01 * ((hi[0] - lo[0]).hypot(hi[1] - lo[1])) + 1e-300;
    ([lo[0] - margin, lo[1] - margin], [hi[0] + margin, hi[1] + margin])
}

/// The pieces W_i ∩ t of one cell with the source triangles t, with their densities, in relative
/// coordinates.
fn cell_pieces(measure: &SourceMeasure, site: [f64; 2], cell: &LabelledPolygon) -> Vec<(LabelledPolygon, f64)> {
    let mut pieces = Vec::new();
    if cell.vertices.is_empty() {
        return pieces;
    }
    let (clo, chi) = cell.bounding_box();
    let n = cell.vertices.len();
    for (tri, &density) in measure.triangles.iter().zip(&measure.densities) {
        let v = tri.map(|k| {
            let p = measure.vertices[k as usize];
            [p[0] - site[0], p[1] - site[1]]
        });
        let tlo = [v[0][0].min(v[1][0]).min(v[2][0]), v[0][1].min(v[1][1]).min(v[2][1])];
        let thi = [v[0][0].max(v[1][0]).max(v[2][0]), v[0][1].max(v[1][1]).max(v[2][1])];
        if tlo[0] > chi[0] || tlo[1] > chi[1] || thi[0] < clo[0] || thi[1] < clo[1] {
            continue;
        }
        let mut piece = LabelledPolygon {
            vertices: v.to_vec(),
            labels: vec![NO_SITE; 3],
        };
        for k in 0..n {
            let label = cell.labels[k];
            if label == NO_SITE {
                continue;
            }
            let (p, q) = (cell.vertices[k], cell.vertices[(k + 1) % n]);
            // Outward normal of a counter-clockwise edge p→q is (q − p) rotated by −90°.
            let normal = [q[1] - p[1], p[0] - q[0]];
            let offset = normal[0] * p[0] + normal[1] * p[1];
            piece = piece.clip(normal, offset, label);
            if piece.vertices.is_empty() {
                break;
            }
        }
        if !piece.vertices.is_empty() {
            pieces.push((piece, density));
        }
    }
    pieces
}

/// Restricted power-cell integrals by brute force (the test oracle of `restricted::integrate_cells`).
///
/// `sites` (#N), `weights` (#N, power weights w_i: power distance |x − y_i|² − w_i; heights h
/// relate by w_i = 2h_i + |y_i|²), `measure` (#M triangles). Returns masses, first moments
/// ∫ x dμ, second moments ∫ |x − y_i|² dμ and, for each pair i < j of cells sharing an edge of
/// positive μ-length, (i, j, ∫_{e_ij ∩ Ω} μ ds). Edge masses are taken from the side of the
/// smaller index i. Cost O(N² + N·M): tests only, N ≲ 2000. Inputs are not validated (callers
/// pass equal lengths and finite values).
pub fn integrate_cells_bruteforce(sites: &[[f64; 2]], weights: &[f64], measure: &SourceMeasure) -> CellIntegrals {
    let n = sites.len();
    let (lo, hi) = domain_box(measure);
    let mut out = CellIntegrals {
        masses: vec![0.0; n],
        first_moments: vec![[0.0; 2]; n],
        second_moments: vec![0.0; n],
        edge_masses: Vec::new(),
    };
    for i in 0..n {
        let y = sites[i];
        let cell = power_cell_in_box(sites, weights, i, lo, hi);
        let mut edge_sums: Vec<(u32, f64)> = Vec::new();
        for (piece, density) in cell_pieces(measure, y, &cell) {
            let (area, first, second) = polygon_moments(&piece.vertices);
            out.masses[i] += density * area;
            out.first_moments[i][0] += density * (first[0] + area * y[0]);
            out.first_moments[i][1] += density * (first[1] + area * y[1]);
            out.second_moments[i] += density * second;
            let m = piece.vertices.len();
            for k in 0..m {
                let j = piece.labels[k];
                if j == NO_SITE || (j as usize) < i {
                    continue;
                }
                let (p, q) = (piece.vertices[k], piece.vertices[(k + 1) % m]);
                let length = (q[0] - p[0]).hypot(q[1] - p[1]);
                match edge_sums.iter_mut().find(|e| e.0 == j) {
                    Some(e) => e.1 += density * length,
                    None => edge_sums.push((j, density * length)),
                }
            }
        }
        edge_sums.sort_by_key(|e| e.0);
        out.edge_masses.extend(
            edge_sums
                .into_iter()
                .filter(|e| e.1 > 0.0)
                .map(|(j, m)| (i as u32, j, m)),
        );
    }
    out
}

/// The restricted cells W_i ∩ Ω as polygons in absolute coordinates (counter-clockwise), #N;
/// an empty vector for an empty cell. Ω is the union of the source triangles (convex), so the
/// cell is the cell clipped by the domain's convex hull. Brute force, O(N² + N·M): tests only.
pub fn cell_polygons_bruteforce(sites: &[[f64; 2]], weights: &[f64], measure: &SourceMeasure) -> Vec<Vec<[f64; 2]>> {
    let (lo, hi) = domain_box(measure);
    let hull = measure.domain_hull();
    (0..sites.len())
        .map(|i| {
            let y = sites[i];
            let mut cell = power_cell_in_box(sites, weights, i, lo, hi);
            let h = hull.len();
            for k in 0..h {
                if cell.vertices.is_empty() {
                    break;
                }
                let p = [hull[k][0] - y[0], hull[k][1] - y[1]];
                let q = [hull[(k + 1) % h][0] - y[0], hull[(k + 1) % h][1] - y[1]];
                let normal = [q[1] - p[1], p[0] - q[0]];
                cell = cell.clip(normal, normal[0] * p[0] + normal[1] * p[1], NO_SITE);
            }
            cell.vertices.iter().map(|z| [z[0] + y[0], z[1] + y[1]]).collect()
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn two_sites_split_the_unit_square_in_half() {
        let measure = SourceMeasure::unit_square().unwrap();
        let sites = [[0.25, 0.5], [0.75, 0.5]];
        let c = integrate_cells_bruteforce(&sites, &[0.0, 0.0], &measure);
        assert!((c.masses[0] - 0.5).abs() < 1e-14 && (c.masses[1] - 0.5).abs() < 1e-14);
        // Centroid of [0, 1/2] × [0, 1] is (1/4, 1/2).
        assert!((c.first_moments[0][0] / 0.5 - 0.25).abs() < 1e-14);
        assert!((c.first_moments[0][1] / 0.5 - 0.5).abs() < 1e-14);
        // ∫ over a 1/2 × 1 box of |x − center|² = area·(a² + b²)/12 with a = 1/2, b = 1.
        let expected = 0.5 * (0.25 + 1.0) / 12.0;
        assert!((c.second_moments[0] - expected).abs() < 1e-14);
        assert_eq!(c.edge_masses.len(), 1);
        let (i, j, m) = c.edge_masses[0];
        assert_eq!((i, j), (0, 1));
        assert!((m - 1.0).abs() < 1e-14);
    }

    #[test]
    fn weights_move_the_bisector() {
        // w_0 − w_1 = 0.2 moves the boundary: 2⟨z, d⟩ ≤ |d|² + 0.2 with d = (0.5, 0), z = x − y_0,
        // so z_x ≤ (0.25 + 0.2) / (2·0.5) = 0.45, i.e. x ≤ 0.7.
        let measure = SourceMeasure::unit_square().unwrap();
        let sites = [[0.25, 0.5], [0.75, 0.5]];
        let c = integrate_cells_bruteforce(&sites, &[0.2, 0.0], &measure);
        assert!((c.masses[0] - 0.7).abs() < 1e-14, "{}", c.masses[0]);
        assert!((c.masses[1] - 0.3).abs() < 1e-14);
        let polys = cell_polygons_bruteforce(&sites, &[0.2, 0.0], &measure);
        assert!(polys[0].iter().any(|p| (p[0] - 0.7).abs() < 1e-14));
    }

    #[test]
    fn hidden_site_has_zero_mass_and_grid_is_exact() {
        let measure = SourceMeasure::unit_square().unwrap();
        let k = 4;
        let mut sites = Vec::new();
        for a in 0..k {
            for b in 0..k {
                sites.push([(a as f64 + 0.5) / k as f64, (b as f64 + 0.5) / k as f64]);
            }
        }
        let mut weights = vec![0.0; k * k];
        let c = integrate_cells_bruteforce(&sites, &weights, &measure);
        let side = 1.0 / k as f64;
        for i in 0..k * k {
            assert!((c.masses[i] - side * side).abs() < 1e-15);
            assert!((c.second_moments[i] - side.powi(4) / 6.0).abs() < 1e-16);
        }
        // 2k(k−1) interior edges of length 1/k each.
        assert_eq!(c.edge_masses.len(), 2 * k * (k - 1));
        assert!(c.edge_masses.iter().all(|e| (e.2 - side).abs() < 1e-15));
        weights[5] = -1.0;
        let c = integrate_cells_bruteforce(&sites, &weights, &measure);
        assert_eq!(c.masses[5], 0.0);
        let total: f64 = c.masses.iter().sum();
        assert!((total - 1.0).abs() < 1e-14);
        assert!(c.edge_masses.iter().all(|e| e.0 != 5 && e.1 != 5));
    }
}
