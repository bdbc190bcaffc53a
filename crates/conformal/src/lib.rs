//! # shapespace-conformal
//!
//! Conformal maps of disk-type surfaces onto the unit disk (the discrete Riemann map with an
//! interior marker p ↦ 0 and a boundary marker q ↦ 1), Möbius normalization, map quality
//! measures and constrained harmonic maps. See `ARCHITECTURE.md` for the code map and the measured
//! accuracy, and `docs/decisions/0001-green-function-disk-map.md` for the choice of method.
//!
//! * [`disk_map()`]: the Riemann map (Green's function + harmonic conjugate on the intrinsic
//!   Delaunay triangulation), with densities and conformal factors;
//! * [`bff`]: the same map by Boundary First Flattening with the disk target: second order on
//!   smooth surfaces, less accurate than the Green's map on the real meshes measured, so not
//!   the default (`docs/decisions/0001-green-function-disk-map.md`);
//! * [`mobius`]: disk automorphisms z ↦ e^{iθ}(z − a)/(1 − āz);
//! * [`markers`]: interior/boundary markers, parsing and automatic choices;
//! * [`quality`]: area, quasi-conformal and angle distortion, flips;
//! * [`harmonic`]: harmonic maps with boundary and landmark constraints;
//! * [`intrinsic`]: intrinsic triangulations and Delaunay edge flips;
//! * [`sphere`]: conformal maps of closed genus-0 surfaces onto the unit sphere
//!   ([`sphere_map()`]), three-marker and Möbius-centering normalizations.
//!
//! ```
//! use shapespace_conformal::{disk_map, DiskMapParams, Markers};
//! use shapespace_geometry::primitives::spherical_cap;
//!
//! // a hemisphere with its pole as the centre: the conformal map is stereographic projection,
//! // r = tan(θ/2) (first order in the edge length, `docs/conventions.md`)
//! let cap = spherical_cap(std::f64::consts::FRAC_PI_2, 24);
//! let map = disk_map(&cap, &Markers::default(), &DiskMapParams::default())?;
//! assert_eq!(map.quality.num_flipped, 0);
//! let ring = 12; // vertices of ring k are at polar angle θ = (π/2)·k/24
//! let v = 1 + 3 * ring * (ring - 1); // the first vertex of that ring
//! let r = map.uv[v][0].hypot(map.uv[v][1]);
//! assert!((r - (std::f64::consts::FRAC_PI_8).tan()).abs() < 5e-3, "r = {r}");
//! # Ok::<(), shapespace_conformal::ConformalError>(())
//! ```

// `!(x > 0.0)` is used on purpose: it also rejects NaN. Index loops mirror the mathematics.
#![allow(clippy::neg_cmp_op_on_partial_ord, clippy::needless_range_loop)]

pub mod bff;
pub mod disk_map;
pub mod error;
mod finish;
pub mod fold_repair;
pub mod green;
pub mod harmonic;
pub mod intrinsic;
mod linsolve;
pub mod markers;
pub mod mobius;
pub mod quality;
pub mod sphere;

pub use bff::{bff_disk_coordinates, bff_disk_map, BffCoordinates, BffDiskMap, BffInfo, BffParams};
pub use disk_map::{disk_map, resolve_markers_of, Construction, DiskMap, DiskMapInfo, DiskMapParams, PolePlacement};
pub use error::ConformalError;
pub use harmonic::{harmonic_map, BoundaryConstraint, HarmonicConstraints};
pub use markers::{BoundaryMarker, CenterMarker, MarkerFile, Markers};
pub use mobius::Mobius;
pub use sphere::{sphere_map, SphereMap, SphereMapInfo, SphereMapParams, SphereNormalization};
