//! GPU node cache: nodes live in a few large arena buffers (each within the adapter's storage
//! binding limit), allocated first-fit and evicted least-recently-drawn first under a memory
//! budget.

use crate::dataset::GpuNode;
use std::collections::{HashMap, HashSet};
use strata_format::NodeKey;

/// Bytes per point on the GPU: position + colour (16) and intensity/classification (4).
pub const GPU_POINT_BYTES: u64 = 20;
/// Points per arena at most (2^22: 64 MiB of positions), so that arena and index fit a u32.
const MAX_ARENA_SHIFT: u32 = 22;

pub struct Arena {
    pub points: wgpu::Buffer,
    pub attributes: wgpu::Buffer,
    /// Free ranges `(start, len)`, sorted and coalesced.
    free: Vec<(u32, u32)>,
}

#[derive(Debug, Clone, Copy)]
pub struct Slot {
    pub arena: u32,
    pub start: u32,
    pub count: u32,
    last_used: u64,
}

pub struct NodeCache {
    pub arenas: Vec<Arena>,
    slots: HashMap<NodeKey, Slot>,
    /// log2 of the points per arena.
    pub arena_shift: u32,
    budget_bytes: u64,
}

#[derive(Debug)]
pub enum InsertError {
    /// Nothing can be evicted to make room (everything resident is on screen).
    Full,
    /// The node is larger than an arena.
    TooLarge { points: usize, arena_points: u32 },
}

impl NodeCache {
    pub fn new(max_binding: u64, budget_bytes: u64) -> NodeCache {
        let by_binding = (max_binding / 16).max(1).ilog2();
        let by_budget = (budget_bytes / GPU_POINT_BYTES).max(1 << 16).ilog2();
        NodeCache {
            arenas: Vec::new(),
            slots: HashMap::new(),
            arena_shift: MAX_ARENA_SHIFT.min(by_binding).min(by_budget),
            budget_bytes,
        }
    }

    pub fn arena_points(&self) -> u32 {
        1 << self.arena_shift
    }

    pub fn contains(&self, key: NodeKey) -> bool {
        self.slots.contains_key(&key)
    }

    pub fn slot(&self, key: NodeKey) -> Option<Slot> {
        self.slots.get(&key).copied()
    }

    pub fn resident_nodes(&self) -> usize {
        self.slots.len()
    }

    pub fn resident_points(&self) -> u64 {
        self.slots.values().map(|s| s.count as u64).sum()
    }

    /// GPU memory held by the arenas.
    pub fn gpu_bytes(&self) -> u64 {
        self.arenas.len() as u64 * self.arena_points() as u64 * GPU_POINT_BYTES
    }

    pub fn touch(&mut self, keys: &[NodeKey], frame: u64) {
        for k in keys {
            if let Some(s) = self.slots.get_mut(k) {
                s.last_used = frame;
            }
        }
    }

    /// Uploads a node; may evict nodes not in `protect`.
    pub fn insert(
        &mut self,
        device: &wgpu::Device,
        queue: &wgpu::Queue,
        node: &GpuNode,
        frame: u64,
        protect: &HashSet<NodeKey>,
    ) -> Result<(), InsertError> {
        let count = node.points.len();
        if count > self.arena_points() as usize {
            return Err(InsertError::TooLarge {
                points: count,
                arena_points: self.arena_points(),
            });
        }
        if let Some(old) = self.slots.remove(&node.key) {
            self.release(old);
        }
        let count = count as u32;
        let (arena, start) = loop {
            if let Some(found) = self.allocate(count) {
                break found;
            }
            let next_bytes = (self.arenas.len() as u64 + 1) * self.arena_points() as u64;
            if self.arenas.is_empty() || next_bytes * GPU_POINT_BYTES <= self.budget_bytes {
                self.arenas.push(self.new_arena(device));
                continue;
            }
            let victim = self
                .slots
                .iter()
                .filter(|(k, _)| !protect.contains(k))
                .min_by_key(|(k, s)| (s.last_used, std::cmp::Reverse(k.level)))
                .map(|(k, _)| *k);
            match victim.and_then(|k| self.slots.remove(&k)) {
                Some(slot) => self.release(slot),
                None => return Err(InsertError::Full),
            }
        };
        let a = &self.arenas[arena as usize];
        if count > 0 {
            queue.write_buffer(
                &a.points,
                start as u64 * 16,
                bytemuck::cast_slice(&node.points),
            );
            queue.write_buffer(
                &a.attributes,
                start as u64 * 4,
                bytemuck::cast_slice(&node.attributes),
            );
        }
        self.slots.insert(
            node.key,
            Slot {
                arena,
                start,
                count,
                last_used: frame,
            },
        );
        Ok(())
    }

    fn new_arena(&self, device: &wgpu::Device) -> Arena {
        let n = self.arena_points() as u64;
        let make = |label: &str, bytes: u64| {
            device.create_buffer(&wgpu::BufferDescriptor {
                label: Some(label),
                size: bytes,
                usage: wgpu::BufferUsages::STORAGE | wgpu::BufferUsages::COPY_DST,
                mapped_at_creation: false,
            })
        };
        Arena {
            points: make("arena points", n * 16),
            attributes: make("arena attributes", n * 4),
            free: vec![(0, self.arena_points())],
        }
    }

    fn allocate(&mut self, count: u32) -> Option<(u32, u32)> {
        let count = count.max(1);
        for (ai, arena) in self.arenas.iter_mut().enumerate() {
            if let Some(i) = arena.free.iter().position(|&(_, len)| len >= count) {
                let (start, len) = arena.free[i];
                if len == count {
                    arena.free.remove(i);
                } else {
                    arena.free[i] = (start + count, len - count);
                }
                return Some((ai as u32, start));
            }
        }
        None
    }

    fn release(&mut self, slot: Slot) {
        let free = &mut self.arenas[slot.arena as usize].free;
        let len = slot.count.max(1);
        let at = free.partition_point(|&(s, _)| s < slot.start);
        free.insert(at, (slot.start, len));
        // Coalesce with the next and the previous range.
        if at + 1 < free.len() && free[at].0 + free[at].1 == free[at + 1].0 {
            free[at].1 += free[at + 1].1;
            free.remove(at + 1);
        }
        if at > 0 && free[at - 1].0 + free[at - 1].1 == free[at].0 {
            free[at - 1].1 += free[at].1;
            free.remove(at);
        }
    }
}
