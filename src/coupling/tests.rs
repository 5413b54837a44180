//! Tests of the coupled step.

use std::sync::Arc;

use super::*;
use crate::lattice::{Face, Grid};
use crate::lbm::{Boundaries, FluidParams};
use crate::rigid::{Motion, Sphere};

fn sphere_box(n: usize, d: f64, g: [f64; 3], iterations: usize) -> Coupled<f64> {
    let mut fluid = Fluid::<f64>::new(
        Grid::new(n, n, n),
        FluidParams::trt(1.0 / 6.0).with_body_force(g),
        Boundaries::periodic(),
    )
    .unwrap();
    fluid.initialize(|_, _, _| (1.0, [0.0; 3]));
    let c = n as f64 / 2.0;
    let body = RigidBody::new(Arc::new(Sphere::new(d)), 1.0, Motion::Fixed).with_position(Vec3::new(c, c, c));
    Coupled::new(fluid, vec![body], CouplingParams { iterations, ..Default::default() }).unwrap()
}

#[test]
fn fluid_at_rest_stays_at_rest_around_a_fixed_body() {
    let mut c = sphere_box(12, 4.0, [0.0; 3], 2);
    c.run(20).unwrap();
    let (_, u) = c.fluid().fields();
    let umax = u.iter().flat_map(|v| v.iter()).fold(0.0f64, |a, &b| a.max(b.abs()));
    assert!(umax < 1e-14, "u_max = {umax}");
    assert!(c.hydrodynamic_force(0).norm() < 1e-14);
    assert!(c.hydrodynamic_torque(0).norm() < 1e-14);
}

#[test]
fn force_on_the_body_balances_the_body_force_at_steady_state() {
    let n = 12;
    let g = 1e-6;
    let mut c = sphere_box(n, 4.0, [g, 0.0, 0.0], 1);
    // About 18 relaxation times L³/(6πνaK) of the mean flow (≈ 165 steps with the default
    // retraction: the effective sphere is smaller, K lower and the relaxation slower than
    // without): the remaining imbalance is far below the tolerance.
    c.run(3000).unwrap();
    let f = c.hydrodynamic_force(0);
    let total = g * (n * n * n) as f64;
    assert!((f.x - total).abs() < 1e-6 * total, "F = {f}, G L³ = {total}");
    assert!(f.y.abs() < 1e-9 * total && f.z.abs() < 1e-9 * total);
}

/// Every stencil node of every marker lies in the band, and the band-limited velocity equals
/// the fluid's own `macroscopic` at those nodes bitwise: for a tilted cylinder that moves
/// across the periodic boundaries of a box, and a sphere next to a wall; with the markers on
/// the surface and retracted by the largest retraction a case file allows (their stencils
/// reach deeper: the band is widened by the retraction).
#[test]
fn band_covers_every_stencil_node_and_matches_macroscopic() {
    for retraction in [0.0, 0.499] {
        band_covers(retraction);
    }
}

fn band_covers(retraction: f64) {
    use crate::ibm::{interpolate, FnField};
    use crate::lbm::FaceBoundary;
    use crate::rigid::{Cylinder, Quat};
    let grid = Grid::new(20, 16, 18);
    let bounds =
        Boundaries::periodic().with(Face::ZMin, FaceBoundary::NoSlip).with(Face::ZMax, FaceBoundary::NoSlip);
    let mut fluid =
        Fluid::<f32>::new(grid, FluidParams::bgk(0.1).with_body_force([1e-5, 0.0, 0.0]), bounds).unwrap();
    fluid.initialize(|x, y, z| {
        (1.0, [0.01 * (z as f64 / 18.0), 0.002 * (x as f64 / 20.0), 0.001 * (y as f64 / 16.0)])
    });
    let cyl = RigidBody::new(
        Arc::new(Cylinder::new(5.0, 12.0)),
        1.25,
        Motion::constant(Vec3::new(0.37, -0.21, 0.0), Vec3::new(0.011, 0.02, -0.013)),
    )
    .with_position(Vec3::new(18.3, 1.7, 9.2))
    .with_orientation(Quat::from_euler_angles(0.7, -0.4, 1.1));
    let sph = RigidBody::new(Arc::new(Sphere::new(4.0)), 1.0, Motion::Fixed)
        .with_position(Vec3::new(6.0, 9.5, 1.6));
    let mut c = Coupled::new(
        fluid,
        vec![cyl, sph],
        CouplingParams { iterations: 2, retraction, ..Default::default() },
    )
    .unwrap();
    // The band path (two bodies in a small box would take the whole grid by size).
    c.dense_override = Some(false);
    for step in 0..12 {
        c.step().unwrap();
        // After the step, `band_prev` is this step's band and the stencils are this step's.
        assert!(!c.band_prev.whole_grid, "step {step}: the band should have been built");
        let mut in_band = vec![false; grid.nodes()];
        for z in 0..grid.nz {
            for r in c.band_prev.plane(z) {
                for x in r.x0..r.x0 + r.len {
                    in_band[grid.index(x as usize, r.y as usize, r.z as usize)] = true;
                }
            }
        }
        for m in 0..c.marker_count() {
            c.stencils.for_each_node(m, |n, w| {
                assert!(in_band[n] || w == 0.0, "step {step}: marker {m}, stencil node {n} not in the band");
            });
        }
    }
    // Band velocity == macroscopic, bitwise, through the interpolation.
    std::mem::swap(&mut c.band, &mut c.band_prev);
    c.band_velocity();
    let mut via_band = vec![[0.0; 3]; c.marker_count()];
    interpolate(&c.velocity, &c.stencils, &mut via_band);
    let fluid = &c.fluid;
    let field = FnField {
        nodes: grid.nodes(),
        f: |n: usize| {
            let [x, y, z] = grid.coords(n);
            fluid.macroscopic(x, y, z).1
        },
    };
    let mut direct = vec![[0.0; 3]; c.marker_count()];
    interpolate(&field, &c.stencils, &mut direct);
    assert_eq!(via_band, direct);
}

/// A neutrally buoyant free sphere in fluid at rest stays at rest (no spurious force from the
/// interior term or the band), and a free sphere heavier than the fluid starts to fall with
/// the acceleration of its net weight over its mass plus the (interior-fluid) lag.
#[test]
fn free_sphere_at_rest_stays_at_rest_and_heavy_one_falls() {
    let mk = |density: f64| {
        let mut fluid =
            Fluid::<f64>::new(Grid::new(16, 16, 16), FluidParams::trt(0.1), Boundaries::periodic()).unwrap();
        fluid.initialize(|_, _, _| (1.0, [0.0; 3]));
        let body = RigidBody::new(Arc::new(Sphere::new(6.0)), density, Motion::Free)
            .with_position(Vec3::new(8.2, 7.9, 8.1));
        Coupled::new(fluid, vec![body], CouplingParams { gravity: [0.0, 0.0, -1e-4], ..Default::default() })
            .unwrap()
    };
    let mut neutral = mk(1.0);
    neutral.run(50).unwrap();
    let b = &neutral.bodies()[0];
    assert!(b.velocity.norm() < 1e-13 && b.angular_velocity.norm() < 1e-13, "{:?}", b.velocity);
    let mut heavy = mk(1.25);
    heavy.run(200).unwrap();
    let b = &heavy.bodies()[0];
    assert!(b.velocity.z < 0.0 && b.velocity.z.is_finite(), "v = {}", b.velocity);
    assert!(b.velocity.x.abs() < 1e-3 * b.velocity.z.abs() && b.velocity.y.abs() < 1e-3 * b.velocity.z.abs());
}
/// Snapshot at an even step, continue; restore into a fresh coupling, continue: bitwise equal.
#[test]
fn restore_continues_bitwise() {
    let mk = || {
        let mut fluid =
            Fluid::<f32>::new(Grid::new(14, 14, 20), FluidParams::bgk(0.05), Boundaries::closed_box())
                .unwrap();
        fluid.initialize(|_, _, _| (1.0, [0.0; 3]));
        let body = RigidBody::new(Arc::new(crate::rigid::Cylinder::new(4.0, 8.0)), 1.25, Motion::Free)
            .with_position(Vec3::new(4.6, 7.1, 12.0))
            .with_velocities(Vec3::new(-0.02, 0.0, 0.0), Vec3::zeros())
            .with_orientation(crate::rigid::Quat::from_euler_angles(0.3, 0.9, 0.0));
        // Contacts on, and the cylinder released at the wall x = -1/2 so that they act.
        let params = CouplingParams {
            gravity: [0.0, 0.0, -1e-4],
            contacts: Some(crate::contact::ContactParams::default()),
            ..Default::default()
        };
        Coupled::new(fluid, vec![body], params).unwrap()
    };
    let mut a = mk();
    a.run(20).unwrap();
    let s = a.snapshot().unwrap();
    let mut touched = 0.0f64;
    for _ in 0..40 {
        a.step().unwrap();
        touched = touched.max(a.loads(0).contact_force.norm());
    }
    assert!(touched > 0.0, "the contact with the wall never happened");
    let mut b = mk();
    b.run(3).unwrap(); // a different history, overwritten by the restore
    b.restore(&s).unwrap();
    b.run(40).unwrap();
    assert_eq!(a.fluid().populations_all(), b.fluid().populations_all());
    let (pa, pb) = (&a.bodies()[0], &b.bodies()[0]);
    assert_eq!(
        (pa.position, pa.velocity, pa.angular_velocity),
        (pb.position, pb.velocity, pb.angular_velocity)
    );
    assert_eq!(pa.orientation, pb.orientation);
}
/// With contacts on, a heavy sphere released above the floor of a closed box comes to rest on
/// it without its markers crossing the contact's saturation distance of the wall, and the
/// wall's contact force and the fluid then carry the net weight (averaged over the last 1000
/// steps).
#[test]
fn sphere_settles_on_the_floor_with_contacts() {
    let mut fluid =
        Fluid::<f32>::new(Grid::new(16, 16, 24), FluidParams::bgk(0.1), Boundaries::closed_box()).unwrap();
    fluid.initialize(|_, _, _| (1.0, [0.0; 3]));
    let g = 2e-3;
    let body = RigidBody::new(Arc::new(Sphere::new(6.0)), 1.25, Motion::Free)
        .with_position(Vec3::new(7.5, 7.5, 8.0));
    let params = CouplingParams {
        gravity: [0.0, 0.0, -g],
        contacts: Some(crate::contact::ContactParams::default()),
        ..Default::default()
    };
    let mut c = Coupled::new(fluid, vec![body], params).unwrap();
    let mut lowest = f64::INFINITY;
    let mut support = 0.0;
    for k in 0..6000 {
        c.step().unwrap();
        if k >= 5000 {
            support += (c.loads(0).contact_force.z + c.loads(0).force().z) / 1000.0;
        }
        let b = &c.bodies()[0];
        // Gap between the sphere's surface and the floor plane at z = -1/2.
        lowest = lowest.min(b.position.z - 3.0 + 0.5);
    }
    let b = &c.bodies()[0];
    let weight = b.net_weight(Vec3::new(0.0, 0.0, -g), 1.0);
    assert!(lowest > 0.2 - 0.05, "closest approach to the floor {lowest}");
    assert!(
        b.velocity.norm() < 1e-5,
        "still moving: {:?} at z = {}, lowest {lowest}",
        b.velocity,
        b.position.z
    );
    assert!((support + weight.z).abs() < 0.02 * weight.norm(), "support {support} vs weight {}", weight.z);
}

/// The bits of the fluid's populations and of the bodies' positions and velocities.
fn state_bits(c: &Coupled<f32>) -> (Vec<u32>, Vec<u64>) {
    let pops = c.fluid().snapshot().unwrap().populations.iter().map(|v| v.to_bits()).collect();
    let bodies = c
        .bodies()
        .iter()
        .flat_map(|b| b.position.iter().chain(b.velocity.iter()).map(|v| v.to_bits()).collect::<Vec<_>>())
        .collect();
    (pops, bodies)
}

/// The band velocity and the clearing of the force field give the same bits over the bands
/// only and over the whole grid (the size-chosen shortcut for dense beds of small bodies,
/// which builds no band), and when the two alternate from step to step (every transition:
/// a step after one without a built band clears the whole field).
#[test]
fn dense_and_sparse_band_paths_agree_bitwise() {
    // `dense(step)`: the override of each step.
    let run = |dense: &dyn Fn(usize) -> Option<bool>| {
        let mut fluid =
            Fluid::<f32>::new(Grid::new(20, 20, 24), FluidParams::bgk(0.05), Boundaries::closed_box())
                .unwrap();
        fluid.initialize(|x, y, _| (1.0, [1e-3 * ((x + 2 * y) as f64 * 0.4).sin(), 0.0, 0.0]));
        let bodies: Vec<RigidBody> = (0..4)
            .map(|k| {
                RigidBody::new(Arc::new(Sphere::new(4.0)), 1.25, Motion::Free).with_position(Vec3::new(
                    5.0 + 9.0 * (k % 2) as f64,
                    6.0 + 8.0 * (k / 2) as f64,
                    8.0 + k as f64,
                ))
            })
            .collect();
        let params = CouplingParams { gravity: [0.0, 0.0, -1e-4], ..Default::default() };
        let mut c = Coupled::new(fluid, bodies, params).unwrap();
        for step in 0..30 {
            c.dense_override = dense(step);
            c.step().unwrap();
            if let Some(d) = dense(step) {
                assert_eq!(c.band_prev.whole_grid, d, "step {step}");
            }
        }
        let (pops, bodies) = state_bits(&c);
        (pops, bodies, c.band_nodes())
    };
    let sparse = run(&|_| Some(false));
    let dense = run(&|_| Some(true));
    // Dense, dense, sparse, sparse, dense, sparse, …: every transition, repeatedly.
    let alternating = run(&|step| Some([true, true, false, false, true, false][step % 6]));
    let chosen = run(&|_| None);
    assert!(sparse.0 == dense.0, "populations differ");
    assert_eq!(sparse.1, dense.1, "bodies differ");
    assert!(sparse.0 == alternating.0, "populations differ (alternating)");
    assert_eq!(sparse.1, alternating.1, "bodies differ (alternating)");
    assert!(sparse.0 == chosen.0, "populations differ (chosen by size)");
    assert_eq!(sparse.1, chosen.1, "bodies differ (chosen by size)");
}

/// Small bodies whose bands hold more than `DENSE_BAND_FRACTION` of the grid: no band is built (the per-body
/// estimate from `Coupled::new` decides before any step), the whole grid is used instead,
/// and the results are those of the band, bit for bit.
#[test]
fn dense_bed_builds_no_band_and_agrees_bitwise() {
    let run = |dense: Option<bool>| {
        let n = 12;
        let mut fluid =
            Fluid::<f32>::new(Grid::new(n, n, n), FluidParams::bgk(0.05), Boundaries::periodic()).unwrap();
        fluid.initialize(|x, y, z| (1.0, [1e-3 * ((x + 2 * y) as f64 * 0.4).sin(), 2e-4 * z as f64, 0.0]));
        let bodies: Vec<RigidBody> = (0..8)
            .map(|k| {
                let at = |b: usize| 3.0 + 6.0 * ((k >> b) & 1) as f64 + 0.1 * k as f64;
                RigidBody::new(Arc::new(Sphere::new(3.0)), 1.25, Motion::Free).with_position(Vec3::new(
                    at(0),
                    at(1),
                    at(2),
                ))
            })
            .collect();
        let params = CouplingParams { gravity: [0.0, 0.0, -1e-4], ..Default::default() };
        let mut c = Coupled::new(fluid, bodies, params).unwrap();
        c.dense_override = dense;
        let mut whole = true;
        for _ in 0..20 {
            c.step().unwrap();
            whole &= c.band_prev.whole_grid;
        }
        let (pops, bodies) = state_bits(&c);
        (pops, bodies, whole, c.band_nodes())
    };
    let (chosen, band) = (run(None), run(Some(false)));
    assert!(chosen.2, "the band should not have been built");
    assert!(!band.2);
    let threshold = super::DENSE_BAND_FRACTION * (12 * 12 * 12) as f64;
    assert!(band.3 as f64 > threshold, "the bands hold {} nodes", band.3);
    assert!(chosen.3 as f64 > threshold, "the estimate is {} nodes", chosen.3);
    assert!(chosen.0 == band.0, "populations differ");
    assert_eq!(chosen.1, band.1, "bodies differ");
}

/// Equal marker sets are shared (one allocation), different ones are not, and the order of
/// the bodies is kept.
#[test]
fn equal_marker_sets_are_shared() {
    let a = Sphere::new(6.0).markers(0.7);
    let b = Sphere::new(8.0).markers(0.7);
    let sets = shared_sets([a.clone(), b.clone(), a.clone(), b.clone(), a.clone()].into_iter());
    assert!(Arc::ptr_eq(&sets[0], &sets[2]) && Arc::ptr_eq(&sets[0], &sets[4]));
    assert!(Arc::ptr_eq(&sets[1], &sets[3]));
    assert!(!Arc::ptr_eq(&sets[0], &sets[1]));
    assert_eq!(&sets[0][..], &a[..]);
    assert_eq!(&sets[1][..], &b[..]);
}

/// The forcing markers are retracted by `retraction` (signed distance `−r_d`, area weights of
/// the retracted surface), the contact markers stay on the true surface, and the interior
/// term keeps the true volume (`Σ α ≈ V`, not the retracted one); a zero retraction gives
/// the true markers for both, bit for bit; a body too thin for the retraction is refused.
#[test]
fn forcing_markers_retracted_contact_markers_true() {
    use crate::rigid::Cylinder;
    let make = |retraction: f64, shape: Arc<dyn Shape>| {
        let mut fluid =
            Fluid::<f64>::new(Grid::new(16, 16, 16), FluidParams::trt(1.0 / 6.0), Boundaries::periodic())
                .unwrap();
        fluid.initialize(|_, _, _| (1.0, [0.0; 3]));
        let body = RigidBody::new(shape, 1.0, Motion::Fixed).with_position(Vec3::new(8.0, 8.0, 8.0));
        Coupled::new(fluid, vec![body], CouplingParams { retraction, ..Default::default() })
    };
    let sphere: Arc<dyn Shape> = Arc::new(Sphere::new(8.0));
    let cyl: Arc<dyn Shape> = Arc::new(Cylinder::new(5.0, 9.0));
    for shape in [sphere.clone(), cyl] {
        let mut c = make(0.35, shape.clone()).unwrap();
        assert_eq!(c.retraction(), 0.35);
        for m in c.markers(0) {
            assert!((shape.signed_distance(&m.position) + 0.35).abs() < 1e-12, "{m:?}");
        }
        for m in c.contact_markers(0) {
            assert!(shape.signed_distance(&m.position).abs() < 1e-12, "{m:?}");
        }
        let area: f64 = c.markers(0).iter().map(|m| m.area).sum();
        assert!(area < shape.surface_area());
        c.step().unwrap();
        let v = c.interior_momentum(0).before.2;
        assert!((v / shape.volume() - 1.0).abs() < 0.05, "Σα = {v}, V = {}", shape.volume());
        let c0 = make(0.0, shape.clone()).unwrap();
        assert_eq!(c0.markers(0), shape.markers(DEFAULT_MARKER_SPACING).as_slice());
        assert_eq!(c0.contact_markers(0), c0.markers(0));
    }
    let thin = make(0.6, Arc::new(Sphere::new(1.1)));
    assert!(matches!(thin, Err(CouplingError::Retraction { body: 0, .. })));
}

/// The band's widening by the retraction is needed: the stencil nodes of markers retracted by
/// 0.499 reach deeper into the body than `√3 ×` the kernel's support (the band's half-width
/// without retraction), and no deeper than the widened half-width.
#[test]
fn retracted_stencils_need_the_widened_band() {
    let n = 24;
    let mut fluid =
        Fluid::<f64>::new(Grid::new(n, n, n), FluidParams::trt(1.0 / 6.0), Boundaries::periodic()).unwrap();
    fluid.initialize(|_, _, _| (1.0, [0.0; 3]));
    let centre = Vec3::new(11.83, 12.27, 11.61);
    let shape: Arc<dyn Shape> = Arc::new(Sphere::new(14.0));
    let body = RigidBody::new(shape.clone(), 1.0, Motion::Fixed).with_position(centre);
    let mut c =
        Coupled::new(fluid, vec![body], CouplingParams { retraction: 0.499, ..Default::default() }).unwrap();
    c.step().unwrap();
    let grid = c.fluid().grid();
    let mut deepest = 0.0f64;
    for m in 0..c.marker_count() {
        c.stencils.for_each_node(m, |node, w| {
            if w != 0.0 {
                let [x, y, z] = grid.coords(node);
                let p = Vec3::new(x as f64, y as f64, z as f64) - centre;
                deepest = deepest.max(shape.signed_distance(&p).abs());
            }
        });
    }
    let unwidened = DeltaKernel::default().support() * 3f64.sqrt();
    assert!(deepest > unwidened, "deepest stencil node at |sd| = {deepest}");
    assert!(deepest < c.band_half_width, "deepest {deepest}, band {}", c.band_half_width);
}

/// The interior sums of phases 3 and 7 equal, bit for bit, a fresh walk of each body's rows
/// with the signed distance evaluated at the partial nodes (the computation without gathering
/// over phase 3's record): for a free tilted cylinder moving across the periodic boundaries
/// and a free sphere next to a wall, over steps in which both move.
#[test]
fn interior_sums_equal_a_fresh_walk_bitwise() {
    use super::band::{emit_runs, row_spans};
    use super::interior::Moment;
    use crate::lbm::FaceBoundary;
    use crate::rigid::{Cylinder, Quat};
    /// The walk of phases 3 and 7 without the record (reference).
    fn walk(fluid: &Fluid<f32>, body: &RigidBody, periodic: [bool; 3]) -> [u64; 7] {
        let grid = fluid.grid();
        let shape = body.shape().as_ref();
        let c = body.position;
        let (mut p, mut l, mut v) = (Vec3::zeros(), Vec3::zeros(), 0.0);
        row_spans(body, grid, periodic, 0.5, Some(-0.5), |s| {
            emit_runs(grid, periodic, (s.xa, s.xb, s.y, s.z), |run, shift| {
                let (yu, zu) = ((run.y as i64 + shift[1]) as f64, (run.z as i64 + shift[2]) as f64);
                fluid.for_each_in_run(run, |x, _rho, j, _f| {
                    let xu = x as i64 + shift[0];
                    let r = Vec3::new(xu as f64 - c.x, yu - c.y, zu - c.z);
                    let alpha = if s.xs <= xu && xu <= s.xe {
                        1.0
                    } else {
                        (0.5 - shape.signed_distance(&(s.origin + s.dir * xu as f64))).clamp(0.0, 1.0)
                    };
                    if alpha > 0.0 {
                        v += alpha;
                        let m = Vec3::from(j) * alpha;
                        p += m;
                        l += r.cross(&m);
                    }
                });
            });
        });
        bits((p, l, v))
    }
    fn bits((p, l, v): (Vec3, Vec3, f64)) -> [u64; 7] {
        [p.x, p.y, p.z, l.x, l.y, l.z, v].map(f64::to_bits)
    }
    let grid = Grid::new(20, 16, 18);
    let bounds =
        Boundaries::periodic().with(Face::ZMin, FaceBoundary::NoSlip).with(Face::ZMax, FaceBoundary::NoSlip);
    let mut fluid = Fluid::<f32>::new(grid, FluidParams::bgk(0.1), bounds).unwrap();
    fluid.initialize(|x, y, z| {
        (1.0, [0.01 * (z as f64 / 18.0), 0.002 * (x as f64 / 20.0), 0.001 * (y as f64 / 16.0)])
    });
    let cyl = RigidBody::new(Arc::new(Cylinder::new(5.0, 12.0)), 1.25, Motion::Free)
        .with_position(Vec3::new(18.3, 1.7, 9.2))
        .with_velocities(Vec3::new(0.07, -0.05, 0.0), Vec3::new(0.011, 0.02, -0.013))
        .with_orientation(Quat::from_euler_angles(0.7, -0.4, 1.1));
    let sph = RigidBody::new(Arc::new(Sphere::new(4.0)), 1.5, Motion::Free)
        .with_position(Vec3::new(6.0, 9.5, 2.6))
        .with_velocities(Vec3::new(-0.03, 0.02, 0.0), Vec3::new(0.0, 0.01, 0.02));
    let params = CouplingParams { gravity: [0.0, 0.0, -1e-4], ..Default::default() };
    let mut c = Coupled::new(fluid, vec![cyl, sph], params).unwrap();
    let start = c.bodies()[0].position;
    for step in 0..10 {
        // `Coupled::step`'s phases, with the sums checked after 3 and 7.
        c.place_markers();
        c.build_geometry().unwrap();
        c.interior_sums(Moment::Before);
        for (b, body) in c.bodies.iter().enumerate() {
            let before = walk(&c.fluid, body, c.periodic);
            assert_eq!(bits(c.interior[b].before), before, "step {step}, body {b}, before");
        }
        c.clear_forcing();
        c.force();
        c.fluid.step();
        c.interior_sums(Moment::After);
        for (b, body) in c.bodies.iter().enumerate() {
            let after = walk(&c.fluid, body, c.periodic);
            assert_eq!(bits(c.interior[b].after), after, "step {step}, body {b}, after");
            assert_ne!(c.interior[b].before, c.interior[b].after, "step {step}, body {b}: the fluid changed");
        }
        c.collect_loads();
        c.advance_bodies();
        std::mem::swap(&mut c.band, &mut c.band_prev);
    }
    assert!((c.bodies()[0].position - start).norm() > 0.3, "the cylinder should have moved");
}

/// The spreading's row update of the fluid's force field (`ForceFieldWriter::add_row`, rows of
/// 3 and of other lengths) leaves bitwise the field that node-by-node updates leave, in `f32`
/// storage, over repeated overlapping updates.
#[test]
fn force_field_rows_update_as_nodes_do() {
    let new = || {
        let mut f =
            Fluid::<f32>::new(Grid::new(8, 6, 5), FluidParams::bgk(0.1), Boundaries::closed_box()).unwrap();
        f.enable_force_field();
        f
    };
    let (mut by_rows, mut by_nodes) = (new(), new());
    let layout = by_rows.padded_layout();
    let mut rng = crate::util::SplitMix64(3);
    let updates: Vec<(usize, Vec<f64>, [f64; 3])> = (0..400)
        .map(|k| {
            let len = [3, 3, 2, 4, 1][k % 5];
            let (x, y, z) = ((k * 7) % (8 - len + 1), (k * 5) % 6, (k * 3) % 5);
            let w = (0..len).map(|_| rng.uniform(0.0, 0.4)).collect();
            let f = [rng.uniform(-1e-3, 1e-3), rng.uniform(-1e-3, 1e-3), rng.uniform(-1e-3, 1e-3)];
            (layout.index(x, y, z), w, f)
        })
        .collect();
    {
        let (rows, nodes) = (by_rows.force_field_writer(), by_nodes.force_field_writer());
        for (p, w, f) in &updates {
            // SAFETY: interior nodes of the grid (x + len ≤ 8), one thread.
            unsafe { rows.add_row(*p, w, *f) };
            for (k, &wk) in w.iter().enumerate() {
                unsafe { nodes.add(p + k, wk, *f) };
            }
        }
    }
    let mut touched = 0;
    for z in 0..5 {
        for y in 0..6 {
            for x in 0..8 {
                let (a, b) = (by_rows.force_at(x, y, z), by_nodes.force_at(x, y, z));
                assert_eq!(a.map(f64::to_bits), b.map(f64::to_bits), "node ({x}, {y}, {z})");
                touched += usize::from(a != [0.0; 3]);
            }
        }
    }
    assert!(touched > 80, "{touched} nodes updated");
}
