//! # Poiseuille flow: a channel driven by a body force between two no-slip walls
//!
//! **Physics.** A `1 × 1 × N` box, periodic in x and y, half-way bounce-back walls on the z
//! faces (so the walls sit at `z = −½` and `z = N − ½`: width `H = N`), uniform body force
//! density `F` along x, fluid initially at rest, run to steady state (criterion:
//! `run_to_steady` (in `cases`), relative change below 1e-13 over one e-folding time; the number of
//! steps and the last change are in the table).
//!
//! **Reference.** The exact steady solution of the Navier–Stokes equations,
//! `u_x(z) = F/(2ρν) (z + ½)(N − ½ − z)`, with `ρ = 1` (no pressure gradient, the density
//! stays uniform), `u_max = F N²/(8ν)`.
//!
//! **Resolutions.** `N = 8, 16, 32, 64` (quick), and `128` (full), at fixed `ν = 0.1`
//! (`τ = 0.8`) and fixed `u_max = 0.02` (Mach 0.035): `F = 8 ν u_max / N²`, i.e. diffusive
//! scaling, so the only thing that changes is the resolution.
//!
//! **Metric.** Relative L2 error of `u_x(z)` over the N nodes, `‖u − u_exact‖₂/‖u_exact‖₂`;
//! observed order = minus the least-squares slope of `log error` on `log N`.
//!
//! **Tolerances and why.**
//! - BGK: order ≥ 1.8. LBM with half-way bounce-back is second order (physics.md §5; Ginzburg &
//!   d'Humières 2003): for BGK the wall sits at `−½ + δ` with `δ² ∝ (τ−½)² − 3/16`, a
//!   viscosity-dependent error that shrinks as `1/N²` relative. 1.8 rather than 2.0 leaves room
//!   for the pre-asymptotic coarsest point (N = 8) in the least-squares fit; a first-order
//!   scheme (e.g. a misplaced wall, `O(1/N)`) gives ≈ 1 and fails.
//! - TRT with magic parameter `Λ = 3/16`: the parabolic profile is an exact solution of the
//!   discrete scheme with the wall exactly half-way (Ginzburg, Verhaeghe & d'Humières 2008,
//!   Commun. Comput. Phys. 3:427, Sec. 4), for every N and every ν. Relative L2 error
//!   ≤ 1e-10 in f64: the round-off of the steady state is that of the discrete problem,
//!   amplified by its condition number `∝ N²` (observed: 2e-14 at N = 8, 2e-13 at N = 64,
//!   3e-12 at N = 128), and the steady-state criterion leaves `< 1.6e-13`; 1e-10 is the
//!   issue's bound and is far above both, while any discretisation error (BGK: 1e-2 … 4e-5
//!   here) is far above it. Two viscosities
//!   (`ν = 0.1` and `0.4`, `τ = 0.8` and `1.7`) show that it does not depend on ν.
//! - The TRT errors are round-off: they are printed but not compared with the `.ref` file.

use rayon::prelude::*;
use slurry::lbm::{FaceBoundary, Fluid, FluidParams};

use super::{channel, column, run_to_steady, STEADY_TOL};
use crate::{fit, CaseOutput, Check, Table, Tier};

const CASE: &str = "poiseuille";
const U_MAX: f64 = 0.02;

/// Resolutions of the study.
pub fn resolutions(tier: Tier) -> Vec<usize> {
    match tier {
        Tier::Quick => vec![8, 16, 32, 64],
        Tier::Full => vec![8, 16, 32, 64, 128],
    }
}

/// The exact profile.
pub fn exact(n: usize, force: f64, nu: f64) -> Vec<f64> {
    (0..n)
        .map(|z| {
            let z = z as f64;
            force / (2.0 * nu) * (z + 0.5) * (n as f64 - 0.5 - z)
        })
        .collect()
}

struct Row {
    n: usize,
    force: f64,
    steps: u64,
    rel_change: f64,
    converged: bool,
    l2: f64,
    max: f64,
}

fn solve(n: usize, trt: bool, nu: f64) -> Row {
    let force = 8.0 * nu * U_MAX / (n * n) as f64;
    let base = if trt { FluidParams::trt(nu) } else { FluidParams::bgk(nu) };
    let params = base.with_body_force([force, 0.0, 0.0]);
    let mut f =
        Fluid::<f64>::new(column(n), params, channel(FaceBoundary::NoSlip)).expect("valid Poiseuille set-up");
    f.initialize(|_, _, _| (1.0, [0.0; 3]));
    let max_steps = (40.0 * (n * n) as f64 / nu) as u64;
    let s = run_to_steady(&mut f, nu, max_steps);
    let ex = exact(n, force, nu);
    Row {
        n,
        force,
        steps: s.steps,
        rel_change: s.rel_change,
        converged: s.converged,
        l2: fit::rel_l2(&s.profile, &ex),
        max: fit::rel_max(&s.profile, &ex),
    }
}

fn study(tier: Tier, trt: bool, nu: f64, compare_errors: bool) -> (Table, Vec<Row>) {
    let rows: Vec<Row> = resolutions(tier).into_par_iter().map(|n| solve(n, trt, nu)).collect();
    let name = if trt { "trt" } else { "bgk" };
    let mut t = Table::new(
        format!("{name} nu={nu} u_max={U_MAX}"),
        &[
            ("N", true),
            ("F", true),
            ("steps", false),
            ("rel_change", false),
            ("L2_error", compare_errors),
            ("max_error", compare_errors),
        ],
    );
    for r in &rows {
        t.push(vec![r.n as f64, r.force, r.steps as f64, r.rel_change, r.l2, r.max]);
    }
    (t, rows)
}

fn steady_check(label: &str, rows: &[Row]) -> Check {
    let worst = rows.iter().map(|r| r.rel_change).fold(0.0, f64::max);
    let all = rows.iter().all(|r| r.converged);
    let mut c = Check::at_most(
        CASE,
        format!("{label}_steady_rel_change"),
        worst,
        STEADY_TOL,
        "steady state reached at every N: relative change over one e-folding time of the \
         slowest mode below 1e-13, so < 1.6e-13 remains (see cases::run_to_steady)",
    );
    c.pass &= all;
    c
}

/// Runs the case.
pub fn run(tier: Tier) -> CaseOutput {
    let mut out = CaseOutput { has_ref: true, ..Default::default() };
    let nu = 0.1;
    let (tb, bgk) = study(tier, false, nu, true);
    let ns: Vec<f64> = bgk.iter().map(|r| r.n as f64).collect();
    let errs: Vec<f64> = bgk.iter().map(|r| r.l2).collect();
    out.checks.push(steady_check("bgk_nu0.1", &bgk));
    out.checks.push(Check::at_least(
        CASE,
        "bgk_nu0.1_L2_order",
        fit::order(&ns, &errs),
        2.0,
        1.8,
        "half-way bounce-back + BGK is second order (wall offset ∝ (τ−½)²−3/16 gives O(1/N²)); \
         1.8 allows for the pre-asymptotic N = 8 in the least-squares fit",
    ));
    out.tables.push(tb);
    for nu_t in [0.1, 0.4] {
        let (tt, trt) = study(tier, true, nu_t, false);
        let label = format!("trt_nu{nu_t}");
        out.checks.push(steady_check(&label, &trt));
        let worst = trt.iter().map(|r| r.l2).fold(0.0, f64::max);
        out.checks.push(Check::at_most(
            CASE,
            format!("{label}_L2_error_max_over_N"),
            worst,
            1e-10,
            "TRT with Λ = 3/16 makes the parabola an exact solution with the wall exactly \
             half-way, for any N and ν (Ginzburg et al. 2008); what remains is round-off \
             (ε times a condition number ∝ N²: ≈ 3e-12 at N = 128) and the < 1.6e-13 left by \
             the steady-state criterion",
        ));
        out.tables.push(tt);
    }
    out
}
