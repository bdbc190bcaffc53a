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
