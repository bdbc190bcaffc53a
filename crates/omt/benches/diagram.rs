//! Power-diagram construction and restricted integration timings (prints a table; run with
//! `cargo bench -p shapespace-omt --bench diagram`). Uniform random sites in the unit disk, zero
//! weights (Voronoi), measure = `SourceMeasure::unit_disk(256)`. Construction is single-threaded;
//! integration is timed on one thread and on the default rayon pool.

use std::time::Instant;

use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use shapespace_omt::power_diagram::PowerDiagram;
use shapespace_omt::restricted::RestrictedIntegrator;
use shapespace_omt::SourceMeasure;

fn disk_points(n: usize, seed: u64) -> Vec<[f64; 2]> {
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    let mut out = Vec::with_capacity(n);
    while out.len() < n {
        let p = [2.0 * rng.random::<f64>() - 1.0, 2.0 * rng.random::<f64>() - 1.0];
        if p[0] * p[0] + p[1] * p[1] < 1.0 {
            out.push(p);
        }
    }
    out
}

/// CPU time (user + system) of the whole process in seconds, from /proc/self/stat (Linux;
/// 0 elsewhere). The machine is shared, so CPU time is reported next to wall time.
fn cpu_seconds() -> f64 {
    let Ok(stat) = std::fs::read_to_string("/proc/self/stat") else {
        return 0.0;
    };
    let Some(rest) = stat.rsplit(')').next() else {
        return 0.0;
    };
    let fields: Vec<&str> = rest.split_whitespace().collect();
    let ticks = |k: usize| fields.get(k).and_then(|s| s.parse::<f64>().ok()).unwrap_or(0.0);
    // Fields 14 and 15 of stat (utime, stime) are at 11 and 12 after the command name.
    (ticks(11) + ticks(12)) / 100.0
}

/// Best wall time and mean CPU time over `reps` runs.
fn best_of<T>(reps: usize, mut f: impl FnMut() -> T) -> (f64, f64, T) {
    let mut best = f64::INFINITY;
    let mut last = None;
    let cpu0 = cpu_seconds();
    for _ in 0..reps {
        let t = Instant::now();
        let r = f();
        best = best.min(t.elapsed().as_secs_f64());
        last = Some(r);
    }
    let cpu = (cpu_seconds() - cpu0) / reps as f64;
    (best, cpu, last.expect("reps > 0"))
}

fn main() {
    let sizes: Vec<usize> = match std::env::var("DIAGRAM_BENCH_MAX") {
        Ok(s) => {
            let max: usize = s.parse().unwrap_or(1_000_000);
            [1_000, 10_000, 100_000, 1_000_000]
                .into_iter()
                .filter(|&n| n <= max)
                .collect()
        }
        Err(_) => vec![1_000, 10_000, 100_000, 1_000_000],
    };
    let measure = SourceMeasure::unit_disk(256).expect("valid measure");
    let integrator = RestrictedIntegrator::new(&measure);
    let one_thread = rayon::ThreadPoolBuilder::new()
        .num_threads(1)
        .build()
        .expect("thread pool");
    println!(
        "| N | construction wall / CPU (s) | integration 1 thread wall / CPU (s) | integration {} threads wall (s) | Σ mass error |",
        rayon::current_num_threads()
    );
    println!("|---|---|---|---|---|");
    for &n in &sizes {
        let sites = disk_points(n, 42);
        let weights = vec![0.0; n];
        let reps = if n <= 100_000 { 5 } else { 2 };
        let (t_build, c_build, diagram) = best_of(reps, || PowerDiagram::new(&sites, &weights).expect("valid input"));
        let (t_one, c_one, cells) = best_of(reps, || one_thread.install(|| integrator.integrate(&diagram)));
        let (t_par, _, _) = best_of(reps, || integrator.integrate(&diagram));
        let total: f64 = cells.masses.iter().sum();
        let err = (total - measure.total_mass()).abs() / measure.total_mass();
        println!("| {n} | {t_build:.4} / {c_build:.3} | {t_one:.4} / {c_one:.3} | {t_par:.4} | {err:.1e} |");
    }
    // Fine source mesh (the solver's regime on faces): N = 10k sites, a 100×100 grid of the unit
    // square (M = 20k triangles) in shuffled order, varying densities.
    {
        let k = 100u32;
        let mut rng = ChaCha8Rng::seed_from_u64(7);
        let vertices: Vec<[f64; 2]> = (0..(k + 1) * (k + 1))
            .map(|v| [(v % (k + 1)) as f64 / k as f64, (v / (k + 1)) as f64 / k as f64])
            .collect();
        let mut triangles = Vec::new();
        for i in 0..k {
            for j in 0..k {
                let v = |a: u32, b: u32| b * (k + 1) + a;
                triangles.push([v(i, j), v(i + 1, j), v(i + 1, j + 1)]);
                triangles.push([v(i, j), v(i + 1, j + 1), v(i, j + 1)]);
            }
        }
        for t in (1..triangles.len()).rev() {
            let s = rng.random_range(0..=t);
            triangles.swap(t, s);
        }
        let densities: Vec<f64> = (0..triangles.len()).map(|_| 0.1 + rng.random::<f64>()).collect();
        let fine = SourceMeasure::new(vertices, triangles, densities).expect("valid measure");
        let fine_integrator = RestrictedIntegrator::new(&fine);
        let n = 10_000;
        let sites: Vec<[f64; 2]> = (0..n).map(|_| [rng.random::<f64>(), rng.random::<f64>()]).collect();
        let weights = vec![0.0; n];
        let diagram = PowerDiagram::new(&sites, &weights).expect("valid input");
        let (t_one, c_one, cells) = best_of(5, || one_thread.install(|| fine_integrator.integrate(&diagram)));
        let total: f64 = cells.masses.iter().sum();
        let err = (total - fine.total_mass()).abs() / fine.total_mass();
        println!("| {n} (M = 20k shuffled triangles) | – | {t_one:.4} / {c_one:.3} | – | {err:.1e} |");
    }
    // Worst case for the exact arithmetic: a square grid (every 4 neighbours co-circular).
    let k = 316;
    let h = 1.4 / k as f64;
    let sites: Vec<[f64; 2]> = (0..k * k)
        .map(|i| [-0.7 + h * (i % k) as f64, -0.7 + h * (i / k) as f64])
        .collect();
    let weights = vec![0.0; k * k];
    let (t_build, c_build, diagram) = best_of(2, || PowerDiagram::new(&sites, &weights).expect("valid input"));
    let (t_one, c_one, cells) = best_of(2, || one_thread.install(|| integrator.integrate(&diagram)));
    let total: f64 = cells.masses.iter().sum();
    let err = (total - measure.total_mass()).abs() / measure.total_mass();
    println!(
        "| {} (grid) | {t_build:.4} / {c_build:.3} | {t_one:.4} / {c_one:.3} | – | {err:.1e} |",
        k * k
    );
}
