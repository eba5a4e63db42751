//! Putting a chunk's rows in Morton (Z) order, so that every octree node below the chunk, and
//! every sampling cell of a node, is one contiguous run of rows: splitting a node becomes a
//! binary search and sampling a single pass, with no per-level sorting.

/// Bits per axis a key holds at most. Coarse keys sort in few passes; a node finer than its
/// chunk's key sorts its own points again (see `tree`).
pub const KEY_BITS: u32 = 12;

/// Spreads the low 21 bits of `v` to every third bit.
#[inline]
fn spread(v: u64) -> u64 {
    let mut x = v & 0x1f_ffff;
    x = (x | (x << 32)) & 0x001f_0000_0000_ffff;
    x = (x | (x << 16)) & 0x001f_0000_ff00_00ff;
    x = (x | (x << 8)) & 0x100f_00f0_0f00_f00f;
    x = (x | (x << 4)) & 0x10c3_0c30_c30c_30c3;
    x = (x | (x << 2)) & 0x1249_2492_4924_9249;
    x
}

/// The Morton key of a cell: x in the highest bit of each triple, so octants 0..7 (x<<2|y<<1|z)
/// come out in key order.
#[inline]
pub fn key(c: [u64; 3]) -> u64 {
    (spread(c[0]) << 2) | (spread(c[1]) << 1) | spread(c[2])
}

/// Buffers a sort reuses from one call to the next.
#[derive(Debug, Default)]
pub struct SortScratch {
    keys: Vec<u64>,
    /// The bits of a key that hold the position's index.
    index_mask: u64,
    spare: Vec<u64>,
    pos: Vec<[i32; 3]>,
    order: Vec<u32>,
}

/// Stable LSD radix sort of `keys` on bits `from..to`; `scratch` is any buffer.
pub fn radix_sort(keys: &mut Vec<u64>, scratch: &mut Vec<u64>, from: u32, to: u32) {
    const DIGIT: u32 = 12;
    const BUCKETS: usize = 1 << DIGIT;
    scratch.clear();
    scratch.resize(keys.len(), 0);
    let mut counts = vec![0usize; BUCKETS];
    let mut shift = from;
    while shift < to {
        counts.fill(0);
        for &k in keys.iter() {
            counts[((k >> shift) as usize) & (BUCKETS - 1)] += 1;
        }
        // A digit every key shares leaves the order as it is.
        if counts.contains(&keys.len()) {
            shift += DIGIT;
            continue;
        }
        let mut at = 0;
        for c in counts.iter_mut() {
            let n = *c;
            *c = at;
            at += n;
        }
        for &k in keys.iter() {
            let b = ((k >> shift) as usize) & (BUCKETS - 1);
            scratch[counts[b]] = k;
            counts[b] += 1;
        }
        std::mem::swap(keys, scratch);
        shift += DIGIT;
    }
}

/// Sorts `pos` (and `order` alongside) into Morton order within the node at integer corner
/// `node_min` with edge `2^node_bits`. Returns the order's resolution: the shift below which
/// positions are not told apart (such ties keep their order).
pub fn sort_positions(
    pos: &mut [[i32; 3]],
    order: &mut [u32],
    node_min: [i64; 3],
    node_bits: u32,
    scratch: &mut SortScratch,
) -> u32 {
    let shift = sort_keys(pos, node_min, node_bits, scratch);
    if scratch.is_identity() {
        return shift;
    }
    let SortScratch {
        keys,
        index_mask,
        pos: old_pos,
        order: old_order,
        ..
    } = scratch;
    old_pos.clear();
    old_pos.extend_from_slice(pos);
    old_order.clear();
    old_order.extend_from_slice(order);
    for (j, k) in keys.iter().enumerate() {
        let i = (k & *index_mask) as usize;
        pos[j] = old_pos[i];
        order[j] = old_order[i];
    }
    shift
}

/// Sorts the Morton keys of `pos` (as `sort_positions` orders them) into `scratch`, leaving
/// `pos` as it is: `scratch.sorted_indices()` then gives the order. Returns the resolution, as
/// `sort_positions` does.
pub fn sort_keys(
    pos: &[[i32; 3]],
    node_min: [i64; 3],
    node_bits: u32,
    scratch: &mut SortScratch,
) -> u32 {
    let n = pos.len();
    // Key and local index share one u64: the key above, the index below.
    let index_bits = (usize::BITS - n.leading_zeros()).max(1);
    let kbits = node_bits.min(KEY_BITS).min((64 - index_bits) / 3);
    let shift = node_bits - kbits;
    let keys = &mut scratch.keys;
    keys.clear();
    keys.extend(pos.iter().enumerate().map(|(i, p)| {
        let c = |a: usize| ((p[a] as i64 - node_min[a]) >> shift) as u64;
        (key([c(0), c(1), c(2)]) << index_bits) | i as u64
    }));
    radix_sort(keys, &mut scratch.spare, index_bits, index_bits + 3 * kbits);
    scratch.index_mask = (1u64 << index_bits) - 1;
    shift
}

impl SortScratch {
    /// After `sort_keys`: the index in `pos` of each position, in Morton order.
    pub fn sorted_indices(&self) -> impl ExactSizeIterator<Item = usize> + '_ {
        self.keys.iter().map(|k| (k & self.index_mask) as usize)
    }

    /// After `sort_keys`: whether the positions were in Morton order already.
    fn is_identity(&self) -> bool {
        self.sorted_indices().enumerate().all(|(j, i)| i == j)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn keys_interleave_x_highest() {
        assert_eq!(key([1, 0, 0]), 0b100);
        assert_eq!(key([0, 1, 0]), 0b010);
        assert_eq!(key([0, 0, 1]), 0b001);
        assert_eq!(key([2, 0, 0]), 0b100_000);
        let max = (1u64 << 21) - 1;
        assert_eq!(key([max, max, max]), (1u64 << 63) - 1);
    }

    #[test]
    fn radix_sort_is_stable_and_ordered() {
        let mut keys: Vec<u64> = (0..5000u64)
            .map(|i| ((i * 7919) % 1000) << 13 | i)
            .collect();
        let mut expect = keys.clone();
        expect.sort_by_key(|k| k >> 13);
        radix_sort(&mut keys, &mut Vec::new(), 13, 64);
        assert_eq!(keys, expect);
    }

    /// `sort_keys` gives the order `sort_positions` puts positions in, so a chunk gathered by
    /// it is the same rows in the same order: at a node wider than the key (ties below its
    /// resolution), narrower, and already in order.
    #[test]
    fn sorted_keys_give_the_order_sort_positions_makes() {
        let mut rng = crate::synth::Rng::new(5, 0, 0);
        for (bits, n) in [(20u32, 5000usize), (8, 3000), (20, 1)] {
            let side = (1u64 << bits) as f64;
            let pos: Vec<[i32; 3]> = (0..n)
                .map(|_| [0, 1, 2].map(|_| (rng.unit() * side) as i32 - 7))
                .collect();
            let min = [-7i64; 3];
            for input in [pos.clone(), {
                let mut p = pos.clone();
                let mut o: Vec<u32> = (0..n as u32).collect();
                sort_positions(&mut p, &mut o, min, bits, &mut SortScratch::default());
                p
            }] {
                let (mut sorted, mut order) = (input.clone(), (0..n as u32).collect::<Vec<_>>());
                let shift = sort_positions(
                    &mut sorted,
                    &mut order,
                    min,
                    bits,
                    &mut SortScratch::default(),
                );
                let mut scratch = SortScratch::default();
                assert_eq!(sort_keys(&input, min, bits, &mut scratch), shift);
                let indices: Vec<usize> = scratch.sorted_indices().collect();
                assert_eq!(
                    indices,
                    order.iter().map(|&o| o as usize).collect::<Vec<_>>()
                );
                let gathered: Vec<[i32; 3]> = indices.iter().map(|&i| input[i]).collect();
                assert_eq!(gathered, sorted, "{bits} bits, {n} positions");
            }
        }
    }

    #[test]
    fn sorted_positions_put_each_octant_together() {
        let pts: Vec<[i32; 3]> = (0..1000)
            .map(|i| [(i * 37) % 64, (i * 11) % 64, (i * 5) % 64])
            .collect();
        let mut pos = pts.clone();
        let mut order: Vec<u32> = (0..1000).collect();
        let mut scratch = SortScratch::default();
        let shift = sort_positions(&mut pos, &mut order, [0, 0, 0], 6, &mut scratch);
        assert_eq!(shift, 0);
        let octant = |p: &[i32; 3]| ((p[0] >> 5) << 2 | (p[1] >> 5) << 1 | (p[2] >> 5)) as u8;
        assert!(pos.windows(2).all(|w| octant(&w[0]) <= octant(&w[1])));
        for (p, &o) in pos.iter().zip(&order) {
            assert_eq!(*p, pts[o as usize]);
        }
        let mut seen = order.clone();
        seen.sort();
        assert_eq!(seen, (0..1000).collect::<Vec<u32>>());
    }
}
