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
//! such folds get the sphere map's local repair (a stereographic chart around each cluster).
//!
//! Measured (`tests/sphere_param.rs`): an ellipsoid 1:1:2 of 2,562 vertices goes from a 95th
//! percentile |ln(one-ring area ratio)| of 1.50 (conformal) to 0.027, with no flipped face;
//! TOSCA wolf0 from 24.9 to 0.40, but its centroid map folds 132 faces and the local repair
//! leaves 4 of 8,684: the disk's patch re-embedding ([`crate::fold_repair`]) is not yet
//! available on the sphere.

use shapespace_conformal::sphere::quality::orientation_on_sphere;
use shapespace_conformal::sphere::repair::repair_sphere_folds;
use shapespace_conformal::{sphere_map, SphereMap, SphereMapParams};
use shapespace_geometry::quantities::vertex_dual_areas;
use shapespace_geometry::TriMesh;
use shapespace_omt::sphere::{solve_sphere_ot, SphereMeasure, SphereOtParams};
use shapespace_omt::OmtError;

use crate::error::AnalysisError;

/// Options of [`area_preserving_sphere_map`].
#[derive(Clone, Debug, Default)]
pub struct SphereParamParams {
    /// The conformal sphere map (normalization: Möbius centering by default).
    pub sphere_map: SphereMapParams,
    /// The OT solver on the sphere.
    pub ot: SphereOtParams,
    /// Subdivisions of the icosphere carrying the uniform source (20·4^s flat triangles);
    /// default: the smallest s ≥ 4 with at least two triangles per vertex.
    pub source_subdivisions: Option<usize>,
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
    /// Vertex moves of the fold repair (the moved vertices' cells no longer have their exact
    /// areas).
    pub fold_repairs: usize,
    /// Subdivisions of the icosphere source.
    pub source_subdivisions: usize,
}

/// The area-preserving map of a closed genus-0 `mesh` onto the unit sphere (module docs).
///
/// Errors: the conformal sphere map fails (not a closed genus-0 surface, beyond double
/// precision, bad markers); the OT solve fails or does not converge; a cell is empty.
pub fn area_preserving_sphere_map(
    mesh: &TriMesh,
    params: &SphereParamParams,
) -> Result<SphereAreaPreservingMap, AnalysisError> {
    let conformal = sphere_map(mesh, &params.sphere_map).map_err(AnalysisError::SphereMap)?;
    let n = mesh.num_vertices();
    let subdivisions = params.source_subdivisions.unwrap_or_else(|| {
        let mut s = 4;
        while 20 * 4usize.pow(s as u32) < 2 * n && s < 9 {
            s += 1;
        }
        s
    });
    let source = SphereMeasure::uniform_icosphere(subdivisions).map_err(AnalysisError::Transport)?;
    let thirds = vertex_dual_areas(mesh);
    let total: f64 = thirds.iter().sum();
    let masses: Vec<f64> = thirds.iter().map(|a| a * source.total_mass() / total).collect();
    let solution = solve_sphere_ot(&source, &conformal.positions, &masses, &params.ot)
        .and_then(|s| s.into_result())
        .map_err(AnalysisError::Transport)?;
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
    // the centroid map can fold slivers, as in the plane: the local repair of the sphere map,
    // in a stereographic chart around each cluster of folded faces
    // (rounds while it still moves vertices: a repaired cluster can leave a fold beside it)
    let flipped = |x: &[[f64; 3]]| {
        mesh.faces
            .iter()
            .filter(|f| {
                let [a, b, c] = f.map(|v| x[v as usize]);
                orientation_on_sphere(a, b, c) != 1
            })
            .count()
    };
    let mut fold_repairs = 0;
    for _ in 0..8 {
        if flipped(&positions) == 0 {
            break;
        }
        let moves = repair_sphere_folds(mesh, &mut positions, &vec![false; n]);
        if moves == 0 {
            break;
        }
        fold_repairs += moves;
    }
    let num_flipped = flipped(&positions);
    Ok(SphereAreaPreservingMap {
        positions,
        conformal,
        target_masses: solution.target_masses.clone(),
        cell_areas: solution.cells.masses.clone(),
        heights: solution.heights.clone(),
        iterations: solution.iterations,
        num_flipped,
        fold_repairs,
        source_subdivisions: subdivisions,
    })
}
