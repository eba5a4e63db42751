//! Structure-aware mutations of real inputs, one generator per class of fault: each case is a
//! file and what must come of converting it.

use super::bytes::{
    binary_ply, cut_las, eb_descriptor, las_of, put_f64, put_u16, put_u32, put_u64, u16_at, u32_at,
    with_extra_bytes,
};
use std::path::Path;

/// What converting a case must give.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Expect {
    /// A clean refusal.
    Refuse,
    /// An exact conversion (the points equal the `las` crate's reading).
    Exact,
    /// Either, but nothing else (no panic, abort, hang or silently wrong points).
    Either,
}

pub struct Case {
    pub name: String,
    pub ext: &'static str,
    pub bytes: Vec<u8>,
    pub expect: Expect,
}

/// A small deterministic generator (xorshift64*), so every run of a seed is the same.
pub struct Rng(u64);

impl Rng {
    pub fn new(seed: u64) -> Rng {
        Rng(seed.wrapping_mul(0x9E37_79B9_7F4A_7C15) | 1)
    }
    pub fn next(&mut self) -> u64 {
        self.0 ^= self.0 >> 12;
        self.0 ^= self.0 << 25;
        self.0 ^= self.0 >> 27;
        self.0.wrapping_mul(0x2545_F491_4F6C_DD1D)
    }
    pub fn below(&mut self, n: usize) -> usize {
        (self.next() % n.max(1) as u64) as usize
    }
    pub fn pick<T: Copy>(&mut self, xs: &[T]) -> T {
        xs[self.below(xs.len())]
    }
}

/// The seeds, read once from the shared test data.
pub struct Seeds {
    /// autzen_trim.las cut to its first 2,000 points (LAS 1.2, format 3).
    pub las: Vec<u8>,
    /// autzen_trim_pf7.las cut to 2,000 points (LAS 1.4, format 7).
    pub las14: Vec<u8>,
    pub laz: Vec<u8>,
    pub ply_binary: Vec<u8>,
}

impl Seeds {
    pub fn read(data: &Path) -> Seeds {
        let read = |n: &str| std::fs::read(data.join(n)).expect("seed data");
        Seeds {
            las: cut_las(&read("autzen_trim.las"), 2000),
            las14: cut_las(&read("autzen_trim_pf7.las"), 2000),
            laz: read("autzen_trim.laz"),
            ply_binary: binary_ply(&read("bunny_range_scans_merged.ply"), 2000),
        }
    }
}

fn case(name: String, ext: &'static str, bytes: Vec<u8>, expect: Expect) -> Case {
    Case {
        name,
        ext,
        bytes,
        expect,
    }
}

/// LAS header fields at and beyond their boundaries.
pub fn las_header(s: &Seeds, r: &mut Rng) -> Case {
    let mut b = s.las.clone();
    let n = u32_at(&b, 107);
    let len = b.len();
    let (what, expect): (String, Expect) = match r.below(12) {
        0 => {
            let v = r.pick(&[5e-324, 0.0, f64::NAN, f64::INFINITY, 1e-310, -0.0, 1e300]);
            put_f64(&mut b, 131 + 8 * r.below(3), v);
            (format!("scale {v}"), Expect::Refuse)
        }
        1 => {
            // Beside an offset of 1e308 every step of the scale is lost: refused like NaN.
            let v = r.pick(&[-1e308, 1e308, f64::NAN, f64::NEG_INFINITY]);
            put_f64(&mut b, 155 + 8 * r.below(3), v);
            (format!("offset {v}"), Expect::Refuse)
        }
        2 => {
            let v = r.pick(&[1e9, 1e12, 1e100, 1e300, -1e300]);
            put_f64(&mut b, 179 + 8 * r.below(6), v);
            (format!("bounds field {v}"), Expect::Exact)
        }
        3 => {
            let v = r.pick(&[0, n - 1, n + 1, u32::MAX, n / 2]);
            put_u32(&mut b, 107, v);
            (format!("point count {v}"), Expect::Refuse)
        }
        4 => {
            let v = r.pick(&[0u32, 100, 226, len as u32, len as u32 + 1, u32::MAX]);
            put_u32(&mut b, 96, v);
            (format!("offset to points {v}"), Expect::Refuse)
        }
        5 => {
            let v = r.pick(&[0u16, 100, 226, 1000, u16::MAX]);
            put_u16(&mut b, 94, v);
            (format!("header size {v}"), Expect::Refuse)
        }
        6 => {
            let v = r.pick(&[6u32, 1000, u32::MAX]);
            put_u32(&mut b, 100, v);
            (format!("VLR count {v}"), Expect::Refuse)
        }
        7 => {
            let v = r.pick(&[0u16, 20, 33, 35, 1000, u16::MAX]);
            put_u16(&mut b, 105, v);
            (format!("record length {v}"), Expect::Refuse)
        }
        8 => {
            let v = r.pick(&[11u8, 63, 0x83, 0x43]);
            b[104] = v;
            (format!("point format byte {v:#x}"), Expect::Refuse)
        }
        9 => {
            let (ma, mi) = r.pick(&[(1u8, 5u8), (2, 0), (0, 9)]);
            b[24] = ma;
            b[25] = mi;
            (format!("version {ma}.{mi}"), Expect::Refuse)
        }
        10 => {
            // LAS 1.4: legacy and 1.4 counts disagree.
            b = s.las14.clone();
            let n = u32_at(&b, 107) as u64;
            let (legacy, full) = r.pick(&[(n, n - 1), (n, n + 1), (n, 0), (n - 1, n), (n + 1, n)]);
            put_u32(&mut b, 107, legacy as u32);
            put_u64(&mut b, 247, full);
            (format!("1.4 counts {legacy} and {full}"), Expect::Refuse)
        }
        _ => {
            // LAS 1.4, legacy count 0: valid.
            b = s.las14.clone();
            put_u32(&mut b, 107, 0);
            ("1.4 with legacy count 0".into(), Expect::Exact)
        }
    };
    case(format!("las header: {what}"), "las", b, expect)
}

/// Extra bytes VLRs: clashing names, non-finite scales, nonsense types and lengths.
pub fn extra_bytes(s: &Seeds, r: &mut Rng) -> Case {
    let clash = r.pick(&[
        "intensity",
        "classification",
        "x",
        "gps_time",
        "rgb",
        "user_data",
    ]);
    let (what, descs, extra, expect) = match r.below(6) {
        0 => (
            format!("name {clash}"),
            vec![eb_descriptor(clash, 3, 0, 0.0)],
            2,
            Expect::Exact,
        ),
        1 => (
            "two fields of one name".into(),
            vec![eb_descriptor("a", 3, 0, 0.0), eb_descriptor("a", 3, 0, 0.0)],
            4,
            Expect::Exact,
        ),
        2 => {
            let v = r.pick(&[f64::NAN, f64::INFINITY]);
            (
                format!("scale {v}"),
                vec![eb_descriptor("h", 9, 0x08, v)],
                4,
                Expect::Refuse,
            )
        }
        3 => (
            "unknown data type".into(),
            vec![eb_descriptor("h", 200, 0, 0.0)],
            4,
            Expect::Refuse,
        ),
        4 => (
            "more bytes described than carried".into(),
            vec![eb_descriptor("h", 10, 0, 0.0)],
            4,
            Expect::Refuse,
        ),
        _ => {
            let mut d = eb_descriptor("h", 3, 0, 0.0);
            d.truncate(100);
            (
                "VLR not a multiple of 192".into(),
                vec![d],
                2,
                Expect::Refuse,
            )
        }
    };
    let b = with_extra_bytes(&s.las, &descs, extra);
    case(format!("extra bytes: {what}"), "las", b, expect)
}

/// The laszip VLR and the chunk table of a LAZ file.
pub fn laszip(s: &Seeds, r: &mut Rng) -> Case {
    let mut b = s.laz.clone();
    let start = u32_at(&b, 96) as usize;
    // The laszip VLR is the one whose user id is "laszip encoded".
    let mut at = u16_at(&b, 94) as usize;
    let mut vlr = 0;
    for _ in 0..u32_at(&b, 100) {
        if &b[at + 2..at + 16] == b"laszip encoded" {
            vlr = at + 54;
        }
        at += 54 + u16_at(&b, at + 20) as usize;
    }
    let table = u64::from_le_bytes(b[start..start + 8].try_into().expect("8 bytes")) as usize;
    let n = u32_at(&b, 107);
    let len = b.len();
    let what = match r.below(11) {
        0 => {
            let v = r.pick(&[1u32, 7, 1999, 49_999, 50_001, 110_000]);
            put_u32(&mut b, vlr + 12, v);
            format!("chunk size {v}")
        }
        1 => {
            let v = r.pick(&[0u16, 1, 2, 100, u16::MAX]);
            put_u16(&mut b, vlr + 32, v);
            format!("item count {v}")
        }
        2 => {
            let item = r.below(u16_at(&b, vlr + 32) as usize);
            let v = r.pick(&[0u16, 1, 19, 21, 100, u16::MAX]);
            put_u16(&mut b, vlr + 36 + 6 * item, v);
            format!("item {item} size {v}")
        }
        3 => {
            let v = r.pick(&[33u16, 35, 20, 0]);
            put_u16(&mut b, 105, v);
            format!("record length {v} against the items")
        }
        4 => {
            let v = r.pick(&[
                0u64,
                8,
                start as u64 + 8,
                len as u64,
                len as u64 - 4,
                u64::MAX / 2,
            ]);
            put_u64(&mut b, start, v);
            format!("chunk table offset {v}")
        }
        5 => {
            let v = r.pick(&[0u32, 1, 2, 4, 1 << 20, u32::MAX]);
            put_u32(&mut b, table + 4, v);
            format!("chunk count {v}")
        }
        6 => {
            let v = r.pick(&[0u32, n - 1, n + 1, n - 20_000, u32::MAX]);
            put_u32(&mut b, 107, v);
            format!("point count {v}")
        }
        7 => {
            let v = r.pick(&[0u16, 1, 4, 9]);
            put_u16(&mut b, vlr, v);
            format!("compressor {v}")
        }
        8 => {
            let at = table + 8 + r.below(len - table - 8);
            b[at] ^= 1 << r.below(8);
            format!("chunk table bit at {at}")
        }
        9 => {
            b.truncate(table + r.below(len - table));
            format!("truncated at {}", b.len())
        }
        _ => {
            let at = start + 8 + r.below(table - start - 8);
            b[at] ^= 1 << r.below(8);
            format!("compressed bit at {at}")
        }
    };
    case(format!("laz: {what}"), "laz", b, Expect::Either)
}

/// Bits flipped in uncompressed records, and the LAZ bit set on a plain file.
pub fn records(s: &Seeds, r: &mut Rng) -> Case {
    let mut b = s.las.clone();
    let start = u32_at(&b, 96) as usize;
    if r.below(8) == 0 {
        b[104] |= 0x80;
        return case(
            "records: LAZ bit on a plain file".into(),
            "las",
            b,
            Expect::Refuse,
        );
    }
    let flips = 1 + r.below(8);
    for _ in 0..flips {
        let at = start + r.below(b.len() - start);
        b[at] ^= 1 << r.below(8);
    }
    case(
        format!("records: {flips} bit flips"),
        "las",
        b,
        Expect::Either,
    )
}

/// PLY headers and bodies.
pub fn ply(s: &Seeds, r: &mut Rng) -> Case {
    let ascii = |body: &str, props: &str, n: usize| {
        format!("ply\nformat ascii 1.0\nelement vertex {n}\n{props}end_header\n{body}").into_bytes()
    };
    let xyz = "property float x\nproperty float y\nproperty float z\n";
    let list = "property float x\nproperty float y\nproperty float z\nproperty list uchar int l\nproperty float w\n";
    let (what, bytes, expect) = match r.below(14) {
        0 => {
            let text = String::from_utf8_lossy(&s.ply_binary).to_string();
            let b = text
                .replacen("property float y\n", "property float y\nproperty float x\n", 1)
                .into_bytes();
            ("property named twice", b, Expect::Refuse)
        }
        1 => {
            let b = ascii(
                "1 2 3\n4 5 6\n",
                &format!("{xyz}element vertex 1\n{xyz}"),
                1,
            );
            ("two vertex elements", b, Expect::Refuse)
        }
        2 => (
            "format ascii 2.0",
            "ply\nformat ascii 2.0\nelement vertex 1\nproperty float x\nproperty float y\nproperty float z\nend_header\n1 2 3\n".into(),
            Expect::Refuse,
        ),
        3 => {
            let b = String::from_utf8_lossy(&ascii("1 2 3\n4 5 6\n", xyz, 2))
                .replace("format ascii 1.0", "format binary_little_endian 1.0")
                .into_bytes();
            ("binary format over a text body", b, Expect::Refuse)
        }
        4 => {
            let b = String::from_utf8_lossy(&ascii("1 2 3\r", xyz, 1))
                .replace('\n', "\r")
                .into_bytes();
            ("carriage returns only", b, Expect::Refuse)
        }
        5 => {
            let c = r.pick(&["-1", "NaN", "abc", "1e17", "100000000000000000", "3"]);
            let b = ascii(&format!("1 2 3 {c} 1 2 5\n"), list, 1);
            let _ = c;
            ("ascii list count", b, Expect::Refuse)
        }
        6 => {
            let mut b = format!(
                "ply\nformat binary_little_endian 1.0\nelement vertex 1\n{list}end_header\n"
            )
            .into_bytes();
            for v in [1f32, 2.0, 3.0] {
                b.extend_from_slice(&v.to_le_bytes());
            }
            let c = r.pick(&[255u8, 200, 3]);
            b.push(c);
            b.extend_from_slice(&[0; 8]);
            b.extend_from_slice(&1f32.to_le_bytes());
            ("binary list count", b, Expect::Refuse)
        }
        7 => {
            let mut b = "ply\nformat binary_little_endian 1.0\nelement face 1\nproperty list uint int v\nelement vertex 1\nproperty float x\nproperty float y\nproperty float z\nend_header\n".as_bytes().to_vec();
            b.extend_from_slice(&u32::MAX.to_le_bytes());
            b.extend_from_slice(&[0; 12]);
            ("binary list count 0xffffffff", b, Expect::Refuse)
        }
        8 => {
            let v = r.pick(&["1e308", "-1.7e308", "inf", "nan"]);
            let b = format!("ply\nformat ascii 1.0\nelement vertex 2\nproperty double x\nproperty double y\nproperty double z\nend_header\n{v} 0 0\n0 0 0\n").into_bytes();
            // A finite position may convert (on a coarsened scale, with its warning); the
            // metadata of what converts must read back (verify), so never hold a null.
            let e = if v.parse::<f64>().is_ok_and(f64::is_finite) {
                Expect::Either
            } else {
                Expect::Refuse
            };
            ("huge double position", b, e)
        }
        9 => {
            let b = ascii("1 2 3 4\n", xyz, 1);
            ("more values than properties", b, Expect::Refuse)
        }
        10 => {
            let b = ascii("1 2 3\n", "property float x\nproperty float y\nproperty floot z\n", 1);
            ("unknown property type", b, Expect::Refuse)
        }
        11 => {
            let b = ascii("1 2 300\n", "property float x\nproperty float y\nproperty uchar z\n", 1);
            ("value beyond its type", b, Expect::Refuse)
        }
        12 => {
            let mut b = s.ply_binary.clone();
            let at = b.len() - 1 - r.below(b.len() / 2);
            b.truncate(at);
            ("truncated body", b, Expect::Refuse)
        }
        _ => {
            let mut b = s.ply_binary.clone();
            let header = b.windows(10).position(|w| w == b"end_header").unwrap_or(0);
            let at = r.below(header.max(1));
            b[at] = r.pick(&[b'\r', 0, b' ', b'#', 0x1b]);
            ("header byte", b, Expect::Either)
        }
    };
    case(format!("ply: {what}"), "ply", bytes, expect)
}

/// Odd but valid clouds: each must convert exactly.
pub fn odd_valid(s: &Seeds, r: &mut Rng) -> Case {
    let (what, points): (&str, Vec<[i32; 3]>) = match r.below(6) {
        0 => ("one point", vec![[5, -7, 9]]),
        1 => ("all points identical", vec![[123, 456, 789]; 50]),
        2 => (
            "positions at the ends of i32",
            vec![
                [i32::MIN, i32::MIN, i32::MIN],
                [i32::MAX, i32::MAX, i32::MAX],
                [0, 0, 0],
            ],
        ),
        3 => (
            "zero extent on two axes",
            (0..100).map(|i| [i * 3, 42, -42]).collect(),
        ),
        4 => (
            "one end of i32 on one axis",
            (0..20).map(|i| [i32::MAX - i, i, i32::MIN + i]).collect(),
        ),
        _ => (
            "two points far apart",
            vec![[i32::MIN + 1, 0, 0], [i32::MAX - 1, 1, 1]],
        ),
    };
    case(
        format!("odd valid: {what}"),
        "las",
        las_of(&points, &s.las),
        Expect::Exact,
    )
}
