//! [`Contacts`]: broad phase (cell list on bounding spheres), narrow phase (marker patches and bins),
//! parallel per-pair evaluation and the serial, ordered accumulation into per-body loads.

use std::sync::Mutex;

use rayon::prelude::*;

use crate::rigid::{Marker, RigidBody, Vec3};

use super::force::{Hit, Pose};
use super::grid::{fill, for_cells, Geometry};
use super::list::{scratch_capacity, Narrow, PairList, Scratch, DEFAULT_SKIN};
use super::params::{ContactParamError, ContactParams, Walls};
use super::patches::Patches;

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

/// Safety margin (lattice units) added to every pruning radius, far above round-off (≲ 1e-12
/// at coordinates of a few hundred) and far below any physical length: pruning never drops a
/// pair that the exact criterion `|x_j − x_i| < reach` keeps.
pub(crate) const MARGIN: f64 = 1e-6;

/// Body pairs (or bodies, for the walls) per parallel task of an evaluation.
const EVAL_CHUNK: usize = 32;

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
    /// ([`Hit::stiffness`]).
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
        let (c, k) = h.stiffness(p);
        self.damping += c;
        self.spring += k;
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

/// The contact model of Derksen (2020, Table 1) between the surface markers of rigid bodies
/// and against the box walls (module [`super`]): owns the per-body data computed once (bounding
/// radii, marker patches) and every buffer of an evaluation, so that a warm evaluation does not
/// allocate.
#[derive(Debug)]
pub struct Contacts {
    params: ContactParams,
    walls: Walls,
    wall_list: Vec<(usize, f64, Vec3)>,
    reach: f64,
    radius: Vec<f64>,
    surface_tol: Vec<f64>,
    marker_counts: Vec<usize>,
    patches: Vec<Patches>,
    big: Vec<bool>,
    small: Vec<u32>,
    /// The largest bounding radius of the bodies in the cell list.
    r_small: f64,
    // Per evaluation.
    pub(crate) poses: Vec<Pose>,
    cell_of: Vec<u32>,
    cell_start: Vec<u32>,
    cell_items: Vec<u32>,
    pairs: Vec<(u32, u32)>,
    /// Bodies whose list entries are found again in this evaluation.
    stale: Vec<u32>,
    /// Poses at which the list's entries are found (the narrow phase's).
    reference: Vec<Pose>,
    slots: Vec<Slot>,
    wall_slots: Vec<Slot>,
    pub(crate) loads: Vec<ContactLoad>,
    /// Per body `(Σ c, Σ k w)` of the last evaluation ([`ContactStats::damping_rate`]).
    stiffness: Vec<[f64; 2]>,
    wall_reaction: Vec3,
    stats: ContactStats,
    scratch: Vec<Mutex<Scratch>>,
    list: PairList,
    // Sub-cycling (module `subcycle`).
    pub(crate) external: Vec<ContactLoad>,
    pub(crate) external_prev: Vec<Option<ContactLoad>>,
    pub(crate) average: Vec<ContactLoad>,
}

impl Contacts {
    /// Prepares contacts between `bodies` (any motion kind) with their body-frame `markers`
    /// (`markers[b]` belongs to `bodies[b]`, the same sets that are passed to every later
    /// call) inside `walls`. Computes once per body its bounding radius (largest marker
    /// distance from the centre of mass), the largest `|signed_distance|` of its markers, and
    /// static body-frame patches of its markers.
    ///
    /// # Errors
    /// If the parameters are invalid ([`ContactParams::validate`]).
    ///
    /// # Panics
    /// If `bodies` and `markers` differ in length.
    pub fn new<M: AsRef<[Marker]>>(
        params: ContactParams,
        walls: Walls,
        bodies: &[RigidBody],
        markers: &[M],
    ) -> Result<Self, ContactParamError> {
        params.validate()?;
        assert_eq!(bodies.len(), markers.len(), "one marker set per body");
        let reach = params.reach();
        let radius: Vec<f64> = markers
            .iter()
            .map(|m| m.as_ref().iter().map(|mk| mk.position.norm()).fold(0.0, f64::max))
            .collect();
        let surface_tol: Vec<f64> = bodies
            .iter()
            .zip(markers)
            .map(|(b, m)| {
                m.as_ref().iter().map(|mk| b.shape().signed_distance(&mk.position).abs()).fold(0.0, f64::max)
            })
            .collect();
        let mut sorted = radius.clone();
        sorted.sort_by(f64::total_cmp);
        let r_med = sorted.get(sorted.len().saturating_sub(1) / 2).copied().unwrap_or(0.0);
        // Bodies far larger than the typical one (an impeller among particles) stay out of the
        // cell list and are tested against every body.
        let big: Vec<bool> = radius.iter().map(|&r| r > 4.0 * r_med).collect();
        let small: Vec<u32> = (0..radius.len()).filter(|&b| !big[b]).map(|b| b as u32).collect();
        let r_small = small.iter().map(|&b| radius[b as usize]).fold(0.0, f64::max);
        let patches = markers.iter().map(|m| Patches::new(m.as_ref())).collect();
        let wall_list = walls.iter().map(|(a, _, p, n)| (a, p, n)).collect();
        let n = bodies.len();
        Ok(Self {
            params,
            walls,
            wall_list,
            reach,
            surface_tol,
            marker_counts: markers.iter().map(|m| m.as_ref().len()).collect(),
            patches,
            big,
            small,
            r_small,
            radius,
            poses: Vec::with_capacity(n),
            cell_of: Vec::new(),
            cell_start: Vec::new(),
            cell_items: Vec::new(),
            pairs: Vec::new(),
            stale: Vec::new(),
            reference: Vec::with_capacity(n),
            slots: Vec::new(),
            wall_slots: Vec::with_capacity(n),
            loads: vec![ContactLoad::ZERO; n],
            stiffness: vec![[0.0; 2]; n],
            wall_reaction: Vec3::zeros(),
            stats: ContactStats::default(),
            scratch: Vec::new(),
            list: PairList::new(DEFAULT_SKIN),
            external: Vec::with_capacity(n),
            external_prev: vec![None; n],
            average: vec![ContactLoad::ZERO; n],
        })
    }

    /// The parameters.
    pub fn params(&self) -> &ContactParams {
        &self.params
    }

    /// The walls.
    pub fn walls(&self) -> &Walls {
        &self.walls
    }

    /// The largest marker–marker distance considered, [`ContactParams::reach`].
    pub fn reach(&self) -> f64 {
        self.reach
    }

    /// Per body, the bounding radius used by the broad phase.
    pub fn bounding_radii(&self) -> &[f64] {
        &self.radius
    }

    /// The contact loads of the last evaluation ([`Contacts::compute`]), per body.
    pub fn loads(&self) -> &[ContactLoad] {
        &self.loads
    }

    /// The total force the bodies exert on the walls in the last evaluation (minus the sum of
    /// the wall forces on the bodies): `Σ_b F_b + wall_reaction = 0` to round-off.
    pub fn wall_reaction(&self) -> Vec3 {
        self.wall_reaction
    }

    /// Counters of the last evaluation.
    pub fn stats(&self) -> &ContactStats {
        &self.stats
    }

    /// Total capacity (elements) of the internal buffers, per-thread scratch included: constant
    /// from one evaluation to the next once warm (no allocation in steady state).
    pub fn buffer_capacity(&self) -> usize {
        scratch_capacity(&self.scratch)
            + self.list.capacity()
            + self.stale.capacity()
            + self.reference.capacity()
            + self.poses.capacity()
            + self.cell_of.capacity()
            + self.cell_start.capacity()
            + self.cell_items.capacity()
            + self.pairs.capacity()
            + self.slots.capacity()
            + self.wall_slots.capacity()
            + self.loads.capacity()
            + self.stiffness.capacity()
            + self.external.capacity()
            + self.average.capacity()
    }

    /// Checks that the bodies and markers match those given to [`Contacts::new`].
    pub(crate) fn check<M: AsRef<[Marker]>>(&self, bodies: &[RigidBody], markers: &[M]) {
        assert!(
            bodies.len() == self.radius.len() && markers.len() == self.radius.len(),
            "contacts were set up for {} bodies, got {} bodies and {} marker sets",
            self.radius.len(),
            bodies.len(),
            markers.len()
        );
        for (b, m) in markers.iter().enumerate() {
            assert_eq!(
                m.as_ref().len(),
                self.marker_counts[b],
                "body {b}: not the marker set of Contacts::new"
            );
        }
    }

    /// The contact force and torque on every body with the bodies' current states (module
    /// [`super`] for the model, the pair selection and the summation order). Loads on fixed and
    /// prescribed bodies are returned too (for an impeller: the solids torque); applying them
    /// is the caller's business. Deterministic: bitwise the same for any number of threads.
    ///
    /// # Panics
    /// If `bodies` or `markers` do not match those given to [`Contacts::new`].
    pub fn compute<M: AsRef<[Marker]> + Sync>(
        &mut self,
        bodies: &[RigidBody],
        markers: &[M],
    ) -> &[ContactLoad] {
        self.check(bodies, markers);
        self.poses.clear();
        self.poses.extend(bodies.iter().map(Pose::of));
        self.evaluate(bodies, markers);
        &self.loads
    }

    /// Evaluates the contacts at `self.poses`: rebuilds the marker-pair list if a body has
    /// moved by more than half its skin since the last build (module `list`), places the
    /// listed markers, then the loads of every listed body pair and of the walls (in parallel),
    /// accumulated in a fixed order.
    pub(crate) fn evaluate<M: AsRef<[Marker]> + Sync>(&mut self, bodies: &[RigidBody], markers: &[M]) {
        self.stats = ContactStats::default();
        self.loads.resize(bodies.len(), ContactLoad::ZERO);
        if self.reach <= 0.0 {
            self.loads.fill(ContactLoad::ZERO);
            self.wall_reaction = Vec3::zeros();
            return;
        }
        // Scratch sized up front for the largest body, so that which thread meets which pair
        // does not decide when a buffer grows.
        let m = self.marker_counts.iter().copied().max().unwrap_or(0);
        let threads = rayon::current_num_threads().max(1);
        while self.scratch.len() < threads {
            self.scratch.push(Mutex::new(Scratch::sized(m)));
        }
        let n = bodies.len();
        let full = if self.list.valid_for(n) {
            self.list.stale(&self.poses, &self.radius, &mut self.stale);
            // A refresh tests each stale body against every body; past an eighth of them (and
            // more than one) the cell-list broad phase and a full rebuild are cheaper.
            self.stale.len() > (n / 8).max(1)
        } else {
            true
        };
        if full || !self.stale.is_empty() {
            let range = self.reach + self.list.skin();
            if full {
                self.broad_phase(range);
                self.reference.clear();
                self.reference.extend_from_slice(&self.poses);
            } else {
                // The others at their references, the stale ones where they are now.
                self.list.reference_poses(&self.poses, &mut self.reference);
                for &b in &self.stale {
                    self.reference[b as usize] = self.poses[b as usize];
                }
                self.stale_pairs(range);
            }
            let narrow = Narrow {
                p: &self.params,
                skin: self.list.skin(),
                walls: &self.wall_list,
                range,
                wall_range: self.params.cutoff() + 0.5 * self.list.skin(),
                poses: &self.reference,
                radius: &self.radius,
                surface_tol: &self.surface_tol,
                patches: &self.patches,
                bodies,
                markers,
            };
            if full {
                self.list.rebuild(&narrow, &self.pairs, &self.scratch);
            } else {
                self.list.refresh(&narrow, &self.stale, &self.pairs, &self.scratch);
            }
        }
        let (list, params, poses, scratch) = (&self.list, &self.params, &self.poses, &self.scratch);
        let reach2 = self.reach * self.reach;
        self.stats.candidate_pairs = list.pairs().len();
        self.slots.clear();
        self.slots.resize(list.pairs().len(), Slot::EMPTY);
        // Chunks of pairs, one scratch lock each.
        self.slots.par_chunks_mut(EVAL_CHUNK).enumerate().for_each(|(c, out)| {
            let t = rayon::current_thread_index().unwrap_or(0) % scratch.len();
            let mut s = scratch[t].lock().unwrap_or_else(|e| e.into_inner());
            for (o, slot) in out.iter_mut().enumerate() {
                *slot = list.pair_slot(c * EVAL_CHUNK + o, poses, markers, params, reach2, &mut s);
            }
        });
        self.wall_slots.clear();
        self.wall_slots.resize(bodies.len(), Slot::EMPTY);
        if !self.wall_list.is_empty() {
            let walls = &self.wall_list;
            self.wall_slots.par_chunks_mut(EVAL_CHUNK).enumerate().for_each(|(c, out)| {
                let t = rayon::current_thread_index().unwrap_or(0) % scratch.len();
                let mut s = scratch[t].lock().unwrap_or_else(|e| e.into_inner());
                for (o, slot) in out.iter_mut().enumerate() {
                    let b = c * EVAL_CHUNK + o;
                    *slot = list.wall_slot(b, &poses[b], markers, params, walls, &mut s);
                }
            });
        }
        self.stiffness.resize(n, [0.0; 2]);
        self.wall_reaction = accumulate(
            self.list.pairs(),
            &self.slots,
            &self.wall_slots,
            &mut self.loads,
            &mut self.stiffness,
            &mut self.stats,
        );
        stiffness_rates(bodies, &self.stiffness, &mut self.stats);
    }

    /// Sets the skin of the marker-pair list (module `list`; default [`DEFAULT_SKIN`]) and
    /// forgets the list. The loads do not depend on it (bitwise), only the cost.
    ///
    /// # Panics
    /// If `skin` is negative or not finite.
    pub fn set_skin(&mut self, skin: f64) {
        assert!(skin.is_finite() && skin >= 0.0, "the skin must be finite and non-negative");
        self.list = PairList::new(skin);
    }

    /// Rebuilds of the marker-pair list so far, and its current length (marker pairs,
    /// marker–wall pairs).
    pub fn list_stats(&self) -> (u64, usize, usize) {
        let (p, w) = self.list.len();
        (self.list.rebuilds(), p, w)
    }

    /// Full rebuilds of the marker-pair list so far (the rest of [`Contacts::list_stats`]'s
    /// count are refreshes of the bodies that moved).
    pub fn full_rebuilds(&self) -> u64 {
        self.list.full_rebuilds()
    }

    /// The candidate body pairs of a refresh into `self.pairs`: every pair `(a, b)`, `a < b`,
    /// that involves a stale body and passes [`Contacts::broad_phase`]'s test at the
    /// reference poses, sorted, each once.
    fn stale_pairs(&mut self, range: f64) {
        let poses = &self.reference;
        let radius = &self.radius;
        let reach = range + MARGIN;
        self.pairs.clear();
        for &s in &self.stale {
            let s = s as usize;
            for b in 0..poses.len() {
                let (ps, pb) = (&poses[s], &poses[b]);
                let r = radius[s] + radius[b] + reach;
                if b != s && (ps.free || pb.free) && (ps.position - pb.position).norm_squared() < r * r {
                    self.pairs.push((s.min(b) as u32, s.max(b) as u32));
                }
            }
        }
        self.pairs.sort_unstable();
        self.pairs.dedup();
    }

    /// Candidate body pairs `(a, b)`, `a < b`, sorted: bounding spheres closer than `range`
    /// (`|c_a − c_b| < r_a + r_b + range`) and not both bodies non-free.
    fn broad_phase(&mut self, range: f64) {
        let poses = &self.poses;
        let radius = &self.radius;
        let reach = range + MARGIN;
        let pairs = &mut self.pairs;
        pairs.clear();
        let test = |a: usize, b: usize| {
            let (pa, pb) = (&poses[a], &poses[b]);
            let r = radius[a] + radius[b] + reach;
            (pa.free || pb.free) && (pa.position - pb.position).norm_squared() < r * r
        };
        let small = &self.small;
        if !small.is_empty() {
            let (mut lo, mut hi) = (Vec3::repeat(f64::INFINITY), Vec3::repeat(f64::NEG_INFINITY));
            for &b in small {
                lo = lo.inf(&poses[b as usize].position);
                hi = hi.sup(&poses[b as usize].position);
            }
            let edge = 2.0 * self.r_small + range + 2.0 * MARGIN;
            let geo = Geometry::covering(&lo, &hi, edge, 8 * small.len() + 64);
            let (start, items) = (&mut self.cell_start, &mut self.cell_items);
            fill(
                geo.len(),
                small.len(),
                |k| geo.clamped_index(&poses[small[k] as usize].position),
                &mut self.cell_of,
                start,
                items,
            );
            for (k, &a) in small.iter().enumerate() {
                let c = self.cell_of[k] as usize;
                let (cx, cy, cz) =
                    (c % geo.dims[0], (c / geo.dims[0]) % geo.dims[1], c / (geo.dims[0] * geo.dims[1]));
                let Some(r) = geo.neighbours([cx as i64, cy as i64, cz as i64]) else { continue };
                for_cells(&geo, r, |cell| {
                    for &kb in &items[start[cell] as usize..start[cell + 1] as usize] {
                        let b = small[kb as usize];
                        if b > a && test(a as usize, b as usize) {
                            pairs.push((a, b));
                        }
                    }
                });
            }
        }
        for g in (0..self.big.len()).filter(|&g| self.big[g]) {
            for b in 0..self.big.len() {
                if b == g || (self.big[b] && b < g) {
                    continue;
                }
                if test(g, b) {
                    pairs.push((g.min(b) as u32, g.max(b) as u32));
                }
            }
        }
        pairs.sort_unstable();
    }
}
