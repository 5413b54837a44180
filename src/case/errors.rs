//! Case-file errors ([`CaseError`], [`CaseErrorKind`]: file, dotted key, value, allowed
//! range) and the rewriting of the TOML parser's messages into them (unknown keys with the
//! allowed ones, type errors with line and column and the expected type in words).

use super::*;

/// A case-file error: the file and what is wrong in it.
#[derive(Debug, thiserror::Error)]
#[error("{}: {kind}", file.display())]
pub struct CaseError {
    /// The case file (or the name given to [`Case::parse`]).
    pub file: PathBuf,
    /// What is wrong.
    pub kind: CaseErrorKind,
}

/// What is wrong in a case file. Every variant names the key (dotted, e.g. `fluid.tau`).
#[derive(Debug, thiserror::Error)]
pub enum CaseErrorKind {
    /// The file cannot be read.
    #[error("cannot read the case file: {0}")]
    Read(std::io::Error),
    /// Refused before it is parsed: not a regular file, or too large ([`super::input`]).
    #[error("{0}")]
    Refused(String),
    /// Not valid TOML.
    #[error("TOML syntax error at line {line}, column {column}: {message}")]
    Syntax {
        /// 1-based line.
        line: usize,
        /// 1-based column.
        column: usize,
        /// The parser's message.
        message: String,
    },
    /// A key that the format does not have.
    #[error("unknown key `{key}`; allowed: {allowed}")]
    UnknownKey {
        /// The dotted key.
        key: String,
        /// The keys allowed at that place, comma-separated.
        allowed: String,
    },
    /// A required key is absent.
    #[error("missing key `{key}` ({what})")]
    Missing {
        /// The dotted key.
        key: String,
        /// What it should be.
        what: String,
    },
    /// A value of the wrong type or an unknown option (from serde).
    #[error("{}line {line}, column {column}: {message}", key.as_ref().map(|k| format!("`{k}` at ")).unwrap_or_default())]
    Type {
        /// The dotted key, when it could be located.
        key: Option<String>,
        /// 1-based line.
        line: usize,
        /// 1-based column.
        column: usize,
        /// Serde's message (names the expected type or the allowed options).
        message: String,
    },
    /// A value out of range or inconsistent with another.
    #[error("{key} = {value}: {allowed}")]
    Invalid {
        /// The dotted key.
        key: String,
        /// The value as written (normalised).
        value: String,
        /// What is allowed.
        allowed: String,
    },
}

impl CaseErrorKind {
    /// The dotted key the error is about, if any.
    pub fn key(&self) -> Option<&str> {
        match self {
            CaseErrorKind::Read(_) | CaseErrorKind::Refused(_) | CaseErrorKind::Syntax { .. } => None,
            CaseErrorKind::UnknownKey { key, .. }
            | CaseErrorKind::Missing { key, .. }
            | CaseErrorKind::Invalid { key, .. } => Some(key),
            CaseErrorKind::Type { key, .. } => key.as_deref(),
        }
    }
}

/// An [`CaseErrorKind::Invalid`]; computed limits in `allowed` are rounded for people
/// ([`crate::util::humanize_numbers`]: `2.4000000000000004` reads `2.4`).
pub(crate) fn invalid(
    key: impl Into<String>,
    value: impl fmt::Display,
    allowed: impl Into<String>,
) -> CaseErrorKind {
    CaseErrorKind::Invalid {
        key: key.into(),
        value: short_value(value.to_string()),
        allowed: crate::util::humanize_numbers(&allowed.into()),
    }
}

/// A value as written, but a number that Rust's `Display` spells with many digits
/// (`1e-300` as 0.000…001) in exponent form, which reads back the same.
fn short_value(v: String) -> String {
    match v.parse::<f64>() {
        Ok(x) if v.len() > 12 && x.is_finite() => {
            let e = format!("{x:e}");
            if e.len() < v.len() {
                e
            } else {
                v
            }
        }
        _ => v,
    }
}

/// Checks every key of the parsed document against the fields of the section structs.
pub(super) fn check_unknown_keys(doc: &toml::Table) -> Result<(), CaseErrorKind> {
    let top = keys::struct_fields::<Case>();
    let unknown = |key: String, allowed: &[&str]| {
        let mut allowed = allowed.join(", ");
        if key.ends_with(".gravity") {
            allowed.push_str(" (gravity is a top-level key: write it above the first [table])");
        }
        CaseErrorKind::UnknownKey { key, allowed }
    };
    let check_table = |name: &str, t: &toml::Table, fields: &[&str]| -> Result<(), CaseErrorKind> {
        match t.keys().find(|k| !fields.contains(&k.as_str())) {
            Some(k) => Err(unknown(format!("{name}.{k}"), fields)),
            None => Ok(()),
        }
    };
    for (name, value) in doc {
        let fields: &[&str] = match name.as_str() {
            "gravity" => continue,
            "domain" => keys::struct_fields::<DomainSection>(),
            "fluid" => keys::struct_fields::<FluidSection>(),
            "boundaries" => keys::struct_fields::<BoundarySection>(),
            "initial" => keys::struct_fields::<InitialSection>(),
            "run" => keys::struct_fields::<RunSection>(),
            "ibm" => keys::struct_fields::<IbmSection>(),
            "contacts" => keys::struct_fields::<crate::contact::ContactParams>(),
            "particles" => keys::struct_fields::<ParticleSpec>(),
            "random_particles" => keys::struct_fields::<RandomParticles>(),
            "impeller" => keys::struct_fields::<ImpellerSection>(),
            _ => return Err(unknown(name.clone(), top)),
        };
        let array_of_tables = name == "particles" || name == "random_particles";
        match value {
            // `[particles]` written for `[[particles]]`: serde's "expected a sequence" names
            // the line and the fix (`type_error`).
            toml::Value::Table(t) => check_table(name, t, fields)?,
            toml::Value::Array(items) if array_of_tables => {
                for (i, item) in items.iter().enumerate() {
                    match item {
                        toml::Value::Table(t) => check_table(&format!("{name}[{i}]"), t, fields)?,
                        other => {
                            return Err(CaseErrorKind::Invalid {
                                key: format!("{name}[{i}]"),
                                value: other.to_string(),
                                allowed: format!(
                                "each entry is a table of keys ({}): write [[{name}]] with one key per line",
                                fields.join(", ")
                            ),
                            })
                        }
                    }
                }
            }
            other => {
                let (what, write) = if array_of_tables {
                    ("an array of tables", format!("[[{name}]] (one per entry)"))
                } else {
                    ("a table", format!("[{name}] with its keys on the lines below"))
                };
                return Err(CaseErrorKind::Invalid {
                    key: name.clone(),
                    value: other.to_string(),
                    allowed: format!("{name} must be {what}: write {write}; keys: {}", fields.join(", ")),
                });
            }
        }
    }
    Ok(())
}

/// Turns a serde error from `toml::from_str` into a located, keyed error.
pub(super) fn type_error(text: &str, e: &toml::de::Error) -> CaseErrorKind {
    let msg = one_line(e.message());
    let span = e.span();
    let (line, column) = span.as_ref().map_or((0, 0), |s| keys::line_column(text, s.start));
    let key = span.as_ref().and_then(|s| keys::key_at(text, s.start));
    // "missing field `nx`": the span covers the table that lacks it.
    if let Some(field) = msg.strip_prefix("missing field `").and_then(|r| r.strip_suffix('`')) {
        let key = match key {
            Some(section) if !keys::struct_fields::<Case>().contains(&field) => {
                format!("{section}.{field}")
            }
            _ => field.to_string(),
        };
        let what = missing_what(&key);
        return CaseErrorKind::Missing { key, what };
    }
    let mut message = plain_types(&msg);
    if let Some(k) = key.as_deref().filter(|k| *k == "particles" || *k == "random_particles") {
        if message.contains("expected a sequence") {
            message.push_str(&format!(" (write [[{k}]], an array of tables: one per entry)"));
        }
    }
    CaseErrorKind::Type { key, line, column, message }
}

/// Replaces Rust type names in serde messages with what a case-file author writes.
fn plain_types(msg: &str) -> String {
    msg.replace("expected usize", "expected a non-negative integer")
        .replace("expected u64", "expected a non-negative integer")
        .replace("expected f64", "expected a number")
}

/// A parser message on one line.
pub(super) fn one_line(msg: &str) -> String {
    msg.trim().lines().map(str::trim).filter(|l| !l.is_empty()).collect::<Vec<_>>().join("; ")
}

/// What a required key should hold (for "missing key" messages).
fn missing_what(key: &str) -> String {
    match key {
        "domain" => "a [domain] table with nx, ny, nz".into(),
        "fluid" => "a [fluid] table with nu or tau".into(),
        "boundaries" => "a [boundaries] table with x_min, x_max, y_min, y_max, z_min, z_max".into(),
        "run" => "a [run] table with steps and output_every".into(),
        "domain.nx" | "domain.ny" | "domain.nz" => "an integer >= 1".into(),
        "run.steps" => "an integer >= 1".into(),
        "run.output_every" => "an integer, 1 <= output_every <= run.steps".into(),
        k if k.starts_with("particles[") || k.starts_with("random_particles[") => {
            match k.rsplit('.').next().unwrap_or("") {
                "shape" => "\"sphere\" or \"cylinder\"".into(),
                "diameter" => "a number > 0 (lattice units)".into(),
                "density" => "the density ratio rho_p/rho_f > 0".into(),
                "position" => "[x, y, z] (lattice units)".into(),
                "seed" => "an integer 0 <= seed < 2^63".into(),
                _ => "required".into(),
            }
        }
        k if k.starts_with("boundaries.") => {
            "\"periodic\", \"no_slip\" or { moving_wall = [ux, uy, uz] }".into()
        }
        _ => "required".into(),
    }
}
