//! Probe: TOSCA meshes cut open as `shapespace prepare` does, then along a seam through `K`
//! extremities (`geometry::seam`), against the small-disk cut alone: crowding of the conformal
//! image (points within 1e-9 / 1e-12 mean spacings of another) and the area-preserving map.
//! `cargo run --release -p shapespace-tools --bin seam_probe -- K dog0 victoria0 ...`
use shapespace_tools::crowding;

use std::time::Instant;

use shapespace_analysis::area_preserving::{area_preserving_map, transport_problem, AreaPreservingParams};
use shapespace_analysis::distortion::map_distortion;
use shapespace_conformal::Markers;
use shapespace_geometry::prepare::{prepare_disk, PrepareOptions};
use shapespace_geometry::seam::{cut_along_seam, extremities, seam_tree};

fn crowding(mesh: &shapespace_geometry::TriMesh) -> String {
    crowding_with(mesh, &Markers::default())
}

fn crowding_with(mesh: &shapespace_geometry::TriMesh, markers: &Markers) -> String {
    match transport_problem(mesh, markers, &AreaPreservingParams::default()) {
        Ok(problem) => {
            let y = &problem.conformal.uv;
            let n = y.len();
            let spacing = (std::f64::consts::PI / n as f64).sqrt();
            let nn: Vec<f64> = crowding::nearest_neighbour_distances(y)
                .0
                .iter()
                .map(|d| d / spacing)
                .collect();
            let below = |t: f64| nn.iter().filter(|&&d| d < t).count();
            format!(
                "min nn/spacing {:.1e}, < 1e-3: {}, < 1e-6: {}, < 1e-9: {}, < 1e-12: {}",
                nn.iter().cloned().fold(f64::INFINITY, f64::min),
                below(1e-3),
                below(1e-6),
                below(1e-9),
                below(1e-12)
            )
        }
        Err(e) => format!(
            "conformal failed: {e}: {}",
            std::error::Error::source(&e).map(|s| s.to_string()).unwrap_or_default()
        ),
    }
}

fn run(label: &str, mesh: &shapespace_geometry::TriMesh) {
    println!(
        "  {label}: V {} F {}; {}",
        mesh.num_vertices(),
        mesh.num_faces(),
        crowding(mesh)
    );
    let t = Instant::now();
    match area_preserving_map(mesh, &Markers::default(), &AreaPreservingParams::default()) {
        Ok(map) => {
            let d = map_distortion("ap", mesh, &map.uv).expect("distortion");
            println!(
                "    map: total {:.2} s (conformal {:.2}, OT {:.2}), {} steps, error {:.1e}, median |Υ| {:.3}, flips {}",
                map.timings.total,
                map.timings.conformal,
                map.timings.ot,
                map.ot.iterations,
                map.ot.max_relative_error,
                d.abs_area_distortion.median,
                d.num_flipped
            );
        }
        Err(e) => println!("    map failed after {:.1} s: {e}", t.elapsed().as_secs_f64()),
    }
}

fn main() {
    let mut args = std::env::args().skip(1);
    let k: usize = args.next().expect("K").parse().expect("K: a count");
    let tosca = shapespace_test_support::shared_datasets_dir().join("tosca"); // $SHAPESPACE_DATA
    let baseline = std::env::var("BASELINE").is_ok();
    for name in args {
        let mesh = shapespace_geometry::io::read_mesh(&tosca.join(format!("{name}.off"))).unwrap();
        let (disk, _, _) = prepare_disk(&mesh, &PrepareOptions::default()).unwrap();
        println!("{name}:");
        if baseline {
            run("disk cut", &disk);
        }
        if std::env::var("BALANCE").is_ok() {
            let mut markers = Markers::default();
            for round in 0..5 {
                let problem = match transport_problem(&disk, &markers, &AreaPreservingParams::default()) {
                    Ok(p) => p,
                    Err(e) => {
                        println!("  round {round}: {e}");
                        break;
                    }
                };
                let (y, nu) = (&problem.conformal.uv, &problem.target_masses);
                let total: f64 = nu.iter().sum();
                let m = y
                    .iter()
                    .zip(nu)
                    .fold([0.0; 2], |m, (p, w)| [m[0] + w * p[0] / total, m[1] + w * p[1] / total]);
                let next = (0..y.len())
                    .filter(|&i| !problem.is_boundary[i])
                    .min_by(|&a, &b| {
                        let da = (y[a][0] - m[0]).hypot(y[a][1] - m[1]);
                        let db = (y[b][0] - m[0]).hypot(y[b][1] - m[1]);
                        da.total_cmp(&db)
                    })
                    .unwrap();
                println!(
                    "  round {round}: center {:?}, mean of the image |m| = {:.3e}; {}",
                    markers.center,
                    m[0].hypot(m[1]),
                    crowding_with(&disk, &markers)
                );
                markers.center = shapespace_conformal::CenterMarker::Vertex(next as u32);
            }
            continue;
        }
        let t = Instant::now();
        let terminals = extremities(&disk, k).unwrap();
        let seam = seam_tree(&disk, &terminals).unwrap();
        match cut_along_seam(&disk, &seam) {
            Ok((cut, _)) => {
                println!(
                    "  seam: {} terminals, {} edges, {:.2} s",
                    terminals.len(),
                    seam.len(),
                    t.elapsed().as_secs_f64()
                );
                let conn = shapespace_geometry::Connectivity::of(&cut);
                let on = conn.boundary_vertices(cut.num_vertices());
                let ears = cut.faces.iter().filter(|f| f.iter().all(|&v| on[v as usize])).count();
                let bridges = shapespace_geometry::prepare::boundary_bridges(&cut);
                println!("  ears {ears}, bridges {}", bridges.len());
                if let Ok(f) = std::env::var("FACE") {
                    let f: usize = f.parse().unwrap();
                    let mut degree = vec![0; disk.num_vertices()];
                    for e in &seam {
                        degree[e[0] as usize] += 1;
                        degree[e[1] as usize] += 1;
                    }
                    let dconn = shapespace_geometry::Connectivity::of(&disk);
                    for &v in &disk.faces[f] {
                        let d = shapespace_geometry::paths::edge_path_distances(&disk, &dconn, v);
                        let near = |pred: &dyn Fn(usize) -> bool| {
                            (0..disk.num_vertices())
                                .filter(|&w| pred(w))
                                .map(|w| d[w])
                                .fold(f64::INFINITY, f64::min)
                        };
                        println!(
                            "    face {f} vertex {v}: seam degree {}, distance to a terminal {:.3}, to a junction {:.3}, to the seam {:.3}, to the boundary {:.3}",
                            degree[v as usize],
                            near(&|w| terminals.contains(&(w as u32))),
                            near(&|w| degree[w] >= 3),
                            near(&|w| degree[w] >= 1),
                            near(&|w| on[w] && degree[w] == 0)
                        );
                    }
                }
                run("disk cut + seam", &cut);
                if std::env::var("BFF").is_ok() {
                    println!("  {}", bff_check(&cut).chars().take(600).collect::<String>());
                }
                let split = shapespace_geometry::prepare::split_edges(&cut, &bridges).unwrap();
                run("disk cut + seam, bridges split", &split);
            }
            Err(e) => println!("  seam cut failed: {e}"),
        }
    }
}

/// BFF on the cut mesh: folded faces or the error.
#[allow(dead_code)]
pub fn bff_check(mesh: &shapespace_geometry::TriMesh) -> String {
    use shapespace_analysis::area_preserving::{domain_measure, domain_polygon, Domain};
    match shapespace_conformal::bff::bff_disk_map(mesh, &Markers::default(), &Default::default()) {
        Ok(m) => {
            let s2 = m.scale * m.scale;
            let masses: Vec<f64> = shapespace_geometry::quantities::vertex_dual_areas(mesh)
                .iter()
                .map(|a| a * s2)
                .collect();
            let polygon = domain_polygon(Domain::Disk, 4096).unwrap();
            let measure = domain_measure(Domain::Disk, &polygon).unwrap();
            let t = Instant::now();
            let sol = shapespace_omt::solve_ot(&measure, &m.uv, &masses, &Default::default());
            match sol {
                Ok(sol) => format!(
                    "bff ok ({} its); OT {} steps, error {:.1e}, {:.2} s, stop {:?}",
                    m.info.iterations,
                    sol.iterations,
                    sol.max_relative_error,
                    t.elapsed().as_secs_f64(),
                    sol.stop
                ),
                Err(e) => format!("bff ok; OT failed: {e}"),
            }
        }
        Err(e) => format!("bff failed: {e}"),
    }
}
