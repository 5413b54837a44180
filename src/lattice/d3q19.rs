//! The D3Q19 velocity set.
//!
//! Ordering: rest first, then nine pairs `(i, i+1)` of opposite velocities, so that
//! `OPP[i] = i + 1` for odd `i` and `OPP[i] = i - 1` for even `i > 0`. The pairing lets
//! collision operators work on `(i, ī)` pairs, and the AA-pattern kernel swap slots cheaply.
//!
//! Weights (exact fractions): rest 1/3, the six face neighbours 1/18, the twelve edge
//! neighbours 1/36; speed of sound c_s² = 1/3.

/// Number of discrete velocities.
pub const Q: usize = 19;

/// Lattice speed of sound squared, c_s² = 1/3.
pub const CS2: f64 = 1.0 / 3.0;

/// Discrete velocities c_i (lattice units).
pub const C: [[i32; 3]; Q] = [
    [0, 0, 0],
    [1, 0, 0],
    [-1, 0, 0],
    [0, 1, 0],
    [0, -1, 0],
    [0, 0, 1],
    [0, 0, -1],
    [1, 1, 0],
    [-1, -1, 0],
    [1, -1, 0],
    [-1, 1, 0],
    [1, 0, 1],
    [-1, 0, -1],
    [1, 0, -1],
    [-1, 0, 1],
    [0, 1, 1],
    [0, -1, -1],
    [0, 1, -1],
    [0, -1, 1],
];

/// Quadrature weights w_i.
pub const W: [f64; Q] = [
    1.0 / 3.0,
    1.0 / 18.0,
    1.0 / 18.0,
    1.0 / 18.0,
    1.0 / 18.0,
    1.0 / 18.0,
    1.0 / 18.0,
    1.0 / 36.0,
    1.0 / 36.0,
    1.0 / 36.0,
    1.0 / 36.0,
    1.0 / 36.0,
    1.0 / 36.0,
    1.0 / 36.0,
    1.0 / 36.0,
    1.0 / 36.0,
    1.0 / 36.0,
    1.0 / 36.0,
    1.0 / 36.0,
];

/// Index of the opposite velocity: `C[OPP[i]] = -C[i]`.
pub const OPP: [usize; Q] = [0, 2, 1, 4, 3, 6, 5, 8, 7, 10, 9, 12, 11, 14, 13, 16, 15, 18, 17];

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn moments_of_the_weights() {
        // Σw = 1, Σw c = 0, Σw c_a c_b = c_s² δ_ab: the isotropy the equilibrium relies on.
        let s: f64 = W.iter().sum();
        assert!((s - 1.0).abs() < 1e-15);
        for a in 0..3 {
            let m1: f64 = (0..Q).map(|i| W[i] * C[i][a] as f64).sum();
            assert!(m1.abs() < 1e-15);
            for b in 0..3 {
                let m2: f64 = (0..Q).map(|i| W[i] * (C[i][a] * C[i][b]) as f64).sum();
                let want = if a == b { CS2 } else { 0.0 };
                assert!((m2 - want).abs() < 1e-15, "a={a} b={b} m2={m2}");
            }
        }
    }

    #[test]
    fn opposites_pair_up() {
        for i in 0..Q {
            assert_eq!(OPP[OPP[i]], i);
            for a in 0..3 {
                assert_eq!(C[OPP[i]][a], -C[i][a]);
            }
            assert_eq!(W[OPP[i]], W[i]);
        }
    }
}
