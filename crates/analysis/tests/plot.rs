//! Plots are written as valid, non-empty PNG and SVG files.

use std::path::PathBuf;

use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use shapespace_analysis::plot::{
    histogram_counts, histograms, mds_scatter, mds_scatter_matrix, ColorScale, ScatterLabels,
};
use shapespace_analysis::{classical_mds, DistanceMatrix};

fn out(name: &str) -> PathBuf {
    let dir = PathBuf::from(env!("CARGO_TARGET_TMPDIR")).join("plots");
    std::fs::create_dir_all(&dir).unwrap();
    dir.join(name)
}

fn check_png(path: &PathBuf) {
    let bytes = std::fs::read(path).unwrap();
    assert_eq!(&bytes[..8], b"\x89PNG\r\n\x1a\n");
    // IHDR: width and height, big-endian, at bytes 16..24.
    let w = u32::from_be_bytes(bytes[16..20].try_into().unwrap());
    let h = u32::from_be_bytes(bytes[20..24].try_into().unwrap());
    assert_eq!((w, h), (1100, 760));
    assert!(bytes.len() > 10_000, "suspiciously small PNG: {} bytes", bytes.len());
}

fn check_svg(path: &PathBuf, must_contain: &[&str]) {
    let text = std::fs::read_to_string(path).unwrap();
    assert!(text.trim_start().starts_with("<svg"), "{}", &text[..80.min(text.len())]);
    assert!(text.trim_end().ends_with("</svg>"));
    for s in must_contain {
        assert!(text.contains(s), "SVG lacks {s:?}");
    }
}

/// The text of every `<text>` element of an SVG file, trimmed.
fn svg_texts(path: &PathBuf) -> Vec<String> {
    let text = std::fs::read_to_string(path).unwrap();
    text.split("</text>")
        .filter_map(|chunk| chunk.rfind('>').map(|i| chunk[i + 1..].trim().to_string()))
        .collect()
}

/// Five people × four expressions: identity offsets plus expression offsets plus noise.
fn synthetic_faces() -> (DistanceMatrix, Vec<String>, Vec<String>) {
    let mut rng = ChaCha8Rng::seed_from_u64(1);
    let people: Vec<[f64; 3]> = (0..5)
        .map(|_| std::array::from_fn(|_| rng.random_range(-1.0..1.0)))
        .collect();
    let expr: Vec<[f64; 3]> = (0..4)
        .map(|_| std::array::from_fn(|_| rng.random_range(-0.4..0.4)))
        .collect();
    let expressions = ["neutral", "smile", "anger", "surprise"];
    let (mut pts, mut ids, mut exs, mut names) = (vec![], vec![], vec![], vec![]);
    for (p, pv) in people.iter().enumerate() {
        for (e, ev) in expr.iter().enumerate() {
            pts.push(std::array::from_fn::<f64, 3, _>(|k| {
                pv[k] + ev[k] + rng.random_range(-0.05..0.05)
            }));
            ids.push(format!("person{}", p + 1));
            exs.push(expressions[e].to_string());
            names.push(format!("p{p}_e{e}"));
        }
    }
    let n = pts.len();
    let values = (0..n * n)
        .map(|k| {
            let (a, b) = (pts[k / n], pts[k % n]);
            (0..3).map(|c| (a[c] - b[c]).powi(2)).sum::<f64>().sqrt()
        })
        .collect();
    (DistanceMatrix::new(names, values).unwrap(), ids, exs)
}

#[test]
fn mds_scatter_writes_png_and_svg() {
    let (d, ids, exs) = synthetic_faces();
    let mds = classical_mds(&d, 2).unwrap();
    let ids: Vec<&str> = ids.iter().map(String::as_str).collect();
    let exs: Vec<&str> = exs.iter().map(String::as_str).collect();
    for ext in ["png", "svg"] {
        let path = out(&format!("scatter.{ext}"));
        let labels = ScatterLabels {
            color: Some(("identity", &ids)),
            marker: Some(("expression", &exs)),
            ..ScatterLabels::default()
        };
        mds_scatter(&path, &mds, &labels, "Synthetic faces: classical MDS").unwrap();
        if ext == "png" {
            check_png(&path);
        } else {
            check_svg(&path, &["person5", "surprise", "MDS 1 (", "% var)"]);
        }
    }
    // Unlabelled and 1-D variants.
    let path = out("scatter_plain.png");
    mds_scatter(&path, &mds, &ScatterLabels::default(), "no labels").unwrap();
    check_png(&path);
    let mds1 = classical_mds(&d, 1).unwrap();
    let path = out("scatter_1d.svg");
    let by_identity = ScatterLabels {
        color: Some(("identity", &ids)),
        ..ScatterLabels::default()
    };
    mds_scatter(&path, &mds1, &by_identity, "1-D").unwrap();
    check_svg(&path, &["MDS 1 ("]);
    // Bad input.
    assert!(mds_scatter(&out("x.jpg"), &mds, &ScatterLabels::default(), "t").is_err());
    let short = ScatterLabels {
        color: Some(("identity", &ids[..3])),
        ..ScatterLabels::default()
    };
    assert!(mds_scatter(&out("x.png"), &mds, &short, "t").is_err());
}

/// Point labels, a numeric column on the continuous scale (its legend runs from the smallest
/// to the largest value, in viridis' end colours), and a scatter matrix of three axes.
#[test]
fn point_labels_continuous_colours_and_a_scatter_matrix() {
    let (d, _, _) = synthetic_faces();
    let n = d.len();
    let names: Vec<&str> = d.names.iter().map(String::as_str).collect();
    let ages: Vec<String> = (0..n).map(|i| format!("{}", 20 + 3 * i)).collect();
    let ages: Vec<&str> = ages.iter().map(String::as_str).collect();
    let mds = classical_mds(&d, 3).unwrap();
    let labels = ScatterLabels {
        color: Some(("age", &ages)),
        point_labels: Some(&names),
        ..ScatterLabels::default()
    };
    let path = out("continuous.svg");
    mds_scatter(&path, &mds, &labels, "ages").unwrap();
    let last = format!("{}", 20 + 3 * (n - 1));
    check_svg(&path, &["#440154", "#FDE725"]);
    let texts = svg_texts(&path);
    for t in ["age (colour scale)", "20", last.as_str(), names[0], names[n - 1]] {
        assert!(texts.iter().any(|x| x == t), "no text {t:?} in {texts:?}");
    }
    for ext in ["svg", "png"] {
        let path = out(&format!("matrix.{ext}"));
        mds_scatter_matrix(&path, &mds, 3, &labels, "three axes").unwrap();
        if ext == "svg" {
            check_svg(&path, &["MDS 1 (", "MDS 2 (", "MDS 3 (", "age (colour scale)"]);
        } else {
            let bytes = std::fs::read(&path).unwrap();
            assert_eq!(&bytes[..8], b"\x89PNG\r\n\x1a\n");
        }
    }
    // more axes than the embedding has, and a word on a continuous scale
    assert!(mds_scatter_matrix(&out("m.png"), &mds, 4, &labels, "t").is_err());
    let mut words = ages.clone();
    words[2] = "old";
    let forced = ScatterLabels {
        color: Some(("age", &words)),
        color_scale: ColorScale::Continuous,
        ..ScatterLabels::default()
    };
    let err = mds_scatter(&out("w.png"), &mds, &forced, "t").unwrap_err().to_string();
    assert!(err.contains("\"old\" of point 2 is not a finite number"), "{err}");
}

#[test]
fn histograms_write_png_and_svg_and_count_correctly() {
    let mut rng = ChaCha8Rng::seed_from_u64(2);
    // Log area distortion of a conformal map (wide) and an area-preserving map (narrow).
    let conformal: Vec<f64> = (0..5000)
        .map(|_| rng.random_range(-1.5..1.5) + rng.random_range(-1.5..1.5))
        .collect();
    let omt: Vec<f64> = (0..3000)
        .map(|_| 0.05 * (rng.random_range(-1.0..1.0) + rng.random_range(-1.0..1.0)))
        .collect();
    let series: [(&str, &[f64]); 2] = [("conformal", &conformal), ("area-preserving (OMT)", &omt)];
    for ext in ["png", "svg"] {
        let path = out(&format!("hist.{ext}"));
        let h = histograms(
            &path,
            &series,
            60,
            Some((-3.0, 3.0)),
            "Area distortion",
            "log(area ratio)",
        )
        .unwrap();
        assert_eq!(h.outside, vec![0, 0]);
        assert_eq!(h.counts[0].iter().sum::<usize>(), 5000);
        if ext == "png" {
            check_png(&path);
        } else {
            check_svg(&path, &["conformal (n=5000)", "log(area ratio)"]);
        }
    }
    // Exact binning: [0, 1) and [1, 2], the last bin closed; 2.5 and NaN fall outside.
    let v = [0.0, 0.5, 0.999, 1.0, 2.0, 2.5, f64::NAN];
    let h = histogram_counts(&[("v", &v)], 2, Some((0.0, 2.0))).unwrap();
    assert_eq!(h.counts[0], vec![3, 2]);
    assert_eq!(h.outside, vec![2]);
    // Automatic range covers all finite values.
    let h = histogram_counts(&[("v", &v)], 5, None).unwrap();
    assert_eq!(h.range, (0.0, 2.5));
    assert_eq!(h.outside, vec![1]);
    assert!(histogram_counts(&[("v", &v)], 0, None).is_err());
    assert!(histogram_counts(&[("v", &v)], 3, Some((1.0, 1.0))).is_err());
}
