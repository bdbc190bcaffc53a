//! Spectral refinement of a registration by ZoomOut [Melzi, Ren, Rodolà, Sharma, Wonka,
//! Ovsjanikov 2019, "ZoomOut: spectral upsampling for efficient shape correspondence", Alg. 1].
//!
//! With Φ_S (#V₁ × K) and Φ_T (#V₂ × K) the first K Laplace–Beltrami eigenvectors of S₁ and S₂
//! (`shapespace_geometry::spectral`, both surfaces scaled to unit area, M-orthonormal) and a
//! vertex map T: S₁ → S₂ (the pull-back Π, Π[v, T(v)] = 1), one ZoomOut step at size k is
//! $$ C_k = \arg\min_C \bigl\| \Phi_S^{(k)} C - \Pi \, \Phi_T^{(k)} \bigr\|_{M_S}, \qquad
//!    T(v) = \arg\min_w \bigl\| \Phi_T^{(k)}(w,:) \, C_k^\top - \Phi_S^{(k)}(v,:) \bigr\|, $$
//! the functional map C_k (k × k, target coefficients to source coefficients; with every
//! vertex in the fit C_k = Φ_Sᵀ M_S Π Φ_T), then the vertex map by nearest neighbours in the
//! k-dimensional spectral embedding, in the form of the authors' code (targets embedded by Cᵀ).
//! The other form, Φ_S C against Φ_T, measured far worse: wolf0 → wolf1 mean geodesic error
//! 0.0150 against 0.0021 at k = 80. k grows from a first size to `k_end` by `k_step`. The seed T
//! is the first stage's map (the corner of largest barycentric weight of each f(v)).
//!
//! Several first sizes ([`ZoomOutParams::k_starts`], default 20 and 8): ZoomOut runs from each
//! and keeps the final vertex map whose nearest-neighbour residual
//! $$ E = \sum_v m_v \bigl\| \Phi_T^{(k)}(T(v),:) \, C_k^\top - \Phi_S^{(k)}(v,:) \bigr\|^2 $$
//! at k = `k_end` (landmark coordinates included, m the source's lumped masses) is smallest (ties:
//! the earlier size). Limbs with a nearly round cross-section let ZoomOut settle on a twisted
//! image (the lion poses' front paw turned by 160–180° about its axis, 0.06–0.07 √area off
//! around it), and which runs do depends on the first size; E tells the runs apart without a
//! ground truth (decision 0055).
//!
//! Landmark pairs in the fits ([`ZoomOutParams::landmark_fit`], default 20): every step's
//! least-squares fit of C takes the landmark pairs (l_i, its partner) as further samples whose
//! images stay the partners, each with 20 times a sample's mean weight (1 % of the surface's
//! mass with the default 2,000 samples, more on meshes with fewer vertices than that), the pairs
//! whose coordinates were left out as well. The samples' images
//! come from the current map, which on a twisted limb is wrong around the landmark at its tip;
//! the held pairs make C carry each landmark's spectral coordinates onto its partner's, and the
//! limb follows. Without them ZoomOut left the landmark x0 of lion0 → remeshed lion1 0.063 √area
//! off its partner, its paw twisted, where a first stage with g's landmarks held had put it
//! 0.004 off (decision 0066).
//!
//! Landmarks: both embeddings of the nearest-neighbour step carry, after the k spectral
//! coordinates, w · d(v, l_i) / √area for each landmark pair (l_i on S₁, its partner on S₂; d the
//! heat-method geodesic distance of each surface on its intrinsic Delaunay triangulation,
//! [`crate::geodesic::HeatGeodesics::intrinsic_delaunay`]; w =
//! [`ZoomOutParams::landmark_weight`], default 3). With the mesh's own cotangent operators the
//! field from a hoof tip of the Sumner horse poses (angles down to 0.01°) spanned −1.16 to 0.10
//! √area where the Dijkstra distance reaches 1.47, and the largest values of the cat poses' fields were
//! 3–45 % below those on their remeshings (decision 0037). The spectral coordinates alone do not tell a
//! limb from its mirror image, and the first stage's map, the only thing that does, is forgotten
//! after the first steps: on the Sumner cat pair cat0 → cat1 a leg drifted onto the other one
//! (samples 0.006 from a landmark 0.21 of √area off) when the first stage changed slightly, mean
//! error 0.0318 against 0.0168 before the change; with the landmark coordinates 0.0172 (w = 1:
//! 0.0322, w = 10: 0.0203, w = 30: 0.0837; the wolf pair 0.0010 for w = 0, 1 and 3, 0.0013 for
//! w = 10; decision 0031).
//!
//! Speed: the steps below `k_end` fit C on `samples` source vertices spread by farthest-point
//! sampling in space, each weighted by the lumped mass of the vertices nearest to it (weighted
//! least squares: a quadrature of the M_S inner product that covers thin limbs as well as the
//! body; uniform random samples left the paws and tails few of them, decision 0058); the last
//! step maps every source vertex. The nearest neighbour of a
//! query is searched approximately: the [`STARTS`] nearest of `samples` target samples (spread
//! the same way; by
//! blocks of dense products ‖t‖² − 2 q·t in single precision) and the query's current image
//! start a steepest descent along the target's edges (each point's distance evaluated once per
//! query, a descent stopped where it meets an earlier one's path), the best end wins. Exact
//! search over all target vertices gave the same wolf0 → wolf1 error (0.0017) and made a
//! centaur pair (15,757 vertices, k = 120, eigenpairs included) take 40–50 s instead of
//! 20–24 s under the same load.
//!
//! The final vertex map is untangled in 3D ([`crate::registration::untangle`]); then
//! [`crate::registration::refine_registration`] moves the vertices of faces still flipped to
//! points inside the target's faces, tested in the target's disk image or, on the sphere route,
//! its sphere image (decisions 0034, 0063).
//!
//! Output ([`ZoomOutOutput`]): the vertex map itself, or each source vertex projected onto the
//! nearest triangle of the target's spectral embedding among the faces around its nearest
//! vertex (a vertex-to-point map; Ezuz & Ben-Chen 2017, "Deblurring and denoising of maps
//! between shapes", §4). By default the vertex map between meshes of one triangulation (the
//! projection doubled the wolf poses' error, decision 0023), projected points otherwise: onto
//! the bench's remeshed targets 3–18 % below the errors with vertex output (decision 0056).
//! Projected points are smoothed after the untangling ([`ZoomOutParams::smoothing`] sweeps
//! towards the mean-value combination of the neighbours' images, by closest points; 3–5 %
//! lower errors on the remeshed targets, decision 0064).

use std::time::Instant;

use faer::linalg::matmul::matmul;
use faer::{Accum, Mat, MatRef, Par};
use rayon::prelude::*;
use serde::Serialize;
use shapespace_geometry::quantities::vertex_dual_areas;
use shapespace_geometry::spectral::{laplace_beltrami_eigenpairs, EigenParams};
use shapespace_geometry::vec3::{add, norm2, sub};
use shapespace_geometry::{Connectivity, TriMesh};

use crate::error::AnalysisError;
use crate::geodesic::HeatGeodesics;
use crate::registration::untangle::{
    untangle_vertex_map, PointUntangleParams, VertexMapUntangleInfo, VertexMapUntangleParams,
};

/// How the first-stage registration is refined.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Hash, Serialize, serde::Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum Refinement {
    /// The first stage as it is.
    None,
    /// ZoomOut (module docs; the default, decision 0065).
    #[default]
    ZoomOut,
}

impl Refinement {
    /// `none` or `zoomout`.
    pub fn name(self) -> &'static str {
        match self {
            Refinement::None => "none",
            Refinement::ZoomOut => "zoomout",
        }
    }
}

impl std::fmt::Display for Refinement {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(self.name())
    }
}

impl std::str::FromStr for Refinement {
    type Err = AnalysisError;
    /// Parses `none` or `zoomout` (case-insensitive).
    fn from_str(s: &str) -> Result<Self, Self::Err> {
        match s.trim().to_ascii_lowercase().as_str() {
            "none" => Ok(Refinement::None),
            "zoomout" | "zoom-out" => Ok(Refinement::ZoomOut),
            other => Err(AnalysisError::InvalidInput(format!(
                "unknown refinement `{other}` (expected none or zoomout)"
            ))),
        }
    }
}

/// What ZoomOut returns for each source vertex.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize)]
#[serde(rename_all = "kebab-case")]
pub enum ZoomOutOutput {
    /// `Vertex` when the two meshes share their triangulation (the same vertex count and the
    /// same faces: a pose set whose vertex i corresponds across poses), `Projected` otherwise,
    /// where a target vertex is only the nearest sample of the true image (decision 0056).
    #[default]
    Auto,
    /// A target vertex (barycentric coordinates (1, 0, 0) in one of its faces).
    Vertex,
    /// The nearest point of the target's spectral embedding on the faces around the nearest
    /// vertex (module docs).
    Projected,
}

impl ZoomOutOutput {
    /// `auto`, `vertex` or `projected`.
    pub fn name(self) -> &'static str {
        match self {
            ZoomOutOutput::Auto => "auto",
            ZoomOutOutput::Vertex => "vertex",
            ZoomOutOutput::Projected => "projected",
        }
    }

    /// The output for a pair: `Auto` resolved by whether `source` and `target` share their
    /// triangulation, the others as they are.
    pub fn for_pair(self, source: &TriMesh, target: &TriMesh) -> ZoomOutOutput {
        match self {
            ZoomOutOutput::Auto if source.same_triangulation(target) => ZoomOutOutput::Vertex,
            ZoomOutOutput::Auto => ZoomOutOutput::Projected,
            other => other,
        }
    }
}

impl std::str::FromStr for ZoomOutOutput {
    type Err = AnalysisError;
    /// Parses `auto`, `vertex` or `projected` (case-insensitive).
    fn from_str(s: &str) -> Result<Self, Self::Err> {
        match s.trim().to_ascii_lowercase().as_str() {
            "auto" => Ok(ZoomOutOutput::Auto),
            "vertex" => Ok(ZoomOutOutput::Vertex),
            "projected" => Ok(ZoomOutOutput::Projected),
            other => Err(AnalysisError::InvalidInput(format!(
                "unknown ZoomOut output `{other}` (expected auto, vertex or projected)"
            ))),
        }
    }
}

/// Parameters of [`zoomout`].
#[derive(Clone, Debug, PartialEq)]
pub struct ZoomOutParams {
    /// First spectral sizes: ZoomOut runs from each and keeps the map of smallest residual
    /// (module docs; default 20 and 8).
    pub k_starts: Vec<usize>,
    /// Last spectral size: the eigenpairs computed per mesh (default 120).
    pub k_end: usize,
    /// Increment of k (default 8: on the five bench classes within 3 % of the errors with 4 or
    /// below them, in up to 19 % less time; decision 0057).
    pub k_step: usize,
    /// Source vertices the steps below `k_end` run on, and target vertices the nearest-neighbour
    /// search starts from: farthest-point samples weighted by the mass nearest to each (module
    /// docs; default 2,000; all when fewer).
    pub samples: usize,
    /// Vertex map or projected points (default `Auto`: the vertex map between meshes of one
    /// triangulation, projected points otherwise; decision 0056).
    pub output: ZoomOutOutput,
    /// The eigen solver's parameters (default: blocks of 16, relative residual 1e-3: the wolf
    /// pairs' mean error the same to five digits as with 1e-4 (0.00311), a Krylov basis of 400
    /// instead of 464 columns, about 20 % less time; 1e-4 had matched 1e-6 on the centaur).
    pub eigen: EigenParams,
    /// The 3D untangling of the final vertex map ([`crate::registration::untangle`]), ranked by
    /// the spectral distance (`sweeps` = 0 turns it off).
    pub untangle: VertexMapUntangleParams,
    /// The 3D untangling of the refined map with points inside the target's faces, after the
    /// vertex map's ([`crate::registration::untangle::untangle_points`], run by
    /// [`crate::registration::refine_registration`] with the target's disk or sphere image;
    /// `sweeps` = 0 turns the untangling off, not the smoothing; its `smooth_rounds` is set
    /// by [`ZoomOutParams::point_pass`]).
    pub point_untangle: PointUntangleParams,
    /// Sweeps of projected smoothing after the untangling with points when the output is
    /// projected points ([`PointUntangleParams::smooth_rounds`]; default 3, 0 turns it off):
    /// each image moves towards the mean-value combination of its neighbours' images, put
    /// back on S₂ by closest point, which removes the scatter of the per-vertex projections
    /// (decision 0064).
    pub smoothing: usize,
    /// Weight w of the landmark coordinates appended to both embeddings of the nearest-neighbour
    /// step: w · d(v, l_i) / √area per landmark pair (heat-method geodesic distance on each
    /// surface), so that a limb cannot drift onto its mirror image (module docs; 0 turns them
    /// off; default 3).
    pub landmark_weight: f64,
    /// Weight of each landmark pair in the functional maps' least-squares fits, in units of a
    /// sample's mean quadrature weight: the pairs join the samples with their partners held in
    /// every step, so that C carries each landmark onto its partner (module docs; 0 leaves them
    /// out; default 20: 1 % of the source's mass per pair with 2,000 samples, a larger share on
    /// meshes with fewer vertices, where every vertex is a sample; decision 0066).
    pub landmark_fit: f64,
}

impl Default for ZoomOutParams {
    fn default() -> Self {
        ZoomOutParams {
            k_starts: vec![20, 8],
            k_end: 120,
            k_step: 8,
            samples: 2000,
            output: ZoomOutOutput::Auto,
            eigen: EigenParams {
                block_size: 16,
                tolerance: 1e-3,
                ..EigenParams::default()
            },
            untangle: VertexMapUntangleParams::default(),
            point_untangle: PointUntangleParams::default(),
            smoothing: SMOOTHING_SWEEPS,
            landmark_weight: LANDMARK_WEIGHT,
            landmark_fit: LANDMARK_FIT,
        }
    }
}

/// The first `k` Laplace–Beltrami eigenpairs of a mesh with its lumped masses, for the surface
/// scaled to unit area (so that two surfaces of different sizes have comparable embeddings:
/// ZoomOut's nearest neighbours compare Φ_S against Φ_T Cᵀ, which scales with the areas).
#[derive(Clone, Debug)]
pub struct SpectralBasis {
    /// λ_0 ≤ … ≤ λ_{k−1} of the unit-area surface.
    pub values: Vec<f64>,
    /// Φ, #V × k, M-orthonormal for `mass`.
    pub vectors: Mat<f64>,
    /// Lumped vertex masses (barycentric dual areas) over the total area, #V (sum 1).
    pub mass: Vec<f64>,
    /// Wall-clock seconds.
    pub seconds: f64,
}

impl SpectralBasis {
    /// The first `k` eigenpairs of `mesh` (`shapespace_geometry::spectral`). Errors from the
    /// eigen solver (degenerate vertices, no convergence).
    pub fn of(mesh: &TriMesh, k: usize, params: &EigenParams) -> Result<Self, AnalysisError> {
        let t = Instant::now();
        let e = laplace_beltrami_eigenpairs(mesh, k, params).map_err(AnalysisError::Mesh)?;
        let mass = vertex_dual_areas(mesh);
        let area: f64 = mass.iter().sum();
        let mut vectors = e.vectors;
        vectors *= faer::Scale(area.sqrt());
        Ok(SpectralBasis {
            values: e.values.iter().map(|l| l * area).collect(),
            vectors,
            mass: mass.iter().map(|m| m / area).collect(),
            seconds: t.elapsed().as_secs_f64(),
        })
    }

    fn k(&self) -> usize {
        self.vectors.ncols()
    }
}

/// A refined map: per source vertex a face of the target and barycentric coordinates in it.
#[derive(Clone, Debug)]
pub struct RefinedMap {
    /// The final vertex map (nearest target vertex in the spectral embedding), #V₁.
    pub vertex_map: Vec<u32>,
    /// Face of S₂ holding the image, #V₁.
    pub faces: Vec<u32>,
    /// Barycentric coordinates in that face, #V₁.
    pub bary: Vec<[f64; 3]>,
    /// Spectral sizes visited by the kept run.
    pub sizes: Vec<usize>,
    /// What `faces` and `bary` hold: `Vertex` or `Projected` ([`ZoomOutOutput::for_pair`]).
    pub output: ZoomOutOutput,
    /// Every run, in the order of [`ZoomOutParams::k_starts`].
    pub runs: Vec<ZoomOutRun>,
    /// What the 3D untangling of the vertex map did.
    pub untangle: VertexMapUntangleInfo,
    /// Landmarks whose coordinates were left out because their distance fields disagreed
    /// along the seed map ([`LANDMARK_DISAGREEMENT`]).
    pub landmarks_dropped: usize,
    /// Wall-clock seconds of the iterations (eigenpairs excluded).
    pub seconds: f64,
}

/// One ZoomOut run of [`zoomout`]: its first spectral size, its final residual E (module docs)
/// and whether its map was kept.
#[derive(Clone, Copy, Debug, PartialEq, Serialize)]
pub struct ZoomOutRun {
    /// First spectral size.
    pub k_start: usize,
    /// Nearest-neighbour residual of the final map at `k_end`.
    pub residual: f64,
    /// Whether this run's map was kept (the smallest residual, the earliest of equals).
    pub kept: bool,
}

/// Default [`ZoomOutParams::smoothing`].
pub const SMOOTHING_SWEEPS: usize = 3;

impl ZoomOutParams {
    /// The parameters of the untangling with points after a run whose output was `output`:
    /// [`ZoomOutParams::point_untangle`], with [`ZoomOutParams::smoothing`] sweeps of projected
    /// smoothing when the output is projected points.
    pub fn point_pass(&self, output: ZoomOutOutput) -> PointUntangleParams {
        PointUntangleParams {
            smooth_rounds: if output == ZoomOutOutput::Projected {
                self.smoothing
            } else {
                0
            },
            ..self.point_untangle.clone()
        }
    }
}

/// Default [`ZoomOutParams::landmark_weight`].
pub const LANDMARK_WEIGHT: f64 = 3.0;

/// Default [`ZoomOutParams::landmark_fit`].
pub const LANDMARK_FIT: f64 = 20.0;

/// ZoomOut from the vertex map `seed` (#V₁ target vertices) with the bases of `source` and
/// `target` and the landmark pairs `landmarks` (vertex of S₁, vertex of S₂; module docs).
/// Errors: sizes that do not match, no first size, a first size 0 or beyond `k_end`, `k_end`
/// beyond the bases, a landmark weight (`landmark_weight`, `landmark_fit`) negative or not
/// finite, a seed vertex or a landmark out of range, the heat method failing on a surface.
pub fn zoomout(
    source: &TriMesh,
    target: &TriMesh,
    source_basis: &SpectralBasis,
    target_basis: &SpectralBasis,
    seed: &[u32],
    landmarks: &[(u32, u32)],
    params: &ZoomOutParams,
) -> Result<RefinedMap, AnalysisError> {
    let t0 = Instant::now();
    let (n1, n2) = (source.num_vertices(), target.num_vertices());
    check_inputs(source, target, source_basis, target_basis, seed, landmarks, params)?;
    let k_end = params.k_end;
    let (lm_s, lm_t, landmarks_dropped) = landmark_columns(source, target, landmarks, seed, params)?;
    let (mut samples, mut sample_weights) = spread_samples(source, &source_basis.mass, params.samples.max(1));
    // the landmark pairs join the fits' samples, their partners held (`landmark_fit`)
    let n_free = samples.len();
    let mut fixed: Vec<u32> = Vec::new();
    if params.landmark_fit > 0.0 {
        let mean_weight = sample_weights.iter().sum::<f64>() / n_free as f64;
        for &(a, b) in landmarks {
            samples.push(a);
            sample_weights.push(params.landmark_fit * mean_weight);
            fixed.push(b);
        }
    }
    let conn = Connectivity::of(target);
    let space = SpectralSpace {
        n1,
        n2,
        phi_s: source_basis.vectors.as_ref(),
        phi_t: target_basis.vectors.as_ref(),
        nl: lm_s.ncols(),
        lm_s,
        lm_t,
        samples,
        sample_weights,
        n_free,
        fixed,
        target_samples: spread_samples(target, &target_basis.mass, params.samples.max(1)).0,
        neighbors: conn.vertex_neighbors(n2),
    };
    // the runs are independent: side by side, then the first of smallest residual is kept
    let passes: Vec<ZoomOutPass> = params
        .k_starts
        .par_iter()
        .map(|&k_start| space.run(&source_basis.mass, seed, k_start, params.k_step, k_end))
        .collect();
    let mut runs: Vec<ZoomOutRun> = params
        .k_starts
        .iter()
        .zip(&passes)
        .map(|(&k_start, pass)| ZoomOutRun {
            k_start,
            residual: pass.residual,
            kept: false,
        })
        .collect();
    let index = (0..runs.len())
        .reduce(|best, i| {
            if runs[i].residual < runs[best].residual {
                i
            } else {
                best
            }
        })
        .expect("check_inputs: at least one first size");
    runs[index].kept = true;
    let pass = passes.into_iter().nth(index).expect("one pass per first size");
    let ZoomOutPass {
        sizes,
        queries: q,
        points,
        mut vertex_map,
        ..
    } = pass;
    let spectral_cost = |v: usize, w: u32| distance2(points.as_ref(), q.row(v), w);
    let untangle = untangle_vertex_map(source, target, &mut vertex_map, &spectral_cost, &params.untangle);
    let output = params.output.for_pair(source, target);
    let (faces, bary) = surface_images(target, &conn, &vertex_map, q.as_ref(), points.as_ref(), output);
    Ok(RefinedMap {
        vertex_map,
        faces,
        bary,
        sizes,
        output,
        runs,
        untangle,
        landmarks_dropped,
        seconds: t0.elapsed().as_secs_f64(),
    })
}

/// The errors of [`zoomout`] before any work: sizes that do not match, spectral sizes out of
/// order or beyond the bases, a landmark weight that is negative or not finite, a seed vertex
/// or a landmark out of range.
fn check_inputs(
    source: &TriMesh,
    target: &TriMesh,
    source_basis: &SpectralBasis,
    target_basis: &SpectralBasis,
    seed: &[u32],
    landmarks: &[(u32, u32)],
    params: &ZoomOutParams,
) -> Result<(), AnalysisError> {
    let (n1, n2) = (source.num_vertices(), target.num_vertices());
    if source_basis.vectors.nrows() != n1 || target_basis.vectors.nrows() != n2 || seed.len() != n1 {
        return Err(AnalysisError::InvalidInput(format!(
            "zoomout: bases of {} and {} rows and a seed of {} for meshes of {n1} and {n2} vertices",
            source_basis.vectors.nrows(),
            target_basis.vectors.nrows(),
            seed.len()
        )));
    }
    let k_end = params.k_end;
    if params.k_starts.is_empty() || params.k_step == 0 || params.k_starts.iter().any(|&k| k == 0 || k > k_end) {
        return Err(AnalysisError::InvalidInput(format!(
            "zoomout: first spectral sizes {:?} to {k_end} by {} (need at least one, each in 1..={k_end}, and a step > 0)",
            params.k_starts, params.k_step
        )));
    }
    if k_end > source_basis.k() || k_end > target_basis.k() {
        return Err(AnalysisError::InvalidInput(format!(
            "zoomout: k_end = {k_end} but the bases have {} and {} eigenpairs",
            source_basis.k(),
            target_basis.k()
        )));
    }
    for (name, w) in [
        ("landmark_weight", params.landmark_weight),
        ("landmark_fit", params.landmark_fit),
    ] {
        if !(w.is_finite() && w >= 0.0) {
            return Err(AnalysisError::InvalidInput(format!(
                "zoomout: {name} = {w} (expected a finite number, 0 or more)"
            )));
        }
    }
    if let Some(v) = seed.iter().position(|&w| w as usize >= n2) {
        return Err(AnalysisError::InvalidInput(format!(
            "zoomout: seed maps source vertex {v} to {} (target has {n2} vertices)",
            seed[v]
        )));
    }
    if let Some(&(a, b)) = landmarks.iter().find(|&&(a, b)| a as usize >= n1 || b as usize >= n2) {
        return Err(AnalysisError::InvalidInput(format!(
            "zoomout: landmark pair ({a}, {b}) out of range ({n1} and {n2} vertices)"
        )));
    }
    Ok(())
}

/// The landmark coordinates of both surfaces, w · d(v, l_i) / √area (#V × L; no columns without
/// landmarks or with weight 0), without the landmarks whose two distance fields disagree along
/// the seed map (median difference above [`LANDMARK_DISAGREEMENT`] of √area: the field is wrong
/// on one surface, or the seed maps its limb elsewhere); with the number left out.
fn landmark_columns(
    source: &TriMesh,
    target: &TriMesh,
    landmarks: &[(u32, u32)],
    seed: &[u32],
    params: &ZoomOutParams,
) -> Result<(Mat<f64>, Mat<f64>, usize), AnalysisError> {
    let use_landmarks = params.landmark_weight > 0.0 && !landmarks.is_empty();
    let landmark_coordinates = |mesh: &TriMesh, vertices: Vec<u32>| -> Result<Mat<f64>, AnalysisError> {
        if !use_landmarks {
            return Ok(Mat::zeros(mesh.num_vertices(), 0));
        }
        let scale = params.landmark_weight / shapespace_geometry::quantities::total_area(mesh).sqrt();
        let d = HeatGeodesics::intrinsic_delaunay(mesh)?.distances(&vertices)?;
        Ok(Mat::from_fn(mesh.num_vertices(), d.len(), |v, i| scale * d[i][v]))
    };
    let (lm_s, lm_t) = rayon::join(
        || landmark_coordinates(source, landmarks.iter().map(|p| p.0).collect()),
        || landmark_coordinates(target, landmarks.iter().map(|p| p.1).collect()),
    );
    let (mut lm_s, mut lm_t) = (lm_s?, lm_t?);
    let dropped = drop_disagreeing_landmarks(&mut lm_s, &mut lm_t, seed, params.landmark_weight);
    Ok((lm_s, lm_t, dropped))
}

/// The spectral embedding of [`zoomout`]'s nearest-neighbour steps: both bases, the landmark
/// coordinates (`nl` columns), the source samples the steps below `k_end` fit C on (with their
/// quadrature weights), the target samples the coarse search starts from and the target's
/// vertex neighbours the descent walks along.
struct SpectralSpace<'a> {
    n1: usize,
    n2: usize,
    phi_s: MatRef<'a, f64>,
    phi_t: MatRef<'a, f64>,
    nl: usize,
    lm_s: Mat<f64>,
    lm_t: Mat<f64>,
    /// The fits' source vertices: the spread samples, then the landmarks held (`n_free..`).
    samples: Vec<u32>,
    sample_weights: Vec<f64>,
    /// Spread samples, whose images each step updates; the rest are the landmarks.
    n_free: usize,
    /// The landmarks' partners on S₂, the images of `samples[n_free..]` in every fit.
    fixed: Vec<u32>,
    target_samples: Vec<u32>,
    neighbors: Vec<Vec<u32>>,
}

/// The outcome of one ZoomOut run ([`SpectralSpace::run`]).
struct ZoomOutPass {
    sizes: Vec<usize>,
    /// The final step's embedding: queries (#V₁ rows) and points (#V₂ rows).
    queries: Mat<f64>,
    points: Mat<f64>,
    vertex_map: Vec<u32>,
    residual: f64,
}

impl SpectralSpace<'_> {
    /// ZoomOut from the seed map with k from `k_start` to `k_end` by `k_step` (module docs): the
    /// steps below `k_end` on the samples (with their quadrature weights), the last one on every
    /// source vertex; the residual E weighted by the source's lumped `mass`.
    fn run(&self, mass: &[f64], seed: &[u32], k_start: usize, k_step: usize, k_end: usize) -> ZoomOutPass {
        let (samples, weights) = (&self.samples, &self.sample_weights);
        let mut sizes: Vec<usize> = (k_start..k_end).step_by(k_step).collect();
        sizes.push(k_end);
        // the spread samples' images from the seed, then the held partners (never searched)
        let free = &samples[..self.n_free];
        let mut map_samples: Vec<u32> = free.iter().map(|&v| seed[v as usize]).collect();
        map_samples.extend_from_slice(&self.fixed);
        let mut c = Mat::<f64>::zeros(0, 0);
        for (step, &k) in sizes.iter().enumerate() {
            c = functional_map(self.phi_s, weights, self.phi_t, samples, &map_samples, k);
            if step + 1 < sizes.len() {
                let (q, p) = self.embed(Some(free), &c, k);
                let images = self.nearest(q.as_ref(), p.as_ref(), &map_samples[..self.n_free]);
                map_samples[..self.n_free].copy_from_slice(&images);
            }
        }
        // last step: every source vertex at k_end
        let (queries, points) = self.embed(None, &c, k_end);
        let vertex_map = self.nearest(queries.as_ref(), points.as_ref(), seed);
        let residual = (0..self.n1)
            .map(|v| mass[v] * distance2(points.as_ref(), queries.row(v), vertex_map[v]))
            .sum();
        ZoomOutPass {
            sizes,
            queries,
            points,
            vertex_map,
            residual,
        }
    }

    /// (queries, points) of the nearest-neighbour step: Φ_S[rows] (every source vertex for
    /// None) against the rows of Φ_T Cᵀ, each followed by the landmark coordinates.
    fn embed(&self, rows: Option<&[u32]>, c: &Mat<f64>, k: usize) -> (Mat<f64>, Mat<f64>) {
        let (n1, n2, nl) = (self.n1, self.n2, self.nl);
        let all: Vec<u32>;
        let rows = match rows {
            Some(r) => r,
            None => {
                all = (0..n1 as u32).collect();
                &all
            }
        };
        let queries = Mat::<f64>::from_fn(rows.len(), k + nl, |i, j| {
            let v = rows[i] as usize;
            if j < k {
                self.phi_s[(v, j)]
            } else {
                self.lm_s[(v, j - k)]
            }
        });
        let mut points = Mat::<f64>::zeros(n2, k + nl);
        matmul(
            points.as_mut().subcols_mut(0, k),
            Accum::Replace,
            self.phi_t.subcols(0, k),
            c.transpose(),
            1.0,
            Par::rayon(0),
        );
        points.as_mut().subcols_mut(k, nl).copy_from(self.lm_t.as_ref());
        (queries, points)
    }

    /// Per query, the nearest point by steepest descent along the target's edges from the
    /// nearest target samples and from the current image.
    fn nearest(&self, queries: MatRef<'_, f64>, points: MatRef<'_, f64>, current: &[u32]) -> Vec<u32> {
        let target_samples = &self.target_samples;
        let coarse = nearest_rows_top::<STARTS>(queries, sample_rows(points, target_samples, points.ncols()).as_ref());
        // each point's coordinates side by side in memory for the descent
        let by_point: Vec<f64> = (0..points.nrows())
            .flat_map(|w| points.row(w).iter().copied())
            .collect();
        (0..queries.nrows())
            .into_par_iter()
            .map_init(
                || Descent::new(&by_point, points.ncols()),
                |descent, i| {
                    descent.start_query(queries.row(i));
                    coarse[i]
                        .iter()
                        .map(|&s| target_samples[s as usize])
                        .chain([current[i]])
                        .map(|start| {
                            let w = descent.descend(&self.neighbors, start);
                            (descent.distance(w), w)
                        })
                        .fold((f64::INFINITY, 0), |a, b| if b.0 < a.0 { b } else { a })
                        .1
                },
            )
            .collect()
    }
}

/// Per source vertex the face of S₂ and barycentric coordinates of its image: the target
/// vertex itself ([`ZoomOutOutput::Vertex`]) or the query projected onto the faces around it
/// ([`ZoomOutOutput::Projected`]).
fn surface_images(
    target: &TriMesh,
    conn: &Connectivity,
    vertex_map: &[u32],
    q: MatRef<'_, f64>,
    points: MatRef<'_, f64>,
    output: ZoomOutOutput,
) -> (Vec<u32>, Vec<[f64; 3]>) {
    (0..vertex_map.len())
        .into_par_iter()
        .map(|v| {
            let w = vertex_map[v] as usize;
            match output {
                // `Auto` is resolved by the caller ([`ZoomOutOutput::for_pair`])
                ZoomOutOutput::Vertex | ZoomOutOutput::Auto => vertex_in_face(target, &conn.vertex_faces[w], w),
                ZoomOutOutput::Projected => {
                    let query: Vec<f64> = q.row(v).iter().copied().collect();
                    project_onto_faces(target, &conn.vertex_faces[w], points, &query, w)
                }
            }
        })
        .unzip()
}

/// Median disagreement (over √area) above which a landmark's coordinates are left out.
pub const LANDMARK_DISAGREEMENT: f64 = 0.5;

/// Removes the landmark columns i of `lm_s` (#V₁ × L) and `lm_t` (#V₂ × L), both scaled by
/// `weight`, whose median over the source vertices v of |lm_s[v, i] − lm_t[seed[v], i]| exceeds
/// `weight` · [`LANDMARK_DISAGREEMENT`]. Returns how many were removed.
fn drop_disagreeing_landmarks(lm_s: &mut Mat<f64>, lm_t: &mut Mat<f64>, seed: &[u32], weight: f64) -> usize {
    let keep: Vec<usize> = (0..lm_s.ncols())
        .filter(|&i| {
            let mut d: Vec<f64> = (0..lm_s.nrows())
                .map(|v| (lm_s[(v, i)] - lm_t[(seed[v] as usize, i)]).abs())
                .collect();
            let mid = d.len() / 2;
            d.select_nth_unstable_by(mid, f64::total_cmp);
            d[mid] <= weight * LANDMARK_DISAGREEMENT
        })
        .collect();
    let dropped = lm_s.ncols() - keep.len();
    if dropped > 0 {
        *lm_s = Mat::from_fn(lm_s.nrows(), keep.len(), |v, j| lm_s[(v, keep[j])]);
        *lm_t = Mat::from_fn(lm_t.nrows(), keep.len(), |v, j| lm_t[(v, keep[j])]);
    }
    dropped
}

/// The steepest descents of one query at a time ([`Descent::descend`]) over points stored one
/// after the other (`dim` coordinates each), with what the query's earlier descents found: the
/// squared distance of every point evaluated, and the end of every vertex on a path.
struct Descent<'a> {
    points: &'a [f64],
    dim: usize,
    query: Vec<f64>,
    /// (vertex, end of the descent through it) for the query's paths so far.
    visited: Vec<(u32, u32)>,
    /// Per target vertex: (query stamp, squared distance) of its last evaluation.
    known: Vec<(u32, f64)>,
    stamp: u32,
}

impl<'a> Descent<'a> {
    fn new(points: &'a [f64], dim: usize) -> Self {
        Descent {
            points,
            dim,
            query: Vec::new(),
            visited: Vec::new(),
            known: Vec::new(),
            stamp: 0,
        }
    }

    /// Forgets the previous query.
    fn start_query(&mut self, query: faer::RowRef<'_, f64>) {
        self.query.clear();
        self.query.extend(query.iter().copied());
        self.visited.clear();
        if self.known.is_empty() || self.stamp == u32::MAX {
            self.known = vec![(0, 0.0); self.points.len() / self.dim.max(1)];
            self.stamp = 0;
        }
        self.stamp += 1;
    }

    /// ‖points[w] − query‖² (the sum of [`distance2`]), evaluated once per query.
    fn distance(&mut self, w: u32) -> f64 {
        let entry = &mut self.known[w as usize];
        if entry.0 != self.stamp {
            let p = &self.points[w as usize * self.dim..][..self.dim];
            let q = &self.query;
            *entry = (self.stamp, lane_sum(q.len(), |j| (p[j] - q[j]).powi(2)));
        }
        entry.1
    }

    /// Steepest descent of w ↦ ‖points[w] − query‖ along the edges (`neighbors`) from `start`:
    /// the vertex where no neighbour is nearer. The path from a vertex depends on nothing else,
    /// so a descent that reaches a vertex of an earlier path of the same query ends where that
    /// one did.
    fn descend(&mut self, neighbors: &[Vec<u32>], start: u32) -> u32 {
        let first = self.visited.len();
        let (mut w, mut best) = (start, self.distance(start));
        let end = loop {
            if let Some(&(_, end)) = self.visited[..first].iter().find(|e| e.0 == w) {
                break end;
            }
            self.visited.push((w, u32::MAX));
            let mut next = w;
            for &u in &neighbors[w as usize] {
                let d = self.distance(u);
                if d < best {
                    (best, next) = (d, u);
                }
            }
            if next == w {
                break w;
            }
            w = next;
        };
        for e in &mut self.visited[first..] {
            e.1 = end;
        }
        end
    }
}

/// Independent partial sums of [`lane_sum`] (sums of squares are a chain of dependent additions
/// otherwise).
const LANES: usize = 8;

/// Σ_{j<n} term(j), in [`LANES`] partial sums (term j into sum j mod LANES), added pairwise at
/// the end: the one order every squared distance of this module is summed in.
#[inline(always)]
fn lane_sum(n: usize, term: impl Fn(usize) -> f64) -> f64 {
    let mut acc = [0.0; LANES];
    let whole = n - n % LANES;
    for j in (0..whole).step_by(LANES) {
        for (l, a) in acc.iter_mut().enumerate() {
            *a += term(j + l);
        }
    }
    for j in whole..n {
        acc[j - whole] += term(j);
    }
    ((acc[0] + acc[4]) + (acc[1] + acc[5])) + ((acc[2] + acc[6]) + (acc[3] + acc[7]))
}

/// ‖points[w] − query‖².
fn distance2(points: MatRef<'_, f64>, query: faer::RowRef<'_, f64>, w: u32) -> f64 {
    let p = points.row(w as usize);
    lane_sum(query.ncols(), |j| (p[j] - query[j]).powi(2))
}

/// Rows `rows` of the first k columns of `phi`.
fn sample_rows(phi: MatRef<'_, f64>, rows: &[u32], k: usize) -> Mat<f64> {
    Mat::<f64>::from_fn(rows.len(), k, |i, j| phi[(rows[i] as usize, j)])
}

/// C_k = argmin_C ‖W^{1/2}(Φ_S[samples] C − Φ_T[map])‖ with W the samples' quadrature
/// `weights`: the weighted least-squares functional map, k × k, from the normal equations
/// (AᵀWA) C = AᵀW B by Cholesky (with every vertex a sample, and no landmark rows, AᵀWA = I and
/// C = Φ_Sᵀ M Π Φ_T). Falls back to the plain product AᵀWB if AᵀWA is not definite (fewer
/// samples than k); the spread samples' weights sum to the total mass ([`spread_samples`]), so
/// that product is the M_S one's estimate (the landmark rows add their share).
fn functional_map(
    phi_s: MatRef<'_, f64>,
    weights: &[f64],
    phi_t: MatRef<'_, f64>,
    samples: &[u32],
    map: &[u32],
    k: usize,
) -> Mat<f64> {
    let a = sample_rows(phi_s, samples, k);
    let wa = Mat::<f64>::from_fn(samples.len(), k, |i, j| weights[i] * a[(i, j)]);
    let b = sample_rows(phi_t, map, k);
    let mut c = Mat::<f64>::zeros(k, k);
    matmul(
        c.as_mut(),
        Accum::Replace,
        wa.transpose(),
        b.as_ref(),
        1.0,
        Par::rayon(0),
    );
    let mut normal = Mat::<f64>::zeros(k, k);
    matmul(
        normal.as_mut(),
        Accum::Replace,
        wa.transpose(),
        a.as_ref(),
        1.0,
        Par::rayon(0),
    );
    if let Ok(llt) = normal.llt(faer::Side::Lower) {
        use faer::linalg::solvers::Solve;
        llt.solve_in_place(c.as_mut());
    }
    c
}

/// `k` vertices of `mesh` spread by farthest-point sampling in space (from the vertex nearest
/// the centroid), sorted, each with the mass (`mass`, #V) of the vertices nearest to it: a
/// quadrature of the mesh's inner product on the samples. All vertices, with their own
/// masses, when k ≥ #V; fewer than k when the vertices have fewer distinct positions.
fn spread_samples(mesh: &TriMesh, mass: &[f64], k: usize) -> (Vec<u32>, Vec<f64>) {
    let n = mesh.num_vertices();
    if k >= n {
        return ((0..n as u32).collect(), mass.to_vec());
    }
    let p = &mesh.positions;
    let d2 = |a: [f64; 3], b: [f64; 3]| norm2(sub(a, b));
    let c = p.iter().fold([0.0; 3], |s, &q| add(s, q)).map(|x| x / n as f64);
    let first = (0..n).min_by(|&a, &b| d2(p[a], c).total_cmp(&d2(p[b], c))).unwrap_or(0);
    let mut nearest = vec![f64::INFINITY; n];
    let mut owner = vec![0u32; n];
    let mut chosen = Vec::with_capacity(k);
    let mut next = first;
    for s in 0..k {
        if s > 0 && nearest[next] <= 0.0 {
            // every vertex left coincides with a sample
            break;
        }
        chosen.push(next as u32);
        let q = p[next];
        let (mut far, mut far_d) = (0, -1.0);
        for v in 0..n {
            let d = d2(p[v], q);
            if d < nearest[v] {
                nearest[v] = d;
                owner[v] = s as u32;
            }
            if nearest[v] > far_d {
                far_d = nearest[v];
                far = v;
            }
        }
        next = far;
    }
    let mut weights = vec![0.0; chosen.len()];
    for v in 0..n {
        weights[owner[v] as usize] += mass[v];
    }
    let mut order: Vec<usize> = (0..chosen.len()).collect();
    order.sort_unstable_by_key(|&i| chosen[i]);
    (
        order.iter().map(|&i| chosen[i]).collect(),
        order.iter().map(|&i| weights[i]).collect(),
    )
}

/// Starts of the descent per query from the target samples: the nearest ones.
pub const STARTS: usize = 4;

/// For each row of `queries` (m × k), the index of the nearest row of `points` (n × k): blocks
/// of queries in parallel, each scoring ‖p‖² − 2 q·p by one dense product (single precision).
#[cfg(test)]
fn nearest_rows(queries: MatRef<'_, f64>, points: MatRef<'_, f64>) -> Vec<u32> {
    nearest_rows_top::<1>(queries, points)
        .into_iter()
        .map(|t| t[0])
        .collect()
}

/// For each row of `queries`, the indices of the R nearest rows of `points`, nearest first
/// (the nearest repeated when there are fewer than R points), by blocks of dense products in
/// single precision: these are the descents' starts, whose ends are compared in double (the
/// same maps as in double on 59 of the 60 bench pairs, and cat2 → cat1 0.0113 → 0.0111, in
/// about half the time; the cat test pair reference → 0002 went 0.0119 → 0.0120).
fn nearest_rows_top<const R: usize>(queries: MatRef<'_, f64>, points: MatRef<'_, f64>) -> Vec<[u32; R]> {
    const BLOCK: usize = 128;
    const CHUNK: usize = 32;
    const LANES: usize = 8;
    let single = |m: MatRef<'_, f64>| Mat::<f32>::from_fn(m.nrows(), m.ncols(), |i, j| m[(i, j)] as f32);
    let (queries, points) = (single(queries), single(points));
    let n = points.nrows();
    let norms: Vec<f32> = (0..n).map(|w| points.row(w).iter().map(|x| x * x).sum()).collect();
    let m = queries.nrows();
    let blocks: Vec<usize> = (0..m).step_by(BLOCK).collect();
    blocks
        .par_iter()
        .flat_map_iter(|&start| {
            let rows = BLOCK.min(m - start);
            // points × queriesᵀ: each query's products with all points contiguous in one column
            let mut dots = Mat::<f32>::zeros(n, rows);
            matmul(
                dots.as_mut(),
                Accum::Replace,
                points.as_ref(),
                queries.subrows(start, rows).transpose(),
                1.0,
                Par::Seq,
            );
            (0..rows)
                .map(|i| {
                    let column = dots
                        .col(i)
                        .try_as_col_major()
                        .expect("a column of an owned matrix")
                        .as_slice();
                    let mut best = [(f32::INFINITY, 0u32); R];
                    let insert = |best: &mut [(f32, u32); R], s: f32, w: usize| {
                        if s < best[R - 1].0 {
                            let mut j = R - 1;
                            while j > 0 && s < best[j - 1].0 {
                                best[j] = best[j - 1];
                                j -= 1;
                            }
                            best[j] = (s, w as u32);
                        }
                    };
                    // by chunks: the chunk's smallest ‖t‖² − 2 q·t first (in lanes, vectorized),
                    // the insertion only for a chunk that holds a candidate (same order, same result)
                    let whole = n - n % CHUNK;
                    for base in (0..whole).step_by(CHUNK) {
                        let norms: &[f32; CHUNK] = norms[base..base + CHUNK].try_into().expect("a whole chunk");
                        let dots: &[f32; CHUNK] = column[base..base + CHUNK].try_into().expect("a whole chunk");
                        let mut lanes = [f32::INFINITY; LANES];
                        for k in 0..CHUNK {
                            let s = norms[k] - 2.0 * dots[k];
                            let l = &mut lanes[k % LANES];
                            *l = if s < *l { s } else { *l };
                        }
                        let lowest = lanes.iter().fold(f32::INFINITY, |a, &b| if b < a { b } else { a });
                        if lowest < best[R - 1].0 {
                            for k in 0..CHUNK {
                                insert(&mut best, norms[k] - 2.0 * dots[k], base + k);
                            }
                        }
                    }
                    for w in whole..n {
                        insert(&mut best, norms[w] - 2.0 * column[w], w);
                    }
                    let first = best[0].1;
                    best.map(|(s, w)| if s.is_finite() { w } else { first })
                })
                .collect::<Vec<_>>()
        })
        .collect()
}

/// Each target vertex of the vertex map `map` as a face of its star with barycentric
/// coordinates (1 at the vertex).
pub fn vertex_points(target: &TriMesh, map: &[u32]) -> (Vec<u32>, Vec<[f64; 3]>) {
    let conn = Connectivity::of(target);
    map.iter()
        .map(|&w| vertex_in_face(target, &conn.vertex_faces[w as usize], w as usize))
        .unzip()
}

/// Vertex `w` as a face of its star with barycentric coordinates (1 at w).
fn vertex_in_face(target: &TriMesh, star: &[u32], w: usize) -> (u32, [f64; 3]) {
    let f = star[0];
    let face = target.faces[f as usize];
    let mut b = [0.0; 3];
    for k in 0..3 {
        if face[k] as usize == w {
            b[k] = 1.0;
        }
    }
    (f, b)
}

/// The point of the spectral triangles of the faces in `star` nearest to `query` (k values):
/// the face and the barycentric coordinates (clamped onto the triangle).
fn project_onto_faces(
    target: &TriMesh,
    star: &[u32],
    phi: MatRef<'_, f64>,
    query: &[f64],
    w: usize,
) -> (u32, [f64; 3]) {
    let k = query.len();
    let mut best = (f64::INFINITY, vertex_in_face(target, star, w));
    for f in star {
        let face = target.faces[*f as usize];
        let p: [Vec<f64>; 3] = std::array::from_fn(|c| phi.row(face[c] as usize).iter().copied().collect());
        let (b, d2) = closest_point_on_triangle(&p, query, k);
        if d2 < best.0 {
            best = (d2, (*f, b));
        }
    }
    best.1
}

/// The closest point to `x` of the triangle (p0, p1, p2) in ℝᵏ: barycentric coordinates and the
/// squared distance. The minimum of a convex quadratic on the triangle: the interior critical
/// point if it lies inside, otherwise the best of the three edges (each clamped to [0, 1]).
fn closest_point_on_triangle(p: &[Vec<f64>; 3], x: &[f64], k: usize) -> ([f64; 3], f64) {
    let dot = |a: &dyn Fn(usize) -> f64, b: &dyn Fn(usize) -> f64| (0..k).map(|i| a(i) * b(i)).sum::<f64>();
    let e1 = |i: usize| p[1][i] - p[0][i];
    let e2 = |i: usize| p[2][i] - p[0][i];
    let r = |i: usize| x[i] - p[0][i];
    let (a11, a12, a22) = (dot(&e1, &e1), dot(&e1, &e2), dot(&e2, &e2));
    let (b1, b2) = (dot(&e1, &r), dot(&e2, &r));
    let dist2 = |bc: [f64; 3]| {
        (0..k)
            .map(|i| {
                let y = bc[0] * p[0][i] + bc[1] * p[1][i] + bc[2] * p[2][i];
                (y - x[i]).powi(2)
            })
            .sum::<f64>()
    };
    let det = a11 * a22 - a12 * a12;
    if det > 1e-14 * a11 * a22 && det > 0.0 {
        let s = (a22 * b1 - a12 * b2) / det;
        let t = (a11 * b2 - a12 * b1) / det;
        if s >= 0.0 && t >= 0.0 && s + t <= 1.0 {
            let bc = [1.0 - s - t, s, t];
            return (bc, dist2(bc));
        }
    }
    // edges (i, j): x ≈ p_i + u (p_j − p_i), u clamped to [0, 1]
    let mut best = ([1.0, 0.0, 0.0], f64::INFINITY);
    for (i, j) in [(0, 1), (1, 2), (2, 0)] {
        let e = |d: usize| p[j][d] - p[i][d];
        let rr = |d: usize| x[d] - p[i][d];
        let ee = dot(&e, &e);
        let u = if ee > 0.0 {
            (dot(&e, &rr) / ee).clamp(0.0, 1.0)
        } else {
            0.0
        };
        let mut bc = [0.0; 3];
        bc[i] = 1.0 - u;
        bc[j] = u;
        let d = dist2(bc);
        if d < best.1 {
            best = (bc, d);
        }
    }
    best
}

/// The vertex map of a first-stage registration: per source vertex, the corner of its image
/// face with the largest barycentric coordinate.
pub fn nearest_corner_map(target: &TriMesh, faces: &[u32], bary: &[[f64; 3]]) -> Vec<u32> {
    faces
        .iter()
        .zip(bary)
        .map(|(&f, b)| {
            let c = (0..3).fold(0, |a, i| if b[i] > b[a] { i } else { a });
            target.faces[f as usize][c]
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::registration::metrics::sample_indices;

    #[test]
    fn closest_point_on_a_triangle_in_four_dimensions() {
        let p = [
            vec![0.0, 0.0, 0.0, 0.0],
            vec![1.0, 0.0, 0.0, 0.0],
            vec![0.0, 1.0, 0.0, 0.0],
        ];
        // above the interior: the foot of the perpendicular
        let (b, d) = closest_point_on_triangle(&p, &[0.2, 0.3, 0.5, -0.5], 4);
        assert!((b[0] - 0.5).abs() < 1e-15 && (b[1] - 0.2).abs() < 1e-15 && (b[2] - 0.3).abs() < 1e-15);
        assert!((d - 0.5).abs() < 1e-15);
        // beyond the hypotenuse: its closest point
        let (b, d) = closest_point_on_triangle(&p, &[1.0, 1.0, 0.0, 0.0], 4);
        assert!((b[1] - 0.5).abs() < 1e-15 && (b[2] - 0.5).abs() < 1e-15 && b[0].abs() < 1e-15);
        assert!((d - 0.5).abs() < 1e-15);
        // beyond a corner
        let (b, _) = closest_point_on_triangle(&p, &[-1.0, -2.0, 0.0, 0.0], 4);
        assert_eq!(b, [1.0, 0.0, 0.0]);
    }

    /// A 21 × 21 grid on [0, 1]² and a thin strip of 40 × 2 vertices reaching to x = 3 (both
    /// spacing 0.05, jittered by up to 1e-3 so that no vertex is equidistant from two samples),
    /// with unit masses.
    fn square_and_strip() -> (TriMesh, Vec<f64>) {
        let mut jitter = uniform(11);
        let mut positions = Vec::new();
        let mut faces = Vec::new();
        let mut grid = |nx: usize, ny: usize, x0: f64, y0: f64| {
            let base = positions.len() as u32;
            for j in 0..ny {
                for i in 0..nx {
                    positions.push([
                        x0 + 0.05 * i as f64 + 2e-3 * jitter(),
                        y0 + 0.05 * j as f64 + 2e-3 * jitter(),
                        0.0,
                    ]);
                }
            }
            for j in 0..ny - 1 {
                for i in 0..nx - 1 {
                    let v = base + (j * nx + i) as u32;
                    let nx = nx as u32;
                    faces.push([v, v + 1, v + nx + 1]);
                    faces.push([v, v + nx + 1, v + nx]);
                }
            }
        };
        grid(21, 21, 0.0, 0.0);
        grid(40, 2, 1.05, 0.5);
        let n = positions.len();
        (TriMesh::new(positions, faces).unwrap(), vec![1.0; n])
    }

    fn covering_radius(mesh: &TriMesh, samples: &[u32]) -> f64 {
        let d = |a: [f64; 3], b: [f64; 3]| ((a[0] - b[0]).powi(2) + (a[1] - b[1]).powi(2)).sqrt();
        mesh.positions
            .iter()
            .map(|&p| {
                samples
                    .iter()
                    .map(|&s| d(p, mesh.positions[s as usize]))
                    .fold(f64::INFINITY, f64::min)
            })
            .fold(0.0, f64::max)
    }

    /// Farthest-point samples cover the thin strip as well as the square (uniform random ones
    /// of the same size leave gaps more than twice as wide), and their weights are the masses of
    /// the vertices nearest to each (a brute-force check), summing to the total.
    #[test]
    fn spread_samples_cover_thin_parts_and_weigh_their_nearest_vertices() {
        let (mesh, mass) = square_and_strip();
        let n = mesh.num_vertices();
        let (samples, weights) = spread_samples(&mesh, &mass, 60);
        assert_eq!(samples.len(), 60);
        assert!(samples.windows(2).all(|w| w[0] < w[1]), "sorted and distinct");
        let spread = covering_radius(&mesh, &samples);
        let random = covering_radius(&mesh, &sample_indices(n, 60, 0x200d_0017));
        assert!(spread < 0.2, "covering radius {spread}");
        assert!(random > 2.0 * spread, "random {random} against spread {spread}");
        let on_strip = samples
            .iter()
            .filter(|&&s| mesh.positions[s as usize][0] > 1.025)
            .count();
        assert!(on_strip >= 5, "{on_strip} samples on the strip");
        let mut expected = vec![0.0; samples.len()];
        for (v, p) in mesh.positions.iter().enumerate() {
            let d = |s: u32| {
                let q = mesh.positions[s as usize];
                (p[0] - q[0]).powi(2) + (p[1] - q[1]).powi(2)
            };
            let nearest = (0..samples.len())
                .min_by(|&a, &b| d(samples[a]).total_cmp(&d(samples[b])))
                .unwrap();
            expected[nearest] += mass[v];
        }
        assert_eq!(weights, expected);
        assert_eq!(weights.iter().sum::<f64>(), n as f64);
        // every vertex, with its own mass, when asked for as many samples as vertices or more
        let masses: Vec<f64> = (0..n).map(|v| 1.0 + v as f64 / n as f64).collect();
        let (all, own) = spread_samples(&mesh, &masses, n + 5);
        assert_eq!(all, (0..n as u32).collect::<Vec<_>>());
        assert_eq!(own, masses);
        // four distinct positions, each twice: four samples, each with both copies' mass
        let square = [[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [1.0, 1.0, 0.0], [0.0, 1.0, 0.0]];
        let twice: Vec<[f64; 3]> = square.iter().chain(&square).copied().collect();
        let doubled = TriMesh::new(twice, vec![[0, 1, 2], [0, 2, 3], [4, 5, 6], [4, 6, 7]]).unwrap();
        let (four, w) = spread_samples(&doubled, &[1.0; 8], 6);
        assert_eq!(four.len(), 4);
        assert_eq!(w, vec![2.0; 4]);
    }

    /// A seeded generator of uniform numbers in [−0.5, 0.5) (a linear congruential sequence).
    fn uniform(seed: u64) -> impl FnMut() -> f64 {
        let mut state = seed;
        move || {
            state = state
                .wrapping_mul(6364136223846793005)
                .wrapping_add(1442695040888963407);
            (state >> 11) as f64 / (1u64 << 53) as f64 - 0.5
        }
    }

    #[test]
    fn nearest_rows_is_the_brute_force_nearest_neighbour() {
        let mut next = uniform(3);
        let points = Mat::<f64>::from_fn(300, 7, |_, _| next());
        let queries = Mat::<f64>::from_fn(250, 7, |_, _| next());
        let got = nearest_rows(queries.as_ref(), points.as_ref());
        for i in 0..250 {
            let d = |w: usize| (0..7).map(|j| (queries[(i, j)] - points[(w, j)]).powi(2)).sum::<f64>();
            let best = (0..300).min_by(|&a, &b| d(a).total_cmp(&d(b))).unwrap();
            assert_eq!(got[i] as usize, best);
        }
    }

    /// Descents of one query from several starts sharing their paths end where each would on
    /// its own, at a vertex no neighbour of which is nearer; the squared distances agree with a
    /// plain sum to rounding.
    #[test]
    fn shared_descents_end_where_single_ones_do() {
        let mut next = uniform(11);
        // a 30 × 30 grid graph, 13-dimensional points (a remainder after the 8 lanes)
        let m = 30;
        let neighbors: Vec<Vec<u32>> = (0..m * m)
            .map(|w| {
                let (i, j) = (w % m, w / m);
                let mut nb = Vec::new();
                if i > 0 {
                    nb.push((w - 1) as u32);
                }
                if i + 1 < m {
                    nb.push((w + 1) as u32);
                }
                if j > 0 {
                    nb.push((w - m) as u32);
                }
                if j + 1 < m {
                    nb.push((w + m) as u32);
                }
                nb
            })
            .collect();
        let points = Mat::<f64>::from_fn(m * m, 13, |w, j| match j {
            0 => (w % m) as f64 / m as f64,
            1 => (w / m) as f64 / m as f64,
            _ => 0.002 * next(),
        });
        let by_point: Vec<f64> = (0..m * m).flat_map(|w| points.row(w).iter().copied()).collect();
        let mut merged = 0;
        let mut shared = Descent::new(&by_point, 13);
        for _ in 0..200 {
            let q: Vec<f64> = (0..13).map(|_| next() + 0.5).collect();
            let query = faer::Row::<f64>::from_fn(13, |j| q[j]);
            // the squared distances: every form the same, a plain sum's to rounding
            let d = |w: u32| distance2(points.as_ref(), query.as_ref(), w);
            let plain = (0..13).map(|j| (points[(77, j)] - q[j]).powi(2)).sum::<f64>();
            assert!((d(77) - plain).abs() <= 1e-15 * plain);
            shared.start_query(query.as_ref());
            assert_eq!(shared.distance(77), d(77));
            for start in [0u32, 29, 870, 899, 450] {
                let before = shared.visited.len();
                let end = shared.descend(&neighbors, start);
                let mut single = Descent::new(&by_point, 13);
                single.start_query(query.as_ref());
                assert_eq!(end, single.descend(&neighbors, start));
                assert!(neighbors[end as usize].iter().all(|&u| d(u) >= d(end)));
                // a shorter path than its own: it met an earlier one
                merged += usize::from(shared.visited.len() - before < single.visited.len());
            }
        }
        assert!(merged > 0, "no descent met an earlier path");
    }

    #[test]
    fn refinement_names_round_trip() {
        for r in [Refinement::None, Refinement::ZoomOut] {
            assert_eq!(r.name().parse::<Refinement>().unwrap(), r);
        }
        assert!("zoom".parse::<Refinement>().is_err());
        for o in [ZoomOutOutput::Auto, ZoomOutOutput::Vertex, ZoomOutOutput::Projected] {
            assert_eq!(o.name().parse::<ZoomOutOutput>().unwrap(), o);
        }
        assert!("points".parse::<ZoomOutOutput>().is_err());
    }

    /// `Auto` is the vertex map between meshes of one triangulation (whatever their positions),
    /// projected points when the faces or the vertex count differ; the others stay as given.
    #[test]
    fn auto_output_follows_the_triangulation() {
        let square = |z: f64, faces: Vec<[u32; 3]>| {
            TriMesh::new(
                vec![[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [1.0, 1.0, z], [0.0, 1.0, 0.0]],
                faces,
            )
            .unwrap()
        };
        let a = square(0.0, vec![[0, 1, 2], [0, 2, 3]]);
        let moved = square(0.5, vec![[0, 1, 2], [0, 2, 3]]);
        let flipped = square(0.0, vec![[0, 1, 3], [1, 2, 3]]);
        let mut more = square(0.0, vec![[0, 1, 2], [0, 2, 3]]);
        more.positions.push([2.0, 2.0, 0.0]);
        let auto = ZoomOutOutput::Auto;
        assert_eq!(auto.for_pair(&a, &moved), ZoomOutOutput::Vertex);
        assert_eq!(auto.for_pair(&a, &flipped), ZoomOutOutput::Projected);
        assert_eq!(auto.for_pair(&a, &more), ZoomOutOutput::Projected);
        assert_eq!(ZoomOutOutput::Vertex.for_pair(&a, &flipped), ZoomOutOutput::Vertex);
        assert_eq!(ZoomOutOutput::Projected.for_pair(&a, &moved), ZoomOutOutput::Projected);
    }
}
