//! `shapespace param IN --domain sphere --method lie|flow --out OUT [--sphere-markers A,B,C |
//! --rotation-markers A,B] [--report R.json] [--plots DIR] [--no-fold-repair]`: the sphere
//! versions of the Lie-advection map and of the gradient-flow OMT map
//! ([`shapespace_analysis::sphere_flows`]); on a closed genus-0 input `--domain` defaults to
//! `sphere` for these two methods. OUT (.obj, .ply or .off) is the input mesh with every vertex
//! moved to its image on S²; the report has the flow's steps, folds and timings and the
//! distortion block of the other sphere maps (conformal and mapped: |ε|, Υ, Λ, angle
//! distortion, flips). Exit code 1 when faces are still folded on the sphere (the Lie map is
//! written with them; the flow, which needs an unfolded start, then fails with the count).

use std::process::ExitCode;
use std::time::Instant;

use anyhow::{Context, Result};
use shapespace_analysis::distortion::sphere_distortion_report;
use shapespace_analysis::sphere_flows::{sphere_gradient_flow_map, sphere_lie_map, SphereFlowParams, SphereLieParams};
use shapespace_geometry::io::write_mesh;

use super::param::{with_spinner, write_plots_and_report, ParamArgs, ParamMethod};

/// Runs `param --domain sphere --method lie|flow`.
pub fn run(args: &ParamArgs, t0: Instant) -> Result<ExitCode> {
    let input = args.input.display();
    let method = args.method;
    if args.weights.is_some() {
        anyhow::bail!(
            "{input}: --method {} takes no --weights (the Newton OMT map does)",
            method.name()
        );
    }
    if args.start != super::ot::StartArg::Auto {
        anyhow::bail!(
            "{input}: --start chooses the OT's start; --method {} has no OT",
            method.name()
        );
    }
    // an unknown output extension is named before the input is read
    shapespace_geometry::io::MeshFormat::from_path(&args.out)?;
    let normalization = args.sphere.normalization_for(&args.input, &args.markers)?;
    let mesh = super::read_closed_mesh(&args.input)?;
    let mut lie = SphereLieParams {
        fold_repair: !args.no_fold_repair,
        ..Default::default()
    };
    lie.sphere_map.normalization = normalization;
    let (positions, conformal, info, flipped, summary) = if method == ParamMethod::Flow {
        let params = SphereFlowParams {
            start: lie,
            multiresolution_levels: args.flow_levels,
            ..Default::default()
        };
        let message = format!("gradient-flow sphere map of {input} ({} vertices)", mesh.num_vertices());
        let map = with_spinner(message, || sphere_gradient_flow_map(&mesh, &params))
            .with_context(|| format!("mapping {input} onto the sphere"))?;
        let f = &map.info.flow;
        let summary = format!(
            "gradient flow {} steps from {} (‖ζ‖/‖u‖ {:.2e} -> {:.2e}, transport cost {:.4e} -> {:.4e}; {}); conformal {:.2} s, start {:.2} s, flow {:.2} s",
            f.steps,
            super::param::flow_start(&map.info.multiresolution), f.start_curl, f.final_curl, f.start_cost, f.final_cost, f.stop,
            map.timings.conformal, map.timings.start, map.timings.flow
        );
        let info = serde_json::json!({
            "lie_advection": map.info.start,
            "multiresolution": map.info.multiresolution,
            "gradient_flow": map.info.flow,
            "timings": map.timings,
        });
        (map.positions, map.conformal, info, map.info.num_flipped, summary)
    } else {
        let message = format!("Lie-advection sphere map of {input} ({} vertices)", mesh.num_vertices());
        let map = with_spinner(message, || sphere_lie_map(&mesh, &lie))
            .with_context(|| format!("mapping {input} onto the sphere"))?;
        let i = &map.info;
        let repair = match &i.fold_repair {
            None if i.flipped_before_repair == 0 => "no folded faces".to_string(),
            None => format!("{} folded faces (fold repair off)", i.flipped_before_repair),
            Some(r) => format!(
                "fold repair: {} folded before, {} after, {} vertices moved in {} of {} charts",
                i.flipped_before_repair, i.num_flipped, r.vertices_moved, r.repaired, r.clusters
            ),
        };
        let correction = match &i.correction.skipped {
            None => format!(
                "correction {} steps ({} halved)",
                i.correction.steps, i.correction.halvings
            ),
            Some(why) => format!("correction not applied ({why})"),
        };
        let summary = format!(
            "Lie advection {:.1} steps per vertex (max {}); {repair}; {correction}; conformal {:.2} s, advection {:.2} s, repair {:.2} s, correction {:.2} s",
            i.mean_steps, i.max_steps, map.timings.conformal, map.timings.advection, map.timings.repair,
            map.timings.correction
        );
        let info = serde_json::json!({
            "lie_advection": map.info,
            "timings": map.timings,
        });
        (map.positions, map.conformal, info, map.info.num_flipped, summary)
    };
    let mut out_mesh = mesh.clone();
    out_mesh.positions = positions.clone();
    out_mesh.uvs = None;
    write_mesh(&args.out, &out_mesh).with_context(|| format!("writing {}", args.out.display()))?;
    let report = sphere_distortion_report(&mesh, &conformal.positions, &positions)?;
    let (c, m) = (&report.maps[0], &report.maps[1]);
    eprintln!(
        "{input}: {} V, {} F; |ε| median {:.3e} p95 {:.3e} (conformal {:.3e} / {:.3e}); angle distortion p95 {:.2}° (conformal {:.2}°); {} flipped; {summary}",
        mesh.num_vertices(),
        mesh.num_faces(),
        m.abs_vertex_log_area_ratio.median,
        m.abs_vertex_log_area_ratio.p95,
        c.abs_vertex_log_area_ratio.median,
        c.abs_vertex_log_area_ratio.p95,
        m.angle_distortion_deg.p95,
        c.angle_distortion_deg.p95,
        m.num_flipped + m.num_degenerate,
    );
    write_plots_and_report(args, &report, || {
        let mut json = serde_json::json!({
            "input": args.input.display().to_string(),
            "output": args.out.display().to_string(),
            "method": method.name(),
            "domain": "sphere",
            "normalization": format!("{normalization:?}"),
            "num_vertices": mesh.num_vertices(),
            "num_faces": mesh.num_faces(),
            "conformal": conformal.info,
            "num_flipped": flipped,
            "wall_seconds": t0.elapsed().as_secs_f64(),
            "distortion": report,
        });
        if let (Some(all), serde_json::Value::Object(extra)) = (json.as_object_mut(), info) {
            all.extend(extra);
        }
        json
    })?;
    if flipped > 0 {
        eprintln!("shapespace: {input}: {flipped} faces are still folded on the sphere after the fold repair; the map was written");
        return Ok(ExitCode::from(1));
    }
    Ok(ExitCode::SUCCESS)
}
