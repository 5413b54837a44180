//! Case files (TOML) and their validation.
//!
//! A case file describes one fluid run: the box, the fluid, the six face boundaries, the
//! initial state and the run length. The format, with every key, default and allowed range,
//! is documented in `docs/case-format.md`; `examples/` holds complete cases.
//!
//! ```toml
//! [domain]
//! nx = 4
//! ny = 4
//! nz = 32
//!
//! [fluid]
//! precision = "f64"
//! nu = 0.1              # or tau = 0.8 (exactly one of the two)
//! collision = "trt"
//! body_force = [1e-6, 0.0, 0.0]
//!
//! [boundaries]
//! x_min = "periodic"
//! x_max = "periodic"
//! y_min = "periodic"
//! y_max = "periodic"
//! z_min = "no_slip"
//! z_max = { moving_wall = [0.05, 0.0, 0.0] }
//!
//! [run]
//! steps = 2000
//! output_every = 200
//! ```
//!
//! Particles (module [`particles`]): a top-level `gravity = [gx, gy, gz]`, an `[ibm]` section
//! (kernel, forcing iterations, marker spacing, and the forcing markers' `retraction` into the
//! surface, which sets the bodies' hydrodynamic size), explicit `[[particles]]` and random
//! `[[random_particles]]` populations, placed without overlap by [`placement`].
//!
//! [`Case::from_file`] reads and checks a file in four stages, each reporting the file name,
//! the dotted key and what is allowed: TOML syntax; unknown keys (with the list of allowed
//! ones); types (via serde, with line and column); ranges and consistency
//! ([`Case::validate`], which also runs the solver's own [`FluidParams::validate`] and
//! [`Boundaries::validate`]). Nothing is clamped or silently corrected.

mod describe;
mod errors;
pub mod impeller;
pub mod input;
mod keys;
pub mod memory;
pub mod particles;
pub mod placement;
mod schema;
mod sections;
mod validate;

use std::fmt;
use std::path::{Path, PathBuf};

use serde::{Deserialize, Serialize};

use crate::lattice::{Face, Grid, CS2};
use crate::lbm::{Boundaries, Collision, FaceBoundary, FluidError, FluidParams};
pub(crate) use errors::invalid;
use errors::{check_unknown_keys, one_line, type_error};
pub use errors::{CaseError, CaseErrorKind};
pub use impeller::{ImpellerKindSpec, ImpellerSection, ImpellerSetup, PumpingSpec};
pub use particles::{IbmSection, MotionKind, ParticleInit, ParticleSpec, RandomParticles, ShapeKind};
pub use schema::{
    default_mach_limit, mach_limit_allowed, BoundarySection, BoundarySpec, Case, CollisionModel, Device,
    DomainSection, FluidSection, InitialKind, InitialSection, Precision, RunSection,
};

/// Largest allowed relaxation time τ (`fluid.tau`, or `3 fluid.nu + 1/2`): beyond it the
/// fluid is so viscous per step that bounce-back walls slip by more than a lattice spacing
/// (their error grows as τ²) and the run says nothing physical (without it, `nu = 1e12` is
/// accepted).
pub const MAX_TAU: f64 = 100.0;

/// `[a, b, c]` with each component in shortest round-trip form.
pub(crate) fn fmt_vec(v: &[f64; 3]) -> String {
    format!("[{}, {}, {}]", v[0], v[1], v[2])
}

fn norm(v: [f64; 3]) -> f64 {
    (v[0] * v[0] + v[1] * v[1] + v[2] * v[2]).sqrt()
}

/// Mach number `|u|/c_s` of a velocity.
pub fn mach(u: [f64; 3]) -> f64 {
    norm(u) / CS2.sqrt()
}

impl Case {
    /// Reads, parses and validates a case file.
    pub fn from_file(path: impl AsRef<Path>) -> Result<Case, CaseError> {
        let path = path.as_ref();
        // Bounded: a regular file within the size limit, whose parse fits the memory.
        let text = input::read_case_text(path)
            .and_then(|t| input::check_parse_memory(&t).map(|()| t))
            .map_err(|kind| CaseError { file: path.to_path_buf(), kind })?;
        Case::parse(&text, path)
    }

    /// Parses and validates case-file text; `file` names it in errors.
    pub fn parse(text: &str, file: impl AsRef<Path>) -> Result<Case, CaseError> {
        Case::parse_unchecked(text)
            .and_then(|c| c.validate().map(|()| c))
            .map_err(|kind| CaseError { file: file.as_ref().to_path_buf(), kind })
    }

    /// Parses without the range checks of [`Case::validate`] (syntax, keys and types only).
    pub fn parse_unchecked(text: &str) -> Result<Case, CaseErrorKind> {
        let doc: toml::Table = toml::from_str(text).map_err(|e| {
            let (line, column) = e.span().map_or((0, 0), |s| keys::line_column(text, s.start));
            CaseErrorKind::Syntax { line, column, message: one_line(e.message()) }
        })?;
        check_unknown_keys(&doc)?;
        toml::from_str::<Case>(text).map_err(|e| type_error(text, &e))
    }

    /// The grid.
    pub fn grid(&self) -> Grid {
        Grid::new(self.domain.nx, self.domain.ny, self.domain.nz)
    }

    /// Kinematic viscosity ν (from `fluid.nu`, or `(τ − ½)/3` from `fluid.tau`).
    pub fn nu(&self) -> f64 {
        match (self.fluid.nu, self.fluid.tau) {
            (Some(nu), _) => nu,
            (None, Some(tau)) => (tau - 0.5) * CS2,
            (None, None) => f64::NAN,
        }
    }

    /// Relaxation time τ = 3ν + ½.
    pub fn tau(&self) -> f64 {
        self.fluid_params().tau()
    }

    /// The solver's fluid parameters.
    pub fn fluid_params(&self) -> FluidParams {
        let collision = match self.fluid.collision {
            CollisionModel::Bgk => Collision::Bgk,
            CollisionModel::Trt => {
                Collision::Trt { magic: self.fluid.magic.unwrap_or_else(crate::lbm::params::default_magic) }
            }
        };
        FluidParams { nu: self.nu(), collision, body_force: self.fluid.body_force }
    }

    /// The solver's face boundaries.
    pub fn boundaries(&self) -> Boundaries {
        Face::ALL.iter().fold(Boundaries::periodic(), |b, &face| {
            b.with(face, self.boundaries.get(face).to_face_boundary())
        })
    }

    /// Peak speed of the Taylor–Green field divided by its amplitude: `max(1, k_x/k_y)`.
    fn taylor_green_speed_factor(&self) -> f64 {
        let (kx, ky) = self.taylor_green_wavenumbers();
        1f64.max(kx / ky)
    }

    fn taylor_green_wavenumbers(&self) -> (f64, f64) {
        let tau = std::f64::consts::TAU;
        (tau / self.domain.nx as f64, tau / self.domain.ny as f64)
    }

    /// The initial density and velocity at node `(x, y, z)`.
    ///
    /// For `taylor_green`: `u_x = −A cos(k_x x) sin(k_y y)`,
    /// `u_y = A (k_x/k_y) sin(k_x x) cos(k_y y)` (divergence-free),
    /// `ρ = ρ₀ + 3 p` with `p = −ρ₀ A²/4 (cos 2k_x x + (k_x/k_y)² cos 2k_y y)`.
    /// It decays as `exp(−ν (k_x² + k_y²) t)`.
    pub fn initial_state(&self, x: usize, y: usize, _z: usize) -> (f64, [f64; 3]) {
        let i = &self.initial;
        match i.kind {
            InitialKind::Uniform => (i.density, i.velocity.unwrap_or([0.0; 3])),
            InitialKind::TaylorGreen => {
                let a = i.amplitude.unwrap_or(0.0);
                let (kx, ky) = self.taylor_green_wavenumbers();
                let r = kx / ky;
                let (xs, ys) = (kx * x as f64, ky * y as f64);
                let u = [-a * xs.cos() * ys.sin(), a * r * xs.sin() * ys.cos(), 0.0];
                let p = -i.density * a * a / 4.0 * ((2.0 * xs).cos() + r * r * (2.0 * ys).cos());
                (i.density + p / CS2, u)
            }
        }
    }

    /// The largest wall Mach number over the moving walls (0 when none move).
    pub fn max_wall_mach(&self) -> f64 {
        Face::ALL
            .iter()
            .filter_map(|&f| match self.boundaries.get(f) {
                BoundarySpec::MovingWall(v) => Some(mach(v)),
                _ => None,
            })
            .fold(0.0, f64::max)
    }

    /// The case's identity for checkpoints: its normalised TOML without `run.steps`,
    /// `run.checkpoint_every`, `run.snapshots` and `run.mach_limit` (set to its default), so
    /// that a resumed run may be extended, checkpoint at another cadence, write other snapshots
    /// or stop at another Mach number, but not change anything that alters the physics or the
    /// output cadence.
    pub fn fingerprint(&self) -> String {
        let mut c = self.clone();
        c.run.steps = 0;
        c.run.checkpoint_every = None;
        c.run.snapshots.clear();
        // The Mach limit only decides when to stop (no number depends on it): a run it stopped
        // may continue under a higher one. Set to the default, not removed, so that the
        // fingerprints of runs at the default stay what they were.
        c.run.mach_limit = default_mach_limit();
        // The processor changes no number beyond round-off: a run may continue on the other.
        c.run.device = Device::Cpu;
        toml::to_string(&c).unwrap_or_default()
    }

    /// [`Case::fingerprint`] with the contact scheme's cost settings, `[contacts] substeps`,
    /// `lubrication_limiter`, `lubrication_substeps` and `damping`, set to their defaults: what a checkpoint must match for a
    /// resume that switches the contact scheme (`RunOptions::switch_contacts`). The model
    /// (Table 1's constants, which parts act) must still match.
    pub fn fingerprint_except_contact_scheme(&self) -> String {
        let mut c = self.clone();
        if let Some(p) = c.contacts.as_mut() {
            let d = crate::contact::ContactParams::default();
            p.substeps = d.substeps;
            p.lubrication_limiter = d.lubrication_limiter;
            p.lubrication_substeps = d.lubrication_substeps;
            p.damping = d.damping;
        }
        c.fingerprint()
    }

    /// Whether a checkpoint's stored fingerprint `text` ([`Case::fingerprint`] of the case that
    /// wrote it) names this case up to the contact scheme
    /// ([`Case::fingerprint_except_contact_scheme`]).
    pub fn same_except_contact_scheme(&self, text: &str) -> bool {
        toml::from_str::<Case>(text)
            .is_ok_and(|c| c.fingerprint_except_contact_scheme() == self.fingerprint_except_contact_scheme())
    }

    /// Number of time-series rows a run writes: step 0, every `output_every` steps, and the
    /// last step if it is not a multiple of `output_every`.
    pub fn output_rows(&self) -> u64 {
        1 + self.run.steps.div_ceil(self.run.output_every)
    }
}

#[cfg(test)]
mod tests;
