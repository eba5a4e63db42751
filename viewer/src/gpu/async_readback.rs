//! A small GPU buffer read back without stalling the frame loop: a copy is recorded only while
//! no earlier one is in flight, and its bytes arrive a frame or more later (at once when the
//! caller waits for the GPU). The window's pass times and depth noise come this way.

use std::sync::Arc;
use std::sync::atomic::{AtomicU8, Ordering};

const IDLE: u8 = 0;
const MAPPING: u8 = 1;
const MAPPED: u8 = 2;

pub struct AsyncReadback {
    buffer: wgpu::Buffer,
    /// Set from the map callback, which wgpu may run on another thread.
    state: Arc<AtomicU8>,
    /// A copy is recorded and waits for its submission.
    recorded: bool,
}

impl AsyncReadback {
    pub fn new(device: &wgpu::Device, label: &str, size: u64) -> AsyncReadback {
        AsyncReadback {
            buffer: device.create_buffer(&wgpu::BufferDescriptor {
                label: Some(label),
                size,
                usage: wgpu::BufferUsages::MAP_READ | wgpu::BufferUsages::COPY_DST,
                mapped_at_creation: false,
            }),
            state: Arc::new(AtomicU8::new(IDLE)),
            recorded: false,
        }
    }

    /// No copy is recorded or in flight: one may be recorded now.
    pub fn is_idle(&self) -> bool {
        !self.recorded && self.state.load(Ordering::Acquire) == IDLE
    }

    /// Records a copy of `size` bytes of `source` from `offset` into the start of the readback
    /// buffer, if it is idle and the bytes fit; returns whether it did.
    pub fn record(
        &mut self,
        encoder: &mut wgpu::CommandEncoder,
        source: &wgpu::Buffer,
        offset: u64,
        size: u64,
    ) -> bool {
        if !self.is_idle() || size > self.buffer.size() {
            return false;
        }
        encoder.copy_buffer_to_buffer(source, offset, &self.buffer, 0, size);
        self.recorded = true;
        true
    }

    /// After submitting the encoder a copy went into: starts mapping. Returns whether a copy
    /// was recorded (and is now in flight).
    pub fn after_submit(&mut self) -> bool {
        if !std::mem::take(&mut self.recorded) {
            return false;
        }
        self.state.store(MAPPING, Ordering::Release);
        let state = self.state.clone();
        self.buffer
            .slice(..)
            .map_async(wgpu::MapMode::Read, move |result| {
                state.store(
                    if result.is_ok() { MAPPED } else { IDLE },
                    Ordering::Release,
                );
            });
        true
    }

    /// Forgets a recorded copy whose encoder was never submitted (an error on the way), so
    /// that the next may be recorded.
    pub fn abandon(&mut self) {
        self.recorded = false;
    }

    /// The bytes of a finished readback, once; `None` while none has arrived (call after
    /// polling the device). A mapping that fails frees the buffer for the next copy.
    pub fn take(&mut self) -> Option<Vec<u8>> {
        if self.state.load(Ordering::Acquire) != MAPPED {
            return None;
        }
        let data = self
            .buffer
            .slice(..)
            .get_mapped_range()
            .ok()
            .map(|d| d.to_vec());
        self.buffer.unmap();
        self.state.store(IDLE, Ordering::Release);
        data
    }
}
