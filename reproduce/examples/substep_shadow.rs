//! The contact scheme's error where it is used: one suspension, continued from a checkpoint of
//! a reproduction under several contact schemes side by side, compared with the finest.
//!
//! ```text
//! cargo run --release -p slurry-reproduce --example substep_shadow -- CASE SCALE CHECKPOINT \
//!     [--cache DIR] [--at 10,20,50,100] [--threads N] [--json FILE] [SCHEME...]
//! ```
//!
//! A `SCHEME` is `label:substeps[:lubrication_substeps[:limiter]]`, e.g. `ex8:8`,
//! `lub24:2:4`, `lim2:2:1:limiter`; the default is `ex8:8 ex16:16 lub24:2:4 ex32:32`. The
//! last is the reference. Each scheme runs `max(--at)` fluid steps from the same checkpoint
//! (`slurry_reproduce::bench::shadow`: the bed cache must hold the case's bed, as for
//! `slurry bench --coupled --from`); the table gives, after each step count of `--at`, the
//! free particles' RMS position, velocity and angular-velocity differences to the reference,
//! their mean height difference `⟨Δz⟩`, and the mean difference of their mean vertical
//! velocity over the steps (a systematic lift), and, for explicit schemes whose sub-step
//! counts double, the observed order of the position difference (the reference's own error
//! allowed for).
//!
//! Why: the statistics of a stirred suspension (⟨z_p⟩/H) separate two schemes only after
//! tens of revolutions (reproduce/JOURNAL.md, "Lubrication sub-steps"), because the flow is
//! chaotic; over a few hundred steps the trajectories stay close, and their differences are
//! the schemes' own errors, accumulated where the suspension actually is.

use std::path::PathBuf;

use slurry_reproduce::bench::{shadow, shadow_differences, ContactOptions, ShadowScheme};

fn scheme(text: &str) -> ShadowScheme {
    let parts: Vec<&str> = text.split(':').collect();
    let num = |i: usize| -> Option<usize> {
        parts.get(i).map(|p| p.parse().unwrap_or_else(|_| panic!("scheme {text}: {p} is not a count")))
    };
    let limiter = match parts.get(3) {
        None => false,
        Some(&"limiter") => true,
        Some(other) => panic!("scheme {text}: the fourth part must be `limiter`, not {other}"),
    };
    ShadowScheme {
        label: parts[0].to_string(),
        contact: ContactOptions {
            skin: None,
            substeps: Some(num(1).unwrap_or_else(|| panic!("scheme {text}: no sub-step count"))),
            limiter,
            lubrication_substeps: num(2),
            implicit_damping: false,
        },
    }
}

fn main() -> anyhow::Result<()> {
    let mut args = std::env::args().skip(1);
    let usage = "usage: substep_shadow CASE SCALE CHECKPOINT [--cache DIR] [--at 10,20,50,100] [--threads N] [--json FILE] [SCHEME...]";
    let case = args.next().expect(usage);
    let scale: f64 = args.next().expect(usage).parse()?;
    let from = PathBuf::from(args.next().expect(usage));
    let (mut cache, mut at, mut threads, mut json) =
        (PathBuf::from("target/reproduce/cache"), vec![10u64, 20, 50, 100], 2usize, None);
    let mut schemes = Vec::new();
    while let Some(a) = args.next() {
        match a.as_str() {
            "--cache" => cache = PathBuf::from(args.next().expect(usage)),
            "--at" => {
                at = args.next().expect(usage).split(',').map(|s| s.parse()).collect::<Result<_, _>>()?
            }
            "--threads" => threads = args.next().expect(usage).parse()?,
            "--json" => json = Some(PathBuf::from(args.next().expect(usage))),
            s => schemes.push(scheme(s)),
        }
    }
    if schemes.is_empty() {
        schemes = ["ex8:8", "ex16:16", "lub24:2:4", "ex32:32"].map(scheme).to_vec();
    }
    let pool = rayon::ThreadPoolBuilder::new().num_threads(threads).build()?;
    let runs = pool.install(|| shadow(&case, scale, &cache, &from, &at, &schemes, true))?;
    let reference = runs.len() - 1;
    let diffs = shadow_differences(&runs, reference);
    println!(
        "# {case} at s = {scale}: contact schemes against `{}`, from {}\n",
        runs[reference].label,
        from.display()
    );
    println!("| scheme | n_sub × m | steps | RMS ‖Δx‖ | RMS ‖Δv‖ | RMS ‖Δω‖ | ⟨Δz⟩ | s per step |");
    println!("|---|---|---|---|---|---|---|---|");
    for (run, d) in runs.iter().zip(&diffs) {
        for (i, &n) in d.at.iter().enumerate() {
            println!(
                "| {} | {} × {}{} | {n} | {:.3e} | {:.3e} | {:.3e} | {:+.3e} | {:.3} |",
                run.label,
                run.contact_substeps,
                run.lubrication_substeps,
                if run.lubrication_limiter { " (limiter)" } else { "" },
                d.rms_position[i],
                d.rms_velocity[i],
                d.rms_angular[i],
                d.mean_dz[i],
                run.seconds / *d.at.last().unwrap() as f64
            );
        }
    }
    println!("\nMeans over the steps: ⟨w_p⟩ − ⟨w_p⟩_ref; the contacts' elastic energy and interacting marker pairs at the last sub-step:\n");
    println!("| scheme | ⟨w_p⟩ − ref | elastic energy | against ref | marker pairs |");
    println!("|---|---|---|---|---|");
    let mean = |v: &[f64]| v.iter().sum::<f64>() / v.len().max(1) as f64;
    let e_ref = mean(&runs[reference].elastic_energy);
    for (run, d) in runs.iter().zip(&diffs) {
        let e = mean(&run.elastic_energy);
        let pairs = run.marker_pairs.iter().sum::<usize>() as f64 / run.marker_pairs.len().max(1) as f64;
        println!(
            "| {} | {:+.3e} | {e:.4e} | {:+.2} % | {pairs:.0} |",
            d.label,
            d.mean_dw,
            100.0 * (e / e_ref - 1.0)
        );
    }
    // Observed orders between explicit schemes (m = 1, no limiter) whose counts double, from
    // the position differences at the last recorded step: with an error C h^p per scheme and
    // the reference's own h_ref = 1/N, the differences are d_n = C (n^-p − N^-p), so
    // d_n / d_2n fixes p (found by bisection; the velocity differences are noisier).
    println!("\nObserved order p from RMS ‖Δx‖ at the last recorded step, explicit n against 2n (the reference's error allowed for):\n");
    let explicit =
        |r: &slurry_reproduce::bench::ShadowRun| r.lubrication_substeps == 1 && !r.lubrication_limiter;
    let big_n = runs[reference].contact_substeps as f64;
    for (i, a) in runs.iter().enumerate() {
        for (j, b) in runs.iter().enumerate() {
            if i != reference
                && j != reference
                && explicit(a)
                && explicit(b)
                && b.contact_substeps == 2 * a.contact_substeps
            {
                let ratio = *diffs[i].rms_position.last().unwrap() / *diffs[j].rms_position.last().unwrap();
                let n = a.contact_substeps as f64;
                let model = |p: f64| (n.powf(-p) - big_n.powf(-p)) / ((2.0 * n).powf(-p) - big_n.powf(-p));
                let (mut lo, mut hi) = (0.05, 6.0);
                let p = if !(model(lo)..model(hi)).contains(&ratio) {
                    f64::NAN
                } else {
                    for _ in 0..60 {
                        let mid = 0.5 * (lo + hi);
                        if model(mid) < ratio {
                            lo = mid
                        } else {
                            hi = mid
                        }
                    }
                    0.5 * (lo + hi)
                };
                println!("- {} → {}: d ratio {ratio:.2}, p = {p:.2}", a.label, b.label);
            }
        }
    }
    if let Some(path) = json {
        std::fs::write(
            &path,
            serde_json::to_string_pretty(&serde_json::json!({"runs": runs, "differences": diffs}))?,
        )?;
    }
    Ok(())
}
