//! Shared by the scan benchmark and probe: the real scans of
//! `$SHAPESPACE_DATA/outside` (default: `../shared/datasets` beside the workspace), prepared
//! as `shapespace prepare` does (holes but the rim filled) and mapped as `shapespace distances`
//! maps them (markers `auto`). Files from public repositories are read from there, never
//! copied into the project.

use std::path::PathBuf;

use shapespace_analysis::distance::{prepare_shape, Prepared, PreparedShape};
use shapespace_analysis::distances::inputs::{prepare_inputs, shape_names};
use shapespace_analysis::pipeline::{markers_for, DistancesOptions, MarkerOptions};
use shapespace_conformal::DiskMapParams;
use shapespace_geometry::prepare::{prepare_disk, PrepareOptions};
use shapespace_geometry::TriMesh;

/// `$SHAPESPACE_DATA`, else `../shared/datasets` beside the workspace.
pub fn data_dir() -> PathBuf {
    std::env::var_os("SHAPESPACE_DATA")
        .map(PathBuf::from)
        .unwrap_or_else(|| PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../../../shared/datasets"))
}

/// The files `outside/SUB/*.EXT` of the shared datasets folder, sorted by name; empty when
/// absent.
fn outside_files(sub: &str, ext: &str) -> Vec<PathBuf> {
    let mut files: Vec<PathBuf> = std::fs::read_dir(data_dir().join("outside").join(sub))
        .map(|d| {
            d.filter_map(|e| e.ok().map(|e| e.path()))
                .filter(|p| p.extension().is_some_and(|x| x == ext))
                .collect()
        })
        .unwrap_or_default();
    files.sort();
    files
}

/// The facefuns composite faces (30,204 vertices each), sorted by name; empty when absent.
pub fn facefuns_files() -> Vec<PathBuf> {
    outside_files("facefuns", "ply")
}

/// The Sumner & Popović face poses (29,299–29,300 vertices; one face in nine expressions, the
/// mouth a second boundary loop that `prepare` fills), sorted by name; empty when absent.
pub fn sumner_face_files() -> Vec<PathBuf> {
    outside_files("sumner_face_poses", "obj")
}

/// The files prepared as `shapespace prepare` leaves them, then mapped and prepared as
/// `shapespace distances` does ([`prepare_inputs`]: the automatic markers shared by the files
/// of one triangulation, chosen on their mean shape); a file whose map fails is left out with
/// a message naming it.
pub fn prepared_set(files: &[PathBuf]) -> Vec<PreparedShape> {
    let meshes: Vec<TriMesh> = files.iter().map(|f| disk_mesh(f)).collect();
    let names = shape_names(files);
    let prepared = prepare_inputs(
        files,
        Some(&meshes),
        &names,
        &DistancesOptions::default(),
        &|_, _, _| {},
    )
    .unwrap();
    prepared
        .shapes
        .into_iter()
        .zip(&prepared.inputs)
        .filter_map(|(shape, report)| match shape {
            Some(Prepared::Disk(shape)) => Some(*shape),
            _ => {
                let error = report.error.as_deref().unwrap_or("not a disk");
                eprintln!(
                    "{} left out: {}",
                    report.name,
                    error.chars().take(100).collect::<String>()
                );
                None
            }
        })
        .collect()
}

/// The file as `shapespace prepare` leaves it (a disk).
pub fn disk_mesh(path: &std::path::Path) -> TriMesh {
    let mesh = shapespace_geometry::io::read_mesh(path).unwrap();
    prepare_disk(&mesh, &PrepareOptions::default()).unwrap().0
}

/// `mesh` (read from `path`) mapped for the distances with the markers `shapespace distances`
/// resolves for `path` (`auto` for the scans), or the map's error.
pub fn prepared(name: &str, path: &std::path::Path, mesh: &TriMesh) -> Result<PreparedShape, String> {
    let (markers, _) = markers_for(path, &MarkerOptions::default(), mesh.num_vertices()).map_err(|e| e.to_string())?;
    prepare_shape(name, mesh, &markers, &DiskMapParams::default()).map_err(|e| e.to_string())
}
