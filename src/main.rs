//! The `slurry` command line.
//!
//! ```text
//! slurry run CASE.toml --out DIR [--threads N] [--quiet] [--resume | --overwrite]
//! slurry settle CASE.toml --out DIR [--speed V] [--check-every N] [--min-steps N] [--max-steps N]
//! slurry check CASE.toml
//! slurry reproduce CASE|--all [--scale S] [--revolutions R] [--until-steady CAP] [--quick] [--out DIR] [--resume | --overwrite]
//! slurry bench [--sizes 128,256x256x240] [--threads 1,2] [--json FILE]
//! slurry resolution RUN_DIR... [--out FILE]
//! slurry status OUT...
//! ```
//!
//! Exit status: 0 on success; 2 for bad input (case file, command line); 1 for numerical
//! trouble or an output failure. Errors are printed as `error: ...` with their full cause
//! chain.

use std::num::NonZeroUsize;
use std::path::PathBuf;
use std::process::ExitCode;

use anyhow::Context;
use clap::{Args, Parser, Subcommand};

use slurry::case::{Case, CaseError};
use slurry::run::{run_case, RunOptions};
use slurry::settle::{settle_case, SettleOptions};

/// Particle-resolved simulation of dense suspensions (lattice Boltzmann).
#[derive(Parser, Debug)]
#[command(name = "slurry", version, about)]
struct Cli {
    #[command(subcommand)]
    command: Command,
}

/// Subcommands.
#[derive(Subcommand, Debug)]
enum Command {
    /// Run a case file and write its output into a directory.
    Run(RunArgs),
    /// Let a case's particles settle into a bed under gravity (no impeller) and store it.
    Settle(SettleArgs),
    /// Validate a case file and print what it describes.
    Check(CheckArgs),
    /// Measure the fused kernel's throughput (MLUPS) on periodic boxes.
    Bench(BenchArgs),
    /// Reproduce one of the paper's stirred cases (or all six): bed, run, statistics, figures, report.
    Reproduce(ReproduceArgs),
    /// The resolution study of one case: its reproductions at several scales side by side, with
    /// the observed order and Richardson estimate from the three finest steady ones (runs of one
    /// scale from different starts: their mean is the scale's level, their spread the start's
    /// effect).
    Resolution(ResolutionArgs),
    /// Where a reproduction stands, from its files (while it runs, or its archive): progress,
    /// speed and time left, ⟨z_p⟩/H by 10 revolutions, the steady test now, the power numbers.
    Status(StatusArgs),
    /// Keep the end of a reproduction as a start pack: its manifest, its case and the few frames
    /// of its last 20 revolutions that `--start-from` would choose from (under 1 MB, for
    /// its archive), so that `--start-from PACK` works after the output directory is gone
    /// (`--at T`: of the 20 revolutions ending at its time T instead, an earlier state).
    StartPack(StartPackArgs),
}

/// `slurry start-pack`.
#[derive(Args, Debug)]
struct StartPackArgs {
    /// The output directory of `slurry reproduce` (its `--out`), running or finished.
    #[arg(value_name = "OUT")]
    run: PathBuf,
    /// The pack's directory (created; its files are replaced), e.g. the archive's `start/`.
    #[arg(value_name = "PACK")]
    pack: PathBuf,
    /// Take the frames from the 20 revolutions that end at the run's time T (in revolutions
    /// t N, the ramp counting 1, as its report's Figure 5), not from its last 20: an earlier,
    /// lower state, to approach a finer scale's level from below.
    #[arg(long, value_name = "T")]
    at: Option<f64>,
}

/// `slurry status`.
#[derive(Args, Debug)]
struct StatusArgs {
    /// Output directories of `slurry reproduce` (its `--out`), or archives of them.
    #[arg(required = true, value_name = "OUT")]
    dirs: Vec<PathBuf>,
}

/// `slurry resolution`.
#[derive(Args, Debug)]
struct ResolutionArgs {
    /// The output directories of `slurry reproduce` runs of one case at distinct scales (or
    /// their archives): each holds the report's `statistics.json`.
    #[arg(required = true, value_name = "RUN_DIR")]
    runs: Vec<PathBuf>,
    /// Also write the table (Markdown) to this file, atomically.
    #[arg(long, value_name = "FILE")]
    out: Option<PathBuf>,
}

/// `slurry reproduce`.
#[derive(Args, Debug)]
struct ReproduceArgs {
    /// The case: disk-ld1, disk-ld2, disk-ld4, pbt-ld1, pbt-ld2 or pbt-ld4.
    #[arg(required_unless_present = "all", conflicts_with = "all")]
    case: Option<String>,
    /// All six cases, one after the other, then their cross-case summary (`OUT/summary/`:
    /// Figures 5–9 with the three ℓ/d of each impeller on one plot, and the table).
    #[arg(long)]
    all: bool,
    /// With --all: run nothing, only redraw the cross-case summary from the cases already
    /// run under the output directory (e.g. after one was resumed on its own).
    #[arg(long, requires = "all")]
    summary_only: bool,
    /// Scale s of the system, 0.25 ≤ s ≤ 1 (1: the paper's 251 × 251 × 240 with d = 12;
    /// 0.5: d = 6); default 0.25 (d = 3; the smallest at which the random placement fits the
    /// paper's particles in every case).
    #[arg(long, allow_negative_numbers = true)]
    scale: Option<f64>,
    /// Impeller revolutions after the ramp (> 0), run as a fixed length unless --until-steady
    /// is given too. Without either, the run goes to the paper's steady state: 100 revolutions
    /// (200 for pbt-ld1, the paper's "more than 200"), then on as with --until-steady 200 (300
    /// for pbt-ld1); 1–2.5 h per case on 2 cores at the default scale. 0.25 with --quick.
    #[arg(long, allow_negative_numbers = true)]
    revolutions: Option<f64>,
    /// A short smoke-test run (scale 0.25, 0.25 revolutions after the ramp): about a minute on 2 cores.
    #[arg(long)]
    quick: bool,
    /// Output directory (a sub-directory per case with --all); default target/reproduce/CASE.
    #[arg(long, value_name = "DIR")]
    out: Option<PathBuf>,
    /// Cache of settled beds; default target/reproduce/cache.
    #[arg(long, value_name = "DIR")]
    cache: Option<PathBuf>,
    /// Continue an interrupted run from its last checkpoint (bitwise identical result).
    /// A finished run may be continued too, with more --revolutions.
    #[arg(long)]
    resume: bool,
    /// With --resume: continue a checkpoint written under other contact settings
    /// (--contact-substeps, --lubrication-limiter), to measure one contact scheme against
    /// another from the same state; the manifest's sessions record each command.
    #[arg(long, requires = "resume")]
    switch_contacts: bool,
    /// Start over in an output directory that holds an earlier run, replacing its checkpoint,
    /// time series and particle history (without it, or --resume, such a directory is refused).
    #[arg(long, conflicts_with = "resume")]
    overwrite: bool,
    /// Number of worker threads, at most the machine's hardware threads (default: all cores, or RAYON_NUM_THREADS).
    #[arg(long, value_name = "N")]
    threads: Option<NonZeroUsize>,
    /// No progress output.
    #[arg(long)]
    quiet: bool,
    /// Contact sub-steps per fluid step of the stirred run, 1 … 1024 (default: the case's, 8);
    /// to measure a cheaper contact scheme against the default. The bed is settled with 8.
    #[arg(long, value_name = "N")]
    contact_substeps: Option<usize>,
    /// Turn the lubrication limiter on in the stirred run (`[contacts] lubrication_limiter`:
    /// stable at fewer sub-steps; not the default, its effect on the statistics is being
    /// measured).
    #[arg(long)]
    lubrication_limiter: bool,
    /// Lubrication sub-steps per contact sub-step in the stirred run, 1 … 1024
    /// (`[contacts] lubrication_substeps`, default 1): the lubrication frozen as a linear map
    /// of the bodies' velocities at each contact evaluation and stepped this many times
    /// (cheaper at fewer --contact-substeps; not the default, its effect is being measured).
    #[arg(long, value_name = "M")]
    lubrication_substeps: Option<usize>,
    /// How the bed is settled: `dry` (no fluid, amplified gravity against a linear drag;
    /// minutes) or `wet` (in the fluid under the case's gravity, as the paper does; about
    /// 20 min at the default scale, 16× that at s = 1/2). Each is cached separately.
    #[arg(long, value_enum, default_value_t = BedArg::Dry)]
    bed: BedArg,
    /// Stop the stirred run when the Mach number |u|/c_s exceeds this anywhere, 0 < L ≤ 1
    /// (default 0.3). Only a health check: a run it stopped can be resumed (--resume) with a
    /// higher one, and the numbers do not depend on it.
    #[arg(long, value_name = "L", allow_negative_numbers = true)]
    mach_limit: Option<f64>,
    /// Run to steady state: after --revolutions, go on in legs of 10 revolutions until the
    /// report's steady test passes (drift of ⟨z_p⟩/H over the last 20 revolutions at most
    /// 0.005, and its standard error too), to at most CAP revolutions
    /// after the ramp (CAP ≥ --revolutions; --revolutions defaults to 100 here, 200 for
    /// pbt-ld1). `--revolutions 100 --until-steady 200` is the default run.
    #[arg(long, value_name = "CAP", allow_negative_numbers = true)]
    until_steady: Option<f64>,
    /// Start from the particles of another reproduction of the same case (its output
    /// directory, at any scale) instead of the settled bed: a frame of its last 20 revolutions
    /// with the impeller where this run's starts, positions scaled to this grid, at rest; the
    /// choice is written to `start.json`. For a half-scale case, started from the steady state
    /// of a coarser run: the suspension then approaches its level from above. A resumed run
    /// needs the same directory.
    #[arg(long, value_name = "RUN", conflicts_with_all = ["all", "bed"])]
    start_from: Option<PathBuf>,
}

/// `slurry reproduce --bed`.
#[derive(Clone, Copy, Debug, PartialEq, Eq, clap::ValueEnum)]
enum BedArg {
    /// Settled without fluid.
    Dry,
    /// Settled in the fluid.
    Wet,
}

/// `slurry resolution`: the table on stdout (and in `--out`). Runs that cannot be read, or
/// that are not one case at distinct scales, are bad input (exit status 2).
fn cmd_resolution(a: ResolutionArgs) -> anyhow::Result<()> {
    let text = slurry::reproduce::resolution::write_resolution(&a.runs, None)
        .map_err(|e| BadInput(format!("{e:#}")))?;
    print!("{text}");
    if let Some(out) = &a.out {
        slurry::io::atomic_write_bytes(out, text.as_bytes())
            .with_context(|| format!("cannot write {}", out.display()))?;
    }
    Ok(())
}

/// `slurry start-pack`: the pack, then one line on what it holds.
fn cmd_start_pack(a: StartPackArgs) -> anyhow::Result<()> {
    let pack = slurry::reproduce::start::write_start_pack(&a.run, &a.pack, a.at)
        .map_err(|e| BadInput(format!("{e:#}")))?;
    let errors: Vec<String> = pack.phase_errors_deg.iter().map(|e| format!("{e:.3}")).collect();
    println!(
        "{}: frames at steps {:?} (impeller phase errors {} deg), particles.h5 {} bytes",
        a.pack.display(),
        pack.steps,
        errors.join(", "),
        pack.bytes
    );
    Ok(())
}

/// `slurry status`: one block per directory; one that cannot be read is bad input (exit
/// status 2), after the others are printed.
fn cmd_status(a: StatusArgs) -> anyhow::Result<()> {
    let mut bad = Vec::new();
    for (k, dir) in a.dirs.iter().enumerate() {
        if k > 0 {
            println!();
        }
        match slurry::reproduce::status::status(dir) {
            Ok(text) => print!("{text}"),
            Err(e) => bad.push(format!("{e:#}")),
        }
    }
    if bad.is_empty() {
        Ok(())
    } else {
        Err(BadInput(bad.join("\n")).into())
    }
}

/// `slurry bench`.
#[derive(Args, Debug)]
struct BenchArgs {
    /// Box sizes: `N` for N³ or `NXxNYxNZ`, comma separated.
    #[arg(long, value_delimiter = ',', default_values_t = ["128".to_string(), "256x256x240".to_string()])]
    sizes: Vec<String>,
    /// Thread counts, comma separated.
    #[arg(long, value_delimiter = ',', default_values_t = [1usize, 2])]
    threads: Vec<usize>,
    /// Precisions, comma separated (`f32`, `f64`).
    #[arg(long, value_delimiter = ',', default_values_t = ["f32".to_string(), "f64".to_string()])]
    precisions: Vec<String>,
    /// Collision models, comma separated (`bgk`, `trt`).
    #[arg(long, value_delimiter = ',', default_values_t = ["bgk".to_string(), "trt".to_string()])]
    collisions: Vec<String>,
    /// Repetitions per configuration (the best and the median are reported).
    #[arg(long, default_value_t = 5)]
    reps: usize,
    /// Approximate length of one repetition, seconds.
    #[arg(long, default_value_t = 1.0)]
    seconds: f64,
    /// Write the results as a JSON array to this file (atomically).
    #[arg(long, value_name = "FILE")]
    json: Option<PathBuf>,
    /// Measure the coupled step of the paper's cases instead (per phase, beside the fluid-only
    /// step of the same grid; beds from the reproduction's cache, made on first use). The
    /// environment variable SLURRY_BENCH_DENSE=1 (or 0) forces the whole-grid (or the band) path
    /// of the immersed boundary, which gives the same bits, to compare their costs.
    #[arg(long)]
    coupled: bool,
    /// With --coupled: the cases, comma separated (default: all six).
    #[arg(long, value_delimiter = ',')]
    cases: Vec<String>,
    /// With --coupled: the scales, comma separated.
    #[arg(long, value_delimiter = ',', default_values_t = [0.25, 0.5, 1.0], allow_negative_numbers = true)]
    scales: Vec<f64>,
    /// With --coupled: steps before timing (the impeller's ramp has started).
    #[arg(long, default_value_t = 40)]
    warmup: u64,
    /// With --coupled: timed steps.
    #[arg(long, default_value_t = 20)]
    steps: u64,
    /// With --coupled: the skin of the contact pair list, lattice units (default: the
    /// library's, `DEFAULT_SKIN` = 0.15). The loads do not depend on it, only the cost.
    #[arg(long)]
    skin: Option<f64>,
    /// With --coupled: contact sub-steps per fluid step, 1 … 1024 (default: the case's, 8).
    #[arg(long)]
    contact_substeps: Option<usize>,
    /// With --coupled: turn the lubrication limiter on (`[contacts] lubrication_limiter`), so
    /// that fewer sub-steps stay stable.
    #[arg(long)]
    lubrication_limiter: bool,
    /// With --coupled: lubrication sub-steps per contact sub-step, 1 … 1024
    /// (`[contacts] lubrication_substeps`, default 1).
    #[arg(long, value_name = "M")]
    lubrication_substeps: Option<usize>,
    /// With --coupled: start from this checkpoint of a reproduction of the case (one case, one
    /// scale; e.g. `run/checkpoint.h5` of a run at steady state) instead of the settled bed.
    #[arg(long, value_name = "CHECKPOINT")]
    from: Option<PathBuf>,
}

/// `slurry bench --coupled`: the paper's cases at each scale, one thread count (the first of
/// `--threads`, default 2), f32.
fn cmd_bench_coupled(a: BenchArgs) -> anyhow::Result<()> {
    use slurry::reproduce::bench::{bench_case, CoupledBench};
    let cases: Vec<String> = if a.cases.is_empty() {
        slurry::reproduce::paper_cases().iter().map(|c| c.name.to_string()).collect()
    } else {
        a.cases.clone()
    };
    for &s in &a.scales {
        if let Err(e) = slurry::reproduce::check_scale(s) {
            return Err(BadInput(format!("--scales: {e}")).into());
        }
    }
    if a.steps == 0 {
        return Err(BadInput("--steps must be positive".into()).into());
    }
    if let Some(p) = &a.from {
        if cases.len() != 1 || a.scales.len() != 1 {
            return Err(BadInput(format!(
                "--from {}: give exactly one case (--cases) and one scale (--scales) to start from a checkpoint",
                p.display()
            ))
            .into());
        }
        if !p.is_file() {
            return Err(BadInput(format!("--from {}: no such file", p.display())).into());
        }
    }
    if let Some(skin) = a.skin {
        if !(skin.is_finite() && (0.0..=2.0).contains(&skin)) {
            return Err(BadInput(format!("--skin {skin} is out of range: it must be in [0, 2]")).into());
        }
    }
    if let Some(n) = a.contact_substeps {
        slurry::reproduce::check_contact_substeps(n).map_err(BadInput)?;
    }
    if let Some(m) = a.lubrication_substeps {
        slurry::reproduce::check_lubrication_substeps(m, a.lubrication_limiter).map_err(BadInput)?;
    }
    let contact = slurry::reproduce::bench::ContactOptions {
        skin: a.skin,
        substeps: a.contact_substeps,
        limiter: a.lubrication_limiter,
        lubrication_substeps: a.lubrication_substeps,
    };
    let threads = a.threads.iter().copied().max().unwrap_or(2);
    let pool = thread_pool(NonZeroUsize::new(threads))?;
    let cache = PathBuf::from("target").join("reproduce").join("cache");
    let mut rows: Vec<CoupledBench> = Vec::new();
    println!(
        "{:>8} {:>5} {:>5} {:>8} {:>8} {:>8} {:>8} {:>8} {:>8} {:>8} {:>8} {:>8} {:>8} {:>6} {:>8} {:>6} {:>8} {:>8} {:>9} {:>7} {:>7}",
        "case",
        "scale",
        "parts",
        "fluid",
        "step",
        "geometry",
        "interior",
        "forcing",
        "interp",
        "spread",
        "bodies",
        "contacts",
        "output",
        "ratio",
        "markers",
        "band",
        "listed",
        "touching",
        "rebuilds",
        "damp",
        "spring"
    );
    for &s in &a.scales {
        for name in &cases {
            let r = pool.install(|| {
                bench_case(name, s, &cache, a.warmup, a.steps, contact, a.from.as_deref(), false)
            })?;
            println!(
                "{:>8} {:>5} {:>5} {:>8.2} {:>8.2} {:>8.2} {:>8.2} {:>8.2} {:>8.2} {:>8.2} {:>8.2} {:>8.2} {:>8.3} {:>6.2} {:>8} {:>6} {:>8} {:>8} {:>9} {:>7.2} {:>7.2}",
                r.case,
                r.scale,
                r.particles,
                r.fluid_ms,
                r.step_ms,
                r.geometry_ms,
                r.interior_ms,
                r.forcing_ms,
                r.interpolate_ms,
                r.spread_ms,
                r.bodies_ms,
                r.contact_ms,
                r.output_ms,
                r.ratio,
                r.markers,
                format!("{:.2}{}", r.band_fraction, if r.whole_grid { "*" } else { "" }),
                r.listed_pairs,
                r.interacting_pairs,
                format!("{}/{}", r.full_rebuilds, r.list_rebuilds),
                r.max_damping_rate,
                r.max_spring_rate
            );
            rows.push(r);
            if let Some(path) = &a.json {
                let text = serde_json::to_string_pretty(&rows)?;
                slurry::io::atomic_write_bytes(path, text.as_bytes())
                    .with_context(|| format!("cannot write {}", path.display()))?;
            }
        }
    }
    println!(
        "(ms per step; fluid = the fluid-only step of the same grid; ratio = step / fluid; interp, spread: the parts of forcing; band: the bands' estimated nodes / the grid's, * the whole-grid path; damp, spring: the \
         stiffest body's contact rates, per fluid step: explicit sub-steps need n_sub > damp/2 and n_sub > spring/2)"
    );
    Ok(())
}

/// `slurry settle`.
#[derive(Args, Debug)]
struct SettleArgs {
    /// The case file: free particles, gravity and a `[contacts]` section.
    case: PathBuf,
    /// Output directory for `bed.h5` and `bed_particles.toml`.
    #[arg(long, value_name = "DIR")]
    out: PathBuf,
    /// Stop when the mean particle speed falls below this (lattice units).
    #[arg(long, default_value_t = 1e-4, allow_negative_numbers = true)]
    speed: f64,
    /// Steps between checks of the stopping rule.
    #[arg(long, default_value_t = 200)]
    check_every: u64,
    /// No stop before this many steps.
    #[arg(long, default_value_t = 2000)]
    min_steps: u64,
    /// Give up after this many steps (the bed is written, marked as not settled; exit 1).
    #[arg(long, default_value_t = 1_000_000)]
    max_steps: u64,
    /// Number of worker threads, at most the machine's hardware threads (default: all cores, or RAYON_NUM_THREADS).
    #[arg(long, value_name = "N")]
    threads: Option<NonZeroUsize>,
    /// No progress output.
    #[arg(long)]
    quiet: bool,
}

/// `slurry run`.
#[derive(Args, Debug)]
struct RunArgs {
    /// The case file (TOML; see docs/case-format.md).
    case: PathBuf,
    /// Output directory (created if needed). One that holds an earlier run's checkpoint is
    /// refused unless --resume or --overwrite says what to do with it.
    #[arg(long, value_name = "DIR")]
    out: PathBuf,
    /// Number of worker threads, at most the machine's hardware threads (default: all cores, or RAYON_NUM_THREADS).
    #[arg(long, value_name = "N")]
    threads: Option<NonZeroUsize>,
    /// No progress bar.
    #[arg(long)]
    quiet: bool,
    /// Continue from DIR/checkpoint.h5 (written with `run.checkpoint_every`), bitwise
    /// identically to an uninterrupted run; `run.steps` may be raised to extend a run.
    #[arg(long)]
    resume: bool,
    /// With --resume: accept a checkpoint written under other `[contacts] substeps` or
    /// `lubrication_limiter` (everything else must match), to continue a run under another
    /// contact scheme from the same state.
    #[arg(long, requires = "resume")]
    switch_contacts: bool,
    /// Start over in DIR although it holds an earlier run's checkpoint, replacing that run's
    /// checkpoint, time series and particle history.
    #[arg(long, conflicts_with = "resume")]
    overwrite: bool,
}

/// `slurry check`.
#[derive(Args, Debug)]
struct CheckArgs {
    /// The case file (TOML; see docs/case-format.md).
    case: PathBuf,
}

/// Exit status for bad input.
const EXIT_BAD_INPUT: u8 = 2;
/// Exit status for numerical trouble and other run-time failures.
const EXIT_FAILURE: u8 = 1;

fn main() -> ExitCode {
    let cli = Cli::parse();
    // Errors are reported once, as `error: …` lines, never as HDF5's own stack dump.
    hdf5::silence_errors(true);
    // SIGINT and SIGTERM: the stepping loops stop at their next complete state with a
    // checkpoint; anywhere else the process ends at once, as without the handler.
    if let Err(e) = slurry::interrupt::install() {
        eprintln!(
            "warning: cannot handle SIGINT and SIGTERM ({e}); a signal ends the run without a checkpoint"
        );
    }
    let result = match cli.command {
        Command::Run(a) => cmd_run(a),
        Command::Settle(a) => cmd_settle(a),
        Command::Check(a) => cmd_check(a),
        Command::Bench(a) => cmd_bench(a),
        Command::Reproduce(a) => cmd_reproduce(a),
        Command::Resolution(a) => cmd_resolution(a),
        Command::Status(a) => cmd_status(a),
        Command::StartPack(a) => cmd_start_pack(a),
    };
    match result {
        Ok(()) => ExitCode::SUCCESS,
        Err(e) => {
            // A stop that a signal asked for is not an error: said as it is, without the
            // command's "… failed" context.
            if let Some(stop) = e.downcast_ref::<slurry::interrupt::Interrupted>() {
                eprintln!("{stop}");
                return ExitCode::from(stop.signal.exit_status());
            }
            eprintln!("error: {e:#}");
            if e.downcast_ref::<CaseError>().is_some()
                || e.downcast_ref::<BadInput>().is_some()
                || e.downcast_ref::<slurry::run::BadResume>().is_some()
                || e.downcast_ref::<slurry::run::WouldOverwrite>().is_some()
                || e.downcast_ref::<slurry::io::lock::OutputRefused>().is_some()
                || e.downcast_ref::<slurry::io::checksum::Corrupt>().is_some()
            {
                ExitCode::from(EXIT_BAD_INPUT)
            } else {
                ExitCode::from(EXIT_FAILURE)
            }
        }
    }
}

/// A command-line problem found after parsing (exit status 2).
#[derive(Debug, thiserror::Error)]
#[error("{0}")]
struct BadInput(String);

/// The machine's hardware threads (`std::thread::available_parallelism`, which honours CPU
/// affinity and cgroup quotas; 1 when it cannot tell).
fn hardware_threads() -> usize {
    std::thread::available_parallelism().map_or(1, NonZeroUsize::get)
}

/// Refuses a thread count above the machine's (`--threads 100000` never returned).
fn check_threads(flag: &str, n: usize) -> Result<(), BadInput> {
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
fn thread_pool(threads: Option<NonZeroUsize>) -> Result<rayon::ThreadPool, BadInput> {
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
fn usable_out_dir(dir: &std::path::Path) -> Result<(), BadInput> {
    slurry::io::lock::check_output_path(dir, "--out").map_err(|e| BadInput(e.to_string()))?;
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

fn cmd_run(a: RunArgs) -> anyhow::Result<()> {
    let case = Case::from_file(&a.case)?;
    usable_out_dir(&a.out)?;
    let pool = thread_pool(a.threads)?;
    let opts = RunOptions {
        quiet: a.quiet,
        resume: a.resume,
        switch_contacts: a.switch_contacts,
        overwrite: a.overwrite,
    };
    let summary = pool
        .install(|| run_case(&case, &a.out, opts))
        .with_context(|| format!("run of {} failed", a.case.display()))?;
    if !a.quiet {
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

fn cmd_settle(a: SettleArgs) -> anyhow::Result<()> {
    let case = Case::from_file(&a.case)?;
    if !(a.speed.is_finite() && a.speed > 0.0) {
        return Err(BadInput(format!("--speed {}: must be positive and finite", a.speed)).into());
    }
    usable_out_dir(&a.out)?;
    let pool = thread_pool(a.threads)?;
    let opts = SettleOptions {
        speed: a.speed,
        check_every: a.check_every,
        min_steps: a.min_steps,
        max_steps: a.max_steps,
        quiet: a.quiet,
        checkpoint_every_s: slurry::settle::SETTLING_CHECKPOINT_EVERY_S,
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

fn cmd_reproduce(a: ReproduceArgs) -> anyhow::Result<()> {
    use slurry::reproduce::{self, ReproduceOptions};
    let names: Vec<String> = if a.all {
        reproduce::CASES.iter().map(|s| (*s).to_string()).collect()
    } else {
        let name = a.case.clone().unwrap_or_default();
        reproduce::paper_case(&name).map_err(|e| BadInput(e.to_string()))?;
        vec![name]
    };
    let scale = a.scale.unwrap_or(if a.quick { reproduce::QUICK_SCALE } else { reproduce::DEFAULT_SCALE });
    // Each case's (revolutions, cap): given, the smoke test's, or the paper's steady state.
    let schedules: Vec<(f64, Option<f64>)> = names
        .iter()
        .map(|name| match (a.revolutions, a.until_steady, a.quick) {
            (Some(r), cap, _) => (r, cap),
            (None, cap, true) => (reproduce::QUICK_REVOLUTIONS, cap),
            (None, None, false) => {
                let (r, cap) = reproduce::default_revolutions(name);
                (r, Some(cap))
            }
            (None, Some(cap), false) => (reproduce::default_revolutions(name).0, Some(cap)),
        })
        .collect();
    let mut checked = reproduce::check_scale(scale);
    for &(revolutions, cap) in &schedules {
        checked = checked
            .and_then(|()| reproduce::check_revolutions(revolutions))
            .and_then(|()| cap.map_or(Ok(()), |cap| reproduce::check_until_steady(cap, revolutions)));
    }
    checked
        .and_then(|()| a.contact_substeps.map_or(Ok(()), reproduce::check_contact_substeps))
        .and_then(|()| {
            a.lubrication_substeps
                .map_or(Ok(()), |m| reproduce::check_lubrication_substeps(m, a.lubrication_limiter))
        })
        .and_then(|()| a.mach_limit.map_or(Ok(()), reproduce::check_mach_limit))
        .map_err(BadInput)?;
    let contacts = reproduce::ContactOverrides {
        substeps: a.contact_substeps,
        lubrication_limiter: a.lubrication_limiter,
        lubrication_substeps: a.lubrication_substeps,
    };
    let pool = thread_pool(a.threads)?;
    let root = PathBuf::from("target").join("reproduce");
    let cache = a.cache.clone().unwrap_or_else(|| root.join("cache"));
    let summary_root = a.out.clone().unwrap_or_else(|| root.clone());
    if a.summary_only {
        let p = reproduce::summary::write_summary(&summary_root)?;
        eprintln!("summary of the six cases in {}", p.display());
        return Ok(());
    }
    if !a.quiet {
        for (name, &(revolutions, cap)) in names.iter().zip(&schedules) {
            eprintln!("{}", reproduce::announce(name, scale, revolutions, cap, a.quick));
        }
    }
    let out_of = |name: &str| match (&a.out, a.all) {
        (Some(o), true) => o.join(name),
        (Some(o), false) => o.clone(),
        (None, _) => root.join(name),
    };
    // Every case's directory before the first is run: with --all, a later case refused after
    // hours of the earlier ones would leave the summary unwritten.
    if !a.resume && !a.overwrite {
        for name in &names {
            slurry::run::check_fresh_start(&out_of(name).join("run"), "--resume", "--overwrite")?;
        }
    }
    for (name, &(revolutions, until_steady)) in names.iter().zip(&schedules) {
        let out = out_of(name);
        usable_out_dir(&out)?;
        let opts = ReproduceOptions {
            scale,
            revolutions,
            out: out.clone(),
            cache: cache.clone(),
            resume: a.resume,
            switch_contacts: a.switch_contacts,
            overwrite: a.overwrite,
            quiet: a.quiet,
            bed: match a.bed {
                BedArg::Dry => reproduce::BedMethod::default(),
                BedArg::Wet => reproduce::BedMethod::Wet,
            },
            contacts,
            mach_limit: a.mach_limit,
            until_steady,
            start_from: a.start_from.clone(),
        };
        let s = pool
            .install(|| reproduce::reproduce(name, &opts))
            .with_context(|| format!("reproduce {name} failed"))?;
        eprintln!(
            "{name}: done in {:.0} s ({} steps, {:.1} MLUPS); report in {}",
            s.wall_time_s,
            s.record.run.steps,
            s.record.run.mlups,
            s.report.display()
        );
    }
    if a.all {
        let p = reproduce::summary::write_summary(&summary_root)?;
        eprintln!("summary of the six cases in {}", p.display());
    }
    Ok(())
}

fn cmd_check(a: CheckArgs) -> anyhow::Result<()> {
    let case = Case::from_file(&a.case)?;
    print!("{}", case.describe());
    println!("{}: ok", a.case.display());
    Ok(())
}

fn parse_size(s: &str) -> anyhow::Result<slurry::lattice::Grid> {
    let parts: Vec<&str> = s.split('x').collect();
    let nums: Result<Vec<usize>, _> = parts.iter().map(|p| p.trim().parse::<usize>()).collect();
    match nums.as_deref() {
        Ok([n]) if *n >= 2 => Ok(slurry::lattice::Grid::new(*n, *n, *n)),
        Ok([x, y, z]) if *x >= 2 && *y >= 2 && *z >= 2 => Ok(slurry::lattice::Grid::new(*x, *y, *z)),
        _ => Err(BadInput(format!("--sizes: `{s}` is not N or NXxNYxNZ with every size >= 2")).into()),
    }
}

fn cmd_bench(a: BenchArgs) -> anyhow::Result<()> {
    use slurry::bench::{measure, BenchResult};
    if a.coupled {
        return cmd_bench_coupled(a);
    }
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
    println!(
        "{:>13} {:>4} {:>4} {:>3} {:>9} {:>9} {:>7} {:>7}",
        "grid", "prec", "coll", "thr", "MLUPS", "median", "GB/s", "isa"
    );
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
                    println!(
                        "{:>13} {:>4} {:>4} {:>3} {:>9.1} {:>9.1} {:>7.1} {:>7}",
                        format!("{}x{}x{}", g.nx, g.ny, g.nz),
                        r.precision,
                        r.collision,
                        r.threads,
                        r.mlups,
                        r.mlups_median,
                        r.gbs,
                        r.isa
                    );
                    results.push(r);
                }
            }
        }
    }
    if let Some(path) = a.json {
        if let Some(dir) = path.parent().filter(|d| !d.as_os_str().is_empty()) {
            std::fs::create_dir_all(dir).with_context(|| format!("cannot create {}", dir.display()))?;
        }
        let text = serde_json::to_string_pretty(&results)?;
        slurry::io::atomic_write_bytes(&path, text.as_bytes())
            .with_context(|| format!("cannot write {}", path.display()))?;
        println!("wrote {}", path.display());
    }
    Ok(())
}
