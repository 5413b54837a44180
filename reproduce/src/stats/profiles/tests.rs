use std::f64::consts::{FRAC_PI_2, FRAC_PI_4, PI, TAU};

use super::*;
use slurry::rigid::nalgebra::{Unit, UnitQuaternion};
use slurry::util::SplitMix64;

const TANK: Tank = Tank { t: 40.0, h: 60.0, tip_speed: 0.1, steps_per_rev: 1000.0 };

fn cylinder(d: f64, l: f64, mass: f64) -> ParticleProperties {
    ParticleProperties {
        shape: "cylinder".into(),
        diameter: d,
        length: l,
        density: 2.0,
        volume: 0.25 * PI * d * d * l,
        mass,
        motion: "free".into(),
    }
}

fn wxyz(q: &UnitQuaternion<f64>) -> [f64; 4] {
    let q = q.quaternion();
    [q.w, q.i, q.j, q.k]
}

/// Rotation by `angle` about `axis`.
fn rotation(axis: [f64; 3], angle: f64) -> UnitQuaternion<f64> {
    UnitQuaternion::from_axis_angle(&Unit::new_normalize(Vec3::from(axis)), angle)
}

/// A uniformly random rotation (Shoemake 1992).
fn random_rotation(rng: &mut SplitMix64) -> UnitQuaternion<f64> {
    let (u1, u2, u3) = (rng.unit(), rng.unit(), rng.unit());
    let (a, b) = ((1.0 - u1).sqrt(), u1.sqrt());
    UnitQuaternion::from_quaternion(Quaternion::new(
        a * (TAU * u2).sin(),
        a * (TAU * u2).cos(),
        b * (TAU * u3).sin(),
        b * (TAU * u3).cos(),
    ))
}

/// A frame of particles at rest at `(position, orientation)`.
fn frame(step: u64, bodies: &[([f64; 3], UnitQuaternion<f64>)]) -> ParticleFrame {
    let n = bodies.len();
    ParticleFrame {
        step,
        time: step as f64,
        position: bodies.iter().map(|b| b.0).collect(),
        quaternion: bodies.iter().map(|b| wxyz(&b.1)).collect(),
        velocity: vec![[0.0; 3]; n],
        angular_velocity: vec![[0.0; 3]; n],
        force: vec![[0.0; 3]; n],
        torque: vec![[0.0; 3]; n],
    }
}

/// Area of the disc of radius `r` below the chord at height `x` from its centre.
fn segment(r: f64, x: f64) -> f64 {
    let x = x.clamp(-r, r);
    x * (r * r - x * x).sqrt() + r * r * (x / r).asin() + 0.5 * PI * r * r
}

#[test]
fn volume_fraction_integrates_to_the_solids_volume() {
    // Random cylinders wholly inside the tank over three frames; bins of 60/86 Δ.
    let mut rng = SplitMix64(3);
    let statics: Vec<ParticleProperties> =
        (0..30).map(|_| cylinder(4.0, rng.uniform(4.0, 16.0), 1.0)).collect();
    let frames: Vec<ParticleFrame> = (0..3)
        .map(|k| {
            let bodies: Vec<_> = statics
                .iter()
                .map(|_| ([20.0, 20.0, rng.uniform(9.0, 50.0)], random_rotation(&mut rng)))
                .collect();
            frame(k, &bodies)
        })
        .collect();
    let p = volume_fraction_profile(&frames, &statics, &TANK, 0.7).unwrap();
    assert_eq!(p.value.len(), 86);
    let dz = TANK.h * p.bin_width_over_h;
    let solids: f64 = p.value.iter().map(|v| v * dz * TANK.t * TANK.t).sum();
    let want: f64 = statics.iter().map(|s| s.volume).sum();
    assert!((solids / want - 1.0).abs() < 1e-10, "{solids} vs {want}");
    assert!(p.value.iter().all(|&v| v >= 0.0));
    assert!((p.z_over_h[0] - 0.5 / 86.0).abs() < 1e-15 && (p.z_over_h[85] - 85.5 / 86.0).abs() < 1e-15);
}

#[test]
fn vertical_cylinder_fills_whole_slabs_and_parts_of_the_end_slabs() {
    // d = 4, ℓ = 10, centre 20.8 above the floor: it spans [15.8, 25.8]; bins of 1.
    let statics = [cylinder(4.0, 10.0, 1.0)];
    let area = PI * 4.0 / (TANK.t * TANK.t);
    for q in [UnitQuaternion::identity(), rotation([1.0, 0.0, 0.0], PI), rotation([0.0, 0.0, 1.0], 0.7)] {
        let p = volume_fraction_profile(&[frame(0, &[([3.0, 7.0, 20.3], q)])], &statics, &TANK, 1.0).unwrap();
        for (j, &v) in p.value.iter().enumerate() {
            let want = match j {
                15 => 0.2 * area,
                16..=24 => area,
                25 => 0.8 * area,
                _ => 0.0,
            };
            assert!((v - want).abs() <= 1e-13 * area, "bin {j}: {v} vs {want}");
        }
    }
}

#[test]
fn horizontal_cylinder_follows_the_chord_profile() {
    // d = 6, ℓ = 12, centre 30.6 above the floor; A(z) = ℓ 2√(r² − (z − z_c)²), whose slab
    // integral is ℓ (S(z₁ − z_c) − S(z₀ − z_c)) with S the circular-segment area. The
    // computation is exact up to round-off (closed form plus a Gauss rule on an entire
    // integrand), hence 1e-12.
    let (d, l, zc) = (6.0, 12.0, 30.6);
    let statics = [cylinder(d, l, 1.0)];
    for axis in [[1.0, 0.0, 0.0], [1.0, 1.0, 0.0], [0.0, 1.0, 0.0]] {
        // Rotate body z onto the horizontal `axis`.
        let q = UnitQuaternion::rotation_between(&Vec3::z(), &Vec3::from(axis)).unwrap();
        let p = volume_fraction_profile(&[frame(0, &[([20.0, 20.0, zc - 0.5], q)])], &statics, &TANK, 0.5)
            .unwrap();
        let dz = 0.5;
        for (j, &v) in p.value.iter().enumerate() {
            let (z0, z1) = (j as f64 * dz - zc, (j + 1) as f64 * dz - zc);
            let want = l * (segment(0.5 * d, z1) - segment(0.5 * d, z0)) / (TANK.t * TANK.t * dz);
            assert!((v - want).abs() <= 1e-12 * want.abs() + 1e-16, "{axis:?} bin {j}: {v} vs {want}");
        }
    }
}

/// Monte Carlo slab volumes of a cylinder (d, ℓ) tilted by `q` with its centre at `zc` above
/// the floor, slabs of width 1: (estimate, standard error) per slab, as volume fractions.
fn monte_carlo(d: f64, l: f64, q: &UnitQuaternion<f64>, zc: f64, n: usize) -> Vec<(f64, f64)> {
    let mut rng = SplitMix64(2024);
    let mut count = vec![0usize; TANK.h as usize];
    let r = 0.5 * d;
    let mut taken = 0;
    while taken < n {
        let (x, y) = (rng.uniform(-r, r), rng.uniform(-r, r));
        if x * x + y * y >= r * r {
            continue;
        }
        let p = q.transform_vector(&Vec3::new(x, y, rng.uniform(-0.5 * l, 0.5 * l)));
        count[(zc + p.z).floor() as usize] += 1;
        taken += 1;
    }
    let v = 0.25 * PI * d * d * l / (TANK.t * TANK.t);
    count
        .iter()
        .map(|&c| {
            let f = c as f64 / n as f64;
            (v * f, v * (f * (1.0 - f) / n as f64).sqrt())
        })
        .collect()
}

#[test]
fn tilted_cylinder_matches_monte_carlo_within_five_standard_errors() {
    let (d, l, zc) = (4.0, 12.0, 30.0);
    let statics = [cylinder(d, l, 1.0)];
    let q45 = rotation([0.0, 1.0, 0.0], FRAC_PI_4);
    let mc = monte_carlo(d, l, &q45, zc, 400_000);
    let profile = |q: UnitQuaternion<f64>| {
        volume_fraction_profile(&[frame(0, &[([20.0, 20.0, zc - 0.5], q)])], &statics, &TANK, 1.0)
            .unwrap()
            .value
    };
    let exact = profile(q45);
    let mut covered = 0;
    for (j, (&v, &(est, se))) in exact.iter().zip(&mc).enumerate() {
        assert!((v - est).abs() <= 5.0 * se + 1e-15, "bin {j}: {v} vs Monte Carlo {est} ± {se}");
        covered += usize::from(v > 0.0);
    }
    assert!(covered >= 8, "the tilted cylinder spans {covered} bins");
    // The comparison has the power to see a 5° error in the tilt.
    let q40 = rotation([0.0, 1.0, 0.0], 40f64.to_radians());
    let off = profile(q40).iter().zip(&mc).filter(|(&v, &(est, se))| (v - est).abs() > 5.0 * se).count();
    assert!(off > 0, "a 40° profile passes the 45° Monte Carlo test");
}

#[test]
fn kinetic_energy_lands_in_the_centre_bin_with_the_principal_moments() {
    let (d, l, m) = (4.0, 8.0, 250.0);
    let statics = [cylinder(d, l, m)];
    let (i_axial, i_transverse) = (m * d * d / 8.0, m * (0.75 * d * d + l * l) / 12.0);
    let mut rng = SplitMix64(9);
    let v = [[0.01, -0.02, 0.03], [0.0, 0.005, 0.0]];
    let wb = [Vec3::new(0.001, 0.002, 0.003), Vec3::new(-0.004, 0.0, 0.001)];
    let z = [12.3, 40.9]; // above the floor 12.8 (bin 6 of width 2) and 41.4 (bin 20)
    let frames: Vec<ParticleFrame> = (0..2)
        .map(|k| {
            let q = random_rotation(&mut rng);
            let mut f = frame(k as u64, &[([5.0, 5.0, z[k]], q)]);
            f.velocity[0] = v[k];
            let w = q.transform_vector(&wb[k]);
            f.angular_velocity[0] = [w.x, w.y, w.z];
            f
        })
        .collect();
    let (lin, rot) = kinetic_energy_profiles(&frames, &statics, &TANK, 2.0).unwrap();
    assert_eq!(lin.value.len(), 30);
    // k* = k / (frames · Δz) · H / (n m v_tip²).
    let scale = TANK.h / (2.0 * 2.0 * m * TANK.tip_speed * TANK.tip_speed);
    for (k, bin) in [(0, 6), (1, 20)] {
        let klin = 0.5 * m * v[k].iter().map(|x| x * x).sum::<f64>();
        let krot = 0.5 * (i_transverse * (wb[k].x.powi(2) + wb[k].y.powi(2)) + i_axial * wb[k].z.powi(2));
        assert!((lin.value[bin] / (klin * scale) - 1.0).abs() < 1e-12, "linear, frame {k}");
        assert!((rot.value[bin] / (krot * scale) - 1.0).abs() < 1e-12, "rotational, frame {k}");
    }
    for j in (0..30).filter(|&j| j != 6 && j != 20) {
        assert_eq!((lin.value[j], rot.value[j]), (0.0, 0.0), "bin {j}");
    }
}

#[test]
fn rotational_energy_does_not_depend_on_the_orientation() {
    let (d, l, m) = (2.0, 8.0, 10.0);
    let statics = [cylinder(d, l, m)];
    let wb = Vec3::new(0.003, -0.001, 0.002);
    let want = 0.5
        * (m * (0.75 * d * d + l * l) / 12.0 * (wb.x.powi(2) + wb.y.powi(2))
            + m * d * d / 8.0 * wb.z.powi(2));
    let scale = TANK.h / (1.0 * m * TANK.tip_speed * TANK.tip_speed);
    let mut rng = SplitMix64(77);
    for _ in 0..100 {
        let q = random_rotation(&mut rng);
        let mut f = frame(0, &[([0.0, 0.0, 29.5], q)]);
        let w = q.transform_vector(&wb);
        f.angular_velocity[0] = [w.x, w.y, w.z];
        let (_, rot) = kinetic_energy_profiles(&[f], &statics, &TANK, 1.0).unwrap();
        assert!((rot.value[30] / (want * scale) - 1.0).abs() < 1e-12, "{q:?}: {}", rot.value[30] / scale);
    }
    // The same world spin about z: I_axial for a vertical cylinder, I_transverse for a lying one.
    let spin = |q: UnitQuaternion<f64>| {
        let mut f = frame(0, &[([0.0, 0.0, 29.5], q)]);
        f.angular_velocity[0] = [0.0, 0.0, 0.01];
        kinetic_energy_profiles(&[f], &statics, &TANK, 1.0).unwrap().1.value[30] / scale
    };
    let vertical = spin(UnitQuaternion::identity());
    let lying = spin(rotation([1.0, 0.0, 0.0], FRAC_PI_2));
    assert!((vertical / (0.5 * m * d * d / 8.0 * 1e-4) - 1.0).abs() < 1e-12);
    assert!((lying / (0.5 * m * (0.75 * d * d + l * l) / 12.0 * 1e-4) - 1.0).abs() < 1e-12);
}

#[test]
fn kinetic_energy_profile_integrates_to_the_mean_energy_with_the_mean_mass() {
    // Two particles of different mass; Σ k* Δz/H = ⟨Σ k⟩ / (n m̄ v_tip²).
    let statics = [cylinder(4.0, 8.0, 100.0), cylinder(4.0, 4.0, 50.0)];
    let mut rng = SplitMix64(1);
    let mut total = 0.0;
    let frames: Vec<ParticleFrame> = (0..4)
        .map(|k| {
            let mut f = frame(
                k,
                &[
                    ([1.0, 1.0, rng.uniform(0.0, 59.0)], random_rotation(&mut rng)),
                    ([2.0, 2.0, -0.7], UnitQuaternion::identity()),
                ],
            );
            f.velocity = vec![rng.vec3(-0.05, 0.05), rng.vec3(-0.05, 0.05)];
            f.angular_velocity[1] = [0.0, 0.0, 0.02];
            let m = [100.0, 50.0];
            for p in 0..2 {
                total += 0.5 * m[p] * f.velocity[p].iter().map(|x| x * x).sum::<f64>();
            }
            total += 0.5 * 50.0 * 16.0 / 8.0 * 0.02f64.powi(2);
            f
        })
        .collect();
    let (lin, rot) = kinetic_energy_profiles(&frames, &statics, &TANK, 3.0).unwrap();
    let sum: f64 = lin.value.iter().chain(&rot.value).map(|k| k * lin.bin_width_over_h).sum();
    let want = total / 4.0 / (2.0 * 75.0 * TANK.tip_speed * TANK.tip_speed);
    assert!((sum / want - 1.0).abs() < 1e-12, "{sum} vs {want}");
    // The particle below the floor counts in the lowest bin.
    assert!(rot.value[0] > 0.0 && rot.value[1..].iter().all(|&k| k == 0.0));
}

#[test]
fn random_orientations_give_the_sine_pdf() {
    // 200 000 uniformly random orientations in 18 bins. The counts are multinomial with the
    // exact bin probabilities p_j = cos φ_j − cos φ_{j+1}; Pearson's χ² has 17 degrees of
    // freedom (mean 17, standard deviation √34): the test allows 17 + 5√34 ≈ 46.
    let mut rng = SplitMix64(42);
    let frames: Vec<ParticleFrame> = (0..100)
        .map(|k| {
            let bodies: Vec<_> = (0..2000).map(|_| ([0.0, 0.0, 30.0], random_rotation(&mut rng))).collect();
            frame(k, &bodies)
        })
        .collect();
    let pdf = orientation_pdf(&frames, &TANK, 18, None).unwrap();
    let n = 200_000.0;
    assert_eq!(pdf.samples, 200_000);
    let w = pdf.bin_width;
    assert!((pdf.pdf.iter().sum::<f64>() * w - 1.0).abs() < 1e-12);
    let chi2 = |pdf: &[f64]| -> f64 {
        (0..18)
            .map(|j| {
                let e = n * ((j as f64 * w).cos() - ((j + 1) as f64 * w).cos());
                (pdf[j] * n * w - e).powi(2) / e
            })
            .sum()
    };
    let c = chi2(&pdf.pdf);
    assert!(c < 17.0 + 5.0 * 34f64.sqrt(), "χ² = {c}");
    // Against sin φ at the bin centres: five standard errors of the bin plus the midpoint
    // rule's offset |sin''| Δφ²/24 ≤ Δφ²/24.
    let reference = sin_reference(18);
    assert_eq!(reference.phi, pdf.phi);
    for j in 0..18 {
        let p = (j as f64 * w).cos() - ((j + 1) as f64 * w).cos();
        let se = (n * p * (1.0 - p)).sqrt() / (n * w);
        let dev = (pdf.pdf[j] - reference.pdf[j]).abs();
        assert!(dev <= 5.0 * se + w * w / 24.0, "bin {j}: {} vs sin {}", pdf.pdf[j], reference.pdf[j]);
    }
    // The statistic discriminates: lying cylinders are all in the last bin.
    let lying: Vec<ParticleFrame> = (0..100)
        .map(|k| frame(k, &[([0.0, 0.0, 30.0], rotation([0.3, 1.0, 0.0], FRAC_PI_2)); 2000]))
        .collect();
    let flat = orientation_pdf(&lying, &TANK, 18, None).unwrap();
    assert!((flat.pdf[17] - 1.0 / w).abs() < 1e-9 && flat.pdf[..17].iter().all(|&p| p == 0.0));
    assert!(chi2(&flat.pdf) > 1e5);
}

#[test]
fn mobile_particles_are_those_strictly_above_the_threshold() {
    // Heights above the floor 0.1 H, 0.2 H (not mobile: z_p > 0.2 H is strict) and 0.5 H.
    let lying = rotation([1.0, 0.0, 0.0], FRAC_PI_2);
    let f = frame(
        0,
        &[
            ([0.0, 0.0, 6.0 - 0.5], UnitQuaternion::identity()),
            ([0.0, 0.0, 12.0 - 0.5], UnitQuaternion::identity()),
            ([0.0, 0.0, 30.0 - 0.5], lying),
        ],
    );
    let all = orientation_pdf(std::slice::from_ref(&f), &TANK, 6, None).unwrap();
    let mobile = orientation_pdf(std::slice::from_ref(&f), &TANK, 6, Some(0.2)).unwrap();
    assert_eq!((all.samples, mobile.samples), (3, 1));
    let w = mobile.bin_width;
    assert!((all.pdf[0] * w - 2.0 / 3.0).abs() < 1e-15 && (all.pdf[5] * w - 1.0 / 3.0).abs() < 1e-15);
    assert!((mobile.pdf[5] * w - 1.0).abs() < 1e-15 && mobile.pdf[..5].iter().all(|&p| p == 0.0));
    let none = orientation_pdf(&[f], &TANK, 6, Some(0.9)).unwrap();
    assert_eq!(none.samples, 0);
    assert!(none.pdf.iter().all(|&p| p == 0.0));
}

#[test]
fn sin_reference_sums_to_one_up_to_the_midpoint_rule_error() {
    for bins in [9, 18, 90] {
        let s = sin_reference(bins);
        let w = s.bin_width;
        // sin is concave on [0, π/2]: the midpoint rule overshoots, by ≈ Δφ²/24 ∫ sin = Δφ²/24.
        let excess = s.pdf.iter().sum::<f64>() * w - 1.0;
        assert!(excess > 0.0 && excess <= 1.001 * w * w / 24.0, "{bins} bins: excess {excess}");
        assert!((s.phi[bins - 1] - (FRAC_PI_2 - 0.5 * w)).abs() < 1e-15);
    }
}

#[test]
fn bad_input_is_an_error() {
    let mut statics = vec![cylinder(4.0, 8.0, 1.0)];
    let f = frame(0, &[([0.0, 0.0, 3.0], UnitQuaternion::identity())]);
    statics[0].shape = "cube".into();
    let e = volume_fraction_profile(std::slice::from_ref(&f), &statics, &TANK, 1.0).unwrap_err();
    assert!(matches!(e, StatsError::Particle { index: 0, .. }), "{e}");
    statics[0].shape = "cylinder".into();
    statics.push(cylinder(4.0, 8.0, 1.0));
    let e = kinetic_energy_profiles(std::slice::from_ref(&f), &statics, &TANK, 1.0).unwrap_err();
    assert!(matches!(e, StatsError::FrameLength { len: 1, want: 2, .. }), "{e}");
    assert!(matches!(volume_fraction_profile(&[], &statics, &TANK, 1.0), Err(StatsError::Empty(_))));
    assert!(matches!(orientation_pdf(&[f], &TANK, 0, None), Err(StatsError::Argument(_))));
}
