//! # Torque-free rigid body: conservation, Dzhanibekov flip, free precession
//!
//! **Physics.** A free rigid body with no torque (Euler's equations
//! `I ω̇_b = −ω_b × I ω_b` in the body frame, orientation `q̇ = ½ q ⊗ (0, ω_b)`), integrated
//! with the scheme of `slurry::rigid::integrate` (explicit midpoint on the rotation group,
//! exact rotation quaternions, quaternion renormalised each step as `RigidBody::step` does).
//!
//! **Part A: asymmetric top**, `I = (1, 2, 3)`, three initial spins of unit size, each
//! perturbed by 0.05 off a principal axis: `near_minor` `ω_b = (1, 0.05, 0.05)` (axis of the
//! smallest moment), `near_intermediate` `(0.05, 1, 0.05)`, `near_major` `(0.05, 0.05, 1)`.
//! Final time `T = 100` (the intermediate-axis run flips several times: the linearised growth
//! rate is `ω √((I₂−I₁)(I₃−I₂)/(I₁I₃)) = 0.577`).
//! - Reference: kinetic energy `E = ½ ω_b · I ω_b` and world-frame angular momentum
//!   `L = q (I ω_b) q*` are invariants (physics.md §5). Near the intermediate axis the motion
//!   passes close to the separatrix and `ω₂` changes sign periodically (Dzhanibekov / tennis
//!   racket theorem); near the minor and major axes the motion is a stable precession and the
//!   component along that axis never changes sign.
//! - Metrics: `E_err = max_{t≤T} |E(t) − E(0)|/E(0)`, `L_err = max_{t≤T} |L(t) − L(0)|/|L(0)|`
//!   (and the same at `t = T`, printed), for `Δt = 0.02, 0.01, 0.005, 0.0025` (quick;
//!   `0.00125, 0.000625` added for full). Observed order: minus the least-squares slope of
//!   `log err` on `log Δt`. Sign changes of the body-frame `ω` component along the axis that
//!   the spin started near, at the finest `Δt`.
//! - Tolerances: order ≥ 1.8 for `E_err` and `L_err` in every run: the scheme is second order
//!   (local error `O(Δt³)`, module doc of `integrate`), so invariant errors at a fixed time
//!   are `O(Δt²)`; 1.8 allows for the coarsest step in the fit (`|ω|Δt = 0.02`); a first-order
//!   scheme (e.g. explicit Euler for ω, or the body torque not taken at the midpoint) gives ≈ 1
//!   and fails. The maximum over `t ≤ T` is used for the fit because the error at one instant
//!   can pass near zero (its sign oscillates with the precession), which would make a
//!   single-time error non-monotone in `Δt`. Flip counts: ≥ 2 sign changes of `ω₂` in the
//!   intermediate run, exactly 0 in the other two (a qualitative fact of the dynamics, no
//!   tolerance).
//!
//! **Part B: free precession of a symmetric top** with the proportions of the paper's ℓ/d = 2
//! cylinder: `I₁ = I₂ = (3d²/4 + ℓ²)/12 = 57`, `I₃ = d²/8 = 18` for `d = 12`, `ℓ = 24` (scaled by
//! `1/57`), `ω_b(0) = (0.3, 0, 1)`, `q(0) = 1`, `T = 50`.
//! - Reference (exact, e.g. Landau & Lifshitz, Mechanics §33): with `Ω = (I₃ − I₁) ω₃/I₁`,
//!   `ω_b(t) = (0.3 cos Ωt, 0.3 sin Ωt, ω₃)`, and
//!   `q(t) = exp(t L/I₁) ⊗ q(0) ⊗ exp(−Ω t e_z)` (rotation about the fixed `L` at the rate
//!   `|L|/I₁`, composed with a body rotation about the symmetry axis at `−Ω`).
//! - Metrics at `t = T`: orientation error (angle of `q_num⁻¹ q_exact`, radians) and
//!   `|ω_b − ω_b,exact|/|ω_b|`, same `Δt` as part A. Tolerance: order ≥ 1.8 for both (same
//!   reason: a second-order scheme; here the full state is compared, not only invariants).
//!
//! **Reference table.** The error tables are compared with
//! `verification/ref/torque_free-<tier>.ref` (relative 1e-9; the run is bitwise deterministic
//! on one machine). Caveat: the errors are differences of order-one quantities after up to
//! 1.6e5 steps, and the rotation quaternions call libm `sin`/`cos`; with a libm that differs in
//! the last bit the smallest errors here (≈ 1e-9 … 1e-7) would move by ≈ 1e-7 relative, and
//! the table has to be re-blessed on that platform. The single-instant errors `*_T` (the
//! smallest, and not used by any check) are printed but not compared.

use rayon::prelude::*;
use slurry::rigid::integrate::{angular_momentum_world, rotate, rotation_quaternion, rotational_energy};
use slurry::rigid::{Quat, Vec3};

use crate::{fit, CaseOutput, Check, Table, Tier};

const CASE: &str = "torque_free";

/// Time steps of the study.
pub fn time_steps(tier: Tier) -> Vec<f64> {
    match tier {
        Tier::Quick => vec![0.02, 0.01, 0.005, 0.0025],
        Tier::Full => vec![0.02, 0.01, 0.005, 0.0025, 0.00125, 0.000625],
    }
}

/// What one torque-free run measured.
#[derive(Clone, Copy, Debug)]
struct Run {
    e_max: f64,
    e_end: f64,
    l_max: f64,
    l_end: f64,
    sign_changes: usize,
    q: Quat,
    w: Vec3,
}

/// Integrates from `ω_b(0) = w0`, `q(0) = 1`, to `t_end` with step `dt`, counting the sign
/// changes of `ω_b[axis]`.
fn integrate(inertia: Vec3, w0: Vec3, t_end: f64, dt: f64, axis: usize) -> Run {
    let n = (t_end / dt).round() as usize;
    let zero = Vec3::zeros();
    let (mut q, mut w) = (Quat::identity(), w0);
    let e0 = rotational_energy(&inertia, &w);
    let l0 = angular_momentum_world(&q, &inertia, &w);
    let (mut e_max, mut l_max, mut e_err, mut l_err) = (0.0f64, 0.0f64, 0.0, 0.0);
    let mut sign_changes = 0;
    for _ in 0..n {
        let (q1, w1) = rotate(&q, &w, &inertia, &zero, &zero, dt);
        if w1[axis] * w[axis] < 0.0 {
            sign_changes += 1;
        }
        q = Quat::new_normalize(q1);
        w = w1;
        e_err = (rotational_energy(&inertia, &w) - e0).abs() / e0;
        l_err = (angular_momentum_world(&q, &inertia, &w) - l0).norm() / l0.norm();
        e_max = e_max.max(e_err);
        l_max = l_max.max(l_err);
    }
    Run { e_max, e_end: e_err, l_max, l_end: l_err, sign_changes, q, w }
}

/// Runs the case.
pub fn run(tier: Tier) -> CaseOutput {
    let mut out = CaseOutput { has_ref: true, ..Default::default() };
    let dts = time_steps(tier);

    // Part A: asymmetric top.
    let inertia = Vec3::new(1.0, 2.0, 3.0);
    let starts = [
        ("near_minor", Vec3::new(1.0, 0.05, 0.05), 0usize),
        ("near_intermediate", Vec3::new(0.05, 1.0, 0.05), 1),
        ("near_major", Vec3::new(0.05, 0.05, 1.0), 2),
    ];
    for (label, w0, axis) in starts {
        let runs: Vec<Run> = dts.par_iter().map(|&dt| integrate(inertia, w0, 100.0, dt, axis)).collect();
        let mut t = Table::new(
            format!("asymmetric I=(1,2,3) {label} w0=({},{},{}) T=100", w0.x, w0.y, w0.z),
            &[
                ("dt", true),
                ("E_err_max", true),
                ("L_err_max", true),
                ("E_err_T", false),
                ("L_err_T", false),
                ("sign_changes", true),
            ],
        );
        for (dt, r) in dts.iter().zip(&runs) {
            t.push(vec![*dt, r.e_max, r.l_max, r.e_end, r.l_end, r.sign_changes as f64]);
        }
        let e: Vec<f64> = runs.iter().map(|r| r.e_max).collect();
        let l: Vec<f64> = runs.iter().map(|r| r.l_max).collect();
        let inv_dt: Vec<f64> = dts.iter().map(|d| 1.0 / d).collect();
        let why = "second-order scheme (local error O(dt^3)): invariant errors at fixed time are \
                   O(dt^2); 1.8 allows for the coarsest dt in the fit, first order (≈ 1) fails";
        out.checks.push(Check::at_least(
            CASE,
            format!("{label}_energy_order"),
            fit::order(&inv_dt, &e),
            2.0,
            1.8,
            why,
        ));
        out.checks.push(Check::at_least(
            CASE,
            format!("{label}_angular_momentum_order"),
            fit::order(&inv_dt, &l),
            2.0,
            1.8,
            why,
        ));
        let flips = runs.last().expect("runs").sign_changes as f64;
        if axis == 1 {
            out.checks.push(Check::at_least(
                CASE,
                format!("{label}_w2_sign_changes"),
                flips,
                2.0,
                2.0,
                "Dzhanibekov: rotation near the intermediate axis is unstable and flips \
                 periodically (≈ every 20 time units here); at least two flips in T = 100",
            ));
        } else {
            out.checks.push(Check::exact(
                CASE,
                format!("{label}_w{}_sign_changes", axis + 1),
                flips,
                0.0,
                "rotation near the minor or major axis is a stable precession: the component \
                 along that axis keeps its sign",
            ));
        }
        out.tables.push(t);
    }

    // Part B: symmetric top (the ℓ/d = 2 cylinder's proportions) against the exact solution.
    let inertia = Vec3::new(1.0, 1.0, 18.0 / 57.0);
    let w0 = Vec3::new(0.3, 0.0, 1.0);
    let t_end = 50.0;
    let big_omega = (inertia.z - inertia.x) / inertia.x * w0.z;
    let l_world = inertia.component_mul(&w0); // q(0) = 1
    let q_exact = rotation_quaternion(&(l_world * (t_end / inertia.x)))
        * rotation_quaternion(&Vec3::new(0.0, 0.0, -big_omega * t_end));
    let (s, c) = (big_omega * t_end).sin_cos();
    let w_exact = Vec3::new(w0.x * c, w0.x * s, w0.z);
    let runs: Vec<Run> = dts.par_iter().map(|&dt| integrate(inertia, w0, t_end, dt, 2)).collect();
    let mut t = Table::new(
        "symmetric I=(1,1,18/57) w0=(0.3,0,1) T=50 vs exact precession",
        &[("dt", true), ("orientation_err", true), ("omega_err", true), ("E_err_max", true)],
    );
    let mut qe = Vec::new();
    let mut we = Vec::new();
    for (dt, r) in dts.iter().zip(&runs) {
        let a = r.q.angle_to(&q_exact);
        let b = (r.w - w_exact).norm() / w_exact.norm();
        qe.push(a);
        we.push(b);
        t.push(vec![*dt, a, b, r.e_max]);
    }
    let inv_dt: Vec<f64> = dts.iter().map(|d| 1.0 / d).collect();
    let why = "second-order scheme: the state (orientation, body angular velocity) at a fixed \
               time has an O(dt^2) error; 1.8 allows for the coarsest dt in the fit";
    out.checks.push(Check::at_least(
        CASE,
        "precession_orientation_order",
        fit::order(&inv_dt, &qe),
        2.0,
        1.8,
        why,
    ));
    out.checks.push(Check::at_least(CASE, "precession_omega_order", fit::order(&inv_dt, &we), 2.0, 1.8, why));
    out.tables.push(t);
    out
}
