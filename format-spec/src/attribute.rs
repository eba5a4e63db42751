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
    /// IEEE 754 binary16 (half precision).
    F16,
    F32,
    F64,
}

impl AttrType {
    pub fn size(self) -> usize {
        match self {
            AttrType::U8 | AttrType::I8 => 1,
            AttrType::U16 | AttrType::I16 | AttrType::F16 => 2,
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
            AttrType::F16 => "f16",
            AttrType::F32 => "f32",
            AttrType::F64 => "f64",
        }
    }

    pub fn is_float(self) -> bool {
        matches!(self, AttrType::F16 | AttrType::F32 | AttrType::F64)
    }

    /// Reads one component from little-endian bytes as f64 (for display and statistics).
    pub fn read_f64(self, b: &[u8]) -> f64 {
        match self {
            AttrType::U8 => b[0] as f64,
            AttrType::I8 => b[0] as i8 as f64,
            AttrType::U16 => u16::from_le_bytes([b[0], b[1]]) as f64,
            AttrType::I16 => i16::from_le_bytes([b[0], b[1]]) as f64,
            AttrType::F16 => half::f16::from_le_bytes([b[0], b[1]]).to_f64(),
            AttrType::U32 => u32::from_le_bytes([b[0], b[1], b[2], b[3]]) as f64,
            AttrType::I32 => i32::from_le_bytes([b[0], b[1], b[2], b[3]]) as f64,
            AttrType::F32 => f32::from_le_bytes([b[0], b[1], b[2], b[3]]) as f64,
            AttrType::U64 => u64::from_le_bytes(b[..8].try_into().unwrap_or_default()) as f64,
            AttrType::I64 => i64::from_le_bytes(b[..8].try_into().unwrap_or_default()) as f64,
            AttrType::F64 => f64::from_le_bytes(b[..8].try_into().unwrap_or_default()),
        }
    }

    /// One component of a 64-bit integer type exactly (`read_f64` rounds past 2^53); `None`
    /// for every other type, which a double holds whole.
    pub fn read_wide_integer(self, b: &[u8]) -> Option<i128> {
        let word = b.get(..8)?.try_into().ok()?;
        match self {
            AttrType::U64 => Some(i128::from(u64::from_le_bytes(word))),
            AttrType::I64 => Some(i128::from(i64::from_le_bytes(word))),
            _ => None,
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
    /// How the raw components encode the value, where they are not the value itself
    /// (`"oct16"`: a unit vector as two u16, SPEC.md section 4). A reader refuses an encoding it
    /// does not know.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub encoding: Option<String>,
    /// What a time counts from, where the input said (`gps_time` of a LAS file: its global
    /// encoding's bit 0). Two time bases never meet in one attribute.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub time_base: Option<TimeBase>,
    /// The raw value that stands for "no value" (LAS extra bytes' `no_data`, descriptor
    /// option bit 0), per component as the descriptor's eight bytes hold it (an integer type's
    /// value, a float's bits), read as little-endian u64: kept exact for exports to state again.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub no_data: Option<Vec<u64>>,
}

/// What the values of a time attribute count from (SPEC.md section 4).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum TimeBase {
    /// Seconds into the GPS week (LAS global encoding bit 0 clear).
    GpsWeek,
    /// GPS seconds minus 1e9 (LAS global encoding bit 0 set).
    GpsAdjustedStandard,
}

impl TimeBase {
    pub fn name(self) -> &'static str {
        match self {
            TimeBase::GpsWeek => "GPS week time",
            TimeBase::GpsAdjustedStandard => "adjusted standard GPS time",
        }
    }
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
            encoding: None,
            time_base: None,
            no_data: None,
        }
    }

    /// The dataset's unit normal: two u16 in the octahedral encoding.
    pub fn oct16_normal() -> Self {
        Attribute {
            encoding: Some(OCT16.to_string()),
            description: "unit normal, octahedral encoding".into(),
            ..Attribute::new("normal", AttrType::U16, 2)
        }
    }

    pub fn is_oct16(&self) -> bool {
        self.encoding.as_deref() == Some(OCT16) && self.ty == AttrType::U16 && self.count == 2
    }

    /// Bytes per point.
    pub fn size(&self) -> usize {
        self.ty.size() * self.count as usize
    }

    /// Component `c`'s scale and offset (value = offset + scale · raw): 1 and 0 where none
    /// is given.
    pub fn scaling(&self, c: usize) -> (f64, f64) {
        let at = |v: &Option<Vec<f64>>, or: f64| {
            v.as_ref().and_then(|v| v.get(c)).copied().unwrap_or(or)
        };
        (at(&self.scale, 1.0), at(&self.offset, 0.0))
    }
}

/// Attributes a dataset holds at most: far more than any scanner records, few enough that
/// per-attribute lookups stay cheap on a hostile file declaring thousands.
pub const MAX_ATTRIBUTES: usize = 1024;

/// The encoding name of octahedral unit vectors in two u16.
pub const OCT16: &str = "oct16";

/// Encodes a direction as octahedral 2 x u16 (SPEC.md section 4). A zero or non-finite vector
/// gives `[0, 0]`, which the format reserves for "no normal"; no direction encodes to it.
pub fn oct16_encode(n: [f64; 3]) -> [u16; 2] {
    let l1 = n[0].abs() + n[1].abs() + n[2].abs();
    if !(l1 > 0.0 && l1.is_finite()) {
        return [0, 0];
    }
    let (mut u, mut v) = (n[0] / l1, n[1] / l1);
    if n[2] < 0.0 {
        let (pu, pv) = (u, v);
        u = (1.0 - pv.abs()) * if pu >= 0.0 { 1.0 } else { -1.0 };
        v = (1.0 - pu.abs()) * if pv >= 0.0 { 1.0 } else { -1.0 };
    }
    let grid = |t: f64| (t.clamp(-1.0, 1.0) + 1.0) * 0.5 * 65535.0;
    let (gu, gv) = (grid(u), grid(v));
    // Of the grid points around (u, v), the nearest whose decoded z has the sign of n.z:
    // rounded alone, a horizontal normal may land past the octahedron's edge and decode facing
    // down by 1.5e-5, and an upward normal must never face down (`--orient up`). The grid has
    // no point on the edge where an axis meets it, (±1, 0), so the ring one step out is tried
    // too.
    // Only within a few grid steps of the edge can rounding cross it.
    let code = if (1.0 - u.abs() - v.abs()).abs() <= 4.0 / 65535.0 {
        nearest_on_side(gu, gv, n[2] >= 0.0)
    } else {
        [gu.round() as u16, gv.round() as u16]
    };
    // The corner (-1, -1) is the -z pole, as are the other three corners: use another.
    if code == [0, 0] { [65535, 65535] } else { code }
}

/// Of the grid points around grid position (gu, gv), the nearest whose decoded z is on the
/// `upward` side (z >= 0) or the other; the rounded one if none is.
fn nearest_on_side(gu: f64, gv: f64, upward: bool) -> [u16; 2] {
    let side = |cu: f64, cv: f64| {
        let z = 1.0 - (cu / 65535.0 * 2.0 - 1.0).abs() - (cv / 65535.0 * 2.0 - 1.0).abs();
        (z >= 0.0) == upward
    };
    let rounded = [gu.round() as u16, gv.round() as u16];
    if side(gu.round(), gv.round()) {
        return rounded;
    }
    let mut best = (rounded, f64::INFINITY);
    let around = |g: f64| [g.floor() - 1.0, g.floor(), g.ceil(), g.ceil() + 1.0];
    for cu in around(gu).map(|c| c.clamp(0.0, 65535.0)) {
        for cv in around(gv).map(|c| c.clamp(0.0, 65535.0)) {
            let gap = (cu - gu).powi(2) + (cv - gv).powi(2);
            if gap < best.1 && side(cu, cv) {
                best = ([cu as u16, cv as u16], gap);
            }
        }
    }
    best.0
}

/// Decodes octahedral 2 x u16 to a unit vector; `None` for `[0, 0]` (no normal).
pub fn oct16_decode(raw: [u16; 2]) -> Option<[f64; 3]> {
    if raw == [0, 0] {
        return None;
    }
    let u = raw[0] as f64 / 65535.0 * 2.0 - 1.0;
    let v = raw[1] as f64 / 65535.0 * 2.0 - 1.0;
    let z = 1.0 - u.abs() - v.abs();
    let (x, y) = if z < 0.0 {
        (
            (1.0 - v.abs()) * if u >= 0.0 { 1.0 } else { -1.0 },
            (1.0 - u.abs()) * if v >= 0.0 { 1.0 } else { -1.0 },
        )
    } else {
        (u, v)
    };
    let l = (x * x + y * y + z * z).sqrt();
    Some([x / l, y / l, z / l])
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

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn wide_integers_read_whole_to_their_ends() {
        let read = |ty: AttrType, b: [u8; 8]| ty.read_wide_integer(&b);
        assert_eq!(
            read(AttrType::U64, u64::MAX.to_le_bytes()),
            Some(i128::from(u64::MAX))
        );
        assert_eq!(
            read(AttrType::I64, i64::MIN.to_le_bytes()),
            Some(i128::from(i64::MIN))
        );
        // The double they become is not them: 2^64 and 2^53 + 1 round.
        assert_ne!(u64::MAX as f64 as i128, i128::from(u64::MAX));
        assert_eq!(read(AttrType::F64, 1.5f64.to_le_bytes()), None);
        assert_eq!(AttrType::U64.read_wide_integer(&[0; 4]), None);
    }

    fn angle(a: [f64; 3], b: [f64; 3]) -> f64 {
        let d = a[0] * b[0] + a[1] * b[1] + a[2] * b[2];
        d.clamp(-1.0, 1.0).acos().to_degrees()
    }

    #[test]
    fn oct16_round_trips_within_a_hundredth_of_a_degree() {
        let mut worst: f64 = 0.0;
        let mut seed = 12345u64;
        let mut next = || {
            seed = seed
                .wrapping_mul(6364136223846793005)
                .wrapping_add(1442695040888963407);
            (seed >> 11) as f64 / (1u64 << 53) as f64 * 2.0 - 1.0
        };
        let mut dirs: Vec<[f64; 3]> = (0..20000).map(|_| [next(), next(), next()]).collect();
        // The poles, the equator and the octahedron's edges, where the folding changes sides.
        for s in [1.0, -1.0] {
            dirs.extend([
                [0.0, 0.0, s],
                [s, 0.0, 0.0],
                [0.0, s, 0.0],
                [s, s, 0.0],
                [s, -s, 0.0],
            ]);
            dirs.extend([[s, 0.0, -1.0], [0.0, s, -1.0], [s, 1e-9, -1.0]]);
        }
        for d in dirs {
            let l = (d[0] * d[0] + d[1] * d[1] + d[2] * d[2]).sqrt();
            if l < 1e-6 {
                continue;
            }
            let n = d.map(|c| c / l);
            let raw = oct16_encode(n);
            assert_ne!(raw, [0, 0], "{n:?} encoded as the no-normal value");
            let back = oct16_decode(raw).expect("a normal");
            worst = worst.max(angle(n, back));
        }
        assert!(worst < 0.01, "worst round trip {worst} degrees");
        // Near and on the equator, a normal keeps the side of it that it is on.
        for i in 0..20000 {
            let a = i as f64 * 0.000_314_159;
            for z in [0.0f64, 1e-7, 1e-5, -1e-7, -1e-5] {
                let l = (1.0 + z * z).sqrt();
                let n = [a.cos() / l, a.sin() / l, z / l];
                let back = oct16_decode(oct16_encode(n)).expect("a normal");
                assert!(
                    (back[2] >= 0.0) == (z >= 0.0),
                    "{n:?} decodes as {back:?}, on the other side"
                );
                assert!(angle(n, back) < 0.01, "{n:?} decodes as {back:?}");
            }
        }
        assert_eq!(oct16_encode([0.0; 3]), [0, 0]);
        assert_eq!(oct16_encode([f64::NAN, 0.0, 1.0]), [0, 0]);
        assert_eq!(oct16_decode([0, 0]), None);
    }

    #[test]
    fn f16_reads_as_its_value() {
        let b = half::f16::from_f64(0.1234).to_le_bytes();
        assert!((AttrType::F16.read_f64(&b) - 0.1234).abs() < 1e-4);
        assert_eq!(AttrType::F16.size(), 2);
    }
}
