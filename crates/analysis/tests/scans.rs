//! Distances on real scans: the facefuns composite faces (30,204 vertices, MIT,
//! iholzleitner/facefuns; read from `$SHAPESPACE_DATA/outside/facefuns`, default
//! `../shared/datasets` beside the workspace, never copied into the project). Skipped, with a
//! message, when the folder is absent.

use std::path::{Path, PathBuf};

use shapespace_analysis::distance::{
    coarsen_source, directed_distance, prepare_shape, quantize_target, PairwiseOptions, PreparedShape,
};
use shapespace_analysis::pipeline::{markers_for, MarkerOptions};
use shapespace_conformal::DiskMapParams;
use shapespace_geometry::prepare::{prepare_disk, PrepareOptions};

fn data_dir() -> PathBuf {
    std::env::var_os("SHAPESPACE_DATA")
        .map(PathBuf::from)
        .unwrap_or_else(|| PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../../../shared/datasets"))
}

/// The facefuns file `path` prepared as `shapespace prepare` and `shapespace distances` do, or
/// the conformal map's error.
fn prepare_file(path: &Path) -> Result<PreparedShape, shapespace_analysis::AnalysisError> {
    let mesh = prepare_disk(
        &shapespace_geometry::io::read_mesh(path).unwrap(),
        &PrepareOptions::default(),
    )
    .unwrap()
    .0;
    let (markers, _) = markers_for(path, &MarkerOptions::default(), mesh.num_vertices()).unwrap();
    let name = path.file_stem().unwrap().to_string_lossy().to_string();
    prepare_shape(&name, &mesh, &markers, &DiskMapParams::default())
}

/// The facefuns folder, or `None` after saying that it is absent.
fn facefuns_dir() -> Option<PathBuf> {
    let dir = data_dir().join("outside/facefuns");
    if !dir.is_dir() {
        eprintln!("SKIPPED: no real scans in {} (set SHAPESPACE_DATA)", dir.display());
        return None;
    }
    Some(dir)
}

/// The first `n` facefuns faces whose conformal map succeeds, prepared as `shapespace prepare`
/// and `shapespace distances` do; `None` (after saying so) when the scans are absent.
fn facefuns(n: usize) -> Option<Vec<PreparedShape>> {
    let dir = facefuns_dir()?;
    let mut files: Vec<PathBuf> = std::fs::read_dir(&dir)
        .unwrap()
        .filter_map(|e| e.ok().map(|e| e.path()))
        .filter(|p| p.extension().is_some_and(|x| x == "ply"))
        .collect();
    files.sort();
    let mut shapes = Vec::new();
    for f in files {
        // (some faces' maps are refused; the test needs any two that map)
        if let Ok(shape) = prepare_file(&f) {
            shapes.push(shape);
            if shapes.len() == n {
                return Some(shapes);
            }
        }
    }
    panic!("fewer than {n} facefuns faces map");
}

/// The facefuns faces `names` (file stems), prepared as [`facefuns`] does; `None` (after
/// saying so) when the scans are absent.
fn facefuns_named(names: &[&str]) -> Option<Vec<PreparedShape>> {
    let dir = facefuns_dir()?;
    Some(
        names
            .iter()
            .map(|name| prepare_file(&dir.join(format!("{name}.ply"))).unwrap())
            .collect(),
    )
}

/// `--target-points 10000` on 30k-vertex faces: the quantized target has about 10k points
/// with the full mass, and the distance (with the quantization's second-order correction) is
/// within 5e-4 of full resolution on this pair (measured −2.5e-4; −3.8e-4 with the block model
/// C_q − V). Five scan pairs: docs/benchmarks.md "Scans".
#[test]
fn ten_thousand_target_points_within_one_percent() {
    let Some(shapes) = facefuns(2) else { return };
    let (a, b) = (&shapes[0], &shapes[1]);
    assert!(b.points.len() > 30_000);
    let params = PairwiseOptions::default().newton;
    let (full, _) = directed_distance(a, b, &params).unwrap();
    let q = quantize_target(b.clone(), 10_000);
    assert!((9_000..=10_000).contains(&q.points.len()), "{}", q.points.len());
    let (mass, qmass) = (b.masses.iter().sum::<f64>(), q.masses.iter().sum::<f64>());
    assert!((qmass - mass).abs() <= 1e-12 * mass);
    let (quantized, _) = directed_distance(a, &q, &params).unwrap();
    assert!(full.converged && quantized.converged);
    let error = (quantized.distance / full.distance - 1.0).abs();
    assert!(error < 5e-4, "{} vs {}: {error:e}", quantized.distance, full.distance);
}

/// The worst of the five consecutive facefuns pairs at `--target-points 10000`, f46 → f56
/// (the grouping's variance V is 38 % of the cost): with the second-order correction the
/// distance is within 1 % of full resolution (measured −0.93 %; the block model C_q − V gives
/// −1.40 %, beyond it).
#[test]
fn worst_scan_pair_within_one_percent_at_ten_thousand_target_points() {
    let Some(shapes) = facefuns_named(&["f46", "f56"]) else {
        return;
    };
    let (a, b) = (&shapes[0], &shapes[1]);
    let params = PairwiseOptions::default().newton;
    let (full, _) = directed_distance(a, b, &params).unwrap();
    let q = quantize_target(b.clone(), 10_000);
    let (quantized, _) = directed_distance(a, &q, &params).unwrap();
    assert!(full.converged && quantized.converged);
    let error = (quantized.distance / full.distance - 1.0).abs();
    assert!(error < 1e-2, "{} vs {}: {error:e}", quantized.distance, full.distance);
}

/// A scan pair's finest level from the coarse-to-fine start, solved as the distances solve it:
/// f18 → f26 takes 9 Newton steps and 15 evaluations since the 8.6k-point level's cells are
/// integrated on the measure itself for the prolongation (11 and 22 with the cells of the
/// averaged copy the level is solved on; `REINTEGRATE_FROM` in the solver's `multiscale.rs`).
#[test]
fn scan_pair_finest_level_steps() {
    let Some(shapes) = facefuns(2) else { return };
    let (a, b) = (&shapes[0], &shapes[1]);
    let params = shapespace_omt::NewtonParams {
        target_coarsening: Some(b.coarsening.clone()),
        ..PairwiseOptions::default().newton
    };
    let sol = shapespace_omt::solve_ot_prepared(&a.measure, &b.points, &b.masses, &params).unwrap();
    assert!(sol.converged(), "{}", sol.stop_description());
    let shapespace_omt::newton::Start::CoarseToFine { level_iterations, .. } = &sol.start else {
        panic!("start {:?}", sol.start)
    };
    assert_eq!(level_iterations.len(), 3, "{level_iterations:?}");
    assert!(
        sol.iterations <= 9 && sol.evaluations <= 16,
        "{} -> {}: {} finest steps, {} evaluations",
        a.name,
        b.name,
        sol.iterations,
        sol.evaluations
    );
}

/// `--source-faces 10000` on 30k-vertex faces (59.7k source triangles): the averaged source
/// has about 10k triangles and the full mass, and the distance stays within 0.5 % of full
/// resolution (five scan pairs: 0.15 % median, 0.23 % max; docs/benchmarks.md "Scans"), alone and with
/// `--target-points 10000` (with the quantization's correction, as `directed_distance` applies
/// it) within 1 %.
#[test]
fn ten_thousand_source_faces_within_half_a_percent() {
    let Some(shapes) = facefuns(2) else { return };
    let (a, b) = (&shapes[0], &shapes[1]);
    let params = PairwiseOptions::default().newton;
    let (full, _) = directed_distance(a, b, &params).unwrap();
    let c = coarsen_source(a.clone(), 10_000).unwrap();
    let n = c.measure.triangles.len();
    assert!((9_700..=10_000).contains(&n), "{n} triangles");
    let (mass, cmass) = (a.measure.total_mass(), c.measure.total_mass());
    assert!((cmass - mass).abs() <= 1e-9 * mass, "{cmass} against {mass}");
    let (coarse, _) = directed_distance(&c, b, &params).unwrap();
    let q = quantize_target(b.clone(), 10_000);
    let (both, _) = directed_distance(&c, &q, &params).unwrap();
    assert!(full.converged && coarse.converged && both.converged);
    let error = (coarse.distance / full.distance - 1.0).abs();
    assert!(error < 5e-3, "{} vs {}: {error:e}", coarse.distance, full.distance);
    let error = (both.distance / full.distance - 1.0).abs();
    assert!(error < 1e-2, "{} vs {}: {error:e}", both.distance, full.distance);
}

/// The spreading of density peaks in `prepare_shape` acts on the scans' rim (a few faces of
/// 60k at 1e4 × the median density and more, moved a short way) and keeps the mass.
#[test]
fn scan_density_peaks_are_spread_locally() {
    let Some(shapes) = facefuns(1) else { return };
    let s = &shapes[0];
    let info = &s.peak_spreading;
    assert!(info.peak_triangles > 0 && info.changed_triangles < 500, "{info:?}");
    assert!(info.max_patch_diameter < 0.1, "{info:?}");
    let raw = shapespace_omt::SourceMeasure::new(
        s.measure.vertices.clone(),
        s.measure.triangles.clone(),
        s.disk.face_densities.clone(),
    )
    .unwrap();
    let (m0, m1) = (raw.total_mass(), s.measure.total_mass());
    assert!((m0 - m1).abs() <= 1e-12 * m0, "{m0} {m1}");
    let median = {
        let mut d = s.measure.densities.clone();
        d.sort_by(f64::total_cmp);
        d[d.len() / 2]
    };
    assert!(s.measure.densities.iter().all(|&d| d <= 1.0001e4 * median));
}
