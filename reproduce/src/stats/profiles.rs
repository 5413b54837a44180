//! Vertical profiles (volume fraction, kinetic energy) and orientation pdfs over frames.

use std::f64::consts::FRAC_PI_2;

use super::geometry::{cylinder_volume_below, sphere_volume_below};
use super::{bins, check_frames, models, AnglePdf, Model, Profile, Shape, StatsError, Tank};
use slurry::io::{ParticleFrame, ParticleProperties};
use slurry::rigid::integrate::rotational_energy;
use slurry::rigid::nalgebra::Quaternion;
use slurry::rigid::{Quat, Vec3};

/// The world direction of the body `z` axis (a cylinder's axis) of the orientation
/// `q = [w, x, y, z]` (body → world), normalised: the third column of the rotation matrix,
/// `(2(xz + wy), 2(yz − wx), w² − x² − y² + z²)/|q|²` (valid for any non-zero `q`).
pub(crate) fn axis(q: &[f64; 4]) -> [f64; 3] {
    let [w, x, y, z] = *q;
    let n2 = w * w + x * x + y * y + z * z;
    [2.0 * (x * z + w * y) / n2, 2.0 * (y * z - w * x) / n2, (w * w - x * x - y * y + z * z) / n2]
}

fn bin_centres(n: usize) -> Vec<f64> {
    (0..n).map(|j| (j as f64 + 0.5) / n as f64).collect()
}

/// Time-averaged solids volume fraction of horizontal slabs (Figure 6), from the particles'
/// actual shapes:
///
/// ```text
/// φ_j = (1/F) Σ_frames Σ_p V_p(slab j) / (T² Δz),   V_p(slab j) = V_p(z_{j+1} − z_p) − V_p(z_j − z_p)
/// ```
///
/// with `z_j = j Δz` the slab boundaries above the floor, `z_p` the particle centre's height
/// above the floor and `V_p(ζ)` the particle's volume below the height `ζ` relative to its
/// centre ([`cylinder_volume_below`] for a cylinder tilted by its orientation, exact to
/// round-off; [`sphere_volume_below`]). The slabs tile `[0, H]`: `round(H/bin_width)` of them
/// (at least one), of width `Δz = H/bins`. Solids outside `[0, H]` (a particle overlapping
/// the floor or the lid) are not counted. With every particle inside,
/// `Σ_j φ_j Δz T² = Σ_p V_p` to round-off. Error for no frames, an unknown shape, or frame
/// arrays that do not match `statics`.
pub fn volume_fraction_profile(
    frames: &[ParticleFrame],
    statics: &[ParticleProperties],
    tank: &Tank,
    bin_width: f64,
) -> Result<Profile, StatsError> {
    let models = models(statics)?;
    check_frames(frames, statics.len())?;
    if frames.is_empty() {
        return Err(StatsError::Empty("volume fraction: particle frames"));
    }
    let (n, dz) = bins(tank, bin_width)?;
    let mut sum = vec![0.0; n];
    for f in frames {
        for (i, m) in models.iter().enumerate() {
            let zc = f.position[i][2] + 0.5;
            let a = axis(&f.quaternion[i]);
            let extent = match m.shape {
                Shape::Cylinder { diameter, length } => {
                    0.5 * (a[2].abs() * length + a[0].hypot(a[1]).min(1.0) * diameter)
                }
                Shape::Sphere { diameter } => 0.5 * diameter,
            };
            let below = |z: f64| match m.shape {
                Shape::Cylinder { diameter, length } => cylinder_volume_below(diameter, length, a, z),
                Shape::Sphere { diameter } => sphere_volume_below(diameter, z),
            };
            // Boundaries k0 ..= k1 enclose the particle (clamped to the tank).
            let k0 = ((zc - extent) / dz).floor().clamp(0.0, n as f64) as usize;
            let k1 = ((zc + extent) / dz).ceil().clamp(0.0, n as f64) as usize;
            let mut prev = below(k0 as f64 * dz - zc);
            for (k, s) in sum.iter_mut().enumerate().take(k1).skip(k0) {
                let next = below((k + 1) as f64 * dz - zc);
                *s += next - prev;
                prev = next;
            }
        }
    }
    let scale = 1.0 / (frames.len() as f64 * tank.t * tank.t * dz);
    Ok(Profile {
        z_over_h: bin_centres(n),
        value: sum.iter().map(|s| s * scale).collect(),
        bin_width_over_h: 1.0 / n as f64,
    })
}

/// Vertical distribution of the particles' kinetic energy (Figure 7), linear and rotational:
///
/// ```text
/// k_lin = ½ m_p |u_p|²,   k_rot = ½ (I₁ ω₁² + I₂ ω₂² + I₃ ω₃²),
/// k′_j = (1/F) Σ_frames Σ_{p: z_p in bin j} k_p / Δz,   k*_j = k′_j / (n m_p v_tip² / H)
/// ```
///
/// with `ω_i` the angular velocity's components along the particle's principal axes (the
/// world `ω` rotated into the body frame, `ω_b = q* ω q`), `I_i` the principal moments
/// (cylinder: `I₃ = m d²/8` about the axis, `I₁ = I₂ = m (3d²/4 + ℓ²)/12`; sphere:
/// `2 m R²/5`), `z_p` the centre's height above the floor, `n` the particle count and `m_p`
/// the particle mass — the **mean** mass when the particles differ. Each particle counts in
/// the bin of its centre (a centre outside `[0, H]` in the nearest end bin). Bins as in
/// [`volume_fraction_profile`]. `Σ_j k*_j Δz/H` is the mean total energy over `n m_p v_tip²`.
/// Returns `(linear, rotational)`.
pub fn kinetic_energy_profiles(
    frames: &[ParticleFrame],
    statics: &[ParticleProperties],
    tank: &Tank,
    bin_width: f64,
) -> Result<(Profile, Profile), StatsError> {
    let models: Vec<Model> = models(statics)?;
    check_frames(frames, statics.len())?;
    if frames.is_empty() {
        return Err(StatsError::Empty("kinetic energy: particle frames"));
    }
    if models.is_empty() {
        return Err(StatsError::Empty("kinetic energy: particles"));
    }
    if !(tank.tip_speed.is_finite() && tank.tip_speed > 0.0) {
        return Err(StatsError::Argument(format!("tip speed {} must be positive", tank.tip_speed)));
    }
    let (n, dz) = bins(tank, bin_width)?;
    let (mut lin, mut rot) = (vec![0.0; n], vec![0.0; n]);
    for f in frames {
        for (i, m) in models.iter().enumerate() {
            let j = ((f.position[i][2] + 0.5) / dz).floor().clamp(0.0, (n - 1) as f64) as usize;
            let v = Vec3::from(f.velocity[i]);
            lin[j] += 0.5 * m.mass * v.norm_squared();
            let [w, x, y, z] = f.quaternion[i];
            let q = Quat::from_quaternion(Quaternion::new(w, x, y, z));
            let omega_b = q.inverse_transform_vector(&Vec3::from(f.angular_velocity[i]));
            rot[j] += rotational_energy(&m.inertia, &omega_b);
        }
    }
    let mass = models.iter().map(|m| m.mass).sum::<f64>() / models.len() as f64;
    let scale =
        tank.h / (frames.len() as f64 * dz * models.len() as f64 * mass * tank.tip_speed * tank.tip_speed);
    let profile = |sum: Vec<f64>| Profile {
        z_over_h: bin_centres(n),
        value: sum.iter().map(|s| s * scale).collect(),
        bin_width_over_h: 1.0 / n as f64,
    };
    Ok((profile(lin), profile(rot)))
}

/// Probability density of the orientation angle `φ` between the cylinder axis (body `z`) and
/// the vertical, folded to `[0, π/2]`: `φ = acos |a_z|` with `a` the axis in the world frame
/// (Figures 8 and 9). Histogram over all frames and particles, or only the "mobile" ones with
/// `z_p/H > z_min_over_h` when given (the paper: 0.2), in `bins` equal bins, normalised so
/// that `Σ pdf Δφ = 1`; all zeros when no particle qualifies. Randomly oriented cylinders
/// have the density `sin φ` ([`sin_reference`]). Error for `bins = 0`.
pub fn orientation_pdf(
    frames: &[ParticleFrame],
    tank: &Tank,
    bins: usize,
    z_min_over_h: Option<f64>,
) -> Result<AnglePdf, StatsError> {
    if bins == 0 {
        return Err(StatsError::Argument("orientation pdf: zero bins".into()));
    }
    let width = FRAC_PI_2 / bins as f64;
    let mut count = vec![0usize; bins];
    let mut samples = 0;
    for f in frames {
        if f.quaternion.len() != f.position.len() {
            return Err(StatsError::FrameLength {
                step: f.step,
                name: "quaternion",
                len: f.quaternion.len(),
                want: f.position.len(),
            });
        }
        for (p, q) in f.position.iter().zip(&f.quaternion) {
            if z_min_over_h.is_some_and(|zmin| tank.z_over_h(p[2]) <= zmin) {
                continue;
            }
            let phi = axis(q)[2].abs().min(1.0).acos();
            count[((phi / width) as usize).min(bins - 1)] += 1;
            samples += 1;
        }
    }
    let norm = if samples > 0 { 1.0 / (samples as f64 * width) } else { 0.0 };
    Ok(AnglePdf {
        phi: (0..bins).map(|j| (j as f64 + 0.5) * width).collect(),
        pdf: count.iter().map(|&c| c as f64 * norm).collect(),
        bin_width: width,
        samples,
    })
}

/// `sin φ` at the centres of `bins` equal bins over `[0, π/2]`: the pdf of randomly oriented
/// cylinders (their end points are uniform on a sphere, and `∫₀^{π/2} sin φ dφ = 1`). At bin
/// centres the midpoint sum `Σ sin φ_j Δφ` exceeds 1 by about `Δφ²/24` (sin is concave), and
/// each value differs from the bin average of `sin φ` (the expected histogram of random
/// orientations) by at most `Δφ²/24`.
pub fn sin_reference(bins: usize) -> AnglePdf {
    let width = FRAC_PI_2 / bins.max(1) as f64;
    let phi: Vec<f64> = (0..bins).map(|j| (j as f64 + 0.5) * width).collect();
    AnglePdf { pdf: phi.iter().map(|p| p.sin()).collect(), phi, bin_width: width, samples: 0 }
}

#[cfg(test)]
mod tests;
