//! The verification cases, and helpers they share.

pub mod contacts_dry;
pub mod couette;
pub mod free_particles;
pub mod fused_vs_reference;
pub mod ibm_transfer;
pub mod impeller;
pub mod implicit_damping;
pub mod mass_conservation;
pub mod poiseuille;
pub mod quaternion_norm;
pub mod state_pack;
pub mod stokes_drag;
pub mod taylor_green;
pub mod ten_cate;
pub mod torque_free;
pub mod wet_lubrication;

use slurry::device::fluid::DeviceReal;
use slurry::lattice::{Face, Grid};
use slurry::lbm::{Boundaries, FaceBoundary, Fluid, Real};

use crate::backend::Stepper;

use crate::Case;

/// Every case, in run order.
pub fn all() -> Vec<Case> {
    vec![
        Case {
            name: "poiseuille",
            summary: "force-driven channel between no-slip walls: BGK second order, TRT (3/16) exact",
            run: poiseuille::run,
            device: true,
        },
        Case {
            name: "couette",
            summary: "one moving wall: steady profile exact, impulsive start second order (BGK)",
            run: couette::run,
            device: true,
        },
        Case {
            name: "taylor_green",
            summary: "3-D box, 2-D vortex decay: viscosity from the decay rate, second order",
            run: taylor_green::run,
            device: true,
        },
        Case {
            name: "fused_vs_reference",
            summary: "fused AA kernel equals the two-lattice reference bitwise (every ISA)",
            run: fused_vs_reference::run,
            device: false,
        },
        Case {
            name: "mass_conservation",
            summary: "mass (and momentum) conserved to round-off: periodic and lid-driven boxes",
            run: mass_conservation::run,
            device: true,
        },
        Case {
            name: "ibm_transfer",
            summary: "IBM kernels: partition of unity, first moments, <Iu,F> = <u,SF>, bitwise spreading",
            run: ibm_transfer::run,
            device: false,
        },
        Case {
            name: "quaternion_norm",
            summary: "rigid-body quaternion norm drift over 1e6 torque-free steps <= 1e-12",
            run: quaternion_norm::run,
            device: false,
        },
        Case {
            name: "torque_free",
            summary: "torque-free top: energy/angular momentum second order, Dzhanibekov flip, precession",
            run: torque_free::run,
            device: false,
        },
        Case {
            name: "stokes_drag",
            summary:
                "IBM: drag of a periodic array of fixed spheres (d/L = 0.25) vs Zick & Homsy, first order",
            run: stokes_drag::run,
            device: false,
        },
        Case {
            name: "free_particles",
            summary:
                "free bodies at gamma = 1.25: sphere spins at shear/2, falling cylinder's momentum budget",
            run: free_particles::run,
            device: false,
        },
        Case {
            name: "contacts_dry",
            summary: "dry collisions (Table 1 contacts): momentum, energy, restitution, closest approach",
            run: contacts_dry::run,
            device: false,
        },
        Case {
            name: "implicit_damping",
            summary: "backward-Euler contact damping vs the converged explicit scheme: first order, stable at one sub-step",
            run: implicit_damping::run,
            device: false,
        },
        Case {
            name: "wet_lubrication",
            summary:
                "sphere settling onto a fixed sphere in fluid: slows before contact (lubrication), no overlap",
            run: wet_lubrication::run,
            device: false,
        },
        Case {
            name: "ten_cate",
            summary:
                "sphere settling in a closed box (ten Cate et al. 2002, E1-E4): peak velocity vs measured",
            run: ten_cate::run,
            device: false,
        },
        Case {
            name: "state_pack",
            summary:
                "restart from a state pack vs the exact restart: velocity and bodies after 100 steps (stirred tank)",
            run: state_pack::run,
            device: false,
        },
        Case {
            name: "impeller",
            summary:
                "impellers: marker areas and normals; single-phase torque budget, Po_f and pumping at Re = 87",
            run: impeller::run,
            device: false,
        },
    ]
}

/// Boundaries of a channel: periodic in x and y, walls on the z faces (`top` on `z_max`).
pub(crate) fn channel(top: FaceBoundary) -> Boundaries {
    Boundaries::periodic().with(Face::ZMin, FaceBoundary::NoSlip).with(Face::ZMax, top)
}

/// The `u_x(z)` profile at `x = y = 0` of a channel.
pub(crate) fn profile<T: Real>(f: &Fluid<T>) -> Vec<f64> {
    (0..f.grid().nz).map(|z| f.velocity(0, 0, z)[0]).collect()
}

/// Outcome of [`run_to_steady`].
pub(crate) struct Steady {
    /// The final `u_x(z)` profile.
    pub profile: Vec<f64>,
    /// Steps taken.
    pub steps: u64,
    /// `‖u(t) − u(t−K)‖₂ / ‖u(t)‖₂` at the last check.
    pub rel_change: f64,
    /// Whether the criterion was met before `max_steps`.
    pub converged: bool,
}

/// Relative tolerance of the steady-state criterion (see [`run_to_steady`]).
pub(crate) const STEADY_TOL: f64 = 1e-13;

/// Runs a channel of height `N = nz` with viscosity `nu` from its current state until the
/// profile stops changing.
///
/// **Criterion.** Every `K = ⌈N²/(π²ν)⌉` steps (rounded up to even: one e-folding time of the
/// slowest diffusive mode `sin(π(z+½)/N)`) the relative change of the profile over those `K`
/// steps is computed; the run stops when it is below [`STEADY_TOL`] = 1e-13. With the slowest
/// mode decaying as `e^{−t/K}` the distance that remains to the steady state is then
/// `Δ/(1 − e^{−1}) ≈ 1.6 Δ < 1.6e-13` relative: three orders below the 1e-10 the exact cases
/// (TRT Poiseuille) are held to, nine below the BGK errors. It takes about 30 e-folding times
/// (`≈ 3 N²/ν` steps) from rest.
pub(crate) fn run_to_steady<T: DeviceReal>(f: &mut Fluid<T>, nu: f64, max_steps: u64) -> Steady {
    let n = f.grid().nz as f64;
    let k = ((n * n / (std::f64::consts::PI.powi(2) * nu)).ceil() as u64).max(2);
    let k = k + k % 2;
    let mut prev = profile(f);
    let mut f = Stepper::new(f);
    loop {
        f.run(k);
        let f = f.fluid();
        let now = profile(f);
        let d: f64 = now.iter().zip(&prev).map(|(a, b)| (a - b) * (a - b)).sum::<f64>().sqrt();
        let s: f64 = now.iter().map(|a| a * a).sum::<f64>().sqrt();
        let rel = d / s;
        let steps = f.time();
        if rel < STEADY_TOL || steps >= max_steps || !rel.is_finite() {
            return Steady { profile: now, steps, rel_change: rel, converged: rel < STEADY_TOL };
        }
        prev = now;
    }
}

/// Channel grid `1 × 1 × n` (periodic in x and y with one node: the flow is one-dimensional).
pub(crate) fn column(n: usize) -> Grid {
    Grid::new(1, 1, n)
}
