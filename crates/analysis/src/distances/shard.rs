//! Splitting the pairs of a pairwise run into shards and tiles: `distances --shard K/N`
//! computes shard K of N, `merge` assembles the shards, and the Python package's `pairwise`
//! submits tiles as tasks.
//!
//! The directed pairs of a run over n shapes are numbered in the order of
//! [`crate::distance::directed_pairs`] (by target, then source: 0 → 1, 0 → 2, 1 → 2, 0 → 3, …),
//! P of them. Shard K of N (1-based) is the contiguous range of pair numbers
//! `[⌊(K−1)·P/N⌋, ⌊K·P/N⌋)`: the shards hold P/N pairs each, rounded down or up, and depend on
//! nothing but n, `symmetrize`, K and N. Each pair is computed on its own from its two shapes
//! (cold start), so a pair gives the same bits in any shard, tile or whole run.

use crate::distance::directed_pairs;
use crate::error::AnalysisError;

/// Shard `index` (1-based) of `count`.
#[derive(Clone, Copy, Debug, PartialEq, Eq, serde::Serialize, serde::Deserialize)]
pub struct Shard {
    pub index: usize,
    pub count: usize,
}

impl Shard {
    /// Parses `K/N` (1 ≤ K ≤ N).
    pub fn parse(text: &str) -> Result<Shard, AnalysisError> {
        let bad = || {
            AnalysisError::InvalidInput(format!(
                "shard {text:?}: expected K/N with 1 <= K <= N (shard K of N, e.g. 2/8)"
            ))
        };
        let (k, n) = text.split_once('/').ok_or_else(bad)?;
        let index: usize = k.trim().parse().map_err(|_| bad())?;
        let count: usize = n.trim().parse().map_err(|_| bad())?;
        if index == 0 || index > count {
            return Err(bad());
        }
        Ok(Shard { index, count })
    }

    /// The range of pair numbers of this shard among `total` pairs.
    pub fn range(&self, total: usize) -> std::ops::Range<usize> {
        // (u128: no overflow for any pair count)
        let at = |k: usize| (k as u128 * total as u128 / self.count as u128) as usize;
        at(self.index - 1)..at(self.index)
    }

    /// The directed pairs (source, target) of this shard in a run over `n` shapes.
    pub fn pairs(&self, n: usize, symmetrize: bool) -> Vec<(usize, usize)> {
        let total = pair_count(n, symmetrize);
        let range = self.range(total);
        directed_pairs(n, symmetrize)
            .skip(range.start)
            .take(range.len())
            .collect()
    }
}

/// The number of directed pairs of a run over `n` shapes.
pub fn pair_count(n: usize, symmetrize: bool) -> usize {
    let unordered = n * n.saturating_sub(1) / 2;
    if symmetrize {
        2 * unordered
    } else {
        unordered
    }
}

/// The directed pairs of a run over `n` shapes in tiles of at most `size` consecutive pairs
/// (the last one may be shorter): the shards of `⌈P/size⌉` when P is a multiple of `size`.
pub fn tiles(n: usize, symmetrize: bool, size: usize) -> Vec<Vec<(usize, usize)>> {
    let pairs: Vec<(usize, usize)> = directed_pairs(n, symmetrize).collect();
    pairs.chunks(size.max(1)).map(<[_]>::to_vec).collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The shards of any count cover every pair exactly once, in order, with sizes that differ
    /// by at most one.
    #[test]
    fn shards_partition_the_pairs_evenly() {
        for n in [2, 3, 7, 40] {
            for symmetrize in [false, true] {
                let all: Vec<_> = directed_pairs(n, symmetrize).collect();
                assert_eq!(all.len(), pair_count(n, symmetrize));
                for count in [1, 2, 3, 5, 13, 1000] {
                    let shards: Vec<Vec<_>> = (1..=count)
                        .map(|index| Shard { index, count }.pairs(n, symmetrize))
                        .collect();
                    let joined: Vec<_> = shards.iter().flatten().copied().collect();
                    assert_eq!(joined, all, "n {n} count {count}");
                    let sizes: Vec<usize> = shards.iter().map(Vec::len).collect();
                    let (lo, hi) = (sizes.iter().min().unwrap(), sizes.iter().max().unwrap());
                    assert!(hi - lo <= 1, "n {n} count {count}: {sizes:?}");
                }
            }
        }
    }

    #[test]
    fn shard_parsing() {
        assert_eq!(Shard::parse("2/8").unwrap(), Shard { index: 2, count: 8 });
        for bad in ["0/3", "4/3", "3", "a/b", "1/0", ""] {
            let e = Shard::parse(bad).unwrap_err().to_string();
            assert!(e.contains("expected K/N"), "{bad}: {e}");
        }
    }

    #[test]
    fn tiles_cover_the_pairs() {
        let t = tiles(5, false, 4);
        assert_eq!(t.iter().map(Vec::len).collect::<Vec<_>>(), vec![4, 4, 2]);
        assert_eq!(t.concat(), directed_pairs(5, false).collect::<Vec<_>>());
    }
}
