//! PLY point clouds: ASCII and binary (either endianness). The header is parsed by `ply-rs-bw`;
//! the vertex body is decoded here, straight into rows, which is what makes large files fast.

use super::{PointSource, Precision, SourceInfo};
use crate::error::{ConvertError, Result};
use ply_rs_bw::parser::{Parser, Reader};
use ply_rs_bw::ply::{DefaultElement, ElementDef, Encoding, PropertyType, ScalarType};
use std::fs::File;
use std::io::{BufRead, BufReader, Read};
use std::path::Path;
use strata_format::{AttrType, Attribute};

/// What one vertex property becomes.
#[derive(Debug, Clone, Copy)]
enum Target {
    Position(usize),
    /// Byte offset in the attribute row.
    Attr(usize),
    Skip,
}

#[derive(Debug, Clone, Copy)]
struct Prop {
    ty: AttrType,
    /// Length type, for list properties (always skipped).
    list: Option<AttrType>,
    target: Target,
}

pub struct PlySource {
    info: SourceInfo,
    reader: BufReader<File>,
    encoding: Encoding,
    props: Vec<Prop>,
    remaining: u64,
    read_so_far: u64,
    line: String,
    scratch: Vec<u8>,
}

fn attr_type(t: &ScalarType) -> AttrType {
    match t {
        ScalarType::Char => AttrType::I8,
        ScalarType::UChar => AttrType::U8,
        ScalarType::Short => AttrType::I16,
        ScalarType::UShort => AttrType::U16,
        ScalarType::Int => AttrType::I32,
        ScalarType::UInt => AttrType::U32,
        ScalarType::Float => AttrType::F32,
        ScalarType::Double => AttrType::F64,
    }
}

/// Properties that group into one vector attribute: (attribute name, component property names).
const GROUPS: [(&str, [&str; 3]); 3] = [
    ("rgb", ["red", "green", "blue"]),
    ("rgb", ["diffuse_red", "diffuse_green", "diffuse_blue"]),
    ("normal", ["nx", "ny", "nz"]),
];

impl PlySource {
    pub fn open(path: &Path) -> Result<PlySource> {
        let file = File::open(path).map_err(|e| ConvertError::io(path, "cannot open input", e))?;
        let mut magic = [0u8; 4];
        let mut probe = file
            .try_clone()
            .map_err(|e| ConvertError::io(path, "cannot open input", e))?;
        if probe.read_exact(&mut magic).is_err() || &magic[..3] != b"ply" {
            return Err(ConvertError::input(
                path,
                "not a PLY file (it does not start with \"ply\")",
            ));
        }
        drop(probe);
        let file = File::open(path).map_err(|e| ConvertError::io(path, "cannot open input", e))?;
        let mut reader = Reader::new(BufReader::with_capacity(1 << 20, file));
        let header = Parser::<DefaultElement>::new()
            .read_header(&mut reader)
            .map_err(|e| {
                let msg = e.to_string().replace(['\n', '\t'], " ");
                ConvertError::input(path, format!("malformed PLY header ({})", msg.trim()))
            })?;
        let mut body = std::mem::replace(
            reader.get_mut(),
            BufReader::new(
                File::open(path).map_err(|e| ConvertError::io(path, "cannot open input", e))?,
            ),
        );
        let encoding = header.encoding;
        let vertex_pos = header
            .elements
            .keys()
            .position(|k| k == "vertex")
            .ok_or_else(|| ConvertError::input(path, "PLY header has no \"vertex\" element"))?;
        // Elements before the vertices must be skipped.
        for (_, el) in header.elements.iter().take(vertex_pos) {
            skip_element(&mut body, el, encoding).map_err(|e| ConvertError::input(path, e))?;
        }
        let Some((_, vertex)) = header.elements.iter().nth(vertex_pos) else {
            return Err(ConvertError::input(
                path,
                "PLY header has no \"vertex\" element",
            ));
        };
        let names: Vec<&str> = vertex.properties.keys().map(|k| k.as_str()).collect();
        for axis in ["x", "y", "z"] {
            match vertex.properties.get(axis).map(|p| &p.data_type) {
                Some(PropertyType::Scalar(_)) => {}
                Some(PropertyType::List(..)) => {
                    return Err(ConvertError::input(
                        path,
                        format!("vertex property \"{axis}\" is a list, not a number"),
                    ));
                }
                None => {
                    return Err(ConvertError::input(
                        path,
                        format!(
                            "vertex element has no \"{axis}\" property (found: {})",
                            names.join(", ")
                        ),
                    ));
                }
            }
        }
        let mut attributes: Vec<Attribute> = Vec::new();
        let mut props = Vec::new();
        let mut row = 0usize;
        let mut grouped: Vec<(&str, usize)> = Vec::new(); // property name -> row offset
        for (group, comps) in GROUPS {
            let types: Vec<Option<AttrType>> = comps
                .iter()
                .map(|c| match vertex.properties.get(*c).map(|p| &p.data_type) {
                    Some(PropertyType::Scalar(t)) => Some(attr_type(t)),
                    _ => None,
                })
                .collect();
            if let (Some(t), true) = (types[0], types.iter().all(|t| *t == types[0]))
                && attributes.iter().all(|a| a.name != group)
            {
                let ty = t;
                for (i, c) in comps.iter().enumerate() {
                    grouped.push((c, row + i * ty.size()));
                }
                attributes.push(Attribute::new(group, ty, 3));
                row += ty.size() * 3;
            }
        }
        let mut coord_types = Vec::new();
        for (name, def) in &vertex.properties {
            let (ty, list) = match &def.data_type {
                PropertyType::Scalar(t) => (attr_type(t), None),
                PropertyType::List(l, t) => (attr_type(t), Some(attr_type(l))),
            };
            let target = match name.as_str() {
                _ if list.is_some() => Target::Skip,
                "x" => Target::Position(0),
                "y" => Target::Position(1),
                "z" => Target::Position(2),
                n => match grouped.iter().find(|(g, _)| *g == n) {
                    Some((_, off)) => Target::Attr(*off),
                    None => {
                        let a = Attribute::new(n, ty, 1);
                        let off = row;
                        row += a.size();
                        attributes.push(a);
                        Target::Attr(off)
                    }
                },
            };
            if let Target::Position(_) = target {
                coord_types.push(ty);
            }
            props.push(Prop { ty, list, target });
        }
        let precision = if coord_types.contains(&AttrType::F64) {
            Precision::Float64
        } else if coord_types.contains(&AttrType::F32) {
            Precision::Float32
        } else {
            Precision::Integer
        };
        let points = vertex.count as u64;
        Ok(PlySource {
            info: SourceInfo {
                path: path.to_path_buf(),
                points,
                attributes,
                precision,
            },
            reader: body,
            encoding,
            props,
            remaining: points,
            read_so_far: 0,
            line: String::new(),
            scratch: Vec::new(),
        })
    }

    fn truncated(&self) -> ConvertError {
        ConvertError::input(
            &self.info.path,
            format!(
                "file ends after {} of the {} vertices its header announces (truncated)",
                self.read_so_far, self.info.points
            ),
        )
    }
}

/// Reads one binary scalar, returning its value as f64 and writing its little-endian bytes.
fn read_binary(bytes: &[u8], t: AttrType, big_endian: bool, out: &mut [u8; 8]) -> f64 {
    let n = t.size();
    out[..n].copy_from_slice(&bytes[..n]);
    if big_endian {
        out[..n].reverse();
    }
    t.read_f64(&out[..n])
}

/// Encodes an ASCII value as the little-endian bytes of `t`.
fn encode_ascii(token: &str, t: AttrType, out: &mut [u8; 8]) -> Option<f64> {
    let v: f64 = token.parse().ok()?;
    match t {
        AttrType::I8 => out[0] = (v as i8) as u8,
        AttrType::U8 => out[0] = v as u8,
        AttrType::I16 => out[..2].copy_from_slice(&(v as i16).to_le_bytes()),
        AttrType::U16 => out[..2].copy_from_slice(&(v as u16).to_le_bytes()),
        AttrType::I32 => out[..4].copy_from_slice(&(v as i32).to_le_bytes()),
        AttrType::U32 => out[..4].copy_from_slice(&(v as u32).to_le_bytes()),
        AttrType::F32 => out[..4].copy_from_slice(&(v as f32).to_le_bytes()),
        AttrType::F64 => out[..8].copy_from_slice(&v.to_le_bytes()),
        AttrType::I64 => out[..8].copy_from_slice(&(v as i64).to_le_bytes()),
        AttrType::U64 => out[..8].copy_from_slice(&(v as u64).to_le_bytes()),
    }
    Some(v)
}

fn skip_element(
    body: &mut BufReader<File>,
    el: &ElementDef,
    enc: Encoding,
) -> std::result::Result<(), String> {
    let mut line = String::new();
    for i in 0..el.count {
        match enc {
            Encoding::Ascii => {
                line.clear();
                if body.read_line(&mut line).map_err(|e| e.to_string())? == 0 {
                    return Err(format!(
                        "file ends inside element \"{}\" (item {i})",
                        el.name
                    ));
                }
            }
            _ => {
                for p in el.properties.values() {
                    let n = match &p.data_type {
                        PropertyType::Scalar(t) => attr_type(t).size(),
                        PropertyType::List(lt, t) => {
                            let lt = attr_type(lt);
                            let mut b = vec![0u8; lt.size()];
                            body.read_exact(&mut b)
                                .map_err(|_| format!("file ends inside element \"{}\"", el.name))?;
                            let mut o = [0u8; 8];
                            let len = read_binary(&b, lt, enc == Encoding::BinaryBigEndian, &mut o);
                            len as usize * attr_type(t).size()
                        }
                    };
                    let mut b = vec![0u8; n];
                    body.read_exact(&mut b)
                        .map_err(|_| format!("file ends inside element \"{}\"", el.name))?;
                }
            }
        }
    }
    Ok(())
}

impl PointSource for PlySource {
    fn info(&self) -> &SourceInfo {
        &self.info
    }

    fn read(&mut self, max: usize, xyz: &mut Vec<[f64; 3]>, rows: &mut Vec<u8>) -> Result<usize> {
        let n = (max as u64).min(self.remaining) as usize;
        let row_len = self.info.row_len();
        let mut val = [0u8; 8];
        for _ in 0..n {
            let base = rows.len();
            rows.resize(base + row_len, 0);
            let mut p = [0f64; 3];
            match self.encoding {
                Encoding::Ascii => {
                    self.line.clear();
                    let got = self
                        .reader
                        .read_line(&mut self.line)
                        .map_err(|e| ConvertError::io(&self.info.path, "cannot read", e))?;
                    if got == 0 {
                        return Err(self.truncated());
                    }
                    let mut tokens = self.line.split_ascii_whitespace();
                    for prop in &self.props {
                        if let Some(lt) = prop.list {
                            let _ = lt;
                            let len: usize =
                                tokens.next().and_then(|t| t.parse().ok()).unwrap_or(0);
                            for _ in 0..len {
                                tokens.next();
                            }
                            continue;
                        }
                        let token = tokens.next().ok_or_else(|| {
                            ConvertError::input(
                                &self.info.path,
                                format!("vertex {} has too few values", self.read_so_far),
                            )
                        })?;
                        let v = encode_ascii(token, prop.ty, &mut val).ok_or_else(|| {
                            ConvertError::input(
                                &self.info.path,
                                format!(
                                    "vertex {} has a value \"{token}\" that is not a number",
                                    self.read_so_far
                                ),
                            )
                        })?;
                        match prop.target {
                            Target::Position(a) => p[a] = v,
                            Target::Attr(off) => {
                                let s = prop.ty.size();
                                rows[base + off..base + off + s].copy_from_slice(&val[..s]);
                            }
                            Target::Skip => {}
                        }
                    }
                }
                enc => {
                    let big = enc == Encoding::BinaryBigEndian;
                    for prop in &self.props {
                        let s = prop.ty.size();
                        if let Some(lt) = prop.list {
                            self.scratch.resize(lt.size(), 0);
                            if self.reader.read_exact(&mut self.scratch).is_err() {
                                return Err(self.truncated());
                            }
                            let len = read_binary(&self.scratch, lt, big, &mut val) as usize;
                            self.scratch.resize(len * s, 0);
                            if self.reader.read_exact(&mut self.scratch).is_err() {
                                return Err(self.truncated());
                            }
                            continue;
                        }
                        self.scratch.resize(s, 0);
                        if self.reader.read_exact(&mut self.scratch).is_err() {
                            return Err(self.truncated());
                        }
                        let v = read_binary(&self.scratch, prop.ty, big, &mut val);
                        match prop.target {
                            Target::Position(a) => p[a] = v,
                            Target::Attr(off) => {
                                rows[base + off..base + off + s].copy_from_slice(&val[..s])
                            }
                            Target::Skip => {}
                        }
                    }
                }
            }
            xyz.push(p);
            self.read_so_far += 1;
        }
        self.remaining -= n as u64;
        Ok(n)
    }
}
