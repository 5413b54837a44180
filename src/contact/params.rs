//! Contact parameters (the paper's Table 1) and the box walls.

use serde::{Deserialize, Serialize};

use crate::rigid::Vec3;

/// The parameters of the contact model (Derksen 2020, Table 1; lattice units), two switches
/// that turn its parts on or off (verification: an elastic-only collision must conserve
/// energy), and the sub-cycling (sub-steps, lubrication limiter).
///
/// It is also the case file's `[contacts]` section, as it stands: every key optional (Table 1
/// and the defaults below), unknown keys refused; its ranges are checked by
/// [`ContactParams::validate`] and, for `substeps`, by the case (1 … 1024).
///
/// With `δ` the normal and `δ_λ` the tangential distance of a marker pair and
/// `w = (λ − δ_λ)/λ` (module [`super`]):
///
/// ```text
/// elastic (δ < δ0, δ_λ < λ):        F_el = −k (δ0 − δ) w n̂
/// lubrication (δ* < δ_d, δ_λ < λ):  F_lub = (kⁿ Δuⁿ + kᵗ Δuᵗ)(1/δ* − 1/δ_d) w,   δ* = max(δ, δ_sat)
/// ```
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct ContactParams {
    /// Spring constant `k` of the elastic force (Table 1: 5.0).
    pub k: f64,
    /// Range `δ0` of the elastic force: it acts for `δ < δ0` (Table 1: 0.5).
    pub delta0: f64,
    /// Tangential range `λ`: marker pairs with `δ_λ ≥ λ` do not interact (Table 1: 0.5).
    pub lambda: f64,
    /// Normal lubrication coefficient `kⁿ` (Table 1: 5.0).
    pub k_n: f64,
    /// Range `δ_d` of the lubrication force: it acts for `δ < δ_d` (Table 1: 1.0).
    pub delta_d: f64,
    /// Saturation distance `δ_sat` of the lubrication force: `δ* = max(δ, δ_sat)` (Table 1: 0.2).
    pub delta_sat: f64,
    /// Tangential lubrication coefficient `kᵗ` (Table 1: 0.5).
    pub k_t: f64,
    /// Whether the elastic force acts (default `true`).
    pub elastic: bool,
    /// Whether the lubrication forces act (default `true`).
    pub lubrication: bool,
    /// Whether the sub-cycling limits the lubrication to its stable range (default `false`; module
    /// [`super`], "Lubrication limiter"): each body pair's lubrication load in a sub-step of
    /// `h` is multiplied by `min(1, 0.9/(h (ρ_a + ρ_b)))`, `ρ` a bound of each body's damping
    /// rate. `false`: the explicit law, which needs `h · damping_rate < 2`.
    pub lubrication_limiter: bool,
    /// Contact sub-steps per fluid step (≥ 1; default [`super::DEFAULT_SUBSTEPS`]; module
    /// [`super`], "Stability analysis"). Used by whoever sub-cycles the bodies
    /// ([`super::step_bodies`]).
    pub substeps: usize,
    /// Lubrication sub-steps per contact sub-step (≥ 1; default 1; module [`super`],
    /// "Lubrication sub-steps"). Above 1, each contact evaluation also freezes the lubrication
    /// of every interacting pair as a linear map of the bodies' velocities (its normals,
    /// weights, gaps and lever arms those of the evaluation), and the sub-step is split into
    /// this many parts, each with the lubrication recomputed from the bodies' current
    /// velocities through that map and the elastic load held: the stiff damping gets short
    /// steps without a marker-pair evaluation for each. 1: Table 1's law at every evaluation,
    /// bitwise the scheme without this option. Not with the lubrication limiter. Written into
    /// a case's TOML (and so into its fingerprint) only when not 1, so that the fingerprints
    /// of checkpoints and cached beds made before it existed stay valid.
    #[serde(skip_serializing_if = "is_one")]
    pub lubrication_substeps: usize,
    /// How each contact sub-step integrates the lubrication damping (default
    /// [`Damping::Explicit`]; module [`super`], "Implicit damping"). Written into a case's TOML
    /// (and so into its fingerprint) only when not the default, so that the fingerprints of
    /// checkpoints and cached beds made before it existed stay valid.
    #[serde(skip_serializing_if = "Damping::is_explicit")]
    pub damping: Damping,
}

/// How the contact sub-steps integrate Table 1's lubrication damping (`[contacts] damping`).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum Damping {
    /// Explicit Euler on the damping (the law evaluated at the current velocities): stable for
    /// `h · damping_rate < 2`, hence [`super::DEFAULT_SUBSTEPS`] sub-steps.
    #[default]
    Explicit,
    /// Backward Euler on the damping (module [`super`], "Implicit damping"): the damping loads at
    /// the end-of-sub-step velocities, from one sparse symmetric positive-definite solve per
    /// sub-step; unconditionally stable, so the sub-step count is set by the spring
    /// ([`super::IMPLICIT_SUBSTEPS`] recommended).
    Implicit,
}

impl Damping {
    /// The case-file spellings, in words (for error messages).
    pub const ALLOWED: &'static str = "\"explicit\" or \"implicit\"";

    /// Whether this is [`Damping::Explicit`] (serde: the default is not written).
    pub fn is_explicit(&self) -> bool {
        *self == Damping::Explicit
    }

    /// The case-file spelling.
    pub fn name(&self) -> &'static str {
        match self {
            Damping::Explicit => "explicit",
            Damping::Implicit => "implicit",
        }
    }
}

/// Whether `n` is 1 (serde: `lubrication_substeps` at its default is not written).
fn is_one(n: &usize) -> bool {
    *n == 1
}

impl Default for ContactParams {
    /// Table 1 of Derksen (2020), both parts on.
    fn default() -> Self {
        Self {
            k: 5.0,
            delta0: 0.5,
            lambda: 0.5,
            k_n: 5.0,
            delta_d: 1.0,
            delta_sat: 0.2,
            k_t: 0.5,
            elastic: true,
            lubrication: true,
            lubrication_limiter: false,
            substeps: super::DEFAULT_SUBSTEPS,
            lubrication_substeps: 1,
            damping: Damping::Explicit,
        }
    }
}

/// The most lubrication sub-steps per contact sub-step ([`ContactParams::lubrication_substeps`]).
pub const LUBRICATION_SUBSTEPS_MAX: usize = 1024;

/// A contact parameter outside its allowed range.
#[derive(Clone, Debug, PartialEq, thiserror::Error)]
#[error("contact parameter {name} = {value} is out of range: it must be {allowed}")]
pub struct ContactParamError {
    /// The parameter's field name (`"delta_sat"`, …).
    pub name: &'static str,
    /// The value given.
    pub value: f64,
    /// The allowed range, in words (e.g. `"in (0, delta_d = 1)"`).
    pub allowed: String,
}

impl ContactParams {
    /// Checks that `k, δ0, λ, kⁿ, δ_d, kᵗ` are positive and finite, that
    /// `0 < δ_sat < δ_d`, and that `lubrication_substeps` is in
    /// `[1, LUBRICATION_SUBSTEPS_MAX]` (and 1 with the limiter on); the error names the first
    /// offending parameter and its range.
    pub fn validate(&self) -> Result<(), ContactParamError> {
        let positive = [
            ("k", self.k),
            ("delta0", self.delta0),
            ("lambda", self.lambda),
            ("k_n", self.k_n),
            ("delta_d", self.delta_d),
            ("k_t", self.k_t),
        ];
        for (name, value) in positive {
            if !(value.is_finite() && value > 0.0) {
                return Err(ContactParamError { name, value, allowed: "positive and finite".into() });
            }
        }
        if !(self.delta_sat > 0.0 && self.delta_sat < self.delta_d) {
            return Err(ContactParamError {
                name: "delta_sat",
                value: self.delta_sat,
                allowed: format!("in (0, delta_d = {})", self.delta_d),
            });
        }
        if !(1..=LUBRICATION_SUBSTEPS_MAX).contains(&self.lubrication_substeps) {
            return Err(ContactParamError {
                name: "lubrication_substeps",
                value: self.lubrication_substeps as f64,
                allowed: format!("an integer in [1, {LUBRICATION_SUBSTEPS_MAX}] (lubrication sub-steps per contact sub-step)"),
            });
        }
        if self.lubrication_substeps > 1 && self.lubrication_limiter {
            return Err(ContactParamError {
                name: "lubrication_substeps",
                value: self.lubrication_substeps as f64,
                allowed: "1 when lubrication_limiter = true (the two are alternative treatments of the stiff damping)".into(),
            });
        }
        if self.damping == Damping::Implicit && (self.lubrication_substeps > 1 || self.lubrication_limiter) {
            let (name, value) = if self.lubrication_limiter {
                ("lubrication_limiter", 1.0)
            } else {
                ("lubrication_substeps", self.lubrication_substeps as f64)
            };
            return Err(ContactParamError {
                name,
                value,
                allowed: "off (lubrication_limiter = false, lubrication_substeps = 1) when damping = \"implicit\" (they are alternative treatments of the stiff damping)".into(),
            });
        }
        Ok(())
    }

    /// Whether an evaluation hands the lubrication on as operators (module `operator`) and
    /// keeps only the elastic part in its loads: with lubrication sub-steps or implicit damping.
    pub(crate) fn operators(&self) -> bool {
        self.lubrication_substeps > 1 || self.damping == Damping::Implicit
    }

    /// The normal range of the model: the largest `δ` at which any enabled part acts,
    /// `max(δ0 [elastic], δ_d [lubrication])` (0 if both are off).
    pub fn cutoff(&self) -> f64 {
        let e = if self.elastic { self.delta0 } else { 0.0 };
        let l = if self.lubrication { self.delta_d } else { 0.0 };
        e.max(l)
    }

    /// The largest marker–marker distance considered, `√(cutoff² + λ²)`: every pair with
    /// `|δ| < cutoff` and `δ_λ < λ` lies within it (module [`super`], "Which pairs").
    pub fn reach(&self) -> f64 {
        let c = self.cutoff();
        if c > 0.0 {
            c.hypot(self.lambda)
        } else {
            0.0
        }
    }
}

/// The fixed walls of the box: per axis, an optional wall on the low and on the high side,
/// given by the coordinate of its plane.
///
/// With half-way bounce-back on a grid of `n` nodes along an axis (nodes at `0 … n − 1`), the
/// walls lie at `−0.5` and `n − 0.5` ([`Walls::closed_box`]). The fluid (and the particles) are
/// on the inner side: between `planes[a][0]` and `planes[a][1]`.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct Walls {
    /// `planes[axis][side]`: `side = 0` the low wall (outward normal `−e_axis`), `side = 1` the
    /// high wall (outward normal `+e_axis`); `None`: no wall (e.g. a periodic axis).
    pub planes: [[Option<f64>; 2]; 3],
}

impl Walls {
    /// No walls.
    pub fn none() -> Self {
        Self::default()
    }

    /// Walls on both sides of every axis where `walled[a]` holds, at the half-way bounce-back
    /// positions `−0.5` and `n[a] − 0.5` of a grid of `n[a]` nodes.
    pub fn bounce_back(n: [usize; 3], walled: [bool; 3]) -> Self {
        let mut w = Self::none();
        for a in 0..3 {
            if walled[a] {
                w.planes[a] = [Some(-0.5), Some(n[a] as f64 - 0.5)];
            }
        }
        w
    }

    /// A closed box of `n[0] × n[1] × n[2]` nodes: walls on all six faces (the paper's tank).
    pub fn closed_box(n: [usize; 3]) -> Self {
        Self::bounce_back(n, [true; 3])
    }

    /// Whether there is any wall.
    pub fn is_empty(&self) -> bool {
        self.planes.iter().flatten().all(Option::is_none)
    }

    /// The walls in their fixed order (axis 0 low, axis 0 high, axis 1 low, …) as
    /// `(axis, side, plane coordinate, outward normal n̂)`; `n̂` points from the fluid into the
    /// wall (`−e_axis` for the low wall).
    pub fn iter(&self) -> impl Iterator<Item = (usize, usize, f64, Vec3)> + '_ {
        (0..3).flat_map(move |a| {
            (0..2).filter_map(move |s| {
                self.planes[a][s].map(|p| {
                    let mut n = Vec3::zeros();
                    n[a] = if s == 0 { -1.0 } else { 1.0 };
                    (a, s, p, n)
                })
            })
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn defaults_are_table_1_and_valid() {
        let p = ContactParams::default();
        assert_eq!(
            (p.k, p.delta0, p.lambda, p.k_n, p.delta_d, p.delta_sat, p.k_t),
            (5.0, 0.5, 0.5, 5.0, 1.0, 0.2, 0.5)
        );
        p.validate().unwrap();
        assert_eq!(p.cutoff(), 1.0);
        assert!((p.reach() - 1.25f64.sqrt()).abs() < 1e-15);
    }

    #[test]
    fn validation_names_the_parameter_and_range() {
        let e = ContactParams { delta_sat: 1.5, ..Default::default() }.validate().unwrap_err();
        assert_eq!(e.name, "delta_sat");
        let msg = e.to_string();
        assert!(msg.contains("delta_sat = 1.5") && msg.contains("(0, delta_d = 1)"), "{msg}");
        let e = ContactParams { k_t: f64::NAN, ..Default::default() }.validate().unwrap_err();
        assert_eq!(e.name, "k_t");
        assert!(e.to_string().contains("positive and finite"));
        let e = ContactParams { lambda: -1.0, ..Default::default() }.validate().unwrap_err();
        assert_eq!(e.name, "lambda");
        let e = ContactParams { delta_sat: 0.0, ..Default::default() }.validate().unwrap_err();
        assert_eq!(e.name, "delta_sat");
        let e = ContactParams { lubrication_substeps: 0, ..Default::default() }.validate().unwrap_err();
        assert_eq!(e.name, "lubrication_substeps");
        assert!(e.to_string().contains("[1, 1024]"), "{e}");
        let both = ContactParams { lubrication_substeps: 4, lubrication_limiter: true, ..Default::default() };
        let e = both.validate().unwrap_err();
        assert!(e.to_string().contains("lubrication_limiter"), "{e}");
        ContactParams { lubrication_substeps: 4, ..Default::default() }.validate().unwrap();
    }

    /// The default `lubrication_substeps` is not written (the fingerprints of earlier cases,
    /// checkpoints and cached beds stay valid); another value is, and reads back.
    #[test]
    fn lubrication_substeps_is_written_only_when_not_the_default() {
        let text = toml::to_string(&ContactParams::default()).unwrap();
        assert!(!text.contains("lubrication_substeps"), "{text}");
        let p = ContactParams { lubrication_substeps: 4, ..Default::default() };
        let text = toml::to_string(&p).unwrap();
        assert!(text.contains("lubrication_substeps = 4"), "{text}");
        assert_eq!(toml::from_str::<ContactParams>(&text).unwrap(), p);
    }

    /// `damping`: written only when implicit (fingerprints of earlier cases stay valid), read
    /// back, refused with the limiter or lubrication sub-steps, its spelling checked by serde.
    #[test]
    fn damping_key() {
        let text = toml::to_string(&ContactParams::default()).unwrap();
        assert!(!text.contains("damping"), "{text}");
        let p = ContactParams { damping: Damping::Implicit, substeps: 2, ..Default::default() };
        p.validate().unwrap();
        let text = toml::to_string(&p).unwrap();
        assert!(text.contains("damping = \"implicit\""), "{text}");
        assert_eq!(toml::from_str::<ContactParams>(&text).unwrap(), p);
        let e = ContactParams { lubrication_limiter: true, ..p }.validate().unwrap_err();
        assert_eq!(e.name, "lubrication_limiter");
        assert!(e.to_string().contains("damping = \"implicit\""), "{e}");
        let e = ContactParams { lubrication_substeps: 4, ..p }.validate().unwrap_err();
        assert_eq!(e.name, "lubrication_substeps");
        let e = toml::from_str::<ContactParams>("damping = \"backward\"").unwrap_err().to_string();
        assert!(e.contains("backward") && e.contains("explicit") && e.contains("implicit"), "{e}");
    }

    #[test]
    fn box_walls() {
        let w = Walls::closed_box([10, 20, 30]);
        let v: Vec<_> = w.iter().collect();
        assert_eq!(v.len(), 6);
        assert_eq!((v[0].0, v[0].1, v[0].2), (0, 0, -0.5));
        assert_eq!(v[0].3, Vec3::new(-1.0, 0.0, 0.0));
        assert_eq!((v[5].0, v[5].1, v[5].2), (2, 1, 29.5));
        assert_eq!(v[5].3, Vec3::new(0.0, 0.0, 1.0));
        assert!(Walls::none().is_empty());
        assert_eq!(Walls::bounce_back([4, 4, 8], [false, false, true]).iter().count(), 2);
    }
}
