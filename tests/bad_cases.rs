//! The bad-input corpus (issue 15): `slurry check` on every file of `tests/bad_cases/*.toml`
//! must exit with status 2, print a message naming the file and the key of the file's first
//! line (`# expect: KEY`), and neither panic nor die by a signal (an allocation failure
//! aborted with SIGABRT; `memory allocation of N bytes failed`).
//!
//! The corpus runs with `SLURRY_MEMORY_LIMIT=1G`, so that the cases refused for their memory
//! (a 600³ f64 grid, half a billion particles) are refused on any machine.

use std::path::PathBuf;
use std::process::Command;
use std::time::{Duration, Instant};

mod common;

use common::bin;

/// Every corpus file, sorted.
fn corpus() -> Vec<PathBuf> {
    let dir = PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("tests").join("bad_cases");
    let mut files: Vec<PathBuf> = std::fs::read_dir(&dir)
        .unwrap()
        .map(|e| e.unwrap().path())
        .filter(|p| p.extension().is_some_and(|x| x == "toml"))
        .collect();
    files.sort();
    files
}

/// The key of the first line `# expect: KEY`.
fn expected_key(path: &PathBuf) -> String {
    let text = std::fs::read_to_string(path).unwrap();
    let first = text.lines().next().unwrap_or("");
    first
        .strip_prefix("# expect:")
        .unwrap_or_else(|| panic!("{}: the first line must be `# expect: KEY`", path.display()))
        .trim()
        .to_string()
}

#[test]
fn every_bad_case_is_refused_with_status_2_naming_file_and_key() {
    let files = corpus();
    assert!(files.len() >= 25, "the corpus has only {} files", files.len());
    let mut failures = Vec::new();
    for path in &files {
        let key = expected_key(path);
        let t0 = Instant::now();
        let out = Command::new(bin())
            .arg("check")
            .arg(path)
            .env("SLURRY_MEMORY_LIMIT", "1G")
            .env_remove("RUST_BACKTRACE")
            .output()
            .unwrap();
        let took = t0.elapsed();
        let stderr = String::from_utf8_lossy(&out.stderr);
        let name = path.display().to_string();
        let mut why = Vec::new();
        match out.status.code() {
            Some(2) => {}
            Some(c) => why.push(format!("exit status {c}, not 2")),
            None => why.push("killed by a signal".to_string()),
        }
        if !stderr.contains(&name) {
            why.push("the message does not name the file".to_string());
        }
        if !stderr.contains(&key) {
            why.push(format!("the message does not name the key `{key}`"));
        }
        if stderr.contains("panicked")
            || stderr.contains("RUST_BACKTRACE")
            || stderr.contains("memory allocation")
        {
            why.push("it panicked or aborted".to_string());
        }
        if stderr.lines().count() > 3 {
            why.push(format!("{} lines of stderr", stderr.lines().count()));
        }
        if took > Duration::from_secs(10) {
            why.push(format!("it took {took:?}"));
        }
        if !why.is_empty() {
            failures.push(format!("{name}: {}\n  stderr: {}", why.join("; "), stderr.trim()));
        }
    }
    assert!(failures.is_empty(), "{} of {} bad cases:\n{}", failures.len(), files.len(), failures.join("\n"));
}
