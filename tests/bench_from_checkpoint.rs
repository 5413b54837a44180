//! `slurry bench --coupled --from CHECKPOINT`: the coupled step timed from a run's checkpoint
//! (a suspension at steady state) instead of the settled bed. Its refusals come at once,
//! before a bed is made or a fluid is timed: more than one case or scale, a missing file, and
//! a checkpoint of another grid (here a fluid-only run's, which also holds no particles).
//! Starting from a reproduction's checkpoint is tested in `tests/reproduce_regression.rs`,
//! which has one.

use std::path::Path;

mod common;

use common::{slurry, stderr};

#[test]
fn from_needs_one_case_and_one_scale_and_an_existing_file() {
    let o =
        slurry(&["bench", "--coupled", "--cases", "pbt-ld2,pbt-ld4", "--scales", "0.25", "--from", "x.h5"]);
    assert_eq!(o.status.code(), Some(2), "{}", stderr(&o));
    assert!(stderr(&o).contains("--from x.h5") && stderr(&o).contains("exactly one case"), "{}", stderr(&o));
    let o = slurry(&["bench", "--coupled", "--cases", "pbt-ld2", "--scales", "0.25,0.5", "--from", "x.h5"]);
    assert_eq!(o.status.code(), Some(2), "{}", stderr(&o));
    let o = slurry(&["bench", "--coupled", "--cases", "pbt-ld2", "--scales", "0.25", "--from", "no/such.h5"]);
    assert_eq!(o.status.code(), Some(2), "{}", stderr(&o));
    assert!(stderr(&o).contains("no/such.h5") && stderr(&o).contains("no such file"), "{}", stderr(&o));
}

#[test]
fn a_checkpoint_of_another_grid_is_refused_before_the_bed_is_made() {
    let dir = tempfile::tempdir().unwrap();
    let text =
        std::fs::read_to_string(Path::new(env!("CARGO_MANIFEST_DIR")).join("examples/couette.toml")).unwrap();
    let text = text.replace("precision = \"f64\"", "precision = \"f32\"");
    let head = text.split("[run]").next().unwrap();
    let case = dir.path().join("c.toml");
    std::fs::write(&case, format!("{head}[run]\nsteps = 20\noutput_every = 10\ncheckpoint_every = 10\n"))
        .unwrap();
    let out = dir.path().join("out");
    let o = slurry(&["run", case.to_str().unwrap(), "--out", out.to_str().unwrap(), "--quiet"]);
    assert!(o.status.success(), "{}", stderr(&o));
    let cp = out.join("checkpoint.h5");
    assert!(cp.is_file());
    let t0 = std::time::Instant::now();
    let o = slurry(&[
        "bench",
        "--coupled",
        "--cases",
        "pbt-ld2",
        "--scales",
        "0.25",
        "--from",
        cp.to_str().unwrap(),
    ]);
    assert!(!o.status.success());
    let e = stderr(&o);
    assert!(e.contains("--from") && e.contains("grid is 4 x 4 x 32") && e.contains("63 x 63 x 60"), "{e}");
    assert!(t0.elapsed() < std::time::Duration::from_secs(20), "took {:?}", t0.elapsed());
}
