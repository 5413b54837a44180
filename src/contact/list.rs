//! The marker-pair list: every marker pair (and every marker–wall pair) that may come within
//! reach while the bodies stay within half a **skin** of where they were when the list was
//! built — a Verlet list with a skin, reused across the contact sub-steps and across fluid
//! steps (module [`super`], "Evaluation").
//!
//! **Exactness.** The list holds every marker pair with `|x_j − x_i| < reach + skin` at the
//! build poses (the narrow phase of [`Narrow`], run with that range). A marker of body `b`
//! moves, from the build pose `(c₀, R₀)` to a pose `(c, R)`, by at most
//!
//! ```text
//! s_b = |c − c₀| + r_b ‖R − R₀‖_F     (r_b the body's bounding radius; ‖·‖_F ≥ ‖·‖₂)
//! ```
//!
//! so while every body has `s_b ≤ skin/2`, a pair not in the list is still farther apart than
//! `reach` and does not interact. The poses are per body **references**: at the first
//! evaluation where some bodies have moved more (they are *stale*), only their entries are
//! found again, at their current poses (their new references) against the other bodies'
//! references, and merged with the rest of the list in body-pair order
//! ([`PairList::refresh`]); the argument above holds pair by pair. When more than an eighth of
//! the bodies are stale the whole list is rebuilt. A turning impeller (tips moving by tenths of
//! a spacing per fluid step) is so refreshed alone, without rebuilding the bed's list. Walls likewise: a marker is listed against a wall when it is within
//! `cutoff + skin/2` of it. Within a body pair the list is sorted by `(i, j)` (marker indices),
//! against the walls by `(i, wall)`: the order in which the interacting pairs are summed is
//! the oracle's, so the loads are **bitwise those of the brute-force [`super::oracle`]**
//! whenever the list was built or refreshed, and whatever the number of threads (the list's content does
//! not depend on them).
//!
//! **Which pairs.** Within the range, a pair is listed only if it can still interact before
//! the rebuild: its normals can turn to face each other (`n_i·n_j ≤ ρ_a + ρ_b`, with
//! `ρ_b = skin/(2 r_b)` the largest rotation the validity test allows) and its tangential
//! distance can fall below `λ` (a lower bound of `δ_λ` after any allowed motion, in
//! [`Narrow`]'s pair search). In a resting bed of flat faces this lists about 3× the
//! interacting pairs instead of 13× for the range alone.
//!
//! **Cost.** A rebuild costs what one evaluation of a narrow phase at every sub-step costs
//! (patches, signed-distance pruning, per-pair bins); an evaluation from the list costs one
//! transform per listed marker and one distance test per listed pair, plus the force law of
//! the pairs within reach.

use std::sync::Mutex;

use rayon::prelude::*;

use crate::rigid::{Marker, Mat3, RigidBody, Vec3};

use super::force::{wall_distance, wall_force, PairBatch, Pose, WorldMarker, BATCH};
use super::grid::{fill, for_cells, Geometry};
use super::operator::{LubMoments, Mat6, PairOperator};
use super::params::ContactParams;
use super::patches::Patches;
use super::slots::Slot;
use super::MARGIN;

/// Default skin (lattice units): a body may move by 0.075 spacings before its entries are
/// found again. Since only the bodies that moved are refreshed, a small skin costs little:
/// pbt-ld2 at s = 1/4 after the ramp (2 threads, 40 steps) spent 28.5 ms per fluid step on
/// contacts with a skin of 0.3 (200 725 listed marker pairs, 188 partial refreshes), 21.8 ms
/// with 0.15 (105 029 pairs, 264 refreshes) and 24.5 ms with 0.1 (82 162 pairs, 301
/// refreshes); every listed pair is tested at every sub-step.
pub const DEFAULT_SKIN: f64 = 0.15;

/// Body pairs handed to one parallel task of a rebuild (a fixed grouping: the list does not
/// depend on the number of threads).
const CHUNK: usize = 16;

/// Marker pairs filtered by distance at a time in [`PairList::pair_slot`].
const FILTER_CHUNK: usize = BATCH;

/// Per-thread buffers of the rebuild's narrow phase.
#[derive(Debug, Default)]
pub(crate) struct Scratch {
    a: Vec<WorldMarker>,
    b: Vec<WorldMarker>,
    ca: Vec<WorldMarker>,
    cb: Vec<WorldMarker>,
    cell_of: Vec<u32>,
    start: Vec<u32>,
    items: Vec<u32>,
    found: Vec<[u32; 2]>,
    batch: Box<PairBatch>,
}

impl Scratch {
    /// Buffers sized for bodies of up to `m` markers.
    pub fn sized(m: usize) -> Self {
        Self {
            a: Vec::with_capacity(m),
            b: Vec::with_capacity(m),
            ca: Vec::with_capacity(m),
            cb: Vec::with_capacity(m),
            cell_of: Vec::with_capacity(m),
            start: Vec::with_capacity(4 * m + 65),
            items: Vec::with_capacity(m),
            found: Vec::with_capacity(8 * m),
            batch: Box::default(),
        }
    }

    fn capacity(&self) -> usize {
        self.a.capacity()
            + self.b.capacity()
            + self.ca.capacity()
            + self.cb.capacity()
            + self.cell_of.capacity()
            + self.start.capacity()
            + self.items.capacity()
            + self.found.capacity()
    }
}

/// The search of one item (body pair or body) of a rebuild: appends its entries, returns how
/// many.
type Finder<'a> = dyn Fn(usize, &mut Scratch, &mut Vec<[u32; 2]>) -> u32 + Sync + 'a;

/// The output of one rebuild task: per body pair (or body) of its chunk the number of entries,
/// and the entries in order.
#[derive(Debug, Default)]
struct ChunkOut {
    counts: Vec<u32>,
    entries: Vec<[u32; 2]>,
}

/// What the rebuild's narrow phase reads.
pub(crate) struct Narrow<'a, M> {
    pub p: &'a ContactParams,
    /// The skin of the list being built.
    pub skin: f64,
    pub walls: &'a [(usize, f64, Vec3)],
    /// The listing range: `reach + skin`.
    pub range: f64,
    /// The listing distance from a wall: `cutoff + skin/2`.
    pub wall_range: f64,
    pub poses: &'a [Pose],
    pub radius: &'a [f64],
    pub surface_tol: &'a [f64],
    pub patches: &'a [Patches],
    pub bodies: &'a [RigidBody],
    pub markers: &'a [M],
}

impl<M: AsRef<[Marker]>> Narrow<'_, M> {
    /// The markers of body `a` that may lie within `range` of a marker of body `b`, in world
    /// coordinates: `a`'s patches that meet `b`'s bounding sphere grown by `range`, then the
    /// patches and markers within `range + tol_b` of `b`'s surface (`|sd_b|`; `tol_b` the
    /// largest `|sd_b|` of `b`'s own markers). Exact pruning: a marker within `range` of one of
    /// `b`'s markers is within `range + tol_b` of `b`'s surface, and `|sd_b|` is 1-Lipschitz,
    /// so a patch whose centre has `|sd_b| ≥ range + tol_b + radius` holds no such marker.
    fn collect(&self, a: usize, b: usize, out: &mut Vec<WorldMarker>) {
        out.clear();
        let (pa, pb) = (&self.poses[a], &self.poses[b]);
        let ma = self.markers[a].as_ref();
        let shape = self.bodies[b].shape();
        let rho = self.radius[b] + self.range + MARGIN;
        let lim = self.range + self.surface_tol[b] + MARGIN;
        // Body frame of `a` → body frame of `b`: q = R_bᵀ R_a m + R_bᵀ (x_a − x_b).
        let rot = pb.rotation.tr_mul(&pa.rotation);
        let shift = pb.rotation.tr_mul(&(pa.position - pb.position));
        let centre_b = pa.rotation.tr_mul(&(pb.position - pa.position));
        let patches = &self.patches[a];
        let other = &self.patches[b];
        let near = self.range + MARGIN;
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

    /// Whether no marker of `a` can come within `range` of `b`'s markers: `a`'s bounding
    /// sphere is farther than `range` from the box of `b`'s markers, or `sd_b` at `a`'s centre
    /// exceeds `a`'s bounding radius by `range + tol_b` (1-Lipschitz, as above).
    fn apart(&self, a: usize, b: usize) -> bool {
        let (pa, pb) = (&self.poses[a], &self.poses[b]);
        let c = pb.rotation.tr_mul(&(pa.position - pb.position));
        let gap = self.radius[a] + self.range + MARGIN;
        self.patches[b].box_distance2(&c) >= gap * gap
            || self.bodies[b].shape().signed_distance(&c) - self.radius[a]
                >= self.range + self.surface_tol[b] + MARGIN
    }

    /// Appends to `out` the marker pairs `[i, j]` (`i` of `a`, `j` of `b`, `a < b`) closer
    /// than `range`, sorted by `(i, j)`; returns how many.
    fn pair(&self, a: usize, b: usize, s: &mut Scratch, out: &mut Vec<[u32; 2]>) -> u32 {
        let Scratch { ca: ma, cb: mb, cell_of, start, items, found, .. } = s;
        if self.apart(a, b) || self.apart(b, a) {
            return 0;
        }
        self.collect(a, b, ma);
        if ma.is_empty() {
            return 0;
        }
        self.collect(b, a, mb);
        if mb.is_empty() {
            return 0;
        }
        let (mut lo, mut hi) = (mb[0].x, mb[0].x);
        for m in mb.iter() {
            lo = lo.inf(&m.x);
            hi = hi.sup(&m.x);
        }
        // Bins of edge ≥ range: a partner within `range` is in one of the 27 neighbours.
        let geo = Geometry::covering(&lo, &hi, self.range, 4 * mb.len() + 64);
        fill(geo.len(), mb.len(), |k| geo.clamped_index(&mb[k].x), cell_of, start, items);
        let near = self.range + MARGIN;
        let near2 = near * near;
        // While the list is valid, body `b`'s rotation has ‖ΔR_b‖ ≤ skin/(2 r_b) = ρ_b (module
        // docs), so a normal turns by at most ρ_b and `n_i·n_j` changes by at most
        // `ρ = ρ_a + ρ_b`; `Δn = n_i − n_j` changes by at most ρ and `d` by at most the skin.
        let rot =
            |b: usize| if self.radius[b] > 0.0 { 0.5 * self.skin / self.radius[b] } else { f64::INFINITY };
        let rho = rot(a) + rot(b);
        let facing = rho + MARGIN;
        let tangential = self.p.lambda + self.skin + MARGIN;
        let turn = rho * std::f64::consts::FRAC_1_SQRT_2;
        found.clear();
        for mi in ma.iter() {
            let Some(r) = geo.neighbours(geo.coords(&mi.x)) else { continue };
            for_cells(&geo, r, |c| {
                for &k in &items[start[c] as usize..start[c + 1] as usize] {
                    let mj = &mb[k as usize];
                    let d = mj.x - mi.x;
                    let d2 = d.norm_squared();
                    if d2 >= near2 || mi.n.dot(&mj.n) > facing {
                        continue;
                    }
                    // A pair interacts only with facing normals (`n_i'·n_j' ≤ 0`, so
                    // `√2 ≤ |Δn'| ≤ 2`) and `δ_λ' = |d' × Δn'|/|Δn'| < λ`; and
                    // `|d' × Δn'| ≥ |d × Δn| − skin |Δn'| − |d| ρ`, so
                    // `δ_λ' ≥ |d × Δn|/2 − skin − |d| ρ/√2`: a pair above `λ` by that bound
                    // cannot interact before the list is rebuilt.
                    let dn = mi.n - mj.n;
                    if 0.5 * d.cross(&dn).norm() - d2.sqrt() * turn < tangential {
                        found.push([mi.index, mj.index]);
                    }
                }
            });
        }
        found.sort_unstable();
        out.extend_from_slice(found);
        found.len() as u32
    }

    /// Appends to `out` the markers `[i, wall]` of body `b` (free bodies only) within
    /// `wall_range` of a wall, sorted; returns how many.
    fn walls_on(&self, b: usize, s: &mut Scratch, out: &mut Vec<[u32; 2]>) -> u32 {
        let pose = &self.poses[b];
        if !pose.free || self.walls.is_empty() {
            return 0;
        }
        let lim = self.wall_range + MARGIN;
        let mut near = [false; 6];
        let mut any = false;
        for (w, (axis, plane, nhat)) in self.walls.iter().enumerate() {
            near[w] = wall_distance(*axis, *plane, nhat, &pose.position) - self.radius[b] < lim;
            any |= near[w];
        }
        if !any {
            return 0;
        }
        let ms = self.markers[b].as_ref();
        let patches = &self.patches[b];
        let found = &mut s.found;
        found.clear();
        for k in 0..patches.centre.len() {
            let c = pose.position + pose.rotation * patches.centre[k];
            let mut hit = [false; 6];
            let mut any = false;
            for (w, (axis, plane, nhat)) in self.walls.iter().enumerate() {
                hit[w] = near[w] && wall_distance(*axis, *plane, nhat, &c) - patches.radius[k] < lim;
                any |= hit[w];
            }
            if !any {
                continue;
            }
            for &i in patches.markers(k) {
                let (_, x) = pose.marker_position(&ms[i as usize]);
                for (w, (axis, plane, nhat)) in self.walls.iter().enumerate() {
                    if hit[w] && wall_distance(*axis, *plane, nhat, &x) < lim {
                        found.push([i, w as u32]);
                    }
                }
            }
        }
        found.sort_unstable();
        out.extend_from_slice(found);
        found.len() as u32
    }
}

/// The list's content: body pairs with their sides and marker pairs, and the markers listed
/// against walls. Two of them alternate (a refresh merges the current one into the other).
#[derive(Debug, Default)]
struct Content {
    /// Body pairs `(a, b)`, `a < b`, with at least one listed marker pair, sorted.
    pairs: Vec<(u32, u32)>,
    /// Sides of body pair `k`: `side[side_start[2k]..side_start[2k + 1]]` (of `a`) and
    /// `side[side_start[2k + 1]..side_start[2k + 2]]` (of `b`), marker indices, increasing.
    side_start: Vec<u32>,
    side: Vec<u32>,
    /// Marker pairs of body pair `k`: `mpairs[pair_start[k]..pair_start[k + 1]]`, as positions
    /// in its two sides, sorted by marker indices `(i, j)`.
    pair_start: Vec<u32>,
    mpairs: Vec<[u32; 2]>,
    /// Markers of body `b` listed against walls: `wside[wside_start[b]..wside_start[b + 1]]`
    /// (increasing); its candidates `wpairs[wall_start[b]..wall_start[b + 1]]` as
    /// `[position in that side, wall]`, sorted by marker, then wall.
    wside_start: Vec<u32>,
    wside: Vec<u32>,
    wall_start: Vec<u32>,
    wpairs: Vec<[u32; 2]>,
}

impl Content {
    fn clear(&mut self) {
        self.pairs.clear();
        self.side_start.clear();
        self.side.clear();
        self.pair_start.clear();
        self.mpairs.clear();
        self.wside_start.clear();
        self.wside.clear();
        self.wall_start.clear();
        self.wpairs.clear();
        self.side_start.push(0);
        self.pair_start.push(0);
        self.wside_start.push(0);
        self.wall_start.push(0);
    }

    fn capacity(&self) -> usize {
        self.pairs.capacity()
            + self.side_start.capacity()
            + self.side.capacity()
            + self.pair_start.capacity()
            + self.mpairs.capacity()
            + self.wside_start.capacity()
            + self.wside.capacity()
            + self.wall_start.capacity()
            + self.wpairs.capacity()
    }

    /// Appends body pair `pair` of another content `from` (its `k`-th), unchanged.
    fn copy_pair(&mut self, from: &Content, k: usize) {
        self.pairs.push(from.pairs[k]);
        let (s0, s1, s2) = (
            from.side_start[2 * k] as usize,
            from.side_start[2 * k + 1] as usize,
            from.side_start[2 * k + 2] as usize,
        );
        let base = self.side.len();
        self.side.extend_from_slice(&from.side[s0..s2]);
        self.side_start.push((base + s1 - s0) as u32);
        self.side_start.push((base + s2 - s0) as u32);
        self.mpairs
            .extend_from_slice(&from.mpairs[from.pair_start[k] as usize..from.pair_start[k + 1] as usize]);
        self.pair_start.push(self.mpairs.len() as u32);
    }

    /// Appends body pair `pair` with its marker pairs `found` (`[i, j]`, sorted by `(i, j)`):
    /// the sides are the distinct `i`s and `j`s, the pairs their positions.
    fn push_pair(&mut self, pair: (u32, u32), found: &[[u32; 2]]) {
        self.pairs.push(pair);
        // Side a: the i's, already increasing (pairs sorted by (i, j)).
        let sa = self.side.len();
        for &[i, _] in found {
            if self.side.len() == sa || *self.side.last().unwrap() != i {
                self.side.push(i);
            }
        }
        let sb = self.side.len();
        // Side b: the j's, sorted and deduplicated in place.
        self.side.extend(found.iter().map(|e| e[1]));
        self.side[sb..].sort_unstable();
        let mut w = sb;
        for r in sb..self.side.len() {
            if w == sb || self.side[w - 1] != self.side[r] {
                self.side[w] = self.side[r];
                w += 1;
            }
        }
        self.side.truncate(w);
        self.side_start.push(sb as u32);
        self.side_start.push(w as u32);
        let (side_a, side_b) = (&self.side[sa..sb], &self.side[sb..w]);
        let mut ia = 0;
        for &[i, j] in found {
            while side_a[ia] != i {
                ia += 1;
            }
            let jb = side_b.binary_search(&j).expect("j is on side b");
            self.mpairs.push([ia as u32, jb as u32]);
        }
        self.pair_start.push(self.mpairs.len() as u32);
    }

    /// Appends body `b`'s wall entries `found` (`[i, wall]`, sorted).
    fn push_walls(&mut self, found: &[[u32; 2]]) {
        let s0 = self.wside.len();
        for &[i, w] in found {
            if self.wside.len() == s0 || *self.wside.last().unwrap() != i {
                self.wside.push(i);
            }
            self.wpairs.push([(self.wside.len() - 1 - s0) as u32, w]);
        }
        self.wside_start.push(self.wside.len() as u32);
        self.wall_start.push(self.wpairs.len() as u32);
    }

    /// Appends body `b`'s wall entries of another content, unchanged.
    fn copy_walls(&mut self, from: &Content, b: usize) {
        self.wside
            .extend_from_slice(&from.wside[from.wside_start[b] as usize..from.wside_start[b + 1] as usize]);
        self.wpairs
            .extend_from_slice(&from.wpairs[from.wall_start[b] as usize..from.wall_start[b + 1] as usize]);
        self.wside_start.push(self.wside.len() as u32);
        self.wall_start.push(self.wpairs.len() as u32);
    }
}

/// The marker-pair list (module docs).
///
/// Per listed body pair it keeps the two **sides** (the markers of `a` and of `b` that occur in
/// its marker pairs, increasing) and the marker pairs as indices into them; per body, its
/// markers listed against walls. An evaluation transforms each side into a per-thread buffer
/// (the body-frame markers are shared by all bodies of a shape and stay in cache) and walks
/// the pairs: no world-sized table of markers is written or read.
///
/// **Per-body references.** Each body has a reference pose (where it was when its entries were
/// last found); every entry was found at the reference poses of its bodies. A body that has
/// moved by more than `skin/2` from its reference is *stale*: its entries are found again
/// ([`PairList::refresh`]) at its current pose (its new reference) against the others'
/// references, and the rest of the list is kept. An impeller, which turns by a few tenths of a
/// spacing at its tips every fluid step, is thus refreshed alone, instead of forcing the whole
/// bed's list to be rebuilt.
#[derive(Debug)]
pub(crate) struct PairList {
    skin: f64,
    valid: bool,
    /// Refreshes so far (full or partial).
    rebuilds: u64,
    /// Full rebuilds so far.
    full: u64,
    /// Each body's reference pose.
    built: Vec<(Vec3, Mat3)>,
    cur: Content,
    spare: Content,
    /// Per body: whether it is being refreshed (a refresh's buffer).
    mark: Vec<bool>,
    /// Per rebuild task: its output.
    chunks: Vec<Mutex<ChunkOut>>,
}

impl PairList {
    /// An empty (invalid) list.
    pub fn new(skin: f64) -> Self {
        Self {
            skin,
            valid: false,
            rebuilds: 0,
            full: 0,
            built: Vec::new(),
            cur: Content::default(),
            spare: Content::default(),
            mark: Vec::new(),
            chunks: Vec::new(),
        }
    }

    /// The skin.
    pub fn skin(&self) -> f64 {
        self.skin
    }

    /// Refreshes so far (full and partial).
    pub fn rebuilds(&self) -> u64 {
        self.rebuilds
    }

    /// Full rebuilds so far.
    pub fn full_rebuilds(&self) -> u64 {
        self.full
    }

    /// Listed marker pairs and marker–wall pairs.
    pub fn len(&self) -> (usize, usize) {
        (self.cur.mpairs.len(), self.cur.wpairs.len())
    }

    /// The listed body pairs, sorted.
    pub fn pairs(&self) -> &[(u32, u32)] {
        &self.cur.pairs
    }

    /// Whether the list exists for `n` bodies (it was built, for as many bodies).
    pub fn valid_for(&self, n: usize) -> bool {
        self.valid && self.built.len() == n
    }

    /// The bodies (increasing) that have moved by more than `skin/2` from their reference
    /// poses (module docs), into `out`. Only meaningful when [`PairList::valid_for`].
    pub fn stale(&self, poses: &[Pose], radius: &[f64], out: &mut Vec<u32>) {
        out.clear();
        let half = 0.5 * self.skin;
        for (b, ((p, (c0, r0)), r)) in poses.iter().zip(&self.built).zip(radius).enumerate() {
            if (p.position - c0).norm() + r * (p.rotation - r0).norm() > half {
                out.push(b as u32);
            }
        }
    }

    /// The reference poses of the bodies (current poses `poses` with each body's reference
    /// position and rotation), into `out`.
    pub fn reference_poses(&self, poses: &[Pose], out: &mut Vec<Pose>) {
        out.clear();
        out.extend(poses.iter().zip(&self.built).map(|(p, &(position, rotation))| Pose {
            position,
            rotation,
            ..*p
        }));
    }

    /// Total capacity (elements) of the buffers.
    pub fn capacity(&self) -> usize {
        let chunks: usize = self
            .chunks
            .iter()
            .map(|c| {
                let c = c.lock().unwrap_or_else(|e| e.into_inner());
                c.counts.capacity() + c.entries.capacity()
            })
            .sum();
        chunks + self.built.capacity() + self.cur.capacity() + self.spare.capacity() + self.mark.capacity()
    }

    /// Rebuilds the whole list at the narrow phase's poses (every body's new reference) from
    /// the candidate body pairs (the broad phase run with the listing range).
    pub fn rebuild<M: AsRef<[Marker]> + Sync>(
        &mut self,
        narrow: &Narrow<'_, M>,
        candidates: &[(u32, u32)],
        scratch: &[Mutex<Scratch>],
    ) {
        let n = narrow.poses.len();
        self.built.clear();
        self.built.extend(narrow.poses.iter().map(|p| (p.position, p.rotation)));
        self.mark.clear();
        self.mark.resize(n, true);
        self.valid = false;
        self.full += 1;
        self.merge(narrow, candidates, scratch);
    }

    /// Finds again the entries of the `stale` bodies: `narrow.poses` are the reference poses
    /// with the stale bodies' current poses (their new references), `candidates` every body
    /// pair that involves a stale body and passes the broad phase at those poses (sorted).
    /// The other entries are kept. Deterministic: the candidates are cut into fixed chunks and
    /// the result is merged in body-pair order, as a full rebuild orders it.
    pub fn refresh<M: AsRef<[Marker]> + Sync>(
        &mut self,
        narrow: &Narrow<'_, M>,
        stale: &[u32],
        candidates: &[(u32, u32)],
        scratch: &[Mutex<Scratch>],
    ) {
        self.mark.clear();
        self.mark.resize(narrow.poses.len(), false);
        for &b in stale {
            let b = b as usize;
            self.mark[b] = true;
            self.built[b] = (narrow.poses[b].position, narrow.poses[b].rotation);
        }
        self.merge(narrow, candidates, scratch);
    }

    /// The narrow phase on `candidates` and on the marked bodies' walls, merged with the
    /// current content's entries of unmarked bodies into the spare content, which then
    /// becomes current.
    fn merge<M: AsRef<[Marker]> + Sync>(
        &mut self,
        narrow: &Narrow<'_, M>,
        candidates: &[(u32, u32)],
        scratch: &[Mutex<Scratch>],
    ) {
        self.rebuilds += 1;
        let n = narrow.poses.len();
        let pair_chunks = candidates.len().div_ceil(CHUNK);
        let body_chunks = n.div_ceil(CHUNK);
        while self.chunks.len() < pair_chunks.max(body_chunks) {
            self.chunks.push(Mutex::new(ChunkOut::default()));
        }
        let chunks = &self.chunks;
        let task = |k: usize, f: &Finder<'_>, len: usize| {
            let t = rayon::current_thread_index().unwrap_or(0) % scratch.len();
            let mut s = scratch[t].lock().unwrap_or_else(|e| e.into_inner());
            let mut out = chunks[k].lock().unwrap_or_else(|e| e.into_inner());
            let ChunkOut { counts, entries } = &mut *out;
            counts.clear();
            entries.clear();
            for item in k * CHUNK..((k + 1) * CHUNK).min(len) {
                counts.push(f(item, &mut s, entries));
            }
        };
        // Body pairs.
        let pair = |i: usize, s: &mut Scratch, out: &mut Vec<[u32; 2]>| {
            let (a, b) = candidates[i];
            narrow.pair(a as usize, b as usize, s, out)
        };
        (0..pair_chunks).into_par_iter().for_each(|k| task(k, &pair, candidates.len()));
        let valid = self.valid;
        let (cur, spare, mark) = (&self.cur, &mut self.spare, &self.mark);
        spare.clear();
        // Kept pairs of the current content (no marked body), merged with the found ones:
        // neither sequence shares a pair with the other, both are sorted.
        let kept = |k: usize| {
            let (a, b) = cur.pairs[k];
            !mark[a as usize] && !mark[b as usize]
        };
        let old = if valid { cur.pairs.len() } else { 0 };
        let mut k = 0;
        for c in 0..pair_chunks {
            let out = self.chunks[c].lock().unwrap_or_else(|e| e.into_inner());
            let mut at = 0;
            for (i, &count) in out.counts.iter().enumerate() {
                let count = count as usize;
                if count > 0 {
                    let pair = candidates[c * CHUNK + i];
                    while k < old && cur.pairs[k] < pair {
                        if kept(k) {
                            spare.copy_pair(cur, k);
                        }
                        k += 1;
                    }
                    spare.push_pair(pair, &out.entries[at..at + count]);
                }
                at += count;
            }
        }
        while k < old {
            if kept(k) {
                spare.copy_pair(cur, k);
            }
            k += 1;
        }
        // Walls, per body: the marked bodies' found again (in fixed chunks), the others' kept.
        let walls = |b: usize, s: &mut Scratch, out: &mut Vec<[u32; 2]>| {
            if mark[b] {
                narrow.walls_on(b, s, out)
            } else {
                0
            }
        };
        (0..body_chunks).into_par_iter().for_each(|k| task(k, &walls, n));
        for c in 0..body_chunks {
            let out = self.chunks[c].lock().unwrap_or_else(|e| e.into_inner());
            let mut at = 0;
            for (i, &count) in out.counts.iter().enumerate() {
                let b = c * CHUNK + i;
                let count = count as usize;
                if mark[b] || !valid {
                    spare.push_walls(&out.entries[at..at + count]);
                } else {
                    spare.copy_walls(cur, b);
                }
                at += count;
            }
        }
        std::mem::swap(&mut self.cur, &mut self.spare);
        self.valid = true;
    }

    /// The loads of listed body pair `k` (bodies at `poses`, body-frame `markers`): its two
    /// sides placed in the world frame (into `s`), then its marker pairs within `reach`
    /// through the force law, summed in list order (`(i, j)`: the oracle's). Lever arms
    /// `r = R m`, positions `x = c + r`, normals `R n` and velocities `v + ω × r` are formed
    /// with the operations of [`Pose::marker_position`] and [`Pose::marker_normal_velocity`].
    pub fn pair_slot<M: AsRef<[Marker]>>(
        &self,
        k: usize,
        poses: &[Pose],
        markers: &[M],
        p: &ContactParams,
        s: &mut Scratch,
        op: Option<&mut PairOperator>,
    ) -> Slot {
        let reach = p.reach();
        let reach2 = reach * reach;
        let mut slot = Slot::EMPTY;
        let (a, b) = self.cur.pairs[k];
        let (pa, pb) = (&poses[a as usize], &poses[b as usize]);
        let sides = &self.cur.side_start[2 * k..2 * k + 3];
        place(
            pa,
            markers[a as usize].as_ref(),
            &self.cur.side[sides[0] as usize..sides[1] as usize],
            &mut s.a,
        );
        place(
            pb,
            markers[b as usize].as_ref(),
            &self.cur.side[sides[1] as usize..sides[2] as usize],
            &mut s.b,
        );
        let (wa, wb) = (&s.a, &s.b);
        // The pairs within reach, found without branches (about a third of the listed pairs
        // are: a branch per pair would be mispredicted), then through the force law in order.
        let mpairs = &self.cur.mpairs[self.cur.pair_start[k] as usize..self.cur.pair_start[k + 1] as usize];
        let mut within = [[0u32; 2]; FILTER_CHUNK];
        let mut lub = op.is_some().then_some(LubMoments::ZERO);
        for chunk in mpairs.chunks(FILTER_CHUNK) {
            let mut n = 0;
            for &[i, j] in chunk {
                let (mi, mj) = (&wa[i as usize], &wb[j as usize]);
                within[n] = [i, j];
                n += usize::from((mj.x - mi.x).norm_squared() < reach2);
            }
            // The force law on the batch without branches, then the interacting pairs in order.
            let batch = &mut s.batch;
            batch.clear();
            for &[i, j] in &within[..n] {
                batch.push(&wa[i as usize], &wb[j as usize]);
            }
            batch.evaluate(p);
            for &l in batch.hits() {
                let [i, j] = within[l as usize];
                let (ri, rj) = (&wa[i as usize].r, &wb[j as usize].r);
                let h = batch.hit(l as usize);
                slot.add_pair(&h, p, ri, rj, pa, pb);
                if let Some(lub) = lub.as_mut() {
                    lub.add(&h, ri, rj);
                }
            }
        }
        // The operator is read only where the slot has a contact (`Contacts::evaluate`).
        if let (Some(op), Some(lub)) = (op, lub) {
            if slot.count > 0 {
                *op = lub.operator();
            }
        }
        slot
    }

    /// The loads of the walls on body `b` (at `pose`): its listed markers within the cutoff of a
    /// wall, summed in list order (marker, then wall: the oracle's).
    #[allow(clippy::too_many_arguments)] // the pair_slot arguments, plus the walls
    pub fn wall_slot<M: AsRef<[Marker]>>(
        &self,
        b: usize,
        pose: &Pose,
        markers: &[M],
        p: &ContactParams,
        walls: &[(usize, f64, Vec3)],
        s: &mut Scratch,
        op: Option<&mut Mat6>,
    ) -> Slot {
        let mut slot = Slot::EMPTY;
        let range = self.cur.wall_start[b] as usize..self.cur.wall_start[b + 1] as usize;
        if range.is_empty() {
            return slot;
        }
        let side = &self.cur.wside[self.cur.wside_start[b] as usize..self.cur.wside_start[b + 1] as usize];
        place(pose, markers[b].as_ref(), side, &mut s.a);
        let cutoff = p.cutoff();
        let mut lub = op.is_some().then_some(LubMoments::ZERO);
        for &[i, w] in &self.cur.wpairs[range] {
            let (axis, plane, nhat) = &walls[w as usize];
            let m = &s.a[i as usize];
            if wall_distance(*axis, *plane, nhat, &m.x) >= cutoff {
                continue;
            }
            if let Some(h) = wall_force(p, *axis, *plane, nhat, &m.x, &m.n, &m.u) {
                slot.add_wall(&h, p, &m.r, pose);
                if let Some(lub) = lub.as_mut() {
                    lub.add(&h, &m.r, &m.r);
                }
            }
        }
        if let (Some(op), Some(lub)) = (op, lub) {
            if slot.count > 0 {
                *op = lub.wall_block();
            }
        }
        slot
    }
}

/// The markers `side` of a body at `pose`, in the world frame, into `out`: lever arm
/// `r = R m`, position `x = c + r`, normal `R n`, velocity `v + ω × r` (the operations of
/// [`Pose::marker_position`] and [`Pose::marker_normal_velocity`]), each formed once per side
/// marker rather than once per marker pair it belongs to.
#[inline(always)]
fn place(pose: &Pose, markers: &[Marker], side: &[u32], out: &mut Vec<WorldMarker>) {
    out.clear();
    out.extend(side.iter().map(|&i| {
        let m = &markers[i as usize];
        let r = pose.rotation * m.position;
        WorldMarker {
            index: 0,
            r,
            x: pose.position + r,
            n: pose.rotation * m.normal,
            u: pose.velocity + pose.angular_velocity.cross(&r),
        }
    }));
}

/// The total capacity of a set of per-thread scratch buffers.
pub(crate) fn scratch_capacity(scratch: &[Mutex<Scratch>]) -> usize {
    scratch.iter().map(|s| s.lock().unwrap_or_else(|e| e.into_inner()).capacity()).sum()
}
