//! ZoomOut's landmark coordinates on a pose pair whose refinement drifted onto a mirror limb
//! without them: Sumner & Popović's cat, reference → pose 0001 (read from the shared datasets
//! folder; skipped with a message when absent). Both poses are cut to disks as
//! `shapespace prepare` does, around one vertex, so they keep one vertex order (vertex i ↔
//! vertex i is the ground truth); the landmarks are the six extremities by farthest-point
//! sampling from the cut (`geometry::seam::extremities`), the center marker the seventh, as
//! `scripts/cut_pose_set.py` chooses them. The untangling with points on the same cat pairs, and
//! ZoomOut's two first sizes (decision 0055) on the lion poses (`outside/lion_poses`).

use shapespace_analysis::registration::{
    refine_registration, register, registration_metrics, Landmarks, MetricParams, Refinement, Registration,
    RegistrationMetrics, RegistrationParams, SpectralBasis, ZoomOutParams,
};
use shapespace_conformal::{BoundaryMarker, CenterMarker, Markers};
use shapespace_geometry::prepare::{prepare_disk, CutCenter, PrepareOptions};
use shapespace_geometry::{Connectivity, TriMesh};

fn cut_poses(a: &str, b: &str) -> Option<(TriMesh, TriMesh)> {
    cut_pair(
        &format!("sumner_deformation_transfer/cat-poses/{a}.obj"),
        &format!("sumner_deformation_transfer/cat-poses/{b}.obj"),
        false,
    )
}

/// Two poses of one connectivity from the shared folder (None when absent), cut to disks around
/// the vertex of the first nearest its vertex centroid with `prepare`'s default disk (3 rings of
/// edges, so that both poses lose the same faces); with `slit`, then slit along the seam of
/// `prepare --seam 1` chosen on the first pose, the same edges in both.
fn cut_pair(first: &str, second: &str, slit: bool) -> Option<(TriMesh, TriMesh)> {
    let files = shapespace_test_support::shared_files(&[first, second])?;
    let read = |i: usize| shapespace_geometry::io::read_mesh(&files[i]).unwrap();
    let (m0, m1) = (read(0), read(1));
    let n = m0.num_vertices() as f64;
    let c = (0..3)
        .map(|d| m0.positions.iter().map(|p| p[d]).sum::<f64>() / n)
        .collect::<Vec<_>>();
    let dist = |p: &[f64; 3]| (0..3).map(|d| (p[d] - c[d]).powi(2)).sum::<f64>();
    let center = (0..m0.positions.len())
        .min_by(|&a, &b| dist(&m0.positions[a]).total_cmp(&dist(&m0.positions[b])))
        .unwrap() as u32;
    let opts = PrepareOptions {
        cut_center: CutCenter::Vertex(center),
        ..PrepareOptions::default()
    };
    let (d0, _, _) = prepare_disk(&m0, &opts).unwrap();
    let (d1, _, _) = prepare_disk(&m1, &opts).unwrap();
    assert_eq!(d0.faces, d1.faces, "the two poses must keep one connectivity");
    if !slit {
        return Some((d0, d1));
    }
    let tip = shapespace_geometry::seam::extremities(&d0, 1).unwrap();
    let seam = shapespace_geometry::seam::seam_tree(&d0, &tip).unwrap();
    let (s0, _) = shapespace_geometry::seam::cut_along_seam(&d0, &seam).unwrap();
    let (s1, _) = shapespace_geometry::seam::cut_along_seam(&d1, &seam).unwrap();
    assert_eq!(s0.faces, s1.faces);
    Some((s0, s1))
}

/// The cat tests' landmarks and markers on a cut pose `s` (the targets share its vertex order):
/// six of its seven extremities as landmarks, the seventh as the centre marker, and the first
/// boundary vertex as the boundary marker (with the script's choice, the boundary vertex of
/// largest z, reference → 0002 measured 0.128 instead of 0.013: the first stage is sensitive to
/// the disk's rotation on this cut; not examined further).
fn extremity_landmarks(s: &TriMesh) -> (Landmarks, RegistrationParams) {
    let ext = shapespace_geometry::seam::extremities(s, 7).unwrap();
    let on_boundary = Connectivity::of(s).boundary_vertices(s.num_vertices());
    let boundary = (0..s.num_vertices()).find(|&v| on_boundary[v]).unwrap() as u32;
    let markers = Markers {
        center: CenterMarker::Vertex(ext[6]),
        boundary: BoundaryMarker::Vertex(boundary),
    };
    let lm = Landmarks {
        pairs: ext[..6].iter().map(|&v| (v, v)).collect(),
        names: (0..6).map(|i| format!("x{i}")).collect(),
        source_name: "extremities".into(),
    };
    let params = RegistrationParams {
        source_markers: markers.clone(),
        target_markers: markers,
        // the first stage: the tests refine it themselves
        refine: Refinement::None,
        ..RegistrationParams::default()
    };
    (lm, params)
}

/// A cut pose pair after the first stage (the extremity landmarks and markers above), with both
/// surfaces' spectral bases at ZoomOut's default size: what every refinement below starts from.
struct FirstStage {
    s: TriMesh,
    t: TriMesh,
    lm: Landmarks,
    first: Registration,
    b1: SpectralBasis,
    b2: SpectralBasis,
}

impl FirstStage {
    fn of(pair: (TriMesh, TriMesh)) -> Self {
        Self::with_release(pair, true)
    }

    /// The first stage with g's leftover folds re-embedded with the landmarks released (the
    /// default, decision 0062) or with the landmarks held (`--untangle-g held`).
    fn with_release((s, t): (TriMesh, TriMesh), release: bool) -> Self {
        let (lm, mut params) = extremity_landmarks(&s);
        params.harmonic.release_landmarks = release;
        let first = register(&s, &t, &lm, &params).unwrap();
        let zp = ZoomOutParams::default();
        let b1 = SpectralBasis::of(&s, zp.k_end, &zp.eigen).unwrap();
        let b2 = SpectralBasis::of(&t, zp.k_end, &zp.eigen).unwrap();
        FirstStage {
            s,
            t,
            lm,
            first,
            b1,
            b2,
        }
    }

    /// The first stage refined with `params`, and the default metrics of the result.
    fn refined(&self, params: &ZoomOutParams) -> (Registration, RegistrationMetrics) {
        let mut reg = self.first.clone();
        refine_registration(&self.s, &self.t, &mut reg, &self.lm, &self.b1, &self.b2, params).unwrap();
        let m = registration_metrics(&self.s, &self.t, &reg, &MetricParams::default()).unwrap();
        (reg, m)
    }
}

/// Two cat pairs refined by ZoomOut with the landmarks' geodesic distances in the embeddings
/// (weight 3, the default; the heat method on the intrinsic Delaunay triangulation) against
/// without them (weight 0), one run from 20 with the default steps of 8, both without the
/// landmark pairs in the fits (`landmark_fit` 0). Measured (one thread): reference → 0002 mean
/// geodesic error 0.0124 against 0.0129, 0001 → 0002 0.0141 against 0.0322: without them a limb
/// drifts onto the other. The landmark pairs in the fits (the default weight 20, decision 0066)
/// stop that drift as well without the coordinates: 0.0120 and 0.0133. Asserted: below 0.013
/// and 0.018 with the coordinates and with the fit alone, each at most 5 % above the error
/// without either on the first pair and at most 0.6 of it on the second (the drift they stop,
/// cat0 → cat1 of `register-bench` with `scripts/cut_pose_set.py`'s cut, measured 0.0318 →
/// 0.0172, `docs/accuracy.md`). With this
/// test's cut, 0001 → reference measured 0.0716 with and without them in an earlier version: a
/// limb lands on its mirror there. Which single runs drift depends on the samples the steps
/// below `k_end` fit C on: with uniform random samples it was the run from 20 by 8 that drifted
/// with them as well (0.0321) and the run by 4 that they held; with the farthest-point samples
/// (decision 0058) the run by 4 drifts either way (0.0332). Asserted as well: the default
/// refinement (two first sizes, the coordinates and the fit; 0.0103 and 0.0127) below the same
/// bounds. The first stage
/// keeps its landmarks held (`--untangle-g held`): with g's leftover folds re-embedded with the
/// landmarks released (the default, decision 0062) the run from 20 without the coordinates no
/// longer drifts on 0001 → 0002 (0.0130, against 0.0134 with them, the default refinement
/// 0.0131; reference → 0002 0.0124, 0.0139 and 0.0115), so that seed no longer shows what the
/// coordinates stop.
#[test]
fn landmark_coordinates_keep_the_cat_limbs_apart() {
    for (a, b, bound, gain) in [("reference", "0002", 0.013, 1.05), ("0001", "0002", 0.018, 0.6)] {
        let Some(pair) = cut_poses(a, b) else { return };
        let stage = FirstStage::with_release(pair, false);
        let zp = ZoomOutParams::default();
        let run = |weight: f64, fit: f64| {
            // one run from 20: the drift the landmark coordinates stop (with the default two
            // first sizes, 0001 → 0002 measures 0.0129 with them and 0.0125 without)
            let p = ZoomOutParams {
                landmark_weight: weight,
                landmark_fit: fit,
                k_starts: vec![20],
                ..zp.clone()
            };
            stage.refined(&p).1.geodesic.unwrap().summary.mean
        };
        // the coordinates alone, without the landmark pairs in the fits
        let (with, without) = (run(zp.landmark_weight, 0.0), run(0.0, 0.0));
        // the pairs in the fits alone
        let fit_alone = run(0.0, zp.landmark_fit);
        let default = stage.refined(&zp).1.geodesic.unwrap().summary.mean;
        eprintln!(
            "cat {a} -> {b}: geodesic mean {with:.4} with landmark coordinates, {without:.4} without, {fit_alone:.4} with the landmark fit alone, {default:.4} by default"
        );
        assert!(with < bound, "{a} -> {b}: {with}");
        assert!(with <= gain * without, "{a} -> {b}: {with} against {without}");
        assert!(fit_alone < bound, "{a} -> {b}: {fit_alone} with the landmark fit alone");
        assert!(
            fit_alone <= gain * without,
            "{a} -> {b}: {fit_alone} with the landmark fit alone against {without}"
        );
        assert!(default < bound, "{a} -> {b}: {default} by default");
    }
}

/// The untangling with points after ZoomOut's vertex map (`registration::untangle::untangle_points`)
/// on two cat pairs cut as above, against the same refinement without it (its sweeps 0). The
/// pass counts flips with the registration metric's own 3D test, so its count after equals the
/// metric's flipped faces. Measured (flipped 3D area, mean geodesic error; without → with):
/// reference → 0002 0.94 % → 0.17 % and 0.01032 → 0.01031; 0001 → 0002 0.84 % → 0.20 % and
/// 0.01254 → 0.01235. Asserted: the flipped area below 0.2 % and 0.4 %, at most half of the
/// figure without the pass, and the geodesic error at most 2 % above it. Both pairs' sweeps
/// leave less than the region moves' threshold (0.4 % of the area, decision 0054), so none ran
/// (asserted); run wherever a face stays flipped (`region_from_area` 0) on the second pair they
/// took the flipped area to 0.089 % at a geodesic error of 0.01219, 1 % below the default's
/// (asserted: at most half of the default's flipped area, at most 5 % more error; 0.29 of it,
/// 0.064 % against 0.22 %, from the seed before the landmark pairs joined ZoomOut's fits).
#[test]
fn point_untangling_removes_most_flipped_area_on_the_cat() {
    for (a, b, flip_bound) in [("reference", "0002", 0.2), ("0001", "0002", 0.4)] {
        let Some(pair) = cut_poses(a, b) else {
            eprintln!("point_untangling_removes_most_flipped_area_on_the_cat: shared Sumner cat poses absent, skipped");
            return;
        };
        let stage = FirstStage::of(pair);
        let zp = ZoomOutParams::default();
        let run = |sweeps: usize, region_from_area: f64| {
            let mut p = zp.clone();
            p.point_untangle.sweeps = sweeps;
            p.point_untangle.region_from_area = region_from_area;
            let (reg, m) = stage.refined(&p);
            let info = reg.refinement.unwrap().point_untangle;
            (
                m.flipped_area_ratio_3d,
                m.flipped_faces_3d,
                m.geodesic.unwrap().summary.mean,
                info,
            )
        };
        let from = zp.point_untangle.region_from_area;
        let (off, on) = (run(0, from), run(zp.point_untangle.sweeps, from));
        eprintln!(
            "cat {a} -> {b}: flipped 3D area {:.5} -> {:.5}, geodesic mean {:.5} -> {:.5}, {:?}",
            off.0, on.0, off.2, on.2, on.3
        );
        // the sweeps leave less than the region moves' threshold here: none ran
        assert!(on.3.flipped_area_after_sweeps < from, "{:?}", on.3);
        assert_eq!((on.3.regions_moved, on.3.flipped_after), (0, on.3.flipped_after_sweeps));
        assert!(
            (on.3.flipped_area_after_sweeps - on.0).abs() < 1e-12,
            "the pass's share is the metric's"
        );
        assert_eq!(on.3.flipped_after, on.1, "the pass's count is the metric's");
        assert_eq!(on.3.flipped_before, off.1);
        assert!(on.0 < flip_bound / 100.0, "{a} -> {b}: {}", on.0);
        assert!(on.0 <= 0.5 * off.0, "{a} -> {b}: {} against {}", on.0, off.0);
        assert!(on.2 <= 1.02 * off.2, "{a} -> {b}: {} against {}", on.2, off.2);
        // with them wherever a face stays flipped (decisions 0042, 0054), on the second pair
        // only (its region moves take 8 s)
        if a != "0001" {
            continue;
        }
        let everywhere = run(zp.point_untangle.sweeps, 0.0);
        eprintln!(
            "cat {a} -> {b}, region moves on every pair: flipped 3D area {:.5}, geodesic mean {:.5}, {:?}",
            everywhere.0, everywhere.2, everywhere.3
        );
        assert!(everywhere.3.regions_moved >= 1, "{:?}", everywhere.3);
        assert!(
            everywhere.0 <= 0.5 * on.0,
            "{a} -> {b}: {} against {}",
            everywhere.0,
            on.0
        );
        assert!(
            everywhere.2 <= 1.05 * on.2,
            "{a} -> {b}: {} against {}",
            everywhere.2,
            on.2
        );
    }
}

/// The distance field ZoomOut's landmark coordinates are made of, on Sumner & Popović's horse
/// reference pose (shared folder; skipped when absent) from vertex 8319, a hoof tip (landmark x0
/// of `scripts/cut_pose_set.py`'s cut). The heat method with the mesh's own cotangent operators
/// (its faces have angles down to 0.01°) gives a field of largest value 0.099 √area and smallest
/// −1.16 √area there, where the surface's Dijkstra distance along the edges reaches 1.47 √area.
/// ZoomOut uses the heat method on the intrinsic Delaunay triangulation
/// (`HeatGeodesics::intrinsic_delaunay`). Asserted: its largest value within 0.85–1 of the
/// Dijkstra distance's (edge paths are longer than geodesics), nothing below −0.01 √area, and
/// the median relative gap to Dijkstra over the vertices farther than 0.1 √area below 10 %.
#[test]
fn landmark_fields_on_the_horse_follow_the_surface() {
    use shapespace_analysis::geodesic::HeatGeodesics;
    let Some(file) = shapespace_test_support::shared_file("sumner_deformation_transfer/horse-poses/reference.obj")
    else {
        return;
    };
    let mesh = shapespace_geometry::io::read_mesh(&file).unwrap();
    let source = 8319u32;
    let root = shapespace_geometry::quantities::total_area(&mesh).sqrt();
    let neighbors = Connectivity::of(&mesh).vertex_neighbors(mesh.num_vertices());
    let edges = shapespace_conformal::markers::graph_distances(&mesh, &neighbors, &[(source, 0.0)]);
    let plain = &HeatGeodesics::new(&mesh).unwrap().distances(&[source]).unwrap()[0];
    let idt = &HeatGeodesics::intrinsic_delaunay(&mesh)
        .unwrap()
        .distances(&[source])
        .unwrap()[0];
    let range = |d: &[f64]| {
        (
            d.iter().copied().fold(f64::INFINITY, f64::min) / root,
            d.iter().copied().fold(f64::NEG_INFINITY, f64::max) / root,
        )
    };
    let (edge_max, (plain_min, plain_max), (idt_min, idt_max)) = (range(&edges).1, range(plain), range(idt));
    let mut gaps: Vec<f64> = (0..mesh.num_vertices())
        .filter(|&v| edges[v] > 0.1 * root)
        .map(|v| (idt[v] - edges[v]).abs() / edges[v])
        .collect();
    gaps.sort_by(f64::total_cmp);
    let median_gap = gaps[gaps.len() / 2];
    eprintln!(
        "horse reference from vertex {source}: Dijkstra max {edge_max:.3}; plain heat {plain_min:.3}..{plain_max:.3}; \
         intrinsic Delaunay heat {idt_min:.3}..{idt_max:.3}, median gap to Dijkstra {median_gap:.3} (√area)"
    );
    assert!(
        (0.85 * edge_max..=edge_max).contains(&idt_max),
        "{idt_max} against {edge_max}"
    );
    assert!(idt_min > -0.01, "{idt_min}");
    assert!(median_gap < 0.1, "{median_gap}");
}

/// Two lion poses (shared `outside/lion_poses`; None when absent), cut as the cat poses and
/// slit once from the farthest tip (`prepare --seam 1`, as the lions need); six extremities as
/// landmarks.
fn cut_lions(a: &str, b: &str) -> Option<(TriMesh, TriMesh)> {
    cut_pair(
        &format!("outside/lion_poses/{a}.obj"),
        &format!("outside/lion_poses/{b}.obj"),
        true,
    )
}

/// ZoomOut from two first sizes (20 and 8, the default) on lion pairs cut as in [`cut_lions`],
/// without the landmark pairs in the fits (`landmark_fit` 0, which untwists most of the run
/// from 20, below): the run of smaller nearest-neighbour residual is kept, and its map is
/// exactly that run's alone. Measured (one thread; mean geodesic error from 20 alone, from 8 alone, kept): lion3 →
/// lion1 0.0215, 0.0116, 0.0116 (the run from 20 twists the front paw about its axis); lion3 →
/// lion2 0.0450, 0.0106, 0.0106. Asserted on both: the kept run is the one of smallest
/// residual and its map is that run's; the kept error at most 5 % above the better run's and
/// at most 0.8 of the error from 20 alone. The residual does not always keep the better run:
/// on lion2 → lion3 it keeps the run from 20 (0.0141 against 0.0096 from 8; the other three
/// ordered pairs of these poses it gets right; with the uniform random samples before decision
/// 0058 it had kept the better run there, 0.0092).
#[test]
fn zoomout_runs_from_several_first_sizes_on_the_lions() {
    for (a, b, gain) in [("lion3", "lion1", 0.8), ("lion3", "lion2", 0.8)] {
        let Some(pair) = cut_lions(a, b) else {
            eprintln!("zoomout_runs_from_several_first_sizes_on_the_lions: shared lion poses absent, skipped");
            return;
        };
        let stage = FirstStage::of(pair);
        // without the landmark fit, which keeps the run from 20 from twisting the paw (below)
        let zp = ZoomOutParams {
            landmark_fit: 0.0,
            ..ZoomOutParams::default()
        };
        assert_eq!(zp.k_starts, vec![20, 8]);
        let run = |k_starts: Vec<usize>| {
            let (reg, m) = stage.refined(&ZoomOutParams { k_starts, ..zp.clone() });
            let info = reg.refinement.unwrap();
            (m.geodesic.unwrap().summary.mean, info.runs, info.vertex_map)
        };
        let single = [run(vec![20]), run(vec![8])];
        let (e, runs, map) = run(zp.k_starts.clone());
        eprintln!(
            "lion {a} -> {b}: geodesic mean {:.4} from 20, {:.4} from 8, {e:.4} kept; {runs:?}",
            single[0].0, single[1].0
        );
        assert_eq!(runs.len(), 2);
        for (r, one) in runs.iter().zip(&single) {
            assert_eq!(one.1.len(), 1);
            assert_eq!(
                r.residual, one.1[0].residual,
                "a run's residual does not depend on the others"
            );
        }
        let best = if runs[1].residual < runs[0].residual { 1 } else { 0 };
        assert!(runs[best].kept && !runs[1 - best].kept, "{runs:?}");
        assert_eq!(map, single[best].2, "the kept map is that run's own");
        assert_eq!(e, single[best].0);
        let better = single[0].0.min(single[1].0);
        assert!(e <= 1.05 * better, "{a} -> {b}: {e} against the better run's {better}");
        assert!(
            e <= gain * single[0].0,
            "{a} -> {b}: {e} against {} from 20 alone",
            single[0].0
        );
    }
}

/// The landmark pairs in ZoomOut's fits (`ZoomOutParams::landmark_fit`, decision 0066) on the
/// lion pairs above: each single run (from 20, the run that twists the front paw about its
/// axis when the fits see only the samples, and from 8) with the default weight against
/// without the pairs. Measured (one thread; mean geodesic error with → without): lion3 → lion1
/// from 20 0.0180 → 0.0213, from 8 0.0102 → 0.0116; lion3 → lion2 from 20 0.0128 → 0.0441,
/// from 8 0.0091 → 0.0098. Asserted: every run with the pairs below the same run without them,
/// the runs from 20 at most 0.9 of it. The default refinement keeps the run of smaller
/// residual: 0.0102 and 0.0128 (on lion3 → lion2 the run from 20, the worse of the two; the
/// residual's choice, decision 0055).
#[test]
fn landmark_fit_keeps_the_lion_paw_untwisted() {
    for (a, b) in [("lion3", "lion1"), ("lion3", "lion2")] {
        let Some(pair) = cut_lions(a, b) else {
            eprintln!("landmark_fit_keeps_the_lion_paw_untwisted: shared lion poses absent, skipped");
            return;
        };
        let stage = FirstStage::of(pair);
        let zp = ZoomOutParams::default();
        let run = |landmark_fit: f64, k_starts: Vec<usize>| {
            let p = ZoomOutParams {
                landmark_fit,
                k_starts,
                ..zp.clone()
            };
            stage.refined(&p).1.geodesic.unwrap().summary.mean
        };
        for (k_start, gain) in [(20, 0.9), (8, 1.0)] {
            let with = run(zp.landmark_fit, vec![k_start]);
            let without = run(0.0, vec![k_start]);
            eprintln!("lion {a} -> {b}, from {k_start}: {with:.4} with the landmark fit, {without:.4} without");
            assert!(with < without, "{a} -> {b} from {k_start}: {with} against {without}");
            assert!(
                with <= gain * without,
                "{a} -> {b} from {k_start}: {with} against {without}"
            );
        }
    }
}
