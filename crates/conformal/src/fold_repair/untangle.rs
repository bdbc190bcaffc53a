//! Untangling: corners of folded faces moved into the kernels of their stars (module docs of
//! [`super`]).

use super::*;

/// What [`untangle_kernels`] did.
#[derive(Clone, Debug, Default, PartialEq, Serialize)]
pub struct UntangleInfo {
    /// Folded faces before (exact predicate, [`face_is_valid`]).
    pub folded_before: usize,
    /// Folded faces after.
    pub folded_after: usize,
    /// Sweeps run.
    pub sweeps: usize,
    /// Vertex moves made.
    pub moves: usize,
}

/// The kernel of the star of a vertex: the polygon of points x with every face (x, a, b) of the
/// star counter-clockwise (left of every link edge a → b), by Sutherland–Hodgman clipping of the
/// link's bounding box, in coordinates relative to `origin`. Empty when the kernel is.
pub(super) fn star_kernel(links: &[([f64; 2], [f64; 2])], origin: [f64; 2]) -> Vec<[f64; 2]> {
    let rel = |p: [f64; 2]| [p[0] - origin[0], p[1] - origin[1]];
    let (mut lo, mut hi) = ([f64::INFINITY; 2], [f64::NEG_INFINITY; 2]);
    for &(a, b) in links {
        for q in [rel(a), rel(b)] {
            for d in 0..2 {
                lo[d] = lo[d].min(q[d]);
                hi[d] = hi[d].max(q[d]);
            }
        }
    }
    let mut poly = vec![[lo[0], lo[1]], [hi[0], lo[1]], [hi[0], hi[1]], [lo[0], hi[1]]];
    for &(a, b) in links {
        let (a, b) = (rel(a), rel(b));
        let side = |p: [f64; 2]| (b[0] - a[0]) * (p[1] - a[1]) - (b[1] - a[1]) * (p[0] - a[0]);
        let mut out = Vec::with_capacity(poly.len() + 1);
        for k in 0..poly.len() {
            let (p, q) = (poly[k], poly[(k + 1) % poly.len()]);
            let (sp, sq) = (side(p), side(q));
            if sp >= 0.0 {
                out.push(p);
            }
            if (sp >= 0.0) != (sq >= 0.0) {
                let t = sp / (sp - sq);
                out.push([p[0] + t * (q[0] - p[0]), p[1] + t * (q[1] - p[1])]);
            }
        }
        poly = out;
        if poly.len() < 3 {
            return Vec::new();
        }
    }
    poly
}

/// Area centroid of a polygon (relative coordinates); `None` when its area is not positive.
pub(super) fn polygon_centroid(poly: &[[f64; 2]]) -> Option<[f64; 2]> {
    let (mut a, mut cx, mut cy) = (0.0, 0.0, 0.0);
    for k in 0..poly.len() {
        let (p, q) = (poly[k], poly[(k + 1) % poly.len()]);
        let c = p[0] * q[1] - q[0] * p[1];
        a += c;
        cx += (p[0] + q[0]) * c;
        cy += (p[1] + q[1]) * c;
    }
    (a > 0.0 && a.is_finite()).then(|| [cx / (3.0 * a), cy / (3.0 * a)])
}

/// Untangles folded faces of the planar map `uv` (#V) of `faces` by moving free vertices
/// (`fixed[v] == false`) into the kernels of their stars [the kernel is the set of positions
/// where every incident face is counter-clockwise; see e.g. Freitag & Plassmann 2000, "Local
/// optimization-based simplicial mesh untangling"; here the kernel's area centroid is taken
/// instead of an optimum]. Gauss–Seidel sweeps over the free vertices of the folded faces
/// (after `max_sweeps / 2` sweeps without success, also their one-ring neighbours); a move is
/// made only when it strictly lowers the number of invalid faces around the vertex (exact
/// predicate), so the number of folded faces never increases, and only faces around the moved
/// vertex change. Stops when nothing is folded, a sweep moves nothing, or after `max_sweeps`.
/// Fixed vertices (boundary, landmarks) never move.
pub fn untangle_kernels(
    faces: &[[u32; 3]],
    vertex_faces: &[Vec<u32>],
    fixed: &[bool],
    uv: &mut [[f64; 2]],
    max_sweeps: usize,
) -> UntangleInfo {
    let bad = folded_faces(faces, uv).2;
    let mut info = UntangleInfo {
        folded_before: bad.len(),
        folded_after: bad.len(),
        ..Default::default()
    };
    let invalid_around = |uv: &[[f64; 2]], v: usize| {
        vertex_faces[v]
            .iter()
            .filter(|&&f| {
                let [a, b, c] = faces[f as usize].map(|u| uv[u as usize]);
                !face_is_valid(a, b, c)
            })
            .count()
    };
    let mut bad = bad;
    while !bad.is_empty() && info.sweeps < max_sweeps {
        info.sweeps += 1;
        let mut verts: Vec<usize> = bad.iter().flat_map(|&f| faces[f].map(|v| v as usize)).collect();
        if info.sweeps > max_sweeps / 2 {
            let ring: Vec<usize> = verts
                .iter()
                .flat_map(|&v| {
                    vertex_faces[v]
                        .iter()
                        .flat_map(|&f| faces[f as usize].map(|u| u as usize))
                })
                .collect();
            verts.extend(ring);
        }
        verts.sort_unstable();
        verts.dedup();
        let mut moved = false;
        for v in verts {
            if fixed[v] {
                continue;
            }
            let before = invalid_around(uv, v);
            if before == 0 {
                continue;
            }
            let links: Vec<([f64; 2], [f64; 2])> = vertex_faces[v]
                .iter()
                .map(|&f| {
                    let t = faces[f as usize];
                    let k = t.iter().position(|&u| u as usize == v).unwrap_or(0);
                    (uv[t[(k + 1) % 3] as usize], uv[t[(k + 2) % 3] as usize])
                })
                .collect();
            let origin = uv[v];
            let Some(c) = polygon_centroid(&star_kernel(&links, origin)) else {
                continue;
            };
            let old = uv[v];
            uv[v] = [origin[0] + c[0], origin[1] + c[1]];
            if invalid_around(uv, v) < before {
                info.moves += 1;
                moved = true;
            } else {
                uv[v] = old;
            }
        }
        bad = folded_faces(faces, uv).2;
        if !moved && info.sweeps <= max_sweeps / 2 {
            info.sweeps = max_sweeps / 2; // widen to the one-ring neighbours
        } else if !moved {
            break;
        }
    }
    info.folded_after = bad.len();
    info
}
