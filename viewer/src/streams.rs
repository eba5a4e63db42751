//! The per-point streams a node feeds the GPU beside positions and colours
//! (`PointStream::Normals`, `PointStream::Radius`), made when the node is loaded.
//!
//! - Normals: one u32 a point, SPEC.md's `oct16` (U in the low 16 bits, V in the high;
//!   `unpack2x16unorm` in WGSL gives U/65535, V/65535), 0 for a point without a normal.
//! - Radius: one f32 a point, its stored `radius` in real units (0 where the dataset stores
//!   none or the value is not a finite positive number). Where the LOD stopped at the point's
//!   node, a pipeline draws at least the node's spacing (SPEC.md section 4: a point of an
//!   inner node stands for the points its descendants add); `drawn_radius` in frame.wgsl
//!   applies it with the LOD of each frame, so refining a node shrinks what its points drew.

use crate::pipelines::PointStream;
use strata_format::{AttrType, NodeColumns, RowLayout, oct16_encode};

/// Where a dataset keeps what the streams are made from.
#[derive(Debug, Clone, Copy, Default)]
pub(crate) struct StreamSource {
    normal: Option<(usize, NormalKind)>,
    radius: Option<(usize, AttrType)>,
}

/// How a dataset stores its normals.
#[derive(Debug, Clone, Copy)]
pub(crate) enum NormalKind {
    Oct16,
    Floats(AttrType),
}

/// The dataset's `normal` attribute and how it is stored, where it has a usable one.
pub(crate) fn normal_attribute(layout: &RowLayout) -> Option<(usize, NormalKind)> {
    layout.index_of("normal").and_then(|i| {
        let a = &layout.attributes[i];
        if a.is_oct16() {
            Some((i, NormalKind::Oct16))
        } else if a.count == 3 && a.ty.is_float() && a.encoding.is_none() {
            Some((i, NormalKind::Floats(a.ty)))
        } else {
            None
        }
    })
}

impl StreamSource {
    pub fn of(layout: &RowLayout) -> Self {
        let normal = normal_attribute(layout);
        let radius = layout
            .index_of("radius")
            .filter(|&i| layout.attributes[i].count == 1 && layout.attributes[i].ty.is_float())
            .map(|i| (i, layout.attributes[i].ty));
        StreamSource { normal, radius }
    }

    pub fn has_normals(&self) -> bool {
        self.normal.is_some()
    }

    /// The streams of a node of `cols.count` points.
    pub fn streams(&self, layout: &RowLayout, cols: &NodeColumns) -> Vec<(PointStream, Vec<u8>)> {
        let n = cols.count;
        let mut normals = Vec::with_capacity(n * 4);
        match self.normal {
            Some((i, NormalKind::Oct16)) => {
                // Stored as the GPU reads it: U then V, little-endian.
                normals.extend_from_slice(&cols.attribute(layout, i)[..n * 4]);
            }
            Some((i, NormalKind::Floats(ty))) => {
                let col = cols.attribute(layout, i);
                let s = ty.size();
                for p in 0..n {
                    let v: [f64; 3] = std::array::from_fn(|k| ty.read_f64(&col[(p * 3 + k) * s..]));
                    let [u, w] = oct16_encode(v);
                    normals.extend_from_slice(&(u as u32 | (w as u32) << 16).to_le_bytes());
                }
            }
            None => normals.resize(n * 4, 0),
        }
        let mut radii = Vec::with_capacity(n * 4);
        for p in 0..n {
            let stored = self.radius.map_or(0.0, |(i, ty)| {
                let s = ty.size();
                ty.read_f64(&cols.attribute(layout, i)[p * s..(p + 1) * s]) as f32
            });
            // A damaged value (NaN, infinite, negative) is no radius: the spacing rule holds.
            let stored = if stored.is_finite() {
                stored.max(0.0)
            } else {
                0.0
            };
            radii.extend_from_slice(&stored.to_le_bytes());
        }
        vec![
            (PointStream::Normals, normals),
            (PointStream::Radius, radii),
        ]
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use strata_format::{Attribute, encode_node, oct16_decode};

    fn columns(layout: &RowLayout, rows: &[u8]) -> NodeColumns {
        let (payload, crc) = encode_node(rows, layout);
        let n = rows.len() / layout.stride;
        strata_format::decode_node(&payload, n, crc, layout).expect("decode")
    }

    #[test]
    fn normals_pass_through_and_radii_are_the_stored_ones() {
        let layout = RowLayout::new(vec![
            Attribute::oct16_normal(),
            Attribute::new("radius", AttrType::F32, 1),
        ]);
        let mut rows = Vec::new();
        for (n, r) in [
            ([0.0, 0.0, 1.0], 0.05f64),
            ([0.0, 0.0, 0.0], 0.5),
            ([0.0; 3], f64::NAN),
        ] {
            rows.extend([0u8; 12]);
            let [u, v] = oct16_encode(n);
            rows.extend(u.to_le_bytes());
            rows.extend(v.to_le_bytes());
            rows.extend((r as f32).to_le_bytes());
        }
        let cols = columns(&layout, &rows);
        let streams = StreamSource::of(&layout).streams(&layout, &cols);
        let (_, normals) = &streams[0];
        let raw = |p: usize| {
            let w = u32::from_le_bytes(normals[p * 4..p * 4 + 4].try_into().expect("4 bytes"));
            [(w & 0xffff) as u16, (w >> 16) as u16]
        };
        let up = oct16_decode(raw(0)).expect("a normal");
        assert!(up[2] > 0.9999, "{up:?}");
        assert_eq!(raw(1), [0, 0], "no normal stays none");
        let (_, radii) = &streams[1];
        let r = |p: usize| f32::from_le_bytes(radii[p * 4..p * 4 + 4].try_into().expect("4"));
        assert_eq!(r(0), 0.05);
        assert_eq!(r(1), 0.5);
        assert_eq!(r(2), 0.0, "a damaged radius is none");
    }

    #[test]
    fn without_normals_or_radii_points_get_none() {
        let layout = RowLayout::new(vec![Attribute::new("intensity", AttrType::U16, 1)]);
        let rows = [0u8; 14 * 3];
        assert_eq!(layout.stride, 14);
        let cols = columns(&layout, &rows);
        let src = StreamSource::of(&layout);
        assert!(!src.has_normals());
        let streams = src.streams(&layout, &cols);
        assert!(streams[0].1.iter().all(|b| *b == 0));
        assert!(streams[1].1.iter().all(|b| *b == 0));
    }
}
