//! Probe: the error of `--target-points N` on consecutive facefuns pairs, with the grouping's
//! cost subtracted (the block model) and with the second-order estimate of the cross term that
//! the distances use.
//!
//! `cargo run --release -p shapespace-tools --bin quant_probe -- [PAIRS] [N]` (defaults 5,
//! 10000). For a target quantized to groups g (means c_g, masses m_g, covariances
//! S_g = Σ_{i∈g} ν_i (y_i − c_g)(y_i − c_g)ᵀ) and the solution's cells W_g (centroids x̄_g), a
//! split of each cell among its group's points costs
//! cost_q + V − 2 Σ_i ν_i ⟨x̄_i − x̄_g, y_i − c_g⟩. Taking x̄_i − x̄_g = y_i − c_g gives cost_q − V
//! (the block model); the distances take x̄_i − x̄_g = A_g (y_i − c_g) with A_g the
//! least-squares Jacobian of c ↦ x̄ over the cell's neighbours: cost_q + V − 2 Σ_g tr(A_g S_g)
//! (`shapespace_omt::quantization::quantization_correction`, printed as `library`). The probe
//! fits A_g over three neighbourhoods: the cells meeting across edges inside the disk, the
//! Delaunay neighbours of the means, and the neighbours in the solution's power diagram (the
//! library's); and prints, for the last, the model's sub-cell spread Σ_g tr(A_g S_g A_gᵀ)
//! against the cells' own variance Σ_g ∫_{W_g} |x − x̄_g|² dμ, the share of V in groups whose
//! spread exceeds half their cell's variance, and the points per group.

use shapespace_analysis::distance::PairwiseOptions;
use shapespace_analysis::distance::PreparedShape;
use shapespace_tools::scans;
use std::sync::Arc;

type Spread = (f64, f64, f64, f64);

fn solve(
    a: &PreparedShape,
    points: &[[f64; 2]],
    masses: &[f64],
    c: Arc<shapespace_omt::newton::TargetCoarsening>,
) -> shapespace_omt::OtSolution {
    let params = shapespace_omt::NewtonParams {
        target_coarsening: Some(c),
        ..PairwiseOptions::default().newton
    };
    let s = shapespace_omt::solve_ot_prepared(&a.measure, points, masses, &params).unwrap();
    assert!(s.converged());
    s
}

fn main() {
    shapespace_tools::at_repository_root();
    let args: Vec<usize> = std::env::args().skip(1).filter_map(|a| a.parse().ok()).collect();
    let pairs = args.first().copied().unwrap_or(5);
    let n = args.get(1).copied().unwrap_or(10000);
    let mut shapes = Vec::new();
    for f in scans::facefuns_files() {
        if shapes.len() == pairs + 1 {
            break;
        }
        let name = f.file_stem().unwrap().to_string_lossy().to_string();
        if let Ok(s) = scans::prepared(&name, &f, &scans::disk_mesh(&f)) {
            shapes.push(s);
        }
    }
    for w in shapes.windows(2) {
        let (a, b) = (&w[0], &w[1]);
        let full = solve(a, &b.points, &b.masses, b.coarsening.clone());
        let q = shapespace_omt::quantization::quantize(&b.points, &b.masses, n);
        let k = q.points.len();
        let coarsening = Arc::new(shapespace_omt::newton::TargetCoarsening::new(&q.points, &q.masses));
        let sol = solve(a, &q.points, &q.masses, coarsening);
        // S_g and V
        let mut s = vec![[0.0f64; 3]; k];
        for (i, &g) in q.group.iter().enumerate() {
            let d = [b.points[i][0] - q.points[g][0], b.points[i][1] - q.points[g][1]];
            let m = b.masses[i];
            s[g][0] += m * d[0] * d[0];
            s[g][1] += m * d[0] * d[1];
            s[g][2] += m * d[1] * d[1];
        }
        let scale = sol.mass_scale;
        let v: f64 = s.iter().map(|s| s[0] + s[2]).sum::<f64>() * scale;
        let cells = &sol.cells;
        let xbar: Vec<[f64; 2]> = (0..k)
            .map(|g| {
                [
                    cells.first_moments[g][0] / cells.masses[g],
                    cells.first_moments[g][1] / cells.masses[g],
                ]
            })
            .collect();
        // neighbourhoods: the solution's cells meeting inside the disk (edge_masses), the
        // Delaunay triangulation of the group means, the full power diagram at the solution
        let mut nb_edges: Vec<Vec<usize>> = vec![Vec::new(); k];
        for &(i, j, _) in &cells.edge_masses {
            nb_edges[i as usize].push(j as usize);
            nb_edges[j as usize].push(i as usize);
        }
        let pd = shapespace_omt::power_diagram::PowerDiagram::new(&q.points, &vec![0.0; k]).unwrap();
        let nb_delaunay: Vec<Vec<usize>> = (0..k)
            .map(|g| pd.neighbors(g).iter().map(|&j| j as usize).collect())
            .collect();
        let pw = shapespace_omt::power_diagram::PowerDiagram::new(&q.points, &sol.weights).unwrap();
        let nb_power: Vec<Vec<usize>> = (0..k)
            .map(|g| pw.neighbors(g).iter().map(|&j| j as usize).collect())
            .collect();
        let mut traces = Vec::new();
        let mut second = Vec::new();
        // per group: (model spread, cell variance, tr S_g, tr(A_g S_g)), all scaled
        let mut spreads: Vec<Spread> = Vec::new();
        let q_points = q.points.clone();
        for (variant, nb) in [&nb_edges, &nb_delaunay, &nb_power].into_iter().enumerate() {
            let mut cross = 0.0;
            for g in 0..k {
                // A = B D⁻¹, D = Σ dc dcᵀ, B = Σ dx dcᵀ
                let (mut d, mut bm) = ([0.0f64; 4], [0.0f64; 4]);
                for &j in &nb[g] {
                    if cells.masses[j] <= 0.0 {
                        continue;
                    }
                    let dc = [q.points[j][0] - q.points[g][0], q.points[j][1] - q.points[g][1]];
                    let dx = [xbar[j][0] - xbar[g][0], xbar[j][1] - xbar[g][1]];
                    d[0] += dc[0] * dc[0];
                    d[1] += dc[0] * dc[1];
                    d[3] += dc[1] * dc[1];
                    bm[0] += dx[0] * dc[0];
                    bm[1] += dx[0] * dc[1];
                    bm[2] += dx[1] * dc[0];
                    bm[3] += dx[1] * dc[1];
                }
                d[2] = d[1];
                let det = d[0] * d[3] - d[1] * d[2];
                let a = if nb[g].len() >= 3 && det > 0.0 {
                    let inv = [d[3] / det, -d[1] / det, -d[2] / det, d[0] / det];
                    [
                        bm[0] * inv[0] + bm[1] * inv[2],
                        bm[0] * inv[1] + bm[1] * inv[3],
                        bm[2] * inv[0] + bm[3] * inv[2],
                        bm[2] * inv[1] + bm[3] * inv[3],
                    ]
                } else {
                    [1.0, 0.0, 0.0, 1.0]
                };
                // tr(A S), S symmetric
                let t = a[0] * s[g][0] + (a[1] + a[2]) * s[g][1] + a[3] * s[g][2];
                cross += t * scale;
                if variant == 0 {
                    traces.push((a[0] + a[3]) / 2.0);
                }
                if variant == 2 {
                    // the model's between-sub-cell variance tr(A S Aᵀ) against the cell's own
                    // variance ∫_W |x − x̄|² dμ, which bounds what any split can place
                    let q = |r0: f64, r1: f64| r0 * r0 * s[g][0] + 2.0 * r0 * r1 * s[g][1] + r1 * r1 * s[g][2];
                    let spread = (q(a[0], a[1]) + q(a[2], a[3])) * scale;
                    let dx = [xbar[g][0] - q_points[g][0], xbar[g][1] - q_points[g][1]];
                    let own = cells.second_moments[g] - cells.masses[g] * (dx[0] * dx[0] + dx[1] * dx[1]);
                    spreads.push((spread, own, (s[g][0] + s[g][2]) * scale, t * scale));
                }
            }
            second.push((sol.cost + v - 2.0 * cross).max(0.0).sqrt());
        }
        traces.sort_by(f64::total_cmp);
        {
            let sum = |f: &dyn Fn(&Spread) -> f64| spreads.iter().map(f).sum::<f64>();
            let over: Vec<_> = spreads.iter().filter(|x| x.0 > 0.5 * x.1).collect();
            let over_v: f64 = over.iter().map(|x| x.2).sum();
            let mut group_sizes = vec![0usize; k];
            q.group.iter().for_each(|&g| group_sizes[g] += 1);
            group_sizes.sort();
            println!(
                "  model spread Σ tr(A S Aᵀ) {:.3e} against the cells' own variance {:.3e} (V {:.3e}); {} of {k} groups have spread > half their cell's variance ({:.1} % of V); points per group median {} q90 {}",
                sum(&|x| x.0),
                sum(&|x| x.1),
                v,
                over.len(),
                100.0 * over_v / v,
                group_sizes[k / 2],
                group_sizes[9 * k / 10]
            );
        }
        let w = full.cost.sqrt();
        let current = (sol.cost - v).max(0.0).sqrt();
        let library = (sol.cost + shapespace_omt::quantization::quantization_correction(&sol, &q.points, &q.moments))
            .max(0.0)
            .sqrt();
        println!(
            "{} -> {}: {k} points, V/cost {:.3}, error subtracting V {:+.3e}, second order (edges {:+.3e}, delaunay {:+.3e}, power {:+.3e}, library {:+.3e}) | tr(A)/2 q10 {:.3} median {:.3} q90 {:.3}",
            a.name,
            b.name,
            v / full.cost,
            current / w - 1.0,
            second[0] / w - 1.0,
            second[1] / w - 1.0,
            second[2] / w - 1.0,
            library / w - 1.0,
            traces[k / 10],
            traces[k / 2],
            traces[9 * k / 10]
        );
    }
}
