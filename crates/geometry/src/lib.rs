//! # shapespace-geometry
//!
//! Triangle meshes over flat arrays (`Vec<[f64; 3]>` positions, `Vec<[u32; 3]>` faces, indices
//! kept as in the file), their I/O, topology, preparation operations and discrete differential
//! operators. See `ARCHITECTURE.md`.
//!
//! ```
//! use shapespace_geometry::topology::{mesh_report, MeshClass};
//! use shapespace_geometry::TriMesh;
//!
//! // the unit square as two triangles: a disk of area 1 whose four vertices are all on the boundary
//! let square = TriMesh::new(
//!     vec![[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [1.0, 1.0, 0.0], [0.0, 1.0, 0.0]],
//!     vec![[0, 1, 2], [0, 2, 3]],
//! )?;
//! let report = mesh_report(&square)?;
//! assert_eq!(report.classification.class, MeshClass::Disk);
//! assert_eq!((report.num_boundary_loops, report.euler_characteristic), (1, 1));
//! assert!((report.area - 1.0).abs() < 1e-15);
//! # Ok::<(), shapespace_geometry::GeometryError>(())
//! ```

pub mod connectivity;
pub mod curvature;
pub mod error;
pub mod io;
pub mod laplacian;
pub mod mesh;
pub mod paths;
pub mod predicates;
pub mod prepare;
pub mod primitives;
pub mod quantities;
pub mod repair;
pub mod seam;
pub mod spectral;
pub mod topology;
pub mod vec3;

pub use connectivity::Connectivity;
pub use error::GeometryError;
pub use mesh::TriMesh;
