//! What a contact evaluation adds up, and the order it adds it in: [`ContactLoad`] (a body's
//! force and torque), [`ContactStats`] (the counters and stiffness bounds of an evaluation),
//! the per-pair `Slot`s that the parallel tasks fill (one per body pair, one per body for the
//! walls, each summed in a fixed order), and `accumulate`, the serial sum of the slots in pair
//! order then body order that makes the loads bitwise independent of the thread count. The
//! fast path ([`super::Contacts`]) and the [`oracle`](super::oracle) share it, so the two agree
//! bitwise.

use crate::rigid::{RigidBody, Vec3};

use super::force::{Hit, Pose};
use super::params::ContactParams;

/// Force and torque (world frame; torque about the body's centre of mass).
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct ContactLoad {
    /// Force.
    pub force: Vec3,
    /// Torque about the centre of mass.
    pub torque: Vec3,
}

impl ContactLoad {
    /// Zero force and torque.
    pub const ZERO: Self = Self { force: Vec3::new(0.0, 0.0, 0.0), torque: Vec3::new(0.0, 0.0, 0.0) };
}

/// Counters and diagnostics of the last evaluation.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ContactStats {
    /// Body pairs in the marker-pair list (at least one marker pair within the listing range
    /// when the list was built; not both non-free).
    pub candidate_pairs: usize,
    /// Body pairs with at least one interacting marker pair.
    pub touching_pairs: usize,
    /// Interacting marker pairs (body–body).
    pub marker_pairs: usize,
    /// Interacting marker–wall contacts.
    pub wall_contacts: usize,
    /// The smallest normal distance `δ` among the interacting pairs and wall contacts
    /// (`+∞` if none).
    pub min_delta: f64,
    /// `Σ ½ k (δ0 − δ)² w` over the interacting pairs and wall contacts with `δ < δ0`: the
    /// elastic energy stored (a diagnostic; see [`super`] on why it is not an exact potential).
    pub elastic_energy: f64,
    /// The stiffest free body's damping rate `max_b 2 Σ c / m_b` (per unit time), `Σ c` over
    /// the body's interacting pairs and wall contacts of the normal damping coefficient
    /// `kⁿ (1/δ* − 1/δ_d) w`: a Gershgorin bound of the translational eigenvalues of
    /// `M⁻¹ K` (the factor 2: partners that move; exact for two equal bodies). Explicit Euler
    /// damping in sub-steps of `h` is stable for `h · damping_rate < 2` on these modes (module
    /// [`super`], "Stability analysis"; rotation is not included).
    pub damping_rate: f64,
    /// The stiffest free body's spring rate `max_b √(2 Σ k w / m_b)`, the same bound for the
    /// elastic part: position Verlet is stable for `h · spring_rate < 2`.
    pub spring_rate: f64,
}

impl Default for ContactStats {
    fn default() -> Self {
        Self {
            candidate_pairs: 0,
            touching_pairs: 0,
            marker_pairs: 0,
            wall_contacts: 0,
            min_delta: f64::INFINITY,
            elastic_energy: 0.0,
            damping_rate: 0.0,
            spring_rate: 0.0,
        }
    }
}

/// The loads of one body pair (or of one body against the walls), summed in a fixed order:
/// the elastic and the lubrication parts apart (the second is scaled per body pair by
/// [`accumulate`]), and the pair's damping moments that the scaling is formed from.
#[derive(Clone, Copy, Debug)]
pub(crate) struct Slot {
    /// Elastic force and torque on body a, on body b.
    pub fa: Vec3,
    pub ta: Vec3,
    pub fb: Vec3,
    pub tb: Vec3,
    /// Lubrication force and torque on body a, on body b.
    pub la: Vec3,
    pub lta: Vec3,
    pub lb: Vec3,
    pub ltb: Vec3,
    /// `Σ (cⁿ + cᵗ)` over the interacting pairs: the translational part of either body's
    /// damping mobility sum ([`accumulate`]).
    pub mob: f64,
    /// `Σ cⁿ |r × n̂|² + cᵗ |r|²` with body a's lever arms, with body b's: the rotational part.
    pub mob_a: f64,
    pub mob_b: f64,
    pub count: u32,
    pub min_delta: f64,
    pub energy: f64,
    /// `Σ` of the interacting pairs' normal damping coefficients and spring constants
    /// ([`Hit`]).
    pub damping: f64,
    pub spring: f64,
}

impl Slot {
    pub const EMPTY: Self = Self {
        fa: Vec3::new(0.0, 0.0, 0.0),
        ta: Vec3::new(0.0, 0.0, 0.0),
        fb: Vec3::new(0.0, 0.0, 0.0),
        tb: Vec3::new(0.0, 0.0, 0.0),
        la: Vec3::new(0.0, 0.0, 0.0),
        lta: Vec3::new(0.0, 0.0, 0.0),
        lb: Vec3::new(0.0, 0.0, 0.0),
        ltb: Vec3::new(0.0, 0.0, 0.0),
        mob: 0.0,
        mob_a: 0.0,
        mob_b: 0.0,
        count: 0,
        min_delta: f64::INFINITY,
        energy: 0.0,
        damping: 0.0,
        spring: 0.0,
    };

    /// Adds the force of `h` on marker `i` (lever arm `ri`) of body a and its opposite on
    /// marker `j` (lever arm `rj`) of body b. The oracle adds in the same order with the same
    /// operations.
    #[inline(always)]
    pub fn add_pair(&mut self, h: &Hit, p: &ContactParams, ri: &Vec3, rj: &Vec3, pa: &Pose, pb: &Pose) {
        if p.lubrication_limiter && h.damping > 0.0 {
            let (e, l) = (&h.elastic, &h.lub);
            self.fa += e;
            self.ta += ri.cross(e);
            self.fb -= e;
            self.tb += rj.cross(&(-e));
            self.la += l;
            self.lta += ri.cross(l);
            self.lb -= l;
            self.ltb += rj.cross(&(-l));
            self.mob += h.damping + h.damping_t;
            self.mob_a += rotational_mobility(h, ri, pa);
            self.mob_b += rotational_mobility(h, rj, pb);
        } else if p.operators() {
            // Lubrication sub-steps: the lubrication goes into the pair's operator (module
            // `operator`), the slot holds the elastic part only.
            let e = &h.elastic;
            self.fa += e;
            self.ta += ri.cross(e);
            self.fb -= e;
            self.tb += rj.cross(&(-e));
        } else {
            // The explicit law: one force per pair, in the elastic sums.
            let f = &(h.elastic + h.lub);
            self.fa += f;
            self.ta += ri.cross(f);
            self.fb -= f;
            self.tb += rj.cross(&(-f));
        }
        self.tally(h, p);
    }

    /// Adds the force of a wall on a marker with lever arm `r` (body a only).
    #[inline(always)]
    pub fn add_wall(&mut self, h: &Hit, p: &ContactParams, r: &Vec3, pose: &Pose) {
        if p.lubrication_limiter && h.damping > 0.0 {
            self.fa += h.elastic;
            self.ta += r.cross(&h.elastic);
            self.la += h.lub;
            self.lta += r.cross(&h.lub);
            self.mob += h.damping + h.damping_t;
            self.mob_a += rotational_mobility(h, r, pose);
        } else {
            let f = if p.operators() { h.elastic } else { h.elastic + h.lub };
            self.fa += f;
            self.ta += r.cross(&f);
        }
        self.tally(h, p);
    }

    /// The statistics of one interacting pair: count, closest `δ`, energy, stiffness.
    #[inline(always)]
    fn tally(&mut self, h: &Hit, p: &ContactParams) {
        self.count += 1;
        self.min_delta = self.min_delta.min(h.delta);
        self.energy += h.elastic_energy(p);
        self.damping += h.damping;
        self.spring += h.spring;
    }
}

/// `cⁿ (r × n̂)ᵀ I⁻¹ (r × n̂) + cᵗ |r|² max_k(1/I_k)`: the pair's damping times the rotational
/// mobility of its normal direction and a bound of its tangential ones, the rotational part of
/// the body's damping-rate bound.
#[inline(always)]
fn rotational_mobility(h: &Hit, r: &Vec3, pose: &Pose) -> f64 {
    let m = &pose.inv_sqrt_moments;
    let tangential = m.x.max(m.y).max(m.z);
    h.damping * pose.rotational_mobility(r, &h.normal)
        + h.damping_t * r.norm_squared() * tangential * tangential
}

/// Serial accumulation shared by the fast path and the oracle: pair slots in pair order
/// (skipping slots without contacts), then wall slots in body order.
///
/// `stiffness[b]` receives body `b`'s `(Σ c, Σ k w)` over its interacting pairs and wall
/// contacts ([`ContactStats::damping_rate`]).
///
/// **Lubrication limiter** (module [`super`]; slots filled with
/// [`ContactParams::lubrication_limiter`] on). With `h > 0` (a sub-step of length `h`), the
/// lubrication load of body pair `(a, b)` is multiplied by `min(1, IMPLICIT_LIMIT/(h (ρ_a +
/// ρ_b)))`, of a body against the walls by `min(1, IMPLICIT_LIMIT/(h ρ_b))`, where for a free
/// body `ρ_b = Σ (cⁿ + cᵗ)/m_b + Σ cⁿ (r × n̂)ᵀ I⁻¹ (r × n̂) + cᵗ |r|²/I_min` over all its
/// lubricated pairs and wall contacts (a bound of its damping rate, translation and rotation)
/// and `ρ = 0` for a fixed or prescribed one (infinitely heavy). `h = 0` is the explicit law
/// (factor 1). `inverse_mass[b] = (1/m_b, 1)`, zero for non-free bodies; `mobility` is a
/// buffer.
#[allow(clippy::too_many_arguments)]
pub(crate) fn accumulate(
    pairs: &[(u32, u32)],
    slots: &[Slot],
    wall_slots: &[Slot],
    loads: &mut [ContactLoad],
    stiffness: &mut [[f64; 2]],
    stats: &mut ContactStats,
    h: f64,
    inverse_mass: &[[f64; 2]],
    mobility: &mut Vec<f64>,
) -> Vec3 {
    loads.fill(ContactLoad::ZERO);
    stiffness.fill([0.0; 2]);
    mobility.clear();
    mobility.resize(loads.len(), 0.0);
    if h > 0.0 {
        let mut add = |b: usize, mob: f64, rot: f64| {
            let [im, ii] = inverse_mass[b];
            mobility[b] += mob * im + rot * ii;
        };
        for (&(a, b), s) in pairs.iter().zip(slots) {
            if s.mob > 0.0 {
                add(a as usize, s.mob, s.mob_a);
                add(b as usize, s.mob, s.mob_b);
            }
        }
        for (b, s) in wall_slots.iter().enumerate() {
            if s.mob > 0.0 {
                add(b, s.mob, s.mob_a);
            }
        }
    }
    let mut reaction = Vec3::zeros();
    for (&(a, b), s) in pairs.iter().zip(slots) {
        if s.count == 0 {
            continue;
        }
        let (a, b) = (a as usize, b as usize);
        let scale = limiter(h * (mobility[a] + mobility[b]));
        loads[a].force += s.fa + s.la * scale;
        loads[a].torque += s.ta + s.lta * scale;
        loads[b].force += s.fb + s.lb * scale;
        loads[b].torque += s.tb + s.ltb * scale;
        for body in [a, b] {
            stiffness[body][0] += s.damping;
            stiffness[body][1] += s.spring;
        }
        stats.touching_pairs += 1;
        stats.marker_pairs += s.count as usize;
        stats.min_delta = stats.min_delta.min(s.min_delta);
        stats.elastic_energy += s.energy;
    }
    for (b, s) in wall_slots.iter().enumerate() {
        if s.count == 0 {
            continue;
        }
        let scale = limiter(h * mobility[b]);
        let force = s.fa + s.la * scale;
        loads[b].force += force;
        loads[b].torque += s.ta + s.lta * scale;
        stiffness[b][0] += s.damping;
        stiffness[b][1] += s.spring;
        reaction -= force;
        stats.wall_contacts += s.count as usize;
        stats.min_delta = stats.min_delta.min(s.min_delta);
        stats.elastic_energy += s.energy;
    }
    reaction
}

/// The lubrication's scale factor for a body pair whose summed damping-rate bound over a
/// sub-step is `x = h (ρ_a + ρ_b)`: 1 (the explicit law) while `x ≤ IMPLICIT_LIMIT`, else
/// `IMPLICIT_LIMIT / x`.
#[inline(always)]
fn limiter(x: f64) -> f64 {
    if x > IMPLICIT_LIMIT {
        IMPLICIT_LIMIT / x
    } else {
        1.0
    }
}

/// The largest damping-rate bound per sub-step, `h (ρ_a + ρ_b)`, that a body pair's
/// lubrication is given (module [`super`], "Lubrication limiter"): below 1, so that an
/// isolated pair's relative velocity is never reversed, and Gershgorin's bound of the whole
/// system, `2 · IMPLICIT_LIMIT`, stays below the stability limit 2.
pub(crate) const IMPLICIT_LIMIT: f64 = 0.9;

/// Per body `(1/m, 1)` for a free body, `(0, 0)` for a fixed or prescribed one: the weights of
/// the translational and the (already inertia-weighted) rotational sums in [`accumulate`]'s
/// lubrication limiter.
pub(crate) fn inverse_masses(bodies: &[RigidBody], out: &mut Vec<[f64; 2]>) {
    out.clear();
    out.extend(bodies.iter().map(|b| if b.is_free() { [1.0 / b.mass(), 1.0] } else { [0.0; 2] }));
}

/// [`ContactStats::damping_rate`] and [`ContactStats::spring_rate`] from the per-body sums.
pub(crate) fn stiffness_rates(bodies: &[RigidBody], stiffness: &[[f64; 2]], stats: &mut ContactStats) {
    let (mut damping, mut spring) = (0.0f64, 0.0f64);
    for (b, &[c, k]) in bodies.iter().zip(stiffness) {
        if b.is_free() {
            damping = damping.max(2.0 * c / b.mass());
            spring = spring.max((2.0 * k / b.mass()).sqrt());
        }
    }
    stats.damping_rate = damping;
    stats.spring_rate = spring;
}
