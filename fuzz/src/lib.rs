//! What each fuzz target checks, as plain functions of the input bytes, and the driver that runs
//! a target without libFuzzer (replaying files, then a seeded mutation sweep), so that the
//! targets build and run on stable Rust too.
//!
//! A target panics exactly when it finds a defect: a reader that panics, or accepts a mesh that
//! fails [`TriMesh::validate`], or an error that does not name the file; a power diagram that
//! fails its own `sanity_check`, or restricted cell masses that do not add up to the domain's
//! mass.

use std::path::Path;

use shapespace_geometry::TriMesh;

/// Parses `data` as a mesh named `path` (the extension picks the reader): an error must name the
/// file, a mesh must be valid.
pub fn check_mesh_reader(data: &[u8], path: &Path) {
    match shapespace_geometry::io::parse_mesh(data, path) {
        Ok(mesh) => check_mesh(&mesh),
        Err(e) => {
            let message = e.to_string();
            assert!(message.contains(&*path.to_string_lossy()), "error without the file: {message}");
        }
    }
}

fn check_mesh(mesh: &TriMesh) {
    mesh.validate().expect("a mesh the reader returned is valid");
    // the reports and checks that follow reading must not panic either
    if let Ok(report) = shapespace_geometry::topology::mesh_report(mesh) {
        assert!(!report.area.is_nan(), "NaN area");
    }
    let _ = shapespace_geometry::topology::check_coordinate_range(mesh);
}

/// Parses `data` (as UTF-8, lossily) as a marker file and the centre/boundary marker strings.
pub fn check_markers(data: &[u8]) {
    let text = String::from_utf8_lossy(data);
    let _ = shapespace_conformal::MarkerFile::from_json_str(&text, "fuzz.json");
    let _ = shapespace_conformal::CenterMarker::parse(&text);
    let _ = shapespace_conformal::BoundaryMarker::parse(&text);
}

/// Reads sites, weights and a small triangulated domain from `data` (f64 triples, NaN and
/// infinities kept), builds the power diagram, checks its invariants and integrates the
/// restricted cells: their masses must add up to the domain's mass.
pub fn check_power_diagram(data: &[u8]) {
    let values: Vec<f64> = data
        .chunks_exact(8)
        .map(|c| f64::from_le_bytes(c.try_into().unwrap()))
        .collect();
    let sites: Vec<[f64; 2]> = values.chunks_exact(3).map(|v| [v[0], v[1]]).collect();
    let weights: Vec<f64> = values.chunks_exact(3).map(|v| v[2]).collect();
    if sites.is_empty() {
        return;
    }
    let Ok(diagram) = shapespace_omt::power_diagram::PowerDiagram::new(&sites, &weights) else {
        return;
    };
    if let Err(e) = diagram.sanity_check() {
        panic!("power diagram invariant broken: {e}");
    }
    // the integrator's precondition: sites within MAX_SITE_DISTANCE diameters of the source
    // (farther ones are refused by `solve_ot`; see `restricted`'s module docs)
    let reach = shapespace_omt::restricted::MAX_SITE_DISTANCE * 8f64.sqrt();
    if sites
        .iter()
        .any(|p| (p[0].abs() - 1.0).max(0.0).hypot((p[1].abs() - 1.0).max(0.0)) > reach)
    {
        return;
    }
    // the unit square as two triangles, uniform density
    let measure = shapespace_omt::SourceMeasure::new(
        vec![[-1.0, -1.0], [1.0, -1.0], [1.0, 1.0], [-1.0, 1.0]],
        vec![[0, 1, 2], [0, 2, 3]],
        vec![1.0, 1.0],
    )
    .expect("a valid square");
    let integrals = shapespace_omt::restricted::RestrictedIntegrator::new(&measure).integrate(&diagram);
    let total: f64 = integrals.masses.iter().sum();
    assert!(
        (total - 4.0).abs() <= 1e-8 * 4.0,
        "restricted masses add up to {total}, not 4"
    );
}

/// One step of xorshift64* (a fixed stream without dependencies).
fn xorshift(state: &mut u64) -> u64 {
    *state ^= *state >> 12;
    *state ^= *state << 25;
    *state ^= *state >> 27;
    state.wrapping_mul(0x2545_f491_4f6c_dd1d)
}

/// Runs `check` on each file named on the command line, or, without arguments, on `count`
/// seeded mutations (byte flips, cuts, repeated spans) of each file of `seeds`; a panic is
/// reported with the input written to `crash-<target>-<n>` in the working folder, and the
/// process exits 1.
pub fn replay_or_sweep(target: &str, seeds: &[&Path], count: usize, check: impl Fn(&[u8]) + std::panic::RefUnwindSafe) {
    let args: Vec<String> = std::env::args().skip(1).collect();
    let mut inputs: Vec<Vec<u8>> = Vec::new();
    if args.is_empty() {
        let mut state = 0x5eed_2026_u64;
        for seed in seeds {
            let Ok(bytes) = std::fs::read(seed) else { continue };
            inputs.push(bytes.clone());
            for _ in 0..count {
                let mut m = bytes.clone();
                for _ in 0..1 + xorshift(&mut state) % 4 {
                    let n = m.len().max(1) as u64;
                    match xorshift(&mut state) % 4 {
                        0 if !m.is_empty() => {
                            let i = (xorshift(&mut state) % n) as usize;
                            m[i] ^= 1 << (xorshift(&mut state) % 8);
                        }
                        1 => m.truncate((xorshift(&mut state) % n) as usize),
                        2 if !m.is_empty() => {
                            let i = (xorshift(&mut state) % n) as usize;
                            let j = (i + (xorshift(&mut state) % 64) as usize).min(m.len());
                            let span = m[i..j].to_vec();
                            m.splice(i..i, span);
                        }
                        _ if !m.is_empty() => {
                            let i = (xorshift(&mut state) % n) as usize;
                            m[i] = (xorshift(&mut state) % 256) as u8;
                        }
                        _ => {}
                    }
                }
                inputs.push(m);
            }
        }
    } else {
        for a in &args {
            inputs.push(std::fs::read(a).unwrap_or_else(|e| panic!("{a}: {e}")));
        }
    }
    std::panic::set_hook(Box::new(|_| {}));
    let mut crashes = 0;
    for (k, input) in inputs.iter().enumerate() {
        if let Err(payload) = std::panic::catch_unwind(|| check(input)) {
            let what = payload
                .downcast_ref::<&str>()
                .map(|s| s.to_string())
                .or_else(|| payload.downcast_ref::<String>().cloned())
                .unwrap_or_default();
            let name = format!("crash-{target}-{k}");
            let _ = std::fs::write(&name, input);
            eprintln!("{target}: input {k} panics: {what} (written to {name})");
            crashes += 1;
        }
    }
    eprintln!("{target}: {} inputs, {crashes} panics", inputs.len());
    if crashes > 0 {
        std::process::exit(1);
    }
}

/// The plain-binary run of a reader target `read_<ext>`: replays the files given, or sweeps
/// mutations of the corpus `tests/bad_input/*.<ext>` and one public mesh of the shared datasets
/// (`shared_seed`, relative to `../shared/datasets`; left out when absent) through
/// [`check_mesh_reader`].
pub fn mesh_reader_sweep(ext: &str, shared_seed: &str) {
    let root = Path::new(env!("CARGO_MANIFEST_DIR")).join("..");
    let mut corpus: Vec<std::path::PathBuf> = std::fs::read_dir(root.join("tests/bad_input"))
        .map(|d| d.filter_map(|e| e.ok().map(|e| e.path())).collect())
        .unwrap_or_default();
    corpus.sort();
    corpus.push(root.join("../shared/datasets").join(shared_seed));
    let seeds: Vec<&Path> = corpus
        .iter()
        .filter(|p| p.extension().is_some_and(|e| e == ext))
        .map(|p| p.as_path())
        .collect();
    let name = Path::new("fuzz").with_extension(ext);
    replay_or_sweep(&format!("read_{ext}"), &seeds, 2000, |data| check_mesh_reader(data, &name));
}
