//! The `slurry` command line.
//!
//! ```text
//! slurry run CASE.toml --out DIR [--threads N] [--quiet]
//! slurry check CASE.toml
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

use slurry::case::{Case, CaseError, InitialKind};
use slurry::lattice::Face;
use slurry::lbm::Collision;
use slurry::run::{run_case, RunOptions};

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
    /// Validate a case file and print what it describes.
    Check(CheckArgs),
}

/// `slurry run`.
#[derive(Args, Debug)]
struct RunArgs {
    /// The case file (TOML; see docs/case-format.md).
    case: PathBuf,
    /// Output directory (created if needed; files of an earlier run are replaced).
    #[arg(long, value_name = "DIR")]
    out: PathBuf,
    /// Number of worker threads (default: all cores, or RAYON_NUM_THREADS).
    #[arg(long, value_name = "N")]
    threads: Option<NonZeroUsize>,
    /// No progress bar.
    #[arg(long)]
    quiet: bool,
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
    let result = match cli.command {
        Command::Run(a) => cmd_run(a),
        Command::Check(a) => cmd_check(a),
    };
    match result {
        Ok(()) => ExitCode::SUCCESS,
        Err(e) => {
            eprintln!("error: {e:#}");
            if e.downcast_ref::<CaseError>().is_some() || e.downcast_ref::<BadInput>().is_some() {
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

fn cmd_run(a: RunArgs) -> anyhow::Result<()> {
    let case = Case::from_file(&a.case)?;
    std::fs::create_dir_all(&a.out).map_err(|e| {
        BadInput(format!("--out {}: cannot create the output directory: {e}", a.out.display()))
    })?;
    let mut builder = rayon::ThreadPoolBuilder::new();
    if let Some(n) = a.threads {
        builder = builder.num_threads(n.get());
    }
    let pool =
        builder.build().map_err(|e| BadInput(format!("--threads: cannot build the thread pool: {e}")))?;
    let opts = RunOptions { quiet: a.quiet };
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

fn cmd_check(a: CheckArgs) -> anyhow::Result<()> {
    let case = Case::from_file(&a.case)?;
    print!("{}", describe(&case));
    println!("{}: ok", a.case.display());
    Ok(())
}

/// A human-readable summary of a valid case.
fn describe(c: &Case) -> String {
    use std::fmt::Write as _;
    let mut s = String::new();
    let g = c.grid();
    let padded = (g.nx + 2) * (g.ny + 2) * (g.nz + 2);
    let bytes = padded * 19 * c.fluid.precision.bytes();
    let _ = writeln!(
        s,
        "grid        {} x {} x {} = {} nodes ({} precision, ~{:.1} MiB of populations)",
        g.nx,
        g.ny,
        g.nz,
        g.nodes(),
        c.fluid.precision.name(),
        bytes as f64 / (1024.0 * 1024.0)
    );
    let p = c.fluid_params();
    let model = match p.collision {
        Collision::Bgk => "BGK".to_string(),
        Collision::Trt { magic } => format!("TRT (magic {magic})"),
    };
    let _ = writeln!(s, "fluid       nu = {}, tau = {}, {model}", p.nu, p.tau());
    let _ = writeln!(s, "body force  [{}, {}, {}]", p.body_force[0], p.body_force[1], p.body_force[2]);
    for face in Face::ALL {
        let b = c.boundaries.get(face);
        let _ = write!(s, "{:<11} {b}", face.name());
        if let slurry::case::BoundarySpec::MovingWall(v) = b {
            let _ = write!(s, "  (wall Mach {:.4})", slurry::case::mach(v));
        }
        s.push('\n');
    }
    match c.initial.kind {
        InitialKind::Uniform => {
            let v = c.initial.velocity.unwrap_or([0.0; 3]);
            let _ = writeln!(
                s,
                "initial     uniform, density {}, velocity [{}, {}, {}]",
                c.initial.density, v[0], v[1], v[2]
            );
        }
        InitialKind::TaylorGreen => {
            let _ = writeln!(
                s,
                "initial     Taylor-Green, density {}, amplitude {}",
                c.initial.density,
                c.initial.amplitude.unwrap_or(0.0)
            );
        }
    }
    let _ = writeln!(
        s,
        "run         {} steps, output every {} ({} rows), Mach limit {}",
        c.run.steps,
        c.run.output_every,
        c.output_rows(),
        c.run.mach_limit
    );
    s
}
