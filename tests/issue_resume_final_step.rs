//! Issue 15, defect 1: `slurry run --resume` on a particle run whose last checkpoint is its
//! final step rewrote `fields.h5` with a wrong velocity (6498 of 55296 components off by up to
//! 1.6e-4). The velocity's half-force term `u = (j + F/2)/ρ` needs the last step's IBM force
//! field, which the checkpoint did not hold and the restore zeroed; with no step after the
//! restore nothing rebuilt it.
//!
//! Expected: every output of a resumed run is a function of the checkpoint alone, bitwise
//! equal to the uninterrupted run's — resumed at the final step, at an output step and at a
//! checkpoint step that is not an output step: `fields.h5`, `particles.h5`, the time series
//! (physics columns), the final checkpoint (populations and force field) and the summary's
//! final momentum and largest Mach number.

use std::path::Path;
use std::process::Command;

mod common;

use common::{bin, case_toml, write_case};

/// A free sphere falling onto the floor (contacts on) and a free cylinder, f32, TRT.
fn case(steps: u64, checkpoint_every: u64) -> String {
    let run = format!("steps = {steps}\noutput_every = 40\ncheckpoint_every = {checkpoint_every}");
    let closed_box = case_toml([16, 16, 24], "precision = \"f32\"\nnu = 0.05\ncollision = \"trt\"", "", &run);
    format!(
        r#"
gravity = [0.0, 0.0, -2e-4]
{closed_box}
[contacts]

[[particles]]
shape = "cylinder"
diameter = 4.0
length = 8.0
density = 1.5
position = [7.7, 8.2, 15.0]
axis = [1.0, 0.3, 0.8]

[[particles]]
shape = "sphere"
diameter = 4.0
density = 1.5
position = [8.0, 7.0, 3.0]
"#
    )
}

fn run(case: &Path, out: &Path, resume: bool) {
    let mut c = Command::new(bin());
    c.arg("run").arg(case).arg("--out").arg(out).arg("--quiet").arg("--threads").arg("1");
    if resume {
        c.arg("--resume");
    }
    let o = c.output().unwrap();
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
}

fn bits(path: &Path, name: &str) -> Vec<u64> {
    let f = hdf5::File::open(path).unwrap();
    let d = f.dataset(name).unwrap_or_else(|_| panic!("{}: no /{name}", path.display()));
    match d.dtype().unwrap().size() {
        4 => d.read_raw::<f32>().unwrap().iter().map(|v| u64::from(v.to_bits())).collect(),
        _ => d.read_raw::<f64>().unwrap().iter().map(|v| v.to_bits()).collect(),
    }
}

/// The time series without its timing column (`mlups`, the last one).
fn physics_rows(path: &Path) -> Vec<String> {
    std::fs::read_to_string(path)
        .unwrap()
        .lines()
        .map(|l| l.rsplit_once(',').map_or(l, |(a, _)| a).to_string())
        .collect()
}

fn summary(dir: &Path) -> serde_json::Value {
    serde_json::from_str(&std::fs::read_to_string(dir.join("summary.json")).unwrap()).unwrap()
}

fn assert_same_outputs(a: &Path, b: &Path, what: &str) {
    for name in ["density", "velocity"] {
        let (x, y) = (bits(&a.join("fields.h5"), name), bits(&b.join("fields.h5"), name));
        let differ = x.iter().zip(&y).filter(|(p, q)| p != q).count();
        assert!(x.len() == y.len() && differ == 0, "{what}: fields.h5 /{name}: {differ} values differ");
    }
    for name in ["position", "quaternion", "velocity", "angular_velocity", "force", "torque", "time"] {
        assert_eq!(
            bits(&a.join("particles.h5"), name),
            bits(&b.join("particles.h5"), name),
            "{what}: particles.h5 /{name} differs"
        );
    }
    for name in ["populations", "force", "bodies"] {
        assert_eq!(
            bits(&a.join("checkpoint.h5"), name),
            bits(&b.join("checkpoint.h5"), name),
            "{what}: checkpoint.h5 /{name} differs"
        );
    }
    assert_eq!(
        physics_rows(&a.join("timeseries.csv")),
        physics_rows(&b.join("timeseries.csv")),
        "{what}: time series differs"
    );
    let (sa, sb) = (summary(a), summary(b));
    for key in ["final_momentum", "max_mach", "final_mass", "steps"] {
        assert_eq!(sa[key], sb[key], "{what}: summary.json {key} differs");
    }
}

#[test]
fn resume_at_final_output_and_checkpoint_steps_is_bitwise_exact() {
    let tmp = tempfile::tempdir().unwrap();
    let full = write_case(tmp.path(), "full.toml", &case(200, 100));
    let a = tmp.path().join("a");
    run(&full, &a, false);

    // 1. At the final step: a copy of the finished run, resumed (no step follows).
    let b = tmp.path().join("b");
    std::fs::create_dir_all(&b).unwrap();
    for e in std::fs::read_dir(&a).unwrap() {
        let e = e.unwrap();
        std::fs::copy(e.path(), b.join(e.file_name())).unwrap();
    }
    run(&full, &b, true);
    assert_same_outputs(&a, &b, "resumed at the final step");

    // 2. At an output step (120, also a checkpoint): a run of 120 steps extended to 200.
    let c = tmp.path().join("c");
    run(&write_case(tmp.path(), "c.toml", &case(120, 60)), &c, false);
    run(&full, &c, true);
    assert_same_outputs(&a, &c, "resumed at output step 120");

    // 3. At a checkpoint that is not an output step (100; output every 40), the run having
    // gone on to 140 before it stopped: rows and frames after 100 are cut and recomputed.
    let d = tmp.path().join("d");
    run(&write_case(tmp.path(), "d.toml", &case(140, 50)), &d, false);
    run(&full, &d, true);
    assert_same_outputs(&a, &d, "resumed at checkpoint step 100");
}
