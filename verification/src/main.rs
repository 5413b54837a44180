//! `slurry-verify`: runs the verification cases, prints a table of checks and the convergence
//! tables, compares the tables with the committed `.ref` files, writes the JSON report, and
//! exits 1 if any check fails.

use std::path::PathBuf;
use std::process::ExitCode;
use std::time::Instant;

use clap::Parser;
use slurry_verification::{backend, cases, ref_dir, reftable, report, workspace_root, Check, Tier};

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
    /// Where to write the JSON report (default: `<workspace>/target/verification/report.json`,
    /// `report-gpu.json` with `--device gpu`).
    #[arg(long, value_name = "PATH")]
    report: Option<PathBuf>,
    /// Which processor steps the fluid: `cpu`, or `gpu` (the device backend, through Vulkan:
    /// the cases whose flow is the fluid alone, with the CPU's tolerances and reference tables;
    /// `--list` marks them).
    #[arg(long, value_name = "cpu|gpu", default_value = "cpu", value_parser = ["cpu", "gpu"])]
    device: String,
}

fn main() -> ExitCode {
    let args = Args::parse();
    let all = cases::all();
    if args.list {
        for c in &all {
            println!("{:<20} {}{}", c.name, c.summary, if c.device { " [also on the device]" } else { "" });
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
    let gpu = args.device == "gpu";
    if gpu && args.bless {
        eprintln!("error: --bless with --device gpu: the reference tables are the CPU's; bless on the CPU");
        return ExitCode::from(2);
    }
    if gpu {
        if let Some(c) = all.iter().find(|c| !c.device && args.cases.iter().any(|n| n == c.name)) {
            let names: Vec<&str> = all.iter().filter(|c| c.device).map(|c| c.name).collect();
            eprintln!(
                "error: --device gpu: the case '{}' does not run on the device; those that do: {}",
                c.name,
                names.join(", ")
            );
            return ExitCode::from(2);
        }
    }
    let selected: Vec<_> = all
        .iter()
        .filter(|c| args.cases.is_empty() || args.cases.iter().any(|n| n == c.name))
        .filter(|c| !gpu || c.device)
        .collect();
    let tier = args.tier;
    let processor = if gpu {
        match backend::use_device() {
            Ok(ctx) => format!(
                "the fluid on the device {}{}",
                ctx.describe(),
                if ctx.is_cpu_driver() { " (a CPU driver: its timings are no measure of speed)" } else { "" }
            ),
            Err(e) => {
                eprintln!("error: --device gpu: {e}");
                return ExitCode::from(2);
            }
        }
    } else {
        "the CPU".into()
    };
    println!(
        "slurry-verify: tier {}, {} case(s), {} thread(s), {processor}",
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
            let (tol, reason) = if gpu {
                (
                    reftable::DEVICE_REL_TOL,
                    "the CPU's table, the fluid stepped on the device: its round-off differs from \
                     the CPU's (fma contraction), which moves a number run to steady state by the \
                     1.6e-13 the steady criterion leaves over its size (see reftable.rs)",
                )
            } else {
                (
                    reftable::REL_TOL,
                    "bitwise deterministic on one machine (deviation 0 with unchanged \
                     code); 1e-9 relative allows for last-bit libm sin/cos/exp \
                     differences across platforms (<= 1e-11 here) but flags any change \
                     of the arithmetic, to be re-blessed (see reftable.rs)",
                )
            };
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
                Ok(dev) => Check::at_most(case.name, "ref_table_match", dev, tol, reason),
                Err(msg) => {
                    println!("reference table {}: {msg}", path.display());
                    let mut c = Check::at_most(case.name, "ref_table_match", f64::NAN, tol, reason);
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
    let default = if gpu { "target/verification/report-gpu.json" } else { "target/verification/report.json" };
    let path = args.report.unwrap_or_else(|| workspace_root().join(default));
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
