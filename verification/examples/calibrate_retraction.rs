//! Calibration of the immersed boundary's retraction `r_d` (issue 13) on the Stokes drag of
//! the simple-cubic sphere array (`d/L = 0.25`, Zick & Homsy `K = 1.530`; the set-up of the
//! `stokes_drag` verification case: TRT `Λ = 3/16`, `ν = 1/6`, `Re = 0.05`, Roma 3-point
//! kernel, one forcing iteration, marker spacing 0.7).
//!
//! ```text
//! cargo run --release -p slurry-verification --example calibrate_retraction -- run 0.0 6 8 12 16 24
//! cargo run --release -p slurry-verification --example calibrate_retraction -- fit
//! ```
//!
//! - `run R D...`: for each diameter `D` (box `4D`), the steady drag with the forcing markers
//!   retracted by `R`, by Aitken extrapolation of the mean velocity
//!   (`stokes_drag::solve_extrapolated`, to 1e-7 relative); appends a row per `D` to
//!   `verification/ref/retraction_calibration.csv`: `d, retraction, K, rel_error,
//!   hydrodynamic_radius, excess, steps, seconds`, where the hydrodynamic radius `a_h` is the
//!   radius of the sphere whose exact drag (Sangani & Acrivos's series) equals the measured
//!   one and `excess = a_h − (a − R)`: how much larger than its forcing surface the body is.
//! - `fit`: for each retraction in the file, the least-squares `r_d` over `d ≥ 8` that makes
//!   the hydrodynamic radius equal the input radius, `r_d = Σ_d w_d e_d / Σ_d w_d` with `e_d`
//!   the excess at that retraction and `w_d = 1/a²` (the relative error of `K` is about
//!   `1.5 (a_h − a)/a` at this solids fraction, so this minimises the sum of squared relative
//!   errors, linearised), and the relative errors that value predicts (the drag of the sphere
//!   of radius `a − r_d + e_d`, assuming the excess does not move with `r_d`).
//!
//! The method: run `R = 0` over all `D`, fit, run the fitted value (the excess moves a little
//! with `R`: the forcing surface is smaller), fit again from those rows, and run the rounded
//! final value: its row errors are the residuals quoted in CHANGELOG and in
//! `coupling::DEFAULT_RETRACTION`.

use std::io::Write;

use std::f64::consts::PI;

use slurry_verification::cases::stokes_drag::{
    hydrodynamic_radius, k_sangani_acrivos, solve_extrapolated, K_REF,
};
use slurry_verification::workspace_root;

const HEADER: &str = "d,retraction,K,rel_error,hydrodynamic_radius,excess,steps,seconds";

fn csv_path() -> std::path::PathBuf {
    workspace_root().join("verification/ref/retraction_calibration.csv")
}

fn run(retraction: f64, ds: &[usize]) {
    let path = csv_path();
    let new = !path.exists();
    let mut f = std::fs::OpenOptions::new().create(true).append(true).open(&path).expect("open csv");
    if new {
        writeln!(f, "{HEADER}").unwrap();
    }
    for &d in ds {
        let e = solve_extrapolated(d, retraction, 1e-7);
        let (k, steps, change, secs) = (e.k, e.steps, e.change, e.seconds);
        let a = 0.5 * d as f64;
        let ah = hydrodynamic_radius(k, a, 4.0 * d as f64);
        let line = format!(
            "{d},{retraction},{k:.9},{:.6e},{ah:.6},{:.6},{steps},{secs:.1}",
            k / K_REF - 1.0,
            ah - (a - retraction)
        );
        eprintln!("{line}   (last extrapolation change {change:.1e})");
        writeln!(f, "{line}").unwrap();
        f.flush().unwrap();
    }
}

fn fit() {
    let text = std::fs::read_to_string(csv_path()).expect("run first");
    let rows: Vec<Vec<f64>> = text
        .lines()
        .skip(1)
        .filter(|l| !l.trim().is_empty())
        .map(|l| l.split(',').map(|v| v.parse::<f64>().unwrap()).collect())
        .collect();
    let mut rs: Vec<f64> = rows.iter().map(|r| r[1]).collect();
    rs.sort_by(f64::total_cmp);
    rs.dedup();
    for r in rs {
        let sel: Vec<&Vec<f64>> = rows.iter().filter(|row| row[1] == r && row[0] >= 8.0).collect();
        if sel.is_empty() {
            continue;
        }
        let (mut num, mut den) = (0.0, 0.0);
        for row in &sel {
            let a = 0.5 * row[0];
            num += row[5] / (a * a);
            den += 1.0 / (a * a);
        }
        let fitted = num / den;
        println!("from the rows at retraction {r}: fitted r_d = {fitted:.4}");
        for row in rows.iter().filter(|row| row[1] == r) {
            let (a, l) = (0.5 * row[0], 4.0 * row[0]);
            // The drag of the sphere of radius a − r_d + excess, in units of 6π μ a U.
            let ah = a - fitted + row[5];
            let k = ah * k_sangani_acrivos(4.0 * PI * ah.powi(3) / (3.0 * l.powi(3))) / a;
            println!(
                "  d = {:>2}: K = {:.4} (error {:+.2} %), excess {:.4}; predicted error at r_d = {fitted:.3}: {:+.2} %",
                row[0],
                row[2],
                100.0 * row[3],
                row[5],
                100.0 * (k / K_REF - 1.0)
            );
        }
    }
}

fn main() {
    let args: Vec<String> = std::env::args().skip(1).collect();
    match args.first().map(String::as_str) {
        Some("run") if args.len() >= 3 => {
            let r: f64 = args[1].parse().expect("retraction");
            let ds: Vec<usize> = args[2..].iter().map(|v| v.parse().expect("diameter")).collect();
            run(r, &ds);
        }
        Some("fit") => fit(),
        _ => {
            eprintln!("usage: calibrate_retraction run RETRACTION D... | fit");
            std::process::exit(2);
        }
    }
}
