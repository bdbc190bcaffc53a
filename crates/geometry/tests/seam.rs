//! Seam cuts (`geometry::seam`): a closed sphere and a flat disk cut open along edge trees, the
//! counts the cut must produce, the geometry it must keep, the extremities it finds on shapes
//! whose tips are known, and its errors.

use shapespace_geometry::connectivity::Connectivity;
use shapespace_geometry::prepare::{self, PrepareOptions};
use shapespace_geometry::primitives::{capped_tube, grid, icosphere, unit_disk};
use shapespace_geometry::quantities::total_area;
use shapespace_geometry::seam::{cut_along_seam, extremities, seam_tree};
use shapespace_geometry::topology::require_disk;
use shapespace_geometry::TriMesh;

/// Seam degree of every vertex.
fn degrees(n: usize, seam: &[[u32; 2]]) -> Vec<usize> {
    let mut d = vec![0; n];
    for e in seam {
        d[e[0] as usize] += 1;
        d[e[1] as usize] += 1;
    }
    d
}

/// The cut keeps every face's corner positions, the area and the face count, and each new
/// vertex copies the position of the input vertex it names.
fn assert_same_geometry(input: &TriMesh, cut: &TriMesh, origin: &[u32]) {
    assert_eq!(cut.num_faces(), input.num_faces());
    assert_eq!(origin.len(), cut.num_vertices());
    for (f, (a, b)) in input.faces.iter().zip(&cut.faces).enumerate() {
        for k in 0..3 {
            assert_eq!(origin[b[k] as usize], a[k], "face {f} corner {k}");
        }
    }
    for (v, &o) in origin.iter().enumerate() {
        assert_eq!(cut.positions[v], input.positions[o as usize]);
    }
    assert_eq!(total_area(cut), total_area(input));
}

/// An ellipsoid-like sphere stretched 4× along x: its first two farthest-point extremities lie
/// at the two tips (±4, 0, 0) (within the edge-path metric's error: |x| ≥ 3.8, a third of the
/// minor radius from the tip along the surface), and a seam through them and a third extremity opens it into a disk with one
/// copy per extra wedge at every seam vertex and a boundary twice the seam long.
#[test]
fn closed_sphere_opens_along_a_tree() {
    let mut m = icosphere(3);
    for p in &mut m.positions {
        p[0] *= 4.0;
    }
    let tips = extremities(&m, 3).unwrap();
    assert_eq!(tips.len(), 3);
    let mut xs: Vec<f64> = tips[..2].iter().map(|&t| m.positions[t as usize][0]).collect();
    xs.sort_by(f64::total_cmp);
    assert!(
        xs[0] <= -3.8 && xs[1] >= 3.8,
        "the first two extremities are the tips: {xs:?}"
    );
    let seam = seam_tree(&m, &tips).unwrap();
    let d = degrees(m.num_vertices(), &seam);
    // a tree: one vertex more than edges
    assert_eq!(d.iter().filter(|&&x| x > 0).count(), seam.len() + 1);
    assert!(d.contains(&3), "three terminals off one path meet at a junction");
    let (cut, origin) = cut_along_seam(&m, &seam).unwrap();
    require_disk(&cut).unwrap();
    let added: usize = d.iter().map(|&x| x.saturating_sub(1)).sum();
    assert_eq!(cut.num_vertices(), m.num_vertices() + added);
    let loops = Connectivity::of(&cut).boundary_loops(&cut.faces);
    assert_eq!(loops.len(), 1);
    assert_eq!(loops[0].len(), 2 * seam.len());
    assert_same_geometry(&m, &cut, &origin);
}

/// The flat disk: the extremity is its centre (farthest from the boundary), the seam a path
/// from it to the circle; the slit adds one vertex per interior path vertex and one at the
/// boundary end, and lengthens the boundary by twice the path.
#[test]
fn disk_slit_from_its_centre() {
    let m = unit_disk(8);
    let tips = extremities(&m, 1).unwrap();
    assert_eq!(tips, vec![0], "the centre is farthest from the boundary");
    let seam = seam_tree(&m, &tips).unwrap();
    assert_eq!(seam.len(), 8, "eight rings from the centre to the circle");
    let (cut, origin) = cut_along_seam(&m, &seam).unwrap();
    require_disk(&cut).unwrap();
    // path vertices: the centre (a leaf, not split), 7 interior ones (degree 2: +1 each), one on
    // the boundary (degree 1: its open fan splits in two, +1)
    assert_eq!(cut.num_vertices(), m.num_vertices() + 8);
    let before = Connectivity::of(&m).boundary_loops(&m.faces)[0].len();
    let loops = Connectivity::of(&cut).boundary_loops(&cut.faces);
    assert_eq!(loops.len(), 1);
    assert_eq!(loops[0].len(), before + 2 * seam.len());
    assert_same_geometry(&m, &cut, &origin);
    // every cut face still has positive orientation in the plane
    for f in &cut.faces {
        let [a, b, c] = f.map(|v| cut.positions[v as usize]);
        assert!((b[0] - a[0]) * (c[1] - a[1]) - (b[1] - a[1]) * (c[0] - a[0]) > 0.0);
    }
}

/// `prepare_disk` with a seam: the tube's extremity is the cap centre, the slit runs to the open
/// end, the report counts it and the vertex map sends every copy to its input vertex.
#[test]
fn prepare_disk_with_a_seam() {
    let tube = capped_tube(1.0, 6.0, 4, 24);
    let (disk, origin, report) = prepare::prepare_disk(
        &tube,
        &PrepareOptions {
            seam_extremities: 1,
            ..Default::default()
        },
    )
    .unwrap();
    require_disk(&disk).unwrap();
    assert_eq!(report.seam_extremities, vec![Some(0)]);
    assert_eq!(report.seam_edges, 4 + 24, "4 cap rings and 24 tube segments");
    assert_eq!(report.seam_vertices_added, 4 + 24);
    assert_eq!(disk.num_vertices(), tube.num_vertices() + report.seam_vertices_added);
    for (v, o) in origin.iter().enumerate() {
        assert_eq!(
            disk.positions[v],
            tube.positions[o.expect("no vertex without an input") as usize]
        );
    }
    // without the option nothing changes
    let (plain, _, report) = prepare::prepare_disk(&tube, &PrepareOptions::default()).unwrap();
    assert_eq!((plain.num_vertices(), report.seam_edges), (tube.num_vertices(), 0));
}

/// Seams that are not trees, not edges, on the boundary or empty, and surfaces a seam cannot
/// handle, are errors that say so.
#[test]
fn seam_errors() {
    let sphere = icosphere(1);
    let err = |m: &TriMesh, seam: &[[u32; 2]]| cut_along_seam(m, seam).unwrap_err().to_string();
    // a cycle: the three edges of a face
    let [a, b, c] = sphere.faces[0];
    assert!(err(&sphere, &[[a, b], [b, c], [c, a]]).contains("not a tree"));
    // two disjoint paths on a closed surface
    let far = (0..sphere.num_vertices() as u32)
        .find(|&v| !sphere.faces.iter().any(|f| f.contains(&a) && f.contains(&v)))
        .unwrap();
    let neighbour = sphere.faces.iter().find(|f| f.contains(&far)).unwrap();
    let w = *neighbour.iter().find(|&&x| x != far).unwrap();
    assert!(err(&sphere, &[[a, b], [far, w]]).contains("not connected"));
    // not an edge
    assert!(err(&sphere, &[[a, far]]).contains("not an edge"));
    // empty
    assert!(err(&sphere, &[]).contains("no edges"));
    // one edge opens nothing: the result is still a sphere
    assert!(err(&sphere, &[[a, b]]).contains("sphere"));
    // on a disk: a boundary edge, and a path touching the boundary twice (a cycle through it)
    let disk = unit_disk(2);
    let loop_ = &Connectivity::of(&disk).boundary_loops(&disk.faces)[0];
    assert!(err(&disk, &[[loop_[0], loop_[1]]]).contains("boundary"));
    let inner: Vec<u32> = (1..7).collect(); // ring 1
    let outer = disk
        .faces
        .iter()
        .flat_map(|f| f.iter().copied())
        .find(|&v| v >= 7 && disk.faces.iter().any(|f| f.contains(&v) && f.contains(&inner[0])))
        .unwrap();
    let outer2 = disk
        .faces
        .iter()
        .flat_map(|f| f.iter().copied())
        .find(|&v| v >= 7 && v != outer && disk.faces.iter().any(|f| f.contains(&v) && f.contains(&inner[0])))
        .unwrap();
    assert!(err(&disk, &[[inner[0], outer], [inner[0], outer2]]).contains("not a tree"));
    // inconsistent orientation
    let mut flipped = sphere.clone();
    flipped.faces[0].swap(1, 2);
    assert!(err(&flipped, &[[a, b]]).contains("oriented"));
    // a terminal out of range
    assert!(seam_tree(&sphere, &[0, 10_000])
        .unwrap_err()
        .to_string()
        .contains("10000"));
    // two boundary loops (a disk with a face removed): the message names them
    let mut holed = unit_disk(3);
    holed.faces.remove(0);
    let inner = holed.faces[0][0];
    let e = err(&holed, &[[inner, holed.faces[0][1]]]);
    assert!(e.contains("2 boundary loops"), "{e}");
    // a face with a repeated vertex
    let mut degenerate = sphere.clone();
    degenerate.faces.push([a, a, b]);
    assert!(err(&degenerate, &[[a, b]]).contains("repeats"));
    // extremities: an unreferenced vertex 0 is skipped, two components are an error
    let mut shifted = icosphere(1);
    shifted.positions.insert(0, [9.0, 9.0, 9.0]);
    for f in &mut shifted.faces {
        *f = f.map(|v| v + 1);
    }
    let tips = extremities(&shifted, 2).unwrap();
    assert_eq!(tips.len(), 2);
    assert!(!tips.contains(&0), "{tips:?}");
    let mut two = icosphere(1);
    let off = two.num_vertices() as u32;
    two.positions
        .extend(icosphere(1).positions.iter().map(|p| [p[0] + 5.0, p[1], p[2]]));
    two.faces.extend(icosphere(1).faces.iter().map(|f| f.map(|v| v + off)));
    assert!(extremities(&two, 2).unwrap_err().to_string().contains("connected"));
}

/// A seam request that slits a closed surface along every vertex (an icosahedron subdivided
/// once, 1,000 extremities asked for) leaves no interior vertex; the bridges (interior edges
/// joining two boundary vertices) are then split, which gives the disk interior vertices again.
/// A disk with no interior vertex and no bridge to split (one triangle) is an error naming the
/// cause.
#[test]
fn a_seam_through_every_vertex_gets_interior_vertices_back() {
    let sphere = icosphere(1);
    let options = PrepareOptions {
        seam_extremities: 1000,
        ..Default::default()
    };
    let (disk, _, report) = prepare::prepare_disk(&sphere, &options).unwrap();
    assert!(report.seam_edges > 0 && report.bridges_split > 0, "{report:?}");
    require_disk(&disk).unwrap();
    assert_eq!(prepare::interior_components(&disk).1, 1);
    let triangle = TriMesh::new(vec![[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0]], vec![[0, 1, 2]]).unwrap();
    let e = prepare::prepare_disk(&triangle, &PrepareOptions::default())
        .unwrap_err()
        .to_string();
    assert!(
        e.contains("no interior vertex") && e.contains("finer mesh") && !e.contains("seam"),
        "{e}"
    );
}

/// A disk without interior vertex whose bridge (an interior edge joining two boundary vertices)
/// can be split: the square of two triangles gets its diagonal split, one interior vertex.
#[test]
fn a_disk_without_interior_vertex_gets_its_bridge_split() {
    let square = grid(1, 1);
    let (disk, origin, report) = prepare::prepare_disk(&square, &PrepareOptions::default()).unwrap();
    assert_eq!(report.bridges_split, 1);
    assert_eq!(disk.num_vertices(), 5);
    assert_eq!(origin[4], None);
    assert_eq!(prepare::interior_components(&disk).1, 1);
    assert!((total_area(&disk) - 1.0).abs() < 1e-15);
}
