//! Distortion of a surface parameterization, and the side-by-side report of a conformal and an
//! area-preserving map [Su et al. 2015, §5.1 and Fig. 2 (e)–(h); Zhao et al. 2013, §6].
//!
//! Per face (via `shapespace_conformal::quality`, surface scaled to area π): the singular values
//! γ_max ≥ γ_min of the affine map of the face give
//! $$\Upsilon = \ln(\gamma_{max}\gamma_{min}) = \ln\frac{A_{2D}}{A_{3D}}, \qquad
//!   \Lambda = \ln\frac{\gamma_{max}}{\gamma_{min}},$$
//! and the angle distortion is the mean |θ_3D − θ_2D| over the corners (degrees here).
//! Per vertex, the log area ratio of Su et al. §5.1,
//! $$\varepsilon_i = \ln\frac{\sum_{f \ni i} A_{2D}(f) / \sum_f A_{2D}(f)}{\sum_{f \ni i} A_{3D}(f) / \sum_f A_{3D}(f)},$$
//! i.e. both the surface and its image are normalized to the same total area before the one-ring
//! areas are compared (so a global scale does not count). Flipped faces (exact orientation
//! test of the image) are counted with their 3D area fraction; their ε and Υ are still computed
//! from the unsigned image area.

use serde::Serialize;
use shapespace_conformal::quality::{face_distortions, FaceDistortions, Stats};
use shapespace_conformal::sphere::quality::sphere_face_distortions;
use shapespace_geometry::quantities::face_areas;
use shapespace_geometry::TriMesh;

use crate::error::AnalysisError;

/// Distortion of one map `uv` of a mesh (#F per-face arrays, #V per-vertex arrays).
#[derive(Clone, Debug, Serialize)]
pub struct MapDistortion {
    /// Name of the map (e.g. "conformal", "area-preserving").
    pub name: String,
    /// Υ per face, #F (0 = area preserving).
    pub face_area_distortion: Vec<f64>,
    /// Λ per face, #F (0 = conformal).
    pub face_quasi_conformal_distortion: Vec<f64>,
    /// Mean corner angle error per face, degrees, #F.
    pub face_angle_distortion_deg: Vec<f64>,
    /// ε per vertex, #V (0 = the one-ring keeps its share of the area).
    pub vertex_log_area_ratio: Vec<f64>,
    /// Statistics of |Υ|.
    pub abs_area_distortion: Stats,
    /// Statistics of Λ.
    pub quasi_conformal_distortion: Stats,
    /// Statistics of the angle distortion (degrees).
    pub angle_distortion_deg: Stats,
    /// Statistics of |ε|.
    pub abs_vertex_log_area_ratio: Stats,
    /// Faces whose image is clockwise (exact test).
    pub num_flipped: usize,
    /// Faces whose image has exactly zero area.
    pub num_degenerate: usize,
    /// 3D area fraction of the flipped and degenerate faces.
    pub flipped_area_fraction: f64,
    /// Image area of the flipped faces (absolute, in the units of `uv`).
    pub flipped_image_area: f64,
}

/// The conformal and the area-preserving map side by side.
#[derive(Clone, Debug, Serialize)]
pub struct DistortionReport {
    /// #V.
    pub num_vertices: usize,
    /// #F.
    pub num_faces: usize,
    /// The maps, in the order given (conformal first in [`distortion_report`]).
    pub maps: Vec<MapDistortion>,
}

/// Distortion of the map `uv` (#V) of `mesh` (module docs). Errors: `uv` of the wrong length,
/// a zero-area 3D face.
pub fn map_distortion(name: &str, mesh: &TriMesh, uv: &[[f64; 2]]) -> Result<MapDistortion, AnalysisError> {
    let d = face_distortions(mesh, uv).map_err(AnalysisError::DiskMap)?;
    let areas2: Vec<f64> = mesh
        .faces
        .iter()
        .map(|f| {
            let [a, b, c] = f.map(|v| uv[v as usize]);
            0.5 * ((b[0] - a[0]) * (c[1] - a[1]) - (b[1] - a[1]) * (c[0] - a[0])).abs()
        })
        .collect();
    Ok(gather(name, mesh, d, &areas2))
}

/// Distortion of the map `positions` (#V points on the unit sphere) of a closed `mesh`: the
/// same quantities as [`map_distortion`], the image faces taken as flat chordal triangles and
/// the surface scaled to area 4π; a face is flipped when det(a, b, c) < 0 (exact), i.e. when
/// the image triangle turns clockwise seen from outside the sphere. Errors: `positions` of the
/// wrong length, a zero-area 3D face.
pub fn sphere_map_distortion(
    name: &str,
    mesh: &TriMesh,
    positions: &[[f64; 3]],
) -> Result<MapDistortion, AnalysisError> {
    let d = sphere_face_distortions(mesh, positions).map_err(AnalysisError::SphereMap)?;
    let image = mesh.faces.iter().map(|f| {
        let [a, b, c] = f.map(|v| positions[v as usize]);
        let (u, w) = ([0, 1, 2].map(|k| b[k] - a[k]), [0, 1, 2].map(|k| c[k] - a[k]));
        let n = [
            u[1] * w[2] - u[2] * w[1],
            u[2] * w[0] - u[0] * w[2],
            u[0] * w[1] - u[1] * w[0],
        ];
        0.5 * (n[0] * n[0] + n[1] * n[1] + n[2] * n[2]).sqrt()
    });
    Ok(gather(name, mesh, d, &image.collect::<Vec<_>>()))
}

/// [`MapDistortion`] from the per-face values `d` and the unsigned image areas `areas2` (#F).
fn gather(name: &str, mesh: &TriMesh, d: FaceDistortions, areas2: &[f64]) -> MapDistortion {
    let areas3 = face_areas(mesh);
    let (total3, total2): (f64, f64) = (areas3.iter().sum(), areas2.iter().sum());
    let n = mesh.num_vertices();
    let (mut ring3, mut ring2) = (vec![0.0; n], vec![0.0; n]);
    for (f, face) in mesh.faces.iter().enumerate() {
        for &v in face {
            ring3[v as usize] += areas3[f];
            ring2[v as usize] += areas2[f];
        }
    }
    let vertex_log_area_ratio: Vec<f64> = ring2
        .iter()
        .zip(&ring3)
        .map(|(a2, a3)| ((a2 / total2) / (a3 / total3)).ln())
        .collect();
    let mut bad3 = 0.0;
    let mut flipped_image_area = 0.0;
    for (f, &o) in d.orientation.iter().enumerate() {
        if o <= 0 {
            bad3 += areas3[f];
            flipped_image_area += areas2[f];
        }
    }
    let abs_ups: Vec<f64> = d.area_distortion.iter().map(|x| x.abs()).collect();
    let abs_eps: Vec<f64> = vertex_log_area_ratio.iter().map(|x| x.abs()).collect();
    let angle_deg: Vec<f64> = d.angle_distortion.iter().map(|x| x.to_degrees()).collect();
    MapDistortion {
        name: name.to_string(),
        abs_area_distortion: Stats::of(&abs_ups),
        quasi_conformal_distortion: Stats::of(&d.quasi_conformal_distortion),
        angle_distortion_deg: Stats::of(&angle_deg),
        abs_vertex_log_area_ratio: Stats::of(&abs_eps),
        num_flipped: d.orientation.iter().filter(|&&o| o < 0).count(),
        num_degenerate: d.orientation.iter().filter(|&&o| o == 0).count(),
        flipped_area_fraction: if total3 > 0.0 { bad3 / total3 } else { 0.0 },
        flipped_image_area,
        face_area_distortion: d.area_distortion,
        face_quasi_conformal_distortion: d.quasi_conformal_distortion,
        face_angle_distortion_deg: angle_deg,
        vertex_log_area_ratio,
    }
}

/// The side-by-side report of the conformal map `conformal_uv` and the area-preserving map
/// `area_preserving_uv` (both #V) of `mesh`.
pub fn distortion_report(
    mesh: &TriMesh,
    conformal_uv: &[[f64; 2]],
    area_preserving_uv: &[[f64; 2]],
) -> Result<DistortionReport, AnalysisError> {
    Ok(DistortionReport {
        num_vertices: mesh.num_vertices(),
        num_faces: mesh.num_faces(),
        maps: vec![
            map_distortion("conformal", mesh, conformal_uv)?,
            map_distortion("area-preserving", mesh, area_preserving_uv)?,
        ],
    })
}

/// [`distortion_report`] for two maps onto the unit sphere (#V points each, see
/// [`sphere_map_distortion`]).
pub fn sphere_distortion_report(
    mesh: &TriMesh,
    conformal: &[[f64; 3]],
    area_preserving: &[[f64; 3]],
) -> Result<DistortionReport, AnalysisError> {
    Ok(DistortionReport {
        num_vertices: mesh.num_vertices(),
        num_faces: mesh.num_faces(),
        maps: vec![
            sphere_map_distortion("conformal", mesh, conformal)?,
            sphere_map_distortion("area-preserving", mesh, area_preserving)?,
        ],
    })
}
