//! Throughput measurement of the fused kernel (used by `slurry bench` and `cargo xtask bench`).
//!
//! Measures MLUPS (million lattice-node updates per second) of [`Fluid::step`] on a periodic
//! box, best of several repetitions of about `seconds` each, after a warm-up. The implied
//! memory traffic is `2 · 19 · sizeof(T)` bytes per update (AA pattern: every population read
//! once and written once, in place). [`measure_device`] measures the device backend's step the
//! same way.

use std::time::Instant;

use serde::Serialize;

use crate::device::{Context, DeviceError, DeviceFluid};
use crate::lattice::Grid;
use crate::lbm::{Boundaries, Fluid, FluidParams, Real};

/// One benchmark measurement.
#[derive(Clone, Debug, Serialize)]
pub struct BenchResult {
    /// `"f32"` or `"f64"`.
    pub precision: String,
    /// `"bgk"` or `"trt"`.
    pub collision: String,
    /// Worker threads.
    pub threads: usize,
    /// Box size.
    pub nx: usize,
    /// Box size.
    pub ny: usize,
    /// Box size.
    pub nz: usize,
    /// Best repetition, million node updates per second.
    pub mlups: f64,
    /// Median repetition.
    pub mlups_median: f64,
    /// Memory bandwidth implied by the best repetition, GB/s (AA pattern traffic).
    pub gbs: f64,
    /// Instruction set of the kernel.
    pub isa: String,
    /// A device row: the device's copy bandwidth measured in the same run, GB/s
    /// ([`crate::device::bandwidth`]); `gbs / copy_gbs` is the step's fraction of it.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub copy_gbs: Option<f64>,
}

/// The benchmark's fluid: a periodic box with a smooth perturbation.
fn bench_fluid<T: Real>(grid: Grid, trt: bool) -> Fluid<T> {
    let params = if trt { FluidParams::trt(0.05) } else { FluidParams::bgk(0.05) };
    let mut fluid = Fluid::<T>::new(grid, params, Boundaries::periodic()).expect("valid benchmark set-up");
    fluid.initialize(|x, y, z| {
        let s = ((x * 7 + y * 3 + z) as f64 * 0.1).sin();
        (1.0 + 1e-3 * s, [0.01 * s, -0.01 * s, 0.005])
    });
    fluid
}

/// Measures the device backend's fluid step ([`DeviceFluid::run`], f32) on the benchmark's
/// periodic `grid`, as [`measure`] does the CPU's: best and median of `reps` repetitions of
/// about `seconds` each, after a warm-up. `threads` reads 0 (not the CPU's) and `isa` `"gpu"`.
///
/// # Errors
/// The device cannot hold the grid or fails.
pub fn measure_device(
    ctx: &Context,
    grid: Grid,
    trt: bool,
    workgroup: u32,
    reps: usize,
    seconds: f64,
) -> Result<BenchResult, DeviceError> {
    let mut host = bench_fluid::<f32>(grid, trt);
    let mut dev = DeviceFluid::new(ctx, &host, workgroup)?;
    let t0 = Instant::now();
    dev.run(4)?;
    let per_step = t0.elapsed().as_secs_f64() / 4.0;
    let steps = (((seconds / per_step.max(1e-9)) as u64).max(2) + 1) & !1;
    let mut rates = Vec::with_capacity(reps);
    for _ in 0..reps {
        let t = Instant::now();
        dev.run(steps)?;
        rates.push(grid.nodes() as f64 * steps as f64 / t.elapsed().as_secs_f64() / 1e6);
    }
    dev.download(&mut host)?;
    assert!(host.health(1.0).is_ok(), "benchmark state went bad on the device: {}", host.health(1.0));
    rates.sort_by(|a, b| a.partial_cmp(b).unwrap());
    let best = *rates.last().unwrap();
    Ok(BenchResult {
        precision: "f32".to_string(),
        collision: if trt { "trt" } else { "bgk" }.to_string(),
        threads: 0,
        nx: grid.nx,
        ny: grid.ny,
        nz: grid.nz,
        mlups: best,
        mlups_median: rates[rates.len() / 2],
        gbs: best * 1e6 * Fluid::<f32>::bytes_per_update() as f64 / 1e9,
        isa: "gpu".to_string(),
        copy_gbs: None,
    })
}

/// Measures the fused kernel on a periodic `grid` with `threads` rayon workers.
pub fn measure<T: Real>(grid: Grid, trt: bool, threads: usize, reps: usize, seconds: f64) -> BenchResult {
    let pool = rayon::ThreadPoolBuilder::new().num_threads(threads).build().expect("thread pool");
    pool.install(|| {
        let mut fluid = bench_fluid::<T>(grid, trt);
        // Warm-up and calibration (an even number of steps keeps the AA parity aligned).
        let t0 = Instant::now();
        fluid.run(4);
        let per_step = t0.elapsed().as_secs_f64() / 4.0;
        let steps = (((seconds / per_step.max(1e-9)) as u64).max(2) + 1) & !1;
        let mut rates = Vec::with_capacity(reps);
        for _ in 0..reps {
            let t = Instant::now();
            fluid.run(steps);
            rates.push(grid.nodes() as f64 * steps as f64 / t.elapsed().as_secs_f64() / 1e6);
        }
        assert!(fluid.health(1.0).is_ok(), "benchmark state went bad: {}", fluid.health(1.0));
        rates.sort_by(|a, b| a.partial_cmp(b).unwrap());
        let best = *rates.last().unwrap();
        BenchResult {
            precision: T::NAME.to_string(),
            collision: if trt { "trt" } else { "bgk" }.to_string(),
            threads,
            nx: grid.nx,
            ny: grid.ny,
            nz: grid.nz,
            mlups: best,
            mlups_median: rates[rates.len() / 2],
            gbs: best * 1e6 * Fluid::<T>::bytes_per_update() as f64 / 1e9,
            isa: fluid.isa().name().to_string(),
            copy_gbs: None,
        }
    })
}
