//! Contacts (provisional header; full documentation below once numbers are in).

mod engine;
mod force;
mod grid;
pub mod oracle;
mod params;
mod subcycle;

pub use engine::{ContactLoad, ContactStats, Contacts};
pub use oracle::{brute_force, OracleResult};
pub use params::{ContactParamError, ContactParams, Walls};

/// Default number of contact sub-steps per fluid time step.
pub const DEFAULT_SUBSTEPS: usize = 8;
