//! Where the refined registrations' flipped 3D area sits, and what ZoomOut spends its time on.
//!
//! `cargo run --release -p shapespace-tools --bin flip_probe -- SET/CLASS [MAX_PAIRS [SWEEPS
//! [pairs|nopairs [K_STEP]]]]` with `SET/CLASS` a folder of cut poses sharing their
//! triangulation (`scripts/cut_pose_set.py`, landmarks beside them). Per ordered pair (OMT first
//! stage, ZoomOut's untangled vertex map with the defaults): the flipped 3D area of the
//! registration metric, split by what the flipped images are (a face of the target, three
//! mutually adjacent vertices, spread over more than one edge, collapsed, folded in the target's
//! disk φ₂) and by their distance in rings from the cut, with the vertex untangling's own count
//! of flipped faces after it; the seconds of the first stage, the eigenpairs, the landmark
//! distance fields, the iterations and the untangling; the untangling with points applied to
//! that map and to a variant (vertex untangling with SWEEPS sweeps, default 0, with or without
//! its pair moves, ZoomOut's step K_STEP); the connected components of the flipped faces.
use std::path::{Path, PathBuf};
use std::time::Instant;

use shapespace_analysis::geodesic::HeatGeodesics;
use shapespace_analysis::point_location::PointLocator;
use shapespace_analysis::registration::untangle::{untangle_points, PointUntangleParams, TargetImage};
use shapespace_analysis::registration::{
    disk_image, refine_registration, register_with_maps, registration_area_params, registration_metrics,
    HarmonicParams, Landmarks, Method, MetricParams, Registration, SpectralBasis, ZoomOutParams,
};
use shapespace_conformal::MarkerFile;
use shapespace_geometry::quantities::face_areas;
use shapespace_geometry::vec3::{cross, dot, sub};
use shapespace_geometry::{Connectivity, TriMesh};

/// The metric's flipped faces (registration/metrics.rs), recomputed face by face.
fn metric_flips(source: &TriMesh, target: &TriMesh, reg: &Registration) -> (Vec<bool>, Vec<[f64; 2]>) {
    let locator = PointLocator::new(&reg.target_uv, &target.faces).unwrap();
    let uv: Vec<[f64; 2]> = (0..source.num_vertices())
        .map(|v| {
            let t = target.faces[reg.faces[v] as usize];
            let mut u = [0.0; 2];
            for k in 0..3 {
                for d in 0..2 {
                    u[d] += reg.bary[v][k] * reg.target_uv[t[k] as usize][d];
                }
            }
            u
        })
        .collect();
    let flips = source
        .faces
        .iter()
        .map(|f| {
            let p = f.map(|v| reg.points[v as usize]);
            let n = cross(sub(p[1], p[0]), sub(p[2], p[0]));
            let h = f.map(|v| uv[v as usize]);
            let c = [(h[0][0] + h[1][0] + h[2][0]) / 3.0, (h[0][1] + h[1][1] + h[2][1]) / 3.0];
            let r = locator.locate(c).map_or([0.0; 3], |l| {
                let q = target.face_positions(l.face as usize);
                cross(sub(q[1], q[0]), sub(q[2], q[0]))
            });
            dot(n, r) < 0.0
        })
        .collect();
    (flips, uv)
}

fn main() {
    let args: Vec<String> = std::env::args().collect();
    let dir = PathBuf::from(args.get(1).expect("usage: flip_probe SET/CLASS [MAX_PAIRS]"));
    let max_pairs: usize = args.get(2).map_or(usize::MAX, |s| s.parse().unwrap());
    let mut files: Vec<PathBuf> = std::fs::read_dir(&dir)
        .unwrap()
        .filter_map(|e| e.ok().map(|e| e.path()))
        .filter(|p| p.extension().is_some_and(|e| e == "off" || e == "obj"))
        .collect();
    files.sort();
    let meshes: Vec<TriMesh> = files
        .iter()
        .map(|f| shapespace_geometry::io::read_mesh(f).unwrap())
        .collect();
    let markers: Vec<MarkerFile> = files
        .iter()
        .map(|f| MarkerFile::from_json_file(&MarkerFile::sidecar_path(f).unwrap()).unwrap())
        .collect();
    // ZoomOut's untangled vertex map: the untangling with points is applied below, explicitly
    let mut zp = ZoomOutParams::default();
    zp.point_untangle.sweeps = 0;
    let params = registration_area_params();
    let mut maps = Vec::new();
    let mut bases = Vec::new();
    for (m, mf) in meshes.iter().zip(&markers) {
        maps.push(disk_image(m, &mf.markers, Method::Omt, &params).unwrap());
        bases.push(SpectralBasis::of(m, zp.k_end, &zp.eigen).unwrap());
    }
    let name = |p: &Path| p.file_stem().unwrap().to_string_lossy().to_string();
    println!("| pair | flipped 3D % | face of S2 % | adjacent % | spread % | collapsed-ish % | disk-folded % | vertex untangling: flipped faces after | ring 0-2 from cut % | ring ≥ 10 % | geodesic mean |");
    println!("|---|---|---|---|---|---|---|---|---|---|---|");
    let mut timing_rows = Vec::new();
    let mut variant_rows = Vec::new();
    let mut done = 0;
    for i in 0..meshes.len() {
        for j in 0..meshes.len() {
            if i == j || done >= max_pairs {
                continue;
            }
            done += 1;
            let (s, t) = (&meshes[i], &meshes[j]);
            let lm = Landmarks::from_named(&markers[i].landmarks, &markers[j].landmarks, "probe").unwrap();
            let t0 = Instant::now();
            let mut reg =
                register_with_maps(s, t, &maps[i], &maps[j], &lm, &HarmonicParams::for_method(Method::Omt)).unwrap();
            let first = reg.timings.total;
            let harmonic = t0.elapsed().as_secs_f64();
            let tl = Instant::now();
            let (_a, _b) = rayon::join(
                || {
                    HeatGeodesics::new(s)
                        .unwrap()
                        .distances(&lm.pairs.iter().map(|p| p.0).collect::<Vec<_>>())
                },
                || {
                    HeatGeodesics::new(t)
                        .unwrap()
                        .distances(&lm.pairs.iter().map(|p| p.1).collect::<Vec<_>>())
                },
            );
            let landmark_seconds = tl.elapsed().as_secs_f64();
            refine_registration(s, t, &mut reg, &lm, &bases[i], &bases[j], &zp).unwrap();
            let info = reg.refinement.clone().unwrap();
            let met = registration_metrics(s, t, &reg, &MetricParams::default()).unwrap();
            // analysis of the metric's flips
            let (flips, uv) = metric_flips(s, t, &reg);
            let areas = face_areas(s);
            let total: f64 = areas.iter().sum();
            let conn_t = Connectivity::of(t);
            let nb_t = conn_t.vertex_neighbors(t.num_vertices());
            let conn_s = Connectivity::of(s);
            let nb_s = conn_s.vertex_neighbors(s.num_vertices());
            // rings from the cut on S1
            let mut ring = vec![usize::MAX; s.num_vertices()];
            let mut frontier: Vec<usize> = conn_s
                .boundary_vertices(s.num_vertices())
                .iter()
                .enumerate()
                .filter(|(_, &b)| b)
                .map(|(v, _)| v)
                .collect();
            for &v in &frontier {
                ring[v] = 0;
            }
            let mut r = 0;
            while !frontier.is_empty() {
                r += 1;
                let mut next = Vec::new();
                for &v in &frontier {
                    for &u in &nb_s[v] {
                        if ring[u as usize] == usize::MAX {
                            ring[u as usize] = r;
                            next.push(u as usize);
                        }
                    }
                }
                frontier = next;
            }
            let vmap: Vec<u32> = (0..s.num_vertices())
                .map(|v| {
                    let b = reg.bary[v];
                    let k = (0..3).fold(0, |a, i| if b[i] > b[a] { i } else { a });
                    t.faces[reg.faces[v] as usize][k]
                })
                .collect();
            let mut acc = [0.0f64; 8];
            for (fi, f) in s.faces.iter().enumerate() {
                if !flips[fi] {
                    continue;
                }
                let a = areas[fi];
                acc[0] += a;
                let w = f.map(|v| vmap[v as usize]);
                let is_face = conn_t.vertex_faces[w[0] as usize]
                    .iter()
                    .any(|&g| t.faces[g as usize].contains(&w[1]) && t.faces[g as usize].contains(&w[2]));
                let adjacent = (0..3).all(|k| nb_t[w[k] as usize].contains(&w[(k + 1) % 3]));
                let collapsed = w[0] == w[1] || w[1] == w[2] || w[0] == w[2];
                if is_face {
                    acc[1] += a;
                } else if adjacent {
                    acc[2] += a;
                } else if collapsed {
                    acc[4] += a;
                } else {
                    acc[3] += a;
                }
                let h = f.map(|v| uv[v as usize]);
                let sa = (h[1][0] - h[0][0]) * (h[2][1] - h[0][1]) - (h[1][1] - h[0][1]) * (h[2][0] - h[0][0]);
                if sa <= 0.0 {
                    acc[5] += a;
                }
                let mind = f.iter().map(|&v| ring[v as usize]).min().unwrap();
                if mind <= 2 {
                    acc[6] += a;
                }
                if mind >= 10 {
                    acc[7] += a;
                }
            }
            // the point untangling after the vertex map, with and without the vertex untangling
            let mut zp_nu = zp.clone();
            let variant: Vec<String> = std::env::args().skip(3).collect();
            zp_nu.untangle.sweeps = variant.first().map_or(0, |s| s.parse().unwrap());
            zp_nu.untangle.pair_moves = variant.get(1).is_none_or(|s| s == "pairs");
            if let Some(c) = variant.get(3) {
                zp_nu.k_step = c.parse().unwrap();
            }
            let mut reg_nu =
                register_with_maps(s, t, &maps[i], &maps[j], &lm, &HarmonicParams::for_method(Method::Omt)).unwrap();
            refine_registration(s, t, &mut reg_nu, &lm, &bases[i], &bases[j], &zp_nu).unwrap();
            let met_nu = registration_metrics(s, t, &reg_nu, &MetricParams::default()).unwrap();
            for (label, base, mbase) in [
                ("vertex untangling", &reg, &met),
                ("variant vertex untangling", &reg_nu, &met_nu),
            ] {
                let mut pts: Vec<(u32, [f64; 3])> = base.faces.iter().copied().zip(base.bary.iter().copied()).collect();
                let pinfo = untangle_points(
                    s,
                    t,
                    TargetImage::Disk(&base.target_uv),
                    &mut pts,
                    &PointUntangleParams::default(),
                )
                .unwrap();
                let mut reg2 = base.clone();
                for v in 0..s.num_vertices() {
                    let (f, b) = pts[v];
                    reg2.faces[v] = f;
                    reg2.bary[v] = b;
                    let q = t.face_positions(f as usize);
                    reg2.points[v] = std::array::from_fn(|d| (0..3).map(|k| b[k] * q[k][d]).sum());
                }
                let met2 = registration_metrics(s, t, &reg2, &MetricParams::default()).unwrap();
                variant_rows.push(format!(
                    "| {} → {} | {label} + points: flipped 3D {:.2} % → {:.2} %, mean {:.4} → {:.4}, median {:.4} → {:.4}, faces {} → {}, moved {}, sweeps {}, {:.2} s (vertex untangling {:.2} s, iterations {:.2} s) |",
                    name(&files[i]),
                    name(&files[j]),
                    100.0 * mbase.flipped_area_ratio_3d,
                    100.0 * met2.flipped_area_ratio_3d,
                    mbase.geodesic.as_ref().map_or(f64::NAN, |g| g.summary.mean),
                    met2.geodesic.as_ref().map_or(f64::NAN, |g| g.summary.mean),
                    mbase.geodesic.as_ref().map_or(f64::NAN, |g| g.summary.median),
                    met2.geodesic.as_ref().map_or(f64::NAN, |g| g.summary.median),
                    pinfo.flipped_before,
                    pinfo.flipped_after,
                    pinfo.vertices_moved,
                    pinfo.sweeps,
                    pinfo.seconds,
                    base.refinement.as_ref().unwrap().untangle.seconds,
                    base.refinement.as_ref().unwrap().iteration_seconds,
                ));
            }
            let pct = |x: f64| 100.0 * x / total;
            // connected components of the flipped faces (sharing a vertex)
            let mut comp = vec![usize::MAX; s.num_faces()];
            let mut sizes = Vec::new();
            for f0 in 0..s.num_faces() {
                if !flips[f0] || comp[f0] != usize::MAX {
                    continue;
                }
                let id = sizes.len();
                let mut stack = vec![f0];
                comp[f0] = id;
                let mut size = (0usize, 0.0f64, usize::MAX);
                while let Some(f) = stack.pop() {
                    size.0 += 1;
                    size.1 += areas[f];
                    for &v in &s.faces[f] {
                        size.2 = size.2.min(ring[v as usize]);
                        for &g in &conn_s.vertex_faces[v as usize] {
                            let g = g as usize;
                            if flips[g] && comp[g] == usize::MAX {
                                comp[g] = id;
                                stack.push(g);
                            }
                        }
                    }
                }
                sizes.push(size);
            }
            sizes.sort_by_key(|c| std::cmp::Reverse(c.0));
            let big: f64 = sizes.iter().filter(|c| c.0 >= 10).map(|c| c.1).sum();
            variant_rows.push(format!(
                "| {} → {} | {} components; faces of the largest: {:?}; area in components of ≥ 10 faces: {:.2} % of {:.2} % |",
                name(&files[i]),
                name(&files[j]),
                sizes.len(),
                sizes.iter().take(8).map(|c| c.0).collect::<Vec<_>>(),
                pct(big),
                pct(acc[0]),
            ));
            println!(
                "| {} → {} | {:.2} ({:.2}) | {:.2} | {:.2} | {:.2} | {:.2} | {:.2} | ({} faces) | {:.2} | {:.2} | {:.4} |",
                name(&files[i]),
                name(&files[j]),
                pct(acc[0]),
                100.0 * met.flipped_area_ratio_3d,
                pct(acc[1]),
                pct(acc[2]),
                pct(acc[3]),
                pct(acc[4]),
                pct(acc[5]),
                info.untangle.flipped_after,
                pct(acc[6]),
                pct(acc[7]),
                met.geodesic.as_ref().map_or(f64::NAN, |g| g.summary.mean),
            );
            timing_rows.push(format!(
                "| {} → {} | {:.2} | {:.2} | {:.2} + {:.2} | {:.2} | {:.2} | {:.2} | {} → {} |",
                name(&files[i]),
                name(&files[j]),
                first,
                harmonic,
                info.eigen_seconds[0],
                info.eigen_seconds[1],
                landmark_seconds,
                info.iteration_seconds - info.untangle.seconds - landmark_seconds,
                info.untangle.seconds,
                info.untangle.flipped_before,
                info.untangle.flipped_after,
            ));
        }
    }
    println!();
    println!("| pair | first stage s (with disk maps) | g + composition s | eigenpairs s | landmark fields s (approx.) | iterations s | untangle s | untangle flipped before → after |");
    println!("|---|---|---|---|---|---|---|---|");
    for r in timing_rows {
        println!("{r}");
    }
    println!();

    for r in variant_rows {
        println!("{r}");
    }
}
