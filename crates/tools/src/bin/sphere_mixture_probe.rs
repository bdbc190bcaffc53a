//! `sphere_mixture_probe A B [s1,s2,…] [tolerance]`: the transport A → B at the maps' own
//! alignment started from B's own measure: μ_B → y_B (Voronoi start), then the sources
//! (1 − s) μ_B + s μ_A for the listed s (each warm-started), then μ_A.

use shapespace_analysis::sphere_distance::prepare_sphere_shape;
use shapespace_conformal::SphereMapParams;
use shapespace_omt::sphere::{solve_sphere_ot, SphereMeasure, SphereOtParams};

fn mixture(a: &SphereMeasure, b: &SphereMeasure, s: f64) -> SphereMeasure {
    let off = b.vertices.len() as u32;
    let mut vertices = b.vertices.clone();
    vertices.extend_from_slice(&a.vertices);
    let mut triangles = b.triangles.clone();
    triangles.extend(a.triangles.iter().map(|t| t.map(|i| i + off)));
    let mut densities: Vec<f64> = b.densities.iter().map(|d| d * (1.0 - s)).collect();
    densities.extend(a.densities.iter().map(|d| d * s));
    SphereMeasure {
        vertices,
        triangles,
        densities,
    }
}

fn main() {
    let args: Vec<String> = std::env::args().collect();
    if args.len() < 3 {
        eprintln!("usage: sphere_mixture_probe A B [s1,s2,…] [tolerance]");
        std::process::exit(2);
    }
    let prepare = |p: &str| {
        let mesh = shapespace_geometry::io::read_mesh(std::path::Path::new(p)).expect("mesh");
        prepare_sphere_shape(p, &mesh, &SphereMapParams::default()).expect("sphere map")
    };
    let (a, b) = (prepare(&args[1]), prepare(&args[2]));
    let stages: Vec<f64> = args
        .get(3)
        .map(|s| {
            s.split(',')
                .filter(|x| !x.is_empty())
                .map(|x| x.parse().expect("s"))
                .collect()
        })
        .unwrap_or_default();
    let tolerance: f64 = args.get(4).map_or(1e-4, |t| t.parse().expect("tolerance"));
    let t_all = std::time::Instant::now();
    let mut warm: Option<(Vec<f64>, Vec<f64>)> = None;
    let run = |label: String, measure: &SphereMeasure, tol: f64, warm: &mut Option<(Vec<f64>, Vec<f64>)>| {
        let (hi, lo) = warm.take().unzip();
        let p = SphereOtParams {
            tolerance: tol,
            initial_heights: hi,
            initial_heights_lo: lo,
            density_continuation: None,
            ..SphereOtParams::default()
        };
        let t = std::time::Instant::now();
        match solve_sphere_ot(measure, &b.points, &b.masses, &p) {
            Ok(s) => {
                let taus: Vec<String> = s.log.iter().map(|l| format!("{:.0e}/{}", l.step, l.halvings)).collect();
                println!(
                    "{label}: {} steps, {} evals, stop {}, error {:.2e}, cost {:.6e}, {:.2} s; tau/halvings {}",
                    s.iterations,
                    s.evaluations,
                    s.stop,
                    s.max_relative_error,
                    s.cost,
                    t.elapsed().as_secs_f64(),
                    taus.join(" ")
                );
                *warm = Some((s.heights, s.heights_lo));
            }
            Err(e) => println!("{label}: failed {e}"),
        }
    };
    run("B->B".into(), &b.measure, 1e-3, &mut warm);
    for &s in &stages {
        let m = mixture(&a.measure, &b.measure, s);
        run(format!("s={s}"), &m, 1e-3, &mut warm);
    }
    run("A->B".into(), &a.measure, tolerance, &mut warm);
    println!("total {:.2} s", t_all.elapsed().as_secs_f64());
}
