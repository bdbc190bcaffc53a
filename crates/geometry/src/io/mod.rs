//! Mesh readers and writers: Wavefront OBJ, OFF and PLY (ASCII, binary little- and big-endian).
//!
//! All readers return a [`TriMesh`] whose vertex `i` is the `i`-th vertex of the file: indices
//! are never renumbered and unreferenced vertices are kept, so files sharing a connectivity
//! (pose sets, morphable-model samples) correspond by index. Polygons are fan-triangulated,
//! $(v_0, v_{k}, v_{k+1})$ for $k = 1, \dots, n-2$, which keeps the polygon's orientation. A
//! polygon whose fan would overlap itself (a fan triangle facing the opposite way of the
//! polygon's vector area: a nearly planar polygon, not convex and not star-shaped from its first
//! corner) is an error naming the polygon, since its triangles would cover the wrong area
//! (`check_fans`).
//!
//! Readers only reject syntactic and numeric problems: truncated files, counts that disagree
//! with the data, non-numeric tokens, NaN or infinite coordinates, vertex indices out of range,
//! faces with fewer than three vertices, empty files, binary data where text is expected and
//! unknown formats. Topological defects (non-manifold edges or vertices, inconsistent
//! orientation, repeated indices in a face) read fine and are left to
//! [`crate::topology`]. Every error names the file and the line (text) or byte offset and
//! element index (binary PLY): `path:line: problem` or `path: byte N: element i: problem`.
//! No reader panics on any input, and pre-allocation is capped by the file size, so a header
//! declaring $10^{12}$ vertices costs nothing before the truncation is reported.
//!
//! Writers go through [`atomic`]: a temporary file beside the destination, renamed over it once
//! complete, never through a symbolic link. They print coordinates with Rust's shortest
//! round-trip formatting (`{:?}`) in text formats and as raw `f64` in binary PLY, so every `f64`
//! reads back bit for bit.
//!
//! | format | read | write |
//! |---|---|---|
//! | OBJ ([`obj`]) | `v`, `vt`, `f` with `a`, `a/b`, `a//c`, `a/b/c`, negative indices | `v`, optional `vt`, `f` |
//! | OFF ([`off`]) | `OFF`/`COFF`/`NOFF`/... header or none, `#` comments, polygon faces | `OFF` |
//! | PLY ([`ply`]) | ascii, binary LE/BE, any scalar types, `face` and `tristrips` lists | ascii, binary LE/BE (`f64`) |

pub mod atomic;
pub mod obj;
pub mod off;
pub mod ply;

use std::path::{Path, PathBuf};

use crate::error::GeometryError;
use crate::mesh::TriMesh;

pub use atomic::{replace_atomically, write_atomically, AtomicFile};
pub use obj::{parse_obj, read_obj, write_obj, write_obj_to};
pub use off::{parse_off, read_off, write_off, write_off_to};
pub use ply::{parse_ply, read_ply, write_ply, write_ply_to, PlyFormat};

/// A mesh file format, chosen from a file extension.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum MeshFormat {
    /// Wavefront OBJ (`.obj`).
    Obj,
    /// Object File Format (`.off`).
    Off,
    /// Polygon File Format / Stanford PLY (`.ply`).
    Ply,
}

impl MeshFormat {
    /// The format named by the extension of `path` (`.obj`, `.off`, `.ply`, case-insensitive),
    /// or [`GeometryError::UnsupportedFormat`] for any other or no extension.
    pub fn from_path(path: &Path) -> Result<Self, GeometryError> {
        let ext = path.extension().and_then(|e| e.to_str()).map(str::to_ascii_lowercase);
        match ext.as_deref() {
            Some("obj") => Ok(MeshFormat::Obj),
            Some("off") => Ok(MeshFormat::Off),
            Some("ply") => Ok(MeshFormat::Ply),
            Some(other) => Err(GeometryError::UnsupportedFormat {
                path: path.to_path_buf(),
                message: format!("unknown extension '.{other}'; expected .obj, .off or .ply"),
            }),
            None => Err(GeometryError::UnsupportedFormat {
                path: path.to_path_buf(),
                message: "no file extension; expected .obj, .off or .ply".to_string(),
            }),
        }
    }
}

/// Reads a triangle mesh from `path`, choosing the reader by extension (`.obj`, `.off`, `.ply`,
/// case-insensitive). Returns #V positions in file order and #F triangles (polygons
/// fan-triangulated); see the module documentation for what is an error.
pub fn read_mesh(path: &Path) -> Result<TriMesh, GeometryError> {
    parse_mesh(read_mesh_bytes(path)?, path)
}

/// The bytes of the mesh file at `path`, for [`parse_mesh`] (after checking that its extension
/// names a format): [`read_mesh`] in two steps, so that a caller can also hash exactly the
/// bytes it parses.
pub fn read_mesh_bytes(path: &Path) -> Result<Vec<u8>, GeometryError> {
    MeshFormat::from_path(path)?;
    read_bytes(path)
}

/// Parses mesh bytes in the format named by `path`'s extension (`path` also labels error
/// messages); the same result as [`read_mesh`] on a file holding them.
pub fn parse_mesh(data: impl AsRef<[u8]>, path: &Path) -> Result<TriMesh, GeometryError> {
    match MeshFormat::from_path(path)? {
        MeshFormat::Obj => parse_obj(data, path),
        MeshFormat::Off => parse_off(data, path),
        MeshFormat::Ply => parse_ply(data, path),
    }
}

/// Writes `mesh` to `path` in the format named by its extension. PLY files are written as
/// binary little-endian (use [`write_ply`] for ASCII). The mesh is validated first
/// ([`TriMesh::validate`]): indices in range, finite coordinates.
pub fn write_mesh(path: &Path, mesh: &TriMesh) -> Result<(), GeometryError> {
    match MeshFormat::from_path(path)? {
        MeshFormat::Obj => write_obj(path, mesh),
        MeshFormat::Off => write_off(path, mesh),
        MeshFormat::Ply => write_ply(path, mesh, PlyFormat::BinaryLittleEndian),
    }
}

// ---------------------------------------------------------------------------------------------
// Helpers shared by the readers and writers.

/// Reads a whole file, mapping failures to [`GeometryError::Io`].
/// A device or a socket is refused before reading (`/dev/zero` would be read without end);
/// a named pipe is read.
pub(crate) fn read_bytes(path: &Path) -> Result<Vec<u8>, GeometryError> {
    let io_err = |error| GeometryError::Io {
        path: path.to_path_buf(),
        error,
    };
    #[cfg(unix)]
    {
        use std::os::unix::fs::FileTypeExt;
        let kind = std::fs::metadata(path).map_err(io_err)?.file_type();
        if kind.is_char_device() || kind.is_block_device() || kind.is_socket() {
            return Err(io_err(std::io::Error::new(
                std::io::ErrorKind::InvalidInput,
                "not a regular file (a device or a socket); name a mesh file",
            )));
        }
    }
    std::fs::read(path).map_err(io_err)
}

/// Validates `mesh` and runs `write` on an [`AtomicFile`] for `path` (the previous file stays
/// whole if anything fails), mapping I/O failures to [`GeometryError::Io`].
pub(crate) fn write_file(
    path: &Path,
    mesh: &TriMesh,
    write: impl FnOnce(&mut AtomicFile) -> std::io::Result<()>,
) -> Result<(), GeometryError> {
    mesh.validate().map_err(|e| e.with_path(path))?;
    let io_err = |error| GeometryError::Io {
        path: path.to_path_buf(),
        error,
    };
    let mut file = AtomicFile::create(path).map_err(io_err)?;
    write(&mut file).map_err(io_err)?;
    file.commit().map_err(io_err)
}

/// A [`GeometryError::Parse`] at `line` (1-based) of `path`.
pub(crate) fn parse_error(path: &Path, line: usize, message: impl Into<String>) -> GeometryError {
    GeometryError::Parse {
        path: PathBuf::from(path),
        line,
        message: message.into(),
    }
}

/// Lines of a text file as `(1-based line number, bytes)`, split at `\n` with a trailing `\r`
/// removed (CRLF files).
pub(crate) fn lines(data: &[u8]) -> impl Iterator<Item = (usize, &[u8])> {
    // A final newline does not start another (empty) line.
    let data = data.strip_suffix(b"\n").unwrap_or(data);
    data.split(|&b| b == b'\n')
        .enumerate()
        .map(|(i, line)| (i + 1, line.strip_suffix(b"\r").unwrap_or(line)))
        .filter(move |_| !data.is_empty())
}

/// Whitespace-separated tokens of a line.
pub(crate) fn tokens(line: &[u8]) -> impl Iterator<Item = &[u8]> {
    line.split(|b| b.is_ascii_whitespace()).filter(|t| !t.is_empty())
}

/// Rejects a line holding control characters (other than tab, vertical tab, form feed and
/// carriage return): binary data in a file read as text. A carriage return left inside a line
/// (the one of a CRLF line ending is removed before) is refused on its own: it would split the
/// token it sits in (`-0.6\r427` read as two numbers), and a file with CR-only line endings
/// reads as one line.
pub(crate) fn check_text_line(path: &Path, line_no: usize, line: &[u8]) -> Result<(), GeometryError> {
    if let Some(&b) = line
        .iter()
        .find(|&&b| (b < 0x20 && !matches!(b, b'\t' | b'\r' | 0x0b | 0x0c)) || b == 0x7f)
    {
        return Err(parse_error(
            path,
            line_no,
            format!("binary data (byte 0x{b:02x}) in a text file; not a text mesh file or corrupted"),
        ));
    }
    if line.contains(&b'\r') {
        return Err(parse_error(
            path,
            line_no,
            "carriage return (\\r) inside a line: a corrupted number or CR-only line endings; convert the file to LF or CRLF line endings",
        ));
    }
    Ok(())
}

/// A token for an error message: lossy UTF-8, cut to 40 characters.
pub(crate) fn show(token: &[u8]) -> String {
    let s = String::from_utf8_lossy(token);
    if s.chars().count() > 40 {
        format!("{}...", s.chars().take(40).collect::<String>())
    } else {
        s.into_owned()
    }
}

/// Parses a decimal float token (Rust syntax: `1`, `-2.5e-3`, also `inf` and `nan`, which the
/// callers reject as non-finite).
pub(crate) fn parse_f64(token: &[u8]) -> Option<f64> {
    std::str::from_utf8(token).ok()?.parse().ok()
}

/// Parses a decimal integer token with optional sign.
pub(crate) fn parse_i64(token: &[u8]) -> Option<i64> {
    std::str::from_utf8(token).ok()?.parse().ok()
}

/// The three finite coordinates of vertex `vertex` from the line's next tokens (values after
/// them are ignored), for the OFF and OBJ readers.
pub(crate) fn parse_vertex<'a>(
    toks: &mut impl Iterator<Item = &'a [u8]>,
    line_no: usize,
    vertex: usize,
    path: &Path,
) -> Result<[f64; 3], GeometryError> {
    let mut p = [0.0; 3];
    for (k, c) in p.iter_mut().enumerate() {
        let tok = toks.next().ok_or_else(|| {
            parse_error(
                path,
                line_no,
                format!("vertex {vertex} has {k} coordinates, expected 3"),
            )
        })?;
        *c = parse_f64(tok).ok_or_else(|| {
            parse_error(
                path,
                line_no,
                format!("vertex {vertex}: non-numeric coordinate '{}'", show(tok)),
            )
        })?;
    }
    if !p.iter().all(|c| c.is_finite()) {
        return Err(parse_error(
            path,
            line_no,
            format!("vertex {vertex} has a non-finite coordinate"),
        ));
    }
    Ok(p)
}

/// Whether the bytes are empty or only whitespace.
pub(crate) fn is_blank(data: &[u8]) -> bool {
    data.iter().all(|b| b.is_ascii_whitespace())
}

/// A safe `Vec::with_capacity` length for `declared` items when at most `remaining_bytes`
/// are left and each item takes at least `min_bytes` (guards against headers that lie).
pub(crate) fn capped_capacity(declared: usize, remaining_bytes: usize, min_bytes: usize) -> usize {
    declared.min(remaining_bytes / min_bytes.max(1) + 1)
}

/// Appends the fan triangulation $(v_0, v_k, v_{k+1})$ of `polygon` (at least 3 indices) to
/// `faces`.
pub(crate) fn fan_triangulate(polygon: &[u32], faces: &mut Vec<[u32; 3]>) {
    for k in 1..polygon.len().saturating_sub(1) {
        faces.push([polygon[0], polygon[k], polygon[k + 1]]);
    }
}

/// A polygon of more than three corners as a reader fan-triangulated it: its index among the
/// file's faces, its first triangle in the face list, its corner count and its line (text files).
pub(crate) struct Fan {
    pub polygon: usize,
    pub first: usize,
    pub corners: usize,
    pub line: Option<usize>,
}

impl Fan {
    /// The record of `polygon` (`corners` indices) about to be fan-triangulated into `faces`, or
    /// None for a triangle.
    pub fn of(polygon: usize, corners: usize, faces: &[[u32; 3]], line: Option<usize>) -> Option<Fan> {
        (corners > 3).then_some(Fan {
            polygon,
            first: faces.len(),
            corners,
            line,
        })
    }
}

/// Checks that no fan triangle of a polygon faces the opposite way of the polygon's vector area
/// A (the sum of its fan triangles' cross products n_k, the same for any triangulation of a
/// planar polygon): n_k · A < −0.9 |n_k| |A|. In a planar polygon that is a fan that overlaps
/// itself (the first corner does not see the whole polygon), whose triangles cover more than
/// the polygon without any other sign. Non-planar polygons whose triangles merely bend (the
/// ICT FaceKit neutral mesh has one quad of 25,836 folded by 115°, cos −0.36 against A) are
/// left alone: any triangulation of them is a choice. A polygon whose fan triangles cancel
/// (|A| ≤ 1e-10 Σ|n_k| with some n_k ≠ 0: a self-crossing bow tie) is an error too. Triangles of
/// zero area up to rounding (collinear corners) are left to the degenerate-face checks of
/// [`crate::topology`].
pub(crate) fn check_fans(
    path: &Path,
    positions: &[[f64; 3]],
    faces: &[[u32; 3]],
    fans: &[Fan],
) -> Result<(), GeometryError> {
    use crate::vec3::{add, cross, dot, norm, sub};
    for fan in fans {
        let triangles = &faces[fan.first..fan.first + fan.corners - 2];
        // per fan triangle: its cross product n_k and the product of its two edge lengths
        let normals: Vec<([f64; 3], f64)> = triangles
            .iter()
            .map(|t| {
                let [a, b, c] = t.map(|v| positions[v as usize]);
                (cross(sub(b, a), sub(c, a)), norm(sub(b, a)) * norm(sub(c, a)))
            })
            .collect();
        let area = normals.iter().fold([0.0; 3], |s, (n, _)| add(s, *n));
        let total: f64 = normals.iter().map(|(n, _)| norm(*n)).sum();
        let at = |message: String| match fan.line {
            Some(line) => parse_error(path, line, message),
            None => GeometryError::WithPath {
                path: path.to_path_buf(),
                error: Box::new(GeometryError::Invalid(message)),
            },
        };
        // triangles that cancel (a bow tie): no vector area to compare with
        if total > 0.0 && !(norm(area) > 1e-10 * total) {
            return Err(at(format!(
                "face {} (a polygon of {} corners) crosses itself: its fan triangles cancel; \
                 split it into simple polygons first",
                fan.polygon, fan.corners
            )));
        }
        for (k, &(n, scale)) in normals.iter().enumerate() {
            if norm(n) > 1e-10 * scale && dot(n, area) < -0.9 * norm(n) * norm(area) {
                return Err(at(format!(
                    "face {} (a polygon of {} corners) is not convex: its fan triangle {k} from the \
                     first corner faces against the polygon, so the triangles would overlap; \
                     triangulate it first",
                    fan.polygon, fan.corners
                )));
            }
        }
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn lines_strip_crlf_and_number_from_one() {
        let got: Vec<(usize, &[u8])> = lines(b"a\r\nb\n\nc").collect();
        assert_eq!(got, vec![(1, &b"a"[..]), (2, &b"b"[..]), (3, &b""[..]), (4, &b"c"[..])]);
        let got: Vec<(usize, &[u8])> = lines(b"a\n").collect();
        assert_eq!(got, vec![(1, &b"a"[..])]);
        assert_eq!(lines(b"").count(), 0);
    }

    #[test]
    fn extension_dispatch_is_case_insensitive() {
        assert_eq!(MeshFormat::from_path(Path::new("a/B.OBJ")).unwrap(), MeshFormat::Obj);
        assert_eq!(MeshFormat::from_path(Path::new("x.Off")).unwrap(), MeshFormat::Off);
        assert_eq!(MeshFormat::from_path(Path::new("x.ply")).unwrap(), MeshFormat::Ply);
        let err = MeshFormat::from_path(Path::new("x.stl")).unwrap_err().to_string();
        assert!(err.contains("x.stl") && err.contains(".stl"), "{err}");
        assert!(MeshFormat::from_path(Path::new("noext")).is_err());
    }

    #[test]
    fn fan_triangulation_of_a_pentagon() {
        let mut faces = Vec::new();
        fan_triangulate(&[4, 5, 6, 7, 8], &mut faces);
        assert_eq!(faces, vec![[4, 5, 6], [4, 6, 7], [4, 7, 8]]);
    }
}
