//! A committed state pack continued through the whole pipeline (`slurry reproduce CASE
//! --start-from PACK`): the options that the steady regression and the device's reproduction
//! test share.

use std::path::{Path, PathBuf};

use slurry_reproduce::{paper_case, scale_case, schedule, ReproduceOptions};

/// A continuation of the pack `reproduce/CASE/runs/ARCHIVE/state.h5`.
pub struct Continuation {
    /// The pack's path.
    pub pack: PathBuf,
    /// The pack's step.
    pub step: u64,
    /// The options: `revolutions` more after the pack at scale `scale`, into `out`, with the
    /// campaigns' Mach limit `mach_limit`, on the device when `gpu`.
    pub options: ReproduceOptions,
}

/// The continuation of `case`'s pack in `archive` (module docs).
pub fn continuation(
    case: &str,
    archive: &str,
    scale: f64,
    revolutions: f64,
    out: &Path,
    mach_limit: f64,
    gpu: bool,
) -> Continuation {
    let pack = super::common::root().join("reproduce").join(case).join("runs").join(archive).join("state.h5");
    let p = slurry::io::read_state_pack(&pack).unwrap_or_else(|e| panic!("{}: {e}", pack.display()));
    let scaled = scale_case(&paper_case(case).unwrap().case().unwrap(), scale).unwrap();
    let sched = schedule(&scaled, 1.0).unwrap();
    let ramp = sched.ramp_steps.div_ceil(sched.output_every) * sched.output_every;
    let after = (p.time_step - ramp) as f64 / sched.steps_per_revolution;
    let options = ReproduceOptions {
        mach_limit: Some(mach_limit),
        start_from: Some(pack.clone()),
        gpu,
        ..ReproduceOptions::quiet_run(scale, after + revolutions, out.to_path_buf(), out.join("cache"))
    };
    Continuation { pack, step: p.time_step, options }
}
