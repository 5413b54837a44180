//! Small numerical helpers: least-squares fits, norms.

/// Least-squares line `y = a + b x`; returns `(a, b)`. Needs at least two distinct `x`.
pub fn line(x: &[f64], y: &[f64]) -> (f64, f64) {
    assert_eq!(x.len(), y.len());
    assert!(x.len() >= 2, "a fit needs at least two points");
    let n = x.len() as f64;
    let mx = x.iter().sum::<f64>() / n;
    let my = y.iter().sum::<f64>() / n;
    let sxy: f64 = x.iter().zip(y).map(|(a, b)| (a - mx) * (b - my)).sum();
    let sxx: f64 = x.iter().map(|a| (a - mx) * (a - mx)).sum();
    let b = sxy / sxx;
    (my - b * mx, b)
}

/// Observed order of convergence: minus the least-squares slope of `log(error)` against
/// `log(resolution)` over all points (so that `error ∝ N^-p` gives `p`).
pub fn order(resolution: &[f64], error: &[f64]) -> f64 {
    let lx: Vec<f64> = resolution.iter().map(|v| v.ln()).collect();
    let ly: Vec<f64> = error.iter().map(|v| v.ln()).collect();
    -line(&lx, &ly).1
}

/// The observed order `p` and the Richardson estimate `f₀` of a quantity `f` computed at three
/// grid spacings `h₀ > h₁ > h₂` (any ratios), assuming `f(h) = f₀ + C hᵖ`:
///
/// ```text
/// (f₀' − f₁)/(f₁ − f₂) = (h₀ᵖ − h₁ᵖ)/(h₁ᵖ − h₂ᵖ)     (solved for p by bisection on (0.05, 8))
/// f₀ = f₂ − (f₁ − f₂)/((h₁/h₂)ᵖ − 1)
/// ```
///
/// `None` when the sequence is not monotone (the differences change sign), or when no `p` in
/// the bracket fits: then no order can be claimed from these three points.
pub fn richardson3(h: [f64; 3], f: [f64; 3]) -> Option<(f64, f64)> {
    assert!(h[0] > h[1] && h[1] > h[2] && h[2] > 0.0, "spacings must decrease: {h:?}");
    let (d01, d12) = (f[0] - f[1], f[1] - f[2]);
    if d01 == 0.0 || d12 == 0.0 || d01.signum() != d12.signum() {
        return None;
    }
    let target = d01 / d12;
    let ratio = |p: f64| (h[0].powf(p) - h[1].powf(p)) / (h[1].powf(p) - h[2].powf(p));
    let (mut lo, mut hi) = (0.05, 8.0);
    // `ratio` increases with p for decreasing spacings.
    if !(ratio(lo) <= target && target <= ratio(hi)) {
        return None;
    }
    for _ in 0..200 {
        let mid = 0.5 * (lo + hi);
        if ratio(mid) < target {
            lo = mid;
        } else {
            hi = mid;
        }
    }
    let p = 0.5 * (lo + hi);
    Some((p, f[2] - d12 / ((h[1] / h[2]).powf(p) - 1.0)))
}

/// Relative L2 error `sqrt(Σ (a−b)² / Σ b²)` of `a` against the reference `b`.
pub fn rel_l2(a: &[f64], b: &[f64]) -> f64 {
    assert_eq!(a.len(), b.len());
    let num: f64 = a.iter().zip(b).map(|(x, y)| (x - y) * (x - y)).sum();
    let den: f64 = b.iter().map(|y| y * y).sum();
    (num / den).sqrt()
}

/// Maximum relative error `max |a−b| / max |b|`.
pub fn rel_max(a: &[f64], b: &[f64]) -> f64 {
    assert_eq!(a.len(), b.len());
    let num = a.iter().zip(b).map(|(x, y)| (x - y).abs()).fold(0.0, f64::max);
    let den = b.iter().map(|y| y.abs()).fold(0.0, f64::max);
    num / den
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn order_of_an_exact_power_law() {
        let n = [8.0, 16.0, 32.0, 64.0];
        let e: Vec<f64> = n.iter().map(|v: &f64| 3.0 * v.powf(-2.0)).collect();
        assert!((order(&n, &e) - 2.0).abs() < 1e-12);
    }

    #[test]
    fn richardson3_recovers_order_and_limit_for_unequal_ratios() {
        let h = [4.0, 3.0, 2.0];
        for p in [0.7, 1.0, 2.0] {
            let f = h.map(|v: f64| 2.5 + 0.3 * v.powf(p));
            let (q, f0) = richardson3(h, f).unwrap();
            assert!((q - p).abs() < 1e-9 && (f0 - 2.5).abs() < 1e-9, "p {p}: got {q}, {f0}");
        }
        assert!(richardson3(h, [1.0, 2.0, 1.5]).is_none(), "non-monotone");
    }

    #[test]
    fn line_recovers_slope_and_intercept() {
        let x = [0.0, 1.0, 2.0, 5.0];
        let y: Vec<f64> = x.iter().map(|v| 1.5 - 0.25 * v).collect();
        let (a, b) = line(&x, &y);
        assert!((a - 1.5).abs() < 1e-14 && (b + 0.25).abs() < 1e-14);
    }
}
