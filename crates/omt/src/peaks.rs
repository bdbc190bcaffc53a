//! Mass-preserving spreading of density peaks of a source measure.
//!
//! The pushed-forward density of a conformal map, μ_t = area₃(t) / area₂(φ(t)), is a ratio of
//! two areas per triangle; where the map crushes a few triangles of ordinary 3D area to almost
//! nothing in the disk (slivers at the rim of a BFF map of a scan: 4–8 faces of 60k at
//! 1e5–1e10 times the median density, together 2e-4 of the mass), the measure holds what are
//! in effect point masses. A cell boundary that passes through such a triangle makes the cell
//! masses jump with the heights, the damped Newton method's linear model holds only in a window
//! of the triangle's width, and the solve takes twice the steps (measured in
//! `ARCHITECTURE.md`).
//!
//! [`spread_density_peaks`] replaces each peak by the average over a small patch around it:
//! for every triangle whose density exceeds the cap ρ_max = `ratio` × the median density
//! (highest first), the patch grows by vertex rings (the triangles that share a vertex with it)
//! until its mass over its area, M_P / |P|, is at most ρ_max, and every triangle of the patch
//! gets that density. The mass of every patch is kept exactly (up to rounding), so the total
//! mass is unchanged, and mass moves only within a patch: the transport cost changes by at most
//! 2·M_moved·diam(P)·max|x − y| + M_moved·diam(P)² (each unit of moved mass travels at most
//! diam(P)). Measures without peaks are returned unchanged (bitwise).

use crate::error::OmtError;
use crate::measure::SourceMeasure;

/// What [`spread_density_peaks`] did.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct PeakSpreading {
    /// The cap ρ_max (`ratio` × the median density).
    pub cap: f64,
    /// Triangles above the cap before spreading.
    pub peak_triangles: usize,
    /// Triangles whose density changed (the peaks and their patches).
    pub changed_triangles: usize,
    /// The mass of the changed triangles (μ(Ω) units): an upper bound on the mass moved.
    pub changed_mass: f64,
    /// Largest patch diameter (bounding-box diagonal): how far any mass moved at most.
    pub max_patch_diameter: f64,
}

/// The measure with every density above `ratio` × the median density spread over the smallest
/// vertex-ring patch around it whose average is at most that cap (module docs). Total mass and
/// each patch's mass are kept. `ratio` must be finite and ≥ 1. (Should a patch grow to a whole
/// connected component without its average falling below the cap, the component gets its
/// average density.)
pub fn spread_density_peaks(measure: &SourceMeasure, ratio: f64) -> Result<(SourceMeasure, PeakSpreading), OmtError> {
    if !(ratio >= 1.0 && ratio.is_finite()) {
        return Err(OmtError::InvalidInput(format!(
            "density peak ratio must be finite and >= 1, got {ratio}"
        )));
    }
    let densities = &measure.densities;
    let mut sorted = densities.clone();
    sorted.sort_by(f64::total_cmp);
    let cap = ratio * sorted[sorted.len() / 2];
    let mut info = PeakSpreading {
        cap,
        ..PeakSpreading::default()
    };
    let mut peaks: Vec<usize> = (0..densities.len()).filter(|&t| densities[t] > cap).collect();
    info.peak_triangles = peaks.len();
    if peaks.is_empty() {
        return Ok((measure.clone(), info));
    }
    peaks.sort_by(|&a, &b| densities[b].total_cmp(&densities[a]));
    let vertices = &measure.vertices;
    let areas: Vec<f64> = measure
        .triangles
        .iter()
        .map(|tri| {
            let [a, b, c] = tri.map(|v| vertices[v as usize]);
            0.5 * ((b[0] - a[0]) * (c[1] - a[1]) - (b[1] - a[1]) * (c[0] - a[0]))
        })
        .collect();
    let mut vertex_triangles: Vec<Vec<u32>> = vec![Vec::new(); vertices.len()];
    for (t, tri) in measure.triangles.iter().enumerate() {
        for &v in tri {
            vertex_triangles[v as usize].push(t as u32);
        }
    }
    let mut out = densities.clone();
    let mut changed = vec![false; densities.len()];
    let mut in_patch = vec![false; densities.len()];
    let mut seen_vertex = vec![false; vertices.len()];
    for &peak in &peaks {
        if out[peak] <= cap {
            continue; // averaged down by an earlier patch
        }
        let mut patch = vec![peak];
        in_patch[peak] = true;
        let mut touched_vertices: Vec<u32> = Vec::new();
        let (mut mass, mut area) = (out[peak] * areas[peak], areas[peak]);
        let mut frontier = 0;
        while mass > cap * area && patch.len() < densities.len() {
            // one vertex ring: every triangle sharing a vertex with the triangles added last
            let end = patch.len();
            for k in frontier..end {
                for &v in &measure.triangles[patch[k]] {
                    if std::mem::replace(&mut seen_vertex[v as usize], true) {
                        continue;
                    }
                    touched_vertices.push(v);
                    for &t in &vertex_triangles[v as usize] {
                        let t = t as usize;
                        if !std::mem::replace(&mut in_patch[t], true) {
                            patch.push(t);
                            mass += out[t] * areas[t];
                            area += areas[t];
                        }
                    }
                }
            }
            frontier = end;
            if patch.len() == end {
                break; // a component exhausted
            }
        }
        let average = mass / area;
        let (mut lo, mut hi) = ([f64::INFINITY; 2], [f64::NEG_INFINITY; 2]);
        for &t in &patch {
            out[t] = average;
            changed[t] = true;
            in_patch[t] = false;
            for &v in &measure.triangles[t] {
                let p = vertices[v as usize];
                lo = [lo[0].min(p[0]), lo[1].min(p[1])];
                hi = [hi[0].max(p[0]), hi[1].max(p[1])];
            }
        }
        for v in touched_vertices {
            seen_vertex[v as usize] = false;
        }
        info.max_patch_diameter = info.max_patch_diameter.max((hi[0] - lo[0]).hypot(hi[1] - lo[1]));
    }
    for t in 0..out.len() {
        if changed[t] {
            info.changed_triangles += 1;
            info.changed_mass += out[t] * areas[t];
        }
    }
    let spread = SourceMeasure::new(measure.vertices.clone(), measure.triangles.clone(), out)?;
    Ok((spread, info))
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The square [−1, 1]² as an n × n grid of squares cut in two, densities 1.0 … 1.6 in
    /// turn (median 1.3).
    fn square_grid(n: usize) -> SourceMeasure {
        let mut vertices = Vec::new();
        for j in 0..=n {
            for i in 0..=n {
                vertices.push([-1.0 + 2.0 * i as f64 / n as f64, -1.0 + 2.0 * j as f64 / n as f64]);
            }
        }
        let id = |i: usize, j: usize| (j * (n + 1) + i) as u32;
        let mut triangles = Vec::new();
        for j in 0..n {
            for i in 0..n {
                triangles.push([id(i, j), id(i + 1, j), id(i + 1, j + 1)]);
                triangles.push([id(i, j), id(i + 1, j + 1), id(i, j + 1)]);
            }
        }
        let densities = (0..triangles.len()).map(|t| 1.0 + (t % 7) as f64 * 0.1).collect();
        SourceMeasure::new(vertices, triangles, densities).unwrap()
    }

    #[test]
    fn no_peak_leaves_the_measure_bitwise() {
        let m = square_grid(10);
        let (s, info) = spread_density_peaks(&m, 10.0).unwrap();
        assert_eq!(info.peak_triangles, 0);
        assert_eq!(info.changed_triangles, 0);
        assert!(s
            .densities
            .iter()
            .zip(&m.densities)
            .all(|(a, b)| a.to_bits() == b.to_bits()));
    }

    #[test]
    fn peaks_are_capped_and_mass_is_kept_locally() {
        let mut m = square_grid(20);
        // triangles of area 0.005: masses 50 and 15, needing areas 0.38 and 0.12 at the cap 130
        m.densities[10] = 1e4;
        m.densities[401] = 3e3;
        let before = m.total_mass();
        let (s, info) = spread_density_peaks(&m, 100.0).unwrap();
        assert_eq!(info.peak_triangles, 2);
        assert!((info.cap - 130.0).abs() < 1e-9, "{}", info.cap);
        assert!(s.densities.iter().all(|&d| d <= info.cap * (1.0 + 1e-12)));
        assert!(
            (s.total_mass() - before).abs() <= 1e-12 * before,
            "{} {}",
            s.total_mass(),
            before
        );
        // mass moved only near the peaks: an area of 0.38 is three vertex rings of cells of
        // width 0.1 (a 6 × 6 block, diagonal 0.85 … 1.27)
        assert!(info.max_patch_diameter < 1.3, "{}", info.max_patch_diameter);
        assert!(info.changed_triangles < 200, "{}", info.changed_triangles);
        let untouched = (0..m.densities.len())
            .filter(|&t| s.densities[t] == m.densities[t])
            .count();
        assert_eq!(untouched + info.changed_triangles, m.densities.len());
    }

    #[test]
    fn a_peak_larger_than_the_domain_allows_gives_the_mean_density() {
        let mut m = square_grid(4);
        m.densities[3] = 1e9;
        let (s, info) = spread_density_peaks(&m, 10.0).unwrap();
        let mean = m.total_mass() / 4.0;
        assert_eq!(info.changed_triangles, m.densities.len());
        assert!(s.densities.iter().all(|&d| (d - mean).abs() <= 1e-12 * mean));
    }

    #[test]
    fn rejects_a_ratio_below_one() {
        assert!(spread_density_peaks(&square_grid(2), 0.5).is_err());
        assert!(spread_density_peaks(&square_grid(2), f64::NAN).is_err());
    }
}
