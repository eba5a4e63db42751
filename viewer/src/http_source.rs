//! A dataset on an HTTP server (`strata serve`, nginx, object storage): metadata.json, then
//! byte ranges of hierarchy.bin and octree.bin, with a limit on concurrent requests, timeouts and
//! retries with backoff. A server that stops answering yields transient errors, so the viewer
//! keeps what it has and asks again later.

use crate::{Source, ViewerError};
use bytes::Bytes;
use http_body_util::{BodyExt, Empty};
use hyper::{Request, StatusCode, header};
use hyper_util::client::legacy::Client;
use hyper_util::client::legacy::connect::HttpConnector;
use hyper_util::rt::TokioExecutor;
use std::sync::Arc;
use std::time::Duration;
use strata_format::{DatasetFile, Metadata, check_file_head};
use tokio::sync::Semaphore;

pub struct HttpOptions {
    pub token: Option<String>,
    pub concurrency: usize,
    pub timeout: Duration,
    pub retries: u32,
}

impl Default for HttpOptions {
    fn default() -> Self {
        HttpOptions {
            token: None,
            concurrency: 8,
            timeout: Duration::from_secs(10),
            retries: 3,
        }
    }
}

pub struct HttpSource {
    base: String,
    opts: HttpOptions,
    runtime: tokio::runtime::Runtime,
    client: Client<HttpConnector, Empty<Bytes>>,
    slots: Arc<Semaphore>,
}

enum Failure {
    /// Worth retrying: connection refused or reset, timeout, 5xx.
    Transient(String),
    /// Retrying cannot help: 401, 404, 416, a wrong length.
    Permanent(String),
}

impl HttpSource {
    /// Connects to `url` (`http://HOST:PORT/DATASET`) and reads its metadata.
    pub fn open(url: &str, opts: HttpOptions) -> Result<(HttpSource, Metadata), ViewerError> {
        if url.starts_with("https://") {
            return Err(ViewerError::source(
                url,
                "https is not supported; serve the dataset over http or put a TLS proxy in front",
            ));
        }
        let base = url.trim_end_matches('/').to_string();
        let runtime = tokio::runtime::Builder::new_multi_thread()
            .worker_threads(2)
            .enable_all()
            .build()
            .map_err(|e| ViewerError::source(url, format!("cannot start the HTTP client ({e})")))?;
        let mut connector = HttpConnector::new();
        connector.set_connect_timeout(Some(opts.timeout));
        connector.set_nodelay(true);
        let client = Client::builder(TokioExecutor::new())
            .pool_idle_timeout(Duration::from_secs(30))
            .build(connector);
        let source = HttpSource {
            base,
            slots: Arc::new(Semaphore::new(opts.concurrency.max(1))),
            opts,
            runtime,
            client,
        };
        let bytes = source.fetch(DatasetFile::Metadata, None)?;
        let meta_url = format!("{}/{}", source.base, DatasetFile::Metadata.name());
        let metadata = Metadata::from_json(&bytes, std::path::Path::new(&meta_url))?;
        for (file, expected) in [
            (DatasetFile::Hierarchy, metadata.files.hierarchy.size),
            (DatasetFile::Octree, metadata.files.octree.size),
        ] {
            let (head, len) = source.fetch_sized(file, Some((0, 8)))?;
            let magic = match file {
                DatasetFile::Hierarchy => strata_format::HIERARCHY_MAGIC,
                _ => strata_format::OCTREE_MAGIC,
            };
            // A server that gives no Content-Range total leaves the length to the node checksums.
            check_file_head(
                source.url(file),
                len.unwrap_or(expected),
                &head,
                magic,
                expected,
            )?;
        }
        Ok((source, metadata))
    }

    fn url(&self, file: DatasetFile) -> String {
        format!("{}/{}", self.base, file.name())
    }

    /// GET a file, or `range = (offset, len)` of it, retrying transient failures.
    fn fetch(&self, file: DatasetFile, range: Option<(u64, u64)>) -> Result<Vec<u8>, ViewerError> {
        self.fetch_sized(file, range).map(|(body, _)| body)
    }

    /// As `fetch`, with the file's whole length where the answer tells it (the total of
    /// `Content-Range`, or the body of a whole-file answer).
    fn fetch_sized(
        &self,
        file: DatasetFile,
        range: Option<(u64, u64)>,
    ) -> Result<(Vec<u8>, Option<u64>), ViewerError> {
        let url = self.url(file);
        let mut delay = Duration::from_millis(100);
        let mut attempt = 0;
        loop {
            match self.runtime.block_on(self.fetch_once(&url, range)) {
                Ok(b) => return Ok(b),
                Err(Failure::Permanent(what)) => return Err(ViewerError::source(&url, what)),
                Err(Failure::Transient(what)) if attempt >= self.opts.retries => {
                    return Err(ViewerError::unavailable(
                        &url,
                        format!("{what} (after {} attempts)", attempt + 1),
                    ));
                }
                Err(Failure::Transient(_)) => {
                    std::thread::sleep(delay);
                    delay = (delay * 2).min(Duration::from_secs(2));
                    attempt += 1;
                }
            }
        }
    }

    async fn fetch_once(
        &self,
        url: &str,
        range: Option<(u64, u64)>,
    ) -> Result<(Vec<u8>, Option<u64>), Failure> {
        let _slot = self
            .slots
            .acquire()
            .await
            .map_err(|_| Failure::Transient("client shutting down".into()))?;
        let mut req = Request::get(url);
        if let Some((offset, len)) = range {
            req = req.header(
                header::RANGE,
                format!("bytes={offset}-{}", offset + len - 1),
            );
        }
        if let Some(t) = &self.opts.token {
            req = req.header(header::AUTHORIZATION, format!("Bearer {t}"));
        }
        let req = req
            .body(Empty::new())
            .map_err(|e| Failure::Permanent(format!("bad request: {e}")))?;
        let work = async {
            let resp = self
                .client
                .request(req)
                .await
                .map_err(|e| Failure::Transient(format!("request failed ({e})")))?;
            let status = resp.status();
            let total = resp
                .headers()
                .get(header::CONTENT_RANGE)
                .and_then(|v| v.to_str().ok())
                .and_then(|v| v.rsplit_once('/'))
                .and_then(|(_, t)| t.trim().parse::<u64>().ok());
            let body = resp
                .into_body()
                .collect()
                .await
                .map_err(|e| Failure::Transient(format!("body interrupted ({e})")))?
                .to_bytes();
            Ok::<_, Failure>((status, body, total))
        };
        let (status, body, total) = tokio::time::timeout(self.opts.timeout, work)
            .await
            .map_err(|_| {
                Failure::Transient(format!("no answer within {:?}", self.opts.timeout))
            })??;
        match (status, range) {
            (StatusCode::PARTIAL_CONTENT, Some((_, len))) if body.len() as u64 == len => {
                Ok((body.to_vec(), total))
            }
            // A server that ignores Range sends the whole file: take the part we asked for.
            (StatusCode::OK, Some((offset, len))) if body.len() as u64 >= offset + len => Ok((
                body[offset as usize..(offset + len) as usize].to_vec(),
                Some(body.len() as u64),
            )),
            (StatusCode::OK, None) => Ok((body.to_vec(), Some(body.len() as u64))),
            (StatusCode::UNAUTHORIZED | StatusCode::FORBIDDEN, _) => Err(Failure::Permanent(
                format!("HTTP {status}: the server refused access (check --token)"),
            )),
            (s, _) if s.is_server_error() || s == StatusCode::TOO_MANY_REQUESTS => {
                Err(Failure::Transient(format!("HTTP {s}")))
            }
            (s, Some((offset, len))) => Err(Failure::Permanent(format!(
                "HTTP {s} with {} bytes for the {len} bytes at byte {offset}",
                body.len()
            ))),
            (s, None) => Err(Failure::Permanent(format!("HTTP {s}"))),
        }
    }
}

impl Source for HttpSource {
    fn location(&self) -> String {
        self.base.clone()
    }

    fn metadata_bytes(&self) -> Result<Vec<u8>, ViewerError> {
        self.fetch(DatasetFile::Metadata, None)
    }

    fn read(&self, file: DatasetFile, offset: u64, len: u64) -> Result<Vec<u8>, ViewerError> {
        if len == 0 {
            return Ok(Vec::new());
        }
        self.fetch(file, Some((offset, len)))
    }
}
