//! Local untangling of a vertex map T: S₁ → S₂ in 3D: fewer source triangles whose straight
//! image triangle (T(a), T(b), T(c)) faces away from the target surface.
//!
//! A source face t = (a, b, c) is **flipped** under T when its image normal
//! $$ n_t = (x_{T(b)} - x_{T(a)}) \times (x_{T(c)} - x_{T(a)}) $$
//! has a negative dot product with the target's normal there: if (T(a), T(b), T(c)) is a face
//! of S₂, that face's own orientation decides (so the identity map has no flips, even at
//! creases where a face's normal points away from its corners' averaged normals); otherwise the
//! reference is the sum of the area-weighted vertex normals of S₂ at the three image vertices
//! (no disk map needed; on an image triangle inside a small patch of S₂ this is the sign the
//! registration metric's face normal gives). An image with two equal corners has n_t = 0: a
//! **collapse**, not a flip. On thin parts (legs, ears, tails) a source vertex whose spectral
//! nearest neighbour lands on the far side of the part spans straight triangles through the
//! inside of the part, which face away.
//!
//! An image that is neither flipped nor a face of S₂ and has two corners more than one edge apart
//! is **spread**: the registration metric locates such a triangle's centroid through the disk
//! map φ₂, and for corners a few edges apart on a crowded limb that point can land on an
//! unrelated part of S₂ whose normal decides the sign (measured on centaur0 → centaur1: 1,340
//! of the 1,741 faces the metric counted as flipped were spread images this test called fine).
//!
//! The pass: while some face is flipped or (with `compact`) spread, at most `sweeps` times:
//! 1. every vertex of such a face in turn (Gauss–Seidel, in index order) moves to the candidate
//!    w minimizing, in this order, the local score Σ over its faces (2 flipped, 1 collapsed,
//!    1 spread with `compact`, else 0), then `cost(v, w)` (for ZoomOut, the distance in the
//!    spectral embedding; the current image is kept on ties). Candidates: the target vertices
//!    within `ring` edges of T(v), and the images T(u) of v's source neighbours with their
//!    target neighbours;
//! 2. both ends of every edge of a face still flipped or spread move jointly, to the best pair
//!    of candidates (one ring around their images and the neighbours' images), when that lowers
//!    the score of the faces around them (a fold that no single move undoes).
//!
//! A move never raises the total score and lowers it or the total cost, so the pass cannot cycle.
//! A vertex (a face, for the pair moves) is evaluated again only after it or a source neighbour
//! moved: its outcome depends on nothing else.
//! Measured with `register_bench` (ZoomOut, OMT first stage) on the six ordered pairs per class:
//! wolf flipped 3D area 0.79 % → 0.11 % (max 0.29 %) and mean geodesic error 0.0031 → 0.0021;
//! centaur 5.2 % → 1.6 % (max 2.0 %) and 0.0135 → 0.0120 (`docs/registration.md`). Without
//! `compact` (flipped faces only) the wolf kept 0.32 % and 0.0031.
//!
//! The vertex pass converges to a local minimum that keeps 0.09–2.5 % of the area flipped
//! (class means; up to 3.1 % on a pair): scattered images whose corners lie more than one edge
//! apart, where the map contracts or stretches at the scale of an edge and no triple of target
//! vertices is a good image (decision 0034). [`untangle_points`] then moves the vertices of the
//! faces still flipped to points inside the target's faces, against the registration metric's
//! own test, by single moves and, where they leave at least 0.4 % of the area flipped, region
//! moves (decisions 0042, 0054): 0.03–0.33 % (class means; at most 0.40 % on a pair of the five
//! bench classes) at the same geodesic error within 2.5 %. With
//! [`PointUntangleParams::smooth_rounds`] it ends with projected smoothing (decision 0064).
//! The metric's test locates in the target's disk image φ₂ or, for the sphere route, in its
//! sphere image ψ₂ ([`TargetImage`]).

use std::cell::Cell;

use shapespace_conformal::markers::closest_point_barycentric;
use shapespace_geometry::quantities::{face_areas, vertex_normals};

use crate::point_location::{barycentric, PointLocator};
use crate::registration::at_surface_point;
use crate::registration::sphere::SphereLocator;
use crate::registration::truth::SurfacePoint;
use shapespace_geometry::{Connectivity, TriMesh};

/// Parameters of [`untangle_vertex_map`].
#[derive(Clone, Debug, PartialEq)]
pub struct VertexMapUntangleParams {
    /// Sweeps over the vertices of flipped faces (default 8; 0 turns the pass off).
    pub sweeps: usize,
    /// Rings of target vertices around the current image that are candidates (default 2).
    pub ring: usize,
    /// Also move the vertices of spread images (corners more than one edge apart, not flipped)
    /// and count those images like collapses in the local score.
    pub compact: bool,
    /// Also move both ends of an edge of a face still flipped jointly (step 2 of the module
    /// docs).
    pub pair_moves: bool,
}

impl Default for VertexMapUntangleParams {
    fn default() -> Self {
        VertexMapUntangleParams {
            sweeps: 8,
            ring: 2,
            compact: true,
            pair_moves: true,
        }
    }
}

/// What [`untangle_vertex_map`] did.
#[derive(Clone, Debug, Default, PartialEq, serde::Serialize)]
pub struct VertexMapUntangleInfo {
    /// Flipped source faces before and after.
    pub flipped_before: usize,
    pub flipped_after: usize,
    /// Collapsed source faces (two image corners equal) before and after.
    pub collapsed_before: usize,
    pub collapsed_after: usize,
    /// Source vertices whose image changed.
    pub vertices_moved: usize,
    /// Sweeps run.
    pub sweeps: usize,
    /// Flipped faces after the sweeps, before the region moves.
    pub flipped_after_sweeps: usize,
    /// Region moves kept.
    pub regions_moved: usize,
    /// Wall-clock seconds.
    pub seconds: f64,
}

/// Orientation of one image triangle: 1 flipped, 0 fine, and collapsed separately.
#[derive(Clone, Copy, PartialEq, Eq)]
enum Image {
    Fine,
    /// Not flipped, not a face of S₂, and two corners more than one edge apart.
    Spread,
    Flipped,
    Collapsed,
}

struct Geometry<'a> {
    target: &'a TriMesh,
    normals: Vec<[f64; 3]>,
    vertex_faces: Vec<Vec<u32>>,
    neighbors: Vec<Vec<u32>>,
    /// Count spread images in the local score ([`VertexMapUntangleParams::compact`]).
    compact: bool,
}

impl<'a> Geometry<'a> {
    fn of(target: &'a TriMesh, compact: bool) -> Self {
        let conn = Connectivity::of(target);
        Geometry {
            target,
            normals: vertex_normals(target),
            neighbors: conn.vertex_neighbors(target.num_vertices()),
            vertex_faces: conn.vertex_faces,
            compact,
        }
    }

    /// Local score of one image: 2 flipped, 1 collapsed (or spread when compacting), 0 fine.
    fn score(&self, w: [u32; 3]) -> usize {
        match self.classify(w) {
            Image::Flipped => 2,
            Image::Collapsed => 1,
            Image::Spread => usize::from(self.compact),
            Image::Fine => 0,
        }
    }

    /// Whether an image makes its vertices candidates for moving.
    fn bad(&self, w: [u32; 3]) -> bool {
        match self.classify(w) {
            Image::Flipped => true,
            Image::Spread => self.compact,
            _ => false,
        }
    }

    fn classify(&self, w: [u32; 3]) -> Image {
        if w[0] == w[1] || w[1] == w[2] || w[0] == w[2] {
            return Image::Collapsed;
        }
        // a face of S₂ (either orientation): its own orientation decides
        for &f in &self.vertex_faces[w[0] as usize] {
            let t = self.target.faces[f as usize];
            if t.contains(&w[1]) && t.contains(&w[2]) {
                let k = t.iter().position(|&x| x == w[0]).unwrap_or(0);
                return if t[(k + 1) % 3] == w[1] {
                    Image::Fine
                } else {
                    Image::Flipped
                };
            }
        }
        let p = |i: usize| self.target.positions[w[i] as usize];
        let (a, b, c) = (p(0), p(1), p(2));
        let e1 = [b[0] - a[0], b[1] - a[1], b[2] - a[2]];
        let e2 = [c[0] - a[0], c[1] - a[1], c[2] - a[2]];
        let n = [
            e1[1] * e2[2] - e1[2] * e2[1],
            e1[2] * e2[0] - e1[0] * e2[2],
            e1[0] * e2[1] - e1[1] * e2[0],
        ];
        let mut r = [0.0; 3];
        for &x in &w {
            let m = self.normals[x as usize];
            for d in 0..3 {
                r[d] += m[d];
            }
        }
        if n[0] * r[0] + n[1] * r[1] + n[2] * r[2] < 0.0 {
            Image::Flipped
        } else if (0..3).all(|i| self.neighbors[w[i] as usize].contains(&w[(i + 1) % 3])) {
            Image::Fine
        } else {
            Image::Spread
        }
    }
}

/// Flipped and collapsed faces of `source` under the vertex map `map` (module docs).
pub fn count_flipped_images(source: &TriMesh, target: &TriMesh, map: &[u32]) -> (usize, usize) {
    count(source, &Geometry::of(target, false), map)
}

fn count(source: &TriMesh, g: &Geometry<'_>, map: &[u32]) -> (usize, usize) {
    let (mut flipped, mut collapsed) = (0, 0);
    for f in &source.faces {
        match g.classify(f.map(|v| map[v as usize])) {
            Image::Flipped => flipped += 1,
            Image::Collapsed => collapsed += 1,
            Image::Fine | Image::Spread => {}
        }
    }
    (flipped, collapsed)
}

/// Untangles the vertex map `map` (#V₁ target vertices, changed in place) of `source` onto
/// `target` (module docs); `cost(v, w)` ranks candidates w for source vertex v with the same
/// local orientation count. Both meshes consistently oriented; `map` entries in range.
pub fn untangle_vertex_map(
    source: &TriMesh,
    target: &TriMesh,
    map: &mut [u32],
    cost: &(dyn Fn(usize, u32) -> f64 + Sync),
    params: &VertexMapUntangleParams,
) -> VertexMapUntangleInfo {
    let t0 = std::time::Instant::now();
    let g = Geometry::of(target, params.compact);
    let (flipped_before, collapsed_before) = count(source, &g, map);
    let mut info = VertexMapUntangleInfo {
        flipped_before,
        flipped_after: flipped_before,
        collapsed_before,
        collapsed_after: collapsed_before,
        ..VertexMapUntangleInfo::default()
    };
    if flipped_before == 0 || params.sweeps == 0 {
        return info;
    }
    let original: Vec<u32> = map.to_vec();
    let mut sweeper = MoveSweeper::new(source, target, &g, cost, params);
    for sweep in 0..params.sweeps {
        let flipped_faces: Vec<usize> = (0..source.num_faces())
            .filter(|&f| g.bad(source.faces[f].map(|v| map[v as usize])))
            .collect();
        if flipped_faces.is_empty() {
            break;
        }
        info.sweeps = sweep + 1;
        let mut bad = vec![false; source.num_vertices()];
        for &f in &flipped_faces {
            for &v in &source.faces[f] {
                bad[v as usize] = true;
            }
        }
        let mut changed = sweeper.single_moves(map, &bad);
        // pair moves: both ends of an edge of a face still flipped, jointly (a fold that no
        // single vertex undoes)
        for &f in flipped_faces.iter().filter(|_| params.pair_moves) {
            changed |= sweeper.pair_moves(map, f);
        }
        if !changed {
            break;
        }
    }
    let (flipped_after, collapsed_after) = count(source, &g, map);
    info.flipped_after = flipped_after;
    info.collapsed_after = collapsed_after;
    info.vertices_moved = map.iter().zip(&original).filter(|(a, b)| a != b).count();
    info.seconds = t0.elapsed().as_secs_f64();
    info
}

/// The state of [`untangle_vertex_map`]'s sweeps: both meshes' adjacency, the candidate
/// bookkeeping and the clocks that skip evaluations whose outcome cannot have changed.
struct MoveSweeper<'a> {
    source: &'a TriMesh,
    g: &'a Geometry<'a>,
    cost: &'a (dyn Fn(usize, u32) -> f64 + Sync),
    params: &'a VertexMapUntangleParams,
    source_conn: Connectivity,
    source_neighbors: Vec<Vec<u32>>,
    target_neighbors: Vec<Vec<u32>>,
    /// Per target vertex, the stamp of the candidate list it was last pushed to.
    seen: Vec<usize>,
    stamp: usize,
    /// A move's outcome depends only on the images of the moved vertices and their source
    /// neighbours: `changed_at[v]` is the clock of the last move of v or a neighbour, and a
    /// vertex (`single_at`; a face, `pair_at`, for the pair moves) evaluated after that is not
    /// evaluated again (the same result, less work).
    clock: usize,
    changed_at: Vec<usize>,
    single_at: Vec<usize>,
    pair_at: Vec<usize>,
}

impl<'a> MoveSweeper<'a> {
    fn new(
        source: &'a TriMesh,
        target: &TriMesh,
        g: &'a Geometry<'a>,
        cost: &'a (dyn Fn(usize, u32) -> f64 + Sync),
        params: &'a VertexMapUntangleParams,
    ) -> Self {
        let n1 = source.num_vertices();
        let n2 = target.num_vertices();
        let source_conn = Connectivity::of(source);
        let source_neighbors = source_conn.vertex_neighbors(n1);
        let target_neighbors = Connectivity::of(target).vertex_neighbors(n2);
        MoveSweeper {
            source,
            g,
            cost,
            params,
            source_conn,
            source_neighbors,
            target_neighbors,
            seen: vec![usize::MAX; n2],
            stamp: 0,
            clock: 1,
            changed_at: vec![1usize; n1],
            single_at: vec![0usize; n1],
            pair_at: vec![0usize; source.num_faces()],
        }
    }

    /// Local score of v at w: 2 · flipped + collapsed over v's faces.
    fn local(&self, map: &[u32], v: usize, w: u32) -> usize {
        self.source_conn.vertex_faces[v]
            .iter()
            .map(|&f| {
                let face = self.source.faces[f as usize];
                self.g
                    .score(face.map(|u| if u as usize == v { w } else { map[u as usize] }))
            })
            .sum()
    }

    /// Candidates for v: the target vertices within `ring` edges of T(v), then the images of v's
    /// source neighbours (with their target neighbours when `neighbour_rings`); T(v) first.
    fn candidates(&mut self, map: &[u32], v: usize, ring: usize, neighbour_rings: bool) -> Vec<u32> {
        self.stamp += 1;
        let stamp = self.stamp;
        let seen = &mut self.seen;
        let mut out = Vec::new();
        let mut push = |w: u32, out: &mut Vec<u32>| {
            if seen[w as usize] != stamp {
                seen[w as usize] = stamp;
                out.push(w);
            }
        };
        push(map[v], &mut out);
        let mut frontier = 0;
        for _ in 0..ring {
            let end = out.len();
            for i in frontier..end {
                for &u in &self.target_neighbors[out[i] as usize] {
                    push(u, &mut out);
                }
            }
            frontier = end;
        }
        for &u in &self.source_neighbors[v] {
            let w = map[u as usize];
            push(w, &mut out);
            if neighbour_rings {
                for &x in &self.target_neighbors[w as usize] {
                    push(x, &mut out);
                }
            }
        }
        out
    }

    /// Records a move of v: the clock ticks and v and its source neighbours are marked changed.
    fn touch(&mut self, v: usize) {
        self.clock += 1;
        self.changed_at[v] = self.clock;
        for &u in &self.source_neighbors[v] {
            self.changed_at[u as usize] = self.clock;
        }
    }

    /// Single moves: each vertex of a bad image (`bad`) to its best candidate (lowest local
    /// score, then lowest cost); whether any moved.
    fn single_moves(&mut self, map: &mut [u32], bad: &[bool]) -> bool {
        let mut changed = false;
        for v in (0..bad.len()).filter(|&v| bad[v]) {
            if self.single_at[v] > self.changed_at[v] {
                continue;
            }
            self.clock += 1;
            self.single_at[v] = self.clock;
            let candidates = self.candidates(map, v, self.params.ring, true);
            let current = map[v];
            let mut best = (self.local(map, v, current), (self.cost)(v, current), current);
            for &w in &candidates[1..] {
                let s = self.local(map, v, w);
                if s > best.0 {
                    continue;
                }
                let c = (self.cost)(v, w);
                if s < best.0 || c < best.1 {
                    best = (s, c, w);
                }
            }
            if best.2 != current {
                changed = true;
                map[v] = best.2;
                self.touch(v);
            }
        }
        changed
    }

    /// Pair moves on source face f if its image is still bad: both ends of each edge jointly,
    /// over their one-ring candidates; whether any moved.
    fn pair_moves(&mut self, map: &mut [u32], f: usize) -> bool {
        let face = self.source.faces[f];
        if !self.g.bad(face.map(|v| map[v as usize]))
            || face.iter().all(|&v| self.pair_at[f] > self.changed_at[v as usize])
        {
            return false;
        }
        self.clock += 1;
        self.pair_at[f] = self.clock;
        let mut changed = false;
        for k in 0..3 {
            let (v, u) = (face[k] as usize, face[(k + 1) % 3] as usize);
            changed |= self.pair_move(map, v, u);
        }
        changed
    }

    /// The joint move of the edge (v, u): the best pair of candidates by the score over both
    /// one-rings, then the summed cost; whether it moved. The score splits into the faces of v
    /// alone, those of u alone (each scored once per candidate) and the faces of the edge.
    fn pair_move(&mut self, map: &mut [u32], v: usize, u: usize) -> bool {
        let vertex_faces = &self.source_conn.vertex_faces;
        let (source, g) = (self.source, self.g);
        let has = |t: u32, x: usize| source.faces[t as usize].contains(&(x as u32));
        let v_only: Vec<u32> = vertex_faces[v].iter().copied().filter(|&t| !has(t, u)).collect();
        let u_only: Vec<u32> = vertex_faces[u].iter().copied().filter(|&t| !has(t, v)).collect();
        let edge: Vec<u32> = vertex_faces[v].iter().copied().filter(|&t| has(t, u)).collect();
        let image = |map: &[u32], t: u32, wv: u32, wu: u32| {
            source.faces[t as usize].map(|x| {
                if x as usize == v {
                    wv
                } else if x as usize == u {
                    wu
                } else {
                    map[x as usize]
                }
            })
        };
        let alone = |map: &[u32], faces: &[u32], wv: u32, wu: u32| -> usize {
            faces.iter().map(|&t| g.score(image(map, t, wv, wu))).sum()
        };
        let cv = self.candidates(map, v, 1, false);
        let cu = self.candidates(map, u, 1, false);
        let cost = self.cost;
        let (mv, mu) = (map[v], map[u]);
        let sv: Vec<usize> = cv.iter().map(|&wv| alone(map, &v_only, wv, mu)).collect();
        let su: Vec<usize> = cu.iter().map(|&wu| alone(map, &u_only, mv, wu)).collect();
        let joint = |map: &[u32], wv: u32, wu: u32| {
            alone(map, &v_only, wv, mu) + alone(map, &u_only, mv, wu) + alone(map, &edge, wv, wu)
        };
        let mut best = (joint(map, mv, mu), cost(v, mv) + cost(u, mu), mv, mu);
        for (&wv, &sv) in cv.iter().zip(&sv) {
            for (&wu, &su) in cu.iter().zip(&su) {
                let s = sv + su + alone(map, &edge, wv, wu);
                if s > best.0 {
                    continue;
                }
                let c = cost(v, wv) + cost(u, wu);
                if s < best.0 || c < best.1 {
                    best = (s, c, wv, wu);
                }
            }
        }
        if (best.2, best.3) != (mv, mu) {
            map[v] = best.2;
            map[u] = best.3;
            self.touch(v);
            self.touch(u);
            true
        } else {
            false
        }
    }
}

/// Parameters of [`untangle_points`].
#[derive(Clone, Debug, PartialEq)]
pub struct PointUntangleParams {
    /// Gauss–Seidel sweeps over the vertices of flipped images (default 12; 0 turns it off).
    pub sweeps: usize,
    /// Largest ring of source neighbours the region moves add around a connected set of faces
    /// still flipped after the sweeps (default 3; 0 turns the region moves off).
    pub region_rings: usize,
    /// Rounds of region moves, each over the sets still flipped (default 3; 0 turns them off).
    pub region_rounds: usize,
    /// The region moves run only when the faces still flipped after the sweeps cover at least
    /// this share of the source's area (default 0.004; decision 0054): below it the sweeps'
    /// result is kept as it is, since a region laid out again can also move its images away
    /// from where the spectral map put them (0 runs them wherever a face is still flipped).
    pub region_from_area: f64,
    /// Sweeps of projected smoothing after the untangling ([`untangle_points`]; default 0:
    /// none). The refinement overwrites it ([`crate::registration::ZoomOutParams::point_pass`]:
    /// [`crate::registration::ZoomOutParams::smoothing`] for projected output, 0 otherwise).
    pub smooth_rounds: usize,
}

impl Default for PointUntangleParams {
    fn default() -> Self {
        PointUntangleParams {
            sweeps: 12,
            region_rings: 3,
            region_rounds: 3,
            region_from_area: REGION_FROM_AREA,
            smooth_rounds: 0,
        }
    }
}

/// Default [`PointUntangleParams::region_from_area`].
pub const REGION_FROM_AREA: f64 = 0.004;

/// What [`untangle_points`] did.
#[derive(Clone, Debug, Default, PartialEq, serde::Serialize)]
pub struct PointUntangleInfo {
    /// Source faces flipped by the registration metric's 3D test before and after.
    pub flipped_before: usize,
    pub flipped_after: usize,
    /// Source vertices moved off their vertex image.
    pub vertices_moved: usize,
    /// Sweeps run.
    pub sweeps: usize,
    /// Flipped faces after the sweeps, before the region moves, and their share of the
    /// source's area.
    pub flipped_after_sweeps: usize,
    pub flipped_area_after_sweeps: f64,
    /// Region moves kept.
    pub regions_moved: usize,
    /// Moves of the projected smoothing after the untangling.
    pub smoothing_moves: usize,
    /// Wall-clock seconds.
    pub seconds: f64,
}

/// Whether the triangle's area is zero relative to its edges (a collapse, or a corner on the
/// opposite edge).
fn degenerate(x: [[f64; 3]; 3]) -> bool {
    let (e1, e2) = (sub3(x[1], x[0]), sub3(x[2], x[0]));
    let n = cross3(e1, e2);
    let nn = n[0] * n[0] + n[1] * n[1] + n[2] * n[2];
    let ee = (e1[0] * e1[0] + e1[1] * e1[1] + e1[2] * e1[2]).max(e2[0] * e2[0] + e2[1] * e2[1] + e2[2] * e2[2]);
    nn <= 1e-18 * ee * ee
}

/// Gauss–Seidel sweeps of a region move's mean-value layout (regions span at most a few rings).
const LAYOUT_SWEEPS: usize = 400;

/// Single-move sweeps over a region's interior after its layout.
const REGION_SWEEPS: usize = 6;

/// Weight of a flipped image against a degenerate one in the point pass's local score (more
/// than the faces around any vertex, so flips decide first).
const DEGENERATE_LIMIT: usize = 1 << 16;

/// Most faces a walk from the `near` faces crosses before the flip test asks the point locator.
const WALK_STEPS: usize = 32;

/// Smallest barycentric coordinate of a point that only its face holds, whatever the rounding
/// of the neighbours' coordinates (the flip test's walk from a hint stops there).
const INSIDE: f64 = 1e-9;

/// The image of S₂ in which the registration metric locates the face whose normal decides an
/// image triangle's 3D flip: the disk image φ₂ ([`DiskDomain`]) or the sphere image ψ₂
/// ([`SphereDomain`]).
trait TargetDomain {
    /// A point of the image.
    type P: Copy;
    /// The image of the point of S₂ in face `f` at barycentric coordinates `b`.
    fn at(&self, target: &TriMesh, f: u32, b: [f64; 3]) -> Self::P;
    /// The metric's mean of an image triangle's corners (normalized on the sphere).
    fn mean(&self, points: &[Self::P]) -> Self::P;
    /// The mean of a vertex's neighbours' images (a candidate of the single moves).
    fn neighbour_mean(&self, points: &[Self::P]) -> Self::P;
    /// Barycentric coordinates of `c` in the image of face `f` (None when degenerate).
    fn bary(&self, target: &TriMesh, f: u32, c: Self::P) -> Option<[f64; 3]>;
    /// The face whose image holds `c` and the coordinates there (the point locator's).
    fn locate(&self, c: Self::P) -> Option<(u32, [f64; 3])>;
}

/// φ₂: the target's disk image, points located by [`PointLocator`].
struct DiskDomain<'a> {
    uv: &'a [[f64; 2]],
    locator: PointLocator,
}

impl TargetDomain for DiskDomain<'_> {
    type P = [f64; 2];
    fn at(&self, target: &TriMesh, f: u32, b: [f64; 3]) -> [f64; 2] {
        let t = target.faces[f as usize];
        std::array::from_fn(|d| (0..3).map(|k| b[k] * self.uv[t[k] as usize][d]).sum())
    }
    fn mean(&self, points: &[[f64; 2]]) -> [f64; 2] {
        let n = points.len() as f64;
        std::array::from_fn(|d| points.iter().map(|p| p[d]).sum::<f64>() / n)
    }
    fn neighbour_mean(&self, points: &[[f64; 2]]) -> [f64; 2] {
        let n = points.len() as f64;
        std::array::from_fn(|d| points.iter().map(|p| p[d] / n).sum::<f64>())
    }
    fn bary(&self, target: &TriMesh, f: u32, c: [f64; 2]) -> Option<[f64; 3]> {
        let t = target.faces[f as usize].map(|w| self.uv[w as usize]);
        barycentric(c, t[0], t[1], t[2])
    }
    fn locate(&self, c: [f64; 2]) -> Option<(u32, [f64; 3])> {
        self.locator.locate(c).map(|l| (l.face, l.bary))
    }
}

/// ψ₂: the target's sphere image (unit vectors), points of S² located by
/// [`SphereLocator`]; a point of a face's image is the ray through the barycentric
/// combination of its corners, as the sphere route's composition and metric take it.
struct SphereDomain<'a> {
    sphere: &'a [[f64; 3]],
    locator: SphereLocator,
}

fn normalized(x: [f64; 3]) -> [f64; 3] {
    let n = norm3(x);
    if n > 0.0 {
        x.map(|c| c / n)
    } else {
        x
    }
}

impl TargetDomain for SphereDomain<'_> {
    type P = [f64; 3];
    fn at(&self, target: &TriMesh, f: u32, b: [f64; 3]) -> [f64; 3] {
        normalized(at_surface_point(&target.faces, self.sphere, (f, b)))
    }
    fn mean(&self, points: &[[f64; 3]]) -> [f64; 3] {
        normalized(std::array::from_fn(|d| points.iter().map(|p| p[d]).sum()))
    }
    fn neighbour_mean(&self, points: &[[f64; 3]]) -> [f64; 3] {
        self.mean(points)
    }
    /// The ray barycentric coordinates, as the sphere locator (and so the metric) takes them
    /// (`SphereLocator::coordinates`: folded faces of ψ₂ included); None on the far side of
    /// the sphere or for a degenerate face.
    fn bary(&self, _target: &TriMesh, f: u32, c: [f64; 3]) -> Option<[f64; 3]> {
        self.locator.coordinates(c, f).map(|(b, _)| b)
    }
    fn locate(&self, c: [f64; 3]) -> Option<(u32, [f64; 3])> {
        self.locator.locate(c).map(|l| (l.face, l.bary))
    }
}

struct MetricFlipTest<'a, D: TargetDomain> {
    domain: D,
    target: &'a TriMesh,
    /// Per face of S₂, the face across the edge opposite each corner (`u32::MAX` on the
    /// boundary or at a non-manifold edge).
    across: Vec<[u32; 3]>,
}

impl<'a, D: TargetDomain> MetricFlipTest<'a, D> {
    fn new(target: &'a TriMesh, domain: D) -> Self {
        let conn = Connectivity::of(target);
        let across = (0..target.num_faces())
            .map(|f| {
                conn.face_edges[f].map(|e| match conn.edge_faces[e as usize].as_slice() {
                    &[a, b] => {
                        if a as usize == f {
                            b
                        } else {
                            a
                        }
                    }
                    _ => u32::MAX,
                })
            })
            .collect();
        MetricFlipTest { domain, target, across }
    }

    fn bary(&self, f: u32, c: D::P) -> Option<[f64; 3]> {
        self.domain.bary(self.target, f, c)
    }

    /// A face of S₂ whose image in the metric's domain holds `c` (barycentric coordinates all
    /// ≥ 0). First a walk
    /// from `hint` ([`MetricFlipTest::walk`]) that only ends on a face holding `c` with every
    /// coordinate above [`INSIDE`], the only face that does. Otherwise (no hint, a walk that
    /// ends on or near an edge, or stops): the first of `near` that holds `c`, else the end of a
    /// walk from the nearest of them (the one of largest smallest coordinate); else the point
    /// locator's.
    fn face_holding(&self, c: D::P, hint: Option<u32>, near: &[u32]) -> Option<u32> {
        let from_hint = hint.and_then(|f| self.bary(f, c).map(|b| (f, b)));
        if let Some(f) = self.walk(c, from_hint, |m| m > INSIDE) {
            return Some(f);
        }
        let mut start: Option<(f64, u32, [f64; 3])> = None;
        for &f in near {
            if let Some(b) = self.bary(f, c) {
                let m = b[0].min(b[1]).min(b[2]);
                if m >= 0.0 {
                    return Some(f);
                }
                if start.is_none_or(|(sm, _, _)| m > sm) {
                    start = Some((m, f, b));
                }
            }
        }
        self.walk(c, start.map(|(_, f, b)| (f, b)), |m| m >= 0.0)
            .or_else(|| self.domain.locate(c).map(|l| l.0))
    }

    /// A walk towards `c` from a face and its barycentric coordinates, across the edge of the
    /// most negative coordinate, at most [`WALK_STEPS`] faces: the first face whose smallest
    /// coordinate m is `accept`ed; None when it reaches a face holding `c` (m ≥ 0) that it does
    /// not accept, leaves S₂, or stops.
    fn walk(&self, c: D::P, start: Option<(u32, [f64; 3])>, accept: impl Fn(f64) -> bool) -> Option<u32> {
        let mut walk = start;
        for _ in 0..WALK_STEPS {
            let (f, b) = walk?;
            let k = (0..3).fold(0, |a, i| if b[i] < b[a] { i } else { a });
            if accept(b[k]) {
                return Some(f);
            }
            if b[k] >= 0.0 {
                return None;
            }
            let next = self.across[f as usize][k];
            walk = (next != u32::MAX)
                .then(|| self.bary(next, c).map(|b| (next, b)))
                .flatten();
        }
        None
    }

    /// Whether the straight triangle (x[0], x[1], x[2]) faces away from the normal of the face
    /// of S₂ holding the mean of the image points u.
    /// `hint` (a face of S₂ near the mean: the face that held it last time, or one holding a
    /// corner's image; set to the face found) and `near` (faces of S₂ to try next): where
    /// [`MetricFlipTest::face_holding`] starts.
    fn flipped(&self, x: [[f64; 3]; 3], u: [D::P; 3], hint: &Cell<u32>, near: &[u32]) -> bool {
        let n = cross3(sub3(x[1], x[0]), sub3(x[2], x[0]));
        let c = self.domain.mean(&u);
        let start = Some(hint.get()).filter(|&f| f != u32::MAX);
        let Some(face) = self.face_holding(c, start, near) else {
            return false;
        };
        hint.set(face);
        let q = self.target.face_positions(face as usize);
        let r = cross3(sub3(q[1], q[0]), sub3(q[2], q[0]));
        n[0] * r[0] + n[1] * r[1] + n[2] * r[2] < 0.0
    }
}

fn norm3(a: [f64; 3]) -> f64 {
    (a[0] * a[0] + a[1] * a[1] + a[2] * a[2]).sqrt()
}
fn sub3(a: [f64; 3], b: [f64; 3]) -> [f64; 3] {
    [a[0] - b[0], a[1] - b[1], a[2] - b[2]]
}
fn cross3(a: [f64; 3], b: [f64; 3]) -> [f64; 3] {
    [
        a[1] * b[2] - a[2] * b[1],
        a[2] * b[0] - a[0] * b[2],
        a[0] * b[1] - a[1] * b[0],
    ]
}

/// Untangles a vertex-to-point map of `source` onto `target` (`points`: per source vertex a face
/// of S₂ and barycentric coordinates, changed in place) against the 3D test of the registration
/// metric, with `image` the image of S₂ that test locates in (the disk image φ₂ or the sphere
/// image ψ₂, [`TargetImage`]): a source face is flipped when its straight image triangle faces
/// away from the normal of the face of S₂ holding the mean of its corners' images. Vertex maps cannot undo a flip where the map contracts
/// or stretches S₁ against S₂ at the scale of an edge (a source face then has no image among
/// target vertex triples that is neither flipped, collapsed nor spread); points inside the faces
/// can. Gauss–Seidel sweeps over the vertices of flipped faces, each moved to the candidate
/// point with the fewest flipped images around it, then the fewest degenerate ones (zero area:
/// a collapse, or a corner on the opposite edge), then nearest in 3D to its image before the
/// pass (the current point kept on ties). Candidates: on every face of S₂ around the target vertices
/// nearest to the vertex's and its source neighbours' images, the corners, the edge midpoints
/// and the centroid; the mean of the neighbours' images in `image`; once region moves run (their
/// cleaning sweeps), also the closest point of those faces to the 3D mean of the neighbours'
/// images. A move never raises the number
/// of flipped images around the moved vertex; a vertex is evaluated again only
/// after it or a source neighbour moved. Faces still flipped after the sweeps, where single moves
/// are stuck (every corner of the face off by several edges), get region moves
/// (`region_rounds` rounds) when they cover at least `region_from_area` of the source's area
/// (decision 0054): each connected set of them, grown by up to `region_rings` − 1 rings
/// of source neighbours, is laid out in space by Floater's mean-value weights of the source's
/// stars [Floater 2003] with the ring around it fixed, put on S₂ by closest points, cleaned by
/// single moves, and kept only when the flipped (then degenerate) images around it are fewer.
/// Last, with [`PointUntangleParams::smooth_rounds`] (also when nothing was flipped, or with
/// `sweeps` = 0), sweeps of projected smoothing (decision 0064).
/// Errors: `image` not #V₂ points (a disk image that is not a triangulation).
pub fn untangle_points(
    source: &TriMesh,
    target: &TriMesh,
    image: TargetImage<'_>,
    points: &mut [(u32, [f64; 3])],
    params: &PointUntangleParams,
) -> Result<PointUntangleInfo, crate::error::AnalysisError> {
    Ok(match image {
        TargetImage::Disk(uv) => {
            let domain = DiskDomain {
                uv,
                locator: PointLocator::new(uv, &target.faces)?,
            };
            untangle_points_in(source, target, domain, points, params)
        }
        TargetImage::Sphere(sphere) => {
            let domain = SphereDomain {
                sphere,
                locator: SphereLocator::new(sphere, &target.faces)?,
            };
            untangle_points_in(source, target, domain, points, params)
        }
    })
}

/// Where the registration metric's 3D test locates the face of S₂ whose normal is the
/// reference ([`untangle_points`]).
#[derive(Clone, Copy, Debug)]
pub enum TargetImage<'a> {
    /// The disk image φ₂ (#V₂ points of the plane): the face holding the mean of the corners'
    /// φ₂ images.
    Disk(&'a [[f64; 2]]),
    /// The sphere image ψ₂ (#V₂ unit vectors; closed surfaces registered through the sphere,
    /// `crate::registration::sphere`): the face holding the normalized mean of the corners'
    /// sphere images.
    Sphere(&'a [[f64; 3]]),
}

fn untangle_points_in<D: TargetDomain>(
    source: &TriMesh,
    target: &TriMesh,
    domain: D,
    points: &mut [(u32, [f64; 3])],
    params: &PointUntangleParams,
) -> PointUntangleInfo {
    let t0 = std::time::Instant::now();
    let n1 = source.num_vertices();
    let mut pass = PointPass::new(source, target, domain, points);
    let before = pass.flipped_faces(points);
    let mut info = PointUntangleInfo {
        flipped_before: before.len(),
        flipped_after: before.len(),
        ..PointUntangleInfo::default()
    };
    let untangle = !before.is_empty() && params.sweeps > 0;
    if !untangle && params.smooth_rounds == 0 {
        info.seconds = t0.elapsed().as_secs_f64();
        return info;
    }
    let sconn = Connectivity::of(source);
    let adjacency = PassAdjacency {
        snb: sconn.vertex_neighbors(n1),
        sconn,
        tconn: Connectivity::of(target),
    };
    let mut bad_faces = if untangle {
        pass.untangle(&adjacency, points, before, params, &mut info)
    } else {
        before
    };
    if params.smooth_rounds > 0 {
        info.smoothing_moves = pass.smooth(&adjacency, points, params.smooth_rounds);
        bad_faces = pass.flipped_faces(points);
    }
    info.flipped_after = bad_faces.len();
    info.vertices_moved = (0..n1).filter(|&v| pass.p3[v] != pass.original[v]).count();
    info.seconds = t0.elapsed().as_secs_f64();
    info
}

/// The source and target adjacency [`untangle_points`] moves vertices with.
struct PassAdjacency {
    sconn: Connectivity,
    /// Source vertex neighbours.
    snb: Vec<Vec<u32>>,
    tconn: Connectivity,
}

/// The images of [`untangle_points`]: per source vertex its point in 3D (`p3`) and in the
/// metric's image of S₂ (`p2`), the 3D points before the pass (`original`), and the metric's
/// flip test.
struct PointPass<'a, D: TargetDomain> {
    source: &'a TriMesh,
    target: &'a TriMesh,
    test: MetricFlipTest<'a, D>,
    p3: Vec<[f64; 3]>,
    p2: Vec<D::P>,
    original: Vec<[f64; 3]>,
    /// Whether the single moves try the closest point to the neighbours' 3D mean (with the
    /// region moves, decision 0042).
    mean3_candidate: bool,
    /// Per source face, the face of S₂ that held the disk mean of its images at its last flip
    /// test (`u32::MAX` before the first): where the next test's walk starts.
    holder: Vec<Cell<u32>>,
}

/// Candidate spots on every face of S₂ (barycentric): the corners, the edge midpoints and the
/// centroid.
const SPOTS: [[f64; 3]; 7] = [
    [1.0, 0.0, 0.0],
    [0.0, 1.0, 0.0],
    [0.0, 0.0, 1.0],
    [0.5, 0.5, 0.0],
    [0.0, 0.5, 0.5],
    [0.5, 0.0, 0.5],
    [1.0 / 3.0, 1.0 / 3.0, 1.0 / 3.0],
];

impl<'a, D: TargetDomain> PointPass<'a, D> {
    /// The flip test in `domain` and the images of `points`.
    fn new(source: &'a TriMesh, target: &'a TriMesh, domain: D, points: &[SurfacePoint]) -> Self {
        let test = MetricFlipTest::new(target, domain);
        let mut pass = PointPass {
            source,
            target,
            test,
            p3: Vec::new(),
            p2: Vec::new(),
            original: Vec::new(),
            mean3_candidate: false,
            holder: vec![Cell::new(u32::MAX); source.num_faces()],
        };
        pass.p3 = points.iter().map(|&p| pass.x3(p)).collect();
        pass.p2 = points.iter().map(|&p| pass.x2(p)).collect();
        pass.original = pass.p3.clone();
        pass
    }

    /// The 3D position of a point of S₂.
    fn x3(&self, p: SurfacePoint) -> [f64; 3] {
        at_surface_point(&self.target.faces, &self.target.positions, p)
    }

    /// The position of a point of S₂ in the metric's image of S₂.
    fn x2(&self, (f, b): SurfacePoint) -> D::P {
        self.test.domain.at(self.target, f, b)
    }

    /// Where the flip test of source face `f` starts: the face of S₂ that held its mean last
    /// time, else (its first test) `first`, a face holding one of its corners' images.
    fn holder(&self, f: usize, first: u32) -> &Cell<u32> {
        let hint = &self.holder[f];
        if hint.get() == u32::MAX {
            hint.set(first);
        }
        hint
    }

    /// Source faces whose current image (`points`, with `p3` and `p2`) the metric's 3D test
    /// finds flipped.
    fn flipped_faces(&self, points: &[SurfacePoint]) -> Vec<usize> {
        (0..self.source.num_faces())
            .filter(|&f| {
                let face = self.source.faces[f];
                let hint = self.holder(f, points[face[0] as usize].0);
                self.test.flipped(
                    face.map(|v| self.p3[v as usize]),
                    face.map(|v| self.p2[v as usize]),
                    hint,
                    &[],
                )
            })
            .collect()
    }

    /// Score of the source faces around v with v at the point `p` of S₂ (in 3D `x`, in the
    /// metric's image of S₂ `u`): DEGENERATE_LIMIT per flipped image, 1 per degenerate one; counting
    /// stops once above `cap`. The flip test starts from the face that held a face's mean last
    /// time (else p's face), then tries `faces`.
    fn around(
        &self,
        adjacency: &PassAdjacency,
        v: usize,
        faces: &[u32],
        (p, x, u): (SurfacePoint, [f64; 3], D::P),
        cap: usize,
    ) -> usize {
        let mut count = 0;
        for &f in &adjacency.sconn.vertex_faces[v] {
            let face = self.source.faces[f as usize];
            let xs = face.map(|w| if w as usize == v { x } else { self.p3[w as usize] });
            let us = face.map(|w| if w as usize == v { u } else { self.p2[w as usize] });
            if self.test.flipped(xs, us, self.holder(f as usize, p.0), faces) {
                count += DEGENERATE_LIMIT;
            } else if degenerate(xs) {
                count += 1;
            }
            if count > cap {
                break;
            }
        }
        count
    }

    /// The faces of S₂ around the target vertices nearest to the images of v and of its source
    /// neighbours (sorted, once each).
    fn faces_near(&self, adjacency: &PassAdjacency, points: &[SurfacePoint], v: usize) -> Vec<u32> {
        let nearest_corner = |(f, b): SurfacePoint| {
            let k = (0..3).fold(0, |a, i| if b[i] > b[a] { i } else { a });
            self.target.faces[f as usize][k]
        };
        let mut faces: Vec<u32> = std::iter::once(nearest_corner(points[v]))
            .chain(adjacency.snb[v].iter().map(|&u| nearest_corner(points[u as usize])))
            .flat_map(|w| adjacency.tconn.vertex_faces[w as usize].iter().copied())
            .collect();
        faces.sort_unstable();
        faces.dedup();
        faces
    }

    /// The best point for v (module docs of [`untangle_points`]): None when no image around v is
    /// flipped or degenerate, else the best candidate (`points[v]` itself when none is better).
    fn best_point(&self, adjacency: &PassAdjacency, points: &[SurfacePoint], v: usize) -> Option<SurfacePoint> {
        // flipped faces around v with v at (x, u)
        let faces = self.faces_near(adjacency, points, v);
        let current = self.around(adjacency, v, &faces, (points[v], self.p3[v], self.p2[v]), usize::MAX);
        if current == 0 {
            return None;
        }
        let dist = |x: [f64; 3]| {
            let d = sub3(x, self.original[v]);
            d[0] * d[0] + d[1] * d[1] + d[2] * d[2]
        };
        let mut best = (current, dist(self.p3[v]), points[v]);
        let consider = |cand: SurfacePoint, best: &mut (usize, f64, SurfacePoint)| {
            let (x, u) = (self.x3(cand), self.x2(cand));
            let s = self.around(adjacency, v, &faces, (cand, x, u), best.0);
            if s > best.0 {
                return;
            }
            let c = dist(x);
            if s < best.0 || c < best.1 {
                *best = (s, c, cand);
            }
        };
        // the mean of the neighbours' images in the metric's image of S₂
        let snb = &adjacency.snb;
        let images: Vec<D::P> = snb[v].iter().map(|&u| self.p2[u as usize]).collect();
        if !images.is_empty() {
            if let Some(l) = self.test.domain.locate(self.test.domain.neighbour_mean(&images)) {
                consider(l, &mut best);
            }
        }
        // the closest point to the 3D mean of the neighbours' images, on the faces near them
        if self.mean3_candidate {
            let mut mean3 = [0.0; 3];
            for &u in &snb[v] {
                for d in 0..3 {
                    mean3[d] += self.p3[u as usize][d] / snb[v].len() as f64;
                }
            }
            if let Some(closest) = self.closest_on_target(mean3, &faces) {
                consider(closest, &mut best);
            }
        }
        for cand in spots_on(self.target, &faces) {
            consider(cand, &mut best);
        }
        Some(best.2)
    }
}

impl<D: TargetDomain> PointPass<'_, D> {
    /// The closest point to `x` on the target faces `faces` (the first of equal distances);
    /// `None` when no face gives a finite distance.
    fn closest_on_target(&self, x: [f64; 3], faces: &[u32]) -> Option<SurfacePoint> {
        let mut closest: Option<(f64, SurfacePoint)> = None;
        for &f in faces {
            let q = self.target.face_positions(f as usize);
            let b = closest_point_barycentric(x, q[0], q[1], q[2]);
            let y: [f64; 3] = std::array::from_fn(|d| b[0] * q[0][d] + b[1] * q[1][d] + b[2] * q[2][d]);
            let d2 = sub3(y, x).iter().map(|c| c * c).sum::<f64>();
            if d2 < closest.map_or(f64::INFINITY, |c| c.0) {
                closest = Some((d2, (f, b)));
            }
        }
        closest.map(|c| c.1)
    }

    /// Score of the source faces in `faces` with the current images (`points`, with `p3` and
    /// `p2`): DEGENERATE_LIMIT per flipped image, 1 per degenerate one.
    fn score_faces(&self, points: &[SurfacePoint], faces: &[u32]) -> usize {
        faces
            .iter()
            .map(|&f| {
                let face = self.source.faces[f as usize];
                let xs = face.map(|w| self.p3[w as usize]);
                let hint = self.holder(f as usize, points[face[0] as usize].0);
                if self.test.flipped(xs, face.map(|w| self.p2[w as usize]), hint, &[]) {
                    DEGENERATE_LIMIT
                } else {
                    usize::from(degenerate(xs))
                }
            })
            .sum()
    }

    /// The faces of S₂ within `rings` rings of the nearest corners of the images of the
    /// corners of the source `faces` (sorted, once each).
    fn target_faces_near(
        &self,
        adjacency: &PassAdjacency,
        points: &[SurfacePoint],
        faces: &[u32],
        rings: usize,
    ) -> Vec<u32> {
        let mut verts: Vec<u32> = faces
            .iter()
            .flat_map(|&f| self.source.faces[f as usize])
            .map(|v| {
                let (f, b) = points[v as usize];
                let k = (0..3).fold(0, |a, i| if b[i] > b[a] { i } else { a });
                self.target.faces[f as usize][k]
            })
            .collect();
        verts.sort_unstable();
        verts.dedup();
        let mut out: Vec<u32> = Vec::new();
        for _ in 0..rings {
            out = verts
                .iter()
                .flat_map(|&w| adjacency.tconn.vertex_faces[w as usize].iter().copied())
                .collect();
            out.sort_unstable();
            out.dedup();
            verts = out.iter().flat_map(|&f| self.target.faces[f as usize]).collect();
            verts.sort_unstable();
            verts.dedup();
        }
        out
    }

    /// Floater's mean-value weights of source vertex v over its neighbours, from the 3D
    /// angles of its star: w_vu = (tan(α/2) + tan(β/2)) / |x_u − x_v| [Floater 2003, Eq. (5)].
    fn mean_value_weights(&self, adjacency: &PassAdjacency, v: usize) -> Vec<(u32, f64)> {
        let x = &self.source.positions;
        let mut w: Vec<(u32, f64)> = Vec::new();
        for &f in &adjacency.sconn.vertex_faces[v] {
            let t = self.source.faces[f as usize];
            let k = (0..3).position(|k| t[k] as usize == v).unwrap_or(0);
            let (a, b) = (t[(k + 1) % 3], t[(k + 2) % 3]);
            let (ea, eb) = (sub3(x[a as usize], x[v]), sub3(x[b as usize], x[v]));
            let (la, lb) = (norm3(ea), norm3(eb));
            if la == 0.0 || lb == 0.0 {
                continue;
            }
            let c = ((ea[0] * eb[0] + ea[1] * eb[1] + ea[2] * eb[2]) / (la * lb)).clamp(-1.0, 1.0);
            let half = (c.acos() / 2.0).tan();
            if !half.is_finite() {
                continue;
            }
            for (u, l) in [(a, la), (b, lb)] {
                match w.iter_mut().find(|e| e.0 == u) {
                    Some(e) => e.1 += half / l,
                    None => w.push((u, half / l)),
                }
            }
        }
        w
    }

    /// The single-move sweeps and, where they leave enough flipped, the region moves (the
    /// module docs of [`untangle_points`]) from the flipped faces `bad_faces`; the faces still
    /// flipped after them.
    fn untangle(
        &mut self,
        adjacency: &PassAdjacency,
        points: &mut [SurfacePoint],
        mut bad_faces: Vec<usize>,
        params: &PointUntangleParams,
        info: &mut PointUntangleInfo,
    ) -> Vec<usize> {
        let n1 = self.source.num_vertices();
        // a vertex is evaluated again only after it or a source neighbour moved (its result depends
        // on nothing else)
        let mut stale = vec![true; n1];
        while !bad_faces.is_empty() && info.sweeps < params.sweeps {
            info.sweeps += 1;
            let mut verts: Vec<usize> = bad_faces
                .iter()
                .flat_map(|&f| self.source.faces[f].map(|v| v as usize))
                .collect();
            verts.sort_unstable();
            verts.dedup();
            let mut moved = false;
            for v in verts {
                if !stale[v] {
                    continue;
                }
                stale[v] = false;
                let Some(best) = self.best_point(adjacency, points, v) else {
                    continue;
                };
                if best != points[v] {
                    points[v] = best;
                    self.p3[v] = self.x3(best);
                    self.p2[v] = self.x2(best);
                    moved = true;
                    stale[v] = true;
                    for &u in &adjacency.snb[v] {
                        stale[u as usize] = true;
                    }
                }
            }
            bad_faces = self.flipped_faces(points);
            if !moved {
                break;
            }
        }
        info.flipped_after_sweeps = bad_faces.len();
        let areas = face_areas(self.source);
        let flipped_area: f64 = bad_faces.iter().map(|&f| areas[f]).sum();
        info.flipped_area_after_sweeps = flipped_area / areas.iter().sum::<f64>();
        let regions = params.region_rings > 0
            && params.region_rounds > 0
            && !bad_faces.is_empty()
            && info.flipped_area_after_sweeps >= params.region_from_area;
        if regions {
            self.mean3_candidate = true;
            for _ in 0..params.region_rounds {
                let moved = self.region_moves(adjacency, points, &bad_faces, params.region_rings);
                info.regions_moved += moved;
                bad_faces = self.flipped_faces(points);
                if moved == 0 || bad_faces.is_empty() {
                    break;
                }
            }
        }
        bad_faces
    }

    /// Projected smoothing ([`PointUntangleParams::smooth_rounds`] Gauss–Seidel sweeps over the
    /// source's interior vertices): each image moves to the closest point, on the faces of S₂
    /// near it, to the combination of its source neighbours' images by Floater's mean-value
    /// weights of the source star, when that does not raise the score around the vertex
    /// (flipped, then degenerate images). Returns the number of moves.
    fn smooth(&mut self, adjacency: &PassAdjacency, points: &mut [SurfacePoint], rounds: usize) -> usize {
        let n1 = self.source.num_vertices();
        let on_cut = adjacency.sconn.boundary_vertices(n1);
        let weights: Vec<Vec<(u32, f64)>> = (0..n1).map(|v| self.mean_value_weights(adjacency, v)).collect();
        let mut moved = 0;
        for _ in 0..rounds {
            for v in 0..n1 {
                if on_cut[v] {
                    continue;
                }
                let w = &weights[v];
                let total: f64 = w.iter().map(|e| e.1).sum();
                if !(total > 0.0 && total.is_finite()) {
                    continue;
                }
                let mut m = [0.0; 3];
                for &(u, c) in w {
                    for d in 0..3 {
                        m[d] += c * self.p3[u as usize][d] / total;
                    }
                }
                let faces = self.faces_near(adjacency, points, v);
                let Some(cand) = self.closest_on_target(m, &faces) else {
                    continue;
                };
                let cur = self.around(adjacency, v, &faces, (points[v], self.p3[v], self.p2[v]), usize::MAX);
                let (x, u) = (self.x3(cand), self.x2(cand));
                let new = self.around(adjacency, v, &faces, (cand, x, u), cur);
                if new <= cur {
                    points[v] = cand;
                    self.p3[v] = x;
                    self.p2[v] = u;
                    moved += 1;
                }
            }
        }
        moved
    }

    /// Region moves (module docs of [`untangle_points`]): per connected set of the flipped
    /// `bad_faces` (sharing a vertex), the interior vertices (the set's vertices and r − 1 rings
    /// of source neighbours around them, cut vertices excluded) are laid out in space by
    /// Floater's mean-value weights of the source's 3D stars with the ring around them fixed at
    /// its images, each put at its closest point on the faces of S₂ within three rings of the
    /// region's images, and moved by [`REGION_SWEEPS`] single-move sweeps from there; the result
    /// is kept when the score of the source faces around the interior drops, else r grows up to
    /// `rings`. Returns the number of regions moved.
    fn region_moves(
        &mut self,
        adjacency: &PassAdjacency,
        points: &mut [SurfacePoint],
        bad_faces: &[usize],
        rings: usize,
    ) -> usize {
        let n1 = self.source.num_vertices();
        let on_cut = adjacency.sconn.boundary_vertices(n1);
        // connected sets of flipped faces through shared vertices (union–find on vertices)
        let mut parent: Vec<u32> = (0..n1 as u32).collect();
        fn find(parent: &mut [u32], mut v: u32) -> u32 {
            while parent[v as usize] != v {
                parent[v as usize] = parent[parent[v as usize] as usize];
                v = parent[v as usize];
            }
            v
        }
        for &f in bad_faces {
            let t = self.source.faces[f];
            for k in 1..3 {
                let (a, b) = (find(&mut parent, t[0]), find(&mut parent, t[k]));
                parent[a as usize] = b;
            }
        }
        let mut sets: std::collections::BTreeMap<u32, Vec<u32>> = std::collections::BTreeMap::new();
        for &f in bad_faces {
            for v in self.source.faces[f] {
                let r = find(&mut parent, v);
                sets.entry(r).or_default().push(v);
            }
        }
        let mut moved = 0;
        let mut mark = vec![0u32; n1];
        let mut stamp = 0u32;
        for set in sets.into_values() {
            for r in 1..=rings {
                stamp += 1;
                // interior: the set's vertices and r − 1 rings around them
                let mut interior: Vec<u32> = Vec::new();
                for &v in &set {
                    if mark[v as usize] != stamp {
                        mark[v as usize] = stamp;
                        interior.push(v);
                    }
                }
                let mut frontier = interior.clone();
                for _ in 1..r {
                    let mut next = Vec::new();
                    for &v in &frontier {
                        for &u in &adjacency.snb[v as usize] {
                            if mark[u as usize] != stamp {
                                mark[u as usize] = stamp;
                                next.push(u);
                            }
                        }
                    }
                    interior.extend_from_slice(&next);
                    frontier = next;
                }
                interior.retain(|&v| !on_cut[v as usize]);
                if interior.is_empty() {
                    break;
                }
                stamp += 1;
                for &v in &interior {
                    mark[v as usize] = stamp;
                }
                let mut faces: Vec<u32> = interior
                    .iter()
                    .flat_map(|&v| adjacency.sconn.vertex_faces[v as usize].iter().copied())
                    .collect();
                faces.sort_unstable();
                faces.dedup();
                let before = self.score_faces(points, &faces);
                let saved: Vec<([f64; 3], D::P, SurfacePoint)> = interior
                    .iter()
                    .map(|&v| (self.p3[v as usize], self.p2[v as usize], points[v as usize]))
                    .collect();
                // the interior in 3D by Floater's mean-value weights of the source's stars,
                // the ring fixed at its images (Gauss–Seidel from the current images)
                let weights: Vec<Vec<(u32, f64)>> = interior
                    .iter()
                    .map(|&v| self.mean_value_weights(adjacency, v as usize))
                    .collect();
                for _ in 0..LAYOUT_SWEEPS {
                    for (&v, w) in interior.iter().zip(&weights) {
                        let mut m = [0.0; 3];
                        let mut total = 0.0;
                        for &(u, c) in w {
                            for d in 0..3 {
                                m[d] += c * self.p3[u as usize][d];
                            }
                            total += c;
                        }
                        if total > 0.0 && total.is_finite() {
                            self.p3[v as usize] = m.map(|x| x / total);
                        }
                    }
                }
                // the closest points on the faces of S₂ within three rings of the nearest
                // corners of the region's current images
                let near = self.target_faces_near(adjacency, points, &faces, 3);
                for &v in &interior {
                    let p = self
                        .closest_on_target(self.p3[v as usize], &near)
                        .unwrap_or(points[v as usize]);
                    points[v as usize] = p;
                    self.p3[v as usize] = self.x3(p);
                    self.p2[v as usize] = self.x2(p);
                }
                // the single moves on the interior, from the smooth layout
                for _ in 0..REGION_SWEEPS {
                    let mut any = false;
                    for &v in &interior {
                        if let Some(best) = self.best_point(adjacency, points, v as usize) {
                            if best != points[v as usize] {
                                points[v as usize] = best;
                                self.p3[v as usize] = self.x3(best);
                                self.p2[v as usize] = self.x2(best);
                                any = true;
                            }
                        }
                    }
                    if !any {
                        break;
                    }
                }
                let after_score = self.score_faces(points, &faces);
                if after_score < before {
                    moved += 1;
                    break;
                }
                for (&v, &(x3, x2, p)) in interior.iter().zip(&saved) {
                    self.p3[v as usize] = x3;
                    self.p2[v as usize] = x2;
                    points[v as usize] = p;
                }
            }
        }
        moved
    }
}

/// The [`SPOTS`] of `faces` of `target`, each vertex, edge midpoint and centroid once (in the
/// order of their sorted vertex keys).
fn spots_on(target: &TriMesh, faces: &[u32]) -> Vec<SurfacePoint> {
    let mut spots: Vec<([u32; 3], SurfacePoint)> = Vec::with_capacity(7 * faces.len());
    for &f in faces {
        let t = target.faces[f as usize];
        for b in SPOTS {
            let mut key = [u32::MAX; 3];
            for k in 0..3 {
                if b[k] > 0.0 {
                    key[k] = t[k];
                }
            }
            key.sort_unstable();
            spots.push((key, (f, b)));
        }
    }
    spots.sort_unstable_by_key(|s| s.0);
    spots.dedup_by_key(|s| s.0);
    spots.into_iter().map(|s| s.1).collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    /// [`untangle_points`] against the disk image `uv`.
    fn on_disk(
        m: &TriMesh,
        uv: &[[f64; 2]],
        pts: &mut [SurfacePoint],
        params: &PointUntangleParams,
    ) -> PointUntangleInfo {
        untangle_points(m, m, TargetImage::Disk(uv), pts, params).unwrap()
    }

    /// Numbers in [0, 1) from a xorshift generator seeded with `state`.
    fn xorshift(mut state: u64) -> impl FnMut() -> f64 {
        move || {
            state ^= state << 13;
            state ^= state >> 7;
            state ^= state << 17;
            (state >> 11) as f64 / (1u64 << 53) as f64
        }
    }

    /// A regular grid of m × m cells in the plane z = 0, counter-clockwise faces.
    fn grid(m: usize) -> TriMesh {
        let mut p = Vec::new();
        for j in 0..=m {
            for i in 0..=m {
                p.push([i as f64, j as f64, 0.0]);
            }
        }
        let idx = |i: usize, j: usize| (j * (m + 1) + i) as u32;
        let mut f = Vec::new();
        for j in 0..m {
            for i in 0..m {
                f.push([idx(i, j), idx(i + 1, j), idx(i + 1, j + 1)]);
                f.push([idx(i, j), idx(i + 1, j + 1), idx(i, j + 1)]);
            }
        }
        TriMesh::new(p, f).unwrap()
    }

    /// The flip test's walk from nearby faces against the point locator on a jittered 12 × 12
    /// grid: for points strictly inside a face both find that face, from a start next to it
    /// (a walk) or across the grid (more than `WALK_STEPS` faces away: the locator).
    #[test]
    fn the_walk_finds_the_locators_face() {
        let mut m = grid(12);
        let mut rand = xorshift(0x9e37_79b9_7f4a_7c15_u64);
        for p in m.positions.iter_mut() {
            if p[0] > 0.0 && p[0] < 12.0 && p[1] > 0.0 && p[1] < 12.0 {
                p[0] += 0.3 * (rand() - 0.5);
                p[1] += 0.3 * (rand() - 0.5);
            }
        }
        let uv: Vec<[f64; 2]> = m.positions.iter().map(|p| [p[0], p[1]]).collect();
        let domain = DiskDomain {
            uv: &uv,
            locator: PointLocator::new(&uv, &m.faces).unwrap(),
        };
        let test = MetricFlipTest::new(&m, domain);
        let (mut walked, mut checked) = (0, 0);
        for _ in 0..400 {
            let c = [12.0 * rand(), 12.0 * rand()];
            let Some(l) = test.domain.locator.locate(c) else {
                continue;
            };
            if l.bary.iter().any(|&b| b < 1e-9) {
                continue;
            }
            checked += 1;
            // a start two rings away: the corner's faces of a neighbour of the face's first corner
            let w = m.faces[l.face as usize][0] as usize;
            let near: Vec<u32> = (0..m.num_faces() as u32)
                .filter(|&f| {
                    m.faces[f as usize].contains(&(w as u32 + 2)) && !m.faces[f as usize].contains(&(w as u32))
                })
                .collect();
            // the walk itself (not the locator behind it) reaches the face from each of them
            for &f0 in &near {
                let b0 = test.bary(f0, c).unwrap();
                assert_eq!(
                    test.walk(c, Some((f0, b0)), |m| m >= 0.0),
                    Some(l.face),
                    "{c:?} from {f0}"
                );
                walked += usize::from(f0 != l.face);
            }
            assert_eq!(test.face_holding(c, None, &near), Some(l.face), "{c:?} from {near:?}");
            assert_eq!(test.face_holding(c, None, &[0]), Some(l.face), "{c:?} from face 0");
            assert_eq!(test.face_holding(c, None, &[]), Some(l.face));
            // a walk from a hint: next to the face, or across the grid (then the locator)
            assert_eq!(test.face_holding(c, near.first().copied(), &[]), Some(l.face));
            assert_eq!(test.face_holding(c, Some(0), &near), Some(l.face));
        }
        assert!(checked > 300 && walked > 100, "{checked} points, {walked} walks");
    }

    #[test]
    fn the_identity_has_no_flips_and_is_left_alone() {
        let m = grid(6);
        let mut map: Vec<u32> = (0..m.num_vertices() as u32).collect();
        let info = untangle_vertex_map(&m, &m, &mut map, &|_, _| 0.0, &VertexMapUntangleParams::default());
        assert_eq!(
            (info.flipped_before, info.collapsed_before, info.vertices_moved),
            (0, 0, 0)
        );
        assert!(map.iter().enumerate().all(|(v, &w)| v as u32 == w));
    }

    /// Two interior vertices swapped: their faces flip; with the distance to the true partner
    /// as the cost, the pass restores the identity.
    #[test]
    fn a_swap_of_two_vertices_is_undone() {
        let m = grid(6);
        let n = m.num_vertices();
        let mut map: Vec<u32> = (0..n as u32).collect();
        let (a, b) = (7 * 2 + 2, 7 * 2 + 3);
        map.swap(a, b);
        let (flipped, _) = count_flipped_images(&m, &m, &map);
        assert!(flipped > 0);
        let pos = m.positions.clone();
        let cost = move |v: usize, w: u32| {
            let (p, q) = (pos[v], pos[w as usize]);
            (p[0] - q[0]).powi(2) + (p[1] - q[1]).powi(2)
        };
        let info = untangle_vertex_map(&m, &m, &mut map, &cost, &VertexMapUntangleParams::default());
        assert_eq!(info.flipped_before, flipped);
        assert_eq!(info.flipped_after, 0);
        assert!(map.iter().enumerate().all(|(v, &w)| v as u32 == w), "{map:?}");
        assert_eq!(info.vertices_moved, 2);
    }

    /// Reflected target (x ↦ −x with the faces reversed to stay outward): the identity vertex map
    /// onto the mirrored grid has no flips either (the normals follow the faces).
    #[test]
    fn orientation_follows_the_target_faces() {
        let m = grid(4);
        let mirrored = TriMesh::new(
            m.positions.iter().map(|p| [-p[0], p[1], p[2]]).collect(),
            m.faces.iter().map(|f| [f[0], f[2], f[1]]).collect(),
        )
        .unwrap();
        let map: Vec<u32> = (0..m.num_vertices() as u32).collect();
        // the source faces keep their order: every image faces away from the mirrored normals
        assert_eq!(count_flipped_images(&m, &mirrored, &map).0, m.num_faces());
        assert_eq!(count_flipped_images(&mirrored, &mirrored, &map).0, 0);
    }

    /// The grid's vertices as points of the grid itself (a vertex of one of its faces).
    fn identity_points(m: &TriMesh) -> Vec<(u32, [f64; 3])> {
        let conn = Connectivity::of(m);
        (0..m.num_vertices())
            .map(|v| {
                let f = conn.vertex_faces[v][0];
                let t = m.faces[f as usize];
                (f, std::array::from_fn(|k| if t[k] as usize == v { 1.0 } else { 0.0 }))
            })
            .collect()
    }

    /// The projected smoothing on a grid bent onto a cylinder (S₁ = S₂, φ₂ the flat grid): the
    /// identity moves by less than an edge's sagitta (the mean-value combination of a star lies
    /// inside the faceted surface, whose closest point is on a face below the vertex); every
    /// interior image moved to a random point of a face around it is pulled back to
    /// under half its distance from the identity, with no flipped face left.
    #[test]
    fn the_projected_smoothing_pulls_scattered_images_back() {
        let n = 12;
        let mut m = grid(n);
        let uv: Vec<[f64; 2]> = m.positions.iter().map(|p| [p[0] / n as f64, p[1] / n as f64]).collect();
        let radius = 6.0;
        for p in m.positions.iter_mut() {
            let a = p[0] / radius;
            *p = [radius * a.sin(), p[1], radius * (1.0 - a.cos())];
        }
        let params = PointUntangleParams {
            smooth_rounds: 3,
            ..PointUntangleParams::default()
        };
        let at = |(f, b): SurfacePoint| {
            let q = m.face_positions(f as usize);
            std::array::from_fn::<f64, 3, _>(|d| b[0] * q[0][d] + b[1] * q[1][d] + b[2] * q[2][d])
        };
        let off = |pts: &[SurfacePoint]| -> f64 {
            (0..m.num_vertices())
                .map(|v| norm3(sub3(at(pts[v]), m.positions[v])))
                .sum::<f64>()
                / m.num_vertices() as f64
        };
        let identity = identity_points(&m);
        let mut pts = identity.clone();
        on_disk(&m, &uv, &mut pts, &params);
        // the closest point to a point inside the faceted cylinder lies on a face below the
        // vertex: the identity drifts by less than an edge's sagitta h²/(8R)
        let sagitta = 1.0 / (8.0 * radius);
        assert!(off(&pts) < sagitta, "{}", off(&pts));

        let conn = Connectivity::of(&m);
        let boundary = conn.boundary_vertices(m.num_vertices());
        let mut rand = xorshift(0x9e37_79b9_7f4a_7c15_u64);
        let mut scattered = identity.clone();
        for v in 0..m.num_vertices() {
            if boundary[v] {
                continue;
            }
            let faces = &conn.vertex_faces[v];
            let f = faces[(rand() * faces.len() as f64) as usize % faces.len()];
            let (a, b) = (rand(), rand());
            let (a, b) = if a + b > 1.0 { (1.0 - a, 1.0 - b) } else { (a, b) };
            scattered[v] = (f, [a, b, 1.0 - a - b]);
        }
        let mut pts = scattered.clone();
        let info = on_disk(&m, &uv, &mut pts, &params);
        let (before, after) = (off(&scattered), off(&pts));
        assert!(
            after < 0.5 * before,
            "mean distance from the identity {before} -> {after}, {info:?}"
        );
        assert!(info.smoothing_moves > 0 && info.flipped_after == 0, "{info:?}");
        // without the smoothing the untangling alone leaves the scatter
        let mut unsmoothed = scattered.clone();
        on_disk(&m, &uv, &mut unsmoothed, &PointUntangleParams::default());
        assert!(off(&unsmoothed) > 0.8 * before, "{} against {before}", off(&unsmoothed));
    }

    /// A unit icosphere (3 subdivisions) with its vertices jittered on S², and a xorshift
    /// generator of numbers in [0, 1).
    fn jittered_icosphere() -> (TriMesh, impl FnMut() -> f64) {
        let mut m = shapespace_geometry::primitives::icosphere(3);
        let mut rand = xorshift(0x2545_f491_4f6c_dd1d_u64);
        for p in m.positions.iter_mut() {
            let q = [
                p[0] + 0.02 * (rand() - 0.5),
                p[1] + 0.02 * (rand() - 0.5),
                p[2] + 0.02 * (rand() - 0.5),
            ];
            *p = normalized(q);
        }
        (m, rand)
    }

    /// On the sphere: for points strictly inside a spherical triangle, the walk from nearby
    /// faces or a hint finds the locator's face, and the ray coordinates there are the
    /// locator's.
    #[test]
    fn the_sphere_walk_finds_the_locators_face() {
        let (m, mut rand) = jittered_icosphere();
        let domain = SphereDomain {
            sphere: &m.positions,
            locator: SphereLocator::new(&m.positions, &m.faces).unwrap(),
        };
        let test = MetricFlipTest::new(&m, domain);
        let (mut walked, mut checked) = (0, 0);
        for _ in 0..400 {
            let c = normalized([rand() - 0.5, rand() - 0.5, rand() - 0.5]);
            let Some((face, bary)) = test.domain.locate(c) else {
                continue;
            };
            if bary.iter().any(|&b| b < 1e-9) {
                continue;
            }
            checked += 1;
            let b = test.bary(face, c).unwrap();
            assert!((0..3).all(|k| (b[k] - bary[k]).abs() < 1e-12), "{b:?} {bary:?}");
            // a start two rings away
            let w = m.faces[face as usize][0];
            let conn = Connectivity::of(&m);
            let far = conn.vertex_neighbors(m.num_vertices())[w as usize][0];
            let near: Vec<u32> = conn.vertex_faces[far as usize]
                .iter()
                .copied()
                .filter(|&f| !m.faces[f as usize].contains(&w))
                .collect();
            // the walk itself (not the locator behind it) reaches the face from each of them
            for &f0 in &near {
                let b0 = test.bary(f0, c).unwrap();
                assert_eq!(
                    test.walk(c, Some((f0, b0)), |m| m >= 0.0),
                    Some(face),
                    "{c:?} from {f0}"
                );
                walked += usize::from(f0 != face);
            }
            assert_eq!(test.face_holding(c, None, &near), Some(face), "{c:?} from {near:?}");
            assert_eq!(test.face_holding(c, near.first().copied(), &[]), Some(face));
            // from the far side of the sphere: the locator
            assert_eq!(test.face_holding(c, Some(0), &[]), Some(face));
            assert_eq!(test.face_holding(c, None, &[]), Some(face));
        }
        assert!(checked > 300 && walked > 100, "{checked} points, {walked} walks");
    }

    /// On the sphere (S₂ = S₁ = a jittered unit icosphere, ψ₂ its own positions): the identity is
    /// left alone; one vertex pushed past its neighbour (to the centroid of a face beyond it)
    /// flips faces of its star, and the pass leaves every face positively oriented on S² and
    /// moves nothing outside the pushed vertex's one-ring.
    #[test]
    fn the_sphere_point_pass_pulls_a_pushed_vertex_back() {
        let (m, _) = jittered_icosphere();
        let run = |pts: &mut [SurfacePoint]| {
            untangle_points(
                &m,
                &m,
                TargetImage::Sphere(&m.positions),
                pts,
                &PointUntangleParams::default(),
            )
            .unwrap()
        };
        let identity = identity_points(&m);
        let mut pts = identity.clone();
        let info = run(&mut pts);
        assert_eq!((info.flipped_before, info.vertices_moved), (0, 0));
        assert_eq!(pts, identity);

        let conn = Connectivity::of(&m);
        let ring = conn.vertex_neighbors(m.num_vertices());
        let v = 100;
        let u = ring[v][0] as usize;
        // a face around u that does not touch v
        let beyond = conn.vertex_faces[u]
            .iter()
            .copied()
            .find(|&f| {
                !m.faces[f as usize].contains(&(v as u32)) && {
                    let c = m.faces[f as usize].iter().filter(|&&w| ring[v].contains(&w)).count();
                    c <= 1
                }
            })
            .unwrap();
        pts[v] = (beyond, [1.0 / 3.0; 3]);
        let pushed = pts.clone();
        let info = run(&mut pts);
        assert!(info.flipped_before >= 1, "{info:?}");
        assert_eq!(info.flipped_after, 0, "{info:?}");
        assert!(info.vertices_moved >= 1, "{info:?}");
        for w in 0..m.num_vertices() {
            if w != v && !ring[v].contains(&(w as u32)) {
                assert_eq!(pts[w], pushed[w], "vertex {w} moved");
            }
        }
        let point = |(f, b): SurfacePoint| {
            let q = m.face_positions(f as usize);
            std::array::from_fn::<f64, 3, _>(|d| b[0] * q[0][d] + b[1] * q[1][d] + b[2] * q[2][d])
        };
        let at = |w: usize| point(pts[w]);
        // v comes back nearer its own position than where it was pushed
        let (back, away) = (
            norm3(sub3(at(v), m.positions[v])),
            norm3(sub3(point(pushed[v]), m.positions[v])),
        );
        assert!(back < 0.5 * away, "{back} against {away}");
        for f in &m.faces {
            let [a, b, c] = f.map(|w| at(w as usize));
            let n = cross3(sub3(b, a), sub3(c, a));
            assert!(n[0] * a[0] + n[1] * a[1] + n[2] * a[2] > 0.0, "{f:?}");
        }
    }

    #[test]
    fn the_point_pass_leaves_the_identity_alone() {
        let m = grid(5);
        let uv: Vec<[f64; 2]> = m.positions.iter().map(|p| [p[0] / 5.0, p[1] / 5.0]).collect();
        let mut pts = identity_points(&m);
        let before = pts.clone();
        let info = on_disk(&m, &uv, &mut pts, &PointUntangleParams::default());
        assert_eq!(
            (info.flipped_before, info.flipped_after, info.vertices_moved),
            (0, 0, 0)
        );
        assert_eq!(pts, before);
    }

    /// One interior vertex pushed past its neighbour (to the centroid of a face beyond it): its
    /// star folds over; the pass leaves every face of the grid counter-clockwise (none flipped,
    /// none degenerate) and moves nothing outside the pushed vertex's one-ring.
    #[test]
    fn a_vertex_pushed_past_its_neighbour_is_pulled_back() {
        let m = grid(6);
        let uv: Vec<[f64; 2]> = m.positions.iter().map(|p| [p[0] / 6.0, p[1] / 6.0]).collect();
        let idx = |i: u32, j: u32| j * 7 + i;
        let mut pts = identity_points(&m);
        let v = idx(2, 2) as usize;
        let beyond = m
            .faces
            .iter()
            .position(|f| *f == [idx(3, 2), idx(4, 2), idx(4, 3)])
            .unwrap() as u32;
        pts[v] = (beyond, [1.0 / 3.0; 3]);
        let pushed = pts.clone();
        let info = on_disk(&m, &uv, &mut pts, &PointUntangleParams::default());
        assert!(info.flipped_before >= 2, "{info:?}");
        assert_eq!(info.flipped_after, 0, "{info:?}");
        assert!(info.vertices_moved >= 1, "{info:?}");
        let ring = Connectivity::of(&m).vertex_neighbors(m.num_vertices());
        for u in 0..m.num_vertices() {
            if u != v && !ring[v].contains(&(u as u32)) {
                assert_eq!(pts[u], pushed[u], "vertex {u} moved");
            }
        }
        // every face counter-clockwise in the plane
        let at = |u: usize| {
            let (f, b) = pts[u];
            let t = m.faces[f as usize];
            let p = |k: usize| m.positions[t[k] as usize];
            [0, 1].map(|d| b[0] * p(0)[d] + b[1] * p(1)[d] + b[2] * p(2)[d])
        };
        for f in &m.faces {
            let [a, b, c] = f.map(|u| at(u as usize));
            assert!(
                (b[0] - a[0]) * (c[1] - a[1]) - (b[1] - a[1]) * (c[0] - a[0]) > 0.0,
                "{f:?}"
            );
        }
    }

    /// A 4 × 4 block of grid vertices mirrored across its middle column: every face of the block
    /// and of its rim flips. Single moves cannot undo a mirrored patch (each vertex alone would
    /// flip the faces it shares with its mirrored neighbours); the region moves lay the patch out
    /// again from its rim and leave no face flipped, and without them faces stay flipped. The
    /// images' total distance from the identity drops to under a quarter of the mirrored one's.
    #[test]
    fn a_mirrored_patch_is_undone_by_a_region_move() {
        let n = 10;
        let m = grid(n);
        let uv: Vec<[f64; 2]> = m.positions.iter().map(|p| [p[0] / n as f64, p[1] / n as f64]).collect();
        let idx = |i: usize, j: usize| j * (n + 1) + i;
        let identity = identity_points(&m);
        let mut mirrored = identity.clone();
        for j in 3..=6 {
            for i in 3..=6 {
                mirrored[idx(i, j)] = identity[idx(9 - i, j)];
            }
        }
        let run = |params: &PointUntangleParams| {
            let mut pts = mirrored.clone();
            let info = on_disk(&m, &uv, &mut pts, params);
            (info, pts)
        };
        let single = run(&PointUntangleParams {
            region_rounds: 0,
            ..PointUntangleParams::default()
        });
        let (info, pts) = run(&PointUntangleParams {
            region_rounds: 3,
            ..PointUntangleParams::default()
        });
        assert!(info.flipped_before >= 18, "{info:?}");
        assert!(single.0.flipped_after > 0, "{:?}", single.0);
        assert_eq!(info.flipped_after, 0, "{info:?}");
        assert!(info.regions_moved >= 1, "{info:?}");
        // the cut (the grid's border) keeps its images; the patch lies near the identity again
        let at = |(f, b): SurfacePoint| {
            let t = m.faces[f as usize];
            let p = |k: usize| m.positions[t[k] as usize];
            [0, 1].map(|d| b[0] * p(0)[d] + b[1] * p(1)[d] + b[2] * p(2)[d])
        };
        let (mut sum, mut sum_mirrored) = (0.0, 0.0);
        for j in 0..=n {
            for i in 0..=n {
                let v = idx(i, j);
                if i == 0 || j == 0 || i == n || j == n {
                    assert_eq!(pts[v], mirrored[v], "({i}, {j}) moved");
                }
                let y = at(identity[v]);
                let (x, z) = (at(pts[v]), at(mirrored[v]));
                sum += (x[0] - y[0]).hypot(x[1] - y[1]);
                sum_mirrored += (z[0] - y[0]).hypot(z[1] - y[1]);
            }
        }
        // 32 edges mirrored; 7.2 after the pass
        assert!(sum < 0.25 * sum_mirrored, "{sum} against {sum_mirrored}");

        // The same pass with the region moves' area threshold just above what the sweeps leave
        // flipped: no region move, and the result of the sweeps alone, bit for bit; just below
        // it: the region moves' result. The share is the flipped faces' area over the grid's
        // (all faces of the unit grid have area 1/2).
        let share = single.0.flipped_after as f64 * 0.5 / (n * n) as f64;
        assert!(
            (info.flipped_area_after_sweeps - share).abs() < 1e-15,
            "{} against {share}",
            info.flipped_area_after_sweeps
        );
        let (above, pts_above) = run(&PointUntangleParams {
            region_from_area: share * (1.0 + 1e-9),
            ..PointUntangleParams::default()
        });
        assert_eq!(above.regions_moved, 0, "{above:?}");
        assert_eq!(above.flipped_after, single.0.flipped_after);
        assert_eq!(pts_above, single.1);
        let (below, pts_below) = run(&PointUntangleParams {
            region_from_area: share * (1.0 - 1e-9),
            ..PointUntangleParams::default()
        });
        assert_eq!((below.flipped_after, below.regions_moved), (0, info.regions_moved));
        assert_eq!(pts_below, pts);
    }
}
