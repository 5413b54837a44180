//! The device backend: the fluid's step on a GPU (or on a CPU driver that speaks the same API),
//! through [wgpu] on Vulkan.
//!
//! What runs where: the device holds the populations, the force density field and the geometry
//! (obstacle bits, link lists) and runs the time step ([`DeviceFluid::step`]: the fused AA-pattern
//! stream–collide sweep, then the link operations of the box faces and obstacles). The host keeps
//! a [`Fluid<f32>`](crate::lbm::Fluid) of the same set-up as the mirror that output, statistics
//! and checkpoints read: [`DeviceFluid::download`] brings it up to date at output steps,
//! [`DeviceFluid::upload`] sends a restored or edited state back. Nothing crosses per step.
//!
//! - [`Context`]: the adapter and its device and queue, chosen once per process.
//! - [`fluid`]: [`DeviceFluid`], the device copy of the fluid and its step.
//! - [`bandwidth`]: the device's copy bandwidth, the ceiling the step is quoted against.
//! - [`markers`]: [`DeviceMarkers`], the immersed-boundary markers of the coupled step on a
//!   [`DeviceFluid`] (kinematics, stencils, interpolation, direct forcing, deterministic
//!   spreading into its force field, the bodies' IBM loads); per step only the bodies' states
//!   go up and their loads come down.
//! - [`coupled`]: [`DeviceCoupled`], the coupled step: the fluid, the markers and the interior
//!   sums on the device, the bodies and their contacts on the host.
//! - `shaders/`: the kernels in WGSL (`common.wgsl` bindings and parameters,
//!   `stream_collide.wgsl`, `links.wgsl`, compiled when a [`DeviceFluid`] is made; `ibm.wgsl`,
//!   when a [`DeviceMarkers`] is made).
//!
//! The CPU solver ([`crate::lbm`], [`crate::ibm`], `coupling`) is the reference and is not
//! changed by this module: the device runs the same operations in the same order on the same
//! f32 storage (the markers in f32 where the CPU's transfer works in f64).

pub mod bandwidth;
pub mod coupled;
pub mod fluid;
pub mod markers;

pub use coupled::DeviceCoupled;
pub use fluid::DeviceFluid;
pub use markers::DeviceMarkers;

/// Why the device backend cannot be used.
#[derive(Debug, thiserror::Error)]
pub enum DeviceError {
    /// No Vulkan adapter was found.
    #[error(
        "no Vulkan adapter found (a GPU with its Vulkan driver, or Mesa's lavapipe on the CPU): \
         run `cargo xtask setup`, which installs libvulkan1 and mesa-vulkan-drivers, or install \
         your GPU's Vulkan driver and loader"
    )]
    NoAdapter,
    /// The adapter refused to open a device.
    #[error("the Vulkan adapter {adapter} refused a device: {reason}")]
    RequestDevice {
        /// The adapter's name.
        adapter: String,
        /// What wgpu reported.
        reason: String,
    },
    /// The grid does not fit the adapter's limits.
    #[error("{what} ({need}) exceeds the adapter's limit ({limit}) on {adapter}")]
    Limit {
        /// What is too large.
        what: String,
        /// What this fluid needs.
        need: u64,
        /// What the adapter allows.
        limit: u64,
        /// The adapter's name.
        adapter: String,
    },
    /// A marker could not be given a stencil (outside the box on a walled axis, or not
    /// finite): the lowest such marker (global order).
    #[error("marker {0}: outside the box on a walled axis, or not finite")]
    Marker(usize),
    /// A state that does not belong to this device fluid.
    #[error("{0}")]
    Mismatch(String),
    /// An error reported by wgpu while making or running the kernels.
    #[error("device error: {0}")]
    Wgpu(String),
}

/// A Vulkan adapter with its device and queue.
pub struct Context {
    device: wgpu::Device,
    queue: wgpu::Queue,
    info: wgpu::AdapterInfo,
    limits: wgpu::Limits,
}

impl Context {
    /// Opens the best Vulkan adapter: a discrete GPU before an integrated one, before a virtual
    /// one, before a CPU driver (lavapipe). The device gets the adapter's own limits (the
    /// kernels bind 24 storage buffers, more than wgpu's portable defaults).
    ///
    /// # Errors
    /// [`DeviceError::NoAdapter`] (its message names `cargo xtask setup`) or
    /// [`DeviceError::RequestDevice`].
    pub fn new() -> Result<Self, DeviceError> {
        let mut desc = wgpu::InstanceDescriptor::new_without_display_handle();
        desc.backends = wgpu::Backends::VULKAN;
        let instance = wgpu::Instance::new(desc);
        let adapters = pollster::block_on(instance.enumerate_adapters(wgpu::Backends::VULKAN));
        let rank = |t: wgpu::DeviceType| match t {
            wgpu::DeviceType::DiscreteGpu => 0,
            wgpu::DeviceType::IntegratedGpu => 1,
            wgpu::DeviceType::VirtualGpu => 2,
            wgpu::DeviceType::Other => 3,
            wgpu::DeviceType::Cpu => 4,
        };
        let adapter = adapters
            .into_iter()
            .min_by_key(|a| rank(a.get_info().device_type))
            .ok_or(DeviceError::NoAdapter)?;
        let info = adapter.get_info();
        let limits = adapter.limits();
        // 64-bit float shaders where the adapter has them (f64 storage of the fluid).
        let features = adapter.features() & wgpu::Features::SHADER_F64;
        let (device, queue) = pollster::block_on(adapter.request_device(&wgpu::DeviceDescriptor {
            label: Some("slurry"),
            required_features: features,
            required_limits: limits.clone(),
            experimental_features: wgpu::ExperimentalFeatures::disabled(),
            memory_hints: wgpu::MemoryHints::Performance,
            trace: wgpu::Trace::Off,
        }))
        .map_err(|e| DeviceError::RequestDevice { adapter: info.name.clone(), reason: e.to_string() })?;
        Ok(Self { device, queue, info, limits })
    }

    /// The adapter's name, kind and driver, for reports (e.g. `llvmpipe (LLVM 15.0.6, 256 bits)
    /// (Cpu, Vulkan, llvmpipe)`).
    pub fn describe(&self) -> String {
        format!(
            "{} ({:?}, {:?}, {} {})",
            self.info.name, self.info.device_type, self.info.backend, self.info.driver, self.info.driver_info
        )
    }

    /// Whether the device runs 64-bit float shaders (the fluid in f64 storage).
    pub fn has_f64(&self) -> bool {
        self.device.features().contains(wgpu::Features::SHADER_F64)
    }

    /// Whether the adapter is a CPU driver (its timings are then no measure of speed).
    pub fn is_cpu_driver(&self) -> bool {
        self.info.device_type == wgpu::DeviceType::Cpu
    }

    /// The limits the device was opened with.
    pub fn limits(&self) -> &wgpu::Limits {
        &self.limits
    }
}

/// A compute pipeline of `module`'s `entry` with the override `constants`, on `layout` (or the
/// layout derived from the kernel when `None`): what every kernel of the backend is made with.
pub(crate) fn compute_pipeline(
    device: &wgpu::Device,
    layout: Option<&wgpu::PipelineLayout>,
    module: &wgpu::ShaderModule,
    entry: &str,
    constants: &[(&str, f64)],
) -> wgpu::ComputePipeline {
    device.create_compute_pipeline(&wgpu::ComputePipelineDescriptor {
        label: Some(entry),
        layout,
        module,
        entry_point: Some(entry),
        compilation_options: wgpu::PipelineCompilationOptions {
            constants,
            zero_initialize_workgroup_memory: false,
        },
        cache: None,
    })
}

/// Copies the first bytes of each buffer (`(buffer, bytes)`), one after the other, into `out`
/// through `staging` (a mappable buffer at least as long as their sum), and waits: the
/// backend's one read-back.
///
/// # Errors
/// [`DeviceError::Wgpu`] when the copy or the mapping fails.
pub(crate) fn read_buffers(
    device: &wgpu::Device,
    queue: &wgpu::Queue,
    staging: &wgpu::Buffer,
    parts: &[(&wgpu::Buffer, usize)],
    out: &mut [u8],
) -> Result<(), DeviceError> {
    let total: usize = parts.iter().map(|p| p.1).sum();
    if total == 0 {
        return Ok(());
    }
    let mut enc = device.create_command_encoder(&wgpu::CommandEncoderDescriptor { label: None });
    let mut at = 0u64;
    for (b, n) in parts {
        enc.copy_buffer_to_buffer(b, 0, staging, at, *n as u64);
        at += *n as u64;
    }
    queue.submit([enc.finish()]);
    let (tx, rx) = std::sync::mpsc::channel();
    staging.map_async(wgpu::MapMode::Read, ..at, move |r| {
        let _ = tx.send(r);
    });
    device.poll(wgpu::PollType::wait_indefinitely()).map_err(|e| DeviceError::Wgpu(e.to_string()))?;
    rx.recv().map_err(|e| DeviceError::Wgpu(e.to_string()))?.map_err(|e| DeviceError::Wgpu(e.to_string()))?;
    {
        let view = staging.get_mapped_range(..at).map_err(|e| DeviceError::Wgpu(e.to_string()))?;
        out[..total].copy_from_slice(&view[..]);
    }
    staging.unmap();
    Ok(())
}
