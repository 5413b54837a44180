//! The numerics sections of a case file that serve the particles without being particles:
//! `[ibm]` (the immersed boundary: kernel, forcing iterations, marker spacing, retraction)
//! here, and `[contacts]`, which is [`crate::contact::ContactParams`] itself (the paper's Table 1 and the
//! contact sub-steps; one definition, so the section and the model cannot drift apart).
//! Their validation lives with the particles' ([`super::particles`]), which they parametrise.

use serde::{Deserialize, Serialize};

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
