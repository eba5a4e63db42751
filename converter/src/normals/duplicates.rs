//! Repeated positions (a tile written twice, overlapping strips merged): a neighbourhood counts
//! each position once. Otherwise a point stacked k times finds only itself (radius 0, no
//! normal), and a point beside a stack fits its plane to one position weighted k-fold.

use super::kdtree::{Found, KdTree, Pending};

/// Neighbourhoods up to this size are checked for equal distances pair by pair.
const SHORT: usize = 32;

/// Room for the searches that skip repeats.
#[derive(Default)]
pub struct Distinct {
    stack: Vec<Pending>,
    pub found: Found,
    /// The position `found` was searched from: its other repeats, which the search meets one
    /// after another in tree order, take the same neighbours without a search (a heap of a
    /// million points at one position would otherwise search the heap a million times).
    from: Option<[f64; 3]>,
}

impl Distinct {
    /// Whether two of `near` share a position. Equal distances are rare where no position
    /// repeats, so they are looked for first, without a branch.
    pub fn repeats(tree: &KdTree, near: &Found) -> bool {
        let d = &near.dist;
        // Pairwise without a branch for the usual k; sorted for large ones (k up to 256).
        let tie = if d.len() <= SHORT {
            any_equal(d)
        } else {
            let mut sorted = d.clone();
            sorted.sort_unstable_by(f64::total_cmp);
            sorted.windows(2).any(|w| w[0] == w[1])
        };
        tie && (0..d.len()).any(|i| {
            (i + 1..d.len()).any(|j| {
                d[i] == d[j]
                    && tree.points[near.index[i] as usize] == tree.points[near.index[j] as usize]
            })
        })
    }

    /// Into `self.found`, the `k` nearest distinct positions to tree point `t` within
    /// `within` (fewer where fewer are that near), one point for each: nearest first.
    pub fn nearest(&mut self, tree: &KdTree, t: usize, k: usize, within: f64) {
        let at = tree.points[t];
        if self.from != Some(at) {
            tree.nearest_distinct(t, k, within, &mut self.found, &mut self.stack);
            self.from = Some(at);
        }
    }
}

/// Whether two of `d` (at most `SHORT`, none NaN) are equal.
fn any_equal(d: &[f64]) -> bool {
    // The default k as a constant, so that the loops unroll.
    if d.len() == 16 {
        equal_pair(d, 16)
    } else {
        equal_pair(d, d.len())
    }
}

/// Whether two of the `n` values of `d` are equal. Each pair is some value and the one `s`
/// places after it, cyclically, for a shift `s` of at most half the length: the comparisons of
/// a shift run over contiguous slices, which vectorise, where the triangle of pairs did not.
#[inline(always)]
fn equal_pair(d: &[f64], n: usize) -> bool {
    let d = &d[..n];
    let equal = |a: &[f64], b: &[f64]| {
        a.iter()
            .zip(b)
            .fold(0u64, |e, (x, y)| e | u64::from(x == y))
    };
    let mut any = 0u64;
    for s in 1..=n / 2 {
        // Value i against i + s, and those past the end against the start.
        any |= equal(&d[..n - s], &d[s..]) | equal(&d[n - s..], &d[..s]);
    }
    any != 0
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::synth::Rng;

    #[test]
    fn any_equal_finds_every_pair() {
        let mut rng = Rng::new(3, 1, 2);
        for n in 0..=SHORT {
            let distinct: Vec<f64> = (0..n).map(|i| i as f64 + rng.unit() * 0.5).collect();
            assert!(!any_equal(&distinct), "{distinct:?}");
            // Each pair in turn made equal, whatever the gap between them.
            for i in 0..n {
                for j in i + 1..n {
                    let mut d = distinct.clone();
                    d[j] = d[i];
                    assert!(any_equal(&d), "{i} {j} of {n}");
                }
            }
        }
    }
}
