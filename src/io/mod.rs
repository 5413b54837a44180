//! Output: atomic file writes, HDF5 fields with an XDMF description, CSV time series.
//!
//! Every file is written atomically ([`atomic_write`]): to a temporary file in the same
//! directory, synced, then renamed over the target, so a reader (or a crash) never sees a
//! half-written file. The time series is the one exception by design: it grows row by row
//! ([`TimeSeriesWriter`]); its header is written atomically and each row is one `write` of a
//! complete line followed by a flush, so a crash can at worst truncate the last row.
//!
//! - [`atomic`]: [`atomic_write`], [`atomic_write_bytes`];
//! - [`fields`]: [`write_fields_h5`] (`/density`, `/velocity`, shaped z-slowest);
//! - [`xdmf`]: [`write_xdmf`] (XDMF 3 for ParaView, referencing the HDF5 datasets);
//! - [`timeseries`]: [`TimeSeriesWriter`], [`TimeSeriesRow`];
//! - [`checkpoint`]: [`write_checkpoint`], [`read_checkpoint`] (bitwise restart);
//! - [`state_pack`]: [`write_state_pack`], [`read_state_pack`] (a compact state, density and
//!   velocity in `f32` with the bodies' exact states, compressed and checksummed: a restart
//!   that is close, not bitwise);
//! - [`particles`]: [`ParticleHistoryWriter`] (`particles.h5`: one frame per output step,
//!   appended to segment files beside it, each rewritten atomically, and merged into
//!   `particles.h5` at the end of the run);
//! - [`checksum`]: BLAKE3 hashes of what is read back to continue work (checkpoints, cached
//!   beds, start packs), checked on read ([`checksum::Corrupt`]);
//! - [`history`]: a resume's time series and particle history checked against its
//!   checkpoint's step (gaps refused, rows past it cut);
//! - [`lock`]: one writer per output directory ([`lock::claim_output_dir`]: an `flock` held
//!   until the process ends, and the path checked before the first step).

pub mod atomic;
pub mod checkpoint;
pub mod checksum;
pub mod fields;
pub mod history;
pub mod lock;
pub mod particles;
pub mod state_pack;
pub mod timeseries;
pub mod xdmf;

pub use atomic::{atomic_write, atomic_write_bytes, remove_stale_temps};
pub use checkpoint::{
    body_from_row, body_to_row, checkpoint_time_step, read_checkpoint, write_checkpoint,
    write_checkpoint_from, Checkpoint, BODY_STATE_LEN,
};
pub use fields::{hdf5_message, io_message, write_fields_h5, FieldsError};
pub use particles::{
    read_particle_history, read_particle_history_from, ParticleFrame, ParticleHistory, ParticleHistoryWriter,
    ParticleProperties, ParticleStatic, ParticlesError,
};
pub use state_pack::{
    is_state_pack, read_state_pack, write_state_pack, Leg, PackHistory, StatePack, StatePackError,
};
pub use timeseries::{ParticleAggregates, TimeSeriesRow, TimeSeriesWriter};
pub use xdmf::{write_xdmf, xdmf_text};
