//! Distance-matrix and labels CSV I/O.

use std::path::PathBuf;

use shapespace_analysis::{read_distance_matrix, read_labels, write_distance_matrix, AnalysisError, DistanceMatrix};

fn tmp(name: &str) -> PathBuf {
    let dir = PathBuf::from(env!("CARGO_TARGET_TMPDIR")).join("matrix_io");
    std::fs::create_dir_all(&dir).unwrap();
    dir.join(name)
}

#[test]
fn matrix_round_trip_is_exact_and_keeps_missing_entries() {
    let names: Vec<String> = ["face01", "face 02", "face,03"].iter().map(|s| s.to_string()).collect();
    let values = vec![
        0.0,
        0.1,
        1.0 / 3.0, //
        0.1 + 0.2,
        0.0,
        f64::NAN, //
        1e-20,
        123456789.12345679,
        2.5e17,
    ];
    let d = DistanceMatrix::new(names, values).unwrap();
    let path = tmp("round_trip.csv");
    write_distance_matrix(&path, &d).unwrap();
    let text = std::fs::read_to_string(&path).unwrap();
    assert!(text.starts_with("name,face01,face 02,\"face,03\"\n"), "{text}");
    let back = read_distance_matrix(&path).unwrap();
    assert_eq!(back.names, d.names);
    for (a, b) in back.values.iter().zip(&d.values) {
        assert!(a.to_bits() == b.to_bits() || (a.is_nan() && b.is_nan()), "{a} vs {b}");
    }
    assert_eq!(back.missing_pairs(), vec![]); // (1,2) missing one way only
    assert!((back.symmetric(1, 2) - 123456789.12345679).abs() < 1e-6);
}

#[test]
fn nan_and_empty_cells_are_missing() {
    let path = tmp("missing.csv");
    std::fs::write(&path, "name,a,b,c\na,0,,NaN\nb, 0.5 ,0,nan\nc,,,0\n").unwrap();
    let d = read_distance_matrix(&path).unwrap();
    assert!(d.get(0, 1).is_nan() && d.get(0, 2).is_nan() && d.get(1, 2).is_nan());
    assert_eq!(d.get(1, 0), 0.5);
    assert_eq!(d.missing_pairs(), vec![(0, 2), (1, 2)]);
}

fn parse_error(contents: &str) -> (u64, String) {
    let path = tmp("bad.csv");
    std::fs::write(&path, contents).unwrap();
    match read_distance_matrix(&path) {
        Err(e @ AnalysisError::Parse { line, .. }) => {
            let text = e.to_string();
            assert!(text.starts_with(&format!("{}:{line}: ", path.display())), "{text}");
            (line, text)
        }
        other => panic!("expected a parse error, got {other:?}"),
    }
}

#[test]
fn malformed_matrices_report_path_and_line() {
    let (line, msg) = parse_error("name,a,b\na,0,1\nb,1\n");
    assert_eq!(line, 3);
    assert!(msg.contains("expected 3 cells"), "{msg}");
    let (line, msg) = parse_error("name,a,b\na,0,1\nb,x,0\n");
    assert_eq!(line, 3);
    assert!(msg.contains("\"x\""), "{msg}");
    let (line, msg) = parse_error("name,a,b\na,0,-1\nb,1,0\n");
    assert_eq!(line, 2);
    assert!(msg.contains(">= 0"), "{msg}");
    let (line, msg) = parse_error("name,a,b\nb,0,1\na,1,0\n");
    assert_eq!(line, 2);
    assert!(msg.contains("header order"), "{msg}");
    let (line, _) = parse_error("name,a,b\na,0,1\n");
    assert_eq!(line, 1);
    let (_, msg) = parse_error("name,a,a\na,0,1\na,1,0\n");
    assert!(msg.contains("duplicate"), "{msg}");
    let (_, msg) = parse_error("name,a\na,inf\n");
    assert!(msg.contains("finite"), "{msg}");
    // Bytes that are not UTF-8: said in words, not as the parser's record.
    let path = tmp("binary.csv");
    std::fs::write(&path, b"name,a\na,\xff\xfe0\n").unwrap();
    let text = read_distance_matrix(&path).unwrap_err().to_string();
    assert!(
        text.contains("binary.csv:2:") && text.contains("not valid UTF-8"),
        "{text}"
    );
}

#[test]
fn labels_match_by_exact_name_or_file_stem() {
    let names: Vec<String> = ["face01", "face02.obj", "face03"]
        .iter()
        .map(|s| s.to_string())
        .collect();
    let path = tmp("labels.csv");
    std::fs::write(
        &path,
        "file,identity,expression\n\
         scans/face02.ply,p1,smile\n\
         face03,p2,neutral\n\
         /data/face01.obj,p1,neutral\n\
         unrelated.obj,p9,x\n",
    )
    .unwrap();
    let l = read_labels(&path, &names).unwrap();
    assert_eq!(l.columns, vec!["identity", "expression"]);
    assert_eq!(l.values[0], vec!["p1", "neutral"]);
    assert_eq!(l.values[1], vec!["p1", "smile"]);
    assert_eq!(l.values[2], vec!["p2", "neutral"]);
    assert_eq!(l.column("expression").unwrap(), vec!["neutral", "smile", "neutral"]);

    // `name` header, a missing shape (unlabeled: empty cells), an ambiguous match.
    std::fs::write(&path, "name,identity\nface01,p1\nface03,p2\n").unwrap();
    let l = read_labels(&path, &names).unwrap();
    assert_eq!(l.column("identity").unwrap(), vec!["p1", "", "p2"]);
    assert_eq!(l.unlabeled, vec!["face02.obj".to_string()]);
    std::fs::write(
        &path,
        "name,identity\nface01,p1\nface02,p1\na/face03.obj,p2\nb/face03.off,p3\n",
    )
    .unwrap();
    let err = read_labels(&path, &names).unwrap_err();
    assert!(
        matches!(
            &err,
            AnalysisError::AmbiguousLabel {
                line: 5,
                first_line: 4,
                ..
            }
        ),
        "{err}"
    );
    // file paths as keys for names with a dot in the stem, and for names that repeat their
    // stem in different folders (both failed to match before: "no label row", "ambiguous")
    let dotted: Vec<String> = vec!["p.a".into(), "p.b".into()];
    std::fs::write(&path, "file,kind\ndots/p.a.ply,A\ndots/p.b.ply,B\n").unwrap();
    assert_eq!(read_labels(&path, &dotted).unwrap().column("kind").unwrap(), ["A", "B"]);
    let folders: Vec<String> = vec!["x/p".into(), "y/p".into(), "plate121".into()];
    std::fs::write(
        &path,
        "file,kind\ndata/x/p.ply,X\ndata/y/p.ply,Y\ndatasets/disks/plate121.ply,Z\n",
    )
    .unwrap();
    assert_eq!(
        read_labels(&path, &folders).unwrap().column("kind").unwrap(),
        ["X", "Y", "Z"]
    );
    // a bare stem two shapes share names neither
    std::fs::write(&path, "file,kind\np.ply,X\nplate121,Z\n").unwrap();
    let l = read_labels(&path, &folders).unwrap();
    assert_eq!(l.unlabeled, ["x/p", "y/p"]);
    assert_eq!(l.column("kind").unwrap(), ["", "", "Z"]);
    std::fs::write(&path, "shape,identity\nface01,p1\n").unwrap();
    assert!(matches!(
        read_labels(&path, &names),
        Err(AnalysisError::Parse { line: 1, .. })
    ));
    std::fs::write(&path, "file,identity\nface01,p1,extra\n").unwrap();
    assert!(matches!(
        read_labels(&path, &names),
        Err(AnalysisError::Parse { line: 2, .. })
    ));
}

#[test]
fn matrix_constructor_validates() {
    let names = || vec!["a".to_string(), "b".to_string()];
    assert!(matches!(
        DistanceMatrix::new(names(), vec![0.0; 3]),
        Err(AnalysisError::NotSquare { .. })
    ));
    assert!(matches!(
        DistanceMatrix::new(vec!["a".into(), "a".into()], vec![0.0; 4]),
        Err(AnalysisError::DuplicateName { .. })
    ));
    let err = DistanceMatrix::new(names(), vec![0.0, -1.0, 1.0, 0.0]).unwrap_err();
    assert!(matches!(&err, AnalysisError::InvalidDistance { a, b, .. } if a == "a" && b == "b"));
    assert!(DistanceMatrix::from_rows(names(), &[vec![0.0, 1.0], vec![1.0]]).is_err());
}
