//! Probe: fold repair strategies on the centroid map of the area-preserving OT (results in
//! `docs/decisions/0012-fold-repair.md` and `docs/experiments.md`).
//! `cargo run --release -p shapespace-tools --bin repair_probe -- MESH...` (a path, or a
//! TOSCA name such as `horse0`, cut as `shapespace prepare` does). Per mesh: the centroid map
//! without repair, then (A) `repair_folds` (default; env `SWEEPS`, `FLOOR` set its retraction
//! sweeps and log floor τ), (B) `untangle_kernels` alone, (C) B then `repair_folds`, (D) the
//! max-min untangling below (Freitag & Plassmann; face scales = target areas, `UNIT=1`: all 1),
//! (E) D then `repair_folds`. Prints folds, vertices moved, |Υ| and |ε| median / p95, seconds.
use std::time::Instant;

use shapespace_analysis::area_preserving::{area_preserving_map, AreaPreservingParams};
use shapespace_analysis::distortion::map_distortion;
use shapespace_analysis::fold_repair::{
    count_folded_faces, face_is_valid, repair_folds, untangle_kernels, FoldRepairParams, UntangleInfo,
};
use shapespace_conformal::Markers;
use shapespace_geometry::prepare::{prepare_disk, PrepareOptions};
use shapespace_geometry::{Connectivity, TriMesh};

/// The folded faces (exact predicate of the library).
fn folded(faces: &[[u32; 3]], uv: &[[f64; 2]]) -> Vec<usize> {
    (0..faces.len())
        .filter(|&f| {
            let [a, b, c] = faces[f].map(|v| uv[v as usize]);
            !face_is_valid(a, b, c)
        })
        .collect()
}

/// The position p (relative to `origin`) in the bounding box of the link that maximizes
/// min_k (c_k · p + d_k) / w_k, where c_k · p + d_k is the doubled signed area of the star's
/// face (p, a_k, b_k) and w_k > 0 its scale; returns (p, that minimum). A concave
/// piecewise-linear function attains its maximum over a box at a point where three of its
/// pieces meet, two meet on an edge of the box, or at a corner: all of them are enumerated
/// (stars have ~6 faces). `None` for an empty link or a box of zero extent.
fn max_min_position(links: &[([f64; 2], [f64; 2])], scales: &[f64], origin: [f64; 2]) -> Option<([f64; 2], f64)> {
    let rel = |p: [f64; 2]| [p[0] - origin[0], p[1] - origin[1]];
    let (mut lo, mut hi) = ([f64::INFINITY; 2], [f64::NEG_INFINITY; 2]);
    // piece k: alpha_k · p + beta_k (the doubled area of (p, a, b) divided by w_k)
    let mut pieces: Vec<([f64; 2], f64)> = Vec::with_capacity(links.len());
    for (&(a, b), &w) in links.iter().zip(scales) {
        let (a, b) = (rel(a), rel(b));
        for q in [a, b] {
            for d in 0..2 {
                lo[d] = lo[d].min(q[d]);
                hi[d] = hi[d].max(q[d]);
            }
        }
        let c = [a[1] - b[1], b[0] - a[0]];
        let d = a[0] * b[1] - a[1] * b[0];
        pieces.push(([c[0] / w, c[1] / w], d / w));
    }
    if pieces.is_empty() || !(hi[0] > lo[0] && hi[1] > lo[1]) {
        return None;
    }
    let value = |p: [f64; 2]| {
        pieces
            .iter()
            .map(|(a, b)| a[0] * p[0] + a[1] * p[1] + b)
            .fold(f64::INFINITY, f64::min)
    };
    let inside = |p: [f64; 2]| p[0] >= lo[0] && p[0] <= hi[0] && p[1] >= lo[1] && p[1] <= hi[1];
    let mut best: Option<([f64; 2], f64)> = None;
    let mut consider = |p: [f64; 2]| {
        if p[0].is_finite() && p[1].is_finite() && inside(p) {
            let v = value(p);
            if v.is_finite() && best.is_none_or(|(_, b)| v > b) {
                best = Some((p, v));
            }
        }
    };
    for corner in [[lo[0], lo[1]], [hi[0], lo[1]], [hi[0], hi[1]], [lo[0], hi[1]]] {
        consider(corner);
    }
    let k = pieces.len();
    // the line where pieces i and j are equal: (alpha_i − alpha_j) · p = beta_j − beta_i
    let diff = |i: usize, j: usize| {
        let (ai, bi) = pieces[i];
        let (aj, bj) = pieces[j];
        ([ai[0] - aj[0], ai[1] - aj[1]], bj - bi)
    };
    for i in 0..k {
        for j in i + 1..k {
            let (n1, r1) = diff(i, j);
            // on the box edges
            for (axis, x) in [(0, lo[0]), (0, hi[0]), (1, lo[1]), (1, hi[1])] {
                let other = 1 - axis;
                if n1[other] != 0.0 {
                    let mut p = [0.0; 2];
                    p[axis] = x;
                    p[other] = (r1 - n1[axis] * x) / n1[other];
                    consider(p);
                }
            }
            for m in j + 1..k {
                let (n2, r2) = diff(i, m);
                let det = n1[0] * n2[1] - n1[1] * n2[0];
                if det != 0.0 {
                    consider([(r1 * n2[1] - r2 * n1[1]) / det, (n1[0] * r2 - n2[0] * r1) / det]);
                }
            }
        }
    }
    best
}

/// Untangles folded faces of the planar map `uv` (#V) of `faces` by the max-min rule of
/// Freitag & Plassmann [2000, "Local optimization-based simplicial mesh untangling and
/// improvement"]: a free vertex of a folded face moves to the point of its link's bounding
/// box that maximizes the smallest doubled signed area of its faces, each divided by its
/// `face_scales` entry (#F, > 0; e.g. the face's target area, so that small faces count as
/// much as large ones). Unlike `untangle_kernels` this also moves a vertex whose kernel is
/// empty (it makes the worst face less negative), so folds that need several vertices to move
/// get untangled. A move is kept only when the number of invalid faces around the vertex (exact
/// predicate) drops, or stays and the smallest scaled area grows; so the number of folded
/// faces never increases. Gauss–Seidel sweeps over the free vertices of the folded faces
/// (after `max_sweeps / 2` sweeps, or a sweep without a move, also their one-ring
/// neighbours); stops when nothing is folded, a widened sweep moves nothing, or after
/// `max_sweeps`. Fixed vertices never move.
fn untangle_max_min(
    faces: &[[u32; 3]],
    vertex_faces: &[Vec<u32>],
    face_scales: &[f64],
    fixed: &[bool],
    uv: &mut [[f64; 2]],
    max_sweeps: usize,
) -> UntangleInfo {
    let mut bad = folded(faces, uv);
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
    let scale = |f: u32| {
        let w = face_scales.get(f as usize).copied().unwrap_or(1.0);
        if w > 0.0 && w.is_finite() {
            w
        } else {
            1.0
        }
    };
    let mut widened = false;
    while !bad.is_empty() && info.sweeps < max_sweeps {
        info.sweeps += 1;
        widened |= info.sweeps > max_sweeps / 2;
        let mut verts: Vec<usize> = bad.iter().flat_map(|&f| faces[f].map(|v| v as usize)).collect();
        if widened {
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
            let links: Vec<([f64; 2], [f64; 2])> = vertex_faces[v]
                .iter()
                .map(|&f| {
                    let t = faces[f as usize];
                    let k = t.iter().position(|&u| u as usize == v).unwrap_or(0);
                    (uv[t[(k + 1) % 3] as usize], uv[t[(k + 2) % 3] as usize])
                })
                .collect();
            let scales: Vec<f64> = vertex_faces[v].iter().map(|&f| scale(f)).collect();
            let origin = uv[v];
            let Some((p, best)) = max_min_position(&links, &scales, origin) else {
                continue;
            };
            // the current smallest scaled area, evaluated the same way (p = 0)
            let Some((_, now)) = max_min_position_at(&links, &scales, origin) else {
                continue;
            };
            let before = invalid_around(uv, v);
            if before == 0 && !widened {
                continue;
            }
            let old = uv[v];
            uv[v] = [origin[0] + p[0], origin[1] + p[1]];
            let after = invalid_around(uv, v);
            if after < before || (after == before && best > now && uv[v] != old) {
                info.moves += 1;
                moved = true;
            } else {
                uv[v] = old;
            }
        }
        bad = folded(faces, uv);
        if !moved {
            if widened {
                break;
            }
            widened = true;
        }
    }
    info.folded_after = bad.len();
    info
}

/// The smallest scaled doubled area of the star at its current position (relative p = 0), in
/// the form of [`max_min_position`]'s result.
fn max_min_position_at(links: &[([f64; 2], [f64; 2])], scales: &[f64], origin: [f64; 2]) -> Option<([f64; 2], f64)> {
    let v = links
        .iter()
        .zip(scales)
        .map(|(&(a, b), &w)| {
            let (a, b) = (
                [a[0] - origin[0], a[1] - origin[1]],
                [b[0] - origin[0], b[1] - origin[1]],
            );
            (a[0] * b[1] - a[1] * b[0]) / w
        })
        .fold(f64::INFINITY, f64::min);
    v.is_finite().then_some(([0.0; 2], v))
}

fn row(name: &str, mesh: &TriMesh, uv: &[[f64; 2]], base: &[[f64; 2]], secs: f64) {
    let moved = uv.iter().zip(base).filter(|(a, b)| a != b).count();
    let d = map_distortion(name, mesh, uv).unwrap();
    println!(
        "  {name:<28} folds {:>5}  moved {:>6}  |Y| med {:.3} p95 {:.3}  |eps| med {:.3} p95 {:.3}  {secs:.2} s",
        count_folded_faces(&mesh.faces, uv),
        moved,
        d.abs_area_distortion.median,
        d.abs_area_distortion.p95,
        d.abs_vertex_log_area_ratio.median,
        d.abs_vertex_log_area_ratio.p95
    );
}

fn main() {
    for arg in std::env::args().skip(1) {
        let path = if std::path::Path::new(&arg).exists() {
            std::path::PathBuf::from(&arg)
        } else {
            shapespace_test_support::shared_datasets_dir().join(format!("tosca/{arg}.off"))
        };
        let mesh = shapespace_geometry::io::read_mesh(&path).unwrap();
        let mesh = if Connectivity::of(&mesh).boundary_loops(&mesh.faces).len() == 1 {
            mesh
        } else {
            prepare_disk(&mesh, &PrepareOptions::default()).unwrap().0
        };
        let mut params = AreaPreservingParams::default();
        params.fold_repair.enabled = false;
        params.require_convergence = false;
        let map = area_preserving_map(&mesh, &Markers::default(), &params).unwrap();
        println!(
            "{arg}: V {} F {}, OT converged {}",
            mesh.num_vertices(),
            mesh.num_faces(),
            map.ot.converged
        );
        let base = map.uv.clone();
        let conn = Connectivity::of(&mesh);
        row("centroid map", &mesh, &base, &base, 0.0);
        let mut a = base.clone();
        let t = Instant::now();
        let ra = repair_folds(
            &mesh,
            &map.is_boundary,
            &mut a,
            &FoldRepairParams {
                retraction_sweeps: std::env::var("SWEEPS").ok().and_then(|s| s.parse().ok()).unwrap_or(200),
                retraction_log_floor: std::env::var("FLOOR").ok().and_then(|s| s.parse().ok()).unwrap_or(1.0),
                ..Default::default()
            },
        )
        .unwrap();
        println!("    A: {} retraction sweeps", ra.retraction_sweeps);
        row("A repair_folds", &mesh, &a, &base, t.elapsed().as_secs_f64());
        let mut b = base.clone();
        let t = Instant::now();
        let info = untangle_kernels(&mesh.faces, &conn.vertex_faces, &map.is_boundary, &mut b, 200);
        let tb = t.elapsed().as_secs_f64();
        row(&format!("B untangle ({} sweeps)", info.sweeps), &mesh, &b, &base, tb);
        // D: max-min untangling, face scales = target doubled areas (3D share of the disk)
        let areas3 = shapespace_geometry::quantities::face_areas(&mesh);
        let total3: f64 = areas3.iter().sum();
        let scales: Vec<f64> = if std::env::var("UNIT").is_ok() {
            vec![1.0; areas3.len()]
        } else {
            areas3.iter().map(|a| 2.0 * a * std::f64::consts::PI / total3).collect()
        };
        let mut dd = base.clone();
        let t = Instant::now();
        let di = untangle_max_min(&mesh.faces, &conn.vertex_faces, &scales, &map.is_boundary, &mut dd, 200);
        let td = t.elapsed().as_secs_f64();
        row(
            &format!("D max-min ({} sw, {} mv)", di.sweeps, di.moves),
            &mesh,
            &dd,
            &base,
            td,
        );
        {
            let mut with_b = 0;
            let mut left = 0;
            for f in &mesh.faces {
                let [a, b, c] = f.map(|v| dd[v as usize]);
                if !face_is_valid(a, b, c) {
                    left += 1;
                    if f.iter().any(|&v| map.is_boundary[v as usize]) {
                        with_b += 1;
                    }
                }
            }
            println!("    D leaves {left} folded faces, {with_b} touching the boundary");
        }
        if di.folded_after > 0 {
            let mut e = dd.clone();
            let t = Instant::now();
            let r = repair_folds(&mesh, &map.is_boundary, &mut e, &FoldRepairParams::default()).unwrap();
            row(
                &format!("E D+repair (whole {})", r.whole_disk),
                &mesh,
                &e,
                &base,
                td + t.elapsed().as_secs_f64(),
            );
        }
        if info.folded_after > 0 {
            let mut c = b.clone();
            let t = Instant::now();
            let r = repair_folds(&mesh, &map.is_boundary, &mut c, &FoldRepairParams::default()).unwrap();
            row(
                &format!("C B+repair (whole {})", r.whole_disk),
                &mesh,
                &c,
                &base,
                tb + t.elapsed().as_secs_f64(),
            );
        }
    }
}
