//! Benchmark: face pairs at scan resolution against the bundled faces, in one run.
//!
//! `cargo bench -p shapespace-tools --bench scan_bench -- [PAIRS] [--100k] [--quant] [--source]`
//! (2 threads). Scans from `$SHAPESPACE_DATA/outside/facefuns`
//! (default `../shared/datasets`; skipped loudly when absent), prepared as `shapespace prepare`
//! does; those whose conformal map fails are left out. Each row is the median over PAIRS
//! (default 6) consecutive directed pairs, solved as the distances solve them
//! (`PairwiseOptions::default()`, the target's coarsening shared), the bundled and the scan
//! pairs interleaved so that the machine's load hits both alike; each bundled and scan pair is
//! solved twice, cold (the source's averaged coarse copies built inside the timing, as for a
//! source's first pair in a `distances` run) and warm (as for its other pairs):
//! - bundled 9.4k-vertex faces, facefuns 30k-vertex faces, the Sumner face poses (29.3k
//!   vertices, from `outside/sumner_face_poses`, with the automatic markers shared as
//!   `distances` shares them; solved cold), and the facefuns pairs with the densities as
//!   mapped (`prepare_shape` without its spreading of density peaks, i.e. the solver's input
//!   before that fix); each bundled and facefuns pair once more on one thread (warm), as a
//!   `distances` run solves its pairs (one per thread), with the same costs bit for bit;
//! - `--100k`: one facefuns pair subdivided once by edge midpoints (120k vertices; its ratio is
//!   to one bundled pair solved right after it, that source's averaged copies built), and the
//!   peak memory of the process (VmHWM of /proc/self/status) from the subdivided scans'
//!   preparation to the end of their pair (the other scans and the Sumner poses dropped and
//!   the peak reset first, the memory still in use then printed beside it; the whole run's
//!   peak where the kernel refuses the reset), and the peak of a process of its own that
//!   prepares the two subdivided scans and solves their pair (the memory goal's figure);
//! - `--quant`: the scan pairs again with `--target-points N` for N = 20000, 10000, 5000,
//!   2000: the distances' relative error against full resolution (with the second-order
//!   correction, as the distances report it, and with the block model C_q − V) and the time;
//! - `--source`: the scan pairs again with the source density averaged to `--source-faces N`
//!   triangles (N = 30000 … 5000), alone and with `--target-points`: the error against full
//!   resolution (with the quantization's correction, as the distances report it), the time per
//!   pair and the averaging's own time per shape (paid once per shape in a `distances` run).

use shapespace_tools::faces;
use shapespace_tools::scans;

use std::time::Instant;

use shapespace_analysis::distance::{coarsen_source, quantize_target, PairwiseOptions, PreparedShape};
use shapespace_analysis::stats::summarize;
use shapespace_geometry::TriMesh;
use shapespace_omt::newton::Start;
use shapespace_omt::NewtonParams;

struct Solve {
    seconds: f64,
    finest: usize,
    coarse: usize,
    /// The cost towards the target's points (for a quantized target, its groups' means).
    cost: f64,
    /// The target's quantization correction (`PreparedShape::quantization_correction`, timed
    /// with the solve): `cost + correction` is the distances' cost.
    correction: f64,
}

fn solve(a: &PreparedShape, b: &PreparedShape) -> Solve {
    let params = NewtonParams {
        target_coarsening: Some(b.coarsening.clone()),
        ..PairwiseOptions::default().newton
    };
    let t = Instant::now();
    let sol = shapespace_omt::solve_ot_prepared(&a.measure, &b.points, &b.masses, &params).unwrap();
    let correction = b.quantization_correction(&sol, 0.0);
    let seconds = t.elapsed().as_secs_f64();
    assert!(sol.converged(), "{} -> {}: {}", a.name, b.name, sol.stop_description());
    let coarse = match &sol.start {
        Start::CoarseToFine { coarse_iterations, .. } => *coarse_iterations,
        _ => 0,
    };
    Solve {
        seconds,
        finest: sol.iterations,
        coarse,
        cost: sol.cost,
        correction,
    }
}

fn vm_hwm_mb() -> f64 {
    vm_status_mb("VmHWM:")
}

/// A memory figure of /proc/self/status (`VmHWM:`, `VmRSS:`) in MB (NaN where there is none).
fn vm_status_mb(key: &str) -> f64 {
    std::fs::read_to_string("/proc/self/status")
        .ok()
        .and_then(|s| {
            s.lines()
                .find(|l| l.starts_with(key))
                .and_then(|l| l.split_whitespace().nth(1).and_then(|k| k.parse::<f64>().ok()))
        })
        .map_or(f64::NAN, |kb| kb / 1024.0)
}

/// The argument that makes the benchmark solve the subdivided pair alone (its memory figure).
const ALONE: &str = "--subdivided-pair-alone";

/// The prepared scan `name` (file `path`, its disk `mesh`) subdivided once by edge midpoints.
fn subdivided(name: &str, path: &std::path::Path, mesh: &TriMesh) -> Result<PreparedShape, String> {
    let sub = shapespace_geometry::prepare::subdivide_midpoint(mesh).unwrap();
    scans::prepared(&format!("{name}_sub"), path, &sub)
}

/// Reads and prepares the two scans `files` (the parent's subdivided pair), subdivided once,
/// solves their pair and prints `alone: ` with the time and the process's peak memory (VmHWM).
fn subdivided_pair_alone(files: &[String]) {
    let mut fine: Vec<PreparedShape> = Vec::new();
    for f in files {
        let f = std::path::PathBuf::from(f);
        let name = f.file_stem().unwrap().to_string_lossy().to_string();
        match subdivided(&name, &f, &scans::disk_mesh(&f)) {
            Ok(s) => fine.push(s),
            Err(e) => eprintln!("{name} subdivided: {e}"),
        }
    }
    if let [a, b] = &fine[..] {
        let s = solve(a, b);
        println!(
            "alone: {} -> {} ({} points) in {:.2} s, peak memory {:.0} MB",
            a.name,
            b.name,
            b.points.len(),
            s.seconds,
            vm_hwm_mb()
        );
    }
}

fn median(v: &[f64]) -> f64 {
    summarize(v).median.unwrap_or(f64::NAN)
}

fn main() {
    shapespace_tools::at_repository_root();
    let args: Vec<String> = std::env::args().skip(1).filter(|a| a != "--bench").collect();
    let pairs: usize = args.iter().find_map(|a| a.parse().ok()).unwrap_or(6);
    let with_100k = args.iter().any(|a| a == "--100k");
    let with_quant = args.iter().any(|a| a == "--quant");
    let with_source = args.iter().any(|a| a == "--source");
    rayon::ThreadPoolBuilder::new().num_threads(2).build_global().unwrap();
    if let Some(k) = args.iter().position(|a| a == ALONE) {
        subdivided_pair_alone(&args[k + 1..]);
        return;
    }
    let files = scans::facefuns_files();
    if files.is_empty() {
        eprintln!(
            "scan_bench: SKIPPED: no facefuns scans in {} (set SHAPESPACE_DATA)",
            scans::data_dir().join("outside/facefuns").display()
        );
        return;
    }
    let mut scan_shapes = Vec::new();
    let mut scan_meshes = Vec::new();
    for f in &files {
        if scan_shapes.len() == pairs + 1 {
            break;
        }
        let name = f.file_stem().unwrap().to_string_lossy().to_string();
        let mesh = scans::disk_mesh(f);
        match scans::prepared(&name, f, &mesh) {
            Ok(s) => {
                scan_shapes.push(s);
                scan_meshes.push((name, f.clone(), mesh));
            }
            Err(e) => eprintln!(
                "scan_bench: {name} left out: {}",
                e.chars().take(100).collect::<String>()
            ),
        }
    }
    let face_names: Vec<String> = std::fs::read_dir("datasets/faces")
        .unwrap()
        .filter_map(|e| e.ok().map(|e| e.path()))
        .filter(|p| p.extension().is_some_and(|x| x == "obj"))
        .map(|p| p.file_stem().unwrap().to_string_lossy().to_string())
        .collect::<std::collections::BTreeSet<_>>()
        .into_iter()
        .take(pairs + 1)
        .collect();
    let bundled = faces::prepared_faces(&face_names);
    // The Sumner face poses of one triangulation, with their shared automatic markers (pose1,
    // with one vertex less, would keep its own: left out).
    let sumner_files: Vec<_> = scans::sumner_face_files()
        .into_iter()
        .filter(|f| f.file_stem().is_some_and(|s| s != "pose1"))
        .collect();
    let mut sumner = scans::prepared_set(&sumner_files);
    sumner.truncate(pairs + 1);
    let (mut pt, mut ps) = (vec![], vec![]);
    let n = pairs.min(scan_shapes.len() - 1).min(bundled.len() - 1);
    let (mut bt, mut bs, mut st, mut ss) = (vec![], vec![], vec![], vec![]);
    let (mut bw, mut sw) = (vec![], vec![]);
    let (mut b1, mut s1) = (vec![], vec![]);
    // (the global pool's two threads, and one)
    let two = rayon::ThreadPoolBuilder::new().num_threads(2).build().unwrap();
    let one = rayon::ThreadPoolBuilder::new().num_threads(1).build().unwrap();
    let mut scan_solves = Vec::new();
    let (mut rt, mut rs, mut rc) = (vec![], vec![], vec![]);
    for k in 0..n {
        let b = solve(&bundled[k], &bundled[k + 1]);
        let s = solve(&scan_shapes[k], &scan_shapes[k + 1]);
        // The same pairs again (bundled, scan), with the costs of the first solves bit for bit:
        // warm, the sources' averaged copies built (a distances run builds them once per source
        // and reuses them for its other n - 2 pairs), then also on one thread, as a distances
        // run solves its pairs (one per thread).
        let again = |what: &str, pool: &rayon::ThreadPool| {
            let pair = pool.install(|| {
                (
                    solve(&bundled[k], &bundled[k + 1]),
                    solve(&scan_shapes[k], &scan_shapes[k + 1]),
                )
            });
            assert_eq!(
                (pair.0.cost, pair.1.cost),
                (b.cost, s.cost),
                "{what} differs from the first"
            );
            (pair.0.seconds, pair.1.seconds)
        };
        let (bwarm, swarm) = again("a warm solve", &two);
        let (bone, sone) = again("a solve on one thread", &one);
        bw.push(bwarm);
        sw.push(swarm);
        b1.push(bone);
        s1.push(sone);
        // the source density as mapped, without the spreading of its peaks
        let mut raw = scan_shapes[k].clone();
        raw.measure = shapespace_omt::SourceMeasure::new(
            raw.measure.vertices.clone(),
            raw.measure.triangles.clone(),
            raw.disk.face_densities.clone(),
        )
        .unwrap()
        .into();
        let r = solve(&raw, &scan_shapes[k + 1]);
        eprintln!(
            "pair {k}: bundled {:.2} s (warm {:.2} s) {} finest (+{} coarse) | scan {} -> {} {:.2} s (warm {:.2} s) {} finest (+{} coarse) | unspread {:.2} s {} finest (+{} coarse), distance {:+.1e} relative",
            b.seconds, bwarm, b.finest, b.coarse, scan_shapes[k].name, scan_shapes[k + 1].name, s.seconds, swarm, s.finest, s.coarse,
            r.seconds, r.finest, r.coarse, s.cost.sqrt() / r.cost.sqrt() - 1.0
        );
        if k + 1 < sumner.len() {
            let p = solve(&sumner[k], &sumner[k + 1]);
            eprintln!(
                "pair {k}: Sumner face poses {} -> {} {:.2} s {} finest (+{} coarse)",
                sumner[k].name,
                sumner[k + 1].name,
                p.seconds,
                p.finest,
                p.coarse
            );
            pt.push(p.seconds);
            ps.push(p.finest as f64);
        }
        rt.push(r.seconds);
        rs.push(r.finest as f64);
        rc.push((s.cost.sqrt() / r.cost.sqrt() - 1.0).abs());
        bt.push(b.seconds);
        bs.push(b.finest as f64);
        st.push(s.seconds);
        ss.push(s.finest as f64);
        scan_solves.push(s);
    }
    let base = median(&bt);
    println!("| pairs | vertices | pairs measured | median s per pair | finest Newton steps median / max | time ratio to bundled |");
    println!("|---|---:|---:|---:|---:|---:|");
    let max = |v: &[f64]| v.iter().cloned().fold(0.0, f64::max);
    println!(
        "| bundled faces | 9,412 | {n} | {base:.2} | {} / {} | 1 |",
        median(&bs),
        max(&bs)
    );
    println!(
        "| facefuns scans | 30,205 | {n} | {:.2} | {} / {} | {:.1} |",
        median(&st),
        median(&ss),
        max(&ss),
        median(&st) / base
    );
    if !pt.is_empty() {
        println!(
            "| Sumner face poses (prepared, shared markers) | {} | {} | {:.2} | {} / {} | {:.1} |",
            sumner[0].disk.uv.len(),
            pt.len(),
            median(&pt),
            median(&ps),
            max(&ps),
            median(&pt) / base
        );
        let mut all = st.clone();
        all.extend(&pt);
        println!(
            "| all scan pairs above (median) | 29–30k | {} | {:.2} | | {:.1} |",
            all.len(),
            median(&all),
            median(&all) / base
        );
    } else {
        eprintln!(
            "scan_bench: no Sumner face poses in {}",
            scans::data_dir().join("outside/sumner_face_poses").display()
        );
    }
    let warm_base = median(&bw);
    println!(
        "| bundled faces, sources' averaged copies built (as in a distances run) | 9,412 | {n} | {warm_base:.2} | {} / {} | 1 |",
        median(&bs),
        max(&bs)
    );
    println!(
        "| facefuns scans, sources' averaged copies built (as in a distances run) | 30,205 | {n} | {:.2} | {} / {} | {:.1} |",
        median(&sw),
        median(&ss),
        max(&ss),
        median(&sw) / warm_base
    );
    let one_base = median(&b1);
    println!(
        "| bundled faces, sources' copies built, one thread per pair (as a distances run solves them) | 9,412 | {n} | {one_base:.2} | {} / {} | 1 |",
        median(&bs),
        max(&bs)
    );
    println!(
        "| facefuns scans, the same | 30,205 | {n} | {:.2} | {} / {} | {:.1} |",
        median(&s1),
        median(&ss),
        max(&ss),
        median(&s1) / one_base
    );
    println!(
        "| facefuns scans, densities as mapped (no peak spreading) | 30,205 | {n} | {:.2} | {} / {} | {:.1} |",
        median(&rt),
        median(&rs),
        max(&rs),
        median(&rt) / base
    );
    println!(
        "\nspreading the density peaks changed the scan distances by {:.1e} relative (median), {:.1e} (max)",
        median(&rc),
        max(&rc)
    );
    if with_quant {
        println!("\n| --target-points | pairs | distance error vs full: median / max | block model (C_q − V): median / max | uncorrected (cost to the quantized points): median / max | median s per pair | time ratio to full |");
        println!("|---:|---:|---:|---:|---:|---:|---:|");
        let full_t = median(&st);
        for target in [20000, 10000, 5000, 2000] {
            let (mut errs, mut block, mut raw, mut times) = (vec![], vec![], vec![], vec![]);
            for k in 0..n {
                let q = quantize_target(scan_shapes[k + 1].clone(), target);
                let s = solve(&scan_shapes[k], &q);
                let full = scan_solves[k].cost.sqrt();
                let corrected = (s.cost + s.correction).max(0.0).sqrt();
                errs.push((corrected / full - 1.0).abs());
                block.push(((s.cost - q.quantization_variance).max(0.0).sqrt() / full - 1.0).abs());
                raw.push((s.cost.sqrt() / full - 1.0).abs());
                times.push(s.seconds);
            }
            println!(
                "| {target} | {n} | {:.2e} / {:.2e} | {:.2e} / {:.2e} | {:.2e} / {:.2e} | {:.2} | {:.2} |",
                median(&errs),
                max(&errs),
                median(&block),
                max(&block),
                median(&raw),
                max(&raw),
                median(&times),
                median(&times) / full_t
            );
        }
    }
    if with_source {
        println!("\n| --source-faces | --target-points | pairs | source triangles | distance error vs full: median / max | median s per pair | time ratio to full (median of per-pair ratios) | averaging s per shape |");
        println!("|---:|---:|---:|---:|---:|---:|---:|---:|");
        let settings = [
            (Some(30000), None),
            (Some(20000), None),
            (Some(10000), None),
            (Some(5000), None),
            (None, Some(10000)),
            (Some(20000), Some(10000)),
            (Some(10000), Some(10000)),
            (Some(10000), Some(5000)),
        ];
        let m = settings.len();
        let (mut errs, mut times, mut ratios) = (vec![vec![]; m], vec![vec![]; m], vec![vec![]; m]);
        let (mut averaging, mut triangles) = (vec![vec![]; m], vec![vec![]; m]);
        // pair by pair, the full-resolution solve again beside every setting's, so that each
        // ratio compares solves made within seconds of each other
        for k in 0..n {
            for (i, &(faces, target)) in settings.iter().enumerate() {
                let t = Instant::now();
                let a = match faces {
                    Some(f) => coarsen_source(scan_shapes[k].clone(), f).unwrap(),
                    None => scan_shapes[k].clone(),
                };
                averaging[i].push(t.elapsed().as_secs_f64());
                triangles[i].push(a.measure.triangles.len() as f64);
                let b = match target {
                    Some(t) => quantize_target(scan_shapes[k + 1].clone(), t),
                    None => scan_shapes[k + 1].clone(),
                };
                let full = solve(&scan_shapes[k], &scan_shapes[k + 1]);
                let s = solve(&a, &b);
                let corrected = (s.cost + s.correction).max(0.0).sqrt();
                let error = corrected / full.cost.sqrt() - 1.0;
                eprintln!(
                    "{} -> {} source {faces:?} target {target:?}: error {error:+.2e}, {:.2} s against {:.2} s",
                    scan_shapes[k].name,
                    scan_shapes[k + 1].name,
                    s.seconds,
                    full.seconds
                );
                errs[i].push(error.abs());
                times[i].push(s.seconds);
                ratios[i].push(s.seconds / full.seconds);
            }
        }
        for (i, &(faces, target)) in settings.iter().enumerate() {
            let show = |v: Option<usize>| v.map_or("full".to_string(), |v| v.to_string());
            println!(
                "| {} | {} | {n} | {:.0} | {:.2e} / {:.2e} | {:.2} | {:.2} | {:.2} |",
                show(faces),
                show(target),
                median(&triangles[i]),
                median(&errs[i]),
                max(&errs[i]),
                median(&times[i]),
                median(&ratios[i]),
                median(&averaging[i])
            );
        }
    }
    if with_100k {
        // the 100k pair's own peak: the scan shapes go, and the peak (VmHWM) is reset when the
        // kernel allows it (writing 5 to /proc/self/clear_refs)
        drop((scan_shapes, scan_solves, sumner));
        let reset = std::fs::write("/proc/self/clear_refs", "5").is_ok();
        let before = vm_status_mb("VmRSS:");
        // the first two scans whose subdivision maps (the conformal map refuses some)
        let mut fine: Vec<PreparedShape> = Vec::new();
        let mut fine_paths = Vec::new();
        for (name, path, mesh) in &scan_meshes {
            match subdivided(name, path, mesh) {
                Ok(s) => {
                    fine.push(s);
                    fine_paths.push(path.clone());
                }
                Err(e) => eprintln!(
                    "scan_bench: {name} subdivided left out: {}",
                    e.chars().take(100).collect::<String>()
                ),
            }
            if fine.len() == 2 {
                break;
            }
        }
        if fine.len() < 2 {
            println!("\n(no two subdivided scans map: no 120k-vertex row)");
            return;
        }
        let s = solve(&fine[0], &fine[1]);
        let b = solve(&bundled[0], &bundled[1]);
        let s_warm = solve(&fine[0], &fine[1]);
        let b_warm = solve(&bundled[0], &bundled[1]);
        println!(
            "| facefuns subdivided once | {} | 1 | {:.2} | {} / {} | {:.1} (to the bundled pair solved right after it, {:.2} s) |",
            fine[1].points.len(),
            s.seconds,
            s.finest,
            s.finest,
            s.seconds / b.seconds,
            b.seconds
        );
        println!(
            "| the same, sources' averaged copies built | {} | 1 | {:.2} | {} / {} | {:.1} (to the bundled pair, {:.2} s) |",
            fine[1].points.len(),
            s_warm.seconds,
            s_warm.finest,
            s_warm.finest,
            s_warm.seconds / b_warm.seconds,
            b_warm.seconds
        );
        if reset {
            println!(
                "\npeak memory (VmHWM) from the subdivided scans' preparation to the end of their pair: {:.0} MB, of which {before:.0} MB were in use before (the bundled faces, the raw scans)",
                vm_hwm_mb()
            );
        } else {
            println!(
                "\npeak memory (VmHWM) of the whole run (no reset): {:.0} MB",
                vm_hwm_mb()
            );
        }
        // the memory goal's figure: a process of its own that reads and prepares the same two
        // scans, subdivides them and solves their pair (nothing else allocated before)
        drop(fine);
        let alone = std::env::current_exe()
            .and_then(|exe| std::process::Command::new(exe).arg(ALONE).args(&fine_paths).output());
        match &alone {
            Ok(o) => match String::from_utf8_lossy(&o.stdout)
                .lines()
                .find_map(|l| l.strip_prefix("alone: ").map(str::to_owned))
            {
                Some(line) => {
                    println!("a process that prepares the two subdivided scans and solves their pair alone: {line}")
                }
                None => println!(
                    "(the process for the subdivided pair alone gave no figure: {}, {})",
                    o.status,
                    String::from_utf8_lossy(&o.stderr).trim()
                ),
            },
            Err(e) => println!("(the process for the subdivided pair alone did not start: {e})"),
        }
    }
}
