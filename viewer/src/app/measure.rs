//! The panel's measuring tools: distance, area, height and angle between picked points, drawn
//! over the scene, listed with their values, each removable, and kept as GeoJSON beside a local
//! dataset (`measurements.geojson`) or in any file given.

use super::ViewerApp;
use crate::measure::{MeasureKind, Measurement, Measurements, value_decimals};
use crate::overlay::{ScreenProjector, kind_colour, measurement_segments};
use crate::pick::PickedPoint;
use eframe::egui;
use std::path::PathBuf;
use strata_format::finest_step;

#[derive(Default)]
pub struct Measuring {
    pub all: Measurements,
    /// The tool clicks feed, if any.
    pub tool: Option<MeasureKind>,
    /// The measurement being made.
    pub current: Option<Measurement>,
    /// The GeoJSON file saved to and loaded from.
    pub file: String,
    /// Saved on every change: the file beside a local dataset.
    autosave: bool,
    pub error: Option<String>,
}

impl Measuring {
    /// The measurements given, else those saved beside a local dataset.
    pub fn open(location: &str, given: Option<Measurements>) -> Measuring {
        let file = crate::measure::beside(location);
        // Saved on every change only into the dataset's own file, and only when that file was
        // read (or is not there yet): other measurements given, or a file that would not load,
        // are never written over it unasked.
        let given_any = given.is_some();
        let (all, error, read) = match (given, file.as_deref().map(Measurements::load)) {
            (Some(m), _) => (m, None, false),
            (None, Some(Ok(m))) => (m, None, true),
            (None, Some(Err(e))) => (
                Measurements::default(),
                Some(format!("{e}; not saved over until you save them yourself")),
                false,
            ),
            (None, None) => (Measurements::default(), None, false),
        };
        Measuring {
            all,
            autosave: file.is_some() && read && !given_any,
            file: file
                .map(|f| f.display().to_string())
                .unwrap_or_else(|| crate::measure::FILE_NAME.into()),
            error,
            ..Measuring::default()
        }
    }

    /// Takes a picked point into the measurement being made; a kind with a fixed number of
    /// points is finished by its last one.
    pub fn add(&mut self, point: &PickedPoint) {
        let Some(kind) = self.tool else { return };
        let current = self.current.get_or_insert_with(|| Measurement {
            kind,
            name: self.all.next_name(kind),
            points: Vec::new(),
            source: None,
        });
        current.points.push(point.position);
        if !current.takes_more() {
            self.finish();
        }
    }

    /// Keeps the measurement being made if it has its points and they measure something:
    /// points that coincide (one point clicked three times for an angle) are refused as
    /// `strata measure` refuses them, not kept without a value.
    fn finish(&mut self) {
        let Some(m) = self.current.take().filter(Measurement::is_complete) else {
            return;
        };
        if m.values().is_empty() {
            self.error = Some(format!(
                "{}: the points measure no {}: they coincide where the measure needs them apart",
                m.name,
                m.kind.name()
            ));
            return;
        }
        self.all.items.push(m);
        self.changed();
    }

    /// Saves beside the dataset after a change, so that closing the window loses nothing.
    fn changed(&mut self) {
        if self.autosave {
            self.error = self
                .all
                .save(std::path::Path::new(&self.file))
                .err()
                .map(|e| e.to_string());
        }
    }
}

impl ViewerApp {
    pub(super) fn measure_controls(&mut self, ui: &mut egui::Ui) {
        // Open where there are measurements to list.
        let open = !self.measuring.all.items.is_empty();
        let step = finest_step(self.renderer.dataset().metadata().scale);
        egui::CollapsingHeader::new("Measure")
            .default_open(open)
            .show(ui, |ui| {
                let m = &mut self.measuring;
                ui.horizontal_wrapped(|ui| {
                    let mut tool = m.tool;
                    ui.radio_value(&mut tool, None, "off");
                    for k in MeasureKind::ALL {
                        ui.radio_value(&mut tool, Some(k), k.name());
                    }
                    if tool != m.tool {
                        m.current = None;
                        m.tool = tool;
                    }
                });
                if let Some(k) = m.tool {
                    ui.label(match k {
                        MeasureKind::Distance | MeasureKind::Area => "click points, then Finish",
                        MeasureKind::Height => "click the lower point, then the upper",
                        MeasureKind::Angle => "click a point, the vertex, another point",
                    });
                }
                if let Some(c) = &m.current {
                    for line in c.lines(step) {
                        ui.label(egui::RichText::new(line).monospace().small());
                    }
                    let done = c.is_complete() && c.takes_more();
                    ui.horizontal(|ui| {
                        if ui.add_enabled(done, egui::Button::new("Finish")).clicked() {
                            m.finish();
                        }
                        if ui.button("Cancel").clicked() {
                            m.current = None;
                        }
                    });
                }
                let mut remove = None;
                for (i, item) in m.all.items.iter().enumerate() {
                    ui.horizontal(|ui| {
                        if ui.small_button("✕").clicked() {
                            remove = Some(i);
                        }
                        ui.vertical(|ui| {
                            for line in item.lines(step) {
                                ui.label(egui::RichText::new(line).monospace().small());
                            }
                        });
                    });
                }
                if let Some(i) = remove {
                    m.all.items.remove(i);
                    m.changed();
                }
                ui.horizontal(|ui| {
                    ui.add(egui::TextEdit::singleline(&mut m.file).desired_width(150.0));
                    let path = PathBuf::from(&m.file);
                    if ui.button("Save").clicked() {
                        m.error = m.all.save(&path).err().map(|e| e.to_string());
                    }
                    if ui.button("Load").clicked() {
                        match Measurements::load_existing(&path) {
                            Ok(loaded) => {
                                m.all = loaded;
                                m.error = None;
                            }
                            Err(e) => m.error = Some(e.to_string()),
                        }
                    }
                });
                if let Some(e) = &m.error {
                    ui.colored_label(egui::Color32::LIGHT_RED, e);
                }
            });
    }

    /// Paints the measurements over the scene's `rect`, which shows an image of `size`.
    pub(super) fn paint_measurements(
        &self,
        painter: &egui::Painter,
        rect: egui::Rect,
        size: (u32, u32),
    ) {
        let proj = ScreenProjector::new(self.renderer.dataset(), &self.camera, size.0, size.1);
        let step = finest_step(self.renderer.dataset().metadata().scale);
        let to_screen = |[x, y]: [f32; 2]| {
            egui::pos2(
                rect.min.x + x / proj.width * rect.width(),
                rect.min.y + y / proj.height * rect.height(),
            )
        };
        let items = self
            .measuring
            .all
            .items
            .iter()
            .chain(&self.measuring.current);
        for m in items {
            let [r, g, b] = kind_colour(m.kind);
            let colour = egui::Color32::from_rgb(r, g, b);
            for (a, b) in measurement_segments(m) {
                if let Some((a, b)) = proj.segment(a, b) {
                    let line = [to_screen(a), to_screen(b)];
                    painter.line_segment(line, egui::Stroke::new(4.0, egui::Color32::BLACK));
                    painter.line_segment(line, egui::Stroke::new(2.0, colour));
                }
            }
            for p in m.points.iter().filter_map(|p| proj.to_pixel(*p)) {
                painter.circle(
                    to_screen(p),
                    4.0,
                    colour,
                    egui::Stroke::new(1.0, egui::Color32::BLACK),
                );
            }
            // The main value beside the last point.
            let label = m.values().first().map(|(name, v)| {
                let d = value_decimals(name, step);
                match *name {
                    "angle_deg" => format!("{v:.d$}°"),
                    // In the dataset's units, whatever they are.
                    "horizontal_area" => format!("{v:.d$} sq"),
                    _ => format!("{v:.d$}"),
                }
            });
            if let (Some(label), Some(p)) = (label, m.points.last().and_then(|p| proj.to_pixel(*p)))
            {
                let at = to_screen(p) + egui::vec2(8.0, -8.0);
                let font = egui::FontId::proportional(14.0);
                painter.text(
                    at + egui::vec2(1.0, 1.0),
                    egui::Align2::LEFT_BOTTOM,
                    &label,
                    font.clone(),
                    egui::Color32::BLACK,
                );
                painter.text(at, egui::Align2::LEFT_BOTTOM, label, font, colour);
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn measurements_are_saved_on_change_only_over_the_file_they_came_from() {
        let dir = tempfile::tempdir().expect("tempdir");
        let location = dir.path().display().to_string();
        let file = dir.path().join(crate::measure::FILE_NAME);
        // Read back, the dataset's own file is saved on every change.
        let mut m = Measuring::open(&location, None);
        m.changed();
        assert!(file.exists());
        // One that would not load, or other measurements given, are not saved over it.
        std::fs::write(&file, b"{ not geojson").expect("write");
        let mut m = Measuring::open(&location, None);
        assert!(m.error.is_some());
        m.changed();
        let mut given = Measuring::open(&location, Some(Measurements::default()));
        given.changed();
        assert_eq!(std::fs::read(&file).expect("read"), b"{ not geojson");
    }

    #[test]
    fn an_angle_of_coincident_points_is_refused_not_kept_without_a_value() {
        let mut m = Measuring::default();
        let at = [1.0, 2.0, 3.0];
        for (points, kept) in [
            (vec![at; 3], false),
            (vec![at, [2.0, 2.0, 3.0], [1.0, 3.0, 3.0]], true),
        ] {
            m.current = Some(Measurement {
                kind: MeasureKind::Angle,
                name: "angle".into(),
                points,
                source: None,
            });
            m.finish();
            assert_eq!(m.all.items.len(), usize::from(kept));
            assert_eq!(m.error.is_some(), !kept, "{:?}", m.error);
            m.error = None;
        }
    }
}
