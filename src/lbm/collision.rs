//! Collision operators with Guo forcing, on shifted populations.
//!
//! **Shifted populations.** The solver stores `h_i = f_i − w_i`, so that at rest `h_i = 0` and
//! `f32` keeps its significant digits for the deviations that carry the physics. Then
//! `ρ = 1 + δρ` with `δρ = Σ h_i`, and `j = Σ h_i c_i` (since `Σ w_i c_i = 0`).
//!
//! **Velocity** (Guo, half-force corrected): `u = (j + F/2)/ρ`.
//!
//! **Equilibrium** (second order), shifted:
//! `h_i^eq = w_i [δρ + ρ (3 c_i·u + 9/2 (c_i·u)² − 3/2 u²)]`.
//! For a pair `(i, ī)` with `c_ī = −c_i` it splits into an even part
//! `e = w (δρ + ρ(9/2 (c·u)² − 3/2 u²))` and an odd part `o = 3 w ρ c·u`.
//!
//! **Guo source** split into even and odd parts (Seta 2013 for TRT):
//! `S_i = (1 − ω⁺/2) w_i (9 (c_i·u)(c_i·F) − 3 u·F) + (1 − ω⁻/2) 3 w_i c_i·F`.
//! With `ω⁺ = ω⁻ = ω` this is Guo et al. (2002), Eq. 20.
//!
//! **BGK**: `h_i* = h_i − ω (h_i − h_i^eq) + S_i`.
//!
//! **TRT** (Ginzburg): with `h± = (h_i ± h_ī)/2`,
//! `h_i* = h_i − ω⁺ (h⁺ − e) − ω⁻ (h⁻ − o) + S_i`, where `ν = (1/ω⁺ − 1/2)/3` and the magic
//! parameter `Λ = (1/ω⁺ − 1/2)(1/ω⁻ − 1/2)` fixes `ω⁻`. With `Λ = 3/16` half-way bounce-back
//! places the wall exactly half-way for Poiseuille flow, independent of viscosity.
//!
//! Terms dropped: the O(u³) terms of the equilibrium (the usual weakly compressible scheme);
//! the error grows with Mach², which is why [`crate::lbm::Health`] reports the Mach number.

use super::real::Lane;
use super::Real;
use crate::lattice::{C, Q, W};

/// Relaxation rates and source prefactors, in the storage precision.
#[derive(Clone, Copy, Debug)]
pub struct Rates<T> {
    /// ω⁺, the rate of the even moments (sets the viscosity).
    pub omega_plus: T,
    /// ω⁻, the rate of the odd moments (equal to ω⁺ for BGK).
    pub omega_minus: T,
    /// 1 − ω⁺/2.
    pub src_plus: T,
    /// 1 − ω⁻/2.
    pub src_minus: T,
}

impl<T: Real> Rates<T> {
    /// Rates from `ω⁺` and `ω⁻` (given in `f64`, rounded once to `T`).
    pub fn new(omega_plus: f64, omega_minus: f64) -> Self {
        Self {
            omega_plus: T::from_f64(omega_plus),
            omega_minus: T::from_f64(omega_minus),
            src_plus: T::from_f64(1.0 - 0.5 * omega_plus),
            src_minus: T::from_f64(1.0 - 0.5 * omega_minus),
        }
    }
}

/// Density deviation and momentum `(δρ, j)` of shifted populations.
#[inline(always)]
pub fn moments<V: Lane>(h: &[V; Q]) -> (V, [V; 3]) {
    // Sums written out in a fixed order; the same order in every kernel.
    let drho = h[0]
        + h[1]
        + h[2]
        + h[3]
        + h[4]
        + h[5]
        + h[6]
        + h[7]
        + h[8]
        + h[9]
        + h[10]
        + h[11]
        + h[12]
        + h[13]
        + h[14]
        + h[15]
        + h[16]
        + h[17]
        + h[18];
    let jx = (h[1] - h[2]) + (h[7] - h[8]) + (h[9] - h[10]) + (h[11] - h[12]) + (h[13] - h[14]);
    let jy = (h[3] - h[4]) + (h[7] - h[8]) + (h[10] - h[9]) + (h[15] - h[16]) + (h[17] - h[18]);
    let jz = (h[5] - h[6]) + (h[11] - h[12]) + (h[14] - h[13]) + (h[15] - h[16]) + (h[18] - h[17]);
    (drho, [jx, jy, jz])
}

/// `c · a` for a lattice velocity `c = (X, Y, Z)` with components in {−1, 0, 1}, known at
/// compile time: only additions and subtractions, in x, y, z order.
#[inline(always)]
fn cdot<V: Lane, const X: i32, const Y: i32, const Z: i32>(a: &[V; 3]) -> V {
    let mut acc: Option<V> = None;
    for (c, v) in [(X, a[0]), (Y, a[1]), (Z, a[2])] {
        acc = match (c, acc) {
            (0, acc) => acc,
            (1, None) => Some(v),
            (_, None) => Some(-v),
            (1, Some(s)) => Some(s + v),
            (_, Some(s)) => Some(s - v),
        };
    }
    acc.unwrap_or_else(|| V::splat(V::S::ZERO))
}

/// Access to the 19 populations of one node (or one bundle of lane-nodes) during a collision.
pub trait Pops<V> {
    /// Population `i` (pre-collision until `set(i, …)` has been called).
    fn get(&self, i: usize) -> V;
    /// Stores the post-collision population `i`.
    fn set(&mut self, i: usize, v: V);
}

impl<V: Copy> Pops<V> for [V; Q] {
    #[inline(always)]
    fn get(&self, i: usize) -> V {
        self[i]
    }
    #[inline(always)]
    fn set(&mut self, i: usize, v: V) {
        self[i] = v;
    }
}

/// One collision of shifted populations `h` at one node (or at several, lane-wise) with total
/// force `force` (body force plus the node's force density). Updates `h` in place to the
/// post-collision values `h*`.
///
/// Reads: `h`, `force`, `rates`. Writes: `h`. Precondition: `ρ = 1 + Σh > 0`.
/// `TRT = false` gives BGK (and ignores `rates.omega_minus`).
///
/// **Evaluation.** The formulas in the module docs are regrouped so that each pair `(i, ī)`
/// costs about 17 (BGK) or 21 (TRT) operations. With `G = ω⁺ (δρ − 3/2 ρ u²) − 3 (1 − ω⁺/2) u·F`,
/// the even and odd parts of `ω e + S` are
/// `E = w G + (9/2 ω⁺ w ρ) (c·u)² + (9 (1 − ω⁺/2) w) (c·u)(c·F)` and
/// `O = (3 ω⁻ w ρ) (c·u) + (3 (1 − ω⁻/2) w) (c·F)`; then
/// BGK: `h_i* = (1 − ω) h_i + E + O`, `h_ī* = (1 − ω) h_ī + E − O`;
/// TRT: `h_i* = h_i − (ω⁺/2 s + ω⁻/2 d) + (E + O)`, `h_ī* = h_ī − (ω⁺/2 s − ω⁻/2 d) + (E − O)`
/// with `s = h_i + h_ī`, `d = h_i − h_ī`. Rest: `h_0* = (1 − ω⁺) h_0 + w_0 G`.
///
/// **Two passes.** The populations are read through [`Pops`]: pass 1 reads all of them for the
/// moments; pass 2 re-reads each pair `(i, ī)` and writes its two post-collision values right
/// away. In the AA-pattern kernel the two slots a pair writes are exactly the two it reads, so
/// nothing else needs to stay in registers across pairs (measured: 323 → fewer instructions
/// per 4 nodes, most of the difference being register spills).
#[inline(always)]
pub fn collide<V: Lane, P: Pops<V>, const TRT: bool>(h: &mut P, force: [V; 3], rates: &Rates<V::S>) {
    let c = |v: f64| V::splat(V::S::from_f64(v));
    let op = rates.omega_plus.to_f64();
    let om = if TRT { rates.omega_minus.to_f64() } else { op };
    let sp = rates.src_plus.to_f64();
    let sm = if TRT { rates.src_minus.to_f64() } else { sp };
    let (w1, w2) = (W[1], W[7]);

    // Pass 1. Pair sums and differences give the moments.
    // Plain loops, not `std::array::from_fn`: a generic helper from `core` that fails to
    // inline is compiled without the caller's target features and calls every intrinsic out
    // of line (measured: 3.5x slower `slurry run`).
    let zero = V::splat(V::S::ZERO);
    let (mut s, mut d) = ([zero; 9], [zero; 9]);
    for k in 0..9 {
        let (a, b) = (h.get(2 * k + 1), h.get(2 * k + 2));
        s[k] = a + b;
        d[k] = a - b;
    }
    let drho = h.get(0) + ((s[0] + s[1] + s[2]) + (s[3] + s[4]) + (s[5] + s[6]) + (s[7] + s[8]));
    // Pairs: 0:(1,0,0) 1:(0,1,0) 2:(0,0,1) 3:(1,1,0) 4:(1,−1,0) 5:(1,0,1) 6:(1,0,−1) 7:(0,1,1) 8:(0,1,−1)
    let jx = d[0] + (d[3] + d[4]) + (d[5] + d[6]);
    let jy = d[1] + (d[3] - d[4]) + (d[7] + d[8]);
    let jz = d[2] + (d[5] - d[6]) + (d[7] - d[8]);

    let one = c(1.0);
    let half = c(0.5);
    let rho = one + drho;
    let inv_rho = one / rho;
    let u = [
        half.fma(force[0], jx) * inv_rho,
        half.fma(force[1], jy) * inv_rho,
        half.fma(force[2], jz) * inv_rho,
    ];
    let usq = u[0].fma(u[0], u[1].fma(u[1], u[2] * u[2]));
    let uf = u[0].fma(force[0], u[1].fma(force[1], u[2] * force[2]));

    // Per-node coefficients (see the doc above); constants folded in f64, rounded once.
    let g = c(op).fms(c(-1.5).fma(rho * usq, drho), c(3.0 * sp) * uf);
    let (p1, p2) = (c(w1) * g, c(w2) * g);
    let (r1, r2) = (c(4.5 * op * w1) * rho, c(4.5 * op * w2) * rho);
    let (q1, q2) = (c(3.0 * om * w1) * rho, c(3.0 * om * w2) * rho);
    let (n1, n2) = (c(9.0 * sp * w1), c(9.0 * sp * w2));
    let (m1, m2) = (c(3.0 * sm * w1), c(3.0 * sm * w2));
    let keep = c(1.0 - op);
    let (hp, hm) = (c(0.5 * op), c(0.5 * om));

    // Pass 2.
    h.set(0, keep.fma(h.get(0), c(W[0]) * g));

    macro_rules! pair {
        ($k:literal, $x:literal, $y:literal, $z:literal, $p:ident, $r:ident, $q:ident, $n:ident, $m:ident) => {{
            let i = 2 * $k + 1;
            debug_assert_eq!(C[i], [$x, $y, $z]);
            let cu = cdot::<V, $x, $y, $z>(&u);
            let cf = cdot::<V, $x, $y, $z>(&force);
            let e = $r.fma(cu * cu, $n.fma(cu * cf, $p));
            let o = $q.fma(cu, $m * cf);
            let (a, b) = (h.get(i), h.get(i + 1));
            if TRT {
                let md = hm * (a - b);
                let sum = a + b;
                h.set(i, (a - hp.fma(sum, md)) + (e + o));
                h.set(i + 1, (b - hp.fms(sum, md)) + (e - o));
            } else {
                h.set(i, keep.fma(a, e + o));
                h.set(i + 1, keep.fma(b, e - o));
            }
        }};
    }
    pair!(0, 1, 0, 0, p1, r1, q1, n1, m1);
    pair!(1, 0, 1, 0, p1, r1, q1, n1, m1);
    pair!(2, 0, 0, 1, p1, r1, q1, n1, m1);
    pair!(3, 1, 1, 0, p2, r2, q2, n2, m2);
    pair!(4, 1, -1, 0, p2, r2, q2, n2, m2);
    pair!(5, 1, 0, 1, p2, r2, q2, n2, m2);
    pair!(6, 1, 0, -1, p2, r2, q2, n2, m2);
    pair!(7, 0, 1, 1, p2, r2, q2, n2, m2);
    pair!(8, 0, 1, -1, p2, r2, q2, n2, m2);
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Independent, textbook evaluation on unshifted populations in f64.
    fn textbook(f: &[f64; Q], force: [f64; 3], omega: f64) -> [f64; Q] {
        let rho: f64 = f.iter().sum();
        let mut j = [0.0; 3];
        for i in 0..Q {
            for d in 0..3 {
                j[d] += f[i] * C[i][d] as f64;
            }
        }
        let u: Vec<f64> = (0..3).map(|d| (j[d] + 0.5 * force[d]) / rho).collect();
        let usq: f64 = u.iter().map(|x| x * x).sum();
        let mut out = [0.0; Q];
        for i in 0..Q {
            let c: Vec<f64> = C[i].iter().map(|&x| x as f64).collect();
            let cu: f64 = (0..3).map(|d| c[d] * u[d]).sum();
            let feq = W[i] * rho * (1.0 + 3.0 * cu + 4.5 * cu * cu - 1.5 * usq);
            let s: f64 = (0..3).map(|d| (3.0 * (c[d] - u[d]) + 9.0 * cu * c[d]) * force[d]).sum::<f64>()
                * W[i]
                * (1.0 - 0.5 * omega);
            out[i] = f[i] - omega * (f[i] - feq) + s;
        }
        out
    }

    #[test]
    fn bgk_matches_textbook_guo() {
        let mut h = [0.0f64; Q];
        for (i, v) in h.iter_mut().enumerate() {
            *v = 1e-3 * ((i as f64 * 0.77).sin());
        }
        let force = [1e-4, -2e-4, 3e-5];
        let omega = 1.3;
        let f: [f64; Q] = std::array::from_fn(|i| h[i] + W[i]);
        let want = textbook(&f, force, omega);
        collide::<f64, _, false>(&mut h, force, &Rates::new(omega, omega));
        for i in 0..Q {
            // Same formula, regrouped: agreement to a few ulps of the O(1) populations.
            assert!((h[i] + W[i] - want[i]).abs() < 1e-15, "i={i}: {} vs {}", h[i] + W[i], want[i]);
        }
    }

    #[test]
    fn trt_with_equal_rates_is_bgk() {
        let mut a = [0.0f64; Q];
        for (i, v) in a.iter_mut().enumerate() {
            *v = 1e-3 * ((i as f64 * 1.3).cos());
        }
        let mut b = a;
        let force = [3e-5, 1e-5, -2e-5];
        let r = Rates::new(1.6, 1.6);
        collide::<f64, _, false>(&mut a, force, &r);
        collide::<f64, _, true>(&mut b, force, &r);
        for i in 0..Q {
            // Algebraically identical; the two groupings differ by round-off only.
            assert!((a[i] - b[i]).abs() < 1e-16, "i={i}: {} vs {}", a[i], b[i]);
        }
    }

    #[test]
    fn collision_conserves_mass_and_adds_the_force() {
        let mut h = [0.0f64; Q];
        for (i, v) in h.iter_mut().enumerate() {
            *v = 1e-2 * ((i as f64 * 2.1).sin());
        }
        let force = [1e-3, 2e-3, -1e-3];
        let (m0, j0) = moments(&h);
        collide::<f64, _, true>(&mut h, force, &Rates::new(1.2, 1.7));
        let (m1, j1) = moments(&h);
        assert!((m1 - m0).abs() < 1e-16, "{m1} vs {m0}");
        for d in 0..3 {
            assert!((j1[d] - j0[d] - force[d]).abs() < 1e-16, "d={d}: {}", j1[d] - j0[d] - force[d]);
        }
    }
}
