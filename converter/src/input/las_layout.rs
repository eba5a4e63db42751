//! Where each LAS point-record field lives, for point formats 0-10, and how it maps onto Strata
//! attributes. Reading (record -> row) and export (row -> record) share this one table.

use super::las_normals::normal_group;
use strata_format::{AttrType, Attribute};

/// How one attribute's bytes relate to the LAS record.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum FieldOp {
    /// `len` bytes copied as they are.
    Copy {
        record: usize,
        row: usize,
        len: usize,
    },
    /// A bit field: `(record[byte] >> shift) & mask` is the attribute's u8 value.
    Bits {
        record: usize,
        shift: u8,
        mask: u8,
        row: usize,
    },
}

/// One extra-bytes attribute as its VLR describes it.
#[derive(Debug, Clone, PartialEq)]
pub struct ExtraBytesField {
    pub attribute: Attribute,
    /// Raw bytes the field occupies in the record.
    pub len: usize,
}

pub const STANDARD_LEGACY: [&str; 10] = [
    "intensity",
    "return_number",
    "number_of_returns",
    "scan_direction_flag",
    "edge_of_flight_line",
    "classification",
    "classification_flags",
    "scan_angle_rank",
    "user_data",
    "point_source_id",
];

/// Attributes (in row order) and field ops of a LAS point format. Row offsets in the ops are
/// relative to the start of the attributes (after the 12 position bytes). Three extra-bytes
/// fields named like a normal's components become one `normal`
/// ([`NORMAL_FIELD_NAMES`](super::las_normals::NORMAL_FIELD_NAMES)).
pub fn las_fields(
    format_number: u8,
    extra: &[ExtraBytesField],
) -> (Vec<Attribute>, Vec<FieldOp>, usize) {
    fields(format_number, extra, true)
}

/// [`las_fields`] with every extra-bytes field an attribute of its own, for writing a layout
/// that holds `nx ny nz` (or the like) as separate attributes.
pub fn las_fields_ungrouped(
    format_number: u8,
    extra: &[ExtraBytesField],
) -> (Vec<Attribute>, Vec<FieldOp>, usize) {
    fields(format_number, extra, false)
}

fn fields(
    format_number: u8,
    extra: &[ExtraBytesField],
    group_normals: bool,
) -> (Vec<Attribute>, Vec<FieldOp>, usize) {
    let extended = format_number >= 6;
    let mut attrs = Vec::new();
    let mut ops = Vec::new();
    let a = |n: &str, t: AttrType, c: u8| Attribute::new(n, t, c);
    let copy = |record: usize, row: usize, len: usize| FieldOp::Copy { record, row, len };
    let bits = |record: usize, shift: u8, mask: u8, row: usize| FieldOp::Bits {
        record,
        shift,
        mask,
        row,
    };
    // Each attribute takes the next row offset; `op` builds its field op for that offset.
    let mut next = 0usize;
    let mut push = |attrs: &mut Vec<Attribute>, at: Attribute, op: &dyn Fn(usize) -> FieldOp| {
        ops.push(op(next));
        next += at.size();
        attrs.push(at);
    };
    push(&mut attrs, a("intensity", AttrType::U16, 1), &|r| {
        copy(12, r, 2)
    });
    let gps_at = if !extended {
        push(&mut attrs, a("return_number", AttrType::U8, 1), &|r| {
            bits(14, 0, 0x07, r)
        });
        push(&mut attrs, a("number_of_returns", AttrType::U8, 1), &|r| {
            bits(14, 3, 0x07, r)
        });
        push(
            &mut attrs,
            a("scan_direction_flag", AttrType::U8, 1),
            &|r| bits(14, 6, 1, r),
        );
        push(
            &mut attrs,
            a("edge_of_flight_line", AttrType::U8, 1),
            &|r| bits(14, 7, 1, r),
        );
        push(&mut attrs, a("classification", AttrType::U8, 1), &|r| {
            bits(15, 0, 0x1f, r)
        });
        push(
            &mut attrs,
            a("classification_flags", AttrType::U8, 1),
            &|r| bits(15, 5, 0x07, r),
        );
        push(&mut attrs, a("scan_angle_rank", AttrType::I8, 1), &|r| {
            copy(16, r, 1)
        });
        push(&mut attrs, a("user_data", AttrType::U8, 1), &|r| {
            copy(17, r, 1)
        });
        push(&mut attrs, a("point_source_id", AttrType::U16, 1), &|r| {
            copy(18, r, 2)
        });
        20
    } else {
        push(&mut attrs, a("return_number", AttrType::U8, 1), &|r| {
            bits(14, 0, 0x0f, r)
        });
        push(&mut attrs, a("number_of_returns", AttrType::U8, 1), &|r| {
            bits(14, 4, 0x0f, r)
        });
        push(
            &mut attrs,
            a("scan_direction_flag", AttrType::U8, 1),
            &|r| bits(15, 6, 1, r),
        );
        push(
            &mut attrs,
            a("edge_of_flight_line", AttrType::U8, 1),
            &|r| bits(15, 7, 1, r),
        );
        push(&mut attrs, a("classification", AttrType::U8, 1), &|r| {
            copy(16, r, 1)
        });
        push(
            &mut attrs,
            a("classification_flags", AttrType::U8, 1),
            &|r| bits(15, 0, 0x0f, r),
        );
        push(&mut attrs, a("scanner_channel", AttrType::U8, 1), &|r| {
            bits(15, 4, 0x03, r)
        });
        push(&mut attrs, a("user_data", AttrType::U8, 1), &|r| {
            copy(17, r, 1)
        });
        push(&mut attrs, a("scan_angle", AttrType::I16, 1), &|r| {
            copy(18, r, 2)
        });
        push(&mut attrs, a("point_source_id", AttrType::U16, 1), &|r| {
            copy(20, r, 2)
        });
        22
    };
    let has_gps = !matches!(format_number, 0 | 2);
    let has_rgb = matches!(format_number, 2 | 3 | 5 | 7 | 8 | 10);
    let has_nir = matches!(format_number, 8 | 10);
    let has_wave = matches!(format_number, 4 | 5 | 9 | 10);
    let mut at = if has_gps { gps_at + 8 } else { gps_at };
    if has_gps {
        push(&mut attrs, a("gps_time", AttrType::F64, 1), &|r| {
            copy(gps_at, r, 8)
        });
    }
    if has_rgb {
        let rgb_at = at;
        push(&mut attrs, a("rgb", AttrType::U16, 3), &|r| {
            copy(rgb_at, r, 6)
        });
        at += 6;
    }
    if has_nir {
        let nir_at = at;
        push(&mut attrs, a("nir", AttrType::U16, 1), &|r| {
            copy(nir_at, r, 2)
        });
        at += 2;
    }
    if has_wave {
        let w = at;
        push(
            &mut attrs,
            a("wave_packet_descriptor_index", AttrType::U8, 1),
            &|r| copy(w, r, 1),
        );
        push(
            &mut attrs,
            a("wave_packet_offset", AttrType::U64, 1),
            &|r| copy(w + 1, r, 8),
        );
        push(&mut attrs, a("wave_packet_size", AttrType::U32, 1), &|r| {
            copy(w + 9, r, 4)
        });
        push(
            &mut attrs,
            a("wave_return_point_location", AttrType::F32, 1),
            &|r| copy(w + 13, r, 4),
        );
        push(&mut attrs, a("wave_xyz_t", AttrType::F32, 3), &|r| {
            copy(w + 17, r, 12)
        });
        at += 29;
    }
    // Extra bytes: each field is one attribute at its place in the record, except three
    // scalar floats named like a normal's components, which become one `normal` (as PLY's
    // `nx ny nz` do), placed where the first of them is.
    let group = normal_group(extra).filter(|_| group_normals);
    let mut record_at = Vec::with_capacity(extra.len());
    for e in extra {
        record_at.push(at);
        at += e.len;
    }
    for (i, e) in extra.iter().enumerate() {
        match &group {
            Some(g) if g.fields.contains(&i) => {
                if g.fields.iter().min() != Some(&i) {
                    continue;
                }
                let s = g.attribute.ty.size();
                for (c, &f) in g.fields.iter().enumerate() {
                    ops.push(copy(record_at[f], next + c * s, s));
                }
                next += g.attribute.size();
                attrs.push(g.attribute.clone());
            }
            _ => {
                ops.push(copy(record_at[i], next, e.len));
                next += e.len;
                attrs.push(e.attribute.clone());
            }
        }
    }
    (attrs, ops, at)
}

/// Decodes the Extra Bytes VLR (LASF_Spec record 4) into fields, covering exactly
/// `extra_len` bytes; bytes it leaves undescribed become one `extra_bytes` u8 array.
pub fn parse_extra_bytes(
    vlr_data: Option<&[u8]>,
    extra_len: usize,
) -> Result<Vec<ExtraBytesField>, String> {
    let mut fields = Vec::new();
    let mut used = 0usize;
    if let Some(data) = vlr_data {
        if data.len() % 192 != 0 {
            return Err(format!(
                "extra bytes VLR is {} bytes, not a multiple of 192",
                data.len()
            ));
        }
        for d in data.chunks_exact(192) {
            let data_type = d[2];
            let options = d[3];
            let name_end = d[4..36].iter().position(|&b| b == 0).unwrap_or(32);
            let name: String = String::from_utf8_lossy(&d[4..4 + name_end])
                .chars()
                .filter(|c| !c.is_control())
                .collect::<String>()
                .trim()
                .to_string();
            let (ty, count, len) = match data_type {
                0 => (AttrType::U8, options.max(1), options.max(1) as usize),
                1..=10 => {
                    let t = eb_type(data_type);
                    (t, 1, t.size())
                }
                11..=30 => {
                    let base = (data_type - 11) % 10 + 1;
                    let n = if data_type <= 20 { 2 } else { 3 };
                    let t = eb_type(base);
                    (t, n, t.size() * n as usize)
                }
                t => {
                    return Err(format!(
                        "extra bytes field '{name}' has unknown data type {t}"
                    ));
                }
            };
            let f64s = |off: usize| -> Vec<f64> {
                (0..count as usize)
                    .map(|i| {
                        let mut b = [0u8; 8];
                        b.copy_from_slice(&d[off + i * 8..off + i * 8 + 8]);
                        f64::from_le_bytes(b)
                    })
                    .collect()
            };
            let mut attribute =
                Attribute::new(if name.is_empty() { "extra" } else { &name }, ty, count);
            for (flag, at, what) in [(0x08, 112, "scale"), (0x10, 136, "offset")] {
                if data_type == 0 || options & flag == 0 {
                    continue;
                }
                let values = f64s(at);
                if let Some(v) = values.iter().find(|v| !v.is_finite()) {
                    return Err(format!(
                        "extra bytes VLR: field \"{name}\" has a {what} of {v}, which is not a number a value can be scaled by"
                    ));
                }
                match what {
                    "scale" => attribute.scale = Some(values),
                    _ => attribute.offset = Some(values),
                }
            }
            // no_data (option bit 0; not for type 0, whose options byte is its length).
            if data_type != 0 && options & 0x01 != 0 {
                attribute.no_data = Some(
                    (0..count as usize)
                        .map(|i| {
                            let mut b = [0u8; 8];
                            b.copy_from_slice(&d[40 + i * 8..48 + i * 8]);
                            u64::from_le_bytes(b)
                        })
                        .collect(),
                );
            }
            let desc_end = d[160..192].iter().position(|&b| b == 0).unwrap_or(32);
            attribute.description = String::from_utf8_lossy(&d[160..160 + desc_end])
                .chars()
                .filter(|c| !c.is_control())
                .collect::<String>()
                .trim()
                .to_string();
            used += len;
            if used > extra_len {
                return Err(format!(
                    "extra bytes VLR describes {used} bytes but records carry only {extra_len}"
                ));
            }
            fields.push(ExtraBytesField { attribute, len });
        }
    }
    if used < extra_len {
        let rest = extra_len - used;
        if rest > 255 {
            return Err(format!(
                "{rest} undescribed extra bytes per record (at most 255 supported)"
            ));
        }
        fields.push(ExtraBytesField {
            attribute: Attribute::new(UNDESCRIBED, AttrType::U8, rest as u8),
            len: rest,
        });
    }
    Ok(fields)
}

/// Gives every extra-bytes field a name of its own: one that clashes with a standard field of
/// the point format (or x, y, z, or an earlier extra field) is kept as `extra_NAME` (then
/// `extra_NAME_2`, ...), so it never overwrites the real one. Returns a warning per rename.
pub fn rename_clashes(format_number: u8, extra: &mut [ExtraBytesField]) -> Vec<String> {
    let (standard, _, _) = las_fields(format_number, &[]);
    let mut taken: Vec<String> = ["x", "y", "z"].iter().map(|s| s.to_string()).collect();
    taken.extend(standard.iter().map(|a| a.name.clone()));
    let mut warnings = Vec::new();
    for field in extra.iter_mut() {
        let name = field.attribute.name.clone();
        if taken.contains(&name) {
            let new = super::extra_name(&name, |n| taken.iter().any(|t| t == n));
            warnings.push(format!(
                "extra bytes field \"{name}\" has the name of another field of the points; kept as \"{new}\""
            ));
            field.attribute.name = new;
        }
        taken.push(field.attribute.name.clone());
    }
    warnings
}

fn eb_type(code: u8) -> AttrType {
    match code {
        1 => AttrType::U8,
        2 => AttrType::I8,
        3 => AttrType::U16,
        4 => AttrType::I16,
        5 => AttrType::U32,
        6 => AttrType::I32,
        7 => AttrType::U64,
        8 => AttrType::I64,
        9 => AttrType::F32,
        _ => AttrType::F64,
    }
}

/// The name given to the extra bytes of a record that no Extra Bytes descriptor covers.
pub const UNDESCRIBED: &str = "extra_bytes";

/// The Extra Bytes VLR data type code of an attribute type.
pub fn eb_code(t: AttrType) -> u8 {
    match t {
        AttrType::U8 => 1,
        AttrType::I8 => 2,
        AttrType::U16 => 3,
        AttrType::I16 => 4,
        AttrType::U32 => 5,
        AttrType::I32 => 6,
        AttrType::U64 => 7,
        AttrType::I64 => 8,
        AttrType::F32 => 9,
        AttrType::F64 => 10,
        // LAS has no half floats: export widens f16 to f32 (`export::widened`) before writing.
        AttrType::F16 => 9,
    }
}

/// Applies the ops of one record into a row's attribute area.
#[inline]
pub fn record_to_row(ops: &[FieldOp], record: &[u8], row: &mut [u8]) {
    for op in ops {
        match *op {
            FieldOp::Copy {
                record: r,
                row: w,
                len,
            } => copy_field(&mut row[w..w + len], &record[r..r + len]),
            FieldOp::Bits {
                record: r,
                shift,
                mask,
                row: w,
            } => row[w] = (record[r] >> shift) & mask,
        }
    }
}

/// `dst.copy_from_slice(src)` with the common field sizes as single moves (a copy of unknown
/// length is a call to memmove, which dominated per-record conversion).
#[inline]
fn copy_field(dst: &mut [u8], src: &[u8]) {
    match dst.len() {
        1 => dst[0] = src[0],
        2 => dst.copy_from_slice(&src[..2]),
        4 => dst.copy_from_slice(&src[..4]),
        8 => dst.copy_from_slice(&src[..8]),
        _ => dst.copy_from_slice(src),
    }
}

/// The inverse of [`record_to_row`]; `record` must start zeroed in its bit-field bytes.
#[inline]
pub fn row_to_record(ops: &[FieldOp], row: &[u8], record: &mut [u8]) {
    for op in ops {
        match *op {
            FieldOp::Copy {
                record: r,
                row: w,
                len,
            } => record[r..r + len].copy_from_slice(&row[w..w + len]),
            FieldOp::Bits {
                record: r,
                shift,
                mask,
                row: w,
            } => record[r] |= (row[w] & mask) << shift,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn record_lengths_match_the_las_spec() {
        let expected = [20, 28, 26, 34, 57, 63, 30, 36, 38, 59, 67];
        for (f, len) in expected.iter().enumerate() {
            let (_, _, at) = las_fields(f as u8, &[]);
            assert_eq!(at, *len, "point format {f}");
        }
    }

    #[test]
    fn record_row_round_trip_for_every_format() {
        for f in 0..=10u8 {
            let (attrs, ops, len) = las_fields(f, &[]);
            let row_len: usize = attrs.iter().map(|a| a.size()).sum();
            let mut record: Vec<u8> = (0..len).map(|i| (i * 37 + 11) as u8).collect();
            record[..12].fill(0);
            let mut row = vec![0u8; row_len];
            record_to_row(&ops, &record, &mut row);
            let mut back = vec![0u8; len];
            row_to_record(&ops, &row, &mut back);
            assert_eq!(back, record, "point format {f}");
        }
    }

    #[test]
    fn extra_bytes_named_like_standard_fields_are_renamed() {
        let field = |n: &str| ExtraBytesField {
            attribute: Attribute::new(n, AttrType::U16, 1),
            len: 2,
        };
        let mut extra = vec![
            field("intensity"),
            field("x"),
            field("intensity"),
            field("h"),
        ];
        let warnings = rename_clashes(3, &mut extra);
        let names: Vec<&str> = extra.iter().map(|e| e.attribute.name.as_str()).collect();
        assert_eq!(
            names,
            ["extra_intensity", "extra_x", "extra_intensity_2", "h"]
        );
        assert_eq!(warnings.len(), 3);
        let (attrs, _, _) = las_fields(3, &extra);
        let mut all: Vec<&str> = attrs.iter().map(|a| a.name.as_str()).collect();
        all.sort();
        all.dedup();
        assert_eq!(all.len(), attrs.len(), "every name once");
    }

    #[test]
    fn non_finite_extra_bytes_scales_are_refused() {
        let mut d = vec![0u8; 192];
        d[2] = 9;
        d[3] = 0x08;
        d[4] = b'h';
        d[112..120].copy_from_slice(&f64::NAN.to_le_bytes());
        let err = parse_extra_bytes(Some(&d), 4).expect_err("NaN scale");
        assert!(err.contains("field \"h\" has a scale of NaN"), "{err}");
    }
}
