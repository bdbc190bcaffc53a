//! Explicit mesh preparation operations, each called by the user (nothing here runs
//! implicitly): drop unreferenced vertices, keep the largest component, make the orientation
//! consistent, repair degenerate faces ([`crate::repair`]), fill holes, cut a disk out of a closed surface, scale to a given area.
//!
//! Every operation returns a new mesh. Vertex order is preserved except where documented; when
//! vertices are removed, an old→new index map (`Vec<Option<u32>>`, #V of the input) is returned
//! so that per-vertex data and correspondences can follow. Added vertices are appended at the end.
//! Texture coordinates (`uvs`) are carried along when vertices are only removed or reordered and
//! dropped when vertices are added or moved.

use std::collections::HashMap;

use crate::connectivity::Connectivity;
use crate::error::GeometryError;
use crate::mesh::TriMesh;
use crate::paths::edge_path_distances;
use crate::quantities::{face_areas, triangle_area};
use crate::repair::{repair_degenerate_faces, DegenerateRepair};
use crate::topology::{self, face_components, orientation_flips, MeshClass};
use crate::vec3::{add, cross, dot, norm, scale, sub};

/// Old→new vertex index map, #V of the input: `None` for a removed vertex.
pub type VertexMap = Vec<Option<u32>>;

/// Keeps the vertices with `keep[v]`, preserving their relative order, and renumbers the faces
/// (every face must reference kept vertices only).
fn compact_vertices(mesh: &TriMesh, faces: Vec<[u32; 3]>, keep: &[bool]) -> (TriMesh, VertexMap) {
    let mut map = vec![None; mesh.num_vertices()];
    let mut positions = Vec::new();
    let mut uvs = mesh.uvs.as_ref().map(|_| Vec::new());
    for (v, &k) in keep.iter().enumerate() {
        if k {
            map[v] = Some(positions.len() as u32);
            positions.push(mesh.positions[v]);
            if let (Some(out), Some(src)) = (uvs.as_mut(), mesh.uvs.as_ref()) {
                out.push(src[v]);
            }
        }
    }
    let faces = faces
        .into_iter()
        .map(|f| f.map(|v| map[v as usize].expect("face references a removed vertex")))
        .collect();
    (TriMesh { positions, faces, uvs }, map)
}

/// Removes the vertices referenced by no face. The remaining vertices keep their relative order;
/// returns the new mesh and the old→new map (#V of the input).
pub fn drop_unreferenced_vertices(mesh: &TriMesh) -> Result<(TriMesh, VertexMap), GeometryError> {
    mesh.validate()?;
    let keep = topology::referenced_vertices(mesh);
    Ok(compact_vertices(mesh, mesh.faces.clone(), &keep))
}

/// Keeps the connected component (faces through edges) with the most faces (ties: the one
/// containing the smallest face index) and drops every vertex not referenced by it. Face order
/// and the relative vertex order are preserved; returns the old→new vertex map.
pub fn keep_largest_component(mesh: &TriMesh) -> Result<(TriMesh, VertexMap), GeometryError> {
    mesh.validate()?;
    if mesh.faces.is_empty() {
        return Err(GeometryError::Topology("the mesh has no faces".into()));
    }
    let conn = Connectivity::of(mesh);
    let (labels, n) = face_components(&conn, mesh.num_faces());
    let mut counts = vec![0usize; n];
    for &l in &labels {
        counts[l as usize] += 1;
    }
    // labels are numbered by smallest face, so the first maximum is the tie-break we document
    let best = (0..n).fold(0, |b, c| if counts[c] > counts[b] { c } else { b }) as u32;
    let faces: Vec<[u32; 3]> = mesh
        .faces
        .iter()
        .zip(&labels)
        .filter(|(_, &l)| l == best)
        .map(|(f, _)| *f)
        .collect();
    let mut keep = vec![false; mesh.num_vertices()];
    for f in &faces {
        for &v in f {
            keep[v as usize] = true;
        }
    }
    Ok(compact_vertices(mesh, faces, &keep))
}

/// Signed volume (1/6) Σ_f det(a − c, b − c, c' − c) of a set of faces about a reference point
/// `c`: positive for a closed surface whose faces are counter-clockwise seen from outside.
fn signed_volume(mesh: &TriMesh, faces: &[usize], center: [f64; 3]) -> f64 {
    faces
        .iter()
        .map(|&f| {
            let [a, b, c] = mesh.face_positions(f);
            let (a, b, c) = (sub(a, center), sub(b, center), sub(c, center));
            dot(a, cross(b, c)) / 6.0
        })
        .sum()
}

/// What [`reorient`] changed.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct ReorientInfo {
    /// Faces flipped to make the orientation consistent.
    pub faces_flipped_for_consistency: usize,
    /// Closed components whose faces were all flipped to point outward.
    pub closed_components_turned_outward: usize,
}

/// Makes the face orientation consistent and, on closed components, outward.
///
/// Breadth-first search over faces through edges with exactly two faces flips every face that
/// traverses a shared edge in the same direction as its already-visited neighbour (each piece
/// keeps the orientation most of its faces have; flipping `[a, b, c]` gives `[a, c, b]`). Then each closed
/// component (every edge has exactly two faces) with negative signed volume is flipped entirely,
/// so its normals point outward. Vertices are unchanged. Errors for a non-orientable surface,
/// naming the edge where the contradiction appears.
pub fn reorient(mesh: &TriMesh) -> Result<(TriMesh, ReorientInfo), GeometryError> {
    mesh.validate()?;
    let conn = Connectivity::of(mesh);
    let flips = orientation_flips(&mesh.faces, &conn).map_err(|e| {
        GeometryError::Topology(format!(
            "non-orientable surface (like a Möbius strip): orientation contradiction at edge ({}, {}); \
             no consistent orientation exists",
            e[0], e[1]
        ))
    })?;
    let mut out = mesh.clone();
    let mut flipped = 0;
    for (face, &fl) in out.faces.iter_mut().zip(&flips) {
        if fl {
            face.swap(1, 2);
            flipped += 1;
        }
    }
    let (labels, n) = face_components(&conn, mesh.num_faces());
    let mut comp_faces = vec![Vec::new(); n];
    for (f, &l) in labels.iter().enumerate() {
        comp_faces[l as usize].push(f);
    }
    let mut comp_closed = vec![true; n];
    for ef in &conn.edge_faces {
        if ef.len() != 2 {
            comp_closed[labels[ef[0] as usize] as usize] = false;
        }
    }
    let mut turned = 0;
    for c in 0..n {
        if !comp_closed[c] {
            continue;
        }
        // reference point: mean of the face centroids, so the volume is translation-exact-ish
        let mut center = [0.0; 3];
        for &f in &comp_faces[c] {
            let [a, b, cc] = out.face_positions(f);
            center = add(center, scale(add(add(a, b), cc), 1.0 / 3.0));
        }
        center = scale(center, 1.0 / comp_faces[c].len() as f64);
        if signed_volume(&out, &comp_faces[c], center) < 0.0 {
            for &f in &comp_faces[c] {
                out.faces[f].swap(1, 2);
            }
            turned += 1;
        }
    }
    Ok((
        out,
        ReorientInfo {
            faces_flipped_for_consistency: flipped,
            closed_components_turned_outward: turned,
        },
    ))
}

/// Fills one hole by a fan: appends a vertex at the mean of the loop's vertex positions (index
/// #V of the input) and one triangle per loop edge. Each new triangle traverses its loop edge
/// opposite to the existing face on that edge, so the orientation stays consistent.
///
/// `hole` is a cycle of vertices (either direction) whose consecutive pairs, including
/// last→first, are boundary edges (one face), as returned by [`Connectivity::boundary_loops`].
/// Texture coordinates are dropped.
pub fn fill_hole(mesh: &TriMesh, hole: &[u32]) -> Result<TriMesh, GeometryError> {
    mesh.validate()?;
    let conn = Connectivity::of(mesh);
    let mut out = mesh.clone();
    out.uvs = None;
    append_fan(&mut out, &conn, hole)?;
    Ok(out)
}

fn append_fan(out: &mut TriMesh, conn: &Connectivity, hole: &[u32]) -> Result<(), GeometryError> {
    if hole.len() < 3 {
        return Err(GeometryError::Invalid(format!(
            "a hole needs at least 3 vertices, got {}",
            hole.len()
        )));
    }
    let mut edge_index: HashMap<[u32; 2], usize> = HashMap::with_capacity(hole.len());
    let wanted: Vec<[u32; 2]> = (0..hole.len())
        .map(|i| {
            let (a, b) = (hole[i], hole[(i + 1) % hole.len()]);
            [a.min(b), a.max(b)]
        })
        .collect();
    for w in &wanted {
        edge_index.insert(*w, usize::MAX);
    }
    for (e, key) in conn.edges.iter().enumerate() {
        if let Some(slot) = edge_index.get_mut(key) {
            *slot = e;
        }
    }
    let c = out.positions.len() as u32;
    let mut centroid = [0.0; 3];
    for &v in hole {
        let p = *out.positions.get(v as usize).ok_or_else(|| {
            GeometryError::Invalid(format!(
                "hole vertex {v} is out of range ({} vertices)",
                out.positions.len()
            ))
        })?;
        centroid = add(centroid, p);
    }
    centroid = scale(centroid, 1.0 / hole.len() as f64);
    let mut new_faces = Vec::with_capacity(hole.len());
    for (i, w) in wanted.iter().enumerate() {
        let e = edge_index[w];
        if e == usize::MAX || conn.edge_faces[e].len() != 1 {
            let (a, b) = (hole[i], hole[(i + 1) % hole.len()]);
            return Err(GeometryError::Invalid(format!(
                "({a}, {b}) is not a boundary edge (one face), so the hole loop is invalid"
            )));
        }
        let f = conn.edge_faces[e][0] as usize;
        let k = conn.face_edges[f].iter().position(|&x| x as usize == e).unwrap_or(0);
        let face = out.faces[f];
        let (x, y) = (face[(k + 1) % 3], face[(k + 2) % 3]);
        new_faces.push([y, x, c]);
    }
    out.positions.push(centroid);
    out.faces.extend(new_faces);
    Ok(())
}

/// What [`fill_holes_except_longest`] did.
#[derive(Clone, Debug, PartialEq)]
pub struct FillInfo {
    /// Number of holes filled (= number of vertices appended, one per hole, at the end).
    pub holes_filled: usize,
    /// Geometric length of the loop that was kept open.
    pub kept_loop_length: f64,
}

/// Fills every boundary loop but the geometrically longest one (the outer boundary of a face or
/// a scan) with a fan to its centroid ([`fill_hole`]); a manifold mesh with `b` loops and
/// genus 0 becomes a disk. One new vertex per hole is appended (vertex order otherwise kept);
/// texture coordinates are dropped. A mesh with no boundary is an error (see [`cut_disk`]).
pub fn fill_holes_except_longest(mesh: &TriMesh) -> Result<(TriMesh, FillInfo), GeometryError> {
    mesh.validate()?;
    let conn = Connectivity::of(mesh);
    let loops = conn.boundary_loops(&mesh.faces);
    if loops.is_empty() {
        return Err(GeometryError::Topology(
            "no boundary loop: the surface is closed; cut a disk with `prepare::cut_disk`".into(),
        ));
    }
    let length = |l: &[u32]| -> f64 {
        (0..l.len())
            .map(|i| {
                norm(sub(
                    mesh.positions[l[(i + 1) % l.len()] as usize],
                    mesh.positions[l[i] as usize],
                ))
            })
            .sum()
    };
    let lengths: Vec<f64> = loops.iter().map(|l| length(l)).collect();
    let longest = (0..loops.len()).fold(0, |b, i| if lengths[i] > lengths[b] { i } else { b });
    let mut out = mesh.clone();
    out.uvs = None;
    for (i, l) in loops.iter().enumerate() {
        if i != longest {
            append_fan(&mut out, &conn, l)?;
        }
    }
    Ok((
        out,
        FillInfo {
            holes_filled: loops.len() - 1,
            kept_loop_length: lengths[longest],
        },
    ))
}

/// Size of the region removed by [`cut_disk`].
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Radius {
    /// Geodesic radius, approximated by shortest paths along edges (Dijkstra on edge lengths),
    /// in the mesh's length unit.
    Geodesic(f64),
    /// Graph distance in edges: `Rings(1)` is the one-ring of the centre.
    Rings(usize),
}

/// Cuts a disk out of a closed surface: removes the faces whose three vertices all lie in the
/// ball around `center` (edge-path distance ≤ r for [`Radius::Geodesic`], graph distance ≤ k for
/// [`Radius::Rings`]), drops the vertices left unreferenced and checks that the rest is a
/// topological disk. Face order and the relative vertex order are kept; returns the old→new
/// vertex map. `center` itself is always removed with its one-ring of faces.
///
/// Errors when the input has a boundary, when the ball removes no face or every face, and when
/// the remaining mesh is not a disk (e.g. the ball wraps around a handle or pinches the surface);
/// the error gives the classification's reasons.
pub fn cut_disk(mesh: &TriMesh, center: u32, radius: Radius) -> Result<(TriMesh, VertexMap), GeometryError> {
    mesh.validate()?;
    if center as usize >= mesh.num_vertices() {
        return Err(GeometryError::Invalid(format!(
            "cut centre {center} is out of range ({} vertices)",
            mesh.num_vertices()
        )));
    }
    let conn = Connectivity::of(mesh);
    if conn.edge_faces.iter().any(|ef| ef.len() == 1) {
        return Err(GeometryError::Topology(
            "cut_disk needs a closed surface, but this mesh has a boundary".into(),
        ));
    }
    let inside: Vec<bool> = match radius {
        Radius::Geodesic(r) => {
            if r.is_nan() || r < 0.0 {
                return Err(GeometryError::Invalid(format!("cut radius must be ≥ 0, got {r}")));
            }
            edge_path_distances(mesh, &conn, center)
                .iter()
                .map(|&d| d <= r)
                .collect()
        }
        Radius::Rings(k) => {
            let adj = conn.vertex_neighbors(mesh.num_vertices());
            let mut depth = vec![usize::MAX; mesh.num_vertices()];
            depth[center as usize] = 0;
            let mut frontier = vec![center];
            for d in 1..=k {
                let mut next = Vec::new();
                for &v in &frontier {
                    for &w in &adj[v as usize] {
                        if depth[w as usize] == usize::MAX {
                            depth[w as usize] = d;
                            next.push(w);
                        }
                    }
                }
                frontier = next;
            }
            depth.iter().map(|&d| d <= k).collect()
        }
    };
    let faces: Vec<[u32; 3]> = mesh
        .faces
        .iter()
        .filter(|f| {
            let all_in = f.iter().all(|&v| inside[v as usize]);
            let touches_center = f.contains(&center);
            !(all_in || touches_center)
        })
        .copied()
        .collect();
    if faces.is_empty() {
        return Err(GeometryError::Topology(
            "the cut removes every face; choose a smaller radius".into(),
        ));
    }
    let mut keep = vec![false; mesh.num_vertices()];
    for f in &faces {
        for &v in f {
            keep[v as usize] = true;
        }
    }
    let (out, map) = compact_vertices(mesh, faces, &keep);
    let class = topology::classify(&out)?;
    if class.class != MeshClass::Disk {
        return Err(GeometryError::Topology(format!(
            "removing the ball around vertex {center} leaves a non-disk ({}); try another radius or centre",
            class.reasons.join("; ")
        )));
    }
    Ok((out, map))
}

/// The area-weighted centroid Σ_f A_f g_f / Σ_f A_f (g_f the face centroid) for face areas
/// `areas` summing to `total`.
fn area_centroid(mesh: &TriMesh, areas: &[f64], total: f64) -> [f64; 3] {
    let mut c = [0.0; 3];
    for (f, &a) in areas.iter().enumerate() {
        let [p, q, r] = mesh.face_positions(f);
        c = add(c, scale(add(add(p, q), r), a / 3.0));
    }
    scale(c, 1.0 / total)
}

/// Scales the mesh uniformly about its area-weighted centroid c = Σ_f A_f g_f / Σ_f A_f (g_f the
/// face centroid) so that its total area becomes `target_area`: p ↦ c + s (p − c),
/// s = √(target / area). Faces, vertex order and texture coordinates are unchanged. Errors on a
/// zero or non-finite area and on a non-positive target.
pub fn scale_to_area(mesh: &TriMesh, target_area: f64) -> Result<TriMesh, GeometryError> {
    mesh.validate()?;
    if !(target_area > 0.0 && target_area.is_finite()) {
        return Err(GeometryError::Invalid(format!(
            "target area must be positive and finite, got {target_area}"
        )));
    }
    let areas = face_areas(mesh);
    let area: f64 = areas.iter().sum();
    if !(area > 0.0 && area.is_finite()) {
        return Err(GeometryError::Invalid(format!(
            "cannot scale a mesh of area {area} to area {target_area}"
        )));
    }
    let c = area_centroid(mesh, &areas, area);
    let s = (target_area / area).sqrt();
    let mut out = mesh.clone();
    for p in &mut out.positions {
        *p = add(c, scale(sub(*p, c), s));
    }
    // one correction pass: rounding in the scaled coordinates leaves a relative error of a few ulps
    let new_area: f64 = (0..out.num_faces())
        .map(|f| {
            let [a, b, cc] = out.face_positions(f);
            triangle_area(a, b, cc)
        })
        .sum();
    if new_area > 0.0 {
        let t = (target_area / new_area).sqrt();
        for p in &mut out.positions {
            *p = add(c, scale(sub(*p, c), t));
        }
    }
    Ok(out)
}

/// 1-to-4 midpoint subdivision: every edge gets its midpoint (appended after the original
/// vertices, in order of first appearance over the faces) and every face (a, b, c) becomes
/// (a, ab, ca), (ab, b, bc), (ca, bc, c), (ab, bc, ca). The piecewise-linear surface is
/// unchanged (same area, same topology: V + E vertices, 4F faces); texture coordinates, if any,
/// are interpolated the same way. Used to remesh a surface without changing its geometry.
pub fn subdivide_midpoint(mesh: &TriMesh) -> Result<TriMesh, GeometryError> {
    mesh.validate()?;
    let mut positions = mesh.positions.clone();
    let mut uvs = mesh.uvs.clone();
    let mut midpoint: HashMap<(u32, u32), u32> = HashMap::new();
    let mut faces = Vec::with_capacity(4 * mesh.faces.len());
    for &[a, b, c] in &mesh.faces {
        let mut mid = |u: u32, v: u32| -> u32 {
            *midpoint.entry((u.min(v), u.max(v))).or_insert_with(|| {
                positions.push(scale(add(positions[u as usize], positions[v as usize]), 0.5));
                if let Some(uv) = uvs.as_mut() {
                    let (p, q) = (uv[u as usize], uv[v as usize]);
                    uv.push([0.5 * (p[0] + q[0]), 0.5 * (p[1] + q[1])]);
                }
                (positions.len() - 1) as u32
            })
        };
        let (ab, bc, ca) = (mid(a, b), mid(b, c), mid(c, a));
        faces.extend([[a, ab, ca], [ab, b, bc], [ca, bc, c], [ab, bc, ca]]);
    }
    if positions.len() > u32::MAX as usize {
        return Err(GeometryError::Invalid(format!(
            "subdivision would have {} vertices (over the u32 range)",
            positions.len()
        )));
    }
    let mut out = TriMesh::new(positions, faces)?;
    out.uvs = uvs;
    Ok(out)
}

/// The interior edges whose two endpoints both lie on the boundary ("bridges"), each as
/// `[a, b]` with a < b, sorted. A bridge can cut interior vertices off from the rest of the
/// interior ([`interior_components`]).
pub fn boundary_bridges(mesh: &TriMesh) -> Vec<[u32; 2]> {
    let conn = Connectivity::of(mesh);
    let on_boundary = conn.boundary_vertices(mesh.num_vertices());
    // `edges` is sorted and each is (min, max)
    conn.edges
        .iter()
        .zip(&conn.edge_faces)
        .filter(|(e, f)| f.len() == 2 && on_boundary[e[0] as usize] && on_boundary[e[1] as usize])
        .map(|(e, _)| *e)
        .collect()
}

/// Component label per vertex of the graph of interior vertices joined by edges between two
/// interior vertices (`None` for boundary vertices), and the number of components. The
/// Dirichlet problems of the disk maps (boundary values fixed, a source at one interior
/// vertex) are zero on every component without the source: with more than one component, an
/// interior vertex of another component maps onto the boundary circle.
pub fn interior_components(mesh: &TriMesh) -> (Vec<Option<u32>>, usize) {
    let n = mesh.num_vertices();
    let conn = Connectivity::of(mesh);
    let on_boundary = conn.boundary_vertices(n);
    let neighbors = conn.vertex_neighbors(n);
    let mut label: Vec<Option<u32>> = vec![None; n];
    let mut count = 0u32;
    for v in 0..n {
        if on_boundary[v] || label[v].is_some() {
            continue;
        }
        label[v] = Some(count);
        let mut stack = vec![v];
        while let Some(x) = stack.pop() {
            for &y in &neighbors[x] {
                let y = y as usize;
                if !on_boundary[y] && label[y].is_none() {
                    label[y] = Some(count);
                    stack.push(y);
                }
            }
        }
        count += 1;
    }
    (label, count as usize)
}

/// Splits each edge of `edges` (interior edges, `[a, b]`) at its midpoint: the two faces at the
/// edge, (a, b, c) and (b, a, d), become (a, m, c), (m, b, c), (b, m, d), (m, a, d) with the new
/// vertex m appended (texture coordinates, if any, interpolated). The surface is unchanged.
/// Errors: an edge that is not shared by exactly two faces.
pub fn split_edges(mesh: &TriMesh, edges: &[[u32; 2]]) -> Result<TriMesh, GeometryError> {
    mesh.validate()?;
    let mut out = mesh.clone();
    let mut faces_at: HashMap<(u32, u32), Vec<usize>> = HashMap::new();
    let key = |a: u32, b: u32| (a.min(b), a.max(b));
    for (f, t) in out.faces.iter().enumerate() {
        for k in 0..3 {
            faces_at.entry(key(t[k], t[(k + 1) % 3])).or_default().push(f);
        }
    }
    for &[a, b] in edges {
        let at = faces_at.get(&key(a, b)).cloned().unwrap_or_default();
        if at.len() != 2 {
            return Err(GeometryError::Topology(format!(
                "edge {a}-{b} is not an interior edge (it has {} faces), so it cannot be split",
                at.len()
            )));
        }
        let m = out.positions.len() as u32;
        out.positions
            .push(scale(add(out.positions[a as usize], out.positions[b as usize]), 0.5));
        if let Some(uv) = out.uvs.as_mut() {
            let (p, q) = (uv[a as usize], uv[b as usize]);
            uv.push([0.5 * (p[0] + q[0]), 0.5 * (p[1] + q[1])]);
        }
        faces_at.remove(&key(a, b));
        for f in at {
            let t = out.faces[f];
            // rotate so the edge is (t[0], t[1]) in the face's own order
            let k = (0..3)
                .find(|&k| key(t[k], t[(k + 1) % 3]) == key(a, b))
                .ok_or_else(|| GeometryError::Topology(format!("face {f} lost edge {a}-{b} while splitting")))?;
            let (u, v, w) = (t[k], t[(k + 1) % 3], t[(k + 2) % 3]);
            out.faces[f] = [u, m, w];
            out.faces.push([m, v, w]);
            let g = out.faces.len() - 1;
            // edge bookkeeping: (u, m) and (m, w) belong to f, (m, v) and (m, w) to g, (v, w)
            // moves from f to g
            faces_at.entry(key(u, m)).or_default().push(f);
            faces_at.entry(key(m, w)).or_default().extend([f, g]);
            faces_at.entry(key(m, v)).or_default().push(g);
            if let Some(list) = faces_at.get_mut(&key(v, w)) {
                for x in list.iter_mut() {
                    if *x == f {
                        *x = g;
                    }
                }
            }
        }
    }
    if out.positions.len() > u32::MAX as usize {
        return Err(GeometryError::Invalid("too many vertices after splitting edges".into()));
    }
    Ok(out)
}

/// Scales the mesh to total area π, the area of the unit disk (`docs/conventions.md`, "Normalization of a
/// surface"; Su et al. 2015 §4.2), about its area-weighted centroid ([`scale_to_area`]).
pub fn normalize_for_shape_space(mesh: &TriMesh) -> Result<TriMesh, GeometryError> {
    scale_to_area(mesh, std::f64::consts::PI)
}

/// Where [`prepare_disk`] cuts a closed surface open.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum CutCenter {
    /// The vertex nearest to the area-weighted centroid of the surface (the rule of the bundled
    /// TOSCA poses: on a body it lands on the torso, away from the extremities).
    Auto,
    /// A vertex index of the *input* mesh.
    Vertex(u32),
}

/// Options of [`prepare_disk`].
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct PrepareOptions {
    /// Centre of the disk removed from a closed surface.
    pub cut_center: CutCenter,
    /// Size of the removed disk (default: 3 rings).
    pub cut_radius: Radius,
    /// After the disk is made, cut it open along shortest edge paths from this many extremities
    /// to the boundary ([`crate::seam`]; default 0: no seam). One is the measured choice for
    /// bodies: the slit through the farthest tip keeps their conformal images from crowding
    /// beyond f64 (`docs/bodies-and-seams.md`).
    pub seam_extremities: usize,
}

impl Default for PrepareOptions {
    fn default() -> Self {
        PrepareOptions {
            cut_center: CutCenter::Auto,
            cut_radius: Radius::Rings(3),
            seam_extremities: 0,
        }
    }
}

/// What [`prepare_disk`] did, in order.
#[derive(Clone, Debug, Default, PartialEq, serde::Serialize)]
pub struct PrepareReport {
    /// Unreferenced vertices dropped.
    pub unreferenced_dropped: usize,
    /// Faces of the components other than the largest, dropped.
    pub faces_of_other_components_dropped: usize,
    /// Faces with a repeated vertex index, dropped.
    pub repeated_vertex_faces_dropped: usize,
    /// Faces flipped to make the orientation consistent.
    pub faces_flipped: usize,
    /// Closed components whose faces were all flipped to face outward (0 or 1: the largest
    /// component is kept).
    pub closed_components_turned_outward: usize,
    /// Degenerate (zero-area) faces repaired by edge flips, boundary-face removals and edge
    /// collapses ([`repair_degenerate_faces`]).
    pub degenerate_faces_repaired: DegenerateRepair,
    /// Input vertex at the centre of the disk cut from a closed surface, if one was cut.
    pub cut_center: Option<u32>,
    /// Faces removed by the cut.
    pub faces_cut: usize,
    /// Holes filled (every boundary loop but the longest), one vertex appended per hole.
    pub holes_filled: usize,
    /// Input vertices of the seam's extremities (empty without a seam; `None` for an extremity
    /// that is a vertex added by hole filling).
    pub seam_extremities: Vec<Option<u32>>,
    /// Edges of the seam.
    pub seam_edges: usize,
    /// Vertices appended by the seam cut (copies of seam vertices, one per extra wedge).
    pub seam_vertices_added: usize,
    /// Edges joining two boundary vertices split at their midpoints (one vertex appended per
    /// edge), done only when such edges cut interior vertices off from the rest of the
    /// interior ([`interior_components`]), which no harmonic disk map can place inside the disk.
    pub bridges_split: usize,
}

/// The vertex of `m` (the cleaned closed surface; `origin` maps its vertices to the input's
/// `input_vertices`) at which the disk is cut: the given input vertex, or the vertex nearest the
/// area centroid.
fn cut_center_vertex(
    cut_center: CutCenter,
    input_vertices: usize,
    m: &TriMesh,
    origin: &[Option<u32>],
) -> Result<u32, GeometryError> {
    match cut_center {
        CutCenter::Vertex(v) => {
            if v as usize >= input_vertices {
                return Err(GeometryError::Invalid(format!(
                    "cut centre {v} is out of range ({input_vertices} vertices)"
                )));
            }
            Ok(origin.iter().position(|&o| o == Some(v)).ok_or_else(|| {
                GeometryError::Invalid(format!(
                    "cut centre {v} is not on the largest component (or is unreferenced)"
                ))
            })? as u32)
        }
        CutCenter::Auto => {
            let areas = face_areas(m);
            let c = area_centroid(m, &areas, areas.iter().sum());
            Ok((0..m.num_vertices())
                .min_by(|&a, &b| norm(sub(m.positions[a], c)).total_cmp(&norm(sub(m.positions[b], c))))
                .ok_or_else(|| GeometryError::Topology("the mesh has no vertices".into()))? as u32)
        }
    }
}

/// Splits the edges joining two boundary vertices while they cut the interior of `m` into
/// pieces (the new midpoints are interior and join them; rounds, because a split can leave
/// pieces that only the next bridge joins; also when there is no interior vertex at all: a split
/// bridge gives one, as in a square of two triangles); `origin` grows with `None`s.
fn split_bridges(
    mut m: TriMesh,
    report: &mut PrepareReport,
    origin: &mut Vec<Option<u32>>,
) -> Result<TriMesh, GeometryError> {
    for _ in 0..4 {
        if interior_components(&m).1 == 1 {
            break;
        }
        let bridges = boundary_bridges(&m);
        if bridges.is_empty() {
            break;
        }
        m = split_edges(&m, &bridges)?;
        report.bridges_split += bridges.len();
        origin.resize(m.num_vertices(), None);
    }
    Ok(m)
}

/// Makes a disk-topology mesh out of a surface with the explicit operations of this module, in
/// this order: drop unreferenced vertices, keep the largest component, drop faces with a
/// repeated vertex, make the orientation consistent, repair zero-area faces without moving a
/// vertex ([`repair_degenerate_faces`]: edge flips, boundary-face removals, collapses of
/// coincident vertices), cut a disk out of a closed surface ([`cut_disk`] at `options.cut_center`), fill
/// every boundary loop but the longest ([`fill_holes_except_longest`]), check the result with
/// [`topology::require_disk`], optionally cut it open along a seam from its extremities to the
/// boundary (`options.seam_extremities`, [`crate::seam`]), and, when edges joining two boundary
/// vertices cut the interior into pieces ([`interior_components`]), split those edges
/// ([`boundary_bridges`], [`split_edges`]).
///
/// Returns the mesh, the map from its vertices to the input's (`None` for vertices added by hole
/// filling or edge splits; a copy made by the seam cut maps to the input vertex it copies, so
/// seam vertices appear more than once; the others keep their relative order) and what was
/// done. Errors: an
/// invalid mesh, a degenerate face that no flip, removal or collapse repairs (named by input
/// vertices), a non-orientable or non-manifold surface, a cut centre out of range or removed
/// by an earlier step, or a result that is still not a disk (e.g. a closed surface of genus ≥ 1,
/// which a disk cut leaves with handles: the error names the genus), or one without an interior
/// vertex (a seam through every vertex).
pub fn prepare_disk(
    mesh: &TriMesh,
    options: &PrepareOptions,
) -> Result<(TriMesh, Vec<Option<u32>>, PrepareReport), GeometryError> {
    let mut report = PrepareReport::default();
    // new→input index for the current mesh
    let mut origin: Vec<Option<u32>> = (0..mesh.num_vertices() as u32).map(Some).collect();
    let follow = |origin: &[Option<u32>], map: &VertexMap, new_len: usize| -> Vec<Option<u32>> {
        let mut out = vec![None; new_len];
        for (old, new) in map.iter().enumerate() {
            if let Some(n) = new {
                out[*n as usize] = origin[old];
            }
        }
        out
    };
    let (m, map) = drop_unreferenced_vertices(mesh)?;
    report.unreferenced_dropped = mesh.num_vertices() - m.num_vertices();
    origin = follow(&origin, &map, m.num_vertices());
    let faces_before = m.num_faces();
    let (m, map) = keep_largest_component(&m)?;
    report.faces_of_other_components_dropped = faces_before - m.num_faces();
    origin = follow(&origin, &map, m.num_vertices());
    // Faces with a repeated corner have no area and join nothing: dropped. (They used to
    // surface later as "a hole needs at least 3 vertices".)
    let repeats = |t: &[u32; 3]| t[0] == t[1] || t[1] == t[2] || t[2] == t[0];
    let mut m = m;
    let before = m.num_faces();
    m.faces.retain(|t| !repeats(t));
    report.repeated_vertex_faces_dropped = before - m.num_faces();
    if report.repeated_vertex_faces_dropped > 0 {
        let (compact, map) = drop_unreferenced_vertices(&m)?;
        report.unreferenced_dropped += m.num_vertices() - compact.num_vertices();
        origin = follow(&origin, &map, compact.num_vertices());
        m = compact;
        if m.faces.is_empty() {
            return Err(GeometryError::Topology("every face repeats a vertex".into()));
        }
    }
    let input = |v: u32| origin[v as usize].map_or_else(|| format!("new {v}"), |o| o.to_string());
    let non_manifold = topology::non_manifold_edges(&Connectivity::of(&m));
    if let Some(e) = non_manifold.first() {
        return Err(GeometryError::Topology(format!(
            "{} non-manifold edges (more than two faces on one edge), e.g. between input vertices {} and {}: a disk cannot be made by cutting and filling alone",
            non_manifold.len(),
            input(e[0]),
            input(e[1])
        )));
    }
    let (m, info) = reorient(&m)?;
    report.faces_flipped = info.faces_flipped_for_consistency;
    report.closed_components_turned_outward = info.closed_components_turned_outward;
    // zero-area faces (the definition every command shares): flipped, removed or collapsed
    // without moving a vertex ([`crate::repair`])
    let repaired = repair_degenerate_faces(&m);
    if let Some(t) = repaired.remaining.first() {
        let reason = crate::predicates::degenerate_corners(
            m.positions[t[0] as usize],
            m.positions[t[1] as usize],
            m.positions[t[2] as usize],
        )
        .unwrap_or("degenerate");
        return Err(GeometryError::Topology(format!(
            "{} that no edge flip, boundary-face removal or edge collapse repairs, first on input vertices ({}, {}, {}): {reason}",
            if repaired.remaining.len() == 1 {
                "1 degenerate face".to_string()
            } else {
                format!("{} degenerate faces", repaired.remaining.len())
            },
            input(t[0]),
            input(t[1]),
            input(t[2])
        )));
    }
    report.degenerate_faces_repaired = repaired.repair;
    origin = follow(&origin, &repaired.vertex_map, repaired.mesh.num_vertices());
    let mut m = repaired.mesh;
    let conn = Connectivity::of(&m);
    if conn.boundary_loops(&m.faces).is_empty() {
        let center = cut_center_vertex(options.cut_center, mesh.num_vertices(), &m, &origin)?;
        report.cut_center = origin[center as usize];
        let faces_before = m.num_faces();
        let (cut, map) = cut_disk(&m, center, options.cut_radius)?;
        report.faces_cut = faces_before - cut.num_faces();
        origin = follow(&origin, &map, cut.num_vertices());
        m = cut;
    } else if conn.boundary_loops(&m.faces).len() > 1 {
        let (filled, info) = fill_holes_except_longest(&m)?;
        report.holes_filled = info.holes_filled;
        origin.resize(filled.num_vertices(), None);
        m = filled;
    }
    topology::require_disk(&m)?;
    if options.seam_extremities > 0 {
        if let Some(slit) = crate::seam::slit_from_extremities(&m, options.seam_extremities)? {
            let (cut, copies) = (slit.mesh, slit.copies);
            report.seam_extremities = slit.extremities.iter().map(|&t| origin[t as usize]).collect();
            report.seam_edges = slit.seam_edges;
            report.seam_vertices_added = cut.num_vertices() - m.num_vertices();
            origin = copies.iter().map(|&v| origin[v as usize]).collect();
            m = cut;
        }
    }
    // a disk whose interior falls apart at edges joining two boundary vertices
    m = split_bridges(m, &mut report, &mut origin)?;
    if interior_components(&m).1 == 0 {
        let (after, advice) = if report.seam_edges > 0 {
            (", after the seam cut", "use fewer seam extremities or a finer mesh")
        } else {
            ("", "use a finer mesh")
        };
        return Err(GeometryError::Topology(format!(
            "the prepared disk has no interior vertex (all {} vertices lie on its boundary{after}); \
             a disk map needs one: {advice}",
            m.num_vertices()
        )));
    }
    Ok((m, origin, report))
}
