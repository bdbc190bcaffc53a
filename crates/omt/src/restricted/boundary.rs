//! Boundary (Green's theorem) form of the restricted-cell integrals: the fast path of
//! [`RestrictedIntegrator::integrate`](super::RestrictedIntegrator::integrate).
//!
//! For a piece W_i ∩ t (a convex polygon Π, in coordinates z = x − y_i relative to the site) and
//! any ordering of its boundary into directed segments P → Q (counter-clockwise around Π),
//! Green's theorem gives the integrals as sums over the triangles (0, P, Q) fanned from the
//! site, whatever their sign:
//! $$ |Π| = \sum \tfrac12 P \times Q, \quad ∫_Π z = \sum \tfrac12 (P \times Q)\,\tfrac{P + Q}{3},
//! \quad ∫_Π |z|^2 = \sum \tfrac12 (P \times Q)\,\tfrac{|P|^2 + P\cdot Q + |Q|^2}{6}. $$
//! The boundary of Π consists of (a) the parts of the power edges of W_i inside t and (b) arcs of
//! ∂t inside W_i. So instead of clipping t by all ~6.5 half-planes of every cell meeting it
//! (Sutherland–Hodgman, ~20 vertex evaluations and the line set-ups per piece), each cell meeting
//! t clips the *edges* of its power polygon — computed once per diagram, [`CellPolygons`] — by
//! t's three lines (Liang–Barsky), and the arcs of ∂t between the points where the polygon leaves
//! and re-enters t close each piece: after sorting the crossings along ∂t counter-clockwise, each
//! exit of ∂W_i from t is followed by the next entry (at an exit point ∂t enters W_i). The cells
//! meeting t are found as in the clipping path: a walk from the cell containing t's centroid
//! across the power edges that have a part inside t (the pieces of t tile it, so their adjacency
//! graph is connected).
//!
//! Every point is computed relative to its own site and from the two lines that meet there (a
//! power line and a triangle line with its offset in compensated arithmetic, the same call on
//! both sides of a crossing), so each piece's boundary closes exactly and tiny cells keep their
//! relative accuracy, as in the clipping path.
//!
//! The boundary form decides combinatorics with floating-point signs, so it declines any triangle
//! where a decision is close: a power vertex within 1e-12 (relative) of a line of t, a crossing
//! within 1e-10 of a corner of t or of another crossing, nearly parallel lines, a piece without
//! positive area, or areas that do not add up to |t| within 1e-9. Such triangles (a power edge
//! along a source edge, a power vertex on one, crowded cells) go through the clipping path, whose
//! rules for those cases (mean density on a density jump, zero-width pieces dropped) then apply.
//! Both paths give the same integrals up to rounding.

use rayon::prelude::*;

use super::{
    edge_offset, power_line_between, ChunkResult, Line, Piece, RestrictedIntegrator, Scratch, NO_LABEL, NO_SEED,
};
use crate::power_diagram::PowerDiagram;
use crate::predicates::orient;

/// A value of a line's equation this close to zero (relative to the magnitude of its terms)
/// counts as "on the line": the triangle goes through the clipping path.
const ON_LINE: f64 = 1e-12;

/// Parameters along an edge closer than this are a tie (a crossing at a corner of t, two
/// crossings at one point): the triangle goes through the clipping path.
const TIE: f64 = 1e-10;

/// The power cells of one diagram as convex polygons relative to their sites: vertex k and the
/// line of the edge from vertex k to vertex k + 1 (labelled by the neighbour's slot in the
/// diagram's neighbour list; `NO_LABEL` for edges of the bounding frame of unbounded cells).
pub(super) struct CellPolygons {
    offsets: Vec<u32>,
    vertices: Vec<[f64; 2]>,
    lines: Vec<Line>,
    /// Per cell, the largest vertex coordinate in absolute value (relative to the site): scales
    /// the "on the line" test.
    extents: Vec<f64>,
}

/// Intersection of two lines, None when they are nearly parallel (same threshold as the clipping
/// path's `intersect`).
#[inline]
fn meet(l: &Line, h: &Line) -> Option<[f64; 2]> {
    let det = l.n[0] * h.n[1] - l.n[1] * h.n[0];
    let scale = (l.n[0].abs() + l.n[1].abs()) * (h.n[0].abs() + h.n[1].abs());
    if det.abs() > 1e-6 * scale {
        Some([(l.c * h.n[1] - h.c * l.n[1]) / det, (l.n[0] * h.c - h.n[0] * l.c) / det])
    } else {
        None
    }
}

/// The power line of neighbour slot `slot` of cell i, relative to y_i (as in `clip_to_cell`).
#[inline]
fn power_line(diagram: &PowerDiagram, i: usize, slot: usize) -> Line {
    let (n, c) = power_line_between(diagram, i, diagram.neighbor_list()[slot] as usize);
    Line {
        n,
        c,
        label: slot as u32,
    }
}

impl CellPolygons {
    /// Polygons of every cell of a two-dimensional diagram. A bounded cell's vertices are the
    /// intersections of consecutive neighbours' lines (its neighbours are listed
    /// counter-clockwise, and consecutive ones form triangles of the regular triangulation);
    /// unbounded cells, and cells with nearly parallel consecutive lines, are the frame polygon
    /// (a box around Ω) clipped by their lines.
    pub(super) fn new(diagram: &PowerDiagram, frame: &[[f64; 2]]) -> Self {
        let n = diagram.num_sites();
        let chunk = n.div_ceil(64).max(1);
        // per chunk: polygon sizes, vertices, edge lines
        type Part = (Vec<u32>, Vec<[f64; 2]>, Vec<Line>);
        let parts: Vec<Part> = (0..n.div_ceil(chunk))
            .into_par_iter()
            .map_init(
                || Scratch::new(0),
                |s, c| {
                    let (mut lens, mut vertices, mut lines) = (Vec::new(), Vec::new(), Vec::new());
                    for i in c * chunk..((c + 1) * chunk).min(n) {
                        let before = vertices.len();
                        if !diagram.is_hidden(i) && !Self::bounded_cell(diagram, i, &mut vertices, &mut lines) {
                            vertices.truncate(before);
                            lines.truncate(before);
                            if RestrictedIntegrator::clip_to_cell(diagram, i, frame, s) {
                                vertices.extend_from_slice(s.a.vertices());
                                lines.extend_from_slice(&s.a.lines[..s.a.len]);
                            }
                        }
                        lens.push((vertices.len() - before) as u32);
                    }
                    (lens, vertices, lines)
                },
            )
            .collect();
        let mut offsets = Vec::with_capacity(n + 1);
        offsets.push(0u32);
        let mut extents = Vec::with_capacity(n);
        let total: usize = parts.iter().map(|p| p.1.len()).sum();
        let (mut vertices, mut lines) = (Vec::with_capacity(total), Vec::with_capacity(total));
        for (lens, v, l) in parts {
            let mut start = 0;
            for len in lens {
                offsets.push(offsets.last().unwrap() + len);
                let cell = &v[start..start + len as usize];
                extents.push(cell.iter().fold(0.0f64, |r, p| r.max(p[0].abs()).max(p[1].abs())));
                start += len as usize;
            }
            vertices.extend(v);
            lines.extend(l);
        }
        CellPolygons {
            offsets,
            vertices,
            lines,
            extents,
        }
    }

    /// Appends the polygon of cell i from its neighbours' lines; false (with partial output) when
    /// the cell is unbounded or two consecutive lines are nearly parallel.
    fn bounded_cell(diagram: &PowerDiagram, i: usize, vertices: &mut Vec<[f64; 2]>, lines: &mut Vec<Line>) -> bool {
        let offsets = diagram.neighbor_offsets();
        let list = diagram.neighbor_list();
        let sites = diagram.sites();
        let (start, end) = (offsets[i] as usize, offsets[i + 1] as usize);
        if end - start < 3 {
            return false;
        }
        let y = sites[i];
        let mut previous = power_line(diagram, i, end - 1);
        let mut previous_site = sites[list[end - 1] as usize];
        for slot in start..end {
            let next_site = sites[list[slot] as usize];
            if orient(y, previous_site, next_site) <= 0 {
                return false;
            }
            let line = power_line(diagram, i, slot);
            let Some(v) = meet(&previous, &line) else {
                return false;
            };
            // Vertex between the previous neighbour's edge and this one's: the edge that starts
            // here lies on this neighbour's line.
            vertices.push(v);
            lines.push(line);
            previous = line;
            previous_site = next_site;
        }
        true
    }

    #[inline]
    fn cell(&self, i: usize) -> (&[[f64; 2]], &[Line], f64) {
        let (a, b) = (self.offsets[i] as usize, self.offsets[i + 1] as usize);
        (&self.vertices[a..b], &self.lines[a..b], self.extents[i])
    }
}

/// Where the boundary of a cell crosses ∂t: edge m of t, position along it (0 at corner m, 1 at
/// corner m + 1), the point relative to the site, and whether ∂W_i enters t there.
#[derive(Clone, Copy, Debug)]
pub(super) struct Crossing {
    edge: usize,
    position: f64,
    point: [f64; 2],
    entry: bool,
}

/// Largest cell polygon the boundary form takes (more vertices: the clipping path). Cells of
/// face pairs have ~6.5.
const MAX_VERTICES: usize = 64;

/// Per-worker buffers of the boundary form (fixed size: no bounds growth in the inner loops).
pub(super) struct BoundaryScratch {
    values: [[f64; 3]; MAX_VERTICES],
    crossings: [Crossing; 2 * MAX_VERTICES],
}

impl Default for BoundaryScratch {
    fn default() -> Self {
        let none = Crossing {
            edge: 0,
            position: 0.0,
            point: [0.0; 2],
            entry: false,
        };
        BoundaryScratch {
            values: [[0.0; 3]; MAX_VERTICES],
            crossings: [none; 2 * MAX_VERTICES],
        }
    }
}

/// Running integrals of one piece: area, ∫ z, ∫ |z|² (unit density, relative to the site).
#[derive(Default)]
struct Sums {
    area: f64,
    first: [f64; 2],
    second: f64,
}

impl Sums {
    /// Adds the signed triangle (0, p, q).
    /// Sums of 2·area, 2·area·(p + q) and 2·area·(|p|² + p·q + |q|²); [`Self::finish`] scales.
    #[inline]
    fn fan(&mut self, p: [f64; 2], q: [f64; 2]) {
        let a = p[0] * q[1] - p[1] * q[0];
        self.area += a;
        self.first[0] += a * (p[0] + q[0]);
        self.first[1] += a * (p[1] + q[1]);
        self.second += a * ((p[0] * p[0] + p[1] * p[1]) + (p[0] * q[0] + p[1] * q[1]) + (q[0] * q[0] + q[1] * q[1]));
    }

    /// Area, ∫ z and ∫ |z|² from the sums of [`Self::fan`].
    fn finish(&self) -> (f64, [f64; 2], f64) {
        (
            0.5 * self.area,
            [self.first[0] / 6.0, self.first[1] / 6.0],
            self.second / 12.0,
        )
    }
}

/// The triangle's data shared by its pieces: corners (absolute, counter-clockwise) and density.
struct Triangle {
    corners: [[f64; 2]; 3],
    density: f64,
}

/// The next corner (or edge) of a triangle, counter-clockwise.
const NEXT: [usize; 3] = [1, 2, 0];

/// A close decision: the triangle must go through the clipping path.
struct Declined;

impl RestrictedIntegrator {
    /// All pieces of source triangle t by the boundary form (module docs). Returns false, with
    /// `out` unchanged, when the triangle must go through the clipping path instead.
    pub(super) fn integrate_triangle_boundary(
        &self,
        diagram: &PowerDiagram,
        polygons: &CellPolygons,
        t: usize,
        s: &mut Scratch,
        out: &mut ChunkResult,
    ) -> bool {
        let (pieces_before, edges_before) = (out.pieces.len(), out.edges.len());
        s.stamp = s.stamp.wrapping_add(1);
        if s.stamp == 0 {
            s.visited.iter_mut().for_each(|v| *v = 0);
            s.stamp = 1;
        }
        s.queue.clear();
        let triangle = Triangle {
            corners: self.triangles[t].map(|v| self.vertices[v as usize]),
            density: self.densities[t],
        };
        let c = triangle.corners;
        let centroid = [(c[0][0] + c[1][0] + c[2][0]) / 3.0, (c[0][1] + c[1][1] + c[2][1]) / 3.0];
        let n = diagram.num_sites();
        // The walk starts from the cell of t's largest piece at the last integration, or, when
        // there is none or it no longer meets t, from the cell containing t's centroid.
        let seed = self.seeds[t].load(std::sync::atomic::Ordering::Relaxed) as usize;
        let seeded = seed != NO_SEED as usize && seed < n && !diagram.is_hidden(seed);
        let mut first = if seeded { seed } else { diagram.locate(centroid, s.hint) };
        let mut located = !seeded;
        let mut covered = 0.0;
        let mut ok = true;
        'walk: loop {
            s.visited[first] = s.stamp;
            s.queue.push(first as u32);
            let mut is_first = true;
            while let Some(i) = s.queue.pop() {
                match self.boundary_piece(diagram, polygons, i as usize, &triangle, is_first, s, out) {
                    Ok(Some(area)) => covered += area,
                    Ok(None) if !located => {
                        // The remembered cell misses t now: locate and walk again.
                        first = diagram.locate(centroid, Some(first));
                        located = true;
                        s.stamp = s.stamp.wrapping_add(1);
                        if s.stamp == 0 {
                            s.visited.iter_mut().for_each(|v| *v = 0);
                            s.stamp = 1;
                        }
                        continue 'walk;
                    }
                    Ok(None) | Err(Declined) => {
                        ok = false;
                        break 'walk;
                    }
                }
                is_first = false;
            }
            break;
        }
        let area = self.triangle_areas[t];
        if !ok || !((covered - area).abs() <= 1e-9 * area) {
            out.pieces.truncate(pieces_before);
            out.edges.truncate(edges_before);
            return false;
        }
        // (No sort of the pieces by cell: each cell has at most one piece per triangle, so the
        // per-cell sums do not depend on the walk's order.)
        let pieces = &out.pieces[pieces_before..];
        if let Some(largest) = pieces.iter().max_by(|a, b| a.area.total_cmp(&b.area)) {
            self.seeds[t].store(largest.cell, std::sync::atomic::Ordering::Relaxed);
            s.hint = Some(largest.cell as usize);
        }
        true
    }

    /// The piece W_i ∩ t: clips the edges of cell i's polygon to t, closes the piece with the
    /// arcs of ∂t inside the cell, records the piece and its edge masses, and queues the
    /// neighbours across its power edges. Returns the piece's area, or None when cell i (the
    /// walk's first cell) does not meet t.
    #[allow(clippy::too_many_arguments)]
    fn boundary_piece(
        &self,
        diagram: &PowerDiagram,
        polygons: &CellPolygons,
        i: usize,
        triangle: &Triangle,
        is_first: bool,
        s: &mut Scratch,
        out: &mut ChunkResult,
    ) -> Result<Option<f64>, Declined> {
        let y = diagram.sites()[i];
        let c = triangle.corners;
        // t's corners and edge lines relative to y_i (offsets in compensated arithmetic).
        let corners = c.map(|p| [p[0] - y[0], p[1] - y[1]]);
        let (vertices, lines, extent) = polygons.cell(i);
        // The offsets c = n·(p − y) in plain arithmetic are accurate to ~3ε|n| max|p − y|, i.e.
        // to 2e-14 of the cell's size when t's corners are within 64 cell sizes of the site;
        // farther (a tiny cell in a large triangle) they are compensated as in the clipping path.
        let reach = corners.iter().fold(0.0f64, |r, p| r.max(p[0].abs()).max(p[1].abs()));
        let compensated = reach > 64.0 * extent;
        let tri_lines: [Line; 3] = std::array::from_fn(|m| {
            let (p, q) = (c[m], c[NEXT[m]]);
            let n = [q[1] - p[1], p[0] - q[0]];
            let a = corners[m];
            Line {
                n,
                c: if compensated {
                    edge_offset(p, q, y)
                } else {
                    n[0] * a[0] + n[1] * a[1]
                },
                label: NO_LABEL,
            }
        });
        let len = vertices.len();
        if !(3..=MAX_VERTICES).contains(&len) {
            return Err(Declined);
        }
        // |n·v − c| below ON_LINE × (|n₀| + |n₁|) max|v| + |c| (a bound on the terms) counts as
        // on the line.
        let on_line = tri_lines.map(|l| ON_LINE * ((l.n[0].abs() + l.n[1].abs()) * extent + l.c.abs()));
        let b = &mut *s.boundary;
        for (v, slot) in vertices.iter().zip(&mut b.values) {
            let g: [f64; 3] =
                std::array::from_fn(|m| tri_lines[m].n[0] * v[0] + tri_lines[m].n[1] * v[1] - tri_lines[m].c);
            if !(g[0].abs() > on_line[0] && g[1].abs() > on_line[1] && g[2].abs() > on_line[2]) {
                return Err(Declined);
            }
            *slot = g;
        }
        let mut count = 0;
        let list = diagram.neighbor_list();
        let density = triangle.density;
        let mut sums = Sums::default();
        let mut any_segment = false;
        let mut gb = b.values[0];
        for k in 0..len {
            let k1 = if k + 1 == len { 0 } else { k + 1 };
            let ga = gb;
            gb = b.values[k1];
            // Liang–Barsky: the parameter interval of the edge inside t.
            let (mut t0, mut t1) = (0.0f64, 1.0f64);
            let (mut enter, mut exit) = (usize::MAX, usize::MAX);
            let mut outside = false;
            for m in 0..3 {
                let (fa, fb) = (ga[m], gb[m]);
                if fa > 0.0 {
                    if fb > 0.0 {
                        outside = true;
                        break;
                    }
                    let u = fa / (fa - fb);
                    if u > t0 {
                        t0 = u;
                        enter = m;
                    }
                } else if fb > 0.0 {
                    let u = fa / (fa - fb);
                    if u < t1 {
                        t1 = u;
                        exit = m;
                    }
                }
            }
            if outside {
                continue;
            }
            if t0 >= t1 - TIE {
                if t0 <= t1 + TIE {
                    return Err(Declined);
                }
                continue;
            }
            let line = &lines[k];
            if line.label == NO_LABEL {
                // A frame edge inside t: the frame is far outside Ω, so something is off.
                return Err(Declined);
            }
            let p = if enter == usize::MAX {
                vertices[k]
            } else {
                meet(&tri_lines[enter], line).ok_or(Declined)?
            };
            let q = if exit == usize::MAX {
                vertices[k1]
            } else {
                meet(&tri_lines[exit], line).ok_or(Declined)?
            };
            for (m, point, entry) in [(enter, p, true), (exit, q, false)] {
                if m != usize::MAX {
                    let (a, e) = (corners[m], corners[NEXT[m]]);
                    let d = [e[0] - a[0], e[1] - a[1]];
                    let position = ((point[0] - a[0]) * d[0] + (point[1] - a[1]) * d[1]) / (d[0] * d[0] + d[1] * d[1]);
                    if !(position > TIE && position < 1.0 - TIE) {
                        return Err(Declined);
                    }
                    // Insertion sort by (edge, position): counter-clockwise along ∂t.
                    let crossing = Crossing {
                        edge: m,
                        position,
                        point,
                        entry,
                    };
                    let mut at = count;
                    while at > 0 && {
                        let c = &b.crossings[at - 1];
                        c.edge > m || (c.edge == m && c.position > position)
                    } {
                        b.crossings[at] = b.crossings[at - 1];
                        at -= 1;
                    }
                    b.crossings[at] = crossing;
                    count += 1;
                }
            }
            sums.fan(p, q);
            any_segment = true;
            let length = ((q[0] - p[0]) * (q[0] - p[0]) + (q[1] - p[1]) * (q[1] - p[1])).sqrt();
            out.edges.push((line.label, 0.5 * density * length));
            let j = list[line.label as usize] as usize;
            if s.visited[j] != s.stamp {
                s.visited[j] = s.stamp;
                s.queue.push(j as u32);
            }
        }
        if count == 0 {
            if !any_segment {
                // No edge of the cell meets t: t lies inside the cell or misses it, which only
                // the walk's first cell (a guess) may do. Decided by t's centroid.
                if !is_first {
                    return Err(Declined);
                }
                let z = [
                    (corners[0][0] + corners[1][0] + corners[2][0]) / 3.0,
                    (corners[0][1] + corners[1][1] + corners[2][1]) / 3.0,
                ];
                for l in lines {
                    let (x0, x1) = (l.n[0] * z[0], l.n[1] * z[1]);
                    let f = x0 + x1 - l.c;
                    let tolerance = ON_LINE * (x0.abs() + x1.abs() + l.c.abs());
                    if f > tolerance {
                        return Ok(None);
                    }
                    if !(f < -tolerance) {
                        return Err(Declined);
                    }
                }
                for m in 0..3 {
                    sums.fan(corners[m], corners[(m + 1) % 3]);
                }
            }
            // Otherwise the polygon lies inside t and its edges already close the piece.
        } else {
            let crossings = &b.crossings[..count];
            for k in 0..count {
                let (a, next) = (crossings[k], crossings[(k + 1) % count]);
                // Entries and exits alternate along ∂t, at distinct places.
                if a.entry == next.entry || (k + 1 < count && a.edge == next.edge && next.position - a.position <= TIE)
                {
                    return Err(Declined);
                }
                if a.entry {
                    continue;
                }
                // Arc of ∂t from the exit a to the next entry, through the corners between.
                let mut steps = (next.edge + 3 - a.edge) % 3;
                if steps == 0 && next.position < a.position {
                    steps = 3;
                }
                let mut from = a.point;
                for step in 1..=steps {
                    let corner = corners[(a.edge + step) % 3];
                    sums.fan(from, corner);
                    from = corner;
                }
                sums.fan(from, next.point);
            }
        }
        let (area, first_moment, second_moment) = sums.finish();
        if !(area > 0.0) {
            return Err(Declined);
        }
        out.pieces.push(Piece {
            cell: i as u32,
            density,
            area,
            first_moment,
            second_moment,
        });
        Ok(Some(area))
    }
}
