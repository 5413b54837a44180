//! Phases 7–8 of the coupled step: the loads on every body from the marker forces and the
//! interior sums, and the bodies' update (with the implicit shell reaction, module [`super`];
//! sub-cycled with contacts through [`crate::contact::step_bodies`], the one body update that
//! the coupled step and the dry bed share).

use rayon::prelude::*;

use super::{BodyLoads, Coupled, InteriorMomentum};
use crate::contact::{step_bodies, Contacts};
use crate::lbm::Real;
use crate::rigid::{Marker, RigidBody, Vec3};

impl<T: Real> Coupled<T> {
    /// Phase 7 (end): per body `−Σ_m F_m`, `−Σ_m r_m × F_m` over its markers, and the interior
    /// rates with their flux corrections ([`BodyLoads`]); the previous step's contact loads are
    /// kept (the implicit shell reaction predicts with them). Parallel over bodies.
    pub(super) fn collect_loads(&mut self) {
        let (bodies, interior, offsets) = (&self.bodies, &self.interior, &self.offsets);
        let (marker_force, position) = (&self.marker_force, &self.position);
        self.loads.par_iter_mut().enumerate().for_each(|(b, loads)| {
            let body = &bodies[b];
            let mut f = Vec3::zeros();
            let mut t = Vec3::zeros();
            for m in offsets[b]..offsets[b + 1] {
                let fm = Vec3::from(marker_force[m]);
                let r = Vec3::from(position[m]) - body.position;
                f -= fm;
                t -= r.cross(&fm);
            }
            let (interior_force, interior_torque) = interior_loads(body, &interior[b]);
            *loads = BodyLoads { ibm_force: f, ibm_torque: t, interior_force, interior_torque, ..*loads };
        });
    }

    /// Phase 8: free bodies get their hydrodynamic loads (with the implicit shell reaction) and
    /// net weight; then [`step_bodies`] advances every body over the step, sub-cycled with the
    /// contacts when there are any; the averaged contact loads and each free body's velocity
    /// change are recorded.
    pub(super) fn advance_bodies(&mut self) {
        advance_bodies(
            self.contacts.as_mut(),
            &mut self.bodies,
            &self.contact_markers,
            BodyUpdate {
                loads: &mut self.loads,
                shell: &self.shell,
                velocity_change: &mut self.velocity_change,
                start: &mut self.start,
            },
            self.gravity,
        );
    }
}

/// The forcing shell of a body's markers (module docs): `K_t = Σ A_m` and, per body axis,
/// `K_r,k = Σ A_m (|r_m|² − r_{m,k}²)` (a unit-thickness shell of fluid on the surface).
pub(crate) fn shell_inertia(markers: &[Marker]) -> (f64, Vec3) {
    let mut kt = 0.0;
    let mut kr = Vec3::zeros();
    for m in markers {
        let r = m.position;
        kt += m.area;
        kr += Vec3::new(r.y * r.y + r.z * r.z, r.z * r.z + r.x * r.x, r.x * r.x + r.y * r.y) * m.area;
    }
    (kt, kr)
}

/// The external load handed to a free body's integrator, with the shell reaction taken
/// implicitly (module docs): the predicted change `ΔU* = (F + C + K_t ΔUⁿ)/(m + K_t)` (`C` the
/// last step's averaged contact force, which the sub-cycling adds again itself) gives the
/// correction `D = −K_t (ΔU* − ΔUⁿ)`, and `F + D` is returned; per body axis likewise for the
/// torque. `D` vanishes whenever the velocity change is steady (at rest on a bed, in steady
/// fall, in uniform acceleration), so every steady balance is the physical one; without
/// contacts `F + D = m/(m + K_t) (F + K_t ΔUⁿ)`.
pub(crate) fn shell_implicit(
    body: &RigidBody,
    shell: &(f64, Vec3),
    change: &(Vec3, Vec3),
    contact: (Vec3, Vec3),
    f: Vec3,
    t: Vec3,
) -> (Vec3, Vec3) {
    let (kt, kr) = shell;
    let m = body.mass();
    let du = (f + contact.0 + change.0 * *kt) / (m + kt);
    let f = f - (du - change.0) * *kt;
    let inertia = body.mass_properties().principal_moments;
    let tb = body.vector_to_body(&t);
    let cb = body.vector_to_body(&contact.1);
    let dwb = body.vector_to_body(&change.1);
    let tb = Vec3::from_fn(|k, _| {
        let dw = (tb[k] + cb[k] + kr[k] * dwb[k]) / (inertia[k] + kr[k]);
        tb[k] - kr[k] * (dw - dwb[k])
    });
    (f, body.vector_to_world(&tb))
}

/// The interior-fluid loads of a body from its sums before and after the fluid step (module
/// [`super`]): `P⁺ − P⁻ + ω × u V` and `L⁺ − L⁻ + ω × (I_f ω)`, `I_f` the body's inertia at the
/// fluid's density.
pub(crate) fn interior_loads(body: &RigidBody, im: &InteriorMomentum) -> (Vec3, Vec3) {
    let (u, w) = (body.velocity, body.angular_velocity);
    let inertia_fluid = body.inertia_world() / body.density();
    let force = im.after.0 - im.before.0 + w.cross(&u) * im.after.2;
    let torque = im.after.1 - im.before.1 + w.cross(&(inertia_fluid * w));
    (force, torque)
}

/// The per-body arrays that phase 8 reads and writes besides the bodies.
pub(crate) struct BodyUpdate<'a> {
    /// The loads: the hydrodynamic part is read, the averaged contact part written.
    pub loads: &'a mut [BodyLoads],
    /// Each body's forcing shell, [`shell_inertia`].
    pub shell: &'a [(f64, Vec3)],
    /// The last step's velocity change on entry, this step's on return.
    pub velocity_change: &'a mut [(Vec3, Vec3)],
    /// Scratch: the velocities at the step's start.
    pub start: &'a mut [(Vec3, Vec3)],
}

/// Phase 8 (module [`super`]): free bodies get their hydrodynamic loads (with the implicit
/// shell reaction) and net weight under `gravity`; then [`step_bodies`] advances every body
/// over the step, sub-cycled with the contacts when there are any; the averaged contact loads
/// and each free body's velocity change are recorded. The one body update of the coupled step,
/// on the CPU and on the device.
pub(crate) fn advance_bodies<M: AsRef<[Marker]> + Sync>(
    contacts: Option<&mut Contacts>,
    bodies: &mut [RigidBody],
    contact_markers: &[M],
    u: BodyUpdate<'_>,
    gravity: Vec3,
) {
    for (s, b) in u.start.iter_mut().zip(bodies.iter()) {
        *s = (b.velocity, b.angular_velocity);
    }
    // `velocity_change` holds the last step's velocity change until the bodies have moved.
    let substeps = contacts.as_ref().map_or(1, |c| c.params().substeps);
    let (loads, shell, last) = (&*u.loads, u.shell, &*u.velocity_change);
    let averaged = step_bodies(contacts, bodies, contact_markers, substeps, |b: usize, body: &RigidBody| {
        let l = &loads[b];
        shell_implicit(
            body,
            &shell[b],
            &last[b],
            (l.contact_force, l.contact_torque),
            l.force() + body.net_weight(gravity, 1.0),
            l.torque(),
        )
    });
    if let Some(avg) = averaged {
        for (l, a) in u.loads.iter_mut().zip(avg) {
            l.contact_force = a.force;
            l.contact_torque = a.torque;
        }
    }
    for ((c, s), b) in u.velocity_change.iter_mut().zip(u.start.iter()).zip(bodies.iter()) {
        *c = if b.is_free() {
            (b.velocity - s.0, b.angular_velocity - s.1)
        } else {
            (Vec3::zeros(), Vec3::zeros())
        };
    }
}
