//! The E57 file header (ASTM E2807 section 8.2), checked before the `e57` crate reads it: the
//! crate trusts the header before it checks the first page's checksum, so a flipped byte in
//! it was taken for a truncated file or broken XML, and a stated length that is not the
//! file's went unnoticed.

use std::io::Read;

/// Every E57 file is made of pages of this many bytes, each ending in its checksum.
pub const PAGE: usize = 1024;
const SIGNATURE: &[u8; 8] = b"ASTM-E57";

/// CRC-32C (Castagnoli), the checksum at the end of every E57 page (big-endian).
pub fn crc32c(bytes: &[u8]) -> u32 {
    let mut crc = !0u32;
    for &b in bytes {
        crc ^= u32::from(b);
        for _ in 0..8 {
            crc = if crc & 1 == 1 {
                (crc >> 1) ^ 0x82F6_3B78
            } else {
                crc >> 1
            };
        }
    }
    !crc
}

/// Checks the first page of an E57 file of `len` bytes, read from `file`: its checksum, the
/// signature, the page size and the file length the header states. The fault, as the end
/// of a sentence that names the file, where one is found.
pub fn check_header(file: &mut impl Read, len: u64) -> Result<(), String> {
    if len < PAGE as u64 {
        return Err(format!(
            "the file is {len} bytes, too short to be an E57 file (made of {PAGE}-byte pages)"
        ));
    }
    let mut page = [0u8; PAGE];
    file.read_exact(&mut page)
        .map_err(|e| format!("cannot read its first page ({e})"))?;
    let u64_at = |at: usize| {
        let mut b = [0u8; 8];
        b.copy_from_slice(&page[at..at + 8]);
        u64::from_le_bytes(b)
    };
    if &page[..8] != SIGNATURE {
        return Err("it does not start with the E57 signature \"ASTM-E57\"".into());
    }
    let stated = u32::from_be_bytes([page[1020], page[1021], page[1022], page[1023]]);
    let actual = crc32c(&page[..PAGE - 4]);
    if stated != actual {
        return Err(format!(
            "page 0, the file header, fails its CRC-32C checksum (stored {stated:#010x}, \
             computed {actual:#010x}): the file is damaged"
        ));
    }
    let (physical_len, page_size) = (u64_at(16), u64_at(40));
    if page_size != PAGE as u64 {
        return Err(format!(
            "its header states pages of {page_size} bytes; E57 pages are {PAGE}"
        ));
    }
    if physical_len != len {
        let why = if physical_len % PAGE as u64 != 0 {
            "the header is damaged (no whole number of pages)"
        } else if physical_len > len {
            "it is truncated, or its header damaged"
        } else {
            "something was appended to it, or its header is damaged"
        };
        return Err(format!(
            "its header states a length of {physical_len} bytes, but the file has {len}: {why}"
        ));
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A first page with a header stating `len` bytes and pages of `page_size`, its
    /// checksum right.
    fn first_page(len: u64, page_size: u64) -> Vec<u8> {
        let mut p = vec![0u8; PAGE];
        p[..8].copy_from_slice(SIGNATURE);
        p[8..12].copy_from_slice(&1u32.to_le_bytes());
        p[16..24].copy_from_slice(&len.to_le_bytes());
        p[40..48].copy_from_slice(&page_size.to_le_bytes());
        let crc = crc32c(&p[..PAGE - 4]);
        p[PAGE - 4..].copy_from_slice(&crc.to_be_bytes());
        p
    }

    #[test]
    fn crc32c_is_castagnoli() {
        assert_eq!(crc32c(b"123456789"), 0xE306_9283);
    }

    #[test]
    fn the_header_page_is_checked_before_it_is_trusted() {
        let ok = first_page(4096, 1024);
        assert_eq!(check_header(&mut ok.as_slice(), 4096), Ok(()));
        let e = check_header(&mut ok.as_slice(), 3072).expect_err("short");
        assert!(
            e.contains("states a length of 4096 bytes, but the file has 3072"),
            "{e}"
        );
        assert!(e.contains("truncated"), "{e}");
        let mut flipped = ok.clone();
        flipped[25] ^= 0x40;
        let e = check_header(&mut flipped.as_slice(), 4096).expect_err("flipped");
        assert!(
            e.contains("page 0, the file header, fails its CRC-32C checksum"),
            "{e}"
        );
        let odd = first_page(4096, 2048);
        let e = check_header(&mut odd.as_slice(), 4096).expect_err("page size");
        assert!(e.contains("pages of 2048 bytes"), "{e}");
        let mut other = ok;
        other[..8].copy_from_slice(b"LASF....");
        let e = check_header(&mut other.as_slice(), 4096).expect_err("signature");
        assert!(e.contains("signature"), "{e}");
        let e = check_header(&mut [0u8; 100].as_slice(), 100).expect_err("tiny");
        assert!(e.contains("100 bytes, too short"), "{e}");
    }
}
