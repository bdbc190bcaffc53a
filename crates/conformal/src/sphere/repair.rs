//! Fold repair on the sphere: the disk's local repair ([`crate::fold_repair::local`]) in a stereographic
//! chart centred on each cluster of folded faces.
//!
//! The conformal map is computed at the vertices and interpolated on the ORIGINAL faces; as in
//! the plane, slivers (angles of 155°–170° on TOSCA centaur0) whose images hinge on a few
//! percent of their edge length can fold. Each cluster (folded faces whose images lie within
//! 0.3 rad of the first one's) is rotated to the south pole and projected by the orientation-
//! preserving stereographic chart x ↦ (x₁, −x₂)/(1 − x₃), where a patch of a few rings is
//! nearly flat and nearly undistorted; the disk's repair moves free vertices of its folded faces
//! (the patch's outer ring and the markers stay fixed), and the moved vertices go back to S².

use rayon::prelude::*;
use shapespace_geometry::TriMesh;

use super::quality::orientation_on_sphere;

/// Rings of faces around a fold cluster handed to the planar repair.
const PATCH_RINGS: usize = 10;
/// Clusters repaired at most.
const MAX_CLUSTERS: usize = 64;

fn folded(mesh: &TriMesh, x: &[[f64; 3]]) -> Vec<usize> {
    (0..mesh.num_faces())
        .into_par_iter()
        .filter(|&f| {
            let [a, b, c] = mesh.faces[f];
            orientation_on_sphere(x[a as usize], x[b as usize], x[c as usize]) <= 0
        })
        .collect()
}

/// A rotation (rows) taking the unit vector c to the south pole (0, 0, −1).
pub fn rotation_to_south(c: [f64; 3]) -> [[f64; 3]; 3] {
    let e3 = c.map(|x| -x);
    let t = if e3[0].abs() < 0.9 {
        [1.0, 0.0, 0.0]
    } else {
        [0.0, 1.0, 0.0]
    };
    let d = t[0] * e3[0] + t[1] * e3[1] + t[2] * e3[2];
    let p = [t[0] - d * e3[0], t[1] - d * e3[1], t[2] - d * e3[2]];
    let l = (p[0] * p[0] + p[1] * p[1] + p[2] * p[2]).sqrt();
    let e1 = p.map(|x| x / l);
    let e2 = [
        e3[1] * e1[2] - e3[2] * e1[1],
        e3[2] * e1[0] - e3[0] * e1[2],
        e3[0] * e1[1] - e3[1] * e1[0],
    ];
    [e1, e2, e3]
}

/// The orientation-preserving stereographic chart of S² centred at the point that `rot`
/// ([`rotation_to_south`]) takes to the south pole: `rot`, then (x₁, −x₂)/(1 − x₃).
pub fn to_chart(rot: &[[f64; 3]; 3], p: [f64; 3]) -> [f64; 2] {
    let q = rot.map(|r| r[0] * p[0] + r[1] * p[1] + r[2] * p[2]);
    [q[0] / (1.0 - q[2]), -q[1] / (1.0 - q[2])]
}

/// The inverse of [`to_chart`]: the point of S² at chart position `uv`.
pub fn from_chart(rot: &[[f64; 3]; 3], uv: [f64; 2]) -> [f64; 3] {
    let (a, b) = (uv[0], -uv[1]);
    let r2 = a * a + b * b;
    let q = [2.0 * a / (1.0 + r2), 2.0 * b / (1.0 + r2), (r2 - 1.0) / (r2 + 1.0)];
    [0, 1, 2].map(|k| rot[0][k] * q[0] + rot[1][k] * q[1] + rot[2][k] * q[2])
}

/// Repairs folded faces of a map `x` (#V) of the mesh onto S² in place (module docs): the
/// conformal sphere map, and the area-preserving sphere map of the analysis crate; `fixed` (#V)
/// vertices never move. Returns the number of vertex moves; folds that could not be repaired
/// remain (the caller checks again).
pub fn repair_sphere_folds(mesh: &TriMesh, x: &mut [[f64; 3]], fixed: &[bool]) -> usize {
    let mut bad = folded(mesh, x);
    if bad.is_empty() {
        return 0;
    }
    let angles = shapespace_geometry::quantities::corner_angles(mesh);
    let mut vertex_faces = vec![Vec::new(); mesh.num_vertices()];
    for (f, face) in mesh.faces.iter().enumerate() {
        for &v in face {
            vertex_faces[v as usize].push(f as u32);
        }
    }
    let mut moves = 0;
    let mut skipped: Vec<usize> = Vec::new();
    for _ in 0..MAX_CLUSTERS {
        let Some(&f0) = bad.iter().find(|f| !skipped.contains(f)) else {
            break;
        };
        let centroid = |f: usize| {
            let mut c = [0.0; 3];
            for &v in &mesh.faces[f] {
                for k in 0..3 {
                    c[k] += x[v as usize][k];
                }
            }
            let l = (c[0] * c[0] + c[1] * c[1] + c[2] * c[2]).sqrt();
            c.map(|t| t / l)
        };
        let c0 = centroid(f0);
        let cluster: Vec<usize> = bad
            .iter()
            .copied()
            .filter(|&f| {
                let c = centroid(f);
                c[0] * c0[0] + c[1] * c0[1] + c[2] * c0[2] > 0.3f64.cos()
            })
            .collect();
        // the patch: PATCH_RINGS rings of faces around the cluster
        let mut in_patch = vec![false; mesh.num_faces()];
        let mut patch: Vec<usize> = Vec::new();
        for &f in &cluster {
            if !in_patch[f] {
                in_patch[f] = true;
                patch.push(f);
            }
        }
        let mut front = patch.clone();
        for _ in 0..PATCH_RINGS {
            let mut next = Vec::new();
            for &f in &front {
                for &v in &mesh.faces[f] {
                    for &g in &vertex_faces[v as usize] {
                        if !in_patch[g as usize] {
                            in_patch[g as usize] = true;
                            next.push(g as usize);
                        }
                    }
                }
            }
            patch.extend_from_slice(&next);
            front = next;
        }
        // local vertices; a vertex with a face outside the patch is fixed
        let mut local = std::collections::HashMap::new();
        let mut verts: Vec<u32> = Vec::new();
        for &f in &patch {
            for &v in &mesh.faces[f] {
                local.entry(v).or_insert_with(|| {
                    verts.push(v);
                    verts.len() as u32 - 1
                });
            }
        }
        let rot = rotation_to_south(c0);
        let mut uv: Vec<[f64; 2]> = verts.iter().map(|&v| to_chart(&rot, x[v as usize])).collect();
        let local_fixed: Vec<bool> = verts
            .iter()
            .map(|&v| fixed[v as usize] || vertex_faces[v as usize].iter().any(|&g| !in_patch[g as usize]))
            .collect();
        let local_faces: Vec<[u32; 3]> = patch.iter().map(|&f| mesh.faces[f].map(|v| local[&v])).collect();
        let local_angles: Vec<[f64; 3]> = patch.iter().map(|&f| angles[f]).collect();
        let mut local_vf = vec![Vec::new(); verts.len()];
        for (f, face) in local_faces.iter().enumerate() {
            for &v in face {
                local_vf[v as usize].push(f as u32);
            }
        }
        let before = uv.clone();
        let m = crate::fold_repair::local::repair_folds(&local_faces, &local_vf, &local_angles, &local_fixed, &mut uv);
        if m == 0 {
            skipped.extend_from_slice(&cluster);
            continue;
        }
        moves += m;
        for (i, &v) in verts.iter().enumerate() {
            if uv[i] != before[i] {
                x[v as usize] = from_chart(&rot, uv[i]);
            }
        }
        bad = folded(mesh, x);
        if bad.is_empty() {
            break;
        }
    }
    moves
}
