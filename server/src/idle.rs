//! A connection that fails once it has made no progress, in either direction, for a while:
//! a client that stops reading or writing cannot hold a connection. Its opening (until HTTP/1
//! and HTTP/2 are told apart) has a deadline of its own: hyper's header timeout starts only
//! after that, and a client sending nothing, or HTTP/2's preface a byte at a time, held a
//! connection for the idle limit, and again with each byte.

use std::pin::Pin;
use std::task::{Context, Poll};
use std::time::Duration;
use tokio::io::{AsyncRead, AsyncWrite, ReadBuf};
use tokio::time::{Instant, Sleep};

/// Bytes that tell HTTP/1 from HTTP/2: the length of HTTP/2's connection preface.
const OPENING_BYTES: usize = 24;

pub struct IdleTimeout<S> {
    inner: S,
    limit: Duration,
    timer: Pin<Box<Sleep>>,
    /// Bytes still to read before the opening is over (0: over); the first write (an answer)
    /// ends it too.
    opening: usize,
}

impl<S> IdleTimeout<S> {
    /// `opening`: the time the client has to send its first `OPENING_BYTES` bytes (or a whole
    /// shorter request); `limit`: the time without progress after that.
    pub fn new(inner: S, limit: Duration, opening: Duration) -> Self {
        IdleTimeout {
            inner,
            limit,
            timer: Box::pin(tokio::time::sleep(opening.min(limit))),
            opening: OPENING_BYTES,
        }
    }

    /// `read` bytes came in, or (`None`) some went out.
    fn progress(&mut self, read: Option<usize>) {
        if self.opening > 0 {
            match read {
                Some(n) if n < self.opening => {
                    // Still opening: the deadline stands.
                    self.opening -= n;
                    return;
                }
                _ => self.opening = 0,
            }
        }
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
                let read = buf.filled().len() - before;
                // End of input is no progress either: it is the client leaving.
                if read > 0 {
                    this.progress(Some(read));
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
                this.progress(None);
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
                this.progress(None);
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
