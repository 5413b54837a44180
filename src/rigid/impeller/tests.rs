use super::*;
use crate::rigid::shape::testing::SplitMix;
use crate::rigid::DEFAULT_MARKER_SPACING;

/// Checks every marker: on the union's surface, unit normal pointing out of the union
/// (`p + εn` outside, `p − εn` inside), positive weight, and not inside any other part.
fn check(imp: &Impeller, spacing: f64) -> (usize, f64) {
    let ms = imp.markers_by_part(spacing);
    let eps = 1e-6;
    for (i, m) in &ms {
        assert!((m.normal.norm() - 1.0).abs() < 1e-12, "{m:?}");
        assert!(m.area > 0.0);
        assert!(imp.signed_distance(&m.position).abs() < 1e-9, "off the surface: {m:?}");
        assert!(!imp.contains(&(m.position + eps * m.normal)), "p + εn inside (part {i}): {m:?}");
        assert!(imp.contains(&(m.position - eps * m.normal)), "p − εn outside (part {i}): {m:?}");
        for j in (0..imp.part_count()).filter(|j| j != i) {
            assert!(imp.part_signed_distance(j, &m.position) >= 0.0, "marker of part {i} inside part {j}");
        }
    }
    (ms.len(), ms.iter().map(|(_, m)| m.area).sum())
}

#[test]
fn disk_markers_cover_the_exact_area() {
    for scale in [0.3, 0.5, 1.0] {
        let g = ImpellerGeometry::paper_disk(scale, 120.0 * scale);
        let imp = Impeller::new(g).unwrap();
        let r = 66.0 * scale;
        let (t, rs) = (4.0 * scale, 0.04 * 132.0 * scale);
        let exact = 2.0 * PI * r * r + TAU * r * t - PI * rs * rs + TAU * rs * (120.0 * scale - 0.5 * t);
        assert!((imp.surface_area() - exact).abs() < 1e-9 * exact);
        let (n, area) = check(&imp, DEFAULT_MARKER_SPACING);
        let rel = area / exact - 1.0;
        eprintln!("disk s={scale}: {n} markers, area {area:.2} vs exact {exact:.2} ({rel:+.2e})");
        assert!(rel.abs() < 0.01, "disk marker area off by {rel}");
    }
}

#[test]
fn pbt_markers_cover_the_exposed_area() {
    for scale in [0.3, 0.5, 1.0] {
        let g = ImpellerGeometry::paper_pbt(scale, 120.0 * scale);
        let imp = Impeller::new(g).unwrap();
        let (n, area) = check(&imp, DEFAULT_MARKER_SPACING);
        // The reference (a 7× finer marker quadrature) against the sum of the parts' areas,
        // which only overlaps reduce: a sanity bound on the reference itself.
        let parts: f64 = (0..imp.part_count()).map(|i| imp.parts[i].shape.surface_area()).sum();
        let reference = imp.surface_area();
        assert!(reference < parts && reference > 0.8 * parts, "{reference} vs parts {parts}");
        let rel = area / reference - 1.0;
        eprintln!("pbt s={scale}: {n} markers, area {area:.2} vs refined {reference:.2} ({rel:+.2e})");
        assert!(rel.abs() < 0.01, "pbt marker area off by {rel}");
    }
}

#[test]
fn pbt_pumps_down_when_turning_counter_clockwise() {
    // Blade 0 lies along +x and moves towards +y for Ω about +z. Its pushing face (outward
    // normal along the motion) must face down, driving the fluid down; the leading edge
    // (largest y) is its upper edge.
    for (pumping, sign) in [(Pumping::Down, -1.0), (Pumping::Up, 1.0)] {
        let mut g = ImpellerGeometry::paper_pbt(1.0, 0.0);
        if let ImpellerKind::PitchedBlade { pumping: p, .. } = &mut g.kind {
            *p = pumping;
        }
        let imp = Impeller::new(g).unwrap();
        // The faces looking forward (normal along +y): the pushing plate face, and the thin
        // leading-edge face; their area-weighted normal is dominated by the plate.
        let push: Vec3 = imp
            .markers_by_part(DEFAULT_MARKER_SPACING)
            .into_iter()
            .filter(|(i, m)| *i == 1 && m.normal.y > 0.5)
            .map(|(_, m)| m.normal * m.area)
            .sum();
        assert!(push.z * sign > 0.6 * push.norm(), "{pumping:?}: pushing faces' mean normal {push:?}");
        // Leading edge (max y over the blade) is up for pumping down.
        let blade = imp.markers_by_part(DEFAULT_MARKER_SPACING);
        let lead = blade
            .iter()
            .filter(|(i, _)| *i == 1)
            .max_by(|a, b| a.1.position.y.total_cmp(&b.1.position.y))
            .unwrap();
        assert!(lead.1.position.z * -sign > 0.0, "{pumping:?}: leading edge at z = {}", lead.1.position.z);
    }
}

#[test]
fn chords_and_boxes_bound_the_union() {
    let imp = Impeller::new(ImpellerGeometry::paper_pbt(0.5, 50.0)).unwrap();
    let q = Quat::from_axis_angle(&Vec3::z_axis(), 0.37);
    let r = q.to_rotation_matrix().into_inner();
    let mut rng = SplitMix(23);
    for offset in [1.7f64, 0.0, -0.5] {
        let e = imp.half_extents(&r, offset.max(0.0));
        let (mut hits, mut subset_hits) = (0, 0);
        for _ in 0..40_000 {
            let pw = Vec3::new(rng.uniform(-40.0, 40.0), rng.uniform(-40.0, 40.0), rng.uniform(-10.0, 60.0));
            let pb = r.transpose() * pw;
            let inside = imp.signed_distance(&pb) < offset;
            if inside && offset >= 0.0 {
                hits += 1;
                assert!((0..3).all(|k| pw[k].abs() <= e[k] + 1e-9), "{pw:?} outside box {e:?}");
            }
            let dir = r.transpose() * Vec3::x();
            let base = pb - dir * 1.3;
            match imp.chord(&base, &dir, offset) {
                Some((t0, t1)) if offset >= 0.0 => {
                    if inside {
                        assert!(t0 <= 1.3 + 1e-9 && 1.3 <= t1 + 1e-9, "superset chord misses {pb:?}");
                    }
                }
                Some((t0, t1)) => {
                    if t0 < 1.3 && 1.3 < t1 {
                        subset_hits += 1;
                        assert!(inside, "subset chord holds an outside point {pb:?}");
                    }
                }
                None => assert!(!(inside && offset >= 0.0), "no chord for an inside point {pb:?}"),
            }
        }
        assert!(hits > 50 || offset < 0.0, "too few samples inside: {hits}");
        assert!(subset_hits > 10 || offset >= 0.0, "too few samples in subset chords: {subset_hits}");
    }
}

#[test]
fn signed_distance_is_euclidean_outside() {
    // Outside the union, sd is the distance to the nearest marker (dense markers) to within
    // the marker spacing.
    let imp = Impeller::new(ImpellerGeometry::paper_pbt(0.3, 20.0)).unwrap();
    let ms = imp.markers(0.1);
    let mut rng = SplitMix(5);
    for _ in 0..300 {
        let p = Vec3::new(rng.uniform(-30.0, 30.0), rng.uniform(-30.0, 30.0), rng.uniform(-15.0, 25.0));
        let sd = imp.signed_distance(&p);
        if sd > 0.5 {
            let near = ms.iter().map(|m| (m.position - p).norm()).fold(f64::INFINITY, f64::min);
            assert!((near - sd).abs() < 0.1, "sd {sd} vs nearest marker {near} at {p:?}");
        }
    }
}

#[test]
fn ramp_angle_speed_and_displacements() {
    let m = RampedRotation { axis: Vec3::z(), revolutions_per_step: 1.0 / 4000.0, ramp_steps: 4000.0 };
    let full = TAU / 4000.0;
    assert_eq!(m.angular_speed(0.0), 0.0);
    assert!((m.angular_speed(2000.0) - 0.5 * full).abs() < 1e-15);
    assert_eq!(m.angular_speed(5000.0), full);
    // Half a revolution during the ramp (the paper's start-up), continuous at its end.
    assert!((m.angle(4000.0) - PI).abs() < 1e-12);
    assert!((m.angle(4000.0 + 1e-9) - m.angle(4000.0)).abs() < 1e-10);
    // Composed step displacements equal the closed-form angle.
    let mut q = Quat::identity();
    for n in 0..6000 {
        let (dx, dq) = m.displacement(n as f64, 1.0);
        assert_eq!(dx, Vec3::zeros());
        q = dq * q;
    }
    let expect = Quat::from_axis_angle(&Vec3::z_axis(), m.angle(6000.0));
    assert!(q.angle_to(&expect) < 1e-10, "{}", q.angle_to(&expect));
}

#[test]
fn invalid_geometry_names_the_key() {
    let mut g = ImpellerGeometry::paper_pbt(1.0, 100.0);
    if let ImpellerKind::PitchedBlade { pitch, .. } = &mut g.kind {
        *pitch = 0.5 * PI;
    }
    assert_eq!(Impeller::new(g).unwrap_err().key, "pitch_deg");
    let mut g = ImpellerGeometry::paper_pbt(1.0, 100.0);
    if let ImpellerKind::PitchedBlade { hub_diameter, .. } = &mut g.kind {
        *hub_diameter = 10.0;
    }
    assert_eq!(Impeller::new(g).unwrap_err().key, "hub_diameter");
    let mut g = ImpellerGeometry::paper_disk(1.0, 1.0);
    assert_eq!(Impeller::new(g).unwrap_err().key, "shaft_length");
    g.shaft_length = 50.0;
    g.shaft_diameter = 200.0;
    assert_eq!(Impeller::new(g).unwrap_err().key, "shaft_diameter");
    let g = ImpellerGeometry::paper_disk(1.0, 0.0);
    assert!(Impeller::new(g).is_ok(), "no shaft is allowed");
}
