use std::f64::consts::PI;

use super::*;

/// Re = N D²/ν, tip speed π N D, Shields N² D²/(g (γ − 1) d) of a scaled case.
fn groups(c: &Case) -> (f64, f64, f64, f64) {
    let imp = c.impeller.as_ref().unwrap();
    let r = &c.random_particles[0];
    let g = -c.gravity.unwrap()[2];
    let (n, d) = (imp.speed, imp.diameter);
    (n * d * d / c.nu(), PI * n * d, n * n * d * d / (g * (r.density - 1.0) * r.diameter), d / r.diameter)
}

#[test]
fn scaling_keeps_the_dimensionless_groups() {
    for pc in paper_cases() {
        let full = pc.case().unwrap();
        let (re, tip, shields, ratio) = groups(&full);
        assert!((re - 87.12).abs() < 0.01, "{}: Re = {re}", pc.name);
        assert!((tip - 0.10367).abs() < 1e-4, "{}: tip speed {tip}", pc.name);
        assert!((shields - 9.08).abs() < 0.01, "{}: Shields {shields}", pc.name);
        for s in [0.25, 0.5, 1.0] {
            let c = scale_case(&full, s).unwrap();
            let (re_s, tip_s, sh_s, ratio_s) = groups(&c);
            for (a, b, what) in
                [(re, re_s, "Re"), (tip, tip_s, "tip"), (shields, sh_s, "Shields"), (ratio, ratio_s, "D/d")]
            {
                assert!((a - b).abs() <= 1e-12 * a.abs(), "{} at s = {s}: {what} {a} → {b}", pc.name);
            }
            assert_eq!(c.domain.nx, (251.0 * s).round() as usize);
            assert_eq!(c.domain.nz, (240.0 * s).round() as usize);
            assert_eq!(c.random_particles[0].count, full.random_particles[0].count);
            assert_eq!(c.impeller.as_ref().unwrap().ramp_steps, (4000.0 * s).round() as u64);
        }
    }
}

#[test]
fn every_case_places_its_particles_at_the_default_scale() {
    for pc in paper_cases() {
        let mut c = scale_case(&pc.case().unwrap(), DEFAULT_SCALE).unwrap();
        c.impeller = None;
        let n = c.particle_inits().unwrap_or_else(|e| panic!("{}: {e}", pc.name)).len();
        assert_eq!(n, pc.paper().unwrap().particles, "{}", pc.name);
    }
}

#[test]
fn paper_files_parse_and_name_known_statistics() {
    for pc in paper_cases() {
        let p = pc.paper().unwrap();
        assert_eq!(p.case, pc.name);
        assert!(!p.values.is_empty());
        for v in &p.values {
            assert!(["mean_height", "po_fluid", "po_solids", "po"].contains(&v.key.as_str()), "{}", v.key);
            assert!(v.min.is_some() || v.max.is_some(), "{}: {} has no band", pc.name, v.key);
            if let (Some(p), Some(lo), Some(hi)) = (v.paper, v.min, v.max) {
                assert!(lo <= p && p <= hi, "{}: {} band excludes the paper's value", pc.name, v.key);
            }
        }
    }
}

#[test]
fn schedule_is_even_and_covers_the_revolutions() {
    let c = scale_case(&paper_case("pbt-ld2").unwrap().case().unwrap(), 0.25).unwrap();
    let s = schedule(&c, 4.0).unwrap();
    assert_eq!(s.steps_per_revolution, 1000.0);
    assert_eq!(s.output_every % 2, 0);
    assert_eq!(s.checkpoint_every % s.output_every, 0);
    assert!(s.steps >= s.ramp_steps + 4000 && s.steps < s.ramp_steps + 4000 + s.output_every);
    assert!(schedule(&c, 0.0).is_err());
    assert!(scale_case(&c, 0.05).is_err());
    assert!(paper_case("pbt-ld3").unwrap_err().to_string().contains("pbt-ld2"));
}

#[test]
fn contact_overrides_change_only_the_stirred_runs_contacts() {
    let c = scale_case(&paper_case("pbt-ld2").unwrap().case().unwrap(), 0.25).unwrap();
    let none = ContactOverrides::default();
    assert!(none.is_default() && none.describe().is_none());
    let mut same = c.clone();
    none.apply(&mut same);
    assert_eq!(same, c);
    let o = ContactOverrides {
        substeps: Some(2),
        lubrication_limiter: true,
        lubrication_substeps: None,
        implicit_damping: false,
    };
    let mut changed = c.clone();
    o.apply(&mut changed);
    let k = changed.contacts.unwrap();
    assert_eq!((k.substeps, k.lubrication_limiter), (2, true));
    assert_eq!(changed.contacts.map(|k| k.k), c.contacts.map(|k| k.k));
    assert_ne!(changed.fingerprint(), c.fingerprint(), "a resume with other contacts must be refused");
    assert!(o.describe().unwrap().contains("2 sub-steps per fluid step, lubrication limiter on"));
    let implicit = ContactOverrides { substeps: Some(2), implicit_damping: true, ..Default::default() };
    let mut changed = c.clone();
    implicit.apply(&mut changed);
    let k = changed.contacts.unwrap();
    assert_eq!((k.substeps, k.damping.name()), (2, "implicit"));
    assert!(k.validate().is_ok(), "{:?}", k.validate());
    assert!(implicit
        .describe()
        .unwrap()
        .contains("2 sub-steps per fluid step, lubrication damping implicit"));
    assert!(check_contact_substeps(1).is_ok() && check_contact_substeps(1024).is_ok());
    assert!(check_contact_substeps(0).unwrap_err().contains("[1, 1024]"));
    assert!(check_contact_substeps(1025).is_err());
}

/// The wet bed's stopping rule follows the Stokes settling speed, the same at every scale
/// (`g ∝ 1/s`, `d ∝ s`, `ν ∝ s`), and its step window grows with the tank's height.
#[test]
fn wet_settling_scales_with_the_case() {
    for pc in paper_cases() {
        let full = pc.case().unwrap();
        let base = wet_settling(&scale_case(&full, 1.0).unwrap());
        for s in [0.25, 0.5] {
            let c = scale_case(&full, s).unwrap();
            let w = wet_settling(&c);
            let r = &c.random_particles[0];
            let v_s = (r.density - 1.0) * -c.gravity.unwrap()[2] * r.diameter * r.diameter / (18.0 * c.nu());
            assert!((w.speed - 0.02 * v_s).abs() <= 1e-12 * v_s, "{} at s = {s}", pc.name);
            assert!(
                (w.speed - base.speed).abs() <= 1e-9 * base.speed,
                "{}: {} vs {}",
                pc.name,
                w.speed,
                base.speed
            );
            assert_eq!(w.min_steps, (c.domain.nz as f64 / v_s).ceil() as u64);
            assert_eq!(w.max_steps, 4 * w.min_steps);
        }
    }
}

#[test]
fn dry_beds_allow_four_falls_of_the_tank() {
    let full = paper_cases()[4].case().unwrap();
    for (s, max) in [(0.25, 4800), (0.5, 9600), (1.0, 19_200)] {
        let c = scale_case(&full, s).unwrap();
        assert_eq!(DryBedOptions::default().max_steps(&c), max, "s = {s}");
    }
}

/// A bed cached before `--bed` existed (no `wet` key) reads as dry.
#[test]
fn old_bed_records_read_as_dry() {
    let json = r#"{"inputs":"x","particles":[],"steps":3,"mean_speed":0.0,"max_speed":0.0,"settled":true,"mean_height":1.0,"seconds":0.5}"#;
    let rec: BedRecord = serde_json::from_str(json).unwrap();
    assert!(!rec.wet);
}

/// The stirred run writes its fields at the output steps nearest 10 and 90 revolutions after
/// the impeller's start (the paper's Figures 3 and 4), those it reaches.
#[test]
fn snapshots_at_the_papers_revolutions() {
    let c = scale_case(&paper_case("pbt-ld2").unwrap().case().unwrap(), 0.25).unwrap();
    let long = schedule(&c, 100.0).unwrap();
    let s = long.snapshot_steps();
    assert_eq!(s.len(), 2);
    for (step, revs) in s.iter().zip(SNAPSHOT_REVOLUTIONS) {
        assert!(step.is_multiple_of(long.output_every));
        assert!(
            (*step as f64 / long.steps_per_revolution - revs).abs()
                <= long.output_every as f64 / long.steps_per_revolution
        );
    }
    assert_eq!(schedule(&c, 30.0).unwrap().snapshot_steps(), s[..1]);
}

/// A bed read back from the cache is bitwise the bed that was settled. serde_json's default
/// float parser can be one ulp off; the `float_roundtrip` feature makes it exact. Without it
/// the first run of a case (bed settled in memory) and every later one (bed read from the
/// cache) would start from beds one ulp apart, and diverge: pbt-ld2 at s = 1/4 differs from
/// its 50th step (`reproduce/JOURNAL.md`, "A cheaper contact scheme, measured against the
/// default").
#[test]
fn cached_bed_reads_back_bitwise() {
    // Values of that bed that were read back one ulp off, then a pseudo-random batch.
    let mut values = vec![14.477085384794373, 0.9153878522412643, 0.42047522637056123, 13.984197000511575];
    let mut state = 0x9e37_79b9_7f4a_7c15_u64;
    values.extend((0..30_000).map(|_| {
        state = state.wrapping_mul(6_364_136_223_846_793_005).wrapping_add(1_442_695_040_888_963_407);
        (state >> 11) as f64 / (1u64 << 53) as f64 * 63.0
    }));
    let particles: Vec<slurry::case::ParticleSpec> = values
        .chunks_exact(3)
        .map(|x| slurry::case::ParticleSpec {
            shape: slurry::case::ShapeKind::Cylinder,
            diameter: 3.0,
            length: Some(6.0),
            density: 1.5,
            position: [x[0], x[1], x[2]],
            orientation: Some([x[2], x[1], x[0], x[0] / 63.0]),
            axis: None,
            velocity: None,
            angular_velocity: None,
            motion: Default::default(),
        })
        .collect();
    let rec = BedRecord {
        inputs: "x".into(),
        wet: false,
        bed: Bed {
            particles,
            steps: 1,
            mean_speed: 0.1,
            max_speed: 0.2,
            settled: true,
            mean_height: 9.94,
            seconds: 1.0,
            restarts: 0,
            relax_steps: 0,
        },
        start_from: None,
        state_pack: None,
    };
    let back: BedRecord = serde_json::from_str(&serde_json::to_string(&rec).unwrap()).unwrap();
    let bits = |r: &BedRecord| -> Vec<u64> {
        r.bed
            .particles
            .iter()
            .flat_map(|p| p.position.into_iter().chain(p.orientation.unwrap()))
            .map(f64::to_bits)
            .collect()
    };
    let (a, b) = (bits(&rec), bits(&back));
    let off = a.iter().zip(&b).filter(|(x, y)| x != y).count();
    assert_eq!(off, 0, "{off} of {} numbers read back differently", a.len());
}

/// The leg a run is in, by its last row's step: at s = 1/3 (1333.3 steps per revolution) a leg
/// of 100 revolutions ends at step 134 772, 100.08 revolutions after the ramp, and at s = 1/4
/// exactly at 100. A run whose last row is its leg's last step is in that leg (a resume runs
/// its steady test; status shows it complete) at both scales; one row more is the next leg.
#[test]
fn the_leg_of_a_run_is_found_by_its_last_step() {
    let pc = paper_case("pbt-ld2").unwrap();
    for (s, end) in [(0.333333333333, 134_772u64), (0.25, 101_000)] {
        let c = scale_case(&pc.case().unwrap(), s).unwrap();
        let steps = |t: f64| schedule(&c, t).unwrap().steps;
        assert_eq!(steps(100.0), end, "s = {s}");
        let leg = |last: u64| leg_target(&c, 100.0, Some(200.0), last as f64);
        assert_eq!(leg(0), 100.0, "s = {s}");
        assert_eq!(leg(end - 66), 100.0, "s = {s}: mid-leg");
        assert_eq!(leg(end), 100.0, "s = {s}: the leg just ended");
        assert_eq!(leg(end + 66), 110.0, "s = {s}: the next leg begun");
        assert_eq!(leg(steps(110.0)), 110.0, "s = {s}");
        assert_eq!(leg(steps(200.0) + 1000), 200.0, "s = {s}: never past the cap");
        // Without --until-steady a run has one leg, whatever it has done.
        assert_eq!(leg_target(&c, 100.0, None, (end + 66) as f64), 100.0, "s = {s}");
    }
}

/// `shadow_differences`: RMS differences and the mean height and vertical-velocity offsets
/// of two hand-made runs, and zero against itself.
#[test]
fn shadow_differences_of_known_states() {
    use bench::{shadow_differences, ShadowRun};
    let run = |label: &str, dz: f64, dv: f64, w: f64| ShadowRun {
        label: label.into(),
        contact_substeps: 8,
        lubrication_substeps: 1,
        lubrication_limiter: false,
        at: vec![1, 2],
        states: vec![
            vec![
                [0.0, 0.0, 1.0 + dz, 0.0, dv, 0.0, 0.0, 0.0, 0.0],
                [3.0, 0.0, 2.0 - dz, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0],
            ],
            vec![
                [0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0],
                [3.0, 0.0, 2.0 + 2.0 * dz, 0.0, 0.0, 0.0, 0.0, dv, 0.0],
            ],
        ],
        mean_w: vec![w, 2.0 * w],
        elastic_energy: vec![0.0; 2],
        marker_pairs: vec![0; 2],
        seconds: 1.0,
    };
    let runs = [run("ref", 0.0, 0.0, 0.0), run("a", 0.1, 0.2, 0.3)];
    let d = shadow_differences(&runs, 0);
    assert_eq!(d[0].rms_position, vec![0.0, 0.0]);
    assert_eq!((d[0].mean_dz[1], d[0].mean_dw), (0.0, 0.0));
    let a = &d[1];
    // Step 1: Δz = ±0.1 (RMS 0.1, mean 0); Δv on one of two particles (RMS 0.2/√2).
    assert!((a.rms_position[0] - 0.1).abs() < 1e-12 && a.mean_dz[0].abs() < 1e-12, "{a:?}");
    assert!((a.rms_velocity[0] - 0.2 / 2f64.sqrt()).abs() < 1e-12, "{a:?}");
    // Step 2: Δz = 0.2 on one particle (RMS 0.2/√2, mean 0.1), Δω on it.
    assert!((a.rms_position[1] - 0.2 / 2f64.sqrt()).abs() < 1e-12 && (a.mean_dz[1] - 0.1).abs() < 1e-12);
    assert!((a.rms_angular[1] - 0.2 / 2f64.sqrt()).abs() < 1e-12 && a.rms_velocity[1] == 0.0);
    assert!((a.mean_dw - 0.45).abs() < 1e-12, "{}", a.mean_dw);
}

/// The disk and the PBT of one ℓ/d and scale settle the same bed (the impeller is not among a
/// bed's inputs), and a bed cached under one case's name serves the other: at the paper's
/// scale a bed takes 10–16 min to settle here.
#[test]
fn disk_and_pbt_of_one_aspect_ratio_share_their_bed() {
    let scaled = |name: &str| scale_case(&paper_case(name).unwrap().case().unwrap(), DEFAULT_SCALE).unwrap();
    let dry = BedMethod::Dry(DryBedOptions::default());
    for ld in ["ld1", "ld2", "ld4"] {
        let (disk, pbt) = (scaled(&format!("disk-{ld}")), scaled(&format!("pbt-{ld}")));
        assert_eq!(bed_inputs(&disk, &dry).unwrap().1, bed_inputs(&pbt, &dry).unwrap().1, "{ld}");
    }
    assert_ne!(
        bed_inputs(&scaled("pbt-ld1"), &dry).unwrap().1,
        bed_inputs(&scaled("pbt-ld2"), &dry).unwrap().1
    );

    // A record stored under pbt-ld2's name (wet: used as it is) is found for disk-ld2.
    let cache = tempfile::tempdir().unwrap();
    let (pbt, disk) = (scaled("pbt-ld2"), scaled("disk-ld2"));
    let (_, inputs) = bed_inputs(&pbt, &BedMethod::Wet).unwrap();
    let rec = BedRecord {
        inputs: inputs.clone(),
        wet: true,
        bed: Bed {
            particles: Vec::new(),
            steps: 7,
            mean_speed: 0.0,
            max_speed: 0.0,
            settled: true,
            mean_height: 1.0,
            seconds: 0.0,
            restarts: 0,
            relax_steps: 0,
        },
        start_from: None,
        state_pack: None,
    };
    let dir = cache.path().join("beds").join(format!("pbt-ld2-{:016x}", fnv1a(&inputs)));
    std::fs::create_dir_all(&dir).unwrap();
    std::fs::write(dir.join("bed.json"), serde_json::to_string(&rec).unwrap()).unwrap();
    let (key, disk_inputs) = bed_inputs(&disk, &BedMethod::Wet).unwrap();
    let hash = format!("{:016x}", fnv1a(&disk_inputs));
    let own = cache.path().join("beds").join(format!("disk-ld2-{hash}"));
    let (got, from) =
        cached_bed(cache.path(), &own, &hash, &disk_inputs, &key).expect("pbt-ld2's bed not found");
    assert_eq!((got.bed.steps, got.inputs, from), (7, inputs, dir.join("bed.json")));
    // Another aspect ratio's hash finds nothing.
    let (key4, inputs4) = bed_inputs(&scaled("disk-ld4"), &BedMethod::Wet).unwrap();
    let hash4 = format!("{:016x}", fnv1a(&inputs4));
    let own4 = cache.path().join("beds").join(format!("disk-ld4-{hash4}"));
    assert!(cached_bed(cache.path(), &own4, &hash4, &inputs4, &key4).is_none());
}

/// The default run is the paper's steady state ("at least 100 impeller revolutions", "more
/// than 200 revolutions for the combination PBT and ℓ/d = 1"), and what is printed before a
/// run says whether it goes to steady state, and whether its scale is below the paper's
/// resolution.
#[test]
fn the_default_run_goes_to_steady_state_and_says_so() {
    for name in CASES {
        let (r, cap) = default_revolutions(name);
        let first = if name == "pbt-ld1" { 200.0 } else { 100.0 };
        assert_eq!((r, cap), (first, first + 100.0), "{name}");
        assert!(check_until_steady(cap, r).is_ok(), "{name}");
    }
    let steady = announce("pbt-ld2", DEFAULT_SCALE, 100.0, Some(200.0), false, 0.0);
    assert!(steady.contains("to steady state") && steady.contains("at most to 200 revolutions"), "{steady}");
    assert!(steady.contains("d = 3.00") && steady.contains("not a reproduction"), "{steady}");
    // 100.5 revolutions of 1000 steps at 27 ms, then to 200.5.
    assert!(steady.contains("roughly 45 minutes") && steady.contains("about 90 minutes in all"), "{steady}");
    let fixed = announce("pbt-ld2", 0.5, 30.0, None, false, 0.0);
    // 30.5 revolutions of 2000 steps at 108 ms.
    assert!(fixed.contains("roughly 110 minutes") && fixed.contains("108 ms per step"), "{fixed}");
    let long = announce("pbt-ld1", 0.5, 200.0, Some(300.0), false, 0.0);
    assert!(long.contains("roughly 19.2 hours") && long.contains("about 28.8 hours in all"), "{long}");
    // A continuation from revolution 222.6 (a state pack) to 250: only the rest, no ramp.
    let leg = announce("pbt-ld1", DEFAULT_SCALE, 250.0, Some(300.0), false, 222.6);
    // 27.4 revolutions of 1000 steps at 43.2 ms; 77.4 to the cap.
    assert!(leg.contains("(222.6 done)") && leg.contains("roughly 20 minutes"), "{leg}");
    assert!(leg.contains("about 56 minutes in all"), "{leg}");
    assert!(
        fixed.contains("not checked for steady state") && !fixed.contains("not a reproduction"),
        "{fixed}"
    );
}

/// A resumed session records the checkpoint step it continues from when it starts, so that a
/// session killed before it finishes still says it (manifests written by older versions have
/// `null` for every session that did not finish); a fresh one records none.
#[test]
fn a_resumed_session_says_where_it_began_before_it_runs() {
    let dir = tempfile::tempdir().unwrap();
    // Only the checkpoint's `time_step` attribute is read (`io::checkpoint_time_step`).
    let file = hdf5::File::create(dir.path().join(slurry::run::files::CHECKPOINT)).unwrap();
    file.new_attr::<u64>().shape(()).create("time_step").unwrap().write_scalar(&265_320u64).unwrap();
    file.close().unwrap();
    assert_eq!(this_session(dir.path(), true).resumed_from_step, Some(265_320));
    assert_eq!(this_session(dir.path(), false).resumed_from_step, None);
    let empty = tempfile::tempdir().unwrap();
    assert_eq!(this_session(empty.path(), true).resumed_from_step, None, "no checkpoint: nothing to name");
}
