//! # Quaternion norm: 10⁶ torque-free steps
//!
//! **Physics.** A free asymmetric rigid body, principal moments `I = (1, 2, 3)`, no torque,
//! initial body-frame angular velocity `ω_b = (0.3, 1.0, 0.2)` (near the intermediate axis:
//! the body tumbles, so the update quaternions point in every direction), time step
//! `Δt = 0.01` (turns of ≈ 0.01 rad per step, ten times more than a particle at lattice time
//! steps), 10⁶ steps. A second run through the production path, [`RigidBody::step`], for a
//! free cylinder `d = 12`, `ℓ = 24` spinning off-axis.
//!
//! **Reference.** The orientation is a unit quaternion; the update
//! `q^{n+1} = qⁿ ⊗ exp(Δt ω_b^{n+½})` multiplies by an exact rotation quaternion (module
//! `slurry::rigid::integrate`), so in exact arithmetic `|q| = 1` for ever.
//!
//! **Metric.** `max_n ||qⁿ| − 1|` over the 10⁶ steps, for (a) the raw scheme, never
//! renormalised (what the scheme itself does to the norm: only the rounding of one quaternion
//! product per step, ≈ 1e-16, accumulating as a random walk to ≈ 1e-16 · √10⁶ = 1e-13);
//! (b) the scheme with the renormalisation after each step that `RigidBody::step` applies;
//! (c) `RigidBody::step` itself.
//!
//! **Tolerance.** 1e-12 for all three (the bound). Why it separates right from wrong:
//! an update that integrates `q̇ = ½ q ⊗ (0, ω)` with any explicit Runge–Kutta method without
//! renormalising drifts by `O(Δt^{p+1})` per step, i.e. ≥ 1e-6 × 10⁶ steps here; a
//! first-order rotation-vector update with `(1, θ/2)` not normalised drifts by `θ²/8 ≈ 1e-5`
//! per step. Only a norm-preserving update stays at the round-off level.

use std::sync::Arc;
use std::time::Instant;

use slurry::rigid::integrate::rotate;
use slurry::rigid::{Cylinder, Motion, Quat, RigidBody, Vec3};

use crate::{CaseOutput, Check, Table, Tier};

const CASE: &str = "quaternion_norm";
const STEPS: usize = 1_000_000;
const DT: f64 = 0.01;

/// Largest `||q| − 1|` over `STEPS` torque-free steps of the bare scheme, renormalised after
/// each step or not.
fn bare(renormalise: bool) -> f64 {
    let inertia = Vec3::new(1.0, 2.0, 3.0);
    let zero = Vec3::zeros();
    let mut q = Quat::identity();
    let mut w = Vec3::new(0.3, 1.0, 0.2);
    let mut worst = 0.0f64;
    for _ in 0..STEPS {
        let (q1, w1) = rotate(&q, &w, &inertia, &zero, &zero, DT);
        worst = worst.max((q1.norm() - 1.0).abs());
        q = if renormalise { Quat::new_normalize(q1) } else { Quat::new_unchecked(q1) };
        w = w1;
    }
    worst.max((q.norm() - 1.0).abs())
}

/// The same through `RigidBody::step` (a free cylinder).
fn body() -> f64 {
    let mut b = RigidBody::new(Arc::new(Cylinder::new(12.0, 24.0)), 1.25, Motion::Free)
        .with_velocities(Vec3::zeros(), Vec3::new(0.3, -0.1, 1.0));
    let mut worst = 0.0f64;
    for _ in 0..STEPS {
        b.step(DT);
        worst = worst.max((b.orientation.norm() - 1.0).abs());
    }
    worst
}

/// Runs the case (the same at both tiers: 10⁶ steps take a fraction of a second).
pub fn run(_tier: Tier) -> CaseOutput {
    let mut out = CaseOutput::default();
    let mut t = Table::new(
        "max ||q| - 1| over 1e6 steps (variant: 0 = raw, 1 = renormalised, 2 = RigidBody::step)",
        &[("variant", false), ("max_norm_drift", false), ("seconds", false)],
    );
    let reason_raw = "norm-preserving update (product with an exact rotation quaternion): only \
                      round-off, a random walk of ≈ 1e-16 per step (≈ 1e-13 after 1e6 steps); a \
                      non-preserving update drifts by ≥ 1e-6 here";
    let reason_norm = "renormalised after each step: deviation of one rounding (≈ 1e-16)";
    for (k, (label, f)) in
        [("raw", (|| bare(false)) as fn() -> f64), ("renormalised", || bare(true)), ("rigid_body_step", body)]
            .into_iter()
            .enumerate()
    {
        let t0 = Instant::now();
        let d = f();
        t.push(vec![k as f64, d, t0.elapsed().as_secs_f64()]);
        let reason = if k == 0 { reason_raw } else { reason_norm };
        out.checks.push(Check::at_most(CASE, format!("{label}_max_norm_drift"), d, 1e-12, reason));
    }
    out.tables.push(t);
    out
}
