//! What the drivers share (`run`, `settle`, and through them `reproduce`): the solver built
//! from a [`Case`] ([`fluid`], [`coupled`]) and the particle output of `particles.h5`
//! (`particle_frame`, `particle_statics`). A driver builds and writes through these, so
//! that a bed settled by `settle` and a stirred run of `run` start from the same set-up and
//! write the same layout; no driver imports another for them.

use anyhow::Context;

use crate::case::{Case, ImpellerSetup, ParticleInit};
use crate::coupling::{BodyLoads, Coupled};
use crate::io::{ParticleFrame, ParticleStatic};
use crate::lbm::{Fluid, Real};
use crate::rigid::{RigidBody, Vec3};

/// The case's fluid (grid, parameters, box faces) in its initial state.
///
/// # Errors
/// The fluid's parameters are rejected (the case's validation should have caught it).
pub fn fluid<T: Real>(case: &Case) -> anyhow::Result<Fluid<T>> {
    let mut fluid = Fluid::<T>::new(case.grid(), case.fluid_params(), case.boundaries())
        .context("cannot set up the fluid")?;
    fluid.initialize(|x, y, z| case.initial_state(x, y, z));
    Ok(fluid)
}

/// The case's fluid coupled with the bodies of `inits` and, after them, the impeller's.
///
/// # Errors
/// The fluid cannot be set up, or the coupling rejects a body (e.g. one that does not fit).
pub fn coupled<T: Real>(
    case: &Case,
    inits: &[ParticleInit],
    impeller: Option<&ImpellerSetup>,
) -> anyhow::Result<Coupled<T>> {
    let mut bodies: Vec<_> = inits.iter().map(|p| p.body()).collect();
    bodies.extend(impeller.map(ImpellerSetup::body));
    Coupled::new(fluid(case)?, bodies, case.coupling_params())
        .map_err(|e| anyhow::anyhow!("cannot couple the particles and the impeller: {e}"))
}

/// The state of the first `n` bodies (the particles) now, with the hydrodynamic loads of the
/// last step (a frame of `particles.h5`; also the bed of `slurry settle`).
pub(crate) fn particle_frame<T: Real>(c: &Coupled<T>, n: usize) -> ParticleFrame {
    particle_frame_of(c.fluid().time(), &c.bodies()[..n], |b| c.loads(b))
}

/// The frame of `bodies` at step `step`, body `b`'s loads of the last step being `loads(b)`
/// (the CPU's coupling or the device's, [`crate::device::DeviceCoupled::loads`]).
pub(crate) fn particle_frame_of<'a>(
    step: u64,
    bodies: &[RigidBody],
    loads: impl Fn(usize) -> &'a BodyLoads,
) -> ParticleFrame {
    let v3 = |v: &Vec3| [v.x, v.y, v.z];
    ParticleFrame {
        step,
        time: step as f64,
        position: bodies.iter().map(|b| v3(&b.position)).collect(),
        quaternion: bodies
            .iter()
            .map(|b| {
                let q = b.orientation.quaternion();
                [q.w, q.i, q.j, q.k]
            })
            .collect(),
        velocity: bodies.iter().map(|b| v3(&b.velocity)).collect(),
        angular_velocity: bodies.iter().map(|b| v3(&b.angular_velocity)).collect(),
        force: (0..bodies.len()).map(|b| v3(&loads(b).force())).collect(),
        torque: (0..bodies.len()).map(|b| v3(&loads(b).torque())).collect(),
    }
}

/// The static per-particle data of `particles.h5`.
pub(crate) fn particle_statics(inits: &[ParticleInit]) -> Vec<ParticleStatic> {
    inits
        .iter()
        .map(|p| ParticleStatic {
            shape: p.shape.name(),
            diameter: p.diameter,
            length: p.length.unwrap_or(f64::NAN),
            density: p.density,
            volume: p.volume(),
            mass: p.density * p.volume(),
            motion: p.motion.name(),
        })
        .collect()
}
