//! The bad-input corpus `tests/bad_input/`: every file either reads (topological oddities are
//! not read errors) or fails with an error that names the file, the line or byte offset and
//! the problem. Never a panic: each read runs under `catch_unwind`.

use std::path::{Path, PathBuf};

use shapespace_geometry::io::read_mesh;

enum Expect {
    /// An error whose message contains `file:line:` (text) or `file: byte N:` (binary), and
    /// each of the given fragments.
    Error {
        at: &'static str,
        problem: &'static [&'static str],
    },
    /// A successful read with this many vertices and triangles.
    Reads { vertices: usize, faces: usize },
}
use Expect::*;

const fn err(at: &'static str, problem: &'static [&'static str]) -> Expect {
    Error { at, problem }
}

/// Every file in the corpus and what reading it must give.
const CORPUS: &[(&str, Expect)] = &[
    // a lone CR inside a number, PLY 2.0, OFF counts with an extra value
    ("cr_inside_number.obj", err(":2:", &["carriage return"])),
    ("ply_version_2.ply", err(":2:", &["PLY version '2.0'"])),
    (
        "off_counts_extra_value.off",
        err(":2:", &["expected the counts", "found 4 values"]),
    ),
    ("binary_garbage.obj", err(":1:", &["binary data"])),
    ("concave_quad.obj", err(":6:", &["face 0", "not convex"])),
    ("self_crossing_quad.obj", err(":6:", &["face 0", "crosses itself"])),
    (
        "ply_vertex_without_properties.ply",
        err(":6:", &["vertex element has no properties"]),
    ),
    (
        "ply_vertex_without_properties_triangle.ply",
        err(":6:", &["vertex element has no properties"]),
    ),
    ("binary_garbage.off", err(":1:", &["binary data"])),
    ("binary_garbage.ply", err(":1:", &["not a PLY file"])),
    ("empty.obj", err(":1:", &["empty file"])),
    ("empty.off", err(":1:", &["empty file"])),
    ("empty.ply", err(":1:", &["empty file"])),
    ("face_2_vertices.obj", err(":5:", &["face 1 has 2 vertices"])),
    ("face_2_vertices.off", err(":7:", &["face 1 has 2 vertices"])),
    ("face_2_vertices.ply", err(":14:", &["face 1 has 2 vertices"])),
    (
        "face_2_vertices_binary.ply",
        err(": byte 230:", &["face 1 has 2 vertices"]),
    ),
    (
        "index_out_of_range.obj",
        err(":6:", &["vertex index 9 out of range", "4 vertices"]),
    ),
    (
        "index_out_of_range.off",
        err(":6:", &["face 0", "vertex index 3 out of range"]),
    ),
    (
        "index_out_of_range.ply",
        err(":14:", &["face 1", "vertex index 3 out of range"]),
    ),
    (
        "index_out_of_range_binary.ply",
        err(": byte 230:", &["face 1", "vertex index 4 out of range"]),
    ),
    ("index_zero.obj", err(":4:", &["index 0 is invalid"])),
    ("inf.off", err(":5:", &["vertex 2 has a non-finite coordinate"])),
    ("inf.ply", err(":11:", &["vertex 1 has a non-finite coordinate"])),
    ("nan.obj", err(":2:", &["vertex 1 has a non-finite coordinate"])),
    (
        "nan_binary.ply",
        err(": byte 181:", &["vertex 1 has a non-finite coordinate"]),
    ),
    (
        "negative_before_start.obj",
        err(":5:", &["-4 points before the first vertex"]),
    ),
    ("negative_index.off", err(":6:", &["vertex index -1 out of range"])),
    ("non_numeric.obj", err(":2:", &["vertex 1", "non-numeric", "'O'"])),
    ("non_numeric.off", err(":5:", &["vertex 2", "non-numeric", "'1,5'"])),
    ("non_numeric.ply", err(":13:", &["face 0", "non-integer value 'one'"])),
    ("not_off.off", err(":1:", &["not an OFF file"])),
    ("not_ply.ply", err(":1:", &["not a PLY file"])),
    ("obj_no_faces.obj", err(":4:", &["no faces"])),
    // The header says 3 vertices but 4 follow: the 4th vertex line is read as a face.
    ("off_counts_too_small.off", err(":6:", &["face 0 has 1 vertices"])),
    (
        "off_huge_count.off",
        err(":4:", &["end of file", "declares 4000000000 vertices, found 1"]),
    ),
    ("off_missing_counts.off", err(":2:", &["end of file", "counts"])),
    ("ply_bad_type.ply", err(":4:", &["unknown property type 'flaot'"])),
    (
        "ply_header_lies_ascii.ply",
        err(":14:", &["data after the last element", "wrong counts"]),
    ),
    (
        "ply_header_lies_binary.ply",
        err(": byte 172:", &["declares 1000 'vertex' elements", "only 74 bytes"]),
    ),
    ("ply_no_end_header.ply", err(":4:", &["no 'end_header'"])),
    ("ply_no_faces.ply", err(":7:", &["no 'face' or 'tristrips' element"])),
    // Header says 3 vertices, 4 follow: the 4th vertex's bytes are read as face 0.
    (
        "ply_trailing_bytes_binary.ply",
        err(": byte 205:", &["face 0 has 0 vertices"]),
    ),
    ("truncated.obj", err(":7:", &["vertex 4 has 2 coordinates"])),
    (
        "truncated.off",
        err(":8:", &["end of file", "declares 2 faces, found 1"]),
    ),
    (
        "truncated_ascii.ply",
        err(":13:", &["end of file", "declares 4 'vertex' elements, found 3"]),
    ),
    (
        "truncated_binary.ply",
        err(": byte 230:", &["face 1", "unexpected end of file"]),
    ),
    ("unknown_format.stl", err(":", &["unsupported mesh format", "'.stl'"])),
    ("ok_extra_elements_big_endian.ply", Reads { vertices: 4, faces: 3 }),
    ("ok_mixed_tri_quad.obj", Reads { vertices: 5, faces: 3 }),
    ("ok_mixed_tri_quad.ply", Reads { vertices: 5, faces: 3 }),
    ("ok_non_manifold_edge.obj", Reads { vertices: 5, faces: 3 }),
    ("ok_non_manifold_vertex.off", Reads { vertices: 5, faces: 2 }),
    ("ok_unreferenced_vertex.off", Reads { vertices: 3, faces: 1 }),
];

fn corpus_dir() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("../../tests/bad_input")
}

#[test]
fn every_bad_input_fails_cleanly_and_the_good_ones_read() {
    let dir = corpus_dir();
    let mut failures = Vec::new();
    for (name, expect) in CORPUS {
        let path = dir.join(name);
        assert!(path.is_file(), "corpus file {} missing", path.display());
        let result = std::panic::catch_unwind(|| read_mesh(&path));
        let Ok(result) = result else {
            failures.push(format!("{name}: PANIC"));
            continue;
        };
        match (expect, result) {
            (Error { at, problem }, Err(e)) => {
                let message = e.to_string();
                let located = format!("{name}{at}");
                if !message.contains(&located) || !problem.iter().all(|p| message.contains(p)) {
                    failures.push(format!("{name}: expected '{located}' and {problem:?} in: {message}"));
                }
            }
            (Error { .. }, Ok(m)) => failures.push(format!(
                "{name}: read without error ({} V, {} F)",
                m.num_vertices(),
                m.num_faces()
            )),
            (Reads { vertices, faces }, Ok(m)) => {
                if (m.num_vertices(), m.num_faces()) != (*vertices, *faces) || m.validate().is_err() {
                    failures.push(format!("{name}: read {} V, {} F", m.num_vertices(), m.num_faces()));
                }
            }
            (Reads { .. }, Err(e)) => failures.push(format!("{name}: unexpected error: {e}")),
        }
    }
    assert!(failures.is_empty(), "\n{}", failures.join("\n"));
}

#[test]
fn the_table_covers_the_whole_corpus() {
    let mut on_disk: Vec<String> = std::fs::read_dir(corpus_dir())
        .unwrap()
        .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
        .filter(|n| n != "README.md")
        .collect();
    on_disk.sort();
    let mut listed: Vec<String> = CORPUS.iter().map(|(n, _)| n.to_string()).collect();
    listed.sort();
    assert_eq!(on_disk, listed);
}

#[test]
fn topology_problems_read_with_the_faces_as_written() {
    let dir = corpus_dir();
    // Three triangles on the edge (0, 1): a non-manifold edge, kept as in the file.
    let m = read_mesh(&dir.join("ok_non_manifold_edge.obj")).unwrap();
    assert_eq!(m.faces, vec![[0, 1, 2], [1, 0, 3], [0, 1, 4]]);
    // A bowtie: two triangles sharing only vertex 0.
    let m = read_mesh(&dir.join("ok_non_manifold_vertex.off")).unwrap();
    assert_eq!(m.faces, vec![[0, 1, 2], [0, 3, 4]]);
    // CRLF OBJ with a group line: the quad 1 2 3 4 is fanned from its first corner.
    let m = read_mesh(&dir.join("ok_mixed_tri_quad.obj")).unwrap();
    assert_eq!(m.faces, vec![[0, 1, 2], [0, 2, 3], [1, 4, 2]]);
    let p = read_mesh(&dir.join("ok_mixed_tri_quad.ply")).unwrap();
    assert_eq!(p, m);
    // Big-endian doubles with skipped list properties and a skipped element.
    let m = read_mesh(&dir.join("ok_extra_elements_big_endian.ply")).unwrap();
    assert_eq!(
        m.positions,
        vec![[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [1.0, 1.0, 0.0], [0.0, 1.0, 0.0]]
    );
    assert_eq!(m.faces, vec![[0, 1, 2], [0, 1, 2], [0, 2, 3]]);
}

/// Every prefix of a few valid files (a truncation at every byte) and single-byte corruptions
/// give an `Ok` or an `Err` that names the file, never a panic.
#[test]
fn truncations_and_corruptions_never_panic() {
    let dir = corpus_dir();
    for name in [
        "ok_extra_elements_big_endian.ply",
        "ok_mixed_tri_quad.obj",
        "ok_non_manifold_vertex.off",
        "ok_mixed_tri_quad.ply",
    ] {
        let data = std::fs::read(dir.join(name)).unwrap();
        let path = Path::new(name);
        let ext = path.extension().unwrap().to_str().unwrap();
        let parse = |bytes: &[u8]| match ext {
            "obj" => shapespace_geometry::io::parse_obj(bytes, path),
            "off" => shapespace_geometry::io::parse_off(bytes, path),
            _ => shapespace_geometry::io::parse_ply(bytes, path),
        };
        let mut variants: Vec<Vec<u8>> = (0..data.len()).map(|n| data[..n].to_vec()).collect();
        for k in 0..data.len() {
            for b in [0u8, b'\n', b'-', b'9', 0xff] {
                let mut v = data.clone();
                v[k] = b;
                variants.push(v);
            }
        }
        for bytes in &variants {
            let result = std::panic::catch_unwind(|| parse(bytes));
            match result {
                Err(_) => panic!("{name}: panic on input {:?}", String::from_utf8_lossy(bytes)),
                Ok(Err(e)) => assert!(e.to_string().contains(name), "{e}"),
                Ok(Ok(m)) => m.validate().unwrap(),
            }
        }
    }
}

/// a device as a mesh file is refused before reading (`/dev/zero` was read
/// without end), naming the file.
#[cfg(unix)]
#[test]
fn devices_are_not_read_as_meshes() {
    let dir = std::env::temp_dir().join(format!("shapespace-device-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let zero = dir.join("zero.obj");
    let _ = std::fs::remove_file(&zero);
    std::os::unix::fs::symlink("/dev/zero", &zero).unwrap();
    let e = read_mesh(&zero).unwrap_err().to_string();
    assert!(e.contains("zero.obj") && e.contains("not a regular file"), "{e}");
    std::fs::remove_dir_all(&dir).ok();
}
