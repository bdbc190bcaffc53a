//! Shared builders for the solver tests: triangulated disks with radial densities, sunflower
//! point sets, a tiny deterministic generator.

use shapespace_omt::SourceMeasure;

/// A triangulated unit disk (inscribed polygon with 6·rings boundary vertices):
/// [`shapespace_omt::synthetic::disk_rings_mesh`].
pub fn disk_mesh(rings: usize) -> (Vec<[f64; 2]>, Vec<[u32; 3]>) {
    shapespace_omt::synthetic::disk_rings_mesh(rings)
}

/// Triangle average of f by the degree-5 (7-point) Dunavant rule.
pub fn triangle_average(p: [[f64; 2]; 3], f: &dyn Fn([f64; 2]) -> f64) -> f64 {
    let rule: [(f64, f64, f64, f64); 7] = {
        let a1 = 0.059_715_871_789_770;
        let b1 = 0.470_142_064_105_115;
        let a2 = 0.797_426_985_353_087;
        let b2 = 0.101_286_507_323_456;
        let w1 = 0.132_394_152_788_506;
        let w2 = 0.125_939_180_544_827;
        [
            (1.0 / 3.0, 1.0 / 3.0, 1.0 / 3.0, 0.225),
            (a1, b1, b1, w1),
            (b1, a1, b1, w1),
            (b1, b1, a1, w1),
            (a2, b2, b2, w2),
            (b2, a2, b2, w2),
            (b2, b2, a2, w2),
        ]
    };
    rule.iter()
        .map(|&(l0, l1, l2, w)| {
            w * f([
                l0 * p[0][0] + l1 * p[1][0] + l2 * p[2][0],
                l0 * p[0][1] + l1 * p[1][1] + l2 * p[2][1],
            ])
        })
        .sum()
}

/// The unit disk mesh with density = triangle averages of `f`.
pub fn disk_measure(rings: usize, f: &dyn Fn([f64; 2]) -> f64) -> SourceMeasure {
    let (vertices, triangles) = disk_mesh(rings);
    let densities = triangles
        .iter()
        .map(|t| triangle_average(t.map(|v| vertices[v as usize]), f))
        .collect();
    SourceMeasure::new(vertices, triangles, densities).expect("valid disk mesh")
}

/// N points of a sunflower (Vogel) spiral filling the disk of radius `radius` uniformly.
pub fn sunflower(n: usize, radius: f64) -> Vec<[f64; 2]> {
    let golden = std::f64::consts::PI * (3.0 - 5f64.sqrt());
    (0..n)
        .map(|k| {
            let r = radius * ((k as f64 + 0.5) / n as f64).sqrt();
            let t = golden * k as f64;
            [r * t.cos(), r * t.sin()]
        })
        .collect()
}

/// splitmix64-based uniform numbers in [0, 1).
pub struct Rng(pub u64);
impl Rng {
    pub fn next(&mut self) -> f64 {
        self.0 = self.0.wrapping_add(0x9E37_79B9_7F4A_7C15);
        let mut x = self.0;
        x = (x ^ (x >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
        x = (x ^ (x >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
        ((x ^ (x >> 31)) >> 11) as f64 / (1u64 << 53) as f64
    }
    /// Uniform point in the disk of radius `radius`.
    pub fn in_disk(&mut self, radius: f64) -> [f64; 2] {
        let r = radius * self.next().sqrt();
        let t = 2.0 * std::f64::consts::PI * self.next();
        [r * t.cos(), r * t.sin()]
    }
}

/// Composite Gauss–Legendre (5 points) quadrature of f on [a, b] with `panels` panels.
pub fn quadrature(f: &dyn Fn(f64) -> f64, a: f64, b: f64, panels: usize) -> f64 {
    let x = [
        0.0,
        0.538_469_310_105_683_1,
        -0.538_469_310_105_683_1,
        0.906_179_845_938_664,
        -0.906_179_845_938_664,
    ];
    let w = [
        0.568_888_888_888_888_9,
        0.478_628_670_499_366_5,
        0.478_628_670_499_366_5,
        0.236_926_885_056_189_1,
        0.236_926_885_056_189_1,
    ];
    let h = (b - a) / panels as f64;
    (0..panels)
        .map(|p| {
            let c = a + (p as f64 + 0.5) * h;
            (0..5).map(|k| w[k] * f(c + 0.5 * h * x[k])).sum::<f64>() * 0.5 * h
        })
        .sum()
}
