//! Statistics, figures and `report.md` of a reproduction run.
//!
//! Everything here is computed from the run's files (`run/timeseries.csv`,
//! `run/particles.h5`, `run/fields.h5` and its `fields-STEP.h5` snapshots), deterministically, and written atomically:
//!
//! | file | contents |
//! |---|---|
//! | `statistics.h5` | ⟨z_p⟩/H series, profiles, orientation pdfs, power averages ([`crate::stats`]) |
//! | `statistics.json` | the scalar results, how the run started (`start`: `{"kind": "dry-bed"}`, `"wet-bed"` or `"start-from"` with the source), and the comparison with the paper |
//! | `midplane.h5`, `midplane.xmf` | the last step's velocity on the vertical plane through the axis (ParaView) |
//! | `fig03_midplane` or `fig04_midplane` `.png/.svg` | the paper's Figure 3 (disk) or 4 (PBT): \|u\|/v_tip on that plane with the cylinders' sections, at the end |
//! | `fig03_midplane_rev010`, `…_rev090` (disk) or `fig04_…` (PBT) | the same at 10 and 90 revolutions after the impeller's start, as in the paper (from the run's `fields-STEP.h5` snapshots, when the run reached them) |
//! | `fig05_mean_height` | ⟨z_p⟩/H against revolutions |
//! | `fig06_volume_fraction` | time-averaged solids volume fraction against z/H |
//! | `fig07_kinetic_energy` | k* of linear and rotational motion against z/H |
//! | `fig08_orientation` | pdf of φ, all particles and z_p > 0.2H, with sin φ |
//! | `fig09_orientation_mobile` | pdf of φ for z_p > 0.2H, with sin φ |
//! | `fig10_power` | Po_f, Po_c and their sum against revolutions |
//! | `report.md` | the run, the steady-state test, the table against the paper, the figures |

use std::f64::consts::PI;
use std::fmt::Write as _;
use std::path::Path;

use anyhow::Context;
use serde::{Deserialize, Serialize};

use super::{BedRecord, RunRecord};
use crate::stats::{self, Stats, StatsOptions, Tank};
use slurry::case::Case;
use slurry::io::atomic_write_bytes;
use slurry::plot::{self, FieldImage, FieldSize, LegendPosition, LinePlot, Series, SeriesStyle};
use slurry::run::RunSummary;

/// `reproduce/<case>/paper.toml`: the paper's values for a case, with acceptance bands.
#[derive(Clone, Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct PaperValues {
    /// Case name.
    pub case: String,
    /// `"disk"` or `"pbt"`.
    pub impeller: String,
    /// `ℓ/d`.
    pub aspect_ratio: f64,
    /// Particle count.
    pub particles: usize,
    /// The compared values.
    #[serde(rename = "value")]
    pub values: Vec<PaperValue>,
}

/// One compared value.
#[derive(Clone, Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct PaperValue {
    /// Which statistic: `mean_height`, `po_fluid`, `po_solids` or `po`.
    pub key: String,
    /// Its name in the report.
    pub label: String,
    /// The paper's value, when it gives one.
    pub paper: Option<f64>,
    /// Lower end of the acceptance band.
    pub min: Option<f64>,
    /// Upper end of the acceptance band.
    pub max: Option<f64>,
    /// Where the paper gives it.
    pub source: String,
    /// Why the band is what it is.
    pub reason: String,
}

/// Revolutions of the time-averaged profiles (the paper: 10, "after the flow has reached
/// dynamic steady state").
pub const PROFILE_REVOLUTIONS: f64 = 10.0;
/// Revolutions of the power averages (the paper's Figure 10 and Table 2: the last 30).
pub const POWER_REVOLUTIONS: f64 = 30.0;
/// Revolutions of the steady-state test on ⟨z_p⟩/H.
pub const STEADY_REVOLUTIONS: f64 = 20.0;
/// Largest drift of ⟨z_p⟩/H over [`STEADY_REVOLUTIONS`] (and largest standard error of it)
/// that counts as steady ([`stats::steady_state`]): a sixth of the acceptance band of the
/// paper's values (±0.03). A test of `|drift| ≤ 0.015` (older versions) passes runs still
/// rising by 5e-4 per revolution (disk-ld1 and disk-ld2 at s = 1/4 after 130 revolutions,
/// pbt-ld2 at s = 1/3 after 100); one that allows twice the drift's standard error beyond 0.005
/// (older versions) passes slower rises (`reproduce/JOURNAL.md`, "The steady test").
pub const STEADY_DRIFT: f64 = 0.005;
/// Profile bins per particle diameter (the paper: "finer than the diameter").
pub const BINS_PER_DIAMETER: f64 = 4.0;
/// Bins of the orientation pdfs over [0, π/2].
pub const ORIENTATION_BINS: usize = 18;
/// The paper's threshold between bed and mobile particles, `z_p > 0.2 H`.
pub const MOBILE_HEIGHT: f64 = 0.2;

/// The tank of a stirred case, and its impeller.
pub(crate) fn tank_of(case: &Case) -> anyhow::Result<(Tank, slurry::case::ImpellerSetup)> {
    let setup = case
        .impeller_setup()
        .map_err(|k| anyhow::anyhow!("{k}"))?
        .ok_or_else(|| anyhow::anyhow!("the case has no impeller"))?;
    let grid = case.grid();
    let tank = Tank {
        t: grid.nx as f64,
        h: grid.nz as f64,
        tip_speed: setup.tip_speed(),
        steps_per_rev: 1.0 / setup.speed().abs(),
    };
    Ok((tank, setup))
}

/// The report's steady test ([`stats::steady_state`] of `⟨z_p⟩/H` over the last
/// [`STEADY_REVOLUTIONS`], tolerance [`STEADY_DRIFT`]) on the particle history of the finished
/// run of the stirred case `case` in `run_dir`: what `--until-steady` stops on, and the verdict
/// [`write_all`] then reports, from the same frames.
///
/// # Errors
/// The case has no impeller, or `particles.h5` cannot be read.
pub fn steady_test(case: &Case, run_dir: &Path) -> anyhow::Result<stats::SteadyTest> {
    let (tank, _) = tank_of(case)?;
    let path = run_dir.join(slurry::run::files::PARTICLES_H5);
    let hist = slurry::io::read_particle_history(&path)
        .with_context(|| format!("cannot read {}", path.display()))?;
    let series = read_timeseries(&run_dir.join(slurry::run::files::TIMESERIES), tank.h, tank.steps_per_rev)?;
    let mean = stats::joined_mean_height(&series.height_points(), &hist.frames, &tank);
    Ok(stats::steady_state(&mean, STEADY_REVOLUTIONS, STEADY_DRIFT))
}

/// The paper's figure of the mid-plane for an impeller: 3 for the disk, 4 for the PBT.
pub(crate) fn midplane_figure_number(impeller: &str) -> u32 {
    if impeller == "disk" {
        3
    } else {
        4
    }
}

/// The file stem of a run's mid-plane figure: `fig03_midplane` (disk) or `fig04_midplane`
/// (PBT), and with `revs` its snapshot at that many revolutions (`fig03_midplane_rev010`).
/// The report writes them; the summary and `--overwrite` find them by it.
pub(crate) fn midplane_stem(impeller: &str, revs: Option<f64>) -> String {
    let stem = format!("fig{:02}_midplane", midplane_figure_number(impeller));
    match revs {
        Some(r) => format!("{stem}_rev{r:03.0}"),
        None => stem,
    }
}

/// The impeller columns of `timeseries.csv` by revolution.
#[derive(Clone, Debug, Default)]
pub struct TimeSeries {
    /// Revolutions turned (`impeller_angle / 2π`).
    pub revolutions: Vec<f64>,
    /// Time in units of `1/N` (`step · N`), the axis of the particle statistics.
    pub time: Vec<f64>,
    /// `⟨z_p⟩/H` (floor at `z = −½`).
    pub mean_height: Vec<f64>,
    /// `Po_f`.
    pub po_fluid: Vec<f64>,
    /// `Po_c`.
    pub po_solids: Vec<f64>,
    /// The throughput of the block of steps each row closes (`mlups`; NaN where the file has
    /// no such column).
    pub mlups: Vec<f64>,
}

/// Reads the impeller and particle columns of `timeseries.csv` (a box of height `h = nz`).
///
/// # Errors
/// A missing file or column, or a number that does not parse.
pub fn read_timeseries(path: &Path, h: f64, steps_per_rev: f64) -> anyhow::Result<TimeSeries> {
    let text = std::fs::read_to_string(path).with_context(|| format!("cannot read {}", path.display()))?;
    parse_timeseries(&text, path, h, steps_per_rev)
}

impl TimeSeries {
    /// `(time, ⟨z_p⟩/H)` of every row, time in revolutions (`1/N`), as the particle frames.
    pub fn height_points(&self) -> Vec<(f64, f64)> {
        self.time.iter().copied().zip(self.mean_height.iter().copied()).collect()
    }

    /// The step of the last row (`time` is `step / steps_per_rev`: the rounding recovers the
    /// integer step), or `None` for a series without rows.
    pub fn last_step(&self, steps_per_rev: f64) -> Option<f64> {
        self.time.last().map(|t| (t * steps_per_rev).round())
    }
}

/// [`read_timeseries`] of the text of `timeseries.csv` (`path` names it in errors).
///
/// # Errors
/// A missing column, or a number that does not parse.
pub fn parse_timeseries(text: &str, path: &Path, h: f64, steps_per_rev: f64) -> anyhow::Result<TimeSeries> {
    let mut lines = text.lines();
    let header: Vec<&str> = lines.next().unwrap_or_default().split(',').collect();
    let col = |name: &str| {
        header
            .iter()
            .position(|c| *c == name)
            .ok_or_else(|| anyhow::anyhow!("{}: no column {name}", path.display()))
    };
    let (is, ia, iz) = (col("step")?, col("impeller_angle")?, col("particle_mean_z")?);
    let (if_, ic) = (col("po_fluid")?, col("po_solids")?);
    let im = col("mlups").ok();
    let mut timeseries = TimeSeries::default();
    for (k, line) in lines.enumerate() {
        let f: Vec<&str> = line.split(',').collect();
        let num = |i: usize| -> anyhow::Result<f64> {
            f.get(i).and_then(|s| s.parse().ok()).ok_or_else(|| {
                anyhow::anyhow!("{}: row {}: column {i} is not a number", path.display(), k + 2)
            })
        };
        timeseries.time.push(num(is)? / steps_per_rev);
        timeseries.revolutions.push(num(ia)? / (2.0 * PI));
        timeseries.mean_height.push((num(iz)? + 0.5) / h);
        timeseries.po_fluid.push(num(if_)?);
        timeseries.po_solids.push(num(ic)?);
        timeseries.mlups.push(im.and_then(|i| f.get(i)).and_then(|s| s.parse().ok()).unwrap_or(f64::NAN));
    }
    Ok(timeseries)
}

/// The velocity magnitude on the plane `y = j` of `fields.h5`: `(values, nx, nz)`, row `k`
/// (height) after row `k − 1`, x fastest.
///
/// # Errors
/// The file or its `velocity` dataset cannot be read, or `j` is outside it.
pub fn midplane_speed(path: &Path, j: usize) -> anyhow::Result<(Vec<f64>, usize, usize)> {
    let f = hdf5::File::open(path).with_context(|| format!("cannot open {}", path.display()))?;
    let v = f.dataset("velocity").with_context(|| format!("{}: no velocity", path.display()))?;
    let shape = v.shape();
    anyhow::ensure!(shape.len() == 4 && j < shape[1], "{}: velocity has shape {shape:?}", path.display());
    let (nz, nx) = (shape[0], shape[2]);
    let plane: ndarray::Array3<f64> = v
        .read_slice(ndarray::s![.., j, .., ..])
        .with_context(|| format!("cannot read the plane y = {j} of {}", path.display()))?;
    let mut out = Vec::with_capacity(nx * nz);
    for k in 0..nz {
        for i in 0..nx {
            let u = [plane[[k, i, 0]], plane[[k, i, 1]], plane[[k, i, 2]]];
            out.push((u[0] * u[0] + u[1] * u[1] + u[2] * u[2]).sqrt());
        }
    }
    Ok((out, nx, nz))
}

/// Writes the mid-plane speed as `midplane.h5` (`/speed`, `f64[nz][1][nx]`) with
/// `midplane.xmf` (a one-node-thick 3-D mesh at `y = j`, for ParaView).
fn write_midplane(
    out: &Path,
    speed: &[f64],
    nx: usize,
    nz: usize,
    j: usize,
    step: u64,
) -> anyhow::Result<()> {
    let h5 = out.join("midplane.h5");
    slurry::io::atomic_write(&h5, |tmp| -> Result<(), slurry::io::FieldsError> {
        let file = hdf5::File::create(tmp)?;
        file.new_attr::<u64>().shape(()).create("time_step")?.write_scalar(&step)?;
        file.new_attr::<u64>().shape(()).create("y")?.write_scalar(&(j as u64))?;
        let d = file.new_dataset::<f64>().shape([nz, 1, nx]).create("speed")?;
        d.write_raw(speed)?;
        Ok(())
    })
    .with_context(|| format!("cannot write {}", h5.display()))?;
    let xmf = format!(
        "<?xml version=\"1.0\" ?>\n<Xdmf Version=\"3.0\">\n <Domain>\n  <Grid Name=\"midplane\" GridType=\"Uniform\">\n   \
         <Time Value=\"{step}\"/>\n   <Topology TopologyType=\"3DCoRectMesh\" Dimensions=\"{nz} 1 {nx}\"/>\n   \
         <Geometry GeometryType=\"ORIGIN_DXDYDZ\">\n    <DataItem Dimensions=\"3\" Format=\"XML\">0 {j} 0</DataItem>\n    \
         <DataItem Dimensions=\"3\" Format=\"XML\">1 1 1</DataItem>\n   </Geometry>\n   \
         <Attribute Name=\"speed\" AttributeType=\"Scalar\" Center=\"Node\">\n    \
         <DataItem Dimensions=\"{nz} 1 {nx}\" NumberType=\"Float\" Precision=\"8\" Format=\"HDF\">midplane.h5:/speed</DataItem>\n   \
         </Attribute>\n  </Grid>\n </Domain>\n</Xdmf>\n"
    );
    let p = out.join("midplane.xmf");
    atomic_write_bytes(&p, xmf.as_bytes()).with_context(|| format!("cannot write {}", p.display()))
}

/// One row of the comparison with the paper (`statistics.json`'s `comparison`).
#[derive(Clone, Debug, Serialize, Deserialize)]
pub struct Comparison {
    /// Statistic key.
    pub key: String,
    /// Its name.
    pub label: String,
    /// This run's value.
    pub value: f64,
    /// The paper's value.
    pub paper: Option<f64>,
    /// `value − paper`.
    pub deviation: Option<f64>,
    /// The band.
    pub min: Option<f64>,
    /// The band.
    pub max: Option<f64>,
    /// Whether the value lies in the band.
    pub in_band: bool,
    /// Whether the quantity's window reached steady state (the steady-state test).
    pub steady: bool,
    /// Revolutions the value was averaged over.
    pub window_revolutions: f64,
}

/// The scalar results of a run (`statistics.json`; the regression snapshot is taken of it).
#[derive(Clone, Debug, Serialize)]
pub struct Results {
    /// Case.
    pub case: String,
    /// Scale.
    pub scale: f64,
    /// Time at the end in units of `1/N`, `t N` (the paper's time axis,
    /// [`Tank::revolutions`]); the ramp counts at the nominal speed, so `t N` exceeds the
    /// revolutions turned by half the ramp's length times `N`.
    pub revolutions: f64,
    /// ⟨z_p⟩/H at the end.
    pub mean_height_final: f64,
    /// ⟨z_p⟩/H averaged over the last [`STEADY_REVOLUTIONS`] (or what there is).
    pub mean_height: f64,
    /// The steady-state test: steady or not.
    pub steady: bool,
    /// Its drift of ⟨z_p⟩/H over the window.
    pub steady_drift: f64,
    /// The drift's standard error from batch means ([`stats::SteadyTest::drift_se`]; absent
    /// from reports written by older versions).
    pub steady_drift_se: f64,
    /// Its verdict in words.
    pub steady_reason: String,
    /// Power averages over the last [`POWER_REVOLUTIONS`] (or what there is): Po_f.
    pub po_fluid: f64,
    /// Po_c.
    pub po_solids: f64,
    /// Po.
    pub po: f64,
    /// Standard deviation of Po.
    pub po_std: f64,
    /// The power window, revolutions `(from, to)`, and its sample count.
    pub power_window: (f64, f64, usize),
    /// Whether the series covers the whole power window ([`stats::PowerAverages::covered`]:
    /// long enough, and without a lost stretch).
    pub power_covered: bool,
    /// How the run started ([`super::BedRecord::start`]). Absent from reports written by older
    /// versions (all of which started from a dry bed).
    pub start: super::start::RunStart,
    /// The comparison with the paper.
    pub comparison: Vec<Comparison>,
    /// The profiles and series.
    #[serde(skip)]
    pub stats: stats::Stats,
}

/// `x` to 6 significant digits (the snapshot's number format).
fn sig6(x: f64) -> String {
    if x == 0.0 {
        "0".into()
    } else if !x.is_finite() {
        format!("{x}")
    } else {
        format!("{x:.5e}")
    }
}

impl Results {
    /// The statistics as text for the regression snapshot: scalars, the ⟨z_p⟩/H series, the
    /// profiles and pdfs, each number to 6 significant digits.
    pub fn snapshot_text(&self) -> String {
        let mut t = String::new();
        let _ = writeln!(t, "case {} scale {} revolutions {}", self.case, self.scale, sig6(self.revolutions));
        let _ = writeln!(
            t,
            "mean_height_final {} mean_height {}",
            sig6(self.mean_height_final),
            sig6(self.mean_height)
        );
        let _ = writeln!(
            t,
            "power po_fluid {} po_solids {} po {} std {} samples {}",
            sig6(self.po_fluid),
            sig6(self.po_solids),
            sig6(self.po),
            sig6(self.po_std),
            self.power_window.2
        );
        let _ = writeln!(t, "steady {} drift {}", self.steady, sig6(self.steady_drift));
        // The series of the steady test's window: a run continued from a state pack that
        // carries its run's history has the whole run's series, hundreds of revolutions.
        let _ = writeln!(t, "\n<z_p>/H series, last {STEADY_REVOLUTIONS} revolutions (rev, value)");
        let last = self.stats.mean_height.last().map_or(0.0, |p| p.0);
        for (r, z) in self.stats.mean_height.iter().filter(|p| p.0 >= last - STEADY_REVOLUTIONS - 1e-9) {
            let _ = writeln!(t, "{} {}", sig6(*r), sig6(*z));
        }
        let pdf = |p: &stats::AnglePdf| (p.phi.clone(), p.pdf.clone());
        let prof = |p: &stats::Profile| (p.z_over_h.clone(), p.value.clone());
        for (name, (xs, vs)) in [
            ("volume fraction (z/H, phi)", prof(&self.stats.volume_fraction)),
            ("k* linear (z/H, k*)", prof(&self.stats.kinetic_linear)),
            ("k* rotational (z/H, k*)", prof(&self.stats.kinetic_rotational)),
            ("orientation pdf, all (phi, pdf)", pdf(&self.stats.orientation_all)),
            ("orientation pdf, z_p > 0.2H (phi, pdf)", pdf(&self.stats.orientation_mobile)),
        ] {
            let _ = writeln!(t, "\n{name}");
            for (x, v) in xs.iter().zip(&vs) {
                if *v != 0.0 {
                    let _ = writeln!(t, "{} {}", sig6(*x), sig6(*v));
                }
            }
        }
        t
    }
}

fn mean_over_last(rev: &[f64], v: &[f64], last: f64) -> f64 {
    let end = rev.last().copied().unwrap_or(0.0);
    let (s, n) = rev
        .iter()
        .zip(v)
        .filter(|(r, _)| **r >= end - last)
        .fold((0.0, 0usize), |(s, n), (_, x)| (s + x, n + 1));
    s / n.max(1) as f64
}

/// Writes the statistics, figures and `report.md` into `out` (module docs) from the run's
/// files in `out/run` and what was run (`summary`), and returns the scalar results.
///
/// # Errors
/// Reading the run's output or writing the report failed.
pub fn write_all(
    name: &str,
    case: &Case,
    paper: &PaperValues,
    summary: &RunRecord,
    bed: &BedRecord,
    out: &Path,
) -> anyhow::Result<Results> {
    let run = out.join("run");
    let (tank, setup) = tank_of(case)?;
    let (grid, h) = (case.grid(), tank.h);
    let timeseries = read_timeseries(&run.join(slurry::run::files::TIMESERIES), h, tank.steps_per_rev)?;
    let hist = slurry::io::read_particle_history(&run.join(slurry::run::files::PARTICLES_H5))
        .with_context(|| format!("cannot read {}", run.join(slurry::run::files::PARTICLES_H5).display()))?;
    let frames = &hist.frames;
    anyhow::ensure!(!frames.is_empty(), "particles.h5 has no frames");
    let d = hist.statics[0].diameter;
    let bin = d / BINS_PER_DIAMETER;

    // Statistics.
    // The power series after the ramp, in time units of 1/N (as the particle frames).
    let ramp_end = setup.motion.ramp_steps / tank.steps_per_rev;
    let po_series: Vec<(f64, f64, f64)> = timeseries
        .time
        .iter()
        .zip(&timeseries.po_fluid)
        .zip(&timeseries.po_solids)
        .filter(|((t, _), _)| **t >= ramp_end)
        .map(|((t, f), c)| (*t, *f, *c))
        .collect();
    let options = StatsOptions {
        profile_revs: PROFILE_REVOLUTIONS,
        bin_width: bin,
        angle_bins: ORIENTATION_BINS,
        mobile_z_over_h: MOBILE_HEIGHT,
        steady_window_revs: STEADY_REVOLUTIONS,
        steady_tolerance: STEADY_DRIFT,
        power_revs: POWER_REVOLUTIONS,
    };
    let st = Stats::compute(frames, &hist.statics, &tank, &options, &po_series, &timeseries.height_points())?;
    stats::write_stats_h5(&out.join("statistics.h5"), &st)?;
    let height = st.mean_height.clone();
    let steady = st.steady.clone();
    let power = st.power.clone().ok_or_else(|| anyhow::anyhow!("no power series"))?;

    let revs: Vec<f64> = height.iter().map(|p| p.0).collect();
    let zs: Vec<f64> = height.iter().map(|p| p.1).collect();
    let mean_h = mean_over_last(&revs, &zs, STEADY_REVOLUTIONS);
    let value_of = |key: &str| match key {
        "mean_height" => Some((mean_h, steady.window_revs_available.min(STEADY_REVOLUTIONS))),
        "po_fluid" => Some((power.po_fluid, power.revs_covered)),
        "po_solids" => Some((power.po_solids, power.revs_covered)),
        "po" => Some((power.po, power.revs_covered)),
        _ => None,
    };
    let mut comparison = Vec::new();
    for pv in &paper.values {
        let (value, window) =
            value_of(&pv.key).ok_or_else(|| anyhow::anyhow!("paper.toml: unknown key {}", pv.key))?;
        let in_band = pv.min.is_none_or(|m| value >= m) && pv.max.is_none_or(|m| value <= m);
        comparison.push(Comparison {
            key: pv.key.clone(),
            label: pv.label.clone(),
            value,
            paper: pv.paper,
            deviation: pv.paper.map(|p| value - p),
            min: pv.min,
            max: pv.max,
            in_band,
            steady: steady.steady,
            window_revolutions: window,
        });
    }
    let results = Results {
        case: name.to_string(),
        scale: summary.scale,
        revolutions: revs.last().copied().unwrap_or(0.0),
        mean_height_final: zs.last().copied().unwrap_or(f64::NAN),
        mean_height: mean_h,
        steady: steady.steady,
        steady_drift: steady.drift,
        steady_drift_se: steady.drift_se,
        steady_reason: steady.reason.clone(),
        po_fluid: power.po_fluid,
        po_solids: power.po_solids,
        po: power.po,
        po_std: power.po_std,
        power_window: (power.from_rev, power.to_rev, power.samples),
        power_covered: power.covered,
        start: bed.start(),
        comparison,
        stats: st.clone(),
    };
    let json = serde_json::to_string_pretty(&results).context("cannot serialise the results")?;
    let p = out.join("statistics.json");
    atomic_write_bytes(&p, format!("{json}\n").as_bytes())
        .with_context(|| format!("cannot write {}", p.display()))?;

    // The mid-plane (the vertical plane through the axis, x–z), and the figures.
    let j = setup.centre.y.round().clamp(0.0, (grid.ny - 1) as f64) as usize;
    let (speed, nx, nz) = midplane_speed(&run.join(slurry::run::files::FIELDS_H5), j)?;
    write_midplane(out, &speed, nx, nz, j, summary.run.steps)?;
    // The snapshots the run wrote (`[run] snapshots`; a run resumed by an older binary may lack some).
    let mut snapshots = Vec::new();
    for &step in &case.run.snapshots {
        let path = run.join(slurry::run::files::snapshot_h5(step));
        if path.exists() {
            snapshots.push((step, midplane_speed(&path, j)?.0));
        }
    }
    let figs =
        figures(name, paper, &tank, &hist, &speed, (nx, nz), j as f64, &snapshots, &timeseries, &st, out)?;
    // A run from a state pack that carried the packed run's time series.
    let joined = bed.state_pack.as_ref().is_some_and(|p| {
        timeseries.time.first().is_some_and(|t| (t * tank.steps_per_rev).round() < p.step as f64)
    });
    let md = report_md(name, case, paper, summary, (bed, joined), &results, &figs);
    let p = out.join("report.md");
    atomic_write_bytes(&p, md.as_bytes()).with_context(|| format!("cannot write {}", p.display()))?;
    Ok(results)
}

/// Writes `stem.png` and `stem.svg` of a line plot.
fn line_figure(out: &Path, stem: &str, plot: &LinePlot) -> anyhow::Result<String> {
    plot::write_line_png(&out.join(format!("{stem}.png")), plot, 900, 600)?;
    plot::write_line_svg(&out.join(format!("{stem}.svg")), plot, 900, 600)?;
    Ok(stem.to_string())
}

fn points(p: &stats::Profile) -> Vec<(f64, f64)> {
    p.z_over_h.iter().zip(&p.value).map(|(z, v)| (*v, *z)).collect()
}

/// The liquid speed on the mid-plane `y = y` (`nx × nz`, x fastest).
#[derive(Clone, Copy)]
struct MidPlane<'a> {
    speed: &'a [f64],
    nx: usize,
    nz: usize,
    y: f64,
}

/// Writes `stem.png` and `stem.svg`: `|u|/v_tip` on the mid-plane with the sections of the
/// cylinders of `frame` (Figure 3 or 4 of the paper).
fn midplane_figure(
    out: &Path,
    stem: &str,
    tag: &str,
    tank: &Tank,
    hist: &slurry::io::ParticleHistory,
    frame: &slurry::io::ParticleFrame,
    plane: &MidPlane<'_>,
) -> anyhow::Result<()> {
    let outlines: Vec<Vec<(f64, f64)>> = frame
        .position
        .iter()
        .zip(&frame.quaternion)
        .zip(&hist.statics)
        .filter_map(|((c, q), s)| {
            let q =
                nalgebra::UnitQuaternion::from_quaternion(nalgebra::Quaternion::new(q[0], q[1], q[2], q[3]));
            let a = q * nalgebra::Vector3::z();
            plot::cylinder_section(*c, [a.x, a.y, a.z], s.diameter, s.length, plane.y, 48)
        })
        .map(|poly| poly.into_iter().map(|(x, z)| ((x + 0.5) / tank.t, (z + 0.5) / tank.t)).collect())
        .collect();
    let scaled: Vec<f64> = plane.speed.iter().map(|u| u / tank.tip_speed).collect();
    let revs = frame.step as f64 / tank.steps_per_rev;
    let title = format!("{tag}: |u|/v_tip on the mid-plane, {revs:.1} revolutions");
    let img = FieldImage {
        values: &scaled,
        nx: plane.nx,
        ny: plane.nz,
        extent: (0.0, plane.nx as f64 / tank.t, 0.0, plane.nz as f64 / tank.t),
        vmin: 0.0,
        vmax: 1.0,
        title: &title,
        colorbar_label: "|u| / v_tip",
        x_label: "x / T",
        y_label: "z / T",
        outlines: &outlines,
    };
    plot::write_field_png(&out.join(format!("{stem}.png")), &img, FieldSize::MapWidth(700))?;
    plot::write_field_svg(&out.join(format!("{stem}.svg")), &img, FieldSize::MapWidth(700))?;
    Ok(())
}

/// The paper's Figures 3/4–10 for this run (PNG and SVG); returns `(stem, caption)`.
#[allow(clippy::too_many_arguments)]
fn figures(
    name: &str,
    paper: &PaperValues,
    tank: &Tank,
    hist: &slurry::io::ParticleHistory,
    speed: &[f64],
    (nx, nz): (usize, usize),
    plane_y: f64,
    snapshots: &[(u64, Vec<f64>)],
    timeseries: &TimeSeries,
    st: &stats::Stats,
    out: &Path,
) -> anyhow::Result<Vec<(String, String)>> {
    let mut figs = Vec::new();
    let ld = paper.aspect_ratio;
    let tag = format!("{name} (ℓ/d = {ld})");

    // Figure 3 (disk) / 4 (PBT): |u|/v_tip on the mid-plane with the cylinders' sections, at
    // the end of the run and at the snapshots the run wrote (the paper's 10 and 90 revolutions).
    let number = midplane_figure_number(&paper.impeller);
    let stem = midplane_stem(&paper.impeller, None);
    let last = hist.frames.last().expect("frames checked above");
    let plane = MidPlane { speed, nx, nz, y: plane_y };
    midplane_figure(out, &stem, &tag, tank, hist, last, &plane)?;
    figs.push((
        stem.clone(),
        format!(
            "Figure {number}: liquid speed over the tip speed on the vertical plane through the axis at the end of the \
             run, with the cylinders' sections"
        ),
    ));
    for (step, speed) in snapshots {
        let Some(frame) = hist.frames.iter().find(|f| f.step == *step) else { continue };
        let revs = *step as f64 / tank.steps_per_rev;
        let stem = midplane_stem(&paper.impeller, Some(revs));
        midplane_figure(out, &stem, &tag, tank, hist, frame, &MidPlane { speed, ..plane })?;
        figs.push((
            stem,
            format!("Figure {number} at {revs:.0} revolutions after the impeller's start, as in the paper"),
        ));
    }

    // Figure 5.
    let plot5 = LinePlot {
        title: format!("{tag}: mean height of the particles"),
        x_label: "t N (revolutions)".into(),
        y_label: "⟨z_p⟩ / H".into(),
        series: vec![Series::new(
            "this run",
            timeseries.revolutions.iter().copied().zip(timeseries.mean_height.iter().copied()).collect(),
            SeriesStyle::Line,
        )]
        .into_iter()
        .chain(paper.values.iter().filter(|v| v.key == "mean_height").filter_map(|v| {
            let end = timeseries.revolutions.last().copied().unwrap_or(1.0);
            v.paper.map(|p| {
                Series::new(format!("paper (steady) {p}"), vec![(0.0, p), (end, p)], SeriesStyle::Line)
            })
        }))
        .collect(),
        y_range: Some((0.0, 0.5)),
        legend: LegendPosition::LowerRight,
        ..Default::default()
    };
    figs.push((line_figure(out, "fig05_mean_height", &plot5)?, "Figure 5: ⟨z_p⟩/H against time".into()));

    // Figure 6.
    let plot6 = LinePlot {
        title: format!("{tag}: solids volume fraction, last {PROFILE_REVOLUTIONS} revolutions"),
        x_label: "φ".into(),
        y_label: "z / H".into(),
        series: vec![Series::new("", points(&st.volume_fraction), SeriesStyle::Line)],
        y_range: Some((0.0, 1.0)),
        legend: LegendPosition::Hidden,
        ..Default::default()
    };
    figs.push((
        line_figure(out, "fig06_volume_fraction", &plot6)?,
        format!("Figure 6: time-averaged solids volume fraction (bins of d/{BINS_PER_DIAMETER})"),
    ));

    // Figure 7.
    let plot7 = LinePlot {
        title: format!("{tag}: particle kinetic energy, last {PROFILE_REVOLUTIONS} revolutions"),
        x_label: "k* = k′ / (n m_p v_tip² / H)".into(),
        y_label: "z / H".into(),
        series: vec![
            Series::new("linear", points(&st.kinetic_linear), SeriesStyle::Line),
            Series::new("rotational", points(&st.kinetic_rotational), SeriesStyle::Line),
        ],
        y_range: Some((0.0, 1.0)),
        log_x: true,
        legend: LegendPosition::UpperRight,
        ..Default::default()
    };
    figs.push((
        line_figure(out, "fig07_kinetic_energy", &plot7)?,
        "Figure 7: kinetic energy of linear and rotational motion per unit height".into(),
    ));

    // Figures 8 and 9.
    let pdf = |p: &stats::AnglePdf| p.phi.iter().copied().zip(p.pdf.iter().copied()).collect::<Vec<_>>();
    let plot8 = LinePlot {
        title: format!("{tag}: orientation, last {PROFILE_REVOLUTIONS} revolutions"),
        x_label: "φ (rad)".into(),
        y_label: "pdf".into(),
        series: vec![
            Series::new("all", pdf(&st.orientation_all), SeriesStyle::LinePoints),
            Series::new("z_p > 0.2H", pdf(&st.orientation_mobile), SeriesStyle::LinePoints),
            Series::new("sin φ", pdf(&st.orientation_sin), SeriesStyle::Line),
        ],
        x_range: Some((0.0, PI / 2.0)),
        legend: LegendPosition::UpperLeft,
        ..Default::default()
    };
    figs.push((
        line_figure(out, "fig08_orientation", &plot8)?,
        "Figure 8: pdf of the angle φ between axis and vertical".into(),
    ));
    let plot9 = LinePlot {
        title: format!("{tag}: orientation of mobile particles (z_p > 0.2H)"),
        series: vec![
            Series::new("z_p > 0.2H", pdf(&st.orientation_mobile), SeriesStyle::LinePoints),
            Series::new("sin φ", pdf(&st.orientation_sin), SeriesStyle::Line),
        ],
        ..plot8.clone()
    };
    figs.push((
        line_figure(out, "fig09_orientation_mobile", &plot9)?,
        "Figure 9: pdf of φ for the mobile particles".into(),
    ));

    // Figure 10.
    let end = timeseries.revolutions.last().copied().unwrap_or(0.0);
    let from = (end - POWER_REVOLUTIONS).max(0.5);
    let sel = |v: &[f64]| -> Vec<(f64, f64)> {
        timeseries.revolutions.iter().zip(v).filter(|(r, _)| **r >= from).map(|(r, x)| (*r, *x)).collect()
    };
    let total: Vec<f64> = timeseries.po_fluid.iter().zip(&timeseries.po_solids).map(|(a, b)| a + b).collect();
    let mut series = vec![
        Series::new("Po_f (liquid)", sel(&timeseries.po_fluid), SeriesStyle::Line),
        Series::new("Po_c (collisions)", sel(&timeseries.po_solids), SeriesStyle::Line),
        Series::new("Po total", sel(&total), SeriesStyle::Line),
    ];
    for v in paper.values.iter().filter(|v| v.key.starts_with("po")) {
        if let Some(p) = v.paper {
            series.push(Series::new(
                format!("paper {} {p}", v.key),
                vec![(from, p), (end, p)],
                SeriesStyle::Line,
            ));
        }
    }
    let plot10 = LinePlot {
        title: format!("{tag}: power number"),
        x_label: "t N (revolutions)".into(),
        y_label: "Po = 2πNΓ / (ρN³D⁵)".into(),
        series,
        legend: LegendPosition::UpperRight,
        ..Default::default()
    };
    figs.push((line_figure(out, "fig10_power", &plot10)?, "Figure 10: power numbers against time".into()));
    Ok(figs)
}

fn fmt_opt(v: Option<f64>) -> String {
    v.map_or("–".into(), |x| format!("{:.3}", x + 0.0))
}

/// The text of `report.md`.
fn report_md(
    name: &str,
    case: &Case,
    paper: &PaperValues,
    s: &RunRecord,
    (bed, joined): (&BedRecord, bool),
    r: &Results,
    figs: &[(String, String)],
) -> String {
    let g = case.grid();
    let mut m = String::new();
    let _ = writeln!(m, "# Reproduction of Derksen (2020): {name}\n");
    let _ = writeln!(
        m,
        "{} with {} cylinders of ℓ/d = {}, at scale {:.3} of the paper: {} × {} × {} nodes, d = {:.2}, D = {:.1}, \
         ν = {:.5}, N = {:.4e} rev/step, tip speed {:.4}.\n",
        if paper.impeller == "disk" { "Disk" } else { "Pitched-blade turbine" },
        paper.particles,
        paper.aspect_ratio,
        s.scale,
        g.nx,
        g.ny,
        g.nz,
        12.0 * s.scale,
        132.0 * s.scale,
        case.nu(),
        1.0 / s.schedule.steps_per_revolution,
        PI * 132.0 * s.scale / s.schedule.steps_per_revolution
    );
    // The floor is at z = −½ (half-way bounce-back): heights above it, as ⟨z_p⟩/H.
    let height = format!(
        "mean centre height {:.2} above the floor ({:.3} H)",
        bed.bed.mean_height + 0.5,
        (bed.bed.mean_height + 0.5) / g.nz as f64
    );
    let start = match (&bed.start_from, &bed.state_pack) {
        (None, Some(p)) if joined => format!(
            "- Start: **not a settled bed** (the paper's start) but {} (`--start-from`). The run goes on as one: \
             its time series holds the packed run's rows (the legs are in `manifest.json`), so ⟨z_p⟩/H over \
             time, the steady test and the power numbers are the whole run's; φ(z), the kinetic energy and the \
             orientations are from the particle frames of this leg, after the pack.",
            p.describe()
        ),
        (None, Some(p)) => format!(
            "- Start: **not a settled bed** (the paper's start) but {} (`--start-from`), a pack without the \
             run's history. The statistics are those of this run's own revolutions after the pack.",
            p.describe()
        ),
        (Some(from), _) => format!(
            "- Start: **not a settled bed** (the paper's start) but {} (`--start-from`); {height}. The suspension \
             relaxes from that state; the statistics are those of the run's own last revolutions.",
            from.describe()
        ),
        (None, None) => format!(
            "- Bed: placed at random and settled {} in {} steps ({}{}), {height}; {}.",
            if bed.wet { "in the fluid under the case's gravity" } else { "dry (no fluid: amplified gravity against a linear drag)" },
            bed.bed.steps,
            if bed.bed.settled { "settled" } else { "NOT settled: step limit" },
            // A wet settling takes hours and may span sessions: its cost, as the run's is given.
            if bed.wet {
                format!(
                    "; {:.1} h of settling in {} session{}",
                    bed.bed.seconds / 3600.0,
                    bed.bed.restarts + 1,
                    if bed.bed.restarts == 0 { "" } else { "s" }
                )
            } else {
                String::new()
            },
            if s.bed_cached { "from the cache" } else { "made for this run" }
        ),
    };
    let _ = writeln!(m, "{start}");
    let _ = writeln!(
        m,
        "- Run: {} steps = ramp of {} steps + {} revolutions; {:.0} s of stepping at {:.1} MLUPS on {}; \
         largest Mach number {:.3}; relative mass change {:.1e}.",
        s.run.steps,
        s.schedule.ramp_steps,
        s.revolutions,
        s.run.step_time_s,
        s.run.mlups,
        processor(&s.run),
        s.run.max_mach,
        s.run.relative_mass_change
    );
    if let Some(c) = s.contacts.describe() {
        let _ = writeln!(m, "- Contacts of the stirred run: {c}.");
    }
    match s.run.resumed_from {
        Some(k) if k >= s.run.steps => {
            let _ = writeln!(
                m,
                "- This session resumed the run at its last step, {k}: it stepped nothing (the stepping \
                 time, MLUPS and mass change above are this session's, so none; the Mach number is the \
                 resumed state's); it redrew the statistics, figures and this report from the run's files."
            );
        }
        Some(k) => {
            let _ = writeln!(
                m,
                "- This session resumed the run from its checkpoint at step {k}: the stepping time, MLUPS, \
                 Mach number and mass change above are this session's."
            );
        }
        None => {}
    }
    let _ = writeln!(
        m,
        "- Steady state (drift of ⟨z_p⟩/H over the last {STEADY_REVOLUTIONS} revolutions at most {STEADY_DRIFT}, and \
         its standard error too): **{}**: {}.\n",
        if r.steady { "steady" } else { "NOT steady" },
        r.steady_reason
    );
    if !r.steady {
        let _ = writeln!(
            m,
            "The paper needs more than 100 revolutions (200 for the PBT with ℓ/d = 1) to reach steady state; a run \
             that is not steady is compared below for information only, and its deviations are not a verdict on the \
             method.\n"
        );
    }
    let _ = writeln!(m, "## Against the paper\n");
    let _ =
        writeln!(m, "| quantity | this run | paper | deviation | band | in band | steady | averaged over |");
    let _ = writeln!(m, "|---|---|---|---|---|---|---|---|");
    for c in &r.comparison {
        let _ = writeln!(
            m,
            "| {} | {:.3} | {} | {} | [{}, {}] | {} | {} | {:.1} rev |",
            c.label,
            c.value + 0.0,
            fmt_opt(c.paper),
            c.deviation.map_or("–".into(), |d| format!("{d:+.3}")),
            fmt_opt(c.min),
            fmt_opt(c.max),
            if c.in_band { "yes" } else { "**no**" },
            if c.steady { "yes" } else { "no" },
            c.window_revolutions
        );
    }
    let _ = writeln!(m, "\nBands and their reasons (`reproduce/{name}/paper.toml`):\n");
    for v in &paper.values {
        let _ = writeln!(m, "- {}: {} ({})", v.label, v.reason, v.source);
    }
    let _ = writeln!(
        m,
        "\nPower averages over t N = {:.1}–{:.1} ({} samples, after the ramp): Po_f {:.3}, Po_c {:.3}, total {:.3} \
         (standard deviation of the total {:.3}){}.\n",
        r.power_window.0,
        r.power_window.1,
        r.power_window.2,
        r.po_fluid + 0.0,
        r.po_solids + 0.0,
        r.po + 0.0,
        r.po_std,
        if r.power_covered {
            String::new()
        } else {
            format!(
                "; **the series does not cover the paper's window of {POWER_REVOLUTIONS} revolutions** (too short, or a \
                 lost stretch: the average is over what there is)"
            )
        }
    );
    let _ = writeln!(m, "## Figures\n");
    for (stem, caption) in figs {
        let _ = writeln!(m, "**{caption}** ([SVG]({stem}.svg))\n\n![{caption}]({stem}.png)\n");
    }
    let _ = writeln!(
        m,
        "## Files\n\n- `run/`: the stirred run (`timeseries.csv`, `particles.h5`, `fields.h5` + `fields.xmf`, \
         `checkpoint.h5`, `case.toml`, `summary.json`)\n- `statistics.h5`, `statistics.json`: the statistics above\n\
         - `midplane.h5` + `midplane.xmf`: the speed on the mid-plane (ParaView)\n\
         - `manifest.json`: revision, command, host, threads, sessions (restarts) and wall time; \
         `reproduce.json`: the run's summary and these results\n"
    );
    m
}

/// Where the run stepped, for the report: `N threads` on the CPU; on the device, the adapter
/// (the fluid and the markers there, the contacts and the bodies on N host threads).
fn processor(run: &RunSummary) -> String {
    match run.isa.strip_prefix("device: ") {
        Some(adapter) => format!(
            "the device {adapter} (the fluid and the immersed boundary; the contacts and the bodies on {} host threads)",
            run.threads
        ),
        None => format!("{} threads", run.threads),
    }
}
