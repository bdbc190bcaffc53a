//! `shapespace conformal IN --out OUT.obj [--domain auto|disk|sphere] [--center V|x,y,z|auto]
//! [--boundary-marker V|auto] [--landmarks FILE.json] [--sphere-markers P1,P2,P3]
//! [--rotation-markers A,B] [--factors OUT.csv] [--report OUT.json] [--pole center|central]
//! [--method green|bff]`:
//! the discrete Riemann map
//! of a disk-type mesh onto the unit disk ([`shapespace_conformal::disk_map()`], or boundary-first
//! flattening with `--method bff`, [`shapespace_conformal::bff_disk_map`], as a cross-check),
//! or the conformal map of a closed genus-0 mesh onto the unit sphere
//! ([`shapespace_conformal::sphere_map()`]); `--domain auto` (default) takes the sphere for a
//! closed mesh (no boundary edge) and the disk otherwise.
//!
//! Sphere outputs: OUT (.obj, .ply or .off) is the input mesh with every vertex position
//! replaced by its image on the unit sphere (same vertex order and faces); `--factors` writes
//! `vertex,x,y,z,lambda`. Normalization: `--sphere-markers P1,P2,P3` sends the three vertices to
//! the south pole, (1, 0, 0) and the north pole (0, 1, ∞ of the extended plane); otherwise
//! Möbius centering, with `--rotation-markers A,B` putting A at the south pole and B on the half
//! meridian y = 0, x > 0.
//!
//! Markers: a marker file (`--landmarks`, else the sidecar `NAME.landmarks.json` or
//! `landmarks.json` beside the mesh) gives the defaults; `--center` / `--boundary-marker`
//! override it; anything unspecified is `auto`. Outputs: OUT.obj is the input mesh with one
//! `vt u v` per vertex; `--factors` writes `vertex,u,v,lambda`; `--report` writes the quality
//! statistics, the method, the resolved markers and the timings as JSON.

use std::io::Write;
use std::path::{Path, PathBuf};
use std::process::ExitCode;
use std::time::Instant;

use super::markers::MarkerArgs;
use anyhow::{Context, Result};
use shapespace_conformal::quality::QualitySummary;
use shapespace_conformal::{bff_disk_map, disk_map, BffParams, DiskMapParams, PolePlacement};
use shapespace_geometry::io::{read_mesh, write_atomically, write_mesh, AtomicFile};

/// Arguments of `shapespace conformal`.
#[derive(clap::Args)]
pub struct ConformalArgs {
    /// Input mesh (OBJ, OFF, PLY): a disk, or a closed genus-0 surface for the sphere.
    pub input: PathBuf,
    /// Output mesh. Disk: .obj or .ply, the input mesh with per-vertex texture coordinates (the
    /// disk map). Sphere: .obj, .ply or .off, the input faces with every vertex position
    /// replaced by its image on the unit sphere.
    #[arg(long)]
    pub out: PathBuf,
    /// Target domain: `auto` (the sphere when the mesh is closed, else the disk), `disk` or
    /// `sphere` (closed genus-0 meshes only).
    #[arg(long, default_value = "auto", value_parser = ["auto", "disk", "sphere"])]
    pub domain: String,
    #[command(flatten)]
    pub sphere: SphereMarkerArgs,
    #[command(flatten)]
    pub markers: MarkerArgs,
    /// Write per-vertex `vertex,u,v,lambda` (disk) or `vertex,x,y,z,lambda` (sphere) as CSV (λ:
    /// log conformal factor, e^{2λ} = 3D one-ring area / image one-ring area, the surface scaled
    /// to the domain's area).
    #[arg(long)]
    pub factors: Option<PathBuf>,
    /// Write quality statistics, method, markers and timings as JSON.
    #[arg(long)]
    pub report: Option<PathBuf>,
    /// Pole of the Green's function: `center` (at the center marker, default) or `central`
    /// (the vertex farthest from the boundary, then a Möbius map; better when the center is
    /// close to the boundary).
    #[arg(long, default_value = "center", value_parser = ["center", "central"])]
    pub pole: String,
    /// Use the plain cotangent Laplacian instead of the intrinsic Delaunay one (comparison only).
    #[arg(long)]
    pub no_intrinsic_delaunay: bool,
    /// Construction: `green` (Green's function and harmonic conjugate, default) or `bff`
    /// (boundary-first flattening iterated to the circle; same normalization; a cross-check,
    /// compared in `docs/decisions/0001-green-function-disk-map.md`). `--pole` applies to `green` only.
    #[arg(long, default_value = "green", value_parser = ["green", "bff"])]
    pub method: String,
    /// With `green`: report folds that survive the local repair as an error instead of falling
    /// back to BFF's map or re-embedding the folded region (the Green's-function construction
    /// alone, for comparisons).
    #[arg(long)]
    pub no_bff_fallback: bool,
}

/// What the command writes, from either construction.
struct MapOutput {
    uv: Vec<[f64; 2]>,
    conformal_factor: Vec<f64>,
    face_densities: Vec<f64>,
    quality: QualitySummary,
    scale: f64,
    method: String,
    center: String,
    boundary_vertex: u32,
    intrinsic_flips: usize,
    fold_repairs: usize,
    seconds: f64,
    info: serde_json::Value,
}

fn write_factors(path: &Path, map: &MapOutput) -> Result<()> {
    let mut w = AtomicFile::create(path).with_context(|| format!("writing {}", path.display()))?;
    writeln!(w, "vertex,u,v,lambda")?;
    for (i, (z, l)) in map.uv.iter().zip(&map.conformal_factor).enumerate() {
        writeln!(w, "{i},{:?},{:?},{:?}", z[0], z[1], l)?;
    }
    w.commit().with_context(|| format!("writing {}", path.display()))?;
    Ok(())
}

/// The normalization of a sphere map (`conformal` and `param` with `--domain sphere`).
#[derive(clap::Args, Clone, Debug, Default)]
pub struct SphereMarkerArgs {
    /// Sphere: three distinct vertices `P1,P2,P3` sent to the south pole, (1, 0, 0) and the
    /// north pole (0, 1, ∞ of the extended plane), exactly. Default: Möbius centering.
    #[arg(long = "sphere-markers")]
    pub sphere_markers: Option<String>,
    /// Sphere with Möbius centering: two vertices `A,B`; A goes to the south pole and B onto
    /// the half meridian y = 0, x > 0 (without them the rotation is the construction's).
    #[arg(long = "rotation-markers")]
    pub rotation_markers: Option<String>,
}

impl SphereMarkerArgs {
    /// Whether either flag is given.
    pub fn is_given(&self) -> bool {
        self.sphere_markers.is_some() || self.rotation_markers.is_some()
    }

    /// The normalization the flags ask for (Möbius centering without them), for the sphere map
    /// of `input`; the disk's markers (`disk`) given as well are an error naming the file.
    pub fn normalization_for(
        &self,
        input: &Path,
        disk: &MarkerArgs,
    ) -> Result<shapespace_conformal::SphereNormalization> {
        if disk.center.is_some() || disk.boundary_marker.is_some() || disk.landmarks.is_some() {
            anyhow::bail!(
                "{}: --center, --boundary-marker and --landmarks are disk markers; the sphere takes --sphere-markers P1,P2,P3 or --rotation-markers A,B",
                input.display()
            );
        }
        use shapespace_conformal::SphereNormalization;
        Ok(match (&self.sphere_markers, &self.rotation_markers) {
            (Some(_), Some(_)) => anyhow::bail!("--sphere-markers and --rotation-markers exclude each other"),
            (Some(t), None) => {
                let v = parse_vertices(t, 3, "sphere-markers")?;
                SphereNormalization::ThreeMarkers([v[0], v[1], v[2]])
            }
            (None, Some(t)) => {
                let v = parse_vertices(t, 2, "rotation-markers")?;
                SphereNormalization::Centered {
                    rotation: Some([v[0], v[1]]),
                }
            }
            (None, None) => SphereNormalization::Centered { rotation: None },
        })
    }
}

/// Vertex indices `a,b,…` (exactly `n` of them) of the flag `flag`.
fn parse_vertices(text: &str, n: usize, flag: &str) -> Result<Vec<u32>> {
    let v: Vec<u32> = text
        .split(',')
        .map(|t| t.trim().parse::<u32>())
        .collect::<Result<_, _>>()
        .map_err(|_| anyhow::anyhow!("--{flag} {text:?}: expected {n} vertex indices separated by commas"))?;
    if v.len() != n {
        anyhow::bail!("--{flag} {text:?}: expected {n} vertex indices, got {}", v.len());
    }
    Ok(v)
}

/// The sphere route of [`run`].
fn run_sphere(args: &ConformalArgs, mesh: shapespace_geometry::TriMesh, t0: Instant) -> Result<ExitCode> {
    use shapespace_conformal::{sphere_map, SphereMapParams};
    let normalization = args.sphere.normalization_for(&args.input, &args.markers)?;
    let params = SphereMapParams {
        intrinsic_delaunay: !args.no_intrinsic_delaunay,
        normalization,
        ..Default::default()
    };
    let map =
        sphere_map(&mesh, &params).with_context(|| format!("mapping {} onto the sphere", args.input.display()))?;
    let mut out_mesh = mesh.clone();
    out_mesh.positions = map.positions.clone();
    out_mesh.uvs = None;
    write_mesh(&args.out, &out_mesh).with_context(|| format!("writing {}", args.out.display()))?;
    if let Some(p) = &args.factors {
        let mut w = AtomicFile::create(p).with_context(|| format!("writing {}", p.display()))?;
        writeln!(w, "vertex,x,y,z,lambda")?;
        for (i, (x, l)) in map.positions.iter().zip(&map.conformal_factor).enumerate() {
            writeln!(w, "{i},{:?},{:?},{:?},{:?}", x[0], x[1], x[2], l)?;
        }
        w.commit().with_context(|| format!("writing {}", p.display()))?;
    }
    let q = &map.quality;
    eprintln!(
        "{}: {} V, {} F, sphere ({} alternations, {} fold repairs); angle distortion mean {:.3}° p95 {:.3}°; Λ mean {:.3e}; {} flipped; {:.3} s",
        args.input.display(),
        mesh.num_vertices(),
        mesh.num_faces(),
        map.info.schwarz_iterations,
        map.info.fold_repairs,
        q.angle_distortion_deg.mean,
        q.angle_distortion_deg.p95,
        q.quasi_conformal_distortion.mean,
        q.num_flipped,
        map.info.timings.total
    );
    if let Some(p) = &args.report {
        let report = serde_json::json!({
            "input": args.input.display().to_string(),
            "output": args.out.display().to_string(),
            "domain": "sphere",
            "num_vertices": mesh.num_vertices(),
            "num_faces": mesh.num_faces(),
            "scale": map.scale,
            "info": map.info,
            "quality": map.quality,
            "face_density": shapespace_conformal::quality::Stats::of(&map.face_densities),
            "conformal_factor": shapespace_conformal::quality::Stats::of(&map.conformal_factor),
            "wall_seconds": t0.elapsed().as_secs_f64(),
        });
        let text = serde_json::to_string_pretty(&report)?;
        write_atomically(p, text.as_bytes()).with_context(|| format!("writing {}", p.display()))?;
    }
    Ok(ExitCode::SUCCESS)
}

/// Runs the subcommand.
pub fn run(args: &ConformalArgs) -> Result<ExitCode> {
    let t0 = Instant::now();
    super::check_output_files(
        [
            Some(args.out.as_path()),
            args.factors.as_deref(),
            args.report.as_deref(),
        ],
        [Some(args.input.as_path()), args.markers.landmarks.as_deref()],
    )?;
    // an unknown output extension is named before the input is read
    shapespace_geometry::io::MeshFormat::from_path(&args.out)?;
    if args.domain == "disk" {
        super::check_map_output(&args.out)?;
    }
    // (its errors name the file)
    let mut mesh = read_mesh(&args.input)?;
    let sphere = match args.domain.as_str() {
        "sphere" => true,
        "disk" => false,
        _ => shapespace_geometry::topology::mesh_report(&mesh)
            .map(|r| r.closed && r.num_faces > 0)
            .unwrap_or(false),
    };
    if sphere {
        return run_sphere(args, mesh, t0);
    }
    if args.sphere.is_given() {
        anyhow::bail!(
            "{}: --sphere-markers and --rotation-markers apply to the sphere map only (a closed genus-0 mesh, --domain sphere)",
            args.input.display()
        );
    }
    super::check_map_output(&args.out)?;
    shapespace_geometry::topology::require_disk(&mesh)
        .with_context(|| format!("{} is not usable for a disk map", args.input.display()))?;
    let (markers, marker_source) = args.markers.resolve(&args.input, mesh.num_vertices())?;
    let context = || format!("mapping {}", args.input.display());
    let map = if args.method == "bff" {
        let params = BffParams {
            intrinsic_delaunay: !args.no_intrinsic_delaunay,
            ..Default::default()
        };
        let map = bff_disk_map(&mesh, &markers, &params).with_context(context)?;
        MapOutput {
            center: map.info.markers.center.to_string(),
            boundary_vertex: map.info.markers.boundary_vertex,
            intrinsic_flips: map.info.intrinsic_flips,
            fold_repairs: map.info.fold_repairs,
            seconds: map.info.timings.total,
            method: map.info.method.clone(),
            info: serde_json::to_value(&map.info)?,
            uv: map.uv,
            conformal_factor: map.conformal_factor,
            face_densities: map.face_densities,
            quality: map.quality,
            scale: map.scale,
        }
    } else {
        let pole = if args.pole == "central" {
            PolePlacement::Central
        } else {
            PolePlacement::AtCenter
        };
        let params = DiskMapParams {
            intrinsic_delaunay: !args.no_intrinsic_delaunay,
            pole,
            bff_fallback: !args.no_bff_fallback,
            region_repair: !args.no_bff_fallback,
            ..Default::default()
        };
        let map = disk_map(&mesh, &markers, &params).with_context(context)?;
        MapOutput {
            center: map.info.markers.center.to_string(),
            boundary_vertex: map.info.markers.boundary_vertex,
            intrinsic_flips: map.info.intrinsic_flips,
            fold_repairs: map.info.fold_repairs,
            seconds: map.info.timings.total,
            method: map.info.method.to_string(),
            info: serde_json::to_value(&map.info)?,
            uv: map.uv,
            conformal_factor: map.conformal_factor,
            face_densities: map.face_densities,
            quality: map.quality,
            scale: map.scale,
        }
    };
    mesh.uvs = Some(map.uv.clone());
    write_mesh(&args.out, &mesh).with_context(|| format!("writing {}", args.out.display()))?;
    if let Some(p) = &args.factors {
        write_factors(p, &map)?;
    }
    let q = &map.quality;
    eprintln!(
        "{}: {} V, {} F, {}, center {}, boundary {}; {} intrinsic flips, {} fold repairs; Λ mean {:.3e} p95 {:.3e} max {:.3e}; {} flipped; {:.3} s",
        args.input.display(),
        mesh.num_vertices(),
        mesh.num_faces(),
        map.method,
        map.center,
        map.boundary_vertex,
        map.intrinsic_flips,
        map.fold_repairs,
        q.quasi_conformal_distortion.mean,
        q.quasi_conformal_distortion.p95,
        q.quasi_conformal_distortion.max,
        q.num_flipped,
        map.seconds
    );
    if let Some(p) = &args.report {
        let report = serde_json::json!({
            "input": args.input.display().to_string(),
            "output": args.out.display().to_string(),
            "marker_file": marker_source,
            "num_vertices": mesh.num_vertices(),
            "num_faces": mesh.num_faces(),
            "scale": map.scale,
            "method": map.method,
            "info": map.info,
            "quality": map.quality,
            "face_density": shapespace_conformal::quality::Stats::of(&map.face_densities),
            "conformal_factor": shapespace_conformal::quality::Stats::of(&map.conformal_factor),
            "wall_seconds": t0.elapsed().as_secs_f64(),
        });
        let text = serde_json::to_string_pretty(&report)?;
        write_atomically(p, text.as_bytes()).with_context(|| format!("writing {}", p.display()))?;
    }
    Ok(ExitCode::SUCCESS)
}
