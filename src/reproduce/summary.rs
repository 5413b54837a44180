//! The cross-case summary of `slurry reproduce --all` (or `--summary`): the paper's Figures
//! 5–9 with the three aspect ratios of each impeller on one plot, as the paper draws them,
//! and one table of the six cases against the paper.
//!
//! It reads only what each case's report wrote (`CASE/statistics.h5` and
//! `CASE/statistics.json` under one root directory), so it can be redrawn at any time, for
//! instance after a case was resumed on its own; a case without them is listed as not run.
//!
//! | file (in `ROOT/summary/`) | contents |
//! |---|---|
//! | `summary.md` | the table of the six cases (ours beside the paper's, steady or not) and the figures |
//! | `fig05_mean_height_{disk,pbt}` | ⟨z_p⟩/H against revolutions, ℓ/d = 1, 2, 4 |
//! | `fig06_volume_fraction_{disk,pbt}` | time-averaged solids volume fraction against z/H |
//! | `fig07_kinetic_energy_{disk,pbt}` | k* of linear (and rotational) motion against z/H |
//! | `fig08_orientation_{disk,pbt}` | pdf of φ, all particles, with sin φ |
//! | `fig09_orientation_mobile_{disk,pbt}` | pdf of φ for z_p > 0.2H, with sin φ |

use std::f64::consts::PI;
use std::fmt::Write as _;
use std::path::{Path, PathBuf};

use anyhow::Context;

use super::{paper_case, CASES};
use crate::io::atomic_write_bytes;
use crate::plot::{self, LegendPosition, LinePlot, Series, SeriesStyle};

/// One case's curves and scalars, as its report wrote them.
#[derive(Clone, Debug)]
struct CaseResult {
    /// `(rev, ⟨z_p⟩/H)`.
    mean_height: Vec<(f64, f64)>,
    /// `(φ, z/H)` profile.
    volume_fraction: Vec<(f64, f64)>,
    /// `(k*, z/H)`, linear.
    kinetic_linear: Vec<(f64, f64)>,
    /// `(k*, z/H)`, rotational.
    kinetic_rotational: Vec<(f64, f64)>,
    /// `(φ, pdf)`, all particles.
    orientation_all: Vec<(f64, f64)>,
    /// `(φ, pdf)`, mobile particles.
    orientation_mobile: Vec<(f64, f64)>,
    /// `(φ, sin φ)` at the same bins.
    orientation_sin: Vec<(f64, f64)>,
    /// `statistics.json`.
    json: serde_json::Value,
}

/// Reads `dir/statistics.h5` and `dir/statistics.json`; `None` when either is missing.
fn read_case(dir: &Path) -> anyhow::Result<Option<CaseResult>> {
    let (h5, json) = (dir.join("statistics.h5"), dir.join("statistics.json"));
    if !h5.exists() || !json.exists() {
        return Ok(None);
    }
    let text = std::fs::read_to_string(&json).with_context(|| format!("cannot read {}", json.display()))?;
    let json_value: serde_json::Value =
        serde_json::from_str(&text).with_context(|| format!("{}: not JSON", json.display()))?;
    let f = hdf5::File::open(&h5).with_context(|| format!("cannot open {}", h5.display()))?;
    let read = |name: &str| -> anyhow::Result<Vec<f64>> {
        f.dataset(name)
            .and_then(|d| d.read_raw::<f64>())
            .with_context(|| format!("{}: cannot read {name}", h5.display()))
    };
    let zip = |a: Vec<f64>, b: Vec<f64>| a.into_iter().zip(b).collect::<Vec<_>>();
    Ok(Some(CaseResult {
        mean_height: zip(read("mean_height/rev")?, read("mean_height/value")?),
        volume_fraction: zip(read("volume_fraction/value")?, read("volume_fraction/z_over_h")?),
        kinetic_linear: zip(read("kinetic_energy/linear")?, read("kinetic_energy/z_over_h")?),
        kinetic_rotational: zip(read("kinetic_energy/rotational")?, read("kinetic_energy/z_over_h")?),
        orientation_all: zip(read("orientation/phi")?, read("orientation/all")?),
        orientation_mobile: zip(read("orientation/phi")?, read("orientation/mobile")?),
        orientation_sin: zip(read("orientation/phi")?, read("orientation/sin")?),
        json: json_value,
    }))
}

/// `json[key]` as a number.
fn num(json: &serde_json::Value, key: &str) -> Option<f64> {
    json.get(key).and_then(serde_json::Value::as_f64)
}

/// Writes `root/summary/` from the cases' reports under `root/CASE/`; returns the path of
/// `summary.md`.
///
/// # Errors
/// A case's statistics exist but cannot be read; a figure or the table cannot be written.
pub fn write_summary(root: &Path) -> anyhow::Result<PathBuf> {
    let out = root.join("summary");
    std::fs::create_dir_all(&out).with_context(|| format!("cannot create {}", out.display()))?;
    let mut cases = Vec::new();
    for name in CASES {
        let paper = paper_case(name)?.paper()?;
        let result = read_case(&root.join(name))?;
        cases.push((name, paper, result));
    }

    let mut md = String::from("# Derksen (2020): the six cases\n\n");
    md.push_str(
        "Our values beside the paper's (Table 2; ⟨z_p⟩/H from its text). ⟨z_p⟩/H is the mean over the steady \
         test's window, the power numbers over the last 30 revolutions. *Italics*: the run is not steady, so the \
         value is where the transient stood, not a result to compare.\n\n",
    );
    md.push_str(
        "| case | scale | revolutions | steady | ⟨z_p⟩/H | paper | Po_f | paper | Po_c | paper | Po | paper |\n\
         |---|---|---|---|---|---|---|---|---|---|---|---|\n",
    );
    for (name, paper, result) in &cases {
        let theirs = |key: &str| {
            paper
                .values
                .iter()
                .find(|v| v.key == key)
                .and_then(|v| v.paper)
                .map_or("–".into(), |p| format!("{p}"))
        };
        let Some(r) = result else {
            let _ = writeln!(
                md,
                "| {name} | – | – | not run | – | {} | – | {} | – | {} | – | {} |",
                theirs("mean_height"),
                theirs("po_fluid"),
                theirs("po_solids"),
                theirs("po")
            );
            continue;
        };
        let steady = r.json.get("steady").and_then(serde_json::Value::as_bool).unwrap_or(false);
        let ours = |key: &str| {
            num(&r.json, key).map_or("–".into(), |v| {
                if steady {
                    format!("{v:.3}")
                } else {
                    format!("*{v:.3}*")
                }
            })
        };
        let _ = writeln!(
            md,
            "| {name} | {} | {} | {} | {} | {} | {} | {} | {} | {} | {} | {} |",
            num(&r.json, "scale").map_or("–".into(), |s| format!("{s}")),
            num(&r.json, "revolutions").map_or("–".into(), |s| format!("{s:.0}")),
            if steady { "yes" } else { "no" },
            ours("mean_height"),
            theirs("mean_height"),
            ours("po_fluid"),
            theirs("po_fluid"),
            ours("po_solids"),
            theirs("po_solids"),
            ours("po"),
            theirs("po")
        );
    }

    md.push_str(
        "\n## Figures\n\nAs the paper draws them: the three aspect ratios of one impeller on one plot.\n\n",
    );
    for impeller in ["disk", "pbt"] {
        let runs: Vec<(String, &CaseResult)> = cases
            .iter()
            .filter(|(_, p, _)| p.impeller == impeller)
            .filter_map(|(_, p, r)| r.as_ref().map(|r| (format!("ℓ/d = {}", p.aspect_ratio), r)))
            .collect();
        let label = if impeller == "disk" { "disk" } else { "pitched-blade turbine" };
        if runs.is_empty() {
            let _ = writeln!(md, "No {label} case has been run.\n");
            continue;
        }
        for (stem, caption) in figures(&out, impeller, label, &runs)? {
            let _ = writeln!(md, "**{caption}** ([SVG]({stem}.svg))\n\n![{caption}]({stem}.png)\n");
        }
    }
    let path = out.join("summary.md");
    atomic_write_bytes(&path, md.as_bytes()).with_context(|| format!("cannot write {}", path.display()))?;
    Ok(path)
}

/// Figures 5–9 of one impeller with a series per case; returns `(stem, caption)`.
fn figures(
    out: &Path,
    impeller: &str,
    label: &str,
    runs: &[(String, &CaseResult)],
) -> anyhow::Result<Vec<(String, String)>> {
    let write = |stem: String, plot: &LinePlot| -> anyhow::Result<String> {
        plot::write_line_png(&out.join(format!("{stem}.png")), plot, 900, 600)?;
        plot::write_line_svg(&out.join(format!("{stem}.svg")), plot, 900, 600)?;
        Ok(stem)
    };
    let series = |pick: fn(&CaseResult) -> &Vec<(f64, f64)>, style: SeriesStyle| {
        runs.iter().map(|(name, r)| Series::new(name.clone(), pick(r).clone(), style)).collect::<Vec<_>>()
    };
    let profile = |title: String, x_label: &str, series: Vec<Series>, log_x: bool| LinePlot {
        title,
        x_label: x_label.into(),
        y_label: "z / H".into(),
        series,
        y_range: Some((0.0, 1.0)),
        log_x,
        legend: LegendPosition::UpperRight,
        ..Default::default()
    };
    let mut figs = Vec::new();

    let plot5 = LinePlot {
        title: format!("{label}: mean height of the particles"),
        x_label: "t N (revolutions)".into(),
        y_label: "⟨z_p⟩ / H".into(),
        series: series(|r| &r.mean_height, SeriesStyle::Line),
        y_range: Some((0.0, 0.5)),
        legend: LegendPosition::LowerRight,
        ..Default::default()
    };
    figs.push((
        write(format!("fig05_mean_height_{impeller}"), &plot5)?,
        format!("Figure 5 ({label}): ⟨z_p⟩/H"),
    ));

    let plot6 = profile(
        format!("{label}: solids volume fraction (profile window of each run)"),
        "φ",
        series(|r| &r.volume_fraction, SeriesStyle::Line),
        false,
    );
    figs.push((
        write(format!("fig06_volume_fraction_{impeller}"), &plot6)?,
        format!("Figure 6 ({label}): time-averaged solids volume fraction"),
    ));

    let mut kinetic = series(|r| &r.kinetic_linear, SeriesStyle::Line);
    for (name, r) in runs {
        kinetic.push(Series::new(
            format!("{name}, rotational"),
            r.kinetic_rotational.clone(),
            SeriesStyle::Points,
        ));
    }
    let plot7 = profile(
        format!("{label}: particle kinetic energy, linear (lines) and rotational (points)"),
        "k* = k′ / (n m_p v_tip² / H)",
        kinetic,
        true,
    );
    figs.push((
        write(format!("fig07_kinetic_energy_{impeller}"), &plot7)?,
        format!("Figure 7 ({label}): kinetic energy of linear and rotational motion per unit height"),
    ));

    let sin = runs[0].1.orientation_sin.clone();
    let orientation = |title: String, pick: fn(&CaseResult) -> &Vec<(f64, f64)>| {
        let mut s = series(pick, SeriesStyle::LinePoints);
        s.push(Series::new("sin φ", sin.clone(), SeriesStyle::Line));
        LinePlot {
            title,
            x_label: "φ (rad)".into(),
            y_label: "pdf".into(),
            series: s,
            x_range: Some((0.0, PI / 2.0)),
            legend: LegendPosition::UpperLeft,
            ..Default::default()
        }
    };
    let plot8 = orientation(format!("{label}: orientation, all particles"), |r| &r.orientation_all);
    figs.push((
        write(format!("fig08_orientation_{impeller}"), &plot8)?,
        format!("Figure 8 ({label}): pdf of the angle φ between axis and vertical"),
    ));
    let plot9 = orientation(format!("{label}: orientation of mobile particles (z_p > 0.2H)"), |r| {
        &r.orientation_mobile
    });
    figs.push((
        write(format!("fig09_orientation_mobile_{impeller}"), &plot9)?,
        format!("Figure 9 ({label}): pdf of φ for the mobile particles"),
    ));
    Ok(figs)
}
