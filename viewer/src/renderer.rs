//! One frame of the viewer, the same in the window and headless: take what the loaders
//! finished, upload it, choose nodes under the budget, ask for what is missing, and draw what is
//! resident. Nothing here waits for I/O.

use crate::ViewerError;
use crate::camera::Camera;
use crate::dataset::{GpuNode, StreamDataset};
use crate::gpu::GpuContext;
use crate::gpu::async_readback::AsyncReadback;
use crate::gpu::cache::{InsertError, NodeCache};
use crate::gpu::passes::{ArenaDraw, FrameDraw, FrameUniforms, GpuRange, Passes, Screen};
use crate::gpu::pyramid::{PyramidFrame, depth_noise_from};
use crate::gpu::readback::{read_buffer, read_texture};
use crate::gpu::timing::{PassClock, Timer};
use crate::loader::{Done, Job, JobKey, Loader};
use crate::lod::{Selection, SelectionParams, Tree, clip_range, drawn_spacing, select};
use crate::settings::{Pipeline, Settings, SizeMode};
use serde::Serialize;
use std::collections::{BTreeMap, HashMap, HashSet, VecDeque};
use std::sync::Arc;
use std::time::{Duration, Instant};
use strata_format::NodeKey;

/// Statistics of one frame, as `--stats` writes them and the panel shows them.
#[derive(Debug, Clone, Default, Serialize)]
pub struct FrameStats {
    pub frame: u64,
    pub points_drawn: u64,
    pub nodes_drawn: usize,
    /// CPU time of the frame, including waiting for the GPU where the caller waited.
    pub frame_ms: f64,
    /// GPU ms per pass, by `pass_clock`.
    pub passes: BTreeMap<String, f64>,
    /// "timestamps" (queries inside the frame) or "wall" (each pass submitted alone and
    /// waited for).
    pub pass_clock: &'static str,
    /// Stored bytes that arrived from the loaders during this frame.
    pub bytes_loaded: u64,
    pub bytes_loaded_total: u64,
    /// Nodes that could not be loaded (corrupt, unreadable), over the whole session.
    pub nodes_failed: usize,
    pub pages_failed: usize,
    /// Nodes the view wants that are not resident yet.
    pub nodes_missing: usize,
    /// Of those, nodes whose source did not answer; they are asked for again later.
    pub nodes_unavailable: usize,
    /// Fetches that failed for want of an answer (server gone, timeouts), over the session.
    pub fetch_errors: u64,
    pub nodes_visible: usize,
    pub nodes_resident: usize,
    pub nodes_in_flight: usize,
    pub nodes_queued: usize,
    pub gpu_bytes: u64,
    /// The pyramid pipeline's s0 this frame (given, or estimated from the nodes drawn).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub s0: Option<f32>,
    /// The pyramid pipeline's estimate of the depth noise of the visible points, as a
    /// deviation in dataset units (0: too few neighbouring points to tell). In a window the
    /// latest that has arrived, a frame or more behind; headless, this frame's (read back
    /// after waiting for the GPU).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub depth_noise: Option<f32>,
    /// Every node the view and budget call for is resident and drawn.
    pub complete: bool,
}

pub struct Renderer {
    ctx: Arc<GpuContext>,
    ds: Arc<StreamDataset>,
    tree: Tree,
    loader: Loader,
    cache: NodeCache,
    passes: Passes,
    screen: Option<Screen>,
    timer: Timer,
    /// The depth noise on its way back for the stats, and the latest that arrived.
    noise_readback: AsyncReadback,
    depth_noise: Option<f32>,
    /// `PassClock::Auto` means the wall clock here: a CPU adapter, or no timestamp queries.
    auto_wall_clock: bool,
    failed: HashSet<NodeKey>,
    pages_failed: usize,
    errors: Vec<String>,
    uploads: VecDeque<GpuNode>,
    retry_after: HashMap<JobKey, Instant>,
    fetch_errors: u64,
    last_fetch_error: Option<String>,
    last_drawn: HashSet<NodeKey>,
    /// The last frame projected through the 64-bit keys (else the 32-bit planes).
    last_int64: bool,
    /// The last frame ran the pyramid pipeline (its surface buffer holds the result).
    last_pyramid: bool,
    frame: u64,
    bytes_total: u64,
}

/// How long a node or page whose source did not answer waits before it is asked for again.
const RETRY_PAUSE: Duration = Duration::from_millis(500);

/// GPU memory for the node cache unless told otherwise.
pub const DEFAULT_GPU_CACHE: u64 = 2 << 30;

impl Renderer {
    pub fn new(
        ctx: Arc<GpuContext>,
        ds: Arc<StreamDataset>,
        gpu_cache_bytes: u64,
        loader_threads: usize,
    ) -> Result<Renderer, ViewerError> {
        let mut tree = Tree::default();
        tree.add_page(&ds.load_page(&ds.root_page())?);
        let loader = Loader::new(ds.clone(), loader_threads);
        let cache = NodeCache::new(ctx.max_binding(), gpu_cache_bytes);
        let passes = Passes::new(&ctx);
        let timer = Timer::new(&ctx.device, &ctx.queue, ctx.timestamps);
        let noise_readback = AsyncReadback::new(&ctx.device, "depth noise readback", 4);
        let auto_wall_clock =
            !ctx.timestamps || ctx.adapter.get_info().device_type == wgpu::DeviceType::Cpu;
        Ok(Renderer {
            ctx,
            ds,
            tree,
            loader,
            cache,
            passes,
            screen: None,
            noise_readback,
            depth_noise: None,
            timer,
            auto_wall_clock,
            failed: HashSet::new(),
            pages_failed: 0,
            errors: Vec::new(),
            uploads: VecDeque::new(),
            retry_after: HashMap::new(),
            fetch_errors: 0,
            last_fetch_error: None,
            last_drawn: HashSet::new(),
            last_int64: false,
            last_pyramid: false,
            frame: 0,
            bytes_total: 0,
        })
    }

    pub fn dataset(&self) -> &Arc<StreamDataset> {
        &self.ds
    }

    pub fn context(&self) -> &Arc<GpuContext> {
        &self.ctx
    }

    /// Messages of the loads that failed, oldest first.
    pub fn errors(&self) -> &[String] {
        &self.errors
    }

    pub fn output(&self) -> Option<&wgpu::Texture> {
        self.screen.as_ref().map(|s| &s.output)
    }

    /// Blocks until a loader finishes something or `timeout` passes (headless use only).
    pub fn wait_for_loads(&mut self, timeout: std::time::Duration) {
        if let Some(done) = self.loader.wait_finished(timeout) {
            self.accept(done, &mut 0);
        }
    }

    fn accept(&mut self, done: Done, bytes: &mut u64) {
        match done {
            Done::Node(node) => {
                *bytes += node.bytes_read;
                self.uploads.push_back(node);
            }
            Done::NodeFailed(key, e) if e.is_transient() => self.unavailable(JobKey::Node(key), e),
            Done::NodeFailed(key, e) => {
                self.failed.insert(key);
                self.errors.push(e.to_string());
            }
            Done::Page(page) => self.tree.add_page(&page),
            Done::PageFailed(root, e) if e.is_transient() => {
                self.unavailable(JobKey::Page(root), e)
            }
            Done::PageFailed(root, e) => {
                self.tree.drop_page(root);
                self.pages_failed += 1;
                self.errors.push(e.to_string());
            }
        }
    }

    /// A fetch that found no server: try again after a pause, keep drawing what is resident.
    fn unavailable(&mut self, key: JobKey, e: ViewerError) {
        self.fetch_errors += 1;
        self.last_fetch_error = Some(e.to_string());
        self.retry_after.insert(key, Instant::now() + RETRY_PAUSE);
    }

    /// The most recent fetch that found no server, if any.
    pub fn last_fetch_error(&self) -> Option<&str> {
        self.last_fetch_error.as_deref()
    }

    /// Renders one frame of `width` x `height` into the output texture.
    pub fn frame(
        &mut self,
        camera: &Camera,
        width: u32,
        height: u32,
        settings: &Settings,
    ) -> FrameStats {
        let start = Instant::now();
        self.frame += 1;
        let (width, height) = (width.max(1), height.max(1));
        let mut bytes = 0u64;
        let finished: Vec<Done> = self.loader.finished().collect();
        for done in finished {
            self.accept(done, &mut bytes);
        }
        self.bytes_total += bytes;
        self.upload(settings);

        let params = SelectionParams {
            // More than the cache holds would evict what the same frame draws, for ever; a
            // 10 % margin leaves room for fragmentation.
            budget: settings.budget.min(self.cache.capacity_points() / 10 * 9),
            width,
            height,
            min_spacing_px: settings.min_spacing_px,
        };
        let cache = &self.cache;
        let sel = select(
            &self.tree,
            &self.ds,
            camera,
            &params,
            |k| cache.contains(k),
            &self.failed,
        );
        self.request(&sel);
        self.cache.touch(&sel.draw, self.frame);
        self.last_drawn = sel.draw.iter().copied().collect();

        let s0 = (settings.pipeline == Pipeline::Pyramid)
            .then(|| {
                settings
                    .s0
                    .or_else(|| drawn_spacing(&self.tree, &self.ds, &sel.draw))
            })
            .flatten();
        self.draw(camera, width, height, settings, &sel, s0);
        self.collect_readbacks();
        if settings.pipeline != Pipeline::Pyramid {
            self.depth_noise = None;
        }

        let (queued, in_flight) = self.loader.counts();
        FrameStats {
            frame: self.frame,
            points_drawn: sel.draw_points,
            nodes_drawn: sel.draw.len(),
            frame_ms: start.elapsed().as_secs_f64() * 1e3,
            passes: self.timer.last().clone(),
            pass_clock: if self.wall_clock(settings) {
                PassClock::Wall.name()
            } else {
                PassClock::Timestamps.name()
            },
            bytes_loaded: bytes,
            bytes_loaded_total: self.bytes_total,
            nodes_failed: self.failed.len(),
            pages_failed: self.pages_failed,
            nodes_missing: sel.missing_nodes.len(),
            nodes_unavailable: sel
                .missing_nodes
                .iter()
                .filter(|(n, _)| self.retry_after.contains_key(&JobKey::Node(n.key)))
                .count(),
            fetch_errors: self.fetch_errors,
            nodes_visible: sel.draw.len() + sel.missing_nodes.len(),
            nodes_resident: self.cache.resident_nodes(),
            nodes_in_flight: in_flight,
            nodes_queued: queued,
            gpu_bytes: self.cache.gpu_bytes(),
            s0,
            depth_noise: self.depth_noise,
            complete: sel.missing_nodes.is_empty()
                && sel.missing_pages.is_empty()
                && self.uploads.is_empty(),
        }
    }

    fn upload(&mut self, settings: &Settings) {
        let mut budget = settings.upload_points_per_frame.unwrap_or(u64::MAX);
        let mut first = true;
        while let Some(node) = self.uploads.front() {
            let n = node.points.len() as u64;
            // At least one node per frame, however large, so uploads always progress.
            if n > budget && !first {
                break;
            }
            first = false;
            budget = budget.saturating_sub(n);
            let Some(node) = self.uploads.pop_front() else {
                break;
            };
            match self.cache.insert(
                &self.ctx.device,
                &self.ctx.queue,
                &node,
                self.frame,
                &self.last_drawn,
            ) {
                Ok(()) => {}
                // The cache holds only what is on screen: the node waits to be asked for again.
                Err(InsertError::Full) => {}
                Err(InsertError::TooLarge { points, capacity }) => {
                    self.failed.insert(node.key);
                    self.errors.push(format!(
                        "{}: node {} has {points} points, more than the GPU cache holds ({capacity}); raise --gpu-cache",
                        self.ds.location(),
                        node.key
                    ));
                }
            }
        }
    }

    fn request(&mut self, sel: &Selection) {
        let now = Instant::now();
        self.retry_after.retain(|_, t| *t > now);
        let waiting: HashSet<NodeKey> = self.uploads.iter().map(|u| u.key).collect();
        let mut jobs: Vec<(f32, Job)> = sel
            .missing_pages
            .iter()
            .map(|(p, pr)| (*pr, Job::Page(*p)))
            .chain(sel.missing_nodes.iter().map(|(n, pr)| (*pr, Job::Node(*n))))
            .filter(|(_, j)| match j {
                Job::Node(n) => !waiting.contains(&n.key),
                Job::Page(_) => true,
            })
            .filter(|(_, j)| self.retry_after.get(&j.key()).is_none_or(|t| *t <= now))
            .collect();
        jobs.sort_by(|a, b| b.0.total_cmp(&a.0));
        self.loader.set_wanted(jobs.into_iter().map(|(_, j)| j));
    }

    fn draw(
        &mut self,
        camera: &Camera,
        width: u32,
        height: u32,
        settings: &Settings,
        sel: &Selection,
        s0: Option<f32>,
    ) {
        if self
            .screen
            .as_ref()
            .is_none_or(|s| s.width != width || s.height != height)
        {
            self.screen = Some(self.passes.screen(&self.ctx.device, width, height));
        }
        let pyramid = settings.pipeline == Pipeline::Pyramid;
        if let Some(screen) = self
            .screen
            .as_mut()
            .filter(|s| pyramid && s.pyramid.is_none())
        {
            screen.pyramid = Some(self.passes.pyramid_targets(&self.ctx.device, screen));
        }
        let Some(screen) = &self.screen else { return };
        let mut per_arena: BTreeMap<u32, Vec<GpuRange>> = BTreeMap::new();
        for key in &sel.draw {
            for p in self.cache.pieces(*key).unwrap_or_default() {
                per_arena.entry(p.arena).or_default().push(GpuRange {
                    start: p.start,
                    count: p.count,
                    first_group: 0,
                    spacing: self.ds.node_spacing(*key),
                });
            }
        }
        let draws: Vec<ArenaDraw> = per_arena
            .into_iter()
            .map(|(arena, ranges)| ArenaDraw { arena, ranges })
            .collect();
        let aspect = width as f32 / height as f32;
        let (near, far) = clip_range(&self.ds, camera);
        let view_proj = camera.projection(aspect, near, far) * camera.view();
        let (bmin, bmax) = self.ds.bounds();
        let [r, g, b] = settings.background;
        let uniforms = FrameUniforms {
            view_proj: view_proj.to_cols_array_2d(),
            width,
            height,
            point_size: settings.point_size,
            size_mode: match settings.size_mode {
                SizeMode::Fixed => 0,
                SizeMode::Attenuated => 1,
            },
            focal_px: camera.focal_px(height),
            colour_mode: if settings.colour == crate::settings::ColourMode::Rgb
                && !self.ds.has_rgb()
            {
                crate::settings::ColourMode::Elevation.shader_code()
            } else {
                settings.colour.shader_code()
            },
            z_min: bmin.z,
            z_max: bmax.z,
            arena_shift: self.cache.arena_shift,
            edl_strength: match settings.pipeline {
                Pipeline::Edl => settings.edl_strength.max(1e-3),
                Pipeline::Pyramid if settings.pyramid_edl => settings.edl_strength.max(1e-3),
                Pipeline::Points | Pipeline::Pyramid => 0.0,
            },
            edl_radius: settings.edl_radius,
            background: r as u32 | (g as u32) << 8 | (b as u32) << 16 | 255 << 24,
            arena_slots: [u32::MAX; 4],
        };
        let mut encoder = self
            .ctx
            .device
            .create_command_encoder(&wgpu::CommandEncoderDescriptor {
                label: Some("frame"),
            });
        self.timer.begin_frame(self.wall_clock(settings));
        self.last_int64 = screen.keys.is_some() && !settings.force_int32;
        self.last_pyramid = pyramid;
        let focal_px = camera.focal_px(height);
        // Without points there is no scale; any positive s0 leaves an empty frame empty.
        let pyramid_frame = pyramid.then(|| PyramidFrame {
            s0: s0.unwrap_or(1.0),
            fov_y: camera.fov_y,
            far,
            focal_px,
        });
        self.passes.encode(
            &self.ctx,
            &mut encoder,
            screen,
            &self.cache,
            &FrameDraw {
                uniforms: &uniforms,
                arenas: &draws,
                allow_fused: settings.fused_finish,
                force_int32: settings.force_int32,
                pyramid: pyramid_frame,
            },
            &mut self.timer,
        );
        self.timer.resolve(&mut encoder);
        if let Some(p) = screen.pyramid.as_ref().filter(|_| pyramid) {
            p.record_depth_noise(&mut encoder, &mut self.noise_readback);
        }
        self.ctx.queue.submit([encoder.finish()]);
        self.timer.after_submit();
        self.noise_readback.after_submit();
        // Non-blocking: lets map callbacks of earlier frames run.
        let _ = self.ctx.device.poll(wgpu::PollType::Poll);
    }

    /// Whether `settings` time the passes by the wall clock on this adapter.
    fn wall_clock(&self, settings: &Settings) -> bool {
        match settings.pass_clock {
            PassClock::Wall => true,
            PassClock::Timestamps => false,
            PassClock::Auto => self.auto_wall_clock,
        }
    }

    /// Waits for the GPU to finish the submitted work (headless and benchmarks).
    pub fn wait_gpu(&mut self) -> Result<(), ViewerError> {
        self.ctx
            .device
            .poll(wgpu::PollType::wait_indefinitely())
            .map_err(|e| ViewerError::Gpu(format!("waiting for the GPU failed: {e}")))?;
        self.collect_readbacks();
        Ok(())
    }

    /// Takes what arrived of the pass times and the depth noise (after polling the device).
    fn collect_readbacks(&mut self) {
        self.timer.collect();
        if let Some(bytes) = self.noise_readback.take() {
            self.depth_noise = depth_noise_from(&bytes);
        }
    }

    /// The latest pass times (after `wait_gpu`).
    pub fn pass_times(&self) -> BTreeMap<String, f64> {
        self.timer.last().clone()
    }

    /// Reads the output image back as tightly packed RGBA8 rows.
    pub fn read_image(&self) -> Result<(u32, u32, Vec<u8>), ViewerError> {
        let screen = self
            .screen
            .as_ref()
            .ok_or_else(|| ViewerError::Gpu("no frame has been rendered".into()))?;
        let rgba = read_texture(&self.ctx, &screen.output, 4)?;
        Ok((screen.width, screen.height, rgba))
    }

    /// The depth noise the pyramid pipeline measured in the last frame, as a deviation in
    /// dataset units; `None` when the last frame was drawn by another pipeline.
    pub fn read_depth_noise(&self) -> Result<Option<f32>, ViewerError> {
        match self.screen.as_ref().and_then(|s| s.pyramid.as_ref()) {
            Some(p) if self.last_pyramid => Ok(Some(p.read_depth_noise(&self.ctx)?)),
            _ => Ok(None),
        }
    }

    /// Linear depth per pixel (`None` where nothing was drawn), for picking and tests.
    pub fn read_depths(&self) -> Result<Vec<Option<f32>>, ViewerError> {
        Ok(self
            .read_surface()?
            .into_iter()
            .map(|p| p.map(|p| p.depth))
            .collect())
    }

    /// The surface the last frame shows, per pixel: its linear depth, and its view-space normal
    /// where the pipeline estimates one (`pyramid`). `None` where the frame shows background.
    pub fn read_surface(&self) -> Result<Vec<Option<SurfacePixel>>, ViewerError> {
        let screen = self
            .screen
            .as_ref()
            .ok_or_else(|| ViewerError::Gpu("no frame has been rendered".into()))?;
        let pixels = screen.width as u64 * screen.height as u64;
        if let Some(p) = screen.pyramid.as_ref().filter(|_| self.last_pyramid) {
            let data = read_buffer(&self.ctx, &p.surface, pixels * 8)?;
            return Ok(data
                .chunks_exact(8)
                .map(|b| {
                    let depth = u32::from_le_bytes([b[0], b[1], b[2], b[3]]);
                    let normal = u32::from_le_bytes([b[4], b[5], b[6], b[7]]);
                    (depth != u32::MAX).then(|| SurfacePixel {
                        depth: f32::from_bits(depth),
                        normal: Some(decode_octahedral(normal)),
                    })
                })
                .collect());
        }
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

/// Inverse of `encode_normal` in pyramid.wgsl (two snorm16 octahedral coordinates).
fn decode_octahedral(e: u32) -> [f32; 3] {
    let snorm = |v: u32| ((v & 0xffff) as u16 as i16 as f32 / 32767.0).clamp(-1.0, 1.0);
    let (px, py) = (snorm(e), snorm(e >> 16));
    let mut n = glam::Vec3::new(px, py, 1.0 - px.abs() - py.abs());
    if n.z < 0.0 {
        let (x, y) = (n.x, n.y);
        n.x = (1.0 - y.abs()) * if x >= 0.0 { 1.0 } else { -1.0 };
        n.y = (1.0 - x.abs()) * if y >= 0.0 { 1.0 } else { -1.0 };
    }
    n.normalize_or_zero().to_array()
}
