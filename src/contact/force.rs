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

/// Marker pairs handed to [`PairBatch::evaluate`] at a time: the listed pairs filtered by
/// distance in one chunk of the pair list.
pub(crate) const BATCH: usize = 64;

/// Up to [`BATCH`] marker pairs `(i, j)` (each already within reach) in structure-of-arrays
/// form, and, after [`PairBatch::evaluate`], what [`pair_force`] gives for each: whether it
/// interacts, and its [`Hit`]. With AVX2 the batch is evaluated without branches, 4 pairs at a
/// time, every lane doing [`pair_force`]'s operations in its order (no fused multiply-adds), so
/// each hit is bitwise [`pair_force`]'s (the oracle's, tested); elsewhere it is
/// [`pair_force`] itself, pair by pair.
#[derive(Clone, Debug)]
pub(crate) struct PairBatch {
    len: usize,
    xi: [[f64; BATCH]; 3],
    xj: [[f64; BATCH]; 3],
    ni: [[f64; BATCH]; 3],
    nj: [[f64; BATCH]; 3],
    ui: [[f64; BATCH]; 3],
    uj: [[f64; BATCH]; 3],
    elastic: [[f64; BATCH]; 3],
    lub: [[f64; BATCH]; 3],
    normal: [[f64; BATCH]; 3],
    delta: [f64; BATCH],
    w: [f64; BATCH],
    damping: [f64; BATCH],
    damping_t: [f64; BATCH],
    spring: [f64; BATCH],
    hits: [u8; BATCH],
    n_hits: usize,
}

impl Default for PairBatch {
    fn default() -> Self {
        let z = [[0.0; BATCH]; 3];
        Self {
            len: 0,
            xi: z,
            xj: z,
            ni: z,
            nj: z,
            ui: z,
            uj: z,
            elastic: z,
            lub: z,
            normal: z,
            delta: [0.0; BATCH],
            w: [0.0; BATCH],
            damping: [0.0; BATCH],
            damping_t: [0.0; BATCH],
            spring: [0.0; BATCH],
            hits: [0; BATCH],
            n_hits: 0,
        }
    }
}

impl PairBatch {
    /// Empties the batch.
    #[inline(always)]
    pub fn clear(&mut self) {
        self.len = 0;
    }

    /// Appends the pair of marker `i` and its partner `j` (at most [`BATCH`] pairs).
    #[inline(always)]
    pub fn push(&mut self, i: &WorldMarker, j: &WorldMarker) {
        let l = self.len;
        for c in 0..3 {
            self.xi[c][l] = i.x[c];
            self.xj[c][l] = j.x[c];
            self.ni[c][l] = i.n[c];
            self.nj[c][l] = j.n[c];
            self.ui[c][l] = i.u[c];
            self.uj[c][l] = j.u[c];
        }
        self.len = l + 1;
    }

    /// [`pair_force`] for every pair of the batch; then [`PairBatch::hits`] lists the
    /// interacting ones in order and [`PairBatch::hit`] gives each one's [`Hit`].
    #[inline]
    pub fn evaluate(&mut self, p: &ContactParams) {
        #[cfg(target_arch = "x86_64")]
        if std::is_x86_feature_detected!("avx2") {
            // SAFETY: the processor has AVX2 (checked just above).
            unsafe { self.evaluate_avx2(p) };
            return;
        }
        self.evaluate_scalar(p);
    }

    /// [`PairBatch::evaluate`] pair by pair with [`pair_force`] (the lever arms play no part).
    fn evaluate_scalar(&mut self, p: &ContactParams) {
        let mut m = 0;
        for l in 0..self.len.min(BATCH) {
            let marker = |x: &[[f64; BATCH]; 3], n: &[[f64; BATCH]; 3], u: &[[f64; BATCH]; 3]| {
                let v = |a: &[[f64; BATCH]; 3]| Vec3::new(a[0][l], a[1][l], a[2][l]);
                WorldMarker { index: 0, r: Vec3::zeros(), x: v(x), n: v(n), u: v(u) }
            };
            let (i, j) = (marker(&self.xi, &self.ni, &self.ui), marker(&self.xj, &self.nj, &self.uj));
            if let Some(h) = pair_force(p, &i, &j) {
                for c in 0..3 {
                    self.elastic[c][l] = h.elastic[c];
                    self.lub[c][l] = h.lub[c];
                    self.normal[c][l] = h.normal[c];
                }
                self.delta[l] = h.delta;
                self.w[l] = h.w;
                self.damping[l] = h.damping;
                self.damping_t[l] = h.damping_t;
                self.spring[l] = h.spring;
                self.hits[m] = l as u8;
                m += 1;
            }
        }
        self.n_hits = m;
    }

    /// [`PairBatch::evaluate`] with AVX2, 4 lanes at a time: [`pair_force`] and [`law`] without
    /// branches, one IEEE operation per scalar one in the same order; each early return of
    /// theirs is a term of the lane's mask, with the same ordered comparison (false on NaN), so
    /// NaNs go the same way. The interacting lanes' indices go to `hits` in order.
    ///
    /// # Safety
    /// The processor must have AVX2.
    #[cfg(target_arch = "x86_64")]
    #[target_feature(enable = "avx2")]
    unsafe fn evaluate_avx2(&mut self, p: &ContactParams) {
        use std::arch::x86_64::*;
        let n = self.len.min(BATCH);
        let set = |x: f64| _mm256_set1_pd(x);
        let (k, d0, lam) = (set(p.k), set(p.delta0), set(p.lambda));
        let (k_n, delta_d, delta_sat, k_t) = (set(p.k_n), set(p.delta_d), set(p.delta_sat), set(p.k_t));
        let far2 = set(p.lambda * p.lambda * (1.0 + 1e-6) + 1e-12);
        let (zero, one, tiny) = (_mm256_setzero_pd(), set(1.0), set(1e-24));
        let all = _mm256_castsi256_pd(_mm256_set1_epi64x(-1));
        let on_el = if p.elastic { all } else { zero };
        let on_lub = if p.lubrication { all } else { zero };
        let (add, sub, mul, div) = (
            |a, b| _mm256_add_pd(a, b),
            |a, b| _mm256_sub_pd(a, b),
            |a, b| _mm256_mul_pd(a, b),
            |a, b| _mm256_div_pd(a, b),
        );
        let dot =
            |a: [__m256d; 3], b: [__m256d; 3]| add(add(mul(a[0], b[0]), mul(a[1], b[1])), mul(a[2], b[2]));
        let mut m = 0;
        for o in (0..n).step_by(4) {
            // SAFETY: o + 4 ≤ BATCH (BATCH is a multiple of 4); lanes past `n` hold stale but
            // harmless values and are not read back.
            let ld = |a: &[f64; BATCH]| _mm256_loadu_pd(a.as_ptr().add(o));
            let ld3 = |a: &[[f64; BATCH]; 3]| [ld(&a[0]), ld(&a[1]), ld(&a[2])];
            let st = |a: &mut [f64; BATCH], v| _mm256_storeu_pd(a.as_mut_ptr().add(o), v);
            let (ni, nj) = (ld3(&self.ni), ld3(&self.nj));
            let (xi, xj) = (ld3(&self.xi), ld3(&self.xj));
            let (ui, uj) = (ld3(&self.ui), ld3(&self.uj));
            let not_facing = _mm256_cmp_pd::<_CMP_GT_OQ>(dot(ni, nj), zero);
            let dn = [sub(ni[0], nj[0]), sub(ni[1], nj[1]), sub(ni[2], nj[2])];
            let len2 = dot(dn, dn);
            let d = [sub(xj[0], xi[0]), sub(xj[1], xi[1]), sub(xj[2], xi[2])];
            let s = dot(d, dn);
            let d2 = dot(d, d);
            let far = _mm256_cmp_pd::<_CMP_GE_OQ>(sub(mul(d2, len2), mul(s, s)), mul(far2, len2));
            let root = _mm256_sqrt_pd(len2);
            let h = [div(dn[0], root), div(dn[1], root), div(dn[2], root)];
            let delta = dot(d, h);
            let t = [sub(d[0], mul(h[0], delta)), sub(d[1], mul(h[1], delta)), sub(d[2], mul(h[2], delta))];
            let dl = _mm256_sqrt_pd(dot(t, t));
            let w = div(sub(lam, dl), lam);
            let el = _mm256_and_pd(on_el, _mm256_cmp_pd::<_CMP_LT_OQ>(delta, d0));
            let lb = _mm256_and_pd(on_lub, _mm256_cmp_pd::<_CMP_LT_OQ>(delta, delta_d));
            let reject = _mm256_or_pd(
                _mm256_or_pd(not_facing, _mm256_cmp_pd::<_CMP_LT_OQ>(len2, tiny)),
                _mm256_or_pd(far, _mm256_cmp_pd::<_CMP_GE_OQ>(dl, lam)),
            );
            let ok = _mm256_andnot_pd(reject, _mm256_or_pd(el, lb));
            let bits = _mm256_movemask_pd(ok);
            for q in 0..4.min(n - o) {
                self.hits[m] = (o + q) as u8;
                m += usize::from(bits & (1 << q) != 0);
            }
            let fe = mul(mul(k, sub(d0, delta)), w);
            let ds = _mm256_blendv_pd(delta_sat, delta, _mm256_cmp_pd::<_CMP_GT_OQ>(delta, delta_sat));
            let du = [sub(uj[0], ui[0]), sub(uj[1], ui[1]), sub(uj[2], ui[2])];
            let dun = dot(du, h);
            let g = mul(sub(div(one, ds), div(one, delta_d)), w);
            for c in 0..3 {
                let normal = mul(h[c], dun);
                let tangential = sub(du[c], normal);
                // -(h fe): the sign flipped exactly, as negation does.
                let e = _mm256_xor_pd(mul(h[c], fe), set(-0.0));
                st(&mut self.elastic[c], _mm256_and_pd(el, e));
                st(&mut self.lub[c], _mm256_and_pd(lb, mul(add(mul(normal, k_n), mul(tangential, k_t)), g)));
                st(&mut self.normal[c], h[c]);
            }
            st(&mut self.delta, delta);
            st(&mut self.w, w);
            st(&mut self.spring, _mm256_and_pd(el, mul(k, w)));
            st(&mut self.damping, _mm256_and_pd(lb, mul(k_n, g)));
            st(&mut self.damping_t, _mm256_and_pd(lb, mul(k_t, g)));
        }
        self.n_hits = m;
    }

    /// The interacting pairs of the last [`PairBatch::evaluate`], as indices into the batch
    /// (the order of [`PairBatch::push`]).
    #[inline(always)]
    pub fn hits(&self) -> &[u8] {
        &self.hits[..self.n_hits]
    }

    /// The [`Hit`] of interacting pair `l`: bitwise [`pair_force`]'s.
    #[inline(always)]
    pub fn hit(&self, l: usize) -> Hit {
        let v = |a: &[[f64; BATCH]; 3]| Vec3::new(a[0][l], a[1][l], a[2][l]);
        Hit {
            elastic: v(&self.elastic),
            lub: v(&self.lub),
            normal: v(&self.normal),
            delta: self.delta[l],
            w: self.w[l],
            damping: self.damping[l],
            damping_t: self.damping_t[l],
            spring: self.spring[l],
        }
    }
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

    /// The batch (vectorised where the processor allows, and pair by pair) gives
    /// [`pair_force`]'s answer, bit for bit, for every pair: interacting or not, with either
    /// part switched off, facing or not, coincident normals, and past both ranges.
    #[test]
    fn batch_is_bitwise_pair_force() {
        let mut state = 0x2545_f491_4f6c_dd1d_u64;
        let mut r = move || {
            state ^= state << 13;
            state ^= state >> 7;
            state ^= state << 17;
            (state >> 11) as f64 / (1u64 << 53) as f64 * 2.0 - 1.0
        };
        let mut v = |s: f64| [s * r(), s * r(), s * r()];
        let base = ContactParams::default();
        let variants =
            [base, ContactParams { elastic: false, ..base }, ContactParams { lubrication: false, ..base }];
        for p in &variants {
            let mut checked = [0usize; 2];
            for round in 0..400 {
                let mut batch = PairBatch::default();
                let mut pairs = Vec::new();
                let n = 1 + round % BATCH;
                for k in 0..n {
                    let ni = Vec3::from(v(1.0)).normalize();
                    // Mostly facing normals; some equal (|Δn| = 0), some facing the same way.
                    let nj = match k % 7 {
                        0 => ni,
                        1 => Vec3::from(v(1.0)).normalize(),
                        _ => (-ni + Vec3::from(v(0.3))).normalize(),
                    };
                    let i = wm(v(2.0), ni.into(), v(0.1));
                    // Near i: within both ranges about half the time.
                    let x = i.x + Vec3::from(v(0.6));
                    let j = WorldMarker { n: nj, ..wm(x.into(), [1.0, 0.0, 0.0], v(0.1)) };
                    batch.push(&i, &j);
                    pairs.push((i, j));
                }
                let mut scalar = batch.clone();
                batch.evaluate(p);
                scalar.evaluate_scalar(p);
                let hit_bits = |h: &Hit| {
                    [h.elastic, h.lub, h.normal]
                        .iter()
                        .flat_map(|v| v.iter().map(|x| x.to_bits()).collect::<Vec<_>>())
                        .chain([h.delta, h.w, h.damping, h.damping_t, h.spring].map(f64::to_bits))
                        .collect::<Vec<_>>()
                };
                for b in [&batch, &scalar] {
                    let expected: Vec<usize> = pairs
                        .iter()
                        .enumerate()
                        .filter(|(_, (i, j))| pair_force(p, i, j).is_some())
                        .map(|(l, _)| l)
                        .collect();
                    let got: Vec<usize> = b.hits().iter().map(|&l| l as usize).collect();
                    assert_eq!(got, expected);
                    for &l in &got {
                        let (i, j) = &pairs[l];
                        assert_eq!(hit_bits(&b.hit(l)), hit_bits(&pair_force(p, i, j).unwrap()));
                    }
                    checked[0] += got.len();
                    checked[1] += n - got.len();
                }
            }
            assert!(checked[0] > 1000 && checked[1] > 1000, "too few hits or misses: {checked:?}");
        }
    }

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
