//! What `slurry reproduce` says before it starts: the case, the grid, the length of the run and
//! roughly how long its stepping takes on 2 cores.

use super::STEADY_CHECK_REVOLUTIONS;

/// Estimated cost of one coupled step of case `name` at scale `s` on 2 cores, milliseconds:
///
/// t(s) ≈ 27 ms · (4s)² · f_case
///
/// Measured on a 2-core VM (Intel Xeon): pbt-ld2 takes 26–27.5 ms per step at s = 1/4 (a run
/// to its steady verdict) and 92–101 ms at s = 1/2 (from the steady s = 1/4 state), the ratio
/// 3.7–3.9 of the particle work that grows with the markers (∝ s²) while the fluid's share
/// (∝ s³) stays near a tenth; at s = 1, 467 ms from the bed
/// (`benches/results/2026-11-27-coupled-3scales-l.json`; the law gives 432). `f_case` is the
/// case's cost relative to pbt-ld2, the mean of its ratios at s = 1/4 and 1/2 in that one
/// benchmark window (from the beds): the shorter the cylinders the more particles and
/// contacts. The shared VM was at times 1.5–2 times slower.
fn step_ms_estimate(name: &str, scale: f64) -> f64 {
    let f_case = match name {
        "disk-ld1" => 1.5,
        "disk-ld2" => 1.0,
        "disk-ld4" => 0.9,
        "pbt-ld1" => 1.6,
        "pbt-ld4" => 0.77,
        _ => 1.0,
    };
    27.0 * (4.0 * scale).powi(2) * f_case
}

/// What `slurry reproduce` is about to do for case `name` and about how long it takes on 2
/// cores, printed before it starts; `done` revolutions after the ramp are already done (a
/// resume, or a start from a state pack), so only the rest is estimated.
pub fn announce(
    name: &str,
    scale: f64,
    revolutions: f64,
    until_steady: Option<f64>,
    quick: bool,
    done: f64,
) -> String {
    let grid = [251.0, 251.0, 240.0].map(|n: f64| (n * scale).round());
    let ms = step_ms_estimate(name, scale);
    // The ramp (half a revolution of stepping time) only for a run from its start.
    let ramp = if done > 0.0 { 0.0 } else { 0.5 };
    let duration_for = |revs: f64| duration(((revs - done).max(0.0) + ramp) * 4000.0 * scale * ms / 60_000.0);
    let minutes = duration_for(revolutions);
    let what = if quick {
        "about a minute on 2 cores (a smoke test: 0.75 revolution in all, far from steady)".to_string()
    } else if let Some(cap) = until_steady {
        format!(
            "to steady state: roughly {minutes} of stepping on 2 cores (estimate, {ms:.0} ms per step), then on in legs of \
             {STEADY_CHECK_REVOLUTIONS} revolutions until the report's steady test passes, at most to {cap} \
             revolutions (about {} in all)",
            duration_for(cap)
        )
    } else {
        format!(
            "roughly {minutes} of stepping on 2 cores (estimate, {ms:.0} ms per step); a fixed length, not checked for steady \
             state (the paper needs 100-200 revolutions: leave out --revolutions, or add --until-steady CAP)"
        )
    };
    let coarse = if scale < 1.0 / 3.0 {
        "; below the paper's resolution: the coarsest point of the resolution study, not a reproduction"
    } else {
        ""
    };
    let from = if done > 0.0 { format!(" ({done:.1} done)") } else { String::new() };
    format!(
        "reproduce {name}: scale {scale:.3} ({} x {} x {} nodes, d = {:.2}{coarse}), {revolutions} revolutions after the \
         ramp{from}, {what}",
        grid[0],
        grid[1],
        grid[2],
        12.0 * scale
    )
}

/// `m` minutes as "45 minutes" or, from two hours on, "6.0 hours".
fn duration(m: f64) -> String {
    if m < 120.0 {
        format!("{m:.0} minutes")
    } else {
        format!("{:.1} hours", m / 60.0)
    }
}
