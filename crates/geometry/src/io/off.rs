//! OFF (Object File Format, Geomview): reader and writer, ASCII only.
//!
//! Accepted layout (Geomview's `OFF(5)` manual page, restricted to 3-D ASCII files):
//! ```text
//! OFF                      # or COFF, NOFF, CNOFF, STOFF, ...: colour/normal/texture flags
//! nv nf [ne]               # may also follow the keyword on the same line: "OFF nv nf ne"
//! x y z [extra values]     # nv vertex lines; values after the third are ignored
//! k i1 ... ik [colour]     # nf faces, k >= 3, 0-based indices; fan-triangulated
//! ```
//! The keyword line may be missing altogether (the file then starts with the counts), `#`
//! starts a comment anywhere, blank lines are skipped and CRLF line ends are accepted. The
//! reader is line based (one vertex or face per line), which all our data and all common
//! writers follow and which gives exact line numbers in errors. Binary OFF (`OFF BINARY`)
//! and other dimensions (`4OFF`, `nOFF`) are reported as unsupported. Data after the declared
//! faces is an error (the header counts are wrong).
//!
//! The TOSCA files (`tosca/*.off`) and libigl's `camelhead.off` (CRLF, trailing spaces after
//! coordinates) use `OFF` on its own line, then `nv nf 0`.

use std::io::Write;
use std::path::Path;

use super::{
    capped_capacity, check_fans, check_text_line, fan_triangulate, is_blank, lines, parse_error, parse_i64,
    parse_vertex, read_bytes, show, tokens, Fan,
};
use crate::error::GeometryError;
use crate::mesh::TriMesh;

/// Reads the ASCII OFF file at `path` (see the module documentation). Returns #V positions in
/// file order and #F fan-triangulated faces; `uvs` is `None`.
pub fn read_off(path: &Path) -> Result<TriMesh, GeometryError> {
    let data = read_bytes(path)?;
    parse_off(&data, path)
}

/// The lines of an OFF file that carry data: comments removed, blank lines skipped, binary
/// data rejected. Yields `(line number, content)`.
struct ContentLines<'a, I: Iterator<Item = (usize, &'a [u8])>> {
    inner: I,
    path: &'a Path,
    last_line: usize,
}

impl<'a, I: Iterator<Item = (usize, &'a [u8])>> ContentLines<'a, I> {
    fn next_line(&mut self) -> Result<Option<(usize, &'a [u8])>, GeometryError> {
        for (line_no, line) in self.inner.by_ref() {
            self.last_line = line_no;
            check_text_line(self.path, line_no, line)?;
            let content = match line.iter().position(|&b| b == b'#') {
                Some(k) => &line[..k],
                None => line,
            };
            if !is_blank(content) {
                return Ok(Some((line_no, content)));
            }
        }
        Ok(None)
    }
}

/// Parses OFF text (bytes or `&str`); `path` only labels error messages (`path:line: problem`).
/// Same result as [`read_off`].
pub fn parse_off(data: impl AsRef<[u8]>, path: &Path) -> Result<TriMesh, GeometryError> {
    let data = data.as_ref();
    let data = data.strip_prefix(b"\xEF\xBB\xBF").unwrap_or(data); // UTF-8 byte-order mark
    let mut src = ContentLines {
        inner: lines(data),
        path,
        last_line: 0,
    };
    let eof_line = |src: &ContentLines<'_, _>| src.last_line + 1;

    let (num_vertices, num_polygons) = read_header(&mut src, path)?;

    // Vertices: the shortest line "0 0 0\n" takes 6 bytes, a face "3 0 0 0\n" 8.
    let mut positions = Vec::with_capacity(capped_capacity(num_vertices, data.len(), 6));
    for vertex in 0..num_vertices {
        let Some((line_no, line)) = src.next_line()? else {
            return Err(parse_error(
                path,
                eof_line(&src),
                format!("unexpected end of file: the header declares {num_vertices} vertices, found {vertex}"),
            ));
        };
        positions.push(parse_vertex(&mut tokens(line), line_no, vertex, path)?);
    }

    let mut faces = Vec::with_capacity(capped_capacity(num_polygons, data.len(), 8));
    let mut polygon: Vec<u32> = Vec::new();
    let mut fans: Vec<Fan> = Vec::new();
    for face in 0..num_polygons {
        let Some((line_no, line)) = src.next_line()? else {
            return Err(parse_error(
                path,
                eof_line(&src),
                format!("unexpected end of file: the header declares {num_polygons} faces, found {face}"),
            ));
        };
        parse_face(line, line_no, face, num_vertices, &mut polygon, path)?;
        fans.extend(Fan::of(face, polygon.len(), &faces, Some(line_no)));
        fan_triangulate(&polygon, &mut faces);
    }
    if let Some((line_no, line)) = src.next_line()? {
        return Err(parse_error(
            path,
            line_no,
            format!(
                "data after the {num_polygons} faces declared in the header ('{}'); wrong counts?",
                show(line.trim_ascii())
            ),
        ));
    }
    check_fans(path, &positions, &faces, &fans)?;
    Ok(TriMesh {
        positions,
        faces,
        uvs: None,
    })
}

/// The header: the optional keyword, then the counts on the same or the next content line.
/// Returns the vertex and face counts.
fn read_header<'a, I: Iterator<Item = (usize, &'a [u8])>>(
    src: &mut ContentLines<'a, I>,
    path: &Path,
) -> Result<(usize, usize), GeometryError> {
    let Some((mut line_no, first)) = src.next_line()? else {
        return Err(parse_error(path, 1, "empty file: no OFF header"));
    };
    let mut toks: Vec<&[u8]> = tokens(first).collect();
    let has_keyword = toks[0][0].is_ascii_alphabetic() || (toks[0][0].is_ascii_digit() && toks[0].ends_with(b"OFF"));
    if !has_keyword && parse_i64(toks[0]).is_none() {
        return Err(parse_error(
            path,
            line_no,
            format!(
                "not an OFF file: expected 'OFF' or the counts, found '{}'",
                show(toks[0])
            ),
        ));
    }
    if has_keyword {
        let key = toks[0];
        let prefix = key.strip_suffix(b"OFF").ok_or_else(|| {
            parse_error(
                path,
                line_no,
                format!("not an OFF file: expected 'OFF' or the counts, found '{}'", show(key)),
            )
        })?;
        if !prefix.iter().all(|b| b"STCN".contains(b)) {
            return Err(GeometryError::UnsupportedFormat {
                path: path.to_path_buf(),
                message: format!(
                    "OFF variant '{}' (only 3-D OFF, COFF, NOFF, STOFF... are read)",
                    show(key)
                ),
            });
        }
        if toks.get(1).is_some_and(|t| t.eq_ignore_ascii_case(b"BINARY")) {
            return Err(GeometryError::UnsupportedFormat {
                path: path.to_path_buf(),
                message: "binary OFF is not supported; convert it to ASCII OFF or PLY".to_string(),
            });
        }
        toks.remove(0);
        if toks.is_empty() {
            let Some((l, counts)) = src.next_line()? else {
                return Err(parse_error(
                    path,
                    src.last_line + 1,
                    "unexpected end of file: missing the vertex and face counts",
                ));
            };
            line_no = l;
            toks = tokens(counts).collect();
        }
    }
    if toks.len() < 2 || toks.len() > 3 {
        return Err(parse_error(
            path,
            line_no,
            format!("expected the counts 'nv nf [ne]', found {} values", toks.len()),
        ));
    }
    let count = |k: usize, what: &str| -> Result<usize, GeometryError> {
        parse_i64(toks[k])
            .and_then(|n| usize::try_from(n).ok())
            .ok_or_else(|| parse_error(path, line_no, format!("invalid {what} count '{}'", show(toks[k]))))
    };
    let num_vertices = count(0, "vertex")?;
    let num_polygons = count(1, "face")?;
    if num_vertices == 0 {
        return Err(parse_error(path, line_no, "the header declares 0 vertices"));
    }
    if num_polygons == 0 {
        return Err(parse_error(path, line_no, "the header declares 0 faces"));
    }
    if u32::try_from(num_vertices).is_err() {
        return Err(parse_error(
            path,
            line_no,
            format!("{num_vertices} vertices exceed the u32 index range"),
        ));
    }
    Ok((num_vertices, num_polygons))
}

/// One face line: its vertex count k ≥ 3 and k indices below `num_vertices`, into `polygon`
/// (values after them, a face colour, are ignored).
fn parse_face(
    line: &[u8],
    line_no: usize,
    face: usize,
    num_vertices: usize,
    polygon: &mut Vec<u32>,
    path: &Path,
) -> Result<(), GeometryError> {
    let mut toks = tokens(line);
    let k_tok = toks.next().unwrap_or_default();
    let k = parse_i64(k_tok).ok_or_else(|| {
        parse_error(
            path,
            line_no,
            format!("face {face}: non-integer vertex count '{}'", show(k_tok)),
        )
    })?;
    if k < 3 {
        return Err(parse_error(
            path,
            line_no,
            format!("face {face} has {k} vertices (need at least 3)"),
        ));
    }
    polygon.clear();
    for j in 0..k {
        let tok = toks.next().ok_or_else(|| {
            parse_error(
                path,
                line_no,
                format!("face {face} declares {k} vertices but lists {j}"),
            )
        })?;
        let i = parse_i64(tok).ok_or_else(|| {
            parse_error(
                path,
                line_no,
                format!("face {face}: non-integer vertex index '{}'", show(tok)),
            )
        })?;
        if i < 0 || i as u64 >= num_vertices as u64 {
            return Err(parse_error(
                path,
                line_no,
                format!("face {face}: vertex index {i} out of range (the file has {num_vertices} vertices)"),
            ));
        }
        polygon.push(i as u32);
    }
    Ok(())
}

/// Writes `mesh` as ASCII OFF to `path`: `OFF`, `nv nf 0`, one `x y z` line per vertex, one
/// `3 a b c` line per face (0-based). Floats use the shortest representation that reads back
/// exactly. UVs are not written (OFF has no per-vertex UV field in its basic form).
pub fn write_off(path: &Path, mesh: &TriMesh) -> Result<(), GeometryError> {
    super::write_file(path, mesh, |w| write_off_to(w, mesh))
}

/// Writes `mesh` as OFF text to `writer` (the format of [`write_off`]; no validation).
pub fn write_off_to<W: Write>(mut writer: W, mesh: &TriMesh) -> std::io::Result<()> {
    writeln!(writer, "OFF")?;
    writeln!(writer, "{} {} 0", mesh.num_vertices(), mesh.num_faces())?;
    for [x, y, z] in &mesh.positions {
        writeln!(writer, "{x:?} {y:?} {z:?}")?;
    }
    for [a, b, c] in &mesh.faces {
        writeln!(writer, "3 {a} {b} {c}")?;
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    fn parse(text: &str) -> Result<TriMesh, GeometryError> {
        parse_off(text, Path::new("t.off"))
    }

    #[test]
    fn header_variants() {
        let body = "0 0 0\n1 0 0\n1 1 0\n0 1 0\n4 0 1 2 3\n3 0 2 1 255 0 0\n";
        let expected_faces = vec![[0, 1, 2], [0, 2, 3], [0, 2, 1]];
        for header in [
            "OFF\n4 2 0\n",
            "OFF 4 2 0\n",
            "4 2 0\n",
            "# c\nCOFF\r\n\n4 2\n",
            "NOFF # n\n4 2 5\n",
        ] {
            let m = parse(&format!("{header}{body}")).unwrap();
            assert_eq!(m.positions.len(), 4, "{header}");
            assert_eq!(m.faces, expected_faces, "{header}");
        }
        let e = parse("OFF BINARY\n").unwrap_err().to_string();
        assert!(e.contains("t.off") && e.contains("binary OFF"), "{e}");
        let e = parse("4OFF\n").unwrap_err().to_string();
        assert!(e.contains("unsupported"), "{e}");
        let e = parse("PLY\n").unwrap_err().to_string();
        assert!(e.starts_with("t.off:1:") && e.contains("not an OFF file"), "{e}");
    }

    #[test]
    fn errors_name_line_and_problem() {
        let e = parse("OFF\n3 1 0\n0 0 0\n1 0 0\n").unwrap_err().to_string();
        assert!(
            e.starts_with("t.off:5:") && e.contains("declares 3 vertices, found 2"),
            "{e}"
        );
        let e = parse("OFF\n3 2 0\n0 0 0\n1 0 0\n0 1 0\n3 0 1 2\n")
            .unwrap_err()
            .to_string();
        assert!(
            e.starts_with("t.off:7:") && e.contains("declares 2 faces, found 1"),
            "{e}"
        );
        let e = parse("OFF\n3 1 0\n0 0 0\n1 inf 0\n0 1 0\n3 0 1 2\n")
            .unwrap_err()
            .to_string();
        assert!(
            e.starts_with("t.off:4:") && e.contains("vertex 1 has a non-finite"),
            "{e}"
        );
        let e = parse("OFF\n3 1 0\n0 0 0\n1 0 0\n0 1 0\n3 0 1 3\n")
            .unwrap_err()
            .to_string();
        assert!(e.starts_with("t.off:6:") && e.contains("index 3 out of range"), "{e}");
        let e = parse("OFF\n3 1 0\n0 0 0\n1 0 0\n0 1 0\n3 0 -1 2\n")
            .unwrap_err()
            .to_string();
        assert!(e.starts_with("t.off:6:") && e.contains("index -1 out of range"), "{e}");
        let e = parse("OFF\n3 1 0\n0 0 0\n1 0 0\n0 1 0\n2 0 1\n")
            .unwrap_err()
            .to_string();
        assert!(e.starts_with("t.off:6:") && e.contains("2 vertices"), "{e}");
        let e = parse("OFF\n3 1 0\n0 0 0\n1 0 0\n0 1 0\n3 0 1 2\n3 0 1 2\n")
            .unwrap_err()
            .to_string();
        assert!(e.starts_with("t.off:7:") && e.contains("wrong counts"), "{e}");
        let e = parse("OFF\n99999999999 1 0\n0 0 0\n").unwrap_err().to_string();
        assert!(e.contains("exceed"), "{e}");
        let e = parse("OFF\n999999999 1 0\n0 0 0\n").unwrap_err().to_string();
        assert!(e.starts_with("t.off:4:") && e.contains("end of file"), "{e}");
        assert!(parse("").unwrap_err().to_string().contains("empty file"));
        assert!(parse("  \n# only a comment\n")
            .unwrap_err()
            .to_string()
            .contains("empty file"));
    }

    #[test]
    fn round_trip_is_exact() {
        let mesh = TriMesh {
            positions: vec![
                [0.1, -2.0 / 3.0, 1e-300],
                [f64::MAX, -0.0, 5e-324],
                [1.0, 1e22, -7.25],
                [9.0, 9.0, 9.0],
            ],
            faces: vec![[0, 1, 2], [2, 1, 0]],
            uvs: None,
        };
        let mut buf = Vec::new();
        write_off_to(&mut buf, &mesh).unwrap();
        assert_eq!(parse_off(&buf, Path::new("m.off")).unwrap(), mesh);
    }
}
