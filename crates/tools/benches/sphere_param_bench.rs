//! The area-preserving sphere map on the closed meshes of the shared datasets, as a table.
//!
//! `cargo bench -p shapespace-tools --bench sphere_param_bench [-- FILTER]`: the meshes of the
//! TOSCA, lion, GOAST cactus and finger, Sumner cat, libigl and common-3d-test-models folders
//! under `../shared/datasets` (those whose path contains FILTER, when given), and
//! an ellipsoid of revolution (semi-axes 1, 1, 2; 40,962 vertices) as the synthetic reference.
//! Columns: the stages' wall-clock seconds, the whole map's CPU seconds (all threads; steadier
//! than the wall time on a shared machine), Newton steps, faces folded by the centroid map and
//! after the fold repair (exact test on S²), the vertices the repair moved, and the 95th
//! percentile of |ε| (the log one-ring area ratio, both normalized) of the conformal and the
//! area-preserving map, with the angle distortion of both. A failure is a row with its error;
//! meshes that are not closed genus-0 surfaces are listed below the table.

use shapespace_analysis::distortion::sphere_distortion_report;
use shapespace_analysis::sphere_param::{area_preserving_sphere_map, SphereParamParams};
use shapespace_geometry::TriMesh;

fn main() {
    shapespace_tools::at_repository_root();
    let filter = std::env::args().skip(1).find(|a| !a.starts_with('-'));
    let ico = shapespace_geometry::primitives::icosphere(6);
    let ellipsoid = TriMesh::new(
        ico.positions.iter().map(|p| [p[0], p[1], 2.0 * p[2]]).collect(),
        ico.faces.clone(),
    )
    .expect("the ellipsoid is a valid mesh");
    let mut meshes: Vec<(String, TriMesh)> = vec![("ellipsoid 1:1:2".into(), ellipsoid)];
    for dir in [
        "tosca",
        "outside/lion_poses",
        "goast/cactus",
        "goast/finger",
        "common_3d_test_models",
        "libigl_tutorial_data",
        "sumner_deformation_transfer/cat-poses",
    ] {
        let Some(root) = shapespace_test_support::shared_dir(dir) else {
            eprintln!("{dir}: not found beside the repository; skipped");
            continue;
        };
        let mut files: Vec<_> = std::fs::read_dir(&root)
            .map(|d| d.filter_map(|e| e.ok()).map(|e| e.path()).collect())
            .unwrap_or_default();
        files.retain(|p| matches!(p.extension().and_then(|e| e.to_str()), Some("off" | "obj" | "ply")));
        files.sort();
        for p in files {
            let name = format!("{dir}/{}", p.file_name().unwrap_or_default().to_string_lossy());
            match shapespace_geometry::io::read_mesh(&p) {
                Ok(m) => meshes.push((name, m)),
                Err(e) => eprintln!("{name}: {e}"),
            }
        }
    }
    if let Some(f) = &filter {
        meshes.retain(|(name, _)| name.contains(f.as_str()));
    }
    println!(
        "| mesh | V | conformal s | OT s | output s | CPU s | Newton steps | folded before / after repair | vertices moved | p95 abs. ε conformal → area-preserving | angle distortion p95 (°) conformal → area-preserving |"
    );
    println!("|---|---|---|---|---|---|---|---|---|---|---|");
    let mut skipped = Vec::new();
    for (name, mesh) in &meshes {
        match shapespace_geometry::topology::classify(mesh) {
            Ok(c) if c.class == shapespace_geometry::topology::MeshClass::Sphere => {}
            Ok(c) => {
                skipped.push(format!("{name} ({}: {})", c.class, c.reasons.join("; ")));
                continue;
            }
            Err(e) => {
                skipped.push(format!("{name} ({e})"));
                continue;
            }
        }
        let cpu = shapespace_tools::cpu_seconds();
        let result = area_preserving_sphere_map(mesh, &SphereParamParams::default());
        let cpu = shapespace_tools::cpu_seconds() - cpu;
        match result {
            Ok(map) => {
                let report = match sphere_distortion_report(mesh, &map.conformal.positions, &map.positions) {
                    Ok(r) => r,
                    Err(e) => {
                        println!("| {name} | {} | distortion: {e} |", mesh.num_vertices());
                        continue;
                    }
                };
                let (c, a) = (&report.maps[0], &report.maps[1]);
                println!(
                    "| {name} | {} | {:.2} | {:.2} | {:.2} | {cpu:.2} | {} | {} / {} | {} | {:.3} → {:.3} | {:.2} → {:.2} |",
                    mesh.num_vertices(),
                    map.timings.conformal,
                    map.timings.ot,
                    map.timings.output,
                    map.iterations,
                    map.flipped_before_repair,
                    map.num_flipped,
                    map.fold_repair.as_ref().map_or(0, |r| r.vertices_moved),
                    c.abs_vertex_log_area_ratio.p95,
                    a.abs_vertex_log_area_ratio.p95,
                    c.angle_distortion_deg.p95,
                    a.angle_distortion_deg.p95,
                );
            }
            Err(e) => {
                let mut chain = e.to_string();
                let mut source = std::error::Error::source(&e);
                while let Some(s) = source {
                    chain = format!("{chain}: {s}");
                    source = s.source();
                }
                println!("| {name} | {} | error: {chain} |", mesh.num_vertices());
            }
        }
    }
    for s in skipped {
        println!("not a closed genus-0 surface, skipped: {s}");
    }
}
