//! The host–device traffic of one device (every clone of a [`crate::GpuContext`] and its
//! dispatchers count into one ledger): how often the host waited for a readback, the bytes
//! read back and written, and the command submissions. A training run reads it around each
//! iteration, so "each iteration reads back only a few scalars" is a measured figure, also
//! on lavapipe, where times say nothing about a GPU (docs/architecture.md §GPU).

use std::sync::Arc;
use std::sync::atomic::{AtomicU64, Ordering};

/// Counts of host–device traffic: a snapshot, or the difference of two.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub struct Transfers {
    /// Readbacks the host waited for (each one a round trip to the device).
    pub syncs: u64,
    /// Bytes read back to the host.
    pub bytes_down: u64,
    /// Bytes written to the device (uploads and uniforms).
    pub bytes_up: u64,
    /// Command buffers submitted.
    pub submits: u64,
}

impl std::ops::Sub for Transfers {
    type Output = Transfers;
    fn sub(self, o: Transfers) -> Transfers {
        Transfers {
            syncs: self.syncs - o.syncs,
            bytes_down: self.bytes_down - o.bytes_down,
            bytes_up: self.bytes_up - o.bytes_up,
            submits: self.submits - o.submits,
        }
    }
}

impl std::ops::AddAssign for Transfers {
    fn add_assign(&mut self, o: Transfers) {
        self.syncs += o.syncs;
        self.bytes_down += o.bytes_down;
        self.bytes_up += o.bytes_up;
        self.submits += o.submits;
    }
}

/// The shared counters behind [`Transfers`].
#[derive(Debug, Default, Clone)]
pub(crate) struct Ledger(Arc<[AtomicU64; 4]>);

impl Ledger {
    /// A readback of `bytes` requested (the wait, if the host waits, counts apart).
    pub(crate) fn read_back(&self, bytes: u64) {
        self.0[1].fetch_add(bytes, Ordering::Relaxed);
    }

    /// The host waited for the device.
    pub(crate) fn waited(&self) {
        self.0[0].fetch_add(1, Ordering::Relaxed);
    }

    pub(crate) fn wrote(&self, bytes: u64) {
        self.0[2].fetch_add(bytes, Ordering::Relaxed);
    }

    pub(crate) fn submitted(&self) {
        self.0[3].fetch_add(1, Ordering::Relaxed);
    }

    pub(crate) fn snapshot(&self) -> Transfers {
        let v = |k: usize| self.0[k].load(Ordering::Relaxed);
        Transfers { syncs: v(0), bytes_down: v(1), bytes_up: v(2), submits: v(3) }
    }
}
