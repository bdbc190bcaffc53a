//! Semi-discrete optimal transport from the uniform unit disk to random points of equal mass:
//! every power cell ends with the same area.
//!
//!     cargo run --release -p shapespace-omt --example uniform_disk_ot [N]

use shapespace_omt::{solve_ot, NewtonParams, SourceMeasure};

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let n: usize = std::env::args().nth(1).map(|s| s.parse()).transpose()?.unwrap_or(1000);
    // the disk as a regular 1024-gon of density 1; targets: n points of a seeded generator
    let measure = SourceMeasure::unit_disk(1024)?;
    let mut state = 0x2545_f491_4f6c_dd1du64;
    let mut uniform = || {
        state ^= state << 13;
        state ^= state >> 7;
        state ^= state << 17;
        (state >> 11) as f64 / (1u64 << 53) as f64
    };
    let points: Vec<[f64; 2]> = (0..n)
        .map(|_| {
            let (r, t) = (uniform().sqrt() * 0.95, 2.0 * std::f64::consts::PI * uniform());
            [r * t.cos(), r * t.sin()]
        })
        .collect();
    let masses = vec![measure.total_mass() / n as f64; n];
    let solution = solve_ot(&measure, &points, &masses, &NewtonParams::default())?.into_result()?;
    let worst = solution
        .cells
        .masses
        .iter()
        .zip(&masses)
        .map(|(a, m)| (a - m).abs() / m)
        .fold(0.0f64, f64::max);
    println!(
        "{n} points: {} Newton steps, transport cost {:.6e}, largest relative cell-mass error {worst:.2e}",
        solution.iterations, solution.cost
    );
    Ok(())
}
