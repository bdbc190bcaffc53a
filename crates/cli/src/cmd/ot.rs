//! `shapespace ot --points P.csv [--domain disk|square|POLYGON.csv] [--density-mesh PLANAR.obj
//! [--density FACE_DENSITIES.csv]] [--tol 1e-6] [--max-iterations N] --out RESULT.csv
//! [--report R.json] [--cells CELLS.csv]`: semi-discrete optimal transport from a source density
//! to weighted points (damped Newton, `shapespace_omt::solve_ot`). Exit code 1 if not converged.
//!
//! `--domain sphere`: points `x,y,z[,mass]` on the unit sphere, the source uniform on S² (an
//! icosphere) or `--density-mesh` with vertices on S² (`shapespace_omt::solve_sphere_ot`).

use std::path::{Path, PathBuf};
use std::process::ExitCode;

use anyhow::{bail, Context};
use shapespace_geometry::io::{write_atomically, AtomicFile};
use shapespace_omt::linear::LinearSolver;
use shapespace_omt::power_diagram::PowerDiagram;
use shapespace_omt::restricted::cell_polygons;
use shapespace_omt::{solve_ot, NewtonParams, SourceMeasure, StartStrategy};

/// `--start` values.
#[derive(Clone, Copy, Debug, PartialEq, Eq, clap::ValueEnum)]
pub enum StartArg {
    Auto,
    Voronoi,
    CoarseToFine,
}

impl StartArg {
    /// The solver's strategy.
    pub fn strategy(self) -> StartStrategy {
        match self {
            StartArg::Auto => StartStrategy::Auto,
            StartArg::Voronoi => StartStrategy::Voronoi,
            StartArg::CoarseToFine => StartStrategy::CoarseToFine,
        }
    }
}

/// Arguments of `shapespace ot`.
#[derive(clap::Args)]
pub struct OtArgs {
    /// Target points CSV with header `x,y,mass` (masses > 0; rescaled to the source mass); with
    /// `--domain sphere`, `x,y,z` and an optional `mass` column (equal masses without it), every
    /// point within 1e-6 of the unit sphere (then normalized).
    #[arg(long)]
    pub points: PathBuf,
    /// Source domain with uniform density: `disk` (unit disk as a 512-gon), `square` (unit
    /// square), a CSV of a convex polygon (header `x,y`, counter-clockwise), or `sphere` (the
    /// unit sphere S² with the chordal cost |x − y|²). Planar domains are ignored with
    /// `--density-mesh`.
    #[arg(long, default_value = "disk")]
    pub domain: String,
    /// Planar triangulation of a convex domain (OBJ/OFF/PLY; texture coordinates if present,
    /// else x, y of the positions; triangles counter-clockwise). With `--domain sphere`, a
    /// triangulation of the unit sphere (positions within 1e-6 of S²; masses on the flat
    /// triangles: density × flat area).
    #[arg(long)]
    pub density_mesh: Option<PathBuf>,
    /// Per-face densities for `--density-mesh` (CSV with header `density`, one row per face);
    /// uniform density 1 without it.
    #[arg(long, requires = "density_mesh")]
    pub density: Option<PathBuf>,
    /// Tolerance on max_i |μ(W_i) − ν_i| / ν_i.
    #[arg(long, default_value_t = 1e-6)]
    pub tol: f64,
    /// Maximum number of Newton steps (per continuation stage).
    #[arg(long, default_value_t = 100)]
    pub max_iterations: usize,
    /// Initial heights: `auto` (coarse-to-fine for a density ratio above 10 or crowded points,
    /// else Voronoi), `voronoi` or `coarse-to-fine`. Planar domains only: the sphere starts
    /// from its Voronoi diagram (with a density continuation above a density ratio of 10).
    #[arg(long, value_enum, default_value_t = StartArg::Auto)]
    pub start: StartArg,
    /// Solve the Newton systems by Jacobi-preconditioned CG instead of sparse Cholesky.
    #[arg(long)]
    pub cg: bool,
    /// Subdivisions of the icosphere carrying the uniform source with `--domain sphere` and no
    /// `--density-mesh` (20·4^s triangles); default: the fewest from 5 on with at least half as
    /// many triangles as points, at most 7.
    #[arg(long)]
    pub sphere_subdivisions: Option<usize>,
    /// Output CSV `i,height,mass,cx,cy` (mass of the cell, μ-centroid); with `--domain sphere`
    /// `i,height,mass,cx,cy,cz`, the centroid projected radially on S².
    #[arg(long)]
    pub out: PathBuf,
    /// JSON report: cost, iterations, final error, stop reason, per-iteration log, timings.
    #[arg(long)]
    pub report: Option<PathBuf>,
    /// CSV of the restricted cells, one row per polygon vertex: `i,k,x,y`; with `--domain
    /// sphere` one row per corner of each cell's piece of a source triangle: `i,t,k,x,y,z`.
    #[arg(long)]
    pub cells: Option<PathBuf>,
}

#[derive(serde::Deserialize)]
struct PointRow {
    x: f64,
    y: f64,
    mass: f64,
}

#[derive(serde::Deserialize)]
struct XyRow {
    x: f64,
    y: f64,
}

#[derive(serde::Deserialize)]
pub(crate) struct DensityRow {
    pub(crate) density: f64,
}

pub(crate) fn read_rows<T: serde::de::DeserializeOwned>(path: &Path) -> anyhow::Result<Vec<T>> {
    // read the whole file first: the csv reader takes a directory for an empty file
    let data = std::fs::read(path).with_context(|| format!("reading {}", path.display()))?;
    let mut reader = csv::ReaderBuilder::new()
        .trim(csv::Trim::All)
        .from_reader(data.as_slice());
    let mut rows = Vec::new();
    for (k, row) in reader.deserialize().enumerate() {
        rows.push(row.with_context(|| format!("{}:{}: bad row", path.display(), k + 2))?);
    }
    Ok(rows)
}

fn source_measure(args: &OtArgs) -> anyhow::Result<SourceMeasure> {
    if let Some(mesh_path) = &args.density_mesh {
        // (its errors name the file)
        let mesh = shapespace_geometry::io::read_mesh(mesh_path)?;
        let vertices: Vec<[f64; 2]> = match &mesh.uvs {
            Some(uvs) => uvs.clone(),
            None => mesh.positions.iter().map(|p| [p[0], p[1]]).collect(),
        };
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
        let measure = SourceMeasure::new(vertices, mesh.faces.clone(), densities)
            .with_context(|| format!("source measure from {}", mesh_path.display()))?;
        let gap = measure.convexity_gap();
        if !(gap.abs() <= 1e-6) {
            bail!(
                "{}: the triangles do not tile a convex domain (they miss {:.2e} of their convex hull's area{}); the solver clips the cells to that hull",
                mesh_path.display(),
                gap,
                if gap < 0.0 { ": they overlap" } else { "" }
            );
        }
        return Ok(measure);
    }
    Ok(match args.domain.as_str() {
        "disk" => SourceMeasure::unit_disk(512)?,
        "square" => SourceMeasure::unit_square()?,
        path => {
            if !Path::new(path).exists() {
                anyhow::bail!(
                    "--domain {path:?}: expected `disk`, `square` or a polygon CSV file (x,y), and no such file exists"
                );
            }
            let rows: Vec<XyRow> = read_rows(Path::new(path))?;
            let polygon: Vec<[f64; 2]> = rows.iter().map(|r| [r.x, r.y]).collect();
            SourceMeasure::uniform_polygon(&polygon, 1.0).with_context(|| format!("domain polygon {path}"))?
        }
    })
}

pub fn run(args: &OtArgs) -> anyhow::Result<ExitCode> {
    super::check_output_files(
        [Some(args.out.as_path()), args.cells.as_deref(), args.report.as_deref()],
        [
            Some(args.points.as_path()),
            args.density_mesh.as_deref(),
            args.density.as_deref(),
        ],
    )?;
    if args.domain == "sphere" {
        return super::ot_sphere::run(args);
    }
    let measure = source_measure(args)?;
    let rows: Vec<PointRow> = read_rows(&args.points)?;
    let points: Vec<[f64; 2]> = rows.iter().map(|r| [r.x, r.y]).collect();
    let masses: Vec<f64> = rows.iter().map(|r| r.mass).collect();
    let params = NewtonParams {
        tolerance: args.tol,
        max_iterations: args.max_iterations,
        start_strategy: args.start.strategy(),
        linear_solver: if args.cg {
            LinearSolver::ConjugateGradient {
                relative_tolerance: 1e-10,
                max_iterations: 10_000,
            }
        } else {
            LinearSolver::Cholesky
        },
        ..NewtonParams::default()
    };
    eprintln!(
        "shapespace ot: {} points, {} source triangles",
        points.len(),
        measure.triangles.len()
    );
    let solution =
        solve_ot(&measure, &points, &masses, &params).with_context(|| format!("OT to {}", args.points.display()))?;
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
    out.write_record(["i", "height", "mass", "cx", "cy"])?;
    let centroids = solution.centroids();
    for i in 0..points.len() {
        let c = centroids[i].unwrap_or([f64::NAN, f64::NAN]);
        out.write_record([
            i.to_string(),
            format!("{:e}", solution.heights[i]),
            format!("{:e}", solution.cells.masses[i]),
            format!("{:e}", c[0]),
            format!("{:e}", c[1]),
        ])?;
    }
    commit_csv(out).with_context(|| format!("writing {}", args.out.display()))?;

    if let Some(path) = &args.cells {
        let diagram = PowerDiagram::new(&points, &solution.weights)?;
        let polygons = cell_polygons(&diagram, &points, &solution.weights, &measure);
        let file = AtomicFile::create(path).with_context(|| format!("writing {}", path.display()))?;
        let mut w = csv::Writer::from_writer(file);
        w.write_record(["i", "k", "x", "y"])?;
        for (i, polygon) in polygons.iter().enumerate() {
            for (k, p) in polygon.iter().enumerate() {
                w.write_record([
                    i.to_string(),
                    k.to_string(),
                    format!("{:e}", p[0]),
                    format!("{:e}", p[1]),
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
                    "t_diagram": r.t_diagram,
                    "t_integration": r.t_integration,
                    "t_solve": r.t_solve,
                })
            })
            .collect();
        let sum = |f: fn(&shapespace_omt::newton::IterationRecord) -> f64| solution.log.iter().map(f).sum::<f64>();
        let report = serde_json::json!({
            "points": points.len(),
            "source_triangles": measure.triangles.len(),
            "cost": solution.cost,
            "iterations": solution.iterations,
            "max_relative_error": solution.max_relative_error,
            "tolerance": solution.tolerance,
            "converged": solution.converged(),
            "stop_reason": solution.stop_description(),
            "mass_scale": solution.mass_scale,
            "epsilon0": solution.epsilon0,
            "start": format!("{:?}", solution.start),
            "symbolic_factorizations": solution.symbolic_factorizations,
            "timings": {
                "start": solution.t_start,
                "diagram": sum(|r| r.t_diagram),
                "integration": sum(|r| r.t_integration),
                "solve": sum(|r| r.t_solve),
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

/// Flushes a CSV writer and puts its file in place.
pub(crate) fn commit_csv(w: csv::Writer<AtomicFile>) -> std::io::Result<()> {
    w.into_inner().map_err(|e| e.into_error())?.commit()
}
