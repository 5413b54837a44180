//! State packs: a restart from a pack continues close to the exact restart, and a pack that
//! is truncated, corrupted or of another case or grid is refused.
//!
//! The restart: a small stirred tank (36³, f32 BGK, a pitched-blade turbine, 26 free
//! cylinders falling onto the floor with contacts) run `WARM` steps, then continued `AFTER`
//! steps twice from the same step, once from the exact state (`Coupled::snapshot`, what
//! `checkpoint.h5` holds) and once from a state pack written to a file and read back. After
//! `AFTER` steps the relative L2 difference of the velocity field must lie below `TOL_U`, and
//! far below the flow's own change over those steps; the bodies' positions, velocities and
//! angular velocities must agree to `TOL_BODY` of their scales. The reasons for the numbers are
//! with the constants.

use std::path::Path;
use std::time::Instant;

use slurry::case::{Case, ImpellerSetup};
use slurry::coupling::Coupled;
use slurry::io::{read_state_pack, write_state_pack, StatePackError};
use slurry::lbm::Fluid;
use slurry::run::{restore_coupled_from_pack, state_pack_of};

mod common;

use common::case_toml;

/// Held by each test for its whole run: the command test's child processes inherit the
/// descriptors open in this process at the fork, and with them the HDF5 file lock of a pack
/// being written by another test, which its read then finds taken.
static SERIAL: std::sync::Mutex<()> = std::sync::Mutex::new(());

fn serial() -> std::sync::MutexGuard<'static, ()> {
    SERIAL.lock().unwrap_or_else(std::sync::PoisonError::into_inner)
}

/// Steps before the pack (the impeller's ramp is over, the cylinders fall and touch).
const WARM: u64 = 200;
/// Steps continued from the pack and from the exact state.
const AFTER: u64 = 100;
/// Relative L2 of the velocity difference after `AFTER` steps. The pack's velocity is
/// rounded to f32 (relative 6e-8: at the pack's step the two fields differ by that, checked)
/// and the reconstruction drops the non-equilibrium part beyond the strain rate and the
/// force, `O(Δx²)` of a part that is itself `O(Kn)` of the populations, largest where the
/// gradients are steep (the impeller's blades, the bodies' shells). The difference relaxes
/// with the flow; what is left after 100 steps is what the coupling carried forward.
/// Measured 1.0e-3 (2.6e-4 after 400 steps), against the flow's own change over the 100
/// steps of 0.19; a restart at equilibrium plus the force's first moment, without the strain
/// rate's part, gives 7.0e-3 (1.5e-3 after 400 steps). The bound is three times the
/// measurement and fails the restart without the non-equilibrium stress.
const TOL_U: f64 = 3e-3;
/// The bodies' differences after `AFTER` steps, relative to their scales (the cylinder's
/// diameter for positions, the largest particle speed for velocities, the largest angular
/// speed for angular velocities): the bodies feel the flow's difference through the IBM
/// loads only. Measured: positions 1.1e-4, velocities 2.2e-3, angular velocities 2.5e-3
/// (without the strain rate's part: 4.6e-4, 8.5e-3, 1.1e-2). The bound is 2.4 times the
/// largest measurement.
const TOL_BODY: f64 = 6e-3;

fn case_text() -> String {
    let closed_box = case_toml(
        [36, 36, 36],
        "precision = \"f32\"\nnu = 0.02\ncollision = \"bgk\"",
        "",
        "steps = 1\noutput_every = 1",
    );
    format!(
        r#"
gravity = [0.0, 0.0, -2e-4]
{closed_box}
[contacts]

[impeller]
kind = "pbt"
diameter = 18.0
speed = 2.5e-3
ramp_steps = 20
centre = [17.5, 17.5, 20.0]
blade_thickness = 0.75

[[random_particles]]
shape = "cylinder"
diameter = 4.0
length = 6.0
density = 1.25
count = 26
seed = 7
region = [[0.5, 0.5, 0.5], [34.5, 34.5, 12.0]]
clearance = 0.5
"#
    )
}

fn coupled(case: &Case) -> Coupled<f32> {
    let mut fluid = Fluid::<f32>::new(case.grid(), case.fluid_params(), case.boundaries()).unwrap();
    fluid.initialize(|x, y, z| case.initial_state(x, y, z));
    let mut bodies: Vec<_> = case.particle_inits().unwrap().iter().map(|p| p.body()).collect();
    bodies.extend(case.impeller_setup().unwrap().as_ref().map(ImpellerSetup::body));
    Coupled::new(fluid, bodies, case.coupling_params()).unwrap()
}

fn l2(a: &[[f64; 3]], b: &[[f64; 3]]) -> f64 {
    a.iter().zip(b).map(|(x, y)| (0..3).map(|k| (x[k] - y[k]).powi(2)).sum::<f64>()).sum::<f64>().sqrt()
}

fn norm(a: &[[f64; 3]]) -> f64 {
    a.iter().map(|x| x.iter().map(|v| v * v).sum::<f64>()).sum::<f64>().sqrt()
}

/// Continued from the pack and from the exact state, the velocity field and the bodies agree
/// after `AFTER` steps to within the reconstruction's error.
#[test]
fn restart_from_pack_follows_the_exact_restart() {
    let _serial = serial();
    let t0 = Instant::now();
    let case = Case::parse(&case_text(), "state_pack.toml").unwrap();
    let mut c = coupled(&case);
    rayon::scope(|_| c.run(WARM)).unwrap();
    let exact = c.snapshot().unwrap();
    let (_, u_start) = c.fluid().fields();
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("pack.h5");
    let pack =
        state_pack_of(c.fluid(), Some(exact.bodies.clone()), &case.fingerprint(), "stirred test").unwrap();
    write_state_pack(&path, &pack).unwrap();
    let size = std::fs::metadata(&path).unwrap().len();
    let back = read_state_pack(&path).unwrap();
    assert_eq!(back, pack);
    back.check_for(&path, case.grid(), &case.fingerprint(), "this test").unwrap();

    // The exact continuation: the same solver, restored (as a resume from checkpoint.h5 is).
    let mut a = coupled(&case);
    a.restore(&exact).unwrap();
    let mut b = coupled(&case);
    restore_coupled_from_pack(&mut b, &back).unwrap();
    // At the pack's step, the rebuilt fluid has the packed velocity (to f32 rounding).
    let (_, ua0) = a.fluid().fields();
    let (_, ub0) = b.fluid().fields();
    let at_start = l2(&ua0, &ub0) / norm(&ua0);
    assert!(at_start < 1e-6, "the rebuilt velocity at the pack's step: {at_start:e}");
    rayon::scope(|_| a.run(AFTER)).unwrap();
    rayon::scope(|_| b.run(AFTER)).unwrap();
    let (_, ua) = a.fluid().fields();
    let (_, ub) = b.fluid().fields();
    let rel = l2(&ua, &ub) / norm(&ua);
    let own = l2(&ua, &u_start) / norm(&ua);
    let particles = case.particle_inits().unwrap().len();
    let d = 4.0;
    let (mut dx, mut dv, mut dw, mut vmax, mut wmax) = (0.0f64, 0.0f64, 0.0f64, 0.0f64, 0.0f64);
    for (p, q) in a.bodies()[..particles].iter().zip(&b.bodies()[..particles]) {
        dx = dx.max((p.position - q.position).norm());
        dv = dv.max((p.velocity - q.velocity).norm());
        dw = dw.max((p.angular_velocity - q.angular_velocity).norm());
        vmax = vmax.max(p.velocity.norm());
        wmax = wmax.max(p.angular_velocity.norm());
    }
    let imp = |c: &Coupled<f32>| c.bodies()[particles].orientation;
    let impeller_angle = imp(&a).angle_to(&imp(&b));
    println!(
        "pack {size} bytes; after {AFTER} steps: velocity rel. L2 {rel:.3e} (the flow's own change {own:.3e}); \
         bodies: position {:.3e} d, velocity {:.3e} of {vmax:.3e}, angular velocity {:.3e} of {wmax:.3e}; \
         impeller angle {impeller_angle:e}; {:.1} s",
        dx / d,
        dv / vmax,
        dw / wmax,
        t0.elapsed().as_secs_f64()
    );
    assert!(rel < TOL_U, "velocity rel. L2 {rel:e} ≥ {TOL_U:e}");
    assert!(rel < 0.05 * own, "velocity rel. L2 {rel:e} against the flow's own change {own:e}");
    assert!(dx / d < TOL_BODY && dv / vmax < TOL_BODY && dw / wmax < TOL_BODY);
    assert_eq!(impeller_angle, 0.0, "the impeller's prescribed motion is exact");
}

/// A small pack on disk.
fn small_pack(path: &Path) -> slurry::io::StatePack {
    let case = Case::parse(&case_text(), "state_pack.toml").unwrap();
    let c = coupled(&case);
    let bodies = c.snapshot().unwrap().bodies;
    let pack = state_pack_of(c.fluid(), Some(bodies), &case.fingerprint(), "stirred test").unwrap();
    write_state_pack(path, &pack).unwrap();
    pack
}

/// Truncated, corrupted and mismatched packs are refused with a message that says so.
#[test]
fn bad_packs_are_refused() {
    let _serial = serial();
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("pack.h5");
    let pack = small_pack(&path);
    let bytes = std::fs::read(&path).unwrap();

    // Truncated: half of the file.
    let cut = dir.path().join("cut.h5");
    std::fs::write(&cut, &bytes[..bytes.len() / 2]).unwrap();
    let e = read_state_pack(&cut).unwrap_err();
    assert!(matches!(e, StatePackError::Unreadable { .. } | StatePackError::Corrupt { .. }), "{e}");
    let msg = e.to_string();
    assert!(msg.contains("cut.h5") && (msg.contains("truncated") || msg.contains("corrupt")), "{msg}");

    // Corrupted: one value of the bodies changed in place (a flipped bit on disk).
    let offset = hdf5::File::open(&path).unwrap().dataset("bodies").unwrap().offset().unwrap() as usize;
    let mut flipped = bytes.clone();
    flipped[offset + 8 * 3] ^= 0x10;
    let bad = dir.path().join("bad.h5");
    std::fs::write(&bad, &flipped).unwrap();
    let e = read_state_pack(&bad).unwrap_err();
    assert!(matches!(e, StatePackError::Corrupt { .. }), "{e}");
    assert!(e.to_string().contains("bad.h5") && e.to_string().contains("corrupt"), "{e}");

    // Corrupted: a velocity changed through HDF5 (the file stays well-formed).
    let edited = dir.path().join("edited.h5");
    std::fs::write(&edited, &bytes).unwrap();
    {
        let f = hdf5::File::open_rw(&edited).unwrap();
        let d = f.dataset("u").unwrap();
        let mut u: Vec<f32> = d.read_raw().unwrap();
        u[100] += 1e-3;
        d.write_raw(&u).unwrap();
    }
    let e = read_state_pack(&edited).unwrap_err();
    assert!(matches!(e, StatePackError::Corrupt { .. }), "{e}");

    // Not a pack: a checkpoint-like HDF5 file.
    let other = dir.path().join("other.h5");
    hdf5::File::create(&other).unwrap();
    assert!(matches!(read_state_pack(&other).unwrap_err(), StatePackError::NotAPack { .. }));
    assert!(!slurry::io::is_state_pack(&other) && slurry::io::is_state_pack(&path));

    // Mismatched: another grid, another case; both named.
    let e = pack
        .check_for(&path, slurry::lattice::Grid::new(72, 72, 72), &pack.case, "the bigger run")
        .unwrap_err();
    let msg = e.to_string();
    assert!(
        msg.contains("36 x 36 x 36") && msg.contains("72 x 72 x 72") && msg.contains("the bigger run"),
        "{msg}"
    );
    let e = pack.check_for(&path, pack.grid, "another case", "the other run").unwrap_err();
    assert!(e.to_string().contains("'stirred test'") && e.to_string().contains("'the other run'"), "{e}");
}

/// The commands: `slurry state-pack` of a run's checkpoint, `slurry run --from-pack` of the
/// same case continuing from its step, and a pack of another case refused (exit status 2).
#[test]
fn commands_pack_and_continue() {
    let _serial = serial();
    let dir = tempfile::tempdir().unwrap();
    let with_run = |run: &str, nu: &str| {
        case_text().replace("steps = 1\noutput_every = 1", run).replace("nu = 0.02", nu)
    };
    let first = common::write_case(
        dir.path(),
        "first.toml",
        &with_run("steps = 40\noutput_every = 20\ncheckpoint_every = 40", "nu = 0.02"),
    );
    let a = dir.path().join("a");
    let o = common::slurry(&["run", first.to_str().unwrap(), "--out", a.to_str().unwrap(), "--quiet"]);
    assert!(o.status.success(), "{}", common::stderr(&o));
    let pack = dir.path().join("pack.h5");
    let o =
        common::slurry(&["state-pack", a.to_str().unwrap(), pack.to_str().unwrap(), "--label", "first 40"]);
    assert!(o.status.success(), "{}", common::stderr(&o));
    assert!(common::stderr(&o).contains("state pack of step 40"), "{}", common::stderr(&o));
    common::assert_no_temp_files(dir.path());

    let longer = common::write_case(
        dir.path(),
        "longer.toml",
        &with_run("steps = 60\noutput_every = 20", "nu = 0.02"),
    );
    let b = dir.path().join("b");
    let o = common::slurry(&[
        "run",
        longer.to_str().unwrap(),
        "--out",
        b.to_str().unwrap(),
        "--quiet",
        "--from-pack",
        pack.to_str().unwrap(),
    ]);
    assert!(o.status.success(), "{}", common::stderr(&o));
    let series = std::fs::read_to_string(b.join("timeseries.csv")).unwrap();
    let steps: Vec<&str> = series.lines().skip(1).map(|l| l.split(',').next().unwrap()).collect();
    assert_eq!(steps, ["60"], "the time series after the pack's step (whose loads the pack does not hold)");

    let other =
        common::write_case(dir.path(), "other.toml", &with_run("steps = 60\noutput_every = 20", "nu = 0.03"));
    let c = dir.path().join("c");
    let o = common::slurry(&[
        "run",
        other.to_str().unwrap(),
        "--out",
        c.to_str().unwrap(),
        "--quiet",
        "--from-pack",
        pack.to_str().unwrap(),
    ]);
    assert_eq!(o.status.code(), Some(2), "{}", common::stderr(&o));
    let msg = common::stderr(&o);
    assert!(
        msg.contains("the state pack is of 'first 40'") && msg.contains("this run is 'the run in"),
        "{msg}"
    );
}
