//! Reading a frame back from the GPU: the image, the pipeline's measures, and the surface
//! (depth and normal per pixel) for picking, focusing and the quality harness.

use super::Renderer;
use crate::ViewerError;
use crate::gpu::readback::{read_buffer, read_texture};
use crate::gpu::timing::PassTimes;
use crate::lod::drawn_spacing;
use crate::pick::{PickedPoint, ShownSurface, locate, nearest_drawn};
use std::collections::BTreeMap;

impl Renderer {
    /// The latest pass times (after `wait_gpu`).
    pub fn pass_times(&self) -> PassTimes {
        self.timer.last().clone()
    }

    /// Reads the output image (the view, without its guard band) back as tightly packed
    /// RGBA8 rows.
    pub fn read_image(&self) -> Result<(u32, u32, Vec<u8>), ViewerError> {
        let output = self
            .output()
            .ok_or_else(|| ViewerError::Gpu("no frame has been rendered".into()))?;
        let rgba = read_texture(&self.ctx, output, 4)?;
        Ok((output.width(), output.height(), rgba))
    }

    /// What the pipeline of the last frame measured in it, waiting for the GPU.
    pub fn read_measures(&self) -> Result<BTreeMap<&'static str, f32>, ViewerError> {
        match self.active.and_then(|n| self.pipelines.get(n)) {
            Some(p) => p.read_measures(&self.ctx),
            None => Ok(BTreeMap::new()),
        }
    }

    /// The unlit colour of the surface the last frame shows, per pixel of the view
    /// (`None`: background): the pipeline's reconstructed colour, or the resolved colour plane
    /// of the projection.
    pub fn read_albedo(&self) -> Result<Vec<Option<[u8; 3]>>, ViewerError> {
        self.guard.crop_plane(&self.read_padded_albedo()?, "albedo")
    }

    fn read_padded_albedo(&self) -> Result<Vec<Option<[u8; 3]>>, ViewerError> {
        let screen = self
            .screen
            .as_ref()
            .ok_or_else(|| ViewerError::Gpu("no frame has been rendered".into()))?;
        if let Some(albedo) = self
            .active
            .and_then(|n| self.pipelines.get(n))
            .and_then(|p| p.read_albedo(&self.ctx))
        {
            return albedo;
        }
        if self.last_fused {
            return Err(ViewerError::Gpu(
                "the last frame resolved and shaded in one pass and kept no colour plane; \
                 render it with separate passes to read its albedo"
                    .into(),
            ));
        }
        if !self.last_colour_plane {
            return Err(ViewerError::Gpu(
                "the last frame's pipeline resolved no colour plane and keeps no albedo of its own"
                    .into(),
            ));
        }
        let pixels = screen.width as u64 * screen.height as u64;
        let depths = read_buffer(&self.ctx, &screen.depths, pixels * 4)?;
        let colours = read_buffer(&self.ctx, &screen.colours, pixels * 4)?;
        Ok(depths
            .chunks_exact(4)
            .zip(colours.chunks_exact(4))
            .map(|(d, c)| {
                (u32::from_le_bytes([d[0], d[1], d[2], d[3]]) != u32::MAX)
                    .then_some([c[0], c[1], c[2]])
            })
            .collect())
    }

    /// The stored point nearest pixel `(x, y)` of the last frame's view, within `radius` pixels
    /// of it and in the view (not in its guard band): read from its node with every attribute
    /// in full precision. Where the pipeline reconstructs a surface, a point of the surface it
    /// shows (`ShownSurface`). `None` where only background lies within reach.
    pub fn pick(&self, x: u32, y: u32, radius: u32) -> Result<Option<PickedPoint>, ViewerError> {
        let (x, y) = self.guard.padded_pixel((x, y));
        let screen = self
            .screen
            .as_ref()
            .ok_or_else(|| ViewerError::Gpu("no frame has been rendered".into()))?;
        let pixels = screen.width as u64 * screen.height as u64;
        let word = |b: &[u8]| u32::from_le_bytes([b[0], b[1], b[2], b[3]]);
        let mut planes: Vec<Option<(u32, u32)>> = match &screen.keys {
            Some(keys) if self.last_int64 => read_buffer(&self.ctx, keys, pixels * 8)?
                .chunks_exact(8)
                .map(|k| (word(&k[4..]) != u32::MAX).then(|| (word(&k[4..]), word(&k[..4]))))
                .collect(),
            _ => {
                let depths = read_buffer(&self.ctx, &screen.depths, pixels * 4)?;
                let indices = read_buffer(&self.ctx, &screen.indices, pixels * 4)?;
                depths
                    .chunks_exact(4)
                    .zip(indices.chunks_exact(4))
                    .map(|(d, i)| (word(d) != u32::MAX).then(|| (word(d), word(i))))
                    .collect()
            }
        };
        // A pipeline that reconstructs a surface draws over the points: one seen through the
        // gaps of a nearer surface's sampling is hidden behind what the image shows there.
        if let (Some(pixels), Some(view)) = (self.pipeline_surface()?, self.previous_view) {
            let drawn: Vec<_> = self.last_drawn.iter().copied().collect();
            let shown = ShownSurface {
                pixels: &pixels,
                width: screen.width,
                height: screen.height,
                view,
                spacing: drawn_spacing(&self.tree, &self.ds, &drawn).unwrap_or(0.0),
            };
            shown.hide_points_behind(&mut planes, (x, y), radius);
        }
        // What the guard band holds is not in the picture.
        for (i, p) in planes.iter_mut().enumerate() {
            let i = i as u32;
            if !self.guard.in_view((i % screen.width, i / screen.width)) {
                *p = None;
            }
        }
        let Some((pixel, depth, global)) =
            nearest_drawn(&planes, screen.width, screen.height, (x, y), radius)
        else {
            return Ok(None);
        };
        let pixel = [pixel[0] - self.guard.px, pixel[1] - self.guard.px];
        let shift = self.cache.arena_shift;
        let (arena, local) = (global >> shift, global & ((1 << shift) - 1));
        let missing = || {
            ViewerError::Gpu(format!(
                "the point drawn at pixel {},{} is no longer resident",
                pixel[0], pixel[1]
            ))
        };
        let (key, index) = locate(self.cache.slots(), arena, local).ok_or_else(missing)?;
        let info = self.tree.node(key).ok_or_else(missing)?;
        let mut point = self.ds.point(info, index)?;
        point.pixel = pixel;
        point.depth = f32::from_bits(depth);
        Ok(Some(point))
    }

    /// Linear depth per pixel of the view (`None` where nothing was drawn), for picking and
    /// tests.
    pub fn read_depths(&self) -> Result<Vec<Option<f32>>, ViewerError> {
        Ok(self
            .read_surface()?
            .into_iter()
            .map(|p| p.map(|p| p.depth))
            .collect())
    }

    /// The surface the active pipeline reconstructed in the last frame, where it keeps one.
    fn pipeline_surface(&self) -> Result<Option<Vec<Option<SurfacePixel>>>, ViewerError> {
        self.active
            .and_then(|n| self.pipelines.get(n))
            .and_then(|p| p.read_surface(&self.ctx))
            .transpose()
    }

    /// The surface the last frame shows, per pixel of the view: its linear depth, and its
    /// view-space normal where the pipeline reconstructs one. `None` where the frame shows
    /// background.
    pub fn read_surface(&self) -> Result<Vec<Option<SurfacePixel>>, ViewerError> {
        self.guard
            .crop_plane(&self.read_padded_surface()?, "surface")
    }

    fn read_padded_surface(&self) -> Result<Vec<Option<SurfacePixel>>, ViewerError> {
        let screen = self
            .screen
            .as_ref()
            .ok_or_else(|| ViewerError::Gpu("no frame has been rendered".into()))?;
        if let Some(surface) = self.pipeline_surface()? {
            return Ok(surface);
        }
        let pixels = screen.width as u64 * screen.height as u64;
        // On the int64 path the depth plane is the high word of each key (the fused finish
        // pass never writes a separate depth buffer).
        let (source, stride) = match &screen.keys {
            Some(keys) if self.last_int64 => (keys, 8),
            _ => (&screen.depths, 4),
        };
        let data = read_buffer(&self.ctx, source, pixels * stride as u64)?;
        Ok(data
            .chunks_exact(stride)
            .map(|b| {
                let b = &b[stride - 4..];
                let bits = u32::from_le_bytes([b[0], b[1], b[2], b[3]]);
                (bits != u32::MAX).then(|| SurfacePixel {
                    depth: f32::from_bits(bits),
                    normal: None,
                })
            })
            .collect())
    }
}

/// One pixel of the surface a frame shows.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct SurfacePixel {
    /// Linear depth along the view axis, in dataset units.
    pub depth: f32,
    /// Unit normal in view space (x right, y up, z towards the viewer).
    pub normal: Option<[f32; 3]>,
}
