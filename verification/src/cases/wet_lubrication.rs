//! # Wet lubrication: a sphere settling onto a fixed sphere in fluid
//!
//! **What.** The contact model of Table 1 (`slurry::contact`, `ContactParams::default()`,
//! `DEFAULT_SUBSTEPS` sub-steps) inside the coupled step (`slurry::coupling::Coupled`):
//! resolved IBM hydrodynamics plus the marker lubrication and spring, for two spheres
//! approaching in fluid. The claim: the free sphere slows down before contact (resolved squeeze
//! flow plus the lubrication model), never overlaps, and comes to rest carried by the contact.
//!
//! **Set-up.** Closed box `5d × 5d × 6d` (half-way bounce-back walls; contacts with the walls
//! on), BGK `ν = 0.05` (the paper's), f64, fluid at rest. One fixed sphere of diameter `d`
//! (`Motion::Fixed`) centred horizontally at height `d`; one free sphere of diameter `d`,
//! `γ = 1.25`, released from rest on the same vertical with a surface gap `1.5 d`. Gravity
//! `−g ẑ` with `g = 4e-5 (12/d)³`: the paper's value at its `d = 12`, and at other `d` the same
//! Stokes Reynolds number `(γ − 1) g d³/(18 ν²) = 0.38` and the same net weight (9.05e-3), so
//! the quick tier is the full tier at half scale. The approach Reynolds number
//! `Re_p = v_max d/ν` is 0.18 (`d = 6`) and 0.21 (`d = 12`): Stokes-like. Quick tier `d = 6`
//! (30 × 30 × 36), full tier `d = 12` (60 × 60 × 72; the paper's particle resolution).
//! Each run goes until one viscous time `d²/ν` after the gap first falls below `δ0 = 0.5`.
//!
//! **Recorded per step** (along `ê`, the unit vector from the fixed toward the free sphere):
//! the surface gap `h = |x1 − x0| − d`, the approach speed `v = −u1·ê`, and the loads of
//! `Coupled::loads(1)`: IBM force, interior-fluid term and contact force (averaged over the
//! sub-steps); tabulated at the first crossing of `h = 8, 6, 4, 3, 2, 1.5, 1, 0.75, 0.5`
//! (linear interpolation in `h`).
//!
//! **Lubrication on and off.** The comparison run has the lubrication forces off
//! (`ContactParams { lubrication: false, .. }`, i.e. `kⁿ = kᵗ = 0`, elastic on). Before any
//! marker pair comes within `δ_d = 1` both runs are bitwise identical (the contact loads are
//! exactly zero: checked, `contact_zero_before_split`), so the lubrication-off run is continued
//! from the lubrication-on run's state (`Coupled::snapshot`/`restore`) at the first even step
//! with `h < 2`; in the quick tier the lubrication-off run from step 0 is also made and must
//! equal it bitwise at every step (`split_equals_full_run`). This saves 60–70 % of the second
//! run.
//!
//! **Checks (metric, tolerance, why).**
//! - `arrival_speed_over_max`: `v(h = δ0)/v_max < 0.5` (lubrication on). Quasi-steady
//!   approach at low `Re_p`: `v(h)/v_max = R_far/R(h)`; the squeeze-flow asymptote alone with
//!   the unbounded Stokes drag gives `1/(1 + a/(4 δ0)) = 0.4` at `d = 6` and 0.25 at
//!   `d = 12`, and the lubrication model adds to it. Measured (forcing markers retracted by the
//!   calibrated `r_d = 0.36`): 0.252 (`d = 6`), 0.211 (`d = 12`); lubrication off 0.474 and
//!   0.335 (the resolved squeeze flow alone already halves the speed at `d = 12`). Before the
//!   retraction these were 0.197/0.165 and 0.289/0.228: the diffuse IBM interface made the
//!   effective radius `a + O(1)` lattice units (cf. `stokes_drag`), so the resolved gap was
//!   narrower than `h`.
//! - `arrival_speed_on_over_off`: `v_on(δ0)/v_off(δ0) < 1`: the lubrication model adds
//!   resistance from `δ_d = 1` on, so the lubricated sphere arrives slower. Measured 0.531
//!   (`d = 6`), 0.630 (`d = 12`).
//! - `min_gap_no_overlap`: `min h > 0` over both runs, `h` taken at every fluid step (`≥ 0`
//!   in the report). Measured 0.4701
//!   (`d = 6`), 0.4824 (`d = 12`).
//! - `min_gap_lubricated_vs_delta_sat`: lubrication on, `min h ≥ δ_sat = 0.2`: the sphere is
//!   stopped by the spring at `δ ≈ δ0` (net weight 9e-3 against `k (δ0 − δ) Σw`), far from the
//!   saturation distance. Measured 0.4723 and 0.4859.
//! - `rest_force_balance`: one viscous time past arrival, `|F_contact + F_hydro + W|/|W| ≤ 1 %`
//!   (vector; `F_hydro` = IBM + interior term): in a steady state the body's acceleration and
//!   the implicit shell correction vanish, so the contact carries the net weight minus the
//!   hydrodynamic force; 1 % leaves room for the slow drift below. Measured 8.1e-4 and 3.3e-4.
//! - `rest_normal_speed_over_vmax`: `|v|/v_max ≤ 1 %` at the same time: the approach has
//!   stopped (two orders below its peak). Measured 8.0e-3 and 1.4e-3: a creep of the gap
//!   (`h` falls by ≈ 1e-5 per step) that follows the lateral slide below.
//! - **Known deviation (reported, not checked): the resting sphere slides sideways.** As soon
//!   as the spring acts, the contact force has a horizontal component of 4.5 % (`d = 6`) and
//!   2.0 % (`d = 12`) of the net weight (column `lateral_contact_over_weight`): the marker
//!   normals of the two spheres do not form a pattern symmetric about the line of centres, so
//!   `n̂ = (n_i − n_j)/|n_i − n_j|` of the few interacting pairs does not sum to a force along
//!   it. The frictionless free sphere slides off the top of the fixed one at 4.5 % (`d = 6`)
//!   and 2.1 % (`d = 12`) of `v_max` (offset 0.046 and 0.053 one viscous time after arrival);
//!   a sphere resting on top of another is an unstable equilibrium in any case, so this is not
//!   a rest state to hold the total speed to.
//!
//! **Information (table `approach`, not checked): the resistance against the lubrication
//! asymptote.** `R = (F_hydro + F_contact)·ê / v` against `R_lub = (3π/2) μ a²/h` (two equal
//! spheres, `a = d/2`, `μ = ρν`; relative velocity `v`), at `h = 2 … 0.5`: `ratio_*` =
//! `R/R_lub`, `excess_ratio_*` = `(R − R_far)/R_lub` with `R_far = |W|/v_max` (the drag of the
//! sphere falling alone in the box). At `d = 6` the ratio is 6.9–8.4 (excess 2.7–4.8 down to
//! `h = 0.75`; at `h = 0.5` 5.8 with the model, 3.5 without); at `d = 12` 3.7–4.7 (excess
//! 2.3–3.1; 2.1 without the model at `h = 0.5`). Not a pass/fail: the
//! asymptote holds for `h ≪ a`, while here `a/h = 1.5 … 12`, and the IBM does not resolve a
//! gap of one or two lattice spacings (the two forcing shells, 1.5 wide each, overlap): the
//! resolved resistance there is that of spheres with a thicker effective radius, which is what
//! the model's parameters (`δ_d = 1`) were chosen against (Derksen 2019). The ratios fall
//! with resolution, as they should.
//!
//! **Tables** (compared with `verification/ref/wet_lubrication-<tier>.ref`; bitwise
//! deterministic, smooth low-Reynolds runs): `approach` (per gap level) and `summary`
//! (wall-clock seconds printed, not compared). Cost on 2 cores: quick ≈ 20 s (the split check
//! included), full ≈ 5 min (317 s measured with other jobs on the machine).

use std::sync::Arc;
use std::time::Instant;

use slurry::contact::ContactParams;
use slurry::coupling::{Coupled, CoupledState, CouplingParams};
use slurry::lattice::Grid;
use slurry::lbm::{Boundaries, Fluid, FluidParams};
use slurry::rigid::{Motion, RigidBody, Sphere, Vec3};

use crate::report::Value;
use crate::{CaseOutput, Check, Table, Tier};

const CASE: &str = "wet_lubrication";
/// Kinematic viscosity (the paper's).
const NU: f64 = 0.05;
/// Density ratio (the paper's).
const GAMMA: f64 = 1.25;
/// Gravity at `d = 12` (the paper's, physics.md §1); at other `d` scaled as `(12/d)³`, which
/// keeps the Stokes Reynolds number `(γ − 1) g d³/(18 ν²)` (and the net weight) the same.
const G12: f64 = 4.0e-5;
/// Initial surface gap in diameters.
const GAP0: f64 = 1.5;
/// The lubrication-off run starts from the lubrication-on run's state at the first even step
/// with `h <` this (module doc: the contact loads are exactly zero before, so both runs are
/// bitwise identical up to there).
const H_SPLIT: f64 = 2.0;
/// Gap levels at which the approach is tabulated.
const LEVELS: [f64; 9] = [8.0, 6.0, 4.0, 3.0, 2.0, 1.5, 1.0, 0.75, 0.5];

/// One step's record: the state at the start of the step and the loads during it, all along
/// `ê`, the unit vector from the fixed toward the free sphere.
#[derive(Clone, Copy, Debug, Default)]
struct Sample {
    /// Surface gap `h = |x1 − x0| − d`.
    h: f64,
    /// Approach speed `−u1·ê`.
    v: f64,
    /// Distance of the free sphere's centre from the vertical line through the fixed one.
    lateral: f64,
    /// Horizontal speed of the free sphere.
    lateral_speed: f64,
    /// `−Σ F_m · ê` (IBM).
    ibm: f64,
    /// Interior-fluid term along `ê`.
    interior: f64,
    /// Contact force along `ê` (averaged over the sub-steps).
    contact: f64,
}

impl Sample {
    fn lerp(&self, o: &Sample, s: f64) -> Sample {
        let l = |a: f64, b: f64| a + (b - a) * s;
        Sample {
            h: l(self.h, o.h),
            v: l(self.v, o.v),
            lateral: l(self.lateral, o.lateral),
            lateral_speed: l(self.lateral_speed, o.lateral_speed),
            ibm: l(self.ibm, o.ibm),
            interior: l(self.interior, o.interior),
            contact: l(self.contact, o.contact),
        }
    }

    /// The hydrodynamic force along ê.
    fn hydro(&self) -> f64 {
        self.ibm + self.interior
    }
}

/// The set-up at diameter `d`.
struct Setup {
    d: usize,
    g: f64,
    x0: Vec3,
}

impl Setup {
    fn new(d: usize) -> Self {
        let c = 0.5 * (5.0 * d as f64 - 1.0);
        Self { d, g: G12 * (12.0 / d as f64).powi(3), x0: Vec3::new(c, c, d as f64) }
    }

    fn coupling(&self, lubrication: bool) -> Coupled<f64> {
        let (d, df) = (self.d, self.d as f64);
        let mut fluid =
            Fluid::<f64>::new(Grid::new(5 * d, 5 * d, 6 * d), FluidParams::bgk(NU), Boundaries::closed_box())
                .expect("valid set-up");
        fluid.initialize(|_, _, _| (1.0, [0.0; 3]));
        let shape = Arc::new(Sphere::new(df));
        let fixed = RigidBody::new(shape.clone(), GAMMA, Motion::Fixed).with_position(self.x0);
        let x1 = self.x0 + Vec3::z() * (df * (1.0 + GAP0));
        let free = RigidBody::new(shape, GAMMA, Motion::Free).with_position(x1);
        let contacts = ContactParams { lubrication, ..Default::default() };
        let params =
            CouplingParams { gravity: [0.0, 0.0, -self.g], contacts: Some(contacts), ..Default::default() };
        Coupled::new(fluid, vec![fixed, free], params).expect("coupling")
    }

    /// Steps `cp` once and returns the record.
    fn step(&self, cp: &mut Coupled<f64>) -> Sample {
        let b = &cp.bodies()[1];
        let r = b.position - self.x0;
        let e = r / r.norm();
        let (h, v) = (r.norm() - self.d as f64, -b.velocity.dot(&e));
        let lateral = r.xy().norm();
        let lateral_speed = b.velocity.xy().norm();
        cp.step().expect("spheres stay in the box");
        let l = cp.loads(1);
        Sample {
            h,
            v,
            lateral,
            lateral_speed,
            ibm: l.ibm_force.dot(&e),
            interior: l.interior_force.dot(&e),
            contact: l.contact_force.dot(&e),
        }
    }
}

/// Stepping until `rest` steps after the gap first fell below `δ0`.
fn run_to_rest(
    s: &Setup,
    cp: &mut Coupled<f64>,
    samples: &mut Vec<Sample>,
    rest: usize,
    split: bool,
) -> Option<CoupledState<f64>> {
    let mut snap = None;
    let mut arrived: Option<usize> = None;
    let max = 400_000;
    while samples.len() < max {
        let x = s.step(cp);
        samples.push(x);
        if split && snap.is_none() && x.h < H_SPLIT && cp.fluid().time().is_multiple_of(2) {
            snap = Some(cp.snapshot().expect("even step"));
        }
        if arrived.is_none() && x.h < ContactParams::default().delta0 {
            arrived = Some(samples.len());
        }
        if arrived.is_some_and(|a| samples.len() >= a + rest) {
            break;
        }
    }
    snap
}

/// The record interpolated at the first crossing of `h = level` (linear in `h`).
fn at_gap(samples: &[Sample], level: f64) -> Option<Sample> {
    let k = samples.iter().position(|x| x.h <= level)?;
    if k == 0 {
        return Some(samples[0]);
    }
    let (a, b) = (&samples[k - 1], &samples[k]);
    Some(a.lerp(b, (a.h - level) / (a.h - b.h)))
}

/// Both runs at diameter `d`.
struct Outcome {
    on: Vec<Sample>,
    off: Vec<Sample>,
    split: usize,
    weight: Vec3,
    /// End of the lubrication-on run: hydrodynamic and contact force on the free sphere.
    end_hydro: Vec3,
    end_contact: Vec3,
    /// Quick tier: records of the lubrication-off run from step 0 that differ (bitwise) from
    /// the split run; `None` if not run.
    split_mismatch: Option<usize>,
    seconds_on: f64,
    seconds_off: f64,
}

fn outcome(d: usize, check_split: bool) -> Outcome {
    let s = Setup::new(d);
    let df = d as f64;
    let rest = (df * df / NU).round() as usize;
    let t0 = Instant::now();
    let mut on = s.coupling(true);
    let weight = on.bodies()[1].net_weight(Vec3::new(0.0, 0.0, -s.g), 1.0);
    let mut son = Vec::new();
    let snap = run_to_rest(&s, &mut on, &mut son, rest, true).expect("the approach passes h = 2");
    let seconds_on = t0.elapsed().as_secs_f64();
    let split = snap.fluid.time as usize;
    let t1 = Instant::now();
    let mut off = s.coupling(false);
    off.restore(&snap).expect("same set-up");
    let mut soff = son[..split].to_vec();
    run_to_rest(&s, &mut off, &mut soff, rest, false);
    let seconds_off = t1.elapsed().as_secs_f64();
    let split_mismatch = check_split.then(|| {
        let mut full = s.coupling(false);
        let mut sfull = Vec::new();
        while sfull.len() < soff.len() {
            sfull.push(s.step(&mut full));
        }
        let same = |a: &Sample, b: &Sample| {
            [a.h, a.v, a.lateral, a.lateral_speed, a.ibm, a.interior, a.contact]
                .iter()
                .zip([b.h, b.v, b.lateral, b.lateral_speed, b.ibm, b.interior, b.contact])
                .all(|(x, y)| x.to_bits() == y.to_bits())
        };
        sfull.iter().zip(&soff).filter(|(a, b)| !same(a, b)).count()
    });
    let l = on.loads(1);
    Outcome {
        on: son,
        off: soff,
        split,
        weight,
        end_hydro: l.force(),
        end_contact: l.contact_force,
        split_mismatch,
        seconds_on,
        seconds_off,
    }
}

/// A one-sided check `value < bound` (strict).
fn below(metric: &str, value: f64, bound: f64, reason: &str) -> Check {
    Check {
        case: CASE.into(),
        metric: metric.into(),
        value,
        expected: Value::Text(format!("< {bound}")),
        tolerance: Value::Text(format!("< {bound}")),
        pass: value.is_finite() && value < bound,
        reason: reason.into(),
    }
}

/// Runs the case.
pub fn run(tier: Tier) -> CaseOutput {
    let mut out = CaseOutput { has_ref: true, ..Default::default() };
    let d = if tier == Tier::Quick { 6 } else { 12 };
    let df = d as f64;
    let g = Setup::new(d).g;
    let o = outcome(d, tier == Tier::Quick);
    let delta0 = ContactParams::default().delta0;
    let delta_sat = ContactParams::default().delta_sat;
    let vmax = o.on.iter().map(|x| x.v).fold(0.0, f64::max);
    let a = 0.5 * df;
    // Drag far from contact: the net weight over the largest approach speed (quasi-steady).
    let r_far = o.weight.norm() / vmax;
    let mut t = Table::new(
        format!(
            "approach d={d} g={g:e} gamma=1.25 bgk nu=0.05, lubrication on/off: speed over v_max, \
             resistances (force/v along the line of centres), lubrication asymptote R_lub = (3 pi/2) mu a^2/h"
        ),
        &[
            ("h", true),
            ("v_on_over_vmax", true),
            ("v_off_over_vmax", true),
            ("R_hydro_on", true),
            ("R_contact_on", true),
            ("R_hydro_off", true),
            ("R_lub", true),
            ("ratio_on", true),
            ("ratio_off", true),
            ("excess_ratio_on", true),
            ("excess_ratio_off", true),
        ],
    );
    for lv in LEVELS {
        let (Some(x), Some(y)) = (at_gap(&o.on, lv), at_gap(&o.off, lv)) else { continue };
        let r_lub = 1.5 * std::f64::consts::PI * NU * a * a / lv;
        let (r_on, r_off) = ((x.hydro() + x.contact) / x.v, (y.hydro() + y.contact) / y.v);
        t.push(vec![
            lv,
            x.v / vmax,
            y.v / vmax,
            x.hydro() / x.v,
            x.contact / x.v,
            y.hydro() / y.v,
            r_lub,
            r_on / r_lub,
            r_off / r_lub,
            (r_on - r_far) / r_lub,
            (r_off - r_far) / r_lub,
        ]);
    }
    out.tables.push(t);

    let v_on = at_gap(&o.on, delta0).map_or(f64::NAN, |x| x.v);
    let v_off = at_gap(&o.off, delta0).map_or(f64::NAN, |x| x.v);
    let hmin_on = o.on.iter().map(|x| x.h).fold(f64::INFINITY, f64::min);
    let hmin_off = o.off.iter().map(|x| x.h).fold(f64::INFINITY, f64::min);
    let end = o.on.last().expect("steps were run");
    let balance = (o.end_hydro + o.end_contact + o.weight).norm() / o.weight.norm();
    let lateral_contact = o.end_contact.xy().norm() / o.weight.norm();
    let contact_before_split = o.on[..o.split].iter().map(|x| x.contact.abs()).fold(0.0, f64::max);
    let mut t = Table::new(
        format!("summary d={d}: arrival at h = delta0 = {delta0}, closest approach, rest"),
        &[
            ("d", true),
            ("g", true),
            ("v_max", true),
            ("Re_p", true),
            ("split_step", true),
            ("steps_on", true),
            ("steps_off", true),
            ("v_delta0_on_over_vmax", true),
            ("v_delta0_off_over_vmax", true),
            ("h_min_on", true),
            ("h_min_off", true),
            ("h_end", true),
            ("v_normal_end_over_vmax", true),
            ("lateral_offset_end", true),
            ("lateral_speed_end_over_vmax", true),
            ("lateral_contact_over_weight", true),
            ("balance_residual", true),
            ("seconds_on", false),
            ("seconds_off", false),
        ],
    );
    t.push(vec![
        df,
        g,
        vmax,
        vmax * df / NU,
        o.split as f64,
        o.on.len() as f64,
        o.off.len() as f64,
        v_on / vmax,
        v_off / vmax,
        hmin_on,
        hmin_off,
        end.h,
        end.v / vmax,
        end.lateral,
        end.lateral_speed / vmax,
        lateral_contact,
        balance,
        o.seconds_on,
        o.seconds_off,
    ]);
    out.tables.push(t);

    out.checks.push(Check::exact(
        CASE,
        "contact_zero_before_split",
        contact_before_split,
        0.0,
        "the lubrication-off run starts from the lubrication-on run's state at h < 2: exact only if \
         no contact load acted before (no marker pair within delta_d = 1)",
    ));
    if let Some(m) = o.split_mismatch {
        out.checks.push(Check::exact(
            CASE,
            "split_equals_full_run",
            m as f64,
            0.0,
            "quick tier: the lubrication-off run from step 0 equals the split run bitwise, step \
             by step (Coupled::restore continues bitwise; the contact loads were zero before)",
        ));
    }
    out.checks.push(below(
        "arrival_speed_over_max",
        v_on / vmax,
        0.5,
        "the approach speed at h = delta0 (where the spring starts) is at least halved: resolved \
         squeeze flow (lubrication-off arrival reported) plus the lubrication model; the \
         asymptote alone with the unbounded Stokes drag gives 1/(1 + a/(4 delta0)) = 0.4 (d = 6), \
         0.25 (d = 12)",
    ));
    out.checks.push(below(
        "arrival_speed_on_over_off",
        v_on / v_off,
        1.0,
        "the lubrication model (k_n = 5, k_t = 0.5 from delta_d = 1) adds resistance to the \
         resolved squeeze flow: with it the sphere arrives at h = delta0 slower than with the \
         elastic part alone",
    ));
    out.checks.push(Check::at_least(
        CASE,
        "min_gap_no_overlap",
        hmin_on.min(hmin_off),
        0.0,
        0.0,
        "the spheres never overlap (both runs): min over the run of |x1 - x0| - d",
    ));
    out.checks.push(Check::at_least(
        CASE,
        "min_gap_lubricated_vs_delta_sat",
        hmin_on,
        delta_sat,
        delta_sat,
        "with lubrication the surfaces stay outside the saturation distance delta_sat = 0.2 (the \
         settled gap is set by the spring: net weight / (k sum w) below delta0 = 0.5)",
    ));
    out.checks.push(Check::at_most(
        CASE,
        "rest_force_balance",
        balance,
        0.01,
        "at rest the contact force carries the net weight minus the hydrodynamic force: \
         |F_contact + F_hydro + W|/|W| after one viscous time d^2/nu past arrival (the body's \
         acceleration and the implicit shell correction vanish in a steady state); 1 %",
    ));
    out.checks.push(Check::at_most(
        CASE,
        "rest_normal_speed_over_vmax",
        end.v.abs() / vmax,
        0.01,
        "the approach has stopped: normal speed one viscous time d^2/nu past arrival below 1 % \
         of the largest approach speed (what remains is the creep that follows the lateral \
         slide, reported)",
    ));
    out
}
