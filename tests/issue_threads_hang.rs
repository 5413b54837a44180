//! Issue 15, defect 4: `--threads 100000` never returned and `--threads 1000` took 36 s for
//! 10 steps of 128 nodes.
//!
//! Expected: more threads than the machine has (`std::thread::available_parallelism`) are
//! refused at once with exit status 2 and a message naming the flag and the allowed range,
//! for `run`, `settle`, `reproduce` and `bench`, and through `RAYON_NUM_THREADS` too.

use std::process::{Command, Output};
use std::time::{Duration, Instant};

mod common;

use common::bin;

fn slurry(args: &[&str], env: Option<(&str, &str)>) -> (Output, Duration) {
    let t0 = Instant::now();
    let mut c = Command::new(bin());
    c.args(args).current_dir(env!("CARGO_MANIFEST_DIR"));
    if let Some((k, v)) = env {
        c.env(k, v);
    }
    let out = c.output().unwrap();
    (out, t0.elapsed())
}

fn assert_refused(args: &[&str], env: Option<(&str, &str)>, needle: &str) {
    let (out, took) = slurry(args, env);
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert_eq!(out.status.code(), Some(2), "{args:?}: {stderr}");
    assert!(stderr.contains(needle) && stderr.contains("hardware thread"), "{args:?}: {stderr}");
    assert!(took < Duration::from_secs(10), "{args:?} took {took:?}");
}

#[test]
fn more_threads_than_cores_are_refused_at_once() {
    let tmp = tempfile::tempdir().unwrap();
    let out = tmp.path().join("out");
    let out = out.to_str().unwrap();
    let too_many = (std::thread::available_parallelism().unwrap().get() + 1).to_string();
    for n in ["100000", too_many.as_str()] {
        assert_refused(
            &["run", "examples/poiseuille.toml", "--out", out, "--quiet", "--threads", n],
            None,
            "--threads",
        );
        assert_refused(
            &["settle", "examples/poiseuille.toml", "--out", out, "--threads", n],
            None,
            "--threads",
        );
        assert_refused(&["reproduce", "pbt-ld2", "--out", out, "--quiet", "--threads", n], None, "--threads");
        assert_refused(&["bench", "--sizes", "8", "--threads", n], None, "--threads");
    }
    assert_refused(
        &["run", "examples/poiseuille.toml", "--out", out, "--quiet"],
        Some(("RAYON_NUM_THREADS", "100000")),
        "RAYON_NUM_THREADS",
    );
}

#[test]
fn as_many_threads_as_cores_are_accepted() {
    let tmp = tempfile::tempdir().unwrap();
    let out = tmp.path().join("out");
    let n = std::thread::available_parallelism().unwrap().get().to_string();
    let (o, _) = slurry(
        &["run", "examples/couette.toml", "--out", out.to_str().unwrap(), "--quiet", "--threads", &n],
        None,
    );
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
}
