//! Timing and angle distortion of the spherical conformal map, as a table.
//!
//! `cargo bench -p shapespace-tools --bench sphere_map_bench [-- --runs N]`: an
//! icosphere of 163,842 vertices with jittered vertices, the same as an ellipsoid of revolution
//! (semi-axes 1, 1, 2), and the closed TOSCA meshes of the shared datasets when present. Times
//! are the best of N runs (default 3) of `sphere_map` with default parameters (Möbius
//! centering); the pass columns are the stages of `SphereMapTimings`.

use std::time::Instant;

use shapespace_conformal::{sphere_map, SphereMapParams};
use shapespace_geometry::TriMesh;

fn jittered(mut mesh: TriMesh, subdivisions: usize, axes: [f64; 3]) -> TriMesh {
    let h = 1.1 / 2f64.powi(subdivisions as i32);
    let mut seed = 0x9e3779b97f4a7c15u64;
    let mut rnd = || {
        seed = seed.wrapping_mul(6364136223846793005).wrapping_add(1442695040888963407);
        ((seed >> 11) as f64 / (1u64 << 53) as f64) * 2.0 - 1.0
    };
    for p in &mut mesh.positions {
        let q = [
            p[0] + 0.25 * h * rnd(),
            p[1] + 0.25 * h * rnd(),
            p[2] + 0.25 * h * rnd(),
        ];
        let l = (q[0] * q[0] + q[1] * q[1] + q[2] * q[2]).sqrt();
        *p = [axes[0] * q[0] / l, axes[1] * q[1] / l, axes[2] * q[2] / l];
    }
    mesh
}

fn main() {
    shapespace_tools::at_repository_root();
    let args: Vec<String> = std::env::args().collect();
    let runs: usize = args
        .iter()
        .position(|a| a == "--runs")
        .and_then(|i| args.get(i + 1))
        .and_then(|s| s.parse().ok())
        .unwrap_or(3);
    let s = 7;
    let ico = shapespace_geometry::primitives::icosphere(s);
    let mut meshes: Vec<(String, TriMesh)> = vec![
        ("jittered icosphere".into(), jittered(ico.clone(), s, [1.0, 1.0, 1.0])),
        ("ellipsoid 1:1:2".into(), jittered(ico, s, [1.0, 1.0, 2.0])),
    ];
    for rel in ["tosca/horse0.off", "tosca/centaur0.off", "tosca/wolf0.off"] {
        if let Some(p) = shapespace_test_support::shared_file(rel) {
            match shapespace_geometry::io::read_mesh(&p) {
                Ok(m) => meshes.push((rel.into(), m)),
                Err(e) => eprintln!("{rel}: {e}"),
            }
        }
    }
    println!(
        "| mesh | V | F | total s | setup | pass 1 | Schwarz | normalize | finish | alternations | angle distortion mean / p95 (°) | Λ mean | flipped |"
    );
    println!("|---|---|---|---|---|---|---|---|---|---|---|---|---|");
    for (name, mesh) in &meshes {
        let mut best: Option<(f64, shapespace_conformal::SphereMap)> = None;
        for _ in 0..runs.max(1) {
            let t = Instant::now();
            match sphere_map(mesh, &SphereMapParams::default()) {
                Ok(m) => {
                    let secs = t.elapsed().as_secs_f64();
                    if best.as_ref().is_none_or(|(b, _)| secs < *b) {
                        best = Some((secs, m));
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
        if let Some((secs, m)) = best {
            let t = &m.info.timings;
            let q = &m.quality;
            println!(
                "| {name} | {} | {} | {secs:.3} | {:.3} | {:.3} | {:.3} | {:.3} | {:.3} | {} | {:.4} / {:.4} | {:.2e} | {} |",
                mesh.num_vertices(),
                mesh.num_faces(),
                t.setup,
                t.puncture_solve,
                t.cap_solve,
                t.normalize,
                t.finish,
                m.info.schwarz_iterations,
                q.angle_distortion_deg.mean,
                q.angle_distortion_deg.p95,
                q.quasi_conformal_distortion.mean,
                q.num_flipped
            );
        }
    }
}
