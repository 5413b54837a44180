//! Restitution against the number of contact sub-steps, explicit and with the lubrication
//! limiter: how far each contact scheme is from the sub-step-converged collision.
//!
//! `cargo run --release -p slurry-verification --example substep_convergence [D ...]`
//!
//! Dry collisions of `contacts_dry` (no fluid; Table 1 with lubrication) at diameters `D`
//! (default 3, 6, 12: s = 1/4, 1/2, 1), every setup, impact speeds 0.01, 0.02, 0.05 and the tip
//! speed. Reference: the explicit law at 256 sub-steps per fluid step. Prints, per diameter,
//! setup and scheme, the restitution at each speed and the largest |e − e_ref| over the speeds.

use slurry::contact::ContactParams;
use slurry_verification::cases::contacts_dry::{collide, Setup, TIP_SPEED};

fn main() {
    let ds: Vec<f64> = std::env::args().skip(1).map(|a| a.parse().expect("a diameter")).collect();
    let ds = if ds.is_empty() { vec![3.0, 6.0, 12.0] } else { ds };
    let speeds = [0.01, 0.02, 0.05, TIP_SPEED];
    let explicit = ContactParams::default();
    let limited = ContactParams { lubrication_limiter: true, ..Default::default() };
    let schemes: Vec<(&str, ContactParams, usize)> = vec![
        ("explicit 4", explicit, 4),
        ("explicit 8", explicit, 8),
        ("explicit 16", explicit, 16),
        ("explicit 32", explicit, 32),
        ("limiter 1", limited, 1),
        ("limiter 2", limited, 2),
        ("limiter 4", limited, 4),
        ("limiter 8", limited, 8),
        ("limiter 32", limited, 32),
    ];
    println!("| d | setup | scheme | e at {speeds:?} | max abs(e − e_ref) | closest approach (min) |");
    println!("|---|---|---|---|---|---|");
    for &d in &ds {
        for s in Setup::ALL {
            let refs: Vec<_> = speeds.iter().map(|&v| collide(s, d, v, explicit, 256)).collect();
            let reference: Vec<f64> = refs.iter().map(|o| o.restitution).collect();
            let closest = refs.iter().map(|o| o.closest).fold(f64::INFINITY, f64::min);
            println!(
                "| {d} | {} | explicit 256 (reference) | {} | 0 | {closest:.3} |",
                s.name(),
                fmt(&reference)
            );
            for (name, p, n) in &schemes {
                let outs: Vec<_> = speeds.iter().map(|&v| collide(s, d, v, *p, *n)).collect();
                let e: Vec<f64> = outs.iter().map(|o| o.restitution).collect();
                let err = e.iter().zip(&reference).map(|(a, b)| (a - b).abs()).fold(0.0, f64::max);
                let closest = outs.iter().map(|o| o.closest).fold(f64::INFINITY, f64::min);
                println!("| {d} | {} | {name} | {} | {err:.4} | {closest:.3} |", s.name(), fmt(&e));
            }
        }
    }
}

fn fmt(v: &[f64]) -> String {
    v.iter().map(|x| format!("{x:.4}")).collect::<Vec<_>>().join(", ")
}
