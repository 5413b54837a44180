//! `slurry resolution`: the resolution study's table from archived reproductions, and its bad
//! input (exit status 2, naming the run).

#[path = "../../tests/common/mod.rs"]
mod common;

use common::{slurry, stderr};

/// The archived steady pbt-ld2 run at s = 1/4, beside a second "run" at s = 1/2 made from its
/// statistics (scale changed, not steady): the real row, the transient in italics, and no
/// order claimed from one steady scale.
#[test]
fn the_table_of_archived_runs() {
    let archived = "reproduce/pbt-ld2/runs/2026-11-25-s0.25-exact-r200";
    let tmp = tempfile::tempdir().unwrap();
    let text = std::fs::read_to_string(common::root().join(archived).join("statistics.json")).unwrap();
    let mut json: serde_json::Value = serde_json::from_str(&text).unwrap();
    json["scale"] = 0.5.into();
    json["steady"] = false.into();
    let half = tmp.path().join("half");
    std::fs::create_dir(&half).unwrap();
    std::fs::write(half.join("statistics.json"), json.to_string()).unwrap();
    let out = tmp.path().join("resolution.md");
    let o = slurry(&["resolution", half.to_str().unwrap(), archived, "--out", out.to_str().unwrap()]);
    assert_eq!(o.status.code(), Some(0), "{}", stderr(&o));
    let table = String::from_utf8_lossy(&o.stdout).to_string();
    assert_eq!(std::fs::read_to_string(&out).unwrap(), table);
    assert!(table.starts_with("# Resolution study: pbt-ld2"), "{table}");
    // The archived run's values (reproduce/README.md: 0.332, 1.94, 1.20, 3.14), coarsest first;
    // its drift 0.0068 (± 0.0027) is beyond the tolerance 0.005, so it is marked.
    let rows: Vec<&str> = table.lines().filter(|l| l.starts_with("| 0.")).collect();
    assert_eq!(rows.len(), 2, "{table}");
    assert!(
        rows[0].starts_with("| 0.25 | 3 | ")
            && rows[0].contains("| yes | +0.0068 † | not recorded | 0.332 | 1.944 | 1.200 | 3.145 |"),
        "{table}"
    );
    assert!(
        rows[1].starts_with("| 0.5 | 6 | ")
            && rows[1].contains("| no | +0.0068 † | not recorded | *0.332* |"),
        "{table}"
    );
    assert!(table.contains("– (1 steady scale; needs 3)"), "{table}");
}

#[test]
fn bad_runs_are_bad_input() {
    let tmp = tempfile::tempdir().unwrap();
    let missing = tmp.path().join("nothing-here");
    let o = slurry(&["resolution", missing.to_str().unwrap()]);
    assert_eq!(o.status.code(), Some(2), "{}", stderr(&o));
    assert!(stderr(&o).contains(&format!("{}/statistics.json", missing.display())), "{}", stderr(&o));

    let o = slurry(&[
        "resolution",
        "reproduce/pbt-ld2/runs/2026-11-25-s0.25-exact-r200",
        "reproduce/pbt-ld4/runs/2026-11-26-s0.25-r200",
    ]);
    assert_eq!(o.status.code(), Some(2), "{}", stderr(&o));
    assert!(stderr(&o).contains("a resolution study is one case at several scales"), "{}", stderr(&o));

    // The main job's run repeated the 2026-11-25 run from the same dry bed: two runs of one
    // scale from one start are not two starts.
    let o = slurry(&[
        "resolution",
        "reproduce/pbt-ld2/runs/2026-11-25-s0.25-exact-r200",
        "reproduce/pbt-ld2/runs/2026-11-29-s0.25-main",
    ]);
    assert_eq!(o.status.code(), Some(2), "{}", stderr(&o));
    assert!(stderr(&o).contains("are both at scale 0.25"), "{}", stderr(&o));
}
