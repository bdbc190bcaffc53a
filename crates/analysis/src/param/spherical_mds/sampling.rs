//! Farthest-point sampling of landmark vertices by Dijkstra distances along the edges.
//!
//! The first landmark is the vertex farthest from vertex 0; each next one is the vertex
//! farthest from all landmarks chosen so far (Gonzalez 1985; the multiresolution of Elad,
//! Keller & Kimmel embeds such a subset first). Edge-path distances only choose the samples:
//! the stress uses the heat-method distances. Each new landmark's Dijkstra search stops where
//! it no longer improves a vertex's distance to the set, so the total cost stays near
//! O(V log V) per landmark's Voronoi region.

use std::cmp::Reverse;
use std::collections::BinaryHeap;

use shapespace_geometry::connectivity::Connectivity;
use shapespace_geometry::TriMesh;

/// Lowers `dist` (#V) to the edge-path distance from `source` wherever that is smaller.
fn relax_from(neighbors: &[Vec<u32>], positions: &[[f64; 3]], source: usize, dist: &mut [f64]) {
    // non-negative f64 keys order like their bit patterns
    let mut heap = BinaryHeap::new();
    dist[source] = 0.0;
    heap.push(Reverse((0u64, source as u32)));
    while let Some(Reverse((key, v))) = heap.pop() {
        let d = f64::from_bits(key);
        if d > dist[v as usize] {
            continue;
        }
        let p = positions[v as usize];
        for &w in &neighbors[v as usize] {
            let q = positions[w as usize];
            let e = ((p[0] - q[0]).powi(2) + (p[1] - q[1]).powi(2) + (p[2] - q[2]).powi(2)).sqrt();
            let nd = d + e;
            if nd < dist[w as usize] {
                dist[w as usize] = nd;
                heap.push(Reverse((nd.to_bits(), w)));
            }
        }
    }
}

/// `count` landmark vertices of `mesh` by farthest-point sampling (module docs), in the order
/// chosen; all vertices when `count` ≥ #V. Deterministic.
pub fn farthest_point_sample(mesh: &TriMesh, count: usize) -> Vec<u32> {
    let n = mesh.num_vertices();
    if n == 0 || count == 0 {
        return Vec::new();
    }
    let neighbors = Connectivity::of(mesh).vertex_neighbors(n);
    let argmax = |d: &[f64]| {
        (0..n)
            .filter(|&v| d[v].is_finite())
            .max_by(|&a, &b| d[a].total_cmp(&d[b]).then(b.cmp(&a)))
            .unwrap_or(0)
    };
    let mut dist = vec![f64::INFINITY; n];
    relax_from(&neighbors, &mesh.positions, 0, &mut dist);
    let first = argmax(&dist);
    let mut dist = vec![f64::INFINITY; n];
    let mut chosen = vec![first as u32];
    relax_from(&neighbors, &mesh.positions, first, &mut dist);
    while chosen.len() < count.min(n) {
        let next = argmax(&dist);
        if dist[next] == 0.0 {
            // (only unreachable vertices are left)
            break;
        }
        chosen.push(next as u32);
        relax_from(&neighbors, &mesh.positions, next, &mut dist);
    }
    chosen
}

#[cfg(test)]
mod tests {
    use super::*;

    /// On a grid the samples are distinct, the first two are opposite corners, and the covering
    /// radius shrinks as samples are added.
    #[test]
    fn samples_are_spread_and_distinct() {
        let mesh = shapespace_geometry::primitives::grid(20, 20);
        let s = farthest_point_sample(&mesh, 50);
        assert_eq!(s.len(), 50);
        let mut sorted = s.clone();
        sorted.sort_unstable();
        sorted.dedup();
        assert_eq!(sorted.len(), 50);
        let (a, b) = (mesh.positions[s[0] as usize], mesh.positions[s[1] as usize]);
        assert!(
            ((a[0] - b[0]).abs() - 1.0).abs() < 1e-12 && ((a[1] - b[1]).abs() - 1.0).abs() < 1e-12,
            "{a:?} {b:?}"
        );
        let radius = |m: usize| {
            let neighbors = Connectivity::of(&mesh).vertex_neighbors(mesh.num_vertices());
            let mut d = vec![f64::INFINITY; mesh.num_vertices()];
            for &v in &s[..m] {
                relax_from(&neighbors, &mesh.positions, v as usize, &mut d);
            }
            d.iter().fold(0.0f64, |x, &y| x.max(y))
        };
        assert!(radius(50) < 0.6 * radius(10), "{} {}", radius(10), radius(50));
        assert_eq!(farthest_point_sample(&mesh, 10_000).len(), mesh.num_vertices());
    }
}
