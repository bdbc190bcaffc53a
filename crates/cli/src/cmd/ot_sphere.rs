//! `shapespace ot --domain sphere`: semi-discrete OT on the unit sphere with the chordal cost
//! (`shapespace_omt::solve_sphere_ot`), from the uniform density (an icosphere) or a density
//! mesh with vertices on S², to points `x,y,z[,mass]` on S².

use std::process::ExitCode;

use anyhow::{bail, Context};
use shapespace_geometry::io::{write_atomically, AtomicFile};
use shapespace_omt::linear::LinearSolver;
use shapespace_omt::sphere::measure::SPHERE_TOLERANCE;
use shapespace_omt::sphere::SphereIntegrator;
use shapespace_omt::{solve_sphere_ot, SphereMeasure, SphereOtParams};

use super::ot::{commit_csv, read_rows, DensityRow, OtArgs};

#[derive(serde::Deserialize)]
struct SphereRow {
    x: f64,
    y: f64,
    z: f64,
    #[serde(default)]
    mass: Option<f64>,
}

/// Icosphere subdivisions for `n` points: the fewest from 5 on with 20·4^s ≥ n/2, at most 7.
fn default_subdivisions(n: usize) -> usize {
    let mut s = 5;
    while s < 7 && 2 * 20 * 4usize.pow(s as u32) < n {
        s += 1;
    }
    s
}

fn source_measure(args: &OtArgs, n: usize) -> anyhow::Result<SphereMeasure> {
    let Some(mesh_path) = &args.density_mesh else {
        let s = args.sphere_subdivisions.unwrap_or_else(|| default_subdivisions(n));
        if s > 9 {
            bail!("--sphere-subdivisions {s}: at most 9 (20·4^9 = 5.2M triangles)");
        }
        return Ok(SphereMeasure::uniform_icosphere(s)?);
    };
    // (its errors name the file)
    let mesh = shapespace_geometry::io::read_mesh(mesh_path)?;
    if let Some((k, p)) = mesh.positions.iter().enumerate().find(|(_, p)| {
        let r = (p[0] * p[0] + p[1] * p[1] + p[2] * p[2]).sqrt();
        !((r - 1.0).abs() <= SPHERE_TOLERANCE)
    }) {
        let r = (p[0] * p[0] + p[1] * p[1] + p[2] * p[2]).sqrt();
        bail!(
            "{}: vertex {} ({}, {}, {}) is not on the unit sphere (|v| = {r}); --domain sphere needs a triangulation of S² (e.g. a spherical conformal map's output)",
            mesh_path.display(),
            k + 1,
            p[0],
            p[1],
            p[2]
        );
    }
    let densities = match &args.density {
        Some(path) => {
            let rows: Vec<DensityRow> = read_rows(path)?;
            if rows.len() != mesh.faces.len() {
                bail!(
                    "{}: {} densities for {} faces",
                    path.display(),
                    rows.len(),
                    mesh.faces.len()
                );
            }
            rows.into_iter().map(|r| r.density).collect()
        }
        None => vec![1.0; mesh.faces.len()],
    };
    SphereMeasure::new(mesh.positions.clone(), mesh.faces.clone(), densities)
        .with_context(|| format!("spherical source from {}", mesh_path.display()))
}

pub fn run(args: &OtArgs) -> anyhow::Result<ExitCode> {
    let rows: Vec<SphereRow> = read_rows(&args.points)?;
    if rows.is_empty() {
        bail!("{}: no points", args.points.display());
    }
    let mut points = Vec::with_capacity(rows.len());
    let mut masses = Vec::with_capacity(rows.len());
    for (k, r) in rows.iter().enumerate() {
        let norm = (r.x * r.x + r.y * r.y + r.z * r.z).sqrt();
        if !((norm - 1.0).abs() <= SPHERE_TOLERANCE) {
            bail!(
                "{}:{}: point ({}, {}, {}) is not on the unit sphere (|y| = {norm}; --domain sphere accepts |y| within 1e-6 of 1 and normalizes those)",
                args.points.display(),
                k + 2,
                r.x,
                r.y,
                r.z
            );
        }
        points.push([r.x, r.y, r.z]);
        masses.push(r.mass.unwrap_or(1.0));
    }
    if rows.iter().any(|r| r.mass.is_some()) && rows.iter().any(|r| r.mass.is_none()) {
        bail!("{}: some rows have a mass and some do not", args.points.display());
    }
    let measure = source_measure(args, points.len())?;
    let params = SphereOtParams {
        tolerance: args.tol,
        max_iterations: args.max_iterations,
        linear_solver: if args.cg {
            LinearSolver::ConjugateGradient {
                relative_tolerance: 1e-10,
                max_iterations: 10_000,
            }
        } else {
            LinearSolver::Cholesky
        },
        ..Default::default()
    };
    eprintln!(
        "shapespace ot: {} points on the sphere, {} source triangles",
        points.len(),
        measure.triangles.len()
    );
    let solution = solve_sphere_ot(&measure, &points, &masses, &params)
        .with_context(|| format!("OT on the sphere to {}", args.points.display()))?;
    eprintln!(
        "shapespace ot: {}: {} after {} steps, max relative mass error {:.3e}, cost {:.9}, {:.2} s",
        args.points.display(),
        solution.stop,
        solution.iterations,
        solution.max_relative_error,
        solution.cost,
        solution.t_total
    );

    let file = AtomicFile::create(&args.out).with_context(|| format!("writing {}", args.out.display()))?;
    let mut out = csv::Writer::from_writer(file);
    out.write_record(["i", "height", "mass", "cx", "cy", "cz"])?;
    let centroids = solution.centroids_on_sphere();
    for (i, c) in centroids.iter().enumerate() {
        let c = c.unwrap_or([f64::NAN; 3]);
        out.write_record([
            i.to_string(),
            format!("{:e}", solution.heights[i]),
            format!("{:e}", solution.cells.masses[i]),
            format!("{:e}", c[0]),
            format!("{:e}", c[1]),
            format!("{:e}", c[2]),
        ])?;
    }
    commit_csv(out).with_context(|| format!("writing {}", args.out.display()))?;

    if let Some(path) = &args.cells {
        let pieces = SphereIntegrator::new(&measure, &solution.points).pieces(&solution.heights);
        let file = AtomicFile::create(path).with_context(|| format!("writing {}", path.display()))?;
        let mut w = csv::Writer::from_writer(file);
        w.write_record(["i", "t", "k", "x", "y", "z"])?;
        for piece in &pieces {
            for (k, p) in piece.polygon.iter().enumerate() {
                w.write_record([
                    piece.site.to_string(),
                    piece.triangle.to_string(),
                    k.to_string(),
                    format!("{:e}", p[0]),
                    format!("{:e}", p[1]),
                    format!("{:e}", p[2]),
                ])?;
            }
        }
        commit_csv(w).with_context(|| format!("writing {}", path.display()))?;
    }

    if let Some(path) = &args.report {
        let log: Vec<serde_json::Value> = solution
            .log
            .iter()
            .map(|r| {
                serde_json::json!({
                    "max_relative_error": r.max_relative_error,
                    "gradient_norm": r.gradient_norm,
                    "step": r.step,
                    "halvings": r.halvings,
                    "min_cell_mass": r.min_cell_mass,
                    "t_integration": r.t_integration,
                    "t_solve": r.t_solve,
                })
            })
            .collect();
        let report = serde_json::json!({
            "domain": "sphere",
            "points": points.len(),
            "source_triangles": measure.triangles.len(),
            "cost": solution.cost,
            "dual_value": solution.dual_value(),
            "iterations": solution.iterations,
            "evaluations": solution.evaluations,
            "max_relative_error": solution.max_relative_error,
            "tolerance": solution.tolerance,
            "converged": solution.converged(),
            "stop_reason": solution.stop.to_string(),
            "mass_scale": solution.mass_scale,
            "epsilon0": solution.epsilon0,
            "timings": {
                "integration": solution.log.iter().map(|r| r.t_integration).sum::<f64>(),
                "solve": solution.log.iter().map(|r| r.t_solve).sum::<f64>(),
                "total": solution.t_total,
            },
            "log": log,
        });
        write_atomically(path, serde_json::to_string_pretty(&report)?.as_bytes())
            .with_context(|| format!("writing {}", path.display()))?;
    }
    Ok(if solution.converged() {
        ExitCode::SUCCESS
    } else {
        ExitCode::from(1)
    })
}
