//! A rigid body: shape, mass properties, kinematic state, motion kind and load accumulators.

use std::sync::Arc;

use super::integrate::{self, LoadHistory, LoadScheme};
use super::shape::{Marker, MassProperties, Shape};
use super::{Mat3, Quat, Vec3};

/// A motion imposed on a body, as functions of time (world frame; angular velocity about the
/// centre of mass). Impellers implement it ([`super::impeller::RampedRotation`]).
pub trait PrescribedMotion: Send + Sync + std::fmt::Debug {
    /// Velocity of the centre of mass at time `t`.
    fn velocity(&self, t: f64) -> Vec3;

    /// Angular velocity (world frame) at time `t`.
    fn angular_velocity(&self, t: f64) -> Vec3;

    /// The displacement from `t` to `t + dt`: translation of the centre of mass and rotation
    /// (world frame, applied on the left: `q(t + dt) = rotation ⊗ q(t)`).
    ///
    /// The default uses the midpoint velocities, `(dt · v(t + dt/2), exp(dt · ω(t + dt/2)))`:
    /// exact for velocities linear in time about a fixed axis (a linear ramp), second order in
    /// general. Implementations with a closed form override it.
    fn displacement(&self, t: f64, dt: f64) -> (Vec3, Quat) {
        let t_mid = t + 0.5 * dt;
        (self.velocity(t_mid) * dt, integrate::rotation_quaternion(&(self.angular_velocity(t_mid) * dt)))
    }
}

/// Constant velocity and angular velocity: integrated exactly (a rotation about a fixed axis
/// through the centre of mass at a constant rate, composed with a uniform translation).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ConstantMotion {
    /// Velocity of the centre of mass.
    pub velocity: Vec3,
    /// Angular velocity (world frame).
    pub angular_velocity: Vec3,
}

impl PrescribedMotion for ConstantMotion {
    fn velocity(&self, _t: f64) -> Vec3 {
        self.velocity
    }

    fn angular_velocity(&self, _t: f64) -> Vec3 {
        self.angular_velocity
    }

    fn displacement(&self, _t: f64, dt: f64) -> (Vec3, Quat) {
        (self.velocity * dt, integrate::rotation_quaternion(&(self.angular_velocity * dt)))
    }
}

/// How a body moves.
#[derive(Clone, Debug)]
pub enum Motion {
    /// Does not move; velocity and angular velocity are zero; loads are accumulated (so they
    /// can be read, e.g. the drag on a fixed sphere) and discarded by [`RigidBody::step`].
    Fixed,
    /// Follows a prescribed motion exactly; loads are accumulated and discarded.
    Prescribed(Arc<dyn PrescribedMotion>),
    /// Moves under its loads (module [`super::integrate`]).
    Free,
}

impl Motion {
    /// A prescribed constant velocity and angular velocity (world frame).
    pub fn constant(velocity: Vec3, angular_velocity: Vec3) -> Self {
        Motion::Prescribed(Arc::new(ConstantMotion { velocity, angular_velocity }))
    }
}

/// A rigid body.
///
/// State at time [`RigidBody::time`]: position of the centre of mass, orientation (body →
/// world), velocity and angular velocity (world frame). Loads (force, torque about the centre
/// of mass, world frame) are accumulated during a step with [`RigidBody::add_force`],
/// [`RigidBody::add_force_at`] and [`RigidBody::add_torque`] and consumed by
/// [`RigidBody::step`] (see there). The net weight is *not* added automatically: the caller adds
/// [`RigidBody::net_weight`] like any other load.
#[derive(Clone, Debug)]
pub struct RigidBody {
    shape: Arc<dyn Shape>,
    density: f64,
    mass_properties: MassProperties,
    motion: Motion,
    /// Position of the centre of mass.
    pub position: Vec3,
    /// Orientation: maps body-frame vectors to world-frame vectors.
    pub orientation: Quat,
    /// Velocity of the centre of mass.
    pub velocity: Vec3,
    /// Angular velocity, world frame.
    pub angular_velocity: Vec3,
    /// Time of the state.
    pub time: f64,
    /// How the half-step loads are obtained (free bodies).
    pub load_scheme: LoadScheme,
    force: Vec3,
    torque: Vec3,
    history: LoadHistory,
}

impl RigidBody {
    /// A body of `shape` with density `density` (mass properties from the shape), at the
    /// origin with identity orientation, at time 0. Velocities: zero for free and fixed bodies,
    /// the prescribed ones at `t = 0` for prescribed bodies.
    ///
    /// # Panics
    /// If the density is not positive and finite.
    pub fn new(shape: Arc<dyn Shape>, density: f64, motion: Motion) -> Self {
        assert!(density.is_finite() && density > 0.0, "body density must be positive, got {density}");
        let mass_properties = shape.mass_properties(density);
        let mut b = Self {
            shape,
            density,
            mass_properties,
            motion,
            position: Vec3::zeros(),
            orientation: Quat::identity(),
            velocity: Vec3::zeros(),
            angular_velocity: Vec3::zeros(),
            time: 0.0,
            load_scheme: LoadScheme::default(),
            force: Vec3::zeros(),
            torque: Vec3::zeros(),
            history: LoadHistory::default(),
        };
        b.sync_motion();
        b
    }

    /// Sets the position (builder).
    pub fn with_position(mut self, position: Vec3) -> Self {
        self.position = position;
        self
    }

    /// Sets the orientation (builder).
    pub fn with_orientation(mut self, orientation: Quat) -> Self {
        self.orientation = orientation;
        self
    }

    /// Sets the velocity and angular velocity (world frame) of a free body (builder; fixed and
    /// prescribed bodies keep theirs).
    pub fn with_velocities(mut self, velocity: Vec3, angular_velocity: Vec3) -> Self {
        if matches!(self.motion, Motion::Free) {
            self.velocity = velocity;
            self.angular_velocity = angular_velocity;
        }
        self
    }

    /// Sets the time (builder); prescribed velocities are re-evaluated at it.
    pub fn with_time(mut self, time: f64) -> Self {
        self.time = time;
        self.sync_motion();
        self
    }

    /// Velocities of fixed and prescribed bodies at the current time.
    fn sync_motion(&mut self) {
        match &self.motion {
            Motion::Fixed => {
                self.velocity = Vec3::zeros();
                self.angular_velocity = Vec3::zeros();
            }
            Motion::Prescribed(m) => {
                self.velocity = m.velocity(self.time);
                self.angular_velocity = m.angular_velocity(self.time);
            }
            Motion::Free => {}
        }
    }

    /// The shape.
    pub fn shape(&self) -> &Arc<dyn Shape> {
        &self.shape
    }

    /// Density `ρ_p`.
    pub fn density(&self) -> f64 {
        self.density
    }

    /// Mass and principal moments.
    pub fn mass_properties(&self) -> &MassProperties {
        &self.mass_properties
    }

    /// Mass `m`.
    pub fn mass(&self) -> f64 {
        self.mass_properties.mass
    }

    /// The motion kind.
    pub fn motion(&self) -> &Motion {
        &self.motion
    }

    /// Whether the body moves under its loads.
    pub fn is_free(&self) -> bool {
        matches!(self.motion, Motion::Free)
    }

    /// Net weight (gravity and buoyancy), `(ρ_p − ρ_f) V g`, acting at the centre of mass.
    pub fn net_weight(&self, gravity: Vec3, fluid_density: f64) -> Vec3 {
        gravity * ((self.density - fluid_density) * self.shape.volume())
    }

    // ---- loads ----

    /// Adds a force acting at the centre of mass.
    #[inline]
    pub fn add_force(&mut self, f: Vec3) {
        self.force += f;
    }

    /// Adds a force `f` acting at the world point `point`: the force, and the torque
    /// `(point − x) × f` about the centre of mass.
    #[inline]
    pub fn add_force_at(&mut self, point: Vec3, f: Vec3) {
        self.force += f;
        self.torque += (point - self.position).cross(&f);
    }

    /// Adds a torque (world frame, about the centre of mass).
    #[inline]
    pub fn add_torque(&mut self, t: Vec3) {
        self.torque += t;
    }

    /// The force accumulated since the last step.
    pub fn force(&self) -> Vec3 {
        self.force
    }

    /// The torque accumulated since the last step.
    pub fn torque(&self) -> Vec3 {
        self.torque
    }

    /// Sets the accumulated force and torque to zero.
    pub fn clear_accumulators(&mut self) {
        self.force = Vec3::zeros();
        self.torque = Vec3::zeros();
    }

    /// Forgets the previous step's loads, so that the next step uses `F^{n+½} = Fⁿ` (after a
    /// discontinuity of the loads, e.g. when an impeller is switched on).
    pub fn reset_load_history(&mut self) {
        self.history = LoadHistory::default();
    }

    // ---- time integration ----

    /// Advances the body from `time` to `time + dt`, **consuming the accumulators**: they hold
    /// the loads at the current time level (`Fⁿ`, `Tⁿ`, evaluated with the current state), are
    /// used (free bodies; module [`super::integrate`]) and then cleared, so that the next step
    /// starts from zero. Fixed bodies stay where they are; prescribed bodies are moved by their
    /// [`PrescribedMotion::displacement`] and take its velocities at the new time; free bodies
    /// integrate translation and rotation to second order and renormalise the quaternion. No
    /// allocation.
    pub fn step(&mut self, dt: f64) {
        match &self.motion {
            Motion::Fixed => {}
            Motion::Prescribed(m) => {
                let (dx, dq) = m.displacement(self.time, dt);
                self.position += dx;
                self.orientation = Quat::new_normalize((dq * self.orientation).into_inner());
            }
            Motion::Free => {
                let (f_half, t_half) = self.history.half_step(self.load_scheme, self.force, self.torque, dt);
                let (x1, v1) = integrate::translate(
                    &self.position,
                    &self.velocity,
                    &f_half,
                    self.mass_properties.mass,
                    dt,
                );
                let omega_b = self.orientation.inverse_transform_vector(&self.angular_velocity);
                let (q1, w1) = integrate::rotate(
                    &self.orientation,
                    &omega_b,
                    &self.mass_properties.principal_moments,
                    &self.torque,
                    &t_half,
                    dt,
                );
                self.position = x1;
                self.velocity = v1;
                self.orientation = Quat::new_normalize(q1);
                self.angular_velocity = self.orientation.transform_vector(&w1);
            }
        }
        self.time += dt;
        self.sync_motion();
        self.clear_accumulators();
    }

    // ---- frames and kinematics ----

    /// Rotation matrix of the orientation (body → world).
    pub fn rotation_matrix(&self) -> Mat3 {
        self.orientation.to_rotation_matrix().into_inner()
    }

    /// World position of the body-frame point `p`.
    #[inline]
    pub fn to_world(&self, p: &Vec3) -> Vec3 {
        self.position + self.orientation.transform_vector(p)
    }

    /// Body-frame position of the world point `p`.
    #[inline]
    pub fn to_body(&self, p: &Vec3) -> Vec3 {
        self.orientation.inverse_transform_vector(&(p - self.position))
    }

    /// World-frame components of the body-frame vector `v` (a direction, not a point).
    #[inline]
    pub fn vector_to_world(&self, v: &Vec3) -> Vec3 {
        self.orientation.transform_vector(v)
    }

    /// Body-frame components of the world-frame vector `v`.
    #[inline]
    pub fn vector_to_body(&self, v: &Vec3) -> Vec3 {
        self.orientation.inverse_transform_vector(v)
    }

    /// Angular velocity in the body frame.
    pub fn angular_velocity_body(&self) -> Vec3 {
        self.vector_to_body(&self.angular_velocity)
    }

    /// Velocity of the body at the world point `p` (rigid motion: `v + ω × (p − x)`).
    #[inline]
    pub fn point_velocity(&self, p: &Vec3) -> Vec3 {
        self.velocity + self.angular_velocity.cross(&(p - self.position))
    }

    /// Whether the world point `p` is inside the body.
    pub fn contains(&self, p: &Vec3) -> bool {
        self.shape.contains(&self.to_body(p))
    }

    /// Signed distance of the world point `p` to the body's surface (negative inside).
    pub fn signed_distance(&self, p: &Vec3) -> f64 {
        self.shape.signed_distance(&self.to_body(p))
    }

    /// World position, outward unit normal and velocity `v + ω × r` of a marker (given in the
    /// body frame).
    #[inline]
    pub fn marker_world(&self, m: &Marker) -> (Vec3, Vec3, Vec3) {
        let r = self.orientation.transform_vector(&m.position);
        let n = self.orientation.transform_vector(&m.normal);
        (self.position + r, n, self.velocity + self.angular_velocity.cross(&r))
    }

    /// Principal moments rotated to the world frame: `R diag(I) Rᵀ`.
    pub fn inertia_world(&self) -> Mat3 {
        let r = self.rotation_matrix();
        r * Mat3::from_diagonal(&self.mass_properties.principal_moments) * r.transpose()
    }

    /// Linear momentum `m v`.
    pub fn linear_momentum(&self) -> Vec3 {
        self.velocity * self.mass_properties.mass
    }

    /// Angular momentum about the centre of mass, world frame: `R I Rᵀ ω`.
    pub fn angular_momentum(&self) -> Vec3 {
        integrate::angular_momentum_world(
            &self.orientation,
            &self.mass_properties.principal_moments,
            &self.angular_velocity_body(),
        )
    }

    /// Kinetic energy `½ m v² + ½ ω · I ω`.
    pub fn kinetic_energy(&self) -> f64 {
        0.5 * self.mass_properties.mass * self.velocity.norm_squared()
            + integrate::rotational_energy(
                &self.mass_properties.principal_moments,
                &self.angular_velocity_body(),
            )
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::rigid::{Cylinder, Shape, Sphere};

    fn cylinder() -> Arc<dyn Shape> {
        Arc::new(Cylinder::new(12.0, 24.0))
    }

    #[test]
    fn net_weight_is_excess_density_times_volume_times_g() {
        let b = RigidBody::new(cylinder(), 1.25, Motion::Free);
        let g = Vec3::new(0.0, 0.0, -4e-5);
        let w = b.net_weight(g, 1.0);
        let v = std::f64::consts::PI * 36.0 * 24.0;
        assert!((w.z + 0.25 * v * 4e-5).abs() < 1e-15 * v);
        assert_eq!(w.x, 0.0);
    }

    #[test]
    fn force_at_a_point_gives_the_torque() {
        let mut b = RigidBody::new(cylinder(), 1.0, Motion::Free).with_position(Vec3::new(1.0, 2.0, 3.0));
        b.add_force_at(Vec3::new(2.0, 2.0, 3.0), Vec3::new(0.0, 1.0, 0.0));
        b.add_torque(Vec3::new(0.0, 0.0, 0.5));
        assert_eq!(b.force(), Vec3::new(0.0, 1.0, 0.0));
        assert_eq!(b.torque(), Vec3::new(0.0, 0.0, 1.5));
        b.step(1.0);
        assert_eq!(b.force(), Vec3::zeros());
        assert_eq!(b.torque(), Vec3::zeros());
    }

    #[test]
    fn frames_round_trip_and_marker_velocity() {
        let q = Quat::from_scaled_axis(Vec3::new(0.3, -0.2, 0.9));
        let b = RigidBody::new(cylinder(), 1.0, Motion::Free)
            .with_position(Vec3::new(5.0, 6.0, 7.0))
            .with_orientation(q)
            .with_velocities(Vec3::new(0.01, 0.0, 0.0), Vec3::new(0.0, 0.0, 0.002));
        let p = Vec3::new(1.0, -2.0, 0.5);
        assert!((b.to_body(&b.to_world(&p)) - p).norm() < 1e-14);
        // The axis (body z) in the world.
        assert!((b.vector_to_world(&Vec3::z()) - q * Vec3::z()).norm() < 1e-15);
        let m = b.shape().markers(0.7);
        for mk in &m {
            let (x, n, v) = b.marker_world(mk);
            assert!(b.signed_distance(&x).abs() < 1e-12);
            assert!((n.norm() - 1.0).abs() < 1e-14);
            assert!((v - b.point_velocity(&x)).norm() < 1e-16);
        }
        // Inertia tensor: world angular momentum equals I_world ω.
        let l = b.inertia_world() * b.angular_velocity;
        assert!((l - b.angular_momentum()).norm() < 1e-12 * l.norm());
    }

    #[test]
    fn fixed_body_does_not_move() {
        let mut b = RigidBody::new(Arc::new(Sphere::new(4.0)), 2.0, Motion::Fixed)
            .with_velocities(Vec3::new(1.0, 0.0, 0.0), Vec3::new(0.0, 1.0, 0.0));
        b.add_force(Vec3::new(0.0, 0.0, -1.0));
        for _ in 0..10 {
            b.step(1.0);
        }
        assert_eq!(b.position, Vec3::zeros());
        assert_eq!(b.orientation, Quat::identity());
        assert_eq!(b.velocity, Vec3::zeros());
        assert_eq!(b.time, 10.0);
    }

    #[test]
    fn constant_prescribed_motion_is_exact() {
        let v = Vec3::new(0.01, 0.0, -0.02);
        let w = Vec3::new(0.0, 0.0, std::f64::consts::TAU / 4000.0);
        let mut b =
            RigidBody::new(cylinder(), 1.0, Motion::constant(v, w)).with_position(Vec3::new(1.0, 1.0, 1.0));
        for _ in 0..4000 {
            b.add_force(Vec3::new(1.0, 1.0, 1.0)); // ignored
            b.step(1.0);
        }
        // Round-off of 4000 additions to a position of size 80: ≲ 4000 · 1.4e-14.
        assert!((b.position - (Vec3::new(1.0, 1.0, 1.0) + v * 4000.0)).norm() < 1e-10);
        // One full revolution.
        assert!(b.orientation.angle_to(&Quat::identity()) < 1e-11, "{}", b.orientation);
        assert_eq!(b.velocity, v);
        assert_eq!(b.angular_velocity, w);
    }

    #[derive(Debug)]
    struct Ramp;
    impl PrescribedMotion for Ramp {
        fn velocity(&self, _t: f64) -> Vec3 {
            Vec3::zeros()
        }
        fn angular_velocity(&self, t: f64) -> Vec3 {
            Vec3::new(0.0, 0.0, 1e-3 * t.min(100.0))
        }
    }

    #[test]
    fn ramped_rotation_uses_the_midpoint_rule() {
        // ω = 1e-3 t about z for t < 100: angle = 5e-4 t², exact with the default midpoint
        // displacement when the ramp end falls on a step boundary.
        let mut b = RigidBody::new(cylinder(), 1.0, Motion::Prescribed(Arc::new(Ramp)));
        for _ in 0..100 {
            b.step(1.0);
        }
        let exact = Quat::from_axis_angle(&Vec3::z_axis(), 5.0);
        assert!(b.orientation.angle_to(&exact) < 1e-12, "{} vs {exact}", b.orientation);
        assert_eq!(b.angular_velocity.z, 0.1);
    }

    #[test]
    fn falling_free_body_under_net_weight() {
        // Constant load: translation exact; no torque, no rotation.
        let g = Vec3::new(0.0, 0.0, -4e-5);
        let mut b = RigidBody::new(cylinder(), 1.25, Motion::Free);
        for _ in 0..1000 {
            let w = b.net_weight(g, 1.0);
            b.add_force(w);
            b.step(1.0);
        }
        let a = 0.2 * g; // (ρ_p − ρ_f)/ρ_p g
        assert!((b.velocity - a * 1000.0).norm() < 1e-15);
        assert!((b.position - a * 5e5).norm() < 1e-12);
        assert_eq!(b.angular_velocity, Vec3::zeros());
    }

    #[test]
    fn free_symmetric_top_conserves_energy_to_second_order() {
        // A cylinder (I₁ = I₂ ≠ I₃) spinning off-axis: torque-free precession, via the
        // production path (world ω stored, quaternion renormalised each step).
        let run = |n: usize| {
            let mut b = RigidBody::new(cylinder(), 1.0, Motion::Free)
                .with_velocities(Vec3::zeros(), Vec3::new(0.05, 0.0, 0.1));
            let (e0, l0) = (b.kinetic_energy(), b.angular_momentum());
            let dt = 200.0 / n as f64;
            for _ in 0..n {
                b.step(dt);
            }
            ((b.kinetic_energy() - e0).abs() / e0, (b.angular_momentum() - l0).norm() / l0.norm())
        };
        let (e1, l1) = run(1000);
        let (e2, l2) = run(2000);
        let (pe, pl) = ((e1 / e2).log2(), (l1 / l2).log2());
        assert!(pe > 1.8 && pl > 1.8, "orders {pe}, {pl} (errors {e1:e} {e2:e}, {l1:e} {l2:e})");
    }
}
