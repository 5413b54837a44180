//! Issue 15, defect 3: inputs that were accepted silently.
//!
//! - `nu = 1e-300` gives `tau = 3 nu + 1/2 = 0.5` after rounding, which `tau = 0.5` is
//!   refused for: the `tau > 0.5` rule now applies after the conversion.
//! - `nu = 1e12` (tau of order 1e12): tau is bounded by `slurry::case::MAX_TAU`.
//! - `domain = [4, 4, 8]`, an array where a table is documented, was read as `nx, ny, nz`
//!   (serde accepts a sequence for a struct): every section must be a table, and
//!   `[[particles]]` / `[[random_particles]]` arrays of tables.
//! - A sphere of diameter 1e-6 was resolved by one marker: particles must be at least
//!   `MIN_PARTICLE_SIZE` (one lattice spacing) across, cylinders as long.
//!
//! Expected: each is refused by `Case::parse` with its key, the value and the allowed range.

use slurry::case::particles::MIN_PARTICLE_SIZE;
use slurry::case::{Case, MAX_TAU};

mod common;

use common::{case_toml, refusal};

/// A closed 12³ box of fluid at rest.
fn good() -> String {
    case_toml([12, 12, 12], "nu = 0.1", "", "steps = 10\noutput_every = 5")
}

fn refused(text: &str, needles: &[&str]) {
    let e = refusal(text);
    assert!(e.starts_with("bad.toml: "), "{e}");
    for n in needles {
        assert!(e.contains(n), "`{n}` missing from: {e}");
    }
}

#[test]
fn the_good_case_is_accepted() {
    Case::parse(&good(), "good.toml").unwrap();
    Case::parse(&good().replace("nu = 0.1", "nu = 1e-12"), "good.toml").unwrap();
    Case::parse(&good().replace("nu = 0.1", "tau = 100.0"), "good.toml").unwrap();
}

#[test]
fn viscosity_that_rounds_to_tau_one_half_is_refused() {
    refused(&good().replace("nu = 0.1", "nu = 1e-300"), &["fluid.nu = 1e-300", "rounds to 0.5", "> 0.5"]);
    refused(&good().replace("nu = 0.1", "nu = 1e-17"), &["fluid.nu", "rounds to 0.5"]);
}

#[test]
fn viscosity_beyond_the_tau_bound_is_refused() {
    assert_eq!(MAX_TAU, 100.0);
    refused(&good().replace("nu = 0.1", "nu = 1e12"), &["fluid.nu = 1e12", "<= 33.1666666667"]);
    refused(&good().replace("nu = 0.1", "tau = 100.5"), &["fluid.tau = 100.5", "at most 100"]);
}

#[test]
fn sections_given_as_arrays_are_refused() {
    let text = good().replace("[domain]\nnx = 12\nny = 12\nnz = 12\n", "domain = [4, 4, 8]\n");
    refused(&text, &["domain = [4, 4, 8]", "must be a table", "[domain]"]);
    let text = format!("fluid = [0.1]\n{}", good().replace("[fluid]\nnu = 0.1\n", ""));
    refused(&text, &["fluid = [0.1]", "must be a table"]);
    let sphere =
        "\n[particles]\nshape = \"sphere\"\ndiameter = 4.0\ndensity = 1.5\nposition = [6.0, 6.0, 6.0]\n";
    refused(&format!("{}{sphere}", good()), &["`particles` at line", "[[particles]]"]);
    refused(&format!("particles = [[1, 2]]\n{}", good()), &["particles[0]", "table"]);
}

#[test]
fn particles_smaller_than_a_lattice_spacing_are_refused() {
    assert_eq!(MIN_PARTICLE_SIZE, 1.0);
    let sphere = |d: &str| {
        format!("{}\n[[particles]]\nshape = \"sphere\"\ndiameter = {d}\ndensity = 1.5\nposition = [6.0, 6.0, 6.0]\n", good())
    };
    refused(&sphere("1e-6"), &["particles[0].diameter = 0.000001", ">= 1"]);
    Case::parse(&sphere("1.0"), "good.toml").unwrap();
    let cyl = format!(
        "{}\n[[particles]]\nshape = \"cylinder\"\ndiameter = 3.0\nlength = 0.2\ndensity = 1.5\nposition = [6.0, 6.0, 6.0]\n",
        good()
    );
    refused(&cyl, &["particles[0].length = 0.2", ">= 1"]);
}
