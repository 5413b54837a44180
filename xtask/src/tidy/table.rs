//! The module tables of ARCHITECTURE.md and the imports they allow; a lexer good enough to
//! find paths outside comments and strings.

use std::collections::{BTreeMap, BTreeSet};

use super::{Problem, CORE, FLUID, PARTICLES};

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

/// The heading the solver's module table follows.
pub const TABLE_HEADING: &str = "## Module map";
/// The heading the reproduction crate's module table follows.
pub const REPRODUCE_HEADING: &str = "## Module map of the reproduction";
/// How the reproduction crate names the solver's modules in its table and its code.
pub const SOLVER_PREFIX: &str = "slurry::";
/// The header of the table's last column.
const KNOWS_ABOUT: &str = "knows about";

/// Parses the module table under `heading`: the module of each row (the first cell, in
/// backticks) and the modules of its "knows about" column (the first path segment of each
/// backticked name, or the first two of a name of the solver, `slurry::io::x` → `slurry::io`;
/// "nothing" or no backticks: none). Problems: no table, a table broken by a blank line, a row
/// with the wrong number of cells, a module named twice.
pub fn parse_module_table(path: &str, text: &str, heading: &str) -> (ModuleTable, Vec<Problem>) {
    let mut problems = Vec::new();
    let mut table = ModuleTable::default();
    let lines: Vec<&str> = text.lines().collect();
    let title = heading;
    let Some(heading) = lines.iter().position(|l| l.trim() == title) else {
        problems.push(Problem::new(path, 0, format!("no \"{title}\" heading")));
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
        let knows = backticked(&cells[knows_column]).into_iter().map(|name| known_name(&name)).collect();
        if table.rows.insert(module.clone(), Row { line: i + 1, knows }).is_some() {
            problems.push(Problem::new(path, i + 1, format!("module `{module}` has two rows")));
        }
    }
    // Every module a row knows about must itself be a row (the solver's, of its own table).
    for (module, row) in &table.rows {
        for known in &row.knows {
            if !known.starts_with(SOLVER_PREFIX) && !table.rows.contains_key(known) {
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

/// The module a "knows about" name stands for: its first path segment, or for a module of the
/// solver named from the reproduction its first two (`slurry::io` types → `slurry::io`).
pub fn known_name(name: &str) -> String {
    match name.strip_prefix(SOLVER_PREFIX) {
        Some(rest) => format!("{SOLVER_PREFIX}{}", rest.split("::").next().unwrap_or_default()),
        None => name.split("::").next().unwrap_or_default().to_string(),
    }
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

/// The uses `(line, name)` in a file of module `module` that the table does not allow: `name`
/// is a module of the same crate (shown as `crate::name`) or of the solver (`slurry::x`).
pub fn check_imports(
    path: &str,
    module: &str,
    uses: &[(usize, String)],
    table: &ModuleTable,
) -> Vec<Problem> {
    let Some(row) = table.rows.get(module) else {
        return Vec::new(); // reported once, as a missing row
    };
    // One problem per module used against the table: its first use, with the count.
    let mut against: BTreeMap<&str, (usize, usize)> = BTreeMap::new();
    for (line, used) in uses {
        if used != module && !row.knows.contains(used) {
            against.entry(used).or_insert((*line, 0)).1 += 1;
        }
    }
    let allowed: Vec<&str> = row.knows.iter().map(String::as_str).collect();
    let allowed = if allowed.is_empty() { "nothing".to_string() } else { allowed.join(", ") };
    against
        .into_iter()
        .map(|(used, (line, count))| {
            let more = if count > 1 { format!(" ({count} uses in this file)") } else { String::new() };
            let shown =
                if used.starts_with(SOLVER_PREFIX) { used.to_string() } else { format!("crate::{used}") };
            Problem::new(
                path,
                line,
                format!(
                    "`{module}` uses `{shown}`{more}, which ARCHITECTURE.md's module table does not \
                     allow (`{module}` knows about: {allowed}); move the code, or change the table if the \
                     design changed"
                ),
            )
        })
        .collect()
}

/// `(line, first segment)` for every path that starts with `prefix` (`crate::`, `slurry::`) in
/// `text`, comments and string literals left out; `prefix{a::x, b}` gives `a` and `b`.
pub fn paths_after(text: &str, prefix: &str) -> Vec<(usize, String)> {
    let code = strip_comments_and_strings(text);
    let mut found = Vec::new();
    let bytes = code.as_bytes();
    let mut at = 0;
    while let Some(offset) = code[at..].find(prefix) {
        let start = at + offset;
        at = start + prefix.len();
        let preceded_by_ident = start > 0 && (is_ident_byte(bytes[start - 1]) || bytes[start - 1] == b'$');
        if preceded_by_ident {
            continue; // e.g. `$crate::`, `my_crate::` or `xslurry::`
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

pub(super) fn is_ident_byte(b: u8) -> bool {
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

/// Splits a Markdown table row into trimmed cells, at `|` not escaped as `\|`.
pub(super) fn split_cells(line: &str) -> Vec<String> {
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
pub(super) fn backticked(cell: &str) -> Vec<String> {
    cell.split('`').skip(1).step_by(2).map(str::to_string).collect()
}
