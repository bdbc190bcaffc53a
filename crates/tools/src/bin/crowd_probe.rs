//! Probe: how the conformal image of a TOSCA mesh (cut as `shapespace prepare` does) crowds its
//! points. `cargo run --release -p shapespace-tools --bin crowd_probe -- dog0 victoria0`.
//! Prints, per mesh, the histogram of log10(nearest-neighbour distance / mean spacing) and, for
//! thresholds t, the clusters (components of the graph of Delaunay edges shorter than
//! t × spacing): count, largest, their total target mass, and the worst separation ratio
//! (cluster diameter / distance from the cluster to its nearest outside point).
use shapespace_tools::crowding;

use shapespace_analysis::area_preserving::{transport_problem, AreaPreservingParams};
use shapespace_conformal::Markers;
use shapespace_geometry::prepare::{prepare_disk, PrepareOptions};

fn find(p: &mut [usize], i: usize) -> usize {
    let mut r = i;
    while p[r] != r {
        r = p[r];
    }
    let mut j = i;
    while p[j] != r {
        let n = p[j];
        p[j] = r;
        j = n;
    }
    r
}

fn dist(a: [f64; 2], b: [f64; 2]) -> f64 {
    (a[0] - b[0]).hypot(a[1] - b[1])
}

fn main() {
    let tosca = shapespace_test_support::shared_datasets_dir().join("tosca"); // $SHAPESPACE_DATA
    for name in std::env::args().skip(1) {
        let mesh = shapespace_geometry::io::read_mesh(&tosca.join(format!("{name}.off"))).unwrap();
        let (mesh, _, _) = prepare_disk(&mesh, &PrepareOptions::default()).unwrap();
        let problem = transport_problem(&mesh, &Markers::default(), &AreaPreservingParams::default()).unwrap();
        let (c, nu) = (&problem.conformal, &problem.target_masses);
        let y = &c.uv;
        let n = y.len();
        let spacing = (std::f64::consts::PI / n as f64).sqrt();
        let (nn, pd) = crowding::nearest_neighbour_distances(y);
        let mut hist = std::collections::BTreeMap::new();
        for &d in &nn {
            let k = (d / spacing).log10().floor() as i64;
            *hist.entry(k.max(-20)).or_insert(0usize) += 1;
        }
        println!(
            "{name}: N = {n}, spacing {spacing:.2e}, hidden/duplicate {}",
            (0..n).filter(|&i| pd.is_hidden(i)).count()
        );
        println!("  log10(nn/spacing) histogram: {hist:?}");
        for t in [1e-2, 1e-4, 1e-6, 1e-9, 1e-12] {
            let mut p: Vec<usize> = (0..n).collect();
            for i in 0..n {
                for &j in pd.neighbors(i) {
                    if dist(y[i], y[j as usize]) < t * spacing {
                        let (a, b) = (find(&mut p, i), find(&mut p, j as usize));
                        p[a] = b;
                    }
                }
            }
            let mut comps: std::collections::HashMap<usize, Vec<usize>> = Default::default();
            for i in 0..n {
                let r = find(&mut p, i);
                comps.entry(r).or_default().push(i);
            }
            let clusters: Vec<&Vec<usize>> = comps.values().filter(|v| v.len() > 1).collect();
            let in_clusters: usize = clusters.iter().map(|v| v.len()).sum();
            let largest = clusters.iter().map(|v| v.len()).max().unwrap_or(0);
            let mass: f64 = clusters.iter().flat_map(|v| v.iter()).map(|&i| nu[i]).sum();
            // separation: diameter (bounding box diagonal) / min distance to an outside neighbour
            let mut worst: f64 = 0.0;
            for v in &clusters {
                let set: std::collections::HashSet<usize> = v.iter().copied().collect();
                let (mut lo, mut hi) = ([f64::INFINITY; 2], [f64::NEG_INFINITY; 2]);
                let mut out = f64::INFINITY;
                for &i in v.iter() {
                    for k in 0..2 {
                        lo[k] = lo[k].min(y[i][k]);
                        hi[k] = hi[k].max(y[i][k]);
                    }
                    for &j in pd.neighbors(i) {
                        if !set.contains(&(j as usize)) {
                            out = out.min(dist(y[i], y[j as usize]));
                        }
                    }
                }
                worst = worst.max(dist(lo, hi) / out);
            }
            println!(
                "  t = {t:.0e}: {} clusters, {in_clusters} points, largest {largest}, mass {mass:.2e} (of {:.2e}), worst diameter/separation {worst:.2e}",
                clusters.len(),
                nu.iter().sum::<f64>()
            );
        }
    }
}
