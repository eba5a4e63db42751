//! A dataset on an HTTP server (`strata serve`, nginx, object storage): metadata.json, then
//! byte ranges of hierarchy.bin and octree.bin, with a limit on concurrent requests, timeouts and
//! retries with backoff. A server that stops answering yields transient errors, so the viewer
//! keeps what it has and asks again later.
//!
//! Opening takes one round trip: metadata.json, the first `HIERARCHY_PREFIX` bytes of
//! hierarchy.bin (its head and, in format 1.1, the root page, which follows the head) and the
//! head of octree.bin are asked for at once.

use crate::{Source, ViewerError};
use bytes::Bytes;
use http_body_util::{BodyExt, Empty};
use hyper::{Request, StatusCode, header};
use hyper_util::client::legacy::Client;
use hyper_util::client::legacy::connect::HttpConnector;
use hyper_util::rt::TokioExecutor;
use std::sync::Arc;
use std::time::Duration;
use strata_format::{
    DatasetFile, HIERARCHY_HEAD_SIZE, METADATA_MAX_BYTES, Metadata, OCTREE_HEAD_SIZE,
    check_file_head,
};
use tokio::sync::Semaphore;

/// Bytes of hierarchy.bin asked for with metadata.json unless told otherwise: the head, and
/// the root page of any dataset whose root page is under 64 KiB (about 2,700 entries; a page of
/// five levels holds at most 4,681). A larger root page costs one more request. A server sends
/// less when the file is shorter (then the whole hierarchy comes at once).
pub const HIERARCHY_PREFIX: u64 = 64 << 10;

pub struct HttpOptions {
    pub token: Option<String>,
    pub concurrency: usize,
    /// How long one attempt at a read waits for its answer.
    pub timeout: Duration,
    pub retries: u32,
    /// How long one read may take, its retries included: a command given a time to wait
    /// (`render --timeout`) fails within it when the server has gone away, not after every
    /// retry has waited out `timeout`.
    pub give_up_after: Option<Duration>,
    /// Bytes of hierarchy.bin to ask for at open (at least the 32-byte head).
    pub hierarchy_prefix: u64,
}

impl Default for HttpOptions {
    fn default() -> Self {
        HttpOptions {
            token: None,
            concurrency: 8,
            timeout: Duration::from_secs(10),
            retries: 3,
            give_up_after: None,
            hierarchy_prefix: HIERARCHY_PREFIX,
        }
    }
}

pub struct HttpSource {
    /// The dataset's URL without its query: what errors and stats name.
    base: String,
    /// The URL's `?query`, asked with every file (a presigned URL's signature), or empty.
    query: String,
    /// The names of hierarchy.bin and octree.bin, as metadata.json gives them.
    names: [String; 2],
    /// Their sizes, from metadata.json: no read asks beyond them.
    sizes: [u64; 2],
    opts: HttpOptions,
    runtime: tokio::runtime::Runtime,
    client: Client<HttpConnector, Empty<Bytes>>,
    slots: Arc<Semaphore>,
    /// The first bytes of hierarchy.bin, fetched at open; reads inside them ask nothing.
    hierarchy_prefix: Vec<u8>,
}

/// What part of a file to ask for.
#[derive(Debug, Clone, Copy)]
enum Want {
    Whole,
    /// Exactly `len` bytes at `offset`.
    Exact(u64, u64),
    /// Up to `len` bytes at `offset`: fewer where the file ends first.
    Prefix(u64, u64),
}

impl Want {
    fn range(self) -> Option<(u64, u64)> {
        match self {
            Want::Whole => None,
            Want::Exact(o, l) | Want::Prefix(o, l) => Some((o, l)),
        }
    }
}

enum Failure {
    /// Worth retrying: connection refused or reset, timeout, 5xx.
    Transient(String),
    /// Retrying cannot help: 404, 416, a wrong length.
    Permanent(String),
    /// 401 and 403: asking again at once gets the same answer, but a later request may not
    /// (a token rotated, a server restarted with the one given). Failed for good, the nodes
    /// asked for while it lasted stayed holes for the rest of the session, counted as failed
    /// without a word of why; unavailable, they are asked for again and the reason is shown.
    Refused(String),
}

impl HttpSource {
    /// Connects to `url` (`http://HOST:PORT/DATASET`) and reads its metadata.
    pub fn open(url: &str, opts: HttpOptions) -> Result<(HttpSource, Metadata), ViewerError> {
        let (base, query) = split_url(url)?;
        let runtime = tokio::runtime::Builder::new_multi_thread()
            .worker_threads(2)
            .enable_all()
            .build()
            .map_err(|e| {
                ViewerError::source(&base, format!("cannot start the HTTP client ({e})"))
            })?;
        let mut connector = HttpConnector::new();
        connector.set_connect_timeout(Some(opts.timeout));
        connector.set_nodelay(true);
        let client = Client::builder(TokioExecutor::new())
            .pool_idle_timeout(Duration::from_secs(30))
            .build(connector);
        let mut source = HttpSource {
            base,
            query,
            names: [DatasetFile::Hierarchy, DatasetFile::Octree].map(|f| f.name().to_owned()),
            sizes: [0; 2],
            slots: Arc::new(Semaphore::new(opts.concurrency.max(1))),
            opts,
            runtime,
            client,
            hierarchy_prefix: Vec::new(),
        };
        let prefix = source.opts.hierarchy_prefix.max(HIERARCHY_HEAD_SIZE);
        // One round trip: the root page's place is fixed (format 1.1), so it need not wait
        // for the metadata, and neither need the heads.
        let (meta, hierarchy, octree) = source.runtime.block_on(async {
            tokio::join!(
                source.fetch_async(DatasetFile::Metadata, Want::Whole),
                source.fetch_async(DatasetFile::Hierarchy, Want::Prefix(0, prefix)),
                source.fetch_async(DatasetFile::Octree, Want::Prefix(0, OCTREE_HEAD_SIZE)),
            )
        });
        let (bytes, _) = meta?;
        let meta_url = source.url(DatasetFile::Metadata);
        let metadata = Metadata::from_json(&bytes, std::path::Path::new(&meta_url))?;
        let files = &metadata.files;
        source.sizes = [files.hierarchy.size, files.octree.size];
        let names = [files.hierarchy.name.clone(), files.octree.name.clone()];
        // Files of other names than the usual (SPEC.md section 2) were asked for in vain.
        let (hierarchy, octree) = if names == source.names {
            (hierarchy, octree)
        } else {
            source.names = names;
            source.runtime.block_on(async {
                tokio::join!(
                    source.fetch_async(DatasetFile::Hierarchy, Want::Prefix(0, prefix)),
                    source.fetch_async(DatasetFile::Octree, Want::Prefix(0, OCTREE_HEAD_SIZE)),
                )
            })
        };
        for (file, fetched) in [
            (DatasetFile::Hierarchy, hierarchy?),
            (DatasetFile::Octree, octree?),
        ] {
            let (head, len) = fetched;
            // A server that gives no Content-Range total leaves the length to the checksums.
            check_file_head(source.url(file), file, len, &head, &metadata)?;
            if file == DatasetFile::Hierarchy {
                source.hierarchy_prefix = head;
            }
        }
        Ok((source, metadata))
    }

    /// The URL of `file` without the query, as messages name it.
    fn url(&self, file: DatasetFile) -> String {
        let name = match file {
            DatasetFile::Metadata => file.name(),
            DatasetFile::Hierarchy => &self.names[0],
            DatasetFile::Octree => &self.names[1],
        };
        format!("{}/{}", self.base, percent_encoded(name))
    }

    /// GET a file, or `range = (offset, len)` of it, retrying transient failures.
    fn fetch(&self, file: DatasetFile, range: Option<(u64, u64)>) -> Result<Vec<u8>, ViewerError> {
        let want = range.map_or(Want::Whole, |(o, l)| Want::Exact(o, l));
        let fetched = self.runtime.block_on(self.fetch_async(file, want));
        fetched.map(|(body, _)| body)
    }

    /// As `fetch`, with the file's whole length where the answer tells it (the total of
    /// `Content-Range`; for a whole-file answer its body, or its `Content-Length` where the
    /// body went on past the range's end and was left unread).
    async fn fetch_async(
        &self,
        file: DatasetFile,
        want: Want,
    ) -> Result<(Vec<u8>, Option<u64>), ViewerError> {
        let url = self.url(file);
        let request = format!("{url}{}", self.query);
        let started = tokio::time::Instant::now();
        let mut delay = Duration::from_millis(100);
        let mut attempt = 0;
        let deadline = self.opts.give_up_after.map(|bound| started + bound);
        loop {
            match self.fetch_once(&request, want, deadline).await {
                Ok(b) => return Ok(b),
                Err(Failure::Permanent(what)) => return Err(ViewerError::source(&url, what)),
                Err(Failure::Refused(what)) => return Err(ViewerError::unavailable(&url, what)),
                Err(Failure::Transient(what))
                    if attempt >= self.opts.retries
                        || deadline.is_some_and(|d| tokio::time::Instant::now() + delay >= d) =>
                {
                    let tries = match attempt {
                        0 => "1 attempt".to_string(),
                        n => format!("{} attempts", n + 1),
                    };
                    return Err(ViewerError::unavailable(
                        &url,
                        format!(
                            "{what} (gave up after {tries} in {:.1} s)",
                            started.elapsed().as_secs_f64()
                        ),
                    ));
                }
                Err(Failure::Transient(_)) => {
                    tokio::time::sleep(delay).await;
                    delay = (delay * 2).min(Duration::from_secs(2));
                    attempt += 1;
                }
            }
        }
    }

    /// One attempt, waiting at most `timeout` for the whole answer, and not past `deadline`
    /// (the wait for a request slot included).
    async fn fetch_once(
        &self,
        url: &str,
        want: Want,
        deadline: Option<tokio::time::Instant>,
    ) -> Result<(Vec<u8>, Option<u64>), Failure> {
        let range = want.range();
        let late = || Failure::Transient("no answer within the time given".into());
        let slot = self.slots.acquire();
        let _slot = match deadline {
            Some(d) => tokio::time::timeout_at(d, slot).await.map_err(|_| late())?,
            None => slot.await,
        }
        .map_err(|_| Failure::Transient("client shutting down".into()))?;
        let wait = deadline.map_or(self.opts.timeout, |d| {
            d.saturating_duration_since(tokio::time::Instant::now())
                .min(self.opts.timeout)
        });
        if wait.is_zero() {
            return Err(late());
        }
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
                .map_err(|e| Failure::Transient(request_failure(&e)))?;
            let status = resp.status();
            let answered = content_range(resp.headers());
            let total = answered.and_then(|(_, total)| total);
            let length = resp
                .headers()
                .get(header::CONTENT_LENGTH)
                .and_then(|v| v.to_str().ok())
                .and_then(|v| v.trim().parse::<u64>().ok());
            let location = resp
                .headers()
                .get(header::LOCATION)
                .and_then(|v| v.to_str().ok())
                .map(str::to_owned);
            if let (Some((Some(start), _)), StatusCode::PARTIAL_CONTENT, Some((offset, _))) =
                (answered, status, range)
                && start != offset
            {
                return Err(Failure::Permanent(format!(
                    "HTTP {status} for the bytes from {start}, where those from {offset} were asked for"
                )));
            }
            // Bytes of a compressed body are not the file's: a range of them means nothing
            // (object storage sends them for files uploaded with a Content-Encoding).
            if let Some(coding) = resp
                .headers()
                .get(header::CONTENT_ENCODING)
                .and_then(|v| v.to_str().ok())
                .filter(|v| !v.trim().is_empty() && !v.trim().eq_ignore_ascii_case("identity"))
                && status.is_success()
            {
                return Err(Failure::Permanent(format!(
                    "HTTP {status} with Content-Encoding {coding}: the server sends the file \
                     compressed, which byte ranges cannot address; serve it as it is"
                )));
            }
            let cap = body_cap(status, want);
            // A whole file sent for a range: the bytes before it are passed over, not kept.
            let skip = match (status, range) {
                (StatusCode::OK, Some((offset, _))) => offset,
                _ => 0,
            };
            let (body, seen, more) = read_capped(resp.into_body(), skip, cap)
                .await
                .map_err(|e| Failure::Transient(format!("body interrupted ({e})")))?;
            // A whole file sent for a range holds more than the range's end: its length is
            // then what the answer says, if it says. Any other answer longer than asked for
            // is wrong, but for an error page, whose start tells the error.
            let whole = match (more, status, want) {
                (false, ..) => Some(seen),
                (true, StatusCode::OK, Want::Exact(..) | Want::Prefix(..)) => length,
                (true, StatusCode::OK | StatusCode::PARTIAL_CONTENT, _) => {
                    return Err(Failure::Permanent(format!(
                        "HTTP {status} with more than the {cap} bytes expected"
                    )));
                }
                (true, ..) => None,
            };
            Ok::<_, Failure>((status, body, seen, total, whole, location))
        };
        let (status, body, seen, total, whole, location) =
            tokio::time::timeout(wait, work).await.map_err(|_| {
                Failure::Transient(format!("no answer within {:.1} s", wait.as_secs_f64()))
            })??;
        let got = body.len() as u64;
        match (status, want) {
            (StatusCode::PARTIAL_CONTENT, Want::Exact(_, len)) if got == len => Ok((body, total)),
            // Less than asked only where the file ends (when the answer says where that is).
            (StatusCode::PARTIAL_CONTENT, Want::Prefix(offset, len))
                if got <= len && total.is_none_or(|t| got == len.min(t.saturating_sub(offset))) =>
            {
                Ok((body, total))
            }
            // A server that ignores Range sends the whole file; `body` is the part asked for.
            (StatusCode::OK, Want::Exact(offset, len)) if seen >= offset + len => Ok((body, whole)),
            (StatusCode::OK, Want::Prefix(offset, _)) if seen >= offset => Ok((body, whole)),
            (StatusCode::OK, Want::Whole) => Ok((body, whole)),
            (StatusCode::UNAUTHORIZED | StatusCode::FORBIDDEN, _) => Err(Failure::Refused(
                format!("HTTP {status}: the server refused access (check --token)"),
            )),
            (s, _) if s.is_server_error() || s == StatusCode::TOO_MANY_REQUESTS => {
                Err(Failure::Transient(format!("HTTP {s}")))
            }
            (s, _) if s.is_redirection() => Err(Failure::Permanent(format!(
                "HTTP {s} to {}: redirects are not followed (a token must not go to another \
                 host); give the URL it names",
                location.as_deref().map_or("nowhere named", without_query)
            ))),
            (s, Want::Exact(offset, len) | Want::Prefix(offset, len)) => Err(Failure::Permanent(
                format!("HTTP {s} with {got} bytes for the {len} bytes at byte {offset}"),
            )),
            (s, Want::Whole) => Err(Failure::Permanent(format!("HTTP {s}"))),
        }
    }
}

/// The most bytes of an answer's body read: what was asked for (a server that ignores Range
/// sends the whole file, of which the range's end is enough), a metadata file's bound, or the
/// start of an error page. A body that goes on beyond it is not read: a server that never
/// ends one costs no more memory than this.
fn body_cap(status: StatusCode, want: Want) -> u64 {
    match (status, want) {
        (StatusCode::PARTIAL_CONTENT, Want::Exact(_, len) | Want::Prefix(_, len)) => len,
        (StatusCode::OK, Want::Exact(offset, len) | Want::Prefix(offset, len)) => {
            offset.saturating_add(len)
        }
        (StatusCode::OK | StatusCode::PARTIAL_CONTENT, Want::Whole) => METADATA_MAX_BYTES,
        _ => ERROR_BODY_MAX_BYTES,
    }
}

/// The most of an error page read.
const ERROR_BODY_MAX_BYTES: u64 = 64 << 10;

/// The body's first `cap` bytes but for the first `skip`, which are read and passed over;
/// how many bytes were read, and whether the body held more (then left unread).
async fn read_capped(
    mut body: hyper::body::Incoming,
    skip: u64,
    cap: u64,
) -> Result<(Vec<u8>, u64, bool), hyper::Error> {
    let mut out = Vec::new();
    let mut seen = 0u64;
    while let Some(frame) = body.frame().await {
        let Ok(data) = frame?.into_data() else {
            continue;
        };
        let room = cap.saturating_sub(seen);
        let take = (data.len() as u64).min(room);
        let from = skip.saturating_sub(seen).min(take);
        out.extend_from_slice(&data[from as usize..take as usize]);
        seen += take;
        if data.len() as u64 > room {
            return Ok((out, seen, true));
        }
    }
    Ok((out, seen, false))
}

/// The start and the file's length of a `Content-Range: bytes START-END/TOTAL` answer, each
/// where it says (`*` for either).
fn content_range(headers: &header::HeaderMap) -> Option<(Option<u64>, Option<u64>)> {
    let v = headers.get(header::CONTENT_RANGE)?.to_str().ok()?;
    let v = v.trim();
    let (range, total) = v.strip_prefix("bytes ").unwrap_or(v).rsplit_once('/')?;
    let start = range
        .split_once('-')
        .and_then(|(s, _)| s.trim().parse().ok());
    Some((start, total.trim().parse().ok()))
}

/// `url` as the dataset's URL without a trailing slash or fragment, and its `?query` (or
/// ""). Refused: https, and a user name or password in it, which would be neither sent nor
/// kept out of messages (the URL is named in every error and in `--stats`).
fn split_url(url: &str) -> Result<(String, String), ViewerError> {
    let shown = without_query(url);
    let scheme = url.split_once("://").map_or("", |(s, _)| s);
    let rest = match url.split_once("://") {
        Some((s, rest)) if s.eq_ignore_ascii_case("http") => rest,
        Some((s, _)) if s.eq_ignore_ascii_case("https") => {
            return Err(ViewerError::source(
                shown,
                "https is not supported; serve the dataset over http or put a TLS proxy in front",
            ));
        }
        _ => {
            return Err(ViewerError::source(
                shown,
                format!("{scheme:?} is not a scheme this reads; give http://HOST:PORT/DATASET"),
            ));
        }
    };
    let rest = rest.split_once('#').map_or(rest, |(r, _)| r);
    let (path, query) = rest.split_once('?').map_or((rest, ""), |(p, q)| (p, q));
    let authority = path.split_once('/').map_or(path, |(a, _)| a);
    if let Some((_, host)) = authority.rsplit_once('@') {
        return Err(ViewerError::source(
            format!("http://…@{host}"),
            "the URL holds a user name or password, which is not sent; give a token with --token",
        ));
    }
    let query = if query.is_empty() {
        String::new()
    } else {
        format!("?{query}")
    };
    Ok((format!("http://{}", path.trim_end_matches('/')), query))
}

/// `url` without its query or fragment, as messages name it: a presigned URL's signature is a
/// credential.
fn without_query(url: &str) -> &str {
    url.split(['?', '#']).next().unwrap_or(url)
}

/// Bytes of a file name kept as they are in a URL path segment (RFC 3986's unreserved ones);
/// names are plain segments (SPEC.md section 2) but may hold spaces or any other character.
const SEGMENT_KEEPS: &percent_encoding::AsciiSet = &percent_encoding::NON_ALPHANUMERIC
    .remove(b'-')
    .remove(b'.')
    .remove(b'_')
    .remove(b'~');

fn percent_encoded(name: &str) -> String {
    percent_encoding::utf8_percent_encode(name, SEGMENT_KEEPS).to_string()
}

impl Source for HttpSource {
    fn location(&self) -> String {
        self.base.clone()
    }

    fn file_location(&self, file: DatasetFile) -> String {
        self.url(file)
    }

    fn metadata_bytes(&self) -> Result<Vec<u8>, ViewerError> {
        self.fetch(DatasetFile::Metadata, None)
    }

    fn read(&self, file: DatasetFile, offset: u64, len: u64) -> Result<Vec<u8>, ViewerError> {
        if len == 0 {
            return Ok(Vec::new());
        }
        let size = match file {
            DatasetFile::Metadata => METADATA_MAX_BYTES,
            DatasetFile::Hierarchy => self.sizes[0],
            DatasetFile::Octree => self.sizes[1],
        };
        if offset.checked_add(len).is_none_or(|end| end > size) {
            return Err(ViewerError::source(
                self.url(file),
                format!("range of {len} bytes at byte {offset} lies past the end ({size} bytes)"),
            ));
        }
        let prefix = &self.hierarchy_prefix;
        if file == DatasetFile::Hierarchy
            && let Some(end) = offset
                .checked_add(len)
                .filter(|&e| e <= prefix.len() as u64)
        {
            return Ok(prefix[offset as usize..end as usize].to_vec());
        }
        self.fetch(file, Some((offset, len)))
    }
}

/// What a request that got no answer met: hyper's own message names only its stage ("client
/// error (Connect)"); the cause below it says what happened ("Connection refused").
fn request_failure(e: &(dyn std::error::Error + 'static)) -> String {
    let mut causes = Vec::new();
    let mut at = e.source();
    while let Some(cause) = at {
        causes.push(cause.to_string());
        at = cause.source();
    }
    let connect = e
        .downcast_ref::<hyper_util::client::legacy::Error>()
        .is_some_and(|e| e.is_connect());
    match (connect, causes.last()) {
        (true, Some(cause)) => format!("cannot connect: {cause}"),
        (true, None) => "cannot connect".into(),
        (false, Some(cause)) => format!("request failed: {cause}"),
        (false, None) => format!("request failed ({e})"),
    }
}
