//! The coupled step: the lattice fluid ([`crate::lbm`]) and rigid bodies ([`crate::rigid`])
//! joined through the immersed boundary method ([`crate::ibm`]).
//!
//! This is the only module that imports both the fluid and the particle side (ARCHITECTURE.md,
//! "Invariants"). [`Coupled`] owns the [`Fluid`], the bodies (fixed, prescribed and free),
//! each body's forcing markers (body frame, [`Shape::retracted_markers`]: "The immersed
//! boundary's effective size" below) and contact markers ([`Shape::markers`]), the IBM
//! [`Stencils`] and the reusable buffers of a step. The order of a step is written out once, in
//! [`Coupled::step`].
//!
//! # Free bodies: the interior fluid (Kempe & Fröhlich 2012)
//! The direct-forcing IBM drives the fluid *inside* a body as well as outside; the force the
//! fluid exerts on the body's surface is then
//!
//! ```text
//! F_h = −Σ_m F_m + d/dt ∫_{V_p} ρ u dV,    T_h = −Σ_m r_m × F_m + d/dt ∫_{V_p} r × ρ u dV
//! ```
//!
//! (`F_m` the marker forces on the fluid, `r` relative to the body's centre). Approximating
//! the integrals by `ρ V_p U_p` (Uhlmann 2005, "rigid internal fluid") turns the body's
//! equation into `(m − ρV) dU/dt = …`, which amplifies force errors by `γ/(γ − 1) = 5` at the
//! paper's `γ = 1.25` and is unstable below about `γ ≈ 1.2`. Here the integrals are sums over
//! the lattice nodes, weighted by a volume fraction that varies smoothly as the body moves,
//!
//! ```text
//! P = Σ_n α_n (ρu)_n,   L = Σ_n α_n (x_n − x_c) × (ρu)_n,   α_n = clamp(½ − sd(x_n), 0, 1)
//! ```
//!
//! (`sd` the shape's signed distance; `Σ α ≈ V`; a node enters or leaves linearly over one
//! spacing instead of in one jump, which would put spikes of size `|ρu|` into the force), with
//! the lattice momentum `j = Σ f_i c_i`. Both sums are taken **with the body where it is
//! during the step** (at `xⁿ`), once before the forcing and once after [`Fluid::step`]:
//! their difference is the momentum gained by the fluid in that fixed control volume during
//! the step, which contains the IBM force spread *inside* the body in the same step. So the
//! inner half of the forcing shell cancels at once (as in Kempe & Fröhlich's scheme, where
//! the volume integral is taken after the IBM force is applied in the same sub-step), and
//! only the outer half acts on the body. Evaluating the sums at the start of consecutive steps
//! instead (a lagged difference) leaves the whole shell explicit: with `2 S` the forced shell's
//! mass and `m` the body's, a d = 6 sphere at γ = 1.25 has `2S/m = 1.6` and the update blows
//! up within 20 steps (tested while developing this).
//!
//! A fixed control volume misses the flux of momentum through its boundary, which for fluid
//! moving rigidly with the body (`u = U + ω × r`) is `∫ρ(u·∇)u dV = ρV ω × U` and
//! `∫ r × ρ(u·∇)u dV = ω × (I_f ω)` (`I_f` the interior fluid's inertia tensor); these are
//! added analytically, with `V = Σ α` and `I_f = I_p/γ`:
//!
//! ```text
//! F_int = P_after − P_before + V ω × U,   T_int = L_after − L_before + ω × (I_f ω)
//! ```
//!
//! # The shell reaction, taken implicitly
//! Even so, the forcing is explicit: a body's velocity change `ΔUⁿ⁺¹` is felt by the fluid
//! shell that the markers force only in the next step, which then pushes back with
//! `−K ΔUⁿ⁺¹`, `K` the mass of the part of that shell outside the control volume (about
//! half a unit-thickness layer: `K_t ≈ S`, and per body axis `K_r,k = Σ A_m (|r_m|² − r_k²)`).
//! With `m(ΔUⁿ⁺¹) = F_other − K ΔUⁿ` the update has the root `−K/m`: unstable once
//! `K > m`, which a d = 6 sphere at γ = 1.25 reaches for rotation (`K_r/I ≈ 2`; its spin grew
//! by 1.6× per step in the development test). The coupling therefore takes that reaction at
//! the step that causes it: the integrator gets
//!
//! ```text
//! F' = F − K_t (ΔU* − ΔUⁿ),   ΔU* = (F + C + K_t ΔUⁿ)/(m + K_t)     (per body axis for torques)
//! ```
//!
//! (`C` the last step's contact load, which the contact sub-cycling adds itself), i.e.
//! `(m + K) ΔUⁿ⁺¹ = F + K ΔUⁿ` without contacts: the explicit reaction `−K ΔUⁿ` contained in
//! `F` is replaced by the implicit `−K ΔUⁿ⁺¹`. The correction vanishes whenever the velocity
//! change is steady, so a particle resting on a bed is held by contacts equal to its weight. The root becomes `(K − K_true)/(m + K)`, stable for
//! any estimate with `|K_true − K| < m + K`; the effective mass in a sustained acceleration
//! is `m + K_true`, as with the explicit scheme; steady balances are untouched. The loads are
//! used at the step's level (`LoadScheme::Constant`, which [`Coupled::new`] sets for free
//! bodies: an Adams–Bashforth extrapolation of the lagged IBM force was unstable too).
//!
//! # The immersed boundary's effective size: retracted forcing markers
//! A direct-forcing immersed boundary with a regularised delta function makes a body
//! hydrodynamically *larger* than its input shape: the forcing is spread over the kernel's
//! support, and the fluid is held near the solid velocity a fraction of a spacing outside the
//! markers. With the Roma 3-point kernel and one forcing iteration the sphere array of the
//! `stokes_drag` case measures a hydrodynamic radius `a_h` (the radius whose exact drag equals
//! the measured one) of `a + 0.39` at `d = 6` falling to `a + 0.31` at `d = 24`: 9 % excess
//! drag at `d = 12`, a settling sphere 6–12 % too slow, thickened impeller blades. Following
//! Breugem (2012, J. Comput. Phys. 231, 4469: the Lagrangian grid retracted inward by
//! `r_d ≈ 0.3Δ` for his scheme, validated on the same Zick–Homsy array) the markers that
//! force the fluid lie on the surface moved **inward by `r_d`**
//! ([`CouplingParams::retraction`], [`Shape::retracted_markers`]); the default
//! [`DEFAULT_RETRACTION`] is calibrated for the default kernel and one iteration on the
//! `stokes_drag` array alone (`verification/examples/calibrate_retraction.rs`,
//! `verification/ref/retraction_calibration.csv`) and validated on the ten Cate settling
//! sphere (verification case `ten_cate`). More forcing iterations or another kernel change the
//! excess and need their own calibration. Decisions:
//!
//! - **Area weights of the retracted surface.** A retracted marker stands for a piece of the
//!   retracted surface (the shrunk shape's markers: sphere `d − 2r_d`; cylinder `d − 2r_d`,
//!   `ℓ − 2r_d`, rims included; cuboid every edge `− 2r_d`; impeller parts likewise). The
//!   forcing `2ρ(U − u)A_m` then fills a shell of unit thickness on the surface where the
//!   fluid is driven, as on the true surface without retraction; weighting with the true
//!   area would force the retracted shell harder than its volume (by `(a/(a − r_d))²`, 20 %
//!   at `d = 8`). As we recall Breugem's scheme (the paper's text was not at hand when this
//!   was written), his marker volumes are likewise those of a unit-thickness shell about the
//!   retracted sphere.
//! - **Two marker sets.** The forcing markers (`markers`, retracted) give the marker
//!   positions, stencils, forces, the IBM loads and the shell's inertia `K`; the contact
//!   markers (`contact_markers`, on the true surface, as [`Shape::markers`] makes them) go to
//!   [`Contacts`]: the paper's contact law acts between true surfaces. With `r_d = 0` both
//!   are the same markers, bit for bit.
//! - **Volumes, masses, inertia and the interior-fluid term keep the true shape.** The
//!   retraction only moves where the fluid is forced; the body is unchanged. The interior
//!   sums (`α = clamp(½ − sd, 0, 1)`, `sd` of the true shape) count the fluid inside the
//!   *true* surface: with the retraction calibrated, that is the fluid the body carries along
//!   (the hydrodynamic surface is the true one), so its momentum change belongs to the body,
//!   including the layer between the retracted and the true surface, which the forcing holds
//!   at the solid velocity. Using the retracted shape would leave that layer's inertia
//!   (`ρ S r_d`, about 10 % of a `d = 8` sphere's fluid volume) as an extra explicit load on
//!   the body. (The choice is ours, argued here; the calibration and `ten_cate` are run with
//!   it.)
//! - **The band** is widened by `r_d` (the stencils of retracted markers reach `r_d`
//!   deeper; tested).
//! - **Thin parts**: every dimension must exceed `2 r_d` (a case's particles do by the
//!   allowed range, `r_d < 0.5` against a smallest size of 1); the impeller's blades and disk
//!   are checked on their own and refused with the dimension named (the paper's PBT at scale
//!   1/8 has 0.375-thick blades).
//!
//! # Density at the markers
//! The direct-forcing update `ΔF_m = 2 ρ_m (U_m − u_m)` uses `ρ_m = 1`, the reference density
//! of the lattice (`ρ = 1 + O(Ma²)`): interpolating `ρ` would cost a second pass over the
//! stencils per iteration for a correction of relative size `δρ ≈ 1e-4` or below, which the
//! forcing iterations absorb anyway.
//!
//! # The band: no full-grid pass in the step
//! Every grid-sized operation of a step is restricted to the **band** of each body, the nodes
//! within `√3 · h` of its surface (`h` the kernel's support half-width, so every stencil node
//! of every marker is in it), built per step from the shape's chords along x-rows
//! (module `band`): the fluid velocity is evaluated only there (once per node and iteration, not
//! once per stencil entry), the marker forces are spread straight into the fluid's force
//! field (no intermediate buffer, no copy), and the force field is cleared only where the
//! previous step wrote it. The velocity buffer is grid-sized but written and read only at band
//! nodes. Band runs are grouped by z-plane and processed in parallel over planes, each
//! plane's runs in body order: deterministic for any thread count.
//!
//! **Dense beds.** Small bodies in a dense bed have bands several times their volume, and
//! overlapping: when the bands together hold more than a tenth of the grid (`DENSE_BAND_FRACTION`), one pass over every
//! node is cheaper than the bands' runs, and no band is built at all. That holds for every
//! case of the paper at every scale (bands of 0.33–0.38 of the grid at s = 1): a band node,
//! read from 19 populations in short runs, costs about 15 times a node of the one pass. Whether to build it is
//! decided before building, from an estimate: per body, the number of nodes its band had
//! when last built (first in [`Coupled::new`], at the bodies' initial poses), summed. The
//! velocity is then evaluated at every node by the same arithmetic, so the marker
//! velocities, forces and everything after are the same bits either way: the estimate
//! decides only the cost (tested, with the two paths alternating from step to step). A step
//! whose band was not built leaves the next step to clear the whole force field.

use std::fmt;
use std::sync::Arc;

use rayon::prelude::*;

use crate::contact::{ContactParams, Contacts, Walls};
use crate::ibm::{DeltaKernel, StencilError, Stencils};
use crate::lattice::Face;
use crate::lbm::{Fluid, FluidError, FluidState, Real};
use crate::rigid::{
    LoadScheme, Marker, Quat, RetractionError, RigidBody, Shape, Vec3, DEFAULT_MARKER_SPACING,
};

/// The whole-grid path is taken when the bodies' bands are estimated to hold more than this
/// fraction of the grid's nodes (module docs, "Dense beds"). Only the cost depends on it.
///
/// Measured (2 threads, f32, `benches/results/2026-11-27-dense-vs-band.json`): the whole-grid
/// path is the faster in every case, by 1.18–1.43 times at s = 1/4 and 1/2 (band fractions
/// 0.70–2.4) and by 1.72 times at s = 1 (0.33 and 0.38, where a threshold of 1/2 would choose
/// the bands): a band node costs about 15 times a node of the whole-grid pass (the 19
/// populations of a short run each a cache line of their own), so the two break even near a
/// fifteenth of the grid. A single body in a large box (the verification's spheres, fractions
/// below 0.01) keeps its band.
pub const DENSE_BAND_FRACTION: f64 = 0.1;

mod band;
mod forcing;
mod interior;
mod loads;
mod markers;
mod moments;

use band::{band_runs, run_nodes, Band};
use interior::{InteriorNodes, Moment};
// The forcing shell's inertia and its implicit reaction are also the device's coupled step's,
// which advances its bodies on the host as this module does.
pub(crate) use loads::{advance_bodies, interior_loads, shell_inertia, BodyUpdate};
use moments::Moments;

/// Options of the coupling.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct CouplingParams {
    /// The regularised delta function of the IBM transfer.
    pub kernel: DeltaKernel,
    /// Direct-forcing iterations per time step (`K ≥ 1`).
    pub iterations: usize,
    /// Target spacing of the surface markers (lattice units).
    pub marker_spacing: f64,
    /// Gravitational acceleration (lattice units). Free bodies feel their net weight
    /// `(ρ_p − ρ_f) V g`; the fluid itself is not forced by it (its hydrostatic pressure does
    /// not move anything in a closed box).
    pub gravity: [f64; 3],
    /// Contacts between bodies and with the box walls (the paper's Table 1), or `None`; with
    /// their sub-steps per fluid step ([`ContactParams::substeps`], ≥ 1).
    pub contacts: Option<ContactParams>,
    /// Retraction `r_d` of the forcing markers (lattice units, `≥ 0`): the immersed boundary
    /// forces the fluid on every body's surface moved inward by `r_d`
    /// ([`Shape::retracted_markers`]), so that its hydrodynamic size is the input size
    /// (module docs, "The immersed boundary's effective size"). Default
    /// [`DEFAULT_RETRACTION`], calibrated for the Roma 3-point kernel and one forcing
    /// iteration.
    pub retraction: f64,
}

/// The calibrated retraction of the forcing markers (lattice units) for the default
/// [`DeltaKernel`] (Roma 3-point) and one forcing iteration, fitted on the Stokes drag of the
/// periodic sphere array (`verification/ref/retraction_calibration.csv`; module docs).
pub const DEFAULT_RETRACTION: f64 = 0.36;

impl Default for CouplingParams {
    /// The default kernel, one forcing iteration, [`DEFAULT_MARKER_SPACING`], no gravity, no
    /// contacts ([`crate::contact::DEFAULT_SUBSTEPS`] sub-steps once they are turned on), the calibrated
    /// [`DEFAULT_RETRACTION`].
    fn default() -> Self {
        Self {
            kernel: DeltaKernel::default(),
            iterations: 1,
            marker_spacing: DEFAULT_MARKER_SPACING,
            gravity: [0.0; 3],
            contacts: None,
            retraction: DEFAULT_RETRACTION,
        }
    }
}

/// Errors of the coupling.
#[derive(Clone, Debug, PartialEq)]
pub enum CouplingError {
    /// No forcing iteration requested.
    NoIterations,
    /// The marker spacing is not positive and finite.
    MarkerSpacing(f64),
    /// The stencils could not be built (a marker off the box on a walled axis, or not finite).
    Stencil(StencilError),
    /// A state to restore has a different number of bodies.
    BodyCount {
        /// Bodies in this coupling.
        expected: usize,
        /// Bodies in the state.
        found: usize,
    },
    /// A fluid state to restore does not fit (the fluid's message).
    State(String),
    /// Invalid contact parameters or sub-step count.
    Contacts(String),
    /// A body's forcing markers cannot be retracted by [`CouplingParams::retraction`] (a
    /// dimension not larger than twice the retraction, or a negative retraction).
    Retraction {
        /// The body's index.
        body: usize,
        /// Why.
        error: RetractionError,
    },
}

impl fmt::Display for CouplingError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            CouplingError::NoIterations => write!(f, "at least one forcing iteration is needed"),
            CouplingError::MarkerSpacing(h) => {
                write!(f, "marker spacing {h}: must be positive and finite")
            }
            CouplingError::Stencil(e) => write!(f, "IBM stencils: {e}"),
            CouplingError::BodyCount { expected, found } => {
                write!(f, "state has {found} bodies, the case has {expected}")
            }
            CouplingError::State(e) => write!(f, "fluid state: {e}"),
            CouplingError::Contacts(e) => write!(f, "contacts: {e}"),
            CouplingError::Retraction { body, error } => write!(f, "body {body}: {error}"),
        }
    }
}

impl std::error::Error for CouplingError {}

impl From<StencilError> for CouplingError {
    fn from(e: StencilError) -> Self {
        CouplingError::Stencil(e)
    }
}

/// The interior-fluid sums of a body (module docs), with the body at its position during the
/// last step.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct InteriorMomentum {
    /// `(P, L, V)` before the forcing: `P = Σ α j`, `L = Σ α r × j`, `V = Σ α`.
    pub before: (Vec3, Vec3, f64),
    /// `(P, L, V)` after the fluid step.
    pub after: (Vec3, Vec3, f64),
}

/// The loads on one body from the last step (world frame, torques about its centre).
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct BodyLoads {
    /// `−Σ_m F_m` over the body's markers.
    pub ibm_force: Vec3,
    /// `−Σ_m r_m × F_m`.
    pub ibm_torque: Vec3,
    /// Rate of change of the interior fluid's momentum, `P_after − P_before + V ω × U`.
    pub interior_force: Vec3,
    /// Rate of change of the interior fluid's angular momentum,
    /// `L_after − L_before + ω × (I_f ω)`.
    pub interior_torque: Vec3,
    /// Contact force, averaged over the step's sub-steps (zero without contacts). For a
    /// prescribed body (an impeller) this is the paper's "solids" load: reported, not applied.
    pub contact_force: Vec3,
    /// Contact torque about the body's centre, averaged over the sub-steps.
    pub contact_torque: Vec3,
}

impl BodyLoads {
    /// The hydrodynamic force, IBM plus interior term.
    pub fn force(&self) -> Vec3 {
        self.ibm_force + self.interior_force
    }

    /// The hydrodynamic torque, IBM plus interior term.
    pub fn torque(&self) -> Vec3 {
        self.ibm_torque + self.interior_torque
    }
}

/// The kinematic state of one body in a [`CoupledState`].
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct BodyState {
    /// Position of the centre of mass.
    pub position: Vec3,
    /// Orientation quaternion `(w, x, y, z)`.
    pub orientation: [f64; 4],
    /// Velocity.
    pub velocity: Vec3,
    /// Angular velocity (world frame).
    pub angular_velocity: Vec3,
    /// The body's time.
    pub time: f64,
    /// The last step's change of velocity and angular velocity ([`Coupled::velocity_change`]).
    pub velocity_change: (Vec3, Vec3),
    /// The last step's averaged contact force and torque (the next step's shell reaction
    /// predicts with them).
    pub contact: (Vec3, Vec3),
}

/// Everything a coupled run needs to continue bitwise identically: the fluid at an even step
/// (with the last step's force field, which the outputs at this step need) and the bodies'
/// states.
#[derive(Clone, Debug, PartialEq)]
pub struct CoupledState<T> {
    /// The fluid.
    pub fluid: FluidState<T>,
    /// The bodies, in order.
    pub bodies: Vec<BodyState>,
}

/// Wall-clock seconds spent in each phase of [`Coupled::step`], summed over the steps since
/// the coupling was made (or since [`Coupled::reset_timings`]).
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct StepTimings {
    /// Steps counted.
    pub steps: u64,
    /// 1–2: markers, stencils and band.
    pub geometry: f64,
    /// 3 and 7: interior-fluid sums (both).
    pub interior: f64,
    /// 4–5: clearing, band velocity, interpolation, forcing and spreading.
    pub forcing: f64,
    /// The interpolation `u_m = I u` of phase 5 (a part of `forcing`, not added again by
    /// [`StepTimings::total`]).
    pub interpolation: f64,
    /// The spreading `S ΔF` into the fluid's force field of phase 5 (a part of `forcing`).
    pub spreading: f64,
    /// 6: the fluid step.
    pub fluid: f64,
    /// 7–8: loads and the external loads of the body update.
    pub bodies: f64,
    /// 8: the body update itself: contacts and the sub-stepped integration (without contacts,
    /// one integration step per body).
    pub contacts: f64,
}

impl StepTimings {
    /// Total seconds.
    pub fn total(&self) -> f64 {
        self.geometry + self.interior + self.forcing + self.fluid + self.bodies + self.contacts
    }
}

/// A lattice fluid with immersed rigid bodies (fixed, prescribed or free), coupled by
/// direct-forcing IBM. See the module docs and [`Coupled::step`].
pub struct Coupled<T: Real> {
    fluid: Fluid<T>,
    bodies: Vec<RigidBody>,
    /// Per body, its forcing markers in the body frame: the surface retracted by
    /// `retraction` (module docs). Positions, areas and the shell's inertia come from these.
    /// Bodies with equal sets share one ([`shared_sets`]).
    markers: Vec<Arc<[Marker]>>,
    /// Per body, its contact markers in the body frame: on the true surface (the same sets
    /// as `markers` when `retraction = 0`), shared likewise.
    contact_markers: Vec<Arc<[Marker]>>,
    /// The retraction of the forcing markers.
    retraction: f64,
    /// Marker index range of body `b`: `offsets[b]..offsets[b + 1]` (global marker order).
    offsets: Vec<usize>,
    /// The body of each marker (global order).
    owner: Vec<u32>,
    stencils: Stencils,
    iterations: usize,
    gravity: Vec3,
    periodic: [bool; 3],
    /// Half-width of the band: `√3 ×` the kernel's support, plus a margin.
    band_half_width: f64,
    /// The band of this step, and that of the previous step (whose force-field entries are
    /// cleared at the start of the next).
    band: Band,
    band_prev: Band,
    /// Per body, the number of nodes in its band when that was last built (first in
    /// [`Coupled::new`]): their sum decides whether the band is built ([`Coupled::dense_band`]).
    band_estimate: Vec<usize>,
    // ---- reusable buffers, one entry per marker (global order) or per node ----
    /// Marker area weights `A_m`.
    area: Vec<f64>,
    /// Marker world positions.
    position: Vec<[f64; 3]>,
    /// Solid velocity `U_m` at the markers.
    solid: Vec<[f64; 3]>,
    /// Interpolated fluid velocity `u_m`.
    fluid_u: Vec<[f64; 3]>,
    /// Force increment of the current iteration, `ΔF_m A_m`.
    increment: Vec<[f64; 3]>,
    /// Total force of each marker on the fluid in the current step, `Σ_k ΔF_m^k A_m`.
    marker_force: Vec<[f64; 3]>,
    /// Fluid velocity (interior node index); valid at the band nodes of the current step.
    velocity: Vec<[f64; 3]>,
    /// Dense steps: the momentum `j` at every node for the fluid's current state (module `moments`).
    moments: Moments,
    /// Per body, the interior-fluid momentum sums.
    interior: Vec<InteriorMomentum>,
    /// Per body, the nodes and weights of its interior sums, recorded in phase 3 and reused
    /// in phase 7.
    interior_nodes: Vec<InteriorNodes>,
    /// Per body, the loads of the last step.
    loads: Vec<BodyLoads>,
    /// Per body, the forcing shell's mass and body-frame moments `(K_t, K_r)` (module docs).
    shell: Vec<(f64, Vec3)>,
    /// Per free body, its change of velocity and angular velocity (world) in the last step.
    velocity_change: Vec<(Vec3, Vec3)>,
    /// Per body, its velocity and angular velocity at the start of the step's update.
    start: Vec<(Vec3, Vec3)>,
    /// Forces the band to be built (`Some(false)`) or the whole grid (`Some(true)`, no band
    /// built) instead of choosing by the estimated size (tests: both give the same bits).
    dense_override: Option<bool>,
    timings: StepTimings,
    contacts: Option<Contacts>,
}

impl<T: Real> Coupled<T> {
    /// Couples `fluid` with `bodies`, turning on the fluid's force field (the coupling owns it
    /// from now on: it is zero away from the bodies and rewritten near them every step).
    /// Markers are generated once per body at `params.marker_spacing` and kept in a fixed
    /// global order (body by body, marker by marker), so spreading is deterministic: the
    /// forcing markers on the surface retracted by `params.retraction`, the contact markers on
    /// the true surface (module docs).
    ///
    /// # Errors
    /// `params.iterations == 0`, a marker spacing that is not positive and finite, a body
    /// that cannot be retracted by `params.retraction` ([`Shape::retracted_markers`]).
    pub fn new(
        mut fluid: Fluid<T>,
        bodies: Vec<RigidBody>,
        params: CouplingParams,
    ) -> Result<Self, CouplingError> {
        if params.iterations == 0 {
            return Err(CouplingError::NoIterations);
        }
        if !(params.marker_spacing.is_finite() && params.marker_spacing > 0.0) {
            return Err(CouplingError::MarkerSpacing(params.marker_spacing));
        }
        fluid.enable_force_field();
        let mut bodies = bodies;
        for b in bodies.iter_mut().filter(|b| b.is_free()) {
            b.load_scheme = LoadScheme::Constant;
        }
        // The contacts' markers on the true surface; the forcing markers retracted
        // (`retracted_markers(h, 0)` is `markers(h)`, bit for bit).
        let contact_markers = shared_sets(bodies.iter().map(|b| b.shape().markers(params.marker_spacing)));
        let markers = if params.retraction == 0.0 {
            contact_markers.clone()
        } else {
            let sets = bodies
                .iter()
                .enumerate()
                .map(|(i, b)| {
                    b.shape()
                        .retracted_markers(params.marker_spacing, params.retraction)
                        .map_err(|error| CouplingError::Retraction { body: i, error })
                })
                .collect::<Result<Vec<_>, _>>()?;
            shared_sets(sets.into_iter())
        };
        let mut offsets = vec![0];
        for m in &markers {
            offsets.push(offsets.last().unwrap() + m.len());
        }
        let total = *offsets.last().unwrap();
        let b = fluid.boundaries();
        let periodic = std::array::from_fn(|a| b.get(Face::from_axis(a, true)).is_periodic());
        let nodes = fluid.grid().nodes();
        let n_bodies = bodies.len();
        let band = Band { per_body: vec![Vec::new(); n_bodies], ..Band::default() };
        // Retracted markers sit `retraction` inside the surface: their stencils reach that
        // much deeper.
        let band_half_width = params.kernel.support() * 3f64.sqrt() + params.retraction + 1e-6;
        let band_estimate = bodies
            .par_iter()
            .map_init(Vec::new, |runs, body| {
                band_runs(body, fluid.grid(), periodic, band_half_width, runs);
                run_nodes(runs)
            })
            .collect();
        let contacts = match params.contacts {
            Some(cp) => {
                if cp.substeps == 0 {
                    return Err(CouplingError::Contacts("contact substeps must be at least 1".into()));
                }
                let g = fluid.grid();
                let walls = Walls::bounce_back([g.nx, g.ny, g.nz], periodic.map(|p: bool| !p));
                let c = Contacts::new(cp, walls, &bodies, &contact_markers)
                    .map_err(|e| CouplingError::Contacts(e.to_string()))?;
                Some(c)
            }
            None => None,
        };
        let owner =
            markers.iter().enumerate().flat_map(|(b, m)| std::iter::repeat_n(b as u32, m.len())).collect();
        Ok(Self {
            fluid,
            bodies,
            offsets,
            owner,
            stencils: Stencils::new(params.kernel),
            iterations: params.iterations,
            gravity: Vec3::from(params.gravity),
            periodic,
            band_half_width,
            band_prev: band.clone(),
            band,
            band_estimate,
            area: markers.iter().flat_map(|m| m.iter()).map(|m| m.area).collect(),
            position: vec![[0.0; 3]; total],
            solid: vec![[0.0; 3]; total],
            fluid_u: vec![[0.0; 3]; total],
            increment: vec![[0.0; 3]; total],
            marker_force: vec![[0.0; 3]; total],
            velocity: vec![[0.0; 3]; nodes],
            moments: Moments::default(),
            interior: vec![InteriorMomentum::default(); n_bodies],
            interior_nodes: vec![InteriorNodes::default(); n_bodies],
            loads: vec![BodyLoads::default(); n_bodies],
            shell: markers.iter().map(|m| shell_inertia(m)).collect(),
            velocity_change: vec![(Vec3::zeros(), Vec3::zeros()); n_bodies],
            start: vec![(Vec3::zeros(), Vec3::zeros()); n_bodies],
            dense_override: None,
            timings: StepTimings::default(),
            contacts,
            markers,
            contact_markers,
            retraction: params.retraction,
        })
    }

    /// The fluid.
    pub fn fluid(&self) -> &Fluid<T> {
        &self.fluid
    }

    /// The fluid, mutably (initial conditions, obstacles). The force field must stay on and
    /// belongs to the coupling.
    pub fn fluid_mut(&mut self) -> &mut Fluid<T> {
        self.moments.forget();
        &mut self.fluid
    }

    /// The bodies.
    pub fn bodies(&self) -> &[RigidBody] {
        &self.bodies
    }

    /// Gravity.
    pub fn gravity(&self) -> Vec3 {
        self.gravity
    }

    /// Forcing markers of body `b` (body frame): on its surface retracted by
    /// [`Coupled::retraction`].
    pub fn markers(&self, b: usize) -> &[Marker] {
        &self.markers[b]
    }

    /// Contact markers of body `b` (body frame): on its true surface.
    pub fn contact_markers(&self, b: usize) -> &[Marker] {
        &self.contact_markers[b]
    }

    /// The retraction of the forcing markers ([`CouplingParams::retraction`]).
    pub fn retraction(&self) -> f64 {
        self.retraction
    }

    /// Total number of markers.
    pub fn marker_count(&self) -> usize {
        *self.offsets.last().unwrap()
    }

    /// Number of markers on body `b`.
    pub fn body_marker_count(&self, b: usize) -> usize {
        self.offsets[b + 1] - self.offsets[b]
    }

    /// The estimated size of the bodies' bands, in nodes with repetitions (module docs,
    /// "Dense beds"): the sum of each body's band when it was last built.
    pub fn band_estimate(&self) -> usize {
        self.band_estimate.iter().sum()
    }

    /// Whether the last step took the whole-grid path (its band was not built).
    pub fn whole_grid(&self) -> bool {
        self.band.whole_grid
    }

    /// Forces the whole-grid path (`Some(true)`), the band path (`Some(false)`) or leaves
    /// the choice to the estimate (`None`; module docs, "Dense beds"). Only the cost changes.
    pub fn set_dense_override(&mut self, dense: Option<bool>) {
        self.dense_override = dense;
    }

    /// Forcing iterations per step.
    pub fn iterations(&self) -> usize {
        self.iterations
    }

    /// Nodes in the band of the last step (counted once per body: where two bodies' bands
    /// overlap, twice). When that band was not built (the bands were estimated to hold more
    /// than a tenth of the grid, module docs), the estimate: the sum of the bodies' counts from
    /// their last built bands.
    pub fn band_nodes(&self) -> usize {
        if self.band_prev.whole_grid {
            self.band_estimate.iter().sum()
        } else {
            self.band_prev.nodes()
        }
    }

    /// Force of each marker on the fluid in the last step, `Σ_k ΔF_m^k A_m` (global marker
    /// order: body by body).
    pub fn marker_forces(&self) -> &[[f64; 3]] {
        &self.marker_force
    }

    /// The loads on body `b` from the last step.
    pub fn loads(&self, b: usize) -> &BodyLoads {
        &self.loads[b]
    }

    /// Hydrodynamic force on body `b` from the last step: `−Σ_m F_m` over its markers plus
    /// the rate of change of its interior fluid's momentum.
    pub fn hydrodynamic_force(&self, b: usize) -> Vec3 {
        self.loads[b].force()
    }

    /// Hydrodynamic torque on body `b` about its centre, from the last step:
    /// `−Σ_m (X_m − x_c) × F_m` plus the rate of change of its interior fluid's angular
    /// momentum.
    pub fn hydrodynamic_torque(&self, b: usize) -> Vec3 {
        self.loads[b].torque()
    }

    /// The change of velocity and angular velocity (world) of body `b` in the last step (the
    /// state of the implicit shell reaction, module docs; zero for bodies that are not free).
    pub fn velocity_change(&self, b: usize) -> (Vec3, Vec3) {
        self.velocity_change[b]
    }

    /// The state for a checkpoint (at an even time step; see [`Fluid::snapshot`]), with the
    /// fluid's force field (the last step's IBM forcing): the next step does not need it, but
    /// the velocity's half-force term `u = (j + F/2)/ρ` at this step does, so the outputs of a
    /// run resumed here (fields, momentum, Mach number) equal the uninterrupted run's.
    ///
    /// # Errors
    /// At an odd time step.
    pub fn snapshot(&self) -> Result<CoupledState<T>, FluidError> {
        Ok(CoupledState {
            fluid: self.fluid.snapshot()?,
            bodies: body_states(&self.bodies, &self.velocity_change, &self.loads),
        })
    }

    /// Restores a state taken by [`Coupled::snapshot`] from a coupling built the same way (same
    /// case). The continuation is bitwise identical to the uninterrupted run, and with the
    /// state's force field (as `snapshot` takes it) so is everything computed from the fluid
    /// before the next step. Without one (older checkpoints) the field is zero. The next step
    /// clears the whole field first (the previous band is unknown after a restore): what the
    /// uninterrupted run's clearing of its previous band leaves.
    ///
    /// # Errors
    /// A fluid state that does not fit, or a body count that differs.
    pub fn restore(&mut self, s: &CoupledState<T>) -> Result<(), CouplingError> {
        if s.bodies.len() != self.bodies.len() {
            return Err(CouplingError::BodyCount { expected: self.bodies.len(), found: s.bodies.len() });
        }
        self.moments.forget();
        self.fluid.restore(&s.fluid).map_err(|e| CouplingError::State(e.to_string()))?;
        if s.fluid.force.is_none() {
            self.fluid.enable_force_field();
            self.fluid.clear_force_field();
        }
        restore_bodies(&mut self.bodies, &mut self.velocity_change, &mut self.loads, &s.bodies);
        // The previous band := the whole grid, so that the next step clears all of it.
        self.band_prev.set_whole_grid();
        Ok(())
    }

    /// Time spent per phase of the step (see [`StepTimings`]).
    pub fn timings(&self) -> &StepTimings {
        &self.timings
    }

    /// Rebuilds of the contacts' marker-pair list so far (0 without contacts).
    pub fn contact_list_rebuilds(&self) -> u64 {
        self.contacts.as_ref().map_or(0, |c| c.list_stats().0)
    }

    /// Sets the skin of the contact pair list ([`Contacts::set_skin`]); no effect without
    /// contacts. The loads do not depend on it (bitwise), only the cost.
    ///
    /// # Panics
    /// If `skin` is negative or not finite.
    pub fn set_contact_skin(&mut self, skin: f64) {
        if let Some(c) = self.contacts.as_mut() {
            c.set_skin(skin);
        }
    }

    /// The contact engine, if the bodies have contacts.
    pub fn contacts(&self) -> Option<&Contacts> {
        self.contacts.as_ref()
    }

    /// Restarts the phase timers.
    pub fn reset_timings(&mut self) {
        self.timings = StepTimings::default();
    }

    /// The interior-fluid sums of body `b` from the last step.
    pub fn interior_momentum(&self, b: usize) -> &InteriorMomentum {
        &self.interior[b]
    }

    /// Advances the coupled system by one time step (`Δt = 1`). The order, at time `tⁿ`:
    ///
    /// 1. **Markers**: world positions `X_m` and solid velocities `U_m = v + ω × r` from the
    ///    bodies at `tⁿ` (global marker order: body by body, marker by marker).
    /// 2. **Stencils** ([`Stencils::build`], with the box's periodicity) and the **band** of
    ///    each body (module docs), grouped by z-plane; not built when the bands are estimated
    ///    to hold more than a tenth of the grid (`DENSE_BAND_FRACTION`; module docs, "Dense beds").
    /// 3. **Interior sums before**: `P`, `L`, `V` of each free or fixed body from the fluid at
    ///    `tⁿ` (module docs); prescribed bodies (impellers) have no interior term. Each body's
    ///    nodes and weights `α` are recorded for step 7.
    /// 4. **Clear** the force field where the previous step spread (its band; the whole field
    ///    when that was not built), and the marker force totals.
    /// 5. **`K` direct-forcing iterations**, each: the fluid velocity `u = (j + F/2)/ρ` at the
    ///    band nodes (every node when the band was not built; the current force field
    ///    included, so each iteration sees the previous ones' correction); `u_m = I u` at the
    ///    markers; `ΔF_m = 2 ρ_m (U_m − u_m)` with `ρ_m = 1`, times the marker volume `A_m Δ`,
    ///    accumulated per marker; spread (adding) into the fluid's force field.
    /// 6. **[`Fluid::step`]**: collision with the uniform body force plus the IBM force field.
    /// 7. **Interior sums after** (fluid at `tⁿ⁺¹`, bodies still at `tⁿ`: over the nodes and
    ///    weights recorded in step 3, in the same order, the same bits), then the loads:
    ///    per body `−Σ_m F_m`, `−Σ_m r_m × F_m`, plus the interior rate with its flux
    ///    correction ([`BodyLoads`]).
    /// 8. **Bodies advance** ([`RigidBody::step`]): free bodies with their hydrodynamic loads
    ///    and net weight `(ρ_p − 1) V g` (fluid density 1); prescribed bodies move; fixed
    ///    bodies stay. With contacts the step is sub-cycled ([`Contacts::advance`]): contact
    ///    loads recomputed every sub-step, the external loads held; the contact loads averaged
    ///    over the sub-steps are stored in [`BodyLoads`].
    ///
    /// No allocation once the buffers have grown (the first steps).
    ///
    /// # Errors
    /// The stencils could not be built (a marker outside the box on a walled axis, or a
    /// non-finite position); nothing has been changed then.
    pub fn step(&mut self) -> Result<(), CouplingError> {
        let mut clock = std::time::Instant::now();
        let mut lap = |slot: &mut f64| {
            let now = std::time::Instant::now();
            *slot += (now - clock).as_secs_f64();
            clock = now;
        };
        let mut timings = self.timings;
        self.place_markers(); // 1
        self.build_geometry()?; // 2
        lap(&mut timings.geometry);
        self.interior_sums(Moment::Before); // 3
        lap(&mut timings.interior);
        self.clear_forcing(); // 4
        let [interpolation, spreading] = self.force(); // 5
        timings.interpolation += interpolation;
        timings.spreading += spreading;
        lap(&mut timings.forcing);
        self.fluid.step(); // 6
        lap(&mut timings.fluid);
        self.interior_sums(Moment::After); // 7
        lap(&mut timings.interior);
        self.collect_loads(); // 7
        lap(&mut timings.bodies);
        self.advance_bodies(); // 8
        lap(&mut timings.contacts);
        std::mem::swap(&mut self.band, &mut self.band_prev);
        timings.steps += 1;
        self.timings = timings;
        Ok(())
    }

    /// Runs `n` steps.
    ///
    /// # Errors
    /// As [`Coupled::step`]; the run stops at the first error.
    pub fn run(&mut self, n: u64) -> Result<(), CouplingError> {
        for _ in 0..n {
            self.step()?;
        }
        Ok(())
    }

    /// The shape of body `b` (convenience).
    pub fn shape(&self, b: usize) -> &Arc<dyn Shape> {
        self.bodies[b].shape()
    }
}

/// Body-frame marker sets with the equal ones (bit for bit) shared: a population of equal
/// particles keeps one set (a few kB, which stays in cache while the contacts and the marker
/// placement walk every body) instead of one copy per body (27 MB for pbt-ld2 at s = 1/2).
fn shared_sets(sets: impl Iterator<Item = Vec<Marker>>) -> Vec<Arc<[Marker]>> {
    let same = |a: &[Marker], b: &[Marker]| {
        let bits = |m: &Marker| {
            [m.position.x, m.position.y, m.position.z, m.normal.x, m.normal.y, m.normal.z, m.area]
                .map(f64::to_bits)
        };
        a.len() == b.len() && a.iter().zip(b).all(|(x, y)| bits(x) == bits(y))
    };
    let mut unique: Vec<Arc<[Marker]>> = Vec::new();
    sets.map(|set| {
        if let Some(u) = unique.iter().find(|u| same(u, &set)) {
            return u.clone();
        }
        let u: Arc<[Marker]> = set.into();
        unique.push(u.clone());
        u
    })
    .collect()
}

#[cfg(test)]
mod tests;

/// The bodies' states for a snapshot: pose, velocities, time, last velocity change and the
/// averaged contact loads (what [`restore_bodies`] puts back); what [`Coupled::snapshot`] and
/// the device's coupled step share.
pub(crate) fn body_states(
    bodies: &[RigidBody],
    velocity_change: &[(Vec3, Vec3)],
    loads: &[BodyLoads],
) -> Vec<BodyState> {
    bodies
        .iter()
        .zip(velocity_change)
        .zip(loads)
        .map(|((b, c), l)| {
            let q = b.orientation.into_inner();
            BodyState {
                position: b.position,
                orientation: [q.w, q.i, q.j, q.k],
                velocity: b.velocity,
                angular_velocity: b.angular_velocity,
                time: b.time,
                velocity_change: *c,
                contact: (l.contact_force, l.contact_torque),
            }
        })
        .collect()
}

/// Restores the bodies, their last velocity changes and their loads (the contact part; the
/// rest is recomputed by the next step) from a snapshot's `states`: what [`Coupled::restore`]
/// and the device's coupled step share.
pub(crate) fn restore_bodies(
    bodies: &mut [RigidBody],
    velocity_change: &mut [(Vec3, Vec3)],
    loads: &mut [BodyLoads],
    states: &[BodyState],
) {
    for (((b, c), l), st) in
        bodies.iter_mut().zip(velocity_change.iter_mut()).zip(loads.iter_mut()).zip(states)
    {
        *l = BodyLoads { contact_force: st.contact.0, contact_torque: st.contact.1, ..BodyLoads::default() };
        // The quaternion as stored, bit for bit: it was a unit quaternion when written, and
        // normalising it again can move its last bits (and a resumed run off the
        // uninterrupted one).
        let [w, x, y, z] = st.orientation;
        *b = b
            .clone()
            .with_time(st.time)
            .with_position(st.position)
            .with_orientation(Quat::new_unchecked(crate::rigid::nalgebra::Quaternion::new(w, x, y, z)))
            .with_velocities(st.velocity, st.angular_velocity);
        b.reset_load_history();
        *c = st.velocity_change;
    }
}
