//! The settled beds of `slurry reproduce` side by side (issue 14, "The bed": wet against dry):
//! per bed its settling, the mean centre height, and the solids volume fraction φ(z) in slabs
//! of d/4 (the report's Figure 6 bins, `stats::volume_fraction_profile`, from the particles'
//! shapes) up to 0.35 H, with the first layer's peak and the share of the solids above
//! 0.2 H (the paper's line between the bed and the mobile particles).
//!
//! ```sh
//! cargo run --release -p slurry-reproduce --example bed_profile -- CACHE/beds/KEY/bed.json...
//! ```
//!
//! Each argument is a cached bed (`bed.json`: the case it was made from, `wet`, and the
//! particles at rest). Beds of different cases or scales may be listed; each is described
//! against its own tank.

use std::path::Path;

use slurry::case::Case;
use slurry::io::{ParticleFrame, ParticleProperties};
use slurry_reproduce::stats::{volume_fraction_profile, Tank};
use slurry_reproduce::BedRecord;

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
    let rec: BedRecord = serde_json::from_str(&text)
        .map_err(|e| anyhow::anyhow!("{}: not a cached bed: {e}", path.display()))?;
    // The case the bed was made from, with its particles where the bed left them.
    let mut case = Case::parse_unchecked(&rec.inputs)
        .map_err(|e| anyhow::anyhow!("{}: its inputs are not a case: {e}", path.display()))?;
    case.random_particles.clear();
    case.particles = rec.bed.particles.clone();
    let inits = case.particle_inits().map_err(|e| anyhow::anyhow!("{}: {e}", path.display()))?;
    let (nx, nz) = (case.domain.nx as f64, case.domain.nz as f64);
    let statics: Vec<ParticleProperties> = inits
        .iter()
        .map(|p| ParticleProperties {
            shape: p.shape.name().to_string(),
            diameter: p.diameter,
            length: p.length.unwrap_or(f64::NAN),
            density: p.density,
            volume: p.volume(),
            mass: p.density * p.volume(),
            motion: p.motion.name().to_string(),
        })
        .collect();
    let frame = ParticleFrame {
        position: inits.iter().map(|p| [p.position.x, p.position.y, p.position.z]).collect(),
        quaternion: inits
            .iter()
            .map(|p| [p.orientation.w, p.orientation.i, p.orientation.j, p.orientation.k])
            .collect(),
        velocity: vec![[0.0; 3]; inits.len()],
        angular_velocity: vec![[0.0; 3]; inits.len()],
        force: vec![[0.0; 3]; inits.len()],
        torque: vec![[0.0; 3]; inits.len()],
        ..Default::default()
    };
    let d = statics.first().map_or(1.0, |s| s.diameter);
    let tank = Tank { t: nx, h: nz, tip_speed: 1.0, steps_per_rev: 1.0 };
    let prof = volume_fraction_profile(std::slice::from_ref(&frame), &statics, &tank, d / 4.0)?;
    // The bed's mean centre coordinate, above the floor at z = −½ (as the report and ⟨z_p⟩/H).
    let mean = rec.bed.mean_height + 0.5;
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
        if rec.wet { "wet" } else { "dry" }
    );
    println!("## {label}: {}", path.display());
    println!(
        "- {} particles of d = {d}, tank {nx} × {nx} × {nz}; settled {} in {} steps (mean speed at the end {:.2e})",
        statics.len(),
        if rec.bed.settled { "yes" } else { "no" },
        rec.bed.steps,
        rec.bed.mean_speed
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
