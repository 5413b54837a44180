//! State packs of a run: a compact state of a fluid and its bodies ([`state_pack_of`]) or of a
//! run directory's checkpoint ([`write_run_state_pack`]), and the solver rebuilt from one
//! ([`pack_fluid_state`], [`restore_coupled_from_pack`]) for `run --from-pack`; the run's
//! history that a pack of a run directory carries ([`crate::io::PackHistory`]: its time series
//! and legs, [`files::LEGS`]), so that a run continued from it goes on as the same run.

use std::path::Path;

use anyhow::Context;

use super::solver::Solver;
use super::{files, BadResume};
use crate::case::{Case, Precision};
use crate::coupling::{BodyState, Coupled, CoupledState};
use crate::drive;
use crate::io::timeseries::{header_for, rows_through, Columns};
use crate::io::{atomic_write_bytes, read_checkpoint, write_state_pack, Leg, PackHistory, StatePack};
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
        history: None,
    })
}

/// What the first leg of a run from step 0 started from.
pub(super) const INITIAL_LEG: &str = "the case's initial state";

/// Writes the run's legs ([`files::LEGS`]) into `out_dir`, atomically.
pub(super) fn write_legs(out_dir: &Path, legs: &[Leg]) -> anyhow::Result<()> {
    let path = out_dir.join(files::LEGS);
    let mut text = serde_json::to_string_pretty(legs).context("cannot serialise the legs")?;
    text.push('\n');
    atomic_write_bytes(&path, text.as_bytes()).with_context(|| format!("cannot write {}", path.display()))
}

/// The legs of the run in `run_dir` ([`files::LEGS`]), or, for a run written before the file
/// existed, one leg from `history_from` (the step its own history starts after: the pack's,
/// or 0), all ending at `last_step` where the last is concerned.
///
/// # Errors
/// A legs file that cannot be read as a list of legs.
pub fn read_legs(run_dir: &Path, history_from: u64, last_step: u64) -> anyhow::Result<Vec<Leg>> {
    let path = run_dir.join(files::LEGS);
    let mut legs: Vec<Leg> = if path.is_file() {
        let text =
            std::fs::read_to_string(&path).with_context(|| format!("cannot read {}", path.display()))?;
        serde_json::from_str(&text).with_context(|| format!("{}: not a list of legs", path.display()))?
    } else {
        let start = if history_from == 0 {
            INITIAL_LEG.to_string()
        } else {
            format!("a state pack at step {history_from}; the run's history before it is not recorded")
        };
        vec![Leg { first_step: history_from, last_step, start }]
    };
    if let Some(last) = legs.last_mut() {
        last.last_step = last_step;
    }
    Ok(legs)
}

/// The header and the rows with `step <= through` of the time series `text`, as written.
fn series_through(text: &str, through: u64) -> String {
    let mut lines = text.split_inclusive('\n');
    let header = lines.next().unwrap_or_default();
    format!("{header}{}", rows_through(lines, through))
}

/// Writes the packed run's time series `text` as the time series at `path` of a run that
/// continues it, after checking that its header is the one this run writes (`columns`).
///
/// # Errors
/// Another header (a pack of a run with other columns), or the file cannot be written.
pub(super) fn seed_timeseries(path: &Path, text: &str, columns: Columns, pack: &Path) -> anyhow::Result<()> {
    let header = text.lines().next().unwrap_or_default();
    if header != header_for(columns) {
        return Err(BadResume(format!(
            "{}: the packed time series has the columns '{header}', this run writes '{}'",
            pack.display(),
            header_for(columns)
        ))
        .into());
    }
    atomic_write_bytes(path, text.as_bytes()).with_context(|| format!("cannot write {}", path.display()))
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
/// fingerprint (that of the case the run was started with, which `--from-pack` compares), and
/// the run's history: its time series up to the checkpoint's step and its legs
/// ([`read_legs`], the last ending at that step).
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
    let mut p = state_pack_of(&fluid, c.bodies, &c.case, label)?;
    // The run's history up to the checkpoint, where its time series is there.
    let series = run_dir.join(files::TIMESERIES);
    if series.is_file() {
        let text =
            std::fs::read_to_string(&series).with_context(|| format!("cannot read {}", series.display()))?;
        let legs = read_legs(run_dir, c.history_from, p.time_step)?;
        p.history = Some(PackHistory { timeseries: series_through(&text, p.time_step), legs });
    }
    write_state_pack(pack, &p).with_context(|| format!("cannot write {}", pack.display()))?;
    Ok(p.time_step)
}
