//! Property tests of the contact module against its brute-force oracle.
//!
//! Random configurations (seeded; proptest draws the seed): 2–5 bodies, spheres and cylinders
//! of diameter 3–8 and length 2–12, random orientations, each body after the first placed
//! against a previous one at a surface gap drawn in `[−0.3, 1.1]` (some overlapping slightly,
//! most within the lubrication range, some just beyond), random velocities (`|v| ≲ 0.05`)
//! and angular velocities, about one body in four prescribed or fixed; walls (in about half the
//! cases) placed at a gap in `[−0.2, 0.9]` below/beside the lowest/leftmost marker so that
//! bodies touch them.
//!
//! Claims and tolerances:
//! - **fast path ≡ oracle, bitwise**: the fast path (`Contacts::compute`: cell list, marker
//!   bins, parallel pairs) uses the same force law, the same marker arithmetic and the same
//!   summation order as `brute_force` (module doc of `contact::oracle`): every load component,
//!   the wall reaction and the counters must have identical bits. Any pruning bug (a pair
//!   missed by the broad phase, the bounding-sphere or surface-distance filters, the bins)
//!   changes a sum and fails.
//! - **thread-count determinism, bitwise**: pools of 1, 2 and 3 threads give identical bits.
//! - **Newton's third law**: `Σ_b F_b + F_walls = 0` with a tolerance of `1e-13 Σ_b |F_b|`
//!   (each marker pair adds `+f` and `−f` to two body sums, so the total is a sum of ≈ 10³
//!   round-off terms of relative size 1e-16); there is no tolerance on the physics.
//! - **the marker-pair list is exact while it is reused**: a list built at one configuration,
//!   then evaluated after every body has moved (random translation and rotation) by at most
//!   half the skin, gives the oracle's loads at the new configuration bitwise, without a
//!   rebuild; a larger move rebuilds it, and the loads are again the oracle's.
//! - **no allocation in steady state**: the internal buffer capacity does not change between
//!   two evaluations of the same configuration (one thread).
//! - **sub-cycling conserves linear momentum** (free bodies, no walls): `|ΔΣ m v|` below
//!   `1e-14 (Σ |m v| + Σ |F̄|)` over 20 fluid steps of 8 sub-steps (round-off of 160 velocity
//!   updates, ≈ 1e-16 relative each).

use std::sync::Arc;

use proptest::prelude::*;
use slurry::contact::{brute_force, ContactLoad, ContactParams, Contacts, Walls};
use slurry::rigid::{Cylinder, Marker, Motion, Quat, RigidBody, Shape, Sphere, Vec3, DEFAULT_MARKER_SPACING};
use slurry::util::SplitMix64;

struct Config {
    bodies: Vec<RigidBody>,
    markers: Vec<Vec<Marker>>,
    walls: Walls,
}

fn random_unit(rng: &mut SplitMix64) -> Vec3 {
    loop {
        let v = Vec3::from(rng.vec3(-1.0, 1.0));
        let n = v.norm();
        if n > 0.1 && n < 1.0 {
            return v / n;
        }
    }
}

fn random_rotation(rng: &mut SplitMix64) -> Quat {
    Quat::from_axis_angle(
        &nalgebra::Unit::new_normalize(random_unit(rng)),
        rng.uniform(0.0, std::f64::consts::TAU),
    )
}

/// Smallest signed distance of `b`'s markers (placed with `pos`, `q`) to body `other`.
fn gap(other: &RigidBody, m: &[Marker], pos: Vec3, q: Quat) -> f64 {
    m.iter()
        .map(|mk| other.signed_distance(&(pos + q.transform_vector(&mk.position))))
        .fold(f64::INFINITY, f64::min)
}

fn config(seed: u64) -> Config {
    let mut rng = SplitMix64(seed);
    let n = 2 + (rng.next_u64() % 4) as usize;
    let mut bodies: Vec<RigidBody> = Vec::new();
    let mut markers: Vec<Vec<Marker>> = Vec::new();
    for k in 0..n {
        let shape: Arc<dyn Shape> = if rng.unit() < 0.4 {
            Arc::new(Sphere::new(rng.uniform(3.0, 8.0)))
        } else {
            Arc::new(Cylinder::new(rng.uniform(3.0, 8.0), rng.uniform(2.0, 12.0)))
        };
        let m = shape.markers(DEFAULT_MARKER_SPACING);
        let q = random_rotation(&mut rng);
        let pos = if k == 0 {
            Vec3::from(rng.vec3(20.0, 30.0))
        } else {
            // Against a previous body at a target gap, by bisection along a random direction.
            let other = &bodies[(rng.next_u64() % k as u64) as usize];
            let dir = random_unit(&mut rng);
            let target = rng.uniform(-0.3, 1.1);
            let (mut lo, mut hi) = (0.0, 40.0);
            for _ in 0..60 {
                let t = 0.5 * (lo + hi);
                if gap(other, &m, other.position + dir * t, q) < target {
                    lo = t;
                } else {
                    hi = t;
                }
            }
            other.position + dir * hi
        };
        let motion = match rng.next_u64() % 8 {
            0 => Motion::Fixed,
            1 => Motion::constant(Vec3::from(rng.vec3(-0.05, 0.05)), Vec3::from(rng.vec3(-0.01, 0.01))),
            _ => Motion::Free,
        };
        let b = RigidBody::new(shape, 1.25, motion)
            .with_position(pos)
            .with_orientation(q)
            .with_velocities(Vec3::from(rng.vec3(-0.05, 0.05)), Vec3::from(rng.vec3(-0.01, 0.01)));
        bodies.push(b);
        markers.push(m);
    }
    let mut walls = Walls::none();
    if rng.unit() < 0.5 {
        // A floor and a left wall touching the lowest / leftmost markers (some beyond them).
        for axis in [2usize, 0] {
            let lowest = bodies
                .iter()
                .zip(&markers)
                .flat_map(|(b, m)| m.iter().map(move |mk| b.to_world(&mk.position)[axis]))
                .fold(f64::INFINITY, f64::min);
            walls.planes[axis][0] = Some(lowest - rng.uniform(-0.2, 0.9));
        }
        walls.planes[1] = [Some(-1000.0), Some(1000.0)];
    }
    Config { bodies, markers, walls }
}

fn bits(l: &[ContactLoad]) -> Vec<u64> {
    l.iter()
        .flat_map(|c| c.force.iter().chain(c.torque.iter()).map(|v| v.to_bits()).collect::<Vec<_>>())
        .collect()
}

fn fast(
    c: &Config,
    params: ContactParams,
    threads: usize,
) -> (Vec<ContactLoad>, Vec3, slurry::contact::ContactStats) {
    let pool = rayon::ThreadPoolBuilder::new().num_threads(threads).build().unwrap();
    pool.install(|| {
        let mut ct = Contacts::new(params, c.walls, &c.bodies, &c.markers).unwrap();
        let loads = ct.compute(&c.bodies, &c.markers).to_vec();
        (loads, ct.wall_reaction(), *ct.stats())
    })
}

fn params_for(seed: u64) -> ContactParams {
    match seed % 4 {
        0 => ContactParams { elastic: false, ..Default::default() },
        1 => ContactParams { lubrication: false, ..Default::default() },
        _ => ContactParams::default(),
    }
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(48))]

    #[test]
    fn fast_path_equals_oracle_bitwise(seed in any::<u64>()) {
        let c = config(seed);
        let params = params_for(seed);
        let (loads, reaction, stats) = fast(&c, params, 2);
        let o = brute_force(&params, &c.walls, &c.bodies, &c.markers);
        prop_assert_eq!(bits(&loads), bits(&o.loads), "loads differ: {:?} vs {:?}", loads, o.loads);
        prop_assert_eq!(reaction.map(f64::to_bits), o.wall_reaction.map(f64::to_bits));
        prop_assert_eq!(stats.touching_pairs, o.stats.touching_pairs);
        prop_assert_eq!(stats.marker_pairs, o.stats.marker_pairs);
        prop_assert_eq!(stats.wall_contacts, o.stats.wall_contacts);
        prop_assert_eq!(stats.min_delta.to_bits(), o.stats.min_delta.to_bits());
        prop_assert_eq!(stats.elastic_energy.to_bits(), o.stats.elastic_energy.to_bits());
    }

    #[test]
    fn thread_count_does_not_change_a_bit(seed in any::<u64>()) {
        let c = config(seed);
        let params = params_for(seed);
        let (l1, r1, _) = fast(&c, params, 1);
        for t in [2, 3] {
            let (lt, rt, _) = fast(&c, params, t);
            prop_assert_eq!(bits(&l1), bits(&lt));
            prop_assert_eq!(r1.map(f64::to_bits), rt.map(f64::to_bits));
        }
    }

    #[test]
    fn newtons_third_law(seed in any::<u64>()) {
        let c = config(seed);
        let (loads, reaction, _) = fast(&c, ContactParams::default(), 2);
        let total: Vec3 = loads.iter().map(|l| l.force).sum::<Vec3>() + reaction;
        let scale: f64 = loads.iter().map(|l| l.force.norm()).sum::<f64>() + reaction.norm();
        prop_assert!(total.norm() <= 1e-13 * scale.max(1e-300), "Σ F = {total:?}, scale {scale}");
        if c.walls.is_empty() {
            prop_assert_eq!(reaction, Vec3::zeros());
        }
    }
}

/// The configurations above do make contacts (the tests would be vacuous otherwise): over 48
/// seeds, most have touching pairs, several have wall contacts and overlaps (`δ < 0`).
#[test]
fn configurations_exercise_the_model() {
    let (mut touching, mut walls, mut overlap, mut pairs) = (0, 0, 0, 0);
    for seed in 0..48u64 {
        let c = config(seed);
        let o = brute_force(&ContactParams::default(), &c.walls, &c.bodies, &c.markers);
        touching += (o.stats.touching_pairs > 0) as usize;
        walls += (o.stats.wall_contacts > 0) as usize;
        overlap += (o.stats.min_delta < 0.0) as usize;
        pairs += o.stats.marker_pairs;
    }
    eprintln!("EXERCISE {touching} {walls} {overlap} {pairs}");
    assert!(touching >= 40 && walls >= 10 && overlap >= 5, "{touching} {walls} {overlap} {pairs}");
}

/// Moves every body of `c` by a random translation and rotation whose largest marker
/// displacement bound, `|Δc| + r ‖ΔR‖_F` (the list's criterion), is `frac` of `limit`.
fn jiggle(c: &mut Config, rng: &mut SplitMix64, limit: f64, frac: f64) {
    for k in 0..c.bodies.len() {
        move_one(c, rng, k, frac * limit);
    }
}

#[test]
fn reused_list_stays_exact_and_rebuilds_when_bodies_move_too_far() {
    let skin = slurry::contact::DEFAULT_SKIN;
    let mut exercised = 0;
    for seed in 0..24u64 {
        let mut c = config(seed);
        let params = params_for(seed);
        let mut ct = Contacts::new(params, c.walls, &c.bodies, &c.markers).unwrap();
        ct.compute(&c.bodies, &c.markers);
        assert_eq!(ct.list_stats().0, 1);
        let mut rng = SplitMix64(seed ^ 0x5eed);
        // Within half the skin (0.98 of it, leaving room for rounding): reused, exact.
        jiggle(&mut c, &mut rng, 0.5 * skin, 0.98);
        let loads = ct.compute(&c.bodies, &c.markers).to_vec();
        assert_eq!(ct.list_stats().0, 1, "seed {seed}: the list was rebuilt for a move within the skin");
        let o = brute_force(&params, &c.walls, &c.bodies, &c.markers);
        assert_eq!(bits(&loads), bits(&o.loads), "seed {seed}: reused list differs from the oracle");
        assert_eq!(ct.stats().marker_pairs, o.stats.marker_pairs);
        assert_eq!(ct.stats().wall_contacts, o.stats.wall_contacts);
        exercised += usize::from(o.stats.marker_pairs > 0);
        // Beyond it: rebuilt, exact.
        jiggle(&mut c, &mut rng, 0.5 * skin, 3.0);
        let loads = ct.compute(&c.bodies, &c.markers).to_vec();
        assert_eq!(ct.list_stats().0, 2, "seed {seed}: no rebuild after a move beyond the skin");
        let o = brute_force(&params, &c.walls, &c.bodies, &c.markers);
        assert_eq!(bits(&loads), bits(&o.loads), "seed {seed}: rebuilt list differs from the oracle");
    }
    assert!(exercised >= 12, "only {exercised} configurations kept touching pairs after the move");
}

/// Moves body `k` of `c` by a random translation and rotation whose largest marker
/// displacement bound, `|Δc| + r ‖ΔR‖_F` (the list's criterion), is at most `limit`.
fn move_one(c: &mut Config, rng: &mut SplitMix64, k: usize, limit: f64) {
    let r = c.markers[k].iter().map(|mk| mk.position.norm()).fold(0.0, f64::max);
    let axis = nalgebra::Unit::new_normalize(random_unit(rng));
    // ‖R(θ) − I‖_F = 2√2 sin(θ/2) ≤ √2 θ: split the budget evenly.
    let angle = 0.5 * limit / (r.max(1e-9) * std::f64::consts::SQRT_2);
    let shift = random_unit(rng) * (0.5 * limit);
    let b = &mut c.bodies[k];
    let q = Quat::from_axis_angle(&axis, angle) * b.orientation;
    *b = b.clone().with_position(b.position + shift).with_orientation(q);
}

/// One body at a time moves beyond the skin: only its entries are found again (a partial
/// refresh, no full rebuild), against the others' reference poses, and the loads stay the
/// oracle's bitwise; a last move of every body within what the references allow reuses the
/// list and stays exact.
#[test]
fn partial_refresh_of_one_body_stays_exact() {
    let skin = slurry::contact::DEFAULT_SKIN;
    let mut exercised = 0;
    for seed in 0..24u64 {
        let mut c = config(seed);
        let params = params_for(seed);
        let mut ct = Contacts::new(params, c.walls, &c.bodies, &c.markers).unwrap();
        ct.compute(&c.bodies, &c.markers);
        let mut rng = SplitMix64(seed ^ 0xfee1);
        let n = c.bodies.len();
        for round in 0..6 {
            let k = (rng.next_u64() % n as u64) as usize;
            let limit = 0.5 * skin * rng.uniform(1.05, 3.0);
            move_one(&mut c, &mut rng, k, limit);
            let loads = ct.compute(&c.bodies, &c.markers).to_vec();
            assert_eq!(ct.list_stats().0, round as u64 + 2, "seed {seed} round {round}: no refresh");
            assert_eq!(ct.full_rebuilds(), 1, "seed {seed} round {round}: a full rebuild for one body");
            let o = brute_force(&params, &c.walls, &c.bodies, &c.markers);
            assert_eq!(bits(&loads), bits(&o.loads), "seed {seed} round {round}: refreshed list differs");
            assert_eq!(ct.stats().marker_pairs, o.stats.marker_pairs);
            assert_eq!(ct.stats().wall_contacts, o.stats.wall_contacts);
            exercised += usize::from(o.stats.marker_pairs > 0);
        }
        // Every body is at its reference now (refreshed ones got new references): a move of
        // each within 0.98 of half the skin reuses the list, exactly.
        jiggle(&mut c, &mut rng, 0.5 * skin, 0.98);
        let before = ct.list_stats().0;
        let loads = ct.compute(&c.bodies, &c.markers).to_vec();
        assert_eq!(ct.list_stats().0, before);
        let o = brute_force(&params, &c.walls, &c.bodies, &c.markers);
        assert_eq!(bits(&loads), bits(&o.loads), "seed {seed}: reused list differs after refreshes");
    }
    assert!(exercised >= 60, "only {exercised} refreshed configurations had touching pairs");
}

/// In one thread (with several, each thread's scratch grows until that thread has met the
/// largest pair, which depends on the scheduling; then it stops growing too).
#[test]
fn warm_evaluation_does_not_grow_buffers() {
    let pool = rayon::ThreadPoolBuilder::new().num_threads(1).build().unwrap();
    pool.install(|| {
        for seed in 0..8u64 {
            let c = config(seed);
            let mut ct = Contacts::new(ContactParams::default(), c.walls, &c.bodies, &c.markers).unwrap();
            ct.compute(&c.bodies, &c.markers);
            let cap = ct.buffer_capacity();
            for _ in 0..3 {
                ct.compute(&c.bodies, &c.markers);
                assert_eq!(ct.buffer_capacity(), cap);
            }
        }
    });
}

#[test]
fn sub_cycling_conserves_linear_momentum() {
    // Free bodies only, no walls, no external loads: Σ m v is conserved to round-off through
    // contacts (every marker pair applies ±f to two bodies in the same sub-step), with the
    // explicit law (8 sub-steps) and with lubrication sub-steps (2 × 4: each pair's frozen
    // operator gives ±F).
    let split = ContactParams { lubrication_substeps: 4, ..Default::default() };
    for (seed, (params, n_sub)) in
        (0..16u64).zip([(ContactParams::default(), 8), (split, 2)].into_iter().cycle())
    {
        let mut c = config(seed);
        c.walls = Walls::none();
        for b in &mut c.bodies {
            *b = RigidBody::new(b.shape().clone(), 1.25, Motion::Free)
                .with_position(b.position)
                .with_orientation(b.orientation)
                .with_velocities(b.velocity, b.angular_velocity);
        }
        let p0: Vec3 = c.bodies.iter().map(|b| b.linear_momentum()).sum();
        let scale: f64 = c.bodies.iter().map(|b| b.linear_momentum().norm()).sum();
        let mut ct = Contacts::new(params, c.walls, &c.bodies, &c.markers).unwrap();
        let mut impulse = 0.0f64;
        for _ in 0..20 {
            let avg = ct.advance(&mut c.bodies, &c.markers, n_sub);
            impulse += avg.iter().map(|l| l.force.norm()).sum::<f64>();
        }
        let p1: Vec3 = c.bodies.iter().map(|b| b.linear_momentum()).sum();
        assert!((p1 - p0).norm() <= 1e-14 * (scale + impulse), "seed {seed}: {p0:?} -> {p1:?}");
    }
}

/// `ContactStats::damping_rate` and `spring_rate` of a sphere resting over the floor at a gap
/// inside the lubrication range, against the sums formed here marker by marker from Table 1:
/// `2 Σ kⁿ (1/max(δ, δ_sat) − 1/δ_d)/m` and `√(2 Σ k/m)` over the markers facing the floor
/// within `δ_d` (resp. `δ0`), `w = 1` against a wall. Equal to round-off (the sums are formed
/// in another order here).
#[test]
fn stiffness_rates_of_a_sphere_over_the_floor() {
    let p = ContactParams::default();
    let shape: Arc<dyn Shape> = Arc::new(Sphere::new(6.0));
    let m = shape.markers(DEFAULT_MARKER_SPACING);
    let floor = -0.5;
    let lowest = m.iter().map(|k| k.position.z).fold(f64::INFINITY, f64::min);
    let gap = 0.3;
    let mut body = RigidBody::new(shape, 1.25, Motion::Free);
    body.position = Vec3::new(10.0, 10.0, floor + gap - lowest);
    let (mut c, mut k) = (0.0, 0.0);
    for mk in &m {
        let delta = body.position.z + mk.position.z - floor;
        if mk.normal.z < 0.0 && delta < p.delta_d {
            c += p.k_n * (1.0 / delta.max(p.delta_sat) - 1.0 / p.delta_d);
            if delta < p.delta0 {
                k += p.k;
            }
        }
    }
    assert!(c > 0.0 && k > 0.0, "the set-up must engage both parts");
    let walls = Walls::closed_box([20, 20, 20]);
    let bodies = vec![body];
    let markers = vec![m];
    let mut ct = Contacts::new(p, walls, &bodies, &markers).unwrap();
    ct.compute(&bodies, &markers);
    let mass = bodies[0].mass();
    let (damping, spring) = (ct.stats().damping_rate, ct.stats().spring_rate);
    assert!((damping / (2.0 * c / mass) - 1.0).abs() < 1e-12, "{damping} vs {}", 2.0 * c / mass);
    assert!((spring / (2.0 * k / mass).sqrt() - 1.0).abs() < 1e-12, "{spring}");
}
