//! # Mass (and momentum) conservation to round-off
//!
//! **Physics.** The lattice-Boltzmann update conserves mass exactly in exact arithmetic: the
//! collision conserves `Σ_i f_i` at every node (BGK and TRT, and the Guo source has zero
//! sum), streaming only moves populations, and half-way bounce-back returns every population
//! that hits a wall; Ladd's moving-wall term `6 w_ī c_ī·u_w` sums to zero over the links of
//! a node on a flat wall, and at the lid's edges (where a diagonal link crossing two walls uses
//! the mean wall velocity) the terms of the two opposite edges cancel. In a periodic box with no
//! force, total momentum is conserved too; with a uniform body force `F` it grows by exactly
//! `F` per node and step.
//!
//! **Set-ups.**
//! - Periodic box `16³` (quick) / `32³` (full), a seeded pseudo-random initial field
//!   (`ρ = 1 ± 0.01`, `|u_a| ≤ 0.02`, SplitMix64 with a fixed seed), BGK (`ν = 0.08`) and TRT
//!   (`ν = 0.03`, body force `(1e-6, −2e-6, 0)`), f64 and f32.
//! - Closed box `16³` / `32³`, lid (`z_max`) moving at `(0.05, 0, 0)`, a solid block inside,
//!   starting at rest: BGK f64 and TRT f32.
//! - 1000 steps (quick) / 4000 (full).
//!
//! **Metric.** `|m(t) − m(0)|/m(0)` with `m = Σ ρ` over fluid nodes, summed in f64 as
//! `N_fluid + Σ δρ` ([`slurry::lbm::Fluid::mass_deviation`]), so that the summation does not
//! hide the drift. For the periodic runs also the momentum drift per node,
//! `max_a |P_a(t) − P_a(0) − t N F_a| / N`.
//!
//! **Tolerance** (both): the worst case of round-off, `2 Q ε h t`, with `ε` the storage
//! precision's machine epsilon, `h` the largest `|f_i − w_i|` at the start or the end (the
//! scale of the stored numbers, which are shifted by `w_i`), `Q = 19`, `t` steps. Why: each
//! step every stored population goes through about four roundings of relative size ≤ ε/2 on
//! numbers of size ≤ h (collision; the wall term for bounce-back links), so the node's mass or
//! momentum changes by at most `≈ 2 Q ε h` per step, and in the worst case these errors have
//! the same sign everywhere and always. That worst case is not academic: once the random
//! field has decayed the flow is nearly uniform, every node rounds the same numbers the same
//! way, and the drift grows linearly in `t` (observed: the f32 momentum drift grows ∝ t from
//! 250 to 16000 steps, and faster when a body force accelerates the flow and `h` grows). The
//! table also prints the random-walk estimate `ε h √(Q t / n)` (unbiased rounding) for scale;
//! measured drifts lie between the two. A real leak is far above the bound in f64 (e.g. a
//! moving-wall rule that did not cancel at the lid's edges: ≈ 1e-5 per step; a Guo source
//! with non-zero sum: `≈ u F` per step), so the f64 runs are the sensitive ones.

use slurry::device::fluid::DeviceReal;
use slurry::lattice::{Face, Grid, Q};
use slurry::lbm::{Boundaries, FaceBoundary, Fluid, FluidParams, Real};

use crate::backend::Stepper;
use crate::{CaseOutput, Check, Table, Tier};

const CASE: &str = "mass_conservation";

/// A seeded random field `(ρ, u)` per node.
fn random_field(g: Grid, seed: u64) -> Vec<(f64, [f64; 3])> {
    let mut r = slurry::util::SplitMix64(seed);
    (0..g.nodes())
        .map(|_| {
            let rho = 1.0 + 0.02 * (r.unit() - 0.5);
            let u = [0.0; 3].map(|_| 0.04 * (r.unit() - 0.5));
            (rho, u)
        })
        .collect()
}

struct Outcome {
    nodes: usize,
    mass_drift: f64,
    momentum_drift: Option<f64>,
    h_max: f64,
}

fn h_max<T: Real>(f: &Fluid<T>) -> f64 {
    let g = f.grid();
    let mut m = 0.0f64;
    for z in 0..g.nz {
        for y in 0..g.ny {
            for x in 0..g.nx {
                if !f.is_obstacle(x, y, z) {
                    for v in f.shifted_populations(x, y, z) {
                        m = m.max(v.to_f64().abs());
                    }
                }
            }
        }
    }
    m
}

fn periodic<T: DeviceReal>(n: usize, params: FluidParams, steps: u64) -> Outcome {
    let g = Grid::new(n, n, n);
    let field = random_field(g, 0x5EED_0001);
    let mut f = Fluid::<T>::new(g, params, Boundaries::periodic()).expect("valid set-up");
    f.initialize(|x, y, z| field[g.index(x, y, z)]);
    let (nf, d0) = f.mass_deviation();
    let p0 = f.total_momentum();
    let h = h_max(&f);
    Stepper::new(&mut f).run(steps);
    let h = h.max(h_max(&f));
    let (_, d1) = f.mass_deviation();
    let p1 = f.total_momentum();
    let fb = params.body_force;
    let dp = (0..3).map(|a| (p1[a] - p0[a] - steps as f64 * nf as f64 * fb[a]).abs()).fold(0.0, f64::max);
    Outcome {
        nodes: nf,
        mass_drift: (d1 - d0).abs() / (nf as f64 + d0),
        momentum_drift: Some(dp / nf as f64),
        h_max: h,
    }
}

fn lid_box<T: DeviceReal>(n: usize, params: FluidParams, steps: u64) -> Outcome {
    let g = Grid::new(n, n, n);
    let b =
        Boundaries::closed_box().with(Face::ZMax, FaceBoundary::MovingWall { velocity: [0.05, 0.0, 0.0] });
    let mut f = Fluid::<T>::new(g, params, b).expect("valid set-up");
    let (lo, hi) = (n / 4, n / 2);
    f.set_obstacles(|x, y, z| (lo..hi).contains(&x) && (lo..hi).contains(&y) && (lo..hi).contains(&z))
        .expect("even time");
    f.initialize(|_, _, _| (1.0, [0.0; 3]));
    let (nf, d0) = f.mass_deviation();
    Stepper::new(&mut f).run(steps);
    // At rest the populations are 0; their scale is set by the lid: f_neq ~ w·6·U.
    let h = h_max(&f);
    let (_, d1) = f.mass_deviation();
    Outcome { nodes: nf, mass_drift: (d1 - d0).abs() / (nf as f64 + d0), momentum_drift: None, h_max: h }
}

/// Worst-case (coherent) round-off bound on the relative drift: `2 Q ε h t`.
fn bound(eps: f64, o: &Outcome, steps: u64) -> f64 {
    2.0 * Q as f64 * eps * o.h_max * steps as f64
}

/// Random-walk (unbiased rounding) estimate: `ε h √(Q t / n)`.
fn random_walk(eps: f64, o: &Outcome, steps: u64) -> f64 {
    eps * o.h_max * (Q as f64 * steps as f64 / o.nodes as f64).sqrt()
}

/// Runs the case.
pub fn run(tier: Tier) -> CaseOutput {
    let (n, steps) = match tier {
        Tier::Quick => (16, 1000),
        Tier::Full => (32, 4000),
    };
    let bgk = FluidParams::bgk(0.08);
    let trt = FluidParams::trt(0.03).with_body_force([1e-6, -2e-6, 0.0]);
    let e64 = f64::EPSILON;
    let e32 = f32::EPSILON as f64;
    let runs: Vec<(&str, f64, Outcome)> = vec![
        ("periodic_bgk_f64", e64, periodic::<f64>(n, bgk, steps)),
        ("periodic_trt_force_f64", e64, periodic::<f64>(n, trt, steps)),
        ("periodic_bgk_f32", e32, periodic::<f32>(n, bgk, steps)),
        ("periodic_trt_force_f32", e32, periodic::<f32>(n, trt, steps)),
        ("lid_box_bgk_f64", e64, lid_box::<f64>(n, FluidParams::bgk(0.05), steps)),
        ("lid_box_trt_f32", e32, lid_box::<f32>(n, FluidParams::trt(0.05), steps)),
    ];
    let mut out = CaseOutput::default();
    let mut t = Table::new(
        format!(
            "{steps} steps; run: {}",
            runs.iter().enumerate().map(|(k, r)| format!("{k} = {}", r.0)).collect::<Vec<_>>().join(", ")
        ),
        &[
            ("run", false),
            ("fluid_nodes", false),
            ("h_max", false),
            ("mass_drift", false),
            ("random_walk", false),
            ("bound", false),
            ("momentum_drift", false),
        ],
    );
    let why = "round-off only, worst case: ≈ 4 roundings of ≤ ε h/2 per population, Q per node, \
               t steps, all of one sign (a nearly uniform flow rounds coherently): 2 Q ε h t";
    for (k, (name, eps, o)) in runs.iter().enumerate() {
        let b = bound(*eps, o, steps);
        t.push(vec![
            k as f64,
            o.nodes as f64,
            o.h_max,
            o.mass_drift,
            random_walk(*eps, o, steps),
            b,
            o.momentum_drift.unwrap_or(f64::NAN),
        ]);
        out.checks.push(Check::at_most(CASE, format!("{name}_mass_rel_drift"), o.mass_drift, b, why));
        if let Some(dp) = o.momentum_drift {
            out.checks.push(Check::at_most(CASE, format!("{name}_momentum_drift_per_node"), dp, b, why));
        }
    }
    out.tables.push(t);
    out
}
