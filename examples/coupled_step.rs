//! Speed of the coupled step against the fluid-only step, at the paper's scale.
//!
//! ```text
//! cargo run --release --example coupled_step -- [N_BODIES] [L_OVER_D] [SCALE] [STEPS]
//! ```
//!
//! Defaults: 411 free cylinders `ℓ/d = 4`, `d = 12` (scale 1) in a closed `251 × 251 × 240`
//! box, f32 BGK `ν = 0.05`, γ = 1.25, gravity on, 6 timed steps after 2 warm-up steps. The
//! cylinders are placed on a regular arrangement of horizontal slots (axes alternating along x
//! and y, layer by layer, each tilted by a small deterministic angle), non-overlapping, filling
//! the box from the floor: a loose bed's worth of surface, which is what the IBM cost depends
//! on. Prints the per-phase time of the coupled step ([`slurry::coupling::StepTimings`]), the
//! IBM cost per marker, and the ratio to the fluid-only step on the same grid with the force
//! field on.

use std::sync::Arc;
use std::time::Instant;

use slurry::coupling::{Coupled, CouplingParams};
use slurry::lattice::Grid;
use slurry::lbm::{Boundaries, Fluid, FluidParams};
use slurry::rigid::{Cylinder, Motion, Quat, RigidBody, Vec3};

fn main() {
    let args: Vec<f64> = std::env::args().skip(1).map(|a| a.parse().expect("numeric arguments")).collect();
    let n_bodies = args.first().copied().unwrap_or(411.0) as usize;
    let ld = args.get(1).copied().unwrap_or(4.0);
    let scale = args.get(2).copied().unwrap_or(1.0);
    let steps = args.get(3).copied().unwrap_or(6.0) as u64;
    let dims = [
        (251.0 * scale).round() as usize,
        (251.0 * scale).round() as usize,
        (240.0 * scale).round() as usize,
    ];
    let grid = Grid::new(dims[0], dims[1], dims[2]);
    let d = 12.0 * scale;
    let l = ld * d;
    let threads = rayon::current_num_threads();
    println!(
        "grid {dims:?} ({:.1} M nodes), {n_bodies} cylinders d = {d}, l = {l}, {threads} threads",
        grid.nodes() as f64 / 1e6
    );

    let new_fluid = || {
        let mut f = Fluid::<f32>::new(grid, FluidParams::bgk(0.05), Boundaries::closed_box()).expect("fluid");
        f.initialize(|_, _, _| (1.0, [0.0; 3]));
        f
    };

    // Fluid alone, force field on (the coupled kernel reads it too).
    let mut fluid = new_fluid();
    fluid.enable_force_field();
    fluid.run(2);
    let t = Instant::now();
    fluid.run(steps);
    let fluid_step = t.elapsed().as_secs_f64() / steps as f64;
    drop(fluid);
    println!("fluid step: {:.1} ms ({:.0} MLUPS)", fluid_step * 1e3, grid.nodes() as f64 / fluid_step / 1e6);

    // Slots: horizontal cylinders, axis along x on even layers and y on odd ones.
    let gap = 2.0;
    let (sl, sw) = (l + gap, d + gap);
    let mut bodies = Vec::new();
    let mut layer = 0;
    'fill: loop {
        let z = 0.5 * sw + layer as f64 * sw;
        if z + 0.5 * sw > dims[2] as f64 {
            break;
        }
        let along_x = layer % 2 == 0;
        let (na, nb) = if along_x {
            ((dims[0] as f64 / sl) as usize, (dims[1] as f64 / sw) as usize)
        } else {
            ((dims[1] as f64 / sl) as usize, (dims[0] as f64 / sw) as usize)
        };
        for a in 0..na {
            for b in 0..nb {
                if bodies.len() == n_bodies {
                    break 'fill;
                }
                let (pa, pb) = (0.5 * sl + a as f64 * sl, 0.5 * sw + b as f64 * sw);
                let pos = if along_x { Vec3::new(pa, pb, z) } else { Vec3::new(pb, pa, z) };
                let k = bodies.len() as f64;
                // Axis along x or y, tilted by up to ±2° (deterministic).
                let tilt = (0.035 * (k * 0.618).sin(), 0.035 * (k * 1.3).cos());
                let q = if along_x {
                    Quat::from_euler_angles(tilt.0, std::f64::consts::FRAC_PI_2, 0.0)
                } else {
                    Quat::from_euler_angles(std::f64::consts::FRAC_PI_2, tilt.1, 0.0)
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
    let g = (132.0f64 * scale / (4000.0 * scale)).powi(2) / (9.08 * 0.25 * d);
    let mut cp =
        Coupled::new(new_fluid(), bodies, CouplingParams { gravity: [0.0, 0.0, -g], ..Default::default() })
            .expect("coupling");
    let markers = cp.marker_count();
    cp.run(2).expect("coupled warm-up");
    cp.reset_timings();
    let t = Instant::now();
    cp.run(steps).expect("coupled steps");
    let coupled_step = t.elapsed().as_secs_f64() / steps as f64;
    let tm = *cp.timings();
    let per = |s: f64| s / tm.steps as f64 * 1e3;
    println!(
        "coupled step: {:.1} ms = {:.2} x the fluid step; {markers} markers ({:.0} per body), band {} nodes",
        coupled_step * 1e3,
        coupled_step / fluid_step,
        markers as f64 / n_bodies as f64,
        cp.band_nodes()
    );
    println!(
        "  phases (ms/step): geometry {:.1}, interior sums {:.1}, IBM forcing {:.1}, fluid {:.1}, bodies {:.1}",
        per(tm.geometry),
        per(tm.interior),
        per(tm.forcing),
        per(tm.fluid),
        per(tm.bodies)
    );
    println!(
        "  IBM pass (band velocity + interpolate + force + spread) per marker: {:.0} ns ({threads} threads), {:.0} ns·core",
        tm.forcing / tm.steps as f64 / markers as f64 * 1e9,
        tm.forcing / tm.steps as f64 / markers as f64 * 1e9 * threads as f64
    );
}
