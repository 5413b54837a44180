//! The `slurry` command line: the solver's commands (`slurry::cli`) and the paper's
//! reproduction's (`slurry_reproduce::cli`).
//!
//! ```text
//! slurry run CASE.toml --out DIR [--threads N] [--quiet] [--resume [--switch-contacts] | --overwrite]
//! slurry settle CASE.toml --out DIR [--speed V] [--check-every N] [--min-steps N] [--max-steps N]
//! slurry check CASE.toml
//! slurry bench [--sizes 128,256x256x240] [--threads 1,2] [--json FILE] [--coupled ...]
//! slurry reproduce CASE|--all [--scale S] [--revolutions R] [--until-steady CAP] [--quick] [--out DIR] [--resume | --overwrite]
//! slurry resolution RUN_DIR... [--out FILE]
//! slurry status OUT...
//! slurry start-pack OUT PACK [--at T]
//! ```
//!
//! Exit status: 0 on success; 2 for bad input (case file, command line); 1 for numerical
//! trouble or an output failure (`slurry::cli::execute`).

use std::process::ExitCode;

use clap::{Parser, Subcommand};

use slurry::cli as solver;
use slurry_reproduce::cli as paper;

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
    Run(solver::RunArgs),
    /// Let a case's particles settle into a bed under gravity (no impeller) and store it.
    Settle(solver::SettleArgs),
    /// Validate a case file and print what it describes.
    Check(solver::CheckArgs),
    /// Measure the fused kernel's throughput (MLUPS) on periodic boxes, or with --coupled the
    /// paper's cases' coupled step per phase.
    Bench(paper::BenchArgs),
    /// Reproduce one of the paper's stirred cases (or all six): bed, run, statistics, figures, report.
    Reproduce(paper::ReproduceArgs),
    /// The resolution study of one case: its reproductions at several scales side by side, with
    /// the observed order and Richardson estimate from the three finest steady ones (runs of one
    /// scale from different starts: their mean is the scale's level, their spread the start's
    /// effect).
    Resolution(paper::ResolutionArgs),
    /// Where a reproduction stands, from its files (while it runs, or its archive): progress,
    /// speed and time left, ⟨z_p⟩/H by 10 revolutions, the steady test now, the power numbers.
    Status(paper::StatusArgs),
    /// Keep the end of a reproduction as a start pack: its manifest, its case and the few frames
    /// of its last 20 revolutions that `--start-from` would choose from (under 1 MB, for
    /// its archive), so that `--start-from PACK` works after the output directory is gone
    /// (`--at T`: of the 20 revolutions ending at its time T instead, an earlier state).
    StartPack(paper::StartPackArgs),
    /// A run's state at its checkpoint as a state pack: density and velocity (f32, compressed)
    /// with every body's exact state, checksummed, a few MB; `run --from-pack` continues from
    /// it (close to the run's own continuation, not bitwise).
    StatePack(solver::StatePackArgs),
}

fn main() -> ExitCode {
    let cli = Cli::parse();
    solver::execute(|| match cli.command {
        Command::Run(a) => solver::cmd_run(a),
        Command::Settle(a) => solver::cmd_settle(a),
        Command::Check(a) => solver::cmd_check(a),
        Command::Bench(a) => paper::cmd_bench(&a),
        Command::Reproduce(a) => paper::cmd_reproduce(a),
        Command::Resolution(a) => paper::cmd_resolution(a),
        Command::Status(a) => paper::cmd_status(a),
        Command::StartPack(a) => paper::cmd_start_pack(a),
        Command::StatePack(a) => solver::cmd_state_pack(a),
    })
}
