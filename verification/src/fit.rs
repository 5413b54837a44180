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

/// The observed order and Richardson estimate from three resolutions; lives in the library,
/// where the reproduction's resolution study uses it too.
pub use slurry::util::richardson3;

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
    fn line_recovers_slope_and_intercept() {
        let x = [0.0, 1.0, 2.0, 5.0];
        let y: Vec<f64> = x.iter().map(|v| 1.5 - 0.25 * v).collect();
        let (a, b) = line(&x, &y);
        assert!((a - 1.5).abs() < 1e-14 && (b + 0.25).abs() < 1e-14);
    }
}
