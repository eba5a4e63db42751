//! The guard band: a frame is drawn a few pixels beyond each edge of the view, with the same
//! pixel scale, and the view is cut out of it. A pipeline that fills a pixel from its
//! neighbours (the filters' masks, the pull-push, a triangle to a point off the edge) then
//! finds them at the view's edge as anywhere else, instead of a ragged band of background
//! where the points outside were never drawn. Each pipeline declares how far it reaches
//! (`PipelineInfo::guard`).

use crate::camera::Camera;
use crate::pipelines::projection::image_texture;

/// A view of `width` x `height` drawn with `px` pixels more on every side.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub struct Guard {
    pub px: u32,
    pub width: u32,
    pub height: u32,
}

impl Guard {
    /// The size of the drawn frame (an empty view stays empty, for the size check to refuse).
    pub fn padded(&self) -> (u32, u32) {
        if self.width == 0 || self.height == 0 {
            return (self.width, self.height);
        }
        let band = self.px.saturating_mul(2);
        (
            self.width.saturating_add(band),
            self.height.saturating_add(band),
        )
    }

    /// `camera` widened to the padded frame: the same eye, direction and pixel scale, its
    /// view the middle of the padded frame.
    pub fn camera(&self, camera: &Camera) -> Camera {
        let (_, padded_h) = self.padded();
        let half = (camera.fov_y * 0.5).tan() * padded_h as f32 / self.height.max(1) as f32;
        Camera {
            fov_y: 2.0 * half.atan(),
            ..*camera
        }
    }

    /// The view's pixels of a padded frame's per-pixel values, row by row; `None` where
    /// `padded` is not of the padded frame's size.
    pub fn crop<T: Copy>(&self, padded: &[T]) -> Option<Vec<T>> {
        let (pw, ph) = self.padded();
        if padded.len() != pw as usize * ph as usize {
            return None;
        }
        let (px, w) = (self.px as usize, self.width as usize);
        let rows = (0..self.height as usize).map(|y| {
            let row = (y + px) * pw as usize + px;
            &padded[row..row + w]
        });
        Some(rows.flatten().copied().collect())
    }

    /// `crop`, or an error naming `what` where the plane is not of the padded frame's size.
    pub fn crop_plane<T: Copy>(
        &self,
        padded: &[T],
        what: &str,
    ) -> Result<Vec<T>, crate::ViewerError> {
        self.crop(padded).ok_or_else(|| {
            let (pw, ph) = self.padded();
            crate::ViewerError::Gpu(format!(
                "the last frame's {what} holds {} pixels, not the {pw}x{ph} it was drawn at",
                padded.len()
            ))
        })
    }

    /// The padded frame's pixel of the view's pixel `(x, y)`.
    pub fn padded_pixel(&self, (x, y): (u32, u32)) -> (u32, u32) {
        (x.saturating_add(self.px), y.saturating_add(self.px))
    }

    /// Whether the padded frame's pixel `(x, y)` lies in the view.
    pub fn in_view(&self, (x, y): (u32, u32)) -> bool {
        let (x_end, y_end) = (
            self.px.saturating_add(self.width),
            self.px.saturating_add(self.height),
        );
        (self.px..x_end).contains(&x) && (self.px..y_end).contains(&y)
    }

    /// The image the view shows, cut from the padded output; `None` without a band (the
    /// output is the image).
    pub fn shown_texture(&self, device: &wgpu::Device) -> Option<wgpu::Texture> {
        (self.px > 0).then(|| {
            let size = (self.width, self.height);
            image_texture(device, "shown image", size, wgpu::TextureUsages::COPY_DST)
        })
    }

    /// Copies the view out of the padded `output` into `shown`.
    pub fn copy_shown(
        &self,
        encoder: &mut wgpu::CommandEncoder,
        output: &wgpu::Texture,
        shown: &wgpu::Texture,
    ) {
        encoder.copy_texture_to_texture(
            wgpu::TexelCopyTextureInfo {
                texture: output,
                mip_level: 0,
                origin: wgpu::Origin3d {
                    x: self.px,
                    y: self.px,
                    z: 0,
                },
                aspect: wgpu::TextureAspect::All,
            },
            shown.as_image_copy(),
            wgpu::Extent3d {
                width: self.width,
                height: self.height,
                depth_or_array_layers: 1,
            },
        );
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use glam::Vec3;

    #[test]
    fn the_widened_camera_keeps_the_pixel_scale_and_the_view_in_the_middle() {
        let camera = Camera {
            eye: Vec3::new(1.0, -4.0, 2.0),
            target: Vec3::new(0.5, 0.5, 0.0),
            fov_y: 50f32.to_radians(),
        };
        let guard = Guard {
            px: 12,
            width: 320,
            height: 240,
        };
        let (pw, ph) = guard.padded();
        assert_eq!((pw, ph), (344, 264));
        let wide = guard.camera(&camera);
        assert!((wide.focal_px(ph) - camera.focal_px(240)).abs() < 1e-3);
        // A point of the view lands on the padded frame's pixel shifted by the band.
        let vp = camera.projection(320.0 / 240.0, 0.1, 100.0) * camera.view();
        let wide_vp = wide.projection(pw as f32 / ph as f32, 0.1, 100.0) * wide.view();
        for p in [Vec3::new(0.3, 0.9, 0.2), Vec3::new(1.5, 1.0, -0.4)] {
            let (a, b) = (vp.project_point3(p), wide_vp.project_point3(p));
            let pixel = |q: Vec3, w: u32, h: u32| {
                ((q.x * 0.5 + 0.5) * w as f32, (0.5 - q.y * 0.5) * h as f32)
            };
            let (ax, ay) = pixel(a, 320, 240);
            let (bx, by) = pixel(b, pw, ph);
            assert!((ax + 12.0 - bx).abs() < 1e-3 && (ay + 12.0 - by).abs() < 1e-3);
        }
    }

    /// A band a parameter sets names a parameter its pipeline has (a renamed one would leave
    /// only the extra pixels), follows its value rounded up, and stops at the cap; the
    /// pipelines that fill pixels from their neighbours have one.
    #[test]
    fn every_band_follows_its_parameter_within_the_cap() {
        use crate::pipelines::params::{ParamValue, ParamValues};
        use crate::pipelines::{GuardBand, REGISTRY};
        for &info in REGISTRY {
            let GuardBand::Param { name, extra } = info.guard else {
                continue;
            };
            let spec = info.param(name).expect("the band's parameter exists");
            for v in [spec.min, spec.default, spec.max] {
                let mut values = ParamValues::default();
                values.set(info, spec, ParamValue::Value(v));
                let want = (v.ceil() as u32 + extra).min(GuardBand::MAX_PX);
                assert_eq!(info.guard_px(&values), want, "{} {name}={v}", info.name);
            }
        }
        for name in ["pyramid", "filters", "triangulate"] {
            let info = crate::pipelines::find(name).expect("registered");
            assert!(info.guard_px(&ParamValues::default()) >= 16, "{name}");
        }
    }

    #[test]
    fn the_crop_takes_the_middle_rows_and_columns() {
        let guard = Guard {
            px: 1,
            width: 2,
            height: 1,
        };
        let padded: Vec<u32> = (0..12).collect();
        assert_eq!(guard.crop(&padded), Some(vec![5, 6]));
        assert_eq!(guard.crop(&padded[1..]), None);
        assert_eq!(guard.padded_pixel((1, 0)), (2, 1));
        assert!(guard.in_view((2, 1)) && !guard.in_view((3, 1)) && !guard.in_view((1, 0)));
        // An empty view stays empty (the size check refuses it); a pixel far out saturates.
        let empty = Guard { width: 0, ..guard };
        assert_eq!(empty.padded(), (0, 1));
        assert!(!guard.in_view(guard.padded_pixel((u32::MAX, 0))));
    }
}
