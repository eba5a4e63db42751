//! The panel's controls for the chosen pipeline's parameters, drawn from its table in the
//! registry: sliders (linear, logarithmic, whole numbers), checkboxes, a mode's radio buttons,
//! automatic toggles.

use super::ViewerApp;
use crate::pipelines::params::{ParamSpec, ParamValue, Scale};
use eframe::egui;

impl ViewerApp {
    /// The chosen pipeline's parameters, from its table in the registry, and what it measured.
    pub(super) fn pipeline_controls(&mut self, ui: &mut egui::Ui) {
        let info = self.settings.pipeline;
        ui.label(egui::RichText::new(info.description).small());
        if let Some(paper) = info.paper {
            ui.label(egui::RichText::new(format!("paper {paper}")).small());
        }
        for spec in info.params {
            if spec.auto.is_some()
                && let Some(v) = self.stats.params.get(spec.name)
                && self.settings.params.get(info, spec) == ParamValue::Auto
            {
                self.auto_values.insert((info.name, spec.name), *v);
            }
            self.param_control(ui, spec);
        }
        if let Some(note) = self.stats.note {
            ui.label(egui::RichText::new(note).small().italics());
        }
        for (name, value) in &self.stats.measures {
            ui.label(format!("{name} = {value:.4}"));
        }
    }

    fn param_control(&mut self, ui: &mut egui::Ui, spec: &'static ParamSpec) {
        let info = self.settings.pipeline;
        let value = self.settings.params.get(info, spec);
        let set = |app: &mut ViewerApp, v| app.settings.params.set(info, spec, v);
        if spec.scale == Scale::Toggle {
            let mut on = value == ParamValue::Value(1.0);
            if ui
                .checkbox(&mut on, spec.name)
                .on_hover_text(spec.help)
                .changed()
            {
                set(self, ParamValue::Value(if on { 1.0 } else { 0.0 }));
            }
            return;
        }
        let last_auto = self.auto_values.get(&(info.name, spec.name)).copied();
        if spec.auto.is_some() {
            let mut auto = value == ParamValue::Auto;
            let label = format!("{} automatic", spec.name);
            if ui
                .checkbox(&mut auto, label)
                .on_hover_text(spec.help)
                .changed()
            {
                let manual = last_auto.unwrap_or(spec.default).clamp(spec.min, spec.max);
                set(
                    self,
                    if auto {
                        ParamValue::Auto
                    } else {
                        ParamValue::Value(manual)
                    },
                );
            }
        }
        let ParamValue::Value(mut v) = self.settings.params.get(info, spec) else {
            if let Some(v) = self.stats.params.get(spec.name) {
                ui.label(format!("{} = {v:.4}", spec.name));
            }
            return;
        };
        let changed = match spec.scale {
            Scale::Log => {
                // Lengths span orders of magnitude: three decades around the automatic value.
                let centre = last_auto.unwrap_or(v).max(spec.min.max(1e-12)).log10();
                let range = (centre - 1.5).max(spec.min.max(1e-12).log10())
                    ..=(centre + 1.5).min(spec.max.log10());
                let mut log_v = v.max(1e-12).log10();
                let slider = egui::Slider::new(&mut log_v, range).show_value(false);
                let changed = ui.add(slider).on_hover_text(spec.help).changed();
                v = 10f32.powf(log_v);
                // Four decimals of a count in the millions showed f32's rounding of its
                // power of ten (shadow_budget = 2000000.7500).
                let shown = if v >= 1000.0 {
                    format!("{v:.0}")
                } else {
                    format!("{v:.4}")
                };
                ui.label(format!("{} = {shown}", spec.name));
                changed
            }
            Scale::Choice(names) => {
                let mut changed = false;
                ui.horizontal(|ui| {
                    ui.label(spec.name).on_hover_text(spec.help);
                    for (k, name) in names.iter().enumerate() {
                        changed |= ui.radio_value(&mut v, k as f32, *name).changed();
                    }
                });
                changed
            }
            Scale::Integer => {
                let slider = egui::Slider::new(&mut v, spec.min..=spec.max)
                    .step_by(1.0)
                    .text(spec.name);
                ui.add(slider).on_hover_text(spec.help).changed()
            }
            _ => {
                let slider = egui::Slider::new(&mut v, spec.min..=spec.max).text(spec.name);
                ui.add(slider).on_hover_text(spec.help).changed()
            }
        };
        if changed {
            set(self, ParamValue::Value(v.clamp(spec.min, spec.max)));
        }
    }
}
