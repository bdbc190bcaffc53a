//! Conformal maps of closed genus-0 surfaces onto the unit sphere S².
//!
//! By the uniformization theorem a closed genus-0 surface M is conformally equivalent to S²,
//! uniquely up to the Möbius maps of S² [Su et al. 2015, §4.3, Theorem 6]. The construction is
//! linear: three sparse Cholesky factorizations of the intrinsic Delaunay Laplacian (the whole
//! surface, then two overlapping charts) and a few solves (decision
//! `docs/decisions/0020-spherical-conformal-map.md`):
//!
//! 1. **Puncture.** A face p near the surface's area centroid (off the ends of protrusions);
//!    the dipole problem Δz = (∂_x − i∂_y)δ_p gives the conformal map z : M \ {p} → ℂ with a
//!    simple pole at p ([`construct`]).
//! 2. **Schwarz.** Two overlapping charts, u around the side opposite to p and w = 1/u around p,
//!    are solved alternately as Dirichlet problems with boundary values from each other until
//!    the change stops shrinking (2–4 alternations): no chart holds a singularity, so the map is
//!    second-order accurate where pass 1 alone is first order ([`construct`]).
//! 3. **Sphere.** Inverse stereographic projection of the homogeneous coordinates [u : 1] or
//!    [1 : w] ([`mobius`]); the orientation is made positive (outward normals) by conjugation.
//! 4. **Normalization.** Three markers p₁, p₂, p₃ ↦ 0, 1, ∞ of the extended plane (the south
//!    pole, (1, 0, 0), the north pole), or Möbius centering: the boost that puts the centre of
//!    mass of the pushed-forward area, Σ_v ν_v x_v / Σ ν_v with ν_v the barycentric vertex
//!    areas, at the origin, found by Newton's method (the derivative of the centroid along a
//!    boost β is I − C, C = Σ ν x xᵀ / Σ ν; Baden, Crane & Kazhdan 2018, "Möbius
//!    registration"); the rotation left over is fixed by two markers when given.
//! 5. **Fold repair.** The rare folded slivers are repaired in a local stereographic chart
//!    ([`repair`](self) module docs; counted in [`SphereMapInfo::fold_repairs`]).
//! 6. **Densities.** Per face μ_f = A₃(f) / A_chord(f) with the surface scaled to area 4π and
//!    the image face taken as its flat chordal triangle; per vertex the conformal factor
//!    e^{2λ_v} = one-ring A₃ / one-ring A_chord; distortions as for the disk ([`quality`]).

pub mod construct;
pub mod mobius;
pub mod quality;
pub mod repair;

use std::time::Instant;

use rayon::prelude::*;
use serde::Serialize;
use shapespace_geometry::topology::{check_coordinate_range, mesh_report, MeshClass};
use shapespace_geometry::TriMesh;

pub use construct::{Correction, PunctureMethod};
pub use mobius::{Complex, Homogeneous, SphereMobius};
pub use quality::{orientation_on_sphere, sphere_face_distortions};

use crate::error::ConformalError;
use crate::intrinsic::IntrinsicTriangulation;
use crate::quality::{summarize, QualitySummary};

/// Largest norm of the pushed-forward centroid accepted by Möbius centering.
pub const CENTERING_TOLERANCE: f64 = 1e-12;
/// Image triangles whose longest edge on S² is below this (about 5000 ulps of a unit
/// coordinate) are at the resolution of f64: a fold among them is reported as
/// [`ConformalError::OutOfRange`].
pub const SPHERE_RESOLUTION: f64 = 1e-12;
/// Newton iterations of Möbius centering at most.
pub const CENTERING_MAX_ITERATIONS: usize = 100;

/// How the map is normalized (the Möbius group of S² acts on the conformal maps).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize)]
#[serde(rename_all = "kebab-case")]
pub enum SphereNormalization {
    /// Vertices p₁, p₂, p₃ ↦ 0, 1, ∞ of the extended plane: the south pole (0, 0, −1), the
    /// point (1, 0, 0) on the equator and the north pole (0, 0, 1), exactly.
    ThreeMarkers([u32; 3]),
    /// Möbius centering: the centroid of the pushed-forward vertex areas at the origin (to
    /// [`CENTERING_TOLERANCE`]). With `rotation: Some([a, b])`, a goes to the south pole and b
    /// onto the half meridian {y = 0, x > 0}; without, the rotation is the construction's
    /// (deterministic, but depending on the puncture).
    Centered { rotation: Option<[u32; 2]> },
}

/// Parameters of [`sphere_map`].
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct SphereMapParams {
    /// Laplacian of the intrinsic Delaunay triangulation (default true; false: the plain
    /// cotangent Laplacian, for comparisons).
    pub intrinsic_delaunay: bool,
    /// Pass 1 (default [`PunctureMethod::Dipole`]).
    pub method: PunctureMethod,
    /// Pass 2 (default [`Correction::Schwarz`]).
    pub correction: Correction,
    /// Default: centering without rotation markers.
    pub normalization: SphereNormalization,
    /// Repair the few folded original faces in a local stereographic chart (default true;
    /// [`crate::fold_repair::local`]). Without it a fold is an error.
    pub repair_folds: bool,
}

impl Default for SphereMapParams {
    fn default() -> Self {
        SphereMapParams {
            intrinsic_delaunay: true,
            method: PunctureMethod::Dipole,
            correction: Correction::Schwarz,
            normalization: SphereNormalization::Centered { rotation: None },
            repair_folds: true,
        }
    }
}

/// Stage timings of [`sphere_map`], seconds.
#[derive(Clone, Debug, Default, PartialEq, Serialize)]
pub struct SphereMapTimings {
    /// Checks, intrinsic triangulation, flips.
    pub setup: f64,
    /// Pass 1 (factorization and solve).
    pub puncture_solve: f64,
    /// Pass 2.
    pub cap_solve: f64,
    /// Orientation, normalization.
    pub normalize: f64,
    /// Distortions, densities, factors.
    pub finish: f64,
    /// Everything.
    pub total: f64,
}

/// What [`sphere_map`] did.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct SphereMapInfo {
    /// Pass 1's construction.
    pub method: PunctureMethod,
    /// Pass 2's construction.
    pub correction: Correction,
    /// The corners of the puncture face (an intrinsic face).
    pub puncture_vertices: [u32; 3],
    /// The vertex farthest from the puncture (pinned to z = 0 by the dipole solve).
    pub far_vertex: u32,
    /// Vertices recomputed by pass 2 (the larger chart of the Schwarz iteration).
    pub cap_vertices: usize,
    /// Alternations of the Schwarz iteration (1 for the cap, 0 without pass 2).
    pub schwarz_iterations: usize,
    /// Largest change of a chart coordinate in the last alternation.
    pub schwarz_last_change: f64,
    /// Intrinsic edge flips.
    pub intrinsic_flips: usize,
    /// The normalization applied.
    pub normalization: SphereNormalization,
    /// The Möbius map from the construction's homogeneous coordinates to the result (before
    /// the rotation; the vertices moved by the fold repair are off it).
    pub mobius: SphereMobius,
    /// The rotation applied after `mobius` (rows of the matrix; identity without rotation
    /// markers).
    pub rotation: [[f64; 3]; 3],
    /// Newton iterations of Möbius centering (0 for three markers).
    pub centering_iterations: usize,
    /// Vertex moves of the fold repair (0 when the map has no fold).
    pub fold_repairs: usize,
    /// |Σ ν_v x_v| / Σ ν_v of the result (any normalization).
    pub centroid_norm: f64,
    /// Stage timings.
    pub timings: SphereMapTimings,
}

/// A conformal map onto the unit sphere with its densities.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct SphereMap {
    /// Image of each vertex on S², #V.
    pub positions: Vec<[f64; 3]>,
    /// λ per vertex, #V: e^{2λ_v} = (3D one-ring area, surface scaled to area 4π) / (one-ring
    /// area of the chordal image triangles).
    pub conformal_factor: Vec<f64>,
    /// μ per face, #F: 3D area (scaled to 4π) / chordal image area; positive and finite.
    pub face_densities: Vec<f64>,
    /// The factor s applied to 3D lengths to reach total area 4π (s² = 4π / area).
    pub scale: f64,
    /// Construction, normalization, timings.
    pub info: SphereMapInfo,
    /// Distortion statistics (chordal image triangles).
    pub quality: QualitySummary,
}

/// Checks that `mesh` is a closed genus-0 surface the map can take: one component, manifold,
/// consistently oriented, χ = 2, every vertex used, coordinates in range.
pub fn check_sphere(mesh: &TriMesh) -> Result<(), ConformalError> {
    mesh.validate()?;
    if mesh.faces.is_empty() {
        return Err(ConformalError::NotSphere {
            reason: "the mesh has no faces".into(),
        });
    }
    check_coordinate_range(mesh)?;
    let r = mesh_report(mesh)?;
    if r.classification.class != MeshClass::Sphere {
        let reason = if r.classification.class == MeshClass::Disk {
            "a disk (one boundary loop): use the disk map".to_string()
        } else {
            r.classification.reasons.join("; ")
        };
        return Err(ConformalError::NotSphere { reason });
    }
    if r.num_unreferenced_vertices > 0 {
        return Err(ConformalError::NotSphere {
            reason: format!(
                "{} vertices are used by no face (first: {}); `shapespace prepare` removes them",
                r.num_unreferenced_vertices,
                r.first_unreferenced_vertices.first().copied().unwrap_or(0)
            ),
        });
    }
    Ok(())
}

/// The fast test behind [`sphere_map`]'s check (the triangulation is already manifold and
/// consistently oriented): closed, every vertex used, one component, χ = 2.
fn is_sphere(tri: &IntrinsicTriangulation, faces: &[[u32; 3]]) -> bool {
    let n = tri.num_vertices;
    if tri.twin.contains(&crate::intrinsic::NONE) {
        return false;
    }
    let mut used = vec![false; n];
    let mut parent: Vec<u32> = (0..n as u32).collect();
    for f in faces {
        for k in 0..3 {
            used[f[k] as usize] = true;
            shapespace_geometry::topology::union(&mut parent, f[k], f[(k + 1) % 3]);
        }
    }
    let components = (0..n as u32)
        .filter(|&v| shapespace_geometry::topology::find(&mut parent, v) == v)
        .count();
    let chi = n as i64 - (3 * faces.len() / 2) as i64 + faces.len() as i64;
    used.iter().all(|&u| u) && components == 1 && chi == 2
}

/// First and second moments of points on S²: Σ m x and Σ m x xᵀ.
type Moments = ([f64; 3], [[f64; 3]; 3]);

/// Σ m_v x_v and Σ m_v x_v x_vᵀ over the images `t(hom)`, in fixed-size chunks summed in
/// order (deterministic).
fn moments(t: &SphereMobius, hom: &[Homogeneous], masses: &[f64]) -> Option<Moments> {
    let parts: Vec<Option<Moments>> = hom
        .par_chunks(4096)
        .zip(masses.par_chunks(4096))
        .map(|(hs, ms)| {
            let mut c = [0.0; 3];
            let mut cov = [[0.0; 3]; 3];
            for (h, &m) in hs.iter().zip(ms) {
                let x = mobius::to_sphere(t.apply(*h))?;
                for i in 0..3 {
                    c[i] += m * x[i];
                    for j in 0..3 {
                        cov[i][j] += m * x[i] * x[j];
                    }
                }
            }
            Some((c, cov))
        })
        .collect();
    let mut c = [0.0; 3];
    let mut cov = [[0.0; 3]; 3];
    for p in parts {
        let (pc, pcov) = p?;
        for i in 0..3 {
            c[i] += pc[i];
            for j in 0..3 {
                cov[i][j] += pcov[i][j];
            }
        }
    }
    Some((c, cov))
}

/// Solves the 3 × 3 system A x = b by Cramer's rule (`None` when singular).
fn solve3(a: [[f64; 3]; 3], b: [f64; 3]) -> Option<[f64; 3]> {
    let det = |m: [[f64; 3]; 3]| {
        m[0][0] * (m[1][1] * m[2][2] - m[1][2] * m[2][1]) - m[0][1] * (m[1][0] * m[2][2] - m[1][2] * m[2][0])
            + m[0][2] * (m[1][0] * m[2][1] - m[1][1] * m[2][0])
    };
    let d = det(a);
    if !(d.abs() > 1e-300) {
        return None;
    }
    let mut x = [0.0; 3];
    for k in 0..3 {
        let mut m = a;
        for i in 0..3 {
            m[i][k] = b[i];
        }
        x[k] = det(m) / d;
    }
    x.iter().all(|v| v.is_finite()).then_some(x)
}

/// Möbius centering of the points `hom` with weights `masses` (module docs, step 4): the
/// Möbius map and the Newton iterations used.
pub fn mobius_centering(hom: &[Homogeneous], masses: &[f64]) -> Result<(SphereMobius, usize), ConformalError> {
    let total: f64 = masses.iter().sum();
    let nonfinite = || ConformalError::NonFinite {
        stage: "Möbius centering",
        vertex: 0,
    };
    let eval = |t: &SphereMobius| -> Option<Moments> {
        let (c, cov) = moments(t, hom, masses)?;
        Some((c.map(|x| x / total), cov.map(|r| r.map(|x| x / total))))
    };
    let norm = |c: [f64; 3]| (c[0] * c[0] + c[1] * c[1] + c[2] * c[2]).sqrt();
    let mut t = SphereMobius::identity();
    let (mut c, mut cov) = eval(&t).ok_or_else(nonfinite)?;
    for it in 0..CENTERING_MAX_ITERATIONS {
        if norm(c) <= CENTERING_TOLERANCE {
            return Ok((t, it));
        }
        let mut a = [[0.0; 3]; 3];
        for i in 0..3 {
            for j in 0..3 {
                a[i][j] = if i == j { 1.0 } else { 0.0 } - cov[i][j];
            }
        }
        // the centroid moves by (I − C)β along a boost β: Newton aims at −c
        let beta = solve3(a, c.map(|x| -x)).unwrap_or(c.map(|x| -x));
        let mut tau = 1.0;
        let mut accepted = false;
        for _ in 0..60 {
            let trial = SphereMobius::boost(beta.map(|x| x * tau)).compose(&t);
            if let Some((tc, tcov)) = eval(&trial) {
                if norm(tc) < norm(c) {
                    (t, c, cov) = (trial, tc, tcov);
                    accepted = true;
                    break;
                }
            }
            tau *= 0.5;
        }
        if !accepted {
            // no step decreases |c|: at the rounding floor
            if norm(c) <= 1e3 * CENTERING_TOLERANCE {
                return Ok((t, it));
            }
            break;
        }
    }
    if norm(c) <= CENTERING_TOLERANCE {
        return Ok((t, CENTERING_MAX_ITERATIONS));
    }
    Err(ConformalError::NoConvergence {
        what: "Möbius centering",
        iterations: CENTERING_MAX_ITERATIONS,
        residual: norm(c),
    })
}

/// The centre z_c of the charts of pass 2: the point of the plane that Möbius centering of
/// pass 1's map sends to the antipode of the puncture's image, so that the circles |z − z_c| =
/// const around it split the surface evenly (the farthest vertex can be the tip of a
/// protrusion, crowded at one side of the image). `None` when centering fails.
fn balanced_center(z: &[Complex], masses: &[f64]) -> Option<Complex> {
    let one = Complex::new(1.0, 0.0);
    let hom: Vec<Homogeneous> = z.iter().map(|&x| [x, one]).collect();
    let (t, _) = mobius_centering(&hom, masses).ok()?;
    let puncture = mobius::to_sphere(t.apply([one, Complex::default()]))?;
    let h = t.inverse().apply(mobius::from_sphere(puncture.map(|x| -x)));
    let c = h[0] / h[1];
    (c.re.is_finite() && c.im.is_finite()).then_some(c)
}

fn check_marker(v: u32, n: usize, what: &str) -> Result<(), ConformalError> {
    if (v as usize) < n {
        Ok(())
    } else {
        Err(ConformalError::InvalidMarker(format!(
            "{what} vertex {v} is out of range (the mesh has {n} vertices)"
        )))
    }
}

/// The rotation (rows) that sends `a` to the south pole and `b` onto the half meridian
/// {y = 0, x > 0}; `None` when a and b are (anti)parallel to rounding.
fn marker_rotation(a: [f64; 3], b: [f64; 3]) -> Option<[[f64; 3]; 3]> {
    let e3 = a.map(|x| -x);
    let d = b[0] * e3[0] + b[1] * e3[1] + b[2] * e3[2];
    let p = [b[0] - d * e3[0], b[1] - d * e3[1], b[2] - d * e3[2]];
    let l = (p[0] * p[0] + p[1] * p[1] + p[2] * p[2]).sqrt();
    if !(l > 1e-12) {
        return None;
    }
    let e1 = p.map(|x| x / l);
    let e2 = [
        e3[1] * e1[2] - e3[2] * e1[1],
        e3[2] * e1[0] - e3[0] * e1[2],
        e3[0] * e1[1] - e3[1] * e1[0],
    ];
    Some([e1, e2, e3])
}

/// The conformal map of the closed genus-0 surface `mesh` onto the unit sphere, normalized as
/// `params` says (module docs).
///
/// Errors: not a closed genus-0 surface ([`ConformalError::NotSphere`], or the geometry
/// crate's validation errors), degenerate faces, invalid markers (out of range, repeated, or
/// images that coincide), a folded image ([`ConformalError::FoldedImage`]), centering that
/// does not converge, densities beyond f64.
pub fn sphere_map(mesh: &TriMesh, params: &SphereMapParams) -> Result<SphereMap, ConformalError> {
    let t0 = Instant::now();
    let mut timings = SphereMapTimings::default();
    mesh.validate()?;
    if mesh.faces.is_empty() {
        return Err(ConformalError::NotSphere {
            reason: "the mesh has no faces".into(),
        });
    }
    check_coordinate_range(mesh)?;
    let n = mesh.num_vertices();
    check_normalization_markers(params.normalization, n)?;
    let mut tri = IntrinsicTriangulation::from_mesh(mesh)?;
    if !is_sphere(&tri, &mesh.faces) {
        // the reasons, from the full report
        check_sphere(mesh)?;
        return Err(ConformalError::NotSphere {
            reason: "not a closed genus-0 surface".into(),
        });
    }
    if params.intrinsic_delaunay {
        tri.make_delaunay()?;
    }
    let masses = shapespace_geometry::quantities::vertex_dual_areas(mesh);
    let face = construct::auto_puncture(&tri, &mesh.positions, &mesh.faces);
    let corners = [tri.tail[3 * face], tri.tail[3 * face + 1], tri.tail[3 * face + 2]];
    let far = construct::farthest_vertex(&mesh.positions, corners);
    timings.setup = t0.elapsed().as_secs_f64();

    let t1 = Instant::now();
    let (z, ranks) = construct::punctured_plane_map(&tri, face, far, params.method)?;
    timings.puncture_solve = t1.elapsed().as_secs_f64();
    let t2 = Instant::now();
    let zc = balanced_center(&z, &masses).unwrap_or(z[far as usize]);
    let planar = match params.correction {
        Correction::Schwarz => construct::schwarz(&tri, &z, zc, &masses, &ranks)?,
        c => construct::cap_correction(&tri, &z, zc, &masses, c == Correction::Cap)?,
    };
    timings.cap_solve = t2.elapsed().as_secs_f64();

    let t3 = Instant::now();
    let mut hom = planar.hom;
    // orientation: conjugate when most faces come out clockwise seen from outside
    let to_points = |t: &SphereMobius, hom: &[Homogeneous]| -> Result<Vec<[f64; 3]>, ConformalError> {
        hom.par_iter()
            .enumerate()
            .map(|(v, h)| {
                mobius::to_sphere(t.apply(*h)).ok_or(ConformalError::NonFinite {
                    stage: "inverse stereographic projection",
                    vertex: v,
                })
            })
            .collect()
    };
    let id = SphereMobius::identity();
    let raw = to_points(&id, &hom)?;
    let negative = mesh
        .faces
        .par_iter()
        .filter(|f| orientation_on_sphere(raw[f[0] as usize], raw[f[1] as usize], raw[f[2] as usize]) < 0)
        .count();
    if 2 * negative > mesh.num_faces() {
        for h in &mut hom {
            *h = [h[0].conj(), h[1].conj()];
        }
    }
    let mut rotation = [[1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]];
    let mut centering_iterations = 0;
    let (mut mobius, mut positions) = match params.normalization {
        SphereNormalization::ThreeMarkers(p) => {
            let t = SphereMobius::three_points(hom[p[0] as usize], hom[p[1] as usize], hom[p[2] as usize]).ok_or_else(
                || {
                    ConformalError::InvalidMarker(format!(
                        "the images of markers {}, {}, {} coincide to rounding",
                        p[0], p[1], p[2]
                    ))
                },
            )?;
            let mut x = to_points(&t, &hom)?;
            x[p[0] as usize] = [0.0, 0.0, -1.0];
            x[p[1] as usize] = [1.0, 0.0, 0.0];
            x[p[2] as usize] = [0.0, 0.0, 1.0];
            (t, x)
        }
        SphereNormalization::Centered { .. } => {
            let (t, iterations) = mobius_centering(&hom, &masses)?;
            centering_iterations = iterations;
            (t, to_points(&t, &hom)?)
        }
    };
    let unit = |positions: &mut [[f64; 3]]| {
        for p in positions {
            // |x| = 1 to rounding; one Newton step of the normalization keeps it there
            let l2 = p[0] * p[0] + p[1] * p[1] + p[2] * p[2];
            let s = 1.5 - 0.5 * l2;
            *p = p.map(|c| c * s);
        }
    };
    unit(&mut positions);
    let mut fold_repairs = 0;
    if params.repair_folds {
        let mut fixed = vec![false; n];
        if let SphereNormalization::ThreeMarkers(p) = params.normalization {
            p.iter().for_each(|&v| fixed[v as usize] = true);
        }
        fold_repairs = repair::repair_sphere_folds(mesh, &mut positions, &fixed);
    }
    if let SphereNormalization::Centered { rotation: markers } = params.normalization {
        if fold_repairs > 0 {
            // the moved vertices shift the centroid (by 1.7e-8 on TOSCA horse0): centre again,
            // unless that folds a face
            let moved: Vec<Homogeneous> = positions.iter().map(|&p| mobius::from_sphere(p)).collect();
            if let Ok((t, iterations)) = mobius_centering(&moved, &masses) {
                let mut x = to_points(&t, &moved)?;
                unit(&mut x);
                let folded = mesh
                    .faces
                    .par_iter()
                    .any(|f| orientation_on_sphere(x[f[0] as usize], x[f[1] as usize], x[f[2] as usize]) <= 0);
                if !folded {
                    positions = x;
                    mobius = t.compose(&mobius);
                    centering_iterations += iterations;
                }
            }
        }
        if let Some([a, b]) = markers {
            let r = marker_rotation(positions[a as usize], positions[b as usize]).ok_or_else(|| {
                ConformalError::InvalidMarker(format!(
                    "the images of rotation markers {a} and {b} are antipodal or equal to rounding"
                ))
            })?;
            for p in &mut positions {
                let q = *p;
                *p = r.map(|row| row[0] * q[0] + row[1] * q[1] + row[2] * q[2]);
            }
            unit(&mut positions);
            positions[a as usize] = [0.0, 0.0, -1.0];
            positions[b as usize][1] = 0.0;
            rotation = r;
        }
    }
    timings.normalize = t3.elapsed().as_secs_f64();

    let t4 = Instant::now();
    let dist = sphere_face_distortions(mesh, &positions)?;
    let areas = shapespace_geometry::quantities::face_areas(mesh);
    let total: f64 = areas.iter().sum();
    let scale = (4.0 * std::f64::consts::PI / total).sqrt();
    let summary = summarize(&dist, &areas);
    if summary.num_flipped + summary.num_degenerate > 0 {
        let first = dist.orientation.iter().position(|&o| o <= 0).unwrap_or(0);
        // a fold among image triangles at the resolution of f64 on S² is a range error
        // (a protrusion crushed beyond double precision), not a defect of the construction
        let edge = |f: usize| {
            let q = mesh.faces[f].map(|v| positions[v as usize]);
            let d = |a: [f64; 3], b: [f64; 3]| {
                ((a[0] - b[0]).powi(2) + (a[1] - b[1]).powi(2) + (a[2] - b[2]).powi(2)).sqrt()
            };
            d(q[0], q[1]).max(d(q[1], q[2])).max(d(q[2], q[0]))
        };
        if let Some(f) = (0..mesh.num_faces()).find(|&f| dist.orientation[f] <= 0 && edge(f) < SPHERE_RESOLUTION) {
            return Err(ConformalError::OutOfRange {
                what: "image triangle on the sphere",
                element: format!("face {f}"),
                log10_value: edge(f).max(f64::MIN_POSITIVE).log10(),
            });
        }
        return Err(ConformalError::FoldedImage {
            num_flipped: summary.num_flipped + summary.num_degenerate,
            first_face: first,
            flipped_area_fraction: summary.flipped_area_fraction,
            boundary_out_of_order: 0,
            bff_fallback_error: None,
            region_repair_error: None,
        });
    }
    let face_densities = crate::quality::face_densities(&dist.area_distortion)?;
    let conformal_factor = crate::quality::vertex_conformal_factors(mesh, &areas, scale, &dist.area_distortion)?;
    let mut centroid = [0.0; 3];
    let mtotal: f64 = masses.iter().sum();
    for (p, m) in positions.iter().zip(&masses) {
        for k in 0..3 {
            centroid[k] += m * p[k] / mtotal;
        }
    }
    timings.finish = t4.elapsed().as_secs_f64();
    timings.total = t0.elapsed().as_secs_f64();
    Ok(SphereMap {
        positions,
        conformal_factor,
        face_densities,
        scale,
        info: SphereMapInfo {
            method: params.method,
            correction: params.correction,
            puncture_vertices: corners,
            far_vertex: far,
            cap_vertices: planar.cap_vertices,
            schwarz_iterations: planar.iterations,
            schwarz_last_change: planar.last_change,
            intrinsic_flips: tri.num_flips,
            normalization: params.normalization,
            mobius,
            rotation,
            centering_iterations,
            fold_repairs,
            centroid_norm: (centroid[0] * centroid[0] + centroid[1] * centroid[1] + centroid[2] * centroid[2]).sqrt(),
            timings,
        },
        quality: summary,
    })
}

/// The normalization's markers: vertices of the mesh (`n` of them), and distinct.
fn check_normalization_markers(normalization: SphereNormalization, n: usize) -> Result<(), ConformalError> {
    match normalization {
        SphereNormalization::ThreeMarkers(p) => {
            for (k, &v) in p.iter().enumerate() {
                check_marker(v, n, ["p1", "p2", "p3"][k])?;
            }
            if p[0] == p[1] || p[1] == p[2] || p[0] == p[2] {
                return Err(ConformalError::InvalidMarker(format!(
                    "the three markers must be distinct vertices, got {}, {}, {}",
                    p[0], p[1], p[2]
                )));
            }
        }
        SphereNormalization::Centered { rotation: Some([a, b]) } => {
            check_marker(a, n, "rotation")?;
            check_marker(b, n, "rotation")?;
            if a == b {
                return Err(ConformalError::InvalidMarker(format!(
                    "the two rotation markers must be distinct vertices, got {a} twice"
                )));
            }
        }
        SphereNormalization::Centered { rotation: None } => {}
    }
    Ok(())
}
