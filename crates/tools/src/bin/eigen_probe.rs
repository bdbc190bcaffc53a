//! Probe: the Laplace–Beltrami eigenpairs ZoomOut asks of a mesh (its default `EigenParams`),
//! timed, with the Krylov basis they took.
//!
//! `cargo run --release -p shapespace-tools --bin eigen_probe -- MESH [K] [BLOCK] [TOLERANCE]`

use std::time::Instant;

use shapespace_analysis::registration::zoomout::ZoomOutParams;
use shapespace_geometry::spectral::laplace_beltrami_eigenpairs;

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let args: Vec<String> = std::env::args().skip(1).collect();
    let mesh = shapespace_geometry::io::read_mesh(std::path::Path::new(&args[0]))?;
    let defaults = ZoomOutParams::default();
    let k: usize = args.get(1).and_then(|s| s.parse().ok()).unwrap_or(defaults.k_end);
    let mut params = defaults.eigen.clone();
    if let Some(b) = args.get(2).and_then(|s| s.parse().ok()) {
        params.block_size = b;
    }
    if let Some(t) = args.get(3).and_then(|s| s.parse().ok()) {
        params.tolerance = t;
    }
    let t = Instant::now();
    let cpu = shapespace_tools::cpu_seconds();
    let e = laplace_beltrami_eigenpairs(&mesh, k, &params)?;
    println!(
        "{}: V {} k {k} block {} tol {:e}: {:.2} s (CPU {:.2} s), basis {}, max residual {:.1e}, lambda_1 {:.4e} lambda_k {:.4e}",
        args[0],
        mesh.positions.len(),
        params.block_size,
        params.tolerance,
        t.elapsed().as_secs_f64(),
        shapespace_tools::cpu_seconds() - cpu,
        e.basis_size,
        e.max_residual,
        e.values[1],
        e.values[k - 1]
    );
    Ok(())
}
