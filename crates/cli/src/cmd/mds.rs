//! `shapespace mds DIST.csv --out DIR [--labels labels.csv] [--dims 2] [--color-by COL] [--marker-by COL]`:
//! classical MDS of a distance matrix, with plots and shape-space statistics.

use std::path::PathBuf;
use std::process::ExitCode;

use anyhow::Context;
use shapespace_analysis::shape_space::{run_mds, MdsParams, MdsResult};

/// Arguments of `shapespace mds`.
#[derive(clap::Args)]
pub struct MdsArgs {
    /// Square distance matrix CSV (header `name,<names>`; empty or NaN cells are missing).
    pub distances: PathBuf,
    /// Output directory (mds.csv, eigenvalues.csv, mds.png, mds.svg, stats.json).
    #[arg(long)]
    pub out: PathBuf,
    /// Labels CSV: first column `file` or `name` (a shape name, or a file path ending with one), then label columns (an empty cell: unknown).
    #[arg(long)]
    pub labels: Option<PathBuf>,
    /// Number of MDS dimensions written to mds.csv (the plot shows the first two).
    #[arg(long, default_value_t = 2)]
    pub dims: usize,
    /// Label column for point colours (default: the first label column).
    #[arg(long)]
    pub color_by: Option<String>,
    /// Label column for marker shapes (default: the second label column, if any).
    #[arg(long)]
    pub marker_by: Option<String>,
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
    let params = MdsParams {
        dims: args.dims,
        color_by: args.color_by.clone(),
        marker_by: args.marker_by.clone(),
        cross_columns: args.cross_columns.clone(),
        ..MdsParams::default()
    };
    let result = run_mds(&args.distances, args.labels.as_deref(), &args.out, &params)
        .with_context(|| format!("mds of {}", args.distances.display()))?;
    print_summary(&result);
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
