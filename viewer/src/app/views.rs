//! The panel's views: camera bookmarks saved beside a local dataset (`bookmarks.json`),
//! recalled with a click, removed, and flown through in order.

use super::ViewerApp;
use crate::bookmarks::{Bookmark, Bookmarks};
use crate::camera::Camera;
use eframe::egui;
use std::time::Instant;

/// Seconds the fly-through spends between two views.
const SECONDS_PER_VIEW: f32 = 3.0;

/// The views of the session: loaded from, and saved to, the dataset's bookmarks file.
#[derive(Default)]
pub struct Views {
    pub marks: Bookmarks,
    /// Where they are kept; `None` for a dataset read over HTTP (they last the session).
    pub file: Option<std::path::PathBuf>,
    pub error: Option<String>,
    /// A fly-through in progress: when it began.
    pub flying: Option<Instant>,
}

impl Views {
    pub fn open(location: &str) -> Views {
        let file = crate::bookmarks::beside(location);
        let (marks, error) = match file.as_deref().map(Bookmarks::load) {
            Some(Ok(m)) => (m, None),
            Some(Err(e)) => (Bookmarks::default(), Some(e.to_string())),
            None => (Bookmarks::default(), None),
        };
        Views {
            marks,
            file,
            error,
            flying: None,
        }
    }

    fn save(&mut self) {
        if let Some(file) = &self.file {
            self.error = self.marks.save(file).err().map(|e| e.to_string());
        }
    }
}

impl ViewerApp {
    fn camera_of(&self, mark: &Bookmark) -> Option<Camera> {
        let spec = mark.spec(crate::headless::DEFAULT_FOV_DEG);
        Camera::parse(&spec, self.renderer.dataset().anchor(), self.home).ok()
    }

    /// Moves the camera along the views while a fly-through runs.
    pub(super) fn fly_views(&mut self, ctx: &egui::Context) {
        let Some(start) = self.views.flying else {
            return;
        };
        let cams: Vec<Camera> = self
            .views
            .marks
            .keyframes
            .iter()
            .filter_map(|m| self.camera_of(m))
            .collect();
        let t = start.elapsed().as_secs_f32() / SECONDS_PER_VIEW;
        if cams.len() < 2 || t >= (cams.len() - 1) as f32 {
            self.views.flying = None;
            if let Some(last) = cams.last() {
                self.camera = *last;
            }
            return;
        }
        let seg = (t.floor() as usize).min(cams.len() - 2);
        self.camera = cams[seg].lerp(&cams[seg + 1], t - seg as f32);
        ctx.request_repaint();
    }

    pub(super) fn view_controls(&mut self, ui: &mut egui::Ui) {
        egui::CollapsingHeader::new("Views")
            .default_open(false)
            .show(ui, |ui| {
                ui.horizontal(|ui| {
                    if ui.button("Save view").clicked() {
                        let name = format!("view {}", self.views.marks.keyframes.len() + 1);
                        let anchor = self.renderer.dataset().anchor();
                        let mark = Bookmark::of(&self.camera, anchor, name);
                        self.views.marks.keyframes.push(mark);
                        self.views.save();
                    }
                    let many = self.views.marks.keyframes.len() >= 2;
                    if ui
                        .add_enabled(many, egui::Button::new("Fly through"))
                        .clicked()
                    {
                        self.views.flying = Some(Instant::now());
                    }
                });
                let mut go = None;
                let mut remove = None;
                for (i, m) in self.views.marks.keyframes.iter().enumerate() {
                    ui.horizontal(|ui| {
                        let name = m.name.clone().unwrap_or_else(|| format!("view {}", i + 1));
                        if ui.button(name).clicked() {
                            go = Some(i);
                        }
                        if ui.small_button("✕").clicked() {
                            remove = Some(i);
                        }
                    });
                }
                if let Some(cam) = go.and_then(|i| self.camera_of(&self.views.marks.keyframes[i])) {
                    self.views.flying = None;
                    self.camera = cam;
                }
                if let Some(i) = remove {
                    self.views.marks.keyframes.remove(i);
                    self.views.save();
                }
                match &self.views.file {
                    Some(f) => ui.label(egui::RichText::new(f.display().to_string()).small()),
                    None => ui.label(egui::RichText::new("kept for this session only").small()),
                };
                if let Some(e) = &self.views.error {
                    ui.colored_label(egui::Color32::LIGHT_RED, e);
                }
            });
    }
}
