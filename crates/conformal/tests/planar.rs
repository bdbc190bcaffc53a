//! Planar domains f(D) for known univalent maps f: the disk map must recover f⁻¹ (with
//! p = f(0), q = f(1)), i.e. the vertex positions of the unit-disk mesh that was pushed
//! forward by f.
//!
//! Observed max |φ(f(z)) − z| for rings 10/20/40: f(z) = z + 0.3z²: 3.0e-3, 9.6e-4, 3.5e-4
//! (order ≈ 1.5); f(z) = z/(1 − 0.5z) (Möbius onto an off-center disk): 5.4e-3, 1.4e-3,
//! 4.3e-4 (order ≈ 1.8); f = id: 1.25e-3, 6.3e-4, 3.1e-4 (order 1).

use crate::common::*;
use shapespace_geometry::primitives::unit_disk;
use shapespace_geometry::TriMesh;

fn pushed(rings: usize, f: impl Fn(f64, f64) -> (f64, f64)) -> (TriMesh, Vec<[f64; 2]>) {
    let disk = unit_disk(rings);
    let z: Vec<[f64; 2]> = disk.positions.iter().map(|p| [p[0], p[1]]).collect();
    let positions = z.iter().map(|w| {
        let (x, y) = f(w[0], w[1]);
        [x, y, 0.0]
    });
    let mesh = TriMesh::new(positions.collect(), disk.faces.clone()).unwrap();
    (mesh, z)
}

fn recover(f: impl Fn(f64, f64) -> (f64, f64) + Copy) -> Vec<f64> {
    [10, 20, 40]
        .iter()
        .map(|&rings| {
            let (mesh, z) = pushed(rings, f);
            // vertex 0 is z = 0; the boundary vertex at angle 0 is the first of the last ring
            let q = (mesh.num_vertices() - 6 * rings) as u32;
            assert_eq!(z[q as usize], [1.0, 0.0]);
            let dm = map(&mesh, &vertex_markers(0, q));
            let e = max_dist(&dm.uv, &z);
            eprintln!("rings {rings}: max error {e:.2e}");
            e
        })
        .collect()
}

#[test]
fn quadratic_univalent_map_is_inverted() {
    let e = recover(|x, y| (x + 0.3 * (x * x - y * y), y + 0.3 * 2.0 * x * y));
    assert!(e[1] < e[0] / 1.8 && e[2] < e[1] / 1.8, "{e:?}");
    assert!(e[2] < 5e-4, "{e:?}");
}

#[test]
fn mobius_onto_off_center_disk_is_inverted() {
    // f(z) = z/(1 − z/2): the unit disk onto the disk of center 2/3, radius 4/3... (f(0) = 0
    // is not its center, so the normalization matters)
    let e = recover(|x, y| {
        let (dx, dy) = (1.0 - 0.5 * x, -0.5 * y);
        let d2 = dx * dx + dy * dy;
        ((x * dx + y * dy) / d2, (y * dx - x * dy) / d2)
    });
    assert!(e[1] < e[0] / 1.8 && e[2] < e[1] / 1.8, "{e:?}");
    assert!(e[2] < 6e-4, "{e:?}");
}

#[test]
fn flat_unit_disk_maps_to_itself() {
    // f = id: the discrete map is not exactly the identity (discrete Green's function), but
    // converges at first order
    let e = recover(|x, y| (x, y));
    assert!(e[1] < e[0] / 1.8 && e[2] < e[1] / 1.8, "{e:?}");
    assert!(e[2] < 4e-4, "{e:?}");
}
