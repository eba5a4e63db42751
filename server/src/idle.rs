//! A connection that fails once it has made no progress, in either direction, for a while:
//! a client that stops reading or writing cannot hold a connection. Its opening (until HTTP/1
//! and HTTP/2 are told apart) has a deadline of its own, from when the connection opens:
//! hyper's header timeout starts only after that, and a client sending nothing, or HTTP/2's
//! preface a byte at a time, held a connection for the idle limit, and again with each byte.
//! On HTTP/2, progress is an answer going out (`h2_frames`), not the frames that only keep a
//! connection open; a request counts only while no answer has moved since the last one that
//! counted, so that a client holding its answers back cannot hold the connection by asking.

use crate::h2_frames::{FrameScan, Side};
use std::pin::Pin;
use std::task::{Context, Poll};
use std::time::Duration;
use tokio::io::{AsyncRead, AsyncWrite, ReadBuf};
use tokio::time::{Instant, Sleep};

/// What an HTTP/2 connection opens with (prior knowledge); the first byte that differs says
/// HTTP/1, whose requests hyper's header timeout then covers.
const PREFACE: &[u8; 24] = b"PRI * HTTP/2.0\r\n\r\nSM\r\n\r\n";

pub struct IdleTimeout<S> {
    inner: S,
    limit: Duration,
    timer: Pin<Box<Sleep>>,
    /// Bytes of the preface still to read before the opening is over (0: over); a byte that
    /// differs from the preface, or the first write (an answer), ends it too.
    opening: usize,
    /// Once the whole preface came: the frames read and written.
    http2: Option<Http2>,
}

/// What an HTTP/2 connection's progress is read from.
struct Http2 {
    client: FrameScan,
    server: FrameScan,
    /// A request counted as progress, and no answer has moved since.
    asked: bool,
}

impl<S> IdleTimeout<S> {
    /// `opening`: the time the client has to show HTTP/1 (a byte other than the preface's) or
    /// send HTTP/2's whole preface; `limit`: the time without progress after that.
    pub fn new(inner: S, limit: Duration, opening: Duration) -> Self {
        IdleTimeout {
            inner,
            limit,
            timer: Box::pin(tokio::time::sleep(opening.min(limit))),
            opening: PREFACE.len(),
            http2: None,
        }
    }

    /// Bytes that came in.
    fn came_in(&mut self, mut bytes: &[u8]) {
        if self.opening > 0 {
            let at = PREFACE.len() - self.opening;
            let n = bytes.len().min(self.opening);
            let preface = bytes[..n] == PREFACE[at..at + n];
            self.opening = if preface { self.opening - n } else { 0 };
            if self.opening > 0 {
                // Still opening: the deadline stands.
                return;
            }
            if preface {
                self.http2 = Some(Http2 {
                    client: FrameScan::new(Side::Client),
                    server: FrameScan::new(Side::Server),
                    asked: false,
                });
                bytes = &bytes[n..];
                // The preface itself is progress: the opening is over.
                self.moved();
            }
        }
        if let Some(h) = &mut self.http2 {
            if !h.client.feed(bytes) || h.asked {
                return;
            }
            h.asked = true;
        }
        self.moved();
    }

    /// Bytes that went out: the first `written` of those in `bufs`.
    fn wrote<'b>(&mut self, bufs: impl Iterator<Item = &'b [u8]>, written: usize) {
        self.opening = 0;
        if let Some(h) = &mut self.http2 {
            let mut left = written;
            let mut moving = false;
            for b in bufs {
                let n = left.min(b.len());
                moving |= h.server.feed(&b[..n]);
                left -= n;
            }
            if !moving {
                return;
            }
            h.asked = false;
        }
        self.moved();
    }

    fn moved(&mut self) {
        self.timer.as_mut().reset(Instant::now() + self.limit);
    }

    fn check(&mut self, cx: &mut Context<'_>) -> std::io::Result<()> {
        match self.timer.as_mut().poll(cx) {
            Poll::Ready(()) => Err(std::io::Error::new(
                std::io::ErrorKind::TimedOut,
                "connection idle for too long",
            )),
            Poll::Pending => Ok(()),
        }
    }
}

impl<S: AsyncRead + Unpin> AsyncRead for IdleTimeout<S> {
    fn poll_read(
        self: Pin<&mut Self>,
        cx: &mut Context<'_>,
        buf: &mut ReadBuf<'_>,
    ) -> Poll<std::io::Result<()>> {
        let this = self.get_mut();
        let before = buf.filled().len();
        match Pin::new(&mut this.inner).poll_read(cx, buf) {
            Poll::Ready(r) => {
                // End of input is no progress either: it is the client leaving.
                if buf.filled().len() > before {
                    this.came_in(&buf.filled()[before..]);
                }
                Poll::Ready(r)
            }
            Poll::Pending => match this.check(cx) {
                Ok(()) => Poll::Pending,
                Err(e) => Poll::Ready(Err(e)),
            },
        }
    }
}

impl<S: AsyncWrite + Unpin> AsyncWrite for IdleTimeout<S> {
    fn poll_write(
        self: Pin<&mut Self>,
        cx: &mut Context<'_>,
        buf: &[u8],
    ) -> Poll<std::io::Result<usize>> {
        let this = self.get_mut();
        match Pin::new(&mut this.inner).poll_write(cx, buf) {
            Poll::Ready(r) => {
                this.wrote(std::iter::once(buf), *r.as_ref().unwrap_or(&0));
                Poll::Ready(r)
            }
            Poll::Pending => match this.check(cx) {
                Ok(()) => Poll::Pending,
                Err(e) => Poll::Ready(Err(e)),
            },
        }
    }

    /// Vectored writes reach the socket: without them hyper copies each body into its header
    /// buffer before writing.
    fn poll_write_vectored(
        self: Pin<&mut Self>,
        cx: &mut Context<'_>,
        bufs: &[std::io::IoSlice<'_>],
    ) -> Poll<std::io::Result<usize>> {
        let this = self.get_mut();
        match Pin::new(&mut this.inner).poll_write_vectored(cx, bufs) {
            Poll::Ready(r) => {
                this.wrote(bufs.iter().map(|b| &**b), *r.as_ref().unwrap_or(&0));
                Poll::Ready(r)
            }
            Poll::Pending => match this.check(cx) {
                Ok(()) => Poll::Pending,
                Err(e) => Poll::Ready(Err(e)),
            },
        }
    }

    fn is_write_vectored(&self) -> bool {
        self.inner.is_write_vectored()
    }

    fn poll_flush(self: Pin<&mut Self>, cx: &mut Context<'_>) -> Poll<std::io::Result<()>> {
        Pin::new(&mut self.get_mut().inner).poll_flush(cx)
    }

    fn poll_shutdown(self: Pin<&mut Self>, cx: &mut Context<'_>) -> Poll<std::io::Result<()>> {
        Pin::new(&mut self.get_mut().inner).poll_shutdown(cx)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use tokio::io::{AsyncReadExt, AsyncWriteExt};

    /// Reads what is there within `wait`; `Err` if the connection failed.
    async fn read_within(
        io: &mut IdleTimeout<tokio::io::DuplexStream>,
        wait: Duration,
    ) -> std::io::Result<usize> {
        let mut buf = [0u8; 64];
        match tokio::time::timeout(wait, io.read(&mut buf)).await {
            Ok(r) => r,
            Err(_) => Ok(0),
        }
    }

    #[tokio::test]
    async fn the_opening_ends_at_the_first_byte_that_is_not_http_2s() {
        let opening = Duration::from_millis(100);
        // A whole HTTP/1.0 request shorter than the preface: HTTP/1 from its first byte, so
        // only the idle limit applies after (it was cut at the opening deadline while its
        // answer was being made).
        let (mut client, server) = tokio::io::duplex(1024);
        let mut io = IdleTimeout::new(server, Duration::from_secs(10), opening);
        client
            .write_all(b"GET / HTTP/1.0\r\n\r\n")
            .await
            .expect("write");
        assert_eq!(read_within(&mut io, opening).await.expect("read"), 18);
        tokio::time::sleep(opening * 2).await;
        assert!(
            read_within(&mut io, opening).await.is_ok(),
            "cut after the opening"
        );
        // The preface's first bytes, then nothing: cut at the opening deadline.
        let (mut client, server) = tokio::io::duplex(1024);
        let mut io = IdleTimeout::new(server, Duration::from_secs(10), opening);
        client.write_all(b"PRI * HTTP").await.expect("write");
        assert_eq!(read_within(&mut io, opening).await.expect("read"), 10);
        let cut = read_within(&mut io, opening * 3).await;
        assert!(cut.is_err(), "{cut:?}");
    }
}
