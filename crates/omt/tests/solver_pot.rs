//! Cross-check against an exact discrete OT solver (POT's `ot.emd2`, fixture written by
//! `scripts/pot_reference.py`): a source concentrated in K tiny triangles of circumradius δ
//! (plus a 1e-9 background on the rest of the unit square) against M weighted points. As δ → 0
//! the semi-discrete cost tends to the discrete cost Σ P_kj |s_k − y_j|².

use shapespace_omt::{solve_ot, NewtonParams, SourceMeasure};

fn as_points(v: &serde_json::Value) -> Vec<[f64; 2]> {
    v.as_array()
        .unwrap()
        .iter()
        .map(|p| [p[0].as_f64().unwrap(), p[1].as_f64().unwrap()])
        .collect()
}

fn as_numbers(v: &serde_json::Value) -> Vec<f64> {
    v.as_array().unwrap().iter().map(|x| x.as_f64().unwrap()).collect()
}

#[test]
fn semi_discrete_cost_tends_to_the_discrete_cost_as_triangles_shrink() {
    let text = include_str!("fixtures/pot_discrete.json");
    let fixture: serde_json::Value = serde_json::from_str(text).unwrap();
    let discrete = fixture["discrete_cost"].as_f64().unwrap();
    let targets = as_points(&fixture["targets"]);
    let masses = as_numbers(&fixture["target_masses"]);
    let mut errors = Vec::new();
    for level in fixture["levels"].as_array().unwrap() {
        let delta = level["delta"].as_f64().unwrap();
        let triangles: Vec<[u32; 3]> = level["triangles"]
            .as_array()
            .unwrap()
            .iter()
            .map(|t| [0, 1, 2].map(|k| t[k].as_u64().unwrap() as u32))
            .collect();
        let measure = SourceMeasure::new(
            as_points(&level["vertices"]),
            triangles,
            as_numbers(&level["densities"]),
        )
        .unwrap();
        let params = NewtonParams {
            tolerance: 1e-9,
            max_iterations: 200,
            ..Default::default()
        };
        let sol = solve_ot(&measure, &targets, &masses, &params).unwrap();
        assert!(sol.converged(), "δ = {delta}: {}", sol.stop);
        let error = (sol.cost - discrete).abs();
        eprintln!(
            "δ = {delta:e}: semi-discrete cost {:.10}, discrete {discrete:.10}, |Δ| = {error:.2e} ({} steps)",
            sol.cost, sol.iterations
        );
        errors.push((delta, error));
    }
    // First order in δ (the plan splits tiny triangles whose points are O(δ) from s_k).
    for w in errors.windows(2) {
        assert!(w[1].1 < 0.2 * w[0].1, "{errors:?}");
    }
    let (delta, error) = errors[errors.len() - 1];
    assert!(error < 0.1 * delta, "{errors:?}");
}
