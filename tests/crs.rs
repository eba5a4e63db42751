//! The coordinate reference system the inputs state, through `convert` and every export: read
//! the way the global encoding's WKT bit says, one system however it is written, two refused,
//! text that is no WKT no system, and written one way per point format.

mod common;
use common::*;
use std::path::Path;

const UTM10: &str = r#"PROJCS["WGS 84 / UTM zone 10N",GEOGCS["WGS 84",DATUM["WGS_1984",SPHEROID["WGS 84",6378137,298.257223563]],PRIMEM["Greenwich",0],UNIT["degree",0.0174532925199433],AUTHORITY["EPSG","4326"]],PROJECTION["Transverse_Mercator"],PARAMETER["central_meridian",-123],UNIT["metre",1],AUTHORITY["EPSG","32610"]]"#;

/// GeoTIFF keys naming projected system `epsg`.
fn keys(epsg: u16) -> Vec<u8> {
    [1u16, 1, 0, 1, 3072, 0, 1, epsg]
        .iter()
        .flat_map(|k| k.to_le_bytes())
        .collect()
}

/// A LAS 1.4 file of format `format` with one point at `x`, the WKT bit as given, and these
/// `LASF_Projection` records (id, payload).
fn las_with_crs(path: &Path, format: u8, wkt_bit: bool, records: &[(u16, Vec<u8>)], x: f64) {
    let vlrs = records
        .iter()
        .map(|(id, data)| vlr("LASF_Projection", *id, data.clone()))
        .collect();
    las_with_records(path, format, wkt_bit, (vlrs, Vec::new()), x);
}

fn vlr(user: &str, record_id: u16, data: Vec<u8>) -> las::Vlr {
    las::Vlr {
        user_id: user.into(),
        record_id,
        description: String::new(),
        data,
    }
}

/// As `las_with_crs`, with any VLRs and EVLRs.
fn las_with_records(
    path: &Path,
    format: u8,
    wkt_bit: bool,
    (vlrs, evlrs): (Vec<las::Vlr>, Vec<las::Vlr>),
    x: f64,
) {
    let mut builder = las::Builder::from((1, 4));
    builder.point_format = las::point::Format::new(format).expect("format");
    builder.has_wkt_crs = wkt_bit;
    builder.vlrs = vlrs;
    builder.evlrs = evlrs;
    let header = builder.into_header().expect("header");
    let mut writer = las::Writer::from_path(path, header).expect("writer");
    let point = las::Point {
        x,
        return_number: 1,
        number_of_returns: 1,
        gps_time: Some(0.0),
        ..Default::default()
    };
    writer.write_point(point).expect("write");
    writer.close().expect("close");
}

fn dataset_crs(ds: &Path) -> serde_json::Value {
    let meta: serde_json::Value =
        serde_json::from_slice(&std::fs::read(ds.join("metadata.json")).expect("metadata"))
            .expect("JSON");
    meta["crs"].clone()
}

/// Where the WKT and the keys of one file name two systems, the WKT bit says which is the
/// file's (it took the WKT whatever the bit said); text that is no WKT states no system.
#[test]
fn the_wkt_bit_says_which_of_two_systems_a_file_states() {
    let dir = tempfile::tempdir().expect("tempdir");
    let both = [(2112u16, UTM10.as_bytes().to_vec()), (34735, keys(32611))];
    for (bit, want) in [(false, "keys"), (true, "wkt")] {
        let (las, ds) = (
            dir.path().join(format!("{bit}.las")),
            dir.path().join(format!("{bit}")),
        );
        las_with_crs(&las, 1, bit, &both, 0.0);
        let out = run_ok(&["convert", s(&las), "-o", s(&ds)]);
        let said = String::from_utf8_lossy(&out.stderr);
        assert!(said.contains("name two systems"), "{said}");
        let crs = dataset_crs(&ds);
        assert_eq!(crs["wkt"].is_string(), want == "wkt", "{bit}: {crs}");
        assert_eq!(crs["geotiff"].is_object(), want == "keys", "{bit}: {crs}");
    }
    let (las, ds) = (dir.path().join("junk.las"), dir.path().join("junk"));
    las_with_crs(&las, 1, true, &[(2112, b"hello world\0".to_vec())], 0.0);
    let out = run_ok(&["convert", s(&las), "-o", s(&ds)]);
    assert!(String::from_utf8_lossy(&out.stderr).contains("holds no WKT"));
    assert!(dataset_crs(&ds).is_null());
}

/// One system written as WKT by one input and as GeoTIFF keys by another is one system, kept
/// both ways (it was a conflict, and the WKT lost); two systems are refused (they were
/// merged, the first kept, with a warning).
#[test]
fn inputs_merge_in_one_system_and_are_refused_in_two() {
    let dir = tempfile::tempdir().expect("tempdir");
    let (a, b, c) = (
        dir.path().join("a.las"),
        dir.path().join("b.las"),
        dir.path().join("c.las"),
    );
    las_with_crs(&a, 1, false, &[(34735, keys(32610))], 0.0);
    las_with_crs(&b, 6, true, &[(2112, UTM10.as_bytes().to_vec())], 1.0);
    las_with_crs(&c, 1, false, &[(34735, keys(32611))], 2.0);
    let ds = dir.path().join("one");
    let out = run_ok(&["convert", s(&a), s(&b), "-o", s(&ds)]);
    assert!(!String::from_utf8_lossy(&out.stderr).contains("another coordinate"));
    let crs = dataset_crs(&ds);
    assert!(
        crs["wkt"].is_string() && crs["geotiff"].is_object(),
        "{crs}"
    );
    // Format 6 states the WKT alone.
    let las_out = dir.path().join("one.las");
    run_ok(&["export", s(&ds), "-o", s(&las_out)]);
    let ids: Vec<u16> = crs_records(&las_out).iter().map(|r| r.0).collect();
    assert_eq!(ids, [2112]);
    let two = dir.path().join("two");
    refused(
        &["convert", s(&a), s(&c), "-o", s(&two)],
        &["EPSG:32611", "EPSG:32610", "two systems"],
    );
    assert!(!two.exists());
    // Behind a first input that names no code, the two are still told apart.
    let local = dir.path().join("local.las");
    let site = br#"LOCAL_CS["site grid",UNIT["metre",1]]"#.to_vec();
    las_with_crs(&local, 1, true, &[(2112, site)], 3.0);
    refused(
        &["convert", s(&local), s(&a), s(&c), "-o", s(&two)],
        &["EPSG:32611", "EPSG:32610", "two systems"],
    );
}

/// The records of the `LASF_Projection` user in a LAS file, by record id.
fn crs_records(path: &Path) -> Vec<(u16, Vec<u8>)> {
    let reader = las::Reader::from_path(path).expect("read LAS");
    let h = reader.header();
    let mut out: Vec<(u16, Vec<u8>)> = h
        .vlrs()
        .iter()
        .chain(h.evlrs())
        .filter(|v| v.user_id == "LASF_Projection")
        .map(|v| (v.record_id, v.data.clone()))
        .collect();
    out.sort();
    out
}

#[test]
fn the_inputs_crs_goes_back_out_with_every_export() {
    let dir = tempfile::tempdir().expect("tempdir");
    let input = data("autzen_trim.las");
    let ds = dir.path().join("ds");
    run_ok(&["convert", s(&input), "-o", s(&ds), "-q"]);
    let stated = crs_records(&input);
    assert_eq!(
        stated.iter().map(|r| r.0).collect::<Vec<_>>(),
        [2112, 34735, 34736, 34737],
        "the input states its CRS both ways"
    );
    // LAS: the records as the input had them (a trailing NUL of the text records aside).
    let las_out = dir.path().join("out.las");
    run_ok(&["export", s(&ds), "-o", s(&las_out)]);
    let trimmed = |r: &[(u16, Vec<u8>)]| -> Vec<(u16, Vec<u8>)> {
        r.iter()
            .map(|(id, d)| {
                let end = d.iter().rposition(|&b| b != 0).map_or(0, |i| i + 1);
                (*id, d[..end].to_vec())
            })
            .collect()
    };
    // Format 3 here, which states a system one way (LAS 1.4 R15, 2.5): the GeoTIFF keys,
    // which legacy readers know, and the WKT bit clear.
    assert_eq!(trimmed(&crs_records(&las_out)), trimmed(&stated[1..]));
    let reader = las::Reader::from_path(&las_out).expect("read LAS");
    assert!(!reader.header().has_wkt_crs());
    // COPC: the WKT alone, as COPC calls for.
    let copc = dir.path().join("out.copc.laz");
    run_ok(&["export", s(&ds), "-o", s(&copc)]);
    assert_eq!(trimmed(&crs_records(&copc)), trimmed(&stated[..1]));
    // PLY has no place for one: said.
    let ply = dir.path().join("out.ply");
    let out = run_ok(&["export", s(&ds), "-o", s(&ply)]);
    let said = String::from_utf8_lossy(&out.stderr);
    assert!(said.contains("PLY has no place"), "{said}");
    // Potree 2: the WKT as its projection.
    let potree = dir.path().join("potree");
    run_ok(&["export", s(&ds), "-o", s(&potree), "--format", "potree2"]);
    let meta: serde_json::Value =
        serde_json::from_slice(&std::fs::read(potree.join("metadata.json")).expect("metadata"))
            .expect("json");
    let wkt = String::from_utf8_lossy(&trimmed(&stated)[0].1).into_owned();
    assert_eq!(meta["projection"], wkt.as_str());
}

/// An E57 file's coordinateMetadata is its CRS where it holds WKT (it was ignored without a
/// word); other text states none, and is said.
#[test]
fn an_e57_states_its_crs_in_its_coordinate_metadata() {
    let dir = tempfile::tempdir().expect("tempdir");
    for (name, text, want) in [("wkt", UTM10, true), ("code", "EPSG:32610", false)] {
        let path = dir.path().join(format!("{name}.e57"));
        let mut w = e57::E57Writer::from_file(&path, "strata-test-file").expect("e57 writer");
        w.set_coordinate_metadata(Some(text.to_string()));
        let prototype = vec![
            e57::Record::CARTESIAN_X_F64,
            e57::Record::CARTESIAN_Y_F64,
            e57::Record::CARTESIAN_Z_F64,
        ];
        let mut pc = w.add_pointcloud("scan", prototype).expect("scan writer");
        for i in 0..10 {
            let p = [i as f64, 0.0, 0.0].map(e57::RecordValue::Double);
            pc.add_point(p.to_vec()).expect("point");
        }
        pc.finalize().expect("scan written");
        w.finalize().expect("file written");
        let ds = dir.path().join(name);
        let out = run_ok(&["convert", s(&path), "-o", s(&ds)]);
        let crs = dataset_crs(&ds);
        assert_eq!(crs["wkt"].as_str(), want.then_some(UTM10), "{name}: {crs}");
        let said = String::from_utf8_lossy(&out.stderr).contains("is no WKT");
        assert_eq!(said, !want, "{name}");
    }
}

/// A WKT longer than a VLR holds (64 KiB), in the second of two EVLRs: read (the las crate
/// keeps the first EVLR only, and the CRS was lost), and written back by COPC export as an
/// EVLR of its own (it was left out without a word).
#[test]
fn a_long_wkt_in_a_later_evlr_is_read_and_exported_to_copc() {
    let dir = tempfile::tempdir().expect("tempdir");
    let input = dir.path().join("long.las");
    // Spaces between a WKT's tokens are allowed anywhere.
    let long = UTM10.replacen(',', &format!(",{}", " ".repeat(70_000)), 1);
    let mut wkt = long.clone().into_bytes();
    wkt.push(0);
    let evlrs = vec![
        vlr("strata_test", 7, vec![1; 300]),
        vlr("LASF_Projection", 2112, wkt),
    ];
    las_with_records(&input, 6, true, (Vec::new(), evlrs), 0.0);
    let ds = dir.path().join("ds");
    run_ok(&["convert", s(&input), "-o", s(&ds), "-q"]);
    assert_eq!(dataset_crs(&ds)["wkt"], long.as_str());
    let copc = dir.path().join("out.copc.laz");
    run_ok(&["export", s(&ds), "-o", s(&copc)]);
    let back = dir.path().join("back");
    run_ok(&["convert", s(&copc), "-o", s(&back), "-q"]);
    assert_eq!(dataset_crs(&back)["wkt"], long.as_str());
}
