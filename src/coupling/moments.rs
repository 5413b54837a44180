//! Dense beds: the fluid's momentum at every node, read once per fluid state.
//!
//! When the bands hold more than a tenth of the grid (`DENSE_BAND_FRACTION`; small bodies in a dense bed: the band is the
//! whole grid, [`super::band::Band::whole_grid`]), phase 5 evaluates the fluid velocity at
//! every node anyway, and the interior sums of phases 3 and 7 read the momentum of most
//! nodes, each from 19 populations in scattered short runs. Instead, one pass over the grid
//! per fluid state stores per node
//!
//! - the momentum `j` ([`Fluid::run_moments`], bitwise [`Fluid::for_each_in_run`]'s), from which both interior sums of that
//!   state (phase 7 of one step, phase 3 of the next) gather;
//! - in the coupling's velocity buffer, the velocity that phase 5's first iteration would
//!   form at the node after phase 4 has cleared the force field, `u = (j + F₀/2)/ρ` with `F₀`
//!   the force density of a node whose field entry is zero ([`Fluid::zero_field_force`]): the
//!   same operations on the same numbers, so the same bits.
//!
//! The pass runs in phase 7 of a dense step (the fluid has just stepped), or in phase 3 when
//! the stored state is not the fluid's current one (the first step, after a restore or after
//! a sparse step). The stored values carry the fluid time they belong to; any access to the
//! fluid that may change it without stepping ([`super::Coupled::fluid_mut`], restore)
//! forgets them.

use rayon::prelude::*;

use crate::lattice::{Grid, Run};
use crate::lbm::{Fluid, Real};

/// Nodes per piece of a row in [`Moments::fill`].
const CHUNK: usize = 128;

/// Per node the momentum `j` of one fluid state (module docs).
#[derive(Clone, Debug, Default)]
pub(super) struct Moments {
    /// `j` per node, interior order `x + nx (y + ny z)` (empty until first needed).
    j: Vec<[f64; 3]>,
    /// The fluid time and the grid of the stored values, `None` if there are none.
    stored: Option<(u64, Grid)>,
}

impl Moments {
    /// Whether the stored values are those of `fluid`'s current state.
    pub fn current<T: Real>(&self, fluid: &Fluid<T>) -> bool {
        self.stored.map(|(t, _)| t) == Some(fluid.time())
    }

    /// Forgets the stored values (the fluid may have changed).
    pub fn forget(&mut self) {
        self.stored = None;
    }

    /// Reads `j` at every node of `fluid` and writes the zero-field velocity of every node
    /// into `velocity` (interior order; module docs). Parallel over z-planes.
    pub fn fill<T: Real>(&mut self, fluid: &Fluid<T>, velocity: &mut [[f64; 3]]) {
        let grid = fluid.grid();
        let plane = grid.nx * grid.ny;
        self.j.resize(grid.nodes(), [0.0; 3]);
        let f0 = fluid.zero_field_force();
        self.j.par_chunks_mut(plane).zip(velocity.par_chunks_mut(plane)).enumerate().for_each(
            |(z, (js, vel))| {
                // Rows in pieces of `CHUNK` nodes (the densities on the stack: no allocation).
                let mut rho = [0.0f64; CHUNK];
                for y in 0..grid.ny {
                    for x0 in (0..grid.nx).step_by(CHUNK) {
                        let len = CHUNK.min(grid.nx - x0);
                        let run = Run { x0: x0 as u32, len: len as u32, y: y as u32, z: z as u32 };
                        let at = y * grid.nx + x0;
                        let (jr, vr) = (&mut js[at..at + len], &mut vel[at..at + len]);
                        fluid.run_moments(run, &mut rho, jr, f0, vr);
                    }
                }
            },
        );
        self.stored = Some((fluid.time(), grid));
    }

    /// A hint that the stored momenta of `run` will soon be read: a prefetch of each cache line
    /// of the run (nothing if none are stored).
    #[inline(always)]
    pub fn prefetch(&self, run: Run) {
        let Some((_, grid)) = self.stored else { return };
        let start = grid.index(run.x0 as usize, run.y as usize, run.z as usize);
        let end = (start + run.len as usize).min(self.j.len());
        // `[f64; 3]` is 24 bytes: a line every 8/3 nodes; one prefetch per two nodes covers
        // every line of the run.
        for n in (start..end).step_by(2) {
            crate::util::prefetch(&self.j[n]);
        }
    }

    /// Calls `f(x, j)` for every node of `run` (x in order), from the stored values.
    ///
    /// # Panics
    /// If nothing is stored or the run leaves the stored grid.
    #[inline]
    pub fn for_each_j(&self, run: Run, mut f: impl FnMut(usize, [f64; 3])) {
        let (x0, len) = (run.x0 as usize, run.len as usize);
        let (_, grid) = self.stored.expect("no moments stored");
        let base = grid.index(0, run.y as usize, run.z as usize);
        for (k, &j) in self.j[base + x0..base + x0 + len].iter().enumerate() {
            f(x0 + k, j);
        }
    }
}
