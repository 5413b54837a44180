//! Scalar time series as CSV, one row per output step.
//!
//! Columns: `step, time, mass, momentum_x, momentum_y, momentum_z, max_mach, mlups`
//! (lattice units; `time = step` since Δt = 1; `mlups` is the throughput of the block of
//! steps that ended at this row, 0 on the first row). Runs with particles add
//! `particle_mean_z, particle_max_speed` before `mlups` (which stays the last column: the
//! only one that is not physics). Numbers are written in Rust's shortest
//! round-trip form, so `f64` values read back exactly.

use std::fs::{File, OpenOptions};
use std::io::{self, Write};
use std::path::{Path, PathBuf};

use super::atomic::atomic_write_bytes;

/// The CSV header line (without the newline).
pub const HEADER: &str = "step,time,mass,momentum_x,momentum_y,momentum_z,max_mach,mlups";

/// The CSV header of a run with particles.
pub const PARTICLE_HEADER: &str =
    "step,time,mass,momentum_x,momentum_y,momentum_z,max_mach,particle_mean_z,particle_max_speed,mlups";

/// The header for a run with or without particles.
pub fn header(particles: bool) -> &'static str {
    if particles {
        PARTICLE_HEADER
    } else {
        HEADER
    }
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
        let particles = match self.particles {
            Some(p) => format!("{},{},", num(p.mean_z), num(p.max_speed)),
            None => String::new(),
        };
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
    particles: bool,
}

impl TimeSeriesWriter {
    /// Creates (or replaces) the file with just the header, atomically, and opens it for
    /// appending.
    pub fn create(path: &Path) -> io::Result<Self> {
        Self::create_with(path, false)
    }

    /// [`TimeSeriesWriter::create`] with the particle columns when `particles` is set.
    pub fn create_with(path: &Path, particles: bool) -> io::Result<Self> {
        atomic_write_bytes(path, format!("{}\n", header(particles)).as_bytes())?;
        let file = OpenOptions::new().append(true).open(path)?;
        Ok(Self { path: path.to_path_buf(), file, particles })
    }

    /// Re-opens an existing time series for a resumed run: keeps the header and the complete
    /// rows with `step <= through_step` (later rows belong to work lost after the checkpoint),
    /// rewrites the file atomically and opens it for appending.
    pub fn resume(path: &Path, through_step: u64) -> io::Result<Self> {
        let old = std::fs::read_to_string(path)?;
        let mut lines = old.split_inclusive('\n');
        let particles = match lines.next().map(str::trim_end) {
            Some(HEADER) => false,
            Some(PARTICLE_HEADER) => true,
            _ => {
                return Err(io::Error::new(
                    io::ErrorKind::InvalidData,
                    format!("{}: not a slurry time series (unexpected header)", path.display()),
                ))
            }
        };
        let mut kept = format!("{}\n", header(particles));
        for line in lines.filter(|l| l.ends_with('\n')) {
            match line.split(',').next().and_then(|s| s.parse::<u64>().ok()) {
                Some(step) if step <= through_step => kept.push_str(line),
                _ => {}
            }
        }
        atomic_write_bytes(path, kept.as_bytes())?;
        let file = OpenOptions::new().append(true).open(path)?;
        Ok(Self { path: path.to_path_buf(), file, particles })
    }

    /// Appends one row as a single write and flushes it. The row must carry particle
    /// aggregates exactly when the file has the particle columns.
    pub fn append(&mut self, row: &TimeSeriesRow) -> io::Result<()> {
        if row.particles.is_some() != self.particles {
            return Err(io::Error::new(
                io::ErrorKind::InvalidInput,
                format!("{}: row and header disagree on the particle columns", self.path.display()),
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
        };
        w.append(&row).unwrap();
        row.particles = None;
        assert!(w.append(&row).is_err());
        let text = std::fs::read_to_string(&p).unwrap();
        let lines: Vec<&str> = text.lines().collect();
        assert_eq!(lines, [PARTICLE_HEADER, "5,5,1,0,0,0,0,3,5,2"]);
        let w = TimeSeriesWriter::resume(&p, 5).unwrap();
        assert!(w.particles);
    }
}
