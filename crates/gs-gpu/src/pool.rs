//! A pool of device buffers that grow geometrically and shrink again.
//!
//! Buffers are bound whole or in ranges and their contents are lost whenever they are
//! reallocated, so the owner calls [`BufferPool::begin_frame`] only where no buffer holds
//! anything still needed (e.g. at the start of a render), then [`BufferPool::ensure`]s every
//! buffer it uses in that frame before binding it.

use crate::GpuContext;
use std::collections::VecDeque;

/// Smallest buffer size: a released buffer keeps this many bytes (bindings stay valid).
const MIN_BYTES: u64 = 256;

/// When [`BufferPool::begin_frame`] gives memory back.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct ShrinkPolicy {
    /// Frames of need remembered per buffer; a buffer not needed in that many frames is
    /// released, and nothing is shrunk before that much history exists.
    pub window: usize,
    /// A buffer larger than `factor` × its largest need over the window is reallocated to
    /// that need.
    pub factor: u64,
}

impl Default for ShrinkPolicy {
    /// 16 frames, a factor of 4 (well above the 2 of geometric growth, so no oscillation).
    fn default() -> Self {
        Self {
            window: 16,
            factor: 4,
        }
    }
}

impl ShrinkPolicy {
    /// Never shrink (the behaviour of a pool that only grows).
    pub fn never() -> Self {
        Self {
            window: usize::MAX,
            factor: u64::MAX,
        }
    }

    /// The capacity a buffer of capacity `cap` should have given the needs of the window, or
    /// `None` to keep it.
    fn target(&self, cap: u64, needs: &VecDeque<u64>) -> Option<u64> {
        if needs.len() < self.window {
            return None;
        }
        let recent = needs.iter().copied().max().unwrap_or(0);
        let want = recent.next_multiple_of(MIN_BYTES).max(MIN_BYTES);
        (cap > want && (recent == 0 || cap / self.factor > recent)).then_some(want)
    }
}

/// Handle of a buffer of a [`BufferPool`].
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub struct BufId(usize);

/// A buffer range bound to a storage slot.
#[derive(Debug, Clone, Copy)]
pub struct Bind<'a> {
    /// The buffer.
    pub buf: &'a wgpu::Buffer,
    /// First byte.
    pub offset: u64,
    /// Bytes (at least 4).
    pub size: u64,
}

impl<'a> Bind<'a> {
    /// `size` bytes of `buf` from `offset` (sizes below 4 become 4: bindings are never empty).
    pub fn range(buf: &'a wgpu::Buffer, offset: u64, size: u64) -> Self {
        Self {
            buf,
            offset,
            size: size.max(4),
        }
    }

    /// The whole buffer.
    pub fn whole(buf: &'a wgpu::Buffer) -> Self {
        Self::range(buf, 0, buf.size())
    }
}

struct Entry {
    buf: wgpu::Buffer,
    usage: wgpu::BufferUsages,
    label: &'static str,
    /// Geometric growth stops here (e.g. the storage-binding limit: buffers are bound whole).
    limit: u64,
    /// Largest [`BufferPool::ensure`] of each of the last `window` frames (current one last).
    needs: VecDeque<u64>,
}

/// Device buffers by handle, each grown on demand and shrunk by a [`ShrinkPolicy`].
pub struct BufferPool {
    device: wgpu::Device,
    max_binding: u64,
    policy: ShrinkPolicy,
    entries: Vec<Entry>,
}

impl std::fmt::Debug for BufferPool {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(
            f,
            "BufferPool({} buffers, {} bytes)",
            self.entries.len(),
            self.allocated_bytes()
        )
    }
}

impl BufferPool {
    /// An empty pool on `ctx`'s device.
    pub fn new(ctx: &GpuContext, policy: ShrinkPolicy) -> Self {
        Self {
            device: ctx.device().clone(),
            max_binding: ctx.max_storage_binding(),
            policy,
            entries: Vec::new(),
        }
    }

    /// Adds a buffer of `usage` whose geometric growth stops at `limit` bytes.
    pub fn add(&mut self, label: &'static str, usage: wgpu::BufferUsages, limit: u64) -> BufId {
        self.entries.push(Entry {
            buf: create(&self.device, label, usage, MIN_BYTES),
            usage,
            label,
            limit,
            needs: VecDeque::from([0]),
        });
        BufId(self.entries.len() - 1)
    }

    /// Adds a storage buffer (also a copy source and destination) whose growth stops at the
    /// context's storage-binding limit.
    pub fn add_storage(&mut self, label: &'static str) -> BufId {
        let usage = wgpu::BufferUsages::STORAGE
            | wgpu::BufferUsages::COPY_DST
            | wgpu::BufferUsages::COPY_SRC;
        self.add(label, usage, self.max_binding)
    }

    /// Adds a staging buffer for readback (`MAP_READ | COPY_DST`).
    pub fn add_staging(&mut self, label: &'static str) -> BufId {
        let usage = wgpu::BufferUsages::MAP_READ | wgpu::BufferUsages::COPY_DST;
        self.add(label, usage, u64::MAX)
    }

    /// Makes room for `bytes` in buffer `id` (contents are lost when it grows) and records
    /// the need for the shrink policy.
    pub fn ensure(&mut self, id: BufId, bytes: u64) {
        let e = &mut self.entries[id.0];
        if let Some(n) = e.needs.back_mut() {
            *n = (*n).max(bytes);
        }
        let cap = e.buf.size();
        if bytes <= cap {
            return;
        }
        let grown = cap.saturating_mul(2).min(e.limit / MIN_BYTES * MIN_BYTES);
        let cap = bytes.next_multiple_of(4).max(grown);
        e.buf = create(&self.device, e.label, e.usage, cap);
    }

    /// Starts a frame: applies the shrink policy (reallocating buffers, whose contents are
    /// then lost) and opens a new need record. Returns the bytes given back.
    pub fn begin_frame(&mut self) -> u64 {
        let mut freed = 0;
        for e in &mut self.entries {
            let cap = e.buf.size();
            if let Some(want) = self.policy.target(cap, &e.needs) {
                e.buf = create(&self.device, e.label, e.usage, want);
                freed += cap - want;
            }
            e.needs.push_back(0);
            while e.needs.len() > self.policy.window.max(1) {
                e.needs.pop_front();
            }
        }
        freed
    }

    /// The buffer of `id`.
    pub fn buffer(&self, id: BufId) -> &wgpu::Buffer {
        &self.entries[id.0].buf
    }

    /// Current size of buffer `id` in bytes.
    pub fn capacity(&self, id: BufId) -> u64 {
        self.entries[id.0].buf.size()
    }

    /// Total bytes allocated by the pool.
    pub fn allocated_bytes(&self) -> u64 {
        self.entries.iter().map(|e| e.buf.size()).sum()
    }

    /// Buffer `id` bound whole.
    pub fn whole(&self, id: BufId) -> Bind<'_> {
        Bind::whole(self.buffer(id))
    }

    /// `size` bytes of buffer `id` from `offset`.
    pub fn range(&self, id: BufId, offset: u64, size: u64) -> Bind<'_> {
        Bind::range(self.buffer(id), offset, size)
    }
}

fn create(
    device: &wgpu::Device,
    label: &str,
    usage: wgpu::BufferUsages,
    size: u64,
) -> wgpu::Buffer {
    device.create_buffer(&wgpu::BufferDescriptor {
        label: Some(label),
        size,
        usage,
        mapped_at_creation: false,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    fn needs(v: &[u64]) -> VecDeque<u64> {
        v.iter().copied().collect()
    }

    #[test]
    fn policy_keeps_buffers_in_use_and_without_history() {
        let p = ShrinkPolicy {
            window: 4,
            factor: 4,
        };
        assert_eq!(
            p.target(1 << 20, &needs(&[0, 0, 0])),
            None,
            "too little history"
        );
        assert_eq!(
            p.target(1 << 20, &needs(&[1 << 20, 0, 0, 0])),
            None,
            "needed recently"
        );
        assert_eq!(
            p.target(1 << 20, &needs(&[0, 0, 1 << 19, 0])),
            None,
            "within the factor"
        );
        assert_eq!(
            p.target(256, &needs(&[0, 0, 0, 0])),
            None,
            "already minimal"
        );
        assert_eq!(
            ShrinkPolicy::never().target(1 << 30, &needs(&[0; 64])),
            None
        );
    }

    #[test]
    fn policy_releases_idle_and_oversized_buffers() {
        let p = ShrinkPolicy {
            window: 4,
            factor: 4,
        };
        assert_eq!(p.target(1 << 20, &needs(&[0, 0, 0, 0])), Some(MIN_BYTES));
        assert_eq!(p.target(1 << 20, &needs(&[1000, 0, 5000, 0])), Some(5120));
    }
}
