//! Picking: the exact stored point under a pixel, read from its node in full precision (not an
//! interpolated pixel of a reconstruction, nor the f32 the GPU draws with).

use crate::ViewerError;
use crate::dataset::StreamDataset;
use crate::pipelines::ViewFrame;
use crate::renderer::SurfacePixel;
use serde::Serialize;
use strata_format::{NodeInfo, NodeKey};

/// One point as stored, found under a pixel.
#[derive(Debug, Clone, Serialize)]
pub struct PickedPoint {
    /// The pixel of the point's splat that was nearest the one asked for.
    pub pixel: [u32; 2],
    /// Linear depth of the point from the camera, in dataset units.
    pub depth: f32,
    pub node: String,
    /// The point's place inside its node.
    pub index: usize,
    /// Real-world coordinates: offset + scale x the stored integers.
    pub position: [f64; 3],
    /// The finest step of the stored coordinates (the dataset's smallest scale): the
    /// resolution of a measure between picked points.
    #[serde(skip)]
    pub step: f64,
    pub attributes: Vec<PickedAttribute>,
}

/// One attribute of a picked point.
#[derive(Debug, Clone, Serialize)]
pub struct PickedAttribute {
    pub name: String,
    /// Its components, scaled where the attribute stores scaled integers.
    pub values: Vec<f64>,
    /// What the value means, where it has a name (ASPRS classes).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub meaning: Option<&'static str>,
    /// The components exactly, where the attribute stores unscaled 64-bit integers, which
    /// `values` rounds (a double keeps 53 bits).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub integers: Option<Vec<serde_json::Number>>,
}

impl PickedPoint {
    /// One line a value, as `strata pick` prints it and the panel shows it.
    pub fn lines(&self) -> Vec<String> {
        let [x, y, z] = self.position;
        // Every digit the stored position has (rounded to its scale already).
        let mut out = vec![format!("x {x}"), format!("y {y}"), format!("z {z}")];
        for a in &self.attributes {
            let values: Vec<String> = match &a.integers {
                Some(exact) => exact.iter().map(ToString::to_string).collect(),
                None => a.values.iter().map(|v| format_value(*v)).collect(),
            };
            let mut line = format!("{} {}", a.name, values.join(" "));
            if let Some(m) = a.meaning {
                line.push_str(&format!(" ({m})"));
            }
            out.push(line);
        }
        out.push(format!("node {} point {}", self.node, self.index));
        out
    }
}

/// `v` rounded to the decimals of a power-of-ten `scale` (0.01: two), so that a stored
/// 849296.45 prints as that rather than as the nearest f64 sum, 849296.4500000001; any other
/// scale leaves it as it is.
pub fn to_decimals(v: f64, scale: f64) -> f64 {
    let d = -scale.log10().round();
    if !(0.0..=12.0).contains(&d) || (10f64.powf(-d) - scale).abs() > scale * 1e-9 {
        return v;
    }
    let f = 10f64.powf(d);
    let r = (v * f).round() / f;
    // Within a millionth of a step, or (for fine scales far from zero) a few units in the
    // last place of `v`, which is all the sum `offset + scale * n` could round by.
    let near = (scale * 1e-6).max(v.abs() * 4.0 * f64::EPSILON);
    if (r - v).abs() <= near { r } else { v }
}

/// Whole numbers without a fraction, others with all the digits they need.
fn format_value(v: f64) -> String {
    if v.fract() == 0.0 && v.abs() < 1e15 {
        format!("{v:.0}")
    } else {
        format!("{v}")
    }
}

/// The ASPRS name of a LAS classification (LAS 1.4, table 17).
pub fn asprs_class_name(class: u8) -> &'static str {
    match class {
        0 => "created, never classified",
        1 => "unclassified",
        2 => "ground",
        3 => "low vegetation",
        4 => "medium vegetation",
        5 => "high vegetation",
        6 => "building",
        7 => "low point (noise)",
        8 => "model key-point",
        9 => "water",
        10 => "rail",
        11 => "road surface",
        12 => "overlap",
        13 => "wire guard (shield)",
        14 => "wire conductor (phase)",
        15 => "transmission tower",
        16 => "wire-structure connector",
        17 => "bridge deck",
        18 => "high noise",
        19 => "overhead structure",
        20 => "ignored ground",
        21 => "snow",
        22 => "temporal exclusion",
        23..=63 => "reserved",
        _ => "user definable",
    }
}

impl StreamDataset {
    /// Point `index` of node `info`, with every stored attribute, read from the dataset.
    pub fn point(&self, info: &NodeInfo, index: usize) -> Result<PickedPoint, ViewerError> {
        let columns = self.read_columns(info)?;
        if index >= columns.count {
            return Err(ViewerError::source(
                self.location(),
                format!(
                    "node {} has {} points, none at {index}",
                    info.key, columns.count
                ),
            ));
        }
        let m = self.metadata();
        let int = columns.position(index);
        let position = std::array::from_fn(|i| {
            to_decimals(m.offset[i] + m.scale[i] * int[i] as f64, m.scale[i])
        });
        let layout = m.row_layout();
        let attributes = layout
            .attributes
            .iter()
            .enumerate()
            .map(|(k, a)| {
                let column = columns.attribute(&layout, k);
                let raw = &column[index * a.size()..(index + 1) * a.size()];
                let values = attribute_values(a, raw);
                let meaning = (a.name == "classification")
                    .then(|| values.first().map(|c| asprs_class_name(*c as u8)))
                    .flatten();
                PickedAttribute {
                    name: a.name.clone(),
                    values,
                    meaning,
                    integers: exact_integers(a, raw),
                }
            })
            .collect();
        Ok(PickedPoint {
            pixel: [0, 0],
            depth: 0.0,
            node: info.key.to_string(),
            index,
            position,
            step: strata_format::finest_step(m.scale),
            attributes,
        })
    }
}

/// The components of one stored value of attribute `a` exactly, where they are unscaled
/// 64-bit integers.
pub fn exact_integers(a: &strata_format::Attribute, raw: &[u8]) -> Option<Vec<serde_json::Number>> {
    if a.scale.is_some() || a.offset.is_some() {
        return None;
    }
    raw.chunks_exact(a.ty.size())
        .map(|b| {
            let v = a.ty.read_wide_integer(b)?;
            u64::try_from(v)
                .map(serde_json::Number::from)
                .or_else(|_| i64::try_from(v).map(serde_json::Number::from))
                .ok()
        })
        .collect()
}

/// The components of one stored value of attribute `a` (its `a.size()` bytes), scaled where
/// the attribute stores scaled integers.
pub fn attribute_values(a: &strata_format::Attribute, raw: &[u8]) -> Vec<f64> {
    // An octahedral normal is shown as the unit vector it stands for (zero: none).
    if a.is_oct16() && raw.len() >= 4 {
        let code = [
            u16::from_le_bytes([raw[0], raw[1]]),
            u16::from_le_bytes([raw[2], raw[3]]),
        ];
        return strata_format::oct16_decode(code)
            .unwrap_or([0.0; 3])
            .to_vec();
    }
    raw.chunks_exact(a.ty.size())
        .enumerate()
        .map(|(c, b)| {
            let (scale, offset) = a.scaling(c);
            offset + scale * a.ty.read_f64(b)
        })
        .collect()
}

/// The drawn pixel nearest `(x, y)` within `radius`, with its depth bits and point index, from a
/// frame's per-pixel (depth bits, global index), `None` for background.
pub fn nearest_drawn(
    pixels: &[Option<(u32, u32)>],
    width: u32,
    height: u32,
    (x, y): (u32, u32),
    radius: u32,
) -> Option<([u32; 2], u32, u32)> {
    // No pixel of the view is farther than its width and height together (and r² stays far
    // from overflowing).
    let r = (radius as i64).min(width as i64 + height as i64);
    let mut best: Option<(i64, u32, [u32; 2], u32)> = None;
    // Only the offsets that land in the view: a radius far beyond it costs nothing more.
    let (x0, y0) = (x as i64, y as i64);
    for dy in (-r).max(-y0)..=r.min(height as i64 - 1 - y0) {
        for dx in (-r).max(-x0)..=r.min(width as i64 - 1 - x0) {
            let (px, py) = (x as i64 + dx, y as i64 + dy);
            if px < 0 || py < 0 || px >= width as i64 || py >= height as i64 {
                continue;
            }
            let d2 = dx * dx + dy * dy;
            if d2 > r * r {
                continue;
            }
            let at = (py as u64 * width as u64 + px as u64) as usize;
            if let Some(Some((depth, index))) = pixels.get(at).copied() {
                // Nearest to the cursor first, then nearest to the eye.
                if best.is_none_or(|b| (d2, depth) < (b.0, b.1)) {
                    best = Some((d2, depth, [px as u32, py as u32], index));
                }
            }
        }
    }
    best.map(|(_, depth, pixel, index)| (pixel, depth, index))
}

/// Depth bands a reconstruction takes for one surface, in drawn point spacings: `filters`'
/// d~ and the surfels' blending offset default to a few spacings.
const SURFACE_SPACINGS: f32 = 4.0;

/// The steepest a shown surface is taken to be: 87° from the view ray (tan 87° is about 19),
/// where a normal seen edge-on would make any depth its own.
const MIN_FACING_COS: f32 = 0.05;

/// The surface a pipeline reconstructed in a frame, per pixel, with the view it was seen in.
pub struct ShownSurface<'a> {
    pub pixels: &'a [Option<SurfacePixel>],
    pub width: u32,
    pub height: u32,
    pub view: ViewFrame,
    /// The drawn points' spacing (`lod::drawn_spacing`), in dataset units.
    pub spacing: f32,
}

impl ShownSurface<'_> {
    /// Clears, in a frame's per-pixel (depth bits, global index) within `radius` of `at`, the
    /// points hidden behind the shown surface: those where it shows background, and those
    /// behind it by more than its own depth band. The band is a few drawn spacings (what a
    /// reconstruction blends into one surface), or where the surface turns away from the eye,
    /// the depth it falls over two pixels (a point may lie a pixel or two from the pixel that
    /// holds it). The slope comes from the surface's normal, not from its neighbours' depths:
    /// beside a nearer edge those jump to the surface behind, and would hide nothing there, nor
    /// across a pole a pixel wide.
    pub fn hide_points_behind(
        &self,
        pixels: &mut [Option<(u32, u32)>],
        (x, y): (u32, u32),
        radius: u32,
    ) {
        let r = radius.min(self.width + self.height);
        let (x0, x1) = (x.saturating_sub(r), x.saturating_add(r).min(self.width - 1));
        let (y0, y1) = (
            y.saturating_sub(r),
            y.saturating_add(r).min(self.height - 1),
        );
        for py in y0..=y1 {
            for px in x0..=x1 {
                let at = (py * self.width + px) as usize;
                let Some(Some((bits, _))) = pixels.get(at).copied() else {
                    continue;
                };
                let visible = self.pixels.get(at).copied().flatten().is_some_and(|front| {
                    f32::from_bits(bits) <= front.depth + self.band(px, py, front)
                });
                if !visible {
                    pixels[at] = None;
                }
            }
        }
    }

    /// How far behind the surface shown at pixel `(x, y)` a point of it may lie.
    fn band(&self, x: u32, y: u32, front: SurfacePixel) -> f32 {
        let thickness = SURFACE_SPACINGS * self.spacing;
        // A pixel's width at that depth, and how steeply the surface recedes along the ray.
        let pixel = front.depth / self.view.focal_px.max(1e-6);
        let slope = match front.normal {
            Some(n) => {
                let cos = glam::Vec3::from(n).dot(-self.ray(x, y)).abs();
                let cos = cos.max(MIN_FACING_COS);
                (1.0 - cos * cos).sqrt() / cos
            }
            None => 1.0 / MIN_FACING_COS,
        };
        // f32 depths carry a relative error of about 1e-7; a band of 1e-5 stays above it.
        thickness.max(2.0 * pixel * slope).max(1e-5 * front.depth)
    }

    /// The unit ray through pixel `(x, y)` in view space (x right, y up, z towards the eye).
    fn ray(&self, x: u32, y: u32) -> glam::Vec3 {
        let tan_y = (self.view.fov_y * 0.5).tan();
        let ndc_x = (x as f32 + 0.5) / self.width as f32 * 2.0 - 1.0;
        let ndc_y = 1.0 - (y as f32 + 0.5) / self.height as f32 * 2.0;
        glam::Vec3::new(ndc_x * tan_y * self.view.aspect, ndc_y * tan_y, -1.0).normalize()
    }
}

/// The node and the place in it of `local` in arena `arena`, from the node's pieces in the
/// GPU cache (a node's points lie in its pieces in order).
pub fn locate<'a>(
    slots: impl Iterator<Item = (NodeKey, &'a [crate::gpu::cache::Piece])>,
    arena: u32,
    local: u32,
) -> Option<(NodeKey, usize)> {
    for (key, pieces) in slots {
        let mut before = 0usize;
        for p in pieces {
            if p.arena == arena && (p.start..p.start + p.count).contains(&local) {
                return Some((key, before + (local - p.start) as usize));
            }
            before += p.count as usize;
        }
    }
    None
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::gpu::cache::Piece;

    #[test]
    fn a_point_is_found_in_the_piece_that_holds_it() {
        let a = NodeKey::ROOT;
        let pieces = [
            Piece {
                arena: 0,
                start: 100,
                count: 10,
            },
            Piece {
                arena: 1,
                start: 0,
                count: 5,
            },
        ];
        let slots = || std::iter::once((a, &pieces[..]));
        assert_eq!(locate(slots(), 0, 104), Some((a, 4)));
        assert_eq!(locate(slots(), 1, 3), Some((a, 13)));
        assert_eq!(locate(slots(), 1, 5), None);
        assert_eq!(locate(slots(), 0, 99), None);
    }

    #[test]
    fn the_nearest_drawn_pixel_wins_then_the_nearest_to_the_eye() {
        let (w, h) = (5u32, 5u32);
        let mut px = vec![None; 25];
        px[2 * 5 + 4] = Some((50, 7)); // (4, 2): two away
        px[5 + 2] = Some((90, 8)); // (2, 1): one away
        px[3 * 5 + 2] = Some((10, 9)); // (2, 3): one away, nearer the eye
        assert_eq!(nearest_drawn(&px, w, h, (2, 2), 2), Some(([2, 3], 10, 9)));
        assert_eq!(nearest_drawn(&px, w, h, (0, 4), 1), None);
        // A radius far beyond the view looks at the view's pixels only (it hung before).
        assert_eq!(
            nearest_drawn(&px, w, h, (0, 4), u32::MAX),
            Some(([2, 3], 10, 9))
        );
        assert_eq!(asprs_class_name(6), "building");
        assert_eq!(
            to_decimals(849_296.0 + 0.01 * 45.0, 0.01).to_string(),
            "849296.45"
        );
        assert_eq!(to_decimals(1.0 + 0.3 * 2.0, 0.3), 1.0 + 0.3 * 2.0);
        // A fine scale far from zero: the sum rounds by more than a millionth of a step.
        let (offset, scale) = (205.00099999999998, 9.999999999999999e-9);
        let v = offset + scale * 120_400_000.0;
        assert_eq!(to_decimals(v, scale).to_string(), "206.205");
    }

    /// A wall at depth 7 facing the eye, sampled sparsely, and the floor behind it at depth 12
    /// to 18, seen through the wall's gaps and beside it at a grazing angle: the floor's points
    /// are hidden where the wall is shown, even on the wall's edge beside the floor, and kept
    /// where the floor itself is shown, though it falls away steeply from pixel to pixel.
    #[test]
    fn points_behind_the_shown_surface_are_not_picked() {
        let (w, h) = (4u32, 3u32);
        let view = ViewFrame {
            view: glam::Mat4::IDENTITY,
            view_proj: glam::Mat4::IDENTITY,
            fov_y: 0.5,
            near: 0.1,
            far: 100.0,
            focal_px: 10.0,
            aspect: 1.0,
        };
        // Columns 0 and 1 show the wall, 2 and 3 the floor, its depth growing by 3 a row
        // (its normal nearly at right angles to the rays).
        let floor_normal = glam::Vec3::new(0.0, 1.0, 0.1).normalize().to_array();
        let pixels: Vec<Option<SurfacePixel>> = (0..h)
            .flat_map(|y| (0..w).map(move |x| (x, y)))
            .map(|(x, y)| {
                Some(if x < 2 {
                    SurfacePixel {
                        depth: 7.0,
                        normal: Some([0.0, 0.0, 1.0]),
                    }
                } else {
                    SurfacePixel {
                        depth: 12.0 + 3.0 * y as f32,
                        normal: Some(floor_normal),
                    }
                })
            })
            .collect();
        let shown = ShownSurface {
            pixels: &pixels,
            width: w,
            height: h,
            view,
            spacing: 0.01,
        };
        let bits = |d: f32| d.to_bits();
        let mut px = vec![None; 12];
        px[0] = Some((bits(7.03), 1)); // on the wall, within its band
        px[4] = Some((bits(12.0), 2)); // the floor through the wall's gap
        px[5] = Some((bits(15.0), 3)); // the same, on the wall's edge beside the floor
        px[7] = Some((bits(16.0), 4)); // on the floor, a pixel's fall behind its pixel's depth
        px[11] = Some((bits(18.0), 5)); // on the floor, at its pixel's depth
        let mut hidden = px.clone();
        shown.hide_points_behind(&mut hidden, (1, 1), 3);
        assert_eq!(hidden[0], px[0]);
        assert_eq!(hidden[4], None);
        assert_eq!(hidden[5], None);
        assert_eq!(hidden[7], px[7]);
        assert_eq!(hidden[11], px[11]);
        assert_eq!(
            nearest_drawn(&hidden, w, h, (1, 1), 2),
            Some(([0, 0], bits(7.03), 1))
        );
        // Where the image shows background, nothing is picked; and only pixels within the
        // radius are looked at.
        let mut background = pixels.clone();
        background[11] = None;
        let shown = ShownSurface {
            pixels: &background,
            ..shown
        };
        let mut near_corner = px.clone();
        shown.hide_points_behind(&mut near_corner, (3, 2), 0);
        assert_eq!(near_corner[11], None);
        assert_eq!(near_corner[4], px[4], "outside the radius");
        // Sparse, rough points (2.5 apart, heights 0 to 10): a fan of neighbours drawn in front
        // of a point by less than a few spacings is its surface, and the point is picked.
        let rough = ShownSurface {
            spacing: 1.0,
            ..shown
        };
        let mut kept = px.clone();
        kept[4] = Some((bits(10.5), 2));
        rough.hide_points_behind(&mut kept, (0, 1), 0);
        assert_eq!(kept[4], Some((bits(10.5), 2)));
    }

    #[test]
    fn a_picked_point_prints_every_digit_and_its_normal_as_a_vector() {
        let normal = strata_format::Attribute::oct16_normal();
        let code = strata_format::oct16_encode([-0.4472136, 0.0, 0.8944272]);
        let raw: Vec<u8> = code.iter().flat_map(|c| c.to_le_bytes()).collect();
        let values = attribute_values(&normal, &raw);
        assert_eq!(values.len(), 3);
        for (v, want) in values.iter().zip([-0.4472136, 0.0, 0.8944272]) {
            assert!((v - want).abs() < 1e-4, "{values:?}");
        }
        assert_eq!(
            attribute_values(&normal, &[0; 4]),
            vec![0.0; 3],
            "no normal"
        );
        let point = PickedPoint {
            pixel: [0, 0],
            depth: 1.0,
            node: "r".into(),
            index: 0,
            position: [11.0000001, 48.0008986, 300.125],
            step: 1e-7,
            attributes: Vec::new(),
        };
        let lines = point.lines();
        assert_eq!(&lines[..3], ["x 11.0000001", "y 48.0008986", "z 300.125"]);
    }
}
