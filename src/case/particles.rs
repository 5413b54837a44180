//! The particle sections of a case file: `gravity`, `[[particles]]` and
//! `[[random_particles]]`; their validation; and what a run needs from them: the initial
//! particles ([`Case::particle_inits`], [`Case::bodies`]) and the coupling options
//! ([`Case::coupling_params`]). The format is documented in `docs/case-format.md`.
//!
//! Every explicit particle and every random population is checked field by field (keys like
//! `particles[2].diameter`); then the explicit particles are checked against the box and
//! against each other, and the random populations are placed in file order, each clear of
//! everything placed before it (module [`super::placement`]). So [`Case::validate`] succeeding
//! means that [`Case::bodies`] succeeds too.

use std::f64::consts::PI;
use std::sync::Arc;

use serde::{Deserialize, Serialize};

use super::placement::{self, BoxGeometry, CellList, RandomRequest, ShapeDims};
pub use super::sections::IbmSection;
use super::{fmt_vec, invalid, mach, BoundarySpec, Case, CaseErrorKind};
use crate::coupling::{CouplingParams, DEFAULT_RETRACTION};
use crate::lattice::{Face, CS2};
use crate::rigid::{Cylinder, Motion, Quat, RigidBody, Shape, Sphere, Vec3, DEFAULT_MARKER_SPACING};

/// Allowed marker spacings (lattice units), inclusive.
pub const MARKER_SPACING_RANGE: (f64, f64) = (0.3, 1.0);
/// Allowed retractions of the forcing markers (lattice units): `[0, 0.5)`. The upper bound
/// keeps every particle solid ([`MIN_PARTICLE_SIZE`] is 1, so every dimension exceeds
/// `2 r_d`) and stays within the delta kernels' diffuse layer, which is what the retraction
/// compensates; an impeller's thin parts are checked against it on their own.
pub const RETRACTION_RANGE: (f64, f64) = (0.0, 0.5);
/// Largest allowed deviation of an orientation quaternion's norm from 1.
pub const QUATERNION_NORM_TOLERANCE: f64 = 1e-6;
/// Largest allowed `random_particles.volume_fraction`.
pub const MAX_VOLUME_FRACTION: f64 = 0.6;
/// Spacing kept between explicit particles and the walls on walled axes: none — a particle
/// must lie between the walls (at `−0.5` and `n − 0.5`), where every marker has an IBM stencil.
/// A settled bed (`slurry settle`) has particles resting closer than half a spacing to the
/// floor (the contact force's range is δ0 = 0.5), and its `[[particles]]` must be accepted.
pub const EXPLICIT_WALL_MARGIN: f64 = 0.0;
/// Spacing kept between random particles and the walls (default region).
pub const RANDOM_WALL_MARGIN: f64 = 1.0;
/// Smallest particle diameter (and cylinder length), lattice units: the IBM's delta
/// kernels spread each marker over 2–4 nodes, and a particle smaller than one lattice
/// spacing is not resolved (a sphere of diameter 1e-6 got a single marker).
pub const MIN_PARTICLE_SIZE: f64 = 1.0;

/// Particle shape as named in a case file.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum ShapeKind {
    /// A sphere of diameter `diameter`.
    Sphere,
    /// A flat-capped circular cylinder of diameter `diameter` and length `length` (axis along
    /// the body `z` axis).
    Cylinder,
}

impl ShapeKind {
    /// `"sphere"` or `"cylinder"`.
    pub fn name(self) -> &'static str {
        match self {
            ShapeKind::Sphere => "sphere",
            ShapeKind::Cylinder => "cylinder",
        }
    }
}

/// How a particle moves, as named in a case file.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum MotionKind {
    /// Moves under gravity, hydrodynamic and contact loads (the default).
    #[default]
    Free,
    /// Does not move.
    Fixed,
    /// Moves with the constant `velocity` and `angular_velocity` given.
    Prescribed,
}

impl MotionKind {
    /// `"free"`, `"fixed"` or `"prescribed"`.
    pub fn name(self) -> &'static str {
        match self {
            MotionKind::Free => "free",
            MotionKind::Fixed => "fixed",
            MotionKind::Prescribed => "prescribed",
        }
    }
}

fn one() -> f64 {
    1.0
}

/// One `[[particles]]` entry: a particle given explicitly.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ParticleSpec {
    /// `"sphere"` or `"cylinder"`.
    pub shape: ShapeKind,
    /// Diameter `d` (> 0).
    pub diameter: f64,
    /// Length `ℓ` of a cylinder (> 0; required for cylinders, not allowed for spheres).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub length: Option<f64>,
    /// Density ratio `γ = ρ_p/ρ_f` (> 0; the fluid density is 1).
    pub density: f64,
    /// Centre of mass `[x, y, z]`, lattice units (node `(i, j, k)` sits at `(i, j, k)`).
    pub position: [f64; 3],
    /// Orientation as a unit quaternion `[w, x, y, z]` (body → world); exclusive with `axis`.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub orientation: Option<[f64; 4]>,
    /// Direction of the body `z` axis (a cylinder's axis), any non-zero length; the
    /// orientation is the shortest rotation taking `z` to it. Exclusive with `orientation`.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub axis: Option<[f64; 3]>,
    /// Velocity of the centre (initial for free particles, constant for prescribed ones).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub velocity: Option<[f64; 3]>,
    /// Angular velocity, world frame (initial for free, constant for prescribed particles).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub angular_velocity: Option<[f64; 3]>,
    /// `"free"` (default), `"fixed"` or `"prescribed"`.
    #[serde(default)]
    pub motion: MotionKind,
}

/// One `[[random_particles]]` entry: a population of identical particles placed at random,
/// non-overlapping, with uniformly random orientations, at rest.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct RandomParticles {
    /// `"sphere"` or `"cylinder"`.
    pub shape: ShapeKind,
    /// Diameter `d` (> 0).
    pub diameter: f64,
    /// Length `ℓ` of a cylinder (> 0; required for cylinders, not allowed for spheres).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub length: Option<f64>,
    /// Density ratio `γ = ρ_p/ρ_f` (> 0).
    pub density: f64,
    /// Number of particles (≥ 1); exclusive with `volume_fraction`.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub count: Option<usize>,
    /// Solids volume fraction of the box, `n V_p/(nx ny nz)` (0 < … ≤ 0.6), from which the
    /// count is rounded; exclusive with `count`.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub volume_fraction: Option<f64>,
    /// Seed of the placement's random stream (0 … 2⁶³ − 1).
    pub seed: u64,
    /// `[[xlo, ylo, zlo], [xhi, yhi, zhi]]`: the box every particle of the population lies
    /// in entirely. Default: the domain less 1 lattice unit at each wall; the whole period
    /// on periodic axes (where particles may then cross the boundary).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub region: Option<[[f64; 3]; 2]>,
    /// Smallest surface-to-surface distance to every other particle (≥ 0.5; default 1).
    #[serde(default = "one")]
    pub clearance: f64,
    /// `"free"` (default) or `"fixed"`.
    #[serde(default)]
    pub motion: MotionKind,
}

/// A particle as it starts, fully resolved (explicit and random particles alike).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ParticleInit {
    /// Shape.
    pub shape: ShapeKind,
    /// Diameter.
    pub diameter: f64,
    /// Length (cylinders only).
    pub length: Option<f64>,
    /// Density ratio `ρ_p/ρ_f`.
    pub density: f64,
    /// Centre of mass.
    pub position: Vec3,
    /// Orientation (body → world).
    pub orientation: Quat,
    /// Velocity.
    pub velocity: Vec3,
    /// Angular velocity (world frame).
    pub angular_velocity: Vec3,
    /// Motion kind.
    pub motion: MotionKind,
}

impl ParticleInit {
    /// The rigid-body shape.
    pub fn shape(&self) -> Arc<dyn Shape> {
        match (self.shape, self.length) {
            (ShapeKind::Cylinder, Some(l)) => Arc::new(Cylinder::new(self.diameter, l)),
            _ => Arc::new(Sphere::new(self.diameter)),
        }
    }

    /// Volume `V_p`.
    pub fn volume(&self) -> f64 {
        particle_volume(self.shape, self.diameter, self.length)
    }

    /// The rigid body, in its initial state.
    pub fn body(&self) -> RigidBody {
        let motion = match self.motion {
            MotionKind::Free => Motion::Free,
            MotionKind::Fixed => Motion::Fixed,
            MotionKind::Prescribed => Motion::constant(self.velocity, self.angular_velocity),
        };
        let body = RigidBody::new(self.shape(), self.density, motion)
            .with_position(self.position)
            .with_orientation(self.orientation);
        match self.motion {
            MotionKind::Free => body.with_velocities(self.velocity, self.angular_velocity),
            _ => body,
        }
    }
}

/// Surface area: `π d²` or `π d ℓ + π d²/2`.
pub(super) fn particle_surface_area(shape: ShapeKind, d: f64, l: Option<f64>) -> f64 {
    match shape {
        ShapeKind::Sphere => PI * d * d,
        ShapeKind::Cylinder => PI * d * l.unwrap_or(f64::NAN) + 0.5 * PI * d * d,
    }
}

/// `π d³/6` or `π d² ℓ/4`.
fn particle_volume(shape: ShapeKind, d: f64, l: Option<f64>) -> f64 {
    match shape {
        ShapeKind::Sphere => PI * d * d * d / 6.0,
        ShapeKind::Cylinder => 0.25 * PI * d * d * l.unwrap_or(f64::NAN),
    }
}

fn dims(shape: ShapeKind, d: f64, l: Option<f64>) -> ShapeDims {
    match shape {
        ShapeKind::Sphere => ShapeDims::Sphere { diameter: d },
        ShapeKind::Cylinder => ShapeDims::Cylinder { diameter: d, length: l.unwrap_or(f64::NAN) },
    }
}

fn finite3(v: &[f64; 3]) -> bool {
    v.iter().all(|c| c.is_finite())
}

fn norm3(v: &[f64; 3]) -> f64 {
    (v[0] * v[0] + v[1] * v[1] + v[2] * v[2]).sqrt()
}

/// Checks `shape`, `diameter`, `length` and `density` of an entry whose keys start `prefix`.
fn check_shape(
    prefix: &str,
    shape: ShapeKind,
    diameter: f64,
    length: Option<f64>,
    density: f64,
) -> Result<(), CaseErrorKind> {
    if !(diameter.is_finite() && diameter > 0.0) {
        return Err(invalid(
            format!("{prefix}.diameter"),
            diameter,
            "must be finite and > 0 (lattice units)",
        ));
    }
    if diameter < MIN_PARTICLE_SIZE {
        return Err(invalid(
            format!("{prefix}.diameter"),
            diameter,
            format!(
                "must be >= {MIN_PARTICLE_SIZE} (lattice units): the immersed boundary needs a particle at least \
                 one lattice spacing across to resolve it"
            ),
        ));
    }
    match (shape, length) {
        (ShapeKind::Sphere, Some(l)) => {
            return Err(invalid(format!("{prefix}.length"), l, "only allowed with shape = \"cylinder\""));
        }
        (ShapeKind::Cylinder, None) => {
            return Err(CaseErrorKind::Missing {
                key: format!("{prefix}.length"),
                what: "a cylinder needs its length > 0 (lattice units)".into(),
            });
        }
        (ShapeKind::Cylinder, Some(l)) if !(l.is_finite() && l > 0.0) => {
            return Err(invalid(format!("{prefix}.length"), l, "must be finite and > 0 (lattice units)"));
        }
        (ShapeKind::Cylinder, Some(l)) if l < MIN_PARTICLE_SIZE => {
            return Err(invalid(
                format!("{prefix}.length"),
                l,
                format!(
                    "must be >= {MIN_PARTICLE_SIZE} (lattice units): the immersed boundary needs a particle at least \
                     one lattice spacing across to resolve it"
                ),
            ));
        }
        _ => {}
    }
    if !(density.is_finite() && density > 0.0) {
        return Err(invalid(
            format!("{prefix}.density"),
            density,
            "must be finite and > 0 (the density ratio rho_p/rho_f; the fluid density is 1)",
        ));
    }
    Ok(())
}

/// `[[a, b, c], [d, e, f]]`.
fn fmt_region(r: &[[f64; 3]; 2]) -> String {
    format!("[{}, {}]", fmt_vec(&r[0]), fmt_vec(&r[1]))
}

/// `[w, x, y, z]`.
fn fmt_quat(q: &[f64; 4]) -> String {
    format!("[{}, {}, {}, {}]", q[0], q[1], q[2], q[3])
}

const AXES: [&str; 3] = ["x", "y", "z"];

impl Case {
    /// Whether the case has particles (explicit or random).
    pub fn has_particles(&self) -> bool {
        !self.particles.is_empty() || !self.random_particles.is_empty()
    }

    /// Gravitational acceleration (default zero).
    pub fn gravity(&self) -> [f64; 3] {
        self.gravity.unwrap_or([0.0; 3])
    }

    /// The `[ibm]` section, with its defaults when absent.
    pub fn ibm(&self) -> IbmSection {
        self.ibm.unwrap_or_default()
    }

    /// The coupling options: `[ibm]` and `gravity`.
    pub fn coupling_params(&self) -> CouplingParams {
        let ibm = self.ibm();
        CouplingParams {
            kernel: ibm.kernel,
            iterations: ibm.iterations,
            marker_spacing: ibm.marker_spacing,
            retraction: ibm.retraction,
            gravity: self.gravity(),
            contacts: self.contacts,
        }
    }

    /// Number of particles of random population `k`: its `count`, or its `volume_fraction`
    /// of the box volume `nx ny nz` divided by the particle volume, rounded to the nearest
    /// integer. 0 for an invalid entry.
    pub fn random_count(&self, k: usize) -> usize {
        let r = &self.random_particles[k];
        match (r.count, r.volume_fraction) {
            (Some(n), None) => n,
            (None, Some(phi)) => {
                let v_box = (self.domain.nx * self.domain.ny * self.domain.nz) as f64;
                let n = (phi * v_box / particle_volume(r.shape, r.diameter, r.length)).round();
                if n.is_finite() && n >= 0.0 {
                    n as usize
                } else {
                    0
                }
            }
            _ => 0,
        }
    }

    /// [`Case::random_count`] in floating point, without its conversion to `usize` (for
    /// bounds: a volume fraction of tiny particles can ask for more than `usize` holds).
    pub fn random_count_f64(&self, k: usize) -> f64 {
        let r = &self.random_particles[k];
        match (r.count, r.volume_fraction) {
            (Some(n), None) => n as f64,
            (None, Some(phi)) => {
                let v_box = self.domain.nx as f64 * self.domain.ny as f64 * self.domain.nz as f64;
                let n = (phi * v_box / particle_volume(r.shape, r.diameter, r.length)).round();
                if n.is_finite() && n >= 0.0 {
                    n
                } else {
                    0.0
                }
            }
            _ => 0.0,
        }
    }

    /// Total number of particles (explicit plus random; saturating).
    pub fn particle_count(&self) -> usize {
        (0..self.random_particles.len())
            .map(|k| self.random_count(k))
            .fold(self.particles.len(), usize::saturating_add)
    }

    /// The case with the particle defaults written out (`gravity`, `[ibm]`, zero velocities)
    /// when it has particles: what `case.toml` in a run's output holds. A case without
    /// particles is returned unchanged.
    pub fn normalised(&self) -> Case {
        let mut c = self.clone();
        if c.has_particles() {
            c.gravity.get_or_insert([0.0; 3]);
            c.ibm.get_or_insert_with(IbmSection::default);
            for p in &mut c.particles {
                p.velocity.get_or_insert([0.0; 3]);
                p.angular_velocity.get_or_insert([0.0; 3]);
            }
        }
        c
    }

    /// Checks `gravity`, `[ibm]` and each particle entry on its own (no placement).
    pub(super) fn validate_particle_settings(&self) -> Result<(), CaseErrorKind> {
        if let Some(g) = self.gravity {
            if !finite3(&g) {
                return Err(invalid("gravity", fmt_vec(&g), "each component must be finite"));
            }
        }
        if let Some(ibm) = self.ibm {
            if ibm.iterations < 1 {
                return Err(invalid(
                    "ibm.iterations",
                    ibm.iterations,
                    "must be an integer >= 1 (direct-forcing iterations per time step; default 1)",
                ));
            }
            let (lo, hi) = MARKER_SPACING_RANGE;
            if !(ibm.marker_spacing.is_finite() && (lo..=hi).contains(&ibm.marker_spacing)) {
                return Err(invalid(
                    "ibm.marker_spacing",
                    ibm.marker_spacing,
                    format!(
                        "must be in [{lo}, {hi}] (lattice units; the paper uses 0.5-0.75; default {DEFAULT_MARKER_SPACING})"
                    ),
                ));
            }
            let (lo, hi) = RETRACTION_RANGE;
            if !(ibm.retraction.is_finite() && lo <= ibm.retraction && ibm.retraction < hi) {
                return Err(invalid(
                    "ibm.retraction",
                    ibm.retraction,
                    format!(
                        "must be in [{lo}, {hi}) (lattice units: how far the forcing markers are moved into every \
                         body; default {DEFAULT_RETRACTION}, calibrated for kernel = \"roma3\", iterations = 1)"
                    ),
                ));
            }
        }
        if let Some(c) = self.contacts {
            if let Err(e) = c.validate() {
                return Err(invalid(
                    format!("contacts.{}", e.name),
                    e.value,
                    format!("must be {}", e.allowed),
                ));
            }
            if !(1..=1024).contains(&c.substeps) {
                return Err(invalid(
                    "contacts.substeps",
                    c.substeps,
                    "must be an integer in [1, 1024] (contact sub-steps per fluid step)",
                ));
            }
        }
        for (i, p) in self.particles.iter().enumerate() {
            self.validate_explicit(i, p)?;
        }
        for (k, r) in self.random_particles.iter().enumerate() {
            self.validate_random(k, r)?;
        }
        Ok(())
    }

    fn periodic_axes(&self) -> [bool; 3] {
        std::array::from_fn(|a| self.boundaries.get(Face::from_axis(a, true)) == BoundarySpec::Periodic)
    }

    fn box_geometry(&self) -> BoxGeometry {
        BoxGeometry { n: [self.domain.nx, self.domain.ny, self.domain.nz], periodic: self.periodic_axes() }
    }

    fn validate_explicit(&self, i: usize, p: &ParticleSpec) -> Result<(), CaseErrorKind> {
        let pre = format!("particles[{i}]");
        check_shape(&pre, p.shape, p.diameter, p.length, p.density)?;
        if !finite3(&p.position) {
            return Err(invalid(
                format!("{pre}.position"),
                fmt_vec(&p.position),
                "each component must be finite",
            ));
        }
        if let (Some(_), Some(a)) = (p.orientation, p.axis) {
            return Err(invalid(
                format!("{pre}.axis"),
                fmt_vec(&a),
                "give either orientation = [w, x, y, z] or axis = [ax, ay, az], not both",
            ));
        }
        if let Some(q) = p.orientation {
            let n = (q.iter().map(|c| c * c).sum::<f64>()).sqrt();
            if !(q.iter().all(|c| c.is_finite()) && (n - 1.0).abs() <= QUATERNION_NORM_TOLERANCE) {
                return Err(invalid(
                    format!("{pre}.orientation"),
                    fmt_quat(&q),
                    format!(
                        "must be a unit quaternion [w, x, y, z] (its norm is {n}; allowed: |norm - 1| <= {QUATERNION_NORM_TOLERANCE})"
                    ),
                ));
            }
        }
        if let Some(a) = p.axis {
            if !(finite3(&a) && norm3(&a) > 0.0) {
                return Err(invalid(
                    format!("{pre}.axis"),
                    fmt_vec(&a),
                    "must be a finite, non-zero direction (the body z axis; normalised)",
                ));
            }
        }
        for (key, v) in [("velocity", p.velocity), ("angular_velocity", p.angular_velocity)] {
            let Some(v) = v else { continue };
            if !finite3(&v) {
                return Err(invalid(format!("{pre}.{key}"), fmt_vec(&v), "each component must be finite"));
            }
            if p.motion == MotionKind::Fixed && v != [0.0; 3] {
                return Err(invalid(
                    format!("{pre}.{key}"),
                    fmt_vec(&v),
                    "a particle with motion = \"fixed\" does not move: leave it out or give [0, 0, 0]",
                ));
            }
        }
        let limit = self.run.mach_limit;
        let v = p.velocity.unwrap_or([0.0; 3]);
        let w = p.angular_velocity.unwrap_or([0.0; 3]);
        if mach(v) > limit {
            return Err(invalid(
                format!("{pre}.velocity"),
                fmt_vec(&v),
                format!(
                    "Mach number {:.3} exceeds run.mach_limit = {limit}; allowed: |v| <= {:.4}",
                    mach(v),
                    limit * CS2.sqrt()
                ),
            ));
        }
        let r = dims(p.shape, p.diameter, p.length).bounding_radius();
        let surface = norm3(&v) + norm3(&w) * r;
        if surface / CS2.sqrt() > limit {
            return Err(invalid(
                format!("{pre}.angular_velocity"),
                fmt_vec(&w),
                format!(
                    "the fastest surface point moves at |v| + |w| r = {surface:.4} (r = {r:.4}, the bounding radius): \
                     Mach {:.3} exceeds run.mach_limit = {limit}",
                    surface / CS2.sqrt()
                ),
            ));
        }
        Ok(())
    }

    fn validate_random(&self, k: usize, r: &RandomParticles) -> Result<(), CaseErrorKind> {
        let pre = format!("random_particles[{k}]");
        check_shape(&pre, r.shape, r.diameter, r.length, r.density)?;
        match (r.count, r.volume_fraction) {
            (Some(_), Some(phi)) => {
                return Err(invalid(
                    format!("{pre}.volume_fraction"),
                    phi,
                    "give either count or volume_fraction, not both",
                ));
            }
            (None, None) => {
                return Err(CaseErrorKind::Missing {
                    key: format!("{pre}.count"),
                    what: format!("give count >= 1 or volume_fraction in (0, {MAX_VOLUME_FRACTION}]"),
                });
            }
            (Some(n), None) if n < 1 => {
                return Err(invalid(format!("{pre}.count"), n, "must be an integer >= 1"));
            }
            (None, Some(phi)) => {
                if !(phi.is_finite() && phi > 0.0 && phi <= MAX_VOLUME_FRACTION) {
                    return Err(invalid(
                        format!("{pre}.volume_fraction"),
                        phi,
                        format!("must be in (0, {MAX_VOLUME_FRACTION}] (solids volume over the box volume nx ny nz)"),
                    ));
                }
                if self.random_count(k) < 1 {
                    return Err(invalid(
                        format!("{pre}.volume_fraction"),
                        phi,
                        format!(
                            "gives no particle: volume_fraction * nx ny nz / particle volume = {:.3} rounds to 0",
                            phi * (self.domain.nx * self.domain.ny * self.domain.nz) as f64
                                / particle_volume(r.shape, r.diameter, r.length)
                        ),
                    ));
                }
            }
            _ => {}
        }
        if !(r.clearance.is_finite() && r.clearance >= 0.5) {
            return Err(invalid(
                format!("{pre}.clearance"),
                r.clearance,
                "must be finite and >= 0.5 (lattice units, surface to surface, at least the elastic range delta0 = 0.5 of Table 1; default 1)",
            ));
        }
        if r.motion == MotionKind::Prescribed {
            return Err(invalid(
                format!("{pre}.motion"),
                "\"prescribed\"",
                "random particles are \"free\" or \"fixed\" (give prescribed particles as [[particles]])",
            ));
        }
        if let Some(reg) = r.region {
            let periodic = self.periodic_axes();
            let n = [self.domain.nx, self.domain.ny, self.domain.nz];
            for a in 0..3 {
                let (lo, hi) = (reg[0][a], reg[1][a]);
                let (min, max) = if periodic[a] {
                    (-0.5, n[a] as f64 - 0.5)
                } else {
                    (RANDOM_WALL_MARGIN - 0.5, n[a] as f64 - 0.5 - RANDOM_WALL_MARGIN)
                };
                if !(lo.is_finite() && hi.is_finite() && lo < hi && lo >= min && hi <= max) {
                    let why = if periodic[a] {
                        "the periodic box"
                    } else {
                        "the box less 1 lattice unit at each wall (walls at -0.5 and n - 0.5)"
                    };
                    return Err(invalid(
                        format!("{pre}.region"),
                        fmt_region(&reg),
                        format!(
                            "[[xlo, ylo, zlo], [xhi, yhi, zhi]] with lo < hi inside {why}: on {} {min} <= lo < hi <= {max}",
                            AXES[a]
                        ),
                    ));
                }
            }
        }
        // What can be placed at all: the population's solids volume within its region.
        let n = [self.domain.nx, self.domain.ny, self.domain.nz];
        let periodic = self.periodic_axes();
        let region_volume: f64 = (0..3)
            .map(|a| match r.region {
                Some(reg) => reg[1][a] - reg[0][a],
                None if periodic[a] => n[a] as f64,
                None => (n[a] as f64 - 2.0 * RANDOM_WALL_MARGIN).max(0.0),
            })
            .product();
        let count = self.random_count_f64(k);
        let v_p = particle_volume(r.shape, r.diameter, r.length);
        let filled = count * v_p / region_volume;
        if filled.is_nan() || filled > MAX_VOLUME_FRACTION {
            let (key, value) = match r.volume_fraction {
                Some(phi) => ("volume_fraction", phi.to_string()),
                None => ("count", format!("{count}")),
            };
            let most = (MAX_VOLUME_FRACTION * region_volume / v_p).floor();
            return Err(invalid(
                format!("{pre}.{key}"),
                value,
                format!(
                    "{} particles of volume {} would take {} times the volume {} of their region; at most \
                     {MAX_VOLUME_FRACTION} of it can be filled, i.e. count <= {most} (random placement reaches \
                     about 0.38 for spheres, less for elongated cylinders)",
                    crate::util::fmt_num(count),
                    crate::util::fmt_num(v_p),
                    crate::util::fmt_num(filled),
                    crate::util::fmt_num(region_volume)
                ),
            ));
        }
        Ok(())
    }

    /// Every particle as it starts: the explicit ones in file order, then each random
    /// population in file order. Checks each entry, that explicit particles lie inside the box
    /// (with [`EXPLICIT_WALL_MARGIN`] to spare on walled axes) and do not overlap, and places
    /// the random populations (module [`super::placement`]), each particle clear of every
    /// other by its population's `clearance`.
    ///
    /// # Errors
    /// The first problem, naming its key (e.g. `particles[3].position`, or
    /// `random_particles[0].count` when not all could be placed).
    pub fn particle_inits(&self) -> Result<Vec<ParticleInit>, CaseErrorKind> {
        self.validate_particle_settings()?;
        if !self.has_particles() {
            return Ok(Vec::new());
        }
        let geometry = self.box_geometry();
        let n = geometry.n;
        let mut reach: f64 = 0.0;
        for p in &self.particles {
            reach = reach.max(2.0 * dims(p.shape, p.diameter, p.length).bounding_radius());
        }
        let mut clearance_max: f64 = 0.0;
        for r in &self.random_particles {
            reach = reach.max(2.0 * dims(r.shape, r.diameter, r.length).bounding_radius());
            clearance_max = clearance_max.max(r.clearance);
        }
        let mut cells = CellList::new(geometry, reach + clearance_max);
        let mut out = Vec::with_capacity(self.particle_count());

        for (i, p) in self.particles.iter().enumerate() {
            let pre = format!("particles[{i}]");
            let orientation = match (p.orientation, p.axis) {
                (Some(q), _) => Quat::from_quaternion(nalgebra::Quaternion::new(q[0], q[1], q[2], q[3])),
                (None, Some(a)) => {
                    let a = Vec3::from(a);
                    Quat::rotation_between(&Vec3::z(), &a)
                        .unwrap_or_else(|| Quat::from_axis_angle(&Vec3::x_axis(), PI))
                }
                (None, None) => Quat::identity(),
            };
            let init = ParticleInit {
                shape: p.shape,
                diameter: p.diameter,
                length: p.length,
                density: p.density,
                position: Vec3::from(p.position),
                orientation,
                velocity: Vec3::from(p.velocity.unwrap_or([0.0; 3])),
                angular_velocity: Vec3::from(p.angular_velocity.unwrap_or([0.0; 3])),
                motion: p.motion,
            };
            let body = dims(p.shape, p.diameter, p.length).at(init.position, &orientation);
            let e = body.half_extents();
            for a in 0..3 {
                let (x, na) = (p.position[a], n[a] as f64);
                if geometry.periodic[a] {
                    if !(-0.5..na - 0.5).contains(&x) {
                        return Err(invalid(
                            format!("{pre}.position"),
                            fmt_vec(&p.position),
                            format!(
                                "on the periodic {} axis the centre must lie in [-0.5, {})",
                                AXES[a],
                                na - 0.5
                            ),
                        ));
                    }
                    if 2.0 * e[a] >= na {
                        return Err(invalid(
                            format!("{pre}.position"),
                            fmt_vec(&p.position),
                            format!(
                                "the particle is {:.4} across on the periodic {} axis: it must be shorter than the period {na}",
                                2.0 * e[a],
                                AXES[a]
                            ),
                        ));
                    }
                } else {
                    let (lo, hi) = (EXPLICIT_WALL_MARGIN - 0.5, na - 0.5 - EXPLICIT_WALL_MARGIN);
                    if x - e[a] < lo || x + e[a] > hi {
                        let allowed = if lo + e[a] <= hi - e[a] {
                            format!(
                                "the particle reaches {:.4} .. {:.4} on {ax} (half extent {:.4}); it must stay within [{lo}, {hi}] \
                                 (between the walls at -0.5 and {}), so {ax} must be in [{:.4}, {:.4}]",
                                x - e[a],
                                x + e[a],
                                e[a],
                                na - 0.5,
                                lo + e[a],
                                hi - e[a],
                                ax = AXES[a],
                            )
                        } else {
                            format!(
                                "the particle is {:.4} across on {}: it does not fit between the walls (at most {})",
                                2.0 * e[a],
                                AXES[a],
                                hi - lo
                            )
                        };
                        return Err(invalid(format!("{pre}.position"), fmt_vec(&p.position), allowed));
                    }
                }
            }
            if let Some(j) = cells.first_conflict(&body, 0.0) {
                return Err(invalid(
                    format!("{pre}.position"),
                    fmt_vec(&p.position),
                    format!(
                        "{pre} overlaps particles[{j}] (at {}): explicit particles must not overlap",
                        fmt_vec(&self.particles[j].position)
                    ),
                ));
            }
            cells.insert(body);
            out.push(init);
        }

        for (k, r) in self.random_particles.iter().enumerate() {
            let count = self.random_count(k);
            let region: [Option<(f64, f64)>; 3] = std::array::from_fn(|a| match r.region {
                Some(reg) => Some((reg[0][a], reg[1][a])),
                None if geometry.periodic[a] => None,
                None => Some((RANDOM_WALL_MARGIN - 0.5, n[a] as f64 - 0.5 - RANDOM_WALL_MARGIN)),
            });
            let req = RandomRequest {
                shape: dims(r.shape, r.diameter, r.length),
                count,
                seed: r.seed,
                region,
                clearance: r.clearance,
            };
            let placed = placement::place_random(&mut cells, &req).map_err(|f| {
                let (key, value) = match r.volume_fraction {
                    Some(phi) => ("volume_fraction", phi.to_string()),
                    None => ("count", count.to_string()),
                };
                invalid(
                    format!("random_particles[{k}].{key}"),
                    value,
                    format!(
                        "placed only {} of {count} non-overlapping particles ({} attempts; a particle gets {} \
                         attempts in a row): lower the count or volume fraction, enlarge the region, or reduce the clearance",
                        f.placed,
                        f.attempts,
                        placement::MAX_FAILED_ATTEMPTS
                    ),
                )
            })?;
            out.extend(placed.into_iter().map(|(position, orientation)| ParticleInit {
                shape: r.shape,
                diameter: r.diameter,
                length: r.length,
                density: r.density,
                position,
                orientation,
                velocity: Vec3::zeros(),
                angular_velocity: Vec3::zeros(),
                motion: r.motion,
            }));
        }
        self.check_clear_of_impeller(&out)?;
        Ok(out)
    }

    /// Checks that no particle overlaps the impeller at its start position: every marker of
    /// the particle (spacing `[ibm].marker_spacing`) outside the impeller. The paper settles
    /// the bed first and inserts the impeller above it (physics.md §2).
    fn check_clear_of_impeller(&self, inits: &[ParticleInit]) -> Result<(), CaseErrorKind> {
        let Some(imp) = self.impeller_setup()? else { return Ok(()) };
        let body = imp.body();
        let spacing = self.ibm().marker_spacing;
        let mut owner = Vec::with_capacity(inits.len());
        owner.extend((0..self.particles.len()).map(|i| format!("particles[{i}].position")));
        for k in 0..self.random_particles.len() {
            owner.extend(std::iter::repeat_n(format!("random_particles[{k}].region"), self.random_count(k)));
        }
        for (i, p) in inits.iter().enumerate() {
            let pb = p.body();
            let r = pb.shape().bounding_radius();
            if body.signed_distance(&p.position) > r {
                continue;
            }
            let clash = pb
                .shape()
                .markers(spacing)
                .iter()
                .any(|m| body.signed_distance(&pb.marker_world(m).0) <= 0.0);
            if clash {
                let key = owner.get(i).cloned().unwrap_or_else(|| "particles".into());
                return Err(invalid(
                    key,
                    fmt_vec(&[p.position.x, p.position.y, p.position.z]),
                    format!(
                        "particle {i} overlaps the impeller; particles must start clear of it (settle the bed \
                         without the impeller, then add it: physics.md §2)"
                    ),
                ));
            }
        }
        Ok(())
    }

    /// The rigid bodies of [`Case::particle_inits`], in the same order.
    ///
    /// # Errors
    /// As [`Case::particle_inits`].
    pub fn bodies(&self) -> Result<Vec<RigidBody>, CaseErrorKind> {
        Ok(self.particle_inits()?.iter().map(ParticleInit::body).collect())
    }
}
