//! The settled beds of `slurry reproduce` side by side (issue 14, "The bed": wet against dry):
//! per bed its settling, the mean centre height, and the solids volume fraction φ(z) in slabs
//! of d/4 (the report's Figure 6 bins, `stats::volume_fraction_profile`, from the particles'
//! shapes) up to 0.35 H, with the first layer's peak and the share of the solids above
//! 0.2 H (the paper's line between the bed and the mobile particles).
//!
//! ```sh
//! cargo run --release -p slurry-verification --example bed_profile -- CACHE/beds/KEY/bed.json...
//! ```
//!
//! Each argument is a cached bed (`bed.json`: the case it was made from, `wet`, and the
//! particles at rest). Beds of different cases or scales may be listed; each is described
//! against its own tank.

use std::path::Path;

use slurry::io::{ParticleFrame, ParticleProperties};
use slurry::stats::{volume_fraction_profile, Tank};

fn main() -> anyhow::Result<()> {
    let paths: Vec<String> = std::env::args().skip(1).collect();
    if paths.is_empty() {
        anyhow::bail!("usage: bed_profile CACHE/beds/KEY/bed.json... (cached beds of `slurry reproduce`)");
    }
    let mut profiles = Vec::new();
    for p in &paths {
        let (label, z, phi) = describe(Path::new(p))?;
        profiles.push((label, z, phi));
    }
    if profiles.len() > 1 && profiles.windows(2).all(|w| w[0].1 == w[1].1) {
        println!("\nφ(z) side by side (z/H at the slab centres):\n");
        let mut head = "| z/H |".to_string();
        let mut rule = "|---|".to_string();
        for (label, _, _) in &profiles {
            head += &format!(" {label} |");
            rule += "---|";
        }
        println!("{head}\n{rule}");
        for (k, z) in profiles[0].1.iter().enumerate() {
            let mut row = format!("| {z:.3} |");
            for (_, _, phi) in &profiles {
                row += &format!(" {:.3} |", phi[k]);
            }
            println!("{row}");
        }
    }
    Ok(())
}

/// Prints one bed's numbers; returns its label and φ(z) below 0.35 H.
fn describe(path: &Path) -> anyhow::Result<(String, Vec<f64>, Vec<f64>)> {
    let text = std::fs::read_to_string(path).map_err(|e| anyhow::anyhow!("{}: {e}", path.display()))?;
    let bed: serde_json::Value =
        serde_json::from_str(&text).map_err(|e| anyhow::anyhow!("{}: not JSON: {e}", path.display()))?;
    let inputs =
        bed["inputs"].as_str().ok_or_else(|| anyhow::anyhow!("{}: no \"inputs\"", path.display()))?;
    let key = |k: &str| -> anyhow::Result<f64> {
        inputs
            .lines()
            .find_map(|l| l.strip_prefix(&format!("{k} = ")).and_then(|v| v.trim().parse().ok()))
            .ok_or_else(|| anyhow::anyhow!("{}: no `{k} = ` in the bed's inputs", path.display()))
    };
    let (nx, nz) = (key("nx")?, key("nz")?);
    let wet = bed["wet"].as_bool().unwrap_or(false);
    let particles =
        bed["particles"].as_array().ok_or_else(|| anyhow::anyhow!("{}: no \"particles\"", path.display()))?;
    let mut statics = Vec::new();
    let mut frame = ParticleFrame::default();
    for (i, q) in particles.iter().enumerate() {
        let num = |k: &str| q[k].as_f64();
        let arr = |k: &str| -> Option<Vec<f64>> {
            q[k].as_array().map(|a| a.iter().filter_map(|v| v.as_f64()).collect())
        };
        let (d, gamma) = (
            num("diameter").ok_or_else(|| anyhow::anyhow!("particle {i}: no diameter"))?,
            num("density").unwrap_or(f64::NAN),
        );
        let length = num("length").unwrap_or(f64::NAN);
        let pos = arr("position")
            .filter(|v| v.len() == 3)
            .ok_or_else(|| anyhow::anyhow!("particle {i}: no position"))?;
        let quat = arr("orientation").filter(|v| v.len() == 4).unwrap_or_else(|| vec![1.0, 0.0, 0.0, 0.0]);
        if q.get("axis").is_some_and(|a| !a.is_null()) {
            anyhow::bail!(
                "{}: particle {i} gives an axis, not an orientation (not a settled bed)",
                path.display()
            );
        }
        let shape = q["shape"].as_str().unwrap_or("cylinder").to_string();
        let volume = if shape == "sphere" {
            std::f64::consts::PI * d * d * d / 6.0
        } else {
            std::f64::consts::PI * d * d * length / 4.0
        };
        statics.push(ParticleProperties {
            shape,
            diameter: d,
            length,
            density: gamma,
            volume,
            mass: gamma * volume,
            motion: "free".into(),
        });
        frame.position.push([pos[0], pos[1], pos[2]]);
        frame.quaternion.push([quat[0], quat[1], quat[2], quat[3]]);
        frame.velocity.push([0.0; 3]);
        frame.angular_velocity.push([0.0; 3]);
        frame.force.push([0.0; 3]);
        frame.torque.push([0.0; 3]);
    }
    let d = statics.first().map_or(1.0, |s| s.diameter);
    let tank = Tank { t: nx, h: nz, tip_speed: 1.0, steps_per_rev: 1.0 };
    let prof = volume_fraction_profile(std::slice::from_ref(&frame), &statics, &tank, d / 4.0)?;
    let heights: Vec<f64> = frame.position.iter().map(|p| p[2] + 0.5).collect();
    let mean = heights.iter().sum::<f64>() / heights.len() as f64;
    let solids: f64 = statics.iter().map(|s| s.volume).sum();
    let dz = nz / prof.z_over_h.len() as f64;
    let above: f64 =
        prof.z_over_h.iter().zip(&prof.value).filter(|(z, _)| **z > 0.2).map(|(_, v)| v * dz * nx * nx).sum();
    let first = prof
        .z_over_h
        .iter()
        .zip(&prof.value)
        .filter(|(z, _)| **z * nz < d)
        .map(|(_, v)| *v)
        .fold(0.0f64, f64::max);
    let label = format!(
        "{} ({})",
        path.parent().and_then(|p| p.file_name()).map_or("bed".into(), |n| n.to_string_lossy().to_string()),
        if wet { "wet" } else { "dry" }
    );
    println!("## {label}: {}", path.display());
    println!(
        "- {} particles of d = {d}, tank {nx} × {nx} × {nz}; settled {} in {} steps (mean speed at the end {:.2e})",
        statics.len(),
        bed["settled"].as_bool().map_or("?", |s| if s { "yes" } else { "no" }),
        bed["steps"].as_u64().unwrap_or(0),
        bed["mean_speed"].as_f64().unwrap_or(f64::NAN)
    );
    println!(
        "- mean centre height above the floor {mean:.3} = {:.4} H = {:.3} d; first layer's peak φ (z < d) {first:.3}; \
         solids above 0.2 H {:.1} %",
        mean / nz,
        mean / d,
        100.0 * above / solids
    );
    let keep: Vec<usize> = (0..prof.z_over_h.len()).filter(|&k| prof.z_over_h[k] < 0.35).collect();
    Ok((
        label,
        keep.iter().map(|&k| prof.z_over_h[k]).collect(),
        keep.iter().map(|&k| prof.value[k]).collect(),
    ))
}
