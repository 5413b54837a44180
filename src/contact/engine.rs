//! [`Contacts`]: broad phase (cell list on bounding spheres), narrow phase (marker patches and bins),
//! parallel per-pair evaluation and the serial, ordered accumulation into per-body loads.

use std::sync::Mutex;

use rayon::prelude::*;

use crate::rigid::{Marker, RigidBody, Vec3};

use super::force::{pair_force, wall_distance, wall_force, Pose, WorldMarker};
use super::grid::{fill, for_cells, Geometry};
use super::params::{ContactParamError, ContactParams, Walls};

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
    /// Body pairs that passed the broad phase (bounding spheres within reach; not both
    /// non-free).
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
        }
    }
}

/// Safety margin (lattice units) added to every pruning radius, far above round-off (≲ 1e-12
/// at coordinates of a few hundred) and far below any physical length: pruning never drops a
/// pair that the exact criterion `|x_j − x_i| < reach` keeps.
pub(crate) const MARGIN: f64 = 1e-6;

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
    };

    /// Adds the force `f` on marker `i` (lever arm `ri`) of body a and `−f` on marker `j`
    /// (lever arm `rj`) of body b. The oracle adds in the same order with the same operations.
    #[inline(always)]
    pub fn add_pair(&mut self, f: &Vec3, ri: &Vec3, rj: &Vec3, delta: f64, energy: f64) {
        self.fa += f;
        self.ta += ri.cross(f);
        self.fb -= f;
        self.tb += rj.cross(&(-f));
        self.count += 1;
        self.min_delta = self.min_delta.min(delta);
        self.energy += energy;
    }

    /// Adds the force `f` of a wall on a marker with lever arm `r` (body a only).
    #[inline(always)]
    pub fn add_wall(&mut self, f: &Vec3, r: &Vec3, delta: f64, energy: f64) {
        self.fa += f;
        self.ta += r.cross(f);
        self.count += 1;
        self.min_delta = self.min_delta.min(delta);
        self.energy += energy;
    }
}

/// Serial accumulation shared by the fast path and the oracle: pair slots in pair order
/// (skipping slots without contacts), then wall slots in body order.
pub(crate) fn accumulate(
    pairs: &[(u32, u32)],
    slots: &[Slot],
    wall_slots: &[Slot],
    loads: &mut [ContactLoad],
    stats: &mut ContactStats,
) -> Vec3 {
    loads.fill(ContactLoad::ZERO);
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
        reaction -= s.fa;
        stats.wall_contacts += s.count as usize;
        stats.min_delta = stats.min_delta.min(s.min_delta);
        stats.elastic_energy += s.energy;
    }
    reaction
}

/// Edge of the cubes that group a body's markers into patches (lattice units): a patch of a
/// surface holds ≈ 8 markers at spacing 0.7.
const PATCH_EDGE: f64 = 2.0;

/// Static patches of one body's markers (body frame, built once): the markers binned into
/// cubes of edge [`PATCH_EDGE`]; every non-empty cube is a patch, with the bounding sphere of
/// its markers. A query prunes whole patches with one signed-distance evaluation (module
/// [`super`], "Narrow phase").
#[derive(Clone, Debug)]
struct Patches {
    geo: Geometry,
    /// Per grid cell: its patch, or `u32::MAX` if empty.
    cell_patch: Vec<u32>,
    centre: Vec<Vec3>,
    radius: Vec<f64>,
    /// Patch `k` holds the markers `items[start[k]..start[k + 1]]` (increasing index).
    start: Vec<u32>,
    items: Vec<u32>,
    /// Centre and half size of the axis-aligned box of all the body's markers (body frame).
    box_centre: Vec3,
    box_half: Vec3,
}

impl Patches {
    fn new(markers: &[Marker]) -> Self {
        let (mut lo, mut hi) = (Vec3::repeat(f64::INFINITY), Vec3::repeat(f64::NEG_INFINITY));
        for m in markers {
            lo = lo.inf(&m.position);
            hi = hi.sup(&m.position);
        }
        if markers.is_empty() {
            (lo, hi) = (Vec3::zeros(), Vec3::zeros());
        }
        let geo = Geometry::covering(&lo, &hi, PATCH_EDGE, 8 * markers.len() + 64);
        let (mut cell_of, mut cell_start, mut items) = (Vec::new(), Vec::new(), Vec::new());
        fill(
            geo.len(),
            markers.len(),
            |k| geo.clamped_index(&markers[k].position),
            &mut cell_of,
            &mut cell_start,
            &mut items,
        );
        let mut p = Self {
            geo,
            cell_patch: vec![u32::MAX; geo.len()],
            centre: Vec::new(),
            radius: Vec::new(),
            start: Vec::new(),
            items,
            box_centre: (lo + hi) * 0.5,
            box_half: (hi - lo) * 0.5,
        };
        for c in 0..geo.len() {
            let range = cell_start[c] as usize..cell_start[c + 1] as usize;
            if range.is_empty() {
                continue;
            }
            let (mut a, mut b) = (Vec3::repeat(f64::INFINITY), Vec3::repeat(f64::NEG_INFINITY));
            for &k in &p.items[range.clone()] {
                a = a.inf(&markers[k as usize].position);
                b = b.sup(&markers[k as usize].position);
            }
            let centre = (a + b) * 0.5;
            let r = p.items[range.clone()]
                .iter()
                .map(|&k| (markers[k as usize].position - centre).norm())
                .fold(0.0, f64::max);
            p.cell_patch[c] = p.centre.len() as u32;
            p.centre.push(centre);
            p.radius.push(r);
            p.start.push(range.start as u32);
        }
        p.start.push(p.items.len() as u32);
        p
    }

    /// Calls `f(k)` for every patch `k` whose bounding sphere meets the ball `|x − p| < rho`
    /// (body frame).
    #[inline(always)]
    fn visit(&self, p: &Vec3, rho: f64, mut f: impl FnMut(usize)) {
        let Some(r) = self.geo.range(p, rho) else { return };
        let mut test = |k: usize| {
            let reach = rho + self.radius[k];
            if (self.centre[k] - p).norm_squared() < reach * reach {
                f(k);
            }
        };
        let cells = (0..3).map(|a| r[a][1] - r[a][0] + 1).product::<usize>();
        if cells > self.centre.len() {
            (0..self.centre.len()).for_each(&mut test);
        } else {
            for_cells(&self.geo, r, |c| {
                let k = self.cell_patch[c];
                if k != u32::MAX {
                    test(k as usize);
                }
            });
        }
    }

    /// Squared distance from `q` (body frame) to the box of the markers: a lower bound of the
    /// squared distance from `q` to every marker of the body.
    #[inline(always)]
    fn box_distance2(&self, q: &Vec3) -> f64 {
        let e = ((q - self.box_centre).abs() - self.box_half).sup(&Vec3::zeros());
        e.norm_squared()
    }

    /// The markers of patch `k`.
    #[inline(always)]
    fn markers(&self, k: usize) -> &[u32] {
        &self.items[self.start[k] as usize..self.start[k + 1] as usize]
    }
}

/// An interacting marker pair found by the narrow phase.
#[derive(Clone, Copy, Debug)]
struct Active {
    i: u32,
    j: u32,
    f: Vec3,
    ri: Vec3,
    rj: Vec3,
    delta: f64,
    energy: f64,
}

/// Per-thread buffers of the narrow phase.
#[derive(Debug, Default)]
struct Scratch {
    a: Vec<WorldMarker>,
    b: Vec<WorldMarker>,
    cell_of: Vec<u32>,
    start: Vec<u32>,
    items: Vec<u32>,
    active: Vec<Active>,
}

impl Scratch {
    fn capacity(&self) -> usize {
        self.a.capacity()
            + self.b.capacity()
            + self.cell_of.capacity()
            + self.start.capacity()
            + self.items.capacity()
            + self.active.capacity()
    }
}

/// What the per-pair and per-body kernels read.
struct Ctx<'a, M> {
    p: &'a ContactParams,
    walls: &'a [(usize, f64, Vec3)],
    reach: f64,
    poses: &'a [Pose],
    radius: &'a [f64],
    surface_tol: &'a [f64],
    patches: &'a [Patches],
    bodies: &'a [RigidBody],
    markers: &'a [M],
}

impl<M: AsRef<[Marker]>> Ctx<'_, M> {
    /// The markers of body `a` that may lie within `reach` of a marker of body `b`, in world
    /// coordinates (module [`super`], "Narrow phase"): `a`'s patches that meet `b`'s bounding
    /// sphere grown by `reach`, then the patches and markers within `reach + tol_b` of `b`'s
    /// surface (`|sd_b|`; `tol_b` the largest `|sd_b|` of `b`'s own markers). Exact pruning: a
    /// marker within `reach` of one of `b`'s markers is within `reach + tol_b` of `b`'s
    /// surface, and `|sd_b|` is 1-Lipschitz, so a patch whose centre has
    /// `|sd_b| ≥ reach + tol_b + radius` holds no such marker.
    fn collect(&self, a: usize, b: usize, out: &mut Vec<WorldMarker>) {
        out.clear();
        let (pa, pb) = (&self.poses[a], &self.poses[b]);
        let ma = self.markers[a].as_ref();
        let shape = self.bodies[b].shape();
        let rho = self.radius[b] + self.reach + MARGIN;
        let lim = self.reach + self.surface_tol[b] + MARGIN;
        // Body frame of `a` → body frame of `b`: q = R_bᵀ R_a m + R_bᵀ (x_a − x_b).
        let rot = pb.rotation.tr_mul(&pa.rotation);
        let shift = pb.rotation.tr_mul(&(pa.position - pb.position));
        let centre_b = pa.rotation.tr_mul(&(pb.position - pa.position));
        let patches = &self.patches[a];
        let other = &self.patches[b];
        let near = self.reach + MARGIN;
        let near2 = near * near;
        patches.visit(&centre_b, rho, |k| {
            let q = rot * patches.centre[k] + shift;
            let r = patches.radius[k];
            if other.box_distance2(&q) >= (near + r) * (near + r)
                || shape.signed_distance(&q).abs() >= lim + r
            {
                return;
            }
            for &i in patches.markers(k) {
                let m = &ma[i as usize];
                let q = rot * m.position + shift;
                if other.box_distance2(&q) < near2 && shape.signed_distance(&q).abs() < lim {
                    let (r, x) = pa.marker_position(m);
                    let (n, u) = pa.marker_normal_velocity(m, &r);
                    out.push(WorldMarker { index: i, r, x, n, u });
                }
            }
        });
    }

    /// Whether no marker of `a` can come within `reach` of `b`'s markers: `a`'s bounding
    /// sphere is farther than `reach` from the box of `b`'s markers, or `sd_b` at `a`'s centre
    /// exceeds `a`'s bounding radius by `reach + tol_b` (1-Lipschitz, as above).
    fn apart(&self, a: usize, b: usize) -> bool {
        let (pa, pb) = (&self.poses[a], &self.poses[b]);
        let c = pb.rotation.tr_mul(&(pa.position - pb.position));
        let gap = self.radius[a] + self.reach + MARGIN;
        self.patches[b].box_distance2(&c) >= gap * gap
            || self.bodies[b].shape().signed_distance(&c) - self.radius[a]
                >= self.reach + self.surface_tol[b] + MARGIN
    }

    /// The loads of body pair `(a, b)`, `a < b`.
    fn pair(&self, a: usize, b: usize, s: &mut Scratch) -> Slot {
        let Scratch { a: ma, b: mb, cell_of, start, items, active } = s;
        if self.apart(a, b) || self.apart(b, a) {
            return Slot::EMPTY;
        }
        self.collect(a, b, ma);
        if ma.is_empty() {
            return Slot::EMPTY;
        }
        self.collect(b, a, mb);
        if mb.is_empty() {
            return Slot::EMPTY;
        }
        let (mut lo, mut hi) = (mb[0].x, mb[0].x);
        for m in mb.iter() {
            lo = lo.inf(&m.x);
            hi = hi.sup(&m.x);
        }
        // Bins of edge ≥ reach: a partner within `reach` is in one of the 27 neighbours.
        let geo = Geometry::covering(&lo, &hi, self.reach, 4 * mb.len() + 64);
        fill(geo.len(), mb.len(), |k| geo.clamped_index(&mb[k].x), cell_of, start, items);
        let reach2 = self.reach * self.reach;
        active.clear();
        for mi in ma.iter() {
            let Some(r) = geo.neighbours(geo.coords(&mi.x)) else { continue };
            for_cells(&geo, r, |c| {
                for &k in &items[start[c] as usize..start[c + 1] as usize] {
                    let mj = &mb[k as usize];
                    if (mj.x - mi.x).norm_squared() < reach2 {
                        if let Some(h) = pair_force(self.p, mi, mj) {
                            active.push(Active {
                                i: mi.index,
                                j: mj.index,
                                f: h.force,
                                ri: mi.r,
                                rj: mj.r,
                                delta: h.delta,
                                energy: h.elastic_energy(self.p),
                            });
                        }
                    }
                }
            });
        }
        // The oracle's order: (i, j) lexicographic.
        active.sort_unstable_by_key(|h| (h.i, h.j));
        let mut slot = Slot::EMPTY;
        for h in active.iter() {
            slot.add_pair(&h.f, &h.ri, &h.rj, h.delta, h.energy);
        }
        slot
    }

    /// The loads of the walls on body `b` (free bodies only): patches within the cutoff of a
    /// wall (centre distance minus patch radius), their markers against those walls; the hits
    /// summed in the oracle's order (marker index, then wall order).
    fn walls_on(&self, b: usize, s: &mut Scratch) -> Slot {
        let pose = &self.poses[b];
        let mut slot = Slot::EMPTY;
        if !pose.free || self.walls.is_empty() {
            return slot;
        }
        let cutoff = self.p.cutoff();
        let mut near = [false; 6];
        let mut any = false;
        for (w, (axis, plane, nhat)) in self.walls.iter().enumerate() {
            near[w] = wall_distance(*axis, *plane, nhat, &pose.position) - self.radius[b] < cutoff + MARGIN;
            any |= near[w];
        }
        if !any {
            return slot;
        }
        let ms = self.markers[b].as_ref();
        let patches = &self.patches[b];
        let active = &mut s.active;
        active.clear();
        for k in 0..patches.centre.len() {
            let c = pose.position + pose.rotation * patches.centre[k];
            let mut hit = [false; 6];
            let mut any = false;
            for (w, (axis, plane, nhat)) in self.walls.iter().enumerate() {
                hit[w] =
                    near[w] && wall_distance(*axis, *plane, nhat, &c) - patches.radius[k] < cutoff + MARGIN;
                any |= hit[w];
            }
            if !any {
                continue;
            }
            for &i in patches.markers(k) {
                let m = &ms[i as usize];
                let (r, x) = pose.marker_position(m);
                let mut nu: Option<(Vec3, Vec3)> = None;
                for (w, (axis, plane, nhat)) in self.walls.iter().enumerate() {
                    if !hit[w] || wall_distance(*axis, *plane, nhat, &x) >= cutoff {
                        continue;
                    }
                    let (n, u) = *nu.get_or_insert_with(|| pose.marker_normal_velocity(m, &r));
                    if let Some(h) = wall_force(self.p, *axis, *plane, nhat, &x, &n, &u) {
                        active.push(Active {
                            i,
                            j: w as u32,
                            f: h.force,
                            ri: r,
                            rj: r,
                            delta: h.delta,
                            energy: h.elastic_energy(self.p),
                        });
                    }
                }
            }
        }
        active.sort_unstable_by_key(|h| (h.i, h.j));
        for h in active.iter() {
            slot.add_wall(&h.f, &h.ri, h.delta, h.energy);
        }
        slot
    }
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
    cell_edge: f64,
    // Per evaluation.
    pub(crate) poses: Vec<Pose>,
    cell_of: Vec<u32>,
    cell_start: Vec<u32>,
    cell_items: Vec<u32>,
    pairs: Vec<(u32, u32)>,
    slots: Vec<Slot>,
    wall_slots: Vec<Slot>,
    pub(crate) loads: Vec<ContactLoad>,
    wall_reaction: Vec3,
    stats: ContactStats,
    scratch: Vec<Mutex<Scratch>>,
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
        let cell_edge = 2.0 * r_small + reach + 2.0 * MARGIN;
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
            cell_edge,
            radius,
            poses: Vec::with_capacity(n),
            cell_of: Vec::new(),
            cell_start: Vec::new(),
            cell_items: Vec::new(),
            pairs: Vec::new(),
            slots: Vec::new(),
            wall_slots: Vec::with_capacity(n),
            loads: vec![ContactLoad::ZERO; n],
            wall_reaction: Vec3::zeros(),
            stats: ContactStats::default(),
            scratch: Vec::new(),
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
        let scratch: usize =
            self.scratch.iter().map(|s| s.lock().unwrap_or_else(|e| e.into_inner()).capacity()).sum();
        scratch
            + self.poses.capacity()
            + self.cell_of.capacity()
            + self.cell_start.capacity()
            + self.cell_items.capacity()
            + self.pairs.capacity()
            + self.slots.capacity()
            + self.wall_slots.capacity()
            + self.loads.capacity()
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

    /// Evaluates the contacts at `self.poses`.
    pub(crate) fn evaluate<M: AsRef<[Marker]> + Sync>(&mut self, bodies: &[RigidBody], markers: &[M]) {
        self.stats = ContactStats::default();
        self.broad_phase();
        self.stats.candidate_pairs = self.pairs.len();
        let threads = rayon::current_num_threads().max(1);
        while self.scratch.len() < threads {
            // Sized up front for the largest body, so that which thread meets which pair does
            // not decide when a buffer grows: a body contributes at most all its markers to a
            // pair, its bins number at most `4 m + 64` (`collect`), and a marker has at most a
            // handful of partners within `reach` (16 per marker reserved).
            let m = self.marker_counts.iter().copied().max().unwrap_or(0);
            self.scratch.push(Mutex::new(Scratch {
                a: Vec::with_capacity(m),
                b: Vec::with_capacity(m),
                cell_of: Vec::with_capacity(m),
                start: Vec::with_capacity(4 * m + 65),
                items: Vec::with_capacity(m),
                active: Vec::with_capacity(16 * m),
            }));
        }
        let ctx = Ctx {
            p: &self.params,
            walls: &self.wall_list,
            reach: self.reach,
            poses: &self.poses,
            radius: &self.radius,
            surface_tol: &self.surface_tol,
            patches: &self.patches,
            bodies,
            markers,
        };
        let scratch = &self.scratch;
        self.slots.clear();
        self.slots.resize(self.pairs.len(), Slot::EMPTY);
        if self.reach > 0.0 {
            self.pairs.par_iter().zip(self.slots.par_iter_mut()).for_each(|(&(a, b), slot)| {
                let t = rayon::current_thread_index().unwrap_or(0) % scratch.len();
                let mut s = scratch[t].lock().unwrap_or_else(|e| e.into_inner());
                *slot = ctx.pair(a as usize, b as usize, &mut s);
            });
        }
        self.wall_slots.clear();
        self.wall_slots.resize(bodies.len(), Slot::EMPTY);
        if self.reach > 0.0 && !self.wall_list.is_empty() {
            self.wall_slots.par_iter_mut().enumerate().for_each(|(b, slot)| {
                let t = rayon::current_thread_index().unwrap_or(0) % scratch.len();
                let mut s = scratch[t].lock().unwrap_or_else(|e| e.into_inner());
                *slot = ctx.walls_on(b, &mut s);
            });
        }
        self.loads.resize(bodies.len(), ContactLoad::ZERO);
        self.wall_reaction =
            accumulate(&self.pairs, &self.slots, &self.wall_slots, &mut self.loads, &mut self.stats);
    }

    /// Candidate body pairs `(a, b)`, `a < b`, sorted: bounding spheres closer than `reach`
    /// (`|c_a − c_b| < r_a + r_b + reach`) and not both bodies non-free.
    fn broad_phase(&mut self) {
        let poses = &self.poses;
        let radius = &self.radius;
        let reach = self.reach + MARGIN;
        let pairs = &mut self.pairs;
        pairs.clear();
        if self.reach <= 0.0 {
            return;
        }
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
            let geo = Geometry::covering(&lo, &hi, self.cell_edge, 8 * small.len() + 64);
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
