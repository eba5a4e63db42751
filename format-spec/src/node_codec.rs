//! Node payloads: points in column order, LZ4-compressed, protected by CRC-32.

use crate::RowLayout;
use crate::node_key::NodeKey;

/// Encodes rows (each `layout.stride` bytes) into a stored node payload. Returns the payload and
/// its CRC-32. A node of no points has no payload (empty, CRC 0), not an LZ4 block of nothing.
pub fn encode_node(rows: &[u8], layout: &RowLayout) -> (Vec<u8>, u32) {
    let n = rows.len() / layout.stride;
    encode_node_rows(rows, &(0..n as u32).collect::<Vec<_>>(), layout)
}

/// `encode_node` of the rows numbered `which` in `rows`, without gathering them first.
pub fn encode_node_rows(rows: &[u8], which: &[u32], layout: &RowLayout) -> (Vec<u8>, u32) {
    if which.is_empty() {
        return (Vec::new(), 0);
    }
    let columns = rows_to_columns(rows, which, layout);
    let payload = lz4_flex::block::compress(&columns);
    let crc = payload_checksum(&payload);
    (payload, crc)
}

/// The checksum a node record stores for its payload (CRC-32; 0 for an empty payload).
pub fn payload_checksum(payload: &[u8]) -> u32 {
    crc32fast::hash(payload)
}

/// Why a stored payload could not be decoded.
#[derive(Debug, Clone, PartialEq, Eq)]
pub enum NodeDecodeError {
    Checksum { stored: u32, computed: u32 },
    Decompress(String),
}

impl std::fmt::Display for NodeDecodeError {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            NodeDecodeError::Checksum { stored, computed } => write!(
                f,
                "checksum mismatch (hierarchy says {stored:#010x}, payload has {computed:#010x})"
            ),
            NodeDecodeError::Decompress(e) => write!(f, "payload does not decompress ({e})"),
        }
    }
}

/// A decoded node: `count` points, uncompressed columns (x, y, z as i32, then each attribute).
#[derive(Debug, Clone)]
pub struct NodeColumns {
    pub count: usize,
    pub bytes: Vec<u8>,
}

impl NodeColumns {
    /// The integer position of point `i`.
    pub fn position(&self, i: usize) -> [i32; 3] {
        let col = |c: usize| {
            let at = (c * self.count + i) * 4;
            i32::from_le_bytes([
                self.bytes[at],
                self.bytes[at + 1],
                self.bytes[at + 2],
                self.bytes[at + 3],
            ])
        };
        [col(0), col(1), col(2)]
    }

    /// The first point outside the cube of `key` (in a dataset cube of `2^cube_bits` units
    /// from `cube_min`), where one is.
    pub fn first_outside(&self, key: NodeKey, cube_min: [i64; 3], cube_bits: u32) -> Option<usize> {
        let (min, edge) = key.int_bounds(cube_min, cube_bits);
        (0..self.count).find(|&i| {
            let p = self.position(i);
            (0..3).any(|a| {
                let v = p[a] as i64;
                v < min[a] || v >= min[a] + edge
            })
        })
    }

    /// The bytes of attribute column `index` of `layout` (count * attribute size bytes).
    pub fn attribute(&self, layout: &RowLayout, index: usize) -> &[u8] {
        let start = (layout.offsets[index]) * self.count;
        &self.bytes[start..start + layout.attributes[index].size() * self.count]
    }

    /// Transposes back into rows of `layout.stride` bytes.
    pub fn to_rows(&self, layout: &RowLayout) -> Vec<u8> {
        let n = self.count;
        let mut rows = vec![0u8; n * layout.stride];
        // An inner node may hold no point (SPEC section 3): slicing its rows at a field's
        // offset would be out of range.
        if n == 0 {
            return rows;
        }
        let mut fields: Vec<(usize, usize)> = vec![(0, 4), (4, 4), (8, 4)];
        fields.extend(
            layout
                .offsets
                .iter()
                .zip(&layout.attributes)
                .map(|(o, a)| (*o, a.size())),
        );
        let stride = layout.stride;
        for (field_offset, size) in fields {
            let col = &self.bytes[field_offset * n..field_offset * n + size * n];
            let dst = &mut rows[field_offset..];
            // A loop per field width the compiler can unroll: a copy of unknown length per
            // point and field costs a call each.
            macro_rules! copy {
                ($w:literal) => {
                    for (v, row) in col.chunks_exact($w).zip(dst.chunks_mut(stride)) {
                        row[..$w].copy_from_slice(v);
                    }
                };
            }
            match size {
                1 => copy!(1),
                2 => copy!(2),
                4 => copy!(4),
                6 => copy!(6),
                8 => copy!(8),
                12 => copy!(12),
                _ => {
                    for (v, row) in col.chunks_exact(size).zip(dst.chunks_mut(stride)) {
                        row[..size].copy_from_slice(v);
                    }
                }
            }
        }
        rows
    }
}

/// Verifies and decompresses a stored node payload of `count` points. A node of no points has
/// an empty payload (1.1), or the one-byte LZ4 block of nothing that 1.0 writers stored.
pub fn decode_node(
    payload: &[u8],
    count: usize,
    expected_crc: u32,
    layout: &RowLayout,
) -> Result<NodeColumns, NodeDecodeError> {
    if count == 0 && payload.is_empty() && expected_crc == 0 {
        return Ok(NodeColumns {
            count,
            bytes: Vec::new(),
        });
    }
    let computed = payload_checksum(payload);
    if computed != expected_crc {
        return Err(NodeDecodeError::Checksum {
            stored: expected_crc,
            computed,
        });
    }
    // The payload's own sequence headers say how many bytes it decodes to: a count that needs
    // other than that is a damaged entry, refused before anything is allocated for it.
    let expected = count.checked_mul(layout.stride);
    let decoded = lz4_decoded_len(payload);
    let expected = match (expected, decoded) {
        (Some(e), Some(d)) if e == d => e,
        (_, Some(d)) => {
            return Err(NodeDecodeError::Decompress(format!(
                "{count} points need {} bytes, and the payload decodes to {d}",
                count as u128 * layout.stride as u128
            )));
        }
        (_, None) => {
            return Err(NodeDecodeError::Decompress(
                "the payload's LZ4 sequences end early".into(),
            ));
        }
    };
    // Only a payload that truly decodes to this much gets here; an allocation the system
    // refuses outright is still an error, not an abort (one it overcommits is not caught).
    let mut bytes = Vec::new();
    bytes.try_reserve_exact(expected).map_err(|_| {
        NodeDecodeError::Decompress(format!(
            "{count} points take {expected} bytes, more than can be allocated"
        ))
    })?;
    bytes.resize(expected, 0);
    let got = lz4_flex::block::decompress_into(payload, &mut bytes)
        .map_err(|e| NodeDecodeError::Decompress(e.to_string()))?;
    if got != expected {
        return Err(NodeDecodeError::Decompress(format!(
            "{got} bytes where {count} points need {expected}"
        )));
    }
    Ok(NodeColumns { count, bytes })
}

/// The bytes an LZ4 block decodes to, from its sequences' lengths alone (no output is made);
/// `None` where a sequence runs past the block's end.
fn lz4_decoded_len(block: &[u8]) -> Option<usize> {
    // A length of 15 in a token's nibble goes on in bytes, each added, until one below 255.
    fn length(block: &[u8], at: &mut usize, nibble: usize) -> Option<usize> {
        let mut n = nibble;
        if nibble == 15 {
            loop {
                let b = *block.get(*at)?;
                *at += 1;
                n = n.checked_add(b as usize)?;
                if b != 255 {
                    break;
                }
            }
        }
        Some(n)
    }
    let (mut at, mut total) = (0usize, 0usize);
    while at < block.len() {
        let token = block[at] as usize;
        at += 1;
        let literals = length(block, &mut at, token >> 4)?;
        at = at.checked_add(literals).filter(|&a| a <= block.len())?;
        total = total.checked_add(literals)?;
        // The last sequence is literals alone.
        if at == block.len() {
            return Some(total);
        }
        // Two bytes of match offset, then the match's length beyond its least, 4.
        at = at.checked_add(2).filter(|&a| a <= block.len())?;
        let matched = length(block, &mut at, token & 15)?;
        total = total.checked_add(matched)?.checked_add(4)?;
    }
    // An empty block decodes to nothing; any other ends in literals.
    block.is_empty().then_some(0)
}

/// Column order: for each field (x, y, z, attributes...), that field of every point in turn.
/// Column-major payloads compress markedly better than rows with LZ4.
fn rows_to_columns(rows: &[u8], which: &[u32], layout: &RowLayout) -> Vec<u8> {
    let stride = layout.stride;
    let n = which.len();
    let mut out = vec![0u8; n * stride];
    let mut write_field = |field_offset: usize, size: usize| {
        let dst = &mut out[field_offset * n..field_offset * n + size * n];
        match size {
            1 => gather::<1>(dst, rows, which, stride, field_offset),
            2 => gather::<2>(dst, rows, which, stride, field_offset),
            4 => gather::<4>(dst, rows, which, stride, field_offset),
            8 => gather::<8>(dst, rows, which, stride, field_offset),
            _ => {
                for (d, &i) in dst.chunks_exact_mut(size).zip(which) {
                    let at = i as usize * stride + field_offset;
                    d.copy_from_slice(&rows[at..at + size]);
                }
            }
        }
    };
    write_field(0, 4);
    write_field(4, 4);
    write_field(8, 4);
    for (o, a) in layout.offsets.iter().zip(&layout.attributes) {
        write_field(*o, a.size());
    }
    out
}

/// One field of the chosen rows into a column; a fixed size makes each copy a single move.
fn gather<const N: usize>(dst: &mut [u8], rows: &[u8], which: &[u32], stride: usize, at: usize) {
    for (d, &i) in dst.chunks_exact_mut(N).zip(which) {
        let o = i as usize * stride + at;
        d.copy_from_slice(&rows[o..o + N]);
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::{AttrType, Attribute};

    fn layout() -> RowLayout {
        RowLayout::new(vec![
            Attribute::new("intensity", AttrType::U16, 1),
            Attribute::new("rgb", AttrType::U16, 3),
            Attribute::new("gps_time", AttrType::F64, 1),
        ])
    }

    #[test]
    fn round_trips_rows_through_columns() {
        let l = layout();
        let n = 1000;
        let rows: Vec<u8> = (0..n * l.stride).map(|i| (i * 7 % 251) as u8).collect();
        let (payload, crc) = encode_node(&rows, &l);
        let node = decode_node(&payload, n, crc, &l).expect("decodes");
        assert_eq!(node.to_rows(&l), rows);
        let first = &rows[0..12];
        assert_eq!(node.position(0), crate::row_position(first));
    }

    #[test]
    fn an_empty_node_has_no_payload_and_1_0_empty_payloads_still_decode() {
        let l = layout();
        let (payload, crc) = encode_node(&[], &l);
        assert!(payload.is_empty());
        assert_eq!(crc, 0);
        assert_eq!(decode_node(&payload, 0, crc, &l).map(|n| n.count), Ok(0));
        let empty = decode_node(&payload, 0, crc, &l).expect("decodes");
        assert!(empty.to_rows(&l).is_empty(), "no rows, and no panic");
        // What 1.0 writers stored for a node of no points.
        let old = lz4_flex::block::compress(&[]);
        assert_eq!(old.len(), 1);
        let old_crc = crc32fast::hash(&old);
        assert_eq!(decode_node(&old, 0, old_crc, &l).map(|n| n.count), Ok(0));
        assert!(decode_node(&[], 3, 0, &l).is_err());
    }

    #[test]
    fn any_flipped_byte_is_caught() {
        let l = layout();
        let rows: Vec<u8> = (0..50 * l.stride).map(|i| (i % 13) as u8).collect();
        let (payload, crc) = encode_node(&rows, &l);
        for i in 0..payload.len() {
            let mut bad = payload.clone();
            bad[i] ^= 0x40;
            assert!(matches!(
                decode_node(&bad, 50, crc, &l),
                Err(NodeDecodeError::Checksum { .. })
            ));
        }
    }

    /// The decoded size read from the sequences is the size LZ4 makes, for data that
    /// compresses not at all, some, and 255-fold.
    #[test]
    fn the_sequences_say_how_long_a_block_decodes() {
        let noisy: Vec<u8> = (0..5000u32)
            .map(|i| (i.wrapping_mul(2654435761) >> 13) as u8)
            .collect();
        let mixed: Vec<u8> = (0..70_000u32).map(|i| (i / 300 % 7) as u8).collect();
        for data in [noisy, mixed, vec![0u8; 1 << 20], vec![9u8; 5], Vec::new()] {
            let block = lz4_flex::block::compress(&data);
            assert_eq!(lz4_decoded_len(&block), Some(data.len()));
            // Cut by a byte, the last literals run past the end.
            if !data.is_empty() {
                assert_eq!(lz4_decoded_len(&block[..block.len() - 1]), None);
            }
        }
    }

    /// A count far beyond the payload, its checksum right: refused with a message, before
    /// anything the size of the count is allocated (a payload of 200 MB of zeros claiming
    /// 51 GB of points aborted the process before).
    #[test]
    fn a_count_the_payload_does_not_decode_to_is_refused_without_allocating_it() {
        let l = layout();
        let zeros = vec![0u8; 200_000 * l.stride];
        let (payload, crc) = encode_node(&zeros, &l);
        let raw = vec![0u8; 1 << 22];
        for (payload, crc) in [(payload, crc), (raw.clone(), payload_checksum(&raw))] {
            let forged = payload.len() * 255 / l.stride;
            let err = decode_node(&payload, forged, crc, &l).map(|n| n.count);
            assert!(
                matches!(&err, Err(NodeDecodeError::Decompress(m)) if m.contains("decodes to")),
                "{err:?}"
            );
            assert!(decode_node(&payload, usize::MAX / 2, crc, &l).is_err());
        }
        let (payload, crc) = encode_node(&zeros, &l);
        assert_eq!(
            decode_node(&payload, 200_000, crc, &l).map(|n| n.count),
            Ok(200_000)
        );
    }
}
