//! Cutting a closed genus-0 surface open along a tree of edge paths (a *seam*) through its
//! extremities, instead of removing a small disk.
//!
//! Why: a conformal map of a disk shrinks a protrusion exponentially in its length over its
//! width (Su et al. 2015, Fig. 1). A body cut open by a small disk on the torso keeps every limb
//! as an interior protrusion, and its conformal image puts whole fingers, paws and tails into
//! regions a few ulps wide (the TOSCA meshes, `docs/bodies-and-seams.md`). A seam that runs
//! through the limbs' tips turns each limb into a strip along the boundary, which the conformal
//! map opens instead of collapsing — the usual remedy in surface parameterization (cut graphs
//! through points of extreme conformal scale, as in Ben-Chen, Gotsman & Bunin 2008 and Sharp &
//! Crane 2018).
//!
//! The seam is the union of shortest edge paths (Dijkstra on edge lengths) joining the terminals
//! one after another to the tree built so far, so it is a tree. Cutting a closed genus-0 surface
//! along a tree gives a disk whose boundary walks around the tree: a tree vertex of degree d
//! becomes d vertices (one per wedge of its faces between consecutive seam edges), a leaf stays
//! one vertex.

use crate::connectivity::Connectivity;
use crate::error::GeometryError;
use crate::mesh::TriMesh;
use crate::paths::shortest_edge_paths as dijkstra;
use crate::topology;

/// `count` extremities of a connected surface by geodesic farthest-point sampling (edge-path
/// distances). On a surface with boundary the first is the vertex farthest from the boundary,
/// each next one the vertex farthest from the boundary and the ones chosen so far; on a closed
/// surface the first is the vertex farthest from the first face's first vertex. On a body the
/// first ones are the tips of the limbs, the tail and the head. Ties go to the smaller index;
/// fewer are returned when every vertex is chosen or on the boundary. Errors when the surface is
/// not connected.
pub fn extremities(mesh: &TriMesh, count: usize) -> Result<Vec<u32>, GeometryError> {
    mesh.validate()?;
    let conn = Connectivity::of(mesh);
    extremities_in(mesh, &conn, &conn.vertex_neighbors(mesh.num_vertices()), count)
}

/// [`extremities`] on a validated mesh with its connectivity and vertex adjacency.
fn extremities_in(
    mesh: &TriMesh,
    conn: &Connectivity,
    adjacency: &[Vec<u32>],
    count: usize,
) -> Result<Vec<u32>, GeometryError> {
    let n = mesh.num_vertices();
    if n == 0 || count == 0 {
        return Ok(Vec::new());
    }
    let farthest = |dist: &[f64]| -> Option<u32> {
        let mut best: Option<(f64, u32)> = None;
        for (v, &d) in dist.iter().enumerate() {
            if d.is_finite() && d > 0.0 && best.is_none_or(|(b, _)| d > b) {
                best = Some((d, v as u32));
            }
        }
        best.map(|(_, v)| v)
    };
    let on_boundary = conn.boundary_vertices(n);
    let boundary: Vec<u32> = (0..n as u32).filter(|&v| on_boundary[v as usize]).collect();
    // start from a referenced vertex (an unreferenced one reaches nothing)
    let Some(first) = mesh.faces.first().map(|f| f[0]) else {
        return Ok(Vec::new());
    };
    let mut chosen = Vec::new();
    let mut nearest = if boundary.is_empty() {
        let start = farthest(&dijkstra(mesh, adjacency, &[first], |_| false).0).unwrap_or(first);
        chosen.push(start);
        dijkstra(mesh, adjacency, &[start], |_| false).0
    } else {
        dijkstra(mesh, adjacency, &boundary, |_| false).0
    };
    // every referenced vertex must be reachable: one component
    let referenced = crate::topology::referenced_vertices(mesh);
    if let Some(v) = (0..n).find(|&v| referenced[v] && !nearest[v].is_finite()) {
        return Err(GeometryError::Topology(format!(
            "extremities need a connected surface; vertex {v} is not connected to {}",
            if boundary.is_empty() {
                "the rest"
            } else {
                "the boundary"
            }
        )));
    }
    while chosen.len() < count {
        let Some(v) = farthest(&nearest) else { break };
        chosen.push(v);
        if chosen.len() == count {
            break;
        }
        let d = dijkstra(mesh, adjacency, &[v], |_| false).0;
        for (a, b) in nearest.iter_mut().zip(d) {
            *a = a.min(b);
        }
    }
    Ok(chosen)
}

/// The seam through `terminals`: on a closed surface each terminal after the first is joined by
/// a shortest edge path to the nearest vertex of the tree built so far; on a surface with
/// boundary each terminal is joined to the nearest vertex of the boundary or of the paths built
/// so far (so every component of the seam meets the boundary at one vertex). Returns the seam's
/// edges as (min, max) pairs. Errors when a terminal is out of range or cannot be reached.
pub fn seam_tree(mesh: &TriMesh, terminals: &[u32]) -> Result<Vec<[u32; 2]>, GeometryError> {
    mesh.validate()?;
    let conn = Connectivity::of(mesh);
    seam_tree_in(mesh, &conn, &conn.vertex_neighbors(mesh.num_vertices()), terminals)
}

/// [`seam_tree`] on a validated mesh with its connectivity and vertex adjacency.
fn seam_tree_in(
    mesh: &TriMesh,
    conn: &Connectivity,
    adjacency: &[Vec<u32>],
    terminals: &[u32],
) -> Result<Vec<[u32; 2]>, GeometryError> {
    let n = mesh.num_vertices();
    if let Some(&t) = terminals.iter().find(|&&t| t as usize >= n) {
        return Err(GeometryError::Invalid(format!(
            "seam terminal {t} is out of range ({n} vertices)"
        )));
    }
    let mut in_tree = conn.boundary_vertices(n);
    let mut edges = Vec::new();
    let mut rest = terminals;
    if !in_tree.iter().any(|&b| b) {
        let Some((&first, others)) = terminals.split_first() else {
            return Ok(edges);
        };
        in_tree[first as usize] = true;
        rest = others;
    }
    for &t in rest {
        if in_tree[t as usize] {
            continue;
        }
        let (_, previous, reached) = dijkstra(mesh, adjacency, &[t], |v| in_tree[v as usize]);
        let Some(mut v) = reached else {
            return Err(GeometryError::Topology(format!(
                "seam terminal {t} cannot be reached from the boundary or the other terminals"
            )));
        };
        while v != t {
            let p = previous[v as usize];
            edges.push([v.min(p), v.max(p)]);
            in_tree[v as usize] = true;
            v = p;
        }
        in_tree[t as usize] = true;
    }
    Ok(edges)
}

/// Cuts a surface open along `seam` (edges as vertex pairs). On a closed surface the seam must be
/// a tree; on a surface with boundary, a forest each of whose trees meets the boundary at one
/// vertex (with the boundary contracted to a point, the seam is a tree through it). At every
/// vertex the seam edges split its faces into wedges (between consecutive seam edges, and the
/// boundary for a boundary vertex); each wedge gets its own copy of the vertex (the first keeps
/// the index, the others are appended at the end). Faces and their order are kept. Returns the
/// cut mesh and, for each of its vertices, the input vertex it copies. Cutting a sphere or a disk
/// this way gives a disk (checked with [`topology::require_disk`]).
///
/// Errors when the surface is not edge-manifold, not consistently oriented, has a face with a
/// repeated vertex or more than one boundary loop, when a seam vertex is not manifold, when a
/// seam edge is not an edge of the mesh or lies on the boundary, when the seam is empty or not a
/// tree as above, or when the result is not a disk (which also catches non-manifold vertices
/// off the seam and surfaces of higher genus).
pub fn cut_along_seam(mesh: &TriMesh, seam: &[[u32; 2]]) -> Result<(TriMesh, Vec<u32>), GeometryError> {
    mesh.validate()?;
    cut_along_seam_in(mesh, &Connectivity::of(mesh), seam)
}

/// A mesh slit from its extremities ([`slit_from_extremities`]).
pub(crate) struct Slit {
    /// The cut mesh.
    pub mesh: TriMesh,
    /// For each vertex of the cut mesh, the vertex of the input it copies.
    pub copies: Vec<u32>,
    /// The extremities (input vertices).
    pub extremities: Vec<u32>,
    /// Edges of the seam.
    pub seam_edges: usize,
}

/// The slit of [`crate::prepare::prepare_disk`]: the mesh cut along the seam from its `count`
/// extremities to the boundary ([`extremities`], [`seam_tree`], [`cut_along_seam`] on one
/// connectivity); `None` when the seam is empty.
pub(crate) fn slit_from_extremities(mesh: &TriMesh, count: usize) -> Result<Option<Slit>, GeometryError> {
    mesh.validate()?;
    let conn = Connectivity::of(mesh);
    let adjacency = conn.vertex_neighbors(mesh.num_vertices());
    let terminals = extremities_in(mesh, &conn, &adjacency, count)?;
    let seam = seam_tree_in(mesh, &conn, &adjacency, &terminals)?;
    if seam.is_empty() {
        return Ok(None);
    }
    let (cut, copies) = cut_along_seam_in(mesh, &conn, &seam)?;
    Ok(Some(Slit {
        mesh: cut,
        copies,
        extremities: terminals,
        seam_edges: seam.len(),
    }))
}

/// The surface conditions of a seam cut: faces with three distinct vertices, an edge-manifold
/// and consistently oriented surface, at most one boundary loop.
fn check_cuttable(mesh: &TriMesh, conn: &Connectivity) -> Result<(), GeometryError> {
    if let Some(f) = mesh
        .faces
        .iter()
        .position(|f| f[0] == f[1] || f[1] == f[2] || f[2] == f[0])
    {
        return Err(GeometryError::Topology(format!(
            "a seam cut needs faces with three distinct vertices; face {f} repeats one"
        )));
    }
    if let Some(e) = conn.edge_faces.iter().position(|f| f.len() > 2) {
        let [a, b] = conn.edges[e];
        return Err(GeometryError::Topology(format!(
            "a seam cut needs an edge-manifold surface; edge ({a}, {b}) has {} faces",
            conn.edge_faces[e].len()
        )));
    }
    if let Some([a, b]) = topology::inconsistent_edges(&mesh.faces, conn).first() {
        return Err(GeometryError::Topology(format!(
            "a seam cut needs a consistently oriented surface; the two faces at edge ({a}, {b}) run along it in the same direction"
        )));
    }
    let loops = conn.boundary_loops(&mesh.faces).len();
    if loops > 1 {
        return Err(GeometryError::Topology(format!(
            "a seam cut needs a closed surface or a disk; this surface has {loops} boundary loops (fill all but one first: `prepare::fill_holes_except_longest`)"
        )));
    }
    Ok(())
}

/// Checks that `seam` is a set of interior mesh edges forming a tree once the boundary is
/// contracted to one node (connected to the boundary when there is one); returns the seam flag
/// per edge and the seam degree per vertex.
fn checked_seam(
    conn: &Connectivity,
    on_boundary: &[bool],
    seam: &[[u32; 2]],
) -> Result<(Vec<bool>, Vec<u32>), GeometryError> {
    let n = on_boundary.len();
    if seam.is_empty() {
        return Err(GeometryError::Invalid("the seam has no edges".into()));
    }
    let mut is_seam = vec![false; conn.num_edges()];
    let mut degree = vec![0u32; n];
    // Tree check with the boundary contracted to one node (index n): union–find over the nodes.
    let boundary_node = n as u32;
    let mut parent: Vec<u32> = (0..=boundary_node).collect();
    let (find, union) = (topology::find, topology::union);
    let node = |v: u32| if on_boundary[v as usize] { boundary_node } else { v };
    for &[a, b] in seam {
        let key = [a.min(b), a.max(b)];
        let Ok(e) = conn.edges.binary_search(&key) else {
            return Err(GeometryError::Invalid(format!(
                "seam edge ({a}, {b}) is not an edge of the mesh"
            )));
        };
        if is_seam[e] {
            continue;
        }
        if conn.edge_faces[e].len() != 2 {
            return Err(GeometryError::Invalid(format!(
                "seam edge ({a}, {b}) lies on the boundary"
            )));
        }
        if !union(&mut parent, node(a), node(b)) {
            return Err(GeometryError::Invalid(format!(
                "the seam is not a tree: edge ({a}, {b}) closes a cycle (the boundary counts as one vertex)"
            )));
        }
        is_seam[e] = true;
        degree[a as usize] += 1;
        degree[b as usize] += 1;
    }
    let has_boundary = on_boundary.iter().any(|&b| b);
    let r = find(&mut parent, if has_boundary { boundary_node } else { seam[0][0] });
    if let Some(v) = (0..n).find(|&v| degree[v] > 0 && find(&mut parent, node(v as u32)) != r) {
        return Err(GeometryError::Invalid(format!(
            "the seam is not connected{}: vertex {v} is not joined to the rest",
            if has_boundary { " to the boundary" } else { "" }
        )));
    }
    Ok((is_seam, degree))
}

/// [`cut_along_seam`] on a validated mesh with its connectivity.
fn cut_along_seam_in(
    mesh: &TriMesh,
    conn: &Connectivity,
    seam: &[[u32; 2]],
) -> Result<(TriMesh, Vec<u32>), GeometryError> {
    let n = mesh.num_vertices();
    check_cuttable(mesh, conn)?;
    let on_boundary = conn.boundary_vertices(n);
    let (is_seam, degree) = checked_seam(conn, &on_boundary, seam)?;
    let edge_of = |a: u32, b: u32| conn.edges.binary_search(&[a.min(b), a.max(b)]).ok();
    let mut faces = mesh.faces.clone();
    let mut origin: Vec<u32> = (0..n as u32).collect();
    let mut positions = mesh.positions.clone();
    for v in 0..n as u32 {
        let boundary = on_boundary[v as usize];
        if degree[v as usize] == 0 || (!boundary && degree[v as usize] < 2) {
            continue;
        }
        // Walk the fan around v counter-clockwise: face (v, a, b) is followed, across edge
        // {v, b}, by the face holding the directed edge v → b. An interior vertex starts right
        // after a seam edge, a boundary vertex at the face after its boundary edge {v, a}.
        let fan = &conn.vertex_faces[v as usize];
        let rotate = |f: u32| -> [u32; 3] {
            let face = mesh.faces[f as usize];
            let k = face.iter().position(|&x| x == v).unwrap_or(0);
            [face[k], face[(k + 1) % 3], face[(k + 2) % 3]]
        };
        let next = |f: u32| -> Option<(u32, bool)> {
            let [_, _, b] = rotate(f);
            let e = edge_of(v, b)?;
            let g = *conn.edge_faces[e].iter().find(|&&g| g != f)?;
            Some((g, is_seam[e]))
        };
        let start = fan.iter().copied().find(|&f| {
            let [_, a, b] = rotate(f);
            if boundary {
                edge_of(v, a).is_some_and(|e| conn.edge_faces[e].len() == 1)
            } else {
                edge_of(v, b).is_some_and(|e| is_seam[e])
            }
        });
        let start = match (start, boundary) {
            (Some(f), true) => Some(f),
            (Some(f), false) => next(f).map(|(g, _)| g),
            (None, _) => None,
        };
        let Some(start) = start else {
            return Err(GeometryError::Topology(format!(
                "vertex {v}: no start for the walk around it"
            )));
        };
        let (mut f, mut copy, mut visited) = (start, v, 0);
        loop {
            let k = mesh.faces[f as usize].iter().position(|&x| x == v).unwrap_or(0);
            faces[f as usize][k] = copy;
            visited += 1;
            if visited > fan.len() {
                return Err(GeometryError::Topology(format!("vertex {v} is not manifold")));
            }
            let Some((g, crosses_seam)) = next(f) else {
                if boundary {
                    break;
                }
                return Err(GeometryError::Topology(format!("vertex {v}: its fan is not closed")));
            };
            if g == start {
                break;
            }
            if crosses_seam {
                copy = positions.len() as u32;
                positions.push(mesh.positions[v as usize]);
                origin.push(v);
            }
            f = g;
        }
        if visited != fan.len() {
            return Err(GeometryError::Topology(format!(
                "vertex {v} is not manifold: its faces form more than one fan"
            )));
        }
    }
    if positions.len() > u32::MAX as usize {
        return Err(GeometryError::Invalid("too many vertices after the seam cut".into()));
    }
    let out = TriMesh {
        positions,
        faces,
        uvs: None,
    };
    topology::require_disk(&out)?;
    Ok((out, origin))
}
