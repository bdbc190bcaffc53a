//! The retraction of the re-solved region towards the input positions (module docs of
//! [`super`]).

use super::*;

/// Doubled area of face `f` with vertex `v` at `p` (`None`: folded).
pub(super) fn doubled_area_with(faces: &[[u32; 3]], uv: &[[f64; 2]], f: usize, v: usize, p: [f64; 2]) -> Option<f64> {
    let [a, b, c] = faces[f].map(|u| if u as usize == v { p } else { uv[u as usize] });
    doubled_area(a, b, c)
}

/// Retraction towards `target` (the input map): Gauss–Seidel sweeps over `movable` moving
/// each vertex along the segment to its target by the largest step 2^{-s} (s = 0..5) after
/// which every face around it is valid and has doubled area ≥ min(its current value,
/// `floors[f]`), so an embedding stays one and no face is squeezed below its floor. Stops
/// after `max_sweeps` or when a sweep moves nothing. Returns the sweeps run.
pub(super) fn retract(
    faces: &[[u32; 3]],
    vertex_faces: &[Vec<u32>],
    floors: &[f64],
    movable: &[usize],
    target: &[[f64; 2]],
    uv: &mut [[f64; 2]],
    max_sweeps: usize,
) -> usize {
    // doubled area of every face at the current positions (None: folded), kept up to date
    // as vertices move.
    let mut current: Vec<Option<f64>> = vec![None; faces.len()];
    for &v in movable {
        for &f in &vertex_faces[v] {
            let f = f as usize;
            current[f] = doubled_area_with(faces, uv, f, v, uv[v]);
        }
    }
    let star_ok = |uv: &[[f64; 2]], current: &[Option<f64>], v: usize, p: [f64; 2]| {
        vertex_faces[v].iter().all(|&f| {
            let f = f as usize;
            match (doubled_area_with(faces, uv, f, v, p), current[f]) {
                (Some(new), Some(old)) => new >= old.min(floors[f]),
                (Some(_), None) => true,
                (None, _) => false,
            }
        })
    };
    // A vertex is tried again only after it or a vertex of its star moved: otherwise its
    // trials see the same faces and fail the same way (the sweeps are unchanged, just cheaper).
    let mut dirty = vec![false; uv.len()];
    for &v in movable {
        dirty[v] = true;
    }
    for sweep in 0..max_sweeps {
        let mut moved = false;
        for &v in movable {
            if !std::mem::replace(&mut dirty[v], false) {
                continue;
            }
            let (x, goal) = (uv[v], target[v]);
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
                if p != x && star_ok(uv, &current, v, p) {
                    uv[v] = p;
                    for &f in &vertex_faces[v] {
                        let f = f as usize;
                        current[f] = doubled_area_with(faces, uv, f, v, p);
                        for &u in &faces[f] {
                            dirty[u as usize] = true;
                        }
                    }
                    moved = true;
                    break;
                }
                t *= 0.5;
            }
        }
        if !moved {
            return sweep + 1;
        }
    }
    max_sweeps
}

/// [`retract`] run on each connected component of `movable` (adjacency `neighbors`) on its own,
/// the components in parallel; returns the most sweeps any ran. Two movable vertices on one
/// face are neighbours, so different components share no face: each component's moves see
/// only its own vertices' positions, and the result is exactly that of [`retract`] over all of
/// `movable` in its order (Gauss–Seidel order within a component is kept). Each component is
/// solved on a compact copy (its vertices, their stars and the stars' other corners).
#[allow(clippy::too_many_arguments)]
pub(super) fn retract_components(
    faces: &[[u32; 3]],
    vertex_faces: &[Vec<u32>],
    neighbors: &[Vec<u32>],
    floors: &[f64],
    movable: &[usize],
    target: &[[f64; 2]],
    uv: &mut [[f64; 2]],
    max_sweeps: usize,
) -> usize {
    const NONE: u32 = u32::MAX;
    // component of each movable vertex (by breadth-first search), in the order of `movable`
    let mut component = vec![NONE; uv.len()];
    for &v in movable {
        component[v] = NONE - 1;
    }
    let mut count = 0u32;
    let mut queue = Vec::new();
    for &s in movable {
        if component[s] != NONE - 1 {
            continue;
        }
        component[s] = count;
        queue.push(s);
        while let Some(v) = queue.pop() {
            for &u in &neighbors[v] {
                if component[u as usize] == NONE - 1 {
                    component[u as usize] = count;
                    queue.push(u as usize);
                }
            }
        }
        count += 1;
    }
    let mut members: Vec<Vec<usize>> = vec![Vec::new(); count as usize];
    for &v in movable {
        members[component[v] as usize].push(v);
    }
    if members.is_empty() {
        // (what `retract` returns for nothing to move)
        return usize::from(max_sweeps > 0);
    }
    // largest first, for the balance of the parallel loop
    members.sort_by_key(|m| std::cmp::Reverse(m.len()));
    let uv_in: &[[f64; 2]] = uv;
    // per component: its sweeps, and its vertices' final positions
    type Retracted = (usize, Vec<(usize, [f64; 2])>);
    let moved: Vec<Retracted> = members
        .par_iter()
        // (one job per component: rayon's adaptive split would leave the largest ones, listed
        // first, together on one thread)
        .with_max_len(1)
        .map(|part| {
            // compact copy: local vertex ids for the component, its stars' faces and corners
            let mut local: std::collections::HashMap<u32, u32> = std::collections::HashMap::new();
            let mut global: Vec<usize> = Vec::new();
            let mut id = |v: u32, global: &mut Vec<usize>| {
                *local.entry(v).or_insert_with(|| {
                    global.push(v as usize);
                    (global.len() - 1) as u32
                })
            };
            // (a vertex listed twice in `movable` keeps one local id and is tried twice per
            // sweep, as in `retract`)
            let sub_movable: Vec<usize> = part.iter().map(|&v| id(v as u32, &mut global) as usize).collect();
            let distinct = global.len();
            let mut face_id: std::collections::HashMap<u32, u32> = std::collections::HashMap::new();
            let (mut sub_faces, mut sub_floors) = (Vec::new(), Vec::new());
            let mut sub_vertex_faces: Vec<Vec<u32>> = vec![Vec::new(); distinct];
            for k in 0..distinct {
                for &f in &vertex_faces[global[k]] {
                    let g = *face_id.entry(f).or_insert_with(|| {
                        sub_faces.push(faces[f as usize].map(|u| id(u, &mut global)));
                        sub_floors.push(floors[f as usize]);
                        (sub_faces.len() - 1) as u32
                    });
                    sub_vertex_faces[k].push(g);
                }
            }
            let mut sub_uv: Vec<[f64; 2]> = global.iter().map(|&v| uv_in[v]).collect();
            let sub_target: Vec<[f64; 2]> = global.iter().map(|&v| target[v]).collect();
            sub_vertex_faces.resize(global.len(), Vec::new());
            let sweeps = retract(
                &sub_faces,
                &sub_vertex_faces,
                &sub_floors,
                &sub_movable,
                &sub_target,
                &mut sub_uv,
                max_sweeps,
            );
            (sweeps, (0..distinct).map(|k| (global[k], sub_uv[k])).collect())
        })
        .collect();
    let mut sweeps = 0;
    for (s, positions) in moved {
        sweeps = sweeps.max(s);
        for (v, p) in positions {
            uv[v] = p;
        }
    }
    sweeps
}
