//! Ranges and consistency of a parsed case ([`Case::validate`]), and the memory check: the
//! first problem found, naming its key, the value and the allowed range.

use super::*;

impl Case {
    /// Checks ranges and consistency, and places the particles ([`Case::particle_inits`]).
    /// The first problem found is returned, naming its key.
    pub fn validate(&self) -> Result<(), CaseErrorKind> {
        self.validate_settings()?;
        self.check_memory()?;
        self.particle_inits().map(|_| ())
    }

    /// Compares the memory the case needs ([`memory::MemoryEstimate`]) with what the machine
    /// has ([`memory::available_memory`]); refuses the case, naming both, when it does not
    /// fit. The key named is `domain`, or the random population with the most markers when
    /// the particles need more than the grid. Nothing large is allocated here.
    pub fn check_memory(&self) -> Result<(), CaseErrorKind> {
        let Some(limit) = memory::available_memory() else { return Ok(()) };
        let est = memory::MemoryEstimate::of(self);
        if est.total() <= limit.bytes {
            return Ok(());
        }
        let d = &self.domain;
        let grid_value = format!("{} x {} x {} ({})", d.nx, d.ny, d.nz, self.fluid.precision.name());
        let biggest_population = (0..self.random_particles.len()).max_by(|&a, &b| {
            let m = |k: usize| self.random_count_f64(k);
            m(a).total_cmp(&m(b))
        });
        let (key, value, advice) = match biggest_population {
            Some(k) if est.grid_part() < est.markers.saturating_add(est.particles) => {
                let r = &self.random_particles[k];
                match r.volume_fraction {
                    Some(phi) => (
                        format!("random_particles[{k}].volume_fraction"),
                        phi.to_string(),
                        "lower the volume fraction or enlarge the particles",
                    ),
                    None => (
                        format!("random_particles[{k}].count"),
                        self.random_count(k).to_string(),
                        "lower the count",
                    ),
                }
            }
            _ => ("domain".to_string(), grid_value, "use a smaller grid or f32 precision"),
        };
        Err(invalid(
            key,
            value,
            format!(
                "the case needs about {}; this machine has {} available ({}): {advice}",
                est.describe(),
                memory::fmt_bytes(limit.bytes),
                limit.source
            ),
        ))
    }

    /// [`Case::validate`] without placing the particles (each particle entry is still
    /// checked on its own): the cheap part.
    pub fn validate_settings(&self) -> Result<(), CaseErrorKind> {
        self.validate_domain()?;
        self.validate_fluid()?;
        self.validate_run()?;
        self.validate_boundaries()?;
        self.validate_initial()?;
        self.validate_particle_settings()?;
        self.impeller_setup()?;
        Ok(())
    }

    fn validate_domain(&self) -> Result<(), CaseErrorKind> {
        let d = &self.domain;
        for (k, n) in [("nx", d.nx), ("ny", d.ny), ("nz", d.nz)] {
            if n < 1 {
                return Err(invalid(format!("domain.{k}"), n, "must be an integer >= 1"));
            }
        }
        let padded = (d.nx as u128 + 2) * (d.ny as u128 + 2) * (d.nz as u128 + 2);
        if padded >= u32::MAX as u128 {
            return Err(invalid(
                "domain",
                format!("{} x {} x {}", d.nx, d.ny, d.nz),
                "(nx+2)(ny+2)(nz+2) must be below 2^32 nodes",
            ));
        }
        Ok(())
    }

    fn validate_fluid(&self) -> Result<(), CaseErrorKind> {
        let f = &self.fluid;
        match (f.nu, f.tau) {
            (Some(_), Some(tau)) => {
                return Err(invalid(
                    "fluid.tau",
                    tau,
                    "give either fluid.nu or fluid.tau, not both (tau = 3 nu + 1/2)",
                ))
            }
            (None, None) => {
                return Err(CaseErrorKind::Missing {
                    key: "fluid.nu".into(),
                    what: "give fluid.nu > 0 or fluid.tau > 0.5".into(),
                })
            }
            (Some(nu), None) => {
                if !(nu.is_finite() && nu > 0.0) {
                    return Err(invalid("fluid.nu", nu, "must be finite and > 0 (tau = 3 nu + 1/2 > 0.5)"));
                }
                let tau = self.tau();
                let nu_max = (MAX_TAU - 0.5) * CS2;
                if tau.is_nan() || tau <= 0.5 {
                    return Err(invalid(
                        "fluid.nu",
                        nu,
                        format!(
                            "too small: tau = 3 nu + 1/2 rounds to {tau} in double precision, and tau must be > 0.5 \
                             (nu >= 1e-15 is safe; the allowed range is 0 < nu <= {nu_max})"
                        ),
                    ));
                }
                if tau > MAX_TAU {
                    return Err(invalid(
                        "fluid.nu",
                        nu,
                        format!("must be <= {nu_max} (tau = 3 nu + 1/2 <= {MAX_TAU}; here tau = {tau})"),
                    ));
                }
            }
            (None, Some(tau)) => {
                if !(tau.is_finite() && tau > 0.5 && tau <= MAX_TAU) {
                    return Err(invalid(
                        "fluid.tau",
                        tau,
                        format!("must be finite and > 0.5, and at most {MAX_TAU} (tau = 3 nu + 1/2; nu > 0)"),
                    ));
                }
                if self.tau().is_nan() || self.tau() <= 0.5 {
                    return Err(invalid(
                        "fluid.tau",
                        tau,
                        format!(
                            "too close to 0.5: the solver's tau = 3 nu + 1/2 with nu = (tau - 1/2)/3 rounds to {} \
                             (allowed: 0.5 < tau <= {MAX_TAU}, tau - 0.5 >= 1e-15 is safe)",
                            self.tau()
                        ),
                    ));
                }
            }
        }
        if let Some(magic) = f.magic {
            if f.collision != CollisionModel::Trt {
                return Err(invalid("fluid.magic", magic, "only allowed with fluid.collision = \"trt\""));
            }
            if !(magic.is_finite() && magic > 0.0) {
                return Err(invalid(
                    "fluid.magic",
                    magic,
                    "must be finite and > 0 (3/16 = 0.1875 puts bounce-back walls exactly half-way)",
                ));
            }
        }
        if f.body_force.iter().any(|g| !g.is_finite()) {
            return Err(invalid("fluid.body_force", fmt_vec(&f.body_force), "each component must be finite"));
        }
        self.fluid_params().validate().map_err(|e| self.map_fluid_error(e))
    }

    fn validate_run(&self) -> Result<(), CaseErrorKind> {
        let r = &self.run;
        if r.steps < 1 {
            return Err(invalid("run.steps", r.steps, "must be an integer >= 1"));
        }
        if r.output_every < 1 || r.output_every > r.steps {
            return Err(invalid(
                "run.output_every",
                r.output_every,
                format!("must be an integer with 1 <= output_every <= run.steps = {}", r.steps),
            ));
        }
        if let Some(c) = r.checkpoint_every {
            if c < 2 || !c.is_multiple_of(2) || c > r.steps {
                return Err(invalid(
                    "run.checkpoint_every",
                    c,
                    format!(
                        "must be an even integer with 2 <= checkpoint_every <= run.steps = {} \
                         (the solver's state is complete only after an even number of steps)",
                        r.steps
                    ),
                ));
            }
        }
        if r.device == Device::Gpu
            && self.fluid.precision != Precision::F32
            && (self.has_particles() || self.impeller.is_some())
        {
            return Err(invalid(
                "run.device",
                "\"gpu\"",
                "\"cpu\", or \"gpu\" with fluid.precision = \"f32\" for a case with particles or an impeller \
                 (the device's markers work in f32; the fluid alone runs there in f64 too, where the adapter \
                 has 64-bit float shaders)",
            ));
        }
        if let Some(&s) = r.snapshots.iter().find(|&&s| s < 1 || s > r.steps) {
            return Err(invalid(
                "run.snapshots",
                s,
                format!("must hold steps with 1 <= step <= run.steps = {}", r.steps),
            ));
        }
        if !mach_limit_allowed(r.mach_limit) {
            return Err(invalid(
                "run.mach_limit",
                r.mach_limit,
                "must be in (0, 1] (default 0.3; lattice Boltzmann is weakly compressible)",
            ));
        }
        Ok(())
    }

    fn validate_boundaries(&self) -> Result<(), CaseErrorKind> {
        let limit = self.run.mach_limit;
        for face in Face::ALL {
            if let BoundarySpec::MovingWall(v) = self.boundaries.get(face) {
                let key = format!("boundaries.{}.moving_wall", face.name());
                if v.iter().any(|c| !c.is_finite()) {
                    return Err(invalid(key, fmt_vec(&v), "each component must be finite"));
                }
                if v[face.axis()] != 0.0 {
                    return Err(invalid(
                        key,
                        fmt_vec(&v),
                        format!(
                            "the wall moves in its own plane: the {} component must be 0",
                            ["x", "y", "z"][face.axis()]
                        ),
                    ));
                }
                let m = mach(v);
                if m > limit {
                    return Err(invalid(
                        key,
                        fmt_vec(&v),
                        format!(
                            "wall Mach number |u|/c_s = {m:.3} exceeds run.mach_limit = {limit}; allowed: |u| <= {:.4}",
                            limit * CS2.sqrt()
                        ),
                    ));
                }
            }
        }
        self.boundaries().validate().map_err(|e| self.map_fluid_error(e))
    }

    fn validate_initial(&self) -> Result<(), CaseErrorKind> {
        let i = &self.initial;
        let limit = self.run.mach_limit;
        if !(i.density.is_finite() && i.density > 0.0) {
            return Err(invalid("initial.density", i.density, "must be finite and > 0 (default 1)"));
        }
        match i.kind {
            InitialKind::Uniform => {
                if let Some(a) = i.amplitude {
                    return Err(invalid(
                        "initial.amplitude",
                        a,
                        "only allowed with initial.kind = \"taylor_green\"",
                    ));
                }
                if let Some(v) = i.velocity {
                    if v.iter().any(|c| !c.is_finite()) {
                        return Err(invalid(
                            "initial.velocity",
                            fmt_vec(&v),
                            "each component must be finite",
                        ));
                    }
                    if mach(v) > limit {
                        return Err(invalid(
                            "initial.velocity",
                            fmt_vec(&v),
                            format!(
                                "Mach number {:.3} exceeds run.mach_limit = {limit}; allowed: |u| <= {:.4}",
                                mach(v),
                                limit * CS2.sqrt()
                            ),
                        ));
                    }
                }
            }
            InitialKind::TaylorGreen => {
                if let Some(v) = i.velocity {
                    return Err(invalid(
                        "initial.velocity",
                        fmt_vec(&v),
                        "not allowed with initial.kind = \"taylor_green\" (use initial.amplitude)",
                    ));
                }
                let Some(a) = i.amplitude else {
                    return Err(CaseErrorKind::Missing {
                        key: "initial.amplitude".into(),
                        what: "initial.kind = \"taylor_green\" needs a velocity amplitude > 0".into(),
                    });
                };
                let max_amp = limit * CS2.sqrt() / self.taylor_green_speed_factor();
                if !(a.is_finite() && a > 0.0 && a <= max_amp) {
                    return Err(invalid(
                        "initial.amplitude",
                        a,
                        format!(
                            "must be in (0, {max_amp:.4}]: the peak Mach number must stay below run.mach_limit = {limit}"
                        ),
                    ));
                }
                for (lo, hi) in [(Face::XMin, Face::XMax), (Face::YMin, Face::YMax)] {
                    let periodic = |f| self.boundaries.get(f) == BoundarySpec::Periodic;
                    if !(periodic(lo) && periodic(hi)) {
                        return Err(invalid(
                            "initial.kind",
                            "\"taylor_green\"",
                            format!("needs periodic boundaries.{} and boundaries.{}", lo.name(), hi.name()),
                        ));
                    }
                }
            }
        }
        Ok(())
    }

    /// Maps a solver validation error to the case key it comes from.
    fn map_fluid_error(&self, e: FluidError) -> CaseErrorKind {
        match e {
            FluidError::Viscosity { nu, tau } => match self.fluid.tau {
                Some(_) => invalid("fluid.tau", tau, format!("{e}")),
                None => invalid("fluid.nu", nu, format!("{e}")),
            },
            FluidError::Magic { magic } => invalid("fluid.magic", magic, format!("{e}")),
            FluidError::BodyForce { force } => invalid("fluid.body_force", fmt_vec(&force), format!("{e}")),
            FluidError::PeriodicPair { axis } => {
                let lo = Face::from_axis(axis, true);
                let hi = Face::from_axis(axis, false);
                invalid(
                    format!("boundaries.{}/{}", lo.name(), hi.name()),
                    format!(
                        "{} / {}",
                        self.boundaries.get(lo),
                        self.boundaries.get(hi)
                    ),
                    format!(
                        "periodic faces come in pairs: make both boundaries.{} and boundaries.{} periodic, or neither",
                        lo.name(),
                        hi.name()
                    ),
                )
            }
            FluidError::WallVelocity { face, velocity } => {
                invalid(format!("boundaries.{}.moving_wall", face.name()), fmt_vec(&velocity), format!("{e}"))
            }
            FluidError::Grid { grid } => {
                invalid("domain", format!("{} x {} x {}", grid.nx, grid.ny, grid.nz), format!("{e}"))
            }
            other => invalid("case", "?", other.to_string()),
        }
    }
}
