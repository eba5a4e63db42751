//! The bytes of answers read into memory and not yet written to a socket, bounded for each
//! connection and for the whole server. A stream's chunk stays in memory until the client's
//! flow-control window lets it out: an HTTP/2 client that opened 32 streams and read nothing
//! held 8.6 MB a connection, 4.3 GB over 500 connections, with a megabyte of requests. Each
//! read now first takes its size from its connection's share, then from the connection's own
//! reserve or else the server's pool; both come back when the bytes are dropped (written out,
//! or the stream gone). A read that finds no room waits, within the request's time limit. The
//! reserve, never lent to another connection, answers a new client while stalled ones hold the
//! whole pool. At most 512 connections x 256 KiB + 128 MiB: 256 MiB.

use bytes::Bytes;
use std::sync::Arc;
use tokio::sync::{OwnedSemaphorePermit, Semaphore};

/// The unit budgets count in.
const UNIT: usize = 4 << 10;
/// One connection's share: eight 256 KiB chunks in flight, far more than a client that reads
/// keeps waiting (the kernel's socket buffers hold what is on its way).
pub const PER_CONNECTION: usize = 2 << 20;
/// Each connection's own, not drawn from the server's pool: a range read whole.
pub const RESERVED: usize = 256 << 10;
/// The server's pool, what 64 connections at their share hold.
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

    /// A connection's budget: `share` bytes at most, the first `reserved` its own.
    pub fn connection(&self, share: usize, reserved: usize) -> ConnectionBudget {
        ConnectionBudget {
            own: Arc::new(Semaphore::new(units(share))),
            share: units(share),
            reserved: Arc::new(Semaphore::new(units(reserved))),
            server: self.0.clone(),
        }
    }
}

/// One connection's budget, drawn from the server's as it is used.
#[derive(Debug, Clone)]
pub struct ConnectionBudget {
    own: Arc<Semaphore>,
    /// Units in `own` when none are taken.
    share: usize,
    reserved: Arc<Semaphore>,
    server: Arc<Semaphore>,
}

impl ConnectionBudget {
    /// Room for `bytes` (at most the connection's share), once both budgets have it. `None`
    /// only where a semaphore was closed, which never happens while the server runs.
    pub async fn take(&self, bytes: usize) -> Option<Held> {
        let n = u32::try_from(units(bytes).min(self.share)).ok()?;
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
        Some(Held { own, pool })
    }
}

/// Room taken from the connection's share and a pool, given back when dropped.
#[derive(Debug)]
pub struct Held {
    own: OwnedSemaphorePermit,
    /// From the connection's reserve, or the server's pool.
    pool: OwnedSemaphorePermit,
}

impl Held {
    /// Gives back what `bytes` do not need.
    pub fn keep(&mut self, bytes: usize) {
        let excess = self.own.num_permits().saturating_sub(units(bytes));
        drop(self.own.split(excess));
        drop(self.pool.split(excess));
    }
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
