//! # slurry-verification
//!
//! The verification suite of `slurry`, as code: each case in [`cases`] runs the solver on
//! a problem with a known answer (an exact solution, a reference kernel, a conservation law),
//! measures an error, and turns it into [`Check`]s with a tolerance whose reason is written next
//! to it. Convergence cases sweep at least four resolutions, print one error row per resolution
//! ([`Table`]), fit the observed order, and compare their table with the committed one under
//! `verification/ref/<case>-<tier>.ref` ([`reftable`]), so that a change in the numbers shows up
//! in review.
//!
//! Run it with `cargo xtask verify` (or `cargo run --release -p slurry-verification --bin
//! slurry-verify -- --help`). The report (`target/verification/report.json`) is a JSON array with
//! one object per check: `case`, `metric`, `value`, `expected`, `tolerance`, `pass`, `reason`.
//!
//! Cases (each module's `//!` header gives the physics, the reference, the metric and the
//! tolerance with its reason):
//! - [`cases::poiseuille`]: force-driven channel flow, BGK (second order) and TRT (exact);
//! - [`cases::couette`]: steady (exact) and impulsively started (second order) shear flow;
//! - [`cases::taylor_green`]: decaying vortex array, viscosity from the decay rate, second order;
//! - [`cases::fused_vs_reference`]: the fused AA kernel equals the two-lattice oracle bitwise;
//! - [`cases::mass_conservation`]: mass (and momentum) conserved to round-off;
//! - [`cases::ibm_transfer`]: IBM kernels' moment conditions, interpolation/spreading adjoint,
//!   spreading bitwise identical for any thread count; cost per marker;
//! - [`cases::quaternion_norm`]: rigid-body quaternion norm drift over 10⁶ torque-free steps;
//! - [`cases::torque_free`]: torque-free tops: energy and angular momentum to second order,
//!   Dzhanibekov flip near the intermediate axis only, free precession against the exact solution;
//! - [`cases::stokes_drag`]: IBM drag of a periodic array of fixed spheres against Zick & Homsy,
//!   with the calibrated retraction of the forcing markers (and the uncalibrated first-order
//!   study);
//! - [`cases::ten_cate`]: the settling sphere of ten Cate et al. (2002), cases E1–E4, peak
//!   velocity against the measured one (validation of the retraction, calibrated elsewhere);
//! - [`cases::free_particles`]: free bodies at γ = 1.25: a sphere spinning at half the shear rate,
//!   a falling cylinder's momentum budget;
//! - [`cases::contacts_dry`]: dry collisions with the contacts of Table 1: momentum, energy,
//!   restitution, closest approach;
//! - [`cases::implicit_damping`]: backward-Euler contact damping against the explicit scheme
//!   converged in sub-steps: first order in the sub-step, stable at one sub-step;
//! - [`cases::wet_lubrication`]: a sphere settling onto a fixed sphere in fluid: it slows before
//!   contact, never overlaps and comes to rest on the contact;
//! - [`cases::impeller`]: impellers' marker areas and normals; the single-phase torque budget,
//!   power number and pumping direction at Re = 87;
//! - [`cases::state_pack`]: a restart from a state pack (density, velocity, force field, exact
//!   bodies) against the exact restart on a small stirred tank with particles: velocity field and
//!   bodies after 100 steps.

pub mod backend;
pub mod cases;
pub mod fit;
pub mod reftable;
pub mod report;

pub use report::{Check, Value};

use std::fmt;

/// How much work a run does.
#[derive(Clone, Copy, Debug, PartialEq, Eq, clap::ValueEnum)]
pub enum Tier {
    /// For CI: every case, at resolutions that finish in a few minutes on two cores.
    Quick,
    /// For releases: one or two more resolutions per convergence study.
    Full,
}

impl Tier {
    /// `"quick"` or `"full"`.
    pub fn name(self) -> &'static str {
        match self {
            Tier::Quick => "quick",
            Tier::Full => "full",
        }
    }
}

/// A table of numbers with named columns: one row per resolution in a convergence study.
#[derive(Clone, Debug, PartialEq)]
pub struct Table {
    /// Title, unique within a case (e.g. `"bgk nu=0.1"`).
    pub title: String,
    /// Column names.
    pub columns: Vec<Column>,
    /// Rows of values, one per column.
    pub rows: Vec<Vec<f64>>,
}

/// A column of a [`Table`].
#[derive(Clone, Debug, PartialEq)]
pub struct Column {
    /// Name (no spaces).
    pub name: String,
    /// Whether it is written to the committed `.ref` file and compared with it. Columns at the
    /// round-off level (whose digits are noise) are printed but not compared.
    pub compared: bool,
}

impl Table {
    /// An empty table; `columns` are `(name, compared)` pairs.
    pub fn new(title: impl Into<String>, columns: &[(&str, bool)]) -> Self {
        Self {
            title: title.into(),
            columns: columns.iter().map(|&(n, c)| Column { name: n.to_string(), compared: c }).collect(),
            rows: Vec::new(),
        }
    }

    /// Appends a row (must have one value per column).
    pub fn push(&mut self, row: Vec<f64>) {
        assert_eq!(row.len(), self.columns.len(), "table {}", self.title);
        self.rows.push(row);
    }

    /// The values of column `name`.
    pub fn column(&self, name: &str) -> Vec<f64> {
        let k = self
            .columns
            .iter()
            .position(|c| c.name == name)
            .unwrap_or_else(|| panic!("table {} has no column {name}", self.title));
        self.rows.iter().map(|r| r[k]).collect()
    }

    /// The same table restricted to its compared columns (what goes into the `.ref` file).
    pub fn compared_part(&self) -> Table {
        let keep: Vec<usize> = (0..self.columns.len()).filter(|&k| self.columns[k].compared).collect();
        Table {
            title: self.title.clone(),
            columns: keep.iter().map(|&k| self.columns[k].clone()).collect(),
            rows: self.rows.iter().map(|r| keep.iter().map(|&k| r[k]).collect()).collect(),
        }
    }
}

/// Formats a number for tables: integers as integers, others with 10 significant digits.
pub fn fmt_num(v: f64) -> String {
    if v.is_finite() && v == v.trunc() && v.abs() < 1e15 {
        format!("{}", v as i64)
    } else {
        format!("{v:.9e}")
    }
}

impl fmt::Display for Table {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        let cells: Vec<Vec<String>> =
            self.rows.iter().map(|r| r.iter().map(|&v| fmt_num(v)).collect()).collect();
        let widths: Vec<usize> = (0..self.columns.len())
            .map(|k| cells.iter().map(|r| r[k].len()).chain([self.columns[k].name.len()]).max().unwrap_or(0))
            .collect();
        writeln!(f, "## {}", self.title)?;
        let head: Vec<String> =
            self.columns.iter().zip(&widths).map(|(c, w)| format!("{:>w$}", c.name, w = w)).collect();
        writeln!(f, "{}", head.join("  "))?;
        for r in &cells {
            let line: Vec<String> = r.iter().zip(&widths).map(|(c, w)| format!("{c:>w$}", w = w)).collect();
            writeln!(f, "{}", line.join("  "))?;
        }
        Ok(())
    }
}

/// What one case produced: its checks and its tables.
#[derive(Clone, Debug, Default)]
pub struct CaseOutput {
    /// Checks, in the order they were made.
    pub checks: Vec<Check>,
    /// Tables (convergence studies, counts), in print order.
    pub tables: Vec<Table>,
    /// Whether the tables are committed as a `.ref` file and compared with it.
    pub has_ref: bool,
}

/// A verification case: a name, a one-line summary, and the function that runs it.
#[derive(Clone, Copy)]
pub struct Case {
    /// Name used by `--case` and in the report.
    pub name: &'static str,
    /// One line for `--list`.
    pub summary: &'static str,
    /// Runs the case at the given tier.
    pub run: fn(Tier) -> CaseOutput,
    /// Whether the case runs on the device too (`--device gpu`, [`backend`]): its flow is the
    /// fluid alone, stepped through [`backend`]'s stepper.
    pub device: bool,
}

/// Directory of the committed reference tables.
pub fn ref_dir() -> std::path::PathBuf {
    workspace_root().join("verification").join("ref")
}

/// The workspace root: the directory above this crate, or `SLURRY_WORKSPACE` when set (a
/// binary built in another checkout, as `benches/scripts/device-check.sh` runs it).
pub fn workspace_root() -> std::path::PathBuf {
    if let Some(root) = std::env::var_os("SLURRY_WORKSPACE").filter(|r| !r.is_empty()) {
        return root.into();
    }
    std::path::Path::new(env!("CARGO_MANIFEST_DIR"))
        .parent()
        .expect("verification/ has a parent")
        .to_path_buf()
}
