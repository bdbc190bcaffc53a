//! The marker-file and marker-flag parsers on arbitrary bytes (`shapespace_fuzz::check_markers`).
#![cfg_attr(fuzzing, no_main)]

#[cfg(fuzzing)]
libfuzzer_sys::fuzz_target!(|data: &[u8]| {
    shapespace_fuzz::check_markers(data);
});

#[cfg(not(fuzzing))]
fn main() {
    let root = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("..");
    let seed = root.join("datasets/faces/landmarks.json");
    shapespace_fuzz::replay_or_sweep("markers", &[seed.as_path()], 5000, shapespace_fuzz::check_markers);
}
