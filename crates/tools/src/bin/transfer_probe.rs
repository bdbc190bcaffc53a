//! Probe: starts for s → t from a solved s → t' (same source, another target).
//! `transfer_probe S T' T` (face names in datasets/faces).
use shapespace_analysis::distance::PreparedShape;
use shapespace_omt::power_diagram::PowerDiagram;
use shapespace_omt::restricted::RestrictedIntegrator;
use shapespace_omt::{newton::weights_from_heights, solve_ot, NewtonParams};
use shapespace_tools::faces;
use std::time::Instant;

fn main() {
    let args: Vec<String> = std::env::args().skip(1).collect();
    let shapes = faces::prepared_faces(&args);
    let (s, tp, t) = (&shapes[0], &shapes[1], &shapes[2]);
    let base = NewtonParams {
        density_continuation: None,
        max_iterations: 300,
        ..Default::default()
    };
    let run = |label: &str, init: Option<Vec<f64>>, tgt: &PreparedShape| {
        let params = NewtonParams {
            initial_heights: init,
            ..base.clone()
        };
        let sol = solve_ot(&s.measure, &tgt.points, &tgt.masses, &params).unwrap();
        println!(
            "{} -> {} {label}: it {} evals {} t {:.3} cost {:.15e} err0 {:.2e} min0 {:.2e}",
            s.name,
            tgt.name,
            sol.iterations,
            sol.evaluations,
            sol.t_total,
            sol.cost,
            sol.log.first().map(|r| r.max_relative_error).unwrap_or(0.0),
            sol.log.first().map(|r| r.min_cell_mass).unwrap_or(0.0),
        );
        sol
    };
    let prev = run("voronoi", None, tp);
    run("voronoi", None, t);
    run("index", Some(prev.heights.clone()), t);
    // c-transform: u*(y) = max over restricted diagram vertices x of <x,y> - u(x).
    let clock = Instant::now();
    let w = weights_from_heights(&tp.points, &prev.heights);
    let diagram = PowerDiagram::new(&tp.points, &w).unwrap();
    let integ = RestrictedIntegrator::new(&s.measure);
    let polys = integ.cell_polygons(&diagram);
    let mut verts: Vec<([f64; 2], f64)> = Vec::new();
    for (k, poly) in polys.iter().enumerate() {
        let y = tp.points[k];
        for x in poly {
            verts.push((*x, x[0] * y[0] + x[1] * y[1] + prev.heights[k]));
        }
    }
    let hc: Vec<f64> = t
        .points
        .iter()
        .map(|y| {
            let ustar = verts
                .iter()
                .map(|(x, u)| x[0] * y[0] + x[1] * y[1] - u)
                .fold(f64::NEG_INFINITY, f64::max);
            -ustar
        })
        .collect();
    println!(
        "c-transform {:.3} s over {} vertices",
        clock.elapsed().as_secs_f64(),
        verts.len()
    );
    let vor: Vec<f64> = t.points.iter().map(|y| -0.5 * (y[0] * y[0] + y[1] * y[1])).collect();
    let report = |label: &str, h: &[f64]| {
        let cells = shapespace_omt::newton::integrate_at_heights(&s.measure, &t.points, h, Default::default()).unwrap();
        let total: f64 = t.masses.iter().sum();
        let scale = s.measure.total_mass() / total;
        let empty = cells.masses.iter().filter(|&&m| !(m > 0.0)).count();
        let err = cells
            .masses
            .iter()
            .zip(&t.masses)
            .map(|(m, n)| (m - n * scale).abs() / (n * scale))
            .fold(0.0, f64::max);
        let minrel = cells
            .masses
            .iter()
            .zip(&t.masses)
            .map(|(m, n)| m / (n * scale))
            .fold(f64::INFINITY, f64::min);
        println!("{label}: empty {empty} max rel err {err:.3e} min m/nu {minrel:.2e}");
    };
    report("voronoi", &vor);
    report("index", &prev.heights);
    report("ctransform", &hc);
    let anchored = |sol: &shapespace_omt::OtSolution, from: &PreparedShape| -> Vec<f64> {
        let c = sol.centroids();
        (0..t.points.len())
            .map(|k| {
                let x = c[k].unwrap_or(from.points[k]);
                let d = [t.points[k][0] - from.points[k][0], t.points[k][1] - from.points[k][1]];
                sol.heights[k] - (x[0] * d[0] + x[1] * d[1])
            })
            .collect()
    };
    let h = anchored(&prev, tp);
    report("anchored prev", &h);
    run("anchored prev", Some(h), t);
    let selfsol = run("self", None, s);
    let h = anchored(&selfsol, s);
    report("anchored self", &h);
    run("anchored self", Some(h), t);
    for alpha in [0.02, 0.1, 0.3] {
        let h: Vec<f64> = hc
            .iter()
            .zip(&vor)
            .map(|(a, b)| (1.0 - alpha) * a + alpha * b)
            .collect();
        report(&format!("ct+vor {alpha}"), &h);
        run(&format!("ct+vor {alpha}"), Some(h), t);
        let h: Vec<f64> = prev
            .heights
            .iter()
            .zip(&vor)
            .map(|(a, b)| (1.0 - alpha) * a + alpha * b)
            .collect();
        report(&format!("idx+vor {alpha}"), &h);
        run(&format!("idx+vor {alpha}"), Some(h), t);
    }
}
