//! `slurry bench --coupled` (and `cargo xtask bench --coupled`): the cost of the coupled step
//! of the paper's cases, per phase, beside the fluid-only step of the same grid, measured in
//! the same run (the machines are shared and noisy: ratios hold, absolute figures drift).
//!
//! Each case starts from its real settled bed (the reproduction's bed cache, [`super::bed`];
//! made and cached on first use), with the impeller inserted as in [`super::stirred_case`],
//! in `f32`. `warmup` coupled steps run first (the impeller's ramp starts at step 0, so the
//! blades move and particles near them move and touch), then `steps` steps are timed with the
//! coupling's phase timers ([`slurry::coupling::StepTimings`]). The fluid-only step is a
//! [`Fluid`] of the same grid and boundaries with its force field on, timed over as many steps.
//!
//! With `from` (`slurry bench --coupled --from CHECKPOINT`) the coupled solver starts instead
//! from a run's checkpoint of the same case and scale (a reproduction's `run/checkpoint.h5`,
//! written under any contact scheme): the cost of the suspension at steady state, where the
//! particles are spread over the tank and move fast, rather than of the bed being lifted. The
//! particles' definitions then come from the case the checkpoint was written with, not from
//! the bed cache, so a run started from a wet bed or with `--start-from` is measured too, and
//! no bed is made.
//!
//! The per-output work of a run (the health check and the walls' momentum exchange behind the
//! torque balance) is timed once and divided by the case's output interval: `output_ms`.

use std::path::{Path, PathBuf};
use std::time::Instant;

use serde::Serialize;

use slurry::case::ImpellerSetup;
use slurry::coupling::{Coupled, CoupledState};
use slurry::lbm::Fluid;

/// The measurement of one case at one scale (what `target/bench/coupled.json` holds).
#[derive(Clone, Debug, Serialize)]
pub struct CoupledBench {
    /// Case name (`pbt-ld2`, …).
    pub case: String,
    /// Scale `s` (1 = the paper's grid).
    pub scale: f64,
    /// Worker threads.
    pub threads: usize,
    /// `"f32"`.
    pub precision: String,
    /// Grid size.
    pub grid: [usize; 3],
    /// Particles.
    pub particles: usize,
    /// Markers (particles and impeller).
    pub markers: usize,
    /// Fluid-only step on the same grid, ms.
    pub fluid_ms: f64,
    /// Coupled step, ms (all phases).
    pub step_ms: f64,
    /// Phase 1–2: markers, stencils, band, ms per step.
    pub geometry_ms: f64,
    /// Phases 3 and 7: interior sums, ms per step.
    pub interior_ms: f64,
    /// Phases 4–5: forcing, ms per step.
    pub forcing_ms: f64,
    /// The interpolation of phase 5 (part of `forcing_ms`), ms per step.
    pub interpolate_ms: f64,
    /// The spreading of phase 5 (part of `forcing_ms`), ms per step.
    pub spread_ms: f64,
    /// Phase 6 inside the coupled step, ms per step.
    pub fluid_in_step_ms: f64,
    /// Phase 7–8: loads and external loads, ms per step.
    pub bodies_ms: f64,
    /// Phase 8: contacts and the sub-stepped body update, ms per step.
    pub contact_ms: f64,
    /// With implicit damping, the part of `contact_ms` spent assembling its systems, ms per
    /// step (0 with explicit damping).
    pub implicit_assembly_ms: f64,
    /// With implicit damping, the part of `contact_ms` spent solving them, ms per step.
    pub implicit_solve_ms: f64,
    /// With implicit damping, conjugate-gradient iterations per fluid step (all sub-steps).
    pub implicit_iterations: f64,
    /// The immersed boundary's share: geometry + interior + forcing, ms per step.
    pub ibm_ms: f64,
    /// Per-output work of a run divided by its output interval, ms per step.
    pub output_ms: f64,
    /// `step_ms / fluid_ms`.
    pub ratio: f64,
    /// MLUPS of the fluid-only step.
    pub fluid_mlups: f64,
    /// MLUPS of the coupled step (nodes per coupled step).
    pub coupled_mlups: f64,
    /// Rebuilds of the contact pair list during the timed steps.
    pub list_rebuilds: u64,
    /// Full rebuilds of the contact pair list during the timed steps (the rest of
    /// `list_rebuilds` refreshed only the bodies that had moved).
    pub full_rebuilds: u64,
    /// The bodies' bands (nodes within reach of a stencil, with repetitions) as a fraction of
    /// the grid, from the estimate the step chooses its path by (module `coupling`, "Dense
    /// beds"): the whole-grid path above [`slurry::coupling::DENSE_BAND_FRACTION`].
    pub band_fraction: f64,
    /// Whether the timed steps took the whole-grid path (no band built).
    pub whole_grid: bool,
    /// Marker pairs in the contact pair list after the timed steps (body–body).
    pub listed_pairs: usize,
    /// Interacting marker pairs (body–body) in the last contact sub-step.
    pub interacting_pairs: usize,
    /// The largest `ContactStats::damping_rate` seen at the end of a timed step (per unit
    /// time): explicit damping needs sub-steps `h < 2/damping_rate`.
    pub max_damping_rate: f64,
    /// The largest `ContactStats::spring_rate` seen at the end of a timed step.
    pub max_spring_rate: f64,
    /// Contact sub-steps per fluid step.
    pub contact_substeps: usize,
    /// Whether the lubrication limiter was on.
    pub lubrication_limiter: bool,
    /// Lubrication sub-steps per contact sub-step (1: Table 1's law at every evaluation).
    pub lubrication_substeps: usize,
    /// The damping's integration, `"explicit"` or `"implicit"`
    /// ([`slurry::contact::ContactParams::damping`]).
    pub damping: String,
    /// The fluid time step the timed steps started from: the warm-up's end, after the
    /// checkpoint's step when started from one.
    pub start_step: u64,
    /// The checkpoint the coupled solver started from (`None`: the settled bed).
    pub from: Option<String>,
}

/// Changes to the contacts of a benchmarked case (the bed is made as the case says).
#[derive(Clone, Copy, Debug, Default)]
pub struct ContactOptions {
    /// The skin of the marker-pair list (default: the library's); the loads do not depend on
    /// it, only the cost.
    pub skin: Option<f64>,
    /// Contact sub-steps per fluid step (default: the case's).
    pub substeps: Option<usize>,
    /// Turn the lubrication limiter on ([`slurry::contact::ContactParams::lubrication_limiter`]).
    pub limiter: bool,
    /// Lubrication sub-steps per contact sub-step (default: the case's, 1;
    /// [`slurry::contact::ContactParams::lubrication_substeps`]).
    pub lubrication_substeps: Option<usize>,
    /// Integrate the damping implicitly ([`slurry::contact::Damping::Implicit`]).
    pub implicit_damping: bool,
}

/// A benchmarked case made ready to couple: the stirred case at its scale on its cached bed
/// (or on the particles of the checkpoint's case), its output interval, and the checkpoint to
/// start from, if any (read before a bed is made, which may take long).
struct Setup {
    case: slurry::case::Case,
    output_every: u64,
    /// The checkpoint's path, the fingerprint it was written with, and its state.
    checkpoint: Option<(PathBuf, String, CoupledState<f32>)>,
}

impl Setup {
    /// Case `name` at `scale` on its settled bed or, with `from`, on the particles of the case
    /// the checkpoint at `from` was written with (its grid checked here, the rest of the case
    /// in [`Setup::couple`]).
    fn new(name: &str, scale: f64, cache: &Path, from: Option<&Path>, quiet: bool) -> anyhow::Result<Self> {
        let pc = super::paper_case(name)?;
        let scaled = super::scale_case(&pc.case()?, scale)?;
        let g = scaled.grid();
        let checkpoint = from
            .map(|p| read_from(p, [g.nx, g.ny, g.nz]).map(|(case, state)| (p.to_path_buf(), case, state)))
            .transpose()?;
        let sched = super::schedule(&scaled, 1.0)?;
        let case = match &checkpoint {
            Some((path, written_for, _)) => {
                let written: slurry::case::Case = toml::from_str(written_for).map_err(|e| {
                    anyhow::anyhow!(
                        "--from {}: the case it was written with cannot be read: {e}",
                        path.display()
                    )
                })?;
                super::with_particles(&scaled, &written.particles, &sched)
            }
            None => {
                let (bed, _) = super::bed(name, &scaled, super::BedMethod::default(), cache, quiet, None)?;
                super::stirred_case(&scaled, &bed, &sched)
            }
        };
        Ok(Self { case, output_every: sched.output_every, checkpoint })
    }

    /// A fluid of the case's grid in its initial state.
    fn fluid(&self) -> anyhow::Result<Fluid<f32>> {
        let mut f = Fluid::<f32>::new(self.case.grid(), self.case.fluid_params(), self.case.boundaries())?;
        f.initialize(|x, y, z| self.case.initial_state(x, y, z));
        Ok(f)
    }

    /// The coupled solver with the contact scheme changed by `contact`, restored from the
    /// checkpoint if there is one; its coupling parameters.
    fn couple(
        &self,
        contact: ContactOptions,
    ) -> anyhow::Result<(Coupled<f32>, slurry::coupling::CouplingParams)> {
        let case = &self.case;
        let inits = case.particle_inits().map_err(|k| anyhow::anyhow!("invalid case: {k}"))?;
        let impeller = case.impeller_setup().map_err(|k| anyhow::anyhow!("invalid case: {k}"))?;
        let mut bodies: Vec<_> = inits.iter().map(|p| p.body()).collect();
        bodies.extend(impeller.as_ref().map(ImpellerSetup::body));
        let mut params = case.coupling_params();
        if let Some(p) = params.contacts.as_mut() {
            p.substeps = contact.substeps.unwrap_or(p.substeps);
            p.lubrication_limiter |= contact.limiter;
            p.lubrication_substeps = contact.lubrication_substeps.unwrap_or(p.lubrication_substeps);
            if contact.implicit_damping {
                p.damping = slurry::contact::Damping::Implicit;
            }
        }
        let mut c =
            Coupled::new(self.fluid()?, bodies, params).map_err(|e| anyhow::anyhow!("cannot couple: {e}"))?;
        if let Some((path, written_for, state)) = &self.checkpoint {
            // Any contact scheme, any length of run, any start; the same case and scale.
            if !case.same_except_contact_scheme(written_for) {
                anyhow::bail!(
                    "--from {}: the checkpoint was written for another case (it must be a reproduction of the same case at the same scale)",
                    path.display()
                );
            }
            c.restore(state)
                .map_err(|e| anyhow::anyhow!("--from {}: cannot restore: {e}", path.display()))?;
        }
        if let Some(skin) = contact.skin {
            c.set_contact_skin(skin);
        }
        if let Some(v) = std::env::var_os("SLURRY_BENCH_DENSE") {
            let dense = match v.to_str() {
                Some("1") => true,
                Some("0") => false,
                _ => anyhow::bail!(
                    "SLURRY_BENCH_DENSE = {v:?}: must be 1 (the whole-grid path) or 0 (the band path), or unset"
                ),
            };
            c.set_dense_override(Some(dense));
        }
        Ok((c, params))
    }
}

/// Measures case `name` at scale `scale`, from its settled bed or, with `from`, from a run's
/// checkpoint (module docs).
///
/// # Errors
/// An unknown case or scale, a bed that cannot be settled or cached, a coupling that cannot
/// be built, a checkpoint that cannot be read or was written for another case or scale.
#[allow(clippy::too_many_arguments)]
pub fn bench_case(
    name: &str,
    scale: f64,
    cache: &Path,
    warmup: u64,
    steps: u64,
    contact: ContactOptions,
    from: Option<&Path>,
    quiet: bool,
) -> anyhow::Result<CoupledBench> {
    let setup = Setup::new(name, scale, cache, from, quiet)?;
    let case = &setup.case;
    let grid = case.grid();
    let particles = case.particle_inits().map_err(|k| anyhow::anyhow!("invalid case: {k}"))?.len();
    // Fluid alone, force field on (the coupled kernel reads it too).
    let mut fluid = setup.fluid()?;
    fluid.enable_force_field();
    fluid.run(4);
    let fluid_steps = steps.max(2) & !1; // even: the AA parity stays aligned
    let t = Instant::now();
    fluid.run(fluid_steps);
    let fluid_ms = t.elapsed().as_secs_f64() * 1e3 / fluid_steps as f64;
    drop(fluid);

    let (mut c, params) = setup.couple(contact)?;
    for _ in 0..warmup {
        c.step().map_err(|e| anyhow::anyhow!("warm-up step: {e}"))?;
    }
    c.reset_timings();
    let start_step = c.fluid().time();
    let rebuilds0 = c.contact_list_rebuilds();
    let full0 = c.contacts().map_or(0, |k| k.full_rebuilds());
    let implicit = |c: &Coupled<f32>| {
        c.contacts().map_or((0.0, 0.0, 0), |k| {
            let (a, s, _) = k.implicit_solve_time();
            (a, s, k.implicit_cg_iterations())
        })
    };
    let implicit0 = implicit(&c);
    let (mut max_damping_rate, mut max_spring_rate) = (0.0f64, 0.0f64);
    for _ in 0..steps {
        c.step().map_err(|e| anyhow::anyhow!("timed step: {e}"))?;
        if let Some(k) = c.contacts() {
            max_damping_rate = max_damping_rate.max(k.stats().damping_rate);
            max_spring_rate = max_spring_rate.max(k.stats().spring_rate);
        }
    }
    let timings = *c.timings();
    let per = |x: f64| x * 1e3 / steps as f64;
    let t = Instant::now();
    let _ = c.fluid().health(case.run.mach_limit);
    let _ = c.fluid().wall_momentum_exchange([0.0; 3]);
    let output_ms = t.elapsed().as_secs_f64() * 1e3 / setup.output_every as f64;
    let step_ms = per(timings.total());
    let nodes = grid.nodes() as f64;
    Ok(CoupledBench {
        case: name.to_string(),
        scale,
        threads: rayon::current_num_threads(),
        precision: "f32".into(),
        grid: [grid.nx, grid.ny, grid.nz],
        particles,
        markers: c.marker_count(),
        fluid_ms,
        step_ms,
        geometry_ms: per(timings.geometry),
        interior_ms: per(timings.interior),
        forcing_ms: per(timings.forcing),
        interpolate_ms: per(timings.interpolation),
        spread_ms: per(timings.spreading),
        fluid_in_step_ms: per(timings.fluid),
        bodies_ms: per(timings.bodies),
        contact_ms: per(timings.contacts),
        implicit_assembly_ms: per(implicit(&c).0 - implicit0.0),
        implicit_solve_ms: per(implicit(&c).1 - implicit0.1),
        implicit_iterations: (implicit(&c).2 - implicit0.2) as f64 / steps as f64,
        ibm_ms: per(timings.geometry + timings.interior + timings.forcing),
        output_ms,
        ratio: step_ms / fluid_ms,
        fluid_mlups: nodes / fluid_ms / 1e3,
        coupled_mlups: nodes / step_ms / 1e3,
        list_rebuilds: c.contact_list_rebuilds() - rebuilds0,
        full_rebuilds: c.contacts().map_or(0, |k| k.full_rebuilds()) - full0,
        band_fraction: c.band_estimate() as f64 / nodes,
        whole_grid: c.whole_grid(),
        listed_pairs: c.contacts().map_or(0, |k| k.list_stats().1),
        interacting_pairs: c.contacts().map_or(0, |k| k.stats().marker_pairs),
        max_damping_rate,
        max_spring_rate,
        contact_substeps: params.contacts.map_or(0, |p| p.substeps),
        lubrication_limiter: params.contacts.is_some_and(|p| p.lubrication_limiter),
        lubrication_substeps: params.contacts.map_or(0, |p| p.lubrication_substeps),
        damping: params.contacts.map_or("", |p| p.damping.name()).to_string(),
        start_step,
        from: from.map(|p| p.display().to_string()),
    })
}

/// Reads the checkpoint at `path` for [`bench_case`]'s `from`: an `f32` checkpoint with
/// particle states on an `nx × ny × nz` grid (the case's at the benchmarked scale). Returns
/// the fingerprint it was written with and the coupled state.
fn read_from(path: &Path, [nx, ny, nz]: [usize; 3]) -> anyhow::Result<(String, CoupledState<f32>)> {
    let cp = slurry::io::checkpoint::read_checkpoint::<f32>(path).map_err(|e| {
        anyhow::anyhow!("--from {}: cannot be read as an f32 slurry checkpoint: {e}", path.display())
    })?;
    let g = cp.state.grid;
    if (g.nx, g.ny, g.nz) != (nx, ny, nz) {
        anyhow::bail!(
            "--from {}: the checkpoint's grid is {} x {} x {}, the case's at this scale {} x {} x {} (give the scale of the run that wrote it)",
            path.display(),
            g.nx,
            g.ny,
            g.nz,
            nx,
            ny,
            nz
        );
    }
    let Some(bodies) = cp.bodies else {
        anyhow::bail!(
            "--from {}: holds no particle states (not a reproduction's checkpoint)",
            path.display()
        );
    };
    Ok((cp.case, CoupledState { fluid: cp.state, bodies }))
}

/// One contact scheme of a [`shadow`] comparison.
#[derive(Clone, Debug)]
pub struct ShadowScheme {
    /// Its name in the output.
    pub label: String,
    /// The scheme (sub-steps, lubrication sub-steps, limiter; the skin changes no load).
    pub contact: ContactOptions,
}

/// The free particles of one scheme of a [`shadow`] comparison, at the recorded steps.
#[derive(Clone, Debug, Serialize)]
pub struct ShadowRun {
    /// The scheme's name.
    pub label: String,
    /// Contact sub-steps per fluid step.
    pub contact_substeps: usize,
    /// Lubrication sub-steps per contact sub-step.
    pub lubrication_substeps: usize,
    /// Whether the lubrication limiter was on.
    pub lubrication_limiter: bool,
    /// The steps after the checkpoint at which the states were recorded.
    pub at: Vec<u64>,
    /// Per recorded step, per free particle: position, velocity, angular velocity (world).
    pub states: Vec<Vec<[f64; 9]>>,
    /// Per step, the particles' mean vertical velocity `⟨w_p⟩`.
    pub mean_w: Vec<f64>,
    /// Per step, the elastic energy stored in the contacts at the last sub-step
    /// ([`slurry::contact::ContactStats::elastic_energy`]): how deep the surfaces press.
    pub elastic_energy: Vec<f64>,
    /// Per step, the interacting marker pairs at the last sub-step.
    pub marker_pairs: Vec<usize>,
    /// Wall-clock seconds of the steps.
    pub seconds: f64,
}

/// Runs the coupled solver of case `name` at `scale` from the checkpoint `from` under each of
/// `schemes` for `at.last()` steps, recording the free particles' states after each step
/// count of `at` (ascending) and their mean vertical velocity after every step: the
/// trajectories of one suspension under several contact schemes, side by side, before the
/// flow's chaos separates them (the differences to the finest scheme, [`shadow_differences`],
/// measure each scheme's error where it is used). Deterministic: the same bits for any thread
/// count.
///
/// # Errors
/// As [`bench_case`]; `at` empty or not ascending; a step that fails.
pub fn shadow(
    name: &str,
    scale: f64,
    cache: &Path,
    from: &Path,
    at: &[u64],
    schemes: &[ShadowScheme],
    quiet: bool,
) -> anyhow::Result<Vec<ShadowRun>> {
    if at.is_empty() || at.windows(2).any(|w| w[0] >= w[1]) {
        anyhow::bail!("the recorded step counts must be ascending and at least one: {at:?}");
    }
    let setup = Setup::new(name, scale, cache, Some(from), quiet)?;
    let mut runs = Vec::with_capacity(schemes.len());
    for scheme in schemes {
        let (mut c, params) = setup.couple(scheme.contact)?;
        let free: Vec<usize> = (0..c.bodies().len()).filter(|&b| c.bodies()[b].is_free()).collect();
        let mut states = Vec::with_capacity(at.len());
        let mut mean_w = Vec::with_capacity(at[at.len() - 1] as usize);
        let (mut elastic_energy, mut marker_pairs) = (Vec::new(), Vec::new());
        let t = Instant::now();
        for step in 1..=at[at.len() - 1] {
            c.step().map_err(|e| anyhow::anyhow!("{}: step {step}: {e}", scheme.label))?;
            let bodies = c.bodies();
            mean_w.push(free.iter().map(|&b| bodies[b].velocity.z).sum::<f64>() / free.len().max(1) as f64);
            let stats = c.contacts().map(|k| *k.stats()).unwrap_or_default();
            elastic_energy.push(stats.elastic_energy);
            marker_pairs.push(stats.marker_pairs);
            if at.contains(&step) {
                states.push(
                    free.iter()
                        .map(|&b| {
                            let (x, v, w) =
                                (bodies[b].position, bodies[b].velocity, bodies[b].angular_velocity);
                            [x.x, x.y, x.z, v.x, v.y, v.z, w.x, w.y, w.z]
                        })
                        .collect(),
                );
            }
        }
        runs.push(ShadowRun {
            label: scheme.label.clone(),
            contact_substeps: params.contacts.map_or(0, |p| p.substeps),
            lubrication_substeps: params.contacts.map_or(0, |p| p.lubrication_substeps),
            lubrication_limiter: params.contacts.is_some_and(|p| p.lubrication_limiter),
            at: at.to_vec(),
            states,
            mean_w,
            elastic_energy,
            marker_pairs,
            seconds: t.elapsed().as_secs_f64(),
        });
    }
    Ok(runs)
}

/// How one [`ShadowRun`] differs from a reference run of the same suspension, per recorded
/// step: over the free particles, the root mean square of the position difference `|Δx|`, of
/// the velocity difference `|Δv|` and of the angular-velocity difference `|Δω|`, and the mean
/// height difference `⟨Δz⟩` (a systematic lift or settling); over all steps, the mean of
/// `⟨w_p⟩ − ⟨w_p⟩_ref`.
#[derive(Clone, Debug, Serialize)]
pub struct ShadowDiff {
    /// The run's scheme.
    pub label: String,
    /// The recorded step counts.
    pub at: Vec<u64>,
    /// RMS `|Δx|` per recorded step.
    pub rms_position: Vec<f64>,
    /// RMS `|Δv|` per recorded step.
    pub rms_velocity: Vec<f64>,
    /// RMS `|Δω|` per recorded step.
    pub rms_angular: Vec<f64>,
    /// `⟨Δz⟩` per recorded step.
    pub mean_dz: Vec<f64>,
    /// The mean over all steps of the difference of the particles' mean vertical velocity.
    pub mean_dw: f64,
}

/// [`ShadowDiff`] of every run against `runs[reference]`.
///
/// # Panics
/// `reference` out of range, or runs recorded at other steps or with other particles.
pub fn shadow_differences(runs: &[ShadowRun], reference: usize) -> Vec<ShadowDiff> {
    let r = &runs[reference];
    runs.iter()
        .map(|run| {
            assert_eq!(run.at, r.at, "{}: recorded at other steps than the reference", run.label);
            let rms = |k: std::ops::Range<usize>, i: usize| {
                let (a, b) = (&run.states[i], &r.states[i]);
                assert_eq!(a.len(), b.len(), "{}: another number of particles", run.label);
                let sum: f64 =
                    a.iter().zip(b).map(|(p, q)| k.clone().map(|c| (p[c] - q[c]).powi(2)).sum::<f64>()).sum();
                (sum / a.len().max(1) as f64).sqrt()
            };
            let n = run.at.len();
            ShadowDiff {
                label: run.label.clone(),
                at: run.at.clone(),
                rms_position: (0..n).map(|i| rms(0..3, i)).collect(),
                rms_velocity: (0..n).map(|i| rms(3..6, i)).collect(),
                rms_angular: (0..n).map(|i| rms(6..9, i)).collect(),
                mean_dz: (0..n)
                    .map(|i| {
                        let (a, b) = (&run.states[i], &r.states[i]);
                        a.iter().zip(b).map(|(p, q)| p[2] - q[2]).sum::<f64>() / a.len().max(1) as f64
                    })
                    .collect(),
                mean_dw: run.mean_w.iter().zip(&r.mean_w).map(|(a, b)| a - b).sum::<f64>()
                    / run.mean_w.len().max(1) as f64,
            }
        })
        .collect()
}
