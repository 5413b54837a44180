//! Time integration of a free rigid body: second order in time, exactly norm-preserving for
//! the orientation quaternion (up to round-off), explicit, no allocation.
//!
//! # Time levels of the loads
//!
//! A step from `tⁿ` to `tⁿ⁺¹ = tⁿ + Δt` receives the force `Fⁿ` and torque `Tⁿ` (world
//! frame, torque about the centre of mass) *evaluated at time level n*, i.e. with the body
//! state at `tⁿ` (that is what the coupling can compute before it moves the body). A
//! second-order update needs the loads at the half step; they are extrapolated
//! ([`LoadScheme::AdamsBashforth2`], the default) from this step's and the previous step's
//! loads:
//!
//! ```text
//! F^{n+½} = Fⁿ + (r/2)(Fⁿ − F^{n−1}),   r = Δtₙ / Δtₙ₋₁     (the same for T)
//! ```
//!
//! (for `r = 1`: `(3Fⁿ − F^{n−1})/2`). On the first step of a body, or after
//! [`super::RigidBody::reset_load_history`], there is no `F^{n−1}` and `F^{n+½} = Fⁿ` is used:
//! one step with a local error `O(Δt²)`, which does not reduce the global order.
//! [`LoadScheme::Constant`] always uses `F^{n+½} = Fⁿ` (first order for loads that vary in
//! time, second order for constant loads such as the net weight; larger stability region if
//! the loads depend stiffly on the state).
//!
//! # Translation
//!
//! ```text
//! v^{n+1} = vⁿ + Δt F^{n+½}/m
//! x^{n+1} = xⁿ + (Δt/2)(vⁿ + v^{n+1})      (= xⁿ + Δt vⁿ + (Δt²/2) F^{n+½}/m)
//! ```
//!
//! Local error `O(Δt³)` in both: second order.
//!
//! # Rotation
//!
//! State: orientation `qⁿ` (body → world) and the **body-frame** angular velocity `ω_bⁿ`.
//! Euler's equations in the body frame, with the principal moments `I = diag(I₁, I₂, I₃)` and
//! the gyroscopic term:
//!
//! ```text
//! I ω̇_b = T_b − ω_b × (I ω_b),     T_b = q* T q     (world torque seen in the body frame)
//! q̇ = ½ q ⊗ (0, ω_b)
//! ```
//!
//! Write `α(q, ω_b, T) = I⁻¹(q* T q − ω_b × I ω_b)` and `exp(θ) = (cos(|θ|/2), sin(|θ|/2) θ/|θ|)`
//! for the **exact rotation quaternion** of the rotation vector `θ` (a unit quaternion by
//! construction, so no normalisation error of order `Δt^k` ever enters). One step
//! ([`rotate`]), a predictor–corrector (the explicit midpoint rule on the rotation group):
//!
//! ```text
//! 1. predictor:  ω_b^{n+½} = ω_bⁿ + (Δt/2) α(qⁿ, ω_bⁿ, Tⁿ)
//!                q^{n+½}   = qⁿ ⊗ exp((Δt/2) ω_bⁿ)
//! 2. corrector:  ω_b^{n+1} = ω_bⁿ + Δt α(q^{n+½}, ω_b^{n+½}, T^{n+½})
//!                q^{n+1}   = qⁿ ⊗ exp(Δt ω_b^{n+½})
//! ```
//!
//! **Order.** The predictor is accurate to `O(Δt²)`, so `α` at the midpoint is accurate to
//! `O(Δt²)` and `ω_b^{n+1}` has a local error `O(Δt³)`. For the orientation, the exact
//! solution over the step is `qⁿ ⊗ exp(Ω)` with the Magnus expansion
//! `Ω = ∫ω_b dt + ½∫∫[ω_b(t₁), ω_b(t₂)] + …`; the first term equals `Δt ω_b(t^{n+½}) + O(Δt³)`
//! (midpoint rule) and the commutator term is `O(Δt³)` (its integrand is antisymmetric in
//! `t₁ − t₂ = O(Δt)`), so `exp(Δt ω_b^{n+½})` is accurate to `O(Δt³)` per step: the scheme is
//! second order globally (the verification case `torque_free` fits ≈ 2 for energy, angular
//! momentum and orientation). The world-frame torque at the half step is `T^{n+½}` from the
//! extrapolation above; at the predictor, `Tⁿ`.
//!
//! **Norm.** `q^{n+1}` is a product of two unit quaternions, so `|q^{n+1}| = 1` up to the
//! rounding of one quaternion product (a few 1e-16); [`super::RigidBody::step`] renormalises
//! after each step so that these do not random-walk (the verification case `quaternion_norm`
//! measures both the raw and the renormalised drift over 10⁶ steps).
//!
//! **Reference.** The scheme follows Zhao & van Wachem (2013), "A novel quaternion integration
//! approach for describing the behaviour of non-spherical particles", Acta Mech. 224:3091: a
//! predictor–corrector for Euler's equations in the body frame with the orientation advanced
//! by exact rotation quaternions (not by integrating `q̇` and renormalising). It differs in one
//! respect: Zhao & van Wachem stagger the angular velocity at half steps (leapfrog); here `ω`
//! lives at the same time levels as `q` and `x`, because the immersed boundary method needs the
//! marker velocities at the time of the marker positions.
//!
//! **Torque-free motion.** With `T = 0` neither kinetic energy nor angular momentum is
//! conserved exactly by this explicit scheme; their errors at a fixed time are `O(Δt²)` (the
//! verification fits the order), and over very long runs they drift (slowly: the explicit
//! midpoint rule amplifies the undamped oscillation about a stable principal axis by
//! `1 + O((ωΔt)⁴)` per step). At lattice time steps a particle turns by `|ω|Δt ≲ 1e-3` rad per
//! step.

use super::{Quat, Vec3};

/// How the loads at the half step are obtained from those at the step (module doc).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum LoadScheme {
    /// `F^{n+½} = Fⁿ + (r/2)(Fⁿ − F^{n−1})`, `r = Δtₙ/Δtₙ₋₁`: second order (default).
    #[default]
    AdamsBashforth2,
    /// `F^{n+½} = Fⁿ`: second order for constant loads, first order for time-varying ones.
    Constant,
}

/// The loads of the previous step, kept for the extrapolation of [`LoadScheme::AdamsBashforth2`].
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct LoadHistory {
    /// `(F^{n−1}, T^{n−1}, Δtₙ₋₁)`, or `None` before the first step.
    pub previous: Option<(Vec3, Vec3, f64)>,
}

impl LoadHistory {
    /// The loads at the half step, `(F^{n+½}, T^{n+½})`, from `(Fⁿ, Tⁿ)` and the history, and
    /// records `(Fⁿ, Tⁿ, Δt)` as the new history.
    pub fn half_step(&mut self, scheme: LoadScheme, force: Vec3, torque: Vec3, dt: f64) -> (Vec3, Vec3) {
        let half = match (scheme, self.previous) {
            (LoadScheme::AdamsBashforth2, Some((f0, t0, dt0))) => {
                let c = 0.5 * dt / dt0;
                (force + (force - f0) * c, torque + (torque - t0) * c)
            }
            _ => (force, torque),
        };
        self.previous = Some((force, torque, dt));
        half
    }
}

/// The body-frame angular acceleration of Euler's equations,
/// `α = I⁻¹ (T_b − ω_b × (I ω_b))`, with `I` the principal moments and everything in the body
/// frame.
#[inline]
pub fn angular_acceleration(inertia: &Vec3, omega_b: &Vec3, torque_b: &Vec3) -> Vec3 {
    let l = inertia.component_mul(omega_b);
    (torque_b - omega_b.cross(&l)).component_div(inertia)
}

/// The exact rotation quaternion of the rotation vector `theta`: a rotation by `|θ|` about
/// `θ/|θ|` (identity for `θ = 0`), `(cos(|θ|/2), sin(|θ|/2) θ/|θ|)`.
#[inline]
pub fn rotation_quaternion(theta: &Vec3) -> Quat {
    Quat::from_scaled_axis(*theta)
}

/// One translation step (module doc): returns `(x^{n+1}, v^{n+1})` from `xⁿ`, `vⁿ`, the
/// half-step force `F^{n+½}` and the mass.
#[inline]
pub fn translate(x: &Vec3, v: &Vec3, force_half: &Vec3, mass: f64, dt: f64) -> (Vec3, Vec3) {
    let v1 = v + force_half * (dt / mass);
    (x + (v + v1) * (0.5 * dt), v1)
}

/// One rotation step (module doc): returns `(q^{n+1}, ω_b^{n+1})`, **without** renormalising
/// `q^{n+1}` (its norm differs from 1 by the rounding of one quaternion product; callers that
/// keep it over many steps renormalise, as [`super::RigidBody::step`] does).
///
/// `q` is the orientation at `tⁿ`, `omega_b` the body-frame angular velocity at `tⁿ`,
/// `inertia` the principal moments, `torque` and `torque_half` the world-frame torques at `tⁿ`
/// and `t^{n+½}` (about the centre of mass).
#[inline]
pub fn rotate(
    q: &Quat,
    omega_b: &Vec3,
    inertia: &Vec3,
    torque: &Vec3,
    torque_half: &Vec3,
    dt: f64,
) -> (nalgebra::Quaternion<f64>, Vec3) {
    // 1. Predictor.
    let a0 = angular_acceleration(inertia, omega_b, &q.inverse_transform_vector(torque));
    let w_half = omega_b + a0 * (0.5 * dt);
    let q_half = q * rotation_quaternion(&(omega_b * (0.5 * dt)));
    // 2. Corrector.
    let a_half = angular_acceleration(inertia, &w_half, &q_half.inverse_transform_vector(torque_half));
    let w1 = omega_b + a_half * dt;
    let q1 = q.quaternion() * rotation_quaternion(&(w_half * dt)).quaternion();
    (q1, w1)
}

/// Kinetic energy of rotation `½ ω_b · I ω_b` (body frame).
#[inline]
pub fn rotational_energy(inertia: &Vec3, omega_b: &Vec3) -> f64 {
    0.5 * omega_b.dot(&inertia.component_mul(omega_b))
}

/// World-frame angular momentum `q (I ω_b) q*`.
#[inline]
pub fn angular_momentum_world(q: &Quat, inertia: &Vec3, omega_b: &Vec3) -> Vec3 {
    q.transform_vector(&inertia.component_mul(omega_b))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn constant_load_translation_is_exact() {
        // Constant force: x = x0 + v0 t + F t²/(2m) exactly (the scheme's local error vanishes).
        let f = Vec3::new(0.0, 0.0, -2.0);
        let mut h = LoadHistory::default();
        let (mut x, mut v) = (Vec3::new(1.0, 0.0, 0.0), Vec3::new(0.0, 0.5, 1.0));
        for _ in 0..100 {
            let (fh, _) = h.half_step(LoadScheme::AdamsBashforth2, f, Vec3::zeros(), 0.01);
            (x, v) = translate(&x, &v, &fh, 4.0, 0.01);
        }
        let t = 1.0;
        let ex = Vec3::new(1.0, 0.5 * t, t - 0.25 * t * t);
        assert!((x - ex).norm() < 1e-13, "{x:?} vs {ex:?}");
        assert!((v - Vec3::new(0.0, 0.5, 1.0 - 0.5 * t)).norm() < 1e-13);
    }

    #[test]
    fn harmonic_oscillator_is_second_order() {
        // m ẍ = −k x with the force evaluated at time level n and AB2-extrapolated.
        let err = |n: usize| {
            let dt = 1.0 / n as f64;
            let mut h = LoadHistory::default();
            let (mut x, mut v) = (Vec3::new(1.0, 0.0, 0.0), Vec3::zeros());
            for _ in 0..n {
                let (fh, _) = h.half_step(LoadScheme::AdamsBashforth2, -x, Vec3::zeros(), dt);
                (x, v) = translate(&x, &v, &fh, 1.0, dt);
            }
            (x.x - 1f64.cos()).abs() + (v.x + 1f64.sin()).abs()
        };
        let p = (err(100) / err(200)).log2();
        assert!((p - 2.0).abs() < 0.1, "order {p}");
    }

    #[test]
    fn constant_spin_about_a_principal_axis_is_exact() {
        let inertia = Vec3::new(1.0, 2.0, 3.0);
        let w = Vec3::new(0.0, 0.0, 0.7);
        let mut q = Quat::identity();
        let mut wb = w;
        for _ in 0..1000 {
            let (q1, w1) = rotate(&q, &wb, &inertia, &Vec3::zeros(), &Vec3::zeros(), 0.01);
            q = Quat::new_normalize(q1);
            wb = w1;
        }
        assert_eq!(wb, w);
        assert!(q.angle_to(&Quat::from_scaled_axis(w * 10.0)) < 1e-12);
    }

    #[test]
    fn constant_torque_on_a_sphere_is_exact_in_omega() {
        // Isotropic inertia: no gyroscopic term, ω̇ = T/I exactly; T along a fixed world axis
        // and ω parallel to it, so the body-frame torque seen at the predicted orientation is
        // still along ω.
        let inertia = Vec3::repeat(2.0);
        let t = Vec3::new(0.0, 0.0, 1.0);
        let (mut q, mut wb) = (Quat::identity(), Vec3::zeros());
        for _ in 0..100 {
            let (q1, w1) = rotate(&q, &wb, &inertia, &t, &t, 0.01);
            (q, wb) = (Quat::new_normalize(q1), w1);
        }
        assert!((wb.z - 0.5).abs() < 1e-14);
        // Angle ½ (T/I) t² = 0.25 (midpoint rule exact for linear ω).
        assert!((q.angle() - 0.25).abs() < 1e-13, "{}", q.angle());
    }
}
