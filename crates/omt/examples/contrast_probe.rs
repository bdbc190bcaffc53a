//! Probe: per-iteration log of the 100x contrast half-disk case of `ot_bench`.
use shapespace_omt::{solve_ot, NewtonParams, SourceMeasure};

fn rng(state: &mut u64) -> f64 {
    *state = state.wrapping_add(0x9E37_79B9_7F4A_7C15);
    let mut x = *state;
    x = (x ^ (x >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
    x = (x ^ (x >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
    ((x ^ (x >> 31)) >> 11) as f64 / (1u64 << 53) as f64
}

fn disk_points(n: usize, seed: u64) -> Vec<[f64; 2]> {
    let mut s = seed;
    (0..n)
        .map(|_| {
            let r = rng(&mut s).sqrt();
            let t = 2.0 * std::f64::consts::PI * rng(&mut s);
            [r * t.cos(), r * t.sin()]
        })
        .collect()
}

/// Triangulated unit disk with `rings` rings (ring k has 6k vertices), density f at centroids.
fn disk_measure(rings: usize, f: impl Fn([f64; 2]) -> f64) -> SourceMeasure {
    let mut vertices = vec![[0.0, 0.0]];
    let mut ring_start = vec![0usize];
    for k in 1..=rings {
        ring_start.push(vertices.len());
        for j in 0..6 * k {
            let t = 2.0 * std::f64::consts::PI * j as f64 / (6 * k) as f64;
            let r = k as f64 / rings as f64;
            vertices.push([r * t.cos(), r * t.sin()]);
        }
    }
    let mut triangles = Vec::new();
    for k in 0..rings {
        let (n_in, n_out) = (if k == 0 { 1 } else { 6 * k }, 6 * (k + 1));
        let (s_in, s_out) = (ring_start[k], ring_start[k + 1]);
        let (mut i, mut o) = (if k == 0 { 1usize } else { 0 }, 0usize);
        while i < n_in || o < n_out {
            let a_in = if k == 0 { f64::INFINITY } else { (i + 1) as f64 / n_in as f64 };
            let a_out = (o + 1) as f64 / n_out as f64;
            let vi = (s_in + i % n_in) as u32;
            let vo = (s_out + o % n_out) as u32;
            if o < n_out && (i >= n_in || a_out <= a_in) {
                triangles.push([vi, vo, (s_out + (o + 1) % n_out) as u32]);
                o += 1;
            } else {
                triangles.push([vi, vo, (s_in + (i + 1) % n_in) as u32]);
                i += 1;
            }
        }
    }
    let densities = triangles
        .iter()
        .map(|t| {
            let p = t.map(|v| vertices[v as usize]);
            f([(p[0][0] + p[1][0] + p[2][0]) / 3.0, (p[0][1] + p[1][1] + p[2][1]) / 3.0])
        })
        .collect();
    SourceMeasure::new(vertices, triangles, densities).expect("valid disk")
}


fn main() {
    let n: usize = std::env::args().nth(1).and_then(|s| s.parse().ok()).unwrap_or(10_000);
    let c: f64 = std::env::args().nth(2).and_then(|s| s.parse().ok()).unwrap_or(100.0);
    let contrast = disk_measure(30, |x| if x[0] > 0.0 { c } else { 1.0 });
    let points = disk_points(n, 7);
    let masses = vec![1.0; n];
    let mass: Option<f64> = std::env::args().nth(3).and_then(|s| s.parse().ok());
    let params = NewtonParams { density_continuation: None, mass_continuation: mass, max_iterations: 300, ..Default::default() };
    let sol = solve_ot(&contrast, &points, &masses, &params).unwrap();
    for (k, r) in sol.log.iter().enumerate() {
        println!("{k:3} err {:.2e} norm {:.2e} tau {:.4} rej {}/{} minmass {:.2e}", r.max_relative_error, r.gradient_norm, r.step, r.rejected_min_mass, r.rejected_norm, r.min_cell_mass);
    }
    println!("eps0 {:.2e} stop {} iterations {} start {:?} total {:.2} s", sol.epsilon0, sol.stop, sol.iterations, sol.start, sol.t_total);
}
