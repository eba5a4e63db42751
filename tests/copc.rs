//! `strata export DATASET -o OUT.copc.laz`: a COPC 1.0 file that third-party readers take: the
//! `las` crate reads every point back as `strata export` writes it to LAS, and laspy's
//! CopcReader (where Python has laspy and lazrs) answers bounds and level queries with exactly
//! the points Strata holds there.

mod common;

use common::{las_points, run_ok, s};

#[test]
fn the_las_crate_reads_every_point_of_the_copc_file_back() {
    let dir = tempfile::tempdir().expect("tempdir");
    let dataset = common::converted("copc-fixture", "autzen_trim.laz", "autzen");
    let las = dir.path().join("all.las");
    let copc = dir.path().join("all.copc.laz");
    common::run_ok(&["export", s(&dataset), "-o", s(&las)]);
    common::run_ok(&["export", s(&dataset), "-o", s(&copc)]);
    // The legacy scan angle rank (whole degrees) becomes the scan angle of formats 6 to 8, in
    // steps of 0.006°: compared apart, within a step.
    let apart = |path: &std::path::Path| {
        let mut v: Vec<_> = las_points(path)
            .0
            .into_iter()
            .map(|(xyz, mut a)| {
                let angle = std::mem::take(&mut a[9]);
                ((xyz, a), angle)
            })
            .collect();
        v.sort_unstable();
        v
    };
    let (want, got) = (apart(&las), apart(&copc));
    assert_eq!(got.len(), want.len());
    for (g, w) in got.iter().zip(&want) {
        assert_eq!(
            g.0, w.0,
            "the COPC file's points differ from the LAS export's"
        );
        assert!((g.1 - w.1).abs() <= 3, "scan angle {} vs {}", g.1, w.1);
    }

    // `strata info` says what it is; `strata convert` reads it back into the same points.
    let o = common::run_ok(&["info", s(&copc), "--json"]);
    let info: serde_json::Value = serde_json::from_slice(&o.stdout).expect("info JSON");
    let meta = strata_format::LocalDataset::open(&dataset)
        .expect("opens")
        .metadata()
        .clone();
    assert_eq!(info["kind"], "copc");
    assert_eq!(info["points"].as_u64(), Some(meta.points));
    assert_eq!(info["copc"]["points"].as_u64(), Some(meta.points));
    assert_eq!(info["copc"]["spacing"].as_f64(), Some(meta.spacing));
    let back = dir.path().join("back.strata");
    common::run_ok(&["convert", s(&copc), "-o", s(&back), "--quiet"]);
    let again = dir.path().join("again.copc.laz");
    common::run_ok(&["export", s(&back), "-o", s(&again)]);
    assert!(
        apart(&again) == got,
        "a COPC file converted and exported again differs"
    );
    // An existing output is kept unless --overwrite says otherwise.
    let o = common::run(&["export", s(&dataset), "-o", s(&copc)]);
    assert!(!o.status.success());
    assert!(String::from_utf8_lossy(&o.stderr).contains("--overwrite"));

    // What a COPC reader takes on trust in the info VLR is checked, not just printed: a cube
    // of no size, a root page outside the hierarchy.
    let bytes = std::fs::read(&copc).expect("read");
    let vlr = bytes
        .windows(4)
        .position(|w| w == b"copc")
        .expect("the info VLR")
        - 2;
    let data = vlr + 54;
    for (at, value, expect) in [
        (
            data + 24,
            f64::NAN.to_le_bytes(),
            "half size is not a finite positive number",
        ),
        (
            data + 40,
            0u64.to_le_bytes(),
            "root hierarchy page at byte 0",
        ),
        (data + 48, 0u64.to_le_bytes(), ", 0 bytes long"),
    ] {
        let mut b = bytes.clone();
        b[at..at + 8].copy_from_slice(&value);
        let bad = dir.path().join("bad.copc.laz");
        std::fs::write(&bad, b).expect("write");
        let o = common::run(&["info", s(&bad)]);
        let err = String::from_utf8_lossy(&o.stderr);
        assert!(
            !o.status.success() && err.contains(expect),
            "{expect}: {err}"
        );
    }
}

/// Whether Python has laspy and lazrs; CI installs them and sets STRATA_REQUIRE_LASPY.
fn have_laspy() -> bool {
    let ok = std::process::Command::new("python3")
        .args(["-c", "import laspy, lazrs; from laspy import CopcReader"])
        .output()
        .is_ok_and(|o| o.status.success());
    if !ok {
        assert!(
            std::env::var_os("STRATA_REQUIRE_LASPY").is_none(),
            "python3 with laspy and lazrs is missing but STRATA_REQUIRE_LASPY is set"
        );
        eprintln!("skipping: python3 with laspy and lazrs is not installed");
    }
    ok
}

#[test]
fn laspy_answers_level_and_bounds_queries_with_the_points_strata_holds_there() {
    if !have_laspy() {
        return;
    }
    // One scale for x, y and z (autzen); one per axis with extra attributes and no returns
    // (the bunny with normals: its nodes are keyed again in COPC's larger cube); 20 levels
    // with inner nodes left empty (the deep fixture: listed empty so that readers walking
    // the hierarchy from the root reach what lies below).
    let autzen = common::converted("copc-fixture", "autzen_trim.laz", "autzen");
    let dir = tempfile::tempdir().expect("tempdir");
    let bunny = dir.path().join("bunny.strata");
    // The bunny's float intensity (0 to 1) has no whole value for LAS's intensity field, and
    // is refused there: renamed, it goes out as extra bytes like its confidence.
    let ply = std::fs::read_to_string(common::data("bunny_bun_zipper.ply")).expect("bunny");
    let renamed = dir.path().join("bunny.ply");
    std::fs::write(
        &renamed,
        ply.replacen(
            "property float intensity\n",
            "property float reflectance\n",
            1,
        ),
    )
    .expect("write the bunny");
    common::run_ok(&[
        "convert",
        s(&renamed),
        "-o",
        s(&bunny),
        "--normals",
        "--quiet",
    ]);
    let deep = common::deep_dataset("copc-deep");
    for dataset in [&autzen, &bunny, &deep] {
        queries_match(dataset, dir.path());
    }
}

fn queries_match(dataset: &std::path::Path, dir: &std::path::Path) {
    let copc = dir.join("q.copc.laz");
    common::run_ok(&["export", s(dataset), "-o", s(&copc), "--overwrite"]);
    // What Strata holds: each node's stored integers, by level.
    let ds = strata_format::LocalDataset::open(dataset).expect("opens");
    let meta = ds.metadata().clone();
    let mut held: Vec<(u8, [i64; 3])> = Vec::new();
    for node in ds.all_nodes().expect("nodes") {
        let cols = ds.read_node(&node).expect("node");
        for i in 0..cols.count {
            let p = cols.position(i);
            held.push((node.key.level, p.map(i64::from)));
        }
    }
    let real = |k: usize, v: i64| meta.offset[k] + meta.scale[k] * v as f64;
    // Two boxes inside the bounds: the low quarter in x and y, all heights; the middle half.
    let (lo, hi) = (meta.bounds.min, meta.bounds.max);
    let at = |k: usize, f: f64| lo[k] + (hi[k] - lo[k]) * f;
    let boxes = [
        [
            at(0, 0.0),
            at(1, 0.0),
            at(2, 0.0),
            at(0, 0.5),
            at(1, 0.5),
            at(2, 1.0),
        ],
        [
            at(0, 0.25),
            at(1, 0.25),
            at(2, 0.25),
            at(0, 0.75),
            at(1, 0.75),
            at(2, 0.75),
        ],
    ];
    let mut queries: Vec<serde_json::Value> = (0..=meta.depth)
        .map(|l| serde_json::json!({ "level": l }))
        .collect();
    queries.extend(boxes.iter().map(|b| serde_json::json!({ "bounds": b })));
    let qpath = dir.join("queries.json");
    let apath = dir.join("answers.json");
    std::fs::write(&qpath, serde_json::Value::from(queries.clone()).to_string()).expect("write");
    let script = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/copc/queries.py");
    let o = std::process::Command::new("python3")
        .args([s(&script), s(&copc), s(&qpath), s(&apath)])
        .output()
        .expect("python3 runs");
    assert!(
        o.status.success(),
        "laspy: {}",
        String::from_utf8_lossy(&o.stderr)
    );
    let answers: serde_json::Value =
        serde_json::from_slice(&std::fs::read(&apath).expect("answers")).expect("JSON");
    assert!([6, 7, 8].contains(&answers["point_format"].as_u64().expect("format")));
    // The root's spacing in COPC's cube, whose edge is the largest axis's.
    let largest = meta.scale.iter().fold(0.0f64, |m, v| m.max(*v));
    let spacing = answers["spacing"].as_f64().expect("spacing");
    assert!((spacing / (meta.spacing * largest / meta.scale[0]) - 1.0).abs() < 1e-12);
    for k in 0..3 {
        let (lo, hi) = (answers["mins"][k].as_f64(), answers["maxs"][k].as_f64());
        let close = |a: Option<f64>, b: f64| a.is_some_and(|a| (a - b).abs() <= meta.scale[k]);
        assert!(
            close(lo, meta.bounds.min[k]) && close(hi, meta.bounds.max[k]),
            "axis {k}"
        );
    }
    // Without return numbers, every point is a single return (0 is invalid in formats 6+).
    if !meta.attributes.iter().any(|a| a.name == "return_number") {
        assert_eq!(answers["returns"], serde_json::json!([1]));
    }
    // Attributes beyond the point format's, as extra bytes under their names (a normal as
    // PDAL's NormalX, NormalY, NormalZ).
    let extra: Vec<&str> = answers["extra"]
        .as_array()
        .expect("extra")
        .iter()
        .filter_map(|v| v.as_str())
        .collect();
    let has = |n: &str| meta.attributes.iter().any(|a| a.name == n);
    if has("normal") {
        for n in ["NormalX", "NormalY", "NormalZ"] {
            assert!(
                extra.contains(&n),
                "{}: no {n} in {extra:?}",
                dataset.display()
            );
        }
    }
    for n in ["confidence", "radius", "surface_variation"]
        .into_iter()
        .filter(|n| has(n))
    {
        assert!(
            extra.contains(&n),
            "{}: no {n} in {extra:?}",
            dataset.display()
        );
    }
    let got = |i: usize| -> Vec<[i64; 3]> {
        answers["answers"][i]
            .as_array()
            .expect("answer")
            .iter()
            .map(|p| std::array::from_fn(|k| p[k].as_i64().expect("integer")))
            .collect()
    };
    let name = dataset.display();
    let mut total = 0;
    for level in 0..=meta.depth {
        let mut want: Vec<[i64; 3]> = held
            .iter()
            .filter(|(l, _)| *l as u32 == level)
            .map(|(_, p)| *p)
            .collect();
        want.sort_unstable();
        total += want.len();
        assert_eq!(got(level as usize), want, "{name}: level {level}");
    }
    assert_eq!(total, meta.points as usize);
    for (i, b) in boxes.iter().enumerate() {
        let mut want: Vec<[i64; 3]> = held
            .iter()
            .map(|(_, p)| *p)
            .filter(|p| (0..3).all(|k| (b[k]..=b[k + 3]).contains(&real(k, p[k]))))
            .collect();
        want.sort_unstable();
        assert!(
            want.len() > 500,
            "{name}: box {i} holds {} points",
            want.len()
        );
        assert_eq!(got(meta.depth as usize + 1 + i), want, "{name}: box {i}");
    }
}

/// A LAZ whose variable-size chunk table ends with an empty chunk (laz-rs writes one) is valid:
/// laspy reads it, and so does the conversion (it refused it as a corrupt chunk table).
#[test]
fn a_laz_whose_chunk_table_ends_with_an_empty_chunk_converts() {
    if !have_laspy() {
        return;
    }
    let dir = tempfile::tempdir().expect("tempdir");
    // One point (a table of two chunks for it) and many; the layered compressor (format 6)
    // leaves the empty chunk no bytes, the point-wise one (formats 1 and 3) a few.
    for (n, format) in [(1u64, 6), (1000, 6), (1000, 3), (1, 1)] {
        let laz = dir.path().join(format!("empty_chunk{n}_{format}.laz"));
        let script =
            std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/copc/empty_chunk.py");
        let o = std::process::Command::new("python3")
            .args([s(&script), s(&laz), &n.to_string(), &format.to_string()])
            .output()
            .expect("python3 runs");
        assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
        let ds = dir.path().join(format!("ds{n}_{format}"));
        common::run_ok(&["convert", s(&laz), "-o", s(&ds), "-q"]);
        let meta: serde_json::Value =
            serde_json::from_slice(&std::fs::read(ds.join("metadata.json")).expect("metadata"))
                .expect("json");
        assert_eq!(meta["points"], n);
    }
}

/// A CRS given only as GeoTIFF keys vanished from COPC (which states a CRS as WKT) without a
/// word; a legacy LAS keeps the keys and says nothing.
#[test]
fn a_crs_copc_cannot_state_is_said() {
    let dir = tempfile::tempdir().expect("tempdir");
    let (input, ds) = (dir.path().join("geotiff.las"), dir.path().join("ds"));
    // GeoKeyDirectory 1.1.0 with one key: ProjectedCSTypeGeoKey (3072) = EPSG 2994.
    let keys: Vec<u8> = [1u16, 1, 0, 1, 3072, 0, 1, 2994]
        .iter()
        .flat_map(|k| k.to_le_bytes())
        .collect();
    let mut builder = las::Builder::from((1, 2));
    builder.vlrs.push(las::Vlr {
        user_id: "LASF_Projection".into(),
        record_id: 34735,
        description: "GeoKeyDirectoryTag".into(),
        data: keys,
    });
    let header = builder.into_header().expect("header");
    let mut writer = las::Writer::from_path(&input, header).expect("writer");
    writer.write_point(las::Point::default()).expect("write");
    writer.close().expect("close");
    run_ok(&["convert", s(&input), "-o", s(&ds), "-q"]);
    let said = |out: &str| {
        let o = run_ok(&["export", s(&ds), "-o", s(&dir.path().join(out))]);
        String::from_utf8_lossy(&o.stderr).to_string()
    };
    let copc = said("out.copc.laz");
    assert!(
        copc.contains("GeoTIFF keys only, and COPC states one as WKT"),
        "{copc}"
    );
    let las = said("out.las");
    assert!(!las.contains("warning"), "{las}");
}

/// A folder where the COPC file would go is refused before anything is written; it failed
/// after writing the whole file, when the file could not be moved into place. The header
/// states the day it was written, as the LAS export's does (it said 1 January 2026, and the
/// LAS export day 0 of year 0, which is no date).
#[test]
fn a_folder_named_like_the_copc_file_is_refused_at_once() {
    let dir = tempfile::tempdir().expect("tempdir");
    let dataset = common::converted("copc-fixture", "autzen_trim.laz", "autzen");
    let folder = dir.path().join("taken.copc.laz");
    std::fs::create_dir(&folder).expect("mkdir");
    let err = common::refused(
        &["export", s(&dataset), "-o", s(&folder), "--overwrite"],
        &["is a folder; the output is a file"],
    );
    assert!(err.contains(s(&folder)), "{err}");
    let left: Vec<_> = std::fs::read_dir(dir.path())
        .expect("list")
        .map(|e| e.expect("entry").file_name())
        .collect();
    assert_eq!(left, ["taken.copc.laz"], "nothing beside the folder");
    let today = strata_converter::creation_date::today();
    for name in ["dated.copc.laz", "dated.las"] {
        let out = dir.path().join(name);
        run_ok(&["export", s(&dataset), "-o", s(&out)]);
        let head = std::fs::read(&out).expect("read");
        let field = |at: usize| u16::from_le_bytes([head[at], head[at + 1]]);
        let (day, year) = (field(90), field(92));
        // Today, or (run across midnight) the day before.
        assert!(
            year == today.1 || year + 1 == today.1,
            "{name}: year {year}"
        );
        assert!((1..=366).contains(&day), "{name}: day {day}");
        assert!(
            day == today.0 || day + 1 == today.0 || today.0 == 1,
            "{name}: day {day}"
        );
    }
}

/// A COPC file whose hierarchy is not its first EVLR (another writer put a record before it):
/// `strata info` found the hierarchy through the las crate, which keeps only the first EVLR,
/// and said "hierarchy EVLR is missing".
#[test]
fn info_finds_the_hierarchy_behind_another_evlr() {
    let dir = tempfile::tempdir().expect("tempdir");
    let copc = exported_copc(dir.path(), "plain.copc.laz");
    let mut b = std::fs::read(&copc).expect("read");
    let u64_at = |b: &[u8], at: usize| u64::from_le_bytes(b[at..at + 8].try_into().expect("8"));
    let first_evlr = u64_at(&b, 235) as usize;
    // A record of 100 bytes, inserted before the first EVLR (the hierarchy's).
    let mut record = vec![0u8; 60 + 100];
    record[2..13].copy_from_slice(b"other_maker");
    record[18..20].copy_from_slice(&7u16.to_le_bytes());
    record[20..28].copy_from_slice(&100u64.to_le_bytes());
    let moved = record.len() as u64;
    // What points into the hierarchy moves with it: the info VLR's root page, and pages
    // that entries of -1 points name.
    let info = b.windows(4).position(|w| w == b"copc").expect("info VLR") - 2 + 54;
    let root = u64_at(&b, info + 40);
    b[info + 40..info + 48].copy_from_slice(&(root + moved).to_le_bytes());
    let hierarchy = &mut b[first_evlr + 60..];
    for e in hierarchy.chunks_exact_mut(32) {
        if i32::from_le_bytes(e[28..32].try_into().expect("4")) == -1 {
            let at = u64::from_le_bytes(e[16..24].try_into().expect("8"));
            e[16..24].copy_from_slice(&(at + moved).to_le_bytes());
        }
    }
    let evlrs = u32::from_le_bytes(b[243..247].try_into().expect("4"));
    b[243..247].copy_from_slice(&(evlrs + 1).to_le_bytes());
    b.splice(first_evlr..first_evlr, record);
    let moved_copc = dir.path().join("moved.copc.laz");
    std::fs::write(&moved_copc, &b).expect("write");
    let (want, got) = (copc_summary(&copc), copc_summary(&moved_copc));
    assert!(want["points"].as_u64() > Some(0), "{want}");
    assert_eq!(got, want);
}

/// What `strata info` takes from a COPC hierarchy is checked as a reader takes it on trust: an
/// entry whose chunk lies outside the point data, one naming no node of the octree, and
/// counts that do not sum to the header's were printed as if whole.
#[test]
fn info_refuses_a_damaged_hierarchy_entry() {
    let dir = tempfile::tempdir().expect("tempdir");
    let copc = exported_copc(dir.path(), "whole.copc.laz");
    let bytes = std::fs::read(&copc).expect("read");
    let entries = u64::from_le_bytes(bytes[235..243].try_into().expect("8")) as usize + 60;
    // The second entry of the root page, and what is damaged in it.
    let at = entries + 32;
    let damage: [(usize, Vec<u8>, &str); 4] = [
        (16, 0u64.to_le_bytes().to_vec(), "outside bytes"),
        (
            0,
            40i32.to_le_bytes().to_vec(),
            "names no node of an octree",
        ),
        (4, 5i32.to_le_bytes().to_vec(), "names no node of an octree"),
        (28, (-7i32).to_le_bytes().to_vec(), "holds -7 points"),
    ];
    for (field, value, expect) in damage {
        let mut b = bytes.clone();
        b[at + field..at + field + value.len()].copy_from_slice(&value);
        let bad = dir.path().join("bad.copc.laz");
        std::fs::write(&bad, b).expect("write");
        let err = common::refused(&["info", s(&bad)], &[expect, "hierarchy entry 1"]);
        assert!(err.contains(s(&bad)), "{err}");
    }
    // One point more in an entry than its chunk holds: the sum is not the header's count.
    let mut b = bytes.clone();
    let count = i32::from_le_bytes(b[at + 28..at + 32].try_into().expect("4"));
    b[at + 28..at + 32].copy_from_slice(&(count + 1).to_le_bytes());
    let bad = dir.path().join("sum.copc.laz");
    std::fs::write(&bad, b).expect("write");
    common::refused(&["info", s(&bad)], &["hierarchy lists", "and the header"]);

    // The hierarchy split in two pages, as writers of deep octrees do: the root page holds the
    // root's entry and one of -1 points naming the page of the rest, which follows it. The
    // same summary; and that page named outside the hierarchy is refused.
    let evlr = entries - 60;
    let (mut head, page) = (bytes[..entries].to_vec(), &bytes[entries..]);
    assert_eq!(
        evlr + 60 + page.len(),
        bytes.len(),
        "the hierarchy is the last EVLR"
    );
    let rest = &page[32..];
    let mut refer = page[32..64].to_vec();
    refer[16..24].copy_from_slice(&(entries as u64 + 64).to_le_bytes());
    refer[24..28].copy_from_slice(&(rest.len() as i32).to_le_bytes());
    refer[28..32].copy_from_slice(&(-1i32).to_le_bytes());
    head[evlr + 20..evlr + 28].copy_from_slice(&(page.len() as u64 + 32).to_le_bytes());
    let info = head
        .windows(4)
        .position(|w| w == b"copc")
        .expect("info VLR")
        - 2
        + 54;
    head[info + 48..info + 56].copy_from_slice(&64u64.to_le_bytes());
    let split = [head, page[..32].to_vec(), refer, rest.to_vec()].concat();
    let split_copc = dir.path().join("split.copc.laz");
    std::fs::write(&split_copc, &split).expect("write");
    assert_eq!(copc_summary(&split_copc), copc_summary(&copc));
    let mut b = split.clone();
    let refer_at = entries + 32;
    b[refer_at + 16..refer_at + 24].copy_from_slice(&64u64.to_le_bytes());
    let bad = dir.path().join("page.copc.laz");
    std::fs::write(&bad, b).expect("write");
    common::refused(
        &["info", s(&bad)],
        &["page inside the hierarchy EVLR at byte 64"],
    );
    // Pages begun mid-entry: the named page, and the root page, 16 bytes on.
    let mut b = split.clone();
    let mid = entries as u64 + 64 + 16;
    b[refer_at + 16..refer_at + 24].copy_from_slice(&mid.to_le_bytes());
    b[refer_at + 24..refer_at + 28].copy_from_slice(&32i32.to_le_bytes());
    let bad = dir.path().join("mid.copc.laz");
    std::fs::write(&bad, b).expect("write");
    common::refused(&["info", s(&bad)], &["not whole entries"]);
    let mut b = bytes.clone();
    b[info + 40..info + 48].copy_from_slice(&(entries as u64 + 16).to_le_bytes());
    b[info + 48..info + 56].copy_from_slice(&32u64.to_le_bytes());
    let bad = dir.path().join("root.copc.laz");
    std::fs::write(&bad, b).expect("write");
    common::refused(&["info", s(&bad)], &["not a page of whole entries"]);
}

/// The autzen fixture exported to `dir/name` as COPC.
fn exported_copc(dir: &std::path::Path, name: &str) -> std::path::PathBuf {
    let dataset = common::converted("copc-fixture", "autzen_trim.laz", "autzen");
    let copc = dir.join(name);
    run_ok(&["export", s(&dataset), "-o", s(&copc)]);
    copc
}

/// `strata info --json`'s COPC summary of `path`.
fn copc_summary(path: &std::path::Path) -> serde_json::Value {
    let o = run_ok(&["info", s(path), "--json"]);
    let v: serde_json::Value = serde_json::from_slice(&o.stdout).expect("info JSON");
    v["copc"].clone()
}
