//! Mutations of E57 files. Every E57 page ends in a CRC-32C of the rest, so a plain flipped
//! byte only tests the checksum: most cases here repair the checksums they break, so the
//! damage reaches the `e57` crate's XML parser and packet decoder.

use super::cases::{Case, Expect, Rng};
use std::path::Path;

const PAGE: usize = 1024;
const DATA: usize = PAGE - 4;

/// The shared E57 files the mutations start from.
pub struct E57Seeds(Vec<Vec<u8>>);

impl E57Seeds {
    pub fn read(data: &Path) -> E57Seeds {
        let read = |n: &str| std::fs::read(data.join(n)).expect("seed data");
        E57Seeds(vec![
            read("e57_tinyCartesianFloatRgb.e57"),
            read("e57_tiny_spherical.e57"),
            read("e57_bunnyInt21.e57"),
        ])
    }
}

use crate::common::e57_crc32c as crc32c;

/// Rewrites the checksum of the page holding byte `at`.
fn fix_page(b: &mut [u8], at: usize) {
    let start = at / PAGE * PAGE;
    if start + PAGE <= b.len() {
        let crc = crc32c(&b[start..start + DATA]);
        b[start + DATA..start + PAGE].copy_from_slice(&crc.to_be_bytes());
    }
}

/// The physical byte range of the XML section.
fn xml_range(b: &[u8]) -> (usize, usize) {
    let u64_at = |o: usize| {
        let mut v = [0u8; 8];
        v.copy_from_slice(&b[o..o + 8]);
        u64::from_le_bytes(v) as usize
    };
    let (at, len) = (u64_at(24), u64_at(32));
    (at, (at + len + len / DATA * 4 + 4).min(b.len()))
}

/// A payload byte (not a checksum) in `lo..hi`.
fn payload_byte(r: &mut Rng, lo: usize, hi: usize) -> usize {
    loop {
        let at = lo + r.below(hi - lo);
        if at % PAGE < DATA {
            return at;
        }
    }
}

pub fn e57(s: &E57Seeds, r: &mut Rng) -> Case {
    let mut b = s.0[r.below(s.0.len())].clone();
    let (xml_at, xml_end) = xml_range(&b);
    let (name, expect) = match r.below(6) {
        0 => {
            let keep = 1 + r.below(b.len() - 1);
            b.truncate(keep);
            (format!("e57 truncated to {keep} bytes"), Expect::Refuse)
        }
        1 => {
            // Not the header: it has no checksum of its own and some fields are unused.
            let at = 48 + r.below(b.len() - 48);
            b[at] ^= 1 << r.below(8);
            (format!("e57 byte {at} flipped"), Expect::Refuse)
        }
        2 => {
            let n = 1 + r.below(8);
            for _ in 0..n {
                let at = payload_byte(r, 48, xml_at);
                b[at] = r.next() as u8;
                fix_page(&mut b, at);
            }
            (
                format!("e57 {n} point-data bytes changed, checksums repaired"),
                Expect::Either,
            )
        }
        3 => {
            // A digit of the XML becomes another: counts, offsets, scales, limits, poses.
            let digits: Vec<usize> = (xml_at..xml_end)
                .filter(|&i| i % PAGE < DATA && b[i].is_ascii_digit())
                .collect();
            let at = digits[r.below(digits.len())];
            b[at] = b'0' + r.below(10) as u8;
            fix_page(&mut b, at);
            (
                format!("e57 XML digit at {at} changed, checksum repaired"),
                Expect::Either,
            )
        }
        4 => {
            // A run of the point data zeroed: packet headers and lengths of nothing.
            let at = payload_byte(r, 48, xml_at);
            let end = (at + 1 + r.below(64)).min(at / PAGE * PAGE + DATA);
            b[at..end].fill(0);
            fix_page(&mut b, at);
            (
                format!("e57 point data {at}..{end} zeroed, checksum repaired"),
                Expect::Either,
            )
        }
        _ => {
            // An XML byte becomes any byte: broken markup, names, types.
            let at = payload_byte(r, xml_at, xml_end);
            b[at] = r.next() as u8;
            fix_page(&mut b, at);
            (
                format!("e57 XML byte {at} changed, checksum repaired"),
                Expect::Either,
            )
        }
    };
    Case {
        name,
        ext: "e57",
        bytes: b,
        expect,
    }
}

#[test]
fn crc32c_is_castagnoli() {
    // The check value of CRC-32C.
    assert_eq!(crc32c(b"123456789"), 0xE306_9283);
}
