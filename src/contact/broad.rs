//! The broad phase of a marker-pair list build ([`super::Contacts`], step 1 of the module docs'
//! "Evaluation"): the candidate body pairs `(a, b)`, `a < b`, sorted, whose bounding spheres
//! (centre of mass, radius = largest marker distance) come closer than a range and that are
//! not both non-free. A full build finds them with a uniform cell list (bodies far larger than
//! the typical one, an impeller among particles, tested against every body instead); a refresh
//! tests each stale body against every body.

use crate::rigid::Vec3;

use super::force::Pose;
use super::grid::{fill, for_cells, Geometry};
use super::MARGIN;

/// The broad phase's per-body split (computed once) and its buffers: the cell list and the
/// candidate pairs of the last call.
#[derive(Debug)]
pub(super) struct BroadPhase {
    /// Per body: radius above 4 × the median (an impeller among particles), kept out of the
    /// cell list and tested against every body.
    big: Vec<bool>,
    /// The other bodies, those in the cell list.
    small: Vec<u32>,
    /// The largest bounding radius of the bodies in the cell list.
    r_small: f64,
    cell_of: Vec<u32>,
    cell_start: Vec<u32>,
    cell_items: Vec<u32>,
    /// The candidate body pairs of the last call.
    pairs: Vec<(u32, u32)>,
}

impl BroadPhase {
    /// The split of the bodies with bounding radii `radius` into those of the cell list and
    /// those far larger than the typical one.
    pub(super) fn new(radius: &[f64]) -> Self {
        let mut sorted = radius.to_vec();
        sorted.sort_by(f64::total_cmp);
        let r_med = sorted.get(sorted.len().saturating_sub(1) / 2).copied().unwrap_or(0.0);
        // Bodies far larger than the typical one (an impeller among particles) stay out of the
        // cell list and are tested against every body.
        let big: Vec<bool> = radius.iter().map(|&r| r > 4.0 * r_med).collect();
        let small: Vec<u32> = (0..radius.len()).filter(|&b| !big[b]).map(|b| b as u32).collect();
        let r_small = small.iter().map(|&b| radius[b as usize]).fold(0.0, f64::max);
        Self {
            big,
            small,
            r_small,
            cell_of: Vec::new(),
            cell_start: Vec::new(),
            cell_items: Vec::new(),
            pairs: Vec::new(),
        }
    }

    /// The candidate body pairs of the last call ([`BroadPhase::all_pairs`] or
    /// [`BroadPhase::stale_pairs`]), sorted, each once.
    pub(super) fn pairs(&self) -> &[(u32, u32)] {
        &self.pairs
    }

    /// Total capacity (elements) of the buffers.
    pub(super) fn capacity(&self) -> usize {
        self.cell_of.capacity()
            + self.cell_start.capacity()
            + self.cell_items.capacity()
            + self.pairs.capacity()
    }

    /// Candidate body pairs `(a, b)`, `a < b`, sorted: bounding spheres (at `poses`, radii
    /// `radius`) closer than `range` (`|c_a − c_b| < r_a + r_b + range`) and not both bodies
    /// non-free.
    pub(super) fn all_pairs(&mut self, poses: &[Pose], radius: &[f64], range: f64) {
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

    /// The candidate body pairs of a refresh: every pair `(a, b)`, `a < b`, that involves a
    /// body of `stale` and passes [`BroadPhase::all_pairs`]'s test at `poses` (the reference
    /// poses), sorted, each once.
    pub(super) fn stale_pairs(&mut self, stale: &[u32], poses: &[Pose], radius: &[f64], range: f64) {
        let reach = range + MARGIN;
        self.pairs.clear();
        for &s in stale {
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
}
