//! `slurry run --device gpu` with particles and an impeller: the run driver on the device's
//! coupled step (`slurry::device::DeviceCoupled`) against the CPU's (`Coupled<f32>`), on the
//! Vulkan adapter the machine has (a GPU, or Mesa's lavapipe in CI: `cargo xtask setup`).
//!
//! The case is the small stirred tank of `examples/stirred_tank_particles.toml` (a PBT above 26
//! free cylinders with contacts, 36³), shortened to 100 steps: the device run against the CPU
//! run, its checkpoint resumed on either processor, and a start from a state pack on either.
//! The device performs the CPU's operations in the CPU's order on the same f32 populations,
//! with the markers in f32 where the CPU's transfer works in f64, so the two runs differ by
//! round-off that the flow carries and amplifies: `tests/device_markers.rs` measured ~1e-6 relative on the loads after a
//! few dozen steps, growing over the steps. The tolerances below are stated against that;
//! each test prints what it measured. Device runs themselves are compared bitwise.
//!
//! Without a Vulkan adapter these tests fail, with a message that names `cargo xtask setup`.

mod common;

use std::path::Path;

use slurry::case::Case;
use slurry::run::{run_case, RunOptions};

/// The stirred tank's `[run]` table: `steps` steps, a row every 20, a checkpoint every 50.
fn run_table(steps: u64) -> String {
    format!("steps = {steps}\noutput_every = 20\ncheckpoint_every = 50")
}

/// The columns `names` of `dir/timeseries.csv`, a row per output step.
fn series(dir: &Path, names: &[&str]) -> Vec<Vec<f64>> {
    let text = std::fs::read_to_string(dir.join("timeseries.csv")).expect("timeseries.csv");
    let mut lines = text.lines();
    let header: Vec<&str> = lines.next().expect("a header").split(',').collect();
    let cols: Vec<usize> = names
        .iter()
        .map(|n| header.iter().position(|h| h == n).unwrap_or_else(|| panic!("no column {n}")))
        .collect();
    lines
        .map(|l| {
            let v: Vec<&str> = l.split(',').collect();
            cols.iter().map(|&c| v[c].parse().expect("a number")).collect()
        })
        .collect()
}

/// The columns compared: the step, the mass, the impeller's fluid torque, the walls' torque,
/// the particles' mean height.
const COLUMNS: [&str; 5] = ["step", "mass", "torque_fluid", "torque_walls", "particle_mean_z"];

/// The largest differences between two series of [`COLUMNS`], after checking that they have
/// the same steps: mass relative to itself; the torques relative to the largest fluid torque
/// of the series; the mean height in lattice units.
fn differences(a: &[Vec<f64>], b: &[Vec<f64>]) -> [f64; 4] {
    assert_eq!(a.len(), b.len(), "as many rows");
    let scale = a.iter().map(|r| r[2].abs()).fold(0.0, f64::max);
    assert!(scale > 1.0, "the impeller turns the fluid: largest torque {scale}");
    let mut d = [0.0f64; 4];
    for (ra, rb) in a.iter().zip(b) {
        assert_eq!(ra[0], rb[0], "the same steps");
        d[0] = d[0].max((ra[1] - rb[1]).abs() / ra[1]);
        d[1] = d[1].max((ra[2] - rb[2]).abs() / scale);
        d[2] = d[2].max((ra[3] - rb[3]).abs() / scale);
        d[3] = d[3].max((ra[4] - rb[4]).abs());
    }
    d
}

/// Mass, relative: both runs sum f32 populations in f64; the populations differ by a few ulp
/// (2^-24 ≈ 6e-8 relative) at a few nodes near the markers, and the mass sums them over
/// 36³ nodes, so the total moves by far less than 1e-9 of itself (measured: 2e-11).
const MASS: f64 = 1e-9;
/// The impeller's torques, relative to the largest fluid torque of the run: the device's IBM
/// loads are f32 sums where the CPU's are f64 (one f32 rounding, 6e-8, per marker sum) and the
/// flow differs by round-off that grows over the steps (~1e-6 relative after a few dozen steps
/// in `tests/device_markers.rs`); over 100 steps 1e-5 leaves a factor of ten for that growth
/// while a load one step off (the torque changes by several per cent a step during the ramp)
/// or a missing interior term fails by orders of magnitude. Measured: at most 5e-7 (1.1e-6
/// after a state pack, where the rows from step 60 have a smaller largest torque).
const TORQUE: f64 = 1e-5;
/// The particles' mean height (lattice units, ~6.6): the particles move by ~1e-2 over 100
/// steps, so a relative velocity difference of 1e-5 moves them by ~1e-7; 1e-5 allows the
/// same growth as [`TORQUE`]. Measured: at most 3e-8 (positions 2e-7).
const MEAN_Z: f64 = 1e-5;

fn assert_close(what: &str, d: [f64; 4]) {
    println!(
        "{what}: mass {:.2e} (relative), torque_fluid {:.2e}, torque_walls {:.2e} (relative to the largest torque), \
         particle_mean_z {:.2e} (lattice units)",
        d[0], d[1], d[2], d[3]
    );
    assert!(d[0] <= MASS, "{what}: mass differs by {:.2e}", d[0]);
    assert!(d[1] <= TORQUE, "{what}: fluid torque differs by {:.2e}", d[1]);
    assert!(d[2] <= TORQUE, "{what}: walls' torque differs by {:.2e}", d[2]);
    assert!(d[3] <= MEAN_Z, "{what}: mean height differs by {:.2e}", d[3]);
}

#[test]
fn the_stirred_tank_runs_on_the_device_as_on_the_cpu() {
    let tmp = tempfile::tempdir().unwrap();
    let case = common::write_case(tmp.path(), "stirred.toml", &common::stirred_tank(&run_table(100), ""));
    let (cpu, dev) = (tmp.path().join("cpu"), tmp.path().join("dev"));
    for (dir, device) in [(&cpu, "cpu"), (&dev, "gpu")] {
        let start = std::time::Instant::now();
        let out = common::slurry(&[
            "run",
            case.to_str().unwrap(),
            "--out",
            dir.to_str().unwrap(),
            "--device",
            device,
            "--quiet",
        ]);
        assert!(out.status.success(), "slurry run --device {device}: {}", common::stderr(&out));
        println!("--device {device}: 100 steps in {:.1} s", start.elapsed().as_secs_f64());
    }
    let (a, b) = (series(&cpu, &COLUMNS), series(&dev, &COLUMNS));
    assert_eq!(a.len(), 6, "rows at 0, 20, …, 100");
    assert_close("device vs CPU, 100 steps", differences(&a, &b));
    // The particles moved and the impeller turned, so the comparison compared something.
    assert!((a[5][4] - a[0][4]).abs() > 1e-3, "the particles settle: {} to {}", a[0][4], a[5][4]);
    // The device run's output is a CPU run's: its summary names the device, its particle
    // history has the frames of the time series, its checkpoint holds the bodies.
    let summary = std::fs::read_to_string(dev.join("summary.json")).unwrap();
    assert!(summary.contains("\"isa\": \"device: "), "{summary}");
    let history = slurry::io::read_particle_history(&dev.join("particles.h5")).unwrap();
    let steps: Vec<u64> = history.frames.iter().map(|f| f.step).collect();
    assert_eq!(steps, vec![0, 20, 40, 60, 80, 100]);
    // Its last frame's positions are the CPU run's within the mean height's tolerance.
    let cpu_history = slurry::io::read_particle_history(&cpu.join("particles.h5")).unwrap();
    let (p, q) = (&history.frames[5].position, &cpu_history.frames[5].position);
    let dx = p.iter().zip(q).flat_map(|(a, b)| (0..3).map(move |k| (a[k] - b[k]).abs())).fold(0.0, f64::max);
    println!("device vs CPU, particle positions at step 100: max |diff| {dx:.2e}");
    assert!(dx <= MEAN_Z, "positions differ by {dx:.2e}");
    let checkpoint = slurry::io::read_checkpoint::<f32>(&dev.join("checkpoint.h5")).unwrap();
    assert_eq!(checkpoint.state.time, 100);
    assert_eq!(checkpoint.bodies.map(|b| b.len()), Some(27), "26 particles and the impeller");
}

/// Runs the stirred tank on `device` to `steps` in `dir`, resuming its checkpoint when `resume`.
fn run_to(dir: &Path, steps: u64, device: &str, resume: bool) {
    let mut case =
        Case::parse(&common::stirred_tank(&run_table(steps), ""), "stirred.toml").expect("valid case");
    case.run.device = if device == "gpu" { slurry::case::Device::Gpu } else { slurry::case::Device::Cpu };
    let opts = RunOptions { quiet: true, resume, ..RunOptions::default() };
    run_case(&case, dir, opts).unwrap_or_else(|e| panic!("run on {device} to {steps}: {e:#}"));
}

#[test]
fn a_device_checkpoint_resumes_on_the_device_and_on_the_cpu() {
    let tmp = tempfile::tempdir().unwrap();
    let dir = |n: &str| tmp.path().join(n);
    // 50 steps on the device, checkpoint at 50; a copy continues on the CPU, the run itself on the device.
    run_to(&dir("dev"), 50, "gpu", false);
    for copy in ["cpu"] {
        std::fs::create_dir_all(dir(copy)).unwrap();
        for f in ["checkpoint.h5", "timeseries.csv", "particles.h5"] {
            std::fs::copy(dir("dev").join(f), dir(copy).join(f)).unwrap();
        }
    }
    run_to(&dir("dev"), 100, "gpu", true);
    run_to(&dir("cpu"), 100, "cpu", true);
    // The uninterrupted runs, on the device and on the CPU.
    run_to(&dir("dev-whole"), 100, "gpu", false);
    run_to(&dir("cpu-whole"), 100, "cpu", false);
    // The rows every 20 steps (a run to 50 ends with a row of its last step, which the
    // uninterrupted runs do not have).
    let get = |n: &str| {
        let mut s = series(&dir(n), &COLUMNS);
        s.retain(|r| r[0] % 20.0 == 0.0);
        assert_eq!(s.len(), 6, "{n}: rows at 0, 20, …, 100");
        s
    };
    // A device run continued on the device is the uninterrupted device run, bit for bit.
    assert_eq!(get("dev"), get("dev-whole"), "resumed on the device vs uninterrupted");
    // Continued on the CPU, it stays within round-off of both uninterrupted runs.
    assert_close(
        "device to 50, CPU to 100 vs the device throughout",
        differences(&get("cpu"), &get("dev-whole")),
    );
    assert_close(
        "device to 50, CPU to 100 vs the CPU throughout",
        differences(&get("cpu"), &get("cpu-whole")),
    );
    // A CPU checkpoint resumes on the device too.
    run_to(&dir("cpu50"), 50, "cpu", false);
    run_to(&dir("cpu50"), 100, "gpu", true);
    assert_close(
        "CPU to 50, device to 100 vs the CPU throughout",
        differences(&get("cpu50"), &get("cpu-whole")),
    );
}

#[test]
fn a_state_pack_starts_a_device_run_as_it_starts_a_cpu_run() {
    let tmp = tempfile::tempdir().unwrap();
    let dir = |n: &str| tmp.path().join(n);
    run_to(&dir("cpu50"), 50, "cpu", false);
    let pack = dir("stirred.pack.h5");
    let step = slurry::run::write_run_state_pack(&dir("cpu50"), &pack, "test").expect("a state pack");
    assert_eq!(step, 50);
    let mut series_of = Vec::new();
    for device in ["cpu", "gpu"] {
        let mut case = Case::parse(&common::stirred_tank(&run_table(100), ""), "stirred.toml").unwrap();
        case.run.device = if device == "gpu" { slurry::case::Device::Gpu } else { slurry::case::Device::Cpu };
        let out = dir(&format!("pack-{device}"));
        let opts = RunOptions { quiet: true, ..RunOptions::default() };
        slurry::run::run_case_from_pack(&case, &out, opts, &pack)
            .unwrap_or_else(|e| panic!("{device} from the pack: {e:#}"));
        let s = series(&out, &COLUMNS);
        let steps: Vec<f64> = s.iter().map(|r| r[0]).collect();
        // The packed run's rows (its output steps and the checkpoint's), then this run's.
        assert_eq!(steps, vec![0.0, 20.0, 40.0, 50.0, 60.0, 80.0, 100.0], "{device}: one series");
        series_of.push(s.into_iter().filter(|r| r[0] > 50.0).collect::<Vec<_>>());
    }
    assert_close("from a pack at 50, device vs CPU to 100", differences(&series_of[0], &series_of[1]));
}
