//! [`Contacts`], the contact model's state and its evaluation: the per-body data computed once
//! (bounding radii, surface tolerances, marker patches), every buffer of an evaluation, and
//! the evaluation itself (module docs, "Evaluation"): the marker-pair list rebuilt or refreshed
//! when a body has moved beyond half the skin (the broad phase in module `broad`, the narrow
//! phase in module `list`), the per-pair and wall slots filled in parallel, then added in a
//! fixed order (module `slots`).

use std::sync::Mutex;

use rayon::prelude::*;

use crate::rigid::{Marker, RigidBody, Vec3};

use super::broad::BroadPhase;
use super::force::Pose;
use super::implicit::{Implicit, ImplicitSolver};
use super::list::{scratch_capacity, Narrow, PairList, Scratch, DEFAULT_SKIN};
use super::operator::{lubrication_loads, velocity, Mat6, PairOperator, Vec6};
use super::params::{ContactParamError, ContactParams, Walls};
use super::patches::Patches;
use super::slots::{accumulate, inverse_masses, stiffness_rates, ContactLoad, ContactStats, Slot};

/// Body pairs (or bodies, for the walls) per parallel task of an evaluation.
const EVAL_CHUNK: usize = 32;

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
    // Per evaluation.
    pub(crate) poses: Vec<Pose>,
    /// The candidate body pairs of a list build (and its cell list).
    broad: BroadPhase,
    /// Bodies whose list entries are found again in this evaluation.
    stale: Vec<u32>,
    /// Poses at which the list's entries are found (the narrow phase's).
    reference: Vec<Pose>,
    slots: Vec<Slot>,
    wall_slots: Vec<Slot>,
    /// With lubrication sub-steps (module [`super`], "Lubrication sub-steps"): per listed pair
    /// and per body against the walls, the lubrication of the last evaluation as a linear
    /// map of the velocities (valid where the slot has a contact), the bodies' velocities it
    /// is applied to, and the loads it gives. Empty otherwise.
    ops: Vec<PairOperator>,
    wall_ops: Vec<Mat6>,
    velocities: Vec<Vec6>,
    pub(crate) lubrication: Vec<ContactLoad>,
    pub(crate) loads: Vec<ContactLoad>,
    /// Per body `(Σ c, Σ k w)` of the last evaluation ([`ContactStats::damping_rate`]).
    stiffness: Vec<[f64; 2]>,
    /// Per body `[1/m, 1]` (zero for non-free bodies: the weights of the translational and
    /// rotational parts of its damping-rate bound `ρ`) and `ρ` itself (module `slots`,
    /// `accumulate`).
    inverse_mass: Vec<[f64; 2]>,
    mobility: Vec<f64>,
    wall_reaction: Vec3,
    stats: ContactStats,
    scratch: Vec<Mutex<Scratch>>,
    list: PairList,
    // Sub-cycling (module `subcycle`).
    pub(crate) external: Vec<ContactLoad>,
    pub(crate) external_prev: Vec<Option<ContactLoad>>,
    pub(crate) average: Vec<ContactLoad>,
    /// The lubrication summed over the lubrication sub-steps of a contact sub-step.
    pub(crate) lubrication_sum: Vec<ContactLoad>,
    /// With implicit damping (module `implicit`): the solve's buffers and, per body, the known
    /// load of the sub-step (external plus elastic).
    implicit: Implicit,
    pub(crate) known: Vec<Vec6>,
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
        let broad = BroadPhase::new(&radius);
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
            radius,
            poses: Vec::with_capacity(n),
            broad,
            stale: Vec::new(),
            reference: Vec::with_capacity(n),
            slots: Vec::new(),
            wall_slots: Vec::with_capacity(n),
            ops: Vec::new(),
            wall_ops: Vec::new(),
            velocities: Vec::new(),
            lubrication: Vec::new(),
            loads: vec![ContactLoad::ZERO; n],
            stiffness: vec![[0.0; 2]; n],
            inverse_mass: Vec::with_capacity(n),
            mobility: Vec::with_capacity(n),
            wall_reaction: Vec3::zeros(),
            stats: ContactStats::default(),
            scratch: Vec::new(),
            list: PairList::new(DEFAULT_SKIN),
            external: Vec::with_capacity(n),
            external_prev: vec![None; n],
            average: vec![ContactLoad::ZERO; n],
            lubrication_sum: Vec::new(),
            implicit: Implicit::default(),
            known: Vec::new(),
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
            + self.broad.capacity()
            + self.slots.capacity()
            + self.wall_slots.capacity()
            + self.ops.capacity()
            + self.wall_ops.capacity()
            + self.velocities.capacity()
            + self.lubrication.capacity()
            + self.loads.capacity()
            + self.stiffness.capacity()
            + self.external.capacity()
            + self.average.capacity()
            + self.lubrication_sum.capacity()
            + self.implicit.capacity()
            + self.known.capacity()
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
        self.evaluate(bodies, markers, 0.0);
        &self.loads
    }

    /// Evaluates the contacts at `self.poses`: rebuilds the marker-pair list if a body has
    /// moved by more than half its skin since the last build (module `list`), places the
    /// listed markers, then the loads of every listed body pair and of the walls (in parallel),
    /// accumulated in a fixed order. `h`: the length of the sub-step the loads are for, with
    /// which the lubrication is limited (module [`super`], "Lubrication limiter"); 0 for the
    /// explicit law.
    pub(crate) fn evaluate<M: AsRef<[Marker]> + Sync>(
        &mut self,
        bodies: &[RigidBody],
        markers: &[M],
        h: f64,
    ) {
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
                self.broad.all_pairs(&self.poses, &self.radius, range);
                self.reference.clear();
                self.reference.extend_from_slice(&self.poses);
            } else {
                // The others at their references, the stale ones where they are now.
                self.list.reference_poses(&self.poses, &mut self.reference);
                for &b in &self.stale {
                    self.reference[b as usize] = self.poses[b as usize];
                }
                self.broad.stale_pairs(&self.stale, &self.reference, &self.radius, range);
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
                self.list.rebuild(&narrow, self.broad.pairs(), &self.scratch);
            } else {
                self.list.refresh(&narrow, &self.stale, self.broad.pairs(), &self.scratch);
            }
        }
        let (list, params, poses, scratch) = (&self.list, &self.params, &self.poses, &self.scratch);
        self.stats.candidate_pairs = list.pairs().len();
        let operators = params.operators();
        let pairs = list.pairs().len();
        self.slots.clear();
        self.slots.resize(pairs, Slot::EMPTY);
        // Only the entries of pairs in contact are written and read (no clearing).
        self.ops.resize(if operators { pairs } else { 0 }, PairOperator::ZERO);
        // Chunks of pairs (and their operators), one scratch lock each.
        let ops = if operators { Some(&mut self.ops[..]) } else { None };
        par_chunks(&mut self.slots, ops, |c, out, mut ops| {
            let t = rayon::current_thread_index().unwrap_or(0) % scratch.len();
            let mut s = scratch[t].lock().unwrap_or_else(|e| e.into_inner());
            for (o, slot) in out.iter_mut().enumerate() {
                let op = ops.as_deref_mut().map(|ops| &mut ops[o]);
                *slot = list.pair_slot(c * EVAL_CHUNK + o, poses, markers, params, &mut s, op);
            }
        });
        self.wall_slots.clear();
        self.wall_slots.resize(bodies.len(), Slot::EMPTY);
        self.wall_ops.resize(if operators { bodies.len() } else { 0 }, Mat6::zeros());
        if !self.wall_list.is_empty() {
            let walls = &self.wall_list;
            let ops = if operators { Some(&mut self.wall_ops[..]) } else { None };
            par_chunks(&mut self.wall_slots, ops, |c, out, mut ops| {
                let t = rayon::current_thread_index().unwrap_or(0) % scratch.len();
                let mut s = scratch[t].lock().unwrap_or_else(|e| e.into_inner());
                for (o, slot) in out.iter_mut().enumerate() {
                    let b = c * EVAL_CHUNK + o;
                    let op = ops.as_deref_mut().map(|ops| &mut ops[o]);
                    *slot = list.wall_slot(b, &poses[b], markers, params, walls, &mut s, op);
                }
            });
        }
        self.stiffness.resize(n, [0.0; 2]);
        inverse_masses(bodies, &mut self.inverse_mass);
        self.wall_reaction = accumulate(
            self.list.pairs(),
            &self.slots,
            &self.wall_slots,
            &mut self.loads,
            &mut self.stiffness,
            &mut self.stats,
            h,
            &self.inverse_mass,
            &mut self.mobility,
        );
        stiffness_rates(bodies, &self.stiffness, &mut self.stats);
    }

    /// The lubrication loads of every body from the operators of the last evaluation (which
    /// must have had [`ContactParams::lubrication_substeps`] above 1) at the bodies' velocities
    /// `dt` after their clocks (module `operator`, [`velocity`]), into
    /// `self.lubrication`.
    pub(crate) fn lubrication_from_operators(&mut self, bodies: &[RigidBody], dt: f64) {
        debug_assert_eq!(self.ops.len(), self.list.pairs().len());
        self.set_velocities(bodies, dt);
        self.loads_at_velocities(bodies.len());
    }

    /// `self.velocities`: every body's `(v, ω)` `dt` after its clock ([`velocity`]).
    fn set_velocities(&mut self, bodies: &[RigidBody], dt: f64) {
        self.velocities.clear();
        self.velocities.extend(bodies.iter().map(|b| velocity(b, dt)));
    }

    /// The lubrication loads of the last evaluation's operators at `self.velocities`, into
    /// `self.lubrication` (`bodies` loads).
    fn loads_at_velocities(&mut self, bodies: usize) {
        self.lubrication.resize(bodies, ContactLoad::ZERO);
        lubrication_loads(
            self.list.pairs(),
            &self.ops,
            &self.slots,
            &self.wall_ops,
            &self.wall_slots,
            &self.velocities,
            &mut self.lubrication,
        );
    }

    /// Implicit damping (module `implicit`) over a sub-step of length `h` after an evaluation
    /// with operators: solves for the velocities at the sub-step's end under the known loads
    /// `self.known` (free bodies) and the damping of the evaluation's operators (prescribed
    /// bodies at their velocities `dt` after their clocks), and puts the damping loads at those
    /// velocities into `self.lubrication`. Returns the number of bodies in the solve.
    pub(crate) fn implicit_damping(&mut self, bodies: &[RigidBody], h: f64, dt: f64) -> usize {
        debug_assert_eq!(self.ops.len(), self.list.pairs().len());
        self.set_velocities(bodies, dt);
        self.implicit.solve(
            bodies,
            h,
            self.list.pairs(),
            &self.ops,
            &self.slots,
            &self.wall_ops,
            &self.wall_slots,
            &self.known,
            &mut self.velocities,
        );
        self.loads_at_velocities(bodies.len());
        self.implicit.unknowns
    }

    /// With implicit damping: the time spent so far in its solves, `(assembly, factorisation
    /// and solve)` in seconds, and the free bodies in the last solve (benchmarks).
    pub fn implicit_solve_time(&self) -> (f64, f64, usize) {
        let [a, s] = self.implicit.seconds;
        (a, s, self.implicit.unknowns)
    }

    /// Chooses the linear solver of the implicit damping (default
    /// [`ImplicitSolver::ConjugateGradient`]; benchmarks: the two agree to the conjugate
    /// gradients' tolerance).
    pub fn set_implicit_solver(&mut self, solver: ImplicitSolver) {
        self.implicit.solver = solver;
    }

    /// Conjugate-gradient iterations of the implicit damping so far.
    pub fn implicit_cg_iterations(&self) -> u64 {
        self.implicit.iterations
    }

    /// The per-body velocities of the last implicit solve (tests).
    #[cfg(test)]
    pub(crate) fn solved_velocities(&self) -> &[Vec6] {
        &self.velocities
    }

    /// The damping matrix `C` of the last implicit solve, dense, over its unknowns (tests).
    #[cfg(test)]
    pub(crate) fn damping_matrix(&self, bodies: &[RigidBody], h: f64) -> nalgebra::DMatrix<f64> {
        self.implicit.damping_matrix(bodies, h)
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
}

/// `f(c, chunk, ops_chunk)` for every chunk `c` of [`EVAL_CHUNK`] slots, in parallel, with the
/// matching chunk of `ops` when given (one entry per slot).
fn par_chunks<O: Send>(
    slots: &mut [Slot],
    ops: Option<&mut [O]>,
    f: impl Fn(usize, &mut [Slot], Option<&mut [O]>) + Sync + Send,
) {
    match ops {
        Some(ops) => (slots.par_chunks_mut(EVAL_CHUNK), ops.par_chunks_mut(EVAL_CHUNK))
            .into_par_iter()
            .enumerate()
            .for_each(|(c, (out, ops))| f(c, out, Some(ops))),
        None => slots.par_chunks_mut(EVAL_CHUNK).enumerate().for_each(|(c, out)| f(c, out, None)),
    }
}
