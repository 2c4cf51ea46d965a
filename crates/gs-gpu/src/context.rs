//! The wgpu context: adapter choice, device and queue, limits, features, error scopes and
//! readback.

use crate::ledger::{Ledger, Transfers};
use crate::{GpuError, Result};

/// Options of [`GpuContext::new`].
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub struct GpuOptions {
    /// Refuse CPU (software) adapters such as lavapipe.
    pub require_hardware: bool,
    /// Do not enable native `atomic<f32>` even where the adapter has it (kernels then use
    /// their compare-exchange fallback; tests exercise both paths with it).
    pub disable_f32_atomics: bool,
    /// Assume a smaller maximum storage-binding size than the adapter's (bytes; `None` = the
    /// adapter's), e.g. to exercise banded code paths on small inputs.
    pub max_storage_binding: Option<u64>,
}

/// Adapter, device and queue, created once and shared by every kernel of its owner. Cloning
/// shares the same device and queue (wgpu's handles are reference-counted): a rasterizer and the
/// loss kernels of one run use one device.
#[derive(Clone)]
pub struct GpuContext {
    device: wgpu::Device,
    queue: wgpu::Queue,
    info: wgpu::AdapterInfo,
    native_f32_atomics: bool,
    max_binding: u64,
    ledger: Ledger,
}

impl std::fmt::Debug for GpuContext {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("GpuContext")
            .field("adapter", &self.description())
            .field("native_f32_atomics", &self.native_f32_atomics)
            .finish()
    }
}

/// Ranks adapters: discrete > integrated > virtual > other > CPU.
fn adapter_rank(t: wgpu::DeviceType) -> u32 {
    match t {
        wgpu::DeviceType::DiscreteGpu => 0,
        wgpu::DeviceType::IntegratedGpu => 1,
        wgpu::DeviceType::VirtualGpu => 2,
        wgpu::DeviceType::Other => 3,
        wgpu::DeviceType::Cpu => 4,
    }
}

/// The best adapter of this machine that supports compute, if any.
fn pick_adapter(require_hardware: bool) -> Option<(wgpu::Instance, wgpu::Adapter)> {
    // `Instance::new` panics when no backend is compiled in for this platform.
    if wgpu::Instance::enabled_backend_features().is_empty() {
        return None;
    }
    let instance = wgpu::Instance::new(&wgpu::InstanceDescriptor {
        backends: wgpu::Backends::PRIMARY,
        ..Default::default()
    });
    let mut adapters = instance.enumerate_adapters(wgpu::Backends::PRIMARY);
    adapters.retain(|a| {
        let info = a.get_info();
        !(require_hardware && info.device_type == wgpu::DeviceType::Cpu)
            && a.get_downlevel_capabilities()
                .flags
                .contains(wgpu::DownlevelFlags::COMPUTE_SHADERS)
    });
    adapters.sort_by_key(|a| adapter_rank(a.get_info().device_type));
    let a = adapters.into_iter().next()?;
    Some((instance, a))
}

/// Description of the adapter [`GpuContext::new`] would use here (`None` when there is none);
/// cheap enough for logging and for tests that decide whether to skip.
pub fn probe_adapter() -> Option<String> {
    pick_adapter(false).map(|(_, a)| describe(&a.get_info()))
}

/// Whether a hardware (non-CPU) adapter exists.
pub fn hardware_adapter_available() -> bool {
    pick_adapter(true).is_some()
}

fn describe(info: &wgpu::AdapterInfo) -> String {
    format!(
        "{} ({:?}, {:?}, driver {} {})",
        info.name, info.device_type, info.backend, info.driver, info.driver_info
    )
}

impl GpuContext {
    /// Opens the best adapter (see [`GpuOptions`]) with WebGPU's default limits (8 storage
    /// buffers per stage, 16 KiB workgroup memory, 256 invocations, 65535 workgroups per
    /// dimension) and the adapter's buffer sizes, plus `SHADER_FLOAT32_ATOMIC` where offered.
    pub fn new(opts: &GpuOptions) -> Result<Self> {
        let (_instance, adapter) = pick_adapter(opts.require_hardware).ok_or_else(|| {
            GpuError::Unavailable(if opts.require_hardware {
                "no hardware GPU adapter (Vulkan/Metal/DX12) found".into()
            } else {
                "no wgpu adapter (Vulkan/Metal/DX12) found".into()
            })
        })?;
        let info = adapter.get_info();
        let native_f32_atomics = !opts.disable_f32_atomics
            && adapter
                .features()
                .contains(wgpu::Features::SHADER_FLOAT32_ATOMIC);
        let required_features = if native_f32_atomics {
            wgpu::Features::SHADER_FLOAT32_ATOMIC
        } else {
            wgpu::Features::empty()
        };
        let al = adapter.limits();
        let limits = wgpu::Limits {
            max_storage_buffer_binding_size: al.max_storage_buffer_binding_size,
            max_buffer_size: al.max_buffer_size,
            ..wgpu::Limits::default()
        };
        if !limits.check_limits(&al) {
            return Err(GpuError::Unavailable(format!(
                "adapter {} does not meet WebGPU's default limits",
                describe(&info)
            )));
        }
        let (device, queue) = pollster::block_on(adapter.request_device(&wgpu::DeviceDescriptor {
            label: Some("gs-gpu"),
            required_features,
            required_limits: limits,
            experimental_features: wgpu::ExperimentalFeatures::disabled(),
            memory_hints: wgpu::MemoryHints::Performance,
            trace: wgpu::Trace::Off,
        }))
        .map_err(|e| GpuError::Unavailable(format!("{}: {e}", describe(&info))))?;
        // Errors of the owner's work are caught by error scopes and returned; anything else
        // (e.g. a lost device) is logged instead of wgpu's default panic.
        device.on_uncaptured_error(std::sync::Arc::new(|e| {
            eprintln!("gs-gpu: uncaptured device error: {e}");
        }));
        let max_binding = (al.max_storage_buffer_binding_size as u64)
            .min(opts.max_storage_binding.unwrap_or(u64::MAX))
            .max(1 << 16);
        Ok(Self {
            device,
            queue,
            info,
            native_f32_atomics,
            max_binding,
            ledger: Ledger::default(),
        })
    }

    /// The device.
    pub fn device(&self) -> &wgpu::Device {
        &self.device
    }

    /// The queue. Writes through it directly are not counted in [`GpuContext::transfers`];
    /// use [`GpuContext::write_buffer`] or [`GpuContext::write_with`].
    pub fn queue(&self) -> &wgpu::Queue {
        &self.queue
    }

    /// The host–device traffic of this device so far (every clone counts into one ledger).
    pub fn transfers(&self) -> Transfers {
        self.ledger.snapshot()
    }

    /// The ledger, for the dispatchers of this device.
    pub(crate) fn ledger(&self) -> &Ledger {
        &self.ledger
    }

    /// Queues a write of `data` at `offset` in `buffer` (counted in [`GpuContext::transfers`]).
    pub fn write_buffer(&self, buffer: &wgpu::Buffer, offset: u64, data: &[u8]) {
        self.ledger.wrote(data.len() as u64);
        self.queue.write_buffer(buffer, offset, data);
    }

    /// The adapter's information.
    pub fn info(&self) -> &wgpu::AdapterInfo {
        &self.info
    }

    /// "name (device type, backend, driver)" of the adapter in use.
    pub fn description(&self) -> String {
        describe(&self.info)
    }

    /// Whether the adapter is a CPU (software) implementation such as lavapipe.
    pub fn is_software(&self) -> bool {
        self.info.device_type == wgpu::DeviceType::Cpu
    }

    /// Whether `SHADER_FLOAT32_ATOMIC` is enabled (kernels may use `atomic<f32>`).
    pub fn native_f32_atomics(&self) -> bool {
        self.native_f32_atomics
    }

    /// The largest storage binding in bytes (the adapter's, or the smaller one asked for).
    pub fn max_storage_binding(&self) -> u64 {
        self.max_binding
    }

    /// Opens out-of-memory and validation error scopes; close them with
    /// [`pop_error_scopes`](Self::pop_error_scopes) to turn device errors into results.
    pub fn push_error_scopes(&self) {
        self.device.push_error_scope(wgpu::ErrorFilter::OutOfMemory);
        self.device.push_error_scope(wgpu::ErrorFilter::Validation);
    }

    /// Closes the scopes of [`push_error_scopes`](Self::push_error_scopes); the first
    /// validation (else out-of-memory) error becomes [`GpuError::Device`].
    pub fn pop_error_scopes(&self) -> Result<()> {
        let validation = pollster::block_on(self.device.pop_error_scope());
        let oom = pollster::block_on(self.device.pop_error_scope());
        match validation.or(oom) {
            Some(e) => Err(GpuError::Device(e.to_string())),
            None => Ok(()),
        }
    }

    /// Maps the first `bytes` of a `MAP_READ` buffer, waits for the device and returns a copy.
    pub fn read_buffer(&self, buffer: &wgpu::Buffer, bytes: u64) -> Result<Vec<u8>> {
        self.read_mapped(buffer, bytes, |b| b.to_vec())
    }

    /// Maps the first `bytes` of a `MAP_READ` buffer, waits for the device and hands the
    /// mapped bytes to `read` (no copy: large readbacks are unpacked straight from the
    /// mapping, which is at least 4-byte aligned).
    pub fn read_mapped<R>(
        &self,
        buffer: &wgpu::Buffer,
        bytes: u64,
        read: impl FnOnce(&[u8]) -> R,
    ) -> Result<R> {
        let pending = self.request_read(buffer, bytes);
        self.finish_read(pending, read)
    }

    /// Asks for the first `bytes` of a `MAP_READ` buffer after the work submitted so far,
    /// without waiting: several readbacks requested before one [`GpuContext::finish_read`]
    /// cost the host one wait, not one each. The buffer stays mapped-to-be until its read is
    /// finished; its owner must not use it before.
    pub fn request_read(&self, buffer: &wgpu::Buffer, bytes: u64) -> PendingRead {
        let (tx, rx) = std::sync::mpsc::channel();
        if bytes > 0 {
            self.ledger.read_back(bytes);
            buffer.slice(0..bytes).map_async(wgpu::MapMode::Read, move |r| {
                let _ = tx.send(r);
            });
        }
        PendingRead { buffer: Some(buffer.clone()), bytes, rx }
    }

    /// Hands the bytes of a requested readback to `read`, waiting for the device only when
    /// they have not arrived yet (an earlier wait may have brought them).
    pub fn finish_read<R>(&self, mut pending: PendingRead, read: impl FnOnce(&[u8]) -> R) -> Result<R> {
        let (Some(buffer), bytes) = (pending.buffer.take(), pending.bytes) else {
            return Ok(read(&[]));
        };
        let rx = &pending.rx;
        if bytes == 0 {
            return Ok(read(&[]));
        }
        let dev = |e: &dyn std::fmt::Display| GpuError::Device(e.to_string());
        let mapped = match rx.try_recv() {
            Ok(r) => r,
            Err(_) => {
                self.ledger.waited();
                self.device
                    .poll(wgpu::PollType::wait_indefinitely())
                    .map_err(|e| dev(&e))?;
                rx.recv().map_err(|e| dev(&e))?
            }
        };
        mapped.map_err(|e| dev(&e))?;
        let slice = buffer.slice(0..bytes);
        let out = read(&slice.get_mapped_range());
        buffer.unmap();
        Ok(out)
    }

    /// Queues a write of `bytes` bytes to the start of `buffer`, produced by `fill` straight
    /// into the queue's staging memory (no intermediate host copy). A write wgpu refuses is a
    /// validation error of the open error scopes, and `fill` is not called.
    pub fn write_with(&self, buffer: &wgpu::Buffer, bytes: u64, fill: impl FnOnce(&mut [u8])) {
        let Some(size) = std::num::NonZeroU64::new(bytes) else { return };
        self.ledger.wrote(bytes);
        if let Some(mut view) = self.queue.write_buffer_with(buffer, 0, size) {
            fill(&mut view);
        }
    }

    /// Copies `bytes` of `src` (a `COPY_SRC` buffer) from `offset` into a temporary staging
    /// buffer and reads them back: convenient for tests and small results; hot paths keep a
    /// pooled staging buffer and use [`read_buffer`](Self::read_buffer).
    pub fn download(&self, src: &wgpu::Buffer, offset: u64, bytes: u64) -> Result<Vec<u8>> {
        if bytes == 0 {
            return Ok(Vec::new());
        }
        let staging = self.device.create_buffer(&wgpu::BufferDescriptor {
            label: Some("gs-gpu download"),
            size: bytes.next_multiple_of(4),
            usage: wgpu::BufferUsages::MAP_READ | wgpu::BufferUsages::COPY_DST,
            mapped_at_creation: false,
        });
        let mut enc = self
            .device
            .create_command_encoder(&wgpu::CommandEncoderDescriptor { label: None });
        enc.copy_buffer_to_buffer(src, offset, &staging, 0, bytes.next_multiple_of(4));
        self.ledger.submitted();
        self.queue.submit(Some(enc.finish()));
        let mut out = self.read_buffer(&staging, bytes.next_multiple_of(4))?;
        out.truncate(bytes as usize);
        Ok(out)
    }
}

/// A readback requested by [`GpuContext::request_read`] and not yet read; dropped unread, it
/// gives up the mapping, so the buffer may be used again.
#[derive(Debug)]
pub struct PendingRead {
    /// `None` once read.
    buffer: Option<wgpu::Buffer>,
    bytes: u64,
    rx: std::sync::mpsc::Receiver<std::result::Result<(), wgpu::BufferAsyncError>>,
}

impl Drop for PendingRead {
    fn drop(&mut self) {
        if let Some(b) = self.buffer.take().filter(|_| self.bytes > 0) {
            b.unmap();
        }
    }
}
