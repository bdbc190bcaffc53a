//! Wavefront OBJ: reader and writer for triangle meshes with optional per-vertex UVs.
//!
//! Reading follows the OBJ specification (Wavefront, *Advanced Visualizer* manual, appendix B1)
//! for the statements that describe polygon meshes:
//! - `v x y z [w | r g b]`: a position; components after the third are ignored.
//! - `vt u [v [w]]`: a texture coordinate (`v` defaults to 0).
//! - `vn`: normals are counted (for relative indices) but otherwise ignored.
//! - `f` with corners `a`, `a/b`, `a//c` or `a/b/c`; indices are 1-based, negative indices
//!   are relative to the elements defined so far (`-1` is the last one). Polygons are
//!   fan-triangulated.
//! - `#` comments, blank lines, CRLF line ends; `o`, `g`, `s`, `usemtl`, `mtllib`, `l`, `p`
//!   and any other alphabetic keyword (free-form curves and surfaces, grouping, display
//!   attributes) are ignored. A line starting with anything else (a digit, punctuation, a
//!   control character) is an error: the file is not an OBJ text file.
//! - Line continuation with `\` is not supported (no file in our data uses it).
//!
//! **UVs.** OBJ indexes texture coordinates per face corner, while [`TriMesh::uvs`] is per
//! vertex. The reader returns per-vertex UVs only when every face corner carries a `vt`
//! index and each vertex is always paired with the same texture coordinate (same index or
//! same value); a vertex referenced by no face takes `vt` number `i` when there are exactly
//! as many `vt` as `v` lines. In every other case (UV seams, as in the ICT FaceKit head, or
//! faces without `vt`) `uvs` is `None`: the UVs are ignored, not an error.

use std::io::Write;
use std::path::Path;

use super::{
    check_fans, check_text_line, fan_triangulate, lines, parse_error, parse_f64, parse_i64, parse_vertex, read_bytes,
    show, tokens, Fan,
};
use crate::error::GeometryError;
use crate::mesh::TriMesh;

/// Reads the OBJ file at `path` (see the module documentation for the accepted syntax).
/// Returns #V positions in file order, #F fan-triangulated faces and, when the file defines
/// one texture coordinate per vertex, #V `uvs`.
pub fn read_obj(path: &Path) -> Result<TriMesh, GeometryError> {
    let data = read_bytes(path)?;
    parse_obj(&data, path)
}

/// Where a deferred range check found the largest index: (1-based file index, line).
#[derive(Clone, Copy, Default)]
struct MaxIndex {
    index: usize,
    line: usize,
}

impl MaxIndex {
    fn update(&mut self, index: usize, line: usize) {
        if index > self.index {
            *self = MaxIndex { index, line };
        }
    }
}

/// Parses OBJ text (bytes or `&str`); `path` only labels error messages (`path:line: problem`).
/// Same result as [`read_obj`].
pub fn parse_obj(data: impl AsRef<[u8]>, path: &Path) -> Result<TriMesh, GeometryError> {
    let data = data.as_ref();
    let data = data.strip_prefix(b"\xEF\xBB\xBF").unwrap_or(data); // UTF-8 byte-order mark
    let mut positions: Vec<[f64; 3]> = Vec::new();
    let mut texcoords: Vec<[f64; 2]> = Vec::new();
    let mut num_normals = 0usize;
    let mut faces: Vec<[u32; 3]> = Vec::new();
    // Texture-coordinate index per triangle corner, kept while every corner so far has one.
    let mut face_texcoords: Vec<[u32; 3]> = Vec::new();
    let mut all_corners_have_vt = true;
    // Positive indices may refer forward; they are checked against the final counts.
    let mut max_v = MaxIndex::default();
    let mut max_vt = MaxIndex::default();
    let mut polygon: Vec<u32> = Vec::new();
    let mut fans: Vec<Fan> = Vec::new();
    let mut polygon_vt: Vec<u32> = Vec::new();
    let mut tri_vt: Vec<[u32; 3]> = Vec::new();
    let mut last_line = 0usize;
    // Number of `f` statements so far (polygons, before triangulation).
    let mut num_polygons = 0usize;

    for (line_no, line) in lines(data) {
        last_line = line_no;
        check_text_line(path, line_no, line)?;
        let mut toks = tokens(line);
        let Some(key) = toks.next() else { continue };
        match key {
            b"v" => positions.push(parse_vertex(&mut toks, line_no, positions.len(), path)?),
            b"vt" => texcoords.push(parse_texcoord(&mut toks, line_no, texcoords.len(), path)?),
            b"vn" => num_normals += 1,
            b"f" => {
                polygon.clear();
                polygon_vt.clear();
                let mut corner_count = 0usize;
                for corner in toks {
                    corner_count += 1;
                    let mut parts = corner.split(|&b| b == b'/');
                    let v_tok = parts.next().unwrap_or_default();
                    let vt_tok = parts.next();
                    let vn_tok = parts.next();
                    if parts.next().is_some() || v_tok.is_empty() {
                        return Err(parse_error(
                            path,
                            line_no,
                            format!(
                                "malformed face corner '{}' (expected a, a/b, a//c or a/b/c)",
                                show(corner)
                            ),
                        ));
                    }
                    let v = resolve_index(path, line_no, v_tok, positions.len(), "vertex", &mut max_v)?;
                    polygon.push(v);
                    match vt_tok {
                        Some(t) if !t.is_empty() => {
                            let vt =
                                resolve_index(path, line_no, t, texcoords.len(), "texture coordinate", &mut max_vt)?;
                            polygon_vt.push(vt);
                        }
                        _ => all_corners_have_vt = false,
                    }
                    if let Some(t) = vn_tok.filter(|t| !t.is_empty()) {
                        // Normals are not kept, but the index must be an integer.
                        let n = parse_i64(t).ok_or_else(|| {
                            parse_error(path, line_no, format!("non-integer normal index '{}'", show(t)))
                        })?;
                        if n == 0 || (n < 0 && n.unsigned_abs() as usize > num_normals) {
                            return Err(parse_error(path, line_no, format!("normal index {n} out of range")));
                        }
                    }
                }
                if corner_count < 3 {
                    return Err(parse_error(
                        path,
                        line_no,
                        format!("face {num_polygons} has {corner_count} vertices (need at least 3)"),
                    ));
                }
                fans.extend(Fan::of(num_polygons, polygon.len(), &faces, Some(line_no)));
                fan_triangulate(&polygon, &mut faces);
                num_polygons += 1;
                if all_corners_have_vt {
                    tri_vt.clear();
                    fan_triangulate(&polygon_vt, &mut tri_vt);
                    face_texcoords.extend_from_slice(&tri_vt);
                } else {
                    face_texcoords = Vec::new();
                }
            }
            _ if key[0] == b'#' => {}
            _ if key[0].is_ascii_alphabetic() && key.iter().all(|b| b.is_ascii_alphanumeric() || *b == b'_') => {}
            _ => {
                return Err(parse_error(
                    path,
                    line_no,
                    format!("unrecognised OBJ statement '{}'", show(key)),
                ))
            }
        }
    }

    if positions.is_empty() {
        let message = if faces.is_empty() && texcoords.is_empty() {
            "empty file: no vertices and no faces"
        } else {
            "no vertices ('v' lines)"
        };
        return Err(parse_error(path, last_line.max(1), message));
    }
    if max_v.index > positions.len() {
        return Err(parse_error(
            path,
            max_v.line,
            format!(
                "vertex index {} out of range (the file has {} vertices)",
                max_v.index,
                positions.len()
            ),
        ));
    }
    if max_vt.index > texcoords.len() {
        return Err(parse_error(
            path,
            max_vt.line,
            format!(
                "texture coordinate index {} out of range (the file has {} 'vt' lines)",
                max_vt.index,
                texcoords.len()
            ),
        ));
    }
    if faces.is_empty() {
        return Err(parse_error(path, last_line.max(1), "no faces ('f' lines)"));
    }
    check_fans(path, &positions, &faces, &fans)?;
    let uvs = if all_corners_have_vt && !texcoords.is_empty() {
        per_vertex_uvs(positions.len(), &faces, &face_texcoords, &texcoords)
    } else {
        None
    };
    Ok(TriMesh { positions, faces, uvs })
}

/// Texture coordinate `index`: one or two finite values (a missing v is 0; more are ignored).
fn parse_texcoord<'a>(
    toks: &mut impl Iterator<Item = &'a [u8]>,
    line_no: usize,
    index: usize,
    path: &Path,
) -> Result<[f64; 2], GeometryError> {
    let mut uv = [0.0; 2];
    for (k, c) in uv.iter_mut().enumerate() {
        match toks.next() {
            Some(tok) => {
                *c = parse_f64(tok).ok_or_else(|| {
                    parse_error(
                        path,
                        line_no,
                        format!("texture coordinate {index}: non-numeric value '{}'", show(tok)),
                    )
                })?
            }
            None if k == 0 => {
                return Err(parse_error(
                    path,
                    line_no,
                    format!("texture coordinate {index} has no values"),
                ))
            }
            None => {}
        }
    }
    if !uv.iter().all(|c| c.is_finite()) {
        return Err(parse_error(
            path,
            line_no,
            format!("texture coordinate {index} has a non-finite value"),
        ));
    }
    Ok(uv)
}

/// Resolves an OBJ index token (1-based, or negative relative to the `defined` elements so
/// far) to a 0-based index. Positive indices are range-checked later (through `max`).
fn resolve_index(
    path: &Path,
    line_no: usize,
    token: &[u8],
    defined: usize,
    what: &str,
    max: &mut MaxIndex,
) -> Result<u32, GeometryError> {
    let i = parse_i64(token)
        .ok_or_else(|| parse_error(path, line_no, format!("non-integer {what} index '{}'", show(token))))?;
    let zero_based = if i > 0 {
        max.update(i as usize, line_no);
        i as u64 - 1
    } else if i < 0 {
        let back = i.unsigned_abs();
        if back > defined as u64 {
            return Err(parse_error(
                path,
                line_no,
                format!("relative {what} index {i} points before the first {what} (only {defined} defined so far)"),
            ));
        }
        defined as u64 - back
    } else {
        return Err(parse_error(
            path,
            line_no,
            format!("{what} index 0 is invalid (OBJ indices start at 1)"),
        ));
    };
    u32::try_from(zero_based).map_err(|_| {
        parse_error(
            path,
            line_no,
            format!("{what} index {i} is too large (more than 2^32 elements)"),
        )
    })
}

/// Per-vertex UVs when every vertex is paired with one texture coordinate (see the module
/// documentation), else `None`.
fn per_vertex_uvs(
    num_vertices: usize,
    faces: &[[u32; 3]],
    face_texcoords: &[[u32; 3]],
    texcoords: &[[f64; 2]],
) -> Option<Vec<[f64; 2]>> {
    if face_texcoords.len() != faces.len() {
        return None;
    }
    let mut vt_of_vertex = vec![u32::MAX; num_vertices];
    for (face, vts) in faces.iter().zip(face_texcoords) {
        for (&v, &vt) in face.iter().zip(vts) {
            let slot = &mut vt_of_vertex[v as usize];
            if *slot == u32::MAX {
                *slot = vt;
            } else if *slot != vt && texcoords[*slot as usize] != texcoords[vt as usize] {
                return None;
            }
        }
    }
    vt_of_vertex
        .iter()
        .enumerate()
        .map(|(i, &vt)| {
            if vt != u32::MAX {
                Some(texcoords[vt as usize])
            } else if texcoords.len() == num_vertices {
                Some(texcoords[i])
            } else {
                None
            }
        })
        .collect()
}

/// Writes `mesh` as OBJ to `path`: one `v x y z` line per vertex, then, when `mesh.uvs` is
/// `Some`, one `vt u v` line per vertex and faces `f a/a b/b c/c`, else faces `f a b c`
/// (1-based). Floats use the shortest representation that reads back exactly.
pub fn write_obj(path: &Path, mesh: &TriMesh) -> Result<(), GeometryError> {
    super::write_file(path, mesh, |w| write_obj_to(w, mesh))
}

/// Writes `mesh` as OBJ text to `writer` (the format of [`write_obj`]; no validation).
pub fn write_obj_to<W: Write>(mut writer: W, mesh: &TriMesh) -> std::io::Result<()> {
    writeln!(
        writer,
        "# {} vertices, {} triangles (shapespace)",
        mesh.num_vertices(),
        mesh.num_faces()
    )?;
    for [x, y, z] in &mesh.positions {
        writeln!(writer, "v {x:?} {y:?} {z:?}")?;
    }
    match &mesh.uvs {
        Some(uvs) => {
            for [u, v] in uvs {
                writeln!(writer, "vt {u:?} {v:?}")?;
            }
            for [a, b, c] in &mesh.faces {
                let (a, b, c) = (a + 1, b + 1, c + 1);
                writeln!(writer, "f {a}/{a} {b}/{b} {c}/{c}")?;
            }
        }
        None => {
            for [a, b, c] in &mesh.faces {
                writeln!(writer, "f {} {} {}", a + 1, b + 1, c + 1)?;
            }
        }
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    fn parse(text: &str) -> Result<TriMesh, GeometryError> {
        parse_obj(text, Path::new("t.obj"))
    }

    #[test]
    fn all_corner_forms_and_negative_indices() {
        let text = "v 0 0 0\nv 1 0 0\nv 1 1 0 1.0\nv 0 1 0 0.5 0.5 0.5\nvt 0 0\nvt 1 0\nvt 1 1\nvt 0 1\nvn 0 0 1\n\
                    f 1 2 3\nf 1/1 3/3 4/4\nf 1//1 2//1 4//1\nf -4/-4/-1 -3/-3/-1 -2/-2/-1\n";
        let m = parse(text).unwrap();
        assert_eq!(m.positions.len(), 4);
        assert_eq!(m.faces, vec![[0, 1, 2], [0, 2, 3], [0, 1, 3], [0, 1, 2]]);
        // Some corners have no vt: UVs are ignored.
        assert_eq!(m.uvs, None);
    }

    #[test]
    fn ignored_statements_and_byte_order_mark() {
        let text =
            "\u{feff}# c\nmtllib m.mtl\no obj\ng grp\ns off\nusemtl mat\n\tv 0 0 0\nv 1 0 0\nv 0 1 0\nl 1 2\np 3\n\
                    vp 0.5\nf 1 2 3\n";
        let m = parse(text).unwrap();
        assert_eq!((m.positions.len(), m.faces.len()), (3, 1));
    }

    #[test]
    fn quad_is_fan_triangulated_and_uvs_are_per_vertex() {
        let text = "v 0 0 0\nv 1 0 0\nv 1 1 0\nv 0 1 0\nvt 0.5 0.25\nvt 0 0\nvt 1 0\nvt 1 1\n\
                    f 1/2 2/3 3/4 4/1\n";
        let m = parse(text).unwrap();
        assert_eq!(m.faces, vec![[0, 1, 2], [0, 2, 3]]);
        assert_eq!(m.uvs, Some(vec![[0.0, 0.0], [1.0, 0.0], [1.0, 1.0], [0.5, 0.25]]));
    }

    #[test]
    fn uv_seam_gives_no_uvs() {
        let text = "v 0 0 0\nv 1 0 0\nv 1 1 0\nvt 0 0\nvt 1 0\nvt 1 1\nvt 2 2\nf 1/1 2/2 3/3\nf 1/4 3/3 2/2\n";
        assert_eq!(parse(text).unwrap().uvs, None);
    }

    #[test]
    fn errors_name_line_and_problem() {
        let e = parse("v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 -4\n").unwrap_err().to_string();
        assert!(
            e.starts_with("t.obj:4:") && e.contains("before the first vertex"),
            "{e}"
        );
        let e = parse("v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 4\nv 1 1 1\nf 1 2 6\n")
            .unwrap_err()
            .to_string();
        assert!(e.starts_with("t.obj:6:") && e.contains("index 6 out of range"), "{e}");
        let e = parse("v 0 0 0\nv 1 nan 0\n").unwrap_err().to_string();
        assert!(
            e.starts_with("t.obj:2:") && e.contains("vertex 1 has a non-finite coordinate"),
            "{e}"
        );
        let e = parse("v 0 0 0\nv 1 0x 0\n").unwrap_err().to_string();
        assert!(e.starts_with("t.obj:2:") && e.contains("non-numeric"), "{e}");
        let e = parse("v 0 0 0\nv 1 0 0\nv 1 1 0\nv 0 1 0\nf 1 2 3 4\nf 1 2\n")
            .unwrap_err()
            .to_string();
        assert!(e.starts_with("t.obj:6:") && e.contains("face 1 has 2 vertices"), "{e}");
        let e = parse("v 0 0 0\nf 0 1 1\n").unwrap_err().to_string();
        assert!(e.contains("index 0"), "{e}");
        assert!(parse("").unwrap_err().to_string().contains("empty file"));
        assert!(parse("v 0 0 0\n").unwrap_err().to_string().contains("no faces"));
        let e = parse("v 0 0 0\n\u{1}\u{2}garbage\n").unwrap_err().to_string();
        assert!(e.starts_with("t.obj:2:") && e.contains("binary"), "{e}");
    }

    #[test]
    fn round_trip_is_exact() {
        let mesh = TriMesh {
            positions: vec![
                [0.1, -2.0 / 3.0, 1e-300],
                [f64::MAX, -0.0, 5e-324],
                [std::f64::consts::PI, 1e22, -7.25],
            ],
            faces: vec![[0, 1, 2], [2, 1, 0]],
            uvs: Some(vec![[0.3, 1.0 / 3.0], [-1e-9, 2.5], [0.0, 1e100]]),
        };
        let mut buf = Vec::new();
        write_obj_to(&mut buf, &mesh).unwrap();
        assert_eq!(parse_obj(&buf, Path::new("m.obj")).unwrap(), mesh);
        let plain = TriMesh { uvs: None, ..mesh };
        let mut buf = Vec::new();
        write_obj_to(&mut buf, &plain).unwrap();
        assert_eq!(parse_obj(&buf, Path::new("m.obj")).unwrap(), plain);
    }
}
