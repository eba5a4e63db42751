//! The byte grouping of the row work files (see `rowfile`): every row's first byte, then every
//! row's second, and back. Blocks of 8 rows by 8 bytes move as eight 64-bit words transposed
//! in registers, rather than a byte at a time: the grouping runs over every row a conversion
//! writes or reads, and byte by byte it took about 6 % of a conversion's time.

/// Rows per tile: 256 rows of a typical 30 to 60 byte stride fill about half of a 32 KiB
/// first-level cache, so the rows stay there while each of their columns is read or written.
const TILE: usize = 256;

/// Groups the bytes of `rows` (of `stride` bytes each) by their place in the row, into `out`.
pub fn shuffle(rows: &[u8], stride: usize, out: &mut Vec<u8>) {
    let n = rows.len() / stride.max(1);
    out.clear();
    out.resize(n * stride, 0);
    for_each_block(n, stride, |r0, j0, whole| {
        if !whole {
            out[j0 * n + r0] = rows[r0 * stride + j0];
            return;
        }
        let mut words = [0u64; 8];
        for (i, w) in words.iter_mut().enumerate() {
            let at = (r0 + i) * stride + j0;
            *w = word(&rows[at..at + 8]);
        }
        transpose(&mut words);
        for (c, w) in words.iter().enumerate() {
            let at = (j0 + c) * n + r0;
            out[at..at + 8].copy_from_slice(&w.to_le_bytes());
        }
    });
}

/// Appends to `out` the rows whose bytes `grouped` holds grouped by place in the row.
pub fn unshuffle(grouped: &[u8], stride: usize, out: &mut Vec<u8>) {
    let n = grouped.len() / stride.max(1);
    let start = out.len();
    out.resize(start + n * stride, 0);
    let rows = &mut out[start..];
    for_each_block(n, stride, |r0, j0, whole| {
        if !whole {
            rows[r0 * stride + j0] = grouped[j0 * n + r0];
            return;
        }
        let mut words = [0u64; 8];
        for (c, w) in words.iter_mut().enumerate() {
            let at = (j0 + c) * n + r0;
            *w = word(&grouped[at..at + 8]);
        }
        transpose(&mut words);
        for (i, w) in words.iter().enumerate() {
            let at = (r0 + i) * stride + j0;
            rows[at..at + 8].copy_from_slice(&w.to_le_bytes());
        }
    });
}

/// Calls `visit(r0, j0, true)` for every whole block of 8 rows from `r0` by 8 bytes from
/// `j0`, and `visit(r, j, false)` for every byte `j` of row `r` outside them, a tile of rows at
/// a time.
fn for_each_block(n: usize, stride: usize, mut visit: impl FnMut(usize, usize, bool)) {
    let whole_bytes = stride - stride % 8;
    for t0 in (0..n).step_by(TILE) {
        let t1 = (t0 + TILE).min(n);
        let whole_rows = t0 + (t1 - t0) / 8 * 8;
        for j0 in (0..whole_bytes).step_by(8) {
            for r0 in (t0..whole_rows).step_by(8) {
                visit(r0, j0, true);
            }
        }
        for j in whole_bytes..stride {
            for r in t0..whole_rows {
                visit(r, j, false);
            }
        }
        for r in whole_rows..t1 {
            for j in 0..stride {
                visit(r, j, false);
            }
        }
    }
}

/// Eight bytes as a little-endian word.
#[inline]
fn word(bytes: &[u8]) -> u64 {
    let mut w = [0u8; 8];
    w.copy_from_slice(bytes);
    u64::from_le_bytes(w)
}

/// Transposes the 8 x 8 bytes of `m` (byte `j` of word `i`, little endian, is entry (i, j)):
/// the off-diagonal 4 x 4 blocks swap, then the 2 x 2 blocks within each, then the bytes.
#[inline]
fn transpose(m: &mut [u64; 8]) {
    for (half, mask, pairs) in [
        (32, 0x0000_0000_ffff_ffff_u64, [0, 1, 2, 3]),
        (16, 0x0000_ffff_0000_ffff, [0, 1, 4, 5]),
        (8, 0x00ff_00ff_00ff_00ff, [0, 2, 4, 6]),
    ] {
        let other = half / 8;
        for i in pairs {
            let t = ((m[i] >> half) ^ m[i + other]) & mask;
            m[i] ^= t << half;
            m[i + other] ^= t;
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn unshuffle_undoes_shuffle() {
        // Row counts around the block and tile sizes, strides below, at and around multiples
        // of the block's 8 bytes.
        for n in [0, 1, 7, 8, 9, 200, 255, 256, 257, 600] {
            for stride in [1, 3, 8, 13, 16, 37, 40] {
                let rows: Vec<u8> = (0..n * stride).map(|i| (i * 7 + i / 13) as u8).collect();
                let mut grouped = Vec::new();
                shuffle(&rows, stride, &mut grouped);
                // Byte j of row r sits at j·n + r.
                for r in 0..n {
                    for j in 0..stride {
                        assert_eq!(grouped[j * n + r], rows[r * stride + j], "{n} {stride}");
                    }
                }
                let mut back = vec![9u8; 3];
                unshuffle(&grouped, stride, &mut back);
                assert_eq!(&back[..3], &[9, 9, 9], "appended after what was there");
                assert_eq!(&back[3..], &rows[..], "{n} rows of {stride}");
            }
        }
    }

    #[test]
    fn transposes_a_block() {
        let mut m: [u64; 8] =
            std::array::from_fn(|i| u64::from_le_bytes(std::array::from_fn(|j| (i * 8 + j) as u8)));
        transpose(&mut m);
        for (i, w) in m.iter().enumerate() {
            let want: [u8; 8] = std::array::from_fn(|j| (j * 8 + i) as u8);
            assert_eq!(w.to_le_bytes(), want, "word {i}");
        }
    }
}
