//! CI's regression at steady state: the paper's PBT cases at scale 1/4 (63 × 63 × 60 nodes,
//! d = 3) continued for [`REVOLUTIONS`] revolutions from the committed state packs of their
//! steady states (`reproduce/CASE/runs/ARCHIVE/state.h5`, `slurry state-pack`), through the
//! whole pipeline (`slurry reproduce CASE --start-from PACK`), then checked against the
//! archived steady levels.
//!
//! **What is asserted, and why these bands.** For each case, ⟨z_p⟩/H, Po_f, Po_c and Po
//! averaged over the run's window (the rows of its time series after the pack's step, its
//! [`REVOLUTIONS`] revolutions) must lie
//! in `μ ± K σ` ([`K`]), where, from the archived steady run of the same case and scale (its
//! `timeseries.csv`, the column `particle_mean_z` as `(z + ½)/n_z` and the power numbers), the
//! series from [`STEADY_FROM`] revolutions after the ramp to its end is cut into consecutive
//! windows of [`REVOLUTIONS`] revolutions, `μ` is the mean of the windows' means and `σ` their
//! standard deviation: the measured fluctuation of exactly the statistic asserted. With
//! independent, normal window means `|x − μ| > 3σ` has probability 0.3 %; adjacent windows are
//! correlated (the bed exchanges particles over several revolutions), so σ understates the
//! spread of a window from another start somewhat, and a failure here is a change worth
//! looking at, not proof of one. The bands come from the archives at test time (printed), not
//! from numbers copied into this file.
//!
//! Then the paper's ordering over ℓ/d where the archives support it: ⟨z_p⟩/H of ℓ/d = 4 above
//! that of ℓ/d = 2 and of ℓ/d = 1 (archived 10-revolution windows: 0.365 ± 0.006 against
//! 0.321 ± 0.011 and 0.321 ± 0.014; the paper's text: 0.37 against 0.31 and 0.26). The archives
//! do not support the paper's ℓ/d = 2 above ℓ/d = 1 at this scale (pbt-ld1's steady level,
//! 0.338 over its last 20 revolutions, is above pbt-ld2's 0.330), so that is printed, not
//! asserted. Each value is printed beside Table 2 and the text, with
//! its deviation, never asserted against them (the resolution study, `reproduce/README.md`,
//! says how far s = 1/4 is from the paper). The window's statistics (⟨z_p⟩/H series, φ(z),
//! k*, the orientation pdfs, the power numbers) are snapshot-tested with insta: the run is
//! bitwise the same for any thread count.
//!
//! **Known deviation: pbt-ld1's Po_f.** Over the 10 revolutions from its pack, Po_f is 1.8645,
//! 4.4σ below its band (1.9022 ± 0.0258). The same 10 revolutions continued exactly from the
//! checkpoint the pack was written from (`--resume`, bitwise) give 1.9005, inside it, with
//! ⟨z_p⟩/H 0.3403 in both. The two runs' Po_f agree to 0.004 over the first 500 steps after
//! the restart, then differ by ±0.05–0.1 in 500-step means of either sign: the pack's restart
//! starts another realisation of the chaotic flow, and this one's window is low. σ from 15
//! windows of one run understates the spread between realisations (pbt-ld2's pair, exact
//! against pack, differed by 1.0σ; pbt-ld1's by 4.2σ). The value is asserted at its measured
//! 1.8645 instead, so that a change still fails; the other three quantities keep their bands.
//!
//! **pbt-ld1's band is wide.** Its pack is the end of a run from the dry bed continued in five
//! legs to its steady test (250 revolutions, `reproduce/pbt-ld1/runs/2026-12-08-s0.25-steady`),
//! whose joined series gives the band. That series still rises over revolutions 100–250
//! (10-revolution means from 0.29 to 0.339), so σ of its window means (0.014 in ⟨z_p⟩/H) holds
//! that drift as well as the fluctuation; the last five windows alone give 0.336 ± 0.009 (3σ).
//!
//! Each continuation is about 10 000 steps of the coupled step (25–45 ms each on 2 cores).

use std::path::Path;

use slurry_reproduce::start::RunStart;
use slurry_reproduce::{paper_case, reproduce, scale_case, schedule};

#[path = "../../tests/common/mod.rs"]
mod common;
mod packs;

/// Revolutions run from each pack (the N ≥ 10).
const REVOLUTIONS: f64 = 10.0;
/// The band's half-width in standard deviations of the archived window means.
const K: f64 = 3.0;
/// Revolutions after the ramp from which an archived series counts as steady: the paper's
/// "at least 100 impeller revolutions" (its Results section).
const STEADY_FROM: f64 = 100.0;
/// The scale.
const SCALE: f64 = 0.25;
/// The runs' Mach limit (`--mach-limit`), as the campaigns' (`reproduce/README.md`).
const MACH_LIMIT: f64 = 0.4;

/// A case of the regression: its state pack's archive and the archive whose series gives the
/// bands.
struct SteadyCase {
    name: &'static str,
    /// The archive holding `state.h5`.
    pack: &'static str,
    /// The archived steady run (200 revolutions or more from the bed) whose windows give the
    /// bands.
    bands: &'static str,
    /// A value known to lie outside its band (module docs, "Known deviation"): the quantity's
    /// key in [`QUANTITIES`] and its measured value, which is asserted instead (to 1e-5, the
    /// rounding of its five decimals; the run is bitwise deterministic), so that any change to
    /// it still fails.
    known: Option<(&'static str, f64)>,
}

const CASES: [SteadyCase; 3] = [
    SteadyCase {
        name: "pbt-ld1",
        pack: "2026-12-08-s0.25-steady",
        bands: "2026-12-08-s0.25-steady",
        known: Some(("po_fluid", 1.86448)),
    },
    SteadyCase {
        name: "pbt-ld2",
        pack: "2026-12-07-s0.25-steady",
        bands: "2026-11-25-s0.25-exact-r200",
        known: None,
    },
    SteadyCase {
        name: "pbt-ld4",
        pack: "2026-12-07-s0.25-steady",
        bands: "2026-11-26-s0.25-r200",
        known: None,
    },
];

/// The asserted quantities, in the order of [`Band`]s: ⟨z_p⟩/H and the three power numbers,
/// with their keys in the report's comparison with the paper.
const QUANTITIES: [(&str, &str); 4] =
    [("<z_p>/H", "mean_height"), ("Po_f", "po_fluid"), ("Po_c", "po_solids"), ("Po", "po")];

/// A band: the archived window means' mean and standard deviation, and how many windows.
#[derive(Clone, Copy, Debug)]
struct Band {
    mean: f64,
    sd: f64,
    windows: usize,
}

impl Band {
    fn contains(&self, x: f64) -> bool {
        (x - self.mean).abs() <= K * self.sd
    }
}

/// The bands of [`QUANTITIES`] from the archived series `csv` (module docs): `nz` the grid's
/// height, `spr` steps per revolution, `ramp` the steps of the ramp (rounded to outputs).
fn bands(csv: &Path, nz: f64, spr: f64, ramp: f64) -> [Band; 4] {
    let rows = series(csv, nz, spr, ramp);
    let end = rows.last().expect("rows").0;
    let mut means: Vec<[f64; 4]> = Vec::new();
    let mut from = STEADY_FROM;
    while from + REVOLUTIONS <= end + 1e-9 {
        means.push(window_means(&rows, from, from + REVOLUTIONS));
        from += REVOLUTIONS;
    }
    assert!(
        means.len() >= 5,
        "{}: only {} steady windows of {REVOLUTIONS} revolutions",
        csv.display(),
        means.len()
    );
    [0, 1, 2, 3].map(|k| {
        let n = means.len() as f64;
        let mean = means.iter().map(|m| m[k]).sum::<f64>() / n;
        let var = means.iter().map(|m| (m[k] - mean).powi(2)).sum::<f64>() / (n - 1.0);
        Band { mean, sd: var.sqrt(), windows: means.len() }
    })
}

/// The means of [`QUANTITIES`] over the rows of `rows` after `from` and up to `to`
/// (revolutions after the ramp).
fn window_means(rows: &[(f64, [f64; 4])], from: f64, to: f64) -> [f64; 4] {
    let w: Vec<&[f64; 4]> = rows.iter().filter(|(r, _)| *r > from && *r <= to).map(|(_, q)| q).collect();
    assert!(!w.is_empty(), "no rows between {from} and {to} revolutions");
    [0, 1, 2, 3].map(|k| w.iter().map(|q| q[k]).sum::<f64>() / w.len() as f64)
}

/// The rows of the time series `csv` as (revolutions after the ramp, [`QUANTITIES`]): `nz` the
/// grid's height, `spr` steps per revolution, `ramp` the steps of the ramp (rounded to outputs).
fn series(csv: &Path, nz: f64, spr: f64, ramp: f64) -> Vec<(f64, [f64; 4])> {
    let text = std::fs::read_to_string(csv).unwrap_or_else(|e| panic!("{}: {e}", csv.display()));
    let mut lines = text.lines();
    let header: Vec<&str> = lines.next().expect("a header").split(',').collect();
    let col =
        |name: &str| header.iter().position(|h| *h == name).unwrap_or_else(|| panic!("no column {name}"));
    let (step, z, pof, poc, po) =
        (col("step"), col("particle_mean_z"), col("po_fluid"), col("po_solids"), col("po"));
    lines
        .map(|l| {
            let v: Vec<f64> = l.split(',').map(|x| x.parse().expect("a number")).collect();
            ((v[step] - ramp) / spr, [(v[z] + 0.5) / nz, v[pof], v[poc], v[po]])
        })
        .collect()
}

/// Runs `c` from its pack for [`REVOLUTIONS`] revolutions into `out`; returns the results and
/// the pack's step.
fn continue_from_pack(c: &SteadyCase, out: &Path) -> (slurry_reproduce::report::Results, u64) {
    // A health check only (no number depends on it): the campaigns' limit. pbt-ld4's steady
    // flow peaks at a Mach number of 0.301 near the blades within these 10 revolutions.
    let packs::Continuation { pack, step, options: opts } =
        packs::continuation(c.name, c.pack, SCALE, REVOLUTIONS, out, MACH_LIMIT, false);
    let scaled = scale_case(&paper_case(c.name).unwrap().case().unwrap(), SCALE).unwrap();
    let sched = schedule(&scaled, 1.0).unwrap();
    let s = reproduce(c.name, &opts).unwrap_or_else(|e| panic!("{} from {}: {e:#}", c.name, pack.display()));
    let r = s.results;
    match &r.start {
        RunStart::StatePack(from) => assert_eq!((from.step, &from.pack), (step, &pack)),
        other => panic!("{}: started from {other:?}, not the pack", c.name),
    }
    let run = (s.record.run.steps - step) as f64 / sched.steps_per_revolution;
    assert!((run - REVOLUTIONS).abs() < 1e-9, "{}: ran {run} revolutions", c.name);
    (r, step)
}

#[test]
fn steady_states_continued_from_their_packs() {
    let dir = tempfile::tempdir().unwrap();
    let mut heights = Vec::new();
    let mut failures = Vec::new();
    let mut md = String::from(
        "# The steady states at s = 1/4 continued from their packs (reproduce/tests/steady_regression.rs)\n\n\
         Each value over the run's window, its band (archived windows of the same length, mean ± 3σ), and the \
         paper (Table 2; the text's ⟨z_p⟩/H) with the deviation, which is printed, not asserted.\n\n\
         | case | quantity | value | band | paper | deviation |\n|---|---|---|---|---|---|\n",
    );
    for c in &CASES {
        let (r, step) = continue_from_pack(c, &dir.path().join(c.name));
        let scaled = scale_case(&paper_case(c.name).unwrap().case().unwrap(), SCALE).unwrap();
        let sched = schedule(&scaled, 1.0).unwrap();
        let ramp = sched.ramp_steps.div_ceil(sched.output_every) * sched.output_every;
        let csv =
            common::root().join("reproduce").join(c.name).join("runs").join(c.bands).join("timeseries.csv");
        let (nz, spr) = (scaled.grid().nz as f64, sched.steps_per_revolution);
        let b = bands(&csv, nz, spr, ramp as f64);
        // The continuation's own window, the rows after the pack's step: the statistic of the
        // bands (a pack that carries its run's history gives a series that begins before it,
        // which the report's longer averages would reach into).
        let own = series(&dir.path().join(c.name).join("run/timeseries.csv"), nz, spr, ramp as f64);
        let from = (step - ramp) as f64 / spr;
        let values = window_means(&own, from, from + REVOLUTIONS);
        println!("{} at s = {SCALE}, {REVOLUTIONS} revolutions from the pack at step {step}:", c.name);
        for ((&(q, key), v), band) in QUANTITIES.iter().zip(values).zip(b) {
            let against =
                r.comparison.iter().find(|p| p.key == key).and_then(|p| p.paper.map(|x| (x, v - x)));
            println!(
                "  {q:8} {v:.4}  band {:.4} ± {:.4} ({K}σ of {} archived {REVOLUTIONS}-revolution windows){}",
                band.mean,
                K * band.sd,
                band.windows,
                against.map_or_else(String::new, |(x, d)| format!("; the paper {x:.3}, deviation {d:+.3}"))
            );
            let (paper, dev) = against.map_or(("—".into(), "—".into()), |(x, d)| {
                (format!("{x:.3}"), format!("{d:+.3} ({:+.1} %)", 100.0 * d / x))
            });
            let known = c.known.filter(|(k, _)| *k == key);
            md.push_str(&format!(
                "| {} | {q} | {v:.4}{} | {:.4} ± {:.4} ({} windows) | {paper} | {dev} |\n",
                c.name,
                if known.is_some() { " (known deviation: asserted at its measured value)" } else { "" },
                band.mean,
                K * band.sd,
                band.windows
            ));
            if let Some((_, measured)) = known {
                println!("  {q:8} a known deviation (module docs): asserted at its measured {measured:.5}");
                if (v - measured).abs() > 1e-5 {
                    failures.push(format!(
                        "{} {q} = {v:.5}, not the known deviation's measured {measured:.5}",
                        c.name
                    ));
                }
            } else if !band.contains(v) {
                failures.push(format!(
                    "{} {q} = {v:.4} outside {:.4} ± {:.4} (archive {})",
                    c.name,
                    band.mean,
                    K * band.sd,
                    c.bands
                ));
            }
        }
        insta::assert_snapshot!(format!("{}_steady_s0.25", c.name), r.snapshot_text());
        heights.push((c.name, values[0]));
    }
    let out = common::root().join("target/ci");
    std::fs::create_dir_all(&out).unwrap();
    std::fs::write(out.join("steady-regression.md"), &md).unwrap();
    assert!(failures.is_empty(), "outside the archived steady bands:\n{}", failures.join("\n"));
    // The paper's ordering over ℓ/d (its text: 0.37 for ℓ/d = 4 against 0.31 for ℓ/d = 2).
    let h = |n: &str| heights.iter().find(|(c, _)| *c == n).unwrap().1;
    for lower in ["pbt-ld2", "pbt-ld1"] {
        assert!(h("pbt-ld4") > h(lower), "<z_p>/H: ℓ/d = 4 {} not above {lower} {}", h("pbt-ld4"), h(lower));
    }
    println!(
        "<z_p>/H of ℓ/d = 2 {:.4} against ℓ/d = 1 {:.4} (the paper: 0.31 above 0.26; not asserted, module docs)",
        h("pbt-ld2"),
        h("pbt-ld1")
    );
}
