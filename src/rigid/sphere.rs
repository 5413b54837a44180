//! A sphere of diameter `d`, centred at the body origin.

use std::f64::consts::PI;

use super::shape::{check_depth, shrink, sphere_chord, Marker, RetractionError, Shape};
use super::{Mat3, Vec3};

/// A sphere of diameter `d` (radius `R = d/2`) centred at the origin.
///
/// Volume `π d³/6`, surface `π d²`, principal moments `I = (2/5) m R²` about every axis.
///
/// **Markers**: a Fibonacci (golden-angle) lattice of `N = round(π d²/h²)` points, so that
/// every marker stands for the same area `π d²/N ≈ h²` (the same area per marker as the
/// cylinder's rings at spacing `h`). Point `k` sits at height
/// `z_k = R (1 − (2k + 1)/N)` (equal-area bands) and azimuth `k · π(3 − √5)`; the
/// nearest-neighbour distances are close to `h` everywhere (see the unit tests for the
/// statistics at `d = 12`, `h = 0.7`).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Sphere {
    diameter: f64,
}

impl Sphere {
    /// A sphere of diameter `diameter` (> 0, finite).
    ///
    /// # Panics
    /// If the diameter is not positive and finite.
    pub fn new(diameter: f64) -> Self {
        assert!(diameter.is_finite() && diameter > 0.0, "sphere diameter must be positive, got {diameter}");
        Self { diameter }
    }

    /// Diameter `d`.
    pub fn diameter(&self) -> f64 {
        self.diameter
    }

    /// Radius `d/2`.
    pub fn radius(&self) -> f64 {
        0.5 * self.diameter
    }
}

impl Shape for Sphere {
    fn name(&self) -> &'static str {
        "sphere"
    }

    fn volume(&self) -> f64 {
        PI * self.diameter.powi(3) / 6.0
    }

    fn surface_area(&self) -> f64 {
        PI * self.diameter * self.diameter
    }

    fn principal_moments_unit_density(&self) -> Vec3 {
        let r = self.radius();
        Vec3::repeat(0.4 * self.volume() * r * r)
    }

    fn signed_distance(&self, p: &Vec3) -> f64 {
        p.norm() - self.radius()
    }

    fn bounding_radius(&self) -> f64 {
        self.radius()
    }

    fn half_extents(&self, _rotation: &Mat3, offset: f64) -> Vec3 {
        Vec3::repeat(self.radius() + offset)
    }

    /// Exact for every offset: the ball of radius `r + offset`.
    fn chord(&self, p: &Vec3, dir: &Vec3, offset: f64) -> Option<(f64, f64)> {
        sphere_chord(p, dir, self.radius() + offset)
    }

    fn markers(&self, spacing: f64) -> Vec<Marker> {
        assert!(spacing.is_finite() && spacing > 0.0, "marker spacing must be positive, got {spacing}");
        let r = self.radius();
        let s = self.surface_area();
        let n = ((s / (spacing * spacing)).round() as usize).max(1);
        let area = s / n as f64;
        let golden = PI * (3.0 - 5f64.sqrt());
        (0..n)
            .map(|k| {
                let z = 1.0 - (2 * k + 1) as f64 / n as f64;
                let rho = (1.0 - z * z).max(0.0).sqrt();
                let (sn, cs) = (golden * k as f64).sin_cos();
                let normal = Vec3::new(rho * cs, rho * sn, z).normalize();
                Marker { position: normal * r, normal, area }
            })
            .collect()
    }

    /// The markers of the sphere of diameter `d − 2 depth` (concentric).
    fn retracted_markers(&self, spacing: f64, depth: f64) -> Result<Vec<Marker>, RetractionError> {
        check_depth(depth)?;
        Ok(Sphere::new(shrink("sphere", "diameter", self.diameter, depth)?).markers(spacing))
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::rigid::shape::testing::{
        assert_within_5_sigma, check_markers, monte_carlo, nearest_neighbour,
    };
    use crate::rigid::DEFAULT_MARKER_SPACING;

    #[test]
    fn volume_area_and_moments_against_monte_carlo() {
        let s = Sphere::new(2.0);
        assert!((s.volume() - 4.0 * PI / 3.0).abs() < 1e-15);
        assert!((s.surface_area() - 4.0 * PI).abs() < 1e-14);
        let (est, err) = monte_carlo(&s, Vec3::repeat(1.0), 4_000_000, 7);
        let exact = [s.volume(), s.principal_moments_unit_density().x, 0.0, 0.0];
        let exact = [exact[0], exact[1], exact[1], exact[1]];
        assert_within_5_sigma(&est, &err, &exact);
    }

    #[test]
    fn mass_properties_scale_with_density() {
        let s = Sphere::new(12.0);
        let mp = s.mass_properties(1.25);
        assert!((mp.mass - 1.25 * PI * 1728.0 / 6.0).abs() < 1e-10);
        assert!((mp.principal_moments.x - 0.4 * mp.mass * 36.0).abs() < 1e-9);
    }

    #[test]
    fn signed_distance_and_inside() {
        let s = Sphere::new(6.0);
        assert_eq!(s.signed_distance(&Vec3::zeros()), -3.0);
        assert!((s.signed_distance(&Vec3::new(3.0, 4.0, 0.0)) - 2.0).abs() < 1e-15);
        assert!(s.contains(&Vec3::new(1.0, 1.0, 1.0)));
        assert!(!s.contains(&Vec3::new(3.0, 0.0, 0.1)));
        assert_eq!(s.bounding_radius(), 3.0);
    }

    #[test]
    fn markers_areas_normals_and_spacing() {
        for d in [1.0, 6.0, 12.0] {
            let s = Sphere::new(d);
            let m = s.markers(DEFAULT_MARKER_SPACING);
            check_markers(&s, &m, 1e-6 * d);
            let nn = nearest_neighbour(&m);
            let lo = nn.iter().copied().fold(f64::INFINITY, f64::min);
            let hi = nn.iter().copied().fold(0.0, f64::max);
            let mean = nn.iter().sum::<f64>() / nn.len() as f64;
            eprintln!(
                "sphere d={d}: {} markers, nearest neighbour min {lo:.3} mean {mean:.3} max {hi:.3}",
                m.len()
            );
            if d >= 6.0 {
                assert!(lo >= 0.5 && hi <= 0.9, "d={d}: nearest neighbour in [{lo}, {hi}]");
            }
        }
    }
}
