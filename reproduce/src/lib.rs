//! # slurry-reproduce
//!
//! The reproduction of Derksen (2020), "Agitating cylindrical particles in laminar liquid
//! flow", with the `slurry` solver library: the paper's six stirred cases from the bed to the
//! report (`slurry reproduce CASE`, `cargo xtask reproduce CASE`), the paper's statistics
//! ([`stats`]), the cross-case summary, the resolution study, start packs, `slurry status`,
//! and the `slurry` command line itself ([`cli`]: the reproduction's commands beside the
//! solver's, `slurry::cli`).
//!
//! A user's own case needs nothing from this crate: `slurry::run::run_case` and
//! `slurry run CASE.toml` are the solver's.
//!
//! The cases are the folders of `reproduce/` (`disk-ld1` … `pbt-ld4`): each holds the case
//! file at the paper's scale (`case.toml`, physics.md §1–2) and the paper's values with their
//! acceptance bands (`paper.toml`); both are compiled into the binary, so the command works
//! from any directory.
//!
//! # Scaling ([`scale_case`])
//! A run at scale `s` keeps every dimensionless group of the paper and the tip Mach number:
//! the grid is `round(s · (251, 251, 240))`, lengths (`D`, `d`, `ℓ`, the impeller's set
//! dimensions) are multiplied by `s`, and with the tip speed `π N D` and `Re = N D²/ν` fixed,
//! `N → N/s`, `ν → ν s`; the Shields number `N² D²/(g Δρ/ρ d)` then fixes `g → g/s`, and the
//! ramp (half a revolution) takes `4000 s` steps. The particle count is the paper's (so
//! `⟨φ⟩ = 0.148` up to the rounding of the grid). The contact parameters of Table 1 and the
//! marker spacing are in lattice units and stay as they are (next section).
//!
//! # Contacts at reduced scale (a decision; `reproduce/JOURNAL.md`)
//! Table 1's lengths (`δ0 = λ = 0.5`, `δ_d = 1`, `δ_sat = 0.2`) are lattice units: `d/24 … d/12`
//! at the paper's `d = 12`, `d/6 … d/3` at `s = 1/4`. Scaling them with `d` is bounded below
//! by what the markers resolve, and that bound binds at every `s < 1`:
//! - **`λ` and `δ0`**: markers are `h = 0.7` apart at every scale (the IBM's kernel is in
//!   lattice units, so is its marker spacing). A marker pair interacts only if its tangential
//!   offset is below `λ`, so a flat face has `Σ_j w ≈ πλ²/(3h²)` partners per marker: 0.53 at
//!   `λ = 0.5`, 0.03 at `λ = s · 0.5 = 0.125`. Below `λ ≈ h/√2` the force depends on how the
//!   two marker lattices happen to be aligned, and an edge can slip between markers; `δ0`
//!   (the elastic range, which must stop an approach within a marker spacing) likewise.
//! - **`δ_d` and `δ_sat`** stand for the lubrication the grid does not resolve, which starts
//!   at gaps of about one lattice spacing whatever `d` is: they stay in lattice units.
//! - **`k`, `kⁿ`, `kᵗ`** then stay too: with the ranges fixed, the sub-grid lubrication
//!   `kⁿ (1/δ − 1/δ_d)` continues the resolved one at the gap where the grid stops resolving it.
//!
//! So Table 1 is used as printed at every scale. The price at `s = 1/4` (`d = 3`): touching
//! surfaces rest about `δ0 = 0.5 = d/6` apart (`d/24` in the paper), so the settled bed is
//! looser and higher in units of `d`, and nearly every marker pair of two neighbours is
//! within reach (the contacts are then half of the coupled step). This is one of the reasons
//! why `s = 1/4` results are a resolution study's coarsest point, not a reproduction.
//!
//! In units of the flow (a revolution is `4000 s` steps), Table 1 as printed keeps the
//! contacts' time scales within a factor of two of the paper's: per revolution the stiffest
//! body's contacts at `s = 1/4` are about twice as damped and 0.6 times as stiff as at
//! `s = 1` (the measured rates are tabulated in `reproduce/JOURNAL.md`, "Contacts at reduced
//! scale"), so `k, kⁿ, kᵗ` are not rescaled either.
//!
//! # Pipeline ([`reproduce`])
//! 1. **Bed**: the case's seeded random placement in the whole box, settled dry
//!    ([`slurry::settle::dry_bed`], the default) or in the fluid under the case's gravity
//!    (`--bed wet`, [`slurry::settle::wet_bed`], as the paper does), with no impeller. The bed is cached under
//!    `CACHE/beds/<case>-<key>/` by a hash of everything it depends on (the scaled case
//!    without its run settings and impeller, and the settling options), and reused. A wet
//!    settling (hours at `s = 1/2`) keeps its checkpoint in that directory every 10 minutes
//!    and resumes from it when started again (any `reproduce` of the case with `--bed wet`);
//!    the checkpoint is removed once the bed is stored.
//! 2. **Stirred run**: the bed's particles as explicit particles, the impeller inserted,
//!    the ramp (half a revolution) and `R` revolutions, by [`slurry::run::run_case`]:
//!    checkpoints every few revolutions (atomic), `--resume` bitwise identical, progress
//!    with revolutions, `⟨z_p⟩/H`, `Po`, MLUPS and the time left. With `--until-steady CAP`
//!    the run goes on past `R` in legs of [`STEADY_CHECK_REVOLUTIONS`], each a resume of the
//!    last in the same process (so bitwise the run it continues), until the report's steady
//!    test passes on the particle history ([`report::steady_test`]) or `CAP` revolutions are
//!    done; the manifest records the cap and where the run stopped.
//! 3. **Statistics, figures, report** ([`report`]): from `timeseries.csv`, `particles.h5`
//!    and `fields.h5` (and the field snapshots at 10 and 90 revolutions), deterministic,
//!    written atomically.
//! 4. With `--all`, the **cross-case summary** ([`summary`]): the paper's Figures 5–9 with
//!    the three aspect ratios of each impeller on one plot, and one table of the six cases.

#![warn(missing_docs)]

mod announce;
pub mod bench;
pub mod cli;
pub mod manifest;
mod options;
pub mod report;
pub mod resolution;
pub mod start;
pub mod stats;
pub mod status;
pub mod summary;

pub use announce::announce;
pub use options::{
    check_contact_substeps, check_lubrication_substeps, check_mach_limit, check_revolutions, check_scale,
    ContactOverrides, CONTACT_SUBSTEPS_RANGE,
};

use std::fmt::Write as _;
use std::path::{Path, PathBuf};
use std::time::Instant;

use anyhow::Context;
use serde::{Deserialize, Serialize};

use slurry::case::Case;
use slurry::io::atomic_write_bytes;
use slurry::run::{run_case, RunOptions, RunSummary};
use slurry::settle::{
    dry_bed, remove_settling_checkpoint, wet_bed, Bed, DryBedOptions, SettleOptions, SETTLING_CHECKPOINT,
    SETTLING_CHECKPOINT_EVERY_S,
};

/// The paper's cases, in the order of `--all`.
pub const CASES: [&str; 6] = ["disk-ld1", "disk-ld2", "disk-ld4", "pbt-ld1", "pbt-ld2", "pbt-ld4"];

/// The default scale: `d = 3`, 63 × 63 × 60 nodes, the smallest at which every case places
/// its particles. The coupled step takes 25–40 ms here on 2 cores
/// (`benches/results/2026-11-24-coupled-s0.25-after-ramp.json`; the contacts of the bed are
/// half of it; 26–60 ms over whole runs, as the shared VM's speed varies).
pub const DEFAULT_SCALE: f64 = 0.25;
/// The smallest scale: below it the random placement cannot fit the paper's particles
/// (`--scale 0.2` placed only 937 of disk-ld2's 1644 after 15 s); 1/4 places all six cases
/// (`every_case_places_its_particles_at_the_default_scale`).
pub const MIN_SCALE: f64 = 0.25;
/// The largest scale: the paper's.
pub const MAX_SCALE: f64 = 1.0;

/// The default run of a case, `(R, CAP)` as in `--revolutions R --until-steady CAP`, when
/// neither is given: the paper's dynamic steady state. The paper's statements hold after
/// "at least 100 impeller revolutions" and "more than 200 revolutions for the combination
/// PBT and ℓ/d = 1" (its Results section), so `R` is 100, 200 for `pbt-ld1`; after `R` the
/// run goes on in legs of [`STEADY_CHECK_REVOLUTIONS`] until the report's steady test passes,
/// at most to `CAP`. At the default scale on 2 cores that is 1–2.5 hours per case (pbt-ld2's
/// archived trajectory passes the current test at 150 revolutions; 26–60 ms per step), not
/// the 30 minutes we aim for: the coupled step's particle side is the cost
/// (`benches/results/README.md`).
pub fn default_revolutions(case: &str) -> (f64, f64) {
    if case == "pbt-ld1" {
        (200.0, 300.0)
    } else {
        (100.0, 200.0)
    }
}
/// `--quick`: scale (the default's: at 1/5 the random placement cannot fit the paper's 822
/// cylinders of `ℓ/d = 2`).
pub const QUICK_SCALE: f64 = 0.25;
/// `--quick`: revolutions after the ramp (with the half-revolution ramp: 0.75 revolutions).
pub const QUICK_REVOLUTIONS: f64 = 0.25;
/// Output rows (and particle frames) per revolution.
pub const OUTPUTS_PER_REVOLUTION: f64 = 20.0;
/// Revolutions between checkpoints.
pub const CHECKPOINT_REVOLUTIONS: f64 = 0.5;

/// One of the paper's cases: its name, case file and paper values (compiled in).
#[derive(Clone, Copy, Debug)]
pub struct PaperCase {
    /// Folder name under `reproduce/`, e.g. `"pbt-ld2"`.
    pub name: &'static str,
    /// `reproduce/<name>/case.toml`: the case at the paper's scale.
    pub case_toml: &'static str,
    /// `reproduce/<name>/paper.toml`: the paper's values and acceptance bands.
    pub paper_toml: &'static str,
}

macro_rules! paper_case {
    ($name:literal) => {
        PaperCase {
            name: $name,
            case_toml: include_str!(concat!("../", $name, "/case.toml")),
            paper_toml: include_str!(concat!("../", $name, "/paper.toml")),
        }
    };
}

/// Every case of [`CASES`].
pub fn paper_cases() -> [PaperCase; 6] {
    [
        paper_case!("disk-ld1"),
        paper_case!("disk-ld2"),
        paper_case!("disk-ld4"),
        paper_case!("pbt-ld1"),
        paper_case!("pbt-ld2"),
        paper_case!("pbt-ld4"),
    ]
}

/// The case called `name`.
///
/// # Errors
/// An unknown name (the message lists the known ones).
pub fn paper_case(name: &str) -> anyhow::Result<PaperCase> {
    paper_cases()
        .into_iter()
        .find(|c| c.name == name)
        .ok_or_else(|| anyhow::anyhow!("unknown case '{name}': the cases are {}", CASES.join(", ")))
}

impl PaperCase {
    /// The case at the paper's scale (parsed, not placed: its random particles fill the whole
    /// box, impeller included, and are settled before the impeller goes in).
    ///
    /// # Errors
    /// A syntax or key error in the compiled-in file (a defect of this repository).
    pub fn case(&self) -> anyhow::Result<Case> {
        Case::parse_unchecked(self.case_toml)
            .map_err(|kind| anyhow::anyhow!("reproduce/{}/case.toml: {kind}", self.name))
    }

    /// The paper's values and bands.
    ///
    /// # Errors
    /// A syntax or key error in the compiled-in file (a defect of this repository).
    pub fn paper(&self) -> anyhow::Result<report::PaperValues> {
        toml::from_str(self.paper_toml).with_context(|| format!("reproduce/{}/paper.toml", self.name))
    }
}

/// Scales a case at the paper's scale to scale `s` (module docs). `run` is left as it is.
///
/// # Errors
/// `s` not finite or outside `[MIN_SCALE, MAX_SCALE]` ([`check_scale`]); a case without
/// `[impeller]`.
pub fn scale_case(case: &Case, s: f64) -> anyhow::Result<Case> {
    check_scale(s).map_err(anyhow::Error::msg)?;
    let mut c = case.clone();
    let n = |v: usize| ((v as f64) * s).round().max(4.0) as usize;
    c.domain.nx = n(case.domain.nx);
    c.domain.ny = n(case.domain.ny);
    c.domain.nz = n(case.domain.nz);
    c.fluid.nu = Some(case.nu() * s);
    c.fluid.tau = None;
    c.gravity = case.gravity.map(|g| g.map(|x| x / s));
    for r in &mut c.random_particles {
        r.diameter *= s;
        r.length = r.length.map(|l| l * s);
        r.region = r.region.map(|reg| reg.map(|p| p.map(|x| (x + 0.5) * s - 0.5)));
    }
    for p in &mut c.particles {
        p.diameter *= s;
        p.length = p.length.map(|l| l * s);
        p.position = p.position.map(|x| (x + 0.5) * s - 0.5);
    }
    let impeller = c.impeller.as_mut().ok_or_else(|| anyhow::anyhow!("the case has no [impeller]"))?;
    impeller.diameter *= s;
    impeller.speed /= s;
    impeller.ramp_steps = ((impeller.ramp_steps as f64) * s).round() as u64;
    impeller.centre = impeller.centre.map(|p| p.map(|x| (x + 0.5) * s - 0.5));
    for v in [
        &mut impeller.thickness,
        &mut impeller.blade_width,
        &mut impeller.blade_thickness,
        &mut impeller.hub_diameter,
        &mut impeller.hub_height,
        &mut impeller.shaft_diameter,
    ] {
        *v = v.map(|x| x * s);
    }
    Ok(c)
}

/// Options of [`reproduce`].
#[derive(Clone, Debug)]
pub struct ReproduceOptions {
    /// Scale `s` (1: the paper).
    pub scale: f64,
    /// Revolutions after the ramp.
    pub revolutions: f64,
    /// Output directory of this case.
    pub out: PathBuf,
    /// Cache of settled beds (shared by runs).
    pub cache: PathBuf,
    /// Continue an interrupted run from its last checkpoint.
    pub resume: bool,
    /// With `resume`: continue a checkpoint written under other contact sub-steps or another
    /// lubrication limiter setting ([`slurry::run::RunOptions::switch_contacts`]).
    pub switch_contacts: bool,
    /// Start afresh over an earlier run in `out` (its checkpoint, series and history are
    /// replaced); without it, or `resume`, such a directory is refused
    /// ([`slurry::run::check_fresh_start`]).
    pub overwrite: bool,
    /// No progress output.
    pub quiet: bool,
    /// How the bed is settled.
    pub bed: BedMethod,
    /// Contact settings of the stirred run, where they differ from the case's.
    pub contacts: ContactOverrides,
    /// The stirred run's Mach limit, where it differs from the default 0.3 (a health check:
    /// no number changes, so a run stopped by it can be resumed with a higher one).
    pub mach_limit: Option<f64>,
    /// `--until-steady CAP`: after `revolutions`, run on in legs of
    /// [`STEADY_CHECK_REVOLUTIONS`] until the report's steady test passes
    /// ([`report::steady_test`]), to at most `CAP` revolutions after the ramp.
    pub until_steady: Option<f64>,
    /// `--start-from RUN`: start from the particles of the reproduction of the same case in
    /// this output directory (any scale; [`start`]) instead of the settled bed.
    pub start_from: Option<PathBuf>,
    /// The stirred run on the device (`--device gpu`: the fluid and the markers there,
    /// [`slurry::device::DeviceCoupled`]; the case's `[run] device`); the bed is settled on the
    /// CPU either way. Not part of the run's fingerprint: a checkpoint of either continues on
    /// the other.
    pub gpu: bool,
}

impl ReproduceOptions {
    /// A fresh run of `revolutions` at scale `scale` into `out`, beds cached in `cache`, quiet,
    /// on the CPU, everything else as the command line's defaults (no resume, no start, the
    /// case's contacts and Mach limit, a fixed length).
    pub fn quiet_run(scale: f64, revolutions: f64, out: PathBuf, cache: PathBuf) -> Self {
        Self {
            scale,
            revolutions,
            out,
            cache,
            resume: false,
            switch_contacts: false,
            overwrite: false,
            quiet: true,
            bed: BedMethod::default(),
            contacts: ContactOverrides::default(),
            mach_limit: None,
            until_steady: None,
            start_from: None,
            gpu: false,
        }
    }
}

/// Revolutions between two steady tests of `--until-steady`.
pub const STEADY_CHECK_REVOLUTIONS: f64 = 10.0;

/// Checks `--until-steady CAP` against the revolutions asked for: finite and not below them.
///
/// # Errors
/// The message names `--until-steady`, the value and the bound.
pub fn check_until_steady(cap: f64, revolutions: f64) -> Result<(), String> {
    if cap.is_finite() && cap >= revolutions {
        Ok(())
    } else {
        Err(format!(
            "--until-steady {cap}: must be finite and at least the --revolutions to run first ({revolutions})"
        ))
    }
}

/// The stirred run's settings for a scaled case (derived from the impeller).
#[derive(Clone, Copy, Debug, PartialEq, Serialize)]
pub struct Schedule {
    /// Steps per revolution `1/N`.
    pub steps_per_revolution: f64,
    /// Steps of the ramp.
    pub ramp_steps: u64,
    /// Total steps (ramp and revolutions).
    pub steps: u64,
    /// Steps between outputs (even).
    pub output_every: u64,
    /// Steps between checkpoints (a multiple of `output_every`).
    pub checkpoint_every: u64,
}

/// The schedule of `revolutions` after the ramp for the scaled case `c`.
///
/// # Errors
/// A case without `[impeller]`, or `revolutions` not finite and positive.
pub fn schedule(c: &Case, revolutions: f64) -> anyhow::Result<Schedule> {
    check_revolutions(revolutions).map_err(anyhow::Error::msg)?;
    let impeller = c.impeller.as_ref().ok_or_else(|| anyhow::anyhow!("the case has no [impeller]"))?;
    let steps_per_revolution = 1.0 / impeller.speed.abs();
    // Even: checkpoints need an even step (the AA pattern's state is complete there).
    let output_every = (((steps_per_revolution / OUTPUTS_PER_REVOLUTION) / 2.0).round() as u64).max(1) * 2;
    let outputs_per_checkpoint =
        ((CHECKPOINT_REVOLUTIONS * steps_per_revolution / output_every as f64).round() as u64).max(1);
    let steps_after = (revolutions * steps_per_revolution / output_every as f64).ceil() as u64 * output_every;
    let ramp_steps_rounded = impeller.ramp_steps.div_ceil(output_every) * output_every;
    Ok(Schedule {
        steps_per_revolution,
        ramp_steps: impeller.ramp_steps,
        steps: ramp_steps_rounded + steps_after,
        output_every,
        checkpoint_every: outputs_per_checkpoint * output_every,
    })
}

/// Revolutions after the impeller's start at which the stirred run writes its fields (the
/// paper's Figures 3 and 4: "10 and 90 disk revolutions after startup").
pub const SNAPSHOT_REVOLUTIONS: [f64; 2] = [10.0, 90.0];

impl Schedule {
    /// Revolutions after the ramp at `step` (0 before the ramp ends).
    pub fn revolutions_after_ramp(&self, step: u64) -> f64 {
        step.saturating_sub(self.ramp_steps) as f64 / self.steps_per_revolution
    }

    /// The output steps nearest [`SNAPSHOT_REVOLUTIONS`] that the run reaches.
    pub fn snapshot_steps(&self) -> Vec<u64> {
        SNAPSHOT_REVOLUTIONS
            .iter()
            .map(|r| {
                (r * self.steps_per_revolution / self.output_every as f64).round() as u64 * self.output_every
            })
            .filter(|&s| s >= 1 && s <= self.steps)
            .collect()
    }
}

/// FNV-1a, 64 bit: a stable hash for cache keys (the same on every platform and run).
fn fnv1a(text: &str) -> u64 {
    text.bytes().fold(0xcbf2_9ce4_8422_2325, |h, b| (h ^ u64::from(b)).wrapping_mul(0x0100_0000_01b3))
}

/// The cache record of a bed: what it was made from (the hashed text) and the bed.
#[derive(Clone, Debug, Serialize, Deserialize)]
pub struct BedRecord {
    /// What the bed was made from.
    pub inputs: String,
    /// Settled in the fluid (`--bed wet`), not dry; absent (dry) in caches made before `--bed`.
    #[serde(default)]
    pub wet: bool,
    /// The bed.
    #[serde(flatten)]
    pub bed: Bed,
    /// Not a settled bed but another run's particles (`--start-from`, [`start`]); absent for a
    /// settled bed.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub start_from: Option<start::StartFrom>,
    /// Not a settled bed but a state pack's run continued (`--start-from PACK`, [`start`]);
    /// absent otherwise.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub state_pack: Option<start::PackStart>,
}

/// How the bed is settled (`slurry reproduce --bed dry|wet`).
#[derive(Clone, Copy, Debug)]
pub enum BedMethod {
    /// Without fluid, at `gravity_factor` × gravity against a linear drag ([`dry_bed`]): the
    /// default, cheap (contacts only).
    Dry(DryBedOptions),
    /// In the fluid under the case's own gravity, as the paper does ([`wet_bed`]); the
    /// stopping rule from the scaled case ([`wet_settling`]).
    Wet,
}

impl Default for BedMethod {
    fn default() -> Self {
        BedMethod::Dry(DryBedOptions::default())
    }
}

/// In a reproduction's output directory while its bed settles in the fluid: the path of the
/// bed's cache directory ([`bed`]), whose settling record `slurry status` reads.
pub const SETTLING_POINTER: &str = "settling-bed.txt";

/// The wet settling's stopping rule for the scaled case `c`, from the Stokes settling speed
/// of a sphere of the particles' diameter, `v_s = (γ − 1) g d²/(18 ν)` (1.6e-3 at every
/// scale for the paper's cases: `g ∝ 1/s`, `d ∝ s`, `ν ∝ s`): stop when the mean particle
/// speed is below `0.02 v_s`, checked every 100 steps, not before the time to fall the tank's
/// height `n_z / v_s`, and give up after 4 times that (the bed is then marked not settled).
pub fn wet_settling(c: &Case) -> SettleOptions {
    let g = c.gravity();
    let g = (g[0] * g[0] + g[1] * g[1] + g[2] * g[2]).sqrt();
    let (d, gamma) = c
        .random_particles
        .first()
        .map(|r| (r.diameter, r.density))
        .or_else(|| c.particles.first().map(|p| (p.diameter, p.density)))
        .unwrap_or((1.0, 2.0));
    let v_s = ((gamma - 1.0) * g * d * d / (18.0 * c.nu())).max(1e-12);
    let fall = (c.grid().nz as f64 / v_s).ceil().min(1e9) as u64;
    SettleOptions {
        speed: 0.02 * v_s,
        check_every: 100,
        min_steps: fall,
        max_steps: 4 * fall,
        quiet: true,
        checkpoint_every_s: SETTLING_CHECKPOINT_EVERY_S,
    }
}

/// What a bed of the scaled case `c` depends on: the case without its impeller (which the bed
/// is settled without) and with a one-step run section, and the settling method's options,
/// as text (the cache key is its hash). The disk and the PBT of one ℓ/d and scale give the
/// same text, so they share one bed.
///
/// # Errors
/// The case cannot be serialised.
pub fn bed_inputs(c: &Case, method: &BedMethod) -> anyhow::Result<(Case, String)> {
    let mut key_case = c.clone();
    key_case.impeller = None;
    key_case.run = slurry::case::RunSection {
        steps: 1,
        output_every: 1,
        mach_limit: slurry::case::default_mach_limit(),
        checkpoint_every: None,
        snapshots: Vec::new(),
        device: slurry::case::Device::Cpu,
    };
    let case_text = toml::to_string(&key_case.normalised()).context("cannot serialise the case")?;
    let wet = wet_settling(&key_case);
    let inputs = match method {
        BedMethod::Dry(opts) => format!(
            "{case_text}\n# dry bed: gravity x {:?}, terminal speed {:?}, stop below {:?} of it, steps {}..{}\n",
            opts.gravity_factor,
            opts.terminal_speed,
            opts.stop_fraction,
            opts.min_steps,
            opts.max_steps(&key_case)
        ),
        BedMethod::Wet => format!(
            "{case_text}\n# wet bed: in the fluid, stop below mean speed {:?}, checked every {}, steps {}..{}\n",
            wet.speed, wet.check_every, wet.min_steps, wet.max_steps
        ),
    };
    Ok((key_case, inputs))
}

/// A cached bed made from `inputs` (hash `hash`): the case's own entry `dir` first, then
/// another case's entry with the same hash, by name (the disk and the PBT of one ℓ/d and scale
/// settle the same bed, bit for bit, so it is made once). A dry bed the case would refuse as
/// overlapping (cached before `dry_bed` relaxed its overlaps) is passed over, to be settled
/// again (minutes); a wet bed is used as it is (hours to make; the stirred case names any
/// overlap). Returns the record and the file it came from.
fn cached_bed(
    cache: &Path,
    dir: &Path,
    hash: &str,
    inputs: &str,
    key_case: &Case,
) -> Option<(BedRecord, PathBuf)> {
    let mut candidates = vec![dir.join("bed.json")];
    if let Ok(entries) = std::fs::read_dir(cache.join("beds")) {
        let suffix = format!("-{hash}");
        let mut others: Vec<PathBuf> = entries
            .filter_map(|e| e.ok().map(|e| e.path()))
            .filter(|p| {
                p != dir && p.file_name().and_then(|n| n.to_str()).is_some_and(|n| n.ends_with(&suffix))
            })
            .map(|p| p.join("bed.json"))
            .collect();
        others.sort();
        candidates.extend(others);
    }
    candidates.into_iter().find_map(|file| {
        let rec = slurry::io::checksum::read_cached_json::<BedRecord>(&file, "bed")?;
        if rec.inputs != inputs && file == dir.join("bed.json") {
            slurry::io::checksum::report_other_inputs(&file, "bed");
        }
        (rec.inputs == inputs
            && (rec.wet || slurry::settle::admissible(key_case, &rec.bed.particles).is_ok()))
        .then_some((rec, file))
    })
}

/// The bed of the scaled case `c`: from the cache when it holds one made from the same
/// inputs ([`bed_inputs`]; its own entry, else another case's, as the disk's and the PBT's of
/// one ℓ/d), else settled ([`dry_bed`] or [`wet_bed`]) and stored (atomically). Returns the
/// record and whether it came from the cache. While a wet bed settles (hours at s = 1/2,
/// before the run has a manifest), `pointer` (if given) holds the path of the bed's cache
/// directory, where `slurry status` finds the settling's record ([`SETTLING_POINTER`]); it is
/// removed once the bed is stored.
///
/// # Errors
/// Settling failed, or the cache (or the pointer) cannot be written.
pub fn bed(
    name: &str,
    c: &Case,
    method: BedMethod,
    cache: &Path,
    quiet: bool,
    pointer: Option<&Path>,
) -> anyhow::Result<(BedRecord, bool)> {
    let (key_case, inputs) = bed_inputs(c, &method)?;
    let wet = wet_settling(&key_case);
    let hash = format!("{:016x}", fnv1a(&inputs));
    let dir = cache.join("beds").join(format!("{name}-{hash}"));
    let file = dir.join("bed.json");
    // One process settles a bed at a time: another run of the same bed (the same case, or
    // the disk's and the PBT's of one ℓ/d) waits for it and then takes it from the cache.
    let beds = cache.join("beds");
    std::fs::create_dir_all(&beds).with_context(|| format!("cannot create {}", beds.display()))?;
    let _settling = slurry::io::lock::OutputLock::acquire_waiting(
        &beds.join(format!(".{hash}.lock")),
        "--cache",
        |who| {
            if !quiet {
                eprintln!("bed: {who} is settling the same bed into {}; waiting for it", beds.display());
            }
        },
    )?;
    if let Some((rec, from)) = cached_bed(cache, &dir, &hash, &inputs, &key_case) {
        if !quiet && from != file {
            eprintln!("bed: from the cache entry {} (same inputs)", from.display());
        }
        return Ok((rec, true));
    }
    std::fs::create_dir_all(&dir).with_context(|| format!("cannot create {}", dir.display()))?;
    let b = match method {
        BedMethod::Dry(opts) => {
            if !quiet {
                eprintln!("bed: placing {} particles and settling them dry (no fluid) …", c.particle_count());
            }
            dry_bed(&key_case, DryBedOptions { progress_every: if quiet { 0 } else { 250 }, ..opts })?
        }
        BedMethod::Wet => {
            if !quiet {
                eprintln!(
                    "bed: placing {} particles and settling them in the fluid under the case's gravity (stop below \
                     mean speed {:.1e}, steps {}..{}) …",
                    c.particle_count(),
                    wet.speed,
                    wet.min_steps,
                    wet.max_steps
                );
            }
            // Hours at s = 1/2: resumable from its checkpoint beside the cached bed.
            if let Some(p) = pointer {
                let abs = std::path::absolute(&dir).unwrap_or_else(|_| dir.clone());
                atomic_write_bytes(p, format!("{}\n", abs.display()).as_bytes())
                    .with_context(|| format!("cannot write {}", p.display()))?;
            }
            wet_bed(&key_case, SettleOptions { quiet, ..wet }, Some(&dir.join(SETTLING_CHECKPOINT)))?
        }
    };
    if !quiet {
        eprintln!(
            "bed: {} after {} steps{} ({:.0} s{}), mean centre height {:.2}, mean speed {:.1e}, largest {:.1e}",
            if b.settled { "settled" } else { "NOT settled (step limit)" },
            b.steps,
            if b.relax_steps > 0 {
                format!(" and {} relaxing at the case's gravity (overlaps)", b.relax_steps)
            } else {
                String::new()
            },
            b.seconds,
            if b.restarts > 0 { format!(", {} restarts", b.restarts) } else { String::new() },
            b.mean_height,
            b.mean_speed,
            b.max_speed
        );
    }
    let rec = BedRecord {
        inputs,
        wet: matches!(method, BedMethod::Wet),
        bed: b,
        start_from: None,
        state_pack: None,
    };
    let json = serde_json::to_string(&rec).context("cannot serialise the bed")?;
    atomic_write_bytes(&file, json.as_bytes()).with_context(|| format!("cannot write {}", file.display()))?;
    slurry::io::checksum::write_sidecar(&file)
        .with_context(|| format!("cannot write the checksum of {}", file.display()))?;
    remove_settling_checkpoint(&dir.join(SETTLING_CHECKPOINT))?;
    if let Some(p) = pointer.filter(|p| p.exists()) {
        std::fs::remove_file(p).with_context(|| format!("cannot remove {}", p.display()))?;
    }
    Ok((rec, false))
}

/// The stirred case: the scaled case `c` with the bed's particles in place of its random
/// placement, and the run settings of `sched`.
pub fn stirred_case(c: &Case, bed: &BedRecord, sched: &Schedule) -> Case {
    with_particles(c, &bed.bed.particles, sched)
}

/// `c` with `particles` in place of its random placement, and the run settings of `sched`:
/// the stirred case on a bed ([`stirred_case`]), or on the particles a run's checkpoint was
/// written with (`slurry bench --coupled --from`).
pub(crate) fn with_particles(c: &Case, particles: &[slurry::case::ParticleSpec], sched: &Schedule) -> Case {
    let mut s = c.clone();
    s.random_particles.clear();
    s.particles.extend(particles.iter().cloned());
    scheduled(&s, sched)
}

/// `c` with the run settings of `sched`: steps, outputs, checkpoints, snapshots (also each leg
/// of `--until-steady`, whose schedules differ only in their length).
fn scheduled(c: &Case, sched: &Schedule) -> Case {
    let mut s = c.clone();
    s.run.steps = sched.steps;
    s.run.output_every = sched.output_every;
    s.run.checkpoint_every = Some(sched.checkpoint_every);
    s.run.snapshots = sched.snapshot_steps();
    s
}

/// This process's session of the run in `run_dir`; resuming, with the step of the checkpoint
/// it continues from, recorded before the run starts so that a session cut short (killed
/// before it finishes, or stopped on an error) still says where it began.
fn this_session(run_dir: &Path, resume: bool) -> manifest::Session {
    let mut session = manifest::this_session(rayon::current_num_threads());
    if resume {
        session.resumed_from_step =
            slurry::io::checkpoint_time_step(&run_dir.join(slurry::run::files::CHECKPOINT)).ok();
    }
    session
}

/// The step of the last row of the time series of the run in `run_dir` (`None` when there is
/// none to read), from its time in revolutions (`c`'s steps per revolution).
/// Revolutions after the ramp that a run of case `name` at scale `scale` into `out` has
/// already done when it starts: the last row of its time series with `resume`, else the step
/// of a state pack it starts from (`start_from`), else 0 (also when any of them cannot be read:
/// this only shortens the announced estimate).
pub fn revolutions_done(name: &str, scale: f64, out: &Path, resume: bool, start_from: Option<&Path>) -> f64 {
    let done = || -> Option<f64> {
        let scaled = scale_case(&paper_case(name).ok()?.case().ok()?, scale).ok()?;
        let sched = schedule(&scaled, 1.0).ok()?;
        let step = if resume {
            last_step_in_timeseries(&out.join("run"), &scaled, &sched)? as u64
        } else {
            let pack = start_from.filter(|p| slurry::io::is_state_pack(p))?;
            hdf5::File::open(pack).ok()?.attr("time_step").ok()?.read_scalar::<u64>().ok()?
        };
        Some(sched.revolutions_after_ramp(step))
    };
    done().unwrap_or(0.0)
}

fn last_step_in_timeseries(run_dir: &Path, c: &Case, sched: &Schedule) -> Option<f64> {
    let path = run_dir.join(slurry::run::files::TIMESERIES);
    let ts = report::read_timeseries(&path, c.grid().nz as f64, sched.steps_per_revolution).ok()?;
    ts.last_step(sched.steps_per_revolution)
}

/// The target, in revolutions after the ramp, of the leg that a run of the scaled case `c` with
/// `revolutions` (and `--until-steady CAP`: legs of [`STEADY_CHECK_REVOLUTIONS`] after it, up to
/// `CAP`) is in, or ended, once its last row is at step `last_step`: the first leg whose last
/// step ([`schedule`]) is not below `last_step`, or the cap. A leg ends on the output step at or
/// after its revolutions (100.08 revolutions for 100 at s = 1/3), so the rule is on steps, not
/// revolutions. The one rule of a resume (which continues that leg, or, if it was complete,
/// runs the steady test that decides the next) and of `slurry status` (which measures progress
/// against it).
pub(crate) fn leg_target(c: &Case, revolutions: f64, until_steady: Option<f64>, last_step: f64) -> f64 {
    let passed = |t: f64| schedule(c, t).is_ok_and(|s| (s.steps as f64) < last_step);
    let mut target = revolutions;
    if let Some(cap) = until_steady {
        while target < cap && passed(target) {
            target = (target + STEADY_CHECK_REVOLUTIONS).min(cap);
        }
    }
    target
}

/// The verdict of `--until-steady` when it stops.
fn verdict(steady: bool) -> &'static str {
    if steady {
        "steady"
    } else {
        "not steady at the cap"
    }
}

/// What the pipeline ran: the report's input besides the run's files ([`report::write_all`]).
#[derive(Clone, Debug, Serialize)]
pub struct RunRecord {
    /// Case name.
    pub case: String,
    /// Scale.
    pub scale: f64,
    /// Revolutions after the ramp.
    pub revolutions: f64,
    /// The run's schedule.
    pub schedule: Schedule,
    /// Whether the bed came from the cache.
    pub bed_cached: bool,
    /// Contact settings that differ from the case's.
    pub contacts: ContactOverrides,
    /// The stirred run's summary.
    pub run: RunSummary,
}

/// What [`reproduce`] did (`reproduce.json`: the record's fields, then these).
#[derive(Clone, Debug, Serialize)]
pub struct ReproduceSummary {
    /// What was run.
    #[serde(flatten)]
    pub record: RunRecord,
    /// Wall-clock seconds of the whole pipeline.
    pub wall_time_s: f64,
    /// `report.md`.
    pub report: PathBuf,
    /// The statistics and the comparison with the paper.
    pub results: report::Results,
}

/// Runs the pipeline (module docs) for the case `name` into `opts.out`.
///
/// # Errors
/// An unknown case, bad options, a failed settling or run, an output failure.
pub fn reproduce(name: &str, opts: &ReproduceOptions) -> anyhow::Result<ReproduceSummary> {
    let t0 = Instant::now();
    let pc = paper_case(name)?;
    let paper = pc.paper()?;
    let scaled = scale_case(&pc.case()?, opts.scale)?;
    let sched = schedule(&scaled, opts.revolutions)?;
    // Before the bed: a scale this machine cannot hold is refused as bad input.
    scaled.check_memory().map_err(|kind| slurry::case::CaseError {
        file: PathBuf::from(format!("reproduce/{name}/case.toml at --scale {}", opts.scale)),
        kind,
    })?;
    let run_dir = opts.out.join("run");
    slurry::io::lock::claim_output_dir(&opts.out, "--out")?;
    slurry::io::lock::check_output_path(&opts.cache, "--cache")?;
    // Before the bed and the manifest: a fresh start would replace an earlier run's files.
    if !opts.resume && !opts.overwrite {
        slurry::run::check_fresh_start(&run_dir, "--resume", "--overwrite")?;
    }
    if opts.overwrite && !opts.resume {
        // The earlier run's results go with it: a new run that fails must not leave them
        // beside its own series for `--all --summary-only` or `slurry resolution` to read.
        let mut old: Vec<PathBuf> = ["statistics.json", "statistics.h5", "report.md", "reproduce.json"]
            .iter()
            .map(|f| opts.out.join(f))
            .collect();
        // The Figure 3/4 snapshots too: a shorter new run would leave the old one's beside its
        // own (the summary copies them).
        if let Ok(dir) = std::fs::read_dir(&opts.out) {
            old.extend(dir.filter_map(|e| e.ok()).map(|e| e.path()).filter(|p| {
                p.file_name().and_then(|n| n.to_str()).is_some_and(|n| {
                    ["disk", "pbt"].iter().any(|i| n.starts_with(&report::midplane_stem(i, None)))
                })
            }));
        }
        for p in old.iter().filter(|p| p.exists()) {
            std::fs::remove_file(p).with_context(|| format!("--overwrite: cannot remove {}", p.display()))?;
        }
    }
    std::fs::create_dir_all(&opts.out).with_context(|| format!("cannot create {}", opts.out.display()))?;
    let pointer = opts.out.join(SETTLING_POINTER);
    let (bed, cached) = start::start_or_bed(name, &scaled, opts, &pointer)?;
    if cached && !opts.quiet {
        eprintln!(
            "bed: from the cache ({} particles, settled in {} steps)",
            bed.bed.particles.len(),
            bed.bed.steps
        );
    }
    let mut case = stirred_case(&scaled, &bed, &sched);
    opts.contacts.apply(&mut case);
    if let Some(l) = opts.mach_limit {
        case.run.mach_limit = l;
    }
    case.run.device = if opts.gpu { slurry::case::Device::Gpu } else { slurry::case::Device::Cpu };
    case.validate().map_err(|kind| anyhow::anyhow!("the stirred case of {name} is invalid: {kind}"))?;
    let first = manifest::Manifest {
        case: name.to_string(),
        scale: opts.scale,
        revolutions: opts.revolutions,
        until_steady: opts.until_steady,
        contacts: opts.contacts,
        steps: sched.steps,
        status: String::new(),
        steps_done: None,
        revolutions_done: None,
        restarts: 0,
        wall_time_s: 0.0,
        sessions: Vec::new(),
        legs: Vec::new(),
    };
    // The run to `opts.revolutions`; with --until-steady, continued in legs of
    // STEADY_CHECK_REVOLUTIONS (each a resume of the last in this process) until the report's
    // steady test passes or the cap is reached.
    let mut target = opts.revolutions;
    if opts.resume {
        // A resumed run skips the legs it has already passed.
        let last = last_step_in_timeseries(&run_dir, &scaled, &sched).unwrap_or(0.0);
        target = leg_target(&scaled, opts.revolutions, opts.until_steady, last);
    }
    // From a state pack the run continues the packed run's time: the legs it has passed are
    // skipped, and it must go past the pack.
    let pack = bed.state_pack.as_ref().map(|p| (p.pack.clone(), p.step));
    let pack_step = pack.as_ref().map_or(0, |p| p.1);
    if let Some((path, step)) = &pack {
        if !opts.resume {
            target = leg_target(&scaled, opts.revolutions, opts.until_steady, *step as f64);
        }
        let leg_end = schedule(&scaled, target)?.steps;
        if leg_end <= *step {
            // Refused before the manifest records a session.
            let after = sched.revolutions_after_ramp(*step);
            return Err(slurry::run::BadResume(format!(
                "--revolutions {}: the state pack {} is at step {step}, {after:.2} revolutions after the ramp; ask \
                 for more (e.g. --revolutions {:.2} for 10 more)",
                opts.revolutions,
                path.display(),
                after + STEADY_CHECK_REVOLUTIONS
            ))
            .into());
        }
    }
    let session = manifest::Session {
        device: if opts.gpu { "gpu" } else { "cpu" }.into(),
        ..this_session(&run_dir, opts.resume)
    };
    let mut record_file = manifest::Manifest::start(&opts.out, first, opts.resume, session)?;
    let mut so_far: Option<RunSummary> = None;
    let (run, sched, case) = loop {
        let sched = schedule(&scaled, target)?;
        let mut leg_case = scheduled(&case, &sched);
        if let Some((_, step)) = &pack {
            // The fields of Figures 3 and 4 only at steps this run reaches.
            leg_case.run.snapshots.retain(|s| s > step);
        }
        let resume = opts.resume || so_far.is_some();
        let run_opts = RunOptions {
            quiet: opts.quiet,
            resume,
            switch_contacts: opts.switch_contacts,
            overwrite: opts.overwrite && !resume,
        };
        let leg = match &pack {
            Some((path, _)) if !resume => {
                slurry::run::run_case_from_pack(&leg_case, &run_dir, run_opts, path)
            }
            _ => run_case(&leg_case, &run_dir, run_opts),
        };
        let leg = match leg {
            Ok(run) => run,
            Err(e) => {
                // The manifest says the session ended and why; the run's files and its last
                // checkpoint stay for a resume. The run's error is the one reported.
                if let Some(last) = last_step_in_timeseries(&run_dir, &scaled, &sched) {
                    record_file.legs =
                        slurry::run::read_legs(&run_dir, pack_step, last as u64).unwrap_or_default();
                }
                let _ = record_file.stop(&opts.out, t0.elapsed().as_secs_f64(), &e);
                return Err(e);
            }
        };
        let run = match &so_far {
            Some(earlier) => earlier.then(&leg),
            None => leg,
        };
        so_far = Some(run.clone());
        let Some(cap) = opts.until_steady else { break (run, sched, leg_case) };
        let test = report::steady_test(&leg_case, &run_dir)?;
        if test.steady || target >= cap {
            if !opts.quiet {
                eprintln!(
                    "--until-steady: {} after {target} revolutions ({})",
                    verdict(test.steady),
                    test.reason
                );
            }
            break (run, sched, leg_case);
        }
        let next = (target + STEADY_CHECK_REVOLUTIONS).min(cap);
        if !opts.quiet {
            eprintln!(
                "--until-steady: not steady after {target} revolutions ({}); on to {next}",
                test.reason
            );
        }
        target = next;
    };
    record_file.steps = sched.steps;
    let record = RunRecord {
        case: name.to_string(),
        scale: opts.scale,
        revolutions: target,
        schedule: sched,
        bed_cached: cached,
        contacts: opts.contacts,
        run,
    };
    let results = report::write_all(name, &case, &paper, &record, &bed, &opts.out)?;
    let revolutions_done = sched.revolutions_after_ramp(record.run.steps);
    record_file.legs = slurry::run::read_legs(&run_dir, pack_step, record.run.steps)?;
    record_file.finish(&opts.out, t0.elapsed().as_secs_f64(), record.run.steps, revolutions_done)?;
    let summary = ReproduceSummary {
        record,
        wall_time_s: t0.elapsed().as_secs_f64(),
        report: opts.out.join("report.md"),
        results,
    };
    let mut json = serde_json::to_string_pretty(&summary).context("cannot serialise the summary")?;
    let _ = writeln!(json);
    let p = opts.out.join("reproduce.json");
    atomic_write_bytes(&p, json.as_bytes()).with_context(|| format!("cannot write {}", p.display()))?;
    Ok(summary)
}

#[cfg(test)]
mod tests;
