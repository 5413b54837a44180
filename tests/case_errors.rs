//! Case-file errors name the file, the key and what is allowed; the shipped examples are valid.

use std::path::{Path, PathBuf};

use slurry::case::{Case, CaseErrorKind, Precision};

const GOOD: &str = r#"
[domain]
nx = 4
ny = 4
nz = 8

[fluid]
precision = "f32"
tau = 0.65
collision = "bgk"

[boundaries]
x_min = "periodic"
x_max = "periodic"
y_min = "periodic"
y_max = "periodic"
z_min = "no_slip"
z_max = { moving_wall = [0.02, 0.0, 0.0] }

[run]
steps = 20
output_every = 5
"#;

/// Writes `text` to `bad.toml` in a temporary directory and returns the error message.
fn error_of(text: &str) -> (String, PathBuf, tempfile::TempDir) {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("bad.toml");
    std::fs::write(&path, text).unwrap();
    let e = Case::from_file(&path).expect_err("case should be rejected");
    assert_eq!(e.file, path);
    (e.to_string(), path, dir)
}

fn assert_mentions(msg: &str, path: &Path, needles: &[&str]) {
    assert!(
        msg.starts_with(&format!("{}: ", path.display())),
        "message does not start with the file name: {msg}"
    );
    for n in needles {
        assert!(msg.contains(n), "message lacks {n:?}: {msg}");
    }
}

#[test]
fn good_case_parses() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("good.toml");
    std::fs::write(&path, GOOD).unwrap();
    let c = Case::from_file(&path).unwrap();
    assert_eq!(c.fluid.precision, Precision::F32);
    assert!((c.nu() - 0.05).abs() < 1e-15);
}

#[test]
fn missing_file_names_the_file() {
    let e = Case::from_file("/nonexistent/case.toml").unwrap_err();
    assert!(matches!(e.kind, CaseErrorKind::Read(_)));
    assert!(e.to_string().starts_with("/nonexistent/case.toml: cannot read"));
}

#[test]
fn wrong_key_names_file_and_key() {
    let (msg, path, _d) = error_of(&GOOD.replace("tau = 0.65", "viscosity = 0.05"));
    assert_mentions(&msg, &path, &["unknown key `fluid.viscosity`", "allowed: precision, nu, tau"]);
}

#[test]
fn tau_at_one_half_names_fluid_tau() {
    let (msg, path, _d) = error_of(&GOOD.replace("tau = 0.65", "tau = 0.5"));
    assert_mentions(&msg, &path, &["fluid.tau = 0.5", "must be finite and > 0.5"]);
}

#[test]
fn nonpositive_nu_names_fluid_nu() {
    let (msg, path, _d) = error_of(&GOOD.replace("tau = 0.65", "nu = -0.01"));
    assert_mentions(&msg, &path, &["fluid.nu = -0.01", "> 0"]);
    let (msg, path, _d) = error_of(&GOOD.replace("tau = 0.65", "nu = 0"));
    assert_mentions(&msg, &path, &["fluid.nu", "> 0"]);
}

#[test]
fn one_sided_periodic_names_both_faces() {
    let (msg, path, _d) = error_of(&GOOD.replace("x_max = \"periodic\"", "x_max = \"no_slip\""));
    assert_mentions(&msg, &path, &["boundaries.x_min", "x_max", "pairs"]);
}

#[test]
fn wrong_precision_names_key_and_options() {
    let (msg, path, _d) = error_of(&GOOD.replace("\"f32\"", "\"double\""));
    assert_mentions(&msg, &path, &["fluid.precision", "double", "`f32` or `f64`", "line 8"]);
}

#[test]
fn examples_parse_and_validate() {
    let dir = Path::new(env!("CARGO_MANIFEST_DIR")).join("examples");
    let mut n = 0;
    for entry in std::fs::read_dir(&dir).unwrap() {
        let path = entry.unwrap().path();
        if path.extension().is_some_and(|e| e == "toml") {
            let case = Case::from_file(&path).unwrap_or_else(|e| panic!("{e}"));
            case.fluid_params().validate().unwrap();
            case.boundaries().validate().unwrap();
            n += 1;
        }
    }
    assert!(n >= 3, "expected at least three example cases, found {n}");
}
