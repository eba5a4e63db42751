//! The hierarchy page decoder on any bytes: the trailing checksum is rewritten to match, so that
//! the entry and shape checks behind it are reached; the page's root node and page levels come
//! from the first byte, the layout (1.0 or 1.1) from the second.
#![no_main]

use libfuzzer_sys::fuzz_target;
use strata_format::{Layout, NodeKey, PageRef, decode_page};

fuzz_target!(|data: &[u8]| {
    if data.len() < 6 {
        return;
    }
    let layout = if data[1] & 1 == 0 {
        Layout::V1_0
    } else {
        Layout::V1_1
    };
    let root = NodeKey {
        level: data[0] % 32,
        x: 0,
        y: 0,
        z: 0,
    };
    let mut bytes = data[2..].to_vec();
    let n = bytes.len();
    let crc = crc32fast::hash(&bytes[..n - 4]);
    bytes[n - 4..].copy_from_slice(&crc.to_le_bytes());
    let page = PageRef {
        root,
        offset: 0,
        size: n as u64,
        checksum: None,
    };
    if let Ok(p) = decode_page(&bytes, &page, 1 + (data[0] as u32 >> 5), layout) {
        let _ = p.child_pages().count();
        let _ = p.proxies().count();
        let _ = p.nodes().count();
    }
});
