//! The fluid gives bitwise the same state, and bitwise the same reductions (mass, momentum,
//! health), for any number of worker threads (rapier's `thread_count_determinism` in spirit).

use slurry::lattice::{Face, Grid};
use slurry::lbm::{Boundaries, FaceBoundary, Fluid, FluidParams};

fn run(threads: usize) -> (Vec<f32>, (usize, f64), [f64; 3], f64) {
    let pool = rayon::ThreadPoolBuilder::new().num_threads(threads).build().unwrap();
    pool.install(|| {
        let g = Grid::new(37, 19, 23);
        let b = Boundaries::periodic()
            .with(Face::ZMin, FaceBoundary::NoSlip)
            .with(Face::ZMax, FaceBoundary::MovingWall { velocity: [0.04, 0.01, 0.0] });
        let mut f =
            Fluid::<f32>::new(g, FluidParams::trt(0.02).with_body_force([1e-6, 0.0, 0.0]), b).unwrap();
        f.set_obstacles(|x, y, z| {
            (x as i64 - 18).pow(2) + (y as i64 - 9).pow(2) + (z as i64 - 11).pow(2) < 25
        })
        .unwrap();
        f.initialize(|x, y, _| (1.0, [0.01 * ((x + y) as f64 * 0.3).sin(), 0.0, 0.0]));
        f.enable_force_field();
        f.set_force(5, 5, 5, [1e-4, 2e-4, -1e-4]);
        f.run(60);
        (f.snapshot().unwrap().populations, f.mass_deviation(), f.total_momentum(), f.health(0.3).max_mach)
    })
}

#[test]
fn one_two_and_three_threads_agree_bitwise() {
    let one = run(1);
    for t in [2, 3] {
        let other = run(t);
        assert!(
            one.0.iter().zip(&other.0).all(|(a, b)| a.to_bits() == b.to_bits()),
            "populations differ with {t} threads"
        );
        assert_eq!(one.1 .1.to_bits(), other.1 .1.to_bits(), "mass differs with {t} threads");
        for a in 0..3 {
            assert_eq!(one.2[a].to_bits(), other.2[a].to_bits(), "momentum differs with {t} threads");
        }
        assert_eq!(one.3.to_bits(), other.3.to_bits());
    }
}
