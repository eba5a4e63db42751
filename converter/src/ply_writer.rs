//! Writing rows out as PLY (binary little endian): positions as doubles, each attribute as a
//! property of its own type where PLY has one. Also the rule PLY shares with Potree 2.0
//! export: one name per property (`UniqueNames`).

use crate::error::{ConvertError, Result};
use crate::las_records::refuse_encoded;
use crate::part_file::create_part;
use crate::writers::RowWriter;
use std::fs::File;
use std::io::{BufWriter, Write};
use std::path::{Path, PathBuf};
use strata_format::{AttrType, RowLayout, row_position};

pub(crate) struct PlyRowWriter {
    path: PathBuf,
    part: PathBuf,
    out: BufWriter<File>,
    layout: RowLayout,
    scale: [f64; 3],
    offset: [f64; 3],
    /// How each attribute's values are written.
    written_as: Vec<PlyValue>,
}

/// How an attribute's stored values become a PLY property's. Rows come widened for PLY
/// (`export::widened`): no half floats, and 64-bit integers already doubles.
#[derive(Debug, Clone, Copy, PartialEq)]
enum PlyValue {
    /// The stored bytes.
    Stored,
    /// A LAS extra attribute with a scale or offset, as the double it stands for: PLY has no
    /// place for the scale, and a reader would take the raw integer for the value.
    Scaled,
}

impl PlyValue {
    fn of(a: &strata_format::Attribute) -> PlyValue {
        if a.scale.is_some() || a.offset.is_some() {
            PlyValue::Scaled
        } else {
            PlyValue::Stored
        }
    }
}

fn ply_type(t: AttrType) -> &'static str {
    match t {
        AttrType::I8 => "char",
        AttrType::U8 => "uchar",
        AttrType::I16 => "short",
        AttrType::U16 => "ushort",
        AttrType::I32 => "int",
        AttrType::U32 => "uint",
        AttrType::F32 | AttrType::F16 => "float",
        AttrType::F64 | AttrType::U64 | AttrType::I64 => "double",
    }
}

impl PlyRowWriter {
    pub(crate) fn create(
        path: &Path,
        layout: &RowLayout,
        scale: [f64; 3],
        offset: [f64; 3],
        points: u64,
    ) -> Result<Self> {
        refuse_encoded(path, layout)?;
        let (part, file) = create_part(path)?;
        let mut out = BufWriter::with_capacity(1 << 20, file);
        let mut h = format!(
            "ply\nformat binary_little_endian 1.0\ncomment written by strata {}\nelement vertex {points}\nproperty double x\nproperty double y\nproperty double z\n",
            env!("CARGO_PKG_VERSION")
        );
        for (a, names) in layout.attributes.iter().zip(ply_property_names(layout)) {
            let ty = match PlyValue::of(a) {
                PlyValue::Scaled => "double",
                _ => ply_type(a.ty),
            };
            for n in names {
                h.push_str(&format!("property {ty} {n}\n"));
            }
        }
        h.push_str("end_header\n");
        out.write_all(h.as_bytes())
            .map_err(|e| ConvertError::io(&part, "cannot write", e))?;
        Ok(PlyRowWriter {
            path: path.to_path_buf(),
            part,
            out,
            written_as: layout.attributes.iter().map(PlyValue::of).collect(),
            layout: layout.clone(),
            scale,
            offset,
        })
    }
}

/// Names handed out once each: a name already taken gets the first free number (`red_1`,
/// `red_2`), as readers of PLY and Potree 2.0 refuse, or take one of, a name declared twice.
pub(crate) struct UniqueNames {
    taken: std::collections::HashSet<String>,
}

impl UniqueNames {
    /// Names that `reserved` (the position's) already take.
    pub(crate) fn new(reserved: &[&str]) -> UniqueNames {
        UniqueNames {
            taken: reserved.iter().map(|n| n.to_string()).collect(),
        }
    }

    /// `n`, or `n_1`, `n_2`, … where `n` is taken; an empty name is `attribute`.
    pub(crate) fn take(&mut self, n: String) -> String {
        let n = if n.is_empty() {
            "attribute".to_string()
        } else {
            n
        };
        let mut name = n.clone();
        let mut i = 1;
        while self.taken.contains(&name) {
            name = format!("{n}_{i}");
            i += 1;
        }
        self.taken.insert(name.clone());
        name
    }
}

/// Each attribute's PLY property names: a colour as `red green blue`, a normal as `nx ny nz`,
/// other vectors as `NAME_0`, `NAME_1`, …. A name already taken (a scalar `red` beside a
/// colour, a LAS extra attribute named `green`) gets a number (`UniqueNames`); white space,
/// which would end the name in the header, becomes `_`.
fn ply_property_names(layout: &RowLayout) -> Vec<Vec<String>> {
    let mut names = UniqueNames::new(&["x", "y", "z"]);
    let mut unique = |n: String| {
        names.take(
            n.chars()
                .map(|c| if c.is_whitespace() { '_' } else { c })
                .collect(),
        )
    };
    let group = |a: &strata_format::Attribute| -> Option<[&str; 3]> {
        match (a.name.as_str(), a.count) {
            ("rgb", 3) => Some(["red", "green", "blue"]),
            ("normal", 3) => Some(["nx", "ny", "nz"]),
            _ => None,
        }
    };
    // A colour and a normal keep the names readers group them by.
    let grouped: Vec<Option<Vec<String>>> = layout
        .attributes
        .iter()
        .map(|a| group(a).map(|g| g.iter().map(|n| unique(n.to_string())).collect()))
        .collect();
    layout
        .attributes
        .iter()
        .zip(grouped)
        .map(|(a, grouped)| {
            grouped.unwrap_or_else(|| match a.count {
                1 => vec![unique(a.name.clone())],
                c => (0..c).map(|i| unique(format!("{}_{i}", a.name))).collect(),
            })
        })
        .collect()
}

impl RowWriter for PlyRowWriter {
    fn write_rows(&mut self, rows: &[u8]) -> Result<()> {
        let mut rec = Vec::with_capacity(self.layout.stride + 24);
        for row in rows.chunks_exact(self.layout.stride) {
            rec.clear();
            let p = row_position(row);
            for ((o, s), v) in self.offset.iter().zip(&self.scale).zip(p) {
                rec.extend_from_slice(&(o + s * v as f64).to_le_bytes());
            }
            for (i, a) in self.layout.attributes.iter().enumerate() {
                let v = &row[self.layout.offsets[i]..self.layout.offsets[i] + a.size()];
                let values = v.chunks_exact(a.ty.size());
                match self.written_as[i] {
                    PlyValue::Stored => rec.extend_from_slice(v),
                    PlyValue::Scaled => {
                        // LAS 1.4: value = raw · scale + offset, each per component.
                        for (c, raw) in values.enumerate() {
                            let (scale, offset) = a.scaling(c);
                            let value = a.ty.read_f64(raw) * scale + offset;
                            rec.extend_from_slice(&value.to_le_bytes());
                        }
                    }
                }
            }
            self.out
                .write_all(&rec)
                .map_err(|e| ConvertError::io(&self.part, "cannot write", e))?;
        }
        Ok(())
    }

    fn finish(mut self: Box<Self>) -> Result<()> {
        self.out
            .flush()
            .map_err(|e| ConvertError::io(&self.part, "cannot write", e))?;
        std::fs::rename(&self.part, &self.path)
            .map_err(|e| ConvertError::io(&self.path, "cannot move into place", e))
    }
}
