//! Filters on the attributes the GPU's attribute word does not hold (GPS time, point source,
//! extra attributes): the loader compares each point with the ranges as it converts a node and
//! sets `MARK_HIDDEN` in its attribute word; the projection hides marked points like any other
//! filtered point. A change of the ranges loads the nodes again (the GPU keeps no copy of these
//! attributes, so memory does not grow with the attributes a dataset has).

use crate::ViewerError;
use crate::pick::attribute_values;
use crate::settings::AttributeRange;
use strata_format::{NodeColumns, RowLayout};

/// The attribute-word bit of a point outside a marked range (`MARK_HIDDEN` in frame.wgsl).
pub const MARK_HIDDEN: u32 = 1 << 28;

/// One range, resolved against the dataset's layout.
#[derive(Debug, Clone, PartialEq)]
pub struct Mark {
    pub attribute: usize,
    pub lo: f64,
    pub hi: f64,
}

/// The ranges nodes are loaded with.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct Marks(pub Vec<Mark>);

impl Marks {
    /// The ranges of `ranges` on the attributes of `layout`; an attribute the dataset lacks or
    /// one of several components is refused, naming the ones there are.
    pub fn resolve(
        layout: &RowLayout,
        ranges: &[AttributeRange],
        location: &str,
    ) -> Result<Marks, ViewerError> {
        ranges
            .iter()
            .map(|r| {
                let i = layout.index_of(&r.name).ok_or_else(|| {
                    let names: Vec<&str> = layout
                        .attributes
                        .iter()
                        .filter(|a| a.count == 1)
                        .map(|a| a.name.as_str())
                        .collect();
                    ViewerError::source(
                        location,
                        format!(
                            "no attribute {:?} to filter on (there are elevation, {})",
                            r.name,
                            names.join(", ")
                        ),
                    )
                })?;
                let a = &layout.attributes[i];
                if a.count != 1 {
                    return Err(ViewerError::source(
                        location,
                        format!(
                            "attribute {:?} has {} components; a range filters a one-valued attribute",
                            r.name, a.count
                        ),
                    ));
                }
                Ok(Mark {
                    attribute: i,
                    lo: r.lo,
                    hi: r.hi,
                })
            })
            .collect::<Result<_, _>>()
            .map(Marks)
    }

    pub fn is_empty(&self) -> bool {
        self.0.is_empty()
    }

    /// Per point of `cols`, `MARK_HIDDEN` where it lies outside a range (a NaN lies outside
    /// every range), else 0.
    pub fn words(&self, layout: &RowLayout, cols: &NodeColumns) -> Vec<u32> {
        let mut out = vec![0u32; cols.count];
        for m in &self.0 {
            let a = &layout.attributes[m.attribute];
            let column = cols.attribute(layout, m.attribute);
            for (p, raw) in column.chunks_exact(a.size()).enumerate() {
                let v = attribute_values(a, raw)
                    .first()
                    .copied()
                    .unwrap_or(f64::NAN);
                if !(v >= m.lo && v <= m.hi) {
                    out[p] = MARK_HIDDEN;
                }
            }
        }
        out
    }
}

/// The one-valued attributes a range may be set on beyond those of the attribute word, and
/// the range of each over the root node's points (a sample of the whole), for the panel.
pub fn attribute_ranges(ds: &crate::StreamDataset) -> Result<Vec<(String, f64, f64)>, ViewerError> {
    let layout = ds.metadata().row_layout();
    let root = ds.root_hierarchy_page().root_node();
    let cols = match root {
        Some(info) if info.point_count > 0 => Some(ds.read_columns(&info)?),
        _ => None,
    };
    let word = ["intensity", "classification", "return_number"];
    Ok(layout
        .attributes
        .iter()
        .enumerate()
        .filter(|(_, a)| a.count == 1 && !word.contains(&a.name.as_str()))
        .map(|(i, a)| {
            let (lo, hi) = cols.as_ref().map_or((0.0, 1.0), |c| {
                c.attribute(&layout, i)
                    .chunks_exact(a.size())
                    .filter_map(|raw| attribute_values(a, raw).first().copied())
                    .filter(|v| v.is_finite())
                    .fold((f64::INFINITY, f64::NEG_INFINITY), |(l, h), v| {
                        (l.min(v), h.max(v))
                    })
            });
            let (lo, hi) = if lo <= hi { (lo, hi) } else { (0.0, 1.0) };
            (a.name.clone(), lo, hi)
        })
        .collect())
}

#[cfg(test)]
mod tests {
    use super::*;
    use strata_format::{AttrType, Attribute, encode_node};

    #[test]
    fn points_outside_a_range_are_marked_and_unknown_attributes_refused() {
        let layout = RowLayout::new(vec![
            Attribute::new("gps_time", AttrType::F64, 1),
            Attribute::new("rgb", AttrType::U16, 3),
        ]);
        let mut rows = Vec::new();
        for t in [10.0f64, 20.0, 30.0, f64::NAN] {
            rows.extend([0u8; 12]);
            rows.extend(t.to_le_bytes());
            rows.extend([0u8; 6]);
        }
        let (payload, crc) = encode_node(&rows, &layout);
        let cols = strata_format::decode_node(&payload, 4, crc, &layout).expect("decodes");
        let range = |name: &str, lo, hi| AttributeRange {
            name: name.into(),
            lo,
            hi,
        };
        let marks = Marks::resolve(&layout, &[range("gps_time", 15.0, 30.0)], "ds").expect("ok");
        assert_eq!(
            marks.words(&layout, &cols),
            vec![MARK_HIDDEN, 0, 0, MARK_HIDDEN]
        );
        let e = Marks::resolve(&layout, &[range("gps", 0.0, 1.0)], "ds").expect_err("unknown");
        assert!(e.to_string().contains("gps_time"), "{e}");
        let e = Marks::resolve(&layout, &[range("rgb", 0.0, 1.0)], "ds").expect_err("vector");
        assert!(e.to_string().contains("3 components"), "{e}");
    }
}
