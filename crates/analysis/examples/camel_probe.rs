//! Probe: the Newton log (per step: error, τ, rejections by cause, timings) of the area-preserving
//! OT on camelhead subdivided 1-to-4 (45k sites, Voronoi start), run twice; `NOSUB=1` for the
//! original mesh, or a disk mesh given as the argument.
//! `cargo run --release -p shapespace-analysis --example camel_probe [-- MESH]`.
#[path = "common/newton_log.rs"]
mod newton_log;
use shapespace_analysis::area_preserving::{domain_measure, domain_polygon, weighted_target_masses, Domain};
use shapespace_conformal::{disk_map, DiskMapParams, Markers};
use shapespace_geometry::prepare::subdivide_midpoint;

fn main() {
    let root = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("../..");
    let mesh = match std::env::args().nth(1) {
        // any disk mesh (e.g. a TOSCA mesh or Nefertiti cut open by `shapespace prepare`)
        Some(path) => shapespace_geometry::io::read_mesh(std::path::Path::new(&path)).unwrap(),
        None => {
            let m = shapespace_geometry::io::read_mesh(&root.join("datasets/disks/camelhead.off")).unwrap();
            if std::env::var("NOSUB").is_ok() {
                m
            } else {
                subdivide_midpoint(&m).unwrap()
            }
        }
    };
    let c = disk_map(&mesh, &Markers::default(), &DiskMapParams::default()).unwrap();
    let s2 = c.scale * c.scale;
    let thirds: Vec<f64> = shapespace_geometry::quantities::vertex_dual_areas(&mesh)
        .iter()
        .map(|a| a * s2)
        .collect();
    let nu = weighted_target_masses(&thirds, None).unwrap();
    let nb = shapespace_geometry::Connectivity::of(&mesh)
        .boundary_vertices(mesh.num_vertices())
        .iter()
        .filter(|&&b| b)
        .count();
    let poly = domain_polygon(Domain::Disk, (8 * nb).max(1024)).unwrap();
    let measure = domain_measure(Domain::Disk, &poly).unwrap();
    for _ in 0..2 {
        let sol = shapespace_omt::solve_ot(&measure, &c.uv, &nu, &Default::default()).unwrap();
        newton_log::print_newton_log(&sol);
        println!(
            "it {} evals {} start {:?} t_start {:.3} total {:.3} stop {}",
            sol.iterations, sol.evaluations, sol.start, sol.t_start, sol.t_total, sol.stop
        );
    }
}
