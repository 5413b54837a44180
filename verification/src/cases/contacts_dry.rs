//! # Dry contacts: collisions without fluid (the contact model of Table 1 alone)
//!
//! **What.** `slurry::contact` (Derksen 2020, Table 1, between surface markers; module doc
//! there) with the default parameters and the default number of sub-steps
//! (`DEFAULT_SUBSTEPS`), advanced by `Contacts::advance` (position-Verlet sub-cycling), no
//! fluid, no gravity. Bodies of density ratio `γ = 1.25` (the paper's), spheres of diameter
//! `d` and cylinders `ℓ = d`, at the half scale `d = 6` and the paper's `d = 12`. Surfaces start
//! `1.2` apart (just outside `δ_d = 1`), body 0 moving at the impact speed, body 1 at rest.
//!
//! Setups: `sphere_head_on`; `sphere_oblique` (line of centres at 30° to the motion);
//! `cylinder_side` (parallel axes, mantle on mantle); `cylinder_end` (coaxial, cap on cap,
//! markers aligned: the stiffest contact); `wall_flat`, `wall_side`, `wall_edge` (a cylinder
//! falling onto the floor cap down, mantle down, and tilted by 45°, rim first). Impact speeds
//! 0.01 … 0.104 (0.104 = π D N, the paper's impeller tip speed, the fastest impact to expect);
//! the full tier adds 0.005, 0.035, 0.075.
//!
//! **Checks (metric, tolerance, why).**
//! - `momentum_conservation`: `max_t |P(t) − P(0)|/|P(0)|` over every two-body run and every
//!   sub-step. ≤ 1e-13: each marker pair applies `+f` and `−f` to its two bodies in the same
//!   sub-step, so `Σ m v` changes only by round-off (≈ 1e-16 per update, a few 10³ sub-steps);
//!   a force applied to one side only, or on different sub-steps, gives O(1e-2).
//! - `elastic_ke_change_normal_impacts`: lubrication off, `|KE(end) − KE(0)|/KE(0)` after
//!   the bodies separate, worst over the normal impacts (every setup but `sphere_oblique`).
//!   ≤ 1 %: the position-Verlet sub-steps are symplectic for the spring (no drift through a
//!   contact), and a head-on path is retraced on the way out, so the elastic work in equals the
//!   work out to `O(h²)`; measured ≤ 0.34 %.
//! - **Known deviation (reported, not checked): oblique elastic impacts do not conserve KE**
//!   (table `elastic only`, setup 1: at `d = 6` the spheres lose 3–17 % of it, most at
//!   0.02–0.05; at `d = 12` it changes by −0.4 … +1.6 %; full tier). The elastic force of Table 1,
//!   `−k(δ0 − δ) w n̂`, is not the gradient of a potential: `w` (tangential distance) and `n̂`
//!   (marker normals) change along a sliding path, and the missing terms
//!   `½ k (δ0 − δ)² ∇w`, … do net work as marker pairs slide past each other. It is the model,
//!   not the integration: the change is the same to 1e-4 for 4, 8, 16, 32 sub-steps.
//! - `dissipation_lubricated`: with lubrication, `KE(0) − KE(end) ≥ 0` for every run (the
//!   lubrication power `−(kⁿ|Δuⁿ|² + kᵗ|Δuᵗ|²)(1/δ* − 1/δ_d) w` is never positive). No
//!   tolerance.
//! - `energy_never_exceeds_initial`: with lubrication, `max_t (E(t) − E(0))/E(0)`,
//!   `E = KE + Σ ½ k (δ0 − δ)² w` (the elastic energy stored in the interacting pairs), checked
//!   after every sub-step of every run. ≤ 1e-12 (measured: 0): the lubrication acts from
//!   `δ_d = 1`, before the spring (`δ0 = 0.5`) stores anything, and only removes energy.
//! - **Known deviation (reported in the `energy_rise` column, not checked): `E` is not
//!   monotone sub-step by sub-step.** Single sub-steps raise `E` by up to 8.5e-4 `E(0)`
//!   (`cylinder_side`, `d = 12`, 0.075; full tier), erratically in the number of sub-steps
//!   (1.9e-6, 8.5e-4, 2.4e-4, 6.5e-4 for 4, 8, 16, 32): not the integration but the model, whose
//!   elastic force is not the gradient of the stored energy (above) and whose pairs switch on
//!   with a finite force when `n_i·n_j` crosses 0.
//! - `closest_approach`: the smallest signed distance of any marker of one body to the other
//!   body's surface (its `signed_distance` in its own frame) or to the wall, over every
//!   sub-step in contact, worst over the runs: ≥ `δ_sat = 0.2` (the saturation distance: closer
//!   than that the lubrication stops growing). Runs: every setup at `d = 6`; at `d = 12` the
//!   flat and line contacts at every speed, the point and edge contacts (spheres, rim on the
//!   wall) below 0.05.
//! - **Known deviation (reported in table `point and edge impacts`, not checked): with Table
//!   1's parameters, point and edge impacts of `d = 12` bodies at ≥ 0.05 come closer than
//!   `δ_sat`:** spheres head-on 0.246 (0.05), 0.164 (0.075), 0.086 (0.104), oblique 0.206 and
//!   0.137 at 0.075 and 0.104; a cylinder rim first on the wall 0.154 (0.05), 0.035 (0.075) and
//!   −0.081 at the tip speed 0.104 (the rim crosses the wall plane). The kinetic energy
//!   `½ m u²` grows as `d³` while the contact area near a point or an edge (and so the
//!   lubrication and spring force) grows as `d`; flat and line contacts stop at 0.37–0.75.
//!   Converged in the number of sub-steps (4 … 32 agree to 3e-3): a property of the
//!   parameters, not of the integration. In the liquid the resolved lubrication slows the
//!   approach before contact, so this dry test is the worst case.
//! - `saturated_amplification_matches_analysis`: the stability analysis (module doc of
//!   `slurry::contact`) in its exact form. Two cylinders cap on cap (markers aligned) or a
//!   cylinder cap down on the wall, surfaces `0.1` apart (inside `δ_sat`), elastic part off,
//!   relative normal velocity `u0 = 1e-10` (the two bodies at `±u0/2`: zero centre-of-mass
//!   velocity, so that `u` is not a small difference of large velocities). The motion is
//!   normal, so `δ_λ` and `w` stay fixed, and every cap pair is saturated: the damping is linear
//!   with a constant `c` (`= −∂F/∂u`, measured from one evaluation), and per sub-step
//!   `u ← (1 − c h/m_red) u`. Metric: `|g/g_pred − 1|` with `g = u(1)/u(0)` after one fluid
//!   step, `g_pred = (1 − c h/m_red)^{n_sub}`, for `n_sub = 4, 8, 16`. ≤ 1e-9: the few rim–cap
//!   cross pairs are not saturated and their coefficient moves with the gap, by `O(u0)` over
//!   the step (2e-5 at `u0 = 1e-4`, 2e-11 here), plus round-off of ≤ 16 updates. The table shows
//!   `n_sub = 4` unstable for the aligned caps at `d = 6` (`|g| = 7.9 > 1`).
//! - `saturated_stability_d6`, `saturated_monotone_d12`: at the default `n_sub`, the largest
//!   `b = c h/m_red` of these contacts: `< 2` at `d = 6` (explicit Euler damping stable) and
//!   `≤ 1` at `d = 12` (monotone: the relative velocity never reverses).
//! - `limiter_saturated_stable`, `limiter_saturated_monotone`: the same saturated contacts with
//!   the opt-in lubrication limiter (`[contacts] lubrication_limiter`, module doc of
//!   `slurry::contact`, "Lubrication limiter") at `n_sub = 1, 2, 4`, where the explicit law has
//!   `b` up to 10.7 (`|g| > 1`): the per-step amplification must satisfy `0 ≤ g < 1` (stable and monotone).
//!   Each sub-step removes at most `IMPLICIT_LIMIT = 0.9` of the relative velocity the contact
//!   sees, so `g ≥ 0.1^{n_sub} > 0`; `g < 1 − 1e-6` asks that the damping acts at all.
//! - **Lubrication sub-steps** (`[contacts] lubrication_substeps`, module doc of
//!   `slurry::contact`, "Lubrication sub-steps"): every lubricated collision again with 2
//!   contact sub-steps of 4 lubrication sub-steps each (the same 8 damping steps per fluid step
//!   as the default, a quarter of the marker-pair evaluations). `lub_substeps_momentum_conservation`
//!   (≤ 1e-13), `lub_substeps_dissipation_lubricated` (≥ 0), `lub_substeps_energy_never_exceeds_initial`
//!   (≤ 1e-12) and `lub_substeps_closest_approach` (≥ `δ_sat`): as above, for the same reasons
//!   (the frozen operators are symmetric and positive semi-definite in the relative velocity).
//!   `lub_substeps_restitution_change`: `max |e − e_default|` ≤ 1e-3 (measured 2.0e-4) and
//!   `lub_substeps_closest_change`: `max |closest − closest_default|` ≤ 3e-3 (measured 1.0e-3;
//!   3e-3 is the spread of the default scheme's own closest approach over 4 … 32 sub-steps):
//!   the elastic load is held over a contact sub-step of 1/2 instead of 1/8 and the lubrication's
//!   geometry frozen over it, so the outcome moves, but by less than the default's own
//!   sub-step sensitivity. `lub_substeps_saturated_amplification`: the saturated contacts above
//!   with `n_sub × m_lub` = 1 × 8, 2 × 4, 2 × 8, 4 × 4: the per-step amplification is
//!   `(1 − c h/m_red)^{n_sub m_lub}`, `h = 1/(n_sub m_lub)`, to 1e-9 (measured 1.7e-10): the
//!   operator is the law's exact linearisation, so the damping's stability is that of the
//!   explicit law at the lubrication sub-step.
//!
//! **Tables.** Restitution `e = −u_n(end)/u_n(0)` (`u_n` the approach velocity along the
//! contact normal: the line of centres for spheres, at first touch and at the end; the
//! approach direction otherwise; `e = 0` if the bodies end stuck, i.e. still in contact with a
//! kinetic energy of relative motion below 1e-10 of the initial), closest approach, and the
//! energy and momentum metrics, per setup and speed. Compared with
//! `verification/ref/contacts_dry-<tier>.ref` (bitwise deterministic; the runs are smooth, so
//! libm differences across platforms stay at the 1e-12 level).
//!
//! **Cost (reported, not checked; columns `config`, `threads`, `bodies` compared).** One
//! `Contacts::compute`, one thread, minimum of 200 calls: `d = 12`, `ℓ = d` cylinders side by
//! side, cap on cap, cap on the wall, mantle on the wall, surfaces 0.5 apart. Full tier, also:
//! 100 such cylinders with random orientations on a jittered lattice in a closed 90 × 90 × 80
//! box, settled for 3000 steps under net weight (`g = 2e-3`) with a linear drag (terminal speed
//! 0.05, a stand-in for the fluid; rotational drag `36 ×` that) by `Contacts::advance` (a loose
//! bed, `φ ≈ 0.36` below its top, still spreading slowly: frictionless cylinders), then one
//! evaluation with 1 and 2 threads (minimum of 7).

use std::sync::Arc;
use std::time::Instant;

use rayon::prelude::*;
use slurry::contact::{ContactParams, Contacts, Walls, DEFAULT_SUBSTEPS};
use slurry::rigid::{Cylinder, Marker, Motion, Quat, RigidBody, Shape, Sphere, Vec3, DEFAULT_MARKER_SPACING};
use slurry::util::SplitMix64;

use crate::{CaseOutput, Check, Table, Tier};

const CASE: &str = "contacts_dry";
/// Density ratio of the paper's particles.
const GAMMA: f64 = 1.25;
/// Initial surface gap: just outside the lubrication range `δ_d = 1`.
const GAP0: f64 = 1.2;
/// The lubrication sub-step scheme checked against the default: 2 contact sub-steps of 4
/// lubrication sub-steps each (8 damping steps per fluid step, as the default's 8 sub-steps,
/// with a quarter of the marker-pair evaluations).
const LUB_SCHEME: (usize, usize) = (2, 4);
/// Tolerance of the change of a lubricated collision's restitution under [`LUB_SCHEME`]
/// (module doc; measured 2.0e-4 in the quick tier).
const LUB_RESTITUTION_TOL: f64 = 1e-3;
/// Tolerance of the change of its closest approach: the spread of the default scheme's own
/// closest approach over 4 … 32 sub-steps (3e-3, module doc; measured 1.0e-3).
const LUB_CLOSEST_TOL: f64 = 3e-3;
/// The impeller tip speed of the paper (`π D N = π · 132/4000`), the fastest impact expected.
pub const TIP_SPEED: f64 = 0.104;

/// The collision configurations.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Setup {
    /// Two spheres, head-on along x (one at rest).
    SphereHeadOn,
    /// Two spheres, line of centres at 30° to the motion.
    SphereOblique,
    /// Two cylinders `ℓ = d`, parallel axes (z), approaching along x: mantle on mantle.
    CylinderSide,
    /// Two coaxial cylinders `ℓ = d` approaching along their axis: cap on cap, markers
    /// aligned (the stiffest contact).
    CylinderEnd,
    /// A cylinder falling onto the floor with its cap down.
    WallFlat,
    /// A cylinder falling onto the floor on its mantle.
    WallSide,
    /// A cylinder tilted by 45° falling onto the floor rim first.
    WallEdge,
}

impl Setup {
    /// Every setup, in table order (the `setup` column is the index here).
    pub const ALL: [Setup; 7] = [
        Setup::SphereHeadOn,
        Setup::SphereOblique,
        Setup::CylinderSide,
        Setup::CylinderEnd,
        Setup::WallFlat,
        Setup::WallSide,
        Setup::WallEdge,
    ];

    /// Name for tables and metrics.
    pub fn name(self) -> &'static str {
        match self {
            Setup::SphereHeadOn => "sphere_head_on",
            Setup::SphereOblique => "sphere_oblique",
            Setup::CylinderSide => "cylinder_side",
            Setup::CylinderEnd => "cylinder_end",
            Setup::WallFlat => "wall_flat",
            Setup::WallSide => "wall_side",
            Setup::WallEdge => "wall_edge",
        }
    }

    fn is_sphere(self) -> bool {
        matches!(self, Setup::SphereHeadOn | Setup::SphereOblique)
    }

    fn index(self) -> f64 {
        Setup::ALL.iter().position(|&s| s == self).unwrap_or(0) as f64
    }
}

/// Bodies, markers and walls of one scene.
struct Scene {
    bodies: Vec<RigidBody>,
    markers: Vec<Vec<Marker>>,
    walls: Walls,
    /// Approach direction (from body 0 toward body 1 or the wall).
    normal: Vec3,
}

fn floor() -> Walls {
    Walls { planes: [[None, None], [None, None], [Some(0.0), None]] }
}

fn free_body(shape: Arc<dyn Shape>, pos: Vec3, q: Quat, v: Vec3) -> (RigidBody, Vec<Marker>) {
    let m = shape.markers(DEFAULT_MARKER_SPACING);
    let b = RigidBody::new(shape, GAMMA, Motion::Free).with_position(pos).with_orientation(q);
    (b.with_velocities(v, Vec3::zeros()), m)
}

/// The scene of `setup` at diameter `d` (`ℓ = d` for cylinders), body 0 moving at `speed`
/// toward body 1 (at rest) or the floor, surfaces `gap` apart.
fn scene(setup: Setup, d: f64, speed: f64, gap: f64) -> Scene {
    scene_with_length(setup, d, d, speed, gap)
}

/// [`scene`] with cylinders of length `length`.
fn scene_with_length(setup: Setup, d: f64, length: f64, speed: f64, gap: f64) -> Scene {
    let sphere = || Arc::new(Sphere::new(d)) as Arc<dyn Shape>;
    let cyl = || Arc::new(Cylinder::new(d, length)) as Arc<dyn Shape>;
    let id = Quat::identity();
    let two = |s: Arc<dyn Shape>, p1: Vec3, dir: Vec3| {
        let (a, ma) = free_body(s.clone(), Vec3::zeros(), id, dir * speed);
        let (b, mb) = free_body(s, p1, id, Vec3::zeros());
        Scene { bodies: vec![a, b], markers: vec![ma, mb], walls: Walls::none(), normal: dir }
    };
    match setup {
        Setup::SphereHeadOn => two(sphere(), Vec3::x() * (d + gap), Vec3::x()),
        Setup::SphereOblique => {
            let (s, c) = std::f64::consts::FRAC_PI_6.sin_cos();
            two(sphere(), Vec3::new(c, s, 0.0) * (d + gap), Vec3::x())
        }
        Setup::CylinderSide => two(cyl(), Vec3::x() * (d + gap), Vec3::x()),
        Setup::CylinderEnd => two(cyl(), Vec3::z() * (d + gap), Vec3::z()),
        Setup::WallFlat | Setup::WallSide | Setup::WallEdge => {
            let q = match setup {
                Setup::WallFlat => id,
                Setup::WallSide => Quat::from_axis_angle(&Vec3::x_axis(), std::f64::consts::FRAC_PI_2),
                _ => Quat::from_axis_angle(&Vec3::x_axis(), std::f64::consts::FRAC_PI_4),
            };
            let (mut a, ma) = free_body(cyl(), Vec3::zeros(), q, -Vec3::z() * speed);
            let low = ma.iter().map(|m| a.to_world(&m.position).z).fold(f64::INFINITY, f64::min);
            a.position.z = gap - low;
            Scene { bodies: vec![a], markers: vec![ma], walls: floor(), normal: -Vec3::z() }
        }
    }
}

/// What one collision measured.
#[derive(Clone, Copy, Debug)]
pub struct Outcome {
    /// Restitution coefficient (module doc); 0 if the bodies end stuck.
    pub restitution: f64,
    /// Whether the bodies separated (no interacting pair left) before the run ended.
    pub separated: bool,
    /// `max_t |P(t) − P(0)|/|P(0)|` (two bodies; 0 for a wall run).
    pub momentum_err: f64,
    /// `(KE(end) − KE(0))/KE(0)`.
    pub ke_change: f64,
    /// Largest increase of `E = KE + U_el` over one sub-step, relative to `E(0)`.
    pub energy_rise: f64,
    /// `max_t (E(t) − E(0))/E(0)` over every sub-step.
    pub energy_excess: f64,
    /// Closest approach of a marker to the other body's surface or to the wall.
    pub closest: f64,
    /// Fluid steps run.
    pub steps: usize,
}

/// Kinetic energy of the motion relative to the centre of mass (all of it for one body
/// against a wall).
fn relative_ke(bs: &[RigidBody]) -> f64 {
    let ke: f64 = bs.iter().map(|b| b.kinetic_energy()).sum();
    if bs.len() == 1 {
        return ke;
    }
    let p: Vec3 = bs.iter().map(|b| b.linear_momentum()).sum();
    let m: f64 = bs.iter().map(|b| b.mass()).sum();
    ke - 0.5 * p.norm_squared() / m
}

/// Runs `setup` at `speed` with `params` and `n_sub` sub-steps per fluid step.
pub fn collide(setup: Setup, d: f64, speed: f64, params: ContactParams, n_sub: usize) -> Outcome {
    let Scene { mut bodies, markers, walls, normal } = scene(setup, d, speed, GAP0);
    let mut ct = Contacts::new(params, walls, &bodies, &markers).expect("valid parameters");
    let mut diag = Contacts::new(params, walls, &bodies, &markers).expect("valid parameters");
    let momentum = |bs: &[RigidBody]| bs.iter().map(|b| b.linear_momentum()).sum::<Vec3>();
    let energy = |bs: &[RigidBody]| bs.iter().map(|b| b.kinetic_energy()).sum::<f64>();
    let approach = |bs: &[RigidBody], n: &Vec3| {
        let dv = if bs.len() == 2 { bs[0].velocity - bs[1].velocity } else { bs[0].velocity };
        dv.dot(n)
    };
    let centres = |bs: &[RigidBody]| (bs[1].position - bs[0].position).normalize();
    let (p0, e0, ke_rel0) = (momentum(&bodies), energy(&bodies), relative_ke(&bodies));
    let mut u0 = approach(&bodies, &normal);
    let mut touched = false;
    let (mut momentum_err, mut energy_rise, mut closest) = (0.0f64, f64::NEG_INFINITY, f64::INFINITY);
    let mut energy_excess = f64::NEG_INFINITY;
    let mut e_prev = e0;
    let max_steps = (3.0 / speed).ceil() as usize + 400;
    let (mut steps, mut separated, mut stuck) = (0, false, false);
    while steps < max_steps && !separated && !stuck {
        let mut in_contact = false;
        ct.advance_with(&mut bodies, &markers, n_sub, |_, bs, _| {
            diag.compute(bs, &markers);
            let st = *diag.stats();
            let e = energy(bs) + st.elastic_energy;
            energy_rise = energy_rise.max((e - e_prev) / e0);
            energy_excess = energy_excess.max((e - e0) / e0);
            e_prev = e;
            momentum_err = momentum_err.max((momentum(bs) - p0).norm() / p0.norm());
            if st.marker_pairs + st.wall_contacts > 0 {
                if !touched && setup.is_sphere() {
                    u0 = approach(bs, &centres(bs));
                }
                touched = true;
                in_contact = true;
                closest = closest.min(closest_approach(bs, &markers, &walls));
            }
        });
        steps += 1;
        separated = touched && !in_contact;
        stuck = in_contact && relative_ke(&bodies) < 1e-10 * ke_rel0;
    }
    let n_end = if setup.is_sphere() { centres(&bodies) } else { normal };
    Outcome {
        restitution: if separated { -approach(&bodies, &n_end) / u0 } else { 0.0 },
        separated,
        momentum_err: if bodies.len() == 2 { momentum_err } else { 0.0 },
        ke_change: (energy(&bodies) - e0) / e0,
        energy_rise,
        energy_excess,
        closest,
        steps,
    }
}

/// The smallest signed distance of any marker of one body to another body's surface (each in
/// the other's body frame), or of any marker to a wall.
fn closest_approach(bodies: &[RigidBody], markers: &[Vec<Marker>], walls: &Walls) -> f64 {
    let mut best = f64::INFINITY;
    for (a, ba) in bodies.iter().enumerate() {
        for m in &markers[a] {
            let x = ba.to_world(&m.position);
            for (b, bb) in bodies.iter().enumerate() {
                if b != a {
                    best = best.min(bb.signed_distance(&x));
                }
            }
            for (axis, side, plane, _) in walls.iter() {
                best = best.min(if side == 0 { x[axis] - plane } else { plane - x[axis] });
            }
        }
    }
    best
}

/// Impact speeds of the study.
pub fn speeds(tier: Tier) -> Vec<f64> {
    match tier {
        Tier::Quick => vec![0.01, 0.02, 0.05, TIP_SPEED],
        Tier::Full => vec![0.005, 0.01, 0.02, 0.035, 0.05, 0.075, TIP_SPEED],
    }
}

/// The runs where Table 1 does not keep the closest approach above `δ_sat` (module doc).
fn known_deviation(setup: Setup, d: f64, speed: f64) -> bool {
    d > 6.0 && (setup.is_sphere() || setup == Setup::WallEdge) && speed >= 0.05
}

/// The saturated-damping measurement of `saturated_amplification_matches_analysis` (and, with
/// `limiter`, of `limiter_saturated_stable_monotone`): returns `(c, m_red, g, g_pred)`, `g_pred`
/// the explicit law's amplification.
fn saturated(setup: Setup, d: f64, n_sub: usize, limiter: bool) -> (f64, f64, f64, f64) {
    saturated_with(setup, d, n_sub, 1, limiter)
}

/// [`saturated`] with `m_lub` lubrication sub-steps per contact sub-step (module doc of
/// `slurry::contact`, "Lubrication sub-steps"): `g_pred = (1 − c h/m_red)^{n_sub m_lub}` with
/// `h = 1/(n_sub m_lub)`, the explicit law's amplification at that step.
fn saturated_with(setup: Setup, d: f64, n_sub: usize, m_lub: usize, limiter: bool) -> (f64, f64, f64, f64) {
    let u0 = 1e-10;
    let Scene { mut bodies, markers, walls, normal } = scene(setup, d, u0, 0.1);
    if bodies.len() == 2 {
        // Opposite velocities: zero centre-of-mass velocity, so that the relative velocity is
        // not measured as a small difference of two large ones.
        bodies[0].velocity = normal * (0.5 * u0);
        bodies[1].velocity = -normal * (0.5 * u0);
    }
    let params = ContactParams { elastic: false, lubrication_limiter: limiter, ..Default::default() };
    let mut ct = Contacts::new(params, walls, &bodies, &markers).expect("valid parameters");
    let c = -ct.compute(&bodies, &markers)[0].force.dot(&normal) / u0;
    if m_lub > 1 {
        let params = ContactParams { lubrication_substeps: m_lub, ..params };
        ct = Contacts::new(params, walls, &bodies, &markers).expect("valid parameters");
    }
    let m_red = if bodies.len() == 2 {
        bodies[0].mass() * bodies[1].mass() / (bodies[0].mass() + bodies[1].mass())
    } else {
        bodies[0].mass()
    };
    let rel = |bs: &[RigidBody]| {
        (if bs.len() == 2 { bs[0].velocity - bs[1].velocity } else { bs[0].velocity }).dot(&normal)
    };
    let before = rel(&bodies);
    ct.advance(&mut bodies, &markers, n_sub);
    let g = rel(&bodies) / before;
    let steps = n_sub * m_lub;
    let g_pred = (1.0 - c / (m_red * steps as f64)).powi(steps as i32);
    (c, m_red, g, g_pred)
}

/// The saturated contact of `setup` (cylinders of diameter `d` and length `length`, surfaces
/// 0.1 apart, relative normal velocity 1e-10) under `params` with the elastic part off:
/// `(c, m_red, g)`, `c = −∂F/∂u` from one evaluation of the explicit law, `m_red` the reduced
/// mass, `g` the relative velocity's amplification over one fluid step of `n_sub` sub-steps
/// (module doc, `saturated_amplification_matches_analysis`; the case `implicit_damping`).
pub fn saturated_scheme(
    setup: Setup,
    d: f64,
    length: f64,
    n_sub: usize,
    params: ContactParams,
) -> (f64, f64, f64) {
    let u0 = 1e-10;
    let Scene { mut bodies, markers, walls, normal } = scene_with_length(setup, d, length, u0, 0.1);
    if bodies.len() == 2 {
        bodies[0].velocity = normal * (0.5 * u0);
        bodies[1].velocity = -normal * (0.5 * u0);
    }
    let law = ContactParams { elastic: false, ..Default::default() };
    let mut ct = Contacts::new(law, walls, &bodies, &markers).expect("valid parameters");
    let c = -ct.compute(&bodies, &markers)[0].force.dot(&normal) / u0;
    let params = ContactParams { elastic: false, ..params };
    let mut ct = Contacts::new(params, walls, &bodies, &markers).expect("valid parameters");
    let m_red = if bodies.len() == 2 {
        bodies[0].mass() * bodies[1].mass() / (bodies[0].mass() + bodies[1].mass())
    } else {
        bodies[0].mass()
    };
    let rel = |bs: &[RigidBody]| {
        (if bs.len() == 2 { bs[0].velocity - bs[1].velocity } else { bs[0].velocity }).dot(&normal)
    };
    let before = rel(&bodies);
    ct.advance(&mut bodies, &markers, n_sub);
    (c, m_red, rel(&bodies) / before)
}

/// Runs the case.
pub fn run(tier: Tier) -> CaseOutput {
    let mut out = CaseOutput { has_ref: true, ..Default::default() };
    let speeds = speeds(tier);
    let lub = ContactParams::default();
    let dry = ContactParams { lubrication: false, ..Default::default() };
    let sizes = [6.0, 12.0];
    let mut jobs: Vec<(f64, Setup, f64, bool)> = Vec::new();
    for d in sizes {
        for s in Setup::ALL {
            for lubricated in [true, false] {
                jobs.extend(speeds.iter().map(|&v| (d, s, v, lubricated)));
            }
        }
    }
    let res: Vec<Outcome> = jobs
        .par_iter()
        .map(|&(d, s, v, l)| collide(s, d, v, if l { lub } else { dry }, DEFAULT_SUBSTEPS))
        .collect();

    let (mut mom, mut ke_normal, mut excess, mut min_loss) =
        (0.0f64, 0.0f64, f64::NEG_INFINITY, f64::INFINITY);
    let mut closest_ok = f64::INFINITY;
    let mut dev = Table::new(
        "point and edge impacts at d = 12, speed >= 0.05: closest approach (known deviation where below delta_sat = 0.2)",
        &[("d", true), ("setup", true), ("speed", true), ("closest", true)],
    );
    for d in sizes {
        let mut t = Table::new(
            format!(
                "d={d} l=d gamma=1.25 n_sub={DEFAULT_SUBSTEPS}, lubricated: restitution and closest approach"
            ),
            &[
                ("setup", true),
                ("speed", true),
                ("restitution", true),
                ("separated", true),
                ("closest", true),
                ("ke_change", true),
                ("energy_rise", false),
                ("momentum_err", false),
                ("steps", true),
            ],
        );
        let mut te = Table::new(
            format!("d={d} l=d gamma=1.25 n_sub={DEFAULT_SUBSTEPS}, elastic only: kinetic energy through a contact"),
            &[("setup", true), ("speed", true), ("restitution", true), ("ke_change", true), ("closest", true)],
        );
        for (&(dd, s, v, l), o) in jobs.iter().zip(&res) {
            if dd != d {
                continue;
            }
            mom = mom.max(o.momentum_err);
            if l {
                t.push(vec![
                    s.index(),
                    v,
                    o.restitution,
                    o.separated as u8 as f64,
                    o.closest,
                    o.ke_change,
                    o.energy_rise,
                    o.momentum_err,
                    o.steps as f64,
                ]);
                excess = excess.max(o.energy_excess);
                min_loss = min_loss.min(-o.ke_change);
                if known_deviation(s, d, v) {
                    dev.push(vec![d, s.index(), v, o.closest]);
                } else {
                    closest_ok = closest_ok.min(o.closest);
                }
            } else {
                te.push(vec![s.index(), v, o.restitution, o.ke_change, o.closest]);
                if s != Setup::SphereOblique {
                    ke_normal = ke_normal.max(o.ke_change.abs());
                }
            }
        }
        out.tables.push(t);
        out.tables.push(te);
    }
    out.tables.push(dev);
    out.checks.push(Check::at_most(
        CASE,
        "momentum_conservation",
        mom,
        1e-13,
        "each marker pair applies +f and -f to its two bodies in the same sub-step: sum m v \
         changes by round-off only (1e-16 per update); a one-sided force gives O(1e-2)",
    ));
    out.checks.push(Check::at_most(
        CASE,
        "elastic_ke_change_normal_impacts",
        ke_normal,
        0.01,
        "lubrication off: position-Verlet sub-steps are symplectic for the spring and a normal \
         impact retraces its path, so KE returns to O(h^2); measured <= 0.34 %. Oblique impacts \
         are a known deviation of the model (non-conservative elastic force), see the doc",
    ));
    lubricated_checks(&mut out, "", min_loss, excess, closest_ok);

    // Stability at saturation.
    let mut saturation = Table::new(
        "saturated lubrication (elastic off, gap 0.1): per-step amplification of the relative normal velocity",
        &[
            ("d", true),
            ("setup", true),
            ("c", true),
            ("m_red", true),
            ("n_sub", true),
            ("b", true),
            ("g", true),
            ("g_pred", true),
        ],
    );
    let (mut worst_fit, mut b6, mut b12) = (0.0f64, 0.0f64, 0.0f64);
    for d in sizes {
        for s in [Setup::CylinderEnd, Setup::WallFlat] {
            for n in [4, 8, 16] {
                let (c, m, g, gp) = saturated(s, d, n, false);
                let b = c / (m * n as f64);
                saturation.push(vec![d, s.index(), c, m, n as f64, b, g, gp]);
                worst_fit = worst_fit.max((g / gp - 1.0).abs());
                if n == DEFAULT_SUBSTEPS {
                    if d < 12.0 {
                        b6 = b6.max(b);
                    } else {
                        b12 = b12.max(b);
                    }
                }
            }
        }
    }
    out.tables.push(saturation);
    out.checks.push(Check::at_most(
        CASE,
        "saturated_amplification_matches_analysis",
        worst_fit,
        1e-9,
        "saturated, lubrication only, normal motion: the damping is linear and constant, so one \
         fluid step multiplies the relative velocity by (1 - c h/m_red)^n_sub exactly (round-off \
         of <= 16 updates)",
    ));
    out.checks.push(Check::at_most(
        CASE,
        "saturated_stability_d6",
        b6,
        2.0,
        "explicit Euler damping is stable for b = c h/m_red < 2; stiffest contacts at d = 6",
    ));
    out.checks.push(Check::at_most(
        CASE,
        "saturated_monotone_d12",
        b12,
        1.0,
        "b <= 1: the relative velocity decays without reversing (paper scale d = 12)",
    ));

    // The opt-in lubrication limiter on the same saturated contacts, at sub-step counts where the
    // explicit law is unstable.
    let mut limited = Table::new(
        "saturated lubrication with the lubrication limiter: per-step amplification g",
        &[("d", true), ("setup", true), ("n_sub", true), ("b", true), ("g", true)],
    );
    let mut worst_g = f64::NEG_INFINITY;
    let mut least_g = f64::INFINITY;
    for d in sizes {
        for s in [Setup::CylinderEnd, Setup::WallFlat] {
            for n in [1, 2, 4] {
                let (c, m, g, _) = saturated(s, d, n, true);
                limited.push(vec![d, s.index(), n as f64, c / (m * n as f64), g]);
                worst_g = worst_g.max(g);
                least_g = least_g.min(g);
            }
        }
    }
    out.tables.push(limited);
    out.checks.push(Check::at_most(
        CASE,
        "limiter_saturated_stable",
        worst_g,
        1.0 - 1e-6,
        "with the lubrication limiter, the saturated contacts decay at every n_sub = 1, 2, 4 (g < 1), \
         where the explicit law has b up to 10.7 and |g| > 1",
    ));
    out.checks.push(Check::at_least(
        CASE,
        "limiter_saturated_monotone",
        least_g,
        0.0,
        0.0,
        "with the limiter each sub-step removes at most IMPLICIT_LIMIT = 0.9 of the relative velocity \
         it sees: g >= 0, the relative velocity never reverses",
    ));

    lubrication_substeps(&mut out, &jobs, &res);

    out.tables.push(cost(tier));
    out
}

/// The checks every lubricated collision must pass, whatever the sub-stepping (module doc),
/// named `{prefix}dissipation_lubricated`, `{prefix}energy_never_exceeds_initial` and
/// `{prefix}closest_approach`: the smallest kinetic-energy loss, the largest excess of `E` over
/// `E(0)`, the closest approach outside the known deviations.
fn lubricated_checks(out: &mut CaseOutput, prefix: &str, min_loss: f64, excess: f64, closest: f64) {
    out.checks.push(Check::at_least(
        CASE,
        format!("{prefix}dissipation_lubricated"),
        min_loss,
        0.0,
        0.0,
        "lubrication power -(k_n|du_n|^2 + k_t|du_t|^2)(1/d* - 1/d_d) w is never positive (frozen \
         operators: symmetric positive semi-definite in the relative velocity): KE(0) - KE(end) >= 0 \
         for every lubricated run",
    ));
    out.checks.push(Check::at_most(
        CASE,
        format!("{prefix}energy_never_exceeds_initial"),
        excess.max(0.0),
        1e-12,
        "lubricated: the lubrication acts from delta_d = 1, before the spring (delta0 = 0.5) stores \
         anything, and only removes energy; E = KE + sum k(d0-d)^2 w/2 after every sub-step stays \
         at or below E(0) (1e-12: round-off of KE before the contact)",
    ));
    out.checks.push(Check::at_least(
        CASE,
        format!("{prefix}closest_approach"),
        closest,
        0.2,
        0.2,
        "no marker comes closer than delta_sat to another surface or the wall (impact speeds \
         up to the tip speed 0.104); the runs where Table 1 does not achieve it are listed in \
         the table of known deviations",
    ));
}

/// The lubrication sub-steps (module doc of `slurry::contact`, "Lubrication sub-steps";
/// [`LUB_SCHEME`]): the checks of the explicit scheme on the same collisions, the saturated
/// amplification, and the change of every lubricated collision's outcome against the default.
fn lubrication_substeps(out: &mut CaseOutput, jobs: &[(f64, Setup, f64, bool)], res: &[Outcome]) {
    let (n_sub, m_lub) = LUB_SCHEME;
    let params = ContactParams { lubrication_substeps: m_lub, ..Default::default() };
    let lubricated: Vec<(usize, (f64, Setup, f64, bool))> =
        jobs.iter().copied().enumerate().filter(|(_, j)| j.3).collect();
    let alt: Vec<Outcome> =
        lubricated.par_iter().map(|&(_, (d, s, v, _))| collide(s, d, v, params, n_sub)).collect();
    let mut t = Table::new(
        format!(
            "lubricated collisions with {n_sub} contact sub-steps x {m_lub} lubrication sub-steps against the \
             default ({DEFAULT_SUBSTEPS} x 1): restitution and closest approach"
        ),
        &[
            ("d", true),
            ("setup", true),
            ("speed", true),
            ("restitution", true),
            ("restitution_default", true),
            ("closest", true),
            ("closest_default", true),
            ("ke_change", true),
        ],
    );
    let (mut mom, mut excess, mut min_loss, mut closest_ok) =
        (0.0f64, f64::NEG_INFINITY, f64::INFINITY, f64::INFINITY);
    let (mut de, mut dc) = (0.0f64, 0.0f64);
    for (&(k, (d, s, v, _)), o) in lubricated.iter().zip(&alt) {
        let r = &res[k];
        t.push(vec![d, s.index(), v, o.restitution, r.restitution, o.closest, r.closest, o.ke_change]);
        mom = mom.max(o.momentum_err);
        excess = excess.max(o.energy_excess);
        min_loss = min_loss.min(-o.ke_change);
        if !known_deviation(s, d, v) {
            closest_ok = closest_ok.min(o.closest);
            de = de.max((o.restitution - r.restitution).abs());
            dc = dc.max((o.closest - r.closest).abs());
        }
    }
    out.tables.push(t);
    out.checks.push(Check::at_most(
        CASE,
        "lub_substeps_momentum_conservation",
        mom,
        1e-13,
        "with lubrication sub-steps each pair's operator gives +F and -F to its two bodies (the two \
         force rows agree to round-off): sum m v changes by round-off only",
    ));
    lubricated_checks(out, "lub_substeps_", min_loss, excess, closest_ok);
    out.checks.push(Check::at_most(
        CASE,
        "lub_substeps_restitution_change",
        de,
        LUB_RESTITUTION_TOL,
        "largest |e - e_default| over the lubricated collisions (known deviations excluded): the \
         elastic load is held over a contact sub-step of 1/2 instead of 1/8, a coarser position Verlet \
         (error O((omega h)^2), omega h <= 0.85 at d = 6), and the lubrication geometry is frozen over it",
    ));
    out.checks.push(Check::at_most(
        CASE,
        "lub_substeps_closest_change",
        dc,
        LUB_CLOSEST_TOL,
        "largest |closest - closest_default| (lattice units) over the same collisions: the same \
         coarser elastic sub-step",
    ));

    // Saturated contacts: the operators reproduce the explicit law's amplification per
    // lubrication sub-step exactly, at any split of the same number of damping steps.
    let mut sat = Table::new(
        "saturated lubrication (elastic off, gap 0.1) with lubrication sub-steps: n_sub x m_lub damping steps",
        &[("d", true), ("setup", true), ("n_sub", true), ("m_lub", true), ("b", true), ("g", true), ("g_pred", true)],
    );
    let mut worst = 0.0f64;
    for d in [6.0, 12.0] {
        for s in [Setup::CylinderEnd, Setup::WallFlat] {
            for (n, m) in [(1, 8), (2, 4), (2, 8), (4, 4)] {
                let (c, mr, g, gp) = saturated_with(s, d, n, m, false);
                sat.push(vec![d, s.index(), n as f64, m as f64, c / (mr * (n * m) as f64), g, gp]);
                worst = worst.max((g / gp - 1.0).abs());
            }
        }
    }
    out.tables.push(sat);
    out.checks.push(Check::at_most(
        CASE,
        "lub_substeps_saturated_amplification",
        worst,
        1e-9,
        "saturated normal motion, lubrication only: the frozen operator is the law's exact \
         linearisation, so n_sub x m_lub explicit damping steps multiply the relative velocity by \
         (1 - c h/m_red)^(n_sub m_lub), h = 1/(n_sub m_lub), to round-off (as the explicit scheme's check)",
    ));
}

/// `(µs per call, stats)` of `Contacts::compute` on `bodies`, minimum over `reps` calls after
/// one warm-up call, in a pool of `threads` threads.
fn time_compute(
    bodies: &[RigidBody],
    markers: &[Vec<Marker>],
    walls: Walls,
    threads: usize,
    reps: usize,
) -> (f64, slurry::contact::ContactStats) {
    let pool = rayon::ThreadPoolBuilder::new().num_threads(threads).build().expect("thread pool");
    pool.install(|| {
        let mut c =
            Contacts::new(ContactParams::default(), walls, bodies, markers).expect("valid parameters");
        c.compute(bodies, markers);
        let mut best = f64::INFINITY;
        for _ in 0..reps {
            let t0 = Instant::now();
            c.compute(bodies, markers);
            best = best.min(t0.elapsed().as_secs_f64());
        }
        (best * 1e6, *c.stats())
    })
}

/// A settled bed and how it was made.
struct Bed {
    bodies: Vec<RigidBody>,
    markers: Vec<Vec<Marker>>,
    walls: Walls,
    steps: usize,
    seconds: f64,
    /// Solids fraction below the top of the bed.
    phi: f64,
}

/// 100 cylinders `d = 12`, `ℓ = d`, random orientations, on a jittered lattice in a closed
/// 90 × 90 × 80 box, settled for 3000 steps under net weight (`g = 2e-3`) and a linear drag
/// (terminal speed 0.05, a stand-in for the fluid) with `Contacts::advance`. (The pile of
/// frictionless cylinders keeps spreading slowly on the frictionless floor, `|v| ≲ 0.03`; small
/// piles of two or three come to rest to 1e-13.)
fn settled_bed() -> Bed {
    let box_n = [90, 90, 80];
    let walls = Walls::closed_box(box_n);
    let shape: Arc<dyn Shape> = Arc::new(Cylinder::new(12.0, 12.0));
    let m = shape.markers(DEFAULT_MARKER_SPACING);
    let mut rng = SplitMix64(7);
    let mut bodies = Vec::with_capacity(100);
    // Cells of 17.6 > 2 × bounding radius + 0.5: no overlap whatever the orientations.
    'fill: for k in 0.. {
        for j in 0..5 {
            for i in 0..5 {
                if bodies.len() == 100 {
                    break 'fill;
                }
                let c = Vec3::new(
                    9.5 + i as f64 * 17.6 + rng.uniform(-0.3, 0.3),
                    9.5 + j as f64 * 17.6 + rng.uniform(-0.3, 0.3),
                    9.0 + k as f64 * 17.6,
                );
                let axis = loop {
                    let v = Vec3::from(rng.vec3(-1.0, 1.0));
                    if v.norm() > 0.1 && v.norm() < 1.0 {
                        break v.normalize();
                    }
                };
                let q = Quat::rotation_between(&Vec3::z(), &axis).unwrap_or_else(Quat::identity);
                bodies.push(
                    RigidBody::new(shape.clone(), GAMMA, Motion::Free).with_position(c).with_orientation(q),
                );
            }
        }
    }
    let markers = vec![m; bodies.len()];
    let mut ct = Contacts::new(ContactParams::default(), walls, &bodies, &markers).expect("valid parameters");
    let g = Vec3::new(0.0, 0.0, -2e-3);
    let weight = bodies[0].net_weight(g, 1.0);
    let drag = weight.norm() / 0.05;
    let t0 = Instant::now();
    let mut steps = 0;
    loop {
        slurry::contact::step_bodies(Some(&mut ct), &mut bodies, &markers, DEFAULT_SUBSTEPS, |_, b| {
            (weight - b.velocity * drag, -b.angular_velocity * (drag * 36.0))
        });
        steps += 1;
        if steps >= 3000 {
            break;
        }
    }
    let top = bodies.iter().map(|b| b.position.z).fold(0.0, f64::max);
    let solid: f64 = bodies.iter().map(|b| b.shape().volume()).sum();
    let phi = solid / (90.0 * 90.0 * (top + 6.5));
    Bed { bodies, markers, walls, steps, seconds: t0.elapsed().as_secs_f64(), phi }
}

/// Cost of `Contacts::compute` (module doc): per contact type (quick and full), and on a
/// settled bed of 100 cylinders (full).
fn cost(tier: Tier) -> Table {
    let mut t = Table::new(
        "cost of one Contacts::compute, min of repeated calls (config 0-3: cylinder_side, cylinder_end, \
         wall_flat, wall_side at gap 0.5; 4: settled bed of 100 cylinders, full tier)",
        &[
            ("config", true),
            ("threads", true),
            ("bodies", true),
            ("candidate_pairs", false),
            ("touching_pairs", false),
            ("marker_pairs", false),
            ("wall_contacts", false),
            ("us_per_call", false),
            ("settle_steps", false),
            ("settle_s", false),
            ("phi", false),
        ],
    );
    // Config 0..3: one contact of each kind (d = 12, l = d, surfaces 0.5 apart).
    for (k, s) in
        [Setup::CylinderSide, Setup::CylinderEnd, Setup::WallFlat, Setup::WallSide].into_iter().enumerate()
    {
        let sc = scene(s, 12.0, 0.0, 0.5);
        let (us, st) = time_compute(&sc.bodies, &sc.markers, sc.walls, 1, 200);
        t.push(vec![
            k as f64,
            1.0,
            sc.bodies.len() as f64,
            st.candidate_pairs as f64,
            st.touching_pairs as f64,
            st.marker_pairs as f64,
            st.wall_contacts as f64,
            us,
            0.0,
            0.0,
            0.0,
        ]);
    }
    if tier == Tier::Full {
        let Bed { bodies, markers, walls, steps, seconds: secs, phi } = settled_bed();
        for threads in [1, 2] {
            let (us, st) = time_compute(&bodies, &markers, walls, threads, 7);
            t.push(vec![
                4.0,
                threads as f64,
                bodies.len() as f64,
                st.candidate_pairs as f64,
                st.touching_pairs as f64,
                st.marker_pairs as f64,
                st.wall_contacts as f64,
                us,
                steps as f64,
                secs,
                phi,
            ]);
        }
    }
    t
}
