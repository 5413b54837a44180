//! `slurry status`: where a reproduction stands, from an archived run, and its bad input (exit
//! status 2, naming the directory, after the readable ones are printed).

#[path = "../../tests/common/mod.rs"]
mod common;

use common::{slurry, stderr};

/// The archived steady pbt-ld2 run at s = 1/4 and a directory that is not a reproduction's.
#[test]
fn status_of_an_archive_and_of_a_stranger() {
    let archived = "reproduce/pbt-ld2/runs/2026-11-25-s0.25-exact-r200";
    let o = slurry(&["status", archived]);
    assert_eq!(o.status.code(), Some(0), "{}", stderr(&o));
    let text = String::from_utf8_lossy(&o.stdout).to_string();
    assert!(text.contains("finished"), "{text}");
    // The last window and the power numbers of its report (reproduce/README.md).
    assert!(text.contains("191–201 0.333"), "{text}");
    assert!(text.contains("Po_f 1.944, Po_c 1.200, Po 3.145"), "{text}");

    let tmp = tempfile::tempdir().unwrap();
    let o = slurry(&["status", archived, tmp.path().to_str().unwrap()]);
    assert_eq!(o.status.code(), Some(2), "{}", stderr(&o));
    assert!(String::from_utf8_lossy(&o.stdout).contains("Po_f 1.944"));
    let e = stderr(&o);
    assert!(e.contains(tmp.path().to_str().unwrap()) && e.contains("no manifest.json"), "{e}");
}
