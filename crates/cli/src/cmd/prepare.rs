//! `shapespace prepare IN --out OUT [--cut-center V|auto] [--cut-rings K] [--seam N]
//! [--vertex-map MAP.csv]`: a disk-topology mesh for the other commands, by the explicit
//! operations of [`shapespace_geometry::prepare::prepare_disk`] (drop unreferenced vertices, keep
//! the largest component, drop faces with a repeated vertex, orient consistently, repair
//! zero-area faces by edge flips, boundary-face removals and collapses, cut a disk out of a
//! closed surface, fill all holes
//! but the longest, optionally slit the disk from N extremities to its boundary, split the edges
//! between two boundary vertices when they cut interior vertices off).
//! Prints what it did.

use std::io::Write;
use std::path::PathBuf;
use std::process::ExitCode;

use anyhow::{bail, Context, Result};
use shapespace_geometry::io::{read_mesh, write_mesh, AtomicFile};
use shapespace_geometry::prepare::{prepare_disk, CutCenter, PrepareOptions, Radius};

/// Arguments of `shapespace prepare`.
#[derive(clap::Args)]
pub struct PrepareArgs {
    /// Input mesh (OBJ, OFF, PLY).
    pub input: PathBuf,
    /// Output mesh (format from the extension: .obj, .off, .ply).
    #[arg(long)]
    pub out: PathBuf,
    /// Centre of the disk cut out of a closed surface: a vertex index of the input, or `auto`
    /// (the vertex nearest the area-weighted centroid).
    #[arg(long, default_value = "auto")]
    pub cut_center: String,
    /// Size of that disk, in edge rings around the centre.
    #[arg(long, default_value_t = 3)]
    pub cut_rings: usize,
    /// Then slit the disk open along shortest edge paths from this many extremities (geodesic
    /// farthest points from the boundary) to the boundary. Whole bodies need it: without it a
    /// limb's conformal image shrinks exponentially and its points crowd beyond f64. `--seam 1`
    /// maps 24 of the 26 TOSCA meshes; the two David poses need `2` or `3` (their fingers)
    /// (README, "Your own meshes").
    #[arg(long, default_value_t = 0)]
    pub seam: usize,
    /// Also write CSV `vertex,input_vertex` (input_vertex empty for vertices added by hole
    /// filling or edge splits; a seam vertex's copies all name it), so per-vertex data and landmarks can follow.
    #[arg(long)]
    pub vertex_map: Option<PathBuf>,
}

pub fn run(args: &PrepareArgs) -> Result<ExitCode> {
    super::check_output_files(
        [Some(args.out.as_path()), args.vertex_map.as_deref()],
        [Some(args.input.as_path())],
    )?;
    let cut_center = match args.cut_center.trim() {
        "auto" => CutCenter::Auto,
        s => CutCenter::Vertex(
            s.parse()
                .with_context(|| format!("--cut-center {s:?}: expected a vertex index or `auto`"))?,
        ),
    };
    if args.cut_rings == 0 {
        bail!("--cut-rings must be at least 1");
    }
    let mesh = read_mesh(&args.input)?;
    let options = PrepareOptions {
        cut_center,
        cut_radius: Radius::Rings(args.cut_rings),
        seam_extremities: args.seam,
    };
    let (disk, origin, report) =
        prepare_disk(&mesh, &options).with_context(|| format!("{}: cannot make a disk", args.input.display()))?;
    write_mesh(&args.out, &disk)?;
    if let Some(path) = &args.vertex_map {
        let mut w = AtomicFile::create(path).with_context(|| format!("writing {}", path.display()))?;
        writeln!(w, "vertex,input_vertex")?;
        for (v, o) in origin.iter().enumerate() {
            match o {
                Some(o) => writeln!(w, "{v},{o}")?,
                None => writeln!(w, "{v},")?,
            }
        }
        w.commit().with_context(|| format!("writing {}", path.display()))?;
    }
    let mut steps = Vec::new();
    if report.unreferenced_dropped > 0 {
        steps.push(format!("dropped {} unreferenced vertices", report.unreferenced_dropped));
    }
    if report.faces_of_other_components_dropped > 0 {
        steps.push(format!(
            "dropped {} faces of smaller components",
            report.faces_of_other_components_dropped
        ));
    }
    if report.repeated_vertex_faces_dropped > 0 {
        steps.push(format!(
            "dropped {} faces with a repeated vertex",
            report.repeated_vertex_faces_dropped
        ));
    }
    if report.faces_flipped > 0 {
        steps.push(format!(
            "flipped {} faces to a consistent orientation",
            report.faces_flipped
        ));
    }
    if report.closed_components_turned_outward > 0 {
        steps.push("turned the closed surface's faces outward (they faced inward)".to_string());
    }
    let r = &report.degenerate_faces_repaired;
    if r.total() > 0 {
        let how: Vec<String> = [
            (r.flipped, "by an edge flip", "by edge flips"),
            (r.removed, "removed from the boundary", "removed from the boundary"),
            (
                r.collapsed,
                "by collapsing coincident vertices",
                "by collapsing coincident vertices",
            ),
        ]
        .iter()
        .filter(|(n, _, _)| *n > 0)
        .map(|&(n, one, many)| format!("{n} {}", if n == 1 { one } else { many }))
        .collect();
        steps.push(format!(
            "repaired {} degenerate face{} without moving a vertex ({})",
            r.total(),
            if r.total() == 1 { "" } else { "s" },
            how.join(", ")
        ));
    }
    if let Some(c) = report.cut_center {
        steps.push(format!(
            "cut a {}-ring disk ({} faces) around input vertex {c}",
            args.cut_rings, report.faces_cut
        ));
    }
    if report.holes_filled > 0 {
        steps.push(if report.holes_filled == 1 {
            "filled 1 hole (one vertex appended)".to_string()
        } else {
            format!("filled {} holes (one vertex appended per hole)", report.holes_filled)
        });
    }
    if report.seam_edges > 0 {
        steps.push(format!(
            "slit it along {} edges from input vertices [{}] to the boundary ({} vertices appended)",
            report.seam_edges,
            report
                .seam_extremities
                .iter()
                .map(|e| e.map_or("a hole-filling vertex".to_string(), |v| v.to_string()))
                .collect::<Vec<_>>()
                .join(", "),
            report.seam_vertices_added
        ));
    }
    if report.bridges_split > 0 {
        steps.push(format!(
            "split {} edges joining two boundary vertices, which cut interior vertices off from the rest (one vertex appended per edge)",
            report.bridges_split
        ));
    }
    if steps.is_empty() {
        steps.push("already a disk, unchanged".into());
    }
    eprintln!(
        "{}: {} V, {} F -> {}: {} V, {} F, a disk; {}",
        args.input.display(),
        mesh.num_vertices(),
        mesh.num_faces(),
        args.out.display(),
        disk.num_vertices(),
        disk.num_faces(),
        steps.join("; ")
    );
    Ok(ExitCode::SUCCESS)
}
