//! Phases 1–2 of the coupled step: marker world positions and solid velocities, the IBM
//! stencils and each body's band.

use rayon::prelude::*;

use super::band::{band_runs, run_nodes};
use super::{Coupled, CouplingError};
use crate::lbm::Real;

impl<T: Real> Coupled<T> {
    /// Phase 1: every marker's world position `X_m` and solid velocity `U_m = v + ω × r` from
    /// the bodies at `tⁿ` (parallel over markers, global marker order).
    pub(super) fn place_markers(&mut self) {
        let (bodies, markers, offsets, owner) = (&self.bodies, &self.markers, &self.offsets, &self.owner);
        self.position
            .par_iter_mut()
            .zip(self.solid.par_iter_mut())
            .zip(owner.par_iter())
            .enumerate()
            .for_each(|(i, ((x, u), &b))| {
                let b = b as usize;
                let (xw, _n, uw) = bodies[b].marker_world(&markers[b][i - offsets[b]]);
                *x = [xw.x, xw.y, xw.z];
                *u = [uw.x, uw.y, uw.z];
            });
    }

    /// Phase 2: the stencils ([`crate::ibm::Stencils::build`], with the box's periodicity) and
    /// the band of each body, grouped by z-plane; or, when the bands are estimated to hold
    /// more than a tenth of the grid (`DENSE_BAND_FRACTION`; [`Coupled::dense_band`] on the sum of the per-body counts in
    /// `band_estimate`), no runs: the band is the whole grid ([`whole_grid`](super::band::Band::whole_grid)), which
    /// phases 4–5 then treat node by node. The estimate decides only the cost, never the
    /// bits: both paths give the same results (module docs). Each body's count is the number
    /// of band nodes it had when its band was last built (first in [`Coupled::new`]).
    ///
    /// # Errors
    /// A marker outside the box on a walled axis, or not finite (nothing else has changed).
    pub(super) fn build_geometry(&mut self) -> Result<(), CouplingError> {
        let grid = self.fluid.grid();
        self.stencils.build(grid, self.periodic, &self.position)?;
        if self.dense_band(self.band_estimate.iter().sum(), grid.nodes()) {
            self.band.set_whole_grid();
            return Ok(());
        }
        let (periodic, half_width) = (self.periodic, self.band_half_width);
        self.band
            .per_body
            .par_iter_mut()
            .zip(self.band_estimate.par_iter_mut())
            .zip(self.bodies.par_iter())
            .for_each(|((out, count), body)| {
                band_runs(body, grid, periodic, half_width, out);
                *count = run_nodes(out);
            });
        self.band.bucket(grid.nz);
        Ok(())
    }
}
