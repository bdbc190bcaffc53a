//! The triangle mesh type: flat arrays of positions and faces, indices kept as in the source file.

use crate::error::GeometryError;

/// A triangle mesh over flat arrays.
///
/// `positions` has #V entries, `faces` has #F entries of 0-based vertex indices. Vertex order is
/// the order of the source file: readers never renumber, so vertex `i` of two files with the same
/// connectivity corresponds (the ground truth of the pose and face datasets).
#[derive(Clone, Debug, Default, PartialEq)]
pub struct TriMesh {
    /// Vertex positions, #V.
    pub positions: Vec<[f64; 3]>,
    /// Triangles, #F, counter-clockwise when seen from the outside (when consistently oriented).
    pub faces: Vec<[u32; 3]>,
    /// Optional per-vertex texture coordinates (#V when present), e.g. disk coordinates.
    pub uvs: Option<Vec<[f64; 2]>>,
}

impl TriMesh {
    /// A mesh from positions and faces, checking that every index is in range and every
    /// coordinate is finite.
    pub fn new(positions: Vec<[f64; 3]>, faces: Vec<[u32; 3]>) -> Result<Self, GeometryError> {
        let mesh = TriMesh {
            positions,
            faces,
            uvs: None,
        };
        mesh.validate()?;
        Ok(mesh)
    }

    /// Number of vertices #V.
    pub fn num_vertices(&self) -> usize {
        self.positions.len()
    }

    /// Number of faces #F.
    pub fn num_faces(&self) -> usize {
        self.faces.len()
    }

    /// Whether `other` is the same triangulation: the same vertex count and the same faces in
    /// the same order, whatever the positions (the poses of a consistently meshed set).
    pub fn same_triangulation(&self, other: &TriMesh) -> bool {
        self.num_vertices() == other.num_vertices() && self.faces == other.faces
    }

    /// Checks index ranges and finiteness of coordinates (and of UVs, with their count).
    pub fn validate(&self) -> Result<(), GeometryError> {
        let n = self.positions.len();
        for (i, p) in self.positions.iter().enumerate() {
            if !p.iter().all(|c| c.is_finite()) {
                return Err(GeometryError::NonFiniteCoordinate { vertex: i });
            }
        }
        for (f, face) in self.faces.iter().enumerate() {
            for &v in face {
                if v as usize >= n {
                    return Err(GeometryError::IndexOutOfRange {
                        face: f,
                        index: v as i64,
                        num_vertices: n,
                    });
                }
            }
        }
        if let Some(uvs) = &self.uvs {
            if uvs.len() != n {
                return Err(GeometryError::Invalid(format!(
                    "{} texture coordinates for {} vertices",
                    uvs.len(),
                    n
                )));
            }
        }
        Ok(())
    }

    /// The three corner positions of face `f`.
    #[inline]
    pub fn face_positions(&self, f: usize) -> [[f64; 3]; 3] {
        let [a, b, c] = self.faces[f];
        [
            self.positions[a as usize],
            self.positions[b as usize],
            self.positions[c as usize],
        ]
    }
}
