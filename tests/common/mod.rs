//! Fixtures shared by the integration tests. Each file of `tests/` is its own crate and takes
//! these with `mod common;` (the reproduction crate's tests with `#[path]`): the `slurry`
//! binary, case files built from their required sections, and the messages of refused cases.
//!
//! (The library's unit tests, `src/case/tests.rs`, keep their own case text: they are compiled
//! into the library, where this module, which names the binary, does not exist.)

// Each test crate uses a part of these.
#![allow(dead_code)]

use std::path::{Path, PathBuf};
use std::process::{Command, Output};
use std::sync::OnceLock;
use std::time::SystemTime;

use slurry::case::Case;

/// The repository's root, where the commands of the tests run (so that `examples/…` and
/// `reproduce/…` paths resolve): this package's directory, or its parent for the
/// reproduction crate (`reproduce/`).
pub fn root() -> &'static Path {
    let dir = Path::new(env!("CARGO_MANIFEST_DIR"));
    if dir.join("xtask").is_dir() {
        dir
    } else {
        dir.parent().expect("reproduce/ has a parent directory")
    }
}

/// The `slurry` binary of this build. The reproduction crate builds it, so its tests get it
/// from cargo (`CARGO_BIN_EXE_slurry`); the solver's tests find it beside their own
/// executable's directory, where `cargo test --workspace` (or `cargo test` at the root, whose
/// default members are both crates) links it. A binary older than the solver library it
/// should contain is refused, so that a test never runs yesterday's binary.
pub fn bin() -> &'static Path {
    static BIN: OnceLock<PathBuf> = OnceLock::new();
    BIN.get_or_init(|| {
        if let Some(p) = option_env!("CARGO_BIN_EXE_slurry") {
            return PathBuf::from(p);
        }
        let exe = std::env::current_exe().expect("the test's executable");
        let deps = exe.parent().expect("target/PROFILE/deps");
        let bin =
            deps.parent().expect("target/PROFILE").join(format!("slurry{}", std::env::consts::EXE_SUFFIX));
        let modified = |p: &Path| std::fs::metadata(p).and_then(|m| m.modified()).ok();
        let built = modified(&bin).unwrap_or_else(|| {
            panic!(
                "{} is not built: the solver's integration tests run the binary of the reproduction crate; \
                 run them with `cargo test --workspace` (or `cargo test` at the root)",
                bin.display()
            )
        });
        // The newest build of the library in this profile.
        let library: Option<SystemTime> = std::fs::read_dir(deps)
            .into_iter()
            .flatten()
            .flatten()
            .filter(|e| {
                let name = e.file_name().to_string_lossy().into_owned();
                name.starts_with("libslurry-") && name.ends_with(".rlib")
            })
            .filter_map(|e| modified(&e.path()))
            .max();
        if let Some(library) = library {
            assert!(
                built >= library,
                "{} is older than the slurry library: rebuild it with `cargo test --workspace` \
                 (or `cargo build -p slurry-reproduce`) before running these tests",
                bin.display()
            );
        }
        bin
    })
}

/// Runs `slurry ARGS` in the repository's root ([`root`]) and waits.
pub fn slurry(args: &[&str]) -> Output {
    Command::new(bin()).args(args).current_dir(root()).output().expect("the slurry binary runs")
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

/// The small stirred tank of `examples/stirred_tank_particles.toml` (a PBT above 26 free
/// cylinders with contacts in a closed 36³ box), with the lines `run` as its `[run]` table and
/// the lines `contacts` added to its `[contacts]` table.
pub fn stirred_tank(run: &str, contacts: &str) -> String {
    let text = std::fs::read_to_string(root().join("examples/stirred_tank_particles.toml"))
        .expect("examples/stirred_tank_particles.toml");
    let text = text.replacen("steps = 400\noutput_every = 50\n", &format!("{}\n", run.trim()), 1);
    text.replacen("[contacts]\n", &format!("[contacts]\n{}\n", contacts.trim()), 1)
}
