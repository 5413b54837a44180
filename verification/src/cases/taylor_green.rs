//! # Taylor–Green vortex decay (2-D modes in a 3-D periodic box)
//!
//! **Physics.** A periodic `N × N × 2` box (D3Q19 in 3-D; the flow has no z dependence and no
//! z velocity), lattice node `x` at position `x`, `k = 2π/N`:
//! `u_x = U sin(kx) cos(ky)`, `u_y = −U cos(kx) sin(ky)`, `u_z = 0`,
//! `p = ρ₀U²/4 (cos 2kx + cos 2ky)`, initial density `ρ = 1 + 3p` (`p = c_s² δρ`), populations
//! at equilibrium. BGK, `ν = 0.05` (`τ = 0.65`, the paper's value).
//!
//! **Reference.** The exact solution of the incompressible Navier–Stokes equations:
//! `u(x, t) = u(x, 0) e^{−2νk²t}`, so the kinetic energy `E = ½ Σ |u|²` decays as
//! `e^{−4νk²t}` (Taylor & Green 1937; physics.md §5).
//!
//! **Resolutions.** `N = 16, 32, 64, 128` (quick), `256` (full), in diffusive scaling: `ν`
//! fixed, `U = 0.05 · 16/N` (so `Re = UN/ν = 16` and the Mach number `∝ 1/N`), compared at
//! `t = N²/4` steps (`2νk²t = 2π²ν ≈ 0.99`: the velocity has decayed to 0.37).
//!
//! **Metrics.**
//! - Velocity: relative L2 error of `u` over all nodes against the exact field at `t = N²/4`;
//!   observed order by least squares. Tolerance: order ≥ 1.8, because LBM is second order in
//!   space and (in diffusive scaling) in time, and the compressibility error `O(Ma²)` also
//!   falls as `1/N²` here; 1.8 leaves room for the pre-asymptotic coarsest point.
//!   The error is almost all in the amplitude (columns `amp_error`, the projection on the
//!   initial mode over the exact decay, minus 1, and `t_shift`, the time shift in steps that
//!   amplitude error is equivalent to): equilibrium initialisation starts with no
//!   non-equilibrium populations, so the first step diffuses momentum with the `τ = 1` viscosity
//!   `c_s²/2 = 1/6` instead of ν, and the deficit relaxes as `(1 − ω)ⁿ`; summed, an extra
//!   decay worth `(c_s²/2 − ν) τ/ν ≈ 1.52` steps at `ν = 0.05` (observed: 1.54). A constant
//!   shift of O(1) steps out of `N²/4` is an `O(1/N²)` relative error, so it does not spoil the
//!   order.
//! - Viscosity: `ν_fit = −s/(4k²)` with `s` the least-squares slope of `ln E` against `t`
//!   over 13 samples in `t ∈ [N²/16, N²/4]` (the first quarter is skipped: equilibrium
//!   initialisation lacks the non-equilibrium populations, which relax within a few steps,
//!   and the acoustic waves it emits die out). Tolerance: `|ν_fit/ν − 1| ≤ 1 %` at the finest
//!   N (the bound). The deviation is the lattice's dispersion (`O(k²) = O(1/N²)`) plus
//!   `O(Ma²)`; at N = 16 it is a few per mille and it falls as `1/N²`, so the 1 % band is
//!   met with wide margin at the finest N, while a wrong relaxation time (e.g. `τ = 3ν` without
//!   the ½) misses by 30 %.

use rayon::prelude::*;
use slurry::lattice::Grid;
use slurry::lbm::{Boundaries, Fluid, FluidParams};

use crate::backend::Stepper;
use crate::{fit, CaseOutput, Check, Table, Tier};

const CASE: &str = "taylor_green";
const NU: f64 = 0.05;
/// Velocity amplitude at N = 16 (scaled as 1/N).
const U16: f64 = 0.05;
/// Energy samples over the run (t = j·t_end/SAMPLES); the fit uses j ≥ SAMPLES/4.
const SAMPLES: u64 = 16;

/// Resolutions of the study.
pub fn resolutions(tier: Tier) -> Vec<usize> {
    match tier {
        Tier::Quick => vec![16, 32, 64, 128],
        Tier::Full => vec![16, 32, 64, 128, 256],
    }
}

/// Initial state `(ρ, u)` at node `(x, y)` for amplitude `u0` and wave number `k`.
fn initial(x: usize, y: usize, u0: f64, k: f64) -> (f64, [f64; 3]) {
    let (x, y) = (x as f64, y as f64);
    let p = u0 * u0 / 4.0 * ((2.0 * k * x).cos() + (2.0 * k * y).cos());
    (1.0 + 3.0 * p, [u0 * (k * x).sin() * (k * y).cos(), -u0 * (k * x).cos() * (k * y).sin(), 0.0])
}

struct Row {
    n: usize,
    u0: f64,
    steps: u64,
    l2: f64,
    nu_fit: f64,
    amp_error: f64,
    t_shift: f64,
}

fn solve(n: usize) -> Row {
    let k = 2.0 * std::f64::consts::PI / n as f64;
    let u0 = U16 * 16.0 / n as f64;
    let grid = Grid::new(n, n, 2);
    let mut f = Fluid::<f64>::new(grid, FluidParams::bgk(NU), Boundaries::periodic())
        .expect("valid Taylor-Green set-up");
    f.initialize(|x, y, _| initial(x, y, u0, k));
    let t_end = (n * n / 4) as u64;
    let dt = t_end / SAMPLES;
    let (mut times, mut log_energy) = (Vec::new(), Vec::new());
    let mut stepper = Stepper::new(&mut f);
    for j in 1..=SAMPLES {
        stepper.run(dt);
        let f = stepper.fluid();
        if j >= SAMPLES / 4 {
            let (_, u) = f.fields();
            let e: f64 = 0.5 * u.iter().map(|v| v[0] * v[0] + v[1] * v[1] + v[2] * v[2]).sum::<f64>();
            times.push(f.time() as f64);
            log_energy.push(e.ln());
        }
    }
    let steps = f.time();
    let decay = (-2.0 * NU * k * k * steps as f64).exp();
    let (_, u) = f.fields();
    let (mut num, mut den, mut init_u) = (Vec::new(), Vec::new(), Vec::new());
    for (i, v) in u.iter().enumerate() {
        let [x, y, _] = grid.coords(i);
        let u_init = initial(x, y, u0, k).1;
        num.extend_from_slice(v);
        den.extend_from_slice(&u_init.map(|c| c * decay));
        init_u.extend_from_slice(&u_init);
    }
    let slope = fit::line(&times, &log_energy).1;
    // Projection on the initial mode: amplitude error and the time shift it is equivalent to.
    let amp =
        num.iter().zip(&init_u).map(|(p, q)| p * q).sum::<f64>() / init_u.iter().map(|q| q * q).sum::<f64>();
    Row {
        n,
        u0,
        steps,
        l2: fit::rel_l2(&num, &den),
        nu_fit: -slope / (4.0 * k * k),
        amp_error: amp / decay - 1.0,
        t_shift: -(amp / decay).ln() / (2.0 * NU * k * k),
    }
}

/// Runs the case.
pub fn run(tier: Tier) -> CaseOutput {
    let mut out = CaseOutput { has_ref: true, ..Default::default() };
    // Largest first: the two biggest runs share the cores best that way.
    let mut ns = resolutions(tier);
    ns.reverse();
    let mut rows: Vec<Row> = ns.into_par_iter().map(solve).collect();
    rows.reverse();
    let mut t = Table::new(
        format!("bgk nu={NU} Re=16 t=N^2/4"),
        &[
            ("N", true),
            ("U", true),
            ("steps", true),
            ("L2_error", true),
            ("nu_fit", true),
            // Derived with cancellation (a difference from 1 of a ratio close to 1): their
            // last digits are round-off, so they are printed but not compared.
            ("nu_rel_error", false),
            ("amp_error", false),
            ("t_shift", false),
        ],
    );
    for r in &rows {
        t.push(vec![
            r.n as f64,
            r.u0,
            r.steps as f64,
            r.l2,
            r.nu_fit,
            r.nu_fit / NU - 1.0,
            r.amp_error,
            r.t_shift,
        ]);
    }
    out.tables.push(t);
    let ns: Vec<f64> = rows.iter().map(|r| r.n as f64).collect();
    let es: Vec<f64> = rows.iter().map(|r| r.l2).collect();
    out.checks.push(Check::at_least(
        CASE,
        "velocity_L2_order",
        fit::order(&ns, &es),
        2.0,
        1.8,
        "LBM is second order in diffusive scaling (space, time and Ma² ∝ 1/N² all give \
         O(1/N²)); 1.8 allows for the pre-asymptotic N = 16",
    ));
    let finest = rows.last().expect("at least one resolution");
    out.checks.push(Check::at_most(
        CASE,
        format!("nu_fit_rel_error_N{}", finest.n),
        (finest.nu_fit / NU - 1.0).abs(),
        0.01,
        "viscosity from the energy decay rate within 1 % at the finest N (issue bound); the \
         deviation is lattice dispersion O(1/N²) plus O(Ma²), a few per mille at N = 16",
    ));
    out
}
