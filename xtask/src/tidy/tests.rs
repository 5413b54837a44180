//! The rules' own tests, and the repository checked against them.

use std::collections::BTreeSet;
use std::fs;
use std::path::Path;

use super::docs::*;
use super::table::*;
use super::text::*;
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
    let (table, problems) = parse_module_table("ARCHITECTURE.md", text, TABLE_HEADING);
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
    let (_, problems) = parse_module_table("ARCHITECTURE.md", &text, TABLE_HEADING);
    assert_eq!(problems.len(), 1, "{problems:?}");
    assert!(problems[0].message.contains("broken"), "{}", problems[0]);
    assert_eq!(problems[0].line, 12);
}

#[test]
fn an_unescaped_bar_in_a_cell_is_an_error_and_an_escaped_one_is_not() {
    let bad = TABLE.replace("| the grid |", "| the grid |u| |");
    let (_, problems) = parse_module_table("ARCHITECTURE.md", &bad, TABLE_HEADING);
    assert!(messages(&problems).contains("cells"), "{problems:?}");
    let escaped = TABLE.replace("| the grid |", "| the grid \\|u\\| |");
    table(&escaped);
}

#[test]
fn a_module_known_but_without_a_row_is_an_error() {
    let text = TABLE.replace("| `io` | files | `lattice` |\n", "");
    let (_, problems) = parse_module_table("ARCHITECTURE.md", &text, TABLE_HEADING);
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
    let t =
        table(&TABLE.replace(
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
    let problems = check_imports("src/lbm/fluid.rs", "lbm", &paths_after(code, "crate::"), &t);
    assert_eq!(problems.len(), 1, "{problems:?}");
    assert_eq!(problems[0].line, 3);
    assert!(problems[0].message.contains("`lbm` uses `crate::rigid`"), "{}", problems[0]);
    assert!(problems[0].to_string().starts_with("src/lbm/fluid.rs:3: "));
}

#[test]
fn grouped_and_multi_line_crate_paths_are_split() {
    let code = "use crate::{\n    lattice::Grid,\n    rigid::{Vec3, Quat},\n};\nlet x = $crate::io::y;";
    let found = paths_after(code, "crate::");
    assert_eq!(found, vec![(2, "lattice".to_string()), (3, "rigid".to_string())]);
}

#[test]
fn raw_strings_block_comments_and_lifetimes_are_handled() {
    let code = "fn f<'a>(x: &'a str) {}\n/* crate::io /* nested */ crate::io */\nlet s = r#\"crate::io \"q\"\"#;\nuse crate::run;";
    assert_eq!(paths_after(code, "crate::"), vec![(4, "run".to_string())]);
}

#[test]
fn module_of_a_file() {
    assert_eq!(module_under("src/lbm/fluid.rs", "src/").as_deref(), Some("lbm"));
    assert_eq!(module_under("src/run.rs", "src/").as_deref(), Some("run"));
    assert_eq!(module_under("src/lib.rs", "src/").as_deref(), Some("lib"));
    assert_eq!(module_under("tests/cli_run.rs", "src/"), None);
    assert_eq!(module_under("reproduce/src/lib.rs", "reproduce/src/").as_deref(), Some("lib"));
    assert_eq!(module_under("reproduce/src/stats/profiles.rs", "reproduce/src/").as_deref(), Some("stats"));
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

const REPRODUCTION: &str = "\
## Module map of the reproduction

| module | what it holds | knows about |
|---|---|---|
| `lib` | the pipeline | `stats`, `slurry::run`, `slurry::case` types |
| `stats` | statistics | `slurry::io` |
| `main` | the binary | `lib`, `slurry::cli` |
";

#[test]
fn the_reproduction_table_names_solver_modules_by_two_segments() {
    let (t, problems) = parse_module_table("ARCHITECTURE.md", REPRODUCTION, REPRODUCE_HEADING);
    assert!(problems.is_empty(), "{problems:?}");
    assert_eq!(t.rows["lib"].knows, ["stats", "slurry::run", "slurry::case"].map(String::from).into());
    assert_eq!(t.rows["stats"].knows, ["slurry::io"].map(String::from).into());
}

#[test]
fn the_reproduction_uses_are_checked_against_its_table() {
    let (t, _) = parse_module_table("ARCHITECTURE.md", REPRODUCTION, REPRODUCE_HEADING);
    let modules: BTreeSet<String> = ["lib", "stats", "main"].map(String::from).into();
    let code = "use slurry::io::read;\nuse crate::BedRecord;\nlet r = slurry::BUILD_REVISION;\nuse slurry::run::run_case;\n// slurry::settle\n";
    let solver: BTreeSet<String> = ["io", "run", "cli"].map(String::from).into();
    let uses = reproduction_uses(code, &modules, &solver);
    assert_eq!(
        uses,
        vec![(2, "lib".to_string()), (1, "slurry::io".to_string()), (4, "slurry::run".to_string())]
    );
    let m = messages(&check_imports("reproduce/src/stats/mod.rs", "stats", &uses, &t));
    assert!(m.contains("`stats` uses `crate::lib`"), "{m}");
    assert!(m.contains("`stats` uses `slurry::run`"), "{m}");
    assert!(!m.contains("uses `slurry::io`"), "{m}");
    let main = "use slurry_reproduce::cli as paper;\nuse slurry::cli as solver;\n";
    let uses = reproduction_uses(main, &modules, &solver);
    assert_eq!(uses, vec![(1, "lib".to_string()), (2, "slurry::cli".to_string())]);
    assert!(check_imports("reproduce/src/main.rs", "main", &uses, &t).is_empty());
}

#[test]
fn dates_outside_names_and_issue_numbers_in_comments_are_errors() {
    assert_eq!(loose_dates("measured 2026-11-27 on two threads"), vec!["2026-11-27"]);
    assert!(loose_dates("runs/2026-11-25-s0.25-exact-r200 and 2026-11-27-dense.json").is_empty());
    assert!(loose_dates("a seed 12026-11-270").is_empty());
    assert!(names_an_issue("(issue 15: a 600³ grid)"));
    assert!(names_an_issue("Issue #3"));
    assert!(!names_an_issue("an issue of scale; issues remain"));
    let code = "let s = \"2026-01-01\";\n/// Measured 2026-11-27.\nfn f() {} // see issue 12\n/// `runs/2026-11-25-s0.25`\n";
    let problems = check_comment_history("src/a.rs", code);
    assert_eq!(problems.iter().map(|p| p.line).collect::<Vec<_>>(), vec![2, 3], "{problems:?}");
}

#[test]
fn paths_outside_the_repository_are_errors() {
    let doc = "run `benches/scripts/membw.sh`\nsee ../shared/spec/physics.md\nin ~/slurry-runs\n";
    let problems = check_outside_paths("README.md", doc, false);
    assert_eq!(problems.iter().map(|p| p.line).collect::<Vec<_>>(), vec![2, 3], "{problems:?}");
    let code = "let p = \"/tmp/x\"; // a scratch file\n/// reads shared/bench/membw.sh\n";
    let problems = check_outside_paths("src/a.rs", code, true);
    assert_eq!(problems.iter().map(|p| p.line).collect::<Vec<_>>(), vec![2], "{problems:?}");
}

#[test]
fn the_solver_naming_the_reproduction_is_an_error() {
    let dir = std::env::temp_dir().join(format!("xtask-tidy-layering-{}", std::process::id()));
    fs::create_dir_all(&dir).unwrap();
    fs::write(dir.join("Cargo.toml"), "[dependencies]\nslurry-reproduce = { path = \"reproduce\" }\n")
        .unwrap();
    let files = vec![
        (
            "src/run.rs".to_string(),
            "// slurry_reproduce in a comment\nuse slurry_reproduce::stats;\n".to_string(),
        ),
        ("tests/a.rs".to_string(), "let s = \"slurry_reproduce\";\n".to_string()),
    ];
    let problems = check_crate_layering(&dir, &files);
    fs::remove_dir_all(&dir).unwrap();
    let at: Vec<String> = problems.iter().map(|p| format!("{}:{}", p.path.display(), p.line)).collect();
    assert_eq!(at, vec!["src/run.rs:2", "Cargo.toml:2"], "{problems:?}");
}
