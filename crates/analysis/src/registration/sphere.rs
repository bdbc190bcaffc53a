//! Registration of closed genus-0 surfaces through the sphere: the sphere version of the disk
//! route of the parent module [Su et al. 2015, Alg. 4 with S² for the disk]
//! (`docs/decisions/0033-sphere-registration.md`).
//!
//! Two closed genus-0 surfaces S₁, S₂ with landmark pairs (l1_k, l2_k):
//! 1. sphere maps ψ₁: S₁ → S², ψ₂: S₂ → S² ([`sphere_image`]): area-preserving
//!    ([`Method::Omt`], [`crate::sphere_param::area_preserving_sphere_map`]) or conformal
//!    ([`Method::Conformal`], `shapespace_conformal::sphere_map`), both Möbius-centred;
//! 2. **alignment**: the rotation R maximizing Σ_k ⟨R ψ₁(l1_k), ψ₂(l2_k)⟩ (Horn's method,
//!    [`crate::rotation::best_rotation`]); the centred maps differ by a rotation only, and a
//!    Möbius alignment would undo the area preservation of ψ₁;
//! 3. **chart**: the pole N is the centre of the largest cap free of landmarks (the direction
//!    of a Fibonacci grid of [`POLE_CANDIDATES`] points farthest from every R ψ₁(l1_k) and
//!    ψ₂(l2_k)); the source vertex v₀ whose image is nearest to N and its one-ring are held at
//!    their own images, the rest, a disk, is projected stereographically from N
//!    (orientation-preserving chart σ);
//! 3. **harmonic map** g in the chart: the planar landmark-constrained harmonic map of the
//!    parent module (its weights, landmark steps and untangling, [`HarmonicParams`]) of the
//!    projected mesh σ(R ψ₁(S₁ ∖ star v₀)), the link of v₀ fixed (g = identity there) and the
//!    landmarks pinned to σ(ψ₂(l2_k)); back on S² by σ⁻¹. The stereographic projection is
//!    conformal, so the cotangent weights of the projected mesh are those of the spherical
//!    layout up to the discretization (the Dirichlet energy is conformally invariant);
//! 4. **composition** f = ψ₂⁻¹ ∘ g ∘ R ψ₁ by point location on S² ([`SphereLocator`]): the
//!    face of ψ₂(S₂) whose spherical triangle holds g(v), barycentric coordinates of the ray
//!    through g(v) in its flat chordal triangle, and the corresponding 3D point of S₂.
//!
//! Refinement ([`super::refine_registration`]): ZoomOut seeded with the composed map, as on the
//! disk (`--refine zoomout`); it needs no domain, so the closed poses are refined without a cut.
//!
//! Flips ([`sphere_registration_metrics`]): a face of S₁ is flipped on the sphere when its image
//! (g(a), g(b), g(c)) is negatively oriented, det < 0 (ψ₁ is positively oriented, outward
//! normals); in 3D as for the disk, against the normal of the face of S₂ that holds the
//! normalized mean of the three sphere images of the map.

use std::time::Instant;

use serde::Serialize;
use shapespace_conformal::sphere::check_sphere;
use shapespace_conformal::sphere::repair::rotation_to_south;
use shapespace_conformal::sphere_map;
use shapespace_geometry::topology::{mesh_report, MeshClass};
use shapespace_geometry::vec3::{cross, dot, sub};
use shapespace_geometry::{Connectivity, TriMesh};
use shapespace_omt::sphere::fibonacci_sphere;

use super::box_tree::BoxTree;
pub use super::box_tree::LEAF_CAPACITY;
use super::metrics::{image_is_flipped, surface_metrics, FlipCounts};
use super::untangle::TargetImage;
use super::zoomout::ZoomOutParams;
use super::{
    at_surface_point, harmonic_step, refined_beside, HarmonicParams, HarmonicWeights, Landmarks, Method, MetricParams,
    Refinable, RefinementInfo, RegistrationMetrics, RegistrationTimings, ZoomOutRefinement, UNTANGLE_SWEEPS,
};
use crate::error::AnalysisError;
use crate::fold_repair::{count_folded_faces, untangle_kernels, UntangleInfo};
use crate::rotation::{apply, best_rotation, Rotation};
use crate::sphere_param::{area_preserving_sphere_map, SphereParamParams};

/// Candidate poles of the stereographic chart (a Fibonacci grid; spacing about 0.08 rad).
pub const POLE_CANDIDATES: usize = 2000;
/// A point is inside a spherical triangle when its smallest normalized barycentric coordinate
/// is ≥ −this.
pub const INSIDE_TOLERANCE: f64 = 1e-12;

/// Where a registration runs: on the disk (surfaces with one boundary loop) or on the sphere
/// (closed genus-0 surfaces), or chosen from the meshes.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize)]
#[serde(rename_all = "lowercase")]
pub enum Domain {
    /// The sphere when both meshes are closed, the disk when both have a boundary.
    #[default]
    Auto,
    /// Disk maps (the parent module).
    Disk,
    /// Sphere maps (this module).
    Sphere,
}

impl std::str::FromStr for Domain {
    type Err = AnalysisError;
    /// `auto`, `disk` or `sphere` (case-insensitive).
    fn from_str(s: &str) -> Result<Self, Self::Err> {
        match s.trim().to_ascii_lowercase().as_str() {
            "auto" => Ok(Domain::Auto),
            "disk" => Ok(Domain::Disk),
            "sphere" => Ok(Domain::Sphere),
            other => Err(AnalysisError::InvalidInput(format!(
                "unknown registration domain `{other}` (expected auto, disk or sphere)"
            ))),
        }
    }
}

/// The domain of a registration of `source` onto `target` (each with its name for errors):
/// `requested` unless [`Domain::Auto`], which takes the sphere when both meshes are closed
/// genus-0 surfaces and the disk when both are disks. Errors: one closed and one with a
/// boundary ([`AnalysisError::MixedDomains`], naming both), a mesh that is neither (or, for
/// [`Domain::Sphere`], not a closed genus-0 surface: [`AnalysisError::Shape`] naming it and the
/// reason).
pub fn registration_domain(
    requested: Domain,
    source: (&str, &TriMesh),
    target: (&str, &TriMesh),
) -> Result<Domain, AnalysisError> {
    let named = |name: &str, message: String| AnalysisError::Shape {
        name: name.to_string(),
        message,
    };
    match requested {
        Domain::Disk => Ok(Domain::Disk),
        Domain::Sphere => {
            for (name, mesh) in [source, target] {
                check_sphere(mesh).map_err(|e| {
                    named(
                        name,
                        format!("cannot be registered on the sphere: {}", crate::error::error_chain(&e)),
                    )
                })?;
            }
            Ok(Domain::Sphere)
        }
        Domain::Auto => {
            let mut classes = Vec::new();
            for (name, mesh) in [source, target] {
                let r = mesh_report(mesh).map_err(|e| named(name, crate::error::error_chain(&e)))?;
                if r.classification.class == MeshClass::Other {
                    return Err(named(
                        name,
                        format!(
                            "neither a disk nor a closed genus-0 surface ({}): no registration domain",
                            r.classification.reasons.join("; ")
                        ),
                    ));
                }
                classes.push(r.classification.class);
            }
            match (classes[0], classes[1]) {
                (MeshClass::Sphere, MeshClass::Sphere) => registration_domain(Domain::Sphere, source, target),
                (MeshClass::Disk, MeshClass::Disk) => Ok(Domain::Disk),
                (MeshClass::Sphere, _) => Err(AnalysisError::MixedDomains {
                    closed: source.0.to_string(),
                    with_boundary: target.0.to_string(),
                }),
                _ => Err(AnalysisError::MixedDomains {
                    closed: target.0.to_string(),
                    with_boundary: source.0.to_string(),
                }),
            }
        }
    }
}

/// A sphere image ψ(S) of a closed surface: #V points on S² and how it was made.
#[derive(Clone, Debug, PartialEq)]
pub struct SphereImage {
    /// ψ(v) per vertex, #V, unit vectors.
    pub positions: Vec<[f64; 3]>,
    /// The method that made it.
    pub method: Method,
    /// Wall-clock seconds.
    pub seconds: f64,
    /// For [`Method::Omt`]: max_i |cell area − target|/target of the OT solution (NaN for
    /// conformal).
    pub ot_max_relative_error: f64,
    /// Faces of the image that are not positively oriented on S² (exact predicate).
    pub flipped_faces: usize,
}

/// The sphere map of a closed genus-0 `mesh` by `method`: area-preserving
/// ([`area_preserving_sphere_map`] with `params`) or conformal (`sphere_map` with
/// `params.sphere_map`). Errors from either (not closed genus 0, beyond double precision, no
/// OT convergence).
pub fn sphere_image(mesh: &TriMesh, method: Method, params: &SphereParamParams) -> Result<SphereImage, AnalysisError> {
    let t = Instant::now();
    let (positions, ot_max_relative_error) = match method {
        Method::Omt => {
            let ap = area_preserving_sphere_map(mesh, params)?;
            let err = ap
                .cell_areas
                .iter()
                .zip(&ap.target_masses)
                .map(|(c, m)| (c - m).abs() / m)
                .fold(0.0f64, f64::max);
            (ap.positions, err)
        }
        Method::Conformal => (
            sphere_map(mesh, &params.sphere_map)
                .map_err(AnalysisError::SphereMap)?
                .positions,
            f64::NAN,
        ),
    };
    let flipped_faces = mesh
        .faces
        .iter()
        .filter(|f| {
            shapespace_conformal::sphere::orientation_on_sphere(
                positions[f[0] as usize],
                positions[f[1] as usize],
                positions[f[2] as usize],
            ) <= 0
        })
        .count();
    Ok(SphereImage {
        positions,
        method,
        seconds: t.elapsed().as_secs_f64(),
        ot_max_relative_error,
        flipped_faces,
    })
}

/// A registration f: S₁ → S₂ through the sphere (module docs).
#[derive(Clone, Debug)]
pub struct SphereRegistration {
    /// The sphere maps used.
    pub method: Method,
    /// ψ₁(v) per vertex of S₁ (as mapped, before the rotation), #V₁.
    pub source_sphere: Vec<[f64; 3]>,
    /// ψ₂(w) per vertex of S₂, #V₂.
    pub target_sphere: Vec<[f64; 3]>,
    /// The rotation R applied to ψ₁ (rows).
    pub rotation: Rotation,
    /// Root mean square of |R ψ₁(l1_k) − ψ₂(l2_k)| over the landmarks (chordal).
    pub landmark_rms_after_rotation: f64,
    /// The pole N of the stereographic chart.
    pub pole: [f64; 3],
    /// Angular radius of the landmark-free cap around N (radians).
    pub pole_clearance: f64,
    /// The source vertex v₀ nearest to N (held with its one-ring).
    pub pole_vertex: u32,
    /// g(R ψ₁(v)) per vertex of S₁, on S², #V₁.
    pub harmonic_sphere: Vec<[f64; 3]>,
    /// Face of S₂ holding f(v), per vertex of S₁ (#V₁).
    pub faces: Vec<u32>,
    /// Barycentric coordinates of f(v) in that face, #V₁.
    pub bary: Vec<[f64; 3]>,
    /// f(v) in 3D on S₂, #V₁.
    pub points: Vec<[f64; 3]>,
    /// Vertices whose g-image lay in no spherical triangle of ψ₂(S₂) (a gap of a fold) and were
    /// snapped to the nearest one.
    pub num_snapped: usize,
    /// Folded faces of g in the chart before any repair (exact predicate).
    pub harmonic_folded: usize,
    /// Landmark steps used.
    pub harmonic_steps: usize,
    /// What the untangling of g did, when it ran.
    pub harmonic_fold_repair: Option<UntangleInfo>,
    /// The chart repair of the faces of g's image that fold on S² (with
    /// [`HarmonicParams::release_landmarks`]; `None` when none folded).
    pub harmonic_sphere_repair: Option<SphereHarmonicRepair>,
    /// The refinement applied after the sphere stage, if any
    /// ([`super::refine_registration`]): `faces`, `bary` and `points` are then the refined
    /// map's, while `harmonic_sphere` stays the first stage's.
    pub refinement: Option<RefinementInfo>,
    /// Stage timings (`source_map`, `target_map`: the sphere maps).
    pub timings: RegistrationTimings,
}

/// What the repair of g's image on S² did: the sphere maps' chart repair
/// ([`crate::sphere_param::repair_sphere_map_folds`]) on the faces counter-clockwise in g's
/// chart that fold on S² (long slivers, whose straight chart edges are arcs on S²); every
/// vertex may move, the landmarks included.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct SphereHarmonicRepair {
    /// Faces of g's image not positively oriented on S² (exact predicate) before and after.
    pub folded_before: usize,
    pub folded_after: usize,
    /// Vertices the repair moved.
    pub vertices_moved: usize,
    /// The largest chordal distance on S² between a landmark's image and its target.
    pub landmark_shift: f64,
}

/// Registers S₁ onto S₂ through the sphere (module docs): both sphere maps by `method`
/// (in parallel), then [`register_sphere_with_maps`], then with `zoomout` the refinement
/// ([`super::refine_registration`], the eigenpairs of both surfaces computed beside the first
/// stage). Errors: a mesh that is not a closed genus-0 surface, whose sphere map or eigenpairs
/// fail (named `source` / `target`), bad landmarks, fewer than two landmarks, a harmonic map
/// that cannot be solved.
pub fn register_on_sphere(
    source: &TriMesh,
    target: &TriMesh,
    landmarks: &Landmarks,
    method: Method,
    sphere_params: &SphereParamParams,
    harmonic: &HarmonicParams,
    zoomout: Option<&ZoomOutParams>,
) -> Result<SphereRegistration, AnalysisError> {
    registration_domain(Domain::Sphere, ("source", source), ("target", target))?;
    check_sphere_landmarks(source, target, landmarks)?;
    let named = |name: &str, e: AnalysisError| AnalysisError::Shape {
        name: name.to_string(),
        message: crate::error::error_chain(&e),
    };
    let first_stage = || {
        let (psi1, psi2) = rayon::join(
            || sphere_image(source, method, sphere_params),
            || sphere_image(target, method, sphere_params),
        );
        let psi1 = psi1.map_err(|e| named("source", e))?;
        let psi2 = psi2.map_err(|e| named("target", e))?;
        register_sphere_with_maps(source, target, &psi1, &psi2, landmarks, harmonic)
    };
    refined_beside(source, target, landmarks, zoomout, first_stage)
}

fn check_sphere_landmarks(source: &TriMesh, target: &TriMesh, landmarks: &Landmarks) -> Result<(), AnalysisError> {
    landmarks.validate(&vec![false; source.num_vertices()], &vec![false; target.num_vertices()])?;
    if landmarks.len() < 2 {
        return Err(AnalysisError::Landmark {
            source_name: landmarks.source_name.clone(),
            landmark: "-".into(),
            message: format!(
                "{} landmark pairs: the sphere route needs at least 2 (they fix the rotation between the two sphere maps)",
                landmarks.len()
            ),
        });
    }
    Ok(())
}

/// det(a, b, c) = det(a, b − a, c − a) for points of S²: from the edge vectors, so that the
/// value (about the square of the edge length for a small triangle) keeps its relative
/// precision (a·(b × c) would lose it to cancellation: b × c is nearly tangent).
fn det(a: [f64; 3], b: [f64; 3], c: [f64; 3]) -> f64 {
    dot(a, cross(sub(b, a), sub(c, a)))
}
fn normalize(a: [f64; 3]) -> [f64; 3] {
    let n = dot(a, a).sqrt();
    a.map(|x| x / n)
}

/// The stereographic chart from the pole N: x ↦ (X, Y)/(1 + Z) with (X, Y, Z) = Q x and Q the
/// rotation taking N to the south pole; counter-clockwise faces of a positively oriented
/// spherical layout stay counter-clockwise.
#[derive(Clone, Copy, Debug)]
struct Chart {
    q: Rotation,
}

impl Chart {
    fn new(pole: [f64; 3]) -> Self {
        Chart {
            q: rotation_to_south(pole),
        }
    }
    fn project(&self, x: [f64; 3]) -> [f64; 2] {
        let [a, b, c] = apply(&self.q, x);
        [a / (1.0 + c), b / (1.0 + c)]
    }
    fn unproject(&self, w: [f64; 2]) -> [f64; 3] {
        let r2 = w[0] * w[0] + w[1] * w[1];
        let y = [
            2.0 * w[0] / (1.0 + r2),
            2.0 * w[1] / (1.0 + r2),
            (1.0 - r2) / (1.0 + r2),
        ];
        // Qᵀ y
        let q = &self.q;
        normalize([0, 1, 2].map(|i| q[0][i] * y[0] + q[1][i] * y[1] + q[2][i] * y[2]))
    }
}

/// The centre of the largest cap of S² free of `points`, among [`POLE_CANDIDATES`] Fibonacci
/// directions, and its angular radius.
pub fn largest_empty_cap(points: &[[f64; 3]]) -> ([f64; 3], f64) {
    let mut best = ([0.0, 0.0, 1.0], f64::NEG_INFINITY);
    for c in fibonacci_sphere(POLE_CANDIDATES) {
        let closest = points.iter().map(|&p| dot(c, p)).fold(-1.0f64, f64::max);
        let radius = closest.clamp(-1.0, 1.0).acos();
        if radius > best.1 {
            best = (c, radius);
        }
    }
    best
}

/// Steps 2–4 of the module docs with given sphere images ψ₁ (#V₁), ψ₂ (#V₂). Timings include
/// the images' `seconds`. Errors: images of the wrong length, bad or fewer than two landmarks,
/// collinear landmark images (the rotation undetermined), [`HarmonicWeights::IntrinsicDelaunay`]
/// (its solver needs a boundary loop), a harmonic map that cannot be solved.
pub fn register_sphere_with_maps(
    source: &TriMesh,
    target: &TriMesh,
    psi1: &SphereImage,
    psi2: &SphereImage,
    landmarks: &Landmarks,
    harmonic: &HarmonicParams,
) -> Result<SphereRegistration, AnalysisError> {
    check_sphere_landmarks(source, target, landmarks)?;
    if harmonic.weights == HarmonicWeights::IntrinsicDelaunay {
        return Err(AnalysisError::InvalidInput(
            "the intrinsic Delaunay weights hold a boundary loop on the circle; the sphere route's chart has none (use planar, planar-clamped or mean-value)".into(),
        ));
    }
    if psi1.positions.len() != source.num_vertices() || psi2.positions.len() != target.num_vertices() {
        return Err(AnalysisError::InvalidInput(format!(
            "sphere images have {} and {} points for meshes of {} and {} vertices",
            psi1.positions.len(),
            psi2.positions.len(),
            source.num_vertices(),
            target.num_vertices()
        )));
    }
    let t0 = Instant::now();
    let n1 = source.num_vertices();
    // 2. rotation
    let pairs: Vec<([f64; 3], [f64; 3])> = landmarks
        .pairs
        .iter()
        .map(|&(a, b)| (psi1.positions[a as usize], psi2.positions[b as usize]))
        .collect();
    let spread = pairs
        .iter()
        .flat_map(|p| pairs.iter().map(move |q| dot(cross(p.0, q.0), cross(p.0, q.0)).sqrt()))
        .fold(0.0f64, f64::max);
    if spread < 1e-6 {
        return Err(AnalysisError::Landmark {
            source_name: landmarks.source_name.clone(),
            landmark: "-".into(),
            message: "the source landmarks' sphere images are (anti)parallel: the rotation between the sphere maps is undetermined".into(),
        });
    }
    let rotation = best_rotation(pairs.iter().map(|&(a, b)| (a, b, 1.0)));
    let layout: Vec<[f64; 3]> = psi1.positions.iter().map(|&x| apply(&rotation, x)).collect();
    let landmark_rms_after_rotation = (pairs
        .iter()
        .map(|&(a, b)| {
            let r = apply(&rotation, a);
            let d = [r[0] - b[0], r[1] - b[1], r[2] - b[2]];
            dot(d, d)
        })
        .sum::<f64>()
        / pairs.len() as f64)
        .sqrt();
    // 3. chart
    let mut marks: Vec<[f64; 3]> = landmarks.pairs.iter().map(|&(a, _)| layout[a as usize]).collect();
    marks.extend(landmarks.pairs.iter().map(|&(_, b)| psi2.positions[b as usize]));
    let (pole, pole_clearance) = largest_empty_cap(&marks);
    let pole_vertex = (0..n1)
        .max_by(|&a, &b| dot(layout[a], pole).total_cmp(&dot(layout[b], pole)))
        .unwrap_or(0) as u32;
    if landmarks.pairs.iter().any(|&(a, _)| a == pole_vertex) {
        return Err(AnalysisError::InvalidInput(
            "the landmarks leave no free cap on the sphere for the chart's pole".into(),
        ));
    }
    let chart = Chart::new(pole);
    let faces: Vec<[u32; 3]> = source
        .faces
        .iter()
        .copied()
        .filter(|f| !f.contains(&pole_vertex))
        .collect();
    let mut held = vec![false; n1];
    held[pole_vertex as usize] = true;
    for f in source.faces.iter().filter(|f| f.contains(&pole_vertex)) {
        for &v in f {
            held[v as usize] = true;
        }
    }
    for &(a, _) in &landmarks.pairs {
        if held[a as usize] {
            return Err(AnalysisError::InvalidInput(format!(
                "landmark vertex {a} lies in the one-ring of the chart's pole vertex {pole_vertex}"
            )));
        }
    }
    let uv1: Vec<[f64; 2]> = layout.iter().map(|&x| chart.project(x)).collect();
    let fixed: Vec<(u32, [f64; 2])> = (0..n1 as u32)
        .filter(|&v| held[v as usize] && v != pole_vertex)
        .map(|v| (v, uv1[v as usize]))
        .collect();
    let targets: Vec<[f64; 2]> = landmarks
        .pairs
        .iter()
        .map(|&(_, b)| chart.project(psi2.positions[b as usize]))
        .collect();
    // the reduced mesh: the faces off the pole vertex; the pole vertex is held as a constraint
    let reduced = TriMesh {
        positions: source.positions.clone(),
        faces: faces.clone(),
        uvs: None,
    };
    let mut fixed_all = fixed.clone();
    fixed_all.push((pole_vertex, uv1[pole_vertex as usize]));
    let solve_in_steps = |steps: usize| -> Result<Vec<[f64; 2]>, AnalysisError> {
        let mut uv = uv1.clone();
        let mut cache = None;
        for s in 1..=steps {
            let t = s as f64 / steps as f64;
            let pins: Vec<(u32, [f64; 2])> = landmarks
                .pairs
                .iter()
                .zip(&targets)
                .map(|(&(a, _), &y)| {
                    let x = uv1[a as usize];
                    (
                        a,
                        if s == steps {
                            y
                        } else {
                            [x[0] + t * (y[0] - x[0]), x[1] + t * (y[1] - x[1])]
                        },
                    )
                })
                .collect();
            uv = if harmonic.weights == HarmonicWeights::Planar {
                // linear precision: the layout is harmonic for its own planar weights, so the
                // step is solved for the displacement (exactly 0 where nothing moves)
                let zero: Vec<(u32, [f64; 2])> = fixed_all.iter().map(|&(v, _)| (v, [0.0; 2])).collect();
                let moves = pins
                    .iter()
                    .map(|&(v, p)| (v, [p[0] - uv[v as usize][0], p[1] - uv[v as usize][1]]))
                    .collect();
                let d = harmonic_step(&reduced, &uv, &zero, moves, harmonic.weights, &mut cache)?;
                uv.iter().zip(&d).map(|(x, d)| [x[0] + d[0], x[1] + d[1]]).collect()
            } else {
                harmonic_step(&reduced, &uv, &fixed_all, pins, harmonic.weights, &mut cache)?
            };
        }
        Ok(uv)
    };
    let mut uv = solve_in_steps(1)?;
    let mut steps_used = 1;
    if harmonic.landmark_steps > 1 && count_folded_faces(&faces, &uv) > 0 {
        uv = solve_in_steps(harmonic.landmark_steps)?;
        steps_used = harmonic.landmark_steps;
    }
    let harmonic_folded = count_folded_faces(&faces, &uv);
    let harmonic_fold_repair = if harmonic.fold_repair && harmonic_folded > 0 {
        let conn = Connectivity::new(n1, &faces);
        let mut hold = held.clone();
        for &(a, _) in &landmarks.pairs {
            hold[a as usize] = true;
        }
        Some(untangle_kernels(
            &faces,
            &conn.vertex_faces,
            &hold,
            &mut uv,
            UNTANGLE_SWEEPS,
        ))
    } else {
        None
    };
    // back on S²: held vertices keep their rotated images exactly, landmarks their targets
    let mut harmonic_sphere: Vec<[f64; 3]> = (0..n1)
        .map(|v| if held[v] { layout[v] } else { chart.unproject(uv[v]) })
        .collect();
    for &(a, b) in &landmarks.pairs {
        harmonic_sphere[a as usize] = psi2.positions[b as usize];
    }
    // faces that are counter-clockwise in the chart but long slivers on S² (its straight edges
    // are arcs there) flip on S²: the sphere maps' chart repair re-embeds them, tested on S²
    let folded_on_sphere = if harmonic.release_landmarks {
        crate::sphere_param::folded_faces_on_sphere(source, &harmonic_sphere)
    } else {
        0
    };
    let harmonic_sphere_repair = (folded_on_sphere > 0).then(|| {
        let folded_before = folded_on_sphere;
        let info = crate::sphere_param::repair_sphere_map_folds(source, &mut harmonic_sphere);
        let landmark_shift = landmarks
            .pairs
            .iter()
            .map(|&(a, b)| {
                let d = sub(harmonic_sphere[a as usize], psi2.positions[b as usize]);
                dot(d, d).sqrt()
            })
            .fold(0.0, f64::max);
        SphereHarmonicRepair {
            folded_before,
            folded_after: crate::sphere_param::folded_faces_on_sphere(source, &harmonic_sphere),
            vertices_moved: info.vertices_moved,
            landmark_shift,
        }
    });
    let t1 = Instant::now();
    // 4. composition
    let locator = SphereLocator::new(&psi2.positions, &target.faces)?;
    let mut out_faces = Vec::with_capacity(n1);
    let mut bary = Vec::with_capacity(n1);
    let mut points = Vec::with_capacity(n1);
    let mut num_snapped = 0;
    for (v, &y) in harmonic_sphere.iter().enumerate() {
        let loc = locator.locate(y).ok_or_else(|| {
            AnalysisError::InvalidInput(format!(
                "the harmonic image {y:?} of source vertex {v} cannot be located on the sphere"
            ))
        })?;
        if loc.snapped {
            num_snapped += 1;
        }
        out_faces.push(loc.face);
        bary.push(loc.bary);
        points.push(at_surface_point(&target.faces, &target.positions, (loc.face, loc.bary)));
    }
    let t2 = Instant::now();
    let harmonic_seconds = (t1 - t0).as_secs_f64();
    let composition = (t2 - t1).as_secs_f64();
    Ok(SphereRegistration {
        method: psi1.method,
        source_sphere: psi1.positions.clone(),
        target_sphere: psi2.positions.clone(),
        rotation,
        landmark_rms_after_rotation,
        pole,
        pole_clearance,
        pole_vertex,
        harmonic_sphere,
        faces: out_faces,
        bary,
        points,
        num_snapped,
        harmonic_folded,
        harmonic_steps: steps_used,
        harmonic_fold_repair,
        harmonic_sphere_repair,
        refinement: None,
        timings: RegistrationTimings {
            source_map: psi1.seconds,
            target_map: psi2.seconds,
            harmonic: harmonic_seconds,
            composition,
            refine: 0.0,
            total: psi1.seconds + psi2.seconds + harmonic_seconds + composition,
        },
    })
}

impl Refinable for SphereRegistration {
    fn first_map(&self) -> (&[u32], &[[f64; 3]]) {
        (&self.faces, &self.bary)
    }
    fn metric_image(&self) -> TargetImage<'_> {
        TargetImage::Sphere(&self.target_sphere)
    }
    fn take_refined(&mut self, refined: ZoomOutRefinement) {
        (self.faces, self.bary, self.points) = (refined.faces, refined.bary, refined.points);
        self.timings.refine = refined.seconds;
        self.timings.total += refined.seconds;
        self.refinement = Some(refined.info);
    }
}

/// The sphere image of each f(v): g's when the map is the first stage's, otherwise (a refined
/// map) ψ₂ at f(v), the ray through the barycentric combination of its face's corners.
fn map_sphere_images<'a>(reg: &'a SphereRegistration, target: &TriMesh) -> std::borrow::Cow<'a, [[f64; 3]]> {
    if reg.refinement.is_none() {
        return std::borrow::Cow::Borrowed(&reg.harmonic_sphere);
    }
    (0..reg.faces.len())
        .map(|v| {
            normalize(at_surface_point(
                &target.faces,
                &reg.target_sphere,
                (reg.faces[v], reg.bary[v]),
            ))
        })
        .collect()
}

/// The measures of [`crate::registration::metrics`] for a sphere registration: the flips of g
/// on the sphere (module docs) in `flipped_area_ratio` / `flipped_faces` (the first stage's,
/// also for a refined map, as the disk route counts g's flips in the disk), the 3D flips
/// against the normal of the face of S₂ holding the normalized mean of the corners' sphere
/// images (g's, or for a refined map ψ₂ at its points), and the
/// curvature difference, area distortion and geodesic error (against v ↔ v when
/// `params.ground_truth` and the vertex counts agree) as for the disk. Errors as there.
pub fn sphere_registration_metrics(
    source: &TriMesh,
    target: &TriMesh,
    reg: &SphereRegistration,
    params: &MetricParams,
) -> Result<RegistrationMetrics, AnalysisError> {
    let n1 = source.num_vertices();
    if reg.harmonic_sphere.len() != n1 || reg.points.len() != n1 {
        return Err(AnalysisError::InvalidInput(format!(
            "sphere registration has {} points for {} source vertices",
            reg.points.len(),
            n1
        )));
    }
    let areas1 = shapespace_geometry::quantities::face_areas(source);
    let locator = SphereLocator::new(&reg.target_sphere, &target.faces)?;
    let images = map_sphere_images(reg, target);
    let mut flips = FlipCounts::default();
    for (fi, f) in source.faces.iter().enumerate() {
        let [a, b, c] = f.map(|v| reg.harmonic_sphere[v as usize]);
        if det(a, b, c) < 0.0 {
            flips.faces += 1;
            flips.area += areas1[fi];
        }
        let [a, b, c] = f.map(|v| images[v as usize]);
        let m = [a[0] + b[0] + c[0], a[1] + b[1] + c[1], a[2] + b[2] + c[2]];
        let reference = if dot(m, m) > 0.0 {
            locator.locate(normalize(m)).map(|l| l.face)
        } else {
            None
        };
        if image_is_flipped(target, f.map(|v| reg.points[v as usize]), reference) {
            flips.faces_3d += 1;
            flips.area_3d += areas1[fi];
        }
    }
    surface_metrics(
        source,
        target,
        &reg.faces,
        &reg.bary,
        &reg.points,
        reg.num_snapped,
        flips,
        params,
        None,
    )
}

/// Where a point of S² lies in a spherical triangulation: the face, the barycentric
/// coordinates of the ray through the point in the face's flat chordal triangle (corners in
/// the face's order, summing to 1), and whether it was snapped (it lay in no triangle).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct SphereLocation {
    /// Face index.
    pub face: u32,
    /// Barycentric coordinates.
    pub bary: [f64; 3],
    /// The point lay in no spherical triangle (a gap left by folded faces) and the face is the
    /// one of largest smallest coordinate, the coordinates clamped to ≥ 0.
    pub snapped: bool,
}

/// Point location on a triangulation of S² (#V unit vectors, faces): a bounding-volume
/// hierarchy over boxes that contain each spherical triangle (the box of its corners grown by
/// d², d its longest chord: every point of the spherical triangle is within 1 − √(1 − d²) ≤ d²
/// of the flat triangle), queried with the ray barycentric coordinates
/// α = det(y, b, c)/det(a, b, c), … normalized to sum 1 (inside: all ≥ −[`INSIDE_TOLERANCE`]
/// and the unnormalized sum > 0). Among candidates the largest smallest coordinate wins; a point
/// no triangle holds falls back to a scan of all faces.
#[derive(Clone, Debug)]
pub struct SphereLocator {
    positions: Vec<[f64; 3]>,
    faces: Vec<[u32; 3]>,
    tree: BoxTree<3>,
}

impl SphereLocator {
    /// Builds the locator. Errors: a face index out of range, a non-finite position.
    pub fn new(positions: &[[f64; 3]], faces: &[[u32; 3]]) -> Result<Self, AnalysisError> {
        let n = positions.len();
        if let Some(f) = faces.iter().position(|f| f.iter().any(|&v| v as usize >= n)) {
            return Err(AnalysisError::InvalidInput(format!(
                "sphere point location: face {f} references a vertex out of range (#V = {n})"
            )));
        }
        if let Some(v) = positions.iter().position(|p| p.iter().any(|x| !x.is_finite())) {
            return Err(AnalysisError::InvalidInput(format!(
                "sphere point location: vertex {v} has a non-finite position"
            )));
        }
        let boxes: Vec<([f64; 3], [f64; 3])> = faces
            .iter()
            .map(|f| {
                let p = f.map(|v| positions[v as usize]);
                let mut d2 = 0.0f64;
                for k in 0..3 {
                    let (a, b) = (p[k], p[(k + 1) % 3]);
                    let e = [a[0] - b[0], a[1] - b[1], a[2] - b[2]];
                    d2 = d2.max(dot(e, e));
                }
                let pad = d2.min(2.0) + 1e-12;
                let mut lo = [f64::INFINITY; 3];
                let mut hi = [f64::NEG_INFINITY; 3];
                for q in p {
                    for d in 0..3 {
                        lo[d] = lo[d].min(q[d] - pad);
                        hi[d] = hi[d].max(q[d] + pad);
                    }
                }
                (lo, hi)
            })
            .collect();
        Ok(SphereLocator {
            positions: positions.to_vec(),
            faces: faces.to_vec(),
            // (the widest axis; ties to the last)
            tree: BoxTree::new(&boxes, |lo, hi| {
                (0..3)
                    .max_by(|&a, &b| (hi[a] - lo[a]).total_cmp(&(hi[b] - lo[b])))
                    .unwrap_or(0)
            }),
        })
    }

    /// Normalized ray barycentric coordinates of `y` in face `f` and their smallest value, or
    /// `None` when the ray misses the face's plane on the far side (unnormalized sum ≤ 0) or the
    /// face is degenerate.
    pub(crate) fn coordinates(&self, y: [f64; 3], f: u32) -> Option<([f64; 3], f64)> {
        let [a, b, c] = self.faces[f as usize].map(|v| self.positions[v as usize]);
        let d = det(a, b, c);
        if d == 0.0 || !d.is_finite() {
            return None;
        }
        // det(y, b, c), det(a, y, c) = det(y, c, a) and det(a, b, y) = det(y, a, b), each
        // from the edges at y
        let w = [det(y, b, c) / d, det(y, c, a) / d, det(y, a, b) / d];
        let s = w[0] + w[1] + w[2];
        // a positively oriented face sees y with s > 0; a folded (negative) one too, since both
        // signs flip; the antipodal point gives s < 0
        if !(s > 0.0) {
            return None;
        }
        let w = w.map(|x| x / s);
        Some((w, w[0].min(w[1]).min(w[2])))
    }

    /// Locates the unit vector `y` (module docs). `None` for a non-finite point or an empty
    /// triangulation.
    pub fn locate(&self, y: [f64; 3]) -> Option<SphereLocation> {
        if y.iter().any(|x| !x.is_finite()) || self.faces.is_empty() {
            return None;
        }
        let mut best: Option<(u32, [f64; 3], f64)> = None;
        self.tree.for_candidates(y, |t| {
            if let Some((w, m)) = self.coordinates(y, t) {
                if m >= -INSIDE_TOLERANCE && best.is_none_or(|b| m > b.2) {
                    best = Some((t, w, m));
                }
            }
        });
        if let Some((face, bary, _)) = best {
            return Some(SphereLocation {
                face,
                bary,
                snapped: false,
            });
        }
        // in no triangle: the face of largest smallest coordinate over all faces
        let mut fallback: Option<(u32, [f64; 3], f64)> = None;
        for t in 0..self.faces.len() as u32 {
            if let Some((w, m)) = self.coordinates(y, t) {
                if fallback.is_none_or(|b| m > b.2) {
                    fallback = Some((t, w, m));
                }
            }
        }
        fallback.map(|(face, w, _)| {
            let w = w.map(|x| x.max(0.0));
            let s = w[0] + w[1] + w[2];
            SphereLocation {
                face,
                bary: if s > 0.0 { w.map(|x| x / s) } else { [1.0 / 3.0; 3] },
                snapped: true,
            }
        })
    }
}

/// Writes the outputs of a sphere registration into `out`, as
/// [`crate::registration::bench::write_registration`] does for the disk (correspondence.csv,
/// metrics.json, histograms, coloured OBJs); metrics.json also records the domain, the
/// rotation, the chart's pole and the harmonic map's folds.
pub fn write_sphere_registration(
    out: &std::path::Path,
    source: &TriMesh,
    target: &TriMesh,
    reg: &SphereRegistration,
    metrics: &RegistrationMetrics,
    extra: &serde_json::Value,
) -> Result<Vec<std::path::PathBuf>, AnalysisError> {
    let head = serde_json::json!({
        "domain": "sphere",
        "method": reg.method,
        "timings": reg.timings,
        "num_snapped": reg.num_snapped,
        "rotation": reg.rotation,
        "landmark_rms_after_rotation": reg.landmark_rms_after_rotation,
        "pole": reg.pole,
        "pole_clearance": reg.pole_clearance,
        "pole_vertex": reg.pole_vertex,
        "harmonic_folded": reg.harmonic_folded,
        "harmonic_steps": reg.harmonic_steps,
        "harmonic_fold_repair": reg.harmonic_fold_repair,
        "harmonic_sphere_repair": reg.harmonic_sphere_repair,
    });
    let map = super::bench::MapOutput {
        label: reg.method.name(),
        faces: &reg.faces,
        bary: &reg.bary,
        points: &reg.points,
    };
    super::bench::write_map_outputs(out, source, target, &map, head, metrics, extra)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Every face's normalized centroid is located in that face with coordinates 1/3, every
    /// vertex with one coordinate 1, on an icosphere and on a crowded copy: the stereographic
    /// coordinates from a point that is no vertex scaled by 1e-5 (a Möbius map: every vertex
    /// crowds towards the point's antipode, triangles down to ~1e-6); the faces around the
    /// point (two) grow beyond a hemisphere there and are left out.
    #[test]
    fn locator_finds_centroids_and_vertices() {
        let mesh = shapespace_geometry::primitives::icosphere(3);
        let unit: Vec<[f64; 3]> = mesh.positions.iter().map(|&p| normalize(p)).collect();
        let chart = Chart::new(normalize([0.1, 0.2, 1.0]));
        let squeezed: Vec<[f64; 3]> = unit
            .iter()
            .map(|&x| {
                let w = chart.project(x);
                chart.unproject([w[0] * 1e-5, w[1] * 1e-5])
            })
            .collect();
        for (positions, left_out) in [(&unit, 0), (&squeezed, 2)] {
            let faces: Vec<[u32; 3]> = mesh
                .faces
                .iter()
                .copied()
                .filter(|f| {
                    let [a, b, c] = f.map(|v| positions[v as usize]);
                    det(a, b, c) > 0.0
                })
                .collect();
            assert!(
                mesh.faces.len() - faces.len() <= left_out,
                "{} left out",
                mesh.faces.len() - faces.len()
            );
            let smallest = faces
                .iter()
                .map(|f| {
                    let [a, b, c] = f.map(|v| positions[v as usize]);
                    dot(sub(b, a), sub(b, a)).sqrt().min(dot(sub(c, a), sub(c, a)).sqrt())
                })
                .fold(f64::INFINITY, f64::min);
            assert!(smallest < if left_out > 0 { 1e-5 } else { 1.0 }, "{smallest}");
            let loc = SphereLocator::new(positions, &faces).unwrap();
            for (fi, f) in faces.iter().enumerate() {
                let [a, b, c] = f.map(|v| positions[v as usize]);
                let m = normalize([a[0] + b[0] + c[0], a[1] + b[1] + c[1], a[2] + b[2] + c[2]]);
                let l = loc.locate(m).unwrap();
                assert_eq!(l.face as usize, fi);
                assert!(!l.snapped);
                for k in 0..3 {
                    assert!((l.bary[k] - 1.0 / 3.0).abs() < 1e-6, "face {fi}: {:?}", l.bary);
                }
            }
            for (v, &x) in positions.iter().enumerate() {
                let l = loc.locate(x).unwrap();
                let f = faces[l.face as usize];
                let k = f
                    .iter()
                    .position(|&w| w as usize == v)
                    .expect("a face around the vertex");
                assert!((l.bary[k] - 1.0).abs() < 1e-6, "vertex {v}: {:?}", l.bary);
            }
        }
    }

    /// The chart preserves orientation and inverts exactly.
    #[test]
    fn chart_round_trip_and_orientation() {
        let c = Chart::new(normalize([0.3, -0.2, 0.9]));
        let (a, b, d) = (
            normalize([1.0, 0.1, 0.0]),
            normalize([0.9, 0.3, 0.1]),
            normalize([0.95, 0.1, 0.3]),
        );
        assert!(det(a, b, d) > 0.0);
        let [pa, pb, pd] = [a, b, d].map(|x| c.project(x));
        let area = (pb[0] - pa[0]) * (pd[1] - pa[1]) - (pb[1] - pa[1]) * (pd[0] - pa[0]);
        assert!(area > 0.0, "counter-clockwise in the chart");
        for x in [a, b, d] {
            let y = c.unproject(c.project(x));
            assert!((0..3).all(|k| (x[k] - y[k]).abs() < 1e-15), "{x:?} {y:?}");
        }
    }
}
