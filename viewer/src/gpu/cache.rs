//! GPU node cache: nodes live in a few large arena buffers (each within the adapter's storage
//! binding limit) and are evicted least-recently-drawn first under a memory budget. A node
//! takes one free range when one is large enough, else several pieces: projection draws ranges,
//! not nodes, so fragmentation never refuses a node while the free space adds up.

use crate::dataset::GpuNode;
use crate::pipelines::PointStream;
use std::collections::{HashMap, HashSet};
use strata_format::NodeKey;

/// Bytes per point on the GPU: position + colour (16) and intensity/classification (4).
pub const GPU_POINT_BYTES: u64 = 20;
/// Points per arena at most (2^22: 64 MiB of positions), so that arena and index fit a u32.
const MAX_ARENA_SHIFT: u32 = 22;

pub struct Arena {
    pub points: wgpu::Buffer,
    pub attributes: wgpu::Buffer,
    /// The active pipeline's per-point streams, indexed like `points`.
    pub streams: Vec<(PointStream, wgpu::Buffer)>,
    /// Free ranges `(start, len)`, sorted and coalesced.
    free: Vec<(u32, u32)>,
}

impl Arena {
    /// The per-point stream `want` beside this arena, where the active pipeline declared it.
    pub fn stream(&self, want: PointStream) -> Option<&wgpu::Buffer> {
        self.streams
            .iter()
            .find(|(s, _)| *s == want)
            .map(|(_, b)| b)
    }
}

/// Points `start..start + count` of arena `arena`.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Piece {
    pub arena: u32,
    pub start: u32,
    pub count: u32,
}

#[derive(Debug, Clone)]
pub struct Slot {
    pub pieces: Vec<Piece>,
    last_used: u64,
}

pub struct NodeCache {
    pub arenas: Vec<Arena>,
    slots: HashMap<NodeKey, Slot>,
    /// log2 of the points per arena.
    pub arena_shift: u32,
    budget_bytes: u64,
    /// The streams every arena holds (those the active pipeline needs).
    streams: Vec<PointStream>,
}

#[derive(Debug)]
pub enum InsertError {
    /// Nothing can be evicted to make room (everything resident is on screen).
    Full,
    /// The node is larger than the whole cache.
    TooLarge { points: usize, capacity: u64 },
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
            streams: Vec::new(),
        }
    }

    /// GPU bytes a resident point takes with the current streams.
    fn point_bytes(&self) -> u64 {
        GPU_POINT_BYTES
            + self
                .streams
                .iter()
                .map(|s| s.bytes_per_point())
                .sum::<u64>()
    }

    /// Holds exactly `wanted` beside every arena: streams no longer wanted are freed, new ones
    /// made. A new stream the dataset feeds (normals, radius) empties the cache, so that every
    /// node is loaded again with it; a new kept value starts at zero.
    pub fn set_streams(&mut self, device: &wgpu::Device, wanted: &[PointStream]) {
        if self.streams == wanted {
            return;
        }
        let fed = |s: &PointStream| !matches!(s, PointStream::Kept { .. });
        if wanted.iter().any(|s| fed(s) && !self.streams.contains(s)) {
            self.clear();
        }
        let n = self.arena_points() as u64;
        for a in &mut self.arenas {
            a.streams.retain(|(s, _)| wanted.contains(s));
            for s in wanted {
                if !a.streams.iter().any(|(have, _)| have == s) {
                    a.streams.push((*s, stream_buffer(device, *s, n)));
                }
            }
        }
        self.streams = wanted.to_vec();
    }

    /// Forgets every resident node (the arenas stay), so that each is loaded again.
    pub fn clear(&mut self) {
        self.slots.clear();
        for a in &mut self.arenas {
            a.free = vec![(0, 1 << self.arena_shift)];
        }
    }

    /// Arena `arena` and its streams `wanted`, for a pass that binds them; the error names
    /// what is missing.
    pub fn arena_streams<const N: usize>(
        &self,
        arena: u32,
        wanted: [PointStream; N],
    ) -> Result<(&Arena, [&wgpu::Buffer; N]), crate::ViewerError> {
        let a = self
            .arenas
            .get(arena as usize)
            .ok_or_else(|| crate::ViewerError::Gpu(format!("arena {arena} is not resident")))?;
        let mut out = Vec::with_capacity(N);
        for want in wanted {
            out.push(a.stream(want).ok_or_else(|| {
                crate::ViewerError::Gpu(format!("arena {arena} holds no {want:?} stream"))
            })?);
        }
        let streams = out
            .try_into()
            .map_err(|_| crate::ViewerError::Gpu("stream lookup lost a stream".into()))?;
        Ok((a, streams))
    }

    pub fn arena_points(&self) -> u32 {
        1 << self.arena_shift
    }

    /// Points the cache can hold at most: whole arenas within the memory budget (at least one).
    pub fn capacity_points(&self) -> u64 {
        let arena_bytes = self.arena_points() as u64 * self.point_bytes();
        (self.budget_bytes / arena_bytes).max(1) * self.arena_points() as u64
    }

    pub fn contains(&self, key: NodeKey) -> bool {
        self.slots.contains_key(&key)
    }

    /// Every resident node with its pieces.
    pub fn slots(&self) -> impl Iterator<Item = (NodeKey, &[Piece])> {
        self.slots.iter().map(|(k, s)| (*k, s.pieces.as_slice()))
    }

    pub fn pieces(&self, key: NodeKey) -> Option<&[Piece]> {
        self.slots.get(&key).map(|s| s.pieces.as_slice())
    }

    pub fn resident_nodes(&self) -> usize {
        self.slots.len()
    }

    pub fn resident_points(&self) -> u64 {
        self.slots
            .values()
            .flat_map(|s| &s.pieces)
            .map(|p| p.count as u64)
            .sum()
    }

    /// GPU memory held by the arenas.
    pub fn gpu_bytes(&self) -> u64 {
        self.arenas.len() as u64 * self.arena_points() as u64 * self.point_bytes()
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
        if count as u64 > self.capacity_points() {
            return Err(InsertError::TooLarge {
                points: count,
                capacity: self.capacity_points(),
            });
        }
        if let Some(old) = self.slots.remove(&node.key) {
            self.release(&old);
        }
        // A node without points (an inner node whose points all went to its parent) is
        // resident with nothing to draw.
        if count == 0 {
            self.slots.insert(
                node.key,
                Slot {
                    pieces: Vec::new(),
                    last_used: frame,
                },
            );
            return Ok(());
        }
        let count = count as u32;
        let pieces = loop {
            if let Some(found) = self.allocate(count) {
                break found;
            }
            let next_bytes = (self.arenas.len() as u64 + 1) * self.arena_points() as u64;
            if self.arenas.is_empty() || next_bytes * self.point_bytes() <= self.budget_bytes {
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
                Some(slot) => self.release(&slot),
                None => return Err(InsertError::Full),
            }
        };
        let mut done = 0usize;
        for p in &pieces {
            let a = &self.arenas[p.arena as usize];
            let range = done..done + p.count as usize;
            if !range.is_empty() {
                queue.write_buffer(
                    &a.points,
                    p.start as u64 * 16,
                    bytemuck::cast_slice(&node.points[range.clone()]),
                );
                queue.write_buffer(
                    &a.attributes,
                    p.start as u64 * 4,
                    bytemuck::cast_slice(&node.attributes[range.clone()]),
                );
                for (s, buffer) in &a.streams {
                    let bytes = s.bytes_per_point() as usize;
                    let given = node.streams.iter().find(|(have, _)| have == s);
                    let data = match given {
                        Some((_, d)) if d.len() >= range.end * bytes => {
                            std::borrow::Cow::Borrowed(&d[range.start * bytes..range.end * bytes])
                        }
                        // Not stored, or a kept value: zero, not the last node's.
                        _ => std::borrow::Cow::Owned(vec![0u8; range.len() * bytes]),
                    };
                    queue.write_buffer(buffer, p.start as u64 * bytes as u64, &data);
                }
            }
            done += p.count as usize;
        }
        self.slots.insert(
            node.key,
            Slot {
                pieces,
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
            streams: self
                .streams
                .iter()
                .map(|s| (*s, stream_buffer(device, *s, n)))
                .collect(),
            free: vec![(0, self.arena_points())],
        }
    }

    /// One free range that holds `count` points if there is one, else pieces from the largest
    /// free ranges; `None` when the free space does not add up.
    fn allocate(&mut self, count: u32) -> Option<Vec<Piece>> {
        let count = count.max(1);
        for (ai, arena) in self.arenas.iter_mut().enumerate() {
            if let Some(i) = arena.free.iter().position(|&(_, len)| len >= count) {
                return Some(vec![take(&mut arena.free, i, count, ai as u32)]);
            }
        }
        let free: u64 = self
            .arenas
            .iter()
            .flat_map(|a| &a.free)
            .map(|&(_, len)| len as u64)
            .sum();
        if free < count as u64 {
            return None;
        }
        let mut pieces = Vec::new();
        let mut left = count;
        while left > 0 {
            let (ai, i, len) = self
                .arenas
                .iter()
                .enumerate()
                .flat_map(|(ai, a)| {
                    a.free
                        .iter()
                        .enumerate()
                        .map(move |(i, &(_, len))| (ai, i, len))
                })
                .max_by_key(|&(_, _, len)| len)?;
            let n = left.min(len);
            pieces.push(take(&mut self.arenas[ai].free, i, n, ai as u32));
            left -= n;
        }
        Some(pieces)
    }

    fn release(&mut self, slot: &Slot) {
        for p in &slot.pieces {
            release_range(
                &mut self.arenas[p.arena as usize].free,
                p.start,
                p.count.max(1),
            );
        }
    }
}

/// A stream's buffer for `points` points, zeroed.
fn stream_buffer(device: &wgpu::Device, s: PointStream, points: u64) -> wgpu::Buffer {
    device.create_buffer(&wgpu::BufferDescriptor {
        label: Some("arena stream"),
        size: (points * s.bytes_per_point()).max(4),
        // Pipelines that keep a value write it on the GPU and read it next frame.
        usage: wgpu::BufferUsages::STORAGE
            | wgpu::BufferUsages::COPY_DST
            | wgpu::BufferUsages::COPY_SRC,
        mapped_at_creation: false,
    })
}

/// Takes `n` points from the front of free range `i`.
fn take(free: &mut Vec<(u32, u32)>, i: usize, n: u32, arena: u32) -> Piece {
    let (start, len) = free[i];
    if len == n {
        free.remove(i);
    } else {
        free[i] = (start + n, len - n);
    }
    Piece {
        arena,
        start,
        count: n,
    }
}

/// Returns a range to a sorted free list, merging it with its neighbours.
fn release_range(free: &mut Vec<(u32, u32)>, start: u32, len: u32) {
    let at = free.partition_point(|&(s, _)| s < start);
    free.insert(at, (start, len));
    if at + 1 < free.len() && free[at].0 + free[at].1 == free[at + 1].0 {
        free[at].1 += free[at + 1].1;
        free.remove(at + 1);
    }
    if at > 0 && free[at - 1].0 + free[at - 1].1 == free[at].0 {
        free[at - 1].1 += free[at].1;
        free.remove(at);
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn free_ranges_merge_back_into_one() {
        let mut free = vec![(0u32, 100u32)];
        let a = take(&mut free, 0, 30, 0);
        let b = take(&mut free, 0, 30, 0);
        assert_eq!((a.start, b.start), (0, 30));
        assert_eq!(free, vec![(60, 40)]);
        release_range(&mut free, a.start, a.count);
        assert_eq!(free, vec![(0, 30), (60, 40)]);
        release_range(&mut free, b.start, b.count);
        assert_eq!(free, vec![(0, 100)]);
    }
}

#[cfg(test)]
mod stream_tests {
    use super::*;
    use crate::gpu::{GpuContext, ProjectionPath};

    fn node(level: u8, points: usize) -> GpuNode {
        GpuNode {
            key: NodeKey {
                level,
                x: 0,
                y: 0,
                z: 0,
            },
            colours: Default::default(),
            marks: Default::default(),
            points: vec![[0; 4]; points],
            attributes: vec![0; points],
            streams: Vec::new(),
            bytes_read: 0,
            sampling: None,
        }
    }

    #[test]
    fn streams_exist_only_while_wanted_and_a_fed_one_reloads_every_node() {
        let ctx = GpuContext::new(ProjectionPath::Auto).expect("GPU adapter");
        let (d, q) = (&ctx.device, &ctx.queue);
        let mut cache = NodeCache::new(ctx.max_binding(), 64 << 20);
        let protect = HashSet::new();
        cache
            .insert(d, q, &node(0, 1000), 1, &protect)
            .expect("insert");
        let plain = cache.gpu_bytes();
        let kept = PointStream::Kept {
            name: "test",
            bytes: 8,
        };
        cache.set_streams(d, &[kept]);
        // A kept value needs no reload: the node stays, with a zeroed stream beside it.
        assert_eq!(cache.resident_nodes(), 1);
        let n = cache.arena_points() as u64;
        let sizes: Vec<u64> = cache.arenas[0]
            .streams
            .iter()
            .map(|(_, b)| b.size())
            .collect();
        assert_eq!(sizes, vec![n * 8]);
        assert_eq!(cache.gpu_bytes(), plain + n * 8);
        cache
            .insert(d, q, &node(1, 500), 2, &protect)
            .expect("insert");
        // Normals come from the dataset: every node is loaded again with them.
        cache.set_streams(d, &[kept, PointStream::Normals]);
        assert_eq!(cache.resident_nodes(), 0);
        assert_eq!(cache.arenas[0].streams.len(), 2);
        cache.set_streams(d, &[]);
        assert!(cache.arenas.iter().all(|a| a.streams.is_empty()));
        assert_eq!(cache.gpu_bytes(), plain);
        ctx.wait().expect("no GPU fault");
    }
}
