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
    /// For each vertex, the faces around it (unordered), #V.
    pub vertex_faces: Vec<Vec<u32>>,
}

impl Connectivity {
    /// Builds the connectivity of `faces` on `num_vertices` vertices. Faces with repeated indices
    /// still contribute their (possibly degenerate) edges.
    pub fn new(num_vertices: usize, faces: &[[u32; 3]]) -> Self {
        let mut keyed: Vec<([u32; 2], u32, u8)> = Vec::with_capacity(3 * faces.len());
        for (f, face) in faces.iter().enumerate() {
            for k in 0..3 {
                let a = face[(k + 1) % 3];
                let b = face[(k + 2) % 3];
                keyed.push(([a.min(b), a.max(b)], f as u32, k as u8));
            }
        }
        keyed.sort_unstable();
        let mut edges = Vec::new();
        let mut edge_faces: Vec<Vec<u32>> = Vec::new();
        let mut face_edges = vec![[u32::MAX; 3]; faces.len()];
        for (key, f, k) in keyed {
            if edges.last() != Some(&key) {
                edges.push(key);
                edge_faces.push(Vec::with_capacity(2));
            }
            let e = edges.len() - 1;
            edge_faces[e].push(f);
            face_edges[f as usize][k as usize] = e as u32;
        }
        let mut vertex_faces = vec![Vec::new(); num_vertices];
        for (f, face) in faces.iter().enumerate() {
            for &v in face {
                if let Some(list) = vertex_faces.get_mut(v as usize) {
                    if list.last() != Some(&(f as u32)) {
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
    /// counter-clockwise too). Loops are sorted by decreasing length, then by smallest vertex,
    /// and each loop starts at its smallest vertex index: the output is deterministic.
    ///
    /// At a non-manifold boundary vertex (two outgoing boundary half-edges) the walk takes the
    /// unused one with the smallest target; `topology` reports such vertices separately.
    pub fn boundary_loops(&self, faces: &[[u32; 3]]) -> Vec<Vec<u32>> {
        let halfedges = self.boundary_halfedges(faces);
        let mut outgoing: HashMap<u32, Vec<usize>> = HashMap::new();
        for (h, he) in halfedges.iter().enumerate() {
            outgoing.entry(he[0]).or_default().push(h);
        }
        for list in outgoing.values_mut() {
            list.sort_by_key(|&h| halfedges[h][1]);
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
            let mut h = start;
            loop {
                used[h] = true;
                cycle.push(halfedges[h][0]);
                let next_vertex = halfedges[h][1];
                let next = outgoing
                    .get(&next_vertex)
                    .and_then(|list| list.iter().copied().find(|&g| !used[g]));
                match next {
                    Some(g) => h = g,
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
}
