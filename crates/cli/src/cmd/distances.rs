//! `shapespace distances FILES... --out DIR`: conformal Wasserstein distances between disk
//! surfaces (Su et al. 2015, Algorithm 3), or between closed genus-0 surfaces on the sphere,
//! optionally followed by MDS and statistics.

use std::io::IsTerminal;
use std::path::PathBuf;
use std::process::ExitCode;

use super::markers::MarkerArgs;
use anyhow::Context;
use indicatif::{ProgressBar, ProgressStyle};
use shapespace_analysis::distance::PairwiseOptions;
use shapespace_analysis::invariance::Invariance;
use shapespace_analysis::pipeline::{run_distances, DistancesOptions, DistancesRun, Domain};
use shapespace_analysis::shape_space::{run_mds, MdsParams};
use shapespace_omt::NewtonParams;

/// Arguments shared by `distances` and `demo`.
#[derive(clap::Args, Clone)]
pub struct SolverArgs {
    #[command(flatten)]
    pub markers: MarkerArgs,
    #[command(flatten)]
    pub disk_map: super::DiskMapArgs,
    /// Closed genus-0 surfaces (compared on the sphere): three vertices `P1,P2,P3` sent to 0, 1
    /// and ∞ (the south pole, (1, 0, 0), the north pole) in every file (a set with one vertex
    /// order); one transport solve per pair. Without them each pair is minimized over the
    /// rotations of the target's sphere (docs/sphere.md).
    #[arg(long = "sphere-markers", value_name = "P1,P2,P3")]
    pub sphere_markers: Option<String>,
    /// `auto`: closed meshes are compared on the sphere, meshes with a boundary on the disk
    /// (mixing both in one run is an error naming the files); `disk` or `sphere` forces one.
    #[arg(long, default_value = "auto", value_parser = ["auto", "disk", "sphere"])]
    pub domain: String,
    /// Compute both directions of every pair and report their mean and the asymmetry.
    #[arg(long)]
    pub symmetrize: bool,
    /// Relative mass tolerance of the OT solver (max_i |μ(W_i) − ν_i|/ν_i). The default keeps
    /// the bundled faces' distances within ~2e-8 relative of their exact values; `dual_cost` in
    /// pairs.csv checks each pair's cost.
    #[arg(long, default_value_t = PairwiseOptions::default().newton.tolerance)]
    pub tol: f64,
    /// Iteration cap of the OT solver, per level of its coarse-to-fine start and per
    /// continuation stage (a pair whose direct solve stops is solved again from the Voronoi
    /// start with density continuation).
    #[arg(long, default_value_t = PairwiseOptions::default().newton.max_iterations)]
    pub max_iterations: usize,
    /// Start each pair from the heights of the previous pair with the same target instead of the
    /// solver's own start. The default start (coarse-to-fine for these densities) is the faster
    /// one on the bundled faces: 10 against 16 Newton steps at the finest level (median).
    #[arg(long)]
    pub warm_start: bool,
    /// Take the pairs that earlier runs in the output folder computed (its pairs.csv, or the
    /// pairs.partial.csv of a run that was stopped) instead of computing them again, where both
    /// files (compared by content), their markers, the solver settings and the shapespace
    /// executable (a rebuilt one starts over) are the same: a stopped run goes on where it
    /// stopped, a finished one given more files computes only the new pairs. report.json's
    /// `resumed` says what was taken from where.
    #[arg(long, conflicts_with = "warm_start")]
    pub resume: bool,
    /// Give up a pair after about this many seconds (at its first Newton step that would begin
    /// later; status `time limit`, no distance): a few pathological pairs (crowded conformal
    /// images of whole bodies) can otherwise take many minutes each before failing. Pairs that
    /// finish in time are unaffected; which ones do depends on the machine, so --resume computes
    /// the others again.
    #[arg(long, value_name = "SECONDS", conflicts_with = "warm_start")]
    pub pair_time_limit: Option<f64>,
    /// `fixed`: the disks aligned by the markers (interior marker at 0, boundary marker at 1).
    /// `rotation`: each directed cost minimized over rotations of the target's disk, so the
    /// boundary marker plays no part (about 2-3× the time of a fixed pair: candidate rotations
    /// from the shapes' angular mass profiles, then secant steps on the cost's derivative).
    /// Closed meshes on the sphere without --sphere-markers are always minimized over the
    /// rotations of the target's sphere; with them, `rotation` searches too.
    #[arg(long, default_value = "fixed", value_parser = ["fixed", "rotation"])]
    pub invariance: String,
    /// Write debiased distances √max(0, c(a,b) − c(b,b)) to distances.csv: each shape's own
    /// quantization floor c(b,b) (its density against its own points, one extra solve per
    /// shape) is subtracted from the costs towards it. pairs.csv keeps the raw costs;
    /// report.json lists the self-costs and how many pairs were clamped at 0.
    #[arg(long)]
    pub debias: bool,
    /// Worker threads (default: all cores; at most 4 per core; 0 means 1).
    #[arg(long)]
    pub threads: Option<usize>,
    /// Quantize each shape's target points to about N (mass-weighted k-means in the disk; total
    /// mass and mean kept; the costs corrected to second order for the grouping): an
    /// accuracy/time trade-off for large meshes. On five 30k-vertex scan pairs N = 10000
    /// changes the distances by 0.22 % (median; 0.93 % at most) in a third of the time
    /// (docs/benchmarks.md, "Scans").
    #[arg(long, value_name = "N")]
    pub target_points: Option<usize>,
    /// Average each shape's source density over a coarser triangulation of at most N triangles
    /// (a Delaunay triangulation of a sample of its disk image, each triangle keeping its exact
    /// mass): cheaper pairs for meshes with many faces, alone or with --target-points. On five
    /// 30k-vertex scan pairs N = 10000 changes the distances by 0.15 % (median; 0.23 % at most),
    /// and with --target-points 10000 a pair takes a seventh of the time (docs/benchmarks.md,
    /// "Scans").
    #[arg(long, value_name = "N")]
    pub source_faces: Option<usize>,
    /// Keep each shape's per-shape work (conformal map, density, target points) in this folder,
    /// one file per shape keyed by the file's SHA-256, its markers, the settings and the
    /// executable, and take it from there when they come again: shards and later runs do not
    /// compute it again. The results are the same with and without it.
    #[arg(long, value_name = "DIR")]
    pub cache: Option<PathBuf>,
    /// No progress bar (one line with the estimated time of the pairs after the first ones).
    #[arg(long)]
    pub quiet: bool,
}

/// Arguments of `shapespace distances`.
#[derive(clap::Args)]
pub struct DistancesArgs {
    /// Disk-topology meshes, or closed genus-0 meshes (OBJ, OFF, PLY).
    #[arg(required = true)]
    pub files: Vec<PathBuf>,
    /// Output directory (distances.csv, pairs.csv, report.json; with --mds also the MDS files).
    /// While the pairs run, pairs.partial.csv there holds those finished so far (pairs.csv's
    /// columns, in the order they finish): what a run that is stopped early leaves behind (a new
    /// run moves such a file to pairs.partial.prev.csv first; see --resume).
    #[arg(long)]
    pub out: PathBuf,
    #[command(flatten)]
    pub solver: SolverArgs,
    /// Also run MDS and statistics on the result (as `shapespace mds`).
    #[arg(long)]
    pub mds: bool,
    /// Labels CSV for --mds (file,label columns...); read and matched to the files before the
    /// distances are computed, so a bad labels file fails at once.
    #[arg(long, requires = "mds")]
    pub labels: Option<PathBuf>,
    /// Compute only shard K of N of the pairs (1 <= K <= N): the pairs, numbered by target then
    /// source, in N contiguous ranges of equal size (up to one pair). Each shard writes its own
    /// folder (a partial matrix, its pairs, a report that names the shard); `shapespace merge`
    /// assembles the N folders into the files of one run. Every shard prepares every shape
    /// (the automatic markers are chosen over all files). Not with --warm-start, --debias or
    /// --mds.
    #[arg(long, value_name = "K/N", conflicts_with_all = ["mds", "warm_start", "debias"])]
    pub shard: Option<String>,
}

/// Arguments of `shapespace merge`.
#[derive(clap::Args)]
pub struct MergeArgs {
    /// The output folders of `distances --shard K/N` runs, all N shards of one run.
    #[arg(required = true)]
    pub shards: Vec<PathBuf>,
    /// Output folder: distances.csv, pairs.csv, report.json as one run writes them.
    #[arg(long)]
    pub out: PathBuf,
    /// Also run MDS and statistics on the result (as `shapespace mds`).
    #[arg(long)]
    pub mds: bool,
}

/// `shapespace merge`: the shards' folders assembled into one run's files.
pub fn run_merge(args: &MergeArgs) -> anyhow::Result<ExitCode> {
    let mut names = vec!["distances.csv", "pairs.csv", "report.json"];
    if args.mds {
        names.extend(shapespace_analysis::shape_space::MDS_OUTPUTS);
    }
    let inputs: Vec<PathBuf> = args
        .shards
        .iter()
        .flat_map(|d| ["distances.csv", "pairs.csv", "report.json"].map(|f| d.join(f)))
        .collect();
    super::check_output_folder(&args.out, &names, inputs.iter().map(|p| Some(p.as_path())))?;
    let run = shapespace_analysis::pipeline::merge_shards(&args.shards, &args.out)
        .with_context(|| format!("merge into {}", args.out.display()))?;
    let r = &run.report;
    eprintln!(
        "merge: {} shards, {} shapes ({} failed), {} directed pairs ({} failed)",
        args.shards.len(),
        r.inputs.len(),
        r.inputs.iter().filter(|i| !i.ok).count(),
        r.pairs_computed,
        r.pairs_failed
    );
    for f in &r.files {
        eprintln!("merge: wrote {}", f.display());
    }
    if args.mds {
        mds_unless_failed(&run, &args.out, None)?;
    }
    Ok(exit_code(&run))
}

pub fn run(args: &DistancesArgs) -> anyhow::Result<ExitCode> {
    check_outputs(&args.out, &args.files, args.labels.as_deref(), &args.solver, args.mds)?;
    if let Some(labels) = &args.labels {
        check_labels(labels, &args.files)?;
    }
    let shard = args
        .shard
        .as_deref()
        .map(shapespace_analysis::shard::Shard::parse)
        .transpose()
        .context("--shard")?;
    let run = compute_shard(&args.files, &args.out, &args.solver, shard)?;
    if args.mds {
        mds_unless_failed(&run, &args.out, args.labels.as_deref())?;
    }
    Ok(exit_code(&run))
}

/// Checks, before any work, the files a run writes into `out` (with `mds`, the MDS outputs
/// too): none is a symbolic link or one of the inputs (meshes, labels, marker file).
pub fn check_outputs(
    out: &std::path::Path,
    files: &[PathBuf],
    labels: Option<&std::path::Path>,
    solver: &SolverArgs,
    mds: bool,
) -> anyhow::Result<()> {
    use shapespace_analysis::pipeline::{
        PARTIAL_IDENTITY, PARTIAL_PAIRS, PREVIOUS_PARTIAL_IDENTITY, PREVIOUS_PARTIAL_PAIRS,
    };
    let mut names = vec![
        "distances.csv",
        "pairs.csv",
        "report.json",
        PARTIAL_PAIRS,
        PARTIAL_IDENTITY,
        PREVIOUS_PARTIAL_PAIRS,
        PREVIOUS_PARTIAL_IDENTITY,
    ];
    if mds {
        names.extend(shapespace_analysis::shape_space::MDS_OUTPUTS);
    }
    let inputs = files
        .iter()
        .map(|f| Some(f.as_path()))
        .chain([labels, solver.markers.landmarks.as_deref()]);
    super::check_output_folder(out, &names, inputs)
}

/// MDS + statistics on `out/distances.csv` when every file and pair of `run` succeeded. With
/// failures the matrix is incomplete and MDS needs every distance: the MDS is skipped with a
/// message (the exit code stays that of the failures), and the outputs of an earlier MDS in
/// `out`, which would describe other distances, are removed.
pub fn mds_unless_failed(
    run: &DistancesRun,
    out: &std::path::Path,
    labels: Option<&std::path::Path>,
) -> anyhow::Result<()> {
    if run.report.failures.is_empty() {
        return mds(out, labels);
    }
    // incomplete matrix: the shapes with all their distances are embedded, the others listed
    match run_mds(&out.join("distances.csv"), labels, out, &MdsParams::default()) {
        Ok(result) => {
            super::mds::print_summary(&result);
            Ok(())
        }
        Err(shapespace_analysis::AnalysisError::InvalidInput(why)) => {
            for f in shapespace_analysis::shape_space::MDS_OUTPUTS {
                let path = out.join(f);
                if path.exists() {
                    std::fs::remove_file(&path).with_context(|| format!("removing the stale {}", path.display()))?;
                }
            }
            eprintln!("shapespace: MDS skipped: {why}");
            Ok(())
        }
        Err(e) => Err(anyhow::Error::new(e).context("mds")),
    }
}

/// Reads the labels file and matches it to the shapes of `files` (the names the distances will
/// carry), so that a labels file the MDS would refuse fails before any distance is computed.
pub fn check_labels(labels: &std::path::Path, files: &[PathBuf]) -> anyhow::Result<()> {
    shapespace_analysis::matrix_io::read_labels(labels, &shapespace_analysis::pipeline::shape_names(files))
        .context("mds")?;
    Ok(())
}

/// Finished pairs after which a run without progress bar prints its time estimate (at least one
/// per thread).
const ETA_AFTER_PAIRS: usize = 4;

/// `--threads` is capped to this many threads per core.
const MAX_THREADS_PER_CORE: usize = 4;

/// Runs the distances with a progress bar; prints a summary to stderr.
pub fn compute(files: &[PathBuf], out: &std::path::Path, solver: &SolverArgs) -> anyhow::Result<DistancesRun> {
    compute_shard(files, out, solver, None)
}

/// [`compute`], of one shard of the pairs when `shard` is given.
pub fn compute_shard(
    files: &[PathBuf],
    out: &std::path::Path,
    solver: &SolverArgs,
    shard: Option<shapespace_analysis::shard::Shard>,
) -> anyhow::Result<DistancesRun> {
    configure_threads(solver.threads);
    let options = distances_options(solver, shard)?;
    let show = !solver.quiet && std::io::stderr().is_terminal();
    let bar = if show {
        ProgressBar::new(0)
    } else {
        ProgressBar::hidden()
    };
    bar.set_style(
        ProgressStyle::with_template("{prefix:>8} [{bar:30}] {pos}/{len} {elapsed_precise} eta {eta}")
            .unwrap_or_else(|_| ProgressStyle::default_bar())
            .progress_chars("=> "),
    );
    // Without the bar (--quiet or no terminal), one line estimates the pairs' time once the first
    // ETA_AFTER_PAIRS (at least one per thread) have finished; the pairs start when the last
    // shape is prepared.
    let pairs_start = std::sync::Mutex::new(None::<std::time::Instant>);
    let estimate_after = ETA_AFTER_PAIRS.max(rayon::current_num_threads());
    let progress = |done: usize, total: usize, stage: &str| {
        if !show {
            let mut start = pairs_start.lock().unwrap_or_else(|e| e.into_inner());
            match stage {
                "prepare" if done == total => *start = Some(std::time::Instant::now()),
                "pairs" if done == estimate_after.min(total) && done < total => {
                    if let Some(t) = *start {
                        let elapsed = t.elapsed().as_secs_f64();
                        let all = elapsed * total as f64 / done as f64;
                        eprintln!(
                            "distances: {done} of {total} pairs in {elapsed:.1} s; estimated {all:.0} s for all pairs ({:.0} s to go)",
                            all - elapsed
                        );
                    }
                }
                _ => {}
            }
        }
        if bar.length() != Some(total as u64) || done == 1 {
            bar.set_prefix(stage.to_string());
            bar.set_length(total as u64);
            bar.reset_eta();
        }
        bar.set_position(done as u64);
    };
    let run =
        run_distances(files, out, &options, &progress).with_context(|| format!("distances into {}", out.display()))?;
    bar.finish_and_clear();
    print_summary(&run, out, solver, shard);
    Ok(run)
}

/// Builds the global thread pool with `--threads` (capped at a few per core), if given.
fn configure_threads(threads: Option<usize>) {
    if let Some(requested) = threads {
        // More threads than a few per core only cost their creation (10,000 threads took over a
        // minute to start on 2 cores), so the request is capped.
        let cores = std::thread::available_parallelism().map_or(1, |n| n.get());
        let t = requested.clamp(1, MAX_THREADS_PER_CORE * cores);
        if t != requested && requested != 0 {
            eprintln!("shapespace: --threads {requested} capped to {t} ({cores} cores)");
        }
        rayon::ThreadPoolBuilder::new().num_threads(t).build_global().ok();
    }
}

/// The library's options for `solver`'s arguments, checked.
fn distances_options(
    solver: &SolverArgs,
    shard: Option<shapespace_analysis::shard::Shard>,
) -> anyhow::Result<DistancesOptions> {
    anyhow::ensure!(
        solver.tol > 0.0 && solver.tol < 1.0,
        "--tol must be in (0, 1) (a relative mass error per cell), got {}",
        solver.tol
    );
    anyhow::ensure!(solver.max_iterations >= 1, "--max-iterations must be at least 1");
    let time_limit = solver
        .pair_time_limit
        .map(|s| {
            std::time::Duration::try_from_secs_f64(s)
                .ok()
                .filter(|d| !d.is_zero())
                .ok_or_else(|| anyhow::anyhow!("--pair-time-limit must be a positive number of seconds, got {s}"))
        })
        .transpose()?;
    let mut markers = solver.markers.options()?;
    if let Some(text) = &solver.sphere_markers {
        let v: Vec<u32> = text
            .split(',')
            .map(|t| t.trim().parse::<u32>())
            .collect::<Result<_, _>>()
            .map_err(|_| anyhow::anyhow!("--sphere-markers {text:?}: expected 3 vertex indices separated by commas"))?;
        anyhow::ensure!(
            v.len() == 3,
            "--sphere-markers {text:?}: expected 3 vertex indices, got {}",
            v.len()
        );
        anyhow::ensure!(
            solver.domain != "disk",
            "--sphere-markers apply to closed surfaces (the sphere), not with --domain disk"
        );
        markers.sphere_markers = Some([v[0], v[1], v[2]]);
    }
    // The library's pairwise defaults (linear solver, coarse-level tolerance), which the
    // benchmark measures, with the user's tolerance and cap.
    let defaults = PairwiseOptions::default().newton;
    let mut options = DistancesOptions {
        markers,
        pairwise: PairwiseOptions {
            symmetrize: solver.symmetrize,
            newton: NewtonParams {
                tolerance: solver.tol,
                max_iterations: solver.max_iterations,
                ..defaults
            },
            warm_start: solver.warm_start,
            time_limit,
            invariance: match solver.invariance.as_str() {
                "rotation" => Invariance::Rotation,
                _ => Invariance::Fixed,
            },
            debias: solver.debias,
        },
        resume: solver.resume,
        target_points: solver.target_points,
        source_faces: solver.source_faces,
        shard,
        cache: solver.cache.clone(),
        domain: match solver.domain.as_str() {
            "disk" => Domain::Disk,
            "sphere" => Domain::Sphere,
            _ => Domain::Auto,
        },
        ..DistancesOptions::default()
    };
    options.disk_map = solver.disk_map.params();
    if let Some(n) = solver.target_points {
        anyhow::ensure!(n >= 1, "--target-points must be at least 1");
    }
    if let Some(n) = solver.source_faces {
        anyhow::ensure!(n >= 1, "--source-faces must be at least 1");
    }
    Ok(options)
}

/// The run's summary on stderr: warnings, failed inputs and pairs, shard, cache, counts and
/// times, resumed pairs, asymmetry, files written.
fn print_summary(
    run: &DistancesRun,
    out: &std::path::Path,
    solver: &SolverArgs,
    shard: Option<shapespace_analysis::shard::Shard>,
) {
    let r = &run.report;
    for warning in &r.marker_warnings {
        eprintln!("shapespace: warning: {warning}");
    }
    for input in &r.inputs {
        if let Some(moved) = input.conformal_repair_moved {
            eprintln!(
                "shapespace: warning: {}: its conformal map folded faces that only a Tutte re-embedding repaired ({moved} vertices moved: not conformal there, and the densities there are the repair's); its distances are less reliable and slower to solve (docs/your-meshes.md)",
                input.path.display()
            );
        }
    }
    // (an input's error starts with its path)
    for input in r.inputs.iter().filter(|i| !i.ok) {
        match &input.error {
            Some(error) => eprintln!("shapespace: {error}"),
            None => eprintln!("shapespace: {}: failed", input.path.display()),
        }
    }
    // the failures after those of the inputs are the pairs'
    let failed_inputs = r.inputs.iter().filter(|i| i.error.is_some()).count();
    for failure in r
        .failures
        .iter()
        .skip(failed_inputs)
        .filter(|f| !f.ends_with("shape failed to prepare"))
    {
        eprintln!("shapespace: pair {failure}");
    }
    if let Some(shard) = shard {
        eprintln!("distances: shard {} of {}", shard.index, shard.count);
    }
    if let Some(dir) = &solver.cache {
        eprintln!(
            "distances: {} of {} shapes taken from the cache {}",
            run.cache_hits,
            r.inputs.len(),
            dir.display()
        );
    }
    eprintln!(
        "distances: {} shapes ({} failed), {} directed pairs ({} failed) in {:.1} s (prepare {:.1} s, pairs {:.1} s on {} threads)",
        r.inputs.len(),
        r.inputs.iter().filter(|i| !i.ok).count(),
        r.pairs_computed,
        r.pairs_failed,
        r.timings.total,
        r.timings.prepare_wall,
        r.timings.pairs_wall,
        r.threads
    );
    if let Some(resumed) = &r.resumed {
        eprintln!(
            "distances: {} of the directed pairs taken from earlier runs in {}",
            resumed.pairs,
            out.display()
        );
        for source in &resumed.sources {
            eprintln!("distances:   {source}");
        }
    }
    if let Some(a) = &r.asymmetry {
        eprintln!(
            "distances: relative asymmetry median {:.2e}, max {:.2e}",
            a.median.unwrap_or(f64::NAN),
            a.max.unwrap_or(f64::NAN)
        );
    }
    for f in &r.files {
        eprintln!("distances: wrote {}", f.display());
    }
}

/// MDS + statistics on `out/distances.csv`.
pub fn mds(out: &std::path::Path, labels: Option<&std::path::Path>) -> anyhow::Result<()> {
    let result = run_mds(&out.join("distances.csv"), labels, out, &MdsParams::default()).context("mds")?;
    super::mds::print_summary(&result);
    Ok(())
}

/// 0 when every file and pair succeeded, 1 otherwise.
pub fn exit_code(run: &DistancesRun) -> ExitCode {
    if run.report.failures.is_empty() {
        ExitCode::SUCCESS
    } else {
        ExitCode::from(1)
    }
}
