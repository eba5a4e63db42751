//! Response bodies: in memory (a range read in one go), or a large range streamed in chunks, each
//! read on the blocking pool.

use crate::blocking::BlockingPool;
use crate::budget::{ConnectionBudget, LARGEST_READ, charged};
use bytes::Bytes;
use http_body_util::{BodyExt, Full, combinators::UnsyncBoxBody};
use hyper::body::{Body, Frame, SizeHint};
use std::fs::File;
use std::future::Future;
use std::pin::Pin;
use std::sync::Arc;
use std::task::{Context, Poll};

pub type ResponseBody = UnsyncBoxBody<Bytes, std::io::Error>;

/// Chunk size when streaming a range too large to read in one go.
const CHUNK: u64 = 256 << 10;
const _: () = assert!(CHUNK as usize <= LARGEST_READ);

pub fn full(bytes: impl Into<Bytes>) -> ResponseBody {
    Full::new(bytes.into())
        .map_err(|never| match never {})
        .boxed_unsync()
}

pub fn empty() -> ResponseBody {
    full(Bytes::new())
}

type Read = Pin<Box<dyn Future<Output = std::io::Result<Bytes>> + Send>>;

/// Bytes `pos..end` of a file.
pub struct FileStream {
    file: Arc<File>,
    pool: BlockingPool,
    budget: ConnectionBudget,
    pos: u64,
    end: u64,
    pending: Option<Read>,
}

impl FileStream {
    pub fn boxed_body(
        file: File,
        pool: BlockingPool,
        budget: ConnectionBudget,
        start: u64,
        end: u64,
    ) -> ResponseBody {
        FileStream {
            file: Arc::new(file),
            pool,
            budget,
            pos: start,
            end,
            pending: None,
        }
        .boxed_unsync()
    }

    fn next_read(&self) -> Read {
        let (file, pool, pos) = (self.file.clone(), self.pool.clone(), self.pos);
        let budget = self.budget.clone();
        let len = (self.end - pos).min(CHUNK) as usize;
        Box::pin(async move {
            let held = budget
                .take(len)
                .await
                .ok_or_else(|| std::io::Error::other("the server is stopping"))?;
            let bytes = pool
                .run(move || crate::files::read_range(&file, pos, len))
                .await
                .map_err(std::io::Error::other)??;
            Ok(charged(bytes, held))
        })
    }
}

impl Body for FileStream {
    type Data = Bytes;
    type Error = std::io::Error;

    fn poll_frame(
        self: Pin<&mut Self>,
        cx: &mut Context<'_>,
    ) -> Poll<Option<Result<Frame<Bytes>, std::io::Error>>> {
        let this = self.get_mut();
        if this.pos >= this.end {
            return Poll::Ready(None);
        }
        let read = match &mut this.pending {
            Some(r) => r,
            None => this.pending.insert(this.next_read()),
        };
        let result = std::task::ready!(read.as_mut().poll(cx));
        this.pending = None;
        Poll::Ready(Some(result.map(|bytes| {
            this.pos += bytes.len() as u64;
            Frame::data(bytes)
        })))
    }

    fn is_end_stream(&self) -> bool {
        self.pos >= self.end
    }

    fn size_hint(&self) -> SizeHint {
        SizeHint::with_exact(self.end.saturating_sub(self.pos))
    }
}
