//! Exclusive prefix sum of u32 on the device, in place, multi-level.

use crate::{
    Bind, Binding, BufId, BufferPool, Dispatcher, Encoder, GpuContext, GpuError, Kernel, PassUniform,
    Result, grid,
};

/// Elements per scan / radix-sort block (one workgroup).
pub(crate) const BLOCK: u32 = 1024;
/// The workgroup scan snippet shared with the radix scatter.
pub(crate) const BLOCK_SCAN: &str = include_str!("wgsl/block_scan.wgsl");
const SCAN: &str = include_str!("wgsl/scan.wgsl");
const BINDINGS: [Binding<'static>; 2] = [
    Binding::write("data", "array<u32>"),
    Binding::write("sums", "array<u32>"),
];

/// An in-place exclusive prefix sum of u32 (wrapping), 1024 elements per workgroup: block
/// totals are reduced, scanned recursively, and added back. Its scratch lives in the pool it
/// was created with.
#[derive(Debug)]
pub struct PrefixScan {
    reduce: Kernel,
    apply: Kernel,
    tmp: BufId,
}

impl PrefixScan {
    /// Compiles the kernels and adds the scratch buffer to `pool`.
    pub fn new(ctx: &GpuContext, pool: &mut BufferPool) -> Result<Self> {
        let src = [BLOCK_SCAN, SCAN];
        Ok(Self {
            reduce: Kernel::new(ctx, "scan_reduce", &src, &BINDINGS)?,
            apply: Kernel::new(ctx, "scan_apply", &src, &BINDINGS)?,
            tmp: pool.add_storage("scan_tmp"),
        })
    }

    /// Bytes of scratch for `n` elements (all levels).
    fn tmp_bytes(n: u64) -> u64 {
        let mut total = 256;
        let mut m = n;
        while m > BLOCK as u64 {
            m = m.div_ceil(BLOCK as u64);
            total += (m * 4).next_multiple_of(256);
        }
        total
    }

    /// Makes room in the scratch for scans of up to `n` elements (call in every frame that
    /// scans, before binding anything of the pool).
    pub fn reserve(&self, pool: &mut BufferPool, n: u64) {
        pool.ensure(self.tmp, Self::tmp_bytes(n));
    }

    /// Records the exclusive scan of the first `n` u32 of `data`; an error, before anything is
    /// recorded, when the scratch was not reserved for `n`.
    pub fn encode(
        &self,
        disp: &Dispatcher,
        enc: &mut Encoder,
        pool: &BufferPool,
        data: Bind,
        n: u32,
    ) -> Result<()> {
        let (need, have) = (Self::tmp_bytes(n as u64), pool.capacity(self.tmp));
        if need > have {
            return Err(GpuError::NotReserved { label: "scan_tmp", need, have });
        }
        self.level(disp, enc, pool, data, n, 0)
    }

    fn level(
        &self,
        disp: &Dispatcher,
        enc: &mut Encoder,
        pool: &BufferPool,
        data: Bind,
        n: u32,
        tmp_off: u64,
    ) -> Result<()> {
        let nb = n.div_ceil(BLOCK);
        let pass = PassUniform {
            n,
            nb: nb.max(1),
            ..Default::default()
        };
        if nb <= 1 {
            let dummy = pool.range(self.tmp, tmp_off, 4);
            return disp.dispatch(enc, &self.apply, &[data, dummy], pass, (1, 1));
        }
        let sums = pool.range(self.tmp, tmp_off, nb as u64 * 4);
        disp.dispatch(enc, &self.reduce, &[data, sums], pass, grid(nb))?;
        let next = tmp_off + (nb as u64 * 4).next_multiple_of(256);
        self.level(disp, enc, pool, sums, nb, next)?;
        let pass = PassUniform { mode: 1, ..pass };
        disp.dispatch(enc, &self.apply, &[data, sums], pass, grid(nb))
    }
}
