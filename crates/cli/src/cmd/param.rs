//! `shapespace param IN --out OUT.obj [--center V|x,y,z|auto] [--boundary-marker V|auto]
//! [--landmarks FILE.json] [--domain disk|square|sphere] [--weights W.csv] [--report R.json]
//! [--plots DIR] [--no-fold-repair] [--method omt|lie|flow]`: the area-preserving parameterization of a disk-type mesh by optimal mass
//! transport ([`shapespace_analysis::area_preserving::area_preserving_map`]), or with
//! `--domain sphere` of a closed genus-0 mesh onto the unit sphere
//! ([`shapespace_analysis::sphere_param::area_preserving_sphere_map`]; normalized by
//! `--sphere-markers` or `--rotation-markers` as in `shapespace conformal`; OUT (.obj, .ply or
//! .off) is the input mesh with every vertex moved to its image on S²).
//!
//! Markers as in `shapespace conformal` (marker file, else sidecar, then `--center` /
//! `--boundary-marker` overrides). OUT.obj is the input mesh with one `vt u v` per vertex.
//! `--weights` reads `vertex,weight` rows (missing vertices weigh 1). `--report` writes the OT
//! summary, timings and the side-by-side distortion of the conformal and the area-preserving
//! map (per face Υ, Λ, angle; per vertex ε; statistics; flips) as JSON; `--plots` writes the
//! distortion histograms (PNG and SVG). The fold repair after the centroid map is on unless
//! `--no-fold-repair`; the report's `fold_repair` gives the folded faces before, the vertices
//! moved, the rounds and the distortion before and after. Exit code 1 when the OT solver did not reach its
//! tolerance (the map of its last iterate is still written).
//!
//! `--method lie` computes the authalic map by Lie advection instead
//! ([`shapespace_analysis::lie_advection::lie_advection_map`]; no weights); its
//! report has the same distortion block, with the flow's steps and timings in place of the OT
//! summary. Exit code 1 when its fold repair failed (the map is written with its folds).
//!
//! `--method spherical-mds` maps a closed genus-0 mesh onto the unit sphere by spherical
//! multidimensional scaling of its geodesic distances
//! ([`shapespace_analysis::spherical_mds::spherical_mds_map`]; Elad, Keller & Kimmel 2005;
//! `param_smds`).
//!
//! `--method flow` computes the L²-optimal map by the Angenent–Haker–Tannenbaum gradient flow
//! ([`shapespace_analysis::gradient_flow::gradient_flow_map`]; Dominitz & Tannenbaum 2010; no
//! weights) with their multiresolution scheme: `--flow-levels` coarse levels (default 2,
//! [`shapespace_analysis::multiresolution`]) give the flow on the mesh its start, or with
//! `--flow-levels 0` (or when the prolonged map, or its Moser correction, keeps folds after
//! the fold repair) the Lie-advection map does; its report
//! has the same distortion block, with the levels, the flow's steps, curl norms and
//! transport costs. With `--domain sphere` (the
//! default for these two on a closed genus-0 input) both map onto the sphere instead
//! ([`shapespace_analysis::sphere_flows`]; `param_sphere_flows`).

use std::path::PathBuf;
use std::process::ExitCode;
use std::sync::mpsc;
use std::time::{Duration, Instant};

use super::markers::MarkerArgs;
use anyhow::{Context, Result};
use indicatif::{ProgressBar, ProgressDrawTarget, ProgressStyle};
use shapespace_analysis::area_preserving::{area_preserving_map, read_vertex_weights, AreaPreservingParams, Domain};
use shapespace_analysis::distortion::distortion_report;
use shapespace_analysis::gradient_flow::{gradient_flow_map, GradientFlowParams};
use shapespace_analysis::lie_advection::{lie_advection_map, LieAdvectionParams};
use shapespace_analysis::plot::write_distortion_histograms;
use shapespace_geometry::io::{read_mesh, write_atomically, write_mesh};

/// `--method` values.
#[derive(Clone, Copy, Debug, PartialEq, Eq, clap::ValueEnum)]
pub enum ParamMethod {
    /// Conformal map + semi-discrete OT by Newton's method (Su et al. 2015).
    Omt,
    /// Conformal map + Lie advection of the area form (Zou et al. 2011; disk or sphere).
    Lie,
    /// Conformal map + Lie advection + the Angenent–Haker–Tannenbaum gradient flow to the
    /// L²-optimal map (Dominitz & Tannenbaum 2010; disk or sphere).
    Flow,
    /// Spherical multidimensional scaling of the heat-method geodesic distances (Elad, Keller
    /// & Kimmel 2005; sphere only).
    SphericalMds,
}

impl ParamMethod {
    pub(super) fn name(self) -> &'static str {
        match self {
            ParamMethod::Omt => "omt",
            ParamMethod::Lie => "lie",
            ParamMethod::Flow => "flow",
            ParamMethod::SphericalMds => "spherical-mds",
        }
    }
}

/// Arguments of `shapespace param`.
#[derive(clap::Args)]
pub struct ParamArgs {
    /// Input mesh (OBJ, OFF, PLY) with disk topology (closed genus-0 for `--domain sphere`).
    pub input: PathBuf,
    /// Output mesh (.obj or .ply): the input mesh with per-vertex texture coordinates (the area-preserving map).
    #[arg(long)]
    pub out: PathBuf,
    #[command(flatten)]
    pub markers: MarkerArgs,
    #[command(flatten)]
    pub sphere: super::conformal::SphereMarkerArgs,
    #[command(flatten)]
    pub disk_map: super::DiskMapArgs,
    /// `omt` (default): the Newton OMT map; `lie`: the Lie-advection authalic map; `flow`: the
    /// OMT map by the gradient flow from the Lie map (`lie` and `flow`: disk, or sphere on a
    /// closed input); `spherical-mds`: spherical MDS of the geodesic distances (sphere only).
    #[arg(long, value_enum, default_value_t = ParamMethod::Omt)]
    pub method: ParamMethod,
    /// Target domain: `disk` (unit disk, the default), `square` (side √π, centered at 0) or
    /// `sphere` (the unit sphere, for a closed genus-0 mesh; the default of `spherical-mds`, and
    /// of `lie` and `flow` on a closed genus-0 input).
    #[arg(long)]
    pub domain: Option<String>,
    #[command(flatten)]
    pub smds: super::param_smds::SphericalMdsArgs,
    /// Importance weights: CSV with header and rows `vertex,weight` (unlisted vertices: 1).
    #[arg(long)]
    pub weights: Option<PathBuf>,
    /// Write the OT summary, timings and distortion report as JSON.
    #[arg(long)]
    pub report: Option<PathBuf>,
    /// Write distortion histograms (PNG and SVG) into this directory.
    #[arg(long)]
    pub plots: Option<PathBuf>,
    /// OT tolerance on max_i |cell area − target| / target.
    #[arg(long, default_value_t = 1e-6)]
    pub tolerance: f64,
    /// Keep the single-shot centroid map (no repair of folded triangles).
    #[arg(long = "no-fold-repair")]
    pub no_fold_repair: bool,
    /// Initial OT heights: `auto` (coarse-to-fine when a Voronoi cell has < 1e-8 of its target,
    /// as where the conformal image crowds points, or > 100 times it, else Voronoi), `voronoi`,
    /// `coarse-to-fine`.
    #[arg(long, value_enum, default_value_t = super::ot::StartArg::Auto)]
    pub start: super::ot::StartArg,
    /// `--method flow`: coarse levels of Dominitz & Tannenbaum's multiresolution scheme run
    /// before the flow on the mesh; their prolonged, Moser-corrected map is its start (0: the
    /// single-level flow from the Lie map, which on real meshes stalls at that start).
    #[arg(long = "flow-levels", default_value_t = 2)]
    pub flow_levels: usize,
}

impl ParamArgs {
    /// `--domain`, or its default: `sphere` for `--method spherical-mds`, else `disk`.
    pub fn domain(&self) -> &str {
        match (&self.domain, self.method) {
            (Some(d), _) => d,
            (None, ParamMethod::SphericalMds) => "sphere",
            (None, _) => "disk",
        }
    }
}

/// Runs `f` on a worker thread; when it takes more than a second, shows a spinner with
/// `message` on stderr until it finishes.
pub(super) fn with_spinner<T: Send>(message: String, f: impl FnOnce() -> T + Send) -> T {
    std::thread::scope(|scope| {
        let (tx, rx) = mpsc::channel::<()>();
        let worker = scope.spawn(move || {
            let out = f();
            let _ = tx.send(());
            out
        });
        let mut spinner: Option<ProgressBar> = None;
        loop {
            match rx.recv_timeout(Duration::from_millis(if spinner.is_some() { 100 } else { 1000 })) {
                Ok(()) | Err(mpsc::RecvTimeoutError::Disconnected) => break,
                Err(mpsc::RecvTimeoutError::Timeout) => {
                    let bar = spinner.get_or_insert_with(|| {
                        let bar = ProgressBar::with_draw_target(None, ProgressDrawTarget::stderr());
                        bar.set_style(
                            ProgressStyle::with_template("{spinner} {msg} ({elapsed})")
                                .unwrap_or_else(|_| ProgressStyle::default_spinner()),
                        );
                        bar.set_message(message.clone());
                        bar
                    });
                    bar.tick();
                }
            }
        }
        if let Some(bar) = spinner {
            bar.finish_and_clear();
        }
        match worker.join() {
            Ok(out) => out,
            Err(panic) => std::panic::resume_unwind(panic),
        }
    })
}

/// Runs the subcommand.
pub fn run(args: &ParamArgs) -> Result<ExitCode> {
    let t0 = Instant::now();
    if args.method == ParamMethod::SphericalMds {
        return super::param_smds::run(args, t0);
    }
    if args.smds.is_given() {
        anyhow::bail!(
            "{}: --max-angle, --mds-landmarks, --mds-start, --refine-sweeps and --distance-power apply to --method spherical-mds only",
            args.input.display()
        );
    }
    // `lie` and `flow` map a closed genus-0 input onto the sphere unless told otherwise
    let sphere = match (&args.domain, args.method) {
        (Some(d), _) => d == "sphere",
        (None, ParamMethod::Lie | ParamMethod::Flow) => closed_genus_zero(&args.input),
        (None, _) => false,
    };
    if !sphere {
        super::check_map_output(&args.out)?;
    }
    super::check_output_files(
        [Some(args.out.as_path()), args.report.as_deref()],
        [
            Some(args.input.as_path()),
            args.weights.as_deref(),
            args.markers.landmarks.as_deref(),
        ],
    )?;
    if let Some(dir) = &args.plots {
        super::create_output_folder(dir)?;
    }
    if sphere {
        if args.disk_map.params() != shapespace_conformal::DiskMapParams::default() {
            anyhow::bail!(
                "{}: --conformal, --pole, --no-intrinsic-delaunay and --no-bff-fallback choose the disk map; they do not apply to --domain sphere",
                args.input.display()
            );
        }
        if args.method != ParamMethod::Omt {
            return super::param_sphere_flows::run(args, t0);
        }
        return run_sphere(args, t0);
    }
    if args.sphere.is_given() {
        anyhow::bail!(
            "{}: --sphere-markers and --rotation-markers apply to --domain sphere only",
            args.input.display()
        );
    }
    let domain: Domain = args.domain().parse()?;
    // (its errors name the file)
    let mut mesh = read_mesh(&args.input)?;
    shapespace_geometry::topology::require_disk(&mesh)
        .with_context(|| format!("{} is not usable for a disk parameterization", args.input.display()))?;
    let (markers, marker_source) = args.markers.resolve(&args.input, mesh.num_vertices())?;
    if args.method != ParamMethod::Omt {
        let name = args.method.name();
        if domain != Domain::Disk {
            anyhow::bail!(
                "--method {name} maps onto the disk only (got --domain {})",
                args.domain()
            );
        }
        if args.weights.is_some() {
            anyhow::bail!("--method {name} takes no --weights (the Newton OMT map does)");
        }
        if args.method == ParamMethod::Flow {
            return run_flow(args, mesh, markers, marker_source, t0);
        }
        return run_lie(args, mesh, markers, marker_source, t0);
    }
    let weights = match &args.weights {
        Some(p) => Some(read_vertex_weights(p, mesh.num_vertices())?),
        None => None,
    };
    let mut params = AreaPreservingParams {
        domain,
        weights,
        require_convergence: false,
        disk_map: args.disk_map.params(),
        ..Default::default()
    };
    params.newton.tolerance = args.tolerance;
    params.newton.start_strategy = args.start.strategy();
    params.fold_repair.enabled = !args.no_fold_repair;
    let message = format!(
        "area-preserving map of {} ({} vertices)",
        args.input.display(),
        mesh.num_vertices()
    );
    let map = match with_spinner(message, || area_preserving_map(&mesh, &markers, &params)) {
        Ok(map) => map,
        Err(e) => {
            if mentions_crowding(&e) {
                print_seam_hint();
            }
            return Err(e).with_context(|| format!("parameterizing {}", args.input.display()));
        }
    };
    mesh.uvs = Some(map.uv.clone());
    write_mesh(&args.out, &mesh).with_context(|| format!("writing {}", args.out.display()))?;

    let report = distortion_report(&mesh, &map.conformal.uv, &map.uv)?;
    let ap = &report.maps[1];
    eprintln!(
        "{}: {} V, {} F; OT {} after {} iterations (max rel. mass error {:.2e}); |Υ| median {:.3e} p95 {:.3e} (conformal {:.3e} / {:.3e}); Λ median {:.3e}; {} flipped; {}; conformal {:.2} s, OT {:.2} s, output {:.2} s, repair {:.2} s",
        args.input.display(),
        mesh.num_vertices(),
        mesh.num_faces(),
        map.ot.stop,
        map.ot.iterations,
        map.ot.max_relative_error,
        ap.abs_area_distortion.median,
        ap.abs_area_distortion.p95,
        report.maps[0].abs_area_distortion.median,
        report.maps[0].abs_area_distortion.p95,
        ap.quasi_conformal_distortion.median,
        ap.num_flipped,
        repair_summary(&map.fold_repair.info),
        map.timings.conformal,
        map.timings.ot,
        map.timings.output,
        map.timings.repair,
    );
    if let Some(fallback) = &map.conformal.info.bff_fallback {
        eprintln!(
            "{}: the conformal map is BFF's: the Green's-function map folded {} faces that its repair could not fix",
            args.input.display(),
            fallback.green_folds
        );
    }
    if map.boundary_vertices_reordered > 0 {
        eprintln!(
            "{}: {} boundary edges of the centroid map turned backwards around the origin; {} boundary vertices were moved along the domain's boundary to restore their order",
            args.input.display(),
            map.boundary_order_violations,
            map.boundary_vertices_reordered
        );
    }
    if map.square_rotation != 0.0 {
        eprintln!(
            "{}: boundary ears (faces with three boundary corners) fell flat on a side of the square; the conformal image was turned by {:.4} rad before the OT so that the square's corners fall inside them",
            args.input.display(),
            map.square_rotation
        );
    }
    let flat = map.fold_repair.info.flat_boundary_faces;
    if flat > 0 {
        eprintln!(
            "{}: {flat} boundary ears (faces with three boundary corners) lie flat on a side of the square: no move of interior vertices can unfold them, so they stay degenerate in the map (the square has 4 corners for them; --domain disk has none of this, or split those faces)",
            args.input.display()
        );
    }
    write_plots_and_report(args, &report, || {
        report_json(
            args,
            "omt",
            &marker_source,
            &map.conformal,
            &mesh,
            map.domain,
            serde_json::json!({
                "weights": args.weights.as_ref().map(|p| p.display().to_string()),
                "ot": map.ot,
                "max_boundary_projection": map.max_boundary_projection,
                "boundary_order_violations": map.boundary_order_violations,
                "boundary_vertices_reordered": map.boundary_vertices_reordered,
                "square_rotation": map.square_rotation,
                "fold_repair": map.fold_repair,
                "timings": map.timings,
                "wall_seconds": t0.elapsed().as_secs_f64(),
                "distortion": report,
            }),
        )
    })?;
    if !map.ot.converged {
        eprintln!(
            "shapespace: {}: OT did not converge ({}); the map of the last iterate was written",
            args.input.display(),
            map.ot.stop
        );
        if map.ot.stop.contains("crowded") {
            print_seam_hint();
        }
        return Ok(ExitCode::from(1));
    }
    Ok(ExitCode::SUCCESS)
}

/// `--method lie`: the Lie-advection map, its summary line and report.
fn run_lie(
    args: &ParamArgs,
    mut mesh: shapespace_geometry::TriMesh,
    markers: shapespace_conformal::Markers,
    marker_source: String,
    t0: Instant,
) -> Result<ExitCode> {
    let mut params = LieAdvectionParams::default();
    params.fold_repair.enabled = !args.no_fold_repair;
    params.disk_map = args.disk_map.params();
    let message = format!(
        "Lie-advection map of {} ({} vertices)",
        args.input.display(),
        mesh.num_vertices()
    );
    let map = with_spinner(message, || lie_advection_map(&mesh, &markers, &params))
        .with_context(|| format!("parameterizing {}", args.input.display()))?;
    mesh.uvs = Some(map.uv.clone());
    write_mesh(&args.out, &mesh).with_context(|| format!("writing {}", args.out.display()))?;
    let report = distortion_report(&mesh, &map.conformal.uv, &map.uv)?;
    let lie = &report.maps[1];
    let correction = map.info.correction.summary();
    eprintln!(
        "{}: {} V, {} F; Lie advection {:.1} steps per vertex (max {}); {}; |Υ| median {:.3e} p95 {:.3e} (conformal {:.3e} / {:.3e}); Λ median {:.3e}; {} flipped; {}; conformal {:.2} s, advection {:.2} s, repair {:.2} s, correction {:.2} s",
        args.input.display(),
        mesh.num_vertices(),
        mesh.num_faces(),
        map.info.mean_steps,
        map.info.max_steps,
        correction,
        lie.abs_area_distortion.median,
        lie.abs_area_distortion.p95,
        report.maps[0].abs_area_distortion.median,
        report.maps[0].abs_area_distortion.p95,
        lie.quasi_conformal_distortion.median,
        lie.num_flipped,
        repair_summary(&map.info.fold_repair),
        map.timings.conformal,
        map.timings.advection,
        map.timings.repair,
        map.timings.correction,
    );
    if let Some(e) = &map.info.fold_repair_error {
        eprintln!(
            "{}: the fold repair failed ({e}); the advected map was written with its {} folded faces",
            args.input.display(),
            lie.num_flipped + lie.num_degenerate
        );
    }
    write_plots_and_report(args, &report, || {
        report_json(
            args,
            "lie",
            &marker_source,
            &map.conformal,
            &mesh,
            Domain::Disk,
            serde_json::json!({
                "lie_advection": map.info,
                "fold_repair": map.info.fold_repair,
                "timings": map.timings,
                "wall_seconds": t0.elapsed().as_secs_f64(),
                "distortion": report,
            }),
        )
    })?;
    if map.info.fold_repair_error.is_some() {
        return Ok(ExitCode::from(1));
    }
    Ok(ExitCode::SUCCESS)
}

/// Where the flow on the mesh started, for the summary line: the coarse levels' sizes, or the
/// Lie map (and why, when levels were asked for).
pub(crate) fn flow_start(info: &shapespace_analysis::multiresolution::MultiresolutionInfo) -> String {
    match (&info.fallback, info.levels.is_empty()) {
        (Some(why), _) => format!("the Lie map (multiresolution: {why})"),
        (None, true) => "the Lie map".into(),
        (None, false) => format!(
            "levels of {} vertices",
            info.levels
                .iter()
                .map(|l| l.vertices.to_string())
                .collect::<Vec<_>>()
                .join(", ")
        ),
    }
}

/// `--method flow`: the gradient-flow OMT map, its summary line and report.
fn run_flow(
    args: &ParamArgs,
    mut mesh: shapespace_geometry::TriMesh,
    markers: shapespace_conformal::Markers,
    marker_source: String,
    t0: Instant,
) -> Result<ExitCode> {
    let mut params = GradientFlowParams {
        multiresolution_levels: args.flow_levels,
        ..Default::default()
    };
    params.start.fold_repair.enabled = !args.no_fold_repair;
    params.start.disk_map = args.disk_map.params();
    let message = format!(
        "gradient-flow OMT map of {} ({} vertices)",
        args.input.display(),
        mesh.num_vertices()
    );
    let map = with_spinner(message, || gradient_flow_map(&mesh, &markers, &params))
        .with_context(|| format!("parameterizing {}", args.input.display()))?;
    mesh.uvs = Some(map.uv.clone());
    write_mesh(&args.out, &mesh).with_context(|| format!("writing {}", args.out.display()))?;
    let report = distortion_report(&mesh, &map.conformal.uv, &map.uv)?;
    let flow = &report.maps[1];
    let f = &map.info.flow;
    eprintln!(
        "{}: {} V, {} F; gradient flow {} steps from {} (‖ζ‖/‖u‖ {:.2e} -> {:.2e}, transport cost {:.4e} -> {:.4e}; {}); |Υ| median {:.3e} p95 {:.3e} (conformal {:.3e} / {:.3e}); Λ median {:.3e}; {} flipped; conformal {:.2} s, start {:.2} s, flow {:.2} s",
        args.input.display(),
        mesh.num_vertices(),
        mesh.num_faces(),
        f.steps,
        flow_start(&map.info.multiresolution),
        f.start_curl,
        f.final_curl,
        f.start_cost,
        f.final_cost,
        f.stop,
        flow.abs_area_distortion.median,
        flow.abs_area_distortion.p95,
        report.maps[0].abs_area_distortion.median,
        report.maps[0].abs_area_distortion.p95,
        flow.quasi_conformal_distortion.median,
        flow.num_flipped,
        map.timings.conformal,
        map.timings.start,
        map.timings.flow,
    );
    write_plots_and_report(args, &report, || {
        report_json(
            args,
            "flow",
            &marker_source,
            &map.conformal,
            &mesh,
            Domain::Disk,
            serde_json::json!({
                "lie_advection": map.info.start,
                "multiresolution": map.info.multiresolution,
                "gradient_flow": map.info.flow,
                "timings": map.timings,
                "wall_seconds": t0.elapsed().as_secs_f64(),
                "distortion": report,
            }),
        )
    })?;
    Ok(ExitCode::SUCCESS)
}

/// The sphere route of [`run`].
fn run_sphere(args: &ParamArgs, t0: Instant) -> Result<ExitCode> {
    use shapespace_analysis::distortion::sphere_distortion_report;
    use shapespace_analysis::sphere_param::{area_preserving_sphere_map, SphereParamParams};
    // an unknown output extension is named before the input is read
    shapespace_geometry::io::MeshFormat::from_path(&args.out)?;
    let normalization = args.sphere.normalization_for(&args.input, &args.markers)?;
    if args.start != super::ot::StartArg::Auto {
        anyhow::bail!("--start applies to the disk only (the sphere's OT starts from the Voronoi cells with density continuation)");
    }
    let mesh = super::read_closed_mesh(&args.input)?;
    let mut params = SphereParamParams {
        weights: match &args.weights {
            Some(p) => Some(read_vertex_weights(p, mesh.num_vertices())?),
            None => None,
        },
        no_fold_repair: args.no_fold_repair,
        ..Default::default()
    };
    params.sphere_map.normalization = normalization;
    params.ot.tolerance = args.tolerance;
    let message = format!(
        "area-preserving sphere map of {} ({} vertices)",
        args.input.display(),
        mesh.num_vertices()
    );
    let map = with_spinner(message, || area_preserving_sphere_map(&mesh, &params))
        .with_context(|| format!("mapping {} onto the sphere", args.input.display()))?;
    let mut out_mesh = mesh.clone();
    out_mesh.positions = map.positions.clone();
    out_mesh.uvs = None;
    write_mesh(&args.out, &out_mesh).with_context(|| format!("writing {}", args.out.display()))?;
    let report = sphere_distortion_report(&mesh, &map.conformal.positions, &map.positions)?;
    let (c, ap) = (&report.maps[0], &report.maps[1]);
    let repair = match &map.fold_repair {
        None if args.no_fold_repair => format!("{} folded faces (fold repair off)", map.flipped_before_repair),
        Some(r) if map.flipped_before_repair > 0 => format!(
            "fold repair: {} folded before, {} after, {} vertices moved in {} of {} charts",
            map.flipped_before_repair, map.num_flipped, r.vertices_moved, r.repaired, r.clusters
        ),
        _ => "no folded faces".to_string(),
    };
    eprintln!(
        "{}: {} V, {} F; sphere OT after {} iterations on {} icosphere subdivisions; |ε| median {:.3e} p95 {:.3e} (conformal {:.3e} / {:.3e}); angle distortion p95 {:.2}° (conformal {:.2}°); {} flipped; {}; conformal {:.2} s, OT {:.2} s, output {:.2} s",
        args.input.display(),
        mesh.num_vertices(),
        mesh.num_faces(),
        map.iterations,
        map.source_subdivisions,
        ap.abs_vertex_log_area_ratio.median,
        ap.abs_vertex_log_area_ratio.p95,
        c.abs_vertex_log_area_ratio.median,
        c.abs_vertex_log_area_ratio.p95,
        ap.angle_distortion_deg.p95,
        c.angle_distortion_deg.p95,
        ap.num_flipped + ap.num_degenerate,
        repair,
        map.timings.conformal,
        map.timings.ot,
        map.timings.output,
    );
    write_plots_and_report(args, &report, || {
        serde_json::json!({
            "input": args.input.display().to_string(),
            "output": args.out.display().to_string(),
            "domain": "sphere",
            "normalization": format!("{:?}", params.sphere_map.normalization),
            "weights": args.weights.as_ref().map(|p| p.display().to_string()),
            "num_vertices": mesh.num_vertices(),
            "num_faces": mesh.num_faces(),
            "conformal": map.conformal.info,
            "ot": {
                "iterations": map.iterations,
                "tolerance": args.tolerance,
                "source_subdivisions": map.source_subdivisions,
                "max_relative_error": map
                    .cell_areas
                    .iter()
                    .zip(&map.target_masses)
                    .map(|(a, m)| ((a - m) / m).abs())
                    .fold(0.0f64, f64::max),
            },
            "flipped_before_repair": map.flipped_before_repair,
            "fold_repair": map.fold_repair,
            "num_flipped": map.num_flipped,
            "timings": map.timings,
            "wall_seconds": t0.elapsed().as_secs_f64(),
            "distortion": report,
        })
    })?;
    if map.num_flipped > 0 {
        eprintln!(
            "shapespace: {}: {} faces are still folded on the sphere after the fold repair; the map was written",
            args.input.display(),
            map.num_flipped
        );
        return Ok(ExitCode::from(1));
    }
    Ok(ExitCode::SUCCESS)
}

/// Whether `path` reads as a closed genus-0 mesh (unreadable files: no; the disk route then
/// names the problem).
fn closed_genus_zero(path: &std::path::Path) -> bool {
    read_mesh(path)
        .ok()
        .and_then(|m| shapespace_geometry::topology::classify(&m).ok())
        .is_some_and(|c| c.class == shapespace_geometry::topology::MeshClass::Sphere)
}

/// Writes the histograms of `report` into `--plots` and the JSON that `json` builds into
/// `--report` (atomically), for those of the two that are given.
pub(super) fn write_plots_and_report(
    args: &ParamArgs,
    report: &shapespace_analysis::distortion::DistortionReport,
    json: impl FnOnce() -> serde_json::Value,
) -> Result<()> {
    if let Some(dir) = &args.plots {
        write_distortion_histograms(report, dir, 60)
            .with_context(|| format!("writing plots into {}", dir.display()))?;
    }
    if let Some(p) = &args.report {
        let text = serde_json::to_string_pretty(&json())?;
        write_atomically(p, text.as_bytes()).with_context(|| format!("writing {}", p.display()))?;
    }
    Ok(())
}

/// The report of one map: the fields every method writes (input and output, method, markers,
/// the conformal map, the domain, sizes, scale) with the method's own fields `extra` (an
/// object) added.
fn report_json(
    args: &ParamArgs,
    method: &str,
    marker_source: &str,
    conformal: &shapespace_conformal::DiskMap,
    mesh: &shapespace_geometry::TriMesh,
    domain: Domain,
    extra: serde_json::Value,
) -> serde_json::Value {
    let mut json = serde_json::json!({
        "input": args.input.display().to_string(),
        "output": args.out.display().to_string(),
        "method": method,
        "marker_file": marker_source,
        "markers": conformal.info.markers,
        "conformal_method": conformal.info.method,
        "conformal_bff_fallback": conformal.info.bff_fallback,
        "domain": domain,
        "num_vertices": mesh.num_vertices(),
        "num_faces": mesh.num_faces(),
        "scale": conformal.scale,
    });
    if let (Some(all), serde_json::Value::Object(extra)) = (json.as_object_mut(), extra) {
        all.extend(extra);
    }
    json
}

/// Whether an error (or one of its sources) is about interior protrusions crowded beyond f64:
/// the OT's crowding failures, the conformal map's range errors, and a conformal image that
/// still folds with its boundary in order (TOSCA david0/1: the fingers, until slit two or three
/// times); but not crowding along the boundary (a flat tail on the boundary, which no slit
/// helps).
fn mentions_crowding(e: &(dyn std::error::Error + 'static)) -> bool {
    std::iter::successors(Some(e), |e| e.source()).any(|e| {
        let text = e.to_string();
        let folded_inside = matches!(
            e.downcast_ref::<shapespace_conformal::ConformalError>(),
            Some(shapespace_conformal::ConformalError::FoldedImage {
                boundary_out_of_order: 0,
                ..
            })
        );
        folded_inside
            || ((text.contains("crowded") || text.contains("f64 range")) && !text.contains("along the boundary"))
    })
}

/// The remedy for bodies whose limbs crowd the conformal image.
fn print_seam_hint() {
    eprintln!(
        "shapespace: hint: if this is a body whose limbs crowd the conformal image, slit it from its farthest tips to the boundary first: `shapespace prepare IN --out OUT --seam 1`, and if that still fails `--seam 2` or `3` (each slit frees one more protrusion; README, \"Your own meshes\")"
    );
}

/// One line on the fold repair for the stderr summary.
fn repair_summary(info: &shapespace_analysis::fold_repair::FoldRepairInfo) -> String {
    let folded = info.flipped_before + info.degenerate_before;
    if !info.enabled {
        format!("{folded} folded faces (fold repair off)")
    } else if folded == 0 {
        "no folded faces".to_string()
    } else {
        let untangled = if info.untangle.sweeps > 0 {
            format!("{} after the untangling, ", info.untangle.folded_after)
        } else {
            String::new()
        };
        let flat = if info.flat_boundary_faces > 0 {
            format!(" ({} flat boundary ears, left)", info.flat_boundary_faces)
        } else {
            String::new()
        };
        format!(
            "fold repair: {folded} folded before, {untangled}{} after{flat}, {} vertices moved, {} Tutte rounds",
            info.folded_after, info.vertices_moved, info.rounds
        )
    }
}

#[cfg(test)]
mod tests {
    use super::mentions_crowding;
    use shapespace_analysis::AnalysisError;
    use shapespace_conformal::ConformalError;

    fn folded(boundary_out_of_order: usize) -> AnalysisError {
        AnalysisError::DiskMap(ConformalError::FoldedImage {
            num_flipped: 66,
            first_face: 12634,
            flipped_area_fraction: 8.4e-4,
            boundary_out_of_order,
            bff_fallback_error: None,
            region_repair_error: None,
        })
    }

    /// The slit hint follows a conformal image folded inside (TOSCA david1 slit once) and the
    /// crowding messages, but not a boundary out of order or crowding along the boundary.
    #[test]
    fn slit_hint_follows_interior_folds_and_crowding() {
        assert!(mentions_crowding(&folded(0)));
        assert!(!mentions_crowding(&folded(3)));
        let crowded = AnalysisError::InvalidInput("the points are too crowded for double precision".into());
        assert!(mentions_crowding(&crowded));
        let boundary = AnalysisError::InvalidInput("points crowded along the boundary".into());
        assert!(!mentions_crowding(&boundary));
        assert!(!mentions_crowding(&AnalysisError::InvalidInput(
            "weights: bad row".into()
        )));
    }
}
