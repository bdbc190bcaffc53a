//! Coarse-to-fine start [in the spirit of Mérigot 2011, "A multiscale approach to optimal
//! transport"], with a prolongation that provably leaves no cell empty.
//!
//! **Coarsening.** The points are merged pairwise along their shortest Delaunay edges (a greedy
//! matching, shortest first), in rounds, until at most N/4 groups remain (N/2 from 20,000 points
//! on: two rounds); a group is the coarse
//! point at its members' mass-weighted mean, with their total mass. Closest pairs merge first,
//! so a cluster of near-coincident points (the conformal image of a long protrusion) becomes one
//! coarse point before well-spread points are grouped. The coarse problem is solved the same
//! way, recursively, at tolerance max(tol, [`NewtonParams::coarse_tolerance`]) (default 1e-3);
//! levels stop below 1000 points, or below 16 when the points are crowded (two closer than 1e-6
//! of the mean spacing). A coarse level that its own coarse-to-fine start does not solve is
//! solved again from the Voronoi start with density continuation, at its own small size (needed
//! by the TOSCA wolves as distance pairs, whose direct solves otherwise fall to the
//! Voronoi start and the iteration cap). The coarsening depends on the target alone (its masses rescaled to the
//! source's mass change the coarse masses and means by rounding, and at most rarely a merge):
//! [`TargetCoarsening`] holds it, computed from the masses as given, for runs that solve many
//! problems with one target.
//!
//! **Prolongation.** Let H_g be the coarse heights, G_g = −H_g, c_g the μ-centroid of the coarse
//! cell W_g (restricted to Ω), s_g 0.9 times the distance from c_g to the boundary of W_g ∩ Ω,
//! δ_g the RMS distance of the group's members to Y_g, and ψ_δ(o) = √(δ² + |o|²) − δ. With
//! $$\Phi_g(y) = G_g + \langle c_g, y - Y_g\rangle + s_g\,\psi_{\delta_g}(y - Y_g), \qquad
//! \Phi = \max_g \Phi_g,$$
//! the fine heights are h_i = −Φ(y_i). Φ is strictly convex and, since |∇ψ| < 1, every
//! subgradient p ∈ ∂Φ(y_i) lies in a ball B(c_g, s_g) ⊂ W_g ∩ Ω. Convexity gives
//! Φ(y_j) > Φ(y_i) + ⟨p, y_j − y_i⟩ for all j ≠ i, i.e. ⟨p, y_i⟩ + h_i > ⟨p, y_j⟩ + h_j: the fine
//! cell of y_i contains a neighbourhood of p ∈ Ω, so **no fine cell is empty**. Inside W_g the
//! children compete like a Voronoi diagram of the anchors c_g + s_g∇ψ(y_i − Y_g): the coarse cell
//! is split around its centroid in the pattern of the children's offsets, whatever their scale
//! (the ψ's δ_g normalizes it). Also Φ_g ≤ u* (the coarse potential's Legendre transform) with
//! equality at Y_g, so the fine potential stays close to the coarse one.
//!
//! **Averaged source measures.** A coarse level is solved against the source measure averaged
//! over a coarser triangulation ([`crate::averaging`]; exact mass on every coarse triangle)
//! when the measure has many more triangles than the level has points (the conformal image of
//! a face: 18.6k triangles against 1,349 coarse points), since every evaluation integrates the
//! whole source measure. Only the coarse cells enter the prolongation, and its guarantee is
//! geometric, so it holds for the averaged measure too; the finest level always integrates
//! the measure itself.
//! The centroids c_g and spreads s_g of a level prolonged to one of at least 20,000 points
//! ([`REINTEGRATE_FROM`]), when its copy has fewer than 3 triangles per point, come from the
//! coarse cells integrated once more on the finer level's
//! measure (same heights, one evaluation): the averaged copy's centroids are off by up to a
//! coarse triangle's size, and on the 30k-point scans that cost the finest level a fifth of its
//! evaluations.
//!
//! The maximum is taken over the groups within [`RINGS`] edges of the coarse regular
//! triangulation; the prolongation is then checked (every point's anchor in its own cell of the
//! fine diagram) and, for each point that fails and for the point whose cell holds its anchor,
//! recomputed over all groups. Each check round's fine diagram is updated by flips from the
//! previous round's, the first from the Delaunay triangulation of the first coarsening round
//! (the same diagrams as built anew, [`DiagramBuilder::update_from`](crate::power_diagram::DiagramBuilder::update_from)).
//! (A check for hidden points only is not enough: a point whose cell exists but lies outside Ω
//! passes it; two slit copies on the unit circle of the bundled wolf0 slit three times are
//! such points.)
//! Heights are kept in double-double form throughout (children of a crowded group differ by
//! less than an ulp of the heights).
//!
//! **Measured** (`examples/multiscale_probe.rs`, `analysis/examples/param_bench.rs`; numbers in
//! `docs/decisions/0003-coarse-to-fine-start.md`): on 1e4 random points with a 100× density contrast the solve takes 0.75 s
//! (15 Newton steps at the finest level), against 15.8 s by density continuation; on the TOSCA
//! horse and centaur it converges in 16–18 steps instead of 47–62. On problems whose Voronoi start
//! is already good (uniform density and well-spread points) it is slower than the Voronoi start,
//! hence [`super::StartStrategy::Auto`].

use super::{solve_ot_prepared, Heights, NewtonParams};
use crate::error::OmtError;
use crate::measure::SourceMeasure;
use crate::power_diagram::{InsertionOrder, PowerDiagram};
use crate::prepared::PreparedMeasure;
use rayon::prelude::*;
use std::borrow::Cow;
use std::sync::Arc;

/// Points below which no coarse level is used unless they are crowded.
const MIN_FINE: usize = 1000;
/// Points below which no coarse level is used.
const MIN_COARSE: usize = 16;
/// Points are crowded when two of them are closer than CROWDED × the mean spacing
/// √(area of Ω's bounding box / N): a direct solve then starts from cells far too small.
const CROWDED: f64 = 1e-6;
/// Groups within this many edges of the coarse regular triangulation compete for the maximum
/// that defines Φ; the start is then checked and the maximum taken over all groups where needed.
const RINGS: usize = 3;
/// Density-continuation ratio of the retry of a coarse level that its own coarse-to-fine start
/// did not solve (when the caller's parameters have none; the distances' fallback uses the same).
pub const RETRY_CONTINUATION: f64 = 10.0;
/// Fine-to-coarse ratio: pairwise merging rounds continue until at most N/RATIO groups remain
/// (levels below [`LARGE_LEVEL`] points).
const RATIO: usize = 4;
/// The ratio for levels of at least [`LARGE_LEVEL`] points: rounds continue until at most N/2
/// groups remain (two rounds, about 3.5 points per group). From the 30k-point facefuns scans,
/// RATIO 4 gave 6.5 points per group (30,205 → 4,601) and a finest level of 9–23 Newton steps
/// (median 12; the 23-step pair took 65 evaluations); with the 8.6k-point level in between, 7–13
/// steps (median 9–11). `docs/decisions/0024-finer-levels-for-large-targets.md`.
const RATIO_LARGE: usize = 2;
/// Levels of at least this many points are coarsened by [`RATIO_LARGE`] (the bundled faces,
/// 9,412 points, are not: their finest level takes 6–7 steps from the RATIO 4 level).
const LARGE_LEVEL: usize = 20_000;

/// The fine-to-coarse ratio of a level of `n` points.
fn level_ratio(n: usize) -> usize {
    if n >= LARGE_LEVEL {
        RATIO_LARGE
    } else {
        RATIO
    }
}
/// After the first round of a level, two groups merge only if each group of several points has
/// a radius ≥ SCALE_MATCH × their distance (see `coarsen`).
const SCALE_MATCH: f64 = 1e-3;
/// At most this many merging rounds per level.
const MAX_ROUNDS: usize = 6;
/// s_g as a fraction of the distance from the coarse centroid c_g to its cell's boundary.
/// (With the intermediate targets of the Newton steps, 0.9 instead of 0.5 takes the
/// 8-face distance benchmark from 603 to 564 steps and 315 to 291 finest-level evaluations,
/// TOSCA horse0's area-preserving OT from 20 to 14 steps; any value below 1 keeps the
/// guarantee, since the balls B(c_g, s_g) stay inside the cells.)
const SPREAD: f64 = 0.9;
/// A coarse level of n points is solved against the source measure averaged over the Delaunay
/// triangulation of a sample of its vertices ([`crate::averaging`]) of size V/2^k (V vertices,
/// k ≥ 1; quantized so that the copy is shared by the pairs of one source, whose coarse levels
/// differ slightly) in [AVERAGING_MIN_SAMPLE·n, 2·AVERAGING_MIN_SAMPLE·n), when that copy has at
/// most [`AVERAGING_MAX_SHARE`] of the measure's triangles (never on the uniform disk of 512
/// triangles). Measured on face pairs (`analysis/examples/pair_cost.rs`): the copy for a level
/// of 1,349 points has 4.7k triangles instead of 18.6k, the coarse levels cost a third of what
/// they did, and the finest level takes as many steps.
const AVERAGING_MIN_SAMPLE: f64 = 1.5;
/// The largest share of the measure's triangles an averaged copy may have. 0.6 rather than a
/// half: the 8.6k-point level of a 30k-point scan ([`RATIO_LARGE`]) asks for the copy on V/2 =
/// 15,102 vertices (estimated 30.9k triangles of 59.7k, 52 %; `averaged_measure` rounds the
/// stride up, so it is built on every third vertex plus the hull: 10.7k vertices, 20.4k
/// triangles); solved on the measure itself, that level cost as much as the finest level's
/// steps it saved.
const AVERAGING_MAX_SHARE: f64 = 0.6;

/// The sample size of the averaged measure for a coarse level of `coarse_n` points (see
/// [`AVERAGING_MIN_SAMPLE`]), `None` when averaging would not pay.
/// `hull_size` is the number of vertices of the convex hull of the measure's vertices.
fn averaging_sample(measure: &SourceMeasure, coarse_n: usize, hull_size: usize) -> Option<usize> {
    let floor = AVERAGING_MIN_SAMPLE * coarse_n as f64;
    let mut sample = measure.vertices.len() / 2;
    if (sample as f64) < floor {
        return None;
    }
    while (sample / 2) as f64 >= floor {
        sample /= 2;
    }
    // The averaged triangulation has about 2·sample triangles plus one per hull vertex.
    ((2 * sample + hull_size) as f64 <= AVERAGING_MAX_SHARE * measure.triangles.len() as f64).then_some(sample)
}
/// Levels of at least this many points take their coarse level's cells integrated again on
/// their own measure, not on the averaged copy the coarse level was solved on, for the
/// prolongation's centroids and spreads. On the five consecutive facefuns pairs f18 → … → f66
/// (30,205 points, the 8.6k level on a 20.4k-triangle copy of 59.7k) the finest level took 45
/// steps and 85 evaluations instead of 52 and 108, for one evaluation of 8.6k cells on the
/// measure (`scan_probe`; `docs/decisions/0047-coarse-cells-on-the-measure.md`). Smaller levels
/// (the bundled faces' 9,412 points) keep the averaged cells.
const REINTEGRATE_FROM: usize = LARGE_LEVEL;
/// ... and only when the averaged copy has fewer than this many triangles per coarse point
/// (the 8.6k level of a 30k-point scan: 20.4k triangles, 2.4 per point). On the facefuns pair
/// f18 → f26 subdivided once (120,136 points), whose 34.3k level is solved on a copy of 120k
/// triangles (3.5 per point), its cells integrated on the measure cost the finest level a step
/// and five evaluations (11 and 21 instead of 10 and 16).
const REINTEGRATE_TRIANGLES_PER_POINT: f64 = 3.0;
/// Rounds of the check of the anchors after the prolongation.
const REPAIR_ROUNDS: usize = 8;

/// The coarse problem of one level: representatives (mass-weighted means of their groups), their
/// masses (sums of the group's masses), and each fine point's group; computed by [`coarsen`] or
/// borrowed from a [`TargetCoarsening`].
struct Coarsening<'a> {
    points: Cow<'a, [[f64; 2]]>,
    masses: Cow<'a, [f64]>,
    group: Cow<'a, [usize]>,
    /// The shortest Delaunay edge of the fine points.
    closest: f64,
    /// The Delaunay triangulation of the fine points (the first round's).
    delaunay: Option<Cow<'a, PowerDiagram>>,
}

/// The coarsening hierarchy of one target (points and masses) for the coarse-to-fine start:
/// every level's groups, coarse points and masses, the fine points' Delaunay triangulation and
/// the insertion orders. All of it depends on the target only (the merges follow the Delaunay
/// edges and the groups' radii about their mass-weighted means), so a run that solves many
/// problems with one target (the pairwise distances: n − 1 sources per target) builds it once
/// and hands it to each solve through [`NewtonParams::target_coarsening`]. Without it a solve
/// coarsens the masses rescaled to its source's mass (μ(Ω)/Σν, 1 up to rounding on face pairs),
/// so the two starts differ in rounding (which can also flip a discrete choice of a later
/// merging round). The solves agree within their tolerance, not bitwise: such rounding already
/// decides an extra step on TOSCA victoria0, which is why the solver's own path keeps the
/// rescaled masses. A solve whose points or masses differ from the hierarchy's (bitwise)
/// ignores it.
pub struct TargetCoarsening {
    points: Vec<[f64; 2]>,
    masses: Vec<f64>,
    /// The points' insertion order (`None`: the points cannot be triangulated).
    order: Option<InsertionOrder>,
    /// The next coarser level (`None` where the solve would take no coarse level whatever the
    /// measure: fewer than [`MIN_COARSE`] points, a failed coarsening, or one that merges too
    /// little).
    coarse: Option<CoarseLevel>,
}

/// One step down a [`TargetCoarsening`].
struct CoarseLevel {
    group: Vec<usize>,
    closest: f64,
    delaunay: Option<PowerDiagram>,
    /// The hierarchy below, for the coarse points and masses.
    next: Arc<TargetCoarsening>,
}

impl TargetCoarsening {
    /// The hierarchy of the target (`points`, `masses`), as the coarse-to-fine start would
    /// compute it level by level (down to `MIN_COARSE` points; the start decides per solve
    /// how many levels it uses). Invalid input gives a hierarchy without levels.
    pub fn new(points: &[[f64; 2]], masses: &[f64]) -> Self {
        let order = InsertionOrder::new(points).ok();
        let n = points.len();
        let coarse = if n >= MIN_COARSE && masses.len() == n && order.is_some() {
            coarsen(points, masses, None)
                .ok()
                .filter(|c| c.points.len() * 4 <= n * 3)
                .map(|c| CoarseLevel {
                    next: Arc::new(Self::new(&c.points, &c.masses)),
                    group: c.group.into_owned(),
                    closest: c.closest,
                    delaunay: c.delaunay.map(Cow::into_owned),
                })
        } else {
            None
        };
        TargetCoarsening {
            points: points.to_vec(),
            masses: masses.to_vec(),
            order,
            coarse,
        }
    }

    /// Points per level, finest first.
    pub fn level_sizes(&self) -> Vec<usize> {
        let mut sizes = vec![self.points.len()];
        let mut level = self;
        while let Some(c) = &level.coarse {
            level = &c.next;
            sizes.push(level.points.len());
        }
        sizes
    }

    /// Whether this is the hierarchy of exactly these points and masses (bitwise).
    fn matches(&self, points: &[[f64; 2]], masses: &[f64]) -> bool {
        self.points.len() == points.len()
            && self.masses.len() == masses.len()
            && self
                .points
                .iter()
                .zip(points)
                .all(|(a, b)| a[0].to_bits() == b[0].to_bits() && a[1].to_bits() == b[1].to_bits())
            && self.masses.iter().zip(masses).all(|(a, b)| a.to_bits() == b.to_bits())
    }
}

impl std::fmt::Debug for TargetCoarsening {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("TargetCoarsening")
            .field("level_sizes", &self.level_sizes())
            .finish()
    }
}

/// Merges the points pairwise along their shortest Delaunay edges (greedy matching, shortest
/// first), in rounds, until at most N/ratio groups remain (`level_ratio`: RATIO, or RATIO_LARGE
/// from LARGE_LEVEL points on), or a round merges nothing. Closest
/// pairs merge first, so clusters of near-coincident points become one coarse point before
/// well-spread points are grouped. After the first round, a group of several points whose radius
/// is below SCALE_MATCH × the distance to its partner does not merge: its members would be
/// children of one coarse point at two scales at once, and the prolongation would give the inner
/// ones cells as small as their spread (measured: a pair 5e-12 apart merged with points 1e-2 away
/// lost both cells to round-off). It merges at a later level, as one point.
///
/// `delaunay`, when given, is the Delaunay triangulation of `points` (a power diagram with all
/// weights 0) and replaces the first round's own: the regular triangulation of a point set
/// under the exact predicates with symbolic perturbation is unique, and the round sorts its
/// edges completely, so the result is the same.
fn coarsen(
    points: &[[f64; 2]],
    point_masses: &[f64],
    mut delaunay: Option<PowerDiagram>,
) -> Result<Coarsening<'static>, OmtError> {
    let n = points.len();
    let mut reps = points.to_vec();
    let mut masses = point_masses.to_vec();
    let mut group: Vec<usize> = (0..n).collect();
    let mut closest = f64::INFINITY;
    let mut fine_delaunay = None;
    for round in 0..MAX_ROUNDS {
        if round > 0 && reps.len() * level_ratio(n) <= n {
            break;
        }
        // (taken in the first round: later rounds triangulate the merged points)
        let delaunay = match delaunay.take().filter(|d| d.num_sites() == reps.len()) {
            Some(d) => d,
            None => PowerDiagram::new(&reps, &vec![0.0; reps.len()])?,
        };
        let mut edges: Vec<(f64, u32, u32)> = Vec::new();
        for i in 0..reps.len() {
            for &j in delaunay.neighbors(i) {
                if j as usize > i {
                    let q = reps[j as usize];
                    let d = (reps[i][0] - q[0]).powi(2) + (reps[i][1] - q[1]).powi(2);
                    edges.push((d, i as u32, j));
                }
            }
        }
        edges.sort_unstable_by(|a, b| a.0.total_cmp(&b.0).then(a.1.cmp(&b.1)).then(a.2.cmp(&b.2)));
        if round == 0 {
            closest = edges.first().map_or(f64::INFINITY, |e| e.0.sqrt());
        }
        // radius and size of each current group (over the level's points)
        let mut radius = vec![0.0f64; reps.len()];
        let mut size = vec![0usize; reps.len()];
        for (i, &g) in group.iter().enumerate() {
            radius[g] = radius[g].max((points[i][0] - reps[g][0]).hypot(points[i][1] - reps[g][1]));
            size[g] += 1;
        }
        let mut merged_into = vec![usize::MAX; reps.len()];
        let mut count = 0;
        for &(d2, i, j) in &edges {
            let (i, j) = (i as usize, j as usize);
            let reach = SCALE_MATCH * d2.sqrt();
            if (size[i] > 1 && radius[i] < reach) || (size[j] > 1 && radius[j] < reach) {
                continue;
            }
            if merged_into[i] == usize::MAX && merged_into[j] == usize::MAX {
                merged_into[i] = count;
                merged_into[j] = count;
                count += 1;
            }
        }
        if count == 0 {
            break;
        }
        for m in merged_into.iter_mut() {
            if *m == usize::MAX {
                *m = count;
                count += 1;
            }
        }
        let mut next = vec![[0.0; 2]; count];
        let mut next_masses = vec![0.0; count];
        for (i, &g) in merged_into.iter().enumerate() {
            next[g][0] += masses[i] * reps[i][0];
            next[g][1] += masses[i] * reps[i][1];
            next_masses[g] += masses[i];
        }
        for (p, &m) in next.iter_mut().zip(&next_masses) {
            p[0] /= m;
            p[1] /= m;
        }
        for g in group.iter_mut() {
            *g = merged_into[*g];
        }
        reps = next;
        masses = next_masses;
        if round == 0 {
            fine_delaunay = Some(delaunay);
        }
    }
    Ok(Coarsening {
        points: Cow::Owned(reps),
        masses: Cow::Owned(masses),
        group: Cow::Owned(group),
        closest,
        delaunay: fine_delaunay.map(Cow::Owned),
    })
}

/// The boundary of a convex polygon Ω as its edges with their lengths (computed once: the disk
/// polygon of the area-preserving map has 8 edges per boundary vertex, 2,448 for Nefertiti slit,
/// where a `hypot` per edge and group would take a quarter of a second), and a disk inside Ω,
/// which bounds the distance to ∂Ω from below: [`DomainEdges::distance`] goes over the edges
/// only for the groups that the bound cannot settle (those near ∂Ω when Ω is nearly round, as
/// the disk map's polygon is; more of them for a long thin Ω). Every group over every edge is
/// O(N^1.5) work: on the 120k-point scan pair (1,361 edges) the finest prolongation's
/// candidate groups and spreads (`Prolongation::new`) take 0.12 s with the bound and 0.16 s
/// without.
struct DomainEdges {
    edges: Vec<([[f64; 2]; 2], f64)>,
    /// The mean of the polygon's vertices, inside Ω ([`crate::polygon::inner_disk`]).
    centre: [f64; 2],
    /// The distance from `centre` to ∂Ω (−∞ for a degenerate or clockwise polygon: the bound
    /// never applies).
    inradius: f64,
    /// The largest vertex coordinate in absolute value: with |x|, the scale of the rounding of
    /// the distances to ∂Ω.
    size: f64,
}

impl DomainEdges {
    /// The edges of the convex polygon `hull` (counter-clockwise); none below three vertices.
    fn new(hull: &[[f64; 2]]) -> Self {
        if hull.len() < 3 {
            return DomainEdges {
                edges: Vec::new(),
                centre: [0.0; 2],
                inradius: f64::NEG_INFINITY,
                size: 0.0,
            };
        }
        let edges: Vec<_> = (0..hull.len())
            .map(|k| {
                let (a, b) = (hull[k], hull[(k + 1) % hull.len()]);
                ([a, b], (b[0] - a[0]).hypot(b[1] - a[1]))
            })
            .collect();
        let (centre, radius) = crate::polygon::inner_disk(hull);
        DomainEdges {
            edges,
            centre,
            inradius: if radius > 0.0 && radius.is_finite() {
                radius
            } else {
                f64::NEG_INFINITY
            },
            size: hull.iter().fold(0.0f64, |r, p| r.max(p[0].abs()).max(p[1].abs())),
        }
    }

    /// The number of edges.
    fn len(&self) -> usize {
        self.edges.len()
    }

    /// Distance from x to the boundary of the polygon (negative outside; +∞ without edges).
    fn distance(&self, x: [f64; 2]) -> f64 {
        self.edges
            .iter()
            .map(|([a, b], length)| {
                let (ex, ey) = (b[0] - a[0], b[1] - a[1]);
                (ex * (x[1] - a[1]) - ey * (x[0] - a[0])) / length
            })
            .fold(f64::INFINITY, f64::min)
    }

    /// `d.min(self.distance(x))`, without going over the edges when the inner disk shows that
    /// the distance is at least `d` (each edge's signed distance is 1-Lipschitz in x, so it is at
    /// least `inradius` − |x − centre|). The same value either way: the bound is taken with a
    /// margin of 1e-12 × (the coordinates' size + |x|₁), about a thousand times the rounding of
    /// the distances.
    fn min_distance(&self, x: [f64; 2], d: f64) -> f64 {
        let lower = self.inradius - (x[0] - self.centre[0]).hypot(x[1] - self.centre[1]);
        if lower - 1e-12 * (self.size + x[0].abs() + x[1].abs()) >= d {
            d
        } else {
            d.min(self.distance(x))
        }
    }
}

/// ψ_δ(o) = √(δ² + |o|²) − δ, evaluated without cancellation: strictly convex, gradient of
/// norm < 1.
fn pseudo_huber(o: [f64; 2], delta: f64) -> f64 {
    let r2 = o[0] * o[0] + o[1] * o[1];
    if r2 == 0.0 {
        return 0.0;
    }
    r2 / ((delta * delta + r2).sqrt() + delta)
}

/// The coarse-to-fine start of [`coarse_to_fine_heights`].
pub(crate) struct CoarseStart {
    /// The fine heights.
    pub heights: Heights,
    /// Points of the next coarser level.
    pub coarse_points: usize,
    /// Newton steps of all coarser levels.
    pub coarse_iterations: usize,
    /// The same by level, next coarser first.
    pub level_iterations: Vec<usize>,
    /// The power diagram of `heights` built by the last check, with its insertion order (the
    /// first evaluation integrates it instead of building it again); `None` when the last check
    /// round still changed heights.
    pub checked: Option<(PowerDiagram, InsertionOrder)>,
}

/// Initial heights (double-double, #N) from a coarse solve ([`CoarseStart`]); `None` when N is
/// too small for a coarse level or the coarse level could not be solved, neither from its own
/// coarse-to-fine start nor, retried after that start, from the Voronoi start with density
/// continuation (ratio [`RETRY_CONTINUATION`] unless `params` has one).
///
/// Prolongation (module docs): with G_g = −H_g the coarse solution, c_g its cell centroids and
/// Φ_g(y) = G_g + ⟨c_g, y − Y_g⟩ + s_g ψ_{δ_g}(y − Y_g), the fine heights are h_i = −Φ(y_i) with
/// Φ = max_g Φ_g, the maximum taken over the point's group and the groups whose coarse cells
/// border it. Φ is strictly convex and its subgradients lie in the balls B(c_g, s_g) ⊂ W_g ∩ Ω,
/// so the point x = ∂Φ(y_i) satisfies ⟨x, y_i⟩ + h_i > ⟨x, y_j⟩ + h_j for every j ≠ i: every
/// fine cell contains a neighbourhood of a point of Ω, i.e. none is empty.
///
/// `voronoi`: the Delaunay triangulation of `points` and its insertion order when the caller
/// built them already (Auto's Voronoi test); they save the coarsening's first triangulation (not
/// needed when `params.target_coarsening` matches: the hierarchy has its own) and
/// the check's order, and change nothing else.
pub(crate) fn coarse_to_fine_heights(
    measure: &PreparedMeasure,
    points: &[[f64; 2]],
    masses: &[f64],
    targets: &[f64],
    params: &NewtonParams,
    voronoi: Option<(PowerDiagram, InsertionOrder)>,
) -> Result<Option<CoarseStart>, OmtError> {
    let n = points.len();
    if n < MIN_COARSE {
        return Ok(None);
    }
    let (delaunay, fine_order) = voronoi.unzip();
    let cached = params
        .target_coarsening
        .as_deref()
        .filter(|c| c.matches(points, masses));
    // (merged points can coincide in principle, which the Delaunay triangulation of the next
    // round rejects: then no coarse level, not an error)
    let (mut coarse, below) = match cached {
        Some(TargetCoarsening { coarse: None, .. }) => return Ok(None),
        Some(TargetCoarsening {
            coarse: Some(level), ..
        }) => (
            Coarsening {
                points: Cow::Borrowed(&level.next.points),
                masses: Cow::Borrowed(&level.next.masses),
                group: Cow::Borrowed(&level.group),
                closest: level.closest,
                delaunay: level.delaunay.as_ref().map(Cow::Borrowed),
            },
            Some(&level.next),
        ),
        None => match coarsen(points, targets, delaunay) {
            Ok(coarse) => (coarse, None),
            Err(_) => return Ok(None),
        },
    };
    let coarse_n = coarse.points.len();
    let (lo, hi) = crate::polygon::bounding_box(&measure.vertices);
    let spacing = ((hi[0] - lo[0]) * (hi[1] - lo[1]) / n as f64).sqrt();
    let crowded = coarse.closest < CROWDED * spacing;
    if (n < MIN_FINE && !crowded) || coarse_n * 4 > n * 3 {
        return Ok(None);
    }
    // Ω's boundary edges (one per hull vertex), for the averaging rule and the spreads s_g.
    let boundary = DomainEdges::new(&measure.domain_hull());
    let Some(solution) = solve_level(
        measure,
        &coarse.points,
        &coarse.masses,
        below,
        boundary.len(),
        n >= REINTEGRATE_FROM,
        params,
    )?
    else {
        return Ok(None);
    };
    let delaunay = coarse.delaunay.take();
    let prolongation = Prolongation::new(points, &coarse, &solution, &boundary, below)?;
    let (mut heights, mut anchors) = prolongation.initial(points);
    let order = match (fine_order, cached.and_then(|c| c.order.as_ref())) {
        (Some(order), _) if order.len() == n => order,
        (_, Some(order)) => order.clone(),
        _ => InsertionOrder::new(points)?,
    };
    let checked = prolongation.check(points, &mut heights, &mut anchors, &order, delaunay, params)?;
    Ok(Some(CoarseStart {
        heights,
        coarse_points: coarse_n,
        coarse_iterations: solution.all_iterations(),
        level_iterations: std::iter::once(solution.iterations)
            .chain(match &solution.start {
                super::Start::CoarseToFine { level_iterations, .. } => level_iterations.clone(),
                _ => Vec::new(),
            })
            .collect(),
        checked: checked.map(|diagram| (diagram, order)),
    }))
}

/// Solves the coarse level (`points`, `masses`) of a coarse-to-fine start against the source
/// measure, averaged where that pays ([`averaging_sample`]), from its own coarse-to-fine start;
/// a level that start does not solve is retried from the Voronoi start with density
/// continuation. `None` when neither solves it; a time limit passed is an error. With
/// `reintegrate` ([`REINTEGRATE_FROM`]), a level solved on an averaged copy with fewer than
/// [`REINTEGRATE_TRIANGLES_PER_POINT`] triangles per point returns its cells integrated on
/// `measure` itself.
fn solve_level(
    measure: &PreparedMeasure,
    points: &[[f64; 2]],
    masses: &[f64],
    below: Option<&Arc<TargetCoarsening>>,
    hull_size: usize,
    reintegrate: bool,
    params: &NewtonParams,
) -> Result<Option<super::OtSolution>, OmtError> {
    let coarse_n = points.len();
    let coarse_params = NewtonParams {
        tolerance: params.tolerance.max(params.coarse_tolerance),
        target_coarsening: below.cloned(),
        // (the cap applies to the finest level: with 0 the caller asks for the start itself)
        max_iterations: params.max_iterations.max(NewtonParams::default().max_iterations),
        initial_heights: None,
        initial_heights_lo: None,
        start_strategy: super::StartStrategy::CoarseToFine,
        ..params.clone()
    };
    let averaged = averaging_sample(measure, coarse_n, hull_size).and_then(|sample| measure.averaged(sample));
    let level_measure = averaged.as_deref().unwrap_or(measure);
    // The deadline ends the whole solve: a level it stopped (or a level below, whose error comes
    // up through `solve_ot`) is reported as such instead of leaving every enclosing level to
    // try its own Voronoi start.
    let timed_out = || {
        Err(OmtError::TimeLimit(format!(
            "solving the {coarse_n}-point level of the coarse-to-fine start"
        )))
    };
    let solution = match solve_ot_prepared(level_measure, points, masses, &coarse_params) {
        Ok(s) if s.converged() => s,
        Err(e @ OmtError::TimeLimit(_)) => return Err(e),
        // (a level stopped on the deadline included: `StopReason::TimeLimit` means it has passed)
        _ if params.past_deadline() => return timed_out(),
        // A coarse level that its own coarse-to-fine start does not solve (TOSCA wolves as
        // distance pairs: density contrast ~8e13, the 603-point level stops at the cap) gets
        // the robust path at its own small size: the Voronoi start with density continuation.
        // Its cost is bounded by the level's size, and a solved level still gives the finest
        // level its start. Only after a coarse start: without one, `solve_ot` has already run
        // the Voronoi path with the caller's continuation (and a level below that failed has
        // had its own retry). The failed attempt's steps are counted when the retry succeeds.
        Ok(first) if matches!(first.start, super::Start::CoarseToFine { .. }) => {
            let first_iterations = first.all_iterations();
            let retry = NewtonParams {
                start_strategy: super::StartStrategy::Voronoi,
                density_continuation: Some(params.density_continuation.unwrap_or(RETRY_CONTINUATION)),
                ..coarse_params.clone()
            };
            match solve_ot_prepared(level_measure, points, masses, &retry) {
                Ok(mut s) if s.converged() => {
                    s.iterations += first_iterations;
                    s
                }
                Err(e @ OmtError::TimeLimit(_)) => return Err(e),
                _ if params.past_deadline() => return timed_out(),
                _ => return Ok(None),
            }
        }
        _ => return Ok(None),
    };
    // The coarse cells on the measure itself (REINTEGRATE_FROM, on a coarse copy): the prolongation takes its
    // centroids and spreads from them. Same heights, same diagram, so no cell is empty that was
    // not empty on the averaged copy (both densities are positive on all of Ω).
    let mut solution = solution;
    let coarse_copy = averaged
        .as_deref()
        .is_some_and(|a| (a.triangles.len() as f64) < REINTEGRATE_TRIANGLES_PER_POINT * coarse_n as f64);
    if reintegrate && coarse_copy {
        let backend = super::Backend::new(measure, params.integrator, None);
        let heights = Heights::from_parts(&solution.heights, &solution.heights_lo);
        let cells = super::evaluate(&backend, points, &heights)?.cells;
        if cells.masses.iter().all(|&m| m > 0.0) {
            solution.cells = cells;
        }
    }
    Ok(Some(solution))
}
/// The prolongation of a coarse solution to the fine points (module docs): with G_g = −H_g,
/// c_g the coarse cells' centroids, s_g their spreads and δ_g the groups' radii,
/// Φ_g(y) = G_g + ⟨c_g, y − Y_g⟩ + s_g ψ_{δ_g}(y − Y_g), and a fine point's height is
/// −max_k Φ_k(y_i) over the candidate groups.
struct Prolongation<'a> {
    /// The coarse points Y_g.
    coarse: &'a [[f64; 2]],
    /// Each fine point's group.
    group: &'a [usize],
    /// The coarse solution's heights H (double-double parts).
    hh: &'a [f64],
    hl: &'a [f64],
    centroids: Vec<[f64; 2]>,
    scales: Vec<f64>,
    deltas: Vec<f64>,
    /// The fine points of each group.
    members: Vec<Vec<usize>>,
    /// The groups within [`RINGS`] edges of each group ([`candidate_groups`]).
    candidates: Vec<Vec<usize>>,
}

impl<'a> Prolongation<'a> {
    fn new(
        points: &[[f64; 2]],
        coarse: &'a Coarsening<'_>,
        solution: &'a super::OtSolution,
        boundary: &DomainEdges,
        below: Option<&Arc<TargetCoarsening>>,
    ) -> Result<Self, OmtError> {
        let coarse_n = coarse.points.len();
        let cells = &solution.cells;
        let (hh, hl) = (&solution.heights, &solution.heights_lo);
        // H_a − H_b from the double-double parts.
        let height_diff = |a: usize, b: usize| (hh[a] - hh[b]) + (hl[a] - hl[b]);
        let mut neighbours: Vec<Vec<usize>> = vec![Vec::new(); coarse_n];
        for &(i, j, _) in &cells.edge_masses {
            neighbours[i as usize].push(j as usize);
            neighbours[j as usize].push(i as usize);
        }
        // Candidates for the maximum: the groups within RINGS edges of the regular triangulation of
        // the coarse solution (not only the cells that meet inside Ω).
        let candidates = candidate_groups(&coarse.points, hh, hl, below.and_then(|b| b.order.as_ref()))?;
        let centroids: Vec<[f64; 2]> = (0..coarse_n)
            .map(|g| {
                let m = cells.masses[g];
                [cells.first_moments[g][0] / m, cells.first_moments[g][1] / m]
            })
            .collect();
        // s_g: SPREAD × the distance from c_g to the boundary of its cell W_g ∩ Ω (the bisectors with
        // the neighbours, ⟨x, Y_g − Y_j⟩ + H_g − H_j = 0, and ∂Ω).
        let scales: Vec<f64> = (0..coarse_n)
            .into_par_iter()
            .map(|g| {
                let c = centroids[g];
                let y = coarse.points[g];
                let mut d = f64::INFINITY;
                for &j in &neighbours[g] {
                    let yj = coarse.points[j];
                    let gap = [y[0] - yj[0], y[1] - yj[1]];
                    let along = c[0] * gap[0] + c[1] * gap[1] + height_diff(g, j);
                    d = d.min(along / gap[0].hypot(gap[1]));
                }
                let d = boundary.min_distance(c, d);
                if d.is_finite() && d > 0.0 {
                    SPREAD * d
                } else {
                    0.0
                }
            })
            .collect();
        let mut members: Vec<Vec<usize>> = vec![Vec::new(); coarse_n];
        for (i, &g) in coarse.group.iter().enumerate() {
            members[g].push(i);
        }
        let deltas: Vec<f64> = (0..coarse_n)
            .map(|g| {
                let y = coarse.points[g];
                let sum: f64 = members[g]
                    .iter()
                    .map(|&i| (points[i][0] - y[0]).powi(2) + (points[i][1] - y[1]).powi(2))
                    .sum();
                (sum / members[g].len() as f64).sqrt()
            })
            .collect();
        Ok(Self {
            coarse: &coarse.points,
            group: &coarse.group,
            hh,
            hl,
            centroids,
            scales,
            deltas,
            members,
            candidates,
        })
    }

    /// H_a − H_b from the double-double parts.
    fn height_diff(&self, a: usize, b: usize) -> f64 {
        (self.hh[a] - self.hh[b]) + (self.hl[a] - self.hl[b])
    }

    /// Φ_k(y) − G_g for a point y of group g.
    fn phi_rel(&self, k: usize, g: usize, y: [f64; 2]) -> f64 {
        let yk = self.coarse[k];
        let o = [y[0] - yk[0], y[1] - yk[1]];
        let base = if k == g { 0.0 } else { self.height_diff(g, k) };
        base + self.centroids[k][0] * o[0]
            + self.centroids[k][1] * o[1]
            + self.scales[k] * pseudo_huber(o, self.deltas[k])
    }

    /// h_i = H_g − (Φ(y_i) − G_g), in double-double form.
    fn set(&self, heights: &mut Heights, i: usize, rel: f64) {
        let g = self.group[i];
        let (s, e) = crate::predicates::two_sum(self.hh[g], -rel);
        let r = crate::predicates::two_sum(s, e + self.hl[g]);
        heights.hi[i] = r.0;
        heights.lo[i] = r.1;
    }

    /// ∂Φ(y) at a point y where Φ_k attains the maximum: c_k + s_k ∇ψ_δk(y − Y_k).
    fn anchor(&self, k: usize, y: [f64; 2]) -> [f64; 2] {
        let yk = self.coarse[k];
        let o = [y[0] - yk[0], y[1] - yk[1]];
        let norm = (self.deltas[k] * self.deltas[k] + o[0] * o[0] + o[1] * o[1]).sqrt();
        let grad = if norm > 0.0 {
            [o[0] / norm, o[1] / norm]
        } else {
            [0.0, 0.0]
        };
        [
            self.centroids[k][0] + self.scales[k] * grad[0],
            self.centroids[k][1] + self.scales[k] * grad[1],
        ]
    }

    /// max_k Φ_k(y_i) − G_g over the groups `ks` and i's own group g, with its anchor (ties: the
    /// first maximum, g before `ks`).
    fn maximum(&self, points: &[[f64; 2]], i: usize, ks: &mut dyn Iterator<Item = usize>) -> (f64, [f64; 2]) {
        let (g, y) = (self.group[i], points[i]);
        let mut best = (self.phi_rel(g, g, y), g);
        for k in ks {
            let v = self.phi_rel(k, g, y);
            if v > best.0 {
                best = (v, k);
            }
        }
        (best.0, self.anchor(best.1, y))
    }

    /// The maximum over all groups.
    fn exact(&self, points: &[[f64; 2]], i: usize) -> (f64, [f64; 2]) {
        self.maximum(points, i, &mut (0..self.coarse.len()))
    }

    /// The fine heights with the maximum over the candidate groups, and each point's anchor.
    fn initial(&self, points: &[[f64; 2]]) -> (Heights, Vec<[f64; 2]>) {
        let n = points.len();
        let prolonged: Vec<(f64, [f64; 2])> = self
            .group
            .par_iter()
            .enumerate()
            .map(|(i, &g)| {
                // A group of one: y_i = Y_g, where every other Φ_k lies below u*(Y_g) = G_g.
                if self.members[g].len() == 1 {
                    (0.0, self.anchor(g, points[i]))
                } else {
                    self.maximum(points, i, &mut self.candidates[g].iter().copied())
                }
            })
            .collect();
        let mut heights = Heights {
            hi: vec![0.0; n],
            lo: vec![0.0; n],
        };
        let mut anchors = vec![[0.0; 2]; n];
        for (i, &(rel, a)) in prolonged.iter().enumerate() {
            self.set(&mut heights, i, rel);
            anchors[i] = a;
        }
        (heights, anchors)
    }

    /// Checks the prolonged heights (the comment below) and corrects them; returns the power
    /// diagram of the final heights when the last round changed none.
    fn check(
        &self,
        points: &[[f64; 2]],
        heights: &mut Heights,
        anchors: &mut [[f64; 2]],
        order: &InsertionOrder,
        delaunay: Option<Cow<'_, PowerDiagram>>,
        params: &NewtonParams,
    ) -> Result<Option<PowerDiagram>, OmtError> {
        let n = points.len();
        // Check: with the maximum taken over the candidate groups only, a point's value can fall
        // below Φ(y_i); its cell is then too large and may squeeze another's out of Ω or hide it.
        // Every point j must hold its anchor p_j ∈ ∂Φ(y_j) ⊂ Ω in its own cell (then its cell
        // meets Ω in an open set); for each j that does not (hidden or not), take the exact
        // maximum (over all groups) for j and for the point i whose cell contains p_j: one of the
        // two was underestimated.
        let mut exact_done = vec![false; n];
        // the diagram of the final heights, if the last round changed none
        let mut checked = None;
        // each round's diagram is updated by flips (the same diagram as built anew) from the
        // previous round's, the first from the coarsening's Delaunay triangulation
        let mut previous = delaunay;
        for _round in 0..REPAIR_ROUNDS {
            let (w, wl) = heights.weights(points);
            let diagram = match previous.take().filter(|_| params.flip_updates) {
                Some(previous) => PowerDiagram::builder(points, &w)
                    .low_parts(Some(&wl))
                    .order(order)
                    .update_from(&previous)
                    .build()?,
                None => PowerDiagram::builder(points, &w)
                    .low_parts(Some(&wl))
                    .order(order)
                    .build()?,
            };
            // (a walk from j stops at j unless j is hidden or a neighbour is strictly closer)
            let outside: Vec<usize> = (0..n)
                .into_par_iter()
                .filter(|&j| diagram.locate(anchors[j], Some(j)) != j)
                .collect();
            if outside.is_empty() {
                checked = Some(diagram);
                break;
            }
            // The points whose maximum is taken over all groups this round: each failing point
            // and the owner of its anchor, unless done before (the exact maxima in parallel).
            let mut todo = Vec::new();
            for j in outside {
                let i = diagram.locate(anchors[j], Some(j));
                for k in [j, i] {
                    if !exact_done[k] {
                        exact_done[k] = true;
                        todo.push(k);
                    }
                }
            }
            let changed = !todo.is_empty();
            let exact: Vec<(f64, [f64; 2])> = todo.par_iter().map(|&k| self.exact(points, k)).collect();
            for (&k, &(rel, a)) in todo.iter().zip(&exact) {
                self.set(heights, k, rel);
                anchors[k] = a;
            }
            // Every failing point and the owner of its anchor already have the exact maximum: what
            // is left is rounding in the crowded spots (the anchor falls just outside a cell that
            // is not empty); another diagram would find the same.
            if !changed {
                checked = Some(diagram);
                break;
            }
            previous = Some(Cow::Owned(diagram));
        }
        Ok(checked)
    }
}

/// For each coarse group, the groups within [`RINGS`] edges of the regular triangulation of
/// the coarse solution (`heights` + `heights_lo` at `points`; `order`: their insertion order
/// when the level has one): the candidates for the maximum of the prolongation's check.
fn candidate_groups(
    points: &[[f64; 2]],
    heights: &[f64],
    heights_lo: &[f64],
    order: Option<&InsertionOrder>,
) -> Result<Vec<Vec<usize>>, OmtError> {
    let (w, wl) = Heights {
        hi: heights.to_vec(),
        lo: heights_lo.to_vec(),
    }
    .weights(points);
    let built;
    let order = match order {
        Some(order) => order,
        None => {
            built = InsertionOrder::new(points)?;
            &built
        }
    };
    let regular = PowerDiagram::builder(points, &w)
        .low_parts(Some(&wl))
        .order(order)
        .build()?;
    Ok((0..points.len())
        .into_par_iter()
        .map(|g| {
            let mut set = vec![g];
            let mut frontier = vec![g];
            for _ in 0..RINGS {
                let mut next = Vec::new();
                for &a in &frontier {
                    for &b in regular.neighbors(a) {
                        let b = b as usize;
                        if !set.contains(&b) {
                            set.push(b);
                            next.push(b);
                        }
                    }
                }
                frontier = next;
            }
            set
        })
        .collect())
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::newton::solve_ot;
    use crate::synthetic::{disk_rings_measure, random_disk_points};
    use crate::OtSolution;

    /// The start takes a matching [`TargetCoarsening`]'s levels instead of coarsening itself,
    /// on every level: a hierarchy whose first level, or whose second level (below the
    /// 1,000-point level the recursion solves with it), was swapped for that of other masses
    /// changes the start (by 2e-2 and 1.6e-7 of the heights' size); the true one only by rounding
    /// (< 1e-12: it coarsens the masses as given, the solve the rescaled ones).
    #[test]
    fn a_matching_hierarchy_is_used_on_every_level() {
        let measure = disk_rings_measure(30, |x| if x[1] > 0.0 { 20.0 } else { 1.0 }).unwrap();
        let points = random_disk_points(8000, 3);
        let masses: Vec<f64> = (0..points.len()).map(|i| 1.0 + (i % 5) as f64).collect();
        let reversed: Vec<f64> = masses.iter().rev().copied().collect();
        let start = |coarsening: Option<TargetCoarsening>| {
            let params = NewtonParams {
                max_iterations: 0,
                start_strategy: crate::StartStrategy::CoarseToFine,
                target_coarsening: coarsening.map(Arc::new),
                ..NewtonParams::default()
            };
            solve_ot(&measure, &points, &masses, &params).unwrap()
        };
        // start heights up to a constant, relative to their size
        let gap = |a: &OtSolution, b: &OtSolution| {
            let d: Vec<f64> = (0..a.heights.len())
                .map(|i| (a.heights[i] + a.heights_lo[i]) - (b.heights[i] + b.heights_lo[i]))
                .collect();
            let mean = d.iter().sum::<f64>() / d.len() as f64;
            let size = b.heights.iter().fold(0.0f64, |m, h| m.max(h.abs()));
            d.iter().fold(0.0f64, |m, x| m.max((x - mean).abs())) / size
        };
        let own = start(None);
        let hierarchy = TargetCoarsening::new(&points, &masses);
        let sizes = hierarchy.level_sizes();
        assert!(sizes.len() >= 3 && sizes[1] >= MIN_FINE, "levels {sizes:?}");
        let same = start(Some(hierarchy));
        assert!(gap(&same, &own) < 1e-12, "{:e}", gap(&same, &own));
        let first = TargetCoarsening {
            coarse: TargetCoarsening::new(&points, &reversed).coarse,
            ..TargetCoarsening::new(&points, &masses)
        };
        assert!(first.matches(&points, &masses));
        let other = start(Some(first));
        assert!(gap(&other, &own) > 1e-4, "{:e}", gap(&other, &own));
        let mut second = TargetCoarsening::new(&points, &masses);
        let next = Arc::get_mut(&mut second.coarse.as_mut().unwrap().next).unwrap();
        let next_reversed: Vec<f64> = next.masses.iter().rev().copied().collect();
        next.coarse = TargetCoarsening::new(&next.points, &next_reversed).coarse;
        // (the second level only starts the first one's solve, which converges to nearly the
        // same heights from either start: 1.6e-7, still far above rounding)
        let other = start(Some(second));
        assert!(gap(&other, &own) > 1e-10, "{:e}", gap(&other, &own));
    }

    /// A level of at least `LARGE_LEVEL` points is merged to at most N/2 groups, a smaller one to
    /// at most N/4; a round at most halves the groups, so neither overshoots by more than 2×.
    /// Every point belongs to a group and the groups keep the total mass.
    #[test]
    fn large_levels_are_coarsened_to_half() {
        for (n, ratio) in [(LARGE_LEVEL, RATIO_LARGE), (LARGE_LEVEL - 1, RATIO)] {
            let points = random_disk_points(n, 7);
            let masses: Vec<f64> = (0..n).map(|i| 1.0 + (i % 3) as f64).collect();
            let c = coarsen(&points, &masses, None).unwrap();
            let m = c.points.len();
            assert!(m * ratio <= n && 2 * m * ratio > n, "{n} points → {m} groups");
            assert!(c.group.iter().all(|&g| g < m));
            let total: f64 = masses.iter().sum();
            assert!((c.masses.iter().sum::<f64>() - total).abs() <= 1e-12 * total);
        }
    }

    /// The inner disk's bound never changes a spread: `min_distance` equals the minimum with
    /// the distance over every edge, at points inside, near and outside Ω and with bisector
    /// distances d on either side of the boundary's, for the polygon inscribed in the unit circle
    /// (a disk map's Ω), for a long thin one and for that one moved 1e6 away (large coordinates).
    /// The bound lies below the distance; along the normal from the centre to the nearest edge it
    /// is tight, and there a d just above the distance must not be returned (the rounding
    /// margin). On the circle's polygon it skips the edges for nearly every point inside whose
    /// neighbours' bisectors are much nearer than ∂Ω (seen through a copy whose only edge lies
    /// far away: walked, it would give −1e6). Clockwise and two-vertex hulls never skip.
    #[test]
    fn the_inner_disk_bound_gives_the_distance_over_every_edge() {
        let circle: Vec<[f64; 2]> = (0..1361)
            .map(|k| {
                let a = std::f64::consts::TAU * (k as f64 + 0.3 * ((k * 7) % 5) as f64) / 1361.0;
                [a.cos(), a.sin()]
            })
            .collect();
        let thin = vec![[3.0, 2.0], [7.0, 2.1], [7.2, 2.4], [3.1, 2.3]];
        let far_thin: Vec<[f64; 2]> = thin.iter().map(|p| [p[0] + 1e6, p[1] - 1e6]).collect();
        let next_up = |v: f64| {
            if v > 0.0 {
                f64::from_bits(v.to_bits() + 1)
            } else {
                v + f64::MIN_POSITIVE
            }
        };
        for (hull, skips) in [(circle, true), (thin, false), (far_thin, false)] {
            let domain = DomainEdges::new(&hull);
            assert!(domain.inradius > 0.0);
            let far = DomainEdges {
                edges: vec![([[0.0, 1e6], [1.0, 1e6]], 1.0)],
                ..domain
            };
            let (lo, hi) = crate::polygon::bounding_box(&hull);
            let (mut inside, mut skipped) = (0, 0);
            let mut state = 7u64;
            let mut next = || crate::synthetic::uniform01(&mut state);
            let lower = |x: [f64; 2]| domain.inradius - (x[0] - domain.centre[0]).hypot(x[1] - domain.centre[1]);
            for _ in 0..20_000 {
                // points over the bounding box widened by a fifth, so some lie outside Ω
                let x = [
                    lo[0] - 0.2 * (hi[0] - lo[0]) + 1.4 * (hi[0] - lo[0]) * next(),
                    lo[1] - 0.2 * (hi[1] - lo[1]) + 1.4 * (hi[1] - lo[1]) * next(),
                ];
                let exact = domain.distance(x);
                assert!(
                    lower(x) <= exact + 1e-9 * domain.size,
                    "{x:?}: bound {} above {exact}",
                    lower(x)
                );
                for d in [
                    exact,
                    next_up(exact),
                    0.01 * exact,
                    2.0 * exact.abs() + 1e-3,
                    f64::INFINITY,
                ] {
                    assert_eq!(domain.min_distance(x, d), d.min(exact), "{x:?} {d}");
                }
                if exact > 0.0 {
                    inside += 1;
                    skipped += usize::from(far.min_distance(x, 0.01 * exact) == 0.01 * exact);
                }
            }
            assert!(inside > 1000);
            assert!(!skips || skipped * 10 > inside * 9, "{skipped} of {inside} skipped");
            // tight: from the centre towards the nearest edge, the bound equals the distance up
            // to rounding
            let (k, _) = domain
                .edges
                .iter()
                .enumerate()
                .map(|(k, e)| {
                    (
                        k,
                        DomainEdges {
                            edges: vec![*e],
                            ..domain
                        }
                        .distance(domain.centre),
                    )
                })
                .min_by(|a, b| a.1.total_cmp(&b.1))
                .unwrap();
            let ([a, b], length) = domain.edges[k];
            let normal = [(b[1] - a[1]) / length, -(b[0] - a[0]) / length];
            for t in [0.1, 0.5, 0.9, 0.999] {
                let x = [
                    domain.centre[0] + t * domain.inradius * normal[0],
                    domain.centre[1] + t * domain.inradius * normal[1],
                ];
                let exact = domain.distance(x);
                assert!(
                    (lower(x) - exact).abs() <= 1e-12 * domain.size,
                    "{t}: {} vs {exact}",
                    lower(x)
                );
                for d in [exact, next_up(exact)] {
                    assert_eq!(domain.min_distance(x, d), d.min(exact), "{t}: {d}");
                }
            }
        }
        // a clockwise polygon and a segment: no inner disk, the edges always walked
        let clockwise: Vec<[f64; 2]> = [[0.0, 0.0], [0.0, 1.0], [1.0, 1.0], [1.0, 0.0]].to_vec();
        for hull in [clockwise, vec![[0.0, 0.0], [1.0, 0.0]]] {
            let domain = DomainEdges::new(&hull);
            assert_eq!(domain.inradius, f64::NEG_INFINITY);
            assert_eq!(
                domain.min_distance([0.5, 0.5], 0.1),
                0.1f64.min(domain.distance([0.5, 0.5]))
            );
        }
    }
}
