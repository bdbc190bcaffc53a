//! Probe: the distance solves of a few face pairs, one thread, for instruction counts under
//! `valgrind --tool=cachegrind --cache-sim=no` when the machine is too noisy for timings.
//!
//! `cargo run --release -p shapespace-tools --bin pair_cost -- A:B [A:B ...]` (from the
//! repository root; default id00_sad:id01_happy id02_neutral:id05_surprise id07_happy:id03_sad).
//! Prints per pair the Newton steps over all levels, finest-level evaluations, seconds and the
//! distance to full precision. With env `PREPARE_ONLY` it only prepares the faces: the count to
//! subtract from a run's instructions. With env `NO_FLIPS` every power diagram is built by
//! insertion (`NewtonParams::flip_updates` off); with env `FLUX` the Newton evaluations' masses
//! come from the flux form (`NewtonParams::flux_masses` on).
use shapespace_tools::faces;

use shapespace_analysis::distance::{directed_distance, PairwiseOptions};

fn main() {
    let mut pairs: Vec<String> = std::env::args().skip(1).collect();
    if pairs.is_empty() {
        pairs = [
            "id00_sad:id01_happy",
            "id02_neutral:id05_surprise",
            "id07_happy:id03_sad",
        ]
        .map(String::from)
        .to_vec();
    }
    let mut params = PairwiseOptions::default().newton;
    params.flip_updates = std::env::var("NO_FLIPS").is_err();
    params.flux_masses = std::env::var("FLUX").is_ok();
    let (mut steps, mut evaluations, mut seconds) = (0, 0, 0.0);
    for p in &pairs {
        let (a, b) = p.split_once(':').expect("pairs are A:B");
        let shapes = faces::prepared_faces(&[a, b]);
        if std::env::var("PREPARE_ONLY").is_ok() {
            continue;
        }
        let (d, _) = directed_distance(&shapes[0], &shapes[1], &params).expect("pair");
        println!(
            "{a} -> {b}: steps {} evaluations {} seconds {:.3} distance {:.15e} error {:.1e} {}",
            d.iterations, d.evaluations, d.seconds, d.distance, d.max_mass_error, d.status
        );
        steps += d.iterations;
        evaluations += d.evaluations;
        seconds += d.seconds;
    }
    println!("total: steps {steps} evaluations {evaluations} seconds {seconds:.3}");
}
