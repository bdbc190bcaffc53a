//! `shapespace mds DIST.csv --out DIR [--method classical|smacof] [--labels labels.csv] [--dims 2]
//! [--color-by COL] [--marker-by COL] [--color-scale auto|categorical|continuous] [--point-labels]`:
//! classical MDS (or metric MDS by SMACOF) of a distance matrix, with plots, the stress and
//! shape-space statistics. Exit code 1 when SMACOF stopped at its iteration cap (the last
//! configuration is still written).

use std::path::PathBuf;
use std::process::ExitCode;

use anyhow::Context;
use shapespace_analysis::plot::ColorScale;
use shapespace_analysis::shape_space::{run_mds, MdsMethod, MdsParams, MdsResult};

/// `--color-scale` values.
#[derive(Clone, Copy, Debug, clap::ValueEnum)]
pub enum ColorScaleArg {
    Auto,
    Categorical,
    Continuous,
}

/// `--method` values.
#[derive(Clone, Copy, Debug, clap::ValueEnum)]
pub enum MethodArg {
    Classical,
    Smacof,
}

/// Arguments of `shapespace mds`.
#[derive(clap::Args)]
pub struct MdsArgs {
    /// Square distance matrix CSV (header `name,<names>`; empty or NaN cells are missing).
    pub distances: PathBuf,
    /// Output directory (mds.csv, eigenvalues.csv, mds.png, mds.svg, stats.json; mds_matrix.png
    /// and .svg from --dims 3 on).
    #[arg(long)]
    pub out: PathBuf,
    /// `classical` (Torgerson) MDS, or `smacof`: metric MDS minimizing the raw stress by the
    /// Guttman transform, started from the classical embedding. Both report the raw stress and
    /// the stress-1 (stats.json, `mds.stress`).
    #[arg(long, value_enum, default_value_t = MethodArg::Classical)]
    pub method: MethodArg,
    /// SMACOF's iteration cap.
    #[arg(long, default_value_t = 1000)]
    pub max_iterations: usize,
    /// Labels CSV: first column `file` or `name` (a shape name, or a file path ending with one), then label columns (an empty cell: unknown).
    #[arg(long)]
    pub labels: Option<PathBuf>,
    /// Number of MDS dimensions written to mds.csv; the plot shows the first two, and from 3 on
    /// mds_matrix.png/.svg plot the first k (at most 8) as a scatter matrix.
    #[arg(long, default_value_t = 2)]
    pub dims: usize,
    /// Label column for point colours (default: the first label column).
    #[arg(long)]
    pub color_by: Option<String>,
    /// Label column for marker shapes (default: the second label column, if any).
    #[arg(long)]
    pub marker_by: Option<String>,
    /// How the colour column becomes colours: `auto` (a continuous scale when every value is a
    /// number and there are at least 6 distinct ones, else one colour per value),
    /// `categorical` or `continuous`.
    #[arg(long, value_enum, default_value_t = ColorScaleArg::Auto)]
    pub color_scale: ColorScaleArg,
    /// Write each shape's name beside its point.
    #[arg(long)]
    pub point_labels: bool,
    /// Label columns whose cross-column 1-NN accuracies (one per ordered pair) stats.json gets
    /// (default: all columns when there are at most 8, else none: their number is quadratic).
    #[arg(long, value_delimiter = ',')]
    pub cross_columns: Option<Vec<String>>,
}

pub fn run(args: &MdsArgs) -> anyhow::Result<ExitCode> {
    super::check_output_folder(
        &args.out,
        &shapespace_analysis::shape_space::MDS_OUTPUTS,
        [Some(args.distances.as_path()), args.labels.as_deref()],
    )?;
    let mut params = MdsParams {
        method: match args.method {
            MethodArg::Classical => MdsMethod::Classical,
            MethodArg::Smacof => MdsMethod::Smacof,
        },
        dims: args.dims,
        color_by: args.color_by.clone(),
        marker_by: args.marker_by.clone(),
        color_scale: match args.color_scale {
            ColorScaleArg::Auto => ColorScale::Auto,
            ColorScaleArg::Categorical => ColorScale::Categorical,
            ColorScaleArg::Continuous => ColorScale::Continuous,
        },
        point_labels: args.point_labels,
        cross_columns: args.cross_columns.clone(),
        ..MdsParams::default()
    };
    params.smacof.max_iterations = args.max_iterations;
    let result = run_mds(&args.distances, args.labels.as_deref(), &args.out, &params)
        .with_context(|| format!("mds of {}", args.distances.display()))?;
    print_summary(&result);
    if result.stats.mds.smacof_converged == Some(false) {
        eprintln!(
            "shapespace: SMACOF stopped at its iteration cap ({}) before its tolerance; the last configuration was written",
            args.max_iterations
        );
        return Ok(ExitCode::from(1));
    }
    Ok(ExitCode::SUCCESS)
}

/// Prints the embedding's variance shares, the label statistics and the files written (stderr).
pub fn print_summary(result: &MdsResult) {
    if !result.stats.dropped_shapes.is_empty() {
        eprintln!(
            "mds: left out {} shape(s) with missing distances: {}",
            result.stats.dropped_shapes.len(),
            result.stats.dropped_shapes.join(", ")
        );
    }
    if !result.stats.unlabeled_shapes.is_empty() {
        eprintln!(
            "mds: {} shape(s) without a labels row (unknown labels): {}",
            result.stats.unlabeled_shapes.len(),
            result.stats.unlabeled_shapes.join(", ")
        );
    }
    let shares: Vec<String> = result
        .mds
        .variance_shares
        .iter()
        .map(|s| format!("{:.1}%", 100.0 * s))
        .collect();
    eprintln!(
        "mds: {} shapes, {} dims (variance {}), negative/positive eigenvalue mass {:.3}",
        result.names.len(),
        result.mds.dims(),
        shares.join(", "),
        result.stats.mds.negative_ratio
    );
    let m = &result.stats.mds;
    match m.smacof_iterations {
        Some(iterations) => eprintln!(
            "mds: SMACOF stress-1 {:.4} (raw {:.4e}) after {iterations} iterations, from the classical {:.4} (raw {:.4e})",
            m.stress.stress1, m.stress.raw, m.classical_stress.stress1, m.classical_stress.raw
        ),
        None => eprintln!("mds: stress-1 {:.4} (raw {:.4e})", m.stress.stress1, m.stress.raw),
    }
    for (col, s) in &result.stats.labels {
        eprintln!(
            "mds: {col}: 1-NN LOO accuracy {}, silhouette {}",
            s.loo_1nn.accuracy.map_or("n/a".into(), |a| format!(
                "{:.3} ({}/{})",
                a, s.loo_1nn.correct, s.loo_1nn.total
            )),
            s.silhouette.map_or("n/a".into(), |v| format!("{v:.3}"))
        );
    }
    if let Some(note) = &result.stats.cross_skipped {
        eprintln!("mds: {note}");
    }
    for c in &result.stats.cross {
        if let Some(a) = c.loo_1nn.accuracy {
            eprintln!(
                "mds: {} (neighbour with another {}): 1-NN accuracy {:.3}",
                c.target, c.exclude_same, a
            );
        }
    }
    for file in &result.files {
        eprintln!("mds: wrote {}", file.display());
    }
}
