//! Per-view constants kept on the device between calls (docs/architecture.md §GPU): equal
//! slots in one storage buffer (one binding), each holding one `f32` array under the caller's
//! key, evicted least recently used. An array is uploaded on first use and whenever it was
//! evicted; an array without a key (one call's input) is uploaded every call into a slot no
//! other array of that call uses.
//!
//! The caller's contract: one key names one content for the arena's life (e.g. a view's photo
//! at one resolution). The arena checks the length, not the values.

use crate::{Bind, BufId, BufferPool, GpuContext, ShrinkPolicy};
use std::borrow::Cow;

/// A key: the caller's name of a view (or anything constant) and the part of it (two arrays of
/// one view, e.g. its photo and its edge guide, share the first).
pub type ArenaKey = (u64, u32);

#[derive(Debug, Clone, Copy)]
struct Slot {
    /// `None` for an array of one call.
    key: Option<ArenaKey>,
    floats: usize,
    used: u64,
}

/// The arena: its own pool (never shrunk by another frame's policy), slot size and contents.
pub struct Arena {
    pool: BufferPool,
    data: BufId,
    /// The budget in bytes.
    bytes: u64,
    slot_floats: usize,
    slots: Vec<Option<Slot>>,
    clock: u64,
}

impl std::fmt::Debug for Arena {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(f, "Arena({} slots of {} floats)", self.slots.len(), self.slot_floats)
    }
}

impl Arena {
    /// An empty arena on `ctx`'s device holding at most `bytes` (and one storage binding).
    pub fn new(ctx: &GpuContext, label: &'static str, bytes: u64) -> Self {
        let mut pool = BufferPool::new(ctx, ShrinkPolicy::never());
        let data = pool.add_storage(label);
        Self { pool, data, bytes, slot_floats: 0, slots: Vec::new(), clock: 0 }
    }

    /// The offsets (in floats) of the arrays `items` names (key, length), in order, uploading
    /// those not held (`upload(i)` gives item i's values, asked only when it is uploaded);
    /// `None` when they cannot all be held at once within one binding.
    pub fn place<'d>(&mut self, ctx: &GpuContext, items: &[(Option<ArenaKey>, usize)], upload: impl Fn(usize) -> Cow<'d, [f32]>) -> Option<Vec<u32>> {
        let largest = items.iter().map(|&(_, floats)| floats).max()?;
        let mut keyed: Vec<ArenaKey> = items.iter().filter_map(|&(k, _)| k).collect();
        keyed.sort_unstable();
        keyed.dedup();
        let needed = keyed.len() + items.iter().filter(|(k, _)| k.is_none()).count();
        if largest > self.slot_floats || self.slots.len() < needed {
            self.resize(ctx, largest.max(self.slot_floats), needed)?;
        }
        self.clock += 1;
        let mut offsets = Vec::with_capacity(items.len());
        for (i, &(key, floats)) in items.iter().enumerate() {
            let slot = self.slot_of(ctx, key, floats, || upload(i));
            offsets.push(u32::try_from(slot * self.slot_floats).ok()?);
        }
        Some(offsets)
    }

    /// Re-creates the slots at `slot_floats` each, as many as the budget and one binding hold
    /// (at least `needed`, else `None`); everything held is dropped.
    fn resize(&mut self, ctx: &GpuContext, slot_floats: usize, needed: usize) -> Option<()> {
        let slot_bytes = 4 * slot_floats as u64;
        let fit = ctx.max_storage_binding().min(self.bytes) / slot_bytes.max(1);
        let count = usize::try_from(fit).ok()?;
        if count < needed || count.checked_mul(slot_floats)? > u32::MAX as usize {
            return None;
        }
        self.pool.ensure(self.data, slot_bytes * count as u64);
        self.slot_floats = slot_floats;
        self.slots = vec![None; count];
        Some(())
    }

    /// The slot holding `key`, else the slot `values` is uploaded into: a free one, else one
    /// that this call has not used, an earlier call's unkeyed array first, then the least
    /// recently used.
    fn slot_of<'d>(&mut self, ctx: &GpuContext, key: Option<ArenaKey>, floats: usize, values: impl FnOnce() -> Cow<'d, [f32]>) -> usize {
        let clock = self.clock;
        let held = key.and_then(|k| self.slots.iter().position(|s| s.is_some_and(|s| s.key == Some(k) && s.floats == floats)));
        if let Some(i) = held {
            self.slots[i] = Some(Slot { key, floats, used: clock });
            return i;
        }
        let i = self.slots.iter().position(Option::is_none).unwrap_or_else(|| {
            let unused = self.slots.iter().enumerate().filter(|(_, s)| s.is_some_and(|s| s.used < clock));
            unused.min_by_key(|(_, s)| s.map(|s| (s.key.is_some(), s.used))).map_or(0, |(i, _)| i)
        });
        let offset = 4 * (i * self.slot_floats) as u64;
        ctx.write_buffer(self.pool.buffer(self.data), offset, bytemuck::cast_slice(&values()));
        self.slots[i] = Some(Slot { key, floats, used: clock });
        i
    }

    /// The arena bound whole.
    pub fn bind(&self) -> Bind<'_> {
        self.pool.whole(self.data)
    }

    /// The arena's buffer (for copies into or out of a slot).
    pub fn buffer(&self) -> &wgpu::Buffer {
        self.pool.buffer(self.data)
    }
}
