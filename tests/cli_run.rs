//! The `slurry` binary end to end: `run` writes readable output; bad input and numerical
//! trouble give the documented exit codes and messages.

use std::path::Path;
use std::process::{Command, Output};

fn slurry(args: &[&str]) -> Output {
    Command::new(env!("CARGO_BIN_EXE_slurry"))
        .args(args)
        .current_dir(env!("CARGO_MANIFEST_DIR"))
        .output()
        .expect("the slurry binary runs")
}

fn stderr(o: &Output) -> String {
    String::from_utf8_lossy(&o.stderr).into_owned()
}

#[test]
fn poiseuille_runs_and_writes_readable_output() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("out");
    let o = slurry(&[
        "run",
        "examples/poiseuille.toml",
        "--out",
        out.to_str().unwrap(),
        "--quiet",
        "--threads",
        "2",
    ]);
    assert!(o.status.success(), "status {:?}: {}", o.status, stderr(&o));

    // Fields: HDF5 with the documented shapes, finite values, a channel profile.
    let f = hdf5::File::open(out.join("fields.h5")).unwrap();
    let v = f.dataset("velocity").unwrap();
    assert_eq!(v.shape(), vec![32, 4, 4, 3]);
    let u: Vec<f64> = v.read_raw().unwrap();
    assert!(u.iter().all(|x| x.is_finite()));
    let ux = |z: usize| u[z * 4 * 4 * 3];
    assert!(ux(16) > 0.009 && ux(16) < 0.0101, "centre-line speed {}", ux(16));
    assert!(ux(0) < ux(8) && ux(8) < ux(16), "not a channel profile");
    let d = f.dataset("density").unwrap();
    assert_eq!(d.shape(), vec![32, 4, 4]);
    let step: u64 = f.attr("time_step").unwrap().read_scalar().unwrap();
    assert_eq!(step, 10000);

    // XDMF beside it, naming the datasets.
    let xmf = std::fs::read_to_string(out.join("fields.xmf")).unwrap();
    assert!(xmf.contains("fields.h5:/density"));
    assert!(xmf.contains("fields.h5:/velocity"));
    assert!(xmf.contains(r#"Dimensions="32 4 4""#));

    // Time series: header plus one row per output step (0, 1000, ..., 10000).
    let csv = std::fs::read_to_string(out.join("timeseries.csv")).unwrap();
    let lines: Vec<&str> = csv.lines().collect();
    assert!(lines[0].starts_with("step,time,mass,"), "{}", lines[0]);
    assert_eq!(lines.len(), 1 + 11);
    for (i, l) in lines[1..].iter().enumerate() {
        let cols: Vec<&str> = l.split(',').collect();
        assert_eq!(cols.len(), 8, "{l}");
        assert_eq!(cols[0].parse::<u64>().unwrap(), 1000 * i as u64);
        let mass: f64 = cols[2].parse().unwrap();
        assert!((mass - 512.0).abs() < 1e-9, "{l}");
    }

    // Summary and the case as run.
    let s: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(out.join("summary.json")).unwrap()).unwrap();
    assert_eq!(s["steps"], 10000);
    assert!(s["mlups"].as_f64().unwrap() > 0.0);
    assert!(out.join("case.toml").exists());
    assert_no_temp_files(&out);
}

fn assert_no_temp_files(dir: &Path) {
    for e in std::fs::read_dir(dir).unwrap() {
        let name = e.unwrap().file_name().into_string().unwrap();
        assert!(!name.contains(".tmp."), "temporary file left: {name}");
    }
}

#[test]
fn bad_case_exits_2_naming_the_key() {
    let dir = tempfile::tempdir().unwrap();
    let case = dir.path().join("bad.toml");
    let text =
        std::fs::read_to_string(Path::new(env!("CARGO_MANIFEST_DIR")).join("examples/poiseuille.toml"))
            .unwrap()
            .replace("\nnu = 0.1\n", "\nnu = 0.1\nviscosity = 0.1\n");
    std::fs::write(&case, text).unwrap();
    let out = dir.path().join("out");
    let o = slurry(&["run", case.to_str().unwrap(), "--out", out.to_str().unwrap(), "--quiet"]);
    assert_eq!(o.status.code(), Some(2), "{}", stderr(&o));
    let msg = stderr(&o);
    assert!(msg.starts_with("error: "), "{msg}");
    assert!(msg.contains("bad.toml"), "{msg}");
    assert!(msg.contains("fluid.viscosity"), "{msg}");
    assert!(!out.exists(), "output written for a bad case");

    let o = slurry(&["check", case.to_str().unwrap()]);
    assert_eq!(o.status.code(), Some(2), "{}", stderr(&o));
}

#[test]
fn check_accepts_an_example() {
    let o = slurry(&["check", "examples/lid_cavity.toml"]);
    assert!(o.status.success(), "{}", stderr(&o));
    let text = String::from_utf8_lossy(&o.stdout);
    assert!(text.contains("32 x 32 x 32"), "{text}");
}

#[test]
fn runaway_flow_exits_1_with_a_diagnosis() {
    // A strong body force in a periodic box accelerates the fluid without bound:
    // u = g t reaches Mach 0.3 (u = 0.173) after about 173 steps.
    let dir = tempfile::tempdir().unwrap();
    let case = dir.path().join("runaway.toml");
    std::fs::write(
        &case,
        r#"
[domain]
nx = 4
ny = 4
nz = 4
[fluid]
nu = 0.1
body_force = [1e-3, 0.0, 0.0]
[boundaries]
x_min = "periodic"
x_max = "periodic"
y_min = "periodic"
y_max = "periodic"
z_min = "periodic"
z_max = "periodic"
[run]
steps = 1000
output_every = 50
"#,
    )
    .unwrap();
    let out = dir.path().join("out");
    let o = slurry(&["run", case.to_str().unwrap(), "--out", out.to_str().unwrap(), "--quiet"]);
    assert_eq!(o.status.code(), Some(1), "{}", stderr(&o));
    let msg = stderr(&o);
    assert!(msg.contains("numerical trouble at step 200"), "{msg}");
    assert!(msg.contains("exceeds the limit 0.300"), "{msg}");
    let csv = std::fs::read_to_string(out.join("timeseries.csv")).unwrap();
    assert_eq!(csv.lines().count(), 1 + 4, "{csv}"); // steps 0, 50, 100, 150
}

#[test]
fn unusable_output_directory_exits_2() {
    let dir = tempfile::tempdir().unwrap();
    let file = dir.path().join("a_file");
    std::fs::write(&file, "x").unwrap();
    let out = file.join("out");
    let o = slurry(&["run", "examples/couette.toml", "--out", out.to_str().unwrap(), "--quiet"]);
    assert_eq!(o.status.code(), Some(2), "{}", stderr(&o));
    assert!(stderr(&o).contains("--out"), "{}", stderr(&o));
}

#[test]
fn zero_threads_is_a_usage_error() {
    let o = slurry(&["run", "examples/poiseuille.toml", "--out", "/tmp/unused", "--threads", "0"]);
    assert_eq!(o.status.code(), Some(2), "{}", stderr(&o));
}
