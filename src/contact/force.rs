//! The force law of one marker pair and of one marker against a wall (Table 1, with the sign
//! of the module doc), and the body poses both the fast path and the oracle evaluate markers
//! with. Every function here is used by both paths, so that they do the same IEEE operations.

use crate::rigid::{Marker, Mat3, Motion, Quat, RigidBody, Vec3};

use super::params::ContactParams;

/// A body's pose and velocities as the contact evaluation sees them (the body's current state,
/// or the predicted mid-sub-step state of [`super::Contacts::advance`]).
#[derive(Clone, Copy, Debug)]
pub(crate) struct Pose {
    pub position: Vec3,
    pub rotation: Mat3,
    pub velocity: Vec3,
    pub angular_velocity: Vec3,
    pub free: bool,
    /// `1/√I_k` of the principal moments of a free body, zero for a fixed or prescribed one
    /// (infinitely heavy): the rotational mobility of a lever `r` and direction `n̂` is
    /// `|diag(1/√I) Rᵀ (r × n̂)|²` (the lubrication limiter's bound, module `slots`).
    pub inv_sqrt_moments: Vec3,
}

impl Pose {
    /// The body's current state.
    pub fn of(b: &RigidBody) -> Self {
        Self::new(b.position, &b.orientation, b.velocity, b.angular_velocity, b)
    }

    fn new(position: Vec3, q: &Quat, velocity: Vec3, angular_velocity: Vec3, b: &RigidBody) -> Self {
        let free = b.is_free();
        let inv_sqrt_moments =
            if free { b.mass_properties().principal_moments.map(|i| 1.0 / i.sqrt()) } else { Vec3::zeros() };
        Self {
            position,
            rotation: q.to_rotation_matrix().into_inner(),
            velocity,
            angular_velocity,
            free,
            inv_sqrt_moments,
        }
    }

    /// The rotational mobility `(r × n̂)ᵀ I⁻¹ (r × n̂)` of a lever `r` in direction `n̂` (world
    /// frame): the angular response at the marker, along `n̂`, to a unit impulse there.
    #[inline(always)]
    pub fn rotational_mobility(&self, r: &Vec3, nhat: &Vec3) -> f64 {
        let t = self.rotation.tr_mul(&r.cross(nhat));
        t.component_mul(&self.inv_sqrt_moments).norm_squared()
    }

    /// The state at `time + h` predicted from the body's current state: free bodies drift with
    /// their current velocities (`x + h v`, `exp(h ω) q`, velocities unchanged), prescribed
    /// bodies follow their motion exactly, fixed bodies stay.
    pub fn predicted(b: &RigidBody, h: f64) -> Self {
        match b.motion() {
            Motion::Free => Self::new(
                b.position + b.velocity * h,
                &(crate::rigid::integrate::rotation_quaternion(&(b.angular_velocity * h)) * b.orientation),
                b.velocity,
                b.angular_velocity,
                b,
            ),
            Motion::Prescribed(m) => {
                let (dx, dq) = m.displacement(b.time, h);
                let t = b.time + h;
                Self::new(b.position + dx, &(dq * b.orientation), m.velocity(t), m.angular_velocity(t), b)
            }
            Motion::Fixed => Self::of(b),
        }
    }

    /// Lever arm `r = R m` and world position `x + r` of a marker.
    #[inline(always)]
    pub fn marker_position(&self, m: &Marker) -> (Vec3, Vec3) {
        let r = self.rotation * m.position;
        (r, self.position + r)
    }

    /// World normal `R n` and velocity `v + ω × r` of a marker with lever arm `r`.
    #[inline(always)]
    pub fn marker_normal_velocity(&self, m: &Marker, r: &Vec3) -> (Vec3, Vec3) {
        (self.rotation * m.normal, self.velocity + self.angular_velocity.cross(r))
    }
}

/// A marker in the world frame.
#[derive(Clone, Copy, Debug)]
pub(crate) struct WorldMarker {
    pub index: u32,
    /// Lever arm `x − x_body` (as `R m`, exact to rounding of the rotation).
    pub r: Vec3,
    pub x: Vec3,
    pub n: Vec3,
    pub u: Vec3,
}

/// The force on marker `i` from marker `j` (module doc), or `None` if the pair does not
/// interact: normals that do not face each other (`n_i·n_j > 0`, or `|n_i − n_j| < 1e-12`),
/// tangential distance `δ_λ ≥ λ`, or neither part active at this `δ`. The caller has already
/// checked `|x_j − x_i| < reach`.
#[inline(always)]
pub(crate) fn pair_force(p: &ContactParams, i: &WorldMarker, j: &WorldMarker) -> Option<Hit> {
    if i.n.dot(&j.n) > 0.0 {
        return None;
    }
    let dn = i.n - j.n;
    let len2 = dn.norm_squared();
    if len2 < 1e-24 {
        return None;
    }
    let d = j.x - i.x;
    // Cheap rejection (no square root) of the pairs far outside δ_λ < λ, with a relative
    // margin of 1e-6 over the rounding of `|d|² − (d·Δn)²/|Δn|²`; the exact test follows.
    // Multiplied through by `|Δn|² > 0` (no division on this path, which most listed pairs
    // take): `|d|²|Δn|² − (d·Δn)² ≥ (λ²(1 + 1e-6) + 1e-12)|Δn|²`.
    let s = d.dot(&dn);
    if d.norm_squared() * len2 - s * s >= (p.lambda * p.lambda * (1.0 + 1e-6) + 1e-12) * len2 {
        return None;
    }
    let nhat = dn / len2.sqrt();
    let delta = d.dot(&nhat);
    let dl = (d - nhat * delta).norm();
    if dl >= p.lambda {
        return None;
    }
    let w = (p.lambda - dl) / p.lambda;
    law(p, &nhat, delta, w, &(j.u - i.u))
}

/// An interacting marker pair (or marker and wall): the force on the marker in its two parts,
/// the elastic `elastic` and the lubrication `lub` (summed apart: the lubrication limiter
/// scales the second per body pair, module [`super`], "Lubrication limiter"), the contact
/// normal `n̂`, `δ`, `w`, and the pair's normal and tangential damping coefficients
/// `kⁿ (1/δ* − 1/δ_d) w`, `kᵗ (1/δ* − 1/δ_d) w` (0 beyond `δ_d` or with the lubrication off)
/// and spring constant `k w` (0 beyond `δ0` or with the elastic part off):
/// `−∂F·n̂/∂(Δu·n̂)`, `−∂F·t̂/∂(Δu·t̂)` and `−∂F·n̂/∂δ` at fixed `n̂` and `w`, what the
/// sub-step's stability depends on ([`super::ContactStats::damping_rate`]), formed from the
/// law's own factors.
#[derive(Clone, Copy, Debug)]
pub(crate) struct Hit {
    pub elastic: Vec3,
    pub lub: Vec3,
    pub normal: Vec3,
    pub delta: f64,
    pub w: f64,
    pub damping: f64,
    pub damping_t: f64,
    pub spring: f64,
}

impl Hit {
    /// The whole force on the marker, `elastic + lub`.
    #[cfg(test)]
    pub fn force(&self) -> Vec3 {
        self.elastic + self.lub
    }

    /// The pair's elastic energy `½ k (δ0 − δ)² w` (0 if the elastic part is off or `δ ≥ δ0`),
    /// a diagnostic: the elastic force is not its exact gradient (`w` and `n̂` vary too).
    #[inline(always)]
    pub fn elastic_energy(&self, p: &ContactParams) -> f64 {
        if p.elastic && self.delta < p.delta0 {
            0.5 * p.k * (p.delta0 - self.delta) * (p.delta0 - self.delta) * self.w
        } else {
            0.0
        }
    }
}

/// The force on a marker (position `x`, normal `n`, velocity `u`) from the wall with plane
/// coordinate `plane` on `axis` and outward normal `nhat` (`±e_axis`): `δ` is the distance from
/// the marker to the plane (negative beyond it), `δ_λ = 0` (`w = 1`), the wall is at rest.
/// `None` if the marker's normal does not face the wall (`n·n̂ ≤ 0`) or no part acts.
#[inline(always)]
pub(crate) fn wall_force(
    p: &ContactParams,
    axis: usize,
    plane: f64,
    nhat: &Vec3,
    x: &Vec3,
    n: &Vec3,
    u: &Vec3,
) -> Option<Hit> {
    if n.dot(nhat) <= 0.0 {
        return None;
    }
    let delta = wall_distance(axis, plane, nhat, x);
    law(p, nhat, delta, 1.0, &(-u))
}

/// Distance from `x` to the wall plane, measured into the fluid (negative beyond the wall).
#[inline(always)]
pub(crate) fn wall_distance(axis: usize, plane: f64, nhat: &Vec3, x: &Vec3) -> f64 {
    if nhat[axis] < 0.0 {
        x[axis] - plane
    } else {
        plane - x[axis]
    }
}

/// Table 1 for given `n̂` (from `i` toward its partner), `δ`, weight `w` and relative velocity
/// `Δu = u_partner − u_i`: the force on `i`, and the pair's stiffness ([`Hit`]).
#[inline(always)]
fn law(p: &ContactParams, nhat: &Vec3, delta: f64, w: f64, du: &Vec3) -> Option<Hit> {
    let elastic = p.elastic && delta < p.delta0;
    let lub = p.lubrication && delta < p.delta_d;
    if !elastic && !lub {
        return None;
    }
    let mut h = Hit {
        elastic: Vec3::zeros(),
        lub: Vec3::zeros(),
        normal: *nhat,
        delta,
        w,
        damping: 0.0,
        damping_t: 0.0,
        spring: 0.0,
    };
    if elastic {
        h.elastic = -(nhat * (p.k * (p.delta0 - delta) * w));
        h.spring = p.k * w;
    }
    if lub {
        let ds = delta.max(p.delta_sat);
        let dun = nhat * du.dot(nhat);
        let dut = du - dun;
        let g = (1.0 / ds - 1.0 / p.delta_d) * w;
        h.lub = (dun * p.k_n + dut * p.k_t) * g;
        h.damping = p.k_n * g;
        h.damping_t = p.k_t * g;
    }
    Some(h)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn wm(x: [f64; 3], n: [f64; 3], u: [f64; 3]) -> WorldMarker {
        WorldMarker {
            index: 0,
            r: Vec3::zeros(),
            x: Vec3::from(x),
            n: Vec3::from(n).normalize(),
            u: Vec3::from(u),
        }
    }

    #[test]
    fn facing_markers_repel_and_damp_approach() {
        let p = ContactParams::default();
        // i at the origin facing +x, j at x = 0.3 facing −x: δ = 0.3, δ_λ = 0, w = 1.
        let i = wm([0.0; 3], [1.0, 0.0, 0.0], [0.0; 3]);
        let j = wm([0.3, 0.0, 0.0], [-1.0, 0.0, 0.0], [-0.01, 0.0, 0.0]);
        let h = pair_force(&p, &i, &j).unwrap();
        let f = h.force();
        assert!((h.delta - 0.3).abs() < 1e-15 && h.w == 1.0);
        // Elastic −k(δ0 − δ) = −1; lubrication kⁿ Δu (1/0.3 − 1) = 5 · (−0.01) · 2.333.
        let expect = -1.0 + 5.0 * -0.01 * (1.0 / 0.3 - 1.0);
        assert!((f.x - expect).abs() < 1e-14, "{f:?}");
        assert_eq!((f.y, f.z), (0.0, 0.0));
        // Newton's third law by symmetry of the formula.
        let g = pair_force(&p, &j, &i).unwrap().force();
        assert!((f + g).norm() < 1e-15);
    }

    #[test]
    fn saturation_tangential_weight_and_cutoffs() {
        let p = ContactParams { elastic: false, ..Default::default() };
        let i = wm([0.0; 3], [0.0, 0.0, 1.0], [0.0; 3]);
        // Tangential slip only, δ = 0.1 < δ_sat: coefficient kᵗ (1/0.2 − 1) w with δ_λ = 0.25.
        let j = wm([0.25, 0.0, 0.1], [0.0, 0.0, -1.0], [0.0, 0.02, 0.0]);
        let f = pair_force(&p, &i, &j).unwrap().force();
        assert!((f.y - 0.5 * 0.02 * 4.0 * 0.5).abs() < 1e-15, "{f:?}");
        // Beyond λ, beyond δ_d, same-side normals: nothing.
        assert!(pair_force(&p, &i, &wm([0.5, 0.0, 0.1], [0.0, 0.0, -1.0], [0.0; 3])).is_none());
        assert!(pair_force(&p, &i, &wm([0.0, 0.0, 1.0], [0.0, 0.0, -1.0], [0.0; 3])).is_none());
        assert!(pair_force(&p, &i, &wm([0.0, 0.0, 0.1], [0.0, 0.1, 1.0], [0.0; 3])).is_none());
    }

    #[test]
    fn wall_pushes_out() {
        let p = ContactParams::default();
        let nhat = Vec3::new(0.0, 0.0, -1.0); // the floor
        let x = Vec3::new(3.0, 4.0, -0.5 + 0.25);
        let h = wall_force(&p, 2, -0.5, &nhat, &x, &Vec3::new(0.0, 0.0, -1.0), &Vec3::zeros()).unwrap();
        let f = h.force();
        assert!((h.delta - 0.25).abs() < 1e-15);
        assert!((f.z - 5.0 * 0.25).abs() < 1e-14 && f.x == 0.0);
        // A marker whose normal points away from the wall does not feel it.
        assert!(wall_force(&p, 2, -0.5, &nhat, &x, &Vec3::new(0.0, 0.0, 1.0), &Vec3::zeros()).is_none());
    }
}
