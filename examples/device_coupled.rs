//! The coupled step on the device (`slurry::device::DeviceCoupled`: fluid, markers and interior
//! sums on the device; loads, shell reaction, contacts and body update on the host) against the
//! CPU's `Coupled<f32>` on the same scene: time per step of each and the agreement of the
//! bodies' velocities after the steps.
//!
//! ```text
//! cargo run --release --example device_coupled -- [N_BODIES] [SCALE] [STEPS] [WORKGROUP]
//! ```
//!
//! Defaults: 24 free cylinders `ℓ/d = 4`, `d = 12 s` in the paper's closed box
//! `251 s × 251 s × 240 s` at `s = 1/4`, f32 BGK `ν = 0.05`, γ = 1.25, gravity and Table 1's
//! contacts on, 20 timed steps after 2 warm-up steps, work groups of 64. The cylinders lie in
//! horizontal slots, layer by layer from the floor, axes alternating along x and y. On
//! Mesa's lavapipe the device's time says that it works, not how fast a GPU is.

use std::sync::Arc;
use std::time::Instant;

use slurry::contact::ContactParams;
use slurry::coupling::{Coupled, CouplingParams};
use slurry::device::{Context, DeviceCoupled};
use slurry::lattice::Grid;
use slurry::lbm::{Boundaries, Fluid, FluidParams};
use slurry::rigid::{Cylinder, Motion, Quat, RigidBody, Vec3};

fn main() {
    let args: Vec<f64> = std::env::args().skip(1).map(|a| a.parse().expect("numeric arguments")).collect();
    let n_bodies = args.first().copied().unwrap_or(24.0) as usize;
    let scale = args.get(1).copied().unwrap_or(0.25);
    let steps = args.get(2).copied().unwrap_or(20.0) as u64;
    let workgroup = args.get(3).copied().unwrap_or(64.0) as u32;
    let dims = [
        (251.0 * scale).round() as usize,
        (251.0 * scale).round() as usize,
        (240.0 * scale).round() as usize,
    ];
    let grid = Grid::new(dims[0], dims[1], dims[2]);
    let (d, l) = (12.0 * scale, 48.0 * scale);
    let fluid = || {
        let mut f = Fluid::<f32>::new(grid, FluidParams::bgk(0.05), Boundaries::closed_box()).expect("fluid");
        f.initialize(|_, _, _| (1.0, [0.0; 3]));
        f
    };
    let (sl, sw) = (l + 2.0, d + 2.0);
    let mut bodies = Vec::new();
    let mut layer = 0;
    'fill: while 0.5 * sw + (layer + 1) as f64 * sw <= dims[2] as f64 {
        let z = 0.5 * sw + layer as f64 * sw;
        let along_x = layer % 2 == 0;
        let (na, nb) = ((dims[0] as f64 / sl) as usize, (dims[1] as f64 / sw) as usize);
        for a in 0..na {
            for b in 0..nb {
                if bodies.len() == n_bodies {
                    break 'fill;
                }
                let (pa, pb) = (0.5 * sl + a as f64 * sl, 0.5 * sw + b as f64 * sw);
                let (pos, q) = if along_x {
                    (Vec3::new(pa, pb, z), Quat::from_euler_angles(0.0, std::f64::consts::FRAC_PI_2, 0.0))
                } else {
                    (Vec3::new(pb, pa, z), Quat::from_euler_angles(std::f64::consts::FRAC_PI_2, 0.0, 0.0))
                };
                bodies.push(
                    RigidBody::new(Arc::new(Cylinder::new(d, l)), 1.25, Motion::Free)
                        .with_position(pos)
                        .with_orientation(q),
                );
            }
        }
        layer += 1;
    }
    assert_eq!(bodies.len(), n_bodies, "the box holds only {} slots", bodies.len());
    let params = CouplingParams {
        gravity: [0.0, 0.0, -1e-4],
        contacts: Some(ContactParams::default()),
        ..Default::default()
    };

    let mut cpu = Coupled::new(fluid(), bodies.clone(), params).expect("coupling");
    cpu.run(2).expect("CPU warm-up");
    let t = Instant::now();
    cpu.run(steps).expect("CPU steps");
    let cpu_step = t.elapsed().as_secs_f64() / steps as f64;

    let ctx = Context::new().expect("a Vulkan adapter (cargo xtask setup installs lavapipe)");
    let mut dev = DeviceCoupled::new(&ctx, fluid(), bodies, params, workgroup).expect("device coupling");
    dev.run(2).expect("device warm-up");
    let t = Instant::now();
    dev.run(steps).expect("device steps");
    let dev_step = t.elapsed().as_secs_f64() / steps as f64;

    let (mut dv, mut v) = (0.0f64, 0.0f64);
    for (a, b) in cpu.bodies().iter().zip(dev.bodies()) {
        dv = dv.max((a.velocity - b.velocity).norm());
        v = v.max(a.velocity.norm());
    }
    println!(
        "grid {dims:?} ({:.2} M nodes), {n_bodies} cylinders d = {d}, l = {l}, {} markers, {} steps",
        grid.nodes() as f64 / 1e6,
        dev.device_markers().len(),
        steps + 2
    );
    println!("CPU Coupled<f32> ({} threads): {:.1} ms a step", rayon::current_num_threads(), cpu_step * 1e3);
    println!("device ({}): {:.1} ms a step", dev.device_fluid().adapter(), dev_step * 1e3);
    println!("largest velocity difference {dv:.3e} (largest velocity {v:.3e})");
}
