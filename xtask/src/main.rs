//! Repository tasks, run as `cargo xtask <command>` (alias in `.cargo/config.toml`).
//!
//! Std only, and no dependency on `slurry`, so that it builds in seconds on a fresh machine
//! (before the system libraries `slurry` links are even installed).
//!
//! - `setup`: installs the system packages the build and the tests need if missing: libhdf5-dev
//!   and pkg-config (the hdf5 crate), libvulkan1 (the Vulkan loader) and mesa-vulkan-drivers
//!   (lavapipe, the CPU's Vulkan driver, on which the device backend's tests run without a GPU).
//! - `ci`: the test command (`.ci/run`): tidy, setup, fmt, clippy, rustdoc, tests, verification
//!   (quick tier, on the CPU and, for the cases that run there, on the device).
//! - `tidy`: the repository's rules as code (imports against ARCHITECTURE.md's module table,
//!   modules and verification cases listed in the docs, file length, nothing disabled; see
//!   `tidy.rs`).
//! - `verify [ARGS...]`: setup, then the verification suite (`slurry-verify ARGS...`).
//! - `reproduce ARGS...`: setup, then `slurry reproduce ARGS...` in release (the paper's cases).
//! - `bench [--quick] [--no-peer] [ARGS...]`: kernel MLUPS beside the bandwidth ceiling and the
//!   lbmpy peer (see `bench.rs`).

mod bench;
mod tidy;

use std::env;
use std::path::{Path, PathBuf};
use std::process::{Command, ExitCode};
use std::time::Instant;

const HELP: &str = "\
usage: cargo xtask <command> [args]

commands:
  ci               tidy, setup, cargo fmt --check, clippy -D warnings, rustdoc -D warnings, cargo test,
                   verification (quick)
  tidy             repository rules: imports against ARCHITECTURE.md's module table, modules and
                   verification cases listed in the docs, file length, no ignored tests/todo/dbg
  verify [ARGS]    setup, then `slurry-verify ARGS` (try `cargo xtask verify --help`)
  reproduce CASE [--scale S] [--revolutions R] [--until-steady CAP] [--bed dry|wet] [--quick] [--out DIR] [--resume] [--all]
                   setup, then the paper's case CASE (pbt-ld2, ...): bed, run, statistics,
                   figures and report.md (default: scale 1/4 to steady state, 1–2.5 h on 2 cores)
  setup            install libhdf5-dev, pkg-config, libvulkan1 and mesa-vulkan-drivers with apt-get if missing
  bench [--quick] [--no-peer] [ARGS]
                   fused-kernel MLUPS beside membw.sh and the lbmpy peer; ARGS go to `slurry bench`
  bench --coupled [--scales 0.25,0.5,1] [--cases pbt-ld2,...] [--steps N] [--warmup N]
                   the paper's cases' coupled step per phase beside their fluid-only step and
                   membw.sh, into target/bench/coupled.json (full-scale beds are made once: 10–16 min each);
                   --from RUN/run/checkpoint.h5 (one case, one scale) times it from a run's state
";

/// A failed step: what failed (`main` prints it and exits 1).
struct Failed(String);

type Step = Result<(), Failed>;

fn main() -> ExitCode {
    let mut args = env::args().skip(1);
    let cmd = args.next();
    let rest: Vec<String> = args.collect();
    let root = workspace_root();
    let t0 = Instant::now();
    let result = match cmd.as_deref() {
        Some("ci") => ci(&root),
        Some("tidy") => tidy::tidy(&root).map_err(Failed),
        Some("verify") => setup().and_then(|()| verify(&root, &rest)),
        Some("setup") => setup(),
        Some("reproduce") => setup().and_then(|()| reproduce(&root, &rest)),
        Some("bench") => setup().and_then(|()| bench::bench(&root, &rest).map_err(Failed)),
        Some("help" | "--help" | "-h") | None => {
            print!("{HELP}");
            Ok(())
        }
        Some(other) => Err(Failed(format!("unknown command '{other}'\n{HELP}"))),
    };
    let secs = t0.elapsed().as_secs_f64();
    match result {
        Ok(()) => {
            if cmd.as_deref() == Some("ci") {
                println!("\nxtask ci: all steps passed in {secs:.0} s");
            }
            ExitCode::SUCCESS
        }
        Err(Failed(msg)) => {
            eprintln!("\nxtask: {msg} (after {secs:.0} s)");
            ExitCode::FAILURE
        }
    }
}

/// The workspace root: the parent of this crate's directory.
fn workspace_root() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).parent().expect("xtask/ has a parent directory").to_path_buf()
}

fn cargo() -> Command {
    Command::new(env::var("CARGO").unwrap_or_else(|_| "cargo".into()))
}

fn header(title: &str) {
    println!("\n==> {title}");
}

/// Runs `cmd`, inheriting stdio; a non-zero exit or a failure to start is an error.
fn run(what: &str, mut cmd: Command) -> Step {
    let t = Instant::now();
    let status = cmd.status().map_err(|e| Failed(format!("{what}: cannot start: {e}")))?;
    if status.success() {
        println!("--- {what}: ok ({:.0} s)", t.elapsed().as_secs_f64());
        Ok(())
    } else {
        Err(Failed(format!("{what} failed ({status})")))
    }
}

/// The test command: each step printed as a header; stops at the first failure.
fn ci(root: &Path) -> Step {
    header("tidy: repository rules");
    tidy::tidy(root).map_err(Failed)?;

    header("setup: system packages");
    setup()?;

    header("cargo fmt --all -- --check");
    let mut c = cargo();
    c.current_dir(root).args(["fmt", "--all", "--", "--check"]);
    run("fmt", c)?;

    header("cargo clippy --workspace --all-targets --release -- -D warnings");
    let mut c = cargo();
    c.current_dir(root).args(["clippy", "--workspace", "--all-targets", "--release", "--", "-D", "warnings"]);
    run("clippy", c)?;

    header("cargo doc --workspace --no-deps (rustdoc warnings are errors)");
    let mut c = cargo();
    c.current_dir(root).env("RUSTDOCFLAGS", "-D warnings").args(["doc", "--workspace", "--no-deps"]);
    run("doc", c)?;

    header("cargo test --workspace --release");
    let mut c = cargo();
    c.current_dir(root).args(["test", "--workspace", "--release"]);
    run("test", c)?;

    // The reduced regression's values against the paper, with the archived steady runs'
    // (issue: "print each value against Table 2 ... with the deviation"; nothing asserted).
    if let Ok(md) = std::fs::read_to_string(root.join("target/ci/pbt-ld2-against-the-paper.md")) {
        header("pbt-ld2 against the paper (reproduce/tests/reproduce_regression.rs)");
        print!("{md}");
    }

    // The steady states continued from their packs: values, bands and the paper.
    if let Ok(md) = std::fs::read_to_string(root.join("target/ci/steady-regression.md")) {
        header("steady states at s = 1/4 against their bands and the paper (reproduce/tests/steady_regression.rs)");
        print!("{md}");
    }

    // The tests built target/release/slurry (its integration tests need the binary).
    header("inlining check of the release binary (SIMD paths compiled for their ISA)");
    bench::inlining_guard(root).map_err(Failed)?;

    header("verification, quick tier");
    verify(root, &["--tier".into(), "quick".into()])?;

    // The cases that run on the device, on the CPU's Vulkan driver (lavapipe, `setup`).
    header("verification on the device, quick tier");
    verify(root, &["--tier".into(), "quick".into(), "--device".into(), "gpu".into()])
}

/// `slurry-verify ARGS` in release.
fn verify(root: &Path, args: &[String]) -> Step {
    let mut c = cargo();
    c.current_dir(root)
        .args(["run", "--release", "-p", "slurry-verification", "--bin", "slurry-verify", "--"])
        .args(args);
    run("verify", c)
}

/// `slurry reproduce ARGS` in release.
fn reproduce(root: &Path, args: &[String]) -> Step {
    let mut c = cargo();
    c.current_dir(root)
        .args(["run", "--release", "-p", "slurry-reproduce", "--bin", "slurry", "--", "reproduce"])
        .args(args);
    run("reproduce", c)
}

/// Whether `pkg-config` is present and finds hdf5.
fn hdf5_found() -> bool {
    Command::new("pkg-config").args(["--exists", "hdf5"]).status().map(|s| s.success()).unwrap_or(false)
}

fn is_root() -> bool {
    Command::new("id")
        .arg("-u")
        .output()
        .map(|o| String::from_utf8_lossy(&o.stdout).trim() == "0")
        .unwrap_or(false)
}

/// Whether the Vulkan loader (`libvulkan.so.1`) is installed.
fn vulkan_loader_found() -> bool {
    Command::new("ldconfig")
        .arg("-p")
        .output()
        .map(|o| String::from_utf8_lossy(&o.stdout).contains("libvulkan.so.1"))
        .unwrap_or(false)
        || [
            "/usr/lib/x86_64-linux-gnu/libvulkan.so.1",
            "/usr/lib/aarch64-linux-gnu/libvulkan.so.1",
            "/usr/lib/libvulkan.so.1",
        ]
        .iter()
        .any(|p| Path::new(p).exists())
}

/// Whether a Vulkan driver is registered (an ICD manifest: a GPU's driver, or lavapipe).
fn vulkan_driver_found() -> bool {
    ["/usr/share/vulkan/icd.d", "/etc/vulkan/icd.d", "/usr/local/share/vulkan/icd.d"].iter().any(|d| {
        std::fs::read_dir(d)
            .map(|es| es.flatten().any(|e| e.path().extension().is_some_and(|x| x == "json")))
            .unwrap_or(false)
    })
}

/// Installs with apt-get what is missing of: libhdf5-dev and pkg-config (unless pkg-config
/// finds hdf5), libvulkan1 (unless the Vulkan loader is there) and mesa-vulkan-drivers (unless
/// a Vulkan driver is registered: a GPU's own, or lavapipe).
fn setup() -> Step {
    let mut packages = Vec::new();
    if !hdf5_found() {
        packages.extend(["libhdf5-dev", "pkg-config"]);
    }
    if !vulkan_loader_found() {
        packages.push("libvulkan1");
    }
    if !vulkan_driver_found() {
        packages.push("mesa-vulkan-drivers");
    }
    if packages.is_empty() {
        println!("hdf5 found by pkg-config, a Vulkan loader and driver found: nothing to install");
        return Ok(());
    }
    println!(
        "installing {} with apt-get (hdf5 for the hdf5 crate; the Vulkan loader and lavapipe for the device backend)",
        packages.join(" ")
    );
    let apt = |args: &[&str]| {
        let mut c = if is_root() {
            Command::new("apt-get")
        } else {
            let mut c = Command::new("sudo");
            c.arg("apt-get");
            c
        };
        c.env("DEBIAN_FRONTEND", "noninteractive").args(args);
        c
    };
    run("apt-get update", apt(&["update"]))?;
    let mut install = vec!["install", "-y"];
    install.extend(&packages);
    run("apt-get install", apt(&install))?;
    if !hdf5_found() {
        return Err(Failed("after installing libhdf5-dev, `pkg-config --exists hdf5` still fails".into()));
    }
    if !vulkan_loader_found() || !vulkan_driver_found() {
        return Err(Failed(
            "after installing libvulkan1 and mesa-vulkan-drivers, no Vulkan loader or driver is found".into(),
        ));
    }
    Ok(())
}
