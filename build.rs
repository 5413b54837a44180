//! Build script: embeds the git revision of the checkout being built
//! (`git describe --always --dirty --abbrev=12`) as `SLURRY_BUILD_REVISION`, so that a run's
//! `manifest.json` names the build that ran it, not whatever the checkout holds at run time.
//! Empty when the package is not the top of a git work tree (a source tarball, a vendored
//! copy, `cargo package`'s copy inside this checkout): the manifest then says `"unknown"`.
//!
//! **When it reruns** (and so, the value having changed, the package is rebuilt):
//! - HEAD moves: a commit, checkout, reset or pull writes `logs/HEAD` of the work tree (in a
//!   linked worktree its own, under `.git/worktrees/NAME`); `HEAD` itself is watched too, for a
//!   repository without reflogs (then a commit on the current branch is seen through the
//!   branch's loose ref or `packed-refs` of the common directory);
//! - any file compiled into the binary changes (`-dirty`): `src` and `reproduce/src` (the
//!   reproduction crate, which builds the binary), the paper cases' `case.toml` and
//!   `paper.toml` (`include_str!`), `assets` (the plot font), the `Cargo.toml`s, `Cargo.lock`.
//!
//! An edit elsewhere (a README) does not rerun it, so `-dirty` can lag behind such edits; it
//! never misses one to what is compiled in. Git's optional index lock is not taken
//! (`GIT_OPTIONAL_LOCKS=0`), so a background build does not collide with the user's git.

use std::path::{Path, PathBuf};
use std::process::Command;

fn git(args: &[&str]) -> Option<String> {
    let o = Command::new("git").args(args).env("GIT_OPTIONAL_LOCKS", "0").output().ok()?;
    o.status.success().then(|| String::from_utf8_lossy(&o.stdout).trim().to_string())
}

fn main() {
    let manifest_dir = PathBuf::from(std::env::var("CARGO_MANIFEST_DIR").unwrap_or_default());
    let top = git(&["rev-parse", "--show-toplevel"]).map(PathBuf::from);
    let same = |a: &Path, b: &Path| match (a.canonicalize(), b.canonicalize()) {
        (Ok(a), Ok(b)) => a == b,
        _ => false,
    };
    let ours = top.as_deref().is_some_and(|t| same(t, &manifest_dir));
    let rev = if ours {
        git(&["describe", "--always", "--dirty", "--abbrev=12"]).unwrap_or_default()
    } else {
        String::new()
    };
    println!("cargo:rustc-env=SLURRY_BUILD_REVISION={rev}");
    if ours {
        let mut watch: Vec<PathBuf> = ["logs/HEAD", "HEAD"]
            .iter()
            .filter_map(|p| git(&["rev-parse", "--git-path", p]))
            .map(PathBuf::from)
            .collect();
        if let Some(common) = git(&["rev-parse", "--git-common-dir"]) {
            let common = PathBuf::from(common);
            watch.push(common.join("packed-refs"));
            if let Some(r) = git(&["symbolic-ref", "-q", "HEAD"]) {
                watch.push(common.join(r));
            }
        }
        // Only existing paths: a missing one would rerun this script on every build.
        for p in watch.iter().filter(|p| p.exists()) {
            println!("cargo:rerun-if-changed={}", p.display());
        }
    }
    for p in
        ["src", "assets", "Cargo.toml", "Cargo.lock", "build.rs", "reproduce/src", "reproduce/Cargo.toml"]
    {
        println!("cargo:rerun-if-changed={p}");
    }
    for case in ["disk-ld1", "disk-ld2", "disk-ld4", "pbt-ld1", "pbt-ld2", "pbt-ld4"] {
        for f in ["case.toml", "paper.toml"] {
            println!("cargo:rerun-if-changed=reproduce/{case}/{f}");
        }
    }
}
