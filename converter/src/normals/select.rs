//! The k nearest of the points a search took, without the mispredicted branches of a
//! comparison selection: the k-th distance is found by partitions around a guessed value,
//! each writing every distance to both ends of a buffer and keeping the write its side wants,
//! so that no branch depends on a distance; a few rounds leave a handful for an ordinary
//! selection. The points themselves are then picked in one pass.

/// Rounds of guessing before the remaining distances are selected by comparison.
const ROUNDS: usize = 4;

/// The points a search took (squared distance, tree index), room to partition their
/// distances, and those picked.
#[derive(Debug, Default)]
pub(super) struct Taken {
    pub points: Vec<(f64, u32)>,
    spare: [Vec<f64>; 2],
    /// Longer than what it holds, so that picking writes without growing it.
    pub picked: Vec<(f64, u32)>,
}

impl Taken {
    /// Into `self.picked`, the points of `self.points[..m]` (squared distances, all within
    /// `bound`) no farther than the k-th nearest, in no order: `k` of them, or more where
    /// several share the k-th distance (the caller settles those ties). Returns how many.
    /// Leaves `self.points` as it was.
    pub fn select_nearest(&mut self, m: usize, k: usize, bound: f64) -> usize {
        if self.picked.len() < m {
            self.picked.resize(m, (0.0, 0));
        }
        if m <= k {
            self.picked[..m].copy_from_slice(&self.points[..m]);
            return m;
        }
        let kth = self.kth_distance(m, k, bound);
        let mut n = 0;
        for &p in &self.points[..m] {
            self.picked[n] = p;
            n += usize::from(p.0 <= kth);
        }
        n
    }

    /// The k-th smallest squared distance of `self.points[..m]` (m > k ≥ 1).
    fn kth_distance(&mut self, m: usize, k: usize, bound: f64) -> f64 {
        let Taken { points, spare, .. } = self;
        let [one, two] = spare;
        for s in [&mut *one, &mut *two] {
            if s.len() < m {
                s.resize(m, 0.0);
            }
        }
        // The squared distances of points on a surface spread about evenly over 0..bound,
        // so the k-th of n is guessed at k/n of the way; each round narrows the range.
        let (mut lo, mut hi) = (0.0f64, bound);
        let (mut need, mut start, mut len) = (k, 0, m);
        for round in 0..ROUNDS {
            let (src, dst) = if round % 2 == 0 {
                (&one[..], &mut two[..])
            } else {
                (&two[..], &mut one[..])
            };
            let pivot = lo + (hi - lo) * (need as f64 * reciprocal(len));
            // Nearer than the pivot to the front, the rest to the back.
            let (mut near, mut far) = (0, 0);
            let mut part = |d: f64| {
                let below = d < pivot;
                dst[near] = d;
                dst[len - 1 - far] = d;
                near += usize::from(below);
                far += usize::from(!below);
            };
            if round == 0 {
                points[..m].iter().for_each(|p| part(p.0));
            } else {
                src[start..start + len].iter().for_each(|&d| part(d));
            }
            if near == need {
                // The nearest `need` of the range, so the k-th is the farthest of them.
                return dst[..near].iter().fold(0.0, |x, &d| x.max(d));
            }
            // Which side holds the k-th, chosen without a branch: it goes either way about
            // as often, and a mispredicted branch costs more than the choice.
            let below = near > need;
            start = if below { 0 } else { near };
            len = if below { near } else { len - near };
            hi = if below { pivot } else { hi };
            lo = if below { lo } else { pivot };
            need = if below { need } else { need - near };
        }
        // `need` of `len` (more than `need`) remain, in the buffer the last round wrote.
        let rest = if ROUNDS % 2 == 1 { two } else { one };
        let rest = &mut rest[start..start + len];
        *rest.select_nth_unstable_by(need - 1, f64::total_cmp).1
    }
}

/// 1 / n, from a table for the usual sizes: a division's latency would lie on the path
/// from one round to the next.
#[inline]
fn reciprocal(n: usize) -> f64 {
    const TABLE: [f64; 64] = {
        let mut t = [0.0; 64];
        let mut i = 1;
        while i < 64 {
            t[i] = 1.0 / i as f64;
            i += 1;
        }
        t
    };
    match TABLE.get(n) {
        Some(&r) if n > 0 => r,
        _ => 1.0 / n as f64,
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::synth::Rng;

    fn check(distances: &[f64], k: usize) {
        let bound = distances.iter().fold(0.0f64, |m, &d| m.max(d));
        let mut taken = Taken {
            points: distances
                .iter()
                .enumerate()
                .map(|(i, &d)| (d, i as u32))
                .collect(),
            ..Taken::default()
        };
        let before = taken.points.clone();
        let n = taken.select_nearest(distances.len(), k, bound);
        let out = &taken.picked[..n];
        assert_eq!(
            taken.points, before,
            "the points taken are left as they were"
        );
        let mut sorted = distances.to_vec();
        sorted.sort_by(f64::total_cmp);
        let kth = sorted[k.min(sorted.len()) - 1];
        // Exactly those within the k-th distance, ties included.
        let want: Vec<u32> = (0..distances.len() as u32)
            .filter(|&i| distances[i as usize] <= kth)
            .collect();
        let mut got: Vec<u32> = out.iter().map(|p| p.1).collect();
        got.sort_unstable();
        assert_eq!(got, want, "k = {k} of {distances:?}");
        for &(d, i) in out {
            assert_eq!(distances[i as usize], d);
        }
    }

    #[test]
    fn reciprocals_from_the_table_are_the_quotients() {
        for n in 1..200 {
            assert_eq!(reciprocal(n), 1.0 / n as f64, "{n}");
        }
    }

    #[test]
    fn selects_the_points_within_the_kth_distance_of_any_spread() {
        let mut rng = Rng::new(7, 1, 2);
        for m in [1usize, 2, 5, 16, 17, 31, 32, 33, 64, 200] {
            for k in [1usize, 2, 8, 16, 24] {
                // Even over the range, crowded near zero, crowded near the bound, with many
                // equal, and all equal.
                let even: Vec<f64> = (0..m).map(|_| rng.unit()).collect();
                let near: Vec<f64> = (0..m).map(|_| rng.unit().powi(6)).collect();
                let far: Vec<f64> = (0..m).map(|_| 1.0 - rng.unit().powi(6)).collect();
                let equal: Vec<f64> = (0..m).map(|_| (rng.unit() * 3.0).floor()).collect();
                let same = vec![0.25; m];
                let zero = vec![0.0; m];
                for d in [even, near, far, equal, same, zero] {
                    check(&d, k);
                }
            }
        }
    }
}
