//! Phases 3 and 7 of the coupled step: the interior-fluid sums of each free or fixed body
//! (module [`super`], "Free bodies: the interior fluid").

use rayon::prelude::*;

use super::band::{emit_runs, row_spans};
use super::Coupled;
use crate::lattice::Run;
use crate::lbm::kernel::Planes;
use crate::lbm::{Fluid, Real};
use crate::rigid::{Motion, RigidBody, Vec3};

/// Which of the two sums of a step: before the forcing (fluid at `tⁿ`) or after the fluid step
/// (fluid at `tⁿ⁺¹`); the bodies are at `xⁿ` for both.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(super) enum Moment {
    /// Phase 3.
    Before,
    /// Phase 7.
    After,
}

impl<T: Real + Planes> Coupled<T> {
    /// The interior sums `(P, L, V)` of every body that has an interior term, into
    /// `self.interior[b].before` or `.after` (parallel over bodies, each body serial).
    pub(super) fn interior_sums(&mut self, moment: Moment) {
        let (fluid, periodic) = (&self.fluid, self.periodic);
        self.interior.par_iter_mut().zip(self.bodies.par_iter()).for_each(|(im, body)| {
            if has_interior_term(body) {
                let sums = interior_sums(fluid, body, periodic);
                match moment {
                    Moment::Before => im.before = sums,
                    Moment::After => im.after = sums,
                }
            }
        });
    }
}

/// Whether a body's loads include the interior-fluid term: free and fixed bodies do; a
/// prescribed body (an impeller) does not, since its loads are only reported, and the paper's
/// fluid torque on an impeller is the immersed-boundary torque alone. Its sums stay zero.
pub(super) fn has_interior_term(body: &RigidBody) -> bool {
    !matches!(body.motion(), Motion::Prescribed(_))
}

/// `(P, L, V)` of `body`'s interior fluid (module docs): `Σ α j`, `Σ α r × j`, `Σ α` over the
/// nodes with `sd < ½`; nodes deeper than `sd < −½` have `α = 1` without evaluating `sd`.
/// Serial per body (a fixed order: deterministic).
fn interior_sums<T: Real + Planes>(
    fluid: &Fluid<T>,
    body: &RigidBody,
    periodic: [bool; 3],
) -> (Vec3, Vec3, f64) {
    let grid = fluid.grid();
    let shape = body.shape().as_ref();
    let c = body.position;
    let mut p = Vec3::zeros();
    let mut l = Vec3::zeros();
    let mut v = 0.0;
    row_spans(body, grid, periodic, 0.5, Some(-0.5), |s| {
        emit_runs(grid, periodic, (s.xa, s.xb, s.y, s.z), |run: Run, shift| {
            let (yu, zu) = ((run.y as i64 + shift[1]) as f64, (run.z as i64 + shift[2]) as f64);
            fluid.for_each_in_run(run, |x, _rho, j, _f| {
                let xu = x as i64 + shift[0];
                let r = Vec3::new(xu as f64 - c.x, yu - c.y, zu - c.z);
                let alpha = if s.xs <= xu && xu <= s.xe {
                    1.0
                } else {
                    (0.5 - shape.signed_distance(&(s.origin + s.dir * xu as f64))).clamp(0.0, 1.0)
                };
                if alpha > 0.0 {
                    v += alpha;
                    let m = Vec3::from(j) * alpha;
                    p += m;
                    l += r.cross(&m);
                }
            });
        });
    });
    (p, l, v)
}
