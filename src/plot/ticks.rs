//! Tick text: decimals fixed by the axis' span on linear axes, four significant digits on
//! logarithmic ones, scientific notation for very large or small magnitudes.

/// Strips trailing zeros (and a trailing point) from a decimal number's text.
fn trim_zeros(s: &str) -> String {
    if s.contains('.') {
        s.trim_end_matches('0').trim_end_matches('.').to_string()
    } else {
        s.to_string()
    }
}

/// Scientific notation with at most four significant digits: `1.5e-4`.
fn fmt_sci(v: f64) -> String {
    let s = format!("{v:.3e}");
    match s.split_once('e') {
        Some((m, e)) => format!("{}e{e}", trim_zeros(m)),
        None => s,
    }
}

/// Tick text on a linear axis spanning `span`: decimals fixed by the span (so that all
/// ticks of an axis read alike), values within `10⁻⁹·span` of zero written `0`, scientific
/// notation for magnitudes `≥ 10⁵` or `< 10⁻³`.
pub(super) fn fmt_linear_tick(v: f64, span: f64) -> String {
    if v.abs() <= 1e-9 * span {
        return "0".to_string();
    }
    let a = v.abs();
    if !(1e-3..1e5).contains(&a) {
        return fmt_sci(v);
    }
    let decimals = (2 - span.log10().floor() as i32).clamp(0, 10) as usize;
    trim_zeros(&format!("{v:.decimals$}"))
}

/// Tick text on a logarithmic axis: four significant digits, scientific notation for
/// magnitudes `≥ 10⁵` or `< 10⁻³`.
pub(super) fn fmt_log_tick(v: f64) -> String {
    let a = v.abs();
    if a == 0.0 || !(1e-3..1e5).contains(&a) {
        return fmt_sci(v);
    }
    let decimals = (3 - a.log10().floor() as i32).clamp(0, 10) as usize;
    trim_zeros(&format!("{v:.decimals$}"))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn tick_text() {
        assert_eq!(fmt_linear_tick(0.30000000000000004, 1.0), "0.3");
        assert_eq!(fmt_linear_tick(5.5e-17, 1.0), "0");
        assert_eq!(fmt_linear_tick(250.0, 1000.0), "250");
        assert_eq!(fmt_linear_tick(0.015, 0.05), "0.015");
        assert_eq!(fmt_linear_tick(2e6, 1e7), "2e6");
        assert_eq!(fmt_log_tick(0.01), "0.01");
        assert_eq!(fmt_log_tick(1e-5), "1e-5");
        assert_eq!(fmt_log_tick(1000.0), "1000");
    }
}
