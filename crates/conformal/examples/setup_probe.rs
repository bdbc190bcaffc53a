//! Probe: disk_map timings on camelhead subdivided 1-to-4, repeated (for perf).
use shapespace_conformal::{disk_map, DiskMapParams, Markers};
fn main() {
    let root = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("../..");
    let m = shapespace_geometry::io::read_mesh(&root.join("datasets/disks/camelhead.off")).unwrap();
    let m = shapespace_geometry::prepare::subdivide_midpoint(&m).unwrap();
    for _ in 0..5 {
        let d = disk_map(&m, &Markers::default(), &DiskMapParams::default()).unwrap();
        println!("{:?}", d.info.timings);
    }
}
