//! The spherical conformal Wasserstein distance per pair, as a table.
//!
//! `cargo bench -p shapespace-tools --bench sphere_distance_bench [-- FILTER]`: for each mesh,
//! the pair M → M′ where M′ is M with its conformal image turned by a fixed rotation (2.1 rad),
//! so that the minimum over rotations is the self-cost c(M, M) at the identity. Columns: one
//! fixed-alignment solve M → M (the reference of the same run), the pair with the search over
//! SO(3) (proxy grid, scoring solves, full solve and refinement), the ratio of the two, the
//! search's share (proxy and scoring), the solves, and how far the costs of the two are apart.
//! Meshes: a bumpy sphere and an ellipsoid 1:1:2 (2,562 vertices), libigl's decimated Max
//! Planck bust, TOSCA wolf0 (minutes per solve), those of `../shared/datasets` that are present
//! and whose name contains FILTER.

use shapespace_analysis::rotation::{apply, axis_angle};
use shapespace_analysis::sphere_distance::{
    directed_sphere_distance, prepare_sphere_shape, PreparedSphere, SphereAlignment,
};
use shapespace_conformal::SphereMapParams;
use shapespace_geometry::TriMesh;
use shapespace_omt::sphere::{icosphere, SphereOtParams};

fn turned(shape: &PreparedSphere) -> PreparedSphere {
    let r = axis_angle([0.36, 0.48, 0.8], 2.1);
    let turn = |v: &Vec<[f64; 3]>| v.iter().map(|&p| apply(&r, p)).collect::<Vec<_>>();
    let mut out = shape.clone();
    out.map.positions = turn(&shape.map.positions);
    out.measure.vertices = turn(&shape.measure.vertices);
    out.points = turn(&shape.points);
    out.proxy_points = turn(&shape.proxy_points);
    out
}

fn main() {
    shapespace_tools::at_repository_root();
    let filter = std::env::args().skip(1).find(|a| !a.starts_with('-'));
    let (v, f) = icosphere(4);
    let bumpy = TriMesh::new(
        v.iter()
            .map(|p| {
                let r =
                    1.0 + 0.25 * (3.0 * p[0]).sin() * p[1] + 0.3 * p[2] * p[2] * p[0] + 0.2 * (2.0 * p[1] + p[2]).cos();
                p.map(|x| r * x)
            })
            .collect(),
        f.clone(),
    )
    .expect("valid mesh");
    let ellipsoid = TriMesh::new(v.iter().map(|p| [p[0], p[1], 2.0 * p[2]]).collect(), f).expect("valid mesh");
    let mut meshes: Vec<(String, TriMesh)> =
        vec![("bumpy sphere".into(), bumpy), ("ellipsoid 1:1:2".into(), ellipsoid)];
    for rel in ["libigl_tutorial_data/decimated-max.obj", "tosca/wolf0.off"] {
        if let Some(path) = shapespace_test_support::shared_file(rel) {
            match shapespace_geometry::io::read_mesh(&path) {
                Ok(m) => meshes.push((rel.to_string(), m)),
                Err(e) => eprintln!("{rel}: {e}"),
            }
        }
    }
    if let Some(f) = &filter {
        meshes.retain(|(name, _)| name.contains(f.as_str()));
    }
    let params = SphereOtParams {
        tolerance: 1e-4,
        ..SphereOtParams::default()
    };
    println!("| mesh | V | fixed solve s (reference) | rotation pair s | ratio | proxy + scoring s (share) | solves | refinement steps | relative cost difference |");
    println!("|---|---|---|---|---|---|---|---|---|");
    for (name, mesh) in meshes {
        let shape = match prepare_sphere_shape(&name, &mesh, &SphereMapParams::default()) {
            Ok(s) => s,
            Err(e) => {
                println!("| {name} | {} | failed: {e} | | | | | | |", mesh.num_vertices());
                continue;
            }
        };
        let other = turned(&shape);
        let fixed = directed_sphere_distance(&shape, &shape, SphereAlignment::Fixed, &params);
        let search = directed_sphere_distance(&shape, &other, SphereAlignment::Rotation, &params);
        match (fixed, search) {
            (Ok(a), Ok(b)) => {
                let searched = b.seconds_proxy + b.seconds_scoring;
                println!(
                    "| {name} | {} | {:.2} | {:.2} | {:.1} | {:.2} ({:.0} %) | {} | {} | {:.1e} |",
                    mesh.num_vertices(),
                    a.seconds,
                    b.seconds,
                    b.seconds / a.seconds,
                    searched,
                    100.0 * searched / b.seconds,
                    b.solves,
                    b.refinement_steps,
                    (b.cost - a.cost) / a.cost
                );
            }
            (a, b) => println!(
                "| {name} | {} | {} | {} | | | | | |",
                mesh.num_vertices(),
                a.map_or_else(|e| format!("failed: {e}"), |d| format!("{:.2}", d.seconds)),
                b.map_or_else(|e| format!("failed: {e}"), |d| format!("{:.2}", d.seconds))
            ),
        }
    }
}
