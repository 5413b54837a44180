//! Lattice geometry: the D3Q19 velocity set as data, and the box of nodes.
//!
//! Everything here is in lattice units (Δx = Δt = 1). Nothing here knows about
//! populations, collisions or particles.

mod d3q19;
mod grid;

pub use d3q19::{C, CS2, OPP, Q, W};
pub use grid::{Face, Grid, NodeLayout, Run};
