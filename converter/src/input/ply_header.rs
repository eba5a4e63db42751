//! The PLY header: `ply`, a format line, elements and their properties, `end_header`. Parsed
//! here rather than by a general PLY library because a point cloud reader must refuse what such
//! a library quietly accepts (a property declared twice, two elements of one name, an unknown
//! format version) and must say on which line, in words, without echoing control characters.

use std::collections::HashSet;
use std::io::BufRead;
use strata_format::AttrType;

#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Encoding {
    Ascii,
    BinaryLittleEndian,
    BinaryBigEndian,
}

#[derive(Debug, Clone)]
pub struct PropertyDef {
    pub name: String,
    pub ty: AttrType,
    /// The type of the item count, for list properties.
    pub list: Option<AttrType>,
}

#[derive(Debug, Clone)]
pub struct ElementDef {
    pub name: String,
    pub count: u64,
    pub properties: Vec<PropertyDef>,
    /// The header line that declares it.
    pub line: usize,
}

impl ElementDef {
    /// Bytes of one binary item, when it has no list properties.
    pub fn fixed_size(&self) -> Option<u64> {
        self.properties
            .iter()
            .map(|p| p.list.is_none().then_some(p.ty.size() as u64))
            .sum()
    }
}

#[derive(Debug, Clone)]
pub struct PlyHeader {
    pub encoding: Encoding,
    pub elements: Vec<ElementDef>,
    /// Bytes of the header, up to and including the newline after `end_header`.
    pub len: u64,
}

/// Longest header accepted; a header is text of a few hundred lines at most in practice, and
/// ten thousand properties take a quarter of this.
const MAX_HEADER: u64 = 16 << 20;

/// A file's text shown in a message: control characters (a stray carriage return, an escape)
/// become `?` so the message stays one clean line.
pub fn shown(text: &str) -> String {
    let t: String = text
        .chars()
        .take(40)
        .map(|c| if c.is_control() { '?' } else { c })
        .collect();
    if text.chars().count() > 40 {
        format!("{t}...")
    } else {
        t
    }
}

fn scalar(name: &str) -> Option<AttrType> {
    Some(match name {
        "char" | "int8" => AttrType::I8,
        "uchar" | "uint8" => AttrType::U8,
        "short" | "int16" => AttrType::I16,
        "ushort" | "uint16" => AttrType::U16,
        "int" | "int32" => AttrType::I32,
        "uint" | "uint32" => AttrType::U32,
        "float" | "float32" => AttrType::F32,
        "double" | "float64" => AttrType::F64,
        _ => return None,
    })
}

/// Reads the header from the start of the file; the error names the line and the fault.
pub fn read_header<R: BufRead>(input: &mut R) -> Result<PlyHeader, String> {
    let mut len = 0u64;
    let mut encoding = None;
    let mut elements: Vec<ElementDef> = Vec::new();
    // Names seen so far, of the elements and of the last element's properties: looked up per
    // line, so that a header of many thousands of lines is read in linear time.
    let mut element_names: HashSet<String> = HashSet::new();
    let mut property_names: HashSet<String> = HashSet::new();
    let mut raw = Vec::new();
    let mut n = 0usize;
    loop {
        n += 1;
        raw.clear();
        let got = std::io::Read::take(&mut *input, MAX_HEADER - len + 1)
            .read_until(b'\n', &mut raw)
            .map_err(|e| format!("cannot read the PLY header ({})", e.kind()))?;
        len += got as u64;
        if len > MAX_HEADER {
            return Err(format!(
                "the PLY header is longer than {} MiB without an \"end_header\" line",
                MAX_HEADER >> 20
            ));
        }
        if n == 1 && raw.starts_with(b"ply\r") && raw.get(4) != Some(&b'\n') {
            return Err(
                "malformed PLY header, line 1: its lines end in carriage returns alone (old Mac line endings), not in newlines".into(),
            );
        }
        if got == 0 || raw.last() != Some(&b'\n') {
            return Err(format!(
                "the PLY header ends at line {n} without an \"end_header\" line"
            ));
        }
        raw.pop();
        if raw.last() == Some(&b'\r') {
            raw.pop();
        }
        if raw.contains(&b'\r') {
            return Err(format!(
                "malformed PLY header, line {n}: it holds carriage returns inside it (lines must end in a newline, not in a carriage return alone)"
            ));
        }
        if n == 1 {
            if raw != b"ply" {
                return Err("not a PLY file (it does not start with the line \"ply\")".into());
            }
            continue;
        }
        let Ok(text) = std::str::from_utf8(&raw) else {
            return Err(format!("malformed PLY header, line {n}: it is not text"));
        };
        let words: Vec<&str> = text.split_ascii_whitespace().collect();
        let at = |what: String| Err(format!("malformed PLY header, line {n}: {what}"));
        match words.as_slice() {
            [] | ["comment", ..] | ["obj_info", ..] => {}
            ["format", enc, version] => {
                if encoding.is_some() {
                    return at("a second \"format\" line".into());
                }
                encoding = Some(match *enc {
                    "ascii" => Encoding::Ascii,
                    "binary_little_endian" => Encoding::BinaryLittleEndian,
                    "binary_big_endian" => Encoding::BinaryBigEndian,
                    other => {
                        return at(format!(
                            "unknown format \"{}\" (ascii, binary_little_endian or binary_big_endian)",
                            shown(other)
                        ));
                    }
                });
                if *version != "1.0" {
                    return at(format!(
                        "PLY version {} is not supported (1.0 is)",
                        shown(version)
                    ));
                }
            }
            ["format", ..] => {
                return at("the format line must be \"format ENCODING 1.0\"".into());
            }
            ["element", name, count] => {
                let Ok(count) = count.parse::<u64>() else {
                    return at(format!(
                        "element \"{}\" has a count \"{}\" that is not a whole number",
                        shown(name),
                        shown(count)
                    ));
                };
                if !element_names.insert(name.to_string()) {
                    return at(format!(
                        "a second element named \"{}\" (element names must differ)",
                        shown(name)
                    ));
                }
                property_names.clear();
                elements.push(ElementDef {
                    name: name.to_string(),
                    count,
                    properties: Vec::new(),
                    line: n,
                });
            }
            ["property", rest @ ..] => {
                let Some(element) = elements.last_mut() else {
                    return at("a property before any element".into());
                };
                let (ty, list, name) = match rest {
                    ["list", count_ty, item_ty, name] => {
                        let count_ty = scalar(count_ty).filter(|t| !t.is_float());
                        let item = scalar(item_ty);
                        match (count_ty, item) {
                            (Some(c), Some(t)) => (t, Some(c), *name),
                            _ => {
                                return at(format!(
                                    "list property \"{}\" needs a whole-number count type and an item type",
                                    shown(name)
                                ));
                            }
                        }
                    }
                    [ty, name] => match scalar(ty) {
                        Some(t) => (t, None, *name),
                        None => {
                            return at(format!(
                                "property \"{}\" has unknown type \"{}\"",
                                shown(name),
                                shown(ty)
                            ));
                        }
                    },
                    _ => return at("a property line must be \"property TYPE NAME\"".into()),
                };
                if !property_names.insert(name.to_string()) {
                    return at(format!(
                        "property \"{}\" is declared twice in element \"{}\"",
                        shown(name),
                        shown(&element.name)
                    ));
                }
                element.properties.push(PropertyDef {
                    name: name.to_string(),
                    ty,
                    list,
                });
            }
            ["end_header"] => {
                let Some(encoding) = encoding else {
                    return at("the header ends without a \"format\" line".into());
                };
                return Ok(PlyHeader {
                    encoding,
                    elements,
                    len,
                });
            }
            [word, ..] => return at(format!("unknown keyword \"{}\"", shown(word))),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn parse(text: &str) -> Result<PlyHeader, String> {
        read_header(&mut std::io::Cursor::new(text.as_bytes().to_vec()))
    }

    const XYZ: &str = "property float x\nproperty float y\nproperty float z\n";

    #[test]
    fn a_valid_header_gives_its_elements_and_length() {
        let text = format!(
            "ply\nformat binary_little_endian 1.0\ncomment c\nelement vertex 3\n{XYZ}property list uchar int l\nend_header\n"
        );
        let h = parse(&text).expect("valid");
        assert_eq!(h.encoding, Encoding::BinaryLittleEndian);
        assert_eq!(h.elements[0].count, 3);
        assert_eq!(h.elements[0].properties.len(), 4);
        assert_eq!(h.len, text.len() as u64);
    }

    #[test]
    fn faults_are_refused_naming_their_line() {
        let cases = [
            (
                format!(
                    "ply\nformat ascii 1.0\nelement vertex 1\n{XYZ}property float x\nend_header\n"
                ),
                "line 7: property \"x\" is declared twice",
            ),
            (
                format!(
                    "ply\nformat ascii 1.0\nelement vertex 1\n{XYZ}element vertex 1\n{XYZ}end_header\n"
                ),
                "line 7: a second element named \"vertex\"",
            ),
            (
                format!("ply\nformat ascii 2.0\nelement vertex 1\n{XYZ}end_header\n"),
                "line 2: PLY version 2.0 is not supported",
            ),
            (
                format!("ply\nformat ascii 1.0\nelement vertex -1\n{XYZ}end_header\n"),
                "line 3: element \"vertex\" has a count \"-1\"",
            ),
            (
                format!(
                    "ply\nformat ascii 1.0\nelement vertex 1\n{XYZ}property list float int l\nend_header\n"
                ),
                "line 7: list property \"l\" needs a whole-number count type",
            ),
            (
                "ply\rformat ascii 1.0\relement vertex 1\rend_header\r".to_string(),
                "carriage returns alone",
            ),
            (
                "ply\nformat ascii 1.0\r\relement vertex 1\nend_header\n".to_string(),
                "line 2: it holds carriage returns",
            ),
        ];
        for (text, want) in cases {
            let err = parse(&text).expect_err(want);
            assert!(err.contains(want), "{want:?} not in {err:?}");
            assert!(!err.chars().any(|c| c.is_control()), "{err:?}");
        }
    }
}
