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

/// `c_i · a` for a lattice velocity with components in {−1, 0, 1}, without multiplications.
#[inline(always)]
fn cdot<V: Lane>(i: usize, a: &[V; 3]) -> V {
    let c = C[i];
    let mut terms: [Option<V>; 3] = [None; 3];
    for d in 0..3 {
        terms[d] = match c[d] {
            1 => Some(a[d]),
            -1 => Some(-a[d]),
            _ => None,
        };
    }
    let mut acc: Option<V> = None;
    for t in terms.into_iter().flatten() {
        acc = Some(match acc {
            None => t,
            Some(s) => s + t,
        });
    }
    acc.unwrap_or_else(|| V::splat(V::S::ZERO))
}

/// One collision of shifted populations `h` at one node (or `L` nodes, lane-wise) with total
/// force `force` (body force plus the node's force density). Updates `h` in place to the
/// post-collision values `h*`.
///
/// Reads: `h`, `force`, `rates`. Writes: `h`. Preconditions: `ρ = 1 + Σh > 0`.
/// `TRT = false` gives BGK (and ignores `rates.omega_minus`).
#[inline(always)]
pub fn collide<V: Lane, const TRT: bool>(h: &mut [V; Q], force: [V; 3], rates: &Rates<V::S>) {
    let s = |v: f64| V::splat(V::S::from_f64(v));
    let one = s(1.0);
    let half = s(0.5);
    let three = s(3.0);
    let nine = s(9.0);
    let four_half = s(4.5);
    let one_half = s(1.5);

    let (drho, j) = moments(h);
    let rho = one + drho;
    let inv_rho = one / rho;
    let u = [
        (j[0] + half * force[0]) * inv_rho,
        (j[1] + half * force[1]) * inv_rho,
        (j[2] + half * force[2]) * inv_rho,
    ];
    let usq = u[0] * u[0] + u[1] * u[1] + u[2] * u[2];
    let uf = u[0] * force[0] + u[1] * force[1] + u[2] * force[2];
    // Terms shared by all directions.
    let base = drho - rho * (one_half * usq); // δρ − 3/2 ρ u²
    let rho3 = three * rho;
    let uf3 = three * uf;

    let om_p = V::splat(rates.omega_plus);
    let sp = V::splat(rates.src_plus);
    let (om_m, sm) = if TRT {
        (V::splat(rates.omega_minus), V::splat(rates.src_minus))
    } else {
        (om_p, sp)
    };

    // Rest population: only even parts.
    {
        let w = s(W[0]);
        let e = w * base;
        let src = sp * (w * (-uf3));
        h[0] = h[0] - om_p * (h[0] - e) + src;
    }
    // Nine pairs (i, i+1) with c_{i+1} = −c_i.
    let mut i = 1;
    while i < Q {
        let w = s(W[i]);
        let cu = cdot(i, &u);
        let cf = cdot(i, &force);
        let e = w * (base + rho * (four_half * (cu * cu)));
        let o = w * (rho3 * cu);
        let src_e = sp * (w * (nine * (cu * cf) - uf3));
        let src_o = sm * (w * (three * cf));
        let (a, b) = (h[i], h[i + 1]);
        if TRT {
            let hp = half * (a + b);
            let hm = half * (a - b);
            let de = om_p * (hp - e);
            let dodd = om_m * (hm - o);
            h[i] = a - de - dodd + src_e + src_o;
            h[i + 1] = b - de + dodd + src_e - src_o;
        } else {
            h[i] = a - om_p * (a - (e + o)) + (src_e + src_o);
            h[i + 1] = b - om_p * (b - (e - o)) + (src_e - src_o);
        }
        i += 2;
    }
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
            let s: f64 = (0..3)
                .map(|d| (3.0 * (c[d] - u[d]) + 9.0 * cu * c[d]) * force[d])
                .sum::<f64>()
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
        collide::<f64, false>(&mut h, force, &Rates::new(omega, omega));
        for i in 0..Q {
            assert!((h[i] + W[i] - want[i]).abs() < 1e-15, "i={i}");
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
        collide::<f64, false>(&mut a, force, &r);
        collide::<f64, true>(&mut b, force, &r);
        for i in 0..Q {
            assert!((a[i] - b[i]).abs() < 1e-16, "i={i}");
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
        collide::<f64, true>(&mut h, force, &Rates::new(1.2, 1.7));
        let (m1, j1) = moments(&h);
        assert!((m1 - m0).abs() < 1e-16);
        for d in 0..3 {
            assert!((j1[d] - j0[d] - force[d]).abs() < 1e-16, "d={d}");
        }
    }
}
