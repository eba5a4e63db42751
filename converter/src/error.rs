use std::path::PathBuf;

/// Why a conversion, export or synthesis failed. Each message is one sentence that names the
/// file, the place in it and the fault.
#[derive(Debug, thiserror::Error)]
pub enum ConvertError {
    #[error("{}: {what}", path.display())]
    Input { path: PathBuf, what: String },
    #[error("{}: {what}: {source}", path.display())]
    Io {
        path: PathBuf,
        what: String,
        #[source]
        source: std::io::Error,
    },
    #[error("{}: {what}", path.display())]
    Output { path: PathBuf, what: String },
    #[error(transparent)]
    Format(#[from] strata_format::FormatError),
    #[error("{0}")]
    Usage(String),
    /// A LAS point lies outside the bounds its header declares. The conversion catches this
    /// and measures the bounds itself, so a user never sees it.
    #[error("{}: point {record} lies outside the bounds the header declares", path.display())]
    OutsideHeaderBounds { path: PathBuf, record: u64 },
}

impl ConvertError {
    pub fn input(path: impl Into<PathBuf>, what: impl Into<String>) -> Self {
        ConvertError::Input {
            path: path.into(),
            what: what.into(),
        }
    }

    pub fn io(path: impl Into<PathBuf>, what: impl Into<String>, source: std::io::Error) -> Self {
        ConvertError::Io {
            path: path.into(),
            what: what.into(),
            source,
        }
    }

    pub fn output(path: impl Into<PathBuf>, what: impl Into<String>) -> Self {
        ConvertError::Output {
            path: path.into(),
            what: what.into(),
        }
    }
}

pub type Result<T> = std::result::Result<T, ConvertError>;
