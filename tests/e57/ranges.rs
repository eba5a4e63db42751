//! Colour and intensity whose scan states no range for them: float fields without limits,
//! and limits of zero width. The crate normalises such values to zero; they are scaled by
//! their own range instead, and the convert says so.

use super::*;

/// A scan of ten points along x with the given colour and intensity fields, limits and
/// values (the point's index k gives each value), and its colour marked invalid at point
/// `invalid` where given.
fn scan_of(
    w: &mut e57::E57Writer<std::fs::File>,
    field: e57::RecordDataType,
    limits: Option<(e57::RecordValue, e57::RecordValue)>,
    value: impl Fn(usize) -> ([e57::RecordValue; 3], e57::RecordValue),
    (offset, invalid): (f64, Option<usize>),
) {
    let record = |name| e57::Record {
        name,
        data_type: field.clone(),
    };
    let mut prototype = vec![
        e57::Record::CARTESIAN_X_F64,
        e57::Record::CARTESIAN_Y_F64,
        e57::Record::CARTESIAN_Z_F64,
        record(e57::RecordName::ColorRed),
        record(e57::RecordName::ColorGreen),
        record(e57::RecordName::ColorBlue),
        record(e57::RecordName::Intensity),
    ];
    if invalid.is_some() {
        prototype.push(e57::Record {
            name: e57::RecordName::IsColorInvalid,
            data_type: e57::RecordDataType::Integer { min: 0, max: 1 },
        });
    }
    let mut pc = w.add_pointcloud("scan", prototype).expect("scan");
    // Posed, so that its points name their scanner (a Cartesian scan without a pose names none).
    pc.set_transform(Some(crate::write::pose([1.0, 0.0, 0.0, 0.0], [0.0; 3])));
    if let Some((lo, hi)) = limits {
        pc.set_color_limits(Some(e57::ColorLimits {
            red_min: Some(lo.clone()),
            red_max: Some(hi.clone()),
            green_min: Some(lo.clone()),
            green_max: Some(hi.clone()),
            blue_min: Some(lo.clone()),
            blue_max: Some(hi.clone()),
        }));
        pc.set_intensity_limits(Some(e57::IntensityLimits {
            intensity_min: Some(lo),
            intensity_max: Some(hi),
        }));
    }
    for k in 0..10 {
        let mut values: Vec<e57::RecordValue> = [k as f64 + offset, 0.0, 0.0]
            .map(e57::RecordValue::Double)
            .to_vec();
        let (rgb, intensity) = value(k);
        values.extend(rgb);
        values.push(intensity);
        if let Some(i) = invalid {
            values.push(e57::RecordValue::Integer(i64::from(k == i)));
        }
        pc.add_point(values).expect("point");
    }
    pc.finalize().expect("scan written");
}

#[test]
fn colour_and_intensity_without_a_stated_range_are_scaled_by_their_own() {
    let dir = tempfile::tempdir().expect("tempdir");
    let input = dir.path().join("ranges.e57");
    let mut w = e57::E57Writer::from_file(&input, "strata-test-ranges").expect("writer");
    // Doubles without limits: colour in 0..1, intensity in 0..255 (taken as 8 bits). Point
    // 3's colour is invalid: its intensity must not count as a colour.
    let double = e57::RecordDataType::Double {
        min: None,
        max: None,
    };
    scan_of(
        &mut w,
        double,
        None,
        |k| {
            let c = [k as f64 / 9.0, 0.5, 1.0].map(e57::RecordValue::Double);
            (c, e57::RecordValue::Double(k as f64 * 20.0))
        },
        (0.0, Some(3)),
    );
    // Bytes whose limits are 7..7: the field's type range, 0..255, stands in.
    let byte = e57::RecordDataType::Integer { min: 0, max: 255 };
    let seven = e57::RecordValue::Integer(7);
    scan_of(
        &mut w,
        byte,
        Some((seven.clone(), seven.clone())),
        |_| ([0; 3].map(|_| seven.clone()), seven.clone()),
        (100.0, None),
    );
    w.finalize().expect("file written");

    let ds = dir.path().join("ds");
    let out = run(&["convert", s(&input), "-o", s(&ds)]);
    let said = String::from_utf8_lossy(&out.stderr);
    assert!(out.status.success(), "{said}");
    assert!(
        said.contains("scan 0 of 2 states no range for its colour")
            && said.contains("scan 0 of 2 states no range for its intensity")
            && !said.contains("scan 1 of 2"),
        "{said}"
    );
    let (meta, got) = stored(&ds);
    let names: Vec<&str> = meta.attributes.iter().map(|a| a.name.as_str()).collect();
    assert_eq!(names, ["rgb", "intensity", "scanner"]);
    let mut by_x: Vec<(i64, Vec<u16>)> = got.into_iter().map(|(q, t)| (q[0], t)).collect();
    by_x.sort_unstable();
    let unit = |v: f64| (v * 65535.0).round() as u16;
    for (k, (_, tags)) in by_x.iter().enumerate() {
        // Tags: scanner, r, g, b, intensity.
        let want = if k == 3 {
            vec![0, 0, 0, 0, (k * 20 * 257) as u16]
        } else if k < 10 {
            vec![
                0,
                unit(k as f64 / 9.0),
                unit(0.5),
                65535,
                (k * 20 * 257) as u16,
            ]
        } else {
            vec![1, 7 * 257, 7 * 257, 7 * 257, 7 * 257]
        };
        assert_eq!(tags, &want, "point {k}");
    }
}
