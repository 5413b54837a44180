//! Running a case from start to output.
//!
//! [`run_case`] initialises the fluid, advances it in blocks of `run.output_every` steps
//! (the last block may be shorter) and, after step 0 and each block, checks its health,
//! appends a row to `timeseries.csv` and updates the progress bar. Nothing else happens
//! between output points: the stepping loop does no I/O. At the end it writes `fields.h5`
//! with `fields.xmf` beside it, the normalised case as `case.toml`, and `summary.json`; at
//! each step of `run.snapshots` the fields of that step as `fields-STEP.h5`/`.xmf`.
//!
//! With `run.checkpoint_every`, the complete fluid state is written to `checkpoint.h5`
//! (atomically, after a health check) every that many steps; `--resume` restores it after a
//! kill at any moment and continues bitwise identically.
//!
//! **Stopping.** SIGINT (Ctrl-C) or SIGTERM ([`crate::interrupt`]) stops the stepping at the
//! next even step: after a health check the state is written to `checkpoint.h5` (with or
//! without `run.checkpoint_every`) and the run ends with [`crate::interrupt::Interrupted`],
//! naming the step; `--resume` continues it bitwise identically. A second signal ends the
//! process at once.
//!
//! **Particles.** When the case has particles, the fluid and the bodies of
//! [`Case::bodies`] are stepped together by [`Coupled`](crate::coupling::Coupled) (options from
//! [`Case::coupling_params`]); at every output step the time series gains the particle
//! aggregates and `particles.h5` a frame ([`ParticleHistoryWriter`]). Checkpoints then hold
//! the particles' states too ([`Coupled::snapshot`](crate::coupling::Coupled::snapshot)), and a resume continues bitwise
//! identically (`particles.h5` is cut back to the checkpoint's step like the time series).
//!
//! **Impeller.** With `[impeller]` ([`Case::impeller_setup`]) the impeller is one more body of
//! the coupling, after the particles, with its prescribed rotation; the time series gains its
//! angle, speed, torques and power numbers ([`ImpellerTorques`]). Without particles the run
//! is single-phase with the impeller alone.
//!
//! **Device.** With `run.device = "gpu"` (f32 cases) the fluid steps on the device
//! ([`crate::device::DeviceFluid`]), set up and restored on the host first; the host's fluid is
//! its mirror, downloaded at output, checkpoint and snapshot steps and read there by the
//! same code as a CPU run's, so checkpoints and output are a CPU run's. With particles or an
//! impeller the coupled step runs there too ([`crate::device::DeviceCoupled`]: fluid, markers
//! and interior sums on the device, bodies and contacts on the host), set up, resumed or
//! started from a state pack as a CPU coupled solver and then moved onto the device through
//! [`crate::device::DeviceCoupled::restore`]; its checkpoints are its
//! [`crate::device::DeviceCoupled::snapshot`], a CPU run's checkpoint.
//!
//! **State packs.** [`state_pack_of`] takes a compact state of a fluid (and its bodies) at an
//! even step ([`crate::io::state_pack`]), [`write_run_state_pack`] one of a run directory's
//! checkpoint (`slurry state-pack`); [`run_case_from_pack`] starts a run from one, its
//! populations rebuilt by the regularised reconstruction ([`pack_fluid_state`]) and its
//! bodies restored exactly: a continuation close to the run's own, not bitwise.
//!
//! Numerical trouble (non-finite populations, non-positive density, Mach number above
//! `run.mach_limit`) stops the run with a [`NumericalError`] carrying the solver's diagnosis;
//! the time series up to the last healthy output is kept.

use std::io::IsTerminal;
use std::path::{Path, PathBuf};
use std::time::{Duration, Instant};

use anyhow::Context;
use indicatif::{ProgressBar, ProgressDrawTarget, ProgressStyle};
use serde::Serialize;

use crate::case::{Case, Device, ImpellerSetup, Precision};
use crate::coupling::{BodyLoads, CoupledState};
use crate::drive::{self, particle_statics};
use crate::interrupt;
use crate::io::checkpoint::PrecisionMismatch;
use crate::io::timeseries::{Columns, ImpellerTorques};
use crate::io::{
    atomic_write_bytes, read_checkpoint, read_state_pack, write_checkpoint_from, write_fields_h5, write_xdmf,
    Leg, ParticleAggregates, ParticleHistoryWriter, TimeSeriesRow, TimeSeriesWriter,
};
use crate::lattice::Grid;
use crate::lbm::{Fluid, Health, Real};

mod pack;
mod solver;

pub use pack::{
    pack_fluid_state, pack_is_of_case, read_legs, restore_coupled_from_pack, state_pack_of,
    write_run_state_pack,
};
use pack::{restore_from_pack, seed_timeseries, write_legs, INITIAL_LEG};
use solver::Solver;

/// File names written into the output directory.
pub mod files {
    /// The scalar time series.
    pub const TIMESERIES: &str = "timeseries.csv";
    /// Final density and velocity (HDF5).
    pub const FIELDS_H5: &str = "fields.h5";
    /// XDMF description of [`FIELDS_H5`] for ParaView.
    pub const FIELDS_XMF: &str = "fields.xmf";
    /// Run summary (JSON).
    pub const SUMMARY: &str = "summary.json";
    /// The case as run (normalised TOML).
    pub const CASE: &str = "case.toml";
    /// The latest checkpoint (see [`crate::io::checkpoint`]).
    pub const CHECKPOINT: &str = "checkpoint.h5";
    /// The legs the run was stepped in (JSON, [`crate::io::Leg`]): written at a fresh start,
    /// the last leg's `last_step` set when a state pack is written.
    pub const LEGS: &str = "legs.json";
    /// Particle histories (see [`crate::io::particles`]); only for cases with particles.
    pub const PARTICLES_H5: &str = "particles.h5";

    /// The fields of `[run] snapshots` step `step`: `fields-STEP.h5` (9 digits).
    pub fn snapshot_h5(step: u64) -> String {
        format!("fields-{step:09}.h5")
    }

    /// The XDMF description of [`snapshot_h5`]`(step)`.
    pub fn snapshot_xmf(step: u64) -> String {
        format!("fields-{step:09}.xmf")
    }
}

/// Options that do not change the physics.
#[derive(Clone, Copy, Debug, Default)]
pub struct RunOptions {
    /// No progress bar (it is also hidden when stderr is not a terminal).
    pub quiet: bool,
    /// Continue from `checkpoint.h5` in the output directory (bitwise identical to a run that
    /// was never interrupted); the time series is cut back to the checkpoint's step.
    pub resume: bool,
    /// With `resume`: accept a checkpoint written under other contact sub-steps or another
    /// lubrication limiter setting (everything else must match,
    /// [`Case::fingerprint_except_contact_scheme`]): a run continued under a cheaper (or the
    /// default) contact scheme, to measure one against the other from the same state.
    pub switch_contacts: bool,
    /// Start afresh even though the output directory holds an earlier run's checkpoint,
    /// replacing that run's checkpoint, time series and particle history. Without it (and
    /// without `resume`) such a directory is refused ([`check_fresh_start`]).
    pub overwrite: bool,
}

/// A fresh start refused: the output directory holds the checkpoint of an earlier run, which
/// the start would replace with everything it wrote (its time series, particle history and
/// checkpoint); see [`check_fresh_start`].
#[derive(Clone, Debug, thiserror::Error)]
#[error("{0}")]
pub struct WouldOverwrite(pub String);

/// Refuses to start a run afresh in `dir` when it holds an earlier run: its checkpoint
/// (`checkpoint.h5`), or, for a run that wrote none (no `run.checkpoint_every`, or killed
/// before its first), a time series with rows or a particle history. Such a start would
/// replace that run's files, hours of stepping, with one mistyped command. `resume` and
/// `overwrite` name the caller's options that continue the run or accept its loss.
///
/// # Errors
/// [`WouldOverwrite`], naming what the directory holds (the checkpoint, the time series' last
/// step where that can be read) and the options: `resume` only where there is a checkpoint to
/// continue from.
pub fn check_fresh_start(dir: &Path, resume: &str, overwrite: &str) -> Result<(), WouldOverwrite> {
    let checkpoint = dir.join(files::CHECKPOINT);
    let last = last_step(&dir.join(files::TIMESERIES));
    if checkpoint.exists() {
        let last = last.map(|s| format!(", time series to step {s}")).unwrap_or_default();
        return Err(WouldOverwrite(format!(
            "{} holds an earlier run ({}{last}): pass {resume} to continue it, or {overwrite} to \
             start over and replace its checkpoint, time series and particle history",
            dir.display(),
            checkpoint.display()
        )));
    }
    let particles = dir.join(files::PARTICLES_H5);
    let held = match (last, particles.exists()) {
        (Some(s), _) => format!("{} to step {s}", dir.join(files::TIMESERIES).display()),
        (None, true) => particles.display().to_string(),
        (None, false) => return Ok(()),
    };
    Err(WouldOverwrite(format!(
        "{} holds an earlier run ({held}) that wrote no checkpoint, so it cannot be continued: \
         pass {overwrite} to start over and replace its time series and particle history, or \
         choose another output directory",
        dir.display()
    )))
}

/// The step of the last complete row of a time series, if it can be read.
fn last_step(path: &Path) -> Option<u64> {
    let text = std::fs::read_to_string(path).ok()?;
    text.split_inclusive('\n')
        .filter(|l| l.ends_with('\n'))
        .rev()
        .find_map(|l| l.split(',').next()?.parse::<u64>().ok())
}

/// What a finished run reports (also written as `summary.json`).
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct RunSummary {
    /// Steps run.
    pub steps: u64,
    /// Grid.
    pub grid: Grid,
    /// Storage precision (`"f32"` or `"f64"`).
    pub precision: &'static str,
    /// The kernel's instruction set, or `device: ADAPTER` for a run on the device.
    pub isa: String,
    /// Rayon threads used.
    pub threads: usize,
    /// Wall-clock time of the whole run, including output (s).
    pub wall_time_s: f64,
    /// Time spent stepping only (s).
    pub step_time_s: f64,
    /// Million lattice-node updates per second over the stepping time.
    pub mlups: f64,
    /// Mass at step 0.
    pub initial_mass: f64,
    /// Mass at the last step.
    pub final_mass: f64,
    /// `(final − initial) / initial`.
    pub relative_mass_change: f64,
    /// Final total momentum.
    pub final_momentum: [f64; 3],
    /// Largest Mach number seen at any output step.
    pub max_mach: f64,
    /// Number of time-series rows written.
    pub output_rows: u64,
    /// Number of particles (0 for a fluid-only case).
    pub particles: usize,
    /// Number of surface markers over all particles (and the impeller).
    pub markers: usize,
    /// Number of the impeller's surface markers (0 without one).
    pub impeller_markers: usize,
    /// The checkpoint's step when this session resumed a run (the stepping time and MLUPS
    /// are then this session's).
    pub resumed_from: Option<u64>,
}

impl RunSummary {
    /// The summary of this session continued by `later` (a resume of the same run in the same
    /// process, from a checkpoint at or before this session's last step): the steps, the final
    /// state and the counts of `later`; the start, the initial mass and `resumed_from` of this
    /// one; times and rows summed; MLUPS over the steps the two stepped.
    pub fn then(&self, later: &RunSummary) -> RunSummary {
        let stepped = |s: &RunSummary| s.steps.saturating_sub(s.resumed_from.unwrap_or(0)) as f64;
        let step_time_s = self.step_time_s + later.step_time_s;
        let nodes = later.grid.nodes() as f64;
        RunSummary {
            wall_time_s: self.wall_time_s + later.wall_time_s,
            step_time_s,
            mlups: if step_time_s > 0.0 {
                nodes * (stepped(self) + stepped(later)) / step_time_s / 1e6
            } else {
                0.0
            },
            initial_mass: self.initial_mass,
            relative_mass_change: (later.final_mass - self.initial_mass) / self.initial_mass,
            max_mach: self.max_mach.max(later.max_mach),
            output_rows: self.output_rows + later.output_rows,
            resumed_from: self.resumed_from,
            ..later.clone()
        }
    }
}

/// The run stopped for numerical trouble. Its Display is the diagnosis.
#[derive(Clone, Debug, thiserror::Error)]
#[error("numerical trouble at step {step}: {health}; the time series up to step {last_good} is in {}", timeseries.display())]
pub struct NumericalError {
    /// Step at which the check failed.
    pub step: u64,
    /// Last step that passed the check.
    pub last_good: u64,
    /// The solver's health report.
    pub health: Health,
    /// The time-series file.
    pub timeseries: PathBuf,
}

/// A resume that cannot proceed: the checkpoint belongs to another case, or lacks the
/// particle states the case needs.
#[derive(Clone, Debug, thiserror::Error)]
#[error("{0}")]
pub struct BadResume(pub String);

/// The largest `max_mach` of the rows of a time series (0 when there is none or the file
/// cannot be read): a resumed run's summary then covers the rows written before it.
fn kept_max_mach(path: &Path) -> f64 {
    let Ok(text) = std::fs::read_to_string(path) else { return 0.0 };
    let mut lines = text.lines();
    let Some(col) = lines.next().and_then(|h| h.split(',').position(|c| c == "max_mach")) else {
        return 0.0;
    };
    lines.filter_map(|l| l.split(',').nth(col)?.parse::<f64>().ok()).fold(0.0, f64::max)
}

/// The progress message of an output step: revolutions, `⟨z_p⟩/H` and `Po` when the run
/// has an impeller and particles (the floor is at `z = −½`, `h = n_z`).
fn progress_status(t: Option<&ImpellerTorques>, p: Option<&ParticleAggregates>, h: f64) -> String {
    let mut s = String::new();
    if let Some(t) = t {
        s.push_str(&format!("rev {:.2}, ", t.angle / std::f64::consts::TAU));
    }
    if let Some(p) = p {
        s.push_str(&format!("<z_p>/H {:.3}, ", (p.mean_z + 0.5) / h));
    }
    if let Some(t) = t {
        s.push_str(&format!("Po {:.2} (fluid {:.2}), ", t.po, t.po_fluid));
    }
    s
}

/// The impeller's torques and power numbers from the last step: its `loads`, its body's time
/// `t`, the walls' torque from `fluid` (the CPU's coupling or the device's host mirror).
fn impeller_torques<T: Real>(
    loads: &BodyLoads,
    t: f64,
    fluid: &Fluid<T>,
    setup: &ImpellerSetup,
) -> ImpellerTorques {
    let centre = setup.centre;
    let (_, wall_torque) = fluid.wall_momentum_exchange([centre.x, centre.y, centre.z]);
    let fluid = -loads.ibm_torque.z;
    let solids = -loads.contact_torque.z;
    let (po_fluid, po_solids) = (setup.power_number(fluid), setup.power_number(solids));
    ImpellerTorques {
        angle: setup.motion.angle(t),
        omega: setup.motion.angular_speed(t),
        fluid,
        solids,
        walls: wall_torque[2],
        po_fluid,
        po_solids,
        po: po_fluid + po_solids,
    }
}

/// Runs `case`, writing its output into `out_dir` (created if needed). A directory that holds
/// an earlier run is refused unless `opts.resume` (continue it) or `opts.overwrite` (replace
/// its files): [`check_fresh_start`]. Uses the current rayon thread pool.
pub fn run_case(case: &Case, out_dir: &Path, opts: RunOptions) -> anyhow::Result<RunSummary> {
    run_case_with(case, out_dir, opts, None)
}

/// Runs `case` as [`run_case`] does, but starting from the state pack at `pack` (written for
/// this case and grid, [`crate::io::StatePack::check_for`]) instead of the case's initial state: the
/// fluid rebuilt by [`pack_fluid_state`], the bodies restored exactly, the time series and
/// particle history starting at the first output step after the pack's (the pack holds no
/// loads of the step before its own, so the row of its step would read zero torques). Not
/// with `opts.resume` (a run started from a pack is continued from its own checkpoints).
///
/// # Errors
/// As [`run_case`]; a pack that cannot be read or is of another case or grid ([`BadResume`]).
pub fn run_case_from_pack(
    case: &Case,
    out_dir: &Path,
    opts: RunOptions,
    pack: &Path,
) -> anyhow::Result<RunSummary> {
    if opts.resume {
        return Err(BadResume(
            "a start from a state pack begins a run; --resume continues one from its own checkpoint".into(),
        )
        .into());
    }
    run_case_with(case, out_dir, opts, Some(pack))
}

/// [`run_case`], from the state pack `pack` when given.
fn run_case_with(
    case: &Case,
    out_dir: &Path,
    opts: RunOptions,
    pack: Option<&Path>,
) -> anyhow::Result<RunSummary> {
    case.validate_settings().map_err(|kind| anyhow::anyhow!("invalid case: {kind}"))?;
    case.check_memory().map_err(|kind| anyhow::anyhow!("invalid case: {kind}"))?;
    // One writer at a time (held until the process ends), on a path every file can be written
    // under: checked before the first step.
    crate::io::lock::claim_output_dir(out_dir, "--out")?;
    if !opts.resume && !opts.overwrite {
        check_fresh_start(out_dir, "--resume", "--overwrite")?;
    }
    // Temporary files of a write that a kill interrupted (`.checkpoint.h5.tmp.PID`, …).
    crate::io::remove_stale_temps(out_dir);
    match case.fluid.precision {
        Precision::F32 => run_typed::<f32>(case, out_dir, opts, pack),
        Precision::F64 => run_typed::<f64>(case, out_dir, opts, pack),
    }
}

fn progress_bar(steps: u64, quiet: bool) -> ProgressBar {
    if quiet || !std::io::stderr().is_terminal() {
        return ProgressBar::hidden();
    }
    let pb = ProgressBar::with_draw_target(Some(steps), ProgressDrawTarget::stderr());
    pb.set_style(
        ProgressStyle::with_template(
            "{bar:40.cyan/blue} {pos}/{len} steps  {msg}  elapsed {elapsed}  left {eta}",
        )
        .expect("valid template")
        .progress_chars("=> "),
    );
    pb
}

/// Runs a case whose storage precision is `T`: set-up (or resume), the stepping loop, the final
/// output.
fn run_typed<T: Real + hdf5::H5Type>(
    case: &Case,
    out_dir: &Path,
    opts: RunOptions,
    pack: Option<&Path>,
) -> anyhow::Result<RunSummary> {
    let start = Instant::now();
    let mut session = Session::<T>::start(case, out_dir, opts, pack)?;
    let armed = interrupt::arm();
    let stepped = session.step_to_end(opts.quiet, start)?;
    drop(armed);
    session.finish(&stepped, start)
}

/// A run in progress: the solver, the open output files and what the summary reports.
struct Session<'a, T: Real> {
    case: &'a Case,
    out_dir: &'a Path,
    solver: Solver<T>,
    /// The impeller, the body after the particles.
    impeller: Option<ImpellerSetup>,
    particles: usize,
    markers: usize,
    impeller_markers: usize,
    fingerprint: String,
    timeseries: TimeSeriesWriter,
    timeseries_path: PathBuf,
    /// `particles.h5`, with particles.
    history: Option<ParticleHistoryWriter>,
    history_path: PathBuf,
    checkpoint_path: PathBuf,
    /// The largest Mach number of the time-series rows a resume kept.
    max_mach_before: f64,
    /// The checkpoint's step when this session resumed.
    resumed_at: Option<u64>,
    /// The state pack's step when this session started from one: its row and particle frame
    /// are not written (the pack holds no loads of the step before, so its torques and forces
    /// would read zero).
    pack_step: Option<u64>,
    /// The step the run's history starts after (its checkpoints record it): the state pack's
    /// step for a run started from one, else 0.
    history_from: u64,
}

/// What the stepping loop measured, for the summary.
struct Stepped {
    first_step: u64,
    step_time: Duration,
    max_mach: f64,
    rows: u64,
    initial_mass: f64,
}

impl<'a, T: Real + hdf5::H5Type> Session<'a, T> {
    /// The solver at step 0 or restored from the checkpoint, `case.toml` written, the time
    /// series and the particle history created or cut back to the checkpoint's step.
    fn start(
        case: &'a Case,
        out_dir: &'a Path,
        opts: RunOptions,
        pack: Option<&Path>,
    ) -> anyhow::Result<Self> {
        let inits = case.particle_inits().map_err(|kind| anyhow::anyhow!("invalid case: {kind}"))?;
        let impeller = case.impeller_setup().map_err(|kind| anyhow::anyhow!("invalid case: {kind}"))?;
        let particles = inits.len();
        let mut solver = if inits.is_empty() && impeller.is_none() {
            Solver::Fluid(Box::new(drive::fluid(case)?))
        } else {
            Solver::Coupled(Box::new(drive::coupled(case, &inits, impeller.as_ref())?))
        };
        let mut packed_history = None;
        if let Some(pack) = pack {
            let mut p = read_state_pack(pack).map_err(|e| BadResume(e.to_string()))?;
            packed_history = Some((p.history.take(), p.label.clone()));
            let run = format!("the run in {}", out_dir.display());
            // The pack's own fingerprint where the case is the same up to normalisation (the
            // run's `case.toml` continues the run it was written by), or, with
            // `switch_contacts`, up to the contact scheme's cost settings.
            let same = pack_is_of_case(&p, case, opts.switch_contacts);
            let fingerprint = if same { p.case.clone() } else { case.fingerprint() };
            p.check_for(pack, case.grid(), &fingerprint, &run).map_err(|e| BadResume(e.to_string()))?;
            restore_from_pack(&mut solver, &p)
                .with_context(|| format!("cannot start from {}", pack.display()))?;
        }
        let (markers, impeller_markers) = match &solver {
            Solver::Coupled(c) => {
                let impeller_count = if impeller.is_some() { c.body_marker_count(particles) } else { 0 };
                (c.marker_count(), impeller_count)
            }
            Solver::Fluid(_) | Solver::Device { .. } | Solver::DeviceCoupled { .. } => (0, 0),
        };

        let timeseries_path = out_dir.join(files::TIMESERIES);
        let checkpoint_path = out_dir.join(files::CHECKPOINT);
        let history_path = out_dir.join(files::PARTICLES_H5);
        let fingerprint = case.fingerprint();
        let mut history_from = if pack.is_some() { solver.fluid().time() } else { 0 };
        let columns = Columns { particles: particles > 0, impeller: impeller.is_some() };
        let (timeseries, max_mach_before) = if opts.resume {
            let relaxed = opts.switch_contacts.then_some(case);
            history_from = restore(&mut solver, &checkpoint_path, &fingerprint, relaxed, out_dir)?;
            // Before any file is changed: the history must reach the checkpoint.
            let particles_path = (!inits.is_empty()).then_some(history_path.as_path());
            let step = solver.fluid().time();
            check_history(&timeseries_path, particles_path, step, history_from, case, opts.quiet)?;
            let timeseries =
                TimeSeriesWriter::resume(&timeseries_path, solver.fluid().time()).map_err(|e| {
                    BadResume(format!(
                        "cannot resume {}: {e} (the checkpoint is there, the time series is not)",
                        timeseries_path.display()
                    ))
                })?;
            // The largest Mach number of the rows kept (the summary's covers the whole run).
            (timeseries, kept_max_mach(&timeseries_path))
        } else if let (Some(pack), Some((history, label))) = (pack, packed_history) {
            // The packed run goes on: its time series so far, then this leg's rows; its legs,
            // then this one.
            let step = solver.fluid().time();
            let mut legs = Vec::new();
            if let Some(h) = &history {
                seed_timeseries(&timeseries_path, &h.timeseries, columns, pack)?;
                legs.clone_from(&h.legs);
            }
            legs.push(Leg {
                first_step: step,
                last_step: step,
                start: format!(
                    "the state pack {} ('{label}') at step {step}{}",
                    pack.display(),
                    if history.is_some() { "" } else { "; the run's history before it is not in the pack" }
                ),
            });
            write_legs(out_dir, &legs)?;
            let timeseries = if history.is_some() {
                TimeSeriesWriter::resume(&timeseries_path, step)
            } else {
                TimeSeriesWriter::create_columns(&timeseries_path, columns)
            }
            .with_context(|| format!("cannot write {}", timeseries_path.display()))?;
            (timeseries, kept_max_mach(&timeseries_path))
        } else {
            let legs = [Leg { first_step: 0, last_step: 0, start: INITIAL_LEG.to_string() }];
            write_legs(out_dir, &legs)?;
            let timeseries = TimeSeriesWriter::create_columns(&timeseries_path, columns)
                .with_context(|| format!("cannot write {}", timeseries_path.display()))?;
            (timeseries, 0.0)
        };
        let history = if inits.is_empty() {
            None
        } else if opts.resume {
            Some(ParticleHistoryWriter::resume(&history_path, solver.fluid().time()).map_err(|e| {
                BadResume(format!(
                    "cannot resume {}: {e} (the checkpoint is there, the particle history is not)",
                    history_path.display()
                ))
            })?)
        } else {
            let statics = particle_statics(&inits);
            Some(
                ParticleHistoryWriter::create(&history_path, case.grid(), case.gravity(), &statics)
                    .with_context(|| format!("cannot write {}", history_path.display()))?,
            )
        };
        let case_text = toml::to_string(&case.normalised()).context("cannot serialise the case")?;
        let case_path = out_dir.join(files::CASE);
        atomic_write_bytes(&case_path, case_text.as_bytes())
            .with_context(|| format!("cannot write {}", case_path.display()))?;
        let resumed_at = opts.resume.then(|| solver.fluid().time());
        let pack_step = pack.map(|_| solver.fluid().time());
        // Restored (or started) on the host, then moved onto the device as it stands.
        if case.run.device == Device::Gpu {
            solver = solver.onto_device(case, &inits, impeller.as_ref())?;
        }
        Ok(Self {
            case,
            out_dir,
            solver,
            impeller,
            particles,
            markers,
            impeller_markers,
            fingerprint,
            timeseries,
            timeseries_path,
            history,
            history_path,
            checkpoint_path,
            max_mach_before,
            resumed_at,
            pack_step,
            history_from,
        })
    }

    /// Steps in blocks to the end of the run; at each output step a health check, a time-series
    /// row and a particle frame, at each checkpoint step a checkpoint (not again at the step a
    /// resume starts from). Progress on the bar, or a line every 30 s when stderr is not a
    /// terminal.
    fn step_to_end(&mut self, quiet: bool, start: Instant) -> anyhow::Result<Stepped> {
        let nodes = self.case.grid().nodes() as f64;
        let mach_limit = self.case.run.mach_limit;
        let total = self.case.run.steps;
        let output_every = self.case.run.output_every;
        let checkpoint_every = self.case.run.checkpoint_every;
        let progress = progress_bar(total, quiet);
        progress.set_position(self.solver.time());
        let first_step = self.solver.time();
        let mut stepped = Stepped {
            first_step,
            step_time: Duration::ZERO,
            max_mach: self.max_mach_before,
            rows: 0,
            initial_mass: f64::NAN,
        };
        let mut last_good = first_step;
        let mut block_mlups = 0.0;
        let log_lines = !quiet && !std::io::stderr().is_terminal();
        let mut last_log = Instant::now();
        let mut status = String::new();

        loop {
            let step = self.solver.time();
            let output_due = step.is_multiple_of(output_every) || step == total;
            // A stop request is answered at an even step (the state is complete only then; from
            // an odd one the block below stops after one step) with this step's checkpoint,
            // through the same health check and write as the periodic ones.
            let stop = interrupt::requested().filter(|_| step.is_multiple_of(2) && step < total);
            let checkpoint_due =
                (checkpoint_every.is_some_and(|c| step.is_multiple_of(c)) && step > 0) || stop.is_some();
            let snapshot_due = self.case.run.snapshots.contains(&step);
            if output_due || checkpoint_due || snapshot_due {
                self.solver.sync()?;
                let fluid = self.solver.fluid();
                let health = fluid.health(mach_limit);
                if !health.is_ok() {
                    progress.abandon();
                    let timeseries = self.timeseries_path.clone();
                    return Err(NumericalError { step, last_good, health, timeseries }.into());
                }
                last_good = step;
                if output_due {
                    stepped.max_mach = stepped.max_mach.max(health.max_mach);
                }
                // Step 0, the step a resume continues from, or a state pack's step.
                if step == first_step && stepped.initial_mass.is_nan() {
                    stepped.initial_mass = fluid.total_mass();
                }
                // The row of the step a resume starts from is already in the time series; that
                // of a state pack's step would lack the loads of the step before.
                if output_due && self.resumed_at != Some(step) && self.pack_step != Some(step) {
                    status = self.write_output_row(step, health.max_mach, block_mlups)?;
                    stepped.rows += 1;
                }
                // Before the checkpoint of the same step, so that a resume from it finds it.
                if snapshot_due && self.resumed_at != Some(step) {
                    self.write_fields(&files::snapshot_h5(step), &files::snapshot_xmf(step))?;
                }
                if checkpoint_due && self.resumed_at != Some(step) {
                    self.write_checkpoint()?;
                }
            }
            if step >= total {
                break;
            }
            if let Some(signal) = stop {
                progress.abandon();
                self.timeseries
                    .sync()
                    .with_context(|| format!("cannot sync {}", self.timeseries_path.display()))?;
                return Err(interrupt::Interrupted {
                    signal,
                    step,
                    saved: format!(
                        "the state is in {} (the time series to the last output step before it); \
                         `--resume` continues the run from there",
                        self.checkpoint_path.display()
                    ),
                }
                .into());
            }
            // Advance to the next output or checkpoint point.
            let mut next = (step / output_every + 1) * output_every;
            if let Some(c) = checkpoint_every {
                next = next.min((step / c + 1) * c);
            }
            if let Some(&s) = self.case.run.snapshots.iter().filter(|&&s| s > step).min() {
                next = next.min(s);
            }
            let block = next.min(total) - step;
            let block_start = Instant::now();
            // On a worker of the pool: the parallel loops of the step then queue their jobs on
            // the worker's own deque instead of rayon's global injector, which allocates (the
            // warm coupled step allocates nothing: tests/no_alloc_in_step.rs). A step at a
            // time, so that a stop request ends the block at the next even step.
            let solver = &mut self.solver;
            let stepped_block = rayon::scope(|_| solver.advance(block));
            let block = match stepped_block {
                Ok(n) => n,
                Err(e) => {
                    progress.abandon();
                    return Err(anyhow::anyhow!(
                        "the {} step failed between steps {step} and {}: {e:#}; the output up to step {last_good} is kept",
                        if self.solver.is_coupled() { "coupled" } else { "fluid" },
                        next.min(total)
                    ));
                }
            };
            let block_time = block_start.elapsed();
            stepped.step_time += block_time;
            block_mlups = nodes * block as f64 / block_time.as_secs_f64().max(1e-9) / 1e6;
            progress.set_message(format!("{status}{block_mlups:.1} MLUPS"));
            let now_step = self.solver.time();
            progress.set_position(now_step);
            if log_lines && (last_log.elapsed().as_secs_f64() >= 30.0 || now_step >= total) {
                last_log = Instant::now();
                let done = (now_step - first_step) as f64;
                let left = stepped.step_time.as_secs_f64() / done.max(1.0) * (total - now_step) as f64;
                eprintln!(
                    "step {now_step}/{total} ({:.0} %), {status}{block_mlups:.1} MLUPS, {:.0} s elapsed, about {:.0} s left",
                    100.0 * now_step as f64 / total.max(1) as f64,
                    start.elapsed().as_secs_f64(),
                    left
                );
            }
        }
        progress.finish_and_clear();
        Ok(stepped)
    }

    /// The time-series row of output step `step` and the particles' frame; returns the
    /// progress message of the step.
    fn write_output_row(&mut self, step: u64, max_mach: f64, block_mlups: f64) -> anyhow::Result<String> {
        let box_height = self.case.grid().nz as f64;
        let frame = self.solver.particle_frame(self.particles);
        let torques = match (&self.solver, &self.impeller) {
            (Solver::Coupled(c), Some(s)) => {
                let i = self.particles;
                Some(impeller_torques(c.loads(i), c.bodies()[i].time, c.fluid(), s))
            }
            // The loads and bodies are on the host; the fluid is the mirror synced at this step.
            (Solver::DeviceCoupled { device, .. }, Some(s)) => {
                let i = self.particles;
                Some(impeller_torques(device.loads(i), device.bodies()[i].time, self.solver.fluid(), s))
            }
            _ => None,
        };
        let particles = frame.as_ref().map(|f| ParticleAggregates::of(&f.position, &f.velocity));
        let status = progress_status(torques.as_ref(), particles.as_ref(), box_height);
        let fluid = self.solver.fluid();
        self.timeseries
            .append(&TimeSeriesRow {
                step,
                time: step as f64,
                mass: fluid.total_mass(),
                momentum: fluid.total_momentum(),
                max_mach,
                mlups: block_mlups,
                particles,
                impeller: torques,
            })
            .with_context(|| format!("cannot write {}", self.timeseries_path.display()))?;
        if let (Some(writer), Some(frame)) = (self.history.as_mut(), frame) {
            writer.append(&frame).with_context(|| format!("cannot write {}", self.history_path.display()))?;
        }
        Ok(status)
    }

    /// The density and velocity of the present step as `h5_name` (HDF5) with its XDMF
    /// description `xmf_name`, in the output directory, each written atomically.
    fn write_fields(&self, h5_name: &str, xmf_name: &str) -> anyhow::Result<()> {
        let fluid = self.solver.fluid();
        let grid = self.case.grid();
        let (rho, u) = fluid.fields();
        let h5 = self.out_dir.join(h5_name);
        write_fields_h5(&h5, grid, fluid.time(), &rho, &u)
            .with_context(|| format!("cannot write {}", h5.display()))?;
        let xmf = self.out_dir.join(xmf_name);
        write_xdmf(&xmf, grid, fluid.time(), h5_name)
            .with_context(|| format!("cannot write {}", xmf.display()))
    }

    /// The checkpoint of the present (even) step, with the bodies' states when coupled.
    fn write_checkpoint(&mut self) -> anyhow::Result<()> {
        match &mut self.solver {
            Solver::Fluid(f) => {
                let state = f.snapshot().context("checkpoint at an odd step")?;
                write_checkpoint_from(
                    &self.checkpoint_path,
                    &state,
                    None,
                    &self.fingerprint,
                    self.history_from,
                )
            }
            Solver::Coupled(c) => {
                let state = c.snapshot().context("checkpoint at an odd step")?;
                write_checkpoint_from(
                    &self.checkpoint_path,
                    &state.fluid,
                    Some(&state.bodies),
                    &self.fingerprint,
                    self.history_from,
                )
            }
            // The device's state in the CPU's layout: the same checkpoint as a CPU run's.
            Solver::DeviceCoupled { device, .. } => {
                let state = device.snapshot().context("checkpoint at an odd step")?;
                write_checkpoint_from(
                    &self.checkpoint_path,
                    &state.fluid,
                    Some(&state.bodies),
                    &self.fingerprint,
                    self.history_from,
                )
            }
            // The host mirror, synced at this step: the same checkpoint as a CPU run's.
            Solver::Device { host, .. } => {
                let state = host.snapshot().context("checkpoint at an odd step")?;
                write_checkpoint_from(
                    &self.checkpoint_path,
                    &state,
                    None,
                    &self.fingerprint,
                    self.history_from,
                )
            }
        }
        .with_context(|| format!("cannot write {}", self.checkpoint_path.display()))
    }

    /// The time series synced, `fields.h5` and `fields.xmf` of the last step, and the summary
    /// (also written as `summary.json`).
    fn finish(mut self, stepped: &Stepped, start: Instant) -> anyhow::Result<RunSummary> {
        self.timeseries.sync().with_context(|| format!("cannot sync {}", self.timeseries_path.display()))?;
        if let Some(history) = self.history.as_mut() {
            history.finish().with_context(|| format!("cannot merge {}", self.history_path.display()))?;
        }
        self.solver.sync()?;
        self.write_fields(files::FIELDS_H5, files::FIELDS_XMF)?;
        let fluid = self.solver.fluid();
        let grid = self.case.grid();
        let final_mass = fluid.total_mass();
        let step_seconds = stepped.step_time.as_secs_f64();
        let initial_mass = stepped.initial_mass;
        let summary = RunSummary {
            steps: fluid.time(),
            grid,
            precision: T::NAME,
            isa: match &self.solver {
                Solver::Device { device, .. } => format!("device: {}", device.adapter()),
                Solver::DeviceCoupled { device, .. } => {
                    format!("device: {}", device.device_fluid().adapter())
                }
                _ => fluid.isa().name().to_string(),
            },
            threads: rayon::current_num_threads(),
            wall_time_s: start.elapsed().as_secs_f64(),
            step_time_s: step_seconds,
            // Over the steps of this session (a resumed run counts from its checkpoint).
            mlups: if step_seconds > 0.0 {
                grid.nodes() as f64 * (fluid.time() - stepped.first_step) as f64 / step_seconds / 1e6
            } else {
                0.0
            },
            initial_mass,
            final_mass,
            relative_mass_change: (final_mass - initial_mass) / initial_mass,
            final_momentum: fluid.total_momentum(),
            max_mach: stepped.max_mach,
            output_rows: stepped.rows,
            particles: self.particles,
            markers: self.markers,
            impeller_markers: self.impeller_markers,
            resumed_from: self.resumed_at,
        };
        let json = serde_json::to_string_pretty(&summary).context("cannot serialise the summary")?;
        let summary_path = self.out_dir.join(files::SUMMARY);
        atomic_write_bytes(&summary_path, format!("{json}\n").as_bytes())
            .with_context(|| format!("cannot write {}", summary_path.display()))?;
        Ok(summary)
    }
}

/// Checks a resume's history against its checkpoint's step `step`
/// ([`crate::io::history::check_resume_history`]): a gap is refused as [`BadResume`]; rows and
/// frames past the step, which the resume cuts and computes again, are reported unless `quiet`.
fn check_history(
    timeseries: &Path,
    particles: Option<&Path>,
    step: u64,
    history_from: u64,
    case: &Case,
    quiet: bool,
) -> Result<(), BadResume> {
    if !timeseries.is_file() {
        // Reported by the time series' own reopening, as before.
        return Ok(());
    }
    let every = case.run.output_every;
    let repair = crate::io::history::check_resume_history(timeseries, particles, step, every, history_from)
        .map_err(|e| BadResume(format!("cannot resume: {e}")))?;
    if !quiet && repair.rows_after + repair.frames_after > 0 {
        let frames = particles
            .map(|p| format!(" and {} frame(s) of {}", repair.frames_after, p.display()))
            .unwrap_or_default();
        eprintln!(
            "resume: {} row(s) of {}{frames} after the checkpoint's step {step} are cut (work after the \
             checkpoint, computed again)",
            repair.rows_after,
            timeseries.display()
        );
    }
    Ok(())
}

/// Restores `solver` from the checkpoint at `path`, which must have been written for the case
/// with `fingerprint` (and, for a coupled solver, hold the bodies' states). With `relaxed`
/// (the case, on a contact-scheme switch, [`RunOptions::switch_contacts`]) a checkpoint of the
/// same case up to the contact scheme ([`Case::same_except_contact_scheme`]) is accepted too.
/// Returns the step the run's history starts after ([`crate::io::Checkpoint::history_from`]).
fn restore<T: Real + hdf5::H5Type>(
    solver: &mut Solver<T>,
    path: &Path,
    fingerprint: &str,
    relaxed: Option<&Case>,
    out_dir: &Path,
) -> anyhow::Result<u64> {
    let no_checkpoint = || {
        format!(
            "no checkpoint in {} (the run wrote none yet, or it is not a slurry checkpoint)",
            out_dir.display()
        )
    };
    if !path.is_file() {
        return Err(BadResume(no_checkpoint()).into());
    }
    let checkpoint = read_checkpoint::<T>(path).map_err(|e| {
        match (e.downcast_ref::<PrecisionMismatch>(), e.downcast_ref::<crate::io::checksum::Corrupt>()) {
            (Some(p), _) => BadResume(p.to_string()),
            (_, Some(c)) => BadResume(c.to_string()),
            _ => BadResume(format!("{}: {} cannot be read as one", no_checkpoint(), path.display())),
        }
    })?;
    let history_from = checkpoint.history_from;
    let switched = || relaxed.is_some_and(|c| c.same_except_contact_scheme(&checkpoint.case));
    if checkpoint.case != fingerprint && !switched() {
        let also = if relaxed.is_some() {
            ", and with --switch-contacts [contacts] substeps, lubrication_limiter and lubrication_substeps"
        } else {
            ""
        };
        return Err(BadResume(format!(
            "{} was written for a different case (only run.steps, run.checkpoint_every, run.snapshots and run.mach_limit may change{also})",
            path.display()
        ))
        .into());
    }
    match solver {
        Solver::Fluid(f) | Solver::Device { host: f, .. } => {
            f.restore(&checkpoint.state).context("cannot restore the checkpoint")?
        }
        Solver::Coupled(c) => {
            let bodies = checkpoint
                .bodies
                .ok_or_else(|| BadResume(format!("{} holds no particle states", path.display())))?;
            let state = CoupledState { fluid: checkpoint.state, bodies };
            // With the force field when the checkpoint has it (outputs at the resumed step
            // need the velocity's half-force term); older checkpoints restore without.
            c.restore(&state).map_err(|e| anyhow::anyhow!("cannot restore the checkpoint: {e}"))?;
        }
        // A session restores on the host before moving onto the device; restored here, the
        // state goes up as it is.
        Solver::DeviceCoupled { device, synced } => {
            let bodies = checkpoint
                .bodies
                .ok_or_else(|| BadResume(format!("{} holds no particle states", path.display())))?;
            let state = solver::as_f32_state(CoupledState { fluid: checkpoint.state, bodies })?;
            device.restore(&state).map_err(|e| anyhow::anyhow!("cannot restore the checkpoint: {e}"))?;
            *synced = false;
        }
    }
    Ok(history_from)
}
