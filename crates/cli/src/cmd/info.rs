//! `shapespace info FILE...` (being written).

use std::process::ExitCode;

/// Arguments of `shapespace info`.
#[derive(clap::Args)]
pub struct InfoArgs {
    /// Mesh files (OBJ, OFF, PLY).
    #[arg(required = true)]
    pub files: Vec<std::path::PathBuf>,
    /// Print JSON instead of a table.
    #[arg(long)]
    pub json: bool,
}

pub fn run(_args: &InfoArgs) -> anyhow::Result<ExitCode> {
    anyhow::bail!("info is being written")
}
