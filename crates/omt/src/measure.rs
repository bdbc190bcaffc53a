//! The source measure of semi-discrete OT: a density that is constant on each triangle of a
//! planar triangulation whose union Ω is convex (the unit disk as an inscribed polygon, a square,
//! a convex polygon, or the conformal image of a mesh).

use crate::error::OmtError;

/// A piecewise-constant density on a planar triangulation covering a convex domain Ω.
///
/// `vertices` (#M), `triangles` (#T, counter-clockwise) and `densities` (#T, > 0, mass per unit
/// area). The measure of a set A is Σ_t `densities[t]`·|A ∩ t|.
///
/// Plain data: what a solve builds from a measure and could reuse lives in a
/// [`crate::PreparedMeasure`].
#[derive(Clone, Debug, PartialEq)]
pub struct SourceMeasure {
    pub vertices: Vec<[f64; 2]>,
    pub triangles: Vec<[u32; 3]>,
    pub densities: Vec<f64>,
}

/// Signed area of a polygon (positive counter-clockwise): the fan sum of
/// [`crate::polygon::polygon_integrals`].
fn signed_area(p: &[[f64; 2]]) -> f64 {
    crate::polygon::polygon_integrals(p).0
}

impl SourceMeasure {
    /// Checks shapes, finiteness, positive densities and counter-clockwise, non-degenerate
    /// triangles.
    pub fn new(vertices: Vec<[f64; 2]>, triangles: Vec<[u32; 3]>, densities: Vec<f64>) -> Result<Self, OmtError> {
        if triangles.len() != densities.len() {
            return Err(OmtError::InvalidInput(format!(
                "{} triangles but {} densities",
                triangles.len(),
                densities.len()
            )));
        }
        if triangles.is_empty() {
            return Err(OmtError::InvalidInput("the source measure has no triangle".into()));
        }
        if let Some(i) = vertices.iter().position(|p| !(p[0].is_finite() && p[1].is_finite())) {
            return Err(OmtError::InvalidInput(format!("source vertex {i} is not finite")));
        }
        for (t, tri) in triangles.iter().enumerate() {
            if tri.iter().any(|&v| v as usize >= vertices.len()) {
                return Err(OmtError::InvalidInput(format!(
                    "source triangle {t} has an out-of-range vertex"
                )));
            }
            let d = densities[t];
            if !(d.is_finite() && d > 0.0) {
                return Err(OmtError::InvalidInput(format!(
                    "source triangle {t} has density {d} (must be finite and > 0)"
                )));
            }
            let [a, b, c] = tri.map(|v| vertices[v as usize]);
            let area2 = (b[0] - a[0]) * (c[1] - a[1]) - (b[1] - a[1]) * (c[0] - a[0]);
            if !(area2 > 0.0) {
                return Err(OmtError::InvalidInput(format!(
                    "source triangle {t} is degenerate or clockwise (signed double area {area2:e})"
                )));
            }
        }
        Ok(SourceMeasure {
            vertices,
            triangles,
            densities,
        })
    }

    /// Uniform density `density` on a convex polygon given counter-clockwise, triangulated as a
    /// fan from its vertex average. Errors for fewer than 3 vertices and for a polygon that is
    /// not convex and counter-clockwise (its signed area differs from its
    /// convex hull's by more than 1e-9 relative: the solver clips cells to the convex hull).
    pub fn uniform_polygon(polygon: &[[f64; 2]], density: f64) -> Result<Self, OmtError> {
        if polygon.len() < 3 {
            return Err(OmtError::InvalidInput("a polygon needs at least 3 vertices".into()));
        }
        let (area, hull) = (signed_area(polygon), signed_area(&crate::polygon::convex_hull(polygon)));
        if !((area - hull).abs() <= 1e-9 * hull.abs()) {
            return Err(OmtError::InvalidInput(format!(
                "the polygon is not convex and counter-clockwise: its signed area {area:e} differs from its convex hull's {hull:e}"
            )));
        }
        let n = polygon.len();
        let c = polygon.iter().fold([0.0, 0.0], |acc, p| {
            [acc[0] + p[0] / n as f64, acc[1] + p[1] / n as f64]
        });
        let mut vertices = polygon.to_vec();
        vertices.push(c);
        let triangles = (0..n)
            .map(|i| [n as u32, i as u32, ((i + 1) % n) as u32])
            .collect::<Vec<_>>();
        let densities = vec![density; n];
        Self::new(vertices, triangles, densities)
    }

    /// The unit disk as a regular inscribed polygon with `boundary_vertices` vertices (one at
    /// angle 0), uniform density 1 scaled so the total mass is the polygon's area.
    pub fn unit_disk(boundary_vertices: usize) -> Result<Self, OmtError> {
        let polygon: Vec<[f64; 2]> = (0..boundary_vertices)
            .map(|k| {
                let t = 2.0 * std::f64::consts::PI * k as f64 / boundary_vertices as f64;
                [t.cos(), t.sin()]
            })
            .collect();
        Self::uniform_polygon(&polygon, 1.0)
    }

    /// The unit square \[0, 1\]², uniform density 1.
    pub fn unit_square() -> Result<Self, OmtError> {
        Self::uniform_polygon(&[[0.0, 0.0], [1.0, 0.0], [1.0, 1.0], [0.0, 1.0]], 1.0)
    }

    /// The convex hull of the vertices some triangle uses (counter-clockwise): Ω's boundary
    /// when Ω is convex, the polygon the solver clips cells to. Unreferenced vertices do not
    /// count (they would widen the cells).
    pub(crate) fn domain_hull(&self) -> Vec<[f64; 2]> {
        let mut used = vec![false; self.vertices.len()];
        for t in &self.triangles {
            t.iter().for_each(|&v| used[v as usize] = true);
        }
        let points: Vec<[f64; 2]> = self
            .vertices
            .iter()
            .zip(&used)
            .filter(|(_, &u)| u)
            .map(|(p, _)| *p)
            .collect();
        crate::polygon::convex_hull(&points)
    }

    /// How far the triangles fall short of covering the convex hull of the vertices they use:
    /// (hull area − Σ triangle areas) / hull area; 0 for a triangulated convex domain, positive
    /// for a non-convex one (or gaps), negative where triangles overlap. The solver clips cells
    /// to that hull, so only a convex domain gives right cell shapes.
    pub fn convexity_gap(&self) -> f64 {
        let hull_area = signed_area(&self.domain_hull());
        let area: f64 = self
            .triangles
            .iter()
            .map(|t| {
                let [a, b, c] = t.map(|v| self.vertices[v as usize]);
                0.5 * ((b[0] - a[0]) * (c[1] - a[1]) - (b[1] - a[1]) * (c[0] - a[0])).abs()
            })
            .sum();
        (hull_area - area) / hull_area
    }

    /// Total mass μ(Ω) = Σ_t ρ_t |t|.
    pub fn total_mass(&self) -> f64 {
        self.triangles
            .iter()
            .zip(&self.densities)
            .map(|(tri, d)| {
                let [a, b, c] = tri.map(|v| self.vertices[v as usize]);
                0.5 * ((b[0] - a[0]) * (c[1] - a[1]) - (b[1] - a[1]) * (c[0] - a[0])) * d
            })
            .sum()
    }
}
