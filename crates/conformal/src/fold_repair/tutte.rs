//! The Tutte solve of a region by faer's sparse LU, one system per connected component
//! (module docs of [`super`]), and the whole-disk mean-value Tutte map.

use super::*;

/// Solutions of the Tutte system's connected components from an earlier round of
/// [`repair_folds`], keyed by (first vertex, size): the region only grows, so a component with
/// the same first vertex and size is the same vertex set, with the same weights and fixed
/// neighbours, and its solution can be taken as it is.
pub(super) type ComponentSolutions = Vec<((usize, usize), Vec<[f64; 2]>)>;

/// Solves the Tutte system on the region (`in_region`, interior vertices only) with every other
/// vertex fixed at `fixed`, one connected component at a time (in parallel; each solve is
/// sequential, so the result does not depend on the thread count); returns the new positions.
/// With `earlier`, components solved in an earlier call (same weights, same `fixed`) are taken
/// from it, and it is replaced by this call's components.
pub(super) fn solve_region(
    neighbors: &[Vec<u32>],
    weights: &[Vec<f64>],
    in_region: &[bool],
    fixed: &[[f64; 2]],
    earlier: Option<&mut ComponentSolutions>,
) -> Result<Vec<[f64; 2]>, ConformalError> {
    let n = fixed.len();
    // the components, each listed in breadth-first order from its smallest vertex, and every
    // region vertex's index within its component
    let mut local = vec![u32::MAX; n];
    let mut components: Vec<Vec<usize>> = Vec::new();
    for start in 0..n {
        if !in_region[start] || local[start] != u32::MAX {
            continue;
        }
        let mut comp = vec![start];
        local[start] = 0;
        let mut head = 0;
        while head < comp.len() {
            let v = comp[head];
            head += 1;
            for &u in &neighbors[v] {
                let u = u as usize;
                if in_region[u] && local[u] == u32::MAX {
                    local[u] = comp.len() as u32;
                    comp.push(u);
                }
            }
        }
        components.push(comp);
    }
    let known = earlier.as_deref().map_or(&[][..], |e| e.as_slice());
    let solutions: Vec<Vec<[f64; 2]>> = components
        .par_iter()
        // (one job per component: rayon's adaptive split can leave the large ones on one thread)
        .with_max_len(1)
        .map(
            |comp| match known.iter().find(|(key, _)| *key == (comp[0], comp.len())) {
                Some((_, solution)) => Ok(solution.clone()),
                None => solve_component(neighbors, weights, in_region, fixed, &local, comp),
            },
        )
        // (all results first, then the first error in component order: the same error
        // whatever the threads do)
        .collect::<Vec<_>>()
        .into_iter()
        .collect::<Result<_, _>>()?;
    let mut out = fixed.to_vec();
    for (comp, solution) in components.iter().zip(&solutions) {
        for (&v, &p) in comp.iter().zip(solution) {
            out[v] = p;
        }
    }
    if let Some(earlier) = earlier {
        *earlier = components
            .iter()
            .map(|comp| (comp[0], comp.len()))
            .zip(solutions)
            .collect();
    }
    Ok(out)
}

/// The Tutte solve of one connected component `comp` of the region (`local`: each region
/// vertex's index within its component), in coordinates relative to the mean of its fixed
/// neighbours; its vertices' new positions, in the order of `comp`.
pub(super) fn solve_component(
    neighbors: &[Vec<u32>],
    weights: &[Vec<f64>],
    in_region: &[bool],
    fixed: &[[f64; 2]],
    local: &[u32],
    comp: &[usize],
) -> Result<Vec<[f64; 2]>, ConformalError> {
    // reference point: mean of the fixed neighbours
    let (mut c, mut count) = ([0.0f64; 2], 0usize);
    for &v in comp {
        for &u in &neighbors[v] {
            if !in_region[u as usize] {
                c[0] += fixed[u as usize][0];
                c[1] += fixed[u as usize][1];
                count += 1;
            }
        }
    }
    if count == 0 {
        return Err(ConformalError::InvalidInput(format!(
            "fold repair: region component of vertex {} touches no fixed vertex",
            comp[0]
        )));
    }
    c = [c[0] / count as f64, c[1] / count as f64];
    let m = comp.len();
    let mut trip = Vec::with_capacity(m * 8);
    let mut rhs = faer::Mat::<f64>::zeros(m, 2);
    for (li, &v) in comp.iter().enumerate() {
        trip.push(Triplet::new(li, li, 1.0));
        for (&u, &w) in neighbors[v].iter().zip(&weights[v]) {
            let u = u as usize;
            if in_region[u] {
                trip.push(Triplet::new(li, local[u] as usize, -w));
            } else {
                rhs[(li, 0)] += w * (fixed[u][0] - c[0]);
                rhs[(li, 1)] += w * (fixed[u][1] - c[1]);
            }
        }
    }
    let a = SparseColMat::<usize, f64>::try_new_from_triplets(m, m, &trip)
        .map_err(|e| ConformalError::InvalidInput(format!("fold repair: assembling the Tutte system: {e:?}")))?;
    lu_solve_in_place(a.as_ref(), rhs.as_mut()).map_err(|e| {
        ConformalError::InvalidInput(format!("fold repair: LU of the Tutte system ({m} unknowns): {e}"))
    })?;
    comp.iter()
        .enumerate()
        .map(|(li, &v)| {
            let p = [rhs[(li, 0)] + c[0], rhs[(li, 1)] + c[1]];
            if p[0].is_finite() && p[1].is_finite() {
                Ok(p)
            } else {
                Err(ConformalError::InvalidInput(format!(
                    "fold repair: non-finite position of vertex {v}"
                )))
            }
        })
        .collect()
}

/// From this many unknowns on, the Tutte systems are factorized supernodally (faer's automatic
/// choice takes the simplicial LU for these 2-D mesh systems, about twice as slow on the
/// 10⁴-unknown regions of the TOSCA bodies).
pub(super) const SUPERNODAL_LU_MIN: usize = 2000;

/// Solves A X = B in place (B: m × k) by a sparse LU with partial pivoting (faer: COLAMD column
/// ordering; supernodal from [`SUPERNODAL_LU_MIN`] unknowns), sequential, so the result does not
/// depend on the thread count.
pub(super) fn lu_solve_in_place(a: SparseColMatRef<'_, usize, f64>, rhs: faer::MatMut<'_, f64>) -> Result<(), String> {
    let m = a.nrows();
    let params = LuSymbolicParams {
        supernodal_flop_ratio_threshold: if m >= SUPERNODAL_LU_MIN {
            SupernodalThreshold::FORCE_SUPERNODAL
        } else {
            SupernodalThreshold::AUTO
        },
        ..Default::default()
    };
    let symbolic = factorize_symbolic_lu(a.symbolic(), params).map_err(|e| format!("{e:?}"))?;
    let scratch = StackReq::or(
        symbolic.factorize_numeric_lu_scratch::<f64>(Par::Seq, Default::default()),
        symbolic.solve_in_place_scratch::<f64>(rhs.ncols(), Par::Seq),
    );
    let mut buffer = MemBuffer::try_new(scratch).map_err(|e| format!("{e:?}"))?;
    let mut numeric = NumericLu::new();
    let lu = symbolic
        .factorize_numeric_lu(
            &mut numeric,
            a,
            Par::Seq,
            MemStack::new(&mut buffer),
            Default::default(),
        )
        .map_err(|e| format!("{e:?}"))?;
    lu.solve_in_place_with_conj(Conj::No, rhs, Par::Seq, MemStack::new(&mut buffer));
    Ok(())
}

/// The convex-combination (Tutte) map of `mesh` with the mean-value weights of the planar
/// layout `layout` (#V; [`RepairWeights::Layout`], unsigned angles, floored at 1e-12 of the row
/// maximum, a degenerate layout row falling back to the 3D mean-value weights) and the vertices
/// with `fixed[v] = Some(p)` held at p: $x_i = \sum_j w_{ij} x_j$ at every other vertex
/// [Floater 2003, "Mean value coordinates"]. #V positions. Where `layout` is an embedding the
/// weights are its mean value coordinates, so with every fixed vertex at its layout position
/// the result reproduces `layout` (to roundoff). Floater's theorem makes it an embedding when
/// the fixed vertices are exactly a convex boundary polygon in order; fixed interior vertices
/// (landmarks) void that guarantee: count the folds.
///
/// Errors: `fixed` or `layout` not #V long, a free vertex on the boundary of `mesh` (its row
/// would be empty), a degenerate 3D one-ring, a failed sparse solve.
pub fn mean_value_tutte_map(
    mesh: &TriMesh,
    layout: &[[f64; 2]],
    fixed: &[Option<[f64; 2]>],
) -> Result<Vec<[f64; 2]>, ConformalError> {
    let n = mesh.num_vertices();
    if layout.len() != n || fixed.len() != n {
        return Err(ConformalError::InvalidInput(format!(
            "mean-value map: {} layout points and {} constraints for {n} vertices",
            layout.len(),
            fixed.len()
        )));
    }
    let conn = Connectivity::of(mesh);
    let on_boundary = conn.boundary_vertices(n);
    if let Some(v) = (0..n).find(|&v| on_boundary[v] && fixed[v].is_none()) {
        return Err(ConformalError::InvalidInput(format!(
            "mean-value map: boundary vertex {v} is not fixed"
        )));
    }
    let neighbors = conn.vertex_neighbors(n);
    let is_fixed: Vec<bool> = fixed.iter().map(Option::is_some).collect();
    let weights = tutte_weights(
        mesh,
        &conn.vertex_faces,
        &neighbors,
        &is_fixed,
        layout,
        RepairWeights::Layout,
    )?;
    let positions: Vec<[f64; 2]> = fixed.iter().zip(layout).map(|(f, p)| f.unwrap_or(*p)).collect();
    let free: Vec<bool> = is_fixed.iter().map(|f| !f).collect();
    solve_region(&neighbors, &weights, &free, &positions, None)
}
