//! What a contact evaluation adds up, and the order it adds it in: [`ContactLoad`] (a body's
//! force and torque), [`ContactStats`] (the counters and stiffness bounds of an evaluation),
//! the per-pair `Slot`s that the parallel tasks fill (one per body pair, one per body for the
//! walls, each summed in a fixed order), and `accumulate`, the serial sum of the slots in pair
//! order then body order that makes the loads bitwise independent of the thread count. The
//! fast path ([`super::Contacts`]) and the [`oracle`](super::oracle) share it, so the two agree
//! bitwise.

use crate::rigid::{RigidBody, Vec3};

use super::force::Hit;
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

/// The loads of one body pair (or of one body against the walls), summed in a fixed order.
#[derive(Clone, Copy, Debug)]
pub(crate) struct Slot {
    pub fa: Vec3,
    pub ta: Vec3,
    pub fb: Vec3,
    pub tb: Vec3,
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
        count: 0,
        min_delta: f64::INFINITY,
        energy: 0.0,
        damping: 0.0,
        spring: 0.0,
    };

    /// Adds the force `h.force` on marker `i` (lever arm `ri`) of body a and its opposite on
    /// marker `j` (lever arm `rj`) of body b. The oracle adds in the same order with the same
    /// operations.
    #[inline(always)]
    pub fn add_pair(&mut self, h: &Hit, p: &ContactParams, ri: &Vec3, rj: &Vec3) {
        let f = &h.force;
        self.fa += f;
        self.ta += ri.cross(f);
        self.fb -= f;
        self.tb += rj.cross(&(-f));
        self.tally(h, p);
    }

    /// Adds the force `h.force` of a wall on a marker with lever arm `r` (body a only).
    #[inline(always)]
    pub fn add_wall(&mut self, h: &Hit, p: &ContactParams, r: &Vec3) {
        self.fa += h.force;
        self.ta += r.cross(&h.force);
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

/// Serial accumulation shared by the fast path and the oracle: pair slots in pair order
/// (skipping slots without contacts), then wall slots in body order.
///
/// `stiffness[b]` receives body `b`'s `(Σ c, Σ k w)` over its interacting pairs and wall
/// contacts ([`ContactStats::damping_rate`]).
pub(crate) fn accumulate(
    pairs: &[(u32, u32)],
    slots: &[Slot],
    wall_slots: &[Slot],
    loads: &mut [ContactLoad],
    stiffness: &mut [[f64; 2]],
    stats: &mut ContactStats,
) -> Vec3 {
    loads.fill(ContactLoad::ZERO);
    stiffness.fill([0.0; 2]);
    let mut reaction = Vec3::zeros();
    for (&(a, b), s) in pairs.iter().zip(slots) {
        if s.count == 0 {
            continue;
        }
        let (a, b) = (a as usize, b as usize);
        loads[a].force += s.fa;
        loads[a].torque += s.ta;
        loads[b].force += s.fb;
        loads[b].torque += s.tb;
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
        loads[b].force += s.fa;
        loads[b].torque += s.ta;
        stiffness[b][0] += s.damping;
        stiffness[b][1] += s.spring;
        reaction -= s.fa;
        stats.wall_contacts += s.count as usize;
        stats.min_delta = stats.min_delta.min(s.min_delta);
        stats.elastic_energy += s.energy;
    }
    reaction
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
