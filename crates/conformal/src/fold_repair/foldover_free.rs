//! Foldover-free untangling of a planar map with fixed vertices, by the regularized Winslow
//! energy of Garanzha, Kaporin, Kudryavtseva, Protais, Ray and Sokolov ("Foldover-free maps in
//! 50 lines of code", ACM ToG 40(4), 2021).
//!
//! Each face t has a reference triangle (edge vectors $R_t = [r_1 - r_0,\ r_2 - r_0]$,
//! counter-clockwise) and its image's edge vectors $X_t = [x_1 - x_0,\ x_2 - x_0]$; the map's
//! Jacobian on t is $J_t = X_t R_t^{-1}$ and $D_t = \det J_t$. The energy
//! $$ E_\varepsilon(x) = \sum_t |R_t|\, \frac{\operatorname{tr}(J_t^\top J_t) + \lambda (D_t^2 + 1)}{\chi(D_t, \varepsilon)},
//! \qquad \chi(D, \varepsilon) = \frac{D + \sqrt{\varepsilon^2 + D^2}}{2}, $$
//! ($|R_t|$ the reference area) is finite for every layout when ε > 0, and χ(D, ε) → 0 for
//! D < 0 as ε → 0, so a folded face costs ~ 1/ε². Each round minimizes $E_\varepsilon$ over the
//! free vertices by L-BFGS (Armijo backtracking, a per-vertex diagonal scaling from the
//! reference triangles' sizes, which span orders of magnitude on crowded maps), then lowers ε
//! as the paper does: with σ = max(1 − E_new/E_old, 1/10) and μ = (1 − σ) χ(D⁻, ε), D⁻ the
//! smallest D_t, ε becomes $2\sqrt{\mu(\mu - D^-)}$ while D⁻ < μ (so that χ(D⁻, ε) = μ: the worst
//! face's χ shrinks geometrically), else a floor of 1e-10. The rounds stop once every face is
//! valid (the exact predicate of [`face_is_valid`]) and the energy has settled, or when
//! [`FoldoverFreeParams::stall_rounds`] rounds in a row leave more folded faces than the fewest
//! seen.
//!
//! The energy of a face is smallest (2 + 2λ) at a rotation of its reference (tr(JᵀJ)/D ≥ 2 with
//! equality for similarities, (D² + 1)/D ≥ 2 with equality at D = 1), so an embedded input
//! whose reference triangles are its own faces is a minimum and stays where it is; references
//! taken from the surface for the folded faces pull them back to their shape and area.

use super::*;

/// Parameters of [`untangle_foldover_free`].
#[derive(Clone, Debug)]
pub struct FoldoverFreeParams {
    /// Weight λ of the area term (default 1).
    pub lambda: f64,
    /// Rounds (ε updates) at most (default 30).
    pub max_rounds: usize,
    /// L-BFGS iterations per round at most (default 400).
    pub max_iterations: usize,
    /// Pairs kept by L-BFGS (default 8).
    pub history: usize,
    /// Stop after this many rounds in a row that do not lower the fewest folded faces seen
    /// (default 8).
    pub stall_rounds: usize,
}

impl Default for FoldoverFreeParams {
    fn default() -> Self {
        FoldoverFreeParams {
            lambda: 1.0,
            max_rounds: 30,
            max_iterations: 400,
            history: 8,
            stall_rounds: 8,
        }
    }
}

/// What [`untangle_foldover_free`] did.
#[derive(Clone, Debug, Default, PartialEq, Serialize)]
pub struct FoldoverFreeInfo {
    /// Folded faces before and after (exact predicate, [`face_is_valid`]).
    pub folded_before: usize,
    pub folded_after: usize,
    /// Rounds (ε values) and L-BFGS iterations run.
    pub rounds: usize,
    pub iterations: usize,
    /// The smallest det J before and after.
    pub min_det_before: f64,
    pub min_det_after: f64,
    /// The last ε.
    pub epsilon: f64,
}

/// The reference edge vectors [r₁ − r₀, r₂ − r₀] of the 3D triangle (p₀, p₁, p₂) laid flat in
/// its plane, counter-clockwise, scaled to the area `area` (`None` when the triangle is
/// degenerate or `area` is not positive).
pub fn reference_from_surface(p: [[f64; 3]; 3], area: f64) -> Option<[[f64; 2]; 2]> {
    let e1 = [0, 1, 2].map(|k| p[1][k] - p[0][k]);
    let e2 = [0, 1, 2].map(|k| p[2][k] - p[0][k]);
    let l1 = (e1[0] * e1[0] + e1[1] * e1[1] + e1[2] * e1[2]).sqrt();
    let along = (e1[0] * e2[0] + e1[1] * e2[1] + e1[2] * e2[2]) / l1;
    let cross = [
        e1[1] * e2[2] - e1[2] * e2[1],
        e1[2] * e2[0] - e1[0] * e2[2],
        e1[0] * e2[1] - e1[1] * e2[0],
    ];
    let height = (cross[0] * cross[0] + cross[1] * cross[1] + cross[2] * cross[2]).sqrt() / l1;
    let own = 0.5 * l1 * height;
    if !(own > 0.0 && own.is_finite() && area > 0.0 && area.is_finite()) {
        return None;
    }
    let s = (area / own).sqrt();
    Some([[s * l1, 0.0], [s * along, s * height]])
}

/// The reference edge vectors of the equilateral triangle of area `area` (floored at the
/// smallest positive number): the reference of a face whose own triangles are degenerate.
pub fn reference_equilateral(area: f64) -> [[f64; 2]; 2] {
    let side = (4.0 * area.max(f64::MIN_POSITIVE) / 3f64.sqrt()).sqrt();
    [[side, 0.0], [0.5 * side, 0.5 * 3f64.sqrt() * side]]
}

/// The reference edge vectors of the planar triangle (a, b, c) (`None` unless it is
/// counter-clockwise with a positive area).
pub fn reference_from_layout(a: [f64; 2], b: [f64; 2], c: [f64; 2]) -> Option<[[f64; 2]; 2]> {
    let r = [[b[0] - a[0], b[1] - a[1]], [c[0] - a[0], c[1] - a[1]]];
    let det = r[0][0] * r[1][1] - r[0][1] * r[1][0];
    (det > 0.0 && det.is_finite()).then_some(r)
}

/// χ(D, ε) and dχ/dD.
fn chi(d: f64, eps: f64) -> (f64, f64) {
    let r = (eps * eps + d * d).sqrt();
    // (D + r)/2 without cancellation for D < 0: ε²/(2(r − D))
    let c = if d >= 0.0 {
        0.5 * (d + r)
    } else {
        0.5 * eps * eps / (r - d)
    };
    (c, c / r)
}

/// A face's data: its vertices, the inverse of its reference edge matrix and its weight.
struct Face {
    v: [usize; 3],
    /// R⁻¹ (row-major).
    s: [[f64; 2]; 2],
    w: f64,
}

/// The energy's pieces over the faces.
struct Energy<'a> {
    faces: Vec<Face>,
    /// The free variable of each vertex (usize::MAX for a fixed one).
    slot: &'a [usize],
    lambda: f64,
}

impl Energy<'_> {
    /// J of face `f` at `uv`.
    fn jacobian(f: &Face, uv: &[[f64; 2]]) -> [[f64; 2]; 2] {
        let [a, b, c] = f.v.map(|v| uv[v]);
        let x = [[b[0] - a[0], c[0] - a[0]], [b[1] - a[1], c[1] - a[1]]];
        let s = f.s;
        [
            [
                x[0][0] * s[0][0] + x[0][1] * s[1][0],
                x[0][0] * s[0][1] + x[0][1] * s[1][1],
            ],
            [
                x[1][0] * s[0][0] + x[1][1] * s[1][0],
                x[1][0] * s[0][1] + x[1][1] * s[1][1],
            ],
        ]
    }

    fn min_det(&self, uv: &[[f64; 2]]) -> f64 {
        self.faces
            .iter()
            .map(|f| {
                let j = Self::jacobian(f, uv);
                j[0][0] * j[1][1] - j[0][1] * j[1][0]
            })
            .fold(f64::INFINITY, f64::min)
    }

    /// E_ε at `uv`, and its gradient over the free variables into `grad` when given.
    fn eval(&self, uv: &[[f64; 2]], eps: f64, mut grad: Option<&mut [[f64; 2]]>) -> f64 {
        if let Some(g) = grad.as_deref_mut() {
            g.fill([0.0; 2]);
        }
        let mut e = 0.0;
        for f in &self.faces {
            let j = Self::jacobian(f, uv);
            let d = j[0][0] * j[1][1] - j[0][1] * j[1][0];
            let (c, dc) = chi(d, eps);
            let frob = j[0][0] * j[0][0] + j[0][1] * j[0][1] + j[1][0] * j[1][0] + j[1][1] * j[1][1];
            let val = (frob + self.lambda * (d * d + 1.0)) / c;
            e += f.w * val;
            let Some(g) = grad.as_deref_mut() else {
                continue;
            };
            // ∂f/∂J = 2J/χ + (2λD/χ − f χ'/χ) cof(J); ∂f/∂X = ∂f/∂J · R⁻ᵀ
            let k = (2.0 * self.lambda * d - val * dc) / c;
            let cof = [[j[1][1], -j[1][0]], [-j[0][1], j[0][0]]];
            let gj = [0, 1].map(|r| [0, 1].map(|q| f.w * (2.0 * j[r][q] / c + k * cof[r][q])));
            let s = f.s;
            // columns of ∂f/∂X: the derivatives by x₁ − x₀ and x₂ − x₀
            let g1 = [0, 1].map(|r| gj[r][0] * s[0][0] + gj[r][1] * s[0][1]);
            let g2 = [0, 1].map(|r| gj[r][0] * s[1][0] + gj[r][1] * s[1][1]);
            let parts = [[-g1[0] - g2[0], -g1[1] - g2[1]], g1, g2];
            for (&v, p) in f.v.iter().zip(parts) {
                let i = self.slot[v];
                if i != usize::MAX {
                    g[i][0] += p[0];
                    g[i][1] += p[1];
                }
            }
        }
        e
    }

    /// A diagonal scaling per free vertex: the curvature of the tr(JᵀJ) term,
    /// Σ_t |R_t| · 2(1 + λ)/χ_t · |∂J_t/∂x_i|², inverted.
    fn scaling(&self, uv: &[[f64; 2]], eps: f64, n_free: usize) -> Vec<f64> {
        let mut h = vec![0.0; n_free];
        for f in &self.faces {
            let j = Self::jacobian(f, uv);
            let d = j[0][0] * j[1][1] - j[0][1] * j[1][0];
            // χ floored at 1e-3 of its value at D = 1 (≈ 1): a face folded at a small ε would
            // otherwise give its corners a curvature so large that they hardly move
            let c = chi(d, eps).0.max(chi(1.0, eps).0 * 1e-3);
            let s = f.s;
            let rows = [[-(s[0][0] + s[1][0]), -(s[0][1] + s[1][1])], s[0], s[1]];
            for (&v, r) in f.v.iter().zip(rows) {
                let i = self.slot[v];
                if i != usize::MAX {
                    h[i] += f.w * 2.0 * (1.0 + self.lambda) / c * (r[0] * r[0] + r[1] * r[1]);
                }
            }
        }
        h.iter()
            .map(|&x| if x > 0.0 && x.is_finite() { 1.0 / x } else { 1.0 })
            .collect()
    }
}

/// Unfolds the planar map `uv` (#V) of `faces` with the vertices flagged `fixed` (#V) kept,
/// by minimizing the regularized Winslow energy with ε driven down (module docs); `reference`
/// (#F): each face's reference edge vectors ([`reference_from_surface`],
/// [`reference_from_layout`]), counter-clockwise.
///
/// The map is changed only when the result has no folded face or fewer than the input
/// ([`FoldoverFreeInfo::folded_after`] says how many are left). Errors: lengths that do not
/// match, a reference triangle that is not counter-clockwise with a finite positive area.
pub fn untangle_foldover_free(
    faces: &[[u32; 3]],
    fixed: &[bool],
    reference: &[[[f64; 2]; 2]],
    uv: &mut [[f64; 2]],
    params: &FoldoverFreeParams,
) -> Result<FoldoverFreeInfo, ConformalError> {
    let n = uv.len();
    if fixed.len() != n || reference.len() != faces.len() || faces.iter().flatten().any(|&v| v as usize >= n) {
        return Err(ConformalError::InvalidInput(format!(
            "foldover-free untangling: {} fixed flags and {} references for {n} vertices and {} faces",
            fixed.len(),
            reference.len(),
            faces.len()
        )));
    }
    let mut slot = vec![usize::MAX; n];
    let mut free: Vec<usize> = Vec::new();
    for v in 0..n {
        if !fixed[v] {
            slot[v] = free.len();
            free.push(v);
        }
    }
    let total: f64 = reference
        .iter()
        .map(|r| 0.5 * (r[0][0] * r[1][1] - r[0][1] * r[1][0]))
        .sum();
    let mut built = Vec::with_capacity(faces.len());
    for (t, (f, r)) in faces.iter().zip(reference).enumerate() {
        let det = r[0][0] * r[1][1] - r[0][1] * r[1][0];
        if !(det > 0.0 && det.is_finite()) {
            return Err(ConformalError::InvalidInput(format!(
                "foldover-free untangling: the reference triangle of face {t} has area {}",
                0.5 * det
            )));
        }
        // R = [r₁ − r₀, r₂ − r₀] as columns: R = [[r[0][0], r[1][0]], [r[0][1], r[1][1]]]
        let s = [[r[1][1] / det, -r[1][0] / det], [-r[0][1] / det, r[0][0] / det]];
        built.push(Face {
            v: f.map(|v| v as usize),
            s,
            w: 0.5 * det / total,
        });
    }
    // only faces with a free corner matter
    built.retain(|f| f.v.iter().any(|&v| slot[v] != usize::MAX));
    let energy = Energy {
        faces: built,
        slot: &slot,
        lambda: params.lambda,
    };
    let folded_before = count_folded_faces(faces, uv);
    let mut info = FoldoverFreeInfo {
        folded_before,
        folded_after: folded_before,
        min_det_before: energy.min_det(uv),
        ..Default::default()
    };
    info.min_det_after = info.min_det_before;
    if free.is_empty() {
        return Ok(info);
    }
    let mut x = uv.to_vec();
    let d0 = info.min_det_before;
    // the first ε: χ(D⁻, ε) = 0.1 (det J ≈ 1 on a face at its reference area)
    let mut eps = if d0 < 0.1 {
        2.0 * (0.1 * (0.1 - d0)).sqrt()
    } else {
        EPS_FLOOR
    };
    let mut e_old = energy.eval(&x, eps, None);
    let (mut fewest, mut stalled) = (folded_before, 0);
    for _ in 0..params.max_rounds {
        info.rounds += 1;
        let scale = energy.scaling(&x, eps, free.len());
        info.iterations += lbfgs(&energy, &free, &scale, &mut x, eps, params);
        let e_new = energy.eval(&x, eps, None);
        let dmin = energy.min_det(&x);
        info.epsilon = eps;
        let folded = count_folded_faces(faces, &x);
        let valid = dmin > 0.0 && folded == 0;
        let settled = (e_old - e_new).abs() <= 1e-5 * e_new.abs();
        if valid && settled {
            break;
        }
        if folded < fewest {
            (fewest, stalled) = (folded, 0);
        } else {
            stalled += 1;
            if folded > 0 && stalled >= params.stall_rounds {
                break;
            }
        }
        let sigma = (1.0 - e_new / e_old).max(0.1);
        let mu = (1.0 - sigma) * chi(dmin, eps).0;
        eps = if dmin < mu {
            2.0 * (mu * (mu - dmin)).sqrt()
        } else {
            EPS_FLOOR
        };
        e_old = energy.eval(&x, eps, None);
    }
    let folded_after = count_folded_faces(faces, &x);
    if folded_after < folded_before || folded_after == 0 {
        uv.copy_from_slice(&x);
        info.folded_after = folded_after;
        info.min_det_after = energy.min_det(uv);
    }
    Ok(info)
}

/// The smallest ε (det J ≈ 1 on a face at its reference area).
const EPS_FLOOR: f64 = 1e-10;

/// An L-BFGS pair: the step s, the change of the gradient y, and 1/(sᵀy).
type Pair = (Vec<[f64; 2]>, Vec<[f64; 2]>, f64);

/// L-BFGS on E_ε over the free vertices `free` of `x`, with the diagonal scaling `scale`
/// (per free vertex) as its initial inverse Hessian; returns the iterations run.
fn lbfgs(
    energy: &Energy,
    free: &[usize],
    scale: &[f64],
    x: &mut [[f64; 2]],
    eps: f64,
    params: &FoldoverFreeParams,
) -> usize {
    let m = free.len();
    let dot = |a: &[[f64; 2]], b: &[[f64; 2]]| a.iter().zip(b).map(|(p, q)| p[0] * q[0] + p[1] * q[1]).sum::<f64>();
    let mut g = vec![[0.0; 2]; m];
    let mut e = energy.eval(x, eps, Some(&mut g));
    let mut history: VecDeque<Pair> = VecDeque::new();
    let mut g_new = vec![[0.0; 2]; m];
    let mut trial = x.to_vec();
    let mut iterations = 0;
    let mut step0 = 1.0;
    while iterations < params.max_iterations {
        iterations += 1;
        // two-loop recursion, H₀ = γ · scale
        let mut q = g.clone();
        let mut alphas = Vec::with_capacity(history.len());
        for (s, y, rho) in history.iter().rev() {
            let a = rho * dot(s, &q);
            for (qi, yi) in q.iter_mut().zip(y) {
                qi[0] -= a * yi[0];
                qi[1] -= a * yi[1];
            }
            alphas.push(a);
        }
        let gamma = history.back().map_or(1.0, |(s, y, _)| {
            let yhy: f64 = y.iter().zip(scale).map(|(p, h)| h * (p[0] * p[0] + p[1] * p[1])).sum();
            dot(s, y) / yhy
        });
        for (qi, h) in q.iter_mut().zip(scale) {
            qi[0] *= gamma * h;
            qi[1] *= gamma * h;
        }
        for ((s, y, rho), a) in history.iter().zip(alphas.iter().rev()) {
            let b = rho * dot(y, &q);
            for (qi, si) in q.iter_mut().zip(s) {
                qi[0] += (a - b) * si[0];
                qi[1] += (a - b) * si[1];
            }
        }
        // the direction −q; a non-descent one restarts from the scaled gradient
        let mut slope = -dot(&g, &q);
        if !(slope < 0.0) {
            history.clear();
            for ((qi, gi), h) in q.iter_mut().zip(&g).zip(scale) {
                *qi = [gi[0] * h, gi[1] * h];
            }
            slope = -dot(&g, &q);
            if !(slope < 0.0) {
                break;
            }
        }
        // Armijo backtracking
        let mut t = if history.is_empty() { step0 } else { 1.0 };
        let mut accepted = None;
        for _ in 0..40 {
            for (k, &v) in free.iter().enumerate() {
                trial[v] = [x[v][0] - t * q[k][0], x[v][1] - t * q[k][1]];
            }
            let e_trial = energy.eval(&trial, eps, None);
            if e_trial.is_finite() && e_trial <= e + 1e-4 * t * slope {
                accepted = Some(e_trial);
                break;
            }
            t *= 0.5;
        }
        let Some(e_trial) = accepted else {
            break;
        };
        step0 = (2.0 * t).min(1.0);
        energy.eval(&trial, eps, Some(&mut g_new));
        let s: Vec<[f64; 2]> = q.iter().map(|p| [-t * p[0], -t * p[1]]).collect();
        let y: Vec<[f64; 2]> = g_new.iter().zip(&g).map(|(a, b)| [a[0] - b[0], a[1] - b[1]]).collect();
        let sy = dot(&s, &y);
        if sy > 0.0 {
            if history.len() == params.history {
                history.pop_front();
            }
            history.push_back((s, y, 1.0 / sy));
        }
        for &v in free {
            x[v] = trial[v];
        }
        std::mem::swap(&mut g, &mut g_new);
        let decrease = e - e_trial;
        e = e_trial;
        if decrease <= 1e-12 * e.abs() {
            break;
        }
    }
    iterations
}

#[cfg(test)]
mod tests {
    use super::*;
    use shapespace_geometry::primitives;

    /// The equilateral reference: area `area` (det/2), three equal sides, counter-clockwise;
    /// a non-positive area gives the smallest positive one instead of NaN.
    #[test]
    fn the_equilateral_reference_has_the_given_area() {
        for area in [1e-9, 0.3, 7.0] {
            let [e1, e2] = reference_equilateral(area);
            let det = e1[0] * e2[1] - e1[1] * e2[0];
            assert!((0.5 * det / area - 1.0).abs() < 1e-14, "{area}: {det}");
            let len = |v: [f64; 2]| v[0].hypot(v[1]);
            let third = len([e2[0] - e1[0], e2[1] - e1[1]]);
            for l in [len(e2), third] {
                assert!((l / len(e1) - 1.0).abs() < 1e-14, "{area}: sides {} {l}", len(e1));
            }
        }
        let [e1, e2] = reference_equilateral(-1.0);
        assert!(e1[0] > 0.0 && e2[1] > 0.0 && (e1[0] * e2[1]).is_finite());
    }

    /// The flat unit disk of `rings` rings with its boundary flags, laid out by `layout` (an
    /// embedding of the disk).
    fn disk(rings: usize, layout: impl Fn([f64; 2]) -> [f64; 2]) -> (TriMesh, Vec<bool>, Vec<[f64; 2]>) {
        let mesh = primitives::unit_disk(rings);
        let is_boundary = Connectivity::of(&mesh).boundary_vertices(mesh.num_vertices());
        let uv: Vec<[f64; 2]> = mesh.positions.iter().map(|p| layout([p[0], p[1]])).collect();
        assert_eq!(count_folded_faces(&mesh.faces, &uv), 0);
        (mesh, is_boundary, uv)
    }

    /// A five-pointed star: r → r (1 + 0.3 cos 5θ), reflex between the points.
    fn star(p: [f64; 2]) -> [f64; 2] {
        let f = 1.0 + 0.3 * (5.0 * p[1].atan2(p[0])).cos();
        [p[0] * f, p[1] * f]
    }

    fn uniform(state: &mut u64) -> f64 {
        *state ^= *state << 13;
        *state ^= *state >> 7;
        *state ^= *state << 17;
        (*state >> 11) as f64 / (1u64 << 53) as f64
    }

    fn signed_doubled_area(uv: &[[f64; 2]], f: [u32; 3]) -> f64 {
        let [a, b, c] = f.map(|v| uv[v as usize]);
        (b[0] - a[0]) * (c[1] - a[1]) - (b[1] - a[1]) * (c[0] - a[0])
    }

    /// The energy's gradient agrees with central differences, on a folded layout and for ε
    /// large and small.
    #[test]
    fn gradient_matches_differences() {
        let (mesh, fixed, mut uv) = disk(3, star);
        let reference: Vec<_> = mesh
            .faces
            .iter()
            .map(|f| reference_from_surface(f.map(|v| mesh.positions[v as usize]), 0.02).unwrap())
            .collect();
        let mut state = 0x9e37_79b9_7f4a_7c15u64;
        for (v, p) in uv.iter_mut().enumerate() {
            if !fixed[v] {
                p[0] += 0.3 * (uniform(&mut state) - 0.5);
                p[1] += 0.3 * (uniform(&mut state) - 0.5);
            }
        }
        assert!(count_folded_faces(&mesh.faces, &uv) > 0);
        let slot: Vec<usize> = {
            let mut k = 0;
            fixed
                .iter()
                .map(|&b| {
                    if b {
                        usize::MAX
                    } else {
                        k += 1;
                        k - 1
                    }
                })
                .collect()
        };
        let free: Vec<usize> = (0..uv.len()).filter(|&v| !fixed[v]).collect();
        let faces = mesh
            .faces
            .iter()
            .zip(&reference)
            .map(|(f, r)| {
                let det = r[0][0] * r[1][1] - r[0][1] * r[1][0];
                Face {
                    v: f.map(|v| v as usize),
                    s: [[r[1][1] / det, -r[1][0] / det], [-r[0][1] / det, r[0][0] / det]],
                    w: 0.5 * det,
                }
            })
            .collect();
        let energy = Energy {
            faces,
            slot: &slot,
            lambda: 0.7,
        };
        for eps in [1.0, 0.1] {
            let mut g = vec![[0.0; 2]; free.len()];
            energy.eval(&uv, eps, Some(&mut g));
            for (k, &v) in free.iter().enumerate().step_by(3) {
                for d in 0..2 {
                    let h = 1e-6;
                    let mut p = uv.clone();
                    p[v][d] += h;
                    let ep = energy.eval(&p, eps, None);
                    p[v][d] -= 2.0 * h;
                    let em = energy.eval(&p, eps, None);
                    let fd = (ep - em) / (2.0 * h);
                    assert!(
                        (fd - g[k][d]).abs() <= 1e-5 * (1.0 + g[k][d].abs()),
                        "ε {eps}: {fd} vs {}",
                        g[k][d]
                    );
                }
            }
        }
    }

    /// Every interior vertex of a star-shaped patch (its boundary fixed, reflex between the
    /// points, so a Tutte map of it need not embed) thrown to a pseudo-random point of the
    /// inner disk: hundreds of folded faces, none left after the untangling, boundary kept.
    #[test]
    fn scrambled_star_patch_is_untangled() {
        let (mesh, fixed, target) = disk(8, star);
        let mut uv = target.clone();
        let mut state = 0x2545_f491_4f6c_dd1du64;
        for (v, p) in uv.iter_mut().enumerate() {
            if !fixed[v] {
                let r = 0.5 * uniform(&mut state).sqrt();
                let t = uniform(&mut state) * std::f64::consts::TAU;
                *p = [r * t.cos(), r * t.sin()];
            }
        }
        // references: the flat disk's triangles with the star layout's areas
        let reference: Vec<_> = mesh
            .faces
            .iter()
            .map(|&f| {
                let area = 0.5 * signed_doubled_area(&target, f);
                reference_from_surface(f.map(|v| mesh.positions[v as usize]), area).unwrap()
            })
            .collect();
        let before = count_folded_faces(&mesh.faces, &uv);
        assert!(before > 100, "{before}");
        let input = uv.clone();
        let info =
            untangle_foldover_free(&mesh.faces, &fixed, &reference, &mut uv, &FoldoverFreeParams::default()).unwrap();
        assert_eq!(info.folded_before, before);
        assert_eq!(info.folded_after, 0, "{info:?}");
        assert_eq!(count_folded_faces(&mesh.faces, &uv), 0);
        assert!(info.min_det_after > 0.0, "{info:?}");
        for v in (0..uv.len()).filter(|&v| fixed[v]) {
            assert_eq!(uv[v], input[v]);
        }
    }

    /// A fold-free input: with its own faces as references it is a minimum and does not move;
    /// perturbed by 3 % of an edge (still embedded), it returns to the reference layout
    /// without a fold on the way out.
    #[test]
    fn embedded_input_stays_and_returns_to_its_reference() {
        let (mesh, fixed, target) = disk(6, star);
        let reference: Vec<_> = mesh
            .faces
            .iter()
            .map(|f| {
                let [a, b, c] = f.map(|v| target[v as usize]);
                reference_from_layout(a, b, c).unwrap()
            })
            .collect();
        let params = FoldoverFreeParams::default();
        let mut uv = target.clone();
        let info = untangle_foldover_free(&mesh.faces, &fixed, &reference, &mut uv, &params).unwrap();
        assert_eq!((info.folded_before, info.folded_after), (0, 0));
        let moved = uv
            .iter()
            .zip(&target)
            .map(|(p, q)| (p[0] - q[0]).hypot(p[1] - q[1]))
            .fold(0.0, f64::max);
        assert!(moved < 1e-12, "{moved}");
        // perturbed by 3 % of the shortest edge at its vertex
        let mut state = 0x0123_4567_89ab_cdefu64;
        let conn = Connectivity::of(&mesh);
        let neighbors = conn.vertex_neighbors(mesh.num_vertices());
        for v in (0..uv.len()).filter(|&v| !fixed[v]) {
            let h = neighbors[v]
                .iter()
                .map(|&u| (target[u as usize][0] - target[v][0]).hypot(target[u as usize][1] - target[v][1]))
                .fold(f64::INFINITY, f64::min);
            let t = uniform(&mut state) * std::f64::consts::TAU;
            uv[v] = [target[v][0] + 0.03 * h * t.cos(), target[v][1] + 0.03 * h * t.sin()];
        }
        assert_eq!(count_folded_faces(&mesh.faces, &uv), 0);
        let mut out = uv.clone();
        let info = untangle_foldover_free(&mesh.faces, &fixed, &reference, &mut out, &params).unwrap();
        assert_eq!(info.folded_after, 0);
        assert_eq!(count_folded_faces(&mesh.faces, &out), 0);
        let error = out
            .iter()
            .zip(&target)
            .map(|(p, q)| (p[0] - q[0]).hypot(p[1] - q[1]))
            .fold(0.0, f64::max);
        let start = uv
            .iter()
            .zip(&target)
            .map(|(p, q)| (p[0] - q[0]).hypot(p[1] - q[1]))
            .fold(0.0, f64::max);
        assert!(error < 1e-3 * start, "{error} from {start}: {info:?}");
    }
}
