//! What the untangling with points leaves flipped on one registered pair, and how a variant of
//! it does.
//!
//! `cargo run --release -p shapespace-tools --bin untangle_probe -- SOURCE TARGET [TARGET_MARKERS
//! [CACHE]]` with SOURCE and TARGET meshes of a `register-bench` set (markers beside them, or
//! TARGET_MARKERS: a carried marker file of `register-bench --remeshed`, OUT/truth/NAME.landmarks.json).
//! Runs the OMT first stage and ZoomOut (its untangled vertex map, the point pass off; kept in
//! CACHE, a JSON file, when given), then the untangling with points, and prints the flipped 3D
//! area of the registration metric, the degenerate images' area, how far the residual flips'
//! reference faces lie from their images, and the geodesic error (same triangulation only).
//! `REG44_ROUNDS` and `REG44_RINGS` set the region moves' rounds and rings (defaults of
//! `PointUntangleParams`, 3 and 3, with its area threshold, decision 0054).
use std::path::PathBuf;
use std::time::Instant;

use shapespace_analysis::registration::untangle::{untangle_points, PointUntangleParams, TargetImage};
use shapespace_analysis::registration::{
    disk_image, refine_registration, register_with_maps, registration_area_params, registration_metrics,
    HarmonicParams, Landmarks, Method, MetricParams, Registration, SpectralBasis, ZoomOutParams,
};
use shapespace_conformal::MarkerFile;
use shapespace_geometry::quantities::face_areas;
use shapespace_geometry::vec3::{cross, norm, sub};
use shapespace_geometry::TriMesh;

fn with_points(t: &TriMesh, base: &Registration, pts: &[(u32, [f64; 3])]) -> Registration {
    let mut reg = base.clone();
    for (v, &(f, b)) in pts.iter().enumerate() {
        reg.faces[v] = f;
        reg.bary[v] = b;
        let q = t.face_positions(f as usize);
        reg.points[v] = std::array::from_fn(|d| (0..3).map(|k| b[k] * q[k][d]).sum());
    }
    reg
}

fn report(label: &str, s: &TriMesh, t: &TriMesh, reg: &Registration) {
    let met = registration_metrics(s, t, reg, &MetricParams::default()).unwrap();
    let areas = face_areas(s);
    let total: f64 = areas.iter().sum();
    let mut degenerate = 0.0;
    for (fi, f) in s.faces.iter().enumerate() {
        let p = f.map(|v| reg.points[v as usize]);
        let n = norm(cross(sub(p[1], p[0]), sub(p[2], p[0])));
        let e = norm(sub(p[1], p[0])).max(norm(sub(p[2], p[0])));
        if n <= 1e-9 * e * e {
            degenerate += areas[fi];
        }
    }
    println!(
        "{label}: flipped 3D {:.3} %, degenerate {:.3} %, geodesic mean {:.4} median {:.4}",
        100.0 * met.flipped_area_ratio_3d,
        100.0 * degenerate / total,
        met.geodesic.as_ref().map_or(f64::NAN, |g| g.summary.mean),
        met.geodesic.as_ref().map_or(f64::NAN, |g| g.summary.median),
    );
}

fn main() {
    let args: Vec<String> = std::env::args().collect();
    let sp = PathBuf::from(&args[1]);
    let tp = PathBuf::from(&args[2]);
    let s = shapespace_geometry::io::read_mesh(&sp).unwrap();
    let t = shapespace_geometry::io::read_mesh(&tp).unwrap();
    let ms = MarkerFile::from_json_file(&MarkerFile::sidecar_path(&sp).unwrap()).unwrap();
    let mt = match args.get(3).filter(|a| !a.is_empty()) {
        Some(p) => MarkerFile::from_json_file(&PathBuf::from(p)).unwrap(),
        None => MarkerFile::from_json_file(&MarkerFile::sidecar_path(&tp).unwrap()).unwrap(),
    };
    let cache = args.get(4).map(PathBuf::from);
    let lm = Landmarks::from_named(&ms.landmarks, &mt.landmarks, "probe").unwrap();
    let params = registration_area_params();
    let phi1 = disk_image(&s, &ms.markers, Method::Omt, &params).unwrap();
    let phi2 = disk_image(&t, &mt.markers, Method::Omt, &params).unwrap();
    let mut reg = register_with_maps(&s, &t, &phi1, &phi2, &lm, &HarmonicParams::for_method(Method::Omt)).unwrap();
    let cached: Option<Vec<(u32, [f64; 3])>> = cache
        .as_ref()
        .and_then(|c| std::fs::read_to_string(c).ok())
        .map(|text| serde_json::from_str(&text).unwrap());
    let pts = match cached {
        Some(p) => {
            reg.refinement = Some(shapespace_analysis::registration::RefinementInfo {
                refinement: shapespace_analysis::registration::Refinement::ZoomOut,
                sizes: Vec::new(),
                runs: Vec::new(),
                output: Default::default(),
                eigen_seconds: [0.0; 2],
                iteration_seconds: 0.0,
                vertices_moved: 0,
                untangle: Default::default(),
                point_untangle: Default::default(),
                vertex_map: Vec::new(),
            });
            p
        }
        None => {
            let mut zp = ZoomOutParams::default();
            zp.point_untangle.sweeps = 0;
            let b1 = SpectralBasis::of(&s, zp.k_end, &zp.eigen).unwrap();
            let b2 = SpectralBasis::of(&t, zp.k_end, &zp.eigen).unwrap();
            refine_registration(&s, &t, &mut reg, &lm, &b1, &b2, &zp).unwrap();
            let p: Vec<(u32, [f64; 3])> = reg.faces.iter().copied().zip(reg.bary.iter().copied()).collect();
            if let Some(c) = &cache {
                std::fs::write(c, serde_json::to_string(&p).unwrap()).unwrap();
                eprintln!("zoomout {:.1} s", reg.refinement.as_ref().unwrap().iteration_seconds);
            }
            p
        }
    };
    let base = with_points(&t, &reg, &pts);
    report("vertex map", &s, &t, &base);
    let mut p2 = pts.clone();
    let t0 = Instant::now();
    let mut pp = PointUntangleParams::default();
    if let Ok(r) = std::env::var("REG44_RINGS") {
        pp.region_rings = r.parse().unwrap();
    }
    if let Ok(r) = std::env::var("REG44_ROUNDS") {
        pp.region_rounds = r.parse().unwrap();
    }
    let info = untangle_points(&s, &t, TargetImage::Disk(&base.target_uv), &mut p2, &pp).unwrap();
    println!(
        "points: faces {} -> {} (after sweeps {}, regions moved {}), moved {}, sweeps {}, {:.2} s",
        info.flipped_before,
        info.flipped_after,
        info.flipped_after_sweeps,
        info.regions_moved,
        info.vertices_moved,
        info.sweeps,
        t0.elapsed().as_secs_f64()
    );
    let after = with_points(&t, &base, &p2);
    report("after points", &s, &t, &after);
    residual(&s, &t, &after);
}

/// The residual flipped faces: folded in φ₂ or not, their image's spread and how far the
/// reference face lies, in target mean edge lengths.
fn residual(s: &TriMesh, t: &TriMesh, reg: &Registration) {
    use shapespace_analysis::point_location::PointLocator;
    let locator = PointLocator::new(&reg.target_uv, &t.faces).unwrap();
    let edge = t
        .faces
        .iter()
        .map(|f| {
            shapespace_geometry::quantities::face_edge_lengths(f.map(|w| t.positions[w as usize]))
                .iter()
                .sum::<f64>()
        })
        .sum::<f64>()
        / (3 * t.num_faces()) as f64;
    let areas = face_areas(s);
    let total: f64 = areas.iter().sum();
    let uv: Vec<[f64; 2]> = (0..s.num_vertices())
        .map(|v| {
            let f = t.faces[reg.faces[v] as usize];
            std::array::from_fn(|d| (0..3).map(|k| reg.bary[v][k] * reg.target_uv[f[k] as usize][d]).sum())
        })
        .collect();
    let (mut folded, mut far, mut spread, mut n) = (0.0, 0.0, 0.0, 0);
    let mut rows = Vec::new();
    for (fi, f) in s.faces.iter().enumerate() {
        let p = f.map(|v| reg.points[v as usize]);
        let nn = cross(sub(p[1], p[0]), sub(p[2], p[0]));
        let h = f.map(|v| uv[v as usize]);
        let c = [(h[0][0] + h[1][0] + h[2][0]) / 3.0, (h[0][1] + h[1][1] + h[2][1]) / 3.0];
        let Some(l) = locator.locate(c) else { continue };
        let q = t.face_positions(l.face as usize);
        let r = cross(sub(q[1], q[0]), sub(q[2], q[0]));
        if nn[0] * r[0] + nn[1] * r[1] + nn[2] * r[2] >= 0.0 {
            continue;
        }
        n += 1;
        let sa = (h[1][0] - h[0][0]) * (h[2][1] - h[0][1]) - (h[1][1] - h[0][1]) * (h[2][0] - h[0][0]);
        if sa <= 0.0 {
            folded += areas[fi];
        }
        let cen: [f64; 3] = std::array::from_fn(|d| (p[0][d] + p[1][d] + p[2][d]) / 3.0);
        let qc: [f64; 3] = std::array::from_fn(|d| (q[0][d] + q[1][d] + q[2][d]) / 3.0);
        let dist = norm(sub(cen, qc)) / edge;
        let diam = norm(sub(p[1], p[0]))
            .max(norm(sub(p[2], p[0])))
            .max(norm(sub(p[2], p[1])))
            / edge;
        if dist > 2.0 {
            far += areas[fi];
        }
        if diam > 2.0 {
            spread += areas[fi];
        }
        let cosang = -(nn[0] * r[0] + nn[1] * r[1] + nn[2] * r[2]) / (norm(nn) * norm(r));
        let sp = f.map(|v| s.positions[v as usize]);
        let sdiam = norm(sub(sp[1], sp[0]))
            .max(norm(sub(sp[2], sp[0])))
            .max(norm(sub(sp[2], sp[1])))
            / edge;
        let ang = (0..3)
            .map(|k| {
                let (a, b) = (sub(sp[(k + 1) % 3], sp[k]), sub(sp[(k + 2) % 3], sp[k]));
                ((a[0] * b[0] + a[1] * b[1] + a[2] * b[2]) / (norm(a) * norm(b)))
                    .clamp(-1.0, 1.0)
                    .acos()
                    .to_degrees()
            })
            .fold(180.0, f64::min);
        rows.push((areas[fi] / total, sa <= 0.0, dist, diam, cosang, sdiam, ang));
    }
    rows.sort_by(|a, b| b.0.partial_cmp(&a.0).unwrap());
    println!(
        "residual: {n} faces, folded in phi2 {:.3} %, reference > 2 edges from the image {:.3} %, image diameter > 2 edges {:.3} %",
        100.0 * folded / total,
        100.0 * far / total,
        100.0 * spread / total
    );
    for r in rows.iter().take(12) {
        println!(
            "  area {:.4} % folded {} ref dist {:.2} diam {:.2} -cos {:.3} source diam {:.2} min angle {:.2}",
            100.0 * r.0,
            r.1,
            r.2,
            r.3,
            r.4,
            r.5,
            r.6
        );
    }
}
