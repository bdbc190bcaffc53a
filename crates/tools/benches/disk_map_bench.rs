//! Timing table of `disk_map` (`cargo bench -p shapespace-tools
//! --bench disk_map_bench`). Prints size, intrinsic flips, linear solves and the best of 3 runs per
//! stage. Meshes: hemispheres of ~1k/10k/100k faces, a jittered unit disk of ~100k faces, and
//! the libigl face.obj and camelhead (shared datasets folder, `$SHAPESPACE_DATA`) and an ICT face.

use std::path::PathBuf;

use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use shapespace_conformal::{disk_map, DiskMapParams, Markers};
use shapespace_geometry::primitives::{spherical_cap, unit_disk};
use shapespace_geometry::TriMesh;

fn jittered_disk(rings: usize) -> TriMesh {
    let mut m = unit_disk(rings);
    let mut rng = ChaCha8Rng::seed_from_u64(3);
    let n = m.num_vertices();
    let h = 1.0 / rings as f64;
    for p in m.positions.iter_mut().take(n - 6 * rings).skip(1) {
        p[0] += 0.3 * h * (rng.random::<f64>() - 0.5);
        p[1] += 0.3 * h * (rng.random::<f64>() - 0.5);
        p[2] = 0.1 * (3.0 * p[0]).sin() * (2.0 * p[1]).cos();
    }
    m
}

fn main() {
    shapespace_tools::at_repository_root();
    // SHAPESPACE_SEQ=1: single-threaded faer (the machine may be shared)
    if std::env::var_os("SHAPESPACE_SEQ").is_some() {
        faer::set_global_parallelism(faer::Par::Seq);
    }
    let mut cases: Vec<(String, TriMesh)> = vec![
        ("hemisphere r13".into(), spherical_cap(std::f64::consts::FRAC_PI_2, 13)),
        ("hemisphere r41".into(), spherical_cap(std::f64::consts::FRAC_PI_2, 41)),
        (
            "hemisphere r129".into(),
            spherical_cap(std::f64::consts::FRAC_PI_2, 129),
        ),
        ("jittered disk r129".into(), jittered_disk(129)),
    ];
    let data = PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../../datasets");
    let shared = shapespace_test_support::shared_datasets_dir(); // $SHAPESPACE_DATA
    for (name, path) in [
        ("libigl/face.obj", shared.join("libigl_tutorial_data/face.obj")),
        (
            "libigl/camelhead.off",
            shared.join("libigl_tutorial_data/camelhead.off"),
        ),
        ("faces/id00_neutral.obj", data.join("faces/id00_neutral.obj")),
    ] {
        match shapespace_geometry::io::read_mesh(&path) {
            Ok(m) => cases.push((name.into(), m)),
            Err(e) => eprintln!("SKIPPED: {name}: {e}"),
        }
    }
    println!(
        "| mesh | V | F | intrinsic flips | solves | setup s | delaunay s | green s | conjugate s | finish s | total s |"
    );
    println!("|---|---|---|---|---|---|---|---|---|---|---|");
    for (name, mesh) in &cases {
        let mut best: Option<shapespace_conformal::DiskMap> = None;
        for _ in 0..3 {
            match disk_map(mesh, &Markers::default(), &DiskMapParams::default()) {
                Ok(dm) => {
                    if best
                        .as_ref()
                        .is_none_or(|b| dm.info.timings.total < b.info.timings.total)
                    {
                        best = Some(dm);
                    }
                }
                Err(e) => {
                    println!(
                        "| {name} | {} | {} | error: {e} |",
                        mesh.num_vertices(),
                        mesh.num_faces()
                    );
                    break;
                }
            }
        }
        if let Some(dm) = best {
            let t = &dm.info.timings;
            println!(
                "| {name} | {} | {} | {} | {} | {:.3} | {:.3} | {:.3} | {:.3} | {:.3} | {:.3} |",
                mesh.num_vertices(),
                mesh.num_faces(),
                dm.info.intrinsic_flips,
                dm.info.linear_solves,
                t.setup,
                t.delaunay,
                t.green,
                t.conjugate,
                t.finish,
                t.total
            );
        }
    }
}
