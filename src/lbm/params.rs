//! Fluid parameters: viscosity, collision model, body force.

use serde::{Deserialize, Serialize};

use super::FluidError;
use crate::lattice::CS2;

/// Collision model.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
#[serde(tag = "model", rename_all = "snake_case", deny_unknown_fields)]
pub enum Collision {
    /// Single relaxation time (Bhatnagar–Gross–Krook), the paper's scheme.
    Bgk,
    /// Two relaxation times (Ginzburg) with magic parameter
    /// `Λ = (1/ω⁺ − ½)(1/ω⁻ − ½)`; `Λ = 3/16` puts half-way bounce-back walls exactly half-way.
    Trt {
        /// The magic parameter Λ (> 0).
        #[serde(default = "default_magic")]
        magic: f64,
    },
}

/// The default TRT magic parameter, 3/16.
pub fn default_magic() -> f64 {
    3.0 / 16.0
}

/// Physical parameters of the lattice fluid, in lattice units.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub struct FluidParams {
    /// Kinematic viscosity ν (> 0): `τ = 3ν + ½`.
    pub nu: f64,
    /// Collision model.
    pub collision: Collision,
    /// Uniform body force density (force per unit volume), added to every fluid node.
    pub body_force: [f64; 3],
}

impl FluidParams {
    /// BGK with viscosity `nu` and no body force.
    pub fn bgk(nu: f64) -> Self {
        Self { nu, collision: Collision::Bgk, body_force: [0.0; 3] }
    }

    /// TRT with viscosity `nu`, magic parameter 3/16 and no body force.
    pub fn trt(nu: f64) -> Self {
        Self { nu, collision: Collision::Trt { magic: default_magic() }, body_force: [0.0; 3] }
    }

    /// The same parameters with body force `g`.
    pub fn with_body_force(mut self, g: [f64; 3]) -> Self {
        self.body_force = g;
        self
    }

    /// Relaxation time `τ = ν/c_s² + ½`.
    pub fn tau(&self) -> f64 {
        self.nu / CS2 + 0.5
    }

    /// Checks ranges: `ν > 0` (so `τ > ½`), `Λ > 0`, finite body force.
    pub fn validate(&self) -> Result<(), FluidError> {
        if !(self.nu.is_finite() && self.nu > 0.0) {
            return Err(FluidError::Viscosity { nu: self.nu, tau: self.tau() });
        }
        if let Collision::Trt { magic } = self.collision {
            if !(magic.is_finite() && magic > 0.0) {
                return Err(FluidError::Magic { magic });
            }
        }
        if self.body_force.iter().any(|g| !g.is_finite()) {
            return Err(FluidError::BodyForce { force: self.body_force });
        }
        Ok(())
    }

    /// `(ω⁺, ω⁻)`. For BGK both equal `1/τ`; for TRT `ω⁻` follows from Λ:
    /// `1/ω⁻ = ½ + Λ/(1/ω⁺ − ½)`.
    pub fn rates(&self) -> (f64, f64) {
        let tau = self.tau();
        let op = 1.0 / tau;
        match self.collision {
            Collision::Bgk => (op, op),
            Collision::Trt { magic } => {
                let tau_m = 0.5 + magic / (tau - 0.5);
                (op, 1.0 / tau_m)
            }
        }
    }

    /// Whether the collision model is TRT.
    pub fn is_trt(&self) -> bool {
        matches!(self.collision, Collision::Trt { .. })
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn trt_rates_satisfy_the_magic_parameter() {
        let p = FluidParams::trt(0.05);
        let (op, om) = p.rates();
        let lambda = (1.0 / op - 0.5) * (1.0 / om - 0.5);
        assert!((lambda - 3.0 / 16.0).abs() < 1e-15);
        assert!((p.tau() - 0.65).abs() < 1e-15);
    }

    #[test]
    fn nonpositive_viscosity_is_rejected() {
        assert!(FluidParams::bgk(0.0).validate().is_err());
        assert!(FluidParams::bgk(-0.1).validate().is_err());
        assert!(FluidParams::bgk(f64::NAN).validate().is_err());
        assert!(FluidParams::bgk(0.01).validate().is_ok());
    }
}
