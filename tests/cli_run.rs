//! The `slurry` binary end to end: `run` writes readable output; bad input and numerical
//! trouble give the documented exit codes and messages.

use std::path::Path;

mod common;

use common::{assert_no_temp_files, case_toml, slurry, stderr};

#[test]
fn poiseuille_runs_and_writes_readable_output() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("out");
    let o = slurry(&[
        "run",
        "examples/poiseuille.toml",
        "--out",
        out.to_str().unwrap(),
        "--quiet",
        "--threads",
        "2",
    ]);
    assert!(o.status.success(), "status {:?}: {}", o.status, stderr(&o));

    // Fields: HDF5 with the documented shapes, finite values, a channel profile.
    let f = hdf5::File::open(out.join("fields.h5")).unwrap();
    let v = f.dataset("velocity").unwrap();
    assert_eq!(v.shape(), vec![32, 4, 4, 3]);
    let u: Vec<f64> = v.read_raw().unwrap();
    assert!(u.iter().all(|x| x.is_finite()));
    let ux = |z: usize| u[z * 4 * 4 * 3];
    assert!(ux(16) > 0.009 && ux(16) < 0.0101, "centre-line speed {}", ux(16));
    assert!(ux(0) < ux(8) && ux(8) < ux(16), "not a channel profile");
    let d = f.dataset("density").unwrap();
    assert_eq!(d.shape(), vec![32, 4, 4]);
    let step: u64 = f.attr("time_step").unwrap().read_scalar().unwrap();
    assert_eq!(step, 10000);

    // XDMF beside it, naming the datasets.
    let xmf = std::fs::read_to_string(out.join("fields.xmf")).unwrap();
    assert!(xmf.contains("fields.h5:/density"));
    assert!(xmf.contains("fields.h5:/velocity"));
    assert!(xmf.contains(r#"Dimensions="32 4 4""#));

    // Time series: header plus one row per output step (0, 1000, ..., 10000).
    let csv = std::fs::read_to_string(out.join("timeseries.csv")).unwrap();
    let lines: Vec<&str> = csv.lines().collect();
    assert!(lines[0].starts_with("step,time,mass,"), "{}", lines[0]);
    assert_eq!(lines.len(), 1 + 11);
    for (i, l) in lines[1..].iter().enumerate() {
        let cols: Vec<&str> = l.split(',').collect();
        assert_eq!(cols.len(), 8, "{l}");
        assert_eq!(cols[0].parse::<u64>().unwrap(), 1000 * i as u64);
        let mass: f64 = cols[2].parse().unwrap();
        assert!((mass - 512.0).abs() < 1e-9, "{l}");
    }

    // Summary and the case as run.
    let s: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(out.join("summary.json")).unwrap()).unwrap();
    assert_eq!(s["steps"], 10000);
    assert!(s["mlups"].as_f64().unwrap() > 0.0);
    assert!(out.join("case.toml").exists());
    assert_no_temp_files(&out);
}

#[test]
fn bad_case_exits_2_naming_the_key() {
    let dir = tempfile::tempdir().unwrap();
    let case = dir.path().join("bad.toml");
    let text =
        std::fs::read_to_string(Path::new(env!("CARGO_MANIFEST_DIR")).join("examples/poiseuille.toml"))
            .unwrap()
            .replace("\nnu = 0.1\n", "\nnu = 0.1\nviscosity = 0.1\n");
    std::fs::write(&case, text).unwrap();
    let out = dir.path().join("out");
    let o = slurry(&["run", case.to_str().unwrap(), "--out", out.to_str().unwrap(), "--quiet"]);
    assert_eq!(o.status.code(), Some(2), "{}", stderr(&o));
    let msg = stderr(&o);
    assert!(msg.starts_with("error: "), "{msg}");
    assert!(msg.contains("bad.toml"), "{msg}");
    assert!(msg.contains("fluid.viscosity"), "{msg}");
    assert!(!out.exists(), "output written for a bad case");

    let o = slurry(&["check", case.to_str().unwrap()]);
    assert_eq!(o.status.code(), Some(2), "{}", stderr(&o));
}

#[test]
fn check_accepts_an_example() {
    let o = slurry(&["check", "examples/lid_cavity.toml"]);
    assert!(o.status.success(), "{}", stderr(&o));
    let text = String::from_utf8_lossy(&o.stdout);
    assert!(text.contains("32 x 32 x 32"), "{text}");
}

#[test]
fn runaway_flow_exits_1_with_a_diagnosis() {
    // A strong body force in a periodic box accelerates the fluid without bound:
    // u = g t reaches Mach 0.3 (u = 0.173) after about 173 steps.
    let dir = tempfile::tempdir().unwrap();
    let case = dir.path().join("runaway.toml");
    let text = case_toml(
        [4, 4, 4],
        "nu = 0.1\nbody_force = [1e-3, 0.0, 0.0]",
        "xyz",
        "steps = 1000\noutput_every = 50",
    );
    std::fs::write(&case, text).unwrap();
    let out = dir.path().join("out");
    let o = slurry(&["run", case.to_str().unwrap(), "--out", out.to_str().unwrap(), "--quiet"]);
    assert_eq!(o.status.code(), Some(1), "{}", stderr(&o));
    let msg = stderr(&o);
    assert!(msg.contains("numerical trouble at step 200"), "{msg}");
    assert!(msg.contains("exceeds the limit 0.300"), "{msg}");
    let csv = std::fs::read_to_string(out.join("timeseries.csv")).unwrap();
    assert_eq!(csv.lines().count(), 1 + 4, "{csv}"); // steps 0, 50, 100, 150
}

#[test]
fn unusable_output_directory_exits_2() {
    let dir = tempfile::tempdir().unwrap();
    let file = dir.path().join("a_file");
    std::fs::write(&file, "x").unwrap();
    let out = file.join("out");
    let o = slurry(&["run", "examples/couette.toml", "--out", out.to_str().unwrap(), "--quiet"]);
    assert_eq!(o.status.code(), Some(2), "{}", stderr(&o));
    assert!(stderr(&o).contains("--out"), "{}", stderr(&o));
}

#[test]
fn zero_threads_is_a_usage_error() {
    let o = slurry(&["run", "examples/poiseuille.toml", "--out", "/tmp/unused", "--threads", "0"]);
    assert_eq!(o.status.code(), Some(2), "{}", stderr(&o));
}

/// A fixed sphere in a force-driven periodic channel and a prescribed sphere moving through
/// it: 20 steps, output every 10.
fn spheres() -> String {
    let channel = case_toml(
        [16, 16, 24],
        "nu = 0.1\nbody_force = [1e-5, 0.0, 0.0]",
        "xy",
        "steps = 20\noutput_every = 10",
    );
    format!(
        r#"{channel}
[[particles]]
shape = "sphere"
diameter = 6.0
density = 1.0
position = [4.0, 8.0, 8.0]
motion = "fixed"

[[particles]]
shape = "sphere"
diameter = 4.0
density = 1.5
position = [12.0, 8.0, 16.0]
velocity = [0.01, 0.0, 0.0]
motion = "prescribed"
"#
    )
}

#[test]
fn particles_write_a_readable_history() {
    let dir = tempfile::tempdir().unwrap();
    let case = dir.path().join("spheres.toml");
    std::fs::write(&case, spheres()).unwrap();
    let out = dir.path().join("out");
    let o =
        slurry(&["run", case.to_str().unwrap(), "--out", out.to_str().unwrap(), "--quiet", "--threads", "2"]);
    assert!(o.status.success(), "status {:?}: {}", o.status, stderr(&o));

    let f = hdf5::File::open(out.join("particles.h5")).unwrap();
    for (name, k) in [
        ("position", 3),
        ("quaternion", 4),
        ("velocity", 3),
        ("angular_velocity", 3),
        ("force", 3),
        ("torque", 3),
    ] {
        assert_eq!(f.dataset(name).unwrap().shape(), vec![3, 2, k], "{name}");
    }
    assert_eq!(f.dataset("step").unwrap().read_raw::<u64>().unwrap(), vec![0, 10, 20]);
    assert_eq!(f.dataset("time").unwrap().read_raw::<f64>().unwrap(), vec![0.0, 10.0, 20.0]);
    for name in ["shape", "diameter", "length", "density", "volume", "mass", "motion"] {
        assert_eq!(f.dataset(name).unwrap().shape(), vec![2], "{name}");
    }
    let motion: Vec<hdf5::types::VarLenUnicode> = f.dataset("motion").unwrap().read_raw().unwrap();
    assert_eq!([motion[0].as_str(), motion[1].as_str()], ["fixed", "prescribed"]);
    assert_eq!(f.dataset("diameter").unwrap().read_raw::<f64>().unwrap(), vec![6.0, 4.0]);
    let units: hdf5::types::VarLenUnicode = f.attr("units").unwrap().read_scalar().unwrap();
    assert_eq!(units.as_str(), "lattice: Δ, Δt, ρ_f");

    // The prescribed sphere has moved 20 × 0.01 along x; the fixed one has not.
    let pos: Vec<f64> = f.dataset("position").unwrap().read_raw().unwrap();
    let at = |frame: usize, p: usize, k: usize| pos[(frame * 2 + p) * 3 + k];
    assert_eq!([at(2, 0, 0), at(2, 0, 1), at(2, 0, 2)], [4.0, 8.0, 8.0]);
    assert!((at(2, 1, 0) - 12.2).abs() < 1e-12, "{}", at(2, 1, 0));
    let q: Vec<f64> = f.dataset("quaternion").unwrap().read_raw().unwrap();
    assert_eq!(&q[..4], &[1.0, 0.0, 0.0, 0.0]);
    // The flow drags the fixed sphere along +x; zero force at step 0.
    let force: Vec<f64> = f.dataset("force").unwrap().read_raw().unwrap();
    assert!(force.iter().all(|x| x.is_finite()));
    assert!(force[..6].iter().all(|&x| x == 0.0));
    assert!(force[2 * 6] > 0.0, "drag on the fixed sphere {}", force[2 * 6]);

    // The time series has the particle columns before mlups.
    let csv = std::fs::read_to_string(out.join("timeseries.csv")).unwrap();
    let lines: Vec<&str> = csv.lines().collect();
    assert!(lines[0].ends_with(",max_mach,particle_mean_z,particle_max_speed,mlups"), "{}", lines[0]);
    assert_eq!(lines.len(), 4);
    let cols: Vec<&str> = lines[1].split(',').collect();
    assert_eq!(cols[7].parse::<f64>().unwrap(), 12.0);
    assert_eq!(cols[8].parse::<f64>().unwrap(), 0.01);

    let s: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(out.join("summary.json")).unwrap()).unwrap();
    assert_eq!(s["particles"], 2);
    assert!(s["markers"].as_u64().unwrap() > 100);
    let as_run = std::fs::read_to_string(out.join("case.toml")).unwrap();
    assert!(as_run.contains("[[particles]]") && as_run.contains("[ibm]"), "{as_run}");
    assert_no_temp_files(&out);

    // This run wrote no checkpoint: a resume says so (particle resumes themselves are tested
    // in tests/checkpoint_resume.rs).
    let o = slurry(&["run", case.to_str().unwrap(), "--out", out.to_str().unwrap(), "--quiet", "--resume"]);
    assert!(!o.status.success());
    assert!(stderr(&o).contains("checkpoint"), "{}", stderr(&o));
}

/// Three random spheres in a closed box, with contacts; the `[[random_particles]]` come last.
fn settle_case() -> String {
    let closed_box = case_toml(
        [14, 14, 18],
        "precision = \"f32\"\nnu = 0.1\ncollision = \"bgk\"",
        "",
        "steps = 10\noutput_every = 10",
    );
    format!(
        r#"
gravity = [0.0, 0.0, -2e-3]
{closed_box}
[contacts]

[[random_particles]]
shape = "sphere"
diameter = 4.0
density = 1.25
count = 3
seed = 7
"#
    )
}

/// `slurry settle`: three random spheres settle on the floor (mean speed below the threshold,
/// centres within a diameter of the floor); the bed is written, is the same on a second run
/// (bit for bit), and its `[[particles]]` form a valid case in place of the random population.
#[test]
fn settle_writes_a_reusable_bed() {
    let dir = tempfile::tempdir().unwrap();
    let case = dir.path().join("settle.toml");
    let settle_case = settle_case();
    std::fs::write(&case, &settle_case).unwrap();
    let args = |out: &std::path::Path| {
        let mut v: Vec<String> =
            ["settle", case.to_str().unwrap(), "--out", out.to_str().unwrap(), "--quiet"]
                .iter()
                .map(|s| s.to_string())
                .collect();
        v.extend(
            ["--speed", "2e-4", "--min-steps", "400", "--check-every", "100", "--max-steps", "30000"]
                .map(String::from),
        );
        v
    };
    let (a, b) = (dir.path().join("a"), dir.path().join("b"));
    for out in [&a, &b] {
        let v = args(out);
        let o = slurry(&v.iter().map(String::as_str).collect::<Vec<_>>());
        assert!(o.status.success(), "{}", stderr(&o));
        assert!(stderr(&o).starts_with("settled:"), "{}", stderr(&o));
    }
    let pos = |d: &std::path::Path| {
        hdf5::File::open(d.join("bed.h5")).unwrap().dataset("position").unwrap().read_raw::<f64>().unwrap()
    };
    let (pa, pb) = (pos(&a), pos(&b));
    assert_eq!(pa.len(), 9);
    assert!(pa.iter().zip(&pb).all(|(x, y)| x.to_bits() == y.to_bits()), "the bed is not reproducible");
    for k in 0..3 {
        assert!(pa[3 * k + 2] < 2.0 + 4.0, "sphere {k} did not reach the floor: z = {}", pa[3 * k + 2]);
    }
    let bed = std::fs::read_to_string(a.join("bed_particles.toml")).unwrap();
    // The case without its random population (its [run] included), with the bed instead.
    let head = settle_case.split("[[random_particles]]").next().unwrap();
    let stirred = dir.path().join("stirred.toml");
    std::fs::write(&stirred, format!("{head}\n{bed}")).unwrap();
    let o = slurry(&["check", stirred.to_str().unwrap()]);
    assert!(o.status.success(), "{}", stderr(&o));

    // The reproduction's `--bed wet` settles through the same code: with the same stopping
    // rule it gives this bed bit for bit, and says it settled.
    let c = slurry::case::Case::parse(&settle_case, &case).unwrap();
    let opts = slurry::settle::SettleOptions {
        speed: 2e-4,
        check_every: 100,
        min_steps: 400,
        max_steps: 30000,
        quiet: true,
        checkpoint_every_s: 0.0,
    };
    let wet = slurry::settle::wet_bed(&c, opts, None).unwrap();
    assert!(wet.settled && wet.mean_speed < 2e-4, "{wet:?}");
    let wet_pos: Vec<f64> = wet.particles.iter().flat_map(|p| p.position).collect();
    assert!(
        wet_pos.iter().zip(&pa).all(|(x, y)| x.to_bits() == y.to_bits()),
        "wet_bed {wet_pos:?} differs from slurry settle's bed {pa:?}"
    );
}

/// A settling stopped by its step limit keeps its checkpoint (exit 1, "NOT settled"); run
/// again with a larger limit it resumes there, says so, and writes the bed of an
/// uninterrupted settling bit for bit, then removes the checkpoint. A checkpoint written for
/// another stopping rule is refused, naming the file.
#[test]
fn settle_resumes_from_its_checkpoint() {
    let dir = tempfile::tempdir().unwrap();
    let case = dir.path().join("settle.toml");
    std::fs::write(&case, settle_case()).unwrap();
    let settle = |out: &std::path::Path, max_steps: &str, speed: &str| {
        slurry(&[
            "settle",
            case.to_str().unwrap(),
            "--out",
            out.to_str().unwrap(),
            "--speed",
            speed,
            "--min-steps",
            "400",
            "--check-every",
            "100",
            "--max-steps",
            max_steps,
        ])
    };
    let (whole, parts) = (dir.path().join("whole"), dir.path().join("parts"));
    let o = settle(&whole, "30000", "2e-4");
    assert!(o.status.success(), "{}", stderr(&o));
    assert!(!whole.join("settling.h5").exists(), "a settled bed leaves no checkpoint");

    let o = settle(&parts, "600", "2e-4");
    assert!(!o.status.success() && stderr(&o).contains("NOT settled"), "{}", stderr(&o));
    assert!(parts.join("settling.h5").is_file());
    let record = std::fs::read_to_string(parts.join("settling.json")).unwrap();
    assert!(record.contains("\"step\":600") && record.contains("\"restarts\":0"), "{record}");
    // Another stopping rule: refused, the checkpoint kept.
    let o = settle(&parts, "30000", "1e-4");
    assert!(!o.status.success(), "{}", stderr(&o));
    assert!(
        stderr(&o).contains("settling.h5") && stderr(&o).contains("another case or stopping rule"),
        "{}",
        stderr(&o)
    );
    assert!(parts.join("settling.h5").is_file());

    let o = settle(&parts, "30000", "2e-4");
    assert!(o.status.success(), "{}", stderr(&o));
    assert!(stderr(&o).contains("resumed from") && stderr(&o).contains("at step 600"), "{}", stderr(&o));
    assert!(!parts.join("settling.h5").exists() && !parts.join("settling.json").exists());
    let pos = |d: &std::path::Path| {
        hdf5::File::open(d.join("bed.h5")).unwrap().dataset("position").unwrap().read_raw::<f64>().unwrap()
    };
    let (a, b) = (pos(&whole), pos(&parts));
    assert_eq!(a.len(), 9);
    assert!(
        a.iter().zip(&b).all(|(x, y)| x.to_bits() == y.to_bits()),
        "resumed bed {b:?} differs from the uninterrupted one {a:?}"
    );
    let toml = |d: &std::path::Path| std::fs::read_to_string(d.join("bed_particles.toml")).unwrap();
    assert_eq!(toml(&whole), toml(&parts));
}

/// SIGTERM during a settling stops it at its next check with its checkpoint (exit status
/// 143, the step and the checkpoint named); run again, it resumes there and ends with the bed
/// of an uninterrupted settling, bit for bit.
#[test]
fn settle_stopped_by_sigterm_keeps_its_checkpoint_and_resumes_bitwise() {
    use std::io::{BufRead, Read};
    let dir = tempfile::tempdir().unwrap();
    let case = dir.path().join("settle.toml");
    std::fs::write(&case, settle_case()).unwrap();
    // A stopping speed no settling reaches: both end at the step limit, "NOT settled" (exit 1),
    // with the bed written.
    let args = |out: &Path| -> Vec<String> {
        let out = out.to_str().unwrap();
        ["settle", case.to_str().unwrap(), "--out", out, "--speed", "1e-30", "--min-steps", "400"]
            .into_iter()
            .chain(["--check-every", "100", "--max-steps", "20000"])
            .map(String::from)
            .collect()
    };
    let (whole, parts) = (dir.path().join("whole"), dir.path().join("parts"));
    let o = slurry(&args(&whole).iter().map(String::as_str).collect::<Vec<_>>());
    assert_eq!(o.status.code(), Some(1), "{}", stderr(&o));

    let mut child = std::process::Command::new(common::bin())
        .args(args(&parts))
        .stderr(std::process::Stdio::piped())
        .spawn()
        .unwrap();
    let mut err = std::io::BufReader::new(child.stderr.take().unwrap());
    let mut text = String::new();
    // The first progress line (every tenth check) says the settling loop is running.
    while !text.contains("settle: step") {
        assert!(err.read_line(&mut text).unwrap() > 0, "the settling ended first: {text}");
    }
    // SAFETY: kill(2) on our own child, not yet waited for, so its pid is live.
    assert_eq!(unsafe { libc::kill(child.id() as libc::pid_t, libc::SIGTERM) }, 0);
    err.read_to_string(&mut text).unwrap();
    let status = child.wait().unwrap();
    assert_eq!(status.code(), Some(143), "{text}");
    assert!(text.contains("stopped by SIGTERM at step") && text.contains("settling.h5"), "{text}");
    let step: u64 = text.split(" at step ").nth(1).unwrap().split(':').next().unwrap().parse().unwrap();
    assert!(step.is_multiple_of(100) && step < 20000, "stopped at step {step}");
    let record = std::fs::read_to_string(parts.join("settling.json")).unwrap();
    assert!(record.contains(&format!("\"step\":{step},")), "{record}");
    assert_no_temp_files(&parts);

    let o = slurry(&args(&parts).iter().map(String::as_str).collect::<Vec<_>>());
    assert_eq!(o.status.code(), Some(1), "{}", stderr(&o));
    assert!(stderr(&o).contains(&format!("at step {step}")), "{}", stderr(&o));
    let pos = |d: &Path| {
        hdf5::File::open(d.join("bed.h5")).unwrap().dataset("position").unwrap().read_raw::<f64>().unwrap()
    };
    let (a, b) = (pos(&whole), pos(&parts));
    assert!(a.iter().zip(&b).all(|(x, y)| x.to_bits() == y.to_bits()), "resumed {b:?}, uninterrupted {a:?}");
}

/// `[run] snapshots`: the fields of each listed step are written beside the last step's, as
/// `fields-STEP.h5`/`.xmf`, and are those of a run stopped at that step, bit for bit (also
/// at a step that is neither an output nor a checkpoint step).
#[test]
fn snapshots_are_the_fields_of_their_steps() {
    let dir = tempfile::tempdir().unwrap();
    let text =
        std::fs::read_to_string(Path::new(env!("CARGO_MANIFEST_DIR")).join("examples/poiseuille.toml"))
            .unwrap();
    let head = text.split("[run]").next().unwrap();
    let run = |name: &str, run: &str| {
        let case = dir.path().join(format!("{name}.toml"));
        std::fs::write(&case, format!("{head}[run]\n{run}\n")).unwrap();
        let out = dir.path().join(name);
        let o = slurry(&["run", case.to_str().unwrap(), "--out", out.to_str().unwrap(), "--quiet"]);
        assert!(o.status.success(), "{}", stderr(&o));
        out
    };
    let long = run("long", "steps = 100\noutput_every = 50\ncheckpoint_every = 40\nsnapshots = [37, 64]");
    let read = |p: &Path| -> (Vec<f64>, Vec<f64>, u64) {
        let f = hdf5::File::open(p).unwrap();
        let step = f.attr("time_step").unwrap().read_scalar().unwrap();
        (
            f.dataset("density").unwrap().read_raw().unwrap(),
            f.dataset("velocity").unwrap().read_raw().unwrap(),
            step,
        )
    };
    for step in [37u64, 64] {
        let short = run(&format!("to{step}"), &format!("steps = {step}\noutput_every = {step}"));
        let (a, b) = (read(&long.join(format!("fields-{step:09}.h5"))), read(&short.join("fields.h5")));
        assert_eq!(a.2, step);
        let bits = |v: &[f64]| v.iter().map(|x| x.to_bits()).collect::<Vec<_>>();
        assert!(bits(&a.0) == bits(&b.0) && bits(&a.1) == bits(&b.1), "snapshot {step} differs");
        let xmf = std::fs::read_to_string(long.join(format!("fields-{step:09}.xmf"))).unwrap();
        assert!(xmf.contains(&format!("fields-{step:09}.h5:/velocity")), "{xmf}");
    }
    assert_no_temp_files(&long);
    // Outside the run: refused, naming the key and the range.
    let case = dir.path().join("bad.toml");
    std::fs::write(&case, format!("{head}[run]\nsteps = 100\noutput_every = 50\nsnapshots = [101]\n"))
        .unwrap();
    let o = slurry(&["check", case.to_str().unwrap()]);
    assert_eq!(o.status.code(), Some(2), "{}", stderr(&o));
    assert!(stderr(&o).contains("run.snapshots") && stderr(&o).contains("101"), "{}", stderr(&o));
}
