//! Where the verification's fluid steps run: on the CPU (the default), or on the device
//! (`slurry-verify --device gpu`, `cargo xtask verify --device gpu`).
//!
//! On the device the cases whose flow is the fluid alone ([`crate::Case::device`]: Poiseuille,
//! Couette, Taylor–Green, mass conservation) run their set-up, checks and tolerances unchanged;
//! only the time stepping moves: each `Fluid::run` of the case becomes the same steps on a
//! [`DeviceFluid`] made from the case's fluid (the same grid, parameters, boundaries and
//! start), downloaded into that fluid after every stretch, so the case reads its profiles and
//! sums from it as before. f64 cases run in f64 on the device, which needs 64-bit float shaders
//! (lavapipe and NVIDIA's Vulkan driver have them); the device then differs from the CPU by
//! round-off only (`tests/device_fluid.rs`: populations within 5e-18 after 200 steps), so the
//! CPU's tolerances and reference tables apply as they are.

use std::sync::OnceLock;

use slurry::device::fluid::{DeviceReal, DEFAULT_WORKGROUP};
use slurry::device::{Context, DeviceError, DeviceFluid};
use slurry::lbm::Fluid;

static DEVICE: OnceLock<Context> = OnceLock::new();

/// Opens the device for the rest of the process: from here on the cases' fluid steps there.
///
/// # Errors
/// No Vulkan adapter, or the device could not be opened.
pub fn use_device() -> Result<&'static Context, DeviceError> {
    if let Some(c) = DEVICE.get() {
        return Ok(c);
    }
    let ctx = Context::new()?;
    Ok(DEVICE.get_or_init(|| ctx))
}

/// The device, when [`use_device`] opened it.
pub fn device() -> Option<&'static Context> {
    DEVICE.get()
}

/// Steps a case's fluid on the processor chosen ([`use_device`]): the CPU's `Fluid::run`, or
/// the device's, with the fluid downloaded after each [`Stepper::run`].
pub(crate) struct Stepper<'a, T: DeviceReal> {
    fluid: &'a mut Fluid<T>,
    device: Option<DeviceFluid>,
}

impl<'a, T: DeviceReal> Stepper<'a, T> {
    /// A stepper of `fluid` from its present state.
    ///
    /// # Panics
    /// On the device, when the device fluid cannot be made (the adapter's limits, or f64
    /// without 64-bit float shaders): the case cannot run there.
    pub(crate) fn new(fluid: &'a mut Fluid<T>) -> Self {
        let device = device().map(|ctx| {
            DeviceFluid::new(ctx, fluid, DEFAULT_WORKGROUP)
                .unwrap_or_else(|e| panic!("the case's fluid on the device ({}): {e}", ctx.describe()))
        });
        Self { fluid, device }
    }

    /// Advances `n` steps; on the device, then downloads into the fluid.
    ///
    /// # Panics
    /// When the device reports an error.
    pub(crate) fn run(&mut self, n: u64) {
        match &mut self.device {
            None => self.fluid.run(n),
            Some(d) => {
                d.run(n).unwrap_or_else(|e| panic!("device steps: {e}"));
                d.download(self.fluid).unwrap_or_else(|e| panic!("device download: {e}"));
            }
        }
    }

    /// The fluid, as of the last [`Stepper::run`].
    pub(crate) fn fluid(&self) -> &Fluid<T> {
        self.fluid
    }
}
