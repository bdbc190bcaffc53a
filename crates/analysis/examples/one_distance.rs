//! One conformal Wasserstein distance between two meshes with the same markers: what each pair
//! of `shapespace distances` computes.
//!
//!     cargo run --release -p shapespace-analysis --example one_distance [A B]
//!
//! Without arguments it compares two bundled faces, neutral and happy, with the markers of
//! `datasets/faces/landmarks.json`.

use std::path::PathBuf;

use shapespace_analysis::distance::{directed_distance, prepare_shape, PairwiseOptions};
use shapespace_conformal::{DiskMapParams, MarkerFile, Markers};
use shapespace_geometry::io::read_mesh;

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let faces = PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../../datasets/faces");
    let args: Vec<PathBuf> = std::env::args_os().skip(1).map(PathBuf::from).collect();
    let (a, b, markers) = match args.as_slice() {
        [a, b] => (a.clone(), b.clone(), Markers::default()),
        [] => (
            faces.join("id00_neutral.obj"),
            faces.join("id00_happy.obj"),
            MarkerFile::from_json_file(&faces.join("landmarks.json"))?.markers,
        ),
        _ => return Err("give two meshes, or none".into()),
    };
    let params = DiskMapParams::default();
    let sa = prepare_shape("a", &read_mesh(&a)?, &markers, &params)?;
    let sb = prepare_shape("b", &read_mesh(&b)?, &markers, &params)?;
    let newton = PairwiseOptions::default().newton;
    let (ab, _) = directed_distance(&sa, &sb, &newton)?;
    let (ba, _) = directed_distance(&sb, &sa, &newton)?;
    println!(
        "{} -> {}: d = {:.6} ({} Newton steps)",
        a.file_name().unwrap_or_default().to_string_lossy(),
        b.file_name().unwrap_or_default().to_string_lossy(),
        ab.distance,
        ab.iterations
    );
    println!(
        "{} -> {}: d = {:.6} ({} Newton steps)",
        b.file_name().unwrap_or_default().to_string_lossy(),
        a.file_name().unwrap_or_default().to_string_lossy(),
        ba.distance,
        ba.iterations
    );
    println!("cost {:.6e}, dual bound {:.6e}", ab.cost, ab.dual_cost);
    Ok(())
}
