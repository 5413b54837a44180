//! Sub-cycling: advancing the bodies over one fluid time step in `n_sub` contact sub-steps
//! (module [`super`], "Sub-cycling", for the scheme, its reasons and its stability).

use crate::rigid::{LoadScheme, Marker, RigidBody, Vec3};

use super::contacts::Contacts;
use super::force::Pose;
use super::operator::Vec6;
use super::params::Damping;
use super::slots::ContactLoad;

/// One time step `Δt = 1` of `bodies` under external loads, with or without contacts: the one
/// body update that the coupled step, the dry bed and the contact verification share.
///
/// Each free body `b` first gets `external(b, body) = (F, T)` (force, torque about its centre,
/// world frame) in its load accumulators; then, with `contacts`, [`Contacts::advance`]
/// sub-cycles the step in `n_sub` sub-steps and the contact loads averaged over them are
/// returned; without, every body steps once ([`RigidBody::step`]) and `None` is returned.
/// Prescribed bodies follow their motion, fixed bodies stay.
///
/// # Panics
/// As [`Contacts::advance`].
pub fn step_bodies<'c, M: AsRef<[Marker]> + Sync>(
    contacts: Option<&'c mut Contacts>,
    bodies: &mut [RigidBody],
    markers: &[M],
    n_sub: usize,
    mut external: impl FnMut(usize, &RigidBody) -> (Vec3, Vec3),
) -> Option<&'c [ContactLoad]> {
    for (b, body) in bodies.iter_mut().enumerate() {
        if body.is_free() {
            let (f, t) = external(b, body);
            body.add_force(f);
            body.add_torque(t);
        }
    }
    match contacts {
        Some(c) => Some(c.advance(bodies, markers, n_sub)),
        None => {
            bodies.iter_mut().for_each(|b| b.step(1.0));
            None
        }
    }
}

impl Contacts {
    /// Advances every body over one fluid time step `Δt = 1` in `n_sub` sub-steps of
    /// `h = 1/n_sub`, with contacts recomputed in every sub-step, and returns the contact load
    /// on each body **averaged over the sub-steps** (what the caller reports; for a prescribed
    /// body such as an impeller this is the solids force and torque, never applied to it).
    ///
    /// **External loads.** On entry, each body's load accumulators
    /// ([`RigidBody::add_force`], [`RigidBody::add_torque`]) hold its external load at the
    /// fluid time level `n` (hydrodynamic force and torque, net weight): they are read and
    /// cleared. During sub-step `k` (from `t_n + k h` to `t_n + (k+1) h`) a free body feels
    /// `F_ext(t_n + (k + ½) h) + F_c,k`, where
    /// - `F_ext(t) = Fⁿ + (t − t_n)(Fⁿ − F^{n−1})` (Δt = 1) if the body's
    ///   [`RigidBody::load_scheme`] is [`LoadScheme::AdamsBashforth2`] and a previous external
    ///   load is known (from the previous call), else `Fⁿ`. The impulse over the fluid step is
    ///   `Fⁿ + ½(Fⁿ − F^{n−1})`, exactly the Adams–Bashforth half-step load that
    ///   [`RigidBody::step`] would use with `Δt = 1`: the hydrodynamic coupling keeps its
    ///   second-order extrapolation.
    /// - `F_c,k` is the contact load evaluated at the **mid-sub-step pose** predicted from the
    ///   state at `t_n + k h`: free bodies drifted by `h/2` with their current velocities
    ///   (`x + v h/2`, `exp(ω h/2) q`), prescribed bodies at their exact pose at
    ///   `t_n + (k + ½) h`; velocities for the lubrication: a free body's current ones, a
    ///   prescribed body's at the mid-sub-step time. With `RigidBody::step`'s update
    ///   `v' = v + h F/m`, `x' = x + h (v + v')/2` this is the position-Verlet
    ///   (drift–kick–drift) scheme for the elastic force (symplectic: no energy drift through
    ///   an elastic contact) and explicit Euler for the damping, limited to its stable range
    ///   when [`ContactParams::lubrication_limiter`](super::ContactParams) is on (module
    ///   [`super`], "Lubrication limiter").
    ///
    /// Each free body is stepped with [`LoadScheme::Constant`] semantics (its scheme is
    /// restored afterwards): the Adams–Bashforth extrapolation of the sub-step loads would
    /// halve the stability limit of the stiff lubrication damping (AB2 is stable for
    /// `c h/m < 1` on a pure damper, explicit Euler for `c h/m < 2`) and extrapolate the
    /// switching contact forces across sub-steps. The bodies' own load histories (filled with
    /// sub-step loads) are reset at the end; the external-load history used above is kept
    /// here ([`Contacts::reset_history`] forgets it, e.g. after a discontinuity of the loads).
    ///
    /// Prescribed bodies follow their motion through the sub-steps and fixed bodies stay; all
    /// bodies end at time `t + n_sub · h` (exactly `t + 1` when `n_sub` is a power of two). The
    /// caller must not step the bodies again for this fluid step.
    ///
    /// # Panics
    /// If `n_sub == 0` or the bodies/markers do not match [`Contacts::new`].
    pub fn advance<M: AsRef<[Marker]> + Sync>(
        &mut self,
        bodies: &mut [RigidBody],
        markers: &[M],
        n_sub: usize,
    ) -> &[ContactLoad] {
        self.advance_with(bodies, markers, n_sub, |_, _, _| {})
    }

    /// [`Contacts::advance`], calling `observer(k, bodies, contact_loads)` after sub-step `k`
    /// with the bodies at the end of the sub-step and the contact loads that the sub-step
    /// applied (verification: energy after every sub-step).
    pub fn advance_with<M, F>(
        &mut self,
        bodies: &mut [RigidBody],
        markers: &[M],
        n_sub: usize,
        mut observer: F,
    ) -> &[ContactLoad]
    where
        M: AsRef<[Marker]> + Sync,
        F: FnMut(usize, &[RigidBody], &[ContactLoad]),
    {
        assert!(n_sub >= 1, "the number of contact sub-steps must be at least 1");
        self.check(bodies, markers);
        let n = bodies.len();
        let h = 1.0 / n_sub as f64;
        self.external.clear();
        for b in bodies.iter_mut() {
            self.external.push(ContactLoad { force: b.force(), torque: b.torque() });
            b.clear_accumulators();
        }
        self.external_prev.resize(n, None);
        self.average.clear();
        self.average.resize(n, ContactLoad::ZERO);
        let m_lub = self.params().lubrication_substeps;
        let implicit = self.params().damping == Damping::Implicit;
        for k in 0..n_sub {
            self.poses.clear();
            self.poses.extend(bodies.iter().map(|b| Pose::predicted(b, 0.5 * h)));
            let limited = if self.params().lubrication_limiter { h } else { 0.0 };
            self.evaluate(bodies, markers, limited);
            if implicit {
                self.implicit_substep(bodies, k, h);
                observer(k, bodies, &self.loads);
                continue;
            }
            if m_lub > 1 {
                self.lubrication_substeps(bodies, k, h, m_lub);
                observer(k, bodies, &self.loads);
                continue;
            }
            self.step_under_loads(bodies, (k as f64 + 0.5) * h, h);
            observer(k, bodies, &self.loads);
        }
        let inv = 1.0 / n_sub as f64;
        for (i, b) in bodies.iter_mut().enumerate() {
            if b.is_free() {
                b.reset_load_history();
            }
            self.external_prev[i] = Some(self.external[i]);
            self.average[i].force *= inv;
            self.average[i].torque *= inv;
        }
        &self.average
    }

    /// Contact sub-step `k` (of length `h`) in `m` lubrication sub-steps (module [`super`],
    /// "Lubrication sub-steps"), after its evaluation: in each, every free body feels the
    /// external load at the lubrication sub-step's midpoint, the elastic load of the
    /// evaluation, and the lubrication of the evaluation's operators at the bodies' current
    /// velocities (a prescribed body's at the midpoint); each body steps by `h/m`. The
    /// average load of the contact sub-step (elastic plus mean lubrication) is added to
    /// `self.average` and left in `self.loads` for the observer.
    fn lubrication_substeps(&mut self, bodies: &mut [RigidBody], k: usize, h: f64, m: usize) {
        let hm = h / m as f64;
        let inv = 1.0 / m as f64;
        let n = bodies.len();
        // `self.loads` holds the elastic loads of the evaluation; the lubrication is summed
        // over the lubrication sub-steps into `sum`.
        let mut sum = std::mem::take(&mut self.lubrication_sum);
        sum.clear();
        sum.resize(n, ContactLoad::ZERO);
        for j in 0..m {
            self.lubrication_from_operators(bodies, 0.5 * hm);
            let s = k as f64 * h + (j as f64 + 0.5) * hm;
            for (i, b) in bodies.iter_mut().enumerate() {
                let (e, l) = (self.loads[i], self.lubrication[i]);
                sum[i].force += l.force;
                sum[i].torque += l.torque;
                if !b.is_free() {
                    b.step(hm);
                    continue;
                }
                let ext = self.external_at(i, b, s);
                b.add_force(ext.force + e.force + l.force);
                b.add_torque(ext.torque + e.torque + l.torque);
                step_constant(b, hm);
            }
        }
        for i in 0..n {
            let c = &mut self.loads[i];
            c.force += sum[i].force * inv;
            c.torque += sum[i].torque * inv;
            self.average[i].force += c.force;
            self.average[i].torque += c.torque;
        }
        self.lubrication_sum = sum;
    }

    /// Contact sub-step `k` (of length `h`) with implicit damping (module [`super`], "Implicit
    /// damping"), after its evaluation: every free body's known load is the external load at
    /// the sub-step's midpoint plus the evaluation's elastic load; the velocities at the
    /// sub-step's end solve backward Euler with the evaluation's damping operators (a
    /// prescribed body's velocity at the midpoint), and each free body steps by `h` under the
    /// known load plus the damping at those velocities, so that its new velocity is the
    /// solve's (up to the rotation's gyroscopic term, explicit). The sub-step's load (elastic
    /// plus damping) is added to `self.average` and left in `self.loads` for the observer.
    fn implicit_substep(&mut self, bodies: &mut [RigidBody], k: usize, h: f64) {
        let s = (k as f64 + 0.5) * h;
        let mut known = std::mem::take(&mut self.known);
        known.clear();
        for (i, b) in bodies.iter().enumerate() {
            let l = if b.is_free() {
                let ext = self.external_at(i, b, s);
                let e = self.loads[i];
                ContactLoad { force: ext.force + e.force, torque: ext.torque + e.torque }
            } else {
                ContactLoad::ZERO
            };
            known.push(Vec6::new(l.force.x, l.force.y, l.force.z, l.torque.x, l.torque.y, l.torque.z));
        }
        self.known = known;
        self.implicit_damping(bodies, h, 0.5 * h);
        for (c, l) in self.loads.iter_mut().zip(&self.lubrication) {
            c.force += l.force;
            c.torque += l.torque;
        }
        self.step_under_loads(bodies, s, h);
    }

    /// One contact sub-step of length `h` under the sub-step's contact loads `self.loads`
    /// (added to `self.average`): a free body steps under them plus its external load at `s`
    /// into the fluid step, held constant; a prescribed or fixed body follows its motion.
    fn step_under_loads(&mut self, bodies: &mut [RigidBody], s: f64, h: f64) {
        for (i, b) in bodies.iter_mut().enumerate() {
            let c = self.loads[i];
            self.average[i].force += c.force;
            self.average[i].torque += c.torque;
            if !b.is_free() {
                b.step(h);
                continue;
            }
            let ext = self.external_at(i, b, s);
            b.add_force(ext.force + c.force);
            b.add_torque(ext.torque + c.torque);
            step_constant(b, h);
        }
    }

    /// Body `i`'s external load at time `s` into the fluid step ([`Contacts::advance`]): its
    /// linear extrapolation from the last two fluid steps' under
    /// [`LoadScheme::AdamsBashforth2`] when the previous one is known, else the load held.
    #[inline]
    fn external_at(&self, i: usize, b: &RigidBody, s: f64) -> ContactLoad {
        let e = self.external[i];
        match (b.load_scheme, self.external_prev[i]) {
            (LoadScheme::AdamsBashforth2, Some(p)) => ContactLoad {
                force: e.force + (e.force - p.force) * s,
                torque: e.torque + (e.torque - p.torque) * s,
            },
            _ => e,
        }
    }

    /// The contact loads averaged over the sub-steps of the last [`Contacts::advance`].
    pub fn averaged_loads(&self) -> &[ContactLoad] {
        &self.average
    }

    /// Forgets the previous fluid step's external loads: the next [`Contacts::advance`] holds
    /// each external load constant over the step (after a discontinuity of the loads).
    pub fn reset_history(&mut self) {
        self.external_prev.iter_mut().for_each(|p| *p = None);
    }
}

/// Steps a free body by `dt` under the loads in its accumulators held constant (its load scheme
/// restored afterwards): the sub-steps' update ([`Contacts::advance`] says why not AB2).
#[inline]
fn step_constant(b: &mut RigidBody, dt: f64) {
    let scheme = b.load_scheme;
    b.load_scheme = LoadScheme::Constant;
    b.step(dt);
    b.load_scheme = scheme;
}
