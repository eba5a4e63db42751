//! A chunk's rows put in the order its neighbour search visits them, in place: a copy in
//! that order would be a second buffer the size of the rows, its pages new to the process
//! and zeroed by the kernel, for every chunk.

/// Reorders the rows of `rows` (`stride` bytes each) so that row `i` becomes the one at
/// `source[i]` before; `source` is a permutation of `0..rows.len() / stride`. Each cycle of
/// the permutation is followed once, so every row moves once; the row a step reads is the
/// one the next step overwrites, so that write finds it in cache.
pub fn permute_rows(rows: &mut [u8], stride: usize, source: &[u32]) {
    let n = source.len();
    debug_assert_eq!(rows.len(), n * stride);
    let mut placed = vec![false; n];
    let mut held = vec![0u8; stride];
    for start in 0..n {
        if placed[start] || source[start] as usize == start {
            continue;
        }
        held.copy_from_slice(&rows[start * stride..(start + 1) * stride]);
        let mut at = start;
        loop {
            placed[at] = true;
            let from = source[at] as usize;
            if from == start {
                rows[at * stride..(at + 1) * stride].copy_from_slice(&held);
                break;
            }
            rows.copy_within(from * stride..(from + 1) * stride, at * stride);
            at = from;
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::synth::Rng;

    #[test]
    fn rows_land_where_the_permutation_says() {
        let mut rng = Rng::new(9, 1, 2);
        for n in [0usize, 1, 2, 7, 100, 1000] {
            let stride = 5;
            let rows: Vec<u8> = (0..n * stride).map(|i| (i * 31 + i / 7) as u8).collect();
            // A random permutation, and the identity, and a reversal.
            let mut random: Vec<u32> = (0..n as u32).collect();
            for i in (1..n).rev() {
                let j = (rng.unit() * (i + 1) as f64) as usize;
                random.swap(i, j.min(i));
            }
            let identity: Vec<u32> = (0..n as u32).collect();
            let reversed: Vec<u32> = (0..n as u32).rev().collect();
            for source in [random, identity, reversed] {
                let mut moved = rows.clone();
                permute_rows(&mut moved, stride, &source);
                for (i, &s) in source.iter().enumerate() {
                    let s = s as usize;
                    assert_eq!(
                        moved[i * stride..(i + 1) * stride],
                        rows[s * stride..(s + 1) * stride],
                        "row {i} of {n}"
                    );
                }
            }
        }
    }
}
