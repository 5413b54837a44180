//! Contacts between a prescribed body (an impeller stand-in) and a free particle: the
//! particle–impeller mechanism of the paper (its "solids torque"), without fluid through
//! `contact::Contacts` and with fluid through `coupling::Coupled`.
//!
//! **Set-up.** A "spinning rod": a cylinder of diameter 4 and length 24 with its own axis
//! along x, centred on the z axis and rotating about it at `Ω = 0.005` (`Motion::constant`),
//! tip speed `12 Ω = 0.06` (the paper's impeller tip speed is 0.104; at the contact point,
//! 6.2 from the axis, the rod moves at 0.031). A free sphere of diameter 6 (`γ = 1.25`) at
//! rest at radius 8 in the rod's plane of rotation, 50.8° ahead of it, so that the gap between
//! the sphere and the rod's mantle is 1.2 (just outside `δ_d = 1`) when the rod has turned by
//! 12°. Table 1 contacts (`ContactParams::default()`), `DEFAULT_SUBSTEPS` sub-steps, no gravity.
//!
//! **Claims (dry, `Contacts::advance_with`: the loads of every sub-step, and a second
//! `Contacts::compute` at each end-of-sub-step pose).**
//! - Newton's third law: `F_sphere + F_rod = 0`, relative tolerance 1e-12 (each marker pair
//!   adds `+f` to one body and `−f` to the other in the same order, so the sums are exact
//!   negatives; measured 0).
//! - The rod's contact torque about its centre (on the rotation axis) has the lever-arm form
//!   for the elastic part (evaluated alone, lubrication off):
//!   `|T_z − ((x_c − c) × F)_z| ≤ 2 |F|`, `x_c` the point of the rod's surface nearest the
//!   sphere's centre. The elastic marker forces are all repulsive, along `n̂` that vary by
//!   less than ≈ 30° over the patch, and act at rod markers within ≈ 1.7 of `x_c` (closer than
//!   the reach 1.12 to a sphere marker facing the rod), so `|Σ (x_j − x_c) × f_j| ≤ 1.7 Σ|f_j|
//!   ≤ 2 |F|`; measured 0.69 |F| (the rod's cap included). The full model has no such bound:
//!   while the sphere slides along the rod the lubrication pulls at the trailing edge of the
//!   contact and pushes at the leading one, a couple (measured up to 6.6 |F| when the net force
//!   nearly cancels; the angular impulse over the contact is −78.2 against −67.4 from the lever
//!   arm; printed). Checked for the full model: the solids torque opposes the rotation
//!   (`∫ T_z dt · Ω < 0`), as does its lever-arm estimate.
//! - The sphere's momentum change over the whole run equals minus the time integral of the
//!   contact force on the rod, `Σ_k h F_rod,k` (relative 1e-12: the sphere feels nothing else,
//!   and `v' = v + h F/m` per sub-step); the averaged loads that `advance` returns integrate to
//!   the same (relative 1e-12).
//! - The sphere is pushed along the rod's motion at the first contact point: its momentum along
//!   that direction is positive, and its speed along it reaches at least half the rod's speed
//!   there (0.026; a frictionless push by a prescribed surface moves the particle at least at
//!   the surface's normal speed while it lasts; measured 0.059, the elastic rebound adds).
//! - Energy: the work the rod does through the contact, `−Σ_k h T_z,k Ω`, exceeds the sphere's
//!   kinetic energy gain (the lubrication dissipates; measured 0.393 against 0.209).
//! - The rod's motion is unaffected: after every fluid step its pose and velocities are
//!   bitwise those of a twin body stepped without contacts the same way (`n_sub` steps of
//!   `1/n_sub`), its centre has not moved, and its orientation is the exact rotation
//!   `exp(Ω t ẑ) q0` to `1e-15` per sub-step (round-off of one quaternion product each).
//!
//! **With fluid (`Coupled`)**, box `40 × 40 × 16`, closed (bounce-back walls), BGK `ν = 0.05`,
//! the same bodies centred in it, 400 steps: per step, `BodyLoads::contact_force` of the rod
//! and of the sphere sum to zero (relative 1e-12; the sphere stays farther than the reach from
//! every wall, checked, so no wall load enters), the rod reports a non-zero `contact_torque`
//! whenever it has a contact force, the angular impulse `Σ T_z` opposes `Ω` (measured −778,
//! lever-arm estimate −766), the rod's pose is exactly prescribed (bitwise its twin's), and the
//! sphere gains momentum along the rod's motion.

use std::sync::Arc;

use slurry::contact::{ContactLoad, ContactParams, Contacts, Walls, DEFAULT_SUBSTEPS};
use slurry::coupling::{Coupled, CouplingParams};
use slurry::lattice::Grid;
use slurry::lbm::{Boundaries, Fluid, FluidParams};
use slurry::rigid::{Cylinder, Marker, Motion, Quat, RigidBody, Shape, Sphere, Vec3, DEFAULT_MARKER_SPACING};

/// Rod diameter, length and angular velocity.
const ROD_D: f64 = 4.0;
const ROD_L: f64 = 24.0;
const OMEGA: f64 = 0.005;
/// Sphere diameter and its radius from the rotation axis.
const SPHERE_D: f64 = 6.0;
const SPHERE_R: f64 = 8.0;
/// Gap between the sphere and the rod's mantle at first sight of each other.
const GAP0: f64 = 1.2;

/// The rod's orientation at `t = 0`: body z (its axis) along world x.
fn rod_q0() -> Quat {
    Quat::from_axis_angle(&Vec3::y_axis(), std::f64::consts::FRAC_PI_2)
}

/// The rod (body 0) centred at `centre`, and the sphere (body 1) at rest ahead of it.
fn bodies(centre: Vec3) -> (Vec<RigidBody>, Vec<Vec<Marker>>) {
    let rod: Arc<dyn Shape> = Arc::new(Cylinder::new(ROD_D, ROD_L));
    let sphere: Arc<dyn Shape> = Arc::new(Sphere::new(SPHERE_D));
    let markers = vec![rod.markers(DEFAULT_MARKER_SPACING), sphere.markers(DEFAULT_MARKER_SPACING)];
    let phi = ((0.5 * (ROD_D + SPHERE_D) + GAP0) / SPHERE_R).asin() + 12f64.to_radians();
    let paddle = RigidBody::new(rod, 1.25, Motion::constant(Vec3::zeros(), Vec3::new(0.0, 0.0, OMEGA)))
        .with_position(centre)
        .with_orientation(rod_q0());
    let ball = RigidBody::new(sphere, 1.25, Motion::Free)
        .with_position(centre + Vec3::new(phi.cos(), phi.sin(), 0.0) * SPHERE_R);
    (vec![paddle, ball], markers)
}

/// The point of the rod's surface nearest the sphere's centre (the rod frame: clamp the
/// sphere's centre to the rod's radius and half length).
fn contact_point(b: &[RigidBody]) -> Vec3 {
    let (rod, ball) = (&b[0], &b[1]);
    let p = rod.to_body(&ball.position);
    let r = p.xy().norm();
    let s = if r > 0.5 * ROD_D { 0.5 * ROD_D / r } else { 1.0 };
    let half = 0.5 * ROD_L;
    rod.to_world(&Vec3::new(p.x * s, p.y * s, p.z.clamp(-half, half)))
}

/// `|T_z − ((x_c − c) × F)_z| / |F|` for the rod's contact load (0 if there is none).
fn lever_error(b: &[RigidBody], rod: &ContactLoad) -> f64 {
    let f = rod.force.norm();
    if f == 0.0 {
        return 0.0;
    }
    let est = (contact_point(b) - b[0].position).cross(&rod.force);
    (rod.torque.z - est.z).abs() / f
}

/// Distance between two unit quaternions as rotations (sign-insensitive).
fn quat_distance(a: &Quat, b: &Quat) -> f64 {
    let (a, b) = (a.into_inner().coords, b.into_inner().coords);
    (a - b).norm().min((a + b).norm())
}

/// The exact orientation of the rod at time `t`.
fn rod_exact(t: f64) -> Quat {
    Quat::from_axis_angle(&Vec3::z_axis(), OMEGA * t) * rod_q0()
}

/// Asserts that `rod` has exactly the pose and velocities of `twin` (bitwise) and the exact
/// prescribed rotation (to the round-off of `n` quaternion products).
fn assert_prescribed(rod: &RigidBody, twin: &RigidBody, centre: Vec3, n: usize) {
    assert_eq!(rod.position, twin.position, "rod position differs from its contact-free twin");
    assert_eq!(rod.orientation, twin.orientation, "rod orientation differs from its twin");
    assert_eq!(rod.velocity, twin.velocity);
    assert_eq!(rod.angular_velocity, twin.angular_velocity);
    assert_eq!(rod.time, twin.time);
    assert_eq!(rod.position, centre, "the rod's centre must not move");
    let err = quat_distance(&rod.orientation, &rod_exact(rod.time));
    assert!(err <= 1e-15 * n.max(1) as f64, "orientation error {err:e} after {n} sub-steps");
}

#[test]
fn dry_rod_pushes_sphere() {
    let n_sub = DEFAULT_SUBSTEPS;
    let h = 1.0 / n_sub as f64;
    let (mut b, markers) = bodies(Vec3::zeros());
    let mut twin = b[0].clone();
    let params = ContactParams::default();
    let mut ct = Contacts::new(params, Walls::none(), &b, &markers).expect("valid parameters");
    let mut diag = Contacts::new(params, Walls::none(), &b, &markers).expect("valid parameters");
    let elastic_only = ContactParams { lubrication: false, ..params };
    let mut elastic = Contacts::new(elastic_only, Walls::none(), &b, &markers).expect("valid parameters");
    let (p0, ke0) = (b[1].linear_momentum(), b[1].kinetic_energy());
    let mut impulse_rod = Vec3::zeros(); // Σ_k h F_rod,k
    let mut impulse_avg = Vec3::zeros(); // Σ_steps F̄_rod (Δt = 1)
    let mut work = 0.0; // −Σ_k h T_z Ω
    let (mut third, mut lever, mut touched_steps, mut quiet) = (0.0f64, 0.0f64, 0usize, 0usize);
    let mut lever_full = 0.0f64;
    let (mut ang_meas, mut ang_est) = (0.0, 0.0);
    let mut push_dir: Option<Vec3> = None;
    let mut max_push_speed = 0.0f64;
    let mut substeps = 0;
    for _ in 0..2000 {
        let mut touching = false;
        let avg = ct.advance_with(&mut b, &markers, n_sub, |_, bs, loads| {
            let (rod, ball) = (loads[0], loads[1]);
            impulse_rod += rod.force * h;
            work -= rod.torque.dot(&bs[0].angular_velocity) * h;
            let scale = rod.force.norm().max(ball.force.norm());
            if scale > 0.0 {
                touching = true;
                third = third.max((rod.force + ball.force).norm() / scale);
                if push_dir.is_none() {
                    // The rod's velocity at the first contact point.
                    let xc = contact_point(bs);
                    push_dir = Some(bs[0].point_velocity(&xc).normalize());
                }
            }
            diag.compute(bs, &markers);
            let d = diag.loads();
            let scale = d[0].force.norm().max(d[1].force.norm());
            if scale > 0.0 {
                third = third.max((d[0].force + d[1].force).norm() / scale);
                lever_full = lever_full.max(lever_error(bs, &d[0]));
                ang_meas += d[0].torque.z * h;
                ang_est += (contact_point(bs) - bs[0].position).cross(&d[0].force).z * h;
                elastic.compute(bs, &markers);
                lever = lever.max(lever_error(bs, &elastic.loads()[0]));
            }
        });
        impulse_avg += avg[0].force;
        substeps += n_sub;
        for _ in 0..n_sub {
            twin.step(h);
        }
        assert_prescribed(&b[0], &twin, Vec3::zeros(), substeps);
        if let Some(dir) = push_dir {
            max_push_speed = max_push_speed.max(b[1].velocity.dot(&dir));
        }
        if touching {
            touched_steps += 1;
            quiet = 0;
        } else if touched_steps > 0 {
            quiet += 1;
        }
        // Done once the contact has been over for 100 steps (the sphere has left the rod).
        if quiet >= 100 {
            break;
        }
    }
    let dp = b[1].linear_momentum() - p0;
    let dke = b[1].kinetic_energy() - ke0;
    let dir = push_dir.expect("the rod reached the sphere");
    let contact_speed = OMEGA * contact_lever();
    eprintln!(
        "dry: {touched_steps} steps in contact; Newton 3 {third:e}; lever-arm error, elastic part {lever:.3} |F| \
         (full model, not bounded: {lever_full:.3} |F|); angular impulse on the rod {ang_meas:.4e}, \
         lever-arm estimate {ang_est:.4e}; sphere momentum along the push {:.4e} (|dp| {:.4e}); \
         largest push speed {max_push_speed:.4e} (rod at the contact {contact_speed:.4e}); work {work:.4e}, \
         kinetic energy gain {dke:.4e}",
        dp.dot(&dir),
        dp.norm(),
    );
    assert!(touched_steps > 0, "no contact");
    assert!(third <= 1e-12, "Newton's third law: |F_sphere + F_rod|/|F| = {third:e}");
    assert!(lever <= 2.0, "rod torque (elastic part) differs from the lever-arm estimate by {lever} |F|");
    assert!(ang_meas * OMEGA < 0.0 && ang_est * OMEGA < 0.0, "the solids torque must oppose the rotation");
    let e1 = (dp + impulse_rod).norm() / dp.norm();
    assert!(e1 <= 1e-12, "sphere momentum change vs -∫F_rod (sub-steps): {e1:e}");
    let e2 = (dp + impulse_avg).norm() / dp.norm();
    assert!(e2 <= 1e-12, "sphere momentum change vs -Σ averaged F_rod: {e2:e}");
    assert!(dp.dot(&dir) > 0.0, "the sphere must gain momentum along the rod's motion");
    assert!(
        max_push_speed >= 0.5 * contact_speed,
        "push speed {max_push_speed:e} below half the rod's speed at the contact {contact_speed:e}"
    );
    assert!(dke > 0.0 && work > dke, "the rod's work {work:e} must exceed the sphere's energy gain {dke:e}");
}

/// Distance from the rotation axis of the point of the rod's mantle that first meets the
/// sphere: the sphere's centre projected on the rod's axis at first contact.
fn contact_lever() -> f64 {
    let perp = 0.5 * (ROD_D + SPHERE_D) + 1.0;
    (SPHERE_R * SPHERE_R - perp * perp).sqrt()
}

#[test]
fn coupled_rod_pushes_sphere_solids_torque() {
    let (nx, nz) = (40, 16);
    let centre = Vec3::new(0.5 * (nx as f64 - 1.0), 0.5 * (nx as f64 - 1.0), 0.5 * (nz as f64 - 1.0));
    let (b, _) = bodies(centre);
    let mut twin = b[0].clone();
    let mut fluid =
        Fluid::<f64>::new(Grid::new(nx, nx, nz), FluidParams::bgk(0.05), Boundaries::closed_box())
            .expect("set-up");
    fluid.initialize(|_, _, _| (1.0, [0.0; 3]));
    let params = CouplingParams { contacts: Some(ContactParams::default()), ..Default::default() };
    let mut cp = Coupled::new(fluid, b, params).expect("coupling");
    let n_sub = DEFAULT_SUBSTEPS;
    let reach = ContactParams::default().reach();
    let p0 = cp.bodies()[1].linear_momentum();
    let (mut third, mut touched, mut angular_impulse, mut ang_est) = (0.0f64, 0usize, 0.0, 0.0);
    let mut push_dir: Option<Vec3> = None;
    let mut substeps = 0;
    for _ in 0..400 {
        cp.step().expect("bodies stay in the box");
        for _ in 0..n_sub {
            twin.step(1.0 / n_sub as f64);
        }
        substeps += n_sub;
        let bs = cp.bodies();
        assert_prescribed(&bs[0], &twin, centre, substeps);
        // No wall contact: the sphere keeps its surface farther than the reach from every wall.
        let x = bs[1].position;
        let wall = (0..3)
            .map(|a| {
                let n = [nx, nx, nz][a] as f64;
                (x[a] + 0.5).min(n - 0.5 - x[a]) - 0.5 * SPHERE_D
            })
            .fold(f64::INFINITY, f64::min);
        assert!(wall > reach, "the sphere came within {wall} of a wall");
        let (rod, ball) = (*cp.loads(0), *cp.loads(1));
        let scale = rod.contact_force.norm().max(ball.contact_force.norm());
        if scale > 0.0 {
            touched += 1;
            third = third.max((rod.contact_force + ball.contact_force).norm() / scale);
            assert!(rod.contact_torque.norm() > 0.0, "a rod in contact reports its contact torque");
            angular_impulse += rod.contact_torque.z;
            ang_est += (contact_point(bs) - bs[0].position).cross(&rod.contact_force).z;
            if push_dir.is_none() {
                push_dir = Some(bs[0].point_velocity(&contact_point(bs)).normalize());
            }
        }
    }
    let dp = cp.bodies()[1].linear_momentum() - p0;
    let dir = push_dir.expect("the rod reached the sphere");
    eprintln!(
        "coupled: {touched} steps in contact; Newton 3 {third:e}; angular impulse on the rod \
         {angular_impulse:.4e}, lever-arm estimate {ang_est:.4e}; sphere momentum along the push {:.4e}",
        dp.dot(&dir)
    );
    assert!(touched > 0, "no contact");
    assert!(third <= 1e-12, "Newton's third law through Coupled: {third:e}");
    assert!(
        angular_impulse * OMEGA < 0.0 && ang_est * OMEGA < 0.0,
        "the solids torque must oppose the rotation"
    );
    assert!(dp.dot(&dir) > 0.0, "the sphere must gain momentum along the rod's motion");
}
