//! Power diagrams of arbitrary sites and weights, their `sanity_check`, and the restricted cell
//! masses over a square (`shapespace_fuzz::check_power_diagram`).
#![cfg_attr(fuzzing, no_main)]

#[cfg(fuzzing)]
libfuzzer_sys::fuzz_target!(|data: &[u8]| {
    shapespace_fuzz::check_power_diagram(data);
});

#[cfg(not(fuzzing))]
fn main() {
    // seed: a 4 x 4 grid of sites in the square with zero weights, as f64 triples
    let mut seed = Vec::new();
    for i in 0..16 {
        for v in [-0.75 + 0.5 * (i % 4) as f64, -0.75 + 0.5 * (i / 4) as f64, 0.0] {
            seed.extend_from_slice(&v.to_le_bytes());
        }
    }
    let path = std::env::temp_dir().join("shapespace-fuzz-power-diagram-seed");
    std::fs::write(&path, &seed).expect("writing the seed");
    shapespace_fuzz::replay_or_sweep("power_diagram", &[path.as_path()], 3000, shapespace_fuzz::check_power_diagram);
}
