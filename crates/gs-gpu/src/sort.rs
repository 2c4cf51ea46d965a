//! Stable LSD radix sort of (u32 key, u32 value) pairs on the device.

use crate::scan::{BLOCK, BLOCK_SCAN};
use crate::{
    Bind, Binding, BufId, BufferPool, Dispatcher, Encoder, GpuContext, GpuError, Kernel, PassUniform,
    PrefixScan, Result, grid,
};

/// A stable LSD radix sort, 4 bits a pass: per pass a per-block digit histogram
/// (`radix_count`), its exclusive [`PrefixScan`] (digit-major, so the scan yields global
/// offsets) and a stable scatter (`radix_scatter`). Equal keys keep their input order.
#[derive(Debug)]
pub struct RadixSort {
    count: Kernel,
    scatter: Kernel,
    hist: BufId,
    scan: PrefixScan,
}

impl RadixSort {
    /// Compiles the kernels and adds the histogram and scan scratch to `pool`.
    pub fn new(ctx: &GpuContext, pool: &mut BufferPool) -> Result<Self> {
        let count = Kernel::new(
            ctx,
            "radix_count",
            &[include_str!("wgsl/radix_count.wgsl")],
            &[
                Binding::read("keys", "array<u32>"),
                Binding::write("hist", "array<u32>"),
            ],
        )?;
        let u = "array<u32>";
        let scatter = Kernel::new(
            ctx,
            "radix_scatter",
            &[BLOCK_SCAN, include_str!("wgsl/radix_scatter.wgsl")],
            &[
                Binding::read("keys_in", u),
                Binding::read("vals_in", u),
                Binding::read("hist", u),
                Binding::write("keys_out", u),
                Binding::write("vals_out", u),
            ],
        )?;
        Ok(Self {
            count,
            scatter,
            hist: pool.add_storage("radix_hist"),
            scan: PrefixScan::new(ctx, pool)?,
        })
    }

    /// The prefix scan the sort uses (its owner may scan with it too).
    pub fn prefix_scan(&self) -> &PrefixScan {
        &self.scan
    }

    /// Makes room in the scratch for sorts of up to `n` pairs (call in every frame that
    /// sorts, before binding anything of the pool).
    pub fn reserve(&self, pool: &mut BufferPool, n: u64) {
        let blocks = n.div_ceil(BLOCK as u64);
        pool.ensure(self.hist, 16 * (blocks + 1) * 4);
        self.scan.reserve(pool, 16 * blocks + 1);
    }

    /// Records the sort of `n` pairs over the low `bits` bits of the keys, ping-ponging
    /// between the (keys, values) buffers `[a, b]` (`a` the input); returns true when the
    /// result ends in `b` (an odd number of 4-bit passes).
    pub fn encode(
        &self,
        disp: &Dispatcher,
        enc: &mut Encoder,
        pool: &BufferPool,
        [a, b]: [(Bind, Bind); 2],
        n: u32,
        bits: u32,
    ) -> Result<bool> {
        let nb = n.div_ceil(BLOCK);
        let mut in_b = false;
        if n == 0 {
            return Ok(false);
        }
        let (need, have) = (16 * nb as u64 * 4, pool.capacity(self.hist));
        if need > have {
            return Err(GpuError::NotReserved { label: "radix_hist", need, have });
        }
        for p in 0..bits.div_ceil(4) {
            let ((ki, vi), (ko, vo)) = if in_b { (b, a) } else { (a, b) };
            let pass = PassUniform {
                n,
                shift: 4 * p,
                nb,
                ..Default::default()
            };
            let hist = pool.range(self.hist, 0, 16 * nb as u64 * 4);
            disp.dispatch(enc, &self.count, &[ki, hist], pass, grid(nb))?;
            self.scan.encode(disp, enc, pool, hist, 16 * nb)?;
            disp.dispatch(enc, &self.scatter, &[ki, vi, hist, ko, vo], pass, grid(nb))?;
            in_b = !in_b;
        }
        Ok(in_b)
    }
}
