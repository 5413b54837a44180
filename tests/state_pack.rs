//! State packs: a pack that is truncated, corrupted or of another case or grid is refused, and
//! the commands write one from a run and continue the case from it. How close a restart from a
//! pack follows the exact restart is the verification case `state_pack` (quick tier in CI).

use std::path::Path;

use slurry::case::Case;
use slurry::coupling::Coupled;
use slurry::io::{read_state_pack, write_state_pack, StatePackError};
use slurry::run::state_pack_of;

mod common;

/// Held by each test for its whole run: the command test's child processes inherit the
/// descriptors open in this process at the fork, and with them the HDF5 file lock of a pack
/// being written by another test, which its read then finds taken.
static SERIAL: std::sync::Mutex<()> = std::sync::Mutex::new(());

fn serial() -> std::sync::MutexGuard<'static, ()> {
    SERIAL.lock().unwrap_or_else(std::sync::PoisonError::into_inner)
}

/// The small stirred tank (`examples/stirred_tank_particles.toml`) with a one-step `[run]`.
fn case_text() -> String {
    common::stirred_tank("steps = 1\noutput_every = 1", "")
}

fn coupled(case: &Case) -> Coupled<f32> {
    slurry::drive::coupled(case, &case.particle_inits().unwrap(), case.impeller_setup().unwrap().as_ref())
        .unwrap()
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
        &with_run("steps = 60\noutput_every = 20\ncheckpoint_every = 60", "nu = 0.02"),
    );
    let b = dir.path().join("b");
    // `slurry run CASE --out b --quiet EXTRA...`
    let run_b = |case: &Path, extra: &[&str]| {
        let mut args = vec!["run", case.to_str().unwrap(), "--out", b.to_str().unwrap(), "--quiet"];
        args.extend_from_slice(extra);
        common::slurry(&args)
    };
    let o = run_b(&longer, &["--from-pack", pack.to_str().unwrap()]);
    assert!(o.status.success(), "{}", common::stderr(&o));
    // One run: the packed run's rows as written, then this leg's after the pack's step.
    let series_a = std::fs::read_to_string(a.join("timeseries.csv")).unwrap();
    let series = std::fs::read_to_string(b.join("timeseries.csv")).unwrap();
    let steps: Vec<&str> = series.lines().skip(1).map(|l| l.split(',').next().unwrap()).collect();
    assert_eq!(steps, ["0", "20", "40", "60"], "the packed rows, then this leg's");
    assert!(series.starts_with(&series_a), "the packed rows byte for byte");
    let legs = |run: &Path| -> Vec<slurry::io::Leg> { slurry::run::read_legs(run, 0, 0).unwrap() };
    let b_legs = legs(&b);
    assert_eq!(
        b_legs.iter().map(|l| (l.first_step, l.start.contains("first 40"))).collect::<Vec<_>>(),
        [(0, false), (40, true)]
    );
    assert_eq!(b_legs[0].last_step, 40, "the packed leg ends at the pack's step");
    // Its own pack carries both legs and the whole series; its particle history starts after
    // the first pack, so a resume checks the frames against the rows after it.
    let pack_b = dir.path().join("pack-b.h5");
    let o = common::slurry(&["state-pack", b.to_str().unwrap(), pack_b.to_str().unwrap()]);
    assert!(o.status.success(), "{}", common::stderr(&o));
    let h = read_state_pack(&pack_b).unwrap().history.expect("a pack of a run directory has its history");
    assert_eq!(h.timeseries, series);
    assert_eq!(h.legs.iter().map(|l| (l.first_step, l.last_step)).collect::<Vec<_>>(), [(0, 40), (40, 60)]);
    let further = common::write_case(
        dir.path(),
        "further.toml",
        &with_run("steps = 80\noutput_every = 20", "nu = 0.02"),
    );
    let o = run_b(&further, &["--resume"]);
    assert!(o.status.success(), "{}", common::stderr(&o));
    let steps: Vec<String> = std::fs::read_to_string(b.join("timeseries.csv"))
        .unwrap()
        .lines()
        .skip(1)
        .map(|l| l.split(',').next().unwrap().to_string())
        .collect();
    assert_eq!(steps, ["0", "20", "40", "60", "80"]);

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

    // Another contact scheme (implicit damping, 2 sub-steps): refused as another case, taken
    // with --switch-contacts; the flag without a pack or --resume is refused.
    let implicit = common::write_case(
        dir.path(),
        "implicit.toml",
        &common::stirred_tank("steps = 60\noutput_every = 20", "substeps = 2\ndamping = \"implicit\""),
    );
    let from_pack = |out: &str, extra: &[&str]| {
        let d = dir.path().join(out);
        let mut args = vec!["run", implicit.to_str().unwrap(), "--out", d.to_str().unwrap(), "--quiet"];
        args.extend_from_slice(extra);
        common::slurry(&args)
    };
    let o = from_pack("d", &["--from-pack", pack.to_str().unwrap()]);
    assert_eq!(o.status.code(), Some(2), "{}", common::stderr(&o));
    let o = from_pack("e", &["--from-pack", pack.to_str().unwrap(), "--switch-contacts"]);
    assert!(o.status.success(), "{}", common::stderr(&o));
    let o = from_pack("f", &["--switch-contacts"]);
    assert_eq!(o.status.code(), Some(2), "{}", common::stderr(&o));
    assert!(common::stderr(&o).contains("--switch-contacts: needs --resume"), "{}", common::stderr(&o));
}
