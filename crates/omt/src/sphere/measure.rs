//! The source measure on the sphere: a density that is constant on each flat (chordal) triangle
//! of a triangulation whose vertices lie on the unit sphere S², and reproducible spherical
//! inputs (icospheres, Fibonacci and random points) for tests and benchmarks.
//!
//! Masses are taken on the flat triangles: face f carries μ(f) = ρ_f · area(flat f). A density
//! meant on the sphere (a mass per spherical triangle) is converted by
//! ρ_f = mass / area(flat f) ([`SphereMeasure::from_spherical_density`] does this for a density
//! function). The cells then split each flat triangle; a cell's mass differs from the mass of
//! its radial projection on S² by O(h²) relative (h the edge length), since the radial
//! projection's area factor varies by O(h²) across a face.

use crate::error::OmtError;
use crate::synthetic::uniform01;

/// A vertex is accepted on the unit sphere when | |v| − 1 | is at most this.
pub const SPHERE_TOLERANCE: f64 = 1e-6;

/// A piecewise-constant density on a triangulation of the unit sphere by flat triangles.
#[derive(Clone, Debug)]
pub struct SphereMeasure {
    /// Vertices, on S² (within [`SPHERE_TOLERANCE`]).
    pub vertices: Vec<[f64; 3]>,
    /// Triangles (any orientation), #M.
    pub triangles: Vec<[u32; 3]>,
    /// Density per triangle, per unit area of the flat triangle, #M, positive.
    pub densities: Vec<f64>,
}

impl SphereMeasure {
    /// Validates and builds: finite vertices on S², valid indices, non-degenerate triangles,
    /// finite positive densities. Errors name the offending vertex, triangle or density.
    pub fn new(vertices: Vec<[f64; 3]>, triangles: Vec<[u32; 3]>, densities: Vec<f64>) -> Result<Self, OmtError> {
        if triangles.is_empty() {
            return Err(OmtError::InvalidInput("the spherical source has no triangles".into()));
        }
        if densities.len() != triangles.len() {
            return Err(OmtError::InvalidInput(format!(
                "{} densities for {} triangles",
                densities.len(),
                triangles.len()
            )));
        }
        for (k, v) in vertices.iter().enumerate() {
            let r = norm(*v);
            if !v.iter().all(|c| c.is_finite()) || (r - 1.0).abs() > SPHERE_TOLERANCE {
                return Err(OmtError::InvalidInput(format!(
                    "vertex {k} ({}, {}, {}) is not on the unit sphere (|v| = {r})",
                    v[0], v[1], v[2]
                )));
            }
        }
        for (t, tri) in triangles.iter().enumerate() {
            if tri.iter().any(|&i| i as usize >= vertices.len()) {
                return Err(OmtError::InvalidInput(format!(
                    "triangle {t} has a vertex index beyond the {} vertices",
                    vertices.len()
                )));
            }
            let [a, b, c] = tri.map(|i| vertices[i as usize]);
            if !(flat_area(a, b, c) > 0.0) {
                return Err(OmtError::InvalidInput(format!(
                    "triangle {t} is degenerate (zero area)"
                )));
            }
            let d = densities[t];
            if !(d.is_finite() && d > 0.0) {
                return Err(OmtError::InvalidInput(format!(
                    "density {d} of triangle {t} is not positive and finite"
                )));
            }
        }
        Ok(SphereMeasure {
            vertices,
            triangles,
            densities,
        })
    }

    /// The triangulation with ρ_f = ∫ over the spherical triangle of `f` ÷ area(flat f), the
    /// integral approximated by f at the radially projected centroid times the spherical
    /// triangle's area (exact for constant f: the total mass of f ≡ 1 is 4π).
    pub fn from_spherical_density(
        vertices: Vec<[f64; 3]>,
        triangles: Vec<[u32; 3]>,
        f: impl Fn([f64; 3]) -> f64,
    ) -> Result<Self, OmtError> {
        let densities = triangles
            .iter()
            .map(|tri| {
                let [a, b, c] = tri.map(|i| vertices.get(i as usize).copied().unwrap_or([1.0, 0.0, 0.0]));
                let flat = flat_area(a, b, c);
                let centroid = normalize([
                    (a[0] + b[0] + c[0]) / 3.0,
                    (a[1] + b[1] + c[1]) / 3.0,
                    (a[2] + b[2] + c[2]) / 3.0,
                ]);
                f(centroid) * spherical_area(a, b, c) / flat
            })
            .collect();
        SphereMeasure::new(vertices, triangles, densities)
    }

    /// The uniform density 1 on the sphere (total mass 4π) on an icosphere of `subdivisions`
    /// levels (20·4^s triangles).
    pub fn uniform_icosphere(subdivisions: usize) -> Result<Self, OmtError> {
        let (v, t) = icosphere(subdivisions);
        SphereMeasure::from_spherical_density(v, t, |_| 1.0)
    }

    /// μ(S²) = Σ_f ρ_f area(flat f).
    pub fn total_mass(&self) -> f64 {
        self.triangles
            .iter()
            .zip(&self.densities)
            .map(|(tri, d)| d * flat_area_of(&self.vertices, tri))
            .sum()
    }

    /// The mass of each triangle, #M.
    pub fn triangle_masses(&self) -> Vec<f64> {
        self.triangles
            .iter()
            .zip(&self.densities)
            .map(|(tri, d)| d * flat_area_of(&self.vertices, tri))
            .collect()
    }
}

fn flat_area_of(vertices: &[[f64; 3]], tri: &[u32; 3]) -> f64 {
    let [a, b, c] = tri.map(|i| vertices[i as usize]);
    flat_area(a, b, c)
}

/// Area of the flat triangle abc.
pub fn flat_area(a: [f64; 3], b: [f64; 3], c: [f64; 3]) -> f64 {
    0.5 * norm(cross(sub(b, a), sub(c, a)))
}

/// Area of the spherical triangle with unit vertices a, b, c (Van Oosterom–Strackee):
/// tan(E/2) = |a·(b×c)| / (1 + a·b + b·c + c·a).
pub fn spherical_area(a: [f64; 3], b: [f64; 3], c: [f64; 3]) -> f64 {
    let num = dot(a, cross(b, c)).abs();
    let den = 1.0 + dot(a, b) + dot(b, c) + dot(c, a);
    2.0 * num.atan2(den)
}

/// The icosahedron subdivided `subdivisions` times (each triangle into four, new vertices
/// projected on S²): (vertices, triangles oriented outwards).
pub fn icosphere(subdivisions: usize) -> (Vec<[f64; 3]>, Vec<[u32; 3]>) {
    let p = (1.0 + 5f64.sqrt()) / 2.0;
    let mut vertices: Vec<[f64; 3]> = [
        [-1.0, p, 0.0],
        [1.0, p, 0.0],
        [-1.0, -p, 0.0],
        [1.0, -p, 0.0],
        [0.0, -1.0, p],
        [0.0, 1.0, p],
        [0.0, -1.0, -p],
        [0.0, 1.0, -p],
        [p, 0.0, -1.0],
        [p, 0.0, 1.0],
        [-p, 0.0, -1.0],
        [-p, 0.0, 1.0],
    ]
    .into_iter()
    .map(normalize)
    .collect();
    let mut triangles: Vec<[u32; 3]> = vec![
        [0, 11, 5],
        [0, 5, 1],
        [0, 1, 7],
        [0, 7, 10],
        [0, 10, 11],
        [1, 5, 9],
        [5, 11, 4],
        [11, 10, 2],
        [10, 7, 6],
        [7, 1, 8],
        [3, 9, 4],
        [3, 4, 2],
        [3, 2, 6],
        [3, 6, 8],
        [3, 8, 9],
        [4, 9, 5],
        [2, 4, 11],
        [6, 2, 10],
        [8, 6, 7],
        [9, 8, 1],
    ];
    for _ in 0..subdivisions {
        let mut midpoints = std::collections::HashMap::new();
        let mut next = Vec::with_capacity(triangles.len() * 4);
        let mut mid = |a: u32, b: u32, vertices: &mut Vec<[f64; 3]>| -> u32 {
            *midpoints.entry((a.min(b), a.max(b))).or_insert_with(|| {
                let (p, q) = (vertices[a as usize], vertices[b as usize]);
                vertices.push(normalize([p[0] + q[0], p[1] + q[1], p[2] + q[2]]));
                (vertices.len() - 1) as u32
            })
        };
        for &[a, b, c] in &triangles {
            let ab = mid(a, b, &mut vertices);
            let bc = mid(b, c, &mut vertices);
            let ca = mid(c, a, &mut vertices);
            next.extend([[a, ab, ca], [b, bc, ab], [c, ca, bc], [ab, bc, ca]]);
        }
        triangles = next;
    }
    (vertices, triangles)
}

/// `n` points of the Fibonacci (golden-angle) spiral on S²: z_k = 1 − (2k + 1)/n, evenly spread
/// equal-area positions.
pub fn fibonacci_sphere(n: usize) -> Vec<[f64; 3]> {
    let golden = std::f64::consts::PI * (3.0 - 5f64.sqrt());
    (0..n)
        .map(|k| {
            let z = 1.0 - (2 * k + 1) as f64 / n as f64;
            let r = (1.0 - z * z).max(0.0).sqrt();
            let t = golden * k as f64;
            [r * t.cos(), r * t.sin(), z]
        })
        .collect()
}

/// `n` points uniform on S² (z = 2U₁ − 1, azimuth 2πU₂; [`uniform01`] seeded by `seed`).
pub fn random_sphere_points(n: usize, seed: u64) -> Vec<[f64; 3]> {
    let mut s = seed;
    (0..n)
        .map(|_| {
            let z = 2.0 * uniform01(&mut s) - 1.0;
            let t = 2.0 * std::f64::consts::PI * uniform01(&mut s);
            let r = (1.0 - z * z).max(0.0).sqrt();
            [r * t.cos(), r * t.sin(), z]
        })
        .collect()
}

pub(crate) fn sub(a: [f64; 3], b: [f64; 3]) -> [f64; 3] {
    [a[0] - b[0], a[1] - b[1], a[2] - b[2]]
}

pub(crate) fn dot(a: [f64; 3], b: [f64; 3]) -> f64 {
    a[0] * b[0] + a[1] * b[1] + a[2] * b[2]
}

pub(crate) fn cross(a: [f64; 3], b: [f64; 3]) -> [f64; 3] {
    [
        a[1] * b[2] - a[2] * b[1],
        a[2] * b[0] - a[0] * b[2],
        a[0] * b[1] - a[1] * b[0],
    ]
}

pub(crate) fn norm(a: [f64; 3]) -> f64 {
    dot(a, a).sqrt()
}

pub(crate) fn normalize(a: [f64; 3]) -> [f64; 3] {
    let r = norm(a);
    [a[0] / r, a[1] / r, a[2] / r]
}
