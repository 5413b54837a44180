//! State packs: a run's state, compact enough to keep beside the code, from which it can be
//! continued (not bitwise: the populations are rebuilt from the flow, see
//! [`crate::lbm::regularise`]).
//!
//! Layout (HDF5, readable with h5py): `/rho` `f32[nz][ny][nx]` and `/u` `f32[nz][ny][nx][3]`,
//! the density and the velocity (half-force corrected, as in `fields.h5`) at the pack's step;
//! `/force` `f32[nz][ny][nx][3]` when the run has a force field (runs with particles or an
//! impeller: the last step's immersed-boundary force density, zero away from the bodies, which
//! the rebuilt momentum `j = ρu − F/2` needs); `/bodies` `f64[P][26]` with particles or an
//! impeller, every body's complete state as the checkpoint stores it
//! ([`super::checkpoint::body_to_row`]: position, orientation, velocity, angular velocity,
//! time, the last step's velocity change and averaged contact load), exact. The field
//! datasets are chunked by z-plane, shuffled and deflated. From version 2, a pack of a run
//! directory also carries the run's history ([`PackHistory`]): `/timeseries` `u8[]`, the run's
//! `timeseries.csv` up to the pack's step as written (deflated), and the attribute `legs`, the
//! legs the run was stepped in (JSON), so that a run continued from the pack goes on as the same
//! run: one time series, its legs counted.
//!
//! Root attributes: `format` ([`STATE_PACK_FORMAT`]), `version` ([`STATE_PACK_VERSION`]),
//! `time_step`, `nx`, `ny`, `nz`, `case` (the case fingerprint, as checkpoints store it),
//! `label` (what the pack is of, for people: the case's name and scale where known) and
//! `checksum`: BLAKE3 of the metadata and every dataset's bytes ([`content_checksum`]),
//! checked on reading. Written atomically ([`super::atomic_write`]).

use std::path::{Path, PathBuf};

use hdf5::types::VarLenUnicode;

use super::atomic::atomic_write;
use super::checkpoint::{body_from_row, body_to_row, BODY_STATE_LEN};
use super::fields::FieldsError;
use crate::coupling::BodyState;
use crate::lattice::Grid;

/// The `format` attribute of a state pack.
pub const STATE_PACK_FORMAT: &str = "slurry state pack";

/// The layout version this build writes; it reads this one and version 1 (no history).
pub const STATE_PACK_VERSION: u64 = 2;

/// One leg of a run: a stretch of steps between two state packs (or from the run's initial
/// state), stepped in one process or a chain of resumes from its own checkpoints, and what it
/// started from. A campaign that outlives its machines continues a run leg by leg.
#[derive(Clone, Debug, PartialEq, Eq, serde::Serialize, serde::Deserialize)]
pub struct Leg {
    /// The step the leg started from (0, or the state pack's step).
    pub first_step: u64,
    /// The last step it reached (for a leg still running, the last step packed or recorded).
    pub last_step: u64,
    /// What it started from, for people: "the case's initial state", or the state pack.
    pub start: String,
}

/// What a state pack carries of the run's past: its time series and its legs.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct PackHistory {
    /// The run's `timeseries.csv` up to and including the pack's step: its header and rows,
    /// byte for byte as written.
    pub timeseries: String,
    /// The legs the run was stepped in, in order, the last ending at the pack's step.
    pub legs: Vec<Leg>,
}

/// A run's state at one even step: the flow as density and velocity per node (`f32`), the
/// force field of the last step, and every body's exact state.
#[derive(Clone, Debug, PartialEq)]
pub struct StatePack {
    /// The step (even).
    pub time_step: u64,
    /// The grid.
    pub grid: Grid,
    /// Density per node, interior index order (x fastest).
    pub rho: Vec<f32>,
    /// Velocity per node (half-force corrected).
    pub velocity: Vec<[f32; 3]>,
    /// The last step's force density field (without the uniform body force), if the run has
    /// one.
    pub force: Option<Vec<[f32; 3]>>,
    /// Every body's state, in order (particles, then the impeller), if the run has bodies.
    pub bodies: Option<Vec<BodyState>>,
    /// The case fingerprint (as checkpoints store it).
    pub case: String,
    /// What the pack is of, for people (case name and scale where known).
    pub label: String,
    /// The run's history up to the pack's step, where the pack was written from a run
    /// directory (version 2; none in a version-1 pack).
    pub history: Option<PackHistory>,
}

/// A state pack that cannot be used.
#[derive(Clone, Debug, thiserror::Error)]
pub enum StatePackError {
    /// The file cannot be opened or read as HDF5 (missing, truncated, not HDF5).
    #[error("{}: cannot be read as a state pack (missing, truncated or not HDF5): {detail}", path.display())]
    Unreadable {
        /// The file.
        path: PathBuf,
        /// What failed.
        detail: String,
    },
    /// An HDF5 file that is not a state pack.
    #[error("{}: not a slurry state pack (no format attribute \"{STATE_PACK_FORMAT}\")", path.display())]
    NotAPack {
        /// The file.
        path: PathBuf,
    },
    /// A state pack of another layout version.
    #[error("{}: state pack version {found}; this build reads version {STATE_PACK_VERSION}", path.display())]
    Version {
        /// The file.
        path: PathBuf,
        /// Its version.
        found: u64,
    },
    /// Contents that do not match the checksum or the stated shapes.
    #[error(
        "{}: corrupt state pack: {detail}; write it again from its run (`slurry state-pack RUN_DIR PACK`), or \
         continue from the run's own checkpoint (`--resume`)",
        path.display()
    )]
    Corrupt {
        /// The file.
        path: PathBuf,
        /// What does not match.
        detail: String,
    },
    /// A pack of another case or grid than the run it is to continue.
    #[error("{}: the state pack is of {found}; this run is {want}", path.display())]
    Mismatch {
        /// The file.
        path: PathBuf,
        /// What the pack holds.
        found: String,
        /// What the run is.
        want: String,
    },
}

/// The content checksum: BLAKE3 of `meta` and each of `parts` (each preceded by its length),
/// as hex. The one place that hashes, so that the hash can be changed in one place.
pub fn content_checksum(meta: &str, parts: &[&[u8]]) -> String {
    let mut h = blake3::Hasher::new();
    h.update(&(meta.len() as u64).to_le_bytes());
    h.update(meta.as_bytes());
    for p in parts {
        h.update(&(p.len() as u64).to_le_bytes());
        h.update(p);
    }
    h.finalize().to_hex().to_string()
}

/// Little-endian bytes of `f32` values.
fn f32_bytes(v: &[f32]) -> Vec<u8> {
    v.iter().flat_map(|x| x.to_le_bytes()).collect()
}

/// Little-endian bytes of `f64` values.
fn f64_bytes(v: &[f64]) -> Vec<u8> {
    v.iter().flat_map(|x| x.to_le_bytes()).collect()
}

/// A short form of a case fingerprint for messages: its first 12 hex digits of BLAKE3.
pub fn fingerprint_digest(case: &str) -> String {
    content_checksum(case, &[])[..12].to_string()
}

impl StatePack {
    /// The metadata that the checksum covers, for layout `version`.
    fn meta(&self, version: u64) -> String {
        let g = self.grid;
        format!(
            "{STATE_PACK_FORMAT}\n{version}\n{}\n{}\n{}\n{} {} {}\n",
            self.time_step, g.nx, g.ny, g.nz, self.case, self.label
        )
    }

    /// The content checksum of the pack as this build writes it ([`content_checksum`] of the
    /// metadata and the datasets' little-endian bytes, in the order rho, u, force, bodies, then
    /// the history's time series and legs).
    pub fn checksum(&self) -> String {
        self.checksum_of_version(STATE_PACK_VERSION)
    }

    /// The legs as the `legs` attribute stores them (JSON).
    fn legs_json(history: &PackHistory) -> String {
        serde_json::to_string(&history.legs).expect("legs serialise")
    }

    /// The checksum as layout `version` computes it (version 1: no history).
    fn checksum_of_version(&self, version: u64) -> String {
        let mut parts = vec![f32_bytes(&self.rho), f32_bytes(self.velocity.as_flattened())];
        if let Some(f) = &self.force {
            parts.push(f32_bytes(f.as_flattened()));
        }
        if let Some(b) = &self.bodies {
            let flat: Vec<f64> = b.iter().flat_map(body_to_row).collect();
            parts.push(f64_bytes(&flat));
        }
        if let Some(h) = &self.history {
            parts.push(h.timeseries.as_bytes().to_vec());
            parts.push(Self::legs_json(h).into_bytes());
        }
        let refs: Vec<&[u8]> = parts.iter().map(Vec::as_slice).collect();
        content_checksum(&self.meta(version), &refs)
    }

    /// Refuses a pack of another grid or case than the run it is to continue: `grid` and
    /// `case` (the fingerprint) of the run, `label` what it is called. `path` is the pack's.
    ///
    /// # Errors
    /// [`StatePackError::Mismatch`], naming both.
    pub fn check_for(&self, path: &Path, grid: Grid, case: &str, label: &str) -> Result<(), StatePackError> {
        let g = self.grid;
        let describe = |label: &str, g: Grid, case: &str| {
            format!(
                "'{label}' on the {} x {} x {} grid (case {})",
                g.nx,
                g.ny,
                g.nz,
                fingerprint_digest(case)
            )
        };
        if g != grid || self.case != case {
            return Err(StatePackError::Mismatch {
                path: path.to_path_buf(),
                found: describe(&self.label, g, &self.case),
                want: describe(label, grid, case),
            });
        }
        Ok(())
    }
}

/// Writes `pack` to `path`, atomically.
///
/// # Errors
/// A field whose length is not the grid's, or the file cannot be written.
pub fn write_state_pack(path: &Path, pack: &StatePack) -> Result<(), FieldsError> {
    let g = pack.grid;
    let n = g.nodes();
    let length = |name, len| FieldsError::Length { name, len, want: n, nx: g.nx, ny: g.ny, nz: g.nz };
    if pack.rho.len() != n {
        return Err(length("rho", pack.rho.len()));
    }
    if pack.velocity.len() != n {
        return Err(length("u", pack.velocity.len()));
    }
    if let Some(f) = pack.force.as_ref().filter(|f| f.len() != n) {
        return Err(length("force", f.len()));
    }
    let checksum = pack.checksum();
    atomic_write(path, |tmp| -> Result<(), FieldsError> {
        let file = hdf5::File::create(tmp)?;
        let text = |s: &str| -> VarLenUnicode { s.replace('\0', " ").parse().expect("no NUL left") };
        let string_attr = |name: &str, value: &str| -> Result<(), FieldsError> {
            file.new_attr::<VarLenUnicode>().shape(()).create(name)?.write_scalar(&text(value))?;
            Ok(())
        };
        string_attr("format", STATE_PACK_FORMAT)?;
        string_attr("case", &pack.case)?;
        string_attr("label", &pack.label)?;
        string_attr("checksum", &checksum)?;
        file.new_attr::<u64>().shape(()).create("version")?.write_scalar(&STATE_PACK_VERSION)?;
        file.new_attr::<u64>().shape(()).create("time_step")?.write_scalar(&pack.time_step)?;
        for (name, v) in [("nx", g.nx), ("ny", g.ny), ("nz", g.nz)] {
            file.new_attr::<u64>().shape(()).create(name)?.write_scalar(&(v as u64))?;
        }
        let d = file
            .new_dataset::<f32>()
            .shape([g.nz, g.ny, g.nx])
            .chunk([1, g.ny, g.nx])
            .shuffle()
            .deflate(6)
            .create("rho")?;
        d.write_raw(&pack.rho)?;
        let vector = |name: &str, v: &[[f32; 3]]| -> Result<(), FieldsError> {
            let d = file
                .new_dataset::<f32>()
                .shape([g.nz, g.ny, g.nx, 3])
                .chunk([1, g.ny, g.nx, 3])
                .shuffle()
                .deflate(6)
                .create(name)?;
            d.write_raw(v.as_flattened())?;
            Ok(())
        };
        vector("u", &pack.velocity)?;
        if let Some(f) = &pack.force {
            vector("force", f)?;
        }
        if let Some(b) = &pack.bodies {
            let flat: Vec<f64> = b.iter().flat_map(body_to_row).collect();
            let d = file.new_dataset::<f64>().shape([b.len(), BODY_STATE_LEN]).create("bodies")?;
            d.write_raw(&flat)?;
        }
        if let Some(h) = &pack.history {
            let bytes = h.timeseries.as_bytes();
            let d = if bytes.is_empty() {
                file.new_dataset::<u8>().shape([0]).create("timeseries")?
            } else {
                // Chunked (deflate needs it), in chunks of at most 1 MiB.
                let chunk = bytes.len().min(1 << 20);
                file.new_dataset::<u8>()
                    .shape([bytes.len()])
                    .chunk([chunk])
                    .deflate(9)
                    .create("timeseries")?
            };
            d.write_raw(bytes)?;
            string_attr("legs", &StatePack::legs_json(h))?;
        }
        file.close()?;
        Ok(())
    })
}

/// Whether `path` is a state pack (an HDF5 file with the `format` attribute), without
/// reading its contents: what `--start-from` tells from a run directory by.
pub fn is_state_pack(path: &Path) -> bool {
    path.is_file()
        && hdf5::File::open(path).is_ok_and(|f| {
            f.attr("format")
                .and_then(|a| a.read_scalar::<VarLenUnicode>())
                .is_ok_and(|s| s.as_str() == STATE_PACK_FORMAT)
        })
}

/// The bytes each dataset of the HDF5 file at `path` takes on disk (compressed), by name, in
/// name order: where a pack's size goes.
///
/// # Errors
/// The file cannot be opened as HDF5.
pub fn dataset_sizes(path: &Path) -> Result<Vec<(String, u64)>, FieldsError> {
    let file = hdf5::File::open(path)?;
    let mut out = Vec::new();
    for name in file.member_names()? {
        if let Ok(d) = file.dataset(&name) {
            out.push((name, d.storage_size()));
        }
    }
    Ok(out)
}

/// Reads a state pack written by [`write_state_pack`], checking its version, its shapes and
/// its checksum.
///
/// # Errors
/// [`StatePackError`]: unreadable (missing, truncated), not a pack, another version, corrupt.
pub fn read_state_pack(path: &Path) -> Result<StatePack, StatePackError> {
    let unreadable = |e: hdf5::Error| StatePackError::Unreadable {
        path: path.to_path_buf(),
        detail: super::hdf5_message(&e),
    };
    let corrupt = |detail: String| StatePackError::Corrupt { path: path.to_path_buf(), detail };
    let file = hdf5::File::open(path).map_err(unreadable)?;
    let text = |name: &str| -> Result<String, hdf5::Error> {
        Ok(file.attr(name)?.read_scalar::<VarLenUnicode>()?.to_string())
    };
    match text("format") {
        Ok(f) if f == STATE_PACK_FORMAT => {}
        _ => return Err(StatePackError::NotAPack { path: path.to_path_buf() }),
    }
    let number = |name: &str| -> Result<u64, StatePackError> {
        file.attr(name)
            .and_then(|a| a.read_scalar::<u64>())
            .map_err(|e| corrupt(format!("attribute {name}: {}", super::hdf5_message(&e))))
    };
    let version = number("version")?;
    if !(1..=STATE_PACK_VERSION).contains(&version) {
        return Err(StatePackError::Version { path: path.to_path_buf(), found: version });
    }
    let attr_text = |name: &str| {
        text(name).map_err(|e| corrupt(format!("attribute {name}: {}", super::hdf5_message(&e))))
    };
    let grid = Grid::new(number("nx")? as usize, number("ny")? as usize, number("nz")? as usize);
    let n = grid.nodes();
    let read_f32 = |name: &str, per: usize| -> Result<Vec<f32>, StatePackError> {
        let v = file
            .dataset(name)
            .and_then(|d| d.read_raw::<f32>())
            .map_err(|e| corrupt(format!("/{name}: {}", super::hdf5_message(&e))))?;
        if v.len() != per * n {
            return Err(corrupt(format!("/{name} has {} values, the grid needs {}", v.len(), per * n)));
        }
        Ok(v)
    };
    let triples = |v: Vec<f32>| -> Vec<[f32; 3]> { v.chunks_exact(3).map(|c| [c[0], c[1], c[2]]).collect() };
    let rho = read_f32("rho", 1)?;
    let velocity = triples(read_f32("u", 3)?);
    let force = if file.link_exists("force") { Some(triples(read_f32("force", 3)?)) } else { None };
    let bodies = if file.link_exists("bodies") {
        let flat = file
            .dataset("bodies")
            .and_then(|d| d.read_raw::<f64>())
            .map_err(|e| corrupt(format!("/bodies: {}", super::hdf5_message(&e))))?;
        if !flat.len().is_multiple_of(BODY_STATE_LEN) {
            return Err(corrupt(format!("/bodies has {} values, not rows of {BODY_STATE_LEN}", flat.len())));
        }
        Some(
            flat.chunks_exact(BODY_STATE_LEN)
                .map(|c| body_from_row(&std::array::from_fn(|k| c[k])))
                .collect(),
        )
    } else {
        None
    };
    let history = if version >= 2 && file.link_exists("timeseries") {
        let bytes = file
            .dataset("timeseries")
            .and_then(|d| d.read_raw::<u8>())
            .map_err(|e| corrupt(format!("/timeseries: {}", super::hdf5_message(&e))))?;
        let timeseries =
            String::from_utf8(bytes).map_err(|e| corrupt(format!("/timeseries is not UTF-8 text: {e}")))?;
        let legs = serde_json::from_str(&attr_text("legs")?)
            .map_err(|e| corrupt(format!("attribute legs is not a list of legs: {e}")))?;
        Some(PackHistory { timeseries, legs })
    } else {
        None
    };
    let pack = StatePack {
        time_step: number("time_step")?,
        grid,
        rho,
        velocity,
        force,
        bodies,
        case: attr_text("case")?,
        label: attr_text("label")?,
        history,
    };
    let stored = attr_text("checksum")?;
    let actual = pack.checksum_of_version(version);
    if stored != actual {
        return Err(corrupt(super::checksum::mismatch(&stored, &actual)));
    }
    Ok(pack)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn pack() -> StatePack {
        let grid = Grid::new(4, 3, 2);
        let n = grid.nodes();
        StatePack {
            time_step: 8,
            grid,
            rho: (0..n).map(|i| 1.0 + i as f32 * 1e-4).collect(),
            velocity: (0..n).map(|i| [i as f32 * 1e-3, -0.01, 0.5]).collect(),
            force: Some((0..n).map(|i| [0.0, i as f32, 0.0]).collect()),
            bodies: Some(
                (0..2)
                    .map(|k| body_from_row(&std::array::from_fn(|c| (k * BODY_STATE_LEN + c) as f64 * 0.25)))
                    .collect(),
            ),
            case: "[domain]\nnx = 4\n".into(),
            label: "test".into(),
            history: Some(PackHistory {
                timeseries: "step,time\n0,0\n8,8\n".into(),
                legs: vec![Leg { first_step: 0, last_step: 8, start: "the case's initial state".into() }],
            }),
        }
    }

    #[test]
    fn round_trips_exactly() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("pack.h5");
        let p = pack();
        write_state_pack(&path, &p).unwrap();
        assert!(is_state_pack(&path));
        assert_eq!(read_state_pack(&path).unwrap(), p);
        let bare = StatePack { force: None, bodies: None, history: None, ..p };
        write_state_pack(&path, &bare).unwrap();
        assert_eq!(read_state_pack(&path).unwrap(), bare);
        assert_eq!(std::fs::read_dir(dir.path()).unwrap().count(), 1, "no temporary file left");
    }

    #[test]
    fn checksum_covers_metadata_and_data() {
        let p = pack();
        let c = p.checksum();
        assert_ne!(StatePack { time_step: 10, ..p.clone() }.checksum(), c);
        let mut q = p.clone();
        q.velocity[3][1] = -0.010_000_001;
        assert_ne!(q.checksum(), c);
        let mut q = p.clone();
        q.bodies.as_mut().unwrap()[1].time = 1.0;
        assert_ne!(q.checksum(), c);
        assert_ne!(StatePack { force: None, ..p.clone() }.checksum(), c);
        let mut q = p.clone();
        q.history.as_mut().unwrap().timeseries.push_str("10,10\n");
        assert_ne!(q.checksum(), c);
        let mut q = p.clone();
        q.history.as_mut().unwrap().legs[0].last_step = 10;
        assert_ne!(q.checksum(), c);
        assert_ne!(StatePack { history: None, ..p.clone() }.checksum(), c);
    }

    #[test]
    fn mismatch_names_both() {
        let p = pack();
        let path = Path::new("pack.h5");
        assert!(p.check_for(path, p.grid, &p.case, "run").is_ok());
        let e = p.check_for(path, Grid::new(8, 6, 4), &p.case, "bigger").unwrap_err().to_string();
        assert!(
            e.contains("'test' on the 4 x 3 x 2 grid") && e.contains("'bigger' on the 8 x 6 x 4 grid"),
            "{e}"
        );
        let e = p.check_for(path, p.grid, "[domain]\nnx = 5\n", "other").unwrap_err().to_string();
        assert!(
            e.contains(&fingerprint_digest(&p.case)) && e.contains(&fingerprint_digest("[domain]\nnx = 5\n")),
            "{e}"
        );
    }
}
