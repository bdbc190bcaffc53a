//! The conformal map of a disk-type mesh onto the unit disk, with automatic markers, and its
//! distortion: what `shapespace conformal` computes.
//!
//!     cargo run --release -p shapespace-conformal --example disk_map [MESH]
//!
//! Without an argument it maps the bundled face `datasets/faces/id00_neutral.obj`.

use std::path::PathBuf;

use shapespace_conformal::{disk_map, DiskMapParams, Markers};
use shapespace_geometry::io::read_mesh;

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let path = std::env::args_os()
        .nth(1)
        .map(PathBuf::from)
        .unwrap_or_else(|| PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../../datasets/faces/id00_neutral.obj"));
    let mesh = read_mesh(&path)?;
    // auto markers: p ↦ 0 is the vertex farthest from the boundary, q ↦ 1 a boundary vertex
    let map = disk_map(&mesh, &Markers::default(), &DiskMapParams::default())?;
    println!(
        "{}: {} vertices mapped by {}",
        path.file_name().unwrap_or_default().to_string_lossy(),
        map.uv.len(),
        map.info.method
    );
    println!(
        "  markers: centre {}, boundary vertex {}",
        map.info.markers.center, map.info.markers.boundary_vertex
    );
    let q = &map.quality;
    println!(
        "  angle distortion (degrees): median {:.3}, p95 {:.3}, max {:.3}",
        q.angle_distortion_deg.median, q.angle_distortion_deg.p95, q.angle_distortion_deg.max
    );
    println!("  flipped image faces: {}", q.num_flipped);
    // the pushed-forward area density per face: what the distances transport
    let (lo, hi) = map
        .face_densities
        .iter()
        .fold((f64::INFINITY, 0.0f64), |(lo, hi), &d| (lo.min(d), hi.max(d)));
    println!("  face densities from {lo:.3e} to {hi:.3e}");
    Ok(())
}
