//! Build script: embeds the git revision of the checkout being built
//! (`git describe --always --dirty --abbrev=12`) as `SLURRY_BUILD_REVISION`, so that a run's
//! `manifest.json` names the build that ran it, not whatever the checkout holds at run time.
//! Empty when git cannot tell (a source tarball); the manifest then says `"unknown"`.

use std::path::Path;
use std::process::Command;

fn git(args: &[&str]) -> Option<String> {
    let o = Command::new("git").args(args).output().ok()?;
    o.status.success().then(|| String::from_utf8_lossy(&o.stdout).trim().to_string())
}

fn main() {
    let rev = git(&["describe", "--always", "--dirty", "--abbrev=12"]).unwrap_or_default();
    println!("cargo:rustc-env=SLURRY_BUILD_REVISION={rev}");
    // Rebuilt when HEAD moves (a checkout or a commit) and when the sources change (`--dirty`).
    // Only existing paths are named: a missing one would rerun this script on every build.
    if let Some(dir) = git(&["rev-parse", "--git-dir"]) {
        let dir = Path::new(&dir);
        let mut watch = vec![dir.join("HEAD"), dir.join("packed-refs")];
        if let Some(r) = git(&["symbolic-ref", "-q", "HEAD"]) {
            watch.push(dir.join(r));
        }
        for p in watch.iter().filter(|p| p.exists()) {
            println!("cargo:rerun-if-changed={}", p.display());
        }
    }
    println!("cargo:rerun-if-changed=src");
    println!("cargo:rerun-if-changed=Cargo.toml");
    println!("cargo:rerun-if-changed=build.rs");
}
