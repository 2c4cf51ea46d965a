//! Recording and submitting dispatches: per-dispatch uniform slots, bind groups, 2D splits.

use crate::{Bind, GpuContext, GpuError, Kernel, PassUniform, Result};
use std::num::NonZeroU64;

/// Bytes between two per-dispatch uniform slots (the usual dynamic-offset alignment).
pub const SLOT: u64 = 256;
/// Uniform slots, i.e. dispatches, per submission.
pub const MAX_SLOTS: usize = 512;

/// Splits `groups` workgroups into an (x, y) grid with x ≤ 65535 (WGSL side: `group_1d`).
pub fn grid(groups: u32) -> (u32, u32) {
    if groups <= 65535 {
        (groups.max(1), 1)
    } else {
        (65535, groups.div_ceil(65535))
    }
}

/// A command encoder plus the per-dispatch uniform slots written at its submission.
pub struct Encoder {
    /// The wgpu encoder (for copies and clears between dispatches).
    pub encoder: wgpu::CommandEncoder,
    slots: Vec<PassUniform>,
}

/// Owns the frame uniform (binding 0) and the pass-uniform slots (binding 1) of its kernels,
/// and records their dispatches. One per kernel family (a rasterizer, a loss), sharing one
/// [`GpuContext`].
pub struct Dispatcher {
    device: wgpu::Device,
    queue: wgpu::Queue,
    ledger: crate::ledger::Ledger,
    frame: wgpu::Buffer,
    pass: wgpu::Buffer,
}

impl std::fmt::Debug for Dispatcher {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(
            f,
            "Dispatcher(frame uniform of {} bytes)",
            self.frame.size()
        )
    }
}

impl Dispatcher {
    /// A dispatcher whose frame uniform holds `frame_bytes` (e.g. the size of a
    /// [`WgslStruct`](crate::WgslStruct); at least 16).
    pub fn new(ctx: &GpuContext, frame_bytes: u64) -> Self {
        let uniform = |label, size| {
            ctx.device().create_buffer(&wgpu::BufferDescriptor {
                label: Some(label),
                size,
                usage: wgpu::BufferUsages::UNIFORM | wgpu::BufferUsages::COPY_DST,
                mapped_at_creation: false,
            })
        };
        Self {
            ledger: ctx.ledger().clone(),
            device: ctx.device().clone(),
            queue: ctx.queue().clone(),
            frame: uniform("frame", frame_bytes.max(16).next_multiple_of(16)),
            pass: uniform("pass", SLOT * MAX_SLOTS as u64),
        }
    }

    /// Writes the frame uniform (seen by every dispatch submitted after this call).
    pub fn write_frame<T: bytemuck::Pod>(&self, value: &T) {
        self.ledger.wrote(std::mem::size_of::<T>() as u64);
        self.queue
            .write_buffer(&self.frame, 0, bytemuck::bytes_of(value));
    }

    /// A new encoder.
    pub fn encoder(&self) -> Encoder {
        Encoder {
            encoder: self
                .device
                .create_command_encoder(&wgpu::CommandEncoderDescriptor { label: None }),
            slots: Vec::new(),
        }
    }

    /// Records one dispatch of `kernel` with storage bindings `binds` (slots 2..) and `groups`
    /// workgroups; fails when the encoder has no uniform slot left (see
    /// [`make_room`](Self::make_room)).
    pub fn dispatch(
        &self,
        enc: &mut Encoder,
        kernel: &Kernel,
        binds: &[Bind],
        pass: PassUniform,
        groups: (u32, u32),
    ) -> Result<()> {
        if enc.slots.len() >= MAX_SLOTS {
            return Err(GpuError::TooManyDispatches(MAX_SLOTS));
        }
        let slot = enc.slots.len();
        enc.slots.push(PassUniform { unit: 1.0, ..pass });
        let mut entries = vec![
            wgpu::BindGroupEntry {
                binding: 0,
                resource: self.frame.as_entire_binding(),
            },
            wgpu::BindGroupEntry {
                binding: 1,
                resource: wgpu::BindingResource::Buffer(wgpu::BufferBinding {
                    buffer: &self.pass,
                    offset: 0,
                    size: NonZeroU64::new(std::mem::size_of::<PassUniform>() as u64),
                }),
            },
        ];
        for (k, b) in binds.iter().enumerate() {
            entries.push(wgpu::BindGroupEntry {
                binding: 2 + k as u32,
                resource: wgpu::BindingResource::Buffer(wgpu::BufferBinding {
                    buffer: b.buf,
                    offset: b.offset,
                    size: NonZeroU64::new(b.size),
                }),
            });
        }
        let bg = self.device.create_bind_group(&wgpu::BindGroupDescriptor {
            label: None,
            layout: &kernel.layout,
            entries: &entries,
        });
        let mut cp = enc
            .encoder
            .begin_compute_pass(&wgpu::ComputePassDescriptor::default());
        cp.set_pipeline(&kernel.pipeline);
        cp.set_bind_group(0, &bg, &[(slot as u64 * SLOT) as u32]);
        cp.dispatch_workgroups(groups.0, groups.1, 1);
        Ok(())
    }

    /// One thread per element: `pass.n` threads in workgroups of 256 (nothing when 0).
    pub fn dispatch_1d(
        &self,
        enc: &mut Encoder,
        kernel: &Kernel,
        binds: &[Bind],
        pass: PassUniform,
    ) -> Result<()> {
        if pass.n == 0 {
            return Ok(());
        }
        self.dispatch(enc, kernel, binds, pass, grid(pass.n.div_ceil(256)))
    }

    /// Submits `enc` and starts a new encoder when fewer than `k` uniform slots are left (the
    /// recorded dispatches keep their order across submissions).
    pub fn make_room(&self, enc: &mut Encoder, k: usize) {
        if enc.slots.len() + k > MAX_SLOTS {
            let full = std::mem::replace(enc, self.encoder());
            self.submit(full);
        }
    }

    /// Writes the uniform slots and submits (returns at once; a readback waits).
    pub fn submit(&self, enc: Encoder) {
        if !enc.slots.is_empty() {
            let mut bytes = vec![0u8; enc.slots.len() * SLOT as usize];
            for (k, s) in enc.slots.iter().enumerate() {
                let o = k * SLOT as usize;
                bytes[o..o + std::mem::size_of::<PassUniform>()]
                    .copy_from_slice(bytemuck::bytes_of(s));
            }
            self.ledger.wrote(bytes.len() as u64);
            self.queue.write_buffer(&self.pass, 0, &bytes);
        }
        self.ledger.submitted();
        self.queue.submit(Some(enc.encoder.finish()));
    }
}
