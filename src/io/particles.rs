//! Particle histories in HDF5 (`particles.h5`): the state of every particle at every output
//! step, with the particles' static properties.
//!
//! # Layout
//! `F` frames (output steps), `P` particles, everything `f64` unless noted, lattice units
//! (root attribute `units = "lattice: Δ, Δt, ρ_f"`):
//!
//! | dataset | shape | units | contents |
//! |---|---|---|---|
//! | `time` | `[F]` | Δt | time of the frame (= `step`, Δt = 1) |
//! | `step` | `[F]` `u64` | 1 | time step of the frame |
//! | `position` | `[F, P, 3]` | Δ | centre of mass |
//! | `quaternion` | `[F, P, 4]` | 1 | orientation `[w, x, y, z]`, body → world (body `z` is a cylinder's axis) |
//! | `velocity` | `[F, P, 3]` | Δ/Δt | velocity of the centre of mass |
//! | `angular_velocity` | `[F, P, 3]` | 1/Δt | angular velocity, world frame |
//! | `force` | `[F, P, 3]` | ρ_f Δ⁴/Δt² | hydrodynamic force during the step that ended at the frame (0 at step 0) |
//! | `torque` | `[F, P, 3]` | ρ_f Δ⁵/Δt² | hydrodynamic torque about the centre, same step |
//! | `shape` | `[P]` string | – | `"sphere"` or `"cylinder"` |
//! | `diameter` | `[P]` | Δ | diameter `d` |
//! | `length` | `[P]` | Δ | cylinder length `ℓ`; NaN for spheres |
//! | `density` | `[P]` | ρ_f | density ratio `γ = ρ_p/ρ_f` |
//! | `volume` | `[P]` | Δ³ | particle volume |
//! | `mass` | `[P]` | ρ_f Δ³ | particle mass |
//! | `motion` | `[P]` string | – | `"free"`, `"fixed"` or `"prescribed"` |
//!
//! Every dataset has the attributes `units` and `description`. Root attributes: `units`,
//! `description`, `nx`, `ny`, `nz`, `particles` (`P`), `gravity` (`[3]`), `fluid_density`
//! (1). The frame datasets are chunked one frame per chunk and extendable along the first
//! axis.
//!
//! # Crash safety and cost: frame segments
//! The files on disk are always complete. [`ParticleHistoryWriter::create`] writes
//! `particles.h5` with the static data and zero frames. Frames are appended to **segments**
//! beside it, `particles.frames/000000.h5`, `000001.h5`, … ([`SEGMENT_FRAMES`] frames each, the
//! frame datasets and `time`, `step` of the layout above and a root attribute `particles`):
//! each [`ParticleHistoryWriter::append`] rewrites only the last segment atomically (copy,
//! extend by one frame, sync, rename: [`super::atomic_write`]). [`ParticleHistoryWriter::finish`]
//! (at the end of a run) merges the segments into `particles.h5` the same way and then
//! removes them. A crash at any moment leaves `particles.h5` and the segments of the previous
//! output step, and at worst a stale `.NAME.tmp.PID`; a crash between the merge's rename and
//! the removal leaves segments whose frames `particles.h5` already holds, which the readers
//! and [`ParticleHistoryWriter::resume`] recognise by their steps and skip.
//!
//! The cost is linear in the run: an output step copies at most one segment, `SEGMENT_FRAMES`
//! frames of `P × 19 × 8` bytes (32 × 250 kB = 8 MB for the paper's 1644 particles), and the
//! merge copies the history once. (Copying the whole file at every output step would cost
//! `O(F²)` bytes, 250 GB for a 2000-frame run of 822 particles.)
//!
//! [`read_particle_history`] reads `particles.h5` and then the segments, so a run in progress
//! or one stopped by an error reads like a finished one.
//!
//! # Reading
//! [`read_particle_history`] reads a file back whole ([`ParticleHistory`]: the static data as
//! [`ParticleProperties`], every frame, the grid and gravity); [`read_particle_history_from`]
//! reads only the frames from a given index on (the statistics' averaging window).

use std::path::{Path, PathBuf};

use hdf5::types::VarLenUnicode;

use super::atomic::atomic_write;
use crate::lattice::Grid;

/// The root `units` attribute.
pub const UNITS: &str = "lattice: Δ, Δt, ρ_f";

/// The per-frame datasets: name, components per particle, units, description.
pub const FRAME_DATASETS: [(&str, usize, &str, &str); 6] = [
    ("position", 3, "Δ", "centre of mass [x, y, z], world frame"),
    (
        "quaternion",
        4,
        "1",
        "orientation as a unit quaternion [w, x, y, z] that maps body-frame vectors to world-frame \
         vectors (v_world = q v_body q*); the body z axis is a cylinder's axis",
    ),
    ("velocity", 3, "Δ/Δt", "velocity of the centre of mass, world frame"),
    ("angular_velocity", 3, "1/Δt", "angular velocity, world frame (radians per time step)"),
    (
        "force",
        3,
        "ρ_f Δ⁴/Δt²",
        "hydrodynamic force on the particle (marker forces and the interior fluid's momentum change) \
         during the time step that ended at this frame; zero at step 0",
    ),
    (
        "torque",
        3,
        "ρ_f Δ⁵/Δt²",
        "hydrodynamic torque about the centre of mass during the time step that ended at this frame; \
         zero at step 0",
    ),
];

/// Frames per segment file (module docs, "Crash safety and cost").
pub const SEGMENT_FRAMES: usize = 32;

/// The segment directory of the history at `path`: `particles.h5` → `particles.frames/`.
pub fn segment_dir(path: &Path) -> PathBuf {
    path.with_extension("frames")
}

fn segment_path(dir: &Path, index: usize) -> PathBuf {
    dir.join(format!("{index:06}.h5"))
}

/// The segment files in `dir`, in order (`NNNNNN.h5`; none if `dir` does not exist). They
/// must be numbered `0, 1, …` without a gap.
fn segments(dir: &Path) -> Result<Vec<PathBuf>, ParticlesError> {
    let Ok(entries) = std::fs::read_dir(dir) else { return Ok(Vec::new()) };
    let mut found: Vec<usize> = Vec::new();
    for e in entries {
        let name = e?.file_name();
        let Some(stem) = name.to_str().and_then(|n| n.strip_suffix(".h5")) else { continue };
        if stem.len() == 6 && stem.bytes().all(|b| b.is_ascii_digit()) {
            found.push(stem.parse().expect("six digits"));
        }
    }
    found.sort_unstable();
    if let Some((i, &n)) = found.iter().enumerate().find(|&(i, &n)| i != n) {
        return Err(ParticlesError::Malformed(format!(
            "{}: segment {i:06}.h5 is missing (found {n:06}.h5)",
            dir.display()
        )));
    }
    Ok(found.iter().map(|&i| segment_path(dir, i)).collect())
}

/// Creates the extendable frame datasets (and `time`, `step`) with zero frames.
fn create_frame_datasets(file: &hdf5::File, p: usize) -> hdf5::Result<()> {
    let chunk_p = p.max(1);
    for (name, k, units, description) in FRAME_DATASETS {
        let d = file.new_dataset::<f64>().chunk((1, chunk_p, k)).shape((0.., p, k)).create(name)?;
        describe(&d, units, description)?;
    }
    let d = file.new_dataset::<f64>().chunk((64,)).shape((0..,)).create("time")?;
    describe(&d, "Δt", "time of the frame (equals step: Δt = 1)")?;
    let d = file.new_dataset::<u64>().chunk((64,)).shape((0..,)).create("step")?;
    describe(&d, "1", "time step of the frame")
}

/// Resizes the frame datasets of `file` to `frames` frames (cut or extend).
fn resize_frames(file: &hdf5::File, frames: usize, p: usize) -> hdf5::Result<()> {
    for (name, k, _, _) in FRAME_DATASETS {
        file.dataset(name)?.resize((frames, p, k))?;
    }
    file.dataset("time")?.resize((frames,))?;
    file.dataset("step")?.resize((frames,))
}

/// The steps of the frames in `file`.
fn steps_of(file: &hdf5::File) -> hdf5::Result<Vec<u64>> {
    file.dataset("step")?.read_raw::<u64>()
}

/// Copies `src`'s frames `from..` to `dst` at frame `at` (`dst` already resized).
fn copy_frames(src: &hdf5::File, from: usize, dst: &hdf5::File, at: usize) -> hdf5::Result<()> {
    let n = src.dataset("step")?.shape()[0] - from;
    for (name, _, _, _) in FRAME_DATASETS {
        let a = src.dataset(name)?.read_slice::<f64, _, ndarray::Ix3>(ndarray::s![from.., .., ..])?;
        dst.dataset(name)?.write_slice(&a, ndarray::s![at..at + n, .., ..])?;
    }
    let t = src.dataset("time")?.read_slice_1d::<f64, _>(from..)?;
    dst.dataset("time")?.write_slice(&t, at..at + n)?;
    let s = src.dataset("step")?.read_slice_1d::<u64, _>(from..)?;
    dst.dataset("step")?.write_slice(&s, at..at + n)
}

/// What does not change over a run: one entry per particle.
#[derive(Clone, Debug, PartialEq)]
pub struct ParticleStatic {
    /// `"sphere"` or `"cylinder"`.
    pub shape: &'static str,
    /// Diameter.
    pub diameter: f64,
    /// Cylinder length (NaN for spheres).
    pub length: f64,
    /// Density ratio `ρ_p/ρ_f`.
    pub density: f64,
    /// Volume.
    pub volume: f64,
    /// Mass.
    pub mass: f64,
    /// `"free"`, `"fixed"` or `"prescribed"`.
    pub motion: &'static str,
}

/// The state of every particle at one output step (particle order as in the static data).
#[derive(Clone, Debug, Default, PartialEq)]
pub struct ParticleFrame {
    /// Time step.
    pub step: u64,
    /// Time (`= step`).
    pub time: f64,
    /// Centres of mass.
    pub position: Vec<[f64; 3]>,
    /// Orientations `[w, x, y, z]`.
    pub quaternion: Vec<[f64; 4]>,
    /// Velocities.
    pub velocity: Vec<[f64; 3]>,
    /// Angular velocities (world frame).
    pub angular_velocity: Vec<[f64; 3]>,
    /// Hydrodynamic forces of the last step.
    pub force: Vec<[f64; 3]>,
    /// Hydrodynamic torques of the last step (about the centres).
    pub torque: Vec<[f64; 3]>,
}

impl ParticleFrame {
    /// The frame's arrays in [`FRAME_DATASETS`] order, flattened.
    fn arrays(&self) -> [&[f64]; 6] {
        [
            self.position.as_flattened(),
            self.quaternion.as_flattened(),
            self.velocity.as_flattened(),
            self.angular_velocity.as_flattened(),
            self.force.as_flattened(),
            self.torque.as_flattened(),
        ]
    }
}

/// Failure writing or reading the particle history.
#[derive(Debug, thiserror::Error)]
pub enum ParticlesError {
    /// File-system error (temporary file, copy, sync, rename); shown once.
    #[error("{}", super::fields::io_message(.0))]
    Io(std::io::Error),
    /// Error from the HDF5 library, as one line ([`super::fields::hdf5_message`]).
    #[error("{}", super::fields::hdf5_message(.0))]
    Hdf5(hdf5::Error),
    /// A frame array does not have one entry per particle.
    #[error("particle frame: {name} has {len} entries for {want} particles")]
    Length {
        /// Dataset name.
        name: &'static str,
        /// Entries given.
        len: usize,
        /// Particles.
        want: usize,
    },
    /// Array shape error (cannot happen once the lengths are checked).
    #[error("array shape: {0}")]
    Shape(#[from] ndarray::ShapeError),
    /// A file that does not have the documented layout (reading).
    #[error("particle history: {0}")]
    Malformed(String),
}

impl From<std::io::Error> for ParticlesError {
    fn from(e: std::io::Error) -> Self {
        ParticlesError::Io(e)
    }
}

impl From<hdf5::Error> for ParticlesError {
    fn from(e: hdf5::Error) -> Self {
        ParticlesError::Hdf5(e)
    }
}

fn text(s: &str) -> VarLenUnicode {
    s.replace('\0', " ").parse().expect("no NUL left")
}

fn describe(loc: &hdf5::Dataset, units: &str, description: &str) -> hdf5::Result<()> {
    loc.new_attr::<VarLenUnicode>().shape(()).create("units")?.write_scalar(&text(units))?;
    loc.new_attr::<VarLenUnicode>().shape(()).create("description")?.write_scalar(&text(description))?;
    Ok(())
}

/// Appends frames to `particles.h5`, keeping a complete file on disk at all times (module
/// docs).
#[derive(Debug)]
pub struct ParticleHistoryWriter {
    path: PathBuf,
    particles: usize,
    /// Frames written (in `particles.h5` and the segments).
    frames: usize,
    /// Frames in `particles.h5` itself; the rest are in the segments.
    merged: usize,
}

impl ParticleHistoryWriter {
    /// Creates (or replaces) `path` atomically with the static data of `particles` and zero
    /// frames. `grid` and `gravity` go into root attributes.
    pub fn create(
        path: &Path,
        grid: Grid,
        gravity: [f64; 3],
        particles: &[ParticleStatic],
    ) -> Result<Self, ParticlesError> {
        let p = particles.len();
        atomic_write(path, |tmp| -> Result<(), ParticlesError> {
            let file = hdf5::File::create(tmp)?;
            let root_text = |name: &str, value: &str| -> hdf5::Result<()> {
                file.new_attr::<VarLenUnicode>().shape(()).create(name)?.write_scalar(&text(value))
            };
            root_text("units", UNITS)?;
            root_text(
                "description",
                "slurry particle histories: one frame per output step (datasets [frames, particles, ...]) \
                 and static per-particle properties ([particles]); lattice units, fluid density 1",
            )?;
            for (name, v) in [("nx", grid.nx), ("ny", grid.ny), ("nz", grid.nz), ("particles", p)] {
                file.new_attr::<u64>().shape(()).create(name)?.write_scalar(&(v as u64))?;
            }
            file.new_attr::<f64>().shape([3]).create("gravity")?.write_raw(&gravity[..])?;
            file.new_attr::<f64>().shape(()).create("fluid_density")?.write_scalar(&1.0)?;

            create_frame_datasets(&file, p)?;

            let f64s = |name: &str, v: Vec<f64>, units: &str, description: &str| -> hdf5::Result<()> {
                let d = file.new_dataset::<f64>().shape([p]).create(name)?;
                d.write_raw(&v)?;
                describe(&d, units, description)
            };
            let strings = |name: &str, v: Vec<VarLenUnicode>, description: &str| -> hdf5::Result<()> {
                let d = file.new_dataset::<VarLenUnicode>().shape([p]).create(name)?;
                d.write_raw(&v)?;
                describe(&d, "-", description)
            };
            strings(
                "shape",
                particles.iter().map(|s| text(s.shape)).collect(),
                "\"sphere\" or \"cylinder\"",
            )?;
            f64s("diameter", particles.iter().map(|s| s.diameter).collect(), "Δ", "diameter d")?;
            f64s(
                "length",
                particles.iter().map(|s| s.length).collect(),
                "Δ",
                "cylinder length l along the body z axis; NaN for spheres",
            )?;
            f64s(
                "density",
                particles.iter().map(|s| s.density).collect(),
                "ρ_f",
                "density ratio rho_p/rho_f (the fluid density is 1)",
            )?;
            f64s("volume", particles.iter().map(|s| s.volume).collect(), "Δ³", "particle volume")?;
            f64s("mass", particles.iter().map(|s| s.mass).collect(), "ρ_f Δ³", "particle mass")?;
            strings(
                "motion",
                particles.iter().map(|s| text(s.motion)).collect(),
                "\"free\" (moves under its loads), \"fixed\" or \"prescribed\" (constant velocities)",
            )?;
            file.close()?;
            Ok(())
        })?;
        // Segments of an earlier history at this path are not part of the new one.
        remove_segments(path)?;
        Ok(Self { path: path.to_path_buf(), particles: p, frames: 0, merged: 0 })
    }

    /// Opens an existing `path` to continue a resumed run at `step`: frames written after
    /// `step` (by the interrupted run, past its last checkpoint) are cut off, atomically (copy,
    /// shrink, rename) in `particles.h5` or in the segment where they start (later segments are
    /// removed), so the history continues exactly as an uninterrupted run's would.
    pub fn resume(path: &Path, step: u64) -> Result<Self, ParticlesError> {
        let (steps, p) = {
            let file = hdf5::File::open(path)?;
            (steps_of(&file)?, file.attr("particles")?.read_scalar::<u64>()? as usize)
        };
        let keep = steps.iter().take_while(|&&s| s <= step).count();
        if keep < steps.len() {
            cut(path, keep, p)?;
            remove_segments(path)?;
            return Ok(Self { path: path.to_path_buf(), particles: p, frames: keep, merged: keep });
        }
        let dir = segment_dir(path);
        crate::io::remove_stale_temps(&dir);
        let mut last = steps.last().copied();
        let mut frames = keep;
        let segs = segments(&dir)?;
        for (i, seg) in segs.iter().enumerate() {
            let seg_steps = steps_of(&hdf5::File::open(seg)?)?;
            if i == 0 && seg_steps.first().zip(last).is_some_and(|(&first, last)| first <= last) {
                // Merged into particles.h5 before a crash left them: stale.
                remove_segments(path)?;
                frames = keep;
                break;
            }
            let k = seg_steps.iter().take_while(|&&s| s <= step).count();
            if k == seg_steps.len() && k != SEGMENT_FRAMES && i + 1 < segs.len() {
                return Err(ParticlesError::Malformed(format!(
                    "{}: {k} frames, not {SEGMENT_FRAMES}, with later segments",
                    seg.display()
                )));
            }
            if k < seg_steps.len() || i + 1 == segs.len() {
                // The last segment kept: cut to `k` frames (removed if none), the rest removed.
                if k == 0 {
                    std::fs::remove_file(seg)?;
                } else if k < seg_steps.len() {
                    cut(seg, k, p)?;
                }
                for later in &segs[i + 1..] {
                    std::fs::remove_file(later)?;
                }
                frames += k;
                break;
            }
            frames += k;
            last = seg_steps.last().copied();
        }
        Ok(Self { path: path.to_path_buf(), particles: p, frames, merged: keep })
    }

    /// Appends one frame to the last segment (module docs: copy, extend, rename; a new
    /// segment every [`SEGMENT_FRAMES`] frames).
    pub fn append(&mut self, frame: &ParticleFrame) -> Result<(), ParticlesError> {
        let p = self.particles;
        let arrays = frame.arrays();
        for ((name, k, _, _), a) in FRAME_DATASETS.iter().zip(&arrays) {
            if a.len() != p * k {
                return Err(ParticlesError::Length { name, len: a.len() / k, want: p });
            }
        }
        let local = self.frames - self.merged;
        let (index, f) = (local / SEGMENT_FRAMES, local % SEGMENT_FRAMES);
        let dir = segment_dir(&self.path);
        std::fs::create_dir_all(&dir)?;
        let seg = segment_path(&dir, index);
        atomic_write(&seg, |tmp| -> Result<(), ParticlesError> {
            let file = if f == 0 {
                let file = hdf5::File::create(tmp)?;
                file.new_attr::<u64>().shape(()).create("particles")?.write_scalar(&(p as u64))?;
                create_frame_datasets(&file, p)?;
                file
            } else {
                std::fs::copy(&seg, tmp)?;
                hdf5::File::open_rw(tmp)?
            };
            resize_frames(&file, f + 1, p)?;
            for ((name, k, _, _), a) in FRAME_DATASETS.iter().zip(&arrays) {
                let view = ndarray::ArrayView3::from_shape((1, p, *k), a)?;
                file.dataset(name)?.write_slice(view, ndarray::s![f..f + 1, .., ..])?;
            }
            file.dataset("time")?.write_slice(&[frame.time][..], f..f + 1)?;
            file.dataset("step")?.write_slice(&[frame.step][..], f..f + 1)?;
            file.close()?;
            Ok(())
        })?;
        self.frames += 1;
        Ok(())
    }

    /// Merges the segments into `particles.h5` (atomically: copy, extend, rename) and removes
    /// them: one file holds the whole history. Called at the end of a run; appending may go on
    /// after it.
    pub fn finish(&mut self) -> Result<(), ParticlesError> {
        if self.frames > self.merged {
            let (p, merged, frames) = (self.particles, self.merged, self.frames);
            let segs = segments(&segment_dir(&self.path))?;
            let path = self.path.clone();
            atomic_write(&path, |tmp| -> Result<(), ParticlesError> {
                std::fs::copy(&path, tmp)?;
                let file = hdf5::File::open_rw(tmp)?;
                resize_frames(&file, frames, p)?;
                let mut at = merged;
                for seg in &segs {
                    let src = hdf5::File::open(seg)?;
                    copy_frames(&src, 0, &file, at)?;
                    at += src.dataset("step")?.shape()[0];
                }
                if at != frames {
                    return Err(ParticlesError::Malformed(format!(
                        "{}: the segments hold {} frames, {} were written",
                        segment_dir(&path).display(),
                        at - merged,
                        frames - merged
                    )));
                }
                file.close()?;
                Ok(())
            })?;
            self.merged = frames;
        }
        remove_segments(&self.path)
    }

    /// Frames written.
    pub fn frames(&self) -> usize {
        self.frames
    }

    /// Particles per frame.
    pub fn particles(&self) -> usize {
        self.particles
    }

    /// The file's path.
    pub fn path(&self) -> &Path {
        &self.path
    }
}

/// Cuts the history file (or segment) at `path` to its first `keep` frames, atomically.
fn cut(path: &Path, keep: usize, p: usize) -> Result<(), ParticlesError> {
    atomic_write(path, |tmp| -> Result<(), ParticlesError> {
        std::fs::copy(path, tmp)?;
        let file = hdf5::File::open_rw(tmp)?;
        resize_frames(&file, keep, p)?;
        file.close()?;
        Ok(())
    })
}

/// The steps of every frame of the history at `path`, in order: `particles.h5`'s, then the
/// segments' (those `particles.h5` already holds skipped, as the readers skip them). Reads
/// only the `step` datasets.
///
/// # Errors
/// A file cannot be read, or a segment is missing before the last (`segments`).
pub fn history_steps(path: &Path) -> Result<Vec<u64>, ParticlesError> {
    let mut steps = steps_of(&hdf5::File::open(path)?)?;
    for seg in segments(&segment_dir(path))? {
        let last = steps.last().copied();
        steps.extend(steps_of(&hdf5::File::open(&seg)?)?.into_iter().filter(|&s| last.is_none_or(|l| s > l)));
    }
    Ok(steps)
}

/// Removes the segment directory of the history at `path`, if there is one.
fn remove_segments(path: &Path) -> Result<(), ParticlesError> {
    match std::fs::remove_dir_all(segment_dir(path)) {
        Err(e) if e.kind() != std::io::ErrorKind::NotFound => Err(e.into()),
        _ => Ok(()),
    }
}

/// A particle's static properties as read back from `particles.h5` (owned strings; the
/// writer's [`ParticleStatic`] borrows `'static` names).
#[derive(Clone, Debug, PartialEq)]
pub struct ParticleProperties {
    /// `"sphere"` or `"cylinder"`.
    pub shape: String,
    /// Diameter `d` (Δ).
    pub diameter: f64,
    /// Cylinder length `ℓ` (Δ); NaN for spheres.
    pub length: f64,
    /// Density ratio `ρ_p/ρ_f`.
    pub density: f64,
    /// Volume (Δ³).
    pub volume: f64,
    /// Mass (ρ_f Δ³).
    pub mass: f64,
    /// `"free"`, `"fixed"` or `"prescribed"`.
    pub motion: String,
}

/// The contents of a `particles.h5` ([`read_particle_history`]).
#[derive(Clone, Debug, PartialEq)]
pub struct ParticleHistory {
    /// Static properties, one entry per particle (the frames' particle order).
    pub statics: Vec<ParticleProperties>,
    /// The frames read, in file (step) order.
    pub frames: Vec<ParticleFrame>,
    /// Index of the first frame read in the file (0 unless [`read_particle_history_from`]
    /// skipped frames).
    pub first_frame: usize,
    /// Frames in the file (read or skipped).
    pub frames_in_file: usize,
    /// Grid size along x (the tank's footprint side).
    pub nx: usize,
    /// Grid size along y.
    pub ny: usize,
    /// Grid size along z (the tank's height).
    pub nz: usize,
    /// Gravitational acceleration (Δ/Δt²).
    pub gravity: [f64; 3],
}

/// Reads the whole particle history written by [`ParticleHistoryWriter`] (module docs for the
/// layout).
pub fn read_particle_history(path: &Path) -> Result<ParticleHistory, ParticlesError> {
    read_particle_history_from(path, 0)
}

/// Reads the particle history written by [`ParticleHistoryWriter`], skipping the frames before
/// frame index `first_frame` (only the frames `first_frame..` are read from disk; a
/// `first_frame` at or past the end gives no frames).
pub fn read_particle_history_from(
    path: &Path,
    first_frame: usize,
) -> Result<ParticleHistory, ParticlesError> {
    let malformed = |what: String| ParticlesError::Malformed(format!("{}: {what}", path.display()));
    let file = hdf5::File::open(path)?;
    let attr_u64 =
        |name: &str| -> hdf5::Result<usize> { Ok(file.attr(name)?.read_scalar::<u64>()? as usize) };
    let (nx, ny, nz, p) = (attr_u64("nx")?, attr_u64("ny")?, attr_u64("nz")?, attr_u64("particles")?);
    let g = file.attr("gravity")?.read_raw::<f64>()?;
    let gravity: [f64; 3] = g
        .as_slice()
        .try_into()
        .map_err(|_| malformed(format!("gravity has {} components, not 3", g.len())))?;

    let f64s = |name: &str| -> Result<Vec<f64>, ParticlesError> {
        let v = file.dataset(name)?.read_raw::<f64>()?;
        if v.len() != p {
            return Err(malformed(format!("{name} has {} entries for {p} particles", v.len())));
        }
        Ok(v)
    };
    let strings = |name: &str| -> Result<Vec<String>, ParticlesError> {
        let v = file.dataset(name)?.read_raw::<VarLenUnicode>()?;
        if v.len() != p {
            return Err(malformed(format!("{name} has {} entries for {p} particles", v.len())));
        }
        Ok(v.iter().map(|s| s.as_str().to_string()).collect())
    };
    let (shape, motion) = (strings("shape")?, strings("motion")?);
    let (diameter, length, density) = (f64s("diameter")?, f64s("length")?, f64s("density")?);
    let (volume, mass) = (f64s("volume")?, f64s("mass")?);
    let statics = (0..p)
        .map(|i| ParticleProperties {
            shape: shape[i].clone(),
            diameter: diameter[i],
            length: length[i],
            density: density[i],
            volume: volume[i],
            mass: mass[i],
            motion: motion[i].clone(),
        })
        .collect();

    // particles.h5's frames, then the segments' (module docs), skipping segment frames that
    // particles.h5 already holds (a merge interrupted before it removed them).
    let mut frames: Vec<ParticleFrame> = Vec::new();
    let total_main = file.dataset("step")?.shape().first().copied().unwrap_or(0);
    let mut last = read_frames(&file, p, first_frame, &mut frames, &malformed)?;
    let mut total = total_main;
    for seg in segments(&segment_dir(path))? {
        let sf = hdf5::File::open(&seg)?;
        let steps = steps_of(&sf)?;
        let fresh = steps.iter().position(|&s| last.is_none_or(|l| s > l)).unwrap_or(steps.len());
        let n = steps.len() - fresh;
        // Global index of this segment's first fresh frame is `total`.
        let skip = first_frame.saturating_sub(total).min(n);
        let from = fresh + skip;
        if from < steps.len() {
            read_frames(&sf, p, from, &mut frames, &malformed)?;
        }
        if n > 0 {
            last = steps.last().copied();
        }
        total += n;
    }
    let first = first_frame.min(total);
    Ok(ParticleHistory { statics, frames, first_frame: first, frames_in_file: total, nx, ny, nz, gravity })
}

/// Appends the frames `first..` of `file` (particles.h5 or a segment, `p` particles) to
/// `frames`; returns the step of `file`'s last frame.
fn read_frames(
    file: &hdf5::File,
    p: usize,
    first: usize,
    frames: &mut Vec<ParticleFrame>,
    malformed: &dyn Fn(String) -> ParticlesError,
) -> Result<Option<u64>, ParticlesError> {
    let steps_d = file.dataset("step")?;
    let total = steps_d.shape().first().copied().unwrap_or(0);
    let last =
        if total > 0 { steps_d.read_slice_1d::<u64, _>(total - 1..total)?.first().copied() } else { None };
    let first = first.min(total);
    let count = total - first;
    if count == 0 {
        return Ok(last);
    }
    let start = frames.len();
    let steps = steps_d.read_slice_1d::<u64, _>(first..total)?;
    let times = file.dataset("time")?.read_slice_1d::<f64, _>(first..total)?;
    if times.len() != count {
        return Err(malformed(format!("time has {} frames, step has {total}", times.len() + first)));
    }
    for (&step, &time) in steps.iter().zip(times.iter()) {
        frames.push(ParticleFrame { step, time, ..Default::default() });
    }
    for (name, k, _, _) in FRAME_DATASETS {
        let d = file.dataset(name)?;
        if d.shape() != [total, p, k] {
            return Err(malformed(format!("{name} has shape {:?}, expected [{total}, {p}, {k}]", d.shape())));
        }
        let a = d.read_slice::<f64, _, ndarray::Ix3>(ndarray::s![first..total, .., ..])?;
        for (frame, block) in frames[start..].iter_mut().zip(a.outer_iter()) {
            let rows = block.outer_iter();
            match k {
                3 => {
                    let v: Vec<[f64; 3]> = rows.map(|r| [r[0], r[1], r[2]]).collect();
                    match name {
                        "position" => frame.position = v,
                        "velocity" => frame.velocity = v,
                        "angular_velocity" => frame.angular_velocity = v,
                        "force" => frame.force = v,
                        "torque" => frame.torque = v,
                        _ => unreachable!("FRAME_DATASETS has no other three-component dataset"),
                    }
                }
                4 => frame.quaternion = rows.map(|r| [r[0], r[1], r[2], r[3]]).collect(),
                _ => unreachable!("FRAME_DATASETS has three- and four-component datasets only"),
            }
        }
    }
    Ok(last)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn statics() -> Vec<ParticleStatic> {
        vec![
            ParticleStatic {
                shape: "sphere",
                diameter: 6.0,
                length: f64::NAN,
                density: 1.25,
                volume: 113.1,
                mass: 141.4,
                motion: "fixed",
            },
            ParticleStatic {
                shape: "cylinder",
                diameter: 4.0,
                length: 8.0,
                density: 2.0,
                volume: 100.5,
                mass: 201.0,
                motion: "free",
            },
        ]
    }

    fn frame(step: u64) -> ParticleFrame {
        let s = step as f64;
        ParticleFrame {
            step,
            time: s,
            position: vec![[s, 1.0, 2.0], [3.0, 4.0, s]],
            quaternion: vec![[1.0, 0.0, 0.0, 0.0], [0.0, 1.0, 0.0, s]],
            velocity: vec![[0.1; 3], [0.2; 3]],
            angular_velocity: vec![[0.0; 3], [0.0, 0.0, s]],
            force: vec![[1.0, 2.0, 3.0], [4.0, 5.0, 6.0]],
            torque: vec![[-1.0; 3], [-2.0; 3]],
        }
    }

    #[test]
    fn frames_append_with_the_documented_shapes() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("particles.h5");
        let mut w =
            ParticleHistoryWriter::create(&path, Grid::new(8, 9, 10), [0.0, 0.0, -1e-5], &statics()).unwrap();
        // Readable with zero frames.
        let f = hdf5::File::open(&path).unwrap();
        assert_eq!(f.dataset("position").unwrap().shape(), vec![0, 2, 3]);
        drop(f);
        for step in [0, 10, 20] {
            w.append(&frame(step)).unwrap();
        }
        assert_eq!(w.frames(), 3);
        w.finish().unwrap();
        assert!(!segment_dir(&path).exists(), "segments left after the merge");
        let f = hdf5::File::open(&path).unwrap();
        assert_eq!(f.dataset("position").unwrap().shape(), vec![3, 2, 3]);
        assert_eq!(f.dataset("quaternion").unwrap().shape(), vec![3, 2, 4]);
        for name in ["velocity", "angular_velocity", "force", "torque"] {
            assert_eq!(f.dataset(name).unwrap().shape(), vec![3, 2, 3], "{name}");
        }
        assert_eq!(f.dataset("step").unwrap().read_raw::<u64>().unwrap(), vec![0, 10, 20]);
        assert_eq!(f.dataset("time").unwrap().read_raw::<f64>().unwrap(), vec![0.0, 10.0, 20.0]);
        let pos = f.dataset("position").unwrap().read_raw::<f64>().unwrap();
        // Frame 2, particle 1: [3, 4, 20].
        assert_eq!(&pos[(2 * 2 + 1) * 3..(2 * 2 + 2) * 3], &[3.0, 4.0, 20.0]);
        let shapes = f.dataset("shape").unwrap().read_raw::<VarLenUnicode>().unwrap();
        assert_eq!(shapes[1].as_str(), "cylinder");
        let len = f.dataset("length").unwrap().read_raw::<f64>().unwrap();
        assert!(len[0].is_nan() && len[1] == 8.0);
        let units: VarLenUnicode = f.attr("units").unwrap().read_scalar().unwrap();
        assert_eq!(units.as_str(), UNITS);
        let d: VarLenUnicode = f.dataset("force").unwrap().attr("units").unwrap().read_scalar().unwrap();
        assert_eq!(d.as_str(), "ρ_f Δ⁴/Δt²");
        assert_eq!(std::fs::read_dir(dir.path()).unwrap().count(), 1, "temporary file left");
    }

    #[test]
    fn wrong_frame_length_is_an_error_and_leaves_the_file() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("particles.h5");
        let mut w = ParticleHistoryWriter::create(&path, Grid::new(4, 4, 4), [0.0; 3], &statics()).unwrap();
        w.append(&frame(0)).unwrap();
        let mut bad = frame(1);
        bad.torque.pop();
        assert!(matches!(w.append(&bad), Err(ParticlesError::Length { name: "torque", len: 1, want: 2 })));
        w.finish().unwrap();
        let f = hdf5::File::open(&path).unwrap();
        assert_eq!(f.dataset("torque").unwrap().shape(), vec![1, 2, 3]);
    }

    #[test]
    fn read_back_round_trips_the_writer() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("particles.h5");
        let gravity = [0.0, 1e-6, -1e-5];
        let mut w = ParticleHistoryWriter::create(&path, Grid::new(8, 9, 10), gravity, &statics()).unwrap();
        let empty = read_particle_history(&path).unwrap();
        assert!(empty.frames.is_empty());
        assert_eq!(empty.statics.len(), 2);
        let written: Vec<ParticleFrame> = [0, 10, 20, 30].into_iter().map(frame).collect();
        for f in &written {
            w.append(f).unwrap();
        }
        let h = read_particle_history(&path).unwrap();
        assert_eq!((h.nx, h.ny, h.nz), (8, 9, 10));
        assert_eq!(h.gravity, gravity);
        assert_eq!((h.first_frame, h.frames_in_file), (0, 4));
        assert_eq!(h.frames, written);
        for (read, want) in h.statics.iter().zip(statics()) {
            assert_eq!(read.shape, want.shape);
            assert_eq!(read.motion, want.motion);
            assert_eq!(read.diameter, want.diameter);
            assert_eq!(read.length.to_bits(), want.length.to_bits());
            assert_eq!((read.density, read.volume, read.mass), (want.density, want.volume, want.mass));
        }
        let tail = read_particle_history_from(&path, 2).unwrap();
        assert_eq!((tail.first_frame, tail.frames_in_file), (2, 4));
        assert_eq!(tail.frames, written[2..]);
        let none = read_particle_history_from(&path, 9).unwrap();
        assert!(none.frames.is_empty());
        // (Debug text: the sphere's NaN length makes `==` false.)
        assert_eq!(format!("{:?}", none.statics), format!("{:?}", h.statics));
    }
    /// Frames `0, 10, 20, …`: `n` of them.
    fn frames(n: u64) -> Vec<ParticleFrame> {
        (0..n).map(|i| frame(10 * i)).collect()
    }

    #[test]
    fn segments_read_like_one_file_before_and_after_the_merge() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("particles.h5");
        let mut w = ParticleHistoryWriter::create(&path, Grid::new(4, 4, 4), [0.0; 3], &statics()).unwrap();
        let written = frames(2 * SEGMENT_FRAMES as u64 + 5);
        for f in &written {
            w.append(f).unwrap();
        }
        // Three segments, particles.h5 still without frames.
        assert_eq!(segments(&segment_dir(&path)).unwrap().len(), 3);
        assert_eq!(hdf5::File::open(&path).unwrap().dataset("step").unwrap().shape(), vec![0]);
        let during = read_particle_history(&path).unwrap();
        assert_eq!(during.frames, written);
        let tail = read_particle_history_from(&path, SEGMENT_FRAMES + 3).unwrap();
        assert_eq!((tail.first_frame, tail.frames_in_file), (SEGMENT_FRAMES + 3, written.len()));
        assert_eq!(tail.frames, written[SEGMENT_FRAMES + 3..]);
        w.finish().unwrap();
        assert!(!segment_dir(&path).exists());
        assert_eq!(read_particle_history(&path).unwrap().frames, written);
        // Appending goes on after a merge, into new segments.
        let more = frame(10_000);
        w.append(&more).unwrap();
        let all = read_particle_history(&path).unwrap();
        assert_eq!(all.frames.len(), written.len() + 1);
        assert_eq!(all.frames.last(), Some(&more));
    }

    #[test]
    fn resume_cuts_in_a_segment_and_continues_as_uninterrupted() {
        let dir = tempfile::tempdir().unwrap();
        let all = frames(SEGMENT_FRAMES as u64 + 10);
        // Interrupted: everything written, then resumed at the step of frame SEGMENT_FRAMES + 4.
        let path = dir.path().join("particles.h5");
        let mut w = ParticleHistoryWriter::create(&path, Grid::new(4, 4, 4), [0.0; 3], &statics()).unwrap();
        for f in &all {
            w.append(f).unwrap();
        }
        drop(w);
        let at = SEGMENT_FRAMES + 4;
        let mut r = ParticleHistoryWriter::resume(&path, all[at].step).unwrap();
        assert_eq!(r.frames(), at + 1);
        assert_eq!(read_particle_history(&path).unwrap().frames, all[..=at]);
        for f in &all[at + 1..] {
            r.append(f).unwrap();
        }
        r.finish().unwrap();
        assert_eq!(read_particle_history(&path).unwrap().frames, all);
        // Resumed exactly at a segment boundary, and at a step before every frame.
        let mut r = ParticleHistoryWriter::resume(&path, all[SEGMENT_FRAMES - 1].step).unwrap();
        assert_eq!(r.frames(), SEGMENT_FRAMES);
        r.append(&all[SEGMENT_FRAMES]).unwrap();
        assert_eq!(read_particle_history(&path).unwrap().frames, all[..=SEGMENT_FRAMES]);
        let r = ParticleHistoryWriter::resume(&path, 0).unwrap();
        assert_eq!(r.frames(), 1);
        assert!(!segment_dir(&path).exists());
    }

    #[test]
    fn segments_left_by_an_interrupted_merge_are_skipped() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("particles.h5");
        let mut w = ParticleHistoryWriter::create(&path, Grid::new(4, 4, 4), [0.0; 3], &statics()).unwrap();
        let written = frames(SEGMENT_FRAMES as u64 + 2);
        for f in &written {
            w.append(f).unwrap();
        }
        // The merge renamed particles.h5 but died before removing the segments.
        let keep = dir.path().join("keep");
        std::fs::create_dir(&keep).unwrap();
        for seg in segments(&segment_dir(&path)).unwrap() {
            std::fs::copy(&seg, keep.join(seg.file_name().unwrap())).unwrap();
        }
        w.finish().unwrap();
        std::fs::rename(&keep, segment_dir(&path)).unwrap();
        assert_eq!(read_particle_history(&path).unwrap().frames, written);
        let mut r = ParticleHistoryWriter::resume(&path, written.last().unwrap().step).unwrap();
        assert_eq!(r.frames(), written.len());
        assert!(!segment_dir(&path).exists(), "stale segments kept");
        r.append(&frame(99_999)).unwrap();
        assert_eq!(read_particle_history(&path).unwrap().frames.len(), written.len() + 1);
    }
}
