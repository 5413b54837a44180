//! The numerics sections of a case file that serve the particles without being particles:
//! `[ibm]` (the immersed boundary: kernel, forcing iterations, marker spacing, retraction)
//! and `[contacts]` (the paper's Table 1 and the contact sub-steps). Their validation lives
//! with the particles' ([`super::particles`]), which they parametrise.

use serde::{Deserialize, Serialize};

use crate::contact::ContactParams;
use crate::coupling::DEFAULT_RETRACTION;
use crate::ibm::DeltaKernel;
use crate::rigid::DEFAULT_MARKER_SPACING;

/// `[ibm]`: the immersed-boundary numerics (used when the case has particles).
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct IbmSection {
    /// Regularised delta function: `"roma3"` (default), `"peskin4"` or `"linear"`.
    #[serde(default)]
    pub kernel: DeltaKernel,
    /// Direct-forcing iterations per time step (≥ 1; default 1).
    #[serde(default = "one_iteration")]
    pub iterations: usize,
    /// Target spacing of the surface markers, lattice units (0.3 … 1.0; default 0.7).
    #[serde(default = "default_marker_spacing")]
    pub marker_spacing: f64,
    /// Retraction of the forcing markers into every body, lattice units (`0 ≤ r_d < 0.5`;
    /// default [`DEFAULT_RETRACTION`], calibrated on the Stokes drag of a sphere array for
    /// the Roma 3-point kernel and one iteration). Only the markers that force the fluid
    /// move; volumes, masses, the interior-fluid term and the contact markers keep the true
    /// shape ([`crate::coupling`], "The immersed boundary's effective size").
    #[serde(default = "default_retraction")]
    pub retraction: f64,
}

fn default_retraction() -> f64 {
    DEFAULT_RETRACTION
}

fn one_iteration() -> usize {
    1
}

fn default_marker_spacing() -> f64 {
    DEFAULT_MARKER_SPACING
}

impl Default for IbmSection {
    fn default() -> Self {
        Self {
            kernel: DeltaKernel::default(),
            iterations: 1,
            marker_spacing: DEFAULT_MARKER_SPACING,
            retraction: DEFAULT_RETRACTION,
        }
    }
}

/// `[contacts]`: the contact model of the paper's Table 1 between particles and with the box
/// walls. Present (even empty) = contacts on, with Table 1's values for every key not given;
/// absent = no contacts.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ContactsSection {
    /// Spring constant `k` (> 0; Table 1: 5.0).
    #[serde(default = "contact_defaults::k")]
    pub k: f64,
    /// Elastic range `δ0` (> 0; 0.5).
    #[serde(default = "contact_defaults::delta0")]
    pub delta0: f64,
    /// Tangential range `λ` (> 0; 0.5).
    #[serde(default = "contact_defaults::lambda")]
    pub lambda: f64,
    /// Normal lubrication coefficient `kⁿ` (> 0; 5.0).
    #[serde(default = "contact_defaults::k_n")]
    pub k_n: f64,
    /// Lubrication range `δ_d` (> 0; 1.0).
    #[serde(default = "contact_defaults::delta_d")]
    pub delta_d: f64,
    /// Saturation distance `δ_sat` (in (0, δ_d); 0.2).
    #[serde(default = "contact_defaults::delta_sat")]
    pub delta_sat: f64,
    /// Tangential lubrication coefficient `kᵗ` (> 0; 0.5).
    #[serde(default = "contact_defaults::k_t")]
    pub k_t: f64,
    /// Elastic force on (default true).
    #[serde(default = "contact_defaults::on")]
    pub elastic: bool,
    /// Lubrication forces on (default true).
    #[serde(default = "contact_defaults::on")]
    pub lubrication: bool,
    /// Limited (implicit-stable) lubrication in the sub-steps (default false;
    /// `ContactParams::lubrication_limiter`).
    #[serde(default)]
    pub lubrication_limiter: bool,
    /// Contact sub-steps per fluid step (1 … 1024; default `contact::DEFAULT_SUBSTEPS`).
    #[serde(default = "contact_defaults::substeps")]
    pub substeps: usize,
}

/// Serde defaults of [`ContactsSection`]: Table 1.
mod contact_defaults {
    use crate::contact::{ContactParams, DEFAULT_SUBSTEPS};
    pub fn k() -> f64 {
        ContactParams::default().k
    }
    pub fn delta0() -> f64 {
        ContactParams::default().delta0
    }
    pub fn lambda() -> f64 {
        ContactParams::default().lambda
    }
    pub fn k_n() -> f64 {
        ContactParams::default().k_n
    }
    pub fn delta_d() -> f64 {
        ContactParams::default().delta_d
    }
    pub fn delta_sat() -> f64 {
        ContactParams::default().delta_sat
    }
    pub fn k_t() -> f64 {
        ContactParams::default().k_t
    }
    pub fn on() -> bool {
        true
    }
    pub fn substeps() -> usize {
        DEFAULT_SUBSTEPS
    }
}

impl ContactsSection {
    /// The model parameters.
    pub fn params(&self) -> ContactParams {
        ContactParams {
            k: self.k,
            delta0: self.delta0,
            lambda: self.lambda,
            k_n: self.k_n,
            delta_d: self.delta_d,
            delta_sat: self.delta_sat,
            k_t: self.k_t,
            elastic: self.elastic,
            lubrication: self.lubrication,
            lubrication_limiter: self.lubrication_limiter,
        }
    }
}
