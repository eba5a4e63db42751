use std::path::PathBuf;

/// Everything that can go wrong reading a dataset. Each message names the file and the fault.
#[derive(Debug, thiserror::Error)]
pub enum FormatError {
    #[error("{}: {cause}", path.display())]
    Io {
        path: PathBuf,
        /// Not `source`: the message already says it (a chain would print it twice).
        cause: std::io::Error,
    },
    #[error("{}: {what}", path.display())]
    Corrupt { path: PathBuf, what: String },
    #[error(
        "{}: dataset format version {found} is not supported by this reader (it reads {supported})",
        path.display()
    )]
    UnsupportedVersion {
        path: PathBuf,
        found: String,
        supported: String,
    },
}

impl FormatError {
    pub fn io(path: impl Into<PathBuf>, source: std::io::Error) -> Self {
        FormatError::Io {
            path: path.into(),
            cause: source,
        }
    }

    pub fn corrupt(path: impl Into<PathBuf>, what: impl Into<String>) -> Self {
        FormatError::Corrupt {
            path: path.into(),
            what: what.into(),
        }
    }
}

/// The finest step of coordinates stored at `scale` (per axis).
pub fn finest_step(scale: [f64; 3]) -> f64 {
    scale.into_iter().fold(f64::INFINITY, f64::min)
}

/// The decimals that show a multiple of `step` exactly (0.001: 3; 0.25: 2; 1e-7: 7), at most
/// 12; 3 for no step (zero, negative or not finite). Coordinates stored at a scale print to its
/// decimals: fewer hide what was measured (a scan in degrees printed as 11.000), more add
/// digits no point has.
pub fn step_decimals(step: f64) -> usize {
    const MAX: usize = 12;
    if !(step.is_finite() && step > 0.0) {
        return 3;
    }
    (0..MAX)
        .find(|&d| {
            let scaled = step * 10f64.powi(d as i32);
            (scaled - scaled.round()).abs() <= scaled * 1e-9
        })
        .unwrap_or(MAX)
}

/// A number as a person writes it: plain when moderate, in exponent form when tiny or huge.
pub fn number(v: f64) -> String {
    if v == 0.0 || !v.is_finite() || (1e-6..1e15).contains(&v.abs()) {
        format!("{v}")
    } else {
        format!("{v:e}")
    }
}
