//! The solver a run steps ([`Solver`]): the fluid alone, the fluid coupled with bodies, or
//! either on the device with its host mirror.

use crate::case::{Case, ImpellerSetup, ParticleInit};
use crate::coupling::{Coupled, CoupledState};
use crate::device::fluid::DEFAULT_WORKGROUP;
use crate::device::{Context as DeviceContext, DeviceCoupled, DeviceFluid};
use crate::drive::{self, particle_frame, particle_frame_of};
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
    /// The fluid, the markers and the interior sums stepped by the device, the bodies and
    /// their contacts on the host ([`DeviceCoupled`]); the fluid's host mirror
    /// ([`DeviceCoupled::host`]) is up to date when `synced` ([`Solver::sync`] at output
    /// steps). Per step only the bodies' states go up and their loads come down.
    DeviceCoupled {
        device: Box<DeviceCoupled>,
        synced: bool,
    },
}

/// A host fluid as the storage precision it has, for the device fluid's calls (which take
/// the device's precisions, [`crate::device::fluid::DeviceReal`]).
enum HostFluid<'a> {
    F32(&'a mut Fluid<f32>),
    F64(&'a mut Fluid<f64>),
}

fn host_fluid<T: Real>(f: &mut Fluid<T>) -> anyhow::Result<HostFluid<'_>> {
    let any = f as &mut dyn std::any::Any;
    if any.is::<Fluid<f32>>() {
        any.downcast_mut().map(HostFluid::F32)
    } else {
        any.downcast_mut().map(HostFluid::F64)
    }
    .ok_or_else(|| anyhow::anyhow!("the device stores the populations in f32 or f64, not {}", T::NAME))
}

/// A coupled state of a device run with bodies (f32: the markers work in f32).
pub(super) fn as_f32_state<T: Real>(s: CoupledState<T>) -> anyhow::Result<CoupledState<f32>> {
    let b: Box<dyn std::any::Any> = Box::new(s);
    b.downcast::<CoupledState<f32>>().map(|s| *s).map_err(|_| {
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
            // A device run is f32 (`onto_device`), so the downcast holds.
            Solver::DeviceCoupled { device, .. } => (device.host() as &dyn std::any::Any)
                .downcast_ref::<Fluid<T>>()
                .expect("a device run's fluid is f32"),
        }
    }

    /// Whether bodies are coupled to the fluid (on the CPU or on the device).
    pub(super) fn is_coupled(&self) -> bool {
        matches!(self, Solver::Coupled(_) | Solver::DeviceCoupled { .. })
    }

    /// Steps completed.
    pub(super) fn time(&self) -> u64 {
        match self {
            Solver::Device { device, .. } => device.time(),
            Solver::DeviceCoupled { device, .. } => device.device_fluid().time(),
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
            Solver::DeviceCoupled { device, synced } => {
                *synced = false;
                Ok(device.run(n)?)
            }
        }
    }

    /// Advances up to `block` steps: a step at a time on the CPU, in batches of 64 on the
    /// device's fluid (each a wait for the device; the coupled device step waits for its loads
    /// every step, so it goes a step at a time as on the CPU); returns early, at an even step, when a stop is
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
                match host_fluid(host)? {
                    HostFluid::F32(h) => device.download(h)?,
                    HostFluid::F64(h) => device.download(h)?,
                }
                *synced = true;
            }
        }
        if let Solver::DeviceCoupled { device, synced } = self {
            if !*synced {
                device.download()?;
                *synced = true;
            }
        }
        Ok(())
    }

    /// The solver moved onto the device (`run.device = "gpu"`), from its present state: the
    /// fluid alone into a [`DeviceFluid`]; the coupled solver (at an even step) into a
    /// [`DeviceCoupled`] of the same case (`case`, its particles `inits` and `impeller`),
    /// which restores the CPU solver's state ([`DeviceCoupled::restore`]).
    pub(super) fn onto_device(
        self,
        case: &Case,
        inits: &[ParticleInit],
        impeller: Option<&ImpellerSetup>,
    ) -> anyhow::Result<Self> {
        match self {
            Solver::Fluid(mut host) => {
                let ctx = DeviceContext::new()?;
                let device = match host_fluid(&mut host)? {
                    HostFluid::F32(h) => DeviceFluid::new(&ctx, h, DEFAULT_WORKGROUP)?,
                    HostFluid::F64(h) => DeviceFluid::new(&ctx, h, DEFAULT_WORKGROUP)?,
                };
                Ok(Solver::Device { host, device: Box::new(device), synced: true })
            }
            Solver::Coupled(c) => {
                let state = as_f32_state(c.snapshot().map_err(|e| anyhow::anyhow!("onto the device: {e}"))?)?;
                drop(c);
                let mut bodies: Vec<_> = inits.iter().map(|p| p.body()).collect();
                bodies.extend(impeller.map(ImpellerSetup::body));
                let ctx = DeviceContext::new()?;
                let mut device = DeviceCoupled::new(
                    &ctx,
                    drive::fluid::<f32>(case)?,
                    bodies,
                    case.coupling_params(),
                    DEFAULT_WORKGROUP,
                )
                .map_err(|e| {
                    anyhow::anyhow!("cannot couple the particles and the impeller on the device: {e}")
                })?;
                device.restore(&state)?;
                Ok(Solver::DeviceCoupled { device: Box::new(device), synced: false })
            }
            Solver::Device { .. } | Solver::DeviceCoupled { .. } => Ok(self),
        }
    }

    /// The state of the first `n` bodies (the particles) now, with the hydrodynamic loads of
    /// the last step; `None` without particles.
    pub(super) fn particle_frame(&self, n: usize) -> Option<ParticleFrame> {
        match self {
            Solver::Coupled(c) => (n > 0).then(|| particle_frame(c, n)),
            Solver::DeviceCoupled { device, .. } => {
                (n > 0).then(|| particle_frame_of(self.time(), &device.bodies()[..n], |b| device.loads(b)))
            }
            _ => None,
        }
    }
}
