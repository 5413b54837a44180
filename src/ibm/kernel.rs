//! Regularised delta functions: the 1-D kernels `φ(r)` whose tensor product
//! `δ(x) = φ(x) φ(y) φ(z)` (lattice units, Δx = 1) is the weight of a node at offset `x` from a
//! marker.
//!
//! | kernel | half-width `h` | points per axis | nodes per marker | `Σφ = 1` | `Σ rφ = 0` | `Σφ²` const. | even = odd sums | smoothness |
//! |---|---|---|---|---|---|---|---|---|
//! | [`DeltaKernel::Linear`] | 1 | 2 | 8 | yes | yes | no | no | C⁰ |
//! | [`DeltaKernel::Roma3`] | 3/2 | 3 | 27 | yes | yes | yes (= 1/2) | no | C¹ |
//! | [`DeltaKernel::Peskin4`] | 2 | 4 | 64 | yes | yes | yes (= 3/8) | yes (= 1/2) | C¹ |
//!
//! The sums run over the integer nodes `j` at `r = X − j` for any marker position `X`; they hold
//! for every `X`, not only on average. `Σφ = 1` (partition of unity) makes a uniform field
//! interpolate exactly and spreading conserve the total force; `Σ rφ = 0` (first moment) makes
//! a linear field interpolate exactly and spreading conserve the moment of the force (torque)
//! to the same order. A constant `Σφ²` makes the self-interaction of a marker (spread, then
//! interpolate back at the same point) independent of where the marker sits relative to the
//! nodes, which removes the grid-locked oscillation of marker forces as bodies move.
//!
//! # The default: [`DeltaKernel::Roma3`]
//! It satisfies all three conditions with 27 nodes per marker instead of Peskin's 64: the marker
//! work (interpolation and spreading, several forcing iterations per step) costs about 27/64 of
//! Peskin's, the diffuse interface is 3 rather than 4 spacings thick (a smaller correction from
//! the input radius to the hydrodynamic radius), and a marker loses nodes to a wall only within
//! 1 spacing of its outermost node rather than 1.5. It is the kernel of the direct-forcing
//! methods the specification builds on for the interior-fluid momentum (Uhlmann 2005, Kempe &
//! Fröhlich 2012, Breugem 2012). The price: its second derivative jumps (at `|r| = ½` and 3/2),
//! the second moment `Σ r²φ` is not constant, and it lacks Peskin's even/odd condition (equal
//! weight on even and odd nodes, which suppresses odd–even decoupling on collocated grids), so a
//! marker's interpolated velocity varies somewhat more with its position inside a cell than
//! with the wider, smoother 4-point function. The paper (Derksen 2020,
//! citing ten Cate et al. 2002) does not fix the kernel (`physics.md` §3); [`DeltaKernel`] is
//! selectable so the choice can be compared.
//!
//! # References
//! - A. M. Roma, C. S. Peskin, M. J. Berger, "An adaptive version of the immersed boundary
//!   method", J. Comput. Phys. 153 (1999) 509–534, eq. (22) (the 3-point function).
//! - C. S. Peskin, "The immersed boundary method", Acta Numerica 11 (2002) 479–517, §6,
//!   eq. (6.27) (the standard 4-point function: `Σφ = 1`, even and odd sums each `½`,
//!   `Σ rφ = 0`, `Σφ² = 3/8`).
//! - M. Uhlmann, "An immersed boundary method with direct forcing for the simulation of
//!   particulate flows", J. Comput. Phys. 209 (2005) 448–476 (uses the 3-point function).

use serde::Deserialize;

/// Largest number of points per axis of any kernel (Peskin's 4).
pub const MAX_WIDTH: usize = 4;

/// A 1-D regularised delta function `φ(r)`; the 3-D weight is `φ(x) φ(y) φ(z)`.
///
/// In case files: `"linear"`, `"roma3"`, `"peskin4"`.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Hash, Deserialize, serde::Serialize)]
#[serde(rename_all = "snake_case")]
pub enum DeltaKernel {
    /// 2-point linear interpolation (the "hat"): `φ(r) = 1 − |r|` for `|r| ≤ 1`, else 0.
    /// Trilinear in 3-D. `Σφ = 1` and `Σ rφ = 0`, but `Σφ²` varies between ½ and 1 with the
    /// marker's position, and the kernel has a kink at every node.
    Linear,
    /// Roma, Peskin & Berger (1999) 3-point function (the default; see the module docs):
    /// `φ(r) = (1 + √(1 − 3r²))/3` for `|r| ≤ ½`,
    /// `φ(r) = (5 − 3|r| − √(1 − 3(1 − |r|)²))/6` for `½ ≤ |r| ≤ 3/2`, else 0.
    #[default]
    Roma3,
    /// Peskin's (2002) standard 4-point function:
    /// `φ(r) = (3 − 2|r| + √(1 + 4|r| − 4r²))/8` for `|r| ≤ 1`,
    /// `φ(r) = (5 − 2|r| − √(−7 + 12|r| − 4r²))/8` for `1 ≤ |r| ≤ 2`, else 0.
    Peskin4,
}

impl DeltaKernel {
    /// Every kernel, cheapest first.
    pub const ALL: [DeltaKernel; 3] = [DeltaKernel::Linear, DeltaKernel::Roma3, DeltaKernel::Peskin4];

    /// Half-width of the support: `φ(r) = 0` for `|r| ≥ support()`.
    pub fn support(self) -> f64 {
        match self {
            DeltaKernel::Linear => 1.0,
            DeltaKernel::Roma3 => 1.5,
            DeltaKernel::Peskin4 => 2.0,
        }
    }

    /// Number of nodes per axis that can carry a non-zero weight (`2 · support()`).
    pub fn width(self) -> usize {
        match self {
            DeltaKernel::Linear => 2,
            DeltaKernel::Roma3 => 3,
            DeltaKernel::Peskin4 => 4,
        }
    }

    /// Name as in case files (`linear`, `roma3`, `peskin4`).
    pub fn name(self) -> &'static str {
        match self {
            DeltaKernel::Linear => "linear",
            DeltaKernel::Roma3 => "roma3",
            DeltaKernel::Peskin4 => "peskin4",
        }
    }

    /// The 1-D kernel `φ(r)`, for a node at signed distance `r` (lattice units) from the marker.
    /// Even in `r`, non-negative, zero outside `|r| < support()`.
    #[inline]
    pub fn phi(self, r: f64) -> f64 {
        let a = r.abs();
        match self {
            DeltaKernel::Linear => {
                if a < 1.0 {
                    1.0 - a
                } else {
                    0.0
                }
            }
            DeltaKernel::Roma3 => {
                if a <= 0.5 {
                    (1.0 + (1.0 - 3.0 * a * a).sqrt()) / 3.0
                } else if a < 1.5 {
                    let b = 1.0 - a;
                    (5.0 - 3.0 * a - (1.0 - 3.0 * b * b).sqrt()) / 6.0
                } else {
                    0.0
                }
            }
            DeltaKernel::Peskin4 => {
                if a <= 1.0 {
                    (3.0 - 2.0 * a + (1.0 + 4.0 * a - 4.0 * a * a).sqrt()) / 8.0
                } else if a < 2.0 {
                    (5.0 - 2.0 * a - (-7.0 + 12.0 * a - 4.0 * a * a).sqrt()) / 8.0
                } else {
                    0.0
                }
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The 1-D sums over the `width()` nodes `j = lo, …, lo + width − 1` around `x`.
    fn sums(k: DeltaKernel, x: f64) -> (f64, f64, f64, f64, f64) {
        let lo = (x - k.support()).floor() as i64 + 1;
        let (mut s0, mut s1, mut s2, mut even, mut odd) = (0.0, 0.0, 0.0, 0.0, 0.0);
        for j in lo - 1..lo + k.width() as i64 + 1 {
            let r = x - j as f64;
            let p = k.phi(r);
            s0 += p;
            s1 += r * p;
            s2 += p * p;
            if j % 2 == 0 {
                even += p;
            } else {
                odd += p;
            }
        }
        (s0, s1, s2, even, odd)
    }

    #[test]
    fn moment_conditions_in_one_dimension() {
        for k in DeltaKernel::ALL {
            for i in 0..=1000 {
                let x = 10.0 + i as f64 / 1000.0;
                let (s0, s1, s2, even, odd) = sums(k, x);
                assert!((s0 - 1.0).abs() < 4e-16, "{k:?} x={x}: Σφ = {s0}");
                assert!(s1.abs() < 4e-15, "{k:?} x={x}: Σrφ = {s1}");
                match k {
                    DeltaKernel::Roma3 => assert!((s2 - 0.5).abs() < 1e-15, "Σφ² = {s2}"),
                    DeltaKernel::Peskin4 => {
                        assert!((s2 - 0.375).abs() < 1e-15, "Σφ² = {s2}");
                        assert!((even - 0.5).abs() < 1e-15 && (odd - 0.5).abs() < 1e-15);
                    }
                    DeltaKernel::Linear => assert!((0.5 - 1e-15..=1.0 + 1e-15).contains(&s2)),
                }
            }
        }
    }

    #[test]
    fn even_non_negative_compact() {
        for k in DeltaKernel::ALL {
            let h = k.support();
            assert_eq!(k.phi(h), 0.0);
            assert_eq!(k.phi(-h), 0.0);
            assert_eq!(k.phi(h + 0.3), 0.0);
            for i in 0..=400 {
                let r = h * i as f64 / 400.0;
                assert_eq!(k.phi(r), k.phi(-r));
                assert!(k.phi(r) >= 0.0);
            }
        }
    }

    #[test]
    fn serde_names() {
        #[derive(Deserialize)]
        struct W {
            k: DeltaKernel,
        }
        for k in DeltaKernel::ALL {
            let w: W = toml::from_str(&format!("k = \"{}\"", k.name())).unwrap();
            assert_eq!(w.k, k);
        }
        assert!(toml::from_str::<W>("k = \"cosine\"").is_err());
        assert_eq!(DeltaKernel::default(), DeltaKernel::Roma3);
    }
}
