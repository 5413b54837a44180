//! Populations rebuilt from the macroscopic fields: the regularised reconstruction of a
//! restart from density and velocity alone (a state pack, [`crate::io::state_pack`]).
//!
//! At each fluid node the shifted populations are
//!
//! `h_i = h_i^eq(ρ, u) + w_i [ c_i·a₁ / c_s² + Q_i : Π^neq / (2 c_s⁴) ]`, `Q_i = c_i c_i − c_s² I`,
//!
//! the equilibrium of this code (second order, [`super::equilibrium`]) plus the first two
//! Hermite terms of the non-equilibrium part, chosen so that the state's moments are those
//! of the Chapman–Enskog solution of this scheme with Guo forcing:
//!
//! - `a₁ = −F/2`: the pre-collision momentum is `j = ρu − F/2`, since this code's velocity is
//!   `u = (j + F/2)/ρ` ([`super::collision`]); `F` is the force density of the last step (the
//!   uniform body force plus the field);
//! - `Π^neq = −(2 ρ c_s² / ω⁺) S − (u F + F u)/2`, `S = (∇u + ∇uᵀ)/2`: the first-order
//!   pre-collision non-equilibrium stress of BGK (`ω⁺ = 1/τ`) and of TRT (the even moments
//!   relax with `ω⁺`, which sets the viscosity), with the term that Guo's source of weight
//!   `1 − ω⁺/2` leaves in the pre-collision stress.
//!
//! The gradient is taken by central differences; next to a no-slip or moving wall (half-way
//! bounce-back, the wall half a node away) or an obstacle node, from the quadratic through
//! the wall's velocity half a node away, the node and the node on the other side (second
//! order, like the central difference); across periodic faces the neighbour is the image.
//! Obstacle nodes get the rest state (their slots are refilled before they are read).
//!
//! What is lost against the exact populations: the odd non-equilibrium moments beyond the
//! momentum (third order, relaxed with `ω⁻`) and the higher Chapman–Enskog terms of the even
//! ones, one order in the lattice spacing below the part that is rebuilt (which is itself
//! first order): in a steady shear flow 4.7 % of the non-equilibrium part at 32 nodes per
//! wavelength, 2.7 % at 64 (the unit tests). The restart is close, not bitwise:
//! `tests/state_pack.rs` measures how close on a stirred tank with particles.

use rayon::prelude::*;

use super::fluid::equilibrium;
use super::{Fluid, FluidError, FluidState, Real};
use crate::lattice::{Face, C, CS2, Q, W};

/// The macroscopic fields a regularised state is built from, each in interior index order
/// (x fastest): density, velocity (half-force corrected, as [`Fluid::fields`] gives it) and,
/// when the run has one, the force-density field of the last step (without the uniform body
/// force, which the fluid adds).
#[derive(Clone, Copy, Debug)]
pub struct MacroFields<'a> {
    /// Density per node.
    pub rho: &'a [f32],
    /// Velocity per node.
    pub velocity: &'a [[f32; 3]],
    /// Force density field per node, if any.
    pub force: Option<&'a [[f32; 3]]>,
}

/// The derivative at 0 of the quadratic through `(a, ua)`, `(0, u0)`, `(b, ub)`, `a < 0 < b`.
fn quadratic_slope(a: f64, ua: f64, u0: f64, b: f64, ub: f64) -> f64 {
    ua * (-b / (a * (a - b))) + u0 * (-(a + b) / (a * b)) + ub * (-a / (b * (b - a)))
}

impl<T: Real> Fluid<T> {
    /// The state at even step `time` rebuilt from `fields` by the regularised reconstruction
    /// (module [`super::regularise`]): equilibrium plus the non-equilibrium part of the
    /// velocity gradient and the force. Restore it with [`Fluid::restore`] (or
    /// `coupling::Coupled::restore`, with the bodies' states).
    ///
    /// # Errors
    /// Fields whose length is not the grid's ([`FluidError::StateMismatch`]), an odd `time`.
    pub fn regularised_state(&self, time: u64, fields: MacroFields<'_>) -> Result<FluidState<T>, FluidError> {
        let g = self.grid();
        let n = g.nodes();
        if fields.rho.len() != n || fields.velocity.len() != n || fields.force.is_some_and(|f| f.len() != n) {
            return Err(FluidError::StateMismatch { grid: g, expected: g });
        }
        if !time.is_multiple_of(2) {
            return Err(FluidError::OddTime { time });
        }
        let (omega_plus, _) = self.params().rates();
        let body = self.zero_field_force();
        let boundaries = *self.boundaries();
        let dims = [g.nx, g.ny, g.nz];
        let vel = |i: usize| fields.velocity[i].map(f64::from);
        // Per node, node-major.
        let mut h = vec![[T::ZERO; Q]; n];
        h.par_iter_mut().enumerate().for_each(|(i, out)| {
            let p = g.coords(i);
            if self.is_obstacle(p[0], p[1], p[2]) {
                return;
            }
            let rho = f64::from(fields.rho[i]);
            let u = vel(i);
            let field = fields.force.map_or([0.0; 3], |f| f[i].map(f64::from));
            let force: [f64; 3] = std::array::from_fn(|a| field[a] + body[a]);
            // grad[a][b] = ∂_a u_b.
            let mut grad = [[0.0; 3]; 3];
            for (a, row) in grad.iter_mut().enumerate() {
                // The neighbour on each side: (offset, velocity).
                let side = |dir: isize| -> (f64, [f64; 3]) {
                    let mut q = p;
                    let k = p[a] as isize + dir;
                    let face = Face::from_axis(a, dir < 0);
                    let fb = boundaries.get(face);
                    if k < 0 || k >= dims[a] as isize {
                        if fb.is_periodic() {
                            q[a] = k.rem_euclid(dims[a] as isize) as usize;
                        } else {
                            return (0.5 * dir as f64, fb.wall_velocity().unwrap_or([0.0; 3]));
                        }
                    } else {
                        q[a] = k as usize;
                    }
                    if self.is_obstacle(q[0], q[1], q[2]) {
                        (0.5 * dir as f64, [0.0; 3])
                    } else {
                        (dir as f64, vel(g.index(q[0], q[1], q[2])))
                    }
                };
                let (xa, ua) = side(-1);
                let (xb, ub) = side(1);
                for b in 0..3 {
                    row[b] = quadratic_slope(xa, ua[b], u[b], xb, ub[b]);
                }
            }
            // Π^neq and a₁.
            let mut pi = [[0.0; 3]; 3];
            for (a, pa) in pi.iter_mut().enumerate() {
                for (b, v) in pa.iter_mut().enumerate() {
                    let s = 0.5 * (grad[a][b] + grad[b][a]);
                    *v = -2.0 * rho * CS2 / omega_plus * s - 0.5 * (u[a] * force[b] + force[a] * u[b]);
                }
            }
            let a1 = force.map(|f| -0.5 * f);
            let eq = equilibrium(rho, u);
            for q in 0..Q {
                let c = C[q].map(f64::from);
                let first = (c[0] * a1[0] + c[1] * a1[1] + c[2] * a1[2]) / CS2;
                let mut second = 0.0;
                for a in 0..3 {
                    for b in 0..3 {
                        let qab = c[a] * c[b] - if a == b { CS2 } else { 0.0 };
                        second += qab * pi[a][b];
                    }
                }
                second /= 2.0 * CS2 * CS2;
                out[q] = T::from_f64(eq[q] + W[q] * (first + second));
            }
        });
        let mut populations = vec![T::ZERO; Q * n];
        populations.par_chunks_mut(n).enumerate().for_each(|(q, dst)| {
            for (d, node) in dst.iter_mut().zip(&h) {
                *d = node[q];
            }
        });
        let force = fields.force.map(|f| {
            let mut out = vec![T::ZERO; 3 * n];
            for (a, dst) in out.chunks_mut(n).enumerate() {
                for (d, v) in dst.iter_mut().zip(f) {
                    *d = T::from_f64(f64::from(v[a]));
                }
            }
            out
        });
        Ok(FluidState { time, grid: g, populations, force })
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::lattice::Grid;
    use crate::lbm::{Boundaries, FluidParams};

    /// The slope formula is exact for quadratics, on the central and the wall stencil.
    #[test]
    fn quadratic_slope_is_exact_for_quadratics() {
        let f = |x: f64| 2.0 + 3.0 * x - 5.0 * x * x;
        for (a, b) in [(-1.0, 1.0), (-0.5, 1.0), (-1.0, 0.5), (-0.5, 0.5)] {
            let d = quadratic_slope(a, f(a), f(0.0), b, f(b));
            assert!((d - 3.0).abs() < 1e-12, "{a} {b}: {d}");
        }
    }

    /// The rebuilt state has the stored density, and velocity `(j + F/2)/ρ` equal to the
    /// stored velocity at every node, to the storage precision.
    #[test]
    fn moments_are_the_fields() {
        let g = Grid::new(6, 5, 4);
        let mut fluid = Fluid::<f64>::new(g, FluidParams::trt(0.05), Boundaries::closed_box()).unwrap();
        fluid.enable_force_field();
        let n = g.nodes();
        let rho: Vec<f32> = (0..n).map(|i| 1.0 + 1e-3 * (i % 7) as f32).collect();
        let velocity: Vec<[f32; 3]> =
            (0..n).map(|i| [0.01 * (i % 5) as f32, -0.02 * (i % 3) as f32, 0.005 * (i % 4) as f32]).collect();
        let force: Vec<[f32; 3]> = (0..n).map(|i| [1e-4 * (i % 2) as f32, 0.0, -2e-4]).collect();
        let s = fluid
            .regularised_state(4, MacroFields { rho: &rho, velocity: &velocity, force: Some(&force) })
            .unwrap();
        fluid.restore(&s).unwrap();
        assert_eq!(fluid.time(), 4);
        for i in 0..n {
            let [x, y, z] = g.coords(i);
            let (r, u) = fluid.macroscopic(x, y, z);
            assert!((r - f64::from(rho[i])).abs() < 1e-12);
            for a in 0..3 {
                assert!((u[a] - f64::from(velocity[i][a])).abs() < 1e-12, "node {i} axis {a}");
            }
        }
        assert!(fluid
            .regularised_state(3, MacroFields { rho: &rho, velocity: &velocity, force: None })
            .is_err());
        assert!(fluid
            .regularised_state(2, MacroFields { rho: &rho[1..], velocity: &velocity, force: None })
            .is_err());
    }

    /// The largest error of the rebuilt populations relative to the largest non-equilibrium
    /// part, in the steady Kolmogorov flow `u_x = U sin(2π z/L)` on a periodic `2 × 2 × L` box.
    fn kolmogorov_rebuild_error(l: usize) -> f64 {
        let g = Grid::new(2, 2, l);
        let nu = 0.1;
        let k = std::f64::consts::TAU / l as f64;
        let force_amp = nu * k * k * 0.01;
        let fz = |z: usize| force_amp * (k * z as f64).sin();
        let mut fluid = Fluid::<f64>::new(g, FluidParams::bgk(nu), Boundaries::periodic()).unwrap();
        fluid.enable_force_field();
        for i in 0..g.nodes() {
            let [x, y, z] = g.coords(i);
            fluid.set_force(x, y, z, [fz(z), 0.0, 0.0]);
        }
        fluid.run(20 * (1.0 / (nu * k * k)) as u64 / 2 * 2);
        let exact = fluid.snapshot().unwrap();
        let (rho, u) = fluid.fields();
        let rho32: Vec<f32> = rho.iter().map(|&v| v as f32).collect();
        let u32: Vec<[f32; 3]> = u.iter().map(|v| v.map(|c| c as f32)).collect();
        let f32s: Vec<[f32; 3]> = (0..g.nodes()).map(|i| [fz(g.coords(i)[2]) as f32, 0.0, 0.0]).collect();
        let rebuilt = fluid
            .regularised_state(exact.time, MacroFields { rho: &rho32, velocity: &u32, force: Some(&f32s) })
            .unwrap();
        let n = g.nodes();
        let (mut err, mut neq) = (0.0f64, 0.0f64);
        for i in 0..n {
            let eq = equilibrium(rho[i], u[i]);
            for q in 0..Q {
                let h = exact.populations[q * n + i];
                err = err.max((rebuilt.populations[q * n + i] - h).abs());
                neq = neq.max((h - eq[q]).abs());
            }
        }
        assert!(neq > 1e-6, "a non-equilibrium part to rebuild: {neq}");
        err / neq
    }

    /// In a steady shear flow the rebuilt populations are the exact ones up to the dropped
    /// higher Chapman–Enskog terms, first order in the lattice spacing relative to the
    /// non-equilibrium part (second order relative to the populations' deviation from rest):
    /// 4.7 % of it at 32 nodes per wavelength, 2.7 % at 64.
    #[test]
    fn steady_shear_flow_is_rebuilt() {
        let (coarse, fine) = (kolmogorov_rebuild_error(32), kolmogorov_rebuild_error(64));
        assert!(coarse < 0.06, "{coarse}");
        assert!(fine < coarse / 1.6, "converging: {coarse} then {fine}");
    }
}
