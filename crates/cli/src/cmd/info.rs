//! `shapespace info FILE... [--json]`: one [`MeshReport`] per file (V, F, components, boundary
//! loops, χ, genus, manifoldness, orientation, area, disk/sphere class), as a table or as JSON.
//!
//! Every file is read even if another fails; failures print as `shapespace: <file>: <problem>`
//! on stderr and make the exit code 1.

use std::path::{Path, PathBuf};
use std::process::ExitCode;

use rayon::prelude::*;
use shapespace_geometry::io::read_mesh;
use shapespace_geometry::topology::{mesh_report, MeshClass, MeshReport};

/// Arguments of `shapespace info`.
#[derive(clap::Args)]
pub struct InfoArgs {
    /// Mesh files (OBJ, OFF, PLY).
    #[arg(required = true)]
    pub files: Vec<std::path::PathBuf>,
    /// Print JSON instead of a table (an array with one object per file: the report's fields
    /// and `file`, or `file` and `error`).
    #[arg(long)]
    pub json: bool,
}

/// The error text of a failed file, prefixed by the path unless the library already names it.
fn describe_error(path: &Path, err: &shapespace_geometry::GeometryError) -> String {
    let text = err.to_string();
    let shown = path.display().to_string();
    if text.starts_with(&shown) {
        text
    } else {
        format!("{shown}: {text}")
    }
}

/// Area with about six significant digits, without exponent for ordinary sizes.
fn format_area(area: f64) -> String {
    if area == 0.0 || !area.is_finite() {
        return format!("{area}");
    }
    let magnitude = area.abs().log10().floor();
    if (-3.0..7.0).contains(&magnitude) {
        format!("{:.*}", (5.0 - magnitude).max(0.0) as usize, area)
    } else {
        format!("{area:.5e}")
    }
}

fn yes_no(b: bool) -> &'static str {
    if b {
        "yes"
    } else {
        "no"
    }
}

fn print_table(rows: &[(PathBuf, MeshReport)]) {
    let header = [
        "file",
        "V",
        "F",
        "components",
        "loops",
        "χ",
        "genus",
        "manifold",
        "oriented",
        "area",
        "class",
    ];
    let cells: Vec<[String; 11]> = rows
        .iter()
        .map(|(path, r)| {
            [
                path.display().to_string(),
                r.num_vertices.to_string(),
                r.num_faces.to_string(),
                r.num_components.to_string(),
                r.num_boundary_loops.to_string(),
                r.euler_characteristic.to_string(),
                r.genus.to_string(),
                yes_no(r.manifold).to_string(),
                yes_no(r.consistently_oriented).to_string(),
                format_area(r.area),
                r.classification.class.to_string(),
            ]
        })
        .collect();
    let mut widths: Vec<usize> = header.iter().map(|h| h.chars().count()).collect();
    for row in &cells {
        for (w, c) in widths.iter_mut().zip(row) {
            *w = (*w).max(c.chars().count());
        }
    }
    let line = |row: &[String]| {
        let mut out = String::new();
        for (k, (c, &w)) in row.iter().zip(&widths).enumerate() {
            let pad = w - c.chars().count();
            if k == 0 || k >= 7 && k != 9 {
                // text columns left-aligned
                out.push_str(c);
                out.push_str(&" ".repeat(pad));
            } else {
                out.push_str(&" ".repeat(pad));
                out.push_str(c);
            }
            if k + 1 < row.len() {
                out.push_str("  ");
            }
        }
        out.trim_end().to_string()
    };
    println!("{}", line(&header.map(String::from)));
    for row in &cells {
        println!("{}", line(row));
    }
    // why the "other" meshes are neither disks nor spheres, and degenerate faces, which the
    // disk maps refuse whatever the class
    for (path, r) in rows {
        if r.classification.class == MeshClass::Other {
            println!("{}: {}", path.display(), r.classification.reasons.join("; "));
        }
        if let Some(f) = r.first_degenerate_faces.first() {
            println!(
                "{}: {} degenerate face{} (repeated vertex, or zero area), first face {f}",
                path.display(),
                r.num_degenerate_faces,
                if r.num_degenerate_faces == 1 { "" } else { "s" }
            );
        }
    }
}

/// Runs `shapespace info`: 0 if every file was read, 1 if any failed.
pub fn run(args: &InfoArgs) -> anyhow::Result<ExitCode> {
    let results: Vec<(PathBuf, Result<MeshReport, String>)> = args
        .files
        .par_iter()
        .map(|path| {
            // (a mesh outside the range the maps work in is refused as `conformal` refuses it,
            // rather than described with an area that overflows)
            let report = read_mesh(path)
                .and_then(|mesh| {
                    shapespace_geometry::topology::check_coordinate_range(&mesh)?;
                    mesh_report(&mesh)
                })
                .map_err(|e| describe_error(path, &e));
            (path.clone(), report)
        })
        .collect();
    let mut failed = 0;
    for (_, r) in &results {
        if let Err(message) = r {
            eprintln!("shapespace: {message}");
            failed += 1;
        }
    }
    if args.json {
        let mut out = Vec::with_capacity(results.len());
        for (path, r) in &results {
            let mut obj = serde_json::Map::new();
            obj.insert("file".into(), serde_json::Value::String(path.display().to_string()));
            match r {
                Ok(report) => {
                    if let serde_json::Value::Object(fields) = serde_json::to_value(report)? {
                        obj.extend(fields);
                    }
                }
                Err(message) => {
                    obj.insert("error".into(), serde_json::Value::String(message.clone()));
                }
            }
            out.push(serde_json::Value::Object(obj));
        }
        println!("{}", serde_json::to_string_pretty(&out)?);
    } else {
        let ok: Vec<(PathBuf, MeshReport)> = results
            .into_iter()
            .filter_map(|(p, r)| r.ok().map(|r| (p, r)))
            .collect();
        if !ok.is_empty() {
            print_table(&ok);
        }
    }
    Ok(if failed > 0 {
        ExitCode::from(1)
    } else {
        ExitCode::SUCCESS
    })
}
