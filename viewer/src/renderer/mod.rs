//! One frame of the viewer, the same in the window and headless: take what the loaders
//! finished, upload it, choose nodes under the budget, ask for what is missing, and draw what is
//! resident. Nothing here waits for I/O.

use crate::ViewerError;
use crate::camera::Camera;
use crate::dataset::{GpuNode, StreamDataset};
use crate::gpu::GpuContext;
use crate::gpu::cache::{InsertError, NodeCache};
use crate::gpu::timing::{PassClock, Timer};
use crate::loader::{Done, Job, JobKey, Loader};
use crate::lod::{ClipRegion, Selection, SelectionParams, Tree, drawn_spacing, select};
use crate::marks::Marks;
use crate::pipelines::params::ResolvedParams;
use crate::pipelines::projection::{DrawnCount, FacingCheck};
use crate::pipelines::projection::{
    Projection, Screen, ScreenLimitError, check_screen, largest_fitting,
};
use crate::pipelines::{self, Pipeline, PipelineInfo, ScreenBuffer};
use crate::settings::Settings;
use std::collections::{BTreeMap, HashMap, HashSet, VecDeque};

mod draw;
mod guard;
mod readback;
mod stats;

use guard::Guard;
pub use readback::SurfacePixel;
pub use stats::FrameStats;
use std::sync::Arc;
use std::time::{Duration, Instant};
use strata_format::NodeKey;

pub struct Renderer {
    ctx: Arc<GpuContext>,
    ds: Arc<StreamDataset>,
    tree: Tree,
    loader: Loader,
    cache: NodeCache,
    projection: Projection,
    /// The points that pass the filters, counted on the GPU while a filter is set.
    drawn_count: crate::pipelines::projection::DrawnCount,
    /// Which side of the surfaces the stored normals point to, as the views show it.
    facing: FacingCheck,
    /// Whether the last frame had a filter (its points drawn are the counted ones).
    filtered: bool,
    /// The filters the drawn count was last made for.
    counted_filter: crate::PointFilter,
    /// Pipelines compiled so far, by name; only the active one holds screen buffers.
    pipelines: HashMap<&'static str, Box<dyn Pipeline>>,
    /// The pipeline whose screen buffers exist.
    active: Option<&'static str>,
    screen: Option<Screen>,
    /// The guard band the screen was made for, and the view cut out of its output where the
    /// band is not empty.
    guard: Guard,
    shown: Option<wgpu::Texture>,
    timer: Timer,
    /// What the active pipeline measured, latest first arrived.
    measures: BTreeMap<&'static str, f32>,
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
    /// The last frame ended in the fused finish (its colour plane was not written).
    last_fused: bool,
    /// The last frame resolved the projection's colour plane.
    last_colour_plane: bool,
    /// The last frame's view: for pipelines that keep the previous frame, and for picking.
    previous_view: Option<crate::pipelines::ViewFrame>,
    frame: u64,
    bytes_total: u64,
}

/// The guard band of a `width` x `height` view drawn with the settings' pipeline.
fn guard_of(settings: &Settings, width: u32, height: u32) -> Guard {
    Guard {
        px: settings.pipeline.guard_px(&settings.params),
        width,
        height,
    }
}

/// Pixels on a side of a pipeline's extra view, for its level of detail (the light map's
/// size at most).
const EXTRA_VIEW_PX: u32 = 1024;

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
        let tree = Tree::of(&ds)?;
        let loader = Loader::new(ds.clone(), loader_threads);
        let cache = NodeCache::new(ctx.max_binding(), gpu_cache_bytes);
        let (projection, drawn_count, facing) =
            ctx.scoped("compiling the projection", || {
                Projection::new(&ctx).map(|p| {
                    let device = &ctx.device;
                    (p, DrawnCount::new(device), FacingCheck::new(device))
                })
            })??;
        let timer = Timer::new(
            &ctx.device,
            &ctx.queue,
            ctx.timestamps,
            pipelines::max_timed_passes(),
        );
        let auto_wall_clock =
            !ctx.timestamps || ctx.adapter.get_info().device_type == wgpu::DeviceType::Cpu;
        Ok(Renderer {
            ctx,
            ds,
            tree,
            loader,
            cache,
            projection,
            drawn_count,
            facing,
            filtered: false,
            counted_filter: crate::PointFilter::default(),
            pipelines: HashMap::new(),
            active: None,
            screen: None,
            guard: Guard::default(),
            shown: None,
            timer,
            measures: BTreeMap::new(),
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
            last_fused: false,
            last_colour_plane: false,
            previous_view: None,
            frame: 0,
            bytes_total: 0,
        })
    }

    /// The points the last frame's filters let through, counted on the GPU, once read back;
    /// `None` without a filter (every point of the drawn nodes is drawn) or before any count.
    pub fn counted_points_drawn(&mut self) -> Option<u64> {
        if !self.filtered {
            return None;
        }
        self.drawn_count.latest()
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

    /// The last frame's image, the view without its guard band.
    pub fn output(&self) -> Option<&wgpu::Texture> {
        self.shown
            .as_ref()
            .or_else(|| self.screen.as_ref().map(|s| &s.output))
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
                self.tree.measured(node.key, node.sampling);
                self.uploads.push_back(node);
            }
            Done::NodeFailed(key, e) if e.is_transient() => self.unavailable(JobKey::Node(key), e),
            Done::NodeFailed(key, e) => {
                self.failed.insert(key);
                self.errors.push(e.to_string());
            }
            Done::Page(page) => {
                if let Err(what) = self.tree.add_page(&page) {
                    self.pages_failed += 1;
                    self.errors.push(format!("{}: {what}", self.ds.location()));
                }
            }
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

    /// The buffers a `width` x `height` frame of `pipeline` needs.
    fn screen_buffers(
        &self,
        pipeline: &PipelineInfo,
        width: u32,
        height: u32,
    ) -> Vec<ScreenBuffer> {
        let mut b = self.projection.screen_buffers(width, height);
        b.extend((pipeline.screen_buffers)(width, height));
        b
    }

    /// Whether a `width` x `height` frame of the settings' pipeline fits the adapter, its
    /// guard band included, in one sentence naming the size, the buffer and the limit where it
    /// does not.
    pub fn check_size(
        &mut self,
        settings: &Settings,
        width: u32,
        height: u32,
    ) -> Result<(), ViewerError> {
        self.check_guarded(settings.pipeline, guard_of(settings, width, height))
    }

    fn check_guarded(
        &mut self,
        pipeline: &'static PipelineInfo,
        guard: Guard,
    ) -> Result<(), ViewerError> {
        self.pipeline(pipeline)?;
        let limits = self.ctx.device.limits();
        let (w, h) = guard.padded();
        check_screen(&limits, w, h, &self.screen_buffers(pipeline, w, h)).map_err(|e| {
            let (fit_w, fit_h) = self.fit_guarded(pipeline, guard);
            let e = ScreenLimitError {
                width: guard.width,
                height: guard.height,
                ..e
            };
            let band = match guard.px {
                0 => String::new(),
                px => format!(" (drawn with {px} pixels more on every side, the guard band)"),
            };
            ViewerError::Gpu(format!(
                "{e}{band} on {}; the largest image of that shape it holds is {fit_w}x{fit_h}",
                self.ctx.adapter_name
            ))
        })
    }

    /// The largest size of the shape of `width` x `height`, at most that, that a frame of the
    /// settings' pipeline can have on this adapter (the window renders at that and scales up).
    pub fn fit_size(&self, settings: &Settings, width: u32, height: u32) -> (u32, u32) {
        let guard = guard_of(settings, width.max(1), height.max(1));
        self.fit_guarded(settings.pipeline, guard)
    }

    fn fit_guarded(&self, pipeline: &PipelineInfo, guard: Guard) -> (u32, u32) {
        let limits = self.ctx.device.limits();
        largest_fitting(guard.width, guard.height, |width, height| {
            let (w, h) = Guard {
                width,
                height,
                ..guard
            }
            .padded();
            check_screen(&limits, w, h, &self.screen_buffers(pipeline, w, h)).is_ok()
        })
    }

    /// The compiled pipeline `info`, compiling it on first use.
    fn pipeline(&mut self, info: &'static PipelineInfo) -> Result<(), ViewerError> {
        if !self.pipelines.contains_key(info.name) {
            let what = format!("compiling the {} pipeline", info.name);
            let p = self.ctx.scoped(&what, || (info.create)(&self.ctx))??;
            self.pipelines.insert(info.name, p);
        }
        Ok(())
    }

    /// Renders one frame of `width` x `height` into the output texture. A GPU fault, a lost
    /// device or a size the adapter cannot hold is an error, never a panic.
    pub fn frame(
        &mut self,
        camera: &Camera,
        width: u32,
        height: u32,
        settings: &Settings,
    ) -> Result<FrameStats, ViewerError> {
        if let Some(fault) = self.ctx.take_fault() {
            return Err(fault);
        }
        let start = Instant::now();
        self.frame += 1;
        // Everything below draws the padded frame; the view is cut out of it at the end.
        let guard = guard_of(settings, width.max(1), height.max(1));
        let (width, height) = guard.padded();
        let camera = &guard.camera(camera);
        let mut bytes = 0u64;
        let finished: Vec<Done> = self.loader.finished().collect();
        for done in finished {
            self.accept(done, &mut bytes);
        }
        self.bytes_total += bytes;
        // Colouring by normal puts the normals where the stored colours were, and ranges of
        // attributes the GPU does not hold are marked at load: a change of either loads every
        // node again.
        let form = (
            self.ds.colour_word(settings.colour),
            self.ds.marks(&settings.filter)?,
        );
        if form != self.loader.form() {
            self.loader.set_form(form.0, form.1.clone());
            self.cache.clear();
        }
        // The cache holds a pipeline's per-point streams only while that pipeline is active,
        // and those of its shadows only while they are on.
        let ctx = self.ctx.clone();
        let streams = crate::pipelines::shadows::streams(settings.pipeline, &settings.params);
        ctx.scoped("uploading nodes to the GPU", || {
            self.cache.set_streams(&ctx.device, &streams);
            self.upload(settings, &form);
        })?;

        let params = SelectionParams {
            // More than the cache holds would evict what the same frame draws, for ever; a
            // 10 % margin leaves room for fragmentation.
            budget: settings.budget.min(self.cache.capacity_points() / 10 * 9),
            width,
            height,
            min_spacing_px: settings.min_spacing_px,
        };
        let anchor = self.ds.anchor();
        let rel = |v: [f64; 3]| (glam::DVec3::from_array(v) - anchor).as_vec3();
        let mut region = ClipRegion::default();
        for c in &settings.filter.clips {
            let target = if c.outside {
                &mut region.hide
            } else {
                &mut region.keep
            };
            target.push((rel(c.min), rel(c.max)));
        }
        let cache = &self.cache;
        let sel = select(
            &self.tree,
            &self.ds,
            camera,
            &params,
            |k| cache.contains(k),
            &self.failed,
            &region,
        );
        let info = settings.pipeline;
        let (tree, ds) = (&self.tree, &self.ds);
        let resolved = ResolvedParams::resolve(&settings.params, info, || {
            drawn_spacing(tree, ds, &sel.draw)
        });
        // The pipeline's second view (the light's), within what the cache holds beside the
        // camera's nodes.
        let extra = self
            .pipelines
            .get(info.name)
            .and_then(|p| p.extra_view(&resolved, camera, self.ds.bounds().into()))
            .map(|(view, budget)| {
                let room =
                    (self.cache.capacity_points() / 10 * 9).saturating_sub(sel.chosen_points);
                let light = SelectionParams {
                    budget: budget.min(room),
                    width: EXTRA_VIEW_PX,
                    height: EXTRA_VIEW_PX,
                    min_spacing_px: settings.min_spacing_px,
                };
                select(
                    tree,
                    ds,
                    &view,
                    &light,
                    |k| cache.contains(k),
                    &self.failed,
                    &region,
                )
            });
        self.request(&sel, extra.as_ref());
        self.cache.touch(&sel.draw, self.frame);
        if let Some(e) = &extra {
            self.cache.touch(&e.draw, self.frame);
        }
        self.last_drawn = sel.draw.iter().copied().collect();
        if settings.filter != self.counted_filter {
            self.counted_filter = settings.filter.clone();
            self.drawn_count.filters_changed();
        }
        let facing = self.draw(camera, guard, settings, (&sel, extra.as_ref()), &resolved)?;
        self.collect_readbacks();
        // Drawn with the check of its own view, and no verdict arrived since (one made for
        // another view, still in flight).
        let facing_settled =
            facing.is_none_or(|(settled, sides)| settled && sides == self.facing.sides());
        self.filtered = settings.filter != crate::PointFilter::default();
        // While a filter is set, the count of the points it let through (in the window, of a
        // frame or two before: it is read back without waiting).
        let points_drawn = match self.counted_points_drawn() {
            Some(n) => n,
            None => sel.draw_points,
        };

        let (queued, in_flight) = self.loader.counts();
        Ok(FrameStats {
            frame: self.frame,
            points_drawn,
            budget_drawn: params.budget,
            nodes_drawn: sel.draw.len(),
            frame_ms: start.elapsed().as_secs_f64() * 1e3,
            pipeline: info.name,
            params: resolved.iter().collect(),
            measures: self.measures.clone(),
            note: self
                .active
                .and_then(|n| self.pipelines.get(n))
                .and_then(|p| p.note()),
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
            complete: sel.missing_nodes.is_empty()
                && sel.missing_pages.is_empty()
                && extra
                    .as_ref()
                    .is_none_or(|e| e.missing_nodes.is_empty() && e.missing_pages.is_empty())
                && self.uploads.is_empty()
                && facing_settled,
            normal_sides: facing.map(|(_, sides)| sides.name()),
        })
    }

    fn upload(&mut self, settings: &Settings, form: &(crate::dataset::ColourWord, Marks)) {
        let mut budget = settings.upload_points_per_frame.unwrap_or(u64::MAX);
        let mut first = true;
        while let Some(node) = self.uploads.front() {
            // Loaded for the colouring or marks before the last change: it is asked for again.
            if node.colours != form.0 || node.marks != form.1 {
                self.uploads.pop_front();
                continue;
            }
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

    /// Asks the loader for what the view misses, most important first, then what the
    /// pipeline's extra view misses.
    fn request(&mut self, sel: &Selection, extra: Option<&Selection>) {
        let now = Instant::now();
        self.retry_after.retain(|_, t| *t > now);
        let waiting: HashSet<NodeKey> = self.uploads.iter().map(|u| u.key).collect();
        let jobs_of = |sel: &Selection| {
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
            jobs.into_iter().map(|(_, j)| j)
        };
        let mut jobs: Vec<Job> = jobs_of(sel).collect();
        if let Some(e) = extra {
            let asked: HashSet<JobKey> = jobs.iter().map(Job::key).collect();
            let more: Vec<Job> = jobs_of(e).filter(|j| !asked.contains(&j.key())).collect();
            jobs.extend(more);
        }
        self.loader.set_wanted(jobs);
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
        self.ctx.wait()?;
        self.collect_readbacks();
        Ok(())
    }

    /// Takes what arrived of the pass times and the pipeline's measures (after polling).
    fn collect_readbacks(&mut self) {
        self.timer.collect();
        self.facing.take();
        if let Some(p) = self.active.and_then(|n| self.pipelines.get_mut(n)) {
            self.measures = p.measures();
        }
    }
}
