//! Rigid bodies: shapes, mass properties, surface markers, and the time integration of
//! translation and rotation. This module knows nothing of the fluid: loads come in through a
//! body's force and torque accumulators, whoever computes them (immersed boundary, contacts,
//! gravity); only `coupling` will put the two sides together.
//!
//! - [`shape`]: the [`Shape`] trait (volume, principal moments, inside test, signed distance,
//!   surface markers with outward normals and area weights) and [`Marker`];
//! - [`sphere`], [`cylinder`]: the shapes of the first target (Derksen 2020: cylinders of
//!   diameter `d` and length `ℓ`, spheres for the drag calibration); [`cuboid`] (blades);
//! - [`impeller`]: the disk and the pitched-blade turbine on a shaft, a union of parts, and
//!   their prescribed rotation with a start-up ramp;
//! - [`body`]: [`RigidBody`] (state, [`Motion`] kind, load accumulators, frame transforms,
//!   marker positions and velocities, net weight);
//! - [`integrate`]: the second-order, norm-preserving update (loads extrapolated to the half
//!   step; Euler's equations in the body frame with the gyroscopic term; exact rotation
//!   quaternions, after Zhao & van Wachem 2013).
//!
//! **Frames and conventions.** The body frame has its origin at the centre of mass and its
//! axes along the principal axes of inertia. The orientation `q` is a unit quaternion that
//! maps body-frame vectors to world-frame vectors (`v_world = q v_body q*`). Positions,
//! velocities, angular velocity, forces and torques in [`RigidBody`] are world-frame
//! quantities; torques are about the centre of mass. Lattice units throughout.
//!
//! The linear-algebra types are nalgebra's, in `f64`; they are re-exported here so that users
//! of the crate do not need their own nalgebra dependency.

pub mod body;
pub mod cuboid;
pub mod cylinder;
pub mod impeller;
pub mod integrate;
pub mod shape;
pub mod sphere;

pub use body::{ConstantMotion, Motion, PrescribedMotion, RigidBody};
pub use cuboid::Cuboid;
pub use cylinder::Cylinder;
pub use impeller::{Impeller, ImpellerGeometry, ImpellerKind, Pumping, RampedRotation};
pub use integrate::LoadScheme;
pub use shape::{Marker, MassProperties, RetractionError, Shape, DEFAULT_MARKER_SPACING};
pub use sphere::Sphere;

/// Three-vector (`nalgebra::Vector3<f64>`).
pub type Vec3 = nalgebra::Vector3<f64>;
/// Unit quaternion (`nalgebra::UnitQuaternion<f64>`): an orientation, body → world.
pub type Quat = nalgebra::UnitQuaternion<f64>;
/// 3 × 3 matrix (`nalgebra::Matrix3<f64>`).
pub type Mat3 = nalgebra::Matrix3<f64>;

pub use nalgebra;
