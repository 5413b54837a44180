//! Cross-sections of solid finite cylinders by a vertical plane `y = const`, for outlining
//! the particles cut by the mid-plane of a field image (the paper's Figures 3 and 4).
//!
//! # Method
//!
//! Let the cylinder have centre `c`, unit axis `a`, radius `r` and half-length `h`; a point
//! `p` is inside when `|s| ≤ h` and `ρ ≤ r`, with `q = p − c`, `s = q·a` (axial coordinate)
//! and `ρ = |q − s a|` (distance from the axis). In the plane `y = y₀` write `q = (t_x, Δy,
//! t_z)` with `Δy = y₀ − c_y`, and split the in-plane part `t = (t_x, t_z)` along the unit
//! vector `e₁ = b / |b|` of the axis' projection `b = (a_x, a_z)` (any unit vector when
//! `b = 0`) and the perpendicular `e₂`: `t = α e₁ + β e₂`. Because `|b|² + a_y² = 1`,
//!
//! ```text
//! s  = |b| α + a_y Δy,
//! ρ² = (a_y α − |b| Δy)² + β².
//! ```
//!
//! The section is therefore `{(α, β) : α ∈ [α₋, α₊], |β| ≤ W(α)}` with the concave half
//! width `W(α) = √(r² − (a_y α − |b| Δy)²)`, where `[α₋, α₊]` is the intersection of the
//! interval where `|a_y α − |b| Δy| ≤ r` (the side) with the interval where `|s| ≤ h` (the
//! caps); an empty interval means no intersection. This covers every orientation alike: an
//! ellipse possibly cut by the caps' lines for a general axis, a disk for an axis along
//! `y`, a rectangle for an axis in the plane. The boundary is sampled at `α` values spaced
//! evenly in the angle `θ = arccos((a_y α − |b| Δy)/r)` around the axis (so that the
//! polygon is the affine image of an inscribed regular polygon of the cylinder's circle,
//! the usual good sampling of an ellipse), always including `α₋` and `α₊`; every vertex
//! `(α, ±W(α))` lies on the cylinder's surface: on the side where `W` is evaluated, on a
//! cap at the ends `α±` set by a cap.

/// The outline of the intersection of a solid finite cylinder with the vertical plane
/// `y = plane_y`, as a convex polygon of `(x, z)` vertices, counter-clockwise in the
/// `(x, z)` plane, not closed (the last vertex joins the first); `None` when the plane
/// misses the cylinder.
///
/// The cylinder has flat caps: `centre` its centre, `axis` the direction of its axis (a
/// unit vector; it is normalised here), `diameter` and `length` (cap to cap) its size.
/// `segments` is the number of vertices the outline of a full circle gets (at least 4 are
/// used); an elliptic arc gets vertices in proportion to the angle it spans around the
/// axis, and a cut by a cap is a straight edge. Every vertex lies on the cylinder's surface
/// (to rounding), so the polygon is inscribed in the exact section.
///
/// A plane that only touches the cylinder (along a side line, or at a cap's rim) gives a
/// degenerate polygon (a segment or a point). Non-finite input, a zero axis, a
/// non-positive diameter or a negative length give `None`.
///
/// For a field image whose extent is in other units (scaled by the tank diameter, shifted
/// to the axis), map the vertices the same way as the grid.
pub fn cylinder_section(
    centre: [f64; 3],
    axis: [f64; 3],
    diameter: f64,
    length: f64,
    plane_y: f64,
    segments: usize,
) -> Option<Vec<(f64, f64)>> {
    let finite = centre.iter().chain(&axis).chain(&[diameter, length, plane_y]).all(|v| v.is_finite());
    let norm = axis.iter().map(|v| v * v).sum::<f64>().sqrt();
    if !finite || !norm.is_finite() || norm <= 0.0 || diameter <= 0.0 || length < 0.0 {
        return None;
    }
    let a = axis.map(|v| v / norm);
    let (r, h) = (0.5 * diameter, 0.5 * length);
    let dy = plane_y - centre[1];
    let ay = a[1];
    let bn = a[0].hypot(a[2]);
    let e1 = if bn > 0.0 { (a[0] / bn, a[2] / bn) } else { (1.0, 0.0) };
    let e2 = (-e1.1, e1.0);

    // The interval of α inside the side, |a_y α − |b| Δy| ≤ r, …
    let side = if ay != 0.0 {
        let (p, q) = ((bn * dy - r) / ay, (bn * dy + r) / ay);
        (p.min(q), p.max(q))
    } else if (bn * dy).abs() <= r {
        (f64::NEG_INFINITY, f64::INFINITY)
    } else {
        return None;
    };
    // … and between the caps, |b| α + a_y Δy ∈ [−h, h].
    let caps = if bn > 0.0 {
        ((-h - ay * dy) / bn, (h - ay * dy) / bn)
    } else if (ay * dy).abs() <= h {
        (f64::NEG_INFINITY, f64::INFINITY)
    } else {
        return None;
    };
    let (lo, hi) = (side.0.max(caps.0), side.1.min(caps.1));
    if lo > hi || !lo.is_finite() || !hi.is_finite() {
        return None;
    }

    // Distance from the axis' plane through e₂ (signed), and the half width.
    let rho = |alpha: f64| (ay * alpha - bn * dy).clamp(-r, r);
    let half_width = |alpha: f64| {
        let p = ay * alpha - bn * dy;
        (r * r - p * p).max(0.0).sqrt()
    };
    let (rho_lo, rho_hi) = (rho(lo), rho(hi));
    let theta = |p: f64| (p / r).clamp(-1.0, 1.0).acos();
    let span = (theta(rho_hi) - theta(rho_lo)).abs();
    let segments = segments.max(4) as f64;
    let n = ((segments * span / std::f64::consts::TAU).ceil() as usize).max(1);
    let (th_lo, th_hi) = (theta(rho_lo), theta(rho_hi));
    let alphas: Vec<f64> = (0..=n)
        .map(|k| {
            if k == 0 {
                return lo;
            }
            if k == n {
                return hi;
            }
            let f = k as f64 / n as f64;
            if (rho_hi - rho_lo).abs() > 1e-12 * r {
                // ρ is affine in α: the α where the angle is θ_k.
                let p = r * (th_lo + f * (th_hi - th_lo)).cos();
                (lo + (hi - lo) * (p - rho_lo) / (rho_hi - rho_lo)).clamp(lo, hi)
            } else {
                lo + f * (hi - lo)
            }
        })
        .collect();

    // Upper edge from α₊ back to α₋, then the lower edge forwards: counter-clockwise in
    // (α, β), and (α, β) → (x, z) is a rotation.
    let to_xz = |alpha: f64, beta: f64| {
        (centre[0] + alpha * e1.0 + beta * e2.0, centre[2] + alpha * e1.1 + beta * e2.1)
    };
    let mut poly: Vec<(f64, f64)> = Vec::with_capacity(2 * n + 2);
    let mut push = |p: (f64, f64)| {
        if poly.last() != Some(&p) {
            poly.push(p);
        }
    };
    for &alpha in alphas.iter().rev() {
        push(to_xz(alpha, half_width(alpha)));
    }
    for &alpha in &alphas {
        push(to_xz(alpha, -half_width(alpha)));
    }
    while poly.len() > 1 && poly.first() == poly.last() {
        poly.pop();
    }
    Some(poly)
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::f64::consts::PI;

    /// Exact inside test of the solid cylinder.
    fn inside(p: [f64; 3], c: [f64; 3], a: [f64; 3], d: f64, l: f64) -> bool {
        let q = [p[0] - c[0], p[1] - c[1], p[2] - c[2]];
        let s = q[0] * a[0] + q[1] * a[1] + q[2] * a[2];
        let rad2 = q.iter().map(|v| v * v).sum::<f64>() - s * s;
        s.abs() <= 0.5 * l && rad2 <= 0.25 * d * d
    }

    /// Distance of `p` from the surface of the solid cylinder.
    fn surface_distance(p: [f64; 3], c: [f64; 3], a: [f64; 3], d: f64, l: f64) -> f64 {
        let q = [p[0] - c[0], p[1] - c[1], p[2] - c[2]];
        let s = q[0] * a[0] + q[1] * a[1] + q[2] * a[2];
        let rho = (q.iter().map(|v| v * v).sum::<f64>() - s * s).max(0.0).sqrt();
        let (dr, ds) = (rho - 0.5 * d, s.abs() - 0.5 * l);
        if dr <= 0.0 && ds <= 0.0 {
            -dr.max(ds) // inside: the nearer of side and cap
        } else {
            dr.max(0.0).hypot(ds.max(0.0))
        }
    }

    fn area(poly: &[(f64, f64)]) -> f64 {
        let n = poly.len();
        0.5 * (0..n)
            .map(|k| {
                let (p, q) = (poly[k], poly[(k + 1) % n]);
                p.0 * q.1 - q.0 * p.1
            })
            .sum::<f64>()
    }

    fn perimeter(poly: &[(f64, f64)]) -> f64 {
        let n = poly.len();
        (0..n).map(|k| (poly[(k + 1) % n].0 - poly[k].0).hypot(poly[(k + 1) % n].1 - poly[k].1)).sum()
    }

    /// Counter-clockwise and convex: every turn is a left turn (or straight, to rounding).
    fn assert_convex_ccw(poly: &[(f64, f64)], scale: f64) {
        let n = poly.len();
        assert!(n >= 3, "{n} vertices");
        for k in 0..n {
            let (p, q, s) = (poly[k], poly[(k + 1) % n], poly[(k + 2) % n]);
            let cross = (q.0 - p.0) * (s.1 - q.1) - (q.1 - p.1) * (s.0 - q.0);
            assert!(cross >= -1e-12 * scale * scale, "right turn at vertex {k}: {cross}");
        }
        assert!(area(poly) > 0.0);
    }

    fn unit(v: [f64; 3]) -> [f64; 3] {
        let n = (v[0] * v[0] + v[1] * v[1] + v[2] * v[2]).sqrt();
        v.map(|x| x / n)
    }

    /// Every vertex on the surface to 1e-9.
    fn assert_on_surface(poly: &[(f64, f64)], c: [f64; 3], a: [f64; 3], d: f64, l: f64, y: f64) {
        let a = unit(a);
        for (k, &(x, z)) in poly.iter().enumerate() {
            let dist = surface_distance([x, y, z], c, a, d, l);
            assert!(dist.abs() < 1e-9, "vertex {k} ({x}, {z}) is {dist} off the surface");
        }
    }

    /// The area of the section by counting cell centres of a fine grid (spacing `step`) over
    /// the box `bx × bz` with the exact inside test.
    fn grid_area(
        cyl: ([f64; 3], [f64; 3], f64, f64),
        y: f64,
        bx: (f64, f64),
        bz: (f64, f64),
        step: f64,
    ) -> f64 {
        let (c, a, d, l) = cyl;
        let a = unit(a);
        let (nx, nz) = (((bx.1 - bx.0) / step).ceil() as usize, ((bz.1 - bz.0) / step).ceil() as usize);
        let mut count = 0usize;
        for j in 0..nz {
            let z = bz.0 + (j as f64 + 0.5) * step;
            for i in 0..nx {
                let x = bx.0 + (i as f64 + 0.5) * step;
                count += inside([x, y, z], c, a, d, l) as usize;
            }
        }
        count as f64 * step * step
    }

    fn bbox(poly: &[(f64, f64)]) -> ((f64, f64), (f64, f64)) {
        let f = |g: fn(&(f64, f64)) -> f64| {
            poly.iter().map(g).fold((f64::INFINITY, f64::NEG_INFINITY), |(l, h), v| (l.min(v), h.max(v)))
        };
        (f(|p| p.0), f(|p| p.1))
    }

    #[test]
    fn axis_along_y_is_a_disk_between_the_caps() {
        let (c, d, l) = ([3.0, 5.0, -2.0], 4.0, 6.0);
        for y in [5.0, 7.9, 2.1, 8.0, 2.0] {
            let poly = cylinder_section(c, [0.0, 1.0, 0.0], d, l, y, 64).unwrap();
            assert_eq!(poly.len(), 64, "y = {y}");
            for &(x, z) in &poly {
                assert!(((x - c[0]).hypot(z - c[2]) - 2.0).abs() < 1e-12, "y = {y}: ({x}, {z})");
            }
            assert_convex_ccw(&poly, 2.0);
            assert_on_surface(&poly, c, [0.0, 1.0, 0.0], d, l, y);
            // The inscribed regular 64-gon.
            assert!((area(&poly) - 32.0 * 4.0 * (2.0 * PI / 64.0).sin()).abs() < 1e-12);
        }
        for y in [8.0 + 1e-9, 2.0 - 1e-9, 100.0] {
            assert_eq!(cylinder_section(c, [0.0, -1.0, 0.0], d, l, y, 64), None, "y = {y}");
        }
    }

    #[test]
    fn axis_along_z_is_a_rectangle() {
        let (c, d, l) = ([1.0, 0.0, 10.0], 2.0, 8.0);
        for dy in [0.0, 0.3, -0.8, 0.999] {
            let poly = cylinder_section(c, [0.0, 0.0, 1.0], d, l, dy, 32).unwrap();
            let half = (1.0 - dy * dy).sqrt();
            let ((x0, x1), (z0, z1)) = bbox(&poly);
            assert!((x0 - (1.0 - half)).abs() < 1e-12 && (x1 - (1.0 + half)).abs() < 1e-12, "dy = {dy}");
            assert!((z0 - 6.0).abs() < 1e-12 && (z1 - 14.0).abs() < 1e-12, "dy = {dy}");
            assert!((area(&poly) - 2.0 * half * l).abs() < 1e-12, "dy = {dy}");
            assert_eq!(poly.len(), 4);
            assert_convex_ccw(&poly, 8.0);
            assert_on_surface(&poly, c, [0.0, 0.0, 1.0], d, l, dy);
        }
        assert_eq!(cylinder_section(c, [0.0, 0.0, -1.0], d, l, 1.0 + 1e-9, 32), None);
        assert_eq!(cylinder_section(c, [0.0, 0.0, 1.0], d, l, -1.5, 32), None);
        // Tangent: a degenerate section along the side line.
        let touch = cylinder_section(c, [0.0, 0.0, 1.0], d, l, 1.0, 32).unwrap();
        assert!(area(&touch).abs() < 1e-12 && touch.len() == 2, "{touch:?}");
    }

    #[test]
    fn axis_along_x_is_a_rectangle() {
        let (c, d, l) = ([-4.0, 2.0, 3.0], 3.0, 5.0);
        let y = 2.0 + 1.2;
        let poly = cylinder_section(c, [-1.0, 0.0, 0.0], d, l, y, 32).unwrap();
        let half = (1.5f64 * 1.5 - 1.2 * 1.2).sqrt();
        let ((x0, x1), (z0, z1)) = bbox(&poly);
        assert!((x0 + 6.5).abs() < 1e-12 && (x1 + 1.5).abs() < 1e-12, "{x0} {x1}");
        assert!((z0 - (3.0 - half)).abs() < 1e-12 && (z1 - (3.0 + half)).abs() < 1e-12, "{z0} {z1}");
        assert!((area(&poly) - l * 2.0 * half).abs() < 1e-12);
        assert_convex_ccw(&poly, 5.0);
        assert_on_surface(&poly, c, [-1.0, 0.0, 0.0], d, l, y);
        assert_eq!(cylinder_section(c, [1.0, 0.0, 0.0], d, l, 2.0 - 1.5 - 1e-9, 32), None);
    }

    #[test]
    fn tilted_long_cylinder_cut_through_the_side_is_an_ellipse() {
        // Caps far from the plane: the section is the ellipse of area π r² / |a_y|.
        let (c, d, l) = ([0.5, -1.0, 2.0], 2.0, 100.0);
        for a in [[0.3, 0.8, -0.5], [0.0, 0.2, 1.0], [1.0, -0.05, 0.1], [0.01, 1.0, 0.0]] {
            let n = 720;
            let poly = cylinder_section(c, a, d, l, -1.0 + 0.4, n).unwrap();
            let ay = unit(a)[1].abs();
            let exact = PI / ay;
            // The inscribed polygon lacks at most the fraction 1 − sin(δ)/δ, δ = 2π/n.
            let delta = 2.0 * PI / n as f64;
            let rel = (exact - area(&poly)) / exact;
            assert!(rel >= 0.0 && rel <= 1.0 - delta.sin() / delta + 1e-12, "axis {a:?}: {rel}");
            assert_convex_ccw(&poly, 1.0 / ay);
            assert_on_surface(&poly, c, a, d, l, -0.6);
        }
    }

    #[test]
    fn tilted_sections_match_the_inside_test_on_a_grid() {
        // Sections cut by the caps, through the side only, near-degenerate orientations:
        // (centre, axis, diameter, length, plane y).
        type Case = ([f64; 3], [f64; 3], f64, f64, f64);
        let cases: [Case; 7] = [
            ([0.0, 0.0, 0.0], [0.6, 0.48, 0.64], 2.0, 6.0, 0.9),
            ([1.0, 2.0, -1.0], [0.2, -0.9, 0.4], 1.0, 4.0, 3.5),
            ([0.0, 0.0, 0.0], [1.0, 0.02, 0.3], 1.5, 3.0, -0.3),
            ([0.0, 0.0, 0.0], [1e-7, 1.0, 2e-7], 2.0, 2.0, 0.99),
            ([0.0, 0.0, 0.0], [0.7, 1e-9, -0.7], 2.0, 5.0, 0.2),
            ([0.0, 5.0, 0.0], [0.0, 0.7, 0.7], 3.0, 1.0, 5.5),
            ([0.0, 0.0, 0.0], [0.5, 0.5, 0.5], 1.0, 1.0, -0.6),
        ];
        let step = 0.002;
        for (c, a, d, l, y) in cases {
            let poly = cylinder_section(c, a, d, l, y, 1024).unwrap();
            assert_on_surface(&poly, c, a, d, l, y);
            assert_convex_ccw(&poly, d.max(l));
            let ((x0, x1), (z0, z1)) = bbox(&poly);
            let pad = 0.1;
            let grid = grid_area((c, a, d, l), y, (x0 - pad, x1 + pad), (z0 - pad, z1 + pad), step);
            let poly_area = area(&poly);
            // Counting cell centres errs by at most the area of the cells that the boundary
            // crosses, fewer than √2·P/step + 4 for a convex outline of perimeter P; the
            // inscribed 1024-gon lacks less than 2e-5 of the area.
            let crossed = std::f64::consts::SQRT_2 * perimeter(&poly) / step + 4.0;
            let tol = crossed * step * step + 2e-5 * poly_area;
            assert!(
                (grid - poly_area).abs() <= tol,
                "axis {a:?}, y = {y}: polygon {poly_area}, grid {grid}, tol {tol}"
            );
        }
    }

    #[test]
    fn planes_beyond_the_support_miss_and_just_inside_hit() {
        // The cylinder's extent along y is h|a_y| + r√(1 − a_y²).
        let (c, d, l) = ([0.0, 1.0, 0.0], 2.0, 4.0);
        for a in [[0.6, 0.48, 0.64], [0.0, 1.0, 0.0], [1.0, 0.0, 0.0], [0.3, -0.9, 0.1]] {
            let u = unit(a);
            let reach = 2.0 * u[1].abs() + (1.0 - u[1] * u[1]).max(0.0).sqrt();
            for sign in [-1.0, 1.0] {
                let out = 1.0 + sign * (reach + 1e-7);
                assert_eq!(cylinder_section(c, a, d, l, out, 64), None, "axis {a:?}, y = {out}");
                let inn = 1.0 + sign * (reach - 1e-3);
                let poly = cylinder_section(c, a, d, l, inn, 64).expect("a small section");
                assert!(area(&poly) > 0.0, "axis {a:?}: {}", area(&poly));
                assert_on_surface(&poly, c, a, d, l, inn);
            }
        }
    }

    #[test]
    fn pseudo_random_cylinders() {
        // Vertices on the surface, convex counter-clockwise outlines, and the polygon's
        // centroid inside the cylinder, for many orientations and offsets.
        let mut seed = 0x2545_f491_4f6c_dd1du64;
        let mut rnd = || {
            seed ^= seed << 13;
            seed ^= seed >> 7;
            seed ^= seed << 17;
            (seed >> 11) as f64 / (1u64 << 53) as f64
        };
        let mut hits = 0;
        for _ in 0..400 {
            let c = [rnd() * 10.0, rnd() * 10.0, rnd() * 10.0];
            let a = [rnd() - 0.5, rnd() - 0.5, rnd() - 0.5];
            let (d, l) = (0.5 + rnd() * 2.0, 0.5 + rnd() * 6.0);
            let y = c[1] + (rnd() - 0.5) * 8.0;
            let Some(poly) = cylinder_section(c, a, d, l, y, 48) else {
                // A miss: no grid point of the plane near the cylinder is inside.
                let u = unit(a);
                for i in -60..=60 {
                    for j in -60..=60 {
                        let p = [c[0] + i as f64 * 0.1, y, c[2] + j as f64 * 0.1];
                        assert!(!inside(p, c, u, d, l), "missed section at {p:?}");
                    }
                }
                continue;
            };
            hits += 1;
            assert_on_surface(&poly, c, a, d, l, y);
            if area(&poly) > 1e-6 {
                assert_convex_ccw(&poly, 10.0);
                let n = poly.len() as f64;
                let m = poly.iter().fold((0.0, 0.0), |s, p| (s.0 + p.0 / n, s.1 + p.1 / n));
                assert!(inside([m.0, y, m.1], c, unit(a), d, l));
            }
        }
        assert!(hits > 100, "{hits} hits");
    }

    #[test]
    fn bad_input_is_none() {
        let c = [0.0; 3];
        assert_eq!(cylinder_section(c, [0.0; 3], 1.0, 1.0, 0.0, 16), None);
        assert_eq!(cylinder_section(c, [0.0, 1.0, 0.0], 0.0, 1.0, 0.0, 16), None);
        assert_eq!(cylinder_section(c, [0.0, 1.0, 0.0], 1.0, -1.0, 0.0, 16), None);
        assert_eq!(cylinder_section(c, [f64::NAN, 1.0, 0.0], 1.0, 1.0, 0.0, 16), None);
        assert_eq!(cylinder_section(c, [0.0, 1.0, 0.0], 1.0, 1.0, f64::INFINITY, 16), None);
        // A non-unit axis is normalised.
        let p = cylinder_section(c, [0.0, 0.0, 7.0], 2.0, 2.0, 0.0, 16).unwrap();
        assert!((area(&p) - 4.0).abs() < 1e-12);
    }
}
