//! `strata serve`: a read-only HTTP/1.1 server for a directory of Strata datasets. It lists the
//! datasets and serves their files with single byte ranges, validators and CORS, confined to the
//! directory, optionally behind a bearer token, with limits on connections and time.

mod body;
mod error;
mod handler;
mod idle;
mod listing;
mod path;
mod range;
mod server;

pub use error::ServerError;
pub use server::{ServerConfig, bind, run, shutdown_signal};
