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
//! # Crash safety and cost
//! The file on disk is always complete: [`ParticleHistoryWriter::create`] writes it with zero
//! frames, and each [`ParticleHistoryWriter::append`] copies it to a temporary file beside it,
//! extends the copy's datasets by one frame, closes and syncs the copy and renames it over the
//! original ([`super::atomic_write`]). A crash at any moment leaves the file of the previous
//! output step (a readable file with every frame up to it) and at worst a stale
//! `.particles.h5.tmp.PID`.
//!
//! The price is one copy of the file per output step: `O(F · P)` bytes, so `O(F² P)` over a
//! run. A frame is `P × 19 × 8` bytes (about 250 kB for the paper's 1644 particles), so at
//! 1000 frames the file is about 250 MB and an output step copies it once (a fraction of a second on a local disk; file systems with reflinks, such
//! as XFS and Btrfs, copy without moving the data). Pick `run.output_every` so that the
//! copying stays small beside the stepping between outputs; the paper's 800 000 steps at one
//! frame every 1000 steps (800 frames) copy about 80 GB in all, minutes against days of stepping.
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
    frames: usize,
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

            let chunk_p = p.max(1);
            for (name, k, units, description) in FRAME_DATASETS {
                let d = file.new_dataset::<f64>().chunk((1, chunk_p, k)).shape((0.., p, k)).create(name)?;
                describe(&d, units, description)?;
            }
            let d = file.new_dataset::<f64>().chunk((64,)).shape((0..,)).create("time")?;
            describe(&d, "Δt", "time of the frame (equals step: Δt = 1)")?;
            let d = file.new_dataset::<u64>().chunk((64,)).shape((0..,)).create("step")?;
            describe(&d, "1", "time step of the frame")?;

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
        Ok(Self { path: path.to_path_buf(), particles: p, frames: 0 })
    }

    /// Opens an existing `path` to continue a resumed run at `step`: frames written after
    /// `step` (by the interrupted run, past its last checkpoint) are cut off, atomically (copy,
    /// shrink, rename), so the file continues exactly as an uninterrupted run's would.
    pub fn resume(path: &Path, step: u64) -> Result<Self, ParticlesError> {
        let (keep, total, p) = {
            let file = hdf5::File::open(path)?;
            let steps = file.dataset("step")?.read_raw::<u64>()?;
            let p = file.attr("particles")?.read_scalar::<u64>()? as usize;
            (steps.iter().take_while(|&&s| s <= step).count(), steps.len(), p)
        };
        if keep < total {
            atomic_write(path, |tmp| -> Result<(), ParticlesError> {
                std::fs::copy(path, tmp)?;
                let file = hdf5::File::open_rw(tmp)?;
                for (name, k, _, _) in FRAME_DATASETS {
                    file.dataset(name)?.resize((keep, p, k))?;
                }
                file.dataset("time")?.resize((keep,))?;
                file.dataset("step")?.resize((keep,))?;
                file.close()?;
                Ok(())
            })?;
        }
        Ok(Self { path: path.to_path_buf(), particles: p, frames: keep })
    }

    /// Appends one frame (module docs: copy, extend, rename).
    pub fn append(&mut self, frame: &ParticleFrame) -> Result<(), ParticlesError> {
        let p = self.particles;
        let arrays = frame.arrays();
        for ((name, k, _, _), a) in FRAME_DATASETS.iter().zip(&arrays) {
            if a.len() != p * k {
                return Err(ParticlesError::Length { name, len: a.len() / k, want: p });
            }
        }
        let f = self.frames;
        let path = self.path.clone();
        atomic_write(&path, |tmp| -> Result<(), ParticlesError> {
            std::fs::copy(&path, tmp)?;
            let file = hdf5::File::open_rw(tmp)?;
            for ((name, k, _, _), a) in FRAME_DATASETS.iter().zip(&arrays) {
                let d = file.dataset(name)?;
                d.resize((f + 1, p, *k))?;
                let view = ndarray::ArrayView3::from_shape((1, p, *k), a)?;
                d.write_slice(view, ndarray::s![f..f + 1, .., ..])?;
            }
            let d = file.dataset("time")?;
            d.resize((f + 1,))?;
            d.write_slice(&[frame.time][..], f..f + 1)?;
            let d = file.dataset("step")?;
            d.resize((f + 1,))?;
            d.write_slice(&[frame.step][..], f..f + 1)?;
            file.close()?;
            Ok(())
        })?;
        self.frames += 1;
        Ok(())
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

    let steps_d = file.dataset("step")?;
    let total = steps_d.shape().first().copied().unwrap_or(0);
    let first = first_frame.min(total);
    let count = total - first;
    let mut frames: Vec<ParticleFrame> = Vec::with_capacity(count);
    if count > 0 {
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
                return Err(malformed(format!(
                    "{name} has shape {:?}, expected [{total}, {p}, {k}]",
                    d.shape()
                )));
            }
            let a = d.read_slice::<f64, _, ndarray::Ix3>(ndarray::s![first..total, .., ..])?;
            for (frame, block) in frames.iter_mut().zip(a.outer_iter()) {
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
    }
    Ok(ParticleHistory { statics, frames, first_frame: first, frames_in_file: total, nx, ny, nz, gravity })
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
}
