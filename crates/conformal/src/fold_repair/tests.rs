use super::*;
use shapespace_geometry::primitives;

fn disk_layout(rings: usize) -> (TriMesh, Vec<bool>, Vec<[f64; 2]>) {
    let mesh = primitives::unit_disk(rings);
    let is_boundary = Connectivity::of(&mesh).boundary_vertices(mesh.num_vertices());
    let uv: Vec<[f64; 2]> = mesh.positions.iter().map(|p| [p[0], p[1]]).collect();
    (mesh, is_boundary, uv)
}

/// `reference` squeezed radially (|p| → |p|^e, e = `exponent(p)`): an embedding of the disk.
fn squeezed(reference: &[[f64; 2]], exponent: impl Fn([f64; 2]) -> f64) -> Vec<[f64; 2]> {
    reference
        .iter()
        .map(|&p| {
            let r = p[0].hypot(p[1]);
            let f = if r > 0.0 { r.powf(exponent(p)) / r } else { 1.0 };
            [p[0] * f, p[1] * f]
        })
        .collect()
}

/// Retraction floors: the faces' doubled areas in `reference` times e^{-0.3}, so that some
/// moves towards the reference are refused.
fn retraction_floors(mesh: &TriMesh, reference: &[[f64; 2]]) -> Vec<f64> {
    mesh.faces
        .iter()
        .map(|f| {
            let [a, b, c] = f.map(|v| reference[v as usize]);
            doubled_area(a, b, c).unwrap() * (-0.3f64).exp()
        })
        .collect()
}

/// max_v |a_v − b_v|.
fn max_distance(a: &[[f64; 2]], b: &[[f64; 2]]) -> f64 {
    a.iter()
        .zip(b)
        .map(|(p, q)| (p[0] - q[0]).hypot(p[1] - q[1]))
        .fold(0.0, f64::max)
}

/// The next state of a xorshift64 generator (the tests' reproducible random numbers).
fn xorshift(state: &mut u64) -> u64 {
    *state ^= *state << 13;
    *state ^= *state >> 7;
    *state ^= *state << 17;
    *state
}

/// `reference` with vertex v pushed past its neighbour `far` by half an edge, so that v's
/// star folds, and the number of flipped faces (at least 2).
fn pushed_past(mesh: &TriMesh, reference: &[[f64; 2]], v: usize, far: usize) -> (Vec<[f64; 2]>, usize) {
    let mut uv = reference.to_vec();
    uv[v] = [
        reference[far][0] + 0.5 * (reference[far][0] - reference[v][0]),
        reference[far][1] + 0.5 * (reference[far][1] - reference[v][1]),
    ];
    let (flipped, _, _) = folded_faces(&mesh.faces, &uv);
    assert!(flipped >= 2, "the push should fold faces, got {flipped}");
    (uv, flipped)
}

#[test]
fn validity_uses_orientation_and_an_area_floor() {
    assert!(face_is_valid([0.0, 0.0], [1.0, 0.0], [0.0, 1.0]));
    assert!(!face_is_valid([0.0, 0.0], [0.0, 1.0], [1.0, 0.0]));
    assert!(!face_is_valid([0.0, 0.0], [1.0, 0.0], [2.0, 0.0]));
    // tiny but representable triangles are valid; below 1e-300 doubled area they are not
    assert!(face_is_valid([1e-140, 1e-140], [2e-140, 1e-140], [1e-140, 2e-140]));
    assert!(face_is_valid([0.0, 0.0], [1e-150, 0.0], [0.0, 1e-150]));
    assert!(!face_is_valid([0.0, 0.0], [1e-151, 0.0], [0.0, 1e-151]));
    // subnormal edge vectors (their power-of-two scale overflows): area ~1e-646, folded
    let (a, h) = (2f64.powi(-1023), 2f64.powi(-1073));
    assert!(!face_is_valid([a, a], [a + h, a - h], [a + h, a + h]));
}

/// The per-vertex weights sum each vertex's faces in increasing order: the same bits as the
/// loop over all faces they replaced, on a jittered disk.
#[test]
fn per_vertex_mean_value_weights_equal_the_loop_over_faces() {
    let (mesh, is_boundary, mut uv) = disk_layout(12);
    let mut state = 0x9e37_79b9_7f4a_7c15u64;
    for (v, p) in uv.iter_mut().enumerate() {
        if !is_boundary[v] {
            let state = xorshift(&mut state);
            p[0] += 0.02 * ((state >> 11) as f64 / (1u64 << 53) as f64 - 0.5);
            p[1] += 0.02 * ((state & 0xffff) as f64 / 65536.0 - 0.5);
        }
    }
    let conn = Connectivity::of(&mesh);
    let neighbors = conn.vertex_neighbors(mesh.num_vertices());
    let got = mean_value_weights(&mesh.faces, &conn.vertex_faces, &neighbors, &is_boundary, &uv);
    let mut want: Vec<Vec<f64>> = neighbors
        .iter()
        .zip(&is_boundary)
        .map(|(n, &b)| if b { Vec::new() } else { vec![0.0; n.len()] })
        .collect();
    for face in &mesh.faces {
        for c in 0..3 {
            let (i, j, k) = (face[c] as usize, face[(c + 1) % 3] as usize, face[(c + 2) % 3] as usize);
            if is_boundary[i] {
                continue;
            }
            let (a, b) = (
                [uv[j][0] - uv[i][0], uv[j][1] - uv[i][1]],
                [uv[k][0] - uv[i][0], uv[k][1] - uv[i][1]],
            );
            let t = half_angle_tan(a, b);
            for (other, e) in [(j, a), (k, b)] {
                let slot = neighbors[i].binary_search(&(other as u32)).unwrap();
                let m = e[0].abs().max(e[1].abs());
                want[i][slot] += t / (m * ((e[0] / m) * (e[0] / m) + (e[1] / m) * (e[1] / m)).sqrt());
            }
        }
    }
    assert_eq!(got, want);
    assert!(got.iter().any(|row| row.len() > 4));
}

/// The float filter in `doubled_area` never decides differently from the exact
/// predicate: random and nearly collinear triangles at scales 1e-140 … 1e3.
#[test]
fn filtered_validity_agrees_with_the_exact_predicate() {
    let mut state = 0x2545_f491_4f6c_dd1du64;
    let mut next = || (xorshift(&mut state) >> 11) as f64 / (1u64 << 53) as f64 - 0.5;
    let mut decided_by_filter = 0;
    for k in 0..20_000 {
        let scale = [1e-140, 1e-20, 1.0, 1e3][k % 4];
        let a = [next() * scale, next() * scale];
        let b = [next() * scale, next() * scale];
        // every other triangle nearly collinear: c on the line ab plus a tiny offset
        let c = if k % 2 == 0 {
            [next() * scale, next() * scale]
        } else {
            let t = next();
            let off = next() * scale * [1e-12, 1e-15, 1e-17][k % 3];
            [
                a[0] + t * (b[0] - a[0]) - off * (b[1] - a[1]),
                a[1] + t * (b[1] - a[1]) + off * (b[0] - a[0]),
            ]
        };
        let exact_positive = orient_scaled(a, b, c) == Sign::Positive;
        let got = doubled_area(a, b, c);
        if !exact_positive {
            assert!(got.is_none(), "{a:?} {b:?} {c:?}");
        } else {
            decided_by_filter += 1;
            let d1 = [b[0] - a[0], b[1] - a[1]];
            let d2 = [c[0] - a[0], c[1] - a[1]];
            let cross = d1[0] * d2[1] - d1[1] * d2[0];
            if cross > 1e-250 {
                let area = got.expect("a positive face of area > 1e-250 is valid");
                assert!((area - cross).abs() <= 1e-9 * cross, "{area} vs {cross}");
            }
        }
    }
    assert!(decided_by_filter > 5_000);
}

/// The retraction tries a vertex again only after its star changed; it must end where the
/// plain sweeps over every vertex end (same positions, same sweep count).
#[test]
fn retraction_with_a_worklist_matches_plain_sweeps() {
    let (mesh, is_boundary, reference) = disk_layout(10);
    let n = mesh.num_vertices();
    let conn = Connectivity::of(&mesh);
    let movable: Vec<usize> = (0..n).filter(|&v| !is_boundary[v]).collect();
    // start: the disk squeezed radially (an embedding), target: the reference layout,
    // floors from the reference areas minus a margin, so some moves are refused
    let start = squeezed(&reference, |_| 1.8);
    let floors = retraction_floors(&mesh, &reference);
    let mut fast = start.clone();
    let sweeps = retract(
        &mesh.faces,
        &conn.vertex_faces,
        &floors,
        &movable,
        &reference,
        &mut fast,
        200,
    );
    // plain Gauss–Seidel sweeps (the rule of `retract` without the worklist)
    let mut plain = start.clone();
    let star_ok = |uv: &[[f64; 2]], v: usize, p: [f64; 2]| {
        conn.vertex_faces[v].iter().all(|&f| {
            let f = f as usize;
            match (
                doubled_area_with(&mesh.faces, uv, f, v, p),
                doubled_area_with(&mesh.faces, uv, f, v, uv[v]),
            ) {
                (Some(new), Some(old)) => new >= old.min(floors[f]),
                (Some(_), None) => true,
                (None, _) => false,
            }
        })
    };
    let mut plain_sweeps = 200;
    for sweep in 0..200 {
        let mut moved = false;
        for &v in &movable {
            let (x, goal) = (plain[v], reference[v]);
            if x == goal {
                continue;
            }
            let mut t = 1.0;
            for _ in 0..6 {
                let p = if t == 1.0 {
                    goal
                } else {
                    [x[0] + t * (goal[0] - x[0]), x[1] + t * (goal[1] - x[1])]
                };
                if p != x && star_ok(&plain, v, p) {
                    plain[v] = p;
                    moved = true;
                    break;
                }
                t *= 0.5;
            }
        }
        if !moved {
            plain_sweeps = sweep + 1;
            break;
        }
    }
    assert!(sweeps > 2, "the case should need several sweeps, took {sweeps}");
    assert_eq!(sweeps, plain_sweeps);
    assert_eq!(fast, plain);
    assert_ne!(fast, reference, "the floors should hold some vertices back");
}

/// The retraction run per connected component of the movable vertices (in parallel) ends
/// exactly where one retraction over all of them does, after as many sweeps.
#[test]
fn retraction_by_components_matches_one_retraction() {
    let (mesh, is_boundary, reference) = disk_layout(12);
    let n = mesh.num_vertices();
    let conn = Connectivity::of(&mesh);
    let neighbors = conn.vertex_neighbors(n);
    // movable: interior vertices off the centre and off three fixed spokes, i.e. three
    // sectors that share no face
    let tau = std::f64::consts::TAU;
    let movable: Vec<usize> = (0..n)
        .filter(|&v| {
            let p = reference[v];
            let sector = (p[1].atan2(p[0]).rem_euclid(tau) / (tau / 3.0)).fract();
            !is_boundary[v] && p[0].hypot(p[1]) > 0.3 && sector > 0.12 && sector < 0.88
        })
        .collect();
    let mut component = vec![usize::MAX; n];
    let mut count = 0;
    for &s in &movable {
        if component[s] == usize::MAX {
            let mut stack = vec![s];
            component[s] = count;
            while let Some(v) = stack.pop() {
                for &u in &neighbors[v] {
                    if component[u as usize] == usize::MAX && movable.contains(&(u as usize)) {
                        component[u as usize] = count;
                        stack.push(u as usize);
                    }
                }
            }
            count += 1;
        }
    }
    assert_eq!(count, 3, "three sectors");
    // start: squeezed radially, with one sector squeezed harder (different sweep counts)
    let start = squeezed(&reference, |p| if p[1] > 0.0 { 1.8 } else { 1.4 });
    let floors = retraction_floors(&mesh, &reference);
    let mut one = start.clone();
    let sweeps = retract(
        &mesh.faces,
        &conn.vertex_faces,
        &floors,
        &movable,
        &reference,
        &mut one,
        200,
    );
    let mut parts = start.clone();
    let part_sweeps = retract_components(
        &mesh.faces,
        &conn.vertex_faces,
        &neighbors,
        &floors,
        &movable,
        &reference,
        &mut parts,
        200,
    );
    assert!(sweeps > 2, "the case should need several sweeps, took {sweeps}");
    assert_eq!(part_sweeps, sweeps);
    assert_eq!(parts, one);
    assert_ne!(one, start);
    assert_ne!(one, reference, "the floors should hold some vertices back");
    // a vertex listed twice is tried twice per sweep by both
    let mut repeated = movable.clone();
    repeated.insert(3, movable[movable.len() / 2]);
    let (mut one, mut parts) = (start.clone(), start.clone());
    let sweeps = retract(
        &mesh.faces,
        &conn.vertex_faces,
        &floors,
        &repeated,
        &reference,
        &mut one,
        200,
    );
    let part_sweeps = retract_components(
        &mesh.faces,
        &conn.vertex_faces,
        &neighbors,
        &floors,
        &repeated,
        &reference,
        &mut parts,
        200,
    );
    assert_eq!((part_sweeps, &parts), (sweeps, &one));
}

#[test]
fn half_angle_tangent_is_exact_on_known_angles() {
    let t = half_angle_tan([1.0, 0.0], [0.0, 2.0]);
    assert!((t - 1.0).abs() < 1e-15);
    let t = half_angle_tan([1.0, 0.0], [-1.0, 1.0]); // 135°
    assert!((t - (3.0 * std::f64::consts::PI / 8.0).tan()).abs() < 1e-14);
    let t = half_angle_tan([1e-200, 0.0, 0.0], [1e-200, 1e-200, 0.0]); // 45°, tiny
    assert!((t - (std::f64::consts::PI / 8.0).tan()).abs() < 1e-15);
    assert!(half_angle_tan([0.0, 0.0], [1.0, 0.0]).is_nan());
}

#[test]
fn layout_weights_reproduce_an_embedded_map() {
    // 6 rings: the simplicial LU; 30 rings (2.6k interior vertices): the supernodal one
    for rings in [6, 30] {
        let (mesh, is_boundary, uv) = disk_layout(rings);
        let n = mesh.num_vertices();
        let conn = Connectivity::of(&mesh);
        let neighbors = conn.vertex_neighbors(n);
        let w = tutte_weights(
            &mesh,
            &conn.vertex_faces,
            &neighbors,
            &is_boundary,
            &uv,
            RepairWeights::Layout,
        )
        .unwrap();
        let all_interior: Vec<bool> = is_boundary.iter().map(|b| !b).collect();
        let interior = all_interior.iter().filter(|&&b| b).count();
        assert_eq!(interior >= SUPERNODAL_LU_MIN, rings == 30, "{interior} unknowns");
        let out = solve_region(&neighbors, &w, &all_interior, &uv, None).unwrap();
        let d = max_distance(&out, &uv);
        assert!(d < 1e-14, "{rings} rings: max displacement {d:e}");
    }
}

/// A component whose vertex set did not change since the last round is taken from it, and
/// the positions equal a fresh solve's bit for bit; a grown component is solved again.
#[test]
fn unchanged_components_are_taken_from_the_earlier_round() {
    let (mesh, is_boundary, mut uv) = disk_layout(12);
    let n = mesh.num_vertices();
    let mut state = 7u64;
    for (p, &b) in uv.iter_mut().zip(&is_boundary) {
        if !b {
            p[0] += 0.01 * (xorshift(&mut state) as f64 / u64::MAX as f64 - 0.5);
            p[1] += 0.01 * (xorshift(&mut state) as f64 / u64::MAX as f64 - 0.5);
        }
    }
    let conn = Connectivity::of(&mesh);
    let neighbors = conn.vertex_neighbors(n);
    let w = tutte_weights(
        &mesh,
        &conn.vertex_faces,
        &neighbors,
        &is_boundary,
        &uv,
        RepairWeights::Surface,
    )
    .unwrap();
    let near = |c: [f64; 2], r: f64| -> Vec<bool> {
        (0..n)
            .map(|v| !is_boundary[v] && (uv[v][0] - c[0]).hypot(uv[v][1] - c[1]) < r)
            .collect()
    };
    let (a, a_grown, b) = (near([-0.5, 0.0], 0.2), near([-0.5, 0.0], 0.3), near([0.5, 0.0], 0.2));
    let union = |x: &[bool], y: &[bool]| -> Vec<bool> { x.iter().zip(y).map(|(p, q)| *p || *q).collect() };
    let (first, second) = (union(&a, &b), union(&a_grown, &b));
    let mut earlier = ComponentSolutions::new();
    solve_region(&neighbors, &w, &first, &uv, Some(&mut earlier)).unwrap();
    assert_eq!(earlier.len(), 2);
    let cached = solve_region(&neighbors, &w, &second, &uv, Some(&mut earlier)).unwrap();
    let fresh = solve_region(&neighbors, &w, &second, &uv, None).unwrap();
    assert_eq!(cached, fresh);
    assert!(
        max_distance(&fresh, &uv) > 1e-4,
        "the solve moves the jittered vertices"
    );
    // the entry for b is what is taken: a marked copy shows up in the result
    let key_b = earlier.iter().map(|(k, _)| *k).find(|&(v, _)| b[v]).unwrap();
    for (k, solution) in earlier.iter_mut() {
        if *k == key_b {
            solution.iter_mut().for_each(|p| *p = [9.0, 9.0]);
        }
    }
    let marked = solve_region(&neighbors, &w, &second, &uv, Some(&mut earlier)).unwrap();
    for v in 0..n {
        let expected = if b[v] { [9.0, 9.0] } else { fresh[v] };
        assert_eq!(marked[v], expected, "vertex {v}");
    }
}

/// The unit test of the issue: fold a known planar disk mesh by pushing an interior vertex
/// across its neighbours; the repair restores an embedding, moving only nearby vertices.
#[test]
fn pushed_vertex_fold_is_repaired_locally() {
    let (mesh, is_boundary, reference) = disk_layout(8);
    let n = mesh.num_vertices();
    let neighbors = Connectivity::of(&mesh).vertex_neighbors(n);
    // an interior vertex on ring 4 and the direction to its farthest neighbour
    let v = (0..n)
        .find(|&v| !is_boundary[v] && (reference[v][0].hypot(reference[v][1]) - 0.5).abs() < 1e-9)
        .unwrap();
    let far = *neighbors[v]
        .iter()
        .max_by(|&&a, &&b| {
            let d =
                |u: u32| (reference[u as usize][0] - reference[v][0]).hypot(reference[u as usize][1] - reference[v][1]);
            d(a).total_cmp(&d(b))
        })
        .unwrap() as usize;
    let (uv, flipped) = pushed_past(&mesh, &reference, v, far);
    for kind in [RepairWeights::Layout, RepairWeights::Surface] {
        let mut out = uv.clone();
        // the Tutte rounds alone (the kernel untangling would fix this fold by itself: see
        // `pushed_vertex_fold_is_untangled_first`)
        let params = FoldRepairParams {
            weights: kind,
            untangle_sweeps: 0,
            ..Default::default()
        };
        let info = repair_folds(&mesh, &is_boundary, &mut out, &params).unwrap();
        assert!(info.rounds >= 1 && info.untangle == UntangleInfo::default(), "{info:?}");
        let (f, d, _) = folded_faces(&mesh.faces, &out);
        assert_eq!((f, d), (0, 0), "{kind:?}: {info:?}");
        assert_eq!(info.flipped_before, flipped);
        assert_eq!(info.folded_after, 0);
        assert!(!info.whole_disk, "{kind:?}: {info:?}");
        assert!(info.vertices_moved < n / 4, "{kind:?}: {info:?}");
        // vertices far from v do not move
        for u in 0..n {
            let dist = (reference[u][0] - reference[v][0]).hypot(reference[u][1] - reference[v][1]);
            if dist > 0.6 {
                assert_eq!(out[u], uv[u], "{kind:?}: vertex {u} at distance {dist} moved");
            }
        }
        if kind == RepairWeights::Layout {
            // the pushed vertex's layout weights come from its folded star; it lands within
            // its neighbours' hull, near its old place
            let e = (out[v][0] - reference[v][0]).hypot(out[v][1] - reference[v][1]);
            assert!(
                e < 0.125,
                "vertex {v} repaired to {:?}, reference {:?}",
                out[v],
                reference[v]
            );
        }
    }
}

/// By default the kernel untangling runs first: a single pushed vertex's fold is undone by
/// moving corners of the folded faces into the kernels of their stars, and no Tutte round
/// runs.
#[test]
fn pushed_vertex_fold_is_untangled_first() {
    let (mesh, is_boundary, reference) = disk_layout(6);
    let v = (0..mesh.num_vertices()).find(|&v| !is_boundary[v] && v > 0).unwrap();
    let conn = Connectivity::of(&mesh);
    let neighbors = conn.vertex_neighbors(mesh.num_vertices());
    let far = neighbors[v][0] as usize;
    let (uv, flipped) = pushed_past(&mesh, &reference, v, far);
    let mut out = uv.clone();
    let info = repair_folds(&mesh, &is_boundary, &mut out, &FoldRepairParams::default()).unwrap();
    assert_eq!(folded_faces(&mesh.faces, &out).2.len(), 0, "{info:?}");
    assert_eq!(info.flipped_before, flipped);
    assert_eq!(
        (info.rounds, info.folded_after, info.untangle.folded_after),
        (0, 0, 0),
        "{info:?}"
    );
    assert!(info.untangle.moves >= 1);
    // only corners of the folded faces move (the sweep visits them in index order, so a
    // neighbour of v may go first); everything else keeps its place
    let corners: std::collections::BTreeSet<usize> = folded_faces(&mesh.faces, &uv)
        .2
        .iter()
        .flat_map(|&f| mesh.faces[f].map(|u| u as usize))
        .collect();
    assert!(corners.contains(&v));
    let moved: Vec<usize> = (0..out.len()).filter(|&u| out[u] != uv[u]).collect();
    assert_eq!(info.vertices_moved, moved.len(), "{info:?}");
    assert!(
        !moved.is_empty() && moved.iter().all(|u| corners.contains(u)),
        "{moved:?} not in {corners:?}"
    );
    assert!(moved.len() < corners.len(), "{moved:?}");
}

/// A scrambled map (every interior vertex at a pseudo-random point of the disk) needs the
/// whole disk: Floater's theorem then gives an embedding.
#[test]
fn scrambled_map_is_repaired_on_the_whole_disk() {
    let (mesh, is_boundary, reference) = disk_layout(10);
    let mut uv = reference.clone();
    let mut state = 0x2545_f491_4f6c_dd1du64;
    for (v, p) in uv.iter_mut().enumerate() {
        if !is_boundary[v] {
            let state = xorshift(&mut state);
            let r = 0.9 * ((state >> 11) as f64 / (1u64 << 53) as f64).sqrt();
            let t = (state & 0xffff) as f64 / 65536.0 * std::f64::consts::TAU;
            *p = [r * t.cos(), r * t.sin()];
        }
    }
    let before = folded_faces(&mesh.faces, &uv).0;
    assert!(before > 50, "{before}");
    let info = repair_folds(&mesh, &is_boundary, &mut uv, &FoldRepairParams::default()).unwrap();
    assert_eq!(folded_faces(&mesh.faces, &uv).2.len(), 0, "{info:?}");
    assert!(info.whole_disk, "{info:?}");
    for (v, p) in uv.iter().enumerate() {
        if is_boundary[v] {
            assert_eq!(*p, reference[v]);
        } else {
            assert!(p[0].hypot(p[1]) < 1.0);
        }
    }
}

#[test]
fn disabled_repair_only_counts() {
    let (mesh, is_boundary, reference) = disk_layout(4);
    let mut uv = reference.clone();
    let v = (0..mesh.num_vertices()).find(|&v| !is_boundary[v] && v > 0).unwrap();
    uv[v] = [-uv[v][0] * 3.0, -uv[v][1] * 3.0];
    let before = uv.clone();
    let info = repair_folds(
        &mesh,
        &is_boundary,
        &mut uv,
        &FoldRepairParams {
            enabled: false,
            ..Default::default()
        },
    )
    .unwrap();
    assert_eq!(uv, before);
    assert!(info.flipped_before > 0 && info.folded_after == info.flipped_before + info.degenerate_before);
    assert_eq!((info.rounds, info.vertices_moved), (0, 0));
}

/// Kernel untangling of a pushed vertex: the fold is removed, the count never grows, and
/// fixed vertices (the boundary and a pinned "landmark") do not move.
#[test]
fn untangle_kernels_removes_a_pushed_fold_and_keeps_fixed_vertices() {
    let (mesh, is_boundary, reference) = disk_layout(8);
    let n = mesh.num_vertices();
    let conn = Connectivity::of(&mesh);
    let neighbors = conn.vertex_neighbors(n);
    let v = (0..n)
        .find(|&v| !is_boundary[v] && (reference[v][0].hypot(reference[v][1]) - 0.5).abs() < 1e-9)
        .unwrap();
    let far = neighbors[v][0] as usize;
    let (mut uv, _) = pushed_past(&mesh, &reference, v, far);
    let mut fixed = is_boundary.clone();
    let pinned = neighbors[v]
        .iter()
        .map(|&u| u as usize)
        .find(|&u| u != far && !is_boundary[u])
        .unwrap();
    fixed[pinned] = true;
    let before = uv.clone();
    let info = untangle_kernels(&mesh.faces, &conn.vertex_faces, &fixed, &mut uv, 20);
    assert!(info.folded_before >= 2, "{info:?}");
    assert_eq!(info.folded_after, 0, "{info:?}");
    assert_eq!(count_folded_faces(&mesh.faces, &uv), 0);
    for u in (0..n).filter(|&u| fixed[u]) {
        assert_eq!(uv[u], before[u], "fixed vertex {u} moved");
    }
    // an embedded map is left as it is
    let mut clean = reference.clone();
    let info = untangle_kernels(&mesh.faces, &conn.vertex_faces, &is_boundary, &mut clean, 20);
    assert_eq!((info.folded_before, info.moves), (0, 0));
    assert_eq!(clean, reference);
}

/// The mean-value Tutte map reproduces an embedded layout when its vertices are pinned where
/// the layout has them (here: the boundary and one interior landmark), and with a warped but
/// embedded layout (r ↦ r², boundary fixed) it is an embedding.
#[test]
fn mean_value_tutte_map_reproduces_and_embeds() {
    let (mesh, is_boundary, reference) = disk_layout(8);
    let n = mesh.num_vertices();
    let landmark = (0..n).find(|&v| !is_boundary[v] && reference[v][0] > 0.3).unwrap();
    let fixed: Vec<Option<[f64; 2]>> = (0..n)
        .map(|v| (is_boundary[v] || v == landmark).then_some(reference[v]))
        .collect();
    let out = mean_value_tutte_map(&mesh, &reference, &fixed).unwrap();
    let d = max_distance(&out, &reference);
    assert!(d < 1e-12, "max displacement {d:e}");
    let warped: Vec<[f64; 2]> = reference
        .iter()
        .map(|p| {
            let r = p[0].hypot(p[1]);
            [p[0] * r, p[1] * r]
        })
        .collect();
    let boundary_only: Vec<Option<[f64; 2]>> = (0..n).map(|v| is_boundary[v].then_some(warped[v])).collect();
    let out = mean_value_tutte_map(&mesh, &warped, &boundary_only).unwrap();
    assert_eq!(count_folded_faces(&mesh.faces, &out), 0);
    // the bad inputs are errors
    assert!(mean_value_tutte_map(&mesh, &reference[..n - 1], &fixed).is_err());
    let free_boundary: Vec<Option<[f64; 2]>> = vec![None; n];
    assert!(mean_value_tutte_map(&mesh, &reference, &free_boundary).is_err());
}
