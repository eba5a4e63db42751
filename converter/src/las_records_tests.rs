//! A dataset's rows as LAS records: conversions between types and point format families, and
//! the values LAS cannot hold refused.

use super::*;

#[test]
fn descriptions_are_cut_between_characters() {
    let long = "surface variation λ0 / (λ0 + λ1 + λ2)";
    let cut = text_prefix(long, 32);
    assert!(cut.len() <= 32 && long.starts_with(cut), "{cut:?}");
    assert_eq!(
        text_prefix(long, 19),
        "surface variation ",
        "λ takes bytes 18 and 19"
    );
    assert_eq!(text_prefix("intensity", 32), "intensity");
}

#[test]
fn a_field_of_another_type_is_converted_or_refused_beyond_its_range_or_as_a_fraction() {
    // A PLY's f32 intensity into LAS's u16 field; a u16 classification into the u8 one; a
    // u16 return number into format 6's four bits.
    let layout = RowLayout::new(vec![
        Attribute::new("intensity", AttrType::F32, 1),
        Attribute::new("classification", AttrType::U16, 1),
        Attribute::new("return_number", AttrType::U16, 1),
    ]);
    let plan = LasRecords::new(Path::new("x.las"), &layout, 6).expect("plan");
    let row = |i: f32, c: u16, r: u16| {
        let mut row = vec![0u8; 12];
        row.extend(i.to_le_bytes());
        row.extend(c.to_le_bytes());
        row.extend(r.to_le_bytes());
        row
    };
    let fits = row(1234.0, 255, 15);
    assert!(plan.check_fits(Path::new("x.las"), &fits).is_ok());
    let mut recs = Vec::new();
    plan.fill(&fits, &mut recs);
    assert_eq!(u16::from_le_bytes([recs[12], recs[13]]), 1234);
    assert_eq!(recs[14] & 0xF, 15, "return number");
    assert_eq!(recs[16], 255, "classification");
    for (bad, said) in [
        (
            row(-5.0, 2, 1),
            "intensity is -5, outside what LAS's field holds (0 to 65535)",
        ),
        (row(1e9, 2, 1), "intensity is 1000000000, outside"),
        (row(f32::NAN, 2, 1), "intensity is NaN, outside"),
        (row(f32::INFINITY, 2, 1), "intensity is inf, outside"),
        // A fraction is not rounded away: the field holds whole numbers.
        (
            row(0.25, 2, 1),
            "intensity is 0.25, not a whole number, and LAS's field holds whole numbers only",
        ),
        (row(1234.6, 2, 1), "intensity is 1234.6, not a whole number"),
        (
            row(1.0, 300, 1),
            "classification is 300, outside what LAS's field holds (0 to 255)",
        ),
        (
            row(1.0, 2, 20),
            "return_number is 20, outside what LAS point format 6 holds (0 to 15)",
        ),
    ] {
        refuses(&plan, &bad, said);
    }
}

/// `plan` refuses `row`, saying `said`.
fn refuses(plan: &LasRecords, row: &[u8], said: &str) {
    let err = plan
        .check_fits(Path::new("x.las"), row)
        .expect_err(said)
        .to_string();
    assert!(err.contains(said), "{err}");
}

/// A scan angle is written where LAS defines one (±30000 steps of 0.006°), and a scanner
/// channel where format 6 has bits for it (0 to 3): beyond, refused, not cut or wrapped
/// (an extra-bytes `scanner_channel` of a format-1 file held 0 to 255).
#[test]
fn a_scan_angle_or_channel_beyond_las_is_refused() {
    let layout = RowLayout::new(vec![
        Attribute::new("scan_angle", AttrType::I16, 1),
        Attribute::new("scanner_channel", AttrType::U8, 1),
    ]);
    let plan = LasRecords::new(Path::new("x.las"), &layout, 6).expect("plan");
    let row = |angle: i16, channel: u8| {
        let mut row = vec![0u8; 12];
        row.extend(angle.to_le_bytes());
        row.push(channel);
        row
    };
    for ok in [row(-30000, 0), row(30000, 3)] {
        assert!(plan.check_fits(Path::new("x.las"), &ok).is_ok());
    }
    for (bad, said) in [
        (
            row(32190, 0),
            "scan_angle is 32190, outside what LAS's field holds",
        ),
        (
            row(0, 4),
            "scanner_channel is 4, outside what LAS point format 6 holds (0 to 3)",
        ),
    ] {
        refuses(&plan, &bad, said);
    }
}

#[test]
fn a_rank_of_any_type_becomes_the_scan_angle_or_is_refused() {
    // A PLY's float scan_angle_rank into format 6's scan_angle (0.006° steps): read as
    // the float it is, not as its first byte.
    let layout = RowLayout::new(vec![Attribute::new("scan_angle_rank", AttrType::F32, 1)]);
    let plan = LasRecords::new(Path::new("x.las"), &layout, 6).expect("plan");
    let row = |deg: f32| {
        let mut row = vec![0u8; 12];
        row.extend(deg.to_le_bytes());
        row
    };
    for (deg, steps) in [
        (-12.5f32, -2083i16),
        (90.0, 15000),
        (0.0, 0),
        (-180.0, -30000),
    ] {
        let r = row(deg);
        assert!(plan.check_fits(Path::new("x.las"), &r).is_ok(), "{deg}");
        let mut recs = Vec::new();
        plan.fill(&r, &mut recs);
        assert_eq!(i16::from_le_bytes([recs[18], recs[19]]), steps, "{deg}°");
    }
    for bad in [200.0f32, f32::NAN] {
        let err = plan
            .check_fits(Path::new("x.las"), &row(bad))
            .expect_err("refused")
            .to_string();
        assert!(err.contains("scan_angle_rank is"), "{err}");
    }
}
