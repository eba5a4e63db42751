use std::path::{Path, PathBuf};

/// Why a conversion, export or synthesis failed. Each message is one sentence that names the
/// file, the place in it and the fault.
#[derive(Debug, thiserror::Error)]
pub enum ConvertError {
    #[error("{}: {what}", path.display())]
    Input { path: PathBuf, what: String },
    #[error("{}: {what}: {cause}", path.display())]
    Io {
        path: PathBuf,
        what: String,
        /// Named `cause`, not `source`: the message already says it, and an error chain
        /// that listed it again would print the OS error twice.
        cause: std::io::Error,
    },
    #[error("{}: {what}", path.display())]
    Output { path: PathBuf, what: String },
    /// A point's value that the output's format cannot hold (boxed: the details would make
    /// every `Result` of the crate larger).
    #[error("{0}")]
    Unfit(Box<Unfit>),
    /// Checked before any work: the conversion would not fit on the disk.
    #[error("{}: this needs about {} of free disk there, but only {} is free", path.display(), crate::sys::format_bytes_apart(*needed, *free).0, crate::sys::format_bytes_apart(*needed, *free).1)]
    NoSpace {
        path: PathBuf,
        needed: u64,
        free: u64,
    },
    /// `--finish` of a plan some of whose tasks have not finished.
    #[error("{}: cannot finish the conversion: {} of its {total} tasks not finished ({}); run `strata convert --plan {} --task K` for each", plan.display(), missing.len(), task_list(missing), plan.display())]
    TasksUnfinished {
        plan: PathBuf,
        missing: Vec<usize>,
        total: usize,
    },
    #[error(transparent)]
    Format(#[from] strata_format::FormatError),
    #[error("{0}")]
    Usage(String),
    /// A bug in the converter, not a fault of the inputs or the options: a worker panicked.
    #[error("internal fault while {during}: {message}; please report this")]
    Internal { during: String, message: String },
    /// The system would not start another worker thread (too many asked for with
    /// `--threads`, or no memory left for a thread's stack).
    #[error("cannot start worker thread {index} while {during} ({cause}); give fewer --threads")]
    Threads {
        during: String,
        index: usize,
        cause: std::io::Error,
    },
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
            cause: source,
        }
    }

    pub fn output(path: impl Into<PathBuf>, what: impl Into<String>) -> Self {
        ConvertError::Output {
            path: path.into(),
            what: what.into(),
        }
    }

    /// A value (as `shown` writes it) of `field` that the output `path` cannot hold, at row
    /// `row` of the rows written, and `why`.
    pub fn unfit(
        path: &Path,
        field: &str,
        value: String,
        row: usize,
        why: impl Into<String>,
    ) -> Self {
        ConvertError::Unfit(Box::new(Unfit {
            path: path.to_path_buf(),
            field: field.to_string(),
            value,
            why: why.into(),
            row,
            place: None,
        }))
    }

    /// Says where an `Unfit` value is: point `point(row)` of `node` of `dataset` (`point`
    /// maps the rows written to the node's points). Other errors pass unchanged.
    pub fn placed(
        self,
        dataset: &Path,
        node: &strata_format::NodeKey,
        point: impl FnOnce(usize) -> usize,
    ) -> Self {
        match self {
            ConvertError::Unfit(mut u) if u.place.is_none() => {
                u.place = Some(format!(
                    "point {} of node {node} of the dataset {}",
                    point(u.row),
                    dataset.display()
                ));
                ConvertError::Unfit(u)
            }
            other => other,
        }
    }

    pub fn internal(during: impl Into<String>, message: impl Into<String>) -> Self {
        ConvertError::Internal {
            during: during.into(),
            message: message.into(),
        }
    }
}

/// A point's value that the output's format cannot hold (a class beyond the point format's
/// bits, a fraction in an integer field): refused, not cut or rounded.
#[derive(Debug)]
pub struct Unfit {
    /// The output.
    pub path: PathBuf,
    pub field: String,
    pub value: String,
    /// What the format holds instead, and what to do.
    pub why: String,
    /// The row of the rows handed to the writer.
    pub row: usize,
    /// Which point of which node of which dataset, filled in by the caller that knows
    /// (`ConvertError::placed`).
    pub place: Option<String>,
}

impl std::fmt::Display for Unfit {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(
            f,
            "{}: a point's {} is {}",
            self.path.display(),
            self.field,
            self.value
        )?;
        if let Some(place) = &self.place {
            write!(f, " ({place})")?;
        }
        write!(f, ", {}", self.why)
    }
}

/// `v`, of type `ty`, in that type's own digits (an f32's -0.6, not -0.6000000238418579).
pub(crate) fn shown(ty: strata_format::AttrType, v: f64) -> String {
    if ty == strata_format::AttrType::F32 {
        format!("{}", v as f32)
    } else {
        format!("{v}")
    }
}

/// "task 3", "tasks 0, 2 and 5", at most a dozen named.
fn task_list(tasks: &[usize]) -> String {
    let named: Vec<String> = tasks.iter().take(12).map(|t| t.to_string()).collect();
    let more = tasks.len().saturating_sub(named.len());
    match (named.len(), more) {
        (1, _) => format!("task {}", named[0]),
        (_, 0) => {
            let (last, rest) = named
                .split_last()
                .map_or(("", &[][..]), |(l, r)| (l.as_str(), r));
            format!("tasks {} and {last}", rest.join(", "))
        }
        _ => format!("tasks {} and {more} more", named.join(", ")),
    }
}

/// For `map_err`: an I/O error on `path` while doing `what`.
pub(crate) fn io_err(path: &Path, what: &str) -> impl FnOnce(std::io::Error) -> ConvertError {
    let path = path.to_path_buf();
    let what = what.to_string();
    move |e| ConvertError::io(path, what, e)
}

/// The message a panic was raised with, when it has one.
pub(crate) fn panic_message(payload: &(dyn std::any::Any + Send)) -> String {
    if let Some(s) = payload.downcast_ref::<&str>() {
        (*s).to_string()
    } else if let Some(s) = payload.downcast_ref::<String>() {
        s.clone()
    } else {
        "a worker panicked".to_string()
    }
}

/// Starts worker `index` of `scope` on `f`; a thread the system refuses is an error naming
/// `during`, not the panic of `Scope::spawn`.
pub(crate) fn spawn_worker<'scope, T: Send + 'scope>(
    scope: &'scope std::thread::Scope<'scope, '_>,
    during: &str,
    index: usize,
    f: impl FnOnce() -> T + Send + 'scope,
) -> Result<std::thread::ScopedJoinHandle<'scope, T>> {
    std::thread::Builder::new()
        .spawn_scoped(scope, f)
        .map_err(|cause| ConvertError::Threads {
            during: during.to_string(),
            index,
            cause,
        })
}

pub type Result<T> = std::result::Result<T, ConvertError>;
