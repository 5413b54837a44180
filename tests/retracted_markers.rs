//! The immersed boundary's forcing markers retracted into every shape (issue 13,
//! `Shape::retracted_markers`): on the inner parallel surface (signed distance `−r_d` from the
//! true surface), with that surface's outward normals and area weights (summing to the
//! retracted surface's area, which is the shrunk shape's: sphere `d − 2r_d`, cylinder
//! `d − 2r_d` and `ℓ − 2r_d` with its rims, cuboid every edge `− 2r_d`, impeller parts
//! likewise); zero retraction gives the true markers bit for bit; a shape too thin for the
//! retraction is refused, naming the dimension.

use std::f64::consts::{PI, TAU};

use proptest::prelude::*;
use slurry::rigid::impeller::{ImpellerGeometry, ImpellerKind};
use slurry::rigid::{Cuboid, Cylinder, Impeller, Marker, RetractionError, Shape, Sphere, Vec3};

/// Every marker at signed distance `−depth` from `shape` with a unit normal pointing out of the
/// retracted body (`p + εn` less deep than `p − εn`), positive weights summing to `area`.
fn check(shape: &dyn Shape, m: &[Marker], depth: f64, area: f64) -> Result<(), TestCaseError> {
    prop_assert!(!m.is_empty());
    let eps = 1e-6;
    for k in m {
        prop_assert!((k.normal.norm() - 1.0).abs() < 1e-14);
        let sd = shape.signed_distance(&k.position);
        prop_assert!((sd + depth).abs() < 1e-9, "sd = {sd}, depth {depth}: {k:?}");
        prop_assert!(
            shape.signed_distance(&(k.position + eps * k.normal))
                > shape.signed_distance(&(k.position - eps * k.normal))
        );
        prop_assert!(k.area > 0.0);
    }
    let total: f64 = m.iter().map(|k| k.area).sum();
    prop_assert!((total - area).abs() <= 1e-12 * area, "areas sum to {total}, retracted surface {area}");
    Ok(())
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(64))]

    #[test]
    fn sphere_retracted(d in 1.0f64..30.0, depth in 0.0f64..0.5, h in 0.5f64..0.75) {
        let s = Sphere::new(d);
        let m = s.retracted_markers(h, depth).unwrap();
        check(&s, &m, depth, PI * (d - 2.0 * depth).powi(2))?;
    }

    #[test]
    fn cylinder_retracted(d in 1.0f64..30.0, l in 1.0f64..60.0, depth in 0.0f64..0.5, h in 0.5f64..0.75) {
        let c = Cylinder::new(d, l);
        let m = c.retracted_markers(h, depth).unwrap();
        let (dr, lr) = (d - 2.0 * depth, l - 2.0 * depth);
        check(&c, &m, depth, PI * dr * lr + 0.5 * PI * dr * dr)?;
    }

    #[test]
    fn cuboid_retracted(
        x in 1.0f64..30.0, y in 1.0f64..30.0, z in 1.0f64..30.0, depth in 0.0f64..0.5, h in 0.5f64..0.75,
    ) {
        let c = Cuboid::new(Vec3::new(x, y, z));
        let m = c.retracted_markers(h, depth).unwrap();
        let (a, b, e) = (x - 2.0 * depth, y - 2.0 * depth, z - 2.0 * depth);
        check(&c, &m, depth, 2.0 * (a * b + b * e + e * a))?;
    }
}

#[test]
fn zero_retraction_is_the_true_markers() {
    let shapes: Vec<Box<dyn Shape>> = vec![
        Box::new(Sphere::new(7.3)),
        Box::new(Cylinder::new(3.0, 6.0)),
        Box::new(Cuboid::new(Vec3::new(13.2, 6.6, 0.75))),
        Box::new(Impeller::new(ImpellerGeometry::paper_pbt(0.25, 30.0)).unwrap()),
        Box::new(Impeller::new(ImpellerGeometry::paper_disk(0.25, 30.0)).unwrap()),
    ];
    for s in &shapes {
        assert_eq!(s.retracted_markers(0.7, 0.0).unwrap(), s.markers(0.7), "{}", s.name());
    }
}

/// The disk impeller: the retracted markers lie at depth `r_d` in the union (the shaft's top
/// ring, at the lid, excepted: the shaft's top end is no surface), and their weights sum to
/// the exposed area of the shrunk disk-and-shaft, `2πR'² + 2πR't' − πr'² + 2πr'(ℓ − t'/2)`
/// with `R' = R − r_d`, `t' = t − 2r_d`, `r' = r_s − r_d` (the shaft keeps its length to the
/// lid); the PBT: the same depth, and the area that of the impeller built from the shrunk
/// dimensions (the same construction; the PBT's exposed area has no closed form); both within
/// 1 %, the bound of the true markers.
#[test]
fn impeller_retracted() {
    let depth = 0.35;
    for scale in [0.25, 0.5] {
        let shaft = 120.0 * scale;
        for g in [ImpellerGeometry::paper_disk(scale, shaft), ImpellerGeometry::paper_pbt(scale, shaft)] {
            let imp = Impeller::new(g).unwrap();
            let ms = imp.retracted_markers_by_part(0.7, depth).unwrap();
            for (i, m) in &ms {
                if m.position.z > shaft - 1.0 {
                    continue;
                }
                let sd = imp.signed_distance(&m.position);
                assert!((sd + depth).abs() < 1e-9, "scale {scale}, part {i}: sd {sd} at {m:?}");
            }
            let area: f64 = ms.iter().map(|(_, m)| m.area).sum();
            let reference = match g.kind {
                ImpellerKind::Disk { thickness } => {
                    let (r, t, rs) =
                        (0.5 * g.diameter - depth, thickness - 2.0 * depth, 0.5 * g.shaft_diameter - depth);
                    TAU * r * r + TAU * r * t - PI * rs * rs + TAU * rs * (shaft - 0.5 * t)
                }
                ImpellerKind::PitchedBlade {
                    blades,
                    pitch,
                    blade_width,
                    blade_thickness,
                    hub_diameter,
                    hub_height,
                    pumping,
                } => {
                    let shrunk = ImpellerGeometry {
                        diameter: g.diameter - 2.0 * depth,
                        kind: ImpellerKind::PitchedBlade {
                            blades,
                            pitch,
                            blade_width: blade_width - 2.0 * depth,
                            blade_thickness: blade_thickness - 2.0 * depth,
                            hub_diameter: hub_diameter - 2.0 * depth,
                            hub_height: hub_height - 2.0 * depth,
                            pumping,
                        },
                        shaft_diameter: g.shaft_diameter - 2.0 * depth,
                        shaft_length: shaft,
                    };
                    // Its shaft starts on the shrunk hub, like the retracted one.
                    Impeller::new(shrunk).unwrap().surface_area()
                }
            };
            let rel = area / reference - 1.0;
            // 1 %: the bound of the true markers (verification case `impeller`): the weights
            // tile each part's faces exactly, only cells cut by another part's surface (the
            // shaft's foot on the disk, the blade roots in the hub) are all-or-nothing.
            assert!(rel.abs() < 0.01, "scale {scale} {:?}: area {area}, reference {reference}", g.kind);
        }
    }
}

#[test]
fn too_thin_is_refused_naming_the_dimension() {
    let thin = |r: Result<Vec<Marker>, RetractionError>| match r {
        Err(RetractionError::TooThin { dimension, .. }) => dimension,
        other => panic!("expected TooThin, got {other:?}"),
    };
    assert_eq!(thin(Sphere::new(1.0).retracted_markers(0.7, 0.5)), "diameter");
    assert_eq!(thin(Cylinder::new(4.0, 0.9).retracted_markers(0.7, 0.45)), "length");
    assert_eq!(thin(Cuboid::new(Vec3::new(5.0, 0.6, 3.0)).retracted_markers(0.7, 0.3)), "y edge");
    // The PBT at scale 1/8: blades 0.375 thick.
    let pbt = Impeller::new(ImpellerGeometry::paper_pbt(0.125, 15.0)).unwrap();
    assert_eq!(thin(pbt.retracted_markers(0.7, 0.2)), "blade_thickness");
    assert!(matches!(Sphere::new(3.0).retracted_markers(0.7, -0.1), Err(RetractionError::Depth(_))));
}
