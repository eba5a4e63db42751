//! PLY point clouds: ASCII and binary (either endianness). The header is parsed by
//! `ply_header`; the vertex body is decoded here, straight into rows, which is what makes large
//! files fast. Every count read from the file is checked against the bytes left in it before it
//! is used.

use super::ply_header::{ElementDef, Encoding, PlyHeader, read_header, shown};
use super::ply_skip::skip_text_elements;
use super::{PointSource, Precision, SourceInfo};
use crate::error::{ConvertError, Result};
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

#[derive(Debug, Clone)]
struct Prop {
    ty: AttrType,
    /// Length type, for list properties (always skipped).
    list: Option<AttrType>,
    target: Target,
    name: String,
}

pub struct PlySource {
    info: SourceInfo,
    reader: BufReader<File>,
    encoding: Encoding,
    props: Vec<Prop>,
    remaining: u64,
    read_so_far: u64,
    /// Bytes of the file not yet read.
    left: u64,
    /// The elements after the vertices: read through once the vertices are, so that the body
    /// is checked to its end whichever element is last.
    after: Vec<ElementDef>,
    line: String,
    scratch: Vec<u8>,
}

/// Properties that group into one vector attribute: (attribute name, component property names).
/// The first of a name's groups found is taken.
const GROUPS: [(&str, [&str; 3]); 5] = [
    ("rgb", ["red", "green", "blue"]),
    ("rgb", ["diffuse_red", "diffuse_green", "diffuse_blue"]),
    ("rgb", ["r", "g", "b"]),
    ("normal", ["nx", "ny", "nz"]),
    ("normal", ["normal_x", "normal_y", "normal_z"]),
];

impl PlySource {
    pub fn open(path: &Path) -> Result<PlySource> {
        let file = File::open(path).map_err(|e| ConvertError::io(path, "cannot open input", e))?;
        let file_len = file
            .metadata()
            .map_err(|e| ConvertError::io(path, "cannot read file size", e))?
            .len();
        let mut body = BufReader::with_capacity(1 << 20, file);
        let header = read_header(&mut body).map_err(|e| ConvertError::input(path, e))?;
        let bad = |what: String| ConvertError::input(path, what);
        let PlyHeader {
            encoding,
            elements,
            len,
        } = header;
        let Some(vertex_pos) = elements.iter().position(|e| e.name == "vertex") else {
            return Err(bad("the PLY header has no \"vertex\" element".into()));
        };
        check_sizes(&elements, encoding, file_len - len).map_err(&bad)?;
        let mut left = file_len - len;
        // Elements before the vertices must be skipped.
        for el in &elements[..vertex_pos] {
            skip_element(&mut body, el, encoding, &mut left).map_err(&bad)?;
        }
        let vertex = &elements[vertex_pos];
        let names: Vec<&str> = vertex.properties.iter().map(|p| p.name.as_str()).collect();
        let find = |n: &str| vertex.properties.iter().find(|p| p.name == n);
        for axis in ["x", "y", "z"] {
            match find(axis).map(|p| p.list) {
                Some(None) => {}
                Some(Some(_)) => {
                    return Err(bad(format!(
                        "vertex property \"{axis}\" is a list, not a number"
                    )));
                }
                None => {
                    return Err(bad(format!(
                        "vertex element has no \"{axis}\" property (found: {})",
                        shown(&names.join(", "))
                    )));
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
                .map(|c| find(c).filter(|p| p.list.is_none()).map(|p| p.ty))
                .collect();
            if let (Some(t), true) = (types[0], types.iter().all(|t| *t == types[0]))
                && attributes.iter().all(|a| a.name != group)
                && vertex.properties.iter().all(|p| p.name != group)
            {
                for (i, c) in comps.iter().enumerate() {
                    grouped.push((c, row + i * t.size()));
                }
                attributes.push(Attribute::new(group, t, 3));
                row += t.size() * 3;
            }
        }
        let mut coord_types = Vec::new();
        for def in &vertex.properties {
            let (ty, list) = (def.ty, def.list);
            let target = match def.name.as_str() {
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
            props.push(Prop {
                ty,
                list,
                target,
                name: def.name.clone(),
            });
        }
        let precision = if coord_types.contains(&AttrType::F64) {
            Precision::Float64
        } else if coord_types.contains(&AttrType::F32) {
            Precision::Float32
        } else {
            Precision::Integer
        };
        let points = vertex.count;
        let warnings = super::keep_scanner_name_free(&mut attributes)
            .map(|w| format!("{}: {w}", path.display()))
            .into_iter()
            .collect();
        Ok(PlySource {
            info: SourceInfo {
                path: path.to_path_buf(),
                points,
                attributes,
                precision,
                warnings,
                scanners: Vec::new(),
                crs: None,
                time_from_unknown_start: false,
            },
            reader: body,
            encoding,
            props,
            remaining: points,
            read_so_far: 0,
            left,
            after: elements[vertex_pos + 1..].to_vec(),
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

    fn fault(&self, what: String) -> ConvertError {
        ConvertError::input(
            &self.info.path,
            format!("vertex {} (counting from 0): {what}", self.read_so_far),
        )
    }

    /// Reads exactly `n` bytes into the scratch buffer, counting them off the file.
    fn fill(&mut self, n: u64) -> Result<()> {
        if n > self.left {
            return Err(self.truncated());
        }
        self.scratch.resize(n as usize, 0);
        if self.reader.read_exact(&mut self.scratch).is_err() {
            return Err(self.truncated());
        }
        self.left -= n;
        Ok(())
    }

    /// After the last vertex: the elements that follow are read through, and after the last
    /// element nothing may follow (but white space in text).
    fn check_end(&mut self) -> Result<()> {
        let path = &self.info.path;
        if self.encoding == Encoding::Ascii && !self.after.is_empty() {
            return skip_text_elements(&mut self.reader, &self.after, &mut self.left)
                .map_err(|e| ConvertError::input(path, e));
        }
        for el in &self.after {
            skip_element(&mut self.reader, el, self.encoding, &mut self.left)
                .map_err(|e| ConvertError::input(path, e))?;
        }
        if self.left == 0 {
            return Ok(());
        }
        let mut rest = Vec::new();
        let _ = (&mut self.reader).take(1 << 16).read_to_end(&mut rest);
        let only_space = rest.iter().all(|b| b.is_ascii_whitespace() || *b == 0);
        if self.encoding != Encoding::Ascii || !only_space {
            let last = match self.after.last() {
                Some(el) => format!("the last item of element \"{}\"", shown(&el.name)),
                None => format!("the last of the {} vertices", self.info.points),
            };
            return Err(ConvertError::input(
                path,
                format!(
                    "{} bytes follow {last}, the header's last element (does the format line say the right encoding?)",
                    self.left
                ),
            ));
        }
        Ok(())
    }
}

/// The body must have room for what the header announces, before anything is read or
/// allocated; a binary body without lists must match it to the byte.
fn check_sizes(
    elements: &[ElementDef],
    enc: Encoding,
    body: u64,
) -> std::result::Result<(), String> {
    let mut least = 0u64;
    let mut exact = true;
    for el in elements {
        let props = el.properties.len() as u64;
        let item = match enc {
            // A value and its separator are at least two characters.
            Encoding::Ascii => 2 * props.max(1),
            _ => el
                .properties
                .iter()
                .map(|p| p.list.unwrap_or(p.ty).size() as u64)
                .sum(),
        };
        exact &= enc != Encoding::Ascii && el.fixed_size().is_some();
        least = el
            .count
            .checked_mul(item)
            .and_then(|n| n.checked_add(least))
            .unwrap_or(u64::MAX);
        // The last ASCII line may lack its newline.
        if least.saturating_sub(1) > body {
            return Err(format!(
                "the header announces {} items of element \"{}\" (line {}), but the {body} bytes after the header cannot hold them (truncated)",
                el.count,
                shown(&el.name),
                el.line
            ));
        }
    }
    if exact && least < body {
        return Err(format!(
            "the {body} bytes after the header are {} more than its elements describe (does the format line say the right encoding?)",
            body - least
        ));
    }
    Ok(())
}

/// Reads the whole-number item count of a binary list.
fn list_count(bytes: &[u8], t: AttrType, big_endian: bool) -> u64 {
    let mut out = [0u8; 8];
    let v = read_binary(bytes, t, big_endian, &mut out);
    // Integer types only (the header refuses float counts); negative counts become huge and
    // fail the size check that follows.
    if v < 0.0 { u64::MAX } else { v as u64 }
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

/// Encodes an ASCII value as the little-endian bytes of `t`; `None` when the token is not a
/// number of that type (a whole number in range, for the integer types).
fn encode_ascii(token: &str, t: AttrType, out: &mut [u8; 8]) -> Option<f64> {
    if t.is_float() {
        let v: f64 = token.parse().ok()?;
        match t {
            // A finite value beyond f32's range is not a float's.
            AttrType::F32 if v.is_finite() && !(v as f32).is_finite() => return None,
            AttrType::F32 => out[..4].copy_from_slice(&(v as f32).to_le_bytes()),
            _ => out[..8].copy_from_slice(&v.to_le_bytes()),
        }
        return Some(v);
    }
    let v: i64 = token.parse().ok()?;
    match t {
        AttrType::I8 => out[0] = i8::try_from(v).ok()? as u8,
        AttrType::U8 => out[0] = u8::try_from(v).ok()?,
        AttrType::I16 => out[..2].copy_from_slice(&i16::try_from(v).ok()?.to_le_bytes()),
        AttrType::U16 => out[..2].copy_from_slice(&u16::try_from(v).ok()?.to_le_bytes()),
        AttrType::I32 => out[..4].copy_from_slice(&i32::try_from(v).ok()?.to_le_bytes()),
        AttrType::U32 => out[..4].copy_from_slice(&u32::try_from(v).ok()?.to_le_bytes()),
        AttrType::I64 => out[..8].copy_from_slice(&v.to_le_bytes()),
        _ => out[..8].copy_from_slice(&u64::try_from(v).ok()?.to_le_bytes()),
    }
    Some(v as f64)
}

fn skip_element(
    body: &mut BufReader<File>,
    el: &ElementDef,
    enc: Encoding,
    left: &mut u64,
) -> std::result::Result<(), String> {
    let name = shown(&el.name);
    let ends = |i: u64| format!("the file ends inside element \"{name}\" (item {i})");
    let mut line = Vec::new();
    for i in 0..el.count {
        match enc {
            Encoding::Ascii => {
                line.clear();
                let got = body
                    .take(*left)
                    .read_until(b'\n', &mut line)
                    .map_err(|e| format!("cannot read element \"{name}\" ({})", e.kind()))?;
                if got == 0 {
                    return Err(ends(i));
                }
                *left -= got as u64;
            }
            _ => {
                for p in &el.properties {
                    let n = match p.list {
                        None => p.ty.size() as u64,
                        Some(lt) => {
                            let mut b = [0u8; 8];
                            let k = lt.size();
                            if (k as u64) > *left || body.read_exact(&mut b[..k]).is_err() {
                                return Err(ends(i));
                            }
                            *left -= k as u64;
                            let count = list_count(&b[..k], lt, enc == Encoding::BinaryBigEndian);
                            count.saturating_mul(p.ty.size() as u64)
                        }
                    };
                    if n > *left {
                        return Err(ends(i));
                    }
                    // Skipped, never allocated: a count from the file is only as good as the
                    // bytes behind it.
                    let skipped = std::io::copy(&mut body.take(n), &mut std::io::sink())
                        .map_err(|e| format!("cannot read element \"{name}\" ({})", e.kind()))?;
                    if skipped != n {
                        return Err(ends(i));
                    }
                    *left -= n;
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
        let props = std::mem::take(&mut self.props);
        let result = (|| {
            for _ in 0..n {
                let base = rows.len();
                rows.resize(base + row_len, 0);
                let p = match self.encoding {
                    Encoding::Ascii => self.ascii_vertex(&props, &mut rows[base..], &mut val)?,
                    _ => self.binary_vertex(&props, &mut rows[base..], &mut val)?,
                };
                xyz.push(p);
                self.read_so_far += 1;
                self.remaining -= 1;
            }
            if self.remaining == 0 && n > 0 {
                self.check_end()?;
            }
            Ok(n)
        })();
        self.props = props;
        result
    }
}

impl PlySource {
    /// Decodes one text line of properties into `row`; returns the position.
    fn ascii_vertex(
        &mut self,
        props: &[Prop],
        row: &mut [u8],
        val: &mut [u8; 8],
    ) -> Result<[f64; 3]> {
        self.line.clear();
        let got = (&mut self.reader)
            .take(self.left)
            .read_line(&mut self.line)
            .map_err(|e| {
                self.fault(format!(
                    "the line is not text ({})",
                    if e.kind() == std::io::ErrorKind::InvalidData {
                        "it holds bytes that are not UTF-8".to_string()
                    } else {
                        e.kind().to_string()
                    }
                ))
            })?;
        if got == 0 {
            return Err(self.truncated());
        }
        self.left -= got as u64;
        let line = std::mem::take(&mut self.line);
        let mut tokens = line.split_ascii_whitespace();
        let mut p = [0f64; 3];
        for prop in props {
            if prop.list.is_some() {
                let token = tokens.next().unwrap_or("");
                let Ok(len) = token.parse::<u64>() else {
                    return Err(self.fault(format!(
                        "list \"{}\" has an item count \"{}\" that is not a whole number",
                        shown(&prop.name),
                        shown(token)
                    )));
                };
                // Items are taken one by one from this line: a count beyond them ends at once.
                let mut taken = 0u64;
                while taken < len && tokens.next().is_some() {
                    taken += 1;
                }
                if taken < len {
                    return Err(self.fault(format!(
                        "list \"{}\" announces {len} items but the line holds only {taken}",
                        shown(&prop.name)
                    )));
                }
                continue;
            }
            let Some(token) = tokens.next() else {
                return Err(self.fault(format!(
                    "the line has no value for property \"{}\"",
                    shown(&prop.name)
                )));
            };
            let Some(v) = encode_ascii(token, prop.ty, val) else {
                return Err(self.fault(format!(
                    "property \"{}\" has a value \"{}\" that is not a {} number",
                    shown(&prop.name),
                    shown(token),
                    prop.ty.name()
                )));
            };
            match prop.target {
                Target::Position(a) => p[a] = v,
                Target::Attr(off) => {
                    let s = prop.ty.size();
                    row[off..off + s].copy_from_slice(&val[..s]);
                }
                Target::Skip => {}
            }
        }
        let extra = tokens.count();
        self.line = line;
        if extra > 0 {
            return Err(self.fault(format!(
                "the line holds {extra} values more than the header's {} properties",
                props.len()
            )));
        }
        Ok(p)
    }

    /// Decodes one binary vertex into `row`; returns the position.
    fn binary_vertex(
        &mut self,
        props: &[Prop],
        row: &mut [u8],
        val: &mut [u8; 8],
    ) -> Result<[f64; 3]> {
        let big = self.encoding == Encoding::BinaryBigEndian;
        let mut p = [0f64; 3];
        for prop in props {
            let s = prop.ty.size();
            if let Some(lt) = prop.list {
                self.fill(lt.size() as u64)?;
                let len = list_count(&self.scratch, lt, big);
                let bytes = len.saturating_mul(s as u64);
                if bytes > self.left {
                    return Err(self.fault(format!(
                        "list \"{}\" announces {len} items, more than the {} bytes left in the file",
                        shown(&prop.name),
                        self.left
                    )));
                }
                // Skipped, never allocated.
                let skipped =
                    std::io::copy(&mut (&mut self.reader).take(bytes), &mut std::io::sink())
                        .map_err(|_| self.truncated())?;
                if skipped != bytes {
                    return Err(self.truncated());
                }
                self.left -= bytes;
                continue;
            }
            self.fill(s as u64)?;
            let v = read_binary(&self.scratch, prop.ty, big, val);
            match prop.target {
                Target::Position(a) => p[a] = v,
                Target::Attr(off) => row[off..off + s].copy_from_slice(&val[..s]),
                Target::Skip => {}
            }
        }
        Ok(p)
    }
}
