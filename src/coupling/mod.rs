//! The coupled step: the lattice fluid ([`crate::lbm`]) and rigid bodies ([`crate::rigid`])
//! joined through the immersed boundary method ([`crate::ibm`]).
//!
//! This is the only module that imports both the fluid and the particle side (ARCHITECTURE.md,
//! "Invariants"). [`Coupled`] owns the [`Fluid`], the bodies, each body's surface markers (body
//! frame, from [`Shape::markers`]), the IBM [`Stencils`] and the reusable buffers of a step.
//!
//! **Scope (issue 3, first part).** Fixed and prescribed bodies only: steps 1–6 of the coupled
//! step of ARCHITECTURE.md, without the interior-fluid momentum term of step 6 (Kempe &
//! Fröhlich 2012), which only free bodies need (for a fixed body it vanishes at steady state;
//! for a prescribed body the force reported here is the IBM force alone). Free bodies, contacts
//! and step 7 come later; [`Coupled::new`] rejects free bodies with
//! [`CouplingError::FreeBody`].
//!
//! **Density at the markers.** The direct-forcing update `ΔF_m = 2 ρ_m (U_m − u_m)` uses
//! `ρ_m = 1`, the reference density of the lattice (`ρ = 1 + O(Ma²)`): interpolating `ρ` would
//! cost a second pass over the stencils per iteration for a correction of relative size
//! `δρ ≈ 1e-4` or below, which the forcing iterations absorb anyway.
//!
//! **Performance note.** The marker forces are spread into a full-grid buffer which is then
//! copied into the fluid's force field (one pass over all nodes per forcing iteration, and one
//! clear per step). This is simple and correct; restricting the copy (and the velocity gather)
//! to the band of nodes the stencils touch is the performance work still to come.

use std::fmt;
use std::sync::Arc;

use rayon::prelude::*;

use crate::ibm::{interpolate, spread, DeltaKernel, FnField, StencilError, Stencils};
use crate::lattice::Face;
use crate::lbm::kernel::Planes;
use crate::lbm::{Fluid, Real};
use crate::rigid::{Marker, RigidBody, Shape, Vec3, DEFAULT_MARKER_SPACING};

/// Options of the coupling.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct CouplingParams {
    /// The regularised delta function of the IBM transfer.
    pub kernel: DeltaKernel,
    /// Direct-forcing iterations per time step (`K ≥ 1`).
    pub iterations: usize,
    /// Target spacing of the surface markers (lattice units).
    pub marker_spacing: f64,
}

impl Default for CouplingParams {
    /// The default kernel, one forcing iteration, [`DEFAULT_MARKER_SPACING`].
    fn default() -> Self {
        Self { kernel: DeltaKernel::default(), iterations: 1, marker_spacing: DEFAULT_MARKER_SPACING }
    }
}

/// Errors of the coupling.
#[derive(Clone, Debug, PartialEq)]
pub enum CouplingError {
    /// Body `index` is free: not supported yet (no interior-fluid momentum term, no integration).
    FreeBody {
        /// Index of the body.
        index: usize,
    },
    /// No forcing iteration requested.
    NoIterations,
    /// The stencils could not be built (a marker off the box on a walled axis, or not finite).
    Stencil(StencilError),
}

impl fmt::Display for CouplingError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            CouplingError::FreeBody { index } => {
                write!(f, "body {index} is free: the coupling handles fixed and prescribed bodies only")
            }
            CouplingError::NoIterations => write!(f, "at least one forcing iteration is needed"),
            CouplingError::Stencil(e) => write!(f, "IBM stencils: {e}"),
        }
    }
}

impl std::error::Error for CouplingError {}

impl From<StencilError> for CouplingError {
    fn from(e: StencilError) -> Self {
        CouplingError::Stencil(e)
    }
}

/// A lattice fluid with immersed rigid bodies (fixed or prescribed), coupled by direct-forcing
/// IBM. See the module docs and [`Coupled::step`].
pub struct Coupled<T: Real + Planes> {
    fluid: Fluid<T>,
    bodies: Vec<RigidBody>,
    /// Per body, its markers in the body frame.
    markers: Vec<Vec<Marker>>,
    /// Marker index range of body `b`: `offsets[b]..offsets[b + 1]` (global marker order).
    offsets: Vec<usize>,
    stencils: Stencils,
    iterations: usize,
    periodic: [bool; 3],
    // ---- reusable buffers, one entry per marker (global order) or per node ----
    /// Marker area weights `A_m`.
    area: Vec<f64>,
    /// Marker world positions.
    position: Vec<[f64; 3]>,
    /// Solid velocity `U_m` at the markers.
    solid: Vec<[f64; 3]>,
    /// Interpolated fluid velocity `u_m`.
    fluid_u: Vec<[f64; 3]>,
    /// Force increment of the current iteration, `ΔF_m A_m`.
    increment: Vec<[f64; 3]>,
    /// Total force of each marker on the fluid in the current step, `Σ_k ΔF_m^k A_m`.
    marker_force: Vec<[f64; 3]>,
    /// Full-grid force density spread by the markers (interior index).
    field: Vec<[f64; 3]>,
    /// Hydrodynamic force and torque (about the centre) on each body, from the last step.
    hydro: Vec<(Vec3, Vec3)>,
}

impl<T: Real + Planes> Coupled<T> {
    /// Couples `fluid` with `bodies` (fixed or prescribed), turning on the fluid's force field.
    /// Markers are generated once per body at `params.marker_spacing` and kept in a fixed
    /// global order (body by body, marker by marker), so spreading is deterministic.
    ///
    /// # Errors
    /// A free body ([`CouplingError::FreeBody`]), `params.iterations == 0`.
    pub fn new(
        mut fluid: Fluid<T>,
        bodies: Vec<RigidBody>,
        params: CouplingParams,
    ) -> Result<Self, CouplingError> {
        if let Some(index) = bodies.iter().position(|b| b.is_free()) {
            return Err(CouplingError::FreeBody { index });
        }
        if params.iterations == 0 {
            return Err(CouplingError::NoIterations);
        }
        fluid.enable_force_field();
        let markers: Vec<Vec<Marker>> =
            bodies.iter().map(|b| b.shape().markers(params.marker_spacing)).collect();
        let mut offsets = vec![0];
        for m in &markers {
            offsets.push(offsets.last().unwrap() + m.len());
        }
        let total = *offsets.last().unwrap();
        let b = fluid.boundaries();
        let periodic = std::array::from_fn(|a| b.get(Face::from_axis(a, true)).is_periodic());
        let nodes = fluid.grid().nodes();
        let n_bodies = bodies.len();
        Ok(Self {
            fluid,
            bodies,
            offsets,
            stencils: Stencils::new(params.kernel),
            iterations: params.iterations,
            periodic,
            area: markers.iter().flatten().map(|m| m.area).collect(),
            position: vec![[0.0; 3]; total],
            solid: vec![[0.0; 3]; total],
            fluid_u: vec![[0.0; 3]; total],
            increment: vec![[0.0; 3]; total],
            marker_force: vec![[0.0; 3]; total],
            field: vec![[0.0; 3]; nodes],
            hydro: vec![(Vec3::zeros(), Vec3::zeros()); n_bodies],
            markers,
        })
    }

    /// The fluid.
    pub fn fluid(&self) -> &Fluid<T> {
        &self.fluid
    }

    /// The fluid, mutably (initial conditions, obstacles). The force field must stay on.
    pub fn fluid_mut(&mut self) -> &mut Fluid<T> {
        &mut self.fluid
    }

    /// The bodies.
    pub fn bodies(&self) -> &[RigidBody] {
        &self.bodies
    }

    /// Markers of body `b` (body frame).
    pub fn markers(&self, b: usize) -> &[Marker] {
        &self.markers[b]
    }

    /// Total number of markers.
    pub fn marker_count(&self) -> usize {
        *self.offsets.last().unwrap()
    }

    /// Forcing iterations per step.
    pub fn iterations(&self) -> usize {
        self.iterations
    }

    /// Force of each marker on the fluid in the last step, `Σ_k ΔF_m^k A_m` (global marker
    /// order: body by body).
    pub fn marker_forces(&self) -> &[[f64; 3]] {
        &self.marker_force
    }

    /// Hydrodynamic force on body `b` from the last step: `−Σ_m F_m` over its markers.
    pub fn hydrodynamic_force(&self, b: usize) -> Vec3 {
        self.hydro[b].0
    }

    /// Hydrodynamic torque on body `b` about its centre, from the last step:
    /// `−Σ_m (X_m − x_c) × F_m`.
    pub fn hydrodynamic_torque(&self, b: usize) -> Vec3 {
        self.hydro[b].1
    }

    /// Advances the coupled system by one time step (`Δt = 1`). The order, at time `t_n`:
    ///
    /// 1. Marker world positions `X_m` and solid velocities `U_m = v + ω × r` from the bodies
    ///    at `t_n` (global marker order: body by body, marker by marker).
    /// 2. [`Stencils::build`] with the box's periodicity (from the fluid's boundaries); no
    ///    allocation once warm.
    /// 3. The spread buffer is zeroed (the fluid's force field is overwritten from it below,
    ///    so it too starts the step cleared).
    /// 4. `K` direct-forcing iterations, each: interpolate the fluid velocity
    ///    `u_m = I u` with `u = (j + F/2)/ρ` read from the populations through a
    ///    [`FnField`] over [`Fluid::macroscopic`] (which includes the current force field's
    ///    half-force correction, so each iteration sees the velocity corrected by the
    ///    previous ones); `ΔF_m = 2 ρ_m (U_m − u_m)` with `ρ_m = 1` (module docs); marker force
    ///    `ΔF_m · A_m` (marker volume `A_m Δ`, `Δ = 1`), accumulated per marker; spread into the
    ///    full-grid buffer (adds) and the buffer copied into the fluid's force field.
    /// 5. [`Fluid::step`]: collision with the uniform body force plus the IBM force field.
    /// 6. Hydrodynamic force and torque on each body: `−Σ_m F_m` and `−Σ_m (X_m − x_c) × F_m`
    ///    over its markers (the interior-fluid momentum term is not included: fixed and
    ///    prescribed bodies only), stored (see [`Coupled::hydrodynamic_force`]).
    ///
    /// Then fixed and prescribed bodies are advanced by [`RigidBody::step`] (prescribed ones
    /// move; no loads are applied to them).
    ///
    /// # Errors
    /// The stencils could not be built; nothing has been changed then.
    pub fn step(&mut self) -> Result<(), CouplingError> {
        // 1. Marker positions and velocities.
        for (b, body) in self.bodies.iter().enumerate() {
            let range = self.offsets[b]..self.offsets[b + 1];
            for ((m, x), u) in
                self.markers[b].iter().zip(&mut self.position[range.clone()]).zip(&mut self.solid[range])
            {
                let (xw, _n, uw) = body.marker_world(m);
                *x = [xw.x, xw.y, xw.z];
                *u = [uw.x, uw.y, uw.z];
            }
        }
        // 2. Stencils.
        let grid = self.fluid.grid();
        self.stencils.build(grid, self.periodic, &self.position)?;
        // 3. Clear.
        self.field.par_iter_mut().for_each(|v| *v = [0.0; 3]);
        self.marker_force.par_iter_mut().for_each(|v| *v = [0.0; 3]);
        // 4. Forcing iterations.
        for _ in 0..self.iterations {
            {
                let fluid = &self.fluid;
                let field = FnField {
                    nodes: grid.nodes(),
                    f: |n: usize| {
                        let [x, y, z] = grid.coords(n);
                        fluid.macroscopic(x, y, z).1
                    },
                };
                interpolate(&field, &self.stencils, &mut self.fluid_u);
            }
            for m in 0..self.increment.len() {
                let a = self.area[m];
                let (us, uf) = (self.solid[m], self.fluid_u[m]);
                let df: [f64; 3] = std::array::from_fn(|k| 2.0 * (us[k] - uf[k]) * a);
                self.increment[m] = df;
                for k in 0..3 {
                    self.marker_force[m][k] += df[k];
                }
            }
            spread(&self.increment, &self.stencils, &mut self.field);
            for z in 0..grid.nz {
                for y in 0..grid.ny {
                    for x in 0..grid.nx {
                        self.fluid.set_force(x, y, z, self.field[grid.index(x, y, z)]);
                    }
                }
            }
        }
        // 5. Fluid step.
        self.fluid.step();
        // 6. Loads on the bodies.
        for (b, body) in self.bodies.iter().enumerate() {
            let mut f = Vec3::zeros();
            let mut t = Vec3::zeros();
            for m in self.offsets[b]..self.offsets[b + 1] {
                let fm = Vec3::from(self.marker_force[m]);
                let r = Vec3::from(self.position[m]) - body.position;
                f -= fm;
                t -= r.cross(&fm);
            }
            self.hydro[b] = (f, t);
        }
        for body in &mut self.bodies {
            body.step(1.0);
        }
        Ok(())
    }

    /// Runs `n` steps.
    ///
    /// # Errors
    /// As [`Coupled::step`]; the run stops at the first error.
    pub fn run(&mut self, n: u64) -> Result<(), CouplingError> {
        for _ in 0..n {
            self.step()?;
        }
        Ok(())
    }

    /// The shape of body `b` (convenience).
    pub fn shape(&self, b: usize) -> &Arc<dyn Shape> {
        self.bodies[b].shape()
    }
}

#[cfg(test)]
mod tests;
