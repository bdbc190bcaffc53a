//! Semi-discrete optimal transport on the unit sphere S² with the chordal quadratic cost
//! |x − y|² = 2 − 2⟨x, y⟩: a density constant on each flat triangle of a spherical
//! triangulation ([`SphereMeasure`]) to points y_i on S² with masses ν_i.
//!
//! Heights h and weights w_i = 2h_i + |y_i|² = 2h_i + 1 follow the planar conventions
//! (conventions, "Heights and weights"; "Closed genus-0 surfaces"): the Laguerre cell of y_i is
//! where ⟨x, y_i⟩ + h_i is largest, the 3D power cell of weight w_i, and since every |y_i| = 1
//! the Voronoi start is h = 0. Cells are computed per flat source triangle ([`cells`]), the
//! solver is damped Newton ([`newton`]); docs/decisions/0021-spherical-laguerre-cells.md
//! explains the construction.

pub mod cells;
pub mod measure;
pub mod multiscale;
pub mod newton;

pub use cells::{CellPiece, SiteTree, SphereCells, SphereIntegrator};
pub use measure::{fibonacci_sphere, icosphere, random_sphere_points, spherical_area, SphereMeasure};
pub use newton::{
    normalize_sphere_points, solve_sphere_ot, SphereIteration, SphereOtParams, SphereOtSolution, SphereStart,
};
