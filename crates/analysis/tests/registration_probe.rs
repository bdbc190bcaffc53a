//! Probe (ignored): harmonic-map variants of the registration on the wolf poses, OMT and
//! conformal disk maps. `cargo test --release -p shapespace-analysis --test integration registration_probe:: -- --ignored --nocapture`

use std::path::{Path, PathBuf};
use std::time::Instant;

use shapespace_analysis::fold_repair::count_folded_faces;
use shapespace_analysis::registration::{
    disk_image, register_with_maps, registration_area_params, registration_metrics, HarmonicParams, HarmonicWeights,
    Landmarks, Method, MetricParams,
};
use shapespace_conformal::MarkerFile;
use shapespace_geometry::TriMesh;

fn dir(class: &str) -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("../../datasets/poses")
        .join(class)
}

#[test]
#[ignore]
fn probe_harmonic_variants() {
    let class = std::env::var("PROBE_CLASS").unwrap_or_else(|_| "wolf".into());
    let meshes: Vec<TriMesh> = (0..3)
        .map(|i| shapespace_geometry::io::read_mesh(&dir(&class).join(format!("{class}{i}.off"))).unwrap())
        .collect();
    let mf = MarkerFile::from_json_file(&dir(&class).join("landmarks.json")).unwrap();
    let lm = Landmarks::from_named(&mf.landmarks, &mf.landmarks, "landmarks.json").unwrap();
    let none = Landmarks::from_pairs(vec![], "none");
    let p = registration_area_params();
    let methods: Vec<Method> = match std::env::var("PROBE_METHODS") {
        Ok(s) => s.split(',').map(|m| m.parse().unwrap()).collect(),
        Err(_) => vec![Method::Omt, Method::Conformal],
    };
    for method in methods {
        let maps: Vec<_> = meshes
            .iter()
            .map(|m| {
                let d = disk_image(m, &mf.markers, method, &p).unwrap();
                eprintln!(
                    "{method}: disk map {:.2}s, folded {} (exact), flipped {}",
                    d.seconds,
                    count_folded_faces(&m.faces, &d.uv),
                    d.flipped_faces
                );
                d
            })
            .collect();
        let variants: Vec<(HarmonicWeights, usize, bool)> = match std::env::var("PROBE_VARIANTS") {
            // e.g. planar:8:1,mean-value:1:0
            Ok(v) => v
                .split(',')
                .map(|t| {
                    let f: Vec<&str> = t.split(':').collect();
                    (f[0].parse().unwrap(), f[1].parse().unwrap(), f[2] == "1")
                })
                .collect(),
            Err(_) => vec![
                (HarmonicWeights::Planar, 1, false),
                (HarmonicWeights::Planar, 1, true),
                (HarmonicWeights::Planar, 4, true),
                (HarmonicWeights::MeanValue, 1, false),
                (HarmonicWeights::MeanValue, 1, true),
                (HarmonicWeights::IntrinsicDelaunay, 1, false),
                (HarmonicWeights::IntrinsicDelaunay, 1, true),
            ],
        };
        for (lmk, lname) in [(&lm, "landmarks"), (&none, "no-landmarks")] {
            for &(w, rep, fr) in &variants {
                if lname == "no-landmarks" && (rep > 1 || fr) {
                    continue;
                }
                let hp = HarmonicParams {
                    weights: w,
                    fold_repair: fr,
                    foldover_free: false,
                    release_landmarks: false,
                    landmark_steps: rep,
                };
                let mut acc = [0.0f64; 9];
                let mut k = 0.0;
                let mut errs = Vec::new();
                for i in 0..3 {
                    for j in 0..3 {
                        if i == j {
                            continue;
                        }
                        let t = Instant::now();
                        let reg = match register_with_maps(&meshes[i], &meshes[j], &maps[i], &maps[j], lmk, &hp) {
                            Ok(r) => r,
                            Err(e) => {
                                errs.push(format!("{i}->{j}: {e}"));
                                continue;
                            }
                        };
                        let tg = t.elapsed().as_secs_f64();
                        let met = registration_metrics(&meshes[i], &meshes[j], &reg, &MetricParams::default()).unwrap();
                        let g = met.geodesic.as_ref().unwrap().summary;
                        for (a, v) in acc.iter_mut().zip([
                            100.0 * met.flipped_area_ratio,
                            100.0 * met.flipped_area_ratio_3d,
                            reg.harmonic_folded as f64,
                            met.flipped_faces as f64,
                            met.flipped_faces_3d as f64,
                            g.mean,
                            g.median,
                            tg,
                            reg.harmonic_fold_repair
                                .as_ref()
                                .map_or(reg.harmonic_folded, |u| u.folded_after) as f64,
                        ]) {
                            *a += v;
                        }
                        k += 1.0;
                        if std::env::var("PROBE_VERBOSE").is_ok() {
                            eprintln!(
                                "  {i}->{j}: g folded {} left {:?} 3D flipped {}",
                                reg.harmonic_folded, reg.harmonic_fold_repair, met.flipped_faces_3d
                            );
                        }
                    }
                }
                let a = acc.map(|x| x / k);
                eprintln!(
                    "{method} {lname} {:>18} steps={rep:<3} untangle={fr:<5}: flipped% disk {:.4} 3D {:.3} | g folded {:.1} left {:.1} flipped faces {:.1} 3D {:.1} | geo mean {:.4} median {:.4} | g+comp {:.3}s | errors {:?}",
                    w.name(), a[0], a[1], a[2], a[8], a[3], a[4], a[5], a[6], a[7], errs
                );
            }
        }
    }
}
