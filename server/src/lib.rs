//! `strata serve`: a read-only HTTP/1.1 and HTTP/2 (h2c) server for a directory of Strata
//! datasets. It lists the datasets and serves the files their metadata names, with single byte
//! ranges, validators and CORS, confined to the directory, optionally behind a bearer token, with
//! limits on connections and time. Every file-system call runs on a bounded blocking pool.

mod access_log;
mod auth;
mod blocking;
mod body;
mod budget;
mod catalog;
mod error;
mod files;
mod h2_frames;
mod handler;
mod idle;
mod path;
mod range;
mod serve_file;
mod server;

pub use access_log::LogFormat;
pub use auth::check_token;
pub use error::ServerError;
pub use server::{ServerConfig, bind, run, shutdown_signal};
