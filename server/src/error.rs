use std::path::PathBuf;

#[derive(Debug, thiserror::Error)]
pub enum ServerError {
    #[error("{}: cannot serve this directory ({what})", path.display())]
    Root { path: PathBuf, what: String },
    #[error("cannot listen on {addr}: {cause}")]
    Bind {
        addr: String,
        /// Not `source`: the message already says it (a chain would print it twice).
        cause: std::io::Error,
    },
    #[error("{0}")]
    Token(String),
    #[error("server: {0}")]
    Io(#[from] std::io::Error),
}
