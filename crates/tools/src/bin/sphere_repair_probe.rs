//! Probe: the fold repair record of the area-preserving sphere map of one closed mesh.
//! `sphere_repair_probe PATH` (relative to the shared datasets folder, or an existing path).
use shapespace_analysis::sphere_param::{area_preserving_sphere_map, SphereParamParams};

fn main() {
    shapespace_tools::at_repository_root();
    let arg = std::env::args().nth(1).unwrap_or("goast/finger/finger0.ply".into());
    let path = if std::path::Path::new(&arg).exists() {
        std::path::PathBuf::from(&arg)
    } else {
        shapespace_test_support::shared_datasets_dir().join(&arg)
    };
    let mesh = shapespace_geometry::io::read_mesh(&path).unwrap_or_else(|e| panic!("{e}"));
    let map = area_preserving_sphere_map(&mesh, &SphereParamParams::default()).unwrap();
    println!(
        "{}: {} Newton steps, folded {} → {}, OT {:.2} s; repair {:?}",
        path.display(),
        map.iterations,
        map.flipped_before_repair,
        map.num_flipped,
        map.timings.ot,
        map.fold_repair
    );
}
