//! The solver a run steps ([`Solver`]): the fluid alone, the fluid coupled with bodies, or the
//! fluid on the device with its host mirror.

use crate::coupling::Coupled;
use crate::device::{fluid::DEFAULT_WORKGROUP, Context as DeviceContext, DeviceFluid};
use crate::drive::particle_frame;
use crate::interrupt;
use crate::io::ParticleFrame;
use crate::lbm::{Fluid, Real};

/// The fluid alone, or the fluid coupled with particles, or the fluid alone on the device.
pub(super) enum Solver<T: Real> {
    Fluid(Box<Fluid<T>>),
    Coupled(Box<Coupled<T>>),
    /// The fluid stepped by the device; `host` is its mirror for output, up to date when
    /// `synced` ([`Solver::sync`] at output steps).
    Device {
        host: Box<Fluid<T>>,
        device: Box<DeviceFluid>,
        synced: bool,
    },
}

/// The f32 fluid that a device run holds (case validation admits `run.device = "gpu"` only
/// with `fluid.precision = "f32"`).
fn as_f32<T: Real>(f: &mut Fluid<T>) -> anyhow::Result<&mut Fluid<f32>> {
    (f as &mut dyn std::any::Any).downcast_mut::<Fluid<f32>>().ok_or_else(|| {
        anyhow::anyhow!("the device stores the populations in f32: set fluid.precision = \"f32\"")
    })
}

impl<T: Real> Solver<T> {
    /// The fluid; on the device, its host mirror as of the last [`Solver::sync`].
    pub(super) fn fluid(&self) -> &Fluid<T> {
        match self {
            Solver::Fluid(f) => f,
            Solver::Coupled(c) => c.fluid(),
            Solver::Device { host, .. } => host,
        }
    }

    /// Steps completed.
    pub(super) fn time(&self) -> u64 {
        match self {
            Solver::Device { device, .. } => device.time(),
            _ => self.fluid().time(),
        }
    }

    pub(super) fn run(&mut self, n: u64) -> anyhow::Result<()> {
        match self {
            Solver::Fluid(f) => {
                f.run(n);
                Ok(())
            }
            Solver::Coupled(c) => Ok(c.run(n)?),
            Solver::Device { device, synced, .. } => {
                *synced = false;
                Ok(device.run(n)?)
            }
        }
    }

    /// Advances up to `block` steps: a step at a time on the CPU, in batches of 64 on the
    /// device (each a wait for the device); returns early, at an even step, when a stop is
    /// requested. Returns the steps done.
    pub(super) fn advance(&mut self, block: u64) -> anyhow::Result<u64> {
        let batch = if matches!(self, Solver::Device { .. }) { 64 } else { 1 };
        let mut done = 0;
        while done < block {
            // From an odd step one step first, so that the batches end at even steps.
            let n = if self.time().is_multiple_of(2) { batch } else { 1 }.min(block - done);
            self.run(n)?;
            done += n;
            if interrupt::requested().is_some() && self.time().is_multiple_of(2) {
                return Ok(done);
            }
        }
        Ok(block)
    }

    /// Brings the device run's host mirror up to date (nothing to do on the CPU).
    pub(super) fn sync(&mut self) -> anyhow::Result<()> {
        if let Solver::Device { host, device, synced } = self {
            if !*synced {
                device.download(as_f32(host)?)?;
                *synced = true;
            }
        }
        Ok(())
    }

    /// The fluid moved onto the device (`run.device = "gpu"`), from its present state.
    pub(super) fn onto_device(self) -> anyhow::Result<Self> {
        let Solver::Fluid(mut host) = self else {
            anyhow::bail!(
                "the device runs the fluid only so far: run a case with particles or an impeller on the CPU"
            );
        };
        let ctx = DeviceContext::new()?;
        let device = DeviceFluid::new(&ctx, as_f32(&mut host)?, DEFAULT_WORKGROUP)?;
        Ok(Solver::Device { host, device: Box::new(device), synced: true })
    }

    /// The state of the first `n` bodies (the particles) now, with the hydrodynamic loads of
    /// the last step; `None` without particles.
    pub(super) fn particle_frame(&self, n: usize) -> Option<ParticleFrame> {
        let Solver::Coupled(c) = self else { return None };
        (n > 0).then(|| particle_frame(c, n))
    }
}
