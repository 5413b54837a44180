//! The device backend's fluid (`slurry::device::DeviceFluid`) against the CPU solver
//! (`Fluid<f32>`), on the Vulkan adapter the machine has (a GPU, or Mesa's lavapipe in CI:
//! `cargo xtask setup` installs it).
//!
//! Small grids with odd sizes (indexing errors show), 100–200 steps: a periodic box driven by a
//! body force and a force field (BGK and TRT), a closed box with a moving lid, a solid block,
//! and a run on the device continued from its checkpoint on the CPU and on the device. The
//! device performs the CPU's operations in the CPU's order on the same f32 storage, but its
//! driver may contract or split `fma` and round `1/ρ` otherwise (Vulkan allows it), so the two
//! differ by round-off: the bound [`BOUND`] below says how much that may be, and each test
//! prints what it measured. Device runs themselves are compared bitwise.
//!
//! Without a Vulkan adapter these tests fail, with a message that names `cargo xtask setup`.

use std::path::Path;
use std::sync::OnceLock;

use slurry::case::Case;
use slurry::device::{fluid::DeviceReal, fluid::DEFAULT_WORKGROUP, Context, DeviceFluid};
use slurry::io::read_checkpoint;
use slurry::lattice::{Face, Grid};
use slurry::lbm::{Boundaries, FaceBoundary, Fluid, FluidParams, Real};
use slurry::run::{run_case, RunOptions};

/// The largest difference allowed between a population on the device and on the CPU after
/// 200 steps. The populations are O(1e-2) here; one f32 rounding of such a value is at most
/// 2^-24 · 2^-6 ≈ 1e-9. A driver that does not fuse `fma` or rounds `1/ρ` within 2.5 ulp
/// (Vulkan's bound) changes a few roundings per collision, and the differences are carried
/// and damped by the collision (|1 − ω| < 1): a few ulp per step, growing at most linearly,
/// 200 steps × a few × 1e-9 ≈ 1e-6. Measured on lavapipe (Mesa 22.3, LLVM 15): at most 3.7e-9,
/// most populations differing by an ulp or two.
const BOUND: f64 = 2e-6;

/// [`BOUND`]'s argument in f64 storage (an ulp 2^29 times smaller): 2e-6 · 2^-29 ≈ 3.7e-15.
const BOUND_F64: f64 = 3.7e-15;

fn ctx() -> &'static Context {
    static CTX: OnceLock<Context> = OnceLock::new();
    CTX.get_or_init(|| match Context::new() {
        Ok(c) => c,
        Err(e) => panic!("the device tests need a Vulkan adapter: {e}"),
    })
}

/// The largest difference between the two fluids' shifted populations over all interior
/// nodes and directions, and how many differ at all.
fn difference<T: DeviceReal>(a: &Fluid<T>, b: &Fluid<T>) -> (f64, usize) {
    assert_eq!(a.time(), b.time());
    let (pa, pb) = (a.populations_all(), b.populations_all());
    let mut max = 0.0f64;
    let mut n = 0;
    for (x, y) in pa.iter().zip(&pb) {
        if x.to_bits() != y.to_bits() {
            n += 1;
            max = max.max((x - y).abs());
        }
    }
    (max, n)
}

/// A smooth, nonuniform start: density and velocity varying along all three axes.
fn start<T: Real>(f: &mut Fluid<T>) {
    f.initialize(|x, y, z| {
        let s = ((x * 7 + y * 3 + z * 5) as f64 * 0.13).sin();
        let c = ((x + 2 * y + 3 * z) as f64 * 0.21).cos();
        (1.0 + 2e-3 * s, [0.02 * s, -0.015 * c, 0.01 * s * c])
    });
}

/// A force field that varies from node to node.
fn force_field<T: Real>(f: &mut Fluid<T>) {
    f.enable_force_field();
    let g = f.grid();
    for z in 0..g.nz {
        for y in 0..g.ny {
            for x in 0..g.nx {
                let s = ((x * 5 + y * 11 + z * 3) as f64 * 0.37).sin();
                f.set_force(x, y, z, [1e-5 * s, -2e-5 * s, 5e-6]);
            }
        }
    }
}

/// Runs `cpu` and a device copy of it `steps` steps, downloads, and returns the device's
/// host mirror (a copy of `cpu` made before stepping).
fn on_both<T: DeviceReal>(cpu: &mut Fluid<T>, steps: u64, make: impl Fn() -> Fluid<T>) -> Fluid<T> {
    let mut host = make();
    let mut dev = DeviceFluid::new(ctx(), &host, DEFAULT_WORKGROUP).expect("device fluid");
    dev.run(steps).expect("device steps");
    dev.download(&mut host).expect("download");
    cpu.run(steps);
    host
}

/// The bound for storage precision `T`: [`BOUND`], or for f64 [`BOUND_F64`].
fn bound<T: DeviceReal>() -> f64 {
    if T::WGSL == "f64" {
        BOUND_F64
    } else {
        BOUND
    }
}

/// Compares and reports; fails beyond [`bound`].
fn check<T: DeviceReal>(what: &str, cpu: &Fluid<T>, dev: &Fluid<T>) {
    let (max, n) = difference(cpu, dev);
    let bound = bound::<T>();
    println!("{what}: {n} of {} populations differ, max |diff| = {max:.3e}", cpu.grid().nodes() * 19);
    assert!(max <= bound, "{what}: device and CPU differ by {max:.3e} > {bound:e} ({n} populations differ)");
}

fn periodic_forced<T: Real>(trt: bool) -> Fluid<T> {
    let g = Grid::new(24, 20, 18);
    let p = if trt { FluidParams::trt(0.04) } else { FluidParams::bgk(0.04) };
    let mut f = Fluid::<T>::new(g, p.with_body_force([2e-5, -1e-5, 3e-6]), Boundaries::periodic()).unwrap();
    start(&mut f);
    force_field(&mut f);
    f
}

#[test]
fn periodic_box_with_body_force_and_force_field_bgk() {
    let make = || periodic_forced::<f32>(false);
    let mut cpu = make();
    let (_, mass0) = cpu.mass_deviation();
    let dev = on_both(&mut cpu, 200, make);
    check("periodic BGK, body force and field, 200 steps", &cpu, &dev);
    // Mass: the collision conserves Σh exactly in exact arithmetic; in f32 each node's 19
    // stored values are rounded each step (≤ 1e-9 each at O(1e-2)), with signs that do not
    // line up: √(8640 · 19 · 200) · 1e-9 ≈ 2e-5 over the run. Measured: 1.9e-6, as on the CPU.
    let (_, mass1) = dev.mass_deviation();
    let (_, cpu1) = cpu.mass_deviation();
    println!("mass deviation {mass0:.6e} -> device {mass1:.6e}, CPU {cpu1:.6e}");
    assert!((mass1 - mass0).abs() < 2e-5, "device mass changed by {:.3e}", mass1 - mass0);
}

fn periodic_trt<T: DeviceReal>() {
    let make = periodic_forced::<T>;
    let mut cpu = make(true);
    let dev = on_both(&mut cpu, 200, || make(true));
    check(&format!("periodic TRT, body force and field, 200 steps, {}", T::WGSL), &cpu, &dev);
}

#[test]
fn periodic_box_with_body_force_and_force_field_trt() {
    periodic_trt::<f32>();
}

fn closed_box<T: DeviceReal>() {
    let make = || {
        let g = Grid::new(23, 19, 17);
        let b = Boundaries::closed_box()
            .with(Face::ZMax, FaceBoundary::MovingWall { velocity: [0.05, 0.02, 0.0] });
        let mut f = Fluid::<T>::new(g, FluidParams::trt(0.05), b).unwrap();
        start(&mut f);
        f
    };
    let mut cpu = make();
    let dev = on_both(&mut cpu, 150, make);
    check(&format!("closed box, moving lid, TRT, 150 steps, {}", T::WGSL), &cpu, &dev);
    // Closed box: no population leaves; the walls' terms sum to zero over each wall (ρ_w = 1).
    let (m0, m1) = (make().mass_deviation().1, dev.mass_deviation().1);
    // The bound of the periodic box's mass check (round-off only), for a similar node count.
    assert!((m1 - m0).abs() < 2e-5, "mass changed by {:.3e}", m1 - m0);
}

#[test]
fn closed_box_with_a_moving_lid() {
    closed_box::<f32>();
}

fn solid_block<T: DeviceReal>() {
    let make = || {
        let g = Grid::new(25, 20, 18);
        let b = Boundaries::periodic()
            .with(Face::YMin, FaceBoundary::NoSlip)
            .with(Face::YMax, FaceBoundary::NoSlip);
        let mut f = Fluid::<T>::new(g, FluidParams::bgk(0.03).with_body_force([1e-5, 0.0, 0.0]), b).unwrap();
        f.set_obstacles(|x, y, z| (8..13).contains(&x) && (5..12).contains(&y) && (4..15).contains(&z))
            .unwrap();
        start(&mut f);
        f
    };
    let mut cpu = make();
    let dev = on_both(&mut cpu, 101, make);
    // 101: the comparison at odd time reads the AA layout through the ghost and obstacle slots.
    check(&format!("channel with a solid block, BGK, 101 steps, {}", T::WGSL), &cpu, &dev);
}

#[test]
fn solid_block_in_a_driven_channel() {
    solid_block::<f32>();
}

/// f64 storage on the device, where the adapter has 64-bit float shaders (lavapipe and
/// NVIDIA's Vulkan driver do): the same three set-ups against the CPU's `Fluid<f64>`, within
/// [`BOUND_F64`]; an adapter without them refuses f64 with an error that says so.
#[test]
fn f64_storage_on_the_device_as_on_the_cpu() {
    if !ctx().has_f64() {
        let f = periodic_forced::<f64>(true);
        let e = DeviceFluid::new(ctx(), &f, DEFAULT_WORKGROUP).err().expect("refused without f64 shaders");
        assert!(e.to_string().contains("f64"), "{e}");
        println!("the adapter has no f64 shaders: refused ({e})");
        return;
    }
    periodic_trt::<f64>();
    closed_box::<f64>();
    solid_block::<f64>();
}

#[test]
fn an_f64_host_fluid_does_not_fit_an_f32_device_fluid() {
    let host = periodic_forced::<f32>(true);
    let dev = DeviceFluid::new(ctx(), &host, DEFAULT_WORKGROUP).unwrap();
    let mut other = periodic_forced::<f64>(true);
    let e = dev.download(&mut other).unwrap_err().to_string();
    assert!(e.contains("f64") && e.contains("f32"), "{e}");
}

/// The device's populations after `steps` steps with work groups of `wg`.
fn device_run(wg: u32, steps: u64) -> Vec<f64> {
    let mut host = periodic_forced::<f32>(true);
    let mut dev = DeviceFluid::new(ctx(), &host, wg).expect("device fluid");
    dev.run(steps).unwrap();
    dev.download(&mut host).unwrap();
    host.populations_all()
}

#[test]
fn device_runs_are_bitwise_reproducible_for_any_work_group_size() {
    let first = device_run(64, 100);
    assert!(first.iter().any(|&v| v != 0.0), "the state moved");
    let bits = |v: &[f64]| v.iter().map(|x| x.to_bits()).collect::<Vec<_>>();
    assert_eq!(bits(&first), bits(&device_run(64, 100)), "two runs differ");
    for wg in [1, 7, 32, 256] {
        assert_eq!(bits(&first), bits(&device_run(wg, 100)), "work-group size {wg} differs from 64");
    }
}

#[test]
fn upload_download_round_trip_and_stepping_in_pieces() {
    // 60 steps in pieces (odd ones included) with a download and an upload between them equal 60 at once.
    let mut a = periodic_forced::<f32>(false);
    let mut dev = DeviceFluid::new(ctx(), &a, DEFAULT_WORKGROUP).unwrap();
    for n in [1, 13, 2, 44] {
        dev.run(n).unwrap();
        dev.download(&mut a).unwrap();
        dev.upload(&a).unwrap();
    }
    let mut b = periodic_forced::<f32>(false);
    let mut whole = DeviceFluid::new(ctx(), &b, DEFAULT_WORKGROUP).unwrap();
    whole.run(60).unwrap();
    whole.download(&mut b).unwrap();
    assert_eq!(a.time(), 60);
    assert_eq!(difference(&a, &b), (0.0, 0), "stepping in pieces changed the result");
}

/// A fluid-only case: Taylor–Green in x–y, a moving lid on z, a body force; f32 TRT.
fn case_text(steps: u64, device: &str) -> String {
    format!(
        "[domain]\nnx = 21\nny = 18\nnz = 13\n\n[fluid]\nprecision = \"f32\"\nnu = 0.05\ncollision = \"trt\"\n\
         body_force = [1e-6, 0.0, 0.0]\n\n[boundaries]\nx_min = \"periodic\"\nx_max = \"periodic\"\n\
         y_min = \"periodic\"\ny_max = \"periodic\"\nz_min = \"no_slip\"\nz_max = {{ moving_wall = [0.03, 0.0, 0.0] }}\n\n\
         [initial]\nkind = \"taylor_green\"\namplitude = 0.02\n\n\
         [run]\nsteps = {steps}\noutput_every = 50\ncheckpoint_every = 100\ndevice = \"{device}\"\n"
    )
}

fn run_to(dir: &Path, steps: u64, device: &str, resume: bool) {
    let case = Case::parse(&case_text(steps, device), "device.toml").expect("valid case");
    let opts = RunOptions { quiet: true, resume, ..RunOptions::default() };
    run_case(&case, dir, opts).unwrap_or_else(|e| panic!("run on {device} to {steps}: {e:#}"));
}

fn checkpoint_fluid(dir: &Path) -> Vec<f32> {
    read_checkpoint::<f32>(&dir.join("checkpoint.h5")).unwrap().state.populations
}

#[test]
fn a_device_checkpoint_resumes_on_the_cpu_and_on_the_device() {
    ctx();
    let tmp = tempfile::tempdir().unwrap();
    let (dev, cpu, reference) = (tmp.path().join("dev"), tmp.path().join("cpu"), tmp.path().join("ref"));
    // 100 steps on the device, checkpoint at 100; a copy continues on the CPU.
    run_to(&dev, 100, "gpu", false);
    std::fs::create_dir_all(&cpu).unwrap();
    for f in ["checkpoint.h5", "timeseries.csv"] {
        std::fs::copy(dev.join(f), cpu.join(f)).unwrap();
    }
    run_to(&cpu, 200, "cpu", true);
    run_to(&dev, 200, "gpu", true);
    run_to(&reference, 200, "cpu", false);
    let want = checkpoint_fluid(&reference);
    for (what, dir) in [("device, then the CPU", &cpu), ("device throughout", &dev)] {
        let got = checkpoint_fluid(dir);
        assert_eq!(got.len(), want.len());
        let max = got.iter().zip(&want).map(|(a, b)| (a - b).abs() as f64).fold(0.0, f64::max);
        println!("{what} vs the CPU alone at step 200: max |diff| = {max:.3e}");
        assert!(max <= BOUND, "{what}: {max:.3e} from the CPU-only run");
    }
}

#[test]
fn f64_runs_the_fluid_alone_on_the_device_and_refuses_bodies() {
    let text = std::fs::read_to_string(
        Path::new(env!("CARGO_MANIFEST_DIR")).join("examples/stirred_tank_particles.toml"),
    )
    .unwrap();
    // Particles and an impeller in f32 run there (tests/device_run.rs) ...
    let mut case = Case::parse(&text, "stirred.toml").unwrap();
    case.run.device = slurry::case::Device::Gpu;
    case.validate_settings().expect("an f32 case with particles and an impeller runs on the device");
    // ... in f64 they do not: the markers work in f32.
    let mut case = Case::parse(&text.replace("\"f32\"", "\"f64\""), "stirred64.toml").unwrap();
    case.run.device = slurry::case::Device::Gpu;
    let e = case.validate_settings().unwrap_err().to_string();
    assert!(e.contains("run.device") && e.contains("f32"), "{e}");
    // The fluid alone runs in f64 where the adapter has 64-bit float shaders, as on the CPU.
    let f64_text = |steps: u64, device: &str| case_text(steps, device).replace("\"f32\"", "\"f64\"");
    let tmp = tempfile::tempdir().unwrap();
    let run = |dir: &Path, device: &str| {
        let case = Case::parse(&f64_text(100, device), "f64.toml").expect("valid f64 case");
        run_case(&case, dir, RunOptions { quiet: true, ..RunOptions::default() })
    };
    let (dev, cpu) = (tmp.path().join("dev"), tmp.path().join("cpu"));
    let got = run(&dev, "gpu");
    if !ctx().has_f64() {
        let e = format!("{:#}", got.expect_err("refused without f64 shaders"));
        assert!(e.contains("f64"), "{e}");
        return;
    }
    got.expect("the f64 fluid on the device");
    run(&cpu, "cpu").expect("the f64 fluid on the CPU");
    let read = |d: &Path| read_checkpoint::<f64>(&d.join("checkpoint.h5")).unwrap().state.populations;
    let (a, b) = (read(&dev), read(&cpu));
    assert_eq!(a.len(), b.len());
    let max = a.iter().zip(&b).map(|(x, y)| (x - y).abs()).fold(0.0, f64::max);
    println!("f64 run on the device vs the CPU at step 100: max |diff| = {max:.3e}");
    assert!(max <= BOUND_F64, "f64 device run: {max:.3e} from the CPU's");
}
