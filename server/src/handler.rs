//! One request: CORS, token, method, path, then the listing or a file (whole, one range, or
//! not modified).

use crate::body::{FileBody, ResponseBody, empty, full};
use crate::listing;
use crate::path::{Refusal, resolve, segments};
use crate::range::{RangeRequest, parse_range};
use crate::server::ServerConfig;
use hyper::header::{self, HeaderValue};
use hyper::{Method, Request, Response, StatusCode};
use std::io::Write;
use std::net::SocketAddr;
use std::sync::Arc;
use std::time::{Instant, UNIX_EPOCH};
use tokio::io::AsyncSeekExt;

pub async fn handle<B>(
    req: Request<B>,
    peer: SocketAddr,
    config: Arc<ServerConfig>,
) -> Result<Response<ResponseBody>, std::convert::Infallible> {
    let start = Instant::now();
    let method = req.method().clone();
    let path = req.uri().path().to_string();
    let mut resp = match tokio::time::timeout(config.request_timeout, respond(&req, &config)).await
    {
        Ok(r) => r,
        Err(_) => status(StatusCode::SERVICE_UNAVAILABLE, "request timed out\n"),
    };
    if let Some(origin) = &config.cors {
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
    if config.access_log {
        let bytes = resp
            .headers()
            .get(header::CONTENT_LENGTH)
            .and_then(|v| v.to_str().ok())
            .unwrap_or("0")
            .to_string();
        let _ = writeln!(
            std::io::stderr(),
            "{peer} \"{method} {path}\" {} {bytes} {:.1}ms",
            resp.status().as_u16(),
            start.elapsed().as_secs_f64() * 1e3
        );
    }
    Ok(resp)
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

fn authorized<B>(req: &Request<B>, token: &str) -> bool {
    let Some(given) = req
        .headers()
        .get(header::AUTHORIZATION)
        .and_then(|v| v.to_str().ok())
        .and_then(|v| v.strip_prefix("Bearer "))
    else {
        return false;
    };
    // Constant time in the token's length: no early exit on the first differing byte.
    let (a, b) = (given.trim().as_bytes(), token.as_bytes());
    a.len() == b.len() && a.iter().zip(b).fold(0u8, |acc, (x, y)| acc | (x ^ y)) == 0
}

async fn respond<B>(req: &Request<B>, config: &ServerConfig) -> Response<ResponseBody> {
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
            HeaderValue::from_static("Range, Authorization, If-None-Match"),
        );
        h.insert(
            header::ACCESS_CONTROL_MAX_AGE,
            HeaderValue::from_static("3600"),
        );
        return r;
    }
    if let Some(token) = &config.token
        && !authorized(req, token)
    {
        let mut r = status(StatusCode::UNAUTHORIZED, "a bearer token is required\n");
        r.headers_mut().insert(
            header::WWW_AUTHENTICATE,
            HeaderValue::from_static("Bearer realm=\"strata\""),
        );
        return r;
    }
    let head = req.method() == Method::HEAD;
    if req.method() != Method::GET && !head {
        let mut r = status(
            StatusCode::METHOD_NOT_ALLOWED,
            "read-only: GET and HEAD only\n",
        );
        r.headers_mut().insert(
            header::ALLOW,
            HeaderValue::from_static("GET, HEAD, OPTIONS"),
        );
        return r;
    }
    let segs = match segments(req.uri().path()) {
        Ok(s) => s,
        Err(Refusal::BadPath(_)) => return status(StatusCode::BAD_REQUEST, "bad path\n"),
        Err(_) => return status(StatusCode::NOT_FOUND, "not found\n"),
    };
    if segs.is_empty() {
        let json = serde_json::to_vec_pretty(&listing::list(&config.root)).unwrap_or_default();
        let len = json.len();
        let mut r = Response::new(if head { empty() } else { full(json) });
        let h = r.headers_mut();
        h.insert(
            header::CONTENT_TYPE,
            HeaderValue::from_static("application/json"),
        );
        h.insert(header::CONTENT_LENGTH, HeaderValue::from(len));
        h.insert(header::CACHE_CONTROL, HeaderValue::from_static("no-cache"));
        return r;
    }
    let root = config.root.clone();
    let file = match tokio::task::spawn_blocking(move || resolve(&root, &segs)).await {
        Ok(Ok(p)) => p,
        Ok(Err(Refusal::Outside)) => {
            return status(StatusCode::FORBIDDEN, "outside the served directory\n");
        }
        Ok(Err(Refusal::BadPath(_))) => return status(StatusCode::BAD_REQUEST, "bad path\n"),
        _ => return status(StatusCode::NOT_FOUND, "not found\n"),
    };
    serve_file(req, &file, head).await
}

async fn serve_file<B>(
    req: &Request<B>,
    path: &std::path::Path,
    head: bool,
) -> Response<ResponseBody> {
    let Ok(mut f) = tokio::fs::File::open(path).await else {
        return status(StatusCode::NOT_FOUND, "not found\n");
    };
    let Ok(meta) = f.metadata().await else {
        return status(StatusCode::NOT_FOUND, "not found\n");
    };
    if !meta.is_file() {
        return status(StatusCode::NOT_FOUND, "not found\n");
    }
    let len = meta.len();
    let modified = meta.modified().ok();
    let mtime_ns = modified
        .and_then(|m| m.duration_since(UNIX_EPOCH).ok())
        .map_or(0, |d| d.as_nanos());
    let etag = format!("\"{len:x}-{mtime_ns:x}\"");
    let mut builder = Response::builder()
        .header(header::ACCEPT_RANGES, "bytes")
        .header(header::ETAG, &etag)
        .header(header::CACHE_CONTROL, "public, max-age=60")
        .header(header::CONTENT_TYPE, content_type(path));
    if let Some(m) = modified {
        builder = builder.header(header::LAST_MODIFIED, httpdate::fmt_http_date(m));
    }
    let if_none_match = req
        .headers()
        .get(header::IF_NONE_MATCH)
        .and_then(|v| v.to_str().ok());
    if if_none_match.is_some_and(|v| v.split(',').any(|t| t.trim() == etag || t.trim() == "*")) {
        return builder
            .status(StatusCode::NOT_MODIFIED)
            .body(empty())
            .unwrap_or_else(|_| status(StatusCode::INTERNAL_SERVER_ERROR, "response\n"));
    }
    // A range applies only while the representation is the one the client saw.
    let if_range_ok = req
        .headers()
        .get(header::IF_RANGE)
        .and_then(|v| v.to_str().ok())
        .is_none_or(|v| v.trim() == etag);
    let range_header = req
        .headers()
        .get(header::RANGE)
        .and_then(|v| v.to_str().ok())
        .filter(|_| if_range_ok);
    let (code, start, end) = match parse_range(range_header, len) {
        RangeRequest::Whole => (StatusCode::OK, 0, len),
        RangeRequest::Part { start, end } => {
            builder = builder.header(
                header::CONTENT_RANGE,
                format!("bytes {start}-{}/{len}", end - 1),
            );
            (StatusCode::PARTIAL_CONTENT, start, end)
        }
        RangeRequest::Unsatisfiable => {
            return builder
                .status(StatusCode::RANGE_NOT_SATISFIABLE)
                .header(header::CONTENT_RANGE, format!("bytes */{len}"))
                .header(header::CONTENT_LENGTH, 0)
                .body(empty())
                .unwrap_or_else(|_| status(StatusCode::INTERNAL_SERVER_ERROR, "response\n"));
        }
    };
    let count = end - start;
    builder = builder.status(code).header(header::CONTENT_LENGTH, count);
    let body = if head || count == 0 {
        empty()
    } else {
        if start > 0 && f.seek(std::io::SeekFrom::Start(start)).await.is_err() {
            return status(StatusCode::INTERNAL_SERVER_ERROR, "cannot seek\n");
        }
        FileBody::boxed_body(f, count)
    };
    builder
        .body(body)
        .unwrap_or_else(|_| status(StatusCode::INTERNAL_SERVER_ERROR, "response\n"))
}

fn content_type(path: &std::path::Path) -> &'static str {
    match path.extension().and_then(|e| e.to_str()) {
        Some("json") => "application/json",
        Some("png") => "image/png",
        _ => "application/octet-stream",
    }
}
