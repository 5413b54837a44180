//! Issue 15, defect 6 (consistency): bad input gets exit status 2 everywhere. A missing or
//! unreadable checkpoint under `--resume`, and an output directory that exists but cannot be
//! written, gave 1; the resume error printed HDF5's internal stack.
//!
//! Expected: exit status 2 and one line: `no checkpoint in DIR (the run wrote none yet, or it
//! is not a slurry checkpoint)`, or `--out DIR: cannot write into the output directory`.

use std::path::Path;
use std::process::Output;

mod common;

use common::{slurry, stderr};

fn run(out: &Path, resume: bool) -> Output {
    let out = out.to_str().unwrap();
    let mut args = vec!["run", "examples/couette.toml", "--quiet", "--out", out];
    if resume {
        args.push("--resume");
    }
    slurry(&args)
}

#[test]
fn missing_or_unreadable_checkpoint_is_bad_input() {
    let tmp = tempfile::tempdir().unwrap();
    let want = format!(
        "no checkpoint in {} (the run wrote none yet, or it is not a slurry checkpoint)",
        tmp.path().display()
    );
    let o = run(tmp.path(), true);
    assert_eq!(o.status.code(), Some(2), "{}", stderr(&o));
    assert!(stderr(&o).contains(&want), "{}", stderr(&o));

    std::fs::write(tmp.path().join("checkpoint.h5"), b"not an HDF5 file").unwrap();
    let o = run(tmp.path(), true);
    let e = stderr(&o);
    assert_eq!(o.status.code(), Some(2), "{e}");
    assert!(e.contains(&want), "{e}");
    assert!(!e.contains("H5F") && !e.contains("HDF5") && e.lines().count() == 1, "{e}");
}

#[test]
fn output_directory_that_cannot_be_written_is_bad_input() {
    // A directory that exists and that nobody, root included, can create files in.
    let o = run(Path::new("/proc/self"), false);
    assert_eq!(o.status.code(), Some(2), "{}", stderr(&o));
    assert!(
        stderr(&o).contains("--out /proc/self: cannot write into the output directory"),
        "{}",
        stderr(&o)
    );

    // A read-only directory (when the tests do not run as root, who may write anyway).
    let tmp = tempfile::tempdir().unwrap();
    let ro = tmp.path().join("ro");
    std::fs::create_dir(&ro).unwrap();
    use std::os::unix::fs::PermissionsExt;
    std::fs::set_permissions(&ro, std::fs::Permissions::from_mode(0o555)).unwrap();
    if std::fs::write(ro.join("probe"), b"x").is_err() {
        let o = run(&ro, false);
        assert_eq!(o.status.code(), Some(2), "{}", stderr(&o));
        assert!(stderr(&o).contains("cannot write into the output directory"), "{}", stderr(&o));
    }
    std::fs::set_permissions(&ro, std::fs::Permissions::from_mode(0o755)).unwrap();
}
