//! `slurry status OUT`: where a reproduction stands, read from its files alone, while it runs
//! (a campaign of several sessions) or after it (an archive).
//!
//! From `OUT/manifest.json` (case, scale, target, sessions) and the time series
//! (`OUT/run/timeseries.csv` of a run directory, or `OUT/timeseries.csv` of an archive; a last
//! row still being written is left out), it prints:
//!
//! - the progress: the last step written against the target, in revolutions after the ramp,
//!   and, while the manifest says "running", how long ago the last row was written (a run
//!   killed without a word stays "running" in its manifest: an old last row tells);
//! - the speed, the median of the last [`SPEED_ROWS`] rows' MLUPS as ms per step, and the time
//!   left to the target at that speed (a run continued by `--until-steady` may go on past it,
//!   in legs of 10 revolutions);
//! - `⟨z_p⟩/H` over 10-revolution windows after the ramp (`t N` from the impeller's start, the
//!   axis of the report);
//! - the report's steady test ([`stats::steady_state`] over [`report::STEADY_REVOLUTIONS`],
//!   tolerance [`report::STEADY_DRIFT`]) applied to the time series' `⟨z_p⟩/H` as it stands;
//!   the report applies it to the particle frames, which are written at the same steps, so
//!   this is the verdict the report would give now, not a substitute for it;
//! - `Po_f`, `Po_c` and `Po` over the last [`report::POWER_REVOLUTIONS`] revolutions after the
//!   ramp.
//!
//! It only reads: a running reproduction is not disturbed.

use std::fmt::Write as _;
use std::path::{Path, PathBuf};
use std::time::SystemTime;

use anyhow::Context;

use super::manifest::{utc, Manifest};
use super::report::{self, TimeSeries};
use super::{paper_case, scale_case, schedule};
use crate::stats;

/// Rows of the time series whose MLUPS the speed is the median of.
pub const SPEED_ROWS: usize = 20;

/// Length of the windows of `⟨z_p⟩/H`, revolutions.
pub const WINDOW_REVOLUTIONS: f64 = 10.0;

/// The status of the reproduction in `out` (module docs), as text.
///
/// # Errors
/// No readable `manifest.json` in `out`, an unknown case or scale in it, or no readable time
/// series.
pub fn status(out: &Path) -> anyhow::Result<String> {
    let manifest = Manifest::read(out).ok_or_else(|| {
        anyhow::anyhow!(
            "{}: no readable manifest.json: not the output directory of `slurry reproduce`, nor its archive",
            out.display()
        )
    })?;
    let case = scale_case(&paper_case(&manifest.case)?.case()?, manifest.scale).with_context(|| {
        format!("{}: case {} at scale {}", out.join("manifest.json").display(), manifest.case, manifest.scale)
    })?;
    let sched = schedule(&case, manifest.revolutions)?;
    let grid = case.grid();
    let nodes = (grid.nx * grid.ny * grid.nz) as f64;
    let path = timeseries_path(out);
    let text = std::fs::read_to_string(&path).with_context(|| format!("cannot read {}", path.display()))?;
    let ts =
        report::parse_timeseries(complete_rows(&text), &path, grid.nz as f64, sched.steps_per_revolution)?;
    let age = std::fs::metadata(&path)
        .and_then(|m| m.modified())
        .ok()
        .and_then(|t| SystemTime::now().duration_since(t).ok())
        .map(|d| d.as_secs_f64());
    Ok(describe(
        &manifest,
        &ts,
        sched.steps_per_revolution,
        sched.ramp_steps as f64,
        nodes,
        (grid.nx, grid.ny, grid.nz),
        age,
    ))
}

/// `OUT/run/timeseries.csv` (a run directory) if it exists, else `OUT/timeseries.csv` (an
/// archive).
fn timeseries_path(out: &Path) -> PathBuf {
    let run = out.join("run").join(crate::run::files::TIMESERIES);
    if run.exists() {
        run
    } else {
        out.join(crate::run::files::TIMESERIES)
    }
}

/// The text up to its last complete line: a row still being appended is left out.
fn complete_rows(text: &str) -> &str {
    match text.rfind('\n') {
        Some(i) => &text[..=i],
        None => "",
    }
}

/// Seconds as `1.2 h`, `14 min` or `35 s`.
fn duration(s: f64) -> String {
    if s >= 5400.0 {
        format!("{:.1} h", s / 3600.0)
    } else if s >= 90.0 {
        format!("{:.0} min", s / 60.0)
    } else {
        format!("{s:.0} s")
    }
}

/// The status text from what was read (module docs); `age`: seconds since the time series was
/// last written.
fn describe(
    m: &Manifest,
    ts: &TimeSeries,
    steps_per_rev: f64,
    ramp_steps: f64,
    nodes: f64,
    (nx, ny, nz): (usize, usize, usize),
    age: Option<f64>,
) -> String {
    let mut s = String::new();
    let _ = writeln!(
        s,
        "{} at scale {} ({nx} × {ny} × {nz} nodes, {steps_per_rev:.0} steps per revolution): {}",
        m.case, m.scale, m.status
    );
    let (first, last) = (m.sessions.first(), m.sessions.last());
    if let (Some(first), Some(last)) = (first, last) {
        let _ = writeln!(
            s,
            "sessions: {} (restarts {}), the first started {}, the last {} ({}), binary {}",
            m.sessions.len(),
            m.restarts,
            first.started,
            last.started,
            last.ended
                .as_deref()
                .map_or("no end recorded: running, or stopped without a word".into(), |e| format!(
                    "ended {e}"
                )),
            last.git_revision
        );
    }
    let ramp_end = ramp_steps / steps_per_rev;
    let Some(&t_last) = ts.time.last() else {
        let _ = writeln!(s, "the time series has no rows yet");
        return s;
    };
    let step = ts.steps.last().copied().unwrap_or(0.0);
    let until = m
        .until_steady
        .map_or(String::new(), |c| format!("; `--until-steady` continues in legs of 10 up to {c}"));
    let _ = writeln!(
        s,
        "progress: step {step:.0} of {} ({:.1} of {} revolutions after the ramp{until}){}",
        m.steps,
        (t_last - ramp_end).max(0.0),
        m.revolutions,
        // Only a running run's file age says something (an archive's is its copy's).
        age.filter(|_| m.status == "running")
            .map_or(String::new(), |a| format!("; last row written {} ago", duration(a)))
    );
    let recent: Vec<f64> =
        ts.mlups.iter().rev().take(SPEED_ROWS).copied().filter(|v| v.is_finite() && *v > 0.0).collect();
    if !recent.is_empty() {
        let mut sorted = recent.clone();
        sorted.sort_by(f64::total_cmp);
        let mlups = sorted[sorted.len() / 2];
        let ms = nodes / (mlups * 1e6) * 1e3;
        let left = (m.steps as f64 - step).max(0.0) * ms * 1e-3;
        let now = SystemTime::now().duration_since(SystemTime::UNIX_EPOCH).map_or(0, |d| d.as_secs());
        let eta = if left > 0.0 {
            format!(
                "; at that speed the target is {} of stepping away (about {})",
                duration(left),
                utc(now + left as u64)
            )
        } else {
            String::new()
        };
        let _ = writeln!(
            s,
            "speed: {ms:.1} ms per step ({mlups:.1} MLUPS, median of the last {} rows){eta}",
            recent.len()
        );
    }
    // ⟨z_p⟩/H by windows after the ramp.
    let mut windows = Vec::new();
    let mut lo = ramp_end;
    while lo < t_last {
        let hi = lo + WINDOW_REVOLUTIONS;
        let v: Vec<f64> = ts
            .time
            .iter()
            .zip(&ts.mean_height)
            .filter(|(t, _)| **t >= lo && **t < hi)
            .map(|(_, z)| *z)
            .collect();
        if !v.is_empty() {
            let partial = if t_last < hi { "*" } else { "" };
            windows.push(format!("{lo:.0}–{hi:.0}{partial} {:.3}", v.iter().sum::<f64>() / v.len() as f64));
        }
        lo = hi;
    }
    if !windows.is_empty() {
        let _ = writeln!(
            s,
            "⟨z_p⟩/H by 10 revolutions (t N; * the window is not complete): {}",
            windows.join(", ")
        );
    }
    let series: Vec<(f64, f64)> = ts.time.iter().copied().zip(ts.mean_height.iter().copied()).collect();
    let st = stats::steady_state(&series, report::STEADY_REVOLUTIONS, report::STEADY_DRIFT);
    let _ = writeln!(s, "steady test on the time series now: {}", st.reason);
    let from = (t_last - report::POWER_REVOLUTIONS).max(ramp_end);
    let po: Vec<(f64, f64)> = ts
        .time
        .iter()
        .zip(ts.po_fluid.iter().zip(&ts.po_solids))
        .filter(|(t, _)| **t >= from)
        .map(|(_, (f, c))| (*f, *c))
        .collect();
    if !po.is_empty() && t_last > ramp_end {
        let n = po.len() as f64;
        let (f, c) = (po.iter().map(|p| p.0).sum::<f64>() / n, po.iter().map(|p| p.1).sum::<f64>() / n);
        let _ = writeln!(
            s,
            "power numbers over t N {from:.1}–{t_last:.1} ({} rows): Po_f {f:.3}, Po_c {c:.3}, Po {:.3}",
            po.len(),
            f + c
        );
    }
    s
}

#[cfg(test)]
mod tests {
    use super::{complete_rows, status};
    use std::path::Path;

    #[test]
    fn a_row_being_written_is_left_out() {
        assert_eq!(complete_rows("a,b\n1,2\n3,"), "a,b\n1,2\n");
        assert_eq!(complete_rows("a,b\n1,2\n"), "a,b\n1,2\n");
        assert_eq!(complete_rows("a,b"), "");
    }

    /// The archived steady pbt-ld2 run at s = 1/4: the numbers of its report, recomputed from
    /// its time series.
    #[test]
    fn status_of_the_archived_pbt_ld2_run() {
        let dir =
            Path::new(env!("CARGO_MANIFEST_DIR")).join("reproduce/pbt-ld2/runs/2026-11-25-s0.25-exact-r200");
        let text = status(&dir).unwrap();
        assert!(
            text.starts_with(
                "pbt-ld2 at scale 0.25 (63 × 63 × 60 nodes, 1000 steps per revolution): finished"
            ),
            "{text}"
        );
        assert!(text.contains("of 200 revolutions after the ramp"), "{text}");
        assert!(text.contains("steady test on the time series now: steady"), "{text}");
        assert!(
            text.contains("⟨z_p⟩/H by 10 revolutions (t N; * the window is not complete): 1–11 "),
            "{text}"
        );
        // The report's power averages over t N 171–201: Po_f 1.944, Po_c 1.200 (Table 2's
        // comparison in reproduce/README.md), from the same rows.
        assert!(text.contains("Po_f 1.944, Po_c 1.200"), "{text}");
    }

    #[test]
    fn a_directory_without_a_manifest_is_named() {
        let dir = tempfile::tempdir().unwrap();
        let e = status(dir.path()).unwrap_err().to_string();
        assert!(e.contains("no readable manifest.json"), "{e}");
    }
}
