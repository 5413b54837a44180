//! Checkpoints and `slurry run --resume`: a run killed with SIGKILL at an arbitrary moment and
//! resumed gives bitwise the same fields, checkpoint and time series (physics columns) as a
//! run that was never interrupted; a checkpoint of another case is refused. A run stopped by
//! SIGINT or SIGTERM writes a checkpoint where it stops (exit status 130 or 143) and resumes
//! from it bitwise likewise.

use std::path::Path;
use std::process::{Command, Stdio};
use std::time::{Duration, Instant};

mod common;

use common::{bin, case_toml, write_case};

/// A channel (periodic x and y) sheared by a moving lid and driven by a body force, f32 TRT.
fn case(steps: u64, nu: f64) -> String {
    case_toml(
        [48, 48, 24],
        &format!("precision = \"f32\"\nnu = {nu}\ncollision = \"trt\"\nbody_force = [1e-6, 0.0, 0.0]"),
        "xy",
        &format!("steps = {steps}\noutput_every = 100\ncheckpoint_every = 200"),
    )
    .replace("z_max = \"no_slip\"", "z_max = { moving_wall = [0.05, 0.0, 0.0] }")
}

fn run(case: &Path, out: &Path, resume: bool) -> std::process::Output {
    let mut c = Command::new(bin());
    c.args(["run"]).arg(case).arg("--out").arg(out).arg("--quiet");
    if resume {
        c.arg("--resume");
    }
    c.output().unwrap()
}

fn read(path: &Path, name: &str) -> Vec<f64> {
    hdf5::File::open(path).unwrap().dataset(name).unwrap().read_raw::<f64>().unwrap()
}

fn read_f32(path: &Path, name: &str) -> Vec<f32> {
    hdf5::File::open(path).unwrap().dataset(name).unwrap().read_raw::<f32>().unwrap()
}

/// The time series without its timing column (`mlups`, the last one).
fn physics_rows(path: &Path) -> Vec<String> {
    std::fs::read_to_string(path)
        .unwrap()
        .lines()
        .map(|l| l.rsplit_once(',').map_or(l, |(a, _)| a).to_string())
        .collect()
}

#[test]
fn killed_and_resumed_equals_uninterrupted() {
    let tmp = tempfile::tempdir().unwrap();
    let steps = 2000;
    let c = write_case(tmp.path(), "c.toml", &case(steps, 0.05));
    let a = tmp.path().join("a");
    let b = tmp.path().join("b");
    let out = run(&c, &a, false);
    assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));

    // Start the same run, kill it (SIGKILL) as soon as its first checkpoint exists.
    let mut child =
        Command::new(bin()).args(["run"]).arg(&c).arg("--out").arg(&b).arg("--quiet").spawn().unwrap();
    let t0 = Instant::now();
    while !b.join("checkpoint.h5").exists() && t0.elapsed() < Duration::from_secs(60) {
        std::thread::sleep(Duration::from_millis(2));
    }
    let _ = child.kill();
    let _ = child.wait();
    assert!(b.join("checkpoint.h5").exists(), "no checkpoint appeared");

    let out = run(&c, &b, true);
    assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
    for name in ["density", "velocity"] {
        let (x, y) = (read(&a.join("fields.h5"), name), read(&b.join("fields.h5"), name));
        assert!(x.iter().zip(&y).all(|(p, q)| p.to_bits() == q.to_bits()), "{name} differs");
    }
    assert_eq!(
        read_f32(&a.join("checkpoint.h5"), "populations"),
        read_f32(&b.join("checkpoint.h5"), "populations")
    );
    assert_eq!(physics_rows(&a.join("timeseries.csv")), physics_rows(&b.join("timeseries.csv")));
    // Header, step 0, and every 100 steps.
    assert_eq!(physics_rows(&a.join("timeseries.csv")).len() as u64, 2 + steps / 100);
}

#[test]
fn resume_extends_a_run_and_refuses_another_case() {
    let tmp = tempfile::tempdir().unwrap();
    let short = write_case(tmp.path(), "short.toml", &case(400, 0.05));
    let long = write_case(tmp.path(), "long.toml", &case(800, 0.05));
    let other = write_case(tmp.path(), "other.toml", &case(800, 0.06));
    let (a, b) = (tmp.path().join("a"), tmp.path().join("b"));
    assert!(run(&long, &a, false).status.success());
    assert!(run(&short, &b, false).status.success());
    let refused = run(&other, &b, true);
    assert_eq!(refused.status.code(), Some(2));
    assert!(String::from_utf8_lossy(&refused.stderr).contains("different case"));
    assert!(run(&long, &b, true).status.success());
    assert_eq!(read(&a.join("fields.h5"), "velocity"), read(&b.join("fields.h5"), "velocity"));

    let none = run(&long, &tmp.path().join("empty"), true);
    assert!(!none.status.success());
    assert!(String::from_utf8_lossy(&none.stderr).contains("checkpoint"));
}

/// A fresh start in a directory that holds an earlier run's checkpoint is refused (exit 2,
/// the checkpoint, its last step and both options named) and changes no file; `--overwrite`
/// starts over; `--overwrite` with `--resume` is a usage error.
#[test]
fn a_fresh_start_over_a_checkpoint_is_refused_unless_overwrite() {
    let tmp = tempfile::tempdir().unwrap();
    let c = write_case(tmp.path(), "c.toml", &case(400, 0.05));
    let a = tmp.path().join("a");
    assert!(run(&c, &a, false).status.success());
    let series = std::fs::read(a.join("timeseries.csv")).unwrap();
    let checkpoint = std::fs::read(a.join("checkpoint.h5")).unwrap();

    let refused = run(&c, &a, false);
    assert_eq!(refused.status.code(), Some(2));
    let err = String::from_utf8_lossy(&refused.stderr);
    for needle in ["checkpoint.h5", "time series to step 400", "--resume", "--overwrite"] {
        assert!(err.contains(needle), "`{needle}` not in: {err}");
    }
    assert_eq!(std::fs::read(a.join("timeseries.csv")).unwrap(), series, "the series was touched");
    assert_eq!(std::fs::read(a.join("checkpoint.h5")).unwrap(), checkpoint, "the checkpoint was touched");

    let again =
        Command::new(bin()).arg("run").arg(&c).arg("--out").arg(&a).args(["--quiet", "--overwrite"]).output();
    assert!(again.unwrap().status.success());
    assert_eq!(physics_rows(&a.join("timeseries.csv")).len(), 2 + 4, "the run started over");

    // A run that wrote no checkpoint (none asked for, or killed before the first) is protected
    // too: only --overwrite is offered, since there is nothing to resume from.
    std::fs::remove_file(a.join("checkpoint.h5")).unwrap();
    let series = std::fs::read(a.join("timeseries.csv")).unwrap();
    let refused = run(&c, &a, false);
    assert_eq!(refused.status.code(), Some(2));
    let err = String::from_utf8_lossy(&refused.stderr);
    for needle in ["timeseries.csv to step 400", "wrote no checkpoint", "--overwrite"] {
        assert!(err.contains(needle), "`{needle}` not in: {err}");
    }
    assert!(!err.contains("--resume"), "nothing to resume from: {err}");
    assert_eq!(std::fs::read(a.join("timeseries.csv")).unwrap(), series, "the series was touched");

    let both = Command::new(bin())
        .arg("run")
        .arg(&c)
        .arg("--out")
        .arg(&a)
        .args(["--resume", "--overwrite"])
        .output();
    assert_eq!(both.unwrap().status.code(), Some(2), "clap's usage error");
}

fn particle_case(steps: u64) -> String {
    particle_case_with(steps, "", 8.0)
}

/// The particle case with `extra` appended (e.g. `[contacts]`) and the sphere at height `z`.
fn particle_case_with(steps: u64, extra: &str, z: f64) -> String {
    let run = format!("steps = {steps}\noutput_every = 50\ncheckpoint_every = 100");
    let closed_box = case_toml([20, 20, 32], "precision = \"f32\"\nnu = 0.05\ncollision = \"bgk\"", "", &run);
    format!(
        r#"
gravity = [0.0, 0.0, -1e-4]
{closed_box}
[[particles]]
shape = "cylinder"
diameter = 6.0
length = 12.0
density = 1.25
position = [9.7, 10.2, 20.0]
axis = [1.0, 0.3, 0.8]

[[particles]]
shape = "sphere"
diameter = 5.0
density = 1.25
position = [10.0, 9.0, {z}]

{extra}
"#
    )
}

/// With free particles: a run stopped at its checkpoint and resumed to a later end gives
/// bitwise the same particle histories, fields and time series as one uninterrupted run.
#[test]
fn particle_run_resumed_equals_uninterrupted() {
    resumed_equals_uninterrupted(&particle_case(400), &particle_case(250));
}

/// The same with contacts, the sphere near the floor within the lubrication range (the
/// contact sub-cycling and its state across a restore). With two particles this passed even
/// before orientations were restored bit for bit: the renormalisation moved last bits only
/// for some quaternions, which the 822 particles of `slurry reproduce` exposed (its resume
/// after `kill -9` is now bitwise identical; checked by hand, see CHANGELOG).
#[test]
fn particle_run_with_contacts_resumed_equals_uninterrupted() {
    let (long, short) =
        (particle_case_with(400, "[contacts]", 2.8), particle_case_with(250, "[contacts]", 2.8));
    resumed_equals_uninterrupted(&long, &short);
}

fn resumed_equals_uninterrupted(long_case: &str, short_case: &str) {
    let tmp = tempfile::tempdir().unwrap();
    let long = write_case(tmp.path(), "long.toml", long_case);
    let short = write_case(tmp.path(), "short.toml", short_case);
    let (a, b) = (tmp.path().join("a"), tmp.path().join("b"));
    let out = run(&long, &a, false);
    assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
    // The short run writes frames up to step 250 and its last checkpoint at 200: the resume
    // must cut the frame at 250 and recompute it.
    assert!(run(&short, &b, false).status.success());
    let out = run(&long, &b, true);
    assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
    assert_same_particle_run(&a, &b);
}

/// The particle histories, the final velocity field and the time series (physics columns)
/// of the runs in `a` and `b` are the same, bit for bit.
fn assert_same_particle_run(a: &Path, b: &Path) {
    for name in ["position", "quaternion", "velocity", "angular_velocity", "force", "torque", "time"] {
        let (x, y) = (read(&a.join("particles.h5"), name), read(&b.join("particles.h5"), name));
        assert_eq!(x.len(), y.len(), "{name}: frame count");
        assert!(x.iter().zip(&y).all(|(p, q)| p.to_bits() == q.to_bits()), "{name} differs");
    }
    assert_eq!(read(&a.join("fields.h5"), "velocity"), read(&b.join("fields.h5"), "velocity"));
    assert_eq!(physics_rows(&a.join("timeseries.csv")), physics_rows(&b.join("timeseries.csv")));
}

/// `--switch-contacts`: a checkpoint written under one contact scheme continues under another
/// (`[contacts] substeps`, `lubrication_limiter`) only when asked, and only those may change:
/// another Table 1 constant is still refused. The continued run keeps the history up to the
/// checkpoint bit for bit and runs to its end.
#[test]
fn switch_contacts_resumes_under_another_contact_scheme_only() {
    let tmp = tempfile::tempdir().unwrap();
    let explicit = write_case(tmp.path(), "explicit.toml", &particle_case_with(250, "[contacts]", 2.8));
    let limited = "[contacts]\nsubsteps = 2\nlubrication_limiter = true";
    let cheaper = write_case(tmp.path(), "cheaper.toml", &particle_case_with(400, limited, 2.8));
    let stiffer = write_case(
        tmp.path(),
        "stiffer.toml",
        &particle_case_with(400, "[contacts]\nk = 4.0\nsubsteps = 2", 2.8),
    );
    let reference = write_case(tmp.path(), "reference.toml", &particle_case_with(400, "[contacts]", 2.8));
    let (a, b) = (tmp.path().join("a"), tmp.path().join("b"));
    assert!(run(&reference, &a, false).status.success());
    assert!(run(&explicit, &b, false).status.success());
    let switch = |case: &Path| {
        Command::new(bin())
            .args(["run"])
            .arg(case)
            .arg("--out")
            .arg(&b)
            .args(["--quiet", "--resume", "--switch-contacts"])
            .output()
            .unwrap()
    };
    let refused = run(&cheaper, &b, true);
    assert_eq!(refused.status.code(), Some(2));
    assert!(String::from_utf8_lossy(&refused.stderr).contains("different case"));
    let refused = switch(&stiffer);
    assert_eq!(refused.status.code(), Some(2), "{}", String::from_utf8_lossy(&refused.stderr));
    assert!(String::from_utf8_lossy(&refused.stderr).contains("--switch-contacts"));
    let out = switch(&cheaper);
    assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
    // Frames to the checkpoint (step 200, 5 frames of 50 steps) as the uninterrupted
    // explicit run's; the whole history, 9 frames, to step 400.
    let (steps_a, steps_b) = (read(&a.join("particles.h5"), "time"), read(&b.join("particles.h5"), "time"));
    assert_eq!((steps_a.len(), &steps_a), (9, &steps_b));
    let (x, y) = (read(&a.join("particles.h5"), "position"), read(&b.join("particles.h5"), "position"));
    let per_frame = x.len() / steps_a.len();
    let kept = 5 * per_frame;
    assert!(x[..kept].iter().zip(&y[..kept]).all(|(p, q)| p.to_bits() == q.to_bits()));
    assert!(physics_rows(&b.join("timeseries.csv")).last().unwrap().starts_with("400,"));
}

/// Starts `slurry run CASE --out OUT`, sends it `signal` once its time series holds `rows`
/// rows, and waits for it.
fn signalled_run(case: &Path, out: &Path, signal: i32, rows: usize) -> std::process::Output {
    let mut child = Command::new(bin())
        .args(["run"])
        .arg(case)
        .arg("--out")
        .arg(out)
        .arg("--quiet")
        .stderr(Stdio::piped())
        .spawn()
        .unwrap();
    let series = out.join("timeseries.csv");
    let t0 = Instant::now();
    // Header and `rows` rows.
    while std::fs::read_to_string(&series).map_or(0, |t| t.lines().count()) < rows + 1 {
        if let Some(status) = child.try_wait().unwrap() {
            panic!("the run ended ({status}) before the signal was sent: make it longer");
        }
        assert!(t0.elapsed() < Duration::from_secs(120), "no {rows} rows after 120 s");
        std::thread::sleep(Duration::from_millis(1));
    }
    // SAFETY: kill(2) on our own child, which has not been waited for, so its pid is live.
    assert_eq!(unsafe { libc::kill(child.id() as libc::pid_t, signal) }, 0);
    child.wait_with_output().unwrap()
}

/// The step at which a stopped run says it stopped (`stopped by … at step N: …`).
fn stopped_at(stderr: &str) -> u64 {
    let rest = stderr.split_once(" at step ").unwrap_or_else(|| panic!("no stop reported: {stderr}")).1;
    rest.split(|c: char| !c.is_ascii_digit()).next().unwrap().parse().unwrap()
}

/// SIGTERM stops a run with particles and contacts, whose case asks for no checkpoints, at an
/// even step with a checkpoint of that step (exit status 143, the step, the checkpoint and
/// `--resume` named); resumed, its particle histories, fields and time series are the
/// uninterrupted run's, bit for bit.
#[test]
fn sigterm_stops_at_a_checkpoint_and_the_resume_is_bitwise() {
    let tmp = tempfile::tempdir().unwrap();
    let steps = 6000;
    let text = particle_case_with(steps, "[contacts]", 2.8).replace("\ncheckpoint_every = 100", "");
    assert!(!text.contains("checkpoint_every"));
    let c = write_case(tmp.path(), "c.toml", &text);
    let (a, b) = (tmp.path().join("a"), tmp.path().join("b"));
    let out = run(&c, &a, false);
    assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
    assert!(!a.join("checkpoint.h5").exists(), "no checkpoint was asked for");

    let out = signalled_run(&c, &b, libc::SIGTERM, 8);
    let err = String::from_utf8_lossy(&out.stderr);
    assert_eq!(out.status.code(), Some(143), "{err}");
    for needle in ["stopped by SIGTERM at step", "checkpoint.h5", "--resume"] {
        assert!(err.contains(needle), "`{needle}` not in: {err}");
    }
    let step = stopped_at(&err);
    assert!(step.is_multiple_of(2) && step >= 350 && step < steps, "stopped at step {step}");
    let checkpoint = hdf5::File::open(b.join("checkpoint.h5")).unwrap();
    assert_eq!(checkpoint.attr("time_step").unwrap().read_scalar::<u64>().unwrap(), step);
    assert!(!read(&b.join("checkpoint.h5"), "bodies").is_empty(), "the particles' states");
    let last_row = physics_rows(&b.join("timeseries.csv")).last().unwrap().clone();
    let last_row_step: u64 = last_row.split(',').next().unwrap().parse().unwrap();
    assert!(last_row_step <= step && step - last_row_step < 50, "last row {last_row_step}, stop {step}");
    common::assert_no_temp_files(&b);

    let out = run(&c, &b, true);
    assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
    assert_same_particle_run(&a, &b);
}

/// SIGINT (Ctrl-C) stops a fluid-only run the same way (exit status 130), between its own
/// checkpoints; the resume gives the uninterrupted run's fields and time series bitwise.
#[test]
fn sigint_stops_a_fluid_run_at_a_checkpoint_and_the_resume_is_bitwise() {
    let tmp = tempfile::tempdir().unwrap();
    let steps = 20_000;
    let c = write_case(tmp.path(), "c.toml", &case(steps, 0.05));
    let (a, b) = (tmp.path().join("a"), tmp.path().join("b"));
    assert!(run(&c, &a, false).status.success());

    let out = signalled_run(&c, &b, libc::SIGINT, 4);
    let err = String::from_utf8_lossy(&out.stderr);
    assert_eq!(out.status.code(), Some(130), "{err}");
    assert!(err.contains("stopped by SIGINT (Ctrl-C) at step"), "{err}");
    let step = stopped_at(&err);
    assert!(step.is_multiple_of(2) && step >= 300 && step < steps, "stopped at step {step}");
    let checkpoint = hdf5::File::open(b.join("checkpoint.h5")).unwrap();
    assert_eq!(checkpoint.attr("time_step").unwrap().read_scalar::<u64>().unwrap(), step);

    let out = run(&c, &b, true);
    assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
    for name in ["density", "velocity"] {
        let (x, y) = (read(&a.join("fields.h5"), name), read(&b.join("fields.h5"), name));
        assert!(x.iter().zip(&y).all(|(p, q)| p.to_bits() == q.to_bits()), "{name} differs");
    }
    assert_eq!(physics_rows(&a.join("timeseries.csv")), physics_rows(&b.join("timeseries.csv")));
}
