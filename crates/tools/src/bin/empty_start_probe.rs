//! Probe: the empty cells of the starts of an area-preserving OT problem (Voronoi, and the
//! coarse-to-fine start evaluated with `max_iterations = 0`), then the solve.
//! `empty_start_probe MESH` (a disk, e.g. written by `shapespace prepare --seam 3`).
use shapespace_analysis::area_preserving::{transport_problem, AreaPreservingParams};
use shapespace_conformal::Markers;
use shapespace_omt::{solve_ot, NewtonParams, StartStrategy};

fn main() {
    let path = std::env::args().nth(1).expect("mesh path");
    let disk = shapespace_geometry::io::read_mesh(std::path::Path::new(&path)).unwrap();
    let params = AreaPreservingParams::default();
    let p = transport_problem(&disk, &Markers::default(), &params).unwrap();
    let y = &p.conformal.uv;
    let describe = |label: &str, masses: &[f64]| {
        let empty: Vec<usize> = (0..y.len()).filter(|&i| !(masses[i] > 0.0)).collect();
        println!("{label}: {} of {} cells empty", empty.len(), y.len());
        for &i in empty.iter().take(8) {
            let nearest = (0..y.len())
                .filter(|&j| j != i)
                .map(|j| (y[j][0] - y[i][0]).hypot(y[j][1] - y[i][1]))
                .fold(f64::INFINITY, f64::min);
            println!(
                "  {i}: y {:?}, |y| − 1 = {:.3e}, boundary {}, ν {:.3e}, nearest other point {nearest:.3e}",
                y[i],
                y[i][0].hypot(y[i][1]) - 1.0,
                p.is_boundary[i],
                p.target_masses[i]
            );
        }
    };
    let h: Vec<f64> = y.iter().map(|q| -0.5 * (q[0] * q[0] + q[1] * q[1])).collect();
    match shapespace_omt::newton::integrate_at_heights(&p.measure, y, &h, Default::default()) {
        Ok(cells) => describe("Voronoi start", &cells.masses),
        Err(e) => println!("Voronoi start: {e}"),
    }
    let start_only = NewtonParams {
        max_iterations: 0,
        start_strategy: StartStrategy::CoarseToFine,
        ..params.newton.clone()
    };
    match solve_ot(&p.measure, y, &p.target_masses, &start_only) {
        Ok(s) => describe(&format!("{:?} start", s.start), &s.cells.masses),
        Err(e) => println!("coarse-to-fine start: {e}"),
    }
    match solve_ot(&p.measure, y, &p.target_masses, &params.newton) {
        Ok(s) => println!("solve: {} steps, {}", s.iterations, s.stop),
        Err(e) => println!("solve: {e}"),
    }
}
