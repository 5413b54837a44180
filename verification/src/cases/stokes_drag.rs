//! # Stokes drag of a simple-cubic periodic array of fixed spheres (IBM coupling)
//!
//! **Physics.** One sphere of diameter `d` (input diameter, markers at spacing 0.7, Roma
//! 3-point kernel, one forcing iteration) fixed at the centre of a fully periodic box of edge `L = 4d`
//! (`d/L = 0.25`, solids fraction `π/384 ≈ 0.0082`), i.e. a simple-cubic array. The fluid
//! (f64, TRT with `Λ = 3/16`, `ν = 1/6`: with the magic parameter the wall position of the
//! lattice scheme does not depend on the viscosity, so the result measures the IBM and not a
//! `τ`-dependent offset) is driven by a uniform body force density `G` along x, starts at rest
//! and is run to steady state: every `W = ⌈L³/(6πνaK)⌉` steps (the relaxation time of the mean flow,
//! `dU/dt = G − 6πνaK U/L³`: the slowest mode, observed e-folding ≈ 900 steps at `d = 6`) the relative change of the mean
//! velocity over those `W` steps must fall below 1e-9. The coupling is
//! `slurry::coupling::Coupled` (direct forcing, force field cleared each step).
//!
//! **Reference.** `K = F/(6π μ a U) = 1.530` for `d/L = 0.25` (Zick & Homsy 1982; physics.md
//! §5), with `μ = ρν` (`ρ = 1`), `a = d/2` the *input* radius, `F` the drag on one sphere and
//! `U` the superficial velocity: the mean of the fluid velocity `u = (j + F/2)/ρ` over **all**
//! nodes of the box (nodes inside the sphere included). Particle Reynolds number
//! `Re = U d/ν = 0.05` (`G` is set from the reference `K` so that `U ≈ 0.05 ν/d`; the
//! measured `Re` is in the table): Stokes flow to `O(Re)`.
//!
//! **The calibrated immersed boundary** (issue 13). The forcing markers are retracted into
//! the sphere by the default `coupling::DEFAULT_RETRACTION` = 0.36, fitted on *this* array
//! (`examples/calibrate_retraction.rs`, data in `ref/retraction_calibration.csv`): the
//! uncalibrated boundary's hydrodynamic radius (the radius whose exact drag, by Sangani &
//! Acrivos's series for the simple-cubic array, equals the measured one) is `a + 0.391,
//! 0.377, 0.351, 0.334, 0.315` at `d = 6, 8, 12, 16, 24` (drag errors 21, 15, 9.1, 6.4,
//! 4.0 %); the least-squares retraction over `d = 8–24` (weights `1/a²`: relative errors) is
//! 0.361 from those runs and 0.364 from runs at 0.36 (the excess grows by about 0.002 with
//! the retraction), rounded to 0.36. Residual drag errors at 0.36: `+1.6, +0.80, −0.13,
//! −0.43 %` at `d = 6, 8, 12, 16` and `−0.53 %` at 24 (CSV; `d = 4` is in the table below).
//!
//! **Metrics.**
//! - Calibrated (`r_d = 0.36`, one forcing iteration): `K` and `K/1.530 − 1` per `d`, run to
//!   a steady state of 1e-9 (above).
//! - Force balance: at steady state the momentum of the fluid is constant, so the IBM force on
//!   the sphere equals the total body force, `F_x = G L³` (spreading is a partition of unity on
//!   a periodic box, so `Σ_nodes S F = Σ_m F_m`). `|F_x/(G L³) − 1|`, worst over `d`.
//! - Uncalibrated (`r_d = 0`): `K`, its error and the hydrodynamic radius's excess per `d`,
//!   from the Aitken-extrapolated steady state ([`solve_extrapolated`]: it agrees with the
//!   1e-9 steady state to 4e-8 at `d = 6, 8`, in a sixth of the steps); observed order =
//!   minus the least-squares slope of `log error` on `log d`.
//! - Forcing iterations (uncalibrated): `K_it = 1` and `3` compared in a third table.
//!
//! **Tolerances and why.**
//! - Calibrated `|K/1.530 − 1| ≤ 1.5 %` at each `d ≥ 8` (the calibrated range): the fit leaves
//!   at most 1 % there; the margin covers the rounding of the fitted 0.361–0.364 to 0.36. A
//!   retraction off by 0.06 (or none: 15 % at `d = 8`) fails.
//! - Calibrated `≤ 4 %` at `d = 4` and `6`, below the calibrated range, where the excess grows
//!   (0.39 at `d = 6`; measured 1.6 % at `d = 6`, the `d = 4` value in the table).
//! - Uncalibrated order ≥ 0.7: with a fixed input radius the diffuse interface of the IBM
//!   makes the effective radius `a + O(1)` lattice units, so the error of `K` falls at first
//!   order in `1/d` (physics.md §3 and §5). A fit over `d = 4 … 8` (16 in the full tier) may
//!   be pre-asymptotic; 0.7 leaves room for that while a non-converging coupling (order ≈ 0)
//!   fails.
//! - Force balance ≤ 1e-6: the steady-state criterion (1e-9 relative over an e-folding time)
//!   leaves a momentum imbalance `W · dU/dt ∝ 1e-9`, far below; a wrong marker volume or a
//!   force spread but not counted (or counted twice) would show at O(1).
//! - Forcing iterations: the default is 1 (see the report of issue 3 for the comparison); more
//!   iterations thicken the boundary further, and the calibrated retraction is for 1.

use std::sync::Arc;

use rayon::prelude::*;
use slurry::coupling::{Coupled, CouplingParams, DEFAULT_RETRACTION};
use slurry::lattice::Grid;
use slurry::lbm::{Boundaries, Fluid, FluidParams};
use slurry::rigid::{Motion, RigidBody, Sphere, Vec3};

use crate::{fit, CaseOutput, Check, Table, Tier};

const CASE: &str = "stokes_drag";
/// Zick & Homsy 1982, `d/L = 0.25`.
pub const K_REF: f64 = 1.530;
const NU: f64 = 1.0 / 6.0;
const RE: f64 = 0.05;
/// Steady-state criterion of [`solve`]: relative change of the mean velocity over one relaxation time.
pub const STEADY: f64 = 1e-9;

/// Resolutions (sphere diameters) of the study.
pub fn resolutions(tier: Tier) -> Vec<usize> {
    match tier {
        Tier::Quick => vec![4, 6, 8],
        Tier::Full => vec![4, 6, 8, 12],
    }
}

/// The dimensionless drag of a simple-cubic array of spheres at solids fraction `c`, by the
/// series of Sangani & Acrivos (1982, Int. J. Multiphase Flow 8, 343) for the simple-cubic
/// array: `K = 1/(1 − 1.7601 c^{1/3} + c − 1.5593 c² + 3.9799 c^{8/3} − 3.0734 c^{10/3})`. It
/// reproduces the Zick & Homsy values of physics.md §5 to 0.1 % up to `c = 0.125` (unit
/// test), and gives 1.531 at this case's `c = π/384`.
pub fn k_sangani_acrivos(c: f64) -> f64 {
    let x = c.cbrt();
    1.0 / (1.0 - 1.7601 * x + c - 1.5593 * c * c + 3.9799 * x.powi(8) - 3.0734 * x.powi(10))
}

/// The **hydrodynamic radius** `a_h` of a sphere in a simple-cubic array of period `L` whose
/// measured drag is `K_meas` in units of `6π μ a U` (`a` the input radius): the radius of the
/// sphere whose exact drag ([`k_sangani_acrivos`] at solids fraction `4π a_h³/(3L³)`) is the
/// measured one, `a_h K(c(a_h)) = a K_meas` (bisection; the left side increases with `a_h`).
pub fn hydrodynamic_radius(k_meas: f64, a: f64, l: f64) -> f64 {
    let target = a * k_meas;
    let f =
        |r: f64| r * k_sangani_acrivos(4.0 * std::f64::consts::PI * r.powi(3) / (3.0 * l.powi(3))) - target;
    let (mut lo, mut hi) = (0.5 * a, 1.5 * a);
    assert!(f(lo) < 0.0 && f(hi) > 0.0, "hydrodynamic radius outside [a/2, 3a/2]");
    for _ in 0..200 {
        let mid = 0.5 * (lo + hi);
        if f(mid) < 0.0 {
            lo = mid;
        } else {
            hi = mid;
        }
    }
    0.5 * (lo + hi)
}

/// One steady solution of the array.
pub struct Row {
    /// Sphere diameter (input), lattice units.
    pub d: usize,
    /// Time steps run.
    pub steps: u64,
    /// Relative change of the mean velocity over the last relaxation time.
    pub rel_change: f64,
    /// Superficial velocity `U` (mean over all nodes).
    pub u: f64,
    /// `K = F/(6π μ a U)` with the input radius `a = d/2`.
    pub k: f64,
    /// `|F_x/(G L³) − 1|`.
    pub balance: f64,
    /// Wall-clock seconds.
    pub seconds: f64,
}

fn mean_u(c: &Coupled<f64>) -> f64 {
    let (_, u) = c.fluid().fields();
    u.iter().map(|v| v[0]).sum::<f64>() / u.len() as f64
}

/// The array at diameter `d` (box `4d`), body force `G` and relaxation time `W` (even).
fn setup(d: usize, iterations: usize, retraction: f64) -> (Coupled<f64>, f64, u64) {
    let l = 4 * d;
    let a = d as f64 / 2.0;
    let u_target = RE * NU / d as f64;
    let g = K_REF * 6.0 * std::f64::consts::PI * NU * a * u_target / (l * l * l) as f64;
    let mut fluid = Fluid::<f64>::new(
        Grid::new(l, l, l),
        FluidParams::trt(NU).with_body_force([g, 0.0, 0.0]),
        Boundaries::periodic(),
    )
    .expect("valid Stokes-drag set-up");
    fluid.initialize(|_, _, _| (1.0, [0.0; 3]));
    let c = l as f64 / 2.0;
    let body =
        RigidBody::new(Arc::new(Sphere::new(d as f64)), 1.0, Motion::Fixed).with_position(Vec3::new(c, c, c));
    let cp = Coupled::new(fluid, vec![body], CouplingParams { iterations, retraction, ..Default::default() })
        .expect("fixed body");
    // Relaxation time of the mean flow, U' = G − F/L³ with F = 6πνaK U: L³/(6πνaK) (this,
    // not the diffusive L²/(4π²ν), is the slowest mode: observed e-folding ≈ 900 steps at d = 6).
    let w = ((l * l * l) as f64 / (6.0 * std::f64::consts::PI * NU * a * K_REF)).ceil() as u64;
    (cp, g, w + w % 2)
}

/// The steady array at diameter `d` with `iterations` forcing iterations and the forcing
/// markers retracted by `retraction`, run until the mean velocity changes by less than
/// [`STEADY`] (relative) over one relaxation time `W` of the mean flow (at most `40 W`).
pub fn solve(d: usize, iterations: usize, retraction: f64) -> Row {
    let t0 = std::time::Instant::now();
    let l = 4 * d;
    let a = d as f64 / 2.0;
    let (mut cp, g, w) = setup(d, iterations, retraction);
    let max_steps = 40 * w;
    let mut prev = mean_u(&cp);
    let mut steps = 0;
    let (u, rel) = loop {
        cp.run(w).expect("stencils");
        steps += w;
        let now = mean_u(&cp);
        let rel = ((now - prev) / now).abs();
        if rel < STEADY || steps >= max_steps || !rel.is_finite() {
            break (now, rel);
        }
        prev = now;
    };
    let f = cp.hydrodynamic_force(0).x;
    let total = g * (l * l * l) as f64;
    Row {
        d,
        steps,
        rel_change: rel,
        u,
        k: f / (6.0 * std::f64::consts::PI * NU * a * u),
        balance: (f / total - 1.0).abs(),
        seconds: t0.elapsed().as_secs_f64(),
    }
}

fn table(title: String, rows: &[Row]) -> Table {
    let mut t = Table::new(
        title,
        &[
            ("d", true),
            ("L", true),
            ("steps", false),
            ("rel_change", false),
            ("U", true),
            ("Re", false),
            ("K", true),
            ("rel_error", true),
            ("force_balance", false),
            ("seconds", false),
        ],
    );
    for r in rows {
        t.push(vec![
            r.d as f64,
            (4 * r.d) as f64,
            r.steps as f64,
            r.rel_change,
            r.u,
            r.u * r.d as f64 / NU,
            r.k,
            (r.k / K_REF - 1.0).abs(),
            r.balance,
            r.seconds,
        ]);
    }
    t
}

/// The result of [`solve_extrapolated`].
#[derive(Clone, Copy, Debug)]
pub struct Extrapolated {
    /// `K = G L³/(6π μ a U_∞)`.
    pub k: f64,
    /// The extrapolated superficial velocity `U_∞`.
    pub u: f64,
    /// Time steps run.
    pub steps: u64,
    /// Relative change of the last extrapolation from the one before.
    pub change: f64,
    /// Wall-clock seconds.
    pub seconds: f64,
}

/// The steady superficial velocity of the array at diameter `d` (one forcing iteration,
/// retraction `retraction`) by Aitken extrapolation of the mean velocity's exponential
/// approach, and `K = G L³/(6π μ a U_∞)` (at steady state the drag equals the total body force,
/// as the `force_balance` check of [`run`] verifies to 1e-9). The mean flow relaxes as
/// `U(t) = U_∞ − A e^{−t/W}` once the diffusive modes of the box (time `L²/(4π²ν) ≈ W/11`)
/// have died out; samples `Δ = W/2` apart from `t = W` on give `U_∞ = U₃ − (U₃ − U₂)²/(U₃ −
/// 2U₂ + U₁)`, repeated every `Δ` until two successive extrapolations agree to `tol`
/// (relative), at most `8 W`. About a tenth of the steps of [`solve`]: the calibration of the
/// retraction (`examples/calibrate_retraction.rs`) needs `d = 24` (a 96³ box).
pub fn solve_extrapolated(d: usize, retraction: f64, tol: f64) -> Extrapolated {
    let t0 = std::time::Instant::now();
    let l = 4 * d;
    let a = d as f64 / 2.0;
    let (mut cp, g, w) = setup(d, 1, retraction);
    let dt = w / 2;
    cp.run(w).expect("stencils");
    let mut steps = w;
    let mut samples = vec![mean_u(&cp)];
    let mut prev = f64::NAN;
    loop {
        cp.run(dt).expect("stencils");
        steps += dt;
        samples.push(mean_u(&cp));
        let n = samples.len();
        if n >= 3 {
            let (u1, u2, u3) = (samples[n - 3], samples[n - 2], samples[n - 1]);
            let den = u3 - 2.0 * u2 + u1;
            let est = if den.abs() > 0.0 { u3 - (u3 - u2) * (u3 - u2) / den } else { u3 };
            let change = ((est - prev) / est).abs();
            if change < tol || steps >= 8 * w {
                let k = g * (l * l * l) as f64 / (6.0 * std::f64::consts::PI * NU * a * est);
                return Extrapolated { k, u: est, steps, change, seconds: t0.elapsed().as_secs_f64() };
            }
            prev = est;
        }
    }
}

/// Bound on `|K/K_ref − 1|` with the calibrated retraction at `d ≥ 8` (module docs).
pub const TOL_CALIBRATED: f64 = 0.015;
/// The same at `d = 4` and `6`, below the calibration's range (module docs).
pub const TOL_CALIBRATED_COARSE: f64 = 0.04;

/// Runs the case.
pub fn run(tier: Tier) -> CaseOutput {
    let mut out = CaseOutput { has_ref: true, ..Default::default() };
    let rows: Vec<Row> = resolutions(tier).into_par_iter().map(|d| solve(d, 1, DEFAULT_RETRACTION)).collect();
    let worst_change = rows.iter().map(|r| r.rel_change).fold(0.0, f64::max);
    out.checks.push(Check::at_most(
        CASE,
        "steady_rel_change",
        worst_change,
        STEADY,
        "steady state at every d: relative change of the mean velocity over one relaxation time \
         of the mean flow L³/(6πνaK) below 1e-9",
    ));
    for r in &rows {
        let (bound, why) = if r.d >= 8 {
            (
                TOL_CALIBRATED,
                "calibrated retraction (fitted on d = 8-24 of this array): residual at most 1 % at d = 8-24 \
                 (retraction_calibration.csv); 1.5 % leaves room for the rounding of the fitted value, while \
                 the uncalibrated 15 % at d = 8 (or a retraction off by 0.06) fails",
            )
        } else {
            (
                TOL_CALIBRATED_COARSE,
                "below the calibrated range: the diffuse interface's excess grows at small d (0.39 at d = 6 \
                 against 0.36 fitted); 4 % bounds the measured 2-3 %",
            )
        };
        out.checks.push(Check::at_most(
            CASE,
            format!("d{}_K_rel_error_calibrated", r.d),
            r.k / K_REF - 1.0,
            bound,
            why,
        ));
    }
    let worst_balance = rows.iter().map(|r| r.balance).fold(0.0, f64::max);
    out.checks.push(Check::at_most(
        CASE,
        "force_balance_max_over_d",
        worst_balance,
        1e-6,
        "at steady state the IBM force on the sphere equals the total body force G L³ (spreading \
         is a partition of unity on a periodic box); the 1e-9 steady criterion leaves far less, \
         a wrong marker volume or a lost/double-counted force gives O(1)",
    ));
    out.tables.push(table(
        format!("trt nu=1/6 Re={RE} K_ref={K_REF} forcing_iterations=1 retraction={DEFAULT_RETRACTION}"),
        &rows,
    ));
    // The uncalibrated immersed boundary (markers on the input surface): first-order
    // convergence of K, by the cheaper extrapolated solution.
    let ds: Vec<usize> = match tier {
        Tier::Quick => vec![4, 6, 8],
        Tier::Full => vec![4, 6, 8, 12, 16],
    };
    let raw: Vec<(usize, Extrapolated)> =
        ds.into_par_iter().map(|d| (d, solve_extrapolated(d, 0.0, 1e-7))).collect();
    let mut t = Table::new(
        "retraction=0 (uncalibrated), Aitken-extrapolated steady state",
        &[
            ("d", true),
            ("steps", false),
            ("extrapolation_change", false),
            ("K", true),
            ("rel_error", true),
            ("hydrodynamic_radius_excess", true),
            ("seconds", false),
        ],
    );
    for (d, e) in &raw {
        let a = 0.5 * *d as f64;
        let excess = hydrodynamic_radius(e.k, a, 4.0 * *d as f64) - a;
        t.push(vec![*d as f64, e.steps as f64, e.change, e.k, e.k / K_REF - 1.0, excess, e.seconds]);
    }
    let ds: Vec<f64> = raw.iter().map(|r| r.0 as f64).collect();
    let errs: Vec<f64> = raw.iter().map(|r| (r.1.k / K_REF - 1.0).abs()).collect();
    out.checks.push(Check::at_least(
        CASE,
        "uncalibrated_K_rel_error_order",
        fit::order(&ds, &errs),
        1.0,
        0.7,
        "IBM with a fixed input radius: effective radius a + O(1), so the error of K is first \
         order in 1/d (physics.md §3, §5); 0.7 allows for the pre-asymptotic coarse points",
    ));
    out.tables.push(t);
    // The forcing-iteration comparison (uncalibrated): at d = 4 in the quick tier (seconds),
    // d = 8 in the full tier (minutes).
    let d_its = if tier == Tier::Quick { 4 } else { 8 };
    let its: Vec<Row> = [1usize, 3].into_par_iter().map(|k| solve(d_its, k, 0.0)).collect();
    let mut t = table(format!("d={d_its}: forcing iterations 1 vs 3"), &its);
    t.title = format!("d={d_its} forcing iterations (rows: 1, 3), retraction=0");
    out.tables.push(t);
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn sangani_acrivos_reproduces_zick_homsy() {
        // physics.md §5: solids fraction → K (Zick & Homsy 1982).
        for (c, k) in [(0.027, 2.008), (0.064, 2.810), (0.125, 4.292)] {
            let rel = (k_sangani_acrivos(c) / k - 1.0).abs();
            assert!(rel < 1e-3, "c = {c}: {} vs {k}", k_sangani_acrivos(c));
        }
        let c = std::f64::consts::PI / 384.0;
        assert!((k_sangani_acrivos(c) / K_REF - 1.0).abs() < 1e-3);
    }

    #[test]
    fn hydrodynamic_radius_inverts_the_drag() {
        let (a, l) = (6.0f64, 48.0f64);
        let c = |r: f64| 4.0 * std::f64::consts::PI * r.powi(3) / (3.0 * l.powi(3));
        for ah in [5.5, 6.0, 6.7] {
            let k_meas = ah * k_sangani_acrivos(c(ah)) / a;
            assert!((hydrodynamic_radius(k_meas, a, l) - ah).abs() < 1e-9);
        }
    }
}
