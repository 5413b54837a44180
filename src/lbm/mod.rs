//! The lattice-Boltzmann fluid solver (D3Q19; BGK or TRT; Guo forcing).
//!
//! Knows nothing of particles: the coupling writes forces into the fluid's force density
//! field ([`Fluid::enable_force_field`], [`Fluid::set_force`]) and reads velocities back.
//!
//! - [`collision`]: equilibrium, BGK and TRT operators, Guo forcing (written once, lane-generic).
//! - [`kernel`]: the fused AA-pattern stream–collide kernel, vectorised, dispatched at run time.
//! - [`boundary`]: box faces (periodic, no-slip, moving wall) and obstacle links.
//! - [`fluid`]: the solver state and its time step, macroscopic fields, conservation sums.
//! - [`reference`](mod@reference): a plain two-lattice kernel kept as the oracle for the fused one.
//! - [`health`]: non-finite values and Mach number.
//! - [`regularise`]: populations rebuilt from density, velocity and force (the restart from a
//!   state pack).

pub mod boundary;
pub mod collision;
pub mod fluid;
pub mod health;
pub mod kernel;
pub mod params;
pub mod real;
pub mod reference;
pub mod regularise;
pub mod simd;

pub use boundary::{Boundaries, FaceBoundary};
pub use fluid::{equilibrium, Fluid, FluidState, ForceFieldWriter};
pub use health::Health;
pub use kernel::Isa;
pub use params::{Collision, FluidParams};
pub use real::Real;
pub use reference::ReferenceFluid;
pub use regularise::MacroFields;

use crate::lattice::{Face, Grid};

/// Invalid fluid set-up.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum FluidError {
    /// ν ≤ 0 (τ ≤ ½) or not finite.
    #[error("viscosity nu = {nu} gives tau = {tau}; allowed: nu > 0 (tau > 0.5)")]
    Viscosity {
        /// The rejected viscosity.
        nu: f64,
        /// The relaxation time it implies.
        tau: f64,
    },
    /// TRT magic parameter ≤ 0.
    #[error("TRT magic parameter {magic} is not allowed; allowed: magic > 0 (3/16 = 0.1875 is exact for Poiseuille)")]
    Magic {
        /// The rejected value.
        magic: f64,
    },
    /// Non-finite body force.
    #[error("body force {force:?} must be finite")]
    BodyForce {
        /// The rejected force.
        force: [f64; 3],
    },
    /// Only one face of a pair is periodic.
    #[error("periodic boundaries must come in pairs: axis {axis} has one periodic face and one wall")]
    PeriodicPair {
        /// 0 = x, 1 = y, 2 = z.
        axis: usize,
    },
    /// A wall with a normal velocity component or a non-finite one.
    #[error("wall {face:?} velocity {velocity:?}: must be finite and tangential (zero normal component)")]
    WallVelocity {
        /// The face.
        face: Face,
        /// The rejected velocity.
        velocity: [f64; 3],
    },
    /// Geometry changed at odd time.
    #[error("obstacles can only be changed at even time steps (now t = {time})")]
    OddTime {
        /// The current time step.
        time: u64,
    },
    /// A state that does not fit this fluid.
    #[error("state for grid {grid:?} does not fit this fluid's grid {expected:?}")]
    StateMismatch {
        /// The state's grid.
        grid: Grid,
        /// This fluid's grid.
        expected: Grid,
    },
    /// Empty or too large grid.
    #[error("grid {grid:?}: each size must be >= 1 and the padded grid below 2^32 nodes")]
    Grid {
        /// The rejected grid.
        grid: Grid,
    },
}
