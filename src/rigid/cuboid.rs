//! A rectangular box (cuboid): the flat blades of the pitched-blade turbine.

use super::shape::{check_depth, shrink, Marker, RetractionError, Shape};
use super::{Mat3, Vec3};

/// A solid box with half extents `a = (a_x, a_y, a_z)` along the body axes, centred at the
/// origin.
///
/// Volume `8 a_x a_y a_z`, surface `8 (a_x a_y + a_y a_z + a_z a_x)`, principal moments at unit
/// density `V/3 · (a_y² + a_z², a_z² + a_x², a_x² + a_y²)`.
///
/// Signed distance (exact): with `q = |p| − a` (component-wise),
/// `sd = |max(q, 0)| + min(max(q_x, q_y, q_z), 0)`.
///
/// **Markers** at requested spacing `h`: each face is cut into `n₁ × n₂` equal cells,
/// `n = max(1, round(edge/h))` along each of its edges, with one marker at each cell's centre,
/// the face's outward normal and the cell's area as weight. The weights sum to the surface
/// area exactly; edges and corners carry no marker of their own (the nearest markers sit half
/// a cell, about `h/2`, from an edge, so that the markers of two faces meeting at an edge are
/// about `h/√2` apart).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Cuboid {
    half: Vec3,
}

impl Cuboid {
    /// A box of full edge lengths `size` (each > 0, finite).
    ///
    /// # Panics
    /// If an edge length is not positive and finite.
    pub fn new(size: Vec3) -> Self {
        assert!(
            size.iter().all(|s| s.is_finite() && *s > 0.0),
            "cuboid edge lengths must be positive, got {size:?}"
        );
        Self { half: 0.5 * size }
    }

    /// Half extents `a`.
    pub fn half_extents_body(&self) -> Vec3 {
        self.half
    }
}

impl Shape for Cuboid {
    fn name(&self) -> &'static str {
        "cuboid"
    }

    fn volume(&self) -> f64 {
        8.0 * self.half.x * self.half.y * self.half.z
    }

    fn surface_area(&self) -> f64 {
        let a = self.half;
        8.0 * (a.x * a.y + a.y * a.z + a.z * a.x)
    }

    fn principal_moments_unit_density(&self) -> Vec3 {
        let (v, a) = (self.volume(), self.half);
        Vec3::new(a.y * a.y + a.z * a.z, a.z * a.z + a.x * a.x, a.x * a.x + a.y * a.y) * (v / 3.0)
    }

    fn signed_distance(&self, p: &Vec3) -> f64 {
        let q = p.abs() - self.half;
        q.sup(&Vec3::zeros()).norm() + q.max().min(0.0)
    }

    fn bounding_radius(&self) -> f64 {
        self.half.norm()
    }

    /// The box expanded by `offset` on every face: `e_k = Σ_j |R_kj| (a_j + offset)`.
    fn half_extents(&self, rotation: &Mat3, offset: f64) -> Vec3 {
        let a = self.half.add_scalar(offset);
        rotation.abs() * a
    }

    /// The chord of the box expanded (`offset > 0`; it contains the rounded set
    /// `{sd < offset}`) or shrunk (`offset < 0`; then it *is* that set) by `offset` on every
    /// face: the slab method.
    fn chord(&self, p: &Vec3, dir: &Vec3, offset: f64) -> Option<(f64, f64)> {
        let a = self.half.add_scalar(offset);
        if a.min() <= 0.0 {
            return None;
        }
        let (mut t0, mut t1) = (f64::NEG_INFINITY, f64::INFINITY);
        for k in 0..3 {
            if dir[k].abs() > 1e-300 {
                let (u, v) = ((-a[k] - p[k]) / dir[k], (a[k] - p[k]) / dir[k]);
                t0 = t0.max(u.min(v));
                t1 = t1.min(u.max(v));
            } else if p[k].abs() >= a[k] {
                return None;
            }
        }
        (t0 < t1).then_some((t0, t1))
    }

    fn markers(&self, spacing: f64) -> Vec<Marker> {
        assert!(spacing.is_finite() && spacing > 0.0, "marker spacing must be positive, got {spacing}");
        let a = self.half;
        let mut out = Vec::new();
        for k in 0..3 {
            // The face's two in-plane axes.
            let (i, j) = ((k + 1) % 3, (k + 2) % 3);
            let ni = ((2.0 * a[i] / spacing).round() as usize).max(1);
            let nj = ((2.0 * a[j] / spacing).round() as usize).max(1);
            let (hi, hj) = (2.0 * a[i] / ni as f64, 2.0 * a[j] / nj as f64);
            for sign in [-1.0, 1.0] {
                let mut normal = Vec3::zeros();
                normal[k] = sign;
                for u in 0..ni {
                    for v in 0..nj {
                        let mut position = Vec3::zeros();
                        position[k] = sign * a[k];
                        position[i] = -a[i] + (u as f64 + 0.5) * hi;
                        position[j] = -a[j] + (v as f64 + 0.5) * hj;
                        out.push(Marker { position, normal, area: hi * hj });
                    }
                }
            }
        }
        out
    }

    /// The markers of the box with every edge shortened by `2 depth` (same centre and axes:
    /// the inner parallel body of a box).
    fn retracted_markers(&self, spacing: f64, depth: f64) -> Result<Vec<Marker>, RetractionError> {
        check_depth(depth)?;
        let e = 2.0 * self.half;
        let size = Vec3::new(
            shrink("cuboid", "x edge", e.x, depth)?,
            shrink("cuboid", "y edge", e.y, depth)?,
            shrink("cuboid", "z edge", e.z, depth)?,
        );
        Ok(Cuboid::new(size).markers(spacing))
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::rigid::shape::testing::{
        assert_within_5_sigma, check_markers, monte_carlo, nearest_neighbour, sd_gradient, SplitMix,
    };
    use crate::rigid::{Quat, DEFAULT_MARKER_SPACING};

    #[test]
    fn volume_moments_against_monte_carlo() {
        let c = Cuboid::new(Vec3::new(1.0, 2.0, 0.5));
        let (est, err) = monte_carlo(&c, Vec3::new(0.6, 1.1, 0.3), 2_000_000, 5);
        let i = c.principal_moments_unit_density();
        let exact = [c.volume(), i.x, i.y, i.z];
        assert_within_5_sigma(&est, &err, &exact);
    }

    #[test]
    fn signed_distance_exact_cases_and_eikonal() {
        let c = Cuboid::new(Vec3::new(2.0, 4.0, 6.0));
        let sd = |x: f64, y: f64, z: f64| c.signed_distance(&Vec3::new(x, y, z));
        assert_eq!(sd(0.0, 0.0, 0.0), -1.0);
        assert_eq!(sd(3.0, 0.0, 0.0), 2.0);
        assert!((sd(2.0, 3.0, 0.0) - 2f64.sqrt()).abs() < 1e-15); // beyond an edge
        assert!((sd(2.0, 3.0, 4.0) - 3f64.sqrt()).abs() < 1e-15); // beyond a corner
        let mut rng = SplitMix(9);
        for _ in 0..2000 {
            let p = Vec3::new(rng.uniform(-3.0, 3.0), rng.uniform(-4.0, 4.0), rng.uniform(-5.0, 5.0));
            assert_eq!(c.contains(&p), sd(p.x, p.y, p.z) < 0.0);
            if sd(p.x, p.y, p.z) > 1e-3 {
                let g = sd_gradient(&c, &p);
                assert!((g.norm() - 1.0).abs() < 1e-6, "|grad sd| = {} at {p:?}", g.norm());
            }
        }
    }

    #[test]
    fn chord_and_half_extents_bound_the_set() {
        // Sample points with sd < offset must lie inside the chord of their row and in the
        // world box; for offset < 0 the chord must lie inside the set.
        let c = Cuboid::new(Vec3::new(3.0, 1.0, 5.0));
        let q = Quat::from_euler_angles(0.3, -0.7, 1.1);
        let r = q.to_rotation_matrix().into_inner();
        let mut rng = SplitMix(17);
        for offset in [1.5f64, 0.0, -0.3] {
            let e = c.half_extents(&r, offset.max(0.0));
            for _ in 0..3000 {
                let pw = Vec3::new(rng.uniform(-5.0, 5.0), rng.uniform(-5.0, 5.0), rng.uniform(-5.0, 5.0));
                let pb = r.transpose() * pw;
                let inside = c.signed_distance(&pb) < offset;
                if inside && offset >= 0.0 {
                    assert!((0..3).all(|k| pw[k].abs() <= e[k] + 1e-12), "{pw:?} outside box {e:?}");
                }
                let dir = r.transpose() * Vec3::x();
                let base = pb - dir * 0.37;
                match c.chord(&base, &dir, offset) {
                    Some((t0, t1)) if offset >= 0.0 => {
                        if inside {
                            assert!(t0 <= 0.37 + 1e-12 && 0.37 <= t1 + 1e-12);
                        }
                    }
                    Some((t0, t1)) => {
                        if t0 < 0.37 && 0.37 < t1 {
                            assert!(inside, "subset chord contains an outside point");
                        }
                    }
                    None => assert!(!(inside && offset >= 0.0)),
                }
            }
        }
    }

    #[test]
    fn markers_tile_the_faces() {
        for size in [Vec3::new(52.8, 26.4, 3.0), Vec3::new(26.4, 13.2, 1.5), Vec3::new(0.3, 2.0, 1.0)] {
            let c = Cuboid::new(size);
            let m = c.markers(DEFAULT_MARKER_SPACING);
            check_markers(&c, &m, 1e-6);
            if size.min() >= 1.5 {
                let nn = nearest_neighbour(&m);
                let hi = nn.iter().copied().fold(0.0, f64::max);
                let lo = nn.iter().copied().fold(f64::INFINITY, f64::min);
                assert!(lo >= 0.45 && hi <= 0.8, "{size:?}: nearest neighbour in [{lo}, {hi}]");
            }
        }
    }
}
