//! Cost of the impeller in the coupled step, at the paper's scale and without particles.
//!
//! ```text
//! cargo run --release --example impeller_step -- [KIND] [SCALE] [STEPS]
//! ```
//!
//! Defaults: the paper's PBT (`KIND = pbt`; or `disk`) at scale 1 (`251 × 251 × 240`,
//! `D = 132`, shaft to the lid), f32 BGK `ν = 0.05`, `N = 1/4000`, 10 timed steps after 4
//! warm-up steps started mid-ramp. Prints the impeller's marker count, the fluid-only step on
//! the same grid (force field on), and the coupled step by phase
//! ([`slurry::coupling::StepTimings`]): the impeller's share is `1 − fluid / coupled`.

use std::time::Instant;

use slurry::coupling::{Coupled, CouplingParams};
use slurry::lattice::Grid;
use slurry::lbm::{Boundaries, Fluid, FluidParams};
use slurry::rigid::impeller::{ImpellerGeometry, RampedRotation};
use slurry::rigid::{Impeller, Motion, RigidBody, Vec3};

fn main() {
    let args: Vec<String> = std::env::args().skip(1).collect();
    let kind = args.first().map_or("pbt", String::as_str).to_string();
    let scale: f64 = args.get(1).map_or(1.0, |a| a.parse().expect("SCALE is a number"));
    let steps: u64 = args.get(2).map_or(10, |a| a.parse().expect("STEPS is an integer"));
    let n = [
        (251.0 * scale).round() as usize,
        (251.0 * scale).round() as usize,
        (240.0 * scale).round() as usize,
    ];
    let grid = Grid::new(n[0], n[1], n[2]);
    let nu = 0.05 * scale;
    let centre = Vec3::new(0.5 * (n[0] as f64 - 1.0), 0.5 * (n[1] as f64 - 1.0), 0.5 * (n[2] as f64 - 1.0));
    let shaft = n[2] as f64 - 0.5 - centre.z;
    let geometry = match kind.as_str() {
        "disk" => ImpellerGeometry::paper_disk(scale, shaft),
        "pbt" => ImpellerGeometry::paper_pbt(scale, shaft),
        other => panic!("KIND must be pbt or disk, not {other}"),
    };
    let shape = std::sync::Arc::new(Impeller::new(geometry).expect("paper geometry"));
    let motion = RampedRotation {
        axis: Vec3::z(),
        revolutions_per_step: 1.0 / (4000.0 * scale),
        ramp_steps: 4000.0 * scale,
    };
    let body = RigidBody::new(shape, 1.0, Motion::Prescribed(std::sync::Arc::new(motion)))
        .with_position(centre)
        .with_time(2000.0 * scale);
    let threads = rayon::current_num_threads();
    println!(
        "grid {n:?} ({:.1} M nodes), {kind} D = {}, {threads} threads",
        grid.nodes() as f64 / 1e6,
        132.0 * scale
    );

    let new_fluid = || {
        let mut f = Fluid::<f32>::new(grid, FluidParams::bgk(nu), Boundaries::closed_box()).expect("fluid");
        f.initialize(|_, _, _| (1.0, [0.0; 3]));
        f
    };
    let mut fluid = new_fluid();
    fluid.enable_force_field();
    fluid.run(2);
    let t = Instant::now();
    fluid.run(steps);
    let fluid_step = t.elapsed().as_secs_f64() / steps as f64;
    drop(fluid);
    println!("fluid step: {:.1} ms ({:.0} MLUPS)", fluid_step * 1e3, grid.nodes() as f64 / fluid_step / 1e6);

    let mut c = Coupled::new(new_fluid(), vec![body], CouplingParams::default()).expect("coupling");
    println!("impeller markers: {}", c.marker_count());
    rayon::scope(|_| c.run(4)).expect("warm-up");
    c.reset_timings();
    let t = Instant::now();
    rayon::scope(|_| c.run(steps)).expect("steps");
    let coupled = t.elapsed().as_secs_f64() / steps as f64;
    let tm = c.timings();
    let per = |s: f64| s / tm.steps as f64 * 1e3;
    println!(
        "coupled step: {:.1} ms = {:.2} x the fluid step; impeller share {:.1} %",
        coupled * 1e3,
        coupled / fluid_step,
        100.0 * (1.0 - fluid_step / coupled)
    );
    println!(
        "  geometry {:.1} ms, interior {:.1} ms, forcing {:.1} ms, fluid {:.1} ms, bodies {:.1} ms",
        per(tm.geometry),
        per(tm.interior),
        per(tm.forcing),
        per(tm.fluid),
        per(tm.bodies)
    );
}
