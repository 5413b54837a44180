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
//! is `f64[P][26]`: one row of [`BODY_STATE_LEN`] numbers per body, laid out (and read back)
//! by [`body_to_row`] and [`body_from_row`], here beside the length.
//!
//! The file is written to a temporary name, synced and renamed: a run killed at any moment
//! leaves either the previous checkpoint or the new one, never a torn file.

use std::path::Path;

use hdf5::types::VarLenUnicode;

use super::atomic::atomic_write;
use super::fields::FieldsError;
use crate::coupling::BodyState;
use crate::lattice::{Grid, Q};
use crate::lbm::{FluidState, Real};
use crate::rigid::Vec3;

/// Numbers per body in `/bodies`: what `coupling::Coupled::restore` needs of a body
/// ([`BodyState`]). The columns:
///
/// | columns | what |
/// |---|---|
/// | 0–2 | position |
/// | 3–6 | orientation quaternion `w, x, y, z` |
/// | 7–9 | velocity |
/// | 10–12 | angular velocity |
/// | 13 | the body's time |
/// | 14–16, 17–19 | the last step's change of velocity, of angular velocity |
/// | 20–22, 23–25 | the last step's averaged contact force, torque |
pub const BODY_STATE_LEN: usize = 26;

/// A body's state as a row of `/bodies` (the columns of [`BODY_STATE_LEN`]).
pub fn body_to_row(b: &BodyState) -> [f64; BODY_STATE_LEN] {
    let v = |x: &Vec3| [x.x, x.y, x.z];
    let mut r = [0.0; BODY_STATE_LEN];
    r[0..3].copy_from_slice(&v(&b.position));
    r[3..7].copy_from_slice(&b.orientation);
    r[7..10].copy_from_slice(&v(&b.velocity));
    r[10..13].copy_from_slice(&v(&b.angular_velocity));
    r[13] = b.time;
    r[14..17].copy_from_slice(&v(&b.velocity_change.0));
    r[17..20].copy_from_slice(&v(&b.velocity_change.1));
    r[20..23].copy_from_slice(&v(&b.contact.0));
    r[23..26].copy_from_slice(&v(&b.contact.1));
    r
}

/// A body's state from a row of `/bodies`: the inverse of [`body_to_row`], bit for bit.
pub fn body_from_row(r: &[f64; BODY_STATE_LEN]) -> BodyState {
    let v = |k: usize| Vec3::new(r[k], r[k + 1], r[k + 2]);
    BodyState {
        position: v(0),
        orientation: [r[3], r[4], r[5], r[6]],
        velocity: v(7),
        angular_velocity: v(10),
        time: r[13],
        velocity_change: (v(14), v(17)),
        contact: (v(20), v(23)),
    }
}

/// A checkpoint read back: the state and the case fingerprint it was written with.
pub struct Checkpoint<T> {
    /// The fluid state.
    pub state: FluidState<T>,
    /// The particles' states, in order, if the run had particles.
    pub bodies: Option<Vec<BodyState>>,
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

/// Writes `state`, the particles' states `bodies` (if the run has particles) and the case
/// fingerprint `case` to `path`, atomically.
pub fn write_checkpoint<T: Real + hdf5::H5Type>(
    path: &Path,
    state: &FluidState<T>,
    bodies: Option<&[BodyState]>,
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
            let flat: Vec<f64> = b.iter().flat_map(body_to_row).collect();
            let d = file.new_dataset::<f64>().shape([b.len(), BODY_STATE_LEN]).create("bodies")?;
            d.write_raw(&flat)?;
        }
        file.close()?;
        Ok(())
    })
}

/// The step a checkpoint was written at (its `time_step` attribute), without reading its
/// state: what a resumed session will continue from, known before the run starts.
///
/// # Errors
/// The file cannot be opened as HDF5 or has no `time_step`.
pub fn checkpoint_time_step(path: &Path) -> anyhow::Result<u64> {
    let file = hdf5::File::open(path)?;
    Ok(file.attr("time_step")?.read_scalar::<u64>()?)
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
            Some(flat.chunks(BODY_STATE_LEN).map(|c| body_from_row(&std::array::from_fn(|k| c[k]))).collect())
        }
        Err(_) => None,
    };
    Ok(Checkpoint {
        bodies,
        state: FluidState { time: get("time_step")?, grid, populations, force },
        case: file.attr("case")?.read_scalar::<VarLenUnicode>()?.to_string(),
    })
}

#[cfg(test)]
mod tests {
    use proptest::prelude::*;

    use super::*;

    /// Any `f64` bit pattern (NaNs and infinities included): the row is a plain copy.
    fn any_bits() -> impl Strategy<Value = f64> {
        any::<u64>().prop_map(f64::from_bits)
    }

    fn bits(r: &[f64; BODY_STATE_LEN]) -> Vec<u64> {
        r.iter().map(|x| x.to_bits()).collect()
    }

    proptest! {
        /// Row → state → row gives back every bit, so each column is read and written once
        /// (two fields on one column, or a column left out, lose a value of a random row).
        #[test]
        fn row_round_trips_bitwise(row in prop::array::uniform26(any_bits())) {
            prop_assert_eq!(bits(&body_to_row(&body_from_row(&row))), bits(&row));
        }

        /// State → row → state gives back every field.
        #[test]
        fn state_round_trips(row in prop::array::uniform26(-1e3f64..1e3)) {
            let state = body_from_row(&row);
            prop_assert_eq!(body_from_row(&body_to_row(&state)), state);
        }
    }

    /// The checkpoint file keeps the rows: written and read back, the states are equal.
    #[test]
    fn bodies_survive_the_file() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("checkpoint.h5");
        let grid = Grid::new(2, 2, 2);
        let state = FluidState::<f64> { time: 4, grid, populations: vec![0.25; Q * 8], force: None };
        let bodies: Vec<BodyState> = (0..3)
            .map(|k| body_from_row(&std::array::from_fn(|c| (k * BODY_STATE_LEN + c) as f64 * 0.5)))
            .collect();
        write_checkpoint(&path, &state, Some(&bodies), "case").unwrap();
        let back = read_checkpoint::<f64>(&path).unwrap();
        assert_eq!(back.bodies.as_deref(), Some(&bodies[..]));
        assert_eq!(back.state, state);
        assert_eq!(checkpoint_time_step(&path).unwrap(), 4, "the step, without the state");
        assert!(checkpoint_time_step(&dir.path().join("none.h5")).is_err());
    }
}
