//! Writes one figure of each kind made by `slurry::plot` into a directory, each as PNG and
//! as SVG:
//!
//! - `field.{png,svg}`: a synthetic stand-in for the paper's Figures 3 and 4, `|u| / v_tip`
//!   on a vertical plane through the axis of a stirred tank (a swirling jet leaving the
//!   impeller blades, decaying towards the wall), the impeller and shaft masked as NaN
//!   (grey), with the sections of a few cylindrical particles cut by the plane outlined
//!   ([`cylinder_section`]) — upright, lying, tilted, and one sticking out of the map;
//! - `power.{png,svg}`: power-number time series (linear axes, lines, lines with markers);
//! - `histogram.{png,svg}`: a particle-statistics profile on a logarithmic y axis (markers).
//!
//! Usage: `cargo run --release --example plot_demo -- OUT_DIR`

use std::f64::consts::PI;
use std::path::PathBuf;

use slurry::plot::{
    cylinder_section, write_field_png, write_field_svg, write_line_png, write_line_svg, FieldImage,
    FieldSize, LegendPosition, LinePlot, Series, SeriesStyle,
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
    // Cylinders (in lattice units, tank axis at x = y = 0, mid-plane y = 0): centre, axis,
    // diameter, length. Their sections by the plane, scaled to the figure's units (x / T,
    // z / T).
    let s = (0.5f64).sqrt();
    let cylinders: [([f64; 3], [f64; 3], f64, f64); 7] = [
        ([-45.0, 0.5, 4.0], [0.0, 0.0, 1.0], 6.0, 24.0), // standing upright
        ([-25.0, -1.0, 3.2], [1.0, 0.0, 0.0], 6.0, 24.0), // lying along x
        ([5.0, 1.5, 3.2], [0.0, 1.0, 0.0], 6.0, 6.0),    // lying across the plane: a disk
        ([25.0, 2.0, 10.0], [s, 0.4, s * 0.9], 6.0, 24.0), // tilted, cut by a cap
        ([40.0, 0.0, 60.0], [0.6, 0.48, 0.64], 6.0, 12.0), // tilted, suspended
        ([-10.0, 0.0, 90.0], [0.0, 0.8, 0.6], 6.0, 24.0), // tilted through the side
        ([58.0, 0.0, 30.0], [1.0, 0.0, 0.2], 6.0, 24.0), // sticking out of the map
    ];
    let outlines: Vec<Vec<(f64, f64)>> = cylinders
        .iter()
        .filter_map(|&(c, a, d, l)| cylinder_section(c, a, d, l, 0.0, 96))
        .map(|poly| poly.into_iter().map(|(x, z)| (x / t, z / t)).collect())
        .collect();
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
        outlines: &outlines,
    };
    let field = dir.join("field.png");
    write_field_png(&field, &img, FieldSize::PixelsPerNode(4))?;
    let field_svg = dir.join("field.svg");
    write_field_svg(&field_svg, &img, FieldSize::PixelsPerNode(4))?;

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
    let power_svg = dir.join("power.svg");
    write_line_svg(&power_svg, &power, 800, 500)?;

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
    let hist_svg = dir.join("histogram.svg");
    write_line_svg(&hist_svg, &hist, 700, 480)?;

    for p in [field, field_svg, power_path, power_svg, hist_path, hist_svg] {
        println!("{}", p.display());
    }
    Ok(())
}
