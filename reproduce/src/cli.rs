//! The reproduction's commands of the `slurry` binary: `reproduce`, `status`, `resolution`,
//! `start-pack`, and `bench` (the fluid kernel of `slurry::cli`, or with `--coupled` the
//! paper's cases' coupled step). Their run options are the solver's ([`RunControl`]); errors
//! become exit statuses as for the solver's commands (`slurry::cli::execute`).

use std::num::NonZeroUsize;
use std::path::PathBuf;

use anyhow::Context;
use clap::Args;

use slurry::cli::{thread_pool, usable_out_dir, BadInput, RunControl};

/// `slurry start-pack`.
#[derive(Args, Debug)]
pub struct StartPackArgs {
    /// The output directory of `slurry reproduce` (its `--out`), running or finished.
    #[arg(value_name = "OUT")]
    pub run: PathBuf,
    /// The pack's directory (created; its files are replaced), e.g. the archive's `start/`.
    #[arg(value_name = "PACK")]
    pub pack: PathBuf,
    /// Take the frames from the 20 revolutions that end at the run's time T (in revolutions
    /// t N, the ramp counting 1, as its report's Figure 5), not from its last 20: an earlier,
    /// lower state, to approach a finer scale's level from below.
    #[arg(long, value_name = "T")]
    pub at: Option<f64>,
}

/// `slurry status`.
#[derive(Args, Debug)]
pub struct StatusArgs {
    /// Output directories of `slurry reproduce` (its `--out`), or archives of them.
    #[arg(required = true, value_name = "OUT")]
    pub dirs: Vec<PathBuf>,
}

/// `slurry resolution`.
#[derive(Args, Debug)]
pub struct ResolutionArgs {
    /// The output directories of `slurry reproduce` runs of one case at distinct scales (or
    /// their archives): each holds the report's `statistics.json`.
    #[arg(required = true, value_name = "RUN_DIR")]
    pub runs: Vec<PathBuf>,
    /// Also write the table (Markdown) to this file, atomically.
    #[arg(long, value_name = "FILE")]
    pub out: Option<PathBuf>,
}

/// `slurry reproduce`.
#[derive(Args, Debug)]
pub struct ReproduceArgs {
    /// The case: disk-ld1, disk-ld2, disk-ld4, pbt-ld1, pbt-ld2 or pbt-ld4.
    #[arg(required_unless_present = "all", conflicts_with = "all")]
    pub case: Option<String>,
    /// All six cases, one after the other, then their cross-case summary (`OUT/summary/`:
    /// Figures 5–9 with the three ℓ/d of each impeller on one plot, and the table).
    #[arg(long)]
    pub all: bool,
    /// With --all: run nothing, only redraw the cross-case summary from the cases already
    /// run under the output directory (e.g. after one was resumed on its own).
    #[arg(long, requires = "all")]
    pub summary_only: bool,
    /// Scale s of the system, 0.25 ≤ s ≤ 1 (1: the paper's 251 × 251 × 240 with d = 12;
    /// 0.5: d = 6); default 0.25 (d = 3; the smallest at which the random placement fits the
    /// paper's particles in every case).
    #[arg(long, allow_negative_numbers = true)]
    pub scale: Option<f64>,
    /// Impeller revolutions after the ramp (> 0), run as a fixed length unless --until-steady
    /// is given too. Without either, the run goes to the paper's steady state: 100 revolutions
    /// (200 for pbt-ld1, the paper's "more than 200"), then on as with --until-steady 200 (300
    /// for pbt-ld1); 1–2.5 h per case on 2 cores at the default scale. 0.25 with --quick.
    #[arg(long, allow_negative_numbers = true)]
    pub revolutions: Option<f64>,
    /// A short smoke-test run (scale 0.25, 0.25 revolutions after the ramp): about a minute on 2 cores.
    #[arg(long)]
    pub quick: bool,
    /// Output directory (a sub-directory per case with --all); default target/reproduce/CASE.
    #[arg(long, value_name = "DIR")]
    pub out: Option<PathBuf>,
    /// Cache of settled beds; default target/reproduce/cache.
    #[arg(long, value_name = "DIR")]
    pub cache: Option<PathBuf>,
    /// How the run starts, threads, progress (as `slurry run`).
    #[command(flatten)]
    pub control: RunControl,
    /// Contact sub-steps per fluid step of the stirred run, 1 … 1024 (default: the case's, 8);
    /// to measure a cheaper contact scheme against the default. The bed is settled with 8.
    #[arg(long, value_name = "N")]
    pub contact_substeps: Option<usize>,
    /// Turn the lubrication limiter on in the stirred run (`[contacts] lubrication_limiter`:
    /// stable at fewer sub-steps; not the default: with 2 sub-steps ⟨z_p⟩/H is 0.012 higher
    /// after 100 revolutions at s = 1/4, `reproduce/JOURNAL.md`, "A cheaper contact scheme").
    #[arg(long)]
    pub lubrication_limiter: bool,
    /// Lubrication sub-steps per contact sub-step in the stirred run, 1 … 1024
    /// (`[contacts] lubrication_substeps`, default 1): the lubrication frozen as a linear map
    /// of the bodies' velocities at each contact evaluation and stepped this many times
    /// (cheaper at fewer --contact-substeps; not the default: with 2 × 4 ⟨z_p⟩/H is 0.003–0.0075
    /// lower at s = 1/4, `reproduce/JOURNAL.md`, "Lubrication sub-steps").
    #[arg(long, value_name = "M")]
    pub lubrication_substeps: Option<usize>,
    /// Integrate Table 1's lubrication damping implicitly in the stirred run (`[contacts]
    /// damping = "implicit"`: backward Euler, one sparse solve per contact sub-step; stable at
    /// any sub-step count, so give --contact-substeps too, e.g. 2). Not the default: the
    /// explicit scheme with 8 sub-steps is the paper's. Excludes --lubrication-limiter and
    /// --lubrication-substeps.
    #[arg(long, conflicts_with_all = ["lubrication_limiter", "lubrication_substeps"])]
    pub implicit_damping: bool,
    /// How the bed is settled: `dry` (no fluid, amplified gravity against a linear drag;
    /// minutes) or `wet` (in the fluid under the case's gravity, as the paper does; about
    /// 20 min at the default scale, 16× that at s = 1/2). Each is cached separately.
    #[arg(long, value_enum, default_value_t = BedArg::Dry)]
    pub bed: BedArg,
    /// Stop the stirred run when the Mach number |u|/c_s exceeds this anywhere, 0 < L ≤ 1
    /// (default 0.3). Only a health check: a run it stopped can be resumed (--resume) with a
    /// higher one, and the numbers do not depend on it.
    #[arg(long, value_name = "L", allow_negative_numbers = true)]
    pub mach_limit: Option<f64>,
    /// Run to steady state: after --revolutions, go on in legs of 10 revolutions until the
    /// report's steady test passes (drift of ⟨z_p⟩/H over the last 20 revolutions at most
    /// 0.005, and its standard error too), to at most CAP revolutions
    /// after the ramp (CAP ≥ --revolutions; --revolutions defaults to 100 here, 200 for
    /// pbt-ld1). `--revolutions 100 --until-steady 200` is the default run.
    #[arg(long, value_name = "CAP", allow_negative_numbers = true)]
    pub until_steady: Option<f64>,
    /// Start from the particles of another reproduction of the same case (its output
    /// directory, at any scale) instead of the settled bed: a frame of its last 20 revolutions
    /// with the impeller where this run's starts, positions scaled to this grid, at rest; the
    /// choice is written to `start.json`. For a half-scale case, started from the steady state
    /// of a coarser run: the suspension then approaches its level from above. Or a state pack
    /// (`slurry state-pack`) of a run of this case at this scale: that run continued, its flow
    /// and particles as packed, to --revolutions after the ramp (more than the pack's). A
    /// resumed run needs the same directory or pack.
    #[arg(long, value_name = "RUN", conflicts_with_all = ["all", "bed"])]
    pub start_from: Option<PathBuf>,
    /// Which processor steps the stirred run: `cpu`, or `gpu` (the device backend through
    /// Vulkan: the fluid and the immersed boundary on the device, the contacts and the bodies
    /// on the host; f32 cases, which the paper's are). The bed is settled on the CPU either
    /// way; a checkpoint of either continues on the other.
    #[arg(long, value_name = "DEVICE", value_parser = ["cpu", "gpu"], default_value = "cpu")]
    pub device: String,
}

/// `slurry reproduce --bed`.
#[derive(Clone, Copy, Debug, PartialEq, Eq, clap::ValueEnum)]
pub enum BedArg {
    /// Settled without fluid.
    Dry,
    /// Settled in the fluid.
    Wet,
}

/// `slurry resolution`: the table on stdout (and in `--out`). Runs that cannot be read, or
/// that are not one case at distinct scales, are bad input (exit status 2).
///
/// # Errors
/// Runs that cannot be read or compared (bad input), or the table cannot be written.
pub fn cmd_resolution(a: ResolutionArgs) -> anyhow::Result<()> {
    let text = crate::resolution::write_resolution(&a.runs, None).map_err(|e| BadInput(format!("{e:#}")))?;
    print!("{text}");
    if let Some(out) = &a.out {
        slurry::io::atomic_write_bytes(out, text.as_bytes())
            .with_context(|| format!("cannot write {}", out.display()))?;
    }
    Ok(())
}

/// `slurry start-pack`: the pack, then one line on what it holds.
///
/// # Errors
/// The run cannot be packed (bad input).
pub fn cmd_start_pack(a: StartPackArgs) -> anyhow::Result<()> {
    let pack =
        crate::start::write_start_pack(&a.run, &a.pack, a.at).map_err(|e| BadInput(format!("{e:#}")))?;
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
///
/// # Errors
/// A directory that cannot be read.
pub fn cmd_status(a: StatusArgs) -> anyhow::Result<()> {
    let mut bad = Vec::new();
    for (k, dir) in a.dirs.iter().enumerate() {
        if k > 0 {
            println!();
        }
        match crate::status::status(dir) {
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

/// `slurry bench`: the fused fluid kernel (`slurry::cli::BenchArgs`) or, with `--coupled`, the
/// coupled step of the paper's cases.
#[derive(Args, Debug)]
pub struct BenchArgs {
    /// The fluid kernel's options (`--threads`: with --coupled, the largest is used).
    #[command(flatten)]
    pub fluid: slurry::cli::BenchArgs,
    /// Measure the coupled step of the paper's cases instead (per phase, beside the fluid-only
    /// step of the same grid; beds from the reproduction's cache, made on first use). The
    /// environment variable SLURRY_BENCH_DENSE=1 (or 0) forces the whole-grid (or the band) path
    /// of the immersed boundary, which gives the same bits, to compare their costs.
    #[arg(long)]
    pub coupled: bool,
    /// With --coupled: the cases, comma separated (default: all six).
    #[arg(long, value_delimiter = ',')]
    pub cases: Vec<String>,
    /// With --coupled: the scales, comma separated.
    #[arg(long, value_delimiter = ',', default_values_t = [0.25, 0.5, 1.0], allow_negative_numbers = true)]
    pub scales: Vec<f64>,
    /// With --coupled: steps before timing (the impeller's ramp has started).
    #[arg(long, default_value_t = 40)]
    pub warmup: u64,
    /// With --coupled: timed steps.
    #[arg(long, default_value_t = 20)]
    pub steps: u64,
    /// With --coupled: the skin of the contact pair list, lattice units (default: the
    /// library's, `DEFAULT_SKIN` = 0.15). The loads do not depend on it, only the cost.
    #[arg(long)]
    pub skin: Option<f64>,
    /// With --coupled: contact sub-steps per fluid step, 1 … 1024 (default: the case's, 8).
    #[arg(long)]
    pub contact_substeps: Option<usize>,
    /// With --coupled: turn the lubrication limiter on (`[contacts] lubrication_limiter`), so
    /// that fewer sub-steps stay stable.
    #[arg(long)]
    pub lubrication_limiter: bool,
    /// With --coupled: lubrication sub-steps per contact sub-step, 1 … 1024
    /// (`[contacts] lubrication_substeps`, default 1).
    #[arg(long, value_name = "M")]
    pub lubrication_substeps: Option<usize>,
    /// With --coupled: integrate the contact damping implicitly (`[contacts] damping =
    /// "implicit"`: backward Euler, one sparse solve per sub-step; set --contact-substeps too,
    /// e.g. 2).
    #[arg(long)]
    pub implicit_damping: bool,
    /// With --coupled: start from this checkpoint of a reproduction of the case (one case, one
    /// scale; e.g. `run/checkpoint.h5` of a run at steady state) instead of the settled bed.
    #[arg(long, value_name = "CHECKPOINT")]
    pub from: Option<PathBuf>,
}

/// `slurry bench`: the fluid kernel (`slurry::cli::cmd_bench`), or with `--coupled` the paper's
/// cases' coupled step.
///
/// # Errors
/// Bad flags, a failed measurement, or the JSON file cannot be written.
pub fn cmd_bench(a: &BenchArgs) -> anyhow::Result<()> {
    if a.coupled {
        cmd_bench_coupled(a)
    } else {
        slurry::cli::cmd_bench(&a.fluid)
    }
}

/// `slurry bench --coupled`: the paper's cases at each scale, one thread count (the first of
/// `--threads`, default 2), f32.
///
/// # Errors
/// Bad flags, a failed case, or the JSON file cannot be written.
fn cmd_bench_coupled(a: &BenchArgs) -> anyhow::Result<()> {
    use crate::bench::{bench_case, CoupledBench};
    let cases: Vec<String> = if a.cases.is_empty() {
        crate::paper_cases().iter().map(|c| c.name.to_string()).collect()
    } else {
        a.cases.clone()
    };
    for &s in &a.scales {
        if let Err(e) = crate::check_scale(s) {
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
        crate::check_contact_substeps(n).map_err(BadInput)?;
    }
    if let Some(m) = a.lubrication_substeps {
        crate::check_lubrication_substeps(m, a.lubrication_limiter).map_err(BadInput)?;
    }
    let contact = crate::bench::ContactOptions {
        skin: a.skin,
        substeps: a.contact_substeps,
        limiter: a.lubrication_limiter,
        lubrication_substeps: a.lubrication_substeps,
        implicit_damping: a.implicit_damping,
    };
    let threads = a.fluid.threads.iter().copied().max().unwrap_or(2);
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
            if let Some(path) = &a.fluid.json {
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

/// `slurry reproduce`: one case or all six, each announced, then run from its bed (or its
/// start) to its report; with `--all`, the cross-case summary.
///
/// # Errors
/// Bad input (flags, output directories), or a failed case.
pub fn cmd_reproduce(a: ReproduceArgs) -> anyhow::Result<()> {
    let names: Vec<String> = if a.all {
        crate::CASES.iter().map(|s| (*s).to_string()).collect()
    } else {
        let name = a.case.clone().unwrap_or_default();
        crate::paper_case(&name).map_err(|e| BadInput(e.to_string()))?;
        vec![name]
    };
    let scale = a.scale.unwrap_or(if a.quick { crate::QUICK_SCALE } else { crate::DEFAULT_SCALE });
    // Each case's (revolutions, cap): given, the smoke test's, or the paper's steady state.
    let schedules: Vec<(f64, Option<f64>)> = names
        .iter()
        .map(|name| match (a.revolutions, a.until_steady, a.quick) {
            (Some(r), cap, _) => (r, cap),
            (None, cap, true) => (crate::QUICK_REVOLUTIONS, cap),
            (None, None, false) => {
                let (r, cap) = crate::default_revolutions(name);
                (r, Some(cap))
            }
            (None, Some(cap), false) => (crate::default_revolutions(name).0, Some(cap)),
        })
        .collect();
    let mut checked = crate::check_scale(scale);
    for &(revolutions, cap) in &schedules {
        checked = checked
            .and_then(|()| crate::check_revolutions(revolutions))
            .and_then(|()| cap.map_or(Ok(()), |cap| crate::check_until_steady(cap, revolutions)));
    }
    checked
        .and_then(|()| a.contact_substeps.map_or(Ok(()), crate::check_contact_substeps))
        .and_then(|()| {
            a.lubrication_substeps
                .map_or(Ok(()), |m| crate::check_lubrication_substeps(m, a.lubrication_limiter))
        })
        .and_then(|()| a.mach_limit.map_or(Ok(()), crate::check_mach_limit))
        .map_err(BadInput)?;
    a.control.check_switch_contacts(a.start_from.as_ref().map(|_| "--start-from"))?;
    let contacts = crate::ContactOverrides {
        substeps: a.contact_substeps,
        lubrication_limiter: a.lubrication_limiter,
        lubrication_substeps: a.lubrication_substeps,
        implicit_damping: a.implicit_damping,
    };
    let pool = thread_pool(a.control.console.threads)?;
    let root = PathBuf::from("target").join("reproduce");
    let cache = a.cache.clone().unwrap_or_else(|| root.join("cache"));
    let summary_root = a.out.clone().unwrap_or_else(|| root.clone());
    if a.summary_only {
        let p = crate::summary::write_summary(&summary_root)?;
        eprintln!("summary of the six cases in {}", p.display());
        return Ok(());
    }
    let out_of = |name: &str| match (&a.out, a.all) {
        (Some(o), true) => o.join(name),
        (Some(o), false) => o.clone(),
        (None, _) => root.join(name),
    };
    if !a.control.console.quiet {
        for (name, &(revolutions, cap)) in names.iter().zip(&schedules) {
            let done = crate::revolutions_done(
                name,
                scale,
                &out_of(name),
                a.control.resume,
                a.start_from.as_deref(),
            );
            eprintln!("{}", crate::announce(name, scale, revolutions, cap, a.quick, done));
        }
    }
    // Every case's directory before the first is run: with --all, a later case refused after
    // hours of the earlier ones would leave the summary unwritten.
    if !a.control.resume && !a.control.overwrite {
        for name in &names {
            slurry::run::check_fresh_start(&out_of(name).join("run"), "--resume", "--overwrite")?;
        }
    }
    for (name, &(revolutions, until_steady)) in names.iter().zip(&schedules) {
        let out = out_of(name);
        usable_out_dir(&out)?;
        let opts = crate::ReproduceOptions {
            scale,
            revolutions,
            out: out.clone(),
            cache: cache.clone(),
            resume: a.control.resume,
            switch_contacts: a.control.switch_contacts,
            overwrite: a.control.overwrite,
            quiet: a.control.console.quiet,
            bed: match a.bed {
                BedArg::Dry => crate::BedMethod::default(),
                BedArg::Wet => crate::BedMethod::Wet,
            },
            contacts,
            mach_limit: a.mach_limit,
            until_steady,
            start_from: a.start_from.clone(),
            gpu: a.device == "gpu",
        };
        let s = pool
            .install(|| crate::reproduce(name, &opts))
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
        let p = crate::summary::write_summary(&summary_root)?;
        eprintln!("summary of the six cases in {}", p.display());
    }
    Ok(())
}
