//! The fused AA kernel equals the plain two-lattice reference kernel bitwise, for every
//! boundary kind, both collision models, with and without the force field, on every
//! instruction set this CPU has, after odd and even numbers of steps.

use slurry::lattice::{Face, Grid, Q};
use slurry::lbm::{Boundaries, FaceBoundary, Fluid, FluidParams, Isa, Real, ReferenceFluid};

fn init(x: usize, y: usize, z: usize) -> (f64, [f64; 3]) {
    let s = (x as f64 * 0.7 + y as f64 * 1.3 + z as f64 * 0.4).sin();
    let c = (x as f64 * 0.2 - y as f64 * 0.9 + z as f64 * 1.1).cos();
    (1.0 + 0.01 * s, [0.02 * c, -0.015 * s, 0.01 * s * c])
}

fn force(x: usize, y: usize, z: usize) -> [f64; 3] {
    let s = (x as f64 * 1.7 + y as f64 * 0.3 - z as f64 * 0.8).sin();
    [1e-4 * s, -2e-4 * s, 5e-5]
}

fn obstacle(x: usize, y: usize, z: usize) -> bool {
    // A small block and a single node: rows with obstacles take the scalar path.
    (3..5).contains(&x) && (2..4).contains(&y) && (1..3).contains(&z) || (x, y, z) == (9, 5, 4)
}

fn compare<T: Real>(b: Boundaries, params: FluidParams, ff: bool, obst: bool) {
    // nx = 13 is not a multiple of any lane count: tails take the scalar path too.
    let g = Grid::new(13, 7, 6);
    for isa in Isa::available() {
        let mut a = Fluid::<T>::new(g, params, b).unwrap();
        let mut r = ReferenceFluid::<T>::new(g, params, b).unwrap();
        a.set_isa(isa);
        if obst {
            a.set_obstacles(obstacle).unwrap();
            r.set_obstacles(obstacle);
        }
        a.initialize(init);
        r.initialize(init);
        if ff {
            a.enable_force_field();
            for z in 0..g.nz {
                for y in 0..g.ny {
                    for x in 0..g.nx {
                        a.set_force(x, y, z, force(x, y, z));
                        r.set_force(x, y, z, force(x, y, z));
                    }
                }
            }
        }
        for step in 1..=7 {
            a.step();
            r.step(ff);
            for z in 0..g.nz {
                for y in 0..g.ny {
                    for x in 0..g.nx {
                        if obst && obstacle(x, y, z) {
                            continue;
                        }
                        let ha = a.shifted_populations(x, y, z);
                        let hr = r.shifted_populations(x, y, z);
                        for q in 0..Q {
                            assert!(
                                ha[q].to_f64().to_bits() == hr[q].to_f64().to_bits(),
                                "{} {isa:?} step {step} node ({x},{y},{z}) q {q}: fused {} reference {}",
                                T::NAME,
                                ha[q],
                                hr[q]
                            );
                        }
                    }
                }
            }
        }
    }
}

fn mixed() -> Boundaries {
    Boundaries::periodic()
        .with(Face::ZMin, FaceBoundary::NoSlip)
        .with(Face::ZMax, FaceBoundary::MovingWall { velocity: [0.05, -0.02, 0.0] })
}

fn walls() -> Boundaries {
    Boundaries::closed_box()
        .with(Face::YMax, FaceBoundary::MovingWall { velocity: [0.03, 0.0, 0.01] })
        .with(Face::XMin, FaceBoundary::MovingWall { velocity: [0.0, 0.02, 0.0] })
}

#[test]
fn periodic_bgk_f64() {
    compare::<f64>(
        Boundaries::periodic(),
        FluidParams::bgk(0.05).with_body_force([1e-5, 0.0, -2e-5]),
        false,
        false,
    );
}

#[test]
fn periodic_trt_forcefield_f32() {
    compare::<f32>(Boundaries::periodic(), FluidParams::trt(0.1), true, false);
}

#[test]
fn mixed_walls_obstacles_bgk_f64_and_f32() {
    compare::<f64>(mixed(), FluidParams::bgk(0.08), true, true);
    compare::<f32>(mixed(), FluidParams::bgk(0.08), false, true);
}

#[test]
fn closed_moving_walls_trt_f64_and_f32() {
    compare::<f64>(walls(), FluidParams::trt(0.03).with_body_force([0.0, 1e-5, 0.0]), true, true);
    compare::<f32>(walls(), FluidParams::trt(0.03), true, false);
}

/// A snapshot taken at an even step and restored into a fresh fluid continues bitwise
/// identically (what checkpoints rely on), with walls, obstacles and the force field on.
#[test]
fn snapshot_restore_continues_bitwise() {
    let g = Grid::new(13, 7, 6);
    let params = FluidParams::trt(0.03).with_body_force([0.0, 1e-5, 0.0]);
    let make = || {
        let mut f = Fluid::<f32>::new(g, params, walls()).unwrap();
        f.set_obstacles(obstacle).unwrap();
        f.initialize(init);
        f.enable_force_field();
        f.set_force(2, 3, 4, [1e-4, 0.0, -1e-4]);
        f
    };
    let mut a = make();
    a.run(6);
    let snap = a.snapshot().unwrap();
    a.step();
    assert!(a.snapshot().is_err(), "odd time must refuse a snapshot");
    a.run(7);
    let mut b = make();
    b.run(2); // different state, overwritten by the restore
    b.restore(&snap).unwrap();
    b.run(8);
    assert_eq!(a.time(), b.time());
    assert_eq!(a.snapshot().unwrap(), b.snapshot().unwrap());
}

/// `Fluid::run_moments` (the vectorised row read of the coupling's dense steps) gives
/// bitwise the density and momentum that `Fluid::for_each_in_run` passes, after even and odd
/// numbers of steps, for whole rows and for pieces that start inside a row, and the velocity
/// `(j + F/2)/ρ` bitwise.
fn run_moments_match<T: Real>() {
    let g = Grid::new(13, 7, 6);
    let mut a = Fluid::<T>::new(g, FluidParams::bgk(0.1), walls()).unwrap();
    a.initialize(init);
    let (mut rho, mut j, mut u) = ([0.0f64; 13], [[0.0f64; 3]; 13], [[0.0f64; 3]; 13]);
    let force = [1.5e-5, -2.5e-6, 3.0e-5];
    for step in 0..3 {
        for z in 0..g.nz {
            for y in 0..g.ny {
                for (x0, len) in [(0, 13), (3, 7), (12, 1)] {
                    let run = slurry::lattice::Run { x0, len, y: y as u32, z: z as u32 };
                    a.run_moments(run, &mut rho, &mut j, force, &mut u);
                    a.for_each_in_run(run, |x, r, jj, _| {
                        let k = x - x0 as usize;
                        // u = (j + F/2)/ρ bitwise.
                        let expect: [f64; 3] = std::array::from_fn(|c| (jj[c] + 0.5 * force[c]) / r);
                        assert_eq!(
                            u[k].map(f64::to_bits),
                            expect.map(f64::to_bits),
                            "u at ({x}, {y}, {z}), step {step}"
                        );
                        assert_eq!(r.to_bits(), rho[k].to_bits(), "rho at ({x}, {y}, {z}), step {step}");
                        assert_eq!(
                            jj.map(f64::to_bits),
                            j[k].map(f64::to_bits),
                            "j at ({x}, {y}, {z}), step {step}"
                        );
                    });
                }
            }
        }
        a.step();
    }
}

#[test]
fn run_moments_equal_the_run_reads_bitwise() {
    run_moments_match::<f32>();
    run_moments_match::<f64>();
}
