//! Checkpoints: the fluid's complete state in HDF5, written atomically.
//!
//! Layout: `/populations` is `T[19][nz][ny][nx]` (shifted populations `h = f − w`, storage
//! precision `T`, so a restart is bitwise exact), `/force` is `T[3][nz][ny][nx]` when the force
//! field is on (runs with particles or an impeller: the last step's IBM forcing, which the
//! velocity's half-force term at the checkpoint's step needs, so that the outputs of a run
//! resumed there equal the uninterrupted run's; checkpoints written before it was stored
//! restore with a zero field, exact for every later step). Root attributes: `time_step`, `precision`, `nx`, `ny`, `nz`, and `case`: a
//! fingerprint of the case (its normalised TOML without `run.steps`, so that a run can be
//! extended) which a resume compares before it restores anything. With particles, `/bodies`
//! is `f64[P][26]` ([`BODY_STATE_LEN`]).
//!
//! The file is written to a temporary name, synced and renamed: a run killed at any moment
//! leaves either the previous checkpoint or the new one, never a torn file.

use std::path::Path;

use hdf5::types::VarLenUnicode;

use super::atomic::atomic_write;
use super::fields::FieldsError;
use crate::lattice::{Grid, Q};
use crate::lbm::{FluidState, Real};

/// Numbers per body in `/bodies`: position (3), orientation quaternion `w, x, y, z` (4),
/// velocity (3), angular velocity (3), time (1), the last step's change of velocity (3) and
/// of angular velocity (3), its averaged contact force (3) and torque (3) — what
/// `coupling::Coupled::restore` needs.
pub const BODY_STATE_LEN: usize = 26;

/// A checkpoint read back: the state and the case fingerprint it was written with.
pub struct Checkpoint<T> {
    /// The fluid state.
    pub state: FluidState<T>,
    /// The particles' states, one row of [`BODY_STATE_LEN`] numbers per body, if the run had
    /// particles.
    pub bodies: Option<Vec<[f64; BODY_STATE_LEN]>>,
    /// The case fingerprint stored with it.
    pub case: String,
}

/// A checkpoint written with another storage precision than the case asks for.
#[derive(Clone, Debug, thiserror::Error)]
#[error("{path}: the checkpoint's precision is {found}, the case asks for {want}")]
pub struct PrecisionMismatch {
    /// The checkpoint.
    pub path: std::path::PathBuf,
    /// Its precision.
    pub found: String,
    /// The case's.
    pub want: &'static str,
}

/// Writes `state` with the case fingerprint `case` to `path`, atomically.
pub fn write_checkpoint<T: Real + hdf5::H5Type>(
    path: &Path,
    state: &FluidState<T>,
    bodies: Option<&[[f64; BODY_STATE_LEN]]>,
    case: &str,
) -> Result<(), FieldsError> {
    let g = state.grid;
    atomic_write(path, |tmp| -> Result<(), FieldsError> {
        let file = hdf5::File::create(tmp)?;
        let text = |s: &str| -> VarLenUnicode { s.replace('\0', " ").parse().expect("no NUL left") };
        file.new_attr::<VarLenUnicode>().shape(()).create("case")?.write_scalar(&text(case))?;
        file.new_attr::<VarLenUnicode>().shape(()).create("precision")?.write_scalar(&text(T::NAME))?;
        file.new_attr::<u64>().shape(()).create("time_step")?.write_scalar(&state.time)?;
        for (name, v) in [("nx", g.nx), ("ny", g.ny), ("nz", g.nz)] {
            file.new_attr::<u64>().shape(()).create(name)?.write_scalar(&(v as u64))?;
        }
        let d = file.new_dataset::<T>().shape([Q, g.nz, g.ny, g.nx]).create("populations")?;
        d.write_raw(&state.populations)?;
        if let Some(force) = &state.force {
            let d = file.new_dataset::<T>().shape([3, g.nz, g.ny, g.nx]).create("force")?;
            d.write_raw(force)?;
        }
        if let Some(b) = bodies {
            let flat: Vec<f64> = b.iter().flatten().copied().collect();
            let d = file.new_dataset::<f64>().shape([b.len(), BODY_STATE_LEN]).create("bodies")?;
            d.write_raw(&flat)?;
        }
        file.close()?;
        Ok(())
    })
}

/// Reads a checkpoint written by [`write_checkpoint`] with the same precision `T`.
pub fn read_checkpoint<T: Real + hdf5::H5Type>(path: &Path) -> anyhow::Result<Checkpoint<T>> {
    let file = hdf5::File::open(path)?;
    let precision = file.attr("precision")?.read_scalar::<VarLenUnicode>()?.to_string();
    if precision != T::NAME {
        return Err(PrecisionMismatch { path: path.to_path_buf(), found: precision, want: T::NAME }.into());
    }
    let get = |name: &str| -> anyhow::Result<u64> { Ok(file.attr(name)?.read_scalar::<u64>()?) };
    let grid = Grid::new(get("nx")? as usize, get("ny")? as usize, get("nz")? as usize);
    let populations = file.dataset("populations")?.read_raw::<T>()?;
    let force = match file.dataset("force") {
        Ok(d) => Some(d.read_raw::<T>()?),
        Err(_) => None,
    };
    let bodies = match file.dataset("bodies") {
        Ok(d) => {
            let flat = d.read_raw::<f64>()?;
            if flat.len() % BODY_STATE_LEN != 0 {
                anyhow::bail!(
                    "{}: /bodies has {} values, not rows of {BODY_STATE_LEN}",
                    path.display(),
                    flat.len()
                );
            }
            Some(flat.chunks(BODY_STATE_LEN).map(|c| std::array::from_fn(|k| c[k])).collect())
        }
        Err(_) => None,
    };
    Ok(Checkpoint {
        bodies,
        state: FluidState { time: get("time_step")?, grid, populations, force },
        case: file.attr("case")?.read_scalar::<VarLenUnicode>()?.to_string(),
    })
}
