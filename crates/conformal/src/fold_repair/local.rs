//! Local repair of the conformal map's folded image triangles (the region repair, for maps
//! with many folds, is the parent module's).
//!
//! The discrete Riemann map is evaluated at the vertices and interpolated linearly on the
//! ORIGINAL faces. Real scans contain slivers (angles up to ~175°) whose image orientation
//! hinges on a displacement of a few percent of the local edge length, below the
//! discretization error of any first-order method; a handful of them can fold (measured: one
//! triangle in 7 of 40 ICT faces). The repair moves one free vertex of each folded face — the
//! corner with the largest 3D angle first — to the nearest point of the kernel of its image
//! one-ring (every incident original face counter-clockwise with a margin of 1e-3 of the
//! opposite edge length), found by cyclic projection onto the half-planes (POCS). Boundary
//! vertices, the pole and the boundary marker never move. The deviation from conformality is
//! local to the moved vertices and is reported (`DiskMapInfo::fold_repairs`).
//!
//! When no single vertex can unfold a face (adjacent slivers whose one-ring kernels are empty:
//! TOSCA michael0 and david0 have such a pair), the free vertices within k rings of the fold are
//! re-embedded together as a convex-combination (Tutte) map with mean value weights and the ring
//! around them fixed, for k = 1, 2, … up to [`MAX_PATCH_RINGS`], keeping the first k whose faces
//! are all counter-clockwise (weights from the layout's angles first, then from the surface's:
//! on michael0 the layout weights leave the fold at every k ≤ 6, the surface weights remove it at
//! k = 4, moving 92 vertices). Tutte's theorem guarantees an embedding when the fixed ring is
//! convex; a small patch of an otherwise valid conformal map is close to that, and the result is
//! checked.

use geogram_predicates::Sign;

use crate::quality::orient_scaled;

/// Moves free vertices of folded faces (module docs). `vertex_faces` (#V) lists the original
/// faces around each vertex, `corner_angles` (#F × 3) the 3D angles, `fixed` (#V) the vertices
/// that must not move. Returns the number of vertex moves; folds that could not be repaired
/// remain (the caller checks orientation again). Patches only when at most
/// [`MAX_PATCH_FOLDS`] folds are left after the single-vertex moves
/// ([`repair_folds_with_patches`] sets that bound).
pub fn repair_folds(
    faces: &[[u32; 3]],
    vertex_faces: &[Vec<u32>],
    corner_angles: &[[f64; 3]],
    fixed: &[bool],
    uv: &mut [[f64; 2]],
) -> usize {
    repair_folds_with_patches(faces, vertex_faces, corner_angles, fixed, uv, MAX_PATCH_FOLDS)
}

/// [`repair_folds`] with patches re-embedded when at most `max_patch_folds` folds are left
/// after the single-vertex moves (`usize::MAX`: always).
pub fn repair_folds_with_patches(
    faces: &[[u32; 3]],
    vertex_faces: &[Vec<u32>],
    corner_angles: &[[f64; 3]],
    fixed: &[bool],
    uv: &mut [[f64; 2]],
    max_patch_folds: usize,
) -> usize {
    let ccw = |uv: &[[f64; 2]], f: usize| {
        let [a, b, c] = faces[f];
        orient_scaled(uv[a as usize], uv[b as usize], uv[c as usize]) == Sign::Positive
    };
    let mut moves = 0;
    for _round in 0..10 {
        let bad: Vec<usize> = (0..faces.len()).filter(|&f| !ccw(uv, f)).collect();
        if bad.is_empty() {
            break;
        }
        let mut progress = false;
        for f in bad {
            if ccw(uv, f) {
                continue;
            }
            let mut corners = [0usize, 1, 2];
            corners.sort_by(|&i, &j| corner_angles[f][j].total_cmp(&corner_angles[f][i]));
            for k in corners {
                let v = faces[f][k] as usize;
                if fixed[v] {
                    continue;
                }
                // half-planes: for each incident face (v, x, y) ccw, v left of x→y
                let planes: Vec<([f64; 2], [f64; 2], f64)> = vertex_faces[v]
                    .iter()
                    .map(|&g| {
                        let face = faces[g as usize];
                        let i = face.iter().position(|&w| w as usize == v).unwrap_or(0);
                        let (x, y) = (uv[face[(i + 1) % 3] as usize], uv[face[(i + 2) % 3] as usize]);
                        let e = [y[0] - x[0], y[1] - x[1]];
                        let l = e[0].hypot(e[1]);
                        let n = if l > 0.0 { [-e[1] / l, e[0] / l] } else { [0.0, 0.0] };
                        (x, n, 1e-3 * l)
                    })
                    .collect();
                let old = uv[v];
                let mut p = old;
                for _ in 0..500 {
                    let mut violated = false;
                    for &(x, n, margin) in &planes {
                        let d = n[0] * (p[0] - x[0]) + n[1] * (p[1] - x[1]);
                        if d < margin {
                            p = [p[0] + (margin - d) * n[0], p[1] + (margin - d) * n[1]];
                            violated = true;
                        }
                    }
                    if !violated {
                        break;
                    }
                }
                uv[v] = p;
                if vertex_faces[v].iter().all(|&g| ccw(uv, g as usize)) {
                    moves += 1;
                    progress = true;
                    break;
                }
                uv[v] = old;
            }
        }
        if !progress {
            break;
        }
    }
    let left: Vec<usize> = (0..faces.len()).filter(|&f| !ccw(uv, f)).collect();
    if left.len() <= max_patch_folds {
        for f in left {
            if !ccw(uv, f) {
                moves += repair_by_patch(faces, vertex_faces, corner_angles, fixed, uv, f);
            }
        }
    }
    moves
}

/// Most folds left after the single-vertex moves that are still re-embedded patch by patch.
/// More is not a sliver problem but a folded region (the Sumner face poses leave 50–450), which
/// [`crate::fold_repair`] handles as one region; patch by patch it took 8–20 s on their 29k
/// vertices and left most folds. Where the region repair fails, the disk map tries the patches
/// without this bound (TOSCA michael0 slit once: BFF's map leaves more than 16 scattered
/// slivers, which the patches repair and the region repair does not).
pub const MAX_PATCH_FOLDS: usize = 16;

/// Floater's mean value weights of vertex v (normalized, > 0): w_vj ∝ (tan(α/2) + tan(β/2)) /
/// |x_j − x_v| with |x_j − x_v| measured on the layout `uv` and α, β the angles at v of the
/// faces at edge vj: unsigned angles of the layout (`corner_angles` = None; they reproduce x_v
/// wherever its image star is embedded), or the surface's corner angles (a folded image star
/// no longer dictates the weights). A weight that is not finite falls back to uniform.
fn mean_value_row(
    faces: &[[u32; 3]],
    vertex_faces: &[Vec<u32>],
    corner_angles: Option<&[[f64; 3]]>,
    uv: &[[f64; 2]],
    v: usize,
) -> Vec<(usize, f64)> {
    let mut row: Vec<(usize, f64)> = Vec::new();
    let x = uv[v];
    for &g in &vertex_faces[v] {
        let face = faces[g as usize];
        let i = face.iter().position(|&w| w as usize == v).unwrap_or(0);
        let (a, b) = (face[(i + 1) % 3] as usize, face[(i + 2) % 3] as usize);
        let (ea, eb) = ([uv[a][0] - x[0], uv[a][1] - x[1]], [uv[b][0] - x[0], uv[b][1] - x[1]]);
        let angle = match corner_angles {
            Some(angles) => angles[g as usize][i],
            None => (ea[0] * eb[1] - ea[1] * eb[0])
                .abs()
                .atan2(ea[0] * eb[0] + ea[1] * eb[1]),
        };
        let t = (0.5 * angle).tan();
        for (w, e) in [(a, ea), (b, eb)] {
            let contribution = t / e[0].hypot(e[1]);
            match row.iter_mut().find(|(u, _)| *u == w) {
                Some(entry) => entry.1 += contribution,
                None => row.push((w, contribution)),
            }
        }
    }
    let total: f64 = row.iter().map(|r| r.1).sum();
    if !(total.is_finite() && total > 0.0) || row.iter().any(|r| !r.1.is_finite()) {
        let n = row.len() as f64;
        return row.into_iter().map(|(w, _)| (w, 1.0 / n)).collect();
    }
    let floor = 1e-12 * row.iter().map(|r| r.1).fold(0.0, f64::max);
    let row: Vec<(usize, f64)> = row.into_iter().map(|(w, c)| (w, c.max(floor))).collect();
    let total: f64 = row.iter().map(|r| r.1).sum();
    row.into_iter().map(|(w, c)| (w, c / total)).collect()
}

/// Largest patch (in rings around a folded face) that `repair_by_patch` re-embeds.
pub const MAX_PATCH_RINGS: usize = 6;

/// Re-embeds the free vertices within k rings of face `f` as a uniform Tutte map with the rest
/// fixed, for the smallest k ≤ [`MAX_PATCH_RINGS`] after which every face touching the patch is
/// counter-clockwise (module docs). Returns the number of vertices moved (0 if no k works; `uv`
/// is then unchanged).
fn repair_by_patch(
    faces: &[[u32; 3]],
    vertex_faces: &[Vec<u32>],
    corner_angles: &[[f64; 3]],
    fixed: &[bool],
    uv: &mut [[f64; 2]],
    f: usize,
) -> usize {
    let neighbours = |v: usize| -> Vec<usize> {
        let mut out: Vec<usize> = vertex_faces[v]
            .iter()
            .flat_map(|&g| faces[g as usize].iter().map(|&w| w as usize))
            .filter(|&w| w != v)
            .collect();
        out.sort_unstable();
        out.dedup();
        out
    };
    let ccw = |uv: &[[f64; 2]], g: usize| {
        let [a, b, c] = faces[g];
        orient_scaled(uv[a as usize], uv[b as usize], uv[c as usize]) == Sign::Positive
    };
    let mut region: Vec<usize> = faces[f].iter().map(|&v| v as usize).collect();
    let mut in_region = vec![false; uv.len()];
    for &v in &region {
        in_region[v] = true;
    }
    for _rings in 1..=MAX_PATCH_RINGS {
        let frontier: Vec<usize> = region.clone();
        for v in frontier {
            for w in neighbours(v) {
                if !in_region[w] {
                    in_region[w] = true;
                    region.push(w);
                }
            }
        }
        let free: Vec<usize> = region.iter().copied().filter(|&v| !fixed[v]).collect();
        if free.is_empty() {
            continue;
        }
        let old: Vec<[f64; 2]> = free.iter().map(|&v| uv[v]).collect();
        for angles in [None, Some(corner_angles)] {
            let rows: Vec<Vec<(usize, f64)>> = free
                .iter()
                .map(|&v| mean_value_row(faces, vertex_faces, angles, uv, v))
                .collect();
            // Gauss–Seidel on x_v = Σ w_vj x_j (row-stochastic, diagonally dominant: converges), in
            // coordinates relative to the patch (its image may be tiny against the disk)
            let center = {
                let m = region.len() as f64;
                let sum = region
                    .iter()
                    .fold([0.0, 0.0], |s, &v| [s[0] + uv[v][0], s[1] + uv[v][1]]);
                [sum[0] / m, sum[1] / m]
            };
            let mut local: Vec<[f64; 2]> = uv.iter().map(|p| [p[0] - center[0], p[1] - center[1]]).collect();
            let size = region
                .iter()
                .map(|&v| local[v][0].abs().max(local[v][1].abs()))
                .fold(0.0f64, f64::max)
                .max(1e-300);
            for _sweep in 0..20_000 {
                let mut change = 0.0f64;
                for (k, &v) in free.iter().enumerate() {
                    let mut m = [0.0, 0.0];
                    for &(w, weight) in &rows[k] {
                        m[0] += weight * local[w][0];
                        m[1] += weight * local[w][1];
                    }
                    change = change.max((m[0] - local[v][0]).abs().max((m[1] - local[v][1]).abs()));
                    local[v] = m;
                }
                if change <= 1e-15 * size {
                    break;
                }
            }
            for &v in &free {
                uv[v] = [local[v][0] + center[0], local[v][1] + center[1]];
            }
            let touched: Vec<usize> = {
                let mut t: Vec<usize> = free
                    .iter()
                    .flat_map(|&v| vertex_faces[v].iter().map(|&g| g as usize))
                    .collect();
                t.sort_unstable();
                t.dedup();
                t
            };
            if touched.iter().all(|&g| ccw(uv, g)) {
                return free.len();
            }
            for (k, &v) in free.iter().enumerate() {
                uv[v] = old[k];
            }
        }
    }
    0
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_crossed_sliver_is_unfolded_by_moving_its_obtuse_corner() {
        // square fan around vertex 4 (center) with vertex 4 pushed outside across edge 0-1
        let faces = vec![[0, 1, 4], [1, 2, 4], [2, 3, 4], [3, 0, 4]];
        let mut uv = vec![[0.0, 0.0], [1.0, 0.0], [1.0, 1.0], [0.0, 1.0], [0.5, -0.01]];
        let mut vf = vec![Vec::new(); 5];
        for (f, face) in faces.iter().enumerate() {
            for &v in face {
                vf[v as usize].push(f as u32);
            }
        }
        let angles = vec![[0.1, 0.1, 3.0]; 4];
        let fixed = vec![true, true, true, true, false];
        let moves = repair_folds(&faces, &vf, &angles, &fixed, &mut uv);
        assert_eq!(moves, 1);
        // moved just inside: y = margin 1e-3 above edge 0-1, x unchanged
        assert!(
            (uv[4][1] - 1e-3).abs() < 1e-12 && (uv[4][0] - 0.5).abs() < 1e-12,
            "{:?}",
            uv[4]
        );
    }
}
