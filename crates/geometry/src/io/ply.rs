//! PLY (Polygon File Format, Turk 1994): reader for ASCII, binary little-endian and binary
//! big-endian files; writer for all three.
//!
//! **Reader.** The header (`ply`, `format`, `comment`/`obj_info`, `element`, `property`,
//! `end_header`) is parsed in full, so every element and property is known with its type
//! before the body is read. Then:
//! - `vertex`: the `x`, `y`, `z` properties, of any scalar type (`char`/`int8` ...
//!   `double`/`float64`), become positions; `u`/`v` (or `s`/`t`, `texture_u`/`texture_v`)
//!   become `uvs` when both are present. Other vertex properties (normals, colours, lists)
//!   are skipped.
//! - `face`: the list property `vertex_indices` or `vertex_index`, with any integer count and
//!   index types, gives polygons, fan-triangulated. Other face properties are skipped.
//! - `tristrips`: the same list property holds triangle strips separated by `-1`. Strip
//!   $s_0 s_1 s_2 \dots$ gives triangles $(s_j, s_{j+1}, s_{j+2})$ for even $j$ and
//!   $(s_{j+1}, s_j, s_{j+2})$ for odd $j$ (alternating winding keeps the orientation);
//!   degenerate triangles (a repeated index, used to join strips) are dropped. This is how
//!   `igea.ply` stores its 268,686 triangles.
//! - Any other element is skipped; in binary files its size is known from the header
//!   (scalars by type, lists by their count).
//!
//! ASCII bodies are read one element per line (as every writer we know produces), which gives
//! line numbers in errors; extra or missing values on a line are errors. Binary errors give
//! the byte offset at which the element starts and the element's index. A binary header whose
//! counts need more bytes than the file has is rejected before anything is allocated.
//!
//! **Why hand-written.** `ply-rs-bw` (in the workspace) reads into a `HashMap` per element,
//! about 2.9 s for a 1M-vertex file (CRATES.md), has no `tristrips` support and reports
//! errors without the element index. This reader is a few hundred lines, streams straight
//! into the flat arrays and names the element and byte offset of every problem.

use std::io::Write;
use std::path::{Path, PathBuf};

use super::{
    capped_capacity, check_fans, check_text_line, fan_triangulate, is_blank, parse_error, parse_f64, parse_i64,
    read_bytes, show, tokens, Fan,
};
use crate::error::GeometryError;
use crate::mesh::TriMesh;

/// The encoding of a PLY body.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum PlyFormat {
    /// `format ascii 1.0`: whitespace-separated decimal values, one element per line.
    Ascii,
    /// `format binary_little_endian 1.0`.
    BinaryLittleEndian,
    /// `format binary_big_endian 1.0`.
    BinaryBigEndian,
}

impl PlyFormat {
    fn header_name(self) -> &'static str {
        match self {
            PlyFormat::Ascii => "ascii",
            PlyFormat::BinaryLittleEndian => "binary_little_endian",
            PlyFormat::BinaryBigEndian => "binary_big_endian",
        }
    }
}

/// A PLY scalar type.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum Scalar {
    I8,
    U8,
    I16,
    U16,
    I32,
    U32,
    F32,
    F64,
}

impl Scalar {
    fn from_name(name: &[u8]) -> Option<Scalar> {
        Some(match name {
            b"char" | b"int8" => Scalar::I8,
            b"uchar" | b"uint8" => Scalar::U8,
            b"short" | b"int16" => Scalar::I16,
            b"ushort" | b"uint16" => Scalar::U16,
            b"int" | b"int32" => Scalar::I32,
            b"uint" | b"uint32" => Scalar::U32,
            b"float" | b"float32" => Scalar::F32,
            b"double" | b"float64" => Scalar::F64,
            _ => return None,
        })
    }

    fn size(self) -> usize {
        match self {
            Scalar::I8 | Scalar::U8 => 1,
            Scalar::I16 | Scalar::U16 => 2,
            Scalar::I32 | Scalar::U32 | Scalar::F32 => 4,
            Scalar::F64 => 8,
        }
    }

    fn is_integer(self) -> bool {
        !matches!(self, Scalar::F32 | Scalar::F64)
    }

    /// The value range of an integer type.
    fn range(self) -> (i64, i64) {
        match self {
            Scalar::I8 => (i8::MIN as i64, i8::MAX as i64),
            Scalar::U8 => (0, u8::MAX as i64),
            Scalar::I16 => (i16::MIN as i64, i16::MAX as i64),
            Scalar::U16 => (0, u16::MAX as i64),
            Scalar::I32 => (i32::MIN as i64, i32::MAX as i64),
            Scalar::U32 => (0, u32::MAX as i64),
            Scalar::F32 | Scalar::F64 => (i64::MIN, i64::MAX),
        }
    }
}

#[derive(Clone, Copy, Debug)]
enum Kind {
    Scalar(Scalar),
    List { count: Scalar, item: Scalar },
}

#[derive(Debug)]
struct Property {
    name: String,
    kind: Kind,
}

#[derive(Debug)]
struct Element {
    name: String,
    count: usize,
    properties: Vec<Property>,
}

impl Element {
    /// The fewest bytes one instance takes in a binary body (lists counted as empty).
    fn min_binary_size(&self) -> usize {
        self.properties
            .iter()
            .map(|p| match p.kind {
                Kind::Scalar(t) => t.size(),
                Kind::List { count, .. } => count.size(),
            })
            .sum()
    }

    fn property(&self, name: &str) -> Option<usize> {
        self.properties.iter().position(|p| p.name == name)
    }
}

struct Header {
    format: PlyFormat,
    elements: Vec<Element>,
    /// Byte offset of the body.
    body_start: usize,
    /// Line number of the `end_header` line.
    end_line: usize,
}

fn parse_header(data: &[u8], path: &Path) -> Result<Header, GeometryError> {
    if is_blank(data) {
        return Err(parse_error(path, 1, "empty file"));
    }
    let mut pos = 0usize;
    let mut line_no = 0usize;
    let mut format = None;
    let mut elements: Vec<Element> = Vec::new();
    loop {
        if pos >= data.len() {
            return Err(parse_error(
                path,
                line_no.max(1),
                "the header has no 'end_header' line (truncated or not a PLY file)",
            ));
        }
        let end = data[pos..]
            .iter()
            .position(|&b| b == b'\n')
            .map_or(data.len(), |k| pos + k);
        let raw = &data[pos..end];
        let line = raw.strip_suffix(b"\r").unwrap_or(raw);
        line_no += 1;
        pos = (end + 1).min(data.len());
        if line_no == 1 {
            if line.trim_ascii_end() != b"ply" {
                return Err(parse_error(
                    path,
                    1,
                    format!("not a PLY file: the first line is '{}', expected 'ply'", show(line)),
                ));
            }
            continue;
        }
        check_text_line(path, line_no, line)?;
        let toks: Vec<&[u8]> = tokens(line).collect();
        let Some(&key) = toks.first() else { continue };
        let bad = |message: String| parse_error(path, line_no, message);
        match key {
            b"format" => {
                format = Some(match toks.get(1).copied() {
                    Some(b"ascii") => PlyFormat::Ascii,
                    Some(b"binary_little_endian") => PlyFormat::BinaryLittleEndian,
                    Some(b"binary_big_endian") => PlyFormat::BinaryBigEndian,
                    other => return Err(bad(format!("unknown PLY format '{}'", show(other.unwrap_or_default())))),
                });
                if let Some(version) = toks.get(2).filter(|v| **v != b"1.0") {
                    return Err(bad(format!(
                        "PLY version '{}' is not supported (only 1.0)",
                        show(version)
                    )));
                }
                if toks.len() > 3 {
                    return Err(bad(
                        "expected 'format <ascii|binary_little_endian|binary_big_endian> 1.0'".to_string(),
                    ));
                }
            }
            b"comment" | b"obj_info" => {}
            b"element" => {
                let (Some(name), Some(count)) = (toks.get(1), toks.get(2)) else {
                    return Err(bad("expected 'element <name> <count>'".to_string()));
                };
                let count = parse_i64(count)
                    .and_then(|c| usize::try_from(c).ok())
                    .ok_or_else(|| bad(format!("invalid element count '{}'", show(count))))?;
                elements.push(Element {
                    name: show(name),
                    count,
                    properties: Vec::new(),
                });
            }
            b"property" => {
                let element = elements
                    .last_mut()
                    .ok_or_else(|| bad("property before any element".to_string()))?;
                let type_of =
                    |t: &[u8]| Scalar::from_name(t).ok_or_else(|| bad(format!("unknown property type '{}'", show(t))));
                let (kind, name) = match toks.get(1).copied() {
                    Some(b"list") => {
                        let (Some(ct), Some(it), Some(name)) = (toks.get(2), toks.get(3), toks.get(4)) else {
                            return Err(bad(
                                "expected 'property list <count type> <item type> <name>'".to_string()
                            ));
                        };
                        let count = type_of(ct)?;
                        if !count.is_integer() {
                            return Err(bad(format!("list count type '{}' is not an integer type", show(ct))));
                        }
                        (
                            Kind::List {
                                count,
                                item: type_of(it)?,
                            },
                            name,
                        )
                    }
                    Some(t) => {
                        let name = toks
                            .get(2)
                            .ok_or_else(|| bad("expected 'property <type> <name>'".to_string()))?;
                        (Kind::Scalar(type_of(t)?), name)
                    }
                    None => return Err(bad("expected 'property <type> <name>'".to_string())),
                };
                element.properties.push(Property { name: show(name), kind });
            }
            b"end_header" => {
                let format = format.ok_or_else(|| bad("the header has no 'format' line".to_string()))?;
                return Ok(Header {
                    format,
                    elements,
                    body_start: pos.min(data.len()),
                    end_line: line_no,
                });
            }
            _ => return Err(bad(format!("unknown header keyword '{}'", show(key)))),
        }
        if end >= data.len() {
            pos = data.len();
        }
    }
}

/// A PLY body being read, ASCII or binary: values one at a time, with errors that name the
/// element instance and the line or byte offset.
trait Body {
    /// Starts instance `index` of element `name` (of `count` declared instances).
    fn begin(&mut self, name: &str, index: usize, count: usize) -> Result<(), GeometryError>;
    /// Reads one value of type `t` (integer types convert to `f64` exactly).
    fn value(&mut self, t: Scalar) -> Result<f64, GeometryError>;
    /// Ends the current instance.
    fn end(&mut self) -> Result<(), GeometryError>;
    /// Checks that nothing follows the last element.
    fn finish(&mut self) -> Result<(), GeometryError>;
    /// An error about the current element instance (prefixed with its name and index).
    fn error(&self, message: String) -> GeometryError;
    /// An error at the current element instance whose message names the instance itself.
    fn error_bare(&self, message: String) -> GeometryError;
    /// Bytes not yet read (bounds pre-allocation).
    fn remaining(&self) -> usize;
    /// Checks, before reading them, that `count` instances of `element` can fit.
    fn check_fits(&self, element: &Element) -> Result<(), GeometryError>;
}

/// The element instance being read, for error messages (formatted only on error).
#[derive(Default)]
struct Current {
    name: String,
    index: usize,
}

impl Current {
    fn set(&mut self, name: &str, index: usize) {
        if self.name != name {
            self.name = name.to_string();
        }
        self.index = index;
    }

    fn show(&self) -> String {
        format!("{} {}", self.name, self.index)
    }
}

struct AsciiBody<'a> {
    path: &'a Path,
    data: &'a [u8],
    pos: usize,
    line_no: usize,
    /// The current line and the position of its next token.
    line: &'a [u8],
    cursor: usize,
    current: Current,
}

impl<'a> AsciiBody<'a> {
    /// The next whitespace-separated token of the current line.
    fn next_token(&mut self) -> Option<&'a [u8]> {
        let line = self.line;
        let start = self.cursor + line[self.cursor..].iter().position(|b| !b.is_ascii_whitespace())?;
        let end = line[start..]
            .iter()
            .position(|b| b.is_ascii_whitespace())
            .map_or(line.len(), |k| start + k);
        self.cursor = end;
        Some(&line[start..end])
    }

    /// The next line that is not blank, with its number.
    fn next_line(&mut self) -> Result<Option<&'a [u8]>, GeometryError> {
        while self.pos < self.data.len() {
            let end = self.data[self.pos..]
                .iter()
                .position(|&b| b == b'\n')
                .map_or(self.data.len(), |k| self.pos + k);
            let raw = &self.data[self.pos..end];
            self.pos = end + 1;
            self.line_no += 1;
            let line = raw.strip_suffix(b"\r").unwrap_or(raw);
            check_text_line(self.path, self.line_no, line)?;
            if !is_blank(line) {
                return Ok(Some(line));
            }
        }
        Ok(None)
    }
}

impl Body for AsciiBody<'_> {
    fn begin(&mut self, name: &str, index: usize, count: usize) -> Result<(), GeometryError> {
        self.current.set(name, index);
        match self.next_line()? {
            Some(line) => {
                self.line = line;
                self.cursor = 0;
                Ok(())
            }
            None => Err(parse_error(
                self.path,
                self.line_no + 1,
                format!("unexpected end of file: the header declares {count} '{name}' elements, found {index}"),
            )),
        }
    }

    fn value(&mut self, t: Scalar) -> Result<f64, GeometryError> {
        let Some(tok) = self.next_token() else {
            return Err(self.error("too few values on the line for the properties the header declares".to_string()));
        };
        if t.is_integer() {
            let (lo, hi) = t.range();
            match parse_i64(tok) {
                Some(i) if (lo..=hi).contains(&i) => Ok(i as f64),
                Some(i) => Err(self.error(format!("value {i} out of range for its type {t:?}"))),
                None => Err(self.error(format!("non-integer value '{}' for an integer property", show(tok)))),
            }
        } else {
            parse_f64(tok).ok_or_else(|| self.error(format!("non-numeric value '{}'", show(tok))))
        }
    }

    fn end(&mut self) -> Result<(), GeometryError> {
        match self.next_token() {
            None => Ok(()),
            Some(tok) => Err(self.error(format!(
                "more values on the line than the header declares (next: '{}'); wrong header?",
                show(tok)
            ))),
        }
    }

    fn finish(&mut self) -> Result<(), GeometryError> {
        self.current.set("", 0);
        match self.next_line()? {
            None => Ok(()),
            Some(line) => Err(parse_error(
                self.path,
                self.line_no,
                format!(
                    "data after the last element ('{}'); wrong counts in the header?",
                    show(line.trim_ascii())
                ),
            )),
        }
    }

    fn error(&self, message: String) -> GeometryError {
        parse_error(self.path, self.line_no, format!("{}: {message}", self.current.show()))
    }

    fn error_bare(&self, message: String) -> GeometryError {
        parse_error(self.path, self.line_no, message)
    }

    fn remaining(&self) -> usize {
        self.data.len().saturating_sub(self.pos)
    }

    fn check_fits(&self, _element: &Element) -> Result<(), GeometryError> {
        Ok(())
    }
}

struct BinaryBody<'a> {
    path: &'a Path,
    data: &'a [u8],
    pos: usize,
    big_endian: bool,
    start: usize,
    current: Current,
    count: usize,
}

impl Body for BinaryBody<'_> {
    fn begin(&mut self, name: &str, index: usize, count: usize) -> Result<(), GeometryError> {
        self.start = self.pos;
        self.count = count;
        self.current.set(name, index);
        Ok(())
    }

    fn value(&mut self, t: Scalar) -> Result<f64, GeometryError> {
        let n = t.size();
        if self.data.len() - self.pos < n {
            return Err(self.error(format!(
                "unexpected end of file inside the element (the header declares {} of them; the file has {} bytes)",
                self.count,
                self.data.len()
            )));
        }
        let b = &self.data[self.pos..self.pos + n];
        self.pos += n;
        let be = self.big_endian;
        macro_rules! get {
            ($ty:ty, $n:literal) => {{
                let a: [u8; $n] = b.try_into().expect("slice of the type's size");
                if be {
                    <$ty>::from_be_bytes(a)
                } else {
                    <$ty>::from_le_bytes(a)
                }
            }};
        }
        Ok(match t {
            Scalar::I8 => b[0] as i8 as f64,
            Scalar::U8 => b[0] as f64,
            Scalar::I16 => get!(i16, 2) as f64,
            Scalar::U16 => get!(u16, 2) as f64,
            Scalar::I32 => get!(i32, 4) as f64,
            Scalar::U32 => get!(u32, 4) as f64,
            Scalar::F32 => get!(f32, 4) as f64,
            Scalar::F64 => get!(f64, 8),
        })
    }

    fn end(&mut self) -> Result<(), GeometryError> {
        Ok(())
    }

    fn finish(&mut self) -> Result<(), GeometryError> {
        let rest = self.data.len() - self.pos;
        if rest == 0 {
            return Ok(());
        }
        Err(GeometryError::BinaryParse {
            path: PathBuf::from(self.path),
            offset: self.pos as u64,
            message: format!("{rest} bytes of data after the last element; wrong counts in the header?"),
        })
    }

    fn error(&self, message: String) -> GeometryError {
        self.error_bare(format!("{}: {message}", self.current.show()))
    }

    fn error_bare(&self, message: String) -> GeometryError {
        GeometryError::BinaryParse {
            path: PathBuf::from(self.path),
            offset: self.start as u64,
            message,
        }
    }

    fn remaining(&self) -> usize {
        self.data.len() - self.pos
    }

    fn check_fits(&self, element: &Element) -> Result<(), GeometryError> {
        let min = element.min_binary_size();
        let rest = self.remaining();
        if element.count.checked_mul(min).is_none_or(|need| need > rest) {
            return Err(GeometryError::BinaryParse {
                path: PathBuf::from(self.path),
                offset: self.pos as u64,
                message: format!(
                    "the header declares {} '{}' elements of at least {min} bytes each, but only {rest} bytes follow \
                     (truncated file or wrong counts)",
                    element.count, element.name
                ),
            });
        }
        Ok(())
    }
}

/// Reads the PLY file at `path` (ASCII or binary; see the module documentation). Returns #V
/// positions in file order, #F triangles (polygons fan-triangulated, strips decoded) and
/// `uvs` when the vertices have `u`/`v` (or `s`/`t`) properties.
pub fn read_ply(path: &Path) -> Result<TriMesh, GeometryError> {
    let data = read_bytes(path)?;
    parse_ply(&data, path)
}

/// Parses PLY bytes; `path` only labels error messages. Same result as [`read_ply`].
pub fn parse_ply(data: impl AsRef<[u8]>, path: &Path) -> Result<TriMesh, GeometryError> {
    let data = data.as_ref();
    let header = parse_header(data, path)?;
    match header.format {
        PlyFormat::Ascii => {
            let mut body = AsciiBody {
                path,
                data,
                pos: header.body_start,
                line_no: header.end_line,
                line: &[],
                cursor: 0,
                current: Current::default(),
            };
            read_body(&header, &mut body, path)
        }
        PlyFormat::BinaryLittleEndian | PlyFormat::BinaryBigEndian => {
            let mut body = BinaryBody {
                path,
                data,
                pos: header.body_start,
                big_endian: header.format == PlyFormat::BinaryBigEndian,
                start: header.body_start,
                current: Current::default(),
                count: 0,
            };
            read_body(&header, &mut body, path)
        }
    }
}

/// The vertex-index list property of a `face` or `tristrips` element.
fn index_list_property(element: &Element, path: &Path, line: usize) -> Result<usize, GeometryError> {
    let k = element
        .property("vertex_indices")
        .or_else(|| element.property("vertex_index"))
        .ok_or_else(|| {
            parse_error(
                path,
                line,
                format!("the '{}' element has no 'vertex_indices' list property", element.name),
            )
        })?;
    match element.properties[k].kind {
        Kind::List { item, .. } if item.is_integer() => Ok(k),
        _ => Err(parse_error(
            path,
            line,
            format!(
                "'{}' of element '{}' is not a list of integers",
                element.properties[k].name, element.name
            ),
        )),
    }
}

/// Reads a list property's items (the count first), with capacity capped by the bytes left.
fn read_list(body: &mut impl Body, count: Scalar, item: Scalar, items: &mut Vec<i64>) -> Result<(), GeometryError> {
    let n = body.value(count)?;
    if n < 0.0 {
        return Err(body.error(format!("negative list length {n}")));
    }
    let n = n as usize;
    items.clear();
    items.reserve(capped_capacity(n, body.remaining(), item.size()));
    for _ in 0..n {
        items.push(body.value(item)? as i64);
    }
    Ok(())
}

fn read_body(header: &Header, body: &mut impl Body, path: &Path) -> Result<TriMesh, GeometryError> {
    let at_header = |message: String| parse_error(path, header.end_line, message);
    let num_vertices = declared_vertices(header, path)?;
    let mut positions: Vec<[f64; 3]> = Vec::new();
    let mut uvs: Option<Vec<[f64; 2]>> = None;
    let mut faces: Vec<[u32; 3]> = Vec::new();
    let mut items: Vec<i64> = Vec::new();
    let mut fans: Vec<Fan> = Vec::new();

    for element in &header.elements {
        if element.properties.is_empty() {
            // Nothing is stored for such an element, however large its count.
            continue;
        }
        body.check_fits(element)?;
        match element.name.as_str() {
            "vertex" => (positions, uvs) = read_vertices(element, body, &at_header, &mut items)?,
            "face" | "tristrips" => {
                let list = index_list_property(element, path, header.end_line)?;
                read_faces(element, list, num_vertices, body, &mut items, &mut faces, &mut fans)?;
            }
            _ => skip_element(element, body, &mut items)?,
        }
    }
    body.finish()?;
    if faces.is_empty() {
        return Err(at_header(
            "the file has no faces (all face elements empty or degenerate)".to_string(),
        ));
    }
    check_fans(path, &positions, &faces, &fans)?;
    Ok(TriMesh { positions, faces, uvs })
}

/// The number of vertices the header declares, checked with the header's elements: one vertex
/// element with properties, at least one vertex and at most the u32 range, a face or tristrips
/// element.
fn declared_vertices(header: &Header, path: &Path) -> Result<usize, GeometryError> {
    let at_header = |message: String| parse_error(path, header.end_line, message);
    let vertex_elements: Vec<&Element> = header.elements.iter().filter(|e| e.name == "vertex").collect();
    let num_vertices = match vertex_elements.as_slice() {
        // (an element without properties is skipped by the loop below, so the coordinates'
        // check there would never run)
        [e] if e.properties.is_empty() => {
            return Err(at_header(
                "the vertex element has no properties (no 'x', 'y', 'z')".to_string(),
            ))
        }
        [e] => e.count,
        [] => return Err(at_header("the header declares no 'vertex' element".to_string())),
        _ => {
            return Err(at_header(
                "the header declares more than one 'vertex' element".to_string(),
            ))
        }
    };
    if num_vertices == 0 {
        return Err(at_header("the header declares 0 vertices".to_string()));
    }
    if u32::try_from(num_vertices).is_err() {
        return Err(at_header(format!("{num_vertices} vertices exceed the u32 index range")));
    }
    if !header
        .elements
        .iter()
        .any(|e| e.name == "face" || e.name == "tristrips")
    {
        return Err(at_header(
            "the header declares no 'face' or 'tristrips' element".to_string(),
        ));
    }
    Ok(num_vertices)
}

/// Positions and, when the file has them, texture coordinates.
type VertexData = (Vec<[f64; 3]>, Option<Vec<[f64; 2]>>);

/// Reads the vertex element: positions, and texture coordinates when it has a (u, v), (s, t)
/// or (texture_u, texture_v) pair; non-finite values are errors.
fn read_vertices(
    element: &Element,
    body: &mut impl Body,
    at_header: &impl Fn(String) -> GeometryError,
    items: &mut Vec<i64>,
) -> Result<VertexData, GeometryError> {
    let name = element.name.as_str();
    let mut positions: Vec<[f64; 3]> = Vec::new();
    let coordinate = |c: &str| {
        let k = element
            .property(c)
            .ok_or_else(|| at_header(format!("the vertex element has no '{c}' property")))?;
        match element.properties[k].kind {
            Kind::Scalar(_) => Ok(k),
            Kind::List { .. } => Err(at_header(format!("vertex property '{c}' is a list"))),
        }
    };
    let xyz = [coordinate("x")?, coordinate("y")?, coordinate("z")?];
    let uv = [("u", "v"), ("s", "t"), ("texture_u", "texture_v")]
        .iter()
        .find_map(|(u, v)| Some([coordinate(u).ok()?, coordinate(v).ok()?]));
    let capacity = capped_capacity(element.count, body.remaining(), element.min_binary_size().max(2));
    positions.reserve(capacity);
    let mut uv_values: Vec<[f64; 2]> = Vec::with_capacity(if uv.is_some() { capacity } else { 0 });
    for i in 0..element.count {
        body.begin(name, i, element.count)?;
        let mut p = [0.0; 3];
        let mut t = [0.0; 2];
        for (k, prop) in element.properties.iter().enumerate() {
            match prop.kind {
                Kind::Scalar(s) => {
                    let x = body.value(s)?;
                    if let Some(c) = xyz.iter().position(|&j| j == k) {
                        p[c] = x;
                    } else if let Some(c) = uv.and_then(|uv| uv.iter().position(|&j| j == k)) {
                        t[c] = x;
                    }
                }
                Kind::List { count, item } => read_list(body, count, item, items)?,
            }
        }
        body.end()?;
        if !p.iter().all(|c| c.is_finite()) {
            return Err(body.error_bare(format!("vertex {i} has a non-finite coordinate")));
        }
        if !t.iter().all(|c| c.is_finite()) {
            return Err(body.error_bare(format!("vertex {i} has a non-finite texture coordinate")));
        }
        positions.push(p);
        if uv.is_some() {
            uv_values.push(t);
        }
    }
    Ok((positions, uv.is_some().then_some(uv_values)))
}

/// Reads a face or tristrips element: its index list (property `list`) fan-triangulated into
/// `faces` (polygons' fans recorded in `fans`), or strips turned into triangles; indices are
/// checked against `num_vertices`.
fn read_faces(
    element: &Element,
    list: usize,
    num_vertices: usize,
    body: &mut impl Body,
    items: &mut Vec<i64>,
    faces: &mut Vec<[u32; 3]>,
    fans: &mut Vec<Fan>,
) -> Result<(), GeometryError> {
    let name = element.name.as_str();
    let mut polygon: Vec<u32> = Vec::new();
    let strips = name == "tristrips";
    if !strips {
        faces.reserve(capped_capacity(
            element.count,
            body.remaining(),
            element.min_binary_size().max(2),
        ));
    }
    for i in 0..element.count {
        body.begin(name, i, element.count)?;
        for (k, prop) in element.properties.iter().enumerate() {
            match prop.kind {
                Kind::Scalar(s) => {
                    body.value(s)?;
                }
                Kind::List { count, item } => {
                    read_list(body, count, item, items)?;
                    if k != list {
                        continue;
                    }
                    if strips {
                        strips_to_triangles(items, num_vertices, faces).map_err(|m| body.error(m))?;
                        continue;
                    }
                    if items.len() < 3 {
                        return Err(body.error_bare(format!("face {i} has {} vertices (need at least 3)", items.len())));
                    }
                    polygon.clear();
                    for &v in items.iter() {
                        if v < 0 || v as u64 >= num_vertices as u64 {
                            return Err(body.error(format!(
                                "vertex index {v} out of range (the header declares {num_vertices} vertices)"
                            )));
                        }
                        polygon.push(v as u32);
                    }
                    fans.extend(Fan::of(i, polygon.len(), faces, None));
                    fan_triangulate(&polygon, faces);
                }
            }
        }
        body.end()?;
    }
    Ok(())
}

/// Reads past an element the mesh does not use.
fn skip_element(element: &Element, body: &mut impl Body, items: &mut Vec<i64>) -> Result<(), GeometryError> {
    let name = element.name.as_str();
    for i in 0..element.count {
        body.begin(name, i, element.count)?;
        for prop in &element.properties {
            match prop.kind {
                Kind::Scalar(s) => {
                    body.value(s)?;
                }
                Kind::List { count, item } => read_list(body, count, item, items)?,
            }
        }
        body.end()?;
    }
    Ok(())
}

/// Decodes triangle strips separated by `-1` (see the module documentation), dropping
/// degenerate triangles. Errors on other negative or out-of-range indices.
fn strips_to_triangles(indices: &[i64], num_vertices: usize, faces: &mut Vec<[u32; 3]>) -> Result<(), String> {
    for strip in indices.split(|&v| v == -1) {
        for &v in strip {
            if v < 0 || v as u64 >= num_vertices as u64 {
                return Err(format!(
                    "strip vertex index {v} out of range (the header declares {num_vertices} vertices)"
                ));
            }
        }
        for (j, w) in strip.windows(3).enumerate() {
            let [a, b, c] = [w[0] as u32, w[1] as u32, w[2] as u32];
            if a == b || b == c || a == c {
                continue;
            }
            faces.push(if j % 2 == 0 { [a, b, c] } else { [b, a, c] });
        }
    }
    Ok(())
}

/// Writes `mesh` as PLY to `path` in the given `format`: `element vertex` with `double x y z`
/// (and `double u v` when `mesh.uvs` is `Some`), `element face` with
/// `property list uchar uint vertex_indices`. Values read back exactly: raw `f64` in binary,
/// shortest round-trip decimals in ASCII.
pub fn write_ply(path: &Path, mesh: &TriMesh, format: PlyFormat) -> Result<(), GeometryError> {
    super::write_file(path, mesh, |w| write_ply_to(w, mesh, format))
}

/// Writes `mesh` as PLY to `writer` (the format of [`write_ply`]; no validation).
pub fn write_ply_to<W: Write>(mut writer: W, mesh: &TriMesh, format: PlyFormat) -> std::io::Result<()> {
    writeln!(writer, "ply")?;
    writeln!(writer, "format {} 1.0", format.header_name())?;
    writeln!(writer, "comment written by shapespace")?;
    writeln!(writer, "element vertex {}", mesh.num_vertices())?;
    for c in ["x", "y", "z"] {
        writeln!(writer, "property double {c}")?;
    }
    if mesh.uvs.is_some() {
        writeln!(writer, "property double u")?;
        writeln!(writer, "property double v")?;
    }
    writeln!(writer, "element face {}", mesh.num_faces())?;
    writeln!(writer, "property list uchar uint vertex_indices")?;
    writeln!(writer, "end_header")?;
    let uv_of = |i: usize| mesh.uvs.as_ref().map(|uvs| uvs[i]);
    match format {
        PlyFormat::Ascii => {
            for (i, [x, y, z]) in mesh.positions.iter().enumerate() {
                match uv_of(i) {
                    Some([u, v]) => writeln!(writer, "{x:?} {y:?} {z:?} {u:?} {v:?}")?,
                    None => writeln!(writer, "{x:?} {y:?} {z:?}")?,
                }
            }
            for [a, b, c] in &mesh.faces {
                writeln!(writer, "3 {a} {b} {c}")?;
            }
        }
        PlyFormat::BinaryLittleEndian | PlyFormat::BinaryBigEndian => {
            let be = format == PlyFormat::BinaryBigEndian;
            let f = |x: f64| if be { x.to_be_bytes() } else { x.to_le_bytes() };
            let u = |x: u32| if be { x.to_be_bytes() } else { x.to_le_bytes() };
            for (i, p) in mesh.positions.iter().enumerate() {
                for &x in p.iter().chain(uv_of(i).iter().flatten()) {
                    writer.write_all(&f(x))?;
                }
            }
            for face in &mesh.faces {
                writer.write_all(&[3])?;
                for &v in face {
                    writer.write_all(&u(v))?;
                }
            }
        }
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    fn parse(data: &[u8]) -> Result<TriMesh, GeometryError> {
        parse_ply(data, Path::new("t.ply"))
    }

    const ASCII_HEADER: &str = "ply\nformat ascii 1.0\ncomment c\nelement vertex 4\nproperty float x\nproperty float y\n\
                                property float z\nproperty uchar red\nelement face 2\nproperty list uchar int vertex_index\n\
                                property int flags\nend_header\n";

    #[test]
    fn ascii_with_extra_properties_and_a_quad() {
        let text = format!("{ASCII_HEADER}0 0 0 1\n1 0 0 2\n1 1 0 3\n0 1 0 4\n4 0 1 2 3 7\n3 3 2 1 8\n");
        let m = parse(text.as_bytes()).unwrap();
        assert_eq!(
            m.positions,
            vec![[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [1.0, 1.0, 0.0], [0.0, 1.0, 0.0]]
        );
        assert_eq!(m.faces, vec![[0, 1, 2], [0, 2, 3], [3, 2, 1]]);
    }

    #[test]
    fn ascii_errors_name_line_and_element() {
        let e =
            parse(format!("{ASCII_HEADER}0 0 0 1\n1 0 0 2\n1 1 0 3\n0 1 0 4\n4 0 1 2 9 7\n").as_bytes()).unwrap_err();
        let e = e.to_string();
        assert!(
            e.starts_with("t.ply:17: face 0:") && e.contains("index 9 out of range"),
            "{e}"
        );
        let e = parse(format!("{ASCII_HEADER}0 0 0 1\n1 0 0 2\n").as_bytes())
            .unwrap_err()
            .to_string();
        assert!(
            e.starts_with("t.ply:15:") && e.contains("declares 4 'vertex' elements, found 2"),
            "{e}"
        );
        let e = parse(format!("{ASCII_HEADER}0 0 0 1\n1 0 nan 2\n").as_bytes())
            .unwrap_err()
            .to_string();
        assert!(
            e.starts_with("t.ply:14:") && e.contains("vertex 1 has a non-finite"),
            "{e}"
        );
        let e = parse(format!("{ASCII_HEADER}0 0 0 1 5\n").as_bytes())
            .unwrap_err()
            .to_string();
        assert!(e.starts_with("t.ply:13: vertex 0:") && e.contains("more values"), "{e}");
        let e = parse(format!("{ASCII_HEADER}0 0 0 1\n1 0 0 2\n1 1 0 3\n0 1 0 4\n2 0 1 7\n").as_bytes()).unwrap_err();
        assert!(e.to_string().contains("t.ply:17: face 0 has 2 vertices"), "{e}");
        let header = "ply\nformat ascii 1.0\nelement vertex 1\nproperty float x\nelement face 0\n\
                      property list uchar int vertex_indices\nend_header\n";
        let e = parse(header.as_bytes()).unwrap_err().to_string();
        assert!(e.starts_with("t.ply:7:") && e.contains("no 'y' property"), "{e}");
        let e = parse(b"solid cube\n").unwrap_err().to_string();
        assert!(e.starts_with("t.ply:1:") && e.contains("not a PLY file"), "{e}");
        let e = parse(b"ply\nformat ascii 1.0\nelement vertex 3\n")
            .unwrap_err()
            .to_string();
        assert!(e.contains("end_header"), "{e}");
        assert!(parse(b"").unwrap_err().to_string().contains("empty file"));
    }

    #[test]
    fn integer_coordinate_types_in_binary_little_endian() {
        let mut data = b"ply\nformat binary_little_endian 1.0\nelement vertex 3\nproperty char x\nproperty ushort y\n\
                         property int z\nproperty float32 nx\nelement face 1\nproperty list uint16 uint8 vertex_index\n\
                         end_header\n"
            .to_vec();
        for (x, y, z) in [(-1i8, 65535u16, -7i32), (2, 0, 1 << 30), (127, 3, 0)] {
            data.push(x as u8);
            data.extend_from_slice(&y.to_le_bytes());
            data.extend_from_slice(&z.to_le_bytes());
            data.extend_from_slice(&0.5f32.to_le_bytes());
        }
        data.extend_from_slice(&3u16.to_le_bytes());
        data.extend_from_slice(&[2, 1, 0]);
        let m = parse(&data).unwrap();
        assert_eq!(
            m.positions,
            vec![[-1.0, 65535.0, -7.0], [2.0, 0.0, (1 << 30) as f64], [127.0, 3.0, 0.0]]
        );
        assert_eq!(m.faces, vec![[2, 1, 0]]);
        // ASCII values outside their declared type are errors.
        let text = "ply\nformat ascii 1.0\nelement vertex 3\nproperty uchar x\nproperty float y\nproperty float z\n\
                    element face 1\nproperty list uchar int vertex_indices\nend_header\n0 0 0\n256 0 0\n0 1 0\n3 0 1 2\n";
        let e = parse(text.as_bytes()).unwrap_err().to_string();
        assert!(
            e.starts_with("t.ply:11: vertex 1:") && e.contains("256 out of range"),
            "{e}"
        );
    }

    #[test]
    fn tristrips_alternate_winding_and_drop_degenerates() {
        let mut data = b"ply\nformat binary_big_endian 1.0\nelement vertex 6\nproperty double x\nproperty double y\n\
                         property double z\nelement tristrips 1\nproperty list int int vertex_indices\nend_header\n"
            .to_vec();
        for i in 0..6 {
            for c in [i as f64, (i % 2) as f64, 0.5] {
                data.extend_from_slice(&c.to_be_bytes());
            }
        }
        // Strip 0 1 2 3 4 -1, then 3 3 4 5 (a repeated index: one degenerate triangle).
        let strip: [i32; 10] = [0, 1, 2, 3, 4, -1, 3, 3, 4, 5];
        data.extend_from_slice(&(strip.len() as i32).to_be_bytes());
        for s in strip {
            data.extend_from_slice(&s.to_be_bytes());
        }
        let m = parse(&data).unwrap();
        assert_eq!(m.positions[5], [5.0, 1.0, 0.5]);
        assert_eq!(m.faces, vec![[0, 1, 2], [2, 1, 3], [2, 3, 4], [4, 3, 5]]);
    }

    #[test]
    fn binary_header_lies_are_caught_before_allocating() {
        let data = b"ply\nformat binary_little_endian 1.0\nelement vertex 4000000000\nproperty float x\n\
                     property float y\nproperty float z\nelement face 1\nproperty list uchar int vertex_indices\n\
                     end_header\n\0\0\0\0";
        let e = parse(data).unwrap_err().to_string();
        assert!(
            e.starts_with("t.ply: byte 178:") && e.contains("4000000000 'vertex' elements"),
            "{e}"
        );
    }

    fn sample() -> TriMesh {
        TriMesh {
            positions: vec![
                [0.1, -2.0 / 3.0, 1e-300],
                [f64::MAX, -0.0, 5e-324],
                [1.0, 1e22, -7.25],
                [9.0, 9.0, 9.0],
            ],
            faces: vec![[0, 1, 2], [2, 1, 3]],
            uvs: Some(vec![[0.3, 1.0 / 3.0], [-1e-9, 2.5], [0.0, 1e100], [1.0, 1.0]]),
        }
    }

    #[test]
    fn round_trip_is_exact_in_all_formats() {
        for format in [
            PlyFormat::Ascii,
            PlyFormat::BinaryLittleEndian,
            PlyFormat::BinaryBigEndian,
        ] {
            for mesh in [sample(), TriMesh { uvs: None, ..sample() }] {
                let mut buf = Vec::new();
                write_ply_to(&mut buf, &mesh, format).unwrap();
                assert_eq!(parse(&buf).unwrap(), mesh, "{format:?}");
            }
        }
    }

    #[test]
    fn truncated_binary_names_element_and_offset() {
        let mut buf = Vec::new();
        write_ply_to(
            &mut buf,
            &TriMesh { uvs: None, ..sample() },
            PlyFormat::BinaryLittleEndian,
        )
        .unwrap();
        // Cut inside face 1: the header check passes (lists are counted as empty), the read fails.
        buf.truncate(buf.len() - 3);
        let e = parse(&buf).unwrap_err().to_string();
        assert!(e.contains("face 1: unexpected end of file"), "{e}");
        let offset: usize = e
            .split("byte ")
            .nth(1)
            .unwrap()
            .split(':')
            .next()
            .unwrap()
            .parse()
            .unwrap();
        assert_eq!(offset, buf.len() + 3 - 13, "{e}");
    }
}
