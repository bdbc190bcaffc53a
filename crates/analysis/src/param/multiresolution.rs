//! The multiresolution scheme of the OMT gradient flow [Dominitz & Tannenbaum 2010, "Texture
//! mapping via optimal mass transport", IEEE TVCG 16(3)]: the flow is run first on coarse
//! resolutions of the domain, and each result, prolonged to the next finer one, is where the
//! flow continues; the flow on the mesh itself starts from the prolonged coarse optimal map
//! instead of a first mass-preserving map of its own.
//!
//! Dominitz & Tannenbaum resample the density on a nested hierarchy of the sphere (a subdivided
//! polyhedron, with spherical wavelets as the levels' bases). Here the coarse levels are nested
//! regular triangulations of the domain and the finest level is the conformal image of the mesh
//! (the domain of [`crate::gradient_flow`] and [`crate::sphere_flows`]):
//!
//! - **Levels.** With `levels` = L, level k = L, …, 1 has about #V / 4^k vertices: the
//!   concentric-ring unit disk ([`shapespace_geometry::primitives::unit_disk`], rings
//!   ⌊√(#V / (3·4^k))⌋ ≥ 4) or the icosphere ([`shapespace_geometry::primitives::icosphere`],
//!   the finest subdivision s ≥ 2 with 10·4^s ≤ (#V − 2) / 4^k). Coarser levels that would repeat
//!   a size or fall below those minima are dropped.
//! - **Restriction.** The surface area of each face of the mesh is spread over the conformal
//!   image of that face (its k² sub-triangle centroids, k ≈ 2 √(|f| / mean coarse face area),
//!   at most 32) and each share added to the coarse face holding it, so the coarse masses sum
//!   to the surface area; a coarse face that receives nothing gets the density of the mesh
//!   face holding its centroid times its area.
//! - **Coarsest level.** The first mass-preserving map is the Moser (Lie) advection of the
//!   coarse grid ([`crate::lie_advection::advect`], [`crate::sphere_flows::advect_on_sphere`]),
//!   then the flow.
//! - **Prolongation.** The coarse map is interpolated linearly at the next level's domain
//!   points (point location in the coarse domain; rim points put back on the circle, points
//!   on S² normalized). The interpolation's area error is then removed by the Moser advection
//!   of the prolonged map to the level's masses (the first mass-preserving map's construction,
//!   started from the prolonged map instead of the conformal one). Where the image crowds
//!   beyond the coarse grid the advection folds a few faces, as the Lie map's does; they are
//!   repaired as the Lie map's are ([`crate::fold_repair`], gnomonic charts on S²), and only
//!   when folds remain is the correction skipped, keeping the prolonged map. The flow
//!   continues from there with its mass projections.
//!
//! Folds of a level's start (the coarse Lie map, or a prolonged map, also on the mesh) are
//! repaired as the single-level maps' are: [`crate::fold_repair`] on the disk, gnomonic charts
//! on S². When folds remain, a coarse level fails, or the Moser correction on the mesh fails
//! (the prolonged map is then not mass-preserving), the scheme reports why and the caller falls
//! back to the single-level flow from its own first mass-preserving map; only when that one
//! keeps folds does the flow start from the uncorrected prolonged map (`uncorrected_start`:
//! an unfolded map whose area the flow's projections may not correct).

use serde::Serialize;
use shapespace_conformal::sphere::quality::orientation_on_sphere;
use shapespace_geometry::{primitives, Connectivity, TriMesh};

use crate::error::AnalysisError;
use crate::fold_repair::{repair_folds, repair_folds_with};
use crate::gradient_flow::{flow, FlowControl, FlowInfo, GradientFlowParams};
use crate::lie_advection::{advect, face_is_ccw, signed_area, LieAdvectionParams};
use crate::point_location::PointLocator;
use crate::registration::sphere::SphereLocator;
use crate::sphere_flows::{
    advect_on_sphere, chord_areas, normalized, sphere_flow, unfolded_on_sphere, SphereLieParams,
};
use crate::sphere_param::repair_in_charts;

type P3 = [f64; 3];

/// Most sub-triangles per side when a mesh face's mass is spread over the coarse faces.
const MAX_SPLIT: usize = 32;

/// One coarse level of the scheme.
#[derive(Clone, Debug, Default, PartialEq, Serialize)]
pub struct LevelInfo {
    /// Vertices of the level's grid.
    pub vertices: usize,
    /// Mean integration steps per vertex of the Moser advection that made the level's start
    /// mass-preserving (0: none, the prolonged map as it was).
    pub lie_mean_steps: f64,
    /// Faces folded by the level's start (the coarse Lie map or the prolonged map) and, on the
    /// sphere, left after the chart repair.
    pub start_folds: usize,
    /// See `start_folds`.
    pub start_folds_after_repair: usize,
    /// The flow on this level.
    pub flow: FlowInfo,
}

/// What the multiresolution scheme did before the flow on the mesh.
#[derive(Clone, Debug, Default, PartialEq, Serialize)]
pub struct MultiresolutionInfo {
    /// The coarse levels, coarsest first (empty: the single-level flow).
    pub levels: Vec<LevelInfo>,
    /// Faces of the mesh folded by the prolonged coarse map and, on the sphere, left after the
    /// chart repair.
    pub prolonged_folds: usize,
    /// See `prolonged_folds`.
    pub prolonged_folds_after_repair: usize,
    /// Mean integration steps per vertex of the Moser advection of the prolonged map on the
    /// mesh (0: not applied, because the prolonged map folds or the advection leaves folds
    /// after the repair).
    pub correction_mean_steps: f64,
    /// The flow on the mesh started from the prolonged map without its Moser correction,
    /// because the correction failed and the Lie map keeps folds.
    pub uncorrected_start: bool,
    /// Why the flow on the mesh did not start from the prolonged map (it then starts from its
    /// own first mass-preserving map); `None` when it did or no level was asked for.
    pub fallback: Option<String>,
}

/// The ring counts of the disk levels for a mesh of `n` vertices, coarsest first.
pub fn disk_level_rings(n: usize, levels: usize) -> Vec<usize> {
    let mut rings: Vec<usize> = (1..=levels)
        .rev()
        .map(|k| ((n as f64) / (3.0 * 4f64.powi(k as i32))).sqrt().floor() as usize)
        .filter(|&r| r >= 4)
        .collect();
    rings.dedup();
    rings
}

/// The icosphere subdivisions of the sphere levels for a mesh of `n` vertices, coarsest first.
pub fn sphere_level_subdivisions(n: usize, levels: usize) -> Vec<usize> {
    let mut subdivisions: Vec<usize> = (1..=levels)
        .rev()
        .filter_map(|k| {
            let cap = n.saturating_sub(2) as f64 / 4f64.powi(k as i32);
            (2..12usize).take_while(|&s| 10.0 * 4f64.powi(s as i32) <= cap).last()
        })
        .collect();
    subdivisions.dedup();
    subdivisions
}

/// Barycentric coordinates of the centroids of the k² sub-triangles of a triangle split k
/// times per side.
fn split_centroids(k: usize) -> Vec<[f64; 3]> {
    let kf = k as f64;
    let mut out = Vec::with_capacity(k * k);
    for i in 0..k {
        for j in 0..k - i {
            let (a, b) = ((i as f64 + 1.0 / 3.0) / kf, (j as f64 + 1.0 / 3.0) / kf);
            out.push([a, b, 1.0 - a - b]);
            if i + j + 1 < k {
                let (a, b) = ((i as f64 + 2.0 / 3.0) / kf, (j as f64 + 2.0 / 3.0) / kf);
                out.push([a, b, 1.0 - a - b]);
            }
        }
    }
    out
}

/// Restriction (module docs): the coarse masses (#F of the grid) of the mesh's
/// `surface_areas` over its image faces of `domain_areas` (#F); `point_in_coarse(f, bary)`:
/// the coarse face holding that point of image face f; `density_at_coarse_centroid(c)`: the
/// mesh's density there, for coarse faces that receive nothing.
fn restrict(
    surface_areas: &[f64],
    domain_areas: &[f64],
    coarse_areas: &[f64],
    point_in_coarse: impl Fn(usize, [f64; 3]) -> Option<usize>,
    density_at_coarse_centroid: impl Fn(usize) -> Option<f64>,
) -> Result<Vec<f64>, AnalysisError> {
    let mean_coarse = coarse_areas.iter().sum::<f64>() / coarse_areas.len().max(1) as f64;
    let mut masses = vec![0.0; coarse_areas.len()];
    let mut splits: Vec<Vec<[f64; 3]>> = vec![Vec::new(); MAX_SPLIT + 1];
    for (f, (&a, &d)) in surface_areas.iter().zip(domain_areas).enumerate() {
        let k = ((2.0 * (d.abs() / mean_coarse).sqrt()).ceil() as usize).clamp(1, MAX_SPLIT);
        if splits[k].is_empty() {
            splits[k] = split_centroids(k);
        }
        let share = a / (k * k) as f64;
        for &bary in &splits[k] {
            if let Some(c) = point_in_coarse(f, bary) {
                masses[c] += share;
            }
        }
    }
    for (c, m) in masses.iter_mut().enumerate() {
        if *m <= 0.0 {
            *m = density_at_coarse_centroid(c).unwrap_or(0.0) * coarse_areas[c];
        }
        if !(m.is_finite() && *m > 0.0) {
            return Err(AnalysisError::InvalidInput(format!(
                "multiresolution: coarse face {c} receives no mass"
            )));
        }
    }
    Ok(masses)
}

fn interpolate2(u: &[[f64; 2]], face: [u32; 3], bary: [f64; 3]) -> [f64; 2] {
    let mut p = [0.0; 2];
    for k in 0..3 {
        for d in 0..2 {
            p[d] += bary[k] * u[face[k] as usize][d];
        }
    }
    p
}

fn interpolate3(u: &[P3], face: [u32; 3], bary: [f64; 3]) -> P3 {
    let mut p = [0.0; 3];
    for k in 0..3 {
        for d in 0..3 {
            p[d] += bary[k] * u[face[k] as usize][d];
        }
    }
    normalized(p)
}

/// A level's domain and map, as the next level sees it.
struct Level<P> {
    x: Vec<P>,
    faces: Vec<[u32; 3]>,
    u: Vec<P>,
}

/// The disk's coarse levels (module docs) for the flow on the mesh `faces` with its conformal
/// image `domain` (#V, counter-clockwise, rim on the unit circle where `is_boundary`) and
/// `surface_areas` (#F): the prolonged map on the mesh (#V, rim on the circle), which may fold
/// faces (counted in `info.prolonged_folds`; the caller repairs and corrects it). A coarse
/// level's folded start is repaired ([`crate::fold_repair`]) before its flow. Errors: no level
/// fits the mesh, or a coarse level failed.
pub fn disk_multiresolution_start(
    faces: &[[u32; 3]],
    surface_areas: &[f64],
    is_boundary: &[bool],
    domain: &[[f64; 2]],
    levels: usize,
    params: &GradientFlowParams,
    info: &mut MultiresolutionInfo,
) -> Result<Vec<[f64; 2]>, AnalysisError> {
    let lie = &params.start;
    let rings = disk_level_rings(domain.len(), levels);
    if rings.is_empty() {
        return Err(AnalysisError::InvalidInput(format!(
            "multiresolution: {} vertices leave no coarse level",
            domain.len()
        )));
    }
    let domain_areas: Vec<f64> = faces.iter().map(|f| signed_area(domain, f)).collect();
    let fine_locator = PointLocator::new(domain, faces)?;
    let mut previous: Option<Level<[f64; 2]>> = None;
    for r in rings {
        let grid = primitives::unit_disk(r);
        let x: Vec<[f64; 2]> = grid.positions.iter().map(|p| [p[0], p[1]]).collect();
        let rim = Connectivity::of(&grid).boundary_vertices(x.len());
        let coarse_areas: Vec<f64> = grid.faces.iter().map(|f| signed_area(&x, f)).collect();
        let locator = PointLocator::new(&x, &grid.faces)?;
        let masses = restrict(
            surface_areas,
            &domain_areas,
            &coarse_areas,
            |f, bary| Some(locator.locate(interpolate2(domain, faces[f], bary))?.face as usize),
            |c| {
                let p = interpolate2(&x, grid.faces[c], [1.0 / 3.0; 3]);
                let f = fine_locator.locate(p)?.face as usize;
                Some(surface_areas[f] / domain_areas[f])
            },
        )?;
        let mut level = LevelInfo {
            vertices: x.len(),
            ..Default::default()
        };
        let start = match &previous {
            None => {
                let (u, lie_info) = advect(&grid.faces, &masses, &rim, &x, lie)?;
                level.lie_mean_steps = lie_info.mean_steps;
                u
            }
            Some(prev) => {
                let prolonged = prolong_disk(prev, &x, &rim)?;
                let (u, steps) = disk_moser_correction(&grid, None, &masses, &rim, prolonged, lie);
                level.lie_mean_steps = steps.unwrap_or(0.0);
                u
            }
        };
        let mut start = start;
        level.start_folds = grid.faces.iter().filter(|f| !face_is_ccw(&start, f)).count();
        if level.start_folds > 0 {
            // (a failed repair leaves folds, counted below)
            let _ = repair_folds(&grid, &rim, &mut start, &lie.fold_repair);
            level.start_folds_after_repair = grid.faces.iter().filter(|f| !face_is_ccw(&start, f)).count();
            if level.start_folds_after_repair > 0 {
                return Err(AnalysisError::FlowStartFolded {
                    folded: level.start_folds_after_repair,
                    reason: format!(
                        "the start of the {}-vertex level keeps them after the fold repair",
                        x.len()
                    ),
                });
            }
        }
        let (u, flow_info) = flow(&grid.faces, &masses, &rim, &x, &start, params)?;
        level.flow = flow_info;
        info.levels.push(level);
        previous = Some(Level {
            x,
            faces: grid.faces,
            u,
        });
    }
    let start = prolong_disk(previous.as_ref().expect("one level at least"), domain, is_boundary)?;
    info.prolonged_folds = faces.iter().filter(|f| !face_is_ccw(&start, f)).count();
    Ok(start)
}

/// The Moser advection of a prolonged map to the level's masses (module docs, "Prolongation"),
/// with its mean steps per vertex. Faces the advection folds are repaired as the Lie map's are
/// ([`crate::fold_repair`] with `lie.fold_repair`, `connectivity` that of `mesh`); the
/// prolonged map itself (and `None`) when the advection fails or folds remain.
pub(crate) fn disk_moser_correction(
    mesh: &TriMesh,
    connectivity: Option<&Connectivity>,
    masses: &[f64],
    rim: &[bool],
    prolonged: Vec<[f64; 2]>,
    lie: &LieAdvectionParams,
) -> (Vec<[f64; 2]>, Option<f64>) {
    let faces = &mesh.faces;
    if faces.iter().any(|f| !face_is_ccw(&prolonged, f)) {
        return (prolonged, None);
    }
    let Ok((mut u, info)) = advect(faces, masses, rim, &prolonged, lie) else {
        return (prolonged, None);
    };
    if faces.iter().any(|f| !face_is_ccw(&u, f)) {
        // (a failed repair leaves folds, refused below)
        let _ = repair_folds_with(mesh, connectivity, rim, &mut u, &lie.fold_repair);
    }
    if faces.iter().all(|f| face_is_ccw(&u, f)) {
        (u, Some(info.mean_steps))
    } else {
        (prolonged, None)
    }
}

/// As [`disk_moser_correction`] on S², the advection's folds repaired in gnomonic charts as
/// the sphere's Lie map's are ([`crate::sphere_param`]).
pub(crate) fn sphere_moser_correction(
    mesh: &TriMesh,
    masses: &[f64],
    prolonged: Vec<P3>,
    lie: &SphereLieParams,
) -> (Vec<P3>, Option<f64>) {
    let faces = &mesh.faces;
    if !unfolded_on_sphere(faces, &prolonged) {
        return (prolonged, None);
    }
    let Ok((mut u, info)) = advect_on_sphere(faces, masses, &prolonged, 1.0, lie) else {
        return (prolonged, None);
    };
    if !unfolded_on_sphere(faces, &u) {
        repair_in_charts(mesh, &mut u);
    }
    if unfolded_on_sphere(faces, &u) {
        (u, Some(info.mean_steps))
    } else {
        (prolonged, None)
    }
}

/// The start a flow takes from the prolonged map: refused when `folded_after_repair` faces are
/// still folded (`fold_reason` says after which repair); else the Moser `correction` of it,
/// whose mean steps go to `info`, or, when the correction fails, an error with the uncorrected
/// map kept in `uncorrected` (the fallback's last resort).
pub(crate) fn corrected_start<P>(
    folded_after_repair: usize,
    correction: impl FnOnce() -> (Vec<P>, Option<f64>),
    info: &mut MultiresolutionInfo,
    uncorrected: &mut Option<Vec<P>>,
    fold_reason: &str,
) -> Result<Vec<P>, AnalysisError> {
    match folded_after_repair {
        0 => match correction() {
            (start, Some(steps)) => {
                info.correction_mean_steps = steps;
                Ok(start)
            }
            (start, None) => {
                *uncorrected = Some(start);
                Err(AnalysisError::InvalidInput(
                    "the Moser correction of the prolonged map fails or folds".into(),
                ))
            }
        },
        folded => Err(AnalysisError::FlowStartFolded {
            folded,
            reason: fold_reason.into(),
        }),
    }
}

fn prolong_disk(level: &Level<[f64; 2]>, points: &[[f64; 2]], rim: &[bool]) -> Result<Vec<[f64; 2]>, AnalysisError> {
    let locator = PointLocator::new(&level.x, &level.faces)?;
    points
        .iter()
        .zip(rim)
        .map(|(&p, &on_rim)| {
            let loc = locator
                .locate(p)
                .ok_or_else(|| AnalysisError::InvalidInput(format!("multiresolution: cannot locate {p:?}")))?;
            let q = interpolate2(&level.u, level.faces[loc.face as usize], loc.bary);
            Ok(if on_rim {
                let r = q[0].hypot(q[1]);
                [q[0] / r, q[1] / r]
            } else {
                q
            })
        })
        .collect()
}

/// The sphere's coarse levels (module docs) for the flow on the mesh `faces` with its conformal
/// image `domain` (#V unit vectors) and `surface_areas` (#F): the prolonged map on the mesh,
/// which may fold faces (counted in `info.prolonged_folds`; the caller repairs and corrects it). A coarse
/// level's folded start is repaired in gnomonic charts ([`crate::sphere_param`]) before its
/// flow. Errors: no level fits the mesh or a coarse level failed.
pub fn sphere_multiresolution_start(
    faces: &[[u32; 3]],
    surface_areas: &[f64],
    domain: &[P3],
    levels: usize,
    control: &FlowControl,
    lie: &SphereLieParams,
    info: &mut MultiresolutionInfo,
) -> Result<Vec<P3>, AnalysisError> {
    let subdivisions = sphere_level_subdivisions(domain.len(), levels);
    if subdivisions.is_empty() {
        return Err(AnalysisError::InvalidInput(format!(
            "multiresolution: {} vertices leave no coarse level",
            domain.len()
        )));
    }
    let domain_areas = chord_areas(faces, domain);
    let fine_locator = SphereLocator::new(domain, faces)?;
    let mut previous: Option<Level<P3>> = None;
    for s in subdivisions {
        let grid = primitives::icosphere(s);
        let x = grid.positions.clone();
        let coarse_areas = chord_areas(&grid.faces, &x);
        let locator = SphereLocator::new(&x, &grid.faces)?;
        let masses = restrict(
            surface_areas,
            &domain_areas,
            &coarse_areas,
            |f, bary| Some(locator.locate(interpolate3(domain, faces[f], bary))?.face as usize),
            |c| {
                let p = interpolate3(&x, grid.faces[c], [1.0 / 3.0; 3]);
                let f = fine_locator.locate(p)?.face as usize;
                Some(surface_areas[f] / domain_areas[f])
            },
        )?;
        let mut level = LevelInfo {
            vertices: x.len(),
            ..Default::default()
        };
        let start = match &previous {
            None => {
                let (u, lie_info) = advect_on_sphere(&grid.faces, &masses, &x, 1.0, lie)?;
                level.lie_mean_steps = lie_info.mean_steps;
                u
            }
            Some(prev) => {
                let prolonged = prolong_sphere(prev, &x)?;
                let (u, steps) = sphere_moser_correction(&grid, &masses, prolonged, lie);
                level.lie_mean_steps = steps.unwrap_or(0.0);
                u
            }
        };
        let mut start = start;
        level.start_folds = count_folded(&grid.faces, &start);
        if level.start_folds > 0 {
            repair_in_charts(&grid, &mut start);
            level.start_folds_after_repair = count_folded(&grid.faces, &start);
        }
        let (u, flow_info) = sphere_flow(&grid.faces, &masses, &x, &start, control)?;
        level.flow = flow_info;
        info.levels.push(level);
        previous = Some(Level {
            x,
            faces: grid.faces,
            u,
        });
    }
    let start = prolong_sphere(previous.as_ref().expect("one level at least"), domain)?;
    info.prolonged_folds = count_folded(faces, &start);
    Ok(start)
}

/// Faces of `x` not positively oriented on S² (exact).
pub(crate) fn count_folded(faces: &[[u32; 3]], x: &[P3]) -> usize {
    if unfolded_on_sphere(faces, x) {
        return 0;
    }
    faces
        .iter()
        .filter(|f| {
            let [a, b, c] = f.map(|v| x[v as usize]);
            orientation_on_sphere(a, b, c) != 1
        })
        .count()
}

fn prolong_sphere(level: &Level<P3>, points: &[P3]) -> Result<Vec<P3>, AnalysisError> {
    let locator = SphereLocator::new(&level.x, &level.faces)?;
    points
        .iter()
        .map(|&p| {
            let loc = locator
                .locate(p)
                .ok_or_else(|| AnalysisError::InvalidInput(format!("multiresolution: cannot locate {p:?}")))?;
            Ok(interpolate3(&level.u, level.faces[loc.face as usize], loc.bary))
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn split_centroids_cover_the_triangle_evenly() {
        for k in 1..6 {
            let c = split_centroids(k);
            assert_eq!(c.len(), k * k);
            let mean = [0, 1, 2].map(|d| c.iter().map(|b| b[d]).sum::<f64>() / c.len() as f64);
            for m in mean {
                assert!((m - 1.0 / 3.0).abs() < 1e-12, "{k} {mean:?}");
            }
            assert!(c.iter().all(|b| b.iter().all(|&t| t > 0.0)));
        }
    }

    #[test]
    fn level_sizes() {
        // 817 vertices (16 rings): 8 rings (217) and 4 rings (61)
        assert_eq!(disk_level_rings(817, 2), vec![4, 8]);
        assert_eq!(disk_level_rings(100, 2), Vec::<usize>::new());
        // 10,242 vertices: 642 and 2,562; 4,344: 162 and 642
        assert_eq!(sphere_level_subdivisions(10_242, 2), vec![3, 4]);
        assert_eq!(sphere_level_subdivisions(4_344, 2), vec![2, 3]);
        assert_eq!(sphere_level_subdivisions(400, 2), Vec::<usize>::new());
    }
}
