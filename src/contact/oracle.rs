//! The brute-force oracle: every marker pair of every body pair, every marker against every
//! wall, with the same force law, the same world-frame marker arithmetic and the same
//! summation order as [`super::Contacts::compute`], so that the two agree **bitwise** (tested
//! in `tests/contact_oracle.rs`).
//!
//! Order of the sums (both paths):
//! - per body pair `(a, b)`, `a < b`: the interacting marker pairs in lexicographic order of
//!   `(i, j)` (marker index in `a`, marker index in `b`) — the fast path finds them in bin
//!   order and sorts them;
//! - per body against the walls: markers in index order, for each the walls in the order of
//!   [`super::Walls::iter`];
//! - per body total: the pair sums of the pairs with at least one interacting marker pair in
//!   lexicographic pair order, then the body's wall sum (if it has a wall contact).
//!
//! Cost `O(Σ_{a<b} N_a N_b)`: for tests and verification only.

use crate::rigid::{Marker, RigidBody, Vec3};

use super::force::{pair_force, wall_force, Pose, WorldMarker};
use super::params::{ContactParams, Walls};
use super::slots::{accumulate, inverse_masses, stiffness_rates, ContactLoad, ContactStats, Slot};

/// What the oracle computed.
#[derive(Clone, Debug, PartialEq)]
pub struct OracleResult {
    /// Contact load per body.
    pub loads: Vec<ContactLoad>,
    /// Total force on the walls (see [`super::Contacts::wall_reaction`]).
    pub wall_reaction: Vec3,
    /// Counters; `candidate_pairs` counts every body pair with at least one free body.
    pub stats: ContactStats,
}

/// The contact loads by brute force (module doc), with the bodies' current states.
///
/// # Panics
/// If `bodies` and `markers` differ in length.
pub fn brute_force<M: AsRef<[Marker]>>(
    params: &ContactParams,
    walls: &Walls,
    bodies: &[RigidBody],
    markers: &[M],
) -> OracleResult {
    assert_eq!(bodies.len(), markers.len(), "one marker set per body");
    let poses: Vec<Pose> = bodies.iter().map(Pose::of).collect();
    let world: Vec<Vec<WorldMarker>> = poses
        .iter()
        .zip(markers)
        .map(|(p, ms)| {
            ms.as_ref()
                .iter()
                .enumerate()
                .map(|(k, m)| {
                    let (r, x) = p.marker_position(m);
                    let (n, u) = p.marker_normal_velocity(m, &r);
                    WorldMarker { index: k as u32, r, x, n, u }
                })
                .collect()
        })
        .collect();
    let reach = params.reach();
    let reach2 = reach * reach;
    let n = bodies.len();
    let mut pairs = Vec::new();
    let mut slots = Vec::new();
    if reach > 0.0 {
        for a in 0..n {
            for b in a + 1..n {
                if !poses[a].free && !poses[b].free {
                    continue;
                }
                let mut slot = Slot::EMPTY;
                for mi in &world[a] {
                    for mj in &world[b] {
                        if (mj.x - mi.x).norm_squared() < reach2 {
                            if let Some(h) = pair_force(params, mi, mj) {
                                slot.add_pair(&h, params, &mi.r, &mj.r, &poses[a], &poses[b]);
                            }
                        }
                    }
                }
                pairs.push((a as u32, b as u32));
                slots.push(slot);
            }
        }
    }
    let wall_list: Vec<_> = walls.iter().collect();
    let mut wall_slots = vec![Slot::EMPTY; n];
    if reach > 0.0 {
        for b in 0..n {
            if !poses[b].free {
                continue;
            }
            for m in &world[b] {
                for &(axis, _, plane, nhat) in &wall_list {
                    if let Some(h) = wall_force(params, axis, plane, &nhat, &m.x, &m.n, &m.u) {
                        wall_slots[b].add_wall(&h, params, &m.r, &poses[b]);
                    }
                }
            }
        }
    }
    let mut loads = vec![ContactLoad::ZERO; n];
    let mut stats = ContactStats { candidate_pairs: pairs.len(), ..Default::default() };
    let mut stiffness = vec![[0.0; 2]; n];
    let mut inverse_mass = Vec::new();
    inverse_masses(bodies, &mut inverse_mass);
    let wall_reaction = accumulate(
        &pairs,
        &slots,
        &wall_slots,
        &mut loads,
        &mut stiffness,
        &mut stats,
        0.0,
        &inverse_mass,
        &mut Vec::new(),
    );
    stiffness_rates(bodies, &stiffness, &mut stats);
    OracleResult { loads, wall_reaction, stats }
}
