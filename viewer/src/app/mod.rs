//! `strata view`: the window. The same `Renderer` as headless draws into a texture that egui
//! shows beside the panel of settings and live statistics.

use crate::camera::Camera;
use crate::gpu::{GpuContext, ProjectionPath};
use crate::headless::{default_camera, write_png};
use crate::pipelines::REGISTRY;
use crate::renderer::{FrameStats, Renderer};
use crate::settings::{ColourMode, MAX_BUDGET, MIN_BUDGET, Settings, SizeMode};
use crate::{HttpOptions, StreamDataset, ViewerError};
use eframe::egui;
use std::path::PathBuf;
use std::sync::Arc;
use std::sync::atomic::{AtomicBool, Ordering};
use std::time::Instant;

mod clip;
mod filters;
mod measure;
mod navigate;
mod params;
mod profile;
mod views;
mod window_failure;

pub use profile::PointsWriter;

pub struct WindowOptions {
    pub settings: Settings,
    pub gpu_cache_bytes: u64,
    pub loader_threads: usize,
    pub projection: ProjectionPath,
    /// Save a screenshot of the whole window after this many frames, then close (for tests
    /// and documentation).
    pub screenshot: Option<(PathBuf, u32)>,
    pub size: (u32, u32),
    pub token: Option<String>,
    /// Measurements to show at start (else the dataset's own measurements.geojson).
    pub measurements: Option<crate::measure::Measurements>,
    /// A height profile to read and show at start.
    pub profile: Option<crate::profile::Corridor>,
    /// How the profile window writes LAS, LAZ and PLY (the viewer itself writes CSV only).
    pub points_writer: Option<PointsWriter>,
}

struct ViewerApp {
    renderer: Renderer,
    camera: Camera,
    home: Camera,
    settings: Settings,
    /// The renderer's output as egui shows it: re-registered whenever the output changes.
    texture: Option<(egui::TextureId, wgpu::Texture)>,
    stats: FrameStats,
    frames: u32,
    /// Frames still to draw of an unchanged view, for pipelines that converge over frames
    /// (`PipelineInfo::warmup_frames`), and the view they are counted for (camera, pipeline,
    /// parameters, size, point filters).
    settling: (u32, Option<SettleKey>),
    last_frame: Instant,
    io_rate: f64,
    frame_ms_avg: f64,
    scene_size: f32,
    /// The dataset's real-world elevation range, for the elevation filter.
    bounds_z: (f64, f64),
    /// The last value of each automatic parameter, which its manual slider is centred on.
    auto_values: std::collections::HashMap<(&'static str, &'static str), f32>,
    /// The frame failed (a GPU fault, a lost device): shown in the panel, nothing drawn.
    error: Option<String>,
    /// The renderer's node failures already written to stderr.
    errors_reported: usize,
    views: views::Views,
    measuring: measure::Measuring,
    /// The clip box handle being dragged.
    clip_drag: Option<clip::Handle>,
    /// The attributes a range may be set on, with their ranges in the root node (read once).
    attribute_ranges: Option<Vec<(String, f64, f64)>>,
    /// The attribute range being edited in the panel, and why the last one was refused.
    attribute_edit: (String, f64, f64),
    attribute_error: Option<String>,
    profiling: profile::Profiling,
    /// The point last clicked, as stored (or why none could be read).
    picked: Option<Result<crate::pick::PickedPoint, String>>,
    /// The size the scene is rendered at, where the adapter holds less than the window asks.
    reduced: Option<(u32, u32, u32, u32)>,
    screenshot: Option<(PathBuf, u32)>,
    screenshot_done: Arc<AtomicBool>,
    screenshot_error: Arc<std::sync::Mutex<Option<String>>>,
}

/// Opens the window and runs until it is closed.
pub fn run_window(location: &str, opts: WindowOptions) -> Result<(), ViewerError> {
    let http = HttpOptions {
        token: opts.token.clone(),
        ..HttpOptions::default()
    };
    let ds = Arc::new(StreamDataset::open(location, http)?);
    ds.check_colour(opts.settings.colour)?;
    ds.check_filter(&opts.settings.filter)?;
    let ctx = Arc::new(GpuContext::new(opts.projection)?);
    let renderer = Renderer::new(
        ctx.clone(),
        ds.clone(),
        opts.gpu_cache_bytes,
        opts.loader_threads,
    )?;
    // The scene's part of the window: all but the 280-point panel.
    let home = default_camera(&ds, opts.size.0.saturating_sub(280).max(1), opts.size.1);
    let (min, max) = ds.bounds();
    let screenshot_error = Arc::new(std::sync::Mutex::new(None));
    let mut app = ViewerApp {
        renderer,
        camera: home,
        home,
        settings: opts.settings,
        auto_values: Default::default(),
        error: None,
        errors_reported: 0,
        views: views::Views::open(location),
        measuring: measure::Measuring::open(location, opts.measurements),
        clip_drag: None,
        attribute_ranges: None,
        attribute_edit: (String::new(), 0.0, 1.0),
        attribute_error: None,
        profiling: profile::Profiling::new(opts.points_writer),
        picked: None,
        reduced: None,
        texture: None,
        stats: FrameStats::default(),
        frames: 0,
        settling: (0, None),
        last_frame: Instant::now(),
        io_rate: 0.0,
        frame_ms_avg: 0.0,
        scene_size: (max - min).length().max(1e-3),
        bounds_z: (ds.metadata().bounds.min[2], ds.metadata().bounds.max[2]),
        screenshot: opts.screenshot,
        screenshot_done: Arc::new(AtomicBool::new(false)),
        screenshot_error: screenshot_error.clone(),
    };
    if let Some(corridor) = opts.profile {
        // The line is drawn at the lowest height of the dataset: the ground, mostly.
        let z = ds.metadata().bounds.min[2];
        app.profiling.line = corridor.line.iter().map(|p| [p[0], p[1], z]).collect();
        app.profiling.width = corridor.width;
        app.profiling.start(ds.clone());
    }
    let native = eframe::NativeOptions {
        viewport: egui::ViewportBuilder::default()
            .with_title(format!("Strata: {}", ds.location()))
            .with_inner_size([opts.size.0 as f32, opts.size.1 as f32]),
        renderer: eframe::Renderer::Wgpu,
        wgpu_options: eframe::egui_wgpu::WgpuConfiguration {
            wgpu_setup: eframe::egui_wgpu::WgpuSetup::Existing(
                eframe::egui_wgpu::WgpuSetupExisting {
                    instance: ctx.instance.clone(),
                    adapter: ctx.adapter.clone(),
                    device: ctx.device.clone(),
                    queue: ctx.queue.clone(),
                },
            ),
            ..Default::default()
        },
        ..Default::default()
    };
    eframe::run_native("strata", native, Box::new(move |_cc| Ok(Box::new(app))))
        .map_err(|e| ViewerError::Window(window_failure::window_failure(&e)))?;
    match screenshot_error.lock().map(|mut e| e.take()) {
        Ok(Some(e)) => Err(ViewerError::Gpu(e)),
        _ => Ok(()),
    }
}

/// What a view's convergence over frames depends on.
type SettleKey = (
    Camera,
    &'static str,
    crate::pipelines::params::ParamValues,
    (u32, u32),
    crate::settings::PointFilter,
);

impl eframe::App for ViewerApp {
    fn ui(&mut self, ui: &mut egui::Ui, frame: &mut eframe::Frame) {
        let ctx = ui.ctx().clone();
        egui::Panel::left("settings")
            .resizable(false)
            .exact_size(280.0)
            .show(ui, |ui| {
                egui::ScrollArea::vertical().show(ui, |ui| self.panel(ui));
            });
        egui::CentralPanel::default()
            .frame(egui::Frame::NONE)
            .show(ui, |ui| self.scene(ui, frame));
        self.profile_window(&ctx);
        self.take_screenshot(&ctx);
        if !self.stats.complete || self.screenshot.is_some() || self.settling.0 > 0 {
            ctx.request_repaint();
        }
    }
}

impl ViewerApp {
    fn panel(&mut self, ui: &mut egui::Ui) {
        ui.heading("Strata");
        ui.label(self.renderer.dataset().location());
        ui.separator();

        ui.label("Point budget");
        let mut log_budget = (self.settings.budget as f64).log10();
        let slider = egui::Slider::new(
            &mut log_budget,
            (MIN_BUDGET as f64).log10()..=(MAX_BUDGET as f64).log10(),
        )
        .show_value(false);
        if ui.add(slider).changed() {
            self.settings.budget = 10f64.powf(log_budget).round() as u64;
        }
        ui.label(format!("{} points", group_digits(self.settings.budget)));
        let root = self.renderer.dataset().root_points();
        if root > self.stats.budget_drawn && self.stats.frame > 0 {
            let limit = if self.stats.budget_drawn < self.settings.budget {
                "what the GPU cache holds"
            } else {
                "the budget"
            };
            ui.colored_label(
                egui::Color32::LIGHT_RED,
                format!(
                    "Nothing is drawn: the root node alone holds {} points, more than {limit}",
                    group_digits(root)
                ),
            );
        }

        ui.label("Pipeline");
        ui.horizontal_wrapped(|ui| {
            for p in REGISTRY {
                let chosen = std::ptr::eq(self.settings.pipeline, *p);
                if ui
                    .radio(chosen, p.name)
                    .on_hover_text(p.description)
                    .clicked()
                {
                    self.settings.pipeline = p;
                }
            }
        });
        self.pipeline_controls(ui);

        self.filter_controls(ui);
        self.clip_controls(ui);
        self.measure_controls(ui);
        self.profile_controls(ui);
        self.view_controls(ui);

        let sized = self.settings.pipeline.uses_point_size;
        let size = ui.add_enabled_ui(sized, |ui| {
            ui.label("Point size");
            ui.add(egui::Slider::new(&mut self.settings.point_size, 0.5..=10.0));
            let mut attenuate = self.settings.size_mode == SizeMode::Attenuated;
            if ui
                .checkbox(&mut attenuate, "size by point spacing")
                .changed()
            {
                self.settings.set_size_mode(if attenuate {
                    SizeMode::Attenuated
                } else {
                    SizeMode::Fixed
                });
            }
        });
        size.response.on_disabled_hover_text(format!(
            "the point size does not change what {} draws",
            self.settings.pipeline.name
        ));

        ui.label("Colour");
        let ds = self.renderer.dataset().clone();
        egui::Grid::new("colour").num_columns(2).show(ui, |ui| {
            for (i, c) in ColourMode::ALL.into_iter().enumerate() {
                // Greyed where the dataset lacks the attribute (normals: convert --normals).
                ui.add_enabled_ui(ds.offers(c), |ui| {
                    ui.radio_value(&mut self.settings.colour, c, c.name())
                        .on_disabled_hover_text(format!(
                            "the dataset has no \"{}\" attribute (convert it with --normals)",
                            c.attribute().unwrap_or_default()
                        ));
                });
                if i % 2 == 1 {
                    ui.end_row();
                }
            }
        });
        ui.add(egui::Slider::new(&mut self.settings.min_spacing_px, 0.5..=4.0).text("detail (px)"));
        if ui.button("Reset view (R)").clicked() {
            self.camera = self.home;
        }
        ui.separator();

        if let Some(e) = &self.error {
            ui.colored_label(egui::Color32::LIGHT_RED, e);
        }
        if let Some((w, h, rw, rh)) = self.reduced {
            ui.colored_label(
                egui::Color32::YELLOW,
                format!("rendering at {rw}x{rh} of {w}x{h}: the adapter holds no larger image"),
            );
        }
        match &self.picked {
            Some(Ok(p)) => {
                ui.heading("Picked point");
                for line in p.lines() {
                    ui.label(egui::RichText::new(line).monospace().small());
                }
                if ui.button("Clear").clicked() {
                    self.picked = None;
                }
                ui.separator();
            }
            Some(Err(e)) => {
                ui.colored_label(egui::Color32::LIGHT_RED, e);
            }
            None => {}
        }
        let s = &self.stats;
        ui.heading("Statistics");
        egui::Grid::new("stats").num_columns(2).show(ui, |ui| {
            let mut row = |k: &str, v: String| {
                ui.label(k);
                ui.label(v);
                ui.end_row();
            };
            row("frame", format!("{:.1} ms", self.frame_ms_avg));
            row("points drawn", group_digits(s.points_drawn));
            row("nodes drawn", s.nodes_drawn.to_string());
            row("nodes visible", s.nodes_visible.to_string());
            row("nodes resident", s.nodes_resident.to_string());
            row(
                "in flight / queued",
                format!("{} / {}", s.nodes_in_flight, s.nodes_queued),
            );
            row("failed", s.nodes_failed.to_string());
            row(
                "unavailable",
                format!("{} ({} fetch errors)", s.nodes_unavailable, s.fetch_errors),
            );
            row(
                "GPU memory",
                format!("{:.0} MiB", s.gpu_bytes as f64 / (1 << 20) as f64),
            );
            row("I/O", format!("{:.1} MB/s", self.io_rate / 1e6));
            if let Some(sides) = s.normal_sides {
                row("normals", sides.to_string());
            }
            if !s.passes.is_empty() {
                row("pass clock", s.pass_clock.to_string());
            }
            for (pass, ms) in s.passes.iter() {
                row(&format!("GPU {pass}"), format!("{ms:.2} ms"));
            }
        });
        ui.label(if s.complete {
            "complete"
        } else {
            "streaming..."
        });
        self.failures(ui);
        ui.separator();
        ui.label(&self.renderer.context().adapter_name);
        ui.label(
            egui::RichText::new(self.camera.to_spec(self.renderer.dataset().anchor())).small(),
        );
    }

    /// Why nodes failed, and the latest fetch that found no server: the counts alone said
    /// nothing of which or why. Each failure also goes to stderr once, for the log.
    fn failures(&mut self, ui: &mut egui::Ui) {
        let errors = self.renderer.errors();
        for e in &errors[self.errors_reported.min(errors.len())..] {
            eprintln!("warning: {e}");
        }
        self.errors_reported = errors.len();
        if !errors.is_empty() {
            egui::CollapsingHeader::new(format!("{} failed", errors.len()))
                .id_salt("failures")
                .show(ui, |ui| {
                    // The first ones: a damaged file fails its nodes alike.
                    for e in errors.iter().take(20) {
                        ui.colored_label(egui::Color32::LIGHT_RED, egui::RichText::new(e).small());
                    }
                    if errors.len() > 20 {
                        ui.label(format!("and {} more", errors.len() - 20));
                    }
                });
        }
        if self.stats.nodes_unavailable > 0
            && let Some(e) = self.renderer.last_fetch_error()
        {
            ui.colored_label(
                egui::Color32::YELLOW,
                egui::RichText::new(format!("asked again later: {e}")).small(),
            );
        }
    }

    fn scene(&mut self, ui: &mut egui::Ui, frame: &mut eframe::Frame) {
        let rect = ui.available_rect_before_wrap();
        let response = ui.allocate_rect(rect, egui::Sense::click_and_drag());
        self.navigate(ui, &response, rect);
        let ctx = ui.ctx().clone();
        self.fly_views(&ctx);

        let ppp = ui.ctx().pixels_per_point();
        let w = (rect.width() * ppp).round().max(1.0) as u32;
        let h = (rect.height() * ppp).round().max(1.0) as u32;
        let now = Instant::now();
        let dt = now.duration_since(self.last_frame).as_secs_f64().max(1e-6);
        self.last_frame = now;
        // A window larger than the adapter holds renders at the largest size of its shape
        // that fits, scaled up to the window.
        let (rw, rh) = self.renderer.fit_size(&self.settings, w, h);
        self.reduced = ((rw, rh) != (w, h)).then_some((w, h, rw, rh));
        let (w, h) = (rw, rh);
        match self.renderer.frame(&self.camera, w, h, &self.settings) {
            Ok(stats) => {
                self.frame_ms_avg = self.frame_ms_avg * 0.9 + dt * 1e3 * 0.1;
                self.io_rate = self.io_rate * 0.9 + stats.bytes_loaded as f64 / dt * 0.1;
                let info = self.settings.pipeline;
                let key = (
                    self.camera,
                    info.name,
                    self.settings.params.clone(),
                    (w, h),
                    self.settings.filter.clone(),
                );
                self.settling = if self.settling.1.as_ref() != Some(&key) || !stats.complete {
                    (info.warmup_frames(&self.settings.params), Some(key))
                } else {
                    (self.settling.0.saturating_sub(1), self.settling.1.take())
                };
                self.stats = stats;
                self.error = None;
            }
            Err(e) => self.error = Some(e.to_string()),
        }
        self.frames += 1;
        // A lost device cannot draw again, and painting on it would fail inside egui: close
        // the window and report why.
        if let Some(lost) = self.renderer.context().lost_error() {
            if let Ok(mut slot) = self.screenshot_error.lock() {
                slot.get_or_insert(lost.to_string());
            }
            self.texture = None;
            ui.ctx().send_viewport_cmd(egui::ViewportCommand::Close);
            return;
        }

        let Some(state) = frame.wgpu_render_state() else {
            return;
        };
        let Some(output) = self.renderer.output() else {
            return;
        };
        let stale = self
            .texture
            .as_ref()
            .is_none_or(|(_, shown)| shown != output);
        if stale {
            let view = output.create_view(&Default::default());
            let mut egui_renderer = state.renderer.write();
            if let Some((old, _)) = self.texture.take() {
                egui_renderer.free_texture(&old);
            }
            let id = egui_renderer.register_native_texture(
                &state.device,
                &view,
                wgpu::FilterMode::Nearest,
            );
            self.texture = Some((id, output.clone()));
        }
        if let Some((id, shown)) = &self.texture {
            let id = *id;
            let size = (shown.width(), shown.height());
            ui.painter().image(
                id,
                rect,
                egui::Rect::from_min_max(egui::pos2(0.0, 0.0), egui::pos2(1.0, 1.0)),
                egui::Color32::WHITE,
            );
            self.paint_measurements(ui.painter(), rect, size);
            self.paint_profile(ui.painter(), rect, size);
            self.paint_clips(ui.painter(), rect, size);
        }
    }

    fn take_screenshot(&mut self, ctx: &egui::Context) {
        let Some((path, after)) = &self.screenshot else {
            return;
        };
        if self.screenshot_done.load(Ordering::Acquire) {
            ctx.send_viewport_cmd(egui::ViewportCommand::Close);
            return;
        }
        // egui never answers a screenshot it cannot take (an unusual surface format, a failed
        // map): give up rather than wait for ever.
        if self.frames > *after + SCREENSHOT_PATIENCE {
            if let Ok(mut slot) = self.screenshot_error.lock() {
                slot.get_or_insert(format!(
                    "{}: no screenshot arrived within {SCREENSHOT_PATIENCE} frames",
                    path.display()
                ));
            }
            self.screenshot_done.store(true, Ordering::Release);
            ctx.send_viewport_cmd(egui::ViewportCommand::Close);
            return;
        }
        if self.frames == *after {
            let path = path.clone();
            let done = self.screenshot_done.clone();
            let error = self.screenshot_error.clone();
            let repaint = ctx.clone();
            ctx.request_screenshot(move |image| {
                let rgba: Vec<u8> = image.pixels.iter().flat_map(|c| c.to_array()).collect();
                if let Err(e) = write_png(&path, image.size[0] as u32, image.size[1] as u32, &rgba)
                    && let Ok(mut slot) = error.lock()
                {
                    *slot = Some(e.to_string());
                }
                done.store(true, Ordering::Release);
                repaint.request_repaint();
            });
        }
    }
}

/// Frames a requested screenshot may take to arrive.
const SCREENSHOT_PATIENCE: u32 = 300;

fn group_digits(n: u64) -> String {
    let s = n.to_string();
    let mut out = String::new();
    for (i, c) in s.chars().enumerate() {
        if i > 0 && (s.len() - i).is_multiple_of(3) {
            out.push(',');
        }
        out.push(c);
    }
    out
}
