//! A finite (flat-capped) cylinder of diameter `d` and length `ℓ`: the particle of Derksen
//! (2020), with `ℓ/d = 1, 2, 4`.

use std::f64::consts::{FRAC_1_SQRT_2, PI, TAU};

use super::shape::{check_depth, ring, shrink, Marker, RetractionError, Shape};
use super::{Mat3, Vec3};

/// A solid circular cylinder of diameter `d` and length `ℓ`, axis along body `z`, centred at
/// the origin (caps at `z = ±ℓ/2`).
///
/// Volume `π d² ℓ/4`, surface `π d ℓ + 2 · π d²/4`. Principal moments (physics.md §1):
/// `I_axial = I_z = m d²/8`, `I_transverse = I_x = I_y = m (3d²/4 + ℓ²)/12`.
///
/// **Markers** at requested spacing `h` (with `R = d/2`):
/// - the length is cut into `n_z = max(1, round(ℓ/h))` bands of height `h_z = ℓ/n_z`, the
///   radius into `n_r = max(1, round(R/h))` annuli of width `h_r = R/n_r`, so that the
///   spacing is close to `h` along the axis and radially;
/// - **mantle**: `n_z − 1` rings at `z = −ℓ/2 + k h_z`, `k = 1 … n_z − 1`, each of
///   `m = max(3, round(2πR/h))` markers (spacing `2πR/m ≈ h` around), normal `(cos θ, sin θ, 0)`,
///   weight `2πR h_z / m` (the band `|z − z_k| < h_z/2`);
/// - **caps**: a centre marker (weight `π h_r²/4`, the disc `r < h_r/2`) and `n_r − 1` rings at
///   `r_j = j h_r` of `max(3, round(2π r_j/h))` markers, weight: the annulus
///   `|r − r_j| < h_r/2`, `2π r_j h_r`, shared equally; normal `±z`;
/// - **rims**: one ring on each edge (`r = R`, `z = ±ℓ/2`) of `m` markers with the bisector
///   normal `(cos θ, sin θ, ±1)/√2`. **Area split:** a rim marker stands for the half-band of
///   the mantle next to the edge (`ℓ/2 − h_z/2 < |z| < ℓ/2`, area `πR h_z`) plus the
///   half-annulus of the cap next to the edge (`R − h_r/2 < r < R`, area
///   `π(R h_r − h_r²/4)`), divided equally among the `m` rim markers.
///
/// The pieces tile the surface exactly: mantle `(n_z − 1) · 2πR h_z + 2 · πR h_z = 2πRℓ`;
/// cap `π h_r²/4 + Σ_{j=1}^{n_r−1} 2π j h_r² + π(R h_r − h_r²/4) = π h_r² n_r(n_r − 1) + πR h_r
/// = πR²`. So the weights sum to `π d ℓ + 2 · π d²/4` to round-off. Successive rings are
/// rotated by half a marker spacing (alternating phase) so that markers of neighbouring rings
/// interleave. The nearest-neighbour statistics at `d = 12`, `h = 0.7` are in the unit tests.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Cylinder {
    diameter: f64,
    length: f64,
}

impl Cylinder {
    /// A cylinder of diameter `diameter` and length `length` (both > 0, finite).
    ///
    /// # Panics
    /// If either is not positive and finite.
    pub fn new(diameter: f64, length: f64) -> Self {
        assert!(
            diameter.is_finite() && diameter > 0.0 && length.is_finite() && length > 0.0,
            "cylinder diameter and length must be positive, got d = {diameter}, l = {length}"
        );
        Self { diameter, length }
    }

    /// Diameter `d`.
    pub fn diameter(&self) -> f64 {
        self.diameter
    }

    /// Length `ℓ` (along body `z`).
    pub fn length(&self) -> f64 {
        self.length
    }

    /// Radius `d/2`.
    pub fn radius(&self) -> f64 {
        0.5 * self.diameter
    }
}

/// Markers on a ring of radius `r`: about `2πr/h`, at least 3.
fn ring_count(r: f64, h: f64) -> usize {
    ((TAU * r / h).round() as usize).max(3)
}

impl Shape for Cylinder {
    fn name(&self) -> &'static str {
        "cylinder"
    }

    fn volume(&self) -> f64 {
        0.25 * PI * self.diameter * self.diameter * self.length
    }

    fn surface_area(&self) -> f64 {
        PI * self.diameter * self.length + 0.5 * PI * self.diameter * self.diameter
    }

    fn principal_moments_unit_density(&self) -> Vec3 {
        let m = self.volume();
        let (d, l) = (self.diameter, self.length);
        let transverse = m * (0.75 * d * d + l * l) / 12.0;
        Vec3::new(transverse, transverse, m * d * d / 8.0)
    }

    fn signed_distance(&self, p: &Vec3) -> f64 {
        // `sqrt(x² + y²)` rather than `hypot`: no overflow is possible at lattice sizes, and
        // libm's `hypot` took 16 % of a dense bed's contact step (it is called per marker).
        let qr = (p.x * p.x + p.y * p.y).sqrt() - self.radius();
        let qz = p.z.abs() - 0.5 * self.length;
        let (a, b) = (qr.max(0.0), qz.max(0.0));
        qr.max(qz).min(0.0) + (a * a + b * b).sqrt()
    }

    fn bounding_radius(&self) -> f64 {
        self.radius().hypot(0.5 * self.length)
    }

    /// The box of the flat-capped cylinder of radius `R + offset` and half-length
    /// `ℓ/2 + offset` (which contains the rounded set `{sd < offset}`): with `a` the world
    /// axis, `e_k = (ℓ/2 + offset)|a_k| + (R + offset)√(1 − a_k²)`.
    fn half_extents(&self, rotation: &Mat3, offset: f64) -> Vec3 {
        let a = rotation.column(2);
        let (r, h) = (self.radius() + offset, 0.5 * self.length + offset);
        Vec3::from_fn(|k, _| h * a[k].abs() + r * (1.0 - a[k] * a[k]).max(0.0).sqrt())
    }

    /// The chord of the flat-capped cylinder of radius `R + offset` and half-length
    /// `ℓ/2 + offset`. For `offset < 0` that cylinder *is* the set `{sd < offset}` (exact);
    /// for `offset > 0` it contains the set (whose rims are rounded): a superset, as the
    /// trait asks.
    fn chord(&self, p: &Vec3, dir: &Vec3, offset: f64) -> Option<(f64, f64)> {
        let (r, h) = (self.radius() + offset, 0.5 * self.length + offset);
        if r <= 0.0 || h <= 0.0 {
            return None;
        }
        // Slab |z| < h.
        let (mut t0, mut t1) = if dir.z.abs() > 1e-300 {
            let (a, b) = ((-h - p.z) / dir.z, (h - p.z) / dir.z);
            (a.min(b), a.max(b))
        } else if p.z.abs() < h {
            (f64::NEG_INFINITY, f64::INFINITY)
        } else {
            return None;
        };
        // Infinite cylinder x² + y² < r².
        let a = dir.x * dir.x + dir.y * dir.y;
        let b = p.x * dir.x + p.y * dir.y;
        let c = p.x * p.x + p.y * p.y - r * r;
        if a > 1e-300 {
            let disc = b * b - a * c;
            if disc <= 0.0 {
                return None;
            }
            let s = disc.sqrt();
            t0 = t0.max((-b - s) / a);
            t1 = t1.min((-b + s) / a);
        } else if c >= 0.0 {
            return None;
        }
        (t0 < t1).then_some((t0, t1))
    }

    fn markers(&self, spacing: f64) -> Vec<Marker> {
        assert!(spacing.is_finite() && spacing > 0.0, "marker spacing must be positive, got {spacing}");
        let h = spacing;
        let r = self.radius();
        let half = 0.5 * self.length;
        let nz = ((self.length / h).round() as usize).max(1);
        let hz = self.length / nz as f64;
        let nr = ((r / h).round() as usize).max(1);
        let hr = r / nr as f64;
        let m = ring_count(r, h);
        let alt = |k: usize, n: usize| if k % 2 == 1 { PI / n as f64 } else { 0.0 };
        let mut out = Vec::new();
        // Mantle interior rings.
        let a_mantle = TAU * r * hz / m as f64;
        for k in 1..nz {
            let z = -half + k as f64 * hz;
            ring(&mut out, m, r, z, alt(k, m), a_mantle, |c, s| Vec3::new(c, s, 0.0));
        }
        // Rims (k = 0 at the bottom, k = n_z at the top) and caps.
        let a_rim = (PI * r * hz + PI * (r * hr - 0.25 * hr * hr)) / m as f64;
        for (sign, k) in [(-1.0, 0), (1.0, nz)] {
            let z = sign * half;
            ring(&mut out, m, r, z, alt(k, m), a_rim, |c, s| {
                Vec3::new(c * FRAC_1_SQRT_2, s * FRAC_1_SQRT_2, sign * FRAC_1_SQRT_2)
            });
            let n_cap = Vec3::new(0.0, 0.0, sign);
            out.push(Marker { position: Vec3::new(0.0, 0.0, z), normal: n_cap, area: 0.25 * PI * hr * hr });
            for j in 1..nr {
                let rj = j as f64 * hr;
                let mj = ring_count(rj, h);
                ring(&mut out, mj, rj, z, alt(j, mj), TAU * rj * hr / mj as f64, |_, _| n_cap);
            }
        }
        out
    }

    /// The markers of the cylinder of diameter `d − 2 depth` and length `ℓ − 2 depth`
    /// (same axis and centre; the inner parallel body of a flat-capped cylinder is exactly
    /// that, with sharp rims).
    fn retracted_markers(&self, spacing: f64, depth: f64) -> Result<Vec<Marker>, RetractionError> {
        check_depth(depth)?;
        let d = shrink("cylinder", "diameter", self.diameter, depth)?;
        let l = shrink("cylinder", "length", self.length, depth)?;
        Ok(Cylinder::new(d, l).markers(spacing))
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::rigid::shape::testing::{
        assert_within_5_sigma, check_markers, monte_carlo, nearest_neighbour, sd_gradient,
    };
    use crate::rigid::DEFAULT_MARKER_SPACING;

    #[test]
    fn paper_moments() {
        // physics.md §1: I_axial = m d²/8, I_transverse = m(3d²/4 + ℓ²)/12, m = γ π d² ℓ/4.
        for (d, l) in [(12.0, 12.0), (12.0, 24.0), (12.0, 48.0)] {
            let c = Cylinder::new(d, l);
            let mp = c.mass_properties(1.25);
            let m = 1.25 * PI * d * d * l / 4.0;
            assert!((mp.mass - m).abs() < 1e-12 * m);
            assert!((mp.principal_moments.z - m * d * d / 8.0).abs() < 1e-12 * mp.principal_moments.z);
            let it = m * (3.0 * d * d / 4.0 + l * l) / 12.0;
            assert!((mp.principal_moments.x - it).abs() < 1e-12 * it);
            assert_eq!(mp.principal_moments.x, mp.principal_moments.y);
            assert!(
                (c.surface_area() - (PI * d * l + 2.0 * PI * d * d / 4.0)).abs() < 1e-12 * c.surface_area()
            );
        }
    }

    #[test]
    fn volume_and_moments_against_monte_carlo() {
        // ℓ/d = 2 so that the transverse and axial moments differ.
        let c = Cylinder::new(1.0, 2.0);
        let (est, err) = monte_carlo(&c, Vec3::new(0.5, 0.5, 1.0), 4_000_000, 11);
        let i = c.principal_moments_unit_density();
        let exact = [c.volume(), i.x, i.y, i.z];
        // ≈ 3e-4 relative for the volume with 4e6 samples; a wrong factor (e.g. ℓ² → ℓ²/4) is
        // off by 10 %.
        assert_within_5_sigma(&est, &err, &exact);
    }

    #[test]
    fn signed_distance_properties() {
        let c = Cylinder::new(2.0, 4.0);
        let sd = |x: f64, y: f64, z: f64| c.signed_distance(&Vec3::new(x, y, z));
        assert_eq!(sd(0.0, 0.0, 0.0), -1.0); // nearer the mantle (1) than the caps (2)
        assert_eq!(sd(0.0, 0.0, 1.5), -0.5); // nearer the cap
        assert_eq!(sd(3.0, 0.0, 0.0), 2.0); // radial
        assert_eq!(sd(0.0, 0.0, 5.0), 3.0); // axial
        assert!((sd(4.0, 0.0, 6.0) - 5.0).abs() < 1e-15); // beyond the rim: distance to the edge (3, 4)
                                                          // Eikonal: |∇ sd| = 1 away from the medial surface, by central differences.
        let mut rng = crate::rigid::shape::testing::SplitMix(3);
        for _ in 0..1000 {
            let p = Vec3::new(rng.uniform(-3.0, 3.0), rng.uniform(-3.0, 3.0), rng.uniform(-4.0, 4.0));
            let g = sd_gradient(&c, &p);
            let inside_medial = c.contains(&p) && (1.0 - p.x.hypot(p.y) - (2.0 - p.z.abs())).abs() < 1e-3;
            if !inside_medial && p.x.hypot(p.y) > 1e-3 {
                assert!((g.norm() - 1.0).abs() < 1e-6, "|grad sd| = {} at {p:?}", g.norm());
            }
            assert_eq!(c.contains(&p), sd(p.x, p.y, p.z) < 0.0);
            assert!(sd(p.x, p.y, p.z) >= -c.bounding_radius());
        }
        assert!((c.bounding_radius() - 5f64.sqrt()).abs() < 1e-15);
    }

    #[test]
    fn markers_areas_normals_and_spacing() {
        for (d, l) in [(12.0, 12.0), (12.0, 24.0), (12.0, 48.0), (6.0, 6.0), (6.0, 24.0), (1.0, 0.3)] {
            let c = Cylinder::new(d, l);
            let m = c.markers(DEFAULT_MARKER_SPACING);
            check_markers(&c, &m, 1e-6);
            let nn = nearest_neighbour(&m);
            let lo = nn.iter().copied().fold(f64::INFINITY, f64::min);
            let hi = nn.iter().copied().fold(0.0, f64::max);
            let mean = nn.iter().sum::<f64>() / nn.len() as f64;
            eprintln!(
                "cylinder d={d} l={l}: {} markers, nearest neighbour min {lo:.3} mean {mean:.3} max {hi:.3}",
                m.len()
            );
            if d >= 6.0 {
                assert!(lo >= 0.5 && hi <= 0.9, "d={d} l={l}: nearest neighbour in [{lo}, {hi}]");
            }
        }
    }

    #[test]
    fn markers_follow_the_spacing() {
        let c = Cylinder::new(12.0, 24.0);
        let n07 = c.markers(0.7).len() as f64;
        let n05 = c.markers(0.5).len() as f64;
        // Markers per area ∝ 1/h²: (0.7/0.5)² = 1.96, within the rounding of ring counts.
        assert!((n05 / n07 - 1.96).abs() < 0.1, "{n05} / {n07}");
    }
}
