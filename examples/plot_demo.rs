//! Writes one figure of each kind made by `slurry::plot` into a directory:
//!
//! - `field.png`: a synthetic stand-in for the paper's Figures 3 and 4, `|u| / v_tip` on a
//!   vertical plane through the axis of a stirred tank (a swirling jet leaving the impeller
//!   blades, decaying towards the wall), the impeller and shaft masked as NaN (grey);
//! - `power.png`: power-number time series (linear axes, lines, lines with markers);
//! - `histogram.png`: a particle-statistics profile on a logarithmic y axis (markers).
//!
//! Usage: `cargo run --release --example plot_demo -- OUT_DIR`

use std::f64::consts::PI;
use std::path::PathBuf;

use slurry::plot::{
    write_field_png, write_line_png, FieldImage, FieldSize, LegendPosition, LinePlot, Series, SeriesStyle,
};

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let dir = PathBuf::from(std::env::args().nth(1).ok_or("usage: plot_demo OUT_DIR")?);
    std::fs::create_dir_all(&dir)?;

    // A tank of diameter T = 120 lattice spacings and height H = T, impeller of diameter
    // D = T/3 at height C = T/3, shaft on the axis. Plane through the axis: x ∈ [−T/2, T/2].
    let (nx, ny) = (120usize, 120usize);
    let t = nx as f64;
    let (d, c) = (t / 3.0, t / 3.0);
    let mut speed = vec![0.0; nx * ny];
    for j in 0..ny {
        for i in 0..nx {
            let x = i as f64 + 0.5 - t / 2.0;
            let z = j as f64 + 0.5;
            let r = x.abs();
            let blade = r < d / 2.0 && (z - c).abs() < d / 10.0;
            let shaft = r < 1.5 && z > c;
            speed[j * nx + i] = if blade || shaft {
                f64::NAN
            } else {
                // Radial jet from the blade tips, widening and decaying; weak recirculation.
                let jet = (-(z - c).powi(2) / (2.0 * (3.0 + 0.15 * (r - d / 2.0).max(0.0)).powi(2))).exp();
                let decay = (d / 2.0 / r.max(d / 2.0)).powf(1.2);
                let swirl = 0.5 * (r / (d / 2.0)).min(1.0) * (-(z - c).abs() / (0.3 * t)).exp();
                let loops = 0.12 * (PI * z / t).sin() * (PI * r / (t / 2.0)).sin();
                0.85 * jet * decay + 0.3 * swirl + loops.abs()
            };
        }
    }
    let img = FieldImage {
        values: &speed,
        nx,
        ny,
        extent: (-0.5, 0.5, 0.0, 1.0),
        vmin: 0.0,
        vmax: 1.0,
        title: "Mid-plane speed (synthetic), Re = 100",
        colorbar_label: "|u| / v_tip",
        x_label: "r / T",
        y_label: "z / T",
    };
    let field = dir.join("field.png");
    write_field_png(&field, &img, FieldSize::PixelsPerNode(4))?;

    // Power number vs time, two impellers.
    let np = |np0: f64, k: f64| -> Vec<(f64, f64)> {
        (0..=200)
            .map(|n| {
                let tn = n as f64 * 0.05;
                (tn, np0 * (1.0 + 0.8 * (-tn / 1.5).exp()) + 0.05 * (k * tn).sin())
            })
            .collect()
    };
    let power = LinePlot {
        title: "Power number".into(),
        x_label: "t N (revolutions)".into(),
        y_label: "Np = P / (ρ N³ D⁵)".into(),
        series: vec![
            Series::new("pitched blade, Re = 100", np(1.9, 7.0), SeriesStyle::Line),
            Series::new(
                "Rushton, Re = 100",
                np(4.2, 5.0).into_iter().step_by(10).collect(),
                SeriesStyle::LinePoints,
            ),
        ],
        ..Default::default()
    };
    let power_path = dir.join("power.png");
    write_line_png(&power_path, &power, 800, 500)?;

    // A histogram-like profile on a log axis.
    let bins: Vec<(f64, f64)> = (0..25)
        .map(|k| {
            let z = (k as f64 + 0.5) / 25.0;
            (z, 0.6 * (-z / 0.18).exp() + 1e-3)
        })
        .collect();
    let hist = LinePlot {
        title: "Particle concentration profile".into(),
        x_label: "z / H".into(),
        y_label: "φ(z) / φ_mean".into(),
        series: vec![
            Series::new("simulation", bins.clone(), SeriesStyle::Points),
            Series::new("exponential fit", bins, SeriesStyle::Line),
        ],
        log_y: true,
        legend: LegendPosition::UpperRight,
        ..Default::default()
    };
    let hist_path = dir.join("histogram.png");
    write_line_png(&hist_path, &hist, 700, 480)?;

    for p in [field, power_path, hist_path] {
        println!("{}", p.display());
    }
    Ok(())
}
