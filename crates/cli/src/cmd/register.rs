//! `shapespace register SOURCE TARGET [--landmarks pairs.csv] [--method omt|conformal] [--domain auto|disk|sphere] [--refine none|zoomout] --out DIR`
//! and `shapespace register-bench DATASET_DIR --out DIR [--methods omt,conformal] [--refine none|zoomout] [--closed DIR]`:
//! registration f = φ₂⁻¹ ∘ g ∘ φ₁ through disk maps and a landmark-constrained harmonic map
//! (Su et al. 2015, Alg. 4), refined by ZoomOut unless `--refine none`, or of closed genus-0 surfaces
//! through the sphere (`registration::sphere`), its quality measures, and the benchmark over
//! pose sets (with `--closed`, the sphere route on the closed poses in the same run).

use std::path::{Path, PathBuf};
use std::process::ExitCode;
use std::time::Instant;

use anyhow::Context;
use shapespace_analysis::registration::bench::{register_bench, write_registration, BenchResult, MethodSummary};
use shapespace_analysis::registration::sphere::{
    register_on_sphere, registration_domain, sphere_registration_metrics, write_sphere_registration, Domain,
};
use shapespace_analysis::registration::sphere_bench::sphere_bench;
use shapespace_analysis::registration::{
    register, registration_area_params, registration_metrics, HarmonicParams, Landmarks, Method, MetricParams,
    Refinement, RegistrationMetrics, RegistrationParams, ZoomOutOutput, ZoomOutParams,
};
use shapespace_analysis::shared_markers::{share_auto_markers, MarkerInput};
use shapespace_analysis::sphere_param::SphereParamParams;
use shapespace_conformal::{resolve_markers_of, BoundaryMarker, CenterMarker, MarkerFile};

/// Arguments of `shapespace register`.
#[derive(clap::Args)]
pub struct RegisterArgs {
    /// Source mesh S₁ (disk topology, or a closed genus-0 surface).
    pub source: PathBuf,
    /// Target mesh S₂ (of the same kind as the source).
    pub target: PathBuf,
    /// Where to register: `auto` (the sphere when both meshes are closed genus-0 surfaces, the
    /// disk when both have one boundary loop; one of each is refused), `disk` or `sphere`. On the
    /// sphere: Möbius-centred sphere maps (`--method`), the rotation fitted to the landmarks (at
    /// least 2), the harmonic map in a stereographic chart; `--center` and `--boundary-marker`
    /// do not apply.
    #[arg(long, default_value = "auto")]
    pub domain: String,
    #[command(flatten)]
    pub disk_map: super::DiskMapArgs,
    /// Landmark pairs CSV `source,target` (vertex indices). Default: the named landmarks of the
    /// meshes' marker files, paired by name. Allowed: interior vertices of both meshes, each used
    /// by one landmark per side (boundary vertices are refused: the boundary is mapped onto the
    /// circle as a whole).
    #[arg(long)]
    pub landmarks: Option<PathBuf>,
    /// Interior marker p ↦ 0 of both meshes: a vertex index, a point `x,y,z` (projected to each
    /// surface) or `auto`. Overrides the marker files. A vertex index is for meshes that share
    /// their vertex order.
    #[arg(long)]
    pub center: Option<String>,
    /// Boundary marker q ↦ 1 of both meshes: a boundary vertex index or `auto`. Overrides the
    /// marker files. Where it is automatic on both and the meshes have the same faces, one
    /// choice is made for both (on their mean shape), as `distances` does.
    #[arg(long = "boundary-marker")]
    pub boundary_marker: Option<String>,
    /// Marker file of the source (`{"center", "boundary", "landmarks"}`); default: its sidecar
    /// `NAME.landmarks.json` or `landmarks.json` beside it.
    #[arg(long)]
    pub source_markers: Option<PathBuf>,
    /// Marker file of the target; default: its sidecar.
    #[arg(long)]
    pub target_markers: Option<PathBuf>,
    /// Disk maps: `omt` (area-preserving) or `conformal` (the baseline).
    #[arg(long, default_value = "omt")]
    pub method: String,
    /// Output directory (correspondence.csv, metrics.json, histograms, coloured OBJs).
    #[arg(long)]
    pub out: PathBuf,
    /// Refinement after the disk or sphere stage: `zoomout` (spectral refinement, Melzi et al. 2019:
    /// Laplace–Beltrami eigenpairs of both meshes, k from 20 and from 8 to 120, the run of smaller
    /// residual kept) or `none` (the first stage alone). Default: `zoomout`, or `none` with a note
    /// when a mesh has fewer vertices than ZoomOut's eigenpairs (`--zoomout-k-end`).
    #[arg(long)]
    pub refine: Option<String>,
    /// Weights of the harmonic map g: `planar` (cotangent weights of the planar mesh φ₁(S₁),
    /// signed; default), `planar-clamped` (negative ones set to 0), `mean-value` (Floater's
    /// weights of φ₁(S₁)) or `intrinsic-delaunay`.
    #[arg(long)]
    pub weights: Option<String>,
    /// Untangle folded faces of g: `on` (kernel moves with the boundary and landmarks fixed,
    /// then the folds left re-embedded with the landmarks released, disk only), `held` (the
    /// kernel moves alone: landmarks exactly on their targets, folds may be left),
    /// `foldover-free` (`held`, then the foldover-free untangling of the folds left, disk
    /// only) or `off` (default: on for omt, off for conformal).
    #[arg(long)]
    pub untangle_g: Option<String>,
    /// Steps in which the landmarks move from φ₁ to φ₂, each solved with the weights of the
    /// previous layout (default: 16 for omt, 1 for conformal).
    #[arg(long)]
    pub landmark_steps: Option<usize>,
    /// Number of sampled vertices for the geodesic error (when both meshes share the vertex order).
    #[arg(long, default_value_t = 300)]
    pub samples: usize,
    /// The meshes do not share their vertex order: no geodesic error against the identity
    /// correspondence (vertex i ↔ vertex i), which is computed whenever the vertex counts agree.
    #[arg(long)]
    pub no_ground_truth: bool,
    /// Seed of the vertex sample.
    #[arg(long, default_value_t = 7)]
    pub seed: u64,
    #[command(flatten)]
    pub zoomout: ZoomOutArgs,
}

/// ZoomOut's options of `register` and `register-bench`.
#[derive(clap::Args)]
pub struct ZoomOutArgs {
    /// ZoomOut's landmark weight: the landmarks' geodesic distances (over √area, times this)
    /// join both spectral embeddings of its nearest-neighbour step; 0 leaves them out.
    #[arg(long, default_value_t = shapespace_analysis::registration::zoomout::LANDMARK_WEIGHT, value_parser = weight)]
    pub landmark_weight: f64,
    /// ZoomOut's landmark fit: each landmark pair joins the samples its functional maps are
    /// fitted on, with its partner held, at this many times a sample's mean weight (decision
    /// 0066); 0 leaves them out.
    #[arg(long, default_value_t = shapespace_analysis::registration::zoomout::LANDMARK_FIT, value_parser = weight)]
    pub landmark_fit: f64,
    /// ZoomOut's first spectral sizes, comma-separated: it runs from each and keeps the map whose
    /// final nearest-neighbour residual is smallest (decision 0055); `20` alone is a single run.
    #[arg(long, default_value = "20,8", value_parser = spectral_sizes)]
    pub zoomout_starts: SpectralSizes,
    /// ZoomOut's last spectral size: the Laplace–Beltrami eigenpairs computed per mesh (8 to
    /// 1000). More is sharper on most pose sets and slower (the measured curve:
    /// docs/accuracy.md).
    #[arg(long, default_value_t = ZoomOutParams::default().k_end, value_parser = spectral_end)]
    pub zoomout_k_end: usize,
    /// What ZoomOut returns per source vertex: `vertex` (a target vertex), `projected` (the
    /// nearest point of the target's spectral embedding on the faces around it) or `auto`
    /// (vertex between meshes of one triangulation, projected otherwise; decision 0056).
    #[arg(long, default_value = "auto", value_parser = zoomout_output)]
    pub zoomout_output: ZoomOutOutput,
    /// Source vertices ZoomOut's steps below the last size are fitted on, and target vertices
    /// its nearest-neighbour search starts from (farthest-point samples; all when fewer).
    #[arg(long, default_value_t = ZoomOutParams::default().samples as u64, value_parser = clap::value_parser!(u64).range(1..))]
    pub zoomout_samples: u64,
}

impl ZoomOutArgs {
    /// ZoomOut's parameters: the defaults with these options. Errors: a first size beyond the
    /// last one.
    fn params(&self) -> anyhow::Result<ZoomOutParams> {
        let k_end = self.zoomout_k_end;
        if let Some(k) = self.zoomout_starts.0.iter().find(|&&k| k > k_end) {
            anyhow::bail!("--zoomout-starts {k}: beyond the last spectral size --zoomout-k-end {k_end}");
        }
        Ok(ZoomOutParams {
            output: self.zoomout_output,
            landmark_weight: self.landmark_weight,
            landmark_fit: self.landmark_fit,
            k_starts: self.zoomout_starts.0.clone(),
            k_end,
            samples: self.zoomout_samples as usize,
            ..ZoomOutParams::default()
        })
    }
}

/// Arguments of `shapespace register-bench`.
#[derive(clap::Args)]
pub struct RegisterBenchArgs {
    /// Folder of class folders (e.g. datasets/poses with wolf/ and centaur/), each holding meshes
    /// with the same vertex order and a landmarks.json.
    pub dataset: PathBuf,
    /// Output directory (results.csv, summary.json, geodesic_curve.csv, histograms).
    #[arg(long)]
    pub out: PathBuf,
    /// Comma-separated methods.
    #[arg(long, default_value = "omt,conformal")]
    pub methods: String,
    /// Refinement after the disk or sphere stage: `zoomout` (spectral refinement, Melzi et al. 2019:
    /// Laplace–Beltrami eigenpairs of both meshes, k from 20 and from 8 to 120, the run of smaller
    /// residual kept) or `none` (the first stage alone; classes whose meshes have fewer vertices
    /// than `--zoomout-k-end` need it).
    #[arg(long, default_value = "zoomout")]
    pub refine: String,
    /// Weights of the harmonic map g: `planar` (cotangent weights of the planar mesh φ₁(S₁),
    /// signed; default), `planar-clamped` (negative ones set to 0), `mean-value` (Floater's
    /// weights of φ₁(S₁)) or `intrinsic-delaunay`.
    #[arg(long)]
    pub weights: Option<String>,
    /// Untangle folded faces of g: `on` (kernel moves with the boundary and landmarks fixed,
    /// then the folds left re-embedded with the landmarks released, disk only), `held` (the
    /// kernel moves alone: landmarks exactly on their targets, folds may be left),
    /// `foldover-free` (`held`, then the foldover-free untangling of the folds left, disk
    /// only) or `off` (default: on for omt, off for conformal).
    #[arg(long)]
    pub untangle_g: Option<String>,
    /// Steps in which the landmarks move from φ₁ to φ₂, each solved with the weights of the
    /// previous layout (default: 16 for omt, 1 for conformal).
    #[arg(long)]
    pub landmark_steps: Option<usize>,
    /// Number of sampled vertices for the geodesic error.
    #[arg(long, default_value_t = 300)]
    pub samples: usize,
    /// Seed of the vertex sample.
    #[arg(long, default_value_t = 7)]
    pub seed: u64,
    /// Folder of remeshed poses (`DIR/CLASS/NAME.off` for each pose NAME, e.g. from
    /// `scripts/remesh_targets.py`): also register every pose onto the remeshings of the other
    /// poses, the ground truth carried over by closest point (written to OUT/truth/).
    #[arg(long)]
    pub remeshed: Option<PathBuf>,
    /// A Python with pyfmaps: run the functional-map peer (`--peer-script`) on the same pairs
    /// and ground truth, and write the side-by-side table OUT/comparison.md (skipped with a
    /// message when the script finds no pyfmaps).
    #[arg(long)]
    pub peer: Option<PathBuf>,
    /// The peer script.
    #[arg(long, default_value = "scripts/pyfmaps_bench.py")]
    pub peer_script: PathBuf,
    #[command(flatten)]
    pub zoomout: ZoomOutArgs,
    /// Rounds of region moves at the end of the untangling with points (decisions 0042, 0054):
    /// each set of faces still flipped is laid out again from the ring around it; 0 leaves them
    /// out.
    #[arg(long, default_value_t = 3)]
    pub region_rounds: usize,
    /// The region moves run only on pairs whose faces still flipped after the single moves
    /// cover at least this share of the source's area (0 runs them wherever a face is still
    /// flipped).
    #[arg(long, default_value_t = shapespace_analysis::registration::untangle::REGION_FROM_AREA, value_parser = area_share)]
    pub region_from_area: f64,
    /// Folder of the closed poses behind the dataset's cut poses (`DIR/NAME.off` for each pose
    /// NAME, e.g. the TOSCA originals): also register them on the sphere with the same landmarks
    /// (carried through `CLASS/original_indices.txt`), methods and refinement, and print both
    /// routes side by side (OUT/sphere_results.csv, OUT/sphere_summary.json).
    #[arg(long)]
    pub closed: Option<PathBuf>,
}

fn marker_file(explicit: Option<&Path>, mesh: &Path) -> anyhow::Result<Option<(PathBuf, MarkerFile)>> {
    let path = match explicit {
        Some(p) => Some(p.to_path_buf()),
        None => MarkerFile::sidecar_path(mesh),
    };
    match path {
        Some(p) => {
            let mf = MarkerFile::from_json_file(&p).with_context(|| format!("reading markers {}", p.display()))?;
            Ok(Some((p, mf)))
        }
        None => Ok(None),
    }
}

/// The method's default g ([`HarmonicParams::for_method`]) with the options given.
fn harmonic_params(
    method: Method,
    weights: Option<&str>,
    untangle: Option<&str>,
    steps: Option<usize>,
) -> anyhow::Result<HarmonicParams> {
    let mut h = HarmonicParams::for_method(method);
    if let Some(w) = weights {
        h.weights = w.parse()?;
    }
    if let Some(u) = untangle {
        (h.fold_repair, h.foldover_free, h.release_landmarks) = match u.trim().to_ascii_lowercase().as_str() {
            "on" | "true" | "yes" => (true, false, true),
            "held" => (true, false, false),
            "foldover-free" => (true, true, false),
            "off" | "false" | "no" => (false, false, false),
            other => anyhow::bail!("--untangle-g: expected on, held, foldover-free or off, got `{other}`"),
        };
    }
    if let Some(k) = steps {
        anyhow::ensure!(k >= 1, "--landmark-steps must be at least 1");
        h.landmark_steps = k;
    }
    Ok(h)
}

pub fn run(args: &RegisterArgs) -> anyhow::Result<ExitCode> {
    let method: Method = args.method.parse()?;
    let asked: Option<Refinement> = args.refine.as_deref().map(str::parse).transpose()?;
    super::create_output_folder(&args.out)?;
    // (its errors name the file)
    let read = |p: &Path| shapespace_geometry::io::read_mesh(p);
    let source = read(&args.source)?;
    let target = read(&args.target)?;
    let refine = refinement(args, asked, &source, &target)?;
    let (source_name, target_name) = (args.source.display().to_string(), args.target.display().to_string());
    let domain = registration_domain(args.domain.parse()?, (&source_name, &source), (&target_name, &target))?;
    let m1 = marker_file(args.source_markers.as_deref(), &args.source)?;
    let m2 = marker_file(args.target_markers.as_deref(), &args.target)?;
    let landmarks = match (&args.landmarks, &m1, &m2) {
        (Some(csv), _, _) => Landmarks::from_csv(csv)?,
        (None, Some((p1, f1)), Some((p2, f2))) => Landmarks::from_named(
            &f1.landmarks,
            &f2.landmarks,
            &format!("{} / {}", p1.display(), p2.display()),
        )?,
        _ => anyhow::bail!(
            "no landmarks: no marker file found for {}: pass --landmarks pairs.csv or put a landmarks.json (with \"landmarks\") beside both meshes",
            [(&m1, &args.source), (&m2, &args.target)]
                .iter()
                .filter(|(m, _)| m.is_none())
                .map(|(_, p)| p.display().to_string())
                .collect::<Vec<_>>()
                .join(" and ")
        ),
    };
    if domain == Domain::Sphere {
        return run_sphere(args, method, refine, &source, &target, &landmarks);
    }
    // markers: flags over marker files over auto; automatic ones shared where the faces agree
    let origin =
        |m: &Option<(PathBuf, MarkerFile)>| m.as_ref().map_or("auto".to_string(), |m| m.0.display().to_string());
    let (mut sm, mut tm) = (
        m1.as_ref().map(|m| m.1.markers.clone()).unwrap_or_default(),
        m2.as_ref().map(|m| m.1.markers.clone()).unwrap_or_default(),
    );
    let (mut s_origin, mut t_origin) = (origin(&m1), origin(&m2));
    if let Some(c) = &args.center {
        let c = CenterMarker::parse(c).context("--center")?;
        (sm.center, tm.center) = (c.clone(), c);
        s_origin += ", --center";
        t_origin += ", --center";
    }
    if let Some(b) = &args.boundary_marker {
        let b = BoundaryMarker::parse(b).context("--boundary-marker")?;
        (sm.boundary, tm.boundary) = (b.clone(), b);
        s_origin += ", --boundary-marker";
        t_origin += ", --boundary-marker";
    }
    let shared = share_auto_markers(&[
        MarkerInput {
            name: &source_name,
            mesh: &source,
            markers: &sm,
        },
        MarkerInput {
            name: &target_name,
            mesh: &target,
            markers: &tm,
        },
    ]);
    if let [Some(a), Some(b)] = &shared[..] {
        (sm, tm) = (a.markers.clone(), b.markers.clone());
        s_origin = format!("{s_origin}, {}", a.note);
        t_origin = format!("{t_origin}, {}", b.note);
    }
    let resolved = |side: &str,
                    mesh: &shapespace_geometry::TriMesh,
                    m: &shapespace_conformal::Markers,
                    path: &Path,
                    origin: &str| {
        resolve_markers_of(mesh, m)
            .with_context(|| format!("markers of the {side} {}", path.display()))
            .map(|r| serde_json::json!({"center": r.center, "boundary": r.boundary_vertex, "source": origin}))
    };
    let markers_json = serde_json::json!({
        "source": resolved("source", &source, &sm, &args.source, &s_origin)?,
        "target": resolved("target", &target, &tm, &args.target, &t_origin)?,
    });
    let params = RegistrationParams {
        method,
        source_markers: sm,
        target_markers: tm,
        area_preserving: {
            let mut p = registration_area_params();
            p.disk_map = args.disk_map.params();
            p
        },
        harmonic: harmonic_params(
            method,
            args.weights.as_deref(),
            args.untangle_g.as_deref(),
            args.landmark_steps,
        )?,
        refine,
        zoomout: args.zoomout.params()?,
    };
    eprintln!(
        "register: {} landmark pairs, method {method}, refinement {}",
        landmarks.len(),
        params.refine
    );
    if landmarks.is_empty() {
        eprintln!(
            "register: no landmark pairs ({} names none shared by both meshes): the harmonic map is held by the boundary and the markers only",
            landmarks.source_name
        );
    }
    let t = Instant::now();
    let reg = register(&source, &target, &landmarks, &params)
        .with_context(|| format!("registering {} onto {}", args.source.display(), args.target.display()))?;
    let secs = t.elapsed().as_secs_f64();
    let mp = MetricParams {
        geodesic_samples: args.samples,
        seed: args.seed,
        ground_truth: !args.no_ground_truth,
        ..MetricParams::default()
    };
    let met = registration_metrics(&source, &target, &reg, &mp)?;
    let extra = serde_json::json!({
        "source": args.source.to_string_lossy(), "target": args.target.to_string_lossy(), "landmarks": landmarks.source_name,
        "landmark_names": landmarks.names, "landmark_pairs": landmarks.pairs, "seconds": secs,
        "geodesic_samples": args.samples, "seed": args.seed, "harmonic": params.harmonic,
        "markers": markers_json, "refinement": reg.refinement,
    });
    let files = write_registration(&args.out, &source, &target, &reg, &met, &extra)?;
    if let Some(r) = &reg.harmonic_released {
        match &r.error {
            None => eprintln!(
                "register: g folded {} faces after its untangling; re-embedded with the landmarks released (a region of {} vertices), landmarks off their targets by up to {:.3} in the disk",
                r.folded_before, r.region_vertices, r.landmark_shift
            ),
            Some(e) => eprintln!(
                "register: g folds {} faces after its untangling; the re-embedding with the landmarks released failed ({e}), g kept",
                r.folded_before
            ),
        }
    }
    eprintln!(
        "register: {secs:.2}s (maps {:.2}+{:.2}s, harmonic {:.3}s, composition {:.3}s, refinement {:.2}s); snapped {}",
        reg.timings.source_map,
        reg.timings.target_map,
        reg.timings.harmonic,
        reg.timings.composition,
        reg.timings.refine,
        reg.num_snapped
    );
    print_metrics(&met, "disk", &files);
    Ok(ExitCode::SUCCESS)
}

/// The refinement `register` runs: the one asked for, or by default ZoomOut where both meshes
/// have at least its eigenpairs (`--zoomout-k-end`) as vertices, the first stage alone (with a
/// note naming the mesh) where one has fewer (decision 0065). Errors: `--refine zoomout` asked
/// of such a mesh, before any map.
fn refinement(
    args: &RegisterArgs,
    asked: Option<Refinement>,
    source: &shapespace_geometry::TriMesh,
    target: &shapespace_geometry::TriMesh,
) -> anyhow::Result<Refinement> {
    let k = args.zoomout.zoomout_k_end;
    let small = [(&args.source, source), (&args.target, target)]
        .into_iter()
        .find(|(_, mesh)| mesh.num_vertices() < k);
    match (asked, small) {
        (Some(Refinement::ZoomOut), Some((path, mesh))) => anyhow::bail!(
            "--refine zoomout: {} has {} vertices, fewer than ZoomOut's {k} eigenpairs (--zoomout-k-end); pass a smaller --zoomout-k-end or --refine none",
            path.display(),
            mesh.num_vertices()
        ),
        (Some(r), _) => Ok(r),
        (None, Some((path, mesh))) => {
            eprintln!(
                "register: {} has {} vertices, fewer than ZoomOut's {k} eigenpairs (--zoomout-k-end): the first stage is not refined",
                path.display(),
                mesh.num_vertices()
            );
            Ok(Refinement::None)
        }
        (None, None) => Ok(Refinement::ZoomOut),
    }
}

/// `register` on the sphere (both meshes closed genus-0 surfaces).
fn run_sphere(
    args: &RegisterArgs,
    method: Method,
    refine: Refinement,
    source: &shapespace_geometry::TriMesh,
    target: &shapespace_geometry::TriMesh,
    landmarks: &Landmarks,
) -> anyhow::Result<ExitCode> {
    for (given, flag) in [
        (args.center.is_some(), "--center"),
        (args.boundary_marker.is_some(), "--boundary-marker"),
    ] {
        anyhow::ensure!(
            !given,
            "{flag} applies to disk maps; {} and {} are closed and registered on the sphere",
            args.source.display(),
            args.target.display()
        );
    }
    let zoomout = args.zoomout.params()?;
    let harmonic = harmonic_params(
        method,
        args.weights.as_deref(),
        args.untangle_g.as_deref(),
        args.landmark_steps,
    )?;
    eprintln!(
        "register: closed genus-0 meshes, on the sphere: {} landmark pairs, method {method}, refinement {refine}",
        landmarks.len()
    );
    let t = Instant::now();
    let reg = register_on_sphere(
        source,
        target,
        landmarks,
        method,
        &SphereParamParams::default(),
        &harmonic,
        (refine == Refinement::ZoomOut).then_some(&zoomout),
    )
    .with_context(|| {
        format!(
            "registering {} onto {} on the sphere",
            args.source.display(),
            args.target.display()
        )
    })?;
    let secs = t.elapsed().as_secs_f64();
    let mp = MetricParams {
        geodesic_samples: args.samples,
        seed: args.seed,
        ground_truth: !args.no_ground_truth,
        ..MetricParams::default()
    };
    let met = sphere_registration_metrics(source, target, &reg, &mp)?;
    let extra = serde_json::json!({
        "source": args.source.to_string_lossy(), "target": args.target.to_string_lossy(), "landmarks": landmarks.source_name,
        "landmark_names": landmarks.names, "landmark_pairs": landmarks.pairs, "seconds": secs,
        "geodesic_samples": args.samples, "seed": args.seed, "harmonic": harmonic,
        "refinement": reg.refinement,
    });
    let files = write_sphere_registration(&args.out, source, target, &reg, &met, &extra)?;
    eprintln!(
        "register: {secs:.2}s (sphere maps {:.2}+{:.2}s, harmonic {:.3}s, composition {:.3}s, refinement {:.2}s); pole clearance {:.2} rad, landmark rms after the rotation {:.3}; folded faces of g {} ({} steps); snapped {}",
        reg.timings.source_map,
        reg.timings.target_map,
        reg.timings.harmonic,
        reg.timings.composition,
        reg.timings.refine,
        reg.pole_clearance,
        reg.landmark_rms_after_rotation,
        reg.harmonic_folded,
        reg.harmonic_steps,
        reg.num_snapped
    );
    if let Some(r) = &reg.harmonic_sphere_repair {
        eprintln!(
            "register: g's image folded {} faces on S² (slivers that the chart draws unfolded); re-embedded by the chart repair, {} left, {} vertices moved, landmarks off their targets by up to {:.3} (chordal)",
            r.folded_before, r.folded_after, r.vertices_moved, r.landmark_shift
        );
    }
    print_metrics(&met, "sphere", &files);
    Ok(ExitCode::SUCCESS)
}

/// The metrics' summary lines and the files written, on stderr; `domain` names where the
/// flipped area of g was measured (disk or sphere).
fn print_metrics(met: &RegistrationMetrics, domain: &str, files: &[PathBuf]) {
    eprintln!(
        "register: flipped area {:.4} ({domain}) {:.4} (3D); curvature difference median {:.3} mean {:.3}; area distortion max(J, 1/J) median {:.3} p95 {:.3}, mean |ln J| {:.3}",
        met.flipped_area_ratio,
        met.flipped_area_ratio_3d,
        met.curvature_summary.median,
        met.curvature_summary.mean,
        met.area_distortion_summary.median,
        met.area_distortion_summary.p95,
        met.log_area_distortion_summary.mean
    );
    if let Some(g) = &met.geodesic {
        eprintln!(
            "register: geodesic error against v <-> v ({} samples; the meshes are taken to share their vertex order, --no-ground-truth if they do not) median {:.4} mean {:.4}",
            g.samples.len(),
            g.summary.median,
            g.summary.mean
        );
    }
    for f in files {
        eprintln!("register: wrote {}", f.display());
    }
}

pub fn run_bench(args: &RegisterBenchArgs) -> anyhow::Result<ExitCode> {
    let methods: Vec<Method> = args.methods.split(',').map(str::parse).collect::<Result<_, _>>()?;
    let refine: Refinement = args.refine.parse()?;
    let mut zoomout = args.zoomout.params()?;
    zoomout.point_untangle.region_rounds = args.region_rounds;
    zoomout.point_untangle.region_from_area = args.region_from_area;
    super::create_output_folder(&args.out)?;
    let mp = MetricParams {
        geodesic_samples: args.samples,
        seed: args.seed,
        ..MetricParams::default()
    };
    for &m in &methods {
        harmonic_params(
            m,
            args.weights.as_deref(),
            args.untangle_g.as_deref(),
            args.landmark_steps,
        )?;
    }
    let harmonic = |m: Method| {
        harmonic_params(
            m,
            args.weights.as_deref(),
            args.untangle_g.as_deref(),
            args.landmark_steps,
        )
        .unwrap_or_else(|_| HarmonicParams::for_method(m))
    };
    check_bench_paths(args)?;
    let res = register_bench(
        &args.dataset,
        &args.out,
        args.remeshed.as_deref(),
        &methods,
        &registration_area_params(),
        &harmonic,
        refine,
        &zoomout,
        &mp,
        |m| eprintln!("register-bench: {m}"),
    )
    .with_context(|| format!("benchmark over {}", args.dataset.display()))?;
    print_bench(&res);
    if let Some(python) = &args.peer {
        run_peer(args, python, &res.rows)?;
    }
    let mut failed = res.rows.iter().any(|r| r.status != "ok");
    if let Some(closed) = &args.closed {
        failed |= run_sphere_route(
            args,
            closed,
            &methods,
            &harmonic,
            (refine, &zoomout),
            &mp,
            &res.summaries,
        )?;
    }
    Ok(if failed { ExitCode::from(1) } else { ExitCode::SUCCESS })
}

/// ZoomOut's first spectral sizes (`--zoomout-starts`).
#[derive(Clone, Debug)]
pub struct SpectralSizes(pub Vec<usize>);

/// A comma-separated list of first spectral sizes, each from 1 to ZoomOut's last size.
fn spectral_sizes(s: &str) -> Result<SpectralSizes, String> {
    let sizes = s
        .split(',')
        .map(|t| spectral_size(t, 1, "first", ", at most --zoomout-k-end"))
        .collect::<Result<Vec<usize>, String>>()?;
    Ok(SpectralSizes(sizes))
}

/// The largest spectral size the options accept (eigenpairs per mesh).
const MAX_SPECTRAL_SIZE: usize = 1000;

/// ZoomOut's last spectral size (`--zoomout-k-end`): 8 to [`MAX_SPECTRAL_SIZE`].
fn spectral_end(s: &str) -> Result<usize, String> {
    spectral_size(s, 8, "last", "")
}

/// One spectral size from `low` to [`MAX_SPECTRAL_SIZE`]; `which` and `note` name it in the
/// error.
fn spectral_size(t: &str, low: usize, which: &str, note: &str) -> Result<usize, String> {
    match t.trim().parse::<usize>() {
        Ok(k) if (low..=MAX_SPECTRAL_SIZE).contains(&k) => Ok(k),
        Ok(k) => Err(format!(
            "{k} is not a {which} spectral size (expected {low} to {MAX_SPECTRAL_SIZE}{note})"
        )),
        Err(e) => Err(format!("{t:?}: {e}")),
    }
}

/// ZoomOut's output: `auto`, `vertex` or `projected`.
fn zoomout_output(s: &str) -> Result<ZoomOutOutput, String> {
    s.parse::<ZoomOutOutput>().map_err(|e| e.to_string())
}

/// A weight: a finite number, 0 or more.
fn weight(s: &str) -> Result<f64, String> {
    match s.parse::<f64>() {
        Ok(x) if x.is_finite() && x >= 0.0 => Ok(x),
        Ok(x) => Err(format!("{x} is not a weight (expected a finite number, 0 or more)")),
        Err(e) => Err(format!("{s}: {e}")),
    }
}

/// A share of the source's area: a number in [0, 1].
fn area_share(s: &str) -> Result<f64, String> {
    match s.parse::<f64>() {
        Ok(x) if (0.0..=1.0).contains(&x) => Ok(x),
        Ok(x) => Err(format!(
            "{x} is not a share of the area (expected a number from 0 to 1)"
        )),
        Err(e) => Err(format!("{s}: {e}")),
    }
}

/// The errors of register-bench on its folders before any work: `--remeshed` or `--closed`
/// not a folder, `--peer` without its script.
fn check_bench_paths(args: &RegisterBenchArgs) -> anyhow::Result<()> {
    if let Some(r) = &args.remeshed {
        anyhow::ensure!(r.is_dir(), "--remeshed {}: not a folder", r.display());
    }
    if let Some(c) = &args.closed {
        anyhow::ensure!(c.is_dir(), "--closed {}: not a folder", c.display());
    }
    if args.peer.is_some() {
        anyhow::ensure!(
            args.peer_script.is_file(),
            "--peer-script {}: no such file (run from the repository or pass the script's path)",
            args.peer_script.display()
        );
    }
    Ok(())
}

/// Prints the benchmark's summary table and total time (stdout), its failed pairs and the
/// files written (stderr).
fn print_bench(res: &BenchResult) {
    println!(
        "| class | target | method | refine | pairs ok/failed | flipped area (disk) | flipped area (3D) | curv. diff. median | curv. diff. mean | area dist. median | area dist. p95 | mean abs. ln area dist. | geodesic err. median | geodesic err. mean | s/pair |"
    );
    println!("|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|");
    for s in &res.summaries {
        println!(
            "| {} | {} | {} | {} | {}/{} | {:.4} | {:.4} | {:.3} | {:.3} | {:.3} | {:.3} | {:.3} | {:.4} | {:.4} | {:.2} |",
            s.class,
            s.triangulation,
            s.method,
            s.refine,
            s.pairs_ok,
            s.pairs_failed,
            s.flipped_ratio,
            s.flipped_ratio_3d,
            s.curvature_median,
            s.curvature_mean,
            s.area_distortion_median,
            s.area_distortion_p95,
            s.area_distortion_mean_abs_log,
            s.geodesic_median,
            s.geodesic_mean,
            s.seconds
        );
    }
    println!("total time {:.1} s", res.total_seconds);
    for r in res.rows.iter().filter(|r| r.status != "ok") {
        eprintln!(
            "register-bench: {} {} -> {} ({}) failed: {}",
            r.class, r.source, r.target, r.method, r.status
        );
    }
    for f in &res.files {
        eprintln!("register-bench: wrote {}", f.display());
    }
}

/// The sphere route over the closed poses in `closed` and its table against the cut-disk
/// route's summaries `disk` (same triangulation); whether a sphere pair failed.
fn run_sphere_route(
    args: &RegisterBenchArgs,
    closed: &Path,
    methods: &[Method],
    harmonic: &dyn Fn(Method) -> HarmonicParams,
    (refine, zoomout): (Refinement, &ZoomOutParams),
    mp: &MetricParams,
    disk: &[MethodSummary],
) -> anyhow::Result<bool> {
    let sphere = sphere_bench(
        &args.dataset,
        closed,
        &args.out,
        methods,
        &SphereParamParams::default(),
        harmonic,
        refine,
        zoomout,
        mp,
        |m| eprintln!("register-bench: {m}"),
    )
    .with_context(|| format!("sphere route over {} with {}", args.dataset.display(), closed.display()))?;
    println!();
    println!("Cut-disk route (cut poses) against the sphere route (closed poses), refinement {refine} on both:");
    println!(
        "| class | domain | method | pairs ok/failed | flipped area (disk or sphere) | flipped area (3D) | geodesic err. median | geodesic err. mean | s/pair (maps shared) |"
    );
    println!("|---|---|---|---|---|---|---|---|---|");
    let disk = disk
        .iter()
        .filter(|s| s.triangulation == shapespace_analysis::registration::bench::Triangulation::Same);
    let mut lines: Vec<(String, usize, String)> = Vec::new();
    for (k, (domain, s)) in disk
        .map(|s| ("disk", s))
        .chain(sphere.summaries.iter().map(|s| ("sphere", s)))
        .enumerate()
    {
        lines.push((
            s.class.clone(),
            k,
            format!(
                "| {} | {domain} | {} | {}/{} | {:.4} | {:.4} | {:.4} | {:.4} | {:.2} |",
                s.class,
                s.method,
                s.pairs_ok,
                s.pairs_failed,
                s.flipped_ratio,
                s.flipped_ratio_3d,
                s.geodesic_median,
                s.geodesic_mean,
                s.amortized_seconds
            ),
        ));
    }
    lines.sort_by(|a, b| (a.0 == "all", &a.0, a.1).cmp(&(b.0 == "all", &b.0, b.1)));
    for (_, _, l) in lines {
        println!("{l}");
    }
    println!("sphere route: {:.1} s", sphere.total_seconds);
    for r in sphere.rows.iter().filter(|r| r.status != "ok") {
        eprintln!(
            "register-bench: sphere {} {} -> {} ({}) failed: {}",
            r.class, r.source, r.target, r.method, r.status
        );
    }
    for f in &sphere.files {
        eprintln!("register-bench: wrote {}", f.display());
    }
    Ok(sphere.rows.iter().any(|r| r.status != "ok"))
}

/// Runs the peer script on the benchmark's dataset (and remeshed targets with the ground truth
/// register-bench wrote), then writes OUT/comparison.md from both results.
fn run_peer(
    args: &RegisterBenchArgs,
    python: &Path,
    rows: &[shapespace_analysis::registration::bench::BenchRow],
) -> anyhow::Result<()> {
    use shapespace_analysis::registration::bench::{peer_comparison, read_rows, PeerRow};
    let peer_csv = args.out.join("peer.csv");
    // a previous run's results must not pass for this one's
    if peer_csv.is_file() {
        std::fs::remove_file(&peer_csv).with_context(|| format!("removing {}", peer_csv.display()))?;
    }
    let mut cmd = std::process::Command::new(python);
    cmd.arg(&args.peer_script)
        .arg(&args.dataset)
        .arg("--out")
        .arg(&peer_csv)
        .arg("--samples")
        .arg(args.samples.to_string())
        .arg("--seed")
        .arg(args.seed.to_string());
    if let Some(r) = &args.remeshed {
        cmd.arg("--remeshed").arg(r).arg("--truth").arg(args.out.join("truth"));
    }
    eprintln!("register-bench: peer: {cmd:?}");
    let status = cmd
        .stdout(std::process::Stdio::inherit())
        .status()
        .with_context(|| format!("running the peer {}", python.display()))?;
    anyhow::ensure!(
        status.success(),
        "the peer {} exited with {status}",
        args.peer_script.display()
    );
    if !peer_csv.is_file() {
        eprintln!("register-bench: the peer wrote no results (pyfmaps missing?): no comparison");
        return Ok(());
    }
    let peer: Vec<PeerRow> = read_rows(&peer_csv)?;
    let table = peer_comparison(rows, &peer);
    let path = args.out.join("comparison.md");
    shapespace_geometry::io::write_atomically(&path, table.as_bytes())
        .with_context(|| format!("writing {}", path.display()))?;
    println!("{table}");
    eprintln!("register-bench: wrote {}", path.display());
    Ok(())
}
