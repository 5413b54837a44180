//! Tests of the coupled step.

use std::sync::Arc;

use super::*;
use crate::lattice::Grid;
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
    c.run(2000).unwrap();
    let f = c.hydrodynamic_force(0);
    let total = g * (n * n * n) as f64;
    assert!((f.x - total).abs() < 1e-6 * total, "F = {f}, G L³ = {total}");
    assert!(f.y.abs() < 1e-9 * total && f.z.abs() < 1e-9 * total);
}

#[test]
fn free_bodies_are_rejected() {
    let fluid = Fluid::<f64>::new(Grid::new(8, 8, 8), FluidParams::trt(0.1), Boundaries::periodic()).unwrap();
    let body = RigidBody::new(Arc::new(Sphere::new(3.0)), 1.0, Motion::Free);
    let e = Coupled::new(fluid, vec![body], CouplingParams::default()).err();
    assert_eq!(e, Some(CouplingError::FreeBody { index: 0 }));
}
