//! Progress bars per phase: drawn on a terminal, silent otherwise or with `--quiet`.

use crate::error::Result;
use indicatif::{ProgressBar, ProgressDrawTarget, ProgressStyle};
use serde::Serialize;
use std::io::IsTerminal;
use std::time::Instant;

#[derive(Debug, Clone, Copy)]
pub struct Progress {
    visible: bool,
}

impl Progress {
    pub fn new(quiet: bool) -> Self {
        Progress {
            visible: !quiet && std::io::stderr().is_terminal(),
        }
    }

    pub fn hidden() -> Self {
        Progress { visible: false }
    }

    /// A bar for one phase counting `unit`s up to `len`.
    pub fn phase(&self, name: &str, len: u64, unit: &str) -> ProgressBar {
        if !self.visible {
            return ProgressBar::hidden();
        }
        let bar = ProgressBar::with_draw_target(Some(len), ProgressDrawTarget::stderr());
        let template = format!(
            "{{prefix:>10}} [{{bar:32}}] {{human_pos}}/{{human_len}} {unit} {{per_sec}} ETA {{eta}}"
        );
        if let Ok(style) = ProgressStyle::with_template(&template) {
            bar.set_style(style.progress_chars("=> "));
        }
        bar.set_prefix(name.to_string());
        bar
    }
}

/// How long one phase of a conversion took.
#[derive(Debug, Clone, Serialize)]
pub struct PhaseTime {
    pub name: &'static str,
    pub seconds: f64,
}

/// The phases of one conversion, each under a bar of its own, and how long each took.
#[derive(Debug)]
pub struct Phases {
    progress: Progress,
    times: Vec<PhaseTime>,
}

impl Phases {
    pub fn new(progress: Progress) -> Self {
        Phases {
            progress,
            times: Vec::new(),
        }
    }

    /// Runs phase `name`, with a bar counting `(len, unit)` when given, and records its time
    /// if it succeeds.
    pub fn timed<T>(
        &mut self,
        name: &'static str,
        bar: Option<(u64, &str)>,
        f: impl FnOnce(&ProgressBar) -> Result<T>,
    ) -> Result<T> {
        let start = Instant::now();
        let bar = match bar {
            Some((len, unit)) => self.progress.phase(name, len, unit),
            None => ProgressBar::hidden(),
        };
        let out = f(&bar);
        bar.finish_and_clear();
        let out = out?;
        self.times.push(PhaseTime {
            name,
            seconds: start.elapsed().as_secs_f64(),
        });
        Ok(out)
    }

    pub fn into_times(self) -> Vec<PhaseTime> {
        self.times
    }
}
