//! The lubrication of an evaluation as a linear map of the bodies' velocities (module
//! [`super`], "Lubrication sub-steps"): per interacting body pair a [`PairOperator`], per body
//! against the walls a 6 × 6 block, each summed over the pair's marker pairs in the evaluation's
//! order, and [`lubrication_loads`], which applies them to the bodies' current velocities.
//!
//! Table 1's lubrication on marker `i` of body `a` from marker `j` of body `b` is linear in
//! `Δu = u_j − u_i`: `F = D Δu` with `D = g (kᵗ I + (kⁿ − kᵗ) n̂ n̂ᵀ)`,
//! `g = (1/δ* − 1/δ_d) w` (the pair's [`Hit`] carries `g kⁿ` and `g kᵗ`). With a body's
//! generalised velocity `V = (v, ω)` a marker's velocity is `u_i = J_i V`,
//! `J_i = [I, −[r_i]×]` (`r_i` its lever arm), and the load `(F, r_i × F)` is `J_iᵀ F`. So the
//! pair adds to body `a` the load `J_iᵀ D (J_j V_b − J_i V_a)` and to `b` the opposite force
//! at `j`, `−J_jᵀ D (J_j V_b − J_i V_a)`:
//!
//! ```text
//! load_a = K_ab V_b − K_aa V_a,    load_b = K_abᵀ V_a − K_bb V_b,
//! K_aa = Σ J_iᵀ D J_i,  K_ab = Σ J_iᵀ D J_j,  K_bb = Σ J_jᵀ D J_j
//! ```
//!
//! (a wall at rest: `load_a = −K_aa V_a`). At the velocities of the evaluation this is the
//! evaluation's own lubrication to round-off (tested); `K_aa` and `K_bb` are symmetric and
//! positive semi-definite, and the power of a pair's load,
//! `−(J_j V_b − J_i V_a)ᵀ D (J_j V_b − J_i V_a)`, is never positive, as the law's.

use nalgebra::{Matrix3, Matrix6, Vector6};

use crate::rigid::{Motion, RigidBody, Vec3};

use super::force::Hit;
use super::slots::{ContactLoad, Slot};

/// A 6 × 6 block acting on a generalised velocity `(v, ω)`.
pub(crate) type Mat6 = Matrix6<f64>;
/// A generalised velocity `(v, ω)` or load `(F, T)`.
pub(crate) type Vec6 = Vector6<f64>;

/// The zero blocks.
const ZERO6: Mat6 = Mat6::from_array_storage(nalgebra::ArrayStorage([[0.0; 6]; 6]));
const ZERO3: Matrix3<f64> = Matrix3::from_array_storage(nalgebra::ArrayStorage([[0.0; 3]; 3]));

/// The lubrication of one body pair `(a, b)` as a linear map of their velocities (module docs).
#[derive(Clone, Copy, Debug, PartialEq)]
pub(crate) struct PairOperator {
    pub aa: Mat6,
    pub ab: Mat6,
    pub bb: Mat6,
}

impl PairOperator {
    /// No lubrication.
    pub const ZERO: Self = Self { aa: ZERO6, ab: ZERO6, bb: ZERO6 };

    /// The loads `(F, T)` on `a` and on `b` at velocities `va`, `vb`.
    #[inline]
    pub fn loads(&self, va: &Vec6, vb: &Vec6) -> (Vec6, Vec6) {
        (self.ab * vb - self.aa * va, self.ab.tr_mul(va) - self.bb * vb)
    }
}

/// The sums over a body pair's lubricated marker pairs from which its [`PairOperator`] is
/// formed. With `D = cᵗ I + c' n̂ n̂ᵀ` (`c' = cⁿ − cᵗ`), `X = [r]×` and `ψ = (n̂, r × n̂)`:
///
/// ```text
/// J_iᵀ D J_j = cᵗ [[I, −X_j], [X_i, −X_i X_j]] + c' ψ_i ψ_jᵀ,   X_i X_j = r_j r_iᵀ − (r_i·r_j) I
/// ```
///
/// so the sums of `cᵗ`, `cᵗ r`, `cᵗ r rᵀ` and `c' ψ ψᵀ` give the three blocks (about 150
/// multiply-adds per marker pair instead of three 6 × 6 products).
#[derive(Clone, Copy, Debug)]
pub(crate) struct LubMoments {
    s0: f64,
    si: Vec3,
    sj: Vec3,
    sii: Matrix3<f64>,
    sij: Matrix3<f64>,
    sjj: Matrix3<f64>,
    pii: Mat6,
    pij: Mat6,
    pjj: Mat6,
}

impl LubMoments {
    /// No marker pair.
    pub const ZERO: Self = Self {
        s0: 0.0,
        si: Vec3::new(0.0, 0.0, 0.0),
        sj: Vec3::new(0.0, 0.0, 0.0),
        sii: ZERO3,
        sij: ZERO3,
        sjj: ZERO3,
        pii: ZERO6,
        pij: ZERO6,
        pjj: ZERO6,
    };

    /// Adds the lubrication of the marker pair `h` with lever arms `ri` (on `a`) and `rj` (on
    /// `b`); nothing if it has none.
    #[inline(always)]
    pub fn add(&mut self, h: &Hit, ri: &Vec3, rj: &Vec3) {
        if h.damping == 0.0 && h.damping_t == 0.0 {
            return;
        }
        let (ct, cp, n) = (h.damping_t, h.damping - h.damping_t, &h.normal);
        self.s0 += ct;
        self.si += ri * ct;
        self.sj += rj * ct;
        self.sii += (ri * ct) * ri.transpose();
        self.sij += (ri * ct) * rj.transpose();
        self.sjj += (rj * ct) * rj.transpose();
        let (ti, tj) = (ri.cross(n), rj.cross(n));
        let pi = Vec6::new(n.x, n.y, n.z, ti.x, ti.y, ti.z);
        let pj = Vec6::new(n.x, n.y, n.z, tj.x, tj.y, tj.z);
        let cpi = pi * cp;
        self.pii += cpi * pi.transpose();
        self.pij += cpi * pj.transpose();
        self.pjj += (pj * cp) * pj.transpose();
    }

    /// The pair's operator.
    pub fn operator(&self) -> PairOperator {
        PairOperator {
            aa: assemble(self.s0, &self.si, &self.si, &self.sii) + self.pii,
            ab: assemble(self.s0, &self.si, &self.sj, &self.sij) + self.pij,
            bb: assemble(self.s0, &self.sj, &self.sj, &self.sjj) + self.pjj,
        }
    }

    /// The block of a body against the walls (`ri = rj = r` for every contact: `K_aa`).
    pub fn wall_block(&self) -> Mat6 {
        assemble(self.s0, &self.si, &self.si, &self.sii) + self.pii
    }
}

/// `Σ cᵗ [[I, −X_j], [X_i, −X_i X_j]]` from `s0 = Σ cᵗ`, `si = Σ cᵗ r_i`, `sj = Σ cᵗ r_j` and
/// `sij = Σ cᵗ r_i r_jᵀ`: `[[s0 I, −[sj]×], [[si]×, tr(sij) I − sijᵀ]]`.
fn assemble(s0: f64, si: &Vec3, sj: &Vec3, sij: &Matrix3<f64>) -> Mat6 {
    let mut m = Mat6::zeros();
    m.fixed_view_mut::<3, 3>(0, 0).copy_from(&(Matrix3::identity() * s0));
    m.fixed_view_mut::<3, 3>(0, 3).copy_from(&(-sj.cross_matrix()));
    m.fixed_view_mut::<3, 3>(3, 0).copy_from(&si.cross_matrix());
    m.fixed_view_mut::<3, 3>(3, 3).copy_from(&(Matrix3::identity() * sij.trace() - sij.transpose()));
    m
}

/// A body's generalised velocity for the lubrication at `time + dt` of its clock: a free
/// body's current `(v, ω)` (explicit), a prescribed body's motion at that time, zero for a
/// fixed one (as [`super::force::Pose::predicted`] gives them).
pub(crate) fn velocity(b: &RigidBody, dt: f64) -> Vec6 {
    let (v, w) = match b.motion() {
        Motion::Free => (b.velocity, b.angular_velocity),
        Motion::Prescribed(m) => (m.velocity(b.time + dt), m.angular_velocity(b.time + dt)),
        Motion::Fixed => (Vec3::zeros(), Vec3::zeros()),
    };
    Vec6::new(v.x, v.y, v.z, w.x, w.y, w.z)
}

/// The lubrication loads of every body from the operators of the last evaluation at the
/// velocities `v` (one per body): the pairs in list order (`pairs[k]`, `ops[k]`, only those
/// whose slot has a contact: the others' operators are stale), then the walls in body order
/// (likewise); serial, so bitwise the same for any number of threads. Overwrites `out`.
pub(crate) fn lubrication_loads(
    pairs: &[(u32, u32)],
    ops: &[PairOperator],
    slots: &[Slot],
    walls: &[Mat6],
    wall_slots: &[Slot],
    v: &[Vec6],
    out: &mut [ContactLoad],
) {
    out.fill(ContactLoad::ZERO);
    let add = |load: &mut ContactLoad, l: &Vec6| {
        load.force += Vec3::new(l[0], l[1], l[2]);
        load.torque += Vec3::new(l[3], l[4], l[5]);
    };
    for ((&(a, b), op), _) in pairs.iter().zip(ops).zip(slots).filter(|(_, s)| s.count > 0) {
        let (a, b) = (a as usize, b as usize);
        let (la, lb) = op.loads(&v[a], &v[b]);
        add(&mut out[a], &la);
        add(&mut out[b], &lb);
    }
    for ((b, w), _) in walls.iter().enumerate().zip(wall_slots).filter(|(_, s)| s.count > 0) {
        add(&mut out[b], &(-(w * v[b])));
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn hit(cn: f64, ct: f64, n: Vec3) -> Hit {
        Hit {
            elastic: Vec3::zeros(),
            lub: Vec3::zeros(),
            normal: n.normalize(),
            delta: 0.3,
            w: 0.5,
            damping: cn,
            damping_t: ct,
            spring: 0.0,
        }
    }

    /// The operator gives the law's force `D Δu` on each marker and its torque, and the loads
    /// are dissipative and symmetric where they must be.
    #[test]
    fn operator_is_the_law_linearised_exactly() {
        let h = hit(7.0, 0.7, Vec3::new(0.3, -0.5, 0.8));
        let (ri, rj) = (Vec3::new(0.4, 1.1, -0.2), Vec3::new(-0.9, 0.1, 0.6));
        let mut acc = LubMoments::ZERO;
        acc.add(&h, &ri, &rj);
        let op = acc.operator();
        let va = Vec6::new(0.01, -0.02, 0.005, 0.003, 0.001, -0.002);
        let vb = Vec6::new(-0.004, 0.01, 0.02, -0.001, 0.004, 0.002);
        let (la, lb) = op.loads(&va, &vb);
        let ui = Vec3::new(va[0], va[1], va[2]) + Vec3::new(va[3], va[4], va[5]).cross(&ri);
        let uj = Vec3::new(vb[0], vb[1], vb[2]) + Vec3::new(vb[3], vb[4], vb[5]).cross(&rj);
        let du = uj - ui;
        let n = h.normal;
        let f = n * (n.dot(&du) * h.damping) + (du - n * n.dot(&du)) * h.damping_t;
        let (ta, tb) = (ri.cross(&f), rj.cross(&(-f)));
        for k in 0..3 {
            assert!((la[k] - f[k]).abs() < 1e-15 && (lb[k] + f[k]).abs() < 1e-15, "{la} {lb} {f}");
            assert!((la[3 + k] - ta[k]).abs() < 1e-15 && (lb[3 + k] - tb[k]).abs() < 1e-15);
        }
        // The power of the pair's loads is −Δuᵀ D Δu ≤ 0.
        let power = la.dot(&va) + lb.dot(&vb);
        assert!(power < 0.0 && (power + du.dot(&f)).abs() < 1e-16, "{power}");
        assert!((op.aa - op.aa.transpose()).abs().max() < 1e-15);
        assert!((op.bb - op.bb.transpose()).abs().max() < 1e-15);
        // A pair without lubrication adds nothing.
        let mut none = LubMoments::ZERO;
        none.add(&hit(0.0, 0.0, n), &ri, &rj);
        assert_eq!(none.operator(), PairOperator::ZERO);
        // Sums over several marker pairs are the sum of their operators.
        let h2 = hit(3.0, 0.3, Vec3::new(-0.2, 0.9, 0.1));
        let (r2i, r2j) = (Vec3::new(-0.3, 0.2, 1.0), Vec3::new(0.7, -0.8, 0.05));
        let mut two = acc;
        two.add(&h2, &r2i, &r2j);
        let mut second = LubMoments::ZERO;
        second.add(&h2, &r2i, &r2j);
        let (sum, op2) = (two.operator(), second.operator());
        for (x, y) in [(sum.aa, op.aa + op2.aa), (sum.ab, op.ab + op2.ab), (sum.bb, op.bb + op2.bb)] {
            assert!((x - y).abs().max() < 1e-14);
        }
    }

    /// Bodies in contact (the tests' scene: a free cylinder pinched between another free one and
    /// a moving prescribed one, over the floor), every surface inside the lubrication range: the loads
    /// of an evaluation with lubrication sub-steps (the elastic part) plus the lubrication of
    /// its operators at the same velocities equal the explicit law's loads to round-off.
    #[test]
    fn operators_give_the_evaluations_lubrication() {
        use crate::contact::{fixture::scene, ContactParams, Contacts};
        let (bodies, markers, walls) = scene();
        let explicit = ContactParams::default();
        let mut a = Contacts::new(explicit, walls, &bodies, &markers).unwrap();
        let law = a.compute(&bodies, &markers).to_vec();
        let split = ContactParams { lubrication_substeps: 4, ..explicit };
        let mut b = Contacts::new(split, walls, &bodies, &markers).unwrap();
        let elastic = b.compute(&bodies, &markers).to_vec();
        b.lubrication_from_operators(&bodies, 0.0);
        assert!(a.stats().touching_pairs >= 2 && a.stats().wall_contacts > 0, "{:?}", a.stats());
        let mut lub_scale = 0.0f64;
        for i in 0..bodies.len() {
            let (l, e, o) = (&law[i], &elastic[i], &b.lubrication[i]);
            lub_scale = lub_scale.max(o.force.norm());
            for (x, y) in [(l.force, e.force + o.force), (l.torque, e.torque + o.torque)] {
                assert!((x - y).norm() <= 1e-12 * (1.0 + x.norm()), "body {i}: {x:?} vs {y:?}");
            }
        }
        assert!(lub_scale > 1e-3, "the lubrication must act in this configuration: {lub_scale}");
    }

    #[test]
    fn wall_block_is_the_law_against_a_wall_at_rest() {
        let h = hit(5.0, 0.5, Vec3::new(0.0, 0.0, -1.0));
        let r = Vec3::new(0.5, -0.3, -1.2);
        let mut acc = LubMoments::ZERO;
        acc.add(&h, &r, &r);
        let w = acc.wall_block();
        let v = Vec6::new(0.01, 0.0, -0.03, 0.0, 0.02, 0.01);
        let l = -(w * v);
        let u = Vec3::new(v[0], v[1], v[2]) + Vec3::new(v[3], v[4], v[5]).cross(&r);
        let du = -u;
        let f = Vec3::new(du.x * 0.5, du.y * 0.5, du.z * 5.0);
        let t = r.cross(&f);
        for k in 0..3 {
            assert!((l[k] - f[k]).abs() < 1e-15 && (l[3 + k] - t[k]).abs() < 1e-15, "{l} {f} {t}");
        }
    }
}
