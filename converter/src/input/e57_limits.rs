//! The ranges a scan's intensity and colour are normalised by. The `e57` crate reads a limit
//! stored as a scaled integer as its raw integer without the element's scale and offset (a
//! 0..20 limit on a 0..40 field would halve every value), and gives zero for every value of a
//! float field without limits or of limits of zero width. Here the limits are read from the
//! file's XML with their scale and offset, the field's type range stands in where they are
//! missing or empty, and where neither is a range the values are scaled by their own
//! (`from_values`).

use e57::{PointCloud, RecordDataType, RecordName};

/// A scan's ranges (minimum, maximum in real units) to normalise by; `None` where the file
/// states no usable one (then the scan's own values give it).
#[derive(Debug, Clone, Default, PartialEq)]
pub struct OwnRanges {
    pub intensity: Option<(f64, f64)>,
    pub rgb: Option<[(f64, f64); 3]>,
}

/// One `OwnRanges` per scan (`data3D` child, in order) of the file's XML; from the fields'
/// types alone where the XML cannot be read (the crate has read it already, so it can).
pub fn own_ranges(xml: &str, clouds: &[PointCloud]) -> Vec<OwnRanges> {
    let doc = roxmltree::Document::parse(xml).ok();
    let scans: Vec<roxmltree::Node> = doc
        .as_ref()
        .and_then(|d| {
            d.root_element()
                .children()
                .find(|n| n.has_tag_name("data3D"))
        })
        .map(|d| {
            d.children()
                .filter(|n| n.has_tag_name("vectorChild"))
                .collect()
        })
        .unwrap_or_default();
    clouds
        .iter()
        .enumerate()
        .map(|(i, pc)| of_scan(scans.get(i).copied(), pc))
        .collect()
}

fn of_scan(scan: Option<roxmltree::Node>, pc: &PointCloud) -> OwnRanges {
    let group = |tag: &str| scan?.children().find(|n| n.has_tag_name(tag));
    let intensity = {
        let g = group("intensityLimits");
        let (lo, hi) = (
            g.and_then(|g| limit(g, "intensityMinimum")),
            g.and_then(|g| limit(g, "intensityMaximum")),
        );
        range(lo, hi, pc, RecordName::Intensity)
    };
    let rgb = {
        let g = group("colorLimits");
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
        let stated = |tag: &str| g.and_then(|g| limit(g, tag));
        let ranges: [Option<(f64, f64)>; 3] = std::array::from_fn(|c| {
            let (lo, hi, field) = &channels[c];
            range(stated(lo), stated(hi), pc, field.clone())
        });
        // One channel without a range: all three from the values, on one scale.
        match ranges {
            [Some(r), Some(g), Some(b)] => Some([r, g, b]),
            _ => None,
        }
    };
    OwnRanges { intensity, rgb }
}

/// The limit element `tag` under `group`: a scaled integer's raw value times its scale plus
/// its offset, an integer's or a float's value.
fn limit(group: roxmltree::Node, tag: &str) -> Option<f64> {
    let n = group.children().find(|n| n.has_tag_name(tag))?;
    let text = n.text().unwrap_or("0").trim();
    let number = |name: &str, default: f64| {
        n.attribute(name)
            .map_or(Some(default), |v| v.trim().parse::<f64>().ok())
    };
    let value = match n.attribute("type")? {
        "ScaledInteger" => {
            let raw = text.parse::<i64>().ok()? as f64;
            raw * number("scale", 1.0)? + number("offset", 0.0)?
        }
        _ => text.parse::<f64>().ok()?,
    };
    value.is_finite().then_some(value)
}

/// The range from the limits, each missing one from the field's type range; the type range
/// alone where that is no range (limits of zero width); `None` where neither is.
fn range(
    lo: Option<f64>,
    hi: Option<f64>,
    pc: &PointCloud,
    field: RecordName,
) -> Option<(f64, f64)> {
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
    [
        (lo.unwrap_or(type_lo), hi.unwrap_or(type_hi)),
        (type_lo, type_hi),
    ]
    .into_iter()
    .find(|&r| is_range(r))
}

/// Bounds no sensor's values come near (a field's type range without limits, ±f32::MAX,
/// ±f64::MAX or an integer's ±2^63, says nothing) and a width above zero.
fn is_range((lo, hi): (f64, f64)) -> bool {
    const SAID: f64 = 9_007_199_254_740_992.0;
    lo.abs() < SAID && hi.abs() < SAID && hi > lo
}

/// The range of a field without one stated, from its values' least and greatest: values
/// within 0..1, 0..255 or 0..65535 are taken on that scale (the first that holds them: raw
/// 16-bit values are kept as they are), any others spread over 0..65535 by their own span.
pub fn from_values(least: f64, greatest: f64) -> (f64, f64) {
    if least >= 0.0
        && let Some(top) = [1.0, 255.0, 65535.0].into_iter().find(|&t| greatest <= t)
    {
        return (0.0, top);
    }
    if greatest > least {
        (least, greatest)
    } else {
        (least, least + 1.0)
    }
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
