//! Local repair of folded image triangles.
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

use geogram_predicates::Sign;

use crate::quality::orient_scaled;

/// Moves free vertices of folded faces (module docs). `vertex_faces` (#V) lists the original
/// faces around each vertex, `corner_angles` (#F × 3) the 3D angles, `fixed` (#V) the vertices
/// that must not move. Returns the number of vertex moves; folds that could not be repaired
/// remain (the caller checks orientation again).
pub fn repair_folds(
    faces: &[[u32; 3]],
    vertex_faces: &[Vec<u32>],
    corner_angles: &[[f64; 3]],
    fixed: &[bool],
    uv: &mut [[f64; 2]],
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
    moves
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
