//! The PLY reader on arbitrary bytes (`shapespace_fuzz::check_mesh_reader`).
#![cfg_attr(fuzzing, no_main)]

#[cfg(fuzzing)]
libfuzzer_sys::fuzz_target!(|data: &[u8]| {
    shapespace_fuzz::check_mesh_reader(data, std::path::Path::new("fuzz.ply"));
});

#[cfg(not(fuzzing))]
fn main() {
    shapespace_fuzz::mesh_reader_sweep("ply", "goast/plate/plate121.ply");
}
