//! Shared helpers of the integration tests: analytic errors and dataset paths.

use std::path::PathBuf;

use shapespace_conformal::{disk_map, BoundaryMarker, CenterMarker, DiskMap, DiskMapParams, Markers};
use shapespace_geometry::TriMesh;

#[allow(unused_imports)] // each test binary uses its own subset
pub use shapespace_test_support::{shared_file, PUBLIC_DISKS};

/// The repository's `datasets/` folder (None, after a `SKIPPED` line naming it, when absent).
pub fn datasets_dir() -> Option<PathBuf> {
    let d = shapespace_test_support::repo("datasets");
    if d.is_dir() {
        Some(d)
    } else {
        eprintln!("SKIPPED: the repository's datasets folder {} not found", d.display());
        None
    }
}

/// Markers with a vertex center and a vertex boundary marker.
pub fn vertex_markers(p: u32, q: u32) -> Markers {
    Markers {
        center: CenterMarker::Vertex(p),
        boundary: BoundaryMarker::Vertex(q),
    }
}

/// Maps with default parameters, panicking with the error (tests only).
pub fn map(mesh: &TriMesh, markers: &Markers) -> DiskMap {
    disk_map(mesh, markers, &DiskMapParams::default()).unwrap_or_else(|e| panic!("disk map failed: {e}"))
}

/// Errors of a cap map against stereographic projection: (max radius error, max relative
/// density error over faces at the centroid's exact image radius, max angle error).
pub fn cap_errors(mesh: &TriMesh, alpha: f64, dm: &DiskMap) -> (f64, f64, f64) {
    cap_errors_of(mesh, alpha, &dm.uv, &dm.face_densities, dm.info.markers.boundary_vertex)
}

/// [`cap_errors`] for any map: image `uv` (#V), `face_densities` (#F), boundary marker `q`.
pub fn cap_errors_of(mesh: &TriMesh, alpha: f64, uv: &[[f64; 2]], face_densities: &[f64], q: u32) -> (f64, f64, f64) {
    let big_r = (alpha / 2.0).tan();
    let mut rad: f64 = 0.0;
    let mut ang: f64 = 0.0;
    for (p, z) in mesh.positions.iter().zip(uv) {
        let theta = p[2].clamp(-1.0, 1.0).acos();
        let r_exact = (theta / 2.0).tan() / big_r;
        let r = z[0].hypot(z[1]);
        rad = rad.max((r - r_exact).abs());
        if r_exact > 0.05 {
            // exact angle up to the global rotation fixed by q ↦ 1: compare to q's azimuth
            let phi = p[1].atan2(p[0]);
            let q = mesh.positions[q as usize];
            let phi_q = q[1].atan2(q[0]);
            let expect = phi - phi_q;
            let got = z[1].atan2(z[0]);
            let d = (got - expect).rem_euclid(std::f64::consts::TAU);
            ang = ang.max(d.min(std::f64::consts::TAU - d) * r_exact);
        }
    }
    let mut dens: f64 = 0.0;
    for (f, face) in mesh.faces.iter().enumerate() {
        let c: Vec<f64> = (0..3)
            .map(|d| face.iter().map(|&v| mesh.positions[v as usize][d]).sum::<f64>() / 3.0)
            .collect();
        let n = (c[0] * c[0] + c[1] * c[1] + c[2] * c[2]).sqrt();
        let theta = (c[2] / n).clamp(-1.0, 1.0).acos();
        let r = (theta / 2.0).tan() / big_r;
        let mu = (1.0 + big_r * big_r) / (1.0 + big_r * big_r * r * r).powi(2);
        dens = dens.max((face_densities[f] / mu - 1.0).abs());
    }
    (rad, dens, ang)
}

/// Max distance between two uv arrays.
pub fn max_dist(a: &[[f64; 2]], b: &[[f64; 2]]) -> f64 {
    a.iter()
        .zip(b)
        .map(|(p, q)| (p[0] - q[0]).hypot(p[1] - q[1]))
        .fold(0.0, f64::max)
}
