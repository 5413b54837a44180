//! [`DeviceCoupled`]: the coupled step with the fluid and the immersed-boundary markers on the
//! device and the bodies on the host, for **fixed and prescribed bodies** (obstacles,
//! impellers).
//!
//! Per step, as `coupling::Coupled::step` orders it: the bodies' states at `tⁿ` go up
//! ([`DeviceMarkers::set_bodies`]); on the device the markers are placed, the previous step's
//! forcing is cleared, `K` direct-forcing iterations force the fluid
//! ([`DeviceMarkers::force`]), the fluid steps ([`DeviceFluid::step`]) and the IBM loads are
//! reduced; they come down ([`DeviceMarkers::loads`]); the bodies advance on the host
//! (prescribed bodies follow their motion, fixed bodies stay: `RigidBody::step`, what
//! `contact::step_bodies` does without contacts). The only per-step traffic: 112 bytes a body
//! up, 32 bytes a body down.
//!
//! **What is not here, and why free bodies are refused.** A free body's load on the CPU is the
//! IBM load plus the rate of change of the momentum of the fluid inside it (the interior sums
//! `P`, `L`, `V` before and after the fluid step, `coupling::interior`), and its update takes
//! the forcing shell's reaction implicitly (`coupling::loads`); without both the update is
//! unstable for the paper's density ratio (the `coupling` module docs). Neither is on the
//! device yet, so [`DeviceCoupled::new`] refuses free bodies, and contacts (which act only on
//! free bodies' motion). For a prescribed body the CPU has no interior term either: its loads
//! here are the CPU's hydrodynamic loads (an impeller's torque is the paper's fluid torque).
//! For a fixed body the CPU adds the interior term to the reported load (zero in a steady
//! flow); here only the IBM part is given.

use super::markers::DeviceMarkers;
use super::{Context, DeviceError, DeviceFluid};
use crate::coupling::CouplingParams;
use crate::lbm::Fluid;
use crate::rigid::{Marker, RigidBody, Vec3};

/// The coupled step of fixed and prescribed bodies with the fluid and the markers on the
/// device (module docs).
pub struct DeviceCoupled {
    host: Fluid<f32>,
    fluid: DeviceFluid,
    markers: DeviceMarkers,
    sets: Vec<Vec<Marker>>,
    bodies: Vec<RigidBody>,
    iterations: usize,
    loads: Vec<(Vec3, Vec3)>,
}

impl DeviceCoupled {
    /// Couples `fluid` (made the host mirror; its force field turned on and owned by the
    /// coupling) with `bodies` on the device: each body's forcing markers as
    /// `coupling::Coupled::new` makes them (`params.marker_spacing`, retracted by
    /// `params.retraction`), `params.kernel` and `params.iterations`; work groups of
    /// `workgroup` threads.
    ///
    /// # Errors
    /// [`DeviceError::Mismatch`] for a free body, contacts, no forcing iteration, a marker
    /// spacing that is not positive and finite, or a body that cannot be retracted; the device
    /// fluid's and markers' errors.
    pub fn new(
        ctx: &Context,
        mut fluid: Fluid<f32>,
        bodies: Vec<RigidBody>,
        params: CouplingParams,
        workgroup: u32,
    ) -> Result<Self, DeviceError> {
        if let Some(b) = bodies.iter().position(RigidBody::is_free) {
            return Err(DeviceError::Mismatch(format!(
                "body {b} is free: free bodies need the interior-fluid term and the implicit shell \
                 reaction, which are not on the device yet"
            )));
        }
        if params.contacts.is_some() {
            return Err(DeviceError::Mismatch(
                "contacts are not on the device (they move only free bodies, which are refused)".into(),
            ));
        }
        if params.iterations == 0 {
            return Err(DeviceError::Mismatch("at least one forcing iteration is needed".into()));
        }
        if !(params.marker_spacing.is_finite() && params.marker_spacing > 0.0) {
            return Err(DeviceError::Mismatch(format!(
                "marker spacing {}: must be positive and finite",
                params.marker_spacing
            )));
        }
        let sets = bodies
            .iter()
            .enumerate()
            .map(|(i, b)| {
                b.shape()
                    .retracted_markers(params.marker_spacing, params.retraction)
                    .map_err(|e| DeviceError::Mismatch(format!("body {i}: {e}")))
            })
            .collect::<Result<Vec<_>, _>>()?;
        fluid.enable_force_field();
        let device_fluid = DeviceFluid::new(ctx, &fluid, workgroup)?;
        let refs: Vec<&[Marker]> = sets.iter().map(Vec::as_slice).collect();
        let markers = DeviceMarkers::new(&device_fluid, &refs, params.kernel, workgroup)?;
        let n = bodies.len();
        Ok(Self {
            host: fluid,
            fluid: device_fluid,
            markers,
            sets,
            bodies,
            iterations: params.iterations,
            loads: vec![(Vec3::zeros(), Vec3::zeros()); n],
        })
    }

    /// Advances one time step (module docs). Blocks until the loads are down.
    ///
    /// # Errors
    /// [`DeviceError::Marker`] when a marker left the box on a walled axis or is not finite
    /// (the fluid has stepped without it: the state is to be discarded); the device's errors.
    pub fn step(&mut self) -> Result<(), DeviceError> {
        self.markers.set_bodies(&self.bodies);
        self.markers.force(&self.fluid, self.iterations)?;
        self.fluid.step()?;
        self.loads = self.markers.loads()?;
        for b in &mut self.bodies {
            b.step(1.0);
        }
        Ok(())
    }

    /// Runs `n` steps.
    ///
    /// # Errors
    /// As [`DeviceCoupled::step`]; the run stops at the first error.
    pub fn run(&mut self, n: u64) -> Result<(), DeviceError> {
        for _ in 0..n {
            self.step()?;
        }
        Ok(())
    }

    /// The bodies (on the host).
    pub fn bodies(&self) -> &[RigidBody] {
        &self.bodies
    }

    /// Forcing markers of body `b` (body frame).
    pub fn markers(&self, b: usize) -> &[Marker] {
        &self.sets[b]
    }

    /// The IBM loads on body `b` from the last step: `(−Σ F_m, −Σ r_m × F_m)`, torque about
    /// its centre (world frame).
    pub fn ibm_loads(&self, b: usize) -> (Vec3, Vec3) {
        self.loads[b]
    }

    /// The device fluid.
    pub fn device_fluid(&self) -> &DeviceFluid {
        &self.fluid
    }

    /// The device markers.
    pub fn device_markers(&self) -> &DeviceMarkers {
        &self.markers
    }

    /// The host mirror brought up to date: the device's populations, time and force field
    /// (the last step's forcing, which the velocity `(j + F/2)/ρ` at this step includes), for
    /// output. Blocks until the device is done.
    ///
    /// # Errors
    /// The read-back's.
    pub fn download(&mut self) -> Result<&Fluid<f32>, DeviceError> {
        self.fluid.download(&mut self.host)?;
        let force = self.fluid.download_force()?;
        self.host.raw_force_mut().copy_from_slice(&force);
        Ok(&self.host)
    }
}
