//! One module per subcommand: its clap `Args` struct and a `run` that calls one library function.

pub mod conformal;
pub mod demo;
pub mod distances;
pub mod info;
pub mod markers;
pub mod mds;
pub mod ot;
pub mod param;
pub mod prepare;
pub mod register;

/// Checks, before any work, that the output files given (`None`: an optional output not asked
/// for) can be created where they are named: not an existing folder, and in a folder that
/// exists (so that a wrong path fails at once, not after minutes of computation with some
/// outputs written and others not).
pub(crate) fn check_output_files<'a>(
    files: impl IntoIterator<Item = Option<&'a std::path::Path>>,
) -> anyhow::Result<()> {
    for file in files.into_iter().flatten() {
        if file.is_dir() {
            anyhow::bail!("{}: is a folder; name an output file", file.display());
        }
        let parent = file.parent().filter(|p| !p.as_os_str().is_empty());
        if let Some(parent) = parent.filter(|p| !p.is_dir()) {
            anyhow::bail!(
                "{}: cannot write there: the folder {} does not exist",
                file.display(),
                parent.display()
            );
        }
    }
    Ok(())
}

/// Creates an output folder before any work (an existing file of that name is an error).
pub(crate) fn create_output_folder(dir: &std::path::Path) -> anyhow::Result<()> {
    use anyhow::Context;
    if dir.exists() && !dir.is_dir() {
        anyhow::bail!("{}: exists and is not a folder", dir.display());
    }
    std::fs::create_dir_all(dir).with_context(|| format!("creating the folder {}", dir.display()))
}

/// Checks, before any work, that `out` names a mesh format that stores per-vertex texture
/// coordinates (the map): `.obj` (`vt` lines) or `.ply` (`u`, `v` vertex properties). OFF has
/// no texture coordinates, and any other extension no writer; both are errors naming the file.
pub(crate) fn check_map_output(out: &std::path::Path) -> anyhow::Result<()> {
    use shapespace_geometry::io::MeshFormat;
    match MeshFormat::from_path(out)? {
        MeshFormat::Obj | MeshFormat::Ply => Ok(()),
        MeshFormat::Off => anyhow::bail!(
            "{}: OFF files cannot store the map's per-vertex texture coordinates; write .obj or .ply",
            out.display()
        ),
    }
}
