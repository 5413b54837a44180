//! [`DeviceFluid`]: the D3Q19 fluid's state and time step on the device.
//!
//! **Storage.** The shifted populations in f32 (or in f64 where the adapter has 64-bit float
//! shaders, [`DeviceReal`]), exactly as the CPU's [`Fluid`] stores them:
//! the padded grid with its ghost layer and the same `stride`, one buffer per direction (a
//! binding may hold at most 128 MiB on lavapipe, and per direction the paper's grid needs 62 MB),
//! so that [`DeviceFluid::upload`] and [`DeviceFluid::download`] copy each direction's array
//! as it is. Beside them: the force density field (three buffers, or a placeholder while it is
//! off), one bit per padded node for ghost and obstacle nodes, and the link list of
//! `Fluid::apply_links` (own slot, ghost slot, directions, wall term).
//!
//! **Step.** One AA half-step, as [`Fluid::step`]: the sweep (`stream_collide.wgsl`, even or
//! odd), then the link operations (`links.wgsl`, `pre` after an even sweep, `post` after an odd
//! one). A batch of steps is recorded into one compute pass; wgpu orders the dispatches (each
//! is its own usage scope, and a read-write storage buffer gets a barrier between them).
//!
//! **The CPU's operations, not (yet) the CPU's bits.** The kernel performs the CPU's operations
//! in the CPU's order, with the constants rounded once from f64 exactly as
//! `lbm::collision::collide` rounds them. The driver need not round as the CPU does: Vulkan lets
//! it contract or split `fma` and compute `1/ρ` within 2.5 ulp. On lavapipe (Mesa 22.3) the
//! results differ from the CPU's by a few f32 ulp of the populations (at most 3.7e-9 after
//! 150–200 steps, tests/device_fluid.rs); device runs are bitwise reproducible, for any
//! work-group size.
//!
//! **No runtime checks in the kernels.** The shaders are made with
//! [`wgpu::ShaderRuntimeChecks::unchecked`] (bounds checks cost three times the step on
//! lavapipe). Every index is in range by construction: the sweep runs `x < nx` (checked),
//! `y < ny` and `z < nz` (the dispatch's size), so `p` is an interior node and `p ± o_i` a node
//! of the padded grid (`< stride`); the obstacle bits have `⌈padded/32⌉` words; the link
//! kernel runs `k < n_links` (checked) and its slots come from the CPU fluid's link list, each
//! `< stride`, with directions `< 19`. The kernels have no loops.

use wgpu::util::DeviceExt;

use super::{compute_pipeline, read_buffers, Context, DeviceError};
use crate::lattice::{Grid, Q, W};
use crate::lbm::{Fluid, Real};

/// The storage precisions the device fluid offers: f32 everywhere, f64 where the adapter has
/// 64-bit float shaders ([`Context::has_f64`]).
pub trait DeviceReal: Real + bytemuck::Pod {
    /// The WGSL type (`real` in the kernels is an alias of it).
    const WGSL: &'static str;
    /// Appends the value's bits as 32-bit words, low word first (the device's little-endian
    /// layout of an f64).
    fn push_words(self, out: &mut Vec<u32>);
}

impl DeviceReal for f32 {
    const WGSL: &'static str = "f32";
    fn push_words(self, out: &mut Vec<u32>) {
        out.push(self.to_bits());
    }
}

impl DeviceReal for f64 {
    const WGSL: &'static str = "f64";
    fn push_words(self, out: &mut Vec<u32>) {
        let b = self.to_bits();
        out.extend([b as u32, (b >> 32) as u32]);
    }
}

/// The default work-group size of the kernels (threads along x).
pub const DEFAULT_WORKGROUP: u32 = 64;

/// The kernels' source: the shared bindings, then each kernel.
const COMMON: &str = include_str!("shaders/common.wgsl");
const STREAM_COLLIDE: &str = include_str!("shaders/stream_collide.wgsl");
const LINKS: &str = include_str!("shaders/links.wgsl");

/// Binding numbers (common.wgsl).
const BIND_PARAMS: u32 = 0;
const BIND_F0: u32 = 1;
const BIND_FORCE: u32 = 20;
const BIND_SOLID: u32 = 23;
const BIND_LINKS: u32 = 24;

/// Steps recorded into one command buffer.
const STEPS_PER_SUBMIT: u64 = 64;

/// The fluid on the device: populations, force field and geometry, and the step.
///
/// Made from a CPU [`Fluid<f32>`] ([`DeviceFluid::new`]), whose grid, parameters, boundaries
/// and obstacles it copies; that fluid stays the host mirror for output
/// ([`DeviceFluid::download`]). The geometry is taken once: after `set_obstacles` on the host,
/// make a new `DeviceFluid`.
pub struct DeviceFluid {
    device: wgpu::Device,
    queue: wgpu::Queue,
    adapter: String,
    grid: Grid,
    stride: usize,
    /// The storage precision's WGSL name, `"f32"` or `"f64"` ([`DeviceReal::WGSL`]).
    precision: &'static str,
    trt: bool,
    workgroup: u32,
    /// One buffer per direction, `stride` values each.
    pops: Vec<wgpu::Buffer>,
    /// The force field's three components, while it is on.
    force: Option<[wgpu::Buffer; 3]>,
    placeholder: wgpu::Buffer,
    solid: wgpu::Buffer,
    links: wgpu::Buffer,
    n_links: u32,
    link_groups: [u32; 2],
    params: wgpu::Buffer,
    layout: wgpu::BindGroupLayout,
    bind_group: wgpu::BindGroup,
    pipeline_layout: wgpu::PipelineLayout,
    sweep_module: wgpu::ShaderModule,
    /// Sweep pipelines by `[odd][force field]`.
    sweeps: [[Option<wgpu::ComputePipeline>; 2]; 2],
    /// Link pipelines: `[post, pre]`.
    link_pipes: [wgpu::ComputePipeline; 2],
    /// A staging buffer for downloads, one direction long.
    staging: wgpu::Buffer,
    time: u64,
    /// The uniform body force (as the sweep's parameters hold it, in the storage precision).
    body: [f64; 3],
    /// Which axes are periodic (the others are walled).
    periodic: [bool; 3],
    /// Bumped whenever the force field's buffers are made anew (markers bound to the old ones
    /// must be made again).
    force_generation: u64,
}

/// Checks `need ≤ limit`.
fn within(what: &str, need: u64, limit: u64, adapter: &str) -> Result<(), DeviceError> {
    if need > limit {
        return Err(DeviceError::Limit { what: what.into(), need, limit, adapter: adapter.into() });
    }
    Ok(())
}

/// A storage binding of the layout.
fn storage_entry(binding: u32, read_only: bool) -> wgpu::BindGroupLayoutEntry {
    wgpu::BindGroupLayoutEntry {
        binding,
        visibility: wgpu::ShaderStages::COMPUTE,
        ty: wgpu::BindingType::Buffer {
            ty: wgpu::BufferBindingType::Storage { read_only },
            has_dynamic_offset: false,
            min_binding_size: None,
        },
        count: None,
    }
}

impl DeviceFluid {
    /// A device copy of `fluid` (its grid, parameters, boundaries, obstacles, populations, force
    /// field and time), stepped with work groups of `workgroup` threads along x.
    ///
    /// # Errors
    /// [`DeviceError::Limit`] when a direction's array, the dispatch or the work group exceeds
    /// the adapter's limits; [`DeviceError::Wgpu`] when a kernel does not compile.
    pub fn new<T: DeviceReal>(ctx: &Context, fluid: &Fluid<T>, workgroup: u32) -> Result<Self, DeviceError> {
        let limits = ctx.limits();
        let adapter = ctx.describe();
        if T::WGSL == "f64" && !ctx.has_f64() {
            return Err(DeviceError::Mismatch(format!(
                "f64 storage on the device needs 64-bit float shaders, which the adapter {adapter} does not \
                 offer: use f32 storage, or the CPU"
            )));
        }
        let grid = fluid.grid();
        let stride = fluid.stride();
        let bytes = (stride * size_of::<T>()) as u64;
        within("a direction's array (bytes)", bytes, limits.max_storage_buffer_binding_size, &adapter)?;
        within("a direction's array (bytes)", bytes, limits.max_buffer_size, &adapter)?;
        within("work-group size", workgroup as u64, limits.max_compute_workgroup_size_x as u64, &adapter)?;
        within(
            "work-group size",
            workgroup as u64,
            limits.max_compute_invocations_per_workgroup as u64,
            &adapter,
        )?;
        if workgroup == 0 {
            return Err(DeviceError::Mismatch("work-group size 0: allowed 1 and more".into()));
        }
        let max_groups = limits.max_compute_workgroups_per_dimension as u64;
        within("work groups along x", (grid.nx as u64).div_ceil(workgroup as u64), max_groups, &adapter)?;
        within("work groups along y (ny)", grid.ny as u64, max_groups, &adapter)?;
        within("work groups along z (nz)", grid.nz as u64, max_groups, &adapter)?;
        within(
            "storage buffers per kernel",
            24,
            limits.max_storage_buffers_per_shader_stage as u64,
            &adapter,
        )?;

        let device = ctx.device.clone();
        let queue = ctx.queue.clone();
        let storage =
            wgpu::BufferUsages::STORAGE | wgpu::BufferUsages::COPY_DST | wgpu::BufferUsages::COPY_SRC;
        let pops: Vec<wgpu::Buffer> = (0..Q)
            .map(|q| {
                device.create_buffer(&wgpu::BufferDescriptor {
                    label: Some(&format!("f{q}")),
                    size: bytes,
                    usage: storage,
                    mapped_at_creation: false,
                })
            })
            .collect();
        let placeholder = device.create_buffer(&wgpu::BufferDescriptor {
            label: Some("force placeholder"),
            size: 16,
            usage: wgpu::BufferUsages::STORAGE,
            mapped_at_creation: false,
        });

        // Obstacle and ghost bits.
        let solid_flags = fluid.raw_solid();
        let mut bits = vec![0u32; solid_flags.len().div_ceil(32).max(1)];
        for (n, &s) in solid_flags.iter().enumerate() {
            if s {
                bits[n >> 5] |= 1 << (n & 31);
            }
        }
        let solid = device.create_buffer_init(&wgpu::util::BufferInitDescriptor {
            label: Some("solid"),
            contents: bytemuck::cast_slice(&bits),
            usage: wgpu::BufferUsages::STORAGE,
        });

        // Link list, sorted by directions (threads of a group then mostly take the same branch
        // of the kernel's direction switch; the links are independent, so the order is free).
        let mut list: Vec<([u32; 3], T)> = fluid
            .raw_links()
            .map(|l| {
                let (own_q, own_n) = (l.own / stride, l.own % stride);
                let (ghost_q, ghost_n) = (l.ghost / stride, l.ghost % stride);
                let dirs = own_q as u32 | (ghost_q as u32) << 8 | (l.periodic as u32) << 16;
                ([own_n as u32, ghost_n as u32, dirs], l.term)
            })
            .collect();
        list.sort_by_key(|l| (l.0[2], l.0[0]));
        let n_links = list.len() as u32;
        if list.is_empty() {
            list.push(([0; 3], T::ZERO));
        }
        // common.wgsl's `Link`: three u32, then the term at its alignment (offset 12 in f32,
        // 16 in f64), each element padded to a multiple of its alignment.
        let mut words = Vec::with_capacity(list.len() * 6);
        for (w, term) in &list {
            words.extend_from_slice(w);
            if size_of::<T>() == 8 {
                words.push(0);
            }
            term.push_words(&mut words);
        }
        let links = device.create_buffer_init(&wgpu::util::BufferInitDescriptor {
            label: Some("links"),
            contents: bytemuck::cast_slice(&words),
            usage: wgpu::BufferUsages::STORAGE,
        });
        let groups = (n_links as u64).div_ceil(workgroup as u64);
        let gx = groups.clamp(1, max_groups);
        let gy = groups.div_ceil(gx);
        within("work groups of the link operations", gy, max_groups, &adapter)?;
        let link_groups = [gx as u32, gy as u32];

        let trt = fluid.params().is_trt();
        let params_words = Self::params_words(fluid, n_links, gx as u32 * workgroup);
        let params = device.create_buffer_init(&wgpu::util::BufferInitDescriptor {
            label: Some("params"),
            contents: bytemuck::cast_slice(&params_words),
            usage: wgpu::BufferUsages::UNIFORM | wgpu::BufferUsages::COPY_DST,
        });

        let mut entries = vec![wgpu::BindGroupLayoutEntry {
            binding: BIND_PARAMS,
            visibility: wgpu::ShaderStages::COMPUTE,
            ty: wgpu::BindingType::Buffer {
                ty: wgpu::BufferBindingType::Uniform,
                has_dynamic_offset: false,
                min_binding_size: None,
            },
            count: None,
        }];
        entries.extend((0..Q as u32).map(|q| storage_entry(BIND_F0 + q, false)));
        entries.extend((0..3).map(|a| storage_entry(BIND_FORCE + a, true)));
        entries.push(storage_entry(BIND_SOLID, true));
        entries.push(storage_entry(BIND_LINKS, true));
        let layout = device.create_bind_group_layout(&wgpu::BindGroupLayoutDescriptor {
            label: Some("fluid"),
            entries: &entries,
        });
        let pipeline_layout = device.create_pipeline_layout(&wgpu::PipelineLayoutDescriptor {
            label: Some("fluid"),
            bind_group_layouts: &[Some(&layout)],
            immediate_size: 0,
        });

        let scope = device.push_error_scope(wgpu::ErrorFilter::Validation);
        let module = |label: &str, kernel: &str| {
            let source = format!("alias real = {};\n{COMMON}\n{kernel}", T::WGSL);
            // SAFETY: the kernels index only in range (module docs: every index is bounded by
            // construction) and contain no loops, which is what the unchecked mode requires.
            unsafe {
                device.create_shader_module_trusted(
                    wgpu::ShaderModuleDescriptor {
                        label: Some(label),
                        source: wgpu::ShaderSource::Wgsl(source.into()),
                    },
                    wgpu::ShaderRuntimeChecks::unchecked(),
                )
            }
        };
        let sweep_module = module("stream_collide", STREAM_COLLIDE);
        let links_module = module("links", LINKS);
        let make = |pre: bool| {
            compute_pipeline(
                &device,
                Some(&pipeline_layout),
                &links_module,
                "apply_links",
                &[("WG", workgroup as f64), ("PRE", pre as u8 as f64)],
            )
        };
        let link_pipes = [make(false), make(true)];
        let staging = device.create_buffer(&wgpu::BufferDescriptor {
            label: Some("staging"),
            size: bytes,
            usage: wgpu::BufferUsages::MAP_READ | wgpu::BufferUsages::COPY_DST,
            mapped_at_creation: false,
        });
        let bind_group =
            Self::make_bind_group(&device, &layout, &params, &pops, None, &placeholder, &solid, &links);
        let mut me = Self {
            device,
            queue,
            adapter,
            grid,
            stride,
            precision: T::WGSL,
            trt,
            workgroup,
            pops,
            force: None,
            placeholder,
            solid,
            links,
            n_links,
            link_groups,
            params,
            layout,
            bind_group,
            pipeline_layout,
            sweep_module,
            sweeps: Default::default(),
            link_pipes,
            staging,
            time: fluid.time(),
            body: fluid.raw_body().map(Real::to_f64),
            periodic: std::array::from_fn(|a| {
                fluid.boundaries().get(crate::lattice::Face::from_axis(a, true)).is_periodic()
            }),
            force_generation: 0,
        };
        me.upload(fluid)?;
        me.sweep_pipelines()?;
        if let Some(e) = pollster::block_on(scope.pop()) {
            return Err(DeviceError::Wgpu(e.to_string()));
        }
        Ok(me)
    }

    /// The uniform parameters (common.wgsl `Params`) as 32-bit words: sizes, the body force,
    /// and the collision constants rounded from f64 once to the storage precision, as `collide`
    /// rounds them.
    fn params_words<T: DeviceReal>(fluid: &Fluid<T>, n_links: u32, link_row: u32) -> Vec<u32> {
        let g = fluid.grid();
        let rates = fluid.raw_rates();
        let trt = fluid.params().is_trt();
        let op = rates.omega_plus.to_f64();
        let om = if trt { rates.omega_minus.to_f64() } else { op };
        let sp = rates.src_plus.to_f64();
        let sm = if trt { rates.src_minus.to_f64() } else { sp };
        let (w1, w2) = (W[1], W[7]);
        let body = fluid.raw_body();
        let mut words = vec![
            g.nx as u32,
            g.ny as u32,
            g.nz as u32,
            (g.nx + 2) as u32,
            (g.ny + 2) as u32,
            n_links,
            link_row,
            0,
        ];
        for v in body {
            v.push_words(&mut words);
        }
        for v in [
            op,
            3.0 * sp,
            W[0],
            w1,
            w2,
            4.5 * op * w1,
            4.5 * op * w2,
            3.0 * om * w1,
            3.0 * om * w2,
            9.0 * sp * w1,
            9.0 * sp * w2,
            3.0 * sm * w1,
            3.0 * sm * w2,
            1.0 - op,
            0.5 * op,
            0.5 * om,
        ] {
            T::from_f64(v).push_words(&mut words);
        }
        words.resize(words.len().next_multiple_of(4), 0);
        words
    }

    #[allow(clippy::too_many_arguments)]
    fn make_bind_group(
        device: &wgpu::Device,
        layout: &wgpu::BindGroupLayout,
        params: &wgpu::Buffer,
        pops: &[wgpu::Buffer],
        force: Option<&[wgpu::Buffer; 3]>,
        placeholder: &wgpu::Buffer,
        solid: &wgpu::Buffer,
        links: &wgpu::Buffer,
    ) -> wgpu::BindGroup {
        let mut entries =
            vec![wgpu::BindGroupEntry { binding: BIND_PARAMS, resource: params.as_entire_binding() }];
        for (q, b) in pops.iter().enumerate() {
            entries
                .push(wgpu::BindGroupEntry { binding: BIND_F0 + q as u32, resource: b.as_entire_binding() });
        }
        for a in 0..3 {
            let b = force.map_or(placeholder, |f| &f[a]);
            entries.push(wgpu::BindGroupEntry {
                binding: BIND_FORCE + a as u32,
                resource: b.as_entire_binding(),
            });
        }
        entries.push(wgpu::BindGroupEntry { binding: BIND_SOLID, resource: solid.as_entire_binding() });
        entries.push(wgpu::BindGroupEntry { binding: BIND_LINKS, resource: links.as_entire_binding() });
        device.create_bind_group(&wgpu::BindGroupDescriptor {
            label: Some("fluid"),
            layout,
            entries: &entries,
        })
    }

    /// The even and odd sweep pipelines for the present force-field state, made on first use.
    fn sweep_pipelines(&mut self) -> Result<(), DeviceError> {
        let ff = self.force.is_some();
        for odd in [false, true] {
            if self.sweeps[odd as usize][ff as usize].is_none() {
                let scope = self.device.push_error_scope(wgpu::ErrorFilter::Validation);
                let p = compute_pipeline(
                    &self.device,
                    Some(&self.pipeline_layout),
                    &self.sweep_module,
                    "stream_collide",
                    &[
                        ("WG", self.workgroup as f64),
                        ("ODD", odd as u8 as f64),
                        ("TRT", self.trt as u8 as f64),
                        ("FF", ff as u8 as f64),
                    ],
                );
                if let Some(e) = pollster::block_on(scope.pop()) {
                    return Err(DeviceError::Wgpu(e.to_string()));
                }
                self.sweeps[odd as usize][ff as usize] = Some(p);
            }
        }
        Ok(())
    }

    /// The grid.
    pub fn grid(&self) -> Grid {
        self.grid
    }

    /// Number of completed time steps.
    pub fn time(&self) -> u64 {
        self.time
    }

    /// The work-group size (threads along x).
    pub fn workgroup(&self) -> u32 {
        self.workgroup
    }

    /// The adapter, as [`Context::describe`] gives it.
    pub fn adapter(&self) -> &str {
        &self.adapter
    }

    /// The storage precision, `"f32"` or `"f64"`.
    pub fn precision(&self) -> &'static str {
        self.precision
    }

    /// Checks that `fluid` has this device fluid's grid, layout and precision.
    fn check<T: DeviceReal>(&self, fluid: &Fluid<T>) -> Result<(), DeviceError> {
        if fluid.grid() != self.grid
            || fluid.stride() != self.stride
            || fluid.params().is_trt() != self.trt
            || T::WGSL != self.precision
        {
            return Err(DeviceError::Mismatch(format!(
                "the host fluid (grid {:?}, {}) is not the one this device fluid was made from (grid {:?}, {})",
                fluid.grid(),
                T::WGSL,
                self.grid,
                self.precision
            )));
        }
        Ok(())
    }

    /// Sends `fluid`'s populations, force field and time to the device (after a restore or
    /// any change on the host; the geometry is the one the device fluid was made with).
    ///
    /// # Errors
    /// [`DeviceError::Mismatch`] for a fluid of another grid.
    pub fn upload<T: DeviceReal>(&mut self, fluid: &Fluid<T>) -> Result<(), DeviceError> {
        self.check(fluid)?;
        let f = fluid.raw_populations();
        for (q, b) in self.pops.iter().enumerate() {
            self.queue.write_buffer(b, 0, bytemuck::cast_slice(&f[q * self.stride..(q + 1) * self.stride]));
        }
        self.set_force_field(fluid)?;
        self.time = fluid.time();
        Ok(())
    }

    /// Sends `fluid`'s force density field to the device (or turns the device's off when the
    /// host's is off). The only per-step traffic a coupling needs beside the bodies.
    ///
    /// # Errors
    /// [`DeviceError::Mismatch`] for a fluid of another grid; [`DeviceError::Wgpu`] when the
    /// kernel for a newly enabled field does not compile.
    pub fn set_force_field<T: DeviceReal>(&mut self, fluid: &Fluid<T>) -> Result<(), DeviceError> {
        self.check(fluid)?;
        let field = fluid.raw_force();
        let was = self.force.is_some();
        if field.is_empty() {
            self.force = None;
        } else {
            if self.force.is_none() {
                let make = |a: usize| {
                    self.device.create_buffer(&wgpu::BufferDescriptor {
                        label: Some(["force x", "force y", "force z"][a]),
                        size: (self.stride * size_of::<T>()) as u64,
                        usage: wgpu::BufferUsages::STORAGE
                            | wgpu::BufferUsages::COPY_DST
                            | wgpu::BufferUsages::COPY_SRC,
                        mapped_at_creation: false,
                    })
                };
                self.force = Some([make(0), make(1), make(2)]);
                self.force_generation += 1;
            }
            if let Some(bufs) = &self.force {
                for (a, b) in bufs.iter().enumerate() {
                    self.queue.write_buffer(
                        b,
                        0,
                        bytemuck::cast_slice(&field[a * self.stride..(a + 1) * self.stride]),
                    );
                }
            }
        }
        if was != self.force.is_some() {
            self.bind_group = Self::make_bind_group(
                &self.device,
                &self.layout,
                &self.params,
                &self.pops,
                self.force.as_ref(),
                &self.placeholder,
                &self.solid,
                &self.links,
            );
            self.sweep_pipelines()?;
        }
        Ok(())
    }

    /// Copies the device's populations and time into `fluid` (the host mirror made from the
    /// same set-up), whatever the AA parity: the host then reads fields, sums and health, and
    /// writes checkpoints, as if it had stepped itself. Blocks until the device is done.
    ///
    /// # Errors
    /// [`DeviceError::Mismatch`] for a fluid of another grid; [`DeviceError::Wgpu`] when the
    /// read-back fails.
    pub fn download<T: DeviceReal>(&self, fluid: &mut Fluid<T>) -> Result<(), DeviceError> {
        self.check(fluid)?;
        let stride = self.stride;
        let f = fluid.raw_populations_mut(self.time);
        for (q, b) in self.pops.iter().enumerate() {
            self.read_back(b, &mut f[q * stride..(q + 1) * stride])?;
        }
        Ok(())
    }

    /// The device's force density field, `3·stride` values in the host's layout
    /// (`force[a·stride + n]`, padded node `n`), or nothing while the field is off. Blocks until
    /// the device is done.
    ///
    /// # Errors
    /// [`DeviceError::Wgpu`] when the read-back fails.
    pub fn download_force<T: DeviceReal>(&self) -> Result<Vec<T>, DeviceError> {
        let Some(bufs) = &self.force else { return Ok(Vec::new()) };
        if T::WGSL != self.precision {
            return Err(DeviceError::Mismatch(format!(
                "the force field is in {}, not {}",
                self.precision,
                T::WGSL
            )));
        }
        let stride = self.stride;
        let mut out = vec![T::ZERO; 3 * stride];
        for (a, b) in bufs.iter().enumerate() {
            self.read_back(b, &mut out[a * stride..(a + 1) * stride])?;
        }
        Ok(out)
    }

    /// Copies the first `out.len()` values of `buffer` (at most one direction's array) into
    /// `out` through the staging buffer.
    fn read_back<T: DeviceReal>(&self, buffer: &wgpu::Buffer, out: &mut [T]) -> Result<(), DeviceError> {
        let bytes = size_of_val(out);
        read_buffers(
            &self.device,
            &self.queue,
            &self.staging,
            &[(buffer, bytes)],
            bytemuck::cast_slice_mut(out),
        )
    }

    /// Which axes are periodic (the host fluid's faces when this device fluid was made).
    pub fn periodic(&self) -> [bool; 3] {
        self.periodic
    }

    /// The device and queue, for the other kernels that work on this fluid's buffers.
    pub(super) fn device_queue(&self) -> (&wgpu::Device, &wgpu::Queue) {
        (&self.device, &self.queue)
    }

    /// The population buffers, one per direction (`stride` f32 each).
    pub(super) fn population_buffers(&self) -> &[wgpu::Buffer] {
        &self.pops
    }

    /// The force field's buffers while it is on, and their generation (changes when they are
    /// made anew).
    pub(super) fn force_buffers(&self) -> Option<(&[wgpu::Buffer; 3], u64)> {
        self.force.as_ref().map(|f| (f, self.force_generation))
    }

    /// The uniform body force, in f32 (exact for an f32 fluid, the only one the markers
    /// work on).
    pub(super) fn body_force(&self) -> [f32; 3] {
        self.body.map(|v| v as f32)
    }

    /// Distance between the starts of the padded arrays' components (as the host fluid's).
    pub(super) fn stride(&self) -> usize {
        self.stride
    }

    /// Advances one time step (one AA half-cycle, as [`Fluid::step`]).
    ///
    /// # Errors
    /// [`DeviceError::Wgpu`] when the device reports an error.
    pub fn step(&mut self) -> Result<(), DeviceError> {
        self.run(1)
    }

    /// Advances `n` time steps, recorded `STEPS_PER_SUBMIT` at a time, and waits for them.
    ///
    /// # Errors
    /// [`DeviceError::Wgpu`] when the device reports an error.
    pub fn run(&mut self, n: u64) -> Result<(), DeviceError> {
        self.submit_steps(n);
        self.device
            .poll(wgpu::PollType::wait_indefinitely())
            .map_err(|e| DeviceError::Wgpu(e.to_string()))?;
        Ok(())
    }

    /// Records and submits `n` time steps without waiting for them (the coupled step waits once,
    /// for its loads, after the fluid step and the sums that follow it on the same queue).
    pub(super) fn submit_steps(&mut self, n: u64) {
        let ff = self.force.is_some() as usize;
        let dispatch =
            [(self.grid.nx as u32).div_ceil(self.workgroup), self.grid.ny as u32, self.grid.nz as u32];
        let mut left = n;
        while left > 0 {
            let batch = left.min(STEPS_PER_SUBMIT);
            let mut enc = self.device.create_command_encoder(&wgpu::CommandEncoderDescriptor { label: None });
            {
                let mut pass = enc
                    .begin_compute_pass(&wgpu::ComputePassDescriptor { label: None, timestamp_writes: None });
                pass.set_bind_group(0, &self.bind_group, &[]);
                for _ in 0..batch {
                    let odd = !self.time.is_multiple_of(2);
                    let sweep =
                        self.sweeps[odd as usize][ff].as_ref().expect("sweep pipelines made with the field");
                    pass.set_pipeline(sweep);
                    pass.dispatch_workgroups(dispatch[0], dispatch[1], dispatch[2]);
                    if self.n_links > 0 {
                        // After the even sweep the pre links, after the odd one the post links.
                        pass.set_pipeline(&self.link_pipes[!odd as usize]);
                        pass.dispatch_workgroups(self.link_groups[0], self.link_groups[1], 1);
                    }
                    self.time += 1;
                }
            }
            self.queue.submit([enc.finish()]);
            left -= batch;
        }
    }

    /// Density and velocity of every interior node (obstacle nodes: `ρ = 1`, `u = 0`), through
    /// the host mirror: [`DeviceFluid::download`] into `fluid`, then [`Fluid::fields`].
    ///
    /// # Errors
    /// As [`DeviceFluid::download`].
    #[allow(clippy::type_complexity)]
    pub fn fields<T: DeviceReal>(
        &self,
        fluid: &mut Fluid<T>,
    ) -> Result<(Vec<f64>, Vec<[f64; 3]>), DeviceError> {
        self.download(fluid)?;
        Ok(fluid.fields())
    }
}
