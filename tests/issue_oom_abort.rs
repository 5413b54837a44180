//! Issue 15, defect 2: cases too large for the machine aborted with `memory allocation of N
//! bytes failed` (SIGABRT) instead of an error: a 600³ and a 1500³ f64 grid (both accepted by
//! `slurry check`), `[[random_particles]] count = 100000000000` (`Vec::with_capacity(count)`
//! in the placement, in `check` too), and `volume_fraction = 0.1` of `diameter = 0.001`.
//!
//! Expected: `check` and `run` estimate the memory a case needs (populations, force field,
//! markers, particles, output) and refuse, with exit status 2 and a message naming the
//! estimate and the limit, before allocating anything large; particle counts are bounded by
//! what can be placed, particle sizes by what the IBM resolves. The estimate is tested
//! against its formula, and the refusals do not depend on the machine's memory (a 1500³ f64
//! grid needs about 515 GB; the others are refused whatever the memory).

use std::process::{Command, Output};

use slurry::case::memory::{MemoryEstimate, BYTES_PER_MARKER, BYTES_PER_PARTICLE};
use slurry::case::Case;

mod common;

use common::{bin, case_toml};

/// A channel (periodic x and y) of `nx × ny × nz` nodes, with `extra` appended.
fn case(nx: usize, ny: usize, nz: usize, precision: &str, extra: &str) -> String {
    let fluid = format!("precision = \"{precision}\"\nnu = 0.1");
    format!("{}{extra}\n", case_toml([nx, ny, nz], &fluid, "xy", "steps = 10\noutput_every = 5"))
}

fn check(text: &str, limit: Option<&str>) -> (Output, String, String) {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("case.toml");
    std::fs::write(&path, text).unwrap();
    let mut c = Command::new(bin());
    c.arg("check").arg(&path);
    match limit {
        Some(l) => c.env("SLURRY_MEMORY_LIMIT", l),
        None => c.env_remove("SLURRY_MEMORY_LIMIT"),
    };
    let out = c.output().unwrap();
    let stderr = String::from_utf8_lossy(&out.stderr).to_string();
    (out, stderr, path.display().to_string())
}

fn assert_refused(out: &Output, stderr: &str, path: &str, needles: &[&str]) {
    assert_eq!(out.status.code(), Some(2), "exit status (a signal is None): {stderr}");
    assert!(!stderr.contains("memory allocation") && !stderr.contains("panicked"), "{stderr}");
    assert!(stderr.contains(path), "the file is not named: {stderr}");
    for n in needles {
        assert!(stderr.contains(n), "`{n}` missing: {stderr}");
    }
}

#[test]
fn estimate_follows_its_formula() {
    // Fluid alone, f64, no checkpoint: populations, masks, final fields.
    let c = Case::parse_unchecked(&case(10, 20, 30, "f64", "")).unwrap();
    let (n, p): (f64, f64) = (10.0 * 20.0 * 30.0, 12.0 * 22.0 * 32.0);
    let e = MemoryEstimate::of(&c);
    assert_eq!(e.populations, (19.0 * 8.0 * p) as u64);
    assert_eq!(e.force, 0);
    assert_eq!(e.grid_other, (p + n) as u64);
    assert_eq!(e.output, (32.0 * n) as u64);
    assert_eq!(e.total(), (19.0 * 8.0 * p + p + n + 32.0 * n) as u64);

    // f32 with a checkpoint and 3 spheres of d = 4 (marker spacing 0.5): force field, the
    // coupling's velocity buffer and stored momenta, markers, particles, the checkpoint's copy.
    let extra = "checkpoint_every = 10\n\n[ibm]\nmarker_spacing = 0.5\n\n[[random_particles]]\nshape = \"sphere\"\ndiameter = 4.0\ndensity = 1.5\ncount = 3\nseed = 1\n";
    let c = Case::parse_unchecked(&case(10, 20, 30, "f32", extra)).unwrap();
    let e = MemoryEstimate::of(&c);
    let markers = 3.0 * (std::f64::consts::PI * 16.0 / 0.25 + 1.0);
    assert_eq!(e.populations, (19.0 * 4.0 * p) as u64);
    assert_eq!(e.force, (3.0 * 4.0 * p) as u64);
    assert_eq!(e.grid_other, (p + n + 48.0 * n) as u64);
    assert!((e.marker_count - markers).abs() < 1e-9, "{}", e.marker_count);
    assert_eq!(e.markers, (BYTES_PER_MARKER as f64 * markers) as u64);
    assert_eq!(e.particles, 3 * BYTES_PER_PARTICLE);
    assert_eq!(e.output, (22.0 * 4.0 * n).max(32.0 * n) as u64);

    // No overflow for absurd sizes.
    let c = Case::parse_unchecked(&case(1500, 1500, 1500, "f64", "")).unwrap();
    assert!(MemoryEstimate::of(&c).total() > 500_000_000_000);
}

#[test]
fn grid_1500_cubed_f64_is_refused_naming_estimate_and_limit() {
    let (out, stderr, path) = check(&case(1500, 1500, 1500, "f64", ""), None);
    assert_refused(&out, &stderr, &path, &["domain", "needs about", "available"]);
}

#[test]
fn grid_600_cubed_f64_is_refused_under_a_limit() {
    let (out, stderr, path) = check(&case(600, 600, 600, "f64", ""), Some("16G"));
    assert_refused(
        &out,
        &stderr,
        &path,
        &["domain", "needs about", "16.000 GiB available", "SLURRY_MEMORY_LIMIT"],
    );
    // The same grid in a limit that holds it passes the memory check.
    let (out, stderr, _) = check(&case(60, 60, 60, "f64", ""), Some("16G"));
    assert_eq!(out.status.code(), Some(0), "{stderr}");
}

#[test]
fn huge_random_count_is_refused_before_placement() {
    let extra = "\n[[random_particles]]\nshape = \"sphere\"\ndiameter = 2.0\ndensity = 1.5\ncount = 100000000000\nseed = 1\n";
    let (out, stderr, path) = check(&case(16, 16, 16, "f32", extra), None);
    assert_refused(&out, &stderr, &path, &["random_particles[0].count", "can be filled"]);
}

#[test]
fn tiny_particles_by_volume_fraction_are_refused() {
    let extra = "\n[[random_particles]]\nshape = \"sphere\"\ndiameter = 0.001\ndensity = 1.5\nvolume_fraction = 0.1\nseed = 1\n";
    let (out, stderr, path) = check(&case(16, 16, 16, "f32", extra), None);
    assert_refused(&out, &stderr, &path, &["random_particles[0].diameter", ">= 1"]);
}

#[test]
fn particles_whose_markers_do_not_fit_are_refused_naming_the_population() {
    let extra = "\n[[random_particles]]\nshape = \"sphere\"\ndiameter = 1.0\ndensity = 1.5\nvolume_fraction = 0.3\nseed = 1\n";
    let (out, stderr, path) = check(&case(400, 400, 400, "f32", extra), Some("8G"));
    assert_refused(&out, &stderr, &path, &["random_particles[0].volume_fraction", "markers", "needs about"]);
}

#[test]
fn run_refuses_too_large_a_grid_before_allocating() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("case.toml");
    std::fs::write(&path, case(600, 600, 600, "f64", "")).unwrap();
    let out = Command::new(bin())
        .arg("run")
        .arg(&path)
        .arg("--out")
        .arg(dir.path().join("out"))
        .arg("--quiet")
        .env("SLURRY_MEMORY_LIMIT", "1G")
        .output()
        .unwrap();
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert_eq!(out.status.code(), Some(2), "{stderr}");
    assert!(stderr.contains("needs about") && stderr.contains("domain"), "{stderr}");
}
