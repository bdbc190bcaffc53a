//! Mesh topology: connected components, Euler characteristic, boundary loops, genus,
//! manifoldness, orientation, degenerate and duplicate elements, and the disk / sphere
//! classification used before a conformal map.
//!
//! For a compact orientable surface with `b` boundary loops and genus `g`,
//! $$ \chi = V - E + F = 2 - 2g - b, $$
//! so a disk has χ = 1, b = 1 and a sphere χ = 2, b = 0 (e.g. Botsch et al., *Polygon Mesh
//! Processing*, 2010, §1.3). Here V counts only the vertices referenced by a face, E the
//! distinct undirected vertex pairs of the faces and F all faces.
//!
//! Definitions used throughout:
//! - **component**: a maximal set of faces connected through shared edges (two faces touching
//!   only at a vertex are separate components). Unreferenced vertices are counted separately.
//! - **non-manifold edge**: an edge with more than two incident faces.
//! - **non-manifold vertex**: a vertex whose incident faces form more than one *fan*, two faces
//!   being in the same fan when they are linked by a chain of manifold edges (exactly two faces)
//!   through the vertex. The tip of a bowtie and the endpoints of a non-manifold edge are such
//!   vertices.
//! - **inconsistent orientation**: an edge with exactly two faces that traverse it in the same
//!   direction (a consistently oriented surface uses every interior edge once in each direction).
//! - **degenerate face**: a repeated vertex index, or zero area (exact zero of |(b−a)×(c−a)|).
//! - **duplicate vertices**: vertices with bitwise equal positions (−0.0 = 0.0), found by hashing.
//!
//! The building blocks (`face_components`, `non_manifold_vertices`, ...) expect a valid mesh
//! (indices in range, as from the readers or [`TriMesh::new`]) and the [`Connectivity`] of that
//! mesh; [`mesh_report`], [`classify`] and [`require_disk`] validate first.

use std::collections::HashMap;

use serde::{Deserialize, Serialize};

use crate::connectivity::Connectivity;
use crate::error::GeometryError;
use crate::mesh::TriMesh;
use crate::quantities::face_areas;
use crate::vec3::{cross, max_abs, norm2, scale, sub};

/// How many offending elements a [`MeshReport`] lists (the counts are always complete).
pub const MAX_LISTED: usize = 10;

/// The topological class of a mesh, as needed by the conformal map.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum MeshClass {
    /// One component, edge- and vertex-manifold, consistently oriented, one boundary loop, χ = 1.
    Disk,
    /// One component, manifold, consistently oriented, closed (no boundary), χ = 2.
    Sphere,
    /// Anything else; see [`Classification::reasons`].
    Other,
}

impl std::fmt::Display for MeshClass {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(match self {
            MeshClass::Disk => "disk",
            MeshClass::Sphere => "sphere",
            MeshClass::Other => "other",
        })
    }
}

/// A class and, for [`MeshClass::Other`], human-readable reasons why it is neither a disk nor
/// a sphere (empty for a disk or a sphere).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct Classification {
    pub class: MeshClass,
    pub reasons: Vec<String>,
}

/// Topology of one connected component (faces connected through edges).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct ComponentReport {
    /// Number of faces.
    pub faces: usize,
    /// Number of vertices referenced by these faces.
    pub vertices: usize,
    /// Number of distinct undirected edges of these faces.
    pub edges: usize,
    /// Number of boundary loops of this component.
    pub boundary_loops: usize,
    /// χ = V − E + F of the component.
    pub euler_characteristic: i64,
    /// g = (2 − χ − b)/2; a half-integer or negative value means the component is not an
    /// orientable manifold surface.
    pub genus: f64,
}

/// Everything `shapespace info` reports about a mesh. Counts are complete; lists hold the first
/// [`MAX_LISTED`] offending elements in index order.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct MeshReport {
    /// #V as stored (including unreferenced vertices).
    pub num_vertices: usize,
    /// Vertices referenced by at least one face.
    pub num_referenced_vertices: usize,
    /// Vertices referenced by no face (isolated points).
    pub num_unreferenced_vertices: usize,
    pub first_unreferenced_vertices: Vec<u32>,
    /// #F.
    pub num_faces: usize,
    /// #E, distinct undirected edges.
    pub num_edges: usize,
    /// Number of connected components (faces through edges).
    pub num_components: usize,
    /// The components, largest (by face count) first, at most [`MAX_LISTED`].
    pub components: Vec<ComponentReport>,
    /// Number of boundary loops ([`Connectivity::boundary_loops`]).
    pub num_boundary_loops: usize,
    /// Vertex counts of the boundary loops, longest first, at most [`MAX_LISTED`].
    pub boundary_loop_lengths: Vec<usize>,
    /// χ = V − E + F over referenced vertices.
    pub euler_characteristic: i64,
    /// Σ over components of (2 − χ_c − b_c)/2.
    pub genus: f64,
    pub num_non_manifold_edges: usize,
    pub first_non_manifold_edges: Vec<[u32; 2]>,
    pub num_non_manifold_vertices: usize,
    pub first_non_manifold_vertices: Vec<u32>,
    /// No non-manifold edge and no non-manifold vertex.
    pub manifold: bool,
    /// Edges with two faces traversing them in the same direction.
    pub num_inconsistent_edges: usize,
    pub first_inconsistent_edges: Vec<[u32; 2]>,
    /// Every edge with two faces is used once in each direction.
    pub consistently_oriented: bool,
    /// Faces can be flipped to make the orientation consistent (false for a Möbius strip).
    pub orientable: bool,
    /// Faces with a repeated index or zero area.
    pub num_degenerate_faces: usize,
    pub first_degenerate_faces: Vec<u32>,
    /// Vertices whose position equals that of a vertex with a smaller index.
    pub num_duplicate_vertices: usize,
    /// Pairs (first occurrence, duplicate).
    pub first_duplicate_vertices: Vec<[u32; 2]>,
    /// No boundary edge.
    pub closed: bool,
    /// Total surface area Σ_f A_f.
    pub area: f64,
    /// Axis-aligned bounding box of the referenced vertices, [min, max] (zeros if none).
    pub bounding_box: [[f64; 3]; 2],
    /// The disk / sphere / other class.
    pub classification: Classification,
}

/// Per-vertex flag: referenced by at least one face, #V.
pub fn referenced_vertices(mesh: &TriMesh) -> Vec<bool> {
    let mut used = vec![false; mesh.num_vertices()];
    for face in &mesh.faces {
        for &v in face {
            if let Some(u) = used.get_mut(v as usize) {
                *u = true;
            }
        }
    }
    used
}

/// Vertices referenced by no face, in increasing order.
pub fn unreferenced_vertices(mesh: &TriMesh) -> Vec<u32> {
    referenced_vertices(mesh)
        .iter()
        .enumerate()
        .filter(|(_, &u)| !u)
        .map(|(i, _)| i as u32)
        .collect()
}

/// Root of `x` in the union–find forest `parent` (path halving; a root is its own parent).
pub fn find(parent: &mut [u32], mut x: u32) -> u32 {
    while parent[x as usize] != x {
        let p = parent[x as usize];
        parent[x as usize] = parent[p as usize];
        x = p;
    }
    x
}

/// Joins the sets of `a` and `b` in the union–find forest `parent` (the root of `a`'s set is
/// attached to the root of `b`'s); false when they were one set already.
pub fn union(parent: &mut [u32], a: u32, b: u32) -> bool {
    let (ra, rb) = (find(parent, a), find(parent, b));
    if ra != rb {
        parent[ra as usize] = rb;
    }
    ra != rb
}

/// Connected components of the faces through shared edges (edges with any number of faces).
///
/// Returns (per-face component label, #F; number of components). Labels are numbered by their
/// smallest face index (the component of face 0 is 0).
pub fn face_components(conn: &Connectivity, num_faces: usize) -> (Vec<u32>, usize) {
    let mut parent: Vec<u32> = (0..num_faces as u32).collect();
    for ef in &conn.edge_faces {
        for w in ef.windows(2) {
            let a = find(&mut parent, w[0]);
            let b = find(&mut parent, w[1]);
            if a != b {
                let (lo, hi) = (a.min(b), a.max(b));
                parent[hi as usize] = lo;
            }
        }
    }
    let mut labels = vec![u32::MAX; num_faces];
    let mut root_label: HashMap<u32, u32> = HashMap::new();
    for (f, label) in labels.iter_mut().enumerate() {
        let r = find(&mut parent, f as u32);
        let next = root_label.len() as u32;
        *label = *root_label.entry(r).or_insert(next);
    }
    (labels, root_label.len())
}

/// Edges with more than two incident faces, as (min, max) vertex pairs in edge order.
pub fn non_manifold_edges(conn: &Connectivity) -> Vec<[u32; 2]> {
    conn.edges
        .iter()
        .zip(&conn.edge_faces)
        .filter(|(_, ef)| ef.len() > 2)
        .map(|(e, _)| *e)
        .collect()
}

/// Non-manifold vertices with their number of fans (> 1), in vertex order.
///
/// The faces around a vertex are grouped into fans joined through manifold edges (exactly two
/// faces) incident to the vertex; a manifold vertex has one fan (a full disk inside, a half
/// disk on the boundary).
pub fn non_manifold_vertices(mesh: &TriMesh, conn: &Connectivity) -> Vec<(u32, usize)> {
    let mut out = Vec::new();
    let mut local: Vec<u32> = Vec::new();
    for (v, vf) in conn.vertex_faces.iter().enumerate() {
        if vf.len() < 2 {
            continue;
        }
        // union-find over the positions in vf
        local.clear();
        local.extend(0..vf.len() as u32);
        // vf is sorted (faces are pushed in increasing order), so positions come by bisection
        let pos = |f: u32| vf.binary_search(&f).ok().map(|i| i as u32);
        for &f in vf {
            let face = mesh.faces[f as usize];
            for k in 0..3 {
                // edge opposite corner k joins corners k+1, k+2; it contains v if one of them is v
                let (a, b) = (face[(k + 1) % 3], face[(k + 2) % 3]);
                if (a != v as u32 && b != v as u32) || a == b {
                    continue;
                }
                let e = conn.face_edges[f as usize][k] as usize;
                let ef = &conn.edge_faces[e];
                if ef.len() == 2 {
                    let (Some(i), Some(j)) = (pos(ef[0]), pos(ef[1])) else {
                        continue;
                    };
                    let ri = find(&mut local, i);
                    let rj = find(&mut local, j);
                    if ri != rj {
                        local[ri.max(rj) as usize] = ri.min(rj);
                    }
                }
            }
        }
        let mut fans = 0;
        for i in 0..vf.len() as u32 {
            if find(&mut local, i) == i {
                fans += 1;
            }
        }
        if fans > 1 {
            out.push((v as u32, fans));
        }
    }
    out
}

/// The direction in which face `f` traverses its edge opposite corner `k`: (face[k+1], face[k+2]).
#[inline]
fn directed_edge(face: [u32; 3], k: usize) -> [u32; 2] {
    [face[(k + 1) % 3], face[(k + 2) % 3]]
}

/// For an edge `e` with two faces, whether they traverse it in the same direction.
fn same_direction(faces: &[[u32; 3]], conn: &Connectivity, e: usize) -> bool {
    let ef = &conn.edge_faces[e];
    let dir = |f: u32| {
        let k = conn.face_edges[f as usize]
            .iter()
            .position(|&x| x as usize == e)
            .unwrap_or(0);
        directed_edge(faces[f as usize], k)
    };
    dir(ef[0]) == dir(ef[1])
}

/// Edges with exactly two faces that traverse them in the same direction, as (min, max) pairs.
/// Empty for a consistently oriented mesh. Degenerate edges (a, a) are skipped.
pub fn inconsistent_edges(faces: &[[u32; 3]], conn: &Connectivity) -> Vec<[u32; 2]> {
    (0..conn.num_edges())
        .filter(|&e| {
            conn.edge_faces[e].len() == 2 && conn.edges[e][0] != conn.edges[e][1] && same_direction(faces, conn, e)
        })
        .map(|e| conn.edges[e])
        .collect()
}

/// Per-face flips that make the orientation consistent: flipping face f when `flips[f]` makes
/// every edge with exactly two faces used once in each direction. Found by breadth-first search
/// over faces through such edges; in each connected piece the orientation most of its faces
/// already have is kept (the fewer faces are flipped; on a tie, the first face's), so one face
/// wound the wrong way never mirrors the rest. Returns `Err` for a non-orientable surface (e.g.
/// a Möbius strip), with the edge at which the contradiction was found.
pub fn orientation_flips(faces: &[[u32; 3]], conn: &Connectivity) -> Result<Vec<bool>, [u32; 2]> {
    let nf = faces.len();
    let mut flip = vec![false; nf];
    let mut seen = vec![false; nf];
    let mut queue = std::collections::VecDeque::new();
    let mut piece = Vec::new();
    for start in 0..nf {
        if seen[start] {
            continue;
        }
        seen[start] = true;
        queue.push_back(start);
        piece.clear();
        while let Some(f) = queue.pop_front() {
            piece.push(f);
            for k in 0..3 {
                let e = conn.face_edges[f][k] as usize;
                let ef = &conn.edge_faces[e];
                if ef.len() != 2 || conn.edges[e][0] == conn.edges[e][1] {
                    continue;
                }
                let g = if ef[0] as usize == f { ef[1] } else { ef[0] } as usize;
                if g == f {
                    continue;
                }
                // after flips, f and g must traverse e in opposite directions
                let need = flip[f] ^ same_direction(faces, conn, e);
                if seen[g] {
                    if flip[g] != need {
                        return Err(conn.edges[e]);
                    }
                } else {
                    seen[g] = true;
                    flip[g] = need;
                    queue.push_back(g);
                }
            }
        }
        if 2 * piece.iter().filter(|&&f| flip[f]).count() > piece.len() {
            for &f in &piece {
                flip[f] = !flip[f];
            }
        }
    }
    Ok(flip)
}

/// Degenerate faces, face indices in order: a repeated vertex index, or corners that are
/// coincident, exactly collinear or collinear to rounding
/// ([`crate::predicates::degenerate_corners`], the definition the disk maps use too).
pub fn degenerate_faces(mesh: &TriMesh) -> Vec<u32> {
    (0..mesh.num_faces())
        .filter(|&f| degenerate_face(mesh, f).is_some())
        .map(|f| f as u32)
        .collect()
}

/// Why face `f` of `mesh` is degenerate, if it is ([`degenerate_faces`]).
pub fn degenerate_face(mesh: &TriMesh, f: usize) -> Option<&'static str> {
    let [a, b, c] = mesh.faces[f];
    if a == b || b == c || c == a {
        return Some("repeated vertex");
    }
    let [p, q, r] = mesh.face_positions(f);
    crate::predicates::degenerate_corners(p, q, r)
}

/// Vertices whose position is exactly equal (bitwise, with −0.0 = 0.0) to that of a vertex with
/// a smaller index, as pairs (first occurrence, duplicate) in order of the duplicate.
pub fn duplicate_vertices(mesh: &TriMesh) -> Vec<[u32; 2]> {
    let key = |p: [f64; 3]| p.map(|c| if c == 0.0 { 0u64 } else { c.to_bits() });
    let mut first: HashMap<[u64; 3], u32> = HashMap::with_capacity(mesh.num_vertices());
    let mut out = Vec::new();
    for (i, &p) in mesh.positions.iter().enumerate() {
        match first.entry(key(p)) {
            std::collections::hash_map::Entry::Occupied(o) => out.push([*o.get(), i as u32]),
            std::collections::hash_map::Entry::Vacant(v) => {
                v.insert(i as u32);
            }
        }
    }
    out
}

/// χ = V − E + F over referenced vertices (see the module docs).
pub fn euler_characteristic(mesh: &TriMesh, conn: &Connectivity) -> i64 {
    let v = referenced_vertices(mesh).iter().filter(|&&u| u).count() as i64;
    v - conn.num_edges() as i64 + mesh.num_faces() as i64
}

fn first<T: Clone>(v: &[T]) -> Vec<T> {
    v.iter().take(MAX_LISTED).cloned().collect()
}

/// Computes the full [`MeshReport`] of a mesh in O(V + F log F). Errors only on an invalid
/// mesh (index out of range or non-finite coordinate, [`TriMesh::validate`]).
pub fn mesh_report(mesh: &TriMesh) -> Result<MeshReport, GeometryError> {
    mesh.validate()?;
    let conn = Connectivity::of(mesh);
    let nf = mesh.num_faces();
    let referenced = referenced_vertices(mesh);
    let unreferenced: Vec<u32> = referenced
        .iter()
        .enumerate()
        .filter(|(_, &u)| !u)
        .map(|(i, _)| i as u32)
        .collect();
    let num_referenced = mesh.num_vertices() - unreferenced.len();

    let (labels, num_components) = face_components(&conn, nf);
    let loops = conn.boundary_loops(&mesh.faces);

    // per-component counts
    let mut comp_faces = vec![0usize; num_components];
    let mut comp_edges = vec![0usize; num_components];
    let mut comp_loops = vec![0usize; num_components];
    let mut comp_vertices = vec![0usize; num_components];
    for &l in &labels {
        comp_faces[l as usize] += 1;
    }
    for ef in &conn.edge_faces {
        comp_edges[labels[ef[0] as usize] as usize] += 1;
    }
    for vf in &conn.vertex_faces {
        let mut comps: Vec<u32> = vf.iter().map(|&f| labels[f as usize]).collect();
        comps.sort_unstable();
        comps.dedup();
        for c in comps {
            comp_vertices[c as usize] += 1;
        }
    }
    if !loops.is_empty() {
        // component of a loop: the face of its first boundary edge
        let mut edge_index: HashMap<[u32; 2], usize> = HashMap::with_capacity(conn.num_edges());
        for (e, &key) in conn.edges.iter().enumerate() {
            edge_index.insert(key, e);
        }
        for lp in &loops {
            let (a, b) = (lp[0], lp[1 % lp.len()]);
            if let Some(&e) = edge_index.get(&[a.min(b), a.max(b)]) {
                comp_loops[labels[conn.edge_faces[e][0] as usize] as usize] += 1;
            }
        }
    }
    let mut components: Vec<ComponentReport> = (0..num_components)
        .map(|c| {
            let chi = comp_vertices[c] as i64 - comp_edges[c] as i64 + comp_faces[c] as i64;
            ComponentReport {
                faces: comp_faces[c],
                vertices: comp_vertices[c],
                edges: comp_edges[c],
                boundary_loops: comp_loops[c],
                euler_characteristic: chi,
                genus: (2 - chi - comp_loops[c] as i64) as f64 / 2.0,
            }
        })
        .collect();
    let genus = components.iter().map(|c| c.genus).sum();
    components.sort_by_key(|c| std::cmp::Reverse(c.faces));
    components.truncate(MAX_LISTED);

    let nm_edges = non_manifold_edges(&conn);
    let nm_vertices = non_manifold_vertices(mesh, &conn);
    let inconsistent = inconsistent_edges(&mesh.faces, &conn);
    let orientable = inconsistent.is_empty() || orientation_flips(&mesh.faces, &conn).is_ok();
    let degenerate = degenerate_faces(mesh);
    let duplicates = duplicate_vertices(mesh);
    let closed = conn.edge_faces.iter().all(|ef| ef.len() != 1);
    let mut area: f64 = face_areas(mesh).iter().sum();
    if !area.is_finite() {
        // Coordinates near f64::MAX: the cross products overflow (inf − inf = NaN). Per
        // triangle, the half edges h = (b − a)/2 (computed as b/2 − a/2: never overflows) are
        // scaled to their largest component m, and so is the cross product c of the scaled
        // edges before its length is taken, so nothing under- or overflows on the way; the area
        // ½|2h₁ × 2h₂| = 2 |c| m₁ m₂ is multiplied from the smallest factor up, so it is inf
        // only when the true area exceeds f64 (and 0 for collinear corners, never NaN).
        area = (0..nf)
            .map(|f| {
                let [a, b, c] = mesh.face_positions(f).map(|p| scale(p, 0.5));
                let (h1, h2) = (sub(b, a), sub(c, a));
                let (m1, m2) = (max_abs(h1), max_abs(h2));
                if !(m1 > 0.0 && m2 > 0.0) {
                    return 0.0;
                }
                let n = cross(h1.map(|x| x / m1), h2.map(|x| x / m2));
                let mn = max_abs(n);
                if !(mn > 0.0) {
                    return 0.0;
                }
                let length = mn * norm2(n.map(|x| x / mn)).sqrt();
                2.0 * length * m1.min(m2) * m1.max(m2)
            })
            .sum();
    }

    let mut bbox = [[f64::INFINITY; 3], [f64::NEG_INFINITY; 3]];
    for (p, _) in mesh.positions.iter().zip(&referenced).filter(|(_, &u)| u) {
        for d in 0..3 {
            bbox[0][d] = bbox[0][d].min(p[d]);
            bbox[1][d] = bbox[1][d].max(p[d]);
        }
    }
    if num_referenced == 0 {
        bbox = [[0.0; 3]; 2];
    }

    let mut report = MeshReport {
        num_vertices: mesh.num_vertices(),
        num_referenced_vertices: num_referenced,
        num_unreferenced_vertices: unreferenced.len(),
        first_unreferenced_vertices: first(&unreferenced),
        num_faces: nf,
        num_edges: conn.num_edges(),
        num_components,
        components,
        num_boundary_loops: loops.len(),
        boundary_loop_lengths: loops.iter().take(MAX_LISTED).map(|l| l.len()).collect(),
        euler_characteristic: num_referenced as i64 - conn.num_edges() as i64 + nf as i64,
        genus,
        num_non_manifold_edges: nm_edges.len(),
        first_non_manifold_edges: first(&nm_edges),
        num_non_manifold_vertices: nm_vertices.len(),
        first_non_manifold_vertices: nm_vertices.iter().take(MAX_LISTED).map(|x| x.0).collect(),
        manifold: nm_edges.is_empty() && nm_vertices.is_empty(),
        num_inconsistent_edges: inconsistent.len(),
        first_inconsistent_edges: first(&inconsistent),
        consistently_oriented: inconsistent.is_empty(),
        orientable,
        num_degenerate_faces: degenerate.len(),
        first_degenerate_faces: first(&degenerate),
        num_duplicate_vertices: duplicates.len(),
        first_duplicate_vertices: first(&duplicates),
        closed,
        area,
        bounding_box: bbox,
        classification: Classification {
            class: MeshClass::Other,
            reasons: Vec::new(),
        },
    };
    report.classification = classify_report(&report);
    Ok(report)
}

fn plural(n: usize, one: &str, many: &str) -> String {
    format!("{n} {}", if n == 1 { one } else { many })
}

/// Classifies a mesh from its report (see [`classify`]).
pub fn classify_report(r: &MeshReport) -> Classification {
    let mut common = Vec::new();
    if r.num_faces == 0 {
        return Classification {
            class: MeshClass::Other,
            reasons: vec!["no faces".into()],
        };
    }
    if r.num_components != 1 {
        common.push(format!(
            "{} components (faces connected through edges; a disk or sphere has 1)",
            r.num_components
        ));
    }
    if r.num_non_manifold_edges > 0 {
        let e = r.first_non_manifold_edges[0];
        common.push(format!(
            "{}, first ({}, {})",
            plural(r.num_non_manifold_edges, "non-manifold edge", "non-manifold edges"),
            e[0],
            e[1]
        ));
    }
    if r.num_non_manifold_vertices > 0 {
        common.push(format!(
            "{}, first {}",
            plural(
                r.num_non_manifold_vertices,
                "non-manifold vertex",
                "non-manifold vertices"
            ),
            r.first_non_manifold_vertices[0]
        ));
    }
    if !r.orientable {
        common.push("not orientable (like a Möbius strip)".into());
    } else if r.num_inconsistent_edges > 0 {
        let e = r.first_inconsistent_edges[0];
        common.push(format!(
            "inconsistent orientation at {}, first ({}, {})",
            plural(r.num_inconsistent_edges, "edge", "edges"),
            e[0],
            e[1]
        ));
    }
    let chi = r.euler_characteristic;
    let b = r.num_boundary_loops;
    if common.is_empty() {
        if b == 1 && chi == 1 {
            return Classification {
                class: MeshClass::Disk,
                reasons: Vec::new(),
            };
        }
        if b == 0 && chi == 2 {
            return Classification {
                class: MeshClass::Sphere,
                reasons: Vec::new(),
            };
        }
    }
    let mut reasons = common;
    if b == 0 {
        if chi != 2 {
            reasons.push(format!(
                "closed with χ = {chi} (a sphere needs χ = 2; genus {})",
                r.genus
            ));
        }
    } else {
        if b != 1 {
            reasons.push(format!(
                "{} (a disk needs 1)",
                plural(b, "boundary loop", "boundary loops")
            ));
        }
        if chi != 1 {
            reasons.push(format!("χ = {chi} (a disk needs χ = 1)"));
        }
    }
    if reasons.is_empty() {
        // cannot happen for consistent counts, but never return Other without a reason
        reasons.push(format!("χ = {chi} with {b} boundary loops"));
    }
    Classification {
        class: MeshClass::Other,
        reasons,
    }
}

/// Classifies a mesh as a topological disk, a sphere, or other (with human-readable reasons).
///
/// Disk: 1 component, edge- and vertex-manifold, consistently oriented, exactly 1 boundary
/// loop, χ = 1. Sphere: 1 component, manifold, consistently oriented, closed, χ = 2.
/// Unreferenced vertices, duplicate positions and degenerate faces do not change the class
/// (they are in the [`MeshReport`]; [`require_disk`] rejects the first and last).
///
/// Errors only on an invalid mesh ([`TriMesh::validate`]).
pub fn classify(mesh: &TriMesh) -> Result<Classification, GeometryError> {
    Ok(mesh_report(mesh)?.classification)
}

/// The range of coordinates the disk maps work in: the cotangent weights and face areas go
/// through the squared norm of an edge cross product, of the order of (edge length)⁴, which
/// overflows f64 for edges of about 1e77 and underflows to 0 below about 1e-77 (measured:
/// geometry-central's `cat_head.obj` (shared datasets), of size ~1, maps when scaled by 1e-76 … 1e76 and fails at
/// 1e±80 with a singular Laplacian or "degenerate faces"). The accepted range,
/// coordinates up to [`MAX_COORDINATE`] and a mesh extent above [`MIN_EXTENT`], keeps a margin of
/// 1e25 on both sides (edges down to 1e-25 of the extent). An error that says so (and to
/// rescale), for the vertices referenced by faces; `info` reports the same error.
pub fn check_coordinate_range(mesh: &TriMesh) -> Result<(), GeometryError> {
    let mut lo = [f64::INFINITY; 3];
    let mut hi = [f64::NEG_INFINITY; 3];
    for f in &mesh.faces {
        for &v in f {
            if let Some(p) = mesh.positions.get(v as usize) {
                for d in 0..3 {
                    lo[d] = lo[d].min(p[d]);
                    hi[d] = hi[d].max(p[d]);
                }
            }
        }
    }
    if mesh.faces.is_empty() {
        return Ok(());
    }
    let extent = (0..3).fold(0.0f64, |m, d| m.max(hi[d] - lo[d]));
    let largest = lo.iter().chain(&hi).fold(0.0f64, |m, c| m.max(c.abs()));
    if largest > MAX_COORDINATE || (extent > 0.0 && extent < MIN_EXTENT) {
        return Err(GeometryError::Invalid(format!(
            "coordinates out of the usable range: the mesh spans {extent:e} with coordinates up to {largest:e} \
             (the maps need coordinates up to {MAX_COORDINATE:e} and a size above {MIN_EXTENT:e}); rescale the mesh"
        )));
    }
    Ok(())
}

/// Largest coordinate magnitude [`require_disk`] accepts ([`check_coordinate_range`]).
pub const MAX_COORDINATE: f64 = 1e50;
/// Smallest mesh extent [`require_disk`] accepts ([`check_coordinate_range`]).
pub const MIN_EXTENT: f64 = 1e-50;

/// Checks that a mesh is ready for a disk conformal map: a topological disk ([`classify`])
/// without unreferenced vertices and without degenerate faces. The error says what is wrong and
/// which `prepare` operation fixes it.
pub fn require_disk(mesh: &TriMesh) -> Result<(), GeometryError> {
    let r = mesh_report(mesh)?;
    let mut problems: Vec<String> = Vec::new();
    if r.num_faces == 0 {
        return Err(GeometryError::Topology("the mesh has no faces".into()));
    }
    check_coordinate_range(mesh)?;
    if r.classification.class == MeshClass::Sphere {
        problems.push(
            "closed surface (sphere): cut a disk first (`prepare::cut_disk`, or `shapespace prepare` on the command line; for bodies with limbs `shapespace prepare --seam 1`)".into(),
        );
    } else if r.classification.class == MeshClass::Other {
        if r.num_components > 1 {
            problems.push(format!(
                "{} components: keep one (`prepare::keep_largest_component`, or `shapespace prepare`)",
                r.num_components
            ));
        }
        if r.num_non_manifold_edges > 0 || r.num_non_manifold_vertices > 0 {
            let mut what = Vec::new();
            if let Some(e) = r.first_non_manifold_edges.first() {
                what.push(format!(
                    "{}, first ({}, {})",
                    plural(r.num_non_manifold_edges, "non-manifold edge", "non-manifold edges"),
                    e[0],
                    e[1]
                ));
            }
            if let Some(v) = r.first_non_manifold_vertices.first() {
                what.push(format!(
                    "{}, first {}",
                    plural(
                        r.num_non_manifold_vertices,
                        "non-manifold vertex",
                        "non-manifold vertices"
                    ),
                    v
                ));
            }
            problems.push(format!("{}: repair the mesh in a mesh editor", what.join(" and ")));
        }
        if !r.orientable {
            problems.push("not orientable (like a Möbius strip): no conformal disk map exists".into());
        } else if r.num_inconsistent_edges > 0 {
            problems.push(format!(
                "inconsistent face orientation at {}: fix it with `prepare::reorient` (or `shapespace prepare`)",
                plural(r.num_inconsistent_edges, "edge", "edges")
            ));
        }
        let chi = r.euler_characteristic;
        let b = r.num_boundary_loops;
        if r.num_components == 1 && r.manifold {
            if b == 0 {
                problems.push(format!(
                    "closed surface with χ = {chi} (genus {}): only genus-0 surfaces map to a disk; \
                     cut it into a disk in a mesh editor",
                    r.genus
                ));
            } else if b > 1 {
                let g = r.genus;
                if g == 0.0 {
                    problems.push(format!(
                        "{b} boundary loops: fill the inner holes with `prepare::fill_holes_except_longest` (or `shapespace prepare`)"
                    ));
                } else {
                    problems.push(format!(
                        "{b} boundary loops and genus {g} (χ = {chi}): fill the inner holes with \
                         `prepare::fill_holes_except_longest`, and the handles need cutting in a mesh editor"
                    ));
                }
            } else if chi != 1 {
                problems.push(format!(
                    "one boundary loop but χ = {chi} (genus {}): handles need cutting in a mesh editor",
                    r.genus
                ));
            }
        }
        if problems.is_empty() {
            problems.extend(r.classification.reasons.iter().cloned());
        }
    }
    if r.num_unreferenced_vertices > 0 {
        problems.push(format!(
            "{}, first {}: remove them with `prepare::drop_unreferenced_vertices` (or `shapespace prepare`)",
            plural(
                r.num_unreferenced_vertices,
                "unreferenced vertex",
                "unreferenced vertices"
            ),
            r.first_unreferenced_vertices[0]
        ));
    }
    if r.num_degenerate_faces > 0 {
        problems.push(format!(
            "{} (repeated vertex or zero area), first face {}: `shapespace prepare` repairs them (`prepare::prepare_disk`)",
            plural(r.num_degenerate_faces, "degenerate face", "degenerate faces"),
            r.first_degenerate_faces[0]
        ));
    }
    if problems.is_empty() {
        Ok(())
    } else {
        Err(GeometryError::Topology(format!("not a disk: {}", problems.join("; "))))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn tetra() -> TriMesh {
        TriMesh::new(
            vec![[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]],
            vec![[0, 2, 1], [0, 1, 3], [0, 3, 2], [1, 2, 3]],
        )
        .unwrap()
    }

    #[test]
    fn tetrahedron_is_sphere() {
        let r = mesh_report(&tetra()).unwrap();
        assert_eq!((r.num_edges, r.euler_characteristic, r.num_boundary_loops), (6, 2, 0));
        assert_eq!(r.classification.class, MeshClass::Sphere);
        assert!(r.closed && r.manifold && r.consistently_oriented);
        assert_eq!(r.genus, 0.0);
        assert!(require_disk(&tetra()).unwrap_err().to_string().contains("cut_disk"));
    }

    #[test]
    fn tetrahedron_minus_face_is_disk() {
        let mut m = tetra();
        m.faces.pop();
        let r = mesh_report(&m).unwrap();
        assert_eq!(r.classification.class, MeshClass::Disk, "{:?}", r.classification);
        assert_eq!(r.boundary_loop_lengths, vec![3]);
        require_disk(&m).unwrap();
    }

    #[test]
    fn duplicates_and_unreferenced() {
        let mut m = tetra();
        m.positions.push([1.0, 0.0, 0.0]);
        m.positions.push([-0.0, 0.0, 0.0]);
        let r = mesh_report(&m).unwrap();
        assert_eq!(r.first_duplicate_vertices, vec![[1, 4], [0, 5]]);
        assert_eq!(r.first_unreferenced_vertices, vec![4, 5]);
        assert_eq!(r.classification.class, MeshClass::Sphere);
    }
}
