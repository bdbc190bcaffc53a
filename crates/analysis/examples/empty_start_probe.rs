//! Probe: the empty cells of the Voronoi start of an area-preserving OT problem.
//! `empty_start_probe MESH` (a disk).
use shapespace_analysis::area_preserving::{transport_problem, AreaPreservingParams};
use shapespace_conformal::Markers;
use shapespace_omt::power_diagram::PowerDiagram;

fn main() {
    let path = std::env::args().nth(1).expect("mesh path");
    let disk = shapespace_geometry::io::read_mesh(std::path::Path::new(&path)).unwrap();
    let params = AreaPreservingParams::default();
    let p = transport_problem(&disk, &Markers::default(), &params).unwrap();
    let y = &p.conformal.uv;
    let w: Vec<f64> = y.iter().map(|q| q[0] * q[0] + q[1] * q[1]).collect();
    let d = PowerDiagram::new(y, &vec![0.0; y.len()]).unwrap();
    let hidden: Vec<usize> = (0..y.len()).filter(|&i| d.is_hidden(i)).collect();
    println!("{} points, hidden in the Voronoi diagram: {:?}", y.len(), hidden);
    let _ = w;
    let cells = shapespace_omt::restricted::RestrictedIntegrator::new(&p.measure).integrate(&d);
    let empty: Vec<usize> = (0..y.len()).filter(|&i| !(cells.masses[i] > 0.0)).collect();
    println!("empty: {empty:?}");
    for &i in &empty {
        let r = y[i][0].hypot(y[i][1]);
        println!(
            "  {i}: y {:?} r-1 {:.3e} boundary {} neighbours {:?}",
            y[i],
            r - 1.0,
            p.is_boundary[i],
            d.neighbors(i)
                .iter()
                .map(|&j| (j, y[j as usize], y[j as usize][0].hypot(y[j as usize][1]) - 1.0))
                .collect::<Vec<_>>()
        );
    }
    println!("sanity: {:?}", d.sanity_check());
    let order = shapespace_omt::power_diagram::InsertionOrder::new(y).unwrap();
    let zeros = vec![0.0; y.len()];
    let d2 = PowerDiagram::with_order_dd(y, &zeros, Some(&zeros), &order).unwrap();
    let c2 = shapespace_omt::restricted::RestrictedIntegrator::new(&p.measure).integrate(&d2);
    println!(
        "with order: hidden {} empty {}",
        (0..y.len()).filter(|&i| d2.is_hidden(i)).count(),
        c2.masses.iter().filter(|&&m| !(m > 0.0)).count()
    );
    let h: Vec<f64> = y.iter().map(|q| -0.5 * (q[0] * q[0] + q[1] * q[1])).collect();
    let c3 = shapespace_omt::newton::integrate_at_heights(&p.measure, y, &h, Default::default()).unwrap();
    println!(
        "integrate_at_heights: empty {}",
        c3.masses.iter().filter(|&&m| !(m > 0.0)).count()
    );
    for i in (0..y.len()).filter(|&i| !(c3.masses[i] > 0.0)).take(8) {
        println!(
            "  {i}: y {:?} r-1 {:.3e} boundary {} mass {} voronoi mass {}",
            y[i],
            y[i][0].hypot(y[i][1]) - 1.0,
            p.is_boundary[i],
            c3.masses[i],
            c2.masses[i]
        );
    }
    let w = shapespace_omt::newton::weights_from_heights(y, &h);
    let d4 = PowerDiagram::with_order(y, &w, &order).unwrap();
    let c4 = shapespace_omt::restricted::RestrictedIntegrator::new(&p.measure).integrate(&d4);
    println!(
        "f64 weights: hidden {} empty {} max |w| {:e}",
        (0..y.len()).filter(|&i| d4.is_hidden(i)).count(),
        c4.masses.iter().filter(|&&m| !(m > 0.0)).count(),
        w.iter().fold(0.0f64, |a, b| a.max(b.abs()))
    );
    for i in [4396usize, 4398] {
        let mut near: Vec<(f64, usize)> = (0..y.len())
            .filter(|&j| j != i)
            .map(|j| ((y[j][0] - y[i][0]).hypot(y[j][1] - y[i][1]), j))
            .collect();
        near.sort_by(|a, b| a.0.total_cmp(&b.0));
        println!(
            "  {i}: y {:?} r-1 {:.3e} boundary {} nu {:.3e} nearest {:?}",
            y[i],
            y[i][0].hypot(y[i][1]) - 1.0,
            p.is_boundary[i],
            p.target_masses[i],
            &near[..4]
                .iter()
                .map(|&(d, j)| (d, j, p.is_boundary[j], y[j][0].hypot(y[j][1]) - 1.0))
                .collect::<Vec<_>>()
        );
    }
    let r = shapespace_omt::solve_ot(&p.measure, y, &p.target_masses, &params.newton);
    println!("solve: {:?}", r.map(|s| (s.iterations, s.stop)));
}
