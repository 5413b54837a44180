//! The reproduction pipeline on the device (`slurry reproduce CASE --device gpu`): pbt-ld2 at
//! s = 1/4 continued from its committed steady state pack for [`REVOLUTIONS`] revolutions on
//! the device and on the CPU, through the whole pipeline (start, run, statistics, report,
//! manifest).
//!
//! **What is asserted, and why.**
//! - The manifest's session says `"gpu"` for the device run and `"cpu"` for the other, and the
//!   device run's report names the adapter: a reader of an archived run can tell where it ran.
//! - The reported ⟨z_p⟩/H (last and window mean) and the impeller's fluid torque, Po_f, agree
//!   with the CPU's within [`TOL`] relative. The device computes in f32 as `Coupled<f32>` does,
//!   but sums in another order (marker forces through fixed-point spreading, loads by chunks),
//!   so the two differ in the last bits of each step's loads (1.6e-6 of |F| over 30 steps,
//!   `tests/device_markers.rs`); over these 200 steps of a dense suspension with contacts the
//!   reported values differed by 3.2e-9 (⟨z_p⟩/H) and 1.0e-7 (Po_f) relative on lavapipe
//!   (printed by the test). 1e-5 leaves two orders of margin for other devices and drivers
//!   while still catching any error of the device path in a load or a body update (which moves
//!   Po_f by its whole forcing share, percents, within a few steps).
//!
//! Runs on the Vulkan adapter the machine has (Mesa's lavapipe in CI, `cargo xtask setup`):
//! about 200 steps each way. Without one it fails, with the device's error.

use std::path::Path;

use slurry_reproduce::reproduce;

#[path = "../../tests/common/mod.rs"]
mod common;
mod packs;

/// Revolutions run from the pack on each processor.
const REVOLUTIONS: f64 = 0.2;
/// Relative tolerance between the device's and the CPU's reported values (module docs).
const TOL: f64 = 1e-5;
const CASE: &str = "pbt-ld2";
const SCALE: f64 = 0.25;
const PACK: &str = "2026-12-07-s0.25-steady";

fn run(out: &Path, gpu: bool) -> (slurry_reproduce::report::Results, String) {
    let c = packs::continuation(CASE, PACK, SCALE, REVOLUTIONS, out, 0.4, gpu);
    let s = reproduce(CASE, &c.options)
        .unwrap_or_else(|e| panic!("{CASE} (gpu {gpu}) from {}: {e:#}", c.pack.display()));
    match &s.results.start {
        slurry_reproduce::start::RunStart::StatePack(from) => {
            assert_eq!(from.step, c.step, "the pack's step")
        }
        other => panic!("started from {other:?}, not the pack"),
    }
    let manifest: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(out.join("manifest.json")).unwrap()).unwrap();
    let device = manifest["sessions"].as_array().and_then(|s| s.last()).and_then(|s| s["device"].as_str());
    assert_eq!(device, Some(if gpu { "gpu" } else { "cpu" }), "the manifest's session, gpu {gpu}");
    let report = std::fs::read_to_string(out.join("report.md")).unwrap();
    (s.results, report)
}

#[test]
fn the_reproduction_runs_on_the_device_as_on_the_cpu() {
    let dir = tempfile::tempdir().unwrap();
    let (cpu, cpu_report) = run(&dir.path().join("cpu"), false);
    let (gpu, gpu_report) = run(&dir.path().join("gpu"), true);
    assert!(
        cpu_report.contains(" threads;") && !cpu_report.contains("on the device"),
        "the CPU run's report"
    );
    assert!(gpu_report.contains("on the device "), "the device run's report names the adapter");
    for (name, c, g) in [
        ("<z_p>/H (last)", cpu.mean_height_final, gpu.mean_height_final),
        ("<z_p>/H (window)", cpu.mean_height, gpu.mean_height),
        ("Po_f", cpu.po_fluid, gpu.po_fluid),
    ] {
        let rel = (g - c).abs() / c.abs();
        println!("{name}: CPU {c:.9}, device {g:.9}, relative difference {rel:.2e} (tolerance {TOL:.0e})");
        assert!(rel <= TOL, "{name}: CPU {c}, device {g}, relative difference {rel:.2e} above {TOL:.0e}");
    }
}
