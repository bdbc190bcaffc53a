//! `distances --shard K/N` and `merge`: three shards merged give the files of one run over all
//! pairs, byte for byte but for the timings; shards of different runs, missing shards and a
//! changed row are refused with a message that names them.

use std::path::{Path, PathBuf};
use std::process::{Command, Output};

fn root() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("../..")
}

/// Runs the binary in `dir`.
fn shapespace(dir: &Path, args: &[&str]) -> Output {
    Command::new(env!("CARGO_BIN_EXE_shapespace"))
        .args(args)
        .current_dir(dir)
        .output()
        .expect("the binary runs")
}

fn scratch(name: &str) -> PathBuf {
    let dir = std::env::temp_dir().join(format!("shapespace-shard-test-{}-{name}", std::process::id()));
    let _ = std::fs::remove_dir_all(&dir);
    std::fs::create_dir_all(&dir).unwrap();
    dir
}

fn stderr(out: &Output) -> String {
    String::from_utf8_lossy(&out.stderr).into_owned()
}

/// Four bundled faces (two of one identity), absolute paths: 6 pairs.
fn faces() -> Vec<String> {
    ["id00_happy", "id00_neutral", "id01_sad", "id02_happy"]
        .iter()
        .map(|f| {
            let p = root().join("datasets/faces").join(format!("{f}.obj"));
            std::fs::canonicalize(p).unwrap().display().to_string()
        })
        .collect()
}

/// The report without its timings: `timings` and each input's `seconds`.
fn without_timings(path: &Path) -> serde_json::Value {
    let mut v: serde_json::Value = serde_json::from_str(&std::fs::read_to_string(path).unwrap()).unwrap();
    v.as_object_mut().unwrap().remove("timings");
    for input in v["inputs"].as_array_mut().unwrap() {
        input.as_object_mut().unwrap().remove("seconds");
    }
    v
}

/// pairs.csv without the `seconds` column and the `check` that covers it.
fn pairs_without_seconds(path: &Path) -> Vec<String> {
    std::fs::read_to_string(path)
        .unwrap()
        .lines()
        .map(|line| {
            let cells: Vec<&str> = line.split(',').collect();
            assert_eq!(cells.len(), 11, "{line}");
            [&cells[..6], &cells[7..10]].concat().join(",")
        })
        .collect()
}

/// The report with the lines of its timings removed (the rest byte for byte).
fn report_lines_without_timings(path: &Path) -> Vec<String> {
    let text = std::fs::read_to_string(path).unwrap();
    let mut out = Vec::new();
    let mut in_timings = false;
    for line in text.lines() {
        if line.trim_start().starts_with("\"timings\"") {
            in_timings = true;
        }
        let skip = in_timings || line.trim_start().starts_with("\"seconds\"");
        if in_timings && line.trim_start().starts_with('}') {
            in_timings = false;
        }
        if !skip {
            out.push(line.to_string());
        }
    }
    out
}

#[test]
fn three_shards_merged_equal_one_run() {
    let dir = scratch("merge");
    let files = faces();
    let (single, merged) = (dir.join("single"), dir.join("merged"));
    std::fs::create_dir_all(&single).unwrap();
    std::fs::create_dir_all(&merged).unwrap();
    // the same output name `out` in both folders: report.json's `files` are then the same
    let mut args: Vec<&str> = vec!["distances"];
    args.extend(files.iter().map(String::as_str));
    args.extend(["--out", "out", "--quiet"]);
    let out = shapespace(&single, &args);
    assert!(out.status.success(), "{}", stderr(&out));
    let mut shard_pairs = Vec::new();
    for k in 1..=3 {
        let shard = format!("{k}/3");
        let folder = dir.join(format!("shard{k}")).display().to_string();
        let mut args: Vec<&str> = vec!["distances"];
        args.extend(files.iter().map(String::as_str));
        args.extend(["--out", &folder, "--quiet", "--shard", &shard]);
        let out = shapespace(&dir, &args);
        assert!(out.status.success(), "{}", stderr(&out));
        let rows = std::fs::read_to_string(dir.join(format!("shard{k}/pairs.csv"))).unwrap();
        shard_pairs.push(rows.lines().count() - 1);
    }
    // 6 pairs in 3 shards of 2
    assert_eq!(shard_pairs, vec![2, 2, 2]);
    // shards in any order
    let out = shapespace(
        &merged,
        &["merge", "../shard3", "../shard1", "../shard2", "--out", "out"],
    );
    assert!(out.status.success(), "{}", stderr(&out));
    let (a, b) = (single.join("out"), merged.join("out"));
    assert_eq!(
        std::fs::read(a.join("distances.csv")).unwrap(),
        std::fs::read(b.join("distances.csv")).unwrap(),
        "distances.csv"
    );
    assert_eq!(
        pairs_without_seconds(&a.join("pairs.csv")),
        pairs_without_seconds(&b.join("pairs.csv"))
    );
    assert_eq!(
        without_timings(&a.join("report.json")),
        without_timings(&b.join("report.json"))
    );
    assert_eq!(
        report_lines_without_timings(&a.join("report.json")),
        report_lines_without_timings(&b.join("report.json"))
    );
    // the merged matrix is complete: 4 × 4 with 12 off-diagonal distances > 0
    let text = std::fs::read_to_string(b.join("distances.csv")).unwrap();
    let positive = text
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
    assert_eq!(positive, 12, "{text}");

    // a shard run again with --resume (as the Slurm script runs a shard that died) takes its
    // pairs from its folder, and the merge is unchanged
    let shard2 = dir.join("shard2").display().to_string();
    let mut args: Vec<&str> = vec!["distances"];
    args.extend(files.iter().map(String::as_str));
    args.extend(["--out", &shard2, "--quiet", "--shard", "2/3", "--resume"]);
    let out = shapespace(&dir, &args);
    assert!(out.status.success(), "{}", stderr(&out));
    assert!(
        stderr(&out).contains("2 of the directed pairs taken from earlier runs"),
        "{}",
        stderr(&out)
    );
    let out = shapespace(
        &merged,
        &["merge", "../shard1", "../shard2", "../shard3", "--out", "again"],
    );
    assert!(out.status.success(), "{}", stderr(&out));
    assert_eq!(
        std::fs::read(b.join("distances.csv")).unwrap(),
        std::fs::read(merged.join("again/distances.csv")).unwrap()
    );
    assert_eq!(
        pairs_without_seconds(&b.join("pairs.csv")),
        pairs_without_seconds(&merged.join("again/pairs.csv"))
    );

    // a missing shard is named by its number
    let out = shapespace(&merged, &["merge", "../shard1", "../shard3", "--out", "out2"]);
    assert_eq!(out.status.code(), Some(2));
    assert!(stderr(&out).contains("missing shard 2 of 3"), "{}", stderr(&out));
    assert!(!merged.join("out2/distances.csv").exists());
    // a shard given twice
    let out = shapespace(
        &merged,
        &["merge", "../shard1", "../shard1", "../shard2", "--out", "out2"],
    );
    assert!(stderr(&out).contains("shard 1 of 3 is given twice"), "{}", stderr(&out));
    // the output folder is never one of the shards
    let out = shapespace(&dir, &["merge", "shard1", "shard2", "shard3", "--out", "shard1"]);
    assert_eq!(out.status.code(), Some(2));
    assert!(stderr(&out).contains("is the input"), "{}", stderr(&out));

    // a shard of another run (other tolerance) is refused, naming both reports
    let other = dir.join("other").display().to_string();
    let mut args: Vec<&str> = vec!["distances"];
    args.extend(files.iter().map(String::as_str));
    args.extend(["--out", &other, "--quiet", "--shard", "2/3", "--tol", "1e-5"]);
    let out = shapespace(&dir, &args);
    assert!(out.status.success(), "{}", stderr(&out));
    let out = shapespace(
        &merged,
        &["merge", "../shard1", "../other", "../shard3", "--out", "out2"],
    );
    assert_eq!(out.status.code(), Some(2));
    let message = stderr(&out);
    assert!(
        message.contains("other/report.json is not a shard of the same run as ../shard1/report.json")
            && message.contains("settings differ"),
        "{message}"
    );
    // a row changed after it was written is refused with its line
    let path = dir.join("shard2/pairs.csv");
    let text = std::fs::read_to_string(&path).unwrap();
    let mut lines: Vec<String> = text.lines().map(str::to_string).collect();
    let cells: Vec<String> = lines[1].split(',').map(str::to_string).collect();
    let changed: f64 = cells[2].parse::<f64>().unwrap() * 1.5;
    lines[1] = [&cells[..2], &[changed.to_string()], &cells[3..]].concat().join(",");
    std::fs::write(&path, lines.join("\n") + "\n").unwrap();
    let out = shapespace(
        &merged,
        &["merge", "../shard1", "../shard2", "../shard3", "--out", "out2"],
    );
    assert_eq!(out.status.code(), Some(2));
    assert!(
        stderr(&out).contains("shard2/pairs.csv:2: the row does not match its check"),
        "{}",
        stderr(&out)
    );
    std::fs::remove_dir_all(&dir).ok();
}

#[test]
fn bad_shard_arguments() {
    let dir = scratch("args");
    let files = faces();
    for bad in ["0/3", "4/3", "two"] {
        let out = shapespace(&dir, &["distances", &files[0], &files[1], "--out", "o", "--shard", bad]);
        assert_eq!(out.status.code(), Some(2), "{bad}");
        assert!(stderr(&out).contains("expected K/N"), "{bad}: {}", stderr(&out));
    }
    // a folder that is not a shard's
    std::fs::create_dir_all(dir.join("nothing")).unwrap();
    let out = shapespace(&dir, &["merge", "nothing", "--out", "o"]);
    assert_eq!(out.status.code(), Some(2));
    assert!(stderr(&out).contains("nothing/report.json"), "{}", stderr(&out));
    std::fs::remove_dir_all(&dir).ok();
}

/// `--cache DIR`: the first run stores every shape, a second run and the shards take them all
/// from there, and their files are those of a run without the cache (but the timings).
#[test]
fn the_shape_cache_is_reused_with_the_same_results() {
    let dir = scratch("cache");
    let files = faces();
    let cache = dir.join("cache").display().to_string();
    let run = |out: &str, extra: &[&str]| {
        let mut args: Vec<&str> = vec!["distances"];
        args.extend(files.iter().map(String::as_str));
        args.extend(["--out", out, "--quiet"]);
        args.extend(extra);
        let output = shapespace(&dir, &args);
        assert!(output.status.success(), "{}", stderr(&output));
        stderr(&output)
    };
    run("plain", &[]);
    let first = run("first", &["--cache", &cache]);
    assert!(first.contains("0 of 4 shapes taken from the cache"), "{first}");
    let entries = std::fs::read_dir(dir.join("cache")).unwrap().count();
    assert_eq!(entries, 4);
    let second = run("second", &["--cache", &cache]);
    assert!(second.contains("4 of 4 shapes taken from the cache"), "{second}");
    let shard = run("shard", &["--cache", &cache, "--shard", "2/3"]);
    assert!(shard.contains("4 of 4 shapes taken from the cache"), "{shard}");
    for out in ["first", "second"] {
        let (a, b) = (dir.join("plain"), dir.join(out));
        assert_eq!(
            std::fs::read(a.join("distances.csv")).unwrap(),
            std::fs::read(b.join("distances.csv")).unwrap(),
            "{out}"
        );
        assert_eq!(
            pairs_without_seconds(&a.join("pairs.csv")),
            pairs_without_seconds(&b.join("pairs.csv"))
        );
        let strip = |p: &Path| {
            let mut v = without_timings(p);
            v.as_object_mut().unwrap().remove("files");
            v
        };
        assert_eq!(strip(&a.join("report.json")), strip(&b.join("report.json")), "{out}");
    }
    // a damaged entry is prepared again (and replaced), with the same results
    let entry = std::fs::read_dir(dir.join("cache"))
        .unwrap()
        .next()
        .unwrap()
        .unwrap()
        .path();
    let mut bytes = std::fs::read(&entry).unwrap();
    let middle = bytes.len() / 2;
    bytes[middle] ^= 0x55;
    std::fs::write(&entry, &bytes).unwrap();
    let third = run("third", &["--cache", &cache]);
    assert!(third.contains("3 of 4 shapes taken from the cache"), "{third}");
    assert_eq!(
        std::fs::read(dir.join("plain/distances.csv")).unwrap(),
        std::fs::read(dir.join("third/distances.csv")).unwrap()
    );
    let fourth = run("fourth", &["--cache", &cache]);
    assert!(fourth.contains("4 of 4 shapes taken from the cache"), "{fourth}");
    // other settings are other entries
    let other = run("other", &["--cache", &cache, "--target-points", "2000"]);
    assert!(other.contains("0 of 4 shapes taken from the cache"), "{other}");
    std::fs::remove_dir_all(&dir).ok();
}
