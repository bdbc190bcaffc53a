//! The registration benchmark without the CLI: `cargo bench -p shapespace-tools --bench register_bench -- DATASET_DIR OUT_DIR [omt,conformal] [none|zoomout] [K_END] [vertex|projected] [EIGEN_TOL] [UNTANGLE_SWEEPS] [UNTANGLE_RING] [K_STEP] [SAMPLES] [compact|flips] [REMESHED_DIR]` (same as
//! `shapespace register-bench`). Prints the per-pair rows and the per-method means.
use shapespace_analysis::registration::bench::register_bench;
use shapespace_analysis::registration::{Method, MetricParams, Refinement, ZoomOutParams};
use std::path::PathBuf;

fn main() {
    shapespace_tools::at_repository_root();
    let args: Vec<String> = std::env::args().filter(|a| a != "--bench").collect();
    let dataset = PathBuf::from(args.get(1).map_or("datasets/poses", String::as_str));
    let out = PathBuf::from(args.get(2).map_or("/tmp/register_bench", String::as_str));
    let methods: Vec<Method> = args
        .get(3)
        .map_or("omt,conformal", String::as_str)
        .split(',')
        .map(|m| m.parse().expect("method"))
        .collect();
    let refine: Refinement = args
        .get(4)
        .map_or("zoomout", String::as_str)
        .parse()
        .expect("refinement");
    let mut zoomout = ZoomOutParams::default();
    if let Some(k) = args.get(5) {
        zoomout.k_end = k.parse().expect("k_end");
    }
    if let Some(o) = args.get(6) {
        zoomout.output = o.parse().expect("output");
    }
    if let Some(t) = args.get(7) {
        zoomout.eigen.tolerance = t.parse().expect("eigen tolerance");
    }
    if let Some(s) = args.get(8) {
        zoomout.untangle.sweeps = s.parse().expect("untangle sweeps");
    }
    if let Some(r) = args.get(9) {
        zoomout.untangle.ring = r.parse().expect("untangle ring");
    }
    if let Some(k) = args.get(10) {
        zoomout.k_step = k.parse().expect("k_step");
    }
    if let Some(n) = args.get(11) {
        zoomout.samples = n.parse().expect("samples");
    }
    if let Some(c) = args.get(12) {
        zoomout.untangle.compact = c == "compact";
    }
    let remeshed = args.get(13).map(PathBuf::from);
    let res = register_bench(
        &dataset,
        &out,
        remeshed.as_deref(),
        &methods,
        &shapespace_analysis::registration::registration_area_params(),
        &shapespace_analysis::registration::HarmonicParams::for_method,
        refine,
        &zoomout,
        &MetricParams::default(),
        |m| eprintln!("{m}"),
    )
    .expect("bench");
    for r in &res.rows {
        println!(
            "{} {}->{} {} {:9} {} flip {:.4} flip3d {:.4} curv {:.3}/{:.3} area {:.3}/{:.3}/{:.3} geo {:.4}/{:.4} {:.2}s (refine {:.2}s, eigen {:.2}s, pair {:.2}s, amortized {:.2}s) untangle {}->{} {}",
            r.class,
            r.source,
            r.target,
            r.triangulation,
            r.method.name(),
            r.refine.name(),
            r.flipped_ratio,
            r.flipped_ratio_3d,
            r.curvature_median,
            r.curvature_mean,
            r.area_distortion_median,
            r.area_distortion_p95,
            r.area_distortion_mean_abs_log,
            r.geodesic_median,
            r.geodesic_mean,
            r.seconds,
            r.refine_seconds,
            r.eigen_seconds,
            r.pair_seconds,
            r.amortized_seconds,
            r.untangle_flipped_before,
            r.untangle_flipped_after,
            r.status
        );
    }
    for s in &res.summaries {
        println!("{s:?}");
    }
    println!("total {:.1}s", res.total_seconds);
}
