//! The feature maps L_f keeps on the device: equal slots in one storage buffer (one binding),
//! each holding one view's `[H'][W'][C]` f32 map under the caller's key, evicted least recently
//! used. A view's maps are uploaded on first use and whenever they were evicted.

use gs_features::FeatureMap;
use gs_gpu::{Bind, BufId, BufferPool, GpuContext, ShrinkPolicy};

/// How much device memory the arena holds by default (bytes), at most one storage binding.
pub(super) const ARENA_BYTES: u64 = 1 << 30;

#[derive(Debug, Clone, Copy)]
struct Slot {
    key: u64,
    floats: usize,
    used: u64,
}

/// The arena: its own pool (never shrunk by another frame's policy), slot size and contents.
pub(super) struct Arena {
    pool: BufferPool,
    maps: BufId,
    /// The budget in bytes.
    bytes: u64,
    slot_floats: usize,
    slots: Vec<Option<Slot>>,
    clock: u64,
}

impl Arena {
    pub(super) fn new(ctx: &GpuContext, bytes: u64) -> Self {
        let mut pool = BufferPool::new(ctx, ShrinkPolicy::default());
        let maps = pool.add_storage("feature arena");
        Self { pool, maps, bytes, slot_floats: 0, slots: Vec::new(), clock: 0 }
    }

    /// The offsets (in floats) of `maps` (key, map) in the arena, in order, uploading those
    /// not held; `None` when they cannot all be held at once within one binding.
    pub(super) fn place(&mut self, ctx: &GpuContext, maps: &[(u64, &FeatureMap)]) -> Option<Vec<u32>> {
        let floats = |m: &FeatureMap| m.width() * m.height() * m.channels();
        let largest = maps.iter().map(|(_, m)| floats(m)).max()?;
        let mut keys: Vec<u64> = maps.iter().map(|(k, _)| *k).collect();
        keys.sort_unstable();
        keys.dedup();
        if largest > self.slot_floats || self.slots.len() < keys.len() {
            self.resize(ctx, largest.max(self.slot_floats), keys.len())?;
        }
        self.clock += 1;
        let mut offsets = Vec::with_capacity(maps.len());
        for &(key, map) in maps {
            let slot = self.slot_of(ctx, key, map, floats(map));
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
        if count < needed || (count * slot_floats) > u32::MAX as usize {
            return None;
        }
        self.pool.ensure(self.maps, slot_bytes * count as u64);
        self.slot_floats = slot_floats;
        self.slots = vec![None; count];
        Some(())
    }

    /// The slot holding `key` (uploading `map` into the least recently used slot when not held).
    fn slot_of(&mut self, ctx: &GpuContext, key: u64, map: &FeatureMap, floats: usize) -> usize {
        let clock = self.clock;
        if let Some(i) = self.slots.iter().position(|s| s.is_some_and(|s| s.key == key && s.floats == floats)) {
            self.slots[i] = Some(Slot { key, floats, used: clock });
            return i;
        }
        // A free slot, else the least recently used one not used by this call.
        let i = self.slots.iter().position(Option::is_none).unwrap_or_else(|| {
            let unused = self.slots.iter().enumerate().filter(|(_, s)| s.is_some_and(|s| s.used < clock));
            unused.min_by_key(|(_, s)| s.map_or(0, |s| s.used)).map_or(0, |(i, _)| i)
        });
        let offset = 4 * (i * self.slot_floats) as u64;
        ctx.write_buffer(self.pool.buffer(self.maps), offset, bytemuck::cast_slice(&map.to_f32_vec()));
        self.slots[i] = Some(Slot { key, floats, used: clock });
        i
    }

    /// The arena bound whole.
    pub(super) fn bind(&self) -> Bind<'_> {
        self.pool.whole(self.maps)
    }
}
