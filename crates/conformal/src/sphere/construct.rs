//! The two linear solves of the spherical conformal map: a map of the punctured surface to
//! the plane, then a Dirichlet problem on the cap around the puncture seen from the antipode.
//!
//! **Pass 1, dipole** [Angenent, Haker, Tannenbaum & Kikinis 1999; Haker et al. 2000]: the
//! conformal map z : M \ {p} → ℂ with a simple pole at p solves
//! $$ \Delta z = \Big(\frac{\partial}{\partial x} - i\frac{\partial}{\partial y}\Big)\delta_p, $$
//! with (x, y) a positively oriented frame of the face containing p. In finite elements the
//! right-hand side is b_k = ∂_x φ_k − i ∂_y φ_k at the three corners of that face (φ_k the hat
//! functions; Σ_k b_k = 0, so the singular Laplacian of the closed surface is solvable after
//! pinning one vertex). The discrete source has the dipole moment of 1/(ζ − p) and no
//! antiholomorphic moment (Σ_k b_k x̄_k = 0 by linear precision), so away from p the solution
//! is z ≈ 1/(2π(ζ − p)): no global quasi-conformal error, only a local one within a few rings
//! of p.
//!
//! **Pass 1, puncture triangle** (for comparison; Choi, Lam & Lui 2015, FLASH): the face's
//! corners are fixed at a similar triangle in the plane and the rest is harmonic. The three
//! corner values decide the dipole moments of x and y separately; unless the face's
//! neighbourhood is symmetric their combination carries an antiholomorphic part, a constant
//! Beltrami coefficient of the whole image (measured in the decision record).
//!
//! **Pass 2, Schwarz** (default): pass 1 is accurate only to first order in the edge length
//! everywhere (the discrete dipole's error is a global antiholomorphic term of relative size
//! O(h)), so no local correction near p can remove it. With z_c the point that Möbius centering
//! sends opposite to p and u = (z − z_c)/r₀ (r₀ the area-weighted median of |z − z_c|), the
//! south chart {|u| < 2} holds u and the north chart {|u| > ½} holds w = 1/u. The alternating
//! Schwarz method [Schwarz 1870; Lions 1988] solves the Dirichlet problem of one chart with
//! boundary values from the other through w = 1/u, factorizing each chart once, in pass 1's
//! elimination order restricted to it (no ordering of its own: 8–18 % less CPU time for the
//! whole map of a 163,842-vertex icosphere or ellipsoid, `sphere_map_bench`). A fixed point is
//! discrete harmonic in both charts; in the continuum u and 1/u both harmonic on the overlap
//! forces u to be (anti)holomorphic, i.e. conformal, and neither chart contains a singularity,
//! so the error is that of a smooth Dirichlet problem: second order (measured on icospheres and
//! ellipsoids, `tests/sphere.rs`). The transient dies in 2–4 alternations; after it, every
//! alternation moves the map by the same small step along the Möbius maps (discrete Möbius maps
//! are fixed points only to O(h²)), which the normalization removes, so the iteration stops when
//! the change stops shrinking.
//!
//! **Pass 2, the cap** (for comparison): the vertices with |u| > 1 are recomputed once from
//! the values of pass 1 on the rest. It removes the local error near p but keeps pass 1's
//! global first-order error.

use crate::error::ConformalError;
use crate::intrinsic::{next, prev, IntrinsicTriangulation};
use crate::linsolve::{restricted_laplacian, restricted_laplacian_in_order};
use crate::sphere::mobius::{Complex, Homogeneous};

/// How the punctured surface is mapped to the plane in pass 1.
#[derive(Clone, Copy, Debug, PartialEq, Eq, serde::Serialize)]
#[serde(rename_all = "kebab-case")]
pub enum PunctureMethod {
    /// A dipole source in the puncture face (default).
    Dipole,
    /// The puncture face's corners fixed at a similar planar triangle (FLASH's first step).
    Triangle,
}

/// What replaces pass 1's values near the puncture.
#[derive(Clone, Copy, Debug, PartialEq, Eq, serde::Serialize)]
#[serde(rename_all = "kebab-case")]
pub enum Correction {
    /// Pass 1 only.
    None,
    /// One Dirichlet solve on the half of the surface nearest to the puncture.
    Cap,
    /// Alternating Dirichlet solves on two overlapping charts (default).
    Schwarz,
}

/// The result of the two passes, before normalization.
pub(crate) struct Planar {
    /// Homogeneous coordinates per vertex (ζ = u/v), #V.
    pub hom: Vec<Homogeneous>,
    /// Number of vertices recomputed in pass 2 (the larger chart for `Schwarz`).
    pub cap_vertices: usize,
    /// Alternations of the Schwarz iteration.
    pub iterations: usize,
    /// Largest change of a chart coordinate in the last alternation.
    pub last_change: f64,
}

/// Inner radius of the overlap of the two charts of the Schwarz iteration, relative to the
/// area-weighted median radius (the outer radius is its inverse).
pub const SCHWARZ_INNER_RADIUS: f64 = 0.5;
/// Alternations of the Schwarz iteration at most.
pub const SCHWARZ_MAX_ITERATIONS: usize = 30;
/// The Schwarz iteration stops when an alternation changes the charts by more than this
/// fraction of the previous change (the drift along the Möbius maps: module docs, pass 2).
pub const SCHWARZ_STALL_RATIO: f64 = 0.7;
/// The Schwarz iteration stops when no chart coordinate (of modulus ≤ 1/[`SCHWARZ_INNER_RADIUS`])
/// changes by more than this.
pub const SCHWARZ_TOLERANCE: f64 = 1e-12;

/// A Dirichlet problem of the Laplacian on the vertices with `inside[v]`, factorized once.
struct Chart {
    index: Vec<u32>,
    members: Vec<u32>,
    solver: crate::linsolve::SpdSolver,
    coupling: Vec<crate::linsolve::Coupling>,
}

impl Chart {
    /// The chart of the vertices with `inside[v]`, its unknowns eliminated in the order of
    /// `ranks` (a rank per vertex).
    fn new(tri: &IntrinsicTriangulation, inside: &[bool], ranks: &[u32], what: &str) -> Result<Self, ConformalError> {
        let mut index = vec![u32::MAX; inside.len()];
        let mut members = Vec::new();
        for (v, &i) in inside.iter().enumerate() {
            if i {
                index[v] = members.len() as u32;
                members.push(v as u32);
            }
        }
        let mut order: Vec<usize> = (0..members.len()).collect();
        order.sort_by_key(|&k| (ranks[members[k] as usize], members[k]));
        let (solver, coupling) = restricted_laplacian_in_order(tri, &index, members.len(), Some(&order), what)?;
        Ok(Chart {
            index,
            members,
            solver,
            coupling,
        })
    }

    /// Solves with boundary values `outside(v)` and writes the result into `values`.
    fn solve(
        &self,
        values: &mut [Complex],
        outside: impl Fn(usize) -> Complex,
        stage: &'static str,
    ) -> Result<f64, ConformalError> {
        let m = self.members.len();
        let mut rhs = vec![vec![0.0; m]; 2];
        for &(row, v, w) in &self.coupling {
            let b = outside(v as usize);
            rhs[0][row as usize] += w * b.re;
            rhs[1][row as usize] += w * b.im;
        }
        self.solver.solve_sequential(&mut rhs);
        let mut change: f64 = 0.0;
        for (i, &v) in self.members.iter().enumerate() {
            let x = Complex::new(rhs[0][i], rhs[1][i]);
            if !(x.re.is_finite() && x.im.is_finite()) {
                return Err(ConformalError::NonFinite {
                    stage,
                    vertex: v as usize,
                });
            }
            change = change.max((x - values[v as usize]).abs());
            values[v as usize] = x;
        }
        debug_assert!(self.index.len() == values.len());
        Ok(change)
    }
}

/// The alternating Schwarz method on two charts of the sphere [Schwarz 1870; Lions 1988]:
/// with u = (z − z_c)/r₀ (r₀ the area-weighted median of |z − z_c|), the south chart
/// {|u| < 1/ρ} holds u and the north chart {|u| > ρ} holds w = 1/u, ρ =
/// [`SCHWARZ_INNER_RADIUS`]. Each alternation solves the Dirichlet problem of one chart with
/// boundary values from the other (through w = 1/u), starting from pass 1. A fixed point is
/// discrete harmonic in both charts; in the continuum, u and 1/u both harmonic on the overlap
/// forces u to be (anti)holomorphic, i.e. conformal, and neither chart contains a singularity,
/// so the discretization error is that of a smooth Dirichlet problem. Each chart eliminates its
/// unknowns in the order of `ranks` (pass 1's elimination rank per vertex).
pub(crate) fn schwarz(
    tri: &IntrinsicTriangulation,
    z: &[Complex],
    zc: Complex,
    masses: &[f64],
    ranks: &[u32],
) -> Result<Planar, ConformalError> {
    let n = z.len();
    let r0 = median_radius(z, zc, masses);
    let mut u: Vec<Complex> = z.iter().map(|&x| (x - zc).scale(1.0 / r0)).collect();
    let mut w: Vec<Complex> = u.iter().map(|x| x.recip()).collect();
    let south_in: Vec<bool> = u.iter().map(|x| x.abs() < 1.0 / SCHWARZ_INNER_RADIUS).collect();
    let north_in: Vec<bool> = u.iter().map(|x| x.abs() > SCHWARZ_INNER_RADIUS).collect();
    // a chart that is empty or has no boundary (tiny meshes): pass 1 as it is
    let proper = |inside: &[bool]| inside.iter().any(|&b| b) && !inside.iter().all(|&b| b);
    if !proper(&south_in) || !proper(&north_in) {
        return cap_correction(tri, z, zc, masses, false);
    }
    // (the two factorizations are independent: on two cores they overlap; each eliminates its
    // unknowns in pass 1's order, restricted to it)
    let (south, north) = rayon::join(
        || Chart::new(tri, &south_in, ranks, "the south chart's Laplacian"),
        || Chart::new(tri, &north_in, ranks, "the north chart's Laplacian"),
    );
    let (south, north) = (south?, north?);
    let mut iterations = 0;
    let mut last_change = f64::INFINITY;
    while iterations < SCHWARZ_MAX_ITERATIONS {
        iterations += 1;
        let cn = north.solve(&mut w, |v| u[v].recip(), "north chart")?;
        let cs = south.solve(&mut u, |v| w[v].recip(), "south chart")?;
        let change = cn.max(cs);
        // after the transient the alternations keep moving the map by a constant small step
        // along the Möbius maps (discrete Möbius maps are fixed points only to O(h²)): stop
        // when the change no longer shrinks
        let stalled = iterations >= 2 && change > SCHWARZ_STALL_RATIO * last_change;
        last_change = change;
        if change <= SCHWARZ_TOLERANCE || stalled {
            break;
        }
    }
    let hom = (0..n)
        .map(|v| {
            if south_in[v] && (!north_in[v] || u[v].abs() <= 1.0) {
                [u[v], Complex::new(1.0, 0.0)]
            } else {
                [Complex::new(1.0, 0.0), w[v]]
            }
        })
        .collect();
    Ok(Planar {
        hom,
        cap_vertices: south.members.len().max(north.members.len()),
        iterations,
        last_change,
    })
}

/// The area-weighted median of |z − z_c|.
fn median_radius(z: &[Complex], zc: Complex, masses: &[f64]) -> f64 {
    let n = z.len();
    let r: Vec<f64> = z.iter().map(|&x| (x - zc).abs()).collect();
    let mut order: Vec<usize> = (0..n).collect();
    order.sort_by(|&a, &b| r[a].total_cmp(&r[b]));
    let total: f64 = masses.iter().sum();
    let mut acc = 0.0;
    for &v in &order {
        acc += masses[v];
        if acc >= 0.5 * total {
            return r[v];
        }
    }
    r[order[n - 1]]
}

/// Layout of intrinsic face f: corner k of the face (vertex `tail[3f + k]`) at `p[k]`,
/// counter-clockwise, and its area.
fn layout(tri: &IntrinsicTriangulation, f: usize) -> ([[f64; 2]; 3], f64) {
    let l_ab = tri.length[3 * f];
    let l_bc = tri.length[3 * f + 1];
    let l_ca = tri.length[3 * f + 2];
    let area = tri.face_area(f);
    let xc = (l_ab * l_ab + l_ca * l_ca - l_bc * l_bc) / (2.0 * l_ab);
    let yc = 2.0 * area / l_ab;
    ([[0.0, 0.0], [l_ab, 0.0], [xc, yc]], area)
}

/// The vertex farthest (in 3D) from the corners of face `f`.
pub(crate) fn farthest_vertex(positions: &[[f64; 3]], corners: [u32; 3]) -> u32 {
    let c = positions[corners[0] as usize];
    let mut best = (0usize, -1.0);
    for (v, p) in positions.iter().enumerate() {
        let d = (p[0] - c[0]).powi(2) + (p[1] - c[1]).powi(2) + (p[2] - c[2]).powi(2);
        if d > best.1 {
            best = (v, d);
        }
    }
    best.0 as u32
}

/// Pass 1: z per vertex (#V), with z = 0 at `pin` (dipole) or the corners of `face` at a
/// similar triangle (triangle method), and each vertex's rank in the elimination order of its
/// factorization (the fixed vertices last), which the charts of [`schwarz`] reuse.
pub(crate) fn punctured_plane_map(
    tri: &IntrinsicTriangulation,
    face: usize,
    pin: u32,
    method: PunctureMethod,
) -> Result<(Vec<Complex>, Vec<u32>), ConformalError> {
    let n = tri.num_vertices;
    let corners = [tri.tail[3 * face], tri.tail[3 * face + 1], tri.tail[3 * face + 2]];
    let (p, area) = layout(tri, face);
    let fixed: Vec<(u32, Complex)> = match method {
        PunctureMethod::Dipole => vec![(pin, Complex::default())],
        PunctureMethod::Triangle => (0..3).map(|k| (corners[k], Complex::new(p[k][0], p[k][1]))).collect(),
    };
    let mut index = vec![0u32; n];
    let mut value = vec![None; n];
    for &(v, z) in &fixed {
        value[v as usize] = Some(z);
    }
    let mut m = 0u32;
    for v in 0..n {
        if value[v].is_some() {
            index[v] = u32::MAX;
        } else {
            index[v] = m;
            m += 1;
        }
    }
    let (solver, coupling) = restricted_laplacian(tri, &index, m as usize, "the punctured sphere's Laplacian")?;
    let mut ranks = vec![u32::MAX; n];
    let unknowns: Vec<u32> = (0..n as u32).filter(|&v| index[v as usize] != u32::MAX).collect();
    for (rank, i) in solver.elimination_order().into_iter().enumerate() {
        ranks[unknowns[i] as usize] = rank as u32;
    }
    let mut rhs = vec![vec![0.0; m as usize]; 2];
    match method {
        PunctureMethod::Dipole => {
            // ∇φ_k = rot90(opposite edge)/(2A), counter-clockwise; b_k = ∂x φ_k − i ∂y φ_k
            for k in 0..3 {
                let (q, r) = (p[(k + 1) % 3], p[(k + 2) % 3]);
                let e = [r[0] - q[0], r[1] - q[1]];
                let g = [-e[1] / (2.0 * area), e[0] / (2.0 * area)];
                let i = index[corners[k] as usize];
                if i != u32::MAX {
                    rhs[0][i as usize] += g[0];
                    rhs[1][i as usize] -= g[1];
                }
            }
        }
        PunctureMethod::Triangle => {
            for &(row, v, w) in &coupling {
                if let Some(z) = value[v as usize] {
                    rhs[0][row as usize] += w * z.re;
                    rhs[1][row as usize] += w * z.im;
                }
            }
        }
    }
    solver.solve_sequential(&mut rhs);
    let mut z = vec![Complex::default(); n];
    for v in 0..n {
        z[v] = match value[v] {
            Some(c) => c,
            None => {
                let i = index[v] as usize;
                Complex::new(rhs[0][i], rhs[1][i])
            }
        };
        if !(z[v].re.is_finite() && z[v].im.is_finite()) {
            return Err(ConformalError::NonFinite {
                stage: "punctured plane map",
                vertex: v,
            });
        }
    }
    Ok((z, ranks))
}

/// Pass 2 (module docs): homogeneous coordinates (#V) from the pass-1 map `z`, its centre
/// `zc` and the vertex masses; the cap is recomputed when `correct` is set.
pub(crate) fn cap_correction(
    tri: &IntrinsicTriangulation,
    z: &[Complex],
    zc: Complex,
    masses: &[f64],
    correct: bool,
) -> Result<Planar, ConformalError> {
    let n = z.len();
    let r: Vec<f64> = z.iter().map(|&x| (x - zc).abs()).collect();
    let median = median_radius(z, zc, masses);
    let in_cap: Vec<bool> = (0..n).map(|v| correct && r[v] > median).collect();
    let mut hom: Vec<Homogeneous> = (0..n)
        .map(|v| {
            if r[v] > median {
                [Complex::new(1.0, 0.0), (z[v] - zc).recip()]
            } else {
                [z[v] - zc, Complex::new(1.0, 0.0)]
            }
        })
        .collect();
    let mut index = vec![u32::MAX; n];
    let mut m = 0u32;
    for v in 0..n {
        if in_cap[v] {
            index[v] = m;
            m += 1;
        }
    }
    if m == 0 {
        return Ok(Planar {
            hom,
            cap_vertices: 0,
            iterations: 0,
            last_change: 0.0,
        });
    }
    let (solver, coupling) = restricted_laplacian(tri, &index, m as usize, "the cap's Laplacian")?;
    let mut rhs = vec![vec![0.0; m as usize]; 2];
    for &(row, v, w) in &coupling {
        let wv = (z[v as usize] - zc).recip();
        rhs[0][row as usize] += w * wv.re;
        rhs[1][row as usize] += w * wv.im;
    }
    solver.solve_sequential(&mut rhs);
    for v in 0..n {
        if in_cap[v] {
            let i = index[v] as usize;
            let w = Complex::new(rhs[0][i], rhs[1][i]);
            if !(w.re.is_finite() && w.im.is_finite()) {
                return Err(ConformalError::NonFinite {
                    stage: "cap correction",
                    vertex: v,
                });
            }
            hom[v] = [Complex::new(1.0, 0.0), w];
        }
    }
    Ok(Planar {
        hom,
        cap_vertices: m as usize,
        iterations: 1,
        last_change: 0.0,
    })
}

/// The puncture face chosen automatically: among the intrinsic faces whose corners all lie on
/// the 64 mesh faces nearest to the surface's area centroid, the one closest to equilateral
/// (largest 4√3·A / Σ l²). Near the centroid keeps the puncture off the ends of protrusions,
/// whose far side would otherwise be crowded together in pass 1.
pub(crate) fn auto_puncture(tri: &IntrinsicTriangulation, positions: &[[f64; 3]], faces: &[[u32; 3]]) -> usize {
    let mut centroid = [0.0; 3];
    let mut total = 0.0;
    let fc: Vec<[f64; 3]> = faces
        .iter()
        .map(|f| {
            let p = f.map(|v| positions[v as usize]);
            let a = shapespace_geometry::quantities::triangle_area(p[0], p[1], p[2]);
            let c = [0, 1, 2].map(|d| (p[0][d] + p[1][d] + p[2][d]) / 3.0);
            for d in 0..3 {
                centroid[d] += a * c[d];
            }
            total += a;
            c
        })
        .collect();
    for c in &mut centroid {
        *c /= total;
    }
    let dist = |c: &[f64; 3]| (0..3).map(|d| (c[d] - centroid[d]).powi(2)).sum::<f64>();
    let mut order: Vec<usize> = (0..faces.len()).collect();
    let k = 64.min(faces.len());
    order.select_nth_unstable_by(k - 1, |&a, &b| dist(&fc[a]).total_cmp(&dist(&fc[b])));
    let mut near = vec![false; tri.num_vertices];
    for &f in &order[..k] {
        for &v in &faces[f] {
            near[v as usize] = true;
        }
    }
    let nearest = order[..k]
        .iter()
        .copied()
        .min_by(|&a, &b| dist(&fc[a]).total_cmp(&dist(&fc[b])))
        .unwrap_or(0);
    let quality = |f: usize| {
        let l = [tri.length[3 * f], tri.length[3 * f + 1], tri.length[3 * f + 2]];
        4.0 * 3f64.sqrt() * tri.face_area(f) / (l[0] * l[0] + l[1] * l[1] + l[2] * l[2])
    };
    let mut best: Option<(usize, f64)> = None;
    for f in 0..tri.num_faces() {
        let h = 3 * f as u32;
        if [h, next(h), prev(h)]
            .iter()
            .all(|&g| near[tri.tail[g as usize] as usize])
        {
            let q = quality(f);
            if best.is_none_or(|(_, bq)| q > bq) {
                best = Some((f, q));
            }
        }
    }
    match best {
        Some((f, _)) => f,
        None => {
            // an intrinsic face at a corner of the nearest mesh face
            let v = faces[nearest][0];
            (0..tri.num_faces())
                .find(|&f| (0..3).any(|k| tri.tail[3 * f + k] == v))
                .unwrap_or(0)
        }
    }
}
