//! # Stokes drag of a simple-cubic periodic array of fixed spheres (IBM coupling)
//!
//! **Physics.** One sphere of diameter `d` (input diameter, markers at spacing 0.7, Roma
//! 3-point kernel) fixed at the centre of a fully periodic box of edge `L = 4d`
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
//! §5), with `μ = ρν` (`ρ = 1`), `a = d/2` the *input* radius (no hydrodynamic-radius
//! calibration), `F` the drag on one sphere and `U` the superficial velocity: the mean of the
//! fluid velocity `u = (j + F/2)/ρ` over **all** nodes of the box (nodes inside the sphere
//! included). Particle Reynolds number `Re = U d/ν = 0.05` (`G` is set from the reference `K`
//! so that `U ≈ 0.05 ν/d`; the measured `Re` is in the table): Stokes flow to `O(Re)`.
//!
//! **Metrics.**
//! - `K` and its relative error `|K/1.530 − 1|` per `d`; observed order = minus the
//!   least-squares slope of `log error` on `log d`.
//! - Force balance: at steady state the momentum of the fluid is constant, so the IBM force on
//!   the sphere equals the total body force, `F_x = G L³` (spreading is a partition of unity on
//!   a periodic box, so `Σ_nodes S F = Σ_m F_m`). `|F_x/(G L³) − 1|`, worst over `d`.
//!
//! **Tolerances and why.**
//! - Order ≥ 0.7: with a fixed input radius the diffuse interface of the IBM makes the
//!   effective radius `a + O(1)` lattice units, so the error of `K` falls at first order in
//!   `1/d` (physics.md §3 and §5; ten Cate et al. 2002 calibrate exactly this offset). A fit
//!   over `d = 6 … 12` (16 in the full tier) may be pre-asymptotic; 0.7 leaves room for that
//!   while a non-converging coupling (order ≈ 0) fails.
//! - Force balance ≤ 1e-6: the steady-state criterion (1e-9 relative over an e-folding time)
//!   leaves a momentum imbalance `W · dU/dt ∝ 1e-9`, far below; a wrong marker volume or a
//!   force spread but not counted (or counted twice) would show at O(1).
//! - The error at `d = 12` is reported, not bounded: the first-order IBM error is the known,
//!   uncalibrated effective-radius offset, and its size is what this case documents.
//! - Forcing iterations: `K_it = 1` and `3` at `d = 8` are compared in a second table; the
//!   default is 1 (see the report of issue 3 for the comparison).

use std::sync::Arc;

use rayon::prelude::*;
use slurry::coupling::{Coupled, CouplingParams};
use slurry::lattice::Grid;
use slurry::lbm::{Boundaries, Fluid, FluidParams};
use slurry::rigid::{Motion, RigidBody, Sphere, Vec3};

use crate::{fit, CaseOutput, Check, Table, Tier};

const CASE: &str = "stokes_drag";
/// Zick & Homsy 1982, `d/L = 0.25`.
pub const K_REF: f64 = 1.530;
const NU: f64 = 1.0 / 6.0;
const RE: f64 = 0.05;
const STEADY: f64 = 1e-9;

/// Resolutions (sphere diameters) of the study.
pub fn resolutions(tier: Tier) -> Vec<usize> {
    match tier {
        Tier::Quick => vec![4, 6, 8],
        Tier::Full => vec![4, 6, 8, 12],
    }
}

struct Row {
    d: usize,
    steps: u64,
    rel_change: f64,
    u: f64,
    k: f64,
    balance: f64,
    seconds: f64,
}

fn mean_u(c: &Coupled<f64>) -> f64 {
    let (_, u) = c.fluid().fields();
    u.iter().map(|v| v[0]).sum::<f64>() / u.len() as f64
}

fn solve(d: usize, iterations: usize) -> Row {
    let t0 = std::time::Instant::now();
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
    let mut cp = Coupled::new(fluid, vec![body], CouplingParams { iterations, ..Default::default() })
        .expect("fixed body");
    // Relaxation time of the mean flow, U' = G − F/L³ with F = 6πνaK U: L³/(6πνaK) (this,
    // not the diffusive L²/(4π²ν), is the slowest mode: observed e-folding ≈ 900 steps at d = 6).
    let w = ((l * l * l) as f64 / (6.0 * std::f64::consts::PI * NU * a * K_REF)).ceil() as u64;
    let w = w + w % 2;
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

/// Runs the case.
pub fn run(tier: Tier) -> CaseOutput {
    let mut out = CaseOutput { has_ref: true, ..Default::default() };
    let rows: Vec<Row> = resolutions(tier).into_par_iter().map(|d| solve(d, 1)).collect();
    let ds: Vec<f64> = rows.iter().map(|r| r.d as f64).collect();
    let errs: Vec<f64> = rows.iter().map(|r| (r.k / K_REF - 1.0).abs()).collect();
    let worst_change = rows.iter().map(|r| r.rel_change).fold(0.0, f64::max);
    out.checks.push(Check::at_most(
        CASE,
        "steady_rel_change",
        worst_change,
        STEADY,
        "steady state at every d: relative change of the mean velocity over one relaxation time \
         of the mean flow L³/(6πνaK) below 1e-9",
    ));
    out.checks.push(Check::at_least(
        CASE,
        "K_rel_error_order",
        fit::order(&ds, &errs),
        1.0,
        0.7,
        "IBM with a fixed input radius: effective radius a + O(1), so the error of K is first \
         order in 1/d (physics.md §3, §5); 0.7 allows for the pre-asymptotic coarse points",
    ));
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
    out.tables.push(table(format!("trt nu=1/6 Re={RE} K_ref={K_REF} forcing_iterations=1"), &rows));
    // The forcing-iteration comparison: at d = 4 in the quick tier (seconds), d = 8 in the
    // full tier (minutes).
    let d_its = if tier == Tier::Quick { 4 } else { 8 };
    let its: Vec<Row> = [1usize, 3].into_par_iter().map(|k| solve(d_its, k)).collect();
    let mut t = table(format!("d={d_its}: forcing iterations 1 vs 3"), &its);
    t.title = format!("d={d_its} forcing iterations (rows: 1, 3)");
    out.tables.push(t);
    out
}
