//! Issue 15, defect 6 (unrounded limits): messages printed computed limits with their
//! round-off, e.g. `0 < shaft_diameter < 2.4000000000000004` for the default hub diameter
//! `0.2 D` of an impeller of `D = 12`.
//!
//! Expected: limits for people — rounded to 12 significant digits and printed in their
//! shortest form (`2.4`), by `slurry::util::fmt_num` / `humanize_numbers`.

use slurry::case::Case;
use slurry::util::{fmt_num, humanize_numbers};

mod common;

use common::case_toml;

#[test]
fn shaft_limit_reads_as_the_hub_diameter() {
    let closed_box = case_toml([24, 24, 24], "nu = 0.1", "", "steps = 10\noutput_every = 5");
    let text = &format!(
        r#"{closed_box}
[impeller]
kind = "pbt"
diameter = 12.0
speed = 1e-3
ramp_steps = 100
shaft_diameter = 3.0
"#
    );
    let e = Case::parse(text, "imp.toml").expect_err("accepted").to_string();
    assert!(e.contains("impeller.shaft_diameter = 3") && e.contains("shaft_diameter < 2.4"), "{e}");
    assert!(!e.contains("2.4000000000000004"), "{e}");
}

#[test]
fn helpers_round_for_people() {
    assert_eq!(fmt_num(0.2 * 12.0), "2.4");
    assert_eq!(fmt_num(99.5 / 3.0), "33.1666666667");
    assert_eq!(fmt_num(1e-300), "1e-300");
    assert_eq!(humanize_numbers("< 2.4000000000000004 and 0.30000000000000004"), "< 2.4 and 0.3");
    assert_eq!(humanize_numbers("count 100000000000, d 0.001"), "count 100000000000, d 0.001");
}
