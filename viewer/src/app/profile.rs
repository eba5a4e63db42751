//! The panel's height profile: a polyline clicked on the scene (or given with `strata view
//! --profile`), a corridor width, and the points within it shown as distance against height in
//! a window of their own, read in the background level by level, and exported as CSV or (with
//! the writer the binary hands in) LAS, LAZ or PLY.

use super::ViewerApp;
use crate::dataset::StreamDataset;
use crate::overlay::ScreenProjector;
use crate::profile::{Corridor, Profile, ProfileDetail, extract};
use eframe::egui;
use std::path::Path;
use std::sync::Arc;
use std::sync::mpsc::{Receiver, channel};

/// Writes a profile's points with every attribute (LAS, LAZ or PLY by the extension).
pub type PointsWriter = fn(&StreamDataset, &Profile, &Path) -> Result<(), String>;

/// Pixels across the profile a point is read for: the level of detail is the line's length
/// over this.
const DETAIL_PX: f64 = 2000.0;
/// Points read at most for one profile.
const MAX_READ: u64 = 20_000_000;
/// The plot's size in points.
const PLOT: [f32; 2] = [560.0, 200.0];

pub struct Profiling {
    /// Clicks add vertices to the line.
    pub drawing: bool,
    /// The line's vertices as picked (their heights place the line in the view).
    pub line: Vec<[f64; 3]>,
    pub width: f64,
    pub result: Option<Profile>,
    pending: Option<Receiver<Result<Profile, String>>>,
    pub file: String,
    pub error: Option<String>,
    pub writer: Option<PointsWriter>,
    /// The plot as an image, and the profile it shows (generation, points and level).
    plot: Option<(egui::TextureHandle, (u64, usize, u32))>,
    /// Counts the profiles started, so that a plot is never taken for another's.
    generation: u64,
}

impl Profiling {
    pub fn new(writer: Option<PointsWriter>) -> Profiling {
        Profiling {
            drawing: false,
            line: Vec::new(),
            width: 1.0,
            result: None,
            pending: None,
            file: "profile.csv".into(),
            error: None,
            writer,
            plot: None,
            generation: 0,
        }
    }

    fn corridor(&self) -> Corridor {
        Corridor {
            line: self.line.iter().map(|p| [p[0], p[1]]).collect(),
            width: self.width,
        }
    }

    /// Starts reading the profile of the line in the background.
    pub fn start(&mut self, ds: Arc<StreamDataset>) {
        let corridor = self.corridor();
        if let Err(e) = corridor.check() {
            self.error = Some(e);
            return;
        }
        let (tx, rx) = channel();
        let detail = ProfileDetail {
            spacing: corridor.length() / DETAIL_PX,
            max_points_read: MAX_READ,
        };
        // A profile nobody waits for any more (cleared, or started again) stops after the
        // level it is reading: its receiver is gone.
        std::thread::spawn(move || {
            let last = extract(&ds, &corridor, detail, |p| tx.send(Ok(p.clone())).is_ok());
            if let Err(e) = last {
                let _ = tx.send(Err(e.to_string()));
            }
        });
        self.pending = Some(rx);
        self.result = None;
        self.generation += 1;
        self.error = None;
    }

    /// Takes in what the background reading has sent.
    fn receive(&mut self) -> bool {
        let Some(rx) = &self.pending else {
            return false;
        };
        let mut busy = true;
        loop {
            match rx.try_recv() {
                Ok(Ok(p)) => self.result = Some(p),
                Ok(Err(e)) => self.error = Some(e),
                Err(std::sync::mpsc::TryRecvError::Empty) => break,
                Err(std::sync::mpsc::TryRecvError::Disconnected) => {
                    busy = false;
                    break;
                }
            }
        }
        if !busy {
            self.pending = None;
        }
        busy
    }
}

impl ViewerApp {
    pub(super) fn profile_controls(&mut self, ui: &mut egui::Ui) {
        egui::CollapsingHeader::new("Height profile")
            .default_open(false)
            .show(ui, |ui| {
                let p = &mut self.profiling;
                ui.horizontal(|ui| {
                    if ui.toggle_value(&mut p.drawing, "Draw line").changed() && p.drawing {
                        p.line.clear();
                        self.measuring.tool = None;
                    }
                    if ui.button("Clear").clicked() {
                        p.line.clear();
                        p.result = None;
                        p.pending = None;
                    }
                });
                if p.drawing {
                    ui.label("click points along the line, then Profile");
                }
                ui.add(
                    egui::DragValue::new(&mut p.width)
                        .speed(0.05)
                        .range(0.01..=1e6)
                        .prefix("width "),
                );
                let ready = p.line.len() >= 2;
                if ui
                    .add_enabled(ready, egui::Button::new("Profile"))
                    .clicked()
                {
                    p.drawing = false;
                    p.start(self.renderer.dataset().clone());
                }
            });
    }

    /// The profile's window, while there is a profile.
    pub(super) fn profile_window(&mut self, ctx: &egui::Context) {
        if self.profiling.receive() {
            ctx.request_repaint();
        }
        // Shown for an error alone too: a line with no length (its two clicks on one point)
        // did nothing, where the command line says why.
        let p = &self.profiling;
        if p.result.is_none() && p.pending.is_none() && p.error.is_none() {
            return;
        }
        let ds = self.renderer.dataset().clone();
        let step = strata_format::finest_step(ds.metadata().scale);
        let mut open = true;
        // Below the scene's middle, so that the line it was drawn along stays in sight.
        let corner = ctx.content_rect().right_bottom() - egui::vec2(12.0, 12.0);
        egui::Window::new("Height profile")
            .open(&mut open)
            .pivot(egui::Align2::RIGHT_BOTTOM)
            .default_pos(corner)
            .resizable(false)
            .show(ctx, |ui| {
                let p = &mut self.profiling;
                let Some(profile) = &p.result else {
                    match &p.error {
                        Some(e) => ui.colored_label(egui::Color32::LIGHT_RED, e),
                        None => ui.label("reading..."),
                    };
                    return;
                };
                let key = (p.generation, profile.points.len(), profile.level);
                if p.plot.as_ref().is_none_or(|(_, k)| *k != key) {
                    let image = plot_image(profile);
                    p.plot = Some((ctx.load_texture("profile", image, Default::default()), key));
                }
                if let Some((tex, _)) = &p.plot {
                    ui.image((tex.id(), egui::vec2(PLOT[0], PLOT[1])));
                }
                let (lo, hi) = height_range(profile);
                let d = strata_format::step_decimals(step);
                ui.label(format!(
                    "{} points; 0 to {:.d$} along, heights {lo:.d$} to {hi:.d$}; level {} (spacing {}){}",
                    profile.points.len(),
                    profile.corridor.length(),
                    profile.level,
                    strata_format::number(profile.spacing),
                    if p.pending.is_some() {
                        ", reading finer levels..."
                    } else if !profile.complete {
                        ", stopped at the cap on points read"
                    } else {
                        ""
                    }
                ));
                ui.horizontal(|ui| {
                    ui.add(egui::TextEdit::singleline(&mut p.file).desired_width(220.0));
                    if ui.button("Export").clicked() {
                        let path = Path::new(&p.file);
                        let csv = path
                            .extension()
                            .is_some_and(|e| e.eq_ignore_ascii_case("csv"));
                        p.error = match (csv, p.writer) {
                            (true, _) => profile.write_csv(path).err().map(|e| e.to_string()),
                            (false, Some(write)) => write(&ds, profile, path).err(),
                            (false, None) => Some("this build writes profiles as .csv".into()),
                        };
                    }
                });
                ui.label(egui::RichText::new(".csv, or .las, .laz, .ply with every attribute").small());
                if let Some(e) = &p.error {
                    ui.colored_label(egui::Color32::LIGHT_RED, e);
                }
            });
        if !open {
            self.profiling.result = None;
            self.profiling.pending = None;
            self.profiling.error = None;
        }
    }

    /// Paints the profile's line and its corridor's edges over the scene.
    pub(super) fn paint_profile(
        &self,
        painter: &egui::Painter,
        rect: egui::Rect,
        size: (u32, u32),
    ) {
        let line = &self.profiling.line;
        if line.is_empty() {
            return;
        }
        let proj = ScreenProjector::new(self.renderer.dataset(), &self.camera, size.0, size.1);
        let to_screen = |[x, y]: [f32; 2]| {
            egui::pos2(
                rect.min.x + x / proj.width * rect.width(),
                rect.min.y + y / proj.height * rect.height(),
            )
        };
        let colour = egui::Color32::from_rgb(120, 255, 120);
        let half = self.profiling.width / 2.0;
        for w in line.windows(2) {
            let (a, b) = (w[0], w[1]);
            let (dx, dy) = (b[0] - a[0], b[1] - a[1]);
            let len = dx.hypot(dy).max(1e-12);
            let n = [-dy / len * half, dx / len * half];
            let shift = |p: [f64; 3], s: f64| [p[0] + n[0] * s, p[1] + n[1] * s, p[2]];
            for (s, width) in [(0.0, 2.0), (1.0, 1.0), (-1.0, 1.0)] {
                if let Some((p, q)) = proj.segment(shift(a, s), shift(b, s)) {
                    painter.line_segment(
                        [to_screen(p), to_screen(q)],
                        egui::Stroke::new(width, colour),
                    );
                }
            }
        }
        for p in line.iter().filter_map(|p| proj.to_pixel(*p)) {
            painter.circle_filled(to_screen(p), 3.0, colour);
        }
    }
}

fn height_range(profile: &Profile) -> (f64, f64) {
    let zs = profile.points.iter().map(|p| p.position[2]);
    let lo = zs.clone().fold(f64::INFINITY, f64::min);
    let hi = zs.fold(f64::NEG_INFINITY, f64::max);
    if lo <= hi { (lo, hi) } else { (0.0, 1.0) }
}

/// The profile drawn as an image: distance along the line across, height up, each point a pixel
/// in its stored colour (or by height without colours).
fn plot_image(profile: &Profile) -> egui::ColorImage {
    let (w, h) = (PLOT[0] as usize, PLOT[1] as usize);
    let mut pixels = vec![egui::Color32::from_rgb(16, 18, 22); w * h];
    let (lo, hi) = height_range(profile);
    let length = profile.corridor.length().max(1e-12);
    let span = (hi - lo).max(1e-12);
    let layout = &profile.layout;
    let rgb = layout
        .attributes
        .iter()
        .position(|a| a.name == "rgb" && a.count == 3)
        .map(|i| (layout.offsets[i], layout.attributes[i].ty));
    // 16-bit colours that hold 8-bit values are drawn as they are; others scaled down.
    let wide = rgb.is_some_and(|(at, ty)| {
        let stride = layout.stride;
        profile
            .rows
            .chunks_exact(stride)
            .any(|row| (0..3).any(|c| ty.read_f64(&row[at + c * ty.size()..]) > 255.0))
    });
    for (i, p) in profile.points.iter().enumerate() {
        let x = (p.place.along / length * (w - 1) as f64).round() as usize;
        let y = ((hi - p.position[2]) / span * (h - 1) as f64).round() as usize;
        let colour = match rgb {
            Some((at, ty)) => {
                let row = &profile.rows[i * layout.stride..(i + 1) * layout.stride];
                let ch = |c: usize| {
                    let v = ty.read_f64(&row[at + c * ty.size()..]);
                    (if wide { v / 256.0 } else { v }).clamp(0.0, 255.0) as u8
                };
                egui::Color32::from_rgb(ch(0), ch(1), ch(2))
            }
            None => {
                let t = ((p.position[2] - lo) / span) as f32;
                egui::Color32::from_rgb(
                    (80.0 + 175.0 * t) as u8,
                    (200.0 - 80.0 * t) as u8,
                    255 - (200.0 * t) as u8,
                )
            }
        };
        // Two by two pixels: one is lost on a plot this size.
        for (dx, dy) in [(0, 0), (1, 0), (0, 1), (1, 1)] {
            if let Some(px) = pixels.get_mut((y + dy).min(h - 1) * w + (x + dx).min(w - 1)) {
                *px = colour;
            }
        }
    }
    egui::ColorImage::new([w, h], pixels)
}
