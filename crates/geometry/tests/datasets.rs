//! The bundled datasets against their independently computed statistics.
//!
//! `datasets/stats.json` (made by `scripts/make_stats.py` in Python/NumPy, not by this crate)
//! maps each mesh path, relative to `datasets/`, to `{V, F, E, components, boundary_loops, euler,
//! manifold, oriented, class}`. Every listed file must be readable and its Rust [`MeshReport`]
//! must agree exactly; every mesh file under `datasets/` must be listed. On every mesh the
//! discrete Gauss–Bonnet theorem Σ Θ_i = 2πχ is checked too.

use std::collections::BTreeMap;
use std::path::{Path, PathBuf};

use rayon::prelude::*;
use serde::Deserialize;
use shapespace_geometry::curvature::vertex_angle_defects;
use shapespace_geometry::io::read_mesh;
use shapespace_geometry::topology::{mesh_report, require_disk, MeshClass};

#[derive(Debug, Deserialize)]
#[serde(rename_all = "lowercase")]
enum ExpectedClass {
    Disk,
    Sphere,
    Other,
}

#[derive(Debug, Deserialize)]
#[allow(non_snake_case)]
struct Expected {
    V: usize,
    F: usize,
    E: Option<usize>,
    boundary_loops: usize,
    euler: i64,
    components: usize,
    class: ExpectedClass,
    manifold: Option<bool>,
    oriented: Option<bool>,
}

fn datasets_dir() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("../../datasets")
}

fn mesh_files(dir: &Path, root: &Path, out: &mut Vec<String>) {
    let Ok(entries) = std::fs::read_dir(dir) else { return };
    for entry in entries.flatten() {
        let path = entry.path();
        if path.is_dir() {
            mesh_files(&path, root, out);
        } else if let Some(ext) = path.extension().and_then(|e| e.to_str()) {
            if ["obj", "off", "ply"].contains(&ext.to_ascii_lowercase().as_str()) {
                let rel = path.strip_prefix(root).unwrap().to_string_lossy().replace('\\', "/");
                out.push(rel);
            }
        }
    }
}

#[test]
fn datasets_agree_with_stats_json() {
    let dir = datasets_dir();
    let stats_path = dir.join("stats.json");
    let text = std::fs::read_to_string(&stats_path)
        .unwrap_or_else(|e| panic!("{}: {e} (the bundled datasets are missing)", stats_path.display()));
    let stats: BTreeMap<String, Expected> =
        serde_json::from_str(&text).unwrap_or_else(|e| panic!("{}: {e}", stats_path.display()));
    assert!(!stats.is_empty(), "stats.json lists no mesh");

    // every mesh file on disk is listed
    let mut on_disk = Vec::new();
    mesh_files(&dir, &dir, &mut on_disk);
    on_disk.sort();
    let unlisted: Vec<&String> = on_disk.iter().filter(|f| !stats.contains_key(*f)).collect();
    assert!(unlisted.is_empty(), "mesh files not in stats.json: {unlisted:?}");

    let problems: Vec<String> = stats
        .par_iter()
        .flat_map_iter(|(file, want)| {
            let mut p = Vec::new();
            let mesh = match read_mesh(&dir.join(file)) {
                Ok(m) => m,
                Err(e) => return vec![format!("{file}: cannot be read: {e}")],
            };
            let r = match mesh_report(&mesh) {
                Ok(r) => r,
                Err(e) => return vec![format!("{file}: invalid mesh: {e}")],
            };
            let mut check = |what: &str, got: String, expected: String| {
                if got != expected {
                    p.push(format!("{file}: {what} = {got}, stats.json says {expected}"));
                }
            };
            check("V", r.num_vertices.to_string(), want.V.to_string());
            check("F", r.num_faces.to_string(), want.F.to_string());
            if let Some(e) = want.E {
                check("E", r.num_edges.to_string(), e.to_string());
            }
            check("components", r.num_components.to_string(), want.components.to_string());
            check(
                "boundary loops",
                r.num_boundary_loops.to_string(),
                want.boundary_loops.to_string(),
            );
            check("χ", r.euler_characteristic.to_string(), want.euler.to_string());
            if let Some(m) = want.manifold {
                check("manifold", r.manifold.to_string(), m.to_string());
            }
            if let Some(o) = want.oriented {
                check("oriented", r.consistently_oriented.to_string(), o.to_string());
            }
            let class = match want.class {
                ExpectedClass::Disk => MeshClass::Disk,
                ExpectedClass::Sphere => MeshClass::Sphere,
                ExpectedClass::Other => MeshClass::Other,
            };
            check("class", format!("{:?}", r.classification.class), format!("{class:?}"));
            if class == MeshClass::Disk {
                if let Err(e) = require_disk(&mesh) {
                    p.push(format!("{file}: require_disk fails: {e}"));
                }
            }
            // discrete Gauss–Bonnet on real data
            let total: f64 = vertex_angle_defects(&mesh).iter().sum();
            let expected = 2.0 * std::f64::consts::PI * r.euler_characteristic as f64;
            if (total - expected).abs() > 1e-8 * r.num_faces as f64 {
                p.push(format!("{file}: Σ angle defects = {total}, 2πχ = {expected}"));
            }
            p
        })
        .collect();
    assert!(
        problems.is_empty(),
        "{} problems:\n{}",
        problems.len(),
        problems.join("\n")
    );
}
