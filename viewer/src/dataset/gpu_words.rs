//! A decoded node as the GPU takes it: per point its position relative to the anchor and its
//! colour word, and the attribute word the filters read (`GpuNode`).

use super::{ColourWord, GREY, GpuNode, StreamDataset};
use crate::marks::{Marks, RETURN_ABOVE_15};
use crate::streams::NormalKind;
use glam::DVec3;
use strata_format::{NodeColumns, NodeInfo, oct16_decode};

impl StreamDataset {
    pub(super) fn to_gpu(
        &self,
        info: &NodeInfo,
        cols: &NodeColumns,
        colours: ColourWord,
        marks: &Marks,
    ) -> GpuNode {
        let hidden = marks.words(&self.layout, cols);
        let n = cols.count;
        let m = &self.metadata;
        let base = DVec3::from_array(m.offset) - self.anchor;
        let scale = DVec3::from_array(m.scale);
        let column = |c: usize| &cols.bytes[c * n * 4..(c + 1) * n * 4];
        let (xs, ys, zs) = (column(0), column(1), column(2));
        let read_i32 = |b: &[u8], i: usize| {
            i32::from_le_bytes([b[i * 4], b[i * 4 + 1], b[i * 4 + 2], b[i * 4 + 3]]) as f64
        };
        let c = &self.colour;
        let rgb = c.rgb.map(|(i, ty)| (cols.attribute(&self.layout, i), ty));
        let intensity = c
            .intensity
            .map(|(i, ty)| (cols.attribute(&self.layout, i), ty));
        let class = c
            .classification
            .map(|(i, ty)| (cols.attribute(&self.layout, i), ty));
        let returns = c
            .return_number
            .map(|(i, ty)| (cols.attribute(&self.layout, i), ty));
        let normals = match colours {
            ColourWord::Normal => c
                .normal
                .map(|(i, kind)| (cols.attribute(&self.layout, i), kind)),
            ColourWord::Stored => None,
        };
        let variation = c
            .variation
            .map(|(i, ty)| (cols.attribute(&self.layout, i), ty));
        let mut points = Vec::with_capacity(n);
        let mut attributes = Vec::with_capacity(n);
        for p in 0..n {
            let x = base.x + scale.x * read_i32(xs, p);
            let y = base.y + scale.y * read_i32(ys, p);
            let z = base.z + scale.z * read_i32(zs, p);
            let colour = match (normals, rgb) {
                (Some((col, kind)), _) => normal_colour(col, kind, p),
                (None, Some((col, ty))) => {
                    let s = ty.size();
                    let ch = |k: usize| {
                        let v = ty.read_f64(&col[(p * 3 + k) * s..(p * 3 + k + 1) * s]) as u32;
                        (v >> c.rgb_shift).min(255)
                    };
                    ch(0) | (ch(1) << 8) | (ch(2) << 16) | (255 << 24)
                }
                (None, None) => GREY,
            };
            let alpha = variation.map_or(255, |(col, ty)| {
                let s = ty.size();
                let v = ty.read_f64(&col[p * s..(p + 1) * s]) / c.variation_max;
                // NaN becomes 0.
                (v.clamp(0.0, 1.0) * 255.0).round() as u32
            });
            let colour = (colour & 0x00ff_ffff) | (alpha << 24);
            // Raw, so that filters compare stored values; colouring scales it on the GPU.
            let inten = intensity.map_or(0, |(col, ty)| {
                let s = ty.size();
                ty.read_f64(&col[p * s..(p + 1) * s]).clamp(0.0, 65535.0) as u32
            });
            let ret = returns.map_or(0, |(col, ty)| {
                let s = ty.size();
                match ty.read_f64(&col[p * s..(p + 1) * s]) as u32 {
                    r @ 0..=15 => r,
                    _ => 15 | (RETURN_ABOVE_15 >> 24),
                }
            });
            let cls = class.map_or(0, |(col, ty)| {
                let s = ty.size();
                ty.read_f64(&col[p * s..(p + 1) * s]) as u32 & 0xff
            });
            points.push([
                (x as f32).to_bits(),
                (y as f32).to_bits(),
                (z as f32).to_bits(),
                colour,
            ]);
            attributes.push(inten | (cls << 16) | (ret << 24) | hidden[p]);
        }
        let (_, edge) = self.node_cube(info.key);
        let sampling = super::sampling::sampling_spacing(&points, edge);
        GpuNode {
            key: info.key,
            colours,
            marks: marks.clone(),
            points,
            attributes,
            streams: self.streams.streams(&self.layout, cols),
            bytes_read: info.size as u64,
            sampling,
        }
    }
}

/// Point `p`'s normal as a colour, `(n * 0.5 + 0.5) * 255` (grey without one).
fn normal_colour(col: &[u8], kind: NormalKind, p: usize) -> u32 {
    let n = match kind {
        NormalKind::Oct16 => oct16_decode([
            u16::from_le_bytes([col[p * 4], col[p * 4 + 1]]),
            u16::from_le_bytes([col[p * 4 + 2], col[p * 4 + 3]]),
        ]),
        NormalKind::Floats(ty) => {
            let s = ty.size();
            let v: [f64; 3] = std::array::from_fn(|k| ty.read_f64(&col[(p * 3 + k) * s..]));
            let l = (v[0] * v[0] + v[1] * v[1] + v[2] * v[2]).sqrt();
            (l > 0.0 && l.is_finite()).then(|| v.map(|c| c / l))
        }
    };
    match n {
        Some(n) => {
            let ch = |c: f64| ((c * 0.5 + 0.5) * 255.0).round().clamp(0.0, 255.0) as u32;
            ch(n[0]) | (ch(n[1]) << 8) | (ch(n[2]) << 16) | (255 << 24)
        }
        None => GREY,
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use strata_format::{AttrType, oct16_encode};

    #[test]
    fn normals_colour_as_rgb_and_points_without_one_grey() {
        let rgb = |c: u32| [c & 0xff, (c >> 8) & 0xff, (c >> 16) & 0xff];
        let oct: Vec<u8> = [
            oct16_encode([0.0, 0.0, 1.0]),
            oct16_encode([1.0, 0.0, 0.0]),
            [0, 0],
        ]
        .iter()
        .flat_map(|[u, v]| [u.to_le_bytes(), v.to_le_bytes()].concat())
        .collect();
        // Within one step: the octahedral grid puts a pole a hair off its axis.
        let near = |got: [u32; 3], want: [u32; 3]| {
            let close = got.iter().zip(want).all(|(g, w)| g.abs_diff(w) <= 1);
            assert!(close, "{got:?} is not {want:?}");
        };
        near(
            rgb(normal_colour(&oct, NormalKind::Oct16, 0)),
            [128, 128, 255],
        );
        near(
            rgb(normal_colour(&oct, NormalKind::Oct16, 1)),
            [255, 128, 128],
        );
        assert_eq!(normal_colour(&oct, NormalKind::Oct16, 2), GREY);
        // Three floats, not of unit length: normalised first; all zero is no normal.
        let floats: Vec<u8> = [0.0f32, -3.0, 0.0, 0.0, 0.0, 0.0]
            .iter()
            .flat_map(|v| v.to_le_bytes())
            .collect();
        let f = NormalKind::Floats(AttrType::F32);
        assert_eq!(rgb(normal_colour(&floats, f, 0)), [128, 0, 128]);
        assert_eq!(normal_colour(&floats, f, 1), GREY);
    }
}
