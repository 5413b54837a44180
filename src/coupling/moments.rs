//! Dense beds: the fluid's moments at every node, read once per fluid state.
//!
//! When the bands hold more than half the grid (small bodies in a dense bed: the band is the
//! whole grid, [`super::band::Band::whole_grid`]), phase 5 evaluates the fluid velocity at
//! every node anyway, and the interior sums of phases 3 and 7 read the momentum of most
//! nodes, each from 19 populations in scattered short runs. Instead, right after the fluid
//! changes, one pass over the grid stores per node
//!
//! - `(ρ, j)` ([`Fluid::for_each_in_run`]'s density and momentum), from which both interior
//!   sums (phase 7 of this step, phase 3 of the next, the same fluid state) gather `j`;
//! - the velocity that phase 5's first iteration would form at the node after phase 4 has
//!   cleared the force field, `u = (j + F₀/2)/ρ` with `F₀` the force density of a node whose
//!   field entry is zero ([`Fluid::zero_field_force`]): the same operations on the same
//!   numbers, so the same bits.
//!
//! The pass runs after [`Fluid::step`] (phase 6b) when the step is dense, or in phase 3 when
//! the stored state is not the fluid's current one (the first step, after a restore or a
//! sparse step). [`Moments::time`] records the fluid time of the stored values; any access to
//! the fluid that may change it ([`super::Coupled::fluid_mut`], restore) forgets them.

use rayon::prelude::*;

use crate::lattice::Run;
use crate::lbm::{Fluid, Real};

/// Per node `(ρ, jx, jy, jz)` and the zero-field velocity, for one fluid state (module docs).
#[derive(Clone, Debug, Default)]
pub(super) struct Moments {
    /// `(ρ, j)` per node, interior order `x + nx (y + ny z)` (empty until first needed).
    rho_j: Vec<[f64; 4]>,
    /// The fluid time of the stored values, `None` if there are none.
    time: Option<u64>,
}

impl Moments {
    /// Whether the stored values are those of `fluid`'s current state.
    pub fn current<T: Real>(&self, fluid: &Fluid<T>) -> bool {
        self.time == Some(fluid.time())
    }

    /// Forgets the stored values (the fluid may have changed).
    pub fn forget(&mut self) {
        self.time = None;
    }

    /// Reads `(ρ, j)` at every node of `fluid` and writes the zero-field velocity of every
    /// node into `velocity` (interior order; module docs). Parallel over z-planes.
    pub fn fill<T: Real>(&mut self, fluid: &Fluid<T>, velocity: &mut [[f64; 3]]) {
        let grid = fluid.grid();
        let plane = grid.nx * grid.ny;
        self.rho_j.resize(grid.nodes(), [0.0; 4]);
        let f0 = fluid.zero_field_force();
        self.rho_j.par_chunks_mut(plane).zip(velocity.par_chunks_mut(plane)).enumerate().for_each(
            |(z, (rho_j, vel))| {
                for y in 0..grid.ny {
                    let run = Run { x0: 0, len: grid.nx as u32, y: y as u32, z: z as u32 };
                    let row = y * grid.nx;
                    fluid.for_each_in_run(run, |x, rho, j, _f| {
                        rho_j[row + x] = [rho, j[0], j[1], j[2]];
                        vel[row + x] = [
                            (j[0] + 0.5 * f0[0]) / rho,
                            (j[1] + 0.5 * f0[1]) / rho,
                            (j[2] + 0.5 * f0[2]) / rho,
                        ];
                    });
                }
            },
        );
        self.time = Some(fluid.time());
    }

    /// Calls `f(x, j)` for every node of `run` (x in order), from the stored values.
    ///
    /// # Panics
    /// If nothing is stored or the run leaves the grid the values were stored for.
    #[inline]
    pub fn for_each_j(&self, nx: usize, ny: usize, run: Run, mut f: impl FnMut(usize, [f64; 3])) {
        let (x0, len) = (run.x0 as usize, run.len as usize);
        let base = nx * (run.y as usize + ny * run.z as usize);
        for (k, m) in self.rho_j[base + x0..base + x0 + len].iter().enumerate() {
            f(x0 + k, [m[1], m[2], m[3]]);
        }
    }
}
