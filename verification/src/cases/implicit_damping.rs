//! # Implicit damping: backward Euler on Table 1's lubrication against the converged explicit scheme
//!
//! **What.** `[contacts] damping = "implicit"` (`slurry::contact`, module doc, "Implicit
//! damping"): per contact sub-step the lubrication of the mid-sub-step evaluation is integrated
//! by backward Euler (one sparse symmetric positive-definite solve over the free bodies'
//! `(v, ω)`), the spring explicitly (position Verlet) as before. No fluid.
//!
//! **Approach under a constant force.** A sphere of diameter `d` (`γ = 1.25`; quick tier
//! `d = 6`, full tier `d = 12`) starts with its surface `1.2` above the floor (outside
//! `δ_d = 1`), moving down at `0.02`, and is pushed down by a constant force `F = 0.01 (d/6)³`
//! (every marker's lubrication, then the spring, stop it; it comes to rest on the spring near
//! `δ0`). Recorded after every fluid step for `T = 60` steps: the gap `z − d/2` and the
//! vertical velocity. **Reference**: the explicit scheme at `n_sub = 64`; its own error is
//! estimated from 16, 32, 64 sub-steps by Richardson extrapolation (`slurry::util::richardson3`)
//! of the gap at the step where the reference comes closest to the floor. **Metric**: per
//! `n_sub`, `gap_err = max_t |gap − gap_ref|` (lattice units) and
//! `vel_err = max_t |v − v_ref| / max_t |v_ref|`, for the implicit scheme at `n_sub = 1, 2, 4, 8`
//! (and, for comparison, the explicit one). The observed order is the least-squares slope of
//! `log err` against `log n_sub` over 1 … 8.
//!
//! **Checks (metric, tolerance, why).**
//! - `reference_order`: the Richardson order of the explicit reference from 16, 32, 64 is
//!   `≥ 0.8` (first order expected: explicit Euler damping): the reference is in its asymptotic
//!   range, so its error estimate means something.
//! - `reference_error_over_implicit_8`: the reference's estimated error (`|gap_64 − gap_∞|`)
//!   over the implicit scheme's `gap_err` at `n_sub = 8` `≤ 0.2`: the implicit errors measured
//!   are the implicit scheme's, not the reference's.
//! - `implicit_gap_order`, `implicit_velocity_order`: the fitted orders `≥ 0.9`: backward
//!   Euler is first order; the spring's Verlet step is second order; so the scheme is first
//!   order, and 0.9 leaves room for the kinks where marker pairs switch on (at `δ_d` and `δ0`).
//! - `implicit_limit_equals_explicit`: `max_t |gap_imp,64 − gap_exp,64|` over the reference's
//!   error estimate `|gap_32 − gap_64|`, `≤ 2`: both schemes converge to the same solution
//!   (both first order, errors of opposite sign at most double the difference).
//!
//! **Stability at the stiffest damping (saturated contacts).** Two coaxial cylinders `ℓ = d = 6`
//! cap on cap with aligned markers (the stiffest single contact, module doc of
//! `slurry::contact`) and a disk `d = 6, ℓ = 2` cap down on the floor (`ℓ/d = 1/3`, the
//! paper's disks), `0.1` apart (inside `δ_sat`: constant coefficient `c`), elastic part off,
//! relative normal velocity `1e-10` (`contacts_dry`'s saturated set-up). Per sub-step explicit
//! Euler multiplies the relative velocity by `1 − b`, backward Euler by `1/(1 + b)`,
//! `b = c h/m_red`. `saturated_implicit_amplification`: `|g/g_pred − 1|` with
//! `g_pred = (1 + c h/m_red)^{−n_sub}` after one fluid step, `n_sub = 1, 2, 4`, `≤ 1e-6`: the
//! solve is backward Euler exactly (the residual is the rim–cap cross pairs' coefficients,
//! which move with the gap by `O(u0)`, and a weak coupling of the normal motion to rotation
//! through the marker layout, which the 6 × 6 solve includes and the scalar prediction does not).
//! `saturated_explicit_unstable_n1`: the explicit `|g|` at `n_sub = 1` `> 1` for both contacts
//! (`b = 10.7` and `19`): explicit Euler cannot take these in one step.
//! `saturated_implicit_stable_n1`: the implicit `g` at `n_sub = 1` in `(0, 1)` for both: stable
//! and monotone whatever `b`.
//!
//! **Collisions** (`contacts_dry`'s set-ups at `d = 6`, every speed of the tier, lubrication on)
//! under the implicit scheme at `IMPLICIT_SUBSTEPS`: `momentum_conservation` `≤ 1e-13` (each
//! pair still applies `+F`/`−F`: the pair's damping loads on its two bodies come from the same
//! blocks, so the momentum changes by round-off only), `dissipation_lubricated` `≥ 0`
//! (backward Euler on a positive semi-definite damping dissipates), and the restitution and
//! closest approach against the explicit default, reported (table "largest change": per scheme and
//! `n_sub`, the largest change of restitution and closest approach against explicit 8 sub-steps
//! over every collision; `ended_otherwise` counts runs that ended differently, separated in one
//! and still in contact at the step limit in the other, whose restitution is not compared:
//! `sphere_oblique` at 0.05 separates in step 443–460 of 460 under the implicit scheme, one step
//! later than the limit under the explicit one).

use slurry::contact::{ContactParams, Contacts, Damping, Walls, DEFAULT_SUBSTEPS, IMPLICIT_SUBSTEPS};
use slurry::rigid::{Marker, Motion, RigidBody, Shape, Sphere, Vec3, DEFAULT_MARKER_SPACING};
use std::sync::Arc;

use super::contacts_dry::{collide, saturated_scheme, speeds, Setup};
use crate::{fit, CaseOutput, Check, Table, Tier};

const CASE: &str = "implicit_damping";
/// Density ratio of the paper's particles.
const GAMMA: f64 = 1.25;
/// Fluid steps of the approach.
const STEPS: usize = 60;

fn params(damping: Damping) -> ContactParams {
    ContactParams { damping, ..Default::default() }
}

/// The approach of a sphere of diameter `d` to the floor (module doc): gap and vertical
/// velocity after every fluid step.
fn approach(d: f64, damping: Damping, n_sub: usize) -> (Vec<f64>, Vec<f64>) {
    let shape: Arc<dyn Shape> = Arc::new(Sphere::new(d));
    let markers: Vec<Vec<Marker>> = vec![shape.markers(DEFAULT_MARKER_SPACING)];
    let mut bodies = vec![RigidBody::new(shape, GAMMA, Motion::Free)
        .with_position(Vec3::new(0.0, 0.0, 0.5 * d + 1.2))
        .with_velocities(Vec3::new(0.0, 0.0, -0.02), Vec3::zeros())];
    let walls = Walls { planes: [[None, None], [None, None], [Some(0.0), None]] };
    let mut ct = Contacts::new(params(damping), walls, &bodies, &markers).expect("valid parameters");
    let force = Vec3::new(0.0, 0.0, -0.01 * (d / 6.0).powi(3));
    let (mut gap, mut vel) = (Vec::with_capacity(STEPS), Vec::with_capacity(STEPS));
    for _ in 0..STEPS {
        slurry::contact::step_bodies(Some(&mut ct), &mut bodies, &markers, n_sub, |_, _| {
            (force, Vec3::zeros())
        });
        gap.push(bodies[0].position.z - 0.5 * d);
        vel.push(bodies[0].velocity.z);
    }
    (gap, vel)
}

fn max_abs_diff(a: &[f64], b: &[f64]) -> f64 {
    a.iter().zip(b).map(|(x, y)| (x - y).abs()).fold(0.0, f64::max)
}

/// Runs the case.
pub fn run(tier: Tier) -> CaseOutput {
    let mut out = CaseOutput { has_ref: true, ..Default::default() };
    let d = match tier {
        Tier::Quick => 6.0,
        Tier::Full => 12.0,
    };
    // The reference and its convergence.
    let refs: Vec<(Vec<f64>, Vec<f64>)> =
        [16, 32, 64].iter().map(|&n| approach(d, Damping::Explicit, n)).collect();
    let k_min = (0..STEPS).min_by(|&a, &b| refs[2].0[a].total_cmp(&refs[2].0[b])).unwrap_or(0);
    let g = [refs[0].0[k_min], refs[1].0[k_min], refs[2].0[k_min]];
    let (p_ref, g_inf) =
        fit::richardson3([1.0 / 16.0, 1.0 / 32.0, 1.0 / 64.0], g).unwrap_or((f64::NAN, f64::NAN));
    // Richardson-extrapolated histories from (32, 64) and, for its error, from (16, 32).
    let extrapolate = |coarse: &[f64], fine: &[f64]| -> Vec<f64> {
        let f = 1.0 / (2f64.powf(p_ref) - 1.0);
        coarse.iter().zip(fine).map(|(c, x)| x + (x - c) * f).collect()
    };
    let (gap_ref, vel_ref) = (extrapolate(&refs[1].0, &refs[2].0), extrapolate(&refs[1].1, &refs[2].1));
    let ref_err = max_abs_diff(&gap_ref, &extrapolate(&refs[0].0, &refs[1].0));
    let vmax = vel_ref.iter().map(|v| v.abs()).fold(0.0, f64::max);
    let mut t = Table::new(
        format!("approach d={d}"),
        &[("implicit", true), ("n_sub", true), ("gap_err", true), ("vel_err", true), ("min_gap", true)],
    );
    let mut imp = Vec::new();
    for (flag, damping) in [(0.0, Damping::Explicit), (1.0, Damping::Implicit)] {
        for n in [1usize, 2, 4, 8, 16, 32, 64] {
            let (gp, v) = if damping == Damping::Explicit && n >= 16 {
                refs[n.trailing_zeros() as usize - 4].clone()
            } else {
                approach(d, damping, n)
            };
            let ge = max_abs_diff(&gp, &gap_ref);
            let ve = max_abs_diff(&v, &vel_ref) / vmax;
            let min_gap = gp.iter().copied().fold(f64::INFINITY, f64::min);
            t.push(vec![flag, n as f64, ge, ve, min_gap]);
            if damping == Damping::Implicit {
                imp.push((n, ge, ve, gp));
            }
        }
    }
    out.tables.push(t);
    let mut r = Table::new(
        "reference convergence (explicit, gap at the closest step)",
        &[
            ("step", true),
            ("gap16", true),
            ("gap32", true),
            ("gap64", true),
            ("order", true),
            ("gap_inf", true),
            ("ref_err", true),
        ],
    );
    r.push(vec![(k_min + 1) as f64, g[0], g[1], g[2], p_ref, g_inf, ref_err]);
    out.tables.push(r);
    out.checks.push(Check::at_least(
        CASE,
        "reference_order",
        p_ref,
        1.0,
        0.8,
        "explicit Euler damping is first order: the reference from 16, 32, 64 sub-steps is in its asymptotic range",
    ));
    let first: Vec<_> = imp.iter().filter(|e| e.0 <= 8).collect();
    let imp8 = first.iter().find(|e| e.0 == 8).map_or(f64::NAN, |e| e.1);
    out.checks.push(Check::at_most(
        CASE,
        "reference_error_over_implicit_8",
        ref_err / imp8,
        0.05,
        "the extrapolated reference's own error (from 16-32 against 32-64) is small against the implicit errors measured",
    ));
    let ns: Vec<f64> = first.iter().map(|e| e.0 as f64).collect();
    let ge: Vec<f64> = first.iter().map(|e| e.1).collect();
    let ve: Vec<f64> = first.iter().map(|e| e.2).collect();
    out.checks.push(Check::at_least(
        CASE,
        "implicit_gap_order",
        fit::order(&ns, &ge),
        1.0,
        0.9,
        "backward Euler damping and Verlet spring: first order; 0.9 for the kinks where marker pairs switch on",
    ));
    out.checks.push(Check::at_least(
        CASE,
        "implicit_velocity_order",
        fit::order(&ns, &ve),
        1.0,
        0.9,
        "backward Euler damping and Verlet spring: first order; 0.9 for the kinks where marker pairs switch on",
    ));
    let i32_ = imp.iter().find(|e| e.0 == 32).map(|e| e.3.clone()).unwrap_or_default();
    let i64_ = imp.iter().find(|e| e.0 == 64).map(|e| e.3.clone()).unwrap_or_default();
    out.checks.push(Check::at_most(
        CASE,
        "implicit_limit_equals_explicit",
        max_abs_diff(&extrapolate(&i32_, &i64_), &gap_ref) / imp8,
        0.05,
        "both schemes converge to one solution: their extrapolations from 32 and 64 sub-steps agree far below \
         the implicit error at 8",
    ));

    // Saturated contacts: stability at the stiffest damping.
    let mut s = Table::new(
        "saturated contacts (elastic off, gap 0.1)",
        &[
            ("setup", true),
            ("n_sub", true),
            ("b", true),
            ("g_explicit", true),
            ("g_implicit", true),
            ("g_pred", true),
        ],
    );
    let (mut dev, mut unstable, mut stable, mut predicted) =
        (0.0f64, f64::INFINITY, f64::NEG_INFINITY, f64::INFINITY);
    for (k, (setup, length)) in [(Setup::CylinderEnd, 6.0), (Setup::WallFlat, 2.0)].into_iter().enumerate() {
        for n in [1usize, 2, 4] {
            let (c, m_red, g_exp) = saturated_scheme(setup, 6.0, length, n, params(Damping::Explicit));
            let (_, _, g_imp) = saturated_scheme(setup, 6.0, length, n, params(Damping::Implicit));
            let b = c / (m_red * n as f64);
            let g_pred = (1.0 + b).powi(-(n as i32));
            dev = dev.max((g_imp / g_pred - 1.0).abs());
            if n == 1 {
                unstable = unstable.min(g_exp.abs());
                predicted = predicted.min((1.0 - b).abs());
                stable = stable.max(if g_imp > 0.0 { g_imp } else { f64::INFINITY });
            }
            s.push(vec![k as f64, n as f64, b, g_exp, g_imp, g_pred]);
        }
    }
    out.tables.push(s);
    out.checks.push(Check::at_most(
        CASE,
        "saturated_implicit_amplification",
        dev,
        1e-6,
        "backward Euler multiplies the relative velocity by 1/(1 + c h/m_red) per sub-step; the residual is the \
         unsaturated rim pairs (O(u0)) and the rotation the 6 x 6 solve couples in",
    ));
    out.checks.push(Check::at_least(
        CASE,
        "saturated_explicit_unstable_n1",
        unstable,
        predicted,
        1.0,
        "explicit Euler at b = c h/m_red > 2 amplifies: these contacts need several sub-steps explicitly",
    ));
    out.checks.push(Check::at_most(
        CASE,
        "saturated_implicit_stable_n1",
        stable,
        1.0 - 1e-6,
        "backward Euler: 0 < 1/(1 + b) < 1 for any b > 0 (stable and monotone in one step)",
    ));

    // Collisions under the implicit scheme, and how far they move with its sub-steps.
    let mut c = Table::new(
        format!("collisions d=6, implicit, n_sub={IMPLICIT_SUBSTEPS}"),
        &[
            ("setup", true),
            ("speed", true),
            ("restitution", true),
            ("e_explicit", true),
            ("closest", true),
            ("closest_explicit", true),
            ("momentum_err", false),
        ],
    );
    let mut dev = Table::new(
        "collisions d=6: largest change against the explicit default (8 sub-steps)",
        &[
            ("implicit", true),
            ("n_sub", true),
            ("restitution_change", true),
            ("closest_change", true),
            ("ended_otherwise", true),
        ],
    );
    let jobs: Vec<(Setup, f64)> =
        Setup::ALL.into_iter().flat_map(|s| speeds(tier).into_iter().map(move |v| (s, v))).collect();
    let explicit: Vec<_> =
        jobs.iter().map(|&(s, v)| collide(s, 6.0, v, params(Damping::Explicit), DEFAULT_SUBSTEPS)).collect();
    let (mut mom, mut loss) = (0.0f64, f64::INFINITY);
    for (damping, n) in [
        (Damping::Explicit, 4),
        (Damping::Explicit, 16),
        (Damping::Explicit, 32),
        (Damping::Implicit, 1),
        (Damping::Implicit, 2),
        (Damping::Implicit, 4),
        (Damping::Implicit, 8),
        (Damping::Implicit, 32),
    ] {
        let (mut de, mut dc, mut unlike) = (0.0f64, 0.0f64, 0usize);
        for (&(setup, speed), e) in jobs.iter().zip(&explicit) {
            let o = collide(setup, 6.0, speed, params(damping), n);
            // A run that ends at its step limit still in contact has no restitution (0): compare
            // only runs that ended the same way (both separated, or both stuck).
            if o.separated == e.separated {
                de = de.max((o.restitution - e.restitution).abs());
            } else {
                unlike += 1;
            }
            dc = dc.max((o.closest - e.closest).abs());
            if damping == Damping::Implicit {
                mom = mom.max(o.momentum_err);
                loss = loss.min(-o.ke_change);
            }
            if damping == Damping::Implicit && n == IMPLICIT_SUBSTEPS {
                let k = Setup::ALL.iter().position(|&s| s == setup).unwrap_or(0);
                c.push(vec![
                    k as f64,
                    speed,
                    o.restitution,
                    e.restitution,
                    o.closest,
                    e.closest,
                    o.momentum_err,
                ]);
            }
        }
        dev.push(vec![if damping == Damping::Implicit { 1.0 } else { 0.0 }, n as f64, de, dc, unlike as f64]);
    }
    out.tables.push(c);
    out.tables.push(dev);
    out.checks.push(Check::at_most(
        CASE,
        "momentum_conservation",
        mom,
        1e-13,
        "each pair applies +F and -F from the same blocks: momentum changes by round-off only",
    ));
    out.checks.push(Check::at_least(
        CASE,
        "dissipation_lubricated",
        loss,
        0.0,
        0.0,
        "backward Euler on a positive semi-definite damping never adds energy",
    ));
    out
}
