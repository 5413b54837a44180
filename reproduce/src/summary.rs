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
//! | `summary.md` | the table of the six cases (ours beside the paper's, steady or not), the paper's qualitative findings checked ([`Findings`], [`verdicts`]) and the figures |
//! | `fig05_mean_height_{disk,pbt}` | ⟨z_p⟩/H against revolutions, ℓ/d = 1, 2, 4 |
//! | `fig06_volume_fraction_{disk,pbt}` | time-averaged solids volume fraction against z/H |
//! | `fig07_kinetic_energy_{disk,pbt}` | k* of linear (and rotational) motion against z/H |
//! | `fig08_orientation_{disk,pbt}` | pdf of φ, all particles, with sin φ |
//! | `fig09_orientation_mobile_{disk,pbt}` | pdf of φ for z_p > 0.2H, with sin φ |
//! | `fig03_disk_ld{4,1}_rev{010,090}.png`, `fig04_pbt_…` | the panels of the paper's four-panel Figures 3 (disk) and 4 (PBT): ℓ/d = 4 and 1, 10 and 90 revolutions after the start, copied from each case's report (`snapshot_panels`) |

use std::f64::consts::PI;
use std::fmt::Write as _;
use std::path::{Path, PathBuf};

use anyhow::Context;

use super::{paper_case, report, CASES};
use slurry::io::atomic_write_bytes;
use slurry::plot::{self, LegendPosition, LinePlot, Series, SeriesStyle};

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

/// The numbers behind the paper's qualitative findings, from one case's statistics (the
/// report's windows: the profiles and pdfs over its last 10 revolutions).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Findings {
    /// The report's verdict.
    pub steady: bool,
    /// The run's scale `s` (NaN: not recorded): cases are compared only at equal scales.
    pub scale: f64,
    /// `⟨z_p⟩/H` over the steady test's window.
    pub mean_height: f64,
    /// Mean angle between the cylinder axis and the vertical, all particles (degrees; random
    /// orientation: 57.3°).
    pub phi_all: f64,
    /// The same for the mobile particles (`z_p > 0.2 H`; NaN without any).
    pub phi_mobile: f64,
    /// Fraction of the particles with `φ > 60°` (random: 0.5), all.
    pub flat_all: f64,
    /// `∫ |pdf − sin φ| dφ` of the mobile particles: 0 for random orientation, 2 for disjoint.
    pub l1_mobile: f64,
    /// Linear over rotational kinetic energy, both summed over the height.
    pub kinetic_ratio: f64,
    /// Fraction of the solids volume above mid-height (the impeller's plane).
    pub above_impeller: f64,
}

impl Findings {
    /// From a case's statistics.
    fn of(r: &CaseResult) -> Self {
        let mean_phi = |pdf: &[(f64, f64)]| {
            let (w, m) = pdf.iter().fold((0.0, 0.0), |(w, m), &(phi, p)| (w + p, m + p * phi));
            if w > 0.0 {
                (m / w).to_degrees()
            } else {
                f64::NAN
            }
        };
        let flat = |pdf: &[(f64, f64)]| {
            let total: f64 = pdf.iter().map(|p| p.1).sum();
            pdf.iter().filter(|p| p.0 > PI / 3.0).map(|p| p.1).sum::<f64>() / total
        };
        let dphi = PI / 2.0 / r.orientation_mobile.len().max(1) as f64;
        let l1 =
            r.orientation_mobile.iter().zip(&r.orientation_sin).map(|(p, s)| (p.1 - s.1).abs()).sum::<f64>()
                * dphi;
        let sum = |v: &[(f64, f64)]| v.iter().map(|p| p.0).sum::<f64>();
        let solids = sum(&r.volume_fraction);
        let above: f64 = r.volume_fraction.iter().filter(|p| p.1 > 0.5).map(|p| p.0).sum();
        Findings {
            steady: r.json.get("steady").and_then(serde_json::Value::as_bool).unwrap_or(false),
            scale: num(&r.json, "scale").unwrap_or(f64::NAN),
            mean_height: num(&r.json, "mean_height").unwrap_or(f64::NAN),
            phi_all: mean_phi(&r.orientation_all),
            phi_mobile: mean_phi(&r.orientation_mobile),
            flat_all: flat(&r.orientation_all),
            l1_mobile: l1,
            kinetic_ratio: sum(&r.kinetic_linear) / sum(&r.kinetic_rotational),
            above_impeller: above / solids,
        }
    }
}

/// Our reading of the paper's "virtual absence of particles above the disk" (Results, text on
/// Figure 7): under a tenth of the solids volume above the disk's plane. A suspension uniform
/// over the height has half of it there; the paper's own profiles (Figure 6, upper panel) show
/// the disk's solids below it, so a tenth is generous.
pub const FEW_ABOVE: f64 = 0.10;

/// Two steady ⟨z_p⟩/H closer than this are the same for the findings: twice the largest
/// difference between two realisations of pbt-ld2 at s = 1/4 over a 10-revolution window
/// (0.0025; `reproduce/pbt-ld2/runs/2026-11-25-s0.25-exact-r200`).
pub const SAME_HEIGHT: f64 = 0.005;

/// The paper's five qualitative findings (its Results and Conclusions), each checked on the
/// **steady** cases given as `(impeller, ℓ/d, findings)`: a line per finding, saying
/// "confirmed", "not confirmed" or "not tested" and the numbers that show it.
///
/// 1. Longer cylinders are better suspended and lie more horizontally: per impeller with at
///    least two steady aspect ratios, `⟨z_p⟩/H` and the mean `φ` both rise with ℓ/d.
/// 2. The mobile particles' pdf of `φ` is close to `sin φ` for ℓ/d = 1: its distance from
///    `sin φ` is the smallest of the impeller's steady aspect ratios.
/// 3. Rotational kinetic energy is more than an order of magnitude below linear: the ratio is
///    at least 10 in every steady case.
/// 4. The disk leaves few particles above it ("the solids hardly reach vertical levels higher
///    than the disk", "the virtual absence of particles above the disk"): less than
///    [`FEW_ABOVE`] of the solids volume above mid-height (the disk's plane) with the disk, and
///    less than with the PBT at the same ℓ/d. Lower than the PBT's alone is reported as such,
///    not as confirmed.
/// 5. The disk suspends less than the PBT ("the disk shows lower ⟨z_p⟩/H levels than the
///    PBT"): `⟨z_p⟩/H` lower with the disk by more than [`SAME_HEIGHT`] at each ℓ/d where both
///    are steady.
///
/// Findings 4 and 5 pair a disk case with the PBT case of the same ℓ/d at the same scale; a
/// pair with a value missing is not tested.
pub fn verdicts(cases: &[(&str, f64, Findings)]) -> Vec<String> {
    let steady: Vec<&(&str, f64, Findings)> = cases.iter().filter(|c| c.2.steady).collect();
    let of = |imp: &str| {
        let mut v: Vec<&(&str, f64, Findings)> = steady.iter().copied().filter(|c| c.0 == imp).collect();
        v.sort_by(|a, b| a.1.total_cmp(&b.1));
        v
    };
    let name = |imp: &str| if imp == "pbt" { "PBT" } else { "disk" };
    let list = |v: &[&(&str, f64, Findings)], f: &dyn Fn(&Findings) -> String| {
        v.iter().map(|c| format!("{} at ℓ/d = {}", f(&c.2), c.1)).collect::<Vec<_>>().join(", ")
    };
    let rising =
        |v: &[&(&str, f64, Findings)], f: fn(&Findings) -> f64| v.windows(2).all(|w| f(&w[1].2) > f(&w[0].2));
    // A finding's line: its parts, or what it needs when there is none.
    let finding = |claim: &str, parts: Vec<String>, needs: &str| {
        if parts.is_empty() {
            format!("{claim}: not tested (needs {needs}).")
        } else {
            format!("{claim}: {}.", parts.join("; "))
        }
    };
    let mut out = Vec::new();

    // 1.
    let mut parts = Vec::new();
    for imp in ["disk", "pbt"] {
        let v = of(imp);
        if v.len() < 2 {
            continue;
        }
        let (up, flat) = (rising(&v, |f| f.mean_height), rising(&v, |f| f.phi_all));
        parts.push(format!(
            "{} for the {}: ⟨z_p⟩/H {}; mean φ {}",
            match (up, flat) {
                (true, true) => "confirmed",
                (true, false) => "better suspended but not flatter",
                (false, true) => "flatter but not better suspended",
                (false, false) => "not confirmed",
            },
            name(imp),
            list(&v, &|f| format!("{:.3}", f.mean_height)),
            list(&v, &|f| format!("{:.1}°", f.phi_all)),
        ));
    }
    out.push(finding(
        "Longer cylinders are better suspended and lie more horizontally",
        parts,
        "two aspect ratios of one impeller at steady state",
    ));

    // 2.
    let mut parts = Vec::new();
    for imp in ["disk", "pbt"] {
        let v = of(imp);
        let Some(one) = v.iter().find(|c| c.1 == 1.0) else { continue };
        let closest = v.iter().all(|c| c.2.l1_mobile >= one.2.l1_mobile);
        parts.push(format!(
            "{} for the {}: ∫|pdf − sin φ| dφ of the mobile particles {}",
            if v.len() < 2 {
                "measured (no other aspect ratio to compare)"
            } else if closest {
                "confirmed (closest to sin φ of the aspect ratios)"
            } else {
                "not confirmed (not the closest to sin φ)"
            },
            name(imp),
            list(&v, &|f| format!("{:.3}", f.l1_mobile)),
        ));
    }
    out.push(finding(
        "The mobile particles' orientation is close to random (sin φ) for ℓ/d = 1",
        parts,
        "ℓ/d = 1 at steady state",
    ));

    // 3.
    let parts = if steady.is_empty() {
        Vec::new()
    } else {
        vec![format!(
            "{}: linear over rotational {}",
            if steady.iter().all(|c| c.2.kinetic_ratio >= 10.0) { "confirmed" } else { "not confirmed" },
            steady
                .iter()
                .map(|c| format!("{:.0} ({} ℓ/d = {})", c.2.kinetic_ratio, name(c.0), c.1))
                .collect::<Vec<_>>()
                .join(", ")
        )]
    };
    out.push(finding(
        "Rotational kinetic energy is more than an order of magnitude below linear",
        parts,
        "a case at steady state",
    ));

    // 4.
    let partner = |d: &(&str, f64, Findings)| {
        of("pbt").into_iter().find(|p| p.1 == d.1 && p.2.scale == d.2.scale).map(|p| p.2)
    };
    let pairs: Vec<String> = of("disk")
        .iter()
        .filter_map(|d| {
            let p = partner(d).filter(|p| p.above_impeller.is_finite() && d.2.above_impeller.is_finite())?;
            Some(format!(
                "{} at ℓ/d = {}: {:.1} % of the solids above mid-height with the disk, {:.1} % with the PBT",
                match (d.2.above_impeller < p.above_impeller, d.2.above_impeller < FEW_ABOVE) {
                    (true, true) => "confirmed",
                    (true, false) => "lower than with the PBT, but not few",
                    (false, _) => "not confirmed",
                },
                d.1,
                100.0 * d.2.above_impeller,
                100.0 * p.above_impeller
            ))
        })
        .collect();
    out.push(finding(
        "The disk leaves few particles above it",
        pairs,
        "a disk case and the PBT at the same ℓ/d, both steady",
    ));

    // 5.
    let pairs: Vec<String> = of("disk")
        .iter()
        .filter_map(|d| {
            let p = partner(d).filter(|p| p.mean_height.is_finite() && d.2.mean_height.is_finite())?;
            let below = p.mean_height - d.2.mean_height;
            Some(format!(
                "{} at ℓ/d = {}: ⟨z_p⟩/H {:.3} with the disk, {:.3} with the PBT",
                if below > SAME_HEIGHT {
                    "confirmed".to_string()
                } else if below.abs() <= SAME_HEIGHT {
                    format!("not confirmed (the same within {SAME_HEIGHT})")
                } else {
                    "not confirmed".to_string()
                },
                d.1,
                d.2.mean_height,
                p.mean_height
            ))
        })
        .collect();
    out.push(finding(
        "The disk suspends less than the PBT",
        pairs,
        "a disk case and the PBT at the same ℓ/d, both steady",
    ));
    out
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
        "\n## The paper's qualitative findings\n\nChecked on the steady cases only (`verdicts` in \
         `src/reproduce/summary.rs`); the numbers of every case run, steady or not, below. φ is the angle between \
         the cylinder axis and the vertical (random orientation: mean 57.3°, 50 % beyond 60°); the pdfs and \
         profiles are over each run's last 10 revolutions.\n\n",
    );
    let found: Vec<(&str, (&str, f64, Findings))> = cases
        .iter()
        .filter_map(|(name, p, r)| {
            r.as_ref().map(|r| (*name, (p.impeller.as_str(), p.aspect_ratio, Findings::of(r))))
        })
        .collect();
    for v in verdicts(&found.iter().map(|c| c.1).collect::<Vec<_>>()) {
        let _ = writeln!(md, "- {v}");
    }
    md.push_str(
        "\n| case | steady | ⟨z_p⟩/H | mean φ, all | mean φ, mobile | φ > 60°, all | ∫\\|pdf − sin φ\\| dφ, mobile \
         | kinetic energy, linear / rotational | solids above mid-height |\n|---|---|---|---|---|---|---|---|---|\n",
    );
    for (name, (_, _, f)) in &found {
        let _ = writeln!(
            md,
            "| {name} | {} | {:.3} | {:.1}° | {:.1}° | {:.0} % | {:.3} | {:.0} | {:.1} % |",
            if f.steady { "yes" } else { "no" },
            f.mean_height,
            f.phi_all,
            f.phi_mobile,
            100.0 * f.flat_all,
            f.l1_mobile,
            f.kinetic_ratio,
            100.0 * f.above_impeller
        );
    }

    md.push_str("\n## Figures\n\n");
    for impeller in ["disk", "pbt"] {
        let has_report = |case: &str| cases.iter().any(|(n, _, r)| *n == case && r.is_some());
        md.push_str(&snapshot_panels(root, &out, impeller, has_report)?);
    }
    md.push_str("As the paper draws them: the three aspect ratios of one impeller on one plot.\n\n");
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

/// The paper's four-panel Figure 3 (disk) or 4 (PBT), as a Markdown table of the panels:
/// ℓ/d = 4 (top) and 1 (bottom), 10 and 90 revolutions after the start (left, right). Each
/// panel is the case report's own `fig03_midplane_rev010.png` (…`rev090`, `fig04_…` for the
/// PBT), copied into `out` as `fig03_disk_ld4_rev010.png` etc., so that the summary stands on
/// its own wherever it is copied; a panel the case does not have (no report, or its run did not
/// reach that revolution) is named as missing, and an earlier summary's copy of it is removed.
/// `has_report(case)`: whether the case's report was read (a case listed as not run shows no
/// panels, whatever PNG is left in its directory). Nothing when neither case has a panel.
fn snapshot_panels(
    root: &Path,
    out: &Path,
    impeller: &str,
    has_report: impl Fn(&str) -> bool,
) -> anyhow::Result<String> {
    let figure = report::midplane_figure_number(impeller);
    let label = if impeller == "disk" { "disk" } else { "pitched-blade turbine" };
    let mut rows = String::new();
    let mut found = 0;
    for ld in [4, 1] {
        let case = format!("{impeller}-ld{ld}");
        let _ = write!(rows, "| ℓ/d = {ld} |");
        for rev in [10, 90] {
            let src =
                root.join(&case).join(format!("{}.png", report::midplane_stem(impeller, Some(rev as f64))));
            let name = format!("fig{figure:02}_{impeller}_ld{ld}_rev{rev:03}.png");
            if !has_report(&case) || !src.exists() {
                let stale = out.join(&name);
                if stale.exists() {
                    std::fs::remove_file(&stale)
                        .with_context(|| format!("cannot remove {}", stale.display()))?;
                }
                let _ = write!(rows, " not drawn: `{case}` has no snapshot at {rev} revolutions |");
                continue;
            }
            let bytes = std::fs::read(&src).with_context(|| format!("cannot read {}", src.display()))?;
            let dest = out.join(&name);
            atomic_write_bytes(&dest, &bytes).with_context(|| format!("cannot write {}", dest.display()))?;
            let _ = write!(rows, " ![{case}, {rev} revolutions]({name}) |");
            found += 1;
        }
        rows.push('\n');
    }
    if found == 0 {
        return Ok(String::new());
    }
    Ok(format!(
        "**Figure {figure} ({label}): instantaneous realisations, |u|/v_tip on the vertical mid-plane with the \
         cylinders' sections; ℓ/d = 4 (top) and 1 (bottom), 10 and 90 revolutions after the start (left, right)**\n\n\
         | | 10 revolutions | 90 revolutions |\n|---|---|---|\n{rows}\n"
    ))
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

#[cfg(test)]
mod tests {
    use super::{snapshot_panels, verdicts, Findings};

    #[test]
    fn snapshot_panels_copy_what_exists_and_name_what_is_missing() {
        let root = tempfile::tempdir().unwrap();
        let out = root.path().join("summary");
        std::fs::create_dir_all(&out).unwrap();
        let all = |_: &str| true;
        // No case has a panel: nothing.
        assert_eq!(snapshot_panels(root.path(), &out, "disk", all).unwrap(), "");
        // disk-ld4 has both, disk-ld1 only the one at 10 revolutions; the PBT's are Figure 4's
        // (`fig04_…`; a `fig03_…` beside them is not taken).
        for (case, file) in [
            ("disk-ld4", "fig03_midplane_rev010.png"),
            ("disk-ld4", "fig03_midplane_rev090.png"),
            ("disk-ld1", "fig03_midplane_rev010.png"),
            ("pbt-ld4", "fig04_midplane_rev010.png"),
            ("pbt-ld4", "fig03_midplane_rev090.png"),
        ] {
            let dir = root.path().join(case);
            std::fs::create_dir_all(&dir).unwrap();
            std::fs::write(dir.join(file), format!("{case} {file}")).unwrap();
        }
        // An earlier summary's copy of a panel that is gone now.
        std::fs::write(out.join("fig03_disk_ld1_rev090.png"), "stale").unwrap();
        let md = snapshot_panels(root.path(), &out, "disk", all).unwrap();
        assert!(md.starts_with("**Figure 3 (disk)"), "{md}");
        assert!(md.contains("| ℓ/d = 4 | ![disk-ld4, 10 revolutions](fig03_disk_ld4_rev010.png) | ![disk-ld4, 90 revolutions](fig03_disk_ld4_rev090.png) |"), "{md}");
        assert!(md.contains("| ℓ/d = 1 | ![disk-ld1, 10 revolutions](fig03_disk_ld1_rev010.png) | not drawn: `disk-ld1` has no snapshot at 90 revolutions |"), "{md}");
        assert_eq!(
            std::fs::read_to_string(out.join("fig03_disk_ld4_rev090.png")).unwrap(),
            "disk-ld4 fig03_midplane_rev090.png"
        );
        assert!(!out.join("fig03_disk_ld1_rev090.png").exists(), "the stale copy is removed");
        let md = snapshot_panels(root.path(), &out, "pbt", all).unwrap();
        assert!(md.starts_with("**Figure 4 (pitched-blade turbine)"), "{md}");
        assert!(md.contains("| ℓ/d = 4 | ![pbt-ld4, 10 revolutions](fig04_pbt_ld4_rev010.png) | not drawn: `pbt-ld4` has no snapshot at 90 revolutions |"), "{md}");
        assert!(md.contains("| ℓ/d = 1 | not drawn: `pbt-ld1` has no snapshot at 10 revolutions |"), "{md}");
        // A case without a report shows no panel, whatever PNG its directory holds.
        let md = snapshot_panels(root.path(), &out, "disk", |c: &str| c != "disk-ld4").unwrap();
        assert!(md.contains("| ℓ/d = 4 | not drawn: `disk-ld4` has no snapshot at 10 revolutions |"), "{md}");
        assert!(!out.join("fig03_disk_ld4_rev010.png").exists());
    }

    fn f(
        steady: bool,
        mean_height: f64,
        phi_all: f64,
        l1_mobile: f64,
        kinetic_ratio: f64,
        above: f64,
    ) -> Findings {
        Findings {
            steady,
            scale: 0.25,
            mean_height,
            phi_all,
            phi_mobile: phi_all - 6.0,
            flat_all: 0.6,
            l1_mobile,
            kinetic_ratio,
            above_impeller: above,
        }
    }

    #[test]
    fn verdicts_use_the_steady_cases_and_say_what_fails() {
        // Nothing steady: nothing tested, whatever the numbers.
        let v = verdicts(&[("pbt", 2.0, f(false, 0.3, 60.0, 0.1, 30.0, 0.3))]);
        assert_eq!(v.len(), 5);
        assert!(v.iter().all(|l| l.contains("not tested")), "{v:?}");

        // The two steady PBT cases of the s = 1/4 archives: confirmed, with the numbers.
        let ld2 = f(true, 0.332, 63.1, 0.104, 34.0, 0.275);
        let ld4 = f(true, 0.374, 68.7, 0.259, 16.0, 0.348);
        let v = verdicts(&[("pbt", 4.0, ld4), ("pbt", 2.0, ld2)]);
        assert!(
            v[0].contains("confirmed for the PBT: ⟨z_p⟩/H 0.332 at ℓ/d = 2, 0.374 at ℓ/d = 4"),
            "{}",
            v[0]
        );
        assert!(v[1].contains("not tested"), "{}", v[1]);
        assert!(
            v[2].contains("confirmed: linear over rotational 16 (PBT ℓ/d = 4), 34 (PBT ℓ/d = 2)"),
            "{}",
            v[2]
        );
        assert!(v[3].contains("not tested"), "{}", v[3]);
        assert!(v[4].contains("not tested"), "{}", v[4]);

        // Each finding can fail.
        let lower = f(true, 0.30, 70.0, 0.5, 8.0, 0.4);
        let one = f(true, 0.25, 60.0, 0.05, 40.0, 0.2);
        let disk = f(true, 0.2, 60.0, 0.3, 40.0, 0.45);
        let v = verdicts(&[("pbt", 2.0, ld2), ("pbt", 4.0, lower), ("pbt", 1.0, one), ("disk", 1.0, disk)]);
        assert!(v[0].contains("flatter but not better suspended for the PBT"), "{}", v[0]);
        assert!(v[1].contains("confirmed (closest to sin φ of the aspect ratios) for the PBT"), "{}", v[1]);
        assert!(v[1].contains("measured (no other aspect ratio to compare) for the disk"), "{}", v[1]);
        assert!(v[2].starts_with("Rotational") && v[2].contains(": not confirmed:"), "{}", v[2]);
        assert!(v[3].contains("not confirmed at ℓ/d = 1: 45.0 % of the solids above mid-height with the disk, 20.0 % with the PBT"), "{}", v[3]);
        assert!(
            v[4].contains("confirmed at ℓ/d = 1: ⟨z_p⟩/H 0.200 with the disk, 0.250 with the PBT"),
            "{}",
            v[4]
        );
        assert!(!v[4].contains("not confirmed"), "{}", v[4]);

        // The disk cases of the archives `2026-11-26-s0.25-r130` (both at 130 revolutions):
        // fewer solids above the disk than above the PBT, but a quarter of them, not the
        // paper's "virtual absence"; and not lower than the PBT at ℓ/d = 2.
        let disk2 = f(true, 0.3345, 64.3, 0.131, 35.0, 0.268);
        let disk4 = f(true, 0.3341, 65.5, 0.328, 16.0, 0.259);
        let few = f(true, 0.2, 60.0, 0.3, 40.0, 0.05);
        let v = verdicts(&[("pbt", 2.0, ld2), ("pbt", 4.0, ld4), ("disk", 2.0, disk2), ("disk", 4.0, disk4)]);
        assert!(v[3].contains("lower than with the PBT, but not few at ℓ/d = 2: 26.8 %"), "{}", v[3]);
        assert!(v[3].contains("lower than with the PBT, but not few at ℓ/d = 4: 25.9 %"), "{}", v[3]);
        assert!(
            v[4].contains(
                "not confirmed (the same within 0.005) at ℓ/d = 2: ⟨z_p⟩/H 0.335 with the disk, 0.332 with the PBT"
            ),
            "{}",
            v[4]
        );
        assert!(
            v[4].contains("; confirmed at ℓ/d = 4: ⟨z_p⟩/H 0.334 with the disk, 0.374 with the PBT"),
            "{}",
            v[4]
        );
        let v = verdicts(&[("pbt", 2.0, ld2), ("disk", 2.0, few)]);
        assert!(v[3].contains("confirmed at ℓ/d = 2: 5.0 %") && !v[3].contains("not"), "{}", v[3]);
        assert!(v[4].starts_with("The disk suspends less than the PBT: confirmed at ℓ/d = 2"), "{}", v[4]);

        // Higher by more than SAME_HEIGHT: plainly not confirmed. Pairs at different scales,
        // or with a value missing, are not compared.
        let high = f(true, 0.36, 60.0, 0.3, 40.0, 0.3);
        let v = verdicts(&[("pbt", 2.0, ld2), ("disk", 2.0, high)]);
        assert!(v[4].contains(": not confirmed at ℓ/d = 2: ⟨z_p⟩/H 0.360"), "{}", v[4]);
        let half = Findings { scale: 0.5, ..high };
        let v = verdicts(&[("pbt", 2.0, ld2), ("disk", 2.0, half)]);
        assert!(v[3].contains("not tested") && v[4].contains("not tested"), "{v:?}");
        let missing = Findings { mean_height: f64::NAN, above_impeller: f64::NAN, ..high };
        let v = verdicts(&[("pbt", 2.0, ld2), ("disk", 2.0, missing)]);
        assert!(v[3].contains("not tested") && v[4].contains("not tested"), "{v:?}");
    }
}
