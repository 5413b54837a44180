//! `slurry settle`: let a case's particles settle under gravity into a bed, and store it.
//!
//! The paper's stirred runs start from "loosely packed random beds": particles placed at random
//! without overlap in the whole box ([`crate::case`]'s `[[random_particles]]`), settled under
//! gravity in the fluid with no impeller. This drives such a case — it must have free
//! particles, gravity and `[contacts]` — until the **stopping rule** holds: the mean speed of
//! the free particles, checked every `check_every` steps after at least `min_steps`, is below
//! `speed` (lattice units). The bed is written as
//! - `bed.h5`: one frame in the layout of `particles.h5` ([`crate::io::ParticleHistoryWriter`]),
//!   so the same readers work, and
//! - `bed_particles.toml`: the particles as explicit `[[particles]]` entries (positions and
//!   quaternions in shortest round-trip form, at rest), to paste or append into a stirred case,
//!
//! both written atomically. The placement is seeded, the step is deterministic for any thread
//! count, so the same case gives the same bed bit for bit.

use std::fmt::Write as _;
use std::path::{Path, PathBuf};
use std::time::Instant;

use anyhow::Context;

use crate::case::{Case, Precision};
use crate::coupling::Coupled;
use crate::io::{atomic_write_bytes, ParticleHistoryWriter};
use crate::lbm::kernel::Planes;
use crate::lbm::{Fluid, Real};
use crate::run::{particle_frame, particle_statics};

/// Options of [`settle_case`].
#[derive(Clone, Copy, Debug)]
pub struct SettleOptions {
    /// Stop when the mean speed of the free particles falls below this.
    pub speed: f64,
    /// Steps between checks of the stopping rule (even).
    pub check_every: u64,
    /// No stop before this many steps (the particles first have to start falling).
    pub min_steps: u64,
    /// Give up after this many steps (the bed is written anyway, marked as not settled).
    pub max_steps: u64,
    /// No progress output.
    pub quiet: bool,
}

/// What [`settle_case`] did.
#[derive(Clone, Debug)]
pub struct SettleSummary {
    /// Steps run.
    pub steps: u64,
    /// Mean speed of the free particles at the end.
    pub mean_speed: f64,
    /// Whether the stopping rule was met (else `max_steps` was reached).
    pub settled: bool,
    /// Mean height of the particle centres at the end.
    pub mean_height: f64,
    /// Wall-clock seconds.
    pub seconds: f64,
    /// `bed.h5`.
    pub bed_h5: PathBuf,
    /// `bed_particles.toml`.
    pub bed_toml: PathBuf,
}

/// Settles `case` (module docs) and writes the bed into `out_dir`.
///
/// # Errors
/// A case without free particles, gravity or `[contacts]`; a coupling error; numerical
/// trouble (non-finite particle state); an output failure.
pub fn settle_case(case: &Case, out_dir: &Path, opts: SettleOptions) -> anyhow::Result<SettleSummary> {
    // The paper settles the bed with no impeller present (physics.md §2); an `[impeller]`
    // section is ignored here.
    let mut case = case.clone();
    case.impeller = None;
    let case = &case;
    case.validate_settings().map_err(|kind| anyhow::anyhow!("invalid case: {kind}"))?;
    if !case.has_particles() {
        anyhow::bail!("settle: the case has no particles");
    }
    if case.contacts.is_none() {
        anyhow::bail!(
            "settle: the case needs a [contacts] section (particles would pass through each other)"
        );
    }
    if case.gravity() == [0.0; 3] {
        anyhow::bail!("settle: gravity is zero; nothing would settle");
    }
    std::fs::create_dir_all(out_dir).with_context(|| format!("cannot create {}", out_dir.display()))?;
    match case.fluid.precision {
        Precision::F32 => settle_typed::<f32>(case, out_dir, opts),
        Precision::F64 => settle_typed::<f64>(case, out_dir, opts),
    }
}

fn settle_typed<T: Real + Planes>(
    case: &Case,
    out_dir: &Path,
    opts: SettleOptions,
) -> anyhow::Result<SettleSummary> {
    let start = Instant::now();
    let inits = case.particle_inits().map_err(|kind| anyhow::anyhow!("invalid case: {kind}"))?;
    let mut fluid = Fluid::<T>::new(case.grid(), case.fluid_params(), case.boundaries()).context("fluid")?;
    fluid.initialize(|x, y, z| case.initial_state(x, y, z));
    let bodies = inits.iter().map(|p| p.body()).collect();
    let mut c =
        Coupled::new(fluid, bodies, case.coupling_params()).map_err(|e| anyhow::anyhow!("coupling: {e}"))?;
    let free: Vec<usize> = (0..c.bodies().len()).filter(|&b| c.bodies()[b].is_free()).collect();
    if free.is_empty() {
        anyhow::bail!("settle: no particle is free");
    }
    let mean_speed =
        |c: &Coupled<T>| free.iter().map(|&b| c.bodies()[b].velocity.norm()).sum::<f64>() / free.len() as f64;
    let every = opts.check_every.max(2) + opts.check_every % 2;
    let (mut steps, mut speed, mut settled) = (0u64, f64::INFINITY, false);
    while steps < opts.max_steps {
        rayon::scope(|_| c.run(every))
            .map_err(|e| anyhow::anyhow!("the coupled step failed at step {steps}: {e}"))?;
        steps += every;
        speed = mean_speed(&c);
        if !speed.is_finite() {
            anyhow::bail!("settle: particle velocities became non-finite by step {steps}");
        }
        if !opts.quiet {
            eprintln!(
                "settle: step {steps}, mean particle speed {speed:.3e} (stop below {:.1e}), {:.0} s",
                opts.speed,
                start.elapsed().as_secs_f64()
            );
        }
        if steps >= opts.min_steps && speed < opts.speed {
            settled = true;
            break;
        }
    }
    // The bed: one frame in the particles.h5 layout, and explicit [[particles]] entries.
    let statics = particle_statics(&inits);
    let bed_h5 = out_dir.join("bed.h5");
    let mut w = ParticleHistoryWriter::create(&bed_h5, case.grid(), case.gravity(), &statics)
        .with_context(|| format!("cannot write {}", bed_h5.display()))?;
    let frame = particle_frame(&c, inits.len());
    let bodies = c.bodies();
    w.append(&frame).with_context(|| format!("cannot write {}", bed_h5.display()))?;
    let mut toml = format!(
        "# Settled bed from slurry settle: {} particles after {steps} steps, mean speed {speed:e} ({}).\n",
        bodies.len(),
        if settled { "settled" } else { "NOT settled: max_steps reached" }
    );
    for (p, b) in inits.iter().zip(bodies) {
        let q = b.orientation.quaternion();
        let _ = write!(
            toml,
            "\n[[particles]]\nshape = \"{}\"\ndiameter = {:?}\n{}density = {:?}\nposition = [{:?}, {:?}, {:?}]\n\
             orientation = [{:?}, {:?}, {:?}, {:?}]\nmotion = \"{}\"\n",
            p.shape.name(),
            p.diameter,
            p.length.map_or(String::new(), |l| format!("length = {l:?}\n")),
            p.density,
            b.position.x,
            b.position.y,
            b.position.z,
            q.w,
            q.i,
            q.j,
            q.k,
            p.motion.name()
        );
    }
    let bed_toml = out_dir.join("bed_particles.toml");
    atomic_write_bytes(&bed_toml, toml.as_bytes())
        .with_context(|| format!("cannot write {}", bed_toml.display()))?;
    let mean_height = bodies.iter().map(|b| b.position.z).sum::<f64>() / bodies.len() as f64;
    Ok(SettleSummary {
        steps,
        mean_speed: speed,
        settled,
        mean_height,
        seconds: start.elapsed().as_secs_f64(),
        bed_h5,
        bed_toml,
    })
}
