//! Drawing on top of the rendered scene: measurements, profile lines and clip boxes, placed with
//! the renderer's own projection. The window paints them with egui; headless images get them
//! rasterized here on the CPU, after the frame is read back.

use crate::camera::Camera;
use crate::dataset::StreamDataset;
use crate::lod::clip_range;
use crate::measure::{MeasureKind, Measurements};
use glam::{DVec3, Mat4, Vec4};

/// Real-world points to pixels of a `width` x `height` view, as the frame projects them.
#[derive(Debug, Clone, Copy)]
pub struct ScreenProjector {
    view_proj: Mat4,
    anchor: DVec3,
    pub width: f32,
    pub height: f32,
}

/// Clip-space w below which a point counts as behind the eye.
const NEAR_W: f32 = 1e-4;

impl ScreenProjector {
    pub fn new(ds: &StreamDataset, camera: &Camera, width: u32, height: u32) -> ScreenProjector {
        let (near, far) = clip_range(ds, camera, width as f32 / height.max(1) as f32);
        // `ray` unprojects through the far plane, which the f32 matrix loses beyond a ratio of
        // about 1e5; nothing else here depends on the near plane (`NEAR_W` cuts segments).
        let near = near.max(far * 1e-5);
        ScreenProjector::from_view(camera, ds.anchor(), width, height, near, far)
    }

    /// The projection of `camera`, whose positions are relative to `anchor`, with the given
    /// near and far planes.
    pub fn from_view(
        camera: &Camera,
        anchor: DVec3,
        width: u32,
        height: u32,
        near: f32,
        far: f32,
    ) -> ScreenProjector {
        let aspect = width as f32 / height.max(1) as f32;
        ScreenProjector {
            view_proj: camera.projection(aspect, near, far) * camera.view(),
            anchor,
            width: width as f32,
            height: height as f32,
        }
    }

    fn clip(&self, p: [f64; 3]) -> Vec4 {
        let rel = (DVec3::from_array(p) - self.anchor).as_vec3();
        self.view_proj * rel.extend(1.0)
    }

    fn pixel_of(&self, c: Vec4) -> [f32; 2] {
        [
            (c.x / c.w * 0.5 + 0.5) * self.width,
            (0.5 - c.y / c.w * 0.5) * self.height,
        ]
    }

    /// The pixel (x right, y down, fractional) of a point in front of the eye.
    pub fn to_pixel(&self, p: [f64; 3]) -> Option<[f32; 2]> {
        let c = self.clip(p);
        (c.w > NEAR_W).then(|| self.pixel_of(c))
    }

    /// The ray through pixel `(x, y)` (image pixels, fractional): a point on it and its
    /// direction, in real-world coordinates.
    pub fn ray(&self, [x, y]: [f32; 2]) -> Option<(DVec3, DVec3)> {
        let inv = self.view_proj.as_dmat4().inverse();
        let ndc_x = x as f64 / self.width as f64 * 2.0 - 1.0;
        let ndc_y = 1.0 - y as f64 / self.height as f64 * 2.0;
        let near = inv.project_point3(DVec3::new(ndc_x, ndc_y, 0.0));
        let far = inv.project_point3(DVec3::new(ndc_x, ndc_y, 1.0));
        let dir = (far - near).normalize_or_zero();
        (dir != DVec3::ZERO && near.is_finite()).then(|| (near + self.anchor, dir))
    }

    /// The part of segment `a`-`b` in front of the eye, in pixels.
    pub fn segment(&self, a: [f64; 3], b: [f64; 3]) -> Option<([f32; 2], [f32; 2])> {
        let (mut ca, mut cb) = (self.clip(a), self.clip(b));
        if ca.w <= NEAR_W && cb.w <= NEAR_W {
            return None;
        }
        // Cut at the plane w = NEAR_W so that a segment passing beside the eye stays a segment.
        if ca.w <= NEAR_W {
            let t = (NEAR_W - ca.w) / (cb.w - ca.w);
            ca = ca + (cb - ca) * t;
        } else if cb.w <= NEAR_W {
            let t = (NEAR_W - cb.w) / (ca.w - cb.w);
            cb = cb + (ca - cb) * t;
        }
        Some((self.pixel_of(ca), self.pixel_of(cb)))
    }
}

/// The colour each kind of measurement is drawn in (RGB).
pub fn kind_colour(kind: MeasureKind) -> [u8; 3] {
    match kind {
        MeasureKind::Distance => [255, 214, 10],
        MeasureKind::Area => [40, 220, 255],
        MeasureKind::Height => [255, 80, 220],
        MeasureKind::Angle => [255, 140, 0],
    }
}

/// The segments a measurement is drawn with: its polyline, closed for an area, and for a height
/// the vertical from the lower point and the horizontal to the higher one.
pub fn measurement_segments(m: &crate::measure::Measurement) -> Vec<([f64; 3], [f64; 3])> {
    let p = &m.points;
    let mut out: Vec<_> = p.windows(2).map(|w| (w[0], w[1])).collect();
    match m.kind {
        MeasureKind::Area if p.len() >= 3 => out.push((p[p.len() - 1], p[0])),
        MeasureKind::Height if p.len() == 2 => {
            let (lo, hi) = if p[0][2] <= p[1][2] {
                (p[0], p[1])
            } else {
                (p[1], p[0])
            };
            let corner = [lo[0], lo[1], hi[2]];
            out.push((lo, corner));
            out.push((corner, hi));
        }
        _ => {}
    }
    out
}

/// An RGBA image to draw into.
pub struct Canvas<'a> {
    pub rgba: &'a mut [u8],
    pub width: u32,
    pub height: u32,
}

impl Canvas<'_> {
    fn put(&mut self, x: i64, y: i64, c: [u8; 3]) {
        if x < 0 || y < 0 || x >= self.width as i64 || y >= self.height as i64 {
            return;
        }
        let at = (y as usize * self.width as usize + x as usize) * 4;
        if let Some(px) = self.rgba.get_mut(at..at + 4) {
            px.copy_from_slice(&[c[0], c[1], c[2], 255]);
        }
    }

    /// A square of side `2 r + 1` centred on `(x, y)`.
    pub fn dot(&mut self, [x, y]: [f32; 2], r: i64, c: [u8; 3]) {
        let (cx, cy) = (x.floor() as i64, y.floor() as i64);
        for dy in -r..=r {
            for dx in -r..=r {
                self.put(cx + dx, cy + dy, c);
            }
        }
    }

    /// A line `2 r + 1` pixels wide, clipped to the image.
    pub fn line(&mut self, a: [f32; 2], b: [f32; 2], r: i64, c: [u8; 3]) {
        let Some((a, b)) = clip_to(a, b, self.width as f32, self.height as f32) else {
            return;
        };
        let steps = (b[0] - a[0]).abs().max((b[1] - a[1]).abs()).ceil().max(1.0) as i64;
        for i in 0..=steps {
            let t = i as f32 / steps as f32;
            self.dot([a[0] + (b[0] - a[0]) * t, a[1] + (b[1] - a[1]) * t], r, c);
        }
    }
}

/// The part of a segment within a rectangle grown by a margin (Liang-Barsky, in f64: an end far
/// off screen would lose the pixels in f32), so that a line reaching far off screen costs no
/// more than one crossing it.
fn clip_to(a: [f32; 2], b: [f32; 2], w: f32, h: f32) -> Option<([f32; 2], [f32; 2])> {
    if !(a.iter().chain(&b).all(|v| v.is_finite())) {
        return None;
    }
    let (a, b) = (a.map(f64::from), b.map(f64::from));
    let (w, h, m) = (w as f64, h as f64, 4.0);
    let d = [b[0] - a[0], b[1] - a[1]];
    let (mut t0, mut t1) = (0.0f64, 1.0f64);
    for (p, q) in [
        (-d[0], a[0] + m),
        (d[0], w + m - a[0]),
        (-d[1], a[1] + m),
        (d[1], h + m - a[1]),
    ] {
        if p == 0.0 {
            if q < 0.0 {
                return None;
            }
        } else {
            let r = q / p;
            if p < 0.0 {
                t0 = t0.max(r);
            } else {
                t1 = t1.min(r);
            }
        }
    }
    let at = |t: f64| [(a[0] + d[0] * t) as f32, (a[1] + d[1] * t) as f32];
    (t0 <= t1).then(|| (at(t0), at(t1)))
}

/// Draws every measurement: lines two pixels wide in its kind's colour over a dark edge, and
/// each picked point as a square.
pub fn draw_measurements(canvas: &mut Canvas, proj: &ScreenProjector, all: &Measurements) {
    const EDGE: [u8; 3] = [0, 0, 0];
    for m in &all.items {
        let colour = kind_colour(m.kind);
        let segments: Vec<_> = measurement_segments(m)
            .into_iter()
            .filter_map(|(a, b)| proj.segment(a, b))
            .collect();
        for &(a, b) in &segments {
            canvas.line(a, b, 2, EDGE);
        }
        for &(a, b) in &segments {
            canvas.line(a, b, 1, colour);
        }
        for p in m.points.iter().filter_map(|p| proj.to_pixel(*p)) {
            canvas.dot(p, 4, EDGE);
            canvas.dot(p, 3, colour);
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn lines_are_clipped_to_the_image_and_drawn_where_they_cross_it() {
        let mut rgba = vec![0u8; 20 * 10 * 4];
        let mut c = Canvas {
            rgba: &mut rgba,
            width: 20,
            height: 10,
        };
        // From far off the left to far off the right along row 5.
        c.line([-1e9, 5.5], [1e9, 5.5], 0, [255, 0, 0]);
        let lit: Vec<usize> = (0..200).filter(|i| rgba[i * 4] == 255).collect();
        assert_eq!(lit, (100..120).collect::<Vec<_>>());
        assert!(clip_to([-10.0, -10.0], [-20.0, 30.0], 20.0, 10.0).is_none());
        assert!(clip_to([f32::NAN, 0.0], [1.0, 1.0], 20.0, 10.0).is_none());
    }
}
