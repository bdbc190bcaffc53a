//! Discrete curvatures against closed forms: Gauss–Bonnet on icospheres, flat disks and caps,
//! mean curvature 1/r on spheres (with its convergence under refinement), 1/(2ρ) on a cylinder,
//! and the cotangent Laplacian's exactness on linear functions of planar meshes.

use std::f64::consts::PI;

use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use shapespace_geometry::connectivity::Connectivity;
use shapespace_geometry::curvature::{
    vertex_angle_defects, vertex_gaussian_curvatures, vertex_mean_curvature_normals, vertex_mean_curvatures,
    vertex_mixed_areas,
};
use shapespace_geometry::laplacian::{cotan_laplacian, sparse_mul_vec};
use shapespace_geometry::primitives::{capped_tube, grid, icosphere, spherical_cap, unit_disk};
use shapespace_geometry::quantities::vertex_dual_areas;
use shapespace_geometry::TriMesh;

fn scaled(mut m: TriMesh, s: f64) -> TriMesh {
    for p in &mut m.positions {
        *p = p.map(|c| c * s);
    }
    m
}

#[test]
fn gauss_bonnet_on_icospheres() {
    for s in 2..=5 {
        let m = icosphere(s);
        let defects = vertex_angle_defects(&m);
        let total: f64 = defects.iter().sum();
        assert!((total - 4.0 * PI).abs() < 1e-10, "s = {s}: Σ K = {total}");
        // every defect positive (convex), pointwise K ≈ 1 on the unit sphere
        assert!(defects.iter().all(|&d| d > 0.0));
        let k = vertex_gaussian_curvatures(&m);
        let areas = vertex_mixed_areas(&m);
        assert!((areas.iter().sum::<f64>() - vertex_dual_areas(&m).iter().sum::<f64>()).abs() < 1e-12);
        let integrated: f64 = k.pointwise.iter().zip(&areas).map(|(k, a)| k * a).sum();
        assert!((integrated - 4.0 * PI).abs() < 1e-10);
    }
    // scale invariance of the angle defect, pointwise K scales as 1/s²
    let m = icosphere(3);
    let big = scaled(m.clone(), 1e6);
    let (a, b) = (vertex_gaussian_curvatures(&m), vertex_gaussian_curvatures(&big));
    for v in 0..m.num_vertices() {
        assert!((a.integrated[v] - b.integrated[v]).abs() < 1e-12);
        assert!((a.pointwise[v] - b.pointwise[v] * 1e12).abs() < 1e-9 * a.pointwise[v].abs());
    }
}

/// Per subdivision level s: (s, max |H − 1|, area-weighted mean |H − 1|, max |K − 1|, and
/// max |½|M⁻¹Lx| − 1| with the barycentric mass M instead of mixed areas) on the unit icosphere.
fn sphere_curvature_errors() -> Vec<(usize, f64, f64, f64, f64)> {
    (2..=5)
        .map(|s| {
            let m = icosphere(s);
            let h = vertex_mean_curvatures(&m);
            let max_err = h.iter().map(|x| (x - 1.0).abs()).fold(0.0, f64::max);
            let areas = vertex_mixed_areas(&m);
            let mean_err =
                h.iter().zip(&areas).map(|(x, a)| (x - 1.0).abs() * a).sum::<f64>() / areas.iter().sum::<f64>();
            let k = vertex_gaussian_curvatures(&m);
            let k_err = k.pointwise.iter().map(|x| (x - 1.0).abs()).fold(0.0, f64::max);
            let bary = vertex_dual_areas(&m);
            let bary_err = vertex_mean_curvature_normals(&m)
                .iter()
                .zip(areas.iter().zip(&bary))
                .map(|(hn, (a, b))| ((hn[0] * hn[0] + hn[1] * hn[1] + hn[2] * hn[2]).sqrt() * a / b - 1.0).abs())
                .fold(0.0, f64::max);
            (s, max_err, mean_err, k_err, bary_err)
        })
        .collect()
}

#[test]
fn curvatures_of_spheres_converge() {
    let errors = sphere_curvature_errors();
    println!("unit icosphere, H and K vs 1:");
    println!("  s      #V   max|H-1|   mean|H-1|   max|K-1|   max|H-1| barycentric M");
    for &(s, h, hm, k, b) in &errors {
        println!(
            "  {s}  {:6}  {h:.3e}  {hm:.3e}  {k:.3e}  {b:.3e}",
            10 * 4usize.pow(s as u32) + 2
        );
    }
    for w in errors.windows(2) {
        // second order: each subdivision halves h, so errors drop by about 4
        assert!(w[1].1 < w[0].1 / 3.5, "max |H − 1| is not O(h²): {errors:?}");
        assert!(w[1].2 < w[0].2 / 3.5, "mean |H − 1| is not O(h²): {errors:?}");
        assert!(w[1].3 < w[0].3 / 3.5, "max |K − 1| is not O(h²): {errors:?}");
    }
    assert!(errors.last().unwrap().1 < 1e-5, "{errors:?}");
    // the barycentric mass matrix is not pointwise consistent (why mixed areas are used)
    assert!(errors.iter().all(|e| e.4 > 0.1), "{errors:?}");

    // radius 2 → H = 1/2, and positive (outward normals)
    let m = scaled(icosphere(4), 2.0);
    let h = vertex_mean_curvatures(&m);
    assert!(h.iter().all(|&x| (x - 0.5).abs() < 0.5 * 1e-4));
    // flipped faces (inward normals): H changes sign, |H n| is unchanged
    let mut inward = m.clone();
    for f in &mut inward.faces {
        f.swap(1, 2);
    }
    let hi = vertex_mean_curvatures(&inward);
    for (a, b) in h.iter().zip(&hi) {
        assert!((a + b).abs() < 1e-12);
    }
    // the mean-curvature normal H n points outward, like the position on the sphere
    for (hn, p) in vertex_mean_curvature_normals(&m).iter().zip(&m.positions) {
        let cos = (hn[0] * p[0] + hn[1] * p[1] + hn[2] * p[2])
            / ((hn[0] * hn[0] + hn[1] * hn[1] + hn[2] * hn[2]).sqrt() * 2.0);
        assert!(cos > 0.999);
    }
}

#[test]
fn mean_curvature_of_a_cylinder() {
    // interior tube vertices (away from the cap and the open end): H = 1/(2ρ), K = 0
    let rho = 0.5;
    let m = capped_tube(rho, 4.0, 16, 64);
    let h = vertex_mean_curvatures(&m);
    let k = vertex_angle_defects(&m);
    let mut checked = 0;
    let mut max_err: f64 = 0.0;
    for (v, p) in m.positions.iter().enumerate() {
        if p[2] > 1.0 && p[2] < 3.0 {
            max_err = max_err.max((h[v] * 2.0 * rho - 1.0).abs());
            assert!(k[v].abs() < 1e-12);
            checked += 1;
        }
    }
    println!("cylinder ρ = {rho}, 96 around: max relative error of H = {max_err:.3e}");
    // measured 4e-14: on this prism of right triangles (vertices on the circle) the ratio of the
    // area gradient to the mixed area is exactly 1/(2ρ), independent of the 96 segments
    assert!(max_err < 1e-10, "max relative error {max_err}");
    assert!(checked > 1000);
}

#[test]
fn flat_disk_gauss_bonnet() {
    for rings in [1, 4, 16] {
        let m = unit_disk(rings);
        let conn = Connectivity::of(&m);
        let boundary = conn.boundary_vertices(m.num_vertices());
        let k = vertex_angle_defects(&m);
        let mut interior = 0.0;
        let mut geodesic = 0.0;
        for v in 0..m.num_vertices() {
            if boundary[v] {
                geodesic += k[v];
            } else {
                assert!(k[v].abs() < 1e-12, "K = {} at interior vertex {v}", k[v]);
                interior += k[v];
            }
        }
        // the boundary polygon turns by 2π/(6·rings) at each of its corners
        assert!((geodesic - 2.0 * PI).abs() < 1e-12);
        assert!((interior + geodesic - 2.0 * PI).abs() < 1e-12);
        // mean curvature vanishes inside a flat mesh
        let h = vertex_mean_curvatures(&m);
        for v in 0..m.num_vertices() {
            if !boundary[v] {
                assert!(h[v].abs() < 1e-12);
            }
        }
    }
}

#[test]
fn spherical_cap_gauss_bonnet_split() {
    // a cap of half-angle α on the unit sphere: ∫K dA = 2π(1 − cos α), ∮κ_g ds = 2π cos α.
    // The discrete total is exactly 2πχ = 2π; interior defects converge to the area integral.
    let alpha = 1.0f64;
    let mut prev_err = f64::INFINITY;
    println!(
        "cap α = 1: interior Σ K vs 2π(1 − cos α) = {:.6}",
        2.0 * PI * (1.0 - alpha.cos())
    );
    for rings in [8, 16, 32, 64] {
        let m = spherical_cap(alpha, rings);
        let conn = Connectivity::of(&m);
        let boundary = conn.boundary_vertices(m.num_vertices());
        let k = vertex_angle_defects(&m);
        let total: f64 = k.iter().sum();
        assert!((total - 2.0 * PI).abs() < 1e-10);
        // interior curvature plus the curvature of the half-ring of area at the boundary vertices:
        // compare the interior sum with the exact integral over the cap minus the last half ring
        let interior: f64 = (0..m.num_vertices()).filter(|&v| !boundary[v]).map(|v| k[v]).sum();
        let theta_inner = alpha * (rings as f64 - 0.5) / rings as f64;
        let exact = 2.0 * PI * (1.0 - theta_inner.cos());
        let err = (interior - exact).abs();
        println!("  rings {rings:3}: interior {interior:.6}, exact to θ = α(1 − 1/2n) {exact:.6}, error {err:.2e}");
        assert!(err < prev_err);
        prev_err = err;
    }
    assert!(prev_err < 1e-3);
}

#[test]
fn cotan_laplacian_kills_linear_functions_on_planar_meshes() {
    // regular grid, then the same grid with its interior vertices jittered in the plane
    let mut rng = ChaCha8Rng::seed_from_u64(7);
    for jitter in [0.0, 0.3] {
        let n = 12;
        let mut m = grid(n, n);
        let h = 1.0 / n as f64;
        let conn = Connectivity::of(&m);
        let boundary = conn.boundary_vertices(m.num_vertices());
        for (v, p) in m.positions.iter_mut().enumerate() {
            if !boundary[v] {
                p[0] += jitter * h * (rng.random::<f64>() - 0.5);
                p[1] += jitter * h * (rng.random::<f64>() - 0.5);
            }
        }
        let l = cotan_laplacian(&m).unwrap();
        for (a, b, c) in [(1.0, 0.0, 0.0), (0.0, 1.0, 0.0), (2.5, -1.5, 0.7)] {
            let u: Vec<f64> = m.positions.iter().map(|p| a * p[0] + b * p[1] + c).collect();
            let lu = sparse_mul_vec(&l, &u);
            let mut max_interior: f64 = 0.0;
            let mut max_boundary: f64 = 0.0;
            for v in 0..m.num_vertices() {
                if boundary[v] {
                    max_boundary = max_boundary.max(lu[v].abs());
                } else {
                    max_interior = max_interior.max(lu[v].abs());
                }
            }
            assert!(max_interior < 1e-13, "jitter {jitter}: |L u| = {max_interior}");
            // on the boundary L u is the outward flux, not zero, for a non-constant u
            if a != 0.0 || b != 0.0 {
                assert!(max_boundary > 1e-3);
            }
        }
    }
}
