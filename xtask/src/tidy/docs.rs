//! The lists in the docs (modules, verification cases), and what user documents and rustdoc
//! may not hold: dates and issue numbers in the code's comments, paths outside the repository.

use std::collections::BTreeSet;
use std::fs;
use std::path::Path;

use super::table::is_ident_byte;
use super::Problem;

/// The top-level modules of `src/`: `X.rs` (not `lib.rs` or `main.rs`) and `X/mod.rs`.
pub fn src_modules(src: &Path) -> BTreeSet<String> {
    let mut modules = BTreeSet::new();
    let Ok(entries) = fs::read_dir(src) else { return modules };
    for entry in entries.flatten() {
        let path = entry.path();
        let Some(name) = path.file_name().and_then(|n| n.to_str()).map(str::to_string) else { continue };
        if path.is_dir() && path.join("mod.rs").is_file() {
            modules.insert(name);
        } else if let Some(stem) = name.strip_suffix(".rs") {
            if stem != "lib" && stem != "main" {
                modules.insert(stem.to_string());
            }
        }
    }
    modules
}

/// The verification cases: the files of `verification/src/cases/` but `mod.rs`.
pub fn verification_cases(dir: &Path) -> BTreeSet<String> {
    let Ok(entries) = fs::read_dir(dir) else { return BTreeSet::new() };
    entries
        .flatten()
        .filter_map(|e| e.file_name().to_str().and_then(|n| n.strip_suffix(".rs")).map(str::to_string))
        .filter(|n| n != "mod")
        .collect()
}

/// The top-level module of a file under the source folder `src` (given with its `/`), the crate
/// root's files counting as `lib` and `main`: `src/lbm/fluid.rs` → `lbm`, `src/run.rs` → `run`,
/// `reproduce/src/stats/mod.rs` → `stats`; none outside `src`.
pub fn module_under(rel: &str, src: &str) -> Option<String> {
    let rest = rel.strip_prefix(src)?;
    let first = rest.split('/').next()?;
    Some(first.strip_suffix(".rs").unwrap_or(first).to_string())
}

/// The `//!` lines of `text`, joined.
pub fn doc_text(text: &str) -> String {
    text.lines().filter_map(|l| l.trim_start().strip_prefix("//!")).collect::<Vec<_>>().join("\n")
}

/// `src/lib.rs` declares every module and links it (`` [`X`] ``) in its module docs.
pub fn check_lib_docs(path: &str, text: &str, modules: &BTreeSet<String>) -> Vec<Problem> {
    let docs = doc_text(text);
    let mut problems = Vec::new();
    for m in modules {
        if !docs.contains(&format!("[`{m}`]")) {
            problems.push(Problem::new(path, 1, format!("the module docs do not list [`{m}`]")));
        }
        let declared = text.lines().any(|l| {
            let l = l.trim();
            l == format!("pub mod {m};") || l == format!("mod {m};")
        });
        if !declared {
            problems.push(Problem::new(
                path,
                0,
                format!("src/ holds module `{m}`, which is not declared here"),
            ));
        }
    }
    problems
}

/// The README's "## Layout" section names every module as `src/X` (or `src/X.rs`).
pub fn check_readme_layout(path: &str, text: &str, modules: &BTreeSet<String>) -> Vec<Problem> {
    let lines: Vec<&str> = text.lines().collect();
    let Some(start) = lines.iter().position(|l| l.trim() == "## Layout") else {
        return vec![Problem::new(path, 0, "no \"## Layout\" section")];
    };
    let end =
        lines[start + 1..].iter().position(|l| l.starts_with("## ")).map_or(lines.len(), |i| start + 1 + i);
    let section = lines[start..end].join("\n");
    let mut problems = Vec::new();
    for m in modules {
        let named = section
            .match_indices(&format!("src/{m}"))
            .any(|(i, s)| section[i + s.len()..].bytes().next().is_none_or(|b| !is_ident_byte(b)));
        if !named {
            problems.push(Problem::new(path, start + 1, format!("the layout does not name `src/{m}`")));
        }
    }
    problems
}

/// Each of `items` is listed in `text` (by `listed`), else a problem naming it.
pub fn check_listed(
    path: &str,
    text: &str,
    items: &BTreeSet<String>,
    listed: impl Fn(&str, &str) -> bool,
) -> Vec<Problem> {
    items
        .iter()
        .filter(|item| !listed(item, text))
        .map(|item| Problem::new(path, 0, format!("does not list the verification case `{item}`")))
        .collect()
}

/// The places a user reads that may name no path outside the repository: the user documents,
/// and the comments (rustdoc included) of both crates' sources ([`COMMENT_DIRS`]).
pub const USER_DOCS: &[&str] = &[
    "README.md",
    "ARCHITECTURE.md",
    "CHANGELOG.md",
    "docs",
    "reproduce/README.md",
    "benches/results/README.md",
    "benches/scripts/README.md",
];

/// The source folders whose comments say what the code does: no dates, no issue numbers (the
/// history is in `reproduce/JOURNAL.md`, the changelog and the commits).
pub const COMMENT_DIRS: &[&str] = &["src", "reproduce/src"];

/// Paths that lead out of the repository: the shared folder beside it, home and scratch
/// directories, the machine's work folder.
const OUTSIDE: &[&str] = &[
    "../shared",
    "shared/bench",
    "shared/spec",
    "shared/paper",
    "~/",
    "/work/",
    "/tmp/",
    "/home/",
    "/root/",
];

/// The comment of a line of Rust (from its first `//`), if it has one. A `//` inside a string
/// literal counts too: the rules below are for prose, and strings rarely hold any.
fn comment_of(line: &str) -> Option<&str> {
    line.find("//").map(|i| &line[i..])
}

/// Each ISO date (`YYYY-MM-DD`) in `text` that is not part of a path or file name (preceded by
/// `/`, or followed by `-`: the archives' and records' names are dated).
pub fn loose_dates(text: &str) -> Vec<&str> {
    let b = text.as_bytes();
    let digits = |r: std::ops::Range<usize>| r.clone().all(|k| b.get(k).is_some_and(u8::is_ascii_digit));
    let mut found = Vec::new();
    for i in 0..b.len().saturating_sub(9) {
        let date = digits(i..i + 4)
            && b[i + 4] == b'-'
            && digits(i + 5..i + 7)
            && b[i + 7] == b'-'
            && digits(i + 8..i + 10);
        let inside_number =
            (i > 0 && b[i - 1].is_ascii_digit()) || b.get(i + 10).is_some_and(u8::is_ascii_digit);
        let in_name = (i > 0 && b[i - 1] == b'/') || b.get(i + 10) == Some(&b'-');
        if date && !inside_number && !in_name {
            found.push(&text[i..i + 10]);
        }
    }
    found
}

/// Whether `text` names an issue by number (`issue 12`, `Issue #12`).
pub fn names_an_issue(text: &str) -> bool {
    let lower = text.to_ascii_lowercase();
    lower.match_indices("issue").any(|(i, _)| {
        let rest = lower[i + "issue".len()..].trim_start_matches([' ', '#']);
        rest.len() < lower.len() - i - "issue".len()
            && rest.bytes().next().is_some_and(|b| b.is_ascii_digit())
    })
}

/// The comment lines of `text` (a Rust file of [`COMMENT_DIRS`]) that hold a date or an issue
/// number.
pub fn check_comment_history(path: &str, text: &str) -> Vec<Problem> {
    let mut problems = Vec::new();
    for (i, line) in text.lines().enumerate() {
        let Some(comment) = comment_of(line) else { continue };
        if let Some(date) = loose_dates(comment).first() {
            problems.push(Problem::new(
                path,
                i + 1,
                format!("a date ({date}) in a comment: say what the code does; history goes to reproduce/JOURNAL.md"),
            ));
        }
        if names_an_issue(comment) {
            problems.push(Problem::new(
                path,
                i + 1,
                "an issue number in a comment: say what the code does; history goes to the changelog and the commits",
            ));
        }
    }
    problems
}

/// The lines of `text` (a user document, or with `rust` the comments of a Rust file) that name a
/// path outside the repository.
pub fn check_outside_paths(path: &str, text: &str, rust: bool) -> Vec<Problem> {
    let mut problems = Vec::new();
    for (i, line) in text.lines().enumerate() {
        let prose = if rust { comment_of(line) } else { Some(line) };
        let Some(prose) = prose else { continue };
        if let Some(p) = OUTSIDE.iter().find(|p| prose.contains(*p)) {
            problems.push(Problem::new(
                path,
                i + 1,
                format!("`{p}`: a path outside the repository, which a user of a clone does not have"),
            ));
        }
    }
    problems
}

/// The two crates' layering: the solver (its sources, tests, benches and examples, its build
/// script and the verification suite) never names the reproduction, whose crate uses it, and no
/// manifest but the reproduction's own depends on it.
pub fn check_crate_layering(root: &Path, solver_files: &[(String, String)]) -> Vec<Problem> {
    let mut problems = Vec::new();
    for (rel, text) in solver_files {
        let code = super::table::strip_comments_and_strings(text);
        if let Some(i) = code.lines().position(|l| l.contains("slurry_reproduce")) {
            problems.push(Problem::new(
                rel.as_str(),
                i + 1,
                "the solver uses the reproduction crate (`slurry_reproduce`): the reproduction uses the solver, never \
                 the reverse; move the code into reproduce/",
            ));
        }
    }
    for manifest in ["Cargo.toml", "verification/Cargo.toml"] {
        let Ok(text) = fs::read_to_string(root.join(manifest)) else { continue };
        if let Some(i) = text.lines().position(|l| l.trim_start().starts_with("slurry-reproduce")) {
            problems.push(Problem::new(
                manifest,
                i + 1,
                "depends on `slurry-reproduce`: only the reproduction's own crate may (the solver is below it)",
            ));
        }
    }
    problems
}
