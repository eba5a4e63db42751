//! The access log: one line per answered request (parser rejections included) on stderr, as
//! text or JSON. Lines go through a bounded queue to a thread of their own, which writes them in
//! batches, so a request never waits on stderr; if stderr stops draining, lines are dropped and
//! counted rather than stalling the server.

use serde::Serialize;
use std::io::Write;
use std::net::SocketAddr;
use std::sync::atomic::{AtomicU64, Ordering};
use std::sync::mpsc::{Receiver, SyncSender, TrySendError, sync_channel};
use std::time::{Duration, SystemTime, UNIX_EPOCH};

#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum LogFormat {
    Text,
    Json,
}

/// One answered request.
#[derive(Debug, Serialize)]
pub struct Entry {
    /// Seconds since the Unix epoch.
    pub time: f64,
    pub client: SocketAddr,
    /// `-` for a request the parser rejected.
    pub method: String,
    pub path: String,
    pub version: &'static str,
    pub status: u16,
    /// Body bytes sent.
    pub bytes: u64,
    pub ms: f64,
    /// Why the answer's body was cut short (a file that shrank or failed while it was read);
    /// none where it went out whole or the client left.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub error: Option<String>,
}

impl Entry {
    pub fn new(client: SocketAddr, status: u16, bytes: u64, elapsed: Duration) -> Entry {
        Entry {
            time: SystemTime::now()
                .duration_since(UNIX_EPOCH)
                .map_or(0.0, |d| d.as_secs_f64()),
            client,
            method: "-".into(),
            path: "-".into(),
            version: "-",
            status,
            bytes,
            ms: elapsed.as_secs_f64() * 1e3,
            error: None,
        }
    }

    fn line(&self, format: LogFormat) -> String {
        match format {
            // A quote or a backslash in the path is escaped, so that the quoted request ends
            // where it seems to, and any character but printable ASCII (an HTTP/2 path may
            // carry raw UTF-8: a right-to-left mark turns the line around on a terminal).
            LogFormat::Text => format!(
                "{} \"{} {} {}\" {} {} {:.1}ms{}\n",
                self.client,
                self.method,
                escaped(&self.path),
                self.version,
                self.status,
                self.bytes,
                self.ms,
                self.error
                    .as_ref()
                    .map_or(String::new(), |e| format!(" cut short: {e}"))
            ),
            LogFormat::Json => {
                let mut s = serde_json::to_string(self).unwrap_or_default();
                s.push('\n');
                s
            }
        }
    }
}

const QUEUE: usize = 16 * 1024;

#[derive(Debug)]
pub struct AccessLog {
    format: LogFormat,
    queue: SyncSender<String>,
    dropped: AtomicU64,
}

impl AccessLog {
    pub fn start(format: LogFormat) -> std::io::Result<AccessLog> {
        let (queue, lines) = sync_channel(QUEUE);
        std::thread::Builder::new()
            .name("access-log".into())
            .spawn(move || write_lines(lines))?;
        Ok(AccessLog {
            format,
            queue,
            dropped: AtomicU64::new(0),
        })
    }

    pub fn log(&self, entry: &Entry) {
        match self.queue.try_send(entry.line(self.format)) {
            Ok(()) => {}
            Err(TrySendError::Full(_)) => {
                let n = self.dropped.fetch_add(1, Ordering::Relaxed) + 1;
                if n.is_power_of_two() {
                    let _ = self.queue.try_send(format!(
                        "access log: stderr is not keeping up, {n} lines dropped so far\n"
                    ));
                }
            }
            Err(TrySendError::Disconnected(_)) => {}
        }
    }
}

/// `path` with `"` and `\` escaped by a backslash, and characters other than printable ASCII
/// as `\u{..}`.
fn escaped(path: &str) -> String {
    let mut out = String::with_capacity(path.len());
    for c in path.chars() {
        match c {
            '"' | '\\' => {
                out.push('\\');
                out.push(c);
            }
            ' '..='~' => out.push(c),
            _ => out.push_str(&format!("\\u{{{:x}}}", c as u32)),
        }
    }
    out
}

fn write_lines(lines: Receiver<String>) {
    let mut err = std::io::BufWriter::with_capacity(64 * 1024, std::io::stderr());
    while let Ok(first) = lines.recv() {
        let _ = err.write_all(first.as_bytes());
        // Whatever queued meanwhile goes out in the same write.
        while let Ok(more) = lines.try_recv() {
            let _ = err.write_all(more.as_bytes());
        }
        let _ = err.flush();
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_quote_in_the_path_is_escaped_in_text() {
        let mut e = Entry::new("127.0.0.1:9".parse().expect("addr"), 404, 0, Duration::ZERO);
        e.method = "GET".into();
        e.path = "/x\" HTTP/1.1\\".into();
        let line = e.line(LogFormat::Text);
        assert!(
            line.starts_with("127.0.0.1:9 \"GET /x\\\" HTTP/1.1\\\\ -\" 404 0"),
            "{line}"
        );
        e.path = "/a\u{202e}b\u{7f}é".into();
        let line = e.line(LogFormat::Text);
        assert!(line.contains("/a\\u{202e}b\\u{7f}\\u{e9} -"), "{line}");
    }
}
