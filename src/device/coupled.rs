//! [`DeviceCoupled`]: the coupled step with the fluid, the immersed-boundary markers and the
//! interior-fluid sums on the device and the bodies and their contacts on the host: fixed,
//! prescribed (obstacles, impellers) and free bodies.
//!
//! Per step, in `coupling::Coupled::step`'s order: the bodies' states at `tⁿ` go up
//! ([`DeviceMarkers::set_bodies`]); on the device the interior sums before the forcing
//! (phase 3, when there are free bodies), the markers placed and the previous forcing cleared,
//! `K` direct-forcing iterations ([`DeviceMarkers::force`]: phases 1–2, 4–5), the fluid step
//! (6) and the interior sums after it (7); the IBM loads and the interior sums come down
//! ([`DeviceMarkers::loads`], [`DeviceMarkers::interior_sums`]); on the host the loads are
//! composed as `coupling::loads` composes them (the IBM part plus the interior rates with their
//! flux corrections) and the bodies advance as there (phase 8): free bodies with the implicit
//! shell reaction and their net weight, prescribed bodies along their motion, fixed bodies
//! staying, all sub-cycled with the contacts when there are any (`contact::step_bodies`, with
//! the contacts' own markers on the true surface). The per-step traffic: 112 bytes a body up,
//! 144 bytes a body down.
//!
//! **Limits.** The interior sums need the shape's signed distance on the device: spheres, cylinders and cuboids (`markers/interior`); when there are free bodies,
//! every fixed or free body must be one. Without free bodies the interior sums are skipped and
//! a fixed body's loads lack the interior term (zero in a steady flow), which the CPU reports.
use super::markers::DeviceMarkers;
use super::{Context, DeviceError, DeviceFluid};
use crate::contact::{Contacts, Walls};
use crate::coupling::{
    advance_bodies, body_states, interior_loads, restore_bodies, shell_inertia, BodyLoads, BodyUpdate,
    CoupledState, CouplingParams, InteriorMomentum,
};
use crate::lbm::Fluid;
use crate::rigid::{LoadScheme, Marker, RigidBody, Vec3};

/// The coupled step of fixed and prescribed bodies with the fluid and the markers on the
/// device (module docs).
pub struct DeviceCoupled {
    host: Fluid<f32>,
    fluid: DeviceFluid,
    markers: DeviceMarkers,
    sets: Vec<Vec<Marker>>,
    bodies: Vec<RigidBody>,
    iterations: usize,
    gravity: Vec3,
    /// Whether the interior sums run (there are free bodies).
    interior: bool,
    loads: Vec<BodyLoads>,
    /// Per body, the forcing shell's mass and body-frame moments.
    shell: Vec<(f64, Vec3)>,
    /// Per body, its velocity change in the last step (free bodies; zero otherwise).
    velocity_change: Vec<(Vec3, Vec3)>,
    /// Scratch for the body update: the velocities at the step's start.
    start: Vec<(Vec3, Vec3)>,
    /// The contacts (on the host), with each body's contact markers on its true surface.
    contacts: Option<Contacts>,
    contact_markers: Vec<Vec<Marker>>,
}

impl DeviceCoupled {
    /// Couples `fluid` (made the host mirror; its force field turned on and owned by the
    /// coupling) with `bodies` on the device: each body's forcing markers as
    /// `coupling::Coupled::new` makes them (`params.marker_spacing`, retracted by
    /// `params.retraction`), `params.kernel` and `params.iterations`; work groups of
    /// `workgroup` threads.
    ///
    /// # Errors
    /// [`DeviceError::Mismatch`] for invalid contact parameters, no forcing iteration, a marker spacing that is
    /// not positive and finite, a body that cannot be retracted, or (with free bodies) a fixed
    /// or free body whose signed distance the device does not have; the device fluid's and
    /// markers' errors.
    pub fn new(
        ctx: &Context,
        mut fluid: Fluid<f32>,
        mut bodies: Vec<RigidBody>,
        params: CouplingParams,
        workgroup: u32,
    ) -> Result<Self, DeviceError> {
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
        let mut markers = DeviceMarkers::new(&device_fluid, &refs, params.kernel, workgroup)?;
        let interior = bodies.iter().any(RigidBody::is_free);
        if interior {
            markers.enable_interior(&bodies)?;
        }
        for b in bodies.iter_mut().filter(|b| b.is_free()) {
            b.load_scheme = LoadScheme::Constant;
        }
        // The contacts as `coupling::Coupled::new` makes them: markers on the true surface,
        // the box's walls where it is not periodic.
        let contact_markers: Vec<Vec<Marker>> =
            bodies.iter().map(|b| b.shape().markers(params.marker_spacing)).collect();
        let contacts = match params.contacts {
            Some(cp) => {
                if cp.substeps == 0 {
                    return Err(DeviceError::Mismatch("contact substeps must be at least 1".into()));
                }
                let g = fluid.grid();
                let walls = Walls::bounce_back([g.nx, g.ny, g.nz], device_fluid.periodic().map(|p| !p));
                let c = Contacts::new(cp, walls, &bodies, &contact_markers)
                    .map_err(|e| DeviceError::Mismatch(format!("contacts: {e}")))?;
                Some(c)
            }
            None => None,
        };
        let n = bodies.len();
        Ok(Self {
            host: fluid,
            fluid: device_fluid,
            markers,
            shell: sets.iter().map(|m| shell_inertia(m)).collect(),
            sets,
            bodies,
            iterations: params.iterations,
            gravity: Vec3::from(params.gravity),
            interior,
            loads: vec![BodyLoads::default(); n],
            velocity_change: vec![(Vec3::zeros(), Vec3::zeros()); n],
            start: vec![(Vec3::zeros(), Vec3::zeros()); n],
            contacts,
            contact_markers,
        })
    }

    /// Advances one time step (module docs). Blocks until the loads are down.
    ///
    /// # Errors
    /// [`DeviceError::Marker`] when a marker left the box on a walled axis or is not finite
    /// (the fluid has stepped without it: the state is to be discarded); the device's errors.
    pub fn step(&mut self) -> Result<(), DeviceError> {
        self.markers.set_bodies(&self.bodies);
        if self.interior {
            self.markers.interior(&self.fluid, false)?;
        }
        self.markers.force(&self.fluid, self.iterations)?;
        // Queued behind the forcing; the read-back of the loads below waits for both.
        self.fluid.submit_steps(1);
        if self.interior {
            self.markers.interior(&self.fluid, true)?;
        }
        let (ibm, sums) = if self.interior {
            let (l, s) = self.markers.loads_and_interior_sums()?;
            (l, Some(s))
        } else {
            (self.markers.loads()?, None)
        };
        // Phase 7's loads, as `coupling::loads::collect_loads` composes them.
        for (b, (body, (f, t))) in self.bodies.iter().zip(ibm).enumerate() {
            let (interior_force, interior_torque) = match &sums {
                Some(s) => {
                    let [before, after] = s[b];
                    interior_loads(body, &InteriorMomentum { before, after })
                }
                None => (Vec3::zeros(), Vec3::zeros()),
            };
            self.loads[b] =
                BodyLoads { ibm_force: f, ibm_torque: t, interior_force, interior_torque, ..self.loads[b] };
        }
        advance_bodies(
            self.contacts.as_mut(),
            &mut self.bodies,
            &self.contact_markers,
            BodyUpdate {
                loads: &mut self.loads,
                shell: &self.shell,
                velocity_change: &mut self.velocity_change,
                start: &mut self.start,
            },
            self.gravity,
        );
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
        (self.loads[b].ibm_force, self.loads[b].ibm_torque)
    }

    /// The loads on body `b` from the last step, as `coupling::Coupled::loads` gives them
    /// (the interior term zero when there are no free bodies).
    pub fn loads(&self, b: usize) -> &BodyLoads {
        &self.loads[b]
    }

    /// The device fluid.
    pub fn device_fluid(&self) -> &DeviceFluid {
        &self.fluid
    }

    /// The host mirror of the fluid as of the last [`DeviceCoupled::download`] (or
    /// [`DeviceCoupled::restore`]): what output reads.
    pub fn host(&self) -> &Fluid<f32> {
        &self.host
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

    /// The state for a checkpoint at an even time step, as `coupling::Coupled::snapshot` takes
    /// it (the fluid with the last step's force field, the bodies with their last velocity
    /// change and contact loads): a CPU run's state, which either kind of run restores.
    /// Downloads the fluid into the host mirror first.
    ///
    /// # Errors
    /// At an odd time step ([`DeviceError::Mismatch`]); the read-back's.
    pub fn snapshot(&mut self) -> Result<CoupledState<f32>, DeviceError> {
        self.download()?;
        let fluid = self.host.snapshot().map_err(|e| DeviceError::Mismatch(e.to_string()))?;
        let bodies = body_states(&self.bodies, &self.velocity_change, &self.loads);
        Ok(CoupledState { fluid, bodies })
    }

    /// Restores a state taken by [`DeviceCoupled::snapshot`] or `coupling::Coupled::snapshot`
    /// of the same case, as `Coupled::restore` does: the fluid (with the state's force field,
    /// or a zero one) goes up to the device, the next placement clears the whole field, and the
    /// bodies are set bit for bit. The continuation is bitwise the uninterrupted device run's.
    ///
    /// # Errors
    /// A fluid state that does not fit or a body count that differs
    /// ([`DeviceError::Mismatch`]).
    pub fn restore(&mut self, s: &CoupledState<f32>) -> Result<(), DeviceError> {
        if s.bodies.len() != self.bodies.len() {
            return Err(DeviceError::Mismatch(format!(
                "state has {} bodies, the case has {}",
                s.bodies.len(),
                self.bodies.len()
            )));
        }
        self.host.restore(&s.fluid).map_err(|e| DeviceError::Mismatch(e.to_string()))?;
        if s.fluid.force.is_none() {
            self.host.enable_force_field();
            self.host.clear_force_field();
        }
        self.fluid.upload(&self.host)?;
        self.markers.reset();
        restore_bodies(&mut self.bodies, &mut self.velocity_change, &mut self.loads, &s.bodies);
        Ok(())
    }
}
