//! Checks and the JSON report.

use serde::Serialize;

/// A number or a short text (for `expected` and `tolerance`).
#[derive(Clone, Debug, PartialEq, Serialize)]
#[serde(untagged)]
pub enum Value {
    /// A number.
    Num(f64),
    /// A description, e.g. `">= 1.8"`.
    Text(String),
}

impl std::fmt::Display for Value {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            Value::Num(v) => write!(f, "{}", short(*v)),
            Value::Text(s) => write!(f, "{s}"),
        }
    }
}

/// A number in at most 4 significant digits (for the summary table).
pub fn short(v: f64) -> String {
    if v == 0.0 {
        "0".into()
    } else if v.is_finite() && v == v.trunc() && v.abs() < 1e9 {
        format!("{}", v as i64)
    } else if v.is_finite() && (1e-3..1e4).contains(&v.abs()) {
        format!("{v:.4}")
    } else {
        format!("{v:.3e}")
    }
}

/// One verified claim: a measured value against what is expected, within a tolerance whose
/// reason is stated.
#[derive(Clone, Debug, Serialize)]
pub struct Check {
    /// The case that made it.
    pub case: String,
    /// What was measured (e.g. `"bgk_order"`).
    pub metric: String,
    /// The measured value.
    pub value: f64,
    /// The exact or theoretical value.
    pub expected: Value,
    /// The accepted deviation (a number: `|value − expected| ≤ tolerance`), or a text when the
    /// check is one-sided (e.g. `">= 1.8"`).
    pub tolerance: Value,
    /// Whether it holds.
    pub pass: bool,
    /// Why the tolerance is what it is.
    pub reason: String,
}

impl Check {
    /// `value ≤ bound`, for an error measure whose exact value is 0.
    pub fn at_most(case: &str, metric: impl Into<String>, value: f64, bound: f64, reason: &str) -> Self {
        Self {
            case: case.into(),
            metric: metric.into(),
            value,
            expected: Value::Num(0.0),
            tolerance: Value::Num(bound),
            pass: value.is_finite() && value.abs() <= bound,
            reason: reason.into(),
        }
    }

    /// `value ≥ bound`, for e.g. an observed order whose theoretical value is `expected`.
    pub fn at_least(
        case: &str,
        metric: impl Into<String>,
        value: f64,
        expected: f64,
        bound: f64,
        reason: &str,
    ) -> Self {
        Self {
            case: case.into(),
            metric: metric.into(),
            value,
            expected: Value::Num(expected),
            tolerance: Value::Text(format!(">= {bound}")),
            pass: value.is_finite() && value >= bound,
            reason: reason.into(),
        }
    }

    /// `value == expected` exactly (counts, bitwise comparisons).
    pub fn exact(case: &str, metric: impl Into<String>, value: f64, expected: f64, reason: &str) -> Self {
        Self {
            case: case.into(),
            metric: metric.into(),
            value,
            expected: Value::Num(expected),
            tolerance: Value::Num(0.0),
            pass: value == expected,
            reason: reason.into(),
        }
    }
}

/// Writes the checks as a pretty JSON array, creating the parent directory.
pub fn write_json(path: &std::path::Path, checks: &[Check]) -> std::io::Result<()> {
    if let Some(dir) = path.parent() {
        std::fs::create_dir_all(dir)?;
    }
    let text = serde_json::to_string_pretty(checks).map_err(std::io::Error::other)?;
    std::fs::write(path, text + "\n")
}

/// The summary table: one line per check.
pub fn summary(checks: &[Check]) -> String {
    let rows: Vec<[String; 6]> = checks
        .iter()
        .map(|c| {
            [
                c.case.clone(),
                c.metric.clone(),
                short(c.value),
                c.expected.to_string(),
                c.tolerance.to_string(),
                if c.pass { "ok" } else { "FAIL" }.to_string(),
            ]
        })
        .collect();
    let head = ["case", "metric", "value", "expected", "tolerance", "pass"];
    let mut w = head.map(str::len);
    for r in &rows {
        for k in 0..6 {
            w[k] = w[k].max(r[k].chars().count());
        }
    }
    let line = |cells: &[String]| {
        let mut s = String::new();
        for (k, c) in cells.iter().enumerate() {
            let pad = w[k] - c.chars().count();
            if k == 2 {
                s.push_str(&" ".repeat(pad));
                s.push_str(c);
            } else {
                s.push_str(c);
                if k + 1 < cells.len() {
                    s.push_str(&" ".repeat(pad));
                }
            }
            if k + 1 < cells.len() {
                s.push_str("  ");
            }
        }
        s.trim_end().to_string() + "\n"
    };
    let mut out = line(&head.map(String::from));
    out.push_str(&line(&w.map(|n| "-".repeat(n))));
    for r in &rows {
        out.push_str(&line(r));
    }
    out
}
