//! Phases 4–5 of the coupled step: clearing the force field where the previous step spread,
//! and the direct-forcing iterations (band velocity, interpolation, `2ρ(U − u)A`, spreading
//! straight into the fluid's force field).

use std::time::Instant;

use rayon::prelude::*;

use super::Coupled;
use crate::ibm::{interpolate, spread_into, ForceSink};
use crate::lattice::{NodeLayout, Run};
use crate::lbm::{ForceFieldWriter, Real};
use crate::util::SharedMut;

/// The fluid's force field as a spreading target.
struct FieldSink<'a, T> {
    writer: ForceFieldWriter<'a, T>,
    layout: NodeLayout,
}

impl<T: Real> ForceSink for FieldSink<'_, T> {
    fn layout(&self) -> NodeLayout {
        self.layout
    }

    #[inline(always)]
    unsafe fn add(&self, index: usize, w: f64, f: [f64; 3]) {
        self.writer.add(index, w, f)
    }

    #[inline(always)]
    unsafe fn add_row(&self, index: usize, w: &[f64], f: [f64; 3]) {
        self.writer.add_row(index, w, f)
    }

    #[inline(always)]
    fn prefetch(&self, index: usize) {
        self.writer.prefetch(index)
    }
}

impl<T: Real> Coupled<T> {
    /// Phase 4: zero the force field on the previous step's band (the only nodes where it is
    /// non-zero) and the markers' force totals; the whole field when the previous band is the
    /// whole grid (not built, or unknown after a restore).
    pub(super) fn clear_forcing(&mut self) {
        let grid = self.fluid.grid();
        if self.band_prev.whole_grid {
            // The previous step spread into bands it did not build (small bodies in a dense
            // bed, whose bands overlap and cover most of the grid): one streaming pass over
            // the field. The same result, since the field is zero outside those bands.
            self.fluid.clear_force_field();
            self.marker_force.par_iter_mut().for_each(|v| *v = [0.0; 3]);
            return;
        }
        let layout = self.fluid.padded_layout();
        let prev = &self.band_prev;
        let writer = self.fluid.force_field_writer();
        (0..grid.nz).into_par_iter().for_each(|z| {
            for run in prev.plane(z) {
                let p0 = layout.index(run.x0 as usize, run.y as usize, run.z as usize);
                for p in p0..p0 + run.len as usize {
                    // SAFETY: node p lies in plane z, which only this task touches.
                    unsafe { writer.clear(p) };
                }
            }
        });
        self.marker_force.par_iter_mut().for_each(|v| *v = [0.0; 3]);
    }

    /// Phase 5: `K` direct-forcing iterations, each: the fluid velocity `u = (j + F/2)/ρ` at
    /// the band nodes (the current force field included); `u_m = I u`; the increment
    /// `ΔF_m = 2 ρ_m (U_m − u_m) A_m` (`ρ_m = 1`), accumulated per marker; spread (adding) into
    /// the fluid's force field. Returns the seconds spent in the interpolations and in the
    /// spreadings (for [`super::StepTimings`]).
    pub(super) fn force(&mut self) -> [f64; 2] {
        let mut seconds = [0.0; 2];
        for k in 0..self.iterations {
            // A dense step's first iteration finds the velocity stored with the moments of the
            // current fluid state (module `moments`): the force field is zero there now.
            if !(k == 0 && self.band.whole_grid && self.moments.current(&self.fluid)) {
                self.band_velocity();
            }
            let t = Instant::now();
            interpolate(&self.velocity, &self.stencils, &mut self.fluid_u);
            seconds[0] += t.elapsed().as_secs_f64();
            self.increment
                .par_iter_mut()
                .zip(self.marker_force.par_iter_mut())
                .zip(self.solid.par_iter().zip(self.fluid_u.par_iter()).zip(self.area.par_iter()))
                .for_each(|((inc, tot), ((us, uf), a))| {
                    for k in 0..3 {
                        inc[k] = 2.0 * (us[k] - uf[k]) * a;
                        tot[k] += inc[k];
                    }
                });
            let layout = self.fluid.padded_layout();
            let sink = FieldSink { writer: self.fluid.force_field_writer(), layout };
            let t = Instant::now();
            spread_into(&self.increment, &self.stencils, &sink);
            seconds[1] += t.elapsed().as_secs_f64();
        }
        seconds
    }

    /// The fluid velocity at every band node into `self.velocity` (parallel over planes). When
    /// the band is the whole grid (not built: the bands together were estimated to hold more
    /// nodes than a tenth of the grid, as small bodies in a dense bed, with bands several times
    /// their volume and overlapping, do), the velocity is evaluated once at every node
    /// instead, by the same arithmetic: bitwise the same values at the band nodes.
    pub(super) fn band_velocity(&mut self) {
        let grid = self.fluid.grid();
        let fluid = &self.fluid;
        let band = &self.band;
        let layout = grid.layout();
        let out = SharedMut::new(&mut self.velocity);
        let out = &out;
        let all = band.whole_grid;
        let velocity = |run: Run| {
            let row = layout.index(0, run.y as usize, run.z as usize);
            fluid.for_each_in_run(run, |x, rho, j, f| {
                let u = [(j[0] + 0.5 * f[0]) / rho, (j[1] + 0.5 * f[1]) / rho, (j[2] + 0.5 * f[2]) / rho];
                // SAFETY: node (x, y, z) lies in plane z, which only this task writes; the
                // index is inside the grid-sized buffer.
                unsafe { out.write(row + x, u) };
            });
        };
        (0..grid.nz).into_par_iter().for_each(|z| {
            if all {
                for y in 0..grid.ny {
                    velocity(Run { x0: 0, len: grid.nx as u32, y: y as u32, z: z as u32 });
                }
            } else {
                band.plane(z).iter().for_each(|&run| velocity(run));
            }
        });
    }
}

impl<T: Real> Coupled<T> {
    /// Whether bands of `band_nodes` nodes (with repetitions) are better served by one pass
    /// over all `grid_nodes` nodes: more than `DENSE_BAND_FRACTION` (a tenth) of the grid, or as forced by a test. Only
    /// the cost depends on the answer: the band and the whole-grid paths give the same bits.
    pub(super) fn dense_band(&self, band_nodes: usize, grid_nodes: usize) -> bool {
        self.dense_override.unwrap_or(band_nodes as f64 > super::DENSE_BAND_FRACTION * grid_nodes as f64)
    }
}
