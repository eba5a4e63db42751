//! The panel's views: camera bookmarks saved beside a local dataset (`bookmarks.json`),
//! recalled with a click, removed, and flown through in order, each reached the seconds set
//! beside it after the one before (the same file is the `--path` of `strata render`).

use super::ViewerApp;
use crate::bookmarks::{Bookmark, Bookmarks, DEFAULT_SECONDS, keyframe_times, segment_at};
use crate::camera::Camera;
use eframe::egui;
use std::time::Instant;

/// The views of the session: loaded from, and saved to, the dataset's bookmarks file.
#[derive(Default)]
pub struct Views {
    pub marks: Bookmarks,
    /// Where they are kept; `None` for a dataset read over HTTP (they last the session).
    pub file: Option<std::path::PathBuf>,
    pub error: Option<String>,
    /// A fly-through in progress: when it began.
    pub flying: Option<Instant>,
    /// The file is there but would not load: moved aside before the first save.
    unreadable: bool,
}

impl Views {
    pub fn open(location: &str) -> Views {
        let file = crate::bookmarks::beside(location);
        let (marks, error, unreadable) = match file.as_deref().map(Bookmarks::load) {
            Some(Ok(m)) => (m, None, false),
            Some(Err(e)) => (Bookmarks::default(), Some(e.to_string()), true),
            None => (Bookmarks::default(), None, false),
        };
        Views {
            marks,
            file,
            error,
            flying: None,
            unreadable,
        }
    }

    fn save(&mut self) {
        let Some(file) = &self.file else { return };
        // A file that would not load is kept beside, not written over.
        if self.unreadable {
            let mut aside = file.clone().into_os_string();
            aside.push(".unreadable");
            if let Err(e) = std::fs::rename(file, &aside) {
                self.error = Some(format!(
                    "{}: cannot move the unreadable bookmarks aside ({e}); not saved",
                    file.display()
                ));
                return;
            }
            self.unreadable = false;
        }
        self.error = self.marks.save(file).err().map(|e| e.to_string());
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
        // A view that no longer parses is left out with its time.
        let (cams, seconds): (Vec<Camera>, Vec<Option<f32>>) = self
            .views
            .marks
            .keyframes
            .iter()
            .filter_map(|m| Some((self.camera_of(m)?, m.seconds)))
            .unzip();
        let times = keyframe_times(seconds);
        let t = start.elapsed().as_secs_f32();
        if cams.len() < 2 || cams.len() != times.len() || t >= times[times.len() - 1] {
            self.views.flying = None;
            if let Some(last) = cams.last() {
                self.camera = *last;
            }
            return;
        }
        // Where the eye passes through the target the view has no direction (as `render
        // --path` refuses): the flight stops before it, saying between which views.
        if let Some(i) = cams
            .windows(2)
            .position(|k| k[0].lerp_meets_target(&k[1]).is_some())
        {
            self.views.flying = None;
            self.views.error = Some(format!(
                "between views {} and {} the eye passes through the target; add a view between them",
                i + 1,
                i + 2
            ));
            return;
        }
        let (seg, f) = segment_at(&times, t);
        self.camera = cams[seg].lerp(&cams[seg + 1], f);
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
                let mut retimed = false;
                for (i, m) in self.views.marks.keyframes.iter_mut().enumerate() {
                    ui.horizontal(|ui| {
                        let name = m.name.clone().unwrap_or_else(|| format!("view {}", i + 1));
                        if ui.button(name).clicked() {
                            go = Some(i);
                        }
                        if i > 0 {
                            // Seconds from the view before, as the fly-through takes them.
                            let mut s = m.seconds.unwrap_or(DEFAULT_SECONDS);
                            let drag = egui::DragValue::new(&mut s)
                                .speed(0.1)
                                .range(0.1..=600.0)
                                .suffix(" s");
                            let r = ui.add(drag);
                            if r.changed() {
                                m.seconds = Some(s);
                            }
                            retimed |= r.drag_stopped() || r.lost_focus();
                        }
                        if ui.small_button("✕").clicked() {
                            remove = Some(i);
                        }
                    });
                }
                if retimed {
                    self.views.save();
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

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn bookmarks_that_would_not_load_are_moved_aside_not_written_over() {
        let dir = tempfile::tempdir().expect("tempdir");
        let file = dir.path().join(crate::bookmarks::FILE_NAME);
        std::fs::write(&file, b"{ not json").expect("write");
        let mut views = Views::open(&dir.path().display().to_string());
        assert!(views.error.is_some());
        views.save();
        assert_eq!(views.error, None);
        let aside = dir
            .path()
            .join(format!("{}.unreadable", crate::bookmarks::FILE_NAME));
        assert_eq!(std::fs::read(aside).expect("kept"), b"{ not json");
        assert!(Bookmarks::load(&file).is_ok(), "saved anew");
    }
}
