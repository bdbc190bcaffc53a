//! The area-preserving map of a disk-type mesh onto the unit disk (conformal map + OT +
//! centroid map, Su et al. 2015 Alg. 2): what `shapespace param` computes.
//!
//!     cargo run --release -p shapespace-analysis --example area_preserving [MESH]
//!
//! Without an argument it maps the bundled face `datasets/faces/id00_neutral.obj`.

use std::path::PathBuf;

use shapespace_analysis::area_preserving::{area_preserving_map, AreaPreservingParams};
use shapespace_conformal::Markers;
use shapespace_geometry::io::read_mesh;

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let path = std::env::args_os()
        .nth(1)
        .map(PathBuf::from)
        .unwrap_or_else(|| PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../../datasets/faces/id00_neutral.obj"));
    let mesh = read_mesh(&path)?;
    let map = area_preserving_map(&mesh, &Markers::default(), &AreaPreservingParams::default())?;
    // each vertex's power cell has the area of its one-ring share of the surface
    let worst = map
        .cell_areas
        .iter()
        .zip(&map.target_masses)
        .map(|(a, m)| (a - m).abs() / m)
        .fold(0.0f64, f64::max);
    println!(
        "{}: {} vertices on the {:?}",
        path.file_name().unwrap_or_default().to_string_lossy(),
        map.uv.len(),
        map.domain
    );
    println!("  largest relative cell-area error {worst:.2e}");
    println!("  conformal step: {} flipped faces", map.conformal.quality.num_flipped);
    Ok(())
}
