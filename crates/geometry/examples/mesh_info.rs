//! Reads a mesh and prints what `shapespace info` prints first: counts, topology and class.
//!
//!     cargo run --release -p shapespace-geometry --example mesh_info [MESH]
//!
//! Without an argument it reads the bundled face `datasets/faces/id00_neutral.obj`.

use std::path::PathBuf;

use shapespace_geometry::io::read_mesh;
use shapespace_geometry::topology::mesh_report;

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let path = std::env::args_os()
        .nth(1)
        .map(PathBuf::from)
        .unwrap_or_else(|| PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../../datasets/faces/id00_neutral.obj"));
    let mesh = read_mesh(&path)?;
    let report = mesh_report(&mesh)?;
    println!("{}", path.file_name().unwrap_or_default().to_string_lossy());
    println!("  {} vertices, {} faces", mesh.num_vertices(), mesh.num_faces());
    println!(
        "  {} component(s), {} boundary loop(s), Euler characteristic {}, genus {}",
        report.num_components, report.num_boundary_loops, report.euler_characteristic, report.genus
    );
    println!(
        "  area {:.6}, {} degenerate face(s)",
        report.area, report.num_degenerate_faces
    );
    println!(
        "  class: {:?} {:?}",
        report.classification.class, report.classification.reasons
    );
    Ok(())
}
