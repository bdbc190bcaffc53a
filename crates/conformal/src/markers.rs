//! Interior and boundary markers of a disk map: parsing (CLI strings, JSON sidecars),
//! validation and the deterministic automatic choices.
//!
//! The disk map sends the interior marker p to 0 and the boundary marker q to 1 (Su et al.
//! 2015, Thm. 5: the Riemann map of a disk-type surface is unique given these two points).
//!
//! Automatic rules (deterministic, invariant under rigid motions and uniform scaling up to
//! floating-point ties):
//! * interior: the vertex farthest from the boundary in graph-geodesic distance (Dijkstra on
//!   3D edge lengths from all boundary vertices at once); ties (relative 1e-9) → smallest index;
//! * boundary: the boundary vertex farthest from the center in the same graph-geodesic
//!   distance (from the center vertex, or from the corners of the center's face weighted by
//!   their 3D distance to the point); ties (relative 1e-9) → smallest index. The tie tolerance
//!   makes the choice immune to the roundoff of a rigid motion on symmetric surfaces; near-ties
//!   just above it remain sensitive: pass an explicit marker when the rotation of the image
//!   matters.

use std::cmp::Ordering;
use std::collections::{BTreeMap, BinaryHeap};
use std::path::{Path, PathBuf};

use shapespace_geometry::TriMesh;

use crate::error::ConformalError;

/// The interior marker p.
#[derive(Clone, Debug, PartialEq)]
pub enum CenterMarker {
    /// A vertex index (must not lie on the boundary).
    Vertex(u32),
    /// A point inside a face, by barycentric coordinates (non-negative, summing to 1) with
    /// respect to the face's corners in order.
    Barycentric { face: u32, bary: [f64; 3] },
    /// A point in space, projected to the closest point of the surface.
    Point([f64; 3]),
    /// The vertex farthest from the boundary (see the module docs).
    Auto,
}

/// The boundary marker q.
#[derive(Clone, Debug, PartialEq)]
pub enum BoundaryMarker {
    /// A boundary vertex index.
    Vertex(u32),
    /// The boundary vertex farthest from the center (see the module docs).
    Auto,
}

/// Both markers of a disk map.
#[derive(Clone, Debug, PartialEq)]
pub struct Markers {
    /// Interior marker p ↦ 0.
    pub center: CenterMarker,
    /// Boundary marker q ↦ 1.
    pub boundary: BoundaryMarker,
}

impl Default for Markers {
    fn default() -> Self {
        Markers {
            center: CenterMarker::Auto,
            boundary: BoundaryMarker::Auto,
        }
    }
}

/// A marker file: `{"center": 123 | [x,y,z] | {"face": f, "bary": [b0,b1,b2]} | "auto",
/// "boundary": 456 | "auto", "landmarks": {"name": vertex, ...}}` (every key optional).
#[derive(Clone, Debug, Default, PartialEq)]
pub struct MarkerFile {
    /// The two disk-map markers (missing keys are `Auto`).
    pub markers: Markers,
    /// Named landmark vertices (for registration), sorted by name.
    pub landmarks: BTreeMap<String, u32>,
}

/// The resolved interior marker: a vertex, or a point inside a face. Serialized as in a marker
/// file (`123` or `{"face": f, "bary": [..]}`), so a report's markers can be fed back.
#[derive(Clone, Copy, Debug, PartialEq, serde::Serialize, serde::Deserialize)]
#[serde(untagged)]
pub enum ResolvedCenter {
    /// A mesh vertex.
    Vertex(u32),
    /// A point of a face with barycentric coordinates.
    Face { face: u32, bary: [f64; 3] },
}

impl std::fmt::Display for ResolvedCenter {
    /// `vertex 123`, or `face 12 at (0.2, 0.3, 0.5)` (barycentric).
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            ResolvedCenter::Vertex(v) => write!(f, "vertex {v}"),
            ResolvedCenter::Face { face, bary } => {
                write!(f, "face {face} at ({}, {}, {})", bary[0], bary[1], bary[2])
            }
        }
    }
}

/// Markers checked against a mesh. Serialized as a marker file, `{"center": .., "boundary": q}`.
#[derive(Clone, Copy, Debug, PartialEq, serde::Serialize)]
pub struct ResolvedMarkers {
    /// Interior marker p.
    pub center: ResolvedCenter,
    /// Boundary vertex q.
    #[serde(rename = "boundary")]
    pub boundary_vertex: u32,
}

fn parse_err(source_name: &str, message: impl Into<String>) -> ConformalError {
    ConformalError::MarkerParse {
        source_name: source_name.to_string(),
        message: message.into(),
    }
}

impl CenterMarker {
    /// Parses `V` (vertex index), `x,y,z` (a point) or `auto`.
    pub fn parse(text: &str) -> Result<Self, ConformalError> {
        let t = text.trim();
        if t.eq_ignore_ascii_case("auto") {
            return Ok(CenterMarker::Auto);
        }
        if t.contains(',') {
            let parts: Vec<&str> = t.split(',').map(str::trim).collect();
            if parts.len() != 3 {
                return Err(parse_err("--center", format!("expected x,y,z, got `{t}`")));
            }
            let mut p = [0.0; 3];
            for (k, s) in parts.iter().enumerate() {
                p[k] = s
                    .parse::<f64>()
                    .ok()
                    .filter(|x| x.is_finite())
                    .ok_or_else(|| parse_err("--center", format!("`{s}` is not a finite number")))?;
            }
            return Ok(CenterMarker::Point(p));
        }
        t.parse::<u32>()
            .map(CenterMarker::Vertex)
            .map_err(|_| parse_err("--center", format!("expected a vertex index, x,y,z or auto, got `{t}`")))
    }
}

impl BoundaryMarker {
    /// Parses `V` (vertex index) or `auto`.
    pub fn parse(text: &str) -> Result<Self, ConformalError> {
        let t = text.trim();
        if t.eq_ignore_ascii_case("auto") {
            return Ok(BoundaryMarker::Auto);
        }
        t.parse::<u32>().map(BoundaryMarker::Vertex).map_err(|_| {
            parse_err(
                "--boundary-marker",
                format!("expected a vertex index or auto, got `{t}`"),
            )
        })
    }
}

fn json_u32(v: &serde_json::Value, src: &str, what: &str) -> Result<u32, ConformalError> {
    v.as_u64()
        .and_then(|x| u32::try_from(x).ok())
        .ok_or_else(|| parse_err(src, format!("`{what}` must be a vertex index, got {v}")))
}

/// A JSON value read with a repeated key in any object (at any depth) as an error: JSON
/// readers, `serde_json::Value` included, keep the last value silently, so a marker file naming
/// a landmark twice would lose one without notice.
struct StrictValue(serde_json::Value);

impl<'de> serde::Deserialize<'de> for StrictValue {
    fn deserialize<D: serde::Deserializer<'de>>(deserializer: D) -> Result<Self, D::Error> {
        deserializer.deserialize_any(StrictValueVisitor)
    }
}

struct StrictValueVisitor;

impl<'de> serde::de::Visitor<'de> for StrictValueVisitor {
    type Value = StrictValue;

    fn expecting(&self, f: &mut std::fmt::Formatter) -> std::fmt::Result {
        f.write_str("any JSON value")
    }

    fn visit_map<A: serde::de::MapAccess<'de>>(self, mut map: A) -> Result<StrictValue, A::Error> {
        let mut object = serde_json::Map::new();
        while let Some(key) = map.next_key::<String>()? {
            if object.contains_key(&key) {
                return Err(serde::de::Error::custom(format!(
                    "the key `{key}` appears twice in one object"
                )));
            }
            let StrictValue(value) = map.next_value()?;
            object.insert(key, value);
        }
        Ok(StrictValue(serde_json::Value::Object(object)))
    }

    fn visit_seq<A: serde::de::SeqAccess<'de>>(self, mut seq: A) -> Result<StrictValue, A::Error> {
        let mut array = Vec::new();
        while let Some(StrictValue(value)) = seq.next_element()? {
            array.push(value);
        }
        Ok(StrictValue(serde_json::Value::Array(array)))
    }

    fn visit_bool<E>(self, v: bool) -> Result<StrictValue, E> {
        Ok(StrictValue(v.into()))
    }

    fn visit_i64<E>(self, v: i64) -> Result<StrictValue, E> {
        Ok(StrictValue(v.into()))
    }

    fn visit_u64<E>(self, v: u64) -> Result<StrictValue, E> {
        Ok(StrictValue(v.into()))
    }

    fn visit_f64<E>(self, v: f64) -> Result<StrictValue, E> {
        Ok(StrictValue(v.into()))
    }

    fn visit_str<E>(self, v: &str) -> Result<StrictValue, E> {
        Ok(StrictValue(v.into()))
    }

    fn visit_unit<E>(self) -> Result<StrictValue, E> {
        Ok(StrictValue(serde_json::Value::Null))
    }
}

impl MarkerFile {
    /// Parses the JSON text of a marker file; `source_name` names it in errors. A key repeated
    /// within one object (e.g. a landmark named twice) is an error. A leading byte-order mark
    /// (some editors write one) is skipped.
    pub fn from_json_str(text: &str, source_name: &str) -> Result<Self, ConformalError> {
        let text = text.strip_prefix('\u{feff}').unwrap_or(text);
        let StrictValue(value) =
            serde_json::from_str(text).map_err(|e| parse_err(source_name, format!("line {}: {e}", e.line())))?;
        let obj = value
            .as_object()
            .ok_or_else(|| parse_err(source_name, "expected a JSON object"))?;
        // A misspelt key ("centre") must not silently fall back to the automatic markers.
        if let Some(key) = obj
            .keys()
            .find(|k| !matches!(k.as_str(), "center" | "boundary" | "landmarks" | "comment") && !k.starts_with('_'))
        {
            return Err(parse_err(
                source_name,
                format!("unknown key `{key}` (expected `center`, `boundary`, `landmarks`; `comment` or keys starting with `_` are ignored)"),
            ));
        }
        let mut out = MarkerFile::default();
        if let Some(c) = obj.get("center") {
            out.markers.center = match c {
                serde_json::Value::String(s) if s.eq_ignore_ascii_case("auto") => CenterMarker::Auto,
                serde_json::Value::Number(_) => CenterMarker::Vertex(json_u32(c, source_name, "center")?),
                serde_json::Value::Array(a) if a.len() == 3 => {
                    let mut p = [0.0; 3];
                    for (k, x) in a.iter().enumerate() {
                        p[k] = x
                            .as_f64()
                            .ok_or_else(|| parse_err(source_name, "`center` point must hold 3 numbers"))?;
                    }
                    CenterMarker::Point(p)
                }
                serde_json::Value::Object(o) => {
                    let face = json_u32(
                        o.get("face").unwrap_or(&serde_json::Value::Null),
                        source_name,
                        "center.face",
                    )?;
                    let b = o
                        .get("bary")
                        .and_then(|b| b.as_array())
                        .filter(|b| b.len() == 3)
                        .ok_or_else(|| parse_err(source_name, "`center.bary` must be 3 numbers"))?;
                    let mut bary = [0.0; 3];
                    for (k, x) in b.iter().enumerate() {
                        bary[k] = x
                            .as_f64()
                            .ok_or_else(|| parse_err(source_name, "`center.bary` must be 3 numbers"))?;
                    }
                    CenterMarker::Barycentric { face, bary }
                }
                other => return Err(parse_err(source_name, format!("cannot read `center` from {other}"))),
            };
        }
        if let Some(b) = obj.get("boundary") {
            out.markers.boundary = match b {
                serde_json::Value::String(s) if s.eq_ignore_ascii_case("auto") => BoundaryMarker::Auto,
                _ => BoundaryMarker::Vertex(json_u32(b, source_name, "boundary")?),
            };
        }
        if let Some(l) = obj.get("landmarks") {
            let lo = l
                .as_object()
                .ok_or_else(|| parse_err(source_name, "`landmarks` must be an object name → vertex"))?;
            for (name, v) in lo {
                out.landmarks
                    .insert(name.clone(), json_u32(v, source_name, &format!("landmarks.{name}"))?);
            }
        }
        Ok(out)
    }

    /// Reads and parses a marker file.
    pub fn from_json_file(path: &Path) -> Result<Self, ConformalError> {
        let text = std::fs::read_to_string(path).map_err(|error| ConformalError::Io {
            path: path.to_path_buf(),
            error,
        })?;
        Self::from_json_str(&text, &path.display().to_string())
    }

    /// The sidecar marker file of a mesh, if one exists: `NAME.landmarks.json` beside
    /// `mesh_path` (NAME = file stem), else `landmarks.json` in the same folder (one file for a
    /// set of meshes with the same connectivity).
    pub fn sidecar_path(mesh_path: &Path) -> Option<PathBuf> {
        let dir = mesh_path.parent().unwrap_or(Path::new("."));
        let stem = mesh_path.file_stem()?.to_string_lossy().to_string();
        [dir.join(format!("{stem}.landmarks.json")), dir.join("landmarks.json")]
            .into_iter()
            .find(|p| p.is_file())
    }
}

#[derive(PartialEq)]
struct Entry(f64, u32);
impl Eq for Entry {}
impl PartialOrd for Entry {
    fn partial_cmp(&self, o: &Self) -> Option<Ordering> {
        Some(self.cmp(o))
    }
}
impl Ord for Entry {
    // min-heap on distance, then on index
    fn cmp(&self, o: &Self) -> Ordering {
        o.0.total_cmp(&self.0).then(o.1.cmp(&self.1))
    }
}

/// Graph-geodesic distances (Dijkstra on 3D edge lengths) from weighted sources
/// `(vertex, initial distance)`, #V (infinite where unreachable).
pub fn graph_distances(mesh: &TriMesh, neighbors: &[Vec<u32>], sources: &[(u32, f64)]) -> Vec<f64> {
    let n = mesh.num_vertices();
    let mut dist = vec![f64::INFINITY; n];
    let mut heap = BinaryHeap::new();
    for &(s, d) in sources {
        if d < dist[s as usize] {
            dist[s as usize] = d;
            heap.push(Entry(d, s));
        }
    }
    while let Some(Entry(d, v)) = heap.pop() {
        if d > dist[v as usize] {
            continue;
        }
        let pv = mesh.positions[v as usize];
        for &w in &neighbors[v as usize] {
            let pw = mesh.positions[w as usize];
            let l = ((pv[0] - pw[0]).powi(2) + (pv[1] - pw[1]).powi(2) + (pv[2] - pw[2]).powi(2)).sqrt();
            let nd = d + l;
            if nd < dist[w as usize] {
                dist[w as usize] = nd;
                heap.push(Entry(nd, w));
            }
        }
    }
    dist
}

/// Relative tolerance under which two geodesic distances tie (so that roundoff from a rigid
/// motion cannot change an automatic marker on a symmetric surface).
pub const TIE_TOLERANCE: f64 = 1e-9;

/// Smallest index whose finite value is within a relative [`TIE_TOLERANCE`] of the largest
/// allowed value.
fn argmax(values: &[f64], allowed: impl Fn(usize) -> bool) -> Option<usize> {
    let max = values
        .iter()
        .enumerate()
        .filter(|(i, v)| allowed(*i) && v.is_finite())
        .map(|(_, &v)| v)
        .fold(f64::NEG_INFINITY, f64::max);
    if !max.is_finite() {
        return None;
    }
    let threshold = max - TIE_TOLERANCE * max.abs();
    values
        .iter()
        .enumerate()
        .position(|(i, &v)| allowed(i) && v.is_finite() && v >= threshold)
}

/// Closest point of triangle (a, b, c) to p, as barycentric coordinates
/// [Ericson, *Real-Time Collision Detection*, §5.1.5].
pub fn closest_point_barycentric(p: [f64; 3], a: [f64; 3], b: [f64; 3], c: [f64; 3]) -> [f64; 3] {
    let sub = |x: [f64; 3], y: [f64; 3]| [x[0] - y[0], x[1] - y[1], x[2] - y[2]];
    let dot = |x: [f64; 3], y: [f64; 3]| x[0] * y[0] + x[1] * y[1] + x[2] * y[2];
    let (ab, ac, ap) = (sub(b, a), sub(c, a), sub(p, a));
    let (d1, d2) = (dot(ab, ap), dot(ac, ap));
    if d1 <= 0.0 && d2 <= 0.0 {
        return [1.0, 0.0, 0.0];
    }
    let bp = sub(p, b);
    let (d3, d4) = (dot(ab, bp), dot(ac, bp));
    if d3 >= 0.0 && d4 <= d3 {
        return [0.0, 1.0, 0.0];
    }
    let vc = d1 * d4 - d3 * d2;
    if vc <= 0.0 && d1 >= 0.0 && d3 <= 0.0 {
        let v = d1 / (d1 - d3);
        return [1.0 - v, v, 0.0];
    }
    let cp = sub(p, c);
    let (d5, d6) = (dot(ab, cp), dot(ac, cp));
    if d6 >= 0.0 && d5 <= d6 {
        return [0.0, 0.0, 1.0];
    }
    let vb = d5 * d2 - d1 * d6;
    if vb <= 0.0 && d2 >= 0.0 && d6 <= 0.0 {
        let w = d2 / (d2 - d6);
        return [1.0 - w, 0.0, w];
    }
    let va = d3 * d6 - d5 * d4;
    if va <= 0.0 && (d4 - d3) >= 0.0 && (d5 - d6) >= 0.0 {
        let w = (d4 - d3) / ((d4 - d3) + (d5 - d6));
        return [0.0, 1.0 - w, w];
    }
    let denom = 1.0 / (va + vb + vc);
    let v = vb * denom;
    let w = vc * denom;
    [1.0 - v - w, v, w]
}

/// The vertex farthest from the boundary in graph-geodesic distance (Dijkstra on 3D edge
/// lengths from all boundary vertices; ties within a relative 1e-9 → smallest index): the
/// automatic center, and the pole of the Green's function in [`crate::disk_map()`].
pub fn central_vertex(mesh: &TriMesh, is_boundary: &[bool], neighbors: &[Vec<u32>]) -> Option<u32> {
    let sources: Vec<(u32, f64)> = (0..mesh.num_vertices() as u32)
        .filter(|&v| is_boundary[v as usize])
        .map(|v| (v, 0.0))
        .collect();
    let dist = graph_distances(mesh, neighbors, &sources);
    argmax(&dist, |i| !is_boundary[i] && !neighbors[i].is_empty()).map(|v| v as u32)
}

/// Checks the markers against the mesh and resolves the automatic choices (module docs).
///
/// `is_boundary` (#V) flags boundary vertices, `neighbors` (#V) are vertex adjacency lists.
/// Errors: index out of range, a center on the boundary, a boundary marker not on the
/// boundary, barycentric coordinates that are negative or do not sum to 1 (±1e-9), a center
/// point in a face whose corners all lie on the boundary.
pub fn resolve_markers(
    mesh: &TriMesh,
    is_boundary: &[bool],
    neighbors: &[Vec<u32>],
    markers: &Markers,
) -> Result<ResolvedMarkers, ConformalError> {
    let n = mesh.num_vertices();
    let nf = mesh.num_faces();
    let center = match &markers.center {
        CenterMarker::Vertex(v) => {
            if *v as usize >= n {
                return Err(ConformalError::InvalidMarker(format!(
                    "center vertex {v} out of range (the mesh has {n} vertices)"
                )));
            }
            ResolvedCenter::Vertex(*v)
        }
        CenterMarker::Barycentric { face, bary } => {
            if *face as usize >= nf {
                return Err(ConformalError::InvalidMarker(format!(
                    "center face {face} out of range (the mesh has {nf} faces)"
                )));
            }
            if bary.iter().any(|b| !b.is_finite() || *b < -1e-12) || (bary.iter().sum::<f64>() - 1.0).abs() > 1e-9 {
                return Err(ConformalError::InvalidMarker(format!(
                    "barycentric coordinates {bary:?} must be non-negative and sum to 1"
                )));
            }
            ResolvedCenter::Face {
                face: *face,
                bary: *bary,
            }
        }
        CenterMarker::Point(p) => {
            if p.iter()
                .any(|c| !(c.is_finite() && c.abs() <= shapespace_geometry::topology::MAX_COORDINATE))
            {
                return Err(ConformalError::InvalidMarker(format!(
                    "center point ({:e}, {:e}, {:e}) is not finite or beyond the usable coordinate range (|x| <= {:e})",
                    p[0],
                    p[1],
                    p[2],
                    shapespace_geometry::topology::MAX_COORDINATE
                )));
            }
            let mut best = (f64::INFINITY, 0usize, [1.0, 0.0, 0.0]);
            for f in 0..nf {
                let [a, b, c] = mesh.face_positions(f);
                let bc = closest_point_barycentric(*p, a, b, c);
                let q = [0, 1, 2].map(|d| bc[0] * a[d] + bc[1] * b[d] + bc[2] * c[d]);
                let d2 = (q[0] - p[0]).powi(2) + (q[1] - p[1]).powi(2) + (q[2] - p[2]).powi(2);
                if d2 < best.0 {
                    best = (d2, f, bc);
                }
            }
            if !best.0.is_finite() {
                return Err(ConformalError::InvalidMarker(
                    "the mesh has no face to project the center onto".into(),
                ));
            }
            ResolvedCenter::Face {
                face: best.1 as u32,
                bary: best.2,
            }
        }
        CenterMarker::Auto => ResolvedCenter::Vertex(
            central_vertex(mesh, is_boundary, neighbors)
                .ok_or_else(|| ConformalError::InvalidMarker("the mesh has no interior vertex".into()))?,
        ),
    };
    // snap a face point that sits on a corner to the vertex
    let center = match center {
        ResolvedCenter::Face { face, bary } => {
            let k = (0..3)
                .max_by(|&i, &j| bary[i].total_cmp(&bary[j]).then(j.cmp(&i)))
                .unwrap_or(0);
            if bary[k] >= 1.0 - 1e-12 {
                ResolvedCenter::Vertex(mesh.faces[face as usize][k])
            } else {
                let corners = mesh.faces[face as usize];
                if corners.iter().all(|&v| is_boundary[v as usize]) {
                    return Err(ConformalError::InvalidMarker(format!(
                        "center point lies in face {face} whose corners are all on the boundary; choose a point farther inside"
                    )));
                }
                ResolvedCenter::Face { face, bary }
            }
        }
        c => c,
    };
    if let ResolvedCenter::Vertex(v) = center {
        if is_boundary[v as usize] {
            return Err(ConformalError::InvalidMarker(format!(
                "center vertex {v} lies on the boundary; it must be interior"
            )));
        }
    }
    let boundary_vertex = match markers.boundary {
        BoundaryMarker::Vertex(q) => {
            if q as usize >= n {
                return Err(ConformalError::InvalidMarker(format!(
                    "boundary marker {q} out of range (the mesh has {n} vertices)"
                )));
            }
            if !is_boundary[q as usize] {
                return Err(ConformalError::InvalidMarker(format!(
                    "boundary marker {q} is not a boundary vertex"
                )));
            }
            q
        }
        BoundaryMarker::Auto => {
            let sources: Vec<(u32, f64)> = match center {
                ResolvedCenter::Vertex(v) => vec![(v, 0.0)],
                ResolvedCenter::Face { face, bary } => {
                    let corners = mesh.faces[face as usize];
                    let pts = corners.map(|v| mesh.positions[v as usize]);
                    let x = [0, 1, 2].map(|d| bary[0] * pts[0][d] + bary[1] * pts[1][d] + bary[2] * pts[2][d]);
                    (0..3)
                        .map(|k| {
                            let p = pts[k];
                            (
                                corners[k],
                                ((p[0] - x[0]).powi(2) + (p[1] - x[1]).powi(2) + (p[2] - x[2]).powi(2)).sqrt(),
                            )
                        })
                        .collect()
                }
            };
            let dist = graph_distances(mesh, neighbors, &sources);
            argmax(&dist, |i| is_boundary[i]).ok_or_else(|| {
                ConformalError::InvalidMarker("no boundary vertex is reachable from the center".into())
            })? as u32
        }
    };
    Ok(ResolvedMarkers {
        center,
        boundary_vertex,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn resolved_center_reads_as_words() {
        assert_eq!(ResolvedCenter::Vertex(4841).to_string(), "vertex 4841");
        let face = ResolvedCenter::Face {
            face: 12,
            bary: [0.25, 0.25, 0.5],
        };
        assert_eq!(face.to_string(), "face 12 at (0.25, 0.25, 0.5)");
    }

    #[test]
    fn parse_cli_strings() {
        assert_eq!(CenterMarker::parse("auto").unwrap(), CenterMarker::Auto);
        assert_eq!(CenterMarker::parse(" 17 ").unwrap(), CenterMarker::Vertex(17));
        assert_eq!(
            CenterMarker::parse("1,-2.5,3e-1").unwrap(),
            CenterMarker::Point([1.0, -2.5, 0.3])
        );
        assert!(CenterMarker::parse("1,2").is_err());
        assert!(CenterMarker::parse("-3").is_err());
        assert!(CenterMarker::parse("1,nan,2").is_err());
        assert_eq!(BoundaryMarker::parse("AUTO").unwrap(), BoundaryMarker::Auto);
        assert_eq!(BoundaryMarker::parse("5").unwrap(), BoundaryMarker::Vertex(5));
        assert!(BoundaryMarker::parse("x").is_err());
    }

    /// Resolved markers serialize as a marker file that parses back to the same markers.
    #[test]
    fn resolved_markers_round_trip_through_a_marker_file() {
        for center in [
            ResolvedCenter::Vertex(17),
            ResolvedCenter::Face {
                face: 4,
                bary: [0.25, 0.125, 0.625],
            },
        ] {
            let resolved = ResolvedMarkers {
                center,
                boundary_vertex: 9,
            };
            let text = serde_json::to_string(&resolved).unwrap();
            let f = MarkerFile::from_json_str(&text, "report.json").unwrap();
            let expected = match center {
                ResolvedCenter::Vertex(v) => CenterMarker::Vertex(v),
                ResolvedCenter::Face { face, bary } => CenterMarker::Barycentric { face, bary },
            };
            assert_eq!(f.markers.center, expected, "{text}");
            assert_eq!(f.markers.boundary, BoundaryMarker::Vertex(9), "{text}");
        }
    }

    #[test]
    fn parse_json_files() {
        let f = MarkerFile::from_json_str(
            r#"{"center": 123, "boundary": 456, "landmarks": {"nose": 7, "chin": 9}}"#,
            "t.json",
        )
        .unwrap();
        assert_eq!(f.markers.center, CenterMarker::Vertex(123));
        assert_eq!(f.markers.boundary, BoundaryMarker::Vertex(456));
        assert_eq!(f.landmarks.get("chin"), Some(&9));
        // a byte-order mark first (it was "expected value at line 1 column 1")
        let f = MarkerFile::from_json_str("\u{feff}{\"center\": 12, \"boundary\": 4}", "t.json").unwrap();
        assert_eq!(f.markers.center, CenterMarker::Vertex(12));
        let f = MarkerFile::from_json_str(r#"{"center": {"face": 3, "bary": [0.2, 0.3, 0.5]}}"#, "t.json").unwrap();
        assert_eq!(
            f.markers.center,
            CenterMarker::Barycentric {
                face: 3,
                bary: [0.2, 0.3, 0.5]
            }
        );
        assert_eq!(f.markers.boundary, BoundaryMarker::Auto);
        let f = MarkerFile::from_json_str(r#"{"center": [1, 2, 3], "boundary": "auto"}"#, "t.json").unwrap();
        assert_eq!(f.markers.center, CenterMarker::Point([1.0, 2.0, 3.0]));
        let e = MarkerFile::from_json_str(r#"{"center": -1}"#, "x.json")
            .unwrap_err()
            .to_string();
        assert!(e.starts_with("x.json: "), "{e}");
        assert!(MarkerFile::from_json_str("{", "x.json").is_err());
        assert!(MarkerFile::from_json_str(r#"{"landmarks": {"a": 1.5}}"#, "x.json").is_err());
        // a key named twice in one object, at the top or among the landmarks
        for text in [
            "{\"landmarks\": {\"a\": 1,\n \"a\": 2}}",
            "{\"center\": 1,\n \"center\": 2}",
        ] {
            let e = MarkerFile::from_json_str(text, "x.json").unwrap_err().to_string();
            assert!(
                e.contains("x.json") && e.contains("appears twice") && e.contains("line 2"),
                "{e}"
            );
        }
        // the same name in two different objects is fine
        let f = MarkerFile::from_json_str(
            r#"{"center": {"face": 1, "bary": [0.2, 0.3, 0.5]}, "landmarks": {"face": 3}}"#,
            "x.json",
        )
        .unwrap();
        assert_eq!(f.landmarks.get("face"), Some(&3));
        // a misspelt key is an error naming it, not a silent fallback to automatic markers
        let e = MarkerFile::from_json_str(r#"{"centre": 40}"#, "x.json")
            .unwrap_err()
            .to_string();
        assert!(e.starts_with("x.json: ") && e.contains("`centre`"), "{e}");
        // comments and `_`-keys are ignored
        let f =
            MarkerFile::from_json_str(r#"{"comment": "made by hand", "_by": "me", "center": 4}"#, "t.json").unwrap();
        assert_eq!(f.markers.center, CenterMarker::Vertex(4));
    }

    #[test]
    fn closest_point_regions() {
        let (a, b, c) = ([0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0]);
        assert_eq!(closest_point_barycentric([-1.0, -1.0, 0.0], a, b, c), [1.0, 0.0, 0.0]);
        let bc = closest_point_barycentric([0.25, 0.25, 5.0], a, b, c);
        assert!((bc[0] - 0.5).abs() < 1e-15 && (bc[1] - 0.25).abs() < 1e-15);
        let bc = closest_point_barycentric([0.5, -3.0, 0.0], a, b, c);
        assert_eq!(bc, [0.5, 0.5, 0.0]);
    }
}
