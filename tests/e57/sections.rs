//! E57 binary sections that disagree with themselves, their checksums repaired so that the
//! damage reaches the reading of the points: each refused in one sentence, with no output.
//! The `e57` crate converted them without a word (a shifted packet decoded as garbage, a
//! section too short for its packets read all the same), or grew a queue until memory ran
//! out (a scan whose fields all take no bits).

use super::*;

const PAGE: usize = 1024;
const DATA: usize = PAGE - 4;

fn u64_at(b: &[u8], at: usize) -> u64 {
    u64::from_le_bytes(b[at..at + 8].try_into().expect("8 bytes"))
}

/// The file's bytes without the page checksums.
fn logical(b: &[u8]) -> Vec<u8> {
    b.chunks(PAGE)
        .flat_map(|p| &p[..DATA.min(p.len())])
        .copied()
        .collect()
}

/// Pages of `logical` bytes (the last padded with zeros), each with its checksum.
fn paged(logical: &[u8]) -> Vec<u8> {
    let mut out = Vec::new();
    for chunk in logical.chunks(DATA) {
        let mut page = chunk.to_vec();
        page.resize(DATA, 0);
        let crc = e57_crc32c(&page);
        out.extend_from_slice(&page);
        out.extend_from_slice(&crc.to_be_bytes());
    }
    out
}

/// The file offset of logical (checksums left out) offset `l`.
fn physical(l: u64) -> u64 {
    l / DATA as u64 * PAGE as u64 + l % DATA as u64
}

/// `b` with `bytes` written at physical offset `at` (in one page), checksums repaired.
fn patched(b: &[u8], at: usize, bytes: &[u8]) -> Vec<u8> {
    let mut l = logical(b);
    let at = at / PAGE * DATA + at % PAGE;
    l[at..at + bytes.len()].copy_from_slice(bytes);
    paged(&l)
}

/// `b` with its XML section (the last in the file, as writers put it) replaced by `edit` of
/// it, the header's lengths and the checksums made to agree.
fn with_xml(b: &[u8], edit: impl Fn(&str) -> String) -> Vec<u8> {
    let mut l = logical(b);
    let (at, len) = (u64_at(b, 24) as usize, u64_at(b, 32) as usize);
    let at = at / PAGE * DATA + at % PAGE;
    let xml = String::from_utf8(l[at..at + len].to_vec()).expect("XML text");
    let new = edit(&xml);
    assert_ne!(new, xml, "the edit changed nothing");
    l.truncate(at);
    l.extend_from_slice(new.as_bytes());
    let pages = l.len().div_ceil(DATA);
    l[16..24].copy_from_slice(&((pages * PAGE) as u64).to_le_bytes());
    l[32..40].copy_from_slice(&(new.len() as u64).to_le_bytes());
    paged(&l)
}

fn bunny() -> Vec<u8> {
    std::fs::read(data("e57_bunnyInt21.e57")).expect("bunny e57")
}

fn tiny() -> Vec<u8> {
    std::fs::read(data("e57_tinyCartesianFloatRgb.e57")).expect("tiny e57")
}

#[test]
fn the_repairs_alone_leave_a_readable_file() {
    let dir = tempfile::tempdir().expect("tempdir");
    for (name, b) in [("bunny.e57", bunny()), ("tiny.e57", tiny())] {
        assert_eq!(paged(&logical(&b)), b, "{name}: pages rebuilt");
        let same = with_xml(&b, |x| x.replacen("<e57Root", "<e57Root ", 1));
        let input = written(dir.path(), name, &same);
        let out = dir.path().join(format!("{name}.strata"));
        run_ok(&["convert", s(&input), "-o", s(&out), "--quiet"]);
    }
}

#[test]
fn a_data_packet_longer_than_its_streams_say_is_refused() {
    let dir = tempfile::tempdir().expect("tempdir");
    // The tiny file's first data packet starts at byte 80: its first stream's size, 8360,
    // four bytes more, the packet's length as it was.
    let b = tiny();
    assert_eq!(b[80], 1, "a data packet at byte 80");
    assert_eq!(u16::from_le_bytes([b[86], b[87]]), 8360);
    let bad = patched(&b, 86, &8364u16.to_le_bytes());
    convert_fails(
        &written(dir.path(), "streams.e57", &bad),
        "scan 0 of 1: its data packet at byte 80 states a length of 31368 bytes, but the byte \
         streams it lists take 31372",
    );
}

#[test]
fn a_section_too_short_for_its_packets_is_refused() {
    let dir = tempfile::tempdir().expect("tempdir");
    // The bunny's binary section starts at byte 48; its length, at 56, set to its header's
    // (a scan of no points has that section).
    let b = bunny();
    let bad = patched(&b, 56, &32u64.to_le_bytes());
    convert_fails(
        &written(dir.path(), "short.e57", &bad),
        "scan 0 of 1: its CartesianX field holds values for 0 of the 30571 points it states",
    );
    // Its first data packet put past the section's end (4 bytes on, in the bytes that
    // count, between the pages' checksums).
    let len = u64_at(&logical(&b), 56);
    let beyond = physical(48 + len + 4);
    let bad = patched(&b, 64, &beyond.to_le_bytes());
    convert_fails(
        &written(dir.path(), "beyond.e57", &bad),
        &format!(
            "scan 0 of 1: its binary section at byte 48 ({len} bytes) puts its first data \
             packet at byte {beyond}, outside the section"
        ),
    );
    // A length 4 bytes short: the last packet runs past the section's end.
    let len = u64_at(&logical(&b), 56);
    let bad = patched(&b, 56, &(len - 4).to_le_bytes());
    convert_fails(
        &written(dir.path(), "cut.e57", &bad),
        "past the end of its binary section at byte 48",
    );
}

#[test]
fn two_scans_naming_one_section_are_refused() {
    let dir = tempfile::tempdir().expect("tempdir");
    let twice = with_xml(&tiny(), |x| {
        let start = x.find("<vectorChild").expect("a scan");
        let end = x.find("</vectorChild>").expect("its end") + "</vectorChild>".len();
        format!("{}{}{}", &x[..end], &x[start..end], &x[end..])
    });
    convert_fails(
        &written(dir.path(), "twice.e57", &twice),
        "scans 0 and 1 of 2 name the same binary section (at byte 48)",
    );
}

#[test]
fn a_scan_whose_fields_take_no_bits_is_refused_not_read_forever() {
    let dir = tempfile::tempdir().expect("tempdir");
    let flat = with_xml(&bunny(), |x| {
        x.replace(
            "minimum=\"-1048576\" maximum=\"1048575\"",
            "minimum=\"0\" maximum=\"0\"",
        )
        .replace("minimum=\"0\" maximum=\"1\"", "minimum=\"0\" maximum=\"0\"")
    });
    let input = written(dir.path(), "flat.e57", &flat);
    let out = dir.path().join("flat.strata");
    // Under a memory cap: the crate's reader grew a queue until the allocator aborted.
    let o = std::process::Command::new("bash")
        .args([
            "-c",
            "ulimit -v 4000000 && exec timeout 60 \"$@\"",
            "bash",
            env!("CARGO_BIN_EXE_strata"),
            "convert",
            s(&input),
            "-o",
            s(&out),
        ])
        .output()
        .expect("bash runs");
    let err = String::from_utf8_lossy(&o.stderr);
    assert_eq!(o.status.code(), Some(1), "{err}");
    assert!(
        err.contains("flat.e57: scan 0 of 1: every field of its points takes no bits"),
        "{err}"
    );
    assert!(!out.exists(), "output left behind");
}

/// `b` with `packet` put before the first data packet of its binary section (the first in
/// the file, at byte 48), the offsets after it moved and the checksums repaired.
fn with_packet_before_data(b: &[u8], packet: &[u8]) -> Vec<u8> {
    let logical_of = |p: u64| p / PAGE as u64 * DATA as u64 + p % PAGE as u64;
    let mut l = logical(b);
    let grow = packet.len() as u64;
    let first = logical_of(u64_at(&l, 48 + 16));
    let index = u64_at(&l, 48 + 24);
    if index != 0 {
        let moved = physical(logical_of(index) + grow);
        l[48 + 24..48 + 32].copy_from_slice(&moved.to_le_bytes());
    }
    let section = u64_at(&l, 48 + 8) + grow;
    l[48 + 8..48 + 16].copy_from_slice(&section.to_le_bytes());
    let xml = physical(logical_of(u64_at(&l, 24)) + grow);
    l[24..32].copy_from_slice(&xml.to_le_bytes());
    l.splice(first as usize..first as usize, packet.iter().copied());
    let pages = l.len().div_ceil(DATA);
    l[16..24].copy_from_slice(&((pages * PAGE) as u64).to_le_bytes());
    paged(&l)
}

#[test]
fn a_packet_that_completes_no_point_is_read_past() {
    let dir = tempfile::tempdir().expect("tempdir");
    let b = tiny();
    // A data packet whose byte streams are all empty, as a writer may flush one: the crate's
    // reader took it for a logic error of its own, and the file was refused at point 0.
    let streams = u16::from_le_bytes([b[84], b[85]]);
    let len = (6 + 2 * streams as usize).next_multiple_of(4);
    let mut empty = vec![1, 0];
    empty.extend_from_slice(&(len as u16 - 1).to_le_bytes());
    empty.extend_from_slice(&streams.to_le_bytes());
    empty.resize(len, 0);
    let plain = written(dir.path(), "plain.e57", &b);
    let padded = written(
        dir.path(),
        "padded.e57",
        &with_packet_before_data(&b, &empty),
    );
    let mut points = Vec::new();
    for input in [&plain, &padded] {
        let out = input.with_extension("strata");
        run_ok(&["convert", s(input), "-o", s(&out), "--quiet"]);
        let (_, mut keys) = stored(&out);
        keys.sort();
        points.push(keys);
    }
    assert!(!points[0].is_empty());
    assert_eq!(
        points[0], points[1],
        "the same points past the empty packet"
    );
    // An ignored packet there the crate steps over by its length after its header, and reads
    // on inside the packet after it: refused, saying so, not taken for a damaged file.
    let ignored = with_packet_before_data(&b, &[2, 0, 3, 0]);
    convert_fails(
        &written(dir.path(), "ignored.e57", &ignored),
        "scan 0 of 1: its binary section holds an ignored packet at byte 80 before the data \
         packet at byte 84, which the e57 reader cannot step over",
    );
}

#[test]
fn an_empty_scan_whose_data_offset_is_zero_is_read() {
    // libE57Format leaves an empty scan's data offset 0 (no packet written); the crate never
    // reads it. Written here by the crate, which points it at the section's end, then set so.
    let dir = tempfile::tempdir().expect("tempdir");
    let input = dir.path().join("gap.e57");
    let mut specs = super::three_scans();
    specs[1].points = 0;
    write_e57(&input, &specs);
    let b = std::fs::read(&input).expect("written");
    let l = logical(&b);
    let (at, len) = (u64_at(&b, 24) as usize, u64_at(&b, 32) as usize);
    let at = at / PAGE * DATA + at % PAGE;
    let xml = String::from_utf8(l[at..at + len].to_vec()).expect("XML text");
    let offsets: Vec<u64> = xml
        .split("fileOffset=\"")
        .skip(1)
        .filter_map(|t| t.split('"').next()?.parse().ok())
        .collect();
    assert_eq!(offsets.len(), 3, "{xml}");
    let zeroed = patched(&b, offsets[1] as usize + 16, &0u64.to_le_bytes());
    let input = written(dir.path(), "zeroed.e57", &zeroed);
    let out = dir.path().join("zeroed.strata");
    run_ok(&["convert", s(&input), "-o", s(&out), "--quiet"]);
    let (meta, _) = stored(&out);
    assert_eq!(meta.scanners.len(), 3);
}

#[test]
fn a_record_count_below_the_data_is_refused() {
    let dir = tempfile::tempdir().expect("tempdir");
    // One float fewer than the tiny file's section holds: the crate read 2089 points and
    // dropped the last without a word.
    let fewer = with_xml(&tiny(), |x| {
        x.replace("recordCount=\"2090\"", "recordCount=\"2089\"")
    });
    convert_fails(
        &written(dir.path(), "fewer.e57", &fewer),
        "scan 0 of 1: its CartesianX field's stream holds the bits of 2090 values, but it \
         states 2089 points: the points past that count would be dropped",
    );
    // Bit-packed integers (21 bits): far fewer than the section holds (one fewer hides in the
    // padding of the 32-bit register a writer flushes last); and far fewer still, where the
    // packet that completes the stated points is the first of several, and the points are in
    // the packets after it.
    for count in [30000, 100] {
        let fewer = with_xml(&bunny(), |x| {
            x.replace("recordCount=\"30571\"", &format!("recordCount=\"{count}\""))
        });
        convert_fails(
            &written(dir.path(), &format!("fewer_{count}.e57"), &fewer),
            &format!(
                "scan 0 of 1: its CartesianX field's stream holds the bits of 30572 values, but \
                 it states {count} points"
            ),
        );
    }
    // A field stated to take no bits, whose stream holds the values all the same: the crate
    // gave every point the one value and ignored them.
    let flat_x = with_xml(&bunny(), |x| {
        x.replacen(
            "minimum=\"-1048576\" maximum=\"1048575\"",
            "minimum=\"0\" maximum=\"0\"",
            1,
        )
    });
    convert_fails(
        &written(dir.path(), "flat_x.e57", &flat_x),
        "scan 0 of 1: its CartesianX field takes no bits (its minimum equals its maximum), \
         yet its stream holds",
    );
}
