//! Filters on the attributes the GPU's attribute word does not hold (GPS time, point source,
//! extra attributes), or holds only in part (`WordFit`: a float intensity, a class above 255):
//! the loader compares each point with the ranges as it converts a node and
//! sets `MARK_HIDDEN` in its attribute word; the projection hides marked points like any other
//! filtered point. A change of the ranges loads the nodes again (the GPU keeps no copy of these
//! attributes, so memory does not grow with the attributes a dataset has).

use crate::ViewerError;
use crate::pick::attribute_values;
use crate::settings::{AttributeRange, PointFilter};
use strata_format::{AttrType, NodeColumns, RowLayout};

/// The attribute-word bit of a point outside a marked range (`MARK_HIDDEN` in frame.wgsl).
pub const MARK_HIDDEN: u32 = 1 << 28;

/// The attribute-word bit of a point whose return number is above 15, which the word's four
/// bits cannot hold (`RETURN_ABOVE_15` in frame.wgsl): no return number range takes it.
pub const RETURN_ABOVE_15: u32 = 1 << 31;

/// One filter, resolved against the dataset's layout.
#[derive(Debug, Clone, PartialEq)]
pub struct Mark {
    pub attribute: usize,
    pub keep: Keep,
}

/// What a mark keeps.
#[derive(Debug, Clone, PartialEq)]
pub enum Keep {
    /// Values within, inclusive (NaN is outside).
    Range(f64, f64),
    /// Classes 0 to 255 whose bit is set (bit c of word c / 32); any other value (above 255,
    /// negative, fractional) where `beyond`.
    Classes { mask: [u32; 8], beyond: bool },
}

/// Which filters the GPU's attribute word answers exactly for a dataset's attribute types
/// (`to_gpu` packs intensity in 16 bits, the class in 8, the return number in 4 and a flag);
/// the loader's marks answer the others. A dataset without the attribute fits nowhere: its
/// filter is refused, naming the attributes there are.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct WordFit {
    pub intensity: bool,
    pub classes: bool,
    pub return_number: bool,
}

impl WordFit {
    pub fn of(layout: &RowLayout) -> WordFit {
        let held = |name: &str, types: &[AttrType]| {
            layout.index_of(name).is_some_and(|i| {
                let a = &layout.attributes[i];
                a.count == 1 && a.scale.is_none() && a.offset.is_none() && types.contains(&a.ty)
            })
        };
        WordFit {
            intensity: held("intensity", &[AttrType::U8, AttrType::U16]),
            classes: held("classification", &[AttrType::U8]),
            return_number: held(
                "return_number",
                &[AttrType::U8, AttrType::U16, AttrType::U32, AttrType::U64],
            ),
        }
    }
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
                    let names: Vec<&str> = std::iter::once("elevation")
                        .chain(
                            layout
                                .attributes
                                .iter()
                                .filter(|a| a.count == 1)
                                .map(|a| a.name.as_str()),
                        )
                        .collect();
                    ViewerError::source(
                        location,
                        format!(
                            "no attribute {:?} to filter on (there are {})",
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
                    keep: Keep::Range(r.lo, r.hi),
                })
            })
            .collect::<Result<_, _>>()
            .map(Marks)
    }

    /// The marks of `filter` on `layout`: its ranges of attributes the word does not hold, and
    /// its intensity, return number and class filters where `fit` says the word cannot answer
    /// them exactly.
    pub fn of_filter(
        layout: &RowLayout,
        filter: &PointFilter,
        fit: WordFit,
        location: &str,
    ) -> Result<Marks, ViewerError> {
        let mut ranges = filter.attributes.clone();
        let range = |name: &str, lo: f64, hi: f64| AttributeRange {
            name: name.to_owned(),
            lo,
            hi,
        };
        if let (Some((lo, hi)), false) = (filter.intensity, fit.intensity) {
            ranges.push(range("intensity", lo, hi));
        }
        if let (Some((lo, hi)), false) = (filter.return_number, fit.return_number) {
            ranges.push(range("return_number", lo.into(), hi.into()));
        }
        let mut marks = Marks::resolve(layout, &ranges, location)?;
        if let (Some(mask), false) = (filter.classes, fit.classes) {
            // A missing or many-valued class is refused as a range of it would be.
            let mut class = Marks::resolve(layout, &[range("classification", 0.0, 0.0)], location)?;
            if let Some(m) = class.0.first_mut() {
                m.keep = Keep::Classes {
                    mask,
                    beyond: filter.classes_beyond,
                };
            }
            marks.0.append(&mut class.0);
        }
        Ok(marks)
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
                let kept = match &m.keep {
                    Keep::Range(lo, hi) => v >= *lo && v <= *hi,
                    Keep::Classes { mask, beyond } => {
                        if v.fract() == 0.0 && (0.0..=255.0).contains(&v) {
                            let c = v as usize;
                            mask[c / 32] & (1 << (c % 32)) != 0
                        } else {
                            *beyond
                        }
                    }
                };
                if !kept {
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
    // Those the word holds have controls of their own (live ranges, class checkboxes).
    let fit = ds.word_fit();
    let word = [
        ("intensity", fit.intensity),
        ("classification", fit.classes),
        ("return_number", fit.return_number),
    ];
    Ok(layout
        .attributes
        .iter()
        .enumerate()
        .filter(|(_, a)| a.count == 1 && !word.contains(&(a.name.as_str(), true)))
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

    /// A 16-bit class: shown by its bit up to 255, beyond it as classes are hidden (shown)
    /// and not where some are shown alone. An 8-bit class is the word's to filter.
    #[test]
    fn classes_beyond_the_word_follow_how_the_filter_was_made() {
        let layout = RowLayout::new(vec![Attribute::new("classification", AttrType::U16, 1)]);
        // Each row: the position's three i32, then the class.
        let rows: Vec<u8> = [2u16, 258, 0, 256]
            .iter()
            .flat_map(|c| [0u8; 12].into_iter().chain(c.to_le_bytes()))
            .collect();
        let (payload, crc) = encode_node(&rows, &layout);
        let cols = strata_format::decode_node(&payload, 4, crc, &layout).expect("decodes");
        let fit = WordFit::of(&layout);
        assert!(!fit.classes && !fit.intensity && !fit.return_number);
        let words = |filter: &PointFilter| {
            Marks::of_filter(&layout, filter, fit, "ds")
                .expect("resolves")
                .words(&layout, &cols)
        };
        let mut only = PointFilter::default();
        only.set_classes(&[2], true);
        assert_eq!(words(&only), vec![0, MARK_HIDDEN, MARK_HIDDEN, MARK_HIDDEN]);
        let mut hidden = PointFilter::default();
        hidden.set_classes(&[0], false);
        hidden.set_classes(&[2], false);
        assert_eq!(words(&hidden), vec![MARK_HIDDEN, 0, MARK_HIDDEN, 0]);
        let byte = RowLayout::new(vec![Attribute::new("classification", AttrType::U8, 1)]);
        assert!(WordFit::of(&byte).classes);
        assert!(
            Marks::of_filter(&byte, &only, WordFit::of(&byte), "ds")
                .expect("ok")
                .is_empty()
        );
    }
}
