use serde::{Deserialize, Serialize};

/// The scalar type of one attribute component, stored little-endian.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum AttrType {
    U8,
    I8,
    U16,
    I16,
    U32,
    I32,
    U64,
    I64,
    F32,
    F64,
}

impl AttrType {
    pub fn size(self) -> usize {
        match self {
            AttrType::U8 | AttrType::I8 => 1,
            AttrType::U16 | AttrType::I16 => 2,
            AttrType::U32 | AttrType::I32 | AttrType::F32 => 4,
            AttrType::U64 | AttrType::I64 | AttrType::F64 => 8,
        }
    }

    pub fn name(self) -> &'static str {
        match self {
            AttrType::U8 => "u8",
            AttrType::I8 => "i8",
            AttrType::U16 => "u16",
            AttrType::I16 => "i16",
            AttrType::U32 => "u32",
            AttrType::I32 => "i32",
            AttrType::U64 => "u64",
            AttrType::I64 => "i64",
            AttrType::F32 => "f32",
            AttrType::F64 => "f64",
        }
    }

    pub fn is_float(self) -> bool {
        matches!(self, AttrType::F32 | AttrType::F64)
    }

    /// Reads one component from little-endian bytes as f64 (for display and statistics).
    pub fn read_f64(self, b: &[u8]) -> f64 {
        match self {
            AttrType::U8 => b[0] as f64,
            AttrType::I8 => b[0] as i8 as f64,
            AttrType::U16 => u16::from_le_bytes([b[0], b[1]]) as f64,
            AttrType::I16 => i16::from_le_bytes([b[0], b[1]]) as f64,
            AttrType::U32 => u32::from_le_bytes([b[0], b[1], b[2], b[3]]) as f64,
            AttrType::I32 => i32::from_le_bytes([b[0], b[1], b[2], b[3]]) as f64,
            AttrType::F32 => f32::from_le_bytes([b[0], b[1], b[2], b[3]]) as f64,
            AttrType::U64 => u64::from_le_bytes(b[..8].try_into().unwrap_or_default()) as f64,
            AttrType::I64 => i64::from_le_bytes(b[..8].try_into().unwrap_or_default()) as f64,
            AttrType::F64 => f64::from_le_bytes(b[..8].try_into().unwrap_or_default()),
        }
    }
}

/// One named per-point attribute: `count` components of type `ty`.
///
/// `scale` and `offset` are carried for attributes whose source stored scaled integers (LAS extra
/// bytes): the stored value is the raw integer; value = offset + scale * raw.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Attribute {
    pub name: String,
    #[serde(rename = "type")]
    pub ty: AttrType,
    pub count: u8,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub scale: Option<Vec<f64>>,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub offset: Option<Vec<f64>>,
    #[serde(default, skip_serializing_if = "String::is_empty")]
    pub description: String,
}

impl Attribute {
    pub fn new(name: &str, ty: AttrType, count: u8) -> Self {
        Attribute {
            name: name.to_string(),
            ty,
            count,
            scale: None,
            offset: None,
            description: String::new(),
        }
    }

    /// Bytes per point.
    pub fn size(&self) -> usize {
        self.ty.size() * self.count as usize
    }
}

/// A fixed-stride row layout for points held in memory: 12 bytes of integer position (x, y, z
/// as i32 LE) followed by every attribute in order. The converter and the readers share it.
#[derive(Debug, Clone, PartialEq)]
pub struct RowLayout {
    pub attributes: Vec<Attribute>,
    /// Byte offset of each attribute inside a row.
    pub offsets: Vec<usize>,
    pub stride: usize,
}

impl RowLayout {
    pub const POSITION_BYTES: usize = 12;

    pub fn new(attributes: Vec<Attribute>) -> Self {
        let mut offsets = Vec::with_capacity(attributes.len());
        let mut at = Self::POSITION_BYTES;
        for a in &attributes {
            offsets.push(at);
            at += a.size();
        }
        RowLayout {
            attributes,
            offsets,
            stride: at,
        }
    }

    pub fn index_of(&self, name: &str) -> Option<usize> {
        self.attributes.iter().position(|a| a.name == name)
    }

    /// Byte range of attribute `name` inside a row.
    pub fn range_of(&self, name: &str) -> Option<std::ops::Range<usize>> {
        self.index_of(name)
            .map(|i| self.offsets[i]..self.offsets[i] + self.attributes[i].size())
    }
}

/// Reads the integer position of a row.
#[inline]
pub fn row_position(row: &[u8]) -> [i32; 3] {
    [
        i32::from_le_bytes([row[0], row[1], row[2], row[3]]),
        i32::from_le_bytes([row[4], row[5], row[6], row[7]]),
        i32::from_le_bytes([row[8], row[9], row[10], row[11]]),
    ]
}
