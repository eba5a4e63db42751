//! LAS extra bytes that hold a normal: three scalar floats named like its components are read
//! as one `normal` attribute (as PLY's `nx ny nz` are), and `strata export` writes a normal as
//! three such fields.

use super::las_layout::ExtraBytesField;
use strata_format::Attribute;

/// Whether `name` is one of [`NORMAL_FIELD_NAMES`] (case-insensitive).
pub fn is_normal_component(name: &str) -> bool {
    NORMAL_FIELD_NAMES
        .iter()
        .flatten()
        .any(|n| name.eq_ignore_ascii_case(n))
}

/// Names of a normal's components as extra-bytes fields, compared case-insensitively:
/// `nx ny nz` (PLY's), `normal_x ...`, and `NormalX ...` (PDAL's dimension names, which
/// `strata export` writes).
pub const NORMAL_FIELD_NAMES: [[&str; 3]; 3] = [
    ["nx", "ny", "nz"],
    ["normal_x", "normal_y", "normal_z"],
    ["normalx", "normaly", "normalz"],
];

/// The names `strata export` gives a normal's three extra-bytes fields.
pub const EXPORT_NORMAL_NAMES: [&str; 3] = ["NormalX", "NormalY", "NormalZ"];

/// Three extra-bytes fields that are one normal, and the attribute they make.
pub(super) struct NormalGroup {
    /// Indices into the extra fields of the x, y and z components.
    pub fields: [usize; 3],
    pub attribute: Attribute,
}

/// The first set of [`NORMAL_FIELD_NAMES`] that the fields hold, each name once, as scalar
/// floats of one type without scale or offset; none when a field is already called `normal`.
pub(super) fn normal_group(extra: &[ExtraBytesField]) -> Option<NormalGroup> {
    if extra.iter().any(|e| e.attribute.name == "normal") {
        return None;
    }
    NORMAL_FIELD_NAMES.iter().find_map(|names| {
        let fields = names.map(|n| {
            let mut found = extra
                .iter()
                .enumerate()
                .filter(|(_, e)| e.attribute.name.eq_ignore_ascii_case(n));
            match (found.next(), found.next()) {
                (Some((i, _)), None) => Some(i),
                _ => None,
            }
        });
        let [Some(x), Some(y), Some(z)] = fields else {
            return None;
        };
        let at = |i: usize| &extra[i].attribute;
        let ty = at(x).ty;
        let plain = |i: usize| {
            let a = at(i);
            a.count == 1 && a.ty == ty && a.scale.is_none() && a.offset.is_none()
        };
        (ty.is_float() && [x, y, z].into_iter().all(plain)).then(|| NormalGroup {
            fields: [x, y, z],
            attribute: Attribute::new("normal", ty, 3),
        })
    })
}

#[cfg(test)]
mod tests {
    use super::super::las_layout::{las_fields, record_to_row, row_to_record};
    use super::*;
    use strata_format::AttrType;

    #[test]
    fn extra_bytes_named_like_a_normal_become_one_normal() {
        let f = |n: &str, t: AttrType| ExtraBytesField {
            attribute: Attribute::new(n, t, 1),
            len: t.size(),
        };
        // Out of order and apart in the record: the row holds them together, x y z.
        let extra = [
            f("NormalZ", AttrType::F32),
            f("h", AttrType::U16),
            f("normalx", AttrType::F32),
            f("NORMALY", AttrType::F32),
        ];
        let (attrs, ops, len) = las_fields(0, &extra);
        let tail: Vec<(&str, AttrType, u8)> = attrs[attrs.len() - 2..]
            .iter()
            .map(|a| (a.name.as_str(), a.ty, a.count))
            .collect();
        assert_eq!(
            tail,
            [("normal", AttrType::F32, 3), ("h", AttrType::U16, 1)]
        );
        assert_eq!(len, 20 + 14);
        let mut record = vec![0u8; len];
        for (at, v) in [(20, 3.0f32), (26, 1.0), (30, 2.0)] {
            record[at..at + 4].copy_from_slice(&v.to_le_bytes());
        }
        record[24..26].copy_from_slice(&77u16.to_le_bytes());
        let row_len: usize = attrs.iter().map(|a| a.size()).sum();
        let mut row = vec![0u8; row_len];
        record_to_row(&ops, &record, &mut row);
        let normal_at = row_len - 14;
        let n: Vec<f64> = (0..3)
            .map(|c| AttrType::F32.read_f64(&row[normal_at + 4 * c..]))
            .collect();
        assert_eq!(n, [1.0, 2.0, 3.0]);
        let mut back = vec![0u8; len];
        row_to_record(&ops, &row, &mut back);
        assert_eq!(back, record);
        // Not one normal: mixed types, a scale, or a field already called "normal".
        let mut scaled = f("nz", AttrType::F32);
        scaled.attribute.scale = Some(vec![0.5]);
        for extra in [
            vec![
                f("nx", AttrType::F32),
                f("ny", AttrType::F64),
                f("nz", AttrType::F32),
            ],
            vec![f("nx", AttrType::F32), f("ny", AttrType::F32), scaled],
            vec![
                f("nx", AttrType::F32),
                f("ny", AttrType::F32),
                f("nz", AttrType::F32),
                f("normal", AttrType::U8),
            ],
        ] {
            let (attrs, _, _) = las_fields(0, &extra);
            assert_eq!(attrs.len(), 10 + extra.len(), "{extra:?}");
        }
    }
}
