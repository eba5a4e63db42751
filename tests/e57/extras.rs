//! Return index and count and time stamps, which the crate's simple reader does not give:
//! they are kept as `return_number`, `number_of_returns` and `gps_time`.

use super::*;

/// Per stored point, by x: (scanner, return number, number of returns, time).
fn extras_by_x(ds: &Path) -> Vec<(i32, u16, u8, u8, f64)> {
    let d = LocalDataset::open(ds).expect("dataset opens");
    let layout = d.layout().clone();
    let at = |name: &str| {
        let i = layout.index_of(name).expect(name);
        layout.offsets[i]
    };
    let (scanner, number, count, time) = (
        at("scanner"),
        at("return_number"),
        at("number_of_returns"),
        at("gps_time"),
    );
    let mut out = Vec::new();
    for node in d.all_nodes().expect("nodes") {
        let rows = d.read_node(&node).expect("node").to_rows(&layout);
        for r in rows.chunks_exact(layout.stride) {
            let word = |o: usize, n: usize| r[o..o + n].to_vec();
            out.push((
                i32::from_le_bytes(word(0, 4).try_into().expect("x")),
                u16::from_le_bytes(word(scanner, 2).try_into().expect("scanner")),
                r[number],
                r[count],
                f64::from_le_bytes(word(time, 8).try_into().expect("time")),
            ));
        }
    }
    out.sort_by_key(|p| p.0);
    out
}

#[test]
fn return_numbers_and_time_stamps_are_kept() {
    let dir = tempfile::tempdir().expect("tempdir");
    let input = dir.path().join("extras.e57");
    let mut w = e57::E57Writer::from_file(&input, "strata-test-extras").expect("writer");
    let mut prototype = vec![
        e57::Record::CARTESIAN_X_F64,
        e57::Record::CARTESIAN_Y_F64,
        e57::Record::CARTESIAN_Z_F64,
    ];
    prototype.extend(
        [
            (e57::RecordName::ReturnIndex, 0, 3),
            (e57::RecordName::ReturnCount, 0, 4),
            (e57::RecordName::IsTimeStampInvalid, 0, 1),
        ]
        .map(|(name, min, max)| e57::Record {
            name,
            data_type: e57::RecordDataType::Integer { min, max },
        }),
    );
    prototype.push(e57::Record {
        name: e57::RecordName::TimeStamp,
        data_type: e57::RecordDataType::Double {
            min: None,
            max: None,
        },
    });
    let mut pc = w.add_pointcloud("timed", prototype).expect("scan");
    // Posed, so that its points name their scanner (a Cartesian scan without a pose names none).
    pc.set_transform(Some(crate::write::pose([1.0, 0.0, 0.0, 0.0], [0.0; 3])));
    pc.set_acquisition_start(Some(e57::DateTime {
        gps_time: 1.3e9,
        atomic_reference: true,
    }));
    for k in 0..8i64 {
        let mut values: Vec<e57::RecordValue> =
            [k as f64, 0.0, 0.0].map(e57::RecordValue::Double).to_vec();
        values.extend([k % 3, 2, i64::from(k == 5)].map(e57::RecordValue::Integer));
        values.push(e57::RecordValue::Double(0.25 * k as f64));
        pc.add_point(values).expect("point");
    }
    pc.finalize().expect("scan written");
    // A scan with none of the fields: single returns, time 0.
    let mut pc = w
        .add_pointcloud(
            "plain",
            vec![
                e57::Record::CARTESIAN_X_F64,
                e57::Record::CARTESIAN_Y_F64,
                e57::Record::CARTESIAN_Z_F64,
            ],
        )
        .expect("scan");
    pc.set_transform(Some(crate::write::pose([1.0, 0.0, 0.0, 0.0], [0.0; 3])));
    pc.add_point([100.0, 0.0, 0.0].map(e57::RecordValue::Double).to_vec())
        .expect("point");
    pc.finalize().expect("scan written");
    w.finalize().expect("file written");

    let ds = convert(dir.path(), &[&input]);
    let (meta, _) = stored(&ds);
    let time = meta
        .attributes
        .iter()
        .find(|a| a.name == "gps_time")
        .expect("gps_time");
    assert_eq!(
        time.time_base,
        Some(strata_format::TimeBase::GpsAdjustedStandard)
    );
    let got = extras_by_x(&ds);
    assert_eq!(got.len(), 9);
    for (k, &(_, scanner, number, count, t)) in got.iter().enumerate() {
        let want = if k < 8 {
            // Index k % 3 of 3 returns (the count is raised to the index where it is
            // smaller); 0.3e9 + 0.25 k seconds of adjusted standard time, 0 where invalid.
            let time = if k == 5 { 0.0 } else { 0.3e9 + 0.25 * k as f64 };
            (0, (k % 3 + 1) as u8, 2.max((k % 3 + 1) as u8), time)
        } else {
            (1, 1, 1, 0.0)
        };
        assert_eq!((scanner, number, count, t), want, "point {k}");
    }
}

/// Time stamps from an unknown start (no acquisitionStart) beside a LAS's adjusted standard
/// GPS time are refused: the dataset said adjusted standard time for all of them.
#[test]
fn stamps_from_an_unknown_start_do_not_join_times_of_a_base() {
    let dir = tempfile::tempdir().expect("tempdir");
    let e57_path = dir.path().join("relative.e57");
    let mut w = e57::E57Writer::from_file(&e57_path, "strata-test-relative").expect("writer");
    let prototype = vec![
        e57::Record::CARTESIAN_X_F64,
        e57::Record::CARTESIAN_Y_F64,
        e57::Record::CARTESIAN_Z_F64,
        e57::Record {
            name: e57::RecordName::TimeStamp,
            data_type: e57::RecordDataType::Double {
                min: None,
                max: None,
            },
        },
    ];
    let mut pc = w.add_pointcloud("untimed", prototype).expect("scan");
    for k in 0..4 {
        let values = [k as f64, 0.0, 0.0, 0.5 * k as f64].map(e57::RecordValue::Double);
        pc.add_point(values.to_vec()).expect("point");
    }
    pc.finalize().expect("scan written");
    w.finalize().expect("file written");
    let las_path = dir.path().join("adjusted.las");
    let mut builder = las::Builder::from((1, 4));
    builder.point_format = las::point::Format::new(1).expect("format");
    builder.gps_time_type = las::GpsTimeType::Standard;
    let mut writer =
        las::Writer::from_path(&las_path, builder.into_header().expect("header")).expect("LAS");
    let point = las::Point {
        gps_time: Some(3.1e8),
        return_number: 1,
        number_of_returns: 1,
        ..Default::default()
    };
    writer.write_point(point).expect("point");
    writer.close().expect("close");
    // A PLY's time of no stated base, first, does not let the base in after the E57.
    let ply_path = dir.path().join("untold.ply");
    let ply = "ply\nformat ascii 1.0\nelement vertex 1\nproperty float x\nproperty float y\nproperty float z\nproperty double gps_time\nend_header\n9 0 0 1.5\n";
    std::fs::write(&ply_path, ply).expect("write PLY");
    let orders: [&[&std::path::Path]; 3] = [
        &[&e57_path, &las_path],
        &[&las_path, &e57_path],
        &[&ply_path, &e57_path, &las_path],
    ];
    for inputs in orders {
        let out = dir.path().join("mixed");
        let mut args = vec!["convert"];
        args.extend(inputs.iter().map(|p| common::s(p)));
        args.extend(["-o", common::s(&out)]);
        common::refused(&args, &["unknown start", "adjusted standard GPS time"]);
        assert!(!out.exists());
    }
}
