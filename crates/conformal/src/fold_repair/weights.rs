//! The Tutte weights of the repair: mean-value weights on the layout or on the 3D surface
//! (module docs of [`super`]).

use super::*;

/// tan(θ/2) of the unsigned angle θ ∈ [0, π] between `a` and `b` (∞ at θ = π, NaN for a zero
/// vector). Scale-free: the vectors are scaled by a power of two first.
pub(super) fn half_angle_tan<const D: usize>(a: [f64; D], b: [f64; D]) -> f64 {
    let m = a.iter().chain(b.iter()).fold(0.0f64, |acc, x| acc.max(x.abs()));
    if !(m > 0.0 && m.is_finite()) {
        return f64::NAN;
    }
    let (s, _) = power_of_two_scale(m);
    let (a, b) = (a.map(|x| x * s), b.map(|x| x * s));
    let dot: f64 = (0..D).map(|k| a[k] * b[k]).sum();
    let na = a.iter().map(|x| x * x).sum::<f64>().sqrt();
    let nb = b.iter().map(|x| x * x).sum::<f64>().sqrt();
    // |a × b| = sqrt(|a|²|b|² − dot²), stable via Lagrange: |a|²|b|² − dot² = Σ_{k<l} (a_k b_l − a_l b_k)²
    let mut cr2 = 0.0;
    for k in 0..D {
        for l in k + 1..D {
            let c = a[k] * b[l] - a[l] * b[k];
            cr2 += c * c;
        }
    }
    let cr = cr2.sqrt();
    if na == 0.0 || nb == 0.0 {
        return f64::NAN;
    }
    if dot >= 0.0 {
        cr / (na * nb + dot)
    } else {
        (na * nb - dot) / cr
    }
}

/// Mean-value weights (unsigned angles) of every vertex over its sorted neighbour list
/// `neighbors[i]`, from positions `p` (#V × D). Rows of boundary vertices are left empty.
/// Entries may be 0, ∞ or NaN on degenerate layouts; rows are not normalized.
pub(super) fn mean_value_weights<const D: usize>(
    faces: &[[u32; 3]],
    vertex_faces: &[Vec<u32>],
    neighbors: &[Vec<u32>],
    is_boundary: &[bool],
    p: &[[f64; D]],
) -> Vec<Vec<f64>> {
    let sub = |x: [f64; D], y: [f64; D]| -> [f64; D] { std::array::from_fn(|k| x[k] - y[k]) };
    let norm = |x: [f64; D]| -> f64 {
        // hypot-style scaling to avoid underflow of tiny edges
        let m = x.iter().fold(0.0f64, |acc, v| acc.max(v.abs()));
        if m == 0.0 || !m.is_finite() {
            return m;
        }
        m * x.iter().map(|v| (v / m) * (v / m)).sum::<f64>().sqrt()
    };
    // per vertex, its faces in increasing order (the same sums in the same order as a loop
    // over all faces), in parallel
    (0..neighbors.len())
        .into_par_iter()
        .map(|i| {
            if is_boundary[i] {
                return Vec::new();
            }
            let mut row = vec![0.0; neighbors[i].len()];
            for &f in &vertex_faces[i] {
                let face = faces[f as usize];
                for c in (0..3).filter(|&c| face[c] as usize == i) {
                    let (j, k) = (face[(c + 1) % 3] as usize, face[(c + 2) % 3] as usize);
                    let (a, b) = (sub(p[j], p[i]), sub(p[k], p[i]));
                    let t = half_angle_tan(a, b);
                    for (other, e) in [(j, a), (k, b)] {
                        if let Ok(slot) = neighbors[i].binary_search(&(other as u32)) {
                            row[slot] += t / norm(e);
                        }
                    }
                }
            }
            row
        })
        .collect()
}

/// Normalizes every interior row to sum 1 with entries ≥ 1e-12 of the row maximum; returns
/// false for a row that cannot be (non-finite or all zero), leaving it unchanged.
pub(super) fn normalize_row(row: &mut [f64]) -> bool {
    let max = row
        .iter()
        .fold(0.0f64, |a, &x| if x.is_nan() { f64::NAN } else { a.max(x) });
    if !(max.is_finite() && max > 0.0) || row.iter().any(|x| !x.is_finite() || *x < 0.0) {
        return false;
    }
    for x in row.iter_mut() {
        *x = x.max(1e-12 * max);
    }
    let sum: f64 = row.iter().sum();
    for x in row.iter_mut() {
        *x /= sum;
    }
    true
}

/// The normalized Tutte weights of every interior vertex (module docs). Errors when a surface
/// row is degenerate (a zero-area 3D face).
pub(super) fn tutte_weights(
    mesh: &TriMesh,
    vertex_faces: &[Vec<u32>],
    neighbors: &[Vec<u32>],
    is_boundary: &[bool],
    uv: &[[f64; 2]],
    kind: RepairWeights,
) -> Result<Vec<Vec<f64>>, ConformalError> {
    let (mut surface, layout) = rayon::join(
        || mean_value_weights(&mesh.faces, vertex_faces, neighbors, is_boundary, &mesh.positions),
        || {
            (kind == RepairWeights::Layout)
                .then(|| mean_value_weights(&mesh.faces, vertex_faces, neighbors, is_boundary, uv))
        },
    );
    for (i, row) in surface.iter_mut().enumerate() {
        if !is_boundary[i] && !normalize_row(row) {
            return Err(ConformalError::InvalidInput(format!(
                "fold repair: degenerate 3D one-ring at vertex {i} (zero-length edge or zero-area face)"
            )));
        }
    }
    let Some(mut layout) = layout else {
        return Ok(surface);
    };
    for (i, row) in layout.iter_mut().enumerate() {
        if !is_boundary[i] && !normalize_row(row) {
            row.clone_from(&surface[i]);
        }
    }
    Ok(layout)
}
