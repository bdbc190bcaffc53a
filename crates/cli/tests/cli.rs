//! End-to-end runs of the `shapespace` binary on bundled data: the outputs exist, have the
//! documented shape and agree with each other; bad input exits with status 2 and a message that
//! names the file, never a panic (status 101).

use std::path::{Path, PathBuf};
use std::process::{Command, Output};

/// geometry-central's cat head (131 vertices), a public disk read from the shared datasets
/// folder (`$SHAPESPACE_DATA`, default `../shared/datasets`); tests that need it skip loudly
/// when it is absent.
const CAT_HEAD: &str = "geometry_central_assets/cat_head.obj";
const PLATE: &str = "goast/plate/plate121.ply";

fn root() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("../..")
}

fn shapespace(args: &[&str]) -> Output {
    Command::new(env!("CARGO_BIN_EXE_shapespace"))
        .args(args)
        .current_dir(root())
        .output()
        .expect("the binary runs")
}

fn scratch(name: &str) -> PathBuf {
    let dir = std::env::temp_dir().join(format!("shapespace-cli-test-{}-{name}", std::process::id()));
    let _ = std::fs::remove_dir_all(&dir);
    std::fs::create_dir_all(&dir).unwrap();
    dir
}

fn stderr(out: &Output) -> String {
    String::from_utf8_lossy(&out.stderr).into_owned()
}

/// `shapespace register A B OPTIONS... --out OUT`.
fn register(a: &Path, b: &Path, options: &[&str], out: &Path) -> Output {
    let mut args = vec!["register", a.to_str().unwrap(), b.to_str().unwrap()];
    args.extend_from_slice(options);
    args.extend(["--out", out.to_str().unwrap()]);
    shapespace(&args)
}

/// `vt` lines of an OBJ as (u, v), and the number of `v` lines.
fn read_vt(path: &Path) -> (Vec<[f64; 2]>, usize) {
    let text = std::fs::read_to_string(path).unwrap();
    let mut vt = Vec::new();
    let mut v = 0;
    for line in text.lines() {
        let mut it = line.split_whitespace();
        match it.next() {
            Some("vt") => {
                let u: f64 = it.next().unwrap().parse().unwrap();
                let w: f64 = it.next().unwrap().parse().unwrap();
                vt.push([u, w]);
            }
            Some("v") => v += 1,
            _ => {}
        }
    }
    (vt, v)
}

/// Both constructions of `shapespace conformal` write one `vt` per vertex inside the closed
/// unit disk, the center marker at 0 and the boundary marker at 1, a factor CSV that agrees with
/// the OBJ, and a report; on the same face they agree to the discretization (the library test
/// tests/bff.rs bounds the difference by 1.51e-2, measured; here 2e-2).
#[test]
fn conformal_with_both_methods() {
    let dir = scratch("conformal");
    let mut maps = Vec::new();
    for method in ["green", "bff"] {
        let obj = dir.join(format!("{method}.obj"));
        let csv = dir.join(format!("{method}.csv"));
        let json = dir.join(format!("{method}.json"));
        let conformal = |extra: &[&str]| {
            let mut args = vec!["conformal", "datasets/faces/id00_neutral.obj", "--method", method];
            args.extend(extra);
            shapespace(&args)
        };
        let out = conformal(&[
            "--out",
            obj.to_str().unwrap(),
            "--factors",
            csv.to_str().unwrap(),
            "--report",
            json.to_str().unwrap(),
        ]);
        assert!(out.status.success(), "{method}: {}", stderr(&out));
        let (vt, nv) = read_vt(&obj);
        assert_eq!(vt.len(), nv);
        assert!(vt.iter().all(|p| p[0].hypot(p[1]) <= 1.0 + 1e-12));
        let report: serde_json::Value = serde_json::from_str(&std::fs::read_to_string(&json).unwrap()).unwrap();
        assert_eq!(report["num_vertices"].as_u64().unwrap() as usize, nv);
        assert_eq!(report["quality"]["num_flipped"].as_u64(), Some(0));
        // the markers of the sidecar landmarks.json: center 4841 -> 0, boundary 8889 -> 1
        let center = report["info"]["markers"]["center"].as_u64().unwrap() as usize;
        let boundary = report["info"]["markers"]["boundary"].as_u64().unwrap() as usize;
        assert!(
            vt[center][0].hypot(vt[center][1]) < 1e-12,
            "{method}: center at {:?}",
            vt[center]
        );
        assert!((vt[boundary][0] - 1.0).abs() < 1e-12 && vt[boundary][1].abs() < 1e-12);
        let mut rows = csv::Reader::from_path(&csv).unwrap();
        assert_eq!(rows.headers().unwrap(), vec!["vertex", "u", "v", "lambda"]);
        let mut n = 0;
        for (i, row) in rows.records().enumerate() {
            let row = row.unwrap();
            let (u, v): (f64, f64) = (row[1].parse().unwrap(), row[2].parse().unwrap());
            // the OBJ prints fewer digits than the CSV's round-trip format
            assert!((u - vt[i][0]).abs() < 1e-6 && (v - vt[i][1]).abs() < 1e-6);
            assert!(row[3].parse::<f64>().unwrap().is_finite());
            n += 1;
        }
        assert_eq!(n, nv);
        // the report's markers are a marker file: fed back, they give the same map
        let again = dir.join(format!("{method}-markers.json"));
        std::fs::write(&again, report["info"]["markers"].to_string()).unwrap();
        let obj2 = dir.join(format!("{method}-again.obj"));
        let out = conformal(&["--landmarks", again.to_str().unwrap(), "--out", obj2.to_str().unwrap()]);
        assert!(out.status.success(), "{method}: {}", stderr(&out));
        assert_eq!(read_vt(&obj2).0, vt, "{method}: markers fed back");
        maps.push(vt);
    }
    let diff = maps[0]
        .iter()
        .zip(&maps[1])
        .map(|(a, b)| (a[0] - b[0]).hypot(a[1] - b[1]))
        .fold(0.0f64, f64::max);
    assert!(diff > 0.0 && diff < 2e-2, "green vs bff: max difference {diff:e}");
}

/// Writes `n` sunflower points in the disk of radius 0.95 as `x,y,mass`, with masses
/// 1, 2, …, `period` repeating.
fn write_sunflower_points(path: &Path, n: usize, period: usize) {
    let mut text = String::from("x,y,mass\n");
    for k in 0..n {
        let r = 0.95 * ((k as f64 + 0.5) / n as f64).sqrt();
        let t = k as f64 * 2.399_963_229_728_653;
        text.push_str(&format!("{},{},{}\n", r * t.cos(), r * t.sin(), 1 + k % period));
    }
    std::fs::write(path, text).unwrap();
}

/// Checks the `mass` column of an `ot` result against the targets of [`write_sunflower_points`]
/// (rescaled to the source's total) to a relative 1e-6.
fn assert_sunflower_masses(result: &Path, n: usize, period: usize, label: &str) {
    let mut rows = csv::Reader::from_path(result).unwrap();
    let masses: Vec<f64> = rows.records().map(|r| r.unwrap()[2].parse().unwrap()).collect();
    assert_eq!(masses.len(), n, "{label}");
    let total: f64 = masses.iter().sum();
    let weights: usize = (0..n).map(|k| 1 + k % period).sum();
    for (k, m) in masses.iter().enumerate() {
        let target = total * (1 + k % period) as f64 / weights as f64;
        assert!(
            (m - target).abs() <= 1e-6 * target,
            "{label}, cell {k}: {m} vs {target}"
        );
    }
}

/// `shapespace ot` on a small point set: the result CSV has one row per point, the masses match
/// the targets to the tolerance and the report records convergence.
#[test]
fn ot_on_a_point_file() {
    let dir = scratch("ot");
    let points = dir.join("points.csv");
    // sunflower points, masses 1 and 2 alternating
    let n = 200;
    write_sunflower_points(&points, n, 2);
    let result = dir.join("result.csv");
    let report = dir.join("report.json");
    let out = shapespace(&[
        "ot",
        "--points",
        points.to_str().unwrap(),
        "--out",
        result.to_str().unwrap(),
        "--report",
        report.to_str().unwrap(),
    ]);
    assert!(out.status.success(), "{}", stderr(&out));
    let mut rows = csv::Reader::from_path(&result).unwrap();
    assert_eq!(rows.headers().unwrap(), vec!["i", "height", "mass", "cx", "cy"]);
    // masses rescaled to the disk polygon's area, in the ratio 1 : 2
    assert_sunflower_masses(&result, n, 2, "ot");
    let report: serde_json::Value = serde_json::from_str(&std::fs::read_to_string(&report).unwrap()).unwrap();
    assert!(report.to_string().contains("onverged"), "{report}");
}

/// `shapespace ot --domain sphere`: Fibonacci points on S² with masses 1 and 3 alternating, the
/// uniform source; the cells carry 4π·ν_i/Σν, the centroids lie on S² near their points, the
/// cells CSV lists pieces whose corners lie on the source triangles (inside the unit ball), and
/// a density mesh with a vertex off the sphere or a point off it is refused, naming the file.
#[test]
fn ot_on_the_sphere() {
    let dir = scratch("ot_sphere");
    let points = dir.join("points.csv");
    let n = 300;
    let mut text = String::from("x,y,z,mass\n");
    for k in 0..n {
        let z = 1.0 - (2 * k + 1) as f64 / n as f64;
        let r = (1.0 - z * z).sqrt();
        let t = k as f64 * std::f64::consts::PI * (3.0 - 5f64.sqrt());
        text.push_str(&format!("{},{},{},{}\n", r * t.cos(), r * t.sin(), z, 1 + 2 * (k % 2)));
    }
    std::fs::write(&points, text).unwrap();
    let result = dir.join("result.csv");
    let cells = dir.join("cells.csv");
    let report = dir.join("report.json");
    let out = shapespace(&[
        "ot",
        "--domain",
        "sphere",
        "--points",
        points.to_str().unwrap(),
        "--out",
        result.to_str().unwrap(),
        "--cells",
        cells.to_str().unwrap(),
        "--report",
        report.to_str().unwrap(),
        "--tol",
        "1e-8",
    ]);
    assert!(out.status.success(), "{}", stderr(&out));
    let mut rows = csv::Reader::from_path(&result).unwrap();
    assert_eq!(rows.headers().unwrap(), vec!["i", "height", "mass", "cx", "cy", "cz"]);
    let unit = 4.0 * std::f64::consts::PI / (2.0 * n as f64);
    let mut count = 0;
    for row in rows.records() {
        let row = row.unwrap();
        let v: Vec<f64> = (0..6).map(|k| row[k].parse().unwrap()).collect();
        let k = v[0] as usize;
        let target = unit * (1 + 2 * (k % 2)) as f64;
        assert!(
            (v[2] / target - 1.0).abs() < 1e-7,
            "cell {k}: mass {} against {target}",
            v[2]
        );
        assert!(((v[3] * v[3] + v[4] * v[4] + v[5] * v[5]).sqrt() - 1.0).abs() < 1e-12);
        count += 1;
    }
    assert_eq!(count, n);
    let mut pieces = csv::Reader::from_path(&cells).unwrap();
    assert_eq!(pieces.headers().unwrap(), vec!["i", "t", "k", "x", "y", "z"]);
    for row in pieces.records() {
        let row = row.unwrap();
        let p: Vec<f64> = (3..6).map(|k| row[k].parse().unwrap()).collect();
        let r = (p[0] * p[0] + p[1] * p[1] + p[2] * p[2]).sqrt();
        assert!(r <= 1.0 + 1e-12 && r > 0.99, "{r}");
    }
    let report: serde_json::Value = serde_json::from_str(&std::fs::read_to_string(&report).unwrap()).unwrap();
    assert_eq!(report["converged"], serde_json::json!(true), "{report}");

    let off = dir.join("off.csv");
    std::fs::write(&off, "x,y,z\n0,0,1\n0,0.5,0.5\n").unwrap();
    let out = shapespace(&[
        "ot",
        "--domain",
        "sphere",
        "--points",
        off.to_str().unwrap(),
        "--out",
        dir.join("o.csv").to_str().unwrap(),
    ]);
    assert_eq!(out.status.code(), Some(2), "{}", stderr(&out));
    assert!(
        stderr(&out).contains("off.csv:3") && stderr(&out).contains("not on the unit sphere"),
        "{}",
        stderr(&out)
    );
    let mesh = dir.join("flat.obj");
    std::fs::write(&mesh, "v 0 0 1\nv 1 0 0\nv 0 1 0.5\nf 1 2 3\n").unwrap();
    let out = shapespace(&[
        "ot",
        "--domain",
        "sphere",
        "--density-mesh",
        mesh.to_str().unwrap(),
        "--points",
        points.to_str().unwrap(),
        "--out",
        dir.join("o.csv").to_str().unwrap(),
    ]);
    assert_eq!(out.status.code(), Some(2), "{}", stderr(&out));
    assert!(
        stderr(&out).contains("flat.obj") && stderr(&out).contains("vertex 3"),
        "{}",
        stderr(&out)
    );
}

/// `shapespace ot --start coarse-to-fine` takes the coarse-to-fine start (1,200 points: one
/// coarse level) and reaches the same masses; `--start voronoi` the Voronoi start; the report says
/// which.
#[test]
fn ot_start_strategies() {
    let dir = scratch("ot_start");
    let points = dir.join("points.csv");
    let n = 1200;
    write_sunflower_points(&points, n, 3);
    let mut costs = Vec::new();
    for (start, expect) in [("coarse-to-fine", "CoarseToFine"), ("voronoi", "Voronoi")] {
        let result = dir.join(format!("{start}.csv"));
        let report = dir.join(format!("{start}.json"));
        let out = shapespace(&[
            "ot",
            "--points",
            points.to_str().unwrap(),
            "--start",
            start,
            "--out",
            result.to_str().unwrap(),
            "--report",
            report.to_str().unwrap(),
        ]);
        assert!(out.status.success(), "{}", stderr(&out));
        let report: serde_json::Value = serde_json::from_str(&std::fs::read_to_string(&report).unwrap()).unwrap();
        assert!(report["start"].as_str().unwrap().starts_with(expect), "{report}");
        assert_sunflower_masses(&result, n, 3, start);
        costs.push(report["cost"].as_f64().unwrap());
    }
    assert!((costs[0] - costs[1]).abs() <= 1e-9 * costs[1], "{costs:?}");
}

/// `shapespace param` writes an area-preserving map: one `vt` per vertex, boundary vertices on
/// the unit circle, and a report whose OT converged and whose map has no flipped face.
#[test]
fn param_on_a_face() {
    let dir = scratch("param");
    let obj = dir.join("param.obj");
    let json = dir.join("param.json");
    let out = shapespace(&[
        "param",
        "datasets/faces/id01_sad.obj",
        "--out",
        obj.to_str().unwrap(),
        "--report",
        json.to_str().unwrap(),
    ]);
    assert!(out.status.success(), "{}", stderr(&out));
    let (vt, nv) = read_vt(&obj);
    assert_eq!(vt.len(), nv);
    let on_circle = vt.iter().filter(|p| (p[0].hypot(p[1]) - 1.0).abs() < 1e-9).count();
    assert!(on_circle > 100, "{on_circle} vertices on the circle");
    let report = std::fs::read_to_string(&json).unwrap();
    let report: serde_json::Value = serde_json::from_str(&report).unwrap();
    let text = report.to_string();
    assert!(text.contains("\"converged\":true"), "{text}");
    assert!(text.contains("\"num_flipped\":0"), "{text}");
}

/// `shapespace param --method lie` writes the Lie-advection map: one `vt` per vertex, boundary
/// vertices on the unit circle, a report with the method, the flow's steps and a distortion
/// block whose map has no flipped face and a |Υ| median below the conformal map's; the square
/// and weights are refused with status 2.
#[test]
fn param_lie_on_a_face() {
    let dir = scratch("param_lie");
    let obj = dir.join("lie.obj");
    let json = dir.join("lie.json");
    let out = shapespace(&[
        "param",
        "datasets/faces/id01_sad.obj",
        "--out",
        obj.to_str().unwrap(),
        "--report",
        json.to_str().unwrap(),
        "--method",
        "lie",
    ]);
    assert!(out.status.success(), "{}", stderr(&out));
    assert!(stderr(&out).contains("Lie advection"), "{}", stderr(&out));
    let (vt, nv) = read_vt(&obj);
    assert_eq!(vt.len(), nv);
    let on_circle = vt.iter().filter(|p| (p[0].hypot(p[1]) - 1.0).abs() < 1e-9).count();
    assert!(on_circle > 100, "{on_circle} vertices on the circle");
    let report: serde_json::Value = serde_json::from_str(&std::fs::read_to_string(&json).unwrap()).unwrap();
    assert_eq!(report["method"], "lie");
    assert!(report["lie_advection"]["mean_steps"].as_f64().unwrap() > 1.0);
    let maps = &report["distortion"]["maps"];
    assert_eq!(maps[1]["num_flipped"], 0);
    let median = |k: usize| maps[k]["abs_area_distortion"]["median"].as_f64().unwrap();
    assert!(median(1) < 0.2 * median(0), "{} vs {}", median(1), median(0));
    let square = shapespace(&[
        "param",
        "datasets/faces/id01_sad.obj",
        "--out",
        dir.join("sq.obj").to_str().unwrap(),
        "--method",
        "lie",
        "--domain",
        "square",
    ]);
    assert_eq!(square.status.code(), Some(2), "{}", stderr(&square));
    assert!(stderr(&square).contains("disk only"), "{}", stderr(&square));
}

/// Bad input: exit status 2 (not a panic's 101), and a message naming the file and the problem.
#[test]
fn bad_input_exits_cleanly_and_names_the_file() {
    let dir = scratch("bad");
    let truncated = dir.join("truncated.obj");
    let face = std::fs::read(root().join("datasets/faces/id00_neutral.obj")).unwrap();
    std::fs::write(&truncated, &face[..face.len() - 7]).unwrap();
    let not_a_disk = dir.join("tetrahedron.obj");
    std::fs::write(
        &not_a_disk,
        "v 0 0 0\nv 1 0 0\nv 0 1 0\nv 0 0 1\nf 1 3 2\nf 1 2 4\nf 2 3 4\nf 3 1 4\n",
    )
    .unwrap();
    let nan = dir.join("nan.obj");
    std::fs::write(&nan, "v 0 0 0\nv 1 nan 0\nv 0 1 0\nf 1 2 3\n").unwrap();
    let out_obj = dir.join("out.obj");
    let out_dir = dir.join("out");
    let cases: Vec<(Vec<&str>, &Path, &str)> = vec![
        (vec!["conformal"], &truncated, "has 2 vertices"),
        (vec!["param"], &truncated, "has 2 vertices"),
        (vec!["conformal", "--domain", "disk"], &not_a_disk, "not a disk"),
        (vec!["param"], &not_a_disk, "not a disk"),
        (vec!["conformal", "--method", "bff"], &nan, "non-finite"),
        (
            vec!["conformal", "--center", "999999"],
            Path::new("datasets/faces/id00_neutral.obj"),
            "999999",
        ),
    ];
    for (args, file, problem) in cases {
        let mut all = args.clone();
        all.push(file.to_str().unwrap());
        all.extend(["--out", out_obj.to_str().unwrap()]);
        let out = shapespace(&all);
        let msg = stderr(&out);
        assert_eq!(out.status.code(), Some(2), "{all:?}: {msg}");
        let name = file.file_name().unwrap().to_str().unwrap();
        assert!(msg.contains(name) && msg.contains(problem), "{all:?}: {msg}");
    }
    let pairs = dir.join("pairs.csv");
    std::fs::write(&pairs, "source,target\n0,0\n").unwrap();
    let out = register(
        Path::new("datasets/faces/id00_neutral.obj"),
        &not_a_disk,
        &["--landmarks", pairs.to_str().unwrap()],
        &out_dir,
    );
    assert_eq!(out.status.code(), Some(2), "{}", stderr(&out));
    assert!(stderr(&out).contains("tetrahedron.obj"), "{}", stderr(&out));
}

/// A missing input or a directory in place of a file: exit status 2 and the I/O problem printed
/// once after the path (it was repeated as the error's source).
#[test]
fn io_errors_are_printed_once() {
    let dir = scratch("io");
    let out_obj = dir.join("out.obj");
    let missing = dir.join("missing.obj");
    let folder = dir.join("folder.obj");
    std::fs::create_dir_all(&folder).unwrap();
    for (file, problem) in [(&missing, "No such file"), (&folder, "directory")] {
        for cmd in ["conformal", "param"] {
            let out = shapespace(&[cmd, file.to_str().unwrap(), "--out", out_obj.to_str().unwrap()]);
            let msg = stderr(&out);
            assert_eq!(out.status.code(), Some(2), "{cmd}: {msg}");
            assert!(
                msg.contains(file.file_name().unwrap().to_str().unwrap()),
                "{cmd}: {msg}"
            );
            assert_eq!(msg.matches(problem).count(), 1, "{cmd}: {msg}");
        }
    }
}

/// A 4×4 grid disk (25 vertices, 32 faces) with its coordinates multiplied by `scale`, as OBJ.
fn grid_obj(scale: f64) -> String {
    let mut text = String::new();
    for j in 0..5 {
        for i in 0..5 {
            let (x, y) = (i as f64 / 4.0, j as f64 / 4.0);
            text.push_str(&format!(
                "v {:?} {:?} {:?}\n",
                x * scale,
                y * scale,
                0.1 * x * y * scale
            ));
        }
    }
    for j in 0..4 {
        for i in 0..4 {
            let a = j * 5 + i + 1;
            let (b, c, d) = (a + 1, a + 5, a + 6);
            text.push_str(&format!("f {a} {b} {d}\nf {a} {d} {c}\n"));
        }
    }
    text
}

/// Finite coordinates whose squares overflow (1e300) or underflow (1e-300): the disk commands
/// and `info` say the coordinates are out of range (not "zero-length edge", not an infinite
/// area).
#[test]
fn coordinates_out_of_range_are_named() {
    let dir = scratch("range");
    let out_obj = dir.join("out.obj");
    for (name, scale) in [("huge.obj", 1e300), ("tiny.obj", 1e-300)] {
        let file = dir.join(name);
        std::fs::write(&file, grid_obj(scale)).unwrap();
        for cmd in ["conformal", "param"] {
            let out = shapespace(&[cmd, file.to_str().unwrap(), "--out", out_obj.to_str().unwrap()]);
            let msg = stderr(&out);
            assert_eq!(out.status.code(), Some(2), "{cmd} {name}: {msg}");
            assert!(
                msg.contains(name) && msg.contains("rescale the mesh"),
                "{cmd} {name}: {msg}"
            );
        }
    }
    let out = shapespace(&["info", dir.join("huge.obj").to_str().unwrap()]);
    let table = String::from_utf8_lossy(&out.stdout).into_owned();
    assert!(!table.contains("inf") && !table.contains("NaN"), "{table}");
    assert!(stderr(&out).contains("huge.obj") && stderr(&out).contains("rescale the mesh"));
    // the distances go through the conformal map directly: same message, per file
    let (normal, normal2) = (dir.join("normal.obj"), dir.join("normal2.obj"));
    std::fs::write(&normal, grid_obj(1.0)).unwrap();
    std::fs::write(&normal2, grid_obj(2.0)).unwrap();
    let out = shapespace(&[
        "distances",
        dir.join("tiny.obj").to_str().unwrap(),
        normal.to_str().unwrap(),
        normal2.to_str().unwrap(),
        "--out",
        dir.join("d").to_str().unwrap(),
        "--quiet",
    ]);
    let msg = stderr(&out);
    assert_ne!(out.status.code(), Some(101), "{msg}");
    assert!(msg.contains("tiny.obj") && msg.contains("rescale the mesh"), "{msg}");
    // OT points beyond the power diagram's range
    let points = dir.join("far.csv");
    std::fs::write(&points, "x,y,mass\n1e300,0,1\n0,0,1\n").unwrap();
    let out = shapespace(&[
        "ot",
        "--points",
        points.to_str().unwrap(),
        "--out",
        dir.join("ot.csv").to_str().unwrap(),
    ]);
    let msg = stderr(&out);
    assert_eq!(out.status.code(), Some(2), "{msg}");
    assert!(
        msg.contains("target point 0") && msg.contains("rescale the points"),
        "{msg}"
    );
}

/// Distances whose squares overflow: `mds` exits with status 2 naming the file and the pair
/// (it wrote NaN coordinates and eigenvalues with status 0).
#[test]
fn mds_rejects_distances_whose_squares_overflow() {
    let dir = scratch("mds-big");
    let matrix = dir.join("big.csv");
    std::fs::write(&matrix, "name,a,b,c\na,0,1e300,2\nb,1e300,0,1.5\nc,2,1.5,0\n").unwrap();
    let out = shapespace(&[
        "mds",
        matrix.to_str().unwrap(),
        "--out",
        dir.join("out").to_str().unwrap(),
    ]);
    let msg = stderr(&out);
    assert_eq!(out.status.code(), Some(2), "{msg}");
    assert!(msg.contains("big.csv") && msg.contains("too large"), "{msg}");
}

/// A dataset folder without any class of two meshes: `register-bench` exits with status 2
/// naming the folder (it printed a table of NaN with status 0).
#[test]
fn register_bench_on_an_empty_dataset() {
    let dir = scratch("bench-empty");
    let dataset = dir.join("dataset");
    std::fs::create_dir_all(dataset.join("only-one")).unwrap();
    std::fs::write(dataset.join("only-one/a.obj"), grid_obj(1.0)).unwrap();
    let out = shapespace(&[
        "register-bench",
        dataset.to_str().unwrap(),
        "--out",
        dir.join("out").to_str().unwrap(),
    ]);
    let msg = stderr(&out);
    assert_eq!(out.status.code(), Some(2), "{msg}");
    assert!(msg.contains("dataset") && msg.contains("no class folder"), "{msg}");
}

/// `ot` with a directory in place of a CSV: status 2 and "Is a directory" (it was read as an
/// empty file: "no target point", "0 densities").
#[test]
fn ot_rejects_a_directory_for_a_csv() {
    let dir = scratch("ot-dir");
    let folder = dir.join("points.csv");
    std::fs::create_dir_all(&folder).unwrap();
    let out = shapespace(&[
        "ot",
        "--points",
        folder.to_str().unwrap(),
        "--out",
        dir.join("out.csv").to_str().unwrap(),
    ]);
    let msg = stderr(&out);
    assert_eq!(out.status.code(), Some(2), "{msg}");
    assert!(msg.contains("points.csv") && msg.contains("directory"), "{msg}");
}

/// `distances`: an invalid `--tol` is a usage error (status 2), a pair that fails prints why (it
/// was only in report.json), and a run records the library's pairwise solver settings.
#[test]
fn distances_report_failed_pairs_and_bad_tolerances() {
    let dir = scratch("distances-fail");
    let a = dir.join("a.obj");
    let b = dir.join("b.obj");
    std::fs::write(&a, grid_obj(1.0)).unwrap();
    std::fs::write(&b, grid_obj(2.0).replace("v 0.0 0.0 0.0", "v 0.0 0.0 0.3")).unwrap();
    let out_dir = dir.join("out");
    let run = |extra: &[&str]| {
        let mut args = vec!["distances", a.to_str().unwrap(), b.to_str().unwrap(), "--quiet"];
        args.extend(["--out", out_dir.to_str().unwrap()]);
        args.extend(extra);
        shapespace(&args)
    };
    for tol in ["nan", "1e300", "1"] {
        let out = run(&["--tol", tol]);
        assert_eq!(out.status.code(), Some(2), "{}", stderr(&out));
        assert!(stderr(&out).contains("--tol must be in (0, 1)"), "{}", stderr(&out));
    }
    let out = run(&["--max-iterations", "0"]);
    assert_eq!(out.status.code(), Some(2), "{}", stderr(&out));
    assert!(stderr(&out).contains("--max-iterations"), "{}", stderr(&out));
    // one Newton step is not enough: the pair fails and says why
    let out = run(&["--max-iterations", "1"]);
    assert_eq!(out.status.code(), Some(1), "{}", stderr(&out));
    assert!(stderr(&out).contains("pair a -> b: "), "{}", stderr(&out));
    // with --mds the incomplete matrix is not embedded: exit 1 as without it (it was 2), and
    // an earlier MDS in the folder is removed rather than left beside the new distances
    std::fs::write(out_dir.join("mds.csv"), "stale").unwrap();
    let out = run(&["--max-iterations", "1", "--mds"]);
    assert_eq!(out.status.code(), Some(1), "{}", stderr(&out));
    assert!(stderr(&out).contains("MDS skipped"), "{}", stderr(&out));
    assert!(!out_dir.join("mds.csv").exists());
    // the demo on such a folder does the same
    let demo_out = dir.join("demo");
    let out = shapespace(&[
        "demo",
        "--data",
        dir.to_str().unwrap(),
        "--out",
        demo_out.to_str().unwrap(),
        "--max-iterations",
        "1",
        "--quiet",
    ]);
    assert_eq!(out.status.code(), Some(1), "{}", stderr(&out));
    assert!(stderr(&out).contains("MDS skipped"), "{}", stderr(&out));
    // an absurd thread count is capped (10,000 threads took over a minute to start on 2 cores)
    let out = run(&["--threads", "100000"]);
    assert_eq!(out.status.code(), Some(0), "{}", stderr(&out));
    assert!(stderr(&out).contains("--threads 100000 capped to"), "{}", stderr(&out));
    // the command runs the library's pairwise solver settings (those the benchmark measures;
    // it used to leave the coarse levels at the generic 1e-3, and its --tol default was a
    // literal) and records them
    let report: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(out_dir.join("report.json")).unwrap()).unwrap();
    let expected = shapespace_analysis::distance::PairwiseOptions::default().newton;
    let options = &report["options"];
    assert_eq!(options["tolerance"].as_f64(), Some(expected.tolerance), "{options}");
    assert_eq!(
        options["max_iterations"].as_u64(),
        Some(expected.max_iterations as u64),
        "{options}"
    );
    assert_eq!(
        options["coarse_tolerance"].as_f64(),
        Some(expected.coarse_tolerance),
        "{options}"
    );
    assert_eq!(options["coarse_tolerance"].as_f64(), Some(0.1), "{options}");
    assert_eq!(
        options["linear_solver"].as_str(),
        Some(format!("{:?}", expected.linear_solver).as_str()),
        "{options}"
    );
    // a labels file that is missing fails before any distance is computed (no new
    // distances.csv); one without a row for a shape leaves that shape unlabeled; --labels
    // without --mds is refused
    let labels = dir.join("labels.csv");
    std::fs::write(&labels, "file,person\na,p1\n").unwrap();
    std::fs::remove_dir_all(&out_dir).ok();
    let out = run(&["--mds", "--labels", dir.join("missing.csv").to_str().unwrap()]);
    assert_eq!(out.status.code(), Some(2), "{}", stderr(&out));
    assert!(stderr(&out).contains("missing.csv"), "{}", stderr(&out));
    assert!(!out_dir.join("distances.csv").exists());
    let out = run(&["--mds", "--labels", labels.to_str().unwrap()]);
    assert_eq!(out.status.code(), Some(0), "{}", stderr(&out));
    assert!(
        stderr(&out).contains("1 shape(s) without a labels row (unknown labels): b"),
        "{}",
        stderr(&out)
    );
    let out = run(&["--labels", labels.to_str().unwrap()]);
    assert_eq!(out.status.code(), Some(2), "{}", stderr(&out));
    assert!(stderr(&out).contains("--mds"), "{}", stderr(&out));
}

/// The not-a-disk error points to `shapespace prepare`, and that command turns a closed surface
/// (an icosahedron subdivided once: 42 V, 80 F) and a face with a spare component into disks the
/// conformal map accepts; its vertex map leads back to the input.
/// One hole is "1 hole", not "1 holes".
#[test]
fn prepare_counts_one_filled_hole_in_the_singular() {
    let dir = scratch("prepare_one_hole");
    let mut mesh = shapespace_geometry::primitives::unit_disk(4);
    let is_boundary = shapespace_geometry::Connectivity::of(&mesh).boundary_vertices(mesh.num_vertices());
    let inner = mesh
        .faces
        .iter()
        .position(|f| f.iter().all(|&v| !is_boundary[v as usize]))
        .unwrap();
    mesh.faces.remove(inner);
    let holed = dir.join("holed.obj");
    shapespace_geometry::io::write_mesh(&holed, &mesh).unwrap();
    let out = shapespace(&[
        "prepare",
        holed.to_str().unwrap(),
        "--out",
        dir.join("filled.obj").to_str().unwrap(),
    ]);
    assert_eq!(out.status.code(), Some(0), "{}", stderr(&out));
    assert!(
        stderr(&out).contains("filled 1 hole (one vertex appended)"),
        "{}",
        stderr(&out)
    );
}

#[test]
fn prepare_makes_disks_that_conformal_accepts() {
    let dir = scratch("prepare");
    // subdivided icosahedron, closed
    let mesh = shapespace_geometry::primitives::icosphere(1);
    let closed = dir.join("sphere.obj");
    shapespace_geometry::io::write_mesh(&closed, &mesh).unwrap();
    // the disk map refuses it with the hint (the default `--domain auto` maps it onto the sphere)
    let out = shapespace(&[
        "conformal",
        closed.to_str().unwrap(),
        "--domain",
        "disk",
        "--out",
        dir.join("x.obj").to_str().unwrap(),
    ]);
    assert_eq!(out.status.code(), Some(2));
    assert!(stderr(&out).contains("shapespace prepare"), "{}", stderr(&out));
    let disk = dir.join("sphere_disk.off");
    let map = dir.join("map.csv");
    let out = shapespace(&[
        "prepare",
        closed.to_str().unwrap(),
        "--out",
        disk.to_str().unwrap(),
        "--cut-rings",
        "1",
        "--vertex-map",
        map.to_str().unwrap(),
    ]);
    assert_eq!(out.status.code(), Some(0), "{}", stderr(&out));
    assert!(stderr(&out).contains("cut a 1-ring disk"), "{}", stderr(&out));
    let prepared = shapespace_geometry::io::read_mesh(&disk).unwrap();
    shapespace_geometry::topology::require_disk(&prepared).unwrap();
    assert_eq!(prepared.num_vertices(), mesh.num_vertices() - 1);
    let rows: Vec<String> = std::fs::read_to_string(&map)
        .unwrap()
        .lines()
        .skip(1)
        .map(String::from)
        .collect();
    assert_eq!(rows.len(), prepared.num_vertices());
    for row in &rows {
        let (v, o) = row.split_once(',').unwrap();
        let (v, o): (usize, usize) = (v.parse().unwrap(), o.parse().unwrap());
        assert_eq!(prepared.positions[v], mesh.positions[o]);
    }
    let out = shapespace(&[
        "conformal",
        disk.to_str().unwrap(),
        "--out",
        dir.join("c.obj").to_str().unwrap(),
    ]);
    assert_eq!(out.status.code(), Some(0), "{}", stderr(&out));
    // an out-of-range cut centre is a usage error naming it
    let out = shapespace(&[
        "prepare",
        closed.to_str().unwrap(),
        "--out",
        disk.to_str().unwrap(),
        "--cut-center",
        "4242",
    ]);
    assert_eq!(out.status.code(), Some(2));
    assert!(
        stderr(&out).contains("4242") && stderr(&out).contains("sphere.obj"),
        "{}",
        stderr(&out)
    );
}

/// `prepare --seam 1` on a capped tube: the slit runs from the cap centre (its farthest tip) to
/// the open end, the summary says so, the vertex map names the input vertex of every copy, and
/// `param` maps the result.
#[test]
fn prepare_slits_a_tube_from_its_tip() {
    let dir = scratch("seam");
    let tube = dir.join("tube.obj");
    let mesh = shapespace_geometry::primitives::capped_tube(1.0, 3.0, 4, 9);
    shapespace_geometry::io::write_mesh(&tube, &mesh).unwrap();
    let (disk, map) = (dir.join("tube_disk.obj"), dir.join("map.csv"));
    let out = shapespace(&[
        "prepare",
        tube.to_str().unwrap(),
        "--out",
        disk.to_str().unwrap(),
        "--seam",
        "1",
        "--vertex-map",
        map.to_str().unwrap(),
    ]);
    assert_eq!(out.status.code(), Some(0), "{}", stderr(&out));
    assert!(
        stderr(&out).contains("slit it along 13 edges from input vertices [0]"),
        "{}",
        stderr(&out)
    );
    let prepared = shapespace_geometry::io::read_mesh(&disk).unwrap();
    assert_eq!(prepared.num_vertices(), mesh.num_vertices() + 13);
    let rows = std::fs::read_to_string(&map).unwrap();
    let mut copies = vec![0; mesh.num_vertices()];
    for row in rows.lines().skip(1) {
        let (v, o) = row.split_once(',').unwrap();
        let (v, o): (usize, usize) = (v.parse().unwrap(), o.parse().unwrap());
        assert_eq!(prepared.positions[v], mesh.positions[o]);
        copies[o] += 1;
    }
    assert_eq!(
        copies.iter().filter(|&&c| c == 2).count(),
        13,
        "12 path vertices and the open end's"
    );
    let out = shapespace(&[
        "param",
        disk.to_str().unwrap(),
        "--out",
        dir.join("ap.obj").to_str().unwrap(),
    ]);
    assert_eq!(out.status.code(), Some(0), "{}", stderr(&out));
}

/// The bundled centaur0 slit from two tips: `conformal` falls back to BFF and says so;
/// `--no-bff-fallback` reports the Green's-function folds instead.
#[test]
fn conformal_reports_its_bff_fallback() {
    let dir = scratch("fallback");
    let disk = dir.join("centaur0_slit.obj");
    let out = shapespace(&[
        "prepare",
        "datasets/poses/centaur/centaur0.off",
        "--out",
        disk.to_str().unwrap(),
        "--seam",
        "2",
    ]);
    assert_eq!(out.status.code(), Some(0), "{}", stderr(&out));
    let map = dir.join("map.obj");
    let out = shapespace(&["conformal", disk.to_str().unwrap(), "--out", map.to_str().unwrap()]);
    assert_eq!(out.status.code(), Some(0), "{}", stderr(&out));
    assert!(
        stderr(&out).contains("fallback: the Green's-function map folded"),
        "{}",
        stderr(&out)
    );
    let out = shapespace(&[
        "conformal",
        disk.to_str().unwrap(),
        "--out",
        map.to_str().unwrap(),
        "--no-bff-fallback",
    ]);
    assert_ne!(out.status.code(), Some(0));
    assert!(stderr(&out).contains("flipped or degenerate"), "{}", stderr(&out));
}

/// A disk whose interior an edge between two boundary vertices cuts apart: `conformal` maps it
/// (splitting such edges intrinsically), and `prepare` splits them in the mesh (the vertex map
/// leaves the new vertices without an input vertex) and says so.
#[test]
fn prepare_splits_edges_that_cut_the_interior() {
    let dir = scratch("bridges");
    let strip = dir.join("strip.obj");
    let mesh = shapespace_geometry::primitives::pinched_strip();
    shapespace_geometry::io::write_mesh(&strip, &mesh).unwrap();
    let out = shapespace(&[
        "conformal",
        strip.to_str().unwrap(),
        "--center",
        "4",
        "--out",
        dir.join("x.obj").to_str().unwrap(),
    ]);
    // the map joins the cut-off vertex by intrinsic splits of its own: vertex 9 lies inside
    assert_eq!(out.status.code(), Some(0), "{}", stderr(&out));
    let (uv, nv) = read_vt(&dir.join("x.obj"));
    assert_eq!(nv, mesh.num_vertices());
    let r9 = uv[9][0].hypot(uv[9][1]);
    assert!(r9 > 0.05 && r9 < 0.999, "|z(9)| = {r9}");
    let disk = dir.join("strip_disk.obj");
    let map = dir.join("map.csv");
    let out = shapespace(&[
        "prepare",
        strip.to_str().unwrap(),
        "--out",
        disk.to_str().unwrap(),
        "--vertex-map",
        map.to_str().unwrap(),
    ]);
    assert_eq!(out.status.code(), Some(0), "{}", stderr(&out));
    assert!(
        stderr(&out).contains("split 3 edges joining two boundary vertices"),
        "{}",
        stderr(&out)
    );
    let prepared = shapespace_geometry::io::read_mesh(&disk).unwrap();
    assert_eq!(prepared.num_vertices(), 17);
    assert_eq!(shapespace_geometry::prepare::interior_components(&prepared).1, 1);
    let rows: Vec<String> = std::fs::read_to_string(&map)
        .unwrap()
        .lines()
        .skip(1)
        .map(String::from)
        .collect();
    assert_eq!(rows.len(), 17);
    assert!(rows[14..].iter().all(|r| r.ends_with(',')), "{rows:?}");
}

/// A marker file whose named landmarks lie outside the mesh is an error for `conformal`,
/// `param` and `distances` too (they do not use the landmarks, but the file does not belong to
/// the mesh); in range, the same file is accepted.
#[test]
fn marker_file_landmarks_out_of_range_are_named() {
    let dir = scratch("landmarks_range");
    let mesh = dir.join("grid.obj");
    std::fs::write(&mesh, grid_obj(1.0)).unwrap();
    let mesh2 = dir.join("grid2.obj");
    std::fs::write(&mesh2, grid_obj(2.0)).unwrap();
    let bad = dir.join("bad.json");
    std::fs::write(
        &bad,
        r#"{"center": 12, "boundary": 0, "landmarks": {"nose": 12, "chin": 99999}}"#,
    )
    .unwrap();
    let good = dir.join("good.json");
    std::fs::write(
        &good,
        r#"{"center": 12, "boundary": 0, "landmarks": {"nose": 12, "chin": 24}}"#,
    )
    .unwrap();
    for (cmd, out_name) in [("conformal", "c.obj"), ("param", "p.obj"), ("distances", "d")] {
        let run = |file: &Path| {
            let mut args = vec![cmd, mesh.to_str().unwrap()];
            if cmd == "distances" {
                args.push(mesh2.to_str().unwrap());
            }
            let out = dir.join(out_name);
            args.extend(["--landmarks", file.to_str().unwrap(), "--out", out.to_str().unwrap()]);
            shapespace(&args)
        };
        let out = run(&bad);
        let err = stderr(&out);
        if cmd == "distances" {
            // a failed shape is reported and the run goes on; both inputs fail here
            assert!(err.contains("\"chin\" is vertex 99999"), "{cmd}: {err}");
        } else {
            assert_eq!(out.status.code(), Some(2), "{cmd}: {err}");
            assert!(
                err.contains("bad.json") && err.contains("\"chin\" is vertex 99999") && err.contains("25 vertices"),
                "{cmd}: {err}"
            );
        }
        let out = run(&good);
        assert_eq!(out.status.code(), Some(0), "{cmd}: {}", stderr(&out));
    }
}

/// A center point beyond the coordinate range says so (it said "no face to project the center
/// onto"), and an unknown `--domain` lists the valid values (it said "reading circle: No such
/// file").
#[test]
fn marker_point_and_domain_messages() {
    let Some(cat_head) = shapespace_test_support::shared_file(CAT_HEAD) else {
        return;
    };
    let dir = scratch("messages");
    let out = shapespace(&[
        "conformal",
        cat_head.to_str().unwrap(),
        "--out",
        dir.join("x.obj").to_str().unwrap(),
        "--center",
        "1e300,0,0",
    ]);
    assert_eq!(out.status.code(), Some(2));
    assert!(
        stderr(&out).contains("beyond the usable coordinate range"),
        "{}",
        stderr(&out)
    );
    let points = dir.join("p.csv");
    std::fs::write(&points, "x,y,mass\n0.1,0,1\n0,0.2,1\n").unwrap();
    let out = shapespace(&[
        "ot",
        "--points",
        points.to_str().unwrap(),
        "--domain",
        "circle",
        "--out",
        dir.join("o.csv").to_str().unwrap(),
    ]);
    assert_eq!(out.status.code(), Some(2));
    assert!(stderr(&out).contains("expected `disk`, `square`"), "{}", stderr(&out));
}

/// A marker problem in `register` says what is wrong and for which surface (the disk map's
/// reason used to be cut off after "source: conformal disk map").
#[test]
fn register_names_the_marker_problem() {
    let dir = scratch("register-markers");
    let (a, b) = (dir.join("a.obj"), dir.join("b.obj"));
    std::fs::write(&a, grid_obj(1.0)).unwrap();
    std::fs::write(&b, grid_obj(1.5)).unwrap();
    let markers = dir.join("m.json");
    // vertex 12 is the centre of the 5 × 5 grid: not on the boundary
    std::fs::write(&markers, r#"{"center": 12, "boundary": 12}"#).unwrap();
    let pairs = dir.join("pairs.csv");
    std::fs::write(&pairs, "source,target\n6,6\n").unwrap();
    for (flag, side) in [("--source-markers", "source"), ("--target-markers", "target")] {
        for method in ["omt", "conformal"] {
            let out = register(
                &a,
                &b,
                &[
                    flag,
                    markers.to_str().unwrap(),
                    "--landmarks",
                    pairs.to_str().unwrap(),
                    "--method",
                    method,
                ],
                &dir.join("out"),
            );
            let msg = stderr(&out);
            assert_eq!(out.status.code(), Some(2), "{msg}");
            assert!(
                msg.contains(side) && msg.contains("boundary marker 12 is not a boundary vertex"),
                "{flag} {method}: {msg}"
            );
        }
    }
}

/// `conformal` and `param` write the map in the format the output's extension names: `.ply`
/// carries the same texture coordinates as `.obj`; `.off` (no texture coordinates) and unknown
/// extensions are refused before any work, with exit status 2, naming the file, writing nothing.
#[test]
fn map_outputs_follow_the_extension() {
    let Some(cat_head) = shapespace_test_support::shared_file(CAT_HEAD) else {
        return;
    };
    let dir = scratch("map-formats");
    let input = cat_head.to_str().unwrap();
    for cmd in ["conformal", "param"] {
        let obj = dir.join(format!("{cmd}.obj"));
        let ply = dir.join(format!("{cmd}.ply"));
        for path in [&obj, &ply] {
            let out = shapespace(&[cmd, input, "--out", path.to_str().unwrap()]);
            assert!(out.status.success(), "{cmd} {}: {}", path.display(), stderr(&out));
        }
        let from_obj = shapespace_geometry::io::read_mesh(&obj).unwrap();
        let from_ply = shapespace_geometry::io::read_mesh(&ply).unwrap();
        let (a, b) = (from_obj.uvs.unwrap(), from_ply.uvs.expect("the PLY has u, v"));
        assert_eq!(a.len(), b.len());
        // (OBJ writes shortest round-trip decimals, PLY binary doubles: the same bits)
        assert_eq!(a, b, "{cmd}: the .obj and .ply maps differ");
        for (name, expected) in [("map.off", "cannot store"), ("map.stl", "unknown extension")] {
            let path = dir.join(format!("{cmd}-{name}"));
            let out = shapespace(&[cmd, input, "--out", path.to_str().unwrap()]);
            let err = stderr(&out);
            assert_eq!(out.status.code(), Some(2), "{cmd} {name}: {err}");
            assert!(err.contains(expected) && err.contains(name), "{cmd} {name}: {err}");
            assert!(!path.exists(), "{cmd} {name}: a file was written");
        }
    }
}

/// `demo` checks its folder's labels against the faces before computing anything.
#[test]
fn demo_refuses_labels_that_do_not_match_before_any_distance() {
    let dir = scratch("demo-labels");
    for name in ["id00_happy.obj", "id00_sad.obj", "landmarks.json"] {
        std::fs::copy(root().join("datasets/faces").join(name), dir.join(name)).unwrap();
    }
    std::fs::write(
        dir.join("labels.csv"),
        "file,person\nid00_happy,p0\nid00_happy.obj,p1\n",
    )
    .unwrap();
    let out_dir = dir.join("out");
    let out = shapespace(&[
        "demo",
        "--data",
        dir.to_str().unwrap(),
        "--out",
        out_dir.to_str().unwrap(),
    ]);
    assert_eq!(out.status.code(), Some(2), "{}", stderr(&out));
    assert!(
        stderr(&out).contains("already matched line 2") && stderr(&out).contains("id00_happy"),
        "{}",
        stderr(&out)
    );
    assert!(!out_dir.join("distances.csv").exists());
}

/// `distances --resume` takes the pairs of the earlier run in the folder and computes the rest;
/// it says so, and refuses `--warm-start` (a warm-started pair depends on the pairs before it).
#[test]
fn distances_resume_computes_only_the_new_pairs() {
    let dir = scratch("resume");
    let out = dir.join("d");
    let faces: Vec<String> = ["id00_neutral", "id01_happy", "id02_sad"]
        .iter()
        .map(|n| format!("datasets/faces/{n}.obj"))
        .collect();
    let first = shapespace(&[
        "distances",
        &faces[0],
        &faces[1],
        "--out",
        out.to_str().unwrap(),
        "--quiet",
    ]);
    assert_eq!(first.status.code(), Some(0), "{}", stderr(&first));
    let mut args = vec![
        "distances",
        &faces[0],
        &faces[1],
        &faces[2],
        "--out",
        out.to_str().unwrap(),
    ];
    args.extend(["--quiet", "--resume"]);
    let resumed = shapespace(&args);
    let msg = stderr(&resumed);
    assert_eq!(resumed.status.code(), Some(0), "{msg}");
    assert!(
        msg.contains("distances: 1 of the directed pairs taken from earlier runs"),
        "{msg}"
    );
    assert!(msg.contains("pairs.csv: 1 pairs taken from 1 rows"), "{msg}");
    let pairs = std::fs::read_to_string(out.join("pairs.csv")).unwrap();
    assert_eq!(pairs.lines().count(), 4, "{pairs}");
    let report = std::fs::read_to_string(out.join("report.json")).unwrap();
    assert!(
        report.contains("\"resumed\"") && report.contains("\"sha256\""),
        "{report}"
    );
    args.push("--warm-start");
    let refused = shapespace(&args);
    assert_eq!(refused.status.code(), Some(2), "{}", stderr(&refused));
    assert!(stderr(&refused).contains("--warm-start"), "{}", stderr(&refused));
    // A pair time limit: reached at once, every pair fails with that reason (exit 1); it must
    // be a positive number of seconds.
    let limited_out = dir.join("limited");
    let mut args = vec![
        "distances",
        &faces[0],
        &faces[1],
        "--out",
        limited_out.to_str().unwrap(),
    ];
    args.extend(["--quiet", "--pair-time-limit", "1e-9"]);
    let limited = shapespace(&args);
    let msg = stderr(&limited);
    assert_eq!(limited.status.code(), Some(1), "{msg}");
    assert!(msg.contains("id00_neutral -> id01_happy: failed: time limit"), "{msg}");
    for bad in ["0", "nan", "inf"] {
        let last = args.len() - 1;
        args[last] = bad;
        let refused = shapespace(&args);
        assert_eq!(refused.status.code(), Some(2), "{bad}: {}", stderr(&refused));
        assert!(
            stderr(&refused).contains("--pair-time-limit must be a positive"),
            "{}",
            stderr(&refused)
        );
    }
    std::fs::remove_dir_all(&dir).ok();
}

/// Output paths are checked before any work: a report in a missing folder, a plots folder that
/// is a file, an output that is a folder each exit 2 naming the path, with nothing written
/// (the map used to be written first and the run to fail at the report or plots).
#[test]
fn output_paths_are_checked_before_the_work() {
    let Some(cat_head) = shapespace_test_support::shared_file(CAT_HEAD) else {
        return;
    };
    let dir = scratch("output_paths");
    let file = dir.join("plain_file");
    std::fs::write(&file, "").unwrap();
    let out = dir.join("o.obj");
    let (o, missing, f) = (out.to_str().unwrap(), dir.join("nodir/r.json"), file.to_str().unwrap());
    let face = cat_head.to_str().unwrap();
    for (args, named) in [
        (
            vec!["param", face, "--out", o, "--report", missing.to_str().unwrap()],
            "nodir",
        ),
        (vec!["param", face, "--out", o, "--plots", f], "plain_file"),
        (
            vec!["conformal", face, "--out", o, "--factors", missing.to_str().unwrap()],
            "nodir",
        ),
        (vec!["prepare", face, "--out", dir.to_str().unwrap()], "is a folder"),
    ] {
        let run = shapespace(&args);
        assert_eq!(run.status.code(), Some(2), "{args:?}: {}", stderr(&run));
        assert!(stderr(&run).contains(named), "{args:?}: {}", stderr(&run));
        assert!(!out.exists(), "{args:?} wrote its map");
    }
    // a plots folder that does not exist yet is created
    let plots = dir.join("new/plots");
    let run = shapespace(&["param", face, "--out", o, "--plots", plots.to_str().unwrap()]);
    assert_eq!(run.status.code(), Some(0), "{}", stderr(&run));
    assert!(plots.join("area_distortion.png").exists());
}

/// `register` on two grids with the same vertex count: the geodesic error against v ↔ v is
/// reported unless `--no-ground-truth` says the vertex orders differ; marker files without
/// landmarks register with a note that no landmark holds the map.
#[test]
fn register_ground_truth_is_optional_and_missing_landmarks_are_said() {
    let dir = scratch("register-ground-truth");
    let (a, b) = (dir.join("a.obj"), dir.join("b.obj"));
    std::fs::write(&a, grid_obj(1.0)).unwrap();
    std::fs::write(&b, grid_obj(1.5)).unwrap();
    // vertex 0 is a corner of the 5 × 5 grid
    let markers = dir.join("m.json");
    std::fs::write(&markers, r#"{"center": 12, "boundary": 0}"#).unwrap();
    for (flag, geodesic) in [(None, true), (Some("--no-ground-truth"), false)] {
        let out_dir = dir.join(format!("out{geodesic}"));
        let mut options = vec![
            "--source-markers",
            markers.to_str().unwrap(),
            "--target-markers",
            markers.to_str().unwrap(),
            "--method",
            "conformal",
        ];
        options.extend(flag);
        let out = register(&a, &b, &options, &out_dir);
        let msg = stderr(&out);
        assert_eq!(out.status.code(), Some(0), "{msg}");
        assert!(msg.contains("no landmark pairs"), "{msg}");
        let metrics: serde_json::Value =
            serde_json::from_slice(&std::fs::read(out_dir.join("metrics.json")).unwrap()).unwrap();
        assert_eq!(metrics["metrics"]["geodesic"].is_object(), geodesic, "{flag:?}");
        assert_eq!(msg.contains("geodesic error"), geodesic, "{msg}");
    }
}

/// Runs the binary with its file-size limit (RLIMIT_FSIZE) at `bytes` and SIGXFSZ ignored, so
/// that a write past the limit fails with EFBIG as on a full disk.
#[cfg(target_os = "linux")]
fn shapespace_with_file_size_limit(bytes: u64, args: &[&str]) -> Output {
    let mut sh_args = vec![
        "-c".to_string(),
        format!("trap '' XFSZ; exec prlimit --fsize={bytes} \"$0\" \"$@\""),
        env!("CARGO_BIN_EXE_shapespace").to_string(),
    ];
    sh_args.extend(args.iter().map(|a| a.to_string()));
    Command::new("sh")
        .args(&sh_args)
        .current_dir(root())
        .output()
        .expect("sh runs")
}

/// The names in a folder, sorted.
fn folder_entries(dir: &Path) -> Vec<String> {
    let mut names: Vec<String> = std::fs::read_dir(dir)
        .unwrap()
        .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
        .collect();
    names.sort();
    names
}

/// an output that cannot be written whole (here a file-size limit, as a full
/// disk) fails naming the file and leaves the previous complete file as it was, with no
/// temporary file behind; a resume checkpoint that cannot be written stops the run at once with
/// an error naming it (the pairs used to go on with the checkpoint empty, and the final files
/// were then cut).
#[cfg(target_os = "linux")]
#[test]
fn outputs_are_written_atomically() {
    let Some(cat_head) = shapespace_test_support::shared_file(CAT_HEAD) else {
        return;
    };
    let dir = scratch("atomic");
    let (obj, csv) = (dir.join("map.obj"), dir.join("factors.csv"));
    let args = [
        "conformal",
        cat_head.to_str().unwrap(),
        "--out",
        obj.to_str().unwrap(),
        "--factors",
        csv.to_str().unwrap(),
    ];
    let first = shapespace(&args);
    assert_eq!(first.status.code(), Some(0), "{}", stderr(&first));
    let (obj_before, csv_before) = (std::fs::read(&obj).unwrap(), std::fs::read(&csv).unwrap());
    assert!(obj_before.len() > 4096 && csv_before.len() > 4096);
    let limited = shapespace_with_file_size_limit(4096, &args);
    let msg = stderr(&limited);
    assert_eq!(limited.status.code(), Some(2), "{msg}");
    assert!(msg.contains("map.obj") && msg.contains("too large"), "{msg}");
    assert!(std::fs::read(&obj).unwrap() == obj_before, "the previous map was cut");
    assert!(
        std::fs::read(&csv).unwrap() == csv_before,
        "the previous factors were cut"
    );
    assert_eq!(folder_entries(&dir), ["factors.csv", "map.obj"]);

    // The checkpoint: the run's identity file (about 610 bytes) and the checkpoint's header and
    // first rows (about 140 bytes each) fit under the limit, a later row does not.
    let out = dir.join("d");
    let faces: Vec<String> = ["id00_neutral", "id01_happy", "id02_sad"]
        .iter()
        .map(|n| format!("datasets/faces/{n}.obj"))
        .collect();
    let mut args = vec!["distances"];
    args.extend(faces.iter().map(String::as_str));
    args.extend([
        "--out",
        out.to_str().unwrap(),
        "--quiet",
        "--threads",
        "1",
        "--symmetrize",
    ]);
    let limited = shapespace_with_file_size_limit(660, &args);
    let msg = stderr(&limited);
    assert_eq!(limited.status.code(), Some(2), "{msg}");
    assert!(
        msg.contains("pairs.partial.csv: cannot write the resume checkpoint"),
        "{msg}"
    );
    assert!(msg.contains("the run stopped"), "{msg}");
    assert!(!out.join("distances.csv").exists());
    std::fs::remove_dir_all(&dir).ok();
}

/// an output that is one of the inputs (under the same or another name, or
/// through a hard link) is refused before any work with exit 2 naming it, and the input is left
/// as it was; an output that is a symbolic link, given by name or found in an output folder, is
/// refused and its target left alone.
#[cfg(unix)]
#[test]
fn outputs_never_overwrite_inputs() {
    let Some([cat_head, plate121]) =
        shapespace_test_support::shared_files(&[CAT_HEAD, PLATE]).and_then(|v| <[PathBuf; 2]>::try_from(v).ok())
    else {
        return;
    };
    let dir = scratch("overwrite");
    let cat = dir.join("cat.obj");
    std::fs::copy(&cat_head, &cat).unwrap();
    let plate = dir.join("pl.ply");
    std::fs::copy(&plate121, &plate).unwrap();
    let points = dir.join("p.csv");
    write_sunflower_points(&points, 50, 2);
    let linked = dir.join("hard_link_to_cat.obj");
    std::fs::hard_link(&cat, &linked).unwrap();
    let other_spelling = dir.join(".").join("cat.obj");
    let o = dir.join("o.obj");
    let (cat_s, o_s, pl_s, p_s) = (
        cat.to_str().unwrap(),
        o.to_str().unwrap(),
        plate.to_str().unwrap(),
        points.to_str().unwrap(),
    );
    let before: Vec<Vec<u8>> = [&cat, &plate, &points]
        .iter()
        .map(|p| std::fs::read(p).unwrap())
        .collect();
    for args in [
        vec!["conformal", cat_s, "--out", o_s, "--factors", cat_s],
        vec![
            "conformal",
            cat_s,
            "--out",
            o_s,
            "--report",
            other_spelling.to_str().unwrap(),
        ],
        vec!["conformal", cat_s, "--out", o_s, "--factors", linked.to_str().unwrap()],
        vec!["param", cat_s, "--out", o_s, "--report", cat_s],
        vec!["param", pl_s, "--out", pl_s],
        vec!["prepare", cat_s, "--out", cat_s],
        vec!["ot", "--points", p_s, "--out", p_s],
        vec!["ot", "--points", p_s, "--out", o_s, "--report", p_s],
    ] {
        let run = shapespace(&args);
        let msg = stderr(&run);
        assert_eq!(run.status.code(), Some(2), "{args:?}: {msg}");
        assert!(msg.contains("an output must not replace an input"), "{args:?}: {msg}");
        assert!(!o.exists(), "{args:?} wrote its map");
    }
    let after: Vec<Vec<u8>> = [&cat, &plate, &points]
        .iter()
        .map(|p| std::fs::read(p).unwrap())
        .collect();
    assert!(before == after, "an input was changed");

    // two outputs in one file
    let csv = dir.join("f.csv");
    let run = shapespace(&[
        "conformal",
        cat_s,
        "--out",
        o_s,
        "--factors",
        csv.to_str().unwrap(),
        "--report",
        csv.to_str().unwrap(),
    ]);
    assert_eq!(run.status.code(), Some(2), "{}", stderr(&run));
    assert!(stderr(&run).contains("named for two outputs"), "{}", stderr(&run));

    // symbolic links: an output file, and a file in an output folder
    let elsewhere = dir.join("elsewhere.txt");
    std::fs::write(&elsewhere, "precious").unwrap();
    let link = dir.join("link.csv");
    std::os::unix::fs::symlink(&elsewhere, &link).unwrap();
    let run = shapespace(&["conformal", cat_s, "--out", o_s, "--factors", link.to_str().unwrap()]);
    assert_eq!(run.status.code(), Some(2), "{}", stderr(&run));
    assert!(stderr(&run).contains("is a symbolic link"), "{}", stderr(&run));
    let out = dir.join("d");
    std::fs::create_dir_all(&out).unwrap();
    std::os::unix::fs::symlink(&elsewhere, out.join("distances.csv")).unwrap();
    let run = shapespace(&[
        "distances",
        "datasets/faces/id00_neutral.obj",
        "datasets/faces/id01_happy.obj",
        "--out",
        out.to_str().unwrap(),
        "--quiet",
    ]);
    assert_eq!(run.status.code(), Some(2), "{}", stderr(&run));
    assert!(
        stderr(&run).contains("distances.csv: is a symbolic link"),
        "{}",
        stderr(&run)
    );
    assert_eq!(std::fs::read_to_string(&elsewhere).unwrap(), "precious");
    // mds: its distances file inside its output folder under an output's name
    let mds_in = dir.join("m");
    std::fs::create_dir_all(&mds_in).unwrap();
    let stats = mds_in.join("stats.json");
    std::fs::write(&stats, "name,a,b\na,0,1\nb,1,0\n").unwrap();
    let run = shapespace(&["mds", stats.to_str().unwrap(), "--out", mds_in.to_str().unwrap()]);
    assert_eq!(run.status.code(), Some(2), "{}", stderr(&run));
    assert!(
        stderr(&run).contains("an output must not replace an input"),
        "{}",
        stderr(&run)
    );
    std::fs::remove_dir_all(&dir).ok();
}

/// `--resume` takes only intact rows. A row of pairs.csv whose distance was
/// changed to −1, inf, 1e400 or NaN, whose distance and cost were both changed consistently (a
/// plausible value, caught by the row's check) or whose status is unknown is computed again
/// with a note naming its line, and the run succeeds with the fresh run's values (these rows
/// used to be copied, failing the run or reporting an empty distance as converged).
#[test]
fn resume_recomputes_changed_rows() {
    let dir = scratch("resume_verifies");
    let out = dir.join("d");
    let faces: Vec<String> = ["id00_neutral", "id01_happy", "id02_sad"]
        .iter()
        .map(|n| format!("datasets/faces/{n}.obj"))
        .collect();
    let mut args = vec!["distances"];
    args.extend(faces.iter().map(String::as_str));
    // (coarsened measures: the row checks are under test, not the accuracy)
    args.extend(["--target-points", "600", "--source-faces", "1200"]);
    args.extend(["--out", out.to_str().unwrap(), "--quiet"]);
    let first = shapespace(&args);
    assert_eq!(first.status.code(), Some(0), "{}", stderr(&first));
    let pairs_path = out.join("pairs.csv");
    let report_path = out.join("report.json");
    let (pairs, report) = (
        std::fs::read_to_string(&pairs_path).unwrap(),
        std::fs::read_to_string(&report_path).unwrap(),
    );
    // a row's values without its seconds (a taken row keeps the earlier run's) and its check
    let values = |line: &str| {
        let fields: Vec<&str> = line.split(',').collect();
        [&fields[..6], &fields[7..10]].concat().join(",")
    };
    let original = pairs.lines().nth(1).unwrap().to_string();
    let fields: Vec<&str> = original.split(',').collect();
    assert_eq!(fields[7], "converged");
    let cost: f64 = fields[3].parse().unwrap();
    let plausible_cost = format!("{:?}", cost * 1.02);
    let plausible_distance = format!("{:?}", (cost * 1.02).sqrt());
    args.push("--resume");
    for (label, distance, cost, status) in [
        ("-1", "-1", fields[3], "converged"),
        ("inf", "inf", fields[3], "converged"),
        ("1e400", "1e400", fields[3], "converged"),
        ("NaN", "NaN", fields[3], "converged"),
        (
            "plausible",
            plausible_distance.as_str(),
            plausible_cost.as_str(),
            "converged",
        ),
        ("status", fields[2], fields[3], "converged-ish"),
    ] {
        let mut changed = fields.clone();
        changed[2] = distance;
        changed[3] = cost;
        changed[7] = status;
        let tampered = pairs.replacen(&original, &changed.join(","), 1);
        assert_ne!(tampered, pairs);
        std::fs::write(&pairs_path, &tampered).unwrap();
        std::fs::write(&report_path, &report).unwrap();
        let resumed = shapespace(&args);
        let msg = stderr(&resumed);
        assert_eq!(resumed.status.code(), Some(0), "{label}: {msg}");
        assert!(
            msg.contains("pairs.csv: 2 pairs taken from 3 rows, 1 invalid rows computed again: line 2"),
            "{label}: {msg}"
        );
        let now = std::fs::read_to_string(&pairs_path).unwrap();
        assert_eq!(
            now.lines().map(values).collect::<Vec<_>>(),
            pairs.lines().map(values).collect::<Vec<_>>(),
            "{label}"
        );
    }
    std::fs::remove_dir_all(&dir).ok();
}

/// geometry-central's cat head (`cat_head`) with every coordinate multiplied by 10^`exponent`,
/// written into `dir`.
fn scaled_cat(cat_head: &Path, dir: &Path, exponent: i32) -> PathBuf {
    let text = std::fs::read_to_string(cat_head).unwrap();
    let scale = format!("1e{exponent}").parse::<f64>().unwrap();
    let mut out = String::new();
    for line in text.lines() {
        match line.strip_prefix("v ") {
            Some(rest) => {
                let p: Vec<f64> = rest
                    .split_whitespace()
                    .map(|x| x.parse::<f64>().unwrap() * scale)
                    .collect();
                out.push_str(&format!("v {:?} {:?} {:?}\n", p[0], p[1], p[2]));
            }
            None => {
                out.push_str(line);
                out.push('\n');
            }
        }
    }
    let path = dir.join(format!("cat_{exponent}.obj"));
    std::fs::write(&path, out).unwrap();
    path
}

/// the accepted coordinate range is the one the maps work in. cat_head scaled
/// by 1e-45 and 1e45 maps; scaled by 1e-100, 1e100, 1e140 or 1e154 `info` and `conformal` both
/// refuse it with the same message (`conformal` used to fail with a singular Laplacian or
/// "degenerate faces", and `info` to print an infinite area for a "disk").
#[test]
fn coordinate_range_is_the_working_one() {
    let Some(cat_head) = shapespace_test_support::shared_file(CAT_HEAD) else {
        return;
    };
    let dir = scratch("coordinate_range");
    let o = dir.join("o.obj");
    for exponent in [-45, 45] {
        let cat = scaled_cat(&cat_head, &dir, exponent);
        let run = shapespace(&["conformal", cat.to_str().unwrap(), "--out", o.to_str().unwrap()]);
        assert_eq!(run.status.code(), Some(0), "1e{exponent}: {}", stderr(&run));
        let info = shapespace(&["info", cat.to_str().unwrap()]);
        let table = String::from_utf8_lossy(&info.stdout).into_owned();
        assert_eq!(info.status.code(), Some(0), "1e{exponent}: {}", stderr(&info));
        assert!(
            table.contains("disk") && !table.contains("inf"),
            "1e{exponent}: {table}"
        );
    }
    for exponent in [-100, 100, 140, 154] {
        let cat = scaled_cat(&cat_head, &dir, exponent);
        let name = cat.file_name().unwrap().to_str().unwrap().to_string();
        let run = shapespace(&["conformal", cat.to_str().unwrap(), "--out", o.to_str().unwrap()]);
        let msg = stderr(&run);
        assert_eq!(run.status.code(), Some(2), "1e{exponent}: {msg}");
        assert!(
            msg.contains(&name)
                && msg.contains("coordinates out of the usable range")
                && msg.contains("rescale the mesh"),
            "1e{exponent}: {msg}"
        );
        for json in [false, true] {
            let mut args = vec!["info", cat.to_str().unwrap()];
            if json {
                args.push("--json");
            }
            let info = shapespace(&args);
            let (out, msg) = (String::from_utf8_lossy(&info.stdout).into_owned(), stderr(&info));
            assert_eq!(info.status.code(), Some(1), "1e{exponent}: {msg}");
            assert!(
                msg.contains(&name)
                    && msg.contains("coordinates out of the usable range")
                    && msg.contains("rescale the mesh"),
                "1e{exponent}: {msg}"
            );
            assert!(
                !out.contains("inf") && !out.contains("null") && !out.contains("disk"),
                "1e{exponent}: {out}"
            );
        }
    }
    std::fs::remove_dir_all(&dir).ok();
}

/// One definition of a degenerate face. A 7-vertex fan whose centre is the decimal midpoint of
/// two rim vertices (not exactly on their segment in binary, but with a zero area from its edge
/// lengths): `info` reports the degenerate face, `conformal` and `param` refuse the mesh for it
/// and point to `prepare`, which repairs it (the face on the rim is removed, no vertex moves)
/// into a mesh that `conformal` maps. (`info` said 0 degenerate faces and `prepare` "already a
/// disk, unchanged", then `conformal` failed on face 0.)
#[test]
fn degenerate_faces_are_one_definition() {
    let dir = scratch("degenerate");
    let fan = dir.join("fan.obj");
    let mut text = String::from("v 0.735 0.45 -0.17\nv 0.95 0.01 -0.08\nv 0.52 0.89 -0.26\nv -0.6 0.93 -0.14\n");
    text.push_str("v -1.02 0.05 0.22\nv -0.55 -0.81 -0.04\nv 0.53 -0.92 0.09\n");
    for k in 0..6 {
        text.push_str(&format!("f 1 {} {}\n", k + 2, (k + 1) % 6 + 2));
    }
    std::fs::write(&fan, text).unwrap();
    let info = shapespace(&["info", fan.to_str().unwrap(), "--json"]);
    assert_eq!(info.status.code(), Some(0), "{}", stderr(&info));
    let json: serde_json::Value = serde_json::from_slice(&info.stdout).unwrap();
    assert_eq!(json[0]["num_degenerate_faces"], 1, "{json}");
    assert_eq!(json[0]["first_degenerate_faces"][0], 0, "{json}");
    let info = shapespace(&["info", fan.to_str().unwrap()]);
    let table = String::from_utf8_lossy(&info.stdout).into_owned();
    assert!(table.contains("fan.obj: 1 degenerate face"), "{table}");
    let o = dir.join("o.obj");
    for cmd in ["conformal", "param"] {
        let run = shapespace(&[cmd, fan.to_str().unwrap(), "--out", o.to_str().unwrap()]);
        let msg = stderr(&run);
        assert_eq!(run.status.code(), Some(2), "{cmd}: {msg}");
        assert!(
            msg.contains("fan.obj")
                && msg.contains("1 degenerate face")
                && msg.contains("first face 0")
                && msg.contains("`shapespace prepare` repairs them"),
            "{cmd}: {msg}"
        );
        assert!(!o.exists(), "{cmd}");
    }
    let prepared = dir.join("prepared.obj");
    let run = shapespace(&["prepare", fan.to_str().unwrap(), "--out", prepared.to_str().unwrap()]);
    let msg = stderr(&run);
    assert_eq!(run.status.code(), Some(0), "{msg}");
    assert!(
        msg.contains("repaired 1 degenerate face without moving a vertex (1 removed from the boundary)"),
        "{msg}"
    );
    let info = shapespace(&["info", prepared.to_str().unwrap(), "--json"]);
    let json: serde_json::Value = serde_json::from_slice(&info.stdout).unwrap();
    assert_eq!(json[0]["num_degenerate_faces"], 0, "{json}");
    let run = shapespace(&["conformal", prepared.to_str().unwrap(), "--out", o.to_str().unwrap()]);
    assert_eq!(run.status.code(), Some(0), "{}", stderr(&run));
    assert!(o.exists());
    // distances maps each file directly: the same face and reason
    let run = shapespace(&[
        "distances",
        fan.to_str().unwrap(),
        "datasets/faces/id00_neutral.obj",
        "datasets/faces/id01_happy.obj",
        "--out",
        dir.join("d").to_str().unwrap(),
        "--quiet",
    ]);
    let msg = stderr(&run);
    assert_eq!(run.status.code(), Some(1), "{msg}");
    assert!(
        msg.contains("fan.obj: degenerate face 0: zero area to rounding (nearly collinear corners)"),
        "{msg}"
    );
    std::fs::remove_dir_all(&dir).ok();
}

/// `stats.json` stays linear in the number of label columns. With 40 label
/// columns over 8 shapes the cross-column accuracies (one per ordered pair of columns: 1,560)
/// are skipped with a note unless columns are chosen with `--cross-columns`.
#[test]
fn mds_stats_are_bounded_in_label_columns() {
    let dir = scratch("mds_columns");
    let n = 8;
    let names: Vec<String> = (0..n).map(|i| format!("s{i}")).collect();
    let mut matrix = format!("name,{}\n", names.join(","));
    for i in 0..n {
        let row: Vec<String> = (0..n)
            .map(|j| format!("{}", (i as f64 - j as f64).abs() + if i == j { 0.0 } else { 0.5 }))
            .collect();
        matrix.push_str(&format!("{},{}\n", names[i], row.join(",")));
    }
    let distances = dir.join("d.csv");
    std::fs::write(&distances, matrix).unwrap();
    let columns = 40;
    let mut labels = format!(
        "name,{}\n",
        (0..columns).map(|c| format!("c{c}")).collect::<Vec<_>>().join(",")
    );
    for (i, name) in names.iter().enumerate() {
        let row: Vec<String> = (0..columns).map(|c| format!("v{}", (i + c) % 3)).collect();
        labels.push_str(&format!("{name},{}\n", row.join(",")));
    }
    let labels_path = dir.join("labels.csv");
    std::fs::write(&labels_path, labels).unwrap();
    let out = dir.join("m");
    let args = vec![
        "mds",
        distances.to_str().unwrap(),
        "--labels",
        labels_path.to_str().unwrap(),
        "--out",
        out.to_str().unwrap(),
    ];
    let run = shapespace(&args);
    assert_eq!(run.status.code(), Some(0), "{}", stderr(&run));
    let stats: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(out.join("stats.json")).unwrap()).unwrap();
    assert_eq!(stats["labels"].as_object().unwrap().len(), columns);
    assert_eq!(stats["cross"].as_array().unwrap().len(), 0);
    assert!(
        stats["cross_skipped"].as_str().unwrap().contains("40 label columns"),
        "{}",
        stats["cross_skipped"]
    );
    assert!(stderr(&run).contains("--cross-columns"), "{}", stderr(&run));
    let mut chosen = args.clone();
    chosen.extend(["--cross-columns", "c0,c1,c2"]);
    let run = shapespace(&chosen);
    assert_eq!(run.status.code(), Some(0), "{}", stderr(&run));
    let stats: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(out.join("stats.json")).unwrap()).unwrap();
    assert_eq!(stats["cross"].as_array().unwrap().len(), 6);
    assert!(stats.get("cross_skipped").is_none());
    chosen.push("--cross-columns");
    chosen.push("nope");
    let run = shapespace(&chosen);
    assert_eq!(run.status.code(), Some(2), "{}", stderr(&run));
    assert!(stderr(&run).contains("nope"), "{}", stderr(&run));
    std::fs::remove_dir_all(&dir).ok();
}

/// a second run into an output folder while one is going on (here: the test
/// holds the folder's lock) is refused at once, naming the lock; the lock goes with its holder.
#[test]
fn one_run_at_a_time_per_output_folder() {
    let dir = scratch("lock");
    let out = dir.join("d");
    std::fs::create_dir_all(&out).unwrap();
    let lock = std::fs::OpenOptions::new()
        .write(true)
        .create(true)
        .truncate(false)
        .open(out.join(".shapespace.lock"))
        .unwrap();
    lock.try_lock().unwrap();
    let args = [
        "distances",
        "datasets/faces/id00_neutral.obj",
        "datasets/faces/id01_happy.obj",
        "--out",
        out.to_str().unwrap(),
        "--quiet",
    ];
    let second = shapespace(&args);
    let msg = stderr(&second);
    assert_eq!(second.status.code(), Some(2), "{msg}");
    assert!(
        msg.contains(".shapespace.lock") && msg.contains("another shapespace run is writing into this folder"),
        "{msg}"
    );
    assert!(!out.join("pairs.partial.csv").exists());
    drop(lock);
    let run = shapespace(&args);
    assert_eq!(run.status.code(), Some(0), "{}", stderr(&run));
    std::fs::remove_dir_all(&dir).ok();
}

/// One step of a xorshift64* generator (a fixed, dependency-free stream for the sweep below).
fn xorshift(state: &mut u64) -> u64 {
    *state ^= *state >> 12;
    *state ^= *state << 25;
    *state ^= *state >> 27;
    state.wrapping_mul(0x2545_f491_4f6c_dd1d)
}

/// `bytes` with one seeded mutation: a byte flipped, set to a digit, CR, TAB, NUL or a minus
/// sign; a line removed or repeated; a number replaced by an extreme one; or the file cut.
fn mutate(bytes: &[u8], state: &mut u64) -> Vec<u8> {
    let mut out = bytes.to_vec();
    let pick = |state: &mut u64, n: usize| (xorshift(state) % n.max(1) as u64) as usize;
    let line_starts: Vec<usize> = std::iter::once(0)
        .chain(
            bytes
                .iter()
                .enumerate()
                .filter(|(_, &b)| b == b'\n')
                .map(|(i, _)| i + 1),
        )
        .filter(|&i| i < bytes.len())
        .collect();
    match pick(state, 8) {
        0 => {
            let i = pick(state, out.len());
            out[i] ^= 1 << pick(state, 8);
        }
        1 => {
            let i = pick(state, out.len());
            out[i] = b"0123456789\r\t\0-"[pick(state, 14)];
        }
        2 | 3 => {
            let k = pick(state, line_starts.len());
            let start = line_starts[k];
            let end = line_starts.get(k + 1).copied().unwrap_or(out.len());
            let line = out[start..end].to_vec();
            if pick(state, 2) == 0 {
                out.drain(start..end);
            } else {
                out.splice(start..start, line);
            }
        }
        4 | 5 => {
            // a token that starts with a digit replaced by an extreme value
            let starts: Vec<usize> = (1..out.len())
                .filter(|&i| out[i].is_ascii_digit() && out[i - 1] == b' ')
                .collect();
            if let Some(&i) = starts.get(pick(state, starts.len())) {
                let end = (i..out.len())
                    .find(|&j| out[j] == b' ' || out[j] == b'\n')
                    .unwrap_or(out.len());
                let value = [
                    "1e308",
                    "-1e308",
                    "1e-320",
                    "nan",
                    "inf",
                    "4294967295",
                    "-1",
                    "0",
                    "1e400",
                    "99999999999999999999",
                ][pick(state, 10)];
                out.splice(i..end, value.bytes());
            }
        }
        6 => {
            let k = pick(state, out.len());
            out.truncate(k);
        }
        _ => {
            let i = pick(state, out.len());
            let j = pick(state, out.len());
            out.swap(i, j);
        }
    }
    out
}

/// A seeded mutation sweep over small meshes of every format (600 files, a few seconds):
/// `info` on each, `conformal` on every third, must exit 0, 1 or 2 (never a panic), name the
/// file when it fails, and print no NaN or infinity when it succeeds.
#[test]
fn mutated_meshes_fail_cleanly() {
    let dir = scratch("mutations");
    // three public meshes from the shared datasets (when present) and three of the repository's
    let mut seeds: Vec<PathBuf> = [CAT_HEAD, PLATE, "tosca/wolf0.off"]
        .iter()
        .filter_map(|rel| shapespace_test_support::shared_file(rel))
        .collect();
    seeds.extend(
        [
            "tests/bad_input/ok_extra_elements_big_endian.ply",
            "tests/bad_input/ok_mixed_tri_quad.obj",
            "tests/bad_input/ok_non_manifold_vertex.off",
        ]
        .iter()
        .map(|rel| root().join(rel)),
    );
    let mut state = 0x42_2026_u64;
    let o = dir.join("o.obj");
    let mut failed = 0;
    for (s, seed) in seeds.iter().enumerate() {
        let bytes = std::fs::read(seed).unwrap();
        let ext = seed.extension().unwrap().to_str().unwrap();
        for k in 0..100 {
            let mutated = mutate(&bytes, &mut state);
            let file = dir.join(format!("m{s}_{k}.{ext}"));
            std::fs::write(&file, &mutated).unwrap();
            let name = file.file_name().unwrap().to_str().unwrap().to_string();
            let mut runs = vec![vec!["info", file.to_str().unwrap()]];
            if k % 3 == 0 {
                runs.push(vec!["conformal", file.to_str().unwrap(), "--out", o.to_str().unwrap()]);
            }
            for args in runs {
                let out = shapespace(&args);
                let (stdout, msg) = (String::from_utf8_lossy(&out.stdout).into_owned(), stderr(&out));
                let code = out.status.code();
                assert!(
                    matches!(code, Some(0..=2)),
                    "{args:?} ({}, mutation {k}): {code:?}: {msg}",
                    seed.display()
                );
                if code == Some(0) {
                    assert!(
                        !stdout.contains("NaN") && !stdout.contains("inf"),
                        "{args:?} ({}, mutation {k}): {stdout}",
                        seed.display()
                    );
                } else {
                    failed += 1;
                    assert!(
                        msg.contains(&name),
                        "{args:?} ({}, mutation {k}): {msg}",
                        seed.display()
                    );
                }
            }
        }
    }
    // (the sweep is not vacuous: most mutations are caught)
    assert!(failed > 100, "{failed} failures");
    std::fs::remove_dir_all(&dir).ok();
}

/// `--debias`: distances.csv holds √max(0, c(a, b) − c(b, b)) with the raw costs of pairs.csv
/// and the self-costs of report.json; each self-cost is the shape's own floor (self-distance
/// about 0.019 on the bundled faces), and debiasing lowers every distance.
#[test]
fn distances_debias_subtracts_the_targets_self_cost() {
    let dir = scratch("debias");
    let names = ["id00_happy", "id00_neutral", "id01_happy"];
    let files: Vec<String> = names.iter().map(|n| format!("datasets/faces/{n}.obj")).collect();
    let out_dir = dir.join("run");
    let mut args: Vec<&str> = vec!["distances"];
    args.extend(files.iter().map(|s| s.as_str()));
    args.extend(["--out", out_dir.to_str().unwrap(), "--debias", "--quiet"]);
    let out = shapespace(&args);
    assert_eq!(out.status.code(), Some(0), "{}", stderr(&out));
    let report: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(out_dir.join("report.json")).unwrap()).unwrap();
    let own: Vec<f64> = report["debias"]["self_costs"]
        .as_array()
        .unwrap()
        .iter()
        .map(|c| c.as_f64().unwrap())
        .collect();
    assert_eq!(own.len(), 3);
    for c in &own {
        assert!(c.sqrt() > 0.01 && c.sqrt() < 0.03, "self-distance {}", c.sqrt());
    }
    assert_eq!(report["options"]["debias"], true);
    let matrix = shapespace_analysis::read_distance_matrix(&out_dir.join("distances.csv")).unwrap();
    let pairs = std::fs::read_to_string(out_dir.join("pairs.csv")).unwrap();
    let mut rows = pairs.lines();
    let header: Vec<&str> = rows.next().unwrap().split(',').collect();
    let col = |name: &str| header.iter().position(|h| *h == name).unwrap();
    let mut checked = 0;
    for row in rows {
        let f: Vec<&str> = row.split(',').collect();
        let (a, b) = (f[col("a")], f[col("b")]);
        let (i, j) = (
            names.iter().position(|n| *n == a).unwrap(),
            names.iter().position(|n| *n == b).unwrap(),
        );
        let (raw, cost): (f64, f64) = (f[col("distance")].parse().unwrap(), f[col("cost")].parse().unwrap());
        let expected = (cost - own[j]).max(0.0).sqrt();
        let got = matrix.values[i * 3 + j];
        assert!(
            (got - expected).abs() <= 1e-15 * expected.max(1.0),
            "{a} -> {b}: {got} vs {expected}"
        );
        assert!(got < raw, "{a} -> {b}: {got} vs raw {raw}");
        checked += 1;
    }
    assert_eq!(checked, 3);
}

/// `distances --mds` with a file that fails: the shapes with all their distances are embedded,
/// the failed one is listed in stats.json's `dropped_shapes` and on stderr, the exit code says
/// that something failed; a labels file without a row for one shape leaves it unlabeled.
#[test]
fn mds_runs_on_the_complete_part_of_an_incomplete_run() {
    let dir = scratch("mds_incomplete");
    let names = ["id00_happy", "id00_neutral", "id01_happy", "id01_neutral"];
    let mut files: Vec<String> = names.iter().map(|n| format!("datasets/faces/{n}.obj")).collect();
    let closed = dir.join("closed.obj");
    shapespace_geometry::io::write_mesh(&closed, &shapespace_geometry::primitives::icosphere(1)).unwrap();
    files.push(closed.to_str().unwrap().to_string());
    let labels = dir.join("labels.csv");
    std::fs::write(
        &labels,
        "file,identity\nid00_happy,p0\nid00_neutral,p0\nid01_happy,p1\n",
    )
    .unwrap();
    let out_dir = dir.join("run");
    let mut args: Vec<&str> = vec!["distances"];
    args.extend(files.iter().map(|s| s.as_str()));
    // (a closed file among disks refuses the run unless the domain is given: here it fails alone)
    args.extend([
        "--domain",
        "disk",
        "--out",
        out_dir.to_str().unwrap(),
        "--quiet",
        "--mds",
        "--labels",
    ]);
    args.push(labels.to_str().unwrap());
    let out = shapespace(&args);
    assert_eq!(out.status.code(), Some(1), "{}", stderr(&out));
    assert!(
        stderr(&out).contains("left out 1 shape(s) with missing distances: closed"),
        "{}",
        stderr(&out)
    );
    let stats: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(out_dir.join("stats.json")).unwrap()).unwrap();
    assert_eq!(stats["n"], 4);
    assert_eq!(stats["dropped_shapes"], serde_json::json!(["closed"]));
    assert_eq!(stats["unlabeled_shapes"], serde_json::json!(["id01_neutral"]));
    let mds_rows = std::fs::read_to_string(out_dir.join("mds.csv"))
        .unwrap()
        .lines()
        .count();
    assert_eq!(mds_rows, 1 + 4);
}

/// `register --boundary-marker auto` on two meshes with the same faces: one automatic choice for
/// both, and metrics.json records each mesh's markers and where they came from.
#[test]
fn register_records_its_markers_and_shares_automatic_ones() {
    let dir = scratch("register_markers");
    let out_dir = dir.join("reg");
    let out = register(
        Path::new("datasets/faces/id00_neutral.obj"),
        Path::new("datasets/faces/id01_happy.obj"),
        &["--method", "conformal", "--boundary-marker", "auto", "--samples", "20"],
        &out_dir,
    );
    assert_eq!(out.status.code(), Some(0), "{}", stderr(&out));
    let metrics: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(out_dir.join("metrics.json")).unwrap()).unwrap();
    let m = &metrics["run"]["markers"];
    assert_eq!(m["source"]["center"], 4841, "{m}");
    assert_eq!(m["source"]["boundary"], m["target"]["boundary"], "{m}");
    assert_ne!(m["source"]["boundary"], 8889, "{m}");
    let origin = m["source"]["source"].as_str().unwrap();
    assert!(
        origin.contains("landmarks.json, --boundary-marker, shared by the 2 files"),
        "{origin}"
    );
}

/// A file that fails in `distances` (unreadable, not a disk) is named once per line.
#[test]
fn distances_name_a_failed_file_once() {
    let dir = scratch("failed_once");
    let closed = dir.join("closed.obj");
    shapespace_geometry::io::write_mesh(&closed, &shapespace_geometry::primitives::icosphere(1)).unwrap();
    let bad = dir.join("bad.obj");
    std::fs::write(&bad, "v 0 0 0\nf 1 2 3\n").unwrap();
    let out = shapespace(&[
        "distances",
        closed.to_str().unwrap(),
        bad.to_str().unwrap(),
        "datasets/faces/id00_happy.obj",
        // (a closed file among disks refuses the run unless the domain is given: here it fails alone)
        "--domain",
        "disk",
        "--out",
        dir.join("run").to_str().unwrap(),
        "--quiet",
    ]);
    assert_eq!(out.status.code(), Some(1), "{}", stderr(&out));
    let err = stderr(&out);
    for file in [&closed, &bad] {
        let name = file.to_str().unwrap();
        let line = err
            .lines()
            .find(|l| l.contains(name))
            .unwrap_or_else(|| panic!("{err}"));
        assert_eq!(line.matches(name).count(), 1, "{line}");
    }
}

/// an error line names the file once (`distances` printed
/// `bad.obj: bad: bad.obj:4: ...` and `fan.obj: fan.obj: ...`, `conformal` and `param`
/// `reading bad.obj: bad.obj:4: ...`).
#[test]
fn error_lines_name_the_file_once() {
    let dir = scratch("path_once");
    let bad = dir.join("bad.obj");
    std::fs::write(&bad, "v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 x\n").unwrap();
    let o = dir.join("o.obj");
    for cmd in ["conformal", "param", "info"] {
        let mut args = vec![cmd, bad.to_str().unwrap()];
        if cmd != "info" {
            args.extend(["--out", o.to_str().unwrap()]);
        }
        let run = shapespace(&args);
        let msg = stderr(&run);
        assert_eq!(msg.matches("bad.obj").count(), 1, "{cmd}: {msg}");
        assert!(msg.contains("bad.obj:4: non-integer vertex index"), "{cmd}: {msg}");
    }
    let run = shapespace(&[
        "distances",
        bad.to_str().unwrap(),
        "datasets/faces/id00_neutral.obj",
        "datasets/faces/id01_happy.obj",
        "--out",
        dir.join("d").to_str().unwrap(),
        "--quiet",
    ]);
    let msg = stderr(&run);
    assert_eq!(run.status.code(), Some(1), "{msg}");
    let line = msg.lines().find(|l| l.contains("non-integer")).unwrap_or_default();
    assert_eq!(line.matches("bad.obj").count(), 1, "{msg}");
    assert!(
        line.starts_with("shapespace: ") && line.contains("bad.obj:4: non-integer vertex index"),
        "{msg}"
    );
    std::fs::remove_dir_all(&dir).ok();
}

/// `ot` that stops before its tolerance names the points file in its status line and exits 1.
#[test]
fn ot_names_the_points_file_when_it_stops_unconverged() {
    let dir = scratch("ot_unconverged");
    let points = dir.join("pts.csv");
    write_sunflower_points(&points, 400, 3);
    let out = shapespace(&[
        "ot",
        "--points",
        points.to_str().unwrap(),
        "--out",
        dir.join("r.csv").to_str().unwrap(),
        "--max-iterations",
        "1",
        "--tol",
        "1e-12",
    ]);
    assert_eq!(out.status.code(), Some(1), "{}", stderr(&out));
    let err = stderr(&out);
    let status = err
        .lines()
        .find(|l| l.contains("after 1 steps"))
        .unwrap_or_else(|| panic!("{err}"));
    assert!(status.contains(points.to_str().unwrap()), "{status}");
}

/// `conformal` on a closed genus-0 mesh maps onto the unit sphere (chosen automatically): the
/// output keeps the faces and puts every vertex on S², the factors CSV has one row per vertex,
/// three markers land on the poles and (1, 0, 0); a torus is refused naming the file and its
/// genus; disk markers are refused for the sphere.
#[test]
fn conformal_maps_a_closed_mesh_onto_the_sphere() {
    let dir = scratch("sphere");
    let mut mesh = shapespace_geometry::primitives::icosphere(3);
    for p in &mut mesh.positions {
        *p = [p[0], 0.8 * p[1], 1.5 * p[2]];
    }
    let input = dir.join("egg.obj");
    shapespace_geometry::io::write_mesh(&input, &mesh).unwrap();
    let out_obj = dir.join("egg_sphere.obj");
    let factors = dir.join("factors.csv");
    let report = dir.join("report.json");
    let out = shapespace(&[
        "conformal",
        input.to_str().unwrap(),
        "--out",
        out_obj.to_str().unwrap(),
        "--factors",
        factors.to_str().unwrap(),
        "--report",
        report.to_str().unwrap(),
        "--sphere-markers",
        "0,7,3",
    ]);
    assert_eq!(out.status.code(), Some(0), "{}", stderr(&out));
    assert!(stderr(&out).contains("sphere"), "{}", stderr(&out));
    let mapped = shapespace_geometry::io::read_mesh(&out_obj).unwrap();
    assert_eq!(mapped.faces, mesh.faces);
    for p in &mapped.positions {
        let r = (p[0] * p[0] + p[1] * p[1] + p[2] * p[2]).sqrt();
        assert!((r - 1.0).abs() < 1e-12, "{r}");
    }
    assert_eq!(mapped.positions[0], [0.0, 0.0, -1.0]);
    assert_eq!(mapped.positions[7], [1.0, 0.0, 0.0]);
    assert_eq!(mapped.positions[3], [0.0, 0.0, 1.0]);
    let csv = std::fs::read_to_string(&factors).unwrap();
    assert!(csv.starts_with("vertex,x,y,z,lambda\n"), "{csv}");
    assert_eq!(csv.lines().count(), mesh.num_vertices() + 1);
    let text = std::fs::read_to_string(&report).unwrap();
    assert!(text.contains("\"domain\": \"sphere\""), "{text}");
    assert!(text.contains("\"num_flipped\": 0"), "{text}");

    // a torus
    let (nu, nv) = (12usize, 8usize);
    let mut text = String::new();
    for i in 0..nu {
        for j in 0..nv {
            let (u, v) = (
                2.0 * std::f64::consts::PI * i as f64 / nu as f64,
                2.0 * std::f64::consts::PI * j as f64 / nv as f64,
            );
            text.push_str(&format!(
                "v {} {} {}\n",
                (2.0 + v.cos()) * u.cos(),
                (2.0 + v.cos()) * u.sin(),
                v.sin()
            ));
        }
    }
    let id = |i: usize, j: usize| (i % nu) * nv + (j % nv) + 1;
    for i in 0..nu {
        for j in 0..nv {
            text.push_str(&format!("f {} {} {}\n", id(i, j), id(i + 1, j), id(i + 1, j + 1)));
            text.push_str(&format!("f {} {} {}\n", id(i, j), id(i + 1, j + 1), id(i, j + 1)));
        }
    }
    let torus = dir.join("torus.obj");
    std::fs::write(&torus, text).unwrap();
    for extra in [&[][..], &["--domain", "sphere"][..]] {
        let mut args = vec!["conformal", torus.to_str().unwrap(), "--out", out_obj.to_str().unwrap()];
        args.extend_from_slice(extra);
        let out = shapespace(&args);
        let msg = stderr(&out);
        assert_eq!(out.status.code(), Some(2), "{msg}");
        assert!(msg.contains("torus.obj") && msg.contains("genus 1"), "{msg}");
    }
    // disk markers on a sphere, and sphere markers on a disk
    let out = shapespace(&[
        "conformal",
        input.to_str().unwrap(),
        "--out",
        out_obj.to_str().unwrap(),
        "--center",
        "0",
    ]);
    assert_eq!(out.status.code(), Some(2), "{}", stderr(&out));
    assert!(
        stderr(&out).contains("egg.obj") && stderr(&out).contains("--sphere-markers"),
        "{}",
        stderr(&out)
    );
    let out = shapespace(&[
        "conformal",
        "datasets/faces/id00_neutral.obj",
        "--out",
        out_obj.to_str().unwrap(),
        "--sphere-markers",
        "0,1,2",
    ]);
    assert_eq!(out.status.code(), Some(2), "{}", stderr(&out));
    assert!(stderr(&out).contains("sphere map only"), "{}", stderr(&out));
}

/// `param --domain sphere`: an egg (ellipsoid 1 : 0.8 : 1.5) maps onto S² with the input's
/// faces, no folded face, and a 95th percentile |ε| (log one-ring area ratio) at most a fifth
/// of the conformal map's; importance weights 4 on the upper half (z > 0) give that half its
/// weighted share of the sphere's area; the histograms are written; a disk is refused naming
/// the file.
#[test]
fn param_maps_a_closed_mesh_onto_the_sphere_preserving_area() {
    let dir = scratch("param_sphere");
    let mut mesh = shapespace_geometry::primitives::icosphere(3);
    for p in &mut mesh.positions {
        *p = [p[0], 0.8 * p[1], 1.5 * p[2]];
    }
    let input = dir.join("egg.obj");
    shapespace_geometry::io::write_mesh(&input, &mesh).unwrap();
    let out_obj = dir.join("egg_ap.obj");
    let report = dir.join("report.json");
    let plots = dir.join("plots");
    let run = |extra: &[&str]| {
        let mut args = vec![
            "param",
            input.to_str().unwrap(),
            "--domain",
            "sphere",
            "--out",
            out_obj.to_str().unwrap(),
            "--report",
            report.to_str().unwrap(),
        ];
        args.extend_from_slice(extra);
        let out = shapespace(&args);
        assert_eq!(out.status.code(), Some(0), "{}", stderr(&out));
        let json: serde_json::Value = serde_json::from_str(&std::fs::read_to_string(&report).unwrap()).unwrap();
        (shapespace_geometry::io::read_mesh(&out_obj).unwrap(), json)
    };
    let (mapped, json) = run(&["--plots", plots.to_str().unwrap()]);
    assert_eq!(mapped.faces, mesh.faces);
    for p in &mapped.positions {
        assert!(((p[0] * p[0] + p[1] * p[1] + p[2] * p[2]).sqrt() - 1.0).abs() < 1e-12);
    }
    assert_eq!(json["num_flipped"], 0);
    let p95 = |k: usize| {
        json["distortion"]["maps"][k]["abs_vertex_log_area_ratio"]["p95"]
            .as_f64()
            .unwrap()
    };
    assert!(
        p95(1) < 0.2 * p95(0),
        "p95 |ε|: area-preserving {} against conformal {}",
        p95(1),
        p95(0)
    );
    for stem in ["area_distortion", "angle_distortion", "quasi_conformal_distortion"] {
        assert!(plots.join(format!("{stem}.png")).is_file() && plots.join(format!("{stem}.svg")).is_file());
    }

    // weights 4 on the upper half (z > 0): its share of the image's area against the weighted
    // share of the surface's (one-ring thirds on both sides); the vertices' image areas differ
    // from their cells' where the weight jumps, a first-order error that halves with the mesh
    // size (measured: 0.023 at 642 vertices, 0.011 at 2,562)
    let mut errors = Vec::new();
    for subdivisions in [3, 4] {
        let mut mesh = shapespace_geometry::primitives::icosphere(subdivisions);
        for p in &mut mesh.positions {
            *p = [p[0], 0.8 * p[1], 1.5 * p[2]];
        }
        std::fs::remove_file(&input).unwrap();
        shapespace_geometry::io::write_mesh(&input, &mesh).unwrap();
        let weights = dir.join("weights.csv");
        let upper: Vec<bool> = mesh.positions.iter().map(|p| p[2] > 1e-9).collect();
        let mut text = String::from("vertex,weight\n");
        for (v, _) in upper.iter().enumerate().filter(|(_, &u)| u) {
            text.push_str(&format!("{v},4\n"));
        }
        std::fs::write(&weights, text).unwrap();
        let (mapped, json) = run(&["--weights", weights.to_str().unwrap()]);
        assert_eq!(json["num_flipped"], 0);
        let share = |areas: Vec<f64>, w: f64| {
            let up: f64 = areas.iter().zip(&upper).filter(|(_, &u)| u).map(|(a, _)| w * a).sum();
            let rest: f64 = areas.iter().zip(&upper).filter(|(_, &u)| !u).map(|(a, _)| a).sum();
            up / (up + rest)
        };
        let wanted = share(shapespace_geometry::quantities::vertex_dual_areas(&mesh), 4.0);
        let got = share(shapespace_geometry::quantities::vertex_dual_areas(&mapped), 1.0);
        errors.push((got - wanted).abs());
    }
    assert!(
        errors[0] < 0.03 && errors[1] < 0.6 * errors[0],
        "share errors {errors:?}"
    );

    // a disk has no sphere map
    let out = shapespace(&[
        "param",
        "datasets/faces/id00_neutral.obj",
        "--domain",
        "sphere",
        "--out",
        out_obj.to_str().unwrap(),
    ]);
    assert_eq!(out.status.code(), Some(2), "{}", stderr(&out));
    assert!(
        stderr(&out).contains("id00_neutral.obj") && stderr(&out).contains("not a closed genus-0"),
        "{}",
        stderr(&out)
    );
}

/// `param --method spherical-mds`: an egg (ellipsoid 1 : 1 : 1.3, radius 2.5) maps onto S² with
/// the input's faces and no folded face; the report names the method, its landmarks and a
/// non-increasing stress; `--max-angle` is read in degrees; a disk, a `--domain disk`, an
/// output over the input and the method's flags on another method are refused, naming the file.
#[test]
fn param_spherical_mds_maps_a_closed_mesh_onto_the_sphere() {
    let dir = scratch("param_smds");
    let mut mesh = shapespace_geometry::primitives::icosphere(3);
    for p in &mut mesh.positions {
        *p = [2.5 * p[0], 2.5 * p[1], 3.25 * p[2]];
    }
    let input = dir.join("egg.obj");
    shapespace_geometry::io::write_mesh(&input, &mesh).unwrap();
    let out_ply = dir.join("egg_mds.ply");
    let report = dir.join("report.json");
    let (i, o, r) = (
        input.to_str().unwrap(),
        out_ply.to_str().unwrap(),
        report.to_str().unwrap(),
    );
    let out = shapespace(&[
        "param",
        i,
        "--method",
        "spherical-mds",
        "--out",
        o,
        "--report",
        r,
        "--mds-landmarks",
        "200",
    ]);
    assert_eq!(out.status.code(), Some(0), "{}", stderr(&out));
    let mapped = shapespace_geometry::io::read_mesh(&out_ply).unwrap();
    assert_eq!(mapped.faces, mesh.faces);
    for p in &mapped.positions {
        assert!(((p[0] * p[0] + p[1] * p[1] + p[2] * p[2]).sqrt() - 1.0).abs() < 1e-12);
    }
    let json: serde_json::Value = serde_json::from_str(&std::fs::read_to_string(&report).unwrap()).unwrap();
    assert_eq!(json["method"], "spherical-mds");
    assert_eq!(json["num_flipped"], 0);
    assert_eq!(json["distortion"]["maps"][0]["name"], "spherical-mds");
    assert_eq!(json["spherical_mds"]["num_landmarks"], 200);
    assert_eq!(json["landmarks"].as_array().unwrap().len(), 200);
    let history: Vec<f64> = json["spherical_mds"]["landmark_smacof"]["stress_history"]
        .as_array()
        .unwrap()
        .iter()
        .map(|v| v.as_f64().unwrap())
        .collect();
    assert!(
        !history.is_empty() && history.windows(2).all(|w| w[1] <= w[0]),
        "{history:?}"
    );
    assert!(
        json["distortion"]["maps"][0]["abs_vertex_log_area_ratio"]["p95"]
            .as_f64()
            .unwrap()
            < 0.5
    );

    std::fs::remove_file(&report).unwrap();
    let out = shapespace(&[
        "param",
        i,
        "--method",
        "spherical-mds",
        "--out",
        o,
        "--report",
        r,
        "--mds-landmarks",
        "100",
        "--max-angle",
        "270",
    ]);
    assert_eq!(out.status.code(), Some(0), "{}", stderr(&out));
    let json: serde_json::Value = serde_json::from_str(&std::fs::read_to_string(&report).unwrap()).unwrap();
    let angle = json["spherical_mds"]["max_angle"].as_f64().unwrap();
    assert!((angle - 1.5 * std::f64::consts::PI).abs() < 1e-12, "{angle}");

    let refused = [
        (
            vec![
                "param",
                "datasets/faces/id00_neutral.obj",
                "--method",
                "spherical-mds",
                "--out",
                o,
            ],
            "id00_neutral.obj",
        ),
        (
            vec!["param", i, "--method", "spherical-mds", "--domain", "disk", "--out", o],
            "egg.obj",
        ),
        (vec!["param", i, "--method", "spherical-mds", "--out", i], "egg.obj"),
        (
            vec!["param", i, "--domain", "sphere", "--max-angle", "200", "--out", o],
            "egg.obj",
        ),
        (
            vec![
                "param",
                i,
                "--method",
                "spherical-mds",
                "--max-angle",
                "1000",
                "--out",
                o,
            ],
            "egg.obj",
        ),
    ];
    for (args, name) in refused {
        let out = shapespace(&args);
        assert_eq!(out.status.code(), Some(2), "{args:?}: {}", stderr(&out));
        assert!(stderr(&out).contains(name), "{args:?}: {}", stderr(&out));
    }
    let out = shapespace(&[
        "param",
        "datasets/faces/id00_neutral.obj",
        "--method",
        "spherical-mds",
        "--out",
        o,
    ]);
    assert!(stderr(&out).contains("not a closed genus-0"), "{}", stderr(&out));
}

/// `mds --method smacof` on the bundled faces40 matrix: exit 0, stats.json says smacof with a
/// stress-1 below the classical embedding's, and the summary line reports both; an iteration
/// cap of 1 stops short of the tolerance: exit 1, the configuration still written.
#[test]
fn mds_smacof_reports_the_stress() {
    let dir = scratch("mds_smacof");
    let matrix = root().join("tests/data/faces40/distances.csv");
    let out = dir.join("m");
    let run = shapespace(&[
        "mds",
        matrix.to_str().unwrap(),
        "--out",
        out.to_str().unwrap(),
        "--method",
        "smacof",
    ]);
    assert_eq!(run.status.code(), Some(0), "{}", stderr(&run));
    assert!(stderr(&run).contains("SMACOF stress-1"), "{}", stderr(&run));
    let stats: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(out.join("stats.json")).unwrap()).unwrap();
    let m = &stats["mds"];
    assert_eq!(m["method"], "smacof");
    let (s, c) = (
        m["stress"]["stress1"].as_f64().unwrap(),
        m["classical_stress"]["stress1"].as_f64().unwrap(),
    );
    assert!(s > 0.0 && s < c, "{m}");
    let capped = dir.join("capped");
    let run = shapespace(&[
        "mds",
        matrix.to_str().unwrap(),
        "--out",
        capped.to_str().unwrap(),
        "--method",
        "smacof",
        "--max-iterations",
        "1",
    ]);
    assert_eq!(run.status.code(), Some(1), "{}", stderr(&run));
    assert!(capped.join("mds.csv").is_file());
    std::fs::remove_dir_all(&dir).ok();
}

/// `register --refine`: an unknown refinement is a usage error before any work; `zoomout`, the
/// default, on the wolf poses records the refinement in `metrics.json` and lowers the geodesic
/// error (wolf0 → wolf1: 0.0207 → 0.0017 mean), with the vertex map between the poses' one
/// triangulation and projected points when asked (an unknown output is a usage error); a
/// surface with fewer vertices than the 120 eigenpairs is refused before any map when `zoomout`
/// is asked for, naming the file, and registered by the first stage alone, with a note naming
/// it, by default.
#[test]
fn register_refines_by_zoomout() {
    let dir = scratch("register_refine");
    let out_dir = dir.join("reg");
    let wolf = |i: usize| format!("datasets/poses/wolf/wolf{i}.off");
    let (w0, w1) = (wolf(0), wolf(1));
    let run = |extra: &[&str]| {
        let mut args = vec!["register", w0.as_str(), w1.as_str(), "--out", out_dir.to_str().unwrap()];
        args.extend_from_slice(extra);
        shapespace(&args)
    };
    let out = run(&["--refine", "bogus"]);
    assert_eq!(out.status.code(), Some(2), "{}", stderr(&out));
    assert!(stderr(&out).contains("unknown refinement `bogus`"), "{}", stderr(&out));
    assert!(!out_dir.join("metrics.json").exists());
    let out = run(&["--untangle-g", "pinned"]);
    assert_eq!(out.status.code(), Some(2), "{}", stderr(&out));
    assert!(
        stderr(&out).contains("expected on, held, foldover-free or off, got `pinned`"),
        "{}",
        stderr(&out)
    );
    assert!(!out_dir.join("metrics.json").exists());

    let mean_error = || {
        let metrics: serde_json::Value =
            serde_json::from_str(&std::fs::read_to_string(out_dir.join("metrics.json")).unwrap()).unwrap();
        (
            metrics["metrics"]["geodesic"]["summary"]["mean"].as_f64().unwrap(),
            metrics["run"]["refinement"].clone(),
        )
    };
    let out = run(&["--refine", "none"]);
    assert_eq!(out.status.code(), Some(0), "{}", stderr(&out));
    let (plain, info) = mean_error();
    assert!(info.is_null(), "{info}");
    // the default
    let out = run(&[]);
    assert_eq!(out.status.code(), Some(0), "{}", stderr(&out));
    assert!(stderr(&out).contains("refinement zoomout"), "{}", stderr(&out));
    let (refined, info) = mean_error();
    assert_eq!(info["refinement"], "zoomout", "{info}");
    assert_eq!(info["sizes"].as_array().unwrap().last().unwrap(), 120, "{info}");
    assert!(refined < plain / 4.0 && refined < 0.004, "{plain} -> {refined}");
    // the poses share their triangulation: the vertex map (decision 0056), unless asked
    assert_eq!(info["output"], "vertex", "{info}");
    let out = run(&["--refine", "zoomout", "--zoomout-output", "projected"]);
    assert_eq!(out.status.code(), Some(0), "{}", stderr(&out));
    assert_eq!(mean_error().1["output"], "projected");
    let out = run(&["--refine", "zoomout", "--zoomout-output", "points"]);
    assert_eq!(out.status.code(), Some(2), "{}", stderr(&out));
    assert!(stderr(&out).contains("--zoomout-output") && stderr(&out).contains("points"));
    // a larger last spectral size: sharper on these poses (docs/accuracy.md, the curve of k_end)
    let out = run(&["--refine", "zoomout", "--zoomout-k-end", "160"]);
    assert_eq!(out.status.code(), Some(0), "{}", stderr(&out));
    let (sharper, info) = mean_error();
    assert_eq!(info["sizes"].as_array().unwrap().last().unwrap(), 160, "{info}");
    assert!(sharper < refined, "k_end 120: {refined}, 160: {sharper}");
    // a first size beyond the last one: refused before any work, naming both options
    std::fs::remove_file(out_dir.join("metrics.json")).unwrap();
    let out = run(&[
        "--refine",
        "zoomout",
        "--zoomout-k-end",
        "60",
        "--zoomout-starts",
        "20,80",
    ]);
    let msg = stderr(&out);
    assert_eq!(out.status.code(), Some(2), "{msg}");
    assert!(
        msg.contains("--zoomout-starts 80") && msg.contains("--zoomout-k-end 60"),
        "{msg}"
    );
    assert!(!out_dir.join("metrics.json").exists());

    let (a, b) = (dir.join("a.obj"), dir.join("b.obj"));
    std::fs::write(&a, grid_obj(1.0)).unwrap();
    std::fs::write(&b, grid_obj(1.5)).unwrap();
    let pairs = dir.join("pairs.csv");
    std::fs::write(&pairs, "source,target\n6,6\n").unwrap();
    let grid = |out: &Path, extra: &[&str]| {
        let mut options = vec!["--landmarks", pairs.to_str().unwrap()];
        options.extend_from_slice(extra);
        register(&a, &b, &options, out)
    };
    let out = grid(&dir.join("grid"), &["--refine", "zoomout"]);
    let msg = stderr(&out);
    assert_eq!(out.status.code(), Some(2), "{msg}");
    assert!(
        msg.contains(a.to_str().unwrap()) && msg.contains("25 vertices, fewer than ZoomOut's 120 eigenpairs"),
        "{msg}"
    );
    assert!(!dir.join("grid").join("metrics.json").exists());
    let grid_out = dir.join("grid-default");
    let out = grid(&grid_out, &[]);
    let msg = stderr(&out);
    assert_eq!(out.status.code(), Some(0), "{msg}");
    assert!(
        msg.contains("25 vertices, fewer than ZoomOut's 120 eigenpairs") && msg.contains("refinement none"),
        "{msg}"
    );
    let metrics: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(grid_out.join("metrics.json")).unwrap()).unwrap();
    assert!(
        metrics["run"]["refinement"].is_null(),
        "{}",
        metrics["run"]["refinement"]
    );
}

/// The conformal map's choices reach the commands that map disks on the way: `param` on the
/// bundled centaur0 slit from two tips falls back to BFF by default, refuses the Green's folds
/// with `--no-bff-fallback`, and maps with `--conformal bff`; `distances --conformal bff` maps
/// both faces by BFF (report.json says so) and gives a distance within 5 % of the Green's map's
/// (two discretizations of one conformal map; measured 3.5 % on this pair).
#[test]
fn disk_map_choices_reach_param_and_distances() {
    let dir = scratch("disk_map_choices");
    let disk = dir.join("centaur0_slit.obj");
    let out = shapespace(&[
        "prepare",
        "datasets/poses/centaur/centaur0.off",
        "--out",
        disk.to_str().unwrap(),
        "--seam",
        "2",
    ]);
    assert_eq!(out.status.code(), Some(0), "{}", stderr(&out));
    let map = dir.join("ap.obj");
    let report = dir.join("ap.json");
    let param = |extra: &[&str]| {
        let mut args = vec![
            "param",
            disk.to_str().unwrap(),
            "--out",
            map.to_str().unwrap(),
            "--report",
            report.to_str().unwrap(),
        ];
        args.extend_from_slice(extra);
        shapespace(&args)
    };
    let out = param(&["--no-bff-fallback"]);
    assert_ne!(out.status.code(), Some(0));
    assert!(stderr(&out).contains("flipped or degenerate"), "{}", stderr(&out));
    let out = param(&["--conformal", "bff"]);
    assert_eq!(out.status.code(), Some(0), "{}", stderr(&out));
    let text = std::fs::read_to_string(&report).unwrap();
    assert!(text.contains("bff-disk"), "{text}");
    assert!(!text.contains("fallback: the Green"), "{text}");

    let faces = ["datasets/faces/id00_happy.obj", "datasets/faces/id01_sad.obj"];
    let distance = |name: &str, extra: &[&str]| {
        let out_dir = dir.join(name);
        let mut args = vec![
            "distances",
            faces[0],
            faces[1],
            "--out",
            out_dir.to_str().unwrap(),
            "--quiet",
        ];
        args.extend_from_slice(extra);
        let out = shapespace(&args);
        assert_eq!(out.status.code(), Some(0), "{}", stderr(&out));
        let csv = std::fs::read_to_string(out_dir.join("distances.csv")).unwrap();
        let d: f64 = csv.lines().nth(1).unwrap().split(',').nth(2).unwrap().parse().unwrap();
        let report: serde_json::Value =
            serde_json::from_str(&std::fs::read_to_string(out_dir.join("report.json")).unwrap()).unwrap();
        let methods: Vec<String> = report["inputs"]
            .as_array()
            .unwrap()
            .iter()
            .map(|f| f["conformal_method"].as_str().unwrap_or("").to_string())
            .collect();
        (d, methods)
    };
    let (green, green_methods) = distance("green", &[]);
    let (bff, bff_methods) = distance("bff", &["--conformal", "bff"]);
    assert!(
        green_methods.iter().all(|m| m.starts_with("green-function")),
        "{green_methods:?}"
    );
    assert!(bff_methods.iter().all(|m| m.starts_with("bff-disk")), "{bff_methods:?}");
    assert!(((bff - green) / green).abs() < 0.05, "{bff} {green}");
}

/// `register-bench --remeshed` with a folder that does not exist, or `--peer` without its
/// script: status 2 naming the path, before any registration; a `--region-from-area` that is
/// not a share of the area, a `--zoomout-starts` that is not a list of sizes from 1 to the last
/// size (120 by default), a `--zoomout-k-end` outside 8 to 1000, a `--zoomout-output` other
/// than auto, vertex and projected, a `--zoomout-samples` below 1, or a `--landmark-weight` or
/// `--landmark-fit` that is negative or not finite: status 2 naming the option, no output
/// folder.
#[test]
fn register_bench_names_a_missing_remeshed_folder_or_peer_script() {
    let dir = scratch("bench-remeshed-missing");
    let dataset = dir.join("dataset");
    std::fs::create_dir_all(dataset.join("c")).unwrap();
    std::fs::write(dataset.join("c/a.obj"), grid_obj(1.0)).unwrap();
    std::fs::write(dataset.join("c/b.obj"), grid_obj(2.0)).unwrap();
    let missing = dir.join("no-such-remeshed");
    let out = shapespace(&[
        "register-bench",
        dataset.to_str().unwrap(),
        "--out",
        dir.join("out").to_str().unwrap(),
        "--remeshed",
        missing.to_str().unwrap(),
    ]);
    let msg = stderr(&out);
    assert_eq!(out.status.code(), Some(2), "{msg}");
    assert!(
        msg.contains("no-such-remeshed") && msg.contains("not a folder"),
        "{msg}"
    );
    let out = shapespace(&[
        "register-bench",
        dataset.to_str().unwrap(),
        "--out",
        dir.join("out2").to_str().unwrap(),
        "--peer",
        "python3",
        "--peer-script",
        dir.join("no-such-script.py").to_str().unwrap(),
    ]);
    let msg = stderr(&out);
    assert_eq!(out.status.code(), Some(2), "{msg}");
    assert!(
        msg.contains("no-such-script.py") && msg.contains("no such file"),
        "{msg}"
    );
    // the region moves' area threshold is a share of the area; ZoomOut's first sizes are a
    // comma-separated list of sizes from 1 to its last size (120 by default), which is 8 to 1000
    for (option, bad_values) in [
        ("--region-from-area", &["1.5", "-0.1", "NaN", "half"][..]),
        ("--zoomout-starts", &["0", "121", "8,x", ""][..]),
        ("--zoomout-k-end", &["7", "1001", "x"][..]),
        ("--zoomout-output", &["points", "vertices"][..]),
        ("--zoomout-samples", &["0", "-5", "many"][..]),
        ("--landmark-weight", &["-1", "inf", "NaN", "x"][..]),
        ("--landmark-fit", &["-0.5", "inf", "NaN", "x"][..]),
    ] {
        for bad in bad_values {
            let out = shapespace(&[
                "register-bench",
                dataset.to_str().unwrap(),
                "--out",
                dir.join("out3").to_str().unwrap(),
                &format!("{option}={bad}"),
            ]);
            let msg = stderr(&out);
            assert_eq!(out.status.code(), Some(2), "{option}={bad:?}: {msg}");
            assert!(msg.contains(option) && msg.contains(bad), "{msg}");
            assert!(
                !dir.join("out3").exists(),
                "{option}={bad:?}: an output folder was made"
            );
        }
    }
}

/// `distances` with a closed mesh and a disk: refused with status 2 before any work, naming the
/// closed file and the disk.
#[test]
fn distances_refuses_mixing_closed_meshes_and_disks() {
    let dir = scratch("sphere-mix");
    let closed = dir.join("octahedron.obj");
    std::fs::write(
        &closed,
        "v 1 0 0\nv -1 0 0\nv 0 1 0\nv 0 -1 0\nv 0 0 1\nv 0 0 -1\n\
         f 1 3 5\nf 3 2 5\nf 2 4 5\nf 4 1 5\nf 3 1 6\nf 2 3 6\nf 4 2 6\nf 1 4 6\n",
    )
    .unwrap();
    let disk = "datasets/faces/id00_neutral.obj";
    let out = dir.join("out");
    let run = shapespace(&[
        "distances",
        closed.to_str().unwrap(),
        disk,
        "--out",
        out.to_str().unwrap(),
        "--quiet",
    ]);
    let err = stderr(&run);
    assert_eq!(run.status.code(), Some(2), "{err}");
    assert!(
        err.contains("cannot be mixed") && err.contains("octahedron.obj") && err.contains("id00_neutral.obj"),
        "{err}"
    );
    assert!(!out.join("distances.csv").exists());
    let _ = std::fs::remove_dir_all(&dir);
}

/// `shapespace param --method flow` writes the gradient-flow OMT map: one `vt` per vertex, rim
/// vertices on the unit circle, a report with the method, the multiresolution start used (no
/// fallback), the flow's curl norms and costs (the
/// cost not above the start's) and a distortion block whose map has no flipped face and a |Υ|
/// median below a fifth of the conformal map's; `--domain sphere` is refused with status 2.
#[test]
fn param_flow_on_a_face() {
    let dir = scratch("param_flow");
    let obj = dir.join("flow.obj");
    let json = dir.join("flow.json");
    let out = shapespace(&[
        "param",
        "datasets/faces/id01_sad.obj",
        "--out",
        obj.to_str().unwrap(),
        "--report",
        json.to_str().unwrap(),
        "--method",
        "flow",
    ]);
    assert!(out.status.success(), "{}", stderr(&out));
    assert!(stderr(&out).contains("gradient flow"), "{}", stderr(&out));
    let (vt, nv) = read_vt(&obj);
    assert_eq!(vt.len(), nv);
    let on_circle = vt.iter().filter(|p| (p[0].hypot(p[1]) - 1.0).abs() < 1e-9).count();
    assert!(on_circle > 100, "{on_circle} vertices on the circle");
    let report: serde_json::Value = serde_json::from_str(&std::fs::read_to_string(&json).unwrap()).unwrap();
    assert_eq!(report["method"], "flow");
    // two coarse levels ran, and the flow started from their prolonged, Moser-corrected map
    let levels = &report["multiresolution"];
    assert_eq!(levels["levels"].as_array().unwrap().len(), 2);
    assert!(levels["fallback"].is_null(), "{levels}");
    assert!(levels["correction_mean_steps"].as_f64().unwrap() > 0.0, "{levels}");
    let flow = &report["gradient_flow"];
    assert!(flow["start_curl"].as_f64().unwrap() > 0.0);
    assert!(flow["final_cost"].as_f64().unwrap() <= flow["start_cost"].as_f64().unwrap());
    let maps = &report["distortion"]["maps"];
    assert_eq!(maps[1]["num_flipped"], 0);
    let median = |k: usize| maps[k]["abs_area_distortion"]["median"].as_f64().unwrap();
    assert!(median(1) < 0.2 * median(0), "{} vs {}", median(1), median(0));
    let sphere = shapespace(&[
        "param",
        "datasets/faces/id01_sad.obj",
        "--out",
        dir.join("sphere.obj").to_str().unwrap(),
        "--method",
        "flow",
        "--domain",
        "sphere",
    ]);
    assert_eq!(sphere.status.code(), Some(2), "{}", stderr(&sphere));
    assert!(
        stderr(&sphere).contains("id01_sad.obj") && stderr(&sphere).contains("not a closed genus-0"),
        "{}",
        stderr(&sphere)
    );
}

/// `param --method lie` and `--method flow` on a closed egg (ellipsoid 1 : 0.8 : 1.5): the
/// domain defaults to the sphere for a closed input, the output has the input's faces on S², no
/// folded face, a 95th percentile |ε| at most a fifth of the conformal map's, and the report
/// names the method with its steps; the flow ends below its curl tolerance; weights are
/// refused.
#[test]
fn param_lie_and_flow_map_a_closed_mesh_onto_the_sphere() {
    let dir = scratch("param_sphere_flows");
    let mut mesh = shapespace_geometry::primitives::icosphere(3);
    for p in &mut mesh.positions {
        *p = [p[0], 0.8 * p[1], 1.5 * p[2]];
    }
    let input = dir.join("egg.obj");
    shapespace_geometry::io::write_mesh(&input, &mesh).unwrap();
    let out_mesh = dir.join("egg_on_sphere.ply");
    let report = dir.join("report.json");
    for (method, domain) in [("lie", None), ("flow", Some("sphere"))] {
        let mut args = vec![
            "param",
            input.to_str().unwrap(),
            "--method",
            method,
            "--out",
            out_mesh.to_str().unwrap(),
            "--report",
            report.to_str().unwrap(),
        ];
        if let Some(d) = domain {
            args.extend_from_slice(&["--domain", d]);
        }
        let out = shapespace(&args);
        assert_eq!(out.status.code(), Some(0), "{}", stderr(&out));
        let mapped = shapespace_geometry::io::read_mesh(&out_mesh).unwrap();
        assert_eq!(mapped.faces, mesh.faces);
        for p in &mapped.positions {
            assert!(((p[0] * p[0] + p[1] * p[1] + p[2] * p[2]).sqrt() - 1.0).abs() < 1e-12);
        }
        let json: serde_json::Value = serde_json::from_str(&std::fs::read_to_string(&report).unwrap()).unwrap();
        assert_eq!(json["method"], method);
        assert_eq!(json["domain"], "sphere");
        assert_eq!(json["num_flipped"], 0);
        if method == "lie" {
            assert!(json["lie_advection"]["mean_steps"].as_f64().unwrap() > 1.0);
        } else {
            // the flow starts from the prolonged, Moser-corrected coarse level (162 vertices)
            let levels = &json["multiresolution"];
            assert_eq!(levels["levels"][0]["vertices"], 162, "{levels}");
            assert!(levels["correction_mean_steps"].as_f64().unwrap() > 0.0, "{levels}");
        }
        let p95 = |k: usize| {
            json["distortion"]["maps"][k]["abs_vertex_log_area_ratio"]["p95"]
                .as_f64()
                .unwrap()
        };
        assert!(
            p95(1) < 0.2 * p95(0),
            "{method}: p95 |ε| {} against conformal {}",
            p95(1),
            p95(0)
        );
        if method == "flow" {
            let flow = &json["gradient_flow"];
            // the flow stops at its tolerance (here the Lie map is already there: 0 steps)
            assert!(flow["final_curl"].as_f64().unwrap() <= 1e-3, "{flow}");
            assert!(stderr(&out).contains("gradient flow"), "{}", stderr(&out));
        }
        std::fs::remove_file(&out_mesh).unwrap();
    }
    let weights = dir.join("weights.csv");
    std::fs::write(&weights, "vertex,weight\n0,2\n").unwrap();
    let out = shapespace(&[
        "param",
        input.to_str().unwrap(),
        "--method",
        "lie",
        "--out",
        out_mesh.to_str().unwrap(),
        "--weights",
        weights.to_str().unwrap(),
    ]);
    assert_eq!(out.status.code(), Some(2), "{}", stderr(&out));
    assert!(stderr(&out).contains("takes no --weights"), "{}", stderr(&out));
}

/// `distances` on closed meshes (the sphere route, rotation search): a run over two shapes
/// resumed with a third computes only the new pairs and gives the full run's distances.csv
/// byte for byte; two shards merged give it too. The shapes are an icosphere (162 vertices)
/// stretched into three ellipsoids, one with a bump, so every distance is positive.
#[test]
fn sphere_distances_resume_and_shards_reproduce_the_full_run() {
    let dir = scratch("sphere-resume");
    let mut files = Vec::new();
    for (name, axes, bump) in [
        ("round", [1.0, 1.0, 1.0], 0.0),
        ("long", [1.0, 1.0, 1.8], 0.0),
        ("bumpy", [1.2, 0.9, 1.0], 0.4),
    ] {
        let mut mesh = shapespace_geometry::primitives::icosphere(2);
        for p in &mut mesh.positions {
            let lift = 1.0 + bump * (-8.0 * ((p[0] - 1.0).powi(2) + p[1] * p[1] + p[2] * p[2])).exp();
            *p = [0, 1, 2].map(|k| p[k] * axes[k] * lift);
        }
        let path = dir.join(format!("{name}.obj"));
        shapespace_geometry::io::write_mesh(&path, &mesh).unwrap();
        files.push(path.to_str().unwrap().to_string());
    }
    let run = |out: &Path, files: &[String], extra: &[&str]| {
        let mut args = vec!["distances"];
        args.extend(files.iter().map(String::as_str));
        args.extend(["--out", out.to_str().unwrap(), "--quiet"]);
        args.extend_from_slice(extra);
        let result = shapespace(&args);
        assert_eq!(result.status.code(), Some(0), "{}", stderr(&result));
        stderr(&result)
    };
    let full = dir.join("full");
    run(&full, &files, &[]);
    let matrix = std::fs::read_to_string(full.join("distances.csv")).unwrap();
    let report = std::fs::read_to_string(full.join("report.json")).unwrap();
    assert!(report.contains("\"domain\": \"sphere\""), "{report}");
    let positive = matrix
        .lines()
        .skip(1)
        .flat_map(|l| {
            l.split(',')
                .skip(1)
                .map(|c| c.parse::<f64>().unwrap())
                .collect::<Vec<_>>()
        })
        .filter(|&d| d > 0.0)
        .count();
    assert_eq!(positive, 6, "{matrix}");

    let resumed = dir.join("resumed");
    run(&resumed, &files[..2], &[]);
    let message = run(&resumed, &files, &["--resume"]);
    assert!(message.contains("taken"), "{message}");
    assert_eq!(
        std::fs::read_to_string(resumed.join("distances.csv")).unwrap(),
        matrix,
        "resumed"
    );

    let mut shards = Vec::new();
    for k in 1..=2 {
        let folder = dir.join(format!("shard{k}"));
        run(&folder, &files, &["--shard", &format!("{k}/2")]);
        shards.push(folder.to_str().unwrap().to_string());
    }
    let merged = dir.join("merged");
    let result = shapespace(&["merge", &shards[1], &shards[0], "--out", merged.to_str().unwrap()]);
    assert_eq!(result.status.code(), Some(0), "{}", stderr(&result));
    assert_eq!(
        std::fs::read_to_string(merged.join("distances.csv")).unwrap(),
        matrix,
        "merged"
    );
    let _ = std::fs::remove_dir_all(&dir);
}

/// A latitude–longitude sphere (`rings` rings of `segments` vertices between two poles) as OBJ
/// text, outward faces, every vertex rotated about the axis (1, 1, 1) by `angle`, the ellipsoid
/// axes (1, 1, `stretch`) and a bend x += 0.3 z (z + 1) applied first (no symmetry, so that
/// the sphere map's puncture, the face nearest the area centroid, is one face).
fn lat_long_sphere_obj(rings: usize, segments: usize, stretch: f64, angle: f64) -> String {
    let mut points = vec![[0.0, 0.0, -stretch]];
    for r in 1..=rings {
        let t = std::f64::consts::PI * r as f64 / (rings + 1) as f64;
        for s in 0..segments {
            let p = 2.0 * std::f64::consts::PI * (s as f64 + 0.5 * (r % 2) as f64) / segments as f64;
            let z = -t.cos();
            points.push([t.sin() * p.cos() + 0.3 * z * (z + 1.0), t.sin() * p.sin(), stretch * z]);
        }
    }
    points.push([0.0, 0.0, stretch]);
    let (c, s) = (angle.cos(), angle.sin());
    let k = 1.0 / 3f64.sqrt();
    let text_v: String = points
        .iter()
        .map(|p| {
            // Rodrigues about the unit axis k(1, 1, 1)
            let kxp = [k * (p[2] - p[1]), k * (p[0] - p[2]), k * (p[1] - p[0])];
            let kdp = k * (p[0] + p[1] + p[2]);
            let q: Vec<f64> = (0..3).map(|i| p[i] * c + kxp[i] * s + k * kdp * (1.0 - c)).collect();
            format!("v {:?} {:?} {:?}\n", q[0], q[1], q[2])
        })
        .collect();
    let id = |r: usize, s: usize| 2 + (r - 1) * segments + s % segments; // 1-based
    let mut f = String::new();
    let top = points.len();
    for s in 0..segments {
        f.push_str(&format!("f 1 {} {}\n", id(1, s + 1), id(1, s)));
        f.push_str(&format!("f {top} {} {}\n", id(rings, s), id(rings, s + 1)));
    }
    for r in 1..rings {
        for s in 0..segments {
            let (a, b, c, d) = (id(r, s), id(r, s + 1), id(r + 1, s), id(r + 1, s + 1));
            f.push_str(&format!("f {a} {b} {d}\nf {a} {d} {c}\n"));
        }
    }
    text_v + &f
}

/// `register` on two closed meshes goes to the sphere (a rotated copy registers onto itself:
/// geodesic error 0 to rounding, no flips, by the first stage alone, the default on these
/// 98-vertex meshes, and refined by ZoomOut), and a closed mesh with a disk is refused naming
/// both files, before any map.
#[test]
fn register_closed_meshes_on_the_sphere_and_refuses_mixing() {
    let dir = scratch("register-sphere");
    let (a, b, disk) = (dir.join("a.obj"), dir.join("b.obj"), dir.join("disk.obj"));
    std::fs::write(&a, lat_long_sphere_obj(8, 12, 1.5, 0.0)).unwrap();
    std::fs::write(&b, lat_long_sphere_obj(8, 12, 1.5, 1.1)).unwrap();
    std::fs::write(&disk, grid_obj(1.0)).unwrap();
    let lm = dir.join("lm.csv");
    std::fs::write(&lm, "source,target\n5,5\n40,40\n77,77\n").unwrap();
    let run = |b: &Path, out: &Path, extra: &[&str]| {
        let mut options = vec!["--landmarks", lm.to_str().unwrap(), "--method", "conformal"];
        options.extend(extra);
        register(&a, b, &options, out)
    };
    // the first stage, then refined by ZoomOut: both keep the rotated copy's identity
    for (name, extra) in [
        ("out", &[][..]),
        (
            "refined",
            &["--refine", "zoomout", "--zoomout-k-end", "16", "--zoomout-starts", "8"][..],
        ),
    ] {
        let out_dir = dir.join(name);
        let out = run(&b, &out_dir, extra);
        let msg = stderr(&out);
        assert_eq!(out.status.code(), Some(0), "{msg}");
        assert!(msg.contains("on the sphere"), "{msg}");
        assert_eq!(
            msg.contains("98 vertices, fewer than ZoomOut's 120"),
            extra.is_empty(),
            "{msg}"
        );
        let metrics: serde_json::Value =
            serde_json::from_slice(&std::fs::read(out_dir.join("metrics.json")).unwrap()).unwrap();
        assert_eq!(metrics["domain"], "sphere");
        let geo = metrics["metrics"]["geodesic"]["summary"]["max"].as_f64().unwrap();
        assert!(geo < 1e-9, "{name}: rotated copy: geodesic error {geo}");
        assert_eq!(metrics["metrics"]["flipped_faces"], 0);
        assert_eq!(metrics["metrics"]["flipped_faces_3d"], 0);
        let refinement = &metrics["run"]["refinement"];
        assert_eq!(refinement.is_null(), extra.is_empty(), "{refinement}");
        let rows = std::fs::read_to_string(out_dir.join("correspondence.csv")).unwrap();
        assert_eq!(rows.lines().count(), 1 + 2 + 8 * 12);
    }

    let out = run(&disk, &dir.join("mixed"), &[]);
    let msg = stderr(&out);
    assert_eq!(out.status.code(), Some(2), "{msg}");
    assert!(
        msg.contains(a.to_str().unwrap()) && msg.contains(disk.to_str().unwrap()) && msg.contains("closed"),
        "{msg}"
    );
    assert!(!dir.join("mixed").join("metrics.json").exists());
}

/// `distances --source-faces N` on two bundled faces: the pair runs on the averaged densities,
/// the distance stays within 1 % of full resolution, the report records N and the cache keeps
/// other entries for it; 0 is refused before any work, and a request below what a face's
/// boundary needs fails that face by name (exit 1) instead of running on something else.
#[test]
fn distances_with_averaged_source_densities() {
    let dir = scratch("source-faces");
    let faces = ["datasets/faces/id00_neutral.obj", "datasets/faces/id02_neutral.obj"];
    let run = |name: &str, extra: &[&str]| {
        let out = dir.join(name);
        let mut args = vec![
            "distances",
            faces[0],
            faces[1],
            "--quiet",
            "--out",
            out.to_str().unwrap(),
        ];
        args.extend(extra);
        (shapespace(&args), out)
    };
    let distance = |out: &Path| -> f64 {
        let text = std::fs::read_to_string(out.join("distances.csv")).unwrap();
        let row = text.lines().nth(1).unwrap();
        row.split(',').nth(2).unwrap().parse().unwrap()
    };
    let (full, full_dir) = run("full", &[]);
    assert_eq!(full.status.code(), Some(0), "{}", stderr(&full));
    let (coarse, coarse_dir) = run("coarse", &["--source-faces", "6000"]);
    assert_eq!(coarse.status.code(), Some(0), "{}", stderr(&coarse));
    let (d, d_full) = (distance(&coarse_dir), distance(&full_dir));
    assert!(d != d_full && (d / d_full - 1.0).abs() < 0.01, "{d} against {d_full}");
    let report: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(coarse_dir.join("report.json")).unwrap()).unwrap();
    assert_eq!(
        report["options"]["source_faces"].as_u64(),
        Some(6000),
        "{}",
        report["options"]
    );
    let (zero, _) = run("zero", &["--source-faces", "0"]);
    assert_eq!(zero.status.code(), Some(2), "{}", stderr(&zero));
    assert!(
        stderr(&zero).contains("--source-faces must be at least 1"),
        "{}",
        stderr(&zero)
    );
    let (tiny, _) = run("tiny", &["--source-faces", "50"]);
    assert_eq!(tiny.status.code(), Some(1), "{}", stderr(&tiny));
    assert!(
        stderr(&tiny).contains("id00_neutral.obj") && stderr(&tiny).contains("cannot be averaged to 50 triangles"),
        "{}",
        stderr(&tiny)
    );
    std::fs::remove_dir_all(&dir).ok();
}
