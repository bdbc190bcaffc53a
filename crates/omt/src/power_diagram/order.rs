//! The insertion order of a set of sites ([`InsertionOrder`]): validation, Hilbert sort and
//! biased randomized rounds.

use super::MIN_COORDINATE;
use crate::error::OmtError;
use crate::predicates::orient;

/// Indices of `points` in the order of the Hilbert curve (order 16) over their bounding box,
/// ties by index: an order in which consecutive points are close, for short point-location
/// walks and stratified samples.
pub(crate) fn hilbert_order(points: &[[f64; 2]]) -> Vec<u32> {
    let (lo, hi) = crate::polygon::bounding_box(points);
    let span = (hi[0] - lo[0]).max(hi[1] - lo[1]);
    let scale = if span > 0.0 { 65535.0 / span } else { 0.0 };
    let mut keyed: Vec<(u64, u32)> = points
        .iter()
        .enumerate()
        .map(|(i, p)| {
            let q = |c: usize| ((p[c] - lo[c]) * scale).clamp(0.0, 65535.0) as u32;
            (hilbert_index(q(0), q(1)), i as u32)
        })
        .collect();
    keyed.sort_unstable();
    keyed.into_iter().map(|k| k.1).collect()
}

/// Index of (x, y) ∈ [0, 2¹⁶)² along the Hilbert curve of order 16.
fn hilbert_index(mut x: u32, mut y: u32) -> u64 {
    let n: u32 = 1 << 16;
    let mut d = 0u64;
    let mut s = n / 2;
    while s > 0 {
        let rx = u32::from(x & s > 0);
        let ry = u32::from(y & s > 0);
        d += (s as u64) * (s as u64) * u64::from((3 * rx) ^ ry);
        if ry == 0 {
            if rx == 1 {
                x = n - 1 - x;
                y = n - 1 - y;
            }
            std::mem::swap(&mut x, &mut y);
        }
        s /= 2;
    }
    d
}

/// SplitMix64 finalizer: a fixed pseudo-random hash of an index.
pub(super) fn mix(mut z: u64) -> u64 {
    z = z.wrapping_add(0x9E37_79B9_7F4A_7C15);
    z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
    z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
    z ^ (z >> 31)
}

/// Validates the input; returns the sites sorted along a Hilbert curve (ties by coordinates),
/// or the first pair of coincident sites.
pub(super) fn validate_and_sort(sites: &[[f64; 2]], weights: &[f64]) -> Result<Vec<u32>, OmtError> {
    if sites.len() != weights.len() {
        return Err(OmtError::InvalidInput(format!(
            "{} sites but {} weights",
            sites.len(),
            weights.len()
        )));
    }
    if sites.is_empty() {
        return Err(OmtError::InvalidInput("a power diagram needs at least one site".into()));
    }
    if sites.len() >= (u32::MAX / 8) as usize {
        return Err(OmtError::InvalidInput(format!("too many sites ({})", sites.len())));
    }
    for (i, (p, &w)) in sites.iter().zip(weights).enumerate() {
        if !(p[0].is_finite() && p[1].is_finite()) || p[0].abs() > 1e30 || p[1].abs() > 1e30 {
            return Err(OmtError::InvalidInput(format!(
                "site {i} = ({}, {}) is not finite or exceeds 1e30 in magnitude",
                p[0], p[1]
            )));
        }
        if p.iter().any(|c| *c != 0.0 && c.abs() < MIN_COORDINATE) {
            return Err(OmtError::InvalidInput(format!(
                "site {i} = ({:e}, {:e}) has a nonzero coordinate below {MIN_COORDINATE:e} in magnitude, where the exact predicates' products underflow; rescale the sites or round such coordinates to 0",
                p[0], p[1]
            )));
        }
        if !w.is_finite() || w.abs() > 1e60 {
            return Err(OmtError::InvalidInput(format!(
                "weight {i} = {w} is not finite or exceeds 1e60 in magnitude"
            )));
        }
    }
    let (lo, hi) = crate::polygon::bounding_box(sites);
    let span = (hi[0] - lo[0]).max(hi[1] - lo[1]);
    let scale = if span > 0.0 { 65535.0 / span } else { 0.0 };
    let quantize = |v: f64, c: usize| (((v - lo[c]) * scale).clamp(0.0, 65535.0)) as u32;
    let mut keyed: Vec<(u64, f64, f64, u32)> = sites
        .iter()
        .enumerate()
        .map(|(i, p)| {
            (
                hilbert_index(quantize(p[0], 0), quantize(p[1], 1)),
                p[0] + 0.0,
                p[1] + 0.0,
                i as u32,
            )
        })
        .collect();
    keyed.sort_unstable_by(|a, b| {
        a.0.cmp(&b.0)
            .then(a.1.total_cmp(&b.1))
            .then(a.2.total_cmp(&b.2))
            .then(a.3.cmp(&b.3))
    });
    for pair in keyed.windows(2) {
        if pair[0].1 == pair[1].1 && pair[0].2 == pair[1].2 {
            let (i, j) = (pair[0].3.min(pair[1].3) as usize, pair[0].3.max(pair[1].3) as usize);
            return Err(OmtError::DuplicatePoints { i, j });
        }
    }
    Ok(keyed.into_iter().map(|k| k.3).collect())
}

/// Biased randomized insertion order (Amenta, Choi, Rote 2003): site k goes to round
/// min(trailing_zeros(hash(k)), R); rounds are inserted from the smallest (sparsest) on, each in
/// Hilbert order. Deterministic.
pub(super) fn brio_order(hilbert_sorted: &[u32]) -> Vec<u32> {
    let n = hilbert_sorted.len();
    let rounds = ((n as f64).log2() as u32).saturating_sub(6).min(20);
    let mut buckets: Vec<Vec<u32>> = vec![Vec::new(); rounds as usize + 1];
    for &i in hilbert_sorted {
        let r = (mix(u64::from(i) ^ 0x5EED).trailing_zeros()).min(rounds);
        buckets[(rounds - r) as usize].push(i);
    }
    buckets.into_iter().flatten().collect()
}

/// The order in which [`PowerDiagram`](crate::power_diagram::PowerDiagram) inserts a set of sites: a biased randomized insertion
/// order along a Hilbert curve, starting with a non-degenerate triangle. It depends on the sites
/// only; computing it once (which also validates the sites) saves that part of every diagram of
/// the same sites ([`DiagramBuilder::order`](crate::power_diagram::DiagramBuilder::order)).
#[derive(Clone, Debug)]
pub struct InsertionOrder {
    pub(super) order: Vec<u32>,
    /// The first site along the Hilbert curve (start of point location without a hint).
    pub(super) first: u32,
    /// All sites on one line.
    pub(super) collinear: bool,
}

impl InsertionOrder {
    /// The insertion order of `sites`. Errors as [`PowerDiagram::new`](crate::power_diagram::PowerDiagram::new) for the sites: no site,
    /// a non-finite one or one out of range, coincident sites.
    pub fn new(sites: &[[f64; 2]]) -> Result<Self, OmtError> {
        let sorted = validate_and_sort(sites, &vec![0.0; sites.len()])?;
        Ok(Self::from_sorted(sites, sorted))
    }

    pub(super) fn from_sorted(sites: &[[f64; 2]], sorted: Vec<u32>) -> Self {
        let n = sites.len();
        let first = sorted[0];
        if n == 1 {
            return InsertionOrder {
                order: sorted,
                first,
                collinear: false,
            };
        }
        let mut order = brio_order(&sorted);
        let (a, b) = (order[0], order[1]);
        let third = (2..n).find(|&k| orient(sites[a as usize], sites[b as usize], sites[order[k] as usize]) != 0);
        if let Some(k) = third {
            let c = order.remove(k);
            order.insert(2, c);
        }
        InsertionOrder {
            order,
            first,
            collinear: third.is_none(),
        }
    }

    /// Number of sites.
    pub fn len(&self) -> usize {
        self.order.len()
    }

    /// True for no site (never: `new` rejects that).
    pub fn is_empty(&self) -> bool {
        self.order.is_empty()
    }
}
