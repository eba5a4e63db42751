use std::path::PathBuf;

#[derive(Debug, thiserror::Error)]
pub enum ServerError {
    #[error("{}: cannot serve this directory ({what})", path.display())]
    Root { path: PathBuf, what: String },
    #[error("cannot listen on {addr}: {source}")]
    Bind {
        addr: String,
        #[source]
        source: std::io::Error,
    },
    #[error("{0}")]
    Token(String),
    #[error("server: {0}")]
    Io(#[from] std::io::Error),
}
