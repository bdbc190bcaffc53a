//! The OFF reader on arbitrary bytes (`shapespace_fuzz::check_mesh_reader`).
#![cfg_attr(fuzzing, no_main)]

#[cfg(fuzzing)]
libfuzzer_sys::fuzz_target!(|data: &[u8]| {
    shapespace_fuzz::check_mesh_reader(data, std::path::Path::new("fuzz.off"));
});

#[cfg(not(fuzzing))]
fn main() {
    let root = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("..");
    let mut corpus: Vec<std::path::PathBuf> = std::fs::read_dir(root.join("tests/bad_input"))
        .map(|d| d.filter_map(|e| e.ok().map(|e| e.path())).collect())
        .unwrap_or_default();
    corpus.sort();
    corpus.push(root.join("../shared/datasets/tosca/wolf0.off"));
    let seeds: Vec<&std::path::Path> = corpus
        .iter()
        .filter(|p| p.extension().is_some_and(|e| e == "off"))
        .map(|p| p.as_path())
        .collect();
    shapespace_fuzz::replay_or_sweep("read_off", &seeds, 2000, |data| {
        shapespace_fuzz::check_mesh_reader(data, std::path::Path::new("fuzz.off"))
    });
}
