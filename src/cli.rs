//! The solver's commands for the `slurry` binary: `run`, `check`, `settle`, `state-pack` and
//! `bench`, their
//! clap argument structs, the run options they share with the reproduction's commands
//! ([`RunControl`], [`Console`]), and how a command's outcome becomes the exit status
//! ([`execute`]).
//!
//! The binary itself is built by the reproduction crate (`slurry-reproduce`), which adds its
//! own commands beside these; a user's own case needs only this library.
//!
//! Exit status: 0 on success; 2 for bad input (case file, command line); 1 for numerical
//! trouble or an output failure; 130 or 143 when SIGINT or SIGTERM stopped a run at a
//! checkpoint. Errors are printed as `error: ...` with their full cause chain.

use std::num::NonZeroUsize;
use std::path::{Path, PathBuf};
use std::process::ExitCode;

use anyhow::Context;
use clap::Args;

use crate::case::{Case, CaseError, Device};
use crate::run::{run_case, run_case_from_pack, write_run_state_pack, RunOptions};
use crate::settle::{settle_case, SettleOptions};

/// Exit status for bad input.
pub const EXIT_BAD_INPUT: u8 = 2;
/// Exit status for numerical trouble and other run-time failures.
pub const EXIT_FAILURE: u8 = 1;

/// A command-line problem found after parsing (exit status 2).
#[derive(Debug, thiserror::Error)]
#[error("{0}")]
pub struct BadInput(pub String);

/// The console options of every command that steps: worker threads and progress output.
#[derive(Args, Debug, Clone, Copy)]
pub struct Console {
    /// Number of worker threads, at most the machine's hardware threads (default: all cores,
    /// or RAYON_NUM_THREADS).
    #[arg(long, value_name = "N")]
    pub threads: Option<NonZeroUsize>,
    /// No progress output.
    #[arg(long)]
    pub quiet: bool,
}

/// The run options that `slurry run` and `slurry reproduce` share: how a run starts in an
/// output directory (fresh, resumed, or over an earlier run), and its console.
#[derive(Args, Debug, Clone, Copy)]
pub struct RunControl {
    /// Continue from the output directory's last checkpoint, bitwise identically to an
    /// uninterrupted run. A finished run may be continued too, with more steps (`run.steps`)
    /// or more revolutions (`reproduce --revolutions`).
    #[arg(long)]
    pub resume: bool,
    /// With --resume, or a start from a state pack (`run --from-pack`, `reproduce
    /// --start-from`): accept a checkpoint or pack written under other contact settings
    /// (`[contacts] substeps`, `lubrication_limiter`, `lubrication_substeps`, `damping`;
    /// everything else must match), to continue a run under another contact scheme from the
    /// same state.
    #[arg(long)]
    pub switch_contacts: bool,
    /// Start over in an output directory that holds an earlier run, replacing its checkpoint,
    /// time series and particle history (without it, or --resume, such a directory is
    /// refused).
    #[arg(long, conflicts_with = "resume")]
    pub overwrite: bool,
    /// Threads and progress output.
    #[command(flatten)]
    pub console: Console,
}

impl RunControl {
    /// Refuses `--switch-contacts` without a state to switch from: `--resume`, or a start from
    /// a pack (`start_flag`, the command's flag for it, when given).
    ///
    /// # Errors
    /// `--switch-contacts` alone.
    pub fn check_switch_contacts(&self, start_flag: Option<&str>) -> Result<(), BadInput> {
        if self.switch_contacts && !self.resume && start_flag.is_none() {
            return Err(BadInput(
                "--switch-contacts: needs --resume, or a start from a state pack (run --from-pack, \
                 reproduce --start-from), whose contact settings it relaxes"
                    .into(),
            ));
        }
        Ok(())
    }

    /// The driver's options for these flags.
    pub fn run_options(&self) -> RunOptions {
        RunOptions {
            quiet: self.console.quiet,
            resume: self.resume,
            switch_contacts: self.switch_contacts,
            overwrite: self.overwrite,
        }
    }
}

/// `slurry run`.
#[derive(Args, Debug)]
pub struct RunArgs {
    /// The case file (TOML; see docs/case-format.md).
    pub case: PathBuf,
    /// Output directory (created if needed). One that holds an earlier run's checkpoint is
    /// refused unless --resume or --overwrite says what to do with it.
    #[arg(long, value_name = "DIR")]
    pub out: PathBuf,
    /// Start from this state pack (`slurry state-pack`) of the same case and grid instead of
    /// the case's initial state: the flow rebuilt from its density and velocity, the bodies
    /// exactly as packed; close to the packed run's own continuation, not bitwise.
    #[arg(long, value_name = "PACK", conflicts_with = "resume")]
    pub from_pack: Option<PathBuf>,
    /// Which processor steps the fluid, overriding the case's `[run] device`: `cpu`, or `gpu`
    /// (the device backend through Vulkan; f32 cases, with or without particles and impeller,
    /// and fluid-only f64 cases where the adapter has 64-bit float shaders).
    #[arg(long, value_name = "DEVICE", value_parser = ["cpu", "gpu"])]
    pub device: Option<String>,
    /// How the run starts, threads, progress.
    #[command(flatten)]
    pub control: RunControl,
}

/// `slurry state-pack`: a compact state of a run, to continue it elsewhere.
#[derive(Args, Debug)]
pub struct StatePackArgs {
    /// The run's output directory (its `case.toml` and `checkpoint.h5`).
    pub run_dir: PathBuf,
    /// The pack to write (default: `state-pack.h5` in the run's directory).
    pub pack: Option<PathBuf>,
    /// What the pack is of, stored for people (default: the run directory's path).
    #[arg(long)]
    pub label: Option<String>,
}

/// `slurry settle`.
#[derive(Args, Debug)]
pub struct SettleArgs {
    /// The case file: free particles, gravity and a `[contacts]` section.
    pub case: PathBuf,
    /// Output directory for `bed.h5` and `bed_particles.toml`.
    #[arg(long, value_name = "DIR")]
    pub out: PathBuf,
    /// Stop when the mean particle speed falls below this (lattice units).
    #[arg(long, default_value_t = 1e-4, allow_negative_numbers = true)]
    pub speed: f64,
    /// Steps between checks of the stopping rule.
    #[arg(long, default_value_t = 200)]
    pub check_every: u64,
    /// No stop before this many steps.
    #[arg(long, default_value_t = 2000)]
    pub min_steps: u64,
    /// Give up after this many steps (the bed is written, marked as not settled; exit 1).
    #[arg(long, default_value_t = 1_000_000)]
    pub max_steps: u64,
    /// Threads and progress output.
    #[command(flatten)]
    pub console: Console,
}

/// `slurry check`.
#[derive(Args, Debug)]
pub struct CheckArgs {
    /// The case file (TOML; see docs/case-format.md).
    pub case: PathBuf,
}

/// `slurry bench`: the fused fluid kernel on periodic boxes.
#[derive(Args, Debug)]
pub struct BenchArgs {
    /// Box sizes: `N` for N³ or `NXxNYxNZ`, comma separated.
    #[arg(long, value_delimiter = ',', default_values_t = ["128".to_string(), "256x256x240".to_string()])]
    pub sizes: Vec<String>,
    /// Thread counts, comma separated.
    #[arg(long, value_delimiter = ',', default_values_t = [1usize, 2])]
    pub threads: Vec<usize>,
    /// Precisions, comma separated (`f32`, `f64`).
    #[arg(long, value_delimiter = ',', default_values_t = ["f32".to_string(), "f64".to_string()])]
    pub precisions: Vec<String>,
    /// Collision models, comma separated (`bgk`, `trt`).
    #[arg(long, value_delimiter = ',', default_values_t = ["bgk".to_string(), "trt".to_string()])]
    pub collisions: Vec<String>,
    /// Repetitions per configuration (the best and the median are reported).
    #[arg(long, default_value_t = 5)]
    pub reps: usize,
    /// Approximate length of one repetition, seconds.
    #[arg(long, default_value_t = 1.0)]
    pub seconds: f64,
    /// Write the results as a JSON array to this file (atomically).
    #[arg(long, value_name = "FILE")]
    pub json: Option<PathBuf>,
    /// `gpu`: also measure the device backend's fluid step (f32) beside the CPU's, in the same
    /// run; its rows read `gpu` in the instruction-set column. A CPU driver's (lavapipe's)
    /// figures show that the path works, not its speed.
    #[arg(long, value_name = "DEVICE", value_parser = ["cpu", "gpu"], default_value = "cpu")]
    pub device: String,
    /// The device kernels' work-group size (threads along x), with `--device gpu`.
    #[arg(long, value_name = "N", default_value_t = crate::device::fluid::DEFAULT_WORKGROUP)]
    pub workgroup: u32,
}

/// Runs a command: SIGINT and SIGTERM handled as a request to stop at a checkpoint, HDF5's
/// own error printing silenced, and the outcome turned into the exit status (module docs).
pub fn execute(command: impl FnOnce() -> anyhow::Result<()>) -> ExitCode {
    // Errors are reported once, as `error: …` lines, never as HDF5's own stack dump.
    hdf5::silence_errors(true);
    // SIGINT and SIGTERM: the stepping loops stop at their next complete state with a
    // checkpoint; anywhere else the process ends at once, as without the handler.
    if let Err(e) = crate::interrupt::install() {
        eprintln!(
            "warning: cannot handle SIGINT and SIGTERM ({e}); a signal ends the run without a checkpoint"
        );
    }
    match command() {
        Ok(()) => ExitCode::SUCCESS,
        Err(e) => {
            // A stop that a signal asked for is not an error: said as it is, without the
            // command's "… failed" context.
            if let Some(stop) = e.downcast_ref::<crate::interrupt::Interrupted>() {
                eprintln!("{stop}");
                return ExitCode::from(stop.signal.exit_status());
            }
            eprintln!("error: {e:#}");
            if e.downcast_ref::<CaseError>().is_some()
                || e.downcast_ref::<BadInput>().is_some()
                || e.downcast_ref::<crate::run::BadResume>().is_some()
                || e.downcast_ref::<crate::run::WouldOverwrite>().is_some()
                || e.downcast_ref::<crate::io::lock::OutputRefused>().is_some()
                || e.downcast_ref::<crate::io::checksum::Corrupt>().is_some()
            {
                ExitCode::from(EXIT_BAD_INPUT)
            } else {
                ExitCode::from(EXIT_FAILURE)
            }
        }
    }
}

/// The machine's hardware threads (`std::thread::available_parallelism`, which honours CPU
/// affinity and cgroup quotas; 1 when it cannot tell).
fn hardware_threads() -> usize {
    std::thread::available_parallelism().map_or(1, NonZeroUsize::get)
}

/// Refuses a thread count above the machine's (unchecked, `--threads 100000` never returns).
///
/// # Errors
/// The message names `flag`, the count and the allowed range.
pub fn check_threads(flag: &str, n: usize) -> Result<(), BadInput> {
    let cores = hardware_threads();
    if n > cores {
        return Err(BadInput(format!(
            "{flag} {n}: this machine has {cores} hardware thread(s); allowed: 1 ..= {cores} \
             (more threads than cores only slow the run down)"
        )));
    }
    Ok(())
}

/// The worker pool: `threads`, or rayon's default (all cores, or `RAYON_NUM_THREADS`),
/// refusing more threads than the machine has.
///
/// # Errors
/// Too many threads (naming `--threads` or `RAYON_NUM_THREADS`), or a pool that cannot be
/// built.
pub fn thread_pool(threads: Option<NonZeroUsize>) -> Result<rayon::ThreadPool, BadInput> {
    let mut builder = rayon::ThreadPoolBuilder::new();
    match threads {
        Some(n) => {
            check_threads("--threads", n.get())?;
            builder = builder.num_threads(n.get());
        }
        None => {
            if let Ok(v) = std::env::var("RAYON_NUM_THREADS") {
                if let Ok(n) = v.trim().parse::<usize>() {
                    check_threads("RAYON_NUM_THREADS =", n)?;
                }
            }
        }
    }
    builder.build().map_err(|e| BadInput(format!("--threads: cannot build the thread pool: {e}")))
}

/// Creates the output directory `dir` (flag `--out`) if needed and checks that files can be
/// created in it: an unusable directory is bad input (exit status 2), found before any work.
///
/// # Errors
/// The path is not usable (`io::lock::check_output_path`: not UTF-8, a file), the directory
/// cannot be created, or a file cannot be created in it.
pub fn usable_out_dir(dir: &Path) -> Result<(), BadInput> {
    crate::io::lock::check_output_path(dir, "--out").map_err(|e| BadInput(e.to_string()))?;
    std::fs::create_dir_all(dir)
        .map_err(|e| BadInput(format!("--out {}: cannot create the output directory: {e}", dir.display())))?;
    let probe = dir.join(format!(".slurry-write-test.{}", std::process::id()));
    match std::fs::OpenOptions::new().write(true).create(true).truncate(true).open(&probe) {
        Ok(_) => {
            let _ = std::fs::remove_file(&probe);
            Ok(())
        }
        Err(e) => {
            Err(BadInput(format!("--out {}: cannot write into the output directory: {e}", dir.display())))
        }
    }
}

/// `slurry run`: the case to its end, with a closing line on the console.
///
/// # Errors
/// Bad input (the case, the flags, the output directory) or a failed run.
pub fn cmd_run(a: RunArgs) -> anyhow::Result<()> {
    let mut case = Case::from_file(&a.case)?;
    if let Some(d) = &a.device {
        case.run.device = if d == "gpu" { Device::Gpu } else { Device::Cpu };
    }
    a.control.check_switch_contacts(a.from_pack.as_ref().map(|_| "--from-pack"))?;
    usable_out_dir(&a.out)?;
    let pool = thread_pool(a.control.console.threads)?;
    let opts = a.control.run_options();
    let summary = pool
        .install(|| match &a.from_pack {
            Some(pack) => run_case_from_pack(&case, &a.out, opts, pack),
            None => run_case(&case, &a.out, opts),
        })
        .with_context(|| format!("run of {} failed", a.case.display()))?;
    if !opts.quiet {
        eprintln!(
            "done: {} steps in {:.2} s ({:.1} MLUPS, {} threads, {} {}); max Mach {:.4}; relative mass change {:.2e}; output in {}",
            summary.steps,
            summary.wall_time_s,
            summary.mlups,
            summary.threads,
            summary.precision,
            summary.isa,
            summary.max_mach,
            summary.relative_mass_change,
            a.out.display()
        );
    }
    Ok(())
}

/// `slurry settle`: the case's particles settled into a bed, stored in the output directory.
///
/// # Errors
/// Bad input, a failed settling, or a bed that did not settle within `--max-steps`.
pub fn cmd_settle(a: SettleArgs) -> anyhow::Result<()> {
    let case = Case::from_file(&a.case)?;
    if !(a.speed.is_finite() && a.speed > 0.0) {
        return Err(BadInput(format!("--speed {}: must be positive and finite", a.speed)).into());
    }
    usable_out_dir(&a.out)?;
    let pool = thread_pool(a.console.threads)?;
    let opts = SettleOptions {
        speed: a.speed,
        check_every: a.check_every,
        min_steps: a.min_steps,
        max_steps: a.max_steps,
        quiet: a.console.quiet,
        checkpoint_every_s: crate::settle::SETTLING_CHECKPOINT_EVERY_S,
    };
    let s = pool
        .install(|| settle_case(&case, &a.out, opts))
        .with_context(|| format!("settling {} failed", a.case.display()))?;
    eprintln!(
        "{}: {} steps in {:.1} s, mean particle speed {:.2e}, mean height {:.2}; bed in {} and {}",
        if s.settled { "settled" } else { "NOT settled (max steps reached)" },
        s.steps,
        s.seconds,
        s.mean_speed,
        s.mean_height,
        s.bed_h5.display(),
        s.bed_toml.display()
    );
    if !s.settled {
        anyhow::bail!(
            "the stopping rule (mean speed < {:e}) was not met within {} steps",
            a.speed,
            a.max_steps
        );
    }
    Ok(())
}

/// `slurry state-pack`: the run's checkpoint as a state pack ([`crate::io::state_pack`]).
///
/// # Errors
/// No run (case and checkpoint) in the directory, or the pack cannot be written.
pub fn cmd_state_pack(a: StatePackArgs) -> anyhow::Result<()> {
    let pack = a.pack.clone().unwrap_or_else(|| a.run_dir.join("state-pack.h5"));
    let label = a.label.clone().unwrap_or_else(|| a.run_dir.display().to_string());
    let step = write_run_state_pack(&a.run_dir, &pack, &label)
        .with_context(|| format!("state pack of {} failed", a.run_dir.display()))?;
    let bytes = std::fs::metadata(&pack).map(|m| m.len()).unwrap_or(0);
    let parts: Vec<String> = crate::io::state_pack::dataset_sizes(&pack)
        .unwrap_or_default()
        .iter()
        .map(|(name, b)| format!("{name} {:.2}", *b as f64 / 1e6))
        .collect();
    eprintln!(
        "state pack of step {step}: {} ({:.2} MB: {} MB)",
        pack.display(),
        bytes as f64 / 1e6,
        parts.join(", ")
    );
    Ok(())
}

/// `slurry check`: the case validated and described on stdout.
///
/// # Errors
/// The case file is refused.
pub fn cmd_check(a: CheckArgs) -> anyhow::Result<()> {
    let case = Case::from_file(&a.case)?;
    print!("{}", case.describe());
    println!("{}: ok", a.case.display());
    Ok(())
}

fn parse_size(s: &str) -> anyhow::Result<crate::lattice::Grid> {
    let parts: Vec<&str> = s.split('x').collect();
    let nums: Result<Vec<usize>, _> = parts.iter().map(|p| p.trim().parse::<usize>()).collect();
    match nums.as_deref() {
        Ok([n]) if *n >= 2 => Ok(crate::lattice::Grid::new(*n, *n, *n)),
        Ok([x, y, z]) if *x >= 2 && *y >= 2 && *z >= 2 => Ok(crate::lattice::Grid::new(*x, *y, *z)),
        _ => Err(BadInput(format!("--sizes: `{s}` is not N or NXxNYxNZ with every size >= 2")).into()),
    }
}

/// `slurry bench`: the fused kernel's MLUPS for each size, precision, collision model and
/// thread count, as a table (and JSON with `--json`).
///
/// # Errors
/// Bad flags, or the JSON file cannot be written.
pub fn cmd_bench(a: &BenchArgs) -> anyhow::Result<()> {
    use crate::bench::{measure, measure_device, BenchResult};
    let grids = a.sizes.iter().map(|s| parse_size(s)).collect::<anyhow::Result<Vec<_>>>()?;
    for p in &a.precisions {
        if p != "f32" && p != "f64" {
            return Err(BadInput(format!("--precisions: `{p}`; allowed: f32, f64")).into());
        }
    }
    for c in &a.collisions {
        if c != "bgk" && c != "trt" {
            return Err(BadInput(format!("--collisions: `{c}`; allowed: bgk, trt")).into());
        }
    }
    if a.threads.contains(&0) || a.reps == 0 || a.seconds.is_nan() || a.seconds <= 0.0 {
        return Err(BadInput("--threads, --reps and --seconds must be positive".into()).into());
    }
    for &t in &a.threads {
        check_threads("--threads", t)?;
    }
    let mut results: Vec<BenchResult> = Vec::new();
    let device = if a.device == "gpu" {
        let ctx = crate::device::Context::new()?;
        println!("device: {}", ctx.describe());
        if ctx.is_cpu_driver() {
            println!("(a CPU driver: its MLUPS show that the device path works, not its speed)");
        }
        // The copy ceiling, with buffers the size of the largest grid's populations (f32).
        let bytes = grids.iter().map(|g| 19 * 4 * g.nodes() as u64).max().unwrap_or(1 << 20);
        let bw = crate::device::bandwidth::copy_bandwidth(&ctx, bytes, a.reps)?;
        println!(
            "device copy bandwidth: {:.1} GB/s (median {:.1}; buffers of {} MB, read plus write)",
            bw.gbs,
            bw.gbs_median,
            bw.bytes / 1_000_000
        );
        Some((ctx, bw))
    } else {
        None
    };
    println!(
        "{:>13} {:>4} {:>4} {:>3} {:>9} {:>9} {:>7} {:>7} {:>6}",
        "grid", "prec", "coll", "thr", "MLUPS", "median", "GB/s", "isa", "copy%"
    );
    let row = |r: &BenchResult| {
        println!(
            "{:>13} {:>4} {:>4} {:>3} {:>9.1} {:>9.1} {:>7.1} {:>7} {:>6}",
            format!("{}x{}x{}", r.nx, r.ny, r.nz),
            r.precision,
            r.collision,
            if r.isa == "gpu" { "-".to_string() } else { r.threads.to_string() },
            r.mlups,
            r.mlups_median,
            r.gbs,
            r.isa,
            r.copy_gbs.map_or("-".to_string(), |c| format!("{:.0}", 100.0 * r.gbs / c)),
        );
    };
    for g in &grids {
        for p in &a.precisions {
            for c in &a.collisions {
                for &t in &a.threads {
                    let trt = c == "trt";
                    let r = if p == "f32" {
                        measure::<f32>(*g, trt, t, a.reps, a.seconds)
                    } else {
                        measure::<f64>(*g, trt, t, a.reps, a.seconds)
                    };
                    row(&r);
                    results.push(r);
                }
                if let (Some((ctx, bw)), true) = (&device, p == "f32") {
                    let mut r = measure_device(ctx, *g, c == "trt", a.workgroup, a.reps, a.seconds)?;
                    r.copy_gbs = Some(bw.gbs);
                    row(&r);
                    results.push(r);
                }
            }
        }
    }
    if let Some(path) = &a.json {
        if let Some(dir) = path.parent().filter(|d| !d.as_os_str().is_empty()) {
            std::fs::create_dir_all(dir).with_context(|| format!("cannot create {}", dir.display()))?;
        }
        let text = serde_json::to_string_pretty(&results)?;
        crate::io::atomic_write_bytes(path, text.as_bytes())
            .with_context(|| format!("cannot write {}", path.display()))?;
        println!("wrote {}", path.display());
    }
    Ok(())
}
