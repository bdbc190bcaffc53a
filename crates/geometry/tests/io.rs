//! Mesh I/O on real files and round trips.
//!
//! Counts come from the `SOURCE.md` tables and `mesh_stats.json` of the shared datasets folder
//! (`$SHAPESPACE_DATA`, default `../shared/datasets` beside the workspace; computed there by an
//! independent Python script). The tests on real files read them from that folder and are
//! skipped, with a `SKIPPED` line naming the missing path, when it is absent.

use std::path::{Path, PathBuf};

use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use shapespace_geometry::io::{
    parse_obj, read_mesh, read_obj, read_off, read_ply, write_mesh, write_obj, write_off, write_ply, PlyFormat,
};
use shapespace_geometry::TriMesh;
use shapespace_test_support::{shared_file, shared_root};

/// The small public meshes these tests read, in the shared datasets folder.
const CAT_HEAD: &str = "geometry_central_assets/cat_head.obj";
const PLATE121: &str = "goast/plate/plate121.ply";
const WOLF0: &str = "tosca/wolf0.off";
const WOODY: &str = "common_3d_test_models/woody.obj";

/// A fresh temporary directory for this test process.
fn temp_dir(name: &str) -> PathBuf {
    let dir = std::env::temp_dir().join(format!("shapespace-io-{}-{name}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    dir
}

fn assert_counts(mesh: &TriMesh, v: usize, f: usize, what: &str) {
    assert_eq!((mesh.num_vertices(), mesh.num_faces()), (v, f), "{what}: (V, F)");
    mesh.validate().unwrap();
}

#[test]
fn small_meshes_read_with_the_published_counts() {
    let (Some(cat), Some(plate), Some(wolf), Some(woody)) = (
        shared_file(CAT_HEAD),
        shared_file(PLATE121),
        shared_file(WOLF0),
        shared_file(WOODY),
    ) else {
        return;
    };
    let cat = read_mesh(&cat).unwrap();
    assert_counts(&cat, 131, 248, "cat_head.obj");
    // First and last vertex lines, and the first face line "f 1 2 3", of the file.
    assert_eq!(cat.positions[0], [-0.008298, 0.583053, 0.070454]);
    assert_eq!(cat.faces[0], [0, 1, 2]);
    assert_eq!(cat.uvs, None);

    let plate = read_mesh(&plate).unwrap();
    assert_counts(&plate, 121, 200, "plate121.ply");
    // A flat plate: every z is 0.
    assert!(plate.positions.iter().all(|p| p[2] == 0.0));

    let wolf = read_mesh(&wolf).unwrap();
    assert_counts(&wolf, 4344, 8684, "wolf0.off");
    assert_eq!(wolf.positions[0], [3.106520, 50.349998, 52.238998]);

    let woody = read_mesh(&woody).unwrap();
    assert_counts(&woody, 694, 1267, "woody.obj");
}

#[test]
fn every_format_round_trips_a_real_mesh() {
    let dir = temp_dir("real");
    let Some(wolf) = shared_file(WOLF0) else { return };
    let wolf = read_off(&wolf).unwrap();
    for name in ["w.obj", "w.OFF", "w.ply"] {
        let path = dir.join(name);
        write_mesh(&path, &wolf).unwrap();
        assert_eq!(read_mesh(&path).unwrap(), wolf, "{name}");
    }
    let path = dir.join("w_ascii.ply");
    write_ply(&path, &wolf, PlyFormat::Ascii).unwrap();
    assert_eq!(read_ply(&path).unwrap(), wolf);
    std::fs::remove_dir_all(&dir).unwrap();
}

/// A random mesh whose coordinates are random bit patterns (all finite: tiny, huge,
/// subnormal, negative zero), the hard case for decimal round trips.
fn random_mesh(seed: u64, num_vertices: usize, num_faces: usize, with_uvs: bool) -> TriMesh {
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    let value = |rng: &mut ChaCha8Rng| loop {
        let x = match rng.random_range(0..4) {
            0 => f64::from_bits(rng.random::<u64>()),
            1 => rng.random_range(-1.0..1.0),
            2 => f64::from_bits(rng.random_range(0..1u64 << 52)), // subnormal
            _ => rng.random_range(-1e6..1e6) / 3.0,
        };
        if x.is_finite() {
            return x;
        }
    };
    let positions = (0..num_vertices)
        .map(|_| [value(&mut rng), value(&mut rng), value(&mut rng)])
        .collect();
    let faces = (0..num_faces)
        .map(|_| {
            let n = num_vertices as u32;
            [rng.random_range(0..n), rng.random_range(0..n), rng.random_range(0..n)]
        })
        .collect();
    let uvs = with_uvs.then(|| (0..num_vertices).map(|_| [value(&mut rng), value(&mut rng)]).collect());
    TriMesh { positions, faces, uvs }
}

#[test]
fn round_trips_are_bit_exact() {
    let dir = temp_dir("random");
    for seed in 0..4 {
        let with_uvs = random_mesh(seed, 300, 500, true);
        let no_uvs = TriMesh {
            uvs: None,
            ..with_uvs.clone()
        };

        let path = dir.join("m.obj");
        write_obj(&path, &with_uvs).unwrap();
        let back = read_obj(&path).unwrap();
        let bits = |m: &TriMesh| m.positions.iter().flatten().map(|x| x.to_bits()).collect::<Vec<_>>();
        assert_eq!(bits(&back), bits(&with_uvs), "OBJ positions, seed {seed}");
        assert_eq!(back, with_uvs, "OBJ with uvs, seed {seed}");
        write_obj(&path, &no_uvs).unwrap();
        assert_eq!(read_obj(&path).unwrap(), no_uvs, "OBJ, seed {seed}");

        let path = dir.join("m.off");
        write_off(&path, &no_uvs).unwrap();
        let back = read_off(&path).unwrap();
        assert_eq!(bits(&back), bits(&no_uvs), "OFF positions, seed {seed}");
        assert_eq!(back, no_uvs, "OFF, seed {seed}");

        let path = dir.join("m.ply");
        for format in [
            PlyFormat::Ascii,
            PlyFormat::BinaryLittleEndian,
            PlyFormat::BinaryBigEndian,
        ] {
            for mesh in [&with_uvs, &no_uvs] {
                write_ply(&path, mesh, format).unwrap();
                let back = read_ply(&path).unwrap();
                assert_eq!(bits(&back), bits(mesh), "PLY {format:?} positions, seed {seed}");
                assert_eq!(&back, mesh, "PLY {format:?}, seed {seed}");
            }
        }
    }
    std::fs::remove_dir_all(&dir).unwrap();
}

#[test]
fn writers_refuse_invalid_meshes_and_name_the_file() {
    let dir = temp_dir("invalid");
    let bad_index = TriMesh {
        positions: vec![[0.0; 3]; 3],
        faces: vec![[0, 1, 3]],
        uvs: None,
    };
    let nan = TriMesh {
        positions: vec![[0.0, f64::NAN, 0.0]; 3],
        faces: vec![[0, 1, 2]],
        uvs: None,
    };
    for (mesh, problem) in [(&bad_index, "references vertex 3"), (&nan, "non-finite")] {
        for name in ["x.obj", "x.off", "x.ply"] {
            let path = dir.join(name);
            let e = write_mesh(&path, mesh).unwrap_err().to_string();
            assert!(e.contains(name) && e.contains(problem), "{e}");
            assert!(!path.exists(), "{name} written despite the error");
        }
    }
    let e = write_mesh(&dir.join("x.stl"), &bad_index).unwrap_err().to_string();
    assert!(e.contains("x.stl") && e.contains("unsupported"), "{e}");
    let e = read_mesh(&dir.join("missing.obj")).unwrap_err().to_string();
    assert!(e.contains("missing.obj"), "{e}");
    std::fs::remove_dir_all(&dir).unwrap();
}

#[test]
fn obj_uvs_per_vertex_when_consistent() {
    // camel_b.obj style: vt per vertex and faces "f a/a b/b c/c"; the quad is split.
    let text = "v 0 0 0\nv 1 0 0\nv 1 1 0\nv 0 1 0\nvt 0.5 0.5\nvt 1.5 0.5\nvt 1.5 1.5\nvt 0.5 1.5\n\
                f 1/1 2/2 3/3 4/4\n";
    let m = parse_obj(text, Path::new("uv.obj")).unwrap();
    assert_eq!(m.faces, vec![[0, 1, 2], [0, 2, 3]]);
    assert_eq!(m.uvs.unwrap(), vec![[0.5, 0.5], [1.5, 0.5], [1.5, 1.5], [0.5, 1.5]]);
}

#[test]
fn shared_real_format_variants() {
    let Some(root) = shared_root() else { return };
    let cases: [(&str, usize, usize); 11] = [
        ("libigl_tutorial_data/camelhead.off", 11381, 22704), // CRLF, trailing spaces
        ("tosca/cat0.off", 27894, 55712),
        ("sumner_deformation_transfer/cat-poses/0001.obj", 7207, 14410),
        ("sumner_deformation_transfer/horse-poses/reference.obj", 8431, 16843), // CRLF
        ("ict_facekit/template_face_full_neutral.obj", 9409, 18460),
        ("ict_facekit/original/generic_neutral_mesh.obj", 26719, 52220), // quads, v/vt, mtllib
        ("goast/faces/neutral.ply", 7118, 14037),                        // ascii, vertex_index
        ("geometry_central_assets/cat_head.obj", 131, 248),
        ("libigl_tutorial_data/face.obj", 25905, 51712),
        ("libigl_tutorial_data/camel_b.obj", 2032, 3576), // v/vt faces
        ("common_3d_test_models/igea_trilist.ply", 134345, 268686),
    ];
    for (file, v, f) in cases {
        let mesh = read_mesh(&root.join(file)).unwrap();
        assert_counts(&mesh, v, f, file);
    }
    // ICT head: 28,911 vt for 26,719 v (UV seams), so no per-vertex UVs.
    assert_eq!(
        read_mesh(&root.join("ict_facekit/original/generic_neutral_mesh.obj"))
            .unwrap()
            .uvs,
        None
    );
    // camel_b: one vt per vertex; its first line "vt 68.389594 -2.440819" belongs to vertex 1.
    let camel = read_mesh(&root.join("libigl_tutorial_data/camel_b.obj")).unwrap();
    let uvs = camel.uvs.expect("camel_b.obj has one vt per vertex");
    assert_eq!(uvs.len(), 2032);
    assert_eq!(uvs[0], [68.389594, -2.440819]);
}

#[test]
fn igea_tristrips_match_the_triangle_list() {
    let Some(root) = shared_root() else { return };
    let strips = read_ply(&root.join("common_3d_test_models/igea.ply")).unwrap();
    let list = read_ply(&root.join("common_3d_test_models/igea_trilist.ply")).unwrap();
    assert_eq!(strips.num_vertices(), 134345);
    assert_eq!(strips.positions, list.positions);
    assert_eq!(strips.num_faces(), 268686);
    // The same triangles in the same order: igea_trilist.ply was converted with the same
    // convention (alternating winding, degenerates dropped).
    assert_eq!(strips.faces, list.faces);
    // Independently of that file: the decoded strips form a closed, consistently oriented
    // surface, so every directed edge occurs exactly once and its reverse occurs too.
    let directed: std::collections::HashSet<(u32, u32)> = strips
        .faces
        .iter()
        .flat_map(|&[a, b, c]| [(a, b), (b, c), (c, a)])
        .collect();
    assert_eq!(directed.len(), 3 * strips.num_faces());
    assert!(directed.iter().all(|&(a, b)| directed.contains(&(b, a))));
}

/// Every mesh of the shared datasets against `mesh_stats.json` (file vertex count, triangle
/// count after fan triangulation).
#[test]
fn shared_corpus_matches_mesh_stats() {
    let Some(root) = shared_root() else { return };
    let stats: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(root.join("mesh_stats.json")).unwrap()).unwrap();
    let entries = stats.as_array().unwrap();
    assert!(entries.len() >= 90, "{} entries", entries.len());
    use rayon::prelude::*;
    let checked: usize = entries
        .par_iter()
        .map(|e| {
            let file = e["file"].as_str().unwrap();
            let v = e["V_file"].as_u64().unwrap() as usize;
            let f = e["F_tri"].as_u64().unwrap() as usize;
            let mesh = read_mesh(&root.join(file)).unwrap_or_else(|err| panic!("{err}"));
            assert_counts(&mesh, v, f, file);
            1
        })
        .sum();
    assert_eq!(checked, entries.len());
}

/// A non-convex quad whose fan from its first corner overlaps itself is an error naming the
/// polygon (and its line in text files) in all three formats; the same quad listed from a corner
/// that sees all of it reads as two triangles of its true area, as does a convex pentagon with
/// three collinear corners (a zero-area fan triangle is left to the degenerate-face checks).
#[test]
fn polygons_whose_fan_overlaps_are_errors() {
    let dir = temp_dir("fans");
    // A(0,0) B(2,0) C(0.5,0.5) D(0,2): counter-clockwise, reflex at C, area 1
    let v = "v 0 0 0\nv 2 0 0\nv 0.5 0.5 0\nv 0 2 0\n";
    let bad = dir.join("bad.obj");
    std::fs::write(&bad, format!("{v}f 2 3 4 1\n")).unwrap();
    let e = read_mesh(&bad).unwrap_err().to_string();
    assert!(
        e.contains("bad.obj:5:") && e.contains("face 0") && e.contains("not convex"),
        "{e}"
    );
    let ok = dir.join("ok.obj");
    std::fs::write(&ok, format!("{v}f 1 2 3 4\n")).unwrap();
    let m = read_mesh(&ok).unwrap();
    assert_eq!(m.faces.len(), 2);
    assert!((shapespace_geometry::quantities::total_area(&m) - 1.0).abs() < 1e-15);
    let off = dir.join("bad.off");
    std::fs::write(&off, "OFF\n4 2 0\n0 0 0\n2 0 0\n0.5 0.5 0\n0 2 0\n3 0 1 3\n4 1 2 3 0\n").unwrap();
    let e = read_mesh(&off).unwrap_err().to_string();
    assert!(
        e.contains("bad.off:8:") && e.contains("face 1") && e.contains("not convex"),
        "{e}"
    );
    let ply = dir.join("bad.ply");
    std::fs::write(
        &ply,
        "ply\nformat ascii 1.0\nelement vertex 4\nproperty double x\nproperty double y\nproperty double z\n\
         element face 1\nproperty list uchar int vertex_indices\nend_header\n\
         0 0 0\n2 0 0\n0.5 0.5 0\n0 2 0\n4 1 2 3 0\n",
    )
    .unwrap();
    let e = read_mesh(&ply).unwrap_err().to_string();
    assert!(
        e.contains("bad.ply") && e.contains("face 0") && e.contains("not convex"),
        "{e}"
    );
    // a convex pentagon (unit square with a corner on its bottom edge) listed from that corner:
    // the fan's triangles are all proper; listed from (0,0) one fan triangle has zero area
    let pentagon = dir.join("pentagon.obj");
    let v5 = "v 0 0 0\nv 0.5 0 0\nv 1 0 0\nv 1 1 0\nv 0 1 0\n";
    for face in ["f 2 3 4 5 1\n", "f 1 2 3 4 5\n"] {
        std::fs::write(&pentagon, format!("{v5}{face}")).unwrap();
        let m = read_mesh(&pentagon).unwrap();
        assert_eq!(m.faces.len(), 3);
        assert!(
            (shapespace_geometry::quantities::total_area(&m) - 1.0).abs() < 1e-15,
            "{face}"
        );
    }
    // The same pentagon moved and turned by an angle where the rounded corner on the edge (at
    // 0.3 of it) makes the collinear fan
    // triangle (A, M, B) slightly reversed: rounding, not a fold, so it still reads.
    let turned = (1..90).find_map(|deg| {
        let (sin, cos) = (deg as f64).to_radians().sin_cos();
        let r = |p: [f64; 2]| [0.1 + cos * p[0] - sin * p[1], 0.3 + sin * p[0] + cos * p[1]];
        let (a, b) = (r([0.0, 0.0]), r([1.0, 0.0]));
        let m = [a[0] + 0.3 * (b[0] - a[0]), a[1] + 0.3 * (b[1] - a[1])];
        let z = (m[0] - a[0]) * (b[1] - a[1]) - (m[1] - a[1]) * (b[0] - a[0]);
        (z < 0.0).then(|| [a, m, b, r([1.0, 1.0]), r([0.0, 1.0])])
    });
    let corners = turned.expect("an angle whose rounding reverses the collinear fan triangle");
    let text: String = corners.iter().map(|p| format!("v {:?} {:?} 0\n", p[0], p[1])).collect();
    std::fs::write(&pentagon, format!("{text}f 1 2 3 4 5\n")).unwrap();
    let m = read_mesh(&pentagon).unwrap();
    assert!((shapespace_geometry::quantities::total_area(&m) - 1.0).abs() < 1e-14);
}
