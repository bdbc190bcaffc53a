//! Harmonic maps of a planar (disk) triangulation into the unit disk with boundary and
//! landmark constraints: the map g of the registration f = φ₂⁻¹ ∘ g ∘ φ₁ (Su et al. 2015,
//! Alg. 4).
//!
//! The map minimizes the Dirichlet energy Σ_f A_f |∇g|² of the input planar mesh, i.e. it
//! solves, for each coordinate,
//! $$ (L g)_i = 0 \text{ at free vertices}, \qquad g_j = c_j \text{ at constrained ones}, $$
//! with L the cotangent Laplacian. Weights: the cotangent weights of the **intrinsic
//! Delaunay triangulation** of the planar mesh (for a flat mesh this is the planar Delaunay
//! triangulation of the same vertices inside the same boundary), so every interior weight is
//! ≥ 0 and, with the boundary on a convex curve and no interior constraint, the result is an
//! embedding of that triangulation (Tutte/Floater; Radó's theorem in the smooth case). Images
//! of the ORIGINAL triangles are then very rarely flipped; measure them with
//! [`crate::quality`]. Hard interior landmarks can fold the map: nothing guarantees injectivity
//! then (`docs/conventions.md`, "Registration").
//!
//! Boundary constraints:
//! * [`BoundaryConstraint::Fixed`]: every boundary vertex at a given position;
//! * [`BoundaryConstraint::Anchors`]: a few boundary vertices at given points of the unit
//!   circle; the boundary vertices between two consecutive anchors (in counter-clockwise loop
//!   order) are placed on the arc between them at angles proportional to the cumulative edge
//!   length of the input boundary (arc-length distribution). With one anchor the whole circle
//!   is used. This is a linear "sliding" rule, not a free-boundary optimization.

use faer::sparse::Triplet;
use shapespace_geometry::Connectivity;

use crate::error::ConformalError;
use crate::intrinsic::IntrinsicTriangulation;
use crate::linsolve::SpdSolver;

/// Boundary condition of [`harmonic_map`].
#[derive(Clone, Debug, PartialEq)]
pub enum BoundaryConstraint {
    /// Every boundary vertex at the given position: (vertex, position) pairs.
    Fixed(Vec<(u32, [f64; 2])>),
    /// Anchor vertices at given points of the unit circle (normalized to |z| = 1); the rest of
    /// the boundary by arc length between consecutive anchors.
    Anchors(Vec<(u32, [f64; 2])>),
}

/// Constraints of [`harmonic_map`].
#[derive(Clone, Debug, PartialEq)]
pub struct HarmonicConstraints {
    /// How the boundary is placed.
    pub boundary: BoundaryConstraint,
    /// Interior vertices pinned to given positions (hard landmark constraints).
    pub landmarks: Vec<(u32, [f64; 2])>,
}

/// Boundary positions on the unit circle from anchors, by arc length (module docs).
fn anchored_boundary(
    positions: &[[f64; 2]],
    cycle: &[u32],
    anchors: &[(u32, [f64; 2])],
) -> Result<Vec<(u32, [f64; 2])>, ConformalError> {
    if anchors.is_empty() {
        return Err(ConformalError::InvalidConstraint(
            "at least one boundary anchor is needed".into(),
        ));
    }
    let nb = cycle.len();
    let mut pos_in_loop = std::collections::HashMap::new();
    for (k, &v) in cycle.iter().enumerate() {
        pos_in_loop.insert(v, k);
    }
    let mut anchor_at: Vec<(usize, f64)> = Vec::new();
    for &(v, p) in anchors {
        let k = *pos_in_loop
            .get(&v)
            .ok_or_else(|| ConformalError::InvalidConstraint(format!("anchor {v} is not a boundary vertex")))?;
        let r = p[0].hypot(p[1]);
        if !(r > 0.0) || !r.is_finite() {
            return Err(ConformalError::InvalidConstraint(format!(
                "anchor {v} has no direction"
            )));
        }
        anchor_at.push((k, p[1].atan2(p[0])));
    }
    anchor_at.sort_by_key(|x| x.0);
    if anchor_at.windows(2).any(|w| w[0].0 == w[1].0) {
        return Err(ConformalError::InvalidConstraint(
            "a boundary vertex is anchored twice".into(),
        ));
    }
    let seg_len = |k: usize| {
        let (a, b) = (positions[cycle[k] as usize], positions[cycle[(k + 1) % nb] as usize]);
        (a[0] - b[0]).hypot(a[1] - b[1])
    };
    let tau = std::f64::consts::TAU;
    let mut out = Vec::with_capacity(nb);
    let mut turn = 0.0;
    for i in 0..anchor_at.len() {
        let (k0, t0) = anchor_at[i];
        let (k1, t1) = anchor_at[(i + 1) % anchor_at.len()];
        let mut span = (t1 - t0).rem_euclid(tau);
        if anchor_at.len() == 1 || span == 0.0 {
            span = if anchor_at.len() == 1 { tau } else { span };
        }
        turn += span;
        let steps = if anchor_at.len() == 1 { nb } else { (k1 + nb - k0) % nb };
        let total: f64 = (0..steps).map(|s| seg_len((k0 + s) % nb)).sum();
        let mut acc = 0.0;
        for s in 0..steps {
            let t = t0
                + span
                    * if total > 0.0 {
                        acc / total
                    } else {
                        s as f64 / steps as f64
                    };
            out.push((cycle[(k0 + s) % nb], [t.cos(), t.sin()]));
            acc += seg_len((k0 + s) % nb);
        }
    }
    if (turn - tau).abs() > 1e-9 {
        return Err(ConformalError::InvalidConstraint(format!(
            "anchors are not in counter-clockwise order along the boundary (they wind {:.3} turns)",
            turn / tau
        )));
    }
    Ok(out)
}

/// The harmonic map of the planar triangulation (`positions` #V, `faces` #F, counter-clockwise,
/// one boundary loop) with the given constraints (module docs). Returns #V image positions:
/// constrained vertices exactly at their targets.
///
/// Errors: not a single boundary loop, a boundary vertex without a position (Fixed), anchors
/// out of order, a landmark on the boundary or given twice, degenerate triangles.
pub fn harmonic_map(
    positions: &[[f64; 2]],
    faces: &[[u32; 3]],
    constraints: &HarmonicConstraints,
) -> Result<Vec<[f64; 2]>, ConformalError> {
    let n = positions.len();
    if let Some(f) = faces.iter().position(|f| f.iter().any(|&v| v as usize >= n)) {
        return Err(ConformalError::InvalidConstraint(format!(
            "face {f} references a vertex out of range"
        )));
    }
    let lengths: Vec<f64> = faces
        .iter()
        .flat_map(|f| {
            (0..3).map(move |k| {
                let (a, b) = (positions[f[k] as usize], positions[f[(k + 1) % 3] as usize]);
                (a[0] - b[0]).hypot(a[1] - b[1])
            })
        })
        .collect();
    let mut tri = IntrinsicTriangulation::from_lengths(n, faces, lengths)?;
    tri.make_delaunay()?;
    let conn = Connectivity::new(n, faces);
    let loops = conn.boundary_loops(faces);
    if loops.len() != 1 {
        return Err(ConformalError::NotDisk {
            reason: format!("{} boundary loops (a disk has 1)", loops.len()),
        });
    }
    let cycle = &loops[0];
    let mut target: Vec<Option<[f64; 2]>> = vec![None; n];
    let boundary_targets = match &constraints.boundary {
        BoundaryConstraint::Fixed(list) => list.clone(),
        BoundaryConstraint::Anchors(list) => anchored_boundary(positions, cycle, list)?,
    };
    for &(v, p) in &boundary_targets {
        if v as usize >= n || !tri.is_boundary[v as usize] {
            return Err(ConformalError::InvalidConstraint(format!(
                "vertex {v} is not a boundary vertex"
            )));
        }
        target[v as usize] = Some(p);
    }
    if let Some(&v) = cycle.iter().find(|&&v| target[v as usize].is_none()) {
        return Err(ConformalError::InvalidConstraint(format!(
            "boundary vertex {v} has no position"
        )));
    }
    for &(v, p) in &constraints.landmarks {
        if v as usize >= n {
            return Err(ConformalError::InvalidConstraint(format!("landmark {v} out of range")));
        }
        if tri.is_boundary[v as usize] {
            return Err(ConformalError::InvalidConstraint(format!(
                "landmark {v} lies on the boundary; constrain it through the boundary condition"
            )));
        }
        if target[v as usize].is_some() {
            return Err(ConformalError::InvalidConstraint(format!(
                "landmark {v} is given twice"
            )));
        }
        if !(p[0].is_finite() && p[1].is_finite()) {
            return Err(ConformalError::InvalidConstraint(format!(
                "landmark {v} has a non-finite target"
            )));
        }
        target[v as usize] = Some(p);
    }
    let mut index = vec![u32::MAX; n];
    let mut m = 0usize;
    for v in 0..n {
        if target[v].is_none() {
            index[v] = m as u32;
            m += 1;
        }
    }
    let mut out: Vec<[f64; 2]> = target.iter().map(|t| t.unwrap_or([0.0, 0.0])).collect();
    if m == 0 {
        return Ok(out);
    }
    let mut trip = Vec::with_capacity(4 * tri.tail.len());
    let mut rhs = vec![vec![0.0; m], vec![0.0; m]];
    for (i, j, w) in tri.half_cotan_triplets() {
        if i == j {
            continue;
        }
        let (ii, jj) = (index[i as usize], index[j as usize]);
        for (a, aa, b, bb) in [(i, ii, j, jj), (j, jj, i, ii)] {
            if aa == u32::MAX {
                continue;
            }
            trip.push(Triplet::new(aa as usize, aa as usize, w));
            if bb != u32::MAX {
                trip.push(Triplet::new(aa as usize, bb as usize, -w));
            } else {
                let p = out[b as usize];
                rhs[0][aa as usize] += w * p[0];
                rhs[1][aa as usize] += w * p[1];
            }
            let _ = a;
        }
    }
    let solver = SpdSolver::new(m, &trip, "the harmonic-map Laplacian")?;
    solver.solve(&mut rhs);
    for v in 0..n {
        if index[v] != u32::MAX {
            out[v] = [rhs[0][index[v] as usize], rhs[1][index[v] as usize]];
        }
    }
    Ok(out)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn anchors_distribute_by_arc_length() {
        // square boundary 0..4 with unit sides; anchors at 0 ↦ angle 0 and 2 ↦ angle π
        let positions = vec![[0.0, 0.0], [1.0, 0.0], [1.0, 1.0], [0.0, 1.0]];
        let cycle = vec![0, 1, 2, 3];
        let out = anchored_boundary(&positions, &cycle, &[(0, [1.0, 0.0]), (2, [-1.0, 0.0])]).unwrap();
        let get = |v: u32| out.iter().find(|x| x.0 == v).unwrap().1;
        let p1 = get(1);
        assert!((p1[0] - 0.0).abs() < 1e-15 && (p1[1] - 1.0).abs() < 1e-15, "{p1:?}");
        let p3 = get(3);
        assert!((p3[0]).abs() < 1e-15 && (p3[1] + 1.0).abs() < 1e-15, "{p3:?}");
        // clockwise anchors wind the wrong way around with three of them
        let bad = anchored_boundary(
            &positions,
            &cycle,
            &[(0, [1.0, 0.0]), (1, [0.0, -1.0]), (2, [-1.0, 0.0])],
        );
        assert!(bad.is_err());
    }
}
