//! What every disk construction shares ([`crate::disk_map()`] and [`crate::bff_disk_map`]):
//! the input checks (a disk, the interior joined to the center), the center's image, the
//! normalization of a raw map into the unit disk, its fold repair and its densities
//! ([`finish`]). Keeping them here lets the Green's-function construction fall back to BFF
//! without the two modules importing each other.

use shapespace_geometry::topology::{find, union};
use shapespace_geometry::TriMesh;

use crate::error::ConformalError;
use crate::fold_repair::local::{repair_folds, repair_folds_with_patches};
use crate::fold_repair::{FoldRepairInfo, FoldRepairParams};
use crate::intrinsic::IntrinsicTriangulation;
use crate::markers::{ResolvedCenter, ResolvedMarkers};
use crate::mobius::Mobius;
use crate::quality::{face_distortions, summarize, QualitySummary};

/// Smallest accepted 1 − |φ| ≈ 2πu at an interior vertex (boundary crowding limit): about 90
/// ulps of 1, so that the vertex stays distinguishable from the circle through the Möbius
/// normalization and the snapping of the boundary. The local shape of its image triangles then
/// keeps two to six significant digits (their masses, the 3D areas, are exact; their positions
/// are off by at most an ulp), and the exact orientation test still rejects any fold.
pub const CROWDING_LIMIT: f64 = 1e-14;

/// Interior edges with a negative cotangent weight.
pub(crate) fn count_negative(tri: &IntrinsicTriangulation) -> usize {
    (0..tri.tail.len() as u32)
        .filter(|&h| {
            let t = tri.twin[h as usize];
            t != crate::intrinsic::NONE && h < t && tri.edge_cotan_weight(h) < 0.0
        })
        .count()
}

/// Checks that the intrinsic triangulation is a single disk: one boundary loop, Euler
/// characteristic 1, one component, every vertex used.
pub(crate) fn check_disk(mesh: &TriMesh, tri: &IntrinsicTriangulation) -> Result<(), ConformalError> {
    let n = mesh.num_vertices();
    let nf = mesh.num_faces();
    if nf == 0 {
        return Err(ConformalError::NotDisk {
            reason: "the mesh has no faces".into(),
        });
    }
    let mut used = vec![false; n];
    for f in &mesh.faces {
        for &v in f {
            used[v as usize] = true;
        }
    }
    if let Some(v) = used.iter().position(|u| !u) {
        return Err(ConformalError::NotDisk {
            reason: format!("vertex {v} is not used by any face"),
        });
    }
    let nh = tri.tail.len();
    let nb = tri.twin.iter().filter(|&&t| t == crate::intrinsic::NONE).count();
    let ne = (nh + nb) / 2;
    let chi = n as i64 - ne as i64 + nf as i64;
    // components via union-find over vertices
    let mut parent: Vec<u32> = (0..n as u32).collect();
    for h in 0..nh as u32 {
        union(&mut parent, tri.tail[h as usize], tri.head(h));
    }
    let comps = (0..n as u32).filter(|&v| find(&mut parent, v) == v).count();
    // boundary loops: a boundary vertex with two boundary half-edges out of it would be
    // non-manifold; count loops by walking
    let mut out_b = vec![crate::intrinsic::NONE; n];
    for h in 0..nh {
        if tri.twin[h] == crate::intrinsic::NONE {
            let t = tri.tail[h] as usize;
            if out_b[t] != crate::intrinsic::NONE {
                return Err(ConformalError::NotDisk {
                    reason: format!("non-manifold boundary vertex {t}"),
                });
            }
            out_b[t] = h as u32;
        }
    }
    let mut seen = vec![false; n];
    let mut loops = 0;
    for v in 0..n {
        if out_b[v] != crate::intrinsic::NONE && !seen[v] {
            loops += 1;
            let mut x = v;
            while !seen[x] {
                seen[x] = true;
                x = tri.head(out_b[x]) as usize;
                if out_b[x] == crate::intrinsic::NONE {
                    break;
                }
            }
        }
    }
    if comps != 1 || loops != 1 || chi != 1 {
        return Err(ConformalError::NotDisk {
            reason: format!(
                "{comps} component(s), {loops} boundary loop(s), Euler characteristic {chi} (a disk has 1, 1, 1)"
            ),
        });
    }
    Ok(())
}

/// Boundary edges a → b (surface on the left) whose images turn clockwise around the origin
/// (arg(z_b / z_a) < 0): the boundary is out of order on the circle there, and the face at the
/// edge folds whatever the interior vertices do.
pub(crate) fn boundary_out_of_order(mesh: &TriMesh, uv: &[[f64; 2]]) -> usize {
    clockwise_edges(
        shapespace_geometry::Connectivity::of(mesh)
            .boundary_halfedges(&mesh.faces)
            .into_iter(),
        uv,
    )
}

/// How many of the directed edges a → b turn clockwise around the origin.
pub(crate) fn clockwise_edges(edges: impl Iterator<Item = [u32; 2]>, uv: &[[f64; 2]]) -> usize {
    edges
        .filter(|[a, b]| {
            let (p, q) = (uv[*a as usize], uv[*b as usize]);
            p[0] * q[1] - p[1] * q[0] < 0.0
        })
        .count()
}

/// The interior vertex the center marker stands on: its vertex, or for a point inside a face
/// the interior corner of largest barycentric weight (the pole of the Green's function at p,
/// and the vertex the interior is connected to by [`IntrinsicTriangulation::connect_interior`]).
pub(crate) fn center_vertex(
    mesh: &TriMesh,
    is_boundary: &[bool],
    center: ResolvedCenter,
) -> Result<u32, ConformalError> {
    match center {
        ResolvedCenter::Vertex(v) => Ok(v),
        ResolvedCenter::Face { face, bary } => {
            let corners = mesh.faces[face as usize];
            (0..3)
                .filter(|&k| !is_boundary[corners[k] as usize])
                .max_by(|&i, &j| bary[i].total_cmp(&bary[j]).then(j.cmp(&i)))
                .map(|k| corners[k])
                .ok_or_else(|| ConformalError::InvalidMarker(format!("face {face} has no interior corner")))
        }
    }
}

/// Vertex adjacency from the (unflipped) triangulation, each list sorted. Every edge is listed
/// from its half-edge whose twin comes later (or is missing, on the boundary), in both lists.
pub(crate) fn neighbors(tri: &IntrinsicTriangulation) -> Vec<Vec<u32>> {
    let mut degree = vec![0u32; tri.num_vertices];
    for h in 0..tri.tail.len() {
        if tri.twin[h] == crate::intrinsic::NONE || tri.twin[h] as usize > h {
            degree[tri.tail[h] as usize] += 1;
            degree[tri.head(h as u32) as usize] += 1;
        }
    }
    let mut adj: Vec<Vec<u32>> = degree.iter().map(|&d| Vec::with_capacity(d as usize)).collect();
    for h in 0..tri.tail.len() {
        if tri.twin[h] == crate::intrinsic::NONE || tri.twin[h] as usize > h {
            let (a, b) = (tri.tail[h], tri.head(h as u32));
            adj[a as usize].push(b);
            adj[b as usize].push(a);
        }
    }
    for l in &mut adj {
        l.sort_unstable();
        l.dedup();
    }
    adj
}

/// The image of the center marker under the vertex map z: z(p) for a vertex, the barycentric
/// interpolation for a point inside a face.
pub(crate) fn center_image(mesh: &TriMesh, center: ResolvedCenter, z: &[[f64; 2]]) -> [f64; 2] {
    match center {
        ResolvedCenter::Vertex(v) => z[v as usize],
        ResolvedCenter::Face { face, bary } => {
            let c = mesh.faces[face as usize];
            let mut s = [0.0, 0.0];
            for k in 0..3 {
                s[0] += bary[k] * z[c[k] as usize][0];
                s[1] += bary[k] * z[c[k] as usize][1];
            }
            s
        }
    }
}

/// A normalized disk map with its densities: the common last stage of every construction.
pub(crate) struct Finished {
    pub uv: Vec<[f64; 2]>,
    pub mobius: Mobius,
    pub conformal_factor: Vec<f64>,
    pub face_densities: Vec<f64>,
    pub scale: f64,
    pub quality: QualitySummary,
    pub fold_repairs: usize,
    pub region_repair: Option<FoldRepairInfo>,
}

/// The method name's note on a region repair: empty without one.
pub(crate) fn region_repair_note(info: Option<&FoldRepairInfo>) -> String {
    info.map_or(String::new(), |r| {
        format!(
            "; {} folded faces re-embedded as a Tutte map over {} vertices, {} moved: not conformal there",
            r.flipped_before + r.degenerate_before,
            r.region_vertices,
            r.vertices_moved
        )
    })
}

/// Whether a repaired map can be returned: every face counter-clockwise by the exact test and
/// every face density representable (a map whose orientations are all positive can still have
/// a face whose area underflows).
fn usable(dist: &crate::quality::FaceDistortions) -> bool {
    dist.orientation.iter().all(|&o| o > 0) && crate::quality::face_densities(&dist.area_distortion).is_ok()
}

/// `mobius` applied to every point of `z`, then the boundary vertices snapped to the circle,
/// the boundary marker put at 1 and a vertex center at 0 exactly (step 3 of the module docs).
fn normalized(z: &[[f64; 2]], mobius: &Mobius, is_boundary: &[bool], resolved: &ResolvedMarkers) -> Vec<[f64; 2]> {
    let mut uv: Vec<[f64; 2]> = z.iter().map(|&p| mobius.apply(p)).collect();
    for (v, p) in uv.iter_mut().enumerate() {
        if is_boundary[v] {
            let r = p[0].hypot(p[1]);
            *p = [p[0] / r, p[1] / r];
        }
    }
    uv[resolved.boundary_vertex as usize] = [1.0, 0.0];
    if let ResolvedCenter::Vertex(v) = resolved.center {
        uv[v as usize] = [0.0, 0.0];
    }
    uv
}

/// The Möbius map of the disk sending the center's image to 0 and the boundary marker's to 1;
/// for a center inside a face, iterated until the piecewise-linear image of p is 0 (to 1e-15).
fn normalizing_mobius(mesh: &TriMesh, resolved: &ResolvedMarkers, z: &[[f64; 2]]) -> Result<Mobius, ConformalError> {
    let a_img = center_image(mesh, resolved.center, z);
    if a_img[0].hypot(a_img[1]) >= 1.0 - 1e-12 {
        return Err(ConformalError::InvalidMarker(
            "the center maps onto the boundary circle".into(),
        ));
    }
    let q_img = z[resolved.boundary_vertex as usize];
    let mut mobius = Mobius::normalizing(a_img, q_img);
    if let ResolvedCenter::Face { face, bary } = resolved.center {
        // make the piecewise-linear image of p exactly 0: a ← M⁻¹(Σ_k b_k M(z_k))
        let c = mesh.faces[face as usize];
        for _ in 0..20 {
            let mut g = [0.0, 0.0];
            for k in 0..3 {
                let w = mobius.apply(z[c[k] as usize]);
                g[0] += bary[k] * w[0];
                g[1] += bary[k] * w[1];
            }
            if g[0].hypot(g[1]) < 1e-15 {
                break;
            }
            mobius = Mobius::normalizing(mobius.inverse().apply(g), q_img);
        }
    }
    Ok(mobius)
}

/// The normalized image with its face distortions, and what the fold repair did.
struct Image {
    uv: Vec<[f64; 2]>,
    dist: crate::quality::FaceDistortions,
    mobius: Mobius,
    fold_repairs: usize,
    region: Option<FoldRepairInfo>,
    region_error: Option<String>,
}

/// Repairs the folds of `image`: local moves with the boundary and the center fixed; then, with
/// `region_repair` and folds left, a Tutte re-embedding of the folded region (the center pinned,
/// else with only the boundary fixed and a Möbius map back to p ↦ 0), else the local repair
/// again with unbounded patches (scattered slivers). A repair is kept only where its image is
/// usable.
fn repair_image(
    mesh: &TriMesh,
    is_boundary: &[bool],
    resolved: &ResolvedMarkers,
    region_repair: bool,
    image: &mut Image,
) -> Result<(), ConformalError> {
    let mut vertex_faces = vec![Vec::new(); mesh.num_vertices()];
    for (f, face) in mesh.faces.iter().enumerate() {
        for &v in face {
            vertex_faces[v as usize].push(f as u32);
        }
    }
    let mut fixed = is_boundary.to_vec();
    if let ResolvedCenter::Vertex(v) = resolved.center {
        fixed[v as usize] = true;
    }
    if let ResolvedCenter::Face { face, .. } = resolved.center {
        // the face containing p keeps its corners so that p still maps to 0
        for &v in &mesh.faces[face as usize] {
            fixed[v as usize] = true;
        }
    }
    let angles = shapespace_geometry::quantities::corner_angles(mesh);
    let unrepaired = image.uv.clone();
    image.fold_repairs = repair_folds(&mesh.faces, &vertex_faces, &angles, &fixed, &mut image.uv);
    image.dist = face_distortions(mesh, &image.uv)?;
    if region_repair && image.dist.orientation.iter().any(|&o| o <= 0) {
        // the markers stay where they are: they are fixed like the boundary
        let mut repaired = image.uv.clone();
        match crate::fold_repair::repair_folds(mesh, &fixed, &mut repaired, &FoldRepairParams::default()) {
            Ok(info) => {
                let repaired_dist = face_distortions(mesh, &repaired)?;
                let left = repaired_dist.orientation.iter().filter(|&&o| o <= 0).count();
                if usable(&repaired_dist) {
                    image.uv = repaired;
                    image.dist = repaired_dist;
                    image.region = Some(info);
                } else if left == 0 {
                    image.region_error = Some(format!(
                        "a face of the re-embedded region has an area below the f64 range (its rings: {} vertices)",
                        info.region_vertices
                    ));
                } else {
                    image.region_error = Some(format!(
                        "{left} faces fold by the map's own orientation test after it (its rings: {} vertices)",
                        info.region_vertices
                    ));
                }
            }
            Err(e) => image.region_error = Some(e.to_string()),
        }
        // (a center inside a face stays pinned: a Möbius map would not keep its
        // piecewise-linear image at 0)
        if image.region.is_none() && matches!(resolved.center, ResolvedCenter::Vertex(_)) {
            // a pinned center can lie outside the kernel of its neighbours in the Tutte map
            // (Floater's theorem holds for the boundary alone): repair with the boundary
            // fixed only, then move the center back to 0 by a Möbius map of the disk
            let mut repaired = image.uv.clone();
            // (when this fails too, the pinned attempt's error is the one reported)
            if let Ok(info) =
                crate::fold_repair::repair_folds(mesh, is_boundary, &mut repaired, &FoldRepairParams::default())
            {
                let a = center_image(mesh, resolved.center, &repaired);
                let renormalize = Mobius::normalizing(a, repaired[resolved.boundary_vertex as usize]);
                let repaired = normalized(&repaired, &renormalize, is_boundary, resolved);
                let repaired_dist = face_distortions(mesh, &repaired)?;
                if usable(&repaired_dist) {
                    image.uv = repaired;
                    image.dist = repaired_dist;
                    image.mobius = renormalize.compose(&image.mobius);
                    image.region = Some(info);
                }
            }
        }
        if image.region.is_none() {
            // scattered slivers rather than a folded region: the local repair again, with
            // patches without the bound that keeps them from grinding through a folded region
            let mut repaired = unrepaired;
            let moves =
                repair_folds_with_patches(&mesh.faces, &vertex_faces, &angles, &fixed, &mut repaired, usize::MAX);
            let repaired_dist = face_distortions(mesh, &repaired)?;
            if usable(&repaired_dist) {
                image.uv = repaired;
                image.dist = repaired_dist;
                image.fold_repairs = moves;
                image.region_error = None;
            }
        }
    }
    Ok(())
}

/// Steps 3–5 of the module docs for any map z (#V) of the mesh into the closed unit disk with
/// the boundary on the circle: the Möbius normalization p ↦ 0, q ↦ 1 (a fixed-point iteration
/// for a barycentric p), boundary vertices snapped to |z| = 1, fold repair (if `repair`: local,
/// then with `region_repair` a Tutte re-embedding of the region around the folds that remain,
/// retried with only the boundary fixed and a Möbius map back to p ↦ 0 when the pinned center
/// keeps it from unfolding),
/// densities and conformal factors on the original faces.
///
/// Errors: the center's image on the circle, a fold left after the repair, a density beyond
/// the f64 range, a non-finite conformal factor.
pub(crate) fn finish(
    mesh: &TriMesh,
    is_boundary: &[bool],
    resolved: &ResolvedMarkers,
    z: &[[f64; 2]],
    repair: bool,
    region_repair: bool,
) -> Result<Finished, ConformalError> {
    let mobius = normalizing_mobius(mesh, resolved, z)?;
    let uv = normalized(z, &mobius, is_boundary, resolved);
    // densities and factors on the original faces; fold repair first if needed (crate::fold_repair::local)
    let mut image = Image {
        dist: face_distortions(mesh, &uv)?,
        uv,
        mobius,
        fold_repairs: 0,
        region: None,
        region_error: None,
    };
    if repair && image.dist.orientation.iter().any(|&o| o <= 0) {
        repair_image(mesh, is_boundary, resolved, region_repair, &mut image)?;
    }
    let Image {
        uv,
        mobius,
        dist,
        fold_repairs,
        region,
        region_error,
    } = image;
    let areas = shapespace_geometry::quantities::face_areas(mesh);
    let total: f64 = areas.iter().sum();
    let scale = (std::f64::consts::PI / total).sqrt();
    let summary = summarize(&dist, &areas);
    if summary.num_flipped + summary.num_degenerate > 0 {
        let first = dist.orientation.iter().position(|&o| o <= 0).unwrap_or(0);
        return Err(ConformalError::FoldedImage {
            num_flipped: summary.num_flipped + summary.num_degenerate,
            first_face: first,
            flipped_area_fraction: summary.flipped_area_fraction,
            boundary_out_of_order: boundary_out_of_order(mesh, &uv),
            bff_fallback_error: None,
            region_repair_error: region_error,
        });
    }
    let face_densities = crate::quality::face_densities(&dist.area_distortion)?;
    let conformal_factor = crate::quality::vertex_conformal_factors(mesh, &areas, scale, &dist.area_distortion)?;
    Ok(Finished {
        uv,
        mobius,
        conformal_factor,
        face_densities,
        scale,
        quality: summary,
        fold_repairs,
        region_repair: region,
    })
}
