//! Initial particle placement: a certified minimal-distance test between spheres and finite
//! cylinders, a cell list over the box, and random sequential placement.
//!
//! **Distance test** ([`apart`]): whether two convex bodies are at least a clearance apart,
//! with a *certified* yes: a pair is accepted only when a lower bound on their distance is
//! at least the clearance, so an accepted pair never overlaps. Three stages, cheapest first:
//!
//! 1. bounding spheres (`|c_a − c_b| − r_a − r_b`, exact for two spheres);
//! 2. capsules: a cylinder lies inside the capsule of its axis segment and radius, so the
//!    segment–segment distance minus both radii is a lower bound on the cylinders' distance;
//! 3. GJK (Gilbert, Johnson & Keerthi 1988) on the exact support functions of the flat-capped
//!    cylinders: every iteration gives an upper bound `|v|` (a point of the Minkowski
//!    difference) and a lower bound `v·w/|v|` (the support plane); it stops as soon as one
//!    of them decides. Undecided after [`GJK_ITERATIONS`] (a pair within round-off of the
//!    clearance) counts as "too close": the test errs only on the safe side.
//!
//! **Cell list** ([`CellList`]): cells at least as wide as the largest interaction reach
//! (largest bounding diameter plus the largest clearance), so the candidates of a particle are
//! in the 3 × 3 × 3 cells around its centre; periodic axes wrap, and every periodic image
//! within reach is tested.
//!
//! **Random placement** ([`place_random`]): random sequential addition. Each attempt draws an
//! orientation uniform on SO(3) (Shoemake's quaternion: the axis is uniform on the sphere)
//! and a centre uniform in the region, rejects it if the particle's axis-aligned bounding box
//! leaves the region (the same as the particle leaving it, the region being a box) or if it
//! comes closer than the clearance to any particle already placed, and otherwise keeps it. So
//! the accepted configurations are uniform over the admissible ones, conditioned on the
//! earlier particles. A particle that fails [`MAX_FAILED_ATTEMPTS`] attempts in a row ends
//! the placement with [`PlacementFailure`]. Deterministic for a given seed (one
//! [`SplitMix64`] stream per population, draws in a fixed order, serial); the orientation
//! draws use the platform's `sin`/`cos`, so another platform's math library could move a
//! particle in the last bits.

use crate::rigid::{Quat, Vec3};
use crate::util::SplitMix64;

/// GJK iterations before a pair counts as undecided (and so as too close).
pub const GJK_ITERATIONS: usize = 64;

/// Consecutive failed attempts after which random placement of a particle gives up.
pub const MAX_FAILED_ATTEMPTS: u64 = 10_000;

/// Largest number of cells of a [`CellList`] along one axis (bounds its memory).
pub const MAX_CELLS_PER_AXIS: usize = 64;

/// A convex body in world coordinates, for the distance test.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Convex {
    /// Sphere of centre `c` and radius `r`.
    Sphere {
        /// Centre.
        c: Vec3,
        /// Radius.
        r: f64,
    },
    /// Flat-capped cylinder of centre `c`, unit axis `a`, radius `r`, half-length `h`.
    Cylinder {
        /// Centre.
        c: Vec3,
        /// Unit axis.
        a: Vec3,
        /// Radius.
        r: f64,
        /// Half-length.
        h: f64,
    },
}

impl Convex {
    /// The centre.
    pub fn centre(&self) -> Vec3 {
        match *self {
            Convex::Sphere { c, .. } | Convex::Cylinder { c, .. } => c,
        }
    }

    /// Radius of the bounding sphere about the centre.
    pub fn bounding_radius(&self) -> f64 {
        match *self {
            Convex::Sphere { r, .. } => r,
            Convex::Cylinder { r, h, .. } => r.hypot(h),
        }
    }

    /// The same body moved by `s`.
    pub fn translated(&self, s: Vec3) -> Convex {
        match *self {
            Convex::Sphere { c, r } => Convex::Sphere { c: c + s, r },
            Convex::Cylinder { c, a, r, h } => Convex::Cylinder { c: c + s, a, r, h },
        }
    }

    /// Half extents of the axis-aligned bounding box (exact for both shapes).
    pub fn half_extents(&self) -> Vec3 {
        match *self {
            Convex::Sphere { r, .. } => Vec3::repeat(r),
            Convex::Cylinder { a, r, h, .. } => {
                Vec3::from_fn(|k, _| h * a[k].abs() + r * (1.0 - a[k] * a[k]).max(0.0).sqrt())
            }
        }
    }

    /// A point of the body farthest along `d` (the support mapping).
    fn support(&self, d: &Vec3) -> Vec3 {
        match *self {
            Convex::Sphere { c, r } => {
                let n = d.norm();
                if n > 0.0 {
                    c + d * (r / n)
                } else {
                    c
                }
            }
            Convex::Cylinder { c, a, r, h } => {
                let da = d.dot(&a);
                let perp = d - a * da;
                let pn = perp.norm();
                let cap = if da >= 0.0 { a * h } else { -a * h };
                let rim = if pn > 1e-300 { perp * (r / pn) } else { Vec3::zeros() };
                c + cap + rim
            }
        }
    }

    /// The core segment (end points) and radius of the capsule that contains the body.
    fn capsule(&self) -> (Vec3, Vec3, f64) {
        match *self {
            Convex::Sphere { c, r } => (c, c, r),
            Convex::Cylinder { c, a, r, h } => (c - a * h, c + a * h, r),
        }
    }
}

/// Whether `a` and `b` are certainly at least `clearance` apart (surface to surface). `false`
/// when they are closer, overlap, or the test could not decide (module docs).
pub fn apart(a: &Convex, b: &Convex, clearance: f64) -> bool {
    let dc = (a.centre() - b.centre()).norm();
    let gap = dc - a.bounding_radius() - b.bounding_radius();
    if gap >= clearance {
        return true;
    }
    if let (Convex::Sphere { .. }, Convex::Sphere { .. }) = (a, b) {
        return false;
    }
    let (p1, q1, r1) = a.capsule();
    let (p2, q2, r2) = b.capsule();
    if segment_distance(&p1, &q1, &p2, &q2) - r1 - r2 >= clearance {
        return true;
    }
    gjk_apart(a, b, clearance)
}

/// Distance between the segments `[p1, q1]` and `[p2, q2]` (either may be a point).
/// Ericson, "Real-Time Collision Detection" (2005), §5.1.9.
fn segment_distance(p1: &Vec3, q1: &Vec3, p2: &Vec3, q2: &Vec3) -> f64 {
    let d1 = q1 - p1;
    let d2 = q2 - p2;
    let r = p1 - p2;
    let a = d1.dot(&d1);
    let e = d2.dot(&d2);
    let f = d2.dot(&r);
    let eps = 1e-300;
    let (s, t);
    if a <= eps && e <= eps {
        return r.norm();
    }
    if a <= eps {
        s = 0.0;
        t = (f / e).clamp(0.0, 1.0);
    } else {
        let c = d1.dot(&r);
        if e <= eps {
            t = 0.0;
            s = (-c / a).clamp(0.0, 1.0);
        } else {
            let b = d1.dot(&d2);
            let denom = a * e - b * b;
            let mut s0 = if denom > 0.0 { ((b * f - c * e) / denom).clamp(0.0, 1.0) } else { 0.0 };
            let mut t0 = (b * s0 + f) / e;
            if t0 < 0.0 {
                t0 = 0.0;
                s0 = (-c / a).clamp(0.0, 1.0);
            } else if t0 > 1.0 {
                t0 = 1.0;
                s0 = ((b - c) / a).clamp(0.0, 1.0);
            }
            s = s0;
            t = t0;
        }
    }
    ((p1 + d1 * s) - (p2 + d2 * t)).norm()
}

/// GJK on the Minkowski difference `A − B`: decides `dist(A, B) ≥ clearance` (module docs).
fn gjk_apart(a: &Convex, b: &Convex, clearance: f64) -> bool {
    let support = |d: &Vec3| a.support(d) - b.support(&-d);
    let mut v = a.centre() - b.centre();
    if v.norm() == 0.0 {
        v = Vec3::x();
    }
    let mut simplex: Vec<Vec3> = Vec::with_capacity(4);
    simplex.push(support(&-v));
    v = simplex[0];
    for _ in 0..GJK_ITERATIONS {
        let vn = v.norm();
        // |v| is the length of a point of A − B: an upper bound on the distance.
        if vn < clearance || vn == 0.0 {
            return false;
        }
        let w = support(&-v);
        // Every point x of A − B has v·x ≥ v·w, so |x| ≥ v·w/|v|: a lower bound.
        let vw = v.dot(&w);
        if vw / vn >= clearance {
            return true;
        }
        // No progress possible: converged (to within round-off) without a decision.
        if vn * vn - vw <= 1e-12 * vn * vn || simplex.iter().any(|p| (p - w).norm() <= 1e-12 * (1.0 + vn)) {
            return false;
        }
        simplex.push(w);
        let (closest, kept) = closest_on_simplex(&simplex);
        // A tetrahedron whose closest point lies inside it encloses the origin: the bodies
        // overlap (or touch to within round-off, where `v` is a rounding residue that a
        // clearance of 0 would not stop). Not apart, and no fifth vertex.
        if kept.len() == 4 {
            return false;
        }
        v = closest;
        simplex = kept;
    }
    false
}

/// The point of the convex hull of `points` (1 to 4) closest to the origin, and the vertices
/// of the smallest face that holds it. Brute force over the faces: the closest point of the
/// hull is the shortest of the affine-hull closest points that lie inside their face.
fn closest_on_simplex(points: &[Vec3]) -> (Vec3, Vec<Vec3>) {
    let n = points.len();
    let mut best: Option<(f64, Vec3, u32)> = None;
    for mask in 1u32..(1 << n) {
        let idx: Vec<usize> = (0..n).filter(|i| mask & (1 << i) != 0).collect();
        let Some(lambda) = affine_closest(points, &idx) else { continue };
        if lambda.iter().any(|&l| l <= 0.0) {
            continue;
        }
        let p: Vec3 = idx.iter().zip(&lambda).map(|(&i, &l)| points[i] * l).sum();
        let d = p.norm_squared();
        let better = match best {
            None => true,
            Some((bd, _, bm)) => d < bd || (d == bd && mask.count_ones() < bm.count_ones()),
        };
        if better {
            best = Some((d, p, mask));
        }
    }
    // A single vertex always qualifies (λ = 1), so `best` is set.
    let (_, p, mask) = best.unwrap_or((0.0, points[0], 1));
    let kept = (0..n).filter(|i| mask & (1 << i) != 0).map(|i| points[i]).collect();
    (p, kept)
}

/// Barycentric coordinates of the point of the affine hull of `points[idx]` closest to the
/// origin; `None` when the points are (nearly) affinely dependent.
fn affine_closest(points: &[Vec3], idx: &[usize]) -> Option<Vec<f64>> {
    let p0 = points[idx[0]];
    let k = idx.len() - 1;
    if k == 0 {
        return Some(vec![1.0]);
    }
    let e: Vec<Vec3> = idx[1..].iter().map(|&i| points[i] - p0).collect();
    // Normal equations G μ = −Eᵀ p0, with G_ij = e_i·e_j.
    let mut m = [[0.0f64; 4]; 3];
    let mut scale = 0.0f64;
    for i in 0..k {
        for j in 0..k {
            m[i][j] = e[i].dot(&e[j]);
        }
        m[i][k] = -e[i].dot(&p0);
        scale = scale.max(m[i][i]);
    }
    // Gaussian elimination with partial pivoting.
    for col in 0..k {
        let piv = (col..k).max_by(|&x, &y| m[x][col].abs().total_cmp(&m[y][col].abs()))?;
        if m[piv][col].abs() <= 1e-12 * scale {
            return None;
        }
        m.swap(col, piv);
        for row in col + 1..k {
            let f = m[row][col] / m[col][col];
            for c in col..=k {
                m[row][c] -= f * m[col][c];
            }
        }
    }
    let mut mu = [0.0f64; 3];
    for row in (0..k).rev() {
        let mut s = m[row][k];
        for c in row + 1..k {
            s -= m[row][c] * mu[c];
        }
        mu[row] = s / m[row][row];
    }
    let mut lambda = vec![1.0 - mu[..k].iter().sum::<f64>()];
    lambda.extend_from_slice(&mu[..k]);
    Some(lambda)
}

/// The box and its periodicity, as placement sees it: node coordinates `0 … n − 1` on each
/// axis, walls half a spacing outside, periodic axes of period `n`.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct BoxGeometry {
    /// Nodes per axis.
    pub n: [usize; 3],
    /// Periodic axes.
    pub periodic: [bool; 3],
}

/// Particles placed so far, binned by centre for neighbour queries (module docs).
#[derive(Clone, Debug)]
pub struct CellList {
    geometry: BoxGeometry,
    cells_per_axis: [usize; 3],
    width: [f64; 3],
    cells: Vec<Vec<u32>>,
    bodies: Vec<Convex>,
}

impl CellList {
    /// An empty list for bodies whose pairs interact (bounding spheres plus clearance) within
    /// `reach` of their centres. At most [`MAX_CELLS_PER_AXIS`] cells per axis (wider cells
    /// only add candidates).
    pub fn new(geometry: BoxGeometry, reach: f64) -> Self {
        let reach = if reach.is_finite() && reach > 0.0 { reach } else { 1.0 };
        let cells_per_axis: [usize; 3] = std::array::from_fn(|a| {
            ((geometry.n[a] as f64 / reach).floor() as usize).clamp(1, MAX_CELLS_PER_AXIS)
        });
        let width = std::array::from_fn(|a| geometry.n[a] as f64 / cells_per_axis[a] as f64);
        let total = cells_per_axis.iter().product();
        Self { geometry, cells_per_axis, width, cells: vec![Vec::new(); total], bodies: Vec::new() }
    }

    /// Bodies inserted so far, in insertion order.
    pub fn bodies(&self) -> &[Convex] {
        &self.bodies
    }

    fn cell_of(&self, c: &Vec3) -> [usize; 3] {
        std::array::from_fn(|a| {
            let i = ((c[a] + 0.5) / self.width[a]).floor();
            (i.max(0.0) as usize).min(self.cells_per_axis[a] - 1)
        })
    }

    /// Adds `body` (no test).
    pub fn insert(&mut self, body: Convex) {
        let [i, j, k] = self.cell_of(&body.centre());
        let [mx, my, _] = self.cells_per_axis;
        self.cells[(k * my + j) * mx + i].push(self.bodies.len() as u32);
        self.bodies.push(body);
    }

    /// The first inserted body (lowest index) that `body` comes closer to than `clearance`,
    /// counting periodic images; `None` if it is clear of all.
    pub fn first_conflict(&self, body: &Convex, clearance: f64) -> Option<usize> {
        let mut hit: Option<usize> = None;
        self.visit_candidates(body, |other| {
            if hit.is_none_or(|h| other < h) && !self.clear_of(body, &self.bodies[other], clearance) {
                hit = Some(other);
            }
            true
        });
        hit
    }

    /// Whether `body` comes closer than `clearance` to any inserted body (stops at the first).
    pub fn conflicts(&self, body: &Convex, clearance: f64) -> bool {
        let mut hit = false;
        self.visit_candidates(body, |other| {
            hit = !self.clear_of(body, &self.bodies[other], clearance);
            !hit
        });
        hit
    }

    /// Calls `f` with the index of every inserted body in the cells around `body`'s centre
    /// (each once) while `f` returns `true`.
    fn visit_candidates(&self, body: &Convex, mut f: impl FnMut(usize) -> bool) {
        let cell = self.cell_of(&body.centre());
        let ranges: [Vec<usize>; 3] = std::array::from_fn(|a| {
            let m = self.cells_per_axis[a];
            let i = cell[a];
            let mut v: Vec<usize> = if self.geometry.periodic[a] {
                [i + m - 1, i, i + 1].iter().map(|x| x % m).collect()
            } else {
                (i.saturating_sub(1)..=(i + 1).min(m - 1)).collect()
            };
            v.sort_unstable();
            v.dedup();
            v
        });
        let [mx, my, _] = self.cells_per_axis;
        for &k in &ranges[2] {
            for &j in &ranges[1] {
                for &i in &ranges[0] {
                    for &other in &self.cells[(k * my + j) * mx + i] {
                        if !f(other as usize) {
                            return;
                        }
                    }
                }
            }
        }
    }

    /// Whether `a` is at least `clearance` from `b` and from every periodic image of `b`.
    fn clear_of(&self, a: &Convex, b: &Convex, clearance: f64) -> bool {
        let reach = a.bounding_radius() + b.bounding_radius() + clearance;
        let d = a.centre() - b.centre();
        let shifts: [Vec<f64>; 3] = std::array::from_fn(|ax| {
            if !self.geometry.periodic[ax] {
                return vec![0.0];
            }
            let n = self.geometry.n[ax] as f64;
            [-n, 0.0, n].into_iter().filter(|s| (d[ax] - s).abs() < reach).collect()
        });
        for &sz in &shifts[2] {
            for &sy in &shifts[1] {
                for &sx in &shifts[0] {
                    let image = b.translated(Vec3::new(sx, sy, sz));
                    if !apart(a, &image, clearance) {
                        return false;
                    }
                }
            }
        }
        true
    }
}

/// The shape of a population, as placement needs it.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum ShapeDims {
    /// Sphere of this diameter.
    Sphere {
        /// Diameter.
        diameter: f64,
    },
    /// Cylinder of this diameter and length.
    Cylinder {
        /// Diameter.
        diameter: f64,
        /// Length.
        length: f64,
    },
}

impl ShapeDims {
    /// The body at centre `c` with orientation `q` (body `z` = the cylinder axis).
    pub fn at(&self, c: Vec3, q: &Quat) -> Convex {
        match *self {
            ShapeDims::Sphere { diameter } => Convex::Sphere { c, r: 0.5 * diameter },
            ShapeDims::Cylinder { diameter, length } => {
                Convex::Cylinder { c, a: q * Vec3::z(), r: 0.5 * diameter, h: 0.5 * length }
            }
        }
    }

    /// Radius of the bounding sphere.
    pub fn bounding_radius(&self) -> f64 {
        match *self {
            ShapeDims::Sphere { diameter } => 0.5 * diameter,
            ShapeDims::Cylinder { diameter, length } => (0.5 * diameter).hypot(0.5 * length),
        }
    }

    /// The smallest half extent along any axis over all orientations.
    fn min_half_extent(&self) -> f64 {
        match *self {
            ShapeDims::Sphere { diameter } => 0.5 * diameter,
            ShapeDims::Cylinder { diameter, length } => 0.5 * diameter.min(length),
        }
    }
}

/// A random population to place.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct RandomRequest {
    /// Shape and size.
    pub shape: ShapeDims,
    /// How many.
    pub count: usize,
    /// Seed of the population's random stream.
    pub seed: u64,
    /// Per axis, the interval the whole particle must lie in; `None`: a periodic axis whose
    /// whole period is open (centres uniform over it, particles may cross the boundary).
    pub region: [Option<(f64, f64)>; 3],
    /// Smallest surface-to-surface distance to any other particle.
    pub clearance: f64,
}

/// Random placement stopped: a particle found no place in [`MAX_FAILED_ATTEMPTS`] attempts.
#[derive(Clone, Debug, PartialEq)]
pub struct PlacementFailure {
    /// Particles of the population placed before it stopped.
    pub placed: usize,
    /// Attempts made in all.
    pub attempts: u64,
}

/// A uniformly random rotation (Shoemake 1992, "Uniform random rotations", Graphics Gems III).
pub fn random_rotation(rng: &mut SplitMix64) -> Quat {
    let (u1, u2, u3) = (rng.unit(), rng.unit(), rng.unit());
    let tau = std::f64::consts::TAU;
    let (a, b) = ((1.0 - u1).sqrt(), u1.sqrt());
    let q = nalgebra::Quaternion::new(
        b * (tau * u3).cos(),
        a * (tau * u2).sin(),
        a * (tau * u2).cos(),
        b * (tau * u3).sin(),
    );
    Quat::from_quaternion(q)
}

/// Places `req.count` particles at random into `cells` (which holds the particles placed
/// before; the new ones are inserted), returning their centres and orientations in order.
pub fn place_random(
    cells: &mut CellList,
    req: &RandomRequest,
) -> Result<Vec<(Vec3, Quat)>, PlacementFailure> {
    let mut rng = SplitMix64(req.seed);
    let g = cells.geometry;
    // Centres are drawn in a box that holds every admissible centre (whatever the
    // orientation), then the exact containment test rejects the rest: uniform over the
    // admissible configurations.
    let emin = req.shape.min_half_extent();
    let draw_range: [(f64, f64); 3] = std::array::from_fn(|a| match req.region[a] {
        Some((lo, hi)) => (lo + emin, hi - emin),
        None => (-0.5, g.n[a] as f64 - 0.5),
    });
    let mut out = Vec::with_capacity(req.count);
    let mut attempts = 0u64;
    while out.len() < req.count {
        let mut fails = 0u64;
        loop {
            if fails >= MAX_FAILED_ATTEMPTS {
                return Err(PlacementFailure { placed: out.len(), attempts });
            }
            attempts += 1;
            fails += 1;
            let q = random_rotation(&mut rng);
            let c = Vec3::from_fn(|a, _| {
                let (lo, hi) = draw_range[a];
                if lo <= hi {
                    rng.uniform(lo, hi)
                } else {
                    f64::NAN
                }
            });
            if c.iter().any(|x| x.is_nan()) {
                continue;
            }
            let body = req.shape.at(c, &q);
            let e = body.half_extents();
            let inside = (0..3).all(|a| match req.region[a] {
                Some((lo, hi)) => c[a] - e[a] >= lo && c[a] + e[a] <= hi,
                None => true,
            });
            if !inside || cells.conflicts(&body, req.clearance) {
                continue;
            }
            cells.insert(body);
            out.push((c, q));
            break;
        }
    }
    Ok(out)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn cyl(c: [f64; 3], a: [f64; 3], d: f64, l: f64) -> Convex {
        Convex::Cylinder { c: Vec3::from(c), a: Vec3::from(a).normalize(), r: 0.5 * d, h: 0.5 * l }
    }

    /// Brute-force distance between two cylinders: the smallest distance between surface
    /// samples of each (an over-estimate by at most the sampling gap).
    fn sampled_distance(a: &Convex, b: &Convex) -> f64 {
        let pts = |x: &Convex| -> Vec<Vec3> {
            let Convex::Cylinder { c, a, r, h } = *x else { unreachable!() };
            let u = a.cross(&if a.x.abs() < 0.9 { Vec3::x() } else { Vec3::y() }).normalize();
            let w = a.cross(&u);
            let mut v = Vec::new();
            let n = 48;
            for i in 0..n {
                let t = std::f64::consts::TAU * i as f64 / n as f64;
                let dir = u * t.cos() + w * t.sin();
                for k in 0..=24 {
                    let z = -h + 2.0 * h * k as f64 / 24.0;
                    v.push(c + a * z + dir * r);
                }
                for k in 0..=8 {
                    let rr = r * k as f64 / 8.0;
                    v.push(c + a * h + dir * rr);
                    v.push(c - a * h + dir * rr);
                }
            }
            v
        };
        let (pa, pb) = (pts(a), pts(b));
        let mut best = f64::INFINITY;
        for p in &pa {
            for q in &pb {
                best = best.min((p - q).norm());
            }
        }
        best
    }

    #[test]
    fn parallel_cylinders_side_by_side() {
        // Axes 13 apart, radii 6: gap 1 exactly (line contact geometry).
        let a = cyl([0.0, 0.0, 0.0], [0.0, 0.0, 1.0], 12.0, 48.0);
        let b = cyl([13.0, 0.0, 5.0], [0.0, 0.0, 1.0], 12.0, 48.0);
        assert!(apart(&a, &b, 0.999));
        assert!(!apart(&a, &b, 1.001));
    }

    #[test]
    fn cap_to_cap_and_cap_to_side() {
        // Coaxial, caps 2 apart.
        let a = cyl([0.0, 0.0, 0.0], [0.0, 0.0, 1.0], 12.0, 48.0);
        let b = cyl([3.0, 0.0, 50.0], [0.0, 0.0, 1.0], 12.0, 48.0);
        assert!(apart(&a, &b, 1.99));
        assert!(!apart(&a, &b, 2.01));
        // T-configuration: b's mantle 1.5 above a's cap; the capsule test alone would fail.
        let b = cyl([0.0, 0.0, 24.0 + 1.5 + 6.0], [1.0, 0.0, 0.0], 12.0, 48.0);
        assert!(apart(&a, &b, 1.49));
        assert!(!apart(&a, &b, 1.51));
        // Rim to rim, tilted: compare with a sampled distance.
        let b = cyl([12.0, 6.0, 36.0], [1.0, 1.0, 0.3], 12.0, 24.0);
        let d = sampled_distance(&a, &b);
        assert!(d > 2.0, "sampled {d}");
        assert!(apart(&a, &b, d - 1.3), "sampled {d}");
        assert!(!apart(&a, &b, d + 1e-9), "sampled {d}");
    }

    /// Whether `p` lies inside `x` by more than `margin`.
    fn inside(x: &Convex, p: &Vec3, margin: f64) -> bool {
        match *x {
            Convex::Sphere { c, r } => (p - c).norm() < r - margin,
            Convex::Cylinder { c, a, r, h } => {
                let along = (p - c).dot(&a);
                along.abs() < h - margin && (p - c - a * along).norm() < r - margin
            }
        }
    }

    /// Clearance 0 (the overlap check of explicit particles, e.g. a settled bed's): touching and
    /// interpenetrating pairs, where GJK's simplex can enclose the origin, are decided without a
    /// panic, and an overlap is never called apart: a tetrahedron that encloses the origin to
    /// within round-off must not grow to a fifth vertex and index out of bounds (the full-scale
    /// pbt-ld1 bed, 1644 cylinders with d = 12, has such pairs).
    #[test]
    fn clearance_zero_decides_touching_and_overlapping_pairs() {
        let mut rng = SplitMix64(11);
        let shapes = [
            ShapeDims::Cylinder { diameter: 12.0, length: 12.0 },
            ShapeDims::Cylinder { diameter: 12.0, length: 48.0 },
            ShapeDims::Sphere { diameter: 12.0 },
        ];
        let mut overlapping = 0;
        for k in 0..20_000 {
            let (sa, sb) = (shapes[k % 3], shapes[(k / 3) % 3]);
            let (qa, qb) = (random_rotation(&mut rng), random_rotation(&mut rng));
            let a = sa.at(Vec3::zeros(), &qa);
            // Centres from coincident to just beyond contact.
            let reach = a.bounding_radius() + sb.bounding_radius();
            let dir = Vec3::from(rng.vec3(-1.0, 1.0));
            let dir = if dir.norm() > 1e-3 { dir.normalize() } else { Vec3::x() };
            let b = sb.at(dir * rng.uniform(0.0, reach), &qb);
            let apart0 = apart(&a, &b, 0.0);
            // A point of b's axis (inside b) strictly inside a: the bodies certainly overlap.
            let (p2, q2, _) = b.capsule();
            if (0..=16).any(|i| inside(&a, &(p2 + (q2 - p2) * (i as f64 / 16.0)), 1e-6)) {
                overlapping += 1;
                assert!(!apart0, "pair {k}: overlapping bodies called apart");
            }
            // Apart at 0 must agree with a certified positive gap at a tiny clearance or not.
            if apart(&a, &b, 1e-9) {
                assert!(apart0, "pair {k}");
            }
        }
        assert!(overlapping > 1000, "{overlapping}");
    }

    #[test]
    fn random_pairs_agree_with_sampling() {
        let mut rng = SplitMix64(3);
        let mut decided = 0;
        for _ in 0..100 {
            let qa = random_rotation(&mut rng);
            let qb = random_rotation(&mut rng);
            let shape = ShapeDims::Cylinder { diameter: 12.0, length: 24.0 };
            let a = shape.at(Vec3::zeros(), &qa);
            let b = shape.at(Vec3::from(rng.vec3(-25.0, 25.0)), &qb);
            let d = sampled_distance(&a, &b);
            // The sampled distance over-estimates by at most the half-diagonal of a sampling
            // cell on each surface (0.79 around by 1 along, or 0.79 by 0.75 on the caps).
            if d > 1.3 {
                assert!(apart(&a, &b, d - 1.3), "sampled {d}: not apart at {}", d - 1.3);
            }
            assert!(!apart(&a, &b, d + 1e-9), "sampled {d}: apart beyond it");
            decided += 1;
        }
        assert_eq!(decided, 100);
    }

    #[test]
    fn spheres_and_mixed() {
        let s = Convex::Sphere { c: Vec3::new(0.0, 0.0, 0.0), r: 4.0 };
        let t = Convex::Sphere { c: Vec3::new(10.0, 0.0, 0.0), r: 4.0 };
        assert!(apart(&s, &t, 2.0));
        assert!(!apart(&s, &t, 2.0 + 1e-12));
        // Sphere above the centre of a cap, 1 above it.
        let c = cyl([0.0, 0.0, -29.0], [0.0, 0.0, 1.0], 12.0, 48.0);
        assert!(apart(&s, &c, 0.999));
        assert!(!apart(&s, &c, 1.001));
    }

    fn check_population(cells: &CellList, g: BoxGeometry, clearance: f64) {
        let b = cells.bodies();
        for i in 0..b.len() {
            for j in 0..i {
                assert!(cells.clear_of(&b[i], &b[j], clearance), "{i} and {j} overlap");
            }
            let e = b[i].half_extents();
            let c = b[i].centre();
            for a in 0..3 {
                if !g.periodic[a] {
                    assert!(c[a] - e[a] >= 0.5 - 1e-12 && c[a] + e[a] <= g.n[a] as f64 - 1.5 + 1e-12);
                }
            }
        }
    }

    #[test]
    fn random_placement_is_deterministic_clear_and_inside() {
        let g = BoxGeometry { n: [64, 48, 80], periodic: [true, false, false] };
        let shape = ShapeDims::Cylinder { diameter: 6.0, length: 18.0 };
        let req = RandomRequest {
            shape,
            count: 60,
            seed: 42,
            region: [None, Some((0.5, 46.5)), Some((0.5, 78.5))],
            clearance: 1.0,
        };
        let reach = 2.0 * shape.bounding_radius() + 1.0;
        let mut c1 = CellList::new(g, reach);
        let p1 = place_random(&mut c1, &req).unwrap();
        let mut c2 = CellList::new(g, reach);
        let p2 = place_random(&mut c2, &req).unwrap();
        assert_eq!(p1.len(), 60);
        for (a, b) in p1.iter().zip(&p2) {
            assert_eq!(a.0, b.0);
            assert_eq!(a.1, b.1);
        }
        check_population(&c1, g, 1.0);
        let other = place_random(&mut CellList::new(g, reach), &RandomRequest { seed: 43, ..req }).unwrap();
        assert_ne!(other[0].0, p1[0].0);
    }

    #[test]
    fn impossible_count_reports_how_many_were_placed() {
        let g = BoxGeometry { n: [20, 20, 20], periodic: [false; 3] };
        let shape = ShapeDims::Sphere { diameter: 8.0 };
        let req = RandomRequest { shape, count: 50, seed: 1, region: [Some((0.5, 18.5)); 3], clearance: 1.0 };
        let e = place_random(&mut CellList::new(g, 9.0), &req).unwrap_err();
        assert!(e.placed >= 1 && e.placed < 50, "{e:?}");
        assert!(e.attempts >= MAX_FAILED_ATTEMPTS);
    }
}
