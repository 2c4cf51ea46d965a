//! Per-view constants kept on the device between calls (docs/architecture.md §GPU): equal
//! slots in one storage buffer (one binding), each holding one `f32` array under the caller's
//! key. The buffer starts at a few slots and doubles when full (the arrays held are copied on
//! the device), up to the budget; then the least recently used array is evicted. An array is
//! uploaded on first use and whenever it was evicted; an array without a key (one call's
//! input) is uploaded every call into a slot no other array of that call uses.
//!
//! The caller's contract: one key names one content for the arena's life (e.g. a view's photo
//! at one resolution), or, placed with [`Arena::place_versions`], one content per version (e.g. a
//! view's depth rendered at one iteration): a new version replaces the old one in its slot. A
//! slot placed with [`Arena::place_filled`] is written by the caller on the device (a kernel's
//! output) and then held like an uploaded version; [`Arena::read_held`] brings such arrays back.
//! The arena checks the length and the version, not the values.

use crate::{Bind, GpuContext};
use std::borrow::Cow;

/// A key: the caller's name of a view (or anything constant) and the part of it (two arrays of
/// one view, e.g. its photo and its edge guide, share the first).
pub type ArenaKey = (u64, u32);

#[derive(Debug, Clone, Copy)]
struct Slot {
    /// `None` for an array of one call.
    key: Option<ArenaKey>,
    floats: usize,
    /// The caller's version of the content (0 for [`Arena::place`]).
    version: u64,
    used: u64,
}

/// The arena: its buffer, slot size and contents.
pub struct Arena {
    label: &'static str,
    /// 4 bytes until the first array arrives.
    data: wgpu::Buffer,
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

/// What goes into an item's slot when the arena does not hold it.
enum Fill<'d> {
    /// These values, uploaded; held under the item's key.
    Values(Cow<'d, [f32]>),
    /// The caller's on the device, for one call: not held under the key.
    OneCall,
    /// The caller's on the device, held under the key at the item's version.
    Held,
}

/// Slots an arena starts with (it doubles when full, up to its budget).
const FIRST_SLOTS: usize = 8;

impl Arena {
    /// An empty arena holding at most `bytes` (and one storage binding of the device it is
    /// used on); it allocates as its arrays arrive.
    pub fn new(ctx: &GpuContext, label: &'static str, bytes: u64) -> Self {
        Self { label, data: storage(ctx, label, 4), bytes, slot_floats: 0, slots: Vec::new(), clock: 0 }
    }

    /// The offsets (in floats) of the arrays `items` names (key, length), in order, uploading
    /// those not held (`upload(i)` gives item i's values, asked only when it is uploaded);
    /// `None` when they cannot all be held at once within the budget and one binding.
    pub fn place<'d>(&mut self, ctx: &GpuContext, items: &[(Option<ArenaKey>, usize)], upload: impl Fn(usize) -> Cow<'d, [f32]>) -> Option<Vec<u32>> {
        self.place_with(ctx, items, |i| Some(upload(i)))
    }

    /// [`Arena::place`] where `upload(i)` may be `None`: the caller fills item i's slot itself
    /// on the device (a copy from a [`crate::DeviceImage`]) before its passes read it. Such an
    /// item is never held under a key: it is placed like an item of one call.
    pub fn place_with<'d>(&mut self, ctx: &GpuContext, items: &[(Option<ArenaKey>, usize)], upload: impl Fn(usize) -> Option<Cow<'d, [f32]>>) -> Option<Vec<u32>> {
        self.place_inner(ctx, items, &vec![0; items.len()], |i| upload(i).map_or(Fill::OneCall, Fill::Values))
    }

    /// [`Arena::place`] of arrays whose content changes under one key: item i is held as
    /// `versions[i]`, and a key held at another version is uploaded again into its own slot.
    pub fn place_versions<'d>(&mut self, ctx: &GpuContext, items: &[(Option<ArenaKey>, usize)], versions: &[u64], upload: impl Fn(usize) -> Cow<'d, [f32]>) -> Option<Vec<u32>> {
        if versions.len() != items.len() {
            return None;
        }
        self.place_inner(ctx, items, versions, |i| Fill::Values(upload(i)))
    }

    /// The offset of a slot held under `key` at `version` whose `floats` values the caller
    /// writes on the device before anything reads them (e.g. a kernel copying a rendered
    /// depth in): from then on it is held like an uploaded array of that version. `None` as
    /// [`Arena::place`].
    pub fn place_filled(&mut self, ctx: &GpuContext, key: ArenaKey, floats: usize, version: u64) -> Option<u32> {
        Some(self.place_inner(ctx, &[(Some(key), floats)], &[version], |_| Fill::Held)?[0])
    }

    /// Whether the arena holds `floats` values under `key` at `version`.
    pub fn holds(&self, key: ArenaKey, floats: usize, version: u64) -> bool {
        self.holding(Some(key), floats, version).is_some()
    }

    /// Drops the array held under `key`, whatever its version (e.g. one whose content the
    /// caller could not provide): its next use uploads or fills it again.
    pub fn forget(&mut self, key: ArenaKey) {
        if let Some(i) = self.keyed(Some(key)) {
            self.slots[i] = None;
        }
    }

    /// How many arrays of `floats` values the arena can hold at once, within its budget and
    /// one binding: a caller that never names more keys than that is never evicted.
    pub fn capacity(&self, ctx: &GpuContext, floats: usize) -> usize {
        let slot_bytes = 4 * floats.max(1) as u64;
        usize::try_from(ctx.max_storage_binding().min(self.bytes) / slot_bytes).unwrap_or(usize::MAX)
    }

    /// The values held under each `(key, floats, version)` of `items` (`None` where the arena
    /// does not hold it), copied out of their slots together: one submission, one wait.
    pub fn read_held(&self, ctx: &GpuContext, items: &[(ArenaKey, usize, u64)]) -> crate::Result<Vec<Option<Vec<f32>>>> {
        let slots: Vec<Option<usize>> = items.iter().map(|&(key, floats, version)| self.holding(Some(key), floats, version)).collect();
        let total: u64 = items.iter().zip(&slots).filter(|(_, s)| s.is_some()).map(|(&(_, floats, _), _)| 4 * floats as u64).sum();
        if total == 0 {
            return Ok(vec![None; items.len()]);
        }
        let staging = ctx.device().create_buffer(&wgpu::BufferDescriptor {
            label: Some(self.label),
            size: total,
            usage: wgpu::BufferUsages::MAP_READ | wgpu::BufferUsages::COPY_DST,
            mapped_at_creation: false,
        });
        let mut enc = ctx.device().create_command_encoder(&wgpu::CommandEncoderDescriptor { label: Some(self.label) });
        let mut at = 0u64;
        for (&(_, floats, _), slot) in items.iter().zip(&slots) {
            if let Some(i) = slot {
                enc.copy_buffer_to_buffer(&self.data, 4 * (i * self.slot_floats) as u64, &staging, at, 4 * floats as u64);
                at += 4 * floats as u64;
            }
        }
        ctx.ledger().submitted();
        ctx.queue().submit(Some(enc.finish()));
        let bytes = ctx.read_buffer(&staging, total)?;
        let values: Vec<f32> = bytemuck::pod_collect_to_vec(&bytes);
        let mut at = 0usize;
        Ok(items
            .iter()
            .zip(slots)
            .map(|(&(_, floats, _), slot)| {
                slot.map(|_| {
                    at += floats;
                    values[at - floats..at].to_vec()
                })
            })
            .collect())
    }

    fn place_inner<'d>(&mut self, ctx: &GpuContext, items: &[(Option<ArenaKey>, usize)], versions: &[u64], upload: impl Fn(usize) -> Fill<'d>) -> Option<Vec<u32>> {
        let largest = items.iter().map(|&(_, floats)| floats).max()?;
        let mut keyed: Vec<ArenaKey> = items.iter().filter_map(|&(k, _)| k).collect();
        keyed.sort_unstable();
        keyed.dedup();
        let needed = keyed.len() + items.iter().filter(|(k, _)| k.is_none()).count();
        if largest > self.slot_floats {
            // Larger arrays than the slots: new slots, everything held dropped.
            self.slots.clear();
            self.slot_floats = largest;
            let fit = self.fit(ctx);
            if fit < needed {
                self.slot_floats = 0;
                return None;
            }
            self.grow(ctx, needed.max(FIRST_SLOTS).min(fit))?;
        }
        // A key held at another version reuses its slot: it needs no free one.
        let missing = items.iter().filter(|&&(k, _)| self.keyed(k).is_none()).count();
        let free = self.slots.iter().filter(|s| s.is_none()).count();
        if self.slots.len() < needed || missing > free {
            // Room for this call's arrays first by growing (doubling, within the budget), then
            // by evicting.
            let want = (2 * self.slots.len()).max(self.slots.len() + missing - free.min(missing)).max(needed);
            let fit = self.fit(ctx);
            if want.min(fit) < needed {
                return None;
            }
            if self.slots.len() < fit {
                self.grow(ctx, want.min(fit))?;
            }
        }
        self.clock += 1;
        let mut offsets = Vec::with_capacity(items.len());
        for (i, (&(key, floats), &version)) in items.iter().zip(versions).enumerate() {
            let slot = self.slot_of(ctx, (key, floats, version), || upload(i));
            offsets.push(u32::try_from(slot * self.slot_floats).ok()?);
        }
        Some(offsets)
    }

    /// How many slots of the current size the budget and one binding hold.
    fn fit(&self, ctx: &GpuContext) -> usize {
        let slot_bytes = 4 * self.slot_floats.max(1) as u64;
        let count = ctx.max_storage_binding().min(self.bytes) / slot_bytes;
        usize::try_from(count).unwrap_or(usize::MAX).min(u32::MAX as usize / self.slot_floats.max(1))
    }

    /// Grows to `count` slots (at least those held), copying the arrays held on the device;
    /// `None` when that many do not fit.
    fn grow(&mut self, ctx: &GpuContext, count: usize) -> Option<()> {
        let count = count.max(self.slots.len());
        if count > self.fit(ctx) {
            return None;
        }
        let bytes = 4 * (count * self.slot_floats) as u64;
        let buffer = storage(ctx, self.label, bytes);
        if self.slots.iter().any(Option::is_some) {
            // Queue order: writes queued so far land in the old buffer before this copy.
            let mut enc = ctx.device().create_command_encoder(&wgpu::CommandEncoderDescriptor { label: Some(self.label) });
            let held = 4 * (self.slots.len() * self.slot_floats) as u64;
            enc.copy_buffer_to_buffer(&self.data, 0, &buffer, 0, held.min(bytes));
            ctx.ledger().submitted();
            ctx.queue().submit(Some(enc.finish()));
        }
        self.data = buffer;
        self.slots.resize(count, None);
        Some(())
    }

    /// The slot holding `key` at `version`, else the slot `values` is uploaded into: the one
    /// holding `key` at another version or length, a free one, else one that this call has not
    /// used, an earlier call's unkeyed array first, then the least recently used.
    fn slot_of<'d>(&mut self, ctx: &GpuContext, (key, floats, version): (Option<ArenaKey>, usize, u64), values: impl FnOnce() -> Fill<'d>) -> usize {
        let clock = self.clock;
        if let Some(i) = self.holding(key, floats, version) {
            self.slots[i] = Some(Slot { key, floats, version, used: clock });
            return i;
        }
        let i = self.keyed(key).or_else(|| self.slots.iter().position(Option::is_none)).unwrap_or_else(|| {
            let unused = self.slots.iter().enumerate().filter(|(_, s)| s.is_some_and(|s| s.used < clock));
            unused.min_by_key(|(_, s)| s.map(|s| (s.key.is_some(), s.used))).map_or(0, |(i, _)| i)
        });
        let offset = 4 * (i * self.slot_floats) as u64;
        let key = match values() {
            Fill::Values(v) => {
                ctx.write_buffer(&self.data, offset, bytemuck::cast_slice(&v));
                key
            }
            Fill::Held => key,
            // Filled by the caller: not held under the key, whose content it may not be.
            Fill::OneCall => None,
        };
        self.slots[i] = Some(Slot { key, floats, version, used: clock });
        i
    }

    /// The slot holding the array `key` names with `floats` values at `version` (never one
    /// without a key).
    fn holding(&self, key: Option<ArenaKey>, floats: usize, version: u64) -> Option<usize> {
        self.keyed(key).filter(|&i| self.slots[i].is_some_and(|s| s.floats == floats && s.version == version))
    }

    /// The slot held under `key`, whatever its version (never one without a key).
    fn keyed(&self, key: Option<ArenaKey>) -> Option<usize> {
        let key = key?;
        self.slots.iter().position(|s| s.is_some_and(|s| s.key == Some(key)))
    }

    /// The arena bound whole.
    pub fn bind(&self) -> Bind<'_> {
        Bind::whole(&self.data)
    }

    /// The arena's buffer (for copies into or out of a slot).
    pub fn buffer(&self) -> &wgpu::Buffer {
        &self.data
    }
}

/// A storage buffer of `bytes` (at least 4) that copies may read and write.
fn storage(ctx: &GpuContext, label: &'static str, bytes: u64) -> wgpu::Buffer {
    let usage = wgpu::BufferUsages::STORAGE | wgpu::BufferUsages::COPY_DST | wgpu::BufferUsages::COPY_SRC;
    ctx.device().create_buffer(&wgpu::BufferDescriptor { label: Some(label), size: bytes.max(4), usage, mapped_at_creation: false })
}
