//! The checks of `slurry reproduce`'s options before anything starts (each message names the
//! option, the value and the allowed range), and the stirred run's contact settings where they
//! differ from the case's ([`ContactOverrides`]).

use serde::{Deserialize, Serialize};

use slurry::case::Case;

use super::{MAX_SCALE, MIN_SCALE};

/// Checks a scale before anything starts: finite, `MIN_SCALE ≤ s ≤ MAX_SCALE`.
///
/// # Errors
/// The message names `--scale`, the value and the allowed range, and why.
pub fn check_scale(s: f64) -> Result<(), String> {
    if s.is_finite() && (MIN_SCALE..=MAX_SCALE).contains(&s) {
        return Ok(());
    }
    Err(format!(
        "--scale {s}: allowed {MIN_SCALE} ≤ s ≤ {MAX_SCALE} (1 is the paper's 251 × 251 × 240 with d = 12, 0.5 is \
         d = 6; below {MIN_SCALE} the random placement cannot fit the paper's particles: the particle count is \
         the paper's at every scale, and the wall margin and clearance do not shrink with s)"
    ))
}

/// Checks a number of revolutions after the ramp before anything starts: finite and positive.
///
/// # Errors
/// The message names `--revolutions` and the value.
pub fn check_revolutions(revolutions: f64) -> Result<(), String> {
    if revolutions.is_finite() && revolutions > 0.0 {
        return Ok(());
    }
    Err(format!("--revolutions {revolutions}: must be finite and > 0"))
}

/// The allowed contact sub-steps per fluid step (`--contact-substeps`; `[contacts] substeps`).
pub const CONTACT_SUBSTEPS_RANGE: (usize, usize) = (1, 1024);

/// Checks `--lubrication-substeps` (and that it is not combined with `--lubrication-limiter`)
/// before anything starts.
///
/// # Errors
/// The message names the option, the value and the allowed range.
pub fn check_lubrication_substeps(m: usize, limiter: bool) -> Result<(), String> {
    let hi = CONTACT_SUBSTEPS_RANGE.1; // the same bound as contact::LUBRICATION_SUBSTEPS_MAX
    if !(1..=hi).contains(&m) {
        return Err(format!("--lubrication-substeps {m} is out of range: it must be in [1, {hi}]"));
    }
    if m > 1 && limiter {
        return Err(format!(
            "--lubrication-substeps {m} with --lubrication-limiter: choose one (both treat the stiff lubrication damping)"
        ));
    }
    Ok(())
}

/// Checks `--contact-substeps` before anything starts.
///
/// # Errors
/// The message names the option, the value and the allowed range.
pub fn check_contact_substeps(n: usize) -> Result<(), String> {
    let (lo, hi) = CONTACT_SUBSTEPS_RANGE;
    if (lo..=hi).contains(&n) {
        return Ok(());
    }
    Err(format!("--contact-substeps {n} is out of range: it must be in [{lo}, {hi}]"))
}

/// Checks `slurry reproduce --mach-limit L`: `0 < L ≤ 1`, as `[run] mach_limit`.
///
/// # Errors
/// The message names the option, the value and the allowed range.
pub fn check_mach_limit(l: f64) -> Result<(), String> {
    if slurry::case::mach_limit_allowed(l) {
        return Ok(());
    }
    Err(format!(
        "--mach-limit {l} is out of range: it must be in (0, 1] (default {}; the run stops when |u|/c_s exceeds it anywhere)",
        slurry::case::default_mach_limit()
    ))
}

/// Contact settings of the stirred run that differ from the case's (`slurry reproduce
/// --contact-substeps N --lubrication-limiter`): to measure a cheaper contact scheme against
/// the default on the same bed. The bed is settled with the case's settings either way (so
/// it is shared through the cache); the stirred run's `case.toml`, `reproduce.json` and
/// `report.md` record the change, and its fingerprint differs, so a `--resume` with other
/// settings is refused.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize, Deserialize)]
pub struct ContactOverrides {
    /// Contact sub-steps per fluid step (`None`: the case's, [`slurry::contact::DEFAULT_SUBSTEPS`]).
    pub substeps: Option<usize>,
    /// Turn the lubrication limiter on ([`slurry::contact::ContactParams::lubrication_limiter`]).
    pub lubrication_limiter: bool,
    /// Lubrication sub-steps per contact sub-step (`None`: the case's, 1;
    /// [`slurry::contact::ContactParams::lubrication_substeps`]).
    #[serde(default)]
    pub lubrication_substeps: Option<usize>,
    /// Integrate the lubrication damping implicitly ([`slurry::contact::Damping::Implicit`]).
    #[serde(default)]
    pub implicit_damping: bool,
}

impl ContactOverrides {
    /// Whether the case's settings are kept.
    pub fn is_default(&self) -> bool {
        *self == Self::default()
    }

    /// Applies the overrides to `case`'s `[contacts]` (nothing without one).
    pub fn apply(&self, case: &mut Case) {
        if let Some(c) = case.contacts.as_mut() {
            if let Some(n) = self.substeps {
                c.substeps = n;
            }
            c.lubrication_limiter |= self.lubrication_limiter;
            if let Some(m) = self.lubrication_substeps {
                c.lubrication_substeps = m;
            }
            if self.implicit_damping {
                c.damping = slurry::contact::Damping::Implicit;
            }
        }
    }

    /// In words, for the report: `None` for the case's settings.
    pub fn describe(&self) -> Option<String> {
        if self.is_default() {
            return None;
        }
        let n =
            self.substeps.map_or_else(|| "the case's sub-steps".to_string(), |n| format!("{n} sub-steps"));
        let limiter = if self.lubrication_limiter { ", lubrication limiter on" } else { "" };
        let lub = self.lubrication_substeps.filter(|&m| m > 1).map_or_else(String::new, |m| {
            format!(", {m} lubrication sub-steps each (frozen lubrication operators)")
        });
        let implicit = if self.implicit_damping { ", lubrication damping implicit" } else { "" };
        Some(format!(
            "{n} per fluid step{limiter}{lub}{implicit} (not the default: 8 sub-steps, explicit lubrication)"
        ))
    }
}
