//! The dry bed relaxes the overlaps that its amplified gravity presses in (`settle::dry_bed`):
//! the full-scale pbt-ld1 bed (1644 cylinders, d = 12) came out of 50× gravity with rims sunk
//! into neighbours, which the stirred run refused as overlapping explicit particles.

mod common;

use slurry::case::Case;
use slurry::settle::{admissible, dry_bed, DryBedOptions};

/// Eight random spheres (d = 4) in a narrow closed column under the gravity of the paper at
/// s = 1/4 (4e-5 / s), with Table 1 contacts (`contacts`:
/// extra `[contacts]` keys).
fn column(contacts: &str) -> Case {
    let closed = common::case_toml(
        [10, 10, 40],
        "precision = \"f32\"\nnu = 0.1\ncollision = \"bgk\"",
        "",
        "steps = 1\noutput_every = 1",
    );
    let text = format!(
        "gravity = [0.0, 0.0, -1.6e-4]\n{closed}\n[contacts]\n{contacts}\n[[random_particles]]\nshape = \"sphere\"\n\
         diameter = 4.0\ndensity = 1.25\ncount = 8\nseed = 5\n"
    );
    Case::parse(&text, "column.toml").unwrap()
}

/// With contacts 100 times softer than Table 1's, 50× gravity presses the column's spheres into
/// each other, so the bed relaxes at the case's gravity until the case's own test admits it;
/// with Table 1 none is needed and the bed is returned as settled. Both are admissible as
/// explicit particles.
#[test]
fn amplified_gravity_overlaps_are_relaxed_until_admissible() {
    let opts = DryBedOptions { min_steps: 100, ..DryBedOptions::default() };
    let soft = column("k = 0.05");
    let pressed = dry_bed(&soft, opts).unwrap();
    assert!(pressed.relax_steps > 0, "no relaxation needed: the test presses too little");
    admissible(&soft, &pressed.particles).unwrap();
    assert!(pressed.settled, "relaxed, but not to rest");
    let c = column("");
    let plain = dry_bed(&c, opts).unwrap();
    assert_eq!(plain.relax_steps, 0);
    admissible(&c, &plain.particles).unwrap();
    eprintln!(
        "relaxed in {} steps after {}; plain bed {} steps",
        pressed.relax_steps, pressed.steps, plain.steps
    );
}
