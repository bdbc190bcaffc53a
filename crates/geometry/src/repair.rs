//! Repair of degenerate faces by local connectivity changes that leave the surface as it is.
//!
//! A face is degenerate by [`crate::predicates::degenerate_corners`] (the one definition `info`,
//! `prepare` and the disk maps share): two corners at one position, or three corners on a line
//! (exactly, or to the rounding of the edge lengths the maps compute). Each is repaired by the
//! one operation that removes it without moving a vertex:
//!
//! - **coincident corners** `u`, `v`: the edge `uv` is collapsed (`v` merged into `u`; the faces
//!   on `uv` vanish), when the link condition holds (the common neighbours of `u` and `v` are
//!   the apexes of the faces on `uv`, and two boundary vertices are joined by a boundary edge),
//!   so the surface stays a manifold of the same topology;
//! - **collinear corners**, `c` between `a` and `b` (the corner opposite the longest edge): if
//!   `ab` has a second face `(b, a, d)`, the edge `ab` is flipped to `cd`, which splits that face
//!   at `c` into two proper faces; if `ab` is on the boundary and `c` is interior, the face is
//!   removed, so the boundary runs through `c` along the same line.
//!
//! Each operation removes at least one degenerate face and makes none, so the repair ends; faces
//! it cannot repair (a flip whose new edge exists already or whose new faces are degenerate too,
//! a collapse against the link condition) are returned for the caller to report.

use std::collections::{HashMap, HashSet};

use crate::mesh::TriMesh;
use crate::predicates::degenerate_corners;

/// What [`repair_degenerate_faces`] did.
#[derive(Clone, Debug, Default, PartialEq, Eq, serde::Serialize)]
pub struct DegenerateRepair {
    /// Edges flipped (a collinear face and its neighbour across the long edge became two proper
    /// faces).
    pub flipped: usize,
    /// Collinear faces on the boundary removed.
    pub removed: usize,
    /// Edges between coincident vertices collapsed (one vertex fewer each).
    pub collapsed: usize,
}

impl DegenerateRepair {
    /// Degenerate faces repaired.
    pub fn total(&self) -> usize {
        self.flipped + self.removed + self.collapsed
    }
}

/// The result of [`repair_degenerate_faces`].
#[derive(Clone, Debug)]
pub struct Repaired {
    /// The mesh: faces in input order, a flipped pair in the slots of the two faces it replaces,
    /// removed faces left out; vertices without the collapsed ones, in input order.
    pub mesh: TriMesh,
    /// Old→new vertex index map, #V of the input (`None` for a vertex merged away; its faces now
    /// use the vertex at the same position).
    pub vertex_map: Vec<Option<u32>>,
    /// What was done.
    pub repair: DegenerateRepair,
    /// Faces still degenerate, as vertex triples of the input.
    pub remaining: Vec<[u32; 3]>,
}

/// Repairs the degenerate faces of an oriented manifold mesh (every edge on one or two faces,
/// consistently oriented, no face repeating a vertex index) by flips, boundary-face removals and
/// collapses (module docs). Positions are never moved.
pub fn repair_degenerate_faces(mesh: &TriMesh) -> Repaired {
    let p = &mesh.positions;
    let nv = mesh.num_vertices();
    let mut state = RepairState {
        positions: p,
        faces: mesh.faces.iter().map(|&f| Some(f)).collect(),
        merged_into: (0..nv as u32).collect(),
        touched: Vec::new(),
        repair: DegenerateRepair::default(),
    };
    loop {
        let candidates: Vec<usize> = (0..state.faces.len())
            .filter(|&f| state.faces[f].is_some_and(|t| state.degenerate(t)))
            .collect();
        if candidates.is_empty() {
            break;
        }
        // connectivity of this round; a vertex touched by an operation is left until the next
        // round (every face an operation changes has all its corners touched), so the queries
        // below, made on untouched vertices, see the mesh as it is
        let round = RoundConnectivity::new(&state.faces, nv);
        state.touched = vec![false; nv];
        let mut progress = false;
        for f in candidates {
            let Some(t) = state.faces[f] else { continue };
            if t.iter().any(|&v| state.touched[v as usize]) {
                continue;
            }
            let [q0, q1, q2] = t.map(|v| p[v as usize]);
            let coincident = if q0 == q1 {
                Some((t[0], t[1]))
            } else if q1 == q2 {
                Some((t[1], t[2]))
            } else if q2 == q0 {
                Some((t[2], t[0]))
            } else {
                None
            };
            progress |= match coincident {
                Some((x, y)) => state.collapse(&round, x, y),
                None => state.flip_or_remove(&round, f, t),
            };
        }
        if !progress {
            break;
        }
    }
    state.finish(mesh)
}

/// The repair's state: the faces (None: removed), each vertex's merge target, the vertices an
/// operation touched in this round, and the counts.
struct RepairState<'a> {
    positions: &'a [[f64; 3]],
    faces: Vec<Option<[u32; 3]>>,
    /// collapsed vertex → the vertex it was merged into (followed to the end)
    merged_into: Vec<u32>,
    touched: Vec<bool>,
    repair: DegenerateRepair,
}

/// The connectivity of the faces at the start of a round: the faces, each directed edge's face
/// and each vertex's faces.
struct RoundConnectivity {
    snapshot: Vec<Option<[u32; 3]>>,
    half: HashMap<(u32, u32), usize>,
    vertex_faces: Vec<Vec<usize>>,
}

impl RoundConnectivity {
    fn new(faces: &[Option<[u32; 3]>], nv: usize) -> Self {
        let mut half: HashMap<(u32, u32), usize> = HashMap::new();
        let mut vertex_faces: Vec<Vec<usize>> = vec![Vec::new(); nv];
        for (f, t) in faces.iter().enumerate() {
            if let Some(t) = t {
                for k in 0..3 {
                    half.insert((t[k], t[(k + 1) % 3]), f);
                    vertex_faces[t[k] as usize].push(f);
                }
            }
        }
        RoundConnectivity {
            snapshot: faces.to_vec(),
            half,
            vertex_faces,
        }
    }

    fn on_boundary(&self, v: u32) -> bool {
        self.vertex_faces[v as usize].iter().any(|&f| {
            let t = self.snapshot[f].unwrap();
            (0..3).any(|k| t[k] == v && !self.half.contains_key(&(t[(k + 1) % 3], v)))
        })
    }

    fn neighbours(&self, v: u32) -> HashSet<u32> {
        self.vertex_faces[v as usize]
            .iter()
            .flat_map(|&f| self.snapshot[f].unwrap())
            .filter(|&w| w != v)
            .collect()
    }

    /// The edges of the link of `w` (the edges opposite `w` in its faces), as sorted pairs.
    fn link_edges(&self, w: u32) -> HashSet<[u32; 2]> {
        self.vertex_faces[w as usize]
            .iter()
            .map(|&g| {
                let s = self.snapshot[g].unwrap();
                let k = s.iter().position(|&z| z == w).unwrap();
                let (x, y) = (s[(k + 1) % 3], s[(k + 2) % 3]);
                [x.min(y), x.max(y)]
            })
            .collect()
    }
}

impl RepairState<'_> {
    fn degenerate(&self, t: [u32; 3]) -> bool {
        let p = self.positions;
        degenerate_corners(p[t[0] as usize], p[t[1] as usize], p[t[2] as usize]).is_some()
    }

    /// Collapses the edge between the coincident vertices `x`, `y` (the higher index merges into
    /// the lower) when the link condition holds; whether it did.
    fn collapse(&mut self, round: &RoundConnectivity, x: u32, y: u32) -> bool {
        let (u, v) = (x.min(y), x.max(y));
        // faces on the edge uv and their apexes
        let on_edge: Vec<usize> = [round.half.get(&(u, v)), round.half.get(&(v, u))]
            .into_iter()
            .flatten()
            .copied()
            .collect();
        let apexes: HashSet<u32> = on_edge
            .iter()
            .flat_map(|&g| self.faces[g].unwrap())
            .filter(|&w| w != u && w != v)
            .collect();
        let common: HashSet<u32> = round
            .neighbours(u)
            .intersection(&round.neighbours(v))
            .copied()
            .collect();
        let boundary_edge = on_edge.len() == 1;
        // the link condition: the links of u and v share only the apexes (no edge xy with
        // faces (u, x, y) and (v, x, y): a collapse would stack two faces on it)
        if common != apexes
            || round.link_edges(u).intersection(&round.link_edges(v)).next().is_some()
            || (!boundary_edge && round.on_boundary(u) && round.on_boundary(v))
        {
            return false;
        }
        for &g in &on_edge {
            self.faces[g] = None;
        }
        for &g in &round.vertex_faces[v as usize] {
            if let Some(s) = self.faces[g].as_mut() {
                for w in s.iter_mut() {
                    if *w == v {
                        *w = u;
                    }
                }
                for &w in s.iter() {
                    self.touched[w as usize] = true;
                }
            }
        }
        self.merged_into[v as usize] = u;
        self.touched[u as usize] = true;
        self.touched[v as usize] = true;
        self.repair.collapsed += 1;
        true
    }

    /// Repairs the collinear face `f` = `t`: flips its longest edge, or removes it from the
    /// boundary; whether it did.
    fn flip_or_remove(&mut self, round: &RoundConnectivity, f: usize, t: [u32; 3]) -> bool {
        let p = self.positions;
        // collinear: c opposite the longest edge (a, b), in the face's order (a, b, c)
        let len2 = |i: usize, j: usize| {
            let (x, y) = (p[t[i] as usize], p[t[j] as usize]);
            (x[0] - y[0]).powi(2) + (x[1] - y[1]).powi(2) + (x[2] - y[2]).powi(2)
        };
        let k = (0..3)
            .max_by(|&i, &j| len2(i, (i + 1) % 3).total_cmp(&len2(j, (j + 1) % 3)))
            .unwrap();
        let (a, b, c) = (t[k], t[(k + 1) % 3], t[(k + 2) % 3]);
        match round.half.get(&(b, a)).copied() {
            Some(g) => {
                let s = self.faces[g].unwrap();
                let d = s.into_iter().find(|&w| w != a && w != b).unwrap();
                if self.touched[d as usize] || round.half.contains_key(&(c, d)) || round.half.contains_key(&(d, c)) {
                    return false;
                }
                let (f1, f2) = ([c, a, d], [d, b, c]);
                if self.degenerate(f1) || self.degenerate(f2) {
                    return false;
                }
                self.faces[f] = Some(f1);
                self.faces[g] = Some(f2);
                for w in [a, b, c, d] {
                    self.touched[w as usize] = true;
                }
                self.repair.flipped += 1;
            }
            None => {
                if round.on_boundary(c) {
                    return false;
                }
                self.faces[f] = None;
                for w in [a, b, c] {
                    self.touched[w as usize] = true;
                }
                self.repair.removed += 1;
            }
        }
        true
    }

    /// The repaired mesh: the vertices not merged away (in input order, with their uvs), the
    /// faces left, renumbered.
    fn finish(self, mesh: &TriMesh) -> Repaired {
        let p = self.positions;
        let nv = p.len();
        let find = |mut v: u32| {
            while self.merged_into[v as usize] != v {
                v = self.merged_into[v as usize];
            }
            v
        };
        let mut vertex_map = vec![None; nv];
        let mut positions = Vec::new();
        let mut uvs = mesh.uvs.as_ref().map(|_| Vec::new());
        for v in 0..nv {
            if find(v as u32) == v as u32 {
                vertex_map[v] = Some(positions.len() as u32);
                positions.push(p[v]);
                if let (Some(out), Some(src)) = (uvs.as_mut(), mesh.uvs.as_ref()) {
                    out.push(src[v]);
                }
            }
        }
        let faces: Vec<[u32; 3]> = self.faces.iter().flatten().copied().collect();
        let remaining = faces.iter().copied().filter(|&t| self.degenerate(t)).collect();
        let faces = faces
            .into_iter()
            .map(|t| t.map(|v| vertex_map[v as usize].unwrap()))
            .collect();
        Repaired {
            mesh: TriMesh { positions, faces, uvs },
            vertex_map,
            repair: self.repair,
            remaining,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::quantities::face_areas;
    use crate::topology::{degenerate_faces, mesh_report, MeshClass};

    fn is_disk(m: &TriMesh) -> bool {
        mesh_report(m).unwrap().classification.class == MeshClass::Disk
    }

    fn area(m: &TriMesh) -> f64 {
        face_areas(m).iter().sum()
    }

    /// A hexagon fan around vertex 0 at the centre of the unit hexagon.
    fn hexagon(center: [f64; 3]) -> TriMesh {
        let mut positions = vec![center];
        for k in 0..6 {
            let t = std::f64::consts::PI / 3.0 * k as f64;
            positions.push([t.cos(), t.sin(), 0.0]);
        }
        let faces = (0..6u32).map(|k| [0, k + 1, (k + 1) % 6 + 1]).collect();
        TriMesh::new(positions, faces).unwrap()
    }

    #[test]
    fn an_interior_collinear_face_is_flipped_away() {
        // vertex 2 = (1, 0) exactly on the edge 0–1 from (0, 0) to (2, 0), which has a second
        // face (1, 0, 3) below it
        let positions = vec![
            [0.0, 0.0, 0.0],
            [2.0, 0.0, 0.0],
            [1.0, 0.0, 0.0],
            [1.0, -1.0, 0.0],
            [0.0, 1.0, 0.0],
            [2.0, 1.0, 0.0],
        ];
        // (0, 1, 2) is degenerate (2 on segment 0–1); (1, 0, 3) below; above, 2 joins 0 and 1 to
        // the top edge: (0, 2, 4), (2, 5, 4), (2, 1, 5)
        let faces = vec![[0, 1, 2], [1, 0, 3], [0, 2, 4], [2, 5, 4], [2, 1, 5]];
        let mesh = TriMesh::new(positions, faces).unwrap();
        assert_eq!(degenerate_faces(&mesh), vec![0]);
        let r = repair_degenerate_faces(&mesh);
        assert_eq!(
            r.repair,
            DegenerateRepair {
                flipped: 1,
                removed: 0,
                collapsed: 0
            }
        );
        assert!(r.remaining.is_empty());
        assert!(degenerate_faces(&r.mesh).is_empty());
        assert_eq!(r.mesh.num_faces(), 5);
        assert_eq!(r.mesh.faces[0], [2, 0, 3]);
        assert_eq!(r.mesh.faces[1], [3, 1, 2]);
        // same surface: same area, still an oriented disk
        assert!((area(&r.mesh) - area(&mesh)).abs() < 1e-15);
        assert!(is_disk(&r.mesh));
    }

    #[test]
    fn a_boundary_collinear_face_is_removed() {
        // the centre on the rim edge 1–2 (exactly its midpoint, in binary)
        let mut mesh = hexagon([0.0; 3]);
        let (a, b) = (mesh.positions[1], mesh.positions[2]);
        mesh.positions[0] = [(a[0] + b[0]) / 2.0, (a[1] + b[1]) / 2.0, 0.0];
        assert_eq!(degenerate_faces(&mesh), vec![0]);
        let r = repair_degenerate_faces(&mesh);
        assert_eq!(
            r.repair,
            DegenerateRepair {
                flipped: 0,
                removed: 1,
                collapsed: 0
            }
        );
        assert_eq!(r.mesh.num_faces(), 5);
        assert_eq!(r.vertex_map, (0..7).map(Some).collect::<Vec<_>>());
        assert!(degenerate_faces(&r.mesh).is_empty());
        assert!((area(&r.mesh) - area(&mesh)).abs() < 1e-15);
        assert!(is_disk(&r.mesh));
    }

    #[test]
    fn coincident_vertices_are_collapsed() {
        // vertex 7 duplicates the centre 0 and splits the fan's face (0, 1, 2) into (0, 1, 7),
        // (7, 1, 2) and (0, 7, 2); at 0's position, it makes the first and the last degenerate
        let mut mesh = hexagon([0.0; 3]);
        mesh.positions.push([0.0; 3]);
        mesh.faces[0] = [0, 1, 7];
        mesh.faces.push([7, 1, 2]);
        mesh.faces.push([0, 7, 2]);
        let before = degenerate_faces(&mesh);
        assert_eq!(before, vec![0, 7]);
        let r = repair_degenerate_faces(&mesh);
        assert_eq!(
            r.repair,
            DegenerateRepair {
                flipped: 0,
                removed: 0,
                collapsed: 1
            }
        );
        assert!(r.remaining.is_empty());
        assert_eq!(r.mesh.num_vertices(), 7);
        assert_eq!(r.mesh.num_faces(), 6);
        assert_eq!(r.vertex_map[7], None);
        assert!(degenerate_faces(&r.mesh).is_empty());
        assert!((area(&r.mesh) - area(&mesh)).abs() < 1e-15);
        assert!(is_disk(&r.mesh));
    }

    #[test]
    fn a_collapse_against_the_link_condition_is_left() {
        // a tetrahedron's boundary: nothing degenerate, nothing done
        let mesh = TriMesh::new(
            vec![[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]],
            vec![[0, 2, 1], [0, 1, 3], [1, 2, 3], [2, 0, 3]],
        )
        .unwrap();
        let r = repair_degenerate_faces(&mesh);
        assert_eq!(r.repair.total(), 0);
        assert_eq!(r.mesh.faces, mesh.faces);
        // a tetrahedron squashed: vertex 3 at vertex 0 makes the two faces on edge 0–3
        // degenerate, and collapsing 0–3 would stack two faces on the triangle 0 1 2 (the
        // common neighbours are the apexes, but the links share the edge 1–2)
        let mut flat = mesh.clone();
        flat.positions[3] = flat.positions[0];
        let r = repair_degenerate_faces(&flat);
        assert_eq!(r.repair.total(), 0);
        assert_eq!(r.remaining, vec![[0, 1, 3], [2, 0, 3]]);
    }
}
