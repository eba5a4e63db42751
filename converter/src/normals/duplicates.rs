//! Repeated positions (a tile written twice, overlapping strips merged): a neighbourhood counts
//! each position once. Otherwise a point stacked k times finds only itself (radius 0, no
//! normal), and a point beside a stack fits its plane to one position weighted k-fold.

use super::kdtree::{Found, KdTree, Pending};

/// The most neighbours a search takes to find k distinct positions among repeats: a point
/// with more repeats than this near it gets fewer than k (counted in `normals.partial`).
const MAX_SEARCHED: usize = 4096;

/// Room for the searches that skip repeats.
#[derive(Default)]
pub struct Distinct {
    all: Found,
    stack: Vec<Pending>,
    pub found: Found,
}

impl Distinct {
    /// Whether two of `near` share a position. Equal distances are rare where no position
    /// repeats, so they are looked for first, without a branch.
    pub fn repeats(tree: &KdTree, near: &Found) -> bool {
        let d = &near.dist;
        // Pairwise without a branch for the usual k; sorted for large ones (k up to 256).
        let tie = if d.len() <= 32 {
            d.iter()
                .enumerate()
                .map(|(i, &a)| d[i + 1..].iter().map(|&b| u32::from(a == b)).sum::<u32>())
                .sum::<u32>()
                > 0
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
    /// `within` (fewer where fewer are that near), each as the first of its repeats in tree
    /// order: nearest first.
    pub fn nearest(&mut self, tree: &KdTree, t: usize, k: usize, within: f64) {
        let mut searched = 2 * k;
        loop {
            tree.nearest(t, searched, within, &mut self.all, &mut self.stack);
            // `nearest` orders equal distances by position, so repeats lie side by side.
            self.found.dist.clear();
            self.found.index.clear();
            let mut last: Option<[f64; 3]> = None;
            for (&d, &j) in self.all.dist.iter().zip(&self.all.index) {
                let p = tree.points[j as usize];
                if last != Some(p) && self.found.len() < k {
                    self.found.dist.push(d);
                    self.found.index.push(j);
                }
                last = Some(p);
            }
            let exhausted = self.all.len() < searched;
            if self.found.len() == k || exhausted || searched >= MAX_SEARCHED {
                return;
            }
            searched = (searched * 4).min(MAX_SEARCHED);
        }
    }
}
