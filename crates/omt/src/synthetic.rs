//! Reproducible synthetic inputs for the benchmarks and probes: uniform random points in the
//! unit disk (SplitMix64 from a fixed seed) and a ring triangulation of the unit disk carrying a
//! density function. The solver does not use them.

use crate::error::OmtError;
use crate::measure::SourceMeasure;

/// One SplitMix64 step of `state`, as a uniform f64 in [0, 1) (53 random bits).
pub fn uniform01(state: &mut u64) -> f64 {
    *state = state.wrapping_add(0x9E37_79B9_7F4A_7C15);
    let mut x = *state;
    x = (x ^ (x >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
    x = (x ^ (x >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
    ((x ^ (x >> 31)) >> 11) as f64 / (1u64 << 53) as f64
}

/// `n` points uniform in the unit disk: r = √U₁, θ = 2πU₂ with U from [`uniform01`] seeded by
/// `seed` (the points of `ot_bench`).
pub fn random_disk_points(n: usize, seed: u64) -> Vec<[f64; 2]> {
    let mut s = seed;
    (0..n)
        .map(|_| {
            let r = uniform01(&mut s).sqrt();
            let t = 2.0 * std::f64::consts::PI * uniform01(&mut s);
            [r * t.cos(), r * t.sin()]
        })
        .collect()
}

/// The unit disk triangulated in `rings` rings: the center, then ring k = 1..=rings with 6k
/// vertices on the circle of radius k/rings; consecutive rings are joined by merging their
/// angles. Returns (vertices, counter-clockwise triangles); the boundary is the inscribed
/// 6·rings-gon.
pub fn disk_rings_mesh(rings: usize) -> (Vec<[f64; 2]>, Vec<[u32; 3]>) {
    let mut vertices = vec![[0.0, 0.0]];
    let mut ring_start = vec![0usize];
    for k in 1..=rings {
        ring_start.push(vertices.len());
        for j in 0..6 * k {
            let t = 2.0 * std::f64::consts::PI * j as f64 / (6 * k) as f64;
            let r = k as f64 / rings as f64;
            vertices.push([r * t.cos(), r * t.sin()]);
        }
    }
    let mut triangles = Vec::new();
    for k in 0..rings {
        let (n_in, n_out) = (if k == 0 { 1 } else { 6 * k }, 6 * (k + 1));
        let (s_in, s_out) = (ring_start[k], ring_start[k + 1]);
        let (mut i, mut o) = (if k == 0 { 1usize } else { 0 }, 0usize);
        while i < n_in || o < n_out {
            let a_in = if k == 0 {
                f64::INFINITY
            } else {
                (i + 1) as f64 / n_in as f64
            };
            let a_out = (o + 1) as f64 / n_out as f64;
            let vi = (s_in + i % n_in) as u32;
            let vo = (s_out + o % n_out) as u32;
            if o < n_out && (i >= n_in || a_out <= a_in) {
                triangles.push([vi, vo, (s_out + (o + 1) % n_out) as u32]);
                o += 1;
            } else {
                triangles.push([vi, vo, (s_in + (i + 1) % n_in) as u32]);
                i += 1;
            }
        }
    }
    (vertices, triangles)
}

/// [`disk_rings_mesh`] with density `f` at each triangle's centroid. Errors as
/// [`SourceMeasure::new`] (e.g. a density that is not finite and > 0).
pub fn disk_rings_measure(rings: usize, f: impl Fn([f64; 2]) -> f64) -> Result<SourceMeasure, OmtError> {
    let (vertices, triangles) = disk_rings_mesh(rings);
    let densities = triangles
        .iter()
        .map(|t| {
            let p = t.map(|v| vertices[v as usize]);
            f([(p[0][0] + p[1][0] + p[2][0]) / 3.0, (p[0][1] + p[1][1] + p[2][1]) / 3.0])
        })
        .collect();
    SourceMeasure::new(vertices, triangles, densities)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn points_are_reproducible_and_inside_the_disk() {
        let a = random_disk_points(1000, 7);
        assert_eq!(a, random_disk_points(1000, 7));
        assert_ne!(a, random_disk_points(1000, 8));
        assert!(a.iter().all(|p| p[0].hypot(p[1]) < 1.0));
        // uniform in area: about a quarter of the points within radius ½
        let inner = a.iter().filter(|p| p[0].hypot(p[1]) < 0.5).count();
        assert!((200..300).contains(&inner), "{inner}");
    }

    /// The rings tile the regular 6R-gon: total mass = its area for density 1, and a density
    /// of 3 on x > 0 weighs that half three times (the triangles straddling x = 0 by centroid).
    #[test]
    fn ring_measure_tiles_the_polygon() {
        let rings = 12;
        let m = disk_rings_measure(rings, |_| 1.0).unwrap();
        let k = (6 * rings) as f64;
        let polygon = 0.5 * k * (std::f64::consts::TAU / k).sin();
        assert!(
            (m.total_mass() - polygon).abs() < 1e-12,
            "{} vs {polygon}",
            m.total_mass()
        );
        let h = disk_rings_measure(rings, |x| if x[0] > 0.0 { 3.0 } else { 1.0 }).unwrap();
        assert!(
            (h.total_mass() - 2.0 * polygon).abs() < 0.02 * polygon,
            "{}",
            h.total_mass()
        );
        assert!(disk_rings_measure(rings, |_| f64::NAN).is_err());
    }
}
