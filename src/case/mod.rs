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
//! (kernel, forcing iterations, marker spacing), explicit `[[particles]]` and random
//! `[[random_particles]]` populations, placed without overlap by [`placement`].
//!
//! [`Case::from_file`] reads and checks a file in four stages, each reporting the file name,
//! the dotted key and what is allowed: TOML syntax; unknown keys (with the list of allowed
//! ones); types (via serde, with line and column); ranges and consistency
//! ([`Case::validate`], which also runs the solver's own [`FluidParams::validate`] and
//! [`Boundaries::validate`]). Nothing is clamped or silently corrected.

mod describe;
pub mod impeller;
mod keys;
pub mod memory;
pub mod particles;
pub mod placement;
mod sections;

use std::fmt;
use std::path::{Path, PathBuf};

use serde::{Deserialize, Serialize};

use crate::lattice::{Face, Grid, CS2};
use crate::lbm::{Boundaries, Collision, FaceBoundary, FluidError, FluidParams};
pub use impeller::{ImpellerKindSpec, ImpellerSection, ImpellerSetup, PumpingSpec};
pub use particles::{
    ContactsSection, IbmSection, MotionKind, ParticleInit, ParticleSpec, RandomParticles, ShapeKind,
};

/// A complete case: what [`crate::run::run_case`] needs to run.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Case {
    /// Gravitational acceleration `[gx, gy, gz]` (a top-level key, written above the first
    /// table; default zero). Free particles feel their net weight `(γ − 1) V g`; the fluid is
    /// not forced by it (use `fluid.body_force` for that).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub gravity: Option<[f64; 3]>,
    /// The box of lattice nodes.
    pub domain: DomainSection,
    /// Fluid properties and storage precision.
    pub fluid: FluidSection,
    /// The condition on each of the six faces.
    pub boundaries: BoundarySection,
    /// The initial state (default: uniform, at rest, `ρ = 1`).
    #[serde(default)]
    pub initial: InitialSection,
    /// Run length, output cadence and the health limit.
    pub run: RunSection,
    /// Immersed-boundary numerics (default: see [`IbmSection`]); used with particles.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub ibm: Option<IbmSection>,
    /// Contacts between particles and with the walls (`[contacts]`; absent = none).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub contacts: Option<ContactsSection>,
    /// Particles given one by one (`[[particles]]`).
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub particles: Vec<ParticleSpec>,
    /// Populations of particles placed at random (`[[random_particles]]`).
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub random_particles: Vec<RandomParticles>,
    /// A revolving impeller (`[impeller]`; absent = none).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub impeller: Option<ImpellerSection>,
}

/// `[domain]`: grid size in nodes.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct DomainSection {
    /// Nodes along x (≥ 1).
    pub nx: usize,
    /// Nodes along y (≥ 1).
    pub ny: usize,
    /// Nodes along z (≥ 1).
    pub nz: usize,
}

/// Storage precision of the populations.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum Precision {
    /// Single precision (half the memory traffic; shifted populations keep it accurate).
    F32,
    /// Double precision.
    #[default]
    F64,
}

impl Precision {
    /// `"f32"` or `"f64"`.
    pub fn name(self) -> &'static str {
        match self {
            Precision::F32 => "f32",
            Precision::F64 => "f64",
        }
    }

    /// Bytes per population.
    pub fn bytes(self) -> usize {
        match self {
            Precision::F32 => 4,
            Precision::F64 => 8,
        }
    }
}

/// Collision model as named in a case file.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum CollisionModel {
    /// Single relaxation time.
    #[default]
    Bgk,
    /// Two relaxation times with magic parameter `fluid.magic`.
    Trt,
}

/// `[fluid]`: viscosity (or relaxation time), collision model, body force, precision.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct FluidSection {
    /// Storage precision (default `f64`).
    #[serde(default)]
    pub precision: Precision,
    /// Kinematic viscosity ν (> 0). Exactly one of `nu` and `tau` must be given.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub nu: Option<f64>,
    /// Relaxation time τ = 3ν + ½ (> ½). Exactly one of `nu` and `tau` must be given.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub tau: Option<f64>,
    /// Collision model (default `bgk`).
    #[serde(default)]
    pub collision: CollisionModel,
    /// TRT magic parameter Λ (> 0; default 3/16). Only with `collision = "trt"`.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub magic: Option<f64>,
    /// Uniform body force density `[gx, gy, gz]` (default zero).
    #[serde(default)]
    pub body_force: [f64; 3],
}

/// One face's condition as written in a case file: `"periodic"`, `"no_slip"` or
/// `{ moving_wall = [ux, uy, uz] }`.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum BoundarySpec {
    /// Periodic (the opposite face must be periodic too).
    Periodic,
    /// Stationary no-slip wall.
    NoSlip,
    /// Wall moving in its own plane with this velocity (normal component zero).
    MovingWall([f64; 3]),
}

impl BoundarySpec {
    /// The solver's face condition.
    pub fn to_face_boundary(self) -> FaceBoundary {
        match self {
            BoundarySpec::Periodic => FaceBoundary::Periodic,
            BoundarySpec::NoSlip => FaceBoundary::NoSlip,
            BoundarySpec::MovingWall(velocity) => FaceBoundary::MovingWall { velocity },
        }
    }
}

impl fmt::Display for BoundarySpec {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            BoundarySpec::Periodic => write!(f, "\"periodic\""),
            BoundarySpec::NoSlip => write!(f, "\"no_slip\""),
            BoundarySpec::MovingWall(v) => write!(f, "{{ moving_wall = {} }}", fmt_vec(v)),
        }
    }
}

/// `[boundaries]`: all six faces must be given.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct BoundarySection {
    /// Face x = 0.
    pub x_min: BoundarySpec,
    /// Face x = nx − 1.
    pub x_max: BoundarySpec,
    /// Face y = 0.
    pub y_min: BoundarySpec,
    /// Face y = ny − 1.
    pub y_max: BoundarySpec,
    /// Face z = 0 (floor).
    pub z_min: BoundarySpec,
    /// Face z = nz − 1 (lid).
    pub z_max: BoundarySpec,
}

impl BoundarySection {
    /// The condition on `face`.
    pub fn get(&self, face: Face) -> BoundarySpec {
        match face {
            Face::XMin => self.x_min,
            Face::XMax => self.x_max,
            Face::YMin => self.y_min,
            Face::YMax => self.y_max,
            Face::ZMin => self.z_min,
            Face::ZMax => self.z_max,
        }
    }
}

/// Kind of initial condition.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum InitialKind {
    /// Uniform density `initial.density` and velocity `initial.velocity`.
    #[default]
    Uniform,
    /// Taylor–Green vortex array in the x–y plane (uniform along z):
    /// `u_x = −A cos(k_x x) sin(k_y y)`, `u_y = A (k_x/k_y) sin(k_x x) cos(k_y y)`, `u_z = 0`, with
    /// `k_x = 2π/nx`, `k_y = 2π/ny`, amplitude `A = initial.amplitude`, and the matching
    /// pressure. Needs periodic x and y.
    TaylorGreen,
}

/// `[initial]`: the state at step 0 (equilibrium populations of it).
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct InitialSection {
    /// `"uniform"` (default) or `"taylor_green"`.
    #[serde(default)]
    pub kind: InitialKind,
    /// Mean density (> 0; default 1).
    #[serde(default = "one")]
    pub density: f64,
    /// Uniform velocity (`uniform` only; default zero).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub velocity: Option<[f64; 3]>,
    /// Velocity amplitude (`taylor_green` only; required there).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub amplitude: Option<f64>,
}

fn one() -> f64 {
    1.0
}

impl Default for InitialSection {
    fn default() -> Self {
        Self { kind: InitialKind::Uniform, density: 1.0, velocity: None, amplitude: None }
    }
}

/// `[run]`: how long, how often to record, and when to stop for numerical trouble.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct RunSection {
    /// Number of time steps (≥ 1).
    pub steps: u64,
    /// Record a time-series row (and check health) every this many steps (1 ≤ … ≤ steps).
    pub output_every: u64,
    /// Stop when the Mach number `|u|/c_s` anywhere exceeds this (0 < … ≤ 1; default 0.3).
    #[serde(default = "default_mach_limit")]
    pub mach_limit: f64,
    /// Write `checkpoint.h5` every this many steps (even, 2 ≤ … ≤ steps; default: none).
    /// `slurry run --resume` continues from it bitwise identically.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub checkpoint_every: Option<u64>,
}

/// The default Mach limit, 0.3.
pub fn default_mach_limit() -> f64 {
    0.3
}

/// A case-file error: the file and what is wrong in it.
#[derive(Debug, thiserror::Error)]
#[error("{}: {kind}", file.display())]
pub struct CaseError {
    /// The case file (or the name given to [`Case::parse`]).
    pub file: PathBuf,
    /// What is wrong.
    pub kind: CaseErrorKind,
}

/// What is wrong in a case file. Every variant names the key (dotted, e.g. `fluid.tau`).
#[derive(Debug, thiserror::Error)]
pub enum CaseErrorKind {
    /// The file cannot be read.
    #[error("cannot read the case file: {0}")]
    Read(std::io::Error),
    /// Not valid TOML.
    #[error("TOML syntax error at line {line}, column {column}: {message}")]
    Syntax {
        /// 1-based line.
        line: usize,
        /// 1-based column.
        column: usize,
        /// The parser's message.
        message: String,
    },
    /// A key that the format does not have.
    #[error("unknown key `{key}`; allowed: {allowed}")]
    UnknownKey {
        /// The dotted key.
        key: String,
        /// The keys allowed at that place, comma-separated.
        allowed: String,
    },
    /// A required key is absent.
    #[error("missing key `{key}` ({what})")]
    Missing {
        /// The dotted key.
        key: String,
        /// What it should be.
        what: String,
    },
    /// A value of the wrong type or an unknown option (from serde).
    #[error("{}line {line}, column {column}: {message}", key.as_ref().map(|k| format!("`{k}` at ")).unwrap_or_default())]
    Type {
        /// The dotted key, when it could be located.
        key: Option<String>,
        /// 1-based line.
        line: usize,
        /// 1-based column.
        column: usize,
        /// Serde's message (names the expected type or the allowed options).
        message: String,
    },
    /// A value out of range or inconsistent with another.
    #[error("{key} = {value}: {allowed}")]
    Invalid {
        /// The dotted key.
        key: String,
        /// The value as written (normalised).
        value: String,
        /// What is allowed.
        allowed: String,
    },
}

impl CaseErrorKind {
    /// The dotted key the error is about, if any.
    pub fn key(&self) -> Option<&str> {
        match self {
            CaseErrorKind::Read(_) | CaseErrorKind::Syntax { .. } => None,
            CaseErrorKind::UnknownKey { key, .. }
            | CaseErrorKind::Missing { key, .. }
            | CaseErrorKind::Invalid { key, .. } => Some(key),
            CaseErrorKind::Type { key, .. } => key.as_deref(),
        }
    }
}

/// An [`CaseErrorKind::Invalid`]; computed limits in `allowed` are rounded for people
/// ([`crate::util::humanize_numbers`]: `2.4000000000000004` reads `2.4`).
fn invalid(key: impl Into<String>, value: impl fmt::Display, allowed: impl Into<String>) -> CaseErrorKind {
    CaseErrorKind::Invalid {
        key: key.into(),
        value: short_value(value.to_string()),
        allowed: crate::util::humanize_numbers(&allowed.into()),
    }
}

/// A value as written, but a number that Rust's `Display` spells with many digits
/// (`1e-300` as 0.000…001) in exponent form, which reads back the same.
fn short_value(v: String) -> String {
    match v.parse::<f64>() {
        Ok(x) if v.len() > 12 && x.is_finite() => {
            let e = format!("{x:e}");
            if e.len() < v.len() {
                e
            } else {
                v
            }
        }
        _ => v,
    }
}

/// Largest allowed relaxation time τ (`fluid.tau`, or `3 fluid.nu + 1/2`): beyond it the
/// fluid is so viscous per step that bounce-back walls slip by more than a lattice spacing
/// (their error grows as τ²) and the run says nothing physical; `nu = 1e12` was accepted.
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

/// Checks every key of the parsed document against the fields of the section structs.
fn check_unknown_keys(doc: &toml::Table) -> Result<(), CaseErrorKind> {
    let top = keys::struct_fields::<Case>();
    let unknown = |key: String, allowed: &[&str]| {
        let mut allowed = allowed.join(", ");
        if key.ends_with(".gravity") {
            allowed.push_str(" (gravity is a top-level key: write it above the first [table])");
        }
        CaseErrorKind::UnknownKey { key, allowed }
    };
    let check_table = |name: &str, t: &toml::Table, fields: &[&str]| -> Result<(), CaseErrorKind> {
        match t.keys().find(|k| !fields.contains(&k.as_str())) {
            Some(k) => Err(unknown(format!("{name}.{k}"), fields)),
            None => Ok(()),
        }
    };
    for (name, value) in doc {
        let fields: &[&str] = match name.as_str() {
            "gravity" => continue,
            "domain" => keys::struct_fields::<DomainSection>(),
            "fluid" => keys::struct_fields::<FluidSection>(),
            "boundaries" => keys::struct_fields::<BoundarySection>(),
            "initial" => keys::struct_fields::<InitialSection>(),
            "run" => keys::struct_fields::<RunSection>(),
            "ibm" => keys::struct_fields::<IbmSection>(),
            "contacts" => keys::struct_fields::<ContactsSection>(),
            "particles" => keys::struct_fields::<ParticleSpec>(),
            "random_particles" => keys::struct_fields::<RandomParticles>(),
            "impeller" => keys::struct_fields::<ImpellerSection>(),
            _ => return Err(unknown(name.clone(), top)),
        };
        let array_of_tables = name == "particles" || name == "random_particles";
        match value {
            // `[particles]` written for `[[particles]]`: serde's "expected a sequence" names
            // the line and the fix (`type_error`).
            toml::Value::Table(t) => check_table(name, t, fields)?,
            toml::Value::Array(items) if array_of_tables => {
                for (i, item) in items.iter().enumerate() {
                    match item {
                        toml::Value::Table(t) => check_table(&format!("{name}[{i}]"), t, fields)?,
                        other => {
                            return Err(CaseErrorKind::Invalid {
                                key: format!("{name}[{i}]"),
                                value: other.to_string(),
                                allowed: format!(
                                "each entry is a table of keys ({}): write [[{name}]] with one key per line",
                                fields.join(", ")
                            ),
                            })
                        }
                    }
                }
            }
            other => {
                let (what, write) = if array_of_tables {
                    ("an array of tables", format!("[[{name}]] (one per entry)"))
                } else {
                    ("a table", format!("[{name}] with its keys on the lines below"))
                };
                return Err(CaseErrorKind::Invalid {
                    key: name.clone(),
                    value: other.to_string(),
                    allowed: format!("{name} must be {what}: write {write}; keys: {}", fields.join(", ")),
                });
            }
        }
    }
    Ok(())
}

/// Turns a serde error from `toml::from_str` into a located, keyed error.
fn type_error(text: &str, e: &toml::de::Error) -> CaseErrorKind {
    let msg = one_line(e.message());
    let span = e.span();
    let (line, column) = span.as_ref().map_or((0, 0), |s| keys::line_column(text, s.start));
    let key = span.as_ref().and_then(|s| keys::key_at(text, s.start));
    // "missing field `nx`": the span covers the table that lacks it.
    if let Some(field) = msg.strip_prefix("missing field `").and_then(|r| r.strip_suffix('`')) {
        let key = match key {
            Some(section) if !keys::struct_fields::<Case>().contains(&field) => {
                format!("{section}.{field}")
            }
            _ => field.to_string(),
        };
        let what = missing_what(&key);
        return CaseErrorKind::Missing { key, what };
    }
    let mut message = plain_types(&msg);
    if let Some(k) = key.as_deref().filter(|k| *k == "particles" || *k == "random_particles") {
        if message.contains("expected a sequence") {
            message.push_str(&format!(" (write [[{k}]], an array of tables: one per entry)"));
        }
    }
    CaseErrorKind::Type { key, line, column, message }
}

/// Replaces Rust type names in serde messages with what a case-file author writes.
fn plain_types(msg: &str) -> String {
    msg.replace("expected usize", "expected a non-negative integer")
        .replace("expected u64", "expected a non-negative integer")
        .replace("expected f64", "expected a number")
}

/// A parser message on one line.
fn one_line(msg: &str) -> String {
    msg.trim().lines().map(str::trim).filter(|l| !l.is_empty()).collect::<Vec<_>>().join("; ")
}

/// What a required key should hold (for "missing key" messages).
fn missing_what(key: &str) -> String {
    match key {
        "domain" => "a [domain] table with nx, ny, nz".into(),
        "fluid" => "a [fluid] table with nu or tau".into(),
        "boundaries" => "a [boundaries] table with x_min, x_max, y_min, y_max, z_min, z_max".into(),
        "run" => "a [run] table with steps and output_every".into(),
        "domain.nx" | "domain.ny" | "domain.nz" => "an integer >= 1".into(),
        "run.steps" => "an integer >= 1".into(),
        "run.output_every" => "an integer, 1 <= output_every <= run.steps".into(),
        k if k.starts_with("particles[") || k.starts_with("random_particles[") => {
            match k.rsplit('.').next().unwrap_or("") {
                "shape" => "\"sphere\" or \"cylinder\"".into(),
                "diameter" => "a number > 0 (lattice units)".into(),
                "density" => "the density ratio rho_p/rho_f > 0".into(),
                "position" => "[x, y, z] (lattice units)".into(),
                "seed" => "an integer 0 <= seed < 2^63".into(),
                _ => "required".into(),
            }
        }
        k if k.starts_with("boundaries.") => {
            "\"periodic\", \"no_slip\" or { moving_wall = [ux, uy, uz] }".into()
        }
        _ => "required".into(),
    }
}

impl Case {
    /// Reads, parses and validates a case file.
    pub fn from_file(path: impl AsRef<Path>) -> Result<Case, CaseError> {
        let path = path.as_ref();
        let text = std::fs::read_to_string(path)
            .map_err(|e| CaseError { file: path.to_path_buf(), kind: CaseErrorKind::Read(e) })?;
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

    /// Checks ranges and consistency, and places the particles ([`Case::particle_inits`]).
    /// The first problem found is returned, naming its key.
    pub fn validate(&self) -> Result<(), CaseErrorKind> {
        self.validate_settings()?;
        self.check_memory()?;
        self.particle_inits().map(|_| ())
    }

    /// Compares the memory the case needs ([`memory::MemoryEstimate`]) with what the machine
    /// has ([`memory::available_memory`]); refuses the case, naming both, when it does not
    /// fit. The key named is `domain`, or the random population with the most markers when
    /// the particles need more than the grid. Nothing large is allocated here.
    pub fn check_memory(&self) -> Result<(), CaseErrorKind> {
        let Some(limit) = memory::available_memory() else { return Ok(()) };
        let est = memory::MemoryEstimate::of(self);
        if est.total() <= limit.bytes {
            return Ok(());
        }
        let d = &self.domain;
        let grid_value = format!("{} x {} x {} ({})", d.nx, d.ny, d.nz, self.fluid.precision.name());
        let biggest_population = (0..self.random_particles.len()).max_by(|&a, &b| {
            let m = |k: usize| self.random_count_f64(k);
            m(a).total_cmp(&m(b))
        });
        let (key, value, advice) = match biggest_population {
            Some(k) if est.grid_part() < est.markers.saturating_add(est.particles) => {
                let r = &self.random_particles[k];
                match r.volume_fraction {
                    Some(phi) => (
                        format!("random_particles[{k}].volume_fraction"),
                        phi.to_string(),
                        "lower the volume fraction or enlarge the particles",
                    ),
                    None => (
                        format!("random_particles[{k}].count"),
                        self.random_count(k).to_string(),
                        "lower the count",
                    ),
                }
            }
            _ => ("domain".to_string(), grid_value, "use a smaller grid or f32 precision"),
        };
        Err(invalid(
            key,
            value,
            format!(
                "the case needs about {}; this machine has {} available ({}): {advice}",
                est.describe(),
                memory::fmt_bytes(limit.bytes),
                limit.source
            ),
        ))
    }

    /// [`Case::validate`] without placing the particles (each particle entry is still
    /// checked on its own): the cheap part.
    pub fn validate_settings(&self) -> Result<(), CaseErrorKind> {
        self.validate_domain()?;
        self.validate_fluid()?;
        self.validate_run()?;
        self.validate_boundaries()?;
        self.validate_initial()?;
        self.validate_particle_settings()?;
        self.impeller_setup()?;
        Ok(())
    }

    fn validate_domain(&self) -> Result<(), CaseErrorKind> {
        let d = &self.domain;
        for (k, n) in [("nx", d.nx), ("ny", d.ny), ("nz", d.nz)] {
            if n < 1 {
                return Err(invalid(format!("domain.{k}"), n, "must be an integer >= 1"));
            }
        }
        let padded = (d.nx as u128 + 2) * (d.ny as u128 + 2) * (d.nz as u128 + 2);
        if padded >= u32::MAX as u128 {
            return Err(invalid(
                "domain",
                format!("{} x {} x {}", d.nx, d.ny, d.nz),
                "(nx+2)(ny+2)(nz+2) must be below 2^32 nodes",
            ));
        }
        Ok(())
    }

    fn validate_fluid(&self) -> Result<(), CaseErrorKind> {
        let f = &self.fluid;
        match (f.nu, f.tau) {
            (Some(_), Some(tau)) => {
                return Err(invalid(
                    "fluid.tau",
                    tau,
                    "give either fluid.nu or fluid.tau, not both (tau = 3 nu + 1/2)",
                ))
            }
            (None, None) => {
                return Err(CaseErrorKind::Missing {
                    key: "fluid.nu".into(),
                    what: "give fluid.nu > 0 or fluid.tau > 0.5".into(),
                })
            }
            (Some(nu), None) => {
                if !(nu.is_finite() && nu > 0.0) {
                    return Err(invalid("fluid.nu", nu, "must be finite and > 0 (tau = 3 nu + 1/2 > 0.5)"));
                }
                let tau = self.tau();
                let nu_max = (MAX_TAU - 0.5) * CS2;
                if tau.is_nan() || tau <= 0.5 {
                    return Err(invalid(
                        "fluid.nu",
                        nu,
                        format!(
                            "too small: tau = 3 nu + 1/2 rounds to {tau} in double precision, and tau must be > 0.5 \
                             (nu >= 1e-15 is safe; the allowed range is 0 < nu <= {nu_max})"
                        ),
                    ));
                }
                if tau > MAX_TAU {
                    return Err(invalid(
                        "fluid.nu",
                        nu,
                        format!("must be <= {nu_max} (tau = 3 nu + 1/2 <= {MAX_TAU}; here tau = {tau})"),
                    ));
                }
            }
            (None, Some(tau)) => {
                if !(tau.is_finite() && tau > 0.5 && tau <= MAX_TAU) {
                    return Err(invalid(
                        "fluid.tau",
                        tau,
                        format!("must be finite and > 0.5, and at most {MAX_TAU} (tau = 3 nu + 1/2; nu > 0)"),
                    ));
                }
                if self.tau().is_nan() || self.tau() <= 0.5 {
                    return Err(invalid(
                        "fluid.tau",
                        tau,
                        format!(
                            "too close to 0.5: the solver's tau = 3 nu + 1/2 with nu = (tau - 1/2)/3 rounds to {} \
                             (allowed: 0.5 < tau <= {MAX_TAU}, tau - 0.5 >= 1e-15 is safe)",
                            self.tau()
                        ),
                    ));
                }
            }
        }
        if let Some(magic) = f.magic {
            if f.collision != CollisionModel::Trt {
                return Err(invalid("fluid.magic", magic, "only allowed with fluid.collision = \"trt\""));
            }
            if !(magic.is_finite() && magic > 0.0) {
                return Err(invalid(
                    "fluid.magic",
                    magic,
                    "must be finite and > 0 (3/16 = 0.1875 puts bounce-back walls exactly half-way)",
                ));
            }
        }
        if f.body_force.iter().any(|g| !g.is_finite()) {
            return Err(invalid("fluid.body_force", fmt_vec(&f.body_force), "each component must be finite"));
        }
        self.fluid_params().validate().map_err(|e| self.map_fluid_error(e))
    }

    fn validate_run(&self) -> Result<(), CaseErrorKind> {
        let r = &self.run;
        if r.steps < 1 {
            return Err(invalid("run.steps", r.steps, "must be an integer >= 1"));
        }
        if r.output_every < 1 || r.output_every > r.steps {
            return Err(invalid(
                "run.output_every",
                r.output_every,
                format!("must be an integer with 1 <= output_every <= run.steps = {}", r.steps),
            ));
        }
        if let Some(c) = r.checkpoint_every {
            if c < 2 || !c.is_multiple_of(2) || c > r.steps {
                return Err(invalid(
                    "run.checkpoint_every",
                    c,
                    format!(
                        "must be an even integer with 2 <= checkpoint_every <= run.steps = {} \
                         (the solver's state is complete only after an even number of steps)",
                        r.steps
                    ),
                ));
            }
        }
        if !(r.mach_limit.is_finite() && r.mach_limit > 0.0 && r.mach_limit <= 1.0) {
            return Err(invalid(
                "run.mach_limit",
                r.mach_limit,
                "must be in (0, 1] (default 0.3; lattice Boltzmann is weakly compressible)",
            ));
        }
        Ok(())
    }

    fn validate_boundaries(&self) -> Result<(), CaseErrorKind> {
        let limit = self.run.mach_limit;
        for face in Face::ALL {
            if let BoundarySpec::MovingWall(v) = self.boundaries.get(face) {
                let key = format!("boundaries.{}.moving_wall", face.name());
                if v.iter().any(|c| !c.is_finite()) {
                    return Err(invalid(key, fmt_vec(&v), "each component must be finite"));
                }
                if v[face.axis()] != 0.0 {
                    return Err(invalid(
                        key,
                        fmt_vec(&v),
                        format!(
                            "the wall moves in its own plane: the {} component must be 0",
                            ["x", "y", "z"][face.axis()]
                        ),
                    ));
                }
                let m = mach(v);
                if m > limit {
                    return Err(invalid(
                        key,
                        fmt_vec(&v),
                        format!(
                            "wall Mach number |u|/c_s = {m:.3} exceeds run.mach_limit = {limit}; allowed: |u| <= {:.4}",
                            limit * CS2.sqrt()
                        ),
                    ));
                }
            }
        }
        self.boundaries().validate().map_err(|e| self.map_fluid_error(e))
    }

    fn validate_initial(&self) -> Result<(), CaseErrorKind> {
        let i = &self.initial;
        let limit = self.run.mach_limit;
        if !(i.density.is_finite() && i.density > 0.0) {
            return Err(invalid("initial.density", i.density, "must be finite and > 0 (default 1)"));
        }
        match i.kind {
            InitialKind::Uniform => {
                if let Some(a) = i.amplitude {
                    return Err(invalid(
                        "initial.amplitude",
                        a,
                        "only allowed with initial.kind = \"taylor_green\"",
                    ));
                }
                if let Some(v) = i.velocity {
                    if v.iter().any(|c| !c.is_finite()) {
                        return Err(invalid(
                            "initial.velocity",
                            fmt_vec(&v),
                            "each component must be finite",
                        ));
                    }
                    if mach(v) > limit {
                        return Err(invalid(
                            "initial.velocity",
                            fmt_vec(&v),
                            format!(
                                "Mach number {:.3} exceeds run.mach_limit = {limit}; allowed: |u| <= {:.4}",
                                mach(v),
                                limit * CS2.sqrt()
                            ),
                        ));
                    }
                }
            }
            InitialKind::TaylorGreen => {
                if let Some(v) = i.velocity {
                    return Err(invalid(
                        "initial.velocity",
                        fmt_vec(&v),
                        "not allowed with initial.kind = \"taylor_green\" (use initial.amplitude)",
                    ));
                }
                let Some(a) = i.amplitude else {
                    return Err(CaseErrorKind::Missing {
                        key: "initial.amplitude".into(),
                        what: "initial.kind = \"taylor_green\" needs a velocity amplitude > 0".into(),
                    });
                };
                let max_amp = limit * CS2.sqrt() / self.taylor_green_speed_factor();
                if !(a.is_finite() && a > 0.0 && a <= max_amp) {
                    return Err(invalid(
                        "initial.amplitude",
                        a,
                        format!(
                            "must be in (0, {max_amp:.4}]: the peak Mach number must stay below run.mach_limit = {limit}"
                        ),
                    ));
                }
                for (lo, hi) in [(Face::XMin, Face::XMax), (Face::YMin, Face::YMax)] {
                    let periodic = |f| self.boundaries.get(f) == BoundarySpec::Periodic;
                    if !(periodic(lo) && periodic(hi)) {
                        return Err(invalid(
                            "initial.kind",
                            "\"taylor_green\"",
                            format!("needs periodic boundaries.{} and boundaries.{}", lo.name(), hi.name()),
                        ));
                    }
                }
            }
        }
        Ok(())
    }

    /// Maps a solver validation error to the case key it comes from.
    fn map_fluid_error(&self, e: FluidError) -> CaseErrorKind {
        match e {
            FluidError::Viscosity { nu, tau } => match self.fluid.tau {
                Some(_) => invalid("fluid.tau", tau, format!("{e}")),
                None => invalid("fluid.nu", nu, format!("{e}")),
            },
            FluidError::Magic { magic } => invalid("fluid.magic", magic, format!("{e}")),
            FluidError::BodyForce { force } => invalid("fluid.body_force", fmt_vec(&force), format!("{e}")),
            FluidError::PeriodicPair { axis } => {
                let lo = Face::from_axis(axis, true);
                let hi = Face::from_axis(axis, false);
                invalid(
                    format!("boundaries.{}/{}", lo.name(), hi.name()),
                    format!(
                        "{} / {}",
                        self.boundaries.get(lo),
                        self.boundaries.get(hi)
                    ),
                    format!(
                        "periodic faces come in pairs: make both boundaries.{} and boundaries.{} periodic, or neither",
                        lo.name(),
                        hi.name()
                    ),
                )
            }
            FluidError::WallVelocity { face, velocity } => {
                invalid(format!("boundaries.{}.moving_wall", face.name()), fmt_vec(&velocity), format!("{e}"))
            }
            FluidError::Grid { grid } => {
                invalid("domain", format!("{} x {} x {}", grid.nx, grid.ny, grid.nz), format!("{e}"))
            }
            other => invalid("case", "?", other.to_string()),
        }
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

    /// The case's identity for checkpoints: its normalised TOML with `run.steps` and
    /// `run.checkpoint_every` left out, so that a resumed run may be extended or checkpoint at
    /// another cadence, but not change anything that alters the physics or the output cadence.
    pub fn fingerprint(&self) -> String {
        let mut c = self.clone();
        c.run.steps = 0;
        c.run.checkpoint_every = None;
        toml::to_string(&c).unwrap_or_default()
    }

    /// Number of time-series rows a run writes: step 0, every `output_every` steps, and the
    /// last step if it is not a multiple of `output_every`.
    pub fn output_rows(&self) -> u64 {
        1 + self.run.steps.div_ceil(self.run.output_every)
    }
}

#[cfg(test)]
mod tests;
