//! `slurry reproduce --start-from RUN`: a stirred run that starts from the particles of another
//! reproduction of the same case, at any scale, instead of from a settled bed.
//!
//! The paper starts each case from a loosely packed bed and reports the dynamic steady state
//! after 100–200 revolutions. How fast a bed rises falls with the resolution (at s = 1/2 the
//! suspension rises about half as fast as at s = 1/4, `reproduce/README.md`, "Resolution
//! study"), so from the bed a half-scale case may need more than 200 revolutions. Started
//! from the steady state of a coarser run, the suspension approaches its level from above
//! instead of from below; where both are run, the two bracket the steady level.
//!
//! The start is one frame of the source's `run/particles.h5`:
//!
//! - **positions** mapped as the scaling maps every length ([`super::scale_case`]), per axis by
//!   the ratio of the grids, `x' = (x + ½) n'/n − ½`, so that the walls (at `−½` and `n − ½`)
//!   map onto the walls: the configuration is geometrically similar, gaps included;
//! - **orientations** kept; **velocities** zero: the run starts with the fluid at rest and the
//!   impeller's ramp, as from a bed;
//! - **the frame** is one of the source's last [`WINDOW_REVOLUTIONS`] revolutions in which the
//!   impeller stands where the new run's starts (angle 0), up to its symmetry (a PBT's blade
//!   spacing; any angle for the disk), so that no particle finds a blade inside it: the frame
//!   with the smallest phase error whose particles pass the case's validation (walls' margins,
//!   no overlaps), refused if the blade tips are more than [`MAX_TIP_SHIFT`] from where they stood.
//!
//! **A state pack** (`slurry state-pack`, [`slurry::io::state_pack`]) of a run of this case at
//! this scale is the other kind of source: not particles to start from but the packed run's
//! whole state, which the run continues ([`PackStart`]; `slurry::run::run_case_from_pack`):
//! the flow rebuilt from the pack's density, velocity and force field, every body as it was, the
//! time going on from the pack's step, so `--revolutions` counts from the ramp as for the
//! packed run and must go past the pack. The stirred case is the packed run's (its particles'
//! initial positions come from the pack's case), which the pack's fingerprint then admits; with
//! `--switch-contacts` it may continue under another contact scheme.
//!
//! What was chosen is written to `start.json` in the output directory; a resumed run reads it
//! back (the source may have moved on or gone), so that its case is the one its checkpoint was
//! written for.
//!
//! The source is a reproduction's output directory or a **start pack** of one
//! ([`write_start_pack`], `slurry start-pack`, which `reproduce/tools/archive.sh` writes into
//! every archive): the same layout, with only the [`PACK_FRAMES`] frames the choice above tries
//! first (or, with `--at T`, those of the 20 revolutions ending at the source's time `T`: an
//! earlier, lower state, to approach a finer scale's level from below). A pack chooses the
//! frame the run would, bit for bit, from under a megabyte that goes into git; output
//! directories live outside the checkout and are lost with the machine
//! (`reproduce/JOURNAL.md`, "The campaign's history").

use std::path::{Path, PathBuf};

use anyhow::Context;
use serde::{Deserialize, Serialize};

use super::{manifest, BedRecord};
use slurry::case::{Case, MotionKind, ParticleSpec, ShapeKind};
use slurry::io::{atomic_write_bytes, read_particle_history_from};
use slurry::settle::{admissible, Bed};

/// The file in the output directory that records the start ([`StartFrom`]).
pub const START_FILE: &str = "start.json";

/// The source's last revolutions searched for the start frame.
pub const WINDOW_REVOLUTIONS: f64 = 20.0;

/// Largest distance, lattice units of the new scale, between where the blade tips stand in the
/// chosen frame and where they stand at the new run's start (a quarter of Table 1's elastic
/// range `δ0 = 0.5`).
pub const MAX_TIP_SHIFT: f64 = 0.125;

/// Frames tried for the validation, in order of phase error, before giving up.
const MAX_TRIED: usize = 64;

/// Where a run started from another run's particles: `start.json`, and the report's line.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct StartFrom {
    /// The source: a reproduction's output directory, as given.
    pub dir: PathBuf,
    /// The source's scale.
    pub scale: f64,
    /// Step of the source frame.
    pub step: u64,
    /// The source frame's time in revolutions (`step · N`, ramp included).
    pub revolution: f64,
    /// The source frame's `⟨z_p⟩/H`.
    pub mean_height_over_h: f64,
    /// Per-axis ratio of the grids, new over source.
    pub factor: [f64; 3],
    /// The impeller's angle in the source frame less the nearest angle equivalent to the new
    /// run's start (0 up to its symmetry), degrees.
    pub phase_error_deg: f64,
    /// The blade tips' displacement that phase error makes at the new scale, lattice units.
    pub tip_shift: f64,
}

/// How a stirred run started (`statistics.json`'s `start`, `{"kind": …}`): a settled bed or
/// another run's particles.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(tag = "kind", rename_all = "kebab-case")]
pub enum RunStart {
    /// A bed settled dry.
    DryBed,
    /// A bed settled in the fluid (`--bed wet`).
    WetBed,
    /// Another run's particles (`--start-from`): the source, its frame and its ⟨z_p⟩/H.
    StartFrom(StartFrom),
    /// Another run's whole state (`--start-from PACK`, a state pack): the run it continues.
    StatePack(PackStart),
}

impl RunStart {
    /// A table cell: "dry bed", "wet bed" or "from s = 0.25 at ⟨z_p⟩/H 0.322".
    pub fn label(&self) -> String {
        match self {
            RunStart::DryBed => "dry bed".into(),
            RunStart::WetBed => "wet bed".into(),
            RunStart::StartFrom(f) => format!(
                "from s = {} at ⟨z_p⟩/H {:.3}",
                slurry::util::fmt_num((f.scale * 1e4).round() / 1e4),
                f.mean_height_over_h
            ),
            RunStart::StatePack(p) => format!("state pack at {:.1} revolutions", p.revolution),
        }
    }
}

impl BedRecord {
    /// How a run from this record starts.
    pub fn start(&self) -> RunStart {
        match (&self.start_from, &self.state_pack, self.wet) {
            (Some(from), _, _) => RunStart::StartFrom(from.clone()),
            (None, Some(p), _) => RunStart::StatePack(p.clone()),
            (None, None, true) => RunStart::WetBed,
            (None, None, false) => RunStart::DryBed,
        }
    }
}

impl StartFrom {
    /// One line for the console and the report: the source, its frame, the mapping.
    pub fn describe(&self) -> String {
        format!(
            "the particles of the reproduction in `{}` (scale {:.3}) at its step {} ({:.1} revolutions, ⟨z_p⟩/H \
             {:.3}), positions scaled by {:.4} to this grid, at rest; the impeller {:.3}° from its start angle in that \
             frame (tips {:.3} lattice units)",
            self.dir.display(),
            self.scale,
            self.step,
            self.revolution,
            self.mean_height_over_h,
            self.factor[2],
            self.phase_error_deg,
            self.tip_shift
        )
    }
}

/// The bed record of a run of the scaled case `scaled` (case `name`, output directory `out`)
/// that starts from the reproduction in `src`: chosen afresh and written to `out/start.json`
/// (which a fresh start replaces), or, with `resume`, read back from it.
///
/// # Errors
/// `src` is not a reproduction of `name` with a particle history, has no usable frame (module
/// docs), or `start.json` cannot be written or read; each message names `--start-from` and the
/// path.
pub fn start_bed(
    name: &str,
    scaled: &Case,
    src: &Path,
    out: &Path,
    resume: bool,
) -> anyhow::Result<BedRecord> {
    let file = out.join(START_FILE);
    let is_pack = slurry::io::is_state_pack(src);
    if resume {
        let rec = read_start_record(out)?.with_context(|| {
            format!(
                "--start-from {} with --resume: there is no {} (this run was not started with --start-from)",
                src.display(),
                file.display()
            )
        })?;
        let began = match (&rec.start_from, &rec.state_pack) {
            (Some(from), _) => &from.dir,
            (None, Some(p)) => &p.pack,
            (None, None) => anyhow::bail!("{} records no --start-from source", file.display()),
        };
        anyhow::ensure!(
            began == src,
            "--start-from {}: this run started from {} ({}); give that one",
            src.display(),
            began.display(),
            file.display()
        );
        return Ok(rec);
    }
    let rec = if is_pack { pack_start(name, scaled, src)? } else { choose_start(name, scaled, src)? };
    let json = serde_json::to_string(&rec).context("cannot serialise the start record")?;
    atomic_write_bytes(&file, json.as_bytes()).with_context(|| format!("cannot write {}", file.display()))?;
    Ok(rec)
}

/// The start record of the run in `out` (its [`START_FILE`]), `None` if it has none (it
/// started from a bed).
///
/// # Errors
/// The file exists but cannot be read, or is not a start record; the message names it.
pub fn read_start_record(out: &Path) -> anyhow::Result<Option<BedRecord>> {
    let file = out.join(START_FILE);
    let text = match std::fs::read_to_string(&file) {
        Ok(t) => t,
        Err(e) if e.kind() == std::io::ErrorKind::NotFound => return Ok(None),
        Err(e) => return Err(e).with_context(|| format!("cannot read {}", file.display())),
    };
    serde_json::from_str(&text).with_context(|| format!("{} is not a start record", file.display())).map(Some)
}

/// The run's start, for [`super::reproduce`]: with `opts.start_from`, the record of
/// [`start_bed`] (never from the cache); else the settled bed of [`super::bed`] (and whether it
/// came from the cache), after refusing to resume a run that `start.json` says was started from
/// another run, and removing an earlier run's `start.json` on a fresh start (`--overwrite`).
///
/// # Errors
/// Those of [`start_bed`] and [`super::bed`]; a resume without the `--start-from` the run began
/// with.
pub(super) fn start_or_bed(
    name: &str,
    scaled: &Case,
    opts: &super::ReproduceOptions,
    pointer: &Path,
) -> anyhow::Result<(BedRecord, bool)> {
    let start_file = opts.out.join(START_FILE);
    let (bed, cached) = match &opts.start_from {
        Some(src) => (start_bed(name, scaled, src, &opts.out, opts.resume)?, false),
        None => {
            anyhow::ensure!(
                !(opts.resume && start_file.exists()),
                "{} records that this run started from another run's particles: resume it with the same --start-from",
                start_file.display()
            );
            if start_file.exists() {
                // --overwrite: the earlier run's start goes with it.
                std::fs::remove_file(&start_file)
                    .with_context(|| format!("--overwrite: cannot remove {}", start_file.display()))?;
            }
            super::bed(name, scaled, opts.bed, &opts.cache, opts.quiet, Some(pointer))?
        }
    };
    if !opts.quiet {
        if let Some(from) = &bed.start_from {
            eprintln!("start: {}", from.describe());
        }
        if let Some(p) = &bed.state_pack {
            eprintln!("start: {}", p.describe());
        }
    }
    Ok((bed, cached))
}

/// Where a run started from a state pack (`--start-from PACK`, a file of `slurry state-pack`):
/// the packed run continued, its flow rebuilt from the pack's density, velocity and force
/// field and its bodies exactly as they were ([`slurry::run::run_case_from_pack`]).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct PackStart {
    /// The pack, as given.
    pub pack: PathBuf,
    /// The pack's step.
    pub step: u64,
    /// The pack's time in revolutions (`step · N`, the ramp counting 1, as
    /// [`StartFrom::revolution`]).
    pub revolution: f64,
    /// The pack's label (what it was written from).
    pub label: String,
    /// The pack's content checksum (BLAKE3).
    pub checksum: String,
}

impl PackStart {
    /// One line for the console and the report.
    pub fn describe(&self) -> String {
        format!(
            "the state pack `{}` ({}) at its step {} ({:.1} revolutions): the packed run continued, its flow \
             rebuilt from density, velocity and force field (regularised), its particles as they were",
            self.pack.display(),
            self.label,
            self.step,
            self.revolution
        )
    }
}

/// The start record of a run of the scaled case `scaled` (case `name`) from the state pack
/// `src`: the particles the packed run was started with (its case's, so that the stirred case
/// is the packed run's and the pack's fingerprint check admits it), and the pack's step.
///
/// # Errors
/// `src` cannot be read (or is corrupt), holds no bodies, or was written for another case or
/// scale than `name` at this scale; each message names `--start-from` and the path.
fn pack_start(name: &str, scaled: &Case, src: &Path) -> anyhow::Result<BedRecord> {
    let what = || format!("--start-from {}", src.display());
    let pack = slurry::io::read_state_pack(src).with_context(what)?;
    let grid = scaled.grid();
    anyhow::ensure!(
        pack.grid == grid,
        "{}: a state pack of the {} x {} x {} grid; {name} at this scale is {} x {} x {} (give the --scale it was \
         written at)",
        what(),
        pack.grid.nx,
        pack.grid.ny,
        pack.grid.nz,
        grid.nx,
        grid.ny,
        grid.nz
    );
    anyhow::ensure!(pack.bodies.is_some(), "{}: the pack holds no bodies (not a stirred run's)", what());
    let packed: Case = toml::from_str(&pack.case)
        .map_err(|e| anyhow::anyhow!("{}: the pack's case cannot be read: {e}", what()))?;
    // The particles are the pack's: they must be this case's population (its count, shape,
    // size and density), or the pack is another ℓ/d's.
    let template = scaled.random_particles.first().ok_or_else(|| {
        anyhow::anyhow!("the scaled case {name} has no random particle population to compare with")
    })?;
    let count = scaled.particle_count();
    let alike = |p: &ParticleSpec| {
        p.shape == template.shape
            && p.diameter == template.diameter
            && p.length == template.length
            && p.density == template.density
            && p.motion == template.motion
    };
    anyhow::ensure!(
        packed.particles.len() == count && packed.particles.iter().all(alike),
        "{}: written for another case than {name} at this scale: its {} particles are not this case's {count} \
         {:?} of d = {}, ℓ = {:?}, density {}",
        what(),
        packed.particles.len(),
        template.shape,
        template.diameter,
        template.length,
        template.density
    );
    // The scaled case with the packed run's particles must be the packed run's case up to its
    // run settings and contact scheme (which `run_case_from_pack` checks with the options).
    let mut same = scaled.clone();
    same.random_particles.clear();
    same.particles = packed.particles.clone();
    same.run = packed.run.clone();
    anyhow::ensure!(
        same.normalised().fingerprint_except_contact_scheme()
            == packed.normalised().fingerprint_except_contact_scheme(),
        "{}: written for another case than {name} at this scale (the pack's case {}; this one's {})",
        what(),
        slurry::io::state_pack::fingerprint_digest(&pack.case),
        slurry::io::state_pack::fingerprint_digest(&same.fingerprint())
    );
    let steps_per_rev = super::schedule(scaled, 1.0)?.steps_per_revolution;
    let bed = Bed {
        particles: packed.particles,
        steps: 0,
        mean_speed: 0.0,
        max_speed: 0.0,
        settled: true,
        mean_height: 0.0,
        seconds: 0.0,
        restarts: 0,
        relax_steps: 0,
    };
    let from = PackStart {
        pack: src.to_path_buf(),
        step: pack.time_step,
        revolution: pack.time_step as f64 / steps_per_rev,
        label: pack.label.clone(),
        checksum: pack.checksum(),
    };
    Ok(BedRecord {
        inputs: format!("state pack {} at step {}", src.display(), pack.time_step),
        wet: false,
        bed,
        start_from: None,
        state_pack: Some(from),
    })
}

/// `angle` less the nearest multiple of `period`, in `(−period/2, period/2]`; 0 without one.
pub fn phase_error(angle: f64, period: Option<f64>) -> f64 {
    match period {
        None => 0.0,
        Some(p) => angle - p * (angle / p).round(),
    }
}

/// Maps a position of a grid `n` onto the grid `n_new` (module docs).
pub fn map_position(x: [f64; 3], factor: [f64; 3]) -> [f64; 3] {
    [0, 1, 2].map(|i| (x[i] + 0.5) * factor[i] - 0.5)
}

/// A source of `--start-from`: a reproduction's output directory, or a start pack of one
/// ([`write_start_pack`]), with its frames ranked for a start at angle 0.
struct Source {
    manifest: manifest::Manifest,
    case_text: String,
    case: Case,
    tank: crate::stats::Tank,
    hist: slurry::io::ParticleHistory,
    /// `(phase error, frame index)`, smallest error first; among equals, the latest frame.
    ranked: Vec<(f64, usize)>,
}

impl Source {
    /// Reads `src` (`what` names it in errors): its manifest, its case, and the frames of its
    /// last [`WINDOW_REVOLUTIONS`] revolutions, or, with `at = Some(t)`, of the
    /// [`WINDOW_REVOLUTIONS`] revolutions that end at its time `t` (`t N`, the ramp counting 1,
    /// as [`StartFrom::revolution`] and the report's Figure 5).
    fn open(src: &Path, what: &dyn Fn() -> String, at: Option<f64>) -> anyhow::Result<Source> {
        slurry::io::checksum::verify_list(src, slurry::io::checksum::START_PACK_REMEDY)?;
        let manifest = manifest::Manifest::read(src).ok_or_else(|| {
            anyhow::anyhow!(
                "{}: no readable {} (not a reproduction's output directory)",
                what(),
                manifest::FILE
            )
        })?;
        let run = src.join("run");
        let case_path = run.join(slurry::run::files::CASE);
        let case_text = std::fs::read_to_string(&case_path)
            .with_context(|| format!("{}: cannot read its case {}", what(), case_path.display()))?;
        let case = Case::parse(&case_text, &case_path)
            .with_context(|| format!("{}: cannot read its case", what()))?;
        let (tank, setup) = super::report::tank_of(&case).with_context(what)?;
        let period = setup.symmetry_angle();
        let path = run.join(slurry::run::files::PARTICLES_H5);
        let total = read_particle_history_from(&path, usize::MAX)
            .with_context(|| format!("{}: cannot read {}", what(), path.display()))?
            .frames_in_file;
        anyhow::ensure!(total > 0, "{}: {} has no frames", what(), path.display());
        // Frames per revolution from the source's output interval (its last frame may be off it).
        let spacing = case.run.output_every.max(1) as f64;
        let window = ((WINDOW_REVOLUTIONS * tank.steps_per_rev / spacing).ceil() as usize).max(1);
        let hist = match at {
            None => read_particle_history_from(&path, total.saturating_sub(window))?,
            Some(t) => {
                anyhow::ensure!(t.is_finite() && t > 0.0, "{}: --at {t}: must be finite and > 0", what());
                let (lo, hi) = ((t - WINDOW_REVOLUTIONS) * tank.steps_per_rev, t * tank.steps_per_rev);
                let last = read_particle_history_from(&path, total - 1)?.frames.last().map_or(0, |f| f.step);
                anyhow::ensure!(
                    hi <= last as f64,
                    "{}: --at {t}: allowed 0 < t ≤ {:.2}, the time of its last frame (step {last}, in \
                     revolutions t N, the ramp counting 1)",
                    what(),
                    last as f64 / tank.steps_per_rev
                );
                // Frames are `spacing` steps apart from step 0 (a resume rewrites those after its
                // checkpoint): start a window early, and keep those in (lo, hi]. Where frames are
                // missing (a history with a lost stretch), read them all.
                let first = ((lo / spacing).floor().max(0.0) as usize).saturating_sub(window);
                let mut h = read_particle_history_from(&path, first)?;
                if first > 0 && h.frames.first().is_some_and(|f| f.step as f64 > lo) {
                    h = read_particle_history_from(&path, 0)?;
                }
                h.frames.retain(|f| (f.step as f64) > lo && (f.step as f64) <= hi);
                anyhow::ensure!(
                    !h.frames.is_empty(),
                    "{}: no frame within t N {:.2}–{t}",
                    what(),
                    t - WINDOW_REVOLUTIONS
                );
                h
            }
        };
        let mut ranked: Vec<(f64, usize)> = hist
            .frames
            .iter()
            .enumerate()
            .map(|(k, f)| (phase_error(setup.motion.angle(f.step as f64), period), k))
            .collect();
        ranked.sort_by(|a, b| a.0.abs().total_cmp(&b.0.abs()).then(b.1.cmp(&a.1)));
        Ok(Source { manifest, case_text, case, tank, hist, ranked })
    }
}

/// Frames a start pack keeps ([`write_start_pack`]): the best by phase error. One is used; the
/// others stand in if the target case's validation refuses it.
pub const PACK_FRAMES: usize = 4;

/// What [`write_start_pack`] wrote.
#[derive(Clone, Debug, PartialEq)]
pub struct StartPack {
    /// Steps of the frames kept, in order.
    pub steps: Vec<u64>,
    /// Their phase errors, degrees, in the same order.
    pub phase_errors_deg: Vec<f64>,
    /// Bytes of the pack's `particles.h5`.
    pub bytes: u64,
}

/// Writes into `dest` a **start pack** of the reproduction in `src`: its `manifest.json`, its
/// `run/case.toml`, and a `run/particles.h5` holding only the [`PACK_FRAMES`] frames of its last
/// [`WINDOW_REVOLUTIONS`] revolutions that `--start-from` would try first (smallest impeller
/// phase error; module docs). `--start-from dest` then chooses as `--start-from src` would,
/// from under a megabyte (0.9 MB at 822 particles) that goes into the run's archive: the state a
/// run ended in survives the loss of its output directory (fields and checkpoints stay out of
/// git).
///
/// With `at = Some(t)` the frames come from the [`WINDOW_REVOLUTIONS`] revolutions ending at
/// the source's time `t` instead (`t N`, the ramp counting 1): an earlier state of the run, e.g.
/// one below the level a finer scale reaches, to approach that level from below
/// (`--start-from dest` then chooses among these frames; [`StartFrom`] records the frame's step,
/// time and ⟨z_p⟩/H).
///
/// # Errors
/// `src` is not a reproduction with a particle history, `t` is not within its time, or `dest`
/// cannot be written.
pub fn write_start_pack(src: &Path, dest: &Path, at: Option<f64>) -> anyhow::Result<StartPack> {
    let what = || format!("start pack of {}", src.display());
    let s = Source::open(src, &what, at)?;
    // The frames the choice tries first, in step order, with their phase errors.
    let mut keep: Vec<(f64, usize)> = s.ranked.iter().take(PACK_FRAMES).copied().collect();
    keep.sort_unstable_by_key(|&(_, k)| k);
    // One writer per pack: a second `start-pack` into `dest` is refused while this one writes.
    slurry::io::lock::claim_output_dir(dest, "PACK")?;
    let run = dest.join("run");
    std::fs::create_dir_all(&run).with_context(|| format!("cannot create {}", run.display()))?;
    let manifest_path = src.join(manifest::FILE);
    let manifest_bytes =
        std::fs::read(&manifest_path).with_context(|| format!("cannot read {}", manifest_path.display()))?;
    atomic_write_bytes(&dest.join(manifest::FILE), &manifest_bytes)
        .with_context(|| format!("cannot write {}", dest.join(manifest::FILE).display()))?;
    atomic_write_bytes(&run.join(slurry::run::files::CASE), s.case_text.as_bytes())
        .with_context(|| format!("cannot write {}", run.join(slurry::run::files::CASE).display()))?;
    let statics = s
        .hist
        .statics
        .iter()
        .map(|p| {
            // The names the case's kinds give (`ParticleStatic` holds `'static` ones).
            Ok(slurry::io::ParticleStatic {
                shape: ShapeKind::deserialize(kind(&p.shape))
                    .map_err(|e| anyhow::anyhow!("{}: particle shape {:?}: {e}", what(), p.shape))?
                    .name(),
                diameter: p.diameter,
                length: p.length,
                density: p.density,
                volume: p.volume,
                mass: p.mass,
                motion: MotionKind::deserialize(kind(&p.motion))
                    .map_err(|e| anyhow::anyhow!("{}: particle motion {:?}: {e}", what(), p.motion))?
                    .name(),
            })
        })
        .collect::<anyhow::Result<Vec<_>>>()?;
    let path = run.join(slurry::run::files::PARTICLES_H5);
    // The source's grid (its case's, which its history records).
    let grid = s.case.grid();
    let mut w = slurry::io::ParticleHistoryWriter::create(&path, grid, s.hist.gravity, &statics)
        .with_context(|| format!("cannot write {}", path.display()))?;
    for &(_, k) in &keep {
        w.append(&s.hist.frames[k]).with_context(|| format!("cannot write {}", path.display()))?;
    }
    w.finish().with_context(|| format!("cannot write {}", path.display()))?;
    slurry::io::checksum::write_list(dest, &[manifest::FILE, "run/case.toml", "run/particles.h5"])
        .with_context(|| format!("cannot write {}", dest.join(slurry::io::checksum::LIST_FILE).display()))?;
    Ok(StartPack {
        steps: keep.iter().map(|&(_, k)| s.hist.frames[k].step).collect(),
        phase_errors_deg: keep.iter().map(|&(e, _)| e.to_degrees()).collect(),
        bytes: std::fs::metadata(&path).map(|m| m.len()).unwrap_or(0),
    })
}

/// `v` as a deserializer, to read a kind of the case module by its name.
fn kind(v: &str) -> serde::de::value::StrDeserializer<'_, serde::de::value::Error> {
    serde::de::value::StrDeserializer::new(v)
}

/// Chooses the start frame of `src` for the scaled case `scaled` (module docs).
fn choose_start(name: &str, scaled: &Case, src: &Path) -> anyhow::Result<BedRecord> {
    let what = || format!("--start-from {}", src.display());
    let s = Source::open(src, &what, None)?;
    let (m, hist, src_tank) = (&s.manifest, &s.hist, &s.tank);
    anyhow::ensure!(m.case == name, "{}: a reproduction of {}, not of {name}", what(), m.case);
    let tip_radius = 0.5 * super::report::tank_of(scaled)?.1.diameter();
    let grid = scaled.grid();
    let factor =
        [grid.nx as f64 / hist.nx as f64, grid.ny as f64 / hist.ny as f64, grid.nz as f64 / hist.nz as f64];
    let spread = factor.iter().fold(0.0_f64, |a, &f| a.max((f / factor[2] - 1.0).abs()));
    anyhow::ensure!(
        spread <= 0.01,
        "{}: its grid {} x {} x {} is not similar to this one's {} x {} x {} (ratios {:?} differ by {:.1} %, at most 1 %)",
        what(),
        hist.nx,
        hist.ny,
        hist.nz,
        grid.nx,
        grid.ny,
        grid.nz,
        factor,
        100.0 * spread
    );
    let template = scaled.random_particles.first().ok_or_else(|| {
        anyhow::anyhow!("the scaled case {name} has no random particle population to replace")
    })?;
    let count = scaled.particle_count();
    anyhow::ensure!(
        hist.statics.len() == count,
        "{}: {} particles, this case has {count}",
        what(),
        hist.statics.len()
    );
    let order = &s.ranked;
    let mut refused = Vec::new();
    for &(eps, k) in order.iter().take(MAX_TRIED) {
        let tip_shift = tip_radius * eps.abs();
        if tip_shift > MAX_TIP_SHIFT {
            break;
        }
        let frame = &hist.frames[k];
        let particles: Vec<ParticleSpec> = frame
            .position
            .iter()
            .zip(&frame.quaternion)
            .map(|(x, q)| {
                let n = q.iter().map(|c| c * c).sum::<f64>().sqrt();
                ParticleSpec {
                    shape: template.shape,
                    diameter: template.diameter,
                    length: template.length,
                    density: template.density,
                    position: map_position(*x, factor),
                    orientation: Some(q.map(|c| c / n)),
                    axis: None,
                    velocity: None,
                    angular_velocity: None,
                    motion: MotionKind::Free,
                }
            })
            .collect();
        if let Err(e) = admissible(scaled, &particles) {
            refused.push(format!("step {}: {e}", frame.step));
            continue;
        }
        let mean_z = particles.iter().map(|p| p.position[2]).sum::<f64>() / particles.len() as f64;
        // The source frame's time and ⟨z_p⟩/H, as its report's Figure 5 has them.
        let (revolution, mean_height_over_h) =
            crate::stats::mean_height(std::slice::from_ref(frame), src_tank)[0];
        let from = StartFrom {
            dir: src.to_path_buf(),
            scale: m.scale,
            step: frame.step,
            revolution,
            mean_height_over_h,
            factor,
            phase_error_deg: eps.to_degrees(),
            tip_shift,
        };
        let inputs = format!("case {name}: {}", from.describe());
        let bed = Bed {
            particles,
            steps: 0,
            mean_speed: 0.0,
            max_speed: 0.0,
            settled: true,
            mean_height: mean_z,
            seconds: 0.0,
            restarts: 0,
            relax_steps: 0,
        };
        return Ok(BedRecord { inputs, wet: false, bed, start_from: Some(from), state_pack: None });
    }
    let best = order.first().map_or(f64::NAN, |o| o.0.to_degrees());
    anyhow::bail!(
        "{}: no frame of its last {WINDOW_REVOLUTIONS} revolutions can start this run: the smallest impeller phase \
         error is {best:.3} deg (tip shift at most {MAX_TIP_SHIFT} lattice units allowed){}",
        what(),
        if refused.is_empty() {
            String::new()
        } else {
            format!("; refused by the case's validation: {}", refused.join("; "))
        }
    )
}

#[cfg(test)]
mod tests {
    use std::f64::consts::TAU;

    use super::*;

    #[test]
    fn the_phase_error_is_the_angle_past_the_nearest_blade_position() {
        let q = TAU / 4.0;
        assert!((phase_error(q + 0.01, Some(q)) - 0.01).abs() < 1e-12);
        assert!((phase_error(3.0 * q - 0.02, Some(q)) + 0.02).abs() < 1e-12);
        assert!((phase_error(100.0 * TAU + 0.003, Some(q)) - 0.003).abs() < 1e-9);
        assert_eq!(phase_error(1.234, None), 0.0, "the disk: any angle");
    }

    #[test]
    fn the_pbt_turns_onto_itself_by_a_quarter_turn_the_disk_by_any_angle() {
        let angle = |name: &str| {
            let c = super::super::paper_case(name).unwrap().case().unwrap();
            super::super::report::tank_of(&c).unwrap().1.symmetry_angle()
        };
        assert_eq!(angle("pbt-ld2"), Some(TAU / 4.0));
        assert_eq!(angle("disk-ld2"), None);
    }

    /// A pack of `case` (its fingerprint) on the grid of `on`, with `bodies` (none, or no particles).
    fn pack_of(path: &Path, case: &Case, on: &Case, bodies: bool) {
        let grid = on.grid();
        let n = grid.nodes();
        let pack = slurry::io::StatePack {
            time_step: 1000,
            grid,
            rho: vec![1.0; n],
            velocity: vec![[0.0; 3]; n],
            force: None,
            bodies: bodies.then(Vec::new),
            case: case.fingerprint(),
            label: "test".into(),
            history: None,
        };
        slurry::io::write_state_pack(path, &pack).unwrap();
    }

    fn scaled(name: &str) -> Case {
        super::super::scale_case(&super::super::paper_case(name).unwrap().case().unwrap(), 0.25).unwrap()
    }

    /// The stirred case of `scaled` with its population as explicit particles (all at one
    /// place: only their kind and number are compared).
    fn stirred(scaled: &Case) -> Case {
        let mut c = scaled.clone();
        let t = c.random_particles.remove(0);
        let p = ParticleSpec {
            shape: t.shape,
            diameter: t.diameter,
            length: t.length,
            density: t.density,
            position: [10.0; 3],
            orientation: None,
            axis: None,
            velocity: None,
            angular_velocity: None,
            motion: t.motion,
        };
        c.particles = vec![p; scaled.particle_count()];
        c
    }

    /// A state pack of this case and scale is accepted: the record names the pack, its step
    /// and revolution, and is written to `start.json`, which a resume reads back (and refuses
    /// another source).
    #[test]
    fn a_state_pack_of_the_case_is_the_start() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("pack.h5");
        let s = scaled("pbt-ld2");
        pack_of(&path, &stirred(&s), &s, true);
        let rec = start_bed("pbt-ld2", &s, &path, dir.path(), false).unwrap();
        let p = rec.state_pack.clone().expect("a pack start");
        assert_eq!((p.step, p.label.as_str()), (1000, "test"));
        let spr = super::super::schedule(&s, 1.0).unwrap().steps_per_revolution;
        assert_eq!(p.revolution, 1000.0 / spr);
        assert!(rec.start_from.is_none() && matches!(rec.start(), RunStart::StatePack(_)));
        let again = start_bed("pbt-ld2", &s, &path, dir.path(), true).unwrap();
        assert_eq!(again.state_pack, rec.state_pack);
        let e = start_bed("pbt-ld2", &s, &dir.path().join("other.h5"), dir.path(), true).unwrap_err();
        assert!(e.to_string().contains("give that one"), "{e}");
    }

    /// Packs of another case, another scale, or without bodies are refused, each saying why.
    #[test]
    fn foreign_state_packs_are_refused() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("pack.h5");
        let s = scaled("pbt-ld2");
        for other in ["pbt-ld4", "disk-ld2"] {
            let o = scaled(other);
            pack_of(&path, &stirred(&o), &o, true);
            let e = start_bed("pbt-ld2", &s, &path, dir.path(), false).unwrap_err().to_string();
            assert!(e.contains("another case than pbt-ld2"), "{other}: {e}");
        }
        let third = super::super::scale_case(
            &super::super::paper_case("pbt-ld2").unwrap().case().unwrap(),
            1.0 / 3.0,
        );
        pack_of(&path, &stirred(&s), &third.unwrap(), true);
        let e = start_bed("pbt-ld2", &s, &path, dir.path(), false).unwrap_err().to_string();
        assert!(e.contains("84 x 84 x 80") && e.contains("--scale"), "{e}");
        pack_of(&path, &stirred(&s), &s, false);
        let e = start_bed("pbt-ld2", &s, &path, dir.path(), false).unwrap_err().to_string();
        assert!(e.contains("no bodies"), "{e}");
    }

    #[test]
    fn positions_map_wall_onto_wall() {
        // 63 × 63 × 60 (s = 1/4) onto 84 × 84 × 80 (s = 1/3): the walls at −½ and n − ½.
        let f = [84.0 / 63.0, 84.0 / 63.0, 80.0 / 60.0];
        assert_eq!(map_position([-0.5, -0.5, -0.5], f), [-0.5, -0.5, -0.5]);
        let far = map_position([62.5, 62.5, 59.5], f);
        for (a, b) in far.iter().zip([83.5, 83.5, 79.5]) {
            assert!((a - b).abs() < 1e-12, "{far:?}");
        }
        // The centre onto the centre.
        let c = map_position([31.0, 31.0, 29.5], f);
        assert!((c[0] - 41.5).abs() < 1e-12 && (c[2] - 39.5).abs() < 1e-12, "{c:?}");
    }
}
