//! GPU time per pass, by one of two clocks. Timestamp queries are read back without stalling
//! the frame: results arrive a frame or two later in a window, at once when the caller waits
//! for the GPU. The wall clock submits every pass alone and waits for it, for adapters whose
//! timestamps do not bracket the work: lavapipe runs a dispatch asynchronously after its pass
//! has ended, so its timestamps charge a pass's work to whichever later pass waits for it.

use super::async_readback::AsyncReadback;
use crate::ViewerError;
use serde::ser::{Serialize, SerializeMap, Serializer};
use std::time::Instant;

/// Which clock times the passes.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum PassClock {
    /// The wall clock on CPU adapters, timestamp queries elsewhere.
    Auto,
    /// Timestamp queries inside one submission per frame.
    Timestamps,
    /// Each pass submitted alone and waited for; slows the frame by one round trip per pass.
    Wall,
}

impl PassClock {
    pub const ALL: [PassClock; 3] = [PassClock::Auto, PassClock::Timestamps, PassClock::Wall];

    pub fn name(self) -> &'static str {
        match self {
            PassClock::Auto => "auto",
            PassClock::Timestamps => "timestamps",
            PassClock::Wall => "wall",
        }
    }

    pub fn parse(s: &str) -> Result<PassClock, ViewerError> {
        PassClock::ALL
            .into_iter()
            .find(|c| c.name() == s)
            .ok_or_else(|| {
                ViewerError::argument(s, "unknown pass clock (expected auto, timestamps or wall)")
            })
    }
}

/// GPU ms per pass, in the order the passes first ran this frame (a pass that runs more than
/// once under one name adds up). Written to JSON as an object in that order.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct PassTimes(Vec<(String, f64)>);

impl PassTimes {
    pub fn add(&mut self, name: &str, ms: f64) {
        match self.0.iter_mut().find(|(n, _)| n == name) {
            Some((_, t)) => *t += ms,
            None => self.0.push((name.to_string(), ms)),
        }
    }

    pub fn get(&self, name: &str) -> Option<f64> {
        self.0.iter().find(|(n, _)| n == name).map(|(_, t)| *t)
    }

    pub fn iter(&self) -> impl Iterator<Item = (&str, f64)> {
        self.0.iter().map(|(n, t)| (n.as_str(), *t))
    }

    pub fn is_empty(&self) -> bool {
        self.0.is_empty()
    }

    pub fn clear(&mut self) {
        self.0.clear();
    }
}

impl Serialize for PassTimes {
    fn serialize<S: Serializer>(&self, s: S) -> Result<S::Ok, S::Error> {
        let mut map = s.serialize_map(Some(self.0.len()))?;
        for (name, ms) in &self.0 {
            map.serialize_entry(name, ms)?;
        }
        map.end()
    }
}

pub struct Timer {
    /// Passes one frame can time (timestamp pairs in the query set).
    capacity: u32,
    queries: Option<Queries>,
    device: wgpu::Device,
    queue: wgpu::Queue,
    /// This frame's passes are timed by the wall clock.
    wall: bool,
    /// Under the wall clock: the pass submitted last and when the GPU was idle before it.
    open: Option<(String, Instant)>,
    names: Vec<String>,
    /// Names of the passes in the readback buffer while it is being mapped.
    in_readback: Vec<String>,
    last: PassTimes,
    /// A wait of the wall clock that failed, for the frame to report.
    poll_error: Option<String>,
    /// The readback in flight belongs to frames before a pipeline switch.
    discard_next: bool,
}

struct Queries {
    set: wgpu::QuerySet,
    resolve: wgpu::Buffer,
    readback: AsyncReadback,
    period_ns: f32,
}

impl Timer {
    /// `capacity`: the most passes one frame times (the registry's `max_timed_passes`).
    pub fn new(device: &wgpu::Device, queue: &wgpu::Queue, enabled: bool, capacity: u32) -> Timer {
        let queries = enabled.then(|| {
            let bytes = capacity as u64 * 2 * 8;
            Queries {
                set: device.create_query_set(&wgpu::QuerySetDescriptor {
                    label: Some("pass timestamps"),
                    ty: wgpu::QueryType::Timestamp,
                    count: capacity * 2,
                }),
                resolve: device.create_buffer(&wgpu::BufferDescriptor {
                    label: Some("timestamp resolve"),
                    size: bytes,
                    usage: wgpu::BufferUsages::QUERY_RESOLVE | wgpu::BufferUsages::COPY_SRC,
                    mapped_at_creation: false,
                }),
                readback: AsyncReadback::new(device, "timestamp readback", bytes),
                period_ns: queue.get_timestamp_period(),
            }
        });
        Timer {
            capacity,
            queries,
            device: device.clone(),
            queue: queue.clone(),
            wall: false,
            open: None,
            names: Vec::new(),
            in_readback: Vec::new(),
            last: PassTimes::default(),
            poll_error: None,
            discard_next: false,
        }
    }

    /// `wall`: time this frame's passes by the wall clock.
    pub fn begin_frame(&mut self, wall: bool) {
        self.names.clear();
        self.wall = wall;
        if wall {
            self.last.clear();
        }
    }

    /// Call before encoding a pass named `name` into `encoder`: the timestamp writes for it,
    /// when timestamps time this frame. Under the wall clock it submits what `encoder` holds
    /// and waits, so the pass starts on an idle GPU.
    pub fn pass(
        &mut self,
        encoder: &mut wgpu::CommandEncoder,
        name: &str,
    ) -> Option<wgpu::ComputePassTimestampWrites<'_>> {
        if self.wall {
            self.submit_and_wait(encoder);
            self.open = Some((name.to_string(), Instant::now()));
            return None;
        }
        let q = self.queries.as_ref()?;
        if !q.readback.is_idle() || self.names.len() as u32 >= self.capacity {
            return None;
        }
        let i = self.names.len() as u32;
        self.names.push(name.to_string());
        Some(wgpu::ComputePassTimestampWrites {
            query_set: &q.set,
            beginning_of_pass_write_index: Some(2 * i),
            end_of_pass_write_index: Some(2 * i + 1),
        })
    }

    /// Submits the passes encoded so far, waits for them, and charges the time since the last
    /// pass began to that pass.
    fn submit_and_wait(&mut self, encoder: &mut wgpu::CommandEncoder) {
        let fresh = self
            .device
            .create_command_encoder(&wgpu::CommandEncoderDescriptor {
                label: Some("frame"),
            });
        let done = std::mem::replace(encoder, fresh);
        self.queue.submit([done.finish()]);
        if let Err(e) = self.device.poll(super::context::bounded_wait()) {
            self.poll_error = Some(e.to_string());
        }
        if let Some((name, start)) = self.open.take() {
            self.last.add(&name, start.elapsed().as_secs_f64() * 1e3);
        }
    }

    /// After the passes: under the wall clock, finish timing the last pass; with timestamps,
    /// resolve the queries into the readback buffer.
    pub fn resolve(&mut self, encoder: &mut wgpu::CommandEncoder) {
        if self.wall {
            self.submit_and_wait(encoder);
            return;
        }
        let Some(q) = &mut self.queries else { return };
        if self.names.is_empty() {
            return;
        }
        let n = self.names.len() as u32 * 2;
        encoder.resolve_query_set(&q.set, 0..n, &q.resolve, 0);
        q.readback.record(encoder, &q.resolve, 0, u64::from(n) * 8);
    }

    /// After submitting: start mapping the readback buffer.
    pub fn after_submit(&mut self) {
        let Some(q) = &mut self.queries else { return };
        if q.readback.after_submit() {
            self.in_readback = std::mem::take(&mut self.names);
        }
    }

    /// Collects a finished readback, if any (call after polling the device).
    pub fn collect(&mut self) {
        let Some(q) = &mut self.queries else { return };
        let Some(data) = q.readback.take() else {
            return;
        };
        // A readback left from a timestamped frame does not describe a wall-clock one, nor one
        // from before a pipeline switch this frame.
        if self.wall || std::mem::take(&mut self.discard_next) {
            return;
        }
        let stamps: Vec<u64> = data
            .chunks_exact(8)
            .filter_map(|b| <[u8; 8]>::try_from(b).ok().map(u64::from_le_bytes))
            .collect();
        self.last.clear();
        for (i, name) in self.in_readback.iter().enumerate() {
            let (Some(&a), Some(&b)) = (stamps.get(2 * i), stamps.get(2 * i + 1)) else {
                break;
            };
            let ms = b.saturating_sub(a) as f64 * q.period_ns as f64 / 1e6;
            self.last.add(name, ms);
        }
    }

    /// Forgets the pass times of earlier frames, and the readback on its way back: they
    /// describe another pipeline's passes.
    pub fn discard_pending(&mut self) {
        self.last.clear();
        self.discard_next = self.queries.as_ref().is_some_and(|q| !q.readback.is_idle());
    }

    /// A failed wait of the wall clock since the last call, if any.
    pub fn take_poll_error(&mut self) -> Option<String> {
        self.poll_error.take()
    }

    /// The most recent complete set of pass times (ms).
    pub fn last(&self) -> &PassTimes {
        &self.last
    }
}
