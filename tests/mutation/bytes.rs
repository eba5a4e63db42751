//! Byte-level builders of the mutation seeds and cases: little-endian fields put and read at
//! offsets, LAS files cut short or written from positions, binary PLYs cut short, and extra
//! bytes VLRs.

pub(super) fn put_u16(b: &mut [u8], at: usize, v: u16) {
    b[at..at + 2].copy_from_slice(&v.to_le_bytes());
}
pub(super) fn put_u32(b: &mut [u8], at: usize, v: u32) {
    b[at..at + 4].copy_from_slice(&v.to_le_bytes());
}
pub(super) fn put_u64(b: &mut [u8], at: usize, v: u64) {
    b[at..at + 8].copy_from_slice(&v.to_le_bytes());
}
pub(super) fn put_f64(b: &mut [u8], at: usize, v: f64) {
    b[at..at + 8].copy_from_slice(&v.to_le_bytes());
}
pub(super) fn u32_at(b: &[u8], at: usize) -> u32 {
    u32::from_le_bytes([b[at], b[at + 1], b[at + 2], b[at + 3]])
}
pub(super) fn u16_at(b: &[u8], at: usize) -> u16 {
    u16::from_le_bytes([b[at], b[at + 1]])
}

/// The first `n` records of a LAS file, with the header's counts to match.
pub(super) fn cut_las(full: &[u8], n: u32) -> Vec<u8> {
    let start = u32_at(full, 96) as usize;
    let len = u16_at(full, 105) as usize;
    let mut b = full[..start + n as usize * len].to_vec();
    put_u32(&mut b, 107, n);
    put_u32(&mut b, 111, n);
    for r in 1..5 {
        put_u32(&mut b, 111 + 4 * r, 0);
    }
    if b[25] >= 4 {
        put_u64(&mut b, 247, n as u64);
        put_u64(&mut b, 255, n as u64);
        for r in 1..15 {
            put_u64(&mut b, 255 + 8 * r, 0);
        }
        put_u64(&mut b, 235, 0);
        put_u32(&mut b, 243, 0);
    }
    b
}

/// The first `n` vertices of a binary PLY whose only element is `vertex`.
pub(super) fn binary_ply(full: &[u8], n: usize) -> Vec<u8> {
    let end = full
        .windows(11)
        .position(|w| w == b"end_header\n")
        .expect("PLY header")
        + 11;
    let header = String::from_utf8_lossy(&full[..end]).to_string();
    let mut row = 0;
    for line in header.lines() {
        if let Some(t) = line.strip_prefix("property ") {
            row += match t.split_whitespace().next() {
                Some("double") => 8,
                Some("uchar" | "char") => 1,
                Some("short" | "ushort") => 2,
                _ => 4,
            };
        }
    }
    let count = header
        .lines()
        .find_map(|l| l.strip_prefix("element vertex "))
        .expect("vertex element");
    let mut b = header
        .replace(
            &format!("element vertex {count}"),
            &format!("element vertex {n}"),
        )
        .into_bytes();
    b.extend_from_slice(&full[end..end + n * row]);
    b
}

/// A LAS file of format 0 holding `points` (integer positions) with scale 0.01.
pub(super) fn las_of(points: &[[i32; 3]], seed: &[u8]) -> Vec<u8> {
    let mut b = seed[..227].to_vec();
    b[24] = 1;
    b[25] = 2;
    put_u16(&mut b, 94, 227);
    put_u32(&mut b, 96, 227);
    put_u32(&mut b, 100, 0);
    b[104] = 0;
    put_u16(&mut b, 105, 20);
    put_u32(&mut b, 107, points.len() as u32);
    for a in 0..3 {
        put_f64(&mut b, 131 + 8 * a, 0.01);
        put_f64(&mut b, 155 + 8 * a, 1000.0);
        let lo = points.iter().map(|p| p[a]).min().unwrap_or(0) as f64;
        let hi = points.iter().map(|p| p[a]).max().unwrap_or(0) as f64;
        put_f64(&mut b, 179 + 16 * a, 1000.0 + 0.01 * hi);
        put_f64(&mut b, 187 + 16 * a, 1000.0 + 0.01 * lo);
    }
    for (i, p) in points.iter().enumerate() {
        for v in p {
            b.extend_from_slice(&v.to_le_bytes());
        }
        b.extend_from_slice(&(i as u16).to_le_bytes());
        b.extend_from_slice(&[0x09, 2, 0, 0, 1, 0]);
    }
    b
}

/// One 192-byte extra bytes descriptor.
pub(super) fn eb_descriptor(name: &str, data_type: u8, options: u8, scale: f64) -> Vec<u8> {
    let mut d = vec![0u8; 192];
    d[2] = data_type;
    d[3] = options;
    d[4..4 + name.len()].copy_from_slice(name.as_bytes());
    put_f64(&mut d, 112, scale);
    d
}

/// A format-3 LAS seed with `extra` bytes per record described by `descriptors`.
pub(super) fn with_extra_bytes(seed: &[u8], descriptors: &[Vec<u8>], extra: usize) -> Vec<u8> {
    let start = u32_at(seed, 96) as usize;
    let len = u16_at(seed, 105) as usize;
    let n = u32_at(seed, 107) as usize;
    let body: Vec<u8> = descriptors.concat();
    let mut vlr = vec![0u8; 54];
    vlr[2..11].copy_from_slice(b"LASF_Spec");
    put_u16(&mut vlr, 18, 4);
    put_u16(&mut vlr, 20, body.len() as u16);
    let mut b = seed[..start].to_vec();
    b.extend_from_slice(&vlr);
    b.extend_from_slice(&body);
    let new_start = b.len();
    put_u32(&mut b, 96, new_start as u32);
    put_u32(&mut b, 100, u32_at(seed, 100) + 1);
    put_u16(&mut b, 105, (len + extra) as u16);
    for i in 0..n {
        b.extend_from_slice(&seed[start + i * len..start + (i + 1) * len]);
        b.extend((0..extra).map(|k| (i * 7 + k) as u8));
    }
    b
}
