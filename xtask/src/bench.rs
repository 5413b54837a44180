//! `cargo xtask bench`: the fused kernel's MLUPS beside this machine's memory-bandwidth ceiling
//! (`benches/scripts/membw.sh`) and the lbmpy peer (`benches/scripts/lbmpy-peer.sh`), measured in the
//! same run because the machines are shared and noisy (ratios hold, absolute figures drift).
//!
//! Writes `target/bench/lbm.json` (ours), `target/bench/membw.json` and
//! `target/bench/lbmpy.json` (one JSON object per line, as the scripts print them).

use std::path::Path;
use std::process::Command;

/// Options: `--quick` (128³ only, fewer repetitions), `--no-peer` (skip lbmpy), and anything
/// else is passed to `slurry bench`.
pub fn bench(root: &Path, args: &[String]) -> Result<(), String> {
    if args.iter().any(|a| a == "--coupled") {
        return coupled(root, args);
    }
    let quick = args.iter().any(|a| a == "--quick");
    let no_peer = args.iter().any(|a| a == "--no-peer");
    let mut pass: Vec<String> =
        args.iter().filter(|a| *a != "--quick" && *a != "--no-peer").cloned().collect();
    if quick {
        pass.extend(["--sizes", "128", "--reps", "3", "--seconds", "0.5"].map(String::from));
    }
    let out = root.join("target/bench");
    std::fs::create_dir_all(&out).map_err(|e| format!("cannot create {}: {e}", out.display()))?;
    let lbm_json = out.join("lbm.json");

    println!("== slurry fused kernel (periodic box) ==");
    slurry_bench(root, &lbm_json, &pass).map_err(|e| format!("slurry bench failed: {e}"))?;
    inlining_guard(root)?;
    let ours = std::fs::read_to_string(&lbm_json).map_err(|e| format!("{}: {e}", lbm_json.display()))?;
    let ours: Vec<Row> = split_objects(&ours).iter().filter_map(|o| Row::parse(o)).collect();

    let bench_dir = root.join("benches/scripts");
    println!("\n== memory-bandwidth ceiling (membw.sh 128 1 2) ==");
    let membw = run_script(&bench_dir.join("membw.sh"), &["128", "1", "2"])?;
    std::fs::write(out.join("membw.json"), &membw).map_err(|e| e.to_string())?;
    print!("{membw}");

    let mut peer = String::new();
    if !no_peer {
        println!("\n== lbmpy peer (lbmpy-peer.sh, 128³) ==");
        for method in ["SRT", "TRT"] {
            for prec in ["f64", "f32"] {
                for threads in ["1", "2"] {
                    let args =
                        ["--method", method, "--precision", prec, "--size", "128", "--threads", threads];
                    match run_script(&bench_dir.join("lbmpy-peer.sh"), &args) {
                        Ok(line) => {
                            print!("{line}");
                            peer.push_str(&line);
                        }
                        Err(e) => println!("lbmpy peer {method} {prec} {threads} thread(s) failed: {e}"),
                    }
                }
            }
        }
        std::fs::write(out.join("lbmpy.json"), &peer).map_err(|e| e.to_string())?;
    }

    println!("\n== side by side, 128³ (MLUPS; ratios are what to quote) ==");
    println!(
        "{:>4} {:>4} {:>3} {:>9} {:>9} {:>8} {:>10} {:>9}",
        "prec", "coll", "thr", "slurry", "lbmpy", "ratio", "in-place", "fraction"
    );
    for r in ours.iter().filter(|r| r.n == "128x128x128") {
        let method = if r.collision == "bgk" { "SRT" } else { "TRT" };
        let p = find(&peer, &[("method", method), ("precision", &r.precision), ("threads", &r.threads)]);
        let c = find(&membw, &[("pattern", "inpl"), ("precision", &r.precision), ("threads", &r.threads)]);
        let fmt = |v: Option<f64>| v.map_or("-".to_string(), |v| format!("{v:.1}"));
        println!(
            "{:>4} {:>4} {:>3} {:>9.1} {:>9} {:>8} {:>10} {:>9}",
            r.precision,
            r.collision,
            r.threads,
            r.mlups,
            fmt(p),
            p.map_or("-".into(), |p| format!("{:.2}x", r.mlups / p)),
            fmt(c),
            c.map_or("-".into(), |c| format!("{:.0}%", 100.0 * r.mlups / c)),
        );
    }
    println!("\nfiles: {}, membw.json, lbmpy.json", lbm_json.display());
    Ok(())
}

/// `--coupled [ARGS]`: the coupled step of the paper's cases (`slurry bench --coupled`, default
/// scales 1/4, 1/2 and 1, 2 threads, f32) into `target/bench/coupled.json`, then the
/// bandwidth ceiling (`membw.sh`) in the same run, into `target/bench/membw.json`.
fn coupled(root: &Path, args: &[String]) -> Result<(), String> {
    let out = root.join("target/bench");
    std::fs::create_dir_all(&out).map_err(|e| format!("cannot create {}: {e}", out.display()))?;
    let json = out.join("coupled.json");
    let mut pass: Vec<String> = args.to_vec();
    if !pass.iter().any(|a| a.starts_with("--threads")) {
        pass.extend(["--threads".to_string(), "2".to_string()]);
    }
    println!("== slurry coupled step, the paper's cases ==");
    slurry_bench(root, &json, &pass).map_err(|e| format!("slurry bench --coupled failed: {e}"))?;
    inlining_guard(root)?;
    println!("\n== memory-bandwidth ceiling (membw.sh 128 1 2) ==");
    let membw = run_script(&root.join("benches/scripts/membw.sh"), &["128", "1", "2"])?;
    std::fs::write(out.join("membw.json"), &membw).map_err(|e| e.to_string())?;
    print!("{membw}");
    println!("\nfiles: {}, membw.json", json.display());
    Ok(())
}

/// `slurry bench --json JSON ARGS` in release, through cargo (which builds the binary first).
fn slurry_bench(root: &Path, json: &Path, args: &[String]) -> Result<(), String> {
    let status = Command::new("cargo")
        .current_dir(root)
        .args([
            "run",
            "--release",
            "--quiet",
            "-p",
            "slurry-reproduce",
            "--bin",
            "slurry",
            "--",
            "bench",
            "--json",
        ])
        .arg(json)
        .args(args)
        .status()
        .map_err(|e| format!("cannot run cargo: {e}"))?;
    if status.success() {
        Ok(())
    } else {
        Err(format!("exit status {status}"))
    }
}

/// Fails if the `slurry` binary calls a SIMD intrinsic out of line. That happens when a generic
/// helper in the kernel path (e.g. `std::array::from_fn`) is not inlined into the
/// `#[target_feature]` entry point: it is then compiled without AVX and calls every intrinsic
/// as a function (seen once: `slurry run` at 45 MLUPS while this benchmark showed 150, because
/// the two instantiate the kernel in different crates).
pub fn inlining_guard(root: &Path) -> Result<(), String> {
    let bin = root.join("target/release/slurry");
    if !bin.exists() {
        return Err(format!("{} is not built: nothing to check", bin.display()));
    }
    let Ok(out) = Command::new("objdump").arg("-d").arg("--no-show-raw-insn").arg(&bin).output() else {
        println!("(objdump not found: skipping the check for out-of-line SIMD intrinsics)");
        return Ok(());
    };
    let text = String::from_utf8_lossy(&out.stdout);
    let calls = text.lines().filter(|l| l.contains("call") && l.contains("_mm")).count();
    if calls > 0 {
        return Err(format!(
            "{} calls SIMD intrinsics out of line ({calls} call sites): a helper in the kernel path \
             did not inline into its #[target_feature] function; see src/lbm/simd.rs",
            bin.display()
        ));
    }
    // The dense moment pass's AVX2 copies must hold the vectorised row loop itself, not a call
    // to a copy compiled without AVX2 (seen once: a generic helper in the loop lost its
    // inlining, the copy shrank to 448 bytes and the interior phase ran 20–35 % slower).
    let mut blocks = Vec::new();
    let mut current: Option<usize> = None;
    for line in text.lines() {
        if line.ends_with(">:") {
            current = line.contains("run_moments_avx2").then(|| {
                blocks.push(0usize);
                blocks.len() - 1
            });
        } else if let Some(b) = current {
            blocks[b] += usize::from(line.contains("ymm"));
        }
    }
    if cfg!(target_arch = "x86_64") && blocks.is_empty() {
        return Err(format!("{}: no run_moments_avx2 found (renamed? update this check)", bin.display()));
    }
    if let Some(&few) = blocks.iter().find(|&&n| n < 16) {
        return Err(format!(
            "{}: a copy of run_moments_avx2 holds only {few} AVX2 (ymm) instructions: its row loop \
             was not inlined into it (src/lbm/fluid.rs, run_moments_rows)",
            bin.display()
        ));
    }
    println!(
        "inlining check: no out-of-line SIMD intrinsic calls in {}; {} vectorised copies of run_moments_avx2",
        bin.display(),
        blocks.len()
    );
    Ok(())
}

fn run_script(script: &Path, args: &[&str]) -> Result<String, String> {
    let out = Command::new("bash")
        .arg(script)
        .args(args)
        .output()
        .map_err(|e| format!("cannot run {}: {e}", script.display()))?;
    if !out.status.success() {
        return Err(format!(
            "{} exited with {}: {}",
            script.display(),
            out.status,
            String::from_utf8_lossy(&out.stderr).lines().last().unwrap_or("")
        ));
    }
    Ok(String::from_utf8_lossy(&out.stdout).into_owned())
}

/// One of our rows, from `lbm.json`.
struct Row {
    precision: String,
    collision: String,
    threads: String,
    n: String,
    mlups: f64,
}

impl Row {
    fn parse(o: &str) -> Option<Row> {
        Some(Row {
            precision: field(o, "precision")?,
            collision: field(o, "collision")?,
            threads: field(o, "threads")?,
            n: format!("{}x{}x{}", field(o, "nx")?, field(o, "ny")?, field(o, "nz")?),
            mlups: field(o, "mlups")?.parse().ok()?,
        })
    }
}

/// The `{...}` objects of a JSON array or of JSON lines (flat objects only).
fn split_objects(text: &str) -> Vec<String> {
    let mut out = Vec::new();
    let mut cur = None::<String>;
    for ch in text.chars() {
        match (ch, cur.as_mut()) {
            ('{', None) => cur = Some(String::new()),
            ('}', Some(_)) => out.push(cur.take().unwrap_or_default()),
            (c, Some(s)) => s.push(c),
            _ => {}
        }
    }
    out
}

/// The value of `"key": value` in a flat JSON object, without quotes.
fn field(obj: &str, key: &str) -> Option<String> {
    let pat = format!("\"{key}\"");
    let at = obj.find(&pat)? + pat.len();
    let rest = obj[at..].trim_start().strip_prefix(':')?.trim_start();
    let end = rest.find([',', '}', '\n']).unwrap_or(rest.len());
    Some(rest[..end].trim().trim_matches('"').to_string())
}

/// The `mlups` of the first JSON line in `lines` whose fields match all of `want`.
fn find(lines: &str, want: &[(&str, &str)]) -> Option<f64> {
    split_objects(lines)
        .iter()
        .find(|o| want.iter().all(|(k, v)| field(o, k).as_deref() == Some(*v)))
        .and_then(|o| field(o, "mlups")?.parse().ok())
}
