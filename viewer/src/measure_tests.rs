//! Tests of measure.rs: what each kind measures, names, GeoJSON round trips.

use super::*;

fn m(kind: MeasureKind, points: &[[f64; 3]]) -> Measurement {
    Measurement {
        kind,
        name: kind.name().into(),
        points: points.to_vec(),
        source: None,
    }
}

const O: [f64; 3] = [500_000.0, 4_600_000.0, 100.0];

#[test]
fn a_polygon_that_crosses_itself_is_said() {
    // A bowtie seen from above (the crossing itself: polygon.rs).
    let bowtie = m(
        MeasureKind::Area,
        &[
            at(0.0, 0.0, 0.0),
            at(2.0, 2.0, 0.0),
            at(2.0, 0.0, 0.0),
            at(0.0, 2.0, 0.0),
        ],
    );
    assert_eq!(bowtie.crossing_edges(), Some((1, 3)));
    assert!(
        bowtie
            .lines(0.001)
            .iter()
            .any(|l| l.contains("crosses itself"))
    );
    let path = m(MeasureKind::Distance, &bowtie.points);
    assert_eq!(path.crossing_edges(), None, "a distance has no area");
    // The GeoJSON says it too, and a crossing undone is not kept from the file it was read from.
    let feature = bowtie.to_feature();
    assert_eq!(
        feature["properties"]["crossing_edges"],
        serde_json::json!([1, 3])
    );
    let mut square = bowtie.clone();
    square.points.swap(1, 2);
    square.source = Some(feature);
    assert_eq!(square.crossing_edges(), None);
    assert!(
        square.to_feature()["properties"]
            .get("crossing_edges")
            .is_none()
    );
}

#[test]
fn a_default_name_is_never_one_already_given() {
    let mut all = Measurements {
        items: Vec::new(),
        members: Default::default(),
    };
    assert_eq!(all.next_name(MeasureKind::Distance), "distance 1");
    let mut given = m(MeasureKind::Distance, &[O, O]);
    given.name = "distance 2".into();
    all.items.push(given);
    // One distance: "distance 2" would be next, and is taken.
    assert_eq!(all.next_name(MeasureKind::Distance), "distance 3");
    assert_eq!(all.next_name(MeasureKind::Height), "height 1");
}

fn at(x: f64, y: f64, z: f64) -> [f64; 3] {
    [O[0] + x, O[1] + y, O[2] + z]
}

#[test]
fn each_kind_measures_what_geometry_says() {
    let d = m(
        MeasureKind::Distance,
        &[at(0.0, 0.0, 0.0), at(3.0, 4.0, 0.0), at(3.0, 4.0, 12.0)],
    );
    assert_eq!(d.segment_lengths(), vec![5.0, 12.0]);
    let v: std::collections::HashMap<_, _> = d.values().into_iter().collect();
    assert_eq!(v["total_length"], 17.0);
    assert_eq!(v["height_difference"], 12.0);
    assert_eq!(v["horizontal_distance"], 5.0);

    // A 10 x 10 square tilted 60 degrees: 100 in 3D, 50 seen from above, even far from
    // the origin.
    let (c, s) = (0.5f64, 3f64.sqrt() / 2.0);
    let a = m(
        MeasureKind::Area,
        &[
            at(0.0, 0.0, 0.0),
            at(10.0, 0.0, 0.0),
            at(10.0, 10.0 * c, 10.0 * s),
            at(0.0, 10.0 * c, 10.0 * s),
        ],
    );
    assert!((a.area_3d() - 100.0).abs() < 1e-6, "{}", a.area_3d());
    assert!((a.horizontal_area() - 50.0).abs() < 1e-6);
    assert!((a.segment_lengths().iter().sum::<f64>() - 40.0).abs() < 1e-6);

    let h = m(
        MeasureKind::Height,
        &[at(0.0, 0.0, 2.0), at(6.0, 8.0, -1.0)],
    );
    let v: std::collections::HashMap<_, _> = h.values().into_iter().collect();
    assert_eq!(v["height"], -3.0);
    assert_eq!(v["horizontal_distance"], 10.0);

    let g = m(
        MeasureKind::Angle,
        &[at(1.0, 0.0, 0.0), at(0.0, 0.0, 0.0), at(1.0, 1.0, 0.0)],
    );
    assert!((g.angle_deg().unwrap() - 45.0).abs() < 1e-9);
    let straight = m(
        MeasureKind::Angle,
        &[at(-1.0, 0.0, 0.0), at(0.0, 0.0, 0.0), at(1.0, 0.0, 0.0)],
    );
    assert!((straight.angle_deg().unwrap() - 180.0).abs() < 1e-9);
    assert!(!m(MeasureKind::Height, &[at(0.0, 0.0, 0.0)]).is_complete());
    assert!(!m(MeasureKind::Angle, &[O, O, O, O]).is_complete());
}

#[test]
fn measurements_survive_geojson_and_bad_files_are_named() {
    let all = Measurements {
        items: vec![
            m(
                MeasureKind::Distance,
                &[at(0.0, 0.0, 0.0), at(1.5, 0.0, 0.0)],
            ),
            m(
                MeasureKind::Area,
                &[at(0.0, 0.0, 0.0), at(1.0, 0.0, 0.0), at(0.0, 1.0, 0.0)],
            ),
            m(MeasureKind::Height, &[at(0.0, 0.0, 0.0), at(0.0, 0.0, 3.0)]),
            m(
                MeasureKind::Angle,
                &[at(1.0, 0.0, 0.0), O, at(0.0, 1.0, 0.0)],
            ),
        ],
        ..Measurements::default()
    };
    let dir = tempfile::tempdir().expect("tempdir");
    let path = dir.path().join(FILE_NAME);
    all.save(&path).expect("saved");
    let text = std::fs::read_to_string(&path).expect("read");
    let json: Value = serde_json::from_str(&text).expect("json");
    // The polygon's ring is closed, as GeoJSON wants; the properties carry the results.
    assert_eq!(
        json["features"][1]["geometry"]["coordinates"][0][3],
        json!(at(0.0, 0.0, 0.0))
    );
    assert_eq!(
        json["features"][0]["properties"]["total_length"],
        json!(1.5)
    );
    let back = Measurements::load(&path).expect("loads");
    let plain = |a: &Measurements| -> Vec<(MeasureKind, String, Vec<[f64; 3]>)> {
        a.items
            .iter()
            .map(|m| (m.kind, m.name.clone(), m.points.clone()))
            .collect()
    };
    assert_eq!(plain(&back), plain(&all));
    // What a GIS put in the file is written back as it was, beside a new measurement.
    let gis = r#"{"type":"FeatureCollection","name":"survey","crs":{"type":"name","properties":{"name":"EPSG:2992"}},"features":[{"type":"Feature","id":7,"geometry":{"type":"LineString","coordinates":[[0,0,0],[3,4,0]]},"properties":{"owner":"bob","name":"fence"}}]}"#;
    let mut read = Measurements::from_geojson(gis, "gis.geojson").expect("reads");
    read.items
        .push(m(MeasureKind::Height, &[O, at(0.0, 0.0, 2.0)]));
    let out = read.to_geojson();
    let before: Value = serde_json::from_str(gis).expect("json");
    assert_eq!(out["name"], before["name"]);
    assert_eq!(out["crs"], before["crs"]);
    assert_eq!(out["features"][0]["id"], json!(7));
    assert_eq!(out["features"][0]["properties"]["owner"], json!("bob"));
    assert_eq!(out["features"][0]["properties"]["name"], json!("fence"));
    assert_eq!(out["features"][0]["properties"]["total_length"], json!(5.0));
    assert_eq!(out["features"][1]["properties"]["height"], json!(2.0));
    // A GIS's LineString without our properties is a distance.
    let plain = r#"{"type":"Feature","geometry":{"type":"LineString","coordinates":[[0,0],[3,4]]},"properties":null}"#;
    let p = Measurements::from_geojson(plain, "plain.geojson").expect("reads");
    assert_eq!(p.items[0].values()[0], ("total_length", 5.0));
    for (bad, says) in [
        ("{", "not JSON"),
        (r#"{"type":"Point"}"#, "FeatureCollection"),
        (
            r#"{"type":"FeatureCollection","features":[{"type":"Feature","geometry":{"type":"Point","coordinates":[0,0]}}]}"#,
            "feature 0: a Point",
        ),
        (
            r#"{"type":"Feature","geometry":{"type":"LineString","coordinates":[[0,0,0]]},"properties":{"measure":"height"}}"#,
            "a height needs 2 points, it has 1",
        ),
        (
            r#"{"type":"Feature","geometry":{"type":"LineString","coordinates":[[0,"a"],[1,1]]}}"#,
            "numbers",
        ),
    ] {
        let e = Measurements::from_geojson(bad, "m.geojson").expect_err(bad);
        let e = e.to_string();
        assert!(e.contains("m.geojson") && e.contains(says), "{bad}: {e}");
    }
}

#[test]
fn values_print_to_the_decimals_of_the_coordinates() {
    // A scan in degrees (step 1e-7): 3 decimals printed every length of it as 0.000.
    let deg = m(
        MeasureKind::Distance,
        &[[11.0, 48.0, 300.0], [11.0000123, 48.0, 300.0]],
    );
    let lines = deg.lines(1e-7);
    assert!(
        lines.contains(&"  total length 0.0000123".to_string()),
        "{lines:?}"
    );
    // Millimetres, and an area to square millimetres.
    let mm = m(MeasureKind::Height, &[O, at(3.0, 4.0, 1.25)]);
    assert!(mm.lines(0.001).contains(&"  distance 5.154".to_string()));
    let square = m(
        MeasureKind::Area,
        &[O, at(1.0, 0.0, 0.0), at(1.0, 0.5, 0.0), at(0.0, 0.5, 0.0)],
    );
    let lines = square.lines(0.01);
    assert!(
        lines.contains(&"  horizontal area 0.5000".to_string()),
        "{lines:?}"
    );
    assert!(lines.contains(&"  perimeter 3.00".to_string()), "{lines:?}");
    // A step of no power of ten, and none at all.
    assert_eq!(strata_format::step_decimals(0.25), 2);
    assert_eq!(strata_format::step_decimals(0.1), 1);
    assert_eq!(strata_format::step_decimals(0.0), 3);
    assert_eq!(value_decimals("angle_deg", 1e-7), 3);
}
