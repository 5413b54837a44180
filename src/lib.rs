//! # slurry
//!
//! Particle-resolved simulation of dense solid–liquid suspensions: a D3Q19 lattice-Boltzmann
//! fluid, an immersed boundary method for moving solid surfaces, rigid non-spherical particles,
//! marker-based contacts, and revolving impellers in a closed tank. The first target is
//! Derksen (2020), "Agitating cylindrical particles in laminar liquid flow".
//!
//! Everything in the core runs in lattice units (Δx = Δt = 1, ρ_fluid = 1).
//!
//! Module map (see `ARCHITECTURE.md`, whose module table says which module may use which;
//! `cargo xtask tidy` checks the imports against it):
//! - [`lattice`]: the velocity set and the grid;
//! - [`util`]: seeded random numbers, compensated summation, number formatting, the shared
//!   mutable slice of the parallel phases ([`util::SharedMut`]);
//! - [`lbm`]: the fluid solver (knows nothing of particles);
//! - [`device`]: the fluid's step on a GPU through wgpu (Vulkan), the CPU solver its host
//!   mirror and reference;
//! - [`ibm`]: immersed-boundary transfer: delta kernels, marker stencils, interpolation and
//!   spreading as an adjoint pair (knows nothing of the fluid solver);
//! - [`rigid`]: rigid bodies, shapes and surface markers, quaternion integration (knows
//!   nothing of the fluid);
//! - [`contact`]: the paper's contact and lubrication laws between surface markers and with the
//!   walls, the marker-pair list, sub-cycled body updates (knows only [`rigid`]);
//! - [`coupling`]: the coupled step, the only module that knows both the fluid and the
//!   particles;
//! - [`case`]: case files (TOML) and their validation;
//! - [`io`]: HDF5/XDMF fields, CSV time series, checkpoints, particle histories, atomic writes;
//! - [`interrupt`]: SIGINT and SIGTERM as a request to stop at the next complete state, the
//!   long loops' checkpoint written first;
//! - [`drive`]: what the drivers share: the solver built from a case, the particle output;
//! - [`run`]: driving a case from start to output;
//! - [`settle`]: settling a case's particles to a bed (in the fluid, or dry for the
//!   reproduction);
//! - [`bench`](mod@bench): the fused kernel's throughput;
//! - [`plot`]: PNG and SVG figures (field images with a colour bar, x–y line plots) with a
//!   bundled font;
//! - [`cli`]: the solver's commands (`run`, `check`, `settle`, `bench`) and the options they
//!   share, for the `slurry` binary.
//!
//! The paper's reproduction (its cases, statistics, report and campaign tools) is the
//! separate crate `slurry-reproduce` in `reproduce/`, which builds the `slurry` binary; it
//! uses this library, never the other way round.
#![warn(missing_docs)]

pub mod bench;
pub mod case;
pub mod cli;
pub mod contact;
pub mod coupling;
pub mod device;
pub mod drive;
pub mod ibm;
pub mod interrupt;
pub mod io;
pub mod lattice;
pub mod lbm;
pub mod plot;
pub mod rigid;
pub mod run;
pub mod settle;
pub mod util;

/// The git revision of the checkout this library was built from (`git describe --always
/// --dirty --abbrev=12`, by `build.rs`), empty outside a git work tree: run manifests name the
/// build that ran them.
pub const BUILD_REVISION: &str = env!("SLURRY_BUILD_REVISION");
