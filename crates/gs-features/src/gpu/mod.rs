//! VGG16's trunk on the device (behind the `wgpu` feature), the twin of [`Vgg16`]'s CPU
//! forward: the same checked, normalised input, each 3×3 convolution (+ bias + ReLU) as one
//! dispatch of `conv.wgsl`, each 2×2 max pool as one of `pool.wgsl`, on padded HWC tensors
//! that stay on the device between layers; only the requested activation comes back, and the
//! map is finished on the host as [`Vgg16::extract_with`] finishes it (channel projection,
//! storage precision). The convolutions sum in another order than the host's GEMM, so the
//! maps agree to f32 rounding (the tolerance is in `tests/vgg_gpu.rs`); the pools are exact.
//! Each sum has one fixed order: one image gives one map on one device (docs/method.md §L_f,
//! docs/architecture.md §GPU).
//!
//! The weights go up once, when the extractor is made. An image whose activations do not fit
//! one storage binding of the device is extracted on the host (the reference).

use crate::conv::Padded;
use crate::error::{FeatureError, Result};
use crate::map::FeatureMap;
use crate::net::{ExtractOptions, FeatureLevel, Vgg16, finish_map};
use gs_core::Image;
use gs_gpu::{Binding, BufId, BufferPool, Dispatcher, GpuContext, Kernel, PassUniform, ShrinkPolicy};

/// The convolution's storage bindings, by name (slot order).
const CONV_BINDINGS: [Binding<'static>; 4] = [
    Binding::read("act_in", "array<f32>"),
    Binding::read("weights", "array<vec4<f32>>"),
    Binding::read("bias", "array<vec4<f32>>"),
    Binding::write("act_out", "array<vec4<f32>>"),
];

/// The pool's storage bindings, by name (slot order).
const POOL_BINDINGS: [Binding<'static>; 2] =
    [Binding::read("act_below", "array<vec4<f32>>"), Binding::write("act_out", "array<vec4<f32>>")];

/// Output channels per invocation of either kernel (one `vec4<f32>`).
const LANES: usize = 4;

/// The whole WGSL source of the convolution kernel (for tests that parse what the device
/// compiles).
pub fn conv_kernel_source() -> String {
    gs_gpu::kernel_source(&[include_str!("conv.wgsl")], &CONV_BINDINGS)
}

/// The whole WGSL source of the pool kernel.
pub fn pool_kernel_source() -> String {
    gs_gpu::kernel_source(&[include_str!("pool.wgsl")], &POOL_BINDINGS)
}

fn gpu_error(e: gs_gpu::GpuError) -> FeatureError {
    FeatureError::Device(e.to_string())
}

/// One conv layer's weights on the device.
struct DeviceLayer {
    cin: usize,
    cout: usize,
    /// `[9·cin][cout / 4]` of `vec4<f32>`.
    weights: BufId,
    /// `[cout / 4]` of `vec4<f32>`.
    bias: BufId,
}

/// One step of the trunk as the device runs it.
#[derive(Debug, Clone, Copy, PartialEq)]
enum Op {
    /// Conv layer `k` on an `h × w` input.
    Conv { layer: usize, w: usize, h: usize },
    /// 2×2 max pool of an `h × w × c` input.
    Pool { w: usize, h: usize, c: usize },
}

/// The ops of `level` for a `width × height` input, and the padded float count of the
/// largest tensor among them (input and outputs).
fn plan(layers: &[(usize, usize)], level: FeatureLevel, width: usize, height: usize) -> (Vec<Op>, usize) {
    let (mut w, mut h) = (width, height);
    let mut ops = Vec::new();
    let mut largest = (w + 2) * (h + 2) * layers[0].0;
    for (layer, &(_, cout)) in layers.iter().enumerate().take(level.conv_layers()) {
        if layer == 2 || layer == 4 {
            ops.push(Op::Pool { w, h, c: layers[layer - 1].1 });
            (w, h) = (w / 2, h / 2);
        }
        ops.push(Op::Conv { layer, w, h });
        largest = largest.max((w + 2) * (h + 2) * cout);
    }
    (ops, largest)
}

/// The device executor of VGG16's trunk: its context, kernels and the weights on the device.
pub struct Vgg16Gpu {
    ctx: GpuContext,
    net: Vgg16,
    pool: BufferPool,
    disp: Dispatcher,
    conv: Kernel,
    max_pool: Kernel,
    layers: Vec<DeviceLayer>,
    /// The two activation buffers the layers write in turn.
    ping: [BufId; 2],
    staging: BufId,
}

impl std::fmt::Debug for Vgg16Gpu {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(f, "Vgg16Gpu({})", self.ctx.description())
    }
}

impl Vgg16Gpu {
    /// The trunk of `net` on `ctx`'s device: kernels compiled, every layer's weights uploaded.
    pub fn new(ctx: &GpuContext, net: &Vgg16) -> Result<Self> {
        let ctx = ctx.clone();
        let conv = Kernel::new(&ctx, "conv3x3", &[include_str!("conv.wgsl")], &CONV_BINDINGS).map_err(gpu_error)?;
        let max_pool = Kernel::new(&ctx, "max_pool2", &[include_str!("pool.wgsl")], &POOL_BINDINGS).map_err(gpu_error)?;
        // The weights stay for the extractor's life: the pool never shrinks them.
        let mut pool = BufferPool::new(&ctx, ShrinkPolicy::never());
        let mut layers = Vec::with_capacity(net.layers().len());
        for layer in net.layers() {
            let (weights, bias) = (pool.add_storage("vgg weights"), pool.add_storage("vgg bias"));
            for (id, values) in [(weights, layer.gemm_kernel()), (bias, layer.bias())] {
                let bytes: &[u8] = bytemuck::cast_slice(values);
                pool.ensure(id, bytes.len() as u64);
                ctx.write_buffer(pool.buffer(id), 0, bytes);
            }
            layers.push(DeviceLayer { cin: layer.cin, cout: layer.cout, weights, bias });
        }
        let ping = [pool.add_storage("vgg activation a"), pool.add_storage("vgg activation b")];
        let staging = pool.add_staging("vgg readback");
        let disp = Dispatcher::new(&ctx, 16);
        Ok(Self { ctx, net: net.clone(), pool, disp, conv, max_pool, layers, ping, staging })
    }

    /// The adapter, in words.
    pub fn adapter_description(&self) -> String {
        self.ctx.description()
    }

    /// F = f(I) at `level` with default options, on the device.
    pub fn extract(&mut self, image: &Image, level: FeatureLevel) -> Result<FeatureMap> {
        self.extract_with(image, &ExtractOptions::at(level))
    }

    /// [`Vgg16::extract_with`] on the device: the same input checks and errors, the same map
    /// layout, values within f32 rounding of the host's (`opts.algorithm` names a host
    /// algorithm and is not used here). Extracted on the host when the largest activation
    /// exceeds one storage binding of the device.
    pub fn extract_with(&mut self, image: &Image, opts: &ExtractOptions) -> Result<FeatureMap> {
        let input = self.net.input(image, opts)?;
        let shapes: Vec<(usize, usize)> = self.layers.iter().map(|l| (l.cin, l.cout)).collect();
        let (ops, largest) = plan(&shapes, opts.level, input.w, input.h);
        if 4 * largest as u64 > self.ctx.max_storage_binding() {
            return self.net.extract_with(image, opts);
        }
        let act = self.run(&input, &ops, 4 * largest as u64)?;
        finish_map(act, opts)
    }

    /// Uploads `input`, runs `ops` in one submission and reads the last activation back.
    fn run(&mut self, input: &Padded, ops: &[Op], largest_bytes: u64) -> Result<Padded> {
        for id in self.ping {
            self.pool.ensure(id, largest_bytes);
        }
        self.ctx.write_buffer(self.pool.buffer(self.ping[0]), 0, bytemuck::cast_slice(&input.data));
        let mut enc = self.disp.encoder();
        let mut shape = (input.w, input.h, input.c);
        self.ctx.push_error_scopes();
        for (k, op) in ops.iter().enumerate() {
            let (below, out) = (self.pool.buffer(self.ping[k % 2]), self.pool.buffer(self.ping[(k + 1) % 2]));
            let (pass, kernel, binds, next) = match *op {
                Op::Conv { layer, w, h } => {
                    let l = &self.layers[layer];
                    let binds = vec![gs_gpu::Bind::whole(below), self.pool.whole(l.weights), self.pool.whole(l.bias), gs_gpu::Bind::whole(out)];
                    (layer_pass(w, h, l.cin, l.cout), &self.conv, binds, (w, h, l.cout))
                }
                Op::Pool { w, h, c } => {
                    let binds = vec![gs_gpu::Bind::whole(below), gs_gpu::Bind::whole(out)];
                    (pool_pass(w, h, c), &self.max_pool, binds, (w / 2, h / 2, c))
                }
            };
            // Only the interior is written: the border of the output must be zero.
            enc.encoder.clear_buffer(out, 0, Some(4 * ((next.0 + 2) * (next.1 + 2) * next.2) as u64));
            self.disp.dispatch_1d(&mut enc, kernel, &binds, pass).map_err(gpu_error)?;
            shape = next;
        }
        let (w, h, c) = shape;
        let bytes = 4 * ((w + 2) * (h + 2) * c) as u64;
        self.pool.ensure(self.staging, bytes);
        let last = self.pool.buffer(self.ping[ops.len() % 2]);
        enc.encoder.copy_buffer_to_buffer(last, 0, self.pool.buffer(self.staging), 0, bytes);
        self.disp.submit(enc);
        self.ctx.pop_error_scopes().map_err(gpu_error)?;
        let data = self.ctx.read_mapped(self.pool.buffer(self.staging), bytes, bytemuck::pod_collect_to_vec::<u8, f32>).map_err(gpu_error)?;
        Ok(Padded { h, w, c, data })
    }
}

/// The pass constants of a conv layer on an `h × w` input (the names `conv.wgsl` reads).
fn layer_pass(w: usize, h: usize, cin: usize, cout: usize) -> PassUniform {
    let blocks = cout / LANES;
    PassUniform { n: (w * h * blocks) as u32, p1: w as u32, p3: cin as u32, mode: blocks as u32, ..Default::default() }
}

/// The pass constants of a 2×2 pool of an `h × w × c` input (the names `pool.wgsl` reads).
fn pool_pass(w: usize, h: usize, c: usize) -> PassUniform {
    let (ow, oh, blocks) = (w / 2, h / 2, c / LANES);
    PassUniform { n: (ow * oh * blocks) as u32, p1: ow as u32, p3: w as u32, mode: blocks as u32, ..Default::default() }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn kernels_parse_and_validate() {
        for src in [conv_kernel_source(), pool_kernel_source()] {
            gs_gpu::validate_kernel(&src).unwrap_or_else(|e| panic!("{e}"));
        }
    }

    #[test]
    fn the_plan_pools_where_the_host_does() {
        let shapes = [(3, 64), (64, 64), (64, 128), (128, 128), (128, 256), (256, 256), (256, 256)];
        let (ops, largest) = plan(&shapes, FeatureLevel::Conv2_2, 9, 7);
        assert_eq!(
            ops,
            [
                Op::Conv { layer: 0, w: 9, h: 7 },
                Op::Conv { layer: 1, w: 9, h: 7 },
                Op::Pool { w: 9, h: 7, c: 64 },
                Op::Conv { layer: 2, w: 4, h: 3 },
                Op::Conv { layer: 3, w: 4, h: 3 },
            ]
        );
        assert_eq!(largest, 11 * 9 * 64);
        let (ops, _) = plan(&shapes, FeatureLevel::Conv3_3, 9, 7);
        assert_eq!(ops.len(), 9);
        assert_eq!(ops[5], Op::Pool { w: 4, h: 3, c: 128 });
        assert_eq!(ops[8], Op::Conv { layer: 6, w: 2, h: 1 });
    }
}
