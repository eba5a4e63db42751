//! The accept loop: HTTP/1.1 and HTTP/2 (h2c, prior knowledge) on one port, a connection
//! limit, idle and header timeouts, parser rejections logged, graceful shutdown.

use crate::ServerError;
use crate::access_log::{AccessLog, Entry, LogFormat};
use crate::blocking::BlockingPool;
use crate::budget::{self, ServerBudget};
use crate::catalog::Catalog;
use crate::handler::{Shared, handle};
use crate::idle::IdleTimeout;
use hyper::service::service_fn;
use hyper_util::rt::{TokioExecutor, TokioIo, TokioTimer};
use hyper_util::server::conn::auto;
use hyper_util::server::graceful::GracefulShutdown;
use std::future::Future;
use std::io::Write;
use std::path::PathBuf;
use std::sync::Arc;
use std::time::{Duration, Instant};
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
    pub log_format: LogFormat,
    /// Threads of the file-system pool at most, counting those stuck in a call that outlived its
    /// request.
    pub blocking_threads: usize,
    /// Threads of the file-system pool that serve its queue.
    pub blocking_workers: usize,
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
            log_format: LogFormat::Text,
            blocking_threads: 64,
            // A few per core: more threads only trade places on the cores.
            blocking_workers: std::thread::available_parallelism()
                .map_or(4, |n| 2 * n.get())
                .max(4),
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

/// The HTTP/1.1 and HTTP/2 settings every connection shares.
fn connection_builder(config: &ServerConfig) -> auto::Builder<TokioExecutor> {
    let mut builder = auto::Builder::new(TokioExecutor::new());
    builder
        .http1()
        .timer(TokioTimer::new())
        .header_read_timeout(config.header_timeout)
        // A client that sends its requests and then shuts its side (`nc -N`, HTTP/1.0 tools,
        // scripts) still waits for the answers: hyper would otherwise drop the connection,
        // and every request on it unanswered, at the first read of end-of-file.
        .half_close(true)
        .keep_alive(true);
    builder
        .http2()
        .timer(TokioTimer::new())
        // Each open stream may hold an answer's buffer (a range up to 256 KiB, or a streamed
        // chunk) until the client reads it: few streams, small buffers (256 streams of 4 MiB
        // let one connection hold a gigabyte).
        .max_concurrent_streams(budget::H2_STREAMS)
        // Windows large enough that a 64 KiB node never waits on a WINDOW_UPDATE.
        .initial_stream_window_size(1 << 20)
        .initial_connection_window_size(16 << 20)
        .max_send_buf_size(256 << 10);
    builder
}

/// The status hyper answered a request it could not parse with, if that is how `e` came about.
fn rejected_with(e: &(dyn std::error::Error + 'static)) -> Option<u16> {
    let e = e.downcast_ref::<hyper::Error>()?;
    if !e.is_parse() {
        return None;
    }
    Some(if e.is_parse_too_large() {
        if e.to_string().contains("URI") {
            414
        } else {
            431
        }
    } else {
        400
    })
}

/// Serves until `shutdown` completes, then waits up to the grace period for open requests.
pub async fn run(
    listener: TcpListener,
    config: ServerConfig,
    shutdown: impl Future<Output = ()>,
) -> Result<(), ServerError> {
    let log = match config.access_log {
        true => Some(AccessLog::start(config.log_format)?),
        false => None,
    };
    let shared = Arc::new(Shared {
        catalog: Arc::new(Catalog::new(config.root.clone())),
        pool: BlockingPool::new(config.blocking_workers, config.blocking_threads),
        log,
        budget: ServerBudget::new(budget::SERVER),
        config,
    });
    let config = &shared.config;
    let builder = Arc::new(connection_builder(config));
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
                    let _ = writeln!(std::io::stderr(), "accept failed: {e}");
                    tokio::time::sleep(Duration::from_millis(50)).await;
                    continue;
                }
            },
            () = &mut shutdown => break,
        };
        let accepted = Instant::now();
        let _ = stream.set_nodelay(true);
        let io = TokioIo::new(IdleTimeout::new(
            stream,
            config.idle_timeout,
            config.header_timeout,
        ));
        let for_service = shared.clone();
        let budget = shared.budget.connection();
        let service = service_fn(move |req| handle(req, peer, for_service.clone(), budget.clone()));
        let conn = graceful.watch(builder.serve_connection(io, service).into_owned());
        let for_log = shared.clone();
        tokio::spawn(async move {
            if let Err(e) = conn.await
                && let (Some(status), Some(log)) = (rejected_with(&*e), &for_log.log)
            {
                log.log(&Entry::new(peer, status, 0, accepted.elapsed()));
            }
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
