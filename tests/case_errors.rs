//! Case-file errors name the file, the key and what is allowed; the shipped examples are valid.

use std::path::{Path, PathBuf};

use slurry::case::{Case, CaseErrorKind, Precision};

mod common;

use common::case_toml;

/// A 4 x 4 x 8 channel (periodic x and y) under a moving lid, f32 BGK.
fn good() -> String {
    case_toml(
        [4, 4, 8],
        "precision = \"f32\"\ntau = 0.65\ncollision = \"bgk\"",
        "xy",
        "steps = 20\noutput_every = 5",
    )
    .replace("z_max = \"no_slip\"", "z_max = { moving_wall = [0.02, 0.0, 0.0] }")
}

/// Writes `text` to `bad.toml` in a temporary directory and returns the error message.
fn error_of(text: &str) -> (String, PathBuf, tempfile::TempDir) {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("bad.toml");
    std::fs::write(&path, text).unwrap();
    let e = Case::from_file(&path).expect_err("case should be rejected");
    assert_eq!(e.file, path);
    (e.to_string(), path, dir)
}

fn assert_mentions(msg: &str, path: &Path, needles: &[&str]) {
    assert!(
        msg.starts_with(&format!("{}: ", path.display())),
        "message does not start with the file name: {msg}"
    );
    for n in needles {
        assert!(msg.contains(n), "message lacks {n:?}: {msg}");
    }
}

#[test]
fn good_case_parses() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("good.toml");
    std::fs::write(&path, good()).unwrap();
    let c = Case::from_file(&path).unwrap();
    assert_eq!(c.fluid.precision, Precision::F32);
    assert!((c.nu() - 0.05).abs() < 1e-15);
}

#[test]
fn missing_file_names_the_file() {
    let e = Case::from_file("/nonexistent/case.toml").unwrap_err();
    assert!(matches!(e.kind, CaseErrorKind::Read(_)));
    assert!(e.to_string().starts_with("/nonexistent/case.toml: cannot read"));
}

#[test]
fn wrong_key_names_file_and_key() {
    let (msg, path, _d) = error_of(&good().replace("tau = 0.65", "viscosity = 0.05"));
    assert_mentions(&msg, &path, &["unknown key `fluid.viscosity`", "allowed: precision, nu, tau"]);
}

#[test]
fn tau_at_one_half_names_fluid_tau() {
    let (msg, path, _d) = error_of(&good().replace("tau = 0.65", "tau = 0.5"));
    assert_mentions(&msg, &path, &["fluid.tau = 0.5", "must be finite and > 0.5"]);
}

#[test]
fn nonpositive_nu_names_fluid_nu() {
    let (msg, path, _d) = error_of(&good().replace("tau = 0.65", "nu = -0.01"));
    assert_mentions(&msg, &path, &["fluid.nu = -0.01", "> 0"]);
    let (msg, path, _d) = error_of(&good().replace("tau = 0.65", "nu = 0"));
    assert_mentions(&msg, &path, &["fluid.nu", "> 0"]);
}

#[test]
fn one_sided_periodic_names_both_faces() {
    let (msg, path, _d) = error_of(&good().replace("x_max = \"periodic\"", "x_max = \"no_slip\""));
    assert_mentions(&msg, &path, &["boundaries.x_min", "x_max", "pairs"]);
}

#[test]
fn wrong_precision_names_key_and_options() {
    let (msg, path, _d) = error_of(&good().replace("\"f32\"", "\"double\""));
    assert_mentions(&msg, &path, &["fluid.precision", "double", "`f32` or `f64`", "line 8"]);
}

#[test]
fn examples_parse_and_validate() {
    let dir = Path::new(env!("CARGO_MANIFEST_DIR")).join("examples");
    let mut n = 0;
    for entry in std::fs::read_dir(&dir).unwrap() {
        let path = entry.unwrap().path();
        if path.extension().is_some_and(|e| e == "toml") {
            let case = Case::from_file(&path).unwrap_or_else(|e| panic!("{e}"));
            case.fluid_params().validate().unwrap();
            case.boundaries().validate().unwrap();
            n += 1;
        }
    }
    assert!(n >= 3, "expected at least three example cases, found {n}");
}

// ---- particles ---------------------------------------------------------------------------

/// A 40 x 32 x 48 box, periodic along x, walls elsewhere, with one valid cylinder and one
/// valid random population; tests replace one line (or append one).
fn particles() -> String {
    let duct = case_toml([40, 32, 48], "nu = 0.05", "x", "steps = 10\noutput_every = 5");
    format!(
        r#"gravity = [0.0, 0.0, -4.0e-5]
{duct}
[ibm]
kernel = "roma3"
iterations = 1
marker_spacing = 0.7

[[particles]]
shape = "cylinder"
diameter = 6.0
length = 12.0
density = 1.25
position = [20.0, 16.0, 30.0]
axis = [0.0, 0.0, 1.0]
motion = "free"

[[random_particles]]
shape = "sphere"
diameter = 4.0
density = 1.25
count = 10
seed = 1
"#
    )
}

/// [`particles`] with the line starting with `prefix` (the first one) replaced by `line`.
fn p_edit(prefix: &str, line: &str) -> String {
    let mut done = false;
    let out: Vec<String> = particles()
        .lines()
        .map(|l| {
            if !done && l.starts_with(prefix) {
                done = true;
                line.to_string()
            } else {
                l.to_string()
            }
        })
        .collect();
    assert!(done, "no line starting with {prefix}");
    out.join("\n") + "\n"
}

/// [`particles`] with the random population's lines starting with `prefix` replaced.
fn r_edit(prefix: &str, line: &str) -> String {
    let text = particles();
    let (head, tail) = text.split_once("[[random_particles]]").unwrap();
    let tail: Vec<String> =
        tail.lines().map(|l| if l.starts_with(prefix) { line.to_string() } else { l.to_string() }).collect();
    format!("{head}[[random_particles]]{}\n", tail.join("\n"))
}

fn rejects(text: &str, needles: &[&str]) {
    let (msg, path, _d) = error_of(text);
    assert_mentions(&msg, &path, needles);
    assert!(!msg.trim_end().contains('\n'), "not one line: {msg}");
}

#[test]
fn particle_case_parses() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("p.toml");
    std::fs::write(&path, particles()).unwrap();
    let c = Case::from_file(&path).unwrap_or_else(|e| panic!("{e}"));
    assert_eq!(c.particle_count(), 11);
    assert_eq!(c.bodies().unwrap().len(), 11);
}

#[test]
fn unknown_particle_keys_name_the_entry() {
    rejects(
        &p_edit("diameter", "radius = 3.0"),
        &["unknown key `particles[0].radius`", "allowed: shape, diameter"],
    );
    rejects(&r_edit("seed", "seed = 1\nnumber = 3"), &["unknown key `random_particles[0].number`", "count"]);
    rejects(&p_edit("iterations", "iterations = 1\nsmooth = true"), &["unknown key `ibm.smooth`", "kernel"]);
    rejects(
        &particles().replace("[fluid]\n", "[fluid]\ngravity = [0.0, 0.0, -1.0]\n"),
        &["unknown key `fluid.gravity`", "gravity is a top-level key"],
    );
    rejects(
        &particles().replace("[[particles]]", "[particles]"),
        &["`particles` at line", "expected a sequence", "[[particles]]"],
    );
}

#[test]
fn gravity_must_be_finite() {
    rejects(&p_edit("gravity", "gravity = [0.0, nan, 0.0]"), &["gravity = [0, NaN, 0]", "finite"]);
}

#[test]
fn ibm_ranges() {
    rejects(&p_edit("kernel", "kernel = \"gauss\""), &["ibm.kernel", "gauss", "linear", "roma3", "peskin4"]);
    rejects(&p_edit("iterations", "iterations = 0"), &["ibm.iterations = 0", ">= 1"]);
    rejects(&p_edit("marker_spacing", "marker_spacing = 0.2"), &["ibm.marker_spacing = 0.2", "[0.3, 1]"]);
    rejects(&p_edit("marker_spacing", "marker_spacing = 1.5"), &["ibm.marker_spacing = 1.5", "[0.3, 1]"]);
}

#[test]
fn particle_shape_and_size() {
    rejects(&p_edit("shape", "shape = \"cube\""), &["particles[0].shape", "cube", "sphere", "cylinder"]);
    rejects(&p_edit("diameter", ""), &["missing key `particles[0].diameter`"]);
    rejects(&p_edit("diameter", "diameter = 0.0"), &["particles[0].diameter = 0", "> 0"]);
    rejects(&p_edit("length", "length = -1.0"), &["particles[0].length = -1", "> 0"]);
    rejects(&p_edit("length", ""), &["missing key `particles[0].length`", "cylinder"]);
    rejects(
        &p_edit("shape", "shape = \"sphere\""),
        &["particles[0].length = 12", "only allowed with shape = \"cylinder\""],
    );
    rejects(&p_edit("density", "density = 0.0"), &["particles[0].density = 0", "> 0", "density ratio"]);
    rejects(&p_edit("density", "density = inf"), &["particles[0].density = inf", "finite"]);
    rejects(
        &p_edit("motion", "motion = \"floating\""),
        &["particles[0].motion", "floating", "free", "fixed", "prescribed"],
    );
}

#[test]
fn particle_orientation() {
    rejects(
        &p_edit("axis", "axis = [0.0, 0.0, 1.0]\norientation = [1.0, 0.0, 0.0, 0.0]"),
        &["particles[0].axis = [0, 0, 1]", "either orientation", "not both"],
    );
    rejects(
        &p_edit("axis", "orientation = [1.0, 0.0, 0.0, 0.01]"),
        &["particles[0].orientation = [1, 0, 0, 0.01]", "unit quaternion", "|norm - 1| <= 0.000001"],
    );
    rejects(&p_edit("axis", "axis = [0.0, 0.0, 0.0]"), &["particles[0].axis = [0, 0, 0]", "non-zero"]);
    // A quaternion within 1e-6 of unit length is normalised.
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("q.toml");
    std::fs::write(&path, p_edit("axis", "orientation = [1.0000005, 0.0, 0.0, 0.0]")).unwrap();
    Case::from_file(&path).unwrap();
}

#[test]
fn particle_velocities() {
    rejects(
        &p_edit("motion", "motion = \"fixed\"\nvelocity = [0.01, 0.0, 0.0]"),
        &["particles[0].velocity = [0.01, 0, 0]", "\"fixed\" does not move"],
    );
    rejects(
        &p_edit("motion", "motion = \"fixed\"\nangular_velocity = [0.0, 0.0, 0.01]"),
        &["particles[0].angular_velocity = [0, 0, 0.01]", "\"fixed\" does not move"],
    );
    rejects(&p_edit("motion", "velocity = [nan, 0.0, 0.0]"), &["particles[0].velocity", "finite"]);
    rejects(
        &p_edit("motion", "motion = \"prescribed\"\nvelocity = [0.2, 0.0, 0.0]"),
        &["particles[0].velocity = [0.2, 0, 0]", "Mach", "run.mach_limit = 0.3"],
    );
    rejects(
        &p_edit("motion", "motion = \"prescribed\"\nangular_velocity = [0.0, 0.0, 0.03]"),
        &["particles[0].angular_velocity = [0, 0, 0.03]", "surface point", "run.mach_limit = 0.3"],
    );
}

#[test]
fn particles_must_lie_inside_the_box() {
    // z: the cylinder (half length 6) at z = 5 reaches -1; allowed -0.5 .. 47.5 (the walls).
    rejects(
        &p_edit("position", "position = [20.0, 16.0, 5.0]"),
        &["particles[0].position = [20, 16, 5]", "within [-0.5, 47.5]", "z must be in [5.5000, 41.5000]"],
    );
    rejects(
        &p_edit("position", "position = [20.0, 29.0, 30.0]"),
        &["particles[0].position = [20, 29, 30]", "on y", "within [-0.5, 31.5]"],
    );
    rejects(&p_edit("length", "length = 60.0"), &["particles[0].position", "does not fit between the walls"]);
    // Periodic x: the centre must lie in the period; the particle must be shorter than it.
    rejects(
        &p_edit("position", "position = [40.0, 16.0, 30.0]"),
        &["particles[0].position = [40, 16, 30]", "periodic x axis", "[-0.5, 39.5)"],
    );
    rejects(
        &p_edit("axis", "axis = [1.0, 0.0, 0.0]").replace("length = 12.0", "length = 41.0"),
        &["particles[0].position", "periodic x axis", "shorter than the period 40"],
    );
    rejects(&p_edit("position", "position = [20.0, inf, 30.0]"), &["particles[0].position", "finite"]);
}

#[test]
fn overlapping_particles_name_both() {
    let second = "\n[[particles]]\nshape = \"sphere\"\ndiameter = 6.0\ndensity = 1.0\nposition = [25.5, 16.0, 30.0]\nmotion = \"fixed\"\n";
    let text = particles().replace("[[random_particles]]", &format!("{second}\n[[random_particles]]"));
    rejects(&text, &["particles[1].position = [25.5, 16, 30]", "overlaps particles[0]", "[20, 16, 30]"]);
    // 0.5 further out they are clear (the cylinder's radius 3 + the sphere's 3 = 6).
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("ok.toml");
    std::fs::write(&path, text.replace("[25.5, 16.0, 30.0]", "[26.5, 16.0, 30.0]")).unwrap();
    Case::from_file(&path).unwrap_or_else(|e| panic!("{e}"));
    // Through the periodic x boundary.
    let wrap = particles().replace("position = [20.0, 16.0, 30.0]", "position = [1.0, 16.0, 30.0]").replace(
        "[[random_particles]]",
        &format!("{}\n[[random_particles]]", second.replace("25.5", "37.0")),
    );
    rejects(&wrap, &["particles[1].position = [37, 16, 30]", "overlaps particles[0]"]);
}

#[test]
fn random_population_rules() {
    rejects(
        &r_edit("count", "count = 10\nvolume_fraction = 0.1"),
        &["random_particles[0].volume_fraction = 0.1", "not both"],
    );
    rejects(&r_edit("count", ""), &["missing key `random_particles[0].count`", "volume_fraction"]);
    rejects(&r_edit("count", "count = 0"), &["random_particles[0].count = 0", ">= 1"]);
    rejects(&r_edit("count", "count = -3"), &["random_particles[0].count", "-3"]);
    rejects(
        &r_edit("count", "volume_fraction = 0.7"),
        &["random_particles[0].volume_fraction = 0.7", "(0, 0.6]"],
    );
    rejects(
        &r_edit("count", "volume_fraction = 0.0"),
        &["random_particles[0].volume_fraction = 0", "(0, 0.6]"],
    );
    rejects(
        &r_edit("count", "volume_fraction = 1e-6"),
        &["random_particles[0].volume_fraction = 0.000001", "rounds to 0"],
    );
    rejects(&r_edit("seed", "seed = 1\nclearance = 0.4"), &["random_particles[0].clearance = 0.4", ">= 0.5"]);
    rejects(&r_edit("seed", "seed = -1"), &["random_particles[0].seed", "-1"]);
    rejects(&r_edit("seed", ""), &["missing key `random_particles[0].seed`"]);
    rejects(
        &r_edit("seed", "seed = 1\nmotion = \"prescribed\""),
        &["random_particles[0].motion = \"prescribed\"", "\"free\" or \"fixed\""],
    );
    rejects(&r_edit("shape", "shape = \"cylinder\""), &["missing key `random_particles[0].length`"]);
    rejects(&r_edit("diameter", "diameter = -4.0"), &["random_particles[0].diameter = -4", "> 0"]);
}

#[test]
fn random_region_must_keep_off_the_walls() {
    let region = |r: &str| r_edit("seed", &format!("seed = 1\nregion = {r}"));
    rejects(
        &region("[[0.0, 0.0, 0.5], [39.0, 30.5, 46.5]]"),
        &["random_particles[0].region = [[0, 0, 0.5], [39, 30.5, 46.5]]", "on y", "0.5 <= lo < hi <= 30.5"],
    );
    rejects(
        &region("[[-1.0, 0.5, 0.5], [39.0, 30.5, 46.5]]"),
        &["random_particles[0].region", "on x", "-0.5 <= lo < hi <= 39.5"],
    );
    rejects(
        &region("[[0.0, 0.5, 20.0], [39.0, 30.5, 10.0]]"),
        &["random_particles[0].region", "on z", "lo < hi"],
    );
}

#[test]
fn impossible_placement_says_how_many_were_placed() {
    // More than fit at all is refused before placing (issue 15: tests/issue_oom_abort.rs).
    rejects(
        &r_edit("count", "count = 2000"),
        &["random_particles[0].count = 2000", "at most 0.6", "count <= 988"],
    );
    rejects(
        &r_edit("count", "count = 900"),
        &["random_particles[0].count = 900", "placed only", "of 900", "attempts"],
    );
    rejects(
        &r_edit("count", "volume_fraction = 0.5"),
        &["random_particles[0].volume_fraction = 0.5", "placed only", "lower the count or volume fraction"],
    );
}

/// `[contacts]`: parameters out of range name the key and the range; unknown keys are refused;
/// an empty section is Table 1.
#[test]
fn contact_section_errors_name_key_and_range() {
    let with = |body: &str| format!("{}\n[contacts]\n{body}\n", particles());
    rejects(&with("delta_sat = 1.5"), &["contacts.delta_sat", "1.5", "(0, delta_d = 1)"]);
    rejects(&with("k = -1.0"), &["contacts.k", "-1", "positive"]);
    rejects(&with("substeps = 0"), &["contacts.substeps", "0", "[1, 1024]"]);
    rejects(&with("stiffness = 3.0"), &["contacts.stiffness"]);
    rejects(&with("damping = \"backward\""), &["damping", "backward", "explicit", "implicit"]);
    rejects(
        &with("damping = \"implicit\"\nlubrication_substeps = 4"),
        &["contacts.lubrication_substeps", "4", "damping = \"implicit\""],
    );
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("ok.toml");
    std::fs::write(&path, with("")).unwrap();
    let case = slurry::case::Case::from_file(&path).unwrap();
    let cp = case.coupling_params();
    assert_eq!(cp.contacts, Some(slurry::contact::ContactParams::default()));
    assert_eq!(cp.contacts.unwrap().substeps, slurry::contact::DEFAULT_SUBSTEPS);
}

// ---- impeller ----------------------------------------------------------------------------

/// A closed 40 x 40 x 48 box with a PBT of D = 20 at its centre.
fn impeller() -> String {
    let closed_box = case_toml([40, 40, 48], "nu = 0.02", "", "steps = 10\noutput_every = 5");
    format!(
        "{closed_box}\n[impeller]\nkind = \"pbt\"\ndiameter = 20.0\nspeed = 1.0e-3\nramp_steps = 100\nblade_thickness = 0.75\n"
    )
}

/// `[impeller]`: defaults, keys of the other kind, ranges, fit in the box, and particles that
/// overlap it are refused, naming the key.
#[test]
fn impeller_section_errors_name_key_and_range() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("ok.toml");
    std::fs::write(&path, impeller()).unwrap();
    let case = Case::from_file(&path).unwrap();
    let setup = case.impeller_setup().unwrap().unwrap();
    assert_eq!(setup.centre, slurry::rigid::Vec3::new(19.5, 19.5, 23.5));
    assert!((setup.tip_speed() - std::f64::consts::PI * 20.0e-3).abs() < 1e-15);

    let with = |line: &str| format!("{}{line}\n", impeller());
    rejects(&with("blade_count = 3"), &["impeller.blade_count", "blades"]);
    // Blades of the default thickness 3 D/132 = 0.45 are thinner than twice the default
    // retraction of the forcing markers, and a retraction outside [0, 0.5) is refused.
    rejects(
        &impeller().replace("blade_thickness = 0.75\n", ""),
        &["ibm.retraction", "impeller.blade_thickness = 0.45"],
    );
    rejects(&format!("[ibm]\nretraction = 0.5\n\n{}", impeller()), &["ibm.retraction = 0.5", "[0, 0.5)"]);
    rejects(&format!("[ibm]\nretraction = -0.1\n\n{}", impeller()), &["ibm.retraction = -0.1", "[0, 0.5)"]);
    rejects(&with("thickness = 1.0"), &["impeller.thickness", "only for kind = \"disk\""]);
    rejects(&with("pitch_deg = 95.0"), &["impeller.pitch_deg", "95", "0 < pitch < 90"]);
    rejects(&impeller().replace("speed = 1.0e-3", "speed = 1.0e-2"), &["impeller.speed", "tip Mach", "0.3"]);
    rejects(
        &impeller().replace("diameter = 20.0", "diameter = 44.0"),
        &["impeller.centre", "inside the box"],
    );
    rejects(&with("centre = [19.5, 19.5, 47.0]"), &["impeller.centre", "inside the box"]);
    rejects(
        &impeller()
            .replace("z_max = \"no_slip\"", "z_max = \"periodic\"")
            .replace("z_min = \"no_slip\"", "z_min = \"periodic\""),
        &["impeller.shaft", "z_max"],
    );
    // A particle through the shaft.
    let particle = "\n[[particles]]\nshape = \"sphere\"\ndiameter = 4.0\ndensity = 1.25\nposition = [19.5, 21.0, 40.0]\nmotion = \"free\"\n";
    rejects(&format!("{}{particle}", impeller()), &["particles[0].position", "overlaps the impeller"]);
    // Clear of it: accepted.
    let clear = particle.replace("[19.5, 21.0, 40.0]", "[5.0, 5.0, 40.0]");
    let path = dir.path().join("clear.toml");
    std::fs::write(&path, format!("{}{clear}", impeller())).unwrap();
    Case::from_file(&path).unwrap();
}
