//! # Fused AA kernel ≡ two-lattice reference kernel, bitwise
//!
//! **What.** The production kernel ([`slurry::lbm::Fluid`]: AA pattern, one lattice in place,
//! structure of arrays, ghost-layer link lists, SIMD chosen at run time) against the plain
//! oracle ([`slurry::lbm::ReferenceFluid`]: two lattices, node-major, collide then push, every
//! boundary link resolved on the fly). Same initial state; after every step (odd and even
//! counts: the AA pattern stores the populations differently after each) every shifted
//! population of every fluid node is compared bit for bit.
//!
//! **Configurations.** Periodic box; a channel with a no-slip floor and a moving lid (with
//! obstacles: rows with solid nodes take the scalar path); a closed box with two moving walls
//! (diagonal links crossing two walls average their velocities); degenerate periodic boxes
//! one node wide (as the channel cases use: a periodic link then points back to the node
//! itself). `nx = 13` is not a multiple of any lane count, so row tails take the scalar path.
//! Each in f32 and f64, BGK and TRT, with and without the force field and body force, on every
//! instruction set of this CPU ([`slurry::lbm::Isa::available`]).
//!
//! **Metric.** Number of compared values and number of mismatching bit patterns.
//! **Tolerance: 0 mismatches.** Why: both kernels evaluate the same collision function (written
//! once, lane-generic) with the same IEEE operations in the same order, no fused multiply-add,
//! and streaming and bounce-back are copies plus the same rounded wall term; any difference at
//! all is a bug in indexing, boundary links, or vectorisation (this is the equivalence test of
//! waLBerla's `SweepEquivalenceTest`). The same claim is also a cargo test
//! (`tests/fused_vs_reference.rs`); this case reports the counts.

use slurry::lattice::{Face, Grid, Q};
use slurry::lbm::{Boundaries, FaceBoundary, Fluid, FluidParams, Isa, Real, ReferenceFluid};

use crate::{CaseOutput, Check, Table, Tier};

const CASE: &str = "fused_vs_reference";

fn init(x: usize, y: usize, z: usize) -> (f64, [f64; 3]) {
    let s = (x as f64 * 0.7 + y as f64 * 1.3 + z as f64 * 0.4).sin();
    let c = (x as f64 * 0.2 - y as f64 * 0.9 + z as f64 * 1.1).cos();
    (1.0 + 0.01 * s, [0.02 * c, -0.015 * s, 0.01 * s * c])
}

fn force(x: usize, y: usize, z: usize) -> [f64; 3] {
    let s = (x as f64 * 1.7 + y as f64 * 0.3 - z as f64 * 0.8).sin();
    [1e-4 * s, -2e-4 * s, 5e-5]
}

fn block(x: usize, y: usize, z: usize) -> bool {
    (3..5).contains(&x) && (2..4).contains(&y) && (1..3).contains(&z) || (x, y, z) == (9, 5, 4)
}

struct Config {
    name: &'static str,
    grid: Grid,
    boundaries: Boundaries,
    obstacles: bool,
}

fn configs() -> Vec<Config> {
    let lid = Boundaries::periodic()
        .with(Face::ZMin, FaceBoundary::NoSlip)
        .with(Face::ZMax, FaceBoundary::MovingWall { velocity: [0.05, -0.02, 0.0] });
    let walls = Boundaries::closed_box()
        .with(Face::YMax, FaceBoundary::MovingWall { velocity: [0.03, 0.0, 0.01] })
        .with(Face::XMin, FaceBoundary::MovingWall { velocity: [0.0, 0.02, 0.0] });
    vec![
        Config {
            name: "periodic 13x7x6",
            grid: Grid::new(13, 7, 6),
            boundaries: Boundaries::periodic(),
            obstacles: false,
        },
        Config {
            name: "channel+lid+obstacles 13x7x6",
            grid: Grid::new(13, 7, 6),
            boundaries: lid,
            obstacles: true,
        },
        Config {
            name: "closed moving walls+obstacles 13x7x6",
            grid: Grid::new(13, 7, 6),
            boundaries: walls,
            obstacles: true,
        },
        Config {
            name: "column channel+lid 1x1x9",
            grid: Grid::new(1, 1, 9),
            boundaries: lid,
            obstacles: false,
        },
        Config {
            name: "slab periodic 1x2x5",
            grid: Grid::new(1, 2, 5),
            boundaries: Boundaries::periodic(),
            obstacles: false,
        },
    ]
}

/// `(compared values, mismatches)` for one configuration, precision, model, force setting
/// and ISA, over `steps` steps.
fn compare<T: Real>(c: &Config, params: FluidParams, ff: bool, isa: Isa, steps: u64) -> (u64, u64) {
    let g = c.grid;
    let solid = |x: usize, y: usize, z: usize| c.obstacles && block(x, y, z);
    let mut a = Fluid::<T>::new(g, params, c.boundaries).expect("valid set-up");
    let mut r = ReferenceFluid::<T>::new(g, params, c.boundaries).expect("valid set-up");
    a.set_isa(isa);
    a.set_obstacles(solid).expect("even time");
    r.set_obstacles(solid);
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
    let (mut n, mut bad) = (0u64, 0u64);
    for _ in 0..steps {
        a.step();
        r.step(ff);
        for z in 0..g.nz {
            for y in 0..g.ny {
                for x in 0..g.nx {
                    if solid(x, y, z) {
                        continue;
                    }
                    let ha = a.shifted_populations(x, y, z);
                    let hr = r.shifted_populations(x, y, z);
                    for q in 0..Q {
                        n += 1;
                        if ha[q].to_f64().to_bits() != hr[q].to_f64().to_bits() {
                            bad += 1;
                        }
                    }
                }
            }
        }
    }
    (n, bad)
}

/// Runs the case.
pub fn run(tier: Tier) -> CaseOutput {
    let steps = match tier {
        Tier::Quick => 7,
        Tier::Full => 40,
    };
    let isas = Isa::available();
    let isa_names: Vec<&str> = isas.iter().map(|i| i.name()).collect();
    let mut out = CaseOutput::default();
    let mut t = Table::new(
        format!(
            "per configuration, {steps} steps, summed over f32/f64 x bgk/trt x force field \
             off/on x ISA {{{}}}",
            isa_names.join(", ")
        ),
        &[("config", false), ("compared", false), ("mismatches", false)],
    );
    let (mut total, mut total_bad) = (0u64, 0u64);
    let mut legend = Vec::new();
    for (k, c) in configs().iter().enumerate() {
        legend.push(format!("{k} = {}", c.name));
        let (mut n, mut bad) = (0, 0);
        for &isa in &isas {
            for trt in [false, true] {
                for ff in [false, true] {
                    let base = if trt { FluidParams::trt(0.03) } else { FluidParams::bgk(0.08) };
                    let p = base.with_body_force([1e-5, -2e-5, 0.0]);
                    let (a, b) = compare::<f64>(c, p, ff, isa, steps);
                    let (a2, b2) = compare::<f32>(c, p, ff, isa, steps);
                    n += a + a2;
                    bad += b + b2;
                }
            }
        }
        t.push(vec![k as f64, n as f64, bad as f64]);
        total += n;
        total_bad += bad;
    }
    t.title = format!("{} [config: {}]", t.title, legend.join("; "));
    out.tables.push(t);
    out.checks.push(Check::exact(
        CASE,
        "mismatching_values",
        total_bad as f64,
        0.0,
        "same IEEE operations in the same order in both kernels, no FMA: any difference is a bug",
    ));
    out.checks.push(Check::at_least(
        CASE,
        "compared_values",
        total as f64,
        total as f64,
        1.0,
        "the comparison ran (a count of 0 would make the mismatch check vacuous)",
    ));
    out
}
