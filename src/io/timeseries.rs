//! Scalar time series as CSV, one row per output step.
//!
//! Columns: `step, time, mass, momentum_x, momentum_y, momentum_z, max_mach, mlups`
//! (lattice units; `time = step` since Δt = 1; `mlups` is the throughput of the block of
//! steps that ended at this row, 0 on the first row). Runs with particles add
//! `particle_mean_z, particle_max_speed`, and runs with an impeller
//! `impeller_angle, impeller_omega, torque_fluid, torque_solids, torque_walls, po_fluid,
//! po_solids, po` ([`ImpellerTorques`]), before `mlups` (which stays the last column: the
//! only one that is not physics). Numbers are written in Rust's shortest
//! round-trip form, so `f64` values read back exactly.

use std::fs::{File, OpenOptions};
use std::io::{self, Write};
use std::path::{Path, PathBuf};

use super::atomic::atomic_write_bytes;

/// The CSV header line (without the newline).
pub const HEADER: &str = "step,time,mass,momentum_x,momentum_y,momentum_z,max_mach,mlups";

/// The impeller columns (inserted before `mlups`).
pub const IMPELLER_COLUMNS: &str =
    "impeller_angle,impeller_omega,torque_fluid,torque_solids,torque_walls,po_fluid,po_solids,po";

/// Which optional column groups a time series has.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct Columns {
    /// The particle aggregates.
    pub particles: bool,
    /// The impeller torques.
    pub impeller: bool,
}

impl Columns {
    /// Every combination, for recognising a header.
    const ALL: [Columns; 4] = [
        Columns { particles: false, impeller: false },
        Columns { particles: true, impeller: false },
        Columns { particles: false, impeller: true },
        Columns { particles: true, impeller: true },
    ];
}

/// The complete rows (each ending in a newline) among `lines` whose step is at most `through`,
/// as written: what a resume keeps, and what a state pack carries of a run's series.
pub fn rows_through<'a>(lines: impl Iterator<Item = &'a str>, through: u64) -> String {
    lines
        .filter(|l| l.ends_with('\n'))
        .filter(|l| l.split(',').next().and_then(|s| s.parse::<u64>().ok()).is_some_and(|s| s <= through))
        .collect()
}

/// The header line (without the newline) with the given column groups.
pub fn header_for(c: Columns) -> String {
    let mut h = String::from(HEADER.trim_end_matches(",mlups"));
    if c.particles {
        h.push_str(",particle_mean_z,particle_max_speed");
    }
    if c.impeller {
        h.push(',');
        h.push_str(IMPELLER_COLUMNS);
    }
    h.push_str(",mlups");
    h
}

/// Shortest round-trip form: plain decimal for moderate magnitudes, scientific otherwise
/// (Rust's plain `{}` would spell out 1e-300 with 300 zeros).
fn num(v: f64) -> String {
    let a = v.abs();
    if v == 0.0 || (1e-4..1e16).contains(&a) || !v.is_finite() {
        format!("{v}")
    } else {
        format!("{v:e}")
    }
}

/// One row of the time series.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct TimeSeriesRow {
    /// Time step.
    pub step: u64,
    /// Time (lattice units; equals `step`).
    pub time: f64,
    /// Total mass `Σ ρ`.
    pub mass: f64,
    /// Total momentum `Σ ρ u`.
    pub momentum: [f64; 3],
    /// Largest Mach number `|u|/c_s`.
    pub max_mach: f64,
    /// Million lattice-node updates per second over the preceding block.
    pub mlups: f64,
    /// Particle aggregates (runs with particles only).
    pub particles: Option<ParticleAggregates>,
    /// Impeller torques (runs with an impeller only).
    pub impeller: Option<ImpellerTorques>,
}

/// The impeller's angle, speed and torques about its axis at an output step (the last time
/// step's values; lattice units, fluid density 1). Signs: torques *exerted by* the
/// impeller (positive while it drives the flow for `Ω > 0`), and the torque the fluid exerts
/// on the box walls; at a statistically steady state without particles
/// `torque_fluid ≈ torque_walls`.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ImpellerTorques {
    /// Angle turned since `t = 0`, radians.
    pub angle: f64,
    /// Angular speed `Ω`, radians per step.
    pub omega: f64,
    /// `Γ_f`: torque on the fluid through the immersed-boundary forces on the impeller's
    /// markers, `Σ_m ((X_m − x_c) × F_m)_z`.
    pub fluid: f64,
    /// `Γ_c`: torque on the particles through the particle–impeller contacts (the paper's
    /// solids torque).
    pub solids: f64,
    /// Torque of the fluid on the box walls about the impeller axis (momentum exchange).
    pub walls: f64,
    /// `Po_f = 2πNΓ_f/(ρN³D⁵)` with the nominal `N` (after the ramp).
    pub po_fluid: f64,
    /// `Po_c = 2πNΓ_c/(ρN³D⁵)`.
    pub po_solids: f64,
    /// `Po = Po_f + Po_c`.
    pub po: f64,
}

/// Per-output-step particle aggregates in the time series.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ParticleAggregates {
    /// Mean height `⟨z_p⟩` of the particle centres.
    pub mean_z: f64,
    /// Largest particle speed `max |v_p|`.
    pub max_speed: f64,
}

impl ParticleAggregates {
    /// The aggregates of particles with centres `z` and velocities `v`.
    pub fn of(positions: &[[f64; 3]], velocities: &[[f64; 3]]) -> Self {
        let n = positions.len().max(1) as f64;
        Self {
            mean_z: positions.iter().map(|p| p[2]).sum::<f64>() / n,
            max_speed: velocities
                .iter()
                .map(|v| (v[0] * v[0] + v[1] * v[1] + v[2] * v[2]).sqrt())
                .fold(0.0, f64::max),
        }
    }
}

impl TimeSeriesRow {
    /// The CSV line (with the trailing newline).
    pub fn to_csv_line(&self) -> String {
        let mut particles = match self.particles {
            Some(p) => format!("{},{},", num(p.mean_z), num(p.max_speed)),
            None => String::new(),
        };
        if let Some(t) = self.impeller {
            for v in [t.angle, t.omega, t.fluid, t.solids, t.walls, t.po_fluid, t.po_solids, t.po] {
                particles.push_str(&num(v));
                particles.push(',');
            }
        }
        format!(
            "{},{},{},{},{},{},{},{particles}{}\n",
            self.step,
            num(self.time),
            num(self.mass),
            num(self.momentum[0]),
            num(self.momentum[1]),
            num(self.momentum[2]),
            num(self.max_mach),
            num(self.mlups)
        )
    }
}

/// Appends rows to a CSV file whose header was written atomically.
#[derive(Debug)]
pub struct TimeSeriesWriter {
    path: PathBuf,
    file: File,
    columns: Columns,
}

impl TimeSeriesWriter {
    /// Creates (or replaces) the file with just the header, atomically, and opens it for
    /// appending.
    pub fn create(path: &Path) -> io::Result<Self> {
        Self::create_with(path, false)
    }

    /// [`TimeSeriesWriter::create`] with the particle columns when `particles` is set.
    pub fn create_with(path: &Path, particles: bool) -> io::Result<Self> {
        Self::create_columns(path, Columns { particles, impeller: false })
    }

    /// [`TimeSeriesWriter::create`] with the given optional column groups.
    pub fn create_columns(path: &Path, columns: Columns) -> io::Result<Self> {
        atomic_write_bytes(path, format!("{}\n", header_for(columns)).as_bytes())?;
        let file = OpenOptions::new().append(true).open(path)?;
        Ok(Self { path: path.to_path_buf(), file, columns })
    }

    /// The optional column groups of this file.
    pub fn columns(&self) -> Columns {
        self.columns
    }

    /// Re-opens an existing time series for a resumed run: keeps the header and the complete
    /// rows with `step <= through_step` (later rows belong to work lost after the checkpoint),
    /// rewrites the file atomically and opens it for appending.
    pub fn resume(path: &Path, through_step: u64) -> io::Result<Self> {
        let old = std::fs::read_to_string(path)?;
        let mut lines = old.split_inclusive('\n');
        let first = lines.next().map(str::trim_end);
        let Some(columns) = Columns::ALL.into_iter().find(|c| first == Some(header_for(*c).as_str())) else {
            return Err(io::Error::new(
                io::ErrorKind::InvalidData,
                format!("{}: not a slurry time series (unexpected header)", path.display()),
            ));
        };
        let kept = format!("{}\n{}", header_for(columns), rows_through(lines, through_step));
        atomic_write_bytes(path, kept.as_bytes())?;
        let file = OpenOptions::new().append(true).open(path)?;
        Ok(Self { path: path.to_path_buf(), file, columns })
    }

    /// Appends one row as a single write and flushes it. The row must carry particle
    /// aggregates (impeller torques) exactly when the file has the particle (impeller)
    /// columns.
    pub fn append(&mut self, row: &TimeSeriesRow) -> io::Result<()> {
        if row.particles.is_some() != self.columns.particles
            || row.impeller.is_some() != self.columns.impeller
        {
            return Err(io::Error::new(
                io::ErrorKind::InvalidInput,
                format!(
                    "{}: row and header disagree on the particle or impeller columns",
                    self.path.display()
                ),
            ));
        }
        self.file.write_all(row.to_csv_line().as_bytes())?;
        self.file.flush()
    }

    /// Syncs the file to disk (call at the end of a run).
    pub fn sync(&self) -> io::Result<()> {
        self.file.sync_all()
    }

    /// The file's path.
    pub fn path(&self) -> &Path {
        &self.path
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn header_then_rows() {
        let dir = tempfile::tempdir().unwrap();
        let p = dir.path().join("ts.csv");
        let mut w = TimeSeriesWriter::create(&p).unwrap();
        for step in [0, 10] {
            w.append(&TimeSeriesRow {
                step,
                time: step as f64,
                mass: 64.0 + 1e-13,
                momentum: [0.1, -0.0, 1e-300],
                max_mach: 0.01,
                mlups: 1.5,
                particles: None,
                impeller: None,
            })
            .unwrap();
        }
        w.sync().unwrap();
        let text = std::fs::read_to_string(&p).unwrap();
        let lines: Vec<&str> = text.lines().collect();
        assert_eq!(lines.len(), 3);
        assert_eq!(lines[0], HEADER);
        let cols: Vec<&str> = lines[2].split(',').collect();
        assert_eq!(cols.len(), HEADER.split(',').count());
        assert_eq!(cols[0], "10");
        assert_eq!(cols[2].parse::<f64>().unwrap(), 64.0 + 1e-13);
        assert_eq!(cols[5], "1e-300");
        assert_eq!(cols[4], "-0");
        assert_eq!(num(6.5e-6), "6.5e-6");
        assert_eq!(num(512.0), "512");
    }

    #[test]
    fn particle_columns_come_before_mlups() {
        let dir = tempfile::tempdir().unwrap();
        let p = dir.path().join("ts.csv");
        let mut w = TimeSeriesWriter::create_with(&p, true).unwrap();
        let mut row = TimeSeriesRow {
            step: 5,
            time: 5.0,
            mass: 1.0,
            momentum: [0.0; 3],
            max_mach: 0.0,
            mlups: 2.0,
            particles: Some(ParticleAggregates::of(&[[0.0, 0.0, 2.0], [0.0, 0.0, 4.0]], &[[3.0, 4.0, 0.0]])),
            impeller: None,
        };
        w.append(&row).unwrap();
        row.particles = None;
        assert!(w.append(&row).is_err());
        let text = std::fs::read_to_string(&p).unwrap();
        let lines: Vec<&str> = text.lines().collect();
        assert_eq!(
            lines,
            [header_for(Columns { particles: true, impeller: false }).as_str(), "5,5,1,0,0,0,0,3,5,2"]
        );
        let w = TimeSeriesWriter::resume(&p, 5).unwrap();
        assert!(w.columns().particles);
    }

    #[test]
    fn impeller_columns_after_particles_and_resume() {
        let dir = tempfile::tempdir().unwrap();
        let p = dir.path().join("ts.csv");
        let cols = Columns { particles: true, impeller: true };
        let mut w = TimeSeriesWriter::create_columns(&p, cols).unwrap();
        let t = ImpellerTorques {
            angle: 1.0,
            omega: 0.5,
            fluid: 2.0,
            solids: 0.25,
            walls: 1.5,
            po_fluid: 3.0,
            po_solids: 0.5,
            po: 3.5,
        };
        let mut row = TimeSeriesRow {
            step: 4,
            time: 4.0,
            mass: 1.0,
            momentum: [0.0; 3],
            max_mach: 0.0,
            mlups: 2.0,
            particles: Some(ParticleAggregates { mean_z: 3.0, max_speed: 5.0 }),
            impeller: Some(t),
        };
        w.append(&row).unwrap();
        row.step = 8;
        w.append(&row).unwrap();
        row.impeller = None;
        assert!(w.append(&row).is_err(), "a row without the impeller columns is refused");
        let text = std::fs::read_to_string(&p).unwrap();
        let lines: Vec<&str> = text.lines().collect();
        assert_eq!(lines[0], header_for(cols));
        assert!(
            lines[0].starts_with("step,time,mass,momentum_x,momentum_y,momentum_z,max_mach,particle_mean_z,")
        );
        assert!(lines[0].ends_with("particle_max_speed,impeller_angle,impeller_omega,torque_fluid,torque_solids,torque_walls,po_fluid,po_solids,po,mlups"));
        assert_eq!(lines[1], "4,4,1,0,0,0,0,3,5,1,0.5,2,0.25,1.5,3,0.5,3.5,2");
        let w = TimeSeriesWriter::resume(&p, 4).unwrap();
        assert_eq!(w.columns(), cols);
        assert_eq!(std::fs::read_to_string(&p).unwrap().lines().count(), 2);
    }
}
