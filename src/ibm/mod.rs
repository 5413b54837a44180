//! Immersed boundary method: the transfer between Lagrangian markers and the lattice.
//!
//! A marker at world position `X` (lattice units; node `(i, j, k)` sits at `(i, j, k)`) reads
//! the fluid velocity through a regularised delta function and hands its force back through
//! the same weights:
//!
//! - [`kernel`]: the 1-D kernels `φ` ([`DeltaKernel`]: linear, Roma 3-point (default),
//!   Peskin 4-point) with their formulas, moment conditions and references, and why Roma's is
//!   the default;
//! - [`stencil`]: per marker, the nodes and weights `δ = φ_z φ_y φ_x` ([`Stencils`]), periodic
//!   wrap, walls (dropped nodes, renormalised weights), the z-slab schedule;
//! - [`transfer`]: [`interpolate`] and [`spread`], adjoint (`S = Iᵀ`, weight for weight),
//!   parallel, bitwise deterministic for any thread count, allocation-free.
//!
//! Knows only [`crate::lattice`]: fields are plain per-node arrays on the interior grid (index
//! `x + nx (y + ny z)`), the box's periodicity is a `[bool; 3]`. The coupling feeds it from the
//! fluid solver.
//!
//! A step of the coupling uses it as: [`Stencils::build`] once per step with the markers'
//! positions (parallel over markers), then per forcing iteration [`interpolate`] the velocity,
//! compute the marker forces, [`spread`] them.

pub mod kernel;
pub mod stencil;
pub mod transfer;

pub use kernel::DeltaKernel;
pub use stencil::{StencilError, Stencils};
pub use transfer::{interpolate, spread, spread_into, FnField, ForceSink, NodeField};

#[cfg(test)]
mod tests;
