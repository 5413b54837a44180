//! `[impeller]`: a revolving disk or pitched-blade turbine on a shaft from the lid (physics.md
//! §2 for the defaults the paper leaves open).
//!
//! ```toml
//! [impeller]
//! kind = "pbt"              # or "disk"
//! diameter = 132.0          # D
//! speed = 2.5e-4            # N, revolutions per time step (after the ramp)
//! ramp_steps = 4000         # linear ramp from rest (default 0: none)
//! # centre = [125.0, 125.0, 119.5]   default: the box centre
//! # PBT (defaults in brackets): blades [4], pitch_deg [45], blade_width [0.2 D],
//! #   blade_thickness [3 D/132], hub_diameter [0.2 D], hub_height [the blades' vertical
//! #   extent], pumping ["down"]
//! # disk: thickness [4 D/132]
//! # shaft: shaft [true] (from the impeller up to the z_max face), shaft_diameter [0.08 D]
//! ```
//!
//! The impeller turns about the vertical axis through `centre`, counter-clockwise seen from
//! above for `speed > 0`. It is a prescribed body of the coupling: its markers take part in
//! the immersed boundary forcing and in the contacts with particles (infinitely heavy).

use std::f64::consts::PI;
use std::sync::Arc;

use serde::{Deserialize, Serialize};

use super::{fmt_vec, invalid, mach, Case, CaseErrorKind};
use crate::lattice::Face;
use crate::rigid::impeller::{
    blade_vertical_extent, ImpellerGeometry, ImpellerKind, Pumping, RampedRotation,
};
use crate::rigid::{Impeller, Motion, RetractionError, RigidBody, Shape, Vec3};

/// The impeller kind of the case file.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum ImpellerKindSpec {
    /// A flat disk.
    Disk,
    /// A pitched-blade turbine.
    Pbt,
}

/// The pumping direction of the case file.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum PumpingSpec {
    /// Down (default; the paper).
    #[default]
    Down,
    /// Up.
    Up,
}

/// `[impeller]`: see the module docs. Dimensions in lattice units.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ImpellerSection {
    /// `"disk"` or `"pbt"`.
    pub kind: ImpellerKindSpec,
    /// Impeller diameter `D` (> 0; the paper: 132 at full scale).
    pub diameter: f64,
    /// Revolutions per time step `N` after the ramp (`0 < |N|`, tip Mach `πND/c_s` within
    /// `run.mach_limit`; the paper: 1/4000).
    pub speed: f64,
    /// Steps of the linear start-up ramp (default 0; the paper: 4000).
    #[serde(default)]
    pub ramp_steps: u64,
    /// Centre (on the axis, in the impeller's mid-plane), lattice coordinates (default: the
    /// box centre `((n_x − 1)/2, (n_y − 1)/2, (n_z − 1)/2)`).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub centre: Option<[f64; 3]>,
    /// Disk thickness (disk only; default `4 D/132`).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub thickness: Option<f64>,
    /// Number of blades (PBT; default 4).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub blades: Option<usize>,
    /// Blade pitch in degrees (PBT; default 45).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub pitch_deg: Option<f64>,
    /// Blade width along its surface (PBT; default `0.2 D`).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub blade_width: Option<f64>,
    /// Blade thickness (PBT; default `3 D/132`).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub blade_thickness: Option<f64>,
    /// Hub diameter (PBT; default `0.2 D`).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub hub_diameter: Option<f64>,
    /// Hub height (PBT; default the blades' vertical extent `w sin θ + t cos θ`).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub hub_height: Option<f64>,
    /// `"down"` (default) or `"up"` (PBT).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub pumping: Option<PumpingSpec>,
    /// Whether a shaft runs from the impeller up to the `z_max` face (default true).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub shaft: Option<bool>,
    /// Shaft diameter (default `0.08 D`).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub shaft_diameter: Option<f64>,
}

/// The impeller of a case, ready to be coupled.
#[derive(Clone, Debug)]
pub struct ImpellerSetup {
    /// Its shape.
    pub shape: Arc<Impeller>,
    /// Its rotation.
    pub motion: RampedRotation,
    /// Centre (on the axis, mid-plane), lattice coordinates.
    pub centre: Vec3,
}

impl ImpellerSetup {
    /// Diameter `D`.
    pub fn diameter(&self) -> f64 {
        self.shape.geometry().diameter
    }

    /// Revolutions per step `N`.
    pub fn speed(&self) -> f64 {
        self.motion.revolutions_per_step
    }

    /// Tip speed `π N D`.
    pub fn tip_speed(&self) -> f64 {
        PI * self.speed().abs() * self.diameter()
    }

    /// The power number of a torque `Γ` (fluid density 1): `Po = 2πNΓ/(N³D⁵)`.
    pub fn power_number(&self, torque: f64) -> f64 {
        let (n, d) = (self.speed(), self.diameter());
        2.0 * PI * n * torque / (n * n * n * d.powi(5))
    }

    /// The smallest angle (radians) by which the impeller can turn onto itself: the blade
    /// spacing `2π/n` of a PBT; `None` for the disk, which any angle does.
    pub fn symmetry_angle(&self) -> Option<f64> {
        match self.shape.geometry().kind {
            ImpellerKind::Disk { .. } => None,
            ImpellerKind::PitchedBlade { blades, .. } => Some(2.0 * PI / blades.max(1) as f64),
        }
    }

    /// The prescribed rigid body at time `t = 0` (density 1: nominal, never used).
    pub fn body(&self) -> RigidBody {
        let shape: Arc<dyn Shape> = self.shape.clone();
        RigidBody::new(shape, 1.0, Motion::Prescribed(Arc::new(self.motion))).with_position(self.centre)
    }
}

impl Case {
    /// The impeller (`[impeller]`), validated; `None` without one.
    ///
    /// # Errors
    /// A dimension out of range (naming `impeller.<key>`), a tip Mach number above
    /// `run.mach_limit`, or an impeller that does not fit in the box.
    pub fn impeller_setup(&self) -> Result<Option<ImpellerSetup>, CaseErrorKind> {
        let Some(s) = &self.impeller else { return Ok(None) };
        let d = s.diameter;
        if !(d.is_finite() && d > 0.0) {
            return Err(invalid("impeller.diameter", d, "must be finite and > 0"));
        }
        let n = [self.domain.nx, self.domain.ny, self.domain.nz];
        let centre = s.centre.unwrap_or([0, 1, 2].map(|k| 0.5 * (n[k] as f64 - 1.0)));
        if centre.iter().any(|c| !c.is_finite()) {
            return Err(invalid("impeller.centre", fmt_vec(&centre), "each component must be finite"));
        }
        let shaft = s.shaft.unwrap_or(true);
        let top = n[2] as f64 - 0.5;
        let shaft_length = if shaft { top - centre[2] } else { 0.0 };
        let scale = d / 132.0;
        let only = |key: &str, present: bool, kind: &str| {
            if present {
                Err(invalid(format!("impeller.{key}"), "(given)", format!("only for kind = \"{kind}\"")))
            } else {
                Ok(())
            }
        };
        let kind = match s.kind {
            ImpellerKindSpec::Disk => {
                for (key, present) in [
                    ("blades", s.blades.is_some()),
                    ("pitch_deg", s.pitch_deg.is_some()),
                    ("blade_width", s.blade_width.is_some()),
                    ("blade_thickness", s.blade_thickness.is_some()),
                    ("hub_diameter", s.hub_diameter.is_some()),
                    ("hub_height", s.hub_height.is_some()),
                    ("pumping", s.pumping.is_some()),
                ] {
                    only(key, present, "pbt")?;
                }
                ImpellerKind::Disk { thickness: s.thickness.unwrap_or(4.0 * scale) }
            }
            ImpellerKindSpec::Pbt => {
                only("thickness", s.thickness.is_some(), "disk")?;
                let pitch = s.pitch_deg.unwrap_or(45.0).to_radians();
                let (w, t) = (s.blade_width.unwrap_or(0.2 * d), s.blade_thickness.unwrap_or(3.0 * scale));
                ImpellerKind::PitchedBlade {
                    blades: s.blades.unwrap_or(4),
                    pitch,
                    blade_width: w,
                    blade_thickness: t,
                    hub_diameter: s.hub_diameter.unwrap_or(0.2 * d),
                    hub_height: s.hub_height.unwrap_or(blade_vertical_extent(pitch, w, t)),
                    pumping: match s.pumping.unwrap_or_default() {
                        PumpingSpec::Down => Pumping::Down,
                        PumpingSpec::Up => Pumping::Up,
                    },
                }
            }
        };
        if shaft && self.boundaries.get(Face::ZMax).to_face_boundary() == crate::lbm::FaceBoundary::Periodic {
            return Err(invalid(
                "impeller.shaft",
                true,
                "the shaft runs up to the z_max face, which must be a wall (or set shaft = false)",
            ));
        }
        let geometry = ImpellerGeometry {
            diameter: d,
            kind,
            shaft_diameter: s.shaft_diameter.unwrap_or(0.08 * d),
            shaft_length,
        };
        let shape = Impeller::new(geometry).map_err(|e| {
            if e.key == "shaft_length" {
                invalid(
                    "impeller.centre",
                    fmt_vec(&centre),
                    format!(
                        "the impeller must fit inside the box, below the z_max wall at z = {top} with room for \
                         its shaft (shaft length {:.4}, allowed {})",
                        e.value, e.allowed
                    ),
                )
            } else {
                invalid(format!("impeller.{}", e.key), e.value, e.allowed)
            }
        })?;
        let speed = s.speed;
        let tip_mach = mach([PI * speed * d, 0.0, 0.0]);
        if !(speed.is_finite() && speed != 0.0) || tip_mach > self.run.mach_limit {
            return Err(invalid(
                "impeller.speed",
                speed,
                format!(
                    "must be nonzero with tip Mach number pi N D / c_s <= run.mach_limit = {} (here {tip_mach:.3})",
                    self.run.mach_limit
                ),
            ));
        }
        // Inside the box: the impeller's world box at any angle (its horizontal reach is the
        // radius of its bounding cylinder) within the walls at −0.5 and n − 0.5.
        let shape = Arc::new(shape);
        let reach = shape.radial_reach();
        let (zlo, zhi) = shape.axial_extent();
        let lo = [centre[0] - reach, centre[1] - reach, centre[2] + zlo];
        let hi = [centre[0] + reach, centre[1] + reach, centre[2] + zhi];
        for k in 0..3 {
            if lo[k] < -0.5 || hi[k] > n[k] as f64 - 0.5 + 1e-9 {
                return Err(invalid(
                    "impeller.centre",
                    fmt_vec(&centre),
                    format!(
                        "the impeller (reach {reach:.2} from its axis, {zlo:.2} … {zhi:.2} along it) must fit \
                         inside the box, −0.5 … n − 0.5 on every axis"
                    ),
                ));
            }
        }
        // Last: the impeller's own keys are reported first.
        let retraction = self.ibm().retraction;
        if let Err(e) = geometry.check_retraction(retraction) {
            return Err(invalid(
                "ibm.retraction",
                retraction,
                match e {
                    RetractionError::TooThin { dimension, value, .. } => {
                        let v = crate::util::fmt_num(value);
                        format!(
                            "must be below half of every impeller dimension: impeller.{dimension} = {v} leaves \
                             {v} - 2 x {retraction} <= 0 for the forcing markers (lower the retraction, \
                             thicken the part or scale the impeller up)"
                        )
                    }
                    e => e.to_string(),
                },
            ));
        }
        let motion =
            RampedRotation { axis: Vec3::z(), revolutions_per_step: speed, ramp_steps: s.ramp_steps as f64 };
        Ok(Some(ImpellerSetup { shape, motion, centre: Vec3::from(centre) }))
    }
}
