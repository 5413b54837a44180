//! `cargo xtask tidy`: the repository's rules as code, in the spirit of rust-analyzer's
//! `xtask/src/tidy.rs`. Cheap (reads text, builds nothing), so `cargo xtask ci` runs it first.
//!
//! The rules:
//! - **Imports follow ARCHITECTURE.md.** The module table in `ARCHITECTURE.md` ("## Module
//!   map") is the one source of truth: its "knows about" column names, in backticks, the
//!   modules each `src/` module may use. Every `crate::X` path in a file of `src/<module>/`
//!   (comments left out) must name the module itself or one listed in its row. The table itself
//!   keeps the layering: the fluid (`lbm`) lists no particle module (`rigid`, `contact`, `ibm`)
//!   and those list no fluid, and in the core ([`CORE`]) only `coupling` lists both sides.
//!   The table must be one piece (a blank line inside it turns the rows after it into a
//!   paragraph) with as many cells in each row as in its header (an unescaped `|` adds one).
//! - **Every module and every verification case is listed where the docs list them**: each
//!   top-level module of `src/` is declared and linked in `src/lib.rs`, has a row in the table and
//!   is named in the README's "## Layout"; each file of `verification/src/cases/` is linked in
//!   `verification/src/lib.rs`'s docs and registered in `cases::all()`.
//! - **Files stay short**: at most [`MAX_LINES`] lines, except the few in [`LONG_FILES`], each
//!   with its reason (an entry that is no longer needed is an error too, so the list stays short).
//! - **Nothing disabled or left in**: no ignored tests, `todo` or `dbg` macros in `src`, `tests`,
//!   `verification`, `xtask`, `benches` or `examples`.
//!
//! Each problem is printed as `path:line: message`; all are reported, then tidy fails if any.

use std::collections::{BTreeMap, BTreeSet};
use std::fmt;
use std::fs;
use std::path::{Path, PathBuf};

/// The longest a `.rs` file may be, in lines, unless it is in [`LONG_FILES`].
pub const MAX_LINES: usize = 1000;

/// Files allowed past [`MAX_LINES`], each with the reason. Keep it short: split a file by what it
/// holds rather than add it here.
pub const LONG_FILES: &[(&str, &str)] = &[];

/// The core layers, below the drivers: among these only `coupling` may know both the fluid and
/// the particles. (`case`, `run`, `settle` and `reproduce` sit above the core and assemble it.)
/// (`util`, seeded random numbers and compensated sums, is a leaf every layer may use.)
pub const CORE: &[&str] = &["lattice", "util", "lbm", "ibm", "rigid", "contact", "coupling"];
/// The fluid side of the core.
pub const FLUID: &[&str] = &["lbm"];
/// The particle side of the core.
pub const PARTICLES: &[&str] = &["rigid", "contact", "ibm"];

/// The directories whose `.rs` files the text rules (length, nothing disabled) read.
const CODE_DIRS: &[&str] = &["src", "tests", "verification", "xtask", "benches", "examples"];

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

    // The module table and the imports.
    let modules = src_modules(&root.join("src"));
    let table = read("ARCHITECTURE.md", &mut problems).map(|text| {
        let (table, found) = parse_module_table("ARCHITECTURE.md", &text);
        problems.extend(found);
        table
    });
    if let Some(table) = &table {
        problems.extend(check_table_layering(table));
        for module in &modules {
            if !table.rows.contains_key(module) {
                problems.push(Problem::new(
                    "ARCHITECTURE.md",
                    table.line,
                    format!("module `{module}` (src/) has no row in the module table"),
                ));
            }
        }
        for (module, row) in &table.rows {
            if !modules.contains(module) {
                problems.push(Problem::new(
                    "ARCHITECTURE.md",
                    row.line,
                    format!("the module table lists `{module}`, which is not a module of src/"),
                ));
            }
        }
        for file in rust_files(&root.join("src")) {
            let rel = relative(root, &file);
            let Some(module) = module_of(&rel) else { continue };
            if let Ok(text) = fs::read_to_string(&file) {
                problems.extend(check_imports(&rel, &module, &text, table));
            }
        }
    }

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

// ---------------------------------------------------------------------------------------------
// The module table.

/// The module table of ARCHITECTURE.md.
#[derive(Debug, Default)]
pub struct ModuleTable {
    /// Line of the table's header.
    pub line: usize,
    /// Each module's row.
    pub rows: BTreeMap<String, Row>,
}

/// A row of the module table.
#[derive(Debug)]
pub struct Row {
    /// Its line in ARCHITECTURE.md.
    pub line: usize,
    /// The modules of its "knows about" column.
    pub knows: BTreeSet<String>,
}

/// The heading the module table follows.
const TABLE_HEADING: &str = "## Module map";
/// The header of the table's last column.
const KNOWS_ABOUT: &str = "knows about";

/// Parses the module table under [`TABLE_HEADING`]: the module of each row (the first cell, in
/// backticks) and the modules of its "knows about" column (the first path segment of each
/// backticked name; "nothing" or no backticks: none). Problems: no table, a table broken by a
/// blank line, a row with the wrong number of cells, a module named twice.
pub fn parse_module_table(path: &str, text: &str) -> (ModuleTable, Vec<Problem>) {
    let mut problems = Vec::new();
    let mut table = ModuleTable::default();
    let lines: Vec<&str> = text.lines().collect();
    let Some(heading) = lines.iter().position(|l| l.trim() == TABLE_HEADING) else {
        problems.push(Problem::new(path, 0, format!("no \"{TABLE_HEADING}\" heading")));
        return (table, problems);
    };
    let section_end =
        lines[heading + 1..].iter().position(|l| l.starts_with("#")).map_or(lines.len(), |i| heading + 1 + i);
    let Some(start) = (heading + 1..section_end).find(|&i| lines[i].trim_start().starts_with('|')) else {
        problems.push(Problem::new(path, heading + 1, "no table under the module-map heading"));
        return (table, problems);
    };
    table.line = start + 1;
    let header = split_cells(lines[start]);
    let Some(knows_column) = header.iter().position(|c| c.eq_ignore_ascii_case(KNOWS_ABOUT)) else {
        problems.push(Problem::new(
            path,
            start + 1,
            format!("the module table has no \"{KNOWS_ABOUT}\" column"),
        ));
        return (table, problems);
    };
    let mut in_table = true;
    for (i, line) in lines.iter().enumerate().take(section_end).skip(start + 1) {
        let is_row = line.trim_start().starts_with('|');
        if !is_row {
            in_table = false;
            continue;
        }
        if !in_table {
            problems.push(Problem::new(
                path,
                i + 1,
                "the module table is broken by a line that is not a row: the rows after it render \
                 as a paragraph (keep the table in one piece)",
            ));
            in_table = true;
        }
        let cells = split_cells(line);
        if cells.iter().all(|c| c.chars().all(|ch| matches!(ch, '-' | ':' | ' '))) {
            continue; // the separator row
        }
        if cells.len() != header.len() {
            problems.push(Problem::new(
                path,
                i + 1,
                format!(
                    "row has {} cells, the header {} (escape a `|` inside a cell as `\\|`)",
                    cells.len(),
                    header.len()
                ),
            ));
            continue;
        }
        let Some(module) = backticked(&cells[0]).into_iter().next() else {
            problems.push(Problem::new(path, i + 1, "the first cell names no module in backticks"));
            continue;
        };
        let knows = backticked(&cells[knows_column])
            .into_iter()
            .map(|name| name.split("::").next().unwrap_or_default().to_string())
            .collect();
        if table.rows.insert(module.clone(), Row { line: i + 1, knows }).is_some() {
            problems.push(Problem::new(path, i + 1, format!("module `{module}` has two rows")));
        }
    }
    // Every module a row knows about must itself be a row.
    for (module, row) in &table.rows {
        for known in &row.knows {
            if !table.rows.contains_key(known) {
                problems.push(Problem::new(
                    path,
                    row.line,
                    format!("`{module}` knows about `{known}`, which has no row in the table"),
                ));
            }
        }
    }
    (table, problems)
}

/// The layering the table must keep: [`FLUID`] lists no [`PARTICLES`] module and vice versa,
/// and within [`CORE`] only `coupling` lists both sides.
pub fn check_table_layering(table: &ModuleTable) -> Vec<Problem> {
    let mut problems = Vec::new();
    let path = "ARCHITECTURE.md";
    for core in CORE {
        if !table.rows.contains_key(*core) {
            problems.push(Problem::new(path, table.line, format!("the core module `{core}` has no row")));
        }
    }
    for (module, row) in &table.rows {
        let fluid: Vec<&str> = FLUID.iter().copied().filter(|m| row.knows.contains(*m)).collect();
        let particles: Vec<&str> = PARTICLES.iter().copied().filter(|m| row.knows.contains(*m)).collect();
        if FLUID.contains(&module.as_str()) && !particles.is_empty() {
            problems.push(Problem::new(
                path,
                row.line,
                format!("the fluid (`{module}`) must not know the particle side ({})", particles.join(", ")),
            ));
        }
        if PARTICLES.contains(&module.as_str()) && !fluid.is_empty() {
            problems.push(Problem::new(
                path,
                row.line,
                format!("the particle side (`{module}`) must not know the fluid ({})", fluid.join(", ")),
            ));
        }
        if CORE.contains(&module.as_str()) && module != "coupling" {
            let bad: Vec<&str> = row.knows.iter().map(String::as_str).filter(|m| !CORE.contains(m)).collect();
            if !bad.is_empty() {
                problems.push(Problem::new(
                    path,
                    row.line,
                    format!("the core module `{module}` must not know the drivers ({})", bad.join(", ")),
                ));
            }
            if !fluid.is_empty() && !particles.is_empty() {
                problems.push(Problem::new(
                    path,
                    row.line,
                    format!("only `coupling` knows both the fluid and the particles, not `{module}`"),
                ));
            }
        }
    }
    problems
}

/// The `crate::X` paths in `text` (a file of module `module`) that the table does not allow.
pub fn check_imports(path: &str, module: &str, text: &str, table: &ModuleTable) -> Vec<Problem> {
    let Some(row) = table.rows.get(module) else {
        return Vec::new(); // reported once, as a missing row
    };
    // One problem per module used against the table: its first use, with the count.
    let mut uses: BTreeMap<String, (usize, usize)> = BTreeMap::new();
    for (line, used) in crate_paths(text) {
        if used != module && !row.knows.contains(&used) {
            uses.entry(used).or_insert((line, 0)).1 += 1;
        }
    }
    let allowed: Vec<&str> = row.knows.iter().map(String::as_str).collect();
    let allowed = if allowed.is_empty() { "nothing".to_string() } else { allowed.join(", ") };
    uses.into_iter()
        .map(|(used, (line, count))| {
            let more = if count > 1 { format!(" ({count} uses in this file)") } else { String::new() };
            Problem::new(
                path,
                line,
                format!(
                    "`{module}` uses `crate::{used}`{more}, which ARCHITECTURE.md's module table does not \
                     allow (`{module}` knows about: {allowed}); move the code, or change the table if the \
                     design changed"
                ),
            )
        })
        .collect()
}

/// `(line, module)` for every `crate::module` path in `text`, comments and string literals left
/// out; `crate::{a::x, b}` gives `a` and `b`.
pub fn crate_paths(text: &str) -> Vec<(usize, String)> {
    let code = strip_comments_and_strings(text);
    let mut found = Vec::new();
    let bytes = code.as_bytes();
    let mut at = 0;
    while let Some(offset) = code[at..].find("crate::") {
        let start = at + offset;
        at = start + "crate::".len();
        let preceded_by_ident = start > 0 && (is_ident_byte(bytes[start - 1]) || bytes[start - 1] == b'$');
        if preceded_by_ident {
            continue; // e.g. `$crate::` or `my_crate::`
        }
        let line = code[..start].matches('\n').count() + 1;
        if bytes.get(at) == Some(&b'{') {
            // A group: the first segment of each top-level item.
            let mut depth = 0usize;
            let mut item_start = true;
            for (i, &b) in bytes[at..].iter().enumerate() {
                match b {
                    b'{' => {
                        depth += 1;
                        item_start = depth == 1;
                    }
                    b'}' => {
                        depth -= 1;
                        if depth == 0 {
                            break;
                        }
                    }
                    b',' if depth == 1 => item_start = true,
                    _ if item_start && is_ident_byte(b) => {
                        let ident = ident_at(&code[at + i..]);
                        let line = code[..at + i].matches('\n').count() + 1;
                        found.push((line, ident.to_string()));
                        item_start = false;
                    }
                    _ => {}
                }
            }
        } else {
            let ident = ident_at(&code[at..]);
            if !ident.is_empty() {
                found.push((line, ident.to_string()));
            }
        }
    }
    found
}

/// Whether the `r` at `i` starts a raw-string token (`r"`, or `br"` for a byte string), not the
/// end of an identifier.
fn starts_token(chars: &[char], i: usize) -> bool {
    let is_ident = |c: char| c.is_alphanumeric() || c == '_';
    match i.checked_sub(1).map(|p| chars[p]) {
        None => true,
        Some('b') => i < 2 || !is_ident(chars[i - 2]),
        Some(prev) => !is_ident(prev),
    }
}

fn is_ident_byte(b: u8) -> bool {
    b.is_ascii_alphanumeric() || b == b'_'
}

fn ident_at(s: &str) -> &str {
    let end = s.bytes().position(|b| !is_ident_byte(b)).unwrap_or(s.len());
    &s[..end]
}

/// `text` with comments and the contents of string and char literals blanked (newlines kept, so
/// line numbers hold). A lexer good enough for paths: raw strings `r"…"`/`r#"…"#`, escapes,
/// nested block comments; lifetimes are told from char literals by what follows.
pub fn strip_comments_and_strings(text: &str) -> String {
    let chars: Vec<char> = text.chars().collect();
    let mut out = String::with_capacity(text.len());
    let blank = |c: char| if c == '\n' { '\n' } else { ' ' };
    let mut i = 0;
    while i < chars.len() {
        let c = chars[i];
        let next = chars.get(i + 1).copied();
        if c == '/' && next == Some('/') {
            while i < chars.len() && chars[i] != '\n' {
                out.push(' ');
                i += 1;
            }
        } else if c == '/' && next == Some('*') {
            let mut depth = 0;
            while i < chars.len() {
                if chars[i] == '/' && chars.get(i + 1) == Some(&'*') {
                    depth += 1;
                    out.push_str("  ");
                    i += 2;
                } else if chars[i] == '*' && chars.get(i + 1) == Some(&'/') {
                    depth -= 1;
                    out.push_str("  ");
                    i += 2;
                    if depth == 0 {
                        break;
                    }
                } else {
                    out.push(blank(chars[i]));
                    i += 1;
                }
            }
        } else if c == 'r' && (next == Some('"') || next == Some('#')) && starts_token(&chars, i) {
            // A raw string: r, hashes, quote … quote, hashes.
            let mut j = i + 1;
            while chars.get(j) == Some(&'#') {
                j += 1;
            }
            if chars.get(j) != Some(&'"') {
                out.push(c);
                i += 1;
                continue;
            }
            let hashes = j - i - 1;
            out.extend(std::iter::repeat_n(' ', j - i + 1));
            i = j + 1;
            while i < chars.len() {
                if chars[i] == '"' && (0..hashes).all(|k| chars.get(i + 1 + k) == Some(&'#')) {
                    out.extend(std::iter::repeat_n(' ', hashes + 1));
                    i += hashes + 1;
                    break;
                }
                out.push(blank(chars[i]));
                i += 1;
            }
        } else if c == '"' {
            out.push(' ');
            i += 1;
            while i < chars.len() && chars[i] != '"' {
                if chars[i] == '\\' {
                    out.push(' ');
                    i += 1;
                }
                if i < chars.len() {
                    out.push(blank(chars[i]));
                    i += 1;
                }
            }
            out.push(' ');
            i += 1;
        } else if c == '\'' {
            // A char literal ('x', '\n', '\u{..}') or a lifetime ('a).
            let close = if next == Some('\\') {
                (i + 2..chars.len().min(i + 12)).find(|&k| chars[k] == '\'')
            } else if chars.get(i + 2) == Some(&'\'') {
                Some(i + 2)
            } else {
                None
            };
            match close {
                Some(k) => {
                    out.extend(std::iter::repeat_n(' ', k - i + 1));
                    i = k + 1;
                }
                None => {
                    out.push(c);
                    i += 1;
                }
            }
        } else {
            out.push(c);
            i += 1;
        }
    }
    out
}

// ---------------------------------------------------------------------------------------------
// The lists in the docs.

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

/// The module of a file under `src/` (`src/lbm/fluid.rs` → `lbm`, `src/run.rs` → `run`); none
/// for `lib.rs`, `main.rs` and files outside `src/`.
pub fn module_of(rel: &str) -> Option<String> {
    let rest = rel.strip_prefix("src/")?;
    let first = rest.split('/').next()?;
    let module = first.strip_suffix(".rs").unwrap_or(first);
    (module != "lib" && module != "main").then(|| module.to_string())
}

/// The `//!` lines of `text`, joined.
fn doc_text(text: &str) -> String {
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

// ---------------------------------------------------------------------------------------------
// The text rules.

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

// ---------------------------------------------------------------------------------------------
// Files.

/// The `.rs` files under `dir`, sorted; `target` and hidden directories skipped.
fn rust_files(dir: &Path) -> Vec<PathBuf> {
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
            } else if name.ends_with(".rs") {
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

/// Splits a Markdown table row into trimmed cells, at `|` not escaped as `\|`.
fn split_cells(line: &str) -> Vec<String> {
    let line = line.trim();
    let line = line.strip_prefix('|').unwrap_or(line);
    let line = line.strip_suffix('|').filter(|l| !l.ends_with('\\')).unwrap_or(line);
    let mut cells = vec![String::new()];
    let mut chars = line.chars().peekable();
    while let Some(c) = chars.next() {
        match c {
            '\\' if chars.peek() == Some(&'|') => {
                cells.last_mut().expect("one cell").push('|');
                chars.next();
            }
            '|' => cells.push(String::new()),
            _ => cells.last_mut().expect("one cell").push(c),
        }
    }
    cells.iter().map(|c| c.trim().to_string()).collect()
}

/// The backticked words of `cell`, in order.
fn backticked(cell: &str) -> Vec<String> {
    cell.split('`').skip(1).step_by(2).map(str::to_string).collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    const TABLE: &str = "\
# Architecture

## Module map

| module | what it holds | knows about |
|---|---|---|
| `lattice` | the grid | nothing |
| `util` | sums | nothing |
| `lbm` | the fluid | `lattice` |
| `ibm` | transfer | `lattice` |
| `rigid` | bodies | nothing |
| `contact` | contacts | `rigid` |
| `coupling` | the step | `lbm`, `ibm`, `rigid`, `contact`, `lattice` |
| `run` | the driver | `coupling`, `lbm` state, `io::atomic` |
| `io` | files | `lattice` |

## Next
";

    fn table(text: &str) -> ModuleTable {
        let (table, problems) = parse_module_table("ARCHITECTURE.md", text);
        assert!(problems.is_empty(), "{problems:?}");
        table
    }

    fn messages(problems: &[Problem]) -> String {
        problems.iter().map(|p| format!("{p}\n")).collect()
    }

    #[test]
    fn table_is_parsed_with_the_first_segment_of_each_name() {
        let t = table(TABLE);
        assert_eq!(t.rows.len(), 9);
        assert!(t.rows["lattice"].knows.is_empty());
        assert_eq!(t.rows["run"].knows, ["coupling", "io", "lbm"].map(String::from).into());
        assert_eq!(t.rows["lbm"].line, 9);
        assert!(check_table_layering(&t).is_empty());
    }

    #[test]
    fn a_blank_line_inside_the_table_is_an_error() {
        let text = TABLE.replace("| `rigid` | bodies", "\n| `rigid` | bodies");
        let (_, problems) = parse_module_table("ARCHITECTURE.md", &text);
        assert_eq!(problems.len(), 1, "{problems:?}");
        assert!(problems[0].message.contains("broken"), "{}", problems[0]);
        assert_eq!(problems[0].line, 12);
    }

    #[test]
    fn an_unescaped_bar_in_a_cell_is_an_error_and_an_escaped_one_is_not() {
        let bad = TABLE.replace("| the grid |", "| the grid |u| |");
        let (_, problems) = parse_module_table("ARCHITECTURE.md", &bad);
        assert!(messages(&problems).contains("cells"), "{problems:?}");
        let escaped = TABLE.replace("| the grid |", "| the grid \\|u\\| |");
        table(&escaped);
    }

    #[test]
    fn a_module_known_but_without_a_row_is_an_error() {
        let text = TABLE.replace("| `io` | files | `lattice` |\n", "");
        let (_, problems) = parse_module_table("ARCHITECTURE.md", &text);
        assert!(messages(&problems).contains("`run` knows about `io`, which has no row"), "{problems:?}");
    }

    #[test]
    fn the_fluid_knowing_particles_is_an_error() {
        let t = table(
            &TABLE.replace("| `lbm` | the fluid | `lattice` |", "| `lbm` | the fluid | `lattice`, `rigid` |"),
        );
        let m = messages(&check_table_layering(&t));
        assert!(m.contains("the fluid (`lbm`) must not know the particle side (rigid)"), "{m}");
    }

    #[test]
    fn the_particles_knowing_the_fluid_is_an_error() {
        let t = table(&TABLE.replace("| `rigid` | bodies | nothing |", "| `rigid` | bodies | `lbm` |"));
        let m = messages(&check_table_layering(&t));
        assert!(m.contains("the particle side (`rigid`) must not know the fluid (lbm)"), "{m}");
    }

    #[test]
    fn a_core_module_knowing_both_sides_or_a_driver_is_an_error() {
        let t = table(&TABLE.replace(
            "| `lattice` | the grid | nothing |",
            "| `lattice` | the grid | `lbm`, `contact`, `run` |",
        ));
        let m = messages(&check_table_layering(&t));
        assert!(m.contains("only `coupling` knows both the fluid and the particles, not `lattice`"), "{m}");
        assert!(m.contains("must not know the drivers (run)"), "{m}");
    }

    #[test]
    fn imports_against_the_table_are_errors() {
        let t = table(TABLE);
        let code = "\
//! Uses crate::coupling only in a comment.
use crate::lattice::Grid;
use crate::rigid::Vec3; // a sideways import
fn f() -> &'static str { \"crate::contact in a string\" }
fn g() { let _ = crate::lbm::Fluid::new; let _c = 'x'; }
";
        let problems = check_imports("src/lbm/fluid.rs", "lbm", code, &t);
        assert_eq!(problems.len(), 1, "{problems:?}");
        assert_eq!(problems[0].line, 3);
        assert!(problems[0].message.contains("`lbm` uses `crate::rigid`"), "{}", problems[0]);
        assert!(problems[0].to_string().starts_with("src/lbm/fluid.rs:3: "));
    }

    #[test]
    fn grouped_and_multi_line_crate_paths_are_split() {
        let code = "use crate::{\n    lattice::Grid,\n    rigid::{Vec3, Quat},\n};\nlet x = $crate::io::y;";
        let found = crate_paths(code);
        assert_eq!(found, vec![(2, "lattice".to_string()), (3, "rigid".to_string())]);
    }

    #[test]
    fn raw_strings_block_comments_and_lifetimes_are_handled() {
        let code = "fn f<'a>(x: &'a str) {}\n/* crate::io /* nested */ crate::io */\nlet s = r#\"crate::io \"q\"\"#;\nuse crate::run;";
        assert_eq!(crate_paths(code), vec![(4, "run".to_string())]);
    }

    #[test]
    fn module_of_a_file() {
        assert_eq!(module_of("src/lbm/fluid.rs").as_deref(), Some("lbm"));
        assert_eq!(module_of("src/run.rs").as_deref(), Some("run"));
        assert_eq!(module_of("src/stats/profiles/tests.rs").as_deref(), Some("stats"));
        assert_eq!(module_of("src/lib.rs"), None);
        assert_eq!(module_of("tests/cli_run.rs"), None);
    }

    #[test]
    fn a_module_missing_from_lib_docs_or_declarations_is_an_error() {
        let modules: BTreeSet<String> = ["lbm", "run"].map(String::from).into();
        let lib = "//! - [`lbm`]: the fluid\npub mod lbm;\npub mod run;\n";
        let m = messages(&check_lib_docs("src/lib.rs", lib, &modules));
        assert!(m.contains("do not list [`run`]"), "{m}");
        assert!(!m.contains("[`lbm`]"), "{m}");
        let undeclared = "//! [`lbm`] [`run`]\npub mod lbm;\n";
        let m = messages(&check_lib_docs("src/lib.rs", undeclared, &modules));
        assert!(m.contains("`run`, which is not declared"), "{m}");
    }

    #[test]
    fn a_module_missing_from_the_readme_layout_is_an_error() {
        let modules: BTreeSet<String> = ["lbm", "run", "stats"].map(String::from).into();
        let readme = "# x\n## Layout\n`src/lbm` · `src/run.rs` · `src/statsx`\n## Next\n`src/stats`\n";
        let problems = check_readme_layout("README.md", readme, &modules);
        assert_eq!(problems.len(), 1, "{problems:?}");
        assert!(problems[0].message.contains("`src/stats`"));
        assert_eq!(problems[0].line, 2);
    }

    #[test]
    fn a_case_missing_from_the_lists_is_an_error() {
        let cases: BTreeSet<String> = ["couette", "poiseuille"].map(String::from).into();
        let lib = "//! - [`cases::couette`]: shear\n";
        let problems = check_listed("verification/src/lib.rs", lib, &cases, |case, text| {
            doc_text(text).contains(&format!("[`cases::{case}`]"))
        });
        assert_eq!(problems.len(), 1);
        assert!(problems[0].message.contains("`poiseuille`"));
    }

    #[test]
    fn a_long_file_is_an_error_unless_allowed() {
        let text = "x\n".repeat(MAX_LINES + 1);
        assert_eq!(check_length("src/a.rs", &text, &[]).len(), 1);
        assert!(check_length("src/a.rs", &text, &[("src/a.rs", "why")]).is_empty());
        assert!(check_length("src/a.rs", &"x\n".repeat(MAX_LINES), &[]).is_empty());
    }

    #[test]
    fn a_stale_long_file_entry_is_an_error() {
        let dir = std::env::temp_dir().join(format!("xtask-tidy-{}", std::process::id()));
        fs::create_dir_all(&dir).unwrap();
        fs::write(dir.join("short.rs"), "fn main() {}\n").unwrap();
        let problems = check_stale_long_files(&dir, &[("short.rs", "why"), ("gone.rs", "why")]);
        fs::remove_dir_all(&dir).unwrap();
        assert_eq!(problems.len(), 2, "{problems:?}");
    }

    #[test]
    fn ignored_tests_todo_and_dbg_are_errors() {
        for (bad, what) in [
            (format!("#[{}]\nfn t() {{}}", "ignore"), "ignore"),
            (format!("fn f() {{ {}!() }}", "todo"), "todo"),
            (format!("let x = {}!(1);", "dbg"), "dbg"),
        ] {
            let problems = check_forbidden("tests/a.rs", &format!("// ok\n{bad}"));
            assert_eq!(problems.len(), 1, "{what}: {problems:?}");
            assert_eq!(problems[0].line, 2);
        }
        assert!(check_forbidden("tests/a.rs", "fn ignore_me() { todo_list(); }").is_empty());
    }

    /// The repository itself keeps the rules (so `cargo test` catches what `cargo xtask tidy` does).
    #[test]
    fn repository_is_tidy() {
        let root = Path::new(env!("CARGO_MANIFEST_DIR")).parent().unwrap();
        let problems = check_repository(root);
        assert!(problems.is_empty(), "cargo xtask tidy:\n{}", messages(&problems));
    }
}
