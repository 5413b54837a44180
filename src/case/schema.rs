//! The case file's schema: [`Case`] and its sections (serde), with their documented keys,
//! defaults and allowed values. Checked by `validate`, converted to the solver's types in
//! the parent module.

use super::*;

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
    pub contacts: Option<crate::contact::ContactParams>,
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

/// Which processor steps the fluid: the CPU solver or the device backend.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum Device {
    /// The CPU solver (`lbm::Fluid`), the reference.
    #[default]
    Cpu,
    /// The device backend (`device::DeviceFluid`): a GPU through Vulkan, or a CPU driver (lavapipe).
    Gpu,
}

impl Device {
    /// `"cpu"` or `"gpu"`.
    pub fn name(self) -> &'static str {
        match self {
            Device::Cpu => "cpu",
            Device::Gpu => "gpu",
        }
    }

    /// Whether this is the CPU (for `skip_serializing_if`: a case on the CPU reads as before).
    pub fn is_cpu(&self) -> bool {
        *self == Device::Cpu
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
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
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
    /// Steps at which the whole fields are written besides the last step's, as
    /// `fields-STEP.h5` with `fields-STEP.xmf` (the layout of `fields.h5`; STEP with 9
    /// digits), e.g. for figures at chosen times (each `1 ≤ … ≤ steps`; default none). Not
    /// part of the run's fingerprint: a resume may add some.
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub snapshots: Vec<u64>,
    /// Which processor steps the fluid: `"cpu"` (default) or `"gpu"` (the device backend: the
    /// fluid, and with particles or an impeller the markers too, on the device; f32 cases, and
    /// fluid-only f64 cases where the adapter has 64-bit float shaders; `slurry run --device`
    /// overrides it). Not part of the
    /// run's fingerprint: a checkpoint of either continues on the other.
    #[serde(default, skip_serializing_if = "Device::is_cpu")]
    pub device: Device,
}

/// The default Mach limit, 0.3.
pub fn default_mach_limit() -> f64 {
    0.3
}

/// Whether `l` is an allowed Mach limit (`[run] mach_limit`, `slurry reproduce --mach-limit`):
/// `0 < l ≤ 1`.
pub fn mach_limit_allowed(l: f64) -> bool {
    l.is_finite() && l > 0.0 && l <= 1.0
}
