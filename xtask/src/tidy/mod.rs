//! `cargo xtask tidy`: the repository's rules as code, in the spirit of rust-analyzer's
//! `xtask/src/tidy.rs`. Cheap (reads text, builds nothing), so `cargo xtask ci` runs it first.
//!
//! The rules:
//! - **Two crates, one direction.** The solver (`slurry`: `src/`, its tests, benches, examples
//!   and build script, and the verification suite) never names the reproduction
//!   (`slurry_reproduce`), and no manifest but the reproduction's depends on it
//!   ([`docs::check_crate_layering`]).
//! - **Imports follow ARCHITECTURE.md.** Its two module tables ("## Module map" for the solver,
//!   "## Module map of the reproduction" for `reproduce/src/`) are the one source of truth: the
//!   "knows about" column names, in backticks, the modules each module may use. Every
//!   `crate::X` path in a file of `src/<module>/` (comments left out) must name the module
//!   itself or one listed in its row; in `reproduce/src/<module>/` the same for `crate::X` (or
//!   `slurry_reproduce::X`; an item of the crate root counts as `lib`) and for the solver's
//!   modules, `slurry::X`, which its rows list as `slurry::X`. The solver's table keeps the
//!   layering: the fluid (`lbm`) lists no particle module (`rigid`, `contact`, `ibm`) and those
//!   list no fluid, and in the core ([`CORE`]) only `coupling` lists both sides. Each table
//!   must be one piece (a blank line inside it turns the rows after it into a paragraph) with
//!   as many cells in each row as in its header (an unescaped `|` adds one).
//! - **Every module and every verification case is listed where the docs list them**: each
//!   module of either crate has a row in its table (and a row names a module that exists); each
//!   top-level module of `src/` is declared and linked in `src/lib.rs` and named in the
//!   README's "## Layout"; each file of `verification/src/cases/` is linked in
//!   `verification/src/lib.rs`'s docs and registered in `cases::all()`.
//! - **Comments say what the code does**: no dates (but in the names of dated archives and
//!   records) and no issue numbers in the comments of `src/` and `reproduce/src/`
//!   ([`docs::check_comment_history`]).
//! - **No paths outside the repository** in the user documents ([`docs::USER_DOCS`]) and in
//!   those comments ([`docs::check_outside_paths`]).
//! - **Files stay short**: at most [`MAX_LINES`] lines, except the few in [`LONG_FILES`], each
//!   with its reason (an entry that is no longer needed is an error too, so the list stays short).
//! - **Nothing disabled or left in**: no ignored tests, `todo` or `dbg` macros in any code
//!   folder ([`CODE_DIRS`]).
//!
//! Each problem is printed as `path:line: message`; all are reported, then tidy fails if any.

mod docs;
mod table;
#[cfg(test)]
mod tests;
mod text;

use std::collections::BTreeSet;
use std::fmt;
use std::fs;
use std::path::{Path, PathBuf};

use docs::{
    check_comment_history, check_crate_layering, check_lib_docs, check_listed, check_outside_paths,
    check_readme_layout, doc_text, module_under, src_modules, verification_cases, COMMENT_DIRS, USER_DOCS,
};
use table::{
    check_imports, check_table_layering, parse_module_table, paths_after, ModuleTable, REPRODUCE_HEADING,
    SOLVER_PREFIX, TABLE_HEADING,
};
use text::{check_forbidden, check_length, check_stale_long_files};

/// The longest a `.rs` file may be, in lines, unless it is in [`LONG_FILES`].
pub const MAX_LINES: usize = 1000;

/// Files allowed past [`MAX_LINES`], each with the reason. Keep it short: split a file by what it
/// holds rather than add it here.
pub const LONG_FILES: &[(&str, &str)] = &[];

/// The core layers, below the drivers: among these only `coupling` may know both the fluid and
/// the particles. (`case`, `io`, `drive`, `run` and `settle` sit above the core and assemble
/// it.) (`util`, seeded random numbers and compensated sums, is a leaf every layer may use.)
pub const CORE: &[&str] = &["lattice", "util", "lbm", "ibm", "rigid", "contact", "coupling"];
/// The fluid side of the core.
pub const FLUID: &[&str] = &["lbm"];
/// The particle side of the core.
pub const PARTICLES: &[&str] = &["rigid", "contact", "ibm"];

/// The directories whose `.rs` files the text rules (length, nothing disabled) read.
const CODE_DIRS: &[&str] = &["src", "tests", "verification", "xtask", "benches", "examples", "reproduce"];

/// The solver's code: every `.rs` file here (and `build.rs`) must leave the reproduction alone.
const SOLVER_DIRS: &[&str] = &["src", "tests", "benches", "examples", "verification"];

/// The reproduction crate's sources.
const REPRODUCE_SRC: &str = "reproduce/src";

/// One broken rule, at a place.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Problem {
    /// The file, relative to the repository root.
    pub path: PathBuf,
    /// 1-based line (0: the file as a whole).
    pub line: usize,
    /// What is wrong and what to do.
    pub message: String,
}

impl Problem {
    fn new(path: impl Into<PathBuf>, line: usize, message: impl Into<String>) -> Self {
        Self { path: path.into(), line, message: message.into() }
    }
}

impl fmt::Display for Problem {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        if self.line == 0 {
            write!(f, "{}: {}", self.path.display(), self.message)
        } else {
            write!(f, "{}:{}: {}", self.path.display(), self.line, self.message)
        }
    }
}

/// Runs every rule on the repository at `root`; prints each problem and fails if there is any.
pub fn tidy(root: &Path) -> Result<(), String> {
    let problems = check_repository(root);
    if problems.is_empty() {
        println!("--- tidy: ok");
        return Ok(());
    }
    for p in &problems {
        eprintln!("{p}");
    }
    Err(format!("tidy: {} problem(s)", problems.len()))
}

/// Every rule, on the files under `root`.
pub fn check_repository(root: &Path) -> Vec<Problem> {
    let mut problems = Vec::new();
    let read = |rel: &str, problems: &mut Vec<Problem>| match fs::read_to_string(root.join(rel)) {
        Ok(text) => Some(text),
        Err(e) => {
            problems.push(Problem::new(rel, 0, format!("cannot read: {e}")));
            None
        }
    };

    // The module tables and the imports.
    let modules = src_modules(&root.join("src"));
    let mut reproduce_modules = src_modules(&root.join(REPRODUCE_SRC));
    reproduce_modules.extend(["lib".to_string(), "main".to_string()]);
    if let Some(text) = read("ARCHITECTURE.md", &mut problems) {
        let (solver, found) = parse_module_table("ARCHITECTURE.md", &text, TABLE_HEADING);
        problems.extend(found);
        let (reproduction, found) = parse_module_table("ARCHITECTURE.md", &text, REPRODUCE_HEADING);
        problems.extend(found);
        problems.extend(check_table_layering(&solver));
        problems.extend(check_rows(&solver, &modules, "src/"));
        problems.extend(check_rows(&reproduction, &reproduce_modules, "reproduce/src/"));
        for (module, row) in &reproduction.rows {
            for known in row.knows.iter().filter_map(|k| k.strip_prefix(SOLVER_PREFIX)) {
                if !solver.rows.contains_key(known) {
                    problems.push(Problem::new(
                        "ARCHITECTURE.md",
                        row.line,
                        format!("`{module}` knows about `slurry::{known}`, which has no row in the solver's table"),
                    ));
                }
            }
        }
        for file in rust_files(&root.join("src")) {
            let rel = relative(root, &file);
            let Some(module) = module_under(&rel, "src/").filter(|m| m != "lib" && m != "main") else {
                continue;
            };
            if let Ok(text) = fs::read_to_string(&file) {
                let uses = paths_after(&text, "crate::");
                problems.extend(check_imports(&rel, &module, &uses, &solver));
            }
        }
        for file in rust_files(&root.join(REPRODUCE_SRC)) {
            let rel = relative(root, &file);
            let Some(module) = module_under(&rel, "reproduce/src/") else { continue };
            if let Ok(text) = fs::read_to_string(&file) {
                let uses = reproduction_uses(&text, &reproduce_modules, &modules);
                problems.extend(check_imports(&rel, &module, &uses, &reproduction));
            }
        }
    }

    // The two crates.
    let mut solver_files = Vec::new();
    for dir in SOLVER_DIRS {
        for file in rust_files(&root.join(dir)) {
            if let Ok(text) = fs::read_to_string(&file) {
                solver_files.push((relative(root, &file), text));
            }
        }
    }
    if let Ok(text) = fs::read_to_string(root.join("build.rs")) {
        solver_files.push(("build.rs".to_string(), text));
    }
    problems.extend(check_crate_layering(root, &solver_files));

    // The lists in the docs.
    if let Some(lib) = read("src/lib.rs", &mut problems) {
        problems.extend(check_lib_docs("src/lib.rs", &lib, &modules));
    }
    if let Some(readme) = read("README.md", &mut problems) {
        problems.extend(check_readme_layout("README.md", &readme, &modules));
    }
    let cases = verification_cases(&root.join("verification/src/cases"));
    if let Some(lib) = read("verification/src/lib.rs", &mut problems) {
        problems.extend(check_listed("verification/src/lib.rs", &lib, &cases, |case, text| {
            doc_text(text).contains(&format!("[`cases::{case}`]"))
        }));
    }
    if let Some(all) = read("verification/src/cases/mod.rs", &mut problems) {
        problems.extend(check_listed("verification/src/cases/mod.rs", &all, &cases, |case, text| {
            text.contains(&format!("name: \"{case}\""))
        }));
    }

    // What the documents and comments say.
    for doc in USER_DOCS {
        for file in files_with(&root.join(doc), ".md") {
            if let Ok(text) = fs::read_to_string(&file) {
                problems.extend(check_outside_paths(&relative(root, &file), &text, false));
            }
        }
    }
    for dir in COMMENT_DIRS {
        for file in rust_files(&root.join(dir)) {
            let rel = relative(root, &file);
            let Ok(text) = fs::read_to_string(&file) else { continue };
            problems.extend(check_comment_history(&rel, &text));
            problems.extend(check_outside_paths(&rel, &text, true));
        }
    }

    // The text rules.
    for dir in CODE_DIRS {
        for file in rust_files(&root.join(dir)) {
            let rel = relative(root, &file);
            let Ok(text) = fs::read_to_string(&file) else { continue };
            problems.extend(check_length(&rel, &text, LONG_FILES));
            problems.extend(check_forbidden(&rel, &text));
        }
    }
    problems.extend(check_stale_long_files(root, LONG_FILES));
    problems
}

/// Each module of a crate (`modules`, under `src`) has a row in `table`, and each row names one.
fn check_rows(table: &ModuleTable, modules: &BTreeSet<String>, src: &str) -> Vec<Problem> {
    let mut problems = Vec::new();
    for module in modules {
        if !table.rows.contains_key(module) {
            problems.push(Problem::new(
                "ARCHITECTURE.md",
                table.line,
                format!("module `{module}` ({src}) has no row in its module table"),
            ));
        }
    }
    for (module, row) in &table.rows {
        if !modules.contains(module) {
            problems.push(Problem::new(
                "ARCHITECTURE.md",
                row.line,
                format!("the module table lists `{module}`, which is not a module of {src}"),
            ));
        }
    }
    problems
}

/// The modules a file of the reproduction uses: its own crate's (`crate::X` or
/// `slurry_reproduce::X`; an item of the crate root, `crate::BedRecord`, is `lib`) and the
/// solver's modules (`slurry::X` of `solver`, kept as `slurry::X`; the solver's root items,
/// `slurry::BUILD_REVISION`, are open to every module).
pub fn reproduction_uses(
    text: &str,
    modules: &BTreeSet<String>,
    solver: &BTreeSet<String>,
) -> Vec<(usize, String)> {
    let own = |(line, name): (usize, String)| {
        (line, if modules.contains(&name) { name } else { "lib".to_string() })
    };
    let mut uses: Vec<(usize, String)> = paths_after(text, "crate::").into_iter().map(own).collect();
    uses.extend(paths_after(text, "slurry_reproduce::").into_iter().map(own));
    uses.extend(
        paths_after(text, SOLVER_PREFIX)
            .into_iter()
            .filter(|(_, name)| solver.contains(name))
            .map(|(line, name)| (line, format!("{SOLVER_PREFIX}{name}"))),
    );
    uses
}

/// The `.rs` files under `dir`, sorted; `target` and hidden directories skipped.
fn rust_files(dir: &Path) -> Vec<PathBuf> {
    files_with(dir, ".rs")
}

/// The files under `dir` (or `dir` itself, a file) whose names end with `suffix`, sorted;
/// `target` and hidden directories skipped.
fn files_with(dir: &Path, suffix: &str) -> Vec<PathBuf> {
    if dir.is_file() {
        return vec![dir.to_path_buf()];
    }
    let mut files = Vec::new();
    let mut stack = vec![dir.to_path_buf()];
    while let Some(d) = stack.pop() {
        let Ok(entries) = fs::read_dir(&d) else { continue };
        for entry in entries.flatten() {
            let path = entry.path();
            let name = entry.file_name();
            let name = name.to_string_lossy();
            if path.is_dir() {
                if name != "target" && !name.starts_with('.') {
                    stack.push(path);
                }
            } else if name.ends_with(suffix) {
                files.push(path);
            }
        }
    }
    files.sort();
    files
}

/// `file` relative to `root`, with `/` separators.
fn relative(root: &Path, file: &Path) -> String {
    let rel = file.strip_prefix(root).unwrap_or(file);
    rel.components().map(|c| c.as_os_str().to_string_lossy()).collect::<Vec<_>>().join("/")
}
