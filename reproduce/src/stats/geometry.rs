//! How much of a particle lies below a horizontal plane: the exact volume of a tilted
//! cylinder (and of a sphere) below height `z`, from which the solids volume in a slab is a
//! difference of two values.
//!
//! # The tilted cylinder
//! A cylinder of radius `r` and length `ℓ` whose axis `a` makes the angle `φ` with the
//! vertical (`c = |cos φ| = |a_z|`, `s = sin φ = √(a_x² + a_y²)`) is the set of points
//! `t a + ρ` with `|t| ≤ ℓ/2` and `ρ ⊥ a`, `|ρ| ≤ r`. With `x` the coordinate of `ρ` along the
//! steepest upward direction of the cross-section disc, a point sits at the height
//! `t c + x s` above the centre (the sign of `a_z` does not matter: `t → −t`). Slicing the
//! disc into chords of length `w(x) = 2√(r² − x²)` normal to `x`,
//!
//! ```text
//! V(z) = ∫_{−r}^{r} w(x) L(x) dx,   L(x) = clamp((z − x s)/c + ℓ/2, 0, ℓ)
//! ```
//!
//! where `L(x)` is the axial length of the chord's strip that lies below `z`. `L = ℓ` for
//! `x ≤ x_lo = (z − cℓ/2)/s` and `L = 0` for `x ≥ x_hi = (z + cℓ/2)/s`, linear between.
//! With `a = clamp(x_lo, −r, r)`, `b = clamp(x_hi, −r, r)` and the substitution
//! `x = r sin θ` (`w dx = 2r² cos²θ dθ`, which removes the square-root end singularities):
//!
//! ```text
//! V(z) = ℓ r² (θ_a + π/2 + sin θ_a cos θ_a)  +  ∫_{θ_a}^{θ_b} L(r sin θ) 2r² cos²θ dθ.
//! ```
//!
//! The first term is exact; the integrand of the second is an entire function (a
//! trigonometric polynomial of degree 3) on an interval of length at most π, integrated with
//! 16-point Gauss–Legendre, whose error bound there is below 1e-25 relative: the result is
//! exact to round-off. Evaluating `L` itself (bounded by `ℓ`) rather than a closed form of
//! the second term avoids the cancellation that the closed form suffers as `c → 0`
//! (`x_hi − x_lo = cℓ/s → 0` with a factor `1/c` in front). The special cases `s = 0`
//! (vertical: `V = π r² clamp(z + ℓ/2, 0, ℓ)`) and `c = 0` (horizontal: the middle term
//! vanishes, `V = ℓ · segment area`) come out of the same formulas.

use std::f64::consts::{FRAC_PI_2, PI};
use std::sync::OnceLock;

/// Points of the Gauss–Legendre rule used for the middle term.
const GL_POINTS: usize = 16;

/// Nodes and weights of the `n`-point Gauss–Legendre rule on `[−1, 1]` (Newton's iteration on
/// the Legendre polynomial from the Tricomi initial guesses), nodes in decreasing order.
pub(crate) fn gauss_legendre(n: usize) -> Vec<(f64, f64)> {
    (0..n)
        .map(|i| {
            let mut x = (PI * (i as f64 + 0.75) / (n as f64 + 0.5)).cos();
            let mut dp = 1.0;
            for _ in 0..100 {
                // P_n(x) and P_{n−1}(x) by the three-term recurrence.
                let (mut p0, mut p1) = (1.0, x);
                for k in 2..=n {
                    let p2 = ((2 * k - 1) as f64 * x * p1 - (k - 1) as f64 * p0) / k as f64;
                    (p0, p1) = (p1, p2);
                }
                dp = n as f64 * (x * p1 - p0) / (x * x - 1.0);
                let dx = p1 / dp;
                x -= dx;
                if dx.abs() <= 1e-16 {
                    break;
                }
            }
            (x, 2.0 / ((1.0 - x * x) * dp * dp))
        })
        .collect()
}

fn rule() -> &'static [(f64, f64)] {
    static RULE: OnceLock<Vec<(f64, f64)>> = OnceLock::new();
    RULE.get_or_init(|| gauss_legendre(GL_POINTS))
}

/// Volume of a cylinder of diameter `diameter` and length `length`, with its axis along
/// `axis` (any non-zero vector; normalised here), that lies below the height `z` measured
/// from the cylinder's centre: `V(z)` of the module docs, exact to round-off. `0` for
/// `z ≤ −e`, the whole `π d² ℓ/4` for `z ≥ e`, `e = c ℓ/2 + s d/2` the half vertical extent.
pub fn cylinder_volume_below(diameter: f64, length: f64, axis: [f64; 3], z: f64) -> f64 {
    let r = 0.5 * diameter;
    let norm = (axis[0] * axis[0] + axis[1] * axis[1] + axis[2] * axis[2]).sqrt();
    let c = (axis[2] / norm).abs().min(1.0);
    let s = (axis[0].hypot(axis[1]) / norm).min(1.0);
    let full = PI * r * r * length;
    let half_l = 0.5 * length;
    let extent = c * half_l + s * r;
    if z >= extent {
        return full;
    }
    if z <= -extent {
        return 0.0;
    }
    if s == 0.0 {
        return PI * r * r * (z / c + half_l).clamp(0.0, length);
    }
    let a = ((z - c * half_l) / s).clamp(-r, r);
    let b = ((z + c * half_l) / s).clamp(-r, r);
    let ta = (a / r).clamp(-1.0, 1.0).asin();
    let mut v = length * r * r * (ta + FRAC_PI_2 + ta.sin() * ta.cos());
    if b > a {
        // Here c > 0: with c = 0 the two break points coincide.
        let tb = (b / r).clamp(-1.0, 1.0).asin();
        let (mid, half) = (0.5 * (ta + tb), 0.5 * (tb - ta));
        let mut sum = 0.0;
        for &(x, w) in rule() {
            let (sin, cos) = (mid + half * x).sin_cos();
            let l = ((z - r * sin * s) / c + half_l).clamp(0.0, length);
            sum += w * l * cos * cos;
        }
        v += 2.0 * r * r * half * sum;
    }
    v.clamp(0.0, full)
}

/// Volume of a sphere of diameter `diameter` below the height `z` measured from its centre:
/// the cap `π (R + z)² (2R − z)/3` for `|z| < R`.
pub fn sphere_volume_below(diameter: f64, z: f64) -> f64 {
    let r = 0.5 * diameter;
    if z >= r {
        4.0 / 3.0 * PI * r * r * r
    } else if z <= -r {
        0.0
    } else {
        PI * (r + z) * (r + z) * (2.0 * r - z) / 3.0
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use slurry::util::SplitMix64;

    /// Area of the disc of radius `r` left of the chord at `x`.
    fn segment(r: f64, x: f64) -> f64 {
        let x = x.clamp(-r, r);
        x * (r * r - x * x).sqrt() + r * r * (x / r).asin() + 0.5 * PI * r * r
    }

    #[test]
    fn gauss_legendre_integrates_polynomials_of_degree_2n_minus_1() {
        let rule = gauss_legendre(GL_POINTS);
        let wsum: f64 = rule.iter().map(|p| p.1).sum();
        assert!((wsum - 2.0).abs() < 1e-14, "weights sum {wsum}");
        for k in 0..GL_POINTS {
            // ∫ x^{2k} = 2/(2k+1); odd powers vanish.
            let even: f64 = rule.iter().map(|&(x, w)| w * x.powi(2 * k as i32)).sum();
            let odd: f64 = rule.iter().map(|&(x, w)| w * x.powi(2 * k as i32 + 1)).sum();
            assert!((even - 2.0 / (2 * k + 1) as f64).abs() < 1e-14, "x^{}: {even}", 2 * k);
            assert!(odd.abs() < 1e-14, "x^{}: {odd}", 2 * k + 1);
        }
    }

    #[test]
    fn volume_below_is_zero_full_and_half_at_the_centre() {
        let (d, l) = (6.0, 13.0);
        let full = PI * 9.0 * l;
        let mut rng = SplitMix64(11);
        for _ in 0..200 {
            let axis = rng.vec3(-1.0, 1.0);
            assert_eq!(cylinder_volume_below(d, l, axis, 1e3), full);
            assert_eq!(cylinder_volume_below(d, l, axis, -1e3), 0.0);
            // Point symmetry about the centre: V(z) + V(−z) = V, so V(0) = V/2.
            let half = cylinder_volume_below(d, l, axis, 0.0);
            assert!((half / full - 0.5).abs() < 1e-14, "{axis:?}: V(0)/V = {}", half / full);
            let z = rng.uniform(-8.0, 8.0);
            let sum = cylinder_volume_below(d, l, axis, z) + cylinder_volume_below(d, l, axis, -z);
            assert!((sum / full - 1.0).abs() < 1e-14, "{axis:?}, z = {z}: {}", sum / full);
        }
    }

    #[test]
    fn vertical_and_horizontal_limits_are_continuous() {
        let (d, l) = (4.0, 10.0);
        let r = 0.5 * d;
        for z in [-4.9, -3.0, -0.3, 0.0, 1.7, 4.99] {
            let vertical = PI * r * r * (z + 0.5 * l);
            for axis in [[0.0, 0.0, 1.0], [0.0, 0.0, -1.0], [1e-9, 0.0, 1.0], [0.0, 1e-15, -1.0]] {
                let v = cylinder_volume_below(d, l, axis, z);
                assert!((v - vertical).abs() <= 1e-12 * vertical + 1e-8, "{axis:?} z={z}: {v} vs {vertical}");
            }
        }
        for z in [-1.999, -1.2, 0.0, 0.4, 1.99] {
            let horizontal = l * segment(r, z);
            for axis in
                [[1.0, 0.0, 0.0], [0.6, -0.8, 0.0], [1.0, 0.0, 1e-9], [0.0, 1.0, -1e-13], [1.0, 1.0, 1e-300]]
            {
                let v = cylinder_volume_below(d, l, axis, z);
                assert!(
                    (v - horizontal).abs() <= 1e-12 * horizontal + 1e-7,
                    "{axis:?} z={z}: {v} vs {horizontal}"
                );
            }
        }
    }

    #[test]
    fn volume_below_matches_the_other_order_of_integration() {
        // Independent formula: slices normal to the axis, V(z) = ∫ S((z − t c)/s) dt over
        // |t| < ℓ/2, S the disc's segment area below the chord at x (ρ_z = x s), by the
        // composite Simpson rule with 20 000 panels. S is C¹ with a 3/2-power end behaviour,
        // so the rule's error stays below 1e-9 of the volume.
        let (d, l) = (5.0, 11.0);
        let r = 0.5 * d;
        let full = PI * r * r * l;
        let mut rng = SplitMix64(23);
        for _ in 0..20 {
            let axis = rng.vec3(-1.0, 1.0);
            let n = (axis[0] * axis[0] + axis[1] * axis[1] + axis[2] * axis[2]).sqrt();
            let (c, s) = (axis[2].abs() / n, axis[0].hypot(axis[1]) / n);
            let z = rng.uniform(-6.0, 6.0);
            let panels = 20_000;
            let h = l / panels as f64;
            let f = |t: f64| {
                segment(r, if s > 0.0 { (z - t * c) / s } else { f64::INFINITY.copysign(z - t * c) })
            };
            let mut simpson = f(-0.5 * l) + f(0.5 * l);
            for k in 1..panels {
                simpson += if k % 2 == 1 { 4.0 } else { 2.0 } * f(-0.5 * l + k as f64 * h);
            }
            simpson *= h / 3.0;
            let v = cylinder_volume_below(d, l, axis, z);
            assert!((v - simpson).abs() < 1e-9 * full, "{axis:?} z={z}: {v} vs {simpson}");
        }
    }

    #[test]
    fn volume_below_is_monotone_in_z() {
        let mut rng = SplitMix64(5);
        for _ in 0..50 {
            let axis = rng.vec3(-1.0, 1.0);
            let mut last = 0.0;
            for k in 0..=400 {
                let v = cylinder_volume_below(3.0, 9.0, axis, -6.0 + 0.03 * k as f64);
                assert!(v >= last - 1e-12, "{axis:?}: V decreases at step {k}");
                last = v;
            }
        }
    }

    #[test]
    fn sphere_caps() {
        let d = 2.0;
        assert_eq!(sphere_volume_below(d, -1.0), 0.0);
        assert!((sphere_volume_below(d, 0.0) - 2.0 * PI / 3.0).abs() < 1e-15);
        assert!((sphere_volume_below(d, 1.0) - 4.0 * PI / 3.0).abs() < 1e-15);
        // Cap of height h = 0.5: π h² (3R − h)/3.
        assert!((sphere_volume_below(d, -0.5) - PI * 0.25 * 2.5 / 3.0).abs() < 1e-15);
    }
}
