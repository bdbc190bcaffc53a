//! Probe: the fold repair record of the area-preserving sphere map of one closed mesh.
//! `sphere_repair_probe PATH [SUBDIVISIONS]` (PATH relative to the shared datasets folder, or an
//! existing path; SUBDIVISIONS of the icosphere source, default as the map chooses):
//! folds before and after the repair, the repair's record, and the 95th percentile of |ε| (the
//! log one-ring area ratio, both sides normalized) over all vertices and over the moved ones,
//! before and after the repair.
use shapespace_analysis::sphere_param::{area_preserving_sphere_map, repair_sphere_map_folds, SphereParamParams};
use shapespace_geometry::quantities::vertex_dual_areas;
use shapespace_geometry::TriMesh;

/// |ε| per vertex: |ln(image one-ring share / surface one-ring share)|.
fn abs_eps(mesh: &TriMesh, x: &[[f64; 3]]) -> Vec<f64> {
    let image = TriMesh::new(x.to_vec(), mesh.faces.clone()).expect("same faces");
    let (a, b) = (vertex_dual_areas(mesh), vertex_dual_areas(&image));
    let (sa, sb): (f64, f64) = (a.iter().sum(), b.iter().sum());
    a.iter()
        .zip(&b)
        .map(|(a, b)| ((b / sb) / (a / sa)).ln().abs())
        .collect()
}

fn p95(mut v: Vec<f64>) -> f64 {
    if v.is_empty() {
        return f64::NAN;
    }
    v.sort_by(|a, b| a.total_cmp(b));
    v[((v.len() - 1) as f64 * 0.95).round() as usize]
}

fn main() {
    shapespace_tools::at_repository_root();
    let arg = std::env::args().nth(1).unwrap_or("goast/finger/finger0.ply".into());
    let path = if std::path::Path::new(&arg).exists() {
        std::path::PathBuf::from(&arg)
    } else {
        shapespace_test_support::shared_datasets_dir().join(&arg)
    };
    let mesh = shapespace_geometry::io::read_mesh(&path).unwrap_or_else(|e| panic!("{e}"));
    let params = SphereParamParams {
        no_fold_repair: true,
        source_subdivisions: std::env::args().nth(2).and_then(|s| s.parse().ok()),
        ..Default::default()
    };
    let map = area_preserving_sphere_map(&mesh, &params).unwrap();
    let mut x = map.positions.clone();
    let clock = std::time::Instant::now();
    let info = repair_sphere_map_folds(&mesh, &mut x);
    let seconds = clock.elapsed().as_secs_f64();
    let after = shapespace_analysis::sphere_param::folded_faces_on_sphere(&mesh, &x);
    let (e0, e1) = (abs_eps(&mesh, &map.positions), abs_eps(&mesh, &x));
    let moved: Vec<usize> = (0..x.len()).filter(|&v| x[v] != map.positions[v]).collect();
    let max_step = moved
        .iter()
        .map(|&v| {
            let (p, q) = (x[v], map.positions[v]);
            (p[0] * q[0] + p[1] * q[1] + p[2] * q[2]).clamp(-1.0, 1.0).acos()
        })
        .fold(0.0, f64::max);
    println!(
        "{}: {} subdivisions, {} Newton steps, folded {} → {}, OT {:.2} s, repair {:.2} s; p95 |ε| {:.3} → {:.3}; \
         moved {} (largest move {:.4} rad), their p95 |ε| {:.3} → {:.3}; repair {:?}",
        path.display(),
        map.source_subdivisions,
        map.iterations,
        map.flipped_before_repair,
        after,
        map.timings.ot,
        seconds,
        p95(e0.clone()),
        p95(e1.clone()),
        moved.len(),
        max_step,
        p95(moved.iter().map(|&v| e0[v]).collect()),
        p95(moved.iter().map(|&v| e1[v]).collect()),
        info
    );
}
