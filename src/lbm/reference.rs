//! A plain, obviously correct reference solver: two lattices, node-major (array of
//! structures), collide then push, boundaries resolved link by link on the fly.
//!
//! It exists only as the oracle for the fused AA kernel ([`super::Fluid`]): same collision
//! operator (verified on its own against a textbook formula), independent storage, streaming,
//! and boundary handling. The two agree bitwise.

use super::boundary::{resolve, wall_term, Boundaries, LinkEnd};
use super::collision::{collide, Rates};
use super::fluid::equilibrium;
use super::{FluidError, FluidParams, Real};
use crate::lattice::{Grid, C, OPP, Q, W};

/// Two-lattice reference solver with the same physics as [`super::Fluid`].
pub struct ReferenceFluid<T: Real> {
    grid: Grid,
    params: FluidParams,
    boundaries: Boundaries,
    obstacle: Vec<bool>,
    /// `f[n·Q + i]`: shifted population `h_i` of node `n`.
    f: Vec<T>,
    tmp: Vec<T>,
    force: Vec<[T; 3]>,
    rates: Rates<T>,
    body: [T; 3],
    time: u64,
}

impl<T: Real> ReferenceFluid<T> {
    /// A fluid at rest filling the box.
    pub fn new(grid: Grid, params: FluidParams, boundaries: Boundaries) -> Result<Self, FluidError> {
        params.validate()?;
        boundaries.validate()?;
        let (op, om) = params.rates();
        Ok(Self {
            grid,
            params,
            boundaries,
            obstacle: vec![false; grid.nodes()],
            f: vec![T::ZERO; grid.nodes() * Q],
            tmp: vec![T::ZERO; grid.nodes() * Q],
            force: vec![[T::ZERO; 3]; grid.nodes()],
            rates: Rates::new(op, om),
            body: params.body_force.map(T::from_f64),
            time: 0,
        })
    }

    /// Marks obstacle nodes.
    pub fn set_obstacles(&mut self, is_solid: impl Fn(usize, usize, usize) -> bool) {
        let g = self.grid;
        self.obstacle = (0..g.nodes())
            .map(|n| {
                let [x, y, z] = g.coords(n);
                is_solid(x, y, z)
            })
            .collect();
    }

    /// Equilibrium initial state; time zero.
    pub fn initialize(&mut self, init: impl Fn(usize, usize, usize) -> (f64, [f64; 3])) {
        let g = self.grid;
        for n in 0..g.nodes() {
            let [x, y, z] = g.coords(n);
            let (rho, u) = init(x, y, z);
            let h = equilibrium(rho, u);
            for i in 0..Q {
                self.f[n * Q + i] = T::from_f64(h[i]);
            }
        }
        self.time = 0;
    }

    /// Sets the force density at a node (the field is always on here).
    pub fn set_force(&mut self, x: usize, y: usize, z: usize, fv: [f64; 3]) {
        self.force[self.grid.index(x, y, z)] = fv.map(T::from_f64);
    }

    /// One time step: collide every fluid node, push each post-collision population to its
    /// neighbour, bouncing back at walls and obstacles.
    pub fn step(&mut self, force_field: bool) {
        let g = self.grid;
        let obstacle = &self.obstacle;
        let is_solid = |n: [usize; 3]| obstacle[g.index(n[0], n[1], n[2])];
        for n in 0..g.nodes() {
            if obstacle[n] {
                continue;
            }
            let mut h: [T; Q] = std::array::from_fn(|i| self.f[n * Q + i]);
            let fc = if force_field {
                std::array::from_fn(|a| self.force[n][a] + self.body[a])
            } else {
                self.body
            };
            if self.params.is_trt() {
                collide::<T, _, true>(&mut h, fc, &self.rates);
            } else {
                collide::<T, _, false>(&mut h, fc, &self.rates);
            }
            let x = g.coords(n);
            for i in 0..Q {
                match resolve(&g, &self.boundaries, &is_solid, x, C[i]) {
                    LinkEnd::Interior(m) | LinkEnd::Periodic(m) => {
                        self.tmp[g.index(m[0], m[1], m[2]) * Q + i] = h[i];
                    }
                    LinkEnd::Wall(uw) => {
                        let o = OPP[i];
                        self.tmp[n * Q + o] = h[i] + T::from_f64(wall_term(o, uw));
                    }
                    LinkEnd::Obstacle => {
                        let o = OPP[i];
                        self.tmp[n * Q + o] = h[i] + T::from_f64(wall_term(o, [0.0; 3]));
                    }
                }
            }
        }
        std::mem::swap(&mut self.f, &mut self.tmp);
        self.time += 1;
    }

    /// Pre-collision populations `f_i` (unshifted) at a node.
    pub fn populations(&self, x: usize, y: usize, z: usize) -> [f64; Q] {
        let n = self.grid.index(x, y, z);
        std::array::from_fn(|i| self.f[n * Q + i].to_f64() + W[i])
    }

    /// Shifted populations at a node, in storage precision.
    pub fn shifted_populations(&self, x: usize, y: usize, z: usize) -> [T; Q] {
        let n = self.grid.index(x, y, z);
        std::array::from_fn(|i| self.f[n * Q + i])
    }

    /// Number of completed steps.
    pub fn time(&self) -> u64 {
        self.time
    }
}
