//! Probe: where the Newton steps of a face pair go, on any disk meshes (bundled
//! faces or prepared scans), with the pairwise distances' solver settings.
//!
//! `cargo run --release -p shapespace-tools --bin scan_probe -- A B [C ...]`
//! solves A → B, B → C, ... (consecutive pairs; markers as `shapespace distances` resolves
//! them: sidecar landmarks, else `auto`). Per shape: vertices, density range and quantiles, the
//! map's method (BFF fallback or not), the smallest target masses, the density on the faces at
//! the rim. Per pair: the coarse-to-fine levels (points, Newton steps), then each finest-level
//! step (max relative error, accepted τ, rejected trials, smallest cell mass) and the time split.
//! Env `STEPS=1` prints every finest step, `START=1` the start's m/ν by radius; experiments on
//! the measures (applied after `prepare_shape`): `CAP=k` caps the densities at k × the median
//! (mass is lost), `SPREAD=k` spreads them at k × the median, `NUFLOOR=k` floors the target
//! masses at k × their median. `PREPARE=1` prepares each file as `shapespace prepare` does
//! first (the raw scans of `outside/facefuns`), `SUBDIVIDE=1` then subdivides each once by edge
//! midpoints. `SHARED=1` prepares and maps the files as `shapespace distances` does, with the
//! automatic markers shared by files of one triangulation (the Sumner face poses). `REPEAT=1` solves each pair twice and reports
//! the second solve (the source's averaged coarse copies built by the first: the first's extra
//! time is their construction). Costs are printed minus the target's merge cost
//! (`quantization_variance`), as the distances use them. `KAPPA=k` sets the soft cap of the
//! intermediate targets (`NewtonParams::target_ratio_cap`, default 32) on every level,
//! `COARSE_TOL=t` the coarse levels' tolerance (`NewtonParams::coarse_tolerance`),
//! `REUSE_ORDER=1` takes `LinearSolver::CholeskyReusedOrdering`. Each pair
//! also prints the process's CPU time (all threads), steadier than the wall time on a shared machine.

use std::path::PathBuf;
use std::time::Instant;

use shapespace_analysis::distance::{prepare_shape, PairwiseOptions};
use shapespace_analysis::pipeline::{markers_for, MarkerOptions};
use shapespace_conformal::DiskMapParams;
use shapespace_omt::newton::Start;

fn quantiles(mut v: Vec<f64>, qs: &[f64]) -> Vec<f64> {
    v.sort_by(f64::total_cmp);
    qs.iter()
        .map(|q| v[((v.len() - 1) as f64 * q).round() as usize])
        .collect()
}

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let files: Vec<PathBuf> = std::env::args().skip(1).map(PathBuf::from).collect();
    let steps = std::env::var("STEPS").is_ok();
    let mut shapes = Vec::new();
    // SHARED=1: the files prepared and mapped as `shapespace distances` does, with the automatic
    // markers shared by the files of one triangulation (a file whose map fails is left out)
    let prepared = if std::env::var("SHARED").is_ok() {
        shapespace_tools::scans::prepared_set(&files)
    } else {
        let mut prepared = Vec::new();
        for f in &files {
            let mut mesh = shapespace_geometry::io::read_mesh(f)?;
            if std::env::var("PREPARE").is_ok() {
                mesh = shapespace_tools::scans::disk_mesh(f);
            }
            if std::env::var("SUBDIVIDE").is_ok() {
                mesh = shapespace_geometry::prepare::subdivide_midpoint(&mesh)?;
            }
            let (markers, _) = markers_for(f, &MarkerOptions::default(), mesh.positions.len())?;
            let name = f.file_stem().unwrap().to_string_lossy().to_string();
            prepared.push(prepare_shape(&name, &mesh, &markers, &DiskMapParams::default())?);
        }
        prepared
    };
    for mut shape in prepared {
        let name = shape.name.clone();
        // experiments: env CAP=k caps the densities at k × their median; NUFLOOR=k floors the
        // target masses at k × their median
        if let Some(k) = std::env::var("CAP").ok().and_then(|s| s.parse::<f64>().ok()) {
            let med = quantiles(shape.measure.densities.clone(), &[0.5])[0];
            let d: Vec<f64> = shape.measure.densities.iter().map(|&d| d.min(k * med)).collect();
            shape.measure =
                shapespace_omt::SourceMeasure::new(shape.measure.vertices.clone(), shape.measure.triangles.clone(), d)?
                    .into();
        }
        if let Some(k) = std::env::var("SPREAD").ok().and_then(|s| s.parse::<f64>().ok()) {
            let (m, info) = shapespace_omt::peaks::spread_density_peaks(&shape.measure, k)?;
            println!("{name}: spread {info:?}");
            shape.measure = m.into();
        }
        if let Some(k) = std::env::var("NUFLOOR").ok().and_then(|s| s.parse::<f64>().ok()) {
            let med = quantiles(shape.masses.clone(), &[0.5])[0];
            shape.masses.iter_mut().for_each(|m| *m = m.max(k * med));
            shape.coarsening = std::sync::Arc::new(shapespace_omt::newton::TargetCoarsening::new(
                &shape.points,
                &shape.masses,
            ));
        }
        let d = &shape.measure.densities;
        let q = quantiles(d.clone(), &[0.0, 0.01, 0.5, 0.99, 1.0]);
        let m = quantiles(shape.masses.clone(), &[0.0, 0.001, 0.5]);
        // faces with a vertex on the unit circle: the rim
        let rim: Vec<f64> = shape
            .measure
            .triangles
            .iter()
            .zip(d)
            .filter(|(t, _)| {
                t.iter().any(|&v| {
                    let p = shape.measure.vertices[v as usize];
                    (p[0] * p[0] + p[1] * p[1]).sqrt() > 1.0 - 1e-9
                })
            })
            .map(|(_, &d)| d)
            .collect();
        let r = quantiles(rim.clone(), &[0.0, 0.5, 1.0]);
        {
            let med = q[2];
            let areas: Vec<f64> = shape
                .measure
                .triangles
                .iter()
                .map(|t| {
                    let [a, b, c] = t.map(|v| shape.measure.vertices[v as usize]);
                    0.5 * ((b[0] - a[0]) * (c[1] - a[1]) - (b[1] - a[1]) * (c[0] - a[0])).abs()
                })
                .collect();
            let total: f64 = areas.iter().zip(d).map(|(a, d)| a * d).sum();
            for k in [1e2, 1e3, 1e4, 1e5, 1e6] {
                let (n, mass) = areas
                    .iter()
                    .zip(d)
                    .filter(|(_, &d)| d > k * med)
                    .fold((0, 0.0), |(n, m), (a, d)| (n + 1, m + a * d));
                print!("[>{k:.0e}x median: {n} faces, mass {:.2e}] ", mass / total);
            }
            println!();
        }
        println!(
            "{name}: V {} F {} method {} bff_fallback {:?} prepare {:.2} s | density min {:.2e} q01 {:.2e} median {:.2e} q99 {:.2e} max {:.2e} | rim faces {} density min {:.2e} median {:.2e} max {:.2e} | masses min {:.2e} q001 {:.2e} median {:.2e} | levels {:?}",
            shape.points.len(),
            shape.measure.triangles.len(),
            shape.disk.info.method,
            shape.disk.info.bff_fallback.as_ref().map(|b| b.green_folds),
            shape.seconds,
            q[0], q[1], q[2], q[3], q[4],
            rim.len(), r[0], r[1], r[2],
            m[0], m[1], m[2],
            shape.coarsening.level_sizes(),
        );
        shapes.push(shape);
    }
    let mut params = PairwiseOptions::default().newton;
    if let Some(k) = std::env::var("KAPPA").ok().and_then(|s| s.parse::<f64>().ok()) {
        params.target_ratio_cap = Some(k);
    }
    if std::env::var("REUSE_ORDER").is_ok() {
        params.linear_solver = shapespace_omt::linear::LinearSolver::CholeskyReusedOrdering;
    }
    if let Some(t) = std::env::var("COARSE_TOL").ok().and_then(|s| s.parse::<f64>().ok()) {
        params.coarse_tolerance = t;
    }
    for w in shapes.windows(2) {
        let (a, b) = (&w[0], &w[1]);
        let t = Instant::now();
        let mut cpu = shapespace_tools::cpu_seconds();
        let params = shapespace_omt::NewtonParams {
            target_coarsening: Some(b.coarsening.clone()),
            ..params.clone()
        };
        let mut sol = shapespace_omt::solve_ot_prepared(&a.measure, &b.points, &b.masses, &params)?;
        let mut secs = t.elapsed().as_secs_f64();
        if std::env::var("REPEAT").is_ok() {
            // again, with the source's averaged copies built: what the first solve spent on them
            println!(
                "  first solve {secs:.2} s, start {:.2} s (averaged copies {:?})",
                sol.t_start,
                a.measure.averaged_samples()
            );
            let t = Instant::now();
            cpu = shapespace_tools::cpu_seconds();
            sol = shapespace_omt::solve_ot_prepared(&a.measure, &b.points, &b.masses, &params)?;
            secs = t.elapsed().as_secs_f64();
        }
        let cpu = shapespace_tools::cpu_seconds() - cpu;
        let levels = match &sol.start {
            Start::CoarseToFine { level_iterations, .. } => format!("{level_iterations:?}"),
            s => format!("{s:?}"),
        };
        let (diag, integ, solve) = sol.log.iter().fold((0.0, 0.0, 0.0), |(x, y, z), r| {
            (x + r.t_diagram, y + r.t_integration, z + r.t_solve)
        });
        let taus: Vec<String> = sol.log.iter().map(|r| format!("{:.2}", r.step)).collect();
        let min_mass = sol.log.iter().map(|r| r.min_cell_mass).fold(f64::INFINITY, f64::min);
        println!(
            "PAIR {} -> {}: {} finest steps ({} evals, stop {}), coarse steps by level (coarser first) {levels}, eps0 {:.2e}, min cell mass {:.2e}, cost {:.10e} (minus the target's merge cost) | {:.2} s (CPU {cpu:.2} s): start {:.2} s, finest diagram {:.2} integrate {:.2} solve {:.2} | taus {}",
            a.name,
            b.name,
            sol.iterations,
            sol.evaluations,
            sol.stop,
            sol.epsilon0,
            min_mass,
            sol.cost - b.quantization_variance,
            secs,
            sol.t_start,
            diag,
            integ,
            solve,
            taus.join(" ")
        );
        println!(
            "  linear algebra: assembly {:.2} s, symbolic {:.2} s ({} factorizations, {} orderings), numeric + solve {:.2} s",
            sol.t_assembly, sol.t_symbolic, sol.symbolic_factorizations, sol.orderings, sol.t_numeric
        );
        if std::env::var("START").is_ok() {
            // the start alone (no Newton step): m/ν by radius of the target point
            let start = shapespace_omt::solve_ot(
                &a.measure,
                &b.points,
                &b.masses,
                &shapespace_omt::NewtonParams {
                    max_iterations: 0,
                    ..params.clone()
                },
            )?;
            let nu = &start.target_masses;
            let m = &start.cells.masses;
            for (lo, hi) in [
                (0.0, 0.5),
                (0.5, 0.9),
                (0.9, 0.99),
                (0.99, 0.999),
                (0.999, 1.0 - 1e-9),
                (1.0 - 1e-9, 2.0),
            ] {
                let idx: Vec<usize> = (0..nu.len())
                    .filter(|&i| {
                        let r = b.points[i][0].hypot(b.points[i][1]);
                        r >= lo && r < hi
                    })
                    .collect();
                if idx.is_empty() {
                    continue;
                }
                let ratios: Vec<f64> = idx.iter().map(|&i| m[i] / nu[i]).collect();
                let q = quantiles(ratios, &[0.0, 0.1, 0.5, 0.9, 1.0]);
                let off = idx.iter().filter(|&&i| (m[i] / nu[i]).ln().abs() > 0.3).count();
                let nus = quantiles(idx.iter().map(|&i| nu[i]).collect(), &[0.0, 0.5]);
                println!(
                    "  start |y| in [{lo}, {hi}): {} points, nu min {:.1e} median {:.1e}, m/nu min {:.2e} q10 {:.2e} median {:.2e} q90 {:.2e} max {:.2e}, {off} off by > 35 %",
                    idx.len(), nus[0], nus[1], q[0], q[1], q[2], q[3], q[4]
                );
            }
        }
        if steps {
            for (k, r) in sol.log.iter().enumerate() {
                println!(
                    "  {k:3} err {:.2e} tau {:.3e} rejm {} rejn {} minmass {:.2e} capped {}",
                    r.max_relative_error,
                    r.step,
                    r.rejected_min_mass,
                    r.rejected_norm,
                    r.min_cell_mass,
                    r.intermediate_targets
                );
            }
        }
    }
    Ok(())
}
