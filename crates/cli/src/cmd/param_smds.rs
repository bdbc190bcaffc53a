//! `shapespace param IN --method spherical-mds --out OUT [--max-angle DEG] [--mds-landmarks K]
//! [--mds-start classical|conformal] [--refine-sweeps N] [--distance-power P] [--weights W.csv]
//! [--report R.json] [--plots DIR] [--no-fold-repair]`: the spherical MDS map of a closed genus-0
//! mesh onto the unit sphere ([`shapespace_analysis::spherical_mds::spherical_mds_map`]; Elad,
//! Keller & Kimmel 2005). OUT (.obj, .ply or .off) is the input mesh with every vertex moved to
//! its image on S²; the report has the stages' stress, iterations and timings and the distortion
//! block of the other sphere maps (|ε|, Υ, Λ, angle distortion, flips). Exit code 1 when faces
//! are still folded on the sphere (the map is written).

use std::process::ExitCode;
use std::time::Instant;

use anyhow::{Context, Result};
use shapespace_analysis::area_preserving::read_vertex_weights;
use shapespace_analysis::distortion::{sphere_map_distortion, DistortionReport};
use shapespace_analysis::spherical_mds::{spherical_mds_map, SphericalMdsParams, SphericalMdsStart};
use shapespace_geometry::io::write_mesh;

use super::param::{with_spinner, write_plots_and_report, ParamArgs};

/// `--mds-start` values.
#[derive(Clone, Copy, Debug, PartialEq, Eq, clap::ValueEnum)]
pub enum StartArg {
    /// Spherical classical scaling of the landmarks' target angles.
    Classical,
    /// The conformal sphere map.
    Conformal,
}

/// The options of `--method spherical-mds`.
#[derive(clap::Args, Clone, Debug, Default)]
pub struct SphericalMdsArgs {
    /// spherical-mds: the angle (degrees) the surface's largest geodesic distance becomes on the
    /// sphere (default 180: the farthest points antipodal; above 180 targets beyond 180° are
    /// clamped, laying the surface on a smaller sphere).
    #[arg(long = "max-angle")]
    pub max_angle: Option<f64>,
    /// spherical-mds: landmark vertices embedded first (default 500).
    #[arg(long = "mds-landmarks")]
    pub mds_landmarks: Option<usize>,
    /// spherical-mds: the landmarks' start (default classical).
    #[arg(long = "mds-start", value_enum)]
    pub mds_start: Option<StartArg>,
    /// spherical-mds: refinement sweeps over all vertices after the placement (default 0).
    #[arg(long = "refine-sweeps")]
    pub refine_sweeps: Option<usize>,
    /// spherical-mds: pair weights δ^(−P) (default 0, the plain stress).
    #[arg(long = "distance-power")]
    pub distance_power: Option<f64>,
}

impl SphericalMdsArgs {
    /// Whether any flag is given.
    pub fn is_given(&self) -> bool {
        self.max_angle.is_some()
            || self.mds_landmarks.is_some()
            || self.mds_start.is_some()
            || self.refine_sweeps.is_some()
            || self.distance_power.is_some()
    }
}

/// Runs `param --method spherical-mds`.
pub fn run(args: &ParamArgs, t0: Instant) -> Result<ExitCode> {
    let input = args.input.display();
    if args.domain() != "sphere" {
        anyhow::bail!(
            "{input}: --method spherical-mds maps onto the sphere only (got --domain {})",
            args.domain()
        );
    }
    if args.sphere.is_given()
        || args.markers.center.is_some()
        || args.markers.boundary_marker.is_some()
        || args.markers.landmarks.is_some()
    {
        anyhow::bail!("{input}: --method spherical-mds takes no markers (its map is defined up to a rotation)");
    }
    if args.disk_map.params() != shapespace_conformal::DiskMapParams::default() {
        anyhow::bail!("{input}: --conformal, --pole, --no-intrinsic-delaunay and --no-bff-fallback choose the disk map; they do not apply to --method spherical-mds");
    }
    if args.start != super::ot::StartArg::Auto {
        anyhow::bail!("{input}: --start chooses the OT's start; --method spherical-mds takes --mds-start");
    }
    super::check_output_files(
        [Some(args.out.as_path()), args.report.as_deref()],
        [Some(args.input.as_path()), args.weights.as_deref()],
    )?;
    if let Some(dir) = &args.plots {
        super::create_output_folder(dir)?;
    }
    // an unknown output extension is named before the input is read
    shapespace_geometry::io::MeshFormat::from_path(&args.out)?;
    let mesh = super::read_closed_mesh(&args.input)?;
    let defaults = SphericalMdsParams::default();
    let params = SphericalMdsParams {
        max_angle: args.smds.max_angle.map_or(defaults.max_angle, f64::to_radians),
        start: match args.smds.mds_start {
            None | Some(StartArg::Classical) => SphericalMdsStart::Classical,
            Some(StartArg::Conformal) => SphericalMdsStart::Conformal,
        },
        landmarks: args.smds.mds_landmarks.unwrap_or(defaults.landmarks),
        refine_sweeps: args.smds.refine_sweeps.unwrap_or(defaults.refine_sweeps),
        distance_power: args.smds.distance_power.unwrap_or(defaults.distance_power),
        weights: match &args.weights {
            Some(p) => Some(read_vertex_weights(p, mesh.num_vertices())?),
            None => None,
        },
        fold_repair: !args.no_fold_repair,
        ..defaults
    };
    let message = format!("spherical MDS map of {input} ({} vertices)", mesh.num_vertices());
    let map = with_spinner(message, || spherical_mds_map(&mesh, &params))
        .with_context(|| format!("mapping {input} onto the sphere"))?;
    let mut out_mesh = mesh.clone();
    out_mesh.positions = map.positions.clone();
    out_mesh.uvs = None;
    write_mesh(&args.out, &out_mesh).with_context(|| format!("writing {}", args.out.display()))?;
    let report = DistortionReport {
        num_vertices: mesh.num_vertices(),
        num_faces: mesh.num_faces(),
        maps: vec![sphere_map_distortion("spherical-mds", &mesh, &map.positions)?],
    };
    let d = &report.maps[0];
    let info = &map.info;
    let repair = match &info.fold_repair {
        None if info.flipped_before_repair == 0 => "no folded faces".to_string(),
        None => format!("{} folded faces (fold repair off)", info.flipped_before_repair),
        Some(r) => format!(
            "fold repair: {} folded before, {} after, {} vertices moved in {} of {} charts",
            info.flipped_before_repair, info.num_flipped, r.vertices_moved, r.repaired, r.clusters
        ),
    };
    eprintln!(
        "{input}: {} V, {} F; spherical MDS on {} landmarks ({} SMACOF iterations, stress-1 {:.3e}), {:.1} Gauss-Newton steps per placed vertex; |ε| median {:.3e} p95 {:.3e}; angle distortion median {:.2}° p95 {:.2}°; {} flipped; {repair}; geodesics {:.2} s, landmarks {:.2} s, placement {:.2} s, output {:.2} s",
        mesh.num_vertices(),
        mesh.num_faces(),
        info.num_landmarks,
        info.landmark_smacof.iterations,
        info.landmark_smacof.stress1,
        info.placement_mean_steps,
        d.abs_vertex_log_area_ratio.median,
        d.abs_vertex_log_area_ratio.p95,
        d.angle_distortion_deg.median,
        d.angle_distortion_deg.p95,
        d.num_flipped + d.num_degenerate,
        map.timings.geodesics,
        map.timings.landmarks,
        map.timings.placement,
        map.timings.output,
    );
    write_plots_and_report(args, &report, || {
        serde_json::json!({
            "input": args.input.display().to_string(),
            "output": args.out.display().to_string(),
            "method": "spherical-mds",
            "domain": "sphere",
            "weights": args.weights.as_ref().map(|p| p.display().to_string()),
            "num_vertices": mesh.num_vertices(),
            "num_faces": mesh.num_faces(),
            "spherical_mds": info,
            "landmarks": map.landmarks,
            "flipped_before_repair": info.flipped_before_repair,
            "fold_repair": info.fold_repair,
            "num_flipped": info.num_flipped,
            "timings": map.timings,
            "wall_seconds": t0.elapsed().as_secs_f64(),
            "distortion": report,
        })
    })?;
    if info.num_flipped > 0 {
        eprintln!(
            "shapespace: {input}: {} faces are folded on the sphere; the map was written",
            info.num_flipped
        );
        return Ok(ExitCode::from(1));
    }
    Ok(ExitCode::SUCCESS)
}
