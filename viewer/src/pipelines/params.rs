//! A pipeline's parameters: one table per pipeline that the panel, the command line
//! (`--set NAME=VALUE`), the statistics and the quality harness all read.

use super::PipelineInfo;
use crate::ViewerError;
use std::collections::BTreeMap;

/// How a parameter's value moves on the panel's slider.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Scale {
    Linear,
    /// Slider on a log scale: lengths in dataset units, spanning orders of magnitude.
    Log,
    /// Whole numbers only.
    Integer,
    /// 0 (off) or 1 (on): a checkbox.
    Toggle,
    /// One of these modes, by name or by its index (the value): `shadows=hard` or `shadows=1`.
    Choice(&'static [&'static str]),
}

/// Where a parameter left automatic takes its value each frame.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Auto {
    /// The mean point spacing of the nodes drawn (paper 003's s0, and others' defaults).
    DrawnSpacing,
    /// That many times the mean point spacing of the nodes drawn.
    DrawnSpacings(u32),
}

#[derive(Debug, Clone, Copy)]
pub struct ParamSpec {
    pub name: &'static str,
    pub help: &'static str,
    pub default: f32,
    pub min: f32,
    pub max: f32,
    pub scale: Scale,
    /// The parameter may be left automatic (its default then), set with `NAME=auto`.
    pub auto: Option<Auto>,
}

impl ParamSpec {
    /// Checks a value against the range and the scale; the error names the parameter.
    pub fn check(&self, pipeline: &str, value: f32) -> Result<f32, ViewerError> {
        let whole = matches!(
            self.scale,
            Scale::Integer | Scale::Toggle | Scale::Choice(_)
        );
        if let Scale::Choice(names) = self.scale
            && (!value.is_finite()
                || value < 0.0
                || value >= names.len() as f32
                || value.fract() != 0.0)
        {
            return Err(ViewerError::argument(
                format!("{}={value}", self.name),
                format!(
                    "{pipeline}'s parameter {} takes {}",
                    self.name,
                    self.modes()
                ),
            ));
        }
        if !value.is_finite() || value < self.min || value > self.max {
            return Err(ViewerError::argument(
                format!("{}={value}", self.name),
                format!(
                    "{pipeline}'s parameter {} takes {} to {}",
                    self.name, self.min, self.max
                ),
            ));
        }
        if whole && value.fract() != 0.0 {
            return Err(ViewerError::argument(
                format!("{}={value}", self.name),
                format!("{pipeline}'s parameter {} takes whole numbers", self.name),
            ));
        }
        Ok(value)
    }

    /// The value as the panel and `--set` show it.
    pub fn describe(&self) -> String {
        let range = match self.scale {
            Scale::Toggle => "0 or 1".to_string(),
            Scale::Choice(_) => self.modes(),
            _ => format!("{} to {}", self.min, self.max),
        };
        let default = if self.auto.is_some() {
            "auto".to_string()
        } else if let Some(name) = self.choice_name(self.default) {
            name.to_string()
        } else {
            format!("{}", self.default)
        };
        format!("{range}, default {default}")
    }
}

impl ParamSpec {
    /// A choice parameter's modes, "off, hard or soft (or its number, 0 to 2)".
    fn modes(&self) -> String {
        match self.scale {
            Scale::Choice(names) => format!(
                "{} (or its number, 0 to {})",
                or_list(names),
                names.len().saturating_sub(1)
            ),
            _ => String::new(),
        }
    }

    /// The name of a choice parameter's value `v`; `None` for other scales.
    pub fn choice_name(&self, v: f32) -> Option<&'static str> {
        match self.scale {
            Scale::Choice(names) if v >= 0.0 => names.get(v as usize).copied(),
            _ => None,
        }
    }
}

/// "a, b or c".
fn or_list(names: &[&str]) -> String {
    match names.split_last() {
        Some((last, rest)) if !rest.is_empty() => format!("{} or {last}", rest.join(", ")),
        Some((last, _)) => last.to_string(),
        None => String::new(),
    }
}

/// A value given for a parameter.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum ParamValue {
    Auto,
    Value(f32),
}

/// The values set for every pipeline's parameters; a parameter not set has its default.
/// Kept per pipeline, so switching pipelines in the panel keeps each one's settings.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct ParamValues {
    set: BTreeMap<(&'static str, &'static str), ParamValue>,
}

impl ParamValues {
    /// Sets `name` of `pipeline` from text (`NAME=VALUE` of `--set`): a number, `auto` where
    /// the parameter allows it, `on`/`off`/`true`/`false` for toggles and a mode's name for
    /// choices.
    pub fn set_text(
        &mut self,
        pipeline: &'static PipelineInfo,
        name: &str,
        text: &str,
    ) -> Result<(), ViewerError> {
        // A vector (`light=X,Y,Z`) sets its three parameters NAME.x, NAME.y, NAME.z.
        let axes = ["x", "y", "z"].map(|a| format!("{name}.{a}"));
        if pipeline.param(name).is_err()
            && axes
                .iter()
                .all(|a| pipeline.params.iter().any(|p| p.name == a))
        {
            let parts: Vec<&str> = text.split(',').collect();
            if parts.len() != 3 {
                return Err(ViewerError::argument(
                    format!("{name}={text}"),
                    format!("{}'s {name} takes three numbers X,Y,Z", pipeline.name),
                ));
            }
            // Components confined to -1..1 make a direction: given at any length, it is
            // normalised (`light=1,1,2`).
            let unit = axes.iter().all(|a| {
                pipeline
                    .params
                    .iter()
                    .any(|p| p.name == a && p.min == -1.0 && p.max == 1.0)
            });
            // In doubles, scaled by the largest component first, so that neither a tiny nor a
            // huge direction rounds out of -1..1 or to no length.
            let numbers: Vec<f64> = parts.iter().filter_map(|p| p.trim().parse().ok()).collect();
            let largest = numbers.iter().fold(0.0f64, |m, v| m.max(v.abs()));
            if unit && numbers.len() == 3 && largest > 0.0 && largest.is_finite() {
                let scaled: Vec<f64> = numbers.iter().map(|v| v / largest).collect();
                let length = scaled.iter().map(|v| v * v).sum::<f64>().sqrt();
                for (axis, v) in axes.iter().zip(scaled) {
                    let unit = ((v / length) as f32).clamp(-1.0, 1.0);
                    self.set_text(pipeline, axis, &unit.to_string())?;
                }
                return Ok(());
            }
            for (axis, part) in axes.iter().zip(parts) {
                self.set_text(pipeline, axis, part)?;
            }
            return Ok(());
        }
        let spec = pipeline.param(name)?;
        let text = text.trim();
        let value = if let Some(k) = choice_index(spec, text) {
            ParamValue::Value(k as f32)
        } else {
            match text {
                "auto" if spec.auto.is_some() => ParamValue::Auto,
                "on" | "true" if spec.scale == Scale::Toggle => ParamValue::Value(1.0),
                "off" | "false" if spec.scale == Scale::Toggle => ParamValue::Value(0.0),
                _ => {
                    let v: f32 = text.parse().map_err(|_| {
                        ViewerError::argument(
                            format!("{name}={text}"),
                            format!(
                                "{}'s parameter {name} takes {}",
                                pipeline.name,
                                match spec.scale {
                                    Scale::Choice(_) => spec.modes(),
                                    _ => format!("a number ({})", spec.describe()),
                                }
                            ),
                        )
                    })?;
                    ParamValue::Value(spec.check(pipeline.name, v)?)
                }
            }
        };
        self.set.insert((pipeline.name, spec.name), value);
        Ok(())
    }

    /// Sets a checked value (the panel's sliders stay within range).
    pub fn set(&mut self, pipeline: &'static PipelineInfo, spec: &ParamSpec, value: ParamValue) {
        self.set.insert((pipeline.name, spec.name), value);
    }

    /// The value given for `spec` of `pipeline`, or its default.
    pub fn get(&self, pipeline: &PipelineInfo, spec: &ParamSpec) -> ParamValue {
        match self.set.get(&(pipeline.name, spec.name)) {
            Some(v) => *v,
            None if spec.auto.is_some() => ParamValue::Auto,
            None => ParamValue::Value(spec.default),
        }
    }
}

/// The index of the mode `text` names (in any case) where `spec` is a choice.
fn choice_index(spec: &ParamSpec, text: &str) -> Option<usize> {
    match spec.scale {
        Scale::Choice(names) => names.iter().position(|n| n.eq_ignore_ascii_case(text)),
        _ => None,
    }
}

/// One frame's parameter values, automatic ones resolved; what a pipeline encodes with and
/// what `--stats` records.
#[derive(Debug, Clone, Default)]
pub struct ResolvedParams {
    values: BTreeMap<&'static str, f32>,
    /// The parameters left automatic.
    automatic: std::collections::BTreeSet<&'static str>,
}

impl ResolvedParams {
    /// Resolves `pipeline`'s parameters; `spacing` is the mean point spacing of the nodes
    /// drawn (`None` with nothing drawn, where an automatic value stays unknown).
    pub fn resolve(
        values: &ParamValues,
        pipeline: &PipelineInfo,
        spacing: impl FnOnce() -> Option<f32>,
    ) -> ResolvedParams {
        let mut spacing = Some(spacing);
        let mut spacing_value = None;
        let mut out = BTreeMap::new();
        let mut automatic = std::collections::BTreeSet::new();
        for spec in pipeline.params {
            if values.get(pipeline, spec) == ParamValue::Auto {
                automatic.insert(spec.name);
            }
            let v = match values.get(pipeline, spec) {
                ParamValue::Value(v) => Some(v),
                ParamValue::Auto => match spec.auto {
                    Some(auto @ (Auto::DrawnSpacing | Auto::DrawnSpacings(_))) => {
                        if let Some(f) = spacing.take() {
                            spacing_value = f();
                        }
                        let times = match auto {
                            Auto::DrawnSpacings(n) => n as f32,
                            _ => 1.0,
                        };
                        // Within the parameter's range, as a value set by hand must be: the
                        // spacing of a dataset of one point (or of one position) is nearly 0.
                        spacing_value.map(|s| (s * times).clamp(spec.min, spec.max))
                    }
                    None => Some(spec.default),
                },
            };
            if let Some(v) = v {
                out.insert(spec.name, v);
            }
        }
        ResolvedParams {
            values: out,
            automatic,
        }
    }

    /// The value of `name`, `None` where it is automatic and could not be resolved.
    pub fn get(&self, name: &str) -> Option<f32> {
        self.values.get(name).copied()
    }

    /// Whether `name` was left automatic (its value then comes from the drawn nodes).
    pub fn is_auto(&self, name: &str) -> bool {
        self.automatic.contains(name)
    }

    pub fn get_or(&self, name: &str, fallback: f32) -> f32 {
        self.get(name).unwrap_or(fallback)
    }

    /// A toggle's state.
    pub fn on(&self, name: &str) -> bool {
        self.get(name).is_some_and(|v| v != 0.0)
    }

    pub fn iter(&self) -> impl Iterator<Item = (&'static str, f32)> + '_ {
        self.values.iter().map(|(k, v)| (*k, *v))
    }
}

#[cfg(test)]
mod choice_tests {
    use super::{ParamValue, ParamValues, Scale};
    use crate::pipelines::REGISTRY;

    /// Every mode parameter of the registry: its range is its modes' numbers, and each mode is
    /// set by its name in any case or by its number; another name, a fraction or a number past
    /// the modes is refused naming them.
    #[test]
    fn every_mode_is_set_by_name_or_number_and_a_wrong_one_names_them() {
        let mut seen = 0;
        for &info in REGISTRY {
            for spec in info.params {
                let Scale::Choice(names) = spec.scale else {
                    continue;
                };
                seen += 1;
                assert_eq!(spec.min, 0.0, "{}", spec.name);
                assert_eq!(spec.max, (names.len() - 1) as f32, "{}", spec.name);
                assert!(spec.choice_name(spec.default).is_some(), "{}", spec.name);
                for (k, name) in names.iter().enumerate() {
                    for text in [name.to_string(), name.to_uppercase(), k.to_string()] {
                        let mut values = ParamValues::default();
                        values.set_text(info, spec.name, &text).expect("a mode");
                        assert_eq!(values.get(info, spec), ParamValue::Value(k as f32));
                    }
                }
                let past = names.len().to_string();
                for wrong in ["bright", "0.5", "-1", past.as_str()] {
                    let e = ParamValues::default()
                        .set_text(info, spec.name, wrong)
                        .expect_err(wrong)
                        .to_string();
                    assert!(e.contains(names[names.len() - 1]), "{wrong}: {e}");
                    assert!(e.contains(spec.name), "{wrong}: {e}");
                }
            }
        }
        // shadows (pyramid and filters), antialias, the surfels' mode.
        assert!(seen >= 4, "{seen} mode parameters");
    }
}
