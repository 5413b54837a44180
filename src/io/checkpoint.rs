//! Checkpoints: the fluid's complete state in HDF5, written atomically.
//!
//! Layout: `/populations` is `T[19][nz][ny][nx]` (shifted populations `h = f − w`, storage
//! precision `T`, so a restart is bitwise exact), `/force` is `T[3][nz][ny][nx]` when the force
//! field is on (runs with particles or an impeller: the last step's IBM forcing, which the
//! velocity's half-force term at the checkpoint's step needs, so that the outputs of a run
//! resumed there equal the uninterrupted run's; checkpoints written before it was stored
//! restore with a zero field, exact for every later step). Root attributes: `time_step`, `precision`, `nx`, `ny`, `nz`, `history_from` (only in
//! the checkpoints of a run started from a state pack: the pack's step, after which its
//! history starts), and `case`: a
//! fingerprint of the case (its normalised TOML without `run.steps`, so that a run can be
//! extended) which a resume compares before it restores anything. With particles, `/bodies`
//! is `f64[P][26]`: one row of [`BODY_STATE_LEN`] numbers per body, laid out (and read back)
//! by [`body_to_row`] and [`body_from_row`], here beside the length.
//!
//! The file is written to a temporary name, synced and renamed: a run killed at any moment
//! leaves either the previous checkpoint or the new one, never a torn file.
//!
//! **Checksum.** The root attribute `checksum` is `blake3:HEX`, the BLAKE3 hash of everything
//! a restore reads ([`state_checksum`]: the attributes above, then the populations, the force
//! field and the bodies as their in-memory bytes). [`read_checkpoint`] computes it again and
//! refuses a mismatch as [`Corrupt`]: one flipped bit in the
//! populations would otherwise resume silently into another result. A checkpoint without the
//! attribute (written before it existed) is read with a warning, so that a long run written
//! by an earlier version can still be continued; its next checkpoint has one.

use std::path::Path;

use hdf5::types::VarLenUnicode;

use super::atomic::atomic_write;
use super::checksum::{mismatch, Corrupt};
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
    /// The step the run's history starts after: the state pack's step for a run started from
    /// one (root attribute `history_from`), 0 (absent) for a run from its initial state.
    pub history_from: u64,
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
    write_checkpoint_from(path, state, bodies, case, 0)
}

/// [`write_checkpoint`] of a run whose history starts after step `history_from` (a run
/// started from a state pack; [`Checkpoint::history_from`]): the attribute is written, and
/// checksummed, only when it is not 0, so a run from its initial state writes the same file.
pub fn write_checkpoint_from<T: Real + hdf5::H5Type>(
    path: &Path,
    state: &FluidState<T>,
    bodies: Option<&[BodyState]>,
    case: &str,
    history_from: u64,
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
        let flat: Option<Vec<f64>> = bodies.map(|b| b.iter().flat_map(body_to_row).collect());
        if let Some(flat) = &flat {
            let d = file
                .new_dataset::<f64>()
                .shape([flat.len() / BODY_STATE_LEN, BODY_STATE_LEN])
                .create("bodies")?;
            d.write_raw(flat)?;
        }
        if history_from > 0 {
            file.new_attr::<u64>().shape(()).create("history_from")?.write_scalar(&history_from)?;
        }
        let sum =
            state_checksum(&checksummed_case(&case.replace('\0', " "), history_from), state, flat.as_deref());
        file.new_attr::<VarLenUnicode>().shape(()).create("checksum")?.write_scalar(&text(&sum))?;
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
    let state = FluidState { time: get("time_step")?, grid, populations, force };
    let case = file.attr("case")?.read_scalar::<VarLenUnicode>()?.to_string();
    let history_from = match file.attr("history_from") {
        Ok(a) => a.read_scalar::<u64>()?,
        Err(_) => 0,
    };
    match file.attr("checksum") {
        Ok(a) => {
            let stored = a.read_scalar::<VarLenUnicode>()?.to_string();
            let rows: Option<Vec<f64>> =
                bodies.as_ref().map(|b: &Vec<BodyState>| b.iter().flat_map(body_to_row).collect());
            let computed = state_checksum(&checksummed_case(&case, history_from), &state, rows.as_deref());
            if stored != computed {
                return Err(Corrupt {
                    file: path.to_path_buf(),
                    detail: mismatch(
                        stored.trim_start_matches("blake3:"),
                        computed.trim_start_matches("blake3:"),
                    ),
                    remedy: "continue from an older copy of the checkpoint if there is one, or start over \
                             (`--overwrite`)"
                        .to_string(),
                }
                .into());
            }
        }
        Err(_) => eprintln!(
            "warning: {} has no checksum (written before checkpoints had one): read as it is, unchecked; \
             the next checkpoint has one",
            path.display()
        ),
    }
    Ok(Checkpoint { bodies, state, case, history_from })
}

/// The case text the checksum covers: the fingerprint, and `history_from` after it when it is
/// not 0 (so checkpoints without it keep their checksums).
fn checksummed_case(case: &str, history_from: u64) -> std::borrow::Cow<'_, str> {
    if history_from == 0 {
        std::borrow::Cow::Borrowed(case)
    } else {
        std::borrow::Cow::Owned(format!("{case}\nhistory_from {history_from}"))
    }
}

/// The checksum of a checkpoint (module docs), `blake3:HEX`: the hash of the precision, the
/// step, the grid, the case fingerprint `case`, the populations, the force field (if any) and
/// the bodies' rows `bodies` (if any), each preceded by its length so that no two states hash
/// alike by moving bytes between parts. Numbers are hashed as their in-memory bytes (the
/// bytes HDF5 stores and reads back).
pub fn state_checksum<T: Real>(case: &str, state: &FluidState<T>, bodies: Option<&[f64]>) -> String {
    let mut h = blake3::Hasher::new();
    let mut part = |bytes: &[u8]| {
        h.update(&(bytes.len() as u64).to_le_bytes());
        h.update(bytes);
    };
    part(b"slurry checkpoint 1");
    part(T::NAME.as_bytes());
    let g = state.grid;
    for v in [state.time, g.nx as u64, g.ny as u64, g.nz as u64] {
        part(&v.to_le_bytes());
    }
    part(case.as_bytes());
    part(real_bytes(&state.populations));
    match &state.force {
        Some(f) => part(real_bytes(f)),
        None => part(b"no force"),
    }
    match bodies {
        Some(b) => part(real_bytes(b)),
        None => part(b"no bodies"),
    }
    format!("blake3:{}", h.finalize().to_hex())
}

/// The bytes of a slice of `f32` or `f64`.
fn real_bytes<T: Real>(v: &[T]) -> &[u8] {
    // SAFETY: `Real` is implemented for `f32` and `f64` only: plain numbers without padding or
    // invalid bit patterns, so every byte of the slice is initialised and readable as `u8`
    // (alignment 1), for the slice's lifetime.
    unsafe { std::slice::from_raw_parts(v.as_ptr().cast::<u8>(), std::mem::size_of_val(v)) }
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

    /// A run started from a state pack records the pack's step; it reads back, and is covered
    /// by the checksum (a checkpoint without it keeps the checksum it had).
    #[test]
    fn history_from_is_kept_and_checksummed() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("checkpoint.h5");
        let state = FluidState::<f64> {
            time: 40,
            grid: Grid::new(2, 2, 2),
            populations: vec![0.5; Q * 8],
            force: None,
        };
        write_checkpoint_from(&path, &state, None, "case", 20).unwrap();
        assert_eq!(read_checkpoint::<f64>(&path).unwrap().history_from, 20);
        write_checkpoint(&path, &state, None, "case").unwrap();
        assert_eq!(read_checkpoint::<f64>(&path).unwrap().history_from, 0);
        assert_ne!(checksummed_case("case", 20), checksummed_case("case", 0));
        assert_eq!(checksummed_case("case", 0), "case");
    }

    /// One bit flipped in the populations after the write is found on read, as corruption.
    #[test]
    fn a_flipped_bit_is_refused_as_corrupt() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("checkpoint.h5");
        let grid = Grid::new(2, 2, 2);
        let state = FluidState::<f32> { time: 2, grid, populations: vec![0.125; Q * 8], force: None };
        write_checkpoint(&path, &state, None, "case").unwrap();
        assert!(read_checkpoint::<f32>(&path).is_ok());
        {
            let file = hdf5::File::open_rw(&path).unwrap();
            let d = file.dataset("populations").unwrap();
            let mut p = d.read_raw::<f32>().unwrap();
            p[17] = f32::from_bits(p[17].to_bits() ^ 1);
            d.write_raw(&p).unwrap();
        }
        let e = read_checkpoint::<f32>(&path).err().expect("refused");
        let c = e.downcast_ref::<Corrupt>().expect("a Corrupt error");
        assert_eq!(c.file, path);
        assert!(e.to_string().contains("corrupt"), "{e}");
    }
}
