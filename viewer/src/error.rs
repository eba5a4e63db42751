use std::path::PathBuf;
use strata_format::FormatError;

/// Everything the viewer can report. Each message names the thing (file, URL, adapter) and the fault.
#[derive(Debug, thiserror::Error)]
pub enum ViewerError {
    #[error(transparent)]
    Format(#[from] FormatError),
    #[error("{location}: {what}")]
    Source { location: String, what: String },
    /// A remote source did not answer (after retries); the same request may work later.
    #[error("{location}: {what}")]
    Unavailable { location: String, what: String },
    #[error(
        "no GPU adapter available ({0}); install a Vulkan driver (mesa-vulkan-drivers) or set WGPU_BACKEND"
    )]
    NoAdapter(String),
    #[error("GPU: {0}")]
    Gpu(String),
    /// No window opened: no display, or one that does not answer.
    #[error("cannot open a window: {0}; `strata render` draws views to PNG without one")]
    Window(String),
    #[error("{}: {what}", path.display())]
    Output { path: PathBuf, what: String },
    #[error("{what}: {input:?}")]
    Argument { input: String, what: String },
}

impl ViewerError {
    pub fn source(location: impl Into<String>, what: impl Into<String>) -> Self {
        ViewerError::Source {
            location: location.into(),
            what: what.into(),
        }
    }

    pub fn unavailable(location: impl Into<String>, what: impl Into<String>) -> Self {
        ViewerError::Unavailable {
            location: location.into(),
            what: what.into(),
        }
    }

    /// Whether retrying later can succeed (a server that went away) rather than never (a
    /// corrupt node).
    pub fn is_transient(&self) -> bool {
        matches!(self, ViewerError::Unavailable { .. })
    }

    pub fn output(path: impl Into<PathBuf>, what: impl std::fmt::Display) -> Self {
        ViewerError::Output {
            path: path.into(),
            what: what.to_string(),
        }
    }

    pub fn argument(input: impl Into<String>, what: impl Into<String>) -> Self {
        ViewerError::Argument {
            input: input.into(),
            what: what.into(),
        }
    }
}
