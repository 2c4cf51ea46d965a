//! Compute kernels under one bind-group convention, their WGSL composed from snippets.

use crate::{GpuContext, GpuError, Result, WgslStruct};

crate::wgsl_struct! {
    /// Per-dispatch constants, one 256-byte slot of the dispatcher's uniform buffer per
    /// dispatch (binding 1, dynamic offset). The meaning of each member is the kernel's; the
    /// names are those gs-gpu's own kernels use.
    pub struct PassUniform as "Pass" {
        /// Number of elements (or blocks) this dispatch covers.
        n: u32,
        /// Radix digit shift (or a window start).
        shift: u32,
        /// Number of 1024-element blocks of a radix-sort / scan level (or a window end).
        nb: u32,
        /// First element of a chunked dispatch.
        base: u32,
        /// Kernel-specific mode bits (scan: 1 = add the scanned block sums).
        mode: u32,
        /// Free for the kernel.
        p1: u32,
        /// Free for the kernel.
        p2: u32,
        /// Free for the kernel.
        p3: u32,
        /// 1.0, written by the dispatcher whatever the caller gives: a value the shader
        /// compiler cannot know, which the prelude's compensated sums multiply their terms by
        /// so that no optimiser cancels their error terms as algebra (Mesa's does).
        unit: f32,
    }
}

const PRELUDE: &str = include_str!("wgsl/prelude.wgsl");

/// A storage buffer of a kernel (slot 2 + its index in the table): the WGSL declaration and
/// the bind-group layout entry both come from it.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Binding<'a> {
    /// The variable's name in WGSL.
    pub name: &'a str,
    /// Its WGSL type, e.g. `array<u32>` or `array<atomic<f32>>`.
    pub ty: &'a str,
    /// `var<storage, read>` rather than `var<storage, read_write>`.
    pub read_only: bool,
}

impl<'a> Binding<'a> {
    /// A read-only storage buffer.
    pub const fn read(name: &'a str, ty: &'a str) -> Self {
        Self {
            name,
            ty,
            read_only: true,
        }
    }

    /// A read-write storage buffer.
    pub const fn write(name: &'a str, ty: &'a str) -> Self {
        Self {
            name,
            ty,
            read_only: false,
        }
    }
}

/// The full WGSL of a kernel: the gs-gpu prelude (`Pass`, `pass_`, `Ids`, `linear_group`,
/// `group_1d`, `thread_1d`), the storage declarations of `bindings`, then `sources` in order.
/// Public so that tests can parse exactly what the device compiles.
pub fn kernel_source(sources: &[&str], bindings: &[Binding]) -> String {
    let mut s = PassUniform::wgsl_decl();
    s.push_str(PRELUDE);
    for (k, b) in bindings.iter().enumerate() {
        let access = if b.read_only { "read" } else { "read_write" };
        s.push_str(&format!(
            "@group(0) @binding({}) var<storage, {access}> {}: {};\n",
            2 + k,
            b.name,
            b.ty
        ));
    }
    for src in sources {
        s.push('\n');
        s.push_str(src);
    }
    s
}

/// One compute pipeline and its bind-group layout: binding 0 the frame uniform, 1 the pass
/// uniform (dynamic offset), 2.. the storage buffers of its [`Binding`] table.
#[derive(Debug)]
pub struct Kernel {
    pub(crate) pipeline: wgpu::ComputePipeline,
    pub(crate) layout: wgpu::BindGroupLayout,
}

fn uniform_entry(binding: u32, dynamic: bool) -> wgpu::BindGroupLayoutEntry {
    wgpu::BindGroupLayoutEntry {
        binding,
        visibility: wgpu::ShaderStages::COMPUTE,
        ty: wgpu::BindingType::Buffer {
            ty: wgpu::BufferBindingType::Uniform,
            has_dynamic_offset: dynamic,
            min_binding_size: None,
        },
        count: None,
    }
}

impl Kernel {
    /// Compiles entry point `entry` of [`kernel_source`]`(sources, bindings)`. Shader or
    /// pipeline errors are [`GpuError::Device`].
    pub fn new(
        ctx: &GpuContext,
        entry: &str,
        sources: &[&str],
        bindings: &[Binding],
    ) -> Result<Self> {
        let device = ctx.device();
        ctx.push_error_scopes();
        let module = device.create_shader_module(wgpu::ShaderModuleDescriptor {
            label: Some(entry),
            source: wgpu::ShaderSource::Wgsl(kernel_source(sources, bindings).into()),
        });
        let mut entries = vec![uniform_entry(0, false), uniform_entry(1, true)];
        for (k, b) in bindings.iter().enumerate() {
            entries.push(wgpu::BindGroupLayoutEntry {
                binding: 2 + k as u32,
                visibility: wgpu::ShaderStages::COMPUTE,
                ty: wgpu::BindingType::Buffer {
                    ty: wgpu::BufferBindingType::Storage {
                        read_only: b.read_only,
                    },
                    has_dynamic_offset: false,
                    min_binding_size: None,
                },
                count: None,
            });
        }
        let layout = device.create_bind_group_layout(&wgpu::BindGroupLayoutDescriptor {
            label: Some(entry),
            entries: &entries,
        });
        let pl = device.create_pipeline_layout(&wgpu::PipelineLayoutDescriptor {
            label: Some(entry),
            bind_group_layouts: &[&layout],
            push_constant_ranges: &[],
        });
        let pipeline = device.create_compute_pipeline(&wgpu::ComputePipelineDescriptor {
            label: Some(entry),
            layout: Some(&pl),
            module: &module,
            entry_point: Some(entry),
            compilation_options: Default::default(),
            cache: None,
        });
        ctx.pop_error_scopes().map_err(|e| {
            GpuError::Device(format!(
                "shader or pipeline creation of {entry} failed: {e}"
            ))
        })?;
        Ok(Self { pipeline, layout })
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn pass_uniform_layout_matches_the_prelude() {
        let src = kernel_source(&[], &[Binding::read("x", "array<u32>")]);
        crate::check_layout::<PassUniform>(&src).unwrap();
        assert!(src.contains("@group(0) @binding(2) var<storage, read> x: array<u32>;"));
    }
}
