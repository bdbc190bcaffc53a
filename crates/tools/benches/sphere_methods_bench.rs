//! The sphere's OMT map, its Lie-advection and gradient-flow maps and spherical MDS side by
//! side, on the same closed meshes in one run.
//!
//! `cargo bench -p shapespace-tools --bench sphere_methods_bench [-- FILTER]`: ellipsoids of
//! revolution 1:1:1.5 and 1:1:2 (10,242 vertices) and TOSCA wolf0, centaur0 and horse0 from
//! `../shared/datasets` (skipped with a message when absent); those whose name contains FILTER
//! when given. Rows: `omt` ([`area_preserving_sphere_map`], defaults), `lie` ([`sphere_lie_map`],
//! defaults), `flow` ([`sphere_gradient_flow_map`] from the Lie map, `multiresolution_levels`
//! 0), `flow-mr` (the same with Dominitz & Tannenbaum's multiresolution scheme: the defaults,
//! two coarse icosphere levels), `spherical-mds`
//! ([`spherical_mds_map`], defaults: θ_max 180°, 500 landmarks, classical start) and
//! `spherical-mds 270°` (θ_max 270°). Columns: wall-clock seconds, iterations (Newton steps;
//! mean Bogacki–Shampine steps per vertex, rounded; flow steps; SMACOF iterations on the
//! landmarks), |ε| (the log one-ring area ratio, both normalized)
//! median / p95, the angle distortion median / p95 (degrees), faces folded on S² before and
//! after the chart repair (exact test; `flow-mr`: those of the prolonged coarse map on the
//! mesh). Env `METHODS` (comma separated) keeps only those rows.

use std::time::Instant;

use shapespace_analysis::distortion::sphere_map_distortion;
use shapespace_analysis::sphere_flows::{sphere_gradient_flow_map, sphere_lie_map, SphereFlowParams, SphereLieParams};
use shapespace_analysis::sphere_param::{area_preserving_sphere_map, SphereParamParams};
use shapespace_analysis::spherical_mds::{spherical_mds_map, SphericalMdsParams};
use shapespace_geometry::TriMesh;

fn row(
    name: &str,
    mesh: &TriMesh,
    method: &str,
    seconds: f64,
    iterations: usize,
    x: &[[f64; 3]],
    folds: (usize, usize),
) {
    match sphere_map_distortion(method, mesh, x) {
        Ok(d) => println!(
            "| {name} | {} | {method} | {seconds:.2} | {iterations} | {:.3} / {:.3} | {:.1} / {:.1} | {} / {} |",
            mesh.num_vertices(),
            d.abs_vertex_log_area_ratio.median,
            d.abs_vertex_log_area_ratio.p95,
            d.angle_distortion_deg.median,
            d.angle_distortion_deg.p95,
            folds.0,
            folds.1
        ),
        Err(e) => println!("| {name} | {} | {method} | distortion: {e} |", mesh.num_vertices()),
    }
}

fn main() {
    shapespace_tools::at_repository_root();
    let filter = std::env::args().skip(1).find(|a| !a.starts_with('-'));
    let methods: Option<Vec<String>> = std::env::var("METHODS")
        .ok()
        .map(|m| m.split(',').map(|x| x.trim().to_string()).collect());
    let ico = shapespace_geometry::primitives::icosphere(5);
    let ellipsoid = |c: f64| {
        TriMesh::new(
            ico.positions.iter().map(|p| [p[0], p[1], c * p[2]]).collect(),
            ico.faces.clone(),
        )
        .expect("the ellipsoid is a valid mesh")
    };
    let mut meshes: Vec<(String, TriMesh)> = vec![
        ("ellipsoid 1:1:1.5".into(), ellipsoid(1.5)),
        ("ellipsoid 1:1:2".into(), ellipsoid(2.0)),
    ];
    for pose in ["wolf0", "centaur0", "horse0"] {
        let rel = format!("tosca/{pose}.off");
        match shapespace_test_support::shared_file(&rel) {
            Some(p) => match shapespace_geometry::io::read_mesh(&p) {
                Ok(m) => meshes.push((format!("TOSCA {pose}"), m)),
                Err(e) => eprintln!("{rel}: {e}"),
            },
            None => eprintln!("{rel}: not found beside the repository; skipped"),
        }
    }
    if let Some(f) = &filter {
        meshes.retain(|(name, _)| name.contains(f.as_str()));
    }
    println!("| mesh | V | method | wall s | iterations | abs. ε median / p95 | angle ° median / p95 | folded before / after repair |");
    println!("|---|---:|---|---:|---:|---|---|---|");
    for (name, mesh) in &meshes {
        let wanted = |m: &str| methods.as_ref().is_none_or(|w| w.iter().any(|x| x == m));
        if wanted("omt") {
            let t = Instant::now();
            match area_preserving_sphere_map(mesh, &SphereParamParams::default()) {
                Ok(map) => row(
                    name,
                    mesh,
                    "omt",
                    t.elapsed().as_secs_f64(),
                    map.iterations,
                    &map.positions,
                    (map.flipped_before_repair, map.num_flipped),
                ),
                Err(e) => println!("| {name} | {} | omt | error: {e} |", mesh.num_vertices()),
            }
        }
        if wanted("lie") {
            let t = Instant::now();
            match sphere_lie_map(mesh, &SphereLieParams::default()) {
                Ok(map) => row(
                    name,
                    mesh,
                    "lie",
                    t.elapsed().as_secs_f64(),
                    map.info.mean_steps.round() as usize,
                    &map.positions,
                    (map.info.flipped_before_repair, map.info.num_flipped),
                ),
                Err(e) => println!("| {name} | {} | lie | error: {e} |", mesh.num_vertices()),
            }
        }
        for (method, levels) in [("flow", 0usize), ("flow-mr", 2)] {
            if !wanted(method) {
                continue;
            }
            let params = SphereFlowParams {
                multiresolution_levels: levels,
                ..Default::default()
            };
            let t = Instant::now();
            match sphere_gradient_flow_map(mesh, &params) {
                Ok(map) => {
                    let m = &map.info.multiresolution;
                    let folds = if levels == 0 || m.fallback.is_some() {
                        map.info.start.flipped_before_repair
                    } else {
                        m.prolonged_folds
                    };
                    if !m.levels.is_empty() {
                        eprintln!(
                            "{name} {method}: levels (vertices, steps) {:?}, prolonged folds {} -> {}, fallback {:?}",
                            m.levels.iter().map(|l| (l.vertices, l.flow.steps)).collect::<Vec<_>>(),
                            m.prolonged_folds,
                            m.prolonged_folds_after_repair,
                            m.fallback
                        );
                    }
                    row(
                        name,
                        mesh,
                        method,
                        t.elapsed().as_secs_f64(),
                        map.info.flow.steps,
                        &map.positions,
                        (folds, map.info.num_flipped),
                    )
                }
                Err(e) => println!("| {name} | {} | {method} | error: {e} |", mesh.num_vertices()),
            }
        }
        for (method, degrees) in [("spherical-mds", 180.0f64), ("spherical-mds 270°", 270.0)] {
            if !wanted(method) {
                continue;
            }
            let params = SphericalMdsParams {
                max_angle: degrees.to_radians(),
                ..Default::default()
            };
            let t = Instant::now();
            match spherical_mds_map(mesh, &params) {
                Ok(map) => row(
                    name,
                    mesh,
                    method,
                    t.elapsed().as_secs_f64(),
                    map.info.landmark_smacof.iterations,
                    &map.positions,
                    (map.info.flipped_before_repair, map.info.num_flipped),
                ),
                Err(e) => println!("| {name} | {} | {method} | error: {e} |", mesh.num_vertices()),
            }
        }
    }
}
