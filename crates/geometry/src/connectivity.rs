//! Mesh connectivity from the face list alone (no positions): undirected edges with their faces,
//! vertex–face incidence and ordered boundary loops.

use std::collections::HashMap;

use crate::mesh::TriMesh;

/// Undirected edges and their incident faces.
#[derive(Clone, Debug)]
pub struct Connectivity {
    /// Edges as (min, max) vertex pairs, sorted lexicographically, #E.
    pub edges: Vec<[u32; 2]>,
    /// For each edge, the faces that contain it (1 on the boundary, 2 inside, more if non-manifold).
    pub edge_faces: Vec<Vec<u32>>,
    /// For each face, the edge opposite each corner: `face_edges[f][k]` joins corners k+1 and k+2.
    pub face_edges: Vec<[u32; 3]>,
    /// For each vertex, the faces around it in increasing face order, each once (a face that
    /// repeats the vertex is listed for its first corner only), #V. (Not in rotation order;
    /// the fold repair's per-vertex sums rely on the increasing order.)
    pub vertex_faces: Vec<Vec<u32>>,
}

impl Connectivity {
    /// Builds the connectivity of `faces` on `num_vertices` vertices. Faces with repeated indices
    /// still contribute their (possibly degenerate) edges.
    pub fn new(num_vertices: usize, faces: &[[u32; 3]]) -> Self {
        // One key per (face, corner): the edge (min, max) in the high 64 bits, 3f + k in the low
        // ones, so a plain integer sort orders by edge, then face, then corner.
        let mut keyed: Vec<u128> = Vec::with_capacity(3 * faces.len());
        for (f, face) in faces.iter().enumerate() {
            for k in 0..3 {
                let a = face[(k + 1) % 3];
                let b = face[(k + 2) % 3];
                let edge = (u64::from(a.min(b)) << 32) | u64::from(a.max(b));
                keyed.push((u128::from(edge) << 64) | (3 * f + k) as u128);
            }
        }
        keyed.sort_unstable();
        let mut edges: Vec<[u32; 2]> = Vec::new();
        let mut edge_faces: Vec<Vec<u32>> = Vec::new();
        let mut face_edges = vec![[u32::MAX; 3]; faces.len()];
        let mut run = 0;
        while run < keyed.len() {
            let edge = (keyed[run] >> 64) as u64;
            let end = run + keyed[run..].iter().take_while(|&&x| (x >> 64) as u64 == edge).count();
            let e = edges.len() as u32;
            edges.push([(edge >> 32) as u32, edge as u32]);
            let mut list = Vec::with_capacity(end - run);
            for &x in &keyed[run..end] {
                let corner = x as u64 as usize;
                let (f, k) = (corner / 3, corner % 3);
                list.push(f as u32);
                face_edges[f][k] = e;
            }
            edge_faces.push(list);
            run = end;
        }
        // vertex–face lists allocated once at their final length (a face repeating a vertex is
        // listed once for it)
        let mut degree = vec![0u32; num_vertices];
        let distinct = |face: &[u32; 3], k: usize| (0..k).all(|j| face[j] != face[k]);
        for face in faces {
            for k in 0..3 {
                if distinct(face, k) {
                    if let Some(d) = degree.get_mut(face[k] as usize) {
                        *d += 1;
                    }
                }
            }
        }
        let mut vertex_faces: Vec<Vec<u32>> = degree.iter().map(|&d| Vec::with_capacity(d as usize)).collect();
        for (f, face) in faces.iter().enumerate() {
            for k in 0..3 {
                if distinct(face, k) {
                    if let Some(list) = vertex_faces.get_mut(face[k] as usize) {
                        list.push(f as u32);
                    }
                }
            }
        }
        Connectivity {
            edges,
            edge_faces,
            face_edges,
            vertex_faces,
        }
    }

    /// Connectivity of a mesh.
    pub fn of(mesh: &TriMesh) -> Self {
        Self::new(mesh.num_vertices(), &mesh.faces)
    }

    /// Number of undirected edges #E.
    pub fn num_edges(&self) -> usize {
        self.edges.len()
    }

    /// Boundary edges (exactly one incident face), as directed pairs (a, b) that follow the
    /// orientation of their face, so the surface lies to the left of a → b.
    pub fn boundary_halfedges(&self, faces: &[[u32; 3]]) -> Vec<[u32; 2]> {
        let mut out = Vec::new();
        for (e, ef) in self.edge_faces.iter().enumerate() {
            if ef.len() == 1 {
                let f = ef[0] as usize;
                let k = self.face_edges[f].iter().position(|&x| x == e as u32).unwrap_or(0);
                out.push([faces[f][(k + 1) % 3], faces[f][(k + 2) % 3]]);
            }
        }
        out
    }

    /// Ordered boundary loops, each a vertex cycle following the boundary half-edge direction
    /// (for a consistently oriented disk whose faces are counter-clockwise, the loop is
    /// counter-clockwise too; on a mesh that is not consistently oriented a loop may run
    /// against some of its half-edges, see below). Loops are sorted by decreasing length, then by smallest vertex,
    /// and each loop starts at its smallest vertex index: the output is deterministic.
    ///
    /// At a non-manifold boundary vertex (two outgoing boundary half-edges) the walk takes the
    /// unused one with the smallest target; `topology` reports such vertices separately. Where
    /// no unused half-edge leaves the current vertex, the walk goes on backwards along an unused
    /// one that arrives there (smallest source first), so a boundary whose faces are not
    /// consistently oriented (a wrongly wound face on it, or a Möbius strip) is still one loop
    /// per boundary curve.
    pub fn boundary_loops(&self, faces: &[[u32; 3]]) -> Vec<Vec<u32>> {
        let halfedges = self.boundary_halfedges(faces);
        let mut outgoing: HashMap<u32, Vec<usize>> = HashMap::new();
        let mut incoming: HashMap<u32, Vec<usize>> = HashMap::new();
        for (h, he) in halfedges.iter().enumerate() {
            outgoing.entry(he[0]).or_default().push(h);
            incoming.entry(he[1]).or_default().push(h);
        }
        for list in outgoing.values_mut() {
            list.sort_by_key(|&h| halfedges[h][1]);
        }
        for list in incoming.values_mut() {
            list.sort_by_key(|&h| halfedges[h][0]);
        }
        let mut used = vec![false; halfedges.len()];
        let mut order: Vec<usize> = (0..halfedges.len()).collect();
        order.sort_by_key(|&h| halfedges[h]);
        let mut loops = Vec::new();
        for start in order {
            if used[start] {
                continue;
            }
            let mut cycle = Vec::new();
            let (mut h, mut from) = (start, halfedges[start][0]);
            loop {
                used[h] = true;
                cycle.push(from);
                // the other end of h
                let at = if halfedges[h][0] == from {
                    halfedges[h][1]
                } else {
                    halfedges[h][0]
                };
                let unused = |map: &HashMap<u32, Vec<usize>>| {
                    map.get(&at).and_then(|list| list.iter().copied().find(|&g| !used[g]))
                };
                match unused(&outgoing).or_else(|| unused(&incoming)) {
                    Some(g) => (h, from) = (g, at),
                    None => break,
                }
            }
            // rotate so the loop starts at its smallest vertex
            if let Some((pos, _)) = cycle.iter().enumerate().min_by_key(|(_, &v)| v) {
                cycle.rotate_left(pos);
            }
            loops.push(cycle);
        }
        loops.sort_by(|a, b| b.len().cmp(&a.len()).then(a[0].cmp(&b[0])));
        loops
    }

    /// Per-vertex flag: true when the vertex lies on a boundary edge.
    pub fn boundary_vertices(&self, num_vertices: usize) -> Vec<bool> {
        let mut on = vec![false; num_vertices];
        for (e, ef) in self.edges.iter().zip(&self.edge_faces) {
            if ef.len() == 1 {
                on[e[0] as usize] = true;
                on[e[1] as usize] = true;
            }
        }
        on
    }

    /// Vertex adjacency lists (neighbours through edges), #V, each sorted.
    pub fn vertex_neighbors(&self, num_vertices: usize) -> Vec<Vec<u32>> {
        let mut adj = vec![Vec::new(); num_vertices];
        for e in &self.edges {
            if e[0] != e[1] {
                adj[e[0] as usize].push(e[1]);
                adj[e[1] as usize].push(e[0]);
            }
        }
        for list in &mut adj {
            list.sort_unstable();
        }
        adj
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn square_boundary_loop_is_ccw() {
        // 0-1-2-3 square split along 0-2, counter-clockwise faces
        let faces = vec![[0, 1, 2], [0, 2, 3]];
        let c = Connectivity::new(4, &faces);
        assert_eq!(c.num_edges(), 5);
        let loops = c.boundary_loops(&faces);
        assert_eq!(loops, vec![vec![0, 1, 2, 3]]);
        assert_eq!(c.boundary_vertices(4), vec![true; 4]);
        let interior = c.edges.iter().position(|e| *e == [0, 2]).unwrap();
        assert_eq!(c.edge_faces[interior].len(), 2);
    }

    #[test]
    fn matches_a_brute_force_construction_with_degenerate_and_non_manifold_faces() {
        // a fan, a fin on edge 0-1 (three faces there), faces repeating a vertex (corners 0 and 1,
        // corners 0 and 2), vertex 9 unused
        let faces: Vec<[u32; 3]> = vec![
            [0, 1, 2],
            [0, 2, 3],
            [0, 3, 4],
            [1, 0, 5],
            [0, 1, 6],
            [7, 7, 8],
            [4, 3, 8],
            [4, 8, 4],
        ];
        let n = 10;
        let c = Connectivity::new(n, &faces);
        let mut expected: Vec<[u32; 2]> = faces
            .iter()
            .flat_map(|f| (0..3).map(move |k| [f[(k + 1) % 3].min(f[(k + 2) % 3]), f[(k + 1) % 3].max(f[(k + 2) % 3])]))
            .collect();
        expected.sort_unstable();
        expected.dedup();
        assert_eq!(c.edges, expected);
        for (e, edge) in c.edges.iter().enumerate() {
            let mut holders: Vec<u32> = Vec::new();
            for (f, face) in faces.iter().enumerate() {
                for k in 0..3 {
                    let (a, b) = (face[(k + 1) % 3], face[(k + 2) % 3]);
                    if [a.min(b), a.max(b)] == *edge {
                        holders.push(f as u32);
                        assert_eq!(c.face_edges[f][k], e as u32);
                    }
                }
            }
            assert_eq!(c.edge_faces[e], holders, "edge {edge:?}");
        }
        assert_eq!(
            c.edge_faces[c.edges.iter().position(|e| *e == [0, 1]).unwrap()],
            vec![0, 3, 4]
        );
        for v in 0..n as u32 {
            let around: Vec<u32> = (0..faces.len() as u32)
                .filter(|&f| faces[f as usize].contains(&v))
                .collect();
            assert_eq!(c.vertex_faces[v as usize], around, "vertex {v}");
        }
        // out-of-range indices are skipped in the vertex lists, not a panic
        let short = Connectivity::new(3, &faces[..2]);
        assert_eq!(short.vertex_faces, vec![vec![0, 1], vec![0], vec![0, 1]]);
    }
}
