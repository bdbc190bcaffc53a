//! Area-preserving maps of closed genus-0 surfaces onto the unit sphere: the sphere version of
//! [`crate::area_preserving`] (Su et al. 2015, §4.3 and Alg. 2).
//!
//! The surface, scaled to area 4π, is mapped conformally onto S² ([`sphere_map`]). Each vertex
//! gets the mass of its share of the surface (one third of its one-ring area); semi-discrete OT
//! from the *uniform* measure of S² (a flat icosphere) to the conformal images with these masses
//! ([`solve_sphere_ot`], chordal cost) gives every vertex a Laguerre cell of exactly that area;
//! the vertex moves to its cell's centroid, projected back onto S². Areas are then preserved up
//! to the discretization, and the map stays close to the conformal one where the conformal map
//! already preserved area. Centroids of neighbouring cells can fold a sliver, as in the plane;
//! such folds get the disk's fold repair ([`crate::fold_repair`]) in a gnomonic chart around
//! each cluster, or a stereographic one when no gnomonic chart succeeds, and the foldover-free
//! untangling in the same charts when the repair fails in all of them (`repair_in_charts`).
//!
//! Measured (`tests/sphere_param.rs`): an ellipsoid 1:1:2 of 2,562 vertices goes from a 95th
//! percentile |ln(one-ring area ratio)| of 1.50 (conformal) to 0.027, with no flipped face;
//! TOSCA wolf0 from 24.9 to 0.39, its centroid map folding 132 of 8,684 faces, which the
//! repair unfolds in 30 charts moving 141 vertices; GOAST finger0, whose conformal image crowds
//! the tip's vertices 3e-11 apart, converges from the OT's coarse-to-fine start and the
//! repair leaves no fold. Where the conformal sphere map itself fails (the lion poses' tails,
//! beyond double precision) or the OT does not converge, there is no map; where charts cannot
//! unfold a cluster the map keeps it folded: `benches/sphere_param_bench.rs` in the tools crate
//! lists them (`docs/sphere.md`).

use std::collections::{HashMap, HashSet};
use std::time::Instant;

use rayon::prelude::*;
use shapespace_conformal::sphere::quality::orientation_on_sphere;
use shapespace_conformal::sphere::repair::rotation_to_south;
use shapespace_conformal::{sphere_map, SphereMap, SphereMapParams};
use shapespace_geometry::connectivity::Connectivity;
use shapespace_geometry::quantities::{face_areas, vertex_dual_areas};
use shapespace_geometry::topology::euler_characteristic;
use shapespace_geometry::TriMesh;
use shapespace_omt::sphere::{solve_sphere_ot, SphereMeasure, SphereOtParams};
use shapespace_omt::OmtError;

use crate::area_preserving::weighted_target_masses;
use crate::error::AnalysisError;
use crate::fold_repair::{
    face_is_valid, reference_equilateral, reference_from_layout, reference_from_surface, repair_folds,
    untangle_foldover_free, FoldRepairParams, FoldoverFreeParams,
};

/// Options of [`area_preserving_sphere_map`].
#[derive(Clone, Debug, Default)]
pub struct SphereParamParams {
    /// The conformal sphere map (normalization: Möbius centering by default).
    pub sphere_map: SphereMapParams,
    /// The OT solver on the sphere.
    pub ot: SphereOtParams,
    /// Subdivisions of the icosphere carrying the uniform source (20·4^s flat triangles);
    /// default [`default_source_subdivisions`].
    pub source_subdivisions: Option<usize>,
    /// Per-vertex importance weights w_i > 0 (#V) multiplying the masses, as on the disk
    /// ([`weighted_target_masses`]); `None`: all 1.
    pub weights: Option<Vec<f64>>,
    /// Skip the fold repair after the centroid map (the folds are only counted).
    pub no_fold_repair: bool,
}

/// The result of [`area_preserving_sphere_map`].
#[derive(Clone, Debug)]
pub struct SphereAreaPreservingMap {
    /// Image of each vertex on S², #V.
    pub positions: Vec<[f64; 3]>,
    /// The conformal map the OT started from.
    pub conformal: SphereMap,
    /// Each vertex's target area on S² (one third of its one-ring area, the surface scaled to
    /// the source's total area, about 4π), #V.
    pub target_masses: Vec<f64>,
    /// Area of each vertex's Laguerre cell at the solution, #V.
    pub cell_areas: Vec<f64>,
    /// Heights of the OT solution, #V.
    pub heights: Vec<f64>,
    /// Newton steps of the OT solve.
    pub iterations: usize,
    /// Image faces not positively oriented on S² after the fold repair (exact `orient_3d`
    /// against the centre).
    pub num_flipped: usize,
    /// Subdivisions of the icosphere source.
    pub source_subdivisions: usize,
    /// Faces folded by the centroid map, before the repair.
    pub flipped_before_repair: usize,
    /// The fold repair, when it ran (the moved vertices' cells no longer have their exact
    /// areas).
    pub fold_repair: Option<SphereFoldRepairInfo>,
    /// Wall-clock seconds of the stages.
    pub timings: SphereParamTimings,
}

/// Wall-clock seconds of the stages of [`area_preserving_sphere_map`].
#[derive(Clone, Copy, Debug, Default, serde::Serialize)]
pub struct SphereParamTimings {
    /// The conformal sphere map.
    pub conformal: f64,
    /// The OT solve.
    pub ot: f64,
    /// Centroids and fold repair.
    pub output: f64,
}

/// The area-preserving map of a closed genus-0 `mesh` onto the unit sphere (module docs).
///
/// Errors: the conformal sphere map fails (not a closed genus-0 surface, beyond double
/// precision, bad markers); the OT solve fails or does not converge; a cell is empty.
pub fn area_preserving_sphere_map(
    mesh: &TriMesh,
    params: &SphereParamParams,
) -> Result<SphereAreaPreservingMap, AnalysisError> {
    let clock = Instant::now();
    let conformal = sphere_map(mesh, &params.sphere_map).map_err(AnalysisError::SphereMap)?;
    let mut timings = SphereParamTimings {
        conformal: clock.elapsed().as_secs_f64(),
        ..Default::default()
    };
    let clock = Instant::now();
    let n = mesh.num_vertices();
    let subdivisions = params
        .source_subdivisions
        .unwrap_or_else(|| default_source_subdivisions(n));
    let source = SphereMeasure::uniform_icosphere(subdivisions).map_err(AnalysisError::Transport)?;
    // the disk's masses (Σ = π) scaled to the source's total (4π up to the icosphere's chords)
    let scale = source.total_mass() / std::f64::consts::PI;
    let masses: Vec<f64> = weighted_target_masses(&vertex_dual_areas(mesh), params.weights.as_deref())?
        .into_iter()
        .map(|m| m * scale)
        .collect();
    let solution = solve_sphere_ot(&source, &conformal.positions, &masses, &params.ot)
        .and_then(|s| s.into_result())
        .map_err(AnalysisError::Transport)?;
    timings.ot = clock.elapsed().as_secs_f64();
    let clock = Instant::now();
    let mut positions = solution
        .centroids_on_sphere()
        .into_iter()
        .enumerate()
        .map(|(v, c)| {
            c.ok_or_else(|| {
                AnalysisError::Transport(OmtError::InvalidInput(format!(
                    "the Laguerre cell of vertex {v} is empty at the solution"
                )))
            })
        })
        .collect::<Result<Vec<_>, _>>()?;
    // the centroid map can fold slivers, as in the plane: the disk's repair in a chart
    let flipped_before_repair = folded_on_sphere(mesh, &positions).len();
    let fold_repair = if params.no_fold_repair {
        None
    } else {
        Some(repair_in_charts(mesh, &mut positions))
    };
    let num_flipped = folded_on_sphere(mesh, &positions).len();
    Ok(SphereAreaPreservingMap {
        positions,
        conformal,
        target_masses: solution.target_masses.clone(),
        cell_areas: solution.cells.masses.clone(),
        heights: solution.heights.clone(),
        iterations: solution.iterations,
        num_flipped,
        source_subdivisions: subdivisions,
        flipped_before_repair,
        fold_repair,
        timings: SphereParamTimings {
            output: clock.elapsed().as_secs_f64(),
            ..timings
        },
    })
}

/// The icosphere subdivisions of the uniform source for a mesh of `n` vertices: the smallest
/// s ≥ 4 with 20·4^s ≥ n/2 (half a triangle to two triangles per vertex above the floor), at
/// most 9. The source is uniform, so its resolution does not limit the cells: flat triangles
/// carrying their spherical triangles' masses miss the measure by O(h²) within each. The cost
/// grows with it (one best-site query per source vertex, one clipping per triangle), and again
/// with many cells per triangle (long candidate lists);
/// docs/decisions/0052-sphere-source-resolution.md has the measurements.
pub fn default_source_subdivisions(n: usize) -> usize {
    let mut s = 4;
    while 2 * 20 * 4usize.pow(s as u32) < n && s < 9 {
        s += 1;
    }
    s
}

/// The fold repair of [`area_preserving_sphere_map`] on any map `x` (#V points on S²) of the
/// closed genus-0 `mesh`: re-embeds each cluster of folded faces in a chart around it, every
/// vertex outside the charts kept (`repair_in_charts`).
pub fn repair_sphere_map_folds(mesh: &TriMesh, x: &mut [[f64; 3]]) -> SphereFoldRepairInfo {
    repair_in_charts(mesh, x)
}

/// The number of faces of `mesh` whose image `x` on S² is not positively oriented (exact).
pub fn folded_faces_on_sphere(mesh: &TriMesh, x: &[[f64; 3]]) -> usize {
    folded_on_sphere(mesh, x).len()
}

/// Faces of `mesh` whose image `x` on S² is not positively oriented (exact `orient_3d` against
/// the centre).
pub(crate) fn folded_on_sphere(mesh: &TriMesh, x: &[[f64; 3]]) -> Vec<usize> {
    (0..mesh.num_faces())
        .into_par_iter()
        .filter(|&f| {
            let [a, b, c] = mesh.faces[f].map(|v| x[v as usize]);
            orientation_on_sphere(a, b, c) != 1
        })
        .collect()
}

/// Passes of the chart repair over the clusters left: each pass after the first tries the
/// clusters the previous one gave up, whose surroundings the repairs around them changed, and
/// runs only while the previous pass lowered the folds.
const MAX_PASSES: usize = 4;
/// Rings of faces around a fold cluster in its first chart; ×1.5 after each failure.
const CHART_RINGS: usize = 3;
/// A chart holds at most this fraction of the faces.
const CHART_MAX_FRACTION: f64 = 0.25;
/// A chart's vertices lie within this angle of its centre (radians; the gnomonic projection
/// reaches infinity at π/2; the area factor there is 1/cos³θ ≈ 700).
const CHART_MAX_ANGLE: f64 = 1.45;
/// The stereographic charts tried on a cluster that every gnomonic chart failed: their
/// vertices lie within this angle of the cluster's centre (the chart's scale there is
/// 1/cos²(θ/2) ≈ 16), and they hold at most [`STEREO_MAX_FRACTION`] of the faces.
const STEREO_MAX_ANGLE: f64 = 2.6;
const STEREO_MAX_FRACTION: f64 = 0.5;

/// A chart's projection of S² after the rotation, and its inverse.
type ToChart = fn(&[[f64; 3]; 3], [f64; 3]) -> [f64; 2];
type FromChart = fn(&[[f64; 3]; 3], [f64; 2]) -> [f64; 3];

/// The projection of a chart: gnomonic (great circles straight: planar orientation is the
/// sphere's) or stereographic (conformal, reaches past a hemisphere; checked on S² after).
#[derive(Clone, Copy, PartialEq, Debug)]
enum Projection {
    Gnomonic,
    Stereographic,
}

/// How a chart's interior is re-embedded.
#[derive(Clone, Copy, PartialEq, Debug)]
enum ChartMethod {
    /// The disk's fold repair ([`repair_folds`]: kernel moves, Tutte solves on growing regions,
    /// retraction).
    Tutte,
    /// The foldover-free untangling ([`untangle_foldover_free`]) of the chart as the map left it.
    Untangle,
}

/// What the fold repair of [`area_preserving_sphere_map`] did.
#[derive(Clone, Debug, Default, serde::Serialize)]
pub struct SphereFoldRepairInfo {
    /// Clusters of folded faces (connected through shared vertices) found, over all passes.
    pub clusters: usize,
    /// Passes over the clusters (a cluster given up in one pass is tried again in the next,
    /// while the passes lower the folds; at most 4).
    pub passes: usize,
    /// Clusters whose chart repair was kept.
    pub repaired: usize,
    /// Vertices moved.
    pub vertices_moved: usize,
    /// The largest chart used, in rings around its cluster.
    pub max_rings: usize,
    /// Charts tried and discarded, by reason: not a disk, wider than 1.45 rad, the planar
    /// repair failed or left a fold, a face folded on S² after it.
    pub charts_not_disk: usize,
    pub charts_too_wide: usize,
    pub charts_repair_failed: usize,
    pub charts_folded_on_sphere: usize,
    /// Charts whose planar repair failed and that were grown around their boundary's reflex
    /// corners for a second try.
    pub charts_convexified: usize,
    /// Clusters given up because the next chart would pass a quarter of the faces.
    pub clusters_too_large: usize,
    /// Clusters repaired in a stereographic chart after every gnomonic chart failed
    /// (counted in `repaired`, not in `clusters_too_large`).
    pub stereographic_repaired: usize,
    /// Clusters repaired by the foldover-free untangling after every chart's Tutte repair
    /// failed (counted in `repaired`, and in `stereographic_repaired` when in such a chart).
    pub untangle_repaired: usize,
    /// Clusters every chart's Tutte repair failed on that the untangling was not tried on: the
    /// map folded more than [`UNTANGLE_MAX_FOLDED_SHARE`] of its faces.
    pub untangle_skipped: usize,
}

/// Why a chart was discarded.
enum ChartFailure {
    NotDisk,
    TooWide,
    RepairFailed,
    FoldedOnSphere,
}

/// Re-embeds the folded faces of the map `x` (#V points on S²) by the disk's fold repair
/// ([`crate::fold_repair::repair_folds`]: untangling, Tutte re-embedding in growing regions,
/// retraction) in a gnomonic chart around each cluster of folded faces.
///
/// The gnomonic (central) projection onto the tangent plane at the cluster's mean direction c
/// maps great circles to straight lines, so a planar face turns counter-clockwise exactly when
/// det(a, b, c) > 0 on S², the test of a fold on the sphere (the stereographic chart does not
/// have this: a sliver along a great circle can turn over in it). A chart holds the faces
/// within k rings of the cluster plus the holes they enclose (a ring around a leg encloses its
/// tip), must be a disk (one boundary loop, Euler characteristic 1) and keeps its boundary
/// fixed, so no face outside it changes. The retraction's floors are each face's share of 4π
/// times the projection's area factor 1/cos³θ at the face. A chart whose planar repair fails is
/// grown around its boundary's reflex corners ([`convexify`]) and repaired once more. A chart whose repair fails or
/// leaves a fold on S² (checked exactly) is discarded, and the next one has ⌈1.5k⌉ rings, until
/// a chart passes a quarter of the faces or 1.45 rad from its centre. A cluster that every
/// gnomonic chart failed gets the same sequence of charts in the stereographic projection
/// centred at the cluster's mean direction, up to half the faces and 2.6 rad from that centre
/// (conformal, so the retraction's floors scale by (1 + |u|²)²/4; a large chart's boundary,
/// nearly a circle around the antipode, stays nearly a circle, so the Tutte solve unfolds);
/// its result passes the same exact test on S² (on the GOAST cacti the stereographic pass
/// unfolds every cluster the gnomonic charts left, decision 0045). The planar repair untangles a
/// whole-patch Tutte solve that still folds (a patch's boundary stays where the map put it, and
/// need not be convex). A cluster whose every chart still fails then gets the same ring charts
/// (gnomonic, then stereographic, up to [`UNTANGLE_MAX_FACES`]; unless the map folded more than
/// [`UNTANGLE_MAX_FOLDED_SHARE`] of its faces) once more, each untangled by
/// the foldover-free untangling ([`untangle_foldover_free`]: every interior vertex of the chart
/// moves at once, by the regularized Winslow energy against reference triangles,
/// [`untangle_references`]; decision 0051), and the first that leaves no fold on S² is kept.
/// Clusters given up are tried again in a further pass, up to [`MAX_PASSES`], while the passes
/// lower the folds: the repairs around a cluster change its surroundings (decision 0048).
pub(crate) fn repair_in_charts(mesh: &TriMesh, x: &mut [[f64; 3]]) -> SphereFoldRepairInfo {
    let mut info = SphereFoldRepairInfo::default();
    let conn = Connectivity::of(mesh);
    // each face's share of the sphere's 4π (the charts scale it by their area factor)
    let areas = face_areas(mesh);
    let total: f64 = areas.iter().sum();
    let shares: Vec<f64> = areas.iter().map(|a| a / total * 4.0 * std::f64::consts::PI).collect();
    let mut given_up: HashSet<usize> = HashSet::new();
    // the folded faces, kept up to date around the vertices each repair moves
    let mut folded = vec![false; mesh.num_faces()];
    for f in folded_on_sphere(mesh, x) {
        folded[f] = true;
    }
    let mut num_folded = folded.iter().filter(|&&b| b).count();
    let untangle = (num_folded as f64) <= UNTANGLE_MAX_FOLDED_SHARE * mesh.num_faces() as f64;
    // the folds at the start of the pass; a pass that leaves fewer is followed by another
    let mut pass_start = usize::MAX;
    loop {
        let Some(f0) = (0..mesh.num_faces()).find(|&f| folded[f] && !given_up.contains(&f)) else {
            if num_folded == 0 || num_folded >= pass_start || info.passes == MAX_PASSES {
                return info;
            }
            info.passes += 1;
            pass_start = num_folded;
            given_up.clear();
            continue;
        };
        if pass_start == usize::MAX {
            info.passes = 1;
            pass_start = num_folded;
        }
        info.clusters += 1;
        let mut cluster = vec![f0];
        let mut seen: HashSet<usize> = [f0].into_iter().collect();
        let mut i = 0;
        while i < cluster.len() {
            for &v in &mesh.faces[cluster[i]] {
                for &g in &conn.vertex_faces[v as usize] {
                    if folded[g as usize] && seen.insert(g as usize) {
                        cluster.push(g as usize);
                    }
                }
            }
            i += 1;
        }
        let mut kept = ring_charts(
            mesh,
            &conn,
            x,
            &cluster,
            &shares,
            ChartMethod::Tutte,
            &mut info,
            &mut folded,
            &mut num_folded,
        );
        // caps of the image around the cluster in the stereographic chart: their boundaries are
        // near circles in the chart where mesh rings can be ragged (crowded limbs)
        if let (false, Some(centre)) = (kept, cluster_centre(mesh, x, &cluster)) {
            let limit = (STEREO_MAX_FRACTION * mesh.num_faces() as f64) as usize;
            for radius in CAP_RADII {
                let Some(patch) = cap_patch(mesh, &conn, x, &cluster, centre, radius, limit) else {
                    continue;
                };
                let attempt = repair_patch(
                    mesh,
                    x,
                    &patch,
                    &shares,
                    Projection::Stereographic,
                    Some(centre),
                    ChartMethod::Tutte,
                );
                if take_chart(attempt, &mut info, mesh, &conn, x, &mut folded, &mut num_folded) {
                    info.stereographic_repaired += 1;
                    kept = true;
                    break;
                }
            }
        }
        // the foldover-free untangling in the same ring charts, where every Tutte solve failed
        if !kept && !untangle {
            info.untangle_skipped += 1;
        } else if !kept {
            kept = ring_charts(
                mesh,
                &conn,
                x,
                &cluster,
                &shares,
                ChartMethod::Untangle,
                &mut info,
                &mut folded,
                &mut num_folded,
            );
            if kept {
                info.untangle_repaired += 1;
            }
        }
        if kept {
            info.repaired += 1;
        } else {
            info.clusters_too_large += 1;
            given_up.extend(cluster);
        }
    }
}

/// The ring charts of a cluster (its faces within k rings, k = 3, then ×1.5), gnomonic then
/// stereographic at the cluster's centre, each repaired by `method` until one is kept
/// ([`take_chart`]); a chart whose Tutte repair failed is grown around its reflex corners and
/// tried once more. True when a chart was kept.
#[allow(clippy::too_many_arguments)]
fn ring_charts(
    mesh: &TriMesh,
    conn: &Connectivity,
    x: &mut [[f64; 3]],
    cluster: &[usize],
    shares: &[f64],
    method: ChartMethod,
    info: &mut SphereFoldRepairInfo,
    folded: &mut [bool],
    num_folded: &mut usize,
) -> bool {
    for projection in [Projection::Gnomonic, Projection::Stereographic] {
        let (max_fraction, centre) = match projection {
            Projection::Gnomonic => (CHART_MAX_FRACTION, None),
            Projection::Stereographic => (STEREO_MAX_FRACTION, cluster_centre(mesh, x, cluster)),
        };
        if projection == Projection::Stereographic && centre.is_none() {
            break;
        }
        let mut limit = (max_fraction * mesh.num_faces() as f64) as usize;
        if method == ChartMethod::Untangle {
            limit = limit.min(UNTANGLE_MAX_FACES);
        }
        let mut rings = CHART_RINGS;
        while let Some(mut patch) = chart_patch(mesh, conn, cluster, rings, limit) {
            let mut attempt = repair_patch(mesh, x, &patch, shares, projection, centre, method);
            if method == ChartMethod::Tutte
                && matches!(attempt, Err(ChartFailure::RepairFailed))
                && convexify(mesh, conn, x, &mut patch, limit)
            {
                info.charts_convexified += 1;
                attempt = repair_patch(mesh, x, &patch, shares, projection, centre, method);
            }
            if take_chart(attempt, info, mesh, conn, x, folded, num_folded) {
                info.max_rings = info.max_rings.max(rings);
                if projection == Projection::Stereographic {
                    info.stereographic_repaired += 1;
                }
                return true;
            }
            rings += rings.div_ceil(2);
        }
    }
    false
}

/// Counts a chart's failure in `info`, or applies its moves to `x` and `folded` (with the
/// count `num_folded`) and counts them; true when the chart is kept.
fn take_chart(
    attempt: Result<HashMap<u32, [f64; 3]>, ChartFailure>,
    info: &mut SphereFoldRepairInfo,
    mesh: &TriMesh,
    conn: &Connectivity,
    x: &mut [[f64; 3]],
    folded: &mut [bool],
    num_folded: &mut usize,
) -> bool {
    let moved = match attempt {
        Ok(moved) => moved,
        Err(failure) => {
            *match failure {
                ChartFailure::NotDisk => &mut info.charts_not_disk,
                ChartFailure::TooWide => &mut info.charts_too_wide,
                ChartFailure::RepairFailed => &mut info.charts_repair_failed,
                ChartFailure::FoldedOnSphere => &mut info.charts_folded_on_sphere,
            } += 1;
            return false;
        }
    };
    info.vertices_moved += moved.len();
    for (&v, &p) in &moved {
        x[v as usize] = p;
    }
    *num_folded = refresh_folds(mesh, conn, x, moved.keys(), folded, *num_folded);
    true
}

/// Tests again the faces around the `moved` vertices of the map `x` and updates `folded` (#F);
/// returns the new number of folded faces (`num_folded` before).
fn refresh_folds<'a>(
    mesh: &TriMesh,
    conn: &Connectivity,
    x: &[[f64; 3]],
    moved: impl Iterator<Item = &'a u32>,
    folded: &mut [bool],
    mut num_folded: usize,
) -> usize {
    for &v in moved {
        for &f in &conn.vertex_faces[v as usize] {
            let f = f as usize;
            let [a, b, c] = mesh.faces[f].map(|u| x[u as usize]);
            let now = orientation_on_sphere(a, b, c) != 1;
            if now != folded[f] {
                folded[f] = now;
                if now {
                    num_folded += 1;
                } else {
                    num_folded -= 1;
                }
            }
        }
    }
    num_folded
}

/// The weight λ of the area term of the foldover-free untangling in a chart (the paper's 1
/// balances shape and area; the sphere map's point is its areas: on Sumner cats 0001, 0004,
/// 0007 and TOSCA horse7 the p95 |ε| after the repair is 0.820, 0.688, 0.829, 0.534 with λ = 1,
/// 0.822, 0.680, 0.825, 0.513 with λ = 10, both before the cap below; decision 0051).
const UNTANGLE_AREA_WEIGHT: f64 = 10.0;
/// The largest chart the foldover-free untangling is tried on (faces): on the bodies the
/// charts it unfolds hold 70–550 faces, and a failing one costs up to a second per thousand
/// faces; the spherical MDS maps fold half their faces in clusters no chart repairs (wolf0:
/// `tests/spherical_mds.rs` takes 15 s without the untangling, 35 s with this cap, 58 s with
/// 2,000).
const UNTANGLE_MAX_FACES: usize = 1000;
/// The untangling is for the isolated clusters of a map that folds a few faces: it is skipped
/// when more than this share of the faces is folded at the start of the repair. The centroid
/// maps of the area-preserving sphere map fold at most 3.2 % (TOSCA horse7: 1,214 of 38,492);
/// the spherical MDS maps 39–54 % (wolf0, centaur0, the ellipsoid 1:1:2), in clusters no chart
/// unfolds, where the untangling's failed charts made centaur0's map 7× slower (224 s against
/// 32 s) for 1 % fewer folds.
pub const UNTANGLE_MAX_FOLDED_SHARE: f64 = 0.1;

/// Radii (rad) of the caps around a cluster tried in the stereographic chart after the rings.
const CAP_RADII: [f64; 10] = [0.02, 0.05, 0.1, 0.2, 0.35, 0.5, 0.8, 1.2, 1.8, 2.5];

/// The faces of `mesh` whose three images lie within `radius` of `centre` on S², connected
/// through edges to `cluster` (which they include), plus the holes they enclose; `None` when
/// a cluster face is not in the cap or the patch passes `limit` faces.
fn cap_patch(
    mesh: &TriMesh,
    conn: &Connectivity,
    x: &[[f64; 3]],
    cluster: &[usize],
    centre: [f64; 3],
    radius: f64,
    limit: usize,
) -> Option<Vec<usize>> {
    let min_cos = radius.cos();
    let in_cap = |f: usize| mesh.faces[f].iter().all(|&v| dot(x[v as usize], centre) > min_cos);
    if !cluster.iter().all(|&f| in_cap(f)) {
        return None;
    }
    let mut inside = vec![false; mesh.num_faces()];
    let mut patch: Vec<usize> = Vec::new();
    let mut stack: Vec<usize> = Vec::new();
    for &f in cluster {
        if !std::mem::replace(&mut inside[f], true) {
            patch.push(f);
            stack.push(f);
        }
    }
    while let Some(f) = stack.pop() {
        for &e in &conn.face_edges[f] {
            for &g in &conn.edge_faces[e as usize] {
                let g = g as usize;
                if !inside[g] && in_cap(g) {
                    inside[g] = true;
                    patch.push(g);
                    stack.push(g);
                }
            }
        }
        if patch.len() > limit {
            return None;
        }
    }
    fill_holes(mesh, conn, &mut inside, &mut patch);
    (patch.len() <= limit).then_some(patch)
}

/// Rounds of [`convexify`].
const CONVEX_ROUNDS: usize = 8;

/// Grows `patch` by the faces around its boundary's reflex corners (turning against the loop's
/// majority on S², i.e. in the gnomonic chart, where great circles are straight) for up to
/// [`CONVEX_ROUNDS`] rounds, while it stays below [`CHART_MAX_FRACTION`] of the faces: the
/// planar repair keeps the chart's boundary fixed, and its whole-patch Tutte solve unfolds
/// only when that boundary is convex (Floater's theorem; on the GOAST fingers the solve over
/// a 3-ring chart left 91 of 240 faces folded).
/// Returns whether the patch grew.
fn convexify(mesh: &TriMesh, conn: &Connectivity, x: &[[f64; 3]], patch: &mut Vec<usize>, limit: usize) -> bool {
    let start = patch.len();
    let mut inside = vec![false; mesh.num_faces()];
    for &f in patch.iter() {
        inside[f] = true;
    }
    for _ in 0..CONVEX_ROUNDS {
        let (verts, sub) = patch_mesh(mesh, patch);
        let Some(sub) = sub else {
            break;
        };
        let loops = Connectivity::of(&sub).boundary_loops(&sub.faces);
        if loops.len() != 1 {
            break;
        }
        let ring: Vec<u32> = loops[0].iter().map(|&v| verts[v as usize]).collect();
        let m = ring.len();
        let turns: Vec<i8> = (0..m)
            .map(|k| {
                let [p, v, q] = [ring[(k + m - 1) % m], ring[k], ring[(k + 1) % m]].map(|u| x[u as usize]);
                orientation_on_sphere(p, v, q)
            })
            .collect();
        let sign = if turns.iter().filter(|&&t| t > 0).count() >= turns.iter().filter(|&&t| t < 0).count() {
            1
        } else {
            -1
        };
        let reflex: Vec<u32> = (0..m).filter(|&k| turns[k] == -sign).map(|k| ring[k]).collect();
        if reflex.is_empty() {
            break;
        }
        let (mut grown, mut grown_inside) = (patch.clone(), inside.clone());
        for v in reflex {
            for &g in &conn.vertex_faces[v as usize] {
                if !std::mem::replace(&mut grown_inside[g as usize], true) {
                    grown.push(g as usize);
                }
            }
        }
        fill_holes(mesh, conn, &mut grown_inside, &mut grown);
        if grown.len() > limit {
            break;
        }
        *patch = grown;
        inside = grown_inside;
    }
    patch.len() > start
}

/// The faces within `rings` rings of `cluster` (through shared vertices), plus every hole they
/// enclose: the connected components of the other faces (through shared edges) but the
/// largest. `None` when that passes [`CHART_MAX_FRACTION`] of the faces.
fn chart_patch(
    mesh: &TriMesh,
    conn: &Connectivity,
    cluster: &[usize],
    rings: usize,
    limit: usize,
) -> Option<Vec<usize>> {
    let nf = mesh.num_faces();
    let mut inside = vec![false; nf];
    let mut patch: Vec<usize> = Vec::new();
    for &f in cluster {
        if !std::mem::replace(&mut inside[f], true) {
            patch.push(f);
        }
    }
    let mut front = patch.clone();
    for _ in 0..rings {
        let mut next = Vec::new();
        for &f in &front {
            for &v in &mesh.faces[f] {
                for &g in &conn.vertex_faces[v as usize] {
                    if !std::mem::replace(&mut inside[g as usize], true) {
                        next.push(g as usize);
                    }
                }
            }
        }
        patch.extend_from_slice(&next);
        if patch.len() > limit {
            return None;
        }
        front = next;
    }
    fill_holes(mesh, conn, &mut inside, &mut patch);
    (patch.len() <= limit).then_some(patch)
}

/// Adds to `patch` (with its indicator `inside`, #F) every hole it encloses: the connected
/// components of the other faces (through shared edges) but the largest (of equal sizes, the
/// one whose smallest face index is largest), in increasing face order.
///
/// Every component of the outside shares an edge with the patch (the surface is closed), so
/// the search starts from those faces, and explores each component up to a budget that grows
/// fourfold until at most one component is left unexplored: that one has more faces than any
/// explored one, so it is the largest. Holes are small, so a chart costs about the size of its
/// holes, not of the mesh.
fn fill_holes(mesh: &TriMesh, conn: &Connectivity, inside: &mut [bool], patch: &mut Vec<usize>) {
    let mut seeds: Vec<usize> = Vec::new();
    for &f in patch.iter() {
        for &e in &conn.face_edges[f] {
            seeds.extend(
                conn.edge_faces[e as usize]
                    .iter()
                    .map(|&g| g as usize)
                    .filter(|&g| !inside[g]),
            );
        }
    }
    seeds.sort_unstable();
    seeds.dedup();
    let mut label = vec![usize::MAX; mesh.num_faces()];
    let mut budget = 64;
    let holes: Vec<usize> = loop {
        // per component explored this round: its faces, and whether it was explored to the end;
        // `root` joins the parts of an unfinished component reached from different seeds
        let mut parts: Vec<(Vec<usize>, bool)> = Vec::new();
        let mut root: Vec<usize> = Vec::new();
        let find = |root: &[usize], mut k: usize| {
            while root[k] != k {
                k = root[k];
            }
            k
        };
        for &s in &seeds {
            if label[s] != usize::MAX {
                continue;
            }
            let id = parts.len();
            root.push(id);
            label[s] = id;
            let (mut faces, mut stack) = (vec![s], vec![s]);
            let mut finished = true;
            'search: while let Some(f) = stack.pop() {
                for &e in &conn.face_edges[f] {
                    for &g in &conn.edge_faces[e as usize] {
                        let g = g as usize;
                        if inside[g] {
                            continue;
                        }
                        if label[g] == usize::MAX {
                            label[g] = id;
                            faces.push(g);
                            stack.push(g);
                        } else if label[g] != id {
                            // an unfinished part of the same component (a finished one would
                            // have labelled this seed): this one is unfinished too, even if
                            // it runs out of unlabelled faces
                            let (a, b) = (find(&root, label[g]), find(&root, id));
                            root[b.max(a)] = b.min(a);
                            finished = false;
                        }
                    }
                }
                if faces.len() > budget {
                    finished = false;
                    break 'search;
                }
            }
            parts.push((faces, finished));
        }
        let roots: Vec<usize> = (0..parts.len()).map(|k| find(&root, k)).collect();
        let unfinished: HashSet<usize> = (0..parts.len()).filter(|&k| !parts[k].1).map(|k| roots[k]).collect();
        if unfinished.len() <= 1 {
            // the finished components (each one part) and, if any, the larger unfinished one
            let mut finished: Vec<&Vec<usize>> = parts.iter().filter(|p| p.1).map(|p| &p.0).collect();
            if unfinished.is_empty() {
                // all explored: the largest is the outside (ties as a scan in face order numbers
                // the components, the last of the largest)
                let key = |c: &&Vec<usize>| (c.len(), c.iter().min().copied());
                let largest = finished.iter().copied().max_by_key(key).map(|c| key(&c));
                finished.retain(|c| Some(key(c)) != largest);
            }
            let mut holes: Vec<usize> = finished.into_iter().flatten().copied().collect();
            holes.sort_unstable();
            break holes;
        }
        for (faces, _) in &parts {
            for &f in faces {
                label[f] = usize::MAX;
            }
        }
        budget *= 4;
    };
    for f in holes {
        inside[f] = true;
        patch.push(f);
    }
}

/// The disk's fold repair (or the foldover-free untangling, by `method`) on the faces `patch`
/// of `mesh` in the gnomonic chart at their mean direction (or the `projection` at `centre`). Returns the new positions of the vertices it moved, or the reason when the patch is
/// not a disk, reaches [`CHART_MAX_ANGLE`], or the planar repair fails or leaves a face of the
/// patch folded on S². `shares`: each face's share of 4π (#F).
fn repair_patch(
    mesh: &TriMesh,
    x: &[[f64; 3]],
    patch: &[usize],
    shares: &[f64],
    projection: Projection,
    centre: Option<[f64; 3]>,
    method: ChartMethod,
) -> Result<HashMap<u32, [f64; 3]>, ChartFailure> {
    let (verts, sub) = patch_mesh(mesh, patch);
    let sub = sub.ok_or(ChartFailure::NotDisk)?;
    let sub_conn = Connectivity::of(&sub);
    let loops = sub_conn.boundary_loops(&sub.faces);
    if loops.len() != 1 || euler_characteristic(&sub, &sub_conn) != 1 {
        return Err(ChartFailure::NotDisk);
    }
    let mut is_boundary = vec![false; verts.len()];
    for &v in &loops[0] {
        is_boundary[v as usize] = true;
    }
    let c = match centre {
        Some(c) => c,
        None => mean_direction(x, &verts).ok_or(ChartFailure::TooWide)?,
    };
    let max_angle = match projection {
        Projection::Gnomonic => CHART_MAX_ANGLE,
        Projection::Stereographic => STEREO_MAX_ANGLE,
    };
    let min_cos = max_angle.cos();
    if verts.iter().any(|&v| dot(x[v as usize], c) < min_cos) {
        return Err(ChartFailure::TooWide);
    }
    let rot = rotation_to_south(c);
    let (to_chart, from_chart): (ToChart, FromChart) = match projection {
        Projection::Gnomonic => (gnomonic, from_gnomonic),
        Projection::Stereographic => (stereographic, from_stereographic),
    };
    let mut uv: Vec<[f64; 2]> = verts.iter().map(|&v| to_chart(&rot, x[v as usize])).collect();
    // each face's share of 4π times the chart's area factor at its centroid, 1/cos³θ
    // (gnomonic) or (1 + |u|²)²/4 (stereographic) (the patch's faces are `patch` in order)
    let target_face_areas: Vec<f64> = sub
        .faces
        .iter()
        .zip(patch)
        .map(|(f, &g)| {
            let [p, q, r] = f.map(|v| uv[v as usize]);
            let m = [(p[0] + q[0] + r[0]) / 3.0, (p[1] + q[1] + r[1]) / 3.0];
            let s2 = m[0] * m[0] + m[1] * m[1];
            match projection {
                Projection::Gnomonic => {
                    let cos = 1.0 / (1.0 + s2).sqrt();
                    shares[g] / (cos * cos * cos)
                }
                Projection::Stereographic => shares[g] * (1.0 + s2) * (1.0 + s2) / 4.0,
            }
        })
        .collect();
    let before = uv.clone();
    match method {
        ChartMethod::Tutte => {
            let params = FoldRepairParams {
                target_face_areas: Some(target_face_areas),
                ..Default::default()
            };
            // (a whole-patch Tutte solve can fold: the chart's boundary polygon need not be convex)
            let repaired =
                repair_folds(&sub, &is_boundary, &mut uv, &params).map_err(|_| ChartFailure::RepairFailed)?;
            if repaired.folded_after > 0 {
                return Err(ChartFailure::RepairFailed);
            }
        }
        ChartMethod::Untangle => {
            let reference = untangle_references(&sub, &uv, &target_face_areas);
            let untangled = untangle_foldover_free(
                &sub.faces,
                &is_boundary,
                &reference,
                &mut uv,
                &FoldoverFreeParams {
                    lambda: UNTANGLE_AREA_WEIGHT,
                    ..Default::default()
                },
            )
            .map_err(|_| ChartFailure::RepairFailed)?;
            if untangled.folded_after > 0 {
                return Err(ChartFailure::RepairFailed);
            }
        }
    }
    let moved: HashMap<u32, [f64; 3]> = verts
        .iter()
        .zip(uv.iter().zip(&before))
        .filter(|(_, (p, q))| p != q)
        .map(|(&v, (&p, _))| (v, from_chart(&rot, p)))
        .collect();
    let valid = patch.iter().all(|&f| {
        let [a, b, c] = mesh.faces[f].map(|v| moved.get(&v).copied().unwrap_or(x[v as usize]));
        orientation_on_sphere(a, b, c) == 1
    });
    if valid {
        Ok(moved)
    } else {
        Err(ChartFailure::FoldedOnSphere)
    }
}

/// The reference triangles of the foldover-free untangling of a chart: a face that is valid in
/// the chart and shares no vertex with a folded face keeps its own shape there (the untangling
/// leaves it nearly where it is); the others take their surface triangle's shape with their
/// target area in the chart (an equilateral triangle of that area if the surface's is degenerate).
fn untangle_references(sub: &TriMesh, uv: &[[f64; 2]], target_face_areas: &[f64]) -> Vec<[[f64; 2]; 2]> {
    let mut near_fold = vec![false; sub.num_vertices()];
    for f in &sub.faces {
        let [a, b, c] = f.map(|v| uv[v as usize]);
        if !face_is_valid(a, b, c) {
            for &v in f {
                near_fold[v as usize] = true;
            }
        }
    }
    sub.faces
        .iter()
        .zip(target_face_areas)
        .map(|(f, &area)| {
            let [a, b, c] = f.map(|v| uv[v as usize]);
            let own = if f.iter().any(|&v| near_fold[v as usize]) {
                None
            } else {
                reference_from_layout(a, b, c)
            };
            own.or_else(|| reference_from_surface(f.map(|v| sub.positions[v as usize]), area))
                .unwrap_or_else(|| reference_equilateral(area))
        })
        .collect()
}

fn dot(a: [f64; 3], b: [f64; 3]) -> f64 {
    a[0] * b[0] + a[1] * b[1] + a[2] * b[2]
}

/// The normalized mean of the points `x[v]`, `v` in `verts` (None when it vanishes).
fn mean_direction(x: &[[f64; 3]], verts: &[u32]) -> Option<[f64; 3]> {
    let mut c = [0.0; 3];
    for &v in verts {
        for (ck, xk) in c.iter_mut().zip(x[v as usize]) {
            *ck += xk;
        }
    }
    let l = dot(c, c).sqrt();
    (l.is_finite() && l > 0.0).then(|| c.map(|t| t / l))
}

/// The mean direction of the vertices of the faces `cluster`.
fn cluster_centre(mesh: &TriMesh, x: &[[f64; 3]], cluster: &[usize]) -> Option<[f64; 3]> {
    let mut verts: Vec<u32> = cluster.iter().flat_map(|&f| mesh.faces[f]).collect();
    verts.sort_unstable();
    verts.dedup();
    mean_direction(x, &verts)
}

/// The stereographic chart centred at the point that `rot` ([`rotation_to_south`]) takes to
/// the south pole, from the north pole onto the equatorial plane, oriented as [`gnomonic`]:
/// `rot`, then (x₁, −x₂)/(1 − x₃). Conformal; its area factor is (1 + |u|²)²/4.
fn stereographic(rot: &[[f64; 3]; 3], p: [f64; 3]) -> [f64; 2] {
    let q = rot.map(|r| dot(r, p));
    [q[0] / (1.0 - q[2]), -q[1] / (1.0 - q[2])]
}

/// The inverse of [`stereographic`].
fn from_stereographic(rot: &[[f64; 3]; 3], uv: [f64; 2]) -> [f64; 3] {
    let s = uv[0] * uv[0] + uv[1] * uv[1];
    let q = [2.0 * uv[0] / (1.0 + s), -2.0 * uv[1] / (1.0 + s), (s - 1.0) / (1.0 + s)];
    [0, 1, 2].map(|k| rot[0][k] * q[0] + rot[1][k] * q[1] + rot[2][k] * q[2])
}

/// The gnomonic chart centred at the point that `rot` ([`rotation_to_south`]) takes to the
/// south pole, orientation-preserving as the sphere map's stereographic chart: `rot`, then (x₁, −x₂)/(−x₃).
fn gnomonic(rot: &[[f64; 3]; 3], p: [f64; 3]) -> [f64; 2] {
    let q = rot.map(|r| dot(r, p));
    [q[0] / -q[2], -q[1] / -q[2]]
}

/// The inverse of [`gnomonic`].
fn from_gnomonic(rot: &[[f64; 3]; 3], uv: [f64; 2]) -> [f64; 3] {
    let q = [uv[0], -uv[1], -1.0];
    let l = dot(q, q).sqrt();
    let q = q.map(|t| t / l);
    [0, 1, 2].map(|k| rot[0][k] * q[0] + rot[1][k] * q[1] + rot[2][k] * q[2])
}

/// The faces `patch` of `mesh` as a mesh of their own: the mesh vertex of each local vertex,
/// and the sub-mesh (None when its faces do not form a valid mesh).
fn patch_mesh(mesh: &TriMesh, patch: &[usize]) -> (Vec<u32>, Option<TriMesh>) {
    let mut local = HashMap::new();
    let mut verts: Vec<u32> = Vec::new();
    let faces: Vec<[u32; 3]> = patch
        .iter()
        .map(|&f| {
            mesh.faces[f].map(|v| {
                *local.entry(v).or_insert_with(|| {
                    verts.push(v);
                    verts.len() as u32 - 1
                })
            })
        })
        .collect();
    let sub = TriMesh::new(verts.iter().map(|&v| mesh.positions[v as usize]).collect(), faces).ok();
    (verts, sub)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// [`fill_holes`] by a scan of every face (the components of the outside in face order, all
    /// but the last of the largest added): the oracle of the bounded search.
    fn fill_holes_by_scan(mesh: &TriMesh, conn: &Connectivity, inside: &mut [bool], patch: &mut Vec<usize>) {
        let nf = mesh.num_faces();
        let mut component = vec![usize::MAX; nf];
        let mut sizes: Vec<usize> = Vec::new();
        for start in 0..nf {
            if inside[start] || component[start] != usize::MAX {
                continue;
            }
            let id = sizes.len();
            let mut stack = vec![start];
            component[start] = id;
            let mut size = 0;
            while let Some(f) = stack.pop() {
                size += 1;
                for &e in &conn.face_edges[f] {
                    for &g in &conn.edge_faces[e as usize] {
                        let g = g as usize;
                        if !inside[g] && component[g] == usize::MAX {
                            component[g] = id;
                            stack.push(g);
                        }
                    }
                }
            }
            sizes.push(size);
        }
        let Some(largest) = (0..sizes.len()).max_by_key(|&c| sizes[c]) else {
            return;
        };
        for f in 0..nf {
            if !inside[f] && component[f] != largest {
                inside[f] = true;
                patch.push(f);
            }
        }
    }

    /// The bounded search adds the same holes in the same order as the scan: bands around a
    /// direction (one cap enclosed), two bands (a cap and a ring enclosed), the equator's band
    /// (two caps of equal size: the tie), and random scatters of faces (many small holes).
    #[test]
    fn bounded_hole_search_agrees_with_the_scan() {
        let mesh = shapespace_geometry::primitives::icosphere(4);
        let conn = Connectivity::of(&mesh);
        let centroid = |f: usize| {
            let [a, b, c] = mesh.faces[f].map(|v| mesh.positions[v as usize]);
            let m = [0, 1, 2].map(|k| (a[k] + b[k] + c[k]) / 3.0);
            let l = dot(m, m).sqrt();
            m.map(|t| t / l)
        };
        let band = |c: [f64; 3], lo: f64, hi: f64| -> Vec<bool> {
            (0..mesh.num_faces())
                .map(|f| {
                    let t = dot(centroid(f), c).clamp(-1.0, 1.0).acos();
                    lo < t && t < hi
                })
                .collect()
        };
        let c = [0.6, -0.64, 0.48];
        let mut cases: Vec<Vec<bool>> = vec![
            band(c, 0.3, 0.5),
            band(c, 0.3, 0.5)
                .iter()
                .zip(band(c, 0.9, 1.1))
                .map(|(a, b)| *a || b)
                .collect(),
            band([0.0, 0.0, 1.0], 1.45, 1.69),
            band(c, 2.8, 3.2),
        ];
        let mut state = 0x9e37_79b9_7f4a_7c15u64;
        for percent in [5, 20, 45, 70] {
            cases.push(
                (0..mesh.num_faces())
                    .map(|_| {
                        state ^= state << 13;
                        state ^= state >> 7;
                        state ^= state << 17;
                        state % 100 < percent
                    })
                    .collect(),
            );
        }
        let mut holes_seen = 0;
        for inside in cases {
            let patch: Vec<usize> = (0..mesh.num_faces()).filter(|&f| inside[f]).collect();
            let (mut inside_a, mut patch_a) = (inside.clone(), patch.clone());
            let (mut inside_b, mut patch_b) = (inside.clone(), patch.clone());
            fill_holes(&mesh, &conn, &mut inside_a, &mut patch_a);
            fill_holes_by_scan(&mesh, &conn, &mut inside_b, &mut patch_b);
            assert_eq!(patch_a, patch_b);
            assert_eq!(inside_a, inside_b);
            holes_seen += patch_a.len() - patch.len();
        }
        assert!(holes_seen > 1000, "{holes_seen}");
    }

    /// The stereographic chart and its inverse agree over 2.6 rad from the centre, and the
    /// chart turns the icosphere's faces counter-clockwise there (they are small against the
    /// circles great circles become).
    #[test]
    fn stereographic_chart_round_trip_and_orientation() {
        let c = [0.6, -0.64, 0.48];
        let rot = rotation_to_south(c);
        let mesh = shapespace_geometry::primitives::icosphere(3);
        let min_cos = STEREO_MAX_ANGLE.cos();
        let mut tested = 0;
        for p in mesh.positions.iter().filter(|p| dot(**p, c) > min_cos) {
            let q = from_stereographic(&rot, stereographic(&rot, *p));
            assert!((0..3).all(|k| (q[k] - p[k]).abs() < 1e-14), "{p:?} → {q:?}");
        }
        for f in &mesh.faces {
            let x = f.map(|v| mesh.positions[v as usize]);
            if x.iter().all(|p| dot(*p, c) > min_cos) {
                let [a, b, d] = x.map(|p| stereographic(&rot, p));
                let planar = (b[0] - a[0]) * (d[1] - a[1]) - (b[1] - a[1]) * (d[0] - a[0]);
                assert!(planar > 0.0);
                assert_eq!(orientation_on_sphere(x[0], x[1], x[2]), 1);
                tested += 1;
            }
        }
        assert!(tested > 1000, "{tested}");
    }

    /// A fold inside a patch larger than a hemisphere (every icosphere face within 2.3 rad of
    /// a vertex c, more than half of the 1,280 faces), which no gnomonic chart holds: the
    /// patch's boundary is a small circle's polygon around −c, a circle again in the
    /// stereographic chart at c, so convex, and the Tutte solve unfolds (Floater). One vertex
    /// next to c reflected through c folds its faces; the stereographic repair leaves none
    /// folded on S² and keeps the boundary.
    #[test]
    fn stereographic_chart_unfolds_a_patch_beyond_a_hemisphere() {
        let mesh = shapespace_geometry::primitives::icosphere(3);
        let conn = Connectivity::of(&mesh);
        let mut x = mesh.positions.clone();
        let c = x[0];
        let v = conn.vertex_neighbors(mesh.num_vertices())[0][0] as usize;
        // v reflected through c along the great circle
        let d = dot(x[v], c);
        let p = [0, 1, 2].map(|k| 2.0 * d * c[k] - x[v][k]);
        x[v] = p;
        let folded = folded_on_sphere(&mesh, &x);
        assert!(!folded.is_empty());
        let cos = 2.3f64.cos();
        let patch: Vec<usize> = (0..mesh.num_faces())
            .filter(|&f| mesh.faces[f].iter().all(|&u| dot(mesh.positions[u as usize], c) > cos))
            .collect();
        assert!(2 * patch.len() > mesh.num_faces(), "{} faces", patch.len());
        let areas = face_areas(&mesh);
        let total: f64 = areas.iter().sum();
        let shares: Vec<f64> = areas.iter().map(|a| a / total * 4.0 * std::f64::consts::PI).collect();
        // too wide for a gnomonic chart
        assert!(matches!(
            repair_patch(
                &mesh,
                &x,
                &patch,
                &shares,
                Projection::Gnomonic,
                None,
                ChartMethod::Tutte
            ),
            Err(ChartFailure::TooWide)
        ));
        let Ok(moved) = repair_patch(
            &mesh,
            &x,
            &patch,
            &shares,
            Projection::Stereographic,
            Some(c),
            ChartMethod::Tutte,
        ) else {
            panic!("the stereographic chart failed");
        };
        assert!(moved.contains_key(&(v as u32)));
        for (u, q) in moved {
            x[u as usize] = q;
        }
        assert_eq!(folded_on_sphere(&mesh, &x).len(), 0);
        // the patch's boundary (vertices of faces outside it) did not move
        for f in (0..mesh.num_faces()).filter(|f| !patch.contains(f)) {
            for u in mesh.faces[f] {
                if u as usize != v {
                    assert_eq!(x[u as usize], mesh.positions[u as usize]);
                }
            }
        }
        for p in &x {
            assert!((dot(*p, *p).sqrt() - 1.0).abs() < 1e-14);
        }
    }

    /// The gnomonic chart and its inverse agree, and the chart turns a face counter-clockwise
    /// exactly when it is positively oriented on S².
    #[test]
    fn gnomonic_chart_round_trip_and_orientation() {
        let rot = rotation_to_south([0.6, -0.64, 0.48]);
        let mesh = shapespace_geometry::primitives::icosphere(3);
        let c = [0.6, -0.64, 0.48];
        for p in mesh.positions.iter().filter(|p| dot(**p, c) > 0.2) {
            let q = from_gnomonic(&rot, gnomonic(&rot, *p));
            assert!((0..3).all(|k| (q[k] - p[k]).abs() < 1e-14), "{p:?} → {q:?}");
        }
        let mut tested = 0;
        for f in &mesh.faces {
            let x = f.map(|v| mesh.positions[v as usize]);
            if x.iter().all(|p| dot(*p, c) > 0.2) {
                let [a, b, d] = x.map(|p| gnomonic(&rot, p));
                let planar = (b[0] - a[0]) * (d[1] - a[1]) - (b[1] - a[1]) * (d[0] - a[0]);
                assert_eq!(planar > 0.0, orientation_on_sphere(x[0], x[1], x[2]) == 1);
                let [a, b, d] = [x[0], x[2], x[1]].map(|p| gnomonic(&rot, p));
                let planar = (b[0] - a[0]) * (d[1] - a[1]) - (b[1] - a[1]) * (d[0] - a[0]);
                assert!(planar < 0.0);
                tested += 1;
            }
        }
        assert!(tested > 100);
    }

    /// Folds made on a sphere mesh (a vertex pushed across its neighbours, in several places)
    /// are all unfolded, no face is left folded on S², and vertices far from the folds stay.
    #[test]
    fn charts_unfold_pushed_vertices() {
        let mesh = shapespace_geometry::primitives::icosphere(4);
        let conn = Connectivity::of(&mesh);
        let neighbors = conn.vertex_neighbors(mesh.num_vertices());
        let mut x = mesh.positions.clone();
        let pushed = [7usize, 400, 1500, 2200];
        for &v in &pushed {
            // past the far side of its one-ring: beyond the farthest neighbour
            let w = neighbors[v][0] as usize;
            let q = [0, 1, 2].map(|k| x[v][k] + 1.6 * (x[w][k] - x[v][k]));
            let l = dot(q, q).sqrt();
            x[v] = q.map(|t| t / l);
        }
        let before = folded_on_sphere(&mesh, &x).len();
        assert!(before >= 2 * pushed.len(), "{before} folded");
        let reference = x.clone();
        let info = repair_in_charts(&mesh, &mut x);
        assert_eq!(folded_on_sphere(&mesh, &x).len(), 0, "{info:?}");
        assert_eq!(info.clusters, info.repaired);
        for p in &x {
            assert!((dot(*p, *p).sqrt() - 1.0).abs() < 1e-14);
        }
        // a vertex 6 rings or more from every pushed vertex does not move
        let mut far = vec![true; mesh.num_vertices()];
        let mut front: Vec<usize> = pushed.to_vec();
        for _ in 0..6 {
            let mut next = Vec::new();
            for v in front {
                far[v] = false;
                next.extend(neighbors[v].iter().map(|&w| w as usize).filter(|&w| far[w]));
            }
            front = next;
        }
        for v in front {
            far[v] = false;
        }
        let unmoved = (0..mesh.num_vertices())
            .filter(|&v| far[v])
            .all(|v| x[v] == reference[v]);
        assert!(unmoved && info.vertices_moved < 200, "{info:?}");
    }
}
