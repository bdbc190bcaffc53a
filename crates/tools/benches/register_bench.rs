//! The registration benchmark without the CLI: `cargo bench -p shapespace-tools --bench register_bench -- DATASET_DIR OUT_DIR [omt,conformal]` (same as
//! `shapespace register-bench`). Prints the per-pair rows and the per-method means.
use shapespace_analysis::registration::bench::register_bench;
use shapespace_analysis::registration::{Method, MetricParams};
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
    let res = register_bench(
        &dataset,
        &out,
        &methods,
        &shapespace_analysis::registration::registration_area_params(),
        &shapespace_analysis::registration::HarmonicParams::for_method,
        &MetricParams::default(),
        |m| eprintln!("{m}"),
    )
    .expect("bench");
    for r in &res.rows {
        println!(
            "{} {}->{} {:9} flip {:.4} flip3d {:.4} curv {:.3}/{:.3} area {:.3}/{:.3}/{:.3} geo {:.4}/{:.4} {:.2}s {}",
            r.class,
            r.source,
            r.target,
            r.method.name(),
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
            r.status
        );
    }
    for s in &res.summaries {
        println!("{s:?}");
    }
    println!("total {:.1}s", res.total_seconds);
}
