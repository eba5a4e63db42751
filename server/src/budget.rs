//! The bytes of answers read into memory and not yet written to a socket, bounded for each
//! connection and for the whole server. A stream's chunk stays in memory until the client's
//! flow-control window lets it out: an HTTP/2 client that opened 32 streams and read nothing
//! held 8.6 MB a connection, 4.3 GB over 500 connections, with a megabyte of requests. Each
//! read now first takes its size from its connection's share, then from the connection's own
//! reserve or else the server's pool; both come back when the bytes are dropped (written out,
//! or the stream gone). A chunk that finds no room waits (until the idle limit closes a
//! connection that makes no progress); a range read whole that finds none is streamed
//! instead. The reserve, never lent to another connection, answers a new client while stalled
//! ones hold the whole pool. At most `--max-connections` x 256 KiB + 128 MiB: 256 MiB at the
//! default 512 connections.

use bytes::Bytes;
use std::sync::Arc;
use tokio::sync::{OwnedSemaphorePermit, Semaphore};

/// The unit budgets count in.
const UNIT: usize = 4 << 10;
/// The most one read of an answer takes (a range read whole, a streamed chunk).
pub const LARGEST_READ: usize = 256 << 10;
/// HTTP/2 streams a connection may have open at once.
pub const H2_STREAMS: u32 = 32;
/// One connection's share: two reads for each of its streams, and one more. A client may read
/// its streams one at a time, as flow control lets it: each stream it does not read yet keeps
/// two chunks (hyper reads the next while the one before waits for the window), and the one it
/// reads must still find room for its next (with room for 8 chunks, a client reading 9
/// downloads in turn waited until the idle limit closed its connection). Only the pool bounds
/// the server as a whole.
pub const PER_CONNECTION: usize = (2 * H2_STREAMS as usize + 1) * LARGEST_READ;
/// Each connection's own, not drawn from the server's pool: one read (less, and a read could
/// wait for room that never comes).
pub const RESERVED: usize = LARGEST_READ;
/// The server's pool, what 8 connections at their share hold.
pub const SERVER: usize = 128 << 20;

fn units(bytes: usize) -> usize {
    bytes.div_ceil(UNIT)
}

/// The server's budget; each connection takes its own from it.
#[derive(Debug, Clone)]
pub struct ServerBudget(Arc<Semaphore>);

impl ServerBudget {
    pub fn new(bytes: usize) -> ServerBudget {
        ServerBudget(Arc::new(Semaphore::new(units(bytes))))
    }

    /// A new connection's budget: `PER_CONNECTION` at most, the first `RESERVED` its own.
    pub fn connection(&self) -> ConnectionBudget {
        ConnectionBudget {
            own: Arc::new(Semaphore::new(units(PER_CONNECTION))),
            reserved: Arc::new(Semaphore::new(units(RESERVED))),
            server: self.0.clone(),
        }
    }
}

/// One connection's budget, drawn from the server's as it is used.
#[derive(Debug, Clone)]
pub struct ConnectionBudget {
    own: Arc<Semaphore>,
    reserved: Arc<Semaphore>,
    server: Arc<Semaphore>,
}

impl ConnectionBudget {
    /// Room for `bytes` (at most one read), once the connection's share and a pool have it.
    /// `None` only where a semaphore was closed, which never happens while the server runs.
    pub async fn take(&self, bytes: usize) -> Option<Held> {
        let n = u32::try_from(units(bytes.min(LARGEST_READ))).ok()?;
        // The connection's share first: a connection waiting for the server's pool holds only
        // its own, and never the pool's while it waits for its own.
        let own = self.own.clone().acquire_many_owned(n).await.ok()?;
        // Whichever has room first, the reserve if both: a stream that waits for the pool
        // goes on as soon as its own last chunk is out.
        let pool = tokio::select! {
            biased;
            p = self.reserved.clone().acquire_many_owned(n) => p,
            p = self.server.clone().acquire_many_owned(n) => p,
        }
        .ok()?;
        Some(Held {
            _own: own,
            _pool: pool,
        })
    }

    /// Room for `bytes` (at most one read) where there is some now.
    pub fn try_take(&self, bytes: usize) -> Option<Held> {
        let n = u32::try_from(units(bytes.min(LARGEST_READ))).ok()?;
        let own = self.own.clone().try_acquire_many_owned(n).ok()?;
        let pool = self
            .reserved
            .clone()
            .try_acquire_many_owned(n)
            .or_else(|_| self.server.clone().try_acquire_many_owned(n))
            .ok()?;
        Some(Held {
            _own: own,
            _pool: pool,
        })
    }
}

/// Room taken from the connection's share and a pool, given back when dropped.
#[derive(Debug)]
pub struct Held {
    _own: OwnedSemaphorePermit,
    /// From the connection's reserve, or the server's pool.
    _pool: OwnedSemaphorePermit,
}

struct Charged {
    bytes: Bytes,
    _held: Held,
}

impl AsRef<[u8]> for Charged {
    fn as_ref(&self) -> &[u8] {
        &self.bytes
    }
}

/// `bytes`, holding `held` until the last of their clones is dropped.
pub fn charged(bytes: Bytes, held: Held) -> Bytes {
    Bytes::from_owner(Charged { bytes, _held: held })
}
