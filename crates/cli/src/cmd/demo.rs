//! `shapespace demo`: the main job on the bundled faces: distances, MDS and statistics.

use std::path::PathBuf;
use std::process::ExitCode;

use super::distances::{check_labels, check_outputs, compute, exit_code, mds_unless_failed, SolverArgs};

/// Arguments of `shapespace demo`.
#[derive(clap::Args)]
pub struct DemoArgs {
    /// Folder with the faces, their `landmarks.json` and `labels.csv`.
    #[arg(long, default_value = "datasets/faces")]
    pub data: PathBuf,
    /// Output folder.
    #[arg(long, default_value = "out/demo")]
    pub out: PathBuf,
    #[command(flatten)]
    pub solver: SolverArgs,
}

pub fn run(args: &DemoArgs) -> anyhow::Result<ExitCode> {
    let mut files: Vec<PathBuf> = std::fs::read_dir(&args.data)
        .map_err(|e| {
            anyhow::anyhow!(
                "{}: {e} (run the demo from the repository root, or pass --data)",
                args.data.display()
            )
        })?
        .filter_map(|e| e.ok().map(|e| e.path()))
        .filter(|p| p.extension().is_some_and(|x| x.eq_ignore_ascii_case("obj")))
        .collect();
    files.sort();
    if files.len() < 2 {
        anyhow::bail!("{}: fewer than 2 OBJ meshes", args.data.display());
    }
    eprintln!(
        "demo: {} faces from {} -> {}",
        files.len(),
        args.data.display(),
        args.out.display()
    );
    // (a labels file that does not match the faces fails now, not after the distances)
    let labels = args.data.join("labels.csv");
    let labels = labels.is_file().then_some(labels);
    if let Some(labels) = &labels {
        check_labels(labels, &files)?;
    }
    check_outputs(&args.out, &files, labels.as_deref(), &args.solver, true)?;
    let run = compute(&files, &args.out, &args.solver)?;
    mds_unless_failed(&run, &args.out, labels.as_deref())?;
    Ok(exit_code(&run))
}
