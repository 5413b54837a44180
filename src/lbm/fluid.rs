//! The lattice-Boltzmann fluid: storage, boundaries, time stepping and macroscopic fields.
//!
//! **Padded grid.** Interior node `(x, y, z)`, `0 ≤ x < nx` etc., lives at padded index
//! `(x+1) + px ((y+1) + py (z+1))` with `px = nx+2`, `py = ny+2`, `pz = nz+2`. The ghost layer
//! is never collided; its slots carry the populations that cross the box faces, so that the
//! kernel reads and writes at constant offsets with no branches.
//!
//! **One time step** ([`Fluid::step`]) is one AA half of the cycle:
//! 1. even time: local collide (`(x,i) → (x,ī)`), then `pre` link operations fill the ghost
//!    and obstacle slots that the next odd sweep reads (periodic copies; bounce-back with the
//!    wall term);
//! 2. odd time: stream–collide sweep (`(x−c_i, ī) → (x+c_i, i)`), then `post` link operations
//!    move what it wrote into ghost and obstacle slots back into the box (periodic images;
//!    bounce-back with the wall term).
//!
//! Reads: populations, the force field (when on), obstacle flags. Writes: populations.
//! `step` performs no I/O and no allocation, and never clamps: see [`Fluid::health`].

use rayon::prelude::*;

use super::boundary::{minus_c, resolve, wall_term, Boundaries, LinkEnd};
use super::collision::{moments, Rates};
use super::kernel::{sweep, Isa, Sweep};
use super::{FluidError, FluidParams, Health, Real};
use crate::lattice::{Grid, C, CS2, OPP, Q, W};
use crate::util::SharedMut;

/// One boundary link: before the odd sweep `f[ghost] ← f[own] + term`; after it
/// `f[own] ← f[ghost] + term`. For periodic links `own` is the periodic image slot and
/// `term = 0` is not added.
#[derive(Clone, Copy, Debug)]
struct Link<T> {
    own: usize,
    ghost: usize,
    term: T,
}

/// The complete state of a [`Fluid`] at an even time step, for checkpoints. At even time the
/// AA array is in the standard layout and the ghost slots carry nothing (the next even sweep's
/// `pre` links refill them), so the interior populations, the force field and the time define
/// the future exactly: restoring gives a bitwise identical continuation.
#[derive(Clone, Debug, PartialEq)]
pub struct FluidState<T> {
    /// Time step (even).
    pub time: u64,
    /// The grid the state belongs to.
    pub grid: Grid,
    /// Shifted populations, `q`-major then interior index: `populations[q·N + n]`.
    pub populations: Vec<T>,
    /// Force density field, `a`-major (`force[a·N + n]`), if the field is on.
    pub force: Option<Vec<T>>,
}

/// The D3Q19 lattice-Boltzmann fluid on a box, with storage precision `T` (`f32` or `f64`).
pub struct Fluid<T: Real> {
    grid: Grid,
    params: FluidParams,
    boundaries: Boundaries,
    px: usize,
    py: usize,
    stride: usize,
    f: Vec<T>,
    /// Force density field (`3·stride`), empty while the field is off.
    force: Vec<T>,
    /// Per padded node: ghost or obstacle.
    solid: Vec<bool>,
    /// Per interior node: obstacle (kept for rebuilding and queries).
    obstacle: Vec<bool>,
    row_has_solid: Vec<bool>,
    bounce: Vec<Link<T>>,
    periodic: Vec<Link<T>>,
    off: [isize; Q],
    rates: Rates<T>,
    body: [T; 3],
    time: u64,
    isa: Isa,
}

/// Rounds `n` up to a multiple of 64 and adds 32 elements, so that the 19 arrays are never a
/// power of two apart (which would map the same node of every array to the same cache set).
fn padded_stride(n: usize) -> usize {
    n.div_ceil(64) * 64 + 32
}

/// A zeroed array for the lattice. Large zeroed allocations come straight from `mmap`, untouched;
/// asking for transparent huge pages before the first write cuts TLB misses of the 19–38
/// concurrent streams (the kernel's pages are then 2 MiB instead of 4 KiB where the system
/// allows it; where it does not, nothing changes).
fn lattice_array<T: Real>(n: usize) -> Vec<T> {
    let v = vec![T::ZERO; n];
    #[cfg(target_os = "linux")]
    {
        const HUGE: usize = 1 << 21;
        let start = v.as_ptr() as usize;
        let end = start + std::mem::size_of_val(v.as_slice());
        let first = start.div_ceil(HUGE) * HUGE;
        if end > first + HUGE {
            // SAFETY: the range lies inside the allocation; MADV_HUGEPAGE is advice only and
            // does not change the contents.
            unsafe {
                libc::madvise(first as *mut libc::c_void, (end - first) / HUGE * HUGE, libc::MADV_HUGEPAGE);
            }
        }
    }
    v
}

/// Shifted equilibrium `h_i^eq = w_i [δρ + ρ (3 c·u + 9/2 (c·u)² − 3/2 u²)]` in `f64`.
pub fn equilibrium(rho: f64, u: [f64; 3]) -> [f64; Q] {
    let usq = u[0] * u[0] + u[1] * u[1] + u[2] * u[2];
    std::array::from_fn(|i| {
        let cu: f64 = (0..3).map(|a| C[i][a] as f64 * u[a]).sum();
        W[i] * ((rho - 1.0) + rho * (3.0 * cu + 4.5 * cu * cu - 1.5 * usq))
    })
}

impl<T: Real> Fluid<T> {
    /// A fluid at rest (`ρ = 1`, `u = 0`) filling the whole box, with no obstacles.
    pub fn new(grid: Grid, params: FluidParams, boundaries: Boundaries) -> Result<Self, FluidError> {
        params.validate()?;
        boundaries.validate()?;
        if grid.nx < 1 || grid.ny < 1 || grid.nz < 1 {
            return Err(FluidError::Grid { grid });
        }
        let (px, py, pz) = (grid.nx + 2, grid.ny + 2, grid.nz + 2);
        let padded = px * py * pz;
        if padded >= u32::MAX as usize {
            return Err(FluidError::Grid { grid });
        }
        let stride = padded_stride(padded);
        let off = std::array::from_fn(|i| {
            let c = C[i];
            c[0] as isize + px as isize * (c[1] as isize + py as isize * c[2] as isize)
        });
        let (op, om) = params.rates();
        let mut fluid = Self {
            grid,
            params,
            boundaries,
            px,
            py,
            stride,
            f: lattice_array(Q * stride),
            force: Vec::new(),
            solid: vec![true; padded],
            obstacle: vec![false; grid.nodes()],
            row_has_solid: vec![false; grid.ny * grid.nz],
            bounce: Vec::new(),
            periodic: Vec::new(),
            off,
            rates: Rates::new(op, om),
            body: params.body_force.map(T::from_f64),
            time: 0,
            isa: Isa::detect(),
        };
        fluid.rebuild_geometry();
        Ok(fluid)
    }

    /// The grid.
    pub fn grid(&self) -> Grid {
        self.grid
    }

    /// The fluid parameters.
    pub fn params(&self) -> &FluidParams {
        &self.params
    }

    /// The face boundaries.
    pub fn boundaries(&self) -> &Boundaries {
        &self.boundaries
    }

    /// Number of completed time steps.
    pub fn time(&self) -> u64 {
        self.time
    }

    /// The force density `F` that [`Fluid::for_each_in_run`] reports at a node whose
    /// force-field entry is zero (or without a field): the uniform body force, formed as
    /// `(0 + F_body)` in the storage precision and widened, with the same operations.
    pub fn zero_field_force(&self) -> [f64; 3] {
        [0, 1, 2].map(|a| (T::ZERO + self.body[a]).to_f64())
    }

    /// The instruction set the fused kernel runs with.
    pub fn isa(&self) -> Isa {
        self.isa
    }

    /// Chooses the instruction set (for equivalence tests and benchmarks). Falls back to the
    /// best available if `isa` is not supported by this CPU.
    pub fn set_isa(&mut self, isa: Isa) {
        self.isa = if Isa::available().contains(&isa) { isa } else { Isa::detect() };
    }

    /// Bytes moved per node update by the AA pattern (19 reads and 19 writes of `T`).
    pub fn bytes_per_update() -> usize {
        2 * Q * std::mem::size_of::<T>()
    }

    #[inline]
    fn pidx(&self, x: usize, y: usize, z: usize) -> usize {
        (x + 1) + self.px * ((y + 1) + self.py * (z + 1))
    }

    /// Marks interior nodes as solid obstacles (stationary half-way bounce-back), replacing
    /// any previous obstacles. Populations of fluid nodes are kept; newly freed nodes start
    /// at rest equilibrium. Only at even time (the standard layout): at odd time the AA
    /// state holds post-collision values that a geometry change cannot re-route.
    pub fn set_obstacles(
        &mut self,
        is_solid: impl Fn(usize, usize, usize) -> bool,
    ) -> Result<(), FluidError> {
        if !self.time.is_multiple_of(2) {
            return Err(FluidError::OddTime { time: self.time });
        }
        let g = self.grid;
        let was = std::mem::take(&mut self.obstacle);
        self.obstacle = (0..g.nodes())
            .map(|n| {
                let [x, y, z] = g.coords(n);
                is_solid(x, y, z)
            })
            .collect();
        for n in 0..g.nodes() {
            if was[n] && !self.obstacle[n] {
                let [x, y, z] = g.coords(n);
                let p = self.pidx(x, y, z);
                for q in 0..Q {
                    self.f[q * self.stride + p] = T::ZERO;
                }
            }
        }
        self.rebuild_geometry();
        Ok(())
    }

    /// Whether interior node `(x, y, z)` is an obstacle.
    pub fn is_obstacle(&self, x: usize, y: usize, z: usize) -> bool {
        self.obstacle[self.grid.index(x, y, z)]
    }

    fn rebuild_geometry(&mut self) {
        let g = self.grid;
        let (px, py) = (self.px, self.py);
        let pidx = |x: usize, y: usize, z: usize| (x + 1) + px * ((y + 1) + py * (z + 1));
        self.solid.iter_mut().for_each(|s| *s = true);
        for z in 0..g.nz {
            for y in 0..g.ny {
                let mut any = false;
                for x in 0..g.nx {
                    let o = self.obstacle[g.index(x, y, z)];
                    self.solid[pidx(x, y, z)] = o;
                    any |= o;
                }
                self.row_has_solid[y + g.ny * z] = any;
            }
        }
        let obstacle = &self.obstacle;
        let is_solid = |n: [usize; 3]| obstacle[g.index(n[0], n[1], n[2])];
        let mut bounce = Vec::new();
        let mut periodic = Vec::new();
        for z in 0..g.nz {
            for y in 0..g.ny {
                for x in 0..g.nx {
                    if obstacle[g.index(x, y, z)] {
                        continue;
                    }
                    let own = pidx(x, y, z);
                    for i in 1..Q {
                        // The slot node x reads h_i from in the odd sweep: (x − c_i, ī).
                        let ghost = OPP[i] * self.stride + (own as isize - self.off[i]) as usize;
                        match resolve(&g, &self.boundaries, &is_solid, [x, y, z], minus_c(i)) {
                            LinkEnd::Interior(_) => {}
                            LinkEnd::Periodic(n) => {
                                let image = OPP[i] * self.stride + pidx(n[0], n[1], n[2]);
                                periodic.push(Link { own: image, ghost, term: T::ZERO });
                            }
                            LinkEnd::Wall(uw) => bounce.push(Link {
                                own: i * self.stride + own,
                                ghost,
                                term: T::from_f64(wall_term(i, uw)),
                            }),
                            LinkEnd::Obstacle => bounce.push(Link {
                                own: i * self.stride + own,
                                ghost,
                                term: T::from_f64(wall_term(i, [0.0; 3])),
                            }),
                        }
                    }
                }
            }
        }
        self.bounce = bounce;
        self.periodic = periodic;
    }

    /// Sets every fluid node to the equilibrium of `init(x, y, z) = (ρ, u)` and resets time
    /// to zero.
    pub fn initialize(&mut self, init: impl Fn(usize, usize, usize) -> (f64, [f64; 3]) + Sync) {
        let g = self.grid;
        let mut std = vec![0.0f64; g.nodes() * Q];
        std.par_chunks_mut(Q).enumerate().for_each(|(n, out)| {
            let [x, y, z] = g.coords(n);
            let (rho, u) = init(x, y, z);
            out.copy_from_slice(&equilibrium(rho, u));
        });
        self.load_standard(&std);
    }

    /// Loads shifted populations `h` (node-major, `Q` per node, interior index order) into the
    /// standard layout and sets time to zero.
    fn load_standard(&mut self, h: &[f64]) {
        let g = self.grid;
        for n in 0..g.nodes() {
            let [x, y, z] = g.coords(n);
            let p = self.pidx(x, y, z);
            for q in 0..Q {
                self.f[q * self.stride + p] = T::from_f64(h[n * Q + q]);
            }
        }
        self.time = 0;
    }

    /// Turns on the per-node force density field (zero-initialised). The immersed boundary
    /// method writes into it; the kernel then reads three more arrays per node.
    pub fn enable_force_field(&mut self) {
        if self.force.is_empty() {
            self.force = lattice_array(3 * self.stride);
        }
    }

    /// Sets the whole force density field to zero (if it is on).
    pub fn clear_force_field(&mut self) {
        self.force.par_chunks_mut(1 << 16).for_each(|c| c.iter_mut().for_each(|v| *v = T::ZERO));
    }

    /// Whether the force density field is on.
    pub fn force_field_enabled(&self) -> bool {
        !self.force.is_empty()
    }

    /// Sets the force density at interior node `(x, y, z)` (requires the field to be on).
    pub fn set_force(&mut self, x: usize, y: usize, z: usize, fv: [f64; 3]) {
        assert!(self.force_field_enabled(), "force field is off: call enable_force_field first");
        let p = self.pidx(x, y, z);
        for (a, v) in fv.iter().enumerate() {
            self.force[a * self.stride + p] = T::from_f64(*v);
        }
    }

    /// Force density at interior node `(x, y, z)`: the uniform body force plus the field.
    pub fn force_at(&self, x: usize, y: usize, z: usize) -> [f64; 3] {
        let p = self.pidx(x, y, z);
        std::array::from_fn(|a| {
            let field = if self.force_field_enabled() { self.force[a * self.stride + p] } else { T::ZERO };
            (field + self.body[a]).to_f64()
        })
    }

    /// The state for a checkpoint. Only at even time (see [`FluidState`]).
    pub fn snapshot(&self) -> Result<FluidState<T>, FluidError> {
        if !self.time.is_multiple_of(2) {
            return Err(FluidError::OddTime { time: self.time });
        }
        let g = self.grid;
        let n = g.nodes();
        let gather = |src: &[T], arrays: usize| {
            let mut out = vec![T::ZERO; arrays * n];
            for a in 0..arrays {
                for z in 0..g.nz {
                    for y in 0..g.ny {
                        let from = a * self.stride + self.pidx(0, y, z);
                        let to = a * n + g.index(0, y, z);
                        out[to..to + g.nx].copy_from_slice(&src[from..from + g.nx]);
                    }
                }
            }
            out
        };
        Ok(FluidState {
            time: self.time,
            grid: g,
            populations: gather(&self.f, Q),
            force: self.force_field_enabled().then(|| gather(&self.force, 3)),
        })
    }

    /// Restores a state taken by [`Fluid::snapshot`] on a fluid with the same grid (and the
    /// same parameters, boundaries and obstacles: the caller's responsibility).
    pub fn restore(&mut self, s: &FluidState<T>) -> Result<(), FluidError> {
        let g = self.grid;
        let n = g.nodes();
        if s.grid != g || s.populations.len() != Q * n || s.force.as_ref().is_some_and(|f| f.len() != 3 * n) {
            return Err(FluidError::StateMismatch { grid: s.grid, expected: g });
        }
        if !s.time.is_multiple_of(2) {
            return Err(FluidError::OddTime { time: s.time });
        }
        let scatter = |dst: &mut [T], src: &[T], arrays: usize, stride: usize, px: usize, py: usize| {
            for a in 0..arrays {
                for z in 0..g.nz {
                    for y in 0..g.ny {
                        let to = a * stride + 1 + px * ((y + 1) + py * (z + 1));
                        let from = a * n + g.index(0, y, z);
                        dst[to..to + g.nx].copy_from_slice(&src[from..from + g.nx]);
                    }
                }
            }
        };
        let (stride, px, py) = (self.stride, self.px, self.py);
        scatter(&mut self.f, &s.populations, Q, stride, px, py);
        match &s.force {
            Some(fv) => {
                self.enable_force_field();
                scatter(&mut self.force, fv, 3, stride, px, py);
            }
            None => {
                self.force = Vec::new();
            }
        }
        self.time = s.time;
        Ok(())
    }

    /// Advances one time step (one AA half-cycle; see the module docs).
    pub fn step(&mut self) {
        let odd = !self.time.is_multiple_of(2);
        let s = Sweep {
            f: self.f.as_mut_ptr(),
            force: if self.force_field_enabled() { self.force.as_ptr() } else { std::ptr::null() },
            stride: self.stride,
            off: self.off,
            rates: self.rates,
            body: self.body,
            px: self.px,
            py: self.py,
            nx: self.grid.nx,
            ny: self.grid.ny,
            row_has_solid: self.row_has_solid.as_ptr(),
            solid: self.solid.as_ptr(),
        };
        sweep(self.isa, &s, self.grid.nz, odd, self.params.is_trt(), self.force_field_enabled());
        if odd {
            self.apply_links(false);
        } else {
            self.apply_links(true);
        }
        self.time += 1;
    }

    /// Advances `n` time steps.
    pub fn run(&mut self, n: u64) {
        for _ in 0..n {
            self.step();
        }
    }

    /// `pre = true`: fill ghost and obstacle slots for the next odd sweep.
    /// `pre = false`: return what the odd sweep wrote there into the box.
    fn apply_links(&mut self, pre: bool) {
        let f = SharedMut::new(&mut self.f);
        let f = &f;
        // SAFETY: every slot is the target of at most one link operation per phase
        // (each slot belongs to one link), and sources are never targets in the same phase;
        // every slot is one of the populations' array.
        self.periodic.par_chunks(4096).for_each(|links| unsafe {
            for l in links {
                if pre {
                    f.write(l.ghost, f.read(l.own));
                } else {
                    f.write(l.own, f.read(l.ghost));
                }
            }
        });
        self.bounce.par_chunks(4096).for_each(|links| unsafe {
            for l in links {
                if pre {
                    f.write(l.ghost, f.read(l.own) + l.term);
                } else {
                    f.write(l.own, f.read(l.ghost) + l.term);
                }
            }
        });
    }

    /// Shifted pre-collision populations `h_i = f_i − w_i` at interior node `(x, y, z)` at the
    /// current time, whatever the AA parity.
    pub fn shifted_populations(&self, x: usize, y: usize, z: usize) -> [T; Q] {
        let p = self.pidx(x, y, z);
        if self.time.is_multiple_of(2) {
            std::array::from_fn(|i| self.f[i * self.stride + p])
        } else {
            std::array::from_fn(|i| self.f[OPP[i] * self.stride + (p as isize - self.off[i]) as usize])
        }
    }

    /// Pre-collision populations `f_i` (unshifted) at node `(x, y, z)`, in `f64`.
    pub fn populations(&self, x: usize, y: usize, z: usize) -> [f64; Q] {
        let h = self.shifted_populations(x, y, z);
        std::array::from_fn(|i| h[i].to_f64() + W[i])
    }

    /// All shifted populations, node-major in interior index order, as `f64`.
    pub fn populations_all(&self) -> Vec<f64> {
        let g = self.grid;
        let mut out = vec![0.0; g.nodes() * Q];
        out.par_chunks_mut(Q).enumerate().for_each(|(n, o)| {
            let [x, y, z] = g.coords(n);
            let h = self.shifted_populations(x, y, z);
            for q in 0..Q {
                o[q] = h[q].to_f64();
            }
        });
        out
    }

    /// Density and velocity `(ρ, u)` at a node, with `u = (Σ f_i c_i + F/2)/ρ` (Guo's
    /// half-force correction; `F` the body force plus the node's force density).
    pub fn macroscopic(&self, x: usize, y: usize, z: usize) -> (f64, [f64; 3]) {
        let h: [f64; Q] = self.shifted_populations(x, y, z).map(|v| v.to_f64());
        let (drho, j) = moments(&h);
        let rho = 1.0 + drho;
        let fc = self.force_at(x, y, z);
        (rho, std::array::from_fn(|a| (j[a] + 0.5 * fc[a]) / rho))
    }

    /// Density at a node.
    pub fn density(&self, x: usize, y: usize, z: usize) -> f64 {
        self.macroscopic(x, y, z).0
    }

    /// Velocity at a node (half-force corrected).
    pub fn velocity(&self, x: usize, y: usize, z: usize) -> [f64; 3] {
        self.macroscopic(x, y, z).1
    }

    /// Density and velocity of every interior node (obstacle nodes: `ρ = 1`, `u = 0`),
    /// in interior index order.
    pub fn fields(&self) -> (Vec<f64>, Vec<[f64; 3]>) {
        let g = self.grid;
        let mut rho = vec![1.0; g.nodes()];
        let mut u = vec![[0.0; 3]; g.nodes()];
        rho.par_iter_mut().zip(u.par_iter_mut()).enumerate().for_each(|(n, (r, v))| {
            if !self.obstacle[n] {
                let [x, y, z] = g.coords(n);
                (*r, *v) = self.macroscopic(x, y, z);
            }
        });
        (rho, u)
    }

    /// Per-plane sums, reduced in plane order: bitwise identical for any thread count.
    fn plane_sum<const K: usize>(
        &self,
        per_node: impl Fn(usize, usize, usize) -> [f64; K] + Sync,
    ) -> [f64; K] {
        let g = self.grid;
        let planes: Vec<[f64; K]> = (0..g.nz)
            .into_par_iter()
            .map(|z| {
                let mut acc = [0.0; K];
                for y in 0..g.ny {
                    for x in 0..g.nx {
                        if !self.obstacle[g.index(x, y, z)] {
                            let v = per_node(x, y, z);
                            for k in 0..K {
                                acc[k] += v[k];
                            }
                        }
                    }
                }
                acc
            })
            .collect();
        let mut tot = [0.0; K];
        for p in planes {
            for k in 0..K {
                tot[k] += p[k];
            }
        }
        tot
    }

    /// Total mass `Σ ρ` over fluid nodes. Returned as `(N_fluid, Σ δρ)` summed in `f64`
    /// so that round-off in the deviation is visible: mass = `N_fluid + Σ δρ`.
    pub fn mass_deviation(&self) -> (usize, f64) {
        let n_fluid = self.obstacle.iter().filter(|&&o| !o).count();
        let [d] = self.plane_sum(|x, y, z| {
            let h: [f64; Q] = self.shifted_populations(x, y, z).map(|v| v.to_f64());
            [moments(&h).0]
        });
        (n_fluid, d)
    }

    /// Total mass `Σ ρ` over fluid nodes.
    pub fn total_mass(&self) -> f64 {
        let (n, d) = self.mass_deviation();
        n as f64 + d
    }

    /// Total momentum `Σ ρ u = Σ (j + F/2)` over fluid nodes.
    pub fn total_momentum(&self) -> [f64; 3] {
        self.plane_sum(|x, y, z| {
            let (rho, u) = self.macroscopic(x, y, z);
            [rho * u[0], rho * u[1], rho * u[2]]
        })
    }

    /// Scans every fluid node for non-finite populations, non-positive density and Mach
    /// number `|u|/c_s` above `mach_limit`. Reports the first offending node (lowest index)
    /// and the largest Mach number; it changes nothing.
    pub fn health(&self, mach_limit: f64) -> Health {
        let g = self.grid;
        let cs = CS2.sqrt();
        let per_plane: Vec<Health> = (0..g.nz)
            .into_par_iter()
            .map(|z| {
                let mut hl = Health::default();
                for y in 0..g.ny {
                    for x in 0..g.nx {
                        if self.obstacle[g.index(x, y, z)] {
                            continue;
                        }
                        let h = self.shifted_populations(x, y, z);
                        let node = [x, y, z];
                        if h.iter().any(|v| !v.is_finite()) {
                            hl.note_nonfinite(node);
                            continue;
                        }
                        let (rho, u) = self.macroscopic(x, y, z);
                        if rho <= 0.0 || !rho.is_finite() {
                            hl.note_nonfinite(node);
                            continue;
                        }
                        let mach = (u[0] * u[0] + u[1] * u[1] + u[2] * u[2]).sqrt() / cs;
                        hl.note_mach(mach, node);
                    }
                }
                hl
            })
            .collect();
        let mut tot = Health { mach_limit, ..Health::default() };
        for p in per_plane {
            tot.merge(p);
        }
        tot
    }
}

/// Shared write access to the fluid's force density field, for parallel writers that touch
/// disjoint nodes (the immersed boundary method spreads marker forces by z-slabs). Indices are
/// padded node indices ([`Fluid::padded_layout`]); values are converted to the storage
/// precision `T` on every write (`field ← T(field + w·f)`, the same `f64` operations as
/// `ibm::spread` into a slice, so for `T = f64` the two agree bitwise).
pub struct ForceFieldWriter<'a, T> {
    /// The field, `3·stride` values; the methods that write are `unsafe` and require that no
    /// two threads touch the same node at once ([`SharedMut`]'s contract, per node).
    field: SharedMut<'a, T>,
    stride: usize,
}

impl<T: Real> ForceFieldWriter<'_, T> {
    /// `field[p] += w · f` (component-wise, accumulated in `f64`, stored as `T`).
    ///
    /// # Safety
    /// `p` is a padded index of an interior node, and no other thread accesses node `p`
    /// during the call.
    #[inline(always)]
    pub unsafe fn add(&self, p: usize, w: f64, f: [f64; 3]) {
        debug_assert!(p < self.stride && self.field.len() == 3 * self.stride);
        for (a, fa) in f.iter().enumerate() {
            let i = a * self.stride + p;
            self.field.write(i, T::from_f64(self.field.read(i).to_f64() + w * *fa));
        }
    }

    /// `field[p + k] += w[k] · f` for each `k`: the operations of [`ForceFieldWriter::add`] on
    /// each node (the order among distinct values does not matter), so the same bits. A row of
    /// three (the default kernel's width) is updated component after component, its three
    /// values together; other lengths node by node.
    ///
    /// # Safety
    /// `p + k` is a padded index of an interior node for each `k < w.len()`, and no other
    /// thread accesses those nodes during the call.
    #[inline(always)]
    pub unsafe fn add_row(&self, p: usize, w: &[f64], f: [f64; 3]) {
        debug_assert!(p + w.len() <= self.stride && self.field.len() == 3 * self.stride);
        if let &[w0, w1, w2] = w {
            for (a, fa) in f.iter().enumerate() {
                let i = a * self.stride + p;
                let v = [self.field.read(i), self.field.read(i + 1), self.field.read(i + 2)];
                self.field.write(i, T::from_f64(v[0].to_f64() + w0 * *fa));
                self.field.write(i + 1, T::from_f64(v[1].to_f64() + w1 * *fa));
                self.field.write(i + 2, T::from_f64(v[2].to_f64() + w2 * *fa));
            }
        } else {
            for (k, &wk) in w.iter().enumerate() {
                self.add(p + k, wk, f);
            }
        }
    }

    /// A hint that node `p`'s three components will soon be updated
    /// ([`crate::util::prefetch`]): changes nothing but when they are fetched.
    #[inline(always)]
    pub fn prefetch(&self, p: usize) {
        for a in 0..3 {
            self.field.prefetch(a * self.stride + p);
        }
    }

    /// `field[p] = 0`.
    ///
    /// # Safety
    /// As [`ForceFieldWriter::add`].
    #[inline(always)]
    pub unsafe fn clear(&self, p: usize) {
        debug_assert!(p < self.stride);
        for a in 0..3 {
            self.field.write(a * self.stride + p, T::ZERO);
        }
    }
}

impl<T: Real> Fluid<T> {
    /// The layout of the padded arrays (populations per direction, force field per component):
    /// interior node `(x, y, z)` sits at `(x+1) + px ((y+1) + py (z+1))`.
    pub fn padded_layout(&self) -> crate::lattice::NodeLayout {
        crate::lattice::NodeLayout { base: 1 + self.px * (1 + self.py), sy: self.px, sz: self.px * self.py }
    }

    /// Shared write access to the force field (see [`ForceFieldWriter`]).
    ///
    /// # Panics
    /// If the force field is off.
    pub fn force_field_writer(&mut self) -> ForceFieldWriter<'_, T> {
        assert!(self.force_field_enabled(), "force field is off: call enable_force_field first");
        ForceFieldWriter { field: SharedMut::new(&mut self.force), stride: self.stride }
    }

    /// Density and momentum `j = Σ f_i c_i` (no force correction) of the nodes of `run`, into
    /// `rho[k]` and `j[k]` for the run's `k`-th node: the numbers [`Fluid::for_each_in_run`]
    /// passes, bitwise (the same sums in the same order, [`moments`]), computed a direction at
    /// a time over the whole run, so that the loop over the nodes runs in vector lanes (AVX2
    /// where the processor has it; IEEE operations lane by lane, no fused multiply-add: the
    /// same bits either way). In the same pass, the velocity `u = (j + F/2)/ρ` for a force
    /// density `force` (e.g. [`Fluid::zero_field_force`]) into `velocity[k]`, formed as
    /// `(j[a] + 0.5 * F[a]) / ρ`: bitwise that expression on `j[k]` and `rho[k]` (the divisions
    /// in vector lanes too, each correctly rounded). For passes over the whole grid (the
    /// coupling's dense steps).
    ///
    /// # Panics
    /// If the run leaves the grid, or `rho`, `j` or `velocity` is shorter than the run.
    pub fn run_moments(
        &self,
        run: crate::lattice::Run,
        rho: &mut [f64],
        j: &mut [[f64; 3]],
        force: [f64; 3],
        velocity: &mut [[f64; 3]],
    ) {
        let g = self.grid;
        let (x0, len, y, z) = (run.x0 as usize, run.len as usize, run.y as usize, run.z as usize);
        assert!(x0 + len <= g.nx && y < g.ny && z < g.nz, "run {run:?} outside the grid {g:?}");
        let (rho, j) = (&mut rho[..len], &mut j[..len]);
        let velocity = &mut velocity[..len];
        let even = self.time.is_multiple_of(2);
        let p0 = self.pidx(x0, y, z);
        let src: [&[T]; Q] = std::array::from_fn(|i| {
            let s = if even {
                i * self.stride + p0
            } else {
                (OPP[i] * self.stride + p0).wrapping_add_signed(-self.off[i])
            };
            &self.f[s..s + len]
        });
        #[cfg(target_arch = "x86_64")]
        if std::is_x86_feature_detected!("avx2") {
            // SAFETY: the processor has AVX2 (checked just above).
            unsafe { run_moments_avx2(&src, rho, j, force, velocity) };
            return;
        }
        run_moments_rows(&src, rho, j, force, velocity);
    }

    /// Density, momentum `j = Σ f_i c_i` (no force correction) and force density `F` (the
    /// uniform body force plus the node's field) at every node of `run`, in order:
    /// `f(x, ρ, j, F)`. The physical velocity is `u = (j + F/2)/ρ`; formed as
    /// `(j[a] + 0.5 * F[a]) / ρ` it equals [`Fluid::macroscopic`]'s bitwise (the same sums in
    /// the same order). Read row-wise, for the immersed-boundary band and interior sums.
    ///
    /// # Panics
    /// If the run leaves the grid.
    pub fn for_each_in_run(
        &self,
        run: crate::lattice::Run,
        mut f: impl FnMut(usize, f64, [f64; 3], [f64; 3]),
    ) {
        let g = self.grid;
        let (x0, len, y, z) = (run.x0 as usize, run.len as usize, run.y as usize, run.z as usize);
        assert!(x0 + len <= g.nx && y < g.ny && z < g.nz, "run {run:?} outside the grid {g:?}");
        let even = self.time.is_multiple_of(2);
        let field = self.force_field_enabled();
        let mut src = [0usize; Q];
        let p0 = self.pidx(x0, y, z);
        for i in 0..Q {
            src[i] = if even {
                i * self.stride + p0
            } else {
                (OPP[i] * self.stride + p0).wrapping_add_signed(-self.off[i])
            };
        }
        let mut h = [0.0f64; Q];
        for k in 0..len {
            for i in 0..Q {
                h[i] = self.f[src[i] + k].to_f64();
            }
            let (drho, j) = moments(&h);
            let p = p0 + k;
            let mut fc = [0.0; 3];
            for a in 0..3 {
                let fa = if field { self.force[a * self.stride + p] } else { T::ZERO };
                fc[a] = (fa + self.body[a]).to_f64();
            }
            f(x0 + k, 1.0 + drho, j, fc);
        }
    }

    /// Force and torque that the fluid exerted on every bounce-back surface (the box walls and
    /// obstacles) during the last step, by momentum exchange (Ladd 1994): each link carries
    /// an outgoing population `f_out` (direction `−c_i`, into the wall) and returns
    /// `f_in = f_out + 6 w_i c_i·u_w` (direction `c_i`), so the wall gains
    /// `−c_i (f_out + f_in)` per step, applied at the link's midpoint `x − c_i/2`. Torque about
    /// `origin`. Both populations are still in memory after [`Fluid::step`] (the link
    /// operations copy, they do not move), so this reads them; it changes nothing.
    ///
    /// Summed in fixed chunks of links, reduced in order: bitwise identical for any thread
    /// count. Zero before the first step.
    pub fn wall_momentum_exchange(&self, origin: [f64; 3]) -> ([f64; 3], [f64; 3]) {
        if self.time == 0 {
            return ([0.0; 3], [0.0; 3]);
        }
        let (px, py, stride) = (self.px, self.py, self.stride);
        let parts: Vec<[f64; 6]> = self
            .bounce
            .par_chunks(4096)
            .map(|links| {
                let mut acc = [0.0; 6];
                for l in links {
                    let i = l.own / stride;
                    let p = l.own % stride;
                    let (x, y, z) = (p % px, (p / px) % py, p / (px * py));
                    let node = [x as f64 - 1.0, y as f64 - 1.0, z as f64 - 1.0];
                    let sum = self.f[l.own].to_f64() + self.f[l.ghost].to_f64() + 2.0 * W[i];
                    let c = C[i];
                    let fw = [-(c[0] as f64) * sum, -(c[1] as f64) * sum, -(c[2] as f64) * sum];
                    let r = [
                        node[0] - 0.5 * c[0] as f64 - origin[0],
                        node[1] - 0.5 * c[1] as f64 - origin[1],
                        node[2] - 0.5 * c[2] as f64 - origin[2],
                    ];
                    acc[0] += fw[0];
                    acc[1] += fw[1];
                    acc[2] += fw[2];
                    acc[3] += r[1] * fw[2] - r[2] * fw[1];
                    acc[4] += r[2] * fw[0] - r[0] * fw[2];
                    acc[5] += r[0] * fw[1] - r[1] * fw[0];
                }
                acc
            })
            .collect();
        let mut tot = [0.0; 6];
        for p in parts {
            for k in 0..6 {
                tot[k] += p[k];
            }
        }
        ([tot[0], tot[1], tot[2]], [tot[3], tot[4], tot[5]])
    }
}

/// [`Fluid::run_moments`]'s loop with AVX2 enabled, so that it vectorises 4 nodes wide.
///
/// # Safety
/// The processor must have AVX2.
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2")]
unsafe fn run_moments_avx2<T: Real>(
    src: &[&[T]; Q],
    rho: &mut [f64],
    j: &mut [[f64; 3]],
    force: [f64; 3],
    velocity: &mut [[f64; 3]],
) {
    run_moments_rows(src, rho, j, force, velocity)
}

/// `rho[k] = 1 + δρ`, `j[k]` from the populations `src[i][k]` of each node `k` ([`moments`]),
/// and `velocity[k] = (j[k] + 0.5 F)/rho[k]` component by component (`velocity` as long as
/// `rho`).
#[inline(always)]
fn run_moments_rows<T: Real>(
    src: &[&[T]; Q],
    rho: &mut [f64],
    j: &mut [[f64; 3]],
    force: [f64; 3],
    velocity: &mut [[f64; 3]],
) {
    assert_eq!(velocity.len(), rho.len());
    for (k, (r, jk)) in rho.iter_mut().zip(j.iter_mut()).enumerate() {
        // Filled in a plain loop, not `std::array::from_fn`: a generic helper that is not
        // always inlined into `run_moments_avx2`, which then ran the whole loop without AVX2
        // (seen: the interior phase 20 % slower after an unrelated change elsewhere).
        let mut h = [0.0f64; Q];
        for (hi, s) in h.iter_mut().zip(src) {
            *hi = s[k].to_f64();
        }
        let (drho, m) = moments(&h);
        *r = 1.0 + drho;
        *jk = m;
        let rk = *r;
        velocity[k] =
            [(m[0] + 0.5 * force[0]) / rk, (m[1] + 0.5 * force[1]) / rk, (m[2] + 0.5 * force[2]) / rk];
    }
}

/// One link operation as stored: slots `own` and `ghost` (`q·stride + n`), the wall term, and
/// whether it is a periodic copy (no term added).
pub(crate) struct LinkView<T> {
    pub own: usize,
    pub ghost: usize,
    pub term: T,
    pub periodic: bool,
}

/// The arrays as stored, for a copy of the fluid on another processor (`crate::device`): read
/// and written at output steps, never during the CPU's own step.
impl<T: Real> Fluid<T> {
    /// Distance between the starts of consecutive direction arrays (and force components).
    pub(crate) fn stride(&self) -> usize {
        self.stride
    }

    /// The padded populations `f[q·stride + n]`.
    pub(crate) fn raw_populations(&self) -> &[T] {
        &self.f
    }

    /// The padded populations, to overwrite with a copy of the same step; the time set with it.
    pub(crate) fn raw_populations_mut(&mut self, time: u64) -> &mut [T] {
        self.time = time;
        &mut self.f
    }

    /// The padded force density field `force[a·stride + n]` (empty while off).
    pub(crate) fn raw_force(&self) -> &[T] {
        &self.force
    }

    /// The padded force density field, to overwrite with a copy (empty while off).
    pub(crate) fn raw_force_mut(&mut self) -> &mut [T] {
        &mut self.force
    }

    /// Per padded node: ghost or obstacle (never collided).
    pub(crate) fn raw_solid(&self) -> &[bool] {
        &self.solid
    }

    /// The periodic links, then the bounce-back links (walls and obstacles).
    pub(crate) fn raw_links(&self) -> impl Iterator<Item = LinkView<T>> + '_ {
        let view =
            |l: &Link<T>, periodic: bool| LinkView { own: l.own, ghost: l.ghost, term: l.term, periodic };
        self.periodic
            .iter()
            .map(move |l| view(l, true))
            .chain(self.bounce.iter().map(move |l| view(l, false)))
    }

    /// The relaxation rates in the storage precision.
    pub(crate) fn raw_rates(&self) -> Rates<T> {
        self.rates
    }

    /// The uniform body force in the storage precision.
    pub(crate) fn raw_body(&self) -> [T; 3] {
        self.body
    }
}
