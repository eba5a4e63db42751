//! The accept loop: a connection limit, idle and header timeouts, graceful shutdown.

use crate::ServerError;
use crate::handler::handle;
use crate::idle::IdleTimeout;
use hyper::server::conn::http1;
use hyper::service::service_fn;
use hyper_util::rt::{TokioIo, TokioTimer};
use hyper_util::server::graceful::GracefulShutdown;
use std::future::Future;
use std::io::Write;
use std::path::PathBuf;
use std::sync::Arc;
use std::time::Duration;
use tokio::net::TcpListener;
use tokio::sync::Semaphore;

#[derive(Debug, Clone)]
pub struct ServerConfig {
    /// The served directory, canonical.
    pub root: PathBuf,
    pub token: Option<String>,
    /// `Access-Control-Allow-Origin` value (`*` or an origin); no CORS headers when `None`.
    pub cors: Option<String>,
    pub max_connections: usize,
    /// Time to answer a request once its headers have arrived.
    pub request_timeout: Duration,
    /// A connection with no progress in either direction for this long is closed.
    pub idle_timeout: Duration,
    /// Time a client has to send a request's headers.
    pub header_timeout: Duration,
    /// How long shutdown waits for requests in flight.
    pub shutdown_grace: Duration,
    pub access_log: bool,
}

impl ServerConfig {
    pub fn new(root: &std::path::Path) -> Result<ServerConfig, ServerError> {
        let root = std::fs::canonicalize(root).map_err(|e| ServerError::Root {
            path: root.to_path_buf(),
            what: e.to_string(),
        })?;
        if !root.is_dir() {
            return Err(ServerError::Root {
                path: root,
                what: "not a directory".into(),
            });
        }
        Ok(ServerConfig {
            root,
            token: None,
            cors: None,
            max_connections: 512,
            request_timeout: Duration::from_secs(30),
            idle_timeout: Duration::from_secs(60),
            header_timeout: Duration::from_secs(10),
            shutdown_grace: Duration::from_secs(10),
            access_log: true,
        })
    }
}

pub async fn bind(addr: &str) -> Result<TcpListener, ServerError> {
    TcpListener::bind(addr)
        .await
        .map_err(|cause| ServerError::Bind {
            addr: addr.to_string(),
            cause,
        })
}

/// Serves until `shutdown` completes, then waits up to the grace period for open requests.
pub async fn run(
    listener: TcpListener,
    config: ServerConfig,
    shutdown: impl Future<Output = ()>,
) -> Result<(), ServerError> {
    let config = Arc::new(config);
    let slots = Arc::new(Semaphore::new(config.max_connections.max(1)));
    let graceful = GracefulShutdown::new();
    let mut shutdown = std::pin::pin!(shutdown);
    loop {
        // At the connection limit, new connections wait in the listen backlog.
        let permit = tokio::select! {
            p = slots.clone().acquire_owned() => match p {
                Ok(p) => p,
                Err(_) => break,
            },
            () = &mut shutdown => break,
        };
        let (stream, peer) = tokio::select! {
            r = listener.accept() => match r {
                Ok(x) => x,
                Err(e) => {
                    // Out of descriptors and the like: back off rather than spin.
                    let _ = writeln!(
            std::io::stderr(),
            "accept failed: {e}");
                    tokio::time::sleep(Duration::from_millis(50)).await;
                    continue;
                }
            },
            () = &mut shutdown => break,
        };
        let _ = stream.set_nodelay(true);
        let io = TokioIo::new(IdleTimeout::new(stream, config.idle_timeout));
        let cfg = config.clone();
        let service = service_fn(move |req| handle(req, peer, cfg.clone()));
        let conn = http1::Builder::new()
            .timer(TokioTimer::new())
            .header_read_timeout(config.header_timeout)
            .keep_alive(true)
            .serve_connection(io, service);
        let conn = graceful.watch(conn);
        tokio::spawn(async move {
            let _ = conn.await;
            drop(permit);
        });
    }
    drop(listener);
    tokio::select! {
        () = graceful.shutdown() => {}
        () = tokio::time::sleep(config.shutdown_grace) => {
            let _ = writeln!(
            std::io::stderr(),
            "shutdown: gave up waiting for open connections");
        }
    }
    Ok(())
}

/// Resolves on SIGINT or SIGTERM.
pub async fn shutdown_signal() {
    use tokio::signal::unix::{SignalKind, signal};
    match (
        signal(SignalKind::interrupt()),
        signal(SignalKind::terminate()),
    ) {
        (Ok(mut int), Ok(mut term)) => {
            tokio::select! {
                _ = int.recv() => {}
                _ = term.recv() => {}
            }
        }
        // Without signal handlers, only process exit stops the server.
        _ => std::future::pending::<()>().await,
    }
}
