//! Backward Euler on Table 1's damping (module [`super`], "Implicit damping"): the lubrication
//! operators of an evaluation (module `operator`) assembled into one sparse symmetric
//! positive-definite system over the free bodies' generalised velocities `V = (v, ω)`,
//!
//! ```text
//! (M/h + C) V' = M V/h + F + K_kin,
//! ```
//!
//! `M = diag(m I, I_world)` per body, `C` the damping matrix (per pair: `C_aa += K_aa`,
//! `C_bb += K_bb`, `C_ab = −K_ab`, `C_ba = −K_abᵀ`; per body against the walls `C_aa += W_a`),
//! `F` the known loads (external and elastic), `K_kin` the kinematic terms of fixed and
//! prescribed partners (`K_ab V_b` on a free `a` with a kinematic `b`, `K_abᵀ V_a` on a free `b`
//! with a kinematic `a`). Only free bodies with at least one lubricated contact are unknowns:
//! the others have no damping, so their `V'` is the explicit update.
//!
//! `C` is symmetric (`K_aa`, `K_bb`, `W_a` are, and the off-diagonal blocks are each other's
//! transposes by construction) and positive semi-definite (`VᵀCV = Σ Δuᵀ D Δu ≥ 0` over the
//! marker pairs), `M/h` is positive definite: the system has a unique solution and a Cholesky
//! factor. It is solved ([`ImplicitSolver`]) by block-Jacobi preconditioned conjugate gradients
//! (the default: serial, every sum in a fixed order) or by faer's sparse Cholesky
//! factorisation (approximate minimum degree ordering), sequential: faer is built without its
//! `rayon` feature, so its only parallelism is `Par::Seq`. The assembly runs over the pairs in
//! list order, then the walls in body order, serially: the solution is bitwise the same for any
//! number of threads.

use faer::prelude::Solve;
use faer::sparse::{SparseColMat, Triplet};
use faer::{Mat, Side};

use crate::rigid::RigidBody;

use super::operator::{Mat6, PairOperator, Vec6};
use super::slots::Slot;

/// No unknown (a body that is not free or has no lubricated contact).
const NONE: u32 = u32::MAX;

/// The linear solver of the implicit damping ([`super::Contacts::set_implicit_solver`]).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum ImplicitSolver {
    /// faer's sparse Cholesky factorisation (approximate minimum degree ordering), sequential:
    /// exact to round-off, but its symbolic and numeric factorisations at every sub-step cost
    /// 70 ms per solve on the densest bed at half scale (1644 free bodies), 16 times the
    /// conjugate gradients.
    Cholesky,
    /// Conjugate gradients with a block-Jacobi preconditioner (each free body's 6 × 6 diagonal
    /// block), serial, to a relative residual of [`CG_TOLERANCE`] (the default: 16 iterations
    /// and 4.5 ms per solve on that bed; `M/h` keeps `M/h + C` well conditioned).
    #[default]
    ConjugateGradient,
}

/// The relative residual `|b − A x|/|b|` at which [`ImplicitSolver::ConjugateGradient`] stops.
pub const CG_TOLERANCE: f64 = 1e-12;

/// The buffers of the implicit damping solve (module docs), kept between sub-steps.
#[derive(Debug, Default)]
pub(crate) struct Implicit {
    /// Which linear solver.
    pub(crate) solver: ImplicitSolver,
    /// Iterations of the conjugate gradients, summed over the solves.
    pub(crate) iterations: u64,
    /// Per body: its block among the unknowns, or [`NONE`].
    index: Vec<u32>,
    /// Per unknown: its body.
    body: Vec<u32>,
    /// Per unknown: the diagonal block `M/h + C_aa` and the right-hand side.
    diag: Vec<Mat6>,
    rhs: Vec<Vec6>,
    /// The off-diagonal blocks `(row block, column block, C_rc)` in assembly order.
    off: Vec<(u32, u32, Mat6)>,
    triplets: Vec<Triplet<usize, usize, f64>>,
    /// Unknowns of the last solve (blocks of 6).
    pub(crate) unknowns: usize,
    /// Time spent in the assembly and the factorisation and solve, summed over the solves
    /// (benchmarks: [`super::Contacts::implicit_solve_time`]).
    pub(crate) seconds: [f64; 2],
}

/// Whether a pair's (or a wall's) slot has a contact whose operator is valid (module
/// `operator`: the others' operators are stale).
#[inline]
fn live(s: &Slot) -> bool {
    s.count > 0
}

impl Implicit {
    /// Total capacity of the buffers (elements).
    pub fn capacity(&self) -> usize {
        self.index.capacity()
            + self.body.capacity()
            + self.diag.capacity()
            + self.rhs.capacity()
            + self.off.capacity()
            + self.triplets.capacity()
    }

    /// Solves the backward-Euler damping step of length `h` (module docs) and overwrites `v`
    /// (one generalised velocity per body: a free body's current one, a prescribed body's at
    /// the time its damping is taken, zero for a fixed one) with `V'` for every free body with a
    /// lubricated contact; the others are left as they are. `known[b]`: the known load on free
    /// body `b` over the step (external plus elastic). `pairs`, `ops`, `slots`: the listed body
    /// pairs, their operators and slots; `walls`, `wall_slots`: per body.
    ///
    /// # Panics
    /// If the system is not positive definite (only with non-finite loads or velocities).
    #[allow(clippy::too_many_arguments)]
    pub fn solve(
        &mut self,
        bodies: &[RigidBody],
        h: f64,
        pairs: &[(u32, u32)],
        ops: &[PairOperator],
        slots: &[Slot],
        walls: &[Mat6],
        wall_slots: &[Slot],
        known: &[Vec6],
        v: &mut [Vec6],
    ) {
        let t0 = std::time::Instant::now();
        let n = bodies.len();
        self.index.clear();
        self.index.resize(n, NONE);
        self.body.clear();
        let mark = |b: usize, index: &mut Vec<u32>, body: &mut Vec<u32>| {
            if index[b] == NONE && bodies[b].is_free() {
                index[b] = body.len() as u32;
                body.push(b as u32);
            }
        };
        // Unknowns numbered in order of first appearance: pairs in list order, then walls.
        for (&(a, b), _) in pairs.iter().zip(slots).filter(|(_, s)| live(s)) {
            mark(a as usize, &mut self.index, &mut self.body);
            mark(b as usize, &mut self.index, &mut self.body);
        }
        for (b, _) in wall_slots.iter().enumerate().filter(|(_, s)| live(s)) {
            mark(b, &mut self.index, &mut self.body);
        }
        let m = self.body.len();
        self.unknowns = m;
        if m == 0 {
            self.seconds[0] += t0.elapsed().as_secs_f64();
            return;
        }
        self.diag.clear();
        self.rhs.clear();
        for &b in &self.body {
            let (body, b) = (&bodies[b as usize], b as usize);
            let mut mass = Mat6::zeros();
            mass.fixed_view_mut::<3, 3>(0, 0).fill_diagonal(body.mass());
            mass.fixed_view_mut::<3, 3>(3, 3).copy_from(&body.inertia_world());
            let mass = mass / h;
            self.rhs.push(mass * v[b] + known[b]);
            self.diag.push(mass);
        }
        self.off.clear();
        for ((&(a, b), op), _) in pairs.iter().zip(ops).zip(slots).filter(|(_, s)| live(s)) {
            let (a, b) = (a as usize, b as usize);
            match (self.index[a], self.index[b]) {
                (NONE, NONE) => {}
                (ia, NONE) => {
                    self.diag[ia as usize] += op.aa;
                    self.rhs[ia as usize] += op.ab * v[b];
                }
                (NONE, ib) => {
                    self.diag[ib as usize] += op.bb;
                    self.rhs[ib as usize] += op.ab.tr_mul(&v[a]);
                }
                (ia, ib) => {
                    self.diag[ia as usize] += op.aa;
                    self.diag[ib as usize] += op.bb;
                    self.off.push((ia, ib, -op.ab));
                }
            }
        }
        for ((b, w), _) in walls.iter().enumerate().zip(wall_slots).filter(|(_, s)| live(s)) {
            if self.index[b] != NONE {
                self.diag[self.index[b] as usize] += w;
            }
        }
        // The lower triangle, in a fixed order.
        self.triplets.clear();
        for (i, d) in self.diag.iter().enumerate() {
            for c in 0..6 {
                for r in c..6 {
                    self.triplets.push(Triplet::new(6 * i + r, 6 * i + c, d[(r, c)]));
                }
            }
        }
        for &(i, j, ref blk) in &self.off {
            let (i, j) = (i as usize, j as usize);
            for c in 0..6 {
                for r in 0..6 {
                    // C_ij[r, c] at (6i + r, 6j + c); its transpose C_ji[c, r] at (6j + c, 6i + r).
                    if i > j {
                        self.triplets.push(Triplet::new(6 * i + r, 6 * j + c, blk[(r, c)]));
                    } else {
                        self.triplets.push(Triplet::new(6 * j + c, 6 * i + r, blk[(r, c)]));
                    }
                }
            }
        }
        let t1 = std::time::Instant::now();
        self.seconds[0] += (t1 - t0).as_secs_f64();
        if self.solver == ImplicitSolver::ConjugateGradient {
            let x = self.conjugate_gradient();
            for (i, &b) in self.body.iter().enumerate() {
                v[b as usize] = x[i];
            }
            self.seconds[1] += t1.elapsed().as_secs_f64();
            return;
        }
        let a = SparseColMat::<usize, f64>::try_new_from_triplets(6 * m, 6 * m, &self.triplets)
            .expect("the damping matrix's triplets are in range and distinct");
        let llt = a.sp_cholesky(Side::Lower).unwrap_or_else(|e| {
            panic!(
                "implicit damping: M/h + C is not positive definite ({e:?}); non-finite loads or velocities?"
            )
        });
        let mut x = Mat::<f64>::from_fn(6 * m, 1, |r, _| self.rhs[r / 6][r % 6]);
        llt.solve_in_place(x.as_mut());
        for (i, &b) in self.body.iter().enumerate() {
            v[b as usize] = Vec6::from_fn(|r, _| x[(6 * i + r, 0)]);
        }
        self.seconds[1] += t1.elapsed().as_secs_f64();
    }

    /// `A x` with `A = M/h + C` as assembled (diagonal blocks, then the off-diagonal blocks in
    /// assembly order: a fixed order).
    fn apply(&self, x: &[Vec6], y: &mut [Vec6]) {
        for ((y, d), x) in y.iter_mut().zip(&self.diag).zip(x) {
            *y = d * x;
        }
        for &(i, j, ref blk) in &self.off {
            let (i, j) = (i as usize, j as usize);
            y[i] += blk * x[j];
            y[j] += blk.tr_mul(&x[i]);
        }
    }

    /// Block-Jacobi preconditioned conjugate gradients from `x = 0` to a relative residual of
    /// [`CG_TOLERANCE`], serial (every sum in a fixed order).
    fn conjugate_gradient(&mut self) -> Vec<Vec6> {
        let m = self.diag.len();
        let inv: Vec<Mat6> = self
            .diag
            .iter()
            .map(|d| {
                let sym = (d + d.transpose()) * 0.5;
                sym.cholesky().expect("M/h + C_aa is positive definite").inverse()
            })
            .collect();
        let dot = |a: &[Vec6], b: &[Vec6]| a.iter().zip(b).map(|(x, y)| x.dot(y)).sum::<f64>();
        let mut x = vec![Vec6::zeros(); m];
        let mut r = self.rhs.clone();
        let mut z: Vec<Vec6> = inv.iter().zip(&r).map(|(p, r)| p * r).collect();
        let mut p = z.clone();
        let mut ap = vec![Vec6::zeros(); m];
        let mut rz = dot(&r, &z);
        let stop = CG_TOLERANCE * CG_TOLERANCE * dot(&self.rhs, &self.rhs);
        for _ in 0..(6 * m).max(1) {
            if dot(&r, &r) <= stop {
                break;
            }
            self.iterations += 1;
            self.apply(&p, &mut ap);
            let alpha = rz / dot(&p, &ap);
            for k in 0..m {
                x[k] += p[k] * alpha;
                r[k] -= ap[k] * alpha;
            }
            for k in 0..m {
                z[k] = inv[k] * r[k];
            }
            let rz1 = dot(&r, &z);
            let beta = rz1 / rz;
            rz = rz1;
            for k in 0..m {
                p[k] = z[k] + p[k] * beta;
            }
        }
        x
    }

    /// The damping matrix `C` of the last [`Implicit::solve`] as a dense matrix over its
    /// unknowns (without `M/h`; tests).
    #[cfg(test)]
    pub fn damping_matrix(&self, bodies: &[RigidBody], h: f64) -> nalgebra::DMatrix<f64> {
        let m = self.unknowns;
        let mut c = nalgebra::DMatrix::zeros(6 * m, 6 * m);
        for (i, d) in self.diag.iter().enumerate() {
            let body = &bodies[self.body[i] as usize];
            let mut mass = Mat6::zeros();
            mass.fixed_view_mut::<3, 3>(0, 0).fill_diagonal(body.mass());
            mass.fixed_view_mut::<3, 3>(3, 3).copy_from(&body.inertia_world());
            c.view_mut((6 * i, 6 * i), (6, 6)).copy_from(&(d - mass / h));
        }
        for &(i, j, ref blk) in &self.off {
            let (i, j) = (i as usize, j as usize);
            c.view_mut((6 * i, 6 * j), (6, 6)).copy_from(blk);
            c.view_mut((6 * j, 6 * i), (6, 6)).copy_from(&blk.transpose());
        }
        c
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::contact::fixture::scene;
    use crate::contact::{ContactParams, Contacts, Damping, Walls};
    use crate::rigid::Vec3;

    fn implicit() -> ContactParams {
        ContactParams { damping: Damping::Implicit, ..Default::default() }
    }

    /// The assembled damping matrix is symmetric positive semi-definite, and the solve is
    /// backward Euler: `M (V' − V)/h = F_known + L(V')` for every free body, with `L` the
    /// operators' damping loads (module `operator`) at the solved velocities and the
    /// prescribed body's.
    #[test]
    fn damping_matrix_is_symmetric_psd_and_the_solve_is_backward_euler() {
        let (bodies, markers, walls) = scene();
        let mut ct = Contacts::new(implicit(), walls, &bodies, &markers).unwrap();
        ct.compute(&bodies, &markers);
        assert!(ct.stats().touching_pairs >= 3 && ct.stats().wall_contacts > 0, "{:?}", ct.stats());
        let h = 0.5;
        ct.known = (0..bodies.len())
            .map(|i| Vec6::from_fn(|r, _| 0.01 * ((i * 6 + r) as f64 * 0.7).sin()))
            .collect();
        let unknowns = ct.implicit_damping(&bodies, h, 0.0);
        assert_eq!(unknowns, 3, "the three free bodies");
        let c = ct.damping_matrix(&bodies, h);
        let scale = c.abs().max();
        assert!(scale > 10.0, "the damping acts: {scale}");
        // Symmetric: the off-diagonal blocks are transposes by construction; the diagonal
        // blocks are sums of symmetric products, symmetric to round-off.
        assert!((&c - c.transpose()).abs().max() <= 1e-13 * scale, "not symmetric");
        let sym = (&c + c.transpose()) * 0.5;
        let eig = sym.symmetric_eigenvalues();
        let (lo, hi) = (eig.min(), eig.max());
        assert!(lo >= -1e-12 * scale && hi > 0.0, "not positive semi-definite: {lo} … {hi}");
        let v1 = ct.solved_velocities().to_vec();
        for (i, b) in bodies.iter().enumerate().filter(|(_, b)| b.is_free()) {
            let mut mass = Mat6::zeros();
            mass.fixed_view_mut::<3, 3>(0, 0).fill_diagonal(b.mass());
            mass.fixed_view_mut::<3, 3>(3, 3).copy_from(&b.inertia_world());
            let v0 = Vec6::new(
                b.velocity.x,
                b.velocity.y,
                b.velocity.z,
                b.angular_velocity.x,
                b.angular_velocity.y,
                b.angular_velocity.z,
            );
            let l = &ct.lubrication[i];
            let lub = Vec6::new(l.force.x, l.force.y, l.force.z, l.torque.x, l.torque.y, l.torque.z);
            let lhs = mass * (v1[i] - v0) / h;
            let rhs = ct.known[i] + lub;
            let tol = 1e-10 * (lhs.norm() + lub.norm() + ct.known[i].norm());
            assert!((lhs - rhs).norm() <= tol, "body {i}: {lhs} vs {rhs}");
            assert!(lub.norm() > 1e-4, "body {i} is damped: {lub}");
        }
    }

    /// The block-Jacobi conjugate gradients give the Cholesky solution to their tolerance.
    #[test]
    fn conjugate_gradient_agrees_with_cholesky() {
        let (bodies, markers, walls) = scene();
        let solve = |solver: ImplicitSolver| {
            let mut ct = Contacts::new(implicit(), walls, &bodies, &markers).unwrap();
            ct.set_implicit_solver(solver);
            ct.compute(&bodies, &markers);
            ct.known =
                (0..bodies.len()).map(|i| Vec6::from_fn(|r, _| 0.01 * ((i * 6 + r) as f64).cos())).collect();
            ct.implicit_damping(&bodies, 0.5, 0.0);
            (ct.solved_velocities().to_vec(), ct.implicit_cg_iterations())
        };
        let (chol, none) = solve(ImplicitSolver::Cholesky);
        let (cg, iterations) = solve(ImplicitSolver::ConjugateGradient);
        assert_eq!(none, 0);
        assert!(iterations > 1 && iterations <= 18, "{iterations} iterations for 18 unknowns");
        let scale = chol.iter().map(|v| v.norm()).fold(0.0, f64::max);
        for (a, b) in chol.iter().zip(&cg) {
            // The residual tolerance 1e-12 times the condition number of M/h + C (≈ 1e2 here).
            assert!((a - b).norm() <= 1e-9 * scale, "{a} vs {b}");
        }
    }

    /// Fluid steps of the scene under the implicit scheme are bitwise the same with 1 and 2
    /// threads; two free cylinders alone (no wall, no kinematic body) keep their total momentum
    /// to round-off.
    #[test]
    fn implicit_advance_is_deterministic_and_conserves_momentum() {
        let (bodies, markers, walls) = scene();
        let run = |threads: usize| {
            let pool = rayon::ThreadPoolBuilder::new().num_threads(threads).build().unwrap();
            pool.install(|| {
                let mut bs = bodies.clone();
                let mut ct = Contacts::new(implicit(), walls, &bs, &markers).unwrap();
                for _ in 0..3 {
                    ct.advance(&mut bs, &markers, 2);
                }
                bs.iter()
                    .map(|b| (b.position, b.velocity, b.angular_velocity, b.orientation))
                    .collect::<Vec<_>>()
            })
        };
        assert_eq!(run(1), run(2), "bitwise the same for 1 and 2 threads");
        let mut two = vec![bodies[0].clone(), bodies[1].clone()];
        let m2 = vec![markers[0].clone(), markers[1].clone()];
        let p0: Vec3 = two.iter().map(|b| b.linear_momentum()).sum();
        let mut ct = Contacts::new(implicit(), Walls::none(), &two, &m2).unwrap();
        let (mut worst, mut touching) = (0.0f64, 0usize);
        for _ in 0..20 {
            ct.advance(&mut two, &m2, 1);
            touching = touching.max(ct.stats().touching_pairs);
            let p: Vec3 = two.iter().map(|b| b.linear_momentum()).sum();
            worst = worst.max((p - p0).norm() / p0.norm());
        }
        assert!(touching > 0, "the two bodies interact");
        assert!(worst <= 1e-13, "momentum changed by {worst:e}");
    }
}
