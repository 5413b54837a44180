//! State packs of a run: a compact state of a fluid and its bodies ([`state_pack_of`]) or of a
//! run directory's checkpoint ([`write_run_state_pack`]), and the solver rebuilt from one
//! ([`pack_fluid_state`], [`restore_coupled_from_pack`]) for `run --from-pack`.

use std::path::Path;

use anyhow::Context;

use super::solver::Solver;
use super::{files, BadResume};
use crate::case::{Case, Precision};
use crate::coupling::{BodyState, Coupled, CoupledState};
use crate::drive;
use crate::io::{read_checkpoint, write_state_pack, StatePack};
use crate::lbm::{Fluid, FluidState, MacroFields, Real};

/// A state pack of `fluid` at its present (even) step, with `bodies`' states (exact), the
/// case fingerprint `case` and the label `label`: density and velocity as
/// [`Fluid::fields`] gives them and the force field of the last step, each rounded to `f32`.
///
/// # Errors
/// An odd step.
pub fn state_pack_of<T: Real>(
    fluid: &Fluid<T>,
    bodies: Option<Vec<BodyState>>,
    case: &str,
    label: &str,
) -> anyhow::Result<StatePack> {
    let state = fluid.snapshot().context("a state pack at an odd step")?;
    let (rho, u) = fluid.fields();
    let n = state.grid.nodes();
    let force = state.force.as_ref().map(|f| {
        (0..n)
            .map(|i| [f[i].to_f64() as f32, f[n + i].to_f64() as f32, f[2 * n + i].to_f64() as f32])
            .collect()
    });
    Ok(StatePack {
        time_step: state.time,
        grid: state.grid,
        rho: rho.iter().map(|&r| r as f32).collect(),
        velocity: u.iter().map(|v| v.map(|c| c as f32)).collect(),
        force,
        bodies,
        case: case.to_string(),
        label: label.to_string(),
    })
}

/// Whether `pack` was written for `case`: the same fingerprint, or the same case once both are
/// normalised (the run's `case.toml`, which is normalised, names the case that the run's
/// checkpoint, and so its pack, was written for).
/// With `relax_contacts` ([`super::RunOptions::switch_contacts`]), the contact scheme's cost
/// settings may differ ([`Case::fingerprint_except_contact_scheme`]).
pub fn pack_is_of_case(pack: &StatePack, case: &Case, relax_contacts: bool) -> bool {
    if pack.case == case.fingerprint() {
        return true;
    }
    let Ok(packed) = toml::from_str::<Case>(&pack.case) else { return false };
    let (packed, case) = (packed.normalised(), case.normalised());
    if relax_contacts {
        packed.fingerprint_except_contact_scheme() == case.fingerprint_except_contact_scheme()
    } else {
        packed.fingerprint() == case.fingerprint()
    }
}

/// The fluid state that `pack` stands for, on `fluid`'s grid and parameters: the regularised
/// reconstruction ([`Fluid::regularised_state`]) of its density, velocity and force field.
///
/// # Errors
/// A pack of another grid.
pub fn pack_fluid_state<T: Real>(fluid: &Fluid<T>, pack: &StatePack) -> anyhow::Result<FluidState<T>> {
    let fields = MacroFields { rho: &pack.rho, velocity: &pack.velocity, force: pack.force.as_deref() };
    fluid.regularised_state(pack.time_step, fields).map_err(|e| anyhow::anyhow!("{e}"))
}

/// Restores `c` from `pack`: the fluid rebuilt ([`pack_fluid_state`]), every body's state
/// exactly ([`Coupled::restore`]).
///
/// # Errors
/// A pack of another grid, without bodies, or with another number of them.
pub fn restore_coupled_from_pack<T: Real>(c: &mut Coupled<T>, pack: &StatePack) -> anyhow::Result<()> {
    let fluid = pack_fluid_state(c.fluid(), pack)?;
    let bodies = pack.bodies.clone().ok_or_else(|| BadResume("the state pack holds no bodies".into()))?;
    c.restore(&CoupledState { fluid, bodies }).map_err(|e| anyhow::anyhow!("{e}"))
}

/// Restores `solver` from `pack`.
pub(super) fn restore_from_pack<T: Real>(solver: &mut Solver<T>, pack: &StatePack) -> anyhow::Result<()> {
    match solver {
        Solver::Fluid(f) | Solver::Device { host: f, .. } => {
            let state = pack_fluid_state(f, pack)?;
            f.restore(&state).map_err(|e| anyhow::anyhow!("{e}"))
        }
        Solver::Coupled(c) => restore_coupled_from_pack(c, pack),
        // A session starts from a pack on the host and moves onto the device after.
        Solver::DeviceCoupled { .. } => {
            anyhow::bail!(
                "a device run's state pack is restored on the host before the run moves onto the device"
            )
        }
    }
}

/// Writes a state pack of the run in `run_dir` at its checkpoint's step to `pack` (labelled
/// `label`): the run's fluid set up from its case (`case.toml`), its checkpoint
/// (`checkpoint.h5`) restored exactly, then [`state_pack_of`], with the checkpoint's case
/// fingerprint (that of the case the run was started with, which `--from-pack` compares).
/// Returns the pack's step.
///
/// # Errors
/// No case or checkpoint in `run_dir`, a checkpoint of another grid, a pack that cannot be
/// written.
pub fn write_run_state_pack(run_dir: &Path, pack: &Path, label: &str) -> anyhow::Result<u64> {
    let case_path = run_dir.join(files::CASE);
    let case = Case::from_file(&case_path)?;
    match case.fluid.precision {
        Precision::F32 => write_pack_typed::<f32>(&case, run_dir, pack, label),
        Precision::F64 => write_pack_typed::<f64>(&case, run_dir, pack, label),
    }
}

fn write_pack_typed<T: Real + hdf5::H5Type>(
    case: &Case,
    run_dir: &Path,
    pack: &Path,
    label: &str,
) -> anyhow::Result<u64> {
    let checkpoint = run_dir.join(files::CHECKPOINT);
    let c = read_checkpoint::<T>(&checkpoint)
        .map_err(|e| BadResume(format!("{}: {e:#}", checkpoint.display())))?;
    // The fluid alone gives the fields: the checkpoint holds the force field.
    let mut fluid = drive::fluid::<T>(case)?;
    fluid.restore(&c.state).with_context(|| {
        format!("{} does not fit the case in {}", checkpoint.display(), run_dir.join(files::CASE).display())
    })?;
    let p = state_pack_of(&fluid, c.bodies, &c.case, label)?;
    write_state_pack(pack, &p).with_context(|| format!("cannot write {}", pack.display()))?;
    Ok(p.time_step)
}
