//! [`DeviceMarkers`]: the immersed-boundary markers of the coupled step on the device, working
//! on a [`DeviceFluid`]'s populations and force field (kernels in `shaders/ibm.wgsl`).
//!
//! **What runs on the device** (phases 1, 2, 4, 5 and the IBM part of 7 of
//! `coupling::Coupled::step`; phases 3 and 7's interior sums below):
//! - *kinematics*: each body's forcing markers (body frame, with their area weights) and
//!   owners are uploaded once; per step only the bodies' states go up
//!   ([`DeviceMarkers::set_bodies`]: 112 bytes a body: position, rotation matrix, velocity,
//!   angular velocity), and the markers' arms `R r`, world positions and solid velocities
//!   `U = v + ω × R r` are computed on the device;
//! - *stencils*: those of `ibm::stencil` (any [`DeltaKernel`], periodic wrap, on a walled axis
//!   the points outside the box dropped and the kept weights renormalised, the 3-D weight
//!   `(φ_z φ_y) φ_x`), in f32. Positions are taken relative to the body's integer origin (the
//!   host splits the centre into an integer and a fraction in f64), so the offsets `x − j`
//!   that the weights need carry the rounding of the arm `R r` (a few ulp of the body's size),
//!   not of the box's coordinates. A marker outside the box on a walled axis, or not finite,
//!   gets no stencil and is reported by [`DeviceMarkers::loads`] (the CPU refuses the step
//!   before it starts; here the step has run without that marker and must be discarded);
//! - *interpolation*: `u_m = Σ δ u` with `u = (j + F/2)/ρ` computed at each stencil node from
//!   the pre-collision populations (either AA parity) with the CPU's sums in its order, in f32;
//! - *direct forcing*: `ΔF_m = 2 (U_m − u_m) A_m` (`ρ_m = 1`, as the CPU) and the marker's
//!   total over the iterations;
//! - *spreading* into the fluid's force field, deterministic (below);
//! - *loads*: per body `−Σ F_m` and `−Σ r_m × F_m` in a fixed order: the body's markers in
//!   chunks of [`CHUNK`] (each summed serially in marker order), then the body's chunks in
//!   order; downloaded per step (32 bytes a body).
//!
//! **Deterministic spreading: integer fixed point, not a gather.** Each contribution `w F_m`
//! (f32) is rounded once to an integer multiple of `2⁻⁴⁰` and added into a 64-bit two's
//! complement sum per node and component, kept as two 32-bit words and updated with two
//! integer atomics (the low word's `atomicAdd` returns the old word, from which the carry into
//! the high word follows: the total number of carries is that of the exact sum, whatever the
//! order). Integer sums are exact, so the field is the same bits for any work-group size, any
//! order of the threads and even any order of the markers — stronger than the CPU's slab
//! order. After the spreading of an iteration, the sums at every stencil node are converted to
//! f32 (within an ulp) and stored as the node's force density (every marker that holds the node
//! stores the same bits). The price: 24 bytes a padded node for the sums (the fluid takes 88),
//! and the scale's limits. *Why `2⁻⁴⁰`:* contributions below `2⁻¹⁷` lose their bits below
//! `2⁻⁴¹` (absolute), a relative `2⁻²⁴` of `2⁻¹⁷`: the rounding of an f32 sum of such terms is
//! no smaller; a node's sum must stay below `2²³` in magnitude (the high word is a signed
//! 32-bit integer), while a force density of 1 already changes the fluid's velocity by 1 per
//! step, far beyond the Mach limit. A node of `k` contributions differs from the exact sum of
//! the f32 terms by at most `k 2⁻⁴¹` plus the final conversion's ulp. (A gather over a cell
//! list sorted by cell and marker, as the CPU's slab order is, would need a deterministic sort
//! per step and a list of the nodes to visit. FluidX3D's `spread_force` (M. Lehmann,
//! `src/kernel.cpp` of github.com/ProjectPhysX/FluidX3D; read for the idea only, its licence
//! forbids reuse) spreads with floating-point atomic additions, whose order, hence bits, vary
//! from run to run.)
//!
//! **Clearing.** At each [`DeviceMarkers::place`] the sums and the field are zeroed at the
//! previous stencils' nodes (the only nodes where they are non-zero), as phase 4 clears the
//! previous band; the whole field the first time and after [`DeviceMarkers::reset`].
//!
//! **Interior sums** (`interior`, [`DeviceMarkers::enable_interior`]): `coupling::interior`'s
//! `P`, `L`, `V` of the fixed and free bodies before the forcing and after the fluid step, for
//! spheres, cylinders and cuboids, with compensated f32 sums (downloaded, 112 bytes a body).
//!
//! **Not on the device (left to the host, or not done):** the band (the device needs none:
//! it reads the fluid at the stencil nodes themselves), the composition of the loads with the
//! interior term, the implicit shell reaction and the body update with contacts
//! (`coupling::loads`, `contact`): [`DeviceMarkers::loads`] gives the IBM part of the loads.
//! The CPU computes in f64 from the f32 fluid; here everything is f32 (the agreement is
//! measured in `tests/device_markers.rs`).

use wgpu::util::DeviceExt;

use super::fluid::DeviceFluid;
use super::{compute_pipeline, read_buffers, DeviceError};
use crate::ibm::DeltaKernel;
use crate::lattice::Grid;
use crate::rigid::{Marker, RigidBody, Vec3};

/// The kernels' source.
const IBM: &str = include_str!("shaders/ibm.wgsl");

/// Markers per chunk of the loads' first stage: a constant, so the order of the sums does not
/// depend on the work-group size.
pub const CHUNK: usize = 64;

/// 32-bit words of a body's state in the per-step upload (7 four-word entries).
const BODY_WORDS: usize = 28;

/// Binding numbers of `ibm.wgsl`.
mod bind {
    pub const PARAMS: u32 = 0;
    pub const F0: u32 = 1;
    pub const FORCE: u32 = 20;
    pub const ACC: u32 = 23;
    pub const MARKER_BODY: u32 = 26;
    pub const OWNER: u32 = 27;
    pub const BODIES: u32 = 28;
    pub const STENCIL_N: u32 = 29;
    pub const STENCIL_W: u32 = 30;
    pub const ARM: u32 = 31;
    pub const SOLID_U: u32 = 32;
    pub const MARKER_U: u32 = 33;
    pub const INCREMENT: u32 = 34;
    pub const TOTAL: u32 = 35;
    pub const CHUNKS: u32 = 36;
    pub const BODY_CHUNKS: u32 = 37;
    pub const PARTIAL: u32 = 38;
    pub const LOADS: u32 = 39;
    pub const STATUS: u32 = 40;
    pub const SHAPES: u32 = 41;
    pub const ROWS: u32 = 42;
    pub const ROW_SUMS: u32 = 43;
    pub const INTERIOR: u32 = 44;
    /// The number of bindings of the markers' own kernels.
    pub const COUNT: usize = 41;
}

/// A kernel: its pipeline and bind group, and what its threads run over.
struct Kernel {
    pipeline: wgpu::ComputePipeline,
    group: wgpu::BindGroup,
    threads: u32,
}

/// The kernels of a step.
struct Kernels {
    clear: Kernel,
    place: Kernel,
    interpolate: Kernel,
    forcing: Kernel,
    spread: Kernel,
    settle: Kernel,
    chunk_loads: Kernel,
    body_loads: Kernel,
}

/// The immersed-boundary markers of a set of bodies on the device (module docs).
pub struct DeviceMarkers {
    device: wgpu::Device,
    queue: wgpu::Queue,
    grid: Grid,
    periodic: [bool; 3],
    workgroup: u32,
    force_generation: u64,
    n_markers: usize,
    n_bodies: usize,
    params: wgpu::Buffer,
    params_words: Vec<u32>,
    bodies: wgpu::Buffer,
    increment: wgpu::Buffer,
    marker_u: wgpu::Buffer,
    total: wgpu::Buffer,
    arm: wgpu::Buffer,
    loads: wgpu::Buffer,
    status: wgpu::Buffer,
    acc: [wgpu::Buffer; 3],
    force: [wgpu::Buffer; 3],
    staging: wgpu::Buffer,
    kernels: Kernels,
    /// Threads per row of the 2-D dispatch.
    row_groups: u32,
    /// Whether the next placement clears the whole field (first use, after a reset).
    whole_clear: bool,
    /// The kernels' module and the override constants of this kernel and work group.
    module: wgpu::ShaderModule,
    constants: Vec<(&'static str, f64)>,
    /// The fluid's population buffers (for kernels made later).
    pops: Vec<wgpu::Buffer>,
    /// The interior sums, once enabled ([`DeviceMarkers::enable_interior`]).
    interior: Option<interior::Interior>,
}

mod interior;

/// A kernel `entry` of `module` with its bind group of `(binding, buffer)` pairs (the bindings
/// its entry point uses: the layout is derived from it), over `threads` threads.
fn make_kernel(
    device: &wgpu::Device,
    module: &wgpu::ShaderModule,
    constants: &[(&str, f64)],
    entry: &str,
    bindings: &[(u32, &wgpu::Buffer)],
    threads: usize,
) -> Kernel {
    let pipeline = compute_pipeline(device, None, module, entry, constants);
    let entries: Vec<wgpu::BindGroupEntry> = bindings
        .iter()
        .map(|&(k, b)| wgpu::BindGroupEntry { binding: k, resource: b.as_entire_binding() })
        .collect();
    let group = device.create_bind_group(&wgpu::BindGroupDescriptor {
        label: Some(entry),
        layout: &pipeline.get_bind_group_layout(0),
        entries: &entries,
    });
    Kernel { pipeline, group, threads: threads as u32 }
}

/// A storage buffer of `bytes` (at least 16) with `contents` at its start.
fn storage(device: &wgpu::Device, label: &str, contents: &[u8], bytes: usize) -> wgpu::Buffer {
    let size = bytes.max(contents.len()).max(16).next_multiple_of(16);
    let mut data = contents.to_vec();
    data.resize(size, 0);
    device.create_buffer_init(&wgpu::util::BufferInitDescriptor {
        label: Some(label),
        contents: &data,
        usage: wgpu::BufferUsages::STORAGE | wgpu::BufferUsages::COPY_DST | wgpu::BufferUsages::COPY_SRC,
    })
}

/// The kernel's index in `ibm.wgsl`'s `KERNEL` override.
fn kernel_id(k: DeltaKernel) -> u32 {
    match k {
        DeltaKernel::Linear => 0,
        DeltaKernel::Roma3 => 1,
        DeltaKernel::Peskin4 => 2,
    }
}

impl DeviceMarkers {
    /// The markers of `sets[b]` (body `b`'s forcing markers in its body frame, in order; the
    /// global order is body by body) on the device fluid `fluid`, whose force field must be on,
    /// with the delta function `kernel`, run in work groups of `workgroup` threads.
    ///
    /// # Errors
    /// [`DeviceError::Mismatch`] when the fluid is not f32, its force field is off or the work-group size is
    /// 0; [`DeviceError::Limit`] beyond the adapter's limits; [`DeviceError::Wgpu`] when a
    /// kernel does not compile.
    pub fn new(
        fluid: &DeviceFluid,
        sets: &[&[Marker]],
        kernel: DeltaKernel,
        workgroup: u32,
    ) -> Result<Self, DeviceError> {
        if fluid.precision() != "f32" {
            return Err(DeviceError::Mismatch(format!(
                "the markers work on an f32 device fluid, not {}",
                fluid.precision()
            )));
        }
        let (device, queue) = fluid.device_queue();
        let (device, queue) = (device.clone(), queue.clone());
        let Some((force, force_generation)) = fluid.force_buffers() else {
            return Err(DeviceError::Mismatch(
                "the device fluid's force field is off: the markers spread into it".into(),
            ));
        };
        if workgroup == 0 {
            return Err(DeviceError::Mismatch("work-group size 0: allowed 1 and more".into()));
        }
        let limits = device.limits();
        let adapter = fluid.adapter().to_string();
        if workgroup > limits.max_compute_workgroup_size_x.min(limits.max_compute_invocations_per_workgroup) {
            return Err(DeviceError::Limit {
                what: "work-group size".into(),
                need: workgroup as u64,
                limit: limits.max_compute_workgroup_size_x as u64,
                adapter,
            });
        }
        let grid = fluid.grid();
        let stride = fluid.stride();
        let n_bodies = sets.len();
        let n_markers: usize = sets.iter().map(|s| s.len()).sum();
        let acc_bytes = (8 * stride) as u64;
        if acc_bytes > limits.max_storage_buffer_binding_size.min(limits.max_buffer_size) {
            return Err(DeviceError::Limit {
                what: "a component's fixed-point sums (bytes)".into(),
                need: acc_bytes,
                limit: limits.max_storage_buffer_binding_size,
                adapter,
            });
        }
        if n_markers > u32::MAX as usize / 2 {
            return Err(DeviceError::Limit {
                what: "markers".into(),
                need: n_markers as u64,
                limit: u32::MAX as u64 / 2,
                adapter,
            });
        }

        // The markers once: body-frame position and area, owner; the chunks of the loads.
        let mut marker_body = Vec::with_capacity(4 * n_markers);
        let mut owner = Vec::with_capacity(n_markers);
        let mut chunks: Vec<[u32; 4]> = Vec::new();
        let mut body_chunks: Vec<[u32; 4]> = Vec::with_capacity(n_bodies);
        let mut start = 0usize;
        for (b, set) in sets.iter().enumerate() {
            for m in set.iter() {
                let p = m.position;
                marker_body.extend([p.x as f32, p.y as f32, p.z as f32, m.area as f32]);
                owner.push(b as u32);
            }
            let first = chunks.len() as u32;
            for c in (0..set.len()).step_by(CHUNK) {
                let end = (c + CHUNK).min(set.len());
                chunks.push([(start + c) as u32, (start + end) as u32, b as u32, 0]);
            }
            body_chunks.push([first, chunks.len() as u32, 0, 0]);
            start += set.len();
        }
        let n_chunks = chunks.len();

        let max_groups = limits.max_compute_workgroups_per_dimension;
        let row_groups = (n_markers.max(n_chunks).max(n_bodies).max(1) as u64)
            .div_ceil(workgroup as u64)
            .clamp(1, max_groups as u64) as u32;
        let body = fluid.body_force();
        let periodic = fluid.periodic();
        let params_words: Vec<u32> = vec![
            grid.nx as u32,
            grid.ny as u32,
            grid.nz as u32,
            (grid.nx + 2) as u32,
            (grid.ny + 2) as u32,
            n_markers as u32,
            n_bodies as u32,
            n_chunks as u32,
            row_groups * workgroup,
            0,
            periodic[0] as u32,
            periodic[1] as u32,
            periodic[2] as u32,
            0,
            0,
            0,
            body[0].to_bits(),
            body[1].to_bits(),
            body[2].to_bits(),
            0,
        ];
        let params = device.create_buffer_init(&wgpu::util::BufferInitDescriptor {
            label: Some("ibm params"),
            contents: bytemuck::cast_slice(&params_words),
            usage: wgpu::BufferUsages::UNIFORM | wgpu::BufferUsages::COPY_DST,
        });
        let m16 = 16 * n_markers;
        let cast = bytemuck::cast_slice::<u32, u8>;
        let castf = bytemuck::cast_slice::<f32, u8>;
        let marker_body = storage(&device, "marker body", castf(&marker_body), 0);
        let owner = storage(&device, "owner", cast(&owner), 0);
        let bodies = storage(&device, "bodies", &[], 4 * BODY_WORDS * n_bodies);
        let stencil_n = storage(&device, "stencil nodes", &[], m16);
        let stencil_w = storage(&device, "stencil weights", &[], 3 * m16);
        let arm = storage(&device, "arm", &[], m16);
        let solid_u = storage(&device, "solid velocity", &[], m16);
        let marker_u = storage(&device, "marker velocity", &[], m16);
        let increment = storage(&device, "increment", &[], m16);
        let total = storage(&device, "total", &[], m16);
        let chunks = storage(&device, "chunks", cast(chunks.as_flattened()), 0);
        let body_chunks = storage(&device, "body chunks", cast(body_chunks.as_flattened()), 0);
        let partial = storage(&device, "partial", &[], 32 * n_chunks);
        let loads = storage(&device, "loads", &[], 32 * n_bodies);
        let status = storage(&device, "status", &[], 16);
        let acc = [0, 1, 2].map(|a| storage(&device, ["acc x", "acc y", "acc z"][a], &[], 8 * stride));
        let staging = device.create_buffer(&wgpu::BufferDescriptor {
            label: Some("ibm staging"),
            size: (m16.max(32 * n_bodies + 16).max(16)) as u64,
            usage: wgpu::BufferUsages::MAP_READ | wgpu::BufferUsages::COPY_DST,
            mapped_at_creation: false,
        });

        let mut buffers: Vec<Option<&wgpu::Buffer>> = vec![None; bind::COUNT];
        buffers[bind::PARAMS as usize] = Some(&params);
        for (q, b) in fluid.population_buffers().iter().enumerate() {
            buffers[bind::F0 as usize + q] = Some(b);
        }
        for a in 0..3 {
            buffers[bind::FORCE as usize + a] = Some(&force[a]);
            buffers[bind::ACC as usize + a] = Some(&acc[a]);
        }
        for (k, b) in [
            (bind::MARKER_BODY, &marker_body),
            (bind::OWNER, &owner),
            (bind::BODIES, &bodies),
            (bind::STENCIL_N, &stencil_n),
            (bind::STENCIL_W, &stencil_w),
            (bind::ARM, &arm),
            (bind::SOLID_U, &solid_u),
            (bind::MARKER_U, &marker_u),
            (bind::INCREMENT, &increment),
            (bind::TOTAL, &total),
            (bind::CHUNKS, &chunks),
            (bind::BODY_CHUNKS, &body_chunks),
            (bind::PARTIAL, &partial),
            (bind::LOADS, &loads),
            (bind::STATUS, &status),
        ] {
            buffers[k as usize] = Some(b);
        }

        let scope = device.push_error_scope(wgpu::ErrorFilter::Validation);
        let module = device.create_shader_module(wgpu::ShaderModuleDescriptor {
            label: Some("ibm"),
            source: wgpu::ShaderSource::Wgsl(IBM.into()),
        });
        let width = kernel.width() as f64;
        let kid = kernel_id(kernel) as f64;
        let constants = vec![("WG", workgroup as f64), ("KERNEL", kid), ("WIDTH", width)];
        let make = |entry: &str, clear: bool, bindings: &[u32], threads: usize| -> Kernel {
            let mut constants = constants.clone();
            if entry == "settle" {
                constants.push(("CLEAR", clear as u8 as f64));
            }
            let pairs: Vec<(u32, &wgpu::Buffer)> = bindings
                .iter()
                .map(|&k| (k, buffers[k as usize].expect("every binding has a buffer")))
                .collect();
            make_kernel(&device, &module, &constants, entry, &pairs, threads)
        };
        use bind::*;
        let fluid_bindings: Vec<u32> =
            (0..20).chain([FORCE, FORCE + 1, FORCE + 2, STENCIL_N, STENCIL_W, MARKER_U]).collect();
        let settle_bindings = [PARAMS, FORCE, FORCE + 1, FORCE + 2, ACC, ACC + 1, ACC + 2, STENCIL_N];
        let kernels = Kernels {
            clear: make("settle", true, &settle_bindings, n_markers),
            place: make(
                "place",
                false,
                &[PARAMS, MARKER_BODY, OWNER, BODIES, STENCIL_N, STENCIL_W, ARM, SOLID_U, TOTAL, STATUS],
                n_markers,
            ),
            interpolate: make("interpolate", false, &fluid_bindings, n_markers),
            forcing: make(
                "direct_forcing",
                false,
                &[PARAMS, MARKER_BODY, SOLID_U, MARKER_U, INCREMENT, TOTAL],
                n_markers,
            ),
            spread: make(
                "spread",
                false,
                &[PARAMS, ACC, ACC + 1, ACC + 2, STENCIL_N, STENCIL_W, INCREMENT],
                n_markers,
            ),
            settle: make("settle", false, &settle_bindings, n_markers),
            chunk_loads: make("chunk_loads", false, &[PARAMS, ARM, TOTAL, CHUNKS, PARTIAL], n_chunks),
            body_loads: make("body_loads", false, &[PARAMS, BODY_CHUNKS, PARTIAL, LOADS], n_bodies),
        };
        if let Some(e) = pollster::block_on(scope.pop()) {
            return Err(DeviceError::Wgpu(e.to_string()));
        }
        Ok(Self {
            device,
            queue,
            grid,
            periodic,
            workgroup,
            force_generation,
            n_markers,
            n_bodies,
            params,
            params_words,
            bodies,
            increment,
            marker_u,
            total,
            arm,
            loads,
            status,
            acc,
            force: force.clone(),
            staging,
            kernels,
            row_groups,
            whole_clear: true,
            module,
            constants,
            pops: fluid.population_buffers().to_vec(),
            interior: None,
        })
    }

    /// Number of markers.
    pub fn len(&self) -> usize {
        self.n_markers
    }

    /// Whether there are no markers.
    pub fn is_empty(&self) -> bool {
        self.n_markers == 0
    }

    /// The work-group size.
    pub fn workgroup(&self) -> u32 {
        self.workgroup
    }

    /// Which axes are periodic (the device fluid's).
    pub fn periodic(&self) -> [bool; 3] {
        self.periodic
    }

    /// Makes the next [`DeviceMarkers::place`] clear the whole force field and sums (after the
    /// device fluid's field was uploaded from the host, e.g. after a restore).
    pub fn reset(&mut self) {
        self.whole_clear = true;
    }

    /// Uploads the bodies' states for this step (the only per-step upload: 112 bytes a body):
    /// the centre split into an integer origin and the offset from it (in f64, then the offset
    /// rounded to f32), the rotation matrix (from the quaternion in f64, rounded to f32), the
    /// velocity and the angular velocity.
    ///
    /// # Panics
    /// If `bodies` does not have one body per marker set.
    pub fn set_bodies(&mut self, bodies: &[RigidBody]) {
        assert_eq!(bodies.len(), self.n_bodies, "one body per marker set");
        let mut words = Vec::with_capacity(BODY_WORDS * bodies.len());
        for b in bodies {
            let p = b.position;
            let origin = [p.x.floor(), p.y.floor(), p.z.floor()];
            let frac = [p.x - origin[0], p.y - origin[1], p.z - origin[2]];
            let r = b.rotation_matrix();
            let f = |v: f64| (v as f32).to_bits();
            words.extend(origin.map(|o| (o as i32) as u32));
            words.push(0);
            words.extend(frac.map(f));
            words.push(0);
            for i in 0..3 {
                words.extend([f(r[(i, 0)]), f(r[(i, 1)]), f(r[(i, 2)]), 0]);
            }
            let (v, w) = (b.velocity, b.angular_velocity);
            words.extend([f(v.x), f(v.y), f(v.z), 0, f(w.x), f(w.y), f(w.z), 0]);
        }
        if !words.is_empty() {
            self.queue.write_buffer(&self.bodies, 0, bytemuck::cast_slice(&words));
        }
    }

    /// Checks that `fluid` is the device fluid these markers were made on, with the same force
    /// buffers, and writes the parameters of its present time (the AA parity).
    fn prepare(&mut self, fluid: &DeviceFluid) -> Result<(), DeviceError> {
        let same = fluid.grid() == self.grid
            && fluid.force_buffers().is_some_and(|(_, g)| g == self.force_generation)
            && self.device == *fluid.device_queue().0;
        if !same {
            return Err(DeviceError::Mismatch(
                "these markers were made on another device fluid, or its force field was turned off".into(),
            ));
        }
        self.params_words[9] = (fluid.time() % 2) as u32;
        self.queue.write_buffer(&self.params, 0, bytemuck::cast_slice(&self.params_words));
        Ok(())
    }

    /// Records `kernel` over its threads.
    fn dispatch(&self, pass: &mut wgpu::ComputePass<'_>, kernel: &Kernel) {
        let groups = kernel.threads.div_ceil(self.workgroup);
        if groups == 0 {
            return;
        }
        let gx = groups.min(self.row_groups);
        pass.set_pipeline(&kernel.pipeline);
        pass.set_bind_group(0, &kernel.group, &[]);
        pass.dispatch_workgroups(gx, groups.div_ceil(self.row_groups), 1);
    }

    /// Records `kernels` into one compute pass (after clearing the whole field if due) and
    /// submits it.
    fn submit(&self, kernels: &[&Kernel], clear_all: bool) {
        let mut enc = self.device.create_command_encoder(&wgpu::CommandEncoderDescriptor { label: None });
        if clear_all {
            for b in self.force.iter().chain(&self.acc) {
                enc.clear_buffer(b, 0, None);
            }
        }
        {
            let mut pass =
                enc.begin_compute_pass(&wgpu::ComputePassDescriptor { label: None, timestamp_writes: None });
            for k in kernels {
                self.dispatch(&mut pass, k);
            }
        }
        self.queue.submit([enc.finish()]);
    }

    /// Phases 1, 2 and 4 of the coupled step: clears the force field and its sums where the
    /// previous placement's stencils spread (everywhere the first time and after a reset),
    /// then computes every marker's arm, solid velocity and stencil from the bodies' states of
    /// [`DeviceMarkers::set_bodies`], and zeroes the markers' force totals.
    ///
    /// # Errors
    /// [`DeviceError::Mismatch`] for another device fluid.
    pub fn place(&mut self, fluid: &DeviceFluid) -> Result<(), DeviceError> {
        self.prepare(fluid)?;
        self.queue.write_buffer(&self.status, 0, bytemuck::cast_slice(&[u32::MAX; 4]));
        let whole = std::mem::take(&mut self.whole_clear);
        let k = &self.kernels;
        if whole {
            self.submit(&[&k.place], true);
        } else {
            self.submit(&[&k.clear, &k.place], false);
        }
        Ok(())
    }

    /// Interpolates the fluid velocity `u = (j + F/2)/ρ` (the force field as it stands) at the
    /// placed markers, `u_m = Σ δ u`: the first half of a forcing iteration, for tests and
    /// diagnostics ([`DeviceMarkers::marker_velocities`] reads it).
    ///
    /// # Errors
    /// [`DeviceError::Mismatch`] for another device fluid.
    pub fn interpolate(&mut self, fluid: &DeviceFluid) -> Result<(), DeviceError> {
        self.prepare(fluid)?;
        self.submit(&[&self.kernels.interpolate], false);
        Ok(())
    }

    /// Spreads the given marker forces (one per marker, global order) into the force field at
    /// the placed stencils, adding to what the field holds since the last placement: for tests
    /// of the spreading alone.
    ///
    /// # Errors
    /// [`DeviceError::Mismatch`] for another device fluid or a force count that is not the
    /// marker count.
    pub fn spread_forces(&mut self, fluid: &DeviceFluid, forces: &[[f32; 3]]) -> Result<(), DeviceError> {
        if forces.len() != self.n_markers {
            return Err(DeviceError::Mismatch(format!(
                "{} forces for {} markers",
                forces.len(),
                self.n_markers
            )));
        }
        self.prepare(fluid)?;
        let words: Vec<f32> = forces.iter().flat_map(|f| [f[0], f[1], f[2], 0.0]).collect();
        if !words.is_empty() {
            self.queue.write_buffer(&self.increment, 0, bytemuck::cast_slice(&words));
        }
        let k = &self.kernels;
        self.submit(&[&k.spread, &k.settle], false);
        Ok(())
    }

    /// Phases 1–2, 4 and 5 of the coupled step on the device: [`DeviceMarkers::place`], then
    /// `iterations` direct-forcing iterations, each: interpolation of `u = (j + F/2)/ρ` with
    /// the present force field, `ΔF_m = 2 (U_m − u_m) A_m` added to the marker's total,
    /// spreading of `ΔF_m` into the field's fixed-point sums and the sums stored as the field.
    /// Recorded into one submission; does not wait.
    ///
    /// # Errors
    /// [`DeviceError::Mismatch`] for another device fluid.
    pub fn force(&mut self, fluid: &DeviceFluid, iterations: usize) -> Result<(), DeviceError> {
        self.prepare(fluid)?;
        self.queue.write_buffer(&self.status, 0, bytemuck::cast_slice(&[u32::MAX; 4]));
        let whole = std::mem::take(&mut self.whole_clear);
        let k = &self.kernels;
        let mut list: Vec<&Kernel> = Vec::with_capacity(2 + 4 * iterations);
        if !whole {
            list.push(&k.clear);
        }
        list.push(&k.place);
        for _ in 0..iterations {
            list.extend([&k.interpolate, &k.forcing, &k.spread, &k.settle]);
        }
        self.submit(&list, whole);
        Ok(())
    }

    /// Each body's IBM loads from the markers' totals of the step: `(−Σ F_m, −Σ r_m × F_m)`,
    /// torques about the body's centre, summed in the fixed order of the module docs in f32;
    /// downloaded (32 bytes a body). Waits for the device.
    ///
    /// # Errors
    /// [`DeviceError::Marker`] when a marker could not be placed (outside the box on a walled
    /// axis, or not finite: the step ran without it); [`DeviceError::Wgpu`] when the read-back
    /// fails.
    pub fn loads(&self) -> Result<Vec<(Vec3, Vec3)>, DeviceError> {
        let k = &self.kernels;
        self.submit(&[&k.chunk_loads, &k.body_loads], false);
        let bytes = 32 * self.n_bodies;
        let mut words = vec![0u32; (bytes + 16) / 4];
        self.read(&[(&self.loads, bytes), (&self.status, 16)], bytemuck::cast_slice_mut(&mut words))?;
        self.parse_loads(&words)
    }

    /// The loads from the words of `loads` followed by the status word.
    fn parse_loads(&self, words: &[u32]) -> Result<Vec<(Vec3, Vec3)>, DeviceError> {
        let bad = words[8 * self.n_bodies];
        if bad != u32::MAX {
            return Err(DeviceError::Marker(bad as usize));
        }
        let f = |i: usize| f32::from_bits(words[i]) as f64;
        Ok((0..self.n_bodies)
            .map(|b| {
                let o = 8 * b;
                (Vec3::new(f(o), f(o + 1), f(o + 2)), Vec3::new(f(o + 4), f(o + 5), f(o + 6)))
            })
            .collect())
    }

    /// The interpolated fluid velocity at every marker (global order) from the last
    /// interpolation. Waits for the device.
    ///
    /// # Errors
    /// [`DeviceError::Wgpu`] when the read-back fails.
    pub fn marker_velocities(&self) -> Result<Vec<[f32; 3]>, DeviceError> {
        self.per_marker(&self.marker_u)
    }

    /// Every marker's force on the fluid in the step so far, `Σ_k ΔF_m^k` (global order).
    /// Waits for the device.
    ///
    /// # Errors
    /// [`DeviceError::Wgpu`] when the read-back fails.
    pub fn marker_forces(&self) -> Result<Vec<[f32; 3]>, DeviceError> {
        self.per_marker(&self.total)
    }

    /// Every marker's arm `R r` from its body's centre (world frame) at the last placement;
    /// its world position is the body's centre plus the arm. Waits for the device.
    ///
    /// # Errors
    /// [`DeviceError::Wgpu`] when the read-back fails.
    pub fn marker_arms(&self) -> Result<Vec<[f32; 3]>, DeviceError> {
        self.per_marker(&self.arm)
    }

    /// A per-marker array of four-f32 entries, their first three values.
    fn per_marker(&self, buffer: &wgpu::Buffer) -> Result<Vec<[f32; 3]>, DeviceError> {
        let mut v = vec![0.0f32; 4 * self.n_markers];
        self.read(&[(buffer, 16 * self.n_markers)], bytemuck::cast_slice_mut(&mut v))?;
        Ok(v.chunks_exact(4).map(|c| [c[0], c[1], c[2]]).collect())
    }

    /// Copies the first bytes of each buffer, one after the other, into `out` through the
    /// staging buffer, and waits.
    fn read(&self, parts: &[(&wgpu::Buffer, usize)], out: &mut [u8]) -> Result<(), DeviceError> {
        read_buffers(&self.device, &self.queue, &self.staging, parts, out)
    }
}
