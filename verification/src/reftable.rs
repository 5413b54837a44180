//! Committed reference tables (`verification/ref/<case>-<tier>.ref`).
//!
//! A `.ref` file is the text of a case's convergence tables, restricted to the compared
//! columns ([`crate::Column::compared`]), numbers written in the shortest form that reads back
//! to the same `f64` (so the file reproduces the run exactly):
//!
//! ```text
//! # comments
//! ## <table title>
//! N  L2_error
//! 8  1.112442630120857e-2
//! ```
//!
//! A run compares its tables with the file cell by cell, with relative tolerance
//! [`REL_TOL`] = 1e-9. **Why 1e-9:** the solver is bitwise deterministic on one machine (for
//! any thread count and instruction set), so with unchanged code the deviation is exactly 0.
//! Across platforms the libm `sin`/`cos`/`exp` used to build initial fields and exact
//! solutions may differ in the last bit (≈ 1e-16 relative); an error measure of size `e`
//! computed from values of order 1 turns that into ≈ 1e-16/e (≤ 1e-11 for the errors here),
//! well inside 1e-9. What 1e-9 does catch is any change of the arithmetic: even a regrouping of
//! the collision's operations (same formula, different rounding) moves the steady channel
//! errors by up to ≈ 5e-9 relative (observed), because the round-off of a steady state is
//! amplified by the condition number of the discrete problem (∝ N²) and then divided by the
//! small error. Such a change is re-blessed (`--bless`) and the diff of the `.ref` file shows
//! in which digit the numbers moved; a change of the discretisation moves them in the first
//! few digits. Columns whose digits are round-off by construction are not written.

use crate::{fmt_num, Column, Table};

/// Relative tolerance of the comparison with a committed table.
pub const REL_TOL: f64 = 1e-9;

/// Relative tolerance of the comparison with a committed (CPU) table when the fluid steps on
/// the device (`--device gpu`). The device performs the CPU's operations in the CPU's order,
/// but its driver may contract or split `fma` (Vulkan allows it), so its states differ from the
/// CPU's by round-off (populations within 5e-18 in f64 after 200 steps,
/// `tests/device_fluid.rs`). A tabulated number moves by that round-off relative to its own
/// size: most by 1e-12 (Couette 4.1e-12, Taylor–Green 1.7e-12, measured on lavapipe); an
/// error of a flow run to steady state by the `1.6e-13` of the profile that the steady
/// criterion leaves, divided by the error: Poiseuille's BGK error of 4e-5 at N = 64 moved by
/// 4.6e-9 (measured), and at N = 128 (full tier, error 1e-5) it may move by 1.6e-8. 1e-7
/// leaves a factor of 6 over that; a wrong term on the device moves these numbers in their
/// leading digits.
pub const DEVICE_REL_TOL: f64 = 1e-7;

/// The text of a `.ref` file for `tables` of `case` at `tier`.
pub fn render(case: &str, tier: &str, tables: &[Table]) -> String {
    let mut s = format!(
        "# slurry-verify reference table: case {case}, tier {tier}.\n\
         # Regenerate with `cargo xtask verify --tier {tier} --case {case} --bless` and review the diff.\n\
         # Compared cell by cell with relative tolerance {REL_TOL:e} (see verification/src/reftable.rs).\n"
    );
    for t in tables {
        let t = t.compared_part();
        s.push('\n');
        s.push_str(&format!("## {}\n", t.title));
        let names: Vec<&str> = t.columns.iter().map(|c| c.name.as_str()).collect();
        s.push_str(&names.join("  "));
        s.push('\n');
        for r in &t.rows {
            let cells: Vec<String> = r
                .iter()
                .map(|&v| if v == v.trunc() && v.abs() < 1e15 { fmt_num(v) } else { format!("{v:e}") })
                .collect();
            s.push_str(&cells.join("  "));
            s.push('\n');
        }
    }
    s
}

/// Parses the text of a `.ref` file into tables (all columns marked compared).
pub fn parse(text: &str) -> Result<Vec<Table>, String> {
    let mut tables: Vec<Table> = Vec::new();
    let mut expect_header = false;
    for (ln, line) in text.lines().enumerate() {
        let line = line.trim();
        if let Some(title) = line.strip_prefix("## ") {
            tables.push(Table { title: title.to_string(), columns: Vec::new(), rows: Vec::new() });
            expect_header = true;
            continue;
        }
        if line.is_empty() || line.starts_with('#') {
            continue;
        }
        let t =
            tables.last_mut().ok_or_else(|| format!("line {}: data before the first '## title'", ln + 1))?;
        if expect_header {
            t.columns =
                line.split_whitespace().map(|n| Column { name: n.to_string(), compared: true }).collect();
            expect_header = false;
            continue;
        }
        let row: Result<Vec<f64>, _> = line.split_whitespace().map(str::parse::<f64>).collect();
        let row = row.map_err(|e| format!("line {}: {e}", ln + 1))?;
        if row.len() != t.columns.len() {
            return Err(format!("line {}: {} values for {} columns", ln + 1, row.len(), t.columns.len()));
        }
        t.rows.push(row);
    }
    Ok(tables)
}

/// Compares `now` (the run's tables) with the committed `reference`. Returns the largest
/// relative deviation of any compared cell, or a description of a structural difference
/// (missing table, other columns or row count).
pub fn compare(now: &[Table], reference: &[Table]) -> Result<f64, String> {
    let now: Vec<Table> = now.iter().map(Table::compared_part).collect();
    if now.len() != reference.len() {
        return Err(format!("{} tables now, {} in the reference", now.len(), reference.len()));
    }
    let mut worst = 0.0f64;
    for (a, b) in now.iter().zip(reference) {
        if a.title != b.title {
            return Err(format!("table '{}' where the reference has '{}'", a.title, b.title));
        }
        let ca: Vec<&str> = a.columns.iter().map(|c| c.name.as_str()).collect();
        let cb: Vec<&str> = b.columns.iter().map(|c| c.name.as_str()).collect();
        if ca != cb {
            return Err(format!("table '{}': columns {ca:?} vs reference {cb:?}", a.title));
        }
        if a.rows.len() != b.rows.len() {
            return Err(format!(
                "table '{}': {} rows vs {} in the reference",
                a.title,
                a.rows.len(),
                b.rows.len()
            ));
        }
        for (ra, rb) in a.rows.iter().zip(&b.rows) {
            for (&x, &y) in ra.iter().zip(rb) {
                let scale = x.abs().max(y.abs());
                let d = if x == y { 0.0 } else { (x - y).abs() / scale };
                if !d.is_finite() {
                    return Err(format!("table '{}': non-finite value {x}", a.title));
                }
                worst = worst.max(d);
            }
        }
    }
    Ok(worst)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn render_parse_round_trip() {
        let mut t = Table::new("bgk nu=0.1", &[("N", true), ("L2_error", true), ("steps", false)]);
        t.push(vec![8.0, 1.234567890123456e-3, 100.0]);
        t.push(vec![16.0, 3.1e-4, 400.0]);
        let text = render("x", "quick", std::slice::from_ref(&t));
        let back = parse(&text).unwrap();
        assert_eq!(back.len(), 1);
        assert_eq!(back[0].columns.len(), 2);
        let d = compare(&[t.clone()], &back).unwrap();
        assert!(d < 1e-12, "{d}");
        let mut t2 = t;
        t2.rows[1][1] *= 1.0 + 1e-6;
        assert!(compare(&[t2], &back).unwrap() > REL_TOL);
    }
}
