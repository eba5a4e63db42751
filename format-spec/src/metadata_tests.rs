//! metadata.json: what a reader accepts and refuses.

use super::*;

/// A valid 1.1 `metadata.json` as a JSON value.
fn meta_1_1() -> serde_json::Value {
    serde_json::json!({
        "format": "strata-lpc", "version": [1, 1], "id": "00112233445566778899aabbccddeeff",
        "points": 1, "nodes": 1, "depth": 0,
        "scale": [0.01, 0.01, 0.01], "offset": [0.0, 0.0, 0.0],
        "bounds": {"min": [0.0, 0.0, 0.0], "max": [0.0, 0.0, 0.0]},
        "cube": {"min": [0, 0, 0], "bits": 1}, "spacing": 0.0002, "sampling": "poisson",
        "attributes": [],
        "files": {"hierarchy": {"name": "hierarchy.bin", "size": 68},
                  "octree": {"name": "octree.bin", "size": 40}},
        "hierarchy": {"root_page_offset": 32, "root_page_size": 36, "page_levels": 5}
    })
}

fn parse(v: &serde_json::Value) -> Result<Metadata, String> {
    Metadata::from_json(v.to_string().as_bytes(), Path::new("metadata.json"))
        .map_err(|e| e.to_string())
}

#[test]
fn versions_up_to_ours_are_read_and_newer_ones_refused_by_name() {
    let m = parse(&meta_1_1()).expect("1.1 reads");
    assert_eq!(m.layout(), Layout::V1_1);
    assert_eq!(
        m.id.map(|i| i.to_string()).as_deref(),
        Some("00112233445566778899aabbccddeeff")
    );
    let mut old = meta_1_1();
    old["version"] = serde_json::json!([1, 0]);
    old.as_object_mut().map(|o| o.remove("id"));
    old["hierarchy"]["root_page_offset"] = 8.into();
    assert_eq!(parse(&old).map(|m| m.layout()), Ok(Layout::V1_0));
    let mut newer = meta_1_1();
    newer["version"] = serde_json::json!([1, 2]);
    let err = parse(&newer).err().unwrap_or_default();
    assert!(
        err.contains("version 1.2 is not supported by this reader (it reads 1.0 to 1.1)"),
        "{err}"
    );
    assert!(Metadata::from_json_any_minor(newer.to_string().as_bytes(), Path::new("m")).is_ok());
    // A malformed version is named as found, not as an empty or wrapped number.
    for (bad, shown) in [
        (serde_json::json!("1.1"), "\"1.1\""),
        (serde_json::json!([-1, -1]), "[-1,-1]"),
        (serde_json::json!([1]), "[1]"),
    ] {
        let mut m = meta_1_1();
        m["version"] = bad;
        let err = parse(&m).err().unwrap_or_default();
        assert!(
            err.contains(&format!("two whole numbers (found {shown})")),
            "{err}"
        );
    }
    let mut m = meta_1_1();
    m.as_object_mut().map(|o| o.remove("version"));
    let err = parse(&m).err().unwrap_or_default();
    assert!(err.contains("(found none)"), "{err}");
}

#[test]
fn sampling_and_attribute_scales_are_checked() {
    let mut m = meta_1_1();
    m["sampling"] = "bogus".into();
    let err = parse(&m).err().unwrap_or_default();
    assert!(err.contains("sampling is \"bogus\""), "{err}");
    let mut m = meta_1_1();
    m["attributes"] = serde_json::json!([
        {"name": "position", "type": "i32", "count": 3},
        {"name": "wave", "type": "u16", "count": 2, "scale": [0.5]}
    ]);
    let err = parse(&m).err().unwrap_or_default();
    assert!(
        err.contains("attribute 'wave' has 1 scale value(s) for its 2 component(s)"),
        "{err}"
    );
    m["attributes"][1]["scale"] = serde_json::json!([0.5, 0.25]);
    assert!(parse(&m).is_ok(), "{:?}", parse(&m).err());
}

#[test]
fn the_binary_files_must_be_named_inside_the_dataset() {
    for name in ["/etc/passwd", "../other/octree.bin", "..", "", "a\\b"] {
        let mut m = meta_1_1();
        m["files"]["octree"]["name"] = name.into();
        let err = parse(&m).err().unwrap_or_default();
        assert!(
            err.contains("files.octree.name") && err.contains("not a path"),
            "{name}: {err}"
        );
    }
    let mut m = meta_1_1();
    m["files"]["hierarchy"]["name"] = "sub/hierarchy.bin".into();
    assert!(
        parse(&m)
            .err()
            .unwrap_or_default()
            .contains("files.hierarchy.name")
    );
}

#[test]
fn a_dataset_lists_at_most_max_attributes() {
    let mut m = meta_1_1();
    let many: Vec<serde_json::Value> = (0..=MAX_ATTRIBUTES)
        .map(|i| serde_json::json!({"name": format!("a{i}"), "type": "u8", "count": 1}))
        .collect();
    m["attributes"] = serde_json::Value::Array(many);
    let err = parse(&m).err().unwrap_or_default();
    assert!(err.contains("1025 attributes"), "{err}");
}

/// A second attribute of a name would never be read (`export` wrote one LAS field from the
/// other's values, and `verify` passed it); an empty name or a position axis names nothing.
#[test]
fn attribute_names_are_unique_and_name_something() {
    let attr = |name: &str| serde_json::json!({"name": name, "type": "u8", "count": 1});
    let mut m = meta_1_1();
    m["attributes"] = serde_json::json!([attr("intensity"), attr("return_number")]);
    assert!(parse(&m).is_ok());
    m["attributes"] = serde_json::json!([attr("intensity"), attr("intensity")]);
    let err = parse(&m).err().unwrap_or_default();
    assert!(
        err.contains("two attributes are named 'intensity'"),
        "{err}"
    );
    for name in ["", "x", "z"] {
        m["attributes"] = serde_json::json!([attr("intensity"), attr(name)]);
        let err = parse(&m).err().unwrap_or_default();
        assert!(err.contains(&format!("named {name:?}")), "{name:?}: {err}");
    }
}

#[test]
fn spacing_and_bounds_are_checked() {
    for spacing in [0.0, -4.0] {
        let mut m = meta_1_1();
        m["spacing"] = spacing.into();
        assert!(
            parse(&m)
                .err()
                .unwrap_or_default()
                .contains("spacing must be")
        );
    }
    let mut inverted = meta_1_1();
    inverted["bounds"]["min"] = serde_json::json!([1.0, 0.0, 0.0]);
    assert!(
        parse(&inverted)
            .err()
            .unwrap_or_default()
            .contains("bounds must be")
    );
    // With no points there are no bounds to speak of.
    inverted["points"] = 0.into();
    assert!(parse(&inverted).is_ok());
    // The cube of meta_1_1 spans integer positions 0 and 1: 0 to 0.01 in real units.
    let mut inside = meta_1_1();
    inside["bounds"]["max"] = serde_json::json!([0.01, 0.01, 0.01]);
    assert!(parse(&inside).is_ok());
    for (at, value) in [("max", [0.0, 0.02, 0.0]), ("min", [0.0, 0.0, -0.01])] {
        let mut beyond = meta_1_1();
        beyond["bounds"][at] = serde_json::json!(value);
        let err = parse(&beyond).err().unwrap_or_default();
        assert!(
            err.contains("bounds") && err.contains("outside the root cube"),
            "{err}"
        );
    }
}

#[test]
fn a_1_1_dataset_needs_its_id_and_its_root_page_after_the_head() {
    let mut no_id = meta_1_1();
    no_id.as_object_mut().map(|o| o.remove("id"));
    assert!(
        parse(&no_id)
            .err()
            .unwrap_or_default()
            .contains("dataset id")
    );
    let mut moved = meta_1_1();
    moved["hierarchy"]["root_page_offset"] = 40.into();
    assert!(parse(&moved).err().unwrap_or_default().contains("byte 32"));
    let mut bad_id = meta_1_1();
    bad_id["id"] = "not hex".into();
    assert!(
        parse(&bad_id)
            .err()
            .unwrap_or_default()
            .contains("32 hexadecimal digits")
    );
    let mut one_level = meta_1_1();
    one_level["hierarchy"]["page_levels"] = 1.into();
    assert!(
        parse(&one_level)
            .err()
            .unwrap_or_default()
            .contains("2 to 8")
    );
}
