//! Why a first-stage registration onto a remeshed pose goes wrong where the one onto the pose
//! itself does not: both targets' disk maps compared through the carried ground truth, the
//! harmonic map g onto each (folds before and after its repair), and the first stage's error
//! per landmark region, before and after ZoomOut (the defaults).
//!
//! `cargo run --release -p shapespace-tools --bin remesh_probe -- SOURCE TARGET REMESHED
//! REMESHED_MARKERS.json TRUTH.csv [pin-at-points]` with SOURCE, TARGET two cut poses sharing their
//! triangulation (markers beside them), REMESHED the remeshing of TARGET and its carried markers
//! and ground truth as `register-bench --remeshed` writes them (`OUT/truth/NAME.*`). With
//! `pin-at-points` the landmarks of g on the remeshing are pinned at the disk images of the
//! pose landmarks' closest points instead of at their carried vertices. Regions: the target
//! pose's vertices by their nearest landmark in space.
use std::path::{Path, PathBuf};

use shapespace_analysis::fold_repair::count_folded_faces;
use shapespace_analysis::registration::{
    disk_image, refine_registration, register_with_maps, registration_area_params, DiskImage, HarmonicParams,
    Landmarks, Method, Registration, SpectralBasis, ZoomOutParams,
};
use shapespace_conformal::MarkerFile;
use shapespace_geometry::TriMesh;

fn read(p: &Path) -> TriMesh {
    shapespace_geometry::io::read_mesh(p).unwrap()
}

fn dist(a: [f64; 3], b: [f64; 3]) -> f64 {
    (0..3).map(|d| (a[d] - b[d]).powi(2)).sum::<f64>().sqrt()
}

fn d2(a: [f64; 2], b: [f64; 2]) -> f64 {
    ((a[0] - b[0]).powi(2) + (a[1] - b[1]).powi(2)).sqrt()
}

fn main() {
    let a: Vec<PathBuf> = std::env::args().skip(1).map(PathBuf::from).collect();
    let (src, tgt, rem) = (read(&a[0]), read(&a[1]), read(&a[2]));
    let ms = MarkerFile::from_json_file(&MarkerFile::sidecar_path(&a[0]).unwrap()).unwrap();
    let mt = MarkerFile::from_json_file(&MarkerFile::sidecar_path(&a[1]).unwrap()).unwrap();
    let mr = MarkerFile::from_json_file(&a[3]).unwrap();
    let truth: Vec<(u32, [f64; 3])> = std::fs::read_to_string(&a[4])
        .unwrap()
        .lines()
        .skip(1)
        .map(|l| {
            let x: Vec<&str> = l.split(',').collect();
            (
                x[1].parse().unwrap(),
                [x[2].parse().unwrap(), x[3].parse().unwrap(), x[4].parse().unwrap()],
            )
        })
        .collect();
    let params = registration_area_params();
    let phi1 = disk_image(&src, &ms.markers, Method::Omt, &params).unwrap();
    let phi_t = disk_image(&tgt, &mt.markers, Method::Omt, &params).unwrap();
    let phi_r = disk_image(&rem, &mr.markers, Method::Omt, &params).unwrap();
    let at = |phi: &DiskImage, m: &TriMesh, f: u32, b: [f64; 3]| -> [f64; 2] {
        let t = m.faces[f as usize];
        std::array::from_fn(|d| (0..3).map(|k| b[k] * phi.uv[t[k] as usize][d]).sum())
    };
    println!(
        "disk maps: source flipped {}, target flipped {}, remeshed flipped {}; OT errors {:.1e} {:.1e} {:.1e}",
        phi1.flipped_faces,
        phi_t.flipped_faces,
        phi_r.flipped_faces,
        phi1.ot_max_relative_error,
        phi_t.ot_max_relative_error,
        phi_r.ot_max_relative_error
    );
    let lm_t = Landmarks::from_named(&ms.landmarks, &mt.landmarks, "same").unwrap();
    let lm_r = Landmarks::from_named(&ms.landmarks, &mr.landmarks, "remeshed").unwrap();
    let area = shapespace_geometry::quantities::total_area(&tgt);
    // region of each target vertex: its nearest landmark in 3D
    let region: Vec<usize> = tgt
        .positions
        .iter()
        .map(|&p| {
            (0..lm_t.pairs.len())
                .min_by(|&i, &j| {
                    let (pi, pj) = (
                        tgt.positions[lm_t.pairs[i].1 as usize],
                        tgt.positions[lm_t.pairs[j].1 as usize],
                    );
                    dist(p, pi).partial_cmp(&dist(p, pj)).unwrap()
                })
                .unwrap()
        })
        .collect();
    println!(
        "| landmark | φ₁(l1) | φ₂(l2) pose | φ₂(l2) remeshed | remeshed disk map vs pose's, region median / max |"
    );
    println!("|---|---|---|---|---|");
    for k in 0..lm_t.pairs.len() {
        let mut dd: Vec<f64> = (0..tgt.num_vertices())
            .filter(|&w| region[w] == k)
            .map(|w| d2(phi_t.uv[w], at(&phi_r, &rem, truth[w].0, truth[w].1)))
            .collect();
        dd.sort_by(|x, y| x.partial_cmp(y).unwrap());
        println!(
            "| {} | {:.4?} | {:.4?} | {:.4?} | {:.4} / {:.4} |",
            lm_t.names[k],
            phi1.uv[lm_t.pairs[k].0 as usize],
            phi_t.uv[lm_t.pairs[k].1 as usize],
            phi_r.uv[lm_r.pairs[k].1 as usize],
            dd[dd.len() / 2],
            dd[dd.len() - 1]
        );
    }
    // the remeshed vertices nearest (3D) to each pose landmark: distance over √area, φ₂
    for k in 0..lm_t.pairs.len() {
        let x = tgt.positions[lm_t.pairs[k].1 as usize];
        let mut near: Vec<(f64, usize)> = (0..rem.num_vertices())
            .map(|w| (dist(x, rem.positions[w]), w))
            .collect();
        near.sort_by(|a, b| a.partial_cmp(b).unwrap());
        println!(
            "{}: carried {} at {:.4}; nearest: {}",
            lm_t.names[k],
            lm_r.pairs[k].1,
            dist(x, rem.positions[lm_r.pairs[k].1 as usize]) / area.sqrt(),
            near[..6]
                .iter()
                .map(|&(d, w)| format!("{w} {:.4} {:.3?}", d / area.sqrt(), phi_r.uv[w]))
                .collect::<Vec<_>>()
                .join("; ")
        );
    }
    let hp = HarmonicParams::for_method(Method::Omt);
    let report = |label: &str, reg: &Registration, truth_of: &dyn Fn(usize) -> [f64; 3]| {
        let after = count_folded_faces(&src.faces, &reg.harmonic_uv);
        let mut per = vec![(0usize, 0usize, 0.0f64); lm_t.pairs.len()];
        for v in 0..src.num_vertices() {
            let e = dist(reg.points[v], truth_of(v)) / area.sqrt();
            let r = &mut per[region[v]];
            r.0 += 1;
            r.1 += (e > 0.1) as usize;
            r.2 += e;
        }
        println!(
            "{label}: g folded {} before repair, {} after ({:?}); steps {}; per region (share > 0.1 √area, mean 3D error): {}",
            reg.harmonic_folded,
            after,
            reg.harmonic_fold_repair.as_ref().map(|u| (u.sweeps, u.moves)),
            reg.harmonic_steps,
            per.iter()
                .enumerate()
                .map(|(k, r)| format!("{}: {:.2} {:.4}", lm_t.names[k], r.1 as f64 / r.0 as f64, r.2 / r.0 as f64))
                .collect::<Vec<_>>()
                .join(", ")
        );
    };
    let reg_t = register_with_maps(&src, &tgt, &phi1, &phi_t, &lm_t, &hp).unwrap();
    report("same", &reg_t, &|v| tgt.positions[v]);
    // experiment: pins at the disk image of the landmarks' closest points instead of the vertices
    let mut phi_r = phi_r.clone();
    if a.get(5).is_some_and(|s| s.as_os_str() == "pin-at-points") {
        for k in 0..lm_t.pairs.len() {
            let (f, b) = truth[lm_t.pairs[k].1 as usize];
            let p = at(&phi_r, &rem, f, b);
            println!(
                "pin {}: {:?} -> {:?}",
                lm_t.names[k], phi_r.uv[lm_r.pairs[k].1 as usize], p
            );
            phi_r.uv[lm_r.pairs[k].1 as usize] = p;
        }
    }
    let reg_r = register_with_maps(&src, &rem, &phi1, &phi_r, &lm_r, &hp).unwrap();
    let tp = |v: usize| -> [f64; 3] {
        let (f, b) = truth[v];
        let t = rem.faces[f as usize];
        std::array::from_fn(|d| (0..3).map(|k| b[k] * rem.positions[t[k] as usize][d]).sum())
    };
    report("remeshed", &reg_r, &tp);
    // ZoomOut after each
    let zp = ZoomOutParams::default();
    let (bs, bt, br) = (
        SpectralBasis::of(&src, zp.k_end, &zp.eigen).unwrap(),
        SpectralBasis::of(&tgt, zp.k_end, &zp.eigen).unwrap(),
        SpectralBasis::of(&rem, zp.k_end, &zp.eigen).unwrap(),
    );
    let mut reg_t = reg_t;
    refine_registration(&src, &tgt, &mut reg_t, &lm_t, &bs, &bt, &zp).unwrap();
    report("same + zoomout", &reg_t, &|v| tgt.positions[v]);
    let mut reg_r = reg_r;
    refine_registration(&src, &rem, &mut reg_r, &lm_r, &bs, &br, &zp).unwrap();
    report("remeshed + zoomout", &reg_r, &tp);
}
