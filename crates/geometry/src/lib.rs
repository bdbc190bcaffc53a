//! # shapespace-geometry
//!
//! Triangle meshes over flat arrays (`Vec<[f64; 3]>` positions, `Vec<[u32; 3]>` faces, indices
//! kept as in the file), their I/O, topology, preparation operations and discrete differential
//! operators. See `ARCHITECTURE.md`.

pub mod connectivity;
pub mod curvature;
pub mod error;
pub mod io;
pub mod laplacian;
pub mod mesh;
pub mod predicates;
pub mod prepare;
pub mod primitives;
pub mod quantities;
pub mod repair;
pub mod seam;
pub mod topology;
pub mod vec3;

pub use connectivity::Connectivity;
pub use error::GeometryError;
pub use mesh::TriMesh;
