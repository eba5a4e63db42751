//! The node decoder on any payload: the checksum is computed over the fuzzed bytes so that the
//! LZ4 and column decoding behind it is reached; the point count and layout come from the input.
#![no_main]

use libfuzzer_sys::fuzz_target;
use strata_format::{AttrType, Attribute, RowLayout, decode_node};

fuzz_target!(|data: &[u8]| {
    if data.len() < 6 {
        return;
    }
    let count = u32::from_le_bytes([data[0], data[1], data[2], data[3]]) as usize;
    let attrs = (0..data[4] % 4)
        .map(|i| Attribute::new(&format!("a{i}"), AttrType::U16, 1 + data[5] % 3))
        .collect();
    let layout = RowLayout::new(attrs);
    let payload = &data[6..];
    if let Ok(cols) = decode_node(payload, count, crc32fast::hash(payload), &layout) {
        for i in 0..cols.count.min(64) {
            let _ = cols.position(i);
        }
        let _ = cols.to_rows(&layout);
    }
});
