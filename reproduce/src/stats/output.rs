//! `stats.h5`: every statistic of a run in one HDF5 file.
//!
//! # Layout
//! Lattice units; every dataset has the attributes `units` and `description`.
//!
//! | group / dataset | shape | contents |
//! |---|---|---|
//! | `mean_height/rev`, `mean_height/value` | `[F]` | `⟨z_p⟩/H` per frame (Figure 5) |
//! | `volume_fraction/z_over_h`, `volume_fraction/value` | `[B]` | solids volume fraction profile (Figure 6) |
//! | `kinetic_energy/z_over_h`, `…/linear`, `…/rotational` | `[B]` | `k*` profiles (Figure 7) |
//! | `orientation/phi`, `…/all`, `…/mobile`, `…/sin` | `[A]` | orientation pdfs and `sin φ` (Figures 8, 9) |
//! | `power/rev`, `power/po_fluid`, `power/po_solids` | `[S]` | power-number series (Figure 10) |
//!
//! Attributes: root — `units`, `description`, `tank_side`, `tank_height`, `tip_speed`,
//! `steps_per_rev`, `particles`, `particle_mass`; `mean_height` — the steady-state test
//! (`steady_window_revs`, `steady_window_revs_available`, `steady_samples`, `slope_per_rev`,
//! `drift`, `tolerance`, `steady` (0/1), `reason`); `volume_fraction`, `kinetic_energy` and
//! `orientation` — the averaging window (`from_rev`, `to_rev`, `frames`), the bin width, and
//! for `orientation` the sample counts and `mobile_z_over_h`; `power` — the averages
//! (`po_fluid`, `po_solids`, `po`, `po_std`, `from_rev`, `to_rev`, `revs_covered`, `samples`,
//! `covered`)
//! when there is a power series.

use std::path::Path;

use hdf5::types::VarLenUnicode;

use super::{Stats, StatsError};
use slurry::io::atomic_write;

fn text(s: &str) -> VarLenUnicode {
    s.replace('\0', " ").parse().expect("no NUL left")
}

fn attr_f64(loc: &hdf5::Location, name: &str, v: f64) -> hdf5::Result<()> {
    loc.new_attr::<f64>().shape(()).create(name)?.write_scalar(&v)
}

fn attr_u64(loc: &hdf5::Location, name: &str, v: u64) -> hdf5::Result<()> {
    loc.new_attr::<u64>().shape(()).create(name)?.write_scalar(&v)
}

fn attr_text(loc: &hdf5::Location, name: &str, v: &str) -> hdf5::Result<()> {
    loc.new_attr::<VarLenUnicode>().shape(()).create(name)?.write_scalar(&text(v))
}

fn dataset(group: &hdf5::Group, name: &str, v: &[f64], units: &str, description: &str) -> hdf5::Result<()> {
    let d = group.new_dataset::<f64>().shape([v.len()]).create(name)?;
    d.write_raw(v)?;
    attr_text(&d, "units", units)?;
    attr_text(&d, "description", description)
}

/// Writes `stats` to the HDF5 file `path` atomically (module docs for the layout).
pub fn write_stats_h5(path: &Path, stats: &Stats) -> Result<(), StatsError> {
    atomic_write(path, |tmp| -> Result<(), StatsError> {
        let file = hdf5::File::create(tmp)?;
        attr_text(&file, "units", "lattice: Δ, Δt, ρ_f; heights z/H above the floor z = -0.5")?;
        attr_text(
            &file,
            "description",
            "slurry particle statistics after Derksen (2020): mean height, volume fraction, kinetic energy and \
             orientation profiles, power numbers",
        )?;
        let t = &stats.tank;
        for (name, v) in [
            ("tank_side", t.t),
            ("tank_height", t.h),
            ("tip_speed", t.tip_speed),
            ("steps_per_rev", t.steps_per_rev),
            ("particle_mass", stats.particle_mass),
        ] {
            attr_f64(&file, name, v)?;
        }
        attr_u64(&file, "particles", stats.particles as u64)?;

        let window = |g: &hdf5::Group| -> hdf5::Result<()> {
            attr_f64(g, "from_rev", stats.profile_from_rev)?;
            attr_f64(g, "to_rev", stats.profile_to_rev)?;
            attr_u64(g, "frames", stats.profile_frames as u64)
        };

        let g = file.create_group("mean_height")?;
        let (rev, value): (Vec<f64>, Vec<f64>) = stats.mean_height.iter().copied().unzip();
        dataset(&g, "rev", &rev, "rev", "time in impeller revolutions, step / steps_per_rev")?;
        dataset(
            &g,
            "value",
            &value,
            "1",
            "mean particle centre height <z_p>/H, z_p above the floor z = -0.5",
        )?;
        let s = &stats.steady;
        attr_f64(&g, "steady_window_revs", s.window_revs)?;
        attr_f64(&g, "steady_window_revs_available", s.window_revs_available)?;
        attr_u64(&g, "steady_samples", s.samples as u64)?;
        attr_f64(&g, "slope_per_rev", s.slope_per_rev)?;
        attr_f64(&g, "drift", s.drift)?;
        attr_f64(&g, "tolerance", s.tolerance)?;
        attr_u64(&g, "steady", s.steady as u64)?;
        attr_text(&g, "reason", &s.reason)?;

        let g = file.create_group("volume_fraction")?;
        let p = &stats.volume_fraction;
        dataset(&g, "z_over_h", &p.z_over_h, "1", "bin centre height z/H above the floor")?;
        dataset(
            &g,
            "value",
            &p.value,
            "1",
            "time-averaged solids volume fraction of the horizontal slab, from the particles' tilted shapes",
        )?;
        window(&g)?;
        attr_f64(&g, "bin_width_over_h", p.bin_width_over_h)?;

        let g = file.create_group("kinetic_energy")?;
        let (l, r) = (&stats.kinetic_linear, &stats.kinetic_rotational);
        dataset(&g, "z_over_h", &l.z_over_h, "1", "bin centre height z/H above the floor")?;
        dataset(
            &g,
            "linear",
            &l.value,
            "1",
            "k* = k'/(n m_p v_tip^2/H), k' the time-averaged linear kinetic energy per unit height (by centre)",
        )?;
        dataset(
            &g,
            "rotational",
            &r.value,
            "1",
            "k* of the rotational kinetic energy 1/2 sum I_i omega_i^2 (principal axes)",
        )?;
        window(&g)?;
        attr_f64(&g, "bin_width_over_h", l.bin_width_over_h)?;

        let g = file.create_group("orientation")?;
        let (all, mobile) = (&stats.orientation_all, &stats.orientation_mobile);
        dataset(
            &g,
            "phi",
            &all.phi,
            "rad",
            "bin centre of the angle between the cylinder axis and the vertical",
        )?;
        dataset(&g, "all", &all.pdf, "1/rad", "pdf of the angle, all particles")?;
        dataset(
            &g,
            "mobile",
            &mobile.pdf,
            "1/rad",
            "pdf of the angle, particles with z_p/H > mobile_z_over_h",
        )?;
        dataset(&g, "sin", &stats.orientation_sin.pdf, "1/rad", "sin(phi): the pdf of random orientation")?;
        window(&g)?;
        attr_f64(&g, "bin_width", all.bin_width)?;
        attr_f64(&g, "mobile_z_over_h", stats.options.mobile_z_over_h)?;
        attr_u64(&g, "samples_all", all.samples as u64)?;
        attr_u64(&g, "samples_mobile", mobile.samples as u64)?;

        let g = file.create_group("power")?;
        let col = |k: usize| -> Vec<f64> { stats.power_series.iter().map(|s| [s.0, s.1, s.2][k]).collect() };
        dataset(&g, "rev", &col(0), "rev", "time in impeller revolutions")?;
        dataset(&g, "po_fluid", &col(1), "1", "fluid power number 2 pi N Gamma_f / (rho N^3 D^5)")?;
        dataset(
            &g,
            "po_solids",
            &col(2),
            "1",
            "solids (contact) power number 2 pi N Gamma_c / (rho N^3 D^5)",
        )?;
        if let Some(p) = &stats.power {
            for (name, v) in [
                ("po_fluid", p.po_fluid),
                ("po_solids", p.po_solids),
                ("po", p.po),
                ("po_std", p.po_std),
                ("from_rev", p.from_rev),
                ("to_rev", p.to_rev),
                ("revs_covered", p.revs_covered),
            ] {
                attr_f64(&g, name, v)?;
            }
            attr_u64(&g, "samples", p.samples as u64)?;
            attr_u64(&g, "covered", p.covered as u64)?;
        }
        file.close()?;
        Ok(())
    })
}
