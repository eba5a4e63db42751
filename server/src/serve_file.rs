//! One dataset file: whole, one range, or not modified. Everything that touches the file system
//! (finding the file through the catalog, opening, `fstat`, reading) happens in one job on the
//! blocking pool, so a request costs one hand-off.

use crate::blocking::BlockingPool;
use crate::body::{FileStream, ResponseBody, empty, full};
use crate::budget::{ConnectionBudget, LARGEST_READ, charged};
use crate::catalog::Catalog;
use crate::range::{RangeRequest, parse_range};
use bytes::Bytes;
use hyper::header::{self, HeaderMap};
use hyper::{Response, StatusCode};
use std::fs::File;
use std::sync::Arc;
use std::time::UNIX_EPOCH;

/// Ranges up to this size are read in one `pread` into one buffer; larger ones stream, a chunk
/// at a time as the client takes them. Small, since an answer's buffer lives until the client
/// reads it (4 MiB let 64 stalled HTTP/2 streams hold 265 MiB).
const READ_WHOLE_MAX: u64 = 256 << 10;
const _: () = assert!(READ_WHOLE_MAX as usize <= LARGEST_READ);

/// The request headers the answer depends on, owned so they can travel to the pool.
pub struct Conditions {
    range: Option<String>,
    if_range: Option<String>,
    if_none_match: Option<String>,
    if_match: Option<String>,
    if_unmodified_since: Option<String>,
    if_modified_since: Option<String>,
    head: bool,
    /// Answers only for those who hold the token: no shared cache may keep them.
    private: bool,
}

impl Conditions {
    pub fn of(headers: &HeaderMap, head: bool, private: bool) -> Conditions {
        // A field given once; twice, it is no valid value (RFC 9110, 5.3), and is ignored.
        let get = |name| {
            let mut lines = headers.get_all(name).iter();
            match (lines.next(), lines.next()) {
                (Some(v), None) => v.to_str().ok().map(str::to_string),
                _ => None,
            }
        };
        // A list field (RFC 9110, 5.3): its lines are one list, joined by commas.
        let list = |name| {
            let lines: Option<Vec<&str>> = headers
                .get_all(name)
                .iter()
                .map(|v| v.to_str().ok())
                .collect();
            lines.filter(|l| !l.is_empty()).map(|l| l.join(", "))
        };
        Conditions {
            // RFC 9110, 14.2: Range applies to GET alone; HEAD answers as for the whole.
            range: get(header::RANGE).filter(|_| !head),
            // Present but no single valid value: a validator nothing matches, so that the
            // Range is not applied (taken as absent, it applied to whatever the file is now).
            if_range: headers
                .contains_key(header::IF_RANGE)
                .then(|| get(header::IF_RANGE).unwrap_or_default()),
            if_none_match: list(header::IF_NONE_MATCH),
            if_match: list(header::IF_MATCH),
            if_unmodified_since: get(header::IF_UNMODIFIED_SINCE),
            if_modified_since: get(header::IF_MODIFIED_SINCE),
            head,
            private,
        }
    }
}

enum Outcome {
    NotModified,
    /// If-Match or If-Unmodified-Since failed: 412.
    PreconditionFailed,
    Unsatisfiable,
    /// Bytes `start..end`: already read, or left to stream from `file`.
    Body {
        status: StatusCode,
        start: u64,
        end: u64,
        read: Option<Bytes>,
        file: Option<File>,
    },
}

struct Prepared {
    content_type: &'static str,
    len: u64,
    etag: String,
    /// Last-Modified, as an HTTP date.
    last_modified: Option<String>,
    outcome: Outcome,
}

pub enum Failure {
    /// Not a file a dataset serves, whether or not it exists.
    NotFound,
    /// Reading failed (the file shrank, a disk error) or the pool failed: a 500.
    Io,
}

/// Whole seconds since the epoch: HTTP dates hold no finer time.
fn seconds(t: std::time::SystemTime) -> Option<u64> {
    t.duration_since(UNIX_EPOCH).ok().map(|d| d.as_secs())
}

/// The first second an HTTP date cannot state (year 10000); `httpdate` panics from there on,
/// and before 1970.
const PAST_HTTP_DATES: u64 = 253_402_300_800;

/// The file's modification time, where an HTTP date can state it as a strong validator: a
/// second past, so that the file cannot change again within the second its date names (RFC
/// 9110, 8.8.2.2; else a file written twice within a second and resumed with If-Range by date
/// mixed two versions). A file modified within the last second, or dated in the future, before
/// 1970 or after 9999 (`touch -d @-1`), is served with no Last-Modified and no date validators.
fn http_modified(meta: &std::fs::Metadata) -> Option<std::time::SystemTime> {
    let now = seconds(std::time::SystemTime::now())?;
    meta.modified()
        .ok()
        .filter(|&m| seconds(m).is_some_and(|s| s < now && s < PAST_HTTP_DATES))
}

/// The entity tag of a file: its size, modification time to the nanosecond and inode, so that
/// a file replaced by one of the same size keeping the old time (`cp -p`, `rsync -t`, then a
/// rename) gets a new one.
fn entity_tag(meta: &std::fs::Metadata) -> String {
    use std::os::unix::fs::MetadataExt;
    let mtime_ns = i128::from(meta.mtime()) * 1_000_000_000 + i128::from(meta.mtime_nsec());
    format!("\"{:x}-{mtime_ns:x}-{:x}\"", meta.len(), meta.ino())
}

/// A range up to `READ_WHOLE_MAX` is read whole where `budget` has room for it now, else
/// streamed (a stream waits for room).
fn prepare(
    catalog: &Catalog,
    dataset: &str,
    name: &str,
    c: Conditions,
    budget: &ConnectionBudget,
) -> Result<Prepared, Failure> {
    let path = catalog.file(dataset, name).ok_or(Failure::NotFound)?;
    let (file, meta) = crate::files::open_regular(&path).ok_or(Failure::NotFound)?;
    let len = meta.len();
    // The file's time for the conditions; its date, for Last-Modified, only where strong
    // (If-Unmodified-Since still compares with a file changed this second).
    let modified = meta.modified().ok();
    let last_modified = http_modified(&meta).map(httpdate::fmt_http_date);
    let etag = entity_tag(&meta);
    let content_type = match path.extension().and_then(|e| e.to_str()) {
        Some("json") => "application/json",
        _ => "application/octet-stream",
    };
    // Weak comparison (RFC 9110, 13.1.2): a `W/` prefix does not matter.
    let matches_etag = |v: &str| {
        v.split(',')
            .map(str::trim)
            .any(|t| t == "*" || t.strip_prefix("W/").unwrap_or(t) == etag)
    };
    // RFC 9110, 13.2.2: If-Match (strong comparison), else If-Unmodified-Since, then
    // If-None-Match, else If-Modified-Since, then If-Range.
    let strong = |v: &str| v.split(',').map(str::trim).any(|t| t == "*" || t == etag);
    let precondition_failed = match (&c.if_match, &c.if_unmodified_since) {
        (Some(m), _) => !strong(m),
        (None, Some(since)) => match (httpdate::parse_http_date(since.trim()), modified) {
            (Ok(since), Some(m)) => seconds(m).zip(seconds(since)).is_some_and(|(m, s)| m > s),
            // An invalid date is ignored.
            _ => false,
        },
        (None, None) => false,
    };
    // If-None-Match, else If-Modified-Since: not modified since the date the client holds
    // (an invalid date is ignored).
    let not_modified = match (&c.if_none_match, &c.if_modified_since) {
        (Some(tags), _) => matches_etag(tags),
        (None, Some(since)) => match (httpdate::parse_http_date(since.trim()), modified) {
            (Ok(since), Some(m)) => seconds(m).zip(seconds(since)).is_some_and(|(m, s)| m <= s),
            _ => false,
        },
        (None, None) => false,
    };
    let outcome = if precondition_failed {
        Outcome::PreconditionFailed
    } else if not_modified {
        Outcome::NotModified
    } else {
        // A range applies only while the representation is the one the client saw: the
        // same ETag, or the same Last-Modified date.
        let if_range_ok = c.if_range.as_deref().is_none_or(|v| {
            let v = v.trim();
            v == etag || last_modified.as_deref() == Some(v)
        });
        let range = c.range.as_deref().filter(|_| if_range_ok);
        let (status, start, end) = match parse_range(range, len) {
            RangeRequest::Whole => (StatusCode::OK, 0, len),
            RangeRequest::Part { start, end } => (StatusCode::PARTIAL_CONTENT, start, end),
            RangeRequest::Unsatisfiable => {
                return Ok(Prepared {
                    content_type,
                    len,
                    etag,
                    last_modified,
                    outcome: Outcome::Unsatisfiable,
                });
            }
        };
        let count = end - start;
        let (read, file) = if c.head || count == 0 {
            (None, None)
        } else if count <= READ_WHOLE_MAX
            && let Some(held) = budget.try_take(count as usize)
        {
            let bytes = crate::files::read_range(&file, start, count as usize);
            (Some(charged(bytes.map_err(|_| Failure::Io)?, held)), None)
        } else {
            (None, Some(file))
        };
        Outcome::Body {
            status,
            start,
            end,
            read,
            file,
        }
    };
    Ok(Prepared {
        content_type,
        len,
        etag,
        last_modified,
        outcome,
    })
}

/// Answers a GET or HEAD of `dataset/name`.
pub async fn serve(
    catalog: Arc<Catalog>,
    pool: &BlockingPool,
    budget: &ConnectionBudget,
    dataset: String,
    name: String,
    c: Conditions,
) -> Result<Response<ResponseBody>, Failure> {
    let cache = if c.private {
        "private, max-age=60"
    } else {
        "public, max-age=60"
    };
    let for_job = budget.clone();
    let job = move || prepare(&catalog, &dataset, &name, c, &for_job);
    let p = pool.run(job).await.map_err(|_| Failure::Io)??;
    let mut builder = Response::builder()
        .header(header::ACCEPT_RANGES, "bytes")
        .header(header::ETAG, &p.etag)
        .header(header::CACHE_CONTROL, cache)
        .header(header::CONTENT_TYPE, p.content_type);
    if let Some(m) = p.last_modified {
        builder = builder.header(header::LAST_MODIFIED, m);
    }
    let len = p.len;
    let response = match p.outcome {
        Outcome::NotModified => builder.status(StatusCode::NOT_MODIFIED).body(empty()),
        // Refusals are no representation: nothing for a cache to keep, no type.
        Outcome::PreconditionFailed => Response::builder()
            .status(StatusCode::PRECONDITION_FAILED)
            .header(header::CACHE_CONTROL, "no-store")
            .header(header::CONTENT_LENGTH, 0)
            .body(empty()),
        Outcome::Unsatisfiable => Response::builder()
            .status(StatusCode::RANGE_NOT_SATISFIABLE)
            .header(header::CACHE_CONTROL, "no-store")
            .header(header::ACCEPT_RANGES, "bytes")
            .header(header::CONTENT_RANGE, format!("bytes */{len}"))
            .header(header::CONTENT_LENGTH, 0)
            .body(empty()),
        Outcome::Body {
            status,
            start,
            end,
            read,
            file,
        } => {
            if status == StatusCode::PARTIAL_CONTENT {
                builder = builder.header(
                    header::CONTENT_RANGE,
                    format!("bytes {start}-{}/{len}", end - 1),
                );
            }
            let body = match (read, file) {
                (Some(bytes), _) => full(bytes),
                (None, Some(file)) => {
                    FileStream::boxed_body(file, pool.clone(), budget.clone(), start, end)
                }
                (None, None) => empty(),
            };
            builder
                .status(status)
                .header(header::CONTENT_LENGTH, end - start)
                .body(body)
        }
    };
    response.map_err(|_| Failure::Io)
}
