//! Intensity and colour limits stored as scaled integers. The `e57` crate reads such a limit
//! as its raw integer without the element's scale and offset, cannot use it, and normalises
//! by the field's type range instead (a 0..20 limit on a 0..40 field halves every value). Here
//! the limits are read from the file's XML with their scale and offset, and where one is a
//! scaled integer the scan's values are normalised by them.

use e57::{PointCloud, RecordDataType, RecordName};

/// A scan's ranges (minimum, maximum in real units) for Strata to normalise by, where the
/// crate cannot: `None` where the crate's own normalisation is right.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct OwnRanges {
    pub intensity: Option<(f64, f64)>,
    pub rgb: Option<[(f64, f64); 3]>,
}

/// One `OwnRanges` per scan (`data3D` child, in order) of the file's XML; the default for all
/// where the XML cannot be read (the crate has read it already, so it can).
pub fn own_ranges(xml: &str, clouds: &[PointCloud]) -> Vec<OwnRanges> {
    let Ok(doc) = roxmltree::Document::parse(xml) else {
        return vec![OwnRanges::default(); clouds.len()];
    };
    let scans: Vec<roxmltree::Node> = doc
        .root_element()
        .children()
        .find(|n| n.has_tag_name("data3D"))
        .map(|d| {
            d.children()
                .filter(|n| n.has_tag_name("vectorChild"))
                .collect()
        })
        .unwrap_or_default();
    clouds
        .iter()
        .enumerate()
        .map(|(i, pc)| {
            scans
                .get(i)
                .map_or_else(OwnRanges::default, |s| of_scan(*s, pc))
        })
        .collect()
}

fn of_scan(scan: roxmltree::Node, pc: &PointCloud) -> OwnRanges {
    let group = |tag: &str| scan.children().find(|n| n.has_tag_name(tag));
    let intensity = group("intensityLimits").and_then(|g| {
        let (lo, hi) = (limit(g, "intensityMinimum"), limit(g, "intensityMaximum"));
        scaled(&[lo, hi]).then(|| range(lo, hi, pc, RecordName::Intensity))
    });
    let rgb = group("colorLimits").and_then(|g| {
        let channels = [
            ("colorRedMinimum", "colorRedMaximum", RecordName::ColorRed),
            (
                "colorGreenMinimum",
                "colorGreenMaximum",
                RecordName::ColorGreen,
            ),
            (
                "colorBlueMinimum",
                "colorBlueMaximum",
                RecordName::ColorBlue,
            ),
        ];
        let limits: [(Option<Limit>, Option<Limit>); 3] =
            std::array::from_fn(|c| (limit(g, channels[c].0), limit(g, channels[c].1)));
        let all: Vec<Option<Limit>> = limits.iter().flat_map(|&(lo, hi)| [lo, hi]).collect();
        scaled(&all).then(|| {
            std::array::from_fn(|c| range(limits[c].0, limits[c].1, pc, channels[c].2.clone()))
        })
    });
    OwnRanges { intensity, rgb }
}

/// A limit's real value, and whether it was a scaled integer.
type Limit = (f64, bool);

fn scaled(limits: &[Option<Limit>]) -> bool {
    limits.iter().flatten().any(|l| l.1)
}

/// The limit element `tag` under `group`: a scaled integer's raw value times its scale plus
/// its offset, an integer's or a float's value.
fn limit(group: roxmltree::Node, tag: &str) -> Option<Limit> {
    let n = group.children().find(|n| n.has_tag_name(tag))?;
    let text = n.text().unwrap_or("0").trim();
    let number = |name: &str, default: f64| {
        n.attribute(name)
            .map_or(Some(default), |v| v.trim().parse::<f64>().ok())
    };
    let (value, is_scaled) = match n.attribute("type")? {
        "ScaledInteger" => {
            let raw = text.parse::<i64>().ok()? as f64;
            (raw * number("scale", 1.0)? + number("offset", 0.0)?, true)
        }
        _ => (text.parse::<f64>().ok()?, false),
    };
    value.is_finite().then_some((value, is_scaled))
}

/// The range from the limits, each missing one from the field's type range, as the crate
/// falls back to.
fn range(lo: Option<Limit>, hi: Option<Limit>, pc: &PointCloud, field: RecordName) -> (f64, f64) {
    let (type_lo, type_hi) =
        pc.prototype
            .iter()
            .find(|r| r.name == field)
            .map_or((0.0, 1.0), |r| match r.data_type {
                RecordDataType::ScaledInteger {
                    min,
                    max,
                    scale,
                    offset,
                } => (min as f64 * scale + offset, max as f64 * scale + offset),
                RecordDataType::Integer { min, max } => (min as f64, max as f64),
                RecordDataType::Single { min, max } => (
                    min.map_or(f64::from(f32::MIN), f64::from),
                    max.map_or(f64::from(f32::MAX), f64::from),
                ),
                RecordDataType::Double { min, max } => {
                    (min.unwrap_or(f64::MIN), max.unwrap_or(f64::MAX))
                }
            });
    (lo.map_or(type_lo, |l| l.0), hi.map_or(type_hi, |h| h.0))
}

/// `v` (real units) as 0..1 of `range`; 0 where the range is empty.
#[inline]
pub fn normalised(v: f32, (lo, hi): (f64, f64)) -> f32 {
    let width = hi - lo;
    if width > 0.0 {
        ((f64::from(v) - lo) / width) as f32
    } else {
        0.0
    }
}
