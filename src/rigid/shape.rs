//! The shape trait: what the rest of the code needs to know about a rigid body's geometry.
//!
//! Every quantity is in the body frame: origin at the centre of mass (centroid: bodies are
//! homogeneous), axes along the principal axes of inertia. New shapes (the impellers next)
//! implement [`Shape`] and plug into [`super::RigidBody`] unchanged.

use super::{Mat3, Vec3};

/// Default surface-marker spacing, in lattice units (Δ): 0.7, inside the 0.5–0.75 Δ the paper
/// uses on every solid surface (physics.md §1).
pub const DEFAULT_MARKER_SPACING: f64 = 0.7;

/// Mass and principal moments of inertia of a homogeneous body.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct MassProperties {
    /// Mass `m = ρ V`.
    pub mass: f64,
    /// Principal moments `(I_x, I_y, I_z)` about the centre of mass, along the body axes.
    pub principal_moments: Vec3,
}

/// A point on a body's surface, for the immersed boundary method and for contacts.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Marker {
    /// Position in the body frame.
    pub position: Vec3,
    /// Outward unit normal in the body frame.
    pub normal: Vec3,
    /// Area weight: the surface area the marker stands for. The weights of a shape's markers
    /// sum to its [`Shape::surface_area`] (to round-off).
    pub area: f64,
}

/// A rigid body's geometry, in its body frame.
///
/// Implementations must be consistent: `contains(p) ⇔ signed_distance(p) < 0`, the markers
/// lie on the surface (`signed_distance ≈ 0`) with outward unit normals, and
/// `principal_moments_unit_density` is diagonal in the body axes (the body frame *is* the
/// principal frame).
pub trait Shape: Send + Sync + std::fmt::Debug {
    /// A short name (`"sphere"`, `"cylinder"`), for messages and output.
    fn name(&self) -> &'static str;

    /// Volume `V`.
    fn volume(&self) -> f64;

    /// Surface area `S` (what the marker area weights sum to).
    fn surface_area(&self) -> f64;

    /// Principal moments of inertia at unit density, `∫_V (y² + z², z² + x², x² + y²) dV`.
    fn principal_moments_unit_density(&self) -> Vec3;

    /// Mass and principal moments at density `density`: `m = ρ V`, `I = ρ I₁`.
    fn mass_properties(&self, density: f64) -> MassProperties {
        MassProperties {
            mass: density * self.volume(),
            principal_moments: self.principal_moments_unit_density() * density,
        }
    }

    /// Signed distance from `p` (body frame) to the surface: negative inside, positive
    /// outside, zero on the surface. Exact (a true Euclidean distance) for the shapes here.
    fn signed_distance(&self, p: &Vec3) -> f64;

    /// Whether `p` (body frame) lies strictly inside.
    fn contains(&self, p: &Vec3) -> bool {
        self.signed_distance(p) < 0.0
    }

    /// Radius of the smallest sphere about the centre of mass that encloses the body (the
    /// broad phase of contacts uses it).
    fn bounding_radius(&self) -> f64;

    /// Half extents of a world-frame axis-aligned box, centred on the centre of mass, that
    /// contains every point with `signed_distance < offset` (`offset ≥ 0`) when the body has
    /// rotation `rotation` (body → world). The default is the bounding sphere's cube,
    /// `bounding_radius + offset` on every axis; shapes override it with a tighter box.
    fn half_extents(&self, rotation: &Mat3, offset: f64) -> Vec3 {
        let _ = rotation;
        Vec3::repeat(self.bounding_radius() + offset)
    }

    /// The parameter interval `(t₀, t₁)` of the line `p + t·dir` (body frame, `|dir| = 1`)
    /// that meets the set `{signed_distance < offset}`, as follows:
    /// - `offset ≥ 0`: an interval that **contains** every such `t` (a superset is allowed:
    ///   the caller visits nodes in it and tests them);
    /// - `offset < 0`: an interval **contained** in the set (a subset is allowed: the caller
    ///   skips the nodes in it as "deep inside").
    ///
    /// `None` means: no point (superset case), or nothing known (subset case). The default
    /// uses the bounding sphere for `offset ≥ 0` and knows nothing for `offset < 0`; shapes
    /// override it with exact chords. The immersed boundary band and the interior-fluid sums
    /// of `coupling` are built from these chords, row by row.
    fn chord(&self, p: &Vec3, dir: &Vec3, offset: f64) -> Option<(f64, f64)> {
        if offset < 0.0 {
            return None;
        }
        sphere_chord(p, dir, self.bounding_radius() + offset)
    }

    /// Surface markers at (about) `spacing` apart, with outward unit normals and area weights
    /// summing to [`Shape::surface_area`]. Each shape documents its layout.
    fn markers(&self, spacing: f64) -> Vec<Marker>;

    /// The immersed boundary's forcing markers: the markers (at `spacing`, the same layout as
    /// [`Shape::markers`]) of the surface **retracted** inward by `depth ≥ 0`, i.e. of the
    /// inner parallel body `{sd ≤ −depth}`, with that surface's outward normals and **its**
    /// area weights (they sum to the retracted surface's area, not to
    /// [`Shape::surface_area`]). Every marker lies at signed distance `−depth` from the true
    /// surface. For the convex shapes here the inner parallel body is the same shape with
    /// every dimension reduced by `2 depth` (sphere `d − 2r`; cylinder `d − 2r`, `ℓ − 2r`,
    /// rims included; cuboid every edge `− 2r`); an impeller retracts each part and drops
    /// the markers inside another retracted part. `depth = 0` gives [`Shape::markers`]
    /// exactly. Why the markers are retracted, and by how much: [`crate::coupling`],
    /// "The immersed boundary's effective size".
    ///
    /// The default supports `depth = 0` only.
    ///
    /// # Errors
    /// A dimension of the shape not larger than `2 depth` (nothing would be left), or
    /// `depth` negative or not finite.
    fn retracted_markers(&self, spacing: f64, depth: f64) -> Result<Vec<Marker>, RetractionError> {
        check_depth(depth)?;
        if depth == 0.0 {
            Ok(self.markers(spacing))
        } else {
            Err(RetractionError::Unsupported { shape: self.name() })
        }
    }
}

/// Why a shape's markers cannot be retracted ([`Shape::retracted_markers`]).
#[derive(Clone, Debug, PartialEq, thiserror::Error)]
pub enum RetractionError {
    /// The depth is negative or not finite.
    #[error("retraction {0} must be finite and >= 0")]
    Depth(f64),
    /// A dimension of the shape is not larger than twice the depth.
    #[error(
        "a retraction of {depth} needs the {shape}'s {dimension} ({value}) to exceed 2 x {depth} = {}; \
         lower [ibm].retraction or resolve the {shape} with more lattice nodes",
        2.0 * depth
    )]
    TooThin {
        /// The shape (or impeller part).
        shape: &'static str,
        /// The dimension (`"diameter"`, `"length"`, `"blade_thickness"`, …).
        dimension: &'static str,
        /// Its value (lattice units).
        value: f64,
        /// The retraction depth.
        depth: f64,
    },
    /// The shape does not implement retraction.
    #[error("the {shape} has no retracted markers")]
    Unsupported {
        /// The shape.
        shape: &'static str,
    },
}

/// `depth` must be finite and non-negative.
pub(crate) fn check_depth(depth: f64) -> Result<(), RetractionError> {
    if depth.is_finite() && depth >= 0.0 {
        Ok(())
    } else {
        Err(RetractionError::Depth(depth))
    }
}

/// `value − 2 depth`, or [`RetractionError::TooThin`] if that is not positive.
pub(crate) fn shrink(
    shape: &'static str,
    dimension: &'static str,
    value: f64,
    depth: f64,
) -> Result<f64, RetractionError> {
    let v = value - 2.0 * depth;
    if v > 0.0 {
        Ok(v)
    } else {
        Err(RetractionError::TooThin { shape, dimension, value, depth })
    }
}

/// The chord `(t₀, t₁)` of the line `p + t·dir` (`|dir| = 1`) through the open ball of radius
/// `r` about the origin, or `None` if it misses (or `r ≤ 0`).
pub(crate) fn sphere_chord(p: &Vec3, dir: &Vec3, r: f64) -> Option<(f64, f64)> {
    if r <= 0.0 {
        return None;
    }
    let b = p.dot(dir);
    let c = p.norm_squared() - r * r;
    let disc = b * b - c;
    if disc <= 0.0 {
        return None;
    }
    let s = disc.sqrt();
    Some((-b - s, -b + s))
}

/// `n` points equally spaced on a circle of radius `r` at height `z`, starting at angle
/// `phase`; each with normal `normal(cosθ, sinθ)` and weight `area`. Shared by the shapes.
pub(crate) fn ring(
    out: &mut Vec<Marker>,
    n: usize,
    r: f64,
    z: f64,
    phase: f64,
    area: f64,
    normal: impl Fn(f64, f64) -> Vec3,
) {
    for k in 0..n {
        let th = phase + std::f64::consts::TAU * k as f64 / n as f64;
        let (s, c) = th.sin_cos();
        out.push(Marker { position: Vec3::new(r * c, r * s, z), normal: normal(c, s), area });
    }
}

/// Test helpers shared by the shapes' unit tests.
#[cfg(test)]
pub(crate) mod testing {
    use super::{Marker, Shape, Vec3};

    pub use crate::util::SplitMix64 as SplitMix;

    /// Monte Carlo estimate of volume and unit-density principal moments with `n` samples
    /// uniform in the box `[-h, h]³`, with their standard errors (from the sample variance).
    /// Returns `([V, Ix, Iy, Iz], [σ_V, σ_Ix, σ_Iy, σ_Iz])`.
    pub fn monte_carlo(shape: &dyn Shape, h: Vec3, n: usize, seed: u64) -> ([f64; 4], [f64; 4]) {
        let mut rng = SplitMix(seed);
        let vbox = 8.0 * h.x * h.y * h.z;
        let mut sum = [0.0f64; 4];
        let mut sum2 = [0.0f64; 4];
        for _ in 0..n {
            let p = Vec3::new(rng.uniform(-h.x, h.x), rng.uniform(-h.y, h.y), rng.uniform(-h.z, h.z));
            if shape.contains(&p) {
                let g = [1.0, p.y * p.y + p.z * p.z, p.z * p.z + p.x * p.x, p.x * p.x + p.y * p.y];
                for k in 0..4 {
                    sum[k] += g[k];
                    sum2[k] += g[k] * g[k];
                }
            }
        }
        let nf = n as f64;
        let mut est = [0.0; 4];
        let mut err = [0.0; 4];
        for k in 0..4 {
            let mean = sum[k] / nf;
            let var = sum2[k] / nf - mean * mean;
            est[k] = vbox * mean;
            err[k] = vbox * (var / nf).sqrt();
        }
        (est, err)
    }

    /// Asserts that each Monte Carlo estimate lies within five of its standard errors of the
    /// exact value: a seeded estimator, so the test is deterministic; a correct formula fails
    /// by chance with probability 6e-7, a wrong factor is off by far more.
    pub fn assert_within_5_sigma(est: &[f64; 4], err: &[f64; 4], exact: &[f64; 4]) {
        for k in 0..4 {
            assert!(
                (est[k] - exact[k]).abs() < 5.0 * err[k],
                "k={k}: {} vs {} ± {}",
                est[k],
                exact[k],
                err[k]
            );
        }
    }

    /// `∇ sd` at `p` by central differences of step `1e-6`.
    pub fn sd_gradient(shape: &dyn Shape, p: &Vec3) -> Vec3 {
        let e = 1e-6;
        Vec3::from_fn(|k, _| {
            let mut dp = Vec3::zeros();
            dp[k] = e;
            (shape.signed_distance(&(p + dp)) - shape.signed_distance(&(p - dp))) / (2.0 * e)
        })
    }

    /// Nearest-neighbour distance of every marker (brute force).
    pub fn nearest_neighbour(m: &[Marker]) -> Vec<f64> {
        m.iter()
            .enumerate()
            .map(|(i, a)| {
                m.iter()
                    .enumerate()
                    .filter(|&(j, _)| j != i)
                    .map(|(_, b)| (a.position - b.position).norm())
                    .fold(f64::INFINITY, f64::min)
            })
            .collect()
    }

    /// Checks that every marker is on the surface, has a unit outward normal
    /// (`p + εn` outside, `p − εn` inside) and a positive weight, and that the weights sum to
    /// the surface area to relative 1e-12.
    pub fn check_markers(shape: &dyn Shape, m: &[Marker], eps: f64) {
        assert!(!m.is_empty());
        for mk in m {
            assert!((mk.normal.norm() - 1.0).abs() < 1e-14, "normal not unit: {mk:?}");
            assert!(shape.signed_distance(&mk.position).abs() < 1e-12, "off the surface: {mk:?}");
            assert!(!shape.contains(&(mk.position + eps * mk.normal)), "p + εn inside: {mk:?}");
            assert!(shape.contains(&(mk.position - eps * mk.normal)), "p − εn outside: {mk:?}");
            assert!(mk.area > 0.0);
        }
        let total: f64 = m.iter().map(|mk| mk.area).sum();
        let rel = (total - shape.surface_area()).abs() / shape.surface_area();
        assert!(
            rel < 1e-12,
            "{}: marker areas sum to {total}, surface {}",
            shape.name(),
            shape.surface_area()
        );
    }
}
