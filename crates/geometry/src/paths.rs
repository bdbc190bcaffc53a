//! Shortest paths along mesh edges (Dijkstra on Euclidean edge lengths), used by the disk cut
//! of [`crate::prepare`] and the seams of [`crate::seam`].

use std::cmp::Ordering;
use std::collections::BinaryHeap;

use crate::connectivity::Connectivity;
use crate::mesh::TriMesh;
use crate::vec3::{norm, sub};

#[derive(PartialEq)]
struct Item(f64, u32);
impl Eq for Item {}
impl PartialOrd for Item {
    fn partial_cmp(&self, other: &Self) -> Option<Ordering> {
        Some(self.cmp(other))
    }
}
impl Ord for Item {
    fn cmp(&self, other: &Self) -> Ordering {
        // min-heap on distance, ties by vertex index
        other.0.total_cmp(&self.0).then(other.1.cmp(&self.1))
    }
}

/// Shortest-path distances along edges from `source` (Dijkstra on Euclidean edge lengths), #V;
/// unreachable vertices get +∞.
pub fn edge_path_distances(mesh: &TriMesh, conn: &Connectivity, source: u32) -> Vec<f64> {
    let adj = conn.vertex_neighbors(mesh.num_vertices());
    shortest_edge_paths(mesh, &adj, &[source], |_| false).0
}

/// Edge-path distances from a set of sources (Dijkstra on Euclidean edge lengths, `adjacency`
/// as [`Connectivity::vertex_neighbors`]) and each vertex's predecessor on its shortest path
/// (`u32::MAX` for the sources and unreachable vertices; unreachable distances are +∞). Stops
/// early when `stop(v)` holds for a settled vertex v that is not a source, and returns it.
pub(crate) fn shortest_edge_paths(
    mesh: &TriMesh,
    adjacency: &[Vec<u32>],
    sources: &[u32],
    mut stop: impl FnMut(u32) -> bool,
) -> (Vec<f64>, Vec<u32>, Option<u32>) {
    let n = mesh.num_vertices();
    let mut dist = vec![f64::INFINITY; n];
    let mut previous = vec![u32::MAX; n];
    let mut heap = BinaryHeap::new();
    for &s in sources {
        dist[s as usize] = 0.0;
        heap.push(Item(0.0, s));
    }
    while let Some(Item(d, v)) = heap.pop() {
        if d > dist[v as usize] {
            continue;
        }
        if previous[v as usize] != u32::MAX && stop(v) {
            return (dist, previous, Some(v));
        }
        for &w in &adjacency[v as usize] {
            let nd = d + norm(sub(mesh.positions[w as usize], mesh.positions[v as usize]));
            if nd < dist[w as usize] {
                dist[w as usize] = nd;
                previous[w as usize] = v;
                heap.push(Item(nd, w));
            }
        }
    }
    (dist, previous, None)
}
