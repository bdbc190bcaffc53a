//! Quick probe: hemisphere vs flat disk closed form, and two faces (timings).
use shapespace_analysis::distance::*;
use shapespace_conformal::{BoundaryMarker, CenterMarker, DiskMapParams, Markers};
use shapespace_geometry::primitives::{spherical_cap, unit_disk};
use shapespace_omt::NewtonParams;

fn main() {
    for rings in [20] {
        let cap = spherical_cap(std::f64::consts::FRAC_PI_2, rings);
        let disk = unit_disk(rings);
        let nb = cap.num_vertices() as u32 - 1; // a boundary vertex (last ring)
        let m = Markers { center: CenterMarker::Vertex(0), boundary: BoundaryMarker::Vertex(nb) };
        let t = std::time::Instant::now();
        let a = prepare_shape("cap", &cap, &m, &DiskMapParams::default()).unwrap();
        let b = prepare_shape("disk", &disk, &m, &DiskMapParams::default()).unwrap();
        let tp = t.elapsed().as_secs_f64();
        let (d, _) = directed_distance(&a, &b, &NewtonParams::default()).unwrap();
        let (d2, _) = directed_distance(&b, &a, &NewtonParams::default()).unwrap();
        let (s, _) = directed_distance(&a, &a, &NewtonParams::default()).unwrap();
        println!("rings {rings} V {} prep {tp:.3}s cap->disk cost {:.7} (rel err {:.2e}) it {} {:.3}s | disk->cap {:.7} it {} | self {:.2e}", cap.num_vertices(), d.cost, (d.cost-0.0329512)/0.0329512, d.iterations, d.seconds, d2.cost, d2.iterations, s.cost);
    }
    let dir = std::path::Path::new("datasets/faces");
    if dir.exists() {
        let m = Markers { center: CenterMarker::Vertex(4841), boundary: BoundaryMarker::Vertex(8889) };
        let names = ["id00_neutral", "id00_happy", "id01_neutral"];
        let shapes: Vec<_> = names.iter().map(|n| {
            let mesh = shapespace_geometry::io::read_mesh(&dir.join(format!("{n}.obj"))).unwrap();
            let t = std::time::Instant::now();
            let s = prepare_shape(n, &mesh, &m, &DiskMapParams::default()).unwrap();
            println!("prepare {n}: {:.3}s", t.elapsed().as_secs_f64());
            s
        }).collect();
        log_pair(&shapes[0], &shapes[1]);
        for (i, j) in [(0, 1)] {
            let (d, _) = directed_distance(&shapes[i], &shapes[j], &NewtonParams::default()).unwrap();
            println!("{} -> {}: d {:.5} it {} err {:.1e} {:.3}s {}", names[i], names[j], d.distance, d.iterations, d.max_mass_error, d.seconds, d.status);
        }
    }
}

#[allow(dead_code)]
pub fn log_pair(a: &PreparedShape, b: &PreparedShape) {
    let sol = shapespace_omt::solve_ot(&a.measure, &b.points, &b.masses, &NewtonParams::default()).unwrap();
    for (k, r) in sol.log.iter().enumerate() {
        println!("{k:3} err {:.2e} tau {:.3} halv {} minmass {:.2e} diag {:.3} integ {:.3} solve {:.3}", r.max_relative_error, r.step, r.halvings, r.min_cell_mass, r.t_diagram, r.t_integration, r.t_solve);
    }
    println!("start {:?} eps0 {:.2e} t_start {:.3} total {:.3}", sol.start, sol.epsilon0, sol.t_start, sol.t_total);
}
