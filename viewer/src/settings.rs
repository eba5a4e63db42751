//! What the user controls: budget, pipeline, point size, colouring. Shared by the panel and
//! the command line.

use crate::ViewerError;
pub use crate::gpu::timing::PassClock;
use crate::pipelines::params::ParamValues;
use crate::pipelines::{self, PipelineInfo};

#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum ColourMode {
    Rgb,
    Intensity,
    Classification,
    Elevation,
    /// The normal as RGB, `(n * 0.5 + 0.5) * 255`: x red, y green, z blue.
    Normal,
    /// Surface variation through the elevation ramp.
    Curvature,
}

impl ColourMode {
    pub const ALL: [ColourMode; 6] = [
        ColourMode::Rgb,
        ColourMode::Intensity,
        ColourMode::Classification,
        ColourMode::Elevation,
        ColourMode::Normal,
        ColourMode::Curvature,
    ];

    pub fn name(self) -> &'static str {
        match self {
            ColourMode::Rgb => "rgb",
            ColourMode::Intensity => "intensity",
            ColourMode::Classification => "classification",
            ColourMode::Elevation => "elevation",
            ColourMode::Normal => "normal",
            ColourMode::Curvature => "curvature",
        }
    }

    /// The attribute the colouring needs and is offered only with (the others fall back or
    /// colour every point alike where the dataset lacks theirs).
    pub fn attribute(self) -> Option<&'static str> {
        match self {
            ColourMode::Normal => Some("normal"),
            ColourMode::Curvature => Some("surface_variation"),
            _ => None,
        }
    }

    pub fn parse(s: &str) -> Result<ColourMode, ViewerError> {
        ColourMode::ALL
            .into_iter()
            .find(|p| p.name() == s)
            .ok_or_else(|| {
                ViewerError::argument(
                    s,
                    "unknown colouring (expected rgb, intensity, classification, elevation, normal or curvature)",
                )
            })
    }

    pub fn shader_code(self) -> u32 {
        self as u32
    }
}

#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum SizeMode {
    /// Point size in pixels.
    Fixed,
    /// Point size as a multiple of the node's point spacing, so splats close up.
    Attenuated,
}

impl SizeMode {
    /// The point size a mode starts at: a disc 3 pixels across, or 2 spacings.
    pub fn default_size(self) -> f32 {
        match self {
            SizeMode::Fixed => 3.0,
            SizeMode::Attenuated => 2.0,
        }
    }
}

/// A box in the dataset's coordinates: points inside it are kept, or (with `outside`) hidden.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ClipBox {
    pub min: [f64; 3],
    pub max: [f64; 3],
    pub outside: bool,
}

impl ClipBox {
    /// Clip boxes a frame holds at most.
    pub const MAX: usize = 4;

    /// Parses `min=X,Y,Z;max=X,Y,Z` with an optional `;outside`.
    pub fn parse(spec: &str) -> Result<ClipBox, ViewerError> {
        let fail = |what: &str| ViewerError::argument(spec, what);
        let (mut min, mut max, mut outside) = (None, None, false);
        let triple = |v: &str| -> Option<[f64; 3]> {
            let parts: Vec<f64> = v
                .split(',')
                .map(|c| c.trim().parse().ok())
                .collect::<Option<_>>()?;
            let t: [f64; 3] = parts.try_into().ok()?;
            t.iter().all(|c| c.is_finite()).then_some(t)
        };
        for part in spec.split(';').map(str::trim).filter(|p| !p.is_empty()) {
            match part.split_once('=') {
                Some(("min", v)) => min = Some(triple(v).ok_or_else(|| fail("min needs X,Y,Z"))?),
                Some(("max", v)) => max = Some(triple(v).ok_or_else(|| fail("max needs X,Y,Z"))?),
                None if part == "outside" => outside = true,
                None if part == "inside" => outside = false,
                _ => {
                    return Err(fail(
                        "expected min=X,Y,Z;max=X,Y,Z with an optional ;outside",
                    ));
                }
            }
        }
        let (Some(min), Some(max)) = (min, max) else {
            return Err(fail("a clip box needs both min=X,Y,Z and max=X,Y,Z"));
        };
        if (0..3).any(|i| min[i] > max[i]) {
            return Err(fail("each coordinate of min must be at most that of max"));
        }
        Ok(ClipBox { min, max, outside })
    }
}

/// A range of any other numeric attribute (GPS time, point source, an extra attribute),
/// inclusive, in its real (scaled) values.
#[derive(Debug, Clone, PartialEq)]
pub struct AttributeRange {
    pub name: String,
    pub lo: f64,
    pub hi: f64,
}

/// Which points are drawn: classes shown, and ranges of intensity, elevation, return number
/// and any other numeric attribute. Applied in the projection, so hidden points leave no hole
/// in any pipeline.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct PointFilter {
    /// The classes shown (bit c of word c / 32); `None`: every class.
    pub classes: Option<[u32; 8]>,
    /// Where `classes` is set, whether a class no bit stands for (above 255, as a 16-bit
    /// class of a PLY may be) is shown: as classes are hidden, not where only some are shown.
    pub classes_beyond: bool,
    /// Raw intensity, inclusive.
    pub intensity: Option<(f64, f64)>,
    /// Real-world elevation (z), inclusive.
    pub elevation: Option<(f64, f64)>,
    pub return_number: Option<(u32, u32)>,
    /// Ranges of the attributes the GPU's attribute word does not hold: the loader marks the
    /// points outside them (a change loads the nodes again), the projection hides the marked.
    pub attributes: Vec<AttributeRange>,
    /// Clip boxes: kept inside any box that keeps its inside, hidden inside any that keeps
    /// its outside. They also bound which nodes are loaded.
    pub clips: Vec<ClipBox>,
}

impl PointFilter {
    /// Attributes `--filter` takes from the attribute word on the GPU; any other numeric
    /// attribute of the dataset is taken too (`attributes`).
    pub const RANGES: [&'static str; 3] = ["intensity", "elevation", "return_number"];

    /// Shows only `classes` (`only`), or hides them.
    pub fn set_classes(&mut self, classes: &[u8], only: bool) {
        let mut mask = match (only, self.classes) {
            (true, _) => [0u32; 8],
            (false, Some(m)) => m,
            (false, None) => [u32::MAX; 8],
        };
        self.classes_beyond = !only && self.classes.is_none_or(|_| self.classes_beyond);
        for &c in classes {
            let (word, bit) = (c as usize / 32, c as u32 % 32);
            if only {
                mask[word] |= 1 << bit;
            } else {
                mask[word] &= !(1 << bit);
            }
        }
        self.classes = Some(mask);
    }

    /// Adds a clip box; at most `ClipBox::MAX`.
    pub fn add_clip(&mut self, clip: ClipBox) -> Result<(), ViewerError> {
        if self.clips.len() >= ClipBox::MAX {
            let [a, b] = [clip.min, clip.max].map(|c| format!("{},{},{}", c[0], c[1], c[2]));
            let outside = if clip.outside { ";outside" } else { "" };
            return Err(ViewerError::argument(
                format!("min={a};max={b}{outside}"),
                format!("at most {} clip boxes", ClipBox::MAX),
            ));
        }
        self.clips.push(clip);
        Ok(())
    }

    /// Whether class `c` is shown.
    pub fn shows_class(&self, c: u8) -> bool {
        self.classes
            .is_none_or(|m| m[c as usize / 32] & (1 << (c as u32 % 32)) != 0)
    }

    /// Sets a range from `NAME=LO..HI`; the error names what is wrong.
    pub fn set_range(&mut self, assignment: &str) -> Result<(), ViewerError> {
        let fail = |what: String| ViewerError::argument(assignment, what);
        let (name, range) = assignment
            .split_once('=')
            .ok_or_else(|| fail("expected NAME=LOW..HIGH".into()))?;
        let (lo, hi) = range
            .split_once("..")
            .and_then(|(l, h)| Some((l.trim().parse::<f64>().ok()?, h.trim().parse::<f64>().ok()?)))
            .filter(|(l, h)| l.is_finite() && h.is_finite() && l <= h)
            .ok_or_else(|| {
                fail(format!(
                    "{name} needs a range LOW..HIGH of finite numbers with LOW at most HIGH"
                ))
            })?;
        match name.trim() {
            "intensity" => self.intensity = Some((lo, hi)),
            "elevation" => self.elevation = Some((lo, hi)),
            "return_number" => {
                let whole = |v: f64| v.fract() == 0.0 && (0.0..=15.0).contains(&v);
                if !(whole(lo) && whole(hi)) {
                    return Err(fail(
                        "return_number takes whole numbers from 0 to 15".into(),
                    ));
                }
                self.return_number = Some((lo as u32, hi as u32));
            }
            "" => return Err(fail("expected NAME=LOW..HIGH".into())),
            other => {
                // Checked against the dataset's attributes when it is opened.
                self.attributes.retain(|a| a.name != other);
                self.attributes.push(AttributeRange {
                    name: other.to_string(),
                    lo,
                    hi,
                });
            }
        }
        Ok(())
    }
}

#[derive(Clone)]
pub struct Settings {
    /// Which points are drawn.
    pub filter: PointFilter,
    pub budget: u64,
    /// The render pipeline, from `pipelines::REGISTRY`.
    pub pipeline: &'static PipelineInfo,
    /// Every pipeline's parameter values (the active one's are used).
    pub params: ParamValues,
    pub point_size: f32,
    pub size_mode: SizeMode,
    pub colour: ColourMode,
    /// Refinement stops where a node's point spacing projects below this many pixels.
    pub min_spacing_px: f32,
    pub background: [u8; 3],
    /// GPU uploads per frame are capped so frames stay even while streaming (None: no cap).
    pub upload_points_per_frame: Option<u64>,
    /// Resolve and shade in one pass where the frame allows (off: separate passes, to compare).
    pub fused_finish: bool,
    /// Use the two-pass 32-bit projection even on a device with 64-bit atomics.
    pub force_int32: bool,
    /// The clock the per-pass GPU times are taken with.
    pub pass_clock: PassClock,
}

impl Default for Settings {
    fn default() -> Settings {
        Settings {
            budget: 5_000_000,
            filter: PointFilter::default(),
            pipeline: pipelines::REGISTRY
                .iter()
                .copied()
                .find(|p| p.name == pipelines::DEFAULT_PIPELINE)
                .unwrap_or(pipelines::REGISTRY[0]),
            params: ParamValues::default(),
            point_size: SizeMode::Fixed.default_size(),
            size_mode: SizeMode::Fixed,
            colour: ColourMode::Rgb,
            min_spacing_px: 1.0,
            background: [24, 26, 32],
            upload_points_per_frame: Some(4_000_000),
            fused_finish: true,
            force_int32: false,
            pass_clock: PassClock::Auto,
        }
    }
}

impl Settings {
    /// Switches how points are sized; a size left at the old mode's default takes the new
    /// one's (3 pixels would be 3 spacings, half again the attenuated default).
    pub fn set_size_mode(&mut self, mode: SizeMode) {
        if self.point_size == self.size_mode.default_size() {
            self.point_size = mode.default_size();
        }
        self.size_mode = mode;
    }

    /// Chooses the pipeline `name`; the error lists the registered ones.
    pub fn set_pipeline(&mut self, name: &str) -> Result<(), ViewerError> {
        self.pipeline = pipelines::find(name)?;
        Ok(())
    }

    /// Sets a parameter of the chosen pipeline from `NAME=VALUE`; an unknown name or a value
    /// out of range is refused with a sentence that names it.
    pub fn set_param(&mut self, assignment: &str) -> Result<(), ViewerError> {
        let (name, value) = assignment
            .split_once('=')
            .ok_or_else(|| ViewerError::argument(assignment, "expected NAME=VALUE"))?;
        self.params.set_text(self.pipeline, name.trim(), value)
    }
}

impl std::fmt::Debug for Settings {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("Settings")
            .field("budget", &self.budget)
            .field("pipeline", &self.pipeline.name)
            .field("params", &self.params)
            .finish_non_exhaustive()
    }
}

pub const MIN_BUDGET: u64 = 100_000;
pub const MAX_BUDGET: u64 = 100_000_000;

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_default_size_follows_the_size_mode_and_a_chosen_one_stays() {
        let mut s = Settings::default();
        assert_eq!((s.size_mode, s.point_size), (SizeMode::Fixed, 3.0));
        s.set_size_mode(SizeMode::Attenuated);
        assert_eq!(s.point_size, 2.0);
        s.set_size_mode(SizeMode::Fixed);
        assert_eq!(s.point_size, 3.0);
        s.point_size = 5.0;
        s.set_size_mode(SizeMode::Attenuated);
        assert_eq!((s.size_mode, s.point_size), (SizeMode::Attenuated, 5.0));
    }
}
