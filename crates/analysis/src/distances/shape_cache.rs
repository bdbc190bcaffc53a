//! The per-shape cache of `distances --cache DIR`: what a pairwise run computes once per shape
//! (conformal map, pushed-forward density, target points and masses, after the density peaks'
//! spreading and the target quantization), stored per shape so that shards and later runs do
//! not compute it again.
//!
//! An entry is named by its key ([`entry_key`]): the SHA-256 of the executable
//! ([`crate::resume::build_identity`]), the conformal-map settings and `target_points`, the mesh
//! file's SHA-256 and the markers the shape is mapped with. The markers are those after the
//! automatic markers were shared among the files with the same faces, so the key covers what
//! the other files decide too. An entry holds the shape's pair data and the map's figures that
//! the report shows; the rest of the disk map (its construction's counters and quality
//! statistics) is not kept, and a shape taken from the cache carries only its coordinates,
//! factors, densities, scale and markers (all that the pairs and the report use).
//!
//! Entries are written atomically and end with the SHA-256 of their bytes: a damaged or
//! unreadable entry is a miss (the shape is prepared again and the entry replaced). A shape that
//! fails to prepare is not stored.

use std::path::{Path, PathBuf};
use std::sync::Arc;

use shapespace_conformal::markers::{ResolvedCenter, ResolvedMarkers};
use shapespace_conformal::{DiskMap, DiskMapInfo, Markers, Mobius};
use shapespace_omt::newton::TargetCoarsening;
use shapespace_omt::{PreparedMeasure, SourceMeasure};

use crate::distance::PreparedShape;
use crate::error::AnalysisError;
use crate::resume::sha256_hex;

/// The format's first line; its number changes with the layout, so an entry of another layout
/// is a miss (2: the quantization's second moments after its variance).
const MAGIC: &[u8] = b"shapespace shape cache 2\n";

/// What an entry gives besides the shape: the report's figures of the map.
#[derive(Clone, Debug, PartialEq)]
pub struct CachedFigures {
    pub flipped_faces: usize,
    pub bff_fallback_after_green_folds: Option<usize>,
}

/// The key of a shape's entry (hex SHA-256): executable, settings, file content and markers.
pub fn entry_key(settings: &str, file_sha256: &str, markers: &Markers) -> String {
    let text = format!(
        "{}\u{1e}{settings}\u{1e}{file_sha256}\u{1e}{markers:?}",
        crate::resume::build_identity().unwrap_or_default()
    );
    sha256_hex(text.as_bytes())
}

/// The path of the entry `key` in `dir`.
pub fn entry_path(dir: &Path, key: &str) -> PathBuf {
    dir.join(format!("{key}.shape"))
}

struct Writer(Vec<u8>);

impl Writer {
    fn u64(&mut self, x: u64) {
        self.0.extend_from_slice(&x.to_le_bytes());
    }
    fn f64(&mut self, x: f64) {
        self.0.extend_from_slice(&x.to_le_bytes());
    }
    fn f64s(&mut self, xs: &[f64]) {
        self.u64(xs.len() as u64);
        for &x in xs {
            self.f64(x);
        }
    }
    fn u32s(&mut self, xs: &[u32]) {
        self.u64(xs.len() as u64);
        for x in xs {
            self.0.extend_from_slice(&x.to_le_bytes());
        }
    }
}

struct Reader<'a>(&'a [u8]);

impl Reader<'_> {
    fn take(&mut self, n: usize) -> Option<&[u8]> {
        if self.0.len() < n {
            return None;
        }
        let (head, rest) = self.0.split_at(n);
        self.0 = rest;
        Some(head)
    }
    fn u64(&mut self) -> Option<u64> {
        Some(u64::from_le_bytes(self.take(8)?.try_into().ok()?))
    }
    fn f64(&mut self) -> Option<f64> {
        Some(f64::from_le_bytes(self.take(8)?.try_into().ok()?))
    }
    fn len(&mut self, item: usize) -> Option<usize> {
        let n = usize::try_from(self.u64()?).ok()?;
        (n.checked_mul(item)? <= self.0.len()).then_some(n)
    }
    fn f64s(&mut self) -> Option<Vec<f64>> {
        let n = self.len(8)?;
        (0..n).map(|_| self.f64()).collect()
    }
    fn u32s(&mut self) -> Option<Vec<u32>> {
        let n = self.len(4)?;
        (0..n)
            .map(|_| Some(u32::from_le_bytes(self.take(4)?.try_into().ok()?)))
            .collect()
    }
    fn pairs(&mut self) -> Option<Vec<[f64; 2]>> {
        let flat = self.f64s()?;
        (flat.len() % 2 == 0).then(|| flat.chunks(2).map(|c| [c[0], c[1]]).collect())
    }
}

/// The bytes of an entry for `shape` and its report figures (also how the Python package
/// ships prepared shapes to Dask workers).
pub fn encode(shape: &PreparedShape, figures: &CachedFigures) -> Vec<u8> {
    let mut w = Writer(MAGIC.to_vec());
    let disk = &shape.disk;
    w.u64(disk.info.method.len() as u64);
    w.0.extend_from_slice(disk.info.method.as_bytes());
    match disk.info.markers.center {
        ResolvedCenter::Vertex(v) => {
            w.u64(0);
            w.u64(v as u64);
        }
        ResolvedCenter::Face { face, bary } => {
            w.u64(1);
            w.u64(face as u64);
            bary.iter().for_each(|&b| w.f64(b));
        }
    }
    w.u64(disk.info.markers.boundary_vertex as u64);
    w.f64s(disk.uv.as_flattened());
    w.f64s(&disk.conformal_factor);
    w.f64s(&disk.face_densities);
    w.f64(disk.scale);
    w.f64s(shape.measure.vertices.as_flattened());
    w.u32s(shape.measure.triangles.as_flattened());
    w.f64s(&shape.measure.densities);
    w.f64s(shape.points.as_flattened());
    w.f64s(&shape.masses);
    w.f64(shape.quantization_variance);
    w.f64s(shape.quantization_moments.as_flattened());
    w.u64(figures.flipped_faces as u64);
    w.u64(figures.bff_fallback_after_green_folds.map_or(0, |f| f as u64 + 1));
    let check = sha256_hex(&w.0);
    w.0.extend_from_slice(check.as_bytes());
    w.0
}

/// The shape and figures of an entry's bytes; None when they are not an intact entry.
pub fn decode(bytes: &[u8], name: &str) -> Option<(PreparedShape, CachedFigures)> {
    let (body, check) = bytes.split_at(bytes.len().checked_sub(64)?);
    if sha256_hex(body).as_bytes() != check {
        return None;
    }
    let mut r = Reader(body.strip_prefix(MAGIC)?);
    let method_len = r.len(1)?;
    let method = String::from_utf8(r.take(method_len)?.to_vec()).ok()?;
    let center = match r.u64()? {
        0 => ResolvedCenter::Vertex(u32::try_from(r.u64()?).ok()?),
        1 => ResolvedCenter::Face {
            face: u32::try_from(r.u64()?).ok()?,
            bary: [r.f64()?, r.f64()?, r.f64()?],
        },
        _ => return None,
    };
    let boundary_vertex = u32::try_from(r.u64()?).ok()?;
    let uv = r.pairs()?;
    let conformal_factor = r.f64s()?;
    let face_densities = r.f64s()?;
    let scale = r.f64()?;
    let vertices = r.pairs()?;
    let flat = r.u32s()?;
    if flat.len() % 3 != 0 {
        return None;
    }
    let triangles: Vec<[u32; 3]> = flat.chunks(3).map(|c| [c[0], c[1], c[2]]).collect();
    let densities = r.f64s()?;
    let points = r.pairs()?;
    let masses = r.f64s()?;
    let quantization_variance = r.f64()?;
    let flat = r.f64s()?;
    if flat.len() != 3 * points.len() && !flat.is_empty() {
        return None;
    }
    let quantization_moments: Vec<[f64; 3]> = flat.chunks(3).map(|c| [c[0], c[1], c[2]]).collect();
    let flipped_faces = usize::try_from(r.u64()?).ok()?;
    let bff = r.u64()?;
    if !r.0.is_empty() || points.len() != masses.len() {
        return None;
    }
    let measure = PreparedMeasure::new(SourceMeasure::new(vertices, triangles, densities).ok()?);
    let coarsening = Arc::new(TargetCoarsening::new(&points, &masses));
    let disk = DiskMap {
        uv,
        conformal_factor,
        face_densities,
        scale,
        info: DiskMapInfo {
            method,
            markers: ResolvedMarkers {
                center,
                boundary_vertex,
            },
            pole: 0,
            mobius: Mobius {
                a: [0.0, 0.0],
                theta: 0.0,
            },
            intrinsic_flips: 0,
            inserted_vertices: 0,
            negative_weights_before: 0,
            negative_weights_after: 0,
            fold_repairs: 0,
            boundary_from_flux: false,
            linear_solves: 0,
            timings: Default::default(),
            bff_fallback: None,
            // the method string keeps the region repair's note
            region_repair: None,
        },
        quality: Default::default(),
    };
    let shape = PreparedShape {
        name: name.to_string(),
        disk,
        measure,
        peak_spreading: Default::default(),
        points,
        masses,
        coarsening,
        seconds: 0.0,
        quantization_variance,
        quantization_moments,
    };
    let figures = CachedFigures {
        flipped_faces,
        bff_fallback_after_green_folds: bff.checked_sub(1).map(|f| f as usize),
    };
    Some((shape, figures))
}

/// The shape `name` of the entry `key` in `dir`, if there is an intact one.
pub fn load(dir: &Path, key: &str, name: &str) -> Option<(PreparedShape, CachedFigures)> {
    let bytes = std::fs::read(entry_path(dir, key)).ok()?;
    decode(&bytes, name)
}

/// Stores `shape` under `key` in `dir` (atomically; an entry already there is replaced).
pub fn store(dir: &Path, key: &str, shape: &PreparedShape, figures: &CachedFigures) -> Result<(), AnalysisError> {
    let path = entry_path(dir, key);
    shapespace_geometry::io::write_atomically(&path, &encode(shape, figures)).map_err(|e| AnalysisError::io(&path, e))
}

#[cfg(test)]
mod tests {
    use super::*;

    /// An entry reads back to the same pair data and figures; a changed byte makes it a miss.
    #[test]
    fn entries_round_trip_and_damage_is_a_miss() {
        let mesh = shapespace_test_support::repo("datasets/faces/id00_happy.obj");
        let mesh = shapespace_geometry::io::read_mesh(&mesh).unwrap();
        let shape = crate::distance::prepare_shape("a", &mesh, &Markers::default(), &Default::default()).unwrap();
        let figures = CachedFigures {
            flipped_faces: 3,
            bff_fallback_after_green_folds: Some(0),
        };
        let bytes = encode(&shape, &figures);
        let (back, figures_back) = decode(&bytes, "a").unwrap();
        assert_eq!(figures_back, figures);
        assert_eq!(back.points, shape.points);
        assert_eq!(back.masses, shape.masses);
        assert_eq!(back.measure.vertices, shape.measure.vertices);
        assert_eq!(back.measure.triangles, shape.measure.triangles);
        assert_eq!(back.measure.densities, shape.measure.densities);
        assert_eq!(back.disk.uv, shape.disk.uv);
        assert_eq!(back.disk.info.markers, shape.disk.info.markers);
        assert_eq!(back.disk.scale, shape.disk.scale);
        let mut damaged = bytes.clone();
        damaged[MAGIC.len() + 40] ^= 1;
        assert!(decode(&damaged, "a").is_none());
        assert!(decode(&bytes[..bytes.len() - 1], "a").is_none());
        // a quantized shape keeps its groups' second moments
        let q = crate::distance::quantize_target(shape, 1000);
        let (back, _) = decode(&encode(&q, &figures), "a").unwrap();
        assert_eq!(back.points, q.points);
        assert_eq!(back.quantization_variance, q.quantization_variance);
        assert_eq!(back.quantization_moments, q.quantization_moments);
        assert_eq!(back.quantization_moments.len(), back.points.len());
    }

    /// An intact entry of the first layout (no second moments; its own checksum right) is a
    /// miss, not read as the current layout.
    #[test]
    fn entries_of_the_previous_layout_are_a_miss() {
        let mesh = shapespace_test_support::repo("datasets/faces/id00_happy.obj");
        let mesh = shapespace_geometry::io::read_mesh(&mesh).unwrap();
        let shape = crate::distance::prepare_shape("a", &mesh, &Markers::default(), &Default::default()).unwrap();
        let shape = crate::distance::quantize_target(shape, 1000);
        let figures = CachedFigures {
            flipped_faces: 0,
            bff_fallback_after_green_folds: None,
        };
        let bytes = encode(&shape, &figures);
        let body = &bytes[MAGIC.len()..bytes.len() - 64];
        // the first layout: the same fields without the moments (a length and 3 × #G values)
        let moments = 8 + 24 * shape.points.len();
        let before = body.len() - 16 - moments;
        let mut old = b"shapespace shape cache 1\n".to_vec();
        old.extend_from_slice(&body[..before]);
        old.extend_from_slice(&body[before + moments..]);
        let check = sha256_hex(&old);
        old.extend_from_slice(check.as_bytes());
        assert!(decode(&old, "a").is_none());
        // (the same bytes under the current first line are a well-formed entry of its layout
        // only with the moments)
        let mut relabelled = MAGIC.to_vec();
        relabelled.extend_from_slice(&old[b"shapespace shape cache 1\n".len()..old.len() - 64]);
        let check = sha256_hex(&relabelled);
        relabelled.extend_from_slice(check.as_bytes());
        assert!(decode(&relabelled, "a").is_none());
    }
}
