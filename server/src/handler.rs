//! One request: `Host`, CORS, token, method, path, then the listing or a dataset file; every
//! answer is logged.

use crate::access_log::{AccessLog, Entry};
use crate::auth::bearer_matches;
use crate::blocking::BlockingPool;
use crate::body::{ResponseBody, empty, full};
use crate::budget::{ConnectionBudget, ServerBudget};
use crate::catalog::Catalog;
use crate::path::{Refusal, segments};
use crate::serve_file::{self, Conditions, Failure};
use crate::server::ServerConfig;
use bytes::Bytes;
use http_body_util::BodyExt;
use hyper::body::{Body, Frame, SizeHint};
use hyper::header::{self, HeaderValue};
use hyper::{Method, Request, Response, StatusCode, Version};
use std::net::SocketAddr;
use std::pin::Pin;
use std::sync::Arc;
use std::task::{Context, Poll};
use std::time::Instant;

/// What every request shares.
#[derive(Debug)]
pub struct Shared {
    pub config: ServerConfig,
    pub catalog: Arc<Catalog>,
    pub pool: BlockingPool,
    pub log: Option<AccessLog>,
    /// Memory for answers in flight; each connection draws its share from it.
    pub budget: ServerBudget,
}

pub async fn handle<B>(
    req: Request<B>,
    peer: SocketAddr,
    shared: Arc<Shared>,
    budget: ConnectionBudget,
) -> Result<Response<ResponseBody>, std::convert::Infallible> {
    let start = Instant::now();
    let timeout = shared.config.request_timeout;
    let mut resp = match tokio::time::timeout(timeout, respond(&req, &shared, &budget)).await {
        Ok(r) => r,
        Err(_) => status(StatusCode::SERVICE_UNAVAILABLE, "request timed out\n"),
    };
    if let Some(origin) = &shared.config.cors {
        let h = resp.headers_mut();
        if let Ok(v) = HeaderValue::from_str(origin) {
            h.insert(header::ACCESS_CONTROL_ALLOW_ORIGIN, v);
        }
        h.insert(
            header::ACCESS_CONTROL_EXPOSE_HEADERS,
            HeaderValue::from_static(
                "Content-Range, Content-Length, Accept-Ranges, ETag, Last-Modified",
            ),
        );
        if origin != "*" {
            h.insert(header::VARY, HeaderValue::from_static("Origin"));
        }
    }
    if shared.log.is_none() {
        return Ok(resp);
    }
    let mut entry = Entry::new(peer, resp.status().as_u16(), 0, start.elapsed());
    entry.method = req.method().to_string();
    entry.path = req.uri().path().to_string();
    entry.version = version_name(req.version());
    let shared = shared.clone();
    Ok(resp.map(|body| {
        LoggedBody {
            inner: body,
            entry,
            start,
            shared,
        }
        .boxed_unsync()
    }))
}

/// An answer's body that logs its request when it ends or is dropped: with the bytes that went
/// out and the time until then, and why it was cut short where the file failed. Logged when the
/// headers were ready, a download the client left, or a file cut short while it was read,
/// showed the bytes the answer promised, and a download of minutes the milliseconds its
/// headers took; a file cut short then looked like a client that left.
struct LoggedBody {
    inner: ResponseBody,
    entry: Entry,
    start: Instant,
    shared: Arc<Shared>,
}

impl Body for LoggedBody {
    type Data = Bytes;
    type Error = std::io::Error;

    fn poll_frame(
        self: Pin<&mut Self>,
        cx: &mut Context<'_>,
    ) -> Poll<Option<Result<Frame<Bytes>, std::io::Error>>> {
        let this = self.get_mut();
        let frame = std::task::ready!(Pin::new(&mut this.inner).poll_frame(cx));
        match &frame {
            Some(Ok(f)) => {
                if let Some(data) = f.data_ref() {
                    this.entry.bytes += data.len() as u64;
                }
            }
            // The answer ends short of its length (HTTP/1 closes the connection, HTTP/2 resets
            // the stream); the line says why.
            Some(Err(e)) => this.entry.error = Some(e.to_string()),
            None => {}
        }
        Poll::Ready(frame)
    }

    fn is_end_stream(&self) -> bool {
        self.inner.is_end_stream()
    }

    fn size_hint(&self) -> SizeHint {
        self.inner.size_hint()
    }
}

impl Drop for LoggedBody {
    fn drop(&mut self) {
        if let Some(log) = &self.shared.log {
            self.entry.ms = self.start.elapsed().as_secs_f64() * 1e3;
            log.log(&self.entry);
        }
    }
}

fn version_name(v: Version) -> &'static str {
    match v {
        Version::HTTP_09 => "HTTP/0.9",
        Version::HTTP_10 => "HTTP/1.0",
        Version::HTTP_2 => "HTTP/2.0",
        Version::HTTP_3 => "HTTP/3.0",
        _ => "HTTP/1.1",
    }
}

fn status(code: StatusCode, text: &'static str) -> Response<ResponseBody> {
    let mut r = Response::new(full(text));
    *r.status_mut() = code;
    r.headers_mut().insert(
        header::CONTENT_TYPE,
        HeaderValue::from_static("text/plain; charset=utf-8"),
    );
    r.headers_mut()
        .insert(header::CONTENT_LENGTH, HeaderValue::from(text.len()));
    r
}

fn not_found() -> Response<ResponseBody> {
    status(StatusCode::NOT_FOUND, "not found\n")
}

/// RFC 9112 §3.2: an HTTP/1.1 request carries exactly one `Host`, whose value is a host with an
/// optional port (empty when the target has no authority). HTTP/2 carries `:authority` instead.
fn host_ok<B>(req: &Request<B>) -> bool {
    if req.version() != Version::HTTP_11 {
        return true;
    }
    let mut hosts = req.headers().get_all(header::HOST).iter();
    let (Some(host), None) = (hosts.next(), hosts.next()) else {
        return false;
    };
    let host = host.as_bytes();
    host.is_empty()
        || (!host.contains(&b'@')
            && std::str::from_utf8(host)
                .is_ok_and(|h| h.parse::<hyper::http::uri::Authority>().is_ok()))
}

async fn respond<B>(
    req: &Request<B>,
    shared: &Shared,
    budget: &ConnectionBudget,
) -> Response<ResponseBody> {
    let config = &shared.config;
    if !host_ok(req) {
        return status(
            StatusCode::BAD_REQUEST,
            "an HTTP/1.1 request needs exactly one valid Host header\n",
        );
    }
    if req.method() == Method::OPTIONS && config.cors.is_some() {
        let mut r = Response::new(empty());
        *r.status_mut() = StatusCode::NO_CONTENT;
        let h = r.headers_mut();
        h.insert(
            header::ACCESS_CONTROL_ALLOW_METHODS,
            HeaderValue::from_static("GET, HEAD, OPTIONS"),
        );
        h.insert(
            header::ACCESS_CONTROL_ALLOW_HEADERS,
            HeaderValue::from_static(
                "Range, If-Range, Authorization, If-None-Match, If-Match, If-Unmodified-Since, \
                 If-Modified-Since, \
                 Content-Type",
            ),
        );
        h.insert(
            header::ACCESS_CONTROL_MAX_AGE,
            HeaderValue::from_static("3600"),
        );
        return r;
    }
    if let Some(token) = &config.token {
        let given = req
            .headers()
            .get(header::AUTHORIZATION)
            .map(|v| v.as_bytes());
        if !bearer_matches(given, token) {
            let mut r = status(StatusCode::UNAUTHORIZED, "a bearer token is required\n");
            r.headers_mut().insert(
                header::WWW_AUTHENTICATE,
                HeaderValue::from_static("Bearer realm=\"strata\""),
            );
            return r;
        }
    }
    let head = req.method() == Method::HEAD;
    if req.method() != Method::GET && !head {
        let mut r = status(
            StatusCode::METHOD_NOT_ALLOWED,
            "read-only: GET and HEAD only\n",
        );
        // OPTIONS is answered only where CORS is on (a preflight).
        let allow = if config.cors.is_some() {
            "GET, HEAD, OPTIONS"
        } else {
            "GET, HEAD"
        };
        r.headers_mut()
            .insert(header::ALLOW, HeaderValue::from_static(allow));
        return r;
    }
    let mut segs = match segments(req.uri().path()) {
        Ok(s) => s,
        Err(Refusal::BadPath(_)) => return status(StatusCode::BAD_REQUEST, "bad path\n"),
        Err(Refusal::NotFound) => return not_found(),
    };
    if segs.is_empty() {
        return listing(shared, head).await;
    }
    // A dataset's files lie directly in its directory: `/DATASET/FILE`, nothing deeper.
    if segs.len() != 2 {
        return not_found();
    }
    let (Some(name), Some(dataset)) = (segs.pop(), segs.pop()) else {
        return not_found();
    };
    let conditions = Conditions::of(req.headers(), head, config.token.is_some());
    let catalog = shared.catalog.clone();
    match serve_file::serve(catalog, &shared.pool, budget, dataset, name, conditions).await {
        Ok(r) => r,
        Err(Failure::NotFound) => not_found(),
        Err(Failure::Io) => status(StatusCode::INTERNAL_SERVER_ERROR, "cannot read\n"),
    }
}

async fn listing(shared: &Shared, head: bool) -> Response<ResponseBody> {
    let catalog = shared.catalog.clone();
    let Ok(Some(list)) = shared.pool.run(move || catalog.list()).await else {
        return status(StatusCode::INTERNAL_SERVER_ERROR, "cannot list\n");
    };
    let json = serde_json::to_vec_pretty(&list).unwrap_or_default();
    let len = json.len();
    let mut r = Response::new(if head { empty() } else { full(json) });
    let h = r.headers_mut();
    h.insert(
        header::CONTENT_TYPE,
        HeaderValue::from_static("application/json"),
    );
    h.insert(header::CONTENT_LENGTH, HeaderValue::from(len));
    h.insert(header::CACHE_CONTROL, HeaderValue::from_static("no-cache"));
    r
}
