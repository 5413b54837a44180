//! Box-face boundary conditions, and the link lists that implement them.
//!
//! All walls use half-way bounce-back: a population leaving fluid node `x` along `c_i` towards
//! a wall (or a solid obstacle node) returns to `x` one step later along `c_ī`, plus the
//! moving-wall term (Ladd 1994, with wall density ρ_w = 1):
//!
//! `f_ī(x, t+1) = f_i*(x, t) + 6 w_ī ρ_w c_ī·u_w`.
//!
//! The solver keeps one ghost layer around the box; every link that leaves the fluid is turned
//! into one operation on the population array, applied just before (`pre`) and just after
//! (`post`) the streaming half-step of the AA pattern (see [`super::fluid`]). A link that crosses
//! a periodic face copies between the ghost slot and its periodic image; a link that crosses a
//! wall or enters an obstacle node copies between the ghost (or obstacle) slot and the node's own
//! slot, adding the wall term. Where a diagonal link crosses a periodic and a wall face, the
//! wall wins; where it crosses two walls, `u_w` is the mean of their velocities.

use serde::{Deserialize, Serialize};

use super::FluidError;
use crate::lattice::{Face, Grid, C, OPP, W};

/// Boundary condition on one face of the box.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
#[serde(tag = "kind", rename_all = "snake_case", deny_unknown_fields)]
pub enum FaceBoundary {
    /// Periodic: leaves through this face, enters through the opposite one (which must also
    /// be periodic).
    Periodic,
    /// Stationary no-slip wall (half-way bounce-back).
    NoSlip,
    /// Wall moving in its own plane with `velocity` (lattice units; the normal component must
    /// be zero).
    MovingWall {
        /// Wall velocity.
        velocity: [f64; 3],
    },
}

impl FaceBoundary {
    /// Whether the face is periodic.
    pub fn is_periodic(&self) -> bool {
        matches!(self, FaceBoundary::Periodic)
    }

    /// Wall velocity (zero for a stationary wall); `None` for periodic faces.
    pub fn wall_velocity(&self) -> Option<[f64; 3]> {
        match *self {
            FaceBoundary::Periodic => None,
            FaceBoundary::NoSlip => Some([0.0; 3]),
            FaceBoundary::MovingWall { velocity } => Some(velocity),
        }
    }
}

/// Boundary conditions on the six faces, indexed by [`Face`].
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Boundaries {
    /// One condition per face, in the order of [`Face::ALL`].
    pub faces: [FaceBoundary; 6],
}

impl Boundaries {
    /// Periodic in all directions.
    pub fn periodic() -> Self {
        Self { faces: [FaceBoundary::Periodic; 6] }
    }

    /// Closed box: no-slip walls on all six faces (the paper's tank).
    pub fn closed_box() -> Self {
        Self { faces: [FaceBoundary::NoSlip; 6] }
    }

    /// The same boundaries with `face` set to `b`.
    pub fn with(mut self, face: Face, b: FaceBoundary) -> Self {
        self.faces[face as usize] = b;
        self
    }

    /// The condition on `face`.
    pub fn get(&self, face: Face) -> FaceBoundary {
        self.faces[face as usize]
    }

    /// Checks that periodic faces come in pairs and that walls move tangentially.
    pub fn validate(&self) -> Result<(), FluidError> {
        for axis in 0..3 {
            let lo = self.get(Face::from_axis(axis, true));
            let hi = self.get(Face::from_axis(axis, false));
            if lo.is_periodic() != hi.is_periodic() {
                return Err(FluidError::PeriodicPair { axis });
            }
        }
        for face in Face::ALL {
            if let Some(v) = self.get(face).wall_velocity() {
                if v.iter().any(|c| !c.is_finite()) || v[face.axis()] != 0.0 {
                    return Err(FluidError::WallVelocity { face, velocity: v });
                }
            }
        }
        Ok(())
    }
}

/// Where a link from interior node `x` against direction `i` (to `x − c_i`) ends.
#[derive(Clone, Copy, Debug, PartialEq)]
pub(crate) enum LinkEnd {
    /// An ordinary fluid node inside the box (no face crossed).
    Interior([usize; 3]),
    /// A fluid node reached through periodic faces.
    Periodic([usize; 3]),
    /// A wall (half-way bounce-back) with wall velocity `u_w`.
    Wall([f64; 3]),
    /// A solid obstacle node (stationary bounce-back).
    Obstacle,
}

/// Resolves the node `x + d` (`d` a lattice velocity) against the box boundaries and the
/// obstacle flags. Shared by the fused solver's link lists and the reference kernel.
pub(crate) fn resolve(
    grid: &Grid,
    b: &Boundaries,
    solid: &dyn Fn([usize; 3]) -> bool,
    x: [usize; 3],
    d: [i32; 3],
) -> LinkEnd {
    let mut n = [0usize; 3];
    let mut wrapped = false;
    let mut walls = 0usize;
    let mut uw = [0.0f64; 3];
    for a in 0..3 {
        let m = grid.dim(a) as i64;
        let v = x[a] as i64 + d[a] as i64;
        if (0..m).contains(&v) {
            n[a] = v as usize;
            continue;
        }
        let face = Face::from_axis(a, v < 0);
        match b.get(face).wall_velocity() {
            None => {
                wrapped = true;
                n[a] = v.rem_euclid(m) as usize;
            }
            Some(w) => {
                walls += 1;
                for k in 0..3 {
                    uw[k] += w[k];
                }
            }
        }
    }
    if walls > 0 {
        for v in uw.iter_mut() {
            *v /= walls as f64;
        }
        return LinkEnd::Wall(uw);
    }
    if solid(n) {
        return LinkEnd::Obstacle;
    }
    if wrapped {
        LinkEnd::Periodic(n)
    } else {
        LinkEnd::Interior(n)
    }
}

/// The bounce-back term added to the population returning along `c_i`:
/// `6 w_i c_i·u_w` (ρ_w = 1).
pub(crate) fn wall_term(i: usize, uw: [f64; 3]) -> f64 {
    let cu: f64 = (0..3).map(|a| C[i][a] as f64 * uw[a]).sum();
    6.0 * W[i] * cu
}

/// Negated lattice velocity `−c_i`.
pub(crate) fn minus_c(i: usize) -> [i32; 3] {
    C[OPP[i]]
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn one_sided_periodic_is_rejected() {
        let b = Boundaries::periodic().with(Face::XMin, FaceBoundary::NoSlip);
        assert!(b.validate().is_err());
        assert!(Boundaries::periodic().validate().is_ok());
        assert!(Boundaries::closed_box().validate().is_ok());
    }

    #[test]
    fn wall_moving_through_itself_is_rejected() {
        let b =
            Boundaries::closed_box().with(Face::ZMax, FaceBoundary::MovingWall { velocity: [0.0, 0.0, 0.1] });
        assert!(b.validate().is_err());
    }

    #[test]
    fn corner_link_crossing_a_wall_and_a_periodic_face_bounces() {
        let g = Grid::new(4, 4, 4);
        let b = Boundaries::periodic()
            .with(Face::ZMin, FaceBoundary::NoSlip)
            .with(Face::ZMax, FaceBoundary::NoSlip);
        let none = |_: [usize; 3]| false;
        assert_eq!(resolve(&g, &b, &none, [0, 1, 0], [-1, 0, -1]), LinkEnd::Wall([0.0; 3]));
        assert_eq!(resolve(&g, &b, &none, [0, 1, 1], [-1, 0, -1]), LinkEnd::Periodic([3, 1, 0]));
        assert_eq!(resolve(&g, &b, &none, [1, 1, 1], [-1, 0, -1]), LinkEnd::Interior([0, 1, 0]));
    }
}
