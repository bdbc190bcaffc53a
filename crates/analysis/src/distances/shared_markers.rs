//! Automatic markers chosen once for the files that share one connectivity.
//!
//! A set of meshes with the same vertex count and the same faces (the expressions of one face,
//! the poses of one body) is in vertex-to-vertex correspondence. Resolved on each file alone,
//! the automatic markers ([`shapespace_conformal::markers`]: the vertex farthest from the
//! boundary, the boundary vertex farthest from it) can land on different vertices, and the
//! conformal Wasserstein distance depends on the markers: one file's boundary marker off by a
//! few centimetres gives distances several times the others'. So automatic markers are resolved
//! once per such group, on the group's mean shape (the mean of the vertex positions, the
//! template a set of expressions deforms), and every file of the group gets the same vertex
//! indices. The choice does not depend on the order of the files. Where the mean shape cannot
//! be mapped (degenerate mean faces, e.g. meshes in unrelated frames), the group's file with the
//! smallest name decides.

use std::collections::HashMap;

use shapespace_conformal::markers::ResolvedCenter;
use shapespace_conformal::{resolve_markers_of, BoundaryMarker, CenterMarker, Markers};
use shapespace_geometry::TriMesh;

/// One file as [`share_auto_markers`] reads it.
pub struct MarkerInput<'a> {
    /// Shape name (unique in the run; orders the fallback choice).
    pub name: &'a str,
    pub mesh: &'a TriMesh,
    pub markers: &'a Markers,
}

/// The markers a file gets from its group, and a note on how they were chosen.
#[derive(Clone, Debug, PartialEq)]
pub struct SharedMarkers {
    pub markers: Markers,
    /// E.g. "shared by the 9 files with these faces (resolved on their mean shape)".
    pub note: String,
}

/// True when the markers have an automatic part whose resolution depends only on the mesh and
/// on index-based markers (a center given as a point in space is resolved per file).
fn shareable(m: &Markers) -> bool {
    let auto = matches!(m.center, CenterMarker::Auto) || matches!(m.boundary, BoundaryMarker::Auto);
    auto && !matches!(m.center, CenterMarker::Point(_))
}

/// For every group of at least two files with the same vertex count, the same faces and the
/// same marker settings, with automatic markers: one choice made on the group's mean shape
/// (module docs), given to each of its files (`Some`); `None` for the other files, which keep
/// their own markers.
pub fn share_auto_markers(inputs: &[MarkerInput<'_>]) -> Vec<Option<SharedMarkers>> {
    let mut out = vec![None; inputs.len()];
    let mut groups: HashMap<(usize, u64), Vec<usize>> = HashMap::new();
    for (i, input) in inputs.iter().enumerate() {
        if shareable(input.markers) {
            groups
                .entry((input.mesh.num_vertices(), faces_hash(&input.mesh.faces)))
                .or_default()
                .push(i);
        }
    }
    for mut rest in groups.into_values() {
        // exact equality of faces and markers within the hash group
        while let Some(&first) = rest.first() {
            let (same, other): (Vec<usize>, Vec<usize>) = rest.iter().partition(|&&j| {
                inputs[j].mesh.same_triangulation(inputs[first].mesh) && inputs[j].markers == inputs[first].markers
            });
            rest = other;
            if same.len() < 2 {
                continue;
            }
            if let Some((resolved, how)) = resolve_for_group(inputs, &same) {
                let center = match resolved.center {
                    ResolvedCenter::Vertex(v) => CenterMarker::Vertex(v),
                    ResolvedCenter::Face { face, bary } => CenterMarker::Barycentric { face, bary },
                };
                let shared = SharedMarkers {
                    markers: Markers {
                        center,
                        boundary: BoundaryMarker::Vertex(resolved.boundary_vertex),
                    },
                    note: format!("shared by the {} files with these faces ({how})", same.len()),
                };
                for &j in &same {
                    out[j] = Some(shared.clone());
                }
            }
        }
    }
    out
}

/// The unit 3D direction from the center marker (a vertex, or a point in a face) to the boundary
/// marker; `None` when they coincide.
pub fn marker_axis(mesh: &TriMesh, markers: &shapespace_conformal::markers::ResolvedMarkers) -> Option<[f64; 3]> {
    let p = |v: u32| mesh.positions[v as usize];
    let center = match markers.center {
        ResolvedCenter::Vertex(v) => p(v),
        ResolvedCenter::Face { face, bary } => {
            let f = mesh.faces[face as usize];
            let mut c = [0.0; 3];
            for k in 0..3 {
                for d in 0..3 {
                    c[d] += bary[k] * p(f[k])[d];
                }
            }
            c
        }
    };
    let q = p(markers.boundary_vertex);
    let a = [q[0] - center[0], q[1] - center[1], q[2] - center[2]];
    let len = (a[0] * a[0] + a[1] * a[1] + a[2] * a[2]).sqrt();
    (len > 0.0 && len.is_finite()).then(|| [a[0] / len, a[1] / len, a[2] / len])
}

/// Angle beyond which [`marker_outliers`] flags a file, degrees.
pub const MARKER_OUTLIER_DEGREES: f64 = 45.0;

/// Files whose automatic markers differ strongly from the rest, for sets of different
/// connectivity (where [`share_auto_markers`] cannot make them agree): the angle between a
/// file's marker axis ([`marker_axis`]) and the medoid axis (the one with the largest sum of
/// cosines to all others, so that one stray file does not move the reference), flagged above
/// [`MARKER_OUTLIER_DEGREES`], with at least three files. The measure assumes the files share a
/// frame (scans of one device, one template's expressions): it says that the boundary marker sits
/// on another side of the face than the others', which gives that file's distances a rotation
/// the others do not have. Returns (name, degrees).
pub fn marker_outliers<'a>(axes: &[(&'a str, [f64; 3])]) -> Vec<(&'a str, f64)> {
    if axes.len() < 3 {
        return Vec::new();
    }
    let dot = |a: &[f64; 3], b: &[f64; 3]| a[0] * b[0] + a[1] * b[1] + a[2] * b[2];
    let medoid = (0..axes.len())
        .max_by(|&i, &j| {
            let score = |k: usize| axes.iter().map(|(_, a)| dot(a, &axes[k].1)).sum::<f64>();
            score(i).total_cmp(&score(j)).then(j.cmp(&i))
        })
        .expect("at least three axes");
    axes.iter()
        .filter_map(|(name, a)| {
            let degrees = dot(a, &axes[medoid].1).clamp(-1.0, 1.0).acos().to_degrees();
            (degrees > MARKER_OUTLIER_DEGREES).then_some((*name, degrees))
        })
        .collect()
}

/// The markers of the group on its mean shape, else on its file with the smallest name.
fn resolve_for_group(
    inputs: &[MarkerInput<'_>],
    group: &[usize],
) -> Option<(shapespace_conformal::markers::ResolvedMarkers, String)> {
    let first = inputs[group[0]].mesh;
    let mut mean = vec![[0.0f64; 3]; first.num_vertices()];
    for &j in group {
        for (m, p) in mean.iter_mut().zip(&inputs[j].mesh.positions) {
            for d in 0..3 {
                m[d] += p[d];
            }
        }
    }
    let k = group.len() as f64;
    for m in &mut mean {
        for x in m.iter_mut() {
            *x /= k;
        }
    }
    let markers = inputs[group[0]].markers;
    if let Ok(mesh) = TriMesh::new(mean, first.faces.clone()) {
        if let Ok(r) = resolve_markers_of(&mesh, markers) {
            return Some((r, "resolved on their mean shape".to_string()));
        }
    }
    let j = *group.iter().min_by(|&&a, &&b| inputs[a].name.cmp(inputs[b].name))?;
    resolve_markers_of(inputs[j].mesh, markers)
        .ok()
        .map(|r| (r, format!("resolved on {}", inputs[j].name)))
}

fn faces_hash(faces: &[[u32; 3]]) -> u64 {
    use std::hash::{Hash, Hasher};
    let mut h = std::collections::hash_map::DefaultHasher::new();
    faces.hash(&mut h);
    h.finish()
}

#[cfg(test)]
mod tests {
    use super::*;
    use shapespace_geometry::primitives::unit_disk;

    /// Bends a disk by z = a·x² + b·y (a different shape, the same connectivity).
    fn bent(a: f64, b: f64) -> TriMesh {
        let mut m = unit_disk(6);
        for p in &mut m.positions {
            p[2] = a * p[0] * p[0] + b * p[1];
        }
        m
    }

    #[test]
    fn files_with_one_connectivity_get_one_choice_whatever_their_order() {
        let meshes = [bent(0.0, 0.0), bent(0.6, 0.1), bent(-0.4, 0.3), bent(0.2, -0.5)];
        let names = ["a", "b", "c", "d"];
        let auto = Markers::default();
        let run = |order: &[usize]| {
            let inputs: Vec<MarkerInput> = order
                .iter()
                .map(|&i| MarkerInput {
                    name: names[i],
                    mesh: &meshes[i],
                    markers: &auto,
                })
                .collect();
            let mut out: Vec<(&str, SharedMarkers)> = order
                .iter()
                .zip(share_auto_markers(&inputs))
                .map(|(&i, s)| (names[i], s.expect("shared")))
                .collect();
            out.sort_by(|x, y| x.0.cmp(y.0));
            out
        };
        let forward = run(&[0, 1, 2, 3]);
        assert_eq!(forward, run(&[3, 1, 0, 2]));
        for (_, shared) in &forward {
            assert_eq!(*shared, forward[0].1);
            assert!(
                matches!(shared.markers.boundary, BoundaryMarker::Vertex(_)),
                "{shared:?}"
            );
            assert!(shared.note.contains("shared by the 4 files"), "{}", shared.note);
        }
        // files resolved alone do not all agree here, which is what sharing is for
        let alone: Vec<_> = meshes
            .iter()
            .map(|m| resolve_markers_of(m, &Markers::default()).unwrap().boundary_vertex)
            .collect();
        assert!(alone.iter().any(|&q| q != alone[0]), "{alone:?}");
    }

    #[test]
    fn a_file_whose_marker_axis_points_elsewhere_is_flagged() {
        let axes = [
            ("a", [1.0, 0.0, 0.0]),
            ("b", [0.96, 0.28, 0.0]),
            ("c", [0.96, -0.28, 0.0]),
            ("d", [0.0, 1.0, 0.0]),
        ];
        let flagged = marker_outliers(&axes);
        assert_eq!(flagged.len(), 1, "{flagged:?}");
        assert_eq!(flagged[0].0, "d");
        // against the medoid b: a 16°, c 33°, d 74°
        assert!((flagged[0].1 - 73.7).abs() < 0.1, "{flagged:?}");
        assert!(marker_outliers(&axes[..3]).is_empty());
        assert!(marker_outliers(&axes[..2]).is_empty());
    }

    #[test]
    fn explicit_markers_different_faces_and_single_files_are_left_alone() {
        let (a, b) = (bent(0.3, 0.0), bent(0.1, 0.2));
        let c = unit_disk(5);
        let given = Markers {
            center: CenterMarker::Vertex(0),
            boundary: BoundaryMarker::Vertex(a.num_vertices() as u32 - 1),
        };
        let auto = Markers::default();
        let inputs = vec![
            MarkerInput {
                name: "a",
                mesh: &a,
                markers: &given,
            },
            MarkerInput {
                name: "b",
                mesh: &b,
                markers: &given,
            },
            MarkerInput {
                name: "c",
                mesh: &c,
                markers: &auto,
            },
        ];
        assert_eq!(share_auto_markers(&inputs), vec![None, None, None]);
    }
}
