//! One module per subcommand: its clap `Args` struct and a `run` that calls one library function.

pub mod conformal;
pub mod demo;
pub mod distances;
pub mod info;
pub mod markers;
pub mod mds;
pub mod ot;
pub mod ot_sphere;
pub mod param;
pub mod param_smds;
pub mod param_sphere_flows;
pub mod prepare;
pub mod register;

use std::path::Path;

/// Checks, before any work, that the output files given (`None`: an optional output not asked
/// for) can be created where they are named: not an existing folder, in a folder that exists
/// (so that a wrong path fails at once, not after minutes of computation with some outputs
/// written and others not), not a symbolic link (outputs are never written through links), not
/// one of the `inputs` (the same file under any name: an output must never replace an input)
/// and not named twice.
pub(crate) fn check_output_files<'a>(
    outputs: impl IntoIterator<Item = Option<&'a Path>>,
    inputs: impl IntoIterator<Item = Option<&'a Path>>,
) -> anyhow::Result<()> {
    let inputs: Vec<&Path> = inputs.into_iter().flatten().collect();
    let mut seen: Vec<&Path> = Vec::new();
    for file in outputs.into_iter().flatten() {
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
        check_output_path(file, &inputs)?;
        if let Some(other) = seen.iter().find(|o| same_file(o, file)) {
            anyhow::bail!(
                "{}: named for two outputs (also as {}); name different files",
                file.display(),
                other.display()
            );
        }
        seen.push(file);
    }
    Ok(())
}

/// Checks, before any work, the files `names` that a command writes into the folder `dir`:
/// none is a symbolic link or one of the `inputs` ([`check_output_files`]).
pub(crate) fn check_output_folder<'a>(
    dir: &Path,
    names: &[&str],
    inputs: impl IntoIterator<Item = Option<&'a Path>>,
) -> anyhow::Result<()> {
    let inputs: Vec<&Path> = inputs.into_iter().flatten().collect();
    for name in names {
        check_output_path(&dir.join(name), &inputs)?;
    }
    Ok(())
}

/// Refuses an output `file` that is a symbolic link or the same file as one of `inputs`.
fn check_output_path(file: &Path, inputs: &[&Path]) -> anyhow::Result<()> {
    if std::fs::symlink_metadata(file).is_ok_and(|m| m.file_type().is_symlink()) {
        anyhow::bail!(
            "{}: is a symbolic link; outputs are not written through links (remove it or name another file)",
            file.display()
        );
    }
    if let Some(input) = inputs.iter().find(|input| same_file(input, file)) {
        anyhow::bail!(
            "{}: is the input {}; an output must not replace an input (name another file)",
            file.display(),
            input.display()
        );
    }
    Ok(())
}

/// Whether `a` and `b` name the same file: the same device and inode where both exist (any
/// name, hard link or symbolic link of it), else the same canonical folder and file name.
fn same_file(a: &Path, b: &Path) -> bool {
    #[cfg(unix)]
    if let (Ok(ma), Ok(mb)) = (std::fs::metadata(a), std::fs::metadata(b)) {
        use std::os::unix::fs::MetadataExt;
        return (ma.dev(), ma.ino()) == (mb.dev(), mb.ino());
    }
    let canonical = |p: &Path| -> Option<std::path::PathBuf> {
        if let Ok(c) = p.canonicalize() {
            return Some(c);
        }
        let parent = p
            .parent()
            .filter(|q| !q.as_os_str().is_empty())
            .unwrap_or(Path::new("."));
        Some(parent.canonicalize().ok()?.join(p.file_name()?))
    };
    match (canonical(a), canonical(b)) {
        (Some(x), Some(y)) => x == y,
        _ => false,
    }
}

/// Creates an output folder before any work (an existing file of that name is an error).
/// Reads the mesh at `path` for a map onto the sphere: an error naming the file and the
/// reasons when it is not a closed genus-0 surface.
pub(crate) fn read_closed_mesh(path: &Path) -> anyhow::Result<shapespace_geometry::TriMesh> {
    let mesh = shapespace_geometry::io::read_mesh(path)?;
    let class = shapespace_geometry::topology::classify(&mesh)?;
    if class.class != shapespace_geometry::topology::MeshClass::Sphere {
        anyhow::bail!(
            "{} is not a closed genus-0 surface ({}), so it has no map onto the sphere: {}",
            path.display(),
            class.class,
            class.reasons.join("; ")
        );
    }
    Ok(mesh)
}

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

/// The conformal disk map's choices, as `shapespace conformal` offers them, for the commands
/// that map disks on the way (`distances`, `demo`, `param`, `register`).
#[derive(clap::Args, Clone, Debug)]
pub struct DiskMapArgs {
    /// Construction of the conformal disk map: `green` (Green's function and harmonic
    /// conjugate, with the BFF fallback and the region repair; default) or `bff` (boundary-first
    /// flattening alone; `conformal --method bff`).
    #[arg(long = "conformal", default_value = "green", value_parser = ["green", "bff"])]
    pub construction: String,
    /// Pole of the Green's function: `center` (at the center marker, default) or `central` (the
    /// vertex farthest from the boundary, then a Möbius map), as for `conformal`.
    #[arg(long, default_value = "center", value_parser = ["center", "central"])]
    pub pole: String,
    /// Use the plain cotangent Laplacian instead of the intrinsic Delaunay one (comparison only).
    #[arg(long)]
    pub no_intrinsic_delaunay: bool,
    /// Refuse a mesh whose Green's-function map folds after the local repair instead of falling
    /// back to BFF's map or re-embedding the folded region, as `conformal --no-bff-fallback`.
    #[arg(long)]
    pub no_bff_fallback: bool,
}

impl DiskMapArgs {
    /// The disk map's parameters these flags ask for (the library's defaults without flags).
    pub fn params(&self) -> shapespace_conformal::DiskMapParams {
        use shapespace_conformal::{Construction, DiskMapParams, PolePlacement};
        DiskMapParams {
            construction: if self.construction == "bff" {
                Construction::Bff
            } else {
                Construction::Green
            },
            pole: if self.pole == "central" {
                PolePlacement::Central
            } else {
                PolePlacement::AtCenter
            },
            intrinsic_delaunay: !self.no_intrinsic_delaunay,
            bff_fallback: !self.no_bff_fallback,
            region_repair: !self.no_bff_fallback,
            ..DiskMapParams::default()
        }
    }
}
