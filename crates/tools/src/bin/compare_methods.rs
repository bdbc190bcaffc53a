//! Measured comparison of the two disk-map constructions (release:
//! `cargo run --release -p shapespace-tools --bin compare_methods`): the Green's
//! function map (`disk_map`, default parameters) and Boundary First Flattening with the disk
//! target (`bff_disk_map`, default parameters), both with the same markers, the same
//! intrinsic Delaunay Laplacian, the same Möbius normalization, fold repair and densities.
//!
//! Cases: hemispheres (p = pole, exact map = stereographic projection), the same with every
//! vertex jittered on the sphere by ±0.15 of the ring spacing (an irregular mesh of the same
//! smooth surface), a cap of half-angle 1 with p off the pole (exact = Möbius ∘
//! stereographic), the planar domain f(D),
//! f(z) = z + 0.3z² (exact = f⁻¹), the 40 bundled ICT faces (landmarks.json markers) and the
//! public disks of the shared datasets folder (`$SHAPESPACE_DATA`, default `../shared/datasets`;
//! automatic markers; a missing one is reported and skipped).
//!
//! Columns: wall time (best of 3, the two methods interleaved in the same process), max / mean
//! |z − z_exact| over vertices and max / mean |λ − λ_exact| over interior vertices (e^{2λ} =
//! image density of the area-π surface, one-ring estimate) where a closed form exists; the quasi-conformal
//! distortion Λ = ln(γmax/γmin) per face (median / p95 / max); folded original faces without
//! repair → after repair (vertex moves); iterations (BFF scale-factor iterations) or sparse
//! solves (Green); the smallest 1 − |z| over interior vertices. Then BFF on the alligator
//! without its crowding check, a refinement study (1-to-4 midpoint subdivision of an ICT face,
//! camelhead and the square plate: the same polyhedral surface, so the same continuum map;
//! levels set by COMPARE_FACE_LEVELS (default 3), COMPARE_CAMEL_LEVELS (3),
//! COMPARE_PLATE_LEVELS (5)) and the 40 ICT faces one by one. SHAPESPACE_SEQ=1: single-threaded
//! faer.

use std::path::PathBuf;
use std::time::Instant;

use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use shapespace_conformal::{
    bff_disk_map, disk_map, BffParams, BoundaryMarker, CenterMarker, ConformalError, DiskMapParams, MarkerFile,
    Markers, Mobius,
};
use shapespace_geometry::prepare::subdivide_midpoint;
use shapespace_geometry::primitives::{spherical_cap, unit_disk};
use shapespace_geometry::TriMesh;

/// A closed-form map: per vertex image and λ.
struct Exact {
    uv: Vec<[f64; 2]>,
    lambda: Vec<f64>,
}

struct Case {
    name: String,
    mesh: TriMesh,
    markers: Markers,
    exact: Option<Exact>,
}

/// The outcome of one method on one case.
struct Outcome {
    uv: Vec<[f64; 2]>,
    lambda: Vec<f64>,
    q_median: f64,
    q_p95: f64,
    q_max: f64,
    flipped: usize,
    repairs: usize,
    steps: String,
    min_gap: f64,
}

#[derive(Clone, Copy, PartialEq)]
enum Method {
    Green,
    Bff,
}

impl Method {
    fn name(self) -> &'static str {
        match self {
            Method::Green => "green",
            Method::Bff => "bff",
        }
    }
}

fn interior_vertices(mesh: &TriMesh) -> Vec<bool> {
    let conn = shapespace_geometry::Connectivity::of(mesh);
    conn.boundary_vertices(mesh.num_vertices()).iter().map(|b| !b).collect()
}

fn min_gap(uv: &[[f64; 2]], mesh: &TriMesh) -> f64 {
    uv.iter()
        .zip(interior_vertices(mesh))
        .filter(|(_, i)| *i)
        .map(|(p, _)| 1.0 - p[0].hypot(p[1]))
        .fold(f64::INFINITY, f64::min)
}

fn run(method: Method, mesh: &TriMesh, markers: &Markers, repair: bool) -> Result<Outcome, ConformalError> {
    match method {
        Method::Green => {
            let params = DiskMapParams {
                repair_folds: repair,
                // the Green's-function construction itself, not its BFF fallback
                bff_fallback: false,
                ..Default::default()
            };
            let dm = disk_map(mesh, markers, &params)?;
            let q = &dm.quality.quasi_conformal_distortion;
            Ok(Outcome {
                min_gap: min_gap(&dm.uv, mesh),
                q_median: q.median,
                q_p95: q.p95,
                q_max: q.max,
                flipped: dm.quality.num_flipped + dm.quality.num_degenerate,
                repairs: dm.info.fold_repairs,
                steps: format!("{} solves", dm.info.linear_solves),
                uv: dm.uv,
                lambda: dm.conformal_factor,
            })
        }
        Method::Bff => {
            let params = BffParams {
                repair_folds: repair,
                ..Default::default()
            };
            let dm = bff_disk_map(mesh, markers, &params)?;
            let q = &dm.quality.quasi_conformal_distortion;
            Ok(Outcome {
                min_gap: dm.info.min_interior_gap,
                q_median: q.median,
                q_p95: q.p95,
                q_max: q.max,
                flipped: dm.quality.num_flipped + dm.quality.num_degenerate,
                repairs: dm.info.fold_repairs,
                steps: format!("{} it", dm.info.iterations),
                uv: dm.uv,
                lambda: dm.conformal_factor,
            })
        }
    }
}

/// Folded faces of the raw map (no repair): 0, the count from the error, or None for another
/// error.
fn raw_folds(method: Method, mesh: &TriMesh, markers: &Markers) -> Option<usize> {
    match run(method, mesh, markers, false) {
        Ok(o) => Some(o.flipped),
        Err(ConformalError::FoldedImage { num_flipped, .. }) => Some(num_flipped),
        Err(_) => None,
    }
}

fn max_mean(a: impl Iterator<Item = f64>) -> (f64, f64) {
    let (mut mx, mut sum, mut n) = (0.0f64, 0.0, 0usize);
    for x in a {
        mx = mx.max(x);
        sum += x;
        n += 1;
    }
    (mx, sum / n.max(1) as f64)
}

fn stereo(alpha: f64, x: [f64; 3]) -> [f64; 2] {
    let n = (x[0] * x[0] + x[1] * x[1] + x[2] * x[2]).sqrt();
    let s = 1.0 / ((1.0 + x[2] / n) * (alpha / 2.0).tan());
    [x[0] / n * s, x[1] / n * s]
}

/// Cap of half-angle α, p = vertex `p`, q = last vertex: exact = M ∘ stereographic with
/// M(stereo(p)) = 0, M(stereo(q)) = 1; λ = ½ ln μ(|w|) − ln|M'(w)|, μ(r) = (1+R²)/(1+R²r²)².
fn cap_case(alpha: f64, rings: usize, p: u32, name: String) -> Case {
    cap_case_of(spherical_cap(alpha, rings), alpha, p, name)
}

/// [`cap_case`] for a given mesh whose vertices lie on the unit sphere inside the cap.
fn cap_case_of(mesh: TriMesh, alpha: f64, p: u32, name: String) -> Case {
    let q = (mesh.num_vertices() - 1) as u32;
    let big_r = (alpha / 2.0).tan();
    let w: Vec<[f64; 2]> = mesh.positions.iter().map(|&x| stereo(alpha, x)).collect();
    let mob = Mobius::normalizing(w[p as usize], w[q as usize]);
    let uv = w.iter().map(|&z| mob.apply(z)).collect();
    let lambda = w
        .iter()
        .map(|z| {
            let r2 = z[0] * z[0] + z[1] * z[1];
            let mu = (1.0 + big_r * big_r) / (1.0 + big_r * big_r * r2).powi(2);
            0.5 * mu.ln() - mob.derivative_abs(*z).ln()
        })
        .collect();
    Case {
        name,
        mesh,
        markers: Markers {
            center: CenterMarker::Vertex(p),
            boundary: BoundaryMarker::Vertex(q),
        },
        exact: Some(Exact { uv, lambda }),
    }
}

/// The hemisphere with every vertex but the pole moved on the sphere by up to ±0.15 ring
/// spacings (boundary vertices only along the boundary circle): an irregular triangulation of
/// the same smooth surface, exact map still stereographic projection of the vertices.
fn jittered_hemisphere(rings: usize) -> Case {
    let alpha = std::f64::consts::FRAC_PI_2;
    let mut case = cap_case(alpha, rings, 0, format!("jittered hemisphere, rings {rings}"));
    let n = case.mesh.num_vertices();
    let h = alpha / rings as f64;
    let mut rng = ChaCha8Rng::seed_from_u64(5);
    for (v, p) in case.mesh.positions.iter_mut().enumerate().skip(1) {
        let th = p[2].clamp(-1.0, 1.0).acos();
        let ph = p[1].atan2(p[0]);
        let (th, ph) = if v >= n - 6 * rings {
            (th, ph + 0.3 * h * (rng.random::<f64>() - 0.5))
        } else {
            let t = th + 0.3 * h * (rng.random::<f64>() - 0.5);
            (t, ph + 0.3 * h / t.sin() * (rng.random::<f64>() - 0.5))
        };
        *p = [th.sin() * ph.cos(), th.sin() * ph.sin(), th.cos()];
    }
    cap_case_of(case.mesh, alpha, 0, case.name)
}

/// f(D), f(z) = z + 0.3z²: exact image z (the disk mesh), λ = ln s + ln|f'(z)|, s² = π/area.
fn quadratic_case(rings: usize) -> Case {
    let disk = unit_disk(rings);
    let z: Vec<[f64; 2]> = disk.positions.iter().map(|p| [p[0], p[1]]).collect();
    let positions = z
        .iter()
        .map(|w| [w[0] + 0.3 * (w[0] * w[0] - w[1] * w[1]), w[1] + 0.6 * w[0] * w[1], 0.0])
        .collect();
    let mesh = TriMesh::new(positions, disk.faces.clone()).expect("valid mesh");
    let area: f64 = shapespace_geometry::quantities::face_areas(&mesh).iter().sum();
    let ln_s = 0.5 * (std::f64::consts::PI / area).ln();
    let lambda = z
        .iter()
        .map(|w| ln_s + (1.0 + 0.6 * w[0]).hypot(0.6 * w[1]).ln())
        .collect();
    let q = (mesh.num_vertices() - 6 * rings) as u32;
    Case {
        name: format!("f(D), f = z + 0.3z², rings {rings}"),
        mesh,
        markers: Markers {
            center: CenterMarker::Vertex(0),
            boundary: BoundaryMarker::Vertex(q),
        },
        exact: Some(Exact { uv: z, lambda }),
    }
}

/// Best-of-3 wall time per method (interleaved) and the outcomes.
fn measure(case: &Case) -> Vec<(Method, f64, Result<Outcome, ConformalError>)> {
    let methods = [Method::Green, Method::Bff];
    let mut best = [f64::INFINITY; 2];
    let mut out: Vec<Option<Result<Outcome, ConformalError>>> = vec![None, None];
    for _ in 0..3 {
        for (k, &m) in methods.iter().enumerate() {
            let t = Instant::now();
            let r = run(m, &case.mesh, &case.markers, true);
            best[k] = best[k].min(t.elapsed().as_secs_f64());
            let failed = r.is_err();
            out[k] = Some(r);
            if failed {
                best[k] = f64::NAN;
            }
        }
    }
    methods
        .iter()
        .zip(best)
        .zip(out)
        .map(|((&m, t), r)| (m, t, r.expect("ran")))
        .collect()
}

fn print_row(case: &Case, m: Method, t: f64, r: &Result<Outcome, ConformalError>) {
    let (v, f) = (case.mesh.num_vertices(), case.mesh.num_faces());
    match r {
        Err(e) => println!("| {} | {v} | {f} | {} | – | error: {e} |||||||", case.name, m.name()),
        Ok(o) => {
            let (ez, el) = match &case.exact {
                Some(ex) => {
                    let z = max_mean(o.uv.iter().zip(&ex.uv).map(|(a, b)| (a[0] - b[0]).hypot(a[1] - b[1])));
                    let interior = interior_vertices(&case.mesh);
                    let l = max_mean(
                        o.lambda
                            .iter()
                            .zip(&ex.lambda)
                            .zip(&interior)
                            .filter(|(_, &i)| i)
                            .map(|((a, b), _)| (a - b).abs()),
                    );
                    (
                        format!("{:.2e} / {:.2e}", z.0, z.1),
                        format!("{:.2e} / {:.2e}", l.0, l.1),
                    )
                }
                None => ("–".into(), "–".into()),
            };
            let raw = raw_folds(m, &case.mesh, &case.markers).map_or("?".into(), |x| x.to_string());
            println!(
                "| {} | {v} | {f} | {} | {:.3} | {ez} | {el} | {:.3} / {:.3} / {:.2} | {raw} → {} ({} moves) | {} | {:.1e} |",
                case.name,
                m.name(),
                t,
                o.q_median,
                o.q_p95,
                o.q_max,
                o.flipped,
                o.repairs,
                o.steps,
                o.min_gap
            );
        }
    }
}

fn header() {
    println!(
        "| case | V | F | method | time s | max / mean \\|z − z*\\| | max / mean \\|λ − λ*\\| | Λ median / p95 / max | folds raw → final | iterations | min 1 − \\|z\\| |"
    );
    println!("|---|---|---|---|---|---|---|---|---|---|---|");
}

fn env_usize(name: &str, default: usize) -> usize {
    std::env::var(name).ok().and_then(|s| s.parse().ok()).unwrap_or(default)
}

fn dist_max_mean(a: &[[f64; 2]], b: &[[f64; 2]]) -> String {
    let (mx, mean) = max_mean(a.iter().zip(b).map(|(p, q)| (p[0] - q[0]).hypot(p[1] - q[1])));
    format!("{mx:.2e} / {mean:.2e}")
}

/// Maps `levels` midpoint subdivisions of `mesh` with both methods (markers resolved on the
/// coarse mesh and kept as vertex indices, which subdivision preserves) and prints the
/// distances on the original vertices.
fn refinement(name: &str, mut mesh: TriMesh, markers: Markers, levels: usize) {
    let n0 = mesh.num_vertices();
    let markers = match disk_map(&mesh, &markers, &DiskMapParams::default()) {
        Ok(dm) => match dm.info.markers.center {
            shapespace_conformal::markers::ResolvedCenter::Vertex(v) => Markers {
                center: CenterMarker::Vertex(v),
                boundary: BoundaryMarker::Vertex(dm.info.markers.boundary_vertex),
            },
            _ => markers,
        },
        Err(_) => markers,
    };
    let mut maps: Vec<[Vec<[f64; 2]>; 2]> = Vec::new();
    let mut rows = Vec::new();
    for level in 0..levels {
        if level > 0 {
            match subdivide_midpoint(&mesh) {
                Ok(m) => mesh = m,
                Err(_) => break,
            }
        }
        let mut pair: [Vec<[f64; 2]>; 2] = [Vec::new(), Vec::new()];
        for (k, m) in [Method::Green, Method::Bff].into_iter().enumerate() {
            let t = Instant::now();
            match run(m, &mesh, &markers, true) {
                Ok(o) => {
                    rows.push((level, mesh.num_vertices(), m, t.elapsed().as_secs_f64()));
                    pair[k] = o.uv[..n0].to_vec();
                }
                Err(e) => {
                    println!(
                        "| {name} | {level} | {} | {} | error: {e} ||||",
                        mesh.num_vertices(),
                        m.name()
                    );
                    return;
                }
            }
        }
        maps.push(pair);
    }
    let last = maps.len() - 1;
    for (level, v, m, t) in rows {
        let k = if m == Method::Green { 0 } else { 1 };
        let prev = if level > 0 {
            dist_max_mean(&maps[level][k], &maps[level - 1][k])
        } else {
            "–".into()
        };
        println!(
            "| {name} | {level} | {v} | {} | {t:.2} | {prev} | {} | {} |",
            m.name(),
            dist_max_mean(&maps[level][k], &maps[last][k]),
            dist_max_mean(&maps[level][k], &maps[level][1 - k])
        );
    }
}

/// BFF on the alligator with `crowding_limit: 0`: how many faces crowd against the circle and
/// how much of their shape survives in f64.
fn alligator_without_crowding_check(mesh: &TriMesh) {
    let params = BffParams {
        crowding_limit: 0.0,
        ..Default::default()
    };
    println!();
    match bff_disk_map(mesh, &Markers::default(), &params) {
        Err(e) => println!("alligator, BFF without the crowding check: error: {e}"),
        Ok(dm) => {
            let Ok((d, _)) = shapespace_conformal::quality::evaluate(mesh, &dm.uv) else {
                return;
            };
            let gap = |v: u32| 1.0 - dm.uv[v as usize][0].hypot(dm.uv[v as usize][1]);
            let crowded: Vec<usize> = (0..mesh.num_faces())
                .filter(|&f| mesh.faces[f].iter().any(|&v| gap(v) < 1e-14))
                .collect();
            let bad = crowded
                .iter()
                .filter(|&&f| d.quasi_conformal_distortion[f] > 0.5)
                .count();
            let lmax = crowded
                .iter()
                .map(|&f| d.quasi_conformal_distortion[f])
                .fold(0.0, f64::max);
            let dmax = dm.face_densities.iter().copied().fold(0.0, f64::max);
            println!(
                "alligator, BFF without the crowding check: {} iterations, {} folded faces, min 1 − |z| = {:.1e}; {} of {} faces have a corner with 1 − |z| < 1e-14, {} of those Λ > 0.5 (max {:.2}); max density {:.1e}",
                dm.info.iterations,
                dm.quality.num_flipped + dm.quality.num_degenerate,
                dm.info.min_interior_gap,
                crowded.len(),
                mesh.num_faces(),
                bad,
                lmax,
                dmax
            );
        }
    }
}

fn main() {
    if std::env::var_os("SHAPESPACE_SEQ").is_some() {
        faer::set_global_parallelism(faer::Par::Seq);
    }
    let half_pi = std::f64::consts::FRAC_PI_2;
    let mut cases: Vec<Case> = Vec::new();
    for rings in [10, 20, 40, 80, 129] {
        cases.push(cap_case(half_pi, rings, 0, format!("hemisphere, rings {rings}")));
    }
    for rings in [10, 20, 40, 80] {
        cases.push(jittered_hemisphere(rings));
    }
    for rings in [10, 20, 40, 80] {
        // p = first vertex of ring round(0.7·rings): 0.7 of the cap radius
        let k = (0.7 * rings as f64).round() as usize;
        let p = (1 + 3 * (k - 1) * k) as u32;
        cases.push(cap_case(1.0, rings, p, format!("cap α=1, p at 0.7 R, rings {rings}")));
    }
    for rings in [10, 20, 40] {
        cases.push(quadratic_case(rings));
    }
    let data = PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../../datasets");
    let public = shapespace_test_support::PUBLIC_DISKS
        .iter()
        .copied()
        .chain([("alligator", shapespace_test_support::BEYOND_F64_DISK)]);
    for (name, rel) in public {
        let Some(path) = shapespace_test_support::shared_file(rel) else {
            continue;
        };
        if let Ok(mesh) = shapespace_geometry::io::read_mesh(&path) {
            cases.push(Case {
                name: name.to_string(),
                mesh,
                markers: Markers::default(),
                exact: None,
            });
        }
    }
    header();
    for case in &cases {
        for (m, t, r) in measure(case) {
            print_row(case, m, t, &r);
        }
    }

    // alligator: what BFF returns when its crowding check is switched off
    let shared = shapespace_test_support::shared_datasets_dir();
    if let Ok(mesh) = shapespace_geometry::io::read_mesh(&shared.join(shapespace_test_support::BEYOND_F64_DISK)) {
        alligator_without_crowding_check(&mesh);
    }

    // refinement of the same polyhedral surface (1-to-4 midpoint subdivision keeps the
    // surface, so the continuum map is the same): distances on the original vertices
    let face_levels = env_usize("COMPARE_FACE_LEVELS", 3);
    let plate_levels = env_usize("COMPARE_PLATE_LEVELS", 5);
    let camel_levels = env_usize("COMPARE_CAMEL_LEVELS", 3);
    println!();
    println!("Midpoint-subdivision refinement (distances on the original vertices, max / mean):");
    println!();
    println!("| mesh | level | V | method | time s | to previous level | to finest level, same method | to the other method |");
    println!("|---|---|---|---|---|---|---|---|");
    if let (Ok(mesh), Ok(mf)) = (
        shapespace_geometry::io::read_mesh(&data.join("faces/id00_neutral.obj")),
        MarkerFile::from_json_file(&data.join("faces/landmarks.json")),
    ) {
        refinement("faces/id00_neutral", mesh, mf.markers, face_levels);
    }
    if let Ok(mesh) = shapespace_geometry::io::read_mesh(&shared.join("libigl_tutorial_data/camelhead.off")) {
        refinement("camelhead", mesh, Markers::default(), camel_levels);
    }
    if let Ok(mesh) = shapespace_geometry::io::read_mesh(&shared.join("goast/plate/plate121.ply")) {
        refinement("plate121", mesh, Markers::default(), plate_levels);
    }

    // the 40 ICT faces: per-method aggregate and the agreement of the two maps
    let Ok(mf) = MarkerFile::from_json_file(&data.join("faces/landmarks.json")) else {
        return;
    };
    let mut names: Vec<PathBuf> = std::fs::read_dir(data.join("faces"))
        .map(|d| {
            d.filter_map(|e| e.ok().map(|e| e.path()))
                .filter(|p| p.extension().is_some_and(|x| x == "obj"))
                .collect()
        })
        .unwrap_or_default();
    names.sort();
    println!();
    println!("ICT faces (landmarks.json markers), per face:");
    println!();
    println!(
        "| face | green s | bff s | green Λ p95 / max | bff Λ p95 / max | folds raw green / bff | repairs green / bff | bff it | max / mean \\|z_bff − z_green\\| | max \\|λ_bff − λ_green\\| |"
    );
    println!("|---|---|---|---|---|---|---|---|---|---|");
    let mut agg = [(0.0f64, 0usize, 0usize, 0usize); 2]; // time, faces with raw folds, repairs, failures
    let mut diffs = Vec::new();
    for path in &names {
        let Ok(mesh) = shapespace_geometry::io::read_mesh(path) else {
            continue;
        };
        let name = path
            .file_stem()
            .map(|s| s.to_string_lossy().into_owned())
            .unwrap_or_default();
        let case = Case {
            name: name.clone(),
            mesh,
            markers: mf.markers.clone(),
            exact: None,
        };
        let res = measure(&case);
        let raw: Vec<String> = [Method::Green, Method::Bff]
            .iter()
            .map(|&m| raw_folds(m, &case.mesh, &case.markers).map_or("?".into(), |x| x.to_string()))
            .collect();
        for (k, (_, t, r)) in res.iter().enumerate() {
            agg[k].0 += t;
            if raw[k] != "0" {
                agg[k].1 += 1;
            }
            match r {
                Ok(o) => agg[k].2 += o.repairs,
                Err(_) => agg[k].3 += 1,
            }
        }
        match (&res[0].2, &res[1].2) {
            (Ok(g), Ok(b)) => {
                let d = max_mean(g.uv.iter().zip(&b.uv).map(|(a, c)| (a[0] - c[0]).hypot(a[1] - c[1])));
                let dl = max_mean(g.lambda.iter().zip(&b.lambda).map(|(a, c)| (a - c).abs()));
                diffs.push(d.0);
                println!(
                    "| {name} | {:.3} | {:.3} | {:.3} / {:.2} | {:.3} / {:.2} | {} / {} | {} / {} | {} | {:.2e} / {:.2e} | {:.2e} |",
                    res[0].1, res[1].1, g.q_p95, g.q_max, b.q_p95, b.q_max, raw[0], raw[1], g.repairs, b.repairs,
                    b.steps, d.0, d.1, dl.0
                );
            }
            _ => println!(
                "| {name} | error: {:?} / {:?} |",
                res[0].2.as_ref().err().map(|e| e.to_string()),
                res[1].2.as_ref().err().map(|e| e.to_string())
            ),
        }
    }
    diffs.sort_by(f64::total_cmp);
    println!();
    for (k, m) in ["green", "bff"].iter().enumerate() {
        println!(
            "{m}: total best time {:.2} s, faces with raw folds {}, total repairs {}, failures {}",
            agg[k].0, agg[k].1, agg[k].2, agg[k].3
        );
    }
    if let (Some(lo), Some(hi)) = (diffs.first(), diffs.last()) {
        println!(
            "max |z_bff − z_green| per face: min {lo:.2e}, median {:.2e}, max {hi:.2e}",
            diffs[diffs.len() / 2]
        );
    }
}
