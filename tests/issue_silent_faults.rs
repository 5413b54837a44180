//! Six classes of fault that ended with a wrong result and exit status 0, or with an abort:
//!
//! 1. two writers into one output directory (two runs, or a `--resume` beside the run) both
//!    went on, mixing their files;
//! 2. a bit flipped in a checkpoint resumed into another result (a bit flipped in a cached bed
//!    of the reproduction: `reproduce/tests/cached_bed_checksum.rs`);
//! 3. a resume with a truncated time series or a deleted particle segment exited 0, leaving a
//!    gap in the history;
//! 4. a case of 10⁶ `[[particles]]` aborted under `ulimit -v` (status 134), and `check
//!    /dev/zero` read until memory ran out;
//! 5. a `--out` that is not valid UTF-8 failed at the first HDF5 write, possibly after every
//!    step.
//!
//! Expected: each refused with its exit status and a message that names the file and the
//! cause, before anything earlier is changed.

use std::path::{Path, PathBuf};
use std::process::{Command, Output};
use std::time::{Duration, Instant};

mod common;

use common::{bin, case_toml, stderr, write_case};

/// `slurry ARGS` with `--quiet --threads 1` after them for `run`.
fn slurry(args: &[&std::ffi::OsStr]) -> Output {
    Command::new(bin()).args(args).output().expect("the slurry binary runs")
}

fn run(case: &Path, out: &Path, extra: &[&str]) -> Output {
    Command::new(bin())
        .arg("run")
        .arg(case)
        .arg("--out")
        .arg(out)
        .args(["--quiet", "--threads", "1"])
        .args(extra)
        .output()
        .expect("the slurry binary runs")
}

/// A fluid-only periodic box of 24³ nodes (f32), `steps` long, rows every 100 steps,
/// checkpoints every 200.
fn fluid_case(steps: u64) -> String {
    let run = format!("steps = {steps}\noutput_every = 100\ncheckpoint_every = 200");
    case_toml([24, 24, 24], "precision = \"f32\"\nnu = 0.1\nbody_force = [1e-6, 0.0, 0.0]", "xyz", &run)
}

/// A free sphere and a free cylinder in a closed box, falling (f32), frames every
/// `output_every` steps.
fn particle_case(steps: u64, output_every: u64) -> String {
    let run = format!("steps = {steps}\noutput_every = {output_every}");
    let closed_box = case_toml([16, 16, 24], "precision = \"f32\"\nnu = 0.05\ncollision = \"trt\"", "", &run);
    format!(
        "gravity = [0.0, 0.0, -2e-4]\n{closed_box}\n[contacts]\n\n[[particles]]\nshape = \"cylinder\"\n\
         diameter = 4.0\nlength = 8.0\ndensity = 1.5\nposition = [7.7, 8.2, 15.0]\naxis = [1.0, 0.3, 0.8]\n\n\
         [[particles]]\nshape = \"sphere\"\ndiameter = 4.0\ndensity = 1.5\nposition = [8.0, 7.0, 3.0]\n"
    )
}

/// The steps of the complete rows of a time series.
fn row_steps(path: &Path) -> Vec<u64> {
    std::fs::read_to_string(path)
        .unwrap()
        .lines()
        .skip(1)
        .map(|l| l.split(',').next().unwrap().parse().unwrap())
        .collect()
}

/// Polls `done` every 10 ms for up to 60 s.
fn wait_for(what: &str, done: impl Fn() -> bool) {
    let t = Instant::now();
    while !done() {
        assert!(t.elapsed() < Duration::from_secs(60), "timed out waiting for {what}");
        std::thread::sleep(Duration::from_millis(10));
    }
}

/// Every file of `dir` (recursively) with its bytes, but the lock's record (which names the
/// last process that held the directory, a refused one included).
fn snapshot(dir: &Path) -> Vec<(PathBuf, Vec<u8>)> {
    let mut out = Vec::new();
    let mut stack = vec![dir.to_path_buf()];
    while let Some(d) = stack.pop() {
        for e in std::fs::read_dir(&d).unwrap() {
            let p = e.unwrap().path();
            if p.is_dir() {
                stack.push(p);
            } else if !p.ends_with(".slurry.lock") {
                out.push((p.clone(), std::fs::read(&p).unwrap()));
            }
        }
    }
    out.sort();
    out
}

fn copy_dir(from: &Path, to: &Path) {
    std::fs::create_dir_all(to).unwrap();
    for e in std::fs::read_dir(from).unwrap() {
        let e = e.unwrap();
        if e.path().is_dir() {
            copy_dir(&e.path(), &to.join(e.file_name()));
        } else {
            std::fs::copy(e.path(), to.join(e.file_name())).unwrap();
        }
    }
}

fn assert_refused(o: &Output, status: i32, needles: &[&str]) {
    let err = stderr(o);
    assert_eq!(o.status.code(), Some(status), "exit status: {err}");
    for n in needles {
        assert!(err.contains(n), "`{n}` missing from: {err}");
    }
}

/// Class 1: while a run writes into a directory, a second run and a `--resume` into it are refused
/// with the holder's PID and command; the run's files stay its own. Killed (SIGKILL), it holds
/// nothing: the kernel releases the lock and a resume continues it without a gap or a repeat.
#[test]
fn a_second_writer_is_refused_and_a_killed_holder_releases_the_directory() {
    let tmp = tempfile::tempdir().unwrap();
    let case = write_case(tmp.path(), "long.toml", &fluid_case(100_000));
    let other = write_case(tmp.path(), "other.toml", &fluid_case(400).replace("nu = 0.1", "nu = 0.2"));
    let out = tmp.path().join("out");
    let mut first = Command::new(bin())
        .arg("run")
        .arg(&case)
        .arg("--out")
        .arg(&out)
        .args(["--quiet", "--threads", "1"])
        .spawn()
        .unwrap();
    let pid = first.id();
    let lock = out.join(".slurry.lock");
    wait_for("the lock's record", || {
        std::fs::read_to_string(&lock).is_ok_and(|t| t.starts_with(&format!("{pid}\n")))
    });
    wait_for("the first checkpoint", || out.join("checkpoint.h5").exists());
    let case_before = std::fs::read(out.join("case.toml")).unwrap();

    let second = run(&other, &out, &["--overwrite"]);
    let holder = format!("PID {pid}");
    assert_refused(&second, 2, &["in use", &holder, "slurry run", "long.toml", &out.display().to_string()]);
    let resume = run(&case, &out, &["--resume"]);
    assert_refused(&resume, 2, &["in use", &holder]);
    assert_eq!(std::fs::read(out.join("case.toml")).unwrap(), case_before, "case.toml replaced");

    // SIGKILL: no handler runs; the lock goes with the process.
    assert_eq!(unsafe { libc::kill(pid as libc::pid_t, libc::SIGKILL) }, 0);
    first.wait().unwrap();
    let at = slurry::io::checkpoint_time_step(&out.join("checkpoint.h5")).unwrap();
    let short = write_case(tmp.path(), "short.toml", &fluid_case(at + 400));
    let resumed = run(&short, &out, &["--resume"]);
    assert!(resumed.status.success(), "{}", stderr(&resumed));
    let expected: Vec<u64> = (0..=(at + 400) / 100).map(|k| k * 100).collect();
    assert_eq!(row_steps(&out.join("timeseries.csv")), expected, "a gap or a repeated row");
}

/// Class 2a: one bit flipped in a checkpoint's populations: the resume is refused as corrupt, naming
/// the file and the remedies, and leaves every file as it was.
#[test]
fn a_flipped_bit_in_a_checkpoint_is_refused_as_corrupt() {
    let tmp = tempfile::tempdir().unwrap();
    let out = tmp.path().join("out");
    let o = run(&write_case(tmp.path(), "a.toml", &fluid_case(400)), &out, &[]);
    assert!(o.status.success(), "{}", stderr(&o));
    let checkpoint = out.join("checkpoint.h5");
    {
        let f = hdf5::File::open_rw(&checkpoint).unwrap();
        let d = f.dataset("populations").unwrap();
        let mut p = d.read_raw::<f32>().unwrap();
        p[4321] = f32::from_bits(p[4321].to_bits() ^ (1 << 3));
        d.write_raw(&p).unwrap();
    }
    let before = snapshot(&out);
    let o = run(&write_case(tmp.path(), "b.toml", &fluid_case(800)), &out, &["--resume"]);
    assert_refused(&o, 2, &["corrupt", &checkpoint.display().to_string(), "older copy", "--overwrite"]);
    assert!(!stderr(&o).contains("Mach"), "blamed on the Mach limit: {}", stderr(&o));
    assert_eq!(snapshot(&out), before, "a file changed");
}

/// Class 3: a run stopped by SIGTERM with two particle segments: resumed with its time series
/// truncated, its last segment deleted, or its whole `particles.frames/` deleted, it is refused
/// with the missing steps named and every file as it was; whole, it resumes without a gap.
#[test]
fn a_resume_whose_history_falls_short_of_its_checkpoint_is_refused() {
    let tmp = tempfile::tempdir().unwrap();
    let out = tmp.path().join("out");
    let long = write_case(tmp.path(), "long.toml", &particle_case(20_000, 2));
    let mut child = Command::new(bin())
        .arg("run")
        .arg(&long)
        .arg("--out")
        .arg(&out)
        .args(["--quiet", "--threads", "1"])
        .spawn()
        .unwrap();
    wait_for("a second segment", || out.join("particles.frames/000001.h5").exists());
    assert_eq!(unsafe { libc::kill(child.id() as libc::pid_t, libc::SIGTERM) }, 0);
    assert_eq!(child.wait().unwrap().code(), Some(143));
    let at = slurry::io::checkpoint_time_step(&out.join("checkpoint.h5")).unwrap();
    let rows = row_steps(&out.join("timeseries.csv"));
    assert_eq!(rows.last(), Some(&at), "rows to the stop");
    let short = write_case(tmp.path(), "short.toml", &particle_case(at + 20, 2));
    let segments = out.join("particles.frames");
    let last_segment = std::fs::read_dir(&segments).unwrap().map(|e| e.unwrap().path()).max().unwrap();
    // Full segments of 32 frames (every 2 steps) before the last.
    let full = std::fs::read_dir(&segments).unwrap().count() as u64 - 1;
    let last_kept = format!("last frame kept is step {}", full * 64 - 2);

    let damaged = |name: &str, damage: &dyn Fn(&Path)| {
        let d = tmp.path().join(name);
        copy_dir(&out, &d);
        damage(&d);
        let before = snapshot(&d);
        let o = run(&short, &d, &["--resume"]);
        assert_eq!(snapshot(&d), before, "{name}: a file changed");
        o
    };
    let truncated = damaged("truncated", &|d| {
        let ts = d.join("timeseries.csv");
        let text = std::fs::read_to_string(&ts).unwrap();
        let kept: Vec<&str> = text.lines().take(1 + 23).collect();
        std::fs::write(&ts, format!("{}\n", kept.join("\n"))).unwrap();
    });
    let missing = format!("steps 46 to {at}");
    assert_refused(
        &truncated,
        2,
        &["timeseries.csv", "no rows for", &missing, "last row kept is step 44", "--overwrite"],
    );
    let segment_name = last_segment.file_name().unwrap().to_owned();
    let no_last = damaged("no-last-segment", &|d| {
        std::fs::remove_file(d.join("particles.frames").join(&segment_name)).unwrap()
    });
    assert_refused(&no_last, 2, &["particles.h5", "no frames for", &last_kept, "--overwrite"]);
    let no_frames = damaged("no-frames", &|d| std::fs::remove_dir_all(d.join("particles.frames")).unwrap());
    assert_refused(&no_frames, 2, &["particles.h5", "no frames for steps 0 to", "last frame kept is none"]);

    let whole = run(&short, &out, &["--resume"]);
    assert!(whole.status.success(), "{}", stderr(&whole));
    let expected: Vec<u64> = (0..=(at + 20) / 2).map(|k| 2 * k).collect();
    assert_eq!(row_steps(&out.join("timeseries.csv")), expected);
    let frames: Vec<u64> = slurry::io::read_particle_history(&out.join("particles.h5"))
        .unwrap()
        .frames
        .iter()
        .map(|f| f.step)
        .collect();
    assert_eq!(frames, expected, "the particle history has a gap or a repeat");
}

/// Class 4: 10⁶ `[[particles]]` (92 MB) under `ulimit -v 4G` are refused by size,
/// 2·10⁵ under `SLURRY_MEMORY_LIMIT=200M` (and under `ulimit -v 1G`) by the parse's estimate,
/// both before parsing; `/dev/zero` and a FIFO are refused without being read.
#[test]
fn huge_and_endless_case_files_are_refused_before_parsing() {
    let tmp = tempfile::tempdir().unwrap();
    let head = case_toml([64, 64, 64], "nu = 0.1", "xy", "steps = 10\noutput_every = 5");
    let entry =
        "[[particles]]\nshape = \"sphere\"\ndiameter = 4.0\ndensity = 1.5\nposition = [32.0, 32.0, 32.0]\n";
    let many = |n: usize| format!("gravity = [0.0, 0.0, -1e-5]\n{head}\n[contacts]\n{}", entry.repeat(n));
    let huge = write_case(tmp.path(), "huge.toml", &many(1_000_000));
    assert!(std::fs::metadata(&huge).unwrap().len() > 64 << 20);
    let limited = |limit_kb: u64, path: &Path| {
        Command::new("sh")
            .arg("-c")
            .arg(format!("ulimit -v {limit_kb} && exec \"$0\" check \"$1\""))
            .arg(bin())
            .arg(path)
            .env_remove("SLURRY_MEMORY_LIMIT")
            .env_remove("SLURRY_CASE_SIZE_LIMIT")
            .output()
            .unwrap()
    };
    let o = limited(4 << 20, &huge);
    assert_refused(&o, 2, &["huge.toml", "above the limit of 64.000 MiB", "SLURRY_CASE_SIZE_LIMIT"]);

    let big = write_case(tmp.path(), "big.toml", &many(200_000));
    let o = Command::new(bin()).arg("check").arg(&big).env("SLURRY_MEMORY_LIMIT", "200M").output().unwrap();
    assert_refused(&o, 2, &["big.toml", "[[particles]]", "about 200000 entries", "SLURRY_MEMORY_LIMIT=200M"]);
    let o = limited(1 << 20, &big);
    assert_refused(&o, 2, &["big.toml", "about 200000 entries", "ulimit -v"]);

    let o = slurry(&["check".as_ref(), "/dev/zero".as_ref()]);
    assert_refused(&o, 2, &["/dev/zero", "character device", "not a regular file"]);
    let fifo = tmp.path().join("fifo.toml");
    let c = std::ffi::CString::new(fifo.as_os_str().as_encoded_bytes()).unwrap();
    assert_eq!(unsafe { libc::mkfifo(c.as_ptr(), 0o600) }, 0);
    let o = slurry(&["check".as_ref(), fifo.as_os_str()]);
    assert_refused(&o, 2, &["fifo.toml", "FIFO"]);
}

/// Class 5: a `--out` that is not valid UTF-8 is refused before the first step, naming it; nothing
/// is created there, for `run` and for `settle`.
#[cfg(unix)]
#[test]
fn an_output_path_that_is_not_utf8_is_refused_before_the_first_step() {
    use std::os::unix::ffi::OsStrExt;
    let tmp = tempfile::tempdir().unwrap();
    let case = write_case(tmp.path(), "a.toml", &fluid_case(200));
    let bad = tmp.path().join(std::ffi::OsStr::from_bytes(b"out-\xff"));
    let before = snapshot(tmp.path());
    let o = run(&case, &bad, &[]);
    assert_refused(&o, 2, &["--out", "out-", "not valid UTF-8", "checkpoint.h5"]);
    let o = slurry(&["settle".as_ref(), case.as_os_str(), "--out".as_ref(), bad.as_os_str()]);
    assert_refused(&o, 2, &["not valid UTF-8"]);
    assert!(!bad.exists(), "created the directory");
    assert_eq!(snapshot(tmp.path()), before);
}
