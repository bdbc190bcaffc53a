//! Probe: disk_map timings on camelhead subdivided 1-to-4, repeated (for perf).
use shapespace_conformal::{disk_map, DiskMapParams, Markers};
fn main() {
    let path = shapespace_test_support::shared_datasets_dir().join("libigl_tutorial_data/camelhead.off");
    let m = shapespace_geometry::io::read_mesh(&path).unwrap_or_else(|e| panic!("{e} (set SHAPESPACE_DATA)"));
    let m = shapespace_geometry::prepare::subdivide_midpoint(&m).unwrap();
    for _ in 0..5 {
        let d = disk_map(&m, &Markers::default(), &DiskMapParams::default()).unwrap();
        println!("{:?}", d.info.timings);
    }
}
