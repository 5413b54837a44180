//! One test per validation rule.

use super::*;

const BASE: &str = r#"
[domain]
nx = 4
ny = 4
nz = 8

[fluid]
precision = "f64"
nu = 0.1
collision = "trt"
body_force = [1e-6, 0.0, 0.0]

[boundaries]
x_min = "periodic"
x_max = "periodic"
y_min = "periodic"
y_max = "periodic"
z_min = "no_slip"
z_max = { moving_wall = [0.01, 0.0, 0.0] }

[run]
steps = 100
output_every = 10
"#;

/// BASE with the line starting with `prefix` replaced by `line` (or `line` appended to
/// section `[section]` when `prefix` starts with `[`).
fn edit(prefix: &str, line: &str) -> String {
    if prefix.starts_with('[') {
        return BASE.replace(prefix, &format!("{prefix}\n{line}"));
    }
    let mut found = false;
    let out: Vec<String> = BASE
        .lines()
        .map(|l| {
            if l.starts_with(prefix) {
                found = true;
                line.to_string()
            } else {
                l.to_string()
            }
        })
        .collect();
    assert!(found, "no line starting with {prefix}");
    out.join("\n")
}

fn err(text: &str) -> CaseError {
    match Case::parse(text, "t.toml") {
        Ok(c) => panic!("accepted: {c:?}"),
        Err(e) => e,
    }
}

/// Asserts the error names `key` and that its message contains every needle.
fn assert_err(text: &str, key: &str, needles: &[&str]) {
    let e = err(text);
    let msg = e.to_string();
    assert!(msg.starts_with("t.toml: "), "{msg}");
    assert_eq!(e.kind.key(), Some(key), "{msg}");
    assert!(msg.contains(key), "{msg}");
    for n in needles {
        assert!(msg.contains(n), "{msg} lacks {n}");
    }
}

#[test]
fn base_case_is_valid_and_converts() {
    let c = Case::parse(BASE, "t.toml").unwrap();
    assert_eq!(c.grid(), Grid::new(4, 4, 8));
    assert!((c.tau() - 0.8).abs() < 1e-12);
    let p = c.fluid_params();
    assert_eq!(p.collision, Collision::Trt { magic: 3.0 / 16.0 });
    assert_eq!(p.body_force, [1e-6, 0.0, 0.0]);
    let b = c.boundaries();
    assert_eq!(b.get(Face::XMin), FaceBoundary::Periodic);
    assert_eq!(b.get(Face::ZMin), FaceBoundary::NoSlip);
    assert_eq!(b.get(Face::ZMax), FaceBoundary::MovingWall { velocity: [0.01, 0.0, 0.0] });
    assert_eq!(c.run.mach_limit, 0.3);
    assert_eq!(c.initial, InitialSection::default());
    assert_eq!(c.output_rows(), 11);
    assert_eq!(c.initial_state(1, 2, 3), (1.0, [0.0; 3]));
}

#[test]
fn tau_converts_to_nu() {
    let c = Case::parse(&edit("nu =", "tau = 0.65"), "t.toml").unwrap();
    assert!((c.nu() - 0.05).abs() < 1e-15);
    assert!((c.fluid_params().tau() - 0.65).abs() < 1e-15);
}

#[test]
fn normalised_case_round_trips_through_toml() {
    let c = Case::parse(BASE, "t.toml").unwrap();
    let text = toml::to_string(&c).unwrap();
    assert_eq!(Case::parse(&text, "n.toml").unwrap(), c);
}

#[test]
fn syntax_error_has_line() {
    let e = err("[domain\nnx = 1");
    assert!(matches!(e.kind, CaseErrorKind::Syntax { line: 1, .. }), "{e}");
}

#[test]
fn unknown_key_in_section_lists_allowed() {
    assert_err(
        &edit("nu =", "viscosity = 0.1"),
        "fluid.viscosity",
        &["unknown key", "nu, tau", "precision", "body_force"],
    );
}

#[test]
fn unknown_section_lists_allowed() {
    assert_err(
        &format!("{BASE}\n[output]\nevery = 1\n"),
        "output",
        &[
            "unknown key",
            "domain, fluid, boundaries, initial, run, ibm, contacts, particles, random_particles",
        ],
    );
}

#[test]
fn unknown_face_is_rejected() {
    assert_err(&edit("[boundaries]", "w_min = \"periodic\""), "boundaries.w_min", &["x_min"]);
}

#[test]
fn missing_keys_are_named() {
    assert_err(&edit("nz =", ""), "domain.nz", &["missing key"]);
    assert_err(&edit("steps =", ""), "run.steps", &["missing key"]);
    assert_err(&edit("z_max =", ""), "boundaries.z_max", &["missing key", "no_slip"]);
    let no_domain = BASE.replace("[domain]\nnx = 4\nny = 4\nnz = 8\n", "");
    assert_err(&no_domain, "domain", &["missing key"]);
    assert_err(&edit("nu =", ""), "fluid.nu", &["missing key", "tau"]);
}

#[test]
fn wrong_precision_names_options() {
    assert_err(
        &edit("precision =", "precision = \"f16\""),
        "fluid.precision",
        &["f16", "f32", "f64", "line 8"],
    );
}

#[test]
fn wrong_collision_names_options() {
    assert_err(&edit("collision =", "collision = \"mrt\""), "fluid.collision", &["mrt", "bgk", "trt"]);
}

#[test]
fn wrong_boundary_kind_names_options() {
    assert_err(
        &edit("z_min =", "z_min = \"noslip\""),
        "boundaries.z_min",
        &["noslip", "periodic", "no_slip", "moving_wall"],
    );
}

#[test]
fn wrong_type_names_key() {
    assert_err(&edit("nx =", "nx = \"four\""), "domain.nx", &["four"]);
    assert_err(&edit("nx =", "nx = -4"), "domain.nx", &["-4"]);
    assert_err(&edit("nx =", "nx = 4.5"), "domain.nx", &["line"]);
}

#[test]
fn zero_size_is_rejected() {
    assert_err(&edit("ny =", "ny = 0"), "domain.ny", &["ny = 0", ">= 1"]);
}

#[test]
fn huge_grid_is_rejected() {
    let t = edit("nx =", "nx = 2000").replace("ny = 4", "ny = 2000").replace("nz = 8", "nz = 2000");
    assert_err(&t, "domain", &["2^32"]);
}

#[test]
fn tau_at_or_below_half_is_rejected() {
    assert_err(&edit("nu =", "tau = 0.5"), "fluid.tau", &["fluid.tau = 0.5", "> 0.5", "tau = 3 nu + 1/2"]);
    assert_err(&edit("nu =", "tau = 0.2"), "fluid.tau", &["> 0.5"]);
    assert_err(&edit("nu =", "tau = nan"), "fluid.tau", &["NaN"]);
}

#[test]
fn nonpositive_nu_is_rejected() {
    assert_err(&edit("nu =", "nu = 0.0"), "fluid.nu", &["fluid.nu = 0", "> 0"]);
    assert_err(&edit("nu =", "nu = -0.1"), "fluid.nu", &["-0.1"]);
    assert_err(&edit("nu =", "nu = inf"), "fluid.nu", &["finite"]);
}

#[test]
fn nu_and_tau_together_are_rejected() {
    assert_err(&edit("nu =", "nu = 0.1\ntau = 0.8"), "fluid.tau", &["not both"]);
}

#[test]
fn magic_rules() {
    assert_err(&edit("collision =", "collision = \"trt\"\nmagic = 0.0"), "fluid.magic", &["> 0"]);
    assert_err(
        &edit("collision =", "collision = \"bgk\"\nmagic = 0.25"),
        "fluid.magic",
        &["only allowed", "trt"],
    );
    let c = Case::parse(&edit("collision =", "collision = \"trt\"\nmagic = 0.25"), "t").unwrap();
    assert_eq!(c.fluid_params().collision, Collision::Trt { magic: 0.25 });
}

#[test]
fn nonfinite_body_force_is_rejected() {
    assert_err(&edit("body_force =", "body_force = [0.0, nan, 0.0]"), "fluid.body_force", &["finite"]);
}

#[test]
fn one_sided_periodic_names_both_faces() {
    assert_err(
        &edit("x_max =", "x_max = \"no_slip\""),
        "boundaries.x_min/x_max",
        &["pairs", "\"periodic\" / \"no_slip\""],
    );
}

#[test]
fn wall_moving_through_itself_is_rejected() {
    assert_err(
        &edit("z_max =", "z_max = { moving_wall = [0.0, 0.0, 0.01] }"),
        "boundaries.z_max.moving_wall",
        &["z component must be 0"],
    );
}

#[test]
fn fast_wall_is_rejected() {
    assert_err(
        &edit("z_max =", "z_max = { moving_wall = [0.3, 0.0, 0.0] }"),
        "boundaries.z_max.moving_wall",
        &["Mach", "run.mach_limit = 0.3"],
    );
}

#[test]
fn run_ranges() {
    assert_err(&edit("steps =", "steps = 0"), "run.steps", &[">= 1"]);
    assert_err(&edit("output_every =", "output_every = 0"), "run.output_every", &["1 <= "]);
    assert_err(&edit("output_every =", "output_every = 101"), "run.output_every", &["<= run.steps = 100"]);
    assert_err(&edit("[run]", "mach_limit = 0.0"), "run.mach_limit", &["(0, 1]"]);
    assert_err(&edit("[run]", "mach_limit = 1.5"), "run.mach_limit", &["(0, 1]"]);
    let c = Case::parse(&edit("output_every =", "output_every = 30"), "t").unwrap();
    assert_eq!(c.output_rows(), 5); // 0, 30, 60, 90, 100
}

#[test]
fn initial_rules() {
    let with = |l: &str| format!("{BASE}\n[initial]\n{l}\n");
    assert_err(&with("density = 0.0"), "initial.density", &["> 0"]);
    assert_err(&with("velocity = [0.5, 0.0, 0.0]"), "initial.velocity", &["Mach"]);
    assert_err(&with("velocity = [inf, 0.0, 0.0]"), "initial.velocity", &["finite"]);
    assert_err(&with("amplitude = 0.01"), "initial.amplitude", &["taylor_green"]);
    assert_err(&with("kind = \"taylor_green\""), "initial.amplitude", &["missing key"]);
    assert_err(
        &with("kind = \"taylor_green\"\namplitude = 0.01\nvelocity = [0.0, 0.0, 0.0]"),
        "initial.velocity",
        &["not allowed"],
    );
    assert_err(&with("kind = \"taylor_green\"\namplitude = 0.5"), "initial.amplitude", &["(0, "]);
    assert_err(&with("kind = \"vortex\""), "initial.kind", &["uniform", "taylor_green"]);
    let closed = BASE.replace("\"periodic\"", "\"no_slip\"");
    assert_err(
        &format!("{closed}\n[initial]\nkind = \"taylor_green\"\namplitude = 0.01\n"),
        "initial.kind",
        &["periodic boundaries.x_min"],
    );
    let c = Case::parse(&with("velocity = [0.01, 0.0, 0.0]\ndensity = 1.1"), "t").unwrap();
    assert_eq!(c.initial_state(0, 0, 0), (1.1, [0.01, 0.0, 0.0]));
}

#[test]
fn taylor_green_field_is_divergence_free_and_bounded() {
    let c =
        Case::parse(&format!("{BASE}\n[initial]\nkind = \"taylor_green\"\namplitude = 0.02\n"), "t").unwrap();
    let (nx, ny) = (4, 4);
    let mut umax: f64 = 0.0;
    for y in 0..ny {
        for x in 0..nx {
            let (rho, u) = c.initial_state(x, y, 0);
            assert!(rho > 0.99 && rho < 1.01);
            umax = umax.max(norm(u));
            assert_eq!(u[2], 0.0);
        }
    }
    assert!(umax <= 0.02 * 2f64.sqrt() + 1e-12);
}

#[test]
fn every_error_is_one_line() {
    for t in [
        edit("precision =", "precision = \"f16\""),
        edit("nu =", "viscosity = 0.1"),
        edit("nu =", "tau = 0.5"),
        "[domain\n".to_string(),
    ] {
        let m = err(&t).to_string();
        assert!(!m.trim_end().contains('\n'), "{m}");
    }
}

#[test]
fn checkpoint_every_must_be_even_and_within_steps() {
    for bad in ["checkpoint_every = 3", "checkpoint_every = 0", "checkpoint_every = 200"] {
        assert_err(&edit("[run]", bad), "run.checkpoint_every", &["even", "<= run.steps = 100"]);
    }
    let ok = Case::parse(&edit("[run]", "checkpoint_every = 20"), "t.toml").unwrap();
    assert_eq!(ok.run.checkpoint_every, Some(20));
    // The fingerprint ignores the run length, the checkpoint cadence, the snapshots and the
    // Mach limit (a run may be resumed with other ones), nothing else; at the default Mach
    // limit it is the normalised text without the first two, as in older versions.
    let longer = Case::parse(&edit("steps = 100", "steps = 500"), "t.toml").unwrap();
    assert_eq!(ok.fingerprint(), longer.fingerprint());
    let looser =
        Case::parse(&edit("[run]", "checkpoint_every = 20\nmach_limit = 0.4\nsnapshots = [7]"), "t.toml")
            .unwrap();
    assert_eq!(ok.fingerprint(), looser.fingerprint());
    let mut bare = ok.clone();
    (bare.run.steps, bare.run.checkpoint_every) = (0, None);
    assert_eq!(ok.fingerprint(), toml::to_string(&bare).unwrap());
    let other = Case::parse(&edit("nu = 0.1", "nu = 0.2"), "t.toml").unwrap();
    assert_ne!(ok.fingerprint(), other.fingerprint());
    let cadence = Case::parse(&edit("output_every = 10", "output_every = 20"), "t.toml").unwrap();
    assert_ne!(ok.fingerprint(), cadence.fingerprint());
}

// ---- particles -------------------------------------------------------------------------

/// A closed 40 x 32 x 48 box with periodic x, for particle tests.
const PBOX: &str = r#"
[domain]
nx = 40
ny = 32
nz = 48

[fluid]
nu = 0.05

[boundaries]
x_min = "periodic"
x_max = "periodic"
y_min = "no_slip"
y_max = "no_slip"
z_min = "no_slip"
z_max = "no_slip"

[run]
steps = 10
output_every = 5
"#;

fn pcase(extra: &str) -> Case {
    Case::parse(&format!("gravity = [0.0, 0.0, -4e-5]\n{PBOX}\n{extra}"), "p.toml")
        .unwrap_or_else(|e| panic!("{e}"))
}

#[test]
fn explicit_particles_become_bodies() {
    let c = pcase(
        r#"
[ibm]
kernel = "peskin4"
iterations = 2
marker_spacing = 0.5

[[particles]]
shape = "cylinder"
diameter = 6.0
length = 12.0
density = 1.25
position = [10.0, 16.0, 20.0]
axis = [1.0, 0.0, 0.0]

[[particles]]
shape = "sphere"
diameter = 6.0
density = 2.0
position = [30.0, 16.0, 20.0]
orientation = [0.0, 0.0, 0.0, 1.0]
velocity = [0.01, 0.0, 0.0]
angular_velocity = [0.0, 0.0, 0.001]
motion = "prescribed"
"#,
    );
    assert!(c.has_particles());
    assert_eq!(c.particle_count(), 2);
    let p = c.coupling_params();
    assert_eq!(p.kernel, crate::ibm::DeltaKernel::Peskin4);
    assert_eq!((p.iterations, p.marker_spacing, p.gravity), (2, 0.5, [0.0, 0.0, -4e-5]));
    let b = c.bodies().unwrap();
    assert_eq!(b.len(), 2);
    assert!(b[0].is_free());
    // axis = x: the body z axis points along world x.
    let z = b[0].vector_to_world(&crate::rigid::Vec3::z());
    assert!((z - crate::rigid::Vec3::x()).norm() < 1e-15, "{z}");
    assert!((b[0].mass() - 1.25 * std::f64::consts::PI * 9.0 * 12.0).abs() < 1e-9);
    assert_eq!(b[1].velocity, crate::rigid::Vec3::new(0.01, 0.0, 0.0));
    assert!(matches!(b[1].motion(), crate::rigid::Motion::Prescribed(_)));
    // q = [0, 0, 0, 1]: half a turn about z.
    let x = b[1].vector_to_world(&crate::rigid::Vec3::x());
    assert!((x + crate::rigid::Vec3::x()).norm() < 1e-15);
}

#[test]
fn cases_without_particles_are_unchanged_by_the_particle_keys() {
    let c = Case::parse(BASE, "t.toml").unwrap();
    assert!(!c.has_particles());
    assert_eq!(c.normalised(), c);
    assert!(c.bodies().unwrap().is_empty());
    let text = toml::to_string(&c).unwrap();
    for k in ["gravity", "ibm", "particles"] {
        assert!(!text.contains(k), "{text}");
    }
}

#[test]
fn normalised_particle_case_round_trips_through_toml() {
    let c = pcase(
        "[[particles]]\nshape = \"sphere\"\ndiameter = 4.0\ndensity = 1.5\nposition = [5.0, 6.0, 7.0]\nmotion = \"fixed\"\n\n\
         [[random_particles]]\nshape = \"cylinder\"\ndiameter = 4.0\nlength = 8.0\ndensity = 1.25\ncount = 5\nseed = 9\n",
    );
    let n = c.normalised();
    assert_eq!(n.ibm, Some(IbmSection::default()));
    assert_eq!(n.particles[0].velocity, Some([0.0; 3]));
    let text = toml::to_string(&n).unwrap();
    let back = Case::parse(&text, "n.toml").unwrap();
    assert_eq!(back, n);
    assert_eq!(back.particle_inits().unwrap(), c.particle_inits().unwrap());
}

/// Random placement through the case: the count, determinism for a seed, every particle
/// inside its region (1 from the walls), every pair at least the clearance apart (periodic
/// images included), and random orientations.
#[test]
fn random_population_is_counted_deterministic_clear_and_inside() {
    let text = r#"
[[particles]]
shape = "sphere"
diameter = 8.0
density = 1.0
position = [20.0, 16.0, 24.0]
motion = "fixed"

[[random_particles]]
shape = "cylinder"
diameter = 4.0
length = 12.0
density = 1.25
volume_fraction = 0.08
seed = 7
clearance = 1.5

[[random_particles]]
shape = "sphere"
diameter = 3.0
density = 2.0
count = 20
seed = 8
region = [[-0.5, 0.5, 0.5], [39.5, 30.5, 12.0]]
"#;
    let c = pcase(text);
    // 0.08 * 40 * 32 * 48 / (pi 4 12) = 32.6
    assert_eq!(c.random_count(0), 33);
    assert_eq!(c.particle_count(), 1 + 33 + 20);
    let a = c.particle_inits().unwrap();
    let b = pcase(text).particle_inits().unwrap();
    assert_eq!(a, b, "not deterministic");
    assert_eq!(a.len(), 54);
    let other = pcase(&text.replace("seed = 7", "seed = 70")).particle_inits().unwrap();
    assert_ne!(a[1].position, other[1].position);

    let geometry = placement::BoxGeometry { n: [40, 32, 48], periodic: [true, false, false] };
    let mut cells = placement::CellList::new(geometry, 14.0);
    let mut tilted = 0;
    for (i, p) in a.iter().enumerate() {
        let shape = match p.shape {
            ShapeKind::Sphere => placement::ShapeDims::Sphere { diameter: p.diameter },
            ShapeKind::Cylinder => {
                placement::ShapeDims::Cylinder { diameter: p.diameter, length: p.length.unwrap() }
            }
        };
        let body = shape.at(p.position, &p.orientation);
        let e = body.half_extents();
        for ax in 1..3 {
            assert!(p.position[ax] - e[ax] >= 0.5 - 1e-12, "particle {i} too close to a wall");
            assert!(p.position[ax] + e[ax] <= [40.0, 32.0, 48.0][ax] - 1.5 + 1e-12);
        }
        assert!((-0.5..39.5).contains(&p.position[0]));
        if i > 33 {
            assert!(p.position[2] + e[2] <= 12.0 && p.position[0] - e[0] >= -0.5, "outside its region");
        }
        // 1.5 from the population-0 cylinders (placed against everything before them), 1
        // for the later spheres.
        let clearance = if (1..34).contains(&i) {
            1.5
        } else if i == 0 {
            0.0
        } else {
            1.0
        };
        assert_eq!(cells.first_conflict(&body, clearance - 1e-9), None, "particle {i} too close");
        cells.insert(body);
        let axis = p.orientation * crate::rigid::Vec3::z();
        if axis.z.abs() < 0.9 {
            tilted += 1;
        }
    }
    assert!(tilted > 20, "orientations do not look random: {tilted} of 53 tilted");
}

/// The paper's beds (Derksen 2020: 251 x 251 x 240, volume fraction 0.148, d = 12):
/// 411 cylinders of l/d = 4 and 1644 of l/d = 1 are placed, quickly.
#[test]
fn paper_beds_are_placed_quickly() {
    for (length, count) in [(48.0, 411), (12.0, 1644)] {
        let text = format!(
            r#"
[domain]
nx = 251
ny = 251
nz = 240
[fluid]
nu = 0.05
[boundaries]
x_min = "no_slip"
x_max = "no_slip"
y_min = "no_slip"
y_max = "no_slip"
z_min = "no_slip"
z_max = "no_slip"
[run]
steps = 1
output_every = 1
[[random_particles]]
shape = "cylinder"
diameter = 12.0
length = {length}
density = 1.25
volume_fraction = 0.148
seed = 1
"#
        );
        let c = Case::parse_unchecked(&text).unwrap();
        assert!(c.random_count(0).abs_diff(count) <= 5, "{}", c.random_count(0));
        let t0 = std::time::Instant::now();
        let inits = c.particle_inits().unwrap_or_else(|e| panic!("{e}"));
        let dt = t0.elapsed().as_secs_f64();
        eprintln!("placed {} cylinders l/d = {} in {dt:.3} s", inits.len(), length / 12.0);
        assert_eq!(inits.len(), c.random_count(0));
        assert!(dt < 30.0, "placement took {dt} s");
    }
}

/// `Case::describe` (what `slurry check` prints) names every part of a case: with an impeller,
/// a particle and contacts, a line for each.
#[test]
fn describe_names_everything_the_case_holds() {
    let c = pcase(
        r#"
[impeller]
kind = "pbt"
diameter = 20.0
speed = 1.0e-3
ramp_steps = 100
blade_thickness = 0.75

[contacts]
substeps = 4

[[particles]]
shape = "sphere"
diameter = 4.0
density = 1.25
position = [5.0, 5.0, 5.0]
"#,
    );
    let d = c.describe();
    for item in [
        "grid ",
        "fluid ",
        "x_min ",
        "initial ",
        "gravity ",
        "ibm ",
        "particle ",
        "particles ",
        "impeller ",
        "rotation ",
        "contacts ",
        "memory ",
        "run ",
    ] {
        assert!(d.lines().any(|l| l.starts_with(item)), "no `{item}` line in\n{d}");
    }
    assert!(d.contains("pitched-blade turbine, 4 blades at 45°"), "{d}");
    assert!(d.contains("N = 0.001 rev/step (1000 steps per revolution), ramp 100 steps"), "{d}");
    assert!(d.contains("k 5, δ0 0.5") && d.contains("4 sub-steps per step"), "{d}");
    assert!(!d.contains("damping implicit"), "{d}");
    let mut implicit = c.clone();
    if let Some(p) = implicit.contacts.as_mut() {
        p.damping = crate::contact::Damping::Implicit;
        p.substeps = 2;
    }
    let d = implicit.describe();
    assert!(d.contains("2 sub-steps per step, damping implicit (backward Euler"), "{d}");
}
