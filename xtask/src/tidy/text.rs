//! The text rules: file length, nothing disabled or left in.

use std::fs;
use std::path::Path;

use super::{Problem, MAX_LINES};

/// A file past [`MAX_LINES`] that `allowed` does not name.
pub fn check_length(path: &str, text: &str, allowed: &[(&str, &str)]) -> Vec<Problem> {
    let lines = text.lines().count();
    if lines <= MAX_LINES || allowed.iter().any(|(p, _)| *p == path) {
        return Vec::new();
    }
    vec![Problem::new(
        path,
        0,
        format!(
            "{lines} lines, more than {MAX_LINES}: split it by what it holds \
             (or add it to tidy.rs's LONG_FILES with the reason)"
        ),
    )]
}

/// Entries of `allowed` that are no longer needed (file gone, or now within [`MAX_LINES`]).
pub fn check_stale_long_files(root: &Path, allowed: &[(&str, &str)]) -> Vec<Problem> {
    let mut problems = Vec::new();
    for (path, _) in allowed {
        let lines = fs::read_to_string(root.join(path)).map(|t| t.lines().count()).ok();
        if lines.is_none_or(|n| n <= MAX_LINES) {
            problems.push(Problem::new(
                "xtask/src/tidy.rs",
                0,
                format!(
                    "LONG_FILES names {path}, which is not longer than {MAX_LINES} lines: remove the entry"
                ),
            ));
        }
    }
    problems
}

/// The strings no code may hold (built from pieces so that this file does not hold them).
fn forbidden() -> [(String, &'static str); 3] {
    [
        (format!("#[{}", "ignore"), "an ignored test: assert the present value with a note naming the issue"),
        (format!("{}!(", "todo"), "unfinished code"),
        (format!("{}!(", "dbg"), "debug output left in"),
    ]
}

/// Each line of `text` holding a forbidden string.
pub fn check_forbidden(path: &str, text: &str) -> Vec<Problem> {
    let patterns = forbidden();
    let mut problems = Vec::new();
    for (i, line) in text.lines().enumerate() {
        for (pattern, why) in &patterns {
            if line.contains(pattern.as_str()) {
                problems.push(Problem::new(path, i + 1, format!("`{pattern}`: {why}")));
            }
        }
    }
    problems
}
