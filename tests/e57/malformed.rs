//! Malformed E57 files: one sentence naming the file, no panic, no output.

use super::*;

fn tiny() -> Vec<u8> {
    std::fs::read(data("e57_tinyCartesianFloatRgb.e57")).expect("tiny e57")
}

#[test]
fn truncated_e57_is_refused() {
    let dir = tempfile::tempdir().expect("tempdir");
    let b = tiny();
    convert_fails(
        &written(dir.path(), "cut.e57", &b[..b.len() / 2]),
        "truncated",
    );
    // Cut at a page boundary: the pages are whole but the XML section is gone.
    convert_fails(
        &written(dir.path(), "pages.e57", &b[..20 * 1024]),
        "truncated",
    );
    convert_fails(&written(dir.path(), "stub.e57", &b[..20]), "too short");
}

#[test]
fn e57_with_a_flipped_byte_fails_its_checksum() {
    let dir = tempfile::tempdir().expect("tempdir");
    let mut b = tiny();
    b[2000] ^= 0x10;
    convert_fails(&written(dir.path(), "points.e57", &b), "checksum");
    let mut b = tiny();
    let xml = u64::from_le_bytes(b[24..32].try_into().expect("8 bytes")) as usize;
    b[xml + 10] ^= 0x10;
    convert_fails(&written(dir.path(), "xml.e57", &b), "checksum");
    // In the header's XML offset: the header's own page checksum says so (the offset was
    // followed first, and the file called truncated).
    let mut b = tiny();
    b[31] ^= 0x10;
    convert_fails(
        &written(dir.path(), "header.e57", &b),
        "page 0, the file header, fails its CRC-32C checksum",
    );
    // A stated length that is not the file's, its checksum repaired.
    let mut b = tiny();
    let stated = b.len() as u64 + 1024;
    b[16..24].copy_from_slice(&stated.to_le_bytes());
    let crc = e57_crc32c(&b[..1020]);
    b[1020..1024].copy_from_slice(&crc.to_be_bytes());
    convert_fails(
        &written(dir.path(), "length.e57", &b),
        &format!(
            "its header states a length of {stated} bytes, but the file has {}",
            stated - 1024
        ),
    );
}

#[test]
fn e57_without_point_clouds_or_points_is_refused() {
    let dir = tempfile::tempdir().expect("tempdir");
    let none = dir.path().join("none.e57");
    write_e57(&none, &[]);
    convert_fails(&none, "no point cloud");
    let empty = dir.path().join("empty.e57");
    write_e57(&empty, &[ScanSpec::new(Storage::Double, 0)]);
    convert_fails(&empty, "no points");
    let invalid = dir.path().join("invalid.e57");
    let mut spec = ScanSpec::new(Storage::Double, 10);
    spec.invalid_every = Some(1);
    write_e57(&invalid, &[spec]);
    convert_fails(&invalid, "valid position");
    // A scale of zero would put every point at the offset.
    let zero = dir.path().join("zero.e57");
    let mut spec = ScanSpec::new(Storage::Scaled, 10);
    spec.scale = 0.0;
    write_e57(&zero, &[spec]);
    convert_fails(
        &zero,
        "scan 0 of 1: its CartesianX field is a scaled integer with a scale of zero",
    );
    // Beside an offset of 1e300 the steps of the scale are lost: every point one x.
    let far = dir.path().join("far.e57");
    let mut spec = ScanSpec::new(Storage::Scaled, 10);
    spec.offset = 1e300;
    write_e57(&far, &[spec]);
    convert_fails(
        &far,
        "an offset of 1e300, so large that the steps of its scale",
    );
}
