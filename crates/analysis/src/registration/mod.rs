//! Surface registration through disk maps and a landmark-constrained harmonic map
//! [Su et al. 2015, "Shape classification using Wasserstein distance for brain morphometry
//! analysis", Algorithm 4, §5.3].
//!
//! Two disk-type surfaces S₁, S₂ with landmark pairs (l1_k, l2_k):
//! 1. disk maps φ₁: S₁ → D, φ₂: S₂ → D: area-preserving by OMT ([`Method::Omt`],
//!    [`crate::area_preserving::area_preserving_map`]) or conformal ([`Method::Conformal`],
//!    the baseline: `shapespace_conformal::disk_map`), each with its own interior/boundary
//!    markers (p ↦ 0, q ↦ 1);
//! 2. the harmonic map g of the planar triangulation φ₁(S₁) into D with the cotangent weights
//!    of the planar mesh φ₁(S₁) ([`HarmonicWeights::Planar`], signed, [`planar_harmonic_map`];
//!    or the intrinsic Delaunay weights of `shapespace_conformal::harmonic_map`,
//!    [`HarmonicWeights::IntrinsicDelaunay`]) with
//!    * **boundary**: every boundary vertex of S₁ keeps its position φ₁(v) on the circle
//!      (a choice: both disk maps send their boundary marker to 1 and distribute the boundary by
//!      their own rule, so the boundaries already correspond to the precision of those rules;
//!      sliding by arc length would replace φ₁'s boundary distribution by a chord-length one);
//!    * **landmarks** pinned: $g(\varphi_1(l1_k)) = \varphi_2(l2_k)$;
//!
//!    $$ (L g)_i = 0 \ \text{at free interior vertices}, \quad g = \varphi_1 \ \text{on } \partial S_1, \quad g(\varphi_1(l1_k)) = \varphi_2(l2_k); $$
//! 3. composition f = φ₂⁻¹ ∘ g ∘ φ₁ by point location ([`crate::point_location`]): for each
//!    vertex v of S₁ the point g(φ₁(v)) is located in the triangulation φ₂(S₂) (bounding-volume hierarchy;
//!    points a hair outside its boundary polygon snap to the nearest boundary triangle), and
//!    f(v) is the barycentric point of the corresponding 3D triangle of S₂.
//!
//! Why planar weights by default (measured, wolf0 → wolf1, OMT): an area-preserving (centroid)
//! map folds a few faces (229 of 8,634 on the wolf, 3.6% of the area); the intrinsic Delaunay
//! weights treat those faces as unfolded, so g is not the identity even for a surface registered
//! to itself (mean geodesic error 0.026 of √area); the planar weights reproduce linear maps
//! exactly, g is then the identity up to roundoff, and the mean geodesic error of wolf0 → wolf1
//! drops from 0.032 to 0.024. The price: the folds of φ₁ stay in g (flipped area 3.6% instead
//! of 2.3%).
//!
//! Default g for OMT ([`HarmonicParams::for_method`], measured in `docs/decisions/0015-registration-harmonic-map.md`): planar
//! weights; if one solve folds, the landmarks move to their targets in 16 steps (each solved
//! with the weights of the previous layout), then folded faces are untangled with the boundary
//! and landmarks fixed ([`crate::fold_repair::untangle_kernels`]): 0 folded faces of g on all
//! six wolf pairs (one solve: 9.2 per pair), geodesic mean 0.0282 (one solve: 0.0292). Not a
//! guarantee: on the lion, cat, horse, centaur and remeshed wolf pairs folds are left. Those
//! are re-embedded with the landmarks released ([`HarmonicParams::release_landmarks`]): the
//! region repair with the boundary alone fixed, an embedding by Floater's theorem, the
//! landmarks then a little off their targets ([`HarmonicRelease::landmark_shift`];
//! `docs/decisions/0062-release-the-landmarks-where-g-folds.md`). With the landmarks held
//! (`--untangle-g held`) folds stay; opt-in ([`HarmonicParams::foldover_free`], `--untangle-g
//! foldover-free`): the folds left with the landmarks held are untangled by the foldover-free
//! untangling ([`harmonic_folds`]), around the folds from g, else on the whole disk from φ₁;
//! measured in `docs/experiments.md` (every lion pair unfolded, 3 of 12 cat pairs, no centaur
//! pair).
//!
//! Radó's theorem makes g bijective only without interior constraints; hard landmark pins can
//! fold it (`docs/conventions.md`, "Registration"), and the disk maps themselves may fold: [`metrics`] measures flips.

pub mod bench;
mod box_tree;
pub mod geodesic;
pub mod harmonic_folds;
pub mod landmarks;
pub mod metrics;
pub mod point_location;
pub mod sphere;
pub mod sphere_bench;
pub mod truth;
pub mod untangle;
pub mod zoomout;

use std::time::Instant;

use serde::Serialize;
use shapespace_conformal::{disk_map, harmonic_map, BoundaryConstraint, HarmonicConstraints, Markers};
use shapespace_geometry::{Connectivity, TriMesh};

use crate::area_preserving::{area_preserving_map, AreaPreservingParams};
use crate::error::AnalysisError;
use crate::fold_repair::{count_folded_faces, mean_value_tutte_map, untangle_kernels, UntangleInfo};
use crate::point_location::PointLocator;

use harmonic_folds::untangle_harmonic_folds;
pub use harmonic_folds::{HarmonicUntangleInfo, UNTANGLE_RINGS, UNTANGLE_ROUNDS};
pub use landmarks::Landmarks;
pub use metrics::{registration_metrics, registration_metrics_against, MetricParams, RegistrationMetrics};
pub use zoomout::{Refinement, SpectralBasis, ZoomOutOutput, ZoomOutParams};

/// Weights of the harmonic map g.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize)]
#[serde(rename_all = "kebab-case")]
pub enum HarmonicWeights {
    /// The cotangent weights of the planar mesh φ₁(S₁) itself, with signed angles (a folded
    /// face of φ₁ contributes negative cotangents). Linear precision holds for any planar
    /// configuration, folds included, so with landmarks that agree with φ₁ g is exactly the
    /// identity. Solved by sparse Cholesky, with an LU fallback when folds make the matrix
    /// indefinite. Default.
    #[default]
    Planar,
    /// The planar cotangent weights with every negative edge weight (obtuse pairs of angles,
    /// folded faces) set to 0: a convex-combination map where every vertex keeps a positive
    /// weight, but linear precision is lost at the clamped edges.
    PlanarClamped,
    /// Floater's mean-value weights of the planar mesh φ₁(S₁) (unsigned angles, all > 0;
    /// [`crate::fold_repair::mean_value_tutte_map`]). On an embedded φ₁ they are its mean value
    /// coordinates, so g reproduces φ₁ exactly when the landmarks agree (like `Planar`), and
    /// without landmarks Floater's theorem makes g an embedding.
    MeanValue,
    /// The weights of the intrinsic Delaunay triangulation of φ₁(S₁)'s edge lengths
    /// (`shapespace_conformal::harmonic_map`): all ≥ 0, but a folded face of φ₁ is treated as
    /// unfolded, so g is not the identity on a folded φ₁ even without landmark displacement.
    IntrinsicDelaunay,
}

impl HarmonicWeights {
    /// `planar`, `planar-clamped`, `mean-value` or `intrinsic-delaunay`.
    pub fn name(self) -> &'static str {
        match self {
            HarmonicWeights::Planar => "planar",
            HarmonicWeights::PlanarClamped => "planar-clamped",
            HarmonicWeights::MeanValue => "mean-value",
            HarmonicWeights::IntrinsicDelaunay => "intrinsic-delaunay",
        }
    }
}

impl std::str::FromStr for HarmonicWeights {
    type Err = AnalysisError;
    /// Parses `planar`, `planar-clamped`, `mean-value` or `intrinsic-delaunay` (case-insensitive).
    fn from_str(s: &str) -> Result<Self, Self::Err> {
        match s.trim().to_ascii_lowercase().as_str() {
            "planar" => Ok(HarmonicWeights::Planar),
            "planar-clamped" | "clamped" => Ok(HarmonicWeights::PlanarClamped),
            "mean-value" | "mvc" | "floater" => Ok(HarmonicWeights::MeanValue),
            "intrinsic-delaunay" | "idt" => Ok(HarmonicWeights::IntrinsicDelaunay),
            other => Err(AnalysisError::InvalidInput(format!(
                "unknown harmonic weights `{other}` (expected planar, planar-clamped, mean-value or intrinsic-delaunay)"
            ))),
        }
    }
}

/// How the harmonic map g is computed: its weights, and whether its folds are repaired.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize)]
pub struct HarmonicParams {
    /// Weights of g.
    pub weights: HarmonicWeights,
    /// Untangle folded faces of g with [`crate::fold_repair::untangle_kernels`], the boundary
    /// and the landmark vertices held fixed. (The Tutte-region repair of
    /// [`crate::fold_repair::repair_folds`] does not apply with landmarks held: its whole-disk
    /// solve still folds on every wolf pair; see [`HarmonicParams::release_landmarks`].)
    pub fold_repair: bool,
    /// After the kernel moves of [`HarmonicParams::fold_repair`], untangle the folds they leave
    /// with the foldover-free untangling ([`harmonic_folds`]; disk registration only).
    /// Off by default: it unfolds every lion pair but 3 of 12 cat pairs and no centaur pair,
    /// at 7–75 s a pair (`docs/experiments.md`).
    pub foldover_free: bool,
    /// When folds of g are left after the untangling, re-embed them with the landmarks released:
    /// the disk maps' region repair ([`crate::fold_repair::repair_folds`]) with the boundary
    /// alone fixed. Its Tutte rounds end, at the latest, in a whole-disk solve whose boundary is
    /// the convex unit circle, an embedding by Floater's theorem; its retraction then returns
    /// every vertex, landmarks included, as far towards g as the embedding allows. The landmarks
    /// miss their targets by what is left ([`HarmonicRelease::landmark_shift`]). On the sphere
    /// the chart stays with its landmarks held (the release made the maps worse there,
    /// `docs/experiments.md`); instead the faces of g's image that fold on S² are re-embedded by
    /// the sphere maps' chart repair, which may move a landmark
    /// ([`sphere::SphereHarmonicRepair`]). On by default for OMT (decision 0062).
    pub release_landmarks: bool,
    /// Number K ≥ 1 of steps in which the landmarks move from φ₁(l1_k) to φ₂(l2_k) when one
    /// solve on φ₁ folds; each step solves with the weights of the previous step's layout.
    pub landmark_steps: usize,
}

impl Default for HarmonicParams {
    /// One solve with the planar weights, no untangling (Su et al.'s g; the conformal default).
    fn default() -> Self {
        HarmonicParams {
            weights: HarmonicWeights::Planar,
            fold_repair: false,
            foldover_free: false,
            release_landmarks: false,
            landmark_steps: 1,
        }
    }
}

impl HarmonicParams {
    /// The default g of a method. OMT: planar weights, [`OMT_LANDMARK_STEPS`] landmark steps,
    /// untangling on (measured on the wolf poses: 0 flipped faces of g on all six pairs, geodesic
    /// mean 0.0282 vs 0.0292 for one solve; `docs/decisions/0015-registration-harmonic-map.md`),
    /// the folds it leaves re-embedded with the landmarks released
    /// (`docs/decisions/0062-release-the-landmarks-where-g-folds.md`). Conformal: [`Default`] (the
    /// baseline as published; steps and untangling leave it folding 6–8% of the area).
    pub fn for_method(method: Method) -> Self {
        match method {
            Method::Omt => HarmonicParams {
                weights: HarmonicWeights::Planar,
                fold_repair: true,
                foldover_free: false,
                release_landmarks: true,
                landmark_steps: OMT_LANDMARK_STEPS,
            },
            Method::Conformal => HarmonicParams::default(),
        }
    }
}

/// The region repair of the `folded_before` folded faces of `uv` (g, #V₁, of the faces of
/// `source`) with the vertices flagged `boundary` alone fixed
/// ([`HarmonicParams::release_landmarks`]); `uv` is replaced only by a map without folds.
/// `targets`: each landmark pair's target, in `pairs`' order.
fn release_landmarks(
    source: &TriMesh,
    boundary: &[bool],
    pairs: &[(u32, u32)],
    targets: &[[f64; 2]],
    folded_before: usize,
    uv: &mut [[f64; 2]],
) -> HarmonicRelease {
    let mut repaired = uv.to_vec();
    let result = crate::fold_repair::repair_folds(
        source,
        boundary,
        &mut repaired,
        &crate::fold_repair::FoldRepairParams::default(),
    );
    let mut release = HarmonicRelease {
        folded_before,
        folded_after: folded_before,
        region_vertices: 0,
        rounds: 0,
        landmark_shift: 0.0,
        error: None,
    };
    match result {
        Ok(info) if info.folded_after == 0 && count_folded_faces(&source.faces, &repaired) == 0 => {
            uv.copy_from_slice(&repaired);
            release.folded_after = 0;
            release.region_vertices = info.region_vertices;
            release.rounds = info.rounds;
        }
        Ok(info) => release.error = Some(format!("{} faces left folded", info.folded_after)),
        Err(e) => release.error = Some(e.to_string()),
    }
    release.landmark_shift = pairs
        .iter()
        .zip(targets)
        .map(|(&(a, _), q)| {
            let p = uv[a as usize];
            (p[0] - q[0]).hypot(p[1] - q[1])
        })
        .fold(0.0, f64::max);
    release
}

/// Landmark steps of the default g for [`Method::Omt`].
pub const OMT_LANDMARK_STEPS: usize = 16;

/// Sweep cap of the untangling of g ([`crate::fold_repair::untangle_kernels`]).
pub const UNTANGLE_SWEEPS: usize = 200;

/// Which disk maps φ₁, φ₂ the registration uses.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Hash, Serialize, serde::Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum Method {
    /// Area-preserving maps by optimal mass transport (Su et al. 2015, Alg. 2).
    #[default]
    Omt,
    /// Conformal maps (the baseline of Su et al. 2015, Fig. 7).
    Conformal,
}

impl Method {
    /// `omt` or `conformal`.
    pub fn name(self) -> &'static str {
        match self {
            Method::Omt => "omt",
            Method::Conformal => "conformal",
        }
    }
}

impl std::fmt::Display for Method {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(self.name())
    }
}

impl std::str::FromStr for Method {
    type Err = AnalysisError;
    /// Parses `omt` (also `area-preserving`) or `conformal`, case-insensitive.
    fn from_str(s: &str) -> Result<Self, Self::Err> {
        match s.trim().to_ascii_lowercase().as_str() {
            "omt" | "area-preserving" => Ok(Method::Omt),
            "conformal" => Ok(Method::Conformal),
            other => Err(AnalysisError::InvalidInput(format!(
                "unknown registration method `{other}` (expected omt or conformal)"
            ))),
        }
    }
}

/// Parameters of [`register`].
#[derive(Clone, Debug)]
pub struct RegistrationParams {
    /// Disk maps by OMT (default) or conformal.
    pub method: Method,
    /// Disk-map markers of S₁ (interior p ↦ 0, boundary q ↦ 1).
    pub source_markers: Markers,
    /// Disk-map markers of S₂.
    pub target_markers: Markers,
    /// Parameters of the area-preserving map; its `disk_map` field also parameterizes the
    /// conformal maps of [`Method::Conformal`]. Default: [`registration_area_params`].
    pub area_preserving: AreaPreservingParams,
    /// Weights, landmark steps and untangling of the harmonic map g (set it with
    /// [`HarmonicParams::for_method`] when changing `method`).
    pub harmonic: HarmonicParams,
    /// Refinement of f after the disk-map stage (default ZoomOut, decision 0065).
    pub refine: Refinement,
    /// Parameters of the ZoomOut refinement.
    pub zoomout: ZoomOutParams,
}

impl Default for RegistrationParams {
    fn default() -> Self {
        RegistrationParams {
            method: Method::Omt,
            source_markers: Markers::default(),
            target_markers: Markers::default(),
            area_preserving: registration_area_params(),
            harmonic: HarmonicParams::for_method(Method::Omt),
            refine: Refinement::ZoomOut,
            zoomout: ZoomOutParams::default(),
        }
    }
}

/// The area-preserving parameters used for registration: the defaults of
/// [`AreaPreservingParams`] except `require_convergence = false`: an OT solve that stops at its
/// iteration cap slightly above its tolerance (cell areas off by ~1e-6 relative) still gives a
/// usable disk map (up to [`MAX_USABLE_OT_ERROR`]); the reached accuracy is kept in
/// [`DiskImage::ot_max_relative_error`].
///
/// The fold repair skips the kernel untangling ([`crate::fold_repair::FoldRepairParams::untangle_sweeps`] = 0):
/// measured with `shapespace register-bench datasets/poses`, untangling first gave
/// the wolf a geodesic error of 0.0296 / 0.0232 (mean / median) against 0.0282 / 0.0224 with
/// the Tutte rounds alone, and the centaur 0.0699 / 0.0510 against 0.0692 / 0.0538; the Tutte
/// rounds place a repaired vertex by the mean-value weights of its neighbours, which the
/// planar cotangent weights of g seem to prefer to the kernel centroid.
pub fn registration_area_params() -> AreaPreservingParams {
    let mut params = AreaPreservingParams {
        require_convergence: false,
        ..AreaPreservingParams::default()
    };
    params.fold_repair.untangle_sweeps = 0;
    params
}

/// The largest OT mass error (max_i |μ(W_i) − ν_i|/ν_i) at which a non-converged area-preserving
/// map is still used for registration (cell areas within 0.1 %); beyond it [`disk_image`] fails
/// with the solver's reason instead of registering through a map that is not area-preserving.
pub const MAX_USABLE_OT_ERROR: f64 = 1e-3;

/// A disk image φ(S) of a surface: #V planar positions in the unit disk and how long it took.
#[derive(Clone, Debug, PartialEq)]
pub struct DiskImage {
    /// φ(v) per vertex, #V.
    pub uv: Vec<[f64; 2]>,
    /// The method that made it.
    pub method: Method,
    /// Wall-clock seconds.
    pub seconds: f64,
    /// For [`Method::Omt`]: max_i |μ(W_i) − ν_i|/ν_i reached by the OT solver (NaN for conformal).
    pub ot_max_relative_error: f64,
    /// For [`Method::Omt`]: faces of the disk image with reversed orientation (the centroid map
    /// is not guaranteed to be an embedding); for conformal maps likewise.
    pub flipped_faces: usize,
}

/// The disk map of `mesh` by `method` (module docs, step 1). Errors from the conformal map or
/// the OT solver.
pub fn disk_image(
    mesh: &TriMesh,
    markers: &Markers,
    method: Method,
    params: &AreaPreservingParams,
) -> Result<DiskImage, AnalysisError> {
    let t = Instant::now();
    let (uv, ot_max_relative_error) = match method {
        Method::Omt => {
            let ap = area_preserving_map(mesh, markers, params)?;
            if !(ap.ot.max_relative_error <= MAX_USABLE_OT_ERROR) {
                return Err(AnalysisError::Transport(shapespace_omt::OmtError::NoConvergence {
                    iterations: ap.ot.iterations,
                    residual: ap.ot.max_relative_error,
                    tolerance: MAX_USABLE_OT_ERROR,
                    reason: format!("area-preserving map for registration: {}", ap.ot.stop),
                }));
            }
            (ap.uv, ap.ot.max_relative_error)
        }
        Method::Conformal => (
            disk_map(mesh, markers, &params.disk_map)
                .map_err(AnalysisError::DiskMap)?
                .uv,
            f64::NAN,
        ),
    };
    let seconds = t.elapsed().as_secs_f64();
    let flipped_faces = mesh
        .faces
        .iter()
        .filter(|f| {
            let [a, b, c] = [uv[f[0] as usize], uv[f[1] as usize], uv[f[2] as usize]];
            (b[0] - a[0]) * (c[1] - a[1]) - (b[1] - a[1]) * (c[0] - a[0]) <= 0.0
        })
        .count();
    Ok(DiskImage {
        uv,
        method,
        seconds,
        ot_max_relative_error,
        flipped_faces,
    })
}

/// Wall-clock seconds of the stages of a registration.
#[derive(Clone, Debug, Default, PartialEq, Serialize)]
pub struct RegistrationTimings {
    /// Disk map of S₁.
    pub source_map: f64,
    /// Disk map of S₂.
    pub target_map: f64,
    /// Harmonic map g.
    pub harmonic: f64,
    /// Point location and barycentric images.
    pub composition: f64,
    /// Refinement: the eigenpairs of both surfaces and the ZoomOut iterations (0 without).
    pub refine: f64,
    /// Sum of the above, each part's own wall time: what one registration from scratch costs
    /// with its parts one after the other ([`register`] runs the disk maps side by side and the
    /// eigenpairs beside the first stage, so its own wall time can be lower).
    pub total: f64,
}

/// What a refinement did ([`refine_registration`]).
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct RefinementInfo {
    /// The refinement applied.
    pub refinement: Refinement,
    /// Spectral sizes visited by the kept ZoomOut run.
    pub sizes: Vec<usize>,
    /// ZoomOut's runs, one per first spectral size, with their residuals and the one kept.
    pub runs: Vec<zoomout::ZoomOutRun>,
    /// Vertex map or projected points.
    pub output: ZoomOutOutput,
    /// Seconds of the eigenpairs of S₁ and S₂ (as computed, possibly once for many pairs).
    pub eigen_seconds: [f64; 2],
    /// Seconds of the iterations (with both untanglings).
    pub iteration_seconds: f64,
    /// Source vertices whose nearest target vertex changed from the first stage's.
    pub vertices_moved: usize,
    /// The 3D untangling of the vertex map ([`untangle`]).
    pub untangle: untangle::VertexMapUntangleInfo,
    /// The untangling with points inside the target's faces after it
    /// ([`untangle::untangle_points`]).
    pub point_untangle: untangle::PointUntangleInfo,
    /// The refined vertex map before the point untangling, #V₁.
    #[serde(skip)]
    pub vertex_map: Vec<u32>,
}

/// A registration f: S₁ → S₂ (module docs).
#[derive(Clone, Debug)]
pub struct Registration {
    /// The disk maps used.
    pub method: Method,
    /// φ₁(v) per vertex of S₁, #V₁.
    pub source_uv: Vec<[f64; 2]>,
    /// φ₂(w) per vertex of S₂, #V₂.
    pub target_uv: Vec<[f64; 2]>,
    /// g(φ₁(v)) per vertex of S₁, #V₁.
    pub harmonic_uv: Vec<[f64; 2]>,
    /// Face of S₂ holding f(v), per vertex of S₁ (#V₁).
    pub faces: Vec<u32>,
    /// Barycentric coordinates of f(v) in that face (corners in the face's order), #V₁.
    pub bary: Vec<[f64; 3]>,
    /// f(v) in 3D on S₂, #V₁.
    pub points: Vec<[f64; 3]>,
    /// Vertices whose g-image lay outside φ₂(S₂) and was snapped onto it.
    pub num_snapped: usize,
    /// Largest snap distance in the disk.
    pub max_snap_distance: f64,
    /// Folded faces of g ∘ φ₁ (exact predicate, [`crate::fold_repair::count_folded_faces`])
    /// as computed, before any fold repair.
    pub harmonic_folded: usize,
    /// Landmark steps used: 1, or [`HarmonicParams::landmark_steps`] when one solve folded.
    pub harmonic_steps: usize,
    /// What the fold repair of g did (when [`HarmonicParams::fold_repair`] is on).
    pub harmonic_fold_repair: Option<UntangleInfo>,
    /// What the foldover-free untangling of the folds the kernel moves left did
    /// ([`harmonic_folds`]; `None` when none were left).
    pub harmonic_untangled: Option<HarmonicUntangleInfo>,
    /// The region repair of the folds left with the landmarks released
    /// ([`HarmonicParams::release_landmarks`]; `None` when no fold was left).
    pub harmonic_released: Option<HarmonicRelease>,
    /// The refinement applied after the disk-map stage, if any: `faces`, `bary` and `points` are
    /// then the refined map's, while `harmonic_uv` stays the first stage's.
    pub refinement: Option<RefinementInfo>,
    /// Stage timings.
    pub timings: RegistrationTimings,
}

/// What the region repair of g with the landmarks released did
/// ([`HarmonicParams::release_landmarks`]).
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct HarmonicRelease {
    /// Folded faces of g before it.
    pub folded_before: usize,
    /// Folded faces after it: 0, unless the repair failed (`error`), and g was then kept.
    pub folded_after: usize,
    /// Interior vertices in its last region, and its Tutte rounds.
    pub region_vertices: usize,
    pub rounds: usize,
    /// The largest distance in the disk between a landmark's image and its target φ₂(l₂).
    pub landmark_shift: f64,
    /// The repair's error, when it failed.
    pub error: Option<String>,
}

/// Registers S₁ (`source`) onto S₂ (`target`) by f = φ₂⁻¹ ∘ g ∘ φ₁ (module docs): computes
/// both disk maps by `params.method`, then [`register_with_maps`], then the refinement
/// `params.refine` (ZoomOut by default: both meshes' eigenpairs, computed beside the first
/// stage, and [`refine_registration`]).
///
/// Errors: invalid landmarks (out of range, repeated, on the boundary: named), a disk map that
/// fails, a harmonic map that cannot be solved; with ZoomOut, eigenpairs that fail (named
/// `source` or `target`; among them a mesh with fewer vertices than `zoomout.k_end`) and
/// ZoomOut's errors ([`zoomout::zoomout`]).
pub fn register(
    source: &TriMesh,
    target: &TriMesh,
    landmarks: &Landmarks,
    params: &RegistrationParams,
) -> Result<Registration, AnalysisError> {
    // Which surface failed, in every error before the harmonic map: the topology first (a
    // closed target would otherwise be reported as landmarks out of range), then the landmarks,
    // then the disk maps.
    let named = |name: &str, message: String| AnalysisError::Shape {
        name: name.to_string(),
        message,
    };
    for (name, mesh) in [("source", source), ("target", target)] {
        shapespace_geometry::topology::require_disk(mesh).map_err(|e| named(name, crate::error::error_chain(&e)))?;
    }
    check_landmarks(source, target, landmarks)?;
    let first_stage = || -> Result<Registration, AnalysisError> {
        // The two disk maps are independent: compute them in parallel.
        let (phi1, phi2) = rayon::join(
            || disk_image(source, &params.source_markers, params.method, &params.area_preserving),
            || disk_image(target, &params.target_markers, params.method, &params.area_preserving),
        );
        let phi1 = phi1.map_err(|e| named("source", crate::error::error_chain(&e)))?;
        let phi2 = phi2.map_err(|e| named("target", crate::error::error_chain(&e)))?;
        register_with_maps(source, target, &phi1, &phi2, landmarks, &params.harmonic)
    };
    let zoomout = (params.refine == Refinement::ZoomOut).then_some(&params.zoomout);
    refined_beside(source, target, landmarks, zoomout, first_stage)
}

/// `first_stage`, then with `zoomout` its refinement ([`refine_registration`]). The eigenpairs
/// need nothing from the first stage: they run beside it, on the cores its sequential parts
/// leave idle (the same bases, so the same map, as one after the other). Errors: the first
/// stage's, eigenpairs that fail (named `source` / `target`), the refinement's.
pub(crate) fn refined_beside<R: Refinable + Send>(
    source: &TriMesh,
    target: &TriMesh,
    landmarks: &Landmarks,
    zoomout: Option<&ZoomOutParams>,
    first_stage: impl FnOnce() -> Result<R, AnalysisError> + Send,
) -> Result<R, AnalysisError> {
    let Some(zoomout) = zoomout else {
        return first_stage();
    };
    let (reg, (b1, b2)) = rayon::join(first_stage, || {
        rayon::join(
            || SpectralBasis::of(source, zoomout.k_end, &zoomout.eigen),
            || SpectralBasis::of(target, zoomout.k_end, &zoomout.eigen),
        )
    });
    let mut reg = reg?;
    let named = |name: &str, e: AnalysisError| AnalysisError::Shape {
        name: name.to_string(),
        message: crate::error::error_chain(&e),
    };
    let b1 = b1.map_err(|e| named("source", e))?;
    let b2 = b2.map_err(|e| named("target", e))?;
    refine_registration(source, target, &mut reg, landmarks, &b1, &b2, zoomout)?;
    Ok(reg)
}

/// Refines a first-stage registration, on the disk ([`Registration`]) or on the sphere
/// ([`sphere::SphereRegistration`]), by ZoomOut ([`zoomout`]) seeded with its vertex map (the
/// corner of largest barycentric weight of each f(v)), with the spectral bases of S₁ and S₂ and
/// the landmarks (their geodesic distances join the embeddings), then untangles the result
/// with points inside the target's faces ([`untangle::untangle_points`], against the image of
/// S₂ the route's metric tests flips in: φ₂ or ψ₂) and, for projected output, smooths it
/// ([`ZoomOutParams::point_pass`]): replaces the map's faces, barycentric coordinates and
/// points, records [`RefinementInfo`], and adds the bases' and the iterations' seconds to the
/// timings. Errors from [`zoomout::zoomout`].
pub fn refine_registration(
    source: &TriMesh,
    target: &TriMesh,
    reg: &mut impl Refinable,
    landmarks: &Landmarks,
    source_basis: &SpectralBasis,
    target_basis: &SpectralBasis,
    params: &ZoomOutParams,
) -> Result<(), AnalysisError> {
    let (faces, bary) = reg.first_map();
    let refined = zoomout_refinement(
        (source, target),
        (faces, bary),
        reg.metric_image(),
        landmarks,
        (source_basis, target_basis),
        params,
    )?;
    reg.take_refined(refined);
    Ok(())
}

/// A registration [`refine_registration`] can refine: the disk route's [`Registration`] or the
/// sphere route's [`sphere::SphereRegistration`].
pub trait Refinable {
    /// The map to refine: per source vertex a face of S₂ and barycentric coordinates.
    fn first_map(&self) -> (&[u32], &[[f64; 3]]);
    /// The image of S₂ in which the route's metric locates the reference face of its 3D test.
    fn metric_image(&self) -> untangle::TargetImage<'_>;
    /// Takes the refined map: its faces, coordinates and points, its [`RefinementInfo`] and its
    /// seconds (added to the timings).
    fn take_refined(&mut self, refined: ZoomOutRefinement);
}

impl Refinable for Registration {
    fn first_map(&self) -> (&[u32], &[[f64; 3]]) {
        (&self.faces, &self.bary)
    }
    fn metric_image(&self) -> untangle::TargetImage<'_> {
        untangle::TargetImage::Disk(&self.target_uv)
    }
    fn take_refined(&mut self, refined: ZoomOutRefinement) {
        (self.faces, self.bary, self.points) = (refined.faces, refined.bary, refined.points);
        self.timings.refine = refined.seconds;
        self.timings.total += refined.seconds;
        self.refinement = Some(refined.info);
    }
}

/// A first-stage map refined by ZoomOut and untangled ([`refine_registration`]).
pub struct ZoomOutRefinement {
    /// Face of S₂, barycentric coordinates and 3D point of each f(v), #V₁.
    pub faces: Vec<u32>,
    pub bary: Vec<[f64; 3]>,
    pub points: Vec<[f64; 3]>,
    /// What the refinement did.
    pub info: RefinementInfo,
    /// Seconds of the bases (as computed), the iterations and the untangling with points.
    pub seconds: f64,
}

/// ZoomOut from the first-stage map `first` (per source vertex a face of S₂ and barycentric
/// coordinates; seeded with the corner of largest weight), then the untangling with points
/// against the metric's test in `image` (the disk or the sphere route's image of S₂), with
/// [`ZoomOutParams::point_pass`]. Errors from [`zoomout::zoomout`] and the untangling.
fn zoomout_refinement(
    (source, target): (&TriMesh, &TriMesh),
    (faces, bary): (&[u32], &[[f64; 3]]),
    image: untangle::TargetImage<'_>,
    landmarks: &Landmarks,
    (source_basis, target_basis): (&SpectralBasis, &SpectralBasis),
    params: &ZoomOutParams,
) -> Result<ZoomOutRefinement, AnalysisError> {
    let seed = zoomout::nearest_corner_map(target, faces, bary);
    let refined = zoomout::zoomout(
        source,
        target,
        source_basis,
        target_basis,
        &seed,
        &landmarks.pairs,
        params,
    )?;
    let vertices_moved = seed.iter().zip(&refined.vertex_map).filter(|(a, b)| a != b).count();
    let mut points: Vec<truth::SurfacePoint> = refined
        .faces
        .iter()
        .copied()
        .zip(refined.bary.iter().copied())
        .collect();
    let point_untangle =
        untangle::untangle_points(source, target, image, &mut points, &params.point_pass(refined.output))?;
    let positions = points
        .iter()
        .map(|&p| at_surface_point(&target.faces, &target.positions, p))
        .collect();
    let (faces, bary) = points.into_iter().unzip();
    let seconds = source_basis.seconds + target_basis.seconds + refined.seconds + point_untangle.seconds;
    Ok(ZoomOutRefinement {
        faces,
        bary,
        points: positions,
        seconds,
        info: RefinementInfo {
            refinement: Refinement::ZoomOut,
            sizes: refined.sizes,
            runs: refined.runs,
            output: refined.output,
            eigen_seconds: [source_basis.seconds, target_basis.seconds],
            iteration_seconds: refined.seconds + point_untangle.seconds,
            vertices_moved,
            untangle: refined.untangle,
            vertex_map: refined.vertex_map,
            point_untangle,
        },
    })
}

/// Σ_k b_k values[t_k] over the corners t of `face` (its 3D point with the mesh's positions,
/// its sphere image with ψ, ...).
pub(crate) fn at_surface_point(faces: &[[u32; 3]], values: &[[f64; 3]], (face, b): truth::SurfacePoint) -> [f64; 3] {
    let t = faces[face as usize];
    let mut x = [0.0; 3];
    for k in 0..3 {
        let q = values[t[k] as usize];
        for d in 0..3 {
            x[d] += b[k] * q[d];
        }
    }
    x
}

fn check_landmarks(source: &TriMesh, target: &TriMesh, landmarks: &Landmarks) -> Result<(), AnalysisError> {
    let b1 = Connectivity::of(source).boundary_vertices(source.num_vertices());
    let b2 = Connectivity::of(target).boundary_vertices(target.num_vertices());
    landmarks.validate(&b1, &b2)
}

/// Steps 2–3 of the module docs with given disk images φ₁ (#V₁) and φ₂ (#V₂): the harmonic map
/// g (with `weights`) with S₁'s boundary kept at φ₁ and the landmarks pinned to φ₂(l2_k), then
/// the composition by point location in φ₂(S₂). Timings include the disk images' `seconds`.
pub fn register_with_maps(
    source: &TriMesh,
    target: &TriMesh,
    phi1: &DiskImage,
    phi2: &DiskImage,
    landmarks: &Landmarks,
    harmonic: &HarmonicParams,
) -> Result<Registration, AnalysisError> {
    check_landmarks(source, target, landmarks)?;
    if phi1.uv.len() != source.num_vertices() || phi2.uv.len() != target.num_vertices() {
        return Err(AnalysisError::InvalidInput(format!(
            "disk images have {} and {} points for meshes of {} and {} vertices",
            phi1.uv.len(),
            phi2.uv.len(),
            source.num_vertices(),
            target.num_vertices()
        )));
    }
    let t0 = Instant::now();
    let n1 = source.num_vertices();
    let conn1 = Connectivity::of(source);
    let loops = conn1.boundary_loops(&source.faces);
    let boundary: Vec<(u32, [f64; 2])> = loops.iter().flatten().map(|&v| (v, phi1.uv[v as usize])).collect();
    // one solve on φ₁; if it folds, K steps: the landmarks move along the straight segments
    // φ₁(l1_k) → φ₂(l2_k), step s solved with the weights of the previous step's layout
    let solve_in_steps = |steps: usize| -> Result<Vec<[f64; 2]>, AnalysisError> {
        let mut uv = phi1.uv.clone();
        let mut cache = None;
        for s in 1..=steps {
            let t = s as f64 / steps as f64;
            let pins: Vec<(u32, [f64; 2])> = landmarks
                .pairs
                .iter()
                .map(|&(a, b)| {
                    let (x, y) = (phi1.uv[a as usize], phi2.uv[b as usize]);
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
            uv = harmonic_step(source, &uv, &boundary, pins, harmonic.weights, &mut cache)?;
        }
        Ok(uv)
    };
    let mut harmonic_uv = solve_in_steps(1)?;
    let mut steps_used = 1;
    if harmonic.landmark_steps > 1 && count_folded_faces(&source.faces, &harmonic_uv) > 0 {
        harmonic_uv = solve_in_steps(harmonic.landmark_steps)?;
        steps_used = harmonic.landmark_steps;
    }
    let harmonic_folded = count_folded_faces(&source.faces, &harmonic_uv);
    let mut harmonic_untangled = None;
    let harmonic_fold_repair = if harmonic.fold_repair && harmonic_folded > 0 {
        let mut held = conn1.boundary_vertices(n1);
        for &(a, _) in &landmarks.pairs {
            held[a as usize] = true;
        }
        let kernels = untangle_kernels(
            &source.faces,
            &conn1.vertex_faces,
            &held,
            &mut harmonic_uv,
            UNTANGLE_SWEEPS,
        );
        if harmonic.foldover_free && kernels.folded_after > 0 {
            let neighbors = conn1.vertex_neighbors(n1);
            harmonic_untangled = untangle_harmonic_folds(source, &neighbors, &phi1.uv, &held, &mut harmonic_uv);
        }
        Some(kernels)
    } else {
        None
    };
    let folded_left = if harmonic.release_landmarks {
        count_folded_faces(&source.faces, &harmonic_uv)
    } else {
        0
    };
    let harmonic_released = (folded_left > 0).then(|| {
        let targets: Vec<[f64; 2]> = landmarks.pairs.iter().map(|&(_, b)| phi2.uv[b as usize]).collect();
        release_landmarks(
            source,
            &conn1.boundary_vertices(n1),
            &landmarks.pairs,
            &targets,
            folded_left,
            &mut harmonic_uv,
        )
    });
    let t1 = Instant::now();

    let locator = PointLocator::new(&phi2.uv, &target.faces)?;
    let n = source.num_vertices();
    let mut faces = Vec::with_capacity(n);
    let mut bary = Vec::with_capacity(n);
    let mut points = Vec::with_capacity(n);
    let (mut num_snapped, mut max_snap_distance) = (0usize, 0.0f64);
    for (v, &p) in harmonic_uv.iter().enumerate() {
        let loc = locator.locate(p).ok_or_else(|| {
            AnalysisError::InvalidInput(format!(
                "the harmonic image {p:?} of source vertex {v} cannot be located (non-finite)"
            ))
        })?;
        if loc.snap_distance > 0.0 {
            num_snapped += 1;
            max_snap_distance = max_snap_distance.max(loc.snap_distance);
        }
        faces.push(loc.face);
        bary.push(loc.bary);
        points.push(at_surface_point(&target.faces, &target.positions, (loc.face, loc.bary)));
    }
    let t2 = Instant::now();
    let harmonic = (t1 - t0).as_secs_f64();
    let composition = (t2 - t1).as_secs_f64();
    Ok(Registration {
        method: phi1.method,
        source_uv: phi1.uv.clone(),
        target_uv: phi2.uv.clone(),
        harmonic_uv,
        faces,
        bary,
        points,
        num_snapped,
        max_snap_distance,
        harmonic_folded,
        harmonic_steps: steps_used,
        harmonic_fold_repair,
        harmonic_untangled,
        harmonic_released,
        refinement: None,
        timings: RegistrationTimings {
            source_map: phi1.seconds,
            target_map: phi2.seconds,
            harmonic,
            composition,
            refine: 0.0,
            total: phi1.seconds + phi2.seconds + harmonic + composition,
        },
    })
}

/// One solve of g with the weights of `layout` (#V), the boundary fixed and the `pins` held.
fn harmonic_step(
    source: &TriMesh,
    layout: &[[f64; 2]],
    boundary: &[(u32, [f64; 2])],
    pins: Vec<(u32, [f64; 2])>,
    weights: HarmonicWeights,
    cache: &mut Option<SymbolicCache>,
) -> Result<Vec<[f64; 2]>, AnalysisError> {
    match weights {
        HarmonicWeights::IntrinsicDelaunay => {
            let constraints = HarmonicConstraints {
                boundary: BoundaryConstraint::Fixed(boundary.to_vec()),
                landmarks: pins,
            };
            harmonic_map(layout, &source.faces, &constraints).map_err(AnalysisError::DiskMap)
        }
        HarmonicWeights::Planar => planar_harmonic_map_reusing(layout, &source.faces, boundary, &pins, false, cache),
        HarmonicWeights::PlanarClamped => {
            planar_harmonic_map_reusing(layout, &source.faces, boundary, &pins, true, cache)
        }
        HarmonicWeights::MeanValue => {
            let mut fixed: Vec<Option<[f64; 2]>> = vec![None; source.num_vertices()];
            for &(v, p) in boundary.iter().chain(&pins) {
                fixed[v as usize] = Some(p);
            }
            mean_value_tutte_map(source, layout, &fixed).map_err(AnalysisError::from_fold_repair)
        }
    }
}

/// The harmonic map of the planar triangulation (`positions` #V, `faces` #F) with the cotangent
/// weights of the planar triangles themselves (signed: cot θ = (u·v)/(u×v) with the signed cross
/// product, so folded faces give negative cotangents): (L g)_i = 0 at free vertices, g fixed at
/// the `fixed` vertices (boundary) and `pins` (landmarks). #V image positions. Solved by sparse
/// Cholesky, or LU when the system is indefinite (folded faces). With `clamp_negative`, every
/// edge weight (the sum of the two half-cotangents at the edge) below 0 is set to 0
/// ([`HarmonicWeights::PlanarClamped`]). Errors: a vertex constrained twice, a singular system.
pub fn planar_harmonic_map(
    positions: &[[f64; 2]],
    faces: &[[u32; 3]],
    fixed: &[(u32, [f64; 2])],
    pins: &[(u32, [f64; 2])],
    clamp_negative: bool,
) -> Result<Vec<[f64; 2]>, AnalysisError> {
    planar_harmonic_map_reusing(positions, faces, fixed, pins, clamp_negative, &mut None)
}

/// Symbolic factorizations of the planar Laplacian for the sparsity pattern (column pointers,
/// row indices of the full matrix) they were computed for: Cholesky of the lower triangle, and
/// LU once a Cholesky failed (an indefinite system).
struct SymbolicCache {
    col_ptr: Vec<usize>,
    row_idx: Vec<usize>,
    llt: faer::sparse::linalg::solvers::SymbolicLlt<usize>,
    lu: Option<faer::sparse::linalg::solvers::SymbolicLu<usize>>,
}

/// [`planar_harmonic_map`] reusing the symbolic factorizations in `cache` when the system's
/// sparsity pattern is the one they were made for (same faces and constrained vertices: the
/// landmark steps), and storing new ones otherwise.
///
/// The reduced system is the P1 stiffness matrix of the layout with Dirichlet rows removed:
/// symmetric, and positive definite when no face is folded (cotangent Laplacian = FEM stiffness,
/// positive semidefinite per unfolded triangle, definite once some vertex of every component is
/// fixed). It is solved by sparse Cholesky (about half the work of LU); a folded layout can make
/// it indefinite, and then a failed Cholesky falls back to LU.
fn planar_harmonic_map_reusing(
    positions: &[[f64; 2]],
    faces: &[[u32; 3]],
    fixed: &[(u32, [f64; 2])],
    pins: &[(u32, [f64; 2])],
    clamp_negative: bool,
    cache: &mut Option<SymbolicCache>,
) -> Result<Vec<[f64; 2]>, AnalysisError> {
    use faer::linalg::solvers::Solve;
    use faer::sparse::linalg::solvers::{Llt, Lu, SymbolicLlt, SymbolicLu};
    let n = positions.len();
    let mut target: Vec<Option<[f64; 2]>> = vec![None; n];
    for &(v, p) in fixed.iter().chain(pins) {
        let slot = target
            .get_mut(v as usize)
            .ok_or_else(|| AnalysisError::InvalidInput(format!("harmonic map: vertex {v} out of range")))?;
        if slot.is_some() {
            return Err(AnalysisError::InvalidInput(format!(
                "harmonic map: vertex {v} is constrained twice"
            )));
        }
        *slot = Some(p);
    }
    let mut index = vec![usize::MAX; n];
    let mut m = 0;
    for v in 0..n {
        if target[v].is_none() {
            index[v] = m;
            m += 1;
        }
    }
    let mut out: Vec<[f64; 2]> = target.iter().map(|t| t.unwrap_or([0.0; 2])).collect();
    if m == 0 {
        return Ok(out);
    }
    // edge weights: sum of ½ cot of the angles opposite each edge (one per incident face)
    let mut edges: Vec<(usize, usize, f64)> = Vec::with_capacity(3 * faces.len());
    for f in faces {
        for k in 0..3 {
            let (o, i, j) = (f[k] as usize, f[(k + 1) % 3] as usize, f[(k + 2) % 3] as usize);
            let (u, v) = (
                [positions[i][0] - positions[o][0], positions[i][1] - positions[o][1]],
                [positions[j][0] - positions[o][0], positions[j][1] - positions[o][1]],
            );
            let cross = u[0] * v[1] - u[1] * v[0];
            // a degenerate face contributes nothing, but its edges stay in the pattern
            let w = if cross == 0.0 {
                0.0
            } else {
                0.5 * (u[0] * v[0] + u[1] * v[1]) / cross
            };
            edges.push((i.min(j), i.max(j), w));
        }
    }
    edges.sort_by_key(|e| (e.0, e.1));
    let mut merged: Vec<(usize, usize, f64)> = Vec::with_capacity(edges.len());
    for (i, j, w) in edges {
        match merged.last_mut() {
            Some(last) if (last.0, last.1) == (i, j) => last.2 += w,
            _ => merged.push((i, j, w)),
        }
    }
    let mut trip = Vec::with_capacity(4 * merged.len());
    let mut rhs = faer::Mat::<f64>::zeros(m, 2);
    for (i, j, w) in merged {
        // zero weights are kept as explicit entries: the pattern depends on the mesh only
        let w = if clamp_negative { w.max(0.0) } else { w };
        for (a, b) in [(i, j), (j, i)] {
            if index[a] == usize::MAX {
                continue;
            }
            trip.push(faer::sparse::Triplet::new(index[a], index[a], w));
            if index[b] != usize::MAX {
                trip.push(faer::sparse::Triplet::new(index[a], index[b], -w));
            } else {
                rhs[(index[a], 0)] += w * out[b][0];
                rhs[(index[a], 1)] += w * out[b][1];
            }
        }
    }
    let a = faer::sparse::SparseColMat::<usize, f64>::try_new_from_triplets(m, m, &trip)
        .map_err(|e| AnalysisError::InvalidInput(format!("harmonic map: assembling the Laplacian: {e:?}")))?;
    let solver_error = |what: &str, e: String| {
        AnalysisError::InvalidInput(format!("harmonic map: {what} of the planar Laplacian: {e}"))
    };
    let pattern = a.symbolic();
    let reusable = cache
        .as_mut()
        .filter(|c| c.col_ptr == pattern.col_ptr() && c.row_idx == pattern.row_idx());
    let entry = match reusable {
        Some(entry) => entry,
        None => {
            let llt = SymbolicLlt::try_new(pattern, faer::Side::Lower)
                .map_err(|e| solver_error("symbolic Cholesky", format!("{e:?}")))?;
            cache.insert(SymbolicCache {
                col_ptr: pattern.col_ptr().to_vec(),
                row_idx: pattern.row_idx().to_vec(),
                llt,
                lu: None,
            })
        }
    };
    // faer's Cholesky with Side::Lower reads the lower triangle of the (symmetric) matrix
    match Llt::try_new_with_symbolic(entry.llt.clone(), a.as_ref(), faer::Side::Lower) {
        Ok(llt) => llt.solve_in_place(rhs.as_mut()),
        Err(_) => {
            let symbolic = match &entry.lu {
                Some(lu) => lu.clone(),
                None => {
                    let lu = SymbolicLu::try_new(pattern).map_err(|e| solver_error("symbolic LU", format!("{e:?}")))?;
                    entry.lu = Some(lu.clone());
                    lu
                }
            };
            let lu =
                Lu::try_new_with_symbolic(symbolic, a.as_ref()).map_err(|e| solver_error("LU", format!("{e:?}")))?;
            lu.solve_in_place(rhs.as_mut());
        }
    }
    for v in 0..n {
        if index[v] != usize::MAX {
            let p = [rhs[(index[v], 0)], rhs[(index[v], 1)]];
            if !(p[0].is_finite() && p[1].is_finite()) {
                return Err(AnalysisError::InvalidInput(format!(
                    "harmonic map: non-finite image of vertex {v} (singular planar Laplacian)"
                )));
            }
            out[v] = p;
        }
    }
    Ok(out)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A (2k+1)² grid on [−1, 1]², split along alternating diagonals; #V positions and faces.
    fn grid(k: usize) -> (Vec<[f64; 2]>, Vec<[u32; 3]>, Vec<u32>) {
        let m = 2 * k + 1;
        let mut positions = Vec::new();
        for j in 0..m {
            for i in 0..m {
                let (x, y) = (i as f64 / k as f64 - 1.0, j as f64 / k as f64 - 1.0);
                // a smooth interior warp (no fold) so that the cotangents are not all equal
                positions.push([x + 0.1 * (1.0 - x * x) * y, y + 0.05 * (1.0 - y * y) * x * x]);
            }
        }
        let id = |i: usize, j: usize| (j * m + i) as u32;
        let mut faces = Vec::new();
        for j in 0..m - 1 {
            for i in 0..m - 1 {
                if (i + j) % 2 == 0 {
                    faces.push([id(i, j), id(i + 1, j), id(i + 1, j + 1)]);
                    faces.push([id(i, j), id(i + 1, j + 1), id(i, j + 1)]);
                } else {
                    faces.push([id(i, j), id(i + 1, j), id(i, j + 1)]);
                    faces.push([id(i + 1, j), id(i + 1, j + 1), id(i, j + 1)]);
                }
            }
        }
        let boundary = (0..m * m)
            .filter(|&v| {
                let (i, j) = (v % m, v / m);
                i == 0 || j == 0 || i == m - 1 || j == m - 1
            })
            .map(|v| v as u32)
            .collect();
        (positions, faces, boundary)
    }

    fn affine(p: [f64; 2]) -> [f64; 2] {
        [0.3 + 1.2 * p[0] - 0.4 * p[1], -0.1 + 0.5 * p[0] + 0.9 * p[1]]
    }

    /// Linear precision of the planar cotangent weights: boundary and pin values taken from an
    /// affine map A give A at every vertex, whether the system is definite (Cholesky) or a fold
    /// makes it indefinite (LU fallback); the cached factorizations give the same answer.
    #[test]
    fn planar_harmonic_map_reproduces_affine_maps_through_both_solvers() {
        let (mut positions, faces, boundary) = grid(6);
        let fixed: Vec<(u32, [f64; 2])> = boundary.iter().map(|&v| (v, affine(positions[v as usize]))).collect();
        let pin = 3 * 13 + 4;
        let check = |positions: &[[f64; 2]], cache: &mut Option<SymbolicCache>| {
            let pins = vec![(pin as u32, affine(positions[pin]))];
            let uv = planar_harmonic_map_reusing(positions, &faces, &fixed, &pins, false, cache).unwrap();
            let err = positions
                .iter()
                .zip(&uv)
                .map(|(p, q)| {
                    let a = affine(*p);
                    (a[0] - q[0]).hypot(a[1] - q[1])
                })
                .fold(0.0f64, f64::max);
            assert!(err < 1e-12, "affine map reproduced to {err:e}");
        };
        let mut cache = None;
        check(&positions, &mut cache);
        assert!(
            cache.as_ref().unwrap().lu.is_none(),
            "unfolded layout: Cholesky succeeded"
        );
        check(&positions, &mut cache);

        // push an interior vertex far across its neighbours: its faces fold and the sum of its
        // edge weights (its diagonal entry) becomes negative, so the matrix is not definite
        let v = 6 * 13 + 6;
        positions[v] = [positions[v][0] + 0.45, positions[v][1] + 0.41];
        let diagonal: f64 = faces
            .iter()
            .filter(|f| f.contains(&(v as u32)))
            .map(|f| {
                let k = f.iter().position(|&w| w == v as u32).unwrap();
                // the two angles opposite the edges at v are at the other two corners
                let mut sum = 0.0;
                for o in [f[(k + 1) % 3], f[(k + 2) % 3]] {
                    let other = f.iter().copied().find(|&w| w != o && w != v as u32).unwrap();
                    let (po, pv, pw) = (positions[o as usize], positions[v], positions[other as usize]);
                    let (a, b) = ([pv[0] - po[0], pv[1] - po[1]], [pw[0] - po[0], pw[1] - po[1]]);
                    let cross = a[0] * b[1] - a[1] * b[0];
                    // orientation of the face (o, v, other) as it appears in f
                    let sign = if f[(f.iter().position(|&w| w == o).unwrap() + 1) % 3] == v as u32 {
                        1.0
                    } else {
                        -1.0
                    };
                    sum += 0.5 * (a[0] * b[0] + a[1] * b[1]) / (sign * cross);
                }
                sum
            })
            .sum();
        assert!(
            diagonal < 0.0,
            "the test layout must make the diagonal negative ({diagonal})"
        );
        let mut cache = None;
        check(&positions, &mut cache);
        assert!(
            cache.as_ref().unwrap().lu.is_some(),
            "indefinite system: LU fallback used"
        );
    }
}
