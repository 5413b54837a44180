//! `slurry-verify`: runs the verification cases, prints a table of checks and the convergence
//! tables, compares the tables with the committed `.ref` files, writes the JSON report, and
//! exits 1 if any check fails.

use std::path::PathBuf;
use std::process::ExitCode;
use std::time::Instant;

use clap::Parser;
use slurry_verification::{cases, ref_dir, reftable, report, workspace_root, Check, Tier};

/// Verification suite of slurry: convergence studies against exact solutions, fused ≡ reference
/// kernel, conservation. See verification/src/cases/*.rs for each case's physics, reference and
/// tolerances.
#[derive(Parser, Debug)]
#[command(name = "slurry-verify", version)]
struct Args {
    /// Quick (CI, a few minutes) or full (more resolutions).
    #[arg(long, value_enum, default_value = "quick")]
    tier: Tier,
    /// Run only this case (repeatable). Default: all.
    #[arg(long = "case", value_name = "NAME")]
    cases: Vec<String>,
    /// List the cases and exit.
    #[arg(long)]
    list: bool,
    /// Rewrite the committed reference tables (`verification/ref/<case>-<tier>.ref`) with this
    /// run's numbers instead of comparing with them.
    #[arg(long)]
    bless: bool,
    /// Where to write the JSON report (default: `<workspace>/target/verification/report.json`).
    #[arg(long, value_name = "PATH")]
    report: Option<PathBuf>,
}

fn main() -> ExitCode {
    let args = Args::parse();
    let all = cases::all();
    if args.list {
        for c in &all {
            println!("{:<20} {}", c.name, c.summary);
        }
        return ExitCode::SUCCESS;
    }
    for name in &args.cases {
        if !all.iter().any(|c| c.name == name) {
            let names: Vec<&str> = all.iter().map(|c| c.name).collect();
            eprintln!("error: unknown case '{name}'; known cases: {}", names.join(", "));
            return ExitCode::from(2);
        }
    }
    let selected: Vec<_> =
        all.iter().filter(|c| args.cases.is_empty() || args.cases.iter().any(|n| n == c.name)).collect();
    let tier = args.tier;
    println!(
        "slurry-verify: tier {}, {} case(s), {} thread(s)",
        tier.name(),
        selected.len(),
        rayon::current_num_threads()
    );
    let t0 = Instant::now();
    let mut checks: Vec<Check> = Vec::new();
    for case in selected {
        let tc = Instant::now();
        println!("\n=== {} ({}) ===", case.name, case.summary);
        let mut out = (case.run)(tier);
        for t in &out.tables {
            print!("{t}");
        }
        if out.has_ref {
            let path = ref_dir().join(format!("{}-{}.ref", case.name, tier.name()));
            let reason = "bitwise deterministic on one machine (deviation 0 with unchanged \
                          code); 1e-9 relative allows for last-bit libm sin/cos/exp \
                          differences across platforms (<= 1e-11 here) but flags any change \
                          of the arithmetic, to be re-blessed (see reftable.rs)";
            if args.bless {
                let text = reftable::render(case.name, tier.name(), &out.tables);
                if let Err(e) = std::fs::write(&path, text) {
                    eprintln!("error: cannot write {}: {e}", path.display());
                    return ExitCode::from(2);
                }
                println!("blessed {}", path.display());
            }
            let cmp = std::fs::read_to_string(&path)
                .map_err(|e| format!("cannot read {}: {e} (run with --bless)", path.display()))
                .and_then(|text| reftable::parse(&text))
                .and_then(|refs| reftable::compare(&out.tables, &refs));
            let check = match cmp {
                Ok(dev) => Check::at_most(case.name, "ref_table_match", dev, reftable::REL_TOL, reason),
                Err(msg) => {
                    println!("reference table {}: {msg}", path.display());
                    let mut c =
                        Check::at_most(case.name, "ref_table_match", f64::NAN, reftable::REL_TOL, reason);
                    c.pass = false;
                    c
                }
            };
            out.checks.push(check);
        }
        for c in &out.checks {
            if !c.pass {
                println!(
                    "FAIL {} {}: value {} expected {} tolerance {}",
                    c.case, c.metric, c.value, c.expected, c.tolerance
                );
            }
        }
        println!("({} in {:.1} s)", case.name, tc.elapsed().as_secs_f64());
        checks.extend(out.checks);
    }
    println!("\n=== checks ===");
    print!("{}", report::summary(&checks));
    let path = args.report.unwrap_or_else(|| workspace_root().join("target/verification/report.json"));
    if let Err(e) = report::write_json(&path, &checks) {
        eprintln!("error: cannot write the report {}: {e}", path.display());
        return ExitCode::from(2);
    }
    let failed = checks.iter().filter(|c| !c.pass).count();
    println!(
        "\n{} passed, {} failed ({:.1} s); report: {}",
        checks.len() - failed,
        failed,
        t0.elapsed().as_secs_f64(),
        path.display()
    );
    if failed > 0 {
        ExitCode::FAILURE
    } else {
        ExitCode::SUCCESS
    }
}
