//! The foldover-free untangling of the folds of g that the kernel moves leave (opt-in:
//! [`HarmonicParams::foldover_free`](super::HarmonicParams::foldover_free),
//! `register-bench --untangle-g foldover-free`): the untangling of Garanzha et al. 2021
//! ([`untangle_foldover_free`]) around the folds from g, else on the whole disk from φ₁, with
//! φ₁'s triangles as references. Measured in `docs/experiments.md`: every lion, horse and
//! remeshed wolf pair unfolded, 3 of 12 cat pairs, no centaur pair; off by default.

use serde::Serialize;
use shapespace_geometry::TriMesh;

use crate::fold_repair::{
    count_folded_faces, face_is_valid, grow_region, reference_equilateral, reference_from_layout,
    reference_from_surface, untangle_foldover_free, FoldoverFreeInfo, FoldoverFreeParams,
};

/// Rings of vertices around the folds of g that the local untangling of
/// `untangle_harmonic_folds` frees.
pub const UNTANGLE_RINGS: usize = 4;

/// Rounds (ε values) of each foldover-free untangling of g; the stall stop is off (the count
/// of folded faces drops only once ε is small, after tens of rounds).
pub const UNTANGLE_ROUNDS: usize = 100;

/// What `untangle_harmonic_folds` did: the local untangling of g around its folds, and the
/// whole-disk one from φ₁ when the local one left some.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct HarmonicUntangleInfo {
    /// The untangling of the vertices within [`UNTANGLE_RINGS`] rings of the folds, from g.
    pub local: FoldoverFreeInfo,
    /// The untangling of every interior vertex but the landmarks, from φ₁ (landmarks at their
    /// targets); `None` when the local one left no fold.
    pub global: Option<FoldoverFreeInfo>,
    /// Folded faces of g before and after.
    pub folded_before: usize,
    pub folded_after: usize,
}

/// The foldover-free untangling ([`untangle_foldover_free`]) of the vertices flagged `free` of
/// the map `x` (#V₁, changed in place when the untangling leaves fewer folds), every other
/// vertex fixed. Each face with a free corner takes its triangle in φ₁ (`phi1_uv`) as its
/// reference (the surface's triangle at its share of the disk where φ₁'s is not
/// counter-clockwise), all scaled by one factor so that their total area is the signed area of
/// those faces in `x`: that area is fixed by the fixed vertices, so det J averages 1, as in the
/// reference implementation's normalization. `None` when no vertex is free.
fn untangle_free_vertices(
    source: &TriMesh,
    phi1_uv: &[[f64; 2]],
    free: &[bool],
    x: &mut [[f64; 2]],
) -> Option<FoldoverFreeInfo> {
    let n = x.len();
    let ids: Vec<usize> = (0..source.faces.len())
        .filter(|&t| source.faces[t].iter().any(|&v| free[v as usize]))
        .collect();
    if ids.is_empty() {
        return None;
    }
    let mut local = vec![u32::MAX; n];
    let mut verts: Vec<u32> = Vec::new();
    for &t in &ids {
        for &v in &source.faces[t] {
            if local[v as usize] == u32::MAX {
                local[v as usize] = verts.len() as u32;
                verts.push(v);
            }
        }
    }
    let sub_faces: Vec<[u32; 3]> = ids
        .iter()
        .map(|&t| source.faces[t].map(|v| local[v as usize]))
        .collect();
    let fixed: Vec<bool> = verts.iter().map(|&v| !free[v as usize]).collect();
    let mut sub_uv: Vec<[f64; 2]> = verts.iter().map(|&v| x[v as usize]).collect();
    let areas = shapespace_geometry::quantities::face_areas(source);
    let total: f64 = areas.iter().sum();
    let doubled = |[a, b, c]: [[f64; 2]; 3]| (b[0] - a[0]) * (c[1] - a[1]) - (b[1] - a[1]) * (c[0] - a[0]);
    let mut reference: Vec<[[f64; 2]; 2]> = ids
        .iter()
        .map(|&t| {
            let f = &source.faces[t];
            let [p, q, r] = f.map(|v| phi1_uv[v as usize]);
            let share = areas[t] * std::f64::consts::PI / total;
            reference_from_layout(p, q, r)
                .or_else(|| reference_from_surface(f.map(|v| source.positions[v as usize]), share))
                .unwrap_or_else(|| reference_equilateral(share))
        })
        .collect();
    let signed: f64 = ids
        .iter()
        .map(|&t| 0.5 * doubled(source.faces[t].map(|v| x[v as usize])))
        .sum();
    let reference_area: f64 = reference
        .iter()
        .map(|r| 0.5 * (r[0][0] * r[1][1] - r[0][1] * r[1][0]))
        .sum();
    let k = (signed / reference_area).sqrt();
    if k.is_finite() && k > 0.0 {
        for r in &mut reference {
            *r = r.map(|e| e.map(|c| c * k));
        }
    }
    let params = FoldoverFreeParams {
        max_rounds: UNTANGLE_ROUNDS,
        stall_rounds: UNTANGLE_ROUNDS,
        ..Default::default()
    };
    let info = untangle_foldover_free(&sub_faces, &fixed, &reference, &mut sub_uv, &params).ok()?;
    for (k, &v) in verts.iter().enumerate() {
        x[v as usize] = sub_uv[k];
    }
    Some(info)
}

/// The folds of g (`uv`, #V₁) that the kernel moves left, untangled with the boundary and the
/// landmarks (`held`) fixed (`neighbors`: each vertex's neighbours in S₁), by the foldover-free untangling of Garanzha et al. 2021
/// (`untangle_free_vertices`, φ₁'s triangles as references):
/// 1. **local**: the vertices within [`UNTANGLE_RINGS`] rings of a folded face, from g;
/// 2. **global**, when folds are left: every vertex but the held ones, from φ₁ (`phi1_uv`) with
///    the landmarks at their targets. A folded g is a poor start: on lion poses a landmark drags
///    an inverted sheet of up to 6 % of the disk's area, which no ring of fixed vertices around
///    it leaves room to unfold and from which the barrier cannot escape even with the whole disk
///    free; φ₁ embeds, and only the landmarks' stars fold.
///
/// A result is kept only when no face stays folded; otherwise g is left as it was. `None` when
/// g has no folded face.
pub(super) fn untangle_harmonic_folds(
    source: &TriMesh,
    neighbors: &[Vec<u32>],
    phi1_uv: &[[f64; 2]],
    held: &[bool],
    uv: &mut [[f64; 2]],
) -> Option<HarmonicUntangleInfo> {
    let n = uv.len();
    let folded_before = count_folded_faces(&source.faces, uv);
    if folded_before == 0 {
        return None;
    }
    // the vertices within UNTANGLE_RINGS − 1 edges of a folded face's, but the held ones
    let seeds: Vec<usize> = source
        .faces
        .iter()
        .filter(|f| {
            let [a, b, c] = f.map(|v| uv[v as usize]);
            !face_is_valid(a, b, c)
        })
        .flat_map(|f| f.map(|v| v as usize))
        .collect();
    let mut free = vec![false; n];
    grow_region(neighbors, held, &seeds, UNTANGLE_RINGS - 1, &mut free);
    let mut local_uv = uv.to_vec();
    let local = untangle_free_vertices(source, phi1_uv, &free, &mut local_uv)?;
    let mut unfolded = (count_folded_faces(&source.faces, &local_uv) == 0).then_some(local_uv);
    let mut global = None;
    if unfolded.is_none() {
        let free: Vec<bool> = held.iter().map(|&h| !h).collect();
        let mut start: Vec<[f64; 2]> = (0..n).map(|v| if held[v] { uv[v] } else { phi1_uv[v] }).collect();
        global = untangle_free_vertices(source, phi1_uv, &free, &mut start);
        if count_folded_faces(&source.faces, &start) == 0 {
            unfolded = Some(start);
        }
    }
    let folded_after = match unfolded {
        Some(x) => {
            uv.copy_from_slice(&x);
            0
        }
        None => folded_before,
    };
    Some(HarmonicUntangleInfo {
        local,
        global,
        folded_before,
        folded_after,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The flat disk of 12 rings as φ₁ (ring k holds 6k vertices, the boundary last), with its
    /// boundary held.
    fn flat_disk() -> (TriMesh, Vec<[f64; 2]>, Vec<bool>) {
        let mesh = shapespace_geometry::primitives::unit_disk(12);
        let n = mesh.num_vertices();
        let phi1: Vec<[f64; 2]> = mesh.positions.iter().map(|p| [p[0], p[1]]).collect();
        let held: Vec<bool> = (0..n).map(|v| v >= n - 6 * 12).collect();
        (mesh, phi1, held)
    }

    fn neighbors(mesh: &TriMesh) -> Vec<Vec<u32>> {
        shapespace_geometry::Connectivity::of(mesh).vertex_neighbors(mesh.num_vertices())
    }

    /// The ring of vertex `v` of [`flat_disk`] (its radius times 12).
    fn ring(mesh: &TriMesh, v: usize) -> usize {
        (mesh.positions[v][0].hypot(mesh.positions[v][1]) * 12.0).round() as usize
    }

    /// g folded around the centre of the flat disk (the centre and two vertices of the first
    /// ring pushed through their neighbours) with a landmark held on ring 2: the local
    /// untangling leaves no face folded, keeps the boundary and the landmark, and moves no vertex
    /// beyond the freed rings; an unfolded map is left alone.
    #[test]
    fn harmonic_folds_are_untangled_near_them() {
        let (mesh, phi1, mut held) = flat_disk();
        let n = mesh.num_vertices();
        let mut untouched = phi1.clone();
        assert!(untangle_harmonic_folds(&mesh, &neighbors(&mesh), &phi1, &held, &mut untouched).is_none());
        assert_eq!(untouched, phi1);
        let landmark = (0..n).find(|&v| ring(&mesh, v) == 2).unwrap();
        held[landmark] = true;
        let mut g = phi1.clone();
        g[0] = [0.25, 0.02];
        g[1] = [-0.2, 0.05];
        g[3] = [0.1, -0.22];
        let folded_before = count_folded_faces(&mesh.faces, &g);
        assert!(folded_before >= 3, "{folded_before}");
        let input = g.clone();
        let info = untangle_harmonic_folds(&mesh, &neighbors(&mesh), &phi1, &held, &mut g).expect("folds to untangle");
        assert_eq!((info.folded_before, info.folded_after), (folded_before, 0), "{info:?}");
        assert_eq!(info.local.folded_after, 0, "{info:?}");
        assert!(info.global.is_none());
        assert_eq!(count_folded_faces(&mesh.faces, &g), 0);
        for v in 0..n {
            if held[v] {
                assert_eq!(g[v], input[v], "held vertex {v} moved");
            }
            // the folded faces' vertices lie within ring 2, so ring k is at least k − 2 rings
            // from them; the freed vertices are within UNTANGLE_RINGS − 1 rings
            if ring(&mesh, v) > UNTANGLE_RINGS + 1 {
                assert_eq!(g[v], input[v], "vertex {v} on ring {} moved", ring(&mesh, v));
            }
        }
    }

    /// A landmark of ring 4 pinned across the centre (0.55 away, about 7 rings): g is φ₁ with
    /// that one vertex moved, so its star folds over a sheet of neighbours. The untangling
    /// leaves no face folded (through the whole-disk stage when the rings around the folds do
    /// not suffice), with the boundary and the landmark where they were.
    #[test]
    fn a_far_landmark_is_untangled() {
        let (mesh, phi1, mut held) = flat_disk();
        let n = mesh.num_vertices();
        let landmark = (0..n).find(|&v| ring(&mesh, v) == 4).unwrap();
        held[landmark] = true;
        let mut g = phi1.clone();
        g[landmark] = [phi1[landmark][0] - 0.55, phi1[landmark][1] + 0.05];
        let folded_before = count_folded_faces(&mesh.faces, &g);
        assert!(folded_before >= 2, "{folded_before}");
        let input = g.clone();
        let info = untangle_harmonic_folds(&mesh, &neighbors(&mesh), &phi1, &held, &mut g).expect("folds to untangle");
        assert_eq!((info.folded_before, info.folded_after), (folded_before, 0), "{info:?}");
        assert_eq!(count_folded_faces(&mesh.faces, &g), 0);
        for v in (0..n).filter(|&v| held[v]) {
            assert_eq!(g[v], input[v], "held vertex {v} moved");
        }
    }
}
