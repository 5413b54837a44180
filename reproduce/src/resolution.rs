//! The resolution study of one case (`slurry resolution RUN_DIR...`): its statistics at
//! several scales side by side, the change between neighbouring scales, and, from the three
//! finest **steady** scales when their values are monotone, the observed order `p` and the
//! Richardson estimate `f₀` of
//!
//! ```text
//! f(h) = f₀ + C hᵖ,    h = 1/s    (the grid spacing in units of the paper's: d = 12 s nodes)
//! ```
//!
//! ([`slurry::util::richardson3`]). This table decides what a reduced-scale regression may
//! assert against the paper: a band is supported where the sequence converges towards the
//! paper's value, not where it is one point or wanders.
//!
//! What counts as a point: a run whose report's steady test passed. A run that is not steady
//! is listed (its values in italics) but never enters an order or a limit: a transient is not a
//! point of a resolution study. Each run is read from its report's `statistics.json` (the
//! `--out` directory of `slurry reproduce`, or an archive of it), so the study can be redrawn
//! whenever a scale finishes.
//!
//! Each row names how its run started ([`RunStart`]): from a settled bed, as the paper's runs, or
//! from another run's particles (`--start-from`, the level approached from above or from
//! below). A steady point of the second kind counts, and the table says under it that its level
//! is the bed's only if the steady state does not depend on the start.
//!
//! **Several starts at one scale.** Runs of one scale that started differently (from above and
//! from below, or from the bed) are each a row. Where two or more of them are steady, the
//! scale's level `f̄` is their mean and their spread `Δ_start = max − min` measures how much the
//! steady state depends on the start; the changes between scales and the fit use `f̄`. Each
//! level is then uncertain by about `±Δ_start/2`, so no order is claimed when, among the three
//! finest scales, a spread exceeds half the smallest change between them
//! ([`Convergence::StartDependent`]): the fitted order would be the start's, not the grid's.

use std::fmt::Write as _;
use std::path::{Path, PathBuf};

use anyhow::Context;

use super::report::{STEADY_DRIFT, STEADY_REVOLUTIONS};
use super::start::RunStart;
use super::{check_scale, paper_case};
use slurry::io::atomic_write_bytes;
use slurry::util::richardson3;

/// The statistics the study compares: `statistics.json` key and label.
pub const QUANTITIES: [(&str, &str); 4] =
    [("mean_height", "⟨z_p⟩/H"), ("po_fluid", "Po_f"), ("po_solids", "Po_c"), ("po", "Po")];

/// The smallest ratio of neighbouring scales in a study: closer scales (e.g. 0.333 and 0.3333)
/// are the same resolution, and an order fitted across them would be noise.
pub const MIN_SCALE_RATIO: f64 = 1.05;

/// One scale of the study: one run's report.
#[derive(Clone, Debug, PartialEq)]
pub struct Point {
    /// Where it was read from.
    pub dir: PathBuf,
    /// Scale `s` (1: the paper's grid).
    pub scale: f64,
    /// The run's time at its report in revolutions, `t N` (the ramp counts 1, so 201 for a run
    /// of 200 revolutions after it; NaN: not recorded).
    pub revolutions: f64,
    /// The report's steady test passed.
    pub steady: bool,
    /// The steady test's drift: the fitted change of ⟨z_p⟩/H over its last
    /// [`STEADY_REVOLUTIONS`] (`None`: not recorded). Beyond [`STEADY_DRIFT`] a steady run
    /// passed under a looser test of an older version (on its noise allowance, or
    /// `|drift| ≤ 0.015`) and may still be moving, and the table says so.
    pub drift: Option<f64>,
    /// The power average's window is covered by the series (`None`: the report predates the
    /// record).
    pub power_covered: Option<bool>,
    /// The values of [`QUANTITIES`], in order (`None`: not in the report).
    pub values: [Option<f64>; 4],
    /// How the run started (`None`: not recorded, reports written by older versions).
    pub start: Option<RunStart>,
}

impl Point {
    /// Quantity `q`'s value where it counts as a point of the study: the run is steady and,
    /// for the power numbers, their window is not known to have a lost stretch.
    pub fn counted(&self, q: usize) -> Option<f64> {
        let power = QUANTITIES[q].0 != "mean_height";
        if self.steady && !(power && self.power_covered == Some(false)) {
            self.values[q]
        } else {
            None
        }
    }
}

/// Reads one run's `statistics.json`: the case's name and its [`Point`].
///
/// # Errors
/// The file is missing or not a report's statistics (no `case`, `scale` or `steady`); the case
/// is not one of the paper's; the scale is outside the reproduction's range
/// ([`check_scale`]). Each message names the file.
pub fn read_point(dir: &Path) -> anyhow::Result<(String, Point)> {
    let path = dir.join("statistics.json");
    let text = std::fs::read_to_string(&path).with_context(|| {
        format!(
            "cannot read {}: give the output directory of a finished `slurry reproduce` run",
            path.display()
        )
    })?;
    let json: serde_json::Value =
        serde_json::from_str(&text).with_context(|| format!("{}: not JSON", path.display()))?;
    let num = |k: &str| json.get(k).and_then(serde_json::Value::as_f64);
    let case = json
        .get("case")
        .and_then(serde_json::Value::as_str)
        .with_context(|| format!("{}: no \"case\" (not a report's statistics)", path.display()))?
        .to_string();
    paper_case(&case).with_context(|| format!("{}: \"case\"", path.display()))?;
    let scale = num("scale").with_context(|| format!("{}: no number \"scale\"", path.display()))?;
    check_scale(scale)
        .map_err(|e| anyhow::anyhow!("{}: \"scale\" {}", path.display(), e.trim_start_matches("--scale ")))?;
    let steady = json.get("steady").and_then(serde_json::Value::as_bool).with_context(|| {
        format!("{}: no true/false \"steady\" (not a report's statistics)", path.display())
    })?;
    let point = Point {
        dir: dir.to_path_buf(),
        scale,
        revolutions: num("revolutions").unwrap_or(f64::NAN),
        steady,
        drift: num("steady_drift").filter(|v| v.is_finite()),
        power_covered: json.get("power_covered").and_then(serde_json::Value::as_bool),
        values: QUANTITIES.map(|(k, _)| num(k).filter(|v| v.is_finite())),
        start: json
            .get("start")
            .map(|v| serde_json::from_value::<RunStart>(v.clone()))
            .transpose()
            .with_context(|| format!("{}: \"start\"", path.display()))?,
    };
    Ok((case, point))
}

/// What three or more steady points say about one quantity.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Convergence {
    /// Fewer than three scales where the quantity counts: no order can be fitted.
    TooFew(usize),
    /// The three finest values are not monotone (or their scales are not strictly
    /// increasing), or no order in (0.05, 8) fits them.
    NotMonotone,
    /// Among the three finest scales, the runs of one scale from different starts are further
    /// apart than half the smallest change between the scales ([`START_SPREAD_FRACTION`]).
    StartDependent {
        /// The largest spread `max − min` between the starts of one scale.
        spread: f64,
        /// The smallest change of the level between neighbouring scales among the three.
        change: f64,
    },
    /// The observed order and the Richardson estimate of the limit.
    Order {
        /// `p`.
        order: f64,
        /// `f₀`.
        limit: f64,
    },
}

/// The largest start spread, as a fraction of the smallest change between the three finest
/// scales, for which an order is still claimed: each level is uncertain by about half its
/// spread, so at this fraction by a quarter of the smallest change.
pub const START_SPREAD_FRACTION: f64 = 0.5;

/// One scale's level of one quantity: the mean of its counted runs.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Level {
    /// `s`.
    pub scale: f64,
    /// The mean of the counted runs' values, `f̄`.
    pub value: f64,
    /// `max − min` of the counted runs' values (0 for one run).
    pub spread: f64,
    /// How many runs count at this scale.
    pub runs: usize,
}

/// Two scales of the study are one (the same grid, several runs): equal to a part in 10⁶.
fn same_scale(a: f64, b: f64) -> bool {
    (a / b - 1.0).abs() < 1e-6
}

/// The levels of quantity `q` by scale, over the points where it counts ([`Point::counted`]),
/// in the order of `points` ([`order_points`] sorts them and puts the runs of one scale
/// together).
pub fn levels(points: &[Point], q: usize) -> Vec<Level> {
    let counted: Vec<(f64, f64)> = points.iter().filter_map(|p| p.counted(q).map(|v| (p.scale, v))).collect();
    counted
        .chunk_by(|a, b| same_scale(a.0, b.0))
        .map(|runs| {
            let (lo, hi) =
                runs.iter().fold((f64::INFINITY, f64::NEG_INFINITY), |(l, h), &(_, v)| (l.min(v), h.max(v)));
            let value = runs.iter().map(|&(_, v)| v).sum::<f64>() / runs.len() as f64;
            Level { scale: runs[0].0, value, spread: hi - lo, runs: runs.len() }
        })
        .collect()
}

/// The convergence of quantity `q` (an index into [`QUANTITIES`]) over its [`levels`], from
/// the three finest. `points` as [`order_points`] returns them; out of order or at equal
/// scales there is no order to claim ([`Convergence::NotMonotone`]); nor where the start
/// matters as much as the grid ([`Convergence::StartDependent`]).
pub fn convergence(points: &[Point], q: usize) -> Convergence {
    let levels = levels(points, q);
    if levels.len() < 3 {
        return Convergence::TooFew(levels.len());
    }
    let t = &levels[levels.len() - 3..];
    let spread = t.iter().map(|l| l.spread).fold(0.0, f64::max);
    let change = (t[1].value - t[0].value).abs().min((t[2].value - t[1].value).abs());
    if spread > START_SPREAD_FRACTION * change {
        return Convergence::StartDependent { spread, change };
    }
    match richardson3([0, 1, 2].map(|i| 1.0 / t[i].scale), [0, 1, 2].map(|i| t[i].value)) {
        Some((order, limit)) => Convergence::Order { order, limit },
        None => Convergence::NotMonotone,
    }
}

/// Sorts the points by scale and checks they are one study: neighbouring scales at least
/// [`MIN_SCALE_RATIO`] apart, or the same scale for runs that started differently (recorded,
/// and not equal: from above and from below, or from the bed).
///
/// # Errors
/// Two runs at nearly the same scale, or at one scale from the same (or an unrecorded) start,
/// naming both.
pub fn order_points(mut points: Vec<Point>) -> anyhow::Result<Vec<Point>> {
    points.sort_by(|a, b| a.scale.total_cmp(&b.scale));
    for (i, b) in points.iter().enumerate() {
        for a in &points[..i] {
            if same_scale(a.scale, b.scale) {
                if a.start.is_none() || b.start.is_none() || a.start == b.start {
                    anyhow::bail!(
                        "{} and {} are both at scale {} {}: several runs of one scale must differ in \
                         how they started (from above, from below, from the bed), so that their spread \
                         measures the start's effect",
                        a.dir.display(),
                        b.dir.display(),
                        b.scale,
                        if a.start.is_none() || b.start.is_none() {
                            "and one does not record its start"
                        } else {
                            "from the same start"
                        }
                    );
                }
            } else if b.scale < MIN_SCALE_RATIO * a.scale {
                anyhow::bail!(
                    "{} (scale {}) and {} (scale {}) are the same resolution (neighbouring scales must \
                     differ by a factor of at least {MIN_SCALE_RATIO}): give one run per scale, or runs \
                     of exactly one scale from different starts",
                    a.dir.display(),
                    a.scale,
                    b.dir.display(),
                    b.scale
                );
            }
        }
    }
    Ok(points)
}

/// The study's Markdown: one row per scale, then the change between neighbouring steady
/// scales and the convergence of each quantity, beside the paper's values.
///
/// # Errors
/// `case` is not one of the paper's cases.
pub fn table(case: &str, points: &[Point]) -> anyhow::Result<String> {
    let paper = paper_case(case)?.paper()?;
    let paper_of = |key: &str| paper.values.iter().find(|v| v.key == key).and_then(|v| v.paper);
    let fmt_scale = |s: f64| slurry::util::fmt_num((s * 1e4).round() / 1e4);
    let mut s = String::new();
    let _ = writeln!(s, "# Resolution study: {case}\n");
    let _ = writeln!(
        s,
        "Each row is one run's report (`statistics.json`): ⟨z_p⟩/H over the steady test's window, \
         the power numbers over the last 30 revolutions; t N: the time in impeller revolutions, the \
         ramp counting 1. *Italics*: the value does not count (the \
         run is not steady, or the power window has a lost stretch), so it is listed but enters \
         no order or limit. h = 1/s is the grid spacing in units of the paper's (d = 12 s lattice \
         spacings). Drift: the fitted change of ⟨z_p⟩/H over the steady test's last {} \
         revolutions; the test passes up to {}, so a steady run with a larger drift (†) passed \
         an earlier, looser test and may still be moving in that direction, and its value is a \
         bound more than a limit.\n",
        STEADY_REVOLUTIONS, STEADY_DRIFT
    );
    let mut header = "| s | d | t N at the end | start | steady | drift | power window covered |".to_string();
    let mut rule = "|---|---|---|---|---|---|---|".to_string();
    for (_, label) in QUANTITIES {
        header += &format!(" {label} |");
        rule += "---|";
    }
    let _ = writeln!(s, "{header}\n{rule}");
    for p in points {
        let drift = p.drift.map_or("–".to_string(), |d| {
            format!("{d:+.4}{}", if d.abs() > STEADY_DRIFT { " †" } else { "" })
        });
        let mut row = format!(
            "| {} | {} | {} | {} | {} | {drift} | {} |",
            fmt_scale(p.scale),
            slurry::util::fmt_num((12.0 * p.scale * 100.0).round() / 100.0),
            if p.revolutions.is_finite() { format!("{:.0}", p.revolutions) } else { "–".into() },
            p.start.as_ref().map_or("not recorded".to_string(), RunStart::label),
            if p.steady { "yes" } else { "no" },
            match p.power_covered {
                Some(true) => "yes",
                Some(false) => "no",
                None => "not recorded",
            }
        );
        for (q, v) in p.values.iter().enumerate() {
            row += &match (v, p.counted(q).is_some()) {
                (Some(v), true) => format!(" {v:.3} |"),
                (Some(v), false) => format!(" *{v:.3}* |"),
                (None, _) => " – |".to_string(),
            };
        }
        let _ = writeln!(s, "{row}");
    }
    let mut row = "| paper | 12 | | bed settled in the liquid | | | |".to_string();
    for (key, _) in QUANTITIES {
        row += &format!(" {} |", paper_of(key).map_or("–".to_string(), |v| format!("{v}")));
    }
    let _ = writeln!(s, "{row}");

    // A level reached from another run's state is the bed's only if the steady state does not
    // depend on the start: say so wherever the steady points did not all start from a bed.
    let mut from: Vec<String> = points
        .iter()
        .filter(|p| p.steady && matches!(p.start, Some(RunStart::StartFrom(_))))
        .map(|p| fmt_scale(p.scale))
        .collect();
    from.dedup();
    if !from.is_empty() {
        let _ = writeln!(
            s,
            "\n**Not every steady point started from a bed**: s = {} started from another run's particles \
             (`--start-from`). Its level counts as that scale's only if the steady state does not depend on \
             the start, which is shown where a run from the bed reached the same level at that scale.",
            from.join(", ")
        );
    }

    let several: Vec<(usize, Level)> = (0..QUANTITIES.len())
        .flat_map(|q| levels(points, q).into_iter().filter(|l| l.runs > 1).map(move |l| (q, l)))
        .collect();
    if !several.is_empty() {
        let _ = writeln!(s, "\n## Several starts at one scale\n");
        let _ = writeln!(
            s,
            "The steady runs of one scale that started differently: the scale's level is their mean f̄, \
             and their spread (max − min) is how much the steady state depends on the start. The changes \
             and the fit below use f̄; no order is claimed where, among the three finest scales, a spread \
             exceeds {START_SPREAD_FRACTION} of the smallest change between them.\n"
        );
        let _ = writeln!(s, "| s | quantity | runs | f̄ | spread |\n|---|---|---|---|---|");
        for (q, l) in &several {
            let runs = points
                .iter()
                .filter(|p| same_scale(p.scale, l.scale))
                .filter_map(|p| {
                    p.counted(*q).map(|v| {
                        format!(
                            "{v:.3} ({})",
                            p.start.as_ref().map_or("not recorded".into(), RunStart::label)
                        )
                    })
                })
                .collect::<Vec<_>>()
                .join(", ");
            let _ = writeln!(
                s,
                "| {} | {} | {runs} | {:.3} | {:.3} |",
                fmt_scale(l.scale),
                QUANTITIES[*q].1,
                l.value,
                l.spread
            );
        }
    }

    let _ = writeln!(s, "\n## Convergence\n");
    let _ = writeln!(
        s,
        "| quantity | change between neighbouring counted scales | observed order p | Richardson limit f₀ | paper |"
    );
    let _ = writeln!(s, "|---|---|---|---|---|");
    for (q, (key, label)) in QUANTITIES.iter().enumerate() {
        let changes = levels(points, q)
            .windows(2)
            .map(|w| {
                format!(
                    "{:+.3} (s {} → {})",
                    w[1].value - w[0].value,
                    fmt_scale(w[0].scale),
                    fmt_scale(w[1].scale)
                )
            })
            .collect::<Vec<_>>();
        let (order, limit) = match convergence(points, q) {
            Convergence::TooFew(n) => {
                (format!("– ({n} steady scale{}; needs 3)", if n == 1 { "" } else { "s" }), "–".into())
            }
            Convergence::NotMonotone => ("– (not monotone: no order claimed)".into(), "–".into()),
            Convergence::StartDependent { spread, change } => (
                format!(
                    "– (a start spread of {spread:.3} against a smallest change of {change:.3}: no order claimed)"
                ),
                "–".into(),
            ),
            Convergence::Order { order, limit } => (format!("{order:.2}"), format!("{limit:.3}")),
        };
        let _ = writeln!(
            s,
            "| {label} | {} | {order} | {limit} | {} |",
            if changes.is_empty() { "–".to_string() } else { changes.join(", ") },
            paper_of(key).map_or("–".to_string(), |v| format!("{v}"))
        );
    }
    let _ = writeln!(s, "\nRuns:\n");
    for p in points {
        let _ = writeln!(s, "- s = {}: `{}`", fmt_scale(p.scale), p.dir.display());
    }
    Ok(s)
}

/// `slurry resolution`: reads the runs, checks they are one case at distinct scales (or at one
/// scale from different starts), and returns the table (written atomically to `out` too, when
/// given).
///
/// # Errors
/// A run's statistics cannot be read; the runs are of different cases or share a scale and a
/// start; the
/// case is not one of the paper's; `out` cannot be written.
pub fn write_resolution(dirs: &[PathBuf], out: Option<&Path>) -> anyhow::Result<String> {
    anyhow::ensure!(
        !dirs.is_empty(),
        "no runs given: name the output directories of one case at several scales"
    );
    let mut case: Option<(String, PathBuf)> = None;
    let mut points = Vec::new();
    for d in dirs {
        let (c, p) = read_point(d)?;
        match &case {
            Some((first, dir)) if *first != c => anyhow::bail!(
                "{} is {c} but {} is {first}: a resolution study is one case at several scales",
                d.display(),
                dir.display()
            ),
            Some(_) => {}
            None => case = Some((c, d.clone())),
        }
        points.push(p);
    }
    let (case, _) = case.expect("dirs is not empty");
    let text = table(&case, &order_points(points)?)?;
    if let Some(out) = out {
        atomic_write_bytes(out, text.as_bytes())
            .with_context(|| format!("cannot write {}", out.display()))?;
    }
    Ok(text)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn point(scale: f64, steady: bool, values: [f64; 4]) -> Point {
        Point {
            dir: PathBuf::from(format!("s{scale}")),
            scale,
            revolutions: 200.0,
            steady,
            drift: None,
            power_covered: None,
            values: values.map(Some),
            start: Some(RunStart::DryBed),
        }
    }

    #[test]
    fn the_order_comes_from_the_three_finest_steady_scales() {
        // f(h) = 0.30 + 0.02 h^1.5 at h = 4, 3, 2 (s = 1/4, 1/3, 1/2), and a transient at s = 1.
        let f = |s: f64| 0.30 + 0.02 * (1.0f64 / s).powf(1.5);
        let pts = vec![
            point(0.25, true, [f(0.25); 4]),
            point(1.0 / 3.0, true, [f(1.0 / 3.0); 4]),
            point(0.5, true, [f(0.5); 4]),
            point(1.0, false, [0.9; 4]),
        ];
        let pts = order_points(pts).unwrap();
        match convergence(&pts, 0) {
            Convergence::Order { order, limit } => {
                assert!((order - 1.5).abs() < 1e-6 && (limit - 0.30).abs() < 1e-6, "{order} {limit}")
            }
            other => panic!("{other:?}"),
        }
        // Two steady scales: no order.
        assert_eq!(convergence(&pts[..2], 0), Convergence::TooFew(2));
        // Not monotone: no order claimed.
        let zig =
            vec![point(0.25, true, [0.33; 4]), point(0.4, true, [0.31; 4]), point(0.5, true, [0.32; 4])];
        assert_eq!(convergence(&zig, 0), Convergence::NotMonotone);
    }

    #[test]
    fn the_table_marks_transients_and_says_what_it_cannot_claim() {
        // s = 1/3 with the drift of the run that passed the old test (|drift| ≤ 0.015) at 100
        // revolutions still rising (0.0119), as its report records: steady, counted, but
        // marked; so is s = 1/4, whose 0.0068 passed an older test only on its noise allowance.
        let third = Point { drift: Some(0.0119), ..point(1.0 / 3.0, true, [0.246, 1.856, 0.444, 2.3]) };
        let pts = order_points(vec![
            point(0.5, false, [0.31, 2.0, 1.0, 3.0]),
            third,
            Point { drift: Some(0.0068), ..point(0.25, true, [0.332, 1.944, 1.2, 3.145]) },
        ])
        .unwrap();
        let t = table("pbt-ld2", &pts).unwrap();
        assert!(
            t.contains("| 0.25 | 3 | 200 | dry bed | yes | +0.0068 † | not recorded | 0.332 | 1.944 | 1.200 | 3.145 |"),
            "{t}"
        );
        assert!(t.contains("| 0.3333 | 4 | 200 | dry bed | yes | +0.0119 † | not recorded | 0.246 |"), "{t}");
        assert!(
            t.contains(
                "| 0.5 | 6 | 200 | dry bed | no | – | not recorded | *0.310* | *2.000* | *1.000* | *3.000* |"
            ),
            "{t}"
        );
        assert!(
            t.contains("| paper | 12 | | bed settled in the liquid | | | | 0.31 | 2.37 | 0.537 | 2.91 |"),
            "{t}"
        );
        assert!(
            t.contains("| ⟨z_p⟩/H | -0.086 (s 0.25 → 0.3333) | – (2 steady scales; needs 3) | – | 0.31 |"),
            "{t}"
        );
    }

    #[test]
    fn a_point_started_from_another_run_is_labelled_and_the_table_says_what_that_means() {
        let dir = std::env::temp_dir().join(format!("slurry-resolution-start-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let from = RunStart::StartFrom(crate::start::StartFrom {
            dir: PathBuf::from("reproduce/pbt-ld2/runs/2026-11-29-s0.25-main/start"),
            scale: 0.25,
            step: 140_750,
            revolution: 140.75,
            mean_height_over_h: 0.3224,
            factor: [2.0; 3],
            phase_error_deg: 0.0,
            tip_shift: 0.0,
        });
        let json = serde_json::json!({"case": "pbt-ld2", "scale": 0.5, "steady": true, "start": from});
        assert_eq!(json["start"]["kind"], "start-from", "{json}");
        std::fs::write(dir.join("statistics.json"), json.to_string()).unwrap();
        let (_, top) = read_point(&dir).unwrap();
        assert_eq!(top.start, Some(from));
        std::fs::write(
            dir.join("statistics.json"),
            r#"{"case": "pbt-ld2", "scale": 0.5, "steady": true, "start": {"kind": "dry-bed"}}"#,
        )
        .unwrap();
        assert_eq!(read_point(&dir).unwrap().1.start, Some(RunStart::DryBed));
        std::fs::write(dir.join("statistics.json"), r#"{"case": "pbt-ld2", "scale": 0.5, "steady": true}"#)
            .unwrap();
        assert_eq!(read_point(&dir).unwrap().1.start, None, "reports before the record");
        std::fs::remove_dir_all(&dir).unwrap();

        let mut pts = vec![point(0.25, true, [0.332; 4]), point(1.0 / 3.0, true, [0.288; 4])];
        let t = table("pbt-ld2", &pts).unwrap();
        assert!(!t.contains("Not every steady point"), "{t}");
        pts.push(Point { start: top.start, ..point(0.5, true, [0.3; 4]) });
        pts[0].start = None;
        let t = table("pbt-ld2", &pts).unwrap();
        assert!(t.contains("| 0.5 | 6 | 200 | from s = 0.25 at ⟨z_p⟩/H 0.322 | yes |"), "{t}");
        assert!(t.contains("| 0.25 | 3 | 200 | not recorded | yes |"), "{t}");
        assert!(t.contains("**Not every steady point started from a bed**: s = 0.5 started"), "{t}");
        // A transient started from another run is no point: no note for it.
        pts[2].steady = false;
        assert!(!table("pbt-ld2", &pts).unwrap().contains("Not every steady point"));
    }

    /// A start from another run's state at s = 1/4 whose ⟨z_p⟩/H was `h`.
    fn from_quarter(h: f64) -> RunStart {
        RunStart::StartFrom(crate::start::StartFrom {
            dir: PathBuf::from(format!("start-{h}")),
            scale: 0.25,
            step: 140_750,
            revolution: 140.75,
            mean_height_over_h: h,
            factor: [2.0; 3],
            phase_error_deg: 0.0,
            tip_shift: 0.0,
        })
    }

    #[test]
    fn runs_of_one_scale_from_different_starts_give_its_level_and_their_spread() {
        // pbt-ld2: s = 1/4 and 1/3 from their beds, s = 1/2 from above (0.281) and from below.
        let study = |below: f64| {
            order_points(vec![
                Point { start: Some(from_quarter(0.322)), ..point(0.5, true, [0.281, 1.823, 0.665, 2.489]) },
                point(0.25, true, [0.332, 1.944, 1.2, 3.145]),
                Point { start: Some(from_quarter(0.272)), ..point(0.5, true, [below, 1.825, 0.671, 2.497]) },
                point(1.0 / 3.0, true, [0.288, 1.896, 0.799, 2.695]),
            ])
            .unwrap()
        };
        let pts = study(0.277);
        let l = levels(&pts, 0);
        assert_eq!(l.len(), 3);
        assert_eq!((l[2].scale, l[2].runs), (0.5, 2));
        assert!((l[2].value - 0.279).abs() < 1e-12 && (l[2].spread - 0.004).abs() < 1e-12, "{l:?}");
        // Spread 0.004 against changes of 0.044 and 0.009: within half the smaller, an order.
        assert!(matches!(convergence(&pts, 0), Convergence::Order { .. }), "{:?}", convergence(&pts, 0));
        let t = table("pbt-ld2", &pts).unwrap();
        assert!(t.contains("## Several starts at one scale"), "{t}");
        assert!(
            t.contains(
                "| 0.5 | ⟨z_p⟩/H | 0.281 (from s = 0.25 at ⟨z_p⟩/H 0.322), 0.277 (from s = 0.25 at ⟨z_p⟩/H 0.272) \
                 | 0.279 | 0.004 |"
            ),
            "{t}"
        );
        assert!(t.contains("| ⟨z_p⟩/H | -0.044 (s 0.25 → 0.3333), -0.009 (s 0.3333 → 0.5) |"), "{t}");
        assert!(t.contains("**Not every steady point started from a bed**: s = 0.5 started"), "{t}");
        // From below at 0.271: a spread of 0.010 against a smallest change of 0.012, beyond half.
        let pts = study(0.271);
        match convergence(&pts, 0) {
            Convergence::StartDependent { spread, change } => {
                assert!((spread - 0.010).abs() < 1e-12 && (change - 0.012).abs() < 1e-12, "{spread} {change}")
            }
            other => panic!("{other:?}"),
        }
        let t = table("pbt-ld2", &pts).unwrap();
        assert!(
            t.contains("– (a start spread of 0.010 against a smallest change of 0.012: no order claimed)"),
            "{t}"
        );
        // A start that is not steady is listed but gives no spread.
        let mut pts = study(0.271);
        pts[3].steady = false;
        assert_eq!(levels(&pts, 0)[2].runs, 1);
        assert!(!table("pbt-ld2", &pts).unwrap().contains("## Several starts"));
    }

    #[test]
    fn bad_studies_are_refused_with_the_runs_named() {
        let e = order_points(vec![point(0.5, true, [0.3; 4]), point(0.5, true, [0.3; 4])]).unwrap_err();
        assert!(e.to_string().contains("s0.5 and s0.5 are both at scale 0.5 from the same start"), "{e}");
        let unrecorded = Point { start: None, ..point(0.5, true, [0.3; 4]) };
        let e = order_points(vec![
            Point { start: Some(from_quarter(0.3)), ..point(0.5, true, [0.3; 4]) },
            unrecorded,
        ])
        .unwrap_err();
        assert!(e.to_string().contains("one does not record its start"), "{e}");
        let e = order_points(vec![point(0.3333, true, [0.3; 4]), point(0.333, true, [0.3; 4])]).unwrap_err();
        assert!(e.to_string().contains("s0.333 (scale 0.333) and s0.3333 (scale 0.3333)"), "{e}");
        let dir = std::env::temp_dir().join(format!("slurry-resolution-{}", std::process::id()));
        let (a, b) = (dir.join("a"), dir.join("b"));
        std::fs::create_dir_all(&a).unwrap();
        std::fs::create_dir_all(&b).unwrap();
        std::fs::write(a.join("statistics.json"), r#"{"case": "pbt-ld2", "scale": 0.25, "steady": true}"#)
            .unwrap();
        std::fs::write(b.join("statistics.json"), r#"{"case": "disk-ld2", "scale": 0.5, "steady": true}"#)
            .unwrap();
        let e = write_resolution(&[a.clone(), b.clone()], None).unwrap_err();
        let e = e.to_string();
        assert!(e.contains(&format!("{} is disk-ld2 but {} is pbt-ld2", b.display(), a.display())), "{e}");
        assert!(e.contains("one case"), "{e}");
        let e = write_resolution(&[dir.join("missing")], None).unwrap_err();
        assert!(format!("{e:#}").contains("statistics.json"), "{e:#}");
        std::fs::remove_dir_all(&dir).unwrap();
    }

    #[test]
    fn a_power_window_with_a_lost_stretch_does_not_count() {
        let f = |s: f64| 0.30 + 0.02 * (1.0f64 / s).powf(1.5);
        let mut pts: Vec<Point> =
            [0.25, 1.0 / 3.0, 0.5].iter().map(|&s| point(s, true, [f(s), f(s), f(s), f(s)])).collect();
        pts[2].power_covered = Some(false);
        assert!(matches!(convergence(&pts, 0), Convergence::Order { .. }), "⟨z_p⟩/H still counts");
        for q in 1..4 {
            assert_eq!(convergence(&pts, q), Convergence::TooFew(2), "quantity {q}");
        }
        let t = table("pbt-ld2", &pts).unwrap();
        assert!(
            t.contains("| 0.5 | 6 | 200 | dry bed | yes | – | no | 0.357 | *0.357* | *0.357* | *0.357* |"),
            "{t}"
        );
        // Out of order, the fit claims nothing (and does not panic).
        pts[2].power_covered = None;
        pts.swap(0, 2);
        assert_eq!(convergence(&pts, 0), Convergence::NotMonotone);
    }

    #[test]
    fn a_report_that_is_not_one_is_refused_naming_the_file_key_and_value() {
        let dir = std::env::temp_dir().join(format!("slurry-resolution-keys-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let file = dir.join("statistics.json");
        for (json, needles) in [
            (
                r#"{"case": "pbt-ld2", "scale": 0.1, "steady": true}"#,
                &["\"scale\" 0.1: allowed 0.25 ≤ s ≤ 1"][..],
            ),
            (r#"{"case": "pbt-ld2", "scale": 0.5}"#, &["no true/false \"steady\""][..]),
            (
                r#"{"case": "pbt-ld3", "scale": 0.5, "steady": true}"#,
                &["\"case\"", "unknown case 'pbt-ld3'"][..],
            ),
            (r#"{"scale": 0.5, "steady": true}"#, &["no \"case\""][..]),
            (
                r#"{"case": "pbt-ld2", "scale": 0.5, "steady": true, "start": {"kind": "sideways"}}"#,
                &[
                    "\"start\"",
                    "unknown variant `sideways`, expected one of `dry-bed`, `wet-bed`, `start-from`",
                ][..],
            ),
            (
                r#"{"case": "pbt-ld2", "scale": 0.5, "steady": true, "start": {"kind": "start-from"}}"#,
                &["\"start\"", "missing field `dir`"][..],
            ),
        ] {
            std::fs::write(&file, json).unwrap();
            let e = format!("{:#}", read_point(&dir).unwrap_err());
            assert!(e.contains(&file.display().to_string()), "{e}");
            for n in needles {
                assert!(e.contains(n), "`{n}` not in: {e}");
            }
        }
        std::fs::remove_dir_all(&dir).unwrap();
    }
}
