//! The panel's filters: classification classes shown or hidden one by one (ASPRS names), and
//! ranges of intensity, elevation and return number. The projection applies them, so they hold
//! in every pipeline.

use super::ViewerApp;
use crate::pick::asprs_class_name;
use eframe::egui;

/// The classes the panel lists without counts from the conversion: the ASPRS standard ones
/// (LAS 1.4).
const LISTED_CLASSES: std::ops::RangeInclusive<u8> = 0..=22;

impl ViewerApp {
    pub(super) fn filter_controls(&mut self, ui: &mut egui::Ui) {
        egui::CollapsingHeader::new("Filters")
            .default_open(false)
            .show(ui, |ui| {
                self.class_controls(ui);
                self.range_controls(ui);
                self.attribute_range_controls(ui);
            });
    }

    /// A checkbox per class, where the points carry classes.
    fn class_controls(&mut self, ui: &mut egui::Ui) {
        if !self.renderer.dataset().has_attribute("classification") {
            return;
        }
        ui.horizontal(|ui| {
            if ui.button("all classes").clicked() {
                self.settings.filter.classes = None;
            }
            if ui.button("none").clicked() {
                self.settings.filter.set_classes(&[], true);
            }
        });
        // With counts from the conversion, the classes present; else the standard ones.
        let counts = self.renderer.dataset().metadata().classes.clone();
        let mut listed: Vec<u8> = counts.keys().filter_map(|k| k.parse().ok()).collect();
        if listed.is_empty() {
            listed = LISTED_CLASSES.collect();
        }
        listed.sort_unstable();
        for c in listed {
            let count = counts.get(&c.to_string()).copied();
            let mut shown = self.settings.filter.shows_class(c);
            let label = match count {
                Some(n) => format!("{c} {} ({n})", asprs_class_name(c)),
                None => format!("{c} {}", asprs_class_name(c)),
            };
            if ui.checkbox(&mut shown, label).changed() {
                self.settings.filter.set_classes(&[c], false);
                if shown {
                    let mask = self.settings.filter.classes.get_or_insert([u32::MAX; 8]);
                    mask[c as usize / 32] |= 1 << (c as u32 % 32);
                }
            }
        }
    }

    /// Elevation, and intensity and return number where the GPU's attribute word holds them
    /// (live, as they are dragged); else they are among the ranges applied on a click.
    fn range_controls(&mut self, ui: &mut egui::Ui) {
        let (lo, hi) = (self.bounds_z.0, self.bounds_z.1);
        range_control(
            ui,
            "elevation",
            &mut self.settings.filter.elevation,
            (lo, hi),
        );
        let fit = self.renderer.dataset().word_fit();
        if fit.intensity {
            let imax = self.renderer.dataset().intensity_max().max(1.0) * 1.25;
            range_control(
                ui,
                "intensity",
                &mut self.settings.filter.intensity,
                (0.0, imax),
            );
        }
        if fit.return_number {
            let mut returns = self
                .settings
                .filter
                .return_number
                .map(|(a, b)| (a as f64, b as f64));
            range_control(ui, "return number", &mut returns, (0.0, 15.0));
            self.settings.filter.return_number =
                returns.map(|(a, b)| (a.round() as u32, b.round() as u32));
        }
    }

    /// A range of any other one-valued attribute (GPS time, point source, extra attributes).
    /// Points are marked when their node loads, so a range applies on a click, not while
    /// its ends are dragged: each change loads the nodes again.
    fn attribute_range_controls(&mut self, ui: &mut egui::Ui) {
        // Read once; a failed read (a server away) is tried again on the next frame.
        if self.attribute_ranges.is_none() {
            match crate::marks::attribute_ranges(self.renderer.dataset()) {
                Ok(r) => self.attribute_ranges = Some(r),
                Err(e) => self.attribute_error = Some(e.to_string()),
            }
        }
        let ranges = self.attribute_ranges.clone().unwrap_or_default();
        if ranges.is_empty() {
            if let Some(e) = &self.attribute_error {
                ui.colored_label(egui::Color32::LIGHT_RED, e);
            }
            return;
        }
        ui.label("other attribute (applied on a click)");
        let edit = &mut self.attribute_edit;
        let chosen = ranges.iter().find(|r| r.0 == edit.0).or(ranges.first());
        let Some((name, lo, hi)) = chosen.cloned() else {
            return;
        };
        if edit.0 != name {
            *edit = (name.clone(), lo, hi);
        }
        egui::ComboBox::from_id_salt("attribute range")
            .selected_text(&edit.0)
            .show_ui(ui, |ui| {
                for (n, l, h) in &ranges {
                    if ui.selectable_label(*n == edit.0, n).clicked() {
                        *edit = (n.clone(), *l, *h);
                    }
                }
            });
        let step = ((hi - lo) / 200.0).max(1e-6);
        ui.horizontal(|ui| {
            ui.add(egui::DragValue::new(&mut edit.1).speed(step));
            ui.label("to");
            ui.add(egui::DragValue::new(&mut edit.2).speed(step));
        });
        ui.horizontal(|ui| {
            if ui.button("Apply").clicked() {
                let assignment = format!("{}={}..{}", edit.0, edit.1, edit.2);
                self.attribute_error = self
                    .settings
                    .filter
                    .set_range(&assignment)
                    .err()
                    .map(|e| e.to_string());
            }
            if ui.button("Clear").clicked() {
                let fit = self.renderer.dataset().word_fit();
                let filter = &mut self.settings.filter;
                filter.attributes.clear();
                if !fit.intensity {
                    filter.intensity = None;
                }
                if !fit.return_number {
                    filter.return_number = None;
                }
            }
        });
        let fit = self.renderer.dataset().word_fit();
        let filter = &self.settings.filter;
        let routed = [
            ("intensity", filter.intensity.filter(|_| !fit.intensity)),
            (
                "return_number",
                filter
                    .return_number
                    .filter(|_| !fit.return_number)
                    .map(|(a, b)| (a.into(), b.into())),
            ),
        ];
        let applied = filter
            .attributes
            .iter()
            .map(|a| (a.name.as_str(), a.lo, a.hi));
        let applied = applied.chain(
            routed
                .into_iter()
                .filter_map(|(n, r)| Some((n, r?.0, r?.1))),
        );
        for (name, lo, hi) in applied {
            ui.label(egui::RichText::new(format!("{name} {lo}..{hi}")).small());
        }
        if let Some(e) = &self.attribute_error {
            ui.colored_label(egui::Color32::LIGHT_RED, e);
        }
    }
}

/// An optional range: a checkbox to apply it, then its two ends.
fn range_control(ui: &mut egui::Ui, name: &str, range: &mut Option<(f64, f64)>, full: (f64, f64)) {
    let mut on = range.is_some();
    if ui.checkbox(&mut on, name).changed() {
        *range = on.then_some(full);
    }
    if let Some((lo, hi)) = range.as_mut() {
        let step = ((full.1 - full.0) / 200.0).max(1e-3);
        ui.horizontal(|ui| {
            ui.add(egui::DragValue::new(lo).speed(step).range(full.0..=*hi));
            ui.label("to");
            ui.add(egui::DragValue::new(hi).speed(step).range(*lo..=full.1));
        });
    }
}
