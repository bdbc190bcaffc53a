//! Shared by the scan benchmark and probe: the real scans of
//! `$SHAPESPACE_DATA/outside` (default: `../shared/datasets` beside the workspace), prepared
//! as `shapespace prepare` does (holes but the rim filled) and mapped as `shapespace distances`
//! maps them (markers `auto`). Files from public repositories are read from there, never
//! copied into the project.

use std::path::PathBuf;

use shapespace_analysis::distance::{prepare_shape, PreparedShape};
use shapespace_analysis::pipeline::{markers_for, MarkerOptions};
use shapespace_analysis::shared_markers::{share_auto_markers, MarkerInput};
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

/// The files prepared as `shapespace prepare` leaves them and mapped as `shapespace distances`
/// maps them, with the automatic markers shared by the files of one triangulation (chosen on
/// their mean shape, [`share_auto_markers`]); a file whose map fails is left out with a
/// message naming it.
pub fn prepared_set(files: &[PathBuf]) -> Vec<PreparedShape> {
    let meshes: Vec<(String, TriMesh)> = files
        .iter()
        .map(|f| (f.file_stem().unwrap().to_string_lossy().to_string(), disk_mesh(f)))
        .collect();
    let own: Vec<_> = files
        .iter()
        .zip(&meshes)
        .map(|(f, (_, m))| markers_for(f, &MarkerOptions::default(), m.num_vertices()).unwrap().0)
        .collect();
    let inputs: Vec<MarkerInput<'_>> = meshes
        .iter()
        .zip(&own)
        .map(|((name, mesh), markers)| MarkerInput { name, mesh, markers })
        .collect();
    let shared = share_auto_markers(&inputs);
    meshes
        .iter()
        .zip(own.iter().zip(shared))
        .filter_map(|((name, mesh), (own, shared))| {
            let markers = shared.map_or_else(|| own.clone(), |s| s.markers);
            match prepare_shape(name, mesh, &markers, &DiskMapParams::default()) {
                Ok(s) => Some(s),
                Err(e) => {
                    eprintln!(
                        "{name} left out: {}",
                        e.to_string().chars().take(100).collect::<String>()
                    );
                    None
                }
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
