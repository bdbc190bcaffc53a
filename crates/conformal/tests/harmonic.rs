//! Harmonic maps with boundary and landmark constraints (Su et al. 2015, Alg. 4, the map g).

use geogram_predicates::{orient_2d, Sign};
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use shapespace_conformal::{harmonic_map, BoundaryConstraint, HarmonicConstraints};
use shapespace_geometry::primitives::unit_disk;

fn disk(rings: usize, jitter: f64, seed: u64) -> (Vec<[f64; 2]>, Vec<[u32; 3]>, Vec<u32>) {
    let m = unit_disk(rings);
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    let n = m.num_vertices();
    let nb = 6 * rings;
    let h = 1.0 / rings as f64;
    let pos: Vec<[f64; 2]> = m
        .positions
        .iter()
        .enumerate()
        .map(|(i, p)| {
            if i >= n - nb {
                [p[0], p[1]]
            } else {
                [
                    p[0] + jitter * h * (rng.random::<f64>() - 0.5),
                    p[1] + jitter * h * (rng.random::<f64>() - 0.5),
                ]
            }
        })
        .collect();
    let boundary = ((n - nb) as u32..n as u32).collect();
    (pos, m.faces, boundary)
}

fn flips(uv: &[[f64; 2]], faces: &[[u32; 3]]) -> usize {
    faces
        .iter()
        .filter(|f| orient_2d(&uv[f[0] as usize], &uv[f[1] as usize], &uv[f[2] as usize]) != Sign::Positive)
        .count()
}

#[test]
fn identity_boundary_reproduces_a_flat_mesh() {
    // linear precision of the cotangent Laplacian: boundary = identity ⇒ map = identity
    let (pos, faces, boundary) = disk(12, 0.5, 1);
    let c = HarmonicConstraints {
        boundary: BoundaryConstraint::Fixed(boundary.iter().map(|&v| (v, pos[v as usize])).collect()),
        landmarks: vec![],
    };
    let uv = harmonic_map(&pos, &faces, &c).unwrap();
    let err = uv
        .iter()
        .zip(&pos)
        .map(|(a, b)| (a[0] - b[0]).hypot(a[1] - b[1]))
        .fold(0.0, f64::max);
    assert!(err < 1e-12, "{err}");
}

#[test]
fn rotated_boundary_on_convex_disk_has_no_flips_rado() {
    // boundary vertices moved along the circle by a smooth non-uniform reparametrization:
    // the interior follows without folding (positive intrinsic Delaunay weights, convex target)
    for seed in 0..3 {
        let (pos, faces, boundary) = disk(16, 0.6, seed);
        let fixed: Vec<(u32, [f64; 2])> = boundary
            .iter()
            .map(|&v| {
                let p = pos[v as usize];
                let t = p[1].atan2(p[0]);
                let s = t + 0.4 * (2.0 * t).sin() + 0.3;
                (v, [s.cos(), s.sin()])
            })
            .collect();
        let c = HarmonicConstraints {
            boundary: BoundaryConstraint::Fixed(fixed.clone()),
            landmarks: vec![],
        };
        let uv = harmonic_map(&pos, &faces, &c).unwrap();
        assert_eq!(flips(&uv, &faces), 0, "seed {seed}");
        for (v, p) in fixed {
            assert_eq!(uv[v as usize], p);
        }
        assert!(uv.iter().all(|z| z[0].hypot(z[1]) <= 1.0 + 1e-15));
    }
}

#[test]
fn landmarks_are_hit_exactly_and_anchors_slide_the_boundary() {
    let (pos, faces, boundary) = disk(16, 0.3, 5);
    let n = pos.len() as u32;
    let anchors: Vec<(u32, [f64; 2])> = [0usize, 24, 48, 72]
        .iter()
        .map(|&k| {
            let t = 0.2 + std::f64::consts::FRAC_PI_2 * (k / 24) as f64;
            (boundary[k], [t.cos(), t.sin()])
        })
        .collect();
    // two interior landmarks moved by a small amount
    let landmarks = vec![(0u32, [0.05, -0.03]), (20u32, [pos[20][0] + 0.02, pos[20][1]])];
    let c = HarmonicConstraints {
        boundary: BoundaryConstraint::Anchors(anchors.clone()),
        landmarks: landmarks.clone(),
    };
    let uv = harmonic_map(&pos, &faces, &c).unwrap();
    for (v, p) in landmarks {
        assert_eq!(uv[v as usize], p);
    }
    for (v, p) in &anchors {
        let z = uv[*v as usize];
        assert!((z[0] - p[0]).abs() < 1e-15 && (z[1] - p[1]).abs() < 1e-15);
    }
    for &v in &boundary {
        let z = uv[v as usize];
        assert!((z[0].hypot(z[1]) - 1.0).abs() < 1e-15);
    }
    // equally spaced boundary with anchors a quarter turn apart: vertex k sits at 0.2 + 2πk/96
    let z = uv[boundary[12] as usize];
    let t = z[1].atan2(z[0]);
    assert!((t - (0.2 + std::f64::consts::TAU * 12.0 / 96.0)).abs() < 1e-12, "{t}");
    assert_eq!(flips(&uv, &faces), 0);
    assert!(n > 100);
}

#[test]
fn invalid_constraints_are_errors() {
    let (pos, faces, boundary) = disk(4, 0.0, 0);
    let partial = HarmonicConstraints {
        boundary: BoundaryConstraint::Fixed(boundary[..5].iter().map(|&v| (v, pos[v as usize])).collect()),
        landmarks: vec![],
    };
    assert!(harmonic_map(&pos, &faces, &partial).is_err());
    let on_boundary = HarmonicConstraints {
        boundary: BoundaryConstraint::Anchors(vec![(boundary[0], [1.0, 0.0])]),
        landmarks: vec![(boundary[3], [0.0, 0.0])],
    };
    assert!(harmonic_map(&pos, &faces, &on_boundary).is_err());
    let interior_anchor = HarmonicConstraints {
        boundary: BoundaryConstraint::Anchors(vec![(0, [1.0, 0.0])]),
        landmarks: vec![],
    };
    assert!(harmonic_map(&pos, &faces, &interior_anchor).is_err());
}
