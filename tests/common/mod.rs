//! Fixtures shared by the integration tests. Each file of `tests/` is its own crate and takes
//! these with `mod common;`: the `slurry` binary, case files built from their required
//! sections, and the messages of refused cases.
//!
//! (The library's unit tests, `src/case/tests.rs`, keep their own case text: they are compiled
//! into the library, where this module, which names the binary, does not exist.)

// Each test crate uses a part of these.
#![allow(dead_code)]

use std::path::{Path, PathBuf};
use std::process::{Command, Output};

use slurry::case::Case;

/// The `slurry` binary of this build.
pub const BIN: &str = env!("CARGO_BIN_EXE_slurry");

/// Runs `slurry ARGS` in the crate's root (so that `examples/…` paths resolve) and waits.
pub fn slurry(args: &[&str]) -> Output {
    Command::new(BIN)
        .args(args)
        .current_dir(env!("CARGO_MANIFEST_DIR"))
        .output()
        .expect("the slurry binary runs")
}

/// The standard error of a finished command, as text.
pub fn stderr(o: &Output) -> String {
    String::from_utf8_lossy(&o.stderr).into_owned()
}

/// No temporary file of an atomic write (`*.tmp.*`) is left in `dir`.
pub fn assert_no_temp_files(dir: &Path) {
    for e in std::fs::read_dir(dir).unwrap() {
        let name = e.unwrap().file_name().into_string().unwrap();
        assert!(!name.contains(".tmp."), "temporary file left: {name}");
    }
}

/// A `[boundaries]` section: the two faces normal to each axis named in `periodic` (`""`,
/// `"x"`, `"xy"`, `"xyz"`) periodic, every other face no-slip.
pub fn boundaries(periodic: &str) -> String {
    let mut s = String::from("[boundaries]\n");
    for axis in ["x", "y", "z"] {
        let kind = if periodic.contains(axis) { "periodic" } else { "no_slip" };
        for end in ["min", "max"] {
            s.push_str(&format!("{axis}_{end} = \"{kind}\"\n"));
        }
    }
    s
}

/// A case file's required sections: `[domain]` of `nx × ny × nz` nodes, `[fluid]` with the
/// lines `fluid`, [`boundaries`]`(periodic)` and `[run]` with the lines `run`. Other sections
/// (gravity first, `[[particles]]`, `[contacts]`, …) are added around it by the caller.
pub fn case_toml([nx, ny, nz]: [usize; 3], fluid: &str, periodic: &str, run: &str) -> String {
    format!(
        "\n[domain]\nnx = {nx}\nny = {ny}\nnz = {nz}\n\n[fluid]\n{}\n\n{}\n[run]\n{}\n",
        fluid.trim(),
        boundaries(periodic),
        run.trim()
    )
}

/// The message of `Case::parse` refusing `text` (read as `bad.toml`).
pub fn refusal(text: &str) -> String {
    Case::parse(text, "bad.toml").expect_err("the case should be refused").to_string()
}

/// Writes `text` to `dir/name` and returns the path.
pub fn write_case(dir: &Path, name: &str, text: &str) -> PathBuf {
    let path = dir.join(name);
    std::fs::write(&path, text).unwrap();
    path
}
