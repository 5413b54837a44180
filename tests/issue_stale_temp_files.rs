//! Issue 15, defect 6 (stale temporary files): a write killed between creating its temporary
//! file and renaming it (`.checkpoint.h5.tmp.PID`) left the file behind for good.
//!
//! Expected: the next `slurry run` into that directory removes temporary files of that form
//! whose process is gone (and leaves those of a process still running, and other files).

use std::process::Command;

mod common;

use common::bin;

#[test]
fn next_start_removes_stale_temporary_files() {
    let tmp = tempfile::tempdir().unwrap();
    let out = tmp.path().join("out");
    std::fs::create_dir_all(&out).unwrap();
    // PIDs above the kernel's limit (pid_max ≤ 2^22) belong to no process.
    let stale = [".checkpoint.h5.tmp.999999991", ".fields.h5.tmp.999999992", ".particles.h5.tmp.999999993"];
    for s in stale {
        std::fs::write(out.join(s), b"half a file").unwrap();
    }
    // A live process's temporary file (this test's) and unrelated files stay.
    let live = format!(".checkpoint.h5.tmp.{}", std::process::id());
    for keep in [live.as_str(), "notes.txt", ".hidden", "x.tmp.123"] {
        std::fs::write(out.join(keep), b"keep").unwrap();
    }
    let o = Command::new(bin())
        .current_dir(env!("CARGO_MANIFEST_DIR"))
        .args(["run", "examples/couette.toml", "--quiet", "--out"])
        .arg(&out)
        .output()
        .unwrap();
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    for s in stale {
        assert!(!out.join(s).exists(), "{s} is still there");
    }
    for keep in [live.as_str(), "notes.txt", ".hidden", "x.tmp.123"] {
        assert!(out.join(keep).exists(), "{keep} was removed");
    }
}
